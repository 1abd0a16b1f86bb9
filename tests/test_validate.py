"""Monte Carlo validation: truth recovery with one effect at a time, reproducibility, stopping.

Fast fixed-seed versions run by default (a small two-chip detector, few frames); the
long runs on the seed-000 default are behind the ``slow`` marker.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from click.testing import CliRunner
from scipy import stats

from budget.protocols import estimate, make_plan, simulate
from budget.validate import run_trial, validate
from simcam.render import StarCamera
from simcam.scenario import default_scenario, scenario_from_dict

BASE = {
    "detector": {"chip_cols": 256, "chip_rows": 256, "gap_px": 10.0},
    "lab": {"target_center_px": [-133.0, 0.0], "target": {"spacing_mm": 0.5}, "source": {"match_v_mag": 6.0}},
    "optics": {"r_norm_px": 256.0},
    "protocols": {
        "te": {"frames": 10},
        "hsfe": {"conditions": 6, "frames": 6},
        "chromatic": {"frames": 4, "field_centers_px": [[-150.0, -60.0], [150.0, -60.0], [-150.0, 60.0], [150.0, 60.0]]},
        "distortion": {"frames": 4},
    },
    "validation": {"te_truth_frames": 300, "hsfe_phase_grid": 3, "field_grid": 5, "batch_trials": 4},
}
QUIET = {"prnu_rms": 0.0, "dsnu_rms_e": 0.0}
NO_OPTICS = {
    "distortion": {"k1": 0.0, "k2": 0.0},
    "lateral_colour": {"radial_px_per_nm": [], "uniform_x_px_per_nm": [], "uniform_y_px_per_nm": []},
}


def _scn(**sections):
    data = json.loads(json.dumps(BASE))
    for sec, val in sections.items():
        data.setdefault(sec, {}).update(val)
    return scenario_from_dict(data)


@pytest.fixture(scope="module")
def small():
    return _scn()


def test_results_identical_with_one_and_two_workers(small):
    a = validate(small, trials=4, seed=3, workers=1, keep_example=False)
    b = validate(small, trials=4, seed=3, workers=2, keep_example=False)
    for key in a.samples:
        np.testing.assert_array_equal(a.samples[key], b.samples[key])
    # trial k does not depend on which other trials ran
    t2 = run_trial(small, 3, 2)
    for key, v in t2["values"].items():
        assert a.samples[key][2] == v  # bit-identical on purpose: reproducibility


def test_te_alone_is_recovered_within_monte_carlo_error():
    """Only temporal noise (no PRNU/DSNU, no distortion or colour): TE's mean matches its truth.

    Tolerance: 3 standard errors of the difference, sqrt(se_mean^2 + se_truth^2), with
    se_mean = sd / sqrt(K) over the trials and se_truth from the truth's own sample of
    frames (sd / sqrt(2 (n - 1)) per star, averaged over the stars).
    """
    scn = _scn(detector=QUIET, optics=NO_OPTICS)
    res = validate(scn, trials=24, seed=11, keep_example=False)
    s = res.summary()["te"]
    f = 3 * scn.camera.scale_arcsec_per_px
    te = res.truths["te"]
    for ax in ("x", "y"):
        d = s[ax]["improved"]
        se_truth = te.details[f"standard_error_{ax}_px"] * f / math.sqrt(te.details["stars"])
        assert abs(d["bias"]) < 3 * math.hypot(d["se_bias"], se_truth), d
        # the published mean of per-star sds is low by the c4 factor of N = 10 frames (~2.7 %)
        p = s[ax]["published"]
        assert p["mean"] < d["mean"]


def test_hsfe_invisible_effect_gives_estimate_consistent_with_zero():
    """PRNU and DSNU off and a wide PSF (no pixel-phase error): the static HSFE variance is ~0.

    The unclipped variance estimate tau^2 (before clipping at 0) of each trial is unbiased
    for 0 here; its mean over K trials must lie within 3 standard errors of 0.
    """
    scn = _scn(detector=QUIET, optics=NO_OPTICS | {"psf": {"sigma0_px": 1.6, "sigma_r2_px": 0.0}})
    cam = StarCamera(scn)
    tau2 = []
    for k in range(16):
        d = simulate(make_plan("hsfe", scn), cam, seed=100 + k)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = estimate("hsfe", d.centroids, plate_scale_arcsec=5.5)["improved"]
        tau2.append([r.details["tau2_x_px2"], r.details["tau2_y_px2"]])
    tau2 = np.array(tau2)
    m, se = tau2.mean(axis=0), tau2.std(axis=0, ddof=1) / math.sqrt(len(tau2))
    assert np.all(np.abs(m) < 3 * se)
    # the truth is small but not 0: the threshold (3 sigma of the background noise) and the
    # 11-px window still give the centre of gravity a pixel-phase error for sigma = 1.6 px
    from budget.truth import hsfe_truth

    t = hsfe_truth(cam)
    assert t.x_px < 0.005 and t.y_px < 0.005


def test_lsfe_c1_published_measures_the_calibrated_part_not_the_residual():
    """Pure cubic distortion: the cubic calibration removes all of it (truth ~0), while the
    published sqrt(sigma_d^2 - sigma_Dd^2) reports the spread of the distortion it removed."""
    scn = _scn(detector=QUIET, optics={"distortion": {"k1": 5e-3, "k2": 0.0}, "lateral_colour": NO_OPTICS["lateral_colour"]},
               lab=BASE["lab"] | {"calibration_target": {"marker_error_3sigma_arcsec": 0.0}})
    res = validate(scn, trials=6, seed=5, keep_example=False)
    s = res.summary()["lsfe_c1"]["x"]
    assert res.truths["lsfe_c1"].x_px < 1e-6  # a cubic fits r^3 distortion exactly
    assert s["published"]["mean"] > 10 * max(s["improved"]["mean"], 1e-3)


def test_predictive_interval_coverage_within_binomial_limits():
    """The 95 % interval from the first half of the trials covers the second half's estimates
    at 95 % within binomial limits (99.9 % two-sided)."""
    scn = _scn(detector=QUIET, optics=NO_OPTICS)
    res = validate(scn, trials=80, seed=21, keep_example=False)
    v = res.samples[("te", "published", "x")]
    lo, hi = np.quantile(v[:40], [0.025, 0.975])
    inside = int(np.sum((v[40:] >= lo) & (v[40:] <= hi)))
    # with the interval itself estimated from 40 draws, the coverage of a new draw is
    # Beta-distributed around 0.95; binomial limits of 40 draws at p = 0.95 are generous
    lo_k, hi_k = stats.binom.ppf([0.0005, 0.9995], 40, 0.95)
    assert lo_k - 4 <= inside <= hi_k


def test_adaptive_stopping_reaches_the_tolerance(small):
    res = validate(small, tolerance_3sigma_arcsec=0.05, seed=2, keep_example=False)
    assert res.stopped_by == "tolerance"
    for cls in res.summary().values():
        for ax in cls.values():
            for var in ax.values():
                assert var["se_bias"] <= 0.05 and var["se_std"] <= 0.05
    with pytest.raises(ValueError, match="give one of them"):
        validate(small, trials=4, tolerance_3sigma_arcsec=0.1)


def test_validate_cli_writes_json_and_report(tmp_path, small):
    from budget.cli import cli
    from simcam.scenario import scenario_to_toml

    p = tmp_path / "s.toml"
    p.write_text(scenario_to_toml(small))
    out = tmp_path / "v.json"
    rep = tmp_path / "rep"
    r = CliRunner().invoke(cli, ["validate", str(p), "--trials", "3", "--workers", "1", "--no-progress",
                                 "--json", str(out), "--report", str(rep)])
    assert r.exit_code == 0, r.output
    data = json.loads(out.read_text())
    assert data["scenario_hash"] == small.hash and data["seed"] == 0 and data["trials"] == 3
    for cls in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2", "lsfe", "total"):
        for ax in ("x", "y"):
            for var in ("published", "improved"):
                assert {"truth", "mean", "bias", "std"} <= set(data["classes"][cls][ax][var])
    for f in ("report.md", "estimates.png", "hsfe_residuals.png", "chromatic_residuals.png",
              "distortion_residuals.png", "scenario.toml"):
        assert (rep / f).is_file(), f
    assert small.hash in (rep / "report.md").read_text()


@pytest.mark.slow
def test_default_scenario_long_run():
    """The seed-000 default with 200 trials: the published LSFE-C1 and LSFE-S are far from
    their truths, the improved LSFE-S within 5 %."""
    res = validate(default_scenario(), trials=200, seed=1, workers=2, keep_example=False)
    s = res.summary()
    assert s["lsfe_c1"]["x"]["published"]["bias_percent"] > 1000
    assert abs(s["lsfe_s"]["x"]["improved"]["bias_percent"]) < 5


def test_default_trial_count_comes_from_the_scenario():
    scn = _scn(validation=BASE["validation"] | {"trials": 3})
    res = validate(scn, seed=1, keep_example=False)
    assert res.trials == 3 and res.stopped_by == "trials"
    scn = _scn(validation=BASE["validation"] | {"trials": 100, "tolerance_3sigma_arcsec": 0.2, "batch_trials": 10})
    res = validate(scn, seed=1, keep_example=False)
    assert res.stopped_by == "tolerance" and res.trials < 100


def test_new_maps_per_trial_changes_trials_and_averages_the_hsfe_truth():
    scn = _scn(validation=BASE["validation"] | {"new_maps_per_trial": True})
    res = validate(scn, trials=2, seed=4, keep_example=False)
    assert res.truths["hsfe"].details["map_realisations"] == 4
    fixed = validate(_scn(), trials=2, seed=4, keep_example=False)
    assert res.samples[("hsfe", "published", "x")][1] != fixed.samples[("hsfe", "published", "x")][1]
