"""Image motion of the whiskbroom camera's world by ray tracing to the Earth ellipsoid.

An independent route to the image-motion velocity ``V_P`` of seed 002 (Miao, He, Wang,
Chen, Yang, whiskbroom TDICCD space camera: image-motion velocity model and Monte Carlo
residual synthesis; CIOMP image-motion-velocity-vector theory of Wang, Yu & Yan, *Acta
Optica Sinica* 24(12) 1585 (2004)). It shares no code with
:mod:`simcam.whiskbroom.geometry` (no import; its own vector rotations by Rodrigues'
formula instead of the passive rotation matrices there) and differentiates nothing
analytically: a pixel's line of sight is traced backwards to the ground, the ground point
is held fixed on the rotating Earth, re-projected forwards at ``t - dt`` and ``t + dt``,
and the velocity is the central finite difference of the projected points.

Frames (the paper's, as its text defines them; all right-handed):

* I inertial: I2 the north pole, I3 the orbit's descending node, I1 = I2 x I3.
* E Earth-fixed: = I at t = 0, turning east (counter-clockwise seen from the north) about
  I2 at ``omega_e``; a point fixed on the Earth is at ``Rot(I2, omega_e t) r^E`` in I.
* Orbit: circular, radius ``a = R_eq + H`` (``R_eq`` the equatorial radius, so over the
  ellipsoid the height above the surface grows towards the poles), ascending node along
  ``-I3``, normal ``h = sin i I1 + cos i I2``, position ``a Rot(h, gamma) (-I3)`` with the
  argument of latitude ``gamma(t) = gamma0 + (v/a) t`` and ``v = sqrt(mu/a)`` unless given.
  B axes: B1 along the velocity ``h x r``, B3 zenith, B2 = B3 x B1 (= h).
* S body: attitude (roll phi, pitch theta, psi yaw) of S in B, Euler order 1-2-3 (turn
  about B1 by phi, then about the new 2 axis by theta, then about the new 3 axis by psi;
  Wertz, *Spacecraft Attitude Determination and Control*, 1978, sec. 12.1), each angle
  linear in time.
* Mirror: a plane mirror whose unit normal, in S, is ``e3`` turned about S1 by
  ``alpha(t) = alpha0 + omega_x t`` (``alpha0`` = 45 deg: normal ``(0, -1, 1)/sqrt 2``),
  i.e. the paper's mirror frame M = S turned about M1 = S1. Reflection:
  ``r' = r - 2 (r . n) n`` (its own inverse).
* Camera C = S, pinhole of focal length f at the origin looking along -C2 at the mirror;
  the image plane P lies at +f along C2 with P1, P3 opposite to C1, C3, so the image
  point ``(x1, x3)`` (mm) sits at ``(-x1, f, -x3)`` in C and its ray leaves the pinhole
  along ``(x1, -f, x3)``; a scene direction ``d`` in C is imaged at
  ``x1 = -f d1/d2``, ``x3 = -f d3/d2`` (central projection, ``d2 < 0``).
* Earth: the WGS 84 ellipsoid (NIMA TR8350.2, 3rd ed., 2000: a = 6378.137 km,
  1/f = 298.257223563), polar axis E2: ``(x^2 + z^2)/a^2 + y^2/b^2 = 1``, b = a (1 - f);
  ``flattening = 0`` gives the sphere of radius a (the paper's model).

Back-trace (:func:`ground_points`): the pixel's ray ``(x1, -f, x3)`` is reflected by the
mirror, expressed in I through the body axes, turned into E and intersected with the
ellipsoid: in coordinates scaled by ``(a, b, a)`` the ellipsoid is the unit sphere and
``|p + s u|^2 = 1`` is the quadratic ``A s^2 + 2 B s + C = 0``, whose nearer root is taken
in the cancellation-free form ``s = C / (-B + sqrt(B^2 - A C))`` (Press et al.,
*Numerical Recipes*, 3rd ed., 2007, sec. 5.6).

Forward (:func:`project`): ground point (E) -> Earth rotation -> I -> relative to the
satellite -> S (body axes) -> mirror reflection -> pinhole.

Image motion (:func:`image_motion`): ``V = (x(t + dt) - x(t - dt)) / (2 dt)``; error
``|x'''| dt^2 / 6`` (truncation) plus ``delta / dt`` (rounding, ``delta`` the rounding
error of one projected point). The step study (:func:`step_study`,
``docs/whiskbroom.md``, "Independent image motion") on the default scenario (the 199
synthesis field points of the three arrays) measures ``delta`` of about 1.5e-12 mm (``eps f |r_s| / rho``: the
unit roundoff of positions of size ``|r_s|`` seen over the range ``rho``) and a truncation
error of 0.0143 dt^2 mm/s, i.e. ``|x'''|`` = 0.086 mm/s^3 (the scan, ``x = f tan(2 omega_x
t)``, gives ``16 f omega_x^3`` = 0.081). The total is smallest near
``dt = (3 delta / |x'''|)^(1/3)`` = 4e-4 s: :data:`DT_S`, where the measured error is at
most 5.6e-9 mm/s (6e-11 of V = 97 mm/s). :func:`error_bound` evaluates a bound for a given
state.

Units: km, s, rad; focal length and image coordinates mm; image velocities mm/s.
Everything is vectorised over pixels (N,) and instants (T,): outputs ``(T, N, ...)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from simcam.units import EARTH_RATE_RAD_S, MU_EARTH_KM3_S2, SECONDS_PER_DAY, WGS84_A_KM, WGS84_F

__all__ = ["DT_S", "World", "rodrigues", "satellite_state",
           "lines_of_sight", "ground_points", "project", "image_motion", "drift_angle",
           "tdi_components", "error_bound", "step_study", "sun_synchronous_inclination"]

#: default central-difference half step, s (step study in the module docstring)
DT_S = 4e-4
#: double-precision unit roundoff
_EPS = np.finfo(float).eps


def sun_synchronous_inclination(altitude_km, *, mu_km3_s2, earth_radius_km, j2,
                                nodal_rate_rad_s) -> float:
    """Inclination (rad) of a circular sun-synchronous orbit from the J2 nodal rate.

    ``Omega_dot = -3/2 n J2 (R/a)^2 cos i`` with ``n = sqrt(mu/a^3)`` (Vallado,
    *Fundamentals of Astrodynamics and Applications*, 4th ed., 2013, eq. 9-41) solved for i.
    """
    a = earth_radius_km + altitude_km
    n = math.sqrt(mu_km3_s2 / a**3)
    c = nodal_rate_rad_s / (-1.5 * n * j2 * (earth_radius_km / a) ** 2)
    if not -1.0 <= c <= 1.0:
        raise ValueError(f"no sun-synchronous orbit at altitude {altitude_km} km (cos i = {c:.3f})")
    return math.acos(c)


@dataclass(frozen=True)
class World:
    """The state of the camera's world (scalars; one orbit, attitude and mirror motion).

    ``speed_km_s = None`` means the circular speed ``sqrt(mu/a)``; ``speed_km_s = 0``
    freezes the satellite (and its orbit frame). ``flattening = 0`` is the sphere.
    """

    altitude_km: float
    inclination_rad: float
    focal_length_mm: float
    gamma0_rad: float = 0.0
    mirror_rate_rad_s: float = 0.0
    mirror_rest_rad: float = math.pi / 4
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    yaw_rad: float = 0.0
    roll_rate_rad_s: float = 0.0
    pitch_rate_rad_s: float = 0.0
    yaw_rate_rad_s: float = 0.0
    mu_km3_s2: float = MU_EARTH_KM3_S2
    speed_km_s: float | None = None
    earth_rate_rad_s: float = EARTH_RATE_RAD_S
    equatorial_radius_km: float = WGS84_A_KM
    flattening: float = WGS84_F

    @property
    def orbit_radius_km(self) -> float:
        return self.equatorial_radius_km + self.altitude_km

    @property
    def orbit_speed_km_s(self) -> float:
        if self.speed_km_s is not None:
            return float(self.speed_km_s)
        return math.sqrt(self.mu_km3_s2 / self.orbit_radius_km)

    @property
    def polar_radius_km(self) -> float:
        return self.equatorial_radius_km * (1.0 - self.flattening)

    def sphere(self) -> "World":
        """The same world on the sphere of the equatorial radius (the paper's Earth)."""
        return replace(self, flattening=0.0)

    def with_(self, **changes) -> "World":
        return replace(self, **changes)

    @classmethod
    def from_values(cls, values, *, flattening: float = WGS84_F, mu_km3_s2: float = MU_EARTH_KM3_S2) -> "World":
        """A world from a mapping of named values (e.g. one row of the synthesis's
        parameter arrays zipped with their column names): the field names of this class,
        with ``gamma_rad`` for ``gamma0_rad`` and ``earth_radius_km`` for
        ``equatorial_radius_km``; unknown names raise ``KeyError``."""
        alias = {"gamma_rad": "gamma0_rad", "earth_radius_km": "equatorial_radius_km"}
        names = set(cls.__dataclass_fields__)
        kw = {"flattening": flattening, "mu_km3_s2": mu_km3_s2}
        for k, v in dict(values).items():
            k = alias.get(k, k)
            if k not in names:
                raise KeyError(f"unknown world value {k!r}")
            kw[k] = float(v)
        return cls(**kw)

    @classmethod
    def from_scenario(cls, sc, gamma_rad: float | None = None, *, ellipsoid: bool = True,
                      flattening: float = WGS84_F) -> "World":
        """The nominal world of a whiskbroom scenario (zero attitude) at ``gamma_rad``
        (default: the scenario's ``gamma0``). Reads the scenario's raw fields only; the
        sun-synchronous inclination is computed here (:func:`sun_synchronous_inclination`)."""
        o = sc.orbit
        if o.sun_synchronous:
            inc = sun_synchronous_inclination(
                o.altitude_km, mu_km3_s2=o.mu_km3_s2, earth_radius_km=o.earth_radius_km,
                j2=o.j2, nodal_rate_rad_s=math.radians(o.nodal_rate_deg_day) / SECONDS_PER_DAY)
        else:
            inc = math.radians(o.inclination_deg)
        g = math.radians(o.gamma0_deg) if gamma_rad is None else float(gamma_rad)
        return cls(altitude_km=o.altitude_km, inclination_rad=inc,
                   focal_length_mm=sc.camera.focal_length_mm, gamma0_rad=g,
                   mirror_rate_rad_s=math.radians(sc.mirror.rate_deg_s),
                   mirror_rest_rad=math.radians(sc.mirror.rest_angle_deg),
                   mu_km3_s2=o.mu_km3_s2, earth_rate_rad_s=o.earth_rate_rad_s,
                   equatorial_radius_km=o.earth_radius_km,
                   flattening=flattening if ellipsoid else 0.0)


def rodrigues(v, axis, angle):
    """Active rotation of vectors ``v`` about the unit ``axis`` by ``angle`` (right hand):
    ``v cos a + (k x v) sin a + k (k . v)(1 - cos a)`` (Rodrigues' formula; Goldstein,
    Poole & Safko, *Classical Mechanics*, 3rd ed., 2002, eq. 4.92). Broadcasts.

    Written out, not ``scipy.spatial.transform.Rotation``: the ray trace turns a few vectors
    per instant about per-instant axes, where building scipy rotations costs about seven times
    more (image_motion of the default field: 2.5 ms against 18 ms), and quarter turns stay exact.
    """
    v, k = np.asarray(v, dtype=float), np.asarray(axis, dtype=float)
    a = np.asarray(angle, dtype=float)[..., None]
    c, s = np.cos(a), np.sin(a)
    return v * c + np.cross(k, v) * s + k * np.sum(k * v, -1, keepdims=True) * (1.0 - c)


_E1, _E2, _E3 = np.eye(3)


def _times(t):
    return np.atleast_1d(np.asarray(t, dtype=float))


def satellite_state(world: World, t):
    """Satellite position, body axes and mirror normal at instants ``t`` (T,).

    Returns
    -------
    r_s : (T, 3) km, in I.
    body : (T, 3, 3); ``body[:, k]`` is the body axis S_(k+1) in I.
    normal : (T, 3) mirror unit normal in S.
    """
    t = _times(t)
    w = world
    inc = w.inclination_rad
    h = np.array([math.sin(inc), math.cos(inc), 0.0])
    a = w.orbit_radius_km
    gamma = w.gamma0_rad + w.orbit_speed_km_s / a * t
    r_hat = rodrigues(np.broadcast_to(-_E3, (t.size, 3)), h, gamma)
    b3 = r_hat
    b1 = np.cross(h, r_hat)                       # along the velocity
    b2 = np.cross(b3, b1)
    B = np.stack([b1, b2, b3], 1)                 # (T, 3 axes, 3 comps)
    # Euler 1-2-3: turn the frame about its axis 1, then its new axis 2, then its new axis 3
    ax = B
    for k, ang in ((0, w.roll_rad + w.roll_rate_rad_s * t),
                   (1, w.pitch_rad + w.pitch_rate_rad_s * t),
                   (2, w.yaw_rad + w.yaw_rate_rad_s * t)):
        ax = rodrigues(ax, ax[:, k][:, None, :], ang[:, None])
    alpha = w.mirror_rest_rad + w.mirror_rate_rad_s * t
    normal = rodrigues(np.broadcast_to(_E3, (t.size, 3)), _E1, alpha)
    return a * r_hat, ax, normal


def _reflect(r, n):
    return r - 2.0 * np.sum(r * n, -1, keepdims=True) * n


def _earth_turn(v, angle):
    """Rotate vectors about the polar axis I2 = E2 by ``angle`` (east positive)."""
    return rodrigues(v, _E2, angle)


def lines_of_sight(world: World, x1_mm, x3_mm, t=0.0):
    """Unit line of sight (in I) of image points ``(x1, x3)`` (N,) at instants ``t`` (T,):
    the pinhole ray ``(x1, -f, x3)`` reflected by the mirror, in body axes. (T, N, 3)."""
    x1, x3 = np.broadcast_arrays(np.atleast_1d(np.asarray(x1_mm, dtype=float)),
                                 np.atleast_1d(np.asarray(x3_mm, dtype=float)))
    r_s, body, n = satellite_state(world, t)
    c = np.stack([x1, np.full_like(x1, -world.focal_length_mm), x3], -1)   # (N, 3) in C = S
    c = c / np.linalg.norm(c, axis=-1, keepdims=True)
    l_s = _reflect(c[None, :, :], n[:, None, :])                            # (T, N, 3) in S
    return np.einsum("tnk,tki->tni", l_s, body)                             # sum_k l_k S_k


def ground_points(world: World, x1_mm, x3_mm, t=0.0):
    """Earth-fixed point (km) seen by image points ``(x1, x3)`` (N,) at instants ``t`` (T,).

    Ray-ellipsoid intersection in E (module docstring). Returns (T, N, 3); NaN where the
    line of sight misses the Earth.
    """
    t = _times(t)
    r_s, _, _ = satellite_state(world, t)
    los = lines_of_sight(world, x1_mm, x3_mm, t)
    turn = -world.earth_rate_rad_s * t
    p = _earth_turn(r_s, turn)[:, None, :]                                  # (T, 1, 3) in E
    u = _earth_turn(los, turn[:, None])                                     # (T, N, 3) in E
    scale = np.array([world.equatorial_radius_km, world.polar_radius_km, world.equatorial_radius_km])
    P, U = p / scale, u / scale
    A = np.sum(U * U, -1)
    B = np.sum(P * U, -1)
    C = np.sum(P * P, -1) - 1.0
    disc = B * B - A * C
    root = np.sqrt(np.where((disc >= 0) & (B < 0), disc, np.nan))
    s = C / (-B + root)                                                     # nearer root
    return p + s[..., None] * u


def project(world: World, r_e, t):
    """Image coordinates (mm) of Earth-fixed points ``r_e`` (N, 3) or (T, N, 3) at
    instants ``t`` (T,): Earth rotation, relative to the satellite, body axes, mirror,
    pinhole. Returns (T, N, 2) ``(x_P1, x_P3)``."""
    t = _times(t)
    r_s, body, n = satellite_state(world, t)
    r_e = np.asarray(r_e, dtype=float)
    if r_e.ndim == 2:
        r_e = np.broadcast_to(r_e, (t.size,) + r_e.shape)
    g_i = _earth_turn(r_e, (world.earth_rate_rad_s * t)[:, None])
    rel = g_i - r_s[:, None, :]
    l_s = np.einsum("tni,tki->tnk", rel, body)                              # components on S_k
    d = _reflect(l_s, n[:, None, :])
    f = world.focal_length_mm
    return np.stack([-f * d[..., 0] / d[..., 1], -f * d[..., 2] / d[..., 1]], -1)


def image_motion(world: World, x1_mm, x3_mm, t=0.0, dt: float = DT_S):
    """Image-motion velocity ``V_P`` (mm/s) of the ground seen by image points
    ``(x1, x3)`` (N,) at instants ``t`` (T,): central difference of the re-projected
    Earth-fixed ground points, ``(x(t + dt) - x(t - dt)) / (2 dt)``.

    Returns (T, N, 2): ``(V_P1, V_P3)``.
    """
    t = _times(t)
    g = ground_points(world, x1_mm, x3_mm, t)                               # (T, N, 3)
    xp = project(world, g, t + dt)
    xm = project(world, g, t - dt)
    return (xp - xm) / (2.0 * dt)


def drift_angle(v):
    """Drift angle (rad), the angle of the image motion from the push-broom direction -P1:
    ``atan2(-V_P3, -V_P1)`` (the convention of ``docs/whiskbroom.md``: 0 for a push-broom
    camera over a non-rotating Earth, +4.23 deg at the equator with the Earth's rotation)."""
    v = np.asarray(v)
    return np.arctan2(-v[..., 1], -v[..., 0])


def tdi_components(v, beta_rad):
    """Components (mm/s) of ``V_P`` along the TDI axis ``tau = -(cos beta, sin beta)``
    (the charge-transfer direction of arrays turned by ``beta``) and across it,
    ``lam = (-sin beta, cos beta)``. Returns ``(..., 2)``: (along, across)."""
    v = np.asarray(v)
    c, s = np.cos(beta_rad), np.sin(beta_rad)
    return np.stack([-(v[..., 0] * c + v[..., 1] * s), -v[..., 0] * s + v[..., 1] * c], -1)


def _third_derivative(world, g, t, h):
    """``x'''`` by the central difference ``(x(2h) - 2x(h) + 2x(-h) - x(-2h)) / (2 h^3)``."""
    x = [project(world, g, t + k * h) for k in (2, 1, -1, -2)]
    return (x[0] - 2 * x[1] + 2 * x[2] - x[3]) / (2.0 * h**3)


def error_bound(world: World, x1_mm, x3_mm, t=0.0, dt: float = DT_S, *, h3_s: float = 0.5):
    """Bound (mm/s, per component) on the central-difference error of :func:`image_motion`.

    ``|x'''| dt^2 / 6`` (truncation; ``x'''`` by a wide central difference of step
    ``h3_s``, counted twice for margin) plus ``delta / dt`` with the rounding error of a
    projected point ``delta = 4 eps f |r_s| / rho`` (``rho`` the range to the ground: the
    relative rounding of positions of size ``|r_s|`` turned into an angle over ``rho`` and
    an image offset through f; the step study measures about a sixteenth of that).
    Returns (T, N, 2).
    """
    t = _times(t)
    g = ground_points(world, x1_mm, x3_mm, t)
    x3rd = np.abs(_third_derivative(world, g, t, h3_s))
    r_s, _, _ = satellite_state(world, t)
    rho = np.linalg.norm(g - _earth_turn(r_s, -world.earth_rate_rad_s * t)[:, None, :], axis=-1)
    delta = 4.0 * _EPS * world.focal_length_mm * np.linalg.norm(r_s, axis=-1)[:, None] / rho
    return 2.0 * x3rd * dt**2 / 6.0 + (delta / dt)[..., None]


def step_study(world: World, x1_mm, x3_mm, steps_s, t=0.0, *, reference_dt_s: float = 0.05):
    """Error of :func:`image_motion` against its Richardson extrapolation, per step.

    The reference is ``(4 V(h/2) - V(h))/3`` at ``h = reference_dt_s`` (truncation O(h^4),
    rounding ~3e-11 mm/s here); returns ``(steps, max_abs_error)`` over points and components, so the
    O(dt^2) truncation branch and the O(1/dt) rounding branch can be read off.
    """
    h = reference_dt_s
    ref = (4.0 * image_motion(world, x1_mm, x3_mm, t, h / 2) - image_motion(world, x1_mm, x3_mm, t, h)) / 3.0
    steps = np.asarray(steps_s, dtype=float)
    err = np.array([np.nanmax(np.abs(image_motion(world, x1_mm, x3_mm, t, s) - ref)) for s in steps])
    return steps, err
