"""Error estimators of seed 000 (as published) and improved variants beside them.

All functions are pure functions of centroid tables (``docs/conventions.md``: columns
``star``, ``condition``, ``frame``, ``x``, ``y`` in mosaic px, and ``filter_nm``,
``field``, ``flag`` where they apply). The plate scale is a parameter; the counts
W (stars), N (frames), M (conditions), K (fields) come from the data.

Published (seed 000, Wang et al., Infrared and Laser Engineering 47(9) 0917002, 2018):

* :func:`temporal_error` -- TE, eqs 1-2
* :func:`high_spatial_frequency_error` -- HSFE, eqs 3-12
* :func:`chromatic_error` -- LSFE-S, eqs 13-16 (and the "/3" of section 1.4.1)
* :func:`distortion_residual_error` -- LSFE-C1, eqs 17-30
* :func:`target_marker_error` -- LSFE-C2, given (section 1.4.3)
* :func:`low_spatial_frequency_error` -- LSFE, eq 31
* :func:`single_star_error` -- RSS of TE, HSFE, LSFE (section 2.4)
* :func:`attitude_error` -- eq 32

Improved (derived in ``docs/estimators.md``):

* :func:`temporal_error_pooled` -- pooled RMS, with the c4 discussion
* :func:`high_spatial_frequency_error_debiased` -- temporal noise and common-motion
  removal accounted for
* :func:`chromatic_error_decomposed` -- uniform and radial parts kept apart
* :func:`distortion_residual_error_dof` -- fit degrees of freedom (W - 10)
* :func:`chromatic_error_population` -- a stellar population through the camera's
  spectral response instead of "/2" and "/3"
* :func:`high_spatial_frequency_error_static` -- the static error itself, not its
  consecutive differences
* :func:`distortion_calibration_residual` -- the distortion left after calibration
* :func:`distortion_remaining_displacement` -- the displacement a calibrated camera still makes

Rows with a non-zero ``flag`` or a non-finite ``x``/``y`` are excluded with an
:class:`EstimatorWarning`; stars that then lack what an estimator needs are excluded
with a warning too. Both counts are in the result. Malformed tables raise
:class:`simcam.cli_common.UserInputError` naming the column, star or condition.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import pandas as pd

from simcam.cli_common import UserInputError

__all__ = [
    "EstimatorWarning",
    "ErrorEstimate",
    "HsfeEstimate",
    "ChromaticEstimate",
    "DistortionEstimate",
    "temporal_error",
    "temporal_error_pooled",
    "c4",
    "high_spatial_frequency_error",
    "high_spatial_frequency_error_debiased",
    "high_spatial_frequency_error_static",
    "chromatic_error",
    "chromatic_error_decomposed",
    "chromatic_error_population",
    "distortion_residual_error",
    "distortion_residual_error_dof",
    "distortion_calibration_residual",
    "distortion_remaining_displacement",
    "cubic_design_matrix",
    "target_marker_error",
    "low_spatial_frequency_error",
    "single_star_error",
    "attitude_error",
]


class EstimatorWarning(UserWarning):
    """Data were excluded or a result was clipped; the result records it too."""


# ------------------------------------------------------------------------ results


def _frame_to_records(df: pd.DataFrame) -> list[dict[str, Any]]:
    return [
        {k: (v.item() if hasattr(v, "item") else v) for k, v in row.items()}
        for row in df.to_dict(orient="records")
    ]


@dataclass(frozen=True, kw_only=True)
class ErrorEstimate:
    """One error class, per axis, in px (1 sigma) and arcsec (3 sigma).

    Attributes
    ----------
    quantity : str
        ``"TE"``, ``"HSFE"``, ``"LSFE-S"``, ``"LSFE-C1"``.
    method : str
        ``"published"`` or the name of the improved variant.
    equations : str
        Seed equations (or document section) implemented.
    sigma_x_px, sigma_y_px : float
        1-sigma value per axis (px).
    plate_scale_arcsec : float
        arcsec per px used for the arcsec values.
    n_stars, n_frames, n_conditions : int
        W, N (smallest number of good frames of a star in a condition) and M (or K,
        the number of fields, for LSFE-S) actually used.
    n_stars_excluded, n_rows_excluded : int
        Stars and table rows left out (flagged, non-finite, incomplete).
    flags : tuple of str
        Conditions on the result, e.g. ``"clipped_x"`` (a variance estimate was
        negative and the result set to 0).
    warnings : tuple of str
        The texts of the warnings issued.
    details : dict
        Intermediate scalars (named with units).
    """

    quantity: str
    method: str
    equations: str
    sigma_x_px: float
    sigma_y_px: float
    plate_scale_arcsec: float
    n_stars: int
    n_frames: int
    n_conditions: int
    n_stars_excluded: int = 0
    n_rows_excluded: int = 0
    flags: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    details: dict[str, Any] = field(default_factory=dict)

    @property
    def x_3sigma_arcsec(self) -> float:
        """``3 sigma_x_px * plate_scale_arcsec``."""
        return 3.0 * self.sigma_x_px * self.plate_scale_arcsec

    @property
    def y_3sigma_arcsec(self) -> float:
        """``3 sigma_y_px * plate_scale_arcsec``."""
        return 3.0 * self.sigma_y_px * self.plate_scale_arcsec

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (tables as lists of records)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, pd.DataFrame):
                v = _frame_to_records(v)
            elif isinstance(v, tuple):
                v = list(v)
            elif isinstance(v, dict):
                v = {k: (w.item() if hasattr(w, "item") else w) for k, w in v.items()}
            elif hasattr(v, "item"):
                v = v.item()
            out[f.name] = v
        out["x_3sigma_arcsec"] = self.x_3sigma_arcsec
        out["y_3sigma_arcsec"] = self.y_3sigma_arcsec
        return out


@dataclass(frozen=True, kw_only=True)
class HsfeEstimate(ErrorEstimate):
    """HSFE result with the residual table ``delta_j(k)`` (seed fig. 6).

    ``residuals`` columns: ``star``, ``k`` (1..M-1), ``condition_from``,
    ``condition_to``, ``delta_x_px``, ``delta_y_px``.
    """

    residuals: pd.DataFrame = field(default_factory=pd.DataFrame)


@dataclass(frozen=True, kw_only=True)
class ChromaticEstimate(ErrorEstimate):
    """LSFE-S result with one row per filter pair in ``pairs``."""

    pairs: pd.DataFrame = field(default_factory=pd.DataFrame)


@dataclass(frozen=True, kw_only=True)
class DistortionEstimate(ErrorEstimate):
    """LSFE-C1 result with the per-point residual vectors (seed fig. 8).

    ``residuals`` columns: ``star``, ``x_ref``, ``y_ref``, ``dx_px``, ``dy_px`` (eqs
    19-20), ``fit_x_px``, ``fit_y_px`` (cubic fit), ``ddx_px``, ``ddy_px`` (eqs 25-26).
    """

    residuals: pd.DataFrame = field(default_factory=pd.DataFrame)



# ------------------------------------------------------------------- table input


class _Log:
    """Collects warnings, issues them as EstimatorWarning and keeps their text."""

    def __init__(self) -> None:
        self.messages: list[str] = []

    def warn(self, message: str) -> None:
        self.messages.append(message)
        warnings.warn(message, EstimatorWarning, stacklevel=4)


def _check_plate_scale(plate_scale_arcsec: float) -> float:
    try:
        ps = float(plate_scale_arcsec)
    except (TypeError, ValueError):
        raise UserInputError(f"plate_scale_arcsec: not a number: {plate_scale_arcsec!r}") from None
    if not (math.isfinite(ps) and ps > 0):
        raise UserInputError(f"plate_scale_arcsec: must be finite and > 0, got {plate_scale_arcsec}")
    return ps


def _prepare(
    table: Any, *, required: tuple[str, ...], key: tuple[str, ...], what: str, log: _Log
) -> tuple[pd.DataFrame, int]:
    """Validate columns, drop flagged / non-finite rows; return (good rows, n excluded)."""
    if not isinstance(table, pd.DataFrame):
        raise UserInputError(f"{what}: expected a pandas DataFrame, got {type(table).__name__}")
    missing = [c for c in required if c not in table.columns]
    if missing:
        raise UserInputError(f"{what}: missing column(s) {', '.join(missing)}")
    if table.empty:
        raise UserInputError(f"{what}: the table has no rows")
    for c in ("x", "y"):
        if not pd.api.types.is_numeric_dtype(table[c]):
            raise UserInputError(f"{what}: column {c!r} is not numeric (dtype {table[c].dtype})")
    for c in key:
        if c in ("field",):
            if table[c].isna().any():
                raise UserInputError(f"{what}: column {c!r} has missing values")
            continue
        col = table[c]
        if not pd.api.types.is_numeric_dtype(col) or col.isna().any():
            raise UserInputError(f"{what}: column {c!r} must hold integers without gaps")
        if not np.all(np.asarray(col, dtype=np.float64) == np.round(np.asarray(col, dtype=np.float64))):
            raise UserInputError(f"{what}: column {c!r} must hold integers")
    if _has_duplicate_keys(table, key):
        dup = table.duplicated(subset=list(key), keep=False)
        first = table.loc[dup, list(key)].iloc[0].to_dict()
        raise UserInputError(
            f"{what}: {int(dup.sum())} rows repeat the same ({', '.join(key)}), e.g. {first}"
        )
    bad = ~(np.isfinite(table["x"].to_numpy(float)) & np.isfinite(table["y"].to_numpy(float)))
    if "flag" in table.columns:
        fl = table["flag"]
        if not pd.api.types.is_integer_dtype(fl):
            raise UserInputError(f"{what}: column 'flag' must hold integers (dtype {fl.dtype})")
        bad |= fl.to_numpy() != 0
    n_bad = int(bad.sum())
    if n_bad:
        stars = sorted(set(table.loc[bad, "star"].tolist()))
        shown = ", ".join(str(s) for s in stars[:10]) + (" ..." if len(stars) > 10 else "")
        log.warn(f"{what}: {n_bad} row(s) flagged or with non-finite x/y excluded (stars {shown})")
    # the estimators only read the good rows: the table itself when none is excluded
    good = table.loc[~bad] if n_bad else table
    if good.empty:
        raise UserInputError(f"{what}: no good rows left after excluding flagged/non-finite rows")
    return good, n_bad


def _stars_per_field(wide: pd.DataFrame) -> np.ndarray:
    """Number of rows (stars) of each field of a table indexed by (field, star)."""
    codes, _ = pd.factorize(wide.index.get_level_values("field"))
    return np.bincount(codes)


def _key_codes(table: pd.DataFrame, key: tuple[str, ...]) -> np.ndarray:
    """One integer per row, equal for two rows exactly when all ``key`` columns are equal
    (each column factorised; the codes combined in mixed radix, re-factorised if the
    radix product would overflow)."""
    codes = np.zeros(len(table), dtype=np.int64)
    size = 1
    for c in key:
        col_codes, uniques = pd.factorize(table[c], use_na_sentinel=False)
        if size * max(len(uniques), 1) >= 2**62:
            codes = pd.factorize(codes)[0]
            size = int(codes.max()) + 1
        codes = codes * len(uniques) + col_codes
        size *= max(len(uniques), 1)
    return codes


def _has_duplicate_keys(table: pd.DataFrame, key: tuple[str, ...]) -> bool:
    """Whether two rows share the same values of every ``key`` column."""
    if not key or len(table) < 2:
        return False
    s = np.sort(_key_codes(table, key))
    return bool(np.any(s[1:] == s[:-1]))


def _select_condition(df: Any, condition: int | None, what: str) -> pd.DataFrame:
    """The rows of one static condition (all rows when the table holds only one)."""
    if not isinstance(df, pd.DataFrame):
        raise UserInputError(f"{what}: expected a pandas DataFrame, got {type(df).__name__}")
    if condition is not None:
        if "condition" not in df.columns:
            raise UserInputError(f"{what}: condition={condition} given but the table has no 'condition' column")
        sel = df[df["condition"] == condition]
        if sel.empty:
            raise UserInputError(f"{what}: no rows with condition={condition}")
        return sel
    if "condition" in df.columns and df["condition"].nunique() > 1:
        values = sorted(df["condition"].unique().tolist())
        raise UserInputError(
            f"{what}: the table holds conditions {values}; this estimator uses one static "
            "condition: pass condition=..."
        )
    return df


def _per_star_stats(df: pd.DataFrame, by: list[str], ddof: int) -> pd.DataFrame:
    """Per group of the ``by`` columns (sorted, as ``groupby(by, sort=True)``): count ``n``,
    means and variances (``ddof``; NaN when ``n <= ddof``) of x and y.

    Integer codes and ``numpy.bincount`` instead of a pandas groupby (the estimators run
    in every Monte Carlo trial); the variance is the two-pass sum of squared deviations
    from the group mean, so no precision is lost to cancellation.
    """
    n_rows = len(df)
    codes = np.zeros(n_rows, dtype=np.int64)
    uniques = []
    for c in by:
        u, inv = np.unique(df[c].to_numpy(), return_inverse=True)
        codes = codes * len(u) + inv.reshape(-1)
        uniques.append(u)
    groups, inv = np.unique(codes, return_inverse=True)
    inv = inv.reshape(-1)
    n = np.bincount(inv, minlength=groups.size)
    out = {}
    rem = groups.copy()
    for c, u in reversed(list(zip(by, uniques))):
        out[c] = u[rem % len(u)]
        rem //= len(u)
    out = {c: out[c] for c in by}
    out["n"] = n
    means, variances = {}, {}
    for ax in ("x", "y"):
        v = df[ax].to_numpy(np.float64)
        m = np.bincount(inv, weights=v, minlength=groups.size) / n
        ss = np.bincount(inv, weights=(v - m[inv]) ** 2, minlength=groups.size)
        with np.errstate(invalid="ignore", divide="ignore"):
            var = np.where(n > ddof, ss / np.maximum(n - ddof, 1), np.nan)
        means[f"mean_{ax}"], variances[f"var_{ax}"] = m, var
    out.update(means)
    out.update(variances)
    return pd.DataFrame(out)


# -------------------------------------------------------------------------- TE


def _memo_last(fn):
    """Remember the last call's result for the same table object and arguments.

    The published estimator and its improved variant start from the same per-star
    statistics of the same centroid table; this computes them once. The key holds the
    table itself (compared by identity, so the object stays alive and cannot be
    confused with another), and the warnings the first call logged are replayed into
    the later call's log, so results and warnings are exactly those of a fresh call.
    Callers treat the returned frames as read-only.
    """
    last: dict = {}

    def wrapper(table, *args, log, **kwargs):
        key = (args, tuple(sorted(kwargs.items(), key=lambda kv: kv[0])))
        hit = last.get("entry")
        if hit is not None and hit[0] is table and _same_key(hit[1], key):
            for message in hit[3]:
                log.warn(message)
            return hit[2]
        n0 = len(log.messages)
        out = fn(table, *args, log=log, **kwargs)
        last["entry"] = (table, key, out, tuple(log.messages[n0:]))
        return out

    wrapper.__doc__ = fn.__doc__
    wrapper.__name__ = fn.__name__
    return wrapper


def _same_key(a, b) -> bool:
    try:
        return bool(a == b)
    except (ValueError, TypeError):  # e.g. DataFrames among the arguments
        return len(a) == len(b) and all(_same_arg(x, y) for x, y in zip(a, b))


def _same_arg(x, y) -> bool:
    if isinstance(x, tuple) and isinstance(y, tuple):
        return len(x) == len(y) and all(_same_arg(p, q) for p, q in zip(x, y))
    if isinstance(x, pd.DataFrame) or isinstance(y, pd.DataFrame):
        return x is y
    try:
        return bool(x == y)
    except (ValueError, TypeError):
        return x is y



@_memo_last
def _te_stats(table, *, condition, ddof, what, log):
    if ddof not in (0, 1):
        raise UserInputError(f"ddof: expected 0 or 1, got {ddof}")
    table = _select_condition(table, condition, what)
    df, n_bad = _prepare(table, required=("star", "frame", "x", "y"),
                         key=tuple(c for c in ("star", "condition", "frame") if c in table.columns),
                         what=what, log=log)
    all_stars = set(table["star"].tolist())
    st = _per_star_stats(df, ["star"], ddof)
    few = st["n"] < 2
    st = st.loc[~few]
    dropped = sorted(all_stars - set(st["star"].tolist()))
    n_excl = len(dropped)
    if n_excl:
        log.warn(f"{what}: {n_excl} star(s) with fewer than 2 good frames excluded "
                 f"(stars {dropped[:10]})")
    if st.empty:
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
    c = c4(st["n"].to_numpy())
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


# ------------------------------------------------------------------------ HSFE


@_memo_last
def _hsfe_stats(table, *, what: str, log: _Log):
    """Good rows and per-(star, condition) statistics of an HSFE table (shared by variants)."""
    df, n_bad = _prepare(table, required=("star", "condition", "frame", "x", "y"),
                         key=("star", "condition", "frame"), what=what, log=log)
    return df, n_bad, _per_star_stats(df, ["star", "condition"], 1)


def _hsfe_matrices(table, *, need_frames: int, what: str, log: _Log):
    df, n_bad, st = _hsfe_stats(table, what=what, log=log)
    conditions = np.sort(df["condition"].unique())
    m = conditions.size
    if m < 2:
        raise UserInputError(f"{what}: needs at least 2 conditions, got {m} ({conditions.tolist()})")
    # st has one row per (star, condition), sorted by (star, condition)
    st_star = st["star"].to_numpy()
    keep = st["n"].to_numpy() >= need_frames
    kept_stars, n_conditions = np.unique(st_star[keep], return_counts=True)
    all_stars = np.unique(table["star"].to_numpy())
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
        return st[col].to_numpy(float)[sel].reshape(w, m)

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
        residuals=_residual_table(stars, conds, dx, dy),
    )


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
        if tau2 < 0:
            flags.append(f"clipped_{ax}")
            log.warn(f"HSFE: the debiased variance along {ax} is negative ({tau2:.3g} px^2): "
                     "temporal noise dominates; set to 0")
            tau2 = 0.0
        sig[ax] = math.sqrt(tau2)
    return HsfeEstimate(
        quantity="HSFE", method="debiased", equations="docs/estimators.md (HSFE debiased)",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=int(n.min()), n_conditions=m,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, flags=tuple(flags),
        warnings=tuple(log.messages), details=details,
        residuals=_residual_table(stars, conds, resid["x"], resid["y"]),
    )


# ------------------------------------------------------------------- chromatic


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
        if tau2 < 0:
            flags.append(f"clipped_{ax}")
            log.warn(f"HSFE: the static variance along {ax} is negative ({tau2:.3g} px^2): "
                     "temporal noise dominates; set to 0")
            tau2 = 0.0
        sig[ax] = math.sqrt(tau2)
    return HsfeEstimate(
        quantity="HSFE", method="static", equations="docs/estimators.md (HSFE static)",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=int(n.min()), n_conditions=m,
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, flags=tuple(flags),
        warnings=tuple(log.messages), details=details,
        residuals=_residual_table(stars, conds, resid["x"], resid["y"]),
    )


@_memo_last
def _chromatic_means(table, *, reference_filter_nm, what, log):
    if not isinstance(table, pd.DataFrame):
        raise UserInputError(f"{what}: expected a pandas DataFrame, got {type(table).__name__}")
    df, n_bad = _prepare(table, required=("star", "field", "filter_nm", "x", "y"),
                         key=tuple(c for c in ("star", "field", "filter_nm", "condition", "frame")
                                   if c in table.columns), what=what, log=log)
    filters = np.sort(df["filter_nm"].unique())
    if filters.size < 2:
        raise UserInputError(f"{what}: needs at least 2 filters in column 'filter_nm', got {filters.tolist()}")
    if reference_filter_nm is None:
        ref = int(filters[(filters.size - 1) // 2])
    else:
        ref = int(reference_filter_nm)
        if ref not in filters:
            raise UserInputError(f"{what}: reference_filter_nm={ref} is not in the data's filters {filters.tolist()}")
    # per (field, star) and filter: mean x, y and count, by bincount on integer codes
    # (every (field, star) pair of the table is kept, sorted, NaN where a filter is missing)
    f_codes, f_uni = pd.factorize(table["field"], sort=True)
    s_uni, s_codes = np.unique(table["star"].to_numpy(), return_inverse=True)
    n_s = len(s_uni)
    present = np.unique(f_codes * n_s + s_codes.reshape(-1))        # sorted by (field, star)
    pairs_index = pd.MultiIndex.from_arrays([np.asarray(f_uni)[present // n_s], s_uni[present % n_s]],
                                            names=["field", "star"])
    row = np.searchsorted(present, pd.Index(f_uni).get_indexer(df["field"]) * n_s
                          + np.searchsorted(s_uni, df["star"].to_numpy()))
    col = np.searchsorted(filters, df["filter_nm"].to_numpy())
    cell = row * filters.size + col
    size = len(pairs_index) * filters.size
    count = np.bincount(cell, minlength=size).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = np.bincount(cell, weights=df["x"].to_numpy(np.float64), minlength=size) / count
        my = np.bincount(cell, weights=df["y"].to_numpy(np.float64), minlength=size) / count
    count[count == 0] = np.nan
    mx, my, count = (a.reshape(len(pairs_index), filters.size) for a in (mx, my, count))
    complete = np.isfinite(count).all(axis=1)
    n_excl = int((~complete).sum())
    if n_excl:
        lost = [f"{f}/{s}" for f, s in pairs_index[~complete][:10]]
        log.warn(f"{what}: {n_excl} (field, star) pair(s) lack a filter and are excluded ({', '.join(lost)})")
    columns = pd.Index(filters, name="filter_nm")
    index = pairs_index[complete] if n_excl else pairs_index
    wide_x, wide_y, wide_n = (pd.DataFrame(a[complete] if n_excl else a, index=index, columns=columns)
                              for a in (mx, my, count))
    if wide_x.empty:
        raise UserInputError(f"{what}: no (field, star) seen through every filter")
    pairs = []
    for f in filters:
        if f == ref:
            continue
        lo, hi = (int(f), ref) if f < ref else (ref, int(f))
        pairs.append((lo, hi))
    return df, n_bad, n_excl, filters, ref, pairs, wide_x, wide_y, wide_n


def chromatic_error(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    reference_filter_nm: int | None = None,
    spectrum_factor: float = 3.0,
) -> ChromaticEstimate:
    """Chromatic low-frequency error LSFE-S as published (seed 000 eqs 13-16).

    Per field ``k`` and filter, per-star means (eqs 13-14). Each filter is paired with
    the reference filter, longer minus shorter wavelength: ``delta_j(600-500) =
    Xbar_600 - Xbar_500``, ``delta_j(800-600) = Xbar_800 - Xbar_600`` (eq 15). Then
    ``delta_bar = sum_k sum_j delta_j / (2 W K)`` (eq 16; ``W K`` = the number of
    (field, star) pairs seen through every filter, K = 4 in the seed). The seed's text:
    the largest ``|delta_bar|`` "divided by 3" approximates the chromatic error of a
    star: ``sigma_LSFE-S = max_pairs |delta_bar| / spectrum_factor`` (px), reported as
    ``3 sigma * plate_scale`` arcsec like every other class. See docs/estimators.md
    for how this reproduces (and does not reproduce) the seed's table 1 and section 2.3.1.

    Parameters
    ----------
    table : pandas.DataFrame
        Columns ``star``, ``field``, ``filter_nm``, ``x``, ``y`` (px), optional
        ``frame``, ``flag``.
    plate_scale_arcsec : float
    reference_filter_nm : int, optional
        Default: the middle filter (the lower middle for an even count).
    spectrum_factor : float
        The seed's 3 (filter band versus stellar spectrum).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` columns: ``pair``, ``filter_short_nm``, ``filter_long_nm``,
        ``delta_bar_x_px``, ``delta_bar_y_px``, ``delta_bar_x_arcsec``,
        ``delta_bar_y_arcsec``.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    if not spectrum_factor > 0:
        raise UserInputError(f"spectrum_factor: must be > 0, got {spectrum_factor}")
    log = _Log()
    (_, n_bad, n_excl, filters, ref, pairs, wx, wy, wn) = _chromatic_means(
        table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    n_pts = len(wx)                                   # W * K
    k = wx.index.get_level_values("field").nunique()
    rows = []
    col = {f: i for i, f in enumerate(wx.columns)}
    ax, ay = wx.to_numpy(), wy.to_numpy()
    for lo, hi in pairs:
        dxb = float((ax[:, col[hi]] - ax[:, col[lo]]).sum()) / (2.0 * n_pts)
        dyb = float((ay[:, col[hi]] - ay[:, col[lo]]).sum()) / (2.0 * n_pts)
        rows.append({"pair": f"{hi}-{lo}", "filter_short_nm": lo, "filter_long_nm": hi,
                     "delta_bar_x_px": dxb, "delta_bar_y_px": dyb,
                     "delta_bar_x_arcsec": dxb * ps, "delta_bar_y_arcsec": dyb * ps})
    pt = pd.DataFrame(rows)
    mx = float(pt["delta_bar_x_px"].abs().max())
    my = float(pt["delta_bar_y_px"].abs().max())
    per_field = _stars_per_field(wx)
    return ChromaticEstimate(
        quantity="LSFE-S", method="published", equations="seed 000 eqs 13-16, section 1.4.1",
        sigma_x_px=mx / spectrum_factor, sigma_y_px=my / spectrum_factor, plate_scale_arcsec=ps,
        n_stars=int(per_field.min()), n_frames=int(wn.min().min()), n_conditions=int(k),
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, warnings=tuple(log.messages),
        details={"max_abs_delta_bar_x_px": mx, "max_abs_delta_bar_y_px": my,
                 "max_abs_delta_bar_x_arcsec": mx * ps, "max_abs_delta_bar_y_arcsec": my * ps,
                 "max_over_factor_x_px": mx / spectrum_factor,
                 "max_over_factor_y_px": my / spectrum_factor,
                 "max_over_factor_x_arcsec": mx / spectrum_factor * ps,
                 "max_over_factor_y_arcsec": my / spectrum_factor * ps,
                 "reference_filter_nm": ref, "n_filters": int(filters.size),
                 "n_fields": int(k), "n_field_star_pairs": int(n_pts),
                 "spectrum_factor": float(spectrum_factor)},
        pairs=pt,
    )


def chromatic_error_decomposed(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    reference_filter_nm: int | None = None,
    spectrum_factor: float = 3.0,
    optical_axis_xy: tuple[float, float] | None = None,
) -> ChromaticEstimate:
    """Chromatic error with the uniform and radial (lateral-colour) parts kept apart.

    For each filter pair the signed per-star differences ``d_j`` (eq 15, all fields)
    are fitted by least squares with ``d_j = u + c r_j``, ``r_j`` the star's position
    (reference filter) relative to the optical axis: ``u`` is the field-uniform shift
    (what eq 16 averages), ``c r_j`` the radial lateral colour (linear in field radius),
    which averages to zero over fields placed symmetrically about the axis and so
    escapes eq 16 (docs/estimators.md, chromatic). The error of a star is the rms over
    the measured positions of ``u + c r_j`` per axis; as in the seed it is halved
    (shift from the midpoint of the band pair) and divided by ``spectrum_factor``;
    ``sigma`` is the largest over the pairs.

    Parameters
    ----------
    table, plate_scale_arcsec, reference_filter_nm, spectrum_factor
        As in :func:`chromatic_error`.
    optical_axis_xy : (float, float), optional
        Optical axis on the mosaic (px); default: the mean position of all measured
        stars (the centre of symmetrically placed fields).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` columns: ``pair``, ``filter_short_nm``, ``filter_long_nm``,
        ``uniform_x_px``, ``uniform_y_px``, ``radial_coefficient`` (px per px of field
        radius), ``radial_shift_at_mean_radius_px``, ``fit_residual_rms_px``,
        ``rms_x_px``, ``rms_y_px``.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    if not spectrum_factor > 0:
        raise UserInputError(f"spectrum_factor: must be > 0, got {spectrum_factor}")
    log = _Log()
    (_, n_bad, n_excl, filters, ref, pairs, wx, wy, wn) = _chromatic_means(
        table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    n_pts = len(wx)
    if n_pts < 3:
        raise UserInputError(f"LSFE-S: the decomposition needs 3+ (field, star) points, got {n_pts}")
    px = wx[ref].to_numpy(float)
    py = wy[ref].to_numpy(float)
    if optical_axis_xy is None:
        ax0, ay0 = float(px.mean()), float(py.mean())
    else:
        ax0, ay0 = (float(v) for v in optical_axis_xy)
    rx, ry = px - ax0, py - ay0
    rmean = float(np.mean(np.hypot(rx, ry)))
    if not rmean > 0:
        raise UserInputError("LSFE-S: all stars sit on the optical axis; no radial part to fit")
    # stacked system [dx; dy] = [[1, 0, rx], [0, 1, ry]] @ (ux, uy, c)
    a = np.zeros((2 * n_pts, 3))
    a[:n_pts, 0] = 1.0
    a[n_pts:, 1] = 1.0
    a[:n_pts, 2] = rx
    a[n_pts:, 2] = ry
    rows = []
    for lo, hi in pairs:
        dx = (wx[hi] - wx[lo]).to_numpy(float)
        dy = (wy[hi] - wy[lo]).to_numpy(float)
        b = np.concatenate([dx, dy])
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        ux, uy, c = (float(v) for v in coef)
        res = b - a @ coef
        mod_x, mod_y = ux + c * rx, uy + c * ry
        rows.append({"pair": f"{hi}-{lo}", "filter_short_nm": lo, "filter_long_nm": hi,
                     "uniform_x_px": ux, "uniform_y_px": uy, "radial_coefficient": c,
                     "radial_shift_at_mean_radius_px": c * rmean,
                     "fit_residual_rms_px": float(np.sqrt(np.mean(res**2))),
                     "rms_x_px": float(np.sqrt(np.mean(mod_x**2))),
                     "rms_y_px": float(np.sqrt(np.mean(mod_y**2)))})
    pt = pd.DataFrame(rows)
    sx = float(pt["rms_x_px"].max()) / (2.0 * spectrum_factor)
    sy = float(pt["rms_y_px"].max()) / (2.0 * spectrum_factor)
    k = wx.index.get_level_values("field").nunique()
    per_field = _stars_per_field(wx)
    return ChromaticEstimate(
        quantity="LSFE-S", method="decomposed", equations="docs/estimators.md (chromatic decomposed)",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=int(per_field.min()), n_frames=int(wn.min().min()), n_conditions=int(k),
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, warnings=tuple(log.messages),
        details={"reference_filter_nm": ref, "optical_axis_x_px": ax0, "optical_axis_y_px": ay0,
                 "mean_field_radius_px": rmean, "n_fields": int(k),
                 "spectrum_factor": float(spectrum_factor)},
        pairs=pt,
    )


# ------------------------------------------------------------------ distortion


def chromatic_error_population(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    filter_wavelength_nm: dict,
    star_wavelengths_nm: Any,
    calibration_wavelength_nm: float,
    reference_filter_nm: int | None = None,
) -> ChromaticEstimate:
    """LSFE-S for a stellar population, from the filter measurements (improved variant).

    The centroid of a polychromatic image moves by the spectrum-weighted mean of the
    per-wavelength lateral shifts; for lateral colour linear in wavelength that is the
    shift at the image's electron-weighted mean wavelength ``lambda_bar``. So each
    (field, star)'s filter means are fitted with ``X = a + b lambda_bar_f`` (least
    squares over the filters, ``lambda_bar_f`` the effective wavelength of the lamp
    through filter ``f``, optics and QE), the slopes are averaged per field (``b_F``,
    its mean square debiased by the slopes' sampling variance over the field's ``W``
    stars), and a star of effective wavelength ``lambda_p`` is displaced from the
    calibration spectrum's position by ``b_F (lambda_p - lambda_cal)``. The error is the
    rms over the population and the fields, per axis (docs/estimators.md, chromatic
    population). It replaces
    the seed's "/2" and "/3" by the camera's own spectral response: the effective
    wavelengths are design data (filters, lamp, optics transmission, QE, stellar types).

    Parameters
    ----------
    table : pandas.DataFrame
        As for :func:`chromatic_error`.
    plate_scale_arcsec : float
    filter_wavelength_nm : dict
        Filter centre (as in ``filter_nm``) -> effective wavelength of the lamp through it, nm.
    star_wavelengths_nm : array_like
        Effective wavelengths of the stellar population (one per star type), nm.
    calibration_wavelength_nm : float
        Effective wavelength of the calibration spectrum (e.g. the unfiltered lamp), nm.
    reference_filter_nm : int, optional
        As in :func:`chromatic_error` (only checked here; every filter enters the fit).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` holds one row per (field, star): slopes ``b_x``, ``b_y`` in px/nm.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    lam_p = np.asarray(star_wavelengths_nm, dtype=float).ravel()
    if lam_p.size == 0 or not np.isfinite(lam_p).all():
        raise UserInputError("star_wavelengths_nm: needs one or more finite wavelengths")
    log = _Log()
    (_, n_bad, n_excl, filters, ref, _pairs, wx, wy, wn) = _chromatic_means(
        table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    missing = [int(f) for f in filters if int(f) not in {int(k) for k in filter_wavelength_nm}]
    if missing:
        raise UserInputError(f"filter_wavelength_nm: no effective wavelength for filter(s) {missing}")
    lam_f = np.array([float({int(k): v for k, v in filter_wavelength_nm.items()}[int(f)]) for f in filters])
    a = np.column_stack([np.ones_like(lam_f), lam_f - lam_f.mean()])
    pinv = np.linalg.pinv(a)
    bx = (pinv @ wx[list(filters)].to_numpy(float).T)[1]
    by = (pinv @ wy[list(filters)].to_numpy(float).T)[1]
    dl = lam_p - float(calibration_wavelength_nm)
    per = pd.DataFrame({"field": wx.index.get_level_values("field"), "star": wx.index.get_level_values("star"),
                        "b_x_px_per_nm": bx, "b_y_px_per_nm": by})
    # Per field, the slope is averaged over its stars (lateral colour varies little across
    # one target); the mean square of that average is debiased by its sampling variance
    # s_b^2 / W (temporal noise in the filter means), clipped at 0.
    fcode, _ = pd.factorize(per["field"])
    cnt = np.bincount(fcode).astype(float)
    msq = {}
    for ax, b in (("x", bx), ("y", by)):
        mean_b = np.bincount(fcode, weights=b) / cnt
        ss = np.bincount(fcode, weights=(b - mean_b[fcode]) ** 2)
        var_b = np.where(cnt > 1, ss / np.maximum(cnt - 1.0, 1.0), 0.0) / cnt   # s_b^2 / W (0 for W = 1)
        msq[ax] = np.clip(mean_b**2 - var_b, 0.0, None)
    sx = float(np.sqrt(np.mean(msq["x"]) * np.mean(dl**2)))
    sy = float(np.sqrt(np.mean(msq["y"]) * np.mean(dl**2)))
    k = wx.index.get_level_values("field").nunique()
    return ChromaticEstimate(
        quantity="LSFE-S", method="population", equations="docs/estimators.md (chromatic population)",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=int(_stars_per_field(wx).min()), n_frames=int(wn.min().min()), n_conditions=int(k),
        n_stars_excluded=n_excl, n_rows_excluded=n_bad, warnings=tuple(log.messages),
        details={"calibration_wavelength_nm": float(calibration_wavelength_nm),
                 "population_wavelengths_nm": lam_p.tolist(),
                 "filter_effective_wavelengths_nm": lam_f.tolist(),
                 "mean_slope_x_px_per_nm": float(bx.mean()), "mean_slope_y_px_per_nm": float(by.mean())},
        pairs=per,
    )


def cubic_design_matrix(u: Any, v: Any) -> np.ndarray:
    """Full bivariate cubic basis (10 terms): 1, u, v, u^2, uv, v^2, u^3, u^2 v, u v^2, v^3."""
    u = np.asarray(u, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    return np.column_stack([np.ones_like(u), u, v, u * u, u * v, v * v,
                            u**3, u * u * v, u * v * v, v**3])


@_memo_last
def _distortion_core(table, reference, *, condition, what, log):
    table = _select_condition(table, condition, what)
    df, n_bad = _prepare(table, required=("star", "frame", "x", "y"),
                         key=tuple(c for c in ("star", "condition", "frame") if c in table.columns),
                         what=what, log=log)
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
    st = _per_star_stats(df, ["star"], 1)                     # eqs 17-18
    unknown = sorted(set(st["star"]) - set(reference["star"]))
    if unknown:
        raise UserInputError(f"{what}: star(s) {unknown[:10]} have no reference coordinates")
    lost = sorted(set(reference["star"]) - set(st["star"]))
    if lost:
        log.warn(f"{what}: {len(lost)} reference point(s) without a good centroid excluded "
                 f"(stars {lost[:10]})")
    # st is sorted by star and every star of st has its reference (checked above)
    m = st
    _need_points(len(m), 10, what)
    ref_star = reference["star"].to_numpy()
    order = np.argsort(ref_star, kind="stable")
    ri = order[np.searchsorted(ref_star[order], m["star"].to_numpy())]
    x0, y0 = reference["x_ref"].to_numpy(float)[ri], reference["y_ref"].to_numpy(float)[ri]
    dx = m["mean_x"].to_numpy(float) - x0                     # eq 19
    dy = m["mean_y"].to_numpy(float) - y0                     # eq 20
    # normalised coordinates for conditioning: centre and half range
    cu, cv = x0.mean(), y0.mean()
    su = max(np.max(np.abs(x0 - cu)), 1e-300)
    sv = max(np.max(np.abs(y0 - cv)), 1e-300)
    a = cubic_design_matrix((x0 - cu) / su, (y0 - cv) / sv)
    if np.linalg.matrix_rank(a) < 10:
        raise UserInputError(f"{what}: the reference points do not determine a full cubic "
                             "(collinear or too regular layout)")
    cx, *_ = np.linalg.lstsq(a, dx, rcond=None)
    cy, *_ = np.linalg.lstsq(a, dy, rcond=None)
    fx, fy = a @ cx, a @ cy
    resid = pd.DataFrame({"star": m["star"].to_numpy(), "x_ref": x0, "y_ref": y0,
                          "dx_px": dx, "dy_px": dy, "fit_x_px": fx, "fit_y_px": fy,
                          "ddx_px": dx - fx, "ddy_px": dy - fy,  # eqs 25-26
                          # temporal variance of each point's N-frame mean
                          "var_mean_x_px2": (m["var_x"] / m["n"]).to_numpy(float),
                          "var_mean_y_px2": (m["var_y"] / m["n"]).to_numpy(float)})
    return resid, n_bad, len(lost), int(m["n"].min())


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
    what = "LSFE-C1"
    resid, n_bad, n_excl, n_min = _distortion_core(table, reference, condition=condition,
                                                   what=what, log=log)
    w = len(resid)
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {}
    for ax in ("x", "y"):
        d = resid[f"d{ax}_px"].to_numpy()
        dd = resid[f"dd{ax}_px"].to_numpy()
        sd = float(np.std(d, ddof=1))                  # eqs 23-24
        sdd = float(np.std(dd, ddof=1))                # eqs 27-28
        details[f"mean_d{ax}_px"] = float(d.mean())
        details[f"sigma_d{ax}_px"] = sd
        details[f"sigma_dd{ax}_px"] = sdd
        sig[ax] = _root_of_difference(sd**2, sdd**2, ax, flags, log, what)   # eqs 29-30
    return DistortionEstimate(
        quantity="LSFE-C1", method="published", equations="seed 000 eqs 17-30",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=n_min, n_conditions=1, n_stars_excluded=n_excl,
        n_rows_excluded=n_bad, flags=tuple(flags), warnings=tuple(log.messages),
        details=details, residuals=resid,
    )


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
    what = "LSFE-C1"
    resid, n_bad, n_excl, n_min = _distortion_core(table, reference, condition=condition,
                                                   what=what, log=log)
    w = len(resid)
    _need_points(w, 11, what)
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {}
    for ax in ("x", "y"):
        d = resid[f"d{ax}_px"].to_numpy()
        dd = resid[f"dd{ax}_px"].to_numpy()
        sd2 = float(np.var(d, ddof=1))
        sres2 = float(np.sum(dd**2)) / (w - 10)
        details[f"sigma_d{ax}_px"] = math.sqrt(sd2)
        details[f"sigma_fit_residual_{ax}_px"] = math.sqrt(sres2)
        sig[ax] = _root_of_difference(sd2, sres2, ax, flags, log, what)
    return DistortionEstimate(
        quantity="LSFE-C1", method="fit-dof", equations="docs/estimators.md (distortion, W-10)",
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=n_min, n_conditions=1, n_stars_excluded=n_excl,
        n_rows_excluded=n_bad, flags=tuple(flags), warnings=tuple(log.messages),
        details=details, residuals=resid,
    )


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
    def fit_residual_variance(resid, ax):
        dd = resid[f"dd{ax}_px"].to_numpy()
        return f"sigma_fit_residual_{ax}_px", float(np.sum(dd**2)) / (len(dd) - 10)

    return _c1_minus_known_noise(table, reference, plate_scale_arcsec, marker_3sigma_arcsec, condition,
                                 fit_residual_variance, min_points=11, method="after-calibration",
                                 equations="docs/estimators.md (distortion left after calibration)")


def _c1_minus_known_noise(table, reference, plate_scale_arcsec, marker_3sigma_arcsec, condition,
                          variance, *, min_points, method, equations) -> DistortionEstimate:
    """``sigma_C1^2 = V - sigma_m^2 - mean_j v_j`` per axis, clipped at 0 with a flag: a
    variance ``V`` of the points (``variance(resid, axis) -> (detail name, V)``) less the
    given marker variance and the temporal variance of the points' means."""
    ps = _check_plate_scale(plate_scale_arcsec)
    m3 = float(_nonneg("marker_3sigma_arcsec", marker_3sigma_arcsec))
    log = _Log()
    what = "LSFE-C1"
    resid, n_bad, n_excl, n_min = _distortion_core(table, reference, condition=condition,
                                                   what=what, log=log)
    w = len(resid)
    if min_points:
        _need_points(w, min_points, what)
    sm2 = (m3 / (3.0 * ps)) ** 2
    flags: list[str] = []
    sig = {}
    details: dict[str, Any] = {"marker_sigma_px": math.sqrt(sm2)}
    for ax in ("x", "y"):
        name, v = variance(resid, ax)
        noise2 = float(np.mean(resid[f"var_mean_{ax}_px2"].to_numpy()))
        details[name] = math.sqrt(v)
        details[f"temporal_variance_of_means_{ax}_px2"] = noise2
        sig[ax] = _root_of_difference(v, sm2 + noise2, ax, flags, log, what)
    return DistortionEstimate(
        quantity="LSFE-C1", method=method, equations=equations,
        sigma_x_px=sig["x"], sigma_y_px=sig["y"], plate_scale_arcsec=ps,
        n_stars=w, n_frames=n_min, n_conditions=1, n_stars_excluded=n_excl,
        n_rows_excluded=n_bad, flags=tuple(flags), warnings=tuple(log.messages),
        details=details, residuals=resid,
    )


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
    def displacement_variance(resid, ax):
        return f"sigma_d{ax}_px", float(np.var(resid[f"d{ax}_px"].to_numpy(), ddof=1))

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


# ----------------------------------------------------------------- combination


def _nonneg(name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise UserInputError(f"{name}: must be finite and >= 0, got {value!r}")
    return arr


def _out(arr: np.ndarray) -> Any:
    return float(arr) if arr.ndim == 0 else arr


def low_spatial_frequency_error(*, chromatic: Any, distortion: Any, marker: Any) -> Any:
    """LSFE combination, seed 000 eq 31: ``sqrt(S^2 + (C1 + C2)^2)``.

    C1 (distortion residual) and C2 (target marker) are correlated and added linearly.
    Any unit, scalars or arrays (e.g. per axis), the result in the same unit.
    """
    s = _nonneg("chromatic", chromatic)
    c1 = _nonneg("distortion", distortion)
    c2 = _nonneg("marker", marker)
    return _out(np.sqrt(s**2 + (c1 + c2) ** 2))


def single_star_error(*, temporal: Any, high_frequency: Any, low_frequency: Any) -> Any:
    """Single-star error, seed 000 section 2.4: RSS of TE, HSFE and LSFE (independent)."""
    te = _nonneg("temporal", temporal)
    h = _nonneg("high_frequency", high_frequency)
    lo = _nonneg("low_frequency", low_frequency)
    return _out(np.sqrt(te**2 + h**2 + lo**2))


def attitude_error(*, single_star: Any, n_stars: int) -> Any:
    """Attitude accuracy with N stars, seed 000 eq 32: ``sigma / sqrt(N)``."""
    s = _nonneg("single_star", single_star)
    if isinstance(n_stars, bool) or not float(n_stars).is_integer() or int(n_stars) < 1:
        raise UserInputError(f"n_stars: must be an integer >= 1, got {n_stars!r}")
    return _out(s / math.sqrt(int(n_stars)))
