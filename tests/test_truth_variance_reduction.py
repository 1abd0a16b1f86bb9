"""The variance-reduced HSFE and TE truths (budget.starcam.truth with its control variates,
budget.starcam.kernels_truth): the same frames as a trial, control variates of exactly
zero mean, the same values as the plain estimators within their standard errors, and
standard errors that match the spread over seeds.

Monte Carlo assertions use fixed seeds; each tolerance is stated where it is used and
follows from the sampling distribution (a z of 4: a false alarm of 6e-5 per check; the
chi-square of a sample variance for the standard errors).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

from budget.starcam import truth as T
from budget.starcam.kernels_truth import D_HALF_RANGE, cv_tables

Z = 4.0


@pytest.fixture(scope="module")
def default():
    from budget.starcam.study import STUDY

    scn = STUDY.load_scenario()
    return scn, STUDY.prepared(scn).camera()


@pytest.fixture(scope="module")
def small_grid(default):
    """The default camera with a 2 x 2 HSFE phase grid (4 phases: the checks run fast)."""
    from budget.starcam.study import STUDY

    scn, _ = default
    s = scn.model_copy(update={"validation": scn.validation.model_copy(update={"hsfe_phase_grid": 2})})
    return STUDY.prepared(s).camera()


def _hsfe_scene(cam, phase_px=0.3):
    from budget.starcam.protocols import make_plan
    from simcam.starcam.render import Placement
    from simcam.starcam.targets import star_grid

    scn = cam.scenario
    c = make_plan("hsfe", scn).conditions[0]
    return cam.scene(Placement(layout=star_grid(scn, center_px=c.field_center_px), platform_dx_px=phase_px,
                               platform_dy_px=phase_px, condition=999_002))


def test_cv_kernel_gives_a_trials_pixels_and_centroids(default):
    """Bit for bit the fused kernel of a trial (budget.starcam.protocols._expose_centroid)."""
    from budget.starcam.protocols import _expose_centroid, centroid_options

    scn, cam = default
    scene = _hsfe_scene(cam)
    chain = cam.window_chain(scene)
    thr = scn.validation.threshold_sigma * centroid_options(cam, chain.col0, scn.validation.threshold_sigma)["noise_dn"]
    x0, y0, _, f0 = _expose_centroid(cam, chain, scene, frames=60, seed=3, dark_mean=None, threshold_dn=thr)
    (x, y, f, *_), _ = T._cv_frames(cam, scene, frames=60, seed=3)
    assert np.array_equal(x, x0) and np.array_equal(y, y0) and np.array_equal(f, f0)


@pytest.mark.parametrize("mu, g, off, r, dlo", [
    (0.0, 1.0, 100.0, 3.0, 128),      # a pixel of mean 0: draws 0
    (3.7, 1.0, 100.0, 3.0, 104),      # faint, threshold around its mean
    (21.4, 1.05, 100.0, 3.0, 128),    # background level, threshold ~3 sigma above
    (34.0, 1.0, 100.0, 3.0, 131),     # at the threshold
    (950.0, 1.0, 100.0, 3.0, 128),    # far above it
    (12.0, 2.0, 10.0, 0.0, 14),       # no read noise: a step
])
def test_tables_against_scipy(mu, g, off, r, dlo):
    """Q = P(n >= tau), M_k = E[n^k 1{n >= tau}] with n = P - mu + r z, tau = G (d - 1/2 - off) - mu,
    against an independent evaluation: scipy's Poisson pmf over all its values (no band,
    no tail in closed form) with the normal's partial moments from scipy
    (``int_u^inf phi = sf(u)``, ``int_u^inf z phi = phi(u)``, ``int_u^inf z^2 phi = u phi(u) + sf(u)``),
    or the step for r = 0. Tolerance: the tables' tail cut (Phi^c(8) ~ 6e-16 per value) and
    double rounding of sums of ~1e3 terms, relative to each moment's scale."""
    nd = 2 * D_HALF_RANGE + 1
    q, m1, m2 = (np.empty((1, 1, 1, nd)) for _ in range(3))
    cv_tables(np.array([[[mu]]]), np.zeros((1, 1), dtype=np.int64), np.array([g]), np.array([off]), np.array([r]),
              np.array([dlo], dtype=np.int64), nd, q, m1, m2)
    ks = np.arange(int(mu + 40 * math.sqrt(mu + 1) + 40) + 1)
    pmf = stats.poisson.pmf(ks, mu) if mu > 0 else (ks == 0).astype(float)
    c = ks - mu
    for di in range(nd):
        th = g * (dlo + di - 0.5 - off)           # the event P + r z >= th
        if r == 0:
            step = (ks >= th).astype(float)
            want = [np.sum(pmf * step), np.sum(pmf * c * step), np.sum(pmf * c * c * step)]
        else:
            u = (th - ks) / r
            sf, pdf = stats.norm.sf(u), stats.norm.pdf(u)
            want = [np.sum(pmf * sf), np.sum(pmf * (c * sf + r * pdf)),
                    np.sum(pmf * (c * c * sf + 2 * c * r * pdf + r * r * (u * pdf + sf)))]
        scale = mu + r * r + 1.0
        assert q[0, 0, 0, di] == pytest.approx(want[0], abs=1e-12)
        assert m1[0, 0, 0, di] == pytest.approx(want[1], abs=1e-12 * scale)
        assert m2[0, 0, 0, di] == pytest.approx(want[2], abs=1e-12 * scale * scale)


def test_control_variates_have_zero_mean(default):
    """psi and kappa over 4000 frames x 25 stars of the TE target (fixed seed): their means
    within Z standard errors of 0 (their sd / sqrt(N); the frames and stars independent)."""
    _, cam = default
    (x, y, flag, px, py, kx, ky), _ = T._cv_frames(cam, T.te_scene(cam), frames=4000, seed=11)
    assert not flag.any()
    for v in (px, py, kx, ky):
        se = v.std(ddof=1) / math.sqrt(v.size)
        assert abs(v.mean()) < Z * se, (v.mean(), se)
    # and they follow the centroid: the corrected scatter is a small fraction of the plain one
    assert (x - px).var(axis=0).mean() < 0.01 * x.var(axis=0).mean()


def test_te_reduced_equals_plain(default):
    """The TE truth with the control variate (400 frames) against the plain estimator (4000
    frames, another seed: independent): within Z combined standard errors."""
    _, cam = default
    cv = T.te_truth(cam, frames=400, seed=1)
    plain = T.te_truth(cam, frames=4000, seed=2, control_variate=False)
    assert "control variate" in cv.details["route"] and plain.details["route"] == "per-star sample sd"
    for ax in ("x", "y"):
        a, b = getattr(cv, f"{ax}_px"), getattr(plain, f"{ax}_px")
        se = math.hypot(getattr(cv, f"se_{ax}_px"), getattr(plain, f"se_{ax}_px"))
        assert abs(a - b) < Z * se, (ax, a, b, se)
    # the reduced estimator's standard error is many times smaller at a tenth of the frames
    assert cv.se_x_px < 0.5 * plain.se_x_px


def test_hsfe_reduced_equals_plain(small_grid):
    """The HSFE truth with the control variate (40 frames per phase) against the plain
    estimator (600 frames per phase, another seed): within Z combined standard errors."""
    cv = T.hsfe_truth(small_grid, frames=40, seed=1)
    plain = T.hsfe_truth(small_grid, frames=600, seed=2, control_variate=False)
    assert "control variate" in cv.details["route"] and "control variate" not in plain.details["route"]
    for ax in ("x", "y"):
        a, b = getattr(cv, f"{ax}_px"), getattr(plain, f"{ax}_px")
        se = math.hypot(getattr(cv, f"se_{ax}_px"), getattr(plain, f"se_{ax}_px"))
        assert abs(a - b) < Z * se, (ax, a, b, se)
    assert cv.se_x_px < plain.se_x_px


def _chi2_bounds(n: int, p: float = 1e-4):
    """Bounds of s^2 / sigma^2 for a sample variance of n values (chi-square, n - 1 dof)."""
    return stats.chi2.ppf(p / 2, n - 1) / (n - 1), stats.chi2.ppf(1 - p / 2, n - 1) / (n - 1)


@pytest.mark.parametrize("cls", ["te", "hsfe"])
def test_reported_se_matches_the_spread_over_seeds(default, small_grid, cls):
    """Over 24 independent seeds, the truths' sample variance over the mean reported se^2
    lies within the chi-square bounds of a sample variance (23 dof, two-sided 1e-4); the
    reported se of each seed scatters little (it comes from the same frames)."""
    n = 24
    if cls == "te":
        _, cam = default
        ts = [T.te_truth(cam, frames=100, seed=100 + s) for s in range(n)]
    else:
        ts = [T.hsfe_truth(small_grid, frames=20, seed=100 + s) for s in range(n)]
    lo, hi = _chi2_bounds(n)
    for ax in ("x", "y"):
        v = np.array([getattr(t, f"{ax}_px") for t in ts])
        se2 = np.mean([getattr(t, f"se_{ax}_px") ** 2 for t in ts])
        r = v.var(ddof=1) / se2
        assert lo < r < hi, (cls, ax, r, lo, hi)


@pytest.mark.slow
def test_long_run_reduced_equals_plain(default):
    """Long runs on the default camera: TE (plain 40000 frames, reduced 4000) and HSFE over
    its 64 phases (plain 2000 frames per phase, the scenario's fixed truth; reduced 200),
    independent seeds, within Z combined standard errors."""
    _, cam = default
    pairs = [(T.te_truth(cam, frames=4000, seed=21), T.te_truth(cam, frames=40000, seed=22, control_variate=False)),
             (T.hsfe_truth(cam, frames=200, seed=21), T.hsfe_truth(cam, frames=2000, seed=22, control_variate=False))]
    for cv, plain in pairs:
        for ax in ("x", "y"):
            a, b = getattr(cv, f"{ax}_px"), getattr(plain, f"{ax}_px")
            se = math.hypot(getattr(cv, f"se_{ax}_px"), getattr(plain, f"se_{ax}_px"))
            assert abs(a - b) < Z * se, (cv.name, ax, a, b, se)
