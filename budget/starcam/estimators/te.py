"""Temporal error TE: seed 000 eqs 1-2 (:func:`temporal_error`), and the pooled RMS with the
c4 discussion of docs/estimators.md (:func:`temporal_error_pooled`, :func:`c4`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from simcam.infra.errors import UserInputError

from .common import _check_plate_scale, _Log, _memo_last, _per_star_stats, _prepare, _select_condition
from .results import ErrorEstimate


@_memo_last
def _te_stats(table, *, condition, ddof, what, log):
    if ddof not in (0, 1):
        raise UserInputError(f"ddof: expected 0 or 1, got {ddof}")
    table = _select_condition(table, condition, what)
    rows, good, n_bad = _prepare(table, required=("star", "frame", "x", "y"),
                                 key=tuple(c for c in ("star", "condition", "frame") if c in table.columns),
                                 what=what, log=log)
    all_stars = set(rows["star"].tolist())
    st = _per_star_stats(good, ["star"], ddof)
    st = st.take(st["n"] >= 2)
    dropped = sorted(all_stars - set(st["star"].tolist()))
    n_excl = len(dropped)
    if n_excl:
        log.warn(f"{what}: {n_excl} star(s) with fewer than 2 good frames excluded "
                 f"(stars {dropped[:10]})")
    if len(st) == 0:
        raise UserInputError(f"{what}: no star has 2 or more good frames")
    return st, n_bad, n_excl


def temporal_error(
    table: pd.DataFrame, *, plate_scale_arcsec: float, ddof: int = 1, condition: int | None = None
) -> ErrorEstimate:
    """Temporal error TE as published (seed 000 eqs 1-2).

    ``sigma_j`` = standard deviation of star ``j``'s centroid over its N frames (the
    seed's "RMS error of each star coordinate", about the star's own mean, ``ddof``
    1 by default as in eqs 23-24), ``sigma_bar = (1/W) sum_j sigma_j`` (eq 1; the seed
    writes the sum over ``i = 1..N`` but averages the per-star values),
    ``TE = 3 sigma_bar * plate_scale`` (eq 2), per axis.

    Parameters
    ----------
    table : pandas.DataFrame
        Columns ``star``, ``frame``, ``x``, ``y`` (px), optional ``condition``, ``flag``.
    plate_scale_arcsec : float
        arcsec per px.
    ddof : {1, 0}
        Delta degrees of freedom of ``sigma_j``.
    condition : int, optional
        Condition to use when the table holds several.

    Returns
    -------
    ErrorEstimate
        ``sigma_*_px`` = ``sigma_bar`` per axis.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    st, n_bad, n_excl = _te_stats(table, condition=condition, ddof=ddof, what="TE", log=log)
    sx = float(np.sqrt(st["var_x"]).mean())
    sy = float(np.sqrt(st["var_y"]).mean())
    return ErrorEstimate(
        quantity="TE", method="published", equations="seed 000 eqs 1-2",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=len(st), n_frames=int(st["n"].min()), n_conditions=1,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad,
        warnings=tuple(log.messages), details={"ddof": ddof},
    )


def c4(n: Any) -> Any:
    """Bias factor of the sample standard deviation: ``E[s] = c4(n) sigma`` (Gaussian).

    ``c4(n) = sqrt(2 / (n - 1)) Gamma(n / 2) / Gamma((n - 1) / 2)``, with the standard
    library's log-gamma (``math.lgamma``; ``scipy.special`` would add 0.2 s to every start).
    """
    n = np.asarray(n, dtype=np.float64)
    if np.any(n < 2):
        raise UserInputError("c4: needs n >= 2")
    lg = np.vectorize(math.lgamma, otypes=[np.float64])
    return np.sqrt(2.0 / (n - 1.0)) * np.exp(lg(n / 2.0) - lg((n - 1.0) / 2.0))


def temporal_error_pooled(
    table: pd.DataFrame, *, plate_scale_arcsec: float, condition: int | None = None
) -> ErrorEstimate:
    """Temporal error as the pooled RMS ``sqrt(mean_j s_j^2)`` (docs/estimators.md, TE).

    ``s_j^2`` is star ``j``'s unbiased (ddof 1) variance; their frame-weighted mean is
    unbiased for the mean variance over stars, which is what a randomly chosen star's
    error variance is. ``details`` also gives the c4-corrected mean of the sample
    standard deviations, ``mean_j(s_j / c4(N_j))``, unbiased for ``mean_j sigma_j``.

    Parameters
    ----------
    table, plate_scale_arcsec, condition
        As in :func:`temporal_error`.

    Returns
    -------
    ErrorEstimate
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    log = _Log()
    st, n_bad, n_excl = _te_stats(table, condition=condition, ddof=1, what="TE", log=log)
    dof = st["n"] - 1.0
    sx = float(np.sqrt((dof * st["var_x"]).sum() / dof.sum()))
    sy = float(np.sqrt((dof * st["var_y"]).sum() / dof.sum()))
    c = c4(st["n"])
    details = {
        "c4_corrected_mean_sigma_x_px": float((np.sqrt(st["var_x"]) / c).mean()),
        "c4_corrected_mean_sigma_y_px": float((np.sqrt(st["var_y"]) / c).mean()),
        "mean_c4": float(np.mean(c)),
    }
    return ErrorEstimate(
        quantity="TE", method="pooled", equations="docs/estimators.md (TE pooled)",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=len(st), n_frames=int(st["n"].min()), n_conditions=1,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad,
        warnings=tuple(log.messages), details=details,
    )
