"""The simulated camera on the sky, observed as onboard and solved (budget.attitude.chain):
temporal noise through the StarCamera against the least-squares propagation, the fused
exposure-and-centroid pass against the renderer's windows and the centroider, the camera model."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from astropy.time import Time
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from budget.attitude.chain import camera_model, observe, random_attitudes, solve_frame
from budget.attitude.solve import attitude_error
from budget.centroid import CentroidWarning, centroid_cog
from budget.starcam.protocols import centroid_options
from simcam.sky.catalogue import Catalogue, v_minus_hp
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import default, with_updates
from simcam.starcam.sky_view import detection_limit, focal_length_px, sky_scene, sky_stars, stars_in_view
from simcam.units import ARCSEC_PER_RAD

EPOCH = Time("2026-03-21T00:00:00", scale="utc")
THRESHOLD_SIGMA = 3.0


def _ring_catalogue(attitude, f_px, *, n, radius_px, v_mag):
    """``n`` equal stars (V, B - V 0.65) equally spaced on a ring of ``radius_px`` about the
    boresight of ``attitude``, none within 260 px of the chip gap (u = 0)."""
    phi = np.radians(22.5) + 2 * np.pi * np.arange(n) / n
    c = np.column_stack([radius_px * np.cos(phi) / f_px, radius_px * np.sin(phi) / f_px, np.ones(n)])
    d = attitude.apply(c / np.linalg.norm(c, axis=1, keepdims=True))
    bv = np.full(n, 0.65)
    return Catalogue(hip=np.arange(1, n + 1), ra_rad=np.arctan2(d[:, 1], d[:, 0]) % (2 * np.pi),
                     dec_rad=np.arcsin(d[:, 2]), parallax_mas=np.zeros(n), pm_ra_mas_yr=np.zeros(n),
                     pm_dec_mas_yr=np.zeros(n), hp_mag=v_mag - v_minus_hp(bv), b_v=bv, v_i=np.zeros(n))


def test_temporal_noise_through_the_camera_is_the_least_squares_propagation():
    # repeated frames at one pointing differ by the temporal noise alone (the pixel maps, the
    # sub-pixel phase and the optics repeat), so the spread over frames is the temporal part
    scn = default()
    cam = StarCamera(scn)
    att = Rotation.from_euler("zyx", [70.0, -20.0, 35.0], degrees=True)
    n, radius_px = 8, 700.0
    sky = sky_stars(cam, EPOCH, catalogue_v_max_mag=math.inf,
                    catalogue=_ring_catalogue(att, focal_length_px(cam), n=n, radius_px=radius_px, v_mag=7.0))
    frames = 400
    obs = observe(cam, sky, att, detection=detection_limit(cam, threshold_sigma=THRESHOLD_SIGMA), pointing=3,
                  seed=11, frames=frames, threshold_sigma=THRESHOLD_SIGMA)
    assert obs.view.n_stars == n and np.isfinite(obs.x_px).all()
    model = camera_model(scn)
    err = np.empty((frames, 3))
    for k in range(frames):
        e = attitude_error(solve_frame(obs, model, frame=k, sigma_px=0.05).attitude, att)
        err[k] = e.x_arcsec, e.y_arcsec, e.roll_arcsec
    # the equal-weight least squares to first order: e = G n, G = (H^T H)^-1 H^T, H the stars'
    # design (image shift du = x - phi v, dv = y + phi u, px and rad) and n their centroid
    # errors, so cov(e) = G diag(sigma_x,i^2, sigma_y,i^2) G^T with each star's own temporal
    # variance over the frames (gnomonic and aberration corrections: < 0.5 %)
    u, v = obs.view.u_px, obs.view.v_px
    h = np.zeros((2 * n, 3))
    h[0::2, 0], h[1::2, 1] = 1.0, 1.0
    h[0::2, 2], h[1::2, 2] = -v, u
    g = np.linalg.pinv(h)
    var = np.empty(2 * n)
    var[0::2], var[1::2] = obs.x_px.var(axis=0, ddof=1), obs.y_px.var(axis=0, ddof=1)
    to_arcsec = np.array([scn.camera.scale_arcsec_per_px, scn.camera.scale_arcsec_per_px, ARCSEC_PER_RAD])
    predicted = np.einsum("kj,j,kj->k", g, var, g) * to_arcsec**2
    # equal stars on a ring: that is sigma^2 / N across the boresight and sigma^2 / (N rho^2) in roll
    sigma2 = var.mean()
    rho = radius_px / focal_length_px(cam)
    np.testing.assert_allclose(predicted[:2], sigma2 * to_arcsec[0] ** 2 / n, rtol=0.15)
    np.testing.assert_allclose(predicted[2], sigma2 * to_arcsec[0] ** 2 / (n * rho**2), rtol=0.15)
    # the attitude's spread over the frames (about its mean: the static errors are a bias) is
    # (frames - 1) s^2 / sigma^2 ~ chi-square(frames - 1); two-sided 99.9 % bounds. The
    # prediction uses variances from the same frames, which only narrows the ratio's spread
    ratio = err.var(axis=0, ddof=1) / predicted
    low, high = chi2.ppf([5e-4, 1 - 5e-4], frames - 1) / (frames - 1)
    assert np.all((low < ratio) & (ratio < high)), ratio
    # and the static errors of this camera (lateral colour against the lamp it was corrected
    # with, distortion beyond its cubic correction, pixel phase) leave a bias of a fraction of
    # an arcsec across the boresight: the frames, signs and scales of the chain agree
    assert np.all(np.abs(err.mean(axis=0)[:2]) < 1.0) and abs(err.mean(axis=0)[2]) < 20.0


def test_the_fused_pass_is_the_renderers_windows_centroided_and_corrected():
    scn = default()
    cam = StarCamera(scn)
    sky = sky_stars(cam, EPOCH, catalogue_v_max_mag=7.5)
    det = detection_limit(cam, threshold_sigma=THRESHOLD_SIGMA)
    att = random_attitudes(1, seed=8)[0]
    obs = observe(cam, sky, att, detection=det, pointing=5, seed=21, frames=3, threshold_sigma=THRESHOLD_SIGMA)
    view = stars_in_view(cam, sky, att, detection=det)
    assert view.n_stars >= 3
    win = cam.render_windows(sky_scene(cam, view, pointing=5), frames=3, seed=21)
    noise = centroid_options(cam, win.col0, THRESHOLD_SIGMA)["noise_dn"]
    w = view.n_stars
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CentroidWarning)
        x, y, _, _ = centroid_cog(win.pixels.astype(np.float64).reshape(3 * w, *win.pixels.shape[2:]),
                                  x0=np.tile(win.col0, 3), y0=np.tile(win.row0, 3), background="border",
                                  threshold_dn=np.tile(THRESHOLD_SIGMA * noise, 3))
    xr, yr = cam.report_positions(x, y)
    np.testing.assert_array_equal(obs.x_px.ravel(), xr)
    np.testing.assert_array_equal(obs.y_px.ravel(), yr)


def test_camera_model_carries_distortion_only_for_an_uncalibrated_camera():
    scn = default()
    m = camera_model(scn)
    assert (m.k1, m.k2, m.p1, m.p2) == (0.0, 0.0, 0.0, 0.0)
    assert m.plate_scale_arcsec == scn.camera.scale_arcsec_per_px and m.n_chips == scn.detector.n_chips
    raw = camera_model(with_updates(scn, {"optics.distortion_correction.kind": "none"}))
    assert (raw.k1, raw.k2) == (scn.optics.distortion.k1, scn.optics.distortion.k2)


def test_a_pointing_without_stars_gives_no_solution():
    cam = StarCamera(default())
    sky = sky_stars(cam, EPOCH, catalogue_v_max_mag=7.5)
    det = detection_limit(cam, threshold_sigma=THRESHOLD_SIGMA)
    # the camera blinded by an impossible threshold: no star detected
    obs = observe(cam, sky, Rotation.identity(), detection=det.__class__(1e12, det.noise_e, det.peak_fraction),
                  pointing=0, seed=1, frames=2, threshold_sigma=THRESHOLD_SIGMA)
    assert obs.view.n_stars == 0 and obs.x_px.shape == (2, 0)
    assert solve_frame(obs, camera_model(cam.scenario), frame=0, sigma_px=0.1) is None


def test_random_attitudes_are_uniform_and_reproducible():
    a = random_attitudes(4000, seed=3)
    assert np.allclose(a.as_quat(), random_attitudes(4000, seed=3).as_quat())
    z = a.apply([0.0, 0.0, 1.0])
    # boresights uniform on the sphere: each coordinate uniform on [-1, 1] (mean 0, se 1/sqrt(3 n))
    assert np.all(np.abs(z.mean(axis=0)) < 4 / math.sqrt(3 * 4000))
    with pytest.raises(ValueError):
        random_attitudes(-1, seed=3)
