"""The faithful forward model (issue 33): the shipped rigid-tile atlas (``atlas_tilelink_rigid_fast.npz``, grid
``faithful``) as the forward model ``tilelink/rigid_fast``, its discrepancy fitted on one set of live sweeps and its
intervals tested on another.

    python experiments/faithful_forward.py [--executor pool:2]

Calibration: the 20 committed sweeps of the converged rigid-tile limit (``LAB_SETS["rigid"]``, ``rigid_limit``, 3
deg, 10-40 Hz; the model the paper's numbers agree with) through the atlas: each object's log(truth / estimate)
and its posterior spread give sigma_eps (``fit_discrepancy``). Test: 20 fresh objects of the atlas's own model
(``rigid_fast``, seed 700, live, cached in ``experiments/cache``) through the atlas with that sigma_eps: error,
68 / 95 % coverage with bootstrap intervals over objects. Writes ``experiments/results/faithful_forward.md`` and
``.json`` (the registry's ``tilelink/rigid_fast`` entry reads sigma_eps from the JSON).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from common import CACHE, HEAD, member, row

from plate_env.bench.scoring import discrepancies, score
from plate_env.build.eq10 import LAB_SETS, lab_backend_of
from plate_env.build.eval_sets import EvalSet, run_eval_set
from plate_env.build.forward_models import FAITHFUL
from plate_env.identify.forward import ForwardModel
from plate_env.identify.inference import fit_discrepancy, identify_atlas
from plate_env.run.executor import BackendSpec, add_executor_argument

CALIBRATION = LAB_SETS["rigid"]
TEST = EvalSet("tilelink_rigid_fast", 20, 700, (3.0,))
RESULTS = Path("experiments/results")


def forward(sigma_eps: float = 0.0, nu: float = math.inf) -> ForwardModel:
    return ForwardModel("tilelink/rigid_fast", (member(FAITHFUL),), sigma_eps=sigma_eps, eps_nu=nu)


def sweeps(es: EvalSet, backend_of, executor) -> tuple[list[float], list]:
    tables = run_eval_set(es, backend_of, executor, progress=True, cache_dir=CACHE)
    return [o.omega_n for o in es.objects()], tables[es.a_p_deg[0]]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_executor_argument(ap)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    cal_truth, cal = sweeps(CALIBRATION, lab_backend_of("rigid"), args.executor)
    test_truth, test = sweeps(TEST, lambda _n: BackendSpec.of("tilelink", model="rigid_fast"), args.executor)
    bare = forward()
    eps, sd = discrepancies(cal_truth, [identify_atlas(t, bare) for t in cal])
    nu, sigma = fit_discrepancy(eps, sd)
    fitted = forward(sigma, nu)
    scores = {"calibration, sigma_eps 0": score(cal_truth, [identify_atlas(t, bare) for t in cal], rng),
              f"calibration, sigma_eps {sigma:.3f} (in sample)":
                  score(cal_truth, [identify_atlas(t, fitted) for t in cal], rng),
              "test, sigma_eps 0": score(test_truth, [identify_atlas(t, bare) for t in test], rng),
              f"test, sigma_eps {sigma:.3f}": score(test_truth, [identify_atlas(t, fitted) for t in test], rng)}
    lines = ["# The faithful forward model: tilelink/rigid_fast", "",
             f"Atlas `{FAITHFUL}` (grid `faithful`, its held-out model error sigma_model "
             f"{bare.members[0].sigma_model:.2f} deg/s). Calibration: {CALIBRATION.n} `rigid_limit` objects (seed "
             f"{CALIBRATION.seed}), 3 deg, {len(CALIBRATION.f_hz)} probes each; test: {TEST.n} fresh `rigid_fast` "
             f"objects (seed {TEST.seed}). Command: `python experiments/faithful_forward.py`.", "",
             f"Discrepancy fitted on the calibration set (`fit_discrepancy`): sigma_eps = {sigma:.4f} (nu {nu:g}); "
             f"mean log(truth / estimate) {float(np.mean(eps)):+.4f}.", "",
             *HEAD, *(row(k, s) for k, s in scores.items()), "",
             "Coverage intervals: bootstrap over objects (`plate_env.bench.scoring.score`). No estimate "
             "counts as an infinite error; a bound counts as covered at 95 % when it holds (`score`)."]
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "faithful_forward.md").write_text("\n".join(lines) + "\n")
    (RESULTS / "faithful_forward.json").write_text(json.dumps(
        {"sigma_eps": sigma, "eps_nu": nu, "eps": eps.tolist(), "sd": sd.tolist(),
         "scores": {k: s.to_dict() for k, s in scores.items()}}, indent=1) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
