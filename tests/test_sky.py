"""The Hipparcos catalogue and apparent places (simcam.sky) against astropy and the catalogue's definition."""

import numpy as np
import pytest
from astropy.time import Time

from simcam.sky.apparent import (
    _skycoord,
    aberration_first_order,
    apparent_directions,
    observer_barycentric_velocity_km_s,
)
from simcam.sky.catalogue import CatalogueError, hipparcos, v_minus_hp

T = Time("2026-03-21T00:00:00", scale="utc")
GEO_POS_KM = np.array([42164.0, 0.0, 0.0])
GEO_VEL_KM_S = np.array([0.0, 3.0747, 0.0])


def _angle_mas(a, b):
    # atan2(|a x b|, a.b): accurate at small angles, unlike arccos
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))) * 3.6e6


def test_catalogue_is_the_whole_hipparcos_new_reduction():
    cat = hipparcos()
    assert len(cat) == 117955
    # Sirius (HIP 32349), parallax 379.21 mas (van Leeuwen 2007); carried by its proper
    # motion from J1991.25 to J2000 it is at the SIMBAD position 06 45 08.917 -16 42 58.02
    # (101.287154, -16.716117 deg; to 1e-5 deg = 0.04")
    from astropy.time import Time as _T

    s = cat.by_hip([32349])
    assert s.parallax_mas[0] == pytest.approx(379.21, abs=0.01)
    j2000 = _skycoord(s, proper_motion=True, parallax=True).apply_space_motion(new_obstime=_T("J2000"))
    assert j2000.ra.deg[0] == pytest.approx(101.287154, abs=1e-5)
    assert j2000.dec.deg[0] == pytest.approx(-16.716117, abs=1e-5)


def test_unknown_hip_number_is_an_error_naming_it():
    with pytest.raises(CatalogueError, match="HIP 999999"):
        hipparcos().by_hip([1, 999999])


def test_v_minus_hp_follows_bessell_table():
    # Bessell (2000) Table 2 rows: B_T-V_T = 0 -> (B-V)_J = -0.005, V-Hp = -0.011;
    # B_T-V_T = 0.5 -> (B-V)_J = 0.465, V-Hp = -0.108 (exact at the table's nodes)
    np.testing.assert_allclose(v_minus_hp([-0.005, 0.465]), [-0.011, -0.108], atol=1e-12)
    # held at the ends
    assert v_minus_hp(3.0) == pytest.approx(-0.162, abs=1e-12)


def test_cone_equals_brute_force_separation():
    from astropy.coordinates import SkyCoord
    import astropy.units as u

    cat = hipparcos()
    center = np.array([0.3, -0.4, 0.866])
    center /= np.linalg.norm(center)
    sel = cat.cone(center, np.radians(4.0), mag_limit=8.0)
    c0 = SkyCoord(*center, representation_type="cartesian").spherical
    sep = SkyCoord(ra=cat.ra_rad * u.rad, dec=cat.dec_rad * u.rad).separation(
        SkyCoord(ra=c0.lon, dec=c0.lat)).deg
    want = np.flatnonzero((sep <= 4.0) & (cat.v_mag <= 8.0))
    assert sorted(sel.hip.tolist()) == sorted(cat.hip[want].tolist())


@pytest.mark.parametrize("direction", [(0.0, 0.6, 0.8), (0.0, -1.0, 0.0), (-0.5, 0.5, -0.7)])
def test_apparent_directions_equal_astropy_gcrs(direction):
    import warnings

    import astropy.units as u
    from astropy.coordinates import GCRS, CartesianRepresentation
    from erfa import ErfaWarning

    cat = hipparcos().cone(direction, np.radians(5.0), mag_limit=7.5)
    a = apparent_directions(cat, T, observer_position_km=GEO_POS_KM, observer_velocity_km_s=GEO_VEL_KM_S)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ErfaWarning)
        sc = _skycoord(cat, proper_motion=True, parallax=True).apply_space_motion(new_obstime=T)
        g = sc.transform_to(GCRS(obstime=T, obsgeoloc=CartesianRepresentation(GEO_POS_KM * u.km),
                                 obsgeovel=CartesianRepresentation(GEO_VEL_KM_S * u.km / u.s)))
    gx = g.cartesian.xyz.value.T
    # the same ERFA steps as astropy's ICRS -> GCRS: equal to rounding (1e-3 mas is 5e-12 rad)
    assert _angle_mas(a, gx).max() < 1e-3


def test_first_order_aberration_within_a_milliarcsecond_of_astropy():
    cat = hipparcos().cone((0.0, 0.6, 0.8), np.radians(5.0), mag_limit=7.5)
    full = apparent_directions(cat, T, observer_position_km=GEO_POS_KM, observer_velocity_km_s=GEO_VEL_KM_S)
    geometric = apparent_directions(cat, T, observer_position_km=GEO_POS_KM,
                                    observer_velocity_km_s=GEO_VEL_KM_S, aberration=False)
    v = observer_barycentric_velocity_km_s(T, GEO_VEL_KM_S)
    first = aberration_first_order(geometric, v)
    # second-order terms are (v/c)^2 ~ 1e-8 rad ~ 2 mas at most, about 0.4 mas here
    assert _angle_mas(full, first).max() < 1.0
    # and aberration itself is tens of arcsec (|v|/c ~ 1e-4 rad ~ 20")
    assert 5e3 < _angle_mas(full, geometric).max() < 21e3
