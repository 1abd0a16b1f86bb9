"""The attitude study's models (issue #34): the lab's improved prediction against the
least-squares textbook, the smear of a turning camera's exposure and the frames of a slew."""

from __future__ import annotations

import math

import numpy as np
import pytest
from astropy.time import Time
from scipy.spatial.transform import Rotation

from budget.attitude.chain import frame_attitudes, observe_pointing
from budget.attitude.predict import LabBudget, predict_attitude
from simcam.sky.catalogue import Catalogue, v_minus_hp
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import default, with_updates
from simcam.starcam.sky_view import (
    SMEAR_STEP_PX,
    detection_limit,
    focal_length_px,
    image_motion_px,
    sky_scene,
    sky_stars,
    stars_in_view,
)

EPOCH = Time("2026-03-21T00:00:00", scale="utc")
ATTITUDE = Rotation.from_euler("zyx", [40.0, 15.0, -25.0], degrees=True)


def _budget(*, te=(0.0, 0.0), hsfe=(0.0, 0.0), lsfe_s=(0.0, 0.0), reference_electrons=1000.0):
    return LabBudget.from_3sigma(single_star=(1.76, 1.95), n_stars=10, te=te, hsfe=hsfe, lsfe_s=lsfe_s,
                                 lsfe_c1=(0.0, 0.0), lsfe_c2=(0.0, 0.0), reference_electrons=reference_electrons)


def _ring(n: int, radius_px: float):
    phi = np.radians(22.5) + 2 * np.pi * np.arange(n) / n
    return radius_px * np.cos(phi), radius_px * np.sin(phi)


def test_equal_stars_on_a_ring_give_sigma_over_sqrt_n_across_and_the_lever_arm_in_roll():
    # per star 1 sigma: TE 0.1" (at the reference electrons), static 0.2": 0.05 arcsec^2 per axis
    b = _budget(te=(0.3, 0.3), hsfe=(0.6, 0.6))
    n, radius, f = 8, 700.0, 37_500.0
    u, v = _ring(n, radius)
    p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=f, electrons=np.full(n, 1000.0))
    np.testing.assert_allclose(np.diag(p.temporal_arcsec2)[:2], 0.01 / n, rtol=1e-12)
    np.testing.assert_allclose(np.diag(p.spatial_arcsec2)[:2], 0.04 / n, rtol=1e-12)
    # roll: the lever arm rho = radius / F (rad), sigma^2 / (N rho^2)
    np.testing.assert_allclose(p.total_arcsec2[2, 2], 0.05 / (n * (radius / f) ** 2), rtol=1e-12)
    np.testing.assert_allclose(p.sigma_arcsec[:2], math.sqrt(0.05 / n), rtol=1e-12)


def test_te_scales_with_the_stars_electrons_and_lsfe_s_does_not_average():
    b = _budget(te=(0.3, 0.6), lsfe_s=(0.3, 0.6))
    n = 10
    u, v = _ring(n, 900.0)
    p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.full(n, 4000.0))
    # four times the reference's electrons: half its TE; the colour shift is the pointing's whatever N
    np.testing.assert_allclose(np.diag(p.temporal_arcsec2)[:2], np.array([0.05, 0.1]) ** 2 / n, rtol=1e-12)
    np.testing.assert_allclose(np.diag(p.spatial_arcsec2), [0.01, 0.04, 0.0], atol=1e-15)
    np.testing.assert_allclose(b.published_sigma_arcsec, np.array([1.76, 1.95]) / 3 / math.sqrt(10))
    with pytest.raises(ValueError, match="electrons"):
        predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.zeros(n))


@pytest.mark.parametrize("n", [3, 10, 40])
def test_the_prediction_with_only_a_rigid_field_offset_is_the_offset_whatever_n(n):
    # the check on the prediction: a shift common to every star (LSFE-S, or a smooth
    # field of infinite correlation length) is the attitude error, whatever N, and no roll
    # (the stars' equal TE only sets their equal weights)
    u, v = _ring(n, 900.0)
    for b in (_budget(te=(0.3, 0.3), lsfe_s=(0.3, 0.6)),
              LabBudget.from_3sigma(single_star=(1.76, 1.95), n_stars=10, te=(0.3, 0.3), hsfe=(0.0, 0.0),
                                    lsfe_s=(0.0, 0.0), lsfe_c1=(0.3, 0.6), lsfe_c2=(0.0, 0.0),
                                    reference_electrons=1000.0, field_correlation_px=1e12)):
        p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.full(n, 1000.0))
        np.testing.assert_allclose(np.diag(p.fov_arcsec2), [0.01, 0.04, 0.0], atol=1e-12)
        np.testing.assert_allclose(p.pixel_arcsec2, 0.0, atol=1e-15)


@pytest.mark.parametrize("n", [3, 10, 40])
def test_the_prediction_with_only_temporal_noise_is_sigma_over_sqrt_n(n):
    # TE 0.3" 3 sigma: 0.1" per star and axis; equal stars centred on the boresight
    b = _budget(te=(0.3, 0.3))
    u, v = _ring(n, 700.0)
    p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.full(n, 1000.0))
    np.testing.assert_allclose(np.sqrt(np.diag(p.temporal_arcsec2)[:2]), 0.1 / math.sqrt(n), rtol=1e-12)
    np.testing.assert_allclose(p.spatial_arcsec2, 0.0, atol=1e-15)


def test_a_correlated_smooth_field_averages_as_its_correlation_allows():
    # two equal stars d apart on the u axis: e_x is the mean of their du, whose variance is
    # f^2 (1 + rho) / 2 with rho = exp(-d^2 / (2 L^2)); L = 0 gives f^2 / 2, the independent case
    f, d, big_l = 0.2, 800.0, 600.0
    u, v = np.array([-d / 2, d / 2]), np.zeros(2)
    for length, rho in ((0.0, 0.0), (big_l, math.exp(-0.5 * (d / big_l) ** 2))):
        b = LabBudget.from_3sigma(single_star=(1.76, 1.95), n_stars=10, te=(0.0, 0.0), hsfe=(0.0, 0.0),
                                  lsfe_s=(0.0, 0.0), lsfe_c1=(3 * f, 3 * f), lsfe_c2=(0.0, 0.0),
                                  reference_electrons=1000.0, field_correlation_px=length)
        p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.full(2, 1000.0))
        assert p.fov_arcsec2[0, 0] == pytest.approx(f**2 * (1 + rho) / 2, rel=1e-12)
    # the pixel part (HSFE) is independent from star to star whatever L: ring, f^2 / N
    b = LabBudget.from_3sigma(single_star=(1.76, 1.95), n_stars=10, te=(0.0, 0.0), hsfe=(0.6, 0.6),
                              lsfe_s=(0.0, 0.0), lsfe_c1=(0.0, 0.0), lsfe_c2=(0.0, 0.0), reference_electrons=1000.0,
                              field_correlation_px=1e6)
    u, v = _ring(8, 700.0)
    p = predict_attitude(b, u_px=u, v_px=v, focal_length_px=37_500.0, electrons=np.full(8, 1000.0))
    np.testing.assert_allclose(np.diag(p.pixel_arcsec2)[:2], 0.04 / 8, rtol=1e-12)
    with pytest.raises(ValueError, match="field_correlation_px"):
        LabBudget.from_3sigma(single_star=(1.76, 1.95), n_stars=10, te=(0.0, 0.0), hsfe=(0.0, 0.0),
                              lsfe_s=(0.0, 0.0), lsfe_c1=(0.0, 0.0), lsfe_c2=(0.0, 0.0), reference_electrons=1.0,
                              field_correlation_px=-1.0)


def _ring_catalogue(attitude, f_px, *, n, radius_px, v_mag=7.0):
    u, v = _ring(n, radius_px)
    c = np.column_stack([u / f_px, v / f_px, np.ones(n)])
    d = attitude.apply(c / np.linalg.norm(c, axis=1, keepdims=True))
    bv = np.full(n, 0.65)
    return Catalogue(hip=np.arange(1, n + 1), ra_rad=np.arctan2(d[:, 1], d[:, 0]) % (2 * np.pi),
                     dec_rad=np.arcsin(d[:, 2]), parallax_mas=np.zeros(n), pm_ra_mas_yr=np.zeros(n),
                     pm_dec_mas_yr=np.zeros(n), hp_mag=v_mag - v_minus_hp(bv), b_v=bv, v_i=np.zeros(n))


def _stamp_moments(scene):
    """Per star: the centroid (chip px) and the second moments of its noise-free stamp."""
    s = scene.stamps
    rows, cols = np.indices(s.shape[1:])
    tot = s.sum(axis=(1, 2))
    cx = (s * cols).sum(axis=(1, 2)) / tot
    cy = (s * rows).sum(axis=(1, 2)) / tot
    vxx = (s * cols**2).sum(axis=(1, 2)) / tot - cx**2
    vyy = (s * rows**2).sum(axis=(1, 2)) / tot - cy**2
    return tot, cx + scene.stamp_col0, cy + scene.stamp_row0, vxx, vyy


def test_a_turning_camera_smears_each_image_about_its_mid_exposure_position():
    cam = StarCamera(default())
    f = focal_length_px(cam)
    sky = sky_stars(cam, EPOCH, catalogue_v_max_mag=math.inf,
                    catalogue=_ring_catalogue(ATTITUDE, f, n=6, radius_px=500.0))
    view = stars_in_view(cam, sky, ATTITUDE, detection=detection_limit(cam, threshold_sigma=3.0))
    assert view.n_stars == 6
    # a roll rate: the image of a star at (u, v) turns by -w T about the boresight, (w T v, -w T u)
    w = np.array([0.0, 0.0, math.radians(0.5)])
    t = cam.scenario.camera.exposure_s
    du, dv = image_motion_px(cam, view, w, t)
    np.testing.assert_allclose(du, w[2] * t * view.v_px, rtol=2e-3, atol=1e-3)
    np.testing.assert_allclose(dv, -w[2] * t * view.u_px, rtol=2e-3, atol=1e-3)
    # a cross-boresight rate, smeared along x by 4 px: the flux is kept, the centroid stays at
    # mid-exposure, and the spread along the motion grows by the box's L^2 / 12
    still = sky_scene(cam, view, pointing=0)
    motion = (np.full(6, 4.0), np.zeros(6))
    smeared = sky_scene(cam, view, pointing=0, motion_px=motion)
    tot0, x0, y0, vxx0, vyy0 = _stamp_moments(still)
    tot1, x1, y1, vxx1, vyy1 = _stamp_moments(smeared)
    np.testing.assert_allclose(tot1, tot0, rtol=1e-9)
    np.testing.assert_allclose(x1, x0, atol=1e-6)
    np.testing.assert_allclose(y1, y0, atol=1e-6)
    # K equally spaced images: their spread is L^2 (1 - 1/K^2) / 12 (the stamps' periodic wings,
    # about 1e-5 of the second moment, are why it is not exact)
    k = math.ceil(4.0 / SMEAR_STEP_PX)
    np.testing.assert_allclose(vxx1 - vxx0, 16.0 * (1.0 - 1.0 / k**2) / 12.0, rtol=2e-5)
    np.testing.assert_allclose(vyy1, vyy0, atol=1e-9)


def test_the_frames_of_a_slew_share_stars_and_centre_on_the_pointing():
    atts = frame_attitudes(ATTITUDE, frames=5, rate_rad_s=[math.radians(0.2), 0.0, 0.0], interval_s=2.0)
    assert np.allclose((ATTITUDE.inv() * atts[2]).magnitude(), 0.0)
    step = np.degrees((atts[:-1].inv() * atts[1:]).magnitude())
    np.testing.assert_allclose(step, 0.4, rtol=1e-12)
    scn = with_updates(default(), {"render.wavelength_step_nm": 50.0})  # fewer wavelengths: a quicker render
    cam = StarCamera(scn)
    sky = sky_stars(cam, EPOCH, catalogue_v_max_mag=7.0)
    att = Rotation.from_euler("zyx", [100.0, 5.0, 30.0], degrees=True)  # near the galactic plane
    frames = observe_pointing(cam, sky, att, detection=detection_limit(cam, threshold_sigma=3.0), seed=2, frames=3,
                              threshold_sigma=3.0, rate_rad_s=[math.radians(0.2), 0.0, 0.0], interval_s=2.0)
    assert [fr.index for fr in frames] == [0, 0, 0]
    hips = [set(fr.observation.view.hip.tolist()) for fr in frames]
    assert all(len(h) >= 3 for h in hips)
    assert len(hips[0] & hips[1]) >= len(hips[0]) // 2  # 0.4 deg apart in a 3.1 deg wide field
    for fr in frames:
        assert fr.observation.attitude is fr.attitude and fr.observation.n_frames == 1
    staring = observe_pointing(cam, sky, att, detection=detection_limit(cam, threshold_sigma=3.0), seed=2, frames=3,
                               threshold_sigma=3.0, rate_rad_s=[0.0, 0.0, 0.0], interval_s=2.0)
    assert [fr.index for fr in staring] == [0, 1, 2] and staring[0].observation is staring[2].observation
