"""Orbit of the scan-mirror spacecraft: osculating elements, zonal J2-J4 Cowell propagation,
the instantaneous orbit frame and the orbit-error matrix ``A_r0r`` (seed 003, eqs. 8, 20-21 [R]).

Inertial frame ``I``: the GCRS axes (z along the Earth's pole, idealised: no precession or
nutation over the run). Earth-fixed frame ``s``: ``r_s = R_z(G)^T r_I`` with the idealised
sidereal angle ``G(t) = G0 + omega_e t`` of the paper (G0 = 0 at t = 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from simcam.scanmirror.geometry import P_ORBIT, nominal_orbit_matrix_sr0, rot_x, rot_z
from simcam.units import JGM3_RADIUS_KM, WGS84_F

__all__ = ["EarthModel", "elements_to_state", "state_to_elements", "zonal_acceleration", "Orbit",
           "propagate", "orbit_frame_matrix_Ir", "earth_fixed_matrix_sI"]


@dataclass(frozen=True)
class EarthModel:
    """Gravity and shape constants. Defaults: JGM-3 (Tapley et al. 1996, JGR 101(B12) 28029),
    ``J_n = -sqrt(2 n + 1) C_n0`` from its normalised zonal coefficients; WGS-84 flattening."""

    mu_km3_s2: float = 398600.4415
    radius_km: float = JGM3_RADIUS_KM
    j2: float = 1.0826360229829945e-3
    j3: float = -2.5324353457543954e-6
    j4: float = -1.619331205071e-6
    rotation_rad_s: float = 7.292115e-5
    flattening: float = WGS84_F
    zonal_degree: int = 4


def elements_to_state(mu, a_km, e, i_rad, raan_rad, argp_rad, nu_rad):
    """Position (km) and velocity (km/s) in ``I`` from classical osculating elements
    (Vallado 2013, Algorithm 10 COE2RV: perifocal state rotated by R3(-raan) R1(-i) R3(-argp))."""
    p = a_km * (1.0 - e * e)
    r_pqw = np.array([p * np.cos(nu_rad), p * np.sin(nu_rad), 0.0]) / (1.0 + e * np.cos(nu_rad))
    v_pqw = np.sqrt(mu / p) * np.array([-np.sin(nu_rad), e + np.cos(nu_rad), 0.0])
    Q = rot_z(raan_rad) @ rot_x(i_rad) @ rot_z(argp_rad)
    return Q @ r_pqw, Q @ v_pqw


def state_to_elements(mu, r, v):
    """(a, e, i, raan, argp, nu) from a state (Vallado 2013, Algorithm 9 RV2COE), vectorised over
    leading axes; angles in rad. For tests and diagnostics."""
    r, v = np.asarray(r, float), np.asarray(v, float)
    h = np.cross(r, v)
    rn, vn, hn = (np.linalg.norm(x, axis=-1) for x in (r, v, h))
    n = np.cross(np.array([0.0, 0.0, 1.0]), h)
    nn = np.linalg.norm(n, axis=-1)
    ev = ((vn**2 - mu / rn)[..., None] * r - np.sum(r * v, -1)[..., None] * v) / mu
    e = np.linalg.norm(ev, axis=-1)
    a = 1.0 / (2.0 / rn - vn**2 / mu)
    i = np.arccos(h[..., 2] / hn)
    raan = np.mod(np.arctan2(n[..., 1], n[..., 0]), 2 * np.pi)
    argp = np.arccos(np.clip(np.sum(n * ev, -1) / (nn * e), -1, 1))
    argp = np.where(ev[..., 2] < 0, 2 * np.pi - argp, argp)
    nu = np.arccos(np.clip(np.sum(ev * r, -1) / (e * rn), -1, 1))
    nu = np.where(np.sum(r * v, -1) < 0, 2 * np.pi - nu, nu)
    return a, e, i, raan, argp, nu


def zonal_acceleration(r_km, earth: EarthModel) -> np.ndarray:
    """Point mass plus zonal J2, J3, J4 acceleration (km/s^2) at ``r_km`` (..., 3) in a frame
    whose z is the Earth's pole (Vallado 2013, eqs. 8-30 and 8-31 (the J2-J4 terms of the
    gradient of the zonal potential); Montenbruck & Gill 2000 section 3.2). Degree 0 gives
    the two-body acceleration."""
    r = np.asarray(r_km, float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    r2 = np.sum(r * r, -1)
    rn = np.sqrt(r2)
    mu, R = earth.mu_km3_s2, earth.radius_km
    k = -mu / (r2 * rn)
    ax, ay, az = k * x, k * y, k * z
    zr2 = z * z / r2
    if earth.zonal_degree >= 2:
        f = -1.5 * earth.j2 * mu * R**2 / rn**5
        ax = ax + f * x * (1 - 5 * zr2)
        ay = ay + f * y * (1 - 5 * zr2)
        az = az + f * z * (3 - 5 * zr2)
    if earth.zonal_degree >= 3:
        f = -2.5 * earth.j3 * mu * R**3 / rn**7
        ax = ax + f * x * (3 * z - 7 * z**3 / r2)
        ay = ay + f * y * (3 * z - 7 * z**3 / r2)
        az = az + f * (6 * z * z - 7 * z**4 / r2 - 0.6 * r2)
    if earth.zonal_degree >= 4:
        f = 15.0 / 8.0 * earth.j4 * mu * R**4 / rn**7
        ax = ax + f * x * (1 - 14 * zr2 + 21 * zr2**2)
        ay = ay + f * y * (1 - 14 * zr2 + 21 * zr2**2)
        az = az + f * z * (5 - 70.0 / 3.0 * zr2 + 21 * zr2**2)
    return np.stack([ax, ay, az], -1)


class Orbit:
    """A propagated orbit: ``state(t)`` -> (r, v) in ``I`` from the DOP853 dense output."""

    def __init__(self, sol, t0: float, t1: float):
        self._sol = sol
        self.t0, self.t1 = t0, t1

    def state(self, t_s):
        """Position (km) and velocity (km/s), arrays (N, 3), at times ``t_s`` (s)."""
        y = self._sol(np.atleast_1d(np.asarray(t_s, float))).T
        return y[:, :3], y[:, 3:]


def propagate(r0_km, v0_km_s, t_end_s: float, earth: EarthModel, *, rtol: float = 1e-12,
              atol_km: float = 1e-9) -> Orbit:
    """Cowell propagation of ``r'' = a_zonal(r)`` with scipy's DOP853 (Hairer, Norsett &
    Wanner 1993, the 8(5,3) Dormand-Prince pair) and dense output over [0, t_end_s]."""

    def rhs(_t, y):
        return np.concatenate([y[3:], zonal_acceleration(y[:3], earth)])

    sol = solve_ivp(rhs, (0.0, float(t_end_s)), np.concatenate([r0_km, v0_km_s]), method="DOP853",
                    rtol=rtol, atol=atol_km, dense_output=True)
    if not sol.success:  # pragma: no cover - DOP853 on a smooth field
        raise RuntimeError(f"orbit propagation failed: {sol.message}")
    return Orbit(sol.sol, 0.0, float(t_end_s))


def orbit_frame_matrix_Ir(r_km, v_km_s) -> np.ndarray:
    """Instantaneous orbit frame ``r`` in ``I``: columns x (along track), y = -h/|h| (south for
    a prograde equatorial orbit), z = -r/|r| (nadir); shape (N, 3, 3)."""
    z = -r_km / np.linalg.norm(r_km, axis=-1, keepdims=True)
    h = np.cross(r_km, v_km_s)
    y = -h / np.linalg.norm(h, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return np.stack([x, y, z], -1)


def earth_fixed_matrix_sI(t_s, earth: EarthModel, g0_rad: float) -> np.ndarray:
    """``A_sI = R_z(G)^T`` with the idealised sidereal angle ``G = G0 + omega_e t``."""
    G = g0_rad + earth.rotation_rad_s * np.asarray(t_s, float)
    return np.swapaxes(rot_z(G), -1, -2)


def orbit_error_matrix_r0r(r_km, v_km_s, t_s, earth: EarthModel, g0_rad: float, omega0_rad: float):
    """Exact ``A_r0r = A_sr0^T A_sI A_Ir`` (eq. 8 [R]) and the orbit radius R (km)."""
    A_sI = earth_fixed_matrix_sI(t_s, earth, g0_rad)
    A = nominal_orbit_matrix_sr0(omega0_rad).T @ A_sI @ orbit_frame_matrix_Ir(r_km, v_km_s)
    return A, np.linalg.norm(r_km, axis=-1)


def first_order_orbit_error_matrix(i_sin_u, i_cos_u, u_plus_dOmega) -> np.ndarray:
    """First-order ``A_r0r`` of eq. (21) [R]: ``[[1, dchi, -(u+dOm)], [-dchi, 1, i sin u],
    [u+dOm, -i sin u, 1]]`` with ``dchi = i cos u``."""
    a, c, w = (np.asarray(x, float) for x in np.broadcast_arrays(i_sin_u, i_cos_u, u_plus_dOmega))
    o = np.ones_like(a)
    return np.stack([np.stack([o, c, -w], -1), np.stack([-c, o, a], -1), np.stack([w, -a, o], -1)], -2)


def orbit_angles(r_km, v_km_s, t_s, earth: EarthModel, g0_rad: float, omega0_rad: float):
    """Inclination i, argument of latitude u and node-longitude offset ``dOmega = RAAN - G -
    Omega_0`` (rad) of the instantaneous orbit (eq. 20 [R]); each (N,)."""
    h = np.cross(r_km, v_km_s)
    hn = np.linalg.norm(h, axis=-1)
    i = np.arccos(h[..., 2] / hn)
    raan = np.arctan2(h[..., 0], -h[..., 1])
    node = np.stack([np.cos(raan), np.sin(raan), np.zeros_like(raan)], -1)
    u = np.arctan2(np.sum(np.cross(node, r_km) * h, -1) / hn, np.sum(node * r_km, -1))
    G = g0_rad + earth.rotation_rad_s * np.asarray(t_s, float)
    d_omega = np.mod(raan - G - omega0_rad + np.pi, 2 * np.pi) - np.pi
    return i, u, d_omega


def exact_orbit_error_matrix(i_rad, u_rad, d_omega_rad) -> np.ndarray:
    """``A_r0r = P^T R_z(dOmega) R_x(i) R_z(u) P`` (eq. 20 [R])."""
    return P_ORBIT.T @ rot_z(d_omega_rad) @ rot_x(i_rad) @ rot_z(u_rad) @ P_ORBIT


def orbit_error_parameters(i_rad, u_rad, d_omega_rad) -> np.ndarray:
    """The paper's three small orbit angles ``(i sin u, i cos u, u + dOmega)`` (eq. 21 [R]),
    ``u + dOmega`` wrapped to (-pi, pi]; shape (..., 3)."""
    w = np.mod(u_rad + d_omega_rad + np.pi, 2 * np.pi) - np.pi
    return np.stack([i_rad * np.sin(u_rad), i_rad * np.cos(u_rad), w], -1)


__all__ += ["orbit_error_matrix_r0r", "first_order_orbit_error_matrix", "orbit_error_parameters", "orbit_angles",
            "exact_orbit_error_matrix"]
