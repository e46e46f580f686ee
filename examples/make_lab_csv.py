"""Write examples/cheese_sweep.csv: a lab-format sweep of the paper's cheese slice, simulated, for the README's
``plate-env fit`` quick start (a lab's own file has the same columns).

    python examples/make_lab_csv.py

The cheese preset (omega_n = 10 pi rad/s, 13.6 g, 80 mm) swept 10-40 Hz in 1 Hz steps at A_p = 3 deg, B_p = 3 mm on
the point-mass tile-link model, each probe placed at a random yaw and 0.2 mm offset (ProbeSpec.perturbed) from a
seeded generator.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

import plate_env as pe

OUT = Path(__file__).with_name("cheese_sweep.csv")


def main() -> None:
    rng = np.random.default_rng(0)
    cheese = pe.preset("cheese")
    specs = [pe.ProbeSpec(cheese, pe.PlateMotion.from_paper(f_p_hz=f, a_p_deg=3.0, b_p_mm=3.0)).perturbed(rng)
             for f in range(10, 41)]
    results = pe.make_physics("tilelink").run(specs)
    with OUT.open("w", newline="") as fh:
        fh.write("# the cheese preset (omega_n = 10 pi rad/s) simulated by python examples/make_lab_csv.py\n")
        w = csv.writer(fh)
        w.writerow(["f_p_hz", "omega_b_deg_s", "stderr_deg_s", "unstable"])
        for s, r in zip(specs, results, strict=True):
            w.writerow([f"{s.motion.freq_hz:g}", f"{r.omega_b_deg_s:.2f}", f"{r.stderr_deg_s:.2f}", int(r.unstable)])
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
