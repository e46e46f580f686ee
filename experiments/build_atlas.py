"""Build an atlas into this checkout: ``plate-env build atlas`` (:mod:`plate_env.build.atlas`) with this
repository's places as defaults: the atlas to plate_env/data/atlas_<physics>_<model>.npz (or atlas_<name>.npz), the
report to experiments/results/atlas_<physics>_<model>.md (or atlas_<name>.md), the cache in experiments/cache.

    python experiments/build_atlas.py [plate-env build atlas options]
    python experiments/build_atlas.py --grid pointmass_m13.6 --repeats 4        # the shipped point-mass atlas
    python experiments/build_atlas.py --physics pybullet --repeats 1            # the shipped PyBullet atlas

Options: ``plate-env build atlas --help``.
"""

from __future__ import annotations

import argparse
import sys

from plate_env.build.atlas import make_backend
from plate_env.cli import main as cli_main


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(add_help=False)
    for opt, default in (("--physics", "tilelink"), ("--model", "pointmass"), ("--name", None), ("--out", None),
                         ("--report", None), ("--cache-dir", None)):
        ap.add_argument(opt, default=default)
    known, _ = ap.parse_known_args(argv)
    if "-h" in argv or "--help" in argv:
        return cli_main(["build", "atlas", "--help"])
    _, model = make_backend(known.physics, known.model)
    tag = known.name or f"{known.physics}_{model}"
    extra = []
    if known.out is None:
        extra += ["--out", f"plate_env/data/atlas_{tag}.npz"]
    if known.report is None:
        extra += ["--report", f"experiments/results/atlas_{tag}.md"]
    if known.cache_dir is None:
        extra += ["--cache-dir", "experiments/cache"]
    return cli_main(["build", "atlas", *argv, *extra])


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
