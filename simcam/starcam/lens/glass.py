"""Optical glass catalogue: refractive index from Sellmeier coefficients.

Every glass is described by the three-term Sellmeier dispersion formula (W. Sellmeier,
Ann. Phys. Chem. 143, 272, 1871; the form used by the SCHOTT and OHARA catalogues, see
SCHOTT Technical Information TIE-29 "Refractive Index and Dispersion", 2016)::

    n^2(lambda) - 1 = sum_{i=1..3} B_i lambda^2 / (lambda^2 - C_i),    lambda in um,

with ``B_i`` dimensionless and ``C_i`` in um^2. The catalogue indices are relative to
air (the glass makers' convention); the lens package therefore gives air the index 1
exactly, so a system in air is traced with relative indices throughout.

Sources of the built-in coefficients
------------------------------------
* SCHOTT glasses (N-BK7, N-K5, N-BAK4, N-SK16, N-LAK9, N-BAF10, N-FK51A, F2, N-SF5,
  N-SF6, N-SF11): SCHOTT Optical Glass data sheets / "Optical Glass - Data Sheets"
  (SCHOTT AG, 2017 and later; coefficients ``B1..B3``, ``C1..C3``), with the catalogue
  ``nd`` and ``vd`` given on the same sheets.
* Fused silica (``F_SILICA``): I. H. Malitson, "Interspecimen comparison of the
  refractive index of fused silica", J. Opt. Soc. Am. 55, 1205-1209 (1965), fit valid
  0.21-3.71 um.
* Calcium fluoride (``CAF2``): I. H. Malitson, "A redetermination of some optical
  properties of calcium fluoride", Appl. Opt. 2, 1103-1107 (1963), fit valid
  0.23-9.7 um.

A prescription may define further glasses by their Sellmeier coefficients (its
``[[glasses]]`` tables, see :mod:`simcam.starcam.lens.prescription`).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field

import numpy as np

from simcam.starcam.lens.errors import LensError

__all__ = [
    "AIR",
    "CATALOGUE",
    "FRAUNHOFER_C_NM",
    "FRAUNHOFER_D_NM",
    "FRAUNHOFER_F_NM",
    "Glass",
    "get_glass",
    "glass_names",
]

#: Fraunhofer lines used for the catalogue nd and vd (helium d, hydrogen F and C), nm.
FRAUNHOFER_D_NM = 587.5618
FRAUNHOFER_F_NM = 486.1327
FRAUNHOFER_C_NM = 656.2725


@dataclass(frozen=True)
class Glass:
    """One optical material described by a three-term Sellmeier formula.

    Parameters
    ----------
    name : str
        Catalogue name (upper case is the lookup key).
    b : tuple of 3 float
        Sellmeier ``B1, B2, B3`` (dimensionless).
    c_um2 : tuple of 3 float
        Sellmeier ``C1, C2, C3`` in um^2.
    source : str
        Where the coefficients come from.
    valid_nm : tuple of 2 float
        Wavelength range of the fit, nm.
    nd, vd : float or None
        Catalogue refractive index at the helium d line and Abbe number, for checks.
    """

    name: str
    b: tuple[float, float, float]
    c_um2: tuple[float, float, float]
    source: str
    valid_nm: tuple[float, float] = (300.0, 2500.0)
    nd: float | None = None
    vd: float | None = None
    is_air: bool = field(default=False, repr=False)

    def __post_init__(self):
        if self.is_air:
            return
        if len(self.b) != 3 or len(self.c_um2) != 3:
            raise LensError(f"glass {self.name}: Sellmeier needs 3 B and 3 C coefficients")
        for name, seq in (("sellmeier_b", self.b), ("sellmeier_c_um2", self.c_um2)):
            if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in seq):
                raise LensError(f"glass {self.name}: {name} must be finite numbers, got {seq!r}")
        lo, hi = self.valid_nm
        if not (0 < lo < hi):
            raise LensError(f"glass {self.name}: valid_nm must be 0 < min < max, got {self.valid_nm}")
        # the formula must be regular (no pole) and give n > 1 over its range
        wl = np.linspace(lo, hi, 257)
        n = self._index(wl)
        if not np.all(np.isfinite(n)) or np.any(n <= 1.0):
            raise LensError(
                f"glass {self.name}: the Sellmeier coefficients give no real index > 1 over "
                f"{lo:g}-{hi:g} nm (a pole or n^2 < 1)"
            )

    def _index(self, wavelength_nm: np.ndarray) -> np.ndarray:
        l2 = (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3) ** 2
        n2 = 1.0 + sum(b * l2 / (l2 - c) for b, c in zip(self.b, self.c_um2))
        with np.errstate(invalid="ignore"):
            return np.sqrt(n2)

    def refractive_index(self, wavelength_nm) -> np.ndarray:
        """Refractive index (relative to air) at ``wavelength_nm`` (nm), Sellmeier formula.

        Raises
        ------
        LensError
            A wavelength outside the glass's valid range.
        """
        wl = np.asarray(wavelength_nm, dtype=np.float64)
        if self.is_air:
            return np.ones_like(wl)
        lo, hi = self.valid_nm
        if wl.size and (not np.all(np.isfinite(wl)) or wl.min() < lo or wl.max() > hi):
            raise LensError(
                f"glass {self.name}: wavelength {wl.min():g}-{wl.max():g} nm outside the range "
                f"of its Sellmeier fit ({lo:g}-{hi:g} nm)"
            )
        return self._index(wl)

    def abbe_number(self) -> float:
        """Abbe number ``vd = (nd - 1) / (nF - nC)`` from the Sellmeier formula."""
        nd, nf, nc = self.refractive_index([FRAUNHOFER_D_NM, FRAUNHOFER_F_NM, FRAUNHOFER_C_NM])
        return float((nd - 1.0) / (nf - nc))


#: The surrounding medium: index 1 exactly (catalogue indices are relative to air).
AIR = Glass(name="AIR", b=(0.0, 0.0, 0.0), c_um2=(0.0, 0.0, 0.0), source="index 1 (relative indices)",
            valid_nm=(1.0, 1e6), nd=1.0, vd=None, is_air=True)

_SCHOTT = "SCHOTT Optical Glass data sheet (SCHOTT AG)"

_GLASSES = (
    # name, B1, B2, B3, C1, C2, C3, valid nm, nd, vd, source
    ("N-BK7", (1.03961212, 0.231792344, 1.01046945), (0.00600069867, 0.0200179144, 103.560653),
     (300.0, 2500.0), 1.51680, 64.17, _SCHOTT),
    ("N-K5", (1.08511833, 0.199562005, 0.930511663), (0.00661099503, 0.024110866, 111.982777),
     (310.0, 2500.0), 1.52249, 59.48, _SCHOTT),
    ("N-BAK4", (1.28834642, 0.132817724, 0.945395373), (0.00779980626, 0.0315631177, 105.965875),
     (320.0, 2500.0), 1.56883, 55.98, _SCHOTT),
    ("N-SK16", (1.34317774, 0.241144399, 0.994317969), (0.00704687339, 0.0229005, 92.7508526),
     (310.0, 2500.0), 1.62041, 60.32, _SCHOTT),
    ("N-LAK9", (1.46231905, 0.344399589, 1.15508372), (0.00724270156, 0.0243353131, 85.4686868),
     (310.0, 2500.0), 1.69100, 54.71, _SCHOTT),
    ("N-BAF10", (1.5851495, 0.143559385, 1.08521269), (0.00926681282, 0.0424489805, 105.613573),
     (350.0, 2500.0), 1.67003, 47.11, _SCHOTT),
    ("N-FK51A", (0.971247817, 0.216901417, 0.904651666), (0.00472301995, 0.0153575612, 168.68133),
     (290.0, 2500.0), 1.48656, 84.47, _SCHOTT),
    ("F2", (1.34533359, 0.209073176, 0.937357162), (0.00997743871, 0.0470450767, 111.886764),
     (320.0, 2500.0), 1.62004, 36.37, _SCHOTT),
    ("N-SF5", (1.52481889, 0.187085527, 1.42729015), (0.011254756, 0.0588995392, 129.141675),
     (370.0, 2500.0), 1.67271, 32.25, _SCHOTT),
    ("N-SF6", (1.77931763, 0.338149866, 2.08734474), (0.0133714182, 0.0617533621, 174.01759),
     (370.0, 2500.0), 1.80518, 25.36, _SCHOTT),
    ("N-SF11", (1.73759695, 0.313747346, 1.89878101), (0.013188707, 0.0623068142, 155.23629),
     (370.0, 2500.0), 1.78472, 25.68, _SCHOTT),
    ("F_SILICA", (0.6961663, 0.4079426, 0.8974794), (0.0684043**2, 0.1162414**2, 9.896161**2),
     (210.0, 3710.0), 1.45846, 67.82, "Malitson, J. Opt. Soc. Am. 55, 1205 (1965)"),
    ("CAF2", (0.5675888, 0.4710914, 3.8484723), (0.050263605**2, 0.1003909**2, 34.649040**2),
     (230.0, 9700.0), 1.43385, 94.99, "Malitson, Appl. Opt. 2, 1103 (1963)"),
)

#: Built-in glasses by upper-case name (``AIR`` included).
CATALOGUE: dict[str, Glass] = {"AIR": AIR}
for _name, _b, _c, _rng, _nd, _vd, _src in _GLASSES:
    CATALOGUE[_name] = Glass(name=_name, b=_b, c_um2=_c, source=_src, valid_nm=_rng, nd=_nd, vd=_vd)

#: Alternative spellings accepted by :func:`get_glass`.
_ALIASES = {"FUSED_SILICA": "F_SILICA", "SILICA": "F_SILICA", "FUSED SILICA": "F_SILICA", "CAF2": "CAF2",
            "CALCIUM_FLUORIDE": "CAF2", "VACUUM": "AIR"}


def glass_names() -> list[str]:
    """Names of the built-in glasses (air excluded)."""
    return [k for k in CATALOGUE if k != "AIR"]


def get_glass(name: str, extra: dict[str, Glass] | None = None) -> Glass:
    """Look up a glass by name (case-insensitive), in ``extra`` first, then the catalogue.

    Raises
    ------
    LensError
        Unknown name; the message lists the closest known names.
    """
    if not isinstance(name, str) or not name.strip():
        raise LensError(f"glass name must be a non-empty string, got {name!r}")
    key = name.strip().upper()
    extra = {k.upper(): v for k, v in (extra or {}).items()}
    if key in extra:
        return extra[key]
    key = _ALIASES.get(key, key)
    if key in CATALOGUE:
        return CATALOGUE[key]
    known = sorted(set(CATALOGUE) | set(extra))
    close = difflib.get_close_matches(key, known, n=3, cutoff=0.6)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    raise LensError(f"unknown glass {name!r}{hint}; known: {', '.join(known)}")
