"""The attitude study (issue #34) on the study contract: its scenario, its trials' seed streams
and truths, the same numbers on one and two workers, the report end to end, and the star
count over the sky against an independent count."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from budget.attitude.study import STUDY
from budget.runner.registry import get_study
from budget.runner.run import run_study
from budget.runner.study import instrument_seed_sequence, trial_seed_sequence
from simcam.config_base import read_toml
from simcam.infra.errors import ScenarioError
from simcam.sky.catalogue import hipparcos
from simcam.starcam import scenario as starcam_scenario
from simcam.starcam.sky_scenario import default, default_text, from_dict


def _scenario(**onboard):
    data = read_toml(text=default_text(), source="t")
    data["onboard"] = {**data["onboard"], **onboard}
    return from_dict(data, source="small.toml")


def test_the_default_flies_seed_000s_camera_and_its_hash_holds_the_camera(tmp_path):
    scn = default()
    assert get_study("attitude") is STUDY and scn.camera == "embedded:seed000_noisy"
    assert scn.camera_scenario == starcam_scenario.load("embedded:seed000_noisy")
    cam = tmp_path / "cam.toml"
    cam.write_text(starcam_scenario.default_text())
    a = from_dict({"camera": str(cam)}, source="s.toml")
    assert a.camera_scenario == starcam_scenario.default() and a.hash != scn.hash
    cam.write_text(starcam_scenario.default_text().replace("exposure_s = 0.1", "exposure_s = 0.25"))
    b = from_dict({"camera": str(cam)}, source="s.toml")
    assert b.camera_scenario.camera.exposure_s == 0.25 and b.hash != a.hash  # same text, another camera


@pytest.mark.parametrize("data,message", [
    ({"camera": "embedded:nope"}, "s.toml: camera: .*no embedded scenario 'nope'"),
    ({"camera": "missing.toml"}, "s.toml: camera: .*missing.toml: file not found"),
    ({"onboard": {"frames": 1}}, r"s.toml: onboard.frames: .*its range is \[2, 10000\]"),
    ({"sky": {"epoch_utc": "yesterday"}}, "s.toml: sky.epoch_utc"),
    ({"budget": {"te_3sigma_arcsec": [1.0, -1.0]}}, "s.toml: budget.te_3sigma_arcsec.1"),
])
def test_a_bad_field_is_one_error_naming_it(data, message):
    with pytest.raises(ScenarioError, match=message):
        from_dict(data, source="s.toml")


def test_a_trial_draws_from_its_documented_streams_and_its_truths_from_the_true_attitude():
    scn = _scenario(frames=3)
    k = 4
    r = STUDY.trial(scn, 7, k)
    # the attitude: Rotation.random with the first of three children of the trial's seed sequence
    att = Rotation.random(random_state=np.random.default_rng(trial_seed_sequence(7, k).spawn(3)[0]))
    b = att.apply([0.0, 0.0, 1.0])
    assert r.aux["blind_draws"] == 0.0
    assert r.aux["ra_deg"] == pytest.approx(math.degrees(math.atan2(b[1], b[0])) % 360.0, abs=1e-9)
    assert r.aux["dec_deg"] == pytest.approx(math.degrees(math.asin(b[2])), abs=1e-9)
    for v in ("published", "improved"):
        for ax in ("x", "y"):
            # one frame's mean square is the frames' mean squared plus their spread (F = 3)
            ms = r.estimates[("spatial", v, ax)] ** 2 + 2 / 3 * r.estimates[("temporal", v, ax)] ** 2
            assert r.truths[("stated_ms", v, ax)] == pytest.approx(ms, rel=1e-9)
            assert r.truths[("stated_rms", v, ax)] == pytest.approx(math.sqrt(ms), rel=1e-9)
    # eq 32 is the same statement for every pointing; the improved one is this pointing's
    assert r.estimates[("stated_rms", "published", "x")] == pytest.approx(1.76 / 3 / math.sqrt(10))
    assert ("stated_rms", "published", "roll") not in r.estimates
    assert r.estimates[("stated_rms", "improved", "roll")] > 5 * r.estimates[("stated_rms", "improved", "x")]
    again = STUDY.trial(scn, 7, k)
    assert again.estimates == r.estimates and again.truths == r.truths and again.aux == r.aux


def test_one_and_two_workers_give_the_same_numbers():
    scn = _scenario(frames=2)
    one = run_study(STUDY, scn, trials=4, seed=3, workers=1)
    two = run_study(STUDY, scn, trials=4, seed=3, workers=2)
    assert set(one.samples) == set(two.samples)
    for key in one.samples:
        assert np.array_equal(one.samples[key], two.samples[key]), key
    for key in one.trial_truths:
        assert np.array_equal(one.trial_truths[key], two.trial_truths[key]), key
    for key in one.sigmas:
        assert np.array_equal(one.sigmas[key], two.sigmas[key]), key
    for name in one.aux:
        assert np.array_equal(one.aux[name], two.aux[name]), name


def test_the_instrument_comes_from_the_instrument_stream_and_can_be_pinned(tmp_path, monkeypatch):
    # each trial's camera has the calibration errors of the first word of
    # instrument_seed_sequence(validation.instrument_seed, seed, k), and its maps too when the
    # flown camera draws them per instrument; pinned, every trial shares that camera
    import budget.attitude.study as study_mod

    seen = []
    observe = study_mod.observe_pointing

    def recording(camera, *args, **kwargs):
        seen.append((camera.detector_seed, camera.calibration_seed))
        return observe(camera, *args, **kwargs)

    monkeypatch.setattr(study_mod, "observe_pointing", recording)
    for new_maps in (False, True):
        cam = tmp_path / f"cam{new_maps}.toml"
        text = starcam_scenario.load("embedded:seed000_noisy").to_toml()
        assert "new_maps_per_trial = true" in text
        cam.write_text(text.replace("new_maps_per_trial = true", f"new_maps_per_trial = {str(new_maps).lower()}"))
        for pinned in ((None, 42) if new_maps else (None,)):
            data = read_toml(text=default_text(), source="t")
            data["camera"], data["onboard"]["frames"] = str(cam), 2
            data["validation"]["instrument_seed"] = pinned
            if pinned is None:
                del data["validation"]["instrument_seed"]
            scn = from_dict(data, source="i.toml")
            seen.clear()
            for k in (0, 1):
                STUDY.trial(scn, 7, k)
            words = [int(instrument_seed_sequence(pinned, 7, k).generate_state(1, np.uint32)[0]) for k in (0, 1)]
            calib = sorted({c for _, c in seen})
            assert calib == sorted(set(words))
            maps = {d for d, _ in seen}
            assert maps == (set(words) if new_maps else {scn.camera_scenario.seed})
            assert (words[0] == words[1]) == (pinned is not None)


def _split_check(run) -> None:
    for v in ("published", "improved"):
        for ax in ("x", "y", "roll"):
            s, f, p = (np.asarray(run.samples[(c, v, ax)], float) for c in ("spatial", "spatial_fov", "spatial_pixel"))
            # the FOV and pixel parts add exactly (pixel = spatial - FOV, per pointing)
            np.testing.assert_allclose(f + p, s, rtol=0, atol=1e-12 * max(1.0, np.abs(s).max()))
            # and in quadrature over the sky: mean(s^2) = mean(f^2) + mean(p^2) + mean(2 f p), the
            # cross term zero when the parts are independent; it is a mean of n independent pointings,
            # so its standard error is sd(2 f p) / sqrt(n): within 4 of them (1 in 16,000 by chance)
            cross = 2.0 * f * p
            assert abs(cross.mean()) <= 4.0 * cross.std(ddof=1) / math.sqrt(cross.size), (v, ax)
            assert np.mean(f**2) > 0 and np.mean(p**2) > 0


def test_the_spatial_error_splits_into_fov_and_pixel_parts_that_add():
    # 40 pointings of 3 frames, fixed seed; the 1,000-pointing split is in docs/attitude.md
    run = run_study(STUDY, _scenario(frames=3), trials=40, seed=11, workers=1)
    _split_check(run)
    # the colour shift of the sky's stars against the lamp is a smooth field: most of x's bias
    fx = np.asarray(run.samples[("spatial_fov", "published", "x")])
    assert np.mean(fx**2) > 0.5 * np.mean(np.asarray(run.samples[("spatial", "published", "x")]) ** 2)


def test_an_ideal_camera_has_no_fov_spatial_error(tmp_path):
    # no distortion, lateral colour or correction: the smooth-field positions are the gnomonic ones
    cam = starcam_scenario.with_updates(starcam_scenario.load("embedded:seed000_ideal"), {
        "optics.distortion.k1": 0.0, "optics.distortion.k2": 0.0, "optics.distortion.p1": 0.0,
        "optics.distortion.p2": 0.0, "optics.distortion.cubic_x_px": [0.0] * 10,
        "optics.distortion.cubic_y_px": [0.0] * 10, "optics.lateral_colour.radial_px_per_nm": [0.0],
        "optics.lateral_colour.uniform_x_px_per_nm": [0.0], "optics.lateral_colour.uniform_y_px_per_nm": [0.0],
        "optics.distortion_correction.kind": "none"})
    path = tmp_path / "ideal.toml"
    path.write_text(cam.to_toml())
    data = read_toml(text=default_text(), source="t")
    data["camera"] = str(path)
    data["onboard"]["frames"] = 2
    data["world"] = {"effects": {"distortion_r5_px_at_corner": 0.0, "distortion_r7_px_at_corner": 0.0,
                                 "nonlinearity_beta": 0.0}}
    r = STUDY.trial(from_dict(data, source="ideal.toml"), 3, 0)
    for v in ("published", "improved"):
        for ax in ("x", "y", "roll"):
            assert abs(r.estimates[("spatial_fov", v, ax)]) < 1e-6, (v, ax)


def test_validate_writes_the_report_end_to_end(tmp_path):
    out = tmp_path / "rep"
    r = subprocess.run([sys.executable, "-m", "budget", "attitude", "validate", "--trials", "8", "--report",
                        str(out), "--workers", "1"], capture_output=True, text=True, timeout=600, check=False)
    assert r.returncode == 0, r.stderr
    md = (out / "report.md").read_text()
    assert md.index("## Attitude on the sky: findings") < md.index("## Attitude on the sky: figures")
    for name in ("attitude_error_vs_n", "attitude_temporal_spatial", "attitude_requirement", "attitude_sky_maps"):
        assert (out / f"{name}.png").is_file() and f"**{name}**: " in md
    assert "Seed 000's eq 32" in md and "Roll" in md and "Requirement" in md
    sky = json.loads((out / "summary.json").read_text())["details"]["sky"]
    assert sky["pointings"] == 8 and sky["published_sigma_arcsec"] == pytest.approx([1.76 / 3 / math.sqrt(10),
                                                                                      1.95 / 3 / math.sqrt(10)])


def _independent_mean_count(scn) -> float:
    """The mean star count a pointing should see: the catalogue's stars with V <= the limit per
    square degree of the whole sky, times the windowable area of the mosaic (each chip less
    half a window at its edges), gnomonic area and distortion neglected (< 1 %)."""
    cam = scn.camera_scenario
    per_deg2 = np.count_nonzero(hipparcos().v_mag <= scn.sky.catalogue_v_max_mag) / (4 * math.pi * (180 / math.pi) ** 2)
    det, m = cam.detector, cam.render.window_px // 2
    px2 = det.n_chips * (det.chip_cols - 2 * m) * (det.chip_rows - 2 * m)
    return per_deg2 * px2 * (cam.camera.scale_arcsec_per_px / 3600.0) ** 2


def _check_the_sky(trials: int, seed: int):
    scn = _scenario(frames=2)
    res = run_study(STUDY, scn, trials=trials, seed=seed, workers=1)
    n = res.aux["n_stars"]
    # blind draws (fewer than 2 stars) are drawn again: few at V 7.5
    assert res.aux["blind_draws"].sum() <= max(2, trials // 50)
    expected = _independent_mean_count(scn)
    assert abs(n.mean() - expected) < 4 * n.std(ddof=1) / math.sqrt(trials), (n.mean(), expected)
    # boresights uniform on the sphere: sin(dec) and each coordinate uniform on [-1, 1]
    dec = np.radians(res.aux["dec_deg"])
    ra = np.radians(res.aux["ra_deg"])
    for c in (np.sin(dec), np.cos(dec) * np.cos(ra), np.cos(dec) * np.sin(ra)):
        assert abs(c.mean()) < 4 / math.sqrt(3 * trials)


def test_the_sky_is_sampled_uniformly_and_its_star_count_is_the_catalogues():
    _check_the_sky(trials=24, seed=11)


@pytest.mark.slow
def test_the_sky_is_sampled_uniformly_and_its_star_count_is_the_catalogues_over_many_pointings():
    _check_the_sky(trials=1500, seed=12)


def test_a_slewing_camera_is_judged_frame_by_frame_against_each_frames_attitude():
    scn = _scenario(frames=3, angular_rate_deg_per_s=[0.05, 0.0, 0.02], frame_interval_s=2.0)
    r = STUDY.trial(scn, 5, 0)
    assert not scn.onboard.staring and set(r.estimates) == set(STUDY.trial(_scenario(frames=3), 5, 0).estimates)
    # 0.1 deg between frames (a sixth of a star's 3.1 deg path across the short side): each frame is
    # solved against its own mid-exposure attitude, so the error stays sub-arcsec across the boresight
    for ax in ("x", "y"):
        assert abs(r.estimates[("spatial", "improved", ax)]) < 2.0
        assert r.estimates[("temporal", "improved", ax)] < 2.0
