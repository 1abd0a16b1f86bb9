"""The Mitsuba tracer of simcam.starcam.lens against the plain-numpy reference tracer (tests/lens_reference.py),
and what happens to rays that miss, leave the clear aperture or are totally reflected.

Real-ray positions must agree to 1e-9 mm on every surface, in both Mitsuba variants
(``llvm_ad_rgb`` vectorised, ``scalar_rgb`` the fallback).
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
import tomllib
from importlib import resources

import lens_reference as ref
import numpy as np
import pytest

from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.prescription import load_prescription
from simcam.starcam.lens.tracer import (
    LOSS_REASONS,
    LensTracer,
    field_bundle,
    symmetric_pupil,
    vogel_pupil,
)

TOL_MM = 1e-9
VARIANTS = ("llvm_ad_rgb", "scalar_rgb")


def _reference_setup(text: str):
    data = tomllib.loads(text)
    data["_glass_coeffs"] = ref.GLASS_COEFFS
    return ref.surfaces_from_prescription_dict(data)


def _embedded_text(name: str) -> str:
    return resources.files("simcam.data").joinpath("lenses").joinpath(f"{name}.toml").read_text()


@pytest.fixture(scope="module")
def tracers():
    p = load_prescription("embedded:star_camera")
    return p, {v: LensTracer(p, variant=v) for v in VARIANTS}


def compare_with_reference(tracer, text, rays, wavelength_nm):
    surfs, indices = _reference_setup(text)
    res = tracer.trace(x_mm=rays[0], y_mm=rays[1], z_mm=rays[2], dx=rays[3], dy=rays[4], dz=rays[5],
                       wavelength_nm=wavelength_nm, record_path=True)
    path, d, ok = ref.trace(surfs, indices(wavelength_nm), *rays)
    np.testing.assert_array_equal(res.alive, ok)
    a = res.alive
    for j, (x, y, z) in enumerate(path):
        keep = a
        for k, c in enumerate((x, y, z)):
            err = np.abs(res.path_mm[j, k][keep] - c[keep])
            assert err.max(initial=0.0) <= TOL_MM, (j, k, err.max())
    for k, c in enumerate(d):
        assert np.abs((res.dx, res.dy, res.dz)[k][a] - c[a]).max(initial=0.0) <= 1e-12
    return res


@pytest.mark.parametrize("variant", VARIANTS)
def test_star_camera_rays_match_the_reference_tracer(tracers, variant):
    p, trs = tracers
    text = _embedded_text("star_camera")
    n = 400 if variant == "llvm_ad_rgb" else 60
    for field in (0.0, 1.7, 3.6):
        rays = field_bundle(p, field_deg=field, n_rays=n)
        for wl in (400.0, 633.0, 1000.0):
            res = compare_with_reference(trs[variant], text, rays, wl)
            assert res.alive.all()


ASPHERE = """
name = "asphere-test"
[analysis]
field_max_deg = 4.0
[[surfaces]]
name = "stop, far in front of a concave surface"
radius_mm = inf
thickness_mm = 50.0
semi_diameter_mm = 6.0
stop = true
[[surfaces]]
name = "concave conic: the ray starts outside its sphere (far hemisphere first)"
radius_mm = -20.0
conic = -0.6
thickness_mm = 8.0
glass = "N-SF6"
semi_diameter_mm = 9.0
[[surfaces]]
name = "even asphere"
radius_mm = -30.0
conic = 0.5
aspheric_coeffs = [2e-5, -1e-7]
thickness_mm = 3.0
semi_diameter_mm = 11.0
[[surfaces]]
name = "flat with aspheric terms"
radius_mm = inf
aspheric_coeffs = [1e-5]
thickness_mm = 4.0
glass = "F_SILICA"
semi_diameter_mm = 12.0
[[surfaces]]
radius_mm = -60.0
thickness_mm = 40.0
semi_diameter_mm = 12.0
"""


@pytest.mark.parametrize("variant", VARIANTS)
def test_conic_aspheric_and_far_hemisphere_surfaces_match_the_reference(tmp_path, variant):
    f = tmp_path / "asphere.toml"
    f.write_text(ASPHERE)
    p = load_prescription(f)
    tr = LensTracer(p, variant=variant)
    assert tr._far_check[1] and not tr._far_check[2]  # the re-query path is exercised
    n = 300 if variant == "llvm_ad_rgb" else 50
    for field in (0.0, 2.5, 4.0):
        rays = field_bundle(p, field_deg=field, n_rays=n)
        res = compare_with_reference(tr, ASPHERE, rays, 550.0)
        assert res.alive.mean() > 0.9


def _single_surface_lens(tmp_path, body: str, stop_sd: float):
    text = textwrap.dedent(f"""
    name = "loss-test"
    [analysis]
    field_max_deg = 1.0
    [[surfaces]]
    name = "stop"
    radius_mm = inf
    thickness_mm = 2.0
    semi_diameter_mm = {stop_sd}
    stop = true
    """) + textwrap.dedent(body)
    f = tmp_path / "loss.toml"
    f.write_text(text)
    return load_prescription(f), text


def _vogel_radii(n, scale):
    x, y = symmetric_pupil(n)
    return scale * np.hypot(x, y)


@pytest.mark.parametrize("variant", VARIANTS)
def test_total_internal_reflection_is_counted_at_its_surface(tmp_path, variant):
    # a flat entry into N-SF6, then an exit surface of radius 8 mm: a ray parallel to the
    # axis at height h meets it at incidence asin(h / R) and is totally reflected when
    # h > R / n (sin of the critical angle = 1 / n)
    p, text = _single_surface_lens(tmp_path, """
    [[surfaces]]
    radius_mm = inf
    thickness_mm = 5.0
    glass = "N-SF6"
    semi_diameter_mm = 7.0
    [[surfaces]]
    radius_mm = 8.0
    thickness_mm = 10.0
    semi_diameter_mm = 7.0
    """, stop_sd=6.0)
    n_rays = 500 if variant == "llvm_ad_rgb" else 80
    wl = 600.0
    n_glass = ref.sellmeier_index(*ref.GLASS_COEFFS["N-SF6"], wl)
    h_crit = 8.0 / n_glass
    r = _vogel_radii(n_rays, 6.0)
    assert np.min(np.abs(r - h_crit)) > 1e-6  # no ray on the boundary
    tr = LensTracer(p, variant=variant)
    rays = field_bundle(p, field_deg=0.0, n_rays=n_rays)
    res = compare_with_reference(tr, text, rays, wl)
    losses = res.losses()
    assert losses[2, LOSS_REASONS.index("tir")] == np.count_nonzero(r > h_crit) > 0
    assert losses.sum() == losses[2, 2]
    assert "surface 2:" in res.describe_losses() and "tir" in res.describe_losses()


@pytest.mark.parametrize("variant", VARIANTS)
def test_rays_missing_a_surface_or_its_aperture_are_counted(tmp_path, variant):
    # surface 1: a sphere of radius 5 mm (rays above 5 mm miss it altogether);
    # surface 2 (flat) has a clear aperture of 2.5 mm
    p, text = _single_surface_lens(tmp_path, """
    [[surfaces]]
    radius_mm = 5.0
    thickness_mm = 3.0
    glass = "F_SILICA"
    semi_diameter_mm = 5.0
    [[surfaces]]
    radius_mm = inf
    thickness_mm = 10.0
    semi_diameter_mm = 2.5
    """, stop_sd=6.0)
    n_rays = 400 if variant == "llvm_ad_rgb" else 80
    r = _vogel_radii(n_rays, 6.0)
    tr = LensTracer(p, variant=variant)
    rays = field_bundle(p, field_deg=0.0, n_rays=n_rays)
    res = tr.trace(x_mm=rays[0], y_mm=rays[1], z_mm=rays[2], dx=rays[3], dy=rays[4], dz=rays[5],
                   wavelength_nm=500.0)
    losses = res.losses()
    assert losses[1, LOSS_REASONS.index("miss")] == np.count_nonzero(r > 5.0) > 0
    assert losses[1, LOSS_REASONS.index("aperture")] == 0
    assert losses[2, LOSS_REASONS.index("aperture")] > 0
    assert res.alive.sum() + losses.sum() == n_rays
    # the survivors are the reference's, and where they are agrees
    surfs, indices = _reference_setup(text)
    path, _, ok = ref.trace(surfs, indices(500.0), *rays)
    inside = ok & (r < 5.0)
    np.testing.assert_array_equal(res.alive, inside)
    assert np.abs(res.x_mm[res.alive] - path[-1][0][res.alive]).max() <= TOL_MM


def test_vogel_pupil_is_uniform_and_batched_wavelengths_equal_separate_traces(tracers):
    x, y = vogel_pupil(20000)
    r2 = x * x + y * y
    assert r2.max() < 1.0
    # equal-area rings hold equal numbers of points
    counts = np.histogram(r2, bins=10, range=(0, 1))[0]
    assert counts.min() >= 1999 and counts.max() <= 2001
    xs, ys = symmetric_pupil(20001, azimuth_deg=30.0)
    assert xs.size == 20001 and np.hypot(xs, ys).max() < 1.0
    # mirror symmetry about the 30 deg meridian, and uniform in area
    a = math.radians(30.0)
    along, across = xs * math.cos(a) + ys * math.sin(a), -xs * math.sin(a) + ys * math.cos(a)
    np.testing.assert_allclose(np.sort(across), -np.sort(across)[::-1], atol=1e-15)
    np.testing.assert_allclose(np.sort(along), -np.sort(along)[::-1], atol=1e-15)
    assert np.histogram(xs**2 + ys**2, bins=5, range=(0, 1))[0].std() < 3
    p, trs = tracers
    tr = trs["llvm_ad_rgb"]
    rays = field_bundle(p, field_deg=2.0, n_rays=200)
    both = tr.trace(*(), **dict(zip(("x_mm", "y_mm", "z_mm", "dx", "dy", "dz"), (np.tile(a, 2) for a in rays))),
                    wavelength_nm=np.repeat([450.0, 800.0], 200))
    for k, wl in enumerate((450.0, 800.0)):
        one = tr.trace(x_mm=rays[0], y_mm=rays[1], z_mm=rays[2], dx=rays[3], dy=rays[4], dz=rays[5], wavelength_nm=wl)
        sub = both.subset(slice(200 * k, 200 * (k + 1)))
        np.testing.assert_array_equal(sub.x_mm, one.x_mm)
        np.testing.assert_array_equal(sub.dz, one.dz)


def test_trace_input_errors(tracers):
    p, trs = tracers
    tr = trs["llvm_ad_rgb"]
    with pytest.raises(LensError, match="same length"):
        tr.trace(x_mm=[0.0], y_mm=[0.0, 1.0], z_mm=[-5.0], dx=[0.0], dy=[0.0], dz=[1.0], wavelength_nm=500.0)
    with pytest.raises(LensError, match="finite"):
        tr.trace(x_mm=[np.nan], y_mm=[0.0], z_mm=[-5.0], dx=[0.0], dy=[0.0], dz=[1.0], wavelength_nm=500.0)
    with pytest.raises(LensError, match=r"2 values for 1 rays"):
        tr.trace(x_mm=[0.0], y_mm=[0.0], z_mm=[-5.0], dx=[0.0], dy=[0.0], dz=[1.0], wavelength_nm=[500.0, 600.0])
    with pytest.raises(LensError, match="outside the range of its Sellmeier fit"):
        tr.trace(x_mm=[0.0], y_mm=[0.0], z_mm=[-5.0], dx=[0.0], dy=[0.0], dz=[1.0], wavelength_nm=200.0)
    with pytest.raises(LensError, match="variant: expected one of"):
        LensTracer(p, variant="cuda_ad_rgb")


def _run(code: str, env_update: dict, drop=("DRJIT_LIBLLVM_PATH",)):
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env.update(env_update)
    return subprocess.run([sys.executable, "-W", "error", "-c", code], env=env, capture_output=True, text=True,
                          timeout=120, check=False)


def test_a_fresh_process_finds_the_pypi_libllvm_and_uses_the_llvm_variant():
    out = _run(textwrap.dedent("""
        import os
        from simcam.starcam.lens.backend import get_backend, MIN_LLVM_MAJOR
        b = get_backend()
        assert b.variant == "llvm_ad_rgb" and b.llvm_version[0] >= MIN_LLVM_MAJOR, b
        assert os.environ["DRJIT_LIBLLVM_PATH"].endswith(".so"), os.environ["DRJIT_LIBLLVM_PATH"]
        print("ok", b.note)
    """), {})
    assert out.returncode == 0, out.stderr
    assert "ok" in out.stdout and "karellen-llvm-core" in out.stdout


def test_without_a_usable_libllvm_tracing_falls_back_to_scalar_with_a_warning(tmp_path):
    out = _run(textwrap.dedent("""
        import warnings
        from simcam.starcam.lens.errors import LensBackendWarning, LensError
        from simcam.starcam.lens.backend import get_backend
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            b = get_backend()
        assert b.variant == "scalar_rgb", b
        assert any(issubclass(x.category, LensBackendWarning) for x in w), [str(x.message) for x in w]
        try:
            get_backend("llvm_ad_rgb")
        except LensError as exc:
            print("refused:", exc)
        from simcam.starcam.lens.tracer import LensTracer, field_bundle
        t = LensTracer("embedded:star_camera", variant="scalar_rgb")
        x, y, z, dx, dy, dz = field_bundle(t.prescription, field_deg=1.0, n_rays=5)
        r = t.trace(x_mm=x, y_mm=y, z_mm=z, dx=dx, dy=dy, dz=dz, wavelength_nm=600.0)
        assert r.alive.all()
        print("ok")
    """), {"DRJIT_LIBLLVM_PATH": str(tmp_path / "no-such-libLLVM.so")})
    assert out.returncode == 0, out.stderr
    assert "ok" in out.stdout and "refused: variant llvm_ad_rgb unavailable" in out.stdout


def test_newton_refinement_converges_from_a_poor_start():
    # the refinement alone, started 0.5 mm off along the ray, lands on the exact sag
    from simcam.starcam.lens.surface import NUMPY, SurfaceShape
    from simcam.starcam.lens.tracer import _refine_and_refract

    shape = SurfaceShape(curvature_per_mm=1 / 40.0, conic=-1.2, aspheric_coeffs=(3e-6,))
    x = np.linspace(-8, 8, 33)
    y = np.zeros_like(x)
    z = np.full_like(x, -5.0)
    px, py, pz, *_ = _refine_and_refract(NUMPY, x=x, y=y, z=z, dx=0 * x, dy=0 * x, dz=1 + 0 * x, t=5.5 + 0 * x,
                                         shape=shape, z_v=0.0, semi_diameter_mm=10.0, mu=1 / 1.5, n_steps=8)
    np.testing.assert_allclose(pz, shape.sag(px * px + py * py), rtol=0, atol=1e-13)
    assert math.isclose(float(pz[16]), 0.0, abs_tol=1e-15)


def test_a_libllvm_whose_libcxx_links_are_missing_still_loads(tmp_path):
    # the karellen-llvm-core wheel ships libc++ as .so.1.0 files; its .pth hook makes the
    # .so.1 links on the first interpreter start. Without them a plain drjit import fails;
    # simcam preloads the .so.1.0 files (same sonames) and the llvm variant works.
    from simcam.starcam.lens.backend import _karellen_libllvm

    src = _karellen_libllvm()
    if src is None:
        pytest.skip("karellen-llvm-core is not installed")
    real = src.resolve()
    cxx = real.parent / "x86_64-unknown-linux-gnu"
    if not (cxx / "libc++.so.1.0").exists():
        pytest.skip("this karellen-llvm-core wheel has another layout")
    lib = tmp_path / "lib"
    (lib / "x86_64-unknown-linux-gnu").mkdir(parents=True)
    import shutil

    shutil.copy(real, lib / real.name)
    for f in ("libc++.so.1.0", "libc++abi.so.1.0", "libunwind.so.1.0"):
        shutil.copy(cxx / f, lib / "x86_64-unknown-linux-gnu" / f)
    env = {"DRJIT_LIBLLVM_PATH": str(lib / real.name)}
    plain = _run("import drjit as dr; print(bool(dr.has_backend(dr.JitBackend.LLVM)))", env)
    assert plain.stdout.strip() == "False"  # the situation simcam repairs
    ours = _run(textwrap.dedent("""
        from simcam.starcam.lens.backend import get_backend
        b = get_backend()
        assert b.variant == "llvm_ad_rgb", b
        print("ok")
    """), env)
    assert ours.returncode == 0 and "ok" in ours.stdout, ours.stderr
