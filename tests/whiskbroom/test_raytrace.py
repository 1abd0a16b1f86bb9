"""Ray-traced image motion of the whiskbroom camera's world (simcam.whiskbroom.raytrace)
against closed forms derived here from first principles, and the validation of the
paper's complex-step V_P (simcam.whiskbroom.geometry) by this independent route.

Tolerances follow from the central difference V = (x(t+dt) - x(t-dt))/(2 dt): truncation
|x'''| dt^2/6 and rounding delta/dt, with delta <= 4 eps f |r_s|/rho the rounding of one
projected point (positions of size |r_s| ~ 7578 km seen over the range rho ~ 1200 km; the
module's step study measures about a sixteenth of that)."""

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from simcam.whiskbroom import raytrace as rt
from simcam.whiskbroom import scenario as wsc

EPS = np.finfo(float).eps
MU, RE, WE = 398600.4418, 6378.137, 7.2921159e-5
A_WGS, F_WGS = 6378.137, 1.0 / 298.257223563
H = 1200.0
F_MM = 4430.0
DT = rt.DT_S


@pytest.fixture(scope="module")
def sc():
    return wsc.default()


def _sun_sync_inclination(o):
    # Vallado (2013) eq. 9-41: Omega_dot = -3/2 n J2 (R/a)^2 cos i, from the scenario's raw fields
    a = o.earth_radius_km + o.altitude_km
    n = math.sqrt(o.mu_km3_s2 / a**3)
    return math.acos(math.radians(o.nodal_rate_deg_day) / 86400.0 / (-1.5 * n * o.j2 * (o.earth_radius_km / a) ** 2))


def _rounding(a_orbit, rho, dt=DT):
    """Rounding bound of the central difference, mm/s (module docstring)."""
    return 4.0 * EPS * F_MM * a_orbit / rho / dt


def test_module_shares_no_code_with_geometry():
    src = Path(rt.__file__).read_text()
    names = set()
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, ast.ImportFrom):
            names.add(node.module or "")
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    assert not any("geometry" in n or "synthesis" in n for n in names), names


def test_rodrigues_quarter_turns():
    # right-handed active rotations: e1 -> e2 about e3, e2 -> e3 about e1, e3 -> e1 about e2
    e = np.eye(3)
    for v, k, w in ((0, 2, 1), (1, 0, 2), (2, 1, 0)):
        np.testing.assert_allclose(rt.rodrigues(e[v], e[k], math.pi / 2), e[w], atol=1e-16)


@pytest.mark.parametrize("inc_deg, gamma_deg", [(100.42, 0.0), (100.42, 50.0), (30.0, 200.0), (0.0, 10.0)])
def test_pushbroom_limit_non_rotating_sphere(inc_deg, gamma_deg):
    # (a) omega_x = 0, nadir, sphere, omega_e = 0. The ground point at nadir at t = 0 lies at
    # central angle -w t from the sub-satellite point at time t; the body keeps nadir, so the
    # point is seen at nadir angle eta, tan eta = R sin(wt)/(a - R cos(wt)), imaged at
    # x = f tan eta along -P1 (the fold at rest preserves angles): V = f w R/(a - R)
    # = f v_ground/H with v_ground = v R/(R + H).
    w_ = rt.World(altitude_km=H, inclination_rad=math.radians(inc_deg), focal_length_mm=F_MM,
                  gamma0_rad=math.radians(gamma_deg), earth_rate_rad_s=0.0, flattening=0.0)
    a = RE + H
    v = math.sqrt(MU / a)
    v_ground = v * RE / a
    speed = F_MM * v_ground / H
    got = rt.image_motion(w_, [0.0], [0.0])[0, 0]
    # x = f R sin u/(a - R cos u), u = w t: x'''/x' = -(1 + 3R/H) w^2, so the truncation is
    # (1 + 3R/H) w^2 dt^2/6 relative (4e-13); rounding <= 4 eps f a/(H dt) (2.7e-9 relative)
    wrate = v / a
    tol = speed * (1 + 3 * RE / H) * wrate**2 * DT**2 / 6 + _rounding(a, H)
    assert tol / speed < 1e-8
    assert abs(got[0] + speed) <= tol          # along -P1
    assert abs(got[1]) <= tol
    assert abs(rt.drift_angle(got)) <= tol / speed


def test_pushbroom_with_earth_rotation_drift_angle(sc):
    # (b) classical drift angle: tan beta = k sin i cos gamma/(1 - k cos i), k = w_e/w_s, and
    # |V| = (f/H) R w_s sqrt((1 - k cos i)^2 + (k sin i cos gamma)^2) (the ground point's
    # velocity relative to the moving sub-satellite point, at nadir, over H)
    o = sc.orbit
    inc = _sun_sync_inclination(o)
    assert math.degrees(inc) == pytest.approx(100.42, abs=0.005)
    a = o.earth_radius_km + o.altitude_km
    ws = math.sqrt(o.mu_km3_s2 / a**3)
    k = o.earth_rate_rad_s / ws
    f = sc.camera.focal_length_mm
    gamma = np.radians([0.0, 30.0, 60.0, 135.0])
    along = 1 - k * math.cos(inc)
    cross = k * math.sin(inc) * np.cos(gamma)
    beta_ref = np.arctan2(cross, along)
    speed_ref = f / o.altitude_km * o.earth_radius_km * ws * np.hypot(along, cross)
    base = rt.World.from_scenario(sc, ellipsoid=False).with_(mirror_rate_rad_s=0.0)
    v = np.array([rt.image_motion(base.with_(gamma0_rad=g), [0.0], [0.0])[0, 0] for g in gamma])
    tol = _rounding(a, o.altitude_km) + 1e-12 * speed_ref     # truncation ~1e-13 relative
    np.testing.assert_array_less(np.abs(np.hypot(v[:, 0], v[:, 1]) - speed_ref), tol)
    np.testing.assert_array_less(np.abs(rt.drift_angle(v) - beta_ref), tol / speed_ref)
    assert math.degrees(beta_ref[0]) == pytest.approx(4.2276, abs=5e-5)
    # on the ellipsoid at the equator the nadir geometry is the sphere's to first order
    ve = rt.image_motion(base.with_(flattening=F_WGS), [0.0], [0.0])[0, 0]
    assert abs(rt.drift_angle(ve) - beta_ref[0]) <= 2 * tol[0] / speed_ref[0]


def test_pure_scan_is_optical_doubling():
    # (c) Earth and satellite frozen: the fold mirror turning at w_x about S1 (an axis in its
    # surface) turns the scene direction d = (x1, -f, x3) in C about C1 at W = 2 w_x;
    # ddot = W e1 x d = W (0, -x3, -f), and the quotient rule on x = -f d1/d2, -f d3/d2 gives
    # V1 = -W x1 x3/f, V3 = -W (f^2 + x3^2)/f: V = 2 f w_x along -P3 at the centre, beta = 90 deg
    wx = math.radians(0.6)
    w_ = rt.World(altitude_km=H, inclination_rad=math.radians(100.42), focal_length_mm=F_MM,
                  gamma0_rad=0.3, speed_km_s=0.0, earth_rate_rad_s=0.0, mirror_rate_rad_s=wx,
                  flattening=0.0)
    x1, x3 = (g.ravel() for g in np.meshgrid(np.linspace(-54, 54, 5), np.linspace(-54, 54, 5)))
    W = 2 * wx
    ref = np.stack([-W * x1 * x3 / F_MM, -W * (F_MM**2 + x3**2) / F_MM], -1)
    got = rt.image_motion(w_, x1, x3)[0]
    # truncation: x ~ f tan(W t) has x'''/x' = 2 W^2 -> W^2 dt^2/3 relative (~2e-11); rounding
    tol = np.abs(ref).max() * W**2 * DT**2 + _rounding(RE + H, H)
    np.testing.assert_array_less(np.abs(got - ref), tol)
    centre = rt.image_motion(w_, [0.0], [0.0])[0, 0]
    assert abs(np.hypot(*centre) - 2 * F_MM * wx) <= tol
    assert abs(math.degrees(rt.drift_angle(centre)) - 90.0) <= math.degrees(tol / (2 * F_MM * wx))


@pytest.mark.parametrize("gamma_deg", [0.0, 40.0, 90.0, 130.0])
def test_ellipsoid_pushbroom_closed_form(gamma_deg):
    # omega_x = 0, omega_e = 0, nadir, WGS 84: the geocentric nadir meets the ellipsoid at the
    # geocentric radius r = a b/sqrt(b^2 cos^2 phi + a^2 sin^2 phi), sin phi = sin i sin gamma;
    # the fixed point is seen at range rho = a_o - r, its line of sight turns at v/rho in I
    # while the body turns at w_s = v/a_o: V = f (v/rho - w_s) = f w_s r/rho along -P1
    # (exact to first order: the surface slope does not enter)
    inc = math.radians(100.42)
    g = math.radians(gamma_deg)
    w_ = rt.World(altitude_km=H, inclination_rad=inc, focal_length_mm=F_MM, gamma0_rad=g,
                  earth_rate_rad_s=0.0)
    b = A_WGS * (1 - F_WGS)
    phi = math.asin(math.sin(inc) * math.sin(g))
    r = A_WGS * b / math.hypot(b * math.cos(phi), A_WGS * math.sin(phi))
    ao = A_WGS + H
    speed = F_MM * math.sqrt(MU / ao**3) * r / (ao - r)
    got = rt.image_motion(w_, [0.0], [0.0])[0, 0]
    tol = _rounding(ao, ao - r) + 1e-12 * speed
    assert abs(got[0] + speed) <= tol and abs(got[1]) <= tol


def _package_params(w):
    from simcam.whiskbroom import geometry as geo
    return geo.make_params(
        1, altitude_km=w.altitude_km, speed_km_s=w.orbit_speed_km_s, inclination_rad=w.inclination_rad,
        gamma_rad=w.gamma0_rad, roll_rad=w.roll_rad, pitch_rad=w.pitch_rad, yaw_rad=w.yaw_rad,
        roll_rate_rad_s=w.roll_rate_rad_s, pitch_rate_rad_s=w.pitch_rate_rad_s,
        yaw_rate_rad_s=w.yaw_rate_rad_s, mirror_rate_rad_s=w.mirror_rate_rad_s,
        mirror_rest_rad=w.mirror_rest_rad, focal_length_mm=w.focal_length_mm,
        earth_rate_rad_s=w.earth_rate_rad_s, earth_radius_km=w.equatorial_radius_km)


def test_paper_complex_step_vp_equals_ray_trace_on_the_sphere(sc):
    # (d) validation of the paper's V_P (nine frames, complex step) by the independent ray
    # trace, spherical option, over the synthesis field of the three arrays: at the default
    # state, across the orbit, and at attitude states with rates and an off-circular speed
    from simcam.whiskbroom import geometry as geo
    from simcam.whiskbroom import synthesis as sy

    x1, x3 = sy.field_points(sc)
    base = rt.World.from_scenario(sc, ellipsoid=False)
    d = math.radians
    states = [base, base.with_(gamma0_rad=d(72.0)), base.with_(gamma0_rad=d(200.0)),
              base.with_(roll_rad=d(0.03), pitch_rad=d(-0.02), yaw_rad=d(0.025),
                         roll_rate_rad_s=d(0.001), pitch_rate_rad_s=d(-0.0008),
                         yaw_rate_rad_s=d(0.0005), speed_km_s=base.orbit_speed_km_s + 0.01),
              base.with_(roll_rad=d(5.0), pitch_rad=d(-3.0), yaw_rad=d(20.0), roll_rate_rad_s=d(0.3),
                         pitch_rate_rad_s=d(-0.2), yaw_rate_rad_s=d(0.1), gamma0_rad=d(33.0))]
    for w_ in states:
        ref = geo.image_motion(_package_params(w_), x1, x3)[0]
        got = rt.image_motion(w_, x1, x3)[0]
        bound = rt.error_bound(w_, x1, x3)[0]
        assert np.all(np.abs(got - ref) <= bound), np.max(np.abs(got - ref) / bound)
    # the bound itself is small: < 1e-9 of V at the default state
    assert np.max(rt.error_bound(base, x1, x3)) < 1e-9 * 90.0


def test_ellipsoid_minus_sphere_over_the_orbit(sc):
    # The reported effect (docs/whiskbroom.md): the circular orbit's height over WGS 84 grows
    # towards the poles, so the push-broom (along-orbit) part f w_s r/rho of V shrinks; at
    # the equator (the default gamma0) nothing changes to first order
    from simcam.whiskbroom import synthesis as sy

    x1, x3 = sy.field_points(sc)
    ell = rt.World.from_scenario(sc)
    at = {}
    for gdeg in (0.0, 90.0):
        we = ell.with_(gamma0_rad=math.radians(gdeg))
        at[gdeg] = rt.image_motion(we, x1, x3)[0] - rt.image_motion(we.sphere(), x1, x3)[0]
    V = 95.0
    assert np.max(np.abs(at[0.0])) < 1e-8 * V * 100      # off-nadir curvature only (~1e-6 mm/s)
    # at gamma = 90 deg: the along-orbit speed differs by f w_s (r/rho - R/H), nearly all of it
    inc, o = ell.inclination_rad, sc.orbit
    b = A_WGS * (1 - F_WGS)
    phi = math.asin(math.sin(inc))
    r = A_WGS * b / math.hypot(b * math.cos(phi), A_WGS * math.sin(phi))
    ao = A_WGS + o.altitude_km
    ws = math.sqrt(MU / ao**3)
    d_along = sc.camera.focal_length_mm * ws * (r / (ao - r) - RE / o.altitude_km)
    centre = np.argmin(np.hypot(x1, x3))
    # the Earth's rotation adds ~k^2 of that; the mirror's scan term does not depend on range
    assert np.hypot(*at[90.0][centre]) == pytest.approx(abs(d_along), rel=0.02)


def test_ground_points_lie_on_the_ellipsoid_along_the_line_of_sight():
    w_ = rt.World(altitude_km=H, inclination_rad=math.radians(100.42), focal_length_mm=F_MM,
                  gamma0_rad=1.1, mirror_rate_rad_s=math.radians(0.6), roll_rad=0.2)
    x1, x3 = np.linspace(-50, 50, 7), np.linspace(30, -30, 7)
    t = np.array([0.0, 3.0, -7.5])
    g = rt.ground_points(w_, x1, x3, t)
    b = A_WGS * (1 - F_WGS)
    q = (g[..., 0] ** 2 + g[..., 2] ** 2) / A_WGS**2 + g[..., 1] ** 2 / b**2
    np.testing.assert_allclose(q, 1.0, rtol=0, atol=8 * EPS)
    # a point on the line of sight is imaged back at its own pixel at the same instant
    back = np.stack([rt.project(w_, g[k], t[k])[0] for k in range(t.size)])
    np.testing.assert_allclose(back[..., 0], np.broadcast_to(x1, back.shape[:2]), rtol=0, atol=1e-9)
    np.testing.assert_allclose(back[..., 1], np.broadcast_to(x3, back.shape[:2]), rtol=0, atol=1e-9)


def test_world_from_values_names():
    w_ = rt.World.from_values({"altitude_km": H, "inclination_rad": 1.0, "focal_length_mm": F_MM,
                               "gamma_rad": 0.5, "earth_radius_km": 6371.0}, flattening=0.0)
    assert (w_.gamma0_rad, w_.equatorial_radius_km, w_.flattening) == (0.5, 6371.0, 0.0)
    with pytest.raises(KeyError):
        rt.World.from_values({"altitude_km": H, "bogus": 1.0})
