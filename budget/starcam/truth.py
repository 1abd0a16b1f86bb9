"""What each error class really is, for a simulated camera: the truth the validator compares to.

Computed from the simulator (the injected physics and positions, which the lab never has)
with dense sampling, following each method's own definition (all values 1 sigma
in px, per axis):

* **TE** (seed 000 eqs 1-2 define it as the mean over stars of each star's temporal
  centroid standard deviation): the same statistic from ``te_truth_frames`` frames of the
  TE condition, centroided as the lab does. Reported beside it: the Cramer-Rao bound of
  an unbiased position estimate from the same pixels (Poisson + read noise; Fisher
  information ``I_xx = sum_p (d mu_p / dx)^2 / (mu_p + sigma_read^2 / g^2 ...)`` in
  electrons, e.g. Mendez et al. 2014, PASP 126, 798, eq. 8 for the Poisson case).
* **HSFE**: the rms of the static, position-dependent error of the *expected* centroid
  under the lab's noise (PRNU, DSNU, pixel-phase "S-curve" as the noise smooths it) over
  ``hsfe_phase_grid^2`` sub-pixel phases of the HSFE target, with the common motion of
  each phase removed (the mean over stars): ``hsfe_truth_frames`` noisy frames per phase,
  split in two halves whose product is unbiased for the square (:func:`hsfe_truth`).
  When every trial draws its camera's pixel maps, TE's and HSFE's truths are each trial's
  camera's own, computed in the trial: :func:`te_trial_truth` (fewer frames) and
  :func:`hsfe_trial_truth` (a random sample of the phases, unbiased for the grid's mean square).
* **LSFE-S**: the rms, over the stellar population ``lsfe_spectral_types`` and a
  ``field_grid`` grid over the detector, of the spectrum-weighted chromatic displacement
  about its reference (``calibration_spectrum``: by default the population mean at each
  field point, whose common offset is calibrated at system level; or the lab lamp, or a
  spectral type).
* **LSFE-C1**: for a camera that applies its own distortion correction (the default,
  ``optics.distortion_correction``), the rms over the whole field the camera uses (the
  mosaic, chip gaps excluded) of the displacement the calibrated camera still makes; for an
  uncalibrated camera (``kind = "none"``), the residual over that field of a full cubic
  fitted to the true static displacement at the calibration grid's points. Beside it the
  lab grid's coverage of the field and the residual over the grid's bounding box.
* **LSFE-C2**: the injected marker calibration error (sigma = 3-sigma value / 3), an input
  of the lab, not a measured result.
* **LSFE** and **total**: independent sources, so root-sum-squares: LSFE =
  sqrt(S^2 + C1^2 + C2^2), total = sqrt(TE^2 + HSFE^2 + LSFE^2). (Seed 000's eq 31 adds
  C1 and C2 linearly; the validation reports how far that is from this.)

World effects (``[world.effects]``, :mod:`simcam.starcam.world`): each truth stays
the quantity its method claims to measure, computed from the injected physics:

* the **detector non-linearity** is part of the camera: TE's and HSFE's truths are computed
  from the camera's own detector chain, so HSFE's truth includes the static centroid error
  the non-linearity adds (an asymmetric image's centroid moves with the compression) and
  TE's the compressed signal's noise;
* the **distortion beyond the cubic** is part of the lens: LSFE-C1's truth is what the
  camera's own cubic correction leaves of the world's whole distortion (the correction is
  fitted, in the earlier calibration, to that distortion), so it includes the r^5 and r^7
  residual; the small displacement of the TE and HSFE targets' stars follows too;
* the **hexapod pose errors** are not in any truth: they move the image, they are not an
  error of the camera. TE's truth is at the nominal pose, HSFE's over sub-pixel phases
  whatever pose reaches them; what a pose error does to an estimate (the roll's field term
  ``r delta`` in HSFE, a pose that is not where it was commanded) is the finding;
* the **target drift** is not temporal noise, so it is not in TE's truth (the centroid's
  temporal noise); the published TE estimator, an rms over frames, then shows the drift as
  a bias, which is the finding. Nor is it in HSFE's or the LSFE truths (common to all stars,
  it is no error of the camera).

:meth:`budget.starcam.study.StarCameraStudy.truth_depends_on_effects` states this for the
robustness runner (distortion and non-linearity change the truths; hexapod and drift do not).

The noisy-frame truths (TE, HSFE) subtract from each frame a control variate of exactly
zero mean (:mod:`budget.starcam.kernels_truth`: the centroid's first-order response to the
frame's pixel deviates, threshold included, less its expectation given the border
medians), on the same frames a trial's kernel gives: the same expectation, a per-frame
scatter two to three orders of magnitude smaller, so the same standard error from far
fewer frames (``control_variate=False``: the plain estimators, for comparison).

Every truth carries its own standard error (``se_x_px``, ``se_y_px``; 0 where nothing
is sampled), which the validator's significance test adds to that of the estimates.
No truth calls an estimator of :mod:`budget.starcam.estimators` or the lab's spectral model
(tests/test_truth_routes.py).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace as dreplace

import numpy as np

from budget.starcam.protocols import centroid_options, make_plan
from simcam import spectra
from simcam.starcam import optics
from simcam.starcam.correction import lamp_image_focal_px, poly_design
from simcam.starcam.render import Placement
from simcam.starcam.targets import calibration_grid, star_grid


@dataclass(frozen=True)
class ClassTruth:
    """Truth of one error class, 1 sigma px per axis, with how it was computed.

    ``se_x_px``, ``se_y_px``: the truth's own Monte Carlo standard error (px; 0 for a truth
    computed without sampling). The validator adds it to the standard error of the mean
    estimate when it tests a bias.
    """

    name: str
    x_px: float
    y_px: float
    details: dict = field(default_factory=dict)
    se_x_px: float = 0.0
    se_y_px: float = 0.0


def _centroid(camera, win, method, scenario, *, pixels=None):
    from budget.centroid.core import centroid_cog, centroid_gaussian_fit, centroid_iwcog
    from budget.starcam.protocols import design_psf_sigma_px

    pix_in = win.pixels if pixels is None else pixels
    f, w = pix_in.shape[:2]
    pix = pix_in.reshape(f * w, *pix_in.shape[2:]).astype(np.float64)
    fn = {"cog": centroid_cog, "iwcog": centroid_iwcog, "gauss": centroid_gaussian_fit}[method]
    opts = centroid_options(camera, win.col0, scenario.validation.threshold_sigma,
                            dark_frames=scenario.validation.dark_frames)
    opts = {k: (np.tile(v, f) if isinstance(v, np.ndarray) else v) for k, v in opts.items()}
    if method == "iwcog":
        opts["weight_sigma_px"] = design_psf_sigma_px(scenario)
    x, y, _, flag = fn(pix, x0=np.tile(win.col0, f), y0=np.tile(win.row0, f), **opts)
    return x.reshape(f, w), y.reshape(f, w), flag.reshape(f, w)


def control_variate_applies(scenario) -> bool:
    """Whether the truths can use the control variates of :mod:`budget.starcam.kernels_truth`:
    the lab's thresholded centre of gravity on frames without a dark frame subtracted (the
    variates are built for that centroid and for integer pixels; otherwise the plain
    estimators are used)."""
    val = scenario.validation
    return val.centroid_method == "cog" and not val.dark_frames


def _cv_frames(camera, scene, *, frames: int, seed: int, prep=None):
    """Frames of ``scene`` exposed and centroided as :func:`budget.starcam.protocols._expose_centroid`
    does (the same frame keys, so the same pixels and centroids), with the control variates:
    x, y, flag, psi_x, psi_y, kappa_x, kappa_y (frames, W), and the kernel's preparation."""
    from budget.starcam.kernels_truth import cv_prepare, expose_centroid_cv

    scn = camera.scenario
    chain = camera.window_chain(scene)
    if prep is None:
        noise = centroid_options(camera, chain.col0, scn.validation.threshold_sigma,
                                 dark_frames=scn.validation.dark_frames)["noise_dn"]
        prep = cv_prepare(chain, threshold_dn=float(scn.validation.threshold_sigma) * noise)
    keys = camera.frame_keys(seed=seed, condition=scene.placement.condition, frames=frames)
    return expose_centroid_cv(chain, keys, prep), prep


def te_scene(camera):
    """The TE target's scene the TE truth exposes (nominal pose, its own condition)."""
    scn = camera.scenario
    c = make_plan("te", scn).conditions[0]
    return camera.scene(Placement(layout=star_grid(scn, center_px=c.field_center_px), condition=999_001))


def te_variance_cv(x, psi, kappa):
    """Per-star centroid variance from ``F`` frames (axis 0) with the control variates
    (:mod:`budget.starcam.kernels_truth`): the mean over frames of

    ``D_f = ((x_f - xbar)^2 - (psi_f - psibar)^2) F / (F - 1) + psi_f^2 - kappa_f``.

    Unbiased: the first part's mean is the difference of two sample variances, unbiased
    for ``Var(x) - Var(psi)``, and ``E[psi^2 - kappa] = E[psi^2] = Var(psi)`` (``E psi = 0`` and
    ``E kappa = 0`` exactly). The centring errors of ``xbar`` and ``psibar`` nearly cancel
    (``psi`` follows ``x``), so the ``D_f`` scatter little and ``sd(D) / sqrt(F)`` is the
    estimate's standard error. Returns the mean of ``D`` and that standard error, per star."""
    f = x.shape[0]
    d = ((x - x.mean(axis=0)) ** 2 - (psi - psi.mean(axis=0)) ** 2) * (f / (f - 1.0)) + psi**2 - kappa
    return d.mean(axis=0), d.std(axis=0, ddof=1) / math.sqrt(f)


def te_truth(camera, *, frames: int, seed: int, control_variate: bool = True,
             cramer_rao: bool = True) -> ClassTruth:
    """TE truth: mean over stars of the temporal centroid sd from ``frames`` noise-only frames.

    Plain route: each star's sample sd (``ddof = 1``), standard error from normal theory
    (:func:`_se_mean_of_sd`). Variance-reduced route (``control_variate`` and
    :func:`control_variate_applies`; the same frames): each star's variance is the mean of
    the per-frame terms ``D_f`` of :func:`te_variance_cv` (their expectation is the variance
    exactly: :mod:`budget.starcam.kernels_truth`), its sd the square root, with
    standard error ``se(V) / (2 sd)`` (delta method; the square root's bias,
    ``se(V)^2 / (8 sd^3)``, is a fraction ``se / (4 sd)`` of that standard error, negligible),
    and the mean over stars ``sqrt(sum_j se_j^2) / W`` (independent stars). ``cramer_rao``: the
    details carry the Cramer-Rao bound of the same pixels (:func:`cramer_rao_bound_px`) for
    the report.
    """
    scn = camera.scenario
    scene = te_scene(camera)
    cv = control_variate and control_variate_applies(scn)
    if cv:
        (x, y, flag, px, py, kx, ky), _ = _cv_frames(camera, scene, frames=frames, seed=seed)
    elif scn.validation.centroid_method == "cog":
        # the fused expose-and-centroid kernel: the same pixels and centroids as rendering
        # the windows and centroid_cog with the same options (tests/test_protocols.py), and
        # the kernel a trial already compiled
        from budget.starcam.protocols import _expose_centroid

        chain = camera.window_chain(scene)
        noise = centroid_options(camera, chain.col0, scn.validation.threshold_sigma,
                                 dark_frames=scn.validation.dark_frames)["noise_dn"]
        x, y, _, flag = _expose_centroid(camera, chain, scene, frames=frames, seed=seed, dark_mean=None,
                                         threshold_dn=float(scn.validation.threshold_sigma) * noise)
    else:
        win = camera.render_windows(scene, frames=frames, seed=seed)
        x, y, flag = _centroid(camera, win, scn.validation.centroid_method, scn)
    good = (flag == 0).all(axis=0)
    if cv:
        vx, svx = te_variance_cv(x[:, good], px[:, good], kx[:, good])
        vy, svy = te_variance_cv(y[:, good], py[:, good], ky[:, good])
        sx, sy = np.sqrt(np.clip(vx, 0.0, None)), np.sqrt(np.clip(vy, 0.0, None))
        w = int(good.sum())
        se_x = float(math.sqrt(np.sum((svx / (2 * sx)) ** 2)) / w)
        se_y = float(math.sqrt(np.sum((svy / (2 * sy)) ** 2)) / w)
        route = "per-star variance less a zero-mean control variate of its square"
    else:
        sx = x[:, good].std(axis=0, ddof=1)
        sy = y[:, good].std(axis=0, ddof=1)
        se_x, se_y = _se_mean_of_sd(sx, frames), _se_mean_of_sd(sy, frames)
        route = "per-star sample sd"
    details = {"frames": frames, "stars": int(good.sum()), "route": route,
               "per_star_sd_x_px": sx.tolist(), "per_star_sd_y_px": sy.tolist()}
    if cramer_rao:
        crb_x, crb_y = cramer_rao_bound_px(camera, scene)
        details |= {"cramer_rao_x_px": float(np.mean(crb_x)), "cramer_rao_y_px": float(np.mean(crb_y))}
    return ClassTruth("te", float(sx.mean()), float(sy.mean()), details, se_x_px=se_x, se_y_px=se_y)


def _se_mean_of_sd(sd, frames: int) -> float:
    """Standard error of the mean over stars of per-star sample sds from ``frames`` frames.

    Each sd has variance ``sd^2 / (2 (n - 1))`` (normal theory, e.g. Kendall & Stuart,
    vol. 1, 10.8); the stars' noise is independent, so the mean's variance is their sum
    divided by ``W^2``.
    """
    sd = np.asarray(sd, dtype=float)
    return float(math.sqrt(np.sum(sd**2 / (2.0 * (frames - 1)))) / sd.size)


def cramer_rao_bound_px(camera, scene, *, step_px: float = 1e-3):
    """Cramer-Rao bound (px, 1 sigma) of each star's x and y from its window's pixels.

    Fisher information of independent pixels with Poisson signal ``mu_p`` (electrons,
    PRNU and dark included) plus Gaussian read noise, in the Gaussian approximation of
    their sum (variance ``mu_p + r^2 + g^2/12``):
    ``I_xx = sum_p (d mu_p / dx)^2 / var_p`` (Mendez et al. 2014, PASP 126, 798);
    ``d mu_p / dx`` by central differences of the exact pixel-integrated image. The bound
    ignores the off-diagonal information (x and y nearly decouple for a symmetric PSF).
    """
    from simcam.detector import dsnu_map, prnu_map

    p = scene.placement
    out = []
    for dx, dy in ((step_px, 0.0), (-step_px, 0.0), (0.0, step_px), (0.0, -step_px)):
        sc = camera.scene(dreplace(p, platform_dx_px=p.platform_dx_px + dx, platform_dy_px=p.platform_dy_px + dy))
        out.append(sc)
    sig0, col0, row0 = camera.expected_windows_e(scene)
    grads = []
    for a, b in ((out[0], out[1]), (out[2], out[3])):
        # same window origins as the central scene (the shift is far below a pixel)
        ea = _expected_at(camera, a, col0, row0)
        eb = _expected_at(camera, b, col0, row0)
        grads.append((ea - eb) / (2 * step_px))
    det = camera.detector_params
    chips = scene.chip
    crb = []
    for g in grads:
        vals = []
        for j in range(scene.n_stars):
            kw = dict(shape=sig0.shape[1:], row0=int(row0[j]), col0=int(col0[j]), mosaic_cols=camera.mosaic.shape[1],
                      params=det, detector_key=camera.detector_key)
            prnu = prnu_map(**kw)
            mu = sig0[j] * prnu + dsnu_map(**kw)
            k = int(chips[j])
            var = mu + det.read_noise_e[k] ** 2 + det.gain_e_per_dn[k] ** 2 / 12.0
            info = np.sum((g[j] * prnu) ** 2 / var)
            vals.append(1.0 / math.sqrt(info))
        crb.append(np.array(vals))
    return crb[0], crb[1]


def _expected_at(camera, scene, col0, row0):
    w = camera.scenario.render.window_px
    sig = np.zeros((scene.n_stars, w, w))
    cc = camera.mosaic.chip_cols
    for j in range(scene.n_stars):
        k = int(scene.chip[j])
        camera._add_stamps(sig[j], scene, chip=k, row0=int(row0[j]), col0=int(col0[j] - k * cc))
    return sig + scene.background_e


def hsfe_truth(camera, *, frames: int, seed: int, chunk_frames: int = 100, control_variate: bool = True) -> ClassTruth:
    """HSFE truth: rms static error of the *expected* centroid under the lab's noise.

    The lab always centroids noisy frames, and temporal noise dithers the centroid's
    threshold and smooths its pixel-phase S-curve, so the static error the HSFE method
    claims to measure is that of the expected centroid ``E[x_c] - x_true`` (not of the
    noise-free centroid). At each of ``hsfe_phase_grid^2`` sub-pixel phases of the HSFE
    target, ``frames`` noisy frames are exposed (the simulator's full detector chain) and
    centroided as the lab does (method, threshold, dark subtraction), the error against
    the injected position is taken per frame, and its common motion (the mean over stars,
    which eqs 7-8 remove) is subtracted. No HSFE estimator statistic (eqs 3-12, the
    double-centred ``tau^2``) is used: the truth needs the true positions, the lab never
    has them.

    The frames are split into two independent halves ``A`` and ``B``; per (phase, star,
    axis) cell ``c`` the product of the two half-means ``e_A e_B`` is unbiased for
    ``e_c^2`` (independent noise), so ``T = mean_c e_A e_B`` is unbiased for the squared
    rms and the truth is ``sqrt(T)``. Its standard error: ``Var(e_A e_B) = e^2 (a + b) + a b``
    with ``a, b`` the variances of the half-means (from the per-frame scatter), summed over
    the cells, and ``se(sqrt T) = se(T) / (2 sqrt T)`` (delta method). With
    ``validation.dark_frames = K`` each chunk of ``chunk_frames`` frames gets its own mean
    of ``K`` dark frames, so the dark frames' noise is averaged over too.

    Variance reduction (``control_variate``, where :func:`control_variate_applies`; the same
    frames): each frame's error less its control variate ``psi`` (:mod:`budget.starcam.kernels_truth`),
    whose expectation is exactly 0, so each cell's expected error is unchanged and every
    formula above holds with the corrected errors (the half-means stay independent); ``psi``
    follows the centroid's response to the frame's noise, so the per-frame scatter, and the
    frames a given standard error needs, drop by two to three orders of magnitude on the
    default camera.
    """
    n = camera.scenario.validation.hsfe_phase_grid
    cells = [hsfe_phase_cell(camera, frames=frames, seed=seed, phase=p, chunk_frames=chunk_frames,
                             control_variate=control_variate) for p in range(n * n)]
    return hsfe_from_cells(camera, cells, frames=frames, control_variate=control_variate)


def hsfe_phase_cell(camera, *, frames: int, seed: int, phase: int, chunk_frames: int = 100,
                    control_variate: bool = True):
    """One sub-pixel phase of :func:`hsfe_truth` (``phase = i n + k``): the half-means of the
    centroid error of each star and axis and their variances, ``(ma, mb, va, vb)``.

    Phases draw independent streams (``SeedSequence(seed, spawn_key=(phase, half, chunk))``),
    so they can be computed anywhere, in any order, and combined by :func:`hsfe_from_cells`.
    """
    scn = camera.scenario
    n = scn.validation.hsfe_phase_grid
    if frames < 4 or frames % 2:
        raise ValueError(f"hsfe truth frames: an even number >= 4, got {frames}")
    i, k = divmod(int(phase), n)
    plan = make_plan("hsfe", scn)
    ctr = plan.conditions[0].field_center_px
    layout = star_grid(scn, center_px=ctr)
    chunk = max(1, min(chunk_frames, frames // 2))
    pl = Placement(layout=layout, platform_dx_px=(i + 0.5) / n, platform_dy_px=(k + 0.5) / n,
                   condition=999_002)
    scene = camera.scene(pl)
    cv = control_variate and control_variate_applies(scn)
    prep = None
    sx = [np.zeros((2, scene.n_stars)), np.zeros((2, scene.n_stars))]
    cnt = [0, 0]
    sq = np.zeros((2, scene.n_stars))
    for half in (0, 1):
        done = 0
        c = 0
        while done < frames // 2:
            m = min(chunk, frames // 2 - done)
            ss = np.random.SeedSequence(seed, spawn_key=(i * n + k, half, c))
            cseed = int(ss.generate_state(1)[0])
            if cv:
                (x, y, flag, px, py, _, _), prep = _cv_frames(camera, scene, frames=m, seed=cseed, prep=prep)
                _check_flags(flag)
                ex = x - scene.truth.x_true.to_numpy()[None] - px
                ey = y - scene.truth.y_true.to_numpy()[None] - py
            else:
                ex, ey = _noisy_errors(camera, scene, frames=m, seed=cseed)
            e = np.stack([ex, ey])                    # (2, m, W)
            e = e - e.mean(axis=2, keepdims=True)      # common motion removed per frame
            sx[half] += e.sum(axis=1)
            sq += (e**2).sum(axis=1)
            cnt[half] += m
            done += m
            c += 1
    ma, mb = sx[0] / cnt[0], sx[1] / cnt[1]
    tot = cnt[0] + cnt[1]
    mean = (sx[0] + sx[1]) / tot
    var = (sq - tot * mean**2) / (tot - 1)            # per-frame variance of the error
    return ma, mb, var / cnt[0], var / cnt[1]


def hsfe_from_cells(camera, cells, *, frames: int, control_variate: bool = True) -> ClassTruth:
    """The HSFE truth (:func:`hsfe_truth`) from the cells of every phase, in phase order, or of
    a sample of the phases (:func:`hsfe_trial_truth`: the standard error is then the frames'
    part only); ``control_variate``: how the cells were computed, for the details."""
    ma = np.stack([c[0] for c in cells], axis=1)   # (2, phases, W)
    mb = np.stack([c[1] for c in cells], axis=1)
    va = np.stack([c[2] for c in cells], axis=1)
    vb = np.stack([c[3] for c in cells], axis=1)
    ncell = ma.shape[1] * ma.shape[2]
    prod = ma * mb
    t2 = prod.reshape(2, -1).mean(axis=1)
    e2 = np.clip(((ma + mb) / 2) ** 2 - (va + vb) / 4, 0.0, None)
    var_t2 = (e2 * (va + vb) + va * vb).reshape(2, -1).sum(axis=1) / ncell**2
    t = np.sqrt(np.clip(t2, 0.0, None))
    se = np.where(t > 0, np.sqrt(var_t2) / (2 * np.where(t > 0, t, 1.0)), np.sqrt(np.sqrt(var_t2)))
    both = (ma + mb) / 2
    return ClassTruth("hsfe", float(t[0]), float(t[1]), {
        "phases": len(cells), "stars": int(ma.shape[2]), "frames_per_phase": int(frames),
        "route": ("expected centroid of noisy frames, split-half product"
                  + (", less a zero-mean control variate"
                     if control_variate and control_variate_applies(camera.scenario) else "")),
        "noise_free_route": False,
        "max_abs_x_px": float(np.abs(both[0]).max()), "max_abs_y_px": float(np.abs(both[1]).max()),
        "mean_square_x_px2": float(t2[0]), "mean_square_y_px2": float(t2[1]),
        "se_mean_square_x_px2": float(math.sqrt(var_t2[0])), "se_mean_square_y_px2": float(math.sqrt(var_t2[1])),
    }, se_x_px=float(se[0]), se_y_px=float(se[1]))


#: noisy frames per phase of a trial's own HSFE truth where the control variate applies
#: (:func:`hsfe_trial_truth`): the fewest the split-half product takes; on the default camera
#: their part of the truth's scatter is about 0.4 % of it, the sampled phases' the rest
TRIAL_HSFE_FRAMES = 4


#: noise-only frames of a trial's own TE truth where the control variate applies
#: (:func:`te_trial_truth`): on ``seed000_noisy`` its standard error is about 0.6 % of the
#: truth, against cameras that differ by 6-8 % and TE estimators that scatter by a few
#: percent per trial
TRIAL_TE_FRAMES = 50


def te_trial_truth(camera, *, seed: int) -> ClassTruth:
    """TE truth of one camera (a trial's, its own pixel maps): :func:`te_truth` with
    :data:`TRIAL_TE_FRAMES` frames where the control variate applies (else the scenario's
    ``te_truth_frames``). Each star's variance is unbiased (the control variate's terms have
    expectation the variance exactly), its square root low by ``se(V)^2 / (8 sd^3)``, below
    1e-4 of the truth at these frames; the truth's scatter about the camera's enters a run's
    per-trial errors, so the bias's standard error carries it."""
    scn = camera.scenario
    frames = TRIAL_TE_FRAMES if control_variate_applies(scn) else scn.validation.te_truth_frames
    return te_truth(camera, frames=frames, seed=seed, cramer_rao=False)  # the trial keeps the value only


def hsfe_trial_phases(scenario, seed: int) -> np.ndarray:
    """The sub-pixel phases (indices ``i n + k`` of the ``hsfe_phase_grid`` grid, ``n`` per
    axis) of a trial's own HSFE truth: ``validation.hsfe_trial_phases`` of them, distinct,
    drawn uniformly without replacement from the grid with ``seed``, in increasing order."""
    val = scenario.validation
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(0,)))
    return np.sort(rng.choice(val.hsfe_phase_grid**2, size=val.hsfe_trial_phases, replace=False))


def hsfe_trial_truth(camera, *, seed: int) -> ClassTruth:
    """HSFE truth of one camera (a trial's, its own pixel maps) from a sample of the phases:
    :func:`hsfe_truth`'s quantity, estimated without bias and cheaply enough to compute in
    every trial.

    The squared truth is the mean over the grid's ``P = hsfe_phase_grid^2`` phases of each
    phase's mean square ``q_p`` (over stars and the split-half product, :func:`hsfe_from_cells`).
    A simple random sample of ``m = validation.hsfe_trial_phases`` phases without replacement
    (:func:`hsfe_trial_phases`) has ``E[mean_(p in sample) q_p] = mean_p q_p`` (each phase is
    drawn with probability ``m / P``; Cochran, *Sampling Techniques*, 3rd ed., thm 2.1), and the
    split-half product keeps each ``q_p`` unbiased, so the sample's mean square is unbiased for
    the camera's. The truth is its square root: a downward bias of about ``c^2 / 8`` of it
    for a relative sd ``c`` of the mean square (second-order delta method), below 0.1 % for
    the default's 4 phases (phases differ by about 15 % in ``q_p``; measured, the trial truth
    scatters by 2-4 % about the camera's 64-phase truth, 4-8 % on seed 000's noisy camera:
    docs/validation.md). Each phase
    takes :data:`TRIAL_HSFE_FRAMES` frames where the control variate applies (else the
    scenario's ``hsfe_truth_frames``), from streams of ``seed`` (``spawn_key=(1,)``).

    The truth's scatter about the camera's full-grid truth enters a run's per-trial errors,
    so the bias's standard error carries it; its ``se_*_px`` is the frames' part only."""
    scn = camera.scenario
    frames = TRIAL_HSFE_FRAMES if control_variate_applies(scn) else scn.validation.hsfe_truth_frames
    fs = int(np.random.SeedSequence(seed, spawn_key=(1,)).generate_state(1)[0])
    cells = [hsfe_phase_cell(camera, frames=frames, seed=fs, phase=int(p)) for p in hsfe_trial_phases(scn, seed)]
    return hsfe_from_cells(camera, cells, frames=frames)


def _noisy_errors(camera, scene, *, frames: int, seed: int):
    """Centroid errors (x, y; (frames, W) px) of ``frames`` noisy frames of ``scene``,
    centroided as the lab does (scenario's method, threshold and dark subtraction)."""
    from budget.starcam.protocols import _expose_centroid

    scn = camera.scenario
    val = scn.validation
    dark_mean = None
    if val.dark_frames:
        dark = camera.render_windows(scene, frames=val.dark_frames, seed=seed, dark=True)
        dark_mean = dark.pixels.astype(np.float64).mean(axis=0)
    tx = scene.truth.x_true.to_numpy()
    ty = scene.truth.y_true.to_numpy()
    if val.centroid_method == "cog":
        chain = camera.window_chain(scene)
        noise = centroid_options(camera, chain.col0, val.threshold_sigma, dark_frames=val.dark_frames)["noise_dn"]
        x, y, _, flag = _expose_centroid(camera, chain, scene, frames=frames, seed=seed, dark_mean=dark_mean,
                                         threshold_dn=float(val.threshold_sigma) * noise)
    else:
        win = camera.render_windows(scene, frames=frames, seed=seed)
        pix = win.pixels.astype(np.float64)
        if dark_mean is not None:
            pix = pix - dark_mean[None]
        x, y, flag = _centroid(camera, win, val.centroid_method, scn, pixels=pix)
    _check_flags(flag)
    return x - tx[None], y - ty[None]


def _check_flags(flag):
    if np.any(flag != 0):
        raise ValueError("hsfe truth: a star of the HSFE target was lost in a noisy frame "
                         "(centroid flag set); the static error of its expected centroid is undefined")


def _field_grid(camera, n: int, margin_px: float = 40.0):
    det = camera.scenario.detector
    half_u = (det.n_chips * det.chip_cols + (det.n_chips - 1) * det.gap_px) / 2 - margin_px
    half_v = det.chip_rows / 2 - margin_px
    u, v = np.meshgrid(np.linspace(-half_u, half_u, n), np.linspace(-half_v, half_v, max(2, (n + 1) // 2)))
    u, v = u.ravel(), v.ravel()
    chip, _, _ = camera.mosaic.focal_to_chip(u, v)
    return u[chip >= 0], v[chip >= 0]


def chromatic_shift_px(camera, weights, u, v):
    """Spectrum-weighted lateral-colour displacement (px) at focal points (u, v)."""
    scn = camera.scenario
    lc = scn.optics.lateral_colour
    su, sv = optics.lateral_colour_shift_px(
        wavelength_nm=camera.spectra.wavelength_nm, u_px=u, v_px=v, ref_wavelength_nm=lc.ref_wavelength_nm,
        radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
        uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px,
    )
    return su @ weights, sv @ weights


def star_weights(camera, spectral_type: str) -> np.ndarray:
    """Wavelength weights of a star of ``spectral_type`` (blackbody at its Teff), no filter."""
    sp = camera.spectra
    t = spectra.star_teff_k(spectral_type=spectral_type)
    flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=t, wavelength_nm=sp.wavelength_nm)
    rate = spectra.detected_electron_rate_per_nm(
        photon_flux_per_nm=flux, aperture_area_m2=sp.aperture_area_m2, transmission=sp.transmission,
        filter_transmission=1.0, qe=sp.qe, wavelength_nm=sp.wavelength_nm)
    return sp.weights(rate)


def lsfe_s_truth(camera) -> ClassTruth:
    """LSFE-S truth: rms chromatic displacement of a stellar population about its reference.

    For each stellar type of ``lsfe_spectral_types`` (blackbody at its Teff through the
    camera's true optics and QE, no filter) and each point of a ``field_grid`` grid over
    the detector, the spectrum-weighted lateral-colour displacement is computed from the
    injected lateral-colour model (all wavelengths, no linearisation). The reference
    (``validation.calibration_spectrum``) is by default the population mean at each field
    point (``population_mean``): the offset common to the population is calibrated at
    system level (seed 000 section 1.4.1), so what varies with a star's colour is what the
    class claims. ``lamp`` (the lab lamp without filter) or a spectral type refer it to
    that spectrum instead. The rms is over types and field points, per axis. Nothing of
    the lab's effective-wavelength model (the improved estimator's) is used.
    """
    scn = camera.scenario
    val = scn.validation
    u, v = _field_grid(camera, val.field_grid)
    dx, dy = [], []
    for st in val.lsfe_spectral_types:
        su, sv = chromatic_shift_px(camera, star_weights(camera, st), u, v)
        dx.append(su)
        dy.append(sv)
    dx, dy = np.array(dx), np.array(dy)
    if val.calibration_spectrum == "population_mean":
        cu, cv = dx.mean(axis=0), dy.mean(axis=0)
    else:
        if val.calibration_spectrum == "lamp":
            _, rate = camera.spectra.electron_rate_per_nm(filter_nm=None)
            w_cal = camera.spectra.weights(rate)
        else:
            w_cal = star_weights(camera, val.calibration_spectrum)
        cu, cv = chromatic_shift_px(camera, w_cal, u, v)
    dx, dy = dx - cu, dy - cv
    return ClassTruth("lsfe_s", float(np.sqrt(np.mean(dx**2))), float(np.sqrt(np.mean(dy**2))), {
        "spectral_types": list(val.lsfe_spectral_types), "field_points": int(u.size),
        "calibration_spectrum": val.calibration_spectrum,
        "per_type_mean_x_px": dx.mean(axis=1).tolist(), "per_type_mean_y_px": dy.mean(axis=1).tolist(),
    })


#: cells of the dense whole-field grid per ``validation.field_grid`` along the mosaic's long side
#: (the short side in proportion): 16 x 9 = 144 x 72 points on seed 000's two-chip mosaic
C1_FIELD_CELLS_PER_GRID = 16


def field_points_px(camera, cells_long: int):
    """Focal-plane points (px) of the field the camera uses: the centres of a grid of square-ish
    cells over the bounding box of its chips (``cells_long`` along the long side), those that fall
    on a chip (the chip gaps excluded)."""
    mos = camera.mosaic
    cu = np.array([-0.5, mos.chip_cols - 0.5, mos.chip_cols - 0.5, -0.5])
    cv = np.array([-0.5, -0.5, mos.chip_rows - 0.5, mos.chip_rows - 0.5])
    u_c, v_c = zip(*(mos.chip_to_focal(np.full(4, k), cu, cv) for k in range(mos.n_chips)))
    u_c, v_c = np.concatenate(u_c), np.concatenate(v_c)
    lu, lv = np.ptp(u_c), np.ptp(v_c)
    nu = cells_long if lu >= lv else max(2, round(cells_long * lu / lv))
    nv = cells_long if lv > lu else max(2, round(cells_long * lv / lu))
    u = u_c.min() + (np.arange(nu) + 0.5) * lu / nu
    v = v_c.min() + (np.arange(nv) + 0.5) * lv / nv
    uu, vv = (a.ravel() for a in np.meshgrid(u, v))
    _, ix, _ = mos.focal_to_mosaic(uu, vv)
    on = np.isfinite(ix)
    return uu[on], vv[on]


def _in_box(lay, u, v):
    return (u >= lay.u_px.min()) & (u <= lay.u_px.max()) & (v >= lay.v_px.min()) & (v <= lay.v_px.max())


def _fitted_residual(camera, u, v):
    """What the calibrated camera still displaces at ideal points ``(u, v)`` (mosaic px), those
    whose ideal point and lamp image both fall on a chip (``ok``), and their raw static displacement."""
    mos = camera.mosaic
    _, ix, iy = mos.focal_to_mosaic(u, v)
    _, mx, my = mos.focal_to_mosaic(*lamp_image_focal_px(camera, u, v))
    ok = np.isfinite(ix) & np.isfinite(mx)   # points in the chip gap image nowhere
    rx_, ry_ = camera.report_positions(mx[ok], my[ok])
    return rx_ - ix[ok], ry_ - iy[ok], mx[ok] - ix[ok], my[ok] - iy[ok], ok


def lsfe_c1_truth(camera) -> ClassTruth:
    """LSFE-C1 truth: rms over the whole field the camera uses of the displacement it still makes.

    The field is the mosaic where stars fall, chip gaps excluded (:func:`field_points_px`,
    :data:`C1_FIELD_CELLS_PER_GRID` x ``validation.field_grid`` cells along its long side; the
    rms over the cell centres is the midpoint rule for the field's mean square, e.g. Press et al.,
    Numerical Recipes, 3rd ed., section 4.1): a star anywhere in the field carries this error,
    not only one inside the lab grid's box.

    * Calibrated camera (``optics.distortion_correction.kind = "fitted"``, the default): the
      camera reports its centroids through the correction of an earlier calibration
      (:mod:`simcam.starcam.correction`). The lamp's image of each ideal point ``p`` (distortion,
      then lateral colour) is reported at ``R(M(D(p) + s(D(p))))`` with ``R`` the camera's
      correction and ``M`` focal plane to mosaic; the remaining displacement ``r = reported -
      M(p)`` about its mean over the field (a common offset is the boresight, calibrated at
      system level), rms per axis.
    * Uncalibrated camera (``kind = "none"``): the camera reports raw centroids, and what a
      distortion calibration would leave is taken as the truth: a full cubic fitted to the true
      static displacement at the lab grid's points, its residual rms over the field (eq 29 on
      such a camera measures the cubic part of the whole distortion, the part a calibration
      removes).

    Beside it (details): ``grid_coverage``, the fraction of the field's area inside the lab
    grid's bounding box (the share of the cells there), and ``box_x_px`` / ``box_y_px``, the
    same residual over the cells inside that box only (the truth's definition before the whole
    field, there on a 36 x 18 grid spanning the box: what the lab grid sees). Neither route
    uses the lab's centroid tables, reference coordinates or estimators.
    """
    scn = camera.scenario
    lay = calibration_grid(scn)
    fu, fv = field_points_px(camera, C1_FIELD_CELLS_PER_GRID * scn.validation.field_grid)
    box = _in_box(lay, fu, fv)
    base = {"dense_points": int(fu.size), "grid_coverage": float(np.mean(box)),
            "calibration_points": int(lay.n_stars), "field": "whole mosaic, chip gaps excluded"}
    corr = camera.onboard_correction
    if corr is not None:
        rx, ry, sx, sy, ok = _fitted_residual(camera, fu, fv)
        inb = box[ok]
        return ClassTruth("lsfe_c1", float(np.std(rx)), float(np.std(ry)), {
            **base, "camera_correction": "fitted", "correction_order": int(corr.order),
            "box_x_px": float(np.std(rx[inb])), "box_y_px": float(np.std(ry[inb])),
            "raw_static_rms_x_px": float(np.std(sx)), "raw_static_rms_y_px": float(np.std(sy)),
            "max_abs_x_px": float(np.abs(rx - rx.mean()).max()), "max_abs_y_px": float(np.abs(ry - ry.mean()).max()),
        })

    def static(u, v):
        pu, pv = lamp_image_focal_px(camera, u, v)
        return pu - u, pv - v

    gx, gy = static(lay.u_px, lay.v_px)
    cu0, cv0 = lay.u_px.mean(), lay.v_px.mean()
    su = np.abs(lay.u_px - cu0).max()
    sv = np.abs(lay.v_px - cv0).max()
    a = poly_design((lay.u_px - cu0) / su, (lay.v_px - cv0) / sv, 3)
    coef_x, *_ = np.linalg.lstsq(a, gx, rcond=None)
    coef_y, *_ = np.linalg.lstsq(a, gy, rcond=None)

    fx, fy = static(fu, fv)
    _, mx, _ = camera.mosaic.focal_to_mosaic(fu + fx, fv + fy)
    on = np.isfinite(mx)   # where a star's image falls on a chip
    fx, fy, inb = fx[on], fy[on], box[on]
    b = poly_design((fu[on] - cu0) / su, (fv[on] - cv0) / sv, 3)
    rx, ry = fx - b @ coef_x, fy - b @ coef_y
    return ClassTruth("lsfe_c1", float(np.sqrt(np.mean(rx**2))), float(np.sqrt(np.mean(ry**2))), {
        **base, "camera_correction": "none (truth: what a cubic calibration would leave)",
        "box_x_px": float(np.sqrt(np.mean(rx[inb]**2))), "box_y_px": float(np.sqrt(np.mean(ry[inb]**2))),
        "static_rms_x_px": float(np.std(fx)), "static_rms_y_px": float(np.std(fy)),
        "cubic_part_rms_x_px": float(np.std(b @ coef_x)), "cubic_part_rms_y_px": float(np.std(b @ coef_y)),
    })


def lsfe_c2_truth(scenario) -> ClassTruth:
    """LSFE-C2 truth: the injected marker calibration error, 1 sigma px per axis."""
    s = scenario.lab.calibration_target.marker_error_3sigma_arcsec / 3.0 / scenario.camera.scale_arcsec_per_px
    return ClassTruth("lsfe_c2", s, s, {"marker_error_3sigma_arcsec": scenario.lab.calibration_target.marker_error_3sigma_arcsec})


def rss_truth(name: str, parts, details: dict | None = None) -> ClassTruth:
    """Root-sum-square of independent classes' truths, with the propagated standard error.

    ``T = sqrt(sum_i t_i^2)``; first order (delta method), ``se(T) = sqrt(sum_i (t_i se_i)^2) / T``.
    """
    vals = {}
    for ax in ("x", "y"):
        t = np.array([getattr(p, f"{ax}_px") for p in parts])
        se = np.array([getattr(p, f"se_{ax}_px") for p in parts])
        tot = float(math.sqrt(np.sum(t**2)))
        vals[ax] = (tot, float(math.sqrt(np.sum((t * se) ** 2)) / tot) if tot > 0 else float(math.sqrt(np.sum(se**2))))
    return ClassTruth(name, vals["x"][0], vals["y"][0], details or {}, se_x_px=vals["x"][1], se_y_px=vals["y"][1])


def combine(t: dict) -> dict:
    """Add the root-sum-square LSFE (S, C1, C2) and total (TE, HSFE, LSFE) to the class truths,
    each where its parts are there (a validation of some protocols computes some classes)."""
    if all(k in t for k in ("lsfe_s", "lsfe_c1", "lsfe_c2")):
        t["lsfe"] = rss_truth("lsfe", [t["lsfe_s"], t["lsfe_c1"], t["lsfe_c2"]], {"combination": "rss of S, C1, C2"})
    if all(k in t for k in ("te", "hsfe", "lsfe")):
        t["total"] = rss_truth("total", [t["te"], t["hsfe"], t["lsfe"]], {"combination": "rss of TE, HSFE, LSFE"})
    return t
