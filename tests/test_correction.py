"""The camera's own distortion correction (simcam.starcam.correction) and the LSFE-C1 truth of a
calibrated camera.

Independent references: the least-squares algebra of a polynomial fit to exact
polynomial data (recovered to rounding), and, for noisy calibration points, the expected
mean square of an OLS fit's error over its own points, p sigma^2 / n (trace of the hat
matrix; Draper & Smith, Applied Regression Analysis, sec. 2.1).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from budget.starcam.truth import lsfe_c1_truth
from simcam.starcam.correction import poly_design
from simcam.starcam.render import StarCamera
from simcam.infra.errors import ScenarioError
from simcam.starcam.scenario import from_dict

SMALL = {
    "detector": {"chip_cols": 256, "chip_rows": 256, "gap_px": 10.0},
    "optics": {"r_norm_px": 256.0,
               "lateral_colour": {"radial_px_per_nm": [], "uniform_x_px_per_nm": [], "uniform_y_px_per_nm": []}},
    # the ideal world: no distortion beyond the scenario's own
    "world": {"effects": {"distortion_r5_px_at_corner": 0.0, "distortion_r7_px_at_corner": 0.0}},
}


def _scn(**corr):
    d = {k: dict(v) for k, v in SMALL.items()}
    d["optics"] = dict(d["optics"], distortion_correction=corr)
    return from_dict(d)


def test_poly_design_has_every_monomial_once():
    b = poly_design(np.array([2.0]), np.array([3.0]), 3)
    expect = [1, 2, 3, 4, 6, 9, 8, 12, 18, 27]
    assert sorted(b.ravel().tolist()) == sorted(expect) and b.shape == (1, 10)


def test_uncalibrated_camera_reports_raw_centroids():
    cam = StarCamera(_scn(kind="none"))
    assert cam.onboard_correction is None
    x, y = cam.report_positions(np.array([10.0, 20.0]), np.array([5.0, 6.0]))
    np.testing.assert_array_equal(x, [10.0, 20.0])
    np.testing.assert_array_equal(y, [5.0, 6.0])


def test_error_free_calibration_of_no_distortion_leaves_nothing():
    """No distortion, no lateral colour, no calibration error: the correction is 0 to
    rounding and so is the truth."""
    d = {k: dict(v) for k, v in SMALL.items()}
    d["optics"] = dict(d["optics"], distortion={"k1": 0.0, "k2": 0.0},
                       distortion_correction={"marker_error_3sigma_arcsec": 0.0, "centroid_noise_px": 0.0})
    cam = StarCamera(from_dict(d))
    c = cam.onboard_correction
    assert np.max(np.abs(c.coef_x)) < 1e-9 and np.max(np.abs(c.coef_y)) < 1e-9
    t = lsfe_c1_truth(cam)
    assert t.x_px < 1e-9 and t.y_px < 1e-9


def test_marker_noise_in_the_earlier_calibration_sets_the_remaining_displacement():
    """No distortion: the remaining displacement is the fitted noise alone. Over the
    calibration's own n points its mean square is p sigma^2 / n in expectation (p = 10
    cubic terms; hat-matrix trace). Over the scenario seeds (one camera each) the mean of
    the points' mean square, divided by sigma^2 p / n, must be 1 within 4 standard errors
    (sd of the ratio from the seeds themselves)."""
    ratios = []
    sig_arcsec = 3.0
    for seed in range(30):
        d = {k: dict(v) for k, v in SMALL.items()}
        d["seed"] = seed
        d["optics"] = dict(d["optics"], distortion={"k1": 0.0, "k2": 0.0},
                           distortion_correction={"marker_error_3sigma_arcsec": sig_arcsec, "centroid_noise_px": 0.0})
        scn = from_dict(d)
        cam = StarCamera(scn)
        c = cam.onboard_correction
        cx, cy = c.correction_px(c.points_x, c.points_y)
        s = sig_arcsec / 3 / scn.camera.scale_arcsec_per_px
        n, p = c.points_x.size, 10
        ratios.append(0.5 * (np.mean(cx**2) + np.mean(cy**2)) / (s**2 * p / n))
    r = np.array(ratios)
    assert abs(r.mean() - 1) < 4 * r.std(ddof=1) / math.sqrt(r.size)


def test_order_needs_enough_points():
    with pytest.raises(ScenarioError, match="distortion_correction"):
        _scn(order=4, rows=4, cols=8)
