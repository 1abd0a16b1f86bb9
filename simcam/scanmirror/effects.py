"""The scan-mirror world's unmodelled effects (seed 003): what a real GEO imager
carries that the lab's batch fit and compensation leave out.

The lab (``budget/scanmirror``: the published and improved estimators, the compensation
and the improved fit's stated covariance) models the star tracker as white noise of
``star_sensing.tracker_sigma_arcsec`` per dwell, the stars at their Hipparcos places, the
deviation as the scenario's sinusoid and the commanded angles as the mirror's. The world
adds, each with a magnitude (0 = off) whose source is in the field's description:

* **Star-tracker bias** (``tracker_bias_arcsec``): a constant small rotation of the
  tracker's attitude, drawn per trial (one instrument), N(0, b^2) per axis. Source: the
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
* **Gaia DR3 star places** (``gaia_offset_fraction``): the world's stars sit on their
  Gaia DR3 positions (Gaia Collaboration, Vallenari et al., A&A 674, A1, 2023) with the
  Hipparcos motions (van Leeuwen, A&A 474, 653, 2007; :func:`simcam.sky.gaia.gaia_world`);
  the lab keeps Hipparcos. 1 = the real offsets (robust sigma about 20 mas per axis at
  2012, tails to 1-2 arcsec for bright stars), 0 = the lab's catalogue; values between
  scale the world-minus-lab offset.
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
  drift seed per axis), compensated by the harmonic model fitted to the undrifted encoder
  (constant, mechanical orders 1-2, electrical orders 1-2, seed 001 eq. 9), and the
  residual scaled to the stated 3 sigma over the turn (seed 001 section 4.3: 2.7 arcsec
  after calibration, 5.4 arcsec after temperature cycling and vibration). The servo
  holds the reading at the command, so the true angle is ``command - e(command)`` (the
  error of this first-order inversion is e * de/dtheta < 0.01 arcsec).

With every magnitude 0 nothing here runs and the study's results are today's bit for bit.
The per-trial draws come from a child of the trial's generator spawned after the lab's
draws, and every effect draws its numbers whatever its magnitude (common random numbers
between robustness cases).
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np
from pydantic import Field

from simcam.effects import EffectsBase, WorldBase
from simcam.noise_processes import gauss_markov
from simcam.sky.apparent import apparent_directions
from simcam.sky.gaia import gaia_world
from simcam.units import RAD_PER_ARCSEC

__all__ = ["ScanMirrorEffects", "ScanMirrorWorld", "WorldEffects", "TrialEffects", "encoder_residual_arcsec",
           "tracker_error_series", "deviation_extra"]

#: the harmonic orders of seed 001's compensation (eq. 9): mechanical and electrical 1-2, and a constant
_MECH_ORDERS = (1, 2)
_ELEC_ORDERS = (1, 2)
#: dense grid (deg) over the turn on which the compensation is fitted, the residual's 3 sigma
#: taken and the residual tabulated; linear interpolation between its points errs by at most
#: h^2 k^2 / 8 of a harmonic of wavenumber k: 1.3e-3 of it for the 8th electrical harmonic
#: (k = 8 x 360 per turn)
_ENC_GRID_STEP_DEG = 0.002


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
    encoder_step_drift_seed: int = Field(1, ge=0, description="drift draw of the step-axis (alpha) encoder")
    encoder_scan_drift_seed: int = Field(2, ge=0, description="drift draw of the scan-axis (beta) encoder")


# --------------------------------------------------------------------------- encoder
def _harmonic_design(angle_deg, pole_pairs: int) -> np.ndarray:
    th = np.radians(np.asarray(angle_deg, float))
    cols = [np.ones_like(th)]
    for k in _MECH_ORDERS:
        cols += [np.cos(k * th), np.sin(k * th)]
    for k in _ELEC_ORDERS:
        cols += [np.cos(k * pole_pairs * th), np.sin(k * pole_pairs * th)]
    return np.stack(cols, -1)


@functools.lru_cache(maxsize=8)
def _encoder(drift_seed: int):
    """The seed-001 encoder's residual after drift and compensation, tabulated over the turn
    (grid deg, residual arcsec), and its 3 sigma (arcsec): the drifted encoder's error
    (:meth:`Inductosyn.error_arcsec`) minus the compensation fitted to the undrifted one."""
    from simcam.encoder.inductosyn import Inductosyn, apply_drift
    from simcam.encoder.inductosyn import default as default_scenario

    sc = default_scenario()
    calibrated = Inductosyn(params=sc.encoder)
    flown = Inductosyn(params=apply_drift(params=sc.encoder, drift=sc.drift, seed=drift_seed))
    grid = np.arange(0.0, 360.0, _ENC_GRID_STEP_DEG)
    X = _harmonic_design(grid, sc.encoder.pole_pairs)
    coef, *_ = np.linalg.lstsq(X, calibrated.error_arcsec(angle_deg=grid), rcond=None)
    resid = flown.error_arcsec(angle_deg=grid) - X @ coef
    return np.append(grid, 360.0), np.append(resid, resid[0]), 3.0 * float(np.std(resid))


def encoder_residual_arcsec(angle_deg, *, drift_seed: int, sigma3_arcsec: float) -> np.ndarray:
    """The compensated encoder's error (reading minus true angle, arcsec) at true angles
    ``angle_deg``, scaled so that its 3 sigma over the turn is ``sigma3_arcsec`` (linear
    interpolation in the residual tabulated every 0.002 deg)."""
    grid, resid, s3 = _encoder(int(drift_seed))
    # the table closes the turn (its last point is the first at 360 deg): interpolation on [0, 360)
    r = np.interp(np.mod(np.asarray(angle_deg, float), 360.0), grid, resid)
    return r * (sigma3_arcsec / s3)


# --------------------------------------------------------------------------- tracker and deviation
def tracker_error_series(rng: np.random.Generator, t_s, *, bias_arcsec: float, fov_arcsec: float, tau_s: float,
                         lfe_arcsec: float, orbit_rate_rad_s: float) -> dict:
    """The world's star-tracker error rotation (N, 3) (rad) at the times ``t_s`` (any order):
    bias + Gauss-Markov FOV error + orbit-periodic LFE (module docstring). Every component
    draws its numbers whatever its magnitude. Returns ``{"total", "bias", "fov", "lfe"}``."""
    t = np.asarray(t_s, float)
    g_bias, g_fov, g_lfe = rng.spawn(3)
    bias = bias_arcsec * RAD_PER_ARCSEC * g_bias.standard_normal(3)
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


# --------------------------------------------------------------------------- one trial's world
@dataclass
class TrialEffects:
    """One trial's draws: tracker error at each dwell's frames (list of (f, 3) rad) and at the
    scan samples ((n, 3) rad), the deviation's extra terms, the encoders."""

    tracker_dwell: list
    tracker_scan: np.ndarray
    tracker_parts: dict
    deviation_offset_rad: np.ndarray
    harmonic_phases_rad: np.ndarray
    parent: WorldEffects

    def deviation(self, t_s, base, *, variable_rad, period_s, phase_rad, axis_rad):
        """The world's deviation: ``base = (dtx, dty)`` of the seed's sinusoid plus the extras."""
        e = self.parent.effects
        if e.deviation_daily_offset_arcsec == 0 and e.deviation_harmonic_fraction == 0:
            return base
        dx, dy = deviation_extra(t_s, offset_rad=self.deviation_offset_rad, variable_rad=variable_rad,
                                 fraction=e.deviation_harmonic_fraction, period_s=period_s, phase_rad=phase_rad,
                                 axis_rad=axis_rad, harmonic_phases_rad=self.harmonic_phases_rad)
        return base[0] + dx, base[1] + dy


class WorldEffects:
    """The scenario's world effects, prepared once per scenario (the simulator side: it reads
    ``scenario.world``; the lab never does).

    ``dwells`` are the lab's dwells (:func:`simcam.scanmirror.stars.find_dwell_stars`, Hipparcos);
    :meth:`world_dwell` gives the same dwell with the world's star places.
    """

    def __init__(self, scenario, world, dwells):
        self.settings = scenario.world
        self.effects = scenario.world.effects
        self.on = bool(self.effects.active())
        self.orbit_rate_rad_s = world.orbit_rate_rad_s
        self._dwells = list(dwells)
        self._world_dwells = None
        if self.on and self.effects.gaia_offset_fraction > 0:
            self._world_dwells = [self._gaia_dwell(d, scenario) for d in self._dwells]

    def _gaia_dwell(self, d, scenario):
        from astropy.time import Time, TimeDelta

        cat = gaia_world(scenario.star_sensing.mag_limit)
        rows = np.searchsorted(cat.hip, d.hip)
        if not np.array_equal(cat.hip[rows], d.hip):  # pragma: no cover - same Hipparcos stars by construction
            raise RuntimeError("the world's Gaia catalogue lacks a dwell star")
        nf = d.frame_t_s.size
        tmid = Time(scenario.orbit.epoch_utc, scale="utc") + TimeDelta(float(d.frame_t_s[nf // 2]), format="sec")
        rm, vm = d.r_km[nf // 2], d.v_km_s[nf // 2]
        u_g = apparent_directions(cat.select(rows), tmid, observer_position_km=rm, observer_velocity_km_s=vm)
        f = self.effects.gaia_offset_fraction
        u = d.apparent_I + f * (u_g - d.apparent_I)
        return dataclasses.replace(d, apparent_I=u / np.linalg.norm(u, axis=-1, keepdims=True))

    def world_dwell(self, k: int, alpha_rad: float | None = None, beta_rad: float | None = None):
        """Dwell ``k`` as the world has it: Gaia places (if on) and the true mirror angles."""
        d = self._world_dwells[k] if self._world_dwells is not None else self._dwells[k]
        a, b = self.true_angles(np.array([d.alpha_rad]), np.array([d.beta_rad]))
        return dataclasses.replace(d, alpha_rad=float(a[0]), beta_rad=float(b[0]))

    def true_angles(self, alpha_rad, beta_rad):
        """The mirror's true step and scan angles when the servos hold the encoder readings at
        the commanded ``alpha_rad, beta_rad``: ``command - e(command)``."""
        s3 = self.effects.encoder_residual_3sigma_arcsec
        if s3 == 0:
            return alpha_rad, beta_rad
        ea = encoder_residual_arcsec(np.rad2deg(alpha_rad), drift_seed=self.settings.encoder_step_drift_seed,
                                     sigma3_arcsec=s3)
        eb = encoder_residual_arcsec(np.rad2deg(beta_rad), drift_seed=self.settings.encoder_scan_drift_seed,
                                     sigma3_arcsec=s3)
        return alpha_rad - ea * RAD_PER_ARCSEC, beta_rad - eb * RAD_PER_ARCSEC

    def draw(self, rng: np.random.Generator, scan_t_s) -> TrialEffects:
        """One trial's draws from ``rng`` (a child of the trial's generator)."""
        e, s = self.effects, self.settings
        g_tr, g_dev = rng.spawn(2)
        frames = [d.frame_t_s for d in self._dwells]
        t_all = np.concatenate(frames + [np.asarray(scan_t_s, float)])
        tr = tracker_error_series(g_tr, t_all, bias_arcsec=e.tracker_bias_arcsec,
                                  fov_arcsec=e.tracker_fov_error_arcsec, tau_s=s.tracker_fov_tau_s,
                                  lfe_arcsec=e.tracker_lfe_arcsec, orbit_rate_rad_s=self.orbit_rate_rad_s)
        out, k = [], 0
        for f in frames:
            out.append(tr["total"][k:k + f.size])
            k += f.size
        offset = e.deviation_daily_offset_arcsec * RAD_PER_ARCSEC * g_dev.standard_normal(2)
        phases = g_dev.uniform(0.0, 2 * np.pi, 2)
        return TrialEffects(out, tr["total"][k:], tr, offset, phases, self)
