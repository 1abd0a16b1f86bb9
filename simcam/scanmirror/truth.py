"""The truth's route to the ground point of the scan mirror's line of sight (seed 003), sharing
nothing with the lab's chain.

The lab's estimators and compensation (``budget/scanmirror/estimation.py``,
``compensation.py``, ``kernels.py``) reach the line of sight through
:mod:`simcam.scanmirror.geometry` (written-out rotation matrices, the reflection
``s = d - 2 (d . w) w`` expanded component by component, the slant range by the law of
cosines, eqs. 3-5, latitude by ``asin``). The world's truth here takes another road to the
same physics:

* the mirror normal ``w^b = R_x(alpha) R_y(beta) A_tau z_m`` (eqs. 1 and 19 [R]) composed as
  quaternions (:class:`scipy.spatial.transform.Rotation`, rotation vectors
  ``(alpha, 0, 0)``, ``(0, beta, 0)`` and ``(dtau_x, dtau_y, 0)``);
* the reflection as the Householder matrix ``H = I - 2 w w^T`` (law of reflection, Born &
  Wolf, *Principles of Optics*, section 3.2) applied to the telescope axis ``d = x_b`` (eq. 2);
* the 3-1-2 attitude (eq. 20 [R], Wertz 1978 App. E): ``A_br = (R_z(psi) R_x(phi)
  R_y(theta))^T``, scipy's intrinsic ``"ZXY"`` Euler sequence;
* the ground point as the near root of the ray-quadric intersection
  ``|S (p + t u)|^2 = 1`` in the Earth-fixed frame (``S = diag(1/a, 1/a, 1/b)``; a sphere
  when ``a = b``), the satellite at ``p = A_sr0 A_r0r (-R z)`` (eqs. 6-9);
* geocentric latitude ``atan2(z, hypot(x, y))`` and longitude ``atan2(y, x)`` (eqs. 10-12).

Nothing here is imported by the lab's modules, and nothing here imports them or the
geometry module (tests/test_scanmirror_truth.py reads the source).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["ground_errors_truth_deg", "ground_latlon_truth", "ground_point_s_truth", "line_of_sight_body_truth"]

_X = np.array([1.0, 0.0, 0.0])
_Z = np.array([0.0, 0.0, 1.0])
#: orbit-frame axes (x east, y south, z nadir) as columns in (radial, along-track, normal): the
#: nominal orbit frame's definition (eq. 9 [R]), stated here again rather than imported
_P = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _flat(x, n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(x, float), (n,)).reshape(n)


def line_of_sight_body_truth(alpha_rad, beta_rad, dtau_x_rad=0.0, dtau_y_rad=0.0) -> np.ndarray:
    """Line of sight in the body frame (N, 3): the telescope axis ``x_b`` reflected by the
    Householder matrix of the deviated mirror normal (eqs. 1, 2 and 19 [R], module docstring)."""
    shape = np.broadcast_shapes(*(np.shape(v) for v in (alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad)))
    n = int(np.prod(shape, dtype=int))
    a, b, tx, ty = (_flat(np.broadcast_to(v, shape), n) for v in (alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad))
    z = np.zeros(n)
    gimbal = Rotation.from_rotvec(np.column_stack([a, z, z])) * Rotation.from_rotvec(np.column_stack([z, b, z]))
    w = (gimbal * Rotation.from_rotvec(np.column_stack([tx, ty, z]))).apply(_Z)
    H = np.eye(3) - 2.0 * w[:, :, None] * w[:, None, :]
    return (H @ _X).reshape(shape + (3,))


def ground_point_s_truth(alpha_rad, beta_rad, dtau_x_rad, dtau_y_rad, att_rad, A_r0r, R_km, *,
                         omega0_rad: float, equatorial_radius_km: float, polar_radius_km: float) -> np.ndarray:
    """Ground point of the line of sight in the Earth-fixed frame ``s`` (N, 3) (km): the ray from
    the satellite intersected with the Earth (a sphere when the radii are equal); NaN rows
    where it misses. Angles (N,), ``att_rad`` (N, 3) (roll, pitch, yaw), ``A_r0r`` (N, 3, 3),
    ``R_km`` (N,)."""
    a = np.atleast_1d(np.asarray(alpha_rad, float))
    n = a.shape[0]
    s_b = line_of_sight_body_truth(a, _flat(beta_rad, n), _flat(dtau_x_rad, n), _flat(dtau_y_rad, n))
    att = np.broadcast_to(np.asarray(att_rad, float), (n, 3))
    s_r = Rotation.from_euler("ZXY", np.column_stack([att[:, 2], att[:, 0], att[:, 1]])).apply(s_b)
    A_sr0 = Rotation.from_rotvec(np.array([0.0, 0.0, omega0_rad])).as_matrix() @ _P
    M = A_sr0 @ np.broadcast_to(np.asarray(A_r0r, float), (n, 3, 3))
    p = -_flat(R_km, n)[:, None] * M[:, :, 2]
    u = np.einsum("nij,nj->ni", M, s_r)
    S = np.array([1.0 / equatorial_radius_km, 1.0 / equatorial_radius_km, 1.0 / polar_radius_km])
    ps, us = p * S, u * S
    qa, qb, qc = np.sum(us * us, 1), np.sum(ps * us, 1), np.sum(ps * ps, 1) - 1.0
    disc = qb * qb - qa * qc
    with np.errstate(invalid="ignore"):
        # near root of qa t^2 + 2 qb t + qc = 0 in the cancellation-free form c / (-b + sqrt(disc))
        t = qc / (-qb + np.sqrt(disc))
    t = np.where((disc >= 0) & (t > 0), t, np.nan)
    return p + t[:, None] * u


def ground_latlon_truth(r_s_km) -> tuple[np.ndarray, np.ndarray]:
    """Geocentric latitude and longitude (rad) of Earth-fixed points, by ``atan2`` (eqs. 10-12)."""
    r = np.asarray(r_s_km, float)
    return np.arctan2(r[..., 2], np.hypot(r[..., 0], r[..., 1])), np.arctan2(r[..., 1], r[..., 0])


def ground_errors_truth_deg(r_s_km, latlon0_rad) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude errors (deg) of the ground points ``r_s_km`` against the nominal
    ``(lat0, lon0)`` (rad); the longitude difference wrapped to [-180, 180) deg."""
    lat, lon = ground_latlon_truth(r_s_km)
    dlon = np.mod(lon - latlon0_rad[1] + np.pi, 2 * np.pi) - np.pi
    return np.rad2deg(lat - latlon0_rad[0]), np.rad2deg(dlon)
