"""Seed 001's claims ledger (budget.inductosyn.claims) evaluated on runs of both worlds of the
embedded default: small runs here (20 trials), the scenario's own size behind ``slow``."""

from __future__ import annotations

import pytest

from budget.inductosyn.claims import CLAIMS, DEFAULT_SCENARIO
from budget.inductosyn.study import STUDY
from budget.runner.claims import WORLDS, ledger_runs, study_claims
from budget.runner.numbers import fmt
from claims_checks import (assert_ledger_table, assert_outcome_follows_numbers, assert_worlds,
                          judged, ledger_of, outcomes)

COEFFICIENTS = ("A_L1c", "A_L1s", "A_L2c", "A_L2s", "A_S1c", "A_S1s", "A_S2c", "A_S2s")


@pytest.fixture(scope="module")
def small():
    return ledger_of(STUDY, None, 20, 11)


def _half_width(c, run) -> tuple[float, float]:
    """The tolerance's edges, from the rules of docs/claims.md (independently of ToleranceRule)."""
    if c.kind == "performance":
        w = max(0.1 * c.figures[0], 0.1)
        return c.figures[0] - w, c.figures[0] + w
    truth = run.statistics((c.class_name, c.variant, c.axis))["truth"]
    w = max(0.1 * abs(truth), 0.1 if c.class_name == "coefficient" else 0.0)
    return -w, w


def _check_ledger(claims, runs, results, trials: int) -> None:
    """The ledger's structure, and every verdict against its own numbers and the runs'."""
    assert len(claims) == 26 and claims == CLAIMS
    assert ledger_runs(claims) == ((DEFAULT_SCENARIO, "seed"), (DEFAULT_SCENARIO, "realistic"))
    assert_worlds(runs)
    by_id = {c.id: c for c in claims}
    for cid, cls, fig in (("short.before", "before", 145.6), ("short.after", "residual", 2.7),
                          ("environment", "environment", 5.4)):
        perf, meth = by_id[f"{cid}.performance"], by_id[f"{cid}.method"]
        assert (perf.kind, perf.class_name, perf.figures) == ("performance", cls, (fig,))
        assert (meth.kind, meth.class_name, meth.variant) == ("method", cls, "published")
    for name in COEFFICIENTS:
        for var in ("published", "improved"):
            c = by_id[f"{name}.{var}"]
            assert (c.kind, c.class_name, c.axis, c.variant) == ("method", "coefficient", name, var)
    untestable = {c.id for c in claims if not c.testable}
    assert untestable == {"long.sigma3", "short.gain", "manufacturing", "flight.mosaic"}
    for r in judged(claims, results):
        c = r.claim
        run = runs[(c.scenario, r.world)]
        v = r.verdict
        if c.kind == "performance":
            # per-trial truths (each trial's instrument): their mean and sd / sqrt(n)
            t = run.statistics((c.class_name, "published", c.axis))
            assert v.estimate == pytest.approx(t["truth"], rel=1e-12) and v.n == trials
            assert v.se == pytest.approx(t["truth_sd"] / trials**0.5, rel=1e-9, abs=1e-15)
        else:
            st = run.statistics((c.class_name, c.variant, c.axis))
            assert (v.estimate, v.se, v.n) == (st["bias"], st["se_bias"], trials)
        lo_t, hi_t = _half_width(c, run)
        assert (v.tolerance.low, v.tolerance.high) == pytest.approx((lo_t, hi_t))
        assert_outcome_follows_numbers(r, lo_t, hi_t)
        assert fmt(v.estimate) in r.sentence
    assert_ledger_table(claims, results)


def test_ledger_on_small_runs(small):
    claims, runs, results = small
    _check_ledger(claims, runs, results, 20)
    got = outcomes(results)
    # far from their tolerances' edges whatever the draw: the truth before compensation
    # (142.9 against 131 to 160, a property of the encoder: its per-instrument sd is 0.007),
    # the 23-face table's bias (+2.2 % +- 0.02 % against 10 %), the first electrical
    # harmonics (17.06 and -64.70, their sd over trials 0.1 against a tolerance of 1.7 / 6.5)
    for w in WORLDS:
        assert got[("short.before.performance", w)] == "holds"
        assert got[("short.before.method", w)] == "holds"
        for var in ("published", "improved"):
            assert got[(f"A_S1c.{var}", w)] == got[(f"A_S1s.{var}", w)] == "holds"


def test_inductosyn_declares_its_claims():
    assert study_claims(STUDY, STUDY.load_scenario(None)) == CLAIMS
    assert STUDY.load_scenario(DEFAULT_SCENARIO) == STUDY.load_scenario(None)


@pytest.mark.slow
def test_ledger_full_size():
    """The scenario's own trial count (1000): the same structure and agreement; the verdicts
    whose intervals lie far from their edges at this size (docs/claims.md, seed 001's
    ledger): the performance before (142.9 in 131 to 160), after the environment (4.0 / 4.3
    +- 0.03 against 4.86 to 5.94: fails), after compensation in the realistic world (2.83 +-
    0.008 in 2.43 to 2.97), and every method claim (biases within 5 % of their truths, se
    below 1 %): the improved A_L2s holds (+0.020 +- 0.002 against 0.1), where the
    significance rule called it biased at 200 trials and recovered at 100."""
    claims, runs, results = ledger_of(STUDY, None, 1000, 0)
    _check_ledger(claims, runs, results, 1000)
    got = outcomes(results)
    for w in WORLDS:
        assert got[("short.before.performance", w)] == "holds"
        assert got[("environment.performance", w)] == "fails"
        for c in claims:
            if c.kind == "method" and c.testable:
                assert got[(c.id, w)] == "holds", (c.id, w)
    assert got[("short.after.performance", "realistic")] == "holds"
