"""Scan-mirror geometry (seed 003, Jia, Xu & Chen 2012): line of sight, attitude, frames, ground point.

Frames (reconstructed from Jia, Xu & Chen 2012 and its precursors, docs/scanmirror.md): body ``b`` (with zero attitude equal to the
instantaneous orbit frame ``r``: x east along the velocity, y south, z nadir), gimbal
``g`` (step angle alpha about x_b, positive south -> north), mirror ``m`` (scan angle beta
about y_g, positive west -> east), Earth-fixed rotating ``s`` (x Greenwich, z north),
nominal orbit frame ``r0`` at the sub-satellite longitude Omega_0.

Every function is vectorised over leading axes: angles are arrays of shape ``(N,)`` (or
scalars) and matrices ``(N, 3, 3)``. Angles in radians, lengths in km.
"""

from __future__ import annotations

import numpy as np

__all__ = ["rot_x", "rot_y", "rot_z", "rotvec_matrix", "mirror_normal_body", "line_of_sight_body",
           "attitude_matrix_br", "nominal_orbit_matrix_sr0", "P_ORBIT", "slant_range_sphere",
           "ray_ellipsoid_range", "latlon_geocentric", "OffDiscError"]


class OffDiscError(ValueError):
    """A line of sight misses the Earth where a ground point is asked for."""


def _trig(a):
    a = np.asarray(a, dtype=float)
    return a, np.cos(a), np.sin(a)


def rot_x(a) -> np.ndarray:
    """Active rotation matrix about x by ``a`` (rad): ``R_x(a)``, shape ``a.shape + (3, 3)``.

    Written out, not ``scipy.spatial.transform.Rotation``: the scan-mirror study is pinned bit for bit
    (tests/test_scanmirror_effects.py, ideal world) and scipy's quaternion route differs in the last bit.
    """
    a, c, s = _trig(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_y(a) -> np.ndarray:
    """Active rotation matrix about y by ``a`` (rad): ``R_y(a)`` (written out: see :func:`rot_x`)."""
    a, c, s = _trig(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def rot_z(a) -> np.ndarray:
    """Active rotation matrix about z by ``a`` (rad): ``R_z(a)`` (written out: see :func:`rot_x`)."""
    a, c, s = _trig(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def rotvec_matrix(v) -> np.ndarray:
    """Active rotation matrix of the rotation vector ``v`` (..., 3) (rad), Rodrigues' formula
    ``R = I + sin(t) K + (1 - cos t) K^2`` (Shuster 1993, eq. 98); written out: see :func:`rot_x`."""
    v = np.asarray(v, dtype=float)
    t = np.linalg.norm(v, axis=-1)
    safe = np.where(t > 0, t, 1.0)
    k = v / safe[..., None]
    K = np.zeros(v.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -k[..., 2], k[..., 1]
    K[..., 1, 0], K[..., 1, 2] = k[..., 2], -k[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -k[..., 1], k[..., 0]
    s, c = np.sin(t)[..., None, None], np.cos(t)[..., None, None]
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


def mirror_normal_body(alpha_rad, beta_rad, dtau_x_rad=0.0, dtau_y_rad=0.0) -> np.ndarray:
    """Mirror normal in the body frame, eq. (1) [R]: ``w^b = R_x(alpha) R_y(beta) A_tau (0, 0, 1)``.

    The normal deviation is the exact rotation with rotation vector
    ``(dtau_x, dtau_y, 0)`` in the mirror frame: ``A_tau z = (k_y sin t, -k_x sin t, cos t)``
    with ``t = |dtau|``, ``k = dtau / t`` (Rodrigues; to first order eq. (19):
    ``w^m = (dtau_y, -dtau_x, 1)``). Written out element by element. Returns (..., 3).
    """
    a, b, tx, ty = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in
                                         (alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad)))
    t = np.hypot(tx, ty)
    sinc = np.where(t > 0, np.sin(t) / np.where(t > 0, t, 1.0), 1.0)
    mx, my, mz = ty * sinc, -tx * sinc, np.cos(t)
    cb, sb, ca, sa = np.cos(b), np.sin(b), np.cos(a), np.sin(a)
    gx, gy, gz = cb * mx + sb * mz, my, -sb * mx + cb * mz          # R_y(beta)
    return np.stack([gx, ca * gy - sa * gz, sa * gy + ca * gz], -1)  # R_x(alpha)


def line_of_sight_body(alpha_rad, beta_rad, dtau_x_rad=0.0, dtau_y_rad=0.0) -> np.ndarray:
    """Line of sight in the body frame, eq. (2) [R]: the telescope axis ``d = x_b`` reflected
    by the mirror, ``s = d - 2 (d . w) w`` (exact law of reflection).

    Without deviation ``s = R_x(alpha) (cos 2 beta, 0, -sin 2 beta)``: nadir at alpha = 0,
    beta = -45 deg. Returns (..., 3) unit vectors.
    """
    w = mirror_normal_body(alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad)
    s = -2.0 * w[..., 0:1] * w
    s[..., 0] += 1.0
    return s


def attitude_matrix_br(roll_rad, pitch_rad, yaw_rad) -> np.ndarray:
    """Attitude matrix ``A_br`` (orbit -> body components), 3-1-2 Euler sequence, eq. (20) [R]:
    ``A_br = C_2(theta) C_1(phi) C_3(psi)`` with ``C_i`` the frame (passive) rotations
    (Wertz 1978, App. E, Table E-1, 3-1-2), written out. Small angles: ``[[1, psi, -theta],
    [-psi, 1, phi], [theta, -phi, 1]]``."""
    f, th, ps = np.broadcast_arrays(*(np.asarray(x, float) for x in (roll_rad, pitch_rad, yaw_rad)))
    cf, sf, ct, st, cp, sp = np.cos(f), np.sin(f), np.cos(th), np.sin(th), np.cos(ps), np.sin(ps)
    return np.stack([np.stack([ct * cp - st * sf * sp, ct * sp + st * sf * cp, -st * cf], -1),
                     np.stack([-cf * sp, cf * cp, sf], -1),
                     np.stack([st * cp + ct * sf * sp, st * sp - ct * sf * cp, ct * cf], -1)], -2)


#: ``P``: columns are the orbit-frame axes (x east, y south, z nadir) in the
#: (radial, along-track, orbit-normal) frame
P_ORBIT = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def nominal_orbit_matrix_sr0(omega0_rad: float) -> np.ndarray:
    """``A_sr0`` of eq. (9) [R]: nominal orbit frame -> Earth-fixed, ``R_z(Omega_0) P``,
    ``[[-sin, 0, -cos], [cos, 0, -sin], [0, -1, 0]]``."""
    return rot_z(omega0_rad) @ P_ORBIT


def slant_range_sphere(cos_xi, radius_km, earth_radius_km):
    """Near root of the law of cosines, eqs. (3)-(5) [R]:
    ``R_s = R cos xi - sqrt(R_e^2 - R^2 sin^2 xi)``; NaN where the line of sight misses the
    sphere (negative discriminant)."""
    cos_xi = np.asarray(cos_xi, float)
    R = np.asarray(radius_km, float)
    disc = earth_radius_km**2 - R**2 * (1.0 - cos_xi**2)
    with np.errstate(invalid="ignore"):
        out = R * cos_xi - np.sqrt(disc)
    return np.where((disc >= 0) & (cos_xi > 0), out, np.nan)


def ray_ellipsoid_range(origin_km, direction, a_km: float, b_km: float):
    """Distance along unit ``direction`` from ``origin_km`` (..., 3) to the near intersection
    with the ellipsoid ``(x^2 + y^2)/a^2 + z^2/b^2 = 1`` (quadratic in the scaled space);
    NaN where it misses."""
    scale = np.array([1.0 / a_km, 1.0 / a_km, 1.0 / b_km])
    o = origin_km * scale
    d = direction * scale
    A = np.sum(d * d, -1)
    B = 2.0 * np.sum(o * d, -1)
    C = np.sum(o * o, -1) - 1.0
    disc = B * B - 4 * A * C
    with np.errstate(invalid="ignore"):
        t = (-B - np.sqrt(disc)) / (2 * A)
    return np.where((disc >= 0) & (t > 0), t, np.nan)


def latlon_geocentric(r_s_km):
    """Geocentric latitude and longitude (rad) of Earth-fixed vectors, eqs. (10)-(12) [R]:
    ``delta = asin(z / |r|)``, ``lambda = atan2(y, x)`` mapped to [0, 2 pi)."""
    r = np.asarray(r_s_km, float)
    lat = np.arcsin(r[..., 2] / np.linalg.norm(r, axis=-1))
    lon = np.mod(np.arctan2(r[..., 1], r[..., 0]), 2 * np.pi)
    return lat, lon
