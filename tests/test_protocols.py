"""Acquisition plans, protocols run on simulated windows, and `budget measure` on FITS frames."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from budget.cli import cli as budget_cli
from budget.starcam.measure import measure_frames
from budget.starcam.protocols import estimate, make_plan, simulate
from budget.starcam.simulate import write_protocol_frames
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import default, from_dict

SMALL = {
    "detector": {"chip_cols": 256, "chip_rows": 256, "gap_px": 10.0},
    # a brighter source than seed 000's V = 7.5 keeps the 500 nm filter frames well above threshold
    "lab": {"target_center_px": [-133.0, 0.0], "target": {"spacing_mm": 0.5}, "source": {"match_v_mag": 6.0}},
    "optics": {"r_norm_px": 256.0},
    "protocols": {
        "hsfe": {"conditions": 4, "frames": 4},
        "te": {"frames": 6},
        "chromatic": {"frames": 3, "field_centers_px": [[-150.0, -60.0], [150.0, -60.0], [-150.0, 60.0], [150.0, 60.0]]},
        "distortion": {"frames": 3},
    },
    # the ideal world: these tests check the simulator's lab physics against its truth
    # tables; the world's effects have their own tests (test_world_starcam.py)
    "world": {"effects": default().world.effects.ideal().model_dump()},
}


def _mean_and_pooled_sd(cen):
    """Per (condition, star) mean position, with the frame-to-frame sd pooled over the condition's stars."""
    g = cen.groupby(["condition", "star"])[["x", "y"]]
    m = g.mean().join(g.var().add_suffix("_var")).join(g.size().rename("n")).reset_index()
    pooled = m.groupby("condition")[["x_var", "y_var"]].transform("mean")
    m["x_sd"], m["y_sd"] = np.sqrt(pooled.x_var), np.sqrt(pooled.y_var)
    return m


@pytest.fixture(scope="module")
def small():
    return from_dict(SMALL)


def test_plans_follow_seed000():
    scn = default()
    te = make_plan("te", scn)
    assert len(te.conditions) == 1 and te.conditions[0].frames >= 30
    h = make_plan("hsfe", scn).to_frame()
    assert len(h) == 12
    step = np.hypot(np.diff(h.platform_dx_px), np.diff(h.platform_dy_px))
    np.testing.assert_allclose(step, 0.2)
    np.testing.assert_allclose(h.platform_dx_px, h.platform_dy_px)  # along 45 deg
    c = make_plan("chromatic", scn).to_frame()
    assert len(c) == 12 and c.field.nunique() == 4 and sorted(c.filter_nm.unique()) == [500.0, 600.0, 800.0]
    d = make_plan("distortion", scn)
    assert d.conditions[0].target == "calibration_grid"
    with pytest.raises(ValueError, match="protocol: unknown 'xyz'"):
        make_plan("xyz", scn)


def test_simulated_protocols_recover_truth_positions(small):
    cam = StarCamera(small)
    for proto in ("te", "hsfe", "chromatic", "distortion"):
        d = simulate(make_plan(proto, small), cam, seed=3)
        assert (d.centroids.flag == 0).all()
        m = _mean_and_pooled_sd(d.centroids)
        # the camera reports through its own distortion correction: compare with what it
        # reports for the true image position
        t = d.truth[["condition", "star", "x_reported", "y_reported"]]
        j = m.merge(t, on=["condition", "star"])
        assert len(j) == len(m)
        # mean over N frames of a thresholded CoG vs truth: temporal noise with standard error
        # sd/sqrt(N) (5 standard errors: two-sided 6e-7 per star-axis, ~1e-4 over all of them)
        # plus 0.03 px for the CoG's own systematic error (threshold, 11x11 window, S-curve)
        se_x = j.x_sd / np.sqrt(j.n)
        se_y = j.y_sd / np.sqrt(j.n)
        assert (np.abs(j.x - j.x_reported) < 5 * se_x + 0.03).all()
        assert (np.abs(j.y - j.y_reported) < 5 * se_y + 0.03).all()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a debiased variance may come out negative at N = 3..6
            res = estimate(proto, d.centroids, plate_scale_arcsec=small.camera.scale_arcsec_per_px,
                           reference=d.reference)
        assert {"published", "improved"} <= set(res)


def test_protocol_noise_streams_are_independent_and_reproducible(small):
    cam = StarCamera(small)
    a = simulate(make_plan("te", small), cam, seed=3).centroids
    b = simulate(make_plan("te", small), cam, seed=3).centroids
    pd.testing.assert_frame_equal(a, b)
    c = simulate(make_plan("te", small), cam, seed=4).centroids
    assert not np.allclose(a.x, c.x)


@pytest.fixture(scope="module")
def frames_dir(tmp_path_factory, small):
    root = tmp_path_factory.mktemp("lab")
    out = {}
    for proto in ("te", "hsfe", "distortion", "chromatic"):
        write_protocol_frames(proto, small, seed=5, out=root / proto, dark_frames=2)
        out[proto] = root / proto
    out["scenario"] = small
    return out


def _static_centroid_error(scn, proto, cond, frames=400):
    """Static error of the expected centroid of each star (truth order) in condition ``cond``
    of ``proto``'s plan (seed 5, 2 dark frames as written), and its standard error."""
    from budget.starcam.protocols import PROTOCOL_STREAM
    from budget.starcam.truth import _noisy_errors
    from simcam.starcam.render import Placement
    from simcam.starcam.scenario import with_updates
    from simcam.starcam.targets import calibration_grid, star_grid

    scn = with_updates(scn, {"validation.dark_frames": 2})
    cam = StarCamera(scn)
    c = make_plan(proto, scn, seed=5, dark_frames=2).conditions[int(cond)]
    lay = calibration_grid(scn) if c.target == "calibration_grid" else star_grid(scn, center_px=c.field_center_px)
    scene = cam.scene(Placement(layout=lay, platform_dx_px=c.platform_dx_px, platform_dy_px=c.platform_dy_px,
                                filter_nm=c.filter_nm, condition=1000 * PROTOCOL_STREAM[proto] + c.index))
    ex, ey = _noisy_errors(cam, scene, frames=frames, seed=77)
    return ex.mean(0), ey.mean(0), ex.std(0, ddof=1) / np.sqrt(frames), ey.std(0, ddof=1) / np.sqrt(frames)


@pytest.mark.parametrize("proto", ["te", "hsfe", "distortion", "chromatic"])
def test_measure_on_simulated_frames_matches_truth(frames_dir, proto):
    d = frames_dir[proto]
    ref = d / "reference.csv" if proto == "distortion" else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # negative debiased variances are expected at N = 3..6
        cen, reference, info = measure_frames(proto, d, reference=ref)
    assert info["plate_scale_arcsec"] == 5.5
    truth = pd.read_csv(d / "truth.csv")
    m = _mean_and_pooled_sd(cen)
    # star identities: each measured star's nearest truth star in its condition is unique
    for cond, g in m.groupby("condition"):
        t = truth[truth.condition == cond]
        dist = np.hypot(g.x.to_numpy()[:, None] - t.x_true.to_numpy()[None], g.y.to_numpy()[:, None] - t.y_true.to_numpy()[None])
        nearest = dist.argmin(axis=1)
        assert len(set(nearest)) == len(g) == len(t)
        # Each star's frame mean against its true position corrected by the static error of
        # the expected centroid (threshold, window, pixel phase, PRNU/DSNU: the CoG's own
        # systematic error), computed for the same scene from 400 noisy frames centroided
        # the same way (budget.starcam.truth._noisy_errors, 2 dark frames subtracted); within 5
        # standard errors of the difference, sqrt(se_mean^2 + se_static^2) per axis.
        bx, by, sbx, sby = _static_centroid_error(frames_dir["scenario"], proto, cond)
        j = nearest
        ex = g.x.to_numpy() - t.x_true.to_numpy()[j] - bx[j]
        ey = g.y.to_numpy() - t.y_true.to_numpy()[j] - by[j]
        n = g.n.to_numpy()
        assert (np.abs(ex) < 5 * np.sqrt(g.x_sd.to_numpy() ** 2 / n + sbx[j] ** 2)).all()
        assert (np.abs(ey) < 5 * np.sqrt(g.y_sd.to_numpy() ** 2 / n + sby[j] ** 2)).all()
    if proto == "hsfe":
        # the same star index follows the same pinhole through the poses
        first = m[m.condition == 0].set_index("star")
        last = m[m.condition == m.condition.max()].set_index("star")
        shift = last[["x", "y"]] - first[["x", "y"]]
        expected = 0.2 * (m.condition.max()) / np.sqrt(2)
        np.testing.assert_allclose(shift.to_numpy(), expected, atol=0.05)


def test_measure_cli_json(frames_dir, tmp_path):
    out = tmp_path / "te.json"
    r = CliRunner().invoke(budget_cli, ["starcam", "measure", "te", str(frames_dir["te"]), "--json", str(out)])
    assert r.exit_code == 0, r.output
    assert "published  TE" in r.output
    data = json.loads(out.read_text())
    assert data["estimates"]["published"]["quantity"] == "TE"
    assert data["estimates"]["published"]["n_stars"] == 25


def _run(args):
    from budget.cli import main

    with pytest.raises(SystemExit) as e:
        main(args)
    return e.value.code


def test_measure_bad_inputs(frames_dir, tmp_path, capsys):
    te = frames_dir["te"]
    # no manifest
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _run(["starcam", "measure", "te", str(empty)]) == 2
    assert "manifest not found" in capsys.readouterr().err
    # a manifest naming a missing frame
    m = pd.read_csv(te / "manifest.csv")
    m.loc[0, "file"] = "nope.fits"
    bad = tmp_path / "m1.csv"
    m.to_csv(bad, index=False)
    assert _run(["starcam", "measure", "te", str(te), "--manifest", str(bad)]) == 2
    assert "nope.fits: frame file not found" in capsys.readouterr().err
    # fewer than 2 frames
    m = pd.read_csv(te / "manifest.csv")
    m1 = m[(m.dark == 1) | (m.frame == 0)]
    one = tmp_path / "m2.csv"
    m1.to_csv(one, index=False)
    assert _run(["starcam", "measure", "te", str(te), "--manifest", str(one)]) == 2
    assert "at least 2 are needed" in capsys.readouterr().err
    # unknown column
    m2 = pd.read_csv(te / "manifest.csv").assign(exposure=1)
    uk = tmp_path / "m3.csv"
    m2.to_csv(uk, index=False)
    assert _run(["starcam", "measure", "te", str(te), "--manifest", str(uk)]) == 2
    assert "unknown column(s) exposure" in capsys.readouterr().err
    # distortion without reference
    assert _run(["starcam", "measure", "distortion", str(frames_dir["distortion"])]) == 2
    assert "--reference" in capsys.readouterr().err


def test_measure_flags_a_nan_pixel_star(frames_dir, tmp_path):
    import shutil

    from astropy.io import fits

    src = frames_dir["te"]
    dst = tmp_path / "te_nan"
    shutil.copytree(src, dst)
    truth = pd.read_csv(dst / "truth.csv")
    x, y = truth.x_true[0], truth.y_true[0]
    with fits.open(dst / "c000_f0001.fits", mode="update") as h:
        data = h[0].data.astype(np.float32)
        data[int(round(y)), int(round(x))] = np.nan
        h[0].data = data
    with pytest.warns(UserWarning, match="(?i)nan|non-finite"):
        cen, _, _ = measure_frames("te", dst)
    assert (cen.flag != 0).sum() == 1
    with pytest.warns(UserWarning, match="excluded"):
        res = estimate("te", cen, plate_scale_arcsec=5.5)
    assert res["published"].n_rows_excluded == 1


@pytest.mark.parametrize("method", ["iwcog", "gauss"])
def test_better_centroids_run_through_the_protocols(small, method):
    cam = StarCamera(small)
    d = simulate(make_plan("te", small), cam, seed=3, method=method)
    assert (d.centroids.flag == 0).all()
    m = _mean_and_pooled_sd(d.centroids).merge(d.truth[["condition", "star", "x_reported", "y_reported"]],
                                               on=["condition", "star"])
    se = m.x_sd / np.sqrt(m.n)
    # systematic allowance: the Gaussian fit is nearly unbiased (0.03 px as for the CoG); the
    # iteratively weighted CoG, with its weight set to the camera PSF's sigma while the image
    # is wider (pinhole disc, pixel), keeps a pixel-phase bias of a few hundredths of a px
    allowance = 0.06 if method == "iwcog" else 0.03
    assert (np.abs(m.x - m.x_reported) < 5 * se + allowance).all()


@pytest.mark.parametrize("dark_frames", [0, 2])
def test_fused_fast_path_equals_windows_then_centroids(small, dark_frames):
    # simulate() without keep_windows exposes and centroids each window in one numba pass
    # (budget.starcam.kernels_trial); with keep_windows it renders the windows and runs
    # centroid_windows on them. Same pixels, same centroid code: identical tables.
    cam = StarCamera(small)
    for proto in ("te", "hsfe", "chromatic", "distortion"):
        plan = make_plan(proto, small, seed=4, dark_frames=dark_frames)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fast = simulate(plan, cam, seed=4, marker_seed=9)
            slow = simulate(plan, cam, seed=4, marker_seed=9, keep_windows=True)
        assert slow.windows and not fast.windows
        pd.testing.assert_frame_equal(fast.centroids, slow.centroids, check_exact=True)
        pd.testing.assert_frame_equal(fast.truth, slow.truth, check_exact=True)


@pytest.mark.parametrize("dark_frames", [0, 2])
def test_fused_fast_path_threads_do_not_change_results(small, dark_frames):
    # the threaded kernel runs the serial one on each window's own copies
    plan = make_plan("hsfe", small, seed=2, dark_frames=dark_frames)
    serial = simulate(plan, StarCamera(small, parallel=False), seed=2).centroids
    threaded = simulate(plan, StarCamera(small, parallel=True), seed=2).centroids
    pd.testing.assert_frame_equal(serial, threaded, check_exact=True)


def _assert_same_estimate(a, b):
    """Two estimates equal field by field: floats bit for bit, tables exactly."""
    import dataclasses

    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, pd.DataFrame):
            pd.testing.assert_frame_equal(x, y, check_exact=True)
        elif isinstance(x, dict):
            assert list(x) == list(y), f.name
            for k in x:
                assert np.array_equal(x[k], y[k], equal_nan=isinstance(x[k], float)), (f.name, k)
        else:
            assert np.array_equal(x, y, equal_nan=isinstance(x, float)), f.name


@pytest.mark.parametrize("world, threshold_sigma", [("realistic", 3.0), ("small", 3.0), ("small", 100.0),
                                                    ("small", 200.0)])
def test_estimates_on_simulated_rows_equal_those_on_the_checked_table(small, world, threshold_sigma):
    # the Monte Carlo trial hands simulate()'s rows to estimate() unchecked; a lab hands it the
    # DataFrame, which is checked and turned into the same rows: every variant, every field
    # (warnings, tables) the same bit for bit; with flagged rows too, where a high threshold
    # loses the 500 nm frames (100 sigma) or also the 600 nm ones (200 sigma: the same error)
    from budget.starcam.study import STUDY

    scn = default() if world == "realistic" else small
    cam = StarCamera(scn)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for proto in ("te", "hsfe", "chromatic", "distortion"):
            d = simulate(make_plan(proto, scn, seed=4), cam, seed=4, marker_seed=9, threshold_sigma=threshold_sigma)
            assert (d.rows["flag"] != 0).any() == (proto == "chromatic" and threshold_sigma > 3.0)
            for spectral in (None, STUDY.prepared(scn).spectral()):
                kw = dict(plate_scale_arcsec=scn.camera.scale_arcsec_per_px, marker_3sigma_arcsec=0.5,
                          reference_filter_nm=scn.protocols.chromatic.reference_filter_nm, spectral=spectral)
                try:
                    fast = estimate(proto, d.rows, reference=d.reference_rows, **kw)
                except Exception as exc:  # noqa: BLE001 - the same error either way
                    with pytest.raises(type(exc), match=re.escape(str(exc))):
                        estimate(proto, d.centroids, reference=d.reference, **kw)
                    continue
                checked = estimate(proto, d.centroids, reference=d.reference, **kw)
                assert list(fast) == list(checked)
                for variant in fast:
                    _assert_same_estimate(fast[variant], checked[variant])


def test_measure_finds_only_the_target_stars_at_the_validate_threshold(tmp_path):
    """`budget measure` centroids at the same threshold as `budget validate` (3 sigma) and
    finds stars on the mean of a condition's frames: with two frames a single-frame 3-sigma
    detection would admit noise "stars"; here exactly the 25 pinholes are
    found, each matched to one true star within 0.5 px."""
    from budget.starcam.measure import DEFAULT_THRESHOLD_SIGMA

    assert DEFAULT_THRESHOLD_SIGMA == default().validation.threshold_sigma
    # the seed's V = 7.5 source (SMALL's brighter one saturates the TE pinholes)
    scn = from_dict(dict(SMALL, protocols=dict(SMALL["protocols"], te={"frames": 2}),
                                  lab=dict(SMALL["lab"], source={"match_v_mag": 7.5})))
    for seed in range(3):
        d = tmp_path / f"te{seed}"
        write_protocol_frames("te", scn, seed=seed, out=d)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cen, _, _ = measure_frames("te", d)
        truth = pd.read_csv(d / "truth.csv")
        m = cen[cen.flag == 0].groupby("star")[["x", "y"]].mean()
        assert len(m) == len(truth) == 25
        dist = np.hypot(m.x.to_numpy()[:, None] - truth.x_true.to_numpy()[None],
                        m.y.to_numpy()[:, None] - truth.y_true.to_numpy()[None])
        assert len(set(dist.argmin(axis=1))) == 25 and dist.min(axis=1).max() < 0.5
