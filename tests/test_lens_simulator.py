"""The traced lens as the simulator's optics: the fit, the scenario's ``optics.lens``, rendering
through it, and ``simcam optics``."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from test_lens_products import SMALL_ANALYSIS, small_star_camera

from simcam.starcam import optics
from simcam.infra.errors import ScenarioError
from simcam.starcam.lens import products as lp
from simcam.starcam.lens.prescription import load_prescription
from simcam.starcam.lens.products import LensProducts, lens_products
from simcam.starcam.lens.simulator import simulator_optics
from simcam.starcam.scenario import (
    OpticsModel,
    Scenario,
    from_dict,
    scenario_to_toml,
    with_updates,
)
from simcam.units import ARCSEC_PER_RAD

F_NOM = 5.5e-3 / (5.5 / ARCSEC_PER_RAD)  # the seed-000 camera's focal length, mm


@pytest.fixture(scope="module")
def lens_file(tmp_path_factory):
    """The embedded star camera with a small analysis grid, and a private products cache."""
    d = tmp_path_factory.mktemp("lens")
    old = os.environ.get("SIMCAM_CACHE_DIR")
    os.environ["SIMCAM_CACHE_DIR"] = str(d / "cache")
    path = small_star_camera(d, SMALL_ANALYSIS.replace("field_points = 4", "field_points = 6")
                             .replace("wavelength_points = 7", "wavelength_points = 13"))
    yield path
    if old is None:
        os.environ.pop("SIMCAM_CACHE_DIR", None)
    else:
        os.environ["SIMCAM_CACHE_DIR"] = old


# --------------------------------------------------------------------------- the fit


def synthetic_products(*, k1, k2, scale, table, s0, s2, rn=2048.0, pitch_um=5.5, ref_nm=600.0):
    """Products whose centroids follow the simulator's own models exactly."""
    field = np.linspace(0.0, 3.6, 8)
    wl = np.linspace(400.0, 1000.0, 13)
    p_mm = pitch_um * 1e-3
    u0 = F_NOM * np.tan(np.radians(field)) / p_mm
    rho = u0 / rn
    u_ref = rn * rho * (1 + k1 * rho**2 + k2 * rho**4) * (1 + scale)
    du, _ = optics.lateral_colour_shift_px(wavelength_nm=wl, u_px=u_ref, v_px=0 * u_ref, ref_wavelength_nm=ref_nm,
                                           radial_coeffs=table, r_norm_px=rn)
    u = u_ref[:, None] + du
    sig_px = s0 + s2 * rho**2
    shape = u.shape
    z = np.zeros(shape)
    return LensProducts(
        prescription_name="synthetic", prescription_hash="0" * 16, variant="none", field_deg=field, wavelength_nm=wl,
        reference_wavelength_nm=ref_nm, efl_mm=F_NOM, bfd_mm=5.0, f_number=F_NOM / 60.0,
        entrance_pupil_radius_mm=30.0, entrance_pupil_z_mm=0.0, paraxial_efl_mm=np.full(wl.size, F_NOM),
        paraxial_bfd_mm=np.full(wl.size, 5.0), focus="best", image_z_mm=255.0, last_vertex_z_mm=250.0,
        rays_per_bundle=1, centroid_x_mm=-u * p_mm, centroid_y_mm=z, chief_x_mm=-u * p_mm,
        sigma_x_mm=np.repeat((sig_px * p_mm)[:, None], wl.size, axis=1),
        sigma_y_mm=np.repeat((sig_px * p_mm)[:, None], wl.size, axis=1), transmitted_fraction=z + 1,
        losses=np.zeros(shape + (1, 3), dtype=np.int64), pixel_pitch_um=pitch_um, psf=np.zeros(shape + (2, 2)),
        psf_outside_fraction=z, spot_dx_mm=np.zeros(shape + (1,)), spot_dy_mm=np.zeros(shape + (1,)),
    )


def test_lateral_colour_table_form_by_hand():
    # du = (u / rn) sum_k sum_m c_km dl^k (r / rn)^(2m), written out term by term
    rng = np.random.default_rng(5)
    c = rng.normal(size=(3, 2)) * np.array([[1e-3], [1e-6], [1e-9]])
    u = np.array([300.0, -1200.0, 0.0])
    v = np.array([-800.0, 400.0, 1500.0])
    wl = np.array([420.0, 600.0, 910.0])
    du, dv = optics.lateral_colour_shift_px(wavelength_nm=wl, u_px=u, v_px=v, ref_wavelength_nm=600.0,
                                            radial_coeffs=c, uniform_x_coeffs=(1e-4,), r_norm_px=2048.0)
    for i in range(3):
        s2 = (u[i] ** 2 + v[i] ** 2) / 2048.0**2
        for j in range(3):
            dl = wl[j] - 600.0
            p = sum(c[k, m] * dl ** (k + 1) * s2**m for k in range(3) for m in range(2))
            assert du[i, j] == pytest.approx(u[i] / 2048.0 * p + 1e-4 * dl, rel=1e-12, abs=1e-15)
            assert dv[i, j] == pytest.approx(v[i] / 2048.0 * p, rel=1e-12, abs=1e-15)
    # one column is the original form
    one, _ = optics.lateral_colour_shift_px(wavelength_nm=wl, u_px=u, v_px=v, ref_wavelength_nm=600.0,
                                            radial_coeffs=c[:, :1], r_norm_px=2048.0)
    ref, _ = optics.lateral_colour_shift_px(wavelength_nm=wl, u_px=u, v_px=v, ref_wavelength_nm=600.0,
                                            radial_coeffs=tuple(c[:, 0]), r_norm_px=2048.0)
    np.testing.assert_array_equal(one, ref)
    with pytest.raises(optics.OpticsError, match="radial_coeffs"):
        optics.lateral_colour_shift_px(wavelength_nm=wl, u_px=u, v_px=v, ref_wavelength_nm=600.0,
                                       radial_coeffs=np.zeros((2, 2, 2)), r_norm_px=2048.0)
    with pytest.raises(ScenarioError, match=r"radial_px_per_nm: table rows must have the same length"):
        from_dict({"optics": {"lateral_colour": {"radial_px_per_nm": [[1e-3, 1e-4], [1e-6]]}}})


def test_the_fit_recovers_the_simulator_models_exactly():
    table = ((2e-3, -1e-3, 4e-4), (-1e-5, 3e-6, 0.0), (2e-8, 0.0, -1e-8))
    prod = synthetic_products(k1=3e-3, k2=-4e-4, scale=2.5e-4, table=table, s0=0.6, s2=0.25)
    presc = load_prescription("embedded:star_camera")
    fit = simulator_optics(prod, presc, pixel_pitch_um=5.5, focal_length_mm=F_NOM, r_norm_px=2048.0,
                           ref_wavelength_nm=600.0, wavelength_min_nm=400.0, wavelength_max_nm=1000.0)
    assert fit.k1 == pytest.approx(3e-3, rel=1e-8) and fit.k2 == pytest.approx(-4e-4, rel=1e-6)
    assert fit.cubic_x_px[1] == pytest.approx(2.5e-4 * 2048.0, rel=1e-8) == fit.cubic_y_px[2]
    assert all(c == 0.0 for i, c in enumerate(fit.cubic_x_px) if i != 1)  # structurally zero, never computed
    got = np.zeros((7, 3))
    got[: len(fit.radial_px_per_nm)] = np.array(fit.radial_px_per_nm)
    want = np.zeros((7, 3))
    want[:3] = np.array(table)
    scale = 100.0 ** np.arange(1, 8)[:, None]  # compare at the fit's own conditioning
    np.testing.assert_allclose(got * scale, want * scale, atol=1e-9)
    assert fit.sigma0_px == pytest.approx(0.6, rel=1e-10) and fit.sigma_r2_px == pytest.approx(0.25, rel=1e-9)
    assert max(fit.distortion_max_px, fit.lateral_colour_max_px, fit.psf_sigma_rms_px) < 1e-8
    # the fitted distortion object maps the ideal positions onto the traced ones
    fu, _ = fit.distortion().forward(u_px=fit.ideal_u_px, v_px=0 * fit.ideal_u_px)
    np.testing.assert_allclose(fu, fit.measured_u_px, atol=1e-8)


def test_the_fit_to_the_traced_lens_leaves_small_residuals(lens_file):
    presc = load_prescription(lens_file)
    prod = lens_products(presc)
    fit = simulator_optics(prod, presc, pixel_pitch_um=5.5, focal_length_mm=F_NOM, r_norm_px=2048.0,
                           ref_wavelength_nm=600.0, wavelength_min_nm=400.0, wavelength_max_nm=1000.0)
    assert fit.distortion_max_px < 0.01
    assert fit.lateral_colour_max_px < 0.05
    assert fit.psf_sigma_rms_px < 0.1
    assert fit.entrance_pupil_diameter_mm == pytest.approx(60.0, rel=1e-12)
    # pincushion distortion (k1 > 0) and a lateral colour table of 3 field terms
    assert fit.k1 > 0 and len(fit.radial_px_per_nm[0]) == 3
    with pytest.raises(Exception, match=r"render\.wavelength_max_nm: 1100 nm is outside the lens's traced range"):
        simulator_optics(prod, presc, pixel_pitch_um=5.5, focal_length_mm=F_NOM, r_norm_px=2048.0,
                         ref_wavelength_nm=600.0, wavelength_min_nm=400.0, wavelength_max_nm=1100.0)


# --------------------------------------------------------------------------- the scenario


def lens_scenario(lens_file, extra=None):
    data = {"optics": {"lens": str(lens_file)}}
    for k, v in (extra or {}).items():
        node = data
        *parents, leaf = k.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[leaf] = v
    return from_dict(data, source="lens_scenario.toml")


def test_a_scenario_with_a_lens_takes_its_optics_from_the_lens(lens_file):
    scn = lens_scenario(lens_file)
    presc = load_prescription(lens_file)
    fit = simulator_optics(lens_products(presc), presc, pixel_pitch_um=5.5, focal_length_mm=F_NOM,
                           r_norm_px=2048.0, ref_wavelength_nm=600.0, wavelength_min_nm=400.0,
                           wavelength_max_nm=1000.0)
    o = scn.optics
    assert o.lens == str(lens_file) and o.psf.kind == "airy"
    assert (o.psf.sigma0_px, o.psf.sigma_r2_px) == (fit.sigma0_px, fit.sigma_r2_px)
    assert (o.distortion.k1, o.distortion.k2) == (fit.k1, fit.k2)
    assert o.lateral_colour.radial_px_per_nm == fit.radial_px_per_nm
    assert o.lateral_colour.uniform_x_px_per_nm == () == o.lateral_colour.uniform_y_px_per_nm
    assert scn.camera.aperture_diameter_mm == pytest.approx(60.0, rel=1e-12)
    # the resolved TOML loads back to the same scenario (the lens values match themselves)
    again = from_dict(__import__("tomllib").loads(scenario_to_toml(scn)))
    assert again == scn and again.hash == scn.hash
    # built in Python, the same
    assert Scenario(optics=OpticsModel(lens=str(lens_file))) == scn
    # updates re-derive what the lens sets; unrelated updates keep it
    assert with_updates(scn, {"camera.exposure_s": 0.2}).optics == scn.optics
    moved = with_updates(scn, {"optics.lateral_colour.ref_wavelength_nm": 700.0})
    assert moved.optics.lateral_colour.radial_px_per_nm != scn.optics.lateral_colour.radial_px_per_nm
    # analytic scenarios are unchanged: no lens, same hash as before lenses existed
    assert Scenario().optics.lens is None and "lens" not in scenario_to_toml(Scenario())


@pytest.mark.parametrize(
    "extra, message",
    [
        ({"optics.distortion.k1": 1e-3}, r"lens_scenario.toml: optics\.distortion: set by optics\.lens = .*differs by"),
        ({"optics.psf.kind": "gaussian"}, r"optics\.psf: set by optics\.lens"),
        ({"optics.lateral_colour.uniform_x_px_per_nm": [6e-4]}, r"optics\.lateral_colour\.uniform_x_px_per_nm: set by"),
        ({"camera.aperture_diameter_mm": 50.0}, r"camera\.aperture_diameter_mm: 50 mm differs from the entrance pupil"),
        ({"camera.plate_scale_arcsec": 5.0}, r"camera: nominal focal length 226\.891 mm .* set camera\.focal_length_mm = 206\.26"),
        ({"render.wavelength_max_nm": 1050.0}, r"render\.wavelength_max_nm: 1050 nm is outside the lens's traced range"),
        ({"detector.chip_cols": 4096}, r"optics\.lens: star_camera is traced to 3\.6 deg but the detector reaches"),
    ],
)
def test_scenario_errors_name_the_field(lens_file, extra, message):
    with pytest.raises(ScenarioError, match=message):
        lens_scenario(lens_file, extra)


def test_a_missing_lens_file_is_named(tmp_path):
    with pytest.raises(ScenarioError, match=r"optics\.lens: .*nope\.toml: lens prescription file not found"):
        from_dict({"optics": {"lens": str(tmp_path / "nope.toml")}})
    with pytest.raises(ScenarioError, match=r"optics\.lens: embedded:nope: no embedded lens"):
        from_dict({"optics": {"lens": "embedded:nope"}})


def test_rendering_through_the_lens_puts_stars_where_the_lens_images_them(lens_file):
    from simcam.starcam.render import Placement, StarCamera
    from simcam.starcam.targets import calibration_grid

    scn = lens_scenario(lens_file)
    presc = load_prescription(lens_file)
    prod = lens_products(presc)
    cam = StarCamera(scn)
    lay = calibration_grid(scn)
    scene = cam.scene(Placement(layout=lay, filter_nm=600.0, condition=0, label="grid"))
    t = scene.truth
    # the distortion the renderer injects is the traced centroid minus the ideal position,
    # interpolated radially between the traced field points (a smooth curve: cubic spline)
    from scipy.interpolate import CubicSpline

    p_mm = 5.5e-3
    u_ref = CubicSpline(prod.wavelength_nm, -prod.centroid_x_mm / p_mm, axis=1)(600.0)
    u0 = F_NOM * np.tan(np.radians(prod.field_deg)) / p_mm
    radial = CubicSpline(u0, u_ref - u0)
    r = np.hypot(lay.u_px, lay.v_px)
    d_lens = radial(r)
    d_sim = np.hypot(lay.u_px + t["distortion_dx_px"], lay.v_px + t["distortion_dy_px"]) - r
    assert np.abs(d_sim - d_lens).max() < 0.02
    assert np.abs(d_lens).max() > 5.0  # the lens does distort: the check has teeth
    # lateral colour: the spectrum-weighted shift of a 600 nm filter is tiny, of the lamp not
    assert np.abs(t["chromatic_dx_px"]).max() < 0.05
    pinhole = cam.scene(Placement(layout=lay, filter_nm=None, condition=1, label="lamp"))
    assert np.abs(pinhole.truth["chromatic_dx_px"]).max() > 0.05
    win = cam.render_windows(scene, frames=1, seed=1)
    assert win.pixels.shape[:2] == (1, lay.n_stars)


# --------------------------------------------------------------------------- the command


def test_simcam_optics_prints_the_table_and_writes_plots(lens_file, tmp_path, capsys):
    from simcam.cli import main

    out = tmp_path / "optics"
    main(["optics", str(lens_file), "--out", str(out)])
    text = capsys.readouterr().out
    assert "paraxial   f' 206.264806 mm" in text and "distortion_px" in text and "lateral colour" in text
    assert sorted(p.name for p in out.iterdir()) == ["distortion.png", "lateral_colour.png", "products.nc", "psf.png",
                                                     "spot_diagrams.png", "table.csv"]
    back = LensProducts.load(out / "products.nc")
    assert back.prescription_hash == load_prescription(lens_file).hash
    bad = tmp_path / "bad.toml"
    bad.write_text(lens_file.read_text().replace('glass = "N-SF5"', 'glass = "N-SF55"'))
    with pytest.raises(SystemExit) as info:
        main(["optics", str(bad)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "error: " in err and "surfaces.5.glass: unknown glass 'N-SF55'" in err


def test_embedded_collimator_through_the_products(tmp_path, monkeypatch):
    monkeypatch.setenv("SIMCAM_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(lp, "_MEMO", {})
    from importlib import resources

    text = resources.files("simcam.data").joinpath("lenses").joinpath("collimator.toml").read_text()
    text = text.replace("rays_per_bundle = 100000", "rays_per_bundle = 2000").replace("field_points = 10", "field_points = 3")
    f = tmp_path / "col.toml"
    f.write_text(text.replace("wavelength_points = 15", "wavelength_points = 3"))
    prod = lens_products(f)
    # the target at 1 m: a pinhole 17.5 mm off axis is seen 1 deg off axis (tan = X / F)
    assert prod.efl_mm == pytest.approx(1000.0, rel=1e-9)
    h = -prod.centroid_x_mm[:, 1]
    np.testing.assert_allclose(h, 1000.0 * np.tan(np.radians(prod.field_deg)), rtol=2e-3, atol=1e-9)
    assert math.isfinite(prod.image_z_mm)
