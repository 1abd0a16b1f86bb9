"""Image-motion geometry of the whiskbroom TDICCD camera (seed 002, Miao et al.).

The nine frames of the paper (its section 2, fig. 2; equations (1)-(6) were lost in
extraction and are reconstructed (docs/whiskbroom.md, [R]) from the
CIOMP image-motion-velocity-vector theory: Wang, Yu & Yan, *Acta Optica Sinica* 24(12)
1585 (2004); Wang et al., *Chinese Optics Letters* 3(7) 07414 (2005)):

* I geocentric inertial: I2 north pole, I3 the orbit's descending node, I1 = I2 x I3;
* E Earth-fixed, = I at t = 0, turning about E2 at the Earth rate (east);
* B orbit: B1 along the velocity, B3 zenith, B2 = B3 x B1 (orbit normal);
* S body: attitude (phi, theta, psi) of S in B, Euler 1-2-3, ``[S<-B] = R3 R2 R1``;
* M mirror: S turned 45 deg about S1, swinging about M1 = S1 at omega_x (eq. 1);
* C camera = S; P image plane: C shifted by f along C2, P1, P3 opposite to C1, C3.

A ground point fixed on the rotating Earth is seen along ``l^S = [S<-B][B<-I](r_g - r_s)``;
the mirror folds it, ``d = F(t) l^S`` with ``F = I - 2 n n^T`` and
``n = [M<-S]^T e3`` (the scan matrix, the reflection ``diag(1, 1, -1)`` and the inverse
scan matrix of the text); the central projection (eq. 2) puts it at
``x_P1 = -f d1/d2``, ``x_P3 = -f d3/d2``. The image-motion velocity (eq. 5) is
``V_P = dx_P/dt`` at t = 0, computed here by the **complex step** (Squire & Trapp, SIAM
Rev. 40, 110 (1998)): every function of the chain is evaluated at complex time
``t = i h`` and ``V = Im(x_P(ih))/h``, exact to rounding for any ``h`` small enough that
``h^2`` terms vanish (no subtraction, hence no truncation or cancellation error). The
drift angle (eq. 6) is ``beta = atan2(V_P3, V_P1)``.

The kinematic closed form (:func:`image_motion_kinematic`) differentiates the same chain
by hand (relative velocity, body angular velocity of the 1-2-3 sequence, and the mirror
identity ``F_dot l = 2 omega_x e1 x (F l)``); it shares nothing with the complex step and
serves as the independent check.

Units: positions km, times s, angles rad, focal length and image coordinates mm, image
velocities mm/s.

All functions accept a parameter array ``params`` of shape ``(S, len(PARAMS))`` (one row
per state; float or complex: the chain is analytic in every parameter, so a complex step
in a parameter gives its exact partial derivative, used by the first-order propagation).
"""

from __future__ import annotations

import numpy as np

__all__ = ["PARAMS", "P", "COMPLEX_STEP_S", "rot1", "rot2", "rot3", "chain_matrices",
           "ground_points", "image_position", "image_motion", "image_motion_kinematic",
           "drift_angle", "pushbroom_classical", "sun_synchronous_inclination",
           "scan_ground_trace", "make_params"]

#: columns of a parameter array
PARAMS = ("altitude_km", "speed_km_s", "inclination_rad", "gamma_rad", "roll_rad", "pitch_rad",
          "yaw_rad", "roll_rate_rad_s", "pitch_rate_rad_s", "yaw_rate_rad_s",
          "mirror_rate_rad_s", "mirror_rest_rad", "focal_length_mm", "earth_rate_rad_s",
          "earth_radius_km")
#: column index of each parameter
P = {name: i for i, name in enumerate(PARAMS)}

#: complex step in time, s (any h with h**2 * |x''| far below rounding works; 1e-20 s)
COMPLEX_STEP_S = 1e-20


def make_params(n: int = 1, **values) -> np.ndarray:
    """A ``(n, len(PARAMS))`` float array with the named columns set (others zero)."""
    unknown = set(values) - set(PARAMS)
    if unknown:
        raise KeyError(f"unknown parameters {sorted(unknown)}")
    out = np.zeros((n, len(PARAMS)))
    for k, v in values.items():
        out[:, P[k]] = v
    return out


def _col(params, name):
    return params[..., P[name]]


def rot1(a):
    """Passive frame rotation about axis 1 (Wertz 1978, App. E): ``[[1,0,0],[0,c,s],[0,-s,c]]``.

    Written out (not ``scipy.spatial.transform.Rotation``) because the complex step needs
    complex angles; tested against scipy for real angles.
    """
    a = np.asarray(a)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, s], -1), np.stack([z, -s, c], -1)], -2)


def rot2(a):
    """Passive frame rotation about axis 2: ``[[c,0,-s],[0,1,0],[s,0,c]]``."""
    a = np.asarray(a)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, z, -s], -1), np.stack([z, o, z], -1), np.stack([s, z, c], -1)], -2)


def rot3(a):
    """Passive frame rotation about axis 3: ``[[c,s,0],[-s,c,0],[0,0,1]]``."""
    a = np.asarray(a)
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(c), np.zeros_like(c)
    return np.stack([np.stack([c, s, z], -1), np.stack([-s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _orbit(params, t):
    """Satellite position ``r_s^I`` (km) and ``[B<-I]`` at time ``t`` (circular orbit).

    ``gamma(t) = gamma0 + (v/a) t`` counted from the ascending node ``-I3``; orbit normal
    ``h = sin i I1 + cos i I2``; ``r_s = a(cos g n_asc + sin g (h x n_asc))`` with
    ``h x n_asc = -cos i I1 + sin i I2`` (the reconstruction's step 3, docs/whiskbroom.md).
    """
    a = _col(params, "earth_radius_km") + _col(params, "altitude_km")
    inc = _col(params, "inclination_rad")
    g = _col(params, "gamma_rad") + _col(params, "speed_km_s") / a * t
    ci, si, cg, sg = np.cos(inc), np.sin(inc), np.cos(g), np.sin(g)
    z = np.zeros_like(cg)
    n_asc = np.stack([z, z, -np.ones_like(cg)], -1)
    hxn = np.stack([-ci, si, z], -1)
    h = np.stack([si, ci, z], -1)
    r_hat = cg[..., None] * n_asc + sg[..., None] * hxn
    v_hat = -sg[..., None] * n_asc + cg[..., None] * hxn
    b_from_i = np.stack([v_hat, h, r_hat], -2)       # rows B1, B2 = B3 x B1 = h, B3
    return a[..., None] * r_hat, b_from_i


def _mirror_fold(params, t):
    """``F(t) = [M<-S]^T diag(1,1,-1) [M<-S]`` with ``[M<-S] = R1(rest + omega_x t)`` (eq. 1)."""
    m = rot1(_col(params, "mirror_rest_rad") + _col(params, "mirror_rate_rad_s") * t)
    ref = np.diag([1.0, 1.0, -1.0])
    return np.swapaxes(m, -1, -2) @ ref @ m


def _attitude(params, t):
    """``[S<-B] = R3(psi) R2(theta) R1(phi)`` (Euler 1-2-3), angles linear in t."""
    phi = _col(params, "roll_rad") + _col(params, "roll_rate_rad_s") * t
    th = _col(params, "pitch_rad") + _col(params, "pitch_rate_rad_s") * t
    psi = _col(params, "yaw_rad") + _col(params, "yaw_rate_rad_s") * t
    return rot3(psi) @ rot2(th) @ rot1(phi)


def chain_matrices(params, t):
    """The time-dependent parts of the chain at time ``t`` (real or complex).

    Returns
    -------
    A : (S, 3, 3)
        ``F(t) [S<-B](t) [B<-I](t)``: inertial vector -> folded camera vector.
    r_s : (S, 3)
        Satellite position in I, km.
    E : (S, 3, 3)
        ``R2(omega_e t)^T``: Earth-fixed -> inertial components.
    """
    r_s, b_from_i = _orbit(params, t)
    A = _mirror_fold(params, t) @ _attitude(params, t) @ b_from_i
    E = np.swapaxes(rot2(_col(params, "earth_rate_rad_s") * t), -1, -2)
    return A, r_s, E


def ground_points(params, x1_mm, x3_mm, t=0.0):
    """Earth-fixed ground point (km) imaged at image point ``(x1, x3)`` at time ``t``.

    Ray cast on the sphere ``|r| = R_e``: the camera direction of image point ``(x1, x3)``
    is ``d^C = (x1, -f, x3)`` (inverse of eq. 2), ``l^I = A^T d^C`` (A is orthogonal),
    and the nearer root of ``|r_s + s l| = R_e``.

    Parameters
    ----------
    params : (S, len(PARAMS)) array
    x1_mm, x3_mm : (N,) arrays
        Image coordinates, mm.

    Returns
    -------
    (S, N, 3) array, km (NaN where the line of sight misses the Earth).
    """
    A, r_s, E = chain_matrices(params, t)
    f = _col(params, "focal_length_mm")
    x1b, x3b = np.broadcast_arrays(np.asarray(x1_mm), np.asarray(x3_mm))
    d = np.empty((f.shape[0],) + x1b.shape + (3,), dtype=np.result_type(f, x1b, A))
    d[..., 0] = x1b
    d[..., 1] = -f[:, None]
    d[..., 2] = x3b
    los = np.einsum("sji,snj->sni", A, d)                      # A^T d
    los = los / np.sqrt(np.sum(los * los, -1))[..., None]
    rs = r_s[:, None, :]
    b = np.sum(rs * los, -1)
    re = _col(params, "earth_radius_km")[:, None]
    c = np.sum(rs * rs, -1) - re * re
    disc = b * b - c
    if np.isrealobj(disc):
        disc = np.where(disc >= 0, disc, np.nan)
    s = -b - np.sqrt(disc)
    r_i = rs + s[..., None] * los
    return np.einsum("sji,snj->sni", E, r_i)                    # E^T r^I = r^E


def image_position(params, r_g_e, t):
    """Image coordinates ``(x_P1, x_P3)`` (mm) of Earth-fixed points at time ``t`` (eq. 2).

    ``d = A(t) (E(t) r_g^E - r_s(t))``, ``x_P1 = -f d1/d2``, ``x_P3 = -f d3/d2``.
    """
    A, r_s, E = chain_matrices(params, t)
    r_i = np.einsum("sij,snj->sni", E, r_g_e)
    d = np.einsum("sij,snj->sni", A, r_i - r_s[:, None, :])
    f = _col(params, "focal_length_mm")[:, None]
    return np.stack([-f * d[..., 0] / d[..., 1], -f * d[..., 2] / d[..., 1]], -1)


def image_motion(params, x1_mm, x3_mm, h: float = COMPLEX_STEP_S):
    """Image-motion velocity ``V_P`` (mm/s) at image points, by the complex step (eq. 5).

    The ground point seen at ``(x1, x3)`` at t = 0 is found by ray casting; its image
    position is then evaluated at complex time ``t = i h``: ``V = Im(x_P(ih)) / h``.

    Parameters
    ----------
    params : (S, len(PARAMS)) real array
    x1_mm, x3_mm : (N,) arrays

    Returns
    -------
    (S, N, 2) array, mm/s: ``(V_P1, V_P3)``.
    """
    params = np.asarray(params, dtype=float)
    g = ground_points(params, x1_mm, x3_mm)
    x = image_position(params.astype(complex), g.astype(complex), 1j * h)
    return x.imag / h


def _body_rate(params):
    """Angular velocity of S relative to I, in S axes, rad/s.

    Orbit frame: ``omega_BI = (v/a) B2``; 1-2-3 Euler rates (Wertz 1978 eq. 12-13 form):
    ``omega_SB = R3 R2 (phidot,0,0) + R3 (0,thetadot,0) + (0,0,psidot)``.
    """
    z = np.zeros_like(_col(params, "roll_rad"))
    psi, th = _col(params, "yaw_rad"), _col(params, "pitch_rad")
    r3, r2 = rot3(psi), rot2(th)
    e_roll = np.stack([_col(params, "roll_rate_rad_s"), z, z], -1)
    e_pitch = np.stack([z, _col(params, "pitch_rate_rad_s"), z], -1)
    e_yaw = np.stack([z, z, _col(params, "yaw_rate_rad_s")], -1)
    w_sb = (np.einsum("sij,sj->si", r3 @ r2, e_roll) + np.einsum("sij,sj->si", r3, e_pitch) + e_yaw)
    a = _col(params, "earth_radius_km") + _col(params, "altitude_km")
    w_bi_b = np.stack([z, _col(params, "speed_km_s") / a, z], -1)
    w_bi_s = np.einsum("sij,sj->si", _attitude(params, 0.0), w_bi_b)
    return w_sb + w_bi_s


def image_motion_kinematic(params, x1_mm, x3_mm):
    """Image-motion velocity (mm/s) by the kinematic closed form (independent check).

    ``l^S = [S<-B][B<-I](r_g - r_s)``; ``ldot = [S<-I](v_g - v_s) - omega x l`` with
    ``v_g = omega_e I2 x r_g``, ``v_s = v B1``, ``omega`` from :func:`_body_rate`;
    ``d = F l``, ``ddot = F ldot + 2 omega_x e1 x d`` (a reflection whose plane contains
    the rotation axis: ``F_dot l = 2 (omega_x e1) x (F l)``); then
    ``V_P1 = -f (ddot1 d2 - d1 ddot2)/d2^2``, ``V_P3 = -f (ddot3 d2 - d3 ddot2)/d2^2``.
    Works for complex ``params`` (used for parameter derivatives by complex step).
    """
    r_g_i = ground_points(params, x1_mm, x3_mm)                  # E = I at t = 0
    r_s, b_from_i = _orbit(params, 0.0)
    s_from_i = _attitude(params, 0.0) @ b_from_i
    F = _mirror_fold(params, 0.0)
    we = _col(params, "earth_rate_rad_s")
    z = np.zeros_like(we)
    v_g = np.cross(np.stack([z, we, z], -1)[:, None, :], r_g_i)
    v_s = _col(params, "speed_km_s")[:, None] * b_from_i[:, 0, :]
    l = np.einsum("sij,snj->sni", s_from_i, r_g_i - r_s[:, None, :])
    v_rel = np.einsum("sij,snj->sni", s_from_i, v_g - v_s[:, None, :])
    w = _body_rate(params)[:, None, :]
    ldot = v_rel - np.cross(np.broadcast_to(w, l.shape), l)
    d = np.einsum("sij,snj->sni", F, l)
    wx = _col(params, "mirror_rate_rad_s")
    e1w = np.stack([wx, z, z], -1)[:, None, :]
    ddot = np.einsum("sij,snj->sni", F, ldot) + 2.0 * np.cross(np.broadcast_to(e1w, d.shape), d)
    f = _col(params, "focal_length_mm")[:, None]
    d2 = d[..., 1]
    v1 = -f * (ddot[..., 0] * d2 - d[..., 0] * ddot[..., 1]) / (d2 * d2)
    v3 = -f * (ddot[..., 2] * d2 - d[..., 2] * ddot[..., 1]) / (d2 * d2)
    return np.stack([v1, v3], -1)


def drift_angle(v):
    """Drift angle (eq. 6), rad: the angle of the image motion from the push-broom direction.

    ``beta = atan2(-V_P3, -V_P1)``. In the reconstructed P axes a nadir push-broom image
    moves along -P1 (the ground recedes backwards); the overall sign of the P axes is the
    paper's inversion convention and is not recoverable, so beta is measured from that
    direction: 0 for a push-broom camera without Earth rotation, +4.23 deg at the equator
    with it (1200 km sun-synchronous), about +76 deg while the mirror scans at +0.6 deg/s.
    """
    v = np.asarray(v)
    return np.arctan2(-v[..., 1], -v[..., 0])


def pushbroom_classical(altitude_km, inclination_rad, gamma_rad, focal_length_mm, *,
                        mu_km3_s2, earth_radius_km, earth_rate_rad_s):
    """Classical nadir push-broom image speed (mm/s) and drift angle (rad).

    ``V = (f/H) R_e omega_s sqrt((1 - k cos i)^2 + (k sin i cos gamma)^2)``,
    ``tan beta = k sin i cos gamma / (1 - k cos i)``, ``k = omega_e/omega_s``
    (Wang et al. 2004; standard drift-angle theory, e.g. Chen Shiping 2009, 186-187).
    """
    a = earth_radius_km + altitude_km
    ws = np.sqrt(mu_km3_s2 / a**3)
    k = earth_rate_rad_s / ws
    along = 1.0 - k * np.cos(inclination_rad)
    cross = k * np.sin(inclination_rad) * np.cos(gamma_rad)
    v = focal_length_mm / altitude_km * earth_radius_km * ws * np.hypot(along, cross)
    return v, np.arctan2(cross, along)


def sun_synchronous_inclination(altitude_km, *, mu_km3_s2, earth_radius_km, j2,
                                nodal_rate_rad_s):
    """Inclination (rad) of a circular sun-synchronous orbit (Vallado 2013 eq. 9-41).

    ``cos i = -2 Omega_dot a^(7/2) / (3 J2 R_e^2 sqrt(mu))``.
    """
    a = earth_radius_km + altitude_km
    c = -2.0 * nodal_rate_rad_s * a**3.5 / (3.0 * j2 * earth_radius_km**2 * np.sqrt(mu_km3_s2))
    if not -1.0 <= c <= 1.0:
        raise ValueError(f"no sun-synchronous orbit at altitude {altitude_km} km (cos i = {c:.3f})")
    return float(np.arccos(c))


def scan_ground_trace(params, x1_mm, x3_mm, times_s):
    """Geodetic-sphere latitude and longitude (deg) of image points while the mirror scans.

    For each time the chain is evaluated at that real time and the image points are ray
    cast; longitude is Earth-fixed, east positive, from the orbit's ascending node at t = 0
    (the direction -E3), unwrapped along the trace.

    Returns
    -------
    lat, lon : (T, N) arrays, deg.
    """
    params = np.atleast_2d(np.asarray(params, dtype=float))
    lat, lon = [], []
    for t in np.asarray(times_s, dtype=float):
        g = ground_points(params[:1], x1_mm, x3_mm, t=t)[0]
        lat.append(np.degrees(np.arcsin(g[:, 1] / np.linalg.norm(g, axis=-1))))
        lon.append(np.arctan2(-g[:, 0], -g[:, 2]))
    return np.array(lat), np.degrees(np.unwrap(np.array(lon), axis=0))
