"""The bayes agent's design discrepancy: ``plate-env build design-discrepancy --within W.json --out FILE`` writes
``agents/models/bayes_design_discrepancy.json`` (installed as ``plate_env_agents/models/``), which
``plate_env_agents.bayes`` reads as ``DESIGN_DISCREPANCY``.

The value is the coherent discrepancy (scale of log omega_n, Student-t degrees of freedom) of the agent's own
estimates, fitted by maximum likelihood on 100 calibration episodes of the agent on live tile-link
(``python experiments/forward_models.py within --episodes 100``: objects of the prior, seed 510; tested on 100 others,
seed 520). That stage records the fit in ``experiments/results/forward_models_within.json`` under ``bayes``
(``sigma_design_fit``, ``nu_design_fit``); this builder reads it from there and rounds the scale to
:data:`SCALE_DECIMALS` decimals, the precision the agent has shipped with. The episodes are kept in a checkout's
experiments/cache (forward_models_bayes_s510.jsonl, _s520.jsonl); refitting from them means rerunning that stage.

The file is read as data, so the build record (command, version, commit) goes beside it, ``FILE.provenance.json``,
and the file stays byte-identical to the shipped one.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from plate_env.core.files import read_json, write_text_atomic

#: The forward model the within stage's episodes were estimated with (its point-mass model).
FORWARD = "tilelink/pointmass"
#: Decimals the shipped scale keeps (0.009925 -> 0.0099).
SCALE_DECIMALS = 4
#: The shipped file's name, in plate_env_agents/models/.
FILE_NAME = "bayes_design_discrepancy.json"


def design_discrepancy(within: dict) -> dict:
    """The file's content from the within stage's numbers (its JSON document); ValueError when they hold no bayes
    fit or a value out of range."""
    try:
        b = within["bayes"]
        scale, nu = float(b["sigma_design_fit"]), float(b["nu_design_fit"])
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"the within results hold no bayes design fit ({exc}): run python "
                         "experiments/forward_models.py within --episodes 100") from None
    if not (math.isfinite(scale) and scale > 0 and nu > 0):
        raise ValueError(f"bayes design fit: scale {scale!r}, nu {nu!r}: expected a scale > 0 and nu > 0")
    return {"design_discrepancy": {FORWARD: {"scale": round(scale, SCALE_DECIMALS), "nu": nu}},
            "provenance": {
                "fitted": "maximum likelihood of each truth under the agent's blurred posterior smoothed by a "
                          "Student-t discrepancy (plate_env.identify.inference.fit_discrepancy_exact)",
                "episodes": {"n": int(b.get("n", 0)), "calibration_seed": b.get("calibration_seed"),
                             "test_seed": b.get("test_seed"), "physics": "tilelink (live), objects of the prior"},
                "from": "experiments/results/forward_models_within.json: bayes.sigma_design_fit, nu_design_fit "
                        "(python experiments/forward_models.py within --episodes 100)",
                "rounding": f"scale to {SCALE_DECIMALS} decimals",
                "build": "plate-env build design-discrepancy --within "
                         "experiments/results/forward_models_within.json --out " + FILE_NAME}}


def build_design_discrepancy(within: str | Path, out: str | Path, record: dict) -> dict:
    """Write the design discrepancy from the within stage's result file to ``out`` and the build record to ``out``
    + ``.provenance.json``; returns the content. Nothing is written when the input is missing or bad."""
    try:
        numbers = read_json(within, "within results")
    except ValueError as exc:
        raise ValueError(f"{exc} (written by python experiments/forward_models.py within --episodes 100)") from None
    content = design_discrepancy(numbers)
    write_text_atomic(out, json.dumps(content, indent=1) + "\n", "--out")
    record = {**record, "artifact": "design-discrepancy", "inputs": {"within": str(within)}}
    write_text_atomic(f"{out}.provenance.json", json.dumps(record, indent=1) + "\n", "build record")
    return content


__all__: Sequence[str] = ("FILE_NAME", "FORWARD", "SCALE_DECIMALS", "build_design_discrepancy",
                          "design_discrepancy")
