"""The catalog of shipped forward models (package data ``forward_models.json``): their names and, for each, the
atlas files of its members (the atlas families a physics backend or a forward model is conditioned from)."""

from __future__ import annotations

import functools
from pathlib import Path

#: Package data: the shipped forward models (written by experiments/forward_models.py).
REGISTRY_FILE = "forward_models.json"


@functools.lru_cache(maxsize=1)
def _catalog_path():
    from importlib import resources

    return resources.files("plate_env") / "data" / REGISTRY_FILE


def read_catalog() -> dict:
    """The catalog as read from the package data (empty when none is shipped): a fresh dict each call, the file
    read again only when it changed (size, modification time)."""
    import json

    ref = _catalog_path()
    try:
        st = Path(str(ref)).stat()
        stamp = (st.st_size, st.st_mtime_ns)
    except OSError:  # no such file, or not a plain one (a zipped package)
        return json.loads(ref.read_text()) if ref.is_file() else {}
    if _CATALOG_TEXT.get("stamp") != stamp:
        _CATALOG_TEXT.update(stamp=stamp, text=ref.read_text())
    return json.loads(_CATALOG_TEXT["text"])


_CATALOG_TEXT: dict = {}


def forward_model_names() -> list[str]:
    """Names of the shipped forward models ("<physics>/<model>" inside one model, ``"lab"`` across models)."""
    return sorted(read_catalog())


def registry_member_atlases(name: str) -> list[list[str]]:
    """The atlas files of each member of a shipped forward model (none if it is not shipped)."""
    return [list(m["atlases"]) for m in read_catalog().get(name, {}).get("members", [])]
