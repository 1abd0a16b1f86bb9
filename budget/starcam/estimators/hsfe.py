"""High spatial frequency error HSFE: seed 000 eqs 3-12 (:func:`high_spatial_frequency_error`),
and the improved variants of docs/estimators.md (HSFE): temporal noise and common-motion
removal accounted for (:func:`high_spatial_frequency_error_debiased`), and the static error
itself rather than its consecutive differences (:func:`high_spatial_frequency_error_static`)."""

from __future__ import annotations

import math
from functools import partial
from typing import Any

import numpy as np
import pandas as pd

from simcam.infra.errors import UserInputError

from .common import _check_plate_scale, _Log, _memo_last, _per_star_stats, _prepare, _unique
from .results import HsfeEstimate


@_memo_last
def _hsfe_stats(table, *, what: str, log: _Log):
    """The table's stars (sorted), good rows and per-(star, condition) statistics of an HSFE
    table (shared by variants)."""
    rows, good, n_bad = _prepare(table, required=("star", "condition", "frame", "x", "y"),
                                 key=("star", "condition", "frame"), what=what, log=log)
    return _unique(rows["star"]), good, n_bad, _per_star_stats(good, ["star", "condition"], 1)


def _hsfe_matrices(table, *, need_frames: int, what: str, log: _Log):
    all_stars, df, n_bad, st = _hsfe_stats(table, what=what, log=log)
    conditions = _unique(st["condition"])                 # those of the good rows
    m = conditions.size
    if m < 2:
        raise UserInputError(f"{what}: needs at least 2 conditions, got {m} ({conditions.tolist()})")
    # st has one row per (star, condition), sorted by (star, condition)
    st_star = st["star"]
    keep = st["n"] >= need_frames
    kept_stars, n_conditions = np.unique(st_star[keep], return_counts=True)
    complete = kept_stars[n_conditions == m]
    dropped = np.setdiff1d(all_stars, complete)
    if dropped.size:
        log.warn(f"{what}: {dropped.size} star(s) lack {need_frames}+ good frames in some "
                 f"condition and are excluded (stars {dropped.tolist()[:10]})")
    w = complete.size
    if w < 2:
        raise UserInputError(f"{what}: needs at least 2 stars seen in every condition, got {w}")
    # rows are sorted by (star, condition) and each complete star has all m conditions
    sel = keep & np.isin(st_star, complete)

    def mat(col):
        return np.asarray(st[col], dtype=float)[sel].reshape(w, m)

    return (df, n_bad, complete, conditions, mat("mean_x"), mat("mean_y"),
            mat("var_x"), mat("var_y"), mat("n"), int(dropped.size))


def _hsfe_residuals(mean):
    d = np.diff(mean, axis=1)                      # eqs 5-6: (W, M-1)
    return d - d.mean(axis=0, keepdims=True)       # eqs 7-8


def _residual_table(stars, conditions, dx, dy):
    w, k = dx.shape
    return pd.DataFrame({
        "star": np.repeat(stars, k),
        "k": np.tile(np.arange(1, k + 1), w),
        "condition_from": np.tile(conditions[:-1], w),
        "condition_to": np.tile(conditions[1:], w),
        "delta_x_px": dx.ravel(),
        "delta_y_px": dy.ravel(),
    })


def high_spatial_frequency_error(table: pd.DataFrame, *, plate_scale_arcsec: float) -> HsfeEstimate:
    """High spatial frequency error HSFE as published (seed 000 eqs 3-12).

    Per condition ``k`` (sorted by ``condition``) and star ``j``: the mean centroid
    ``Xbar_j(k)`` (eqs 3-4); ``dX_j(k) = Xbar_j(k+1) - Xbar_j(k)`` (eqs 5-6);
    ``delta_j(k) = dX_j(k) - (1/W) sum_j dX_j(k)`` (eqs 7-8);
    ``sigma = sqrt(sum_k sum_j delta_j(k)^2 / (W (M - 1)))`` (eqs 9-10);
    ``HSFE = 3 sigma * plate_scale`` (eqs 11-12). Stars missing from a condition are
    excluded from every condition (with a warning).

    Parameters
    ----------
    table : pandas.DataFrame
        Columns ``star``, ``condition``, ``frame``, ``x``, ``y`` (px), optional ``flag``.
    plate_scale_arcsec : float

    Returns
    -------
    HsfeEstimate
        With ``residuals`` = ``delta_j(k)`` per axis.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    (_, n_bad, stars, conds, mx, my, _, _, n, n_excl) = _hsfe_matrices(
        table, need_frames=1, what="HSFE", log=log)
    w, m = mx.shape
    dx, dy = _hsfe_residuals(mx), _hsfe_residuals(my)
    sx = math.sqrt(float(np.sum(dx**2)) / (w * (m - 1)))
    sy = math.sqrt(float(np.sum(dy**2)) / (w * (m - 1)))
    return HsfeEstimate(
        quantity="HSFE", method="published", equations="seed 000 eqs 3-12",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=w, n_frames=int(n.min()), n_conditions=m,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, warnings=tuple(log.messages),
        residuals=partial(_residual_table, stars, conds, dx, dy),
    )


def _clipped_sigma(tau2: float, ax: str, kind: str, flags: list, log) -> float:
    """sqrt of a variance estimate, a negative one (temporal noise dominates) set to 0 with
    flag ``clipped_<ax>`` and a warning."""
    if tau2 < 0:
        flags.append(f"clipped_{ax}")
        log.warn(f"HSFE: the {kind} variance along {ax} is negative ({tau2:.3g} px^2): "
                 "temporal noise dominates; set to 0")
        tau2 = 0.0
    return math.sqrt(tau2)


def high_spatial_frequency_error_debiased(
    table: pd.DataFrame, *, plate_scale_arcsec: float
) -> HsfeEstimate:
    """HSFE with the temporal noise and the common-motion removal accounted for.

    With ``S = sum_k sum_j delta_j(k)^2`` (eqs 5-8) and the temporal variance of each
    consecutive difference ``v_j(k) = s_j^2(k+1)/N_j(k+1) + s_j^2(k)/N_j(k)`` (each
    star's own frame-to-frame variance, ddof 1), ``E[S] = (W-1)(M-1) tau^2 +
    ((W-1)/W) sum v``, so (docs/estimators.md, HSFE)::

        tau^2 = S / ((W - 1)(M - 1)) - sum_k sum_j v_j(k) / (W (M - 1))

    estimates the variance of the common-motion-free consecutive difference without
    temporal noise, the quantity eqs 9-10 aim at. A negative estimate is set to 0 with
    flag ``clipped_x``/``clipped_y`` and a warning. Needs 2+ good frames per star and
    condition.

    Parameters
    ----------
    table, plate_scale_arcsec
        As in :func:`high_spatial_frequency_error`.

    Returns
    -------
    HsfeEstimate
        ``details`` holds the published sigma and the noise term per axis (px).
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    (_, n_bad, stars, conds, mx, my, vx, vy, n, n_excl) = _hsfe_matrices(
        table, need_frames=2, what="HSFE", log=log)
    w, m = mx.shape
    flags = []
    sig = {}
    details: dict[str, Any] = {}
    resid = {}
    for ax, mean, var in (("x", mx, vx), ("y", my, vy)):
        d = _hsfe_residuals(mean)
        resid[ax] = d
        s = float(np.sum(d**2))
        v = var / n
        noise = float(np.sum(v[:, 1:] + v[:, :-1]))
        tau2 = s / ((w - 1) * (m - 1)) - noise / (w * (m - 1))
        details[f"published_sigma_{ax}_px"] = math.sqrt(s / (w * (m - 1)))
        details[f"temporal_noise_variance_{ax}_px2"] = noise / (w * (m - 1))
        details[f"tau2_{ax}_px2"] = tau2
        sig[ax] = _clipped_sigma(tau2, ax, "debiased", flags, log)
    return HsfeEstimate(
        quantity="HSFE", method="debiased", equations="docs/estimators.md (HSFE debiased)",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=int(n.min()), n_conditions=m,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, flags=tuple(flags),
        warnings=tuple(log.messages), details=details,
        residuals=partial(_residual_table, stars, conds, resid["x"], resid["y"]),
    )


def high_spatial_frequency_error_static(
    table: pd.DataFrame, *, plate_scale_arcsec: float
) -> HsfeEstimate:
    """HSFE as the rms static, position-dependent centroid error (improved variant).

    Eqs 5-10 work on differences of consecutive conditions, whose static part is
    ``e(k+1) - e(k)``: for steps of 0.2 px the pixel-phase error of neighbouring
    positions is strongly correlated, so that difference is much smaller than the error
    itself, while the temporal noise of the two N-frame means adds ``2 sigma_TE^2 / N``
    (docs/estimators.md, HSFE). Here the per-condition means ``X_j(k)`` are centred twice:
    over stars in each condition (common motion, as eqs 7-8) and over conditions for each
    star (the target's own geometry, unknown to the lab), ``R_j(k)``. For static errors of
    variance ``tau^2`` independent between stars, ``E[sum R^2] = (W-1)(M-1) tau^2 +
    (1 - 1/W)(1 - 1/M) sum_jk v_jk`` with ``v_jk = s_jk^2 / N_jk`` the temporal variance of
    each mean, so::

        tau^2 = [sum_jk R_j(k)^2 - (1 - 1/W)(1 - 1/M) sum_jk v_jk] / ((W - 1)(M - 1))

    estimates the variance, over the positions the hexapod visited, of the static error
    (PRNU, DSNU, pixel-phase S-curve) with common motion and each star's own mean removed.
    Clipped at 0 with a flag. Needs 2+ good frames per star and condition.

    Parameters
    ----------
    table, plate_scale_arcsec
        As in :func:`high_spatial_frequency_error`.

    Returns
    -------
    HsfeEstimate
        ``residuals`` as for the published HSFE (consecutive differences, for fig. 6).
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    (_, n_bad, stars, conds, mx, my, vx, vy, n, n_excl) = _hsfe_matrices(
        table, need_frames=2, what="HSFE", log=log)
    w, m = mx.shape
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {}
    resid = {}
    for ax, mean, var in (("x", mx, vx), ("y", my, vy)):
        resid[ax] = _hsfe_residuals(mean)
        r = mean - mean.mean(axis=0, keepdims=True)
        r = r - r.mean(axis=1, keepdims=True)
        s = float(np.sum(r**2))
        noise = float(np.sum(var / n)) * (1 - 1 / w) * (1 - 1 / m)
        tau2 = (s - noise) / ((w - 1) * (m - 1))
        details[f"tau2_{ax}_px2"] = tau2
        details[f"temporal_noise_variance_{ax}_px2"] = noise / ((w - 1) * (m - 1))
        sig[ax] = _clipped_sigma(tau2, ax, "static", flags, log)
    return HsfeEstimate(
        quantity="HSFE", method="static", equations="docs/estimators.md (HSFE static)",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=int(n.min()), n_conditions=m,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, flags=tuple(flags),
        warnings=tuple(log.messages), details=details,
        residuals=partial(_residual_table, stars, conds, resid["x"], resid["y"]),
    )
