"""Tests of budget.centroid.core and budget.centroid.frames (thresholded CoG, IWCoG, full-frame
pipeline, flags)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pandas as pd
import pytest
from photutils.centroids import centroid_com
from scipy.special import erf

from budget.centroid.core import (
    CentroidFlag,
    CentroidWarning,
    centroid_cog,
    centroid_gaussian_fit,
    centroid_iwcog,
    centroid_windows,
    subtract_dark,
    window_background,
)
from budget.centroid.frames import centroid_frames, detect_stars, extract_windows, match_stars
from simcam.infra.errors import UserInputError


def _pixel_gaussian(n_pix, centre, sigma):
    """Fraction of a 1-D Gaussian in each pixel [j-0.5, j+0.5) (pixel centres at j)."""
    j = np.arange(n_pix)
    s2 = math.sqrt(2.0) * sigma
    return 0.5 * (erf((j + 0.5 - centre) / s2) - erf((j - 0.5 - centre) / s2))


def _star_windows(xc, yc, *, size=11, sigma=1.0, flux=20000.0, background=100.0):
    xc, yc = np.atleast_1d(xc), np.atleast_1d(yc)
    out = np.empty((xc.size, size, size))
    for q in range(xc.size):
        out[q] = flux * np.outer(_pixel_gaussian(size, yc[q], sigma), _pixel_gaussian(size, xc[q], sigma))
    return out + background


# --------------------------------------------------------------- CoG by hand


def test_cog_by_hand():
    win = np.zeros((1, 3, 3))
    win[0, 1, 1], win[0, 1, 2] = 1.0, 3.0
    # weights 1 at column 1 and 3 at column 2: x = (1*1 + 3*2) / 4 = 1.75, y = 1
    x, y, f, flag = centroid_cog(win, x0=100.0, y0=200.0, background=0.0, threshold_dn=0.5)
    assert x[0] == pytest.approx(101.75, abs=1e-14) and y[0] == pytest.approx(201.0, abs=1e-14)
    assert f[0] == pytest.approx(4.0, rel=np.finfo(float).eps)  # sum of 1 and 3: at most one rounding
    # threshold subtracted: weights 0.5 and 2.5 -> x = (0.5*1 + 2.5*2) / 3 = 5.5/3
    x, _, f, flag = centroid_cog(win, x0=0.0, y0=0.0, background=0.0, threshold_dn=0.5,
                                 subtract_threshold=True)
    assert x[0] == pytest.approx(5.5 / 3, abs=1e-14) and f[0] == pytest.approx(4.0, rel=np.finfo(float).eps)
    # the brightest pixel (column 2) is on the 3x3 window's border
    assert flag[0] == CentroidFlag.EDGE


def test_border_background_by_hand():
    win = np.arange(25, dtype=float).reshape(1, 5, 5)
    # border: 0..4, 20..24, 5, 10, 15, 9, 14, 19 -> 16 values, median (10 + 14) / 2 = 12
    med, sig = window_background(win)
    border = np.r_[0:5, 20:25, 5, 10, 15, 9, 14, 19].astype(float)
    assert med[0] == pytest.approx(12.0, rel=np.finfo(float).eps)  # (10 + 14) / 2: one rounding at most
    assert sig[0] == pytest.approx(1.482602218505602 * np.median(np.abs(border - 12.0)))


# --------------------------------------------------------- photutils agreement


@pytest.mark.parametrize("subtract_threshold", [False, True])
def test_cog_matches_photutils_centroid_com(subtract_threshold):
    rng = np.random.default_rng(11)
    n = 40
    xc, yc = 5 + rng.uniform(-1, 1, n), 5 + rng.uniform(-1, 1, n)
    win = _star_windows(xc, yc, sigma=1.2)
    bg, thr = 100.0, 60.0
    x, y, _, flag = centroid_cog(win, x0=1000.0, y0=50.0, background=bg, threshold_dn=thr,
                                 subtract_threshold=subtract_threshold)
    assert np.all(flag == 0)
    for q in range(n):
        s = win[q] - bg
        data = np.where(s > thr, s - thr if subtract_threshold else s, 0.0)
        px, py = centroid_com(data)
        assert abs(x[q] - (1000.0 + px)) < 1e-10 and abs(y[q] - (50.0 + py)) < 1e-10


def test_nan_pixel_flagged_and_matches_photutils_mask():
    win = _star_windows(5.3, 4.8)
    win[0, 2, 7] = np.nan
    with pytest.warns(CentroidWarning, match="NONFINITE"):
        t = centroid_windows(win, x0=0.0, y0=0.0, background=100.0, threshold_dn=0.0)
    assert t.loc[0, "flag"] == CentroidFlag.NONFINITE
    s = win[0] - 100.0
    px, py = centroid_com(np.where(s > 0, s, 0.0))        # photutils masks the NaN
    assert t.loc[0, "x"] == pytest.approx(px, abs=1e-10) and t.loc[0, "y"] == pytest.approx(py, abs=1e-10)


def test_saturated_and_lost_flags_warn():
    win = np.concatenate([_star_windows(5.0, 5.0, flux=1e6), np.full((1, 11, 11), 100.0)])
    with pytest.warns(CentroidWarning) as rec:
        t = centroid_windows(win, x0=[0, 20], y0=[0, 0], star=[3, 4], background=100.0,
                             threshold_dn=30.0, adc_max_dn=4095.0)
    msgs = " ".join(str(w.message) for w in rec)
    assert "SATURATED" in msgs and "star=3" in msgs and "LOST" in msgs and "star=4" in msgs
    assert t.loc[0, "flag"] & CentroidFlag.SATURATED
    assert t.loc[1, "flag"] & CentroidFlag.LOST and math.isnan(t.loc[1, "x"])
    assert list(t.columns) == ["star", "frame", "x", "y", "flux_dn", "flag"]


def test_translation_of_window_origin_moves_centroid():
    win = _star_windows(4.6, 5.2)
    a = centroid_cog(win, x0=0.0, y0=0.0, background=100.0, threshold_dn=10.0)
    b = centroid_cog(win, x0=2048.0, y0=-7.0, background=100.0, threshold_dn=10.0)
    assert b[0][0] - a[0][0] == pytest.approx(2048.0, abs=1e-9)
    assert b[1][0] - a[1][0] == pytest.approx(-7.0, abs=1e-9)


# ---------------------------------------------------------------------- IWCoG


def test_iwcog_smaller_scurve_than_thresholded_cog():
    # noise-free Gaussian sigma 1 px in 7x7 windows at sub-pixel offsets along 45 deg
    off = np.linspace(-0.5, 0.5, 21)
    win = _star_windows(3 + off, 3 + off, size=7, sigma=1.0, background=0.0)
    xc, _, _, _ = centroid_cog(win, x0=0.0, y0=0.0, background=0.0, threshold_dn=1e-9)
    xi, _, _, fi = centroid_iwcog(win, x0=0.0, y0=0.0, background=0.0, threshold_dn=1e-9,
                                  weight_sigma_px=1.0, psf_sigma_px=1.0)
    assert np.all(fi == 0)
    err_cog = np.max(np.abs(xc - (3 + off)))
    err_iw = np.max(np.abs(xi - (3 + off)))
    assert err_cog > 1e-3          # truncation S-curve of a 7x7 CoG (NOTES.md: ~0.005 px)
    assert err_iw < err_cog / 5   # measured: 4.6e-4 px against 4.6e-3 px


def test_iwcog_gain_does_not_change_fixed_point():
    win = _star_windows(np.array([5.31, 4.77]), np.array([4.9, 5.42]), sigma=1.3)
    a = centroid_iwcog(win, x0=0.0, y0=0.0, weight_sigma_px=1.3, tol_px=1e-10, max_iter=500)
    b = centroid_iwcog(win, x0=0.0, y0=0.0, weight_sigma_px=1.3, psf_sigma_px=1.3, tol_px=1e-10)
    np.testing.assert_allclose(a[0], b[0], atol=1e-8)
    np.testing.assert_allclose(a[1], b[1], atol=1e-8)


def test_iwcog_not_converged_flag():
    win = _star_windows(5.4, 5.4)
    with pytest.warns(CentroidWarning, match="NOT_CONVERGED"):
        t = centroid_windows(win, x0=0.0, y0=0.0, method="iwcog", weight_sigma_px=3.0,
                             max_iter=2, tol_px=1e-12)
    assert t.loc[0, "flag"] & CentroidFlag.NOT_CONVERGED


def test_gaussian_fit_exact_on_noise_free_windows():
    rng = np.random.default_rng(4)
    xt, yt = 5 + rng.uniform(-0.5, 0.5, 20), 5 + rng.uniform(-0.5, 0.5, 20)
    win = _star_windows(xt, yt, sigma=1.3, flux=5e4, background=80.0)
    x, y, f, flag, sig, bg = centroid_gaussian_fit(win, x0=10.0, y0=20.0, return_details=True)
    assert np.all(flag == 0)
    # the model is the generating model: exact up to the convergence tolerance
    np.testing.assert_allclose(x, 10.0 + xt, atol=1e-8)
    np.testing.assert_allclose(y, 20.0 + yt, atol=1e-8)
    np.testing.assert_allclose(sig, 1.3, rtol=1e-7)
    np.testing.assert_allclose(bg, 80.0, rtol=1e-7)
    np.testing.assert_allclose(f, 5e4, rtol=1e-7)


def test_gaussian_fit_noise_scatter_near_cramer_rao():
    # Background-free Gaussian star of flux F, width s, uniform read noise r per pixel:
    # unweighted LSQ is ML and its position sd is close to the Cramer-Rao bound
    # sd_x^2 = r^2 / sum_ab (F dE/dx)^2. We draw R = 400 windows (fixed seed); the sample
    # sd of the errors has relative sd 1/sqrt(2(R-1)) = 3.5 %; allow 15 % (4 sd) above the
    # bound (the bound here ignores the 3 nuisance parameters, which cost a few %).
    rng = np.random.default_rng(12)
    r_e, flux, s = 20.0, 3000.0, 1.2
    n = 400
    xt, yt = 5 + rng.uniform(-0.3, 0.3, n), 5 + rng.uniform(-0.3, 0.3, n)
    clean = _star_windows(xt, yt, sigma=s, flux=flux, background=0.0)
    noisy = clean + rng.normal(0, r_e, clean.shape)
    x, y, _, flag = centroid_gaussian_fit(noisy, x0=0.0, y0=0.0, background=0.0,
                                          threshold_dn=3 * r_e, sigma_start_px=1.0)
    assert np.all(flag == 0)
    j = np.arange(11)
    e = _pixel_gaussian(11, 5.0, s)
    g = lambda t: np.exp(-0.5 * (t / s) ** 2) / (math.sqrt(2 * math.pi) * s)  # noqa: E731
    de = g(j - 0.5 - 5.0) - g(j + 0.5 - 5.0)
    crb = r_e / math.sqrt(np.sum((flux * np.outer(e, de)) ** 2))
    sd = np.std(x - xt, ddof=1)
    assert crb * (1 - 4 / math.sqrt(2 * (n - 1))) < sd < crb * 1.15


def test_cog_noise_scatter_matches_photutils_on_noisy_windows():
    # same background and threshold -> identical definition, also with noise
    rng = np.random.default_rng(2)
    clean = _star_windows(5 + rng.uniform(-.5, .5, 30), 5 + rng.uniform(-.5, .5, 30))
    noisy = rng.poisson(clean) + rng.normal(0, 5.0, clean.shape)
    x, y, _, _ = centroid_cog(noisy, x0=0.0, y0=0.0, background=100.0, threshold_dn=50.0)
    for q in range(30):
        s = noisy[q] - 100.0
        px, py = centroid_com(np.where(s > 50.0, s, 0.0))
        assert abs(x[q] - px) < 1e-10 and abs(y[q] - py) < 1e-10


# ------------------------------------------------------------ full frames


def _frame(stars, *, shape=(64, 96), sigma=1.1, flux=30000.0, level=200.0):
    img = np.full(shape, level)
    for (x, y) in stars:
        img += flux * np.outer(_pixel_gaussian(shape[0], y, sigma), _pixel_gaussian(shape[1], x, sigma))
    return img


def test_detect_match_and_windows():
    stars = [(10.3, 12.6), (50.2, 30.1), (80.7, 50.4)]
    img = _frame(stars)
    det = detect_stars(img, threshold_dn=100.0, background_dn=200.0)
    assert len(det) == 3
    np.testing.assert_array_equal(det["x_peak"], [10, 50, 81])
    np.testing.assert_array_equal(det["y_peak"], [13, 30, 50])
    m = match_stars(x=det["x_peak"], y=det["y_peak"], x_ref=[81.0, 10.0, 30.0], y_ref=[50.0, 13.0, 5.0])
    np.testing.assert_array_equal(m, [2, 0, -1])
    # two references near one detection: only the closer one gets it
    m2 = match_stars(x=[10.0], y=[10.0], x_ref=[11.0, 10.5], y_ref=[10.0, 10.0])
    np.testing.assert_array_equal(m2, [-1, 0])
    win, x0, y0, flag = extract_windows(img, x_center=[3, 50], y_center=[30, 30], size_px=11)
    assert flag[0] == CentroidFlag.EDGE and flag[1] == 0
    # the window origin is an integer pixel index and the pixels are copied: exact
    assert np.isnan(win[0, 0, 0]) and x0[1] == 45.0 and y0[1] == 25.0
    assert win[1, 5, 5] == img[30, 50]


def test_subtract_dark_averages_stack():
    darks = np.stack([np.full((4, 5), 10.0), np.full((4, 5), 14.0)])
    out = subtract_dark(np.full((2, 4, 5), 20.0), dark=darks)
    assert out.shape == (2, 4, 5) and np.all(out == 8.0)
    with pytest.raises(UserInputError, match="dark"):
        subtract_dark(np.zeros((4, 5)), dark=np.zeros((5, 4)))


def test_centroid_frames_recovers_positions_and_flags_lost_star():
    rng = np.random.default_rng(8)
    stars = [(20.3, 15.7), (60.45, 40.2), (85.1, 20.9)]
    dark = np.full((64, 96), 200.0) + rng.normal(0, 2.0, (64, 96))   # fixed pattern
    frames = []
    for f in range(3):
        visible = stars if f != 1 else stars[:2]          # star 2 lost in frame 1
        clean = _frame(visible, level=0.0) + dark
        frames.append(clean + rng.normal(0, 3.0, clean.shape))
    with pytest.warns(CentroidWarning) as rec:
        t = centroid_frames(frames, dark=dark, reference_xy=np.array(stars), frame_ids=[10, 11, 12],
                            threshold_sigma=8.0, extra_columns={"condition": 4, "filter_nm": 600})
    msgs = [str(w.message) for w in rec]
    assert any("UNMATCHED" in m and "(star=2, frame=11)" in m for m in msgs)
    assert any("LOST" in m for m in msgs)
    assert len(t) == 9 and set(t["condition"]) == {4} and set(t["frame"]) == {10, 11, 12}
    lost = t[(t["star"] == 2) & (t["frame"] == 11)].iloc[0]
    assert int(lost["flag"]) & CentroidFlag.UNMATCHED and math.isnan(lost["x"])
    good = t[t["flag"] == 0]
    assert len(good) == 8
    truth = np.array(stars)[good["star"].to_numpy()]
    # 11x11 CoG of a sigma 1.1 px star: truncation at 5 px is negligible; threshold bias
    # and noise (SNR ~ 1e3) stay below 0.02 px
    assert np.max(np.abs(good["x"].to_numpy() - truth[:, 0])) < 0.02
    assert np.max(np.abs(good["y"].to_numpy() - truth[:, 1])) < 0.02


def test_centroid_frames_reference_from_first_frame_and_iwcog():
    stars = [(20.3, 15.7), (60.45, 40.2)]
    frames = [_frame(stars), _frame(stars)]
    t = centroid_frames(frames, method="iwcog", threshold_dn=50.0, weight_sigma_px=1.1,
                        psf_sigma_px=1.1)
    assert len(t) == 4 and np.all(t["flag"] == 0)
    t0 = t[t["frame"] == 0].sort_values("star")
    np.testing.assert_allclose(t0["x"], [20.3, 60.45], atol=2e-3)
    np.testing.assert_allclose(t0["y"], [15.7, 40.2], atol=2e-3)


def test_bad_input():
    with pytest.raises(UserInputError, match="windows"):
        centroid_cog(np.zeros((2, 2)), x0=0, y0=0)
    with pytest.raises(UserInputError, match="x0"):
        centroid_cog(np.zeros((2, 5, 5)), x0=[0, 1, 2], y0=0)
    with pytest.raises(UserInputError, match="method"):
        centroid_windows(np.zeros((1, 5, 5)), x0=0, y0=0, method="moffat")
    with pytest.raises(UserInputError, match="weight_sigma_px"):
        centroid_iwcog(np.zeros((1, 5, 5)), x0=0, y0=0, weight_sigma_px=0)
    with pytest.raises(UserInputError, match="background"):
        centroid_cog(np.zeros((1, 5, 5)), x0=0, y0=0, background="mean")
    with pytest.raises(UserInputError, match="reference_xy"):
        centroid_frames([np.zeros((8, 8))], reference_xy=[1, 2, 3], threshold_dn=1.0)


def test_centroid_table_feeds_the_estimators():
    # plumbing: a centroid table from windows goes straight into TE
    from budget.starcam.estimators import temporal_error

    rng = np.random.default_rng(21)
    w, n = 5, 30
    xt = np.repeat(5 + rng.uniform(-0.5, 0.5, w), n)
    yt = np.repeat(5 + rng.uniform(-0.5, 0.5, w), n)
    win = rng.poisson(_star_windows(xt, yt)) + rng.normal(0, 5.0, (w * n, 11, 11))
    t = centroid_windows(win, x0=0.0, y0=0.0, star=np.repeat(np.arange(w), n),
                         frame=np.tile(np.arange(n), w), background=100.0, threshold_dn=50.0,
                         extra_columns={"condition": 0})
    r = temporal_error(t, plate_scale_arcsec=5.5)
    want = np.mean([np.std(t.loc[t["star"] == s, "x"], ddof=1) for s in range(w)])
    assert r.sigma_x_px == pytest.approx(want, rel=1e-12) and r.n_stars == w and r.n_frames == n


def test_gaussian_fit_flags_empty_window_lost():
    win = np.concatenate([_star_windows(5.2, 4.9), np.full((1, 11, 11), 100.0)])
    with pytest.warns(CentroidWarning, match="LOST"):
        t = centroid_windows(win, x0=0.0, y0=0.0, method="gauss")
    assert t.loc[0, "flag"] == 0 and t.loc[1, "flag"] & CentroidFlag.LOST
    assert t.loc[0, "x"] == pytest.approx(5.2, abs=1e-6) and math.isnan(t.loc[1, "x"])


def test_border_background_matches_numpy_on_random_windows():
    rng = np.random.default_rng(31)
    win = rng.integers(0, 20, (300, 7, 9)).astype(float)     # many ties
    win[::7, 0, 3] = np.nan
    med, sig = window_background(win)
    for q in range(300):
        b = np.concatenate([win[q, 0], win[q, -1], win[q, 1:-1, 0], win[q, 1:-1, -1]])
        b = b[np.isfinite(b)]
        m = np.median(b)
        assert med[q] == pytest.approx(m, rel=np.finfo(float).eps)  # mean of two values: one rounding
        assert sig[q] == pytest.approx(1.482602218505602 * np.median(np.abs(b - m)), abs=1e-12)


def test_median_by_counting_equals_selection():
    # _median counts positive whole values spanning less than MEDIAN_COUNT_SPAN (ADC codes)
    # and selects otherwise: the same number as selection and numpy either way, odd and even
    # counts, ties, spans at the limit, fractions, zeros and negative values
    from budget.centroid.kernels import MEDIAN_COUNT_SPAN, _median, _median_select

    g = np.random.default_rng(8)
    span = MEDIAN_COUNT_SPAN
    cases = [g.integers(90, 130, m).astype(float) for m in (1, 2, 3, 39, 40, 41)]
    cases += [np.r_[100.0, 100.0 + span - 1, g.integers(100, 100 + span, 38)],  # counted
              np.r_[100.0, 100.0 + span, g.integers(100, 100 + span, 38)],  # selected: span too wide
              g.integers(0, 20, 40).astype(float),  # zeros: selected
              g.integers(-20, 20, 40).astype(float),
              g.integers(90, 130, 40) + 0.5, g.normal(100.0, 3.0, 40), np.full(40, 7.0)]
    for v in cases:
        got = _median(v.copy(), v.size)
        assert got == _median_select(v.copy(), v.size) == np.median(v)


def _frame_with_stars(seed, *, big_star=False):
    rng = np.random.default_rng(seed)
    rows, cols = 300, 400
    frame = rng.normal(100.0, 4.0, (rows, cols))
    yy, xx = np.mgrid[0:rows, 0:cols]
    ref = np.array([[50.3, 40.7], [58.1, 44.2], [200.6, 150.4], [3.2, 120.8], [395.4, 290.1], [300.0, 200.0]])
    for i, (x, y) in enumerate(ref):
        if i == len(ref) - 1 and not big_star:
            continue  # a reference without a star
        s = 6.0 if (big_star and i == 2) else 1.2
        frame += 900.0 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * s * s))
    frame[150, 330] += 400.0  # a hot pixel, and a small noise blob near a reference
    frame[44:46, 52:54] += 60.0
    return np.round(frame).astype(np.uint16), ref


@pytest.mark.parametrize("big_star", [False, True])
def test_reference_list_path_equals_whole_frame_detection(monkeypatch, big_star):
    """Detection in boxes around the references gives the table the whole-frame labelling
    gives (stars close together, at the frame's edges, a missing star, a noise blob, dark
    subtraction; a star larger than its box falls back to the whole frame)."""
    import budget.centroid.frames as c

    frames = [_frame_with_stars(s, big_star=big_star)[0] for s in (1, 2)]
    ref = _frame_with_stars(1, big_star=big_star)[1]
    dark = np.random.default_rng(9).normal(2.0, 1.0, frames[0].shape)
    opts = dict(reference_xy=ref, dark=dark, threshold_sigma=5.0, window_size_px=7)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fast = c.centroid_frames(frames, **opts)
        calls = []
        real = c._detect_near
        monkeypatch.setattr(c, "_detect_near", lambda *a, **k: calls.append(real(*a, **k)) or None)
        full = c.centroid_frames(frames, **opts)
    pd.testing.assert_frame_equal(fast, full)
    assert (calls[0] is None) == big_star  # the big star's halo leaves its box: whole frame
