"""End-to-end rendering: windows vs full frames, truth, noise statistics, bad placements."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import erf

from simcam.starcam.render import Placement, RenderError, StarCamera
from simcam.starcam.scenario import default, with_updates
from simcam.starcam.targets import star_grid


def _quiet(scn, **extra):
    """A scenario with the fixed-pattern and background terms and the world's effects
    (non-linearity, higher-order distortion, hexapod, drift) switched off."""
    upd = {"detector.prnu_rms": 0.0, "detector.dsnu_rms_e": 0.0, "detector.dark_current_e_per_s": 0.0,
           "detector.background_e_per_s": 0.0,
           "world.effects": scn.world.effects.ideal().model_dump()}
    upd.update(extra)
    return with_updates(scn, upd)


def _cog(img, col0, row0):
    ys, xs = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    t = img.sum()
    return col0 + (img * xs).sum() / t, row0 + (img * ys).sum() / t


@pytest.fixture(scope="module")
def camera():
    return StarCamera(default())


@pytest.fixture(scope="module")
def scene(camera):
    return camera.scene(Placement(layout=star_grid(camera.scenario), condition=3))


def test_windows_equal_full_frame_pixels(camera, scene):
    frame = camera.render_frame(scene, frame=2, seed=7)
    win = camera.render_windows(scene, frames=1, seed=7, first_frame=2)
    w = camera.scenario.render.window_px
    for j in range(scene.n_stars):
        r0, c0 = int(win.row0[j]), int(win.col0[j])
        np.testing.assert_array_equal(win.pixels[0, j], frame[r0 : r0 + w, c0 : c0 + w])
    # a different frame index gives different noise
    other = camera.render_windows(scene, frames=1, seed=7, first_frame=3)
    assert np.any(other.pixels != win.pixels)


def test_noise_free_centroid_equals_truth_over_full_stamp():
    scn = _quiet(default())
    cam = StarCamera(scn)
    sc = cam.scene(Placement(layout=star_grid(scn)))
    # The whole stamp holds the whole image, so its centre of gravity differs from the true
    # (continuous) centroid only by pixel sampling. By Poisson summation, for a pixel-integrated
    # PSF with transfer function F(nu) = OTF(nu) sinc(nu), sum_m m f(m - x0) - x0 =
    # sum_{k>0} (-1)^k OTF(k) sin(2 pi k x0) / (pi k): at most ~ OTF(1)/pi, and |OTF(1)| <=
    # exp(-2 pi^2 sigma^2) for a Gaussian camera PSF (the pinhole disc and colour only lower it).
    k = cam.mosaic.chip_cols
    for j in range(sc.n_stars):
        x, y = _cog(sc.stamps[j], sc.stamp_col0[j], sc.stamp_row0[j])
        sig = sc.truth.psf_sigma_px[j]
        tol = 1.01 * np.exp(-2 * np.pi**2 * sig**2) / np.pi + 1e-10
        assert abs(x + sc.chip[j] * k - sc.truth.x_true[j]) < tol
        assert abs(y - sc.truth.y_true[j]) < tol
    # with a wide PSF the sampling error vanishes: then the CoG is the truth to rounding
    scn2 = _quiet(default(), **{"optics.psf.sigma0_px": 1.6})
    cam2 = StarCamera(scn2)
    sc2 = cam2.scene(Placement(layout=star_grid(scn2)))
    for j in range(sc2.n_stars):
        x, y = _cog(sc2.stamps[j], sc2.stamp_col0[j], sc2.stamp_row0[j])
        assert x + sc2.chip[j] * k == pytest.approx(sc2.truth.x_true[j], abs=1e-10)
        assert y == pytest.approx(sc2.truth.y_true[j], abs=1e-10)


def test_noise_free_window_centroid_matches_analytic_truncation():
    """Gaussian PSF, point pinhole, no colour: the 11x11 window CoG against erf pixel integrals."""
    scn = _quiet(default(), **{
        "lab.target.pinhole_diameter_um": 0.0,
        "optics.lateral_colour.radial_px_per_nm": [], "optics.lateral_colour.uniform_x_px_per_nm": [],
        "optics.lateral_colour.uniform_y_px_per_nm": [], "optics.psf.sigma_r2_px": 0.0,
        "optics.psf.sigma0_px": 1.2,
    })
    cam = StarCamera(scn)
    sc = cam.scene(Placement(layout=star_grid(scn)))
    win = cam.render_windows(sc, frames=1, seed=0, shot_noise=False, read_noise=False, quantize=False)
    g = scn.detector.chips[0].gain_e_per_dn
    off = scn.detector.chips[0].offset_dn
    w = scn.render.window_px
    s = 1.2
    for j in range(sc.n_stars):
        img = (win.pixels[0, j] - off) * g  # electrons
        xt, yt = sc.truth.x_true[j], sc.truth.y_true[j]
        # independent reference: Gaussian integrated over each pixel = product of erf differences
        cols = win.col0[j] + np.arange(w)
        rows = win.row0[j] + np.arange(w)
        fx = 0.5 * (erf((cols + 0.5 - xt) / (s * np.sqrt(2))) - erf((cols - 0.5 - xt) / (s * np.sqrt(2))))
        fy = 0.5 * (erf((rows + 0.5 - yt) / (s * np.sqrt(2))) - erf((rows - 0.5 - yt) / (s * np.sqrt(2))))
        ref = sc.electrons[j] * np.outer(fy, fx)
        np.testing.assert_allclose(img, ref, rtol=0, atol=1e-6 * sc.electrons[j])
        x_ref, y_ref = _cog(ref, win.col0[j], win.row0[j])
        x_sim, y_sim = _cog(img, win.col0[j], win.row0[j])
        assert x_sim == pytest.approx(x_ref, abs=1e-8) and y_sim == pytest.approx(y_ref, abs=1e-8)
        # and the truncation error itself is small but not zero for an 11x11 window
        assert abs(x_ref - xt) < 1e-3


def test_truth_components_add_up(camera, scene):
    t = scene.truth
    u = t.u_ideal_px + t.platform_dx_px + t.distortion_dx_px + t.chromatic_dx_px
    v = t.v_ideal_px + t.platform_dy_px + t.distortion_dy_px + t.chromatic_dy_px
    _, x, y = camera.mosaic.focal_to_mosaic(u.to_numpy(), v.to_numpy())
    np.testing.assert_allclose(x, t.x_true, atol=1e-9)
    np.testing.assert_allclose(y, t.y_true, atol=1e-9)


def test_pixel_mean_and_variance_match_the_noise_model():
    """Per-pixel mean and variance over frames against gain, shot, read and quantisation noise."""
    scn = with_updates(default(), {"detector.background_e_per_s": 500.0})
    cam = StarCamera(scn)
    sc = cam.scene(Placement(layout=star_grid(scn)))
    n = 400
    win = cam.render_windows(sc, frames=n, seed=11)
    pix = win.pixels[:, 0].astype(float)  # star 0's window, (n, 11, 11)
    # expected electrons per pixel with this detector's own PRNU/DSNU maps
    from simcam.detector import dsnu_map, prnu_map

    sig, col0, row0 = cam.expected_windows_e(sc)
    shape = sig.shape[1:]
    kw = dict(shape=shape, row0=int(row0[0]), col0=int(col0[0]), mosaic_cols=cam.mosaic.shape[1],
              params=cam.detector_params, detector_key=cam.detector_key)
    mean_e = sig[0] * prnu_map(**kw) + dsnu_map(**kw)
    chip = scn.detector.chips[0]
    g, ron = chip.gain_e_per_dn, chip.read_noise_e
    mu = mean_e / g + chip.offset_dn
    var = (mean_e + ron**2) / g**2 + 1.0 / 12.0
    m = pix.mean(axis=0)
    v = pix.var(axis=0, ddof=1)
    # sampling errors: se(mean) = sqrt(var/n); se(var) ~ var sqrt(2/(n-1)) (Gaussian approx.;
    # Poisson excess kurtosis 1/lam is negligible at these counts). 121 pixels at 4.5 se:
    # two-sided p = 7e-6 per pixel, about 1e-3 for the window.
    assert np.all(np.abs(m - mu) < 4.5 * np.sqrt(var / n))
    assert np.all(np.abs(v - var) < 4.5 * var * np.sqrt(2.0 / (n - 1)))


def test_star_off_detector_is_a_named_error():
    scn = with_updates(default(), {"lab.target_center_px": [0.0, 0.0]})  # on the chip gap
    cam = StarCamera(scn)
    with pytest.raises(RenderError, match=r"star \d+ at focal .* off the detector"):
        cam.scene(Placement(layout=star_grid(scn), label="gap"))
    scn = with_updates(default(), {"lab.target_center_px": [-1024.0, 1000.0]})
    with pytest.raises(RenderError, match="off the detector"):
        StarCamera(scn).scene(Placement(layout=star_grid(scn)))


def test_same_seed_same_pixels_and_detector_seed_changes_maps(scene):
    a = StarCamera(default())
    b = StarCamera(default())
    sa = a.scene(scene.placement)
    wa = a.render_windows(sa, frames=2, seed=5)
    wb = b.render_windows(b.scene(scene.placement), frames=2, seed=5)
    np.testing.assert_array_equal(wa.pixels, wb.pixels)
    c = StarCamera(default(), detector_seed=99)
    wc = c.render_windows(c.scene(scene.placement), frames=2, seed=5)
    assert np.any(wc.pixels != wa.pixels)


def test_scene_cache_reuses_images_when_only_the_reference_changes():
    # a new calibrated target per Monte Carlo trial changes only the lab's reference
    # coordinates: the cached images are reused and the truth carries the new reference,
    # exactly as a camera that never saw the first target computes it
    import pandas as pd

    from simcam.starcam.targets import calibration_grid

    scn = default()
    a, b = calibration_grid(scn, marker_seed=1), calibration_grid(scn, marker_seed=2)
    assert np.array_equal(a.u_px, b.u_px) and not np.array_equal(a.reference_u_px, b.reference_u_px)
    cam = StarCamera(scn)
    first = cam.scene(Placement(layout=a, condition=7))
    cam.render_windows(first, frames=1, seed=0)          # fills the scene's window caches
    second = cam.scene(Placement(layout=b, condition=7))
    fresh = StarCamera(scn).scene(Placement(layout=b, condition=7))
    assert second.stamps is first.stamps
    np.testing.assert_array_equal(second.stamps, fresh.stamps)
    pd.testing.assert_frame_equal(second.truth, fresh.truth, check_exact=True)
    assert not np.array_equal(second.truth.x_reference, first.truth.x_reference)
    np.testing.assert_array_equal(cam.render_windows(second, frames=2, seed=5).pixels,
                                  StarCamera(scn).render_windows(fresh, frames=2, seed=5).pixels)


def test_scene_keeps_lateral_colour_per_wavelength_set_and_chip_coordinates_per_star(camera):
    # the camera's lateral-colour model is kept per wavelength set (two filters, interleaved,
    # each equal to the shift function), and a scene's reference positions are each star's
    # chip coordinates, exactly as chip by chip (the calibration grid lands on both chips)
    from simcam.starcam import optics
    from simcam.starcam.targets import calibration_grid

    scn = camera.scenario
    lc = scn.optics.lateral_colour
    u, v = np.linspace(-1900.0, 1900.0, 9), np.linspace(900.0, -900.0, 9)
    for filt in (None, scn.lab.filters[0].center_nm, None, scn.lab.filters[-1].center_nm):
        wl = camera._spectrum(filt)[0]
        got = camera._lateral_colour(wl, u, v)
        ref = optics.lateral_colour_shift_px(
            wavelength_nm=wl, u_px=u, v_px=v, ref_wavelength_nm=lc.ref_wavelength_nm,
            radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
            uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
        assert all(a.tobytes() == b.tobytes() for a, b in zip(got, ref))
    lay = calibration_grid(scn)
    sc = camera.scene(Placement(layout=lay, platform_dx_px=0.3, platform_roll_rad=1e-5, condition=21))
    assert set(sc.chip.tolist()) == {0, 1}
    ud, vd = camera.distortion.forward(u_px=lay.u_px + 0.3 - 1e-5 * lay.v_px, v_px=lay.v_px + 1e-5 * lay.u_px)
    for k in (0, 1):
        sel = sc.chip == k
        xr, yr = camera.mosaic._chip_coords(ud[sel], vd[sel], k)
        assert xr.tobytes() == sc.x_ref_chip[sel].tobytes() and yr.tobytes() == sc.y_ref_chip[sel].tobytes()
