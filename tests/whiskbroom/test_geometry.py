"""Image-motion geometry of the whiskbroom camera (seed 002) against independent references:
scipy's rotations, the classical push-broom drift-angle formula, the pure-scan optical
doubling, the nadir whiskbroom closed form, and the kinematic closed form."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simcam.whiskbroom import geometry as geo
from simcam.whiskbroom import scenario as wsc
from simcam.whiskbroom import synthesis as sy

MU, RE, WE = 398600.4418, 6378.137, 7.2921159e-5


@pytest.fixture(scope="module")
def sc():
    return wsc.default()


def test_elementary_rotations_match_scipy():
    # passive frame rotations = transposes of scipy's active matrices
    a = np.array([0.3, -1.2, 2.5])
    for fn, ax in ((geo.rot1, "x"), (geo.rot2, "y"), (geo.rot3, "z")):
        ref = np.array([Rotation.from_euler(ax, x).as_matrix().T for x in a])
        np.testing.assert_allclose(fn(a), ref, rtol=0, atol=1e-15)


def test_attitude_sequence_is_scipy_intrinsic_xyz():
    p = geo.make_params(1, roll_rad=0.1, pitch_rad=-0.2, yaw_rad=0.3)
    ref = Rotation.from_euler("XYZ", [0.1, -0.2, 0.3]).as_matrix().T
    np.testing.assert_allclose(geo._attitude(p, 0.0)[0], ref, rtol=0, atol=1e-15)


def test_sun_synchronous_inclination_1200km(sc):
    # Vallado (2013) eq. 9-41; the methods notes give 100.42 deg at 1200 km
    assert math.degrees(sc.inclination_rad) == pytest.approx(100.42, abs=0.005)


def _pushbroom(sc, gamma):
    p = sy.nominal_params(sc, gamma)
    p[:, geo.P["mirror_rate_rad_s"]] = 0.0
    return p


def test_pushbroom_limit_equals_classical_drift_angle(sc):
    gamma = np.radians([0.0, 30.0, 60.0])
    v = geo.image_motion(_pushbroom(sc, gamma), [0.0], [0.0])[:, 0]
    speed_ref, beta_ref = geo.pushbroom_classical(
        sc.orbit.altitude_km, sc.inclination_rad, gamma, sc.camera.focal_length_mm,
        mu_km3_s2=MU, earth_radius_km=RE, earth_rate_rad_s=WE)
    # both are exact expressions of the same nadir geometry: agreement to rounding
    np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 1]), speed_ref, rtol=1e-12)
    np.testing.assert_allclose(geo.drift_angle(v), beta_ref, rtol=1e-11)
    # the classical numbers (docs/whiskbroom.md): 4.23, 3.66, 2.12 deg
    assert np.all(np.abs(np.degrees(beta_ref) - [4.2276, 3.66, 2.12]) <= [5e-5, 5e-3, 5e-3])


def test_pure_scan_moves_the_image_at_twice_the_mirror_rate(sc):
    # Earth frozen and satellite at rest: only the fold mirror moves the line of sight.
    p = sy.nominal_params(sc, 0.3)
    p[:, geo.P["speed_km_s"]] = 0.0
    p[:, geo.P["earth_rate_rad_s"]] = 0.0
    v = geo.image_motion(p, [0.0], [0.0])[0, 0]
    expect = 2.0 * sc.camera.focal_length_mm * math.radians(sc.mirror.rate_deg_s)
    assert abs(v[0]) <= 1e-12 * expect
    assert -v[1] == pytest.approx(expect, rel=1e-12)            # along -P3
    assert math.degrees(geo.drift_angle(v)) == pytest.approx(90.0, abs=1e-9)
    # 4 omega_x (what the paper's 83 deg would need) is excluded by far
    assert abs(-v[1] - 2 * expect) > 0.4 * expect


def test_nadir_whiskbroom_drift_angle_is_76_not_83(sc):
    # At gamma = 90 deg the Earth's cross-track term vanishes and at nadir
    # tan beta = 2 omega_x H / (R_e omega_s (1 - k cos i)) exactly (docs/whiskbroom.md).
    v = geo.image_motion(sy.nominal_params(sc, math.pi / 2), [0.0], [0.0])[0, 0]
    a = RE + sc.orbit.altitude_km
    ws = math.sqrt(MU / a**3)
    k = WE / ws
    ref = math.atan2(2 * math.radians(sc.mirror.rate_deg_s) * sc.orbit.altitude_km,
                     RE * ws * (1 - k * math.cos(sc.inclination_rad)))
    assert float(geo.drift_angle(v)) == pytest.approx(ref, rel=1e-11)
    assert math.degrees(ref) == pytest.approx(76.17, abs=0.01)


def _random_states(n, rng, sc):
    p = sy.nominal_params(sc, rng.uniform(0, 2 * np.pi, n))
    P = geo.P
    for name, s in (("roll_rad", 0.02), ("pitch_rad", 0.02), ("yaw_rad", 0.02),
                    ("roll_rate_rad_s", 1e-3), ("pitch_rate_rad_s", 1e-3), ("yaw_rate_rad_s", 1e-3)):
        p[:, P[name]] = rng.normal(0, s, n)
    p[:, P["mirror_rest_rad"]] += rng.normal(0, 0.05, n)
    p[:, P["mirror_rate_rad_s"]] *= rng.uniform(-2, 2, n)
    p[:, P["altitude_km"]] = rng.uniform(500, 2000, n)
    return p


@pytest.mark.parametrize("altitude_km", [500.0, 1200.0, 2000.0])
@pytest.mark.parametrize("route", ["chain", "kinematic"])
def test_image_velocity_over_a_still_sphere_from_first_principles(sc, altitude_km, route):
    """Independent of the package's orbit, attitude and mirror helpers: a nadir camera on a
    circular orbit of radius a = R_e + H over a non-rotating sphere. The orbital speed is
    v = sqrt(mu / a) (Vallado 2013, eq. 1-32); the sub-satellite point moves at
    v_g = v R_e / a, so the line of sight to the nadir point turns at v_g / H relative to
    the ground and the image moves at f v_g / H (push-broom, along -P1: drift angle 0).
    The fold mirror turning at omega_x turns the line of sight at 2 omega_x (reflection
    doubles the mirror's rotation), which moves the image at 2 f omega_x along -P3; at one
    instant the two line-of-sight rates add as vectors. Computed here with mu, R_e and the
    scenario's f, H and omega_x only; both routes of the package (complex-step chain and
    kinematic closed form) must agree with it to rounding (1e-10 relative)."""
    fn = geo.image_motion if route == "chain" else geo.image_motion_kinematic
    a = RE + altitude_km
    v_g = math.sqrt(MU / a) * RE / a                 # km/s on the ground
    f = sc.camera.focal_length_mm
    omega = math.radians(sc.mirror.rate_deg_s)
    along = f * v_g / altitude_km                    # mm/s
    scan = 2.0 * f * omega                           # mm/s
    p = sy.nominal_params(sc, np.array([0.0, 0.7, 2.0]))
    p[:, geo.P["altitude_km"]] = altitude_km
    p[:, geo.P["speed_km_s"]] = math.sqrt(MU / a)
    p[:, geo.P["earth_rate_rad_s"]] = 0.0
    # push-broom: mirror still
    pb = p.copy()
    pb[:, geo.P["mirror_rate_rad_s"]] = 0.0
    v = fn(pb, [0.0], [0.0])[:, 0]
    np.testing.assert_allclose(-v[:, 0], along, rtol=1e-10)
    np.testing.assert_allclose(v[:, 1], 0.0, atol=1e-10 * along)
    # whiskbroom: both motions; drift angle atan(2 omega_x H / v_g)
    v = fn(p, [0.0], [0.0])[:, 0]
    np.testing.assert_allclose(-v[:, 0], along, rtol=1e-10)
    np.testing.assert_allclose(-v[:, 1], scan, rtol=1e-10)
    np.testing.assert_allclose(geo.drift_angle(v), math.atan2(scan, along), rtol=1e-10)


def test_complex_step_chain_and_kinematic_closed_form_equivalence(sc):
    """Equivalence of two routes through the same model, not a physics check: both share
    ``_orbit``, ``_attitude`` and ``_mirror_fold``, so an error there passes here; the
    physics is checked by test_image_velocity_over_a_still_sphere_from_first_principles
    and the limits above."""
    rng = np.random.default_rng(20021)
    p = _random_states(200, rng, sc)
    x1, x3 = rng.uniform(-60, 60, (2, 7))
    v_cs = geo.image_motion(p, x1, x3)
    v_kin = geo.image_motion_kinematic(p, x1, x3)
    # two exact derivatives of the same function: agreement to accumulated rounding
    scale = np.max(np.abs(v_kin), axis=-1, keepdims=True)
    assert np.max(np.abs(v_cs - v_kin) / scale) < 1e-10


def test_numba_kernel_equals_numpy_path(sc):
    rng = np.random.default_rng(3)
    p = _random_states(50, rng, sc)
    x1, x3 = rng.uniform(-60, 60, (2, 11))
    ref = geo.image_motion(p, x1, x3)
    got = sy._motion(p, x1, x3, "numba")
    np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())


def test_ray_cast_lands_on_the_sphere_and_reprojects(sc):
    p = _random_states(5, np.random.default_rng(4), sc)
    x1 = np.array([-40.0, 0.0, 25.0])
    x3 = np.array([10.0, 0.0, -30.0])
    g = geo.ground_points(p, x1, x3)
    np.testing.assert_allclose(np.linalg.norm(g, axis=-1), RE, rtol=1e-13)
    x = geo.image_position(p, g, 0.0)
    np.testing.assert_allclose(x[..., 0], np.broadcast_to(x1, x[..., 0].shape), atol=1e-9)
    np.testing.assert_allclose(x[..., 1], np.broadcast_to(x3, x[..., 1].shape), atol=1e-9)


def test_zero_knowledge_errors_give_exactly_zero_residual(sc):
    u = sy.trial_uniforms(7, np.arange(20))
    draws = sy.standard_draws(sc, u)
    for name in wsc.ERROR_VARIABLES:
        draws[name] = np.zeros(20)
    know, true = sy.trial_params(sc, draws, np.arange(20))
    x1, x3 = sy.field_points(sc)
    r = sy.evaluate(know, true, x1, x3)
    # true and knowledge states are then the same numbers through the same code:
    # the residual is exactly zero, not merely small (eqs 7-8 bookkeeping)
    assert np.all(r.dv_mm_s == 0.0) and np.all(r.dbeta_deg == 0.0) and np.all(r.eps == 0.0)
