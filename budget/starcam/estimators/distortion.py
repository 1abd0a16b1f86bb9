"""Distortion-calibration low-frequency error LSFE-C1 and the marker error LSFE-C2.

Published (seed 000): LSFE-C1, eqs 17-30 (:func:`distortion_residual_error`): per-point
means (eqs 17-18), residuals to the reference coordinates (eqs 19-20), their sample
standard deviation (eqs 21-24), a full bivariate cubic fit of the residuals and the
standard deviation of what it leaves (eqs 25-28), ``sqrt(sigma_dX^2 - sigma_DdX^2)``
(eqs 29-30); LSFE-C2, a given figure (section 1.4.3, :func:`target_marker_error`).

Improved (docs/estimators.md, distortion): the fit's W - 10 degrees of freedom
(:func:`distortion_residual_error_dof`), the distortion left after the calibration
(:func:`distortion_calibration_residual`), the displacement a calibrated camera still makes
(:func:`distortion_remaining_displacement`).

The four LSFE-C1 variants share their steps, one helper each: :func:`_point_means` (eqs
17-18), :func:`_residuals_to_reference` (eqs 19-20), :func:`_cubic_fit` (the cubic of eqs
25-26), :func:`_sample_variance` (eqs 23-24, 27-28) and :func:`_fit_residual_variance`
(the W - 10 degrees of freedom); they differ only in which variances they subtract.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from simcam.infra.errors import UserInputError

from .common import _check_plate_scale, _Log, _memo_last, _nonneg, _per_star_stats, _prepare, _Rows, _select_condition
from .results import DistortionEstimate, ErrorEstimate

_WHAT = "LSFE-C1"


def cubic_design_matrix(u: Any, v: Any) -> np.ndarray:
    """Full bivariate cubic basis (10 terms): 1, u, v, u^2, uv, v^2, u^3, u^2 v, u v^2, v^3."""
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    return np.column_stack([np.ones_like(u), u, v, u * u, u * v, v * v,
                            u**3, u * u * v, u * v * v, v**3])



def _point_means(table, *, condition, what, log):
    """Good rows of one static condition and each point's mean, variance (ddof 1) and
    frame count (eqs 17-18); returns ``(stats sorted by star, n rows excluded)``."""
    table = _select_condition(table, condition, what)
    _, good, n_bad = _prepare(table, required=("star", "frame", "x", "y"),
                              key=tuple(c for c in ("star", "condition", "frame") if c in table.columns),
                              what=what, log=log)
    return _per_star_stats(good, ["star"], 1), n_bad                     # eqs 17-18


def _reference_rows(reference, what) -> _Rows:
    """The reference coordinates ``star, x_ref, y_ref`` as rows, checked when a DataFrame
    (columns there, stars listed once, finite coordinates); a simulated protocol's own
    (:func:`budget.starcam.protocols.reference_table`) meets the checks by construction."""
    if isinstance(reference, _Rows):
        return reference
    if not isinstance(reference, pd.DataFrame):
        raise UserInputError(f"{what}: reference: expected a DataFrame with star, x_ref, y_ref")
    miss = [c for c in ("star", "x_ref", "y_ref") if c not in reference.columns]
    if miss:
        raise UserInputError(f"{what}: reference: missing column(s) {', '.join(miss)}")
    if reference["star"].duplicated().any():
        raise UserInputError(f"{what}: reference: star {reference['star'][reference['star'].duplicated()].iloc[0]} listed twice")
    for c in ("x_ref", "y_ref"):
        if not pd.api.types.is_numeric_dtype(reference[c]) or not np.isfinite(reference[c].to_numpy(float)).all():
            raise UserInputError(f"{what}: reference: column {c!r} must be finite numbers")
    return _Rows({"star": reference["star"].to_numpy(), "x_ref": reference["x_ref"].to_numpy(float),
                  "y_ref": reference["y_ref"].to_numpy(float)})


def _residuals_to_reference(st, reference, *, what, log):
    """Residuals of the point means to the reference coordinates, ``dX_j = Xbar_j - X0_j``
    (eqs 19-20), in the order of ``st`` (sorted by star); returns
    ``(x0, y0, dx, dy, stars of the reference without a good centroid)``."""
    unknown = sorted(set(st["star"].tolist()) - set(reference["star"].tolist()))
    if unknown:
        raise UserInputError(f"{what}: star(s) {unknown[:10]} have no reference coordinates")
    lost = sorted(set(reference["star"].tolist()) - set(st["star"].tolist()))
    if lost:
        log.warn(f"{what}: {len(lost)} reference point(s) without a good centroid excluded "
                 f"(stars {lost[:10]})")
    # st is sorted by star and every star of st has its reference (checked above)
    _need_points(len(st), 10, what)
    ref_star = reference["star"]
    order = np.argsort(ref_star, kind="stable")
    ri = order[np.searchsorted(ref_star[order], st["star"])]
    x0, y0 = reference["x_ref"][ri], reference["y_ref"][ri]
    dx = st["mean_x"] - x0                    # eq 19
    dy = st["mean_y"] - y0                    # eq 20
    return x0, y0, dx, dy, lost


def _cubic_fit(x0, y0, *values, what):
    """Least-squares full bivariate cubic (10 terms) in the reference coordinates, one fit
    per array of ``values``; returns the fitted values (the fit of eqs 25-26).

    The coordinates are centred and divided by their half range before the design matrix is
    formed (conditioning only: the fitted values do not depend on it).
    """
    cu, cv = x0.mean(), y0.mean()
    su = max(np.max(np.abs(x0 - cu)), 1e-300)
    sv = max(np.max(np.abs(y0 - cv)), 1e-300)
    a = cubic_design_matrix((x0 - cu) / su, (y0 - cv) / sv)
    if np.linalg.matrix_rank(a) < 10:
        raise UserInputError(f"{what}: the reference points do not determine a full cubic "
                             "(collinear or too regular layout)")
    return [a @ np.linalg.lstsq(a, d, rcond=None)[0] for d in values]


@_memo_last
def _distortion_core(table, reference, *, condition, what, log):
    """The steps every LSFE-C1 variant shares (eqs 17-20, 25-26): the residuals per point
    ``star, x_ref, y_ref, dx_px, dy_px, fit_x_px, fit_y_px, ddx_px, ddy_px,
    var_mean_x_px2, var_mean_y_px2`` (rows), rows excluded, points excluded, fewest frames."""
    st, n_bad = _point_means(table, condition=condition, what=what, log=log)
    x0, y0, dx, dy, lost = _residuals_to_reference(st, _reference_rows(reference, what), what=what, log=log)
    fx, fy = _cubic_fit(x0, y0, dx, dy, what=what)
    points = _Rows({"star": st["star"], "x_ref": x0, "y_ref": y0,
                    "dx_px": dx, "dy_px": dy, "fit_x_px": fx, "fit_y_px": fy,
                    "ddx_px": dx - fx, "ddy_px": dy - fy,  # eqs 25-26
                    # temporal variance of each point's N-frame mean
                    "var_mean_x_px2": st["var_x"] / st["n"], "var_mean_y_px2": st["var_y"] / st["n"]})
    return points, n_bad, len(lost), int(st["n"].min())


def _sample_variance(d) -> float:
    """Sample variance (ddof 1) of the points: ``sigma_dX^2`` (eqs 23-24) or
    ``sigma_DdX^2`` (eqs 27-28); its root is ``numpy.std(d, ddof=1)``."""
    return float(np.var(d, ddof=1))


def _fit_residual_variance(dd) -> float:
    """``sum_j DdX_j^2 / (W - 10)``: the fit residual's variance with the cubic's 10 degrees
    of freedom taken out (unbiased for the point-to-point variance)."""
    return float(np.sum(dd**2)) / (len(dd) - 10)


def _need_points(w: int, min_points: int, what: str) -> None:
    if w < min_points:
        raise UserInputError(f"{what}: the cubic fit (10 terms) needs at least {min_points} points, got {w}")


def _root_of_difference(a2: float, b2: float, axis: str, flags: list, log: _Log, what: str) -> float:
    diff = a2 - b2
    if diff < 0:
        flags.append(f"clipped_{axis}")
        log.warn(f"{what}: negative variance difference along {axis} ({diff:.3g} px^2); set to 0")
        return 0.0
    return math.sqrt(diff)




def _c1_points(table, reference, condition, log, *, min_points=0):
    points, n_bad, n_excl, n_min = _distortion_core(table, reference, condition=condition, what=_WHAT, log=log)
    if min_points:
        _need_points(len(points), min_points, _WHAT)
    return points, (n_bad, n_excl, n_min)


def _c1_estimate(sig, *, method, equations, ps, points, counts, flags, log, details) -> DistortionEstimate:
    """The estimate of a variant from its sigmas and what :func:`_c1_points` gave."""
    n_bad, n_excl, n_min = counts
    return DistortionEstimate(
        quantity="LSFE-C1", method=method, equations=equations,
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=len(points), n_frames=n_min, n_conditions=1, n_stars_excluded=n_excl,
        n_rows_excluded=n_bad, flags=tuple(flags), warnings=tuple(log.messages),
        details=details, residuals=points.to_frame,
    )


def distortion_residual_error(
    table: pd.DataFrame,
    *,
    reference: pd.DataFrame,
    plate_scale_arcsec: float,
    condition: int | None = None,
) -> DistortionEstimate:
    """Distortion-calibration low-frequency error LSFE-C1 as published (seed 000 eqs 17-30).

    Per-point means (eqs 17-18); residuals to the reference coordinates
    ``dX_j = Xbar_j - X0_j`` (eqs 19-20); their mean and sample standard deviation
    ``sigma_dX`` (ddof 1, eqs 21-24); a full bivariate cubic least-squares fit of the
    residuals in the (normalised) reference coordinates; fit residual
    ``DdX_j = dX_j - fit_j`` (eqs 25-26) and its sample standard deviation
    ``sigma_DdX`` (ddof 1, eqs 27-28); ``sigma_C1 = sqrt(sigma_dX^2 - sigma_DdX^2)``
    (eqs 29-30; 0 with flag ``clipped_*`` and a warning if negative).

    Parameters
    ----------
    table : pandas.DataFrame
        Columns ``star``, ``frame``, ``x``, ``y`` (px), optional ``condition``, ``flag``.
    reference : pandas.DataFrame
        Columns ``star``, ``x_ref``, ``y_ref``: the target's calibrated coordinates
        (mosaic px).
    plate_scale_arcsec : float
    condition : int, optional

    Returns
    -------
    DistortionEstimate
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    points, counts = _c1_points(table, reference, condition, log)
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {}
    for ax in ("x", "y"):
        d = points[f"d{ax}_px"]
        dd = points[f"dd{ax}_px"]
        sd = math.sqrt(_sample_variance(d))            # eqs 23-24
        sdd = math.sqrt(_sample_variance(dd))          # eqs 27-28
        details[f"mean_d{ax}_px"] = float(d.mean())
        details[f"sigma_d{ax}_px"] = sd
        details[f"sigma_dd{ax}_px"] = sdd
        sig[ax] = _root_of_difference(sd**2, sdd**2, ax, flags, log, _WHAT)   # eqs 29-30
    return _c1_estimate(sig, method="published", equations="seed 000 eqs 17-30", ps=ps,
                        points=points, counts=counts, flags=flags, log=log, details=details)


def distortion_residual_error_dof(
    table: pd.DataFrame,
    *,
    reference: pd.DataFrame,
    plate_scale_arcsec: float,
    condition: int | None = None,
) -> DistortionEstimate:
    """LSFE-C1 with the cubic fit's degrees of freedom accounted for.

    The fit residual variance is estimated with its ``W - 10`` degrees of freedom,
    ``s_res^2 = sum_j DdX_j^2 / (W - 10)``, unbiased for the point-to-point
    (non-cubic) variance; then (docs/estimators.md, distortion)
    ``sigma_C1^2 = sigma_dX^2 - s_res^2``, unbiased for the variance over the points of
    the cubic (low-frequency) part. Needs ``W > 10``.

    Parameters
    ----------
    table, reference, plate_scale_arcsec, condition
        As in :func:`distortion_residual_error`.

    Returns
    -------
    DistortionEstimate
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    points, counts = _c1_points(table, reference, condition, log, min_points=11)
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {}
    for ax in ("x", "y"):
        sd2 = _sample_variance(points[f"d{ax}_px"])
        sres2 = _fit_residual_variance(points[f"dd{ax}_px"])
        details[f"sigma_d{ax}_px"] = math.sqrt(sd2)
        details[f"sigma_fit_residual_{ax}_px"] = math.sqrt(sres2)
        sig[ax] = _root_of_difference(sd2, sres2, ax, flags, log, _WHAT)
    return _c1_estimate(sig, method="fit-dof", equations="docs/estimators.md (distortion, W-10)",
                        ps=ps, points=points, counts=counts, flags=flags, log=log, details=details)


def distortion_calibration_residual(
    table: pd.DataFrame,
    *,
    reference: pd.DataFrame,
    plate_scale_arcsec: float,
    marker_3sigma_arcsec: float,
    condition: int | None = None,
) -> DistortionEstimate:
    """LSFE-C1 as the distortion left *after* the cubic calibration (improved variant).

    Eq 29's ``sqrt(sigma_dX^2 - sigma_DdX^2)`` is the spread of the part of the residuals
    that the cubic explains, i.e. the distortion the calibration *removes*, not what it
    leaves (docs/estimators.md, distortion). What is left at the points is the fit
    residual without its measurement noise: with ``s_res^2 = sum_j DdX_j^2 / (W - 10)``
    (unbiased for the point-to-point variance), the marker calibration error
    ``sigma_m = C2 / 3`` (given) and each point's temporal variance of its N-frame mean
    ``v_j = s_j^2 / N_j``::

        sigma_C1^2 = s_res^2 - sigma_m^2 - mean_j v_j

    clipped at 0 with a flag (the static pixel errors of HSFE at the points stay in it).

    Parameters
    ----------
    table, reference, plate_scale_arcsec, condition
        As in :func:`distortion_residual_error`.
    marker_3sigma_arcsec : float
        The target's marker calibration error, 3 sigma arcsec (seed 000's C2).

    Returns
    -------
    DistortionEstimate
    """
    def fit_residual_variance(points, ax):
        return f"sigma_fit_residual_{ax}_px", _fit_residual_variance(points[f"dd{ax}_px"])

    return _c1_minus_known_noise(table, reference, plate_scale_arcsec, marker_3sigma_arcsec, condition,
                                 fit_residual_variance, min_points=11, method="after-calibration",
                                 equations="docs/estimators.md (distortion left after calibration)")


def _c1_minus_known_noise(table, reference, plate_scale_arcsec, marker_3sigma_arcsec, condition,
                          variance, *, min_points, method, equations) -> DistortionEstimate:
    """``sigma_C1^2 = V - sigma_m^2 - mean_j v_j`` per axis, clipped at 0 with a flag: a
    variance ``V`` of the points (``variance(points, axis) -> (detail name, V)``) less the
    given marker variance and the temporal variance of the points' means."""
    ps = _check_plate_scale(plate_scale_arcsec)
    m3 = float(_nonneg("marker_3sigma_arcsec", marker_3sigma_arcsec))
    log = _Log()
    points, counts = _c1_points(table, reference, condition, log, min_points=min_points)
    sm2 = (m3 / (3.0 * ps)) ** 2
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {"marker_sigma_px": math.sqrt(sm2)}
    for ax in ("x", "y"):
        name, v = variance(points, ax)
        noise2 = float(np.mean(points[f"var_mean_{ax}_px2"]))
        details[name] = math.sqrt(v)
        details[f"temporal_variance_of_means_{ax}_px2"] = noise2
        sig[ax] = _root_of_difference(v, sm2 + noise2, ax, flags, log, _WHAT)
    return _c1_estimate(sig, method=method, equations=equations, ps=ps, points=points, counts=counts, flags=flags,
                        log=log, details=details)


def distortion_remaining_displacement(
    table: pd.DataFrame,
    *,
    reference: pd.DataFrame,
    plate_scale_arcsec: float,
    marker_3sigma_arcsec: float,
    condition: int | None = None,
) -> DistortionEstimate:
    """LSFE-C1 of a camera that applies its own distortion correction (improved variant).

    A calibrated camera reports positions already corrected by an earlier calibration;
    what the test grid sees, ``dX_j = Xbar_j - X0_j`` (eqs 19-20), is the displacement the
    camera still makes at the point, plus the marker error of the reference (sigma_m =
    C2 / 3) plus the temporal noise of the N-frame mean (variance ``v_j = s_j^2 / N_j``),
    independent of each other. The spread over the points of what the camera still does
    (the claim of LSFE-C1: the calibrated camera's residual low-frequency error) is then
    (docs/estimators.md, distortion of a calibrated camera)::

        sigma_C1^2 = s_dX^2 - sigma_m^2 - mean_j v_j

    with ``s_dX^2`` the sample variance of ``dX`` (ddof 1, eqs 21-24), clipped at 0 with a
    flag. Unlike eq 29 no cubic is fitted: the cubic part of ``dX`` is what eq 29 reports,
    and on a calibrated camera whose residual is 0 it is the markers' ``sqrt(9/31)
    sigma_m`` (32 points), not a distortion.

    Parameters
    ----------
    table, reference, plate_scale_arcsec, condition, marker_3sigma_arcsec
        As in :func:`distortion_calibration_residual`.

    Returns
    -------
    DistortionEstimate
    """
    def displacement_variance(points, ax):
        return f"sigma_d{ax}_px", _sample_variance(points[f"d{ax}_px"])

    return _c1_minus_known_noise(table, reference, plate_scale_arcsec, marker_3sigma_arcsec, condition,
                                 displacement_variance, min_points=0, method="remaining-displacement",
                                 equations="docs/estimators.md (distortion of a calibrated camera)")


def target_marker_error(
    *, x_3sigma_arcsec: float, y_3sigma_arcsec: float, plate_scale_arcsec: float
) -> ErrorEstimate:
    """LSFE-C2, the target's own marker calibration error (seed 000 section 1.4.3).

    A given figure (the seed: 0.5" 3 sigma from the total station's specification),
    wrapped as an :class:`ErrorEstimate` so it combines like the measured classes:
    ``sigma_px = value / (3 plate_scale)``.

    Parameters
    ----------
    x_3sigma_arcsec, y_3sigma_arcsec : float
        Given 3-sigma marker error per axis (arcsec).
    plate_scale_arcsec : float

    Returns
    -------
    ErrorEstimate
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    vx = float(_nonneg("x_3sigma_arcsec", x_3sigma_arcsec))
    vy = float(_nonneg("y_3sigma_arcsec", y_3sigma_arcsec))
    return ErrorEstimate(
        quantity="LSFE-C2", method="given", equations="seed 000 section 1.4.3",
        sigma_x_px=vx / (3.0 * ps), sigma_y_px=vy / (3.0 * ps), plate_scale_arcsec=ps,
        n_stars=0, n_frames=0, n_conditions=0,
    )
