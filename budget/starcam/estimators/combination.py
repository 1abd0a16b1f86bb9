"""Combination of the error classes: LSFE, seed 000 eq 31 (:func:`low_spatial_frequency_error`);
the single-star error, the RSS of section 2.4 (:func:`single_star_error`); the attitude
error, eq 32 (:func:`attitude_error`). Any unit, scalars or arrays."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from simcam.infra.errors import UserInputError

from .common import _nonneg


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
