"""Seed 003 star sensing and normal-deviation estimation."""

from __future__ import annotations

import copy
import tomllib

import numpy as np
import pytest

from budget.scanmirror.compensation import exact_compensation
from budget.scanmirror.estimation import DwellMeasurement, batch_estimate, published_estimate
from budget.scanmirror.pipeline import Setup, run
from simcam.infra.errors import ScenarioError
from simcam.scanmirror.geometry import attitude_matrix_br, line_of_sight_body, rot_x, rot_y, rotvec_matrix
from simcam.scanmirror.scenario import default_text, from_dict
from simcam.scanmirror.stars import body_to_inertial, find_dwell_stars, true_centroids
from simcam.scanmirror.world import World
from simcam.units import RAD_PER_ARCSEC

DEG = np.pi / 180


def _default(**changes):
    data = tomllib.loads(default_text())
    # the ideal world: these tests check the lab's algebra on what it assumes;
    # tests/test_scanmirror_effects.py covers the realistic world
    data["world"]["effects"] = {k: 0.0 for k in data["world"]["effects"]}
    for dotted, value in changes.items():
        node = data
        *head, last = dotted.split(".")
        for k in head:
            node = node[k]
        node[last] = value
    return from_dict(data, source="test.toml")


@pytest.fixture(scope="module")
def world():
    return World(_default())


@pytest.fixture(scope="module")
def dwell(world):
    return find_dwell_stars(world)[0]


def test_attitude_matrix_is_scipy_312():
    from scipy.spatial.transform import Rotation

    roll, pitch, yaw = 0.1, -0.2, 0.3
    # A_br (orbit -> body components) is the transpose of the body's active rotation
    # R3(yaw) R1(roll) R2(pitch), i.e. scipy's intrinsic "ZXY"
    ref = Rotation.from_euler("ZXY", [yaw, roll, pitch]).as_matrix().T
    assert np.abs(attitude_matrix_br(roll, pitch, yaw) - ref).max() < 1e-15


def test_mirror_normal_is_rotation_product():
    from scipy.spatial.transform import Rotation

    a, b, tx, ty = 0.2, -0.9, 3e-4, -1e-4
    ref = rot_x(a) @ rot_y(b) @ Rotation.from_rotvec([tx, ty, 0.0]).as_matrix()[:, 2]
    w = line_of_sight_body(a, b, tx, ty)
    d = np.array([1.0, 0, 0])
    assert np.abs(w - (d - 2 * (d @ ref) * ref)).max() < 1e-15


def test_star_dwell_points_off_the_earth(world, dwell):
    # the paper's star position: 24.5 deg from nadir, outside the 8.70 deg Earth disc
    s = line_of_sight_body(13 * DEG, -55.5 * DEG)
    assert np.rad2deg(np.arccos(s[2])) == pytest.approx(24.5, abs=0.05)
    assert dwell.hip.size >= 2


def test_apparent_directions_agree_with_astropy_gcrs(world, dwell):
    """Aberration (annual + the spacecraft's velocity): our star directions against astropy's
    own ICRS -> GCRS transform with the spacecraft as observer, to a milliarcsecond."""
    import astropy.units as u
    from astropy.coordinates import GCRS, CartesianRepresentation, Distance, SkyCoord
    from astropy.time import Time, TimeDelta

    from simcam.sky.catalogue import EPOCH_JYEAR, hipparcos

    cat = hipparcos().by_hip(dwell.hip)
    tmid = Time(world.scenario.orbit.epoch_utc, scale="utc") + TimeDelta(float(dwell.frame_t_s[len(dwell.frame_t_s) // 2]), format="sec")
    r, v = world.orbit.state([float(dwell.frame_t_s[len(dwell.frame_t_s) // 2])])
    sc = SkyCoord(ra=cat.ra_rad * u.rad, dec=cat.dec_rad * u.rad,
                  distance=Distance(parallax=np.maximum(cat.parallax_mas, 1e-6) * u.mas),
                  pm_ra_cosdec=cat.pm_ra_mas_yr * u.mas / u.yr, pm_dec=cat.pm_dec_mas_yr * u.mas / u.yr,
                  radial_velocity=np.zeros(len(cat)) * u.km / u.s,
                  obstime=Time(EPOCH_JYEAR, format="jyear", scale="tcb"))
    import warnings

    import erfa
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", erfa.ErfaWarning)
        g = sc.apply_space_motion(new_obstime=tmid).transform_to(
            GCRS(obstime=tmid, obsgeoloc=CartesianRepresentation(r[0] * u.km),
                 obsgeovel=CartesianRepresentation(v[0] * u.km / u.s)))
    ref = g.cartesian.xyz.value.T
    ref /= np.linalg.norm(ref, axis=1, keepdims=True)
    # separation from the cross product (arccos of a dot product floors at 1.5e-8 rad)
    sep = np.linalg.norm(np.cross(ref, dwell.apparent_I), axis=1)
    assert (sep / RAD_PER_ARCSEC).max() < 1e-3
    # and the aberration itself is the ~20" the paper ignores
    ab = np.arccos(np.clip(np.sum(dwell.catalogue_I * dwell.apparent_I, 1), -1, 1)) / RAD_PER_ARCSEC
    assert 5 < ab.min() and ab.max() < 25


def test_published_estimator_identity_star_on_boresight():
    """Noise-free star exactly on the deviated line of sight: eqs. 33-38 recover dtau to
    second order (notes: 36.275"/20.943" -> 36.272"/20.946")."""
    a, b = 13 * DEG, -55.5 * DEG
    dt = np.array([36.275, 20.943]) * RAD_PER_ARCSEC
    A_Ib = rotvec_matrix(np.array([0.3, -0.2, 0.5]))
    star = A_Ib @ line_of_sight_body(a, b, dt[0], dt[1])
    m = DwellMeasurement(star[None, :], A_Ib[None], np.zeros((1, 1, 2)), a, b)
    est = published_estimate(m, star=0, frame=0)
    # first order in dtau (2e-4 rad): the remainder is O(dtau^2) ~ 4e-8 rad = 0.01"
    assert np.abs(est - dt).max() < 0.02 * RAD_PER_ARCSEC


def test_batch_estimate_noise_free_is_exact(world, dwell):
    dt = np.array([-30.0, 12.0]) * RAD_PER_ARCSEC
    att = world.attitude(dwell.frame_t_s)
    m = np.where(dwell.visible[..., None], true_centroids(dwell, dt[0], dt[1], att), np.nan)
    A = body_to_inertial(dwell.r_km, dwell.v_km_s, att)
    est, cov = batch_estimate([DwellMeasurement(dwell.apparent_I, A, m, dwell.alpha_rad, dwell.beta_rad)],
                              centroid_sigma_rad=RAD_PER_ARCSEC, tracker_sigma_rad=RAD_PER_ARCSEC)
    assert np.abs(est - dt).max() < 1e-6 * RAD_PER_ARCSEC
    # ignoring aberration (catalogue directions) costs arcseconds of deviation
    est_cat, _ = batch_estimate([DwellMeasurement(dwell.catalogue_I, A, m, dwell.alpha_rad, dwell.beta_rad)],
                                centroid_sigma_rad=RAD_PER_ARCSEC, tracker_sigma_rad=RAD_PER_ARCSEC)
    assert np.abs(est_cat - dt).max() > 3 * RAD_PER_ARCSEC


def test_batch_estimate_sigma_matches_its_own_noise_model_algebra_check():
    """An algebra check, not a real-world coverage test: the measurements are drawn from the
    same Gaussian noise model, with the same sigmas, that the batch estimator assumes, so
    this checks the Gauss-Newton algebra and the (J^T W J)^-1 bookkeeping only. The
    real-world version (noise and systematics the estimator does not model) is in tests/test_scanmirror_effects.py.

    Monte Carlo (fixed seeds 0..199): the improved estimate's error over its stated sigma
    has mean 0 (tolerance 4/sqrt(N)) and standard deviation 1 (tolerance 4/sqrt(2N), the
    sampling spread of a standard deviation)."""
    setup = Setup(_default(), 1.0, scans=(2,))
    z = []
    for k in range(200):
        o = run(setup, np.random.default_rng(np.random.SeedSequence(0, spawn_key=(k,))))
        z.append((o.dtau_rad["improved"] - o.dtau_true_rad) / o.dtau_sigma_rad)
    z = np.array(z)
    n = len(z)
    assert np.abs(z.mean(0)).max() < 4 / np.sqrt(n)
    assert np.abs(z.std(0, ddof=1) - 1).max() < 4 / np.sqrt(2 * n)


def test_numba_compensation_equals_numpy(world):
    t = np.arange(350.0, 590.0, 5.0)
    p = world.plan(t)
    A, R, _, _ = world.orbit_geometry(t)
    att = world.attitude(t)
    args = (world, p.alpha_rad, p.beta_rad, np.full(t.size, 2e-4), np.full(t.size, -1e-4), att, A, R)
    a1, b1 = exact_compensation(*args)
    a2, b2 = exact_compensation(*args, use_kernel=False)
    assert np.abs(a1 - a2).max() < 1e-13 and np.abs(b1 - b2).max() < 1e-13


def test_error_no_star_brighter_than_limit():
    with pytest.raises(ScenarioError, match=r"test.toml: star_sensing.mag_limit: no catalogue star"):
        find_dwell_stars(World(_default(**{"star_sensing.mag_limit": 2.0})), source="test.toml")


def test_error_scan_leaves_earth_disc():
    data = tomllib.loads(default_text())
    seg = copy.deepcopy(data["scan_plan"]["segments"][1])
    seg["line_deg"] = 12.0
    data["scan_plan"]["segments"][1] = seg
    sc = from_dict(data, source="test.toml")
    with pytest.raises(ScenarioError, match=r"test.toml: scan_plan.segments: area scan 1 leaves the Earth disc"):
        Setup(sc, 1.0, source="test.toml")


@pytest.mark.parametrize("key,value,field", [("orbit.eccentricity", 1.2, "orbit.eccentricity"),
                                             ("orbit.semi_major_axis_km", 6000.0, "orbit.semi_major_axis_km"),
                                             ("orbit.inclination_deg", 200.0, "orbit.inclination_deg")])
def test_error_orbit_element_out_of_range(key, value, field):
    with pytest.raises(ScenarioError, match=rf"test.toml: {field}"):
        _default(**{key: value})


def test_unknown_key_is_named():
    data = tomllib.loads(default_text())
    data["mirror"]["tilt"] = 1.0
    with pytest.raises(ScenarioError, match=r"mirror.tilt: unknown key"):
        from_dict(data, source="test.toml")


def test_profile_attitude_mode_runs_through_the_pipeline():
    sc = _default(**{"attitude.mode": "profile"})
    setup = Setup(sc, 2.0, scans=(2,))
    o = run(setup, np.random.default_rng(5))
    lat, lon = o.errors[2]["improved"].lat_deg, o.errors[2]["improved"].lon_deg
    # Exact compensation leaves the attitude knowledge error k (1" per axis) and the
    # estimate's error of the mirror normal, which the reflection doubles: a line-of-sight
    # error of 1 sigma s = sqrt(k^2 + (2 sigma_dtau)^2) = 1.6" (sigma_dtau = 0.63", the
    # estimator's stated sigma). From GEO a line-of-sight angle d moves the ground point by
    # d (a - R_e) on the ground, a geocentric angle d (a - R_e) / R_e = 5.6 d near nadir
    # (where scan 2 lies): 1 sigma 2.5e-3 deg. The scan's errors are one smooth draw, so
    # their maximum is about one draw's size: 4 sigma (0.010 deg, exceeded with probability
    # 6e-5 per axis) bounds it; the run gives 1.0e-3 / 4.5e-3 deg here.
    k = sc.attitude.knowledge_sigma_arcsec
    s = np.hypot(k, 2 * np.max(o.dtau_sigma_rad) / RAD_PER_ARCSEC)
    g = (sc.orbit.semi_major_axis_km - 6378.137) / 6378.137
    bound = 4 * s * g / 3600.0
    assert 0.009 < bound < 0.011
    assert np.isfinite(lat).all() and np.abs(lat).max() < bound and np.abs(lon).max() < bound
