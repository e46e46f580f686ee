"""Write the evaluation suites (plate_env/data/suites/*.json) and print their content hashes to pin.

    python experiments/make_suites.py [--check]

Run once per new suite version: the files are the suites from then on (plate_env.suites pins their hashes, so
an edited suite is refused until it is saved under a new version). Objects come from the env's object prior
(plate_env.objects.ObjectPrior) with a fixed seed; ``--check`` regenerates in memory and compares with the files.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from plate_env.bench.suites import content_hash, suite_dir
from plate_env.core.objects import ObjectPrior

#: Probe settings of the tile-link suites: the CLI's identify (and the shipped policy's training) settings.
TILELINK_ENV = {"method": "atlas", "f_band_hz": [10.0, 40.0], "amplitudes_deg": [3.0, 12.0],
                "measure_range_s": [0.25, 2.0], "settle_s": 0.5, "b_p_mm": 3.0, "max_probes": 30,
                "cost_per_sim_s": 0.005}
COST_MODEL = {"probe_s": "ramp 0.2 s + settle_s + the window; a probe that ends unstable costs the seconds it ran",
              "cost_per_sim_s": "the env's reward charges this per simulated second (scored here: error against "
                                "simulated probing seconds)"}


def objects(n: int, seed: int, seed_base: int, prior: ObjectPrior | None = None, mass_g: float = 13.6) -> list:
    prior = prior or ObjectPrior()
    return [{"omega_n_pi": round(w / math.pi, 4), "alpha_deg": round(math.degrees(a), 3), "mass_g": mass_g,
             "seed": seed_base + i} for i, (w, a) in enumerate(prior.sample(n, seed))]


def suites() -> list[dict]:
    live = objects(100, seed=2014, seed_base=14_000)
    return [
        {"name": "atlas-v0", "description": "Fast iteration: the tilelink-v0 objects and seeds with probes answered "
         "by the tile-link point-mass atlas (microseconds a probe).",
         "env_kwargs": {"physics": "atlas", **TILELINK_ENV}, "budgets_s": [10.0, 20.0, 40.0],
         "cost_model": COST_MODEL, "objects": live},
        {"name": "tilelink-v0", "description": "100 objects of the env's prior (omega_n log-uniform 3.5-33 pi rad/s, "
         "alpha 30-60 deg, the cheese slice's 13.6 g) on the paper's tile-link model (point mass), live.",
         "env_kwargs": {"physics": "tilelink", **TILELINK_ENV}, "budgets_s": [10.0, 20.0, 40.0],
         "cost_model": COST_MODEL, "objects": live},
        {"name": "pybullet-v0", "description": "A small live PyBullet suite: 6 objects inside the PyBullet atlas "
         "(6-30 pi rad/s), 3 deg probes at 10-26 Hz, the PyBullet atlas's settle time.",
         "env_kwargs": {"physics": "pybullet", "method": "atlas", "f_band_hz": [10.0, 26.0], "amplitudes_deg": [3.0],
                        "measure_range_s": [0.4, 1.0], "settle_s": 0.3, "b_p_mm": 3.0, "max_probes": 12,
                        "cost_per_sim_s": 0.005},
         "budgets_s": [4.0, 8.0, 12.0], "cost_model": COST_MODEL,
         "objects": objects(6, seed=3014, seed_base=15_000, prior=ObjectPrior((6.0, 30.0), (30.0, 60.0)))},
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="compare with the files instead of writing them")
    args = ap.parse_args()
    bad = 0
    for s in suites():
        path = suite_dir() / f"{s['name']}.json"
        if args.check:
            same = path.is_file() and json.loads(path.read_text()) == s
            bad += not same
            print(f"{s['name']}: {'same' if same else 'DIFFERS'}")
            continue
        path.write_text(json.dumps(s, indent=1) + "\n")
        print(f'    "{s["name"]}": "{content_hash(s)}",')
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
