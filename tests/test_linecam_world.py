"""The world of seed 004 (simcam.linecam): camera models, apparent places, TDI imaging.

Independent references: the forward model against its own inverse written differently
(Newton inverse of simcam.distortion vs the explicit Brown correction), astropy/ERFA for the
apparent places, the analytic mid-exposure position of a moving star and photutils'
centroid for the TDI rendering, Pecaut & Mamajek (2013) temperatures for the colour
relation, Pogson's ratio for the signal chain.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from simcam.infra.errors import ScenarioError
from simcam.linecam import signal
from simcam.linecam.attitude import orbit_state, rodrigues, scan_plan
from simcam.linecam.camera import camera_truth, draw_errors, sample_y_mm
from simcam.linecam.scenario import from_dict, default
from simcam.linecam.world import crossing_times, image_passes, sky_strip
from simcam.units import ARCSEC_PER_RAD

SC = default()


def _angle(a, b):
    """Angle between unit vectors, accurate near 0 (atan2 of |a x b| and a . b)."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def _truth(seed=3, scale=1.0):
    th = draw_errors(SC, np.random.default_rng(seed)) * scale
    return camera_truth(SC, th)


def test_scenario_is_strict_and_names_the_field():
    with pytest.raises(ScenarioError, match=r"camera\.n_pixel: unknown key"):
        from_dict({"camera": {"n_pixel": 10}}, source="x.toml")
    with pytest.raises(ScenarioError, match=r"x\.toml: camera\.tdi_stages"):
        from_dict({"camera": {"tdi_stages": 0}}, source="x.toml")
    assert default().hash == SC.hash


def test_forward_and_inverse_camera_models_round_trip():
    # direction -> focal plane (Newton inverse of Brown's correction) -> direction
    # (explicit correction): the two routes share only the coefficients
    cam = _truth(scale=5.0)  # five times the default errors: up to ~10 px of distortion
    rng = np.random.default_rng(0)
    d = np.column_stack([rng.uniform(-0.002, 0.002, 500), rng.uniform(-0.03, 0.03, 500), -np.ones(500)])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    x, y = cam.focal_plane(d)
    back = cam.direction(x, y)
    ang = _angle(back, d)
    assert ang.max() < 1e-9
    # and the other way round from detector positions
    ys = sample_y_mm(np.linspace(0, cam.n_pixels - 1, 101), n_pixels=cam.n_pixels, pitch_mm=cam.pitch_mm)
    xs = np.full(ys.shape, cam.x_line_mm)
    x2, y2 = cam.focal_plane(cam.direction(xs, ys))
    assert np.max(np.abs(x2 - xs)) < 1e-9 and np.max(np.abs(y2 - ys)) < 1e-9  # mm


def test_distortion_single_parameters_give_their_patterns_along_the_line():
    # seed 004 check 4: k1 alone displaces the line's look angles by k1 y'^3 / r_n^2 px,
    # p2 alone by 3 p2 y'^2 / r_n px (x' = 0), df by y' df / f
    s = np.linspace(0, SC.camera.n_pixels - 1, 41)
    y_px = s - 0.5 * (SC.camera.n_pixels - 1)
    rn = 0.5 * SC.camera.n_pixels
    f_px = SC.camera.focal_length_mm / SC.camera.pitch_mm
    base = camera_truth(SC, np.zeros(10)).los_angles(s)[1]
    for j, value, pattern in ((6, 3e-4, y_px**3 / rn**2), (9, 2e-4, 3 * y_px**2 / rn),
                              (5, 0.2, y_px * 0.2 / SC.camera.focal_length_mm / 0.2)):
        th = np.zeros(10)
        th[j] = value
        across = camera_truth(SC, th).los_angles(s)[1]
        shift_px = -(across - base) * f_px * (1 + (y_px / f_px) ** 2)  # d(atan(y/F)) = dy/F/(1+(y/F)^2)
        expected = value * pattern if j != 5 else y_px * value / (SC.camera.focal_length_mm + value)
        # second order: the displacement (< 1 px) changes the pattern by its own slope
        assert np.max(np.abs(shift_px - expected)) < 2e-3 * max(1.0, np.max(np.abs(expected)))


def test_differential_aberration_matches_astropy_within_a_milliarcsecond():
    # the strip's directions are computed by astropy at the pass middle; a star seen
    # 4 s later is moved by the first-order formula with the change of velocity. Reference:
    # astropy (through simcam.sky) at that time.
    from astropy.time import Time

    from simcam.sky.apparent import apparent_directions

    strip = sky_strip(SC, ra_deg=280.0, dec_deg=-5.0, mag_limit=6.5)
    t = strip.plan.t_mid_s[0] + 4.0
    j = np.arange(len(strip.cat))
    ours = strip.at(np.zeros_like(j), j, np.full(j.size, t))
    pos, vel = orbit_state(SC, t)
    ref = apparent_directions(strip.cat, Time(SC.orbit.epoch_utc, scale="utc") + t * _sec(),
                              observer_position_km=pos, observer_velocity_km_s=vel)
    ang_mas = _angle(ours, ref) * ARCSEC_PER_RAD * 1e3
    assert ang_mas.max() < 1.0
    # and aberration is really in it: without it the stars are ~5-25 arcsec away
    plain = apparent_directions(strip.cat, Time(SC.orbit.epoch_utc, scale="utc") + t * _sec(),
                                observer_position_km=pos, observer_velocity_km_s=vel, aberration=False)
    off = _angle(plain, ref) * ARCSEC_PER_RAD
    assert 3.0 < off.max() < 27.0


def _sec():
    import astropy.units as u

    return u.s


def test_orbit_is_circular_two_body():
    # |r| = a, |v| = sqrt(mu / a), r . v = 0 (Vallado 2013 sec. 2.2)
    r, v = orbit_state(SC, np.linspace(0, 6000, 7))
    a = 6378.137 + SC.orbit.altitude_km
    assert np.allclose(np.linalg.norm(r, axis=1), a, rtol=1e-12)
    assert np.allclose(np.linalg.norm(v, axis=1), math.sqrt(398600.4418 / a), rtol=1e-12)
    assert np.max(np.abs(np.sum(r * v, axis=1))) < 1e-6 * a


def test_rodrigues_matches_scipy():
    from scipy.spatial.transform import Rotation

    rv = np.random.default_rng(1).normal(size=(20, 3))
    assert np.allclose(rodrigues(rv), Rotation.from_rotvec(rv).as_matrix(), atol=1e-14)


def _single_star_scenario(**att):
    d = {"attitude": {"knowledge_noise_arcsec": 0.0, **att},
         "detector": {"read_noise_e": 0.0, "prnu_rms": 0.0, "dark_e": 0.0, "dsnu_rms_e": 0.0},
         "camera": {"background_e": 0.0}}
    return from_dict(d, source="test")


@pytest.mark.parametrize("att", [{}, {"rate_mismatch": 0.05}, {"rate_mismatch": -0.03, "cross_rate_deg_s": 0.02}])
def test_centroid_of_a_smeared_tdi_star_is_its_mid_exposure_position(att):
    # seed 004 step 4.2: a star whose image moves against the TDI charge (rate mismatch,
    # cross-track drift) is smeared over the exposure; the centroid of the output, with the
    # time tag of the output line's mid-exposure t_L - N T / 2, is the position of the
    # star at that time. Reference: the analytic crossing (exact forward model) and
    # photutils' centre of mass.
    from photutils.centroids import centroid_com

    sc = _single_star_scenario(**att)
    cam = camera_truth(sc, draw_errors(sc, np.random.default_rng(2)))
    strip = sky_strip(sc, ra_deg=280.0, dec_deg=-5.0, mag_limit=7.0)
    keys = np.arange(1, sc.observation.passes + 1, dtype=np.uint64)
    im = image_passes(sc, cam, strip, frame_keys=keys, detector_key=np.uint64(9), noise=False)
    assert im.windows_dn.shape[0] > 50
    T, N = sc.camera.line_period_s, sc.camera.tdi_stages
    sig = im.windows_dn - sc.detector.offset_dn  # expected DN, no noise
    errs_t, errs_s = [], []
    for i in range(sig.shape[0]):
        cx, cy = centroid_com(sig[i])
        line_c = im.line0[i] + cy
        t_tag = im.t_pass0_s[im.pass_index[i]] + (line_c - 0.5 * N) * T
        errs_t.append((t_tag - im.t_true_s[i]) / T)  # in lines
        errs_s.append(im.col0[i] + cx - im.sample_true[i])
    errs_t, errs_s = np.array(errs_t), np.array(errs_s)
    # tolerance: the window (3 sigma of the PSF plus half the smear) truncates < 0.3 % of
    # the light, mostly symmetrically; the quadratic image motion over the exposure moves
    # the time-average position by a (N T)^2 / 12 < 1e-3 px; the 4 substeps per line are
    # symmetric about each period's middle
    assert np.max(np.abs(errs_t)) < 0.02
    assert np.max(np.abs(errs_s)) < 0.02
    # a time tag at the readout (end of exposure) would be N/2 lines late
    assert np.all(np.abs(errs_t + 0.5 * N) > 0.4 * N)


def test_crossing_times_put_the_star_on_the_line():
    sc = SC
    cam = _truth()
    plan = scan_plan(sc, ra_deg=10.0, dec_deg=20.0)
    rng = np.random.default_rng(4)
    k = rng.integers(0, plan.passes, 50)
    tt = plan.t_mid_s[k] + rng.uniform(-3, 3, 50)
    # stars placed on the line at times tt, detectors s, through the true camera
    s = rng.uniform(100, sc.camera.n_pixels - 100, 50)
    d_cam = cam.direction(np.full(50, cam.x_line_mm), sample_y_mm(s, n_pixels=cam.n_pixels, pitch_mm=cam.pitch_mm))
    a = np.einsum("nij,nj->ni", plan.matrices(tt, k) @ cam.misalignment.as_matrix(), d_cam)
    t, xres, y = crossing_times(cam, plan, a, k)
    assert np.max(np.abs(t - tt)) < 1e-9
    assert np.max(np.abs(y / cam.pitch_mm + 0.5 * (cam.n_pixels - 1) - s)) < 1e-6


def test_teff_from_b_v_against_pecaut_mamajek():
    # Pecaut & Mamajek (2013) Table 5 (dwarfs): B-V and Teff of G2V, K0V, M0V, F0V
    from simcam.spectra import star_teff_k

    for sp, bv in (("G2V", 0.650), ("K0V", 0.816), ("M0V", 1.431), ("F0V", 0.369)):
        assert signal.teff_from_b_v(bv) == pytest.approx(star_teff_k(spectral_type=sp), rel=0.04)


def test_signal_chain_follows_pogson_and_the_patent_shortcut_sits_beside_it():
    cam = SC.camera
    r = signal.star_electron_rate(cam, v_mag=np.array([0.0, 5.0]), b_v=np.array([0.65, 0.65]))
    assert r[1] / r[0] == pytest.approx(0.01, rel=1e-12)  # 10^(-0.4 * 5)
    # order of magnitude: a V = 0 solar-type star through a 125 mm aperture, 0.7 x QE ~0.5:
    # ~1e3 photons s^-1 cm^-2 A^-1 x ~3000 A x 123 cm^2 x ~0.3 -> ~1e8 e-/s
    assert 3e7 < r[0] < 3e8
    i0 = float(r[0])
    m = cam.line_period_s * signal.centre_pixel_fraction(cam.psf_sigma_px)
    mags = np.array([0.0, 4.0, 8.0])
    p = signal.patent_pixel_signal_e(mags, n_stages=cam.tdi_stages, m=m, i0_e_s=i0)
    chain = signal.star_electron_rate(cam, v_mag=mags, b_v=np.full(3, 0.65)) * cam.exposure_s * \
        signal.centre_pixel_fraction(cam.psf_sigma_px)
    # 2.512 against 10^0.4: 0.0047 % per magnitude of difference
    assert np.allclose(p / chain, (2.512 / 10**0.4) ** (-mags), rtol=1e-12)
    # the shortcut ignores colour: an M star of the same V gives a different signal
    red = signal.star_electron_rate(cam, v_mag=5.0, b_v=1.4) / signal.star_electron_rate(cam, v_mag=5.0, b_v=0.65)
    assert abs(float(red) - 1) > 0.05


def test_patents_rotated_blur_centroid_is_the_mid_exposure_position_too():
    # seed 004 step 4.2: rotate the blurred star by its motion angle theta = atan2(B, A)
    # (eq. 4.1 with the scan's body rates), centroid along and across the smear, rotate back.
    # Reference: the exact crossing (mid-exposure) position, and the plain centre of
    # gravity of the same weights (rotation-equivariance: equal to rounding)
    from budget.linecam.pipeline import motion_angle, rotated_blur_centroid

    sc = _single_star_scenario(rate_mismatch=0.08, cross_rate_deg_s=0.03)
    cam = camera_truth(sc, np.zeros(10))
    strip = sky_strip(sc, ra_deg=280.0, dec_deg=-5.0, mag_limit=6.5)
    keys = np.arange(1, sc.observation.passes + 1, dtype=np.uint64)
    im = image_passes(sc, cam, strip, frame_keys=keys, detector_key=np.uint64(9), noise=False)
    T, N = sc.camera.line_period_s, sc.camera.tdi_stages
    f_px = sc.camera.focal_length_mm / sc.camera.pitch_mm
    w0 = sc.camera.matched_rate_rad_s
    rates = (math.radians(0.03), w0 * 1.08, 0.0)
    # relative motion against the TDI charge, in (sample, line) axes of the window:
    # along track the packet follows at the nominal rate, so only the mismatch smears
    smear, _ = motion_angle(f_px=f_px, x_px=0.0, y_px=0.0, rates_rad_s=rates, exposure_s=N * T)
    assert smear > 2.0  # px: a real streak
    theta = math.atan2(f_px * (rates[1] - w0), -f_px * rates[0])  # angle of (d line, d sample)
    for i in range(min(20, im.windows_dn.shape[0])):
        win = im.windows_dn[i] - sc.detector.offset_dn
        # window axes are (line, sample): give the centroid (sample, line) coordinates
        xs, ys, _, _ = rotated_blur_centroid(win, theta=math.pi / 2 - theta, x0=im.col0[i], y0=im.line0[i],
                                             background=0.0)
        tot = win.sum()
        iy, ix = np.indices(win.shape)
        assert xs == pytest.approx(im.col0[i] + (win * ix).sum() / tot, abs=1e-9)
        assert ys == pytest.approx(im.line0[i] + (win * iy).sum() / tot, abs=1e-9)
        t_tag = im.t_pass0_s[im.pass_index[i]] + (ys - 0.5 * N) * T
        assert abs(t_tag - im.t_true_s[i]) / T < 0.03
        assert abs(xs - im.sample_true[i]) < 0.03
