"""Lens prescriptions: TOML loading, the embedded lenses, and bad input named by field."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import paraxial
from simcam.starcam.lens.prescription import (
    embedded_lens_names,
    load_prescription,
    prescription_from_dict,
)

SINGLET = """
name = "singlet"
[analysis]
field_max_deg = 2.0
field_points = 3
wavelength_points = 3
rays_per_bundle = 500
focus_rays_per_bundle = 256
[[surfaces]]
name = "stop"
radius_mm = inf
thickness_mm = 2.0
semi_diameter_mm = 10.0
stop = true
[[surfaces]]
radius_mm = 60.0
thickness_mm = 6.0
glass = "N-BK7"
semi_diameter_mm = 12.0
[[surfaces]]
radius_mm = -300.0
thickness_mm = 95.0
semi_diameter_mm = 12.0
"""


def write(tmp_path, text, name="lens.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_embedded_lenses_load_and_have_their_stated_first_order_properties():
    assert {"star_camera", "collimator"} <= set(embedded_lens_names())
    cam = load_prescription("embedded:star_camera")
    para = paraxial(cam, wavelength_nm=cam.analysis.reference_wavelength_nm)
    # 5.5 um pixels at 5.5 arcsec/px: f' = 5.5e-3 mm / (5.5 / 206264.806...) rad
    f_target = 5.5e-3 / (5.5 / (180.0 * 3600.0 / math.pi))
    assert para.efl_mm == pytest.approx(f_target, rel=1e-9)
    assert 2 * para.entrance_pupil_radius_mm == pytest.approx(60.0, rel=1e-12)
    assert para.bfd_mm > 3.0  # the detector sits behind the last vertex
    col = load_prescription("embedded:collimator")
    assert paraxial(col, wavelength_nm=col.analysis.reference_wavelength_nm).efl_mm == pytest.approx(1000.0, rel=1e-6)


def test_file_and_dict_loading_agree_and_vertex_positions(tmp_path):
    p = load_prescription(write(tmp_path, SINGLET))
    assert p.stop_index == 0
    np.testing.assert_array_equal(p.vertex_z_mm, [0.0, 2.0, 8.0])
    assert p.image_distance_mm == 95.0
    assert [g.name for g in p.media()] == ["AIR", "AIR", "N-BK7", "AIR"]
    import tomllib

    assert prescription_from_dict(tomllib.loads(SINGLET)) == p
    assert load_prescription(p) is p


def test_hash_follows_content_and_not_layout(tmp_path):
    a = load_prescription(write(tmp_path, SINGLET, "a.toml"))
    b = load_prescription(write(tmp_path, "# comment\n" + SINGLET.replace("= 60.0", "=   60.0"), "b.toml"))
    c = load_prescription(write(tmp_path, SINGLET.replace("= 60.0", "= 60.5"), "c.toml"))
    d = load_prescription(write(tmp_path, SINGLET.replace("rays_per_bundle = 500", "rays_per_bundle = 600"), "d.toml"))
    assert a.hash == b.hash and len(a.hash) == 16
    assert len({a.hash, c.hash, d.hash}) == 3


@pytest.mark.parametrize(
    "edit, message",
    [
        (("thickness_mm = 6.0", "thickness_mm = -1.0"), r"surfaces\.1\.thickness_mm: Input should be greater than or equal to 0"),
        (('glass = "N-BK7"', 'glass = "N-BK8"'), r"surfaces\.1\.glass: unknown glass 'N-BK8' \(did you mean N-BK7"),
        (("radius_mm = 60.0", "radius_mm = 0.0"), r"surfaces\.1\.radius_mm: Value error, must not be 0"),
        (("stop = true", "stop = false"), r"exactly one surface needs stop = true \(found 0"),
        (("semi_diameter_mm = 12.0\n[[surfaces]]\nradius_mm = -300.0", "semi_diameter_mm = 12.0\nstop = true\n[[surfaces]]\nradius_mm = -300.0"),
         r"exactly one surface needs stop = true \(found 2: surfaces \[0, 1\]"),
        (("thickness_mm = 6.0", "thickness_mm = 1.0"), r"surfaces\.2: crosses surface 1 inside the clear aperture"),
        (('radius_mm = -300.0\nthickness_mm = 95.0', 'radius_mm = -300.0\nthickness_mm = 95.0\nglass = "F2"'),
         r"surfaces\.2\.glass: the image space must be air"),
        (("semi_diameter_mm = 10.0", "semi_diameter_mm = 10.0\nfocal = 3"), r"surfaces\.0\.focal: unknown key"),
        (("field_max_deg = 2.0", "field_max_deg = -2.0"), r"analysis\.field_max_deg: Input should be greater than 0"),
        (("wavelength_points = 3", "wavelength_points = 3\nreference_wavelength_nm = 350.0"),
         r"analysis: Value error, reference_wavelength_nm = 350 lies outside 400-1000 nm"),
        (("wavelength_points = 3", "wavelength_points = 3\nwavelength_min_nm = 250.0\nreference_wavelength_nm = 500.0"),
         r"surfaces\.1\.glass: N-BK7's Sellmeier fit is valid over 300-2500 nm, analysis asks 250-1000 nm"),
    ],
)
def test_bad_prescriptions_name_the_field(tmp_path, edit, message):
    old, new = edit
    assert old in SINGLET
    with pytest.raises(LensError, match=message) as info:
        load_prescription(write(tmp_path, SINGLET.replace(old, new, 1)))
    assert str(tmp_path / "lens.toml") in str(info.value)


def test_conic_domain_and_radius_nan(tmp_path):
    text = SINGLET.replace("radius_mm = 60.0\n", "radius_mm = 20.0\nconic = 1.0\n")  # (1+k) c^2 s <= 1: rho <= 14.1
    text = text.replace("semi_diameter_mm = 12.0\n[[surfaces]]\nradius_mm = -300.0", "semi_diameter_mm = 15.0\n[[surfaces]]\nradius_mm = -300.0")
    with pytest.raises(LensError, match=r"surfaces\.1\.semi_diameter_mm: 15 mm exceeds the surface's domain"):
        load_prescription(write(tmp_path, text))
    with pytest.raises(LensError, match=r"surfaces\.1\.radius_mm: .*NaN"):
        load_prescription(write(tmp_path, SINGLET.replace("radius_mm = 60.0", "radius_mm = nan")))


def test_user_glass_table(tmp_path):
    text = SINGLET.replace('glass = "N-BK7"', 'glass = "my-glass"') + """
[[glasses]]
name = "MY-GLASS"
sellmeier_b = [1.03961212, 0.231792344, 1.01046945]
sellmeier_c_um2 = [0.00600069867, 0.0200179144, 103.560653]
source = "N-BK7 coefficients, typed again"
"""
    p = load_prescription(write(tmp_path, text))
    ref = load_prescription(write(tmp_path, SINGLET, "ref.toml"))
    np.testing.assert_allclose(p.indices([500.0]), ref.indices([500.0]), rtol=0, atol=0)
    bad = text.replace("0.00600069867", "0.25")
    with pytest.raises(LensError, match=r"glasses\.0: glass MY-GLASS: the Sellmeier coefficients give no real index"):
        load_prescription(write(tmp_path, bad, "bad.toml"))


def test_missing_files_and_unknown_embedded_names(tmp_path):
    with pytest.raises(LensError, match="lens prescription file not found"):
        load_prescription(tmp_path / "nope.toml")
    with pytest.raises(LensError, match=r"no embedded lens 'nope' \(embedded: "):
        load_prescription("embedded:nope")
    with pytest.raises(LensError, match="not valid TOML"):
        load_prescription(write(tmp_path, "name = ", "broken.toml"))
