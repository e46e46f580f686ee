"""Where the faithful rigid tiles fold (issue 33: "report the fold map rather than ship nonsense"), read from the
faithful atlas's committed probe cache, without simulating anything.

    python experiments/fold_map.py [--cache experiments/cache/atlas_faithful.jsonl]

A probe ends "folded" when a tile-link joint bends past the model's fold angle (the disc folds over on itself: the
model no longer describes a sheet lying on a plate). For each plate amplitude and omega_n node of the atlas grid the
table gives how many of its probes folded and at which frequencies. Writes experiments/results/fold_map_rigid_fast.md
and .json.
"""

from __future__ import annotations

import argparse
import json
import math
from collections import defaultdict
from pathlib import Path

RESULTS = Path(__file__).resolve().parent / "results"


def probe_fields(key: str) -> tuple[float, float, float]:
    """(omega_n rad/s, f_p Hz, A_p deg) of a sweep-cache key (plate_env.run.sweeps: backend tag | spec values)."""
    values = [float(x) for x in key.split("|", 1)[1].split(",")]
    return values[0], values[5], math.degrees(values[6])


def fold_map(cache: Path) -> dict:
    """``{A_p deg: {omega_n/pi: {"probes": n, "folded": k, "folded_f_hz": [...]}}}`` from the cache's records."""
    cells: dict = defaultdict(lambda: defaultdict(lambda: {"probes": 0, "folded": 0, "folded_f_hz": set()}))
    for line in cache.read_text().splitlines():
        rec = json.loads(line)
        w, f, amp = probe_fields(rec["key"])
        c = cells[round(amp, 3)][round(w / math.pi, 4)]
        c["probes"] += 1
        if rec.get("reason") == "folded":
            c["folded"] += 1
            c["folded_f_hz"].add(f)
    return {amp: {w: {**c, "folded_f_hz": sorted(c["folded_f_hz"])} for w, c in sorted(by_w.items())}
            for amp, by_w in sorted(cells.items())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cache", default="experiments/cache/atlas_faithful.jsonl")
    args = ap.parse_args()
    m = fold_map(Path(args.cache))
    lines = ["# Where the rigid tiles (rigid_fast) fold", "",
             f"Read from `{args.cache}` (the faithful atlas's probes: 31 f x 16 omega_n x 5 alpha x 2 placements per "
             "amplitude) by `python experiments/fold_map.py`; nothing simulated. A folded probe is unstable with the "
             "reason `folded`: a joint bent past the model's fold angle.", "",
             "| A_p (deg) | omega_n (pi rad/s) | probes | folded | at f_p (Hz) |", "|---|---|---|---|---|"]
    for amp, by_w in m.items():
        for w, c in by_w.items():
            if c["folded"]:
                fs = c["folded_f_hz"]
                lines.append(f"| {amp:g} | {w:g} | {c['probes']} | {c['folded']} | {min(fs):g}-{max(fs):g} |")
        total = sum(c["probes"] for c in by_w.values())
        folded = sum(c["folded"] for c in by_w.values())
        soft = [w for w, c in by_w.items() if c["folded"]]
        lines.append(f"| {amp:g} | all | {total} | {folded} ({100 * folded / total:.1f} %) | "
                     f"{'none' if not soft else f'only omega_n <= {max(soft):g} pi'} |")
    text = "\n".join(lines) + "\n"
    (RESULTS / "fold_map_rigid_fast.md").write_text(text)
    (RESULTS / "fold_map_rigid_fast.json").write_text(json.dumps({f"{a:g}": {f"{w:g}": c for w, c in by.items()}
                                                                  for a, by in m.items()}, indent=1) + "\n")
    print(text)


if __name__ == "__main__":
    main()
