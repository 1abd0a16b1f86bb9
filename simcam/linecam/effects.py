"""What the line camera's world carries and the lab's model leaves out (seed 004).

``[world.effects]`` of the scenario holds one magnitude per effect (unit in the name, 0 =
off, default = the sourced realistic magnitude); ``[world]`` holds settings of the model
forms. Only the world (:mod:`simcam.linecam.world`, :mod:`simcam.linecam.camera`,
:mod:`simcam.linecam.attitude`) reads them; the lab (:mod:`budget.linecam`) never does
(tested). The effects and their model forms:

* **Distortion outside the Brown family** (the lab fits Brown's k1, k2, p1, p2):
  Brown's (1971) third radial term ``k3 r^6`` and the thin-prism terms of Weng, Cohen &
  Herniou, "Camera calibration with distortion models and accuracy evaluation", IEEE PAMI
  14 (1992) 965, eq. (11), extended to fourth order:
  ``Ex = r_n [k3 X r^6 + s1 r^2 + s2 r^4]``, ``Ey = r_n [k3 Y r^6 + s3 r^2 + s4 r^4]``
  (normalised by ``r_n`` = half the line like the lab's Brown terms; added to Brown's
  correction: ``x_ideal = x' - Dx - Ex``). The magnitudes are the displacements at the
  line's end (``r = 1``): ``k3 = a/r_n``; ``s1 = s2 = s3 = s4 = a/(2 r_n)``.
  On the line (``X = 0``) k3 gives ``y'^7`` across and the prism ``y'^4`` along and
  across, shapes no Brown term has (the ``y'^2`` parts are p1's and p2's).
* **Attitude jitter with a coloured spectrum**: the true attitude is the planned one
  times ``exp([j(t)]x)``, ``j`` per axis the sum of the three ZY-3 gyro lines (0.21, 0.56,
  1.12 Hz, amplitudes in the ratio 0.07 : 0.04 : 0.04; Tang et al., Sensors 20:736 (2020),
  Table 1) and a first-order Gauss-Markov band (time constant ``jitter_band_tau_s``; Tong
  et al., IEEE TGRS 53 (2015), doi:10.1109/TGRS.2014.2379435, for jitter the attitude
  data miss), from :mod:`simcam.noise_processes`. The attitude reports do not contain it;
  they keep the white knowledge error of the stated sigma the lab assumes.
* **Star-tracker time-tag bias** ``b``: the attitude reported for time ``t`` is the one
  of ``t - b``, an attitude error ``omega b`` along the body rate.
* **Gaia DR3 world**: the world's stars are on their Gaia DR3 positions with hip2's
  motions perturbed by ``k`` times their formal errors (:func:`simcam.sky.gaia.gaia_world`);
  the lab keeps Hipparcos.
* **Star-colour centroid shift**: lateral colour of the optics, a displacement
  ``x(lambda) = kappa g(lambda) (x', y')/r_n`` with the Cauchy dispersion shape
  ``g = (550 nm / lambda)^2`` (Cauchy 1836: ``n = A + B/lambda^2``); a star of temperature
  T is imaged at the QE-weighted mean ``xbar(T) = int x S_T QE dlambda / int S_T QE dlambda``
  (photon SED ``S_T`` of :func:`simcam.spectra.star_photon_flux_per_nm`, the camera's QE),
  relative to a solar star (5772 K: the camera images the Earth in reflected sunlight, so
  the line of sight that matters is the solar spectrum's). The magnitude is
  ``xbar(3500 K) - xbar(20000 K)`` at the line's end.
* **Line-rate mismatch**: the scan rate differs from the one matched to the line period by
  ``eps``; the star's image moves ``N eps`` px against the charge during an exposure (a
  streak centred on mid-exposure: Guo et al., Opt. Precision Eng. 21 (2013) 2195).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Any

import numpy as np
from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from simcam import spectra
from simcam.effects import EffectsBase, WorldBase
from simcam.noise_processes import sample
from simcam.units import RAD_PER_ARCSEC

__all__ = ["LineCamEffects", "LineCamWorld", "JITTER_TONES_HZ", "JITTER_TONE_RATIOS", "T_SUN_K",
           "extra_distortion_px", "lateral_colour_px", "mean_colour_weight", "chromatic_centroid",
           "jitter_components", "Jitter", "effects_generator"]

def _mag(upper: float):
    """A magnitude: 0 (off) up to a bound far above any real instrument's (a typo is an error)."""
    return Annotated[float, Field(ge=0.0, le=upper, allow_inf_nan=False)]

#: ZY-3 gyro jitter lines, Hz, and their amplitudes relative to the first (Tang et al. 2020, Table 1:
#: 0.07, 0.04, 0.04 arcsec)
JITTER_TONES_HZ = (0.21, 0.56, 1.12)
JITTER_TONE_RATIOS = (1.0, 4.0 / 7.0, 4.0 / 7.0)
#: effective temperature of the Sun, K (IAU 2015 Resolution B3): the reference colour of the LOS
T_SUN_K = 5772.0
#: temperatures between which the lateral-colour magnitude is stated, K
T_COOL_K, T_HOT_K = 3500.0, 20000.0
#: reference wavelength of the Cauchy dispersion shape, nm
LAMBDA_REF_NM = 550.0
#: time step of the world's sampled jitter, s (linear interpolation between samples): 2^-10 s, so
#: that the grid k 2^-10 is exact in binary and its steps are equal (the Gauss-Markov recursion
#: then runs as one IIR filter)
JITTER_STEP_S = 2.0**-10


class LineCamEffects(EffectsBase):
    """Magnitudes of the line camera world's unmodelled effects (0 = off)."""

    distortion_k3_edge_px: _mag(100.0) = Field(
        0.1, description="Brown's k3 r^6 at the line's end, px: <= 0.1 px at the field edge in a traced lens "
                         "(about 0.3 % of the r^3 term)")
    thin_prism_edge_px: _mag(100.0) = Field(
        0.2, description="thin-prism distortion (Weng et al. 1992) at the line's end, px, each axis: 0.1-0.3 px "
                         "from element and detector tilt (engineering estimate)")
    jitter_tones_arcsec: _mag(3600.0) = Field(
        0.07, description="amplitude of the 0.21 Hz attitude-jitter line (0.56 and 1.12 Hz at 4/7 of it), arcsec "
                          "per axis: ZY-3 gyro lines 0.07/0.04/0.04 arcsec (Tang et al. 2020, Table 1)")
    jitter_band_arcsec: _mag(3600.0) = Field(
        0.2, description="rms of the Gauss-Markov jitter band the attitude data miss, arcsec per axis: "
                         "0.1-10 Hz content below ZY-3's 1-3 arcsec image jitter (Tong et al. 2015; "
                         "engineering estimate)")
    time_tag_bias_ms: _mag(1000.0) = Field(
        0.1, description="star-tracker time-tag bias, ms: 0.1-1 ms (a mapping camera's synchronisation went "
                         "from 1 ms to 20 us; Swarm removes a fixed tracker delay)")
    gaia_pm_error_sigmas: _mag(100.0) = Field(
        1.6, description="world stars on Gaia DR3 positions, hip2 proper motions perturbed by this many formal "
                         "errors: hip2 minus Gaia at J2016 is 1.5-3 times hip2's formal error (van Leeuwen 2007 "
                         "vs Gaia DR3)")
    lateral_colour_px: _mag(100.0) = Field(
        0.1, description="star-colour centroid shift at the line's end, 3500 K minus 20000 K star, px: "
                         "0.04-0.14 px for a traced lens with silicon QE, 0.02-0.15 px for TDI lenses")
    line_rate_mismatch_percent: _mag(40.0) = Field(
        0.4, description="scan rate above the rate matched to the line period, %: 0.2-2 % for 0.001-0.005 "
                         "deg/s rate control (Guo et al. 2013); 0.005 deg/s at the 1.15 deg/s star scan")


class LineCamWorld(WorldBase):
    """The line camera's world: effects and the settings of their model forms."""

    effects: LineCamEffects = LineCamEffects()
    jitter_band_tau_s: Annotated[float, Field(gt=0.0, allow_inf_nan=False)] = Field(
        0.05, description="correlation time of the Gauss-Markov jitter band, s (corner 1/(2 pi tau) = 3.2 Hz)")

    @model_validator(mode="before")
    @classmethod
    def _gaia_sky_seed_retired(cls, data: Any) -> Any:
        # the one fixed draw of the Gaia world's proper-motion errors is now each trial's
        # instrument draw (validation.instrument_seed): refuse the old field, saying so
        if isinstance(data, dict) and "gaia_sky_seed" in data:
            raise PydanticCustomError(
                "retired_field", "gaia_sky_seed is replaced by validation.instrument_seed (the Gaia world's "
                "proper-motion errors are drawn per trial, or pinned by an integer there); remove it",
                {"field": "gaia_sky_seed"})
        return data


# --------------------------------------------------------------------------- distortion
def extra_distortion_px(u_px, v_px, *, k3_edge_px: float, prism_edge_px: float, r_norm_px: float):
    """The correction beyond Brown, px: ``(Ex, Ey)`` at measured ``(x', y')`` px (module docstring).

    ``Ex = r_n [k3 X r^6 + s1 r^2 + s2 r^4]``, ``Ey = r_n [k3 Y r^6 + s3 r^2 + s4 r^4]``,
    ``X = x'/r_n``, ``r^2 = X^2 + Y^2``, ``r_n k3 = k3_edge_px``, ``r_n s_i = prism_edge_px / 2``.
    """
    X = np.asarray(u_px, dtype=float) / r_norm_px
    Y = np.asarray(v_px, dtype=float) / r_norm_px
    r2 = X * X + Y * Y
    radial = k3_edge_px * r2**3
    prism = 0.5 * prism_edge_px * (r2 + r2 * r2)
    return radial * X + prism, radial * Y + prism


# --------------------------------------------------------------------------- colour
def chromatic_centroid(weight_per_nm, wavelength_nm, position_px) -> float:
    """``int x(lambda) w(lambda) dlambda / int w dlambda`` (trapezoid on the grid): the centroid of a
    superposition of monochromatic images of weights ``w = S QE`` at positions ``x(lambda)``."""
    w = np.asarray(weight_per_nm, dtype=float)
    lam = np.asarray(wavelength_nm, dtype=float)
    return float(np.trapezoid(w * np.asarray(position_px, dtype=float), lam) / np.trapezoid(w, lam))


def _grid_and_qe(qe_model):
    lam = spectra.wavelength_grid_nm(start_nm=300.0, end_nm=1100.0, step_nm=2.0)
    qe = spectra.cmos_qe_array(wavelength_nm=lam, peak_qe=qe_model.peak_qe, peak_nm=qe_model.peak_nm,
                               blue_cutoff_nm=qe_model.blue_cutoff_nm, red_cutoff_nm=qe_model.red_cutoff_nm)
    return lam, qe


@lru_cache(maxsize=8)
def _colour_table(qe_model):
    lam, qe = _grid_and_qe(qe_model)
    g = (LAMBDA_REF_NM / lam) ** 2
    temps = np.geomspace(2000.0, 50000.0, 96)
    out = np.empty(temps.size)
    for i, t in enumerate(temps):
        flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=float(t), wavelength_nm=lam)
        out[i] = chromatic_centroid(flux * qe, lam, g)
    return temps, out


def mean_colour_weight(qe_model, temperature_k) -> np.ndarray:
    """``gbar(T)``: the Cauchy shape ``(550 nm/lambda)^2`` averaged over a blackbody star's detected
    photons (``S_T QE``), interpolated in log T on a 96-point table (2000-50000 K)."""
    temps, table = _colour_table(qe_model)
    t = np.clip(np.asarray(temperature_k, dtype=float), temps[0], temps[-1])
    return np.interp(np.log(t), np.log(temps), table)


def lateral_colour_px(qe_model, temperature_k, *, edge_px: float) -> np.ndarray:
    """Centroid shift at the line's end (px, per unit ``r/r_n``) of stars at ``temperature_k``
    against a solar star, scaled so that the 3500 K minus 20000 K shift is ``edge_px``:
    ``edge_px (gbar(T) - gbar(T_sun)) / (gbar(3500) - gbar(20000))``."""
    g = mean_colour_weight(qe_model, np.array([T_COOL_K, T_HOT_K, T_SUN_K]))
    kappa = edge_px / (g[0] - g[1])
    return kappa * (mean_colour_weight(qe_model, temperature_k) - g[2])


# --------------------------------------------------------------------------- jitter
def effects_generator(seed_sequence: np.random.SeedSequence) -> np.random.Generator:
    """The effects' own random stream of a trial: a child of the trial's seed sequence by a
    fixed spawn key, so switching effects on or off moves none of the trial's other draws."""
    return np.random.default_rng(np.random.SeedSequence(entropy=seed_sequence.entropy,
                                                        spawn_key=tuple(seed_sequence.spawn_key) + (0xE4FEC7,)))


def jitter_components(effects: LineCamEffects, tau_s: float) -> list[dict]:
    """The jitter of one axis as :class:`simcam.noise_processes.NoiseComponent` specs (rad)."""
    comps = [dict(kind="tone", amplitude=effects.jitter_tones_arcsec * r * RAD_PER_ARCSEC, frequency_hz=f)
             for f, r in zip(JITTER_TONES_HZ, JITTER_TONE_RATIOS)]
    comps.append(dict(kind="gauss_markov", amplitude=effects.jitter_band_arcsec * RAD_PER_ARCSEC, tau_s=tau_s))
    return comps


class Jitter:
    """Three-axis attitude jitter (rad) of one trial, sampled every :data:`JITTER_STEP_S` over
    ``[t0_s, t1_s]`` and linearly interpolated; each axis an independent draw of
    :func:`jitter_components` through :func:`simcam.noise_processes.sample`."""

    def __init__(self, effects: LineCamEffects, tau_s: float, rng: np.random.Generator, t0_s: float, t1_s: float):
        n = int(np.ceil((t1_s - t0_s) / JITTER_STEP_S)) + 2
        self.t0_s = float(t0_s)
        self.tau_s = JITTER_STEP_S * np.arange(n)  # since t0_s, exact
        comps = jitter_components(effects, tau_s)
        self.samples = np.column_stack([sample(child, self.tau_s, comps) for child in rng.spawn(3)])

    def __call__(self, t_s) -> np.ndarray:
        """Jitter rotation vectors (n, 3), rad, at times ``t_s``."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float)) - self.t0_s
        return np.column_stack([np.interp(t, self.tau_s, self.samples[:, i]) for i in range(3)])
