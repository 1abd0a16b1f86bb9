"""Paraxial optics: ABCD matrices against closed-form lens formulas, and the real-ray tracer in
its paraxial limit against ABCD (focal length, back focal distance, chief-ray heights to 1e-6)."""

from __future__ import annotations

import math

import lens_reference as ref
import numpy as np
import pytest

from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import paraxial
from simcam.starcam.lens.prescription import load_prescription, prescription_from_dict
from simcam.starcam.lens.tracer import LensTracer


def singlet(r1, r2, d, glass="N-BK7", stop_gap=1.0, stop_first=True, stop_after=20.0):
    surfs = []
    if stop_first:
        surfs.append({"name": "stop", "radius_mm": math.inf, "thickness_mm": stop_gap, "semi_diameter_mm": 5.0,
                      "stop": True})
    surfs += [
        {"radius_mm": r1, "thickness_mm": d, "glass": glass, "semi_diameter_mm": 8.0},
        {"radius_mm": r2, "thickness_mm": stop_after if not stop_first else 100.0, "semi_diameter_mm": 8.0},
    ]
    if not stop_first:
        surfs.append({"name": "stop", "radius_mm": math.inf, "thickness_mm": 100.0, "semi_diameter_mm": 5.0,
                      "stop": True})
    return prescription_from_dict({"name": "singlet", "analysis": {"field_max_deg": 1.0}, "surfaces": surfs})


@pytest.mark.parametrize("r1, r2, d", [(50.0, -80.0, 6.0), (40.0, math.inf, 4.0), (-60.0, -25.0, 8.0),
                                       (30.0, 45.0, 3.0)])
def test_thick_lens_focal_length_and_back_focal_distance(r1, r2, d):
    # thick-lens formulas (Hecht, Optics, 4th ed., eqs. 6.2 and 6.3)
    p = singlet(r1, r2, d)
    wl = 587.5618
    n = ref.sellmeier_index(*ref.GLASS_COEFFS["N-BK7"], wl)
    c1, c2 = 1 / r1, (0.0 if math.isinf(r2) else 1 / r2)
    power = (n - 1) * (c1 - c2 + (n - 1) * d * c1 * c2 / n)
    f = 1 / power
    bfd = f * (1 - (n - 1) * d * c1 / n)
    para = paraxial(p, wavelength_nm=wl)
    assert para.efl_mm == pytest.approx(f, rel=1e-12)
    assert para.bfd_mm == pytest.approx(bfd, rel=1e-12)
    # stop in front of the lens: the pupil is the stop itself (traced through no surface), so
    # only the rounding of the paraxial imaging of a point at z=0 enters
    assert para.entrance_pupil_z_mm == pytest.approx(0.0, abs=1e-12)
    assert para.entrance_pupil_radius_mm == pytest.approx(5.0, rel=1e-12)
    assert para.f_number == pytest.approx(abs(f) / 10.0, rel=1e-12)
    assert np.linalg.det(para.system_matrix) == pytest.approx(1.0, abs=1e-12)


def test_entrance_pupil_of_a_stop_behind_the_lens():
    # stop 20 mm behind a plano-convex lens (flat side last). Image the stop backwards
    # with the single-surface equation n'/s' - n/s = (n' - n)/R, one surface at a time.
    r1, d, gap = 50.0, 6.0, 20.0
    p = singlet(r1, math.inf, d, stop_first=False, stop_after=gap)
    wl = 600.0
    n = ref.sellmeier_index(*ref.GLASS_COEFFS["N-BK7"], wl)
    # flat surface seen from inside the glass: the stop appears at depth gap * n behind it
    s_in_glass = d + gap * n  # distance from the first vertex, in glass
    # curved surface from glass (index n) to air (index 1), light going backwards:
    # object at s_in_glass to the right (in glass); image in air at z: 1/z' ... use
    # n_obj / s_obj + n_img / s_img = (n_img - n_obj) / R_back with R seen backwards = -r1
    s_img = 1.0 / ((1.0 - n) / (-r1) - n / s_in_glass)
    z_ep = -s_img  # measured along +z from the first vertex
    mag = -(n * s_img) / (1.0 * s_in_glass)  # lateral magnification -(n s') / (n' s) of the stop
    para = paraxial(p, wavelength_nm=wl)
    assert para.entrance_pupil_z_mm == pytest.approx(z_ep, rel=1e-12)
    assert para.entrance_pupil_radius_mm == pytest.approx(abs(5.0 * mag), rel=1e-12)


def test_afocal_system_is_an_error():
    # a plane-parallel plate has no power (C = 0)
    p = prescription_from_dict({"name": "plate", "analysis": {"field_max_deg": 1.0}, "surfaces": [
        {"radius_mm": math.inf, "thickness_mm": 5.0, "glass": "N-BK7", "semi_diameter_mm": 5.0, "stop": True},
        {"radius_mm": math.inf, "thickness_mm": 10.0, "semi_diameter_mm": 5.0}]})
    with pytest.raises(LensError, match="afocal"):
        paraxial(p, wavelength_nm=550.0)


@pytest.fixture(scope="module")
def camera():
    p = load_prescription("embedded:star_camera")
    return p, LensTracer(p)


@pytest.mark.parametrize("wl", [450.0, 600.0, 950.0])
def test_real_rays_in_the_paraxial_limit_agree_with_abcd(camera, wl):
    p, tr = camera
    para = paraxial(p, wavelength_nm=wl)
    z_last = p.vertex_z_mm[-1]
    # a ray parallel to the axis at a small height h: f' = -h / u', BFD = -y_last / u'
    h = 1e-4
    res = tr.trace(x_mm=[0.0], y_mm=[h], z_mm=[-1.0], dx=[0.0], dy=[0.0], dz=[1.0], wavelength_nm=wl)
    u_out = res.dy[0] / res.dz[0]
    efl = -h / u_out
    bfd = (res.z_mm[0] - z_last) - res.y_mm[0] / u_out
    assert efl == pytest.approx(para.efl_mm, rel=1e-6)
    assert bfd == pytest.approx(para.bfd_mm, rel=1e-6)
    # chief ray: slope u through the entrance-pupil centre; heights per unit slope
    u = 1e-6
    z0 = -1.0
    y0 = para.entrance_pupil_z_mm * 0 + (z0 - para.entrance_pupil_z_mm) * u
    dz = 1.0 / math.sqrt(1 + u * u)
    res = tr.trace(x_mm=[0.0], y_mm=[y0], z_mm=[z0], dx=[0.0], dy=[u * dz], dz=[dz], wavelength_nm=wl,
                   record_path=True)
    real = res.path_mm[:, 1, 0] / u
    abcd = para.chief_height_per_slope_mm[:-1]
    big = np.abs(abcd) > 1e-9
    np.testing.assert_allclose(real[big], abcd[big], rtol=1e-6)
    assert np.all(np.abs(real[~big]) < 1e-6)
    # at the paraxial image plane the chief ray is at f' u
    t = (z_last + para.bfd_mm - res.z_mm[0]) / res.dz[0]
    y_img = (res.y_mm[0] + t * res.dy[0]) / u
    assert y_img == pytest.approx(para.chief_height_per_slope_mm[-1], rel=1e-6)
    assert para.chief_height_per_slope_mm[-1] == pytest.approx(para.efl_mm, rel=1e-9)


def test_longitudinal_colour_of_the_collimator_is_that_of_an_achromat():
    p = load_prescription("embedded:collimator")
    bfd = np.array([paraxial(p, wavelength_nm=w).bfd_mm for w in (486.1327, 587.5618, 656.2725)])
    # an achromat brings F and C to a common focus (closely: here within 0.2 mm of 1 m)
    assert abs(bfd[0] - bfd[2]) < 0.2
    assert bfd[1] < min(bfd[0], bfd[2])  # d-line focus nearest: the secondary spectrum
