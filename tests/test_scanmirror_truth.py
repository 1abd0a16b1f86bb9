"""The scan mirror's truth route (simcam.scanmirror.truth) shares nothing with the lab's chain:
it agrees with the geometry module's route to rounding and with closed forms, and the source
(``ast``) shows that neither side imports the other."""

from __future__ import annotations

import ast
import importlib.util
import inspect
from pathlib import Path

import numpy as np
import pytest

from budget.scanmirror import pipeline
from simcam.scanmirror import truth as T
from simcam.scanmirror.geometry import line_of_sight_body, nominal_orbit_matrix_sr0, rotvec_matrix
from simcam.scanmirror.world import World

ROOT = Path(__file__).resolve().parents[1]
#: the lab's chain: the estimators, the compensation and its numba kernel
LAB = ("budget.scanmirror.estimation", "budget.scanmirror.compensation", "budget.scanmirror.kernels")
TRUTH = "simcam.scanmirror.truth"
#: what the truth module may import: numerical libraries only
TRUTH_MAY_IMPORT = {"__future__", "numpy", "scipy.spatial.transform"}


def _imports(module: str) -> set[str]:
    """Every module ``module``'s source imports, inside functions too."""
    tree = ast.parse(Path(importlib.util.find_spec(module).origin).read_text())
    out = set()
    for n in ast.walk(tree):
        if isinstance(n, ast.Import):
            out |= {a.name for a in n.names}
        elif isinstance(n, ast.ImportFrom):
            assert n.level == 0, f"{module}: relative import"
            out.add(n.module)
    return out


def test_truth_imports_nothing_of_the_lab_and_the_lab_nothing_of_the_truth():
    assert _imports(TRUTH) <= TRUTH_MAY_IMPORT, _imports(TRUTH) - TRUTH_MAY_IMPORT
    for lab in LAB:
        assert TRUTH not in _imports(lab), lab
    # the world's evaluation of a compensated command goes through the truth route, not World.ground
    src = inspect.getsource(pipeline._ground_errors)
    assert "truth_ground" in src and "world.ground" not in src


def test_line_of_sight_closed_forms():
    """Eq. 2 [R] without deviation, ``R_x(alpha) (cos 2 beta, 0, -sin 2 beta)``; nadir at
    alpha = 0, beta = -45 deg; a y_m tilt dtau moves the line of sight by 2 dtau E-W and an
    x_m tilt by 2 dtau cos 45 deg (the mirror-optics identities of 003.md section c.5, first
    order: the tolerance is the second-order term, dtau^2 = 1e-8)."""
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-0.3, 0.3, 50), rng.uniform(-1.2, -0.3, 50)
    s = T.line_of_sight_body_truth(a, b)
    want = np.column_stack([np.cos(2 * b), np.sin(a) * np.sin(2 * b), -np.cos(a) * np.sin(2 * b)])
    np.testing.assert_allclose(s, want, atol=4e-16)
    np.testing.assert_allclose(T.line_of_sight_body_truth(0.0, -np.pi / 4), [0, 0, 1], atol=4.5e-16)  # 2 ulp of 1
    d = 1e-4
    nadir = np.array([0.0, 0.0, 1.0])

    def ang(v):
        return np.arccos(np.clip(v @ nadir, -1, 1))

    assert ang(T.line_of_sight_body_truth(0.0, -np.pi / 4, 0.0, d)) == pytest.approx(2 * d, abs=d * d)
    assert ang(T.line_of_sight_body_truth(0.0, -np.pi / 4, d, 0.0)) == pytest.approx(2 * d * np.cos(np.pi / 4),
                                                                                     abs=d * d)


def test_line_of_sight_agrees_with_the_lab_route():
    """Both are unit vectors built from rotations of angles up to 1.2 rad: rounding of a few
    ulp of 1 (2.2e-16 each) over a dozen operations."""
    rng = np.random.default_rng(4)
    n = 2000
    a, b = rng.uniform(-0.3, 0.3, n), rng.uniform(-1.2, -0.3, n)
    tx, ty = rng.normal(0, 1e-3, (2, n))
    np.testing.assert_allclose(T.line_of_sight_body_truth(a, b, tx, ty), line_of_sight_body(a, b, tx, ty),
                               atol=5e-15, rtol=0)


@pytest.mark.parametrize("shape", ["sphere", "ellipsoid"])
def test_ground_point_agrees_with_the_world_route(shape):
    """The ray-quadric root against the law of cosines (sphere) and the scaled-space root of
    the world (ellipsoid), under random attitude, orbit-error matrix, radius and deviation.
    The law of cosines subtracts two numbers of ~4e4 km to get ~3.6e4 km: its rounding is a
    few 1e-16 of 4e4 km, about 1e-11 km; both within 1e-9 km (1 micrometre)."""
    import tomllib

    from budget.scanmirror.study import STUDY

    data = tomllib.loads(STUDY.default_text())
    data["orbit"]["earth_shape"] = shape
    w = World(STUDY.from_dict(data, source="test"))
    rng = np.random.default_rng(5)
    n = 500
    a, b = rng.uniform(-0.05, 0.05, n), np.deg2rad(-45) + rng.uniform(-0.025, 0.025, n)
    tx, ty = rng.normal(0, 1e-4, (2, n))
    att, A, R = rng.normal(0, 1e-4, (n, 3)), rotvec_matrix(rng.normal(0, 1e-2, (n, 3))), 42164 + rng.normal(0, 30, n)
    g_world = w.ground(a, b, tx, ty, att, A, R) @ nominal_orbit_matrix_sr0(w.omega0_rad).T
    polar = w.polar_radius_km if shape == "ellipsoid" else w.earth.radius_km
    g = T.ground_point_s_truth(a, b, tx, ty, att, A, R, omega0_rad=w.omega0_rad,
                               equatorial_radius_km=w.earth.radius_km, polar_radius_km=polar)
    np.testing.assert_allclose(g, g_world, atol=1e-9, rtol=0)


def test_nadir_and_a_miss():
    """Zero errors at nadir: the sub-satellite point (R_e cos Om0, R_e sin Om0, 0); a line of
    sight 24.5 deg off nadir (the star dwell) misses the Earth (8.7 deg radius from GEO)."""
    om = np.deg2rad(105.0)
    g = T.ground_point_s_truth(np.array([0.0, np.deg2rad(13.0)]), np.array([-np.pi / 4, np.deg2rad(-55.5)]), 0.0,
                               0.0, np.zeros(3), np.eye(3), 42164.0, omega0_rad=om, equatorial_radius_km=6378.0,
                               polar_radius_km=6378.0)
    np.testing.assert_allclose(g[0], [6378.0 * np.cos(om), 6378.0 * np.sin(om), 0.0], atol=1e-9)
    assert np.isnan(g[1]).all()
    lat, lon = T.ground_latlon_truth(g[:1])
    # the point is exact to 1e-9 km: its angles to 1e-9 / 6378 = 1.6e-13 rad
    assert lat[0] == pytest.approx(0.0, abs=2e-13) and lon[0] == pytest.approx(om, abs=2e-13)
