"""Glass catalogue of simcam.starcam.lens: Sellmeier indices against the catalogue nd and vd.

The reference values below are typed from the glass makers' data sheets (SCHOTT optical
glass data sheets; Malitson 1965 for fused silica, Malitson 1963 for CaF2), not from
simcam: nd to 5 decimals (so the tolerance is 1e-5 after rounding) and vd to 2 decimals.
"""

from __future__ import annotations

import math

import pytest

from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.glass import (
    AIR,
    CATALOGUE,
    FRAUNHOFER_C_NM,
    FRAUNHOFER_D_NM,
    FRAUNHOFER_F_NM,
    Glass,
    get_glass,
    glass_names,
)

# name: (nd, vd) from the data sheets
DATASHEET = {
    "N-BK7": (1.51680, 64.17),
    "N-K5": (1.52249, 59.48),
    "N-BAK4": (1.56883, 55.98),
    "N-SK16": (1.62041, 60.32),
    "N-LAK9": (1.69100, 54.71),
    "N-BAF10": (1.67003, 47.11),
    "N-FK51A": (1.48656, 84.47),
    "F2": (1.62004, 36.37),
    "N-SF5": (1.67271, 32.25),
    "N-SF6": (1.80518, 25.36),
    "N-SF11": (1.78472, 25.68),
    "F_SILICA": (1.45846, 67.82),
    "CAF2": (1.43385, 94.99),
}


def test_every_catalogue_glass_has_a_datasheet_reference():
    assert sorted(glass_names()) == sorted(DATASHEET)


@pytest.mark.parametrize("name", sorted(DATASHEET))
def test_index_at_d_line_and_abbe_number_match_the_datasheet(name):
    g = get_glass(name)
    nd_ref, vd_ref = DATASHEET[name]
    nd = float(g.refractive_index(FRAUNHOFER_D_NM))
    assert abs(nd - nd_ref) <= 1e-5, (name, nd, nd_ref)
    assert abs(g.abbe_number() - vd_ref) <= 0.01 + 0.005, (name, g.abbe_number(), vd_ref)


def test_sellmeier_formula_by_hand_for_n_bk7():
    # SCHOTT N-BK7 coefficients written out here: n^2 - 1 = sum B l^2 / (l^2 - C), l in um
    b = (1.03961212, 0.231792344, 1.01046945)
    c = (0.00600069867, 0.0200179144, 103.560653)
    for wl_nm in (365.0, 486.1327, 632.8, 1064.0):
        l2 = (wl_nm / 1000.0) ** 2
        ref = math.sqrt(1.0 + sum(bi * l2 / (l2 - ci) for bi, ci in zip(b, c)))
        assert float(get_glass("n-bk7").refractive_index(wl_nm)) == pytest.approx(ref, abs=1e-15)


def test_dispersion_is_normal_over_the_visible_and_near_infrared():
    for g in CATALOGUE.values():
        if g.is_air:
            continue
        n = g.refractive_index([400.0, 500.0, 600.0, 800.0, 1000.0])
        assert all(a > b for a, b in zip(n, n[1:])), g.name


def test_air_is_exactly_one_and_the_fraunhofer_lines():
    assert list(AIR.refractive_index([400.0, 1000.0])) == [1.0, 1.0]
    assert (FRAUNHOFER_F_NM, FRAUNHOFER_D_NM, FRAUNHOFER_C_NM) == (486.1327, 587.5618, 656.2725)


def test_unknown_glass_names_the_closest_matches():
    with pytest.raises(LensError, match=r"unknown glass 'N-BK8' \(did you mean N-BK7"):
        get_glass("N-BK8")
    with pytest.raises(LensError, match="non-empty"):
        get_glass("  ")


def test_aliases_and_case():
    assert get_glass("fused_silica") is get_glass("F_SILICA")
    assert get_glass("caf2") is CATALOGUE["CAF2"]
    assert get_glass("Air").is_air


def test_wavelength_outside_the_fit_is_an_error():
    with pytest.raises(LensError, match="N-SF6: wavelength 350-350 nm outside"):
        get_glass("N-SF6").refractive_index(350.0)


def test_user_glass_with_a_pole_in_range_is_refused():
    with pytest.raises(LensError, match="no real index > 1"):
        Glass(name="BAD", b=(1.0, 0.2, 1.0), c_um2=(0.25, 0.02, 100.0), source="test", valid_nm=(300.0, 1000.0))
    ok = Glass(name="GOOD", b=(1.03961212, 0.231792344, 1.01046945),
               c_um2=(0.00600069867, 0.0200179144, 103.560653), source="test")
    assert get_glass("good", {"GOOD": ok}) is ok
