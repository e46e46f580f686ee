"""The catalog of shipped forward models (package data ``forward_models.json``): their names and, for each, the
atlas files of its members (the atlas families a physics backend or a forward model is conditioned from)."""

from __future__ import annotations

#: Package data: the shipped forward models (written by experiments/forward_models.py).
REGISTRY_FILE = "forward_models.json"


def read_catalog() -> dict:
    """The catalog as read from the package data (empty when none is shipped)."""
    import json
    from importlib import resources

    ref = resources.files("plate_env") / "data" / REGISTRY_FILE
    return json.loads(ref.read_text()) if ref.is_file() else {}


def forward_model_names() -> list[str]:
    """Names of the shipped forward models ("<physics>/<model>" inside one model, ``"lab"`` across models)."""
    return sorted(read_catalog())


def registry_member_atlases(name: str) -> list[list[str]]:
    """The atlas files of each member of a shipped forward model (none if it is not shipped)."""
    return [list(m["atlases"]) for m in read_catalog().get(name, {}).get("members", [])]
