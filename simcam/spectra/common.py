"""What every spectral module shares: :class:`SpectraError`, the argument checks, and the
reader of the package's data tables (``simcam/data/*.csv``, through importlib.resources)."""

from __future__ import annotations

import math
from importlib import resources

import numpy as np


class SpectraError(ValueError):
    """Invalid input to a spectral model: names the parameter and what is wrong."""


def _positive_scalar(value, name: str, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be a real number (got {value!r})") from None
    if not math.isfinite(v):
        raise SpectraError(f"{name}: must be finite (got {v!r})")
    if allow_zero:
        if v < 0:
            raise SpectraError(f"{name}: must be >= 0 (got {v!r})")
    elif v <= 0:
        raise SpectraError(f"{name}: must be > 0 (got {v!r})")
    return v


def _finite_scalar(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be a real number (got {value!r})") from None
    if not math.isfinite(v):
        raise SpectraError(f"{name}: must be finite (got {v!r})")
    return v


def _unit_scalar(value, name: str) -> float:
    v = _finite_scalar(value, name)
    if not 0.0 <= v <= 1.0:
        raise SpectraError(f"{name}: must lie in [0, 1] (got {v!r})")
    return v


def _float_array(value, name: str) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise SpectraError(f"{name}: must be an array of real numbers") from None
    if not np.all(np.isfinite(a)):
        raise SpectraError(f"{name}: contains NaN or infinite values")
    return a


def _wavelengths(value, name: str = "wavelength_nm", *, grid: bool = False) -> np.ndarray:
    """Validate wavelengths (nm): finite and > 0; with ``grid``, 1-D strictly increasing."""
    a = _float_array(value, name)
    if a.size == 0:
        raise SpectraError(f"{name}: is empty")
    if np.any(a <= 0):
        raise SpectraError(f"{name}: wavelengths must be > 0 nm (min {a.min()!r})")
    if grid:
        if a.ndim != 1 or a.size < 2:
            raise SpectraError(f"{name}: must be a 1-D grid of at least 2 wavelengths")
        if np.any(np.diff(a) <= 0):
            raise SpectraError(f"{name}: must be strictly increasing")
    return a


def _unit_values(value, name: str) -> np.ndarray:
    a = _float_array(value, name)
    if np.any(a < 0) or np.any(a > 1):
        raise SpectraError(
            f"{name}: values must lie in [0, 1] (min {a.min()!r}, max {a.max()!r})"
        )
    return a


def _on_grid(value, name: str, wavelength_nm: np.ndarray, *, unit: bool) -> np.ndarray:
    """Validate a scalar or per-wavelength array and broadcast it to the grid shape."""
    a = _unit_values(value, name) if unit else _float_array(value, name)
    if not unit and np.any(a < 0):
        raise SpectraError(f"{name}: must be >= 0 (min {a.min()!r})")
    if a.ndim not in (0, 1) or (a.ndim == 1 and a.shape != wavelength_nm.shape):
        raise SpectraError(
            f"{name}: must be a scalar or have the shape of wavelength_nm "
            f"{wavelength_nm.shape} (got shape {a.shape})"
        )
    return np.broadcast_to(a, wavelength_nm.shape)


def _read_data_csv(name: str) -> tuple[list[str], list[list[str]]]:
    text = resources.files("simcam").joinpath("data", name).read_text(encoding="utf-8")
    rows = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.startswith("#")]
    header = rows[0].split(",")
    return header, [r.split(",") for r in rows[1:]]
