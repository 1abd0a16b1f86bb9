"""The star camera's world effects: each injection against an independent reference.

Monte Carlo assertions use fixed seeds; their tolerances follow from the sampling
distribution (stated at each)."""

from __future__ import annotations

import ast
import math
import os
import pathlib

import numpy as np
import pytest
from golden import assert_close_to_recorded

from simcam.infra.errors import ScenarioError
from simcam.starcam import optics
from simcam.detector import DetectorParams, expose, expose_windows, window_chain
from simcam.starcam.scenario import default, load, with_updates
from simcam.starcam.world import (
    WorldMotion, drift_px, frame_times_s, hexapod_pose_errors, timeline,
)
from simcam.units import ARCSEC_PER_RAD

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _ideal():
    return load("embedded:seed000_ideal")


# --------------------------------------------------------------------------- scenario
def test_default_is_the_realistic_world_and_ideal_is_one_option_away():
    eff = default().world.effects
    assert set(eff.active()) == set(eff.names())
    assert eff.nonlinearity_beta == 0.008 and eff.distortion_r5_px_at_corner == 1.47
    ideal = _ideal()
    assert ideal.world.effects.active() == ()
    # the ideal scenario differs from the default only in [world.effects] (and its name)
    a = default().model_dump(mode="json")
    b = ideal.model_dump(mode="json")
    a.pop("name"), b.pop("name")
    a["world"].pop("effects"), b["world"].pop("effects")
    assert a == b
    # every effect's field carries its physical source
    for name, src in type(eff).sources().items():
        assert len(src) > 40, name


def test_hexapod_error_given_once_and_beta_range():
    with pytest.raises(ScenarioError, match="positioning_noise_px and world.effects.hexapod_repeatability_arcsec"):
        with_updates(default(), {"lab.platform.positioning_noise_px": 0.1})
    with_updates(_ideal(), {"lab.platform.positioning_noise_px": 0.1})  # the lab knob alone: fine
    with pytest.raises(ScenarioError, match="nonlinearity_beta"):
        with_updates(default(), {"world.effects.nonlinearity_beta": 1.5})


def test_lab_modules_never_read_world():
    """The lab side (estimators, plans, measurement, combination) never reads ``.world``."""
    files = list((ROOT / "budget/starcam/estimators").glob("*.py")) + [
        ROOT / "budget/starcam" / n for n in ("protocols.py", "measure.py", "combine.py")]
    for f in files:
        tree = ast.parse(f.read_text())
        bad = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.Attribute) and n.attr == "world"]
        assert not bad, f"{f.name} reads .world at lines {bad}"


# --------------------------------------------------------------------------- non-linearity
def _params(beta, fw=4000.0):
    return DetectorParams(gain_e_per_dn=(1.0, 1.0), offset_dn=(100.0, 100.0), read_noise_e=(0.0, 0.0),
                          full_well_e=(fw, fw), adc_bits=16, nonlinearity_beta=beta)


def _symmetric_window(centre: str):
    # a Gaussian PSF sampled symmetrically about the window's centre pixel (or its corner)
    n = 11 if centre == "pixel" else 12
    c = (n - 1) / 2.0
    y, x = np.mgrid[0:n, 0:n]
    return 3000.0 * np.exp(-((x - c) ** 2 + (y - c) ** 2) / (2 * 1.1**2)), c


@pytest.mark.parametrize("centre", ["pixel", "corner"])
@pytest.mark.parametrize("beta", [0.0, 0.008, 0.05, -0.02])
def test_nonlinearity_keeps_a_symmetric_centroid_and_compresses_flux(centre, beta):
    s, c = _symmetric_window(centre)
    p = _params(beta)
    out = expose_windows(signal_e=s[None], row0=np.array([40]), col0=np.array([60]), mosaic_cols=4096,
                         chip_cols=2048, params=p, frame_key=1, detector_key=2, shot_noise=False,
                         read_noise=False, quantize=False)[0]
    e = out - 100.0                                       # DN -> e- at gain 1
    y, x = np.mgrid[0:e.shape[0], 0:e.shape[1]]
    assert abs((e * x).sum() / e.sum() - c) < 1e-12 and abs((e * y).sum() / e.sum() - c) < 1e-12
    # relative flux bias -beta sum(s^2) / (FW sum(s)), computed here from the input signal
    want = -beta * (s**2).sum() / (4000.0 * s.sum())
    assert e.sum() / s.sum() - 1.0 == pytest.approx(want, abs=1e-13)
    # the full-frame route gives the same pixels as the window route
    blk = expose(signal_e=s, row0=40, col0=60, mosaic_cols=4096, chip_cols=2048, params=p, frame_key=1,
                 detector_key=2, shot_noise=True, read_noise=False, quantize=True)
    win = expose_windows(signal_e=s[None], row0=np.array([40]), col0=np.array([60]), mosaic_cols=4096,
                         chip_cols=2048, params=p, frame_key=1, detector_key=2, shot_noise=True,
                         read_noise=False, quantize=True)[0]
    np.testing.assert_array_equal(blk, win)


def test_nonlinearity_inl_is_beta_over_four():
    # against the end-point line through (0, 0) and (FW, FW (1 - beta)), the largest deviation
    # of s (1 - beta s / FW) is beta FW / 4 at s = FW / 2 (INL = beta / 4 of full scale)
    beta, fw = 0.008, 4000.0
    s = np.linspace(0.0, fw, 40001)
    p = _params(beta, fw)
    ch = window_chain(signal_e=s[None, None, :2048], row0=[0], col0=[0], mosaic_cols=4096, chip_cols=2048, params=p,
                      detector_key=3)
    resp = ch.mean_e[0, 0]
    line = s[:2048] * (1 - beta)
    assert abs(resp - s[:2048] * (1 - beta * s[:2048] / fw)).max() < 1e-9
    full = s * (1 - beta * s / fw) - s * (1 - beta)
    assert full.max() / fw == pytest.approx(beta / 4, rel=1e-9)
    assert line.shape == resp.shape


# --------------------------------------------------------------------------- distortion
def test_higher_order_radial_distortion_jacobian_and_inverse():
    base = optics.CompositeDistortion(
        brown_conrady=optics.BrownConradyDistortion(k1=2e-4, k2=5e-5, r_norm_px=2048.0),
        cubic=optics.CubicDistortion(r_norm_px=2048.0))
    d = optics.HigherOrderRadialDistortion(base=base, a5_px=1.47, a7_px=0.081, r_corner_px=2298.68)
    u = np.array([0.0, 500.0, -1500.0, 2000.0, 2050.0])
    v = np.array([0.0, 300.0, 800.0, -1000.0, 1020.0])
    du, dv = d.displacement(u_px=u, v_px=v)
    bu, bv = base.displacement(u_px=u, v_px=v)
    r = np.hypot(u, v)
    extra = 1.47 * (r / 2298.68) ** 5 + 0.081 * (r / 2298.68) ** 7   # radial, px
    np.testing.assert_allclose(np.hypot(du - bu, dv - bv), extra, atol=1e-12)
    h = 1e-3
    jac = d.jacobian(u_px=u, v_px=v)
    fu1, fv1 = d.forward(u_px=u + h, v_px=v)
    fu0, fv0 = d.forward(u_px=u - h, v_px=v)
    np.testing.assert_allclose(jac[:, 0, 0], (fu1 - fu0) / (2 * h), atol=1e-9)
    np.testing.assert_allclose(jac[:, 1, 0], (fv1 - fv0) / (2 * h), atol=1e-9)
    fu, fv = d.forward(u_px=u, v_px=v)
    iu, iv = d.inverse(u_px=fu, v_px=fv)
    np.testing.assert_allclose(iu, u, atol=1e-9)
    np.testing.assert_allclose(iv, v, atol=1e-9)


def test_injected_higher_orders_match_the_traced_lens_beyond_its_cubic(tmp_path):
    """The injected r^5 + r^7 field, against the traced embedded lens (its products): the part
    of each that a radial cubic (r, r^3: what the lab's 2-D cubic holds radially) leaves."""
    from scipy.interpolate import CubicSpline
    from test_lens_products import SMALL_ANALYSIS, small_star_camera

    from simcam.starcam.lens.prescription import load_prescription
    from simcam.starcam.lens.products import lens_products
    from simcam.starcam.render import mosaic_corner_radius_px

    old = os.environ.get("SIMCAM_CACHE_DIR")
    os.environ["SIMCAM_CACHE_DIR"] = str(tmp_path / "cache")
    try:
        path = small_star_camera(tmp_path, SMALL_ANALYSIS.replace("field_points = 4", "field_points = 10"))
        prod = lens_products(load_prescription(path))
    finally:
        if old is None:
            os.environ.pop("SIMCAM_CACHE_DIR", None)
        else:
            os.environ["SIMCAM_CACHE_DIR"] = old
    scn = default()
    p_mm = scn.camera.pixel_pitch_um * 1e-3
    f_mm = scn.camera.focal_length_effective_mm
    u = CubicSpline(prod.wavelength_nm, -prod.centroid_x_mm / p_mm, axis=1)(600.0)   # traced image height, px
    u0 = f_mm * np.tan(np.radians(prod.field_deg)) / p_mm                              # gnomonic ideal, px
    rc = mosaic_corner_radius_px(scn)
    rho = u0 / rc
    a = np.stack([rho, rho**3], axis=1)

    def beyond_cubic(y):
        c, *_ = np.linalg.lstsq(a, y, rcond=None)
        return y - a @ c

    eff = scn.world.effects
    lens_res = beyond_cubic(u - u0)
    inj_res = beyond_cubic(eff.distortion_r5_px_at_corner * rho**5 + eff.distortion_r7_px_at_corner * rho**7)
    # the residual is ~0.13 px at most; what the injected r^5 + r^7 misses of it is the lens's
    # ninth and higher orders (2e-5 px) plus the small trace's centroid sampling (3000 rays
    # per bundle) and the rounding of the defaults to 3 digits: 0.005 px
    assert np.abs(lens_res).max() > 0.05
    assert np.abs(lens_res - inj_res).max() < 0.005


def test_world_distortion_enters_the_render_and_the_c1_truth():
    from budget.starcam.truth import lsfe_c1_truth
    from simcam.starcam.render import StarCamera

    ideal = _ideal()
    only = with_updates(ideal, {"world.effects.distortion_r5_px_at_corner": 1.47,
                                "world.effects.distortion_r7_px_at_corner": 0.081})
    c0, c1 = StarCamera(ideal), StarCamera(only)
    assert isinstance(c1.distortion, optics.HigherOrderRadialDistortion)
    t0, t1 = lsfe_c1_truth(c0), lsfe_c1_truth(c1)
    # the cubic correction cannot hold r^5: the truth grows (quadrature of 0.21" and the
    # 2-D cubic's residual of the r^5 term, ~0.03 px rms = 0.17", 3 sigma 0.5")
    assert t1.x_px > t0.x_px + 0.005 and t1.y_px > t0.y_px + 0.002


# --------------------------------------------------------------------------- hexapod
def test_roll_moves_each_star_by_r_delta():
    from simcam.starcam.render import Placement, StarCamera
    from simcam.starcam.targets import star_grid

    scn = with_updates(_ideal(), {"optics.distortion.k1": 0.0, "optics.distortion.k2": 0.0,
                                  "optics.lateral_colour.radial_px_per_nm": [0.0]})
    cam = StarCamera(scn)
    lay = star_grid(scn)
    delta = 5e-6
    a = cam.scene(Placement(layout=lay, condition=1)).truth
    b = cam.scene(Placement(layout=lay, condition=1, platform_roll_rad=delta)).truth
    np.testing.assert_allclose(b.x_true - a.x_true, -delta * lay.v_px, atol=1e-9)
    np.testing.assert_allclose(b.y_true - a.y_true, delta * lay.u_px, atol=1e-9)


def test_hexapod_errors_repeatability_and_backlash():
    scn = with_updates(_ideal(), {"world.effects.hexapod_repeatability_arcsec": 0.5,
                                  "world.effects.hexapod_backlash_arcsec": 1.0})
    scale = scn.camera.scale_arcsec_per_px
    n = 600
    poses = [hexapod_pose_errors(scn, s) for s in range(n)]
    # HSFE poses 1..11 are reached by moves along +45 deg: backlash +b on both axes
    dx = np.array([p[("hsfe", 3)][0] for p in poses]) * scale
    roll = np.array([p[("hsfe", 3)][2] for p in poses]) * ARCSEC_PER_RAD
    # mean of n draws of N(b, 0.5^2): 4 standard errors 4 x 0.5 / sqrt(n)
    assert abs(dx.mean() - 1.0) < 4 * 0.5 / math.sqrt(n)
    # the roll is repeatability only: sd 0.5" (sd of a sample sd ~ sigma / sqrt(2n)), mean 0
    assert abs(roll.std(ddof=1) - 0.5) < 4 * 0.5 / math.sqrt(2 * n)
    assert abs(roll.mean()) < 4 * 0.5 / math.sqrt(n)
    # the three filters of a chromatic field share the pose (no move between them)
    assert poses[0][("chromatic", 0)] == poses[0][("chromatic", 1)] == poses[0][("chromatic", 2)]
    assert poses[0][("hsfe", 3)] != poses[0][("hsfe", 4)]
    # off: no error at all
    assert set(hexapod_pose_errors(_ideal(), 3).values()) == {(0.0, 0.0, 0.0)}


def test_a_common_mode_step_leaves_hsfe_unchanged():
    from budget.starcam.protocols import estimate, make_plan, simulate
    from simcam.starcam.render import StarCamera

    scn = _ideal()
    data = simulate(make_plan("hsfe", scn), StarCamera(scn), seed=5)
    cen = data.centroids
    moved = cen.copy()
    rng = np.random.default_rng(0)
    step = {c: rng.normal(0.0, 0.1, 2) for c in cen.condition.unique()}   # a pose error per condition
    moved["x"] = cen.x + cen.condition.map(lambda c: step[c][0])
    moved["y"] = cen.y + cen.condition.map(lambda c: step[c][1])
    a = estimate("hsfe", cen, plate_scale_arcsec=5.5, extra_variants=False)
    b = estimate("hsfe", moved, plate_scale_arcsec=5.5, extra_variants=False)
    for var in ("published", "improved"):
        assert b[var].sigma_x_px == pytest.approx(a[var].sigma_x_px, rel=1e-9, abs=1e-12)
        assert b[var].sigma_y_px == pytest.approx(a[var].sigma_y_px, rel=1e-9, abs=1e-12)


# --------------------------------------------------------------------------- drift
def test_timeline_and_ramp():
    scn = with_updates(_ideal(), {"world.effects.drift_rate_arcsec_per_h": 0.1})
    w = scn.world
    period = scn.camera.exposure_s + w.frame_overhead_s
    tl = timeline(scn)
    assert tl[("te", 0)] == (0.0, period, scn.protocols.te.frames)
    assert tl[("hsfe", 0)][0] == pytest.approx(scn.protocols.te.frames * period + w.setup_s)
    assert tl[("hsfe", 1)][0] == pytest.approx(tl[("hsfe", 0)][0] + scn.protocols.hsfe.frames * period + w.settle_s)
    t = frame_times_s(scn, "te", 0)
    assert t[0] == pytest.approx(scn.camera.exposure_s / 2)
    d = drift_px(scn, 4)[("te", 0)]
    step = np.hypot(*np.diff(d, axis=0).T)
    np.testing.assert_allclose(step, 0.1 / 3600 * period / scn.camera.scale_arcsec_per_px, rtol=1e-9)
    assert drift_px(_ideal(), 4) is None


def test_gauss_markov_drift_is_stationary():
    scn = with_updates(_ideal(), {"world.effects.drift_random_arcsec": 0.03})
    sc = scn.camera.scale_arcsec_per_px
    x = np.array([drift_px(scn, s)[("distortion", 0)][0, 0] for s in range(800)]) * sc
    # the run's last condition, hours after the start: still N(0, 0.03^2) (sample-sd tolerance)
    assert abs(x.std(ddof=1) - 0.03) < 4 * 0.03 / math.sqrt(2 * 800)


def test_gauss_markov_drift_is_the_written_out_recursion_whatever_timelines_came_before():
    # the coefficients a_k, b_k are kept per timeline: two time constants interleaved, each
    # bit for bit the recursion x_k = a_k x_{k-1} + b_k z_k on the trial's own draws
    # (SeedSequence(seed, spawn_key=(STREAM_DRIFT,)): the direction, then the normals)
    from simcam.starcam.world import STREAM_DRIFT, _conditions

    for tau in (600.0, 77.0, 600.0):
        scn = with_updates(_ideal(), {"world.effects.drift_random_arcsec": 0.03, "world.drift_time_constant_s": tau})
        got = drift_px(scn, 5)
        tl = timeline(scn)
        t = np.concatenate([frame_times_s(scn, pr, i) for pr, i, _, _ in _conditions(scn)])
        rng = np.random.default_rng(np.random.SeedSequence(5, spawn_key=(STREAM_DRIFT,)))
        rng.uniform(0.0, 2.0 * math.pi)
        z = rng.normal(0.0, 1.0, (t.size, 2))
        g = np.empty_like(z)
        g[0] = 0.03 * z[0]
        for k in range(1, t.size):
            a = math.exp(-(t[k] - t[k - 1]) / tau)
            g[k] = a * g[k - 1] + 0.03 * math.sqrt(max(0.0, 1.0 - a * a)) * z[k]
        d = (0.0 + g) / scn.camera.scale_arcsec_per_px  # no ramp: rate 0 in the ideal world
        start = 0
        for pr, i, _, _ in _conditions(scn):
            n = tl[(pr, i)][2]
            assert got[(pr, i)].tobytes() == d[start:start + n].tobytes()
            start += n


def test_a_ramp_inflates_the_te_variance_by_a2_n_n_plus_1_over_12(monkeypatch):
    """A ramp of ``a`` px/frame adds ``a f`` to frame f's image, so each star's expected sample
    variance over N frames becomes ``sigma^2 + a^2 N (N + 1) / 12`` (the sample variance of
    ``a f``, f = 0..N-1, exactly). The TE estimator's per-star variances with the ramp against
    that, sigma^2 from the same camera without drift (other noise streams: another seed)."""
    from budget.starcam.protocols import make_plan, simulate
    from simcam.starcam.render import StarCamera

    scn = _ideal()
    n = scn.protocols.te.frames
    a = 2e-3     # px per frame: the ramp's variance 3.1e-4 px^2 against the noise's 1.6e-4
    ramp = np.stack([a * np.arange(n), np.zeros(n)], axis=1)
    plan = make_plan("te", scn)
    cam1 = StarCamera(scn)
    monkeypatch.setattr(cam1, "world_motion", lambda seed: WorldMotion({}, {("te", 0): ramp}))
    v1, v0 = [], []
    for seed in range(4):
        c1 = simulate(plan, cam1, seed=seed).centroids
        c0 = simulate(plan, StarCamera(scn), seed=100 + seed).centroids
        v1.append(c1.pivot(index="frame", columns="star", values="x").to_numpy().var(axis=0, ddof=1))
        v0.append(c0.pivot(index="frame", columns="star", values="x").to_numpy().var(axis=0, ddof=1))
    v1, v0 = np.concatenate(v1), np.concatenate(v0)
    ramp_var = a**2 * n * (n + 1) / 12
    s2 = v0.mean()
    # standard errors (normal theory): Var(s^2) = 2 sigma^4 / (N-1) for the noise alone, and
    # (2 sigma^4 + 4 sigma^2 ramp_var) / (N-1) with the ramp, over W x 4 star-runs each
    m = v1.size
    se = math.sqrt((2 * s2**2 + 4 * s2 * ramp_var) / (n - 1) / m + 2 * s2**2 / (n - 1) / m)
    assert abs(v1.mean() - (s2 + ramp_var)) < 4 * se
    assert ramp_var > 8 * se      # the check resolves the inflation


# --------------------------------------------------------------------------- effects off
#: run_trial(default scenario, seed 7, trial 3) of the code before the world effects (commit c44117e,
#: the previous default scenario = today's ideal world), float.hex: the ideal world must give
#: these to the rounding of its floating-point operations (tests/golden.py)
PRE_ISSUE22_TRIAL = {'hsfe|improved|x': '0x1.031e22850ad22p-9', 'hsfe|improved|y': '0x1.9ff3d20e4290fp-10', 'hsfe|published|x': '0x1.e023a34471ed8p-9', 'hsfe|published|y': '0x1.c96c7e6d81787p-9', 'lsfe_c1|improved|x': '0x0.0p+0', 'lsfe_c1|improved|y': '0x0.0p+0', 'lsfe_c1|published|x': '0x1.07348b6cc99a1p-6', 'lsfe_c1|published|y': '0x1.d1a65f762c266p-7', 'lsfe_s|improved|x': '0x1.cf5cea4011ab4p-6', 'lsfe_s|improved|y': '0x1.0738bd48ec251p-9', 'lsfe_s|published|x': '0x1.3b42415f80c5fp-6', 'lsfe_s|published|y': '0x1.11c6e2acae2fdp-10', 'te|improved|x': '0x1.aee4666961cbcp-7', 'te|improved|y': '0x1.b58bdc16da2a0p-7', 'te|published|x': '0x1.a961c511d1737p-7', 'te|published|y': '0x1.b2980081a0f37p-7'}


def test_effects_off_equals_the_code_before_issue_22():
    from budget.starcam.setup import CameraSetup
    from budget.starcam.validate import run_trial

    # the recorded values are the exact stamp route's (the default profile route moves the
    # stamps by ~1e-15 of the flux without effects: tests/test_stamp_route.py)
    # on the scenario seed's camera (maps and calibration), every trial's when these were recorded
    scn = with_updates(_ideal(), {"render.stamp_route": "exact"})
    got = run_trial(scn, 7, 3, camera=CameraSetup(scn).camera())["values"]
    # the estimates are differences of centroids on a mosaic up to 4096 px wide: four last bits
    # of such a position (3.6e-12 px) is the absolute floor of the comparison
    assert_close_to_recorded({key: float(got[tuple(key.split("|"))]) for key in PRE_ISSUE22_TRIAL},
                             {key: float.fromhex(h) for key, h in PRE_ISSUE22_TRIAL.items()},
                             abs_floor=4 * math.ulp(4096.0))
