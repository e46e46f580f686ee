"""How far this machine's rebuild of the committed artifacts is from the committed bits (issue 37 item 0).

Rebuilds, into a temporary directory, the artifacts whose tests compare against committed numbers (the forward-model
registry, the paper calibration, the Eq. (10) lines from the committed sweeps, one tile-link calibration sweep) and
prints, per artifact, how many numbers differ and the largest relative difference. The tests' tolerance
(plate_env.build.compare.CROSS_CPU_RTOL) is set from these numbers.

    python experiments/cross_cpu.py            # about a minute
"""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import platform
import tempfile
from importlib import resources
from pathlib import Path

from plate_env.build.compare import differences
from plate_env.cli import main

ROOT = Path(__file__).resolve().parents[1]

CACHE = ROOT / "experiments" / "cache"


def _row(name: str, a, b) -> str:
    ds = list(differences(a, b))
    worst = max(ds, key=lambda d: d[3])
    return (f"| {name} | {len(ds)} | {sum(d[3] > 0 for d in ds)} | {worst[3]:.2g} | `{worst[0]}` |")


def main_() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):
        tmp = Path(tmp)
        res = ROOT / "experiments" / "results"
        assert main(["build", "forward-models", "--within", str(res / "forward_models_within.json"),
                     "--lomo", str(res / "forward_models_lomo.json"), "--faithful",
                     str(res / "faithful_forward.json"), "--out", str(tmp / "fm.json")]) == 0
        shipped = json.loads((resources.files("plate_env") / "data" / "forward_models.json").read_text())
        rows.append(_row("forward-model registry", json.loads((tmp / "fm.json").read_text()), shipped))

        from plate_env.identify import lab_calibration_file as lcf
        assert main(["build", "calibration", "paper", "--out", str(tmp / "cal.json")]) == 0
        rows.append(_row("paper calibration (posterior)", dataclasses.asdict(lcf.load(tmp / "cal.json").posterior),
                         dataclasses.asdict(lcf.load(lcf.PAPER).posterior)))

        sweeps = tmp / "sweeps"
        sweeps.mkdir()
        for name in ("sweeps_tilelink_pointmass.jsonl", "evalnuis_tilelink_pointmass_A3_s400.jsonl"):
            (sweeps / name).write_bytes((CACHE / name).read_bytes())
        assert main(["build", "calibration", "eq10", "--sweeps", str(sweeps), "--lab-sweeps", str(CACHE),
                     "--out", str(tmp / "eq10.json")]) == 0
        study = json.loads((res / "eq10_rebuild.json").read_text())["rebuilt"]
        rows.append(_row("Eq. (10) lines from the committed sweeps", json.loads((tmp / "eq10.json").read_text()),
                         study))

        from plate_env.build.eq10 import TILELINK, tilelink_specs
        from plate_env.run.sweeps import backend_tag, load_cache, run_cached, spec_key
        committed = load_cache(CACHE / "sweeps_tilelink_pointmass.jsonl")
        specs = tilelink_specs(3.0)[5 * 31:6 * 31]
        live = run_cached(TILELINK, specs, None, progress=False)
        tag = backend_tag(TILELINK)
        rows.append(_row("one tile-link calibration sweep (31 probes)",
                         [[r.omega_b_deg_s, r.stderr_deg_s, r.unstable] for r in live],
                         [[(d := committed[spec_key(tag, s)])["omega_b_deg_s"], d["stderr_deg_s"], d["unstable"]]
                          for s in specs]))
    print(f"machine: {platform.processor() or platform.machine()}, numpy "
          f"{__import__('numpy').__version__}")
    print("| artifact | numbers | differing | largest relative difference | where |")
    print("|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main_()
