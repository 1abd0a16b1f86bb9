"""The whiskbroom truth (budget.whiskbroom.truth) by its own route: the ray-traced residual
against analytic cases, against the paper's chain, and a source check that it imports nothing
of the predictions."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from budget.whiskbroom import truth as wt
from simcam.whiskbroom import geometry as geo
from simcam.whiskbroom import scenario as wsc
from simcam.whiskbroom import synthesis as sy

ROOT = Path(__file__).resolve().parents[2]
#: what the truth must not import: the predictions and the paper's chain that gives their eps, eta
FORBIDDEN = ("budget.whiskbroom.estimators", "simcam.whiskbroom.synthesis", "simcam.whiskbroom.geometry")


def _rows(k: int = 3):
    sc = wsc.default()
    draws = sy.standard_draws(sc, sy.trial_uniforms(0, [k]))
    know, true = sy.trial_params(sc, draws, [k])
    return sc, know[0], true[0]


def test_truth_imports_nothing_of_the_predictions():
    src = (ROOT / "budget/whiskbroom/truth.py").read_text()
    names = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            names.add(node.module or "")
            names |= {f"{node.module}.{a.name}" for a in node.names}
    bad = {n for n in names for f in FORBIDDEN if n == f or n.startswith(f + ".")}
    assert not bad, bad
    # and no dynamic import
    assert "importlib" not in src and "__import__" not in src


def test_zero_knowledge_error_gives_zero_smear():
    _, _, true = _rows()
    x1, x3 = np.array([0.0, 10.0]), np.array([0.0, -5.0])
    eps, eta, _ = wt.smear_truth(geo.PARAMS, true, true, x1, x3, 0.0)
    # the same ray trace both sides: equal to rounding (a few ulps of 1)
    np.testing.assert_allclose(eps, 0.0, atol=1e-14)
    np.testing.assert_allclose(eta, 0.0, atol=1e-14)


@pytest.mark.parametrize("rel", [1e-3, -5e-4])
def test_focal_length_knowledge_error_is_the_ratio(rel):
    """At the image centre the line of sight does not depend on f, and a pinhole's image
    (x = -f d1/d2) moves in proportion to f: a knowledge f (1 + rel) clocks the charge at
    (1 + rel) V_true along the same direction, so eps = 1/(1 + rel) - 1 and eta = 0 exactly; the
    ray trace's central difference errs by 6e-11 of V on each side (raytrace's step study)."""
    _, _, true = _rows()
    know = true.copy()
    know[geo.P["focal_length_mm"]] *= 1.0 + rel
    eps, eta, _ = wt.smear_truth(geo.PARAMS, know, true, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(eps, 1.0 / (1.0 + rel) - 1.0, rtol=0, atol=2e-10)
    np.testing.assert_allclose(eta, 0.0, atol=2e-10)


def test_ray_traced_smear_is_the_papers_on_its_sphere():
    """Two routes, no shared code: the truth's (eps, eta) and the synthesis's agree to the ray
    trace's error (6e-11 of V per side, so 2e-10 in eps)."""
    sc, know, true = _rows(5)
    x1, x3 = sy.field_points(sc)
    r = sy.evaluate(know[None, :], true[None, :], x1[:5], x3[:5], backend="numpy")
    i = int(r.worst[0])
    eps, eta, _ = wt.smear_truth(geo.PARAMS, know, true, x1[i], x3[i], 0.0)
    assert eps[0] == pytest.approx(float(r.eps[0]), abs=2e-10)
    assert eta[0] == pytest.approx(float(r.eta[0]), abs=2e-10)


def test_stage_limit_truth():
    thr = 0.95
    assert wt.stage_limit_truth([0.99, 0.97, 0.96, 0.94, 0.99], thr) == 3   # the first failure ends the run
    assert wt.stage_limit_truth([0.99, 0.95], thr) == 2                     # at the threshold passes
    assert wt.stage_limit_truth([0.90, 0.99], thr) == 0
    assert wt.stage_limit_truth(np.ones(7), thr) == 7


def test_a_pinned_instrument_is_refused_in_one_line():
    from budget.runner.run import run_study
    from budget.whiskbroom.study import STUDY
    from simcam.infra.errors import ScenarioError

    sc = STUDY.load_scenario(None)
    sc = sc.model_copy(update={"validation": sc.validation.model_copy(update={"instrument_seed": 3})})
    with pytest.raises(ScenarioError) as e:
        run_study(STUDY, sc, trials=2, seed=0, workers=1)
    assert "\n" not in str(e.value) and "validation.instrument_seed: the whiskbroom study draws no" in str(e.value)
