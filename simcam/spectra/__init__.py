"""Spectra and the photon-to-electron chain of the star camera.

Everything here works on a wavelength grid in nanometres (vacuum) and returns plain
``numpy`` arrays for the fast paths; ``*_sd`` variants return
:class:`colour.SpectralDistribution` objects for inspection, plotting and the
colour-science algebra.

Units
-----
* photon spectral radiance: photons s^-1 m^-2 sr^-1 nm^-1
* photon spectral flux density (irradiance) at the entrance pupil:
  photons s^-1 m^-2 nm^-1 (``*_per_nm``)
* detected electron rate density: e- s^-1 nm^-1
* transmissions and quantum efficiencies: dimensionless, 0..1

Models and sources
------------------
* Planck's law in photon units, :func:`planck_photon_radiance`
  (Rybicki & Lightman 1979, *Radiative Processes in Astrophysics*, sec. 1.5, divided by
  the photon energy ``h c / lambda``), CODATA constants from :mod:`scipy.constants`.
* Dwarf effective temperatures, :func:`star_teff_k`: Pecaut & Mamajek (2013, ApJS 208, 9,
  Table 5) as maintained in E. Mamajek's online table (version 2017.10.19), see
  ``simcam/data/spectral_types.csv``.
* Stars are **blackbodies at Teff** (no line blanketing, no Balmer jump): an
  approximation good to roughly 10-20 % in band-integrated photon counts for A-K dwarfs.
* V passband: Bessell (1990, PASP 102, 1181, Table 2), ``simcam/data/bessell_v.csv``,
  read as a response per photon. Bessell & Murphy (2012, PASP 124, 140) read the 1990
  curves as energy responses (photon response proportional to ``S(lambda)/lambda``); that
  reading changes a star's normalisation by -2.4 % (2500 K), +0.2 % (5770 K), +0.9 %
  (9700 K) and +1.5 % (40000 K), well inside the blackbody approximation's error.
* V = 0 zero point: ``f_lambda = 363.1e-11 erg s^-1 cm^-2 A^-1`` (Bessell, Castelli &
  Plez 1998, A&A 333, 231, Table A2), i.e. 3.631e-11 W m^-2 nm^-1, which is
  1.005e8 photons s^-1 m^-2 nm^-1 (about 1005 photons s^-1 cm^-2 A^-1) at 550 nm.
* Lamp: blackbody at the CIE illuminant A temperature 2856 K (CIE 15:2004, sec. 3.1).

Layout
------
One module per topic, every public name re-exported here (``from simcam import spectra``;
``from simcam.spectra import X``): :mod:`.constants`, :mod:`.planck` (grid, Planck's law),
:mod:`.stars` (spectral types, stellar photon flux), :mod:`.photometry` (V passband, zero
point), :mod:`.filters` (interference filters), :mod:`.response` (detector QE, optics
transmission), :mod:`.tables` (colour SpectralDistribution conversions, CSV tables),
:mod:`.chain` (photons -> electrons), :mod:`.lamp`; :mod:`.common` holds the argument
checks and the data-table reader. The data files stay in ``simcam/data/``.
"""

from __future__ import annotations

from .chain import (
    circular_aperture_area_m2,
    detected_electron_rate_per_nm,
    electrons_per_exposure,
    normalised_weights,
    trapezoid_weights_nm,
)
from .common import SpectraError
from .constants import (
    C_LIGHT_M_S,
    CIE_A_TEMPERATURE_K,
    ELEMENTARY_CHARGE_C,
    H_PLANCK_J_S,
    K_BOLTZMANN_J_K,
    SILICON_BANDGAP_EV,
    V_ZERO_POINT_W_M2_NM,
)
from .filters import bandpass_array, bandpass_sd
from .lamp import lamp_photon_spectrum_per_nm, lamp_scale_to_match_star
from .photometry import bessell_v_response, bessell_v_sd, v_band_photon_rate, v_zero_point_photon_rate
from .planck import planck_photon_radiance, total_photon_radiance, wavelength_grid_nm
from .response import cmos_qe_array, cmos_qe_sd, flat_transmission_array
from .stars import spectral_type_table, star_photon_flux_per_nm, star_photon_flux_sd, star_teff_k
from .tables import array_to_sd, read_table_csv, sd_to_array, table_sd

__all__ = [
    "SpectraError",
    "H_PLANCK_J_S",
    "C_LIGHT_M_S",
    "K_BOLTZMANN_J_K",
    "ELEMENTARY_CHARGE_C",
    "V_ZERO_POINT_W_M2_NM",
    "SILICON_BANDGAP_EV",
    "CIE_A_TEMPERATURE_K",
    "wavelength_grid_nm",
    "planck_photon_radiance",
    "total_photon_radiance",
    "spectral_type_table",
    "star_teff_k",
    "bessell_v_sd",
    "bessell_v_response",
    "v_band_photon_rate",
    "v_zero_point_photon_rate",
    "star_photon_flux_per_nm",
    "star_photon_flux_sd",
    "bandpass_array",
    "bandpass_sd",
    "cmos_qe_array",
    "cmos_qe_sd",
    "flat_transmission_array",
    "table_sd",
    "read_table_csv",
    "array_to_sd",
    "sd_to_array",
    "circular_aperture_area_m2",
    "detected_electron_rate_per_nm",
    "electrons_per_exposure",
    "trapezoid_weights_nm",
    "normalised_weights",
    "lamp_photon_spectrum_per_nm",
    "lamp_scale_to_match_star",
]
