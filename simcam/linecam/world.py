"""The world of seed 004: stars crossing a TDI line camera on a scanning spacecraft.

:func:`sky_strip` finds the catalogue stars around the strip and their apparent
directions (through :mod:`simcam.sky`, astropy/ERFA: proper motion, parallax and
aberration of light for the spacecraft as observer), :func:`image_passes` images them
through the true camera (crossing times of the line, motion during the TDI exposure,
the TDI stages, the detector's noise) and returns the windows of the output image around
each star, and :class:`AttitudeReports` gives the attitude a star tracker and gyros would
report at any time (the truth plus white knowledge noise).

Aberration during a pass: the apparent directions are computed by astropy once per pass
(at its middle); the change of the spacecraft's velocity ``dv`` during the pass (a few
m/s) is applied with the first-order formula ``u' = u + dv/c - (u . dv/c) u``
(:func:`simcam.sky.apparent.aberration_first_order`), whose error is
``|v| |dv| / c^2 < 1e-10`` rad. Stars cross the line within a fraction of a second of the
crossing time predicted for the nominal camera; the misalignment changes it by
``|R_u| / w`` (< 0.1 s), over which the apparent direction changes by < 0.1 mas, so each
star's direction is taken at its nominal crossing time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation

from simcam import detector as _det
from simcam.sky.apparent import aberration_first_order, apparent_directions
from simcam.sky.catalogue import EPOCH_JYEAR, Catalogue, hipparcos
from simcam.sky.gaia import GAIA_EPOCH_JYEAR, gaia_match, gaia_world
from simcam.units import ARCSEC_PER_RAD, MAS_PER_RAD

from . import kernels as _k
from .attitude import ScanPlan, orbit_state, rodrigues, scan_plan
from .camera import CameraTruth
from .effects import Jitter, lateral_colour_px
from .scenario import LineCamScenario
from .signal import star_electron_rate, teff_from_b_v

__all__ = ["SkyStrip", "sky_strip", "world_sky_strip", "gaia_pm_offsets", "strip_radius_rad", "PassImages",
           "image_passes",
           "AttitudeReports", "attitude_reports", "world_jitter", "crossing_times", "SUBSTEPS"]

#: midpoint steps per line period in the TDI rendering
SUBSTEPS = 4


def strip_radius_rad(scenario: LineCamScenario) -> float:
    """Radius of a cone that holds the strip and a margin of a tenth of the field."""
    cam = scenario.camera
    half_across = 0.5 * cam.n_pixels * cam.pitch_mm / cam.focal_length_mm
    half_across += 0.5 * scenario.observation.passes * scenario.observation.shift_px * cam.pitch_mm / cam.focal_length_mm
    half_along = 0.5 * math.radians(scenario.stars.strip_length_deg)
    return math.hypot(half_across, half_along) * 1.1


@dataclass(frozen=True)
class SkyStrip:
    """Catalogue stars around a strip and their apparent directions at each pass.

    Attributes
    ----------
    cat : Catalogue
        The stars (brighter than the magnitude limit asked for).
    directions : numpy.ndarray (P, M, 3)
        Apparent unit vectors (GCRS) at the middle of each pass.
    velocity_km_s : numpy.ndarray (P, 3)
        The spacecraft's geocentric velocity at the middle of each pass.
    plan : ScanPlan
    """

    cat: Catalogue
    directions: np.ndarray
    velocity_km_s: np.ndarray | None
    plan: ScanPlan
    scenario: LineCamScenario

    def at(self, pass_index, star_index, t_s) -> np.ndarray:
        """Apparent directions of stars ``star_index`` in passes ``pass_index`` at times
        ``t_s`` (the pass's direction plus the first-order differential aberration of the
        spacecraft's change of velocity; none when built without aberration)."""
        a = self.directions[pass_index, star_index]
        if self.velocity_km_s is None:
            return a
        _, v = orbit_state(self.scenario, t_s)
        return aberration_first_order(a, v - self.velocity_km_s[pass_index])


def sky_strip(scenario: LineCamScenario, *, ra_deg: float, dec_deg: float, mag_limit: float,
              aberration: bool = True, parallax: bool = True, proper_motion: bool = True,
              gaia: bool = False) -> SkyStrip:
    """The stars (V <= ``mag_limit``) around the strip centred at (ra, dec) and their
    apparent directions for each pass (through :func:`simcam.sky.apparent.apparent_directions`;
    cached per scenario and arguments).

    The stars are Hipparcos's (the lab's table) unless ``gaia``: then the world's Gaia DR3
    catalogue with hip2's proper motions (:func:`simcam.sky.gaia.gaia_world`, unperturbed; each
    trial's perturbation is :func:`gaia_pm_offsets`)."""
    return _sky_strip(scenario, float(ra_deg), float(dec_deg), float(mag_limit), bool(aberration),
                      bool(parallax), bool(proper_motion), bool(gaia))


def world_sky_strip(scenario: LineCamScenario, *, ra_deg: float, dec_deg: float,
                    rng: np.random.Generator | None = None) -> SkyStrip:
    """The stars the world images (V <= ``stars.world_mag_limit``, every apparent-place term),
    from the catalogue of the world's ``gaia_pm_error_sigmas`` effect: Hipparcos when it is 0;
    else Gaia DR3 with hip2's proper motions perturbed by a draw from ``rng`` (the instrument's
    stream of the trial, ``validation.instrument_seed``), applied to the cached strip by
    :func:`gaia_pm_offsets`."""
    k_sig = scenario.world.effects.gaia_pm_error_sigmas
    mag = scenario.stars.world_mag_limit
    strip = sky_strip(scenario, ra_deg=ra_deg, dec_deg=dec_deg, mag_limit=mag, gaia=k_sig > 0)
    if k_sig == 0:
        return strip
    if rng is None:
        raise ValueError("rng: the world's Gaia proper-motion errors need the trial's instrument generator")
    return gaia_pm_offsets(strip, mag, k_sig, rng)


def gaia_pm_offsets(strip: SkyStrip, mag_limit: float, pm_error_sigmas: float, rng: np.random.Generator) -> SkyStrip:
    """``strip`` (built on the unperturbed Gaia world) with each star's proper motion perturbed
    by ``N(0, (k sigma_pm)^2)`` per component (``k`` = ``pm_error_sigmas``, sigma_pm hip2's
    formal errors; the draws of :func:`simcam.sky.gaia.gaia_world` for the whole catalogue of
    ``mag_limit``, in its order, so the same generator gives the same sky).

    The world's position of a star moves by ``dmu (t - t_anchor)``: its catalogue row is
    anchored at the Gaia DR3 position at J2016.0 (hip2's at J1991.25 for a star without a Gaia
    match) and propagated with the perturbed motion. Applied to each pass's apparent direction
    ``u`` to first order on the tangent plane, ``u' = (u + dt (dmu_a e_a + dmu_d e_d)) / |.|``
    (``e_a``, ``e_d`` the east and north unit vectors at ``u``); the second-order terms are
    ``|offset|^2`` and ``|offset| |mu dt|`` (< 1e-12 rad for offsets of tens of mas), and
    parallax and aberration act on the offset to ``|offset| 1e-4``."""
    m = gaia_match(float(mag_limit))
    n = m.hip.size
    dpm_ra = pm_error_sigmas * m.pm_ra_err_mas_yr * rng.standard_normal(n)
    dpm_dec = pm_error_sigmas * m.pm_dec_err_mas_yr * rng.standard_normal(n)
    cat = strip.cat
    row = np.searchsorted(m.hip, cat.hip)
    if len(cat) and not np.array_equal(m.hip[np.minimum(row, n - 1)], cat.hip):
        raise ValueError("strip: its stars are not the Gaia world's of this magnitude limit")
    anchor = np.where(m.matched[row], GAIA_EPOCH_JYEAR, EPOCH_JYEAR)
    # the pass's epoch in Julian years (seconds over 365.25 days; UTC against TT moves dt by 2e-6 yr)
    t_yr = _jyear(strip.scenario.orbit.epoch_utc) + strip.plan.t_mid_s / (365.25 * 86400.0)
    dirs = strip.directions.copy()
    for k in range(dirs.shape[0]):
        u = dirs[k]
        dt_yr = t_yr[k] - anchor
        e_a = np.column_stack([-u[:, 1], u[:, 0], np.zeros(len(u))])
        e_a /= np.linalg.norm(e_a, axis=1, keepdims=True)
        e_d = np.cross(u, e_a)
        moved = u + ((dt_yr * dpm_ra[row])[:, None] * e_a + (dt_yr * dpm_dec[row])[:, None] * e_d) / MAS_PER_RAD
        dirs[k] = moved / np.linalg.norm(moved, axis=1, keepdims=True)
    return replace(strip, directions=dirs)


@lru_cache(maxsize=8)
def _jyear(epoch_utc: str) -> float:
    from astropy.time import Time

    return float(Time(epoch_utc, scale="utc").jyear)


@lru_cache(maxsize=4)
def _catalogue(mag_limit: float, gaia: bool) -> Catalogue:
    return gaia_world(mag_limit) if gaia else hipparcos()


@lru_cache(maxsize=16)
def _sky_strip(scenario, ra_deg, dec_deg, mag_limit, aberration, parallax, proper_motion, gaia=False):
    from astropy.time import Time

    plan = scan_plan(scenario, ra_deg=ra_deg, dec_deg=dec_deg)
    ra, dec = np.radians(ra_deg), np.radians(dec_deg)
    centre = np.array([np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra), np.sin(dec)])
    cat = _catalogue(mag_limit, gaia).cone(centre, strip_radius_rad(scenario), mag_limit=mag_limit)
    epoch = Time(scenario.orbit.epoch_utc, scale="utc")
    dirs = np.empty((plan.passes, len(cat), 3))
    vel = np.empty((plan.passes, 3))
    for k in range(plan.passes):
        pos, v = orbit_state(scenario, plan.t_mid_s[k])
        vel[k] = v
        if len(cat):
            dirs[k] = apparent_directions(cat, epoch + plan.t_mid_s[k] * _sec(),
                                          observer_position_km=pos, observer_velocity_km_s=v,
                                          proper_motion=proper_motion, parallax=parallax,
                                          aberration=aberration)
    strip = SkyStrip(cat=cat, directions=dirs, velocity_km_s=vel if aberration else None, plan=plan,
                     scenario=scenario)
    return strip


def _sec():
    import astropy.units as u

    return u.s


# --------------------------------------------------------------------------- crossing
def _focal_plane_at(camera: CameraTruth, plan: ScanPlan, a_gcrs, t, k, jitter=None):
    """Measured focal-plane (x, y) mm of GCRS directions ``a`` at times ``t`` of passes ``k``
    (the true attitude: the plan times the world's ``jitter`` rotation, when given)."""
    r_body = plan.matrices(t, k)
    if jitter is not None:
        r_body = r_body @ rodrigues(jitter(t))
    r_true = r_body @ camera.misalignment.as_matrix()
    d = np.einsum("nji,nj->ni", r_true, a_gcrs)
    return camera.focal_plane(d)


def crossing_times(camera: CameraTruth, plan: ScanPlan, a_gcrs, k, *, t0=None, tol_s: float = 1e-10,
                   max_iter: int = 20, jitter=None):
    """Times at which stars of GCRS directions ``a`` cross the line (``x = x_line``) in
    passes ``k``: secant iterations on the exact forward model, started from ``t0`` (default:
    the middle of the pass) and a first step with the nominal image rate ``f w_y``.

    Returns ``(t, x - x_line, y)`` (s, mm, mm).
    """
    f = camera.focal_length_mm
    w = plan.rate_rad_s[1]
    t_a = plan.t_mid_s[k].astype(float).copy() if t0 is None else np.array(t0, dtype=float)
    x_a, _ = _focal_plane_at(camera, plan, a_gcrs, t_a, k, jitter)
    x_a = x_a - camera.x_line_mm
    t_b = t_a - x_a / (f * w)
    for _ in range(max_iter):
        x_b, y = _focal_plane_at(camera, plan, a_gcrs, t_b, k, jitter)
        x_b = x_b - camera.x_line_mm
        denom = x_b - x_a
        slope = np.where(np.abs(denom) > 0, denom / np.where(t_b != t_a, t_b - t_a, 1.0), f * w)
        slope = np.where(np.abs(slope) > 0.1 * abs(f * w), slope, f * w)
        t_new = t_b - x_b / slope
        t_a, x_a, t_b = t_b, x_b, t_new
        if np.max(np.abs(t_b - t_a), initial=0.0) < tol_s:
            break
    x, y = _focal_plane_at(camera, plan, a_gcrs, t_b, k, jitter)
    return t_b, x - camera.x_line_mm, y


# --------------------------------------------------------------------------- imaging
@dataclass
class PassImages:
    """Windows of the TDI output around each imaged star (what the lab receives).

    Attributes
    ----------
    windows_dn : numpy.ndarray (n, h, w)
        Output in DN; rows are output lines, columns samples.
    line0, col0 : numpy.ndarray (n,)
        Output line (counted from the start of the pass) and sample of ``[0, 0]``.
    pass_index : numpy.ndarray (n,)
    t_pass0_s : numpy.ndarray (P,)
        Readout time of line 0 of each pass, s after the epoch.
    hip, t_true_s, sample_true, electrons : numpy.ndarray (n,)
        The world's truth about each window (not for the lab's estimators): the star,
        its crossing time (image at the line centre), sample there, and its electrons.
    """

    windows_dn: np.ndarray
    line0: np.ndarray
    col0: np.ndarray
    pass_index: np.ndarray
    t_pass0_s: np.ndarray
    hip: np.ndarray
    t_true_s: np.ndarray
    sample_true: np.ndarray
    electrons: np.ndarray


def detector_params(scenario: LineCamScenario) -> _det.DetectorParams:
    d = scenario.detector
    return _det.DetectorParams(gain_e_per_dn=(d.gain_e_per_dn,), offset_dn=(d.offset_dn,),
                               read_noise_e=(d.read_noise_e,), full_well_e=(d.full_well_e,),
                               adc_bits=d.adc_bits, prnu_rms=d.prnu_rms, dark_e=d.dark_e,
                               dsnu_rms_e=d.dsnu_rms_e)


def window_half_px(scenario: LineCamScenario) -> int:
    """Half size of the windows: 3 sigma of the PSF plus half the smear plus half a pixel, at least 3 px."""
    cam, att = scenario.camera, scenario.attitude
    n = cam.tdi_stages
    along = abs(att.rate_mismatch + scenario.world.effects.line_rate_mismatch_percent / 100.0) * n
    w = cam.matched_rate_rad_s
    # across-track drift per exposure: f w_x T N (+ X w_z, zero on the line centre)
    across = abs(math.radians(att.cross_rate_deg_s)) / w * n
    return max(3, int(math.ceil(3.0 * cam.psf_sigma_px + 0.5 * max(along, across) + 0.5)))


def image_passes(scenario: LineCamScenario, camera: CameraTruth, strip: SkyStrip, *,
                 frame_keys, detector_key, noise: bool = True, jitter=None) -> PassImages:
    """Image the stars of ``strip`` in every pass through the true ``camera``.

    For each pass and star: the crossing time ``t*`` of the line (exact forward model,
    :func:`crossing_times`), the image motion about ``t*`` (second order, from the exact
    model at ``t* +- N T``), the expected electrons of a window of the TDI output
    (:func:`simcam.linecam.kernels.render_tdi_windows`), then the detector chain
    (:func:`simcam.detector.expose_windows`: PRNU, dark, shot and read noise, ADC).
    Stars whose window leaves the pass or the line are not imaged.

    Parameters
    ----------
    frame_keys : sequence of uint64 (P,)
        Temporal-noise key of each pass.
    detector_key : uint64
        Key of the fixed PRNU/DSNU maps.
    noise : bool
        False: the expected signal in DN (no shot/read noise, no quantisation).
    jitter : callable or None
        The world's attitude jitter (:func:`world_jitter`): rotation vectors (n, 3) at times.

    The world's star-colour effect (``world.effects.lateral_colour_px``) moves each star's
    image along the line by ``c(T) y'/r_n`` (:func:`simcam.linecam.effects.lateral_colour_px`;
    the along-track part ``c(T) x'/r_n`` is below 1e-3 of it on the line and left out).
    """
    cam = scenario.camera
    plan = strip.plan
    n_st, m = plan.passes, len(strip.cat)
    T, N, p = cam.line_period_s, cam.tdi_stages, cam.pitch_mm
    half = window_half_px(scenario)
    size = 2 * half + 1
    kk = np.repeat(np.arange(n_st), m)
    jj = np.tile(np.arange(m), n_st)
    a = strip.directions[kk, jj]
    # stars in front of the camera and near the strip only
    # stars in front of the camera that the pass's line sweeps (body frame at mid-pass;
    # margins of 2 % of the field and the strip for the misalignment and distortion)
    body = np.einsum("nji,nj->ni", plan.r_mid[kk], a)
    half_across = 0.5 * cam.n_pixels * p / cam.focal_length_mm * 1.02
    half_along = 0.5 * plan.duration_s * abs(plan.rate_rad_s[1]) * 1.02
    near = (body[:, 2] < 0) & (np.abs(np.arctan2(body[:, 1], -body[:, 2])) < half_across)
    near &= np.abs(np.arctan2(body[:, 0], -body[:, 2])) < half_along
    kk, jj = kk[near], jj[near]
    t, _, _ = crossing_times(camera, plan, strip.directions[kk, jj], kk, tol_s=1e-3, jitter=jitter)
    a = strip.at(kk, jj, t)
    t, xres, y = crossing_times(camera, plan, a, kk, t0=t, jitter=jitter)
    s = y / p + 0.5 * (cam.n_pixels - 1)
    t_pass0 = plan.t_start_s
    line_c = (t - t_pass0[kk]) / T + 0.5 * N
    lines_per_pass = int(plan.duration_s / T)
    ok = (np.abs(xres) < 1e-6) & (line_c - half >= N) & (line_c + half < lines_per_pass)
    ok &= (s - half >= 0) & (s + half <= cam.n_pixels - 1)
    kk, jj, a, t, s, line_c = kk[ok], jj[ok], a[ok], t[ok], s[ok], line_c[ok]
    # image motion about t* (px from the line centre along x, samples along y)
    dt = N * T
    xp, yp = _focal_plane_at(camera, plan, a, t + dt, kk, jitter)
    xm, ym = _focal_plane_at(camera, plan, a, t - dt, kk, jitter)
    xp, xm = (xp - camera.x_line_mm) / p, (xm - camera.x_line_mm) / p
    sp, sm = yp / p + 0.5 * (cam.n_pixels - 1), ym / p + 0.5 * (cam.n_pixels - 1)
    vx, ax = (xp - xm) / (2 * dt), (xp + xm) / (2 * dt * dt)
    vs, as_ = (sp - sm) / (2 * dt), (sp + sm - 2 * s) / (2 * dt * dt)
    v, bv = strip.cat.v_mag[jj], strip.cat.b_v[jj]
    bv = np.where(np.isfinite(bv), bv, 0.6)
    colour_px = scenario.world.effects.lateral_colour_px
    if colour_px != 0.0:
        r_n = 0.5 * cam.n_pixels
        y_px = s - 0.5 * (cam.n_pixels - 1) - camera.principal_point_mm[1] / p
        shift = lateral_colour_px(cam.qe, teff_from_b_v(bv), edge_px=colour_px) * y_px / r_n
        s = s + shift
    line0 = np.rint(line_c).astype(np.int64) - half
    col0 = np.rint(s).astype(np.int64) - half
    rate = star_electron_rate(cam, v_mag=v, b_v=bv)
    sdir = 1.0 if plan.rate_rad_s[1] * cam.focal_length_mm >= 0 else -1.0
    n = kk.size
    sig = np.empty((n, size, size))
    zero = np.zeros(n)
    # the kernel's times are relative to each pass's line 0
    _k.render_tdi_windows(sig, line0, col0, t - t_pass0[kk], zero, s, vx, ax, vs, as_, rate, 0.0, T, N,
                          sdir, cam.psf_sigma_px, SUBSTEPS)
    sig += cam.background_e
    params = detector_params(scenario)
    out = np.empty((n, size, size))
    pass_rows = lines_per_pass + 2 * size
    for k in range(n_st):
        sel = np.flatnonzero(kk == k)
        if not sel.size:
            continue
        out[sel] = _det.expose_windows(signal_e=np.ascontiguousarray(sig[sel]), row0=line0[sel] + k * pass_rows,
                                       col0=col0[sel], mosaic_cols=cam.n_pixels, chip_cols=cam.n_pixels,
                                       params=params, frame_key=frame_keys[k], detector_key=detector_key,
                                       shot_noise=noise, read_noise=noise, quantize=noise)
    return PassImages(windows_dn=out, line0=line0, col0=col0, pass_index=kk, t_pass0_s=t_pass0.copy(),
                      hip=strip.cat.hip[jj], t_true_s=t, sample_true=s, electrons=rate * N * T)


class AttitudeReports:
    """The attitude a star tracker + gyro package reports: the truth times a white error.

    ``R_rep(t_i) = R(t_i - b) exp([e_i]x)``, ``e_i ~ N(0, sigma^2 I_3)`` drawn once per
    observation ``i`` (the knowledge error of the body frame; the camera misalignment is
    *not* in it: that is what the calibration finds). ``b`` is the world's time-tag bias
    (the attitude tagged ``t`` is the one of ``t - b``: an error ``omega b`` along the body
    rate ``omega``); ``R`` is the planned attitude, so the world's jitter is not in the
    reports either.
    """

    def __init__(self, plan: ScanPlan, sigma_rad: float, rng: np.random.Generator, time_tag_bias_s: float = 0.0):
        self.plan = plan
        self.sigma_rad = float(sigma_rad)
        self.rng = rng
        self.time_tag_bias_s = float(time_tag_bias_s)

    def report(self, t_s, pass_index) -> Rotation:
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        e = self.sigma_rad * self.rng.standard_normal((t.size, 3))
        if self.time_tag_bias_s != 0.0:
            t = t - self.time_tag_bias_s
        return Rotation.from_matrix(self.plan.matrices(t, pass_index) @ rodrigues(e))


def attitude_reports(scenario: LineCamScenario, plan: ScanPlan, rng: np.random.Generator) -> AttitudeReports:
    """The reports of a scenario: the lab's stated white knowledge error
    (``attitude.knowledge_noise_arcsec``) and the world's time-tag bias."""
    return AttitudeReports(plan, scenario.attitude.knowledge_noise_arcsec / ARCSEC_PER_RAD, rng,
                           time_tag_bias_s=scenario.world.effects.time_tag_bias_ms * 1e-3)


def world_jitter(scenario: LineCamScenario, plan: ScanPlan, rng: np.random.Generator):
    """The world's attitude jitter over all passes (:class:`simcam.linecam.effects.Jitter`), or None
    when both jitter magnitudes are 0 (``rng``: the effects' own stream,
    :func:`simcam.linecam.effects.effects_generator`)."""
    fx = scenario.world.effects
    if fx.jitter_tones_arcsec == 0.0 and fx.jitter_band_arcsec == 0.0:
        return None
    return Jitter(fx, scenario.world.jitter_band_tau_s, rng, float(plan.t_start_s[0]) - 1.0,
                  float(plan.t_start_s[-1]) + plan.duration_s + 1.0)
