"""Tests of the seed-000 estimators (as published) and the improved variants."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from budget.starcam.estimators import (
    EstimatorWarning,
    attitude_error,
    c4,
    chromatic_error,
    chromatic_error_decomposed,
    cubic_design_matrix,
    distortion_residual_error,
    distortion_residual_error_dof,
    high_spatial_frequency_error,
    high_spatial_frequency_error_debiased,
    low_spatial_frequency_error,
    single_star_error,
    target_marker_error,
    temporal_error,
    temporal_error_pooled,
)
from simcam.infra.errors import UserInputError

PS = 5.5  # seed-000 plate scale, passed as a parameter everywhere


def _table(rows, columns=("star", "frame", "x", "y")):
    return pd.DataFrame(rows, columns=list(columns))


# --------------------------------------------------------------------------- TE


def _te_hand_table():
    # star 0: x = 0, 1, 2 -> mean 1, squares 1 + 0 + 1 = 2 -> var (ddof 1) 1 -> sigma 1
    # star 1: x = 0, 0, 3 -> mean 1, squares 1 + 1 + 4 = 6 -> var 3 -> sigma sqrt(3)
    # y = 2 x for both stars -> sigma_y = 2 sigma_x
    xs = {0: [0.0, 1.0, 2.0], 1: [0.0, 0.0, 3.0]}
    return _table([(s, f, x, 2 * x) for s, v in xs.items() for f, x in enumerate(v)])


def test_te_published_by_hand():
    r = temporal_error(_te_hand_table(), plate_scale_arcsec=PS)
    sbar = (1.0 + math.sqrt(3.0)) / 2.0          # eq 1: mean over the W = 2 stars
    assert r.sigma_x_px == pytest.approx(sbar, rel=1e-12)
    assert r.sigma_y_px == pytest.approx(2 * sbar, rel=1e-12)
    assert r.x_3sigma_arcsec == pytest.approx(3 * sbar * 5.5, rel=1e-12)  # eq 2
    assert (r.n_stars, r.n_frames, r.n_conditions) == (2, 3, 1)


def test_te_ddof0_by_hand():
    # ddof 0: star 0 sqrt(2/3), star 1 sqrt(6/3) = sqrt(2)
    r = temporal_error(_te_hand_table(), plate_scale_arcsec=PS, ddof=0)
    assert r.sigma_x_px == pytest.approx((math.sqrt(2 / 3) + math.sqrt(2)) / 2, rel=1e-12)


def test_te_pooled_by_hand():
    # pooled: sqrt((2*1 + 2*3) / (2 + 2)) = sqrt(2)
    r = temporal_error_pooled(_te_hand_table(), plate_scale_arcsec=PS)
    assert r.sigma_x_px == pytest.approx(math.sqrt(2.0), rel=1e-12)
    # c4(3) = sqrt(2/2) Gamma(1.5) / Gamma(1) = sqrt(pi)/2
    assert c4(3) == pytest.approx(math.sqrt(math.pi) / 2, rel=1e-12)
    want = (1.0 + math.sqrt(3.0)) / 2 / (math.sqrt(math.pi) / 2)
    assert r.details["c4_corrected_mean_sigma_x_px"] == pytest.approx(want, rel=1e-12)


def test_te_unchanged_by_constant_offset_and_scales_with_plate_scale():
    t = _te_hand_table()
    shifted = t.assign(x=t["x"] + 1234.5, y=t["y"] - 77.25)
    a = temporal_error(t, plate_scale_arcsec=PS)
    b = temporal_error(shifted, plate_scale_arcsec=PS)
    assert b.sigma_x_px == pytest.approx(a.sigma_x_px, rel=1e-9)
    assert b.sigma_y_px == pytest.approx(a.sigma_y_px, rel=1e-9)
    c = temporal_error(t, plate_scale_arcsec=2 * PS)
    assert c.x_3sigma_arcsec == pytest.approx(2 * a.x_3sigma_arcsec, rel=1e-12)
    assert c.sigma_x_px == a.sigma_x_px  # exact on purpose: the plate scale never enters the pixel sigma


def _noisy_static(rng, *, w, n, sigma_x, sigma_y, conditions=(0,)):
    base = rng.uniform(100, 2000, size=(w, 2))
    rows = []
    for c in conditions:
        for s in range(w):
            xs = base[s, 0] + rng.normal(0, sigma_x, n)
            ys = base[s, 1] + rng.normal(0, sigma_y, n)
            rows += [(s, c, f, xs[f], ys[f]) for f in range(n)]
    return _table(rows, ("star", "condition", "frame", "x", "y"))


def test_te_recovers_known_sigma():
    rng = np.random.default_rng(20260101)
    w, n, sx, sy = 25, 30, 0.05, 0.08
    t = _noisy_static(rng, w=w, n=n, sigma_x=sx, sigma_y=sy)
    pub = temporal_error(t, plate_scale_arcsec=PS)
    pooled = temporal_error_pooled(t, plate_scale_arcsec=PS)
    k = float(c4(n))
    for est, sig in ((pub.sigma_x_px, sx), (pub.sigma_y_px, sy)):
        # mean of W sample sds: E = c4 sigma, sd = sigma sqrt(1 - c4^2) / sqrt(W); 5 sd band
        assert abs(est - k * sig) < 5 * sig * math.sqrt((1 - k * k) / w)
    for est, sig in ((pooled.sigma_x_px, sx), (pooled.sigma_y_px, sy)):
        # pooled variance: chi^2 with W (N-1) dof -> relative sd of sigma ~ 1/sqrt(2 W (N-1))
        assert abs(est / sig - 1) < 5 / math.sqrt(2 * w * (n - 1))


def test_te_flagged_rows_and_stars_excluded_with_warning():
    t = _te_hand_table().assign(flag=0)
    extra = _table([(7, f, 5.0 + f, 1.0) for f in range(3)]).assign(flag=4)   # star 7 lost
    t = pd.concat([t, extra], ignore_index=True)
    with pytest.warns(EstimatorWarning, match="excluded"):
        r = temporal_error(t, plate_scale_arcsec=PS)
    assert r.n_rows_excluded == 3 and r.n_stars_excluded == 1 and r.n_stars == 2
    assert r.sigma_x_px == pytest.approx((1 + math.sqrt(3)) / 2)
    assert len(r.warnings) == 2
    json.dumps(r.to_dict())


def test_te_bad_input():
    t = _te_hand_table()
    with pytest.raises(UserInputError, match="missing column.*frame"):
        temporal_error(t.drop(columns="frame"), plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="'x' is not numeric"):
        temporal_error(t.assign(x="a"), plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="repeat"):
        temporal_error(pd.concat([t, t.iloc[:1]]), plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="plate_scale_arcsec"):
        temporal_error(t, plate_scale_arcsec=-1)
    with pytest.raises(UserInputError, match="conditions"):
        temporal_error(t.assign(condition=[0, 0, 0, 1, 1, 1]), plate_scale_arcsec=PS)
    ok = temporal_error(t.assign(condition=[0, 0, 0, 1, 1, 1], star=0), plate_scale_arcsec=PS,
                        condition=1)
    assert ok.sigma_x_px == pytest.approx(math.sqrt(3))


# ------------------------------------------------------------------------- HSFE


def _hsfe_hand_table(a=0.05):
    # per (star, condition) means; two frames m - a, m + a (var ddof 1 = 2 a^2)
    means = {0: [0.0, 0.3, 0.5], 1: [1.0, 1.1, 1.5]}
    rows = []
    for s, ms in means.items():
        for c, m in enumerate(ms):
            rows += [(s, c, 0, m - a, 2 * m - a), (s, c, 1, m + a, 2 * m + a)]
    return _table(rows, ("star", "condition", "frame", "x", "y"))


def test_hsfe_published_by_hand():
    # dX: star 0 -> 0.3, 0.2; star 1 -> 0.1, 0.4 (eqs 5-6)
    # mean over stars per k: 0.2, 0.3; delta: star 0 -> 0.1, -0.1; star 1 -> -0.1, 0.1 (eqs 7-8)
    # sigma = sqrt(4 * 0.01 / (W (M-1) = 2 * 2)) = 0.1 (eq 9); y = 2 x -> 0.2
    r = high_spatial_frequency_error(_hsfe_hand_table(), plate_scale_arcsec=PS)
    assert r.sigma_x_px == pytest.approx(0.1, rel=1e-12)
    assert r.sigma_y_px == pytest.approx(0.2, rel=1e-12)
    assert r.x_3sigma_arcsec == pytest.approx(3 * 0.1 * 5.5, rel=1e-12)   # eq 11
    assert (r.n_stars, r.n_frames, r.n_conditions) == (2, 2, 3)
    res = r.residuals.sort_values(["star", "k"])
    np.testing.assert_allclose(res["delta_x_px"], [0.1, -0.1, -0.1, 0.1], atol=1e-12)


def test_hsfe_debiased_by_hand():
    # S = 0.04; each mean has variance var/N = 2 a^2 / 2 = a^2 = 0.0025; each difference
    # 0.005; sum over 2 stars x 2 differences = 0.02.
    # tau^2 = S / ((W-1)(M-1)) - sum v / (W (M-1)) = 0.04 / 2 - 0.02 / 4 = 0.015
    r = high_spatial_frequency_error_debiased(_hsfe_hand_table(), plate_scale_arcsec=PS)
    assert r.sigma_x_px == pytest.approx(math.sqrt(0.015), rel=1e-9)
    # y: S = 0.16, var = 2 a^2 too (y = 2m +- a) -> 0.16/2 - 0.005 = 0.075
    assert r.sigma_y_px == pytest.approx(math.sqrt(0.075), rel=1e-9)
    assert r.flags == ()


def test_hsfe_debiased_clips_at_zero_with_flag():
    with pytest.warns(EstimatorWarning, match="negative"):
        r = high_spatial_frequency_error_debiased(_hsfe_hand_table(a=1.0), plate_scale_arcsec=PS)
    assert r.sigma_x_px == 0.0 and "clipped_x" in r.flags


def test_hsfe_unchanged_by_common_translation_per_condition():
    rng = np.random.default_rng(5)
    t = _noisy_static(rng, w=6, n=4, sigma_x=0.01, sigma_y=0.02, conditions=range(5))
    # add a per-(star, condition) pixel error well above the temporal noise
    h = {(s, c): rng.normal(0, 0.1, 2) for s in range(6) for c in range(5)}
    key = list(zip(t["star"], t["condition"]))
    t = t.assign(x=t["x"] + [h[q][0] for q in key], y=t["y"] + [h[q][1] for q in key])
    shift = {c: rng.normal(0, 3, 2) for c in range(5)}
    moved = t.assign(x=t["x"] + t["condition"].map(lambda c: shift[c][0]),
                     y=t["y"] + t["condition"].map(lambda c: shift[c][1]))
    for fn in (high_spatial_frequency_error, high_spatial_frequency_error_debiased):
        a, b = fn(t, plate_scale_arcsec=PS), fn(moved, plate_scale_arcsec=PS)
        assert b.sigma_x_px == pytest.approx(a.sigma_x_px, rel=1e-7)
        assert b.sigma_y_px == pytest.approx(a.sigma_y_px, rel=1e-7)
        np.testing.assert_allclose(b.residuals["delta_x_px"], a.residuals["delta_x_px"], atol=1e-9)
    a = high_spatial_frequency_error(t, plate_scale_arcsec=PS)
    c = high_spatial_frequency_error(t, plate_scale_arcsec=3.0)
    assert c.y_3sigma_arcsec == pytest.approx(a.y_3sigma_arcsec * 3.0 / PS, rel=1e-12)


def test_hsfe_recovers_known_sigma_and_published_is_biased():
    # model: x_jki = base_j + common_k + h_jk + e_jki, h ~ N(0, sh), e ~ N(0, st)
    rng = np.random.default_rng(424242)
    w, m, n, sh, st = 100, 12, 30, 0.02, 0.1
    base = rng.uniform(0, 2000, w)
    rows = []
    for k in range(m):
        common = 0.2 * k
        h = rng.normal(0, sh, w)
        for j in range(w):
            e = rng.normal(0, st, n)
            xs = base[j] + common + h[j] + e
            rows += [(j, k, i, xs[i], 0.0) for i in range(n)]
    t = _table(rows, ("star", "condition", "frame", "x", "y"))
    truth = 2 * sh**2                          # variance of h(k+1) - h(k)
    noise = 2 * st**2 / n                      # temporal variance of a difference of means
    deb = high_spatial_frequency_error_debiased(t, plate_scale_arcsec=PS)
    pub = high_spatial_frequency_error(t, plate_scale_arcsec=PS)
    # Sampling: the W(M-1) residuals are MA(1) in k (rho = -1/2), so
    # Var(S) ~ 2 E[d^2]^2 n (1 + 2 rho^2) = 3 E[d^2]^2 n, n = (W-1)(M-1): relative sd of the
    # variance estimate is sqrt(3/n) of (truth + noise); allow 4 sd.
    sd = math.sqrt(3 / ((w - 1) * (m - 1))) * (truth + noise)
    assert abs(deb.details["tau2_x_px2"] - truth) < 4 * sd
    # the published sigma^2 estimates (W-1)/W (truth + noise), not the truth
    assert abs(pub.sigma_x_px**2 - (w - 1) / w * (truth + noise)) < 4 * sd
    assert pub.sigma_x_px**2 - truth > 4 * sd


def test_hsfe_missing_star_excluded_and_bad_input():
    t = _hsfe_hand_table()
    extra = _table([(9, 0, 0, 3.0, 3.0), (9, 1, 0, 3.1, 3.0)], ("star", "condition", "frame", "x", "y"))
    with pytest.warns(EstimatorWarning, match="1 star"):
        r = high_spatial_frequency_error(pd.concat([t, extra]), plate_scale_arcsec=PS)
    assert r.n_stars_excluded == 1 and r.sigma_x_px == pytest.approx(0.1)
    with pytest.raises(UserInputError, match="at least 2 conditions"):
        high_spatial_frequency_error(t[t["condition"] == 0], plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="missing column"):
        high_spatial_frequency_error(t.drop(columns="condition"), plate_scale_arcsec=PS)


# -------------------------------------------------------------------- chromatic


def _chromatic_hand_table():
    # x per (field, star): filters 500, 600, 800
    xs = {("A", 0): (10.0, 10.1, 10.4), ("A", 1): (20.0, 20.1, 20.2),
          ("B", 0): (30.0, 30.2, 30.5), ("B", 1): (40.0, 40.0, 40.3)}
    rows = []
    for (fld, s), vals in xs.items():
        for f, x in zip((500, 600, 800), vals):
            rows.append((s, fld, f, 0, x, 5.0))
    return _table(rows, ("star", "field", "filter_nm", "frame", "x", "y"))


def test_chromatic_published_by_hand():
    # delta(600-500) x: 0.1, 0.1, 0.2, 0.0 -> sum 0.4 -> / (2 W K = 2*2*2) = 0.05
    # delta(800-600) x: 0.3, 0.1, 0.3, 0.3 -> sum 1.0 -> / 8 = 0.125
    r = chromatic_error(_chromatic_hand_table(), plate_scale_arcsec=PS)
    p = r.pairs.set_index("pair")
    assert p.loc["600-500", "delta_bar_x_px"] == pytest.approx(0.05, abs=1e-12)
    assert p.loc["800-600", "delta_bar_x_px"] == pytest.approx(0.125, abs=1e-12)
    assert p.loc["800-600", "delta_bar_x_arcsec"] == pytest.approx(0.125 * 5.5, abs=1e-12)
    assert r.sigma_x_px == pytest.approx(0.125 / 3, abs=1e-12)        # max |delta| / 3
    assert r.x_3sigma_arcsec == pytest.approx(0.125 * 5.5, abs=1e-12)  # 3 (0.125/3) 5.5
    assert r.sigma_y_px == 0.0
    assert (r.n_stars, r.n_conditions, r.details["reference_filter_nm"]) == (2, 2, 600)


def test_chromatic_seed_table1_reading():
    # Build per-star differences equal to table 1's delta_bar times 2 (eq 16 halves):
    # 600-500: X -1e-4, Y 5e-3; 800-600: X 0.12, Y 7e-3. W = 25 stars, K = 4 fields.
    rows = []
    d = {500: (1e-4 * 2, -5e-3 * 2), 600: (0.0, 0.0), 800: (0.12 * 2, 7e-3 * 2)}
    for fld in ("UL", "UR", "LL", "LR"):
        for s in range(25):
            for f, (dx, dy) in d.items():
                rows.append((s, fld, f, 0, 100.0 + s + dx, 200.0 + dy))
    t = _table(rows, ("star", "field", "filter_nm", "frame", "x", "y"))
    r = chromatic_error(t, plate_scale_arcsec=PS)
    p = r.pairs.set_index("pair")
    assert p.loc["600-500", "delta_bar_x_px"] == pytest.approx(-1e-4, abs=1e-12)
    assert p.loc["600-500", "delta_bar_y_px"] == pytest.approx(5e-3, abs=1e-12)
    assert p.loc["800-600", "delta_bar_x_px"] == pytest.approx(0.12, abs=1e-12)
    assert p.loc["800-600", "delta_bar_y_px"] == pytest.approx(7e-3, abs=1e-12)
    # "max change 0.12 px, /3 = 0.04 px" -> 3 sigma = 0.12 px = 0.66" -- the seed prints it
    # as LSFE-S_y; the x value from table 1 is 7e-3 px -> 0.0385" (the seed prints 0.03" as x).
    assert r.sigma_x_px == pytest.approx(0.04, abs=1e-12)
    assert r.x_3sigma_arcsec == pytest.approx(0.66, abs=1e-12)
    assert r.y_3sigma_arcsec == pytest.approx(7e-3 * 5.5, abs=1e-12)
    assert r.details["max_over_factor_x_px"] == pytest.approx(0.04, abs=1e-12)
    assert r.details["max_abs_delta_bar_x_arcsec"] == pytest.approx(0.66, abs=1e-12)


def _radial_fields(c_lat, uniform, rng=None, noise=0.0):
    # four corner fields symmetric about the axis at (2048, 1024); 3x3 stars in each
    rows = []
    axis = np.array([2048.0, 1024.0])
    for fld, (sx, sy) in {"UL": (-1, -1), "UR": (1, -1), "LL": (-1, 1), "LR": (1, 1)}.items():
        for s in range(9):
            p = axis + np.array([sx * 1500 + 40 * (s % 3 - 1), sy * 700 + 40 * (s // 3 - 1)])
            r = p - axis
            for f, scale in ((500, -1.0), (600, 0.0), (800, 2.0)):
                shift = scale * (np.asarray(uniform) + c_lat * r)
                e = rng.normal(0, noise, 2) if rng is not None else 0.0
                q = p + shift + e
                rows.append((s, fld, f, 0, q[0], q[1]))
    return _table(rows, ("star", "field", "filter_nm", "frame", "x", "y"))


def test_chromatic_decomposed_sees_radial_colour_that_eq16_cancels():
    c_lat = 2e-5                                  # 800-600 shift 2 * 2e-5 * r: 0.06 px at r=1500
    t = _radial_fields(c_lat, uniform=(0.0, 0.0))
    pub = chromatic_error(t, plate_scale_arcsec=PS)
    dec = chromatic_error_decomposed(t, plate_scale_arcsec=PS, optical_axis_xy=(2048.0, 1024.0))
    assert pub.sigma_x_px == pytest.approx(0.0, abs=1e-9)   # symmetric fields cancel
    p = dec.pairs.set_index("pair")
    assert p.loc["800-600", "radial_coefficient"] == pytest.approx(2 * c_lat, rel=1e-6)
    assert p.loc["600-500", "radial_coefficient"] == pytest.approx(c_lat, rel=1e-6)
    assert p.loc["800-600", "uniform_x_px"] == pytest.approx(0.0, abs=1e-9)
    assert dec.sigma_x_px > 0.05 / 6


def test_chromatic_decomposed_uniform_part_is_twice_eq16():
    t = _radial_fields(1e-5, uniform=(0.03, -0.01))
    pub = chromatic_error(t, plate_scale_arcsec=PS).pairs.set_index("pair")
    dec = chromatic_error_decomposed(t, plate_scale_arcsec=PS).pairs.set_index("pair")
    for pair in ("600-500", "800-600"):
        assert dec.loc[pair, "uniform_x_px"] == pytest.approx(2 * pub.loc[pair, "delta_bar_x_px"], abs=1e-9)
        assert dec.loc[pair, "uniform_y_px"] == pytest.approx(2 * pub.loc[pair, "delta_bar_y_px"], abs=1e-9)


def test_chromatic_bad_input_and_missing_filter():
    t = _chromatic_hand_table()
    with pytest.raises(UserInputError, match="reference_filter_nm=700"):
        chromatic_error(t, plate_scale_arcsec=PS, reference_filter_nm=700)
    with pytest.raises(UserInputError, match="missing column.*filter_nm"):
        chromatic_error(t.drop(columns="filter_nm"), plate_scale_arcsec=PS)
    drop = t[~((t["field"] == "B") & (t["star"] == 1) & (t["filter_nm"] == 800))]
    with pytest.warns(EstimatorWarning, match="lack a filter"):
        r = chromatic_error(drop, plate_scale_arcsec=PS)
    assert r.n_stars_excluded == 1
    # remaining 3 pairs: 800-600 x: 0.3 + 0.1 + 0.3 = 0.7 -> / (2 * 3) = 0.11666...
    assert r.pairs.set_index("pair").loc["800-600", "delta_bar_x_px"] == pytest.approx(0.7 / 6)


# ------------------------------------------------------------------- distortion


def _grid(w_cols=8, w_rows=4):
    gx, gy = np.meshgrid(np.linspace(200, 3800, w_cols), np.linspace(150, 1850, w_rows))
    return pd.DataFrame({"star": np.arange(gx.size), "x_ref": gx.ravel(), "y_ref": gy.ravel()})


def _observed(ref, dx, dy, n=2):
    rows = []
    for j, (s, x0, y0) in enumerate(ref[["star", "x_ref", "y_ref"]].itertuples(index=False)):
        for f in range(n):
            rows.append((s, f, x0 + dx[j], y0 + dy[j]))
    return _table(rows)


def test_distortion_exact_cubic_gives_sigma_d():
    ref = _grid()
    u = (ref["x_ref"].to_numpy() - 2000) / 1800
    v = (ref["y_ref"].to_numpy() - 1000) / 850
    dx = 0.1 + 0.2 * u**3 - 0.05 * u * v
    dy = -0.3 * v + 0.1 * u * u * v
    r = distortion_residual_error(_observed(ref, dx, dy), reference=ref, plate_scale_arcsec=PS)
    # fit is exact -> sigma_DdX = 0 -> sigma_C1 = sigma_dX = sqrt(sum (d - mean)^2 / (W - 1))
    want_x = math.sqrt(np.sum((dx - dx.mean()) ** 2) / (32 - 1))
    assert r.details["sigma_ddx_px"] < 1e-12
    assert r.sigma_x_px == pytest.approx(want_x, rel=1e-9)
    assert r.sigma_y_px == pytest.approx(math.sqrt(np.sum((dy - dy.mean()) ** 2) / 31), rel=1e-9)
    assert r.details["mean_dx_px"] == pytest.approx(dx.mean(), rel=1e-9)
    assert (r.n_stars, r.n_frames) == (32, 2)
    assert set(r.residuals.columns) >= {"dx_px", "ddx_px", "fit_x_px"}


def test_distortion_formula_against_independent_fit():
    rng = np.random.default_rng(7)
    ref = _grid()
    u = (ref["x_ref"].to_numpy() - 2000) / 1800
    dx, dy = rng.normal(0, 0.05, 32) + 0.3 * u**3, rng.normal(0, 0.05, 32) + 0.2 * u
    r = distortion_residual_error(_observed(ref, dx, dy), reference=ref, plate_scale_arcsec=PS)
    # independent fit in raw (unnormalised) coordinates: same column space, same residual
    x0, y0 = ref["x_ref"].to_numpy() / 1000, ref["y_ref"].to_numpy() / 1000
    a = cubic_design_matrix(x0, y0)
    res = dx - a @ np.linalg.lstsq(a, dx, rcond=None)[0]
    s_d2 = np.sum((dx - dx.mean()) ** 2) / 31                       # eq 23
    s_dd2 = np.sum((res - res.mean()) ** 2) / 31                    # eq 27
    assert r.sigma_x_px == pytest.approx(math.sqrt(s_d2 - s_dd2), rel=1e-8)   # eq 29
    dof = distortion_residual_error_dof(_observed(ref, dx, dy), reference=ref, plate_scale_arcsec=PS)
    assert s_d2 - np.sum(res**2) / 22 > 0
    assert dof.sigma_x_px == pytest.approx(math.sqrt(s_d2 - np.sum(res**2) / 22), rel=1e-8)


def test_distortion_dof_variant_unbiased_published_biased():
    # cubic part with a known variance over the points plus white noise sn. Over R draws
    # the mean of the estimated variance must match: dof variant -> V; published ->
    # V + 9 sn^2 / (W - 1) (the noise in the 9 non-constant fitted terms). Tolerance:
    # 4 standard errors of the mean over R draws (CLT; sd estimated from the draws).
    rng = np.random.default_rng(99)
    ref = _grid()
    w = len(ref)
    u = (ref["x_ref"].to_numpy() - 2000) / 1800
    v = (ref["y_ref"].to_numpy() - 1000) / 850
    cubic = 0.03 * u**3 + 0.02 * u * v
    var_true = float(np.var(cubic, ddof=1))
    sn = 0.03
    pub, dof = [], []
    for _ in range(300):
        dx = cubic + rng.normal(0, sn, w)
        t = _observed(ref, dx, np.zeros(w), n=1)
        a = distortion_residual_error(t, reference=ref, plate_scale_arcsec=PS)
        pub.append(a.sigma_x_px**2)
        b_d = a.details["sigma_dx_px"] ** 2
        res = a.residuals["ddx_px"].to_numpy()
        dof.append(b_d - np.sum(res**2) / (w - 10))
    pub, dof = np.array(pub), np.array(dof)
    se = lambda z: z.std(ddof=1) / math.sqrt(z.size)  # noqa: E731
    assert abs(dof.mean() - var_true) < 4 * se(dof)
    assert abs(pub.mean() - (var_true + 9 * sn**2 / (w - 1))) < 4 * se(pub)
    assert pub.mean() - var_true > 4 * se(pub)


def test_distortion_dof_clips_with_flag_on_pure_noise():
    rng = np.random.default_rng(3)
    ref = _grid()
    # find a draw where the dof estimate is negative (pure noise: about half the draws)
    for _ in range(50):
        dx = rng.normal(0, 0.05, 32)
        t = _observed(ref, dx, dx, n=1)
        a = cubic_design_matrix(*(ref[["x_ref", "y_ref"]].to_numpy().T / 1000))
        res = dx - a @ np.linalg.lstsq(a, dx, rcond=None)[0]
        if np.var(dx, ddof=1) - np.sum(res**2) / 22 < 0:
            break
    with pytest.warns(EstimatorWarning, match="negative variance"):
        r = distortion_residual_error_dof(t, reference=ref, plate_scale_arcsec=PS)
    assert r.sigma_x_px == 0.0 and "clipped_x" in r.flags and not math.isnan(r.sigma_y_px)


def test_distortion_bad_input():
    ref = _grid()
    t = _observed(ref, np.zeros(32), np.zeros(32))
    with pytest.raises(UserInputError, match="no reference"):
        distortion_residual_error(t, reference=ref.iloc[1:], plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="at least 10"):
        small = ref.iloc[:9]
        distortion_residual_error(t[t["star"] < 9], reference=small, plate_scale_arcsec=PS)
    with pytest.raises(UserInputError, match="x_ref"):
        distortion_residual_error(t, reference=ref.drop(columns="x_ref"), plate_scale_arcsec=PS)
    with pytest.warns(EstimatorWarning, match="without a good centroid"):
        r = distortion_residual_error(t[t["star"] != 5], reference=ref, plate_scale_arcsec=PS)
    assert r.n_stars_excluded == 1 and r.n_stars == 31


# ------------------------------------------------------------------ combination


def test_combination_functions_by_hand():
    assert low_spatial_frequency_error(chromatic=0.03, distortion=0.29, marker=0.5) == pytest.approx(
        math.sqrt(0.03**2 + 0.79**2))
    assert single_star_error(temporal=3.0, high_frequency=4.0, low_frequency=12.0) == pytest.approx(13.0)
    assert attitude_error(single_star=1.8, n_stars=9) == pytest.approx(0.6)
    np.testing.assert_allclose(
        low_spatial_frequency_error(chromatic=np.array([0.0, 3.0]), distortion=np.array([1.0, 1.0]),
                                    marker=np.array([0.0, 3.0])), [1.0, 5.0])
    with pytest.raises(UserInputError, match="marker"):
        low_spatial_frequency_error(chromatic=0.1, distortion=0.1, marker=-0.1)
    with pytest.raises(UserInputError, match="n_stars"):
        attitude_error(single_star=1.0, n_stars=0)


def test_results_are_frozen_and_json_ready():
    import dataclasses

    ref = _grid()
    results = [
        high_spatial_frequency_error(_hsfe_hand_table(), plate_scale_arcsec=PS),
        high_spatial_frequency_error_debiased(_hsfe_hand_table(), plate_scale_arcsec=PS),
        chromatic_error(_chromatic_hand_table(), plate_scale_arcsec=PS),
        chromatic_error_decomposed(_radial_fields(1e-5, (0.01, 0.0)), plate_scale_arcsec=PS),
        distortion_residual_error(_observed(ref, 0.01 * np.arange(32.0) ** 0.5, np.zeros(32)),
                                  reference=ref, plate_scale_arcsec=PS),
    ]
    for r in results:
        d = json.loads(json.dumps(r.to_dict()))
        assert d["x_3sigma_arcsec"] == pytest.approx(3 * r.sigma_x_px * PS)
        assert {"n_stars", "n_frames", "n_conditions", "warnings", "flags"} <= set(d)
        with pytest.raises(dataclasses.FrozenInstanceError):
            r.sigma_x_px = 0.0
    assert len(results[0].to_dict()["residuals"]) == 4


def test_target_marker_error_round_trips_and_scales():
    r = target_marker_error(x_3sigma_arcsec=0.5, y_3sigma_arcsec=0.5, plate_scale_arcsec=PS)
    assert r.sigma_x_px == pytest.approx(0.5 / (3 * 5.5))
    assert r.x_3sigma_arcsec == pytest.approx(0.5)
    assert target_marker_error(x_3sigma_arcsec=0.5, y_3sigma_arcsec=0.5,
                               plate_scale_arcsec=11.0).sigma_x_px == pytest.approx(r.sigma_x_px / 2)
    with pytest.raises(UserInputError, match="x_3sigma_arcsec"):
        target_marker_error(x_3sigma_arcsec=-0.5, y_3sigma_arcsec=0.5, plate_scale_arcsec=PS)


def test_per_star_statistics_match_pandas_groupby():
    # the array implementation against pandas' groupby (independent code): sorted groups,
    # counts, means and ddof variances, singletons giving NaN variance
    from budget.starcam.estimators.common import _per_star_stats, _Rows

    rng = np.random.default_rng(8)
    n = 500
    df = pd.DataFrame({"star": rng.integers(0, 30, n), "condition": rng.integers(0, 4, n),
                       "x": 1000.0 + rng.normal(0, 0.01, n), "y": -5.0 + rng.normal(0, 0.02, n)})
    df = pd.concat([df, pd.DataFrame({"star": [99], "condition": [7], "x": [1.0], "y": [2.0]})],
                   ignore_index=True)
    for by in (["star"], ["star", "condition"]):
        for ddof in (0, 1):
            got = _per_star_stats(_Rows({c: df[c].to_numpy() for c in df.columns}), by, ddof).to_frame()
            g = df.groupby(by, sort=True)
            ref = pd.DataFrame({"n": g["x"].count(), "mean_x": g["x"].mean(), "mean_y": g["y"].mean(),
                                "var_x": g["x"].var(ddof=ddof), "var_y": g["y"].var(ddof=ddof)}).reset_index()
            # x/sd ~ 1e5: both implementations round the deviations at ~1e5 * 2.2e-16 relative
            pd.testing.assert_frame_equal(got, ref, check_exact=False, rtol=1e-9, atol=0, check_dtype=False)


def test_duplicate_key_check_matches_pandas():
    # the factorised-code check against pandas' duplicated() on random small tables with
    # repeated keys, string and float key columns
    from budget.starcam.estimators.common import _has_duplicate_keys

    rng = np.random.default_rng(0)
    for _ in range(200):
        n = int(rng.integers(2, 40))
        df = pd.DataFrame({"a": rng.integers(0, 4, n), "f": rng.choice(["n", "s", "e"], n),
                           "b": rng.integers(0, 3, n).astype(float)})
        assert _has_duplicate_keys(df, ("a", "f", "b")) == bool(df.duplicated(subset=["a", "f", "b"]).any())


def test_linear_unique_equals_numpy_unique():
    # the presence-table unique of integer keys against numpy.unique: values, dtype, inverse,
    # for signed and unsigned keys of small and large range (the latter sorted by numpy)
    from budget.starcam.estimators.common import _unique

    rng = np.random.default_rng(3)
    for dtype in (np.int64, np.int32, np.uint8, np.uint64):
        for n in (1, 2, 100, 5000):
            for span in (1, 3, 50, 10**6):
                a = rng.integers(0, min(span, np.iinfo(dtype).max), n).astype(dtype)
                if np.issubdtype(dtype, np.signedinteger):
                    a = a - dtype(25)
                u, inv = np.unique(a, return_inverse=True)
                got_u, got_inv = _unique(a, return_inverse=True)
                assert got_u.dtype == u.dtype and np.array_equal(got_u, u)
                assert got_inv.dtype == inv.dtype and np.array_equal(got_inv, inv)
                assert np.array_equal(_unique(a), u)
    near_max = np.array([2**64 - 1, 2**64 - 3, 2**64 - 1], dtype=np.uint64)
    assert np.array_equal(_unique(near_max, return_inverse=True)[1], np.unique(near_max, return_inverse=True)[1])
    assert np.array_equal(_unique(near_max), np.unique(near_max))


def test_result_tables_are_built_on_first_access_and_pickle():
    # the estimators hand their tables over as builders (a Monte Carlo trial reads only the
    # sigmas); read, pickled, copied or serialised, a result gives the same table
    import copy
    import pickle

    r = high_spatial_frequency_error(_hsfe_hand_table(), plate_scale_arcsec=PS)
    assert not isinstance(r.__dict__["residuals"], pd.DataFrame)
    for other in (pickle.loads(pickle.dumps(r)), copy.deepcopy(r)):
        pd.testing.assert_frame_equal(other.residuals, r.residuals, check_exact=True)
    assert r.residuals is r.residuals
    assert r.to_dict()["residuals"] == r.residuals.to_dict(orient="records")
