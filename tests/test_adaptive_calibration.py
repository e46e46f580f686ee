"""The feature line's mixture prior over labs (issue 36, plate_env.identify.adaptive_calibration.FeatureMixture):
references that line up like one lab select its component; references that do not, don't; a family's labs can be
taken out of the prior; calibration files from before the mixture are refused by name."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from plate_env.identify import lab_calibration_file as lcf
from plate_env.identify.adaptive_calibration import (
    FEATURE_PRIOR,
    LOG_OMEGA_GRID,
    FeatureMixture,
    FeaturePrior,
    feature_cdf,
    fit_feature_line,
)

WIDE = FeaturePrior((4.0, -0.1, 5.0), ((0.5, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, 0.0, 40.0)), 0.25, 1.5)
TIGHT = FeaturePrior((3.6, 0.1, 3.6), ((0.25, 0.0, 0.0), (0.0, 0.003, 0.0), (0.0, 0.0, 1.0)), 0.08, 0.75)
LOOSE = FeaturePrior((4.2, -0.2, 6.0), ((0.25, 0.0, 0.0), (0.0, 0.003, 0.0), (0.0, 0.0, 1.0)), 0.35, 0.75)
MIX = FeatureMixture((WIDE, TIGHT, LOOSE), (0.5, 0.25, 0.25), ("broad", "tight", "loose"))


def lab_discs(beta, sigma, n, rng):
    """``n`` discs of a lab whose log omega_n is ``beta . (1, f0 - 26, log(w / 600))`` plus ``sigma`` noise."""
    f0 = rng.uniform(24.0, 30.0, n)
    wm = 600.0 * np.exp(0.15 * (f0 - 26.0) / 3.0 + 0.03 * rng.standard_normal(n))
    x = np.c_[np.ones(n), f0 - 26.0, np.log(wm / 600.0)]
    return [(float(a), float(b)) for a, b in zip(f0, wm, strict=True)], x @ np.asarray(beta) + sigma * \
        rng.standard_normal(n)


def width95(line, f) -> float:
    """The predictive's 95 % width as a share of its median."""
    lo, med, hi = np.interp([0.025, 0.5, 0.975], feature_cdf(line, f), LOG_OMEGA_GRID)
    return math.exp(hi - med) - math.exp(lo - med)


def test_references_that_line_up_select_the_tight_component():
    """Five references of a lab on the tight component's line (scatter 0.05) give that component most of the
    posterior weight (prior 1/4) and intervals narrower than the broad prior alone gives them; five references of a
    loose lab (scatter 0.35 about another line) take weight away from it."""
    rng = np.random.default_rng(3)
    feats, y = lab_discs(TIGHT.mean, 0.05, 5, rng)
    line = fit_feature_line(MIX, feats, y)
    assert line.component[1] > 0.6
    broad = fit_feature_line(WIDE, feats, y)
    assert width95(line, feats[0]) < 0.8 * width95(broad, feats[0])  # 0.28 vs 0.40
    feats, y = lab_discs(LOOSE.mean, 0.35, 5, rng)
    assert fit_feature_line(MIX, feats, y).component[1] < 0.25


def test_a_one_component_mixture_is_the_single_prior():
    rng = np.random.default_rng(4)
    feats, y = lab_discs(TIGHT.mean, 0.1, 3, rng)
    a, b = fit_feature_line(WIDE, feats, y), fit_feature_line(FeatureMixture((WIDE,), (1.0,)), feats, y)
    assert np.allclose(a.weight, b.weight) and np.allclose(a.mean, b.mean)


def test_without_takes_a_family_out_and_renormalises():
    m = MIX.without(["tight"])
    assert m.labels == ("broad", "loose") and np.allclose(m.weights, (2 / 3, 1 / 3))
    with pytest.raises(ValueError, match="components are"):
        MIX.without(["rigid"])
    with pytest.raises(ValueError, match="at least one"):
        MIX.without(["broad", "tight", "loose"])
    assert "rigid" in FEATURE_PRIOR.labels and "rigid" not in FEATURE_PRIOR.without(["rigid"]).labels
    with pytest.raises(ValueError, match="weights"):
        FeatureMixture((WIDE, TIGHT), (0.5, 0.6))


def test_a_schema_2_file_is_refused_naming_the_command(tmp_path):
    """Schema 3 made the feature line's prior a mixture; a schema-2 file (one normal prior) is refused, naming the
    command that writes a new one."""
    d = lcf.load(lcf.PAPER).to_json()
    d.pop("content_sha256")
    d["schema_version"] = 2
    d["feature_prior"] = WIDE.to_json()
    path = tmp_path / "v2.json"
    path.write_text(json.dumps({**d, "content_sha256": lcf.content_hash(d)}))
    with pytest.raises(lcf.CalibrationError, match="schema_version 2.*run plate-env calibrate again"):
        lcf.load(path)
