"""Electrons per wavelength from the lab's light source through filter, optics and detector.

Signal equation (photon counting; see :func:`simcam.spectra.detected_electron_rate_per_nm`)::

    r(lambda) = k n_src(lambda) A tau_opt(lambda) tau_filter(lambda) QE(lambda)   [e- s^-1 nm^-1]
    N_e = t_exp integral r(lambda) d lambda                                     [e- per pinhole]

``n_src`` is the lamp's relative blackbody photon spectrum (``kind = "lamp"``) or the
blackbody at the matched star's Teff (``kind = "star"``), scaled by ``k`` so that with
no filter each pinhole gives as many electrons as a star of ``match_v_mag`` (seed 000:
"target brightness matched to the camera, better than Mv 7.5").
"""

from __future__ import annotations

import numpy as np

from simcam import spectra
from simcam.starcam.scenario import Scenario


class SourceSpectra:
    """Spectral chain of one scenario, evaluated on the render wavelength grid."""

    def __init__(self, scenario: Scenario):
        scn = scenario
        r = scn.render
        self.wavelength_nm = spectra.wavelength_grid_nm(
            start_nm=r.wavelength_min_nm, end_nm=r.wavelength_max_nm, step_nm=r.wavelength_step_nm
        )
        wl = self.wavelength_nm
        qe = scn.detector.qe
        self.qe = spectra.cmos_qe_array(
            wavelength_nm=wl, peak_qe=qe.peak_qe, peak_nm=qe.peak_nm,
            blue_cutoff_nm=qe.blue_cutoff_nm, red_cutoff_nm=qe.red_cutoff_nm,
        )
        self.transmission = spectra.flat_transmission_array(
            wavelength_nm=wl, transmission=scn.optics.transmission
        )
        self.aperture_area_m2 = spectra.circular_aperture_area_m2(diameter_mm=scn.camera.aperture_diameter_mm)
        self.exposure_s = scn.camera.exposure_s
        src = scn.lab.source
        star_t = spectra.star_teff_k(spectral_type=src.match_spectral_type)
        if src.kind == "star" and src.star_temperature_k is not None:
            star_t = src.star_temperature_k
        if src.kind == "lamp":
            shape = spectra.lamp_photon_spectrum_per_nm(temperature_k=src.temperature_k, wavelength_nm=wl)
            scale = spectra.lamp_scale_to_match_star(
                v_mag=src.match_v_mag, star_temperature_k=star_t, lamp_temperature_k=src.temperature_k,
                wavelength_nm=wl, transmission=self.transmission, qe=self.qe,
            )
            self.photon_flux_per_nm = scale * shape
        else:
            self.photon_flux_per_nm = spectra.star_photon_flux_per_nm(
                v_mag=src.match_v_mag, temperature_k=star_t, wavelength_nm=wl
            )
        self._filters = {f.center_nm: f for f in scn.lab.filters}
        self._cache: dict = {}

    def filter_transmission(self, filter_nm: float | None) -> np.ndarray | float:
        """Transmission of the lab filter centred at ``filter_nm`` (1 for no filter)."""
        if filter_nm is None:
            return 1.0
        f = self._filters.get(float(filter_nm))
        if f is None:
            raise ValueError(f"filter_nm: no lab filter centred at {filter_nm} nm (have {sorted(self._filters)})")
        return spectra.bandpass_array(
            wavelength_nm=self.wavelength_nm, center_nm=f.center_nm, width_nm=f.width_nm,
            peak_transmission=f.peak_transmission,
        )

    def electron_rate_per_nm(self, *, filter_nm: float | None) -> tuple[np.ndarray, np.ndarray]:
        """(wavelength_nm, e- s^-1 nm^-1) of one pinhole through ``filter_nm`` (None: no filter)."""
        key = None if filter_nm is None else float(filter_nm)
        if key not in self._cache:
            self._cache[key] = spectra.detected_electron_rate_per_nm(
                photon_flux_per_nm=self.photon_flux_per_nm, aperture_area_m2=self.aperture_area_m2,
                transmission=self.transmission, filter_transmission=self.filter_transmission(key),
                qe=self.qe, wavelength_nm=self.wavelength_nm,
            )
        return self.wavelength_nm, self._cache[key]

    def weights(self, electron_rate_per_nm: np.ndarray) -> np.ndarray:
        """Per-wavelength weights (sum 1) of the polychromatic image."""
        return spectra.normalised_weights(electron_rate_per_nm=electron_rate_per_nm, wavelength_nm=self.wavelength_nm)

    def electrons_per_exposure(self, electron_rate_per_nm: np.ndarray) -> float:
        """Mean photo-electrons per pinhole per exposure."""
        return spectra.electrons_per_exposure(
            electron_rate_per_nm=electron_rate_per_nm, wavelength_nm=self.wavelength_nm, exposure_s=self.exposure_s
        )

