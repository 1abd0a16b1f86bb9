"""Seed 000's claims ledger (budget.starcam.claims) evaluated on runs of both worlds of both
embedded cameras: small runs here (10 trials each), the full-size run behind ``slow``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from budget.runner.claims import (WORLDS, Claim, ToleranceRule, evaluate_claims, ledger_runs,
                                  study_claims)
from budget.runner.numbers import fmt
from budget.starcam.claims import DEFAULT_SCENARIO, NOISY_SCENARIO, UNIT
from budget.starcam.study import STUDY
from claims_checks import (assert_ledger_table, assert_outcome_follows_numbers, assert_worlds,
                          judged, ledger_of, outcomes)
CLASSES = ("te", "hsfe", "lsfe_s", "lsfe_c1", "total")
#: the paper's printed figures (x, y), arcsec, 3 sigma
FIGURES = {"te": (1.14, 1.23), "hsfe": (1.08, 1.01), "lsfe_s": (0.03, 0.66), "lsfe_c1": (0.29, 0.41),
           "total": (1.76, 1.95)}


@pytest.fixture(scope="module")
def small():
    return ledger_of(STUDY, None, 10, 11)


def _check_ledger(claims, runs, results, trials: int) -> None:
    """The ledger's structure, and every verdict against its own numbers and the runs'."""
    assert len(claims) == 21
    assert ledger_runs(claims) == ((NOISY_SCENARIO, "seed"), (NOISY_SCENARIO, "realistic"),
                                   (DEFAULT_SCENARIO, "seed"), (DEFAULT_SCENARIO, "realistic"))
    assert_worlds(runs)
    by_id = {c.id: c for c in claims}
    for cls in CLASSES:
        for ax, fig in zip(("x", "y"), FIGURES[cls]):
            perf, meth = by_id[f"{cls}.{ax}.performance"], by_id[f"{cls}.{ax}.method"]
            assert (perf.kind, perf.scenario, perf.class_name, perf.figures) == (
                "performance", NOISY_SCENARIO, cls, (fig,))
            assert (meth.kind, meth.scenario, meth.class_name, meth.variant) == (
                "method", DEFAULT_SCENARIO, cls, "published")
    att = by_id["attitude.eq32"]
    assert att.figures == (0.56, 0.62)
    assert att.untestable == "judged on the sky by the attitude study, whose ledger holds it (budget claims)"
    assert len(results) == 2 * len(claims)
    for r in judged(claims, results):
        c = r.claim
        run = runs[(c.scenario, r.world)]
        v = r.verdict
        if c.kind == "performance":
            key = (c.class_name, "published", c.axis)
            if key in run.trial_truths:  # each trial's camera's own: their mean, se over the cameras
                t = np.asarray(run.trial_truths[key])
                se = math.hypot(t.std(ddof=1) / math.sqrt(t.size), run.trial_truth_se.get(key, 0.0))
                assert (v.estimate, v.se, v.n) == (pytest.approx(t.mean(), rel=1e-12), pytest.approx(se, rel=1e-9),
                                                   trials)
            else:
                t = run.truths[(c.class_name, c.axis)]
                assert (v.estimate, v.se, v.n) == (t.value, t.se, None)
            half = max(0.1 * c.figures[0], 0.1)
            assert (v.tolerance.low, v.tolerance.high) == pytest.approx((c.figures[0] - half, c.figures[0] + half))
        else:
            st = run.statistics((c.class_name, "published", c.axis))
            assert (v.estimate, v.se, v.n) == (st["bias"], st["se_bias"], trials)
            assert (v.tolerance.low, v.tolerance.high) == pytest.approx((-0.1 * st["truth"], 0.1 * st["truth"]))
        want = assert_outcome_follows_numbers(r)
        assert fmt(v.estimate) in r.sentence and fmt(v.se) in r.sentence
        if want == "undetermined" and not v.on_edge and v.n is not None:
            assert f"about {v.n_to_settle} trials would settle it" in r.sentence
    for c, line in zip(claims, assert_ledger_table(claims, results)):
        assert " / ".join(fmt(f) for f in c.figures) in line


def test_ledger_on_small_runs(small):
    claims, runs, results = small
    _check_ledger(claims, runs, results, 10)
    got = outcomes(results)
    # far from their tolerances' edges, whatever the draw: the truths of the paper's noisy
    # camera (TE 1.17 / 1.26 against 1.14 / 1.23; LSFE-S 0.49 / 0.04 against the printed
    # 0.03 / 0.66), the published TE within 1 % of its truth, eq 16 at -34 % / -47 % of its
    # truth. HSFE y over cameras (each trial's pixel maps) is 0.98 +- 0.05 at these 10 trials
    # (0.85-1.37 between cameras) against the paper's 1.01: inside its tolerance band, so not
    # "fails" (the scenario seed's one camera had 0.78 and failed)
    for w in WORLDS:
        assert got[("te.x.performance", w)] == got[("te.y.performance", w)] == "holds"
        assert got[("hsfe.y.performance", w)] in ("holds", "undetermined")
        assert got[("lsfe_s.x.performance", w)] == got[("lsfe_s.y.performance", w)] == "fails"
        assert got[("te.x.method", w)] == got[("te.y.method", w)] == "holds"
        assert got[("lsfe_s.x.method", w)] == got[("lsfe_s.y.method", w)] == "fails"
    # LSFE-C1 over the whole field, each trial's camera's own (issue #33): in the realistic world
    # 1.81" / 0.91" over cameras against the paper's 0.29 / 0.41 and eq 29's 0.35 / 0.39 from the
    # grid's points (the single star in the seed's world, y, is near its tolerance's edge
    # since HSFE y is each camera's own: not asserted)
    assert got[("lsfe_c1.x.performance", "realistic")] == got[("lsfe_c1.y.performance", "realistic")] == "fails"
    assert got[("lsfe_c1.x.method", "realistic")] == got[("lsfe_c1.y.method", "realistic")] == "fails"


def test_an_input_class_has_no_verdict(small):
    _, runs, _ = small
    c2 = Claim(id="c2", words="the markers are known to 0.5 arcsec", figures=(0.5,), unit=UNIT, axis="x",
               condition="", section="section 1.4.3", kind="method", scenario=DEFAULT_SCENARIO,
               class_name="lsfe_c2", variant="published", tolerance=ToleranceRule(reason="10 %", relative=0.1))
    res = evaluate_claims([c2], runs)
    assert all(r.verdict is None and r.no_verdict == "an input of the method, taken as given" for r in res)


def test_starcam_declares_its_claims():
    assert study_claims(STUDY, STUDY.load_scenario(None)) == study_claims(STUDY, STUDY.load_scenario(NOISY_SCENARIO))


@pytest.mark.slow
def test_ledger_full_size():
    """The scenarios' own trial counts (200) and truth sizing: the same structure and agreement,
    and the performance verdicts, decided by truths far from their tolerances' edges (LSFE-C1 y
    in the seed's world, 0.516 +- 0.007 over 600 cameras against the edge 0.51, is left out)."""
    claims, runs, results = ledger_of(STUDY, None, None, 0)
    _check_ledger(claims, runs, results, 200)
    got = outcomes(results)
    # LSFE-C1 over the whole field, each trial's camera's own (issue #33): 0.553 / 0.516 over
    # cameras in the seed's world against the paper's 0.29 / 0.41 +- 0.1; 1.82 / 0.92 in the
    # realistic world, and the single star with it (2.48 / 1.85 against 1.76 / 1.95 +- 10 %)
    # HSFE over cameras (each trial's pixel maps): 0.95 / 0.94 against 1.08 / 1.01 +- 10 %
    holds = {"seed": {"te.x", "te.y", "hsfe.y", "total.x"},
             "realistic": {"te.x", "te.y", "hsfe.y", "total.y"}}
    for cls in CLASSES:
        for ax in ("x", "y"):
            for w in WORLDS:
                if (cls, ax, w) == ("lsfe_c1", "y", "seed"):
                    continue
                want = "holds" if f"{cls}.{ax}" in holds[w] else "fails"
                assert got[(f"{cls}.{ax}.performance", w)] == want, (cls, ax, w)
