"""Tests of the inductosyn physical model and readout (simcam.encoder.inductosyn, simcam.encoder.polygon).

References: seed 001 eqs 1-6 (amplitude-discrimination readout), 7-9 (error model);
the imperfection -> harmonic mapping derived in docs/inductosyn.md.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from simcam.infra.errors import ScenarioError
from simcam.encoder.inductosyn import (
    DriftParams,
    ElectricalErrors,
    Inductosyn,
    InductosynParams,
    MechanicalErrors,
    WindingHarmonic,
    apply_drift,
    default,
    demodulated_error,
    first_order_electrical_error_rad,
    load,
    mechanical_error_rad,
    tracking_null_numeric_rad,
    tracking_null_rad,
    winding_harmonic_order_map,
)
from simcam.encoder.polygon import face_taylor, measure_polygon, nominal_face_angles_deg
from simcam.units import ARCSEC_PER_RAD

THETA_E = np.linspace(0.0, 2 * math.pi, 13, endpoint=False) + 0.1


def _numeric_delta(elec, thetas=THETA_E):
    """theta_d - theta_e from the direct simulation (carrier synthesis + brentq)."""
    return np.array([tracking_null_numeric_rad(theta_e_rad=t, elec=elec) - t for t in thetas])


# ------------------------------------------------------------------- readout (eq 5)
def test_ideal_readout_tracks_exactly():
    """Eq 5-6: with no imperfection the loop null is theta_d = theta_e."""
    elec = ElectricalErrors()
    assert np.max(np.abs(_numeric_delta(elec))) < 1e-12
    assert np.max(np.abs(tracking_null_rad(theta_e_rad=THETA_E, elec=elec) - THETA_E)) < 1e-12


def test_demodulated_error_is_sin_of_difference():
    """Eq 5: the demodulated error of an ideal inductosyn is sin(theta_e - theta_d); the
    quadrature carrier pick-up is rejected by the synchronous demodulator."""
    elec = ElectricalErrors()
    for te, td in [(0.3, 0.1), (2.0, 2.5), (5.0, 4.2)]:
        assert demodulated_error(theta_e_rad=te, theta_d_rad=td, elec=elec) == pytest.approx(
            math.sin(te - td), abs=1e-13)


def test_closed_form_null_equals_numeric_null_all_imperfections():
    """The closed-form null (atan2 + asin) equals the brentq root of the synthesised and
    demodulated carrier, with every imperfection at once (large values)."""
    elec = ElectricalErrors(excitation_imbalance=0.05, coupling_imbalance=-0.02,
                            quadrature_error_deg=2.0, offset_sin=0.08, offset_cos=-0.06,
                            demodulator_offset=0.01,
                            winding_harmonics=(WindingHarmonic(order=3, amplitude=0.01, phase_deg=40),))
    closed = tracking_null_rad(theta_e_rad=THETA_E, elec=elec) - THETA_E
    assert np.max(np.abs(closed - _numeric_delta(elec))) < 1e-11


def _fourier(delta, theta=None):
    """Fourier coefficients (c_k, s_k) of delta sampled on a full uniform period."""
    n = delta.size
    f = np.fft.rfft(delta) / n
    return 2 * f.real, -2 * f.imag


@pytest.mark.parametrize(
    "kwargs, eps",
    [
        (dict(excitation_imbalance=2e-3), 2e-3),
        (dict(coupling_imbalance=-2e-3), 2e-3),
        (dict(quadrature_error_deg=0.1), math.radians(0.1)),
        (dict(offset_sin=2e-3), 2e-3),
        (dict(offset_cos=-2e-3), 2e-3),
        (dict(demodulator_offset=2e-3), 2e-3),
        (dict(winding_harmonics=(WindingHarmonic(order=3, amplitude=2e-3, phase_deg=25),)), 2e-3),
        (dict(winding_harmonics=(WindingHarmonic(order=5, amplitude=2e-3, phase_deg=-60),)), 2e-3),
        (dict(winding_harmonics=(WindingHarmonic(order=7, amplitude=2e-3, phase_deg=10),)), 2e-3),
        (dict(excitation_imbalance=2e-3, quadrature_error_deg=0.1, offset_sin=1e-3,
              offset_cos=2e-3, winding_harmonics=(WindingHarmonic(order=3, amplitude=1e-3),)),
         2e-3 + math.radians(0.1) + 1e-3 + 2e-3 + 1e-3),
    ],
)
def test_first_order_mapping_against_direct_readout(kwargs, eps):
    """docs/inductosyn.md mapping vs the direct simulation of the readout.

    The expansion drops terms of second order in the small parameters, each with a
    coefficient of order one (at most 1 for a single parameter, e.g. the
    ``-(a^2/4) sin 4t`` term of the imbalance): the tolerance is ``2 eps^2``, with ``eps``
    the sum of the parameters' magnitudes when several act (products ``eps_i eps_j`` are
    bounded by ``(sum eps_i)^2``).
    """
    elec = ElectricalErrors(**kwargs)
    num = _numeric_delta(elec)
    first = first_order_electrical_error_rad(theta_e_rad=THETA_E, elec=elec)
    assert np.max(np.abs(num - first)) < 2 * eps**2
    # and the error is really first order: not matched by zero
    assert np.max(np.abs(num)) > 0.3 * eps


def test_mapping_remainder_is_second_order():
    """Halving every small parameter divides the expansion's error by about 4."""
    def remainder(s):
        elec = ElectricalErrors(excitation_imbalance=0.02 * s, quadrature_error_deg=1.0 * s,
                                offset_sin=0.02 * s, offset_cos=-0.01 * s,
                                winding_harmonics=(WindingHarmonic(order=3, amplitude=0.01 * s),))
        t = np.linspace(0, 2 * math.pi, 64, endpoint=False)
        exact = tracking_null_rad(theta_e_rad=t, elec=elec) - t
        return np.max(np.abs(exact - first_order_electrical_error_rad(theta_e_rad=t, elec=elec)))

    ratio = remainder(1.0) / remainder(0.5)
    assert 3.5 < ratio < 4.5


@pytest.mark.parametrize(
    "kwargs, harmonic",
    [
        (dict(offset_sin=0.01), 1),
        (dict(offset_cos=0.01), 1),
        (dict(excitation_imbalance=0.01), 2),
        (dict(quadrature_error_deg=0.5), 2),
        (dict(winding_harmonics=(WindingHarmonic(order=3, amplitude=0.01),)), 4),
        (dict(winding_harmonics=(WindingHarmonic(order=5, amplitude=0.01),)), 4),
        (dict(winding_harmonics=(WindingHarmonic(order=7, amplitude=0.01),)), 8),
    ],
)
def test_dominant_electrical_harmonic(kwargs, harmonic):
    """Each imperfection puts its error at the predicted electrical harmonic (FFT of the
    exact readout over one period): DC offset -> 1st, imbalance and quadrature -> 2nd,
    3rd/5th winding harmonic -> 4th, 7th -> 8th. Other harmonics are second order."""
    elec = ElectricalErrors(**kwargs)
    t = np.linspace(0, 2 * math.pi, 64, endpoint=False)
    d = tracking_null_rad(theta_e_rad=t, elec=elec) - t
    c, s = _fourier(d)
    amp = np.hypot(c, s)
    amp[0] = 0.0
    assert int(np.argmax(amp)) == harmonic
    others = np.delete(amp, harmonic)
    assert np.max(others) < 0.05 * amp[harmonic]


def test_winding_order_map():
    assert [winding_harmonic_order_map(order=n) for n in (3, 5, 7, 9, 11, 13)] == [4, 4, 8, 8, 12, 12]
    with pytest.raises(ValueError):
        winding_harmonic_order_map(order=4)


# ---------------------------------------------------------------- mechanical maps
def test_mechanical_maps_expansions():
    """Eccentricity: r sin u + r^2/2 sin 2u + O(r^3); ellipticity: -k sin 2u + O(k^2);
    tilt: -(alpha^2/4) sin 2u + O(alpha^4)."""
    th = np.linspace(0, 2 * math.pi, 97)
    m = MechanicalErrors(eccentricity_um=50.0, radius_mm=100.0, eccentricity_azimuth_deg=30)
    r = 5e-4
    u = th - math.radians(30)
    assert np.max(np.abs(mechanical_error_rad(theta_rad=th, mech=m)
                         - (r * np.sin(u) + r * r / 2 * np.sin(2 * u)))) < r**3
    k = 1e-4
    m = MechanicalErrors(ellipticity_ppm=100.0, ellipticity_azimuth_deg=-20)
    u = th + math.radians(20)
    assert np.max(np.abs(mechanical_error_rad(theta_rad=th, mech=m) + k * np.sin(2 * u))) < 2 * k**2
    a = math.radians(1.0)
    m = MechanicalErrors(tilt_deg=1.0, tilt_azimuth_deg=10)
    u = th - math.radians(10)
    assert np.max(np.abs(mechanical_error_rad(theta_rad=th, mech=m) + a * a / 4 * np.sin(2 * u))) < a**4


# ------------------------------------------------------------------------ encoder
def test_truth_at_reading_consistent_with_truth_at_angle():
    enc = Inductosyn(params=default().encoder)
    th = np.array([0.0, 1.2345, 47.9, 180.5, 359.99])
    r = enc.continuous_reading_deg(angle_deg=th)
    back = enc.true_angle_deg(reading_deg=r)
    assert np.max(np.abs(back - th)) * 3600 < 1e-8
    e1 = enc.error_arcsec(angle_deg=th)
    e2 = enc.error_at_reading_arcsec(reading_deg=r)
    assert np.max(np.abs(e1 - e2)) < 1e-8


def test_encoder_electrical_error_maps_to_mechanical_by_pole_pairs():
    """An electrical error delta (rad electrical) is delta/P rad mechanical."""
    elec = ElectricalErrors(offset_sin=0.01)
    enc = Inductosyn(params=InductosynParams(pole_pairs=360, resolution_deg=0, electrical=elec))
    th = np.array([10.0, 10.25, 10.5])  # electrical phases 0, 90, 180 deg
    e = enc.error_arcsec(angle_deg=th)
    te = 2 * math.pi * np.array([0.0, 0.25, 0.5])
    expect = (tracking_null_rad(theta_e_rad=te, elec=elec) - te) / 360 * ARCSEC_PER_RAD
    assert np.max(np.abs(e - expect)) < 1e-7


def test_default_scenario_resembles_seed_001():
    """Default unit: ~145 arcsec 3 sigma short-period (23 faces) and a few arcsec long
    period (24 faces), as in seed 001 Tables 1 and 2 (2.7 and 145.6 arcsec)."""
    enc = Inductosyn(params=default().encoder)
    e23 = enc.error_at_reading_arcsec(reading_deg=nominal_face_angles_deg(faces=23))
    e24 = enc.error_at_reading_arcsec(reading_deg=nominal_face_angles_deg(faces=24))
    # The paper's figures are 3 x a sample sd of n = 23 / 24 points: their relative standard
    # error is 1 / sqrt(2 (n - 1)) (normal theory), so the default unit (whose error on the
    # nominal faces is deterministic) agrees when within 2 of those standard errors.
    s23, s24 = 3 * np.std(e23, ddof=1), 3 * np.std(e24, ddof=1)
    assert abs(s23 / 145.6 - 1) < 2 / math.sqrt(2 * 22)
    assert abs(s24 / 2.7 - 1) < 2 / math.sqrt(2 * 23)
    # what matters: the short-period error is an order of magnitude above the long one
    # (seed 001 section 4: "要提高一个量级")
    assert s23 > 10 * s24


def test_unknown_key_and_bad_values_are_scenario_errors(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text("[encoder.electrical]\noffset_sinn = 0.1\n")
    with pytest.raises(ScenarioError, match=r"s.toml: encoder.electrical.offset_sinn: unknown key"):
        load(str(p))
    p.write_text("[encoder]\nresolution_deg = -1\n")
    with pytest.raises(ScenarioError, match="encoder.resolution_deg"):
        load(str(p))
    p.write_text("[encoder.electrical]\nwinding_harmonics = [{order = 4, amplitude = 0.01}]\n")
    with pytest.raises(ScenarioError, match="winding_harmonics.0.order"):
        load(str(p))


def test_non_monotonic_reading_is_refused(tmp_path):
    p = tmp_path / "s.toml"
    """A 7th winding harmonic of 19% makes the Lissajous figure of the two channels loop
    back (7 h > 1): the reading would run backwards, and the scenario is refused."""
    p.write_text("[encoder.electrical]\noffset_sin = 0.3\n"
                 "winding_harmonics = [{order = 7, amplitude = 0.19}]\n")
    with pytest.raises(ScenarioError, match="not monotonic"):
        load(str(p))


# ---------------------------------------------------------------- quantisation
def test_quantisation_residual_is_uniform():
    """Compensating with the exact truth leaves only the quantisation: for a reading of
    slope 1 (mechanical errors only, slope 1 + O(1e-5)) the residual at random angles is
    uniform on [-q/2, q/2]: variance q^2/12. Sampling distribution of the sample variance
    of N uniform draws: sd = q^2 sqrt((1/80 - 1/144)/N); bound 5 sd. KS test p > 1e-3."""
    params = InductosynParams(resolution_deg=1e-4,
                              mechanical=MechanicalErrors(eccentricity_um=0.5, ellipticity_ppm=3))
    enc = Inductosyn(params=params)
    rng = np.random.default_rng(np.random.SeedSequence(2024))
    n = 20000
    th = rng.uniform(0, 360, n)
    r = enc.reading_deg(angle_deg=th)  # quantised, no noise
    resid_arcsec = (enc.true_angle_deg(reading_deg=r) - th) * 3600
    q = 0.36
    assert np.max(np.abs(resid_arcsec)) <= q / 2 * (1 + 1e-4)
    var = np.var(resid_arcsec, ddof=1)
    sd_var = q**2 * math.sqrt((1 / 80 - 1 / 144) / n)
    assert abs(var - q**2 / 12) < 5 * sd_var
    assert stats.kstest(resid_arcsec / q + 0.5, "uniform").pvalue > 1e-3


# ---------------------------------------------------------------- polygon rig
def test_polygon_measurement_noise_free_is_truth_at_reading():
    """A perfect rig (no noise, no face error, no offset, continuous readings) writes
    down exactly the truth at the reading."""
    from simcam.encoder.inductosyn import AutocollimatorParams, PolygonParams

    sc = default()
    enc = Inductosyn(params=sc.encoder.model_copy(update={"resolution_deg": 0.0,
                                                           "reading_noise_arcsec": 0.0}))
    poly = PolygonParams(faces=23)
    tab = measure_polygon(encoder=enc, polygon=poly, autocollimator=AutocollimatorParams(),
                          face_errors_arcsec=np.zeros(23), rng=np.random.default_rng(1))
    truth = enc.error_at_reading_arcsec(reading_deg=nominal_face_angles_deg(faces=23))
    assert np.max(np.abs(tab.error_arcsec.to_numpy() - truth)) < 1e-8


def test_face_taylor_matches_exact_inverse():
    """The fast path's second-order expansion about each face agrees with the exact
    inverse map for displacements up to 1 arcsec (truncation |d|^3 f'''/6 < 1e-6)."""
    enc = Inductosyn(params=default().encoder)
    ft = face_taylor(encoder=enc, faces=23, step_arcsec=0.36)
    for d in (-1.0, -0.18, 0.05, 0.5, 1.0):
        exact = (enc.true_angle_deg(reading_deg=ft.angles_deg + d / 3600) - ft.angles_deg) * 3600
        assert np.max(np.abs(ft.true_offset_arcsec(d_arcsec=np.full(23, d)) - exact)) < 1e-6


def test_drift_is_seeded_and_moves_parameters():
    sc = default()
    a = apply_drift(params=sc.encoder, drift=sc.drift, seed=5)
    b = apply_drift(params=sc.encoder, drift=sc.drift, seed=5)
    c = apply_drift(params=sc.encoder, drift=sc.drift, seed=6)
    assert a == b and a != c and a != sc.encoder
    assert apply_drift(params=sc.encoder, drift=DriftParams(), seed=5) == sc.encoder


def test_sign_conventions():
    """Signs: error = reading - true angle. A positive in-phase feed-through on the sine
    channel (o_s > 0) makes the reading run ahead at electrical phase 0 (delta = +o_s);
    an eccentricity toward azimuth 0 makes the scale lead at shaft angle 90 deg
    (+r sin u); the rig writes the truth's sign (-autocollimator reading)."""
    enc = Inductosyn(params=InductosynParams(resolution_deg=0.0,
                                             electrical=ElectricalErrors(offset_sin=1e-3)))
    e = enc.error_arcsec(angle_deg=np.array([20.0]))[0]
    assert e == pytest.approx(1e-3 / 360 * ARCSEC_PER_RAD, rel=1e-3) and e > 0
    enc = Inductosyn(params=InductosynParams(resolution_deg=0.0, mechanical=MechanicalErrors(
        eccentricity_um=1.0, radius_mm=100.0)))
    assert enc.error_arcsec(angle_deg=np.array([90.0]))[0] == pytest.approx(1e-5 * ARCSEC_PER_RAD, rel=1e-4)
    assert enc.error_arcsec(angle_deg=np.array([270.0]))[0] < 0
