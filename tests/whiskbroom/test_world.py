"""The whiskbroom world's effects: each injection against an independent reference,
the ideal world equal to the pre-issue-22 results (to the rounding of its floating-point
operations: tests/golden.py), the lab never reading ``world``."""

import ast
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from golden import assert_close_to_recorded
from scipy.integrate import quad
from scipy.special import j0

from simcam.whiskbroom import scenario as wsc
from simcam.whiskbroom import tdi
from simcam.whiskbroom import world as wd
from simcam.units import WGS84_F

ROOT = Path(__file__).resolve().parents[2]


def _path(n_stages, n_phase, n_time, along, cross=None):
    t = wd.sample_times(n_stages, n_phase, n_time)
    da = along(t)
    dc = np.zeros_like(t) if cross is None else cross(t)
    return wd.tdi_mtf_path(da, dc, n_stages=n_stages, n_phase=n_phase, n_time=n_time)


def test_path_equals_the_uniform_kernel():
    # the same detector and samples as tdi.pixel_mtf: equal to rounding (a few ulp x 10^4 terms)
    eps, eta = 0.004, -0.002
    a, c = _path(96, 4, 16, lambda t: (1 + eps) * t, lambda t: eta * t)
    ka, kc = tdi.pixel_mtf(eps, eta, n_stages=96, n_phase=4, n_time=16, columns=3)
    assert np.max(np.abs(a - ka)) < 1e-11 and np.max(np.abs(c - kc)) < 1e-11


def test_edge_path_equals_the_uniform_edge_kernel():
    eps, eta = 0.004, -0.002
    kw = dict(n_stages=16, n_phase=4, n_time=2, angle_deg=5.0, lines=12, columns=40)
    t = wd.sample_times(12 + 16, 4, 2)
    got = wd.edge_image_path((1 + eps) * t, eta * t, **kw)
    np.testing.assert_allclose(got, tdi.edge_image(eps, eta, **kw), atol=1e-12)


def test_fast_sinusoidal_jitter_gives_j0():
    # jitter of amplitude a px with period << integration: MTF factor J0(pi a) at Nyquist
    # (time average of exp(-i pi a sin)); 3.37 cycles per line over 384 lines leaves
    # unaveraged terms of order J1(pi a) / 1300 ~ 1e-4
    a = 0.1
    ref, _ = _path(384, 4, 64, lambda t: t)
    jit, _ = _path(384, 4, 64, lambda t: t + a * np.sin(2 * np.pi * 3.37 * t + 0.4))
    assert j0(np.pi * a) == pytest.approx(0.976, abs=1e-3)   # the note rounds 0.97548
    assert jit[-1] / ref[-1] == pytest.approx(j0(np.pi * a), abs=3e-4)


def _ripple_mean(a, n):
    return quad(lambda p: np.sinc(0.5 * n * a * np.sin(p)), 0, 2 * np.pi)[0] / (2 * np.pi)


@pytest.mark.parametrize("a, expected", [(0.0022, 0.991), (0.005, 0.954)])
def test_ripple_phase_averaged_mtf(a, expected):
    # quadrature of sinc(pi N a sin(phi)/2) over the phase (effects note values, 3 digits), the
    # small-a form 1 - (pi N a)^2/48 to its O((pi N a)^4) term, and the pixel-level path with
    # a ripple of period 19000 lines (1.7 s at 90 us) over 32 phases, divided by the
    # static clocking factor: within the clocking's (1 + eps) coupling (~1e-4) + phase sampling
    n = 96
    q = _ripple_mean(a, n)
    assert q == pytest.approx(expected, abs=5e-4)
    assert q == pytest.approx(1 - (np.pi * n * a) ** 2 / 48, abs=(np.pi * n * a) ** 4 / 1000)
    ref, _ = _path(n, 4, 64, lambda t: t)
    period = 19000.0
    vals = []
    for phi in np.arange(32) * 2 * np.pi / 32:
        # displacement: integral of a sin(2 pi t / P + phi) (relative rate ripple, px per line)
        path = lambda t, phi=phi: t - a * period / (2 * np.pi) * (np.cos(2 * np.pi * t / period + phi) - np.cos(phi))
        vals.append(_path(n, 4, 64, path)[0][-1] / ref[-1])
    assert np.mean(vals) == pytest.approx(q, abs=1e-3)


def test_crosstalk_is_common_to_every_stage_count():
    # diffusion is static: MTF(N)/MTF(static) unchanged, the absolute modulation scaled by 1 - 4X
    x = 0.02
    t = wd.sample_times(96, 4, 16)
    da, dc = 1.003 * t, 0.001 * t
    m0 = wd.tdi_modulation(da, dc, n_stages=96, n_phase=4, n_time=16, crosstalk=0.0)
    mx = wd.tdi_modulation(da, dc, n_stages=96, n_phase=4, n_time=16, crosstalk=x)
    s0 = wd.tdi_modulation(np.zeros_like(t), np.zeros_like(t), n_stages=96, n_phase=4, n_time=16, crosstalk=0.0)
    sx = wd.tdi_modulation(np.zeros_like(t), np.zeros_like(t), n_stages=96, n_phase=4, n_time=16, crosstalk=x)
    for i in range(2):
        np.testing.assert_allclose(mx[i] / sx[i], m0[i] / s0[i], rtol=1e-13)
        np.testing.assert_allclose(mx[i] / m0[i], 1 - 4 * x, rtol=1e-13)


def test_crosstalk_lowers_the_slanted_edge_by_its_mtf():
    # the lab's e-SFR divides out a box pixel only: with the kernel it reads low by the
    # kernel's MTF along the edge normal (separable: product at f cos a and f sin a). The
    # 1/4-px ESF binning multiplies both alike, but the Hamming window convolves the spectrum,
    # so the ratio is not exact: 3.5e-3 here, tolerance 5e-3
    from budget.whiskbroom.estimators import slanted_edge_mtf

    x, ang = 0.02, 5.0
    img = tdi.edge_image(0.0, 0.0, n_stages=8, n_phase=4, n_time=2, angle_deg=ang, lines=32, columns=128)
    base = slanted_edge_mtf(img)["mtf"]
    got = slanted_edge_mtf(wd.diffuse(img, x))["mtf"]
    a = math.radians(ang)
    expect = wd.crosstalk_mtf(0.5 * math.cos(a), x) * wd.crosstalk_mtf(0.5 * math.sin(a), x)
    assert got / base == pytest.approx(expect, abs=5e-3)
    assert np.sum(wd.diffuse(img, x)[1:-1, 1:-1]) == pytest.approx(np.sum(img[1:-1, 1:-1]), rel=2e-3)


def test_seib_mtf_limits():
    # Seib (1974): 1 at f = 0; at Nyquist of 8.75 um, 600 nm (a = 0.42 /um), L_D = 2-5 um,
    # L0 = 20-100 um the effects note gives 0.81-0.95
    assert wd.seib_mtf(0.0, absorption_per_um=0.42, depletion_um=3, diffusion_length_um=50) == pytest.approx(1.0)
    ny = 1 / (2 * 8.75e-3)
    lo = wd.seib_mtf(ny, absorption_per_um=0.42, depletion_um=2, diffusion_length_um=100)
    hi = wd.seib_mtf(ny, absorption_per_um=0.42, depletion_um=5, diffusion_length_um=20)
    assert 0.75 < lo < hi < 1.0


def test_jitter_variance_is_the_integral_of_its_lines():
    # tones: one-sided PSD lines (w A)^2/2; over a long record the sample variance -> sum
    w = wsc.WhiskbroomWorld()
    t = np.arange(0, 2000.0, 0.05)
    ang = wd.jitter_angle(np.random.default_rng(3), t, 2.4, w.jitter_tones_hz, w.jitter_tone_weights)
    var = sum((2.4 * math.pi / 648000 * x) ** 2 / 2 for x in w.jitter_tone_weights)
    assert np.var(ang) == pytest.approx(var, rel=0.01)     # finite record: cross terms ~1/(f T) ~ 1e-3


def test_mirror_rate_sensitivity_is_the_pure_scan_coefficient():
    # V is affine in the mirror rate: dV/d omega = the pure-scan closed form (docs/whiskbroom.md):
    # V1 = -2 omega x1 x3 / f, V3 = -2 omega (f^2 + x3^2)/f (nominal state, mirror at 45 deg)
    from simcam.whiskbroom import geometry as geo
    from simcam.whiskbroom import synthesis as sy

    sc = wsc.default()
    row = sy.nominal_params(sc, 0.0)[0]
    f = sc.camera.focal_length_mm
    x1, x3 = np.array([0.0, 10.0, -20.0]), np.array([0.0, 5.0, 12.0])
    g = wd.rate_sensitivity(row, geo.PARAMS, x1, x3, WGS84_F, "mirror_rate_rad_s")
    np.testing.assert_allclose(g[:, 0], -2 * x1 * x3 / f, atol=1e-3)
    np.testing.assert_allclose(g[:, 1], -2 * (f**2 + x3**2) / f, rtol=1e-7)


def test_world_motion_on_the_sphere_is_the_papers_chain():
    # flattening 0: the ray trace reproduces geometry's V_true to its error bound (docs: 3.2e-8 mm/s)
    from simcam.whiskbroom import geometry as geo
    from simcam.whiskbroom import synthesis as sy

    sc = wsc.default()
    know, true = sy.trial_params(sc, sy.standard_draws(sc, sy.trial_uniforms(0, [7])), [7])
    x1, x3 = sy.field_points(sc)
    v = wd.world_motion(true[0], geo.PARAMS, x1[:5], x3[:5], 0.0)
    np.testing.assert_allclose(v, geo.image_motion(true, x1[:5], x3[:5])[0], atol=1e-7)


# ------------------------------------------------------------------ contract
#: validate --trials 4 --seed 0 of the embedded default recorded with the code BEFORE the world effects
#: (commit 5328684, /tmp run of `budget whiskbroom validate --trials 4 --workers 1 --json`):
#: (truth, mean, std) per class/axis/variant
PRE_ISSUE22 = {
    "mtf_nyquist/along/published": (0.9597203466654333, 0.984860097289523, 0.00024854689938520015),
    "mtf_nyquist/along/improved": (0.9597203466654333, 0.9597142164462775, 2.9073411022835023e-08),
    "mtf_nyquist/along/edge": (0.9597203466654333, 0.9410871303853647, 0.002378427779938422),
    "mtf_nyquist/cross/published": (0.9946350329286006, 1.0, 0.008038757203555876),
    "mtf_nyquist/cross/improved": (0.9946350329286006, 0.9946350329198077, 1.3141414559691486e-11),
    "stage_limit/along/published": (184.0, 231.25, 22.911059920192837),
    "stage_limit/along/improved": (184.0, 184.0, 0.0),
}


def test_ideal_world_equals_the_pre_issue22_results(tmp_path):
    # the truth (and the world's edge image) now take the residual from the ray trace
    # (budget.whiskbroom.truth), which agrees with the paper's chain recorded here to 6e-11 of V
    # (simcam.whiskbroom.raytrace's step study): eps moves by about 6e-11 and an MTF at most by
    # max|d sinc(pi N eps / 2) / d eps| = (pi N / 2) 0.44 = 66 (N = 96) times that, 4e-9; so a
    # relative 1e-9 or 1e-8 absolute; the stage limits are counts
    out = tmp_path / "ideal.json"
    subprocess.run([sys.executable, "-m", "budget.cli", "whiskbroom", "validate",
                    str(ROOT / "simcam/whiskbroom/data/ideal.toml"), "--trials", "4", "--workers", "1",
                    "--json", str(out)], check=True, capture_output=True, cwd=ROOT)
    d = json.loads(out.read_text())
    got = {f"{c}/{a}/{v}": (st["truth"], st["mean"], st["std"])
           for c, ax in d["classes"].items() for a, vs in ax.items() for v, st in vs.items()}
    assert_close_to_recorded(got, PRE_ISSUE22, abs_floor=1e-8)


def test_ideal_file_is_the_default_with_every_effect_off():
    ideal = wsc.load(ROOT / "simcam/whiskbroom/data/ideal.toml")
    default = wsc.default()
    assert ideal.world.effects.active() == ()
    assert set(default.world.effects.active()) == set(default.world.effects.names())   # realistic default
    a = default.model_dump(exclude={"name"})
    a["world"]["effects"] = default.world.effects.ideal().model_dump()
    assert a == ideal.model_dump(exclude={"name"})


def test_truth_depends_on_effects():
    from budget.whiskbroom.study import STUDY

    assert STUDY.truth_depends_on_effects(wsc.default()) == {
        "earth_flattening_scale", "attitude_jitter_arcsec", "wheel_jitter_arcsec", "mirror_rate_ripple_fraction"}


def test_the_lab_never_reads_world():
    for mod in ("budget/whiskbroom/estimators.py",):
        tree = ast.parse((ROOT / mod).read_text())
        names = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)}
        names |= {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        assert "world" not in names and "effects" not in names, mod
        imports = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) for a in n.names}
        imports |= {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        assert not any("world" in i or "raytrace" in i for i in imports), mod


def test_effects_scenario_errors():
    from simcam.infra.errors import ScenarioError

    data = wsc.default().model_dump(mode="json")
    data["world"]["effects"]["attitude_jitter_arcsec"] = -1.0
    with pytest.raises(ScenarioError, match="world.effects.attitude_jitter_arcsec"):
        wsc.from_dict(data)
    data = wsc.default().model_dump(mode="json")
    data["world"]["jitter_tone_weights"] = [1.0]
    with pytest.raises(ScenarioError, match="world"):
        wsc.from_dict(data)


# ------------------------------------------------------------------ seed 002's claims as distributions
def test_seed_distribution_quantiles():
    from budget.whiskbroom import claims
    from simcam.whiskbroom import synthesis as sy

    sc = wsc.default()
    d = claims.seed_distribution(sc, range(3), trials=30, backend="numpy")
    assert d["chosen"]["camera.focal_length_mm"] == sc.camera.focal_length_mm
    level = d["levels"][0]["dv_max_abs_mm_s"]
    direct = [sy.synthesize(sc, s, trials=30, backend="numpy").table[0]["dv_max_abs_mm_s"] for s in range(3)]
    np.testing.assert_allclose(level["values"], direct, rtol=1e-12)
    assert level["median"] == pytest.approx(np.median(direct))
    assert level["p05"] <= level["median"] <= level["p95"]


def test_published_sinc_by_its_own_criterion():
    # the paper's criterion (loss from the motion residual, MTF(eps)/MTF(0)): right to < 5e-4;
    # the static clocking factor MTF(0) is the continuous sawtooth's sinc(pi/8) to the
    # midpoint rule over the pi/4 of phase a clock phase spans, 16 samples: relative error
    # ~ (pi/64)^2 / 24 = 1.0e-4
    from budget.whiskbroom import claims

    c = claims.published_criterion(wsc.default(), 0, 12, n_time=16)
    assert c["max_abs_error"] < 5e-4
    assert c["clocking_factor"] == pytest.approx(float(np.sinc(0.125)), abs=1.5e-4)
    assert c["clocking_sinc"] == pytest.approx(0.9745, abs=1e-4)


def test_world_synthesis_truth_side():
    # near the equator (trials 0-4: gamma 0-1.4 deg) WGS 84 and the sphere agree to first
    # order (docs: 8e-9 of V at gamma 0), so the world's residuals equal the paper's closely;
    # on the paper's sphere (scale 0) there is no world route
    from budget.whiskbroom import claims

    sc = wsc.default()
    w = claims.world_synthesis(sc, 0, trials=5)
    assert w["world"]["eps_quantile"] == pytest.approx(w["paper"]["eps_quantile"], abs=2e-5)
    assert w["world"]["dv_max_mm_s"] == pytest.approx(w["paper"]["dv_max_mm_s"], abs=5e-3)
    data = sc.model_dump(mode="json")
    data["world"]["effects"]["earth_flattening_scale"] = 0.0
    assert claims.world_synthesis(wsc.from_dict(data), 0, trials=5) is None
