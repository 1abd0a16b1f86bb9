"""Polygon-and-autocollimator calibration rig for an angle encoder (seed 001 section 3-4).

Lab protocol simulated (the one under which eq 9's compensation
``theta_hat = theta - e(theta)`` is exact, ``theta`` being the *reading*): for face ``i``
of an ``N``-face polygon the servo holds the (quantised) encoder reading at the nominal
face angle ``theta_i = i * 360/N``; the true shaft angle is then the one whose continuous
reading lies within the resolution cell, ``theta_true = f^-1(theta_i + d)`` with
``d = u q - n_r`` (``u`` uniform in [-1/2, 1/2), ``q`` the resolution, ``n_r`` the reading
noise). The autocollimator reads the deviation of face ``i`` from its nominal direction,
``alpha = (theta_true - theta_i) + face_error_i + mount_offset + n_ac`` rounded to its
resolution; the lab writes down ``error_arcsec = -alpha`` (encoder reading minus true
angle) against ``angle_deg = theta_i``. A compensated re-measurement ("verify") holds the
same raw readings and writes ``-alpha - e_hat(theta_i)``.

Random draws for one measurement, in this order when a generator is given:
``u`` (``rng.random(N)``), reading noise (``rng.standard_normal(N)``), autocollimator
noise (``rng.standard_normal(N)``); or the same standardised draws passed in (the Monte
Carlo validator lays a whole trial's draws out in two calls and passes them).
A polygon's face errors are one ``rng.standard_normal(N)`` draw scaled by its uncertainty.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from simcam.encoder.inductosyn import (
    AutocollimatorParams,
    Inductosyn,
    InductosynScenario,
    PolygonParams,
    instrument_rng,
    pinned_instrument,
)
from simcam.noise_processes import random_walk, white_noise
from simcam.units import ARCSEC_PER_DEG, ARCSEC_PER_RAD, SECONDS_PER_HOUR

__all__ = [
    "FaceTaylor",
    "WORLD_STREAM",
    "autocollimator_error_arcsec",
    "autocollimator_reading_rad",
    "certified_face_errors_arcsec",
    "pass_times_s",
    "tilted_face_reading_rad",
    "world_alpha_arcsec",
    "world_rng",
    "draw_face_errors_arcsec",
    "face_taylor",
    "measure_polygon",
    "nominal_face_angles_deg",
    "quantise_arcsec",
]


def nominal_face_angles_deg(*, faces: int) -> np.ndarray:
    """Nominal face angles ``i * 360 / faces`` (deg), i = 0 .. faces-1."""
    if faces < 3:
        raise ValueError("a polygon has at least 3 faces")
    return np.arange(faces) * (360.0 / faces)


def draw_face_errors_arcsec(*, polygon: PolygonParams, rng: np.random.Generator) -> np.ndarray:
    """Residual face-angle errors (after the certificate correction), arcsec."""
    return rng.standard_normal(polygon.faces) * polygon.face_error_arcsec


def quantise_arcsec(*, value_arcsec, resolution_arcsec: float):
    """Round to a resolution (arcsec); identity for 0."""
    x = np.asarray(value_arcsec, dtype=float)
    return x if resolution_arcsec == 0 else np.round(x / resolution_arcsec) * resolution_arcsec


def measure_polygon(*, encoder: Inductosyn, polygon: PolygonParams,
                    autocollimator: AutocollimatorParams, face_errors_arcsec: np.ndarray,
                    rng: np.random.Generator | None = None, draws=None,
                    compensation_arcsec=None) -> pd.DataFrame:
    """One pass round the polygon: the table a lab writes down (exact inverse map).

    Parameters
    ----------
    encoder : the encoder under test (truth).
    polygon, autocollimator : the rig.
    face_errors_arcsec : this polygon's residual face errors (see
        :func:`draw_face_errors_arcsec`).
    rng : generator for this measurement's draws (order in the module docstring).
    draws : alternatively, the standardised draws ``(u, z_read, z_ac)`` (u uniform in
        [0, 1), z standard normal), each of length ``faces``.
    compensation_arcsec : optional ``e_hat`` at the nominal angles (arcsec) subtracted
        from the written error (a compensated re-measurement).

    Returns
    -------
    DataFrame with columns ``angle_deg`` (nominal face angle = held reading) and
    ``error_arcsec`` (reading minus true angle, as measured).
    """
    angles = nominal_face_angles_deg(faces=polygon.faces)
    n = polygon.faces
    q_arcsec = encoder.params.resolution_deg * ARCSEC_PER_DEG
    if draws is None:
        if rng is None:
            raise ValueError("measure_polygon needs rng or draws")
        draws = (rng.random(n), rng.standard_normal(n), rng.standard_normal(n))
    u = np.asarray(draws[0]) - 0.5
    n_read = np.asarray(draws[1]) * encoder.params.reading_noise_arcsec
    n_ac = np.asarray(draws[2]) * autocollimator.noise_arcsec
    d_arcsec = u * q_arcsec - n_read
    true_deg = encoder.true_angle_deg(reading_deg=angles + d_arcsec / ARCSEC_PER_DEG)
    alpha = ((true_deg - angles) * ARCSEC_PER_DEG + face_errors_arcsec
             + polygon.mount_offset_arcsec + n_ac)
    err = -quantise_arcsec(value_arcsec=alpha, resolution_arcsec=autocollimator.resolution_arcsec)
    if compensation_arcsec is not None:
        err = err - np.asarray(compensation_arcsec, dtype=float)
    return pd.DataFrame({"angle_deg": angles, "error_arcsec": err})


class FaceTaylor:
    """Second-order expansion of the measured error about each nominal face angle.

    The true-angle offset from the held reading ``theta_i + d`` (arcsec) is
    ``f^-1(theta_i + d) - theta_i = -e0_i + s1_i d + s2_i d^2 + O(d^3)``. The truncation error
    is ``|f^-1'''| |d|^3 / 6``, below 1e-9 arcsec for |d| < 1 arcsec with the default
    encoder (checked against the exact inverse in tests/test_inductosyn.py).

    Attributes
    ----------
    angles_deg : nominal face angles.
    e0_arcsec : ``theta_i - f^-1(theta_i)`` (arcsec), the exact error at the reading.
    s1 : first derivative of ``f^-1`` (dimensionless).
    s2_per_arcsec : half the second derivative (1/arcsec).
    """

    def __init__(self, *, angles_deg, e0_arcsec, s1, s2_per_arcsec):
        self.angles_deg = angles_deg
        self.e0_arcsec = e0_arcsec
        self.s1 = s1
        self.s2_per_arcsec = s2_per_arcsec

    def true_offset_arcsec(self, *, d_arcsec):
        """``(f^-1(theta_i + d) - theta_i)`` in arcsec, for d (arcsec) of shape (..., N)."""
        return -self.e0_arcsec + self.s1 * d_arcsec + self.s2_per_arcsec * d_arcsec**2


def face_taylor(*, encoder: Inductosyn, faces: int, step_arcsec: float = 0.36) -> FaceTaylor:
    """Exact inverse map at the face angles and its derivatives (central differences)."""
    angles = nominal_face_angles_deg(faces=faces)
    h = step_arcsec / ARCSEC_PER_DEG
    t0 = encoder.true_angle_deg(reading_deg=angles)
    tp = encoder.true_angle_deg(reading_deg=angles + h)
    tm = encoder.true_angle_deg(reading_deg=angles - h)
    s1 = (tp - tm) / (2 * h)
    s2 = (tp - 2 * t0 + tm) / (2 * h * h) / ARCSEC_PER_DEG  # per arcsec
    return FaceTaylor(angles_deg=angles, e0_arcsec=(angles - t0) * ARCSEC_PER_DEG, s1=s1,
                      s2_per_arcsec=s2)


# ------------------------------------------------------------------ world effects
# What the real rig has and the lab's model leaves out (issue "worlds richer than the lab"):
# the magnitudes are ``scenario.world.effects`` (:class:`simcam.encoder.inductosyn.InductosynEffects`).
# Each adds to the autocollimator's deviation ``alpha`` of a face (module docstring), like
# the face errors; the lab writes down ``-alpha``.

#: spawn-key tail of a trial's world draws: trial k's are ``SeedSequence(seed, spawn_key=(k, 1))``,
#: a stream of their own, so the lab's draws (``spawn_key=(k,)``) are the same with or without them
WORLD_STREAM = 1


def world_rng(*, seed: int, trial: int) -> np.random.Generator:
    """Generator of trial ``trial``'s world draws (independent of its measurement draws)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(trial, WORLD_STREAM))))


def certified_face_errors_arcsec(*, z, u_arcsec: float) -> np.ndarray:
    """Face errors left after a certificate's correction: ``delta_i = u (z_i - mean z)``.

    Closure: the face angles of a polygon add up to 360 deg, so ``sum delta_i = 0`` (circle
    closure, Estler 1998). Each harmonic coefficient of a least-squares fit on ``n`` evenly
    spaced faces, ``(2/n) sum delta_i cos(k theta_i)``, then has variance ``2 u^2 / n``
    exactly, and the fitted constant is 0.
    """
    z = np.asarray(z, dtype=float)
    return u_arcsec * (z - z.mean(axis=-1, keepdims=True))


def autocollimator_reading_rad(*, face_normal_rad: float, face_radius_mm: float, offset_xy_mm=(0.0, 0.0)):
    """Autocollimator reading of one face, traced in the plane (exact geometry).

    The beam runs along ``-x`` on the line ``y = 0``; the face, centred at ``offset_xy_mm``
    (the polygon's translation; each of x, y a number or an array) with its normal at
    ``face_normal_rad`` from ``+x``, is a plane (``face_radius_mm = inf``) or a circle of that
    radius (a curved face). The beam is reflected at the hit point about the local normal
    there; the reading is half the angle of the returned beam from ``+x`` (the law of
    reflection). A plane's normal is the same at every point, so a pure translation leaves
    the reading unchanged, exactly; a curved face's reading moves by ``asin(sin psi - y/R) - psi``
    (beam walk).
    """
    nx, ny = math.cos(face_normal_rad), math.sin(face_normal_rad)
    px = np.asarray(offset_xy_mm[0], dtype=float)
    py = np.asarray(offset_xy_mm[1], dtype=float)
    shape = np.broadcast(px, py).shape
    if math.isinf(face_radius_mm):
        lx, ly = np.full(shape, nx), np.full(shape, ny)  # a plane: the local normal everywhere
    else:
        cx, cy = px - face_radius_mm * nx, py - face_radius_mm * ny  # centre of curvature
        hy = 0.0
        hx = cx + np.sqrt(face_radius_mm**2 - (hy - cy) ** 2)  # the hit point on y = 0 facing +x
        lx, ly = (hx - cx) / face_radius_mm, (hy - cy) / face_radius_mm
    dx, dy = -1.0, 0.0
    dot = dx * lx + dy * ly
    rx, ry = dx - 2.0 * dot * lx, dy - 2.0 * dot * ly
    out = 0.5 * np.arctan2(ry, rx)
    return float(out) if out.ndim == 0 else out


def tilted_face_reading_rad(*, theta_rad, gamma_rad, tilt_rad: float, tilt_azimuth_rad: float):
    """Horizontal angle (rad) of face normals on a polygon whose axis is tilted (exact rotation).

    Face ``i``'s normal in the polygon frame is ``(cos g cos t, cos g sin t, sin g)``
    (pyramidal error ``g = gamma_i``, nominal angle ``t = theta_i``); the polygon's axis is
    tilted by ``tau`` about the horizontal axis at azimuth ``phi`` (Rodrigues' rotation);
    the autocollimator reads the azimuth of the tilted normal minus ``theta_i``. To first
    order in the small angles this is ``-tau gamma_i cos(theta_i - phi)`` plus a term in
    ``tau^2`` (the tilt alone).
    """
    t = np.asarray(theta_rad, dtype=float)
    g = np.asarray(gamma_rad, dtype=float)
    n = np.stack([np.cos(g) * np.cos(t), np.cos(g) * np.sin(t), np.sin(g) * np.ones_like(t)])
    a = np.array([math.cos(tilt_azimuth_rad), math.sin(tilt_azimuth_rad), 0.0])
    c, s = math.cos(tilt_rad), math.sin(tilt_rad)
    axn = np.cross(a, n, axis=0)
    adn = np.tensordot(a, n, axes=(0, 0))
    nr = n * c + axn * s + np.outer(a, adn).reshape(n.shape) * (1 - c)
    return np.arctan2(nr[1], nr[0]) - t - np.round((np.arctan2(nr[1], nr[0]) - t) / (2 * math.pi)) * 2 * math.pi


def autocollimator_error_arcsec(*, rng: np.random.Generator, t_s, noise_arcsec: float,
                                drift_arcsec_per_sqrt_h: float) -> np.ndarray:
    """Autocollimator error at reading times ``t_s``: white noise plus a random-walk drift.

    :func:`simcam.noise_processes.white_noise` (``noise_arcsec`` per reading) plus
    :func:`simcam.noise_processes.random_walk` of diffusion ``drift / sqrt(3600 s)`` (rms
    change ``drift_arcsec_per_sqrt_h`` after one hour). Allan variance
    ``noise^2 dt / tau + q tau / 3`` (IEEE Std 952-1997, Annex C): slope -1/2, then +1/2.
    """
    w = white_noise(rng, t_s, noise_arcsec)
    return w + random_walk(rng, t_s, drift_arcsec_per_sqrt_h / math.sqrt(SECONDS_PER_HOUR))


def pass_times_s(*, scenario: InductosynScenario) -> list[np.ndarray]:
    """Reading times (s from the first reading) of the four passes: long raw, long verify,
    short raw, short verify; ``calibration.face_time_s`` per face, ``calibration.pass_setup_s``
    between.
    A pass of ``calibration.repeats`` rounds reads its ``repeats * faces`` faces in a row
    (round-major: the faces of round 0, then of round 1, ...)."""
    cal = scenario.calibration
    r = cal.repeats
    out, start = [], 0.0
    for n in (cal.long_polygon.faces, cal.long_polygon.faces, cal.short_polygon.faces, cal.short_polygon.faces):
        out.append(start + np.arange(r * n) * cal.face_time_s)
        start = out[-1][-1] + cal.face_time_s + cal.pass_setup_s
    return out


def _thermal_basis(angle_deg, pole_pairs: int) -> np.ndarray:
    """cos/sin of mechanical 1, 2 and electrical 1, 2 at readings ``angle_deg`` (rows: 8)."""
    a = np.asarray(angle_deg, dtype=float)
    t = np.radians(a)
    cyc = pole_pairs * a / 360.0
    te = 2 * math.pi * (cyc - np.floor(cyc))
    return np.stack([np.cos(t), np.sin(t), np.cos(2 * t), np.sin(2 * t),
                     np.cos(te), np.sin(te), np.cos(2 * te), np.sin(2 * te)])


def _instrument_polygons(scenario: InductosynScenario, instrument) -> dict:
    """The instrument's polygons: certificate residuals and pyramidal errors (rad) of each,
    tiled over the pass's rounds (stream 0 of :func:`simcam.encoder.inductosyn.instrument_rng`)."""
    w = scenario.world
    cal = scenario.calibration
    ri = instrument_rng(instrument, 0)
    fixed = {}
    for key, poly in (("long", cal.long_polygon), ("short", cal.short_polygon)):
        z = ri.standard_normal(poly.faces)
        g = ri.standard_normal(poly.faces)
        fixed[key] = (np.tile(certified_face_errors_arcsec(z=z, u_arcsec=w.effects.polygon_face_error_arcsec),
                              cal.repeats),
                      np.tile(g * w.pyramidal_error_arcsec / ARCSEC_PER_RAD, cal.repeats))
    return fixed


def world_alpha_arcsec(*, scenario: InductosynScenario, seed: int, trials,
                       instruments=None) -> list[np.ndarray] | None:
    """What the world adds to the autocollimator deviation ``alpha`` of each pass (arcsec).

    For trials ``trials`` (a sequence of trial numbers) returns four arrays (long raw, long
    verify, short raw, short verify) of shape ``(len(trials), repeats * faces)`` (round-major,
    ``calibration.repeats`` rounds of the pass, :func:`pass_times_s`), or None when every
    rig effect is 0 (then the tables are today's, bit for bit). Terms (magnitudes in
    ``world.effects``):

    * ``polygon_face_error_arcsec``: the polygon's certificate residuals
      (:func:`certified_face_errors_arcsec`), one set per polygon of the trial's instrument
      (``instruments``: one seed sequence per trial, :func:`simcam.encoder.inductosyn.instrument_rng`
      stream 0; None: :func:`simcam.encoder.inductosyn.pinned_instrument` for every trial);
    * ``autocollimator_drift_arcsec_per_sqrt_h``: a random walk over the whole session
      (:func:`pass_times_s`), 0 at the first reading;
    * ``polygon_eccentricity_um``: beam walk over the curved face
      (:func:`autocollimator_reading_rad`), lateral offset ``e sin(theta_i - phi)``, ``phi``
      uniform per trial and polygon (each calibration remounts it);
    * ``polygon_tilt_arcsec``: axis tilt with the faces' pyramidal errors
      (:func:`tilted_face_reading_rad`), azimuth uniform per trial and polygon;
    * ``thermal_drift_arcsec_per_sqrt_h``: each harmonic coefficient of the encoder
      (mechanical 1-2, electrical 1-2) random-walks in time; the reading error moves by
      ``sum_j dc_j(t) b_j(theta_i)``, so ``alpha`` by minus that.

    Trial k's draws, in this order from :func:`world_rng`: 4 uniforms (eccentricity azimuth
    long, short; tilt azimuth long, short), the autocollimator walk, then the 8 coefficient
    walks (each over all readings of the session) — all drawn whatever the magnitudes, so
    switching one effect off leaves the others' draws alone (common random numbers).
    """
    w = scenario.world
    eff = w.effects
    if not any((eff.polygon_face_error_arcsec, eff.autocollimator_drift_arcsec_per_sqrt_h,
                eff.polygon_eccentricity_um, eff.polygon_tilt_arcsec, eff.thermal_drift_arcsec_per_sqrt_h)):
        return None
    cal = scenario.calibration
    polys = (cal.long_polygon, cal.long_polygon, cal.short_polygon, cal.short_polygon)
    reps = cal.repeats
    # each pass reads its faces round after round (round-major; one round: the faces once)
    angles = [np.tile(nominal_face_angles_deg(faces=pp.faces), reps) for pp in polys]
    times = pass_times_s(scenario=scenario)
    t_all = np.concatenate(times)
    sizes = [a.size for a in angles]
    edges = np.cumsum([0] + sizes)
    keys = ("long", "long", "short", "short")
    basis = [_thermal_basis(a, scenario.encoder.pole_pairs) for a in angles]
    radius_mm = math.inf if w.face_curvature_arcsec_per_mm == 0 else ARCSEC_PER_RAD / w.face_curvature_arcsec_per_mm
    e_mm = eff.polygon_eccentricity_um * 1e-3
    tau = eff.polygon_tilt_arcsec / ARCSEC_PER_RAD
    q_ac = eff.autocollimator_drift_arcsec_per_sqrt_h / math.sqrt(SECONDS_PER_HOUR)
    q_th = eff.thermal_drift_arcsec_per_sqrt_h / math.sqrt(SECONDS_PER_HOUR)
    trials = list(trials)
    if instruments is None:
        instruments = [pinned_instrument(scenario=scenario)] * len(trials)
    out = [np.zeros((len(trials), n)) for n in sizes]
    for row, k in enumerate(trials):
        fixed = _instrument_polygons(scenario, instruments[row])
        rng = world_rng(seed=seed, trial=k)
        az = rng.uniform(0.0, 2 * math.pi, 4)
        ac = random_walk(rng, t_all, q_ac)
        th = np.stack([random_walk(rng, t_all, q_th) for _ in range(8)])
        for p in range(4):
            pk = 0 if keys[p] == "long" else 1
            sl = slice(edges[p], edges[p + 1])
            th_rad = np.radians(angles[p])
            alpha = fixed[keys[p]][0] + ac[sl] - np.einsum("jn,jn->n", th[:, sl], basis[p])
            if e_mm > 0 and not math.isinf(radius_mm):
                base = autocollimator_reading_rad(face_normal_rad=0.0, face_radius_mm=radius_mm)
                lat = e_mm * np.sin(th_rad - az[pk])
                alpha = alpha + ARCSEC_PER_RAD * (autocollimator_reading_rad(
                    face_normal_rad=0.0, face_radius_mm=radius_mm, offset_xy_mm=(0.0, lat)) - base)
            if tau > 0:
                alpha = alpha + ARCSEC_PER_RAD * tilted_face_reading_rad(
                    theta_rad=th_rad, gamma_rad=fixed[keys[p]][1], tilt_rad=tau, tilt_azimuth_rad=az[2 + pk])
            out[p][row] = alpha
    return out
