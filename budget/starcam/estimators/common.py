"""Shared steps of the estimators: table checks, rows as arrays, per-star statistics, the
last-call memo.

A centroid table is checked once (:func:`_checked_rows`) and turned into :class:`_Rows`,
numpy arrays per column, which is all the estimators compute on; a simulated protocol's
table comes as rows already (:func:`budget.starcam.protocols.simulate`). Nothing here
implements a seed-000 equation by itself; :func:`_per_star_stats` computes the per-star (or
per star and condition) means and variances that eqs 1, 3-4, 13-14 and 17-18 start from.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pandas as pd

from simcam.infra.errors import UserInputError

from .results import EstimatorWarning


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


class _Rows:
    """A centroid table as numpy arrays, one per column (one value per row): what the
    estimators compute on.

    ``columns`` maps a column name to its values; a ``field`` column holds integer codes
    into the sorted labels ``field_labels``. Built from a checked DataFrame
    (:func:`_checked_rows`), or by :func:`budget.starcam.protocols.simulate` from the arrays of
    the table it centroids, which meets those checks by construction (one row per star,
    frame and condition, integer keys and flags), so the estimators take it unchecked.
    """

    __slots__ = ("columns", "field_labels")

    def __init__(self, columns: dict[str, np.ndarray], field_labels: np.ndarray | None = None) -> None:
        self.columns = columns
        self.field_labels = field_labels

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    def __len__(self) -> int:
        return len(next(iter(self.columns.values())))

    def take(self, keep: np.ndarray) -> _Rows:
        """The rows where ``keep`` (boolean, one per row) is true."""
        return _Rows({c: v[keep] for c, v in self.columns.items()}, self.field_labels)

    def to_frame(self) -> pd.DataFrame:
        """The table as a DataFrame, ``field`` as its labels."""
        cols = dict(self.columns)
        if "field" in cols:
            cols["field"] = np.asarray(self.field_labels, dtype=object)[cols["field"]]
        return pd.DataFrame(cols)


def _checked_rows(table: Any, *, required: tuple[str, ...], key: tuple[str, ...], what: str) -> _Rows:
    """The columns of a DataFrame the estimators read (``required``, ``key``, ``flag``), after
    checking them: a DataFrame with rows, the required columns, numeric x and y, integer
    keys without gaps (a ``field`` key without missing values), no two rows with the same
    key, an integer flag. x and y as float64, a ``field`` as codes into its sorted labels."""
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
    if "flag" in table.columns and not pd.api.types.is_integer_dtype(table["flag"]):
        raise UserInputError(f"{what}: column 'flag' must hold integers (dtype {table['flag'].dtype})")
    columns, labels = {}, None
    for c in dict.fromkeys((*required, *key, "flag")):
        if c not in table.columns:
            continue
        if c in ("x", "y"):
            columns[c] = table[c].to_numpy(float)
        elif c == "field":
            columns[c], labels = pd.factorize(table[c], sort=True)
        else:
            columns[c] = table[c].to_numpy()
    return _Rows(columns, labels)


def _prepare(
    table: Any, *, required: tuple[str, ...], key: tuple[str, ...], what: str, log: _Log
) -> tuple[_Rows, _Rows, int]:
    """A table's rows and its good rows (flagged and non-finite rows excluded, with a
    warning): ``(rows, good rows, n excluded)``. A DataFrame is checked first
    (:func:`_checked_rows`); :class:`_Rows` (a simulated protocol's own table) are not."""
    rows = table if isinstance(table, _Rows) else _checked_rows(table, required=required, key=key, what=what)
    bad = ~(np.isfinite(rows["x"]) & np.isfinite(rows["y"]))
    if "flag" in rows:
        bad |= rows["flag"] != 0
    n_bad = int(bad.sum())
    if n_bad:
        stars = sorted(set(rows["star"][bad].tolist()))
        shown = ", ".join(str(s) for s in stars[:10]) + (" ..." if len(stars) > 10 else "")
        log.warn(f"{what}: {n_bad} row(s) flagged or with non-finite x/y excluded (stars {shown})")
    # the estimators only read the good rows: the table itself when none is excluded
    good = rows.take(~bad) if n_bad else rows
    if len(good) == 0:
        raise UserInputError(f"{what}: no good rows left after excluding flagged/non-finite rows")
    return rows, good, n_bad


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


def _select_condition(df: Any, condition: int | None, what: str) -> pd.DataFrame | _Rows:
    """The rows of one static condition (all rows when the table holds only one; rows of a
    simulated static protocol hold one by construction)."""
    if isinstance(df, _Rows):
        return df if condition is None else df.take(df["condition"] == condition)
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


def _unique(values: np.ndarray, *, return_inverse: bool = False):
    """``numpy.unique(values, return_inverse=...)``, the same arrays: for integers whose range
    is at most a few times their count (star, condition and frame numbers) by a table of
    the values present, in linear time, instead of a sort."""
    if values.dtype.kind in "iu" and values.size:
        lo, hi = int(values.min()), int(values.max())
        if hi - lo <= 4 * values.size + 1024:
            present = np.zeros(hi - lo + 1, dtype=bool)
            offset = values - values.dtype.type(lo)
            present[offset] = True
            uniques = np.flatnonzero(present).astype(values.dtype) + values.dtype.type(lo)
            if not return_inverse:
                return uniques
            return uniques, (np.cumsum(present) - 1)[offset]
    return np.unique(values, return_inverse=return_inverse)


def _per_star_stats(rows: _Rows, by: list[str], ddof: int) -> _Rows:
    """Per group of the ``by`` columns (sorted, as ``groupby(by, sort=True)``): count ``n``,
    means and variances (``ddof``; NaN when ``n <= ddof``) of x and y.

    Integer codes and ``numpy.bincount`` instead of a pandas groupby (the estimators run
    in every Monte Carlo trial); the variance is the two-pass sum of squared deviations
    from the group mean, so no precision is lost to cancellation.
    """
    n_rows = len(rows)
    codes = np.zeros(n_rows, dtype=np.int64)
    uniques = []
    for c in by:
        u, inv = _unique(rows[c], return_inverse=True)
        codes = codes * len(u) + inv.reshape(-1)
        uniques.append(u)
    groups, inv = _unique(codes, return_inverse=True)
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
        v = rows[ax]
        m = np.bincount(inv, weights=v, minlength=groups.size) / n
        ss = np.bincount(inv, weights=(v - m[inv]) ** 2, minlength=groups.size)
        with np.errstate(invalid="ignore", divide="ignore"):
            var = np.where(n > ddof, ss / np.maximum(n - ddof, 1), np.nan)
        means[f"mean_{ax}"], variances[f"var_{ax}"] = m, var
    out.update(means)
    out.update(variances)
    return _Rows(out)


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


def _nonneg(name: str, value: Any) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise UserInputError(f"{name}: must be finite and >= 0, got {value!r}")
    return arr
