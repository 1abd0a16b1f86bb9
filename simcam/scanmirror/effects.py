"""The scan-mirror world's unmodelled effects (seed 003): what a real GEO imager
carries that the lab's batch fit and compensation leave out.

The lab (``budget/scanmirror``: the published and improved estimators, the compensation
and the improved fit's stated covariance) models the star tracker as white noise of
``star_sensing.tracker_sigma_arcsec`` per dwell, the stars at their Hipparcos places, the
deviation as the scenario's sinusoid and the commanded angles as the mirror's. The world
adds, each with a magnitude (0 = off) whose source is in the field's description:

* **Star-tracker bias** (``tracker_bias_arcsec``): a constant small rotation of the
  tracker's attitude, drawn per instrument (:class:`Instrument`), N(0, b^2) per axis. Source: the
  CM-1 star-sensor on-orbit evaluation (2024) measured inter-tracker systematics of
  (6.9, -12.6, -1.6) and (-4.5, -27.2, 13.5) arcsec, rms 13.9 arcsec per axis between two
  trackers, so about 10 arcsec per tracker; the error terms of ECSS-E-ST-60-20C
  (Rev. 1/2, "Star sensors terminology and performance specification": bias,
  low-frequency and high-frequency spatial error, temporal noise).
* **FOV spatial error** (``tracker_fov_error_arcsec``, time constant
  ``world.tracker_fov_tau_s``): the stars drift through the tracker's field at the orbit
  rate (15 arcsec/s), so the tracker's spatial (calibration) error of 0.3-1 arcsec
  (ECSS-E-ST-60-20C's definition; size: engineering estimate) becomes a first-order
  Gauss-Markov error of correlation time L / (15 arcsec/s), 24-240 s for L = 0.1-1 deg.
* **Orbit-periodic low-frequency error** (``tracker_lfe_arcsec``): thermo-elastic,
  sum_{k<=3} (a_k cos k w t + b_k sin k w t), w the orbit rate, a_k, b_k ~ N(0, s^2/3) so
  the variance is s^2. Source: CM-1 inter-axis LFE 2.0 arcsec (3 sigma); SED36 LFE
  1.1 arcsec 3 sigma transverse (Ouaknine et al., Proc. SPIE 2018, doi:10.1117/12.2308086);
  Lai et al., Sensors 16:1669 (2016); Liu et al., Traitement du Signal 36 (2019).
* **Attitude knowledge correlated over the scan**: the same tracker process (bias, FOV
  error, LFE) continues through the area scans, so the lab's attitude knowledge there
  carries the error the dwell saw, correlated, on top of the lab's own per-scan white
  knowledge error (``attitude.knowledge_sigma_arcsec``, the lab's model, kept).
* **Gaia DR3 star places** (``gaia_offset_fraction``): the world's stars sit off the
  lab's Hipparcos places by Gaia DR3 minus Hipparcos offsets (Gaia Collaboration,
  Vallenari et al., A&A 674, A1, 2023; van Leeuwen, A&A 474, 653, 2007;
  :meth:`simcam.sky.gaia.GaiaMatch.offsets_mas`, J2016.0, tangent plane): each dwell star
  carries the offset of a catalogue star (to the magnitude limit) that the instrument
  draws, so that a population of instruments sees the population of catalogue errors
  (robust sigma about 20 mas per axis, tails to 1-2 arcsec for bright stars) rather than
  the one realisation of the paper's dwell. 1 = the offsets, 0 = the lab's catalogue;
  values between scale them.
* **Deviation drift beyond the seed's sinusoid** (``deviation_daily_offset_arcsec``,
  ``deviation_harmonic_fraction``): a per-trial offset N(0, o^2) per component (day-to-day
  non-repeatability < 10 urad, GOES-8/9: Ghaffarian et al., NASA NTRS 20010084974; Carr,
  Proc. SPIE 2812, doi:10.1117/12.254116) and 2nd and 3rd harmonics of the daily term at
  a fraction r of its amplitude (10-30 %, engineering estimate after the ELUG form of
  Carr and the FY-4A AGRI thermal-motion compensation, IEEE GRSL 2022), random phases
  per trial, about the seed's deviation axis.
* **Inductosyn encoder residual** (``encoder_residual_3sigma_arcsec``): the step and scan
  angles are read by round inductosyns with seed 001's error model
  (:class:`simcam.encoder.inductosyn.Inductosyn`, Dong et al., Infrared and Laser
  Engineering 48(10) 1013007, 2019): each axis's encoder is the seed-001 default encoder
  after its environmental drift (:func:`~simcam.encoder.inductosyn.apply_drift`, one
  drift seed per axis, drawn per instrument), compensated by the harmonic model fitted to the undrifted encoder
  (constant, mechanical orders 1-2, electrical orders 1-2, seed 001 eq. 9), and the
  residual scaled to the stated 3 sigma over the turn (seed 001 section 4.3: 2.7 arcsec
  after calibration, 5.4 arcsec after temperature cycling and vibration). The servo
  holds the reading at the command, so the true angle is ``command - e(command)`` (the
  error of this first-order inversion is e * de/dtheta < 0.01 arcsec).

With every magnitude 0 nothing here runs and the study's results are today's bit for bit.
The per-trial draws come from a child of the trial's generator spawned after the lab's
draws; the instrument's (:class:`Instrument`: encoders' drift draws, tracker bias, the
stars' catalogue offsets) from the instrument's own seed sequence
(``validation.instrument_seed``: None, a new instrument each trial; an integer, one pinned
instrument). Every effect draws its numbers whatever its magnitude (common random numbers
between robustness cases).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from pydantic import Field, model_validator

from simcam.effects import EffectsBase, WorldBase
from simcam.noise_processes import gauss_markov
from simcam.sky.gaia import gaia_match
from simcam.units import MAS_PER_RAD, RAD_PER_ARCSEC

__all__ = ["ScanMirrorEffects", "ScanMirrorWorld", "WorldEffects", "TrialEffects", "Instrument", "REMOVED_SETTINGS",
           "encoder_residual_arcsec", "tracker_error_series", "deviation_extra", "shift_directions"]

#: the harmonic orders of seed 001's compensation (eq. 9): mechanical and electrical 1-2, and a constant
_MECH_ORDERS = (1, 2)
_ELEC_ORDERS = (1, 2)
#: dense grid (deg) over the turn on which the compensation is fitted (once)
_ENC_GRID_STEP_DEG = 0.002
#: grid (deg) on which each drawn encoder's residual 3 sigma is taken (:func:`_encoder`)
_ENC_SIGMA_GRID_STEP_DEG = 0.025


class ScanMirrorEffects(EffectsBase):
    """Magnitudes of the scan-mirror world's unmodelled effects (0 = off; defaults sourced)."""

    tracker_bias_arcsec: float = Field(
        10.0, ge=0, le=600,
        description="1-sigma per axis of the star tracker's constant rotation (per trial): CM-1 star-sensor on-orbit "
                    "evaluation (2024), inter-tracker systematics (6.9, -12.6, -1.6) and (-4.5, -27.2, 13.5) arcsec, "
                    "rms 13.9 arcsec between two trackers, about 10 per tracker; ECSS-E-ST-60-20C bias term")
    tracker_fov_error_arcsec: float = Field(
        0.5, ge=0, le=60,
        description="1-sigma per axis of the tracker's FOV spatial error, Gauss-Markov in time as the stars drift at "
                    "15 arcsec/s: 0.3-1 arcsec (ECSS-E-ST-60-20C definition; size an engineering estimate)")
    tracker_lfe_arcsec: float = Field(
        0.67, ge=0, le=60,
        description="1-sigma per axis of the orbit-periodic (k <= 3) low-frequency error: CM-1 inter-axis LFE "
                    "2.0 arcsec 3 sigma (SED36: 1.1 arcsec 3 sigma, Ouaknine et al. 2018)")
    gaia_offset_fraction: float = Field(
        1.0, ge=0, le=1,
        description="fraction of the Gaia DR3 minus Hipparcos place offset the world's stars carry: 1 = Gaia DR3 "
                    "positions (Vallenari et al. 2023) with Hipparcos motions (van Leeuwen 2007), 0 = the lab's "
                    "Hipparcos")
    deviation_daily_offset_arcsec: float = Field(
        2.0, ge=0, le=600,
        description="1-sigma per component of the deviation's day-to-day offset: non-repeatability < 10 urad "
                    "(GOES-8/9, Ghaffarian et al., NTRS 20010084974; Carr 1996)")
    deviation_harmonic_fraction: float = Field(
        0.2, ge=0, le=1,
        description="2nd and 3rd harmonics of the daily deviation term, each this fraction of the first: "
                    "10-30 % (engineering estimate after Carr's ELUG form and FY-4A AGRI, IEEE GRSL 2022)")
    encoder_residual_3sigma_arcsec: float = Field(
        5.4, ge=0, le=600,
        description="3 sigma over the turn of each axis's inductosyn residual after harmonic compensation: seed 001 "
                    "(Dong et al. 2019) 2.7 arcsec after calibration, 5.4 arcsec after temperature cycling and "
                    "vibration")


class ScanMirrorWorld(WorldBase):
    """The scan-mirror world: effects' magnitudes and the settings of their model forms."""

    effects: ScanMirrorEffects = ScanMirrorEffects()
    tracker_fov_tau_s: float = Field(
        100.0, gt=0, le=1e6,
        description="correlation time of the FOV spatial error: L / (15 arcsec/s), 24-240 s for L = 0.1-1 deg")

    @model_validator(mode="before")
    @classmethod
    def _removed(cls, data):
        if isinstance(data, dict):
            for name, why in REMOVED_SETTINGS.items():
                if name in data:
                    raise ValueError(f"{name}: no longer a setting: {why}")
        return data


# --------------------------------------------------------------------------- encoder
def _harmonic_design(angle_deg, pole_pairs: int) -> np.ndarray:
    th = np.radians(np.asarray(angle_deg, float))
    cols = [np.ones_like(th)]
    for k in _MECH_ORDERS:
        cols += [np.cos(k * th), np.sin(k * th)]
    for k in _ELEC_ORDERS:
        cols += [np.cos(k * pole_pairs * th), np.sin(k * pole_pairs * th)]
    return np.stack(cols, -1)


@functools.lru_cache(maxsize=1)
def _compensation():
    """The seed-001 default encoder's scenario and the harmonic compensation (seed 001 eq. 9)
    fitted to the undrifted encoder on the dense grid: ``(scenario, coefficients)``."""
    from simcam.encoder.inductosyn import Inductosyn
    from simcam.encoder.inductosyn import default as default_scenario

    sc = default_scenario()
    grid = np.arange(0.0, 360.0, _ENC_GRID_STEP_DEG)
    X = _harmonic_design(grid, sc.encoder.pole_pairs)
    coef, *_ = np.linalg.lstsq(X, Inductosyn(params=sc.encoder).error_arcsec(angle_deg=grid), rcond=None)
    return sc, coef


@functools.lru_cache(maxsize=16)
def _encoder(drift_seed: int):
    """The flown encoder of drift draw ``drift_seed`` (:func:`~simcam.encoder.inductosyn.apply_drift`)
    and the 3 sigma (arcsec) over the turn of its residual after the compensation, taken on a
    uniform grid of 14400 points: exact for the harmonics below 7200 cycles a turn (the 8th
    electrical harmonic of 360 pole pairs has 2880; measured: the 3 sigma on it and on the
    0.002-deg grid agree to 1e-13 relative)."""
    from simcam.encoder.inductosyn import Inductosyn, apply_drift

    sc, coef = _compensation()
    flown = Inductosyn(params=apply_drift(params=sc.encoder, drift=sc.drift, seed=int(drift_seed)))
    grid = np.arange(0.0, 360.0, _ENC_SIGMA_GRID_STEP_DEG)
    resid = flown.error_arcsec(angle_deg=grid) - _harmonic_design(grid, sc.encoder.pole_pairs) @ coef
    return flown, 3.0 * float(np.std(resid))


def encoder_residual_arcsec(angle_deg, *, drift_seed: int, sigma3_arcsec: float) -> np.ndarray:
    """The compensated encoder's error (reading minus true angle, arcsec) at true angles
    ``angle_deg``: the drifted encoder's error minus the compensation, evaluated there, scaled
    so that its 3 sigma over the turn is ``sigma3_arcsec``."""
    sc, coef = _compensation()
    flown, s3 = _encoder(int(drift_seed))
    a = np.mod(np.asarray(angle_deg, float), 360.0)
    r = flown.error_arcsec(angle_deg=a) - _harmonic_design(a, sc.encoder.pole_pairs) @ coef
    return r * (sigma3_arcsec / s3)


# --------------------------------------------------------------------------- tracker and deviation
def tracker_error_series(rng: np.random.Generator, t_s, *, bias_arcsec: float, fov_arcsec: float, tau_s: float,
                         lfe_arcsec: float, orbit_rate_rad_s: float, bias_unit=None) -> dict:
    """The world's star-tracker error rotation (N, 3) (rad) at the times ``t_s`` (any order):
    bias + Gauss-Markov FOV error + orbit-periodic LFE (module docstring). Every component
    draws its numbers whatever its magnitude; the bias is ``bias_arcsec`` times
    ``bias_unit`` (3,) (the instrument's standard normal draws, :class:`Instrument`) or, without
    it, times draws of ``rng``. Returns ``{"total", "bias", "fov", "lfe"}``."""
    t = np.asarray(t_s, float)
    g_bias, g_fov, g_lfe = rng.spawn(3)
    unit = g_bias.standard_normal(3) if bias_unit is None else np.asarray(bias_unit, float)
    bias = bias_arcsec * RAD_PER_ARCSEC * unit
    tu, inv = np.unique(t, return_inverse=True)
    fov = np.stack([gauss_markov(g, tu, 1.0, tau_s) for g in g_fov.spawn(3)], -1)[inv] * (fov_arcsec * RAD_PER_ARCSEC)
    ab = g_lfe.standard_normal((3, 2, 3)) * (lfe_arcsec * RAD_PER_ARCSEC / np.sqrt(3.0))  # (k, cos/sin, axis)
    k = np.arange(1, 4)
    wt = np.multiply.outer(t, k * orbit_rate_rad_s)  # (N, 3 harmonics)
    lfe = np.cos(wt) @ ab[:, 0, :] + np.sin(wt) @ ab[:, 1, :]
    return {"total": bias + fov + lfe, "bias": bias, "fov": fov, "lfe": lfe}


def deviation_extra(t_s, *, offset_rad, variable_rad: float, fraction: float, period_s: float, phase_rad: float,
                    axis_rad: float, harmonic_phases_rad) -> tuple[np.ndarray, np.ndarray]:
    """``(dtau_x, dtau_y)`` (rad) the world adds to the seed's deviation: the offset (2,) and
    ``dtau_v r sum_{k=2,3} sin(k (2 pi t / P + phase) + phi_k)`` about the deviation axis."""
    t = np.asarray(t_s, float)
    u = 2 * np.pi * t / period_s + phase_rad
    h = variable_rad * fraction * sum(np.sin(k * u + p) for k, p in zip((2, 3), harmonic_phases_rad))
    return offset_rad[0] + h * np.cos(axis_rad), offset_rad[1] + h * np.sin(axis_rad)


# --------------------------------------------------------------------------- one instrument
@dataclass(frozen=True)
class Instrument:
    """One instrument's properties, drawn from its own seed sequence
    (``validation.instrument_seed``: :func:`budget.runner.study.instrument_seed_sequence`):
    the drift draws of the step- and scan-axis inductosyns, the star tracker's bias direction
    (standard normal per axis, scaled by ``tracker_bias_arcsec``) and, per dwell star, the
    catalogue star whose Gaia DR3 minus Hipparcos offset it carries (a row of the population
    of :meth:`WorldEffects.offset_population`)."""

    step_drift_seed: int
    scan_drift_seed: int
    tracker_bias_unit: np.ndarray
    star_rows: tuple

    @classmethod
    def draw(cls, seed_sequence: np.random.SeedSequence, *, stars_per_dwell, population: int) -> Instrument:
        """Every property drawn whatever its magnitude (common random numbers between cases)."""
        g_enc, g_bias, g_star = (np.random.default_rng(s) for s in seed_sequence.spawn(3))
        step, scan = (int(x) for x in g_enc.integers(0, 2**31 - 1, 2))
        rows = tuple(g_star.integers(0, max(population, 1), int(n)) for n in stars_per_dwell)
        return cls(step, scan, g_bias.standard_normal(3), rows)


def _tangent_axes(u) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors of increasing right ascension and declination at the directions ``u`` (n, 3)."""
    ra = np.arctan2(u[:, 1], u[:, 0])
    dec = np.arcsin(np.clip(u[:, 2], -1.0, 1.0))
    e_ra = np.column_stack([-np.sin(ra), np.cos(ra), np.zeros_like(ra)])
    e_dec = np.column_stack([-np.sin(dec) * np.cos(ra), -np.sin(dec) * np.sin(ra), np.cos(dec)])
    return e_ra, e_dec


def shift_directions(u, offsets_rad, fraction: float) -> np.ndarray:
    """The unit directions ``u`` (n, 3) moved by ``fraction`` of the tangent-plane offsets
    ``offsets_rad`` (n, 2) (along alpha cos delta, delta) and normalised."""
    e_ra, e_dec = _tangent_axes(u)
    v = u + fraction * (offsets_rad[:, :1] * e_ra + offsets_rad[:, 1:] * e_dec)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


# --------------------------------------------------------------------------- one trial's world
@dataclass
class TrialEffects:
    """One trial's draws: tracker error at each dwell's frames (list of (f, 3) rad) and at the
    scan samples ((n, 3) rad), the deviation's extra terms, the instrument."""

    tracker_dwell: list
    tracker_scan: np.ndarray
    tracker_parts: dict
    deviation_offset_rad: np.ndarray
    harmonic_phases_rad: np.ndarray
    parent: WorldEffects
    instrument: Instrument

    def deviation(self, t_s, base, *, variable_rad, period_s, phase_rad, axis_rad):
        """The world's deviation: ``base = (dtx, dty)`` of the seed's sinusoid plus the extras."""
        e = self.parent.effects
        if e.deviation_daily_offset_arcsec == 0 and e.deviation_harmonic_fraction == 0:
            return base
        dx, dy = deviation_extra(t_s, offset_rad=self.deviation_offset_rad, variable_rad=variable_rad,
                                 fraction=e.deviation_harmonic_fraction, period_s=period_s, phase_rad=phase_rad,
                                 axis_rad=axis_rad, harmonic_phases_rad=self.harmonic_phases_rad)
        return base[0] + dx, base[1] + dy

    def star_offsets_rad(self, k: int) -> np.ndarray:
        """The Gaia DR3 minus Hipparcos offsets (n, 2) (rad; alpha cos delta, delta) the
        stars of dwell ``k`` carry in this instrument's sky."""
        return self.parent.offset_population[self.instrument.star_rows[k]]

    def world_dwell(self, k: int):
        """Dwell ``k`` as the world has it: its stars moved by their catalogue offsets (if on)
        and the mirror at its true angles."""
        d = self.parent.dwells[k]
        f = self.parent.effects.gaia_offset_fraction
        if f > 0:
            d = dataclasses.replace(d, apparent_I=shift_directions(d.apparent_I, self.star_offsets_rad(k), f))
        a, b = self.true_angles(np.array([d.alpha_rad]), np.array([d.beta_rad]))
        return dataclasses.replace(d, alpha_rad=float(a[0]), beta_rad=float(b[0]))

    def true_angles(self, alpha_rad, beta_rad):
        """The mirror's true step and scan angles when the servos hold this instrument's
        encoder readings at the commanded ``alpha_rad, beta_rad``: ``command - e(command)``."""
        s3 = self.parent.effects.encoder_residual_3sigma_arcsec
        if s3 == 0:
            return alpha_rad, beta_rad
        ins = self.instrument
        ea = encoder_residual_arcsec(np.rad2deg(alpha_rad), drift_seed=ins.step_drift_seed, sigma3_arcsec=s3)
        eb = encoder_residual_arcsec(np.rad2deg(beta_rad), drift_seed=ins.scan_drift_seed, sigma3_arcsec=s3)
        return alpha_rad - ea * RAD_PER_ARCSEC, beta_rad - eb * RAD_PER_ARCSEC


#: the world settings that instruments drawn per trial replaced, and what replaces them
REMOVED_SETTINGS = {
    "encoder_step_drift_seed": "the encoders' drift is drawn per instrument; validation.instrument_seed pins one",
    "encoder_scan_drift_seed": "the encoders' drift is drawn per instrument; validation.instrument_seed pins one",
}


class WorldEffects:
    """The scenario's world effects, prepared once per scenario (the simulator side: it reads
    ``scenario.world``; the lab never does).

    ``dwells`` are the lab's dwells (:func:`simcam.scanmirror.stars.find_dwell_stars`, Hipparcos);
    :meth:`TrialEffects.world_dwell` gives a dwell as one trial's world has it.
    """

    def __init__(self, scenario, world, dwells):
        self.settings = scenario.world
        self.effects = scenario.world.effects
        self.on = bool(self.effects.active())
        self.orbit_rate_rad_s = world.orbit_rate_rad_s
        self.dwells = list(dwells)
        self._mag_limit = scenario.star_sensing.mag_limit

    @functools.cached_property
    def offset_population(self) -> np.ndarray:
        """The Gaia DR3 minus Hipparcos place offsets (m, 2) (rad; alpha cos delta, delta, at
        J2016.0) of every Hipparcos star to the scenario's magnitude limit
        (:meth:`simcam.sky.gaia.GaiaMatch.offsets_mas`); 0 for a star without a Gaia match,
        which keeps its Hipparcos place in the world (:func:`simcam.sky.gaia.gaia_world`)."""
        if not (self.on and self.effects.gaia_offset_fraction > 0):
            return np.zeros((1, 2))
        dx, dy = gaia_match(self._mag_limit).offsets_mas()
        return np.nan_to_num(np.column_stack([dx, dy]), nan=0.0) / MAS_PER_RAD

    def draw(self, rng: np.random.Generator, scan_t_s, instrument: np.random.SeedSequence) -> TrialEffects:
        """One trial's draws from ``rng`` (a child of the trial's generator) and its
        instrument's from ``instrument`` (:class:`Instrument`)."""
        e, s = self.effects, self.settings
        ins = Instrument.draw(instrument, stars_per_dwell=[d.hip.size for d in self.dwells],
                              population=self.offset_population.shape[0])
        g_tr, g_dev = rng.spawn(2)
        frames = [d.frame_t_s for d in self.dwells]
        t_all = np.concatenate(frames + [np.asarray(scan_t_s, float)])
        tr = tracker_error_series(g_tr, t_all, bias_arcsec=e.tracker_bias_arcsec,
                                  fov_arcsec=e.tracker_fov_error_arcsec, tau_s=s.tracker_fov_tau_s,
                                  lfe_arcsec=e.tracker_lfe_arcsec, orbit_rate_rad_s=self.orbit_rate_rad_s,
                                  bias_unit=ins.tracker_bias_unit)
        out, k = [], 0
        for f in frames:
            out.append(tr["total"][k:k + f.size])
            k += f.size
        offset = e.deviation_daily_offset_arcsec * RAD_PER_ARCSEC * g_dev.standard_normal(2)
        phases = g_dev.uniform(0.0, 2 * np.pi, 2)
        return TrialEffects(out, tr["total"][k:], tr, offset, phases, self, ins)
