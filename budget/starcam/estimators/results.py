"""What every estimator returns: one error class per axis, with what was excluded.

:class:`ErrorEstimate` and its three subclasses carrying a table (HSFE residuals, LSFE-S
filter pairs, LSFE-C1 residual vectors), and :class:`EstimatorWarning`. No equation here.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any

import pandas as pd


class EstimatorWarning(UserWarning):
    """Data were excluded or a result was clipped; the result records it too."""


class _Table:
    """A result's table (a dataclass field): given as a DataFrame, or as a function that
    builds it, called on first access, so that a result read only for its sigmas (in every
    Monte Carlo trial) never builds its table. Default: an empty table."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: Any, objtype: type | None = None) -> Any:
        if obj is None:
            return pd.DataFrame                      # the default, a function building an empty table
        value = obj.__dict__[self.name]
        if not isinstance(value, pd.DataFrame):
            value = obj.__dict__[self.name] = value()
        return value

    def __set__(self, obj: Any, value: Any) -> None:
        obj.__dict__[self.name] = value


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

    residuals: pd.DataFrame = _Table()


@dataclass(frozen=True, kw_only=True)
class ChromaticEstimate(ErrorEstimate):
    """LSFE-S result with one row per filter pair in ``pairs``."""

    pairs: pd.DataFrame = _Table()


@dataclass(frozen=True, kw_only=True)
class DistortionEstimate(ErrorEstimate):
    """LSFE-C1 result with the per-point residual vectors (seed fig. 8).

    ``residuals`` columns: ``star``, ``x_ref``, ``y_ref``, ``dx_px``, ``dy_px`` (eqs
    19-20), ``fit_x_px``, ``fit_y_px`` (cubic fit), ``ddx_px``, ``ddy_px`` (eqs 25-26).
    """

    residuals: pd.DataFrame = _Table()
