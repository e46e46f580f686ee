"""``plate-env cache``: show or clear the disk cache of derived arrays."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from plate_env.cli.options import Subparsers


def add_parser(sub: Subparsers) -> None:
    c = sub.add_parser("cache", help="show or clear the disk cache of derived arrays (docs/speed.md)")
    c.add_argument("action", choices=("info", "clear"), help="info: where it is, its entries and their size; "
                   "clear: delete its entries (each is computed again when next needed)")


def _megabytes(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


def run(args: argparse.Namespace) -> int:
    from plate_env.core.cache import cache_dir, cache_entries, clear_cache

    root = cache_dir()
    if root is None:
        print("cache: off (PLATE_ENV_CACHE_DIR=off): nothing is kept on disk")
        return 0
    if args.action == "clear":
        gone = clear_cache(root)
        print(f"cache {root}: deleted {len(gone)} entries, {_megabytes(sum(e.size_bytes for e in gone))}")
        return 0
    entries = cache_entries(root)
    print(f"cache {root}: {len(entries)} entries, {_megabytes(sum(e.size_bytes for e in entries))} "
          f"(no size limit: `plate-env cache clear` deletes them)")
    for kind in sorted({e.kind for e in entries}):
        of = [e for e in entries if e.kind == kind]
        print(f"  {kind}: {len(of)} entries, {_megabytes(sum(e.size_bytes for e in of))}")
    return 0
