"""LSFE-C1's truth over the whole field the camera uses (issue #33 item 4), against an independent
computation: this test's own sampling of the field, its own chip geometry and mosaic coordinates,
its own 2-D cubic least-squares fit with numpy, and only the world's functions for the lens
(``simcam.starcam.correction.lamp_image_focal_px``: distortion then the lamp's lateral colour) and,
on the default camera, what the camera reports (``StarCamera.report_positions``). Nothing of
budget.starcam's estimators or truth helpers is used.

The independent value is a Monte Carlo quadrature: ``N`` points uniform over the chips' area (a
point whose lamp image falls off the chips is no star's position and is dropped, as in the
truth), so its mean square carries a standard error from its own sample (sd of r^2 / sqrt(N));
fixed seeds. The truth is a midpoint rule on 144 x 72 cells (16 x validation.field_grid along
the long side); measured against 576 x 288 cells its rms moved by 0.3 % (x) and 0.2 % (y), below
the Monte Carlo's standard error here (0.7-0.9 % of the rms), so the comparison is within 4 of
the Monte Carlo's standard errors.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from budget.starcam.study import STUDY
from budget.starcam.truth import lsfe_c1_truth
from simcam.starcam.correction import lamp_image_focal_px
from simcam.starcam.scenario import default, with_updates

N_POINTS = 60_000
Z = 4.0


def _chips(scn):
    """Own geometry of the default mosaic: chip centres along u, no offsets or rotations."""
    det = scn.detector
    assert all((c.offset_x_px, c.offset_y_px, c.rotation_deg) == (0.0, 0.0, 0.0) for c in det.chips)
    k = np.arange(det.n_chips)
    return det, (k - (det.n_chips - 1) / 2.0) * (det.chip_cols + det.gap_px)


def _to_mosaic(scn, u, v):
    """Own focal (u, v) px -> mosaic (x, y) px; NaN off the chips (pixel areas [-0.5, n - 0.5))."""
    det, cu = _chips(scn)
    x = np.full(u.shape, np.nan)
    y = np.full(u.shape, np.nan)
    for k, c in enumerate(cu):
        xc = u - c + (det.chip_cols - 1) / 2.0
        yc = v + (det.chip_rows - 1) / 2.0
        on = (xc >= -0.5) & (xc < det.chip_cols - 0.5) & (yc >= -0.5) & (yc < det.chip_rows - 0.5)
        x[on], y[on] = k * det.chip_cols + xc[on], yc[on]
    return x, y


def _uniform_field(scn, n, seed):
    """``n`` points uniform over the chips' area (gaps excluded): a chip at random, then a point."""
    det, cu = _chips(scn)
    rng = np.random.default_rng(seed)
    k = rng.integers(0, det.n_chips, n)
    u = cu[k] + rng.uniform(-det.chip_cols / 2, det.chip_cols / 2, n)
    v = rng.uniform(-det.chip_rows / 2, det.chip_rows / 2, n)
    return u, v


def _tiling(scn, rows, cols, extent):
    """Own grid points: centres of a rows x cols tiling of ``extent`` of the mosaic's extent."""
    det, _ = _chips(scn)
    width = det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px
    col, row = np.meshgrid(np.arange(cols), np.arange(rows))
    return ((col.ravel() - (cols - 1) / 2.0) * width * extent / cols,
            (row.ravel() - (rows - 1) / 2.0) * det.chip_rows * extent / rows)


def _cubic(x, y):
    return np.column_stack([x**a * y ** (d - a) for d in range(4) for a in range(d, -1, -1)])


def _own_fit(px, py, dx, dy):
    """Own least-squares cubic of the displacement (dx, dy) at (px, py); returns its evaluator."""
    cx, cy, hx, hy = px.mean(), py.mean(), np.ptp(px) / 2, np.ptp(py) / 2
    a = _cubic((px - cx) / hx, (py - cy) / hy)
    kx, *_ = np.linalg.lstsq(a, dx, rcond=None)
    ky, *_ = np.linalg.lstsq(a, dy, rcond=None)
    return lambda x, y: (_cubic((x - cx) / hx, (y - cy) / hy) @ kx, _cubic((x - cx) / hx, (y - cy) / hy) @ ky)


def _residual(route, scn, cam, u, v):
    """What the camera still displaces at ideal points (u, v), those imaged on the chips; the
    fitted routes in mosaic px, the uncalibrated one in focal px (as the truth defines it)."""
    iu, iv = lamp_image_focal_px(cam, u, v)
    mx, my = _to_mosaic(scn, iu, iv)
    ix, iy = _to_mosaic(scn, u, v)
    if route == "uncalibrated":
        ok = np.isfinite(mx)
        lu, lv = _tiling(scn, scn.lab.calibration_target.rows, scn.lab.calibration_target.cols,
                         scn.lab.calibration_target.extent_fraction)
        gu, gv = lamp_image_focal_px(cam, lu, lv)
        fit = _own_fit(lu, lv, gu - lu, gv - lv)
        fx, fy = fit(u[ok], v[ok])
        return iu[ok] - u[ok] - fx, iv[ok] - v[ok] - fy
    ok = np.isfinite(mx) & np.isfinite(ix)
    if route == "default":
        rx, ry = cam.report_positions(mx[ok], my[ok])
        return rx - ix[ok], ry - iy[ok]
    cor = scn.optics.distortion_correction  # noise-free earlier calibration: own fit = the camera's
    cu, cv = _tiling(scn, cor.rows, cor.cols, cor.extent_fraction)
    cmx, cmy = _to_mosaic(scn, *lamp_image_focal_px(cam, cu, cv))
    crx, cry = _to_mosaic(scn, cu, cv)
    fit = _own_fit(cmx, cmy, cmx - crx, cmy - cry)
    fx, fy = fit(mx[ok], my[ok])
    return mx[ok] - fx - ix[ok], my[ok] - fy - iy[ok]


def _scenario(route):
    scn = default()
    if route == "uncalibrated":
        return with_updates(scn, {"optics.distortion_correction.kind": "none"})
    if route == "noise-free calibration":
        return with_updates(scn, {"optics.distortion_correction.marker_error_3sigma_arcsec": 0.0,
                                  "optics.distortion_correction.centroid_noise_px": 0.0})
    return scn


def _ms_and_se(r, about_mean):
    """Mean square (about the mean for the fitted routes: the boresight is calibrated) and its
    standard error, sd(r^2) / sqrt(N) (the mean's own sampling adds O(1/N))."""
    d = r - r.mean() if about_mean else r
    return float(np.mean(d**2)), float(np.std(d**2, ddof=1) / math.sqrt(d.size))


@pytest.mark.parametrize("route", ["default", "noise-free calibration", "uncalibrated"])
def test_c1_truth_equals_an_independent_whole_field_computation(route):
    scn = _scenario(route)
    cam = STUDY.prepared(scn).camera()
    truth = lsfe_c1_truth(cam)
    u, v = _uniform_field(scn, N_POINTS, seed=20261206)
    rx, ry = _residual(route, scn, cam, u, v)
    for ax, r, t in (("x", rx, truth.x_px), ("y", ry, truth.y_px)):
        ms, se = _ms_and_se(r, about_mean=route != "uncalibrated")
        # within Z standard errors of the Monte Carlo mean square (the truth's own midpoint
        # rule is far closer, module docstring)
        assert abs(t**2 - ms) <= Z * se, (route, ax, t, math.sqrt(ms), se)


def test_c1_details_report_the_grid_coverage_and_the_box_residual():
    """Coverage: the lab grid's points' bounding box, gap excluded, over the chips' area
    (analytic); the truth counts cell centres, so it may differ by the box's perimeter times half a
    cell over the field's area. The box residual: Monte Carlo over the box (points imaged on the
    chips), within 4 standard errors."""
    scn = default()
    cam = STUDY.prepared(scn).camera()
    t = lsfe_c1_truth(cam)
    det, _ = _chips(scn)
    tgt = scn.lab.calibration_target
    lu, lv = _tiling(scn, tgt.rows, tgt.cols, tgt.extent_fraction)
    bw, bh = np.ptp(lu), np.ptp(lv)
    area = det.n_chips * det.chip_cols * det.chip_rows
    coverage = (bw - det.gap_px) * bh / area
    cell = (det.n_chips * det.chip_cols + det.gap_px) / (16 * scn.validation.field_grid)
    assert abs(t.details["grid_coverage"] - coverage) <= (2 * (bw + bh) * cell / 2) / area
    assert 0.4 < coverage < 0.55  # the "47 % of the mosaic"
    rng = np.random.default_rng(7)
    u = rng.uniform(lu.min(), lu.max(), N_POINTS)
    v = rng.uniform(lv.min(), lv.max(), N_POINTS)
    rx, ry = _residual("default", scn, cam, u, v)
    for r, b in ((rx, t.details["box_x_px"]), (ry, t.details["box_y_px"])):
        ms, se = _ms_and_se(r, about_mean=True)
        assert abs(b**2 - ms) <= Z * se
    # the whole field holds the extrapolated corners: its residual exceeds the box's
    assert t.x_px > 2 * t.details["box_x_px"] and t.y_px > 2 * t.details["box_y_px"]
