"""Physical constants of the spectral models (SI 2019 defining constants, photometric and
illuminant references), and the derived private constants the models use."""

from __future__ import annotations

from simcam.units import C_LIGHT_M_S

# The SI defining constants (BIPM, The International System of Units, 9th ed. 2019, table 1):
# exact by definition, so written here rather than importing scipy.constants (0.19 s of
# start-up for four numbers); tests/test_spectra.py checks them against scipy.constants.
# The speed of light, which the sky models use too, is simcam.units.C_LIGHT_M_S (imported above).
H_PLANCK_J_S: float = 6.62607015e-34
"""Planck constant, J s (exact in SI 2019)."""
K_BOLTZMANN_J_K: float = 1.380649e-23
"""Boltzmann constant, J K^-1 (exact in SI 2019)."""
ELEMENTARY_CHARGE_C: float = 1.602176634e-19
"""Elementary charge, C (exact in SI 2019)."""

V_ZERO_POINT_W_M2_NM: float = 3.631e-11
"""Flux density of a V = 0 star, W m^-2 nm^-1.

Bessell, Castelli & Plez (1998, A&A 333, 231), Table A2: 363.1e-11 erg s^-1 cm^-2 A^-1.
Used as a flat ``f_lambda`` reference spectrum: a V = 0 source gives, through the V
passband, the same photon count as a flat spectrum of this flux density.
"""

SILICON_BANDGAP_EV: float = 1.12
"""Band gap of silicon at 300 K, eV (Sze & Ng 2007, *Physics of Semiconductor Devices*,
3rd ed., table of properties of Si at 300 K). Photons with ``lambda > h c / E_g`` (about 1107 nm) make no
photo-electrons."""

CIE_A_TEMPERATURE_K: float = 2856.0
"""Correlated colour temperature of CIE standard illuminant A (tungsten), K (CIE 15:2004)."""

_NM = 1e-9  # metres per nanometre
_HC_J_M = H_PLANCK_J_S * C_LIGHT_M_S  # J m
_C2_M_K = _HC_J_M / K_BOLTZMANN_J_K  # second radiation constant, m K
