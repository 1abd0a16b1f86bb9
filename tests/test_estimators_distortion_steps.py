"""The steps the four LSFE-C1 variants share, each against an independent computation.

budget.starcam.estimators.distortion factors eqs 17-30 into one helper per step (point means,
residuals to the reference, cubic fit, sample variance, fit-dof variance); here each is
checked against code that does not share it: pandas groupby/merge, a design matrix built by
numpy.polynomial (other column order, raw coordinates) solved by scipy.linalg.lstsq, and the
standard library's statistics.variance. Plus: every variant's sigma recomputed from those
independent pieces.
"""

from __future__ import annotations

import math
import statistics
import warnings

import numpy as np
import pandas as pd
import pytest
import scipy.linalg

from budget.starcam.estimators import (
    distortion_calibration_residual,
    distortion_remaining_displacement,
    distortion_residual_error,
    distortion_residual_error_dof,
)
from budget.starcam.estimators.common import _Log
from budget.starcam.estimators.distortion import (
    _cubic_fit,
    _fit_residual_variance,
    _point_means,
    _reference_rows,
    _residuals_to_reference,
    _sample_variance,
)

PS = 5.5
MARKER_3SIGMA_ARCSEC = 0.1


def _case(seed, w_cols=8, w_rows=4, n=5):
    """A jittered 8 x 4 grid, a cubic-plus-noise displacement, n frames of noise per point;
    the reference table shuffled so that its order differs from the sorted stars."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.linspace(200, 3800, w_cols), np.linspace(150, 1850, w_rows))
    gx = gx.ravel() + rng.normal(0, 20, gx.size)
    gy = gy.ravel() + rng.normal(0, 20, gy.size)
    stars = rng.permutation(np.arange(100, 100 + gx.size))
    ref = pd.DataFrame({"star": stars, "x_ref": gx, "y_ref": gy})
    u, v = (gx - 2000) / 1800, (gy - 1000) / 850
    dx = 0.2 * u**3 - 0.05 * u * v + rng.normal(0, 0.03, gx.size)
    dy = 0.1 * v**2 + 0.02 * u + rng.normal(0, 0.03, gx.size)
    rows = [(s, f, x + a + rng.normal(0, 0.02), y + b + rng.normal(0, 0.02))
            for s, x, y, a, b in zip(stars, gx, gy, dx, dy) for f in range(n)]
    return pd.DataFrame(rows, columns=["star", "frame", "x", "y"]), ref


def _independent(table, ref):
    """Per-point means (groupby), residuals to the reference (merge), cubic fit residuals
    (numpy.polynomial monomials of total degree <= 3 in raw coordinates, scipy lstsq)."""
    g = table.groupby("star", sort=True)
    pts = pd.DataFrame({"mx": g["x"].mean(), "my": g["y"].mean(), "vx": g["x"].var(ddof=1),
                        "vy": g["y"].var(ddof=1), "n": g["x"].count()}).reset_index()
    pts = pts.merge(ref, on="star", how="inner")
    pts["dx"], pts["dy"] = pts["mx"] - pts["x_ref"], pts["my"] - pts["y_ref"]
    x, y = pts["x_ref"].to_numpy() / 1000, pts["y_ref"].to_numpy() / 1000
    full = np.polynomial.polynomial.polyvander2d(x, y, [3, 3])       # column i*4 + j: x^i y^j
    a = full[:, [i * 4 + j for i in range(4) for j in range(4) if i + j <= 3]]
    for ax in ("x", "y"):
        d = pts[f"d{ax}"].to_numpy()
        pts[f"fit_{ax}"] = a @ scipy.linalg.lstsq(a, d)[0]
        pts[f"dd{ax}"] = d - pts[f"fit_{ax}"]
    return pts


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_shared_step_matches_an_independent_computation(seed):
    table, ref = _case(seed)
    pts = _independent(table, ref)
    log = _Log()
    st, n_bad = _point_means(table, condition=None, what="LSFE-C1", log=log)
    assert n_bad == 0 and list(st["star"]) == list(pts["star"])
    # eqs 17-18: means of 5 values ~ 1e3 px, summed in another order: a few ulp of 1e3
    np.testing.assert_allclose(st["mean_x"], pts["mx"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(st["var_y"], pts["vy"], rtol=1e-9)
    x0, y0, dx, dy, lost = _residuals_to_reference(st, _reference_rows(ref, "LSFE-C1"), what="LSFE-C1", log=log)
    assert lost == [] and np.array_equal(x0, pts["x_ref"]) and np.array_equal(y0, pts["y_ref"])
    np.testing.assert_allclose(dx, pts["dx"], rtol=0, atol=1e-9)              # eqs 19-20
    fx, fy = _cubic_fit(x0, y0, dx, dy, what="LSFE-C1")
    # same column space, other basis and scaling: fitted values agree to rounding of the
    # solves (condition number of the raw-coordinate design ~1e4, residuals ~0.1 px)
    np.testing.assert_allclose(fx, pts["fit_x"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(fy, pts["fit_y"], rtol=0, atol=1e-9)
    dd = pts["ddx"].to_numpy()
    assert _sample_variance(dd) == pytest.approx(statistics.variance(dd.tolist()), rel=1e-12)
    assert _fit_residual_variance(dd) == pytest.approx(math.fsum(dd**2) / (len(dd) - 10), rel=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_variant_from_the_independent_pieces(seed):
    table, ref = _case(seed)
    pts = _independent(table, ref)
    w = len(pts)
    sm2 = (MARKER_3SIGMA_ARCSEC / (3 * PS)) ** 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # a clipped variant warns; its 0 is checked below
        pub = distortion_residual_error(table, reference=ref, plate_scale_arcsec=PS)
        dof = distortion_residual_error_dof(table, reference=ref, plate_scale_arcsec=PS)
        cal = distortion_calibration_residual(table, reference=ref, plate_scale_arcsec=PS,
                                              marker_3sigma_arcsec=MARKER_3SIGMA_ARCSEC)
        rem = distortion_remaining_displacement(table, reference=ref, plate_scale_arcsec=PS,
                                                marker_3sigma_arcsec=MARKER_3SIGMA_ARCSEC)
    for ax, got in (("x", "sigma_x_px"), ("y", "sigma_y_px")):
        d, dd = pts[f"d{ax}"].to_numpy(), pts[f"dd{ax}"].to_numpy()
        s_d2 = statistics.variance(d.tolist())
        s_dd2 = statistics.variance(dd.tolist())
        s_res2 = math.fsum(dd**2) / (w - 10)
        noise2 = float(np.mean(pts[f"v{ax}"] / pts["n"]))
        want = {"pub": s_d2 - s_dd2, "dof": s_d2 - s_res2, "cal": s_res2 - sm2 - noise2,
                "rem": s_d2 - sm2 - noise2}
        for name, r in (("pub", pub), ("dof", dof), ("cal", cal), ("rem", rem)):
            v = want[name]
            # variances ~1e-2..1e-3 px^2 from sums agreeing to ~1e-12 relative; a difference
            # of two such variances is then good to ~1e-12 px^2 absolute
            assert getattr(r, got) ** 2 == pytest.approx(max(v, 0.0), rel=1e-9, abs=1e-11), (name, ax)
