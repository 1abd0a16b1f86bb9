"""Traced products: PSF against Airy (and against simcam.starcam.psf_stamps' analytic disc x Airy), the
closed-form best focus against a numerical minimisation, the tables, the disk cache."""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest
from scipy import integrate, optimize
from scipy.special import j1

from simcam.starcam import psf_stamps
from simcam.starcam.lens import products as lp
from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import paraxial
from simcam.starcam.lens.prescription import load_prescription
from simcam.starcam.lens.products import (
    LensProducts,
    best_focus_z,
    compute_products,
    lens_products,
    psf_stamp,
)
from simcam.starcam.lens.tracer import LensTracer, field_bundle, symmetric_pupil

SMALL_ANALYSIS = """[analysis]
field_max_deg = 3.6
field_points = 4
wavelength_min_nm = 400.0
wavelength_max_nm = 1000.0
wavelength_points = 7
reference_wavelength_nm = 600.0
rays_per_bundle = 3000
focus_rays_per_bundle = 600
focus = "best"
pixel_pitch_um = 5.5
psf_stamp_px = 32
"""


def small_star_camera(tmp_path, analysis=SMALL_ANALYSIS, name="small.toml"):
    """The embedded star camera with a small analysis grid (fast to trace)."""
    text = resources.files("simcam.data").joinpath("lenses").joinpath("star_camera.toml").read_text()
    head, rest = text.split("[analysis]", 1)
    body = rest[rest.index("[[surfaces]]"):]
    p = tmp_path / name
    p.write_text(head + analysis + "\n" + body)
    return p


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    path = small_star_camera(tmp_path_factory.mktemp("lens"))
    p = load_prescription(path)
    return p, LensTracer(p), compute_products(p)


# --------------------------------------------------------------------------- PSF


def airy_pixel(ix, iy, cutoff):
    """Pixel-integrated Airy pattern (unit integral) over pixel (ix, iy), by quadrature."""

    def irr(y, x):
        r = math.hypot(x, y)
        v = math.pi * cutoff * r
        amp = 1.0 if v == 0.0 else 2.0 * j1(v) / v
        return math.pi * cutoff * cutoff / 4.0 * amp * amp

    val, _ = integrate.dblquad(irr, ix - 0.5, ix + 0.5, iy - 0.5, iy + 0.5, epsabs=1e-11, epsrel=1e-9)
    return val


def test_psf_of_a_point_spot_is_the_pixel_integrated_airy_pattern():
    wl, n_f, pitch = 600.0, 3.4377, 5.5
    cutoff = pitch / (wl * 1e-3 * n_f)
    stamp, outside = psf_stamp(x_px=np.zeros(10), y_px=np.zeros(10), wavelength_nm=wl, f_number=n_f,
                               pixel_pitch_um=pitch, stamp_px=32)
    assert outside == 0.0  # a fraction of counted rays: exactly 0 when none leaves the stamp
    assert stamp.sum() == pytest.approx(1.0, abs=1e-12)
    c = 16
    for ix, iy in [(0, 0), (1, 0), (1, 1), (2, 1), (3, 0), (5, 4)]:
        ref = airy_pixel(ix, iy, cutoff)
        # the stamp is periodic (32 px): the Airy wings folding back are below 1e-5 per px
        assert stamp[c + iy, c + ix] == pytest.approx(ref, abs=1e-5), (ix, iy)
    np.testing.assert_allclose(stamp, stamp.T, atol=1e-15)
    np.testing.assert_allclose(stamp, stamp[::-1, :][np.r_[31, 0:31], :], atol=1e-15)


def test_psf_of_a_uniform_disc_spot_matches_simcam_optics_disc_times_airy():
    # a defocus-like spot: rays uniformly filling a disc of radius a; simcam.starcam.psf_stamps.render_stamps
    # computes the same pixel-integrated (disc x Airy) image analytically (Goodman's OTFs)
    wl, n_f, pitch, a = 700.0, 3.4377, 5.5, 1.3
    x, y = symmetric_pupil(400_000)
    stamp, _ = psf_stamp(x_px=a * x, y_px=a * y, wavelength_nm=wl, f_number=n_f, pixel_pitch_um=pitch,
                         stamp_px=32, oversample=16)
    ref, ox, oy = psf_stamps.render_stamps(
        x_px=np.array([16.0]), y_px=np.array([16.0]), stamp_px=32, psf_kind="airy", sigma_px=np.array([0.0]),
        pinhole_radius_px=a, f_number=n_f, pixel_pitch_um=pitch, wavelength_nm=np.array([wl]),
        weights=np.ones((1, 1)), shift_x_px=np.zeros((1, 1)), shift_y_px=np.zeros((1, 1)),
    )
    assert (ox[0], oy[0]) == (0, 0)
    # binning the rays 1/16 px fine blurs by ~0.02 px: a few 1e-4 of the peak
    assert np.abs(stamp - ref[0]).max() < 1.5e-3 * ref[0].max()


def test_psf_stamp_input_errors():
    with pytest.raises(LensError, match="even integer"):
        psf_stamp(x_px=[0.0], y_px=[0.0], wavelength_nm=600.0, f_number=3.0, pixel_pitch_um=5.5, stamp_px=31)
    with pytest.raises(LensError, match="too coarse"):
        psf_stamp(x_px=[0.0], y_px=[0.0], wavelength_nm=400.0, f_number=3.0, pixel_pitch_um=5.5, oversample=4)
    with pytest.raises(LensError, match="same number"):
        psf_stamp(x_px=[], y_px=[], wavelength_nm=600.0, f_number=3.0, pixel_pitch_um=5.5)


# --------------------------------------------------------------------------- focus


def test_closed_form_best_focus_is_the_minimum_of_the_mean_square_spot_radius(small):
    p, tr, _ = small
    para = paraxial(p, wavelength_nm=600.0)
    results = []
    for f in (0.0, 2.0, 3.6):
        rays = field_bundle(p, field_deg=f, n_rays=800, para=para)
        for wl in (450.0, 600.0, 900.0):
            results.append(tr.trace(x_mm=rays[0], y_mm=rays[1], z_mm=rays[2], dx=rays[3], dy=rays[4], dz=rays[5],
                                    wavelength_nm=wl))

    def objective(z):
        tot = 0.0
        for r in results:
            x, y = r.at_plane(z)
            tot += x.var() + y.var()
        return tot / len(results)

    z_par = p.vertex_z_mm[-1] + para.bfd_mm
    z_star = best_focus_z(results, z_ref=z_par)
    z_num = optimize.minimize_scalar(objective, bracket=(z_par - 0.5, z_par + 0.5), tol=1e-12).x
    assert z_star == pytest.approx(z_num, abs=1e-7)
    assert objective(z_star) <= min(objective(z_star - 1e-4), objective(z_star + 1e-4))
    # the same from another reference plane
    assert best_focus_z(results, z_ref=z_par + 3.0) == pytest.approx(z_star, abs=1e-12)


# --------------------------------------------------------------------------- tables


def test_product_tables(small):
    _, _, prod = small
    nf, nl = 4, 7
    assert prod.centroid_x_mm.shape == (nf, nl) and prod.psf.shape == (nf, nl, 32, 32)
    assert np.all(prod.transmitted_fraction == 1.0) and prod.losses.sum() == 0  # ratios of ray counts: exact
    # a rotationally symmetric lens and a pupil sampling symmetric about the meridian
    assert np.abs(prod.centroid_y_mm).max() < 1e-15
    # image inverted: a star at +theta lands at x < 0, about f' tan(theta) from the axis (the
    # lens has up to 1.4 % pincushion distortion)
    theta = np.radians(prod.field_deg)
    np.testing.assert_allclose(-prod.centroid_x_mm[1:, 3], prod.efl_mm * np.tan(theta[1:]), rtol=1.5e-2)
    assert np.all(prod.centroid_x_mm[1:] < 0)
    # on axis every wavelength is centred
    assert np.abs(prod.centroid_x_mm[0]).max() < 1e-15
    # the chief ray lands near the centroid off axis (coma moves the centroid by ~10 um at the edge)
    assert np.abs(prod.chief_x_mm - prod.centroid_x_mm).max() < 0.02
    # PSF stamps: unit sum, centred on the centroid (first moment at the stamp centre)
    sums = prod.psf.sum(axis=(-1, -2))
    np.testing.assert_allclose(sums, 1.0, atol=1e-9)
    grid = np.arange(32) - 16
    cx = (prod.psf.sum(axis=-2) * grid).sum(axis=-1)
    assert np.abs(cx).max() < 0.05
    # the rms spot of the stamp is at least the geometric one (diffraction adds)
    var_x = (prod.psf.sum(axis=-2) * grid**2).sum(axis=-1) - cx**2
    assert np.all(var_x + 0.02 > (prod.sigma_x_mm / 5.5e-3) ** 2)
    # best focus: between the paraxial foci of the extreme wavelengths, close to paraxial
    assert abs(prod.back_focal_distance_mm - prod.bfd_mm) < 0.5
    assert prod.wavelength_nm[2] == pytest.approx(600.0, rel=4 * np.finfo(float).eps)  # a grid node
    np.testing.assert_allclose(prod.paraxial_efl_mm[2], prod.efl_mm, rtol=1e-12)
    assert np.isfinite(prod.spot_dx_mm).sum(axis=-1).min() == 3000 // max(1, 3000 // lp.SPOT_SAMPLES)


def test_focus_choices(tmp_path):
    p = load_prescription(small_star_camera(tmp_path, SMALL_ANALYSIS.replace('focus = "best"', 'focus = "paraxial"')
                                            .replace("field_points = 4", "field_points = 2")
                                            .replace("wavelength_points = 7", "wavelength_points = 2"), "par.toml"))
    prod = compute_products(p)
    assert prod.image_z_mm == pytest.approx(p.vertex_z_mm[-1] + prod.bfd_mm, abs=1e-12)
    p2 = load_prescription(small_star_camera(tmp_path, SMALL_ANALYSIS.replace('focus = "best"', 'focus = "prescription"')
                                             .replace("field_points = 4", "field_points = 2")
                                             .replace("wavelength_points = 7", "wavelength_points = 2"), "pre.toml"))
    prod2 = compute_products(p2)
    assert prod2.image_z_mm == pytest.approx(p2.vertex_z_mm[-1] + p2.image_distance_mm, abs=1e-12)


def test_a_bundle_that_loses_every_ray_names_the_surface(tmp_path):
    f = tmp_path / "vignette.toml"
    f.write_text("""
name = "vignetting"
[analysis]
field_max_deg = 3.0
field_points = 2
wavelength_points = 2
rays_per_bundle = 200
focus_rays_per_bundle = 100
[[surfaces]]
name = "stop"
radius_mm = inf
thickness_mm = 100.0
semi_diameter_mm = 2.0
stop = true
[[surfaces]]
name = "small window"
radius_mm = inf
thickness_mm = 2.0
glass = "N-BK7"
semi_diameter_mm = 2.5
[[surfaces]]
radius_mm = -50.0
thickness_mm = 50.0
semi_diameter_mm = 2.5
""")
    with pytest.raises(LensError, match=r"every ray of the bundle at field 3 deg, 400 nm is lost \(most at "
                                        r"surfaces\.1: aperture"):
        compute_products(f)


def test_save_load_round_trip_and_the_disk_cache(small, tmp_path, monkeypatch):
    p, _, prod = small
    path = prod.save(tmp_path / "p.nc")
    back = LensProducts.load(path)
    for name in ("centroid_x_mm", "sigma_y_mm", "psf", "losses", "spot_dx_mm", "field_deg", "paraxial_bfd_mm"):
        np.testing.assert_array_equal(getattr(back, name), getattr(prod, name))
    assert (back.variant, back.focus, back.prescription_hash, back.image_z_mm) == (
        prod.variant, prod.focus, prod.prescription_hash, prod.image_z_mm)
    # the cache: traced once, then read from memory, then (memory cleared) from disk
    monkeypatch.setenv("SIMCAM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(lp, "_MEMO", {})
    calls = []
    real = lp.compute_products
    monkeypatch.setattr(lp, "compute_products", lambda *a, **k: calls.append(1) or real(*a, **k))
    first = lens_products(p)
    assert calls == [1] and not first.from_cache
    files = list((tmp_path / "cache" / "lens").glob(f"*{p.hash}.nc"))
    assert len(files) == 1
    assert lens_products(p) is first and calls == [1]
    monkeypatch.setattr(lp, "_MEMO", {})
    again = lens_products(p)
    assert calls == [1] and again.from_cache
    np.testing.assert_array_equal(again.centroid_x_mm, first.centroid_x_mm)
    # a corrupt cache file is traced again and replaced
    monkeypatch.setattr(lp, "_MEMO", {})
    files[0].write_bytes(b"not netcdf")
    third = lens_products(p)
    assert calls == [1, 1] and not third.from_cache
