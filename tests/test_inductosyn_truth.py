"""Seed 001's Fourier truth (budget.inductosyn.truth) against analytic references, its
independence from the lab's fits, and the instrument drawn per trial
(``validation.instrument_seed``)."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.special import jv

from budget.inductosyn.truth import fourier_truth, instrument_coefficients
from budget.runner.study import INSTRUMENT_SPAWN_KEY, instrument_seed_sequence
from simcam.encoder.inductosyn import INSTRUMENT_SPAWN_KEY as SIMCAM_KEY
from simcam.encoder.inductosyn import (
    Inductosyn,
    InductosynParams,
    PitchHarmonic,
    default,
    from_dict,
    pinned_instrument,
    world_encoder_params,
    world_pitch_phases_deg,
    world_pitch_terms,
)
from simcam.infra.errors import ScenarioError
from simcam.units import ARCSEC_PER_RAD

ROOT = Path(__file__).resolve().parents[1]


def _pure(order: int, amplitude: float, phase_deg: float, resolution_deg: float = 0.0) -> InductosynParams:
    """An encoder whose only error is one electrical pitch harmonic: ``A sin(j P theta + phi)``."""
    return InductosynParams(resolution_deg=resolution_deg, pitch_harmonics=(PitchHarmonic(
        domain="electrical", order=order, amplitude_arcsec=amplitude, phase_deg=phase_deg),))


def test_truth_of_a_pure_harmonic_is_keplers_bessel_series():
    """Reading r = theta + a sin(k theta) (k = P, a = A / ARCSEC_PER_RAD) is Kepler's equation
    with eccentricity -k a; its inverse gives the error as a function of the reading,
    ``e(r) = sum_n (2 / n) (-1)^(n+1) J_n(n eps) / k sin(n k r)``, ``eps = k a`` (Watson,
    *Bessel Functions*, 17.2). A = 100 arcsec: eps = 0.175, the fundamental is 0.38 % below
    A and the second harmonic is -J_2(2 eps) A / eps = -8.6 arcsec. The truth's DFT on the
    grid equals the series to its rounding (1e-9 arcsec; orders above 8 P are below 1e-12)."""
    a_arcsec, p = 100.0, 360
    eps = p * a_arcsec / ARCSEC_PER_RAD
    t = fourier_truth(encoder=_pure(1, a_arcsec, 0.0))
    c = t.coefficients(np.zeros((1, 0)))[0]  # A_L1c, A_L1s, A_L2c, A_L2s, A_S1c, A_S1s, ..., A_S4s
    series = {n: (2 / n) * (-1) ** (n + 1) * jv(n, n * eps) * a_arcsec / eps for n in range(1, 40)}
    np.testing.assert_allclose(c[4:], [0, series[1], 0, series[2], 0, series[3], 0, series[4]], atol=1e-9)
    np.testing.assert_allclose(c[:4], 0.0, atol=1e-9)
    # Parseval: the variance is sum c_n^2 / 2 over every order, resolution 0
    s3 = 3 * math.sqrt(sum(v * v / 2 for v in series.values()))
    assert t.sigma3_before_arcsec(np.zeros((1, 0)))[0] == pytest.approx(s3, rel=1e-12)


def test_quantisation_adds_q2_over_12_and_compensation_removes_the_fitted_orders():
    """With a quantum q the variance gains q^2/12 (uniform quantisation error, Widrow and
    Kollar 2008); a compensation by the exact coefficients of the fitted orders leaves only
    the orders above 4 P (the series above) and the quantisation."""
    a_arcsec, p, q_deg = 100.0, 360, 1e-4
    eps = p * a_arcsec / ARCSEC_PER_RAD
    t = fourier_truth(encoder=_pure(1, a_arcsec, 30.0, resolution_deg=q_deg))
    none = np.zeros((1, 0))
    q = q_deg * 3600
    series = [(2 / n) * jv(n, n * eps) * a_arcsec / eps for n in range(1, 40)]
    var = sum(v * v / 2 for v in series)
    assert t.sigma3_before_arcsec(none)[0] == pytest.approx(3 * math.sqrt(var + q * q / 12), rel=1e-12)
    left = sum(v * v / 2 for v in series[4:])
    got = t.sigma3_after_arcsec(none, t.coefficients(none))[0]
    assert got == pytest.approx(3 * math.sqrt(left + q * q / 12), rel=1e-9)
    # the same as the compensated series on the grid, directly (np.var), plus q^2/12
    direct = t.series_arcsec(np.zeros(0), t.coefficients(none)[0])
    assert got == pytest.approx(3 * math.sqrt(np.var(direct) + q * q / 12), rel=1e-9)


def test_instruments_first_order_against_each_instruments_exact_encoder():
    """The default world's encoder terms (0.5 arcsec third electrical harmonic, 0.3 arcsec rms
    irregular pitch error) enter the truth to first order; the neglected |g| |g'| is
    A3^2 3P pi / 648000 = 1.3e-3 arcsec. Each instrument's exact encoder (its own Fourier
    truth, no linearisation) agrees within 2e-3 arcsec in every coefficient and 3 sigma."""
    sc = default()
    t = fourier_truth(encoder=sc.encoder, terms=world_pitch_terms(scenario=sc))
    inst = [instrument_seed_sequence(None, 5, k) for k in range(3)]
    a = instrument_coefficients(np.array([world_pitch_phases_deg(scenario=sc, instrument=i) for i in inst]))
    none = np.zeros((1, 0))
    fit = t.coefficients(a) * 0.97  # a compensation near the truth
    for k in range(3):
        ex = fourier_truth(encoder=world_encoder_params(scenario=sc, instrument=inst[k]))
        np.testing.assert_allclose(t.coefficients(a[k:k + 1]), ex.coefficients(none), atol=2e-3)
        assert t.sigma3_before_arcsec(a[k:k + 1])[0] == pytest.approx(ex.sigma3_before_arcsec(none)[0], abs=2e-3)
        assert t.sigma3_after_arcsec(a[k:k + 1], fit[k:k + 1])[0] == pytest.approx(
            ex.sigma3_after_arcsec(none, fit[k:k + 1])[0], abs=2e-3)
        s = ex.series_arcsec(np.zeros(0), fit[k])
        assert t.maxabs_after_arcsec(a[k:k + 1], fit[k:k + 1])[0][0] == pytest.approx(
            np.max(np.abs(s - s.mean())), abs=1e-2)  # the max's mechanical terms at the reading too
    # the instruments differ: the third electrical harmonic's phase moves A_S3 by its 0.5 arcsec
    assert np.ptp(t.coefficients(a)[:, 8]) > 0.05


def test_truth_imports_nothing_of_the_lab():
    """The truth shares no code with the estimators: budget/inductosyn/truth.py imports no
    module of the lab (budget.*), so no design matrix or fit (ast)."""
    tree = ast.parse((ROOT / "budget" / "inductosyn" / "truth.py").read_text(encoding="utf-8"))
    mods = [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    mods += [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    assert mods and not [m for m in mods if m.startswith("budget")], mods
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
    assert not names & {"design_matrix", "HarmonicSpec", "fit_joint", "fit_harmonics"}


def test_instrument_seed_moves_to_validation():
    with pytest.raises(ScenarioError, match=r"world.instrument_seed: moved to validation.instrument_seed"):
        from_dict({"world": {"instrument_seed": 1}}, source="old.toml")
    assert SIMCAM_KEY == INSTRUMENT_SPAWN_KEY
    pinned = from_dict({"validation": {"instrument_seed": 4}})
    assert pinned_instrument(scenario=pinned).spawn_key == instrument_seed_sequence(4, 0, 9).spawn_key
    assert pinned_instrument(scenario=pinned).entropy == instrument_seed_sequence(4, 0, 9).entropy


def test_classes_follow_the_instrument_seed_and_batches_do_not_matter():
    """Unset: the instrument's truths (before, coefficient) are per trial; pinned: fixed. Trial
    k's tables and truths are the same whatever batch it runs in."""
    from budget.inductosyn.study import STUDY
    from budget.inductosyn.validate import prepare, run_trials

    sc = default()
    flags = {c.name: c.per_trial_truth for c in STUDY.classes(sc)}
    assert flags == {"before": True, "residual": True, "environment": True, "coefficient": True}
    pinned = from_dict({**sc.model_dump(mode="json", exclude_none=True), "validation": {"instrument_seed": 2}})
    flags = {c.name: c.per_trial_truth for c in STUDY.classes(pinned)}
    assert flags == {"before": False, "residual": True, "environment": True, "coefficient": False}
    p = prepare(scenario=sc, dense_step_deg=1.0)
    whole = run_trials(prepared=p, trials=6, seed=9)
    part = run_trials(prepared=p, trials=2, seed=9, first_trial=3)
    for key in ("y_long", "y_short", "y_environment", "true_coefficients", "true_sigma3_before_arcsec",
                "dense_sigma3_after_arcsec", "dense_maxabs_after_arcsec", "true_environment_sigma3_arcsec"):
        np.testing.assert_array_equal(whole[key][3:5], part[key], err_msg=key)
    assert np.ptp(whole["true_coefficients"][:, 8]) > 0.05  # A_S3c: each trial's own encoder
    pp = prepare(scenario=pinned, dense_step_deg=1.0)
    r = run_trials(prepared=pp, trials=3, seed=9)
    np.testing.assert_array_equal(r["true_coefficients"], np.broadcast_to(r["true_coefficients"][0], (3, 12)))


def test_inductosyn_reads_the_encoder_of_its_instrument():
    """The exact encoder of a trial is the scenario's plus the world's pitch terms at the
    phases of that trial's instrument."""
    sc = default()
    inst = instrument_seed_sequence(None, 1, 2)
    enc = Inductosyn(params=world_encoder_params(scenario=sc, instrument=inst))
    terms = world_pitch_terms(scenario=sc)
    phases = world_pitch_phases_deg(scenario=sc, instrument=inst)
    extra = enc.params.pitch_harmonics[len(sc.encoder.pitch_harmonics):]
    assert [h.phase_deg for h in extra] == pytest.approx(list(phases))
    assert [(h.domain, h.order, h.amplitude_arcsec) for h in extra] == [
        (t.domain, t.order, t.amplitude_arcsec) for t in terms]
