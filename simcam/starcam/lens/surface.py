"""Surface shape of a rotationally symmetric refracting surface: sag, slope and normal.

The even-asphere sag (the standard form of lens-design codes, e.g. W. J. Smith, Modern
Optical Engineering, 4th ed., Sec. 18.3; ISO 10110-12), in the surface's local frame
(vertex at the origin, axis along +z)::

    z(s) = c s / (1 + sqrt(1 - (1 + k) c^2 s)) + sum_{m>=2} A_{2m} s^m,    s = x^2 + y^2,

with curvature ``c = 1/R``, conic constant ``k`` (0 sphere, -1 paraboloid) and aspheric
coefficients ``A4, A6, ...`` (mm^-3, mm^-5, ...). Its derivative in ``s`` is::

    dz/ds = c / (2 sqrt(1 - (1 + k) c^2 s)) + sum_{m>=2} m A_{2m} s^(m-1),

(from ``c s / (1 + q) = (1 - q) / ((1 + k) c)`` with ``q = sqrt(1 - (1 + k) c^2 s)``), and
the surface normal is ``grad(z - sag) = (-2 x dz/ds, -2 y dz/ds, 1)``.

The functions take an array namespace ``xp`` (:data:`NUMPY` or the Dr.Jit namespace of
:mod:`simcam.starcam.lens.tracer`) so that one implementation serves the vectorised Mitsuba
tracer and the numpy code (paraxial checks, edge-thickness checks, scalar fallback).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

__all__ = ["NUMPY", "SurfaceShape"]


def _np_select(mask, a, b):
    return np.where(mask, a, b)


def _np_sqrt(x):
    with np.errstate(invalid="ignore"):
        return np.sqrt(x)


#: numpy array namespace for the shape functions (NaN, no warning, for sqrt of < 0).
NUMPY = SimpleNamespace(sqrt=_np_sqrt, select=_np_select, abs=np.abs, name="numpy")


@dataclass(frozen=True)
class SurfaceShape:
    """Shape of one surface: curvature, conic constant, aspheric coefficients.

    Parameters
    ----------
    curvature_per_mm : float
        ``c = 1 / R`` (0 for a flat).
    conic : float
        Conic constant ``k``.
    aspheric_coeffs : tuple of float
        ``A4, A6, A8, ...`` (coefficient of ``s^2, s^3, ...`` with ``s = rho^2``).
    """

    curvature_per_mm: float
    conic: float = 0.0
    aspheric_coeffs: tuple[float, ...] = ()

    @property
    def is_flat(self) -> bool:
        """A plane (no curvature, no aspheric terms)."""
        return self.curvature_per_mm == 0.0 and not any(self.aspheric_coeffs)

    @property
    def is_sphere(self) -> bool:
        """A sphere or plane (conic 0, no aspheric terms)."""
        return self.conic == 0.0 and not any(self.aspheric_coeffs)

    def max_s_mm2(self) -> float:
        """Largest ``s = rho^2`` (mm^2) where the conic term is real (inf if unbounded)."""
        kk = (1.0 + self.conic) * self.curvature_per_mm**2
        return float("inf") if kk <= 0 else 1.0 / kk

    def sag(self, s, xp=NUMPY):
        """Sag ``z(s)`` in mm at ``s = rho^2`` (mm^2); NaN outside the conic's domain."""
        c = self.curvature_per_mm
        kk = (1.0 + self.conic) * c * c
        z = c * s / (1.0 + xp.sqrt(1.0 - kk * s)) if c != 0.0 else s * 0.0
        if self.aspheric_coeffs:
            poly = s * 0.0
            for a in reversed(self.aspheric_coeffs):  # Horner: s^2 (A4 + s (A6 + ...))
                poly = poly * s + a
            z = z + poly * s * s
        return z

    def dsag_ds(self, s, xp=NUMPY):
        """``dz/ds`` (mm^-1) at ``s = rho^2``; NaN outside the conic's domain."""
        c = self.curvature_per_mm
        kk = (1.0 + self.conic) * c * c
        d = c / (2.0 * xp.sqrt(1.0 - kk * s)) if c != 0.0 else s * 0.0
        if self.aspheric_coeffs:
            poly = s * 0.0
            n = len(self.aspheric_coeffs)
            for i, a in enumerate(reversed(self.aspheric_coeffs)):  # m A_{2m} s^(m-1), m = 2..
                m = n + 1 - i
                poly = poly * s + m * a
            d = d + poly * s
        return d
