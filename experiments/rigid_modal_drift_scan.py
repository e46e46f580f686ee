"""Issue 34: the faithful modal route's drift on four probes under its solver settings (step, contact sweeps, mode
counts), beside the reference's drift (``results/rigid_drift.md``). Prints the largest drift (mm) and omega_B (deg/s)
per probe; threshold lifted to 60 mm. Usage: ``python experiments/rigid_modal_drift_scan.py`` (~1-2 min)."""

import json
from dataclasses import replace
from pathlib import Path

from common import load_reference, spec_of
from rigid_drift import drift_row

from plate_env.physics.tilelink.rigid_modal import ModalDiscConfig
from plate_env.physics.tilelink.rigid_modal_kernels import RigidModalPhysics

RESULTS = Path(__file__).resolve().parent / "results"
rows = {r["key"]: r for r in load_reference()}
keys = ["10pi_36.9deg_28Hz", "10pi_50deg_28Hz", "10pi_36.9deg_20Hz", "23pi_36.9deg_22Hz"]
variants = {
  "faithful dt1e-4 it2": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 2),
  "faithful dt1e-4 it4": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 4),
  "faithful dt1e-4 nl50": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=50), 2),
  "nl30 200Hz dt1e-4": (1e-4, ModalDiscConfig(n_nonlinear=30), 2),
  "linear 2kHz dt1e-4": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=0, foreshortening=False), 2),
  "faithful no foreshortening": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30, foreshortening=False), 2),
  "faithful dt1e-4 it8": (1e-4, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 8),
  "faithful dt5e-5 it4": (5e-5, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 4),
  "faithful dt5e-5 it8": (5e-5, ModalDiscConfig(cutoff_hz=2000.0, n_nonlinear=30), 8),
}
ref = {r["key"]: r for r in json.loads((RESULTS / "rigid_drift_reference.json").read_text())["probes"]}
print(f"{'reference':28s}", "  ".join(f"{ref[k]['max_drift_mm']:5.1f} ({ref[k]['omega_b_deg_s']:.0f})" for k in keys))
for name, (dt, cfg, it) in variants.items():
    ph = RigidModalPhysics(dt, cfg, it, slip_limit=0.06)
    specs = [replace(spec_of(rows[k]), record_trace=True) for k in keys]
    out = [drift_row(rows[k], r) for k, r in zip(keys, ph.run(specs), strict=True)]
    print(f"{name:28s}", "  ".join(f"{o['max_drift_mm']:5.1f} ({o['omega_b_deg_s']:.0f})" for o in out), flush=True)
