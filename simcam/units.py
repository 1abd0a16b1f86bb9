"""Unit conversions and the physical constants more than one model uses, each defined once.

Angles: a quantity in the first unit times ``X_PER_Y`` is the same quantity in ``X``
(``angle_arcsec = angle_rad * ARCSEC_PER_RAD``); ``RAD_PER_ARCSEC`` is the exact reciprocal
rounded once (``math.pi / 648000``), not ``1 / ARCSEC_PER_RAD``, so a site that multiplies by
it and one that divides by ``ARCSEC_PER_RAD`` may differ in the last bit, as they did before
these constants were shared. Every value is the double nearest the exact number.

Earth: two sets, because the worlds follow their papers: WGS 84 with the EGM2008 / IERS 2010
gravitational parameter (the whisk-broom and line cameras), and JGM-3 (the scan mirror).

Standard library only: every module of ``simcam`` and ``budget`` may import this one.
"""

from __future__ import annotations

import math

__all__ = ["ARCSEC_PER_DEG", "ARCSEC_PER_RAD", "C_LIGHT_KM_S", "C_LIGHT_M_S", "EARTH_RATE_RAD_S",
           "JGM3_RADIUS_KM", "MAS_PER_RAD", "MU_EARTH_KM3_S2", "RAD_PER_ARCSEC", "RAD_PER_DEG",
           "SECONDS_PER_DAY", "SECONDS_PER_HOUR", "WGS84_A_KM", "WGS84_F"]

# ----------------------------------------------------------------------------- angles
ARCSEC_PER_DEG: float = 3600.0
"""Arcseconds per degree (exact)."""
ARCSEC_PER_RAD: float = 180.0 * 3600.0 / math.pi
"""Arcseconds per radian, ``648000 / pi`` = 206264.80624709636 (the double nearest the exact
value; ``math.degrees(1) * 3600`` and ``180 / pi * 3600`` give the same double)."""
RAD_PER_ARCSEC: float = math.pi / (180.0 * 3600.0)
"""Radians per arcsecond, ``pi / 648000`` = 4.84813681109536e-06 (the double nearest the exact
value; ``pi / 180 / 3600`` gives the same double)."""
MAS_PER_RAD: float = 180.0 / math.pi * 3600e3
"""Milliarcseconds per radian, ``648000000 / pi`` = 206264806.24709636."""
RAD_PER_DEG: float = math.pi / 180.0
"""Radians per degree, ``pi / 180`` (equal to ``math.radians(1)``)."""

# ----------------------------------------------------------------------------- time
SECONDS_PER_HOUR: float = 3600.0
"""Seconds per hour (exact)."""
SECONDS_PER_DAY: float = 86400.0
"""Seconds per day of 24 h (exact; not the sidereal day)."""

# ----------------------------------------------------------------------------- physics
C_LIGHT_M_S: float = 299792458.0
"""Speed of light in vacuum, m s^-1 (exact, SI)."""
C_LIGHT_KM_S: float = C_LIGHT_M_S / 1000.0
"""Speed of light in vacuum, km s^-1 (299792.458, the same double as the literal)."""

# ----------------------------------------------------------------------------- Earth
WGS84_A_KM: float = 6378.137
"""WGS 84 semi-major (equatorial) axis, km (NIMA TR8350.2, 3rd ed., 2000, table 3.1)."""
WGS84_F: float = 1.0 / 298.257223563
"""WGS 84 flattening (NIMA TR8350.2, 3rd ed., 2000, table 3.1)."""
MU_EARTH_KM3_S2: float = 398600.4418
"""Earth's gravitational parameter GM, km^3 s^-2 (EGM2008 / IERS Conventions 2010)."""
EARTH_RATE_RAD_S: float = 7.2921159e-5
"""Earth's rotation rate in inertial space, rad s^-1, to eight digits (the whisk-broom world's;
the scan mirror's JGM-3 model keeps its own 7.292115e-5)."""
JGM3_RADIUS_KM: float = 6378.1363
"""Earth's equatorial radius of the JGM-3 gravity model, km (Tapley et al. 1996, JGR 101(B12)
28029): the scan mirror's Earth."""
