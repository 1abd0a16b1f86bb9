"""Seed 003's claims ledger (budget.scanmirror.claims) evaluated on runs of both worlds of the
embedded default: small runs here (8 trials each, fixed seed), the full-size run (200 trials)
behind ``slow``."""

from __future__ import annotations

import numpy as np
import pytest

from budget.runner.claims import WORLDS, ledger_runs, study_claims
from budget.runner.numbers import fmt
from budget.scanmirror.claims import CLAIMS, DEFAULT_SCENARIO, FIGURES_DEG
from budget.scanmirror.study import STUDY
from claims_checks import (assert_ledger_table, assert_outcome_follows_numbers, assert_worlds,
                          judged, ledger_of, outcomes)


@pytest.fixture(scope="module")
def small():
    return ledger_of(STUDY, None, 8, 3)


def _check_ledger(claims, runs, results, trials: int) -> None:
    """The ledger's structure, and every verdict against its own numbers and the runs'."""
    assert claims == CLAIMS and len(claims) == 10
    assert ledger_runs(claims) == ((DEFAULT_SCENARIO, "seed"), (DEFAULT_SCENARIO, "realistic"))
    assert_worlds(runs)
    for r in judged(claims, results):
        c = r.claim
        run, v = runs[(c.scenario, r.world)], r.verdict
        if c.kind == "bound":
            t = np.asarray(run.trial_truths[("compensated_max", "improved", c.axis)])
            assert (v.estimate, v.n) == (pytest.approx(t.mean(), rel=1e-12), trials)
            assert v.se == pytest.approx(t.std(ddof=1) / np.sqrt(trials), rel=1e-9)
            assert v.tolerance.high == FIGURES_DEG[c.axis]
        else:
            st = run.statistics((c.class_name, "published", c.axis))
            assert (v.estimate, v.se, v.n) == (st["bias"], st["se_bias"], trials)
            half = 1.0 if c.class_name == "dtau" else FIGURES_DEG[c.axis]
            assert (v.tolerance.low, v.tolerance.high) == pytest.approx((-half, half))
        assert_outcome_follows_numbers(r, -np.inf if c.kind == "bound" else v.tolerance.low, v.tolerance.high)
        assert fmt(v.estimate) in r.sentence
    assert_ledger_table(claims, results)


def test_ledger_on_small_runs(small):
    claims, runs, results = small
    _check_ledger(claims, runs, results, 8)
    got = outcomes(results)
    # far from their tolerances' edges whatever the draw (measured at 20 and 200 trials,
    # docs/claims.md): the one-star estimate misses the deviation by 6-9 arcsec (the
    # catalogue's 20-arcsec aberration, first order; se 0.2 in the seed's world), the
    # paper's chain leaves 0.021 / 0.033 deg (lat / lon; se < 0.002 at 8 trials), and the
    # improved chain leaves 0.0015 deg of latitude in the seed's world and 0.011-0.013 deg
    # in the realistic one (se < 0.0015 at 8 trials)
    for ax in ("x", "y"):
        assert got[(f"dtau.{ax}.method", "seed")] == "fails"
    assert got[("dtau.y.method", "realistic")] == "fails"
    for ax in ("lon", "lat"):
        for w in WORLDS:
            assert got[(f"scan2.{ax}.published", w)] == "fails"
        assert got[(f"scan2.{ax}.bound", "realistic")] == "fails"
    assert got[("scan2.lat.bound", "seed")] == "holds"


def test_compensated_max_truth_is_the_worlds_error_and_the_lab_believes_it_zero(small):
    """The bound class's truth is the world's largest error of the improved chain (the same
    number as ground_max's improved estimate, the world's); its estimate, the lab's own
    model's, is 0 to the Newton tolerance (1e-13 rad of scan angle, ~1e-10 deg on the ground)."""
    _, runs, _ = small
    for res in runs.values():
        for ax in ("lat", "lon"):
            t = np.asarray(res.trial_truths[("compensated_max", "improved", ax)])
            np.testing.assert_array_equal(t, np.asarray(res.samples[("ground_max", "improved", ax)]))
            assert np.abs(res.samples[("compensated_max", "improved", ax)]).max() < 1e-9


def test_scanmirror_declares_its_claims():
    assert study_claims(STUDY, STUDY.load_scenario(None)) == CLAIMS
    assert STUDY.load_scenario(DEFAULT_SCENARIO) == STUDY.load_scenario(None)
    untestable = {c.id for c in CLAIMS if not c.testable}
    assert untestable == {"scan1.uncompensated", "scan1.without_estimate", "compensation.angles", "parameters.nine"}


@pytest.mark.slow
def test_ledger_full_size():
    """200 trials a world (as issue #33 measured): the structure and agreement, and the
    headline: the 0.003 deg longitude bound fails in the realistic world by about four times
    (0.012 deg: the scan angles read through seed 001's compensated inductosyns) and the
    0.006 deg latitude bound by about twice, while both hold in the seed's own world."""
    claims, runs, results = ledger_of(STUDY, None, 200, 0)
    _check_ledger(claims, runs, results, 200)
    got = outcomes(results)
    for ax in ("lon", "lat"):
        assert got[(f"scan2.{ax}.bound", "realistic")] == "fails"
        assert got[(f"scan2.{ax}.bound", "seed")] == "holds"
        for w in WORLDS:
            assert got[(f"scan2.{ax}.published", w)] == "fails"
    for ax in ("x", "y"):
        for w in WORLDS:
            assert got[(f"dtau.{ax}.method", w)] == "fails"
    lon = {r.world: r.verdict.estimate for r in results if r.claim.id == "scan2.lon.bound"}
    assert 3.0 < lon["realistic"] / FIGURES_DEG["lon"] < 5.5
