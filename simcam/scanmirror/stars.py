"""Star sensing with the scan mirror (seed 003, eqs. 33-34 [R]): which catalogue stars cross the
star-sensing field during a dwell, their apparent directions, and the imaged centroids.

Image formation: the telescope looks along ``x_b``; a star at apparent direction ``u`` (body
frame) reaches the detector along the mirror reflection ``d' = u - 2 (u . w) w`` (the law of
reflection is an involution), and the detector measures its gnomonic coordinates
``m = (d'_y / d'_x, d'_z / d'_x)`` (rad); the boresight ``d' = x_b`` is ``m = 0``.

Apparent directions come from the shared :mod:`simcam.sky` (Hipparcos, astropy/ERFA: proper
motion and parallax to the epoch, light deflection, aberration for the spacecraft's
barycentric velocity), in the GCRS axes, which are the inertial frame ``I`` of the orbit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simcam.infra.errors import ScenarioError
from simcam.scanmirror.geometry import attitude_matrix_br, mirror_normal_body
from simcam.scanmirror.orbit import orbit_frame_matrix_Ir
from simcam.sky.apparent import apparent_directions
from simcam.sky.catalogue import hipparcos

__all__ = ["DwellStars", "detector_coordinates", "find_dwell_stars", "body_to_inertial"]


def detector_coordinates(u_b, w_b) -> np.ndarray:
    """Gnomonic detector coordinates (rad) of body-frame directions ``u_b`` (..., 3) imaged by
    the mirror of normal ``w_b`` (..., 3)."""
    d = u_b - 2.0 * np.sum(u_b * w_b, -1, keepdims=True) * w_b
    return np.stack([d[..., 1] / d[..., 0], d[..., 2] / d[..., 0]], -1)


def body_to_inertial(r_km, v_km_s, att_rad) -> np.ndarray:
    """``A_Ib = A_Ir A_rb`` (N, 3, 3): the orbit frame from the state and the 3-1-2 attitude."""
    A_Ir = orbit_frame_matrix_Ir(r_km, v_km_s)
    A_br = attitude_matrix_br(att_rad[..., 0], att_rad[..., 1], att_rad[..., 2])
    return A_Ir @ np.swapaxes(A_br, -1, -2)


@dataclass(frozen=True)
class DwellStars:
    """The stars of one star-sensing dwell and its frame times.

    ``apparent_I`` (n, 3): apparent GCRS directions (the truth, all effects);
    ``catalogue_I`` (n, 3): the same without aberration (what the paper's estimator uses);
    ``frame_t_s`` (f,): frame times; ``alpha_rad, beta_rad``: commanded angles;
    ``visible`` (f, n): the star is inside the field at that frame (nominal pointing).
    """

    index: int
    hip: np.ndarray
    v_mag: np.ndarray
    apparent_I: np.ndarray
    catalogue_I: np.ndarray
    frame_t_s: np.ndarray
    alpha_rad: float
    beta_rad: float
    visible: np.ndarray
    r_km: np.ndarray
    v_km_s: np.ndarray


def find_dwell_stars(world, *, source: str = "scenario") -> list[DwellStars]:
    """The stars seen in every star-sensing dwell of the plan (nominal attitude and mirror).

    Raises :class:`ScenarioError` naming ``star_sensing.mag_limit`` when a dwell has no star
    brighter than the limit in its field.
    """
    from astropy.time import Time, TimeDelta

    sc = world.scenario
    ss = sc.star_sensing
    half = np.deg2rad(ss.field_half_width_deg)
    t_grid = np.arange(0.0, world.duration_s, 0.05)
    plan = world.plan(t_grid)
    out = []
    cat_all = hipparcos()
    epoch = Time(sc.orbit.epoch_utc, scale="utc")
    for k in range(1, int(plan.star_dwell.max()) + 1):
        tk = t_grid[plan.star_dwell == k]
        t0, t1 = tk[0], tk[-1]
        nf = ss.frames_per_dwell
        frame_t = t0 + (np.arange(nf) + 0.5) * (t1 - t0) / nf
        a, b = float(plan.alpha_rad[plan.star_dwell == k][0]), float(plan.beta_rad[plan.star_dwell == k][0])
        r, v = world.orbit.state(frame_t)
        A_Ib = body_to_inertial(r, v, np.zeros((nf, 3)))
        w_b = mirror_normal_body(a, b)
        los_b = np.array([1.0, 0.0, 0.0]) - 2.0 * w_b[0] * w_b
        centre = A_Ib[nf // 2] @ los_b
        # the field's corner is sqrt(2) half widths off the boresight; the drift over the dwell
        # (omega_0 * dwell) is added
        radius = np.sqrt(2) * half + world.orbit_rate_rad_s * (t1 - t0) + 1e-3
        cat = cat_all.cone(centre, radius, mag_limit=ss.mag_limit)
        tmid = epoch + TimeDelta(float(frame_t[nf // 2]), format="sec")
        rm, vm = world.orbit.state([frame_t[nf // 2]])
        if len(cat):
            app = apparent_directions(cat, tmid, observer_position_km=rm[0], observer_velocity_km_s=vm[0])
            catl = apparent_directions(cat, tmid, observer_position_km=rm[0], observer_velocity_km_s=vm[0],
                                       aberration=False)
            u_b = np.einsum("fji,nj->fni", A_Ib, app)
            m = detector_coordinates(u_b, np.broadcast_to(w_b, u_b.shape))
            vis = (np.abs(m) <= np.tan(half)).all(-1) & (np.einsum("fni,i->fn", u_b, los_b) > 0)
            keep = vis.any(0)
        else:
            keep = np.zeros(0, bool)
        if not keep.any():
            raise ScenarioError(
                f"{source}: star_sensing.mag_limit: no catalogue star brighter than V = {ss.mag_limit} "
                f"crosses the {2 * ss.field_half_width_deg} deg star-sensing field during star dwell {k} "
                f"(t = {t0:.1f}-{t1:.1f} s); raise the limit, widen star_sensing.field_half_width_deg or "
                f"move the dwell")
        idx = np.flatnonzero(keep)
        out.append(DwellStars(k, cat.hip[idx], cat.v_mag[idx], app[idx], catl[idx], frame_t, a, b, vis[:, idx],
                              r, v))
    return out


def true_centroids(dwell: DwellStars, dtau_x_rad, dtau_y_rad, att_frames_rad) -> np.ndarray:
    """Noise-free detector coordinates (f, n, 2) (rad) of the dwell's stars with the injected
    deviation (scalars or (f,)) and the true attitude at the frames (f, 3): the truth the
    centroid noise is added to."""
    A_Ib = body_to_inertial(dwell.r_km, dwell.v_km_s, att_frames_rad)
    u_b = np.einsum("fji,nj->fni", A_Ib, dwell.apparent_I)
    w = mirror_normal_body(dwell.alpha_rad, dwell.beta_rad, dtau_x_rad, dtau_y_rad)
    w = np.broadcast_to(np.asarray(w)[..., None, :] if np.ndim(w) == 2 else w, u_b.shape)
    return detector_coordinates(u_b, w)


__all__ += ["true_centroids"]
