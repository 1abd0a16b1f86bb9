"""Scan-angle compensation (seed 003, eqs. 22-32 [R]): the small corrections (Delta alpha,
Delta beta) that put the ground point of the line of sight back on its nominal place.

* ``published``: the paper's first-order solution. The ground point's x and y components in
  the nominal orbit frame (eq. 30) are linearised at the nominal angles and zero error in the
  nine error parameters ``p = (dtau_x, dtau_y, roll, pitch, yaw, i sin u, i cos u, u + dOmega,
  dR)`` and in (Delta alpha, Delta beta): ``J [Delta alpha, Delta beta]^T = -G p`` solved by
  Cramer's rule (eqs. 31-32). J and G (the coefficients of eqs. 24-30, lost in extraction) are
  obtained from the forward model by central differences, which gives the same first-order
  coefficients; they depend only on the nominal angles, so they are computed once per plan.
* ``improved``: the exact compensation: Newton iterations on the lab's exact forward model
  (exact attitude matrix, exact orbit-error matrix from the known orbit, exact reflection)
  until the modelled ground point equals the nominal one.

Both use only what the lab knows (its attitude and orbit knowledge, its deviation estimate).
"""

from __future__ import annotations

import numpy as np

from simcam.scanmirror.geometry import attitude_matrix_br
from simcam.scanmirror.orbit import first_order_orbit_error_matrix

__all__ = ["PARAMETERS", "first_order_forward", "FirstOrderCompensator", "exact_compensation"]

PARAMETERS = ("dtau_x", "dtau_y", "roll", "pitch", "yaw", "i_sin_u", "i_cos_u", "u_plus_dOmega", "dR_km")
_H_RAD = 1e-6
_H_KM = 1e-3


def first_order_forward(world, alpha, beta, p):
    """x, y of the ground point in ``r0`` (km) with the first-order orbit matrix (eq. 21) and the
    nine parameters ``p`` (..., 9)."""
    p = np.asarray(p, float)
    A = first_order_orbit_error_matrix(p[..., 5], p[..., 6], p[..., 7])
    return world.ground(alpha, beta, p[..., 0], p[..., 1], p[..., 2:5], A, world.R0_km + p[..., 8])[..., :2]


class FirstOrderCompensator:
    """The published first-order compensation at the nominal angles ``alpha0, beta0`` (N,)."""

    def __init__(self, world, alpha0, beta0):
        self.alpha0, self.beta0 = np.asarray(alpha0, float), np.asarray(beta0, float)
        n = self.alpha0.shape[0]
        z = np.zeros((n, 9))
        J = np.empty((n, 2, 2))
        for j, (da, db) in enumerate(((_H_RAD, 0.0), (0.0, _H_RAD))):
            plus = first_order_forward(world, self.alpha0 + da, self.beta0 + db, z)
            minus = first_order_forward(world, self.alpha0 - da, self.beta0 - db, z)
            J[:, :, j] = (plus - minus) / (2 * _H_RAD)
        G = np.empty((n, 2, 9))
        for k in range(9):
            h = _H_KM if k == 8 else _H_RAD
            dp = np.zeros((n, 9))
            dp[:, k] = h
            G[:, :, k] = (first_order_forward(world, self.alpha0, self.beta0, dp)
                          - first_order_forward(world, self.alpha0, self.beta0, -dp)) / (2 * h)
        # Cramer's rule (eqs. 31-32): [da, db] = -J^-1 G p
        det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
        Jinv = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], -1), np.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], -2)
        Jinv /= det[:, None, None]
        self.J, self.G = J, G
        self.K = -Jinv @ G   # (N, 2, 9)

    def corrections(self, p) -> tuple[np.ndarray, np.ndarray]:
        """(Delta alpha, Delta beta) (rad) for the error parameters ``p`` (N, 9) or (9,)."""
        d = np.einsum("nij,nj->ni", self.K, np.broadcast_to(np.asarray(p, float), (self.K.shape[0], 9)))
        return d[:, 0], d[:, 1]


def exact_compensation(world, alpha0, beta0, dtau_x, dtau_y, att, A_r0r, R_km, *, iterations: int = 6,
                       tol_rad: float = 1e-13, use_kernel: bool = True, target=None):
    """The exact compensation: Newton iterations (Jacobian by central differences) on the lab's
    model until ``x, y`` of its ground point in ``r0`` equal the nominal ones (until the
    step is below ``tol_rad``). Returns the commanded (alpha, beta) (rad). On the sphere the
    numba kernel (:mod:`budget.scanmirror.kernels`) runs the same iterations point by point
    (``use_kernel=False``: the vectorised numpy path, used to test it)."""
    if target is None:
        target = world.nominal_ground(alpha0, beta0)[..., :2]
    a, b = np.array(alpha0, float), np.array(beta0, float)
    att = np.asarray(att, float)
    A_br = attitude_matrix_br(att[..., 0], att[..., 1], att[..., 2])
    if world.scenario.orbit.earth_shape == "sphere" and use_kernel:
        from budget.scanmirror.kernels import exact_compensation_sphere

        n = a.shape[0]
        tx = np.ascontiguousarray(np.broadcast_to(np.asarray(dtau_x, float), (n,)))
        ty = np.ascontiguousarray(np.broadcast_to(np.asarray(dtau_y, float), (n,)))
        return exact_compensation_sphere(a, b, tx, ty, np.ascontiguousarray(A_br),
                                         np.ascontiguousarray(np.broadcast_to(A_r0r, (n, 3, 3))),
                                         np.ascontiguousarray(np.broadcast_to(np.asarray(R_km, float), (n,))),
                                         float(world.earth.radius_km), np.ascontiguousarray(target), iterations,
                                         tol_rad, _H_RAD)

    def f(a_, b_):
        return world.ground(a_, b_, dtau_x, dtau_y, None, A_r0r, R_km, A_br=A_br)[..., :2]

    for _ in range(iterations):
        r = f(a, b) - target
        Ja = (f(a + _H_RAD, b) - f(a - _H_RAD, b)) / (2 * _H_RAD)
        Jb = (f(a, b + _H_RAD) - f(a, b - _H_RAD)) / (2 * _H_RAD)
        det = Ja[:, 0] * Jb[:, 1] - Jb[:, 0] * Ja[:, 1]
        da = (Jb[:, 1] * r[:, 0] - Jb[:, 0] * r[:, 1]) / det
        db = (-Ja[:, 1] * r[:, 0] + Ja[:, 0] * r[:, 1]) / det
        a, b = a - da, b - db
        if max(np.abs(da).max(), np.abs(db).max()) < tol_rad:
            break
    return a, b


def ground_errors_deg(world, r_e_r0, r_e0_r0, *, latlon0=None):
    """Latitude and longitude errors (deg) of ground points against their nominal ones (eq. 21
    of the paper's error definition: Delta lambda = lambda - lambda_0, Delta delta = delta - delta_0)."""
    lat, lon = world.latlon(r_e_r0)
    lat0, lon0 = world.latlon(r_e0_r0) if latlon0 is None else latlon0
    dlon = np.mod(lon - lon0 + np.pi, 2 * np.pi) - np.pi
    return np.rad2deg(lat - lat0), np.rad2deg(dlon)


__all__ += ["ground_errors_deg"]
