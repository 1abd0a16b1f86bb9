"""Attitude of the Earth-pointing spacecraft (seed 003, eq. 20 [R]): small 3-1-2 Euler angles
(roll phi, pitch theta, yaw psi) of the body relative to the instantaneous orbit frame.

Two sources: a PD-controlled rigid body (the paper's law, inertias and gains are lost; ours are
stated in the scenario) or a prescribed profile (constant + sinusoid per axis).

PD model: the linearised Euler equations of a rigid body whose reference frame turns at the
orbit rate omega_0 about the orbit normal (-y_r), gravity-gradient torque omitted (derived from
``I w' + w x I w = T`` with ``w = (phi' - w0 psi, theta' - w0, psi' + w0 phi)``; the same
form as Wie 2008, Space Vehicle Dynamics and Control, section 7.2, without the
gravity-gradient terms)::

    Ix phi''   - w0 (Ix - Iy + Iz) psi' - w0^2 (Iz - Iy) phi = Tx
    Iy theta''                                         = Ty
    Iz psi''   + w0 (Ix - Iy + Iz) phi' + w0^2 (Iy - Ix) psi = Tz

with ``T = -Kp e - Kd e' + T_dist`` (constant disturbance torque). The solution of the linear
system ``x' = A x + b`` is ``x(t) = x_ss + expm(A t) (x0 - x_ss)``, ``x_ss = -A^-1 b``,
evaluated through the eigen-decomposition ``A = V diag(lambda) V^-1`` (modal solution
``x(t) = x_ss + Re(V (exp(lambda t) * V^-1 (x0 - x_ss)))``), computed once per scenario; a
Monte Carlo trial draws only ``x0``. Tested against scipy's ``expm``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import expm

__all__ = ["pd_system_matrix", "PDAttitude", "profile_attitude"]


def pd_system_matrix(inertia_kg_m2, kp_n_m_rad, kd_n_m_s_rad, omega0_rad_s, torque_n_m=(0.0, 0.0, 0.0)):
    """``A`` (6x6) and ``b`` (6,) of ``x' = A x + b``, ``x = (phi, theta, psi, phi', theta', psi')``."""
    Ix, Iy, Iz = (float(v) for v in inertia_kg_m2)
    kp = np.broadcast_to(np.asarray(kp_n_m_rad, float), (3,))
    kd = np.broadcast_to(np.asarray(kd_n_m_s_rad, float), (3,))
    w0 = float(omega0_rad_s)
    A = np.zeros((6, 6))
    A[0:3, 3:6] = np.eye(3)
    h = Ix - Iy + Iz
    # roll
    A[3, 0] = (w0**2 * (Iz - Iy) - kp[0]) / Ix
    A[3, 3] = -kd[0] / Ix
    A[3, 5] = w0 * h / Ix
    # pitch
    A[4, 1] = -kp[1] / Iy
    A[4, 4] = -kd[1] / Iy
    # yaw
    A[5, 2] = (-w0**2 * (Iy - Ix) - kp[2]) / Iz
    A[5, 5] = -kd[2] / Iz
    A[5, 3] = -w0 * h / Iz
    b = np.zeros(6)
    b[3:6] = np.asarray(torque_n_m, float) / np.array([Ix, Iy, Iz])
    return A, b


class PDAttitude:
    """The PD-controlled attitude on the times ``t_s`` (from t = 0), modal solution."""

    def __init__(self, A, b, t_s):
        self.A, self.b = np.asarray(A, float), np.asarray(b, float)
        self.t_s = np.asarray(t_s, float)
        self.x_ss = -np.linalg.solve(self.A, self.b)
        lam, V = np.linalg.eig(self.A)
        if np.linalg.cond(V) > 1e8:  # (nearly) defective: fall back to the matrix exponential
            self._phi = expm(self.A[None, :, :] * self.t_s[:, None, None])
        else:
            self._phi = None
            self._V, self._Vinv = V, np.linalg.inv(V)
            self._exp = np.exp(np.outer(self.t_s, lam))  # (N, 6)

    def angles(self, x0) -> np.ndarray:
        """(N, 3) roll, pitch, yaw (rad) from the initial state ``x0`` (6,) (rad, rad/s)."""
        d = np.asarray(x0, float) - self.x_ss
        if self._phi is not None:
            return (self.x_ss + self._phi @ d)[:, :3]
        c = self._Vinv @ d
        return self.x_ss[:3] + np.real((self._exp * c) @ self._V[:3].T)


def profile_attitude(t_s, constant_rad, amplitude_rad, period_s, phase_rad) -> np.ndarray:
    """Prescribed attitude: ``c + a sin(2 pi t / P + phase)`` per axis; (N, 3) rad."""
    t = np.asarray(t_s, float)[:, None]
    return (np.asarray(constant_rad, float) + np.asarray(amplitude_rad, float)
            * np.sin(2 * np.pi * t / np.asarray(period_s, float) + np.asarray(phase_rad, float)))
