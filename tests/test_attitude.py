"""The attitude solve (budget.attitude.solve) against the analytic least-squares covariance,
a rigid field offset and its own conventions; input errors name their field."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from budget.attitude.solve import (
    AttitudeSolution,
    CameraModel,
    attitude_error,
    camera_directions,
    focal_from_mosaic,
    solve_attitude,
)
from simcam.distortion import BrownConradyDistortion
from simcam.infra.errors import UserInputError
from simcam.units import ARCSEC_PER_RAD

SCALE = 5.5
#: Monte Carlo solves per check
TRIALS = 4000
#: two-sided acceptance of a sample variance of TRIALS zero-mean normal errors (their mean is
#: known to be 0, so TRIALS s^2 / sigma^2 is chi-square with TRIALS degrees of freedom): each
#: check fails by chance with probability 1e-3 (the seed is fixed, so the test is deterministic)
VAR_LOW, VAR_HIGH = chi2.ppf(5e-4, TRIALS) / TRIALS, chi2.ppf(1 - 5e-4, TRIALS) / TRIALS


def _model(**changes) -> CameraModel:
    base = {"plate_scale_arcsec": SCALE, "n_chips": 2, "chip_cols": 2048, "chip_rows": 2048, "gap_px": 20.0,
            "chip_offset_u_px": (0.0, 0.0), "chip_offset_v_px": (0.0, 0.0), "chip_rotation_deg": (0.0, 0.0),
            "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "r_norm_px": 2048.0}
    return CameraModel(**(base | changes))


def _mosaic_of_focal(u, v, model: CameraModel):
    """Mosaic (x, y) of focal (u, v) for a model without chip offsets or rotations (the test's own
    mapping: chip k's centre at (k - 1/2)(cols + gap), mosaic x = k cols + chip x)."""
    cols = model.chip_cols
    chip = (u > 0).astype(int)
    cu = (chip - 0.5) * (cols + model.gap_px)
    return chip * cols + (u - cu) + (cols - 1) / 2.0, v + (model.chip_rows - 1) / 2.0


def _ring(n, radius_px, phase=0.3):
    """``n`` stars equally spaced on a ring about the boresight, clear of the chip gap."""
    phi = phase + 2 * np.pi * np.arange(n) / n
    u, v = radius_px * np.cos(phi), radius_px * np.sin(phi)
    return u + np.where(np.abs(u) < 20.0, 40.0, 0.0), v


def _lsq_covariance_arcsec2(u, v, sigma_px, model: CameraModel):
    """The least-squares covariance of the attitude components (x, y, roll) by the textbook
    formula, independent of scipy's sensitivity matrix: the camera-frame information
    ``sum_i sigma_i^-2 (I - b_i b_i^T)`` inverted, then delta -> (delta_y, -delta_x, delta_z)."""
    f = model.focal_length_px
    b = np.column_stack([u, v, np.full(len(u), f)])
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    w = 1.0 / (np.broadcast_to(sigma_px, (len(u),)) * SCALE / ARCSEC_PER_RAD) ** 2
    info = np.einsum("i,ijk->jk", w, np.eye(3)[None] - b[:, :, None] * b[:, None, :])
    p = np.linalg.inv(info) * ARCSEC_PER_RAD**2
    t = np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1]], float)
    return t @ p @ t.T


def _assert_same_covariance(actual, expected, tol):
    """Two covariances equal to ``tol`` relative to the scale of each element, sqrt(P_ii P_jj)."""
    d = np.sqrt(np.diag(expected))
    assert np.abs((np.asarray(actual) - expected) / np.outer(d, d)).max() < tol


def _monte_carlo(u, v, sigma_px, model, *, seed):
    """Attitude errors (TRIALS, 3: x, y, roll arcsec) of solves from centroids with Gaussian
    noise of ``sigma_px`` per axis, at a fixed random attitude; and the last solution."""
    rng = np.random.default_rng(seed)
    true = Rotation.random(random_state=rng)
    a = true.apply(camera_directions(*_mosaic_of_focal(u, v, model), model))
    x0, y0 = _mosaic_of_focal(u, v, model)
    out = np.empty((TRIALS, 3))
    for k in range(TRIALS):
        sol = solve_attitude(x0 + sigma_px * rng.standard_normal(len(u)), y0 + sigma_px * rng.standard_normal(len(u)),
                             sigma_px, a, model)
        e = attitude_error(sol.attitude, true)
        out[k] = e.x_arcsec, e.y_arcsec, e.roll_arcsec
    return out, sol


def test_temporal_noise_cross_boresight_is_sigma_over_root_n_and_roll_the_lsq_covariance():
    model = _model()
    n, sigma_px = 10, 0.1
    u, v = _ring(n, 900.0)
    p = _lsq_covariance_arcsec2(u, v, sigma_px, model)
    sigma_arcsec = sigma_px * SCALE
    # a ring centred on the boresight: cross-boresight sigma / sqrt(N), to O(radius^2 / F^2) (1e-4)
    np.testing.assert_allclose(np.sqrt(p[0, 0]), sigma_arcsec / math.sqrt(n), rtol=1e-3)
    np.testing.assert_allclose(np.sqrt(p[1, 1]), sigma_arcsec / math.sqrt(n), rtol=1e-3)
    # roll: sigma / (sqrt(N) rho), rho the ring's radius in radians
    np.testing.assert_allclose(np.sqrt(p[2, 2]), sigma_arcsec / math.sqrt(n) / (900.0 / model.focal_length_px),
                               rtol=1e-3)
    err, sol = _monte_carlo(u, v, sigma_px, model, seed=1)
    ratio = np.mean(err**2, axis=0) / np.diag(p)
    assert np.all((VAR_LOW < ratio) & (ratio < VAR_HIGH)), ratio
    _assert_same_covariance(sol.covariance_arcsec2, p, 1e-3)


def test_unequal_stars_off_centre_follow_the_lsq_covariance_on_every_axis():
    model = _model()
    rng = np.random.default_rng(5)
    n = 7
    u = rng.uniform(100, 2000, n)  # all on one chip, off-centre along u: y and roll errors correlate
    u = np.where(np.abs(u) < 30, 60.0, u)
    v = rng.uniform(-900, 900, n)
    sigma_px = rng.uniform(0.03, 0.3, n)
    err, sol = _monte_carlo(u, v, sigma_px, model, seed=2)
    p = _lsq_covariance_arcsec2(u, v, sigma_px, model)
    ratio = np.mean(err**2, axis=0) / np.diag(p)
    assert np.all((VAR_LOW < ratio) & (ratio < VAR_HIGH)), ratio
    # the solver's stated covariance (scipy's sensitivity times the harmonic mean of the
    # variances) is the textbook least-squares one: exactly from noise-free centroids, and
    # from noisy ones to the noise's share of the lever arms (0.3 px in 1000: 1e-3)
    _assert_same_covariance(sol.covariance_arcsec2, p, 1e-3)
    x, y = _mosaic_of_focal(u, v, model)
    exact = solve_attitude(x, y, sigma_px, Rotation.random(random_state=rng).apply(camera_directions(x, y, model)),
                           model)
    _assert_same_covariance(exact.covariance_arcsec2, p, 1e-9)
    # the y-roll correlation of a field off-centre along u (a roll moves its stars along v) is
    # seen in the Monte Carlo too: the sample correlation of TRIALS pairs has standard error
    # (1 - r^2) / sqrt(TRIALS); 4 of them
    r = p[1, 2] / math.sqrt(p[1, 1] * p[2, 2])
    r_mc = np.corrcoef(err[:, 1], err[:, 2])[0, 1]
    assert abs(r_mc - r) < 4 * (1 - r**2) / math.sqrt(TRIALS)
    assert abs(r) > 0.1


@pytest.mark.parametrize("n", [3, 10, 40])
def test_a_rigid_field_offset_is_the_attitude_error_whatever_n(n):
    model = _model()
    rng = np.random.default_rng(n)
    u = rng.uniform(-2000, 2000, n)
    u = np.where(np.abs(u) < 30, 60.0, u)
    v = rng.uniform(-1000, 1000, n)
    true = Rotation.random(random_state=rng)
    x, y = _mosaic_of_focal(u, v, model)
    a = true.apply(camera_directions(x, y, model))
    dx, dy = 0.3, -0.2
    sol = solve_attitude(x + dx, y + dy, 0.1, a, model)
    e = attitude_error(sol.attitude, true)
    # a focal-plane shift d moves a star at field angle theta by d cos^2(theta) (radial) to
    # d cos(theta) (tangential): each star's shift differs from the offset by at most
    # eps = |d| s (1 - cos^2(theta_max)) (<= 4e-3 of it at this field's corner). The least squares
    # are linear in those differences, e = G eps with G the pseudo-inverse of the stars' design
    # (du = x - roll v / F, dv = y + roll u / F), so each component is the offset within
    # sum_j |G_kj| eps: the error does not average down with N
    f = model.focal_length_px
    theta = np.arctan(np.hypot(u, v).max() / f)
    eps = math.hypot(dx, dy) * SCALE * (1 - math.cos(theta) ** 2)
    design = np.zeros((2 * n, 3))
    design[0::2, 0], design[1::2, 1] = 1.0, 1.0
    design[0::2, 2], design[1::2, 2] = -v / f, u / f
    bound = np.abs(np.linalg.pinv(design)).sum(axis=1) * eps
    assert abs(e.x_arcsec - dx * SCALE) <= bound[0]
    assert abs(e.y_arcsec - dy * SCALE) <= bound[1]
    assert abs(e.roll_arcsec) <= bound[2]
    # the residuals show nothing but those differences, (I - H G) eps (a rigid offset is an attitude)
    leave = np.abs(np.eye(2 * n) - design @ np.linalg.pinv(design)).sum(axis=1) * eps
    assert np.all(np.abs(sol.residual_u_arcsec) <= leave[0::2]) and np.all(np.abs(sol.residual_v_arcsec) <= leave[1::2])


def test_noise_free_centroids_give_the_true_attitude_through_distortion_and_chip_layout():
    model = _model(chip_offset_u_px=(1.5, -2.0), chip_offset_v_px=(0.5, 3.0), chip_rotation_deg=(0.01, -0.02),
                   k1=2e-4, k2=5e-5, p1=1e-5, p2=-2e-5)
    rng = np.random.default_rng(9)
    n = 12
    x = rng.uniform(20, 4075, n)
    y = rng.uniform(20, 2027, n)
    true = Rotation.random(random_state=rng)
    # the test's own forward model: mosaic -> chip -> focal (rigid chip placement), then the
    # ideal position under the distortion's inverse; the solve must undo both
    chip = (x >= 2048).astype(int)
    cu = (chip - 0.5) * (2048 + 20.0) + np.array([1.5, -2.0])[chip]
    cv = np.array([0.5, 3.0])[chip]
    th = np.radians(np.array([0.01, -0.02]))[chip]
    dx, dy = x - chip * 2048 - 1023.5, y - 1023.5
    ud, vd = cu + np.cos(th) * dx - np.sin(th) * dy, cv + np.sin(th) * dx + np.cos(th) * dy
    u, v = BrownConradyDistortion(k1=2e-4, k2=5e-5, p1=1e-5, p2=-2e-5, r_norm_px=2048.0).inverse(u_px=ud, v_px=vd)
    fu, fv = focal_from_mosaic(x, y, model)
    np.testing.assert_allclose(fu, u, atol=1e-9)
    np.testing.assert_allclose(fv, v, atol=1e-9)
    b = np.column_stack([u, v, np.full(n, model.focal_length_px)])
    sol = solve_attitude(x, y, 0.05, true.apply(b), model)  # directions of any length
    e = attitude_error(sol.attitude, true)
    assert max(abs(e.x_arcsec), abs(e.y_arcsec), abs(e.roll_arcsec)) < 1e-6
    assert sol.chi2 < 1e-12 and sol.n_stars == n
    assert isinstance(sol, AttitudeSolution) and sol.sigma_arcsec.shape == (3,)


def test_attitude_error_components_and_stacks():
    true = Rotation.random(3, random_state=np.random.default_rng(4))
    eps = 1e-6  # rad
    # the solved attitude rotated by -eps about camera y: the field appears moved by +eps along x
    e = attitude_error(true * Rotation.from_rotvec([0.0, -eps, 0.0]), true)
    np.testing.assert_allclose(e.x_arcsec, eps * ARCSEC_PER_RAD, rtol=1e-9)
    np.testing.assert_allclose(e.y_arcsec, 0.0, atol=1e-9)
    e = attitude_error(true * Rotation.from_rotvec([eps, 0.0, 0.0]), true)
    np.testing.assert_allclose(e.y_arcsec, eps * ARCSEC_PER_RAD, rtol=1e-9)
    e = attitude_error(true * Rotation.from_rotvec([0.0, 0.0, -eps]), true)
    np.testing.assert_allclose(e.roll_arcsec, eps * ARCSEC_PER_RAD, rtol=1e-9)
    one = attitude_error(true[0], true[0])
    assert one.x_arcsec == 0.0 and isinstance(one.roll_arcsec, float)


def test_the_focal_length_gives_the_plate_scale():
    m = CameraModel.from_focal_length(focal_length_mm=206.26480624709636, pixel_pitch_um=5.5,
                                      **{k: v for k, v in vars(_model()).items() if k != "plate_scale_arcsec"})
    assert m.plate_scale_arcsec == pytest.approx(5.5, rel=1e-14)
    with pytest.raises(UserInputError, match="focal_length_mm"):
        CameraModel.from_focal_length(focal_length_mm=0.0, pixel_pitch_um=5.5,
                                      **{k: v for k, v in vars(_model()).items() if k != "plate_scale_arcsec"})


@pytest.mark.parametrize(("call", "field"), [
    (lambda m, a: solve_attitude([100.0], [100.0], 0.1, a[:1], m), "x_px"),
    (lambda m, a: solve_attitude([100.0, 200.0], [100.0, 300.0], 0.0, a[:2], m), "sigma_px"),
    (lambda m, a: solve_attitude([100.0, 200.0], [100.0, 300.0], [0.1, -1], a[:2], m), "sigma_px"),
    (lambda m, a: solve_attitude([100.0, 200.0], [100.0, np.nan], 0.1, a[:2], m), "y_px"),
    (lambda m, a: solve_attitude([100.0, 200.0], [100.0, 300.0], 0.1, a[:3], m), "directions"),
    (lambda m, a: solve_attitude([100.0, 5000.0], [100.0, 300.0], 0.1, a[:2], m), "x_px"),
    (lambda m, a: solve_attitude([100.0, 200.0], [100.0, 300.0], 0.1, np.zeros((2, 3)), m), "directions"),
    (lambda m, a: _model(plate_scale_arcsec=-1.0), "plate_scale_arcsec"),
    (lambda m, a: _model(chip_offset_u_px=(0.0,)), "chip_offset_u_px"),
    (lambda m, a: _model(n_chips=0), "n_chips"),
    (lambda m, a: _model(k1=math.inf), "k1"),
])
def test_bad_input_is_an_error_naming_the_field(call, field):
    a = np.tile([0.0, 0.0, 1.0], (3, 1))
    with pytest.raises(UserInputError, match=field):
        call(_model(), a)
