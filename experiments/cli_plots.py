"""The pictures docs/cli.md shows: each ``--plot`` of the CLI on the cases of issue 40 item 2, at 80 dpi.

    python experiments/cli_plots.py [--out docs/img] [--work /tmp/cli_plots]

Runs, through ``plate_env.cli.main`` exactly as typed on the command line (only the PNG resolution lowered):

    plate-env sweep --omega-n 20pi --freqs 12:34:2 --amp 3 --csv s.csv --plot sweep.png   (tilelink point mass)
    plate-env fit s.csv --amp 3 --plot fit.png
    plate-env identify --physics atlas --omega-n 20pi --seed 2 --plot run.png             (probes at 3 and 12 deg)
    plate-env bench --suite atlas-v0 --agent bayes grid --limit 8 --plot bench.png

and writes docs/img/cli_{sweep,fit,run,bench}.png (the CSV and the bench cache go to ``--work``).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import plate_env.plotting as plotting
from plate_env.cli import main as cli

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "img"), help="where the PNGs go (default: docs/img)")
    ap.add_argument("--work", default="/tmp/cli_plots", help="scratch directory for the CSV and the bench cache")
    args = ap.parse_args()
    out, work = Path(args.out), Path(args.work)
    out.mkdir(parents=True, exist_ok=True)
    work.mkdir(parents=True, exist_ok=True)
    plotting.DPI = 80  # small PNGs for the docs; everything else as the CLI draws it
    csv = work / "s.csv"
    runs = {
        "sweep": ["sweep", "--omega-n", "20pi", "--freqs", "12:34:2", "--amp", "3", "--csv", str(csv),
                  "--no-progress"],
        "fit": ["fit", str(csv), "--amp", "3"],
        "run": ["identify", "--physics", "atlas", "--omega-n", "20pi", "--seed", "2"],
        "bench": ["bench", "--suite", "atlas-v0", "--agent", "bayes", "grid", "--limit", "8", "--no-progress",
                  "--cache", str(work / "bench.jsonl")],
    }
    for name, argv in runs.items():
        png = work / f"{name}.png"
        code = cli(argv + ["--plot", str(png)])
        if code not in (0, 1):
            raise SystemExit(f"plate-env {' '.join(argv)} exited {code}")
        shutil.copyfile(png, out / f"cli_{name}.png")
        print(f"wrote {out / f'cli_{name}.png'}")


if __name__ == "__main__":
    main()
