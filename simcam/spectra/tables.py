"""Tabulated spectra: numpy arrays to and from :class:`colour.SpectralDistribution`, and
two-column CSV tables."""

from __future__ import annotations

import pathlib
import re

from typing import TYPE_CHECKING

if TYPE_CHECKING:  # colour (and the matplotlib it imports) loads only where a SpectralDistribution is made
    import colour

import numpy as np

from .common import SpectraError, _finite_scalar, _float_array, _unit_values, _wavelengths


def array_to_sd(*, wavelength_nm, values, name: str = "") -> colour.SpectralDistribution:
    """Wrap a sampled curve into a colour SpectralDistribution.

    Parameters
    ----------
    wavelength_nm : array_like
        Strictly increasing 1-D grid, nm.
    values : array_like
        Finite values, same shape.
    name : str
        Name of the distribution.
    """
    lam = _wavelengths(wavelength_nm, grid=True)
    v = _float_array(values, "values")
    if v.shape != lam.shape:
        raise SpectraError(f"values: shape {v.shape} differs from wavelength_nm {lam.shape}")
    import colour

    return colour.SpectralDistribution(dict(zip(lam.tolist(), v.tolist(), strict=True)), name=name)


def sd_to_array(*, sd: colour.SpectralDistribution, wavelength_nm, fill: float = 0.0) -> np.ndarray:
    """Sample a SpectralDistribution on a grid by linear interpolation.

    Linear interpolation (``numpy.interp``) between the SD's samples keeps values within
    the range of the samples (no spline overshoot), so a transmission stays in [0, 1].
    Outside the SD's domain the value is ``fill``.

    Parameters
    ----------
    sd : colour.SpectralDistribution
        Distribution with wavelengths in nm.
    wavelength_nm : array_like
        Wavelengths to sample, nm.
    fill : float
        Value outside the SD's wavelength range.

    Returns
    -------
    numpy.ndarray
        Sampled values, shape of ``wavelength_nm``.
    """
    import colour

    if not isinstance(sd, colour.SpectralDistribution):
        raise SpectraError(f"sd: must be a colour.SpectralDistribution (got {type(sd).__name__})")
    lam = _wavelengths(wavelength_nm)
    f = _finite_scalar(fill, "fill")
    return np.interp(lam, np.asarray(sd.wavelengths, float), np.asarray(sd.values, float),
                     left=f, right=f)


def table_sd(*, wavelength_nm, value, name: str = "table") -> colour.SpectralDistribution:
    """A user table (wavelength_nm, value in [0, 1]) as a SpectralDistribution.

    For measured optics transmission, filter curves or QE. Wavelengths must be strictly
    increasing and positive, values within [0, 1].
    """
    v = _unit_values(value, "value")
    return array_to_sd(wavelength_nm=wavelength_nm, values=v, name=name)


def read_table_csv(*, path) -> colour.SpectralDistribution:
    """Read a two-column CSV table ``wavelength_nm,value`` (0..1) into a SpectralDistribution.

    Lines starting with ``#`` are comments; a first row that is not numeric is taken as a
    header and must read ``wavelength_nm,value``.
    """
    p = pathlib.Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as err:
        raise SpectraError(f"path: cannot read {str(p)!r}: {err.strerror}") from None
    rows = [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if rows and not re.match(r"^[-+0-9.]", rows[0]):
        header = [h.strip() for h in rows[0].split(",")]
        if header != ["wavelength_nm", "value"]:
            raise SpectraError(f"{p}: header must be 'wavelength_nm,value' (got {rows[0]!r})")
        rows = rows[1:]
    lam, val = [], []
    for i, r in enumerate(rows, start=1):
        parts = [s.strip() for s in r.split(",")]
        if len(parts) != 2:
            raise SpectraError(f"{p}: data row {i}: expected 2 columns (got {len(parts)})")
        try:
            lam.append(float(parts[0]))
            val.append(float(parts[1]))
        except ValueError:
            raise SpectraError(f"{p}: data row {i}: not a number in {r!r}") from None
    if len(lam) < 2:
        raise SpectraError(f"{p}: needs at least 2 data rows")
    try:
        return table_sd(wavelength_nm=lam, value=val, name=p.stem)
    except SpectraError as err:
        raise SpectraError(f"{p}: {err}") from None
