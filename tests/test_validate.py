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

from budget.starcam.protocols import estimate, make_plan, simulate
from budget.runner.run import run_study
from budget.starcam.study import STUDY
from budget.starcam.validate import run_trial
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import default, from_dict

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
    "validation": {"te_truth_frames": 300, "hsfe_phase_grid": 3, "hsfe_truth_frames": 200, "field_grid": 5,
                   "batch_trials": 4},
    # the ideal world (issue 22): these tests check the lab's methods against closed forms;
    # the world's effects have their own tests (test_world_starcam.py)
    "world": {"effects": {"distortion_r5_px_at_corner": 0.0, "distortion_r7_px_at_corner": 0.0,
                          "nonlinearity_beta": 0.0, "hexapod_repeatability_arcsec": 0.0,
                          "hexapod_backlash_arcsec": 0.0, "drift_rate_arcsec_per_h": 0.0,
                          "drift_random_arcsec": 0.0}},
}
QUIET = {"prnu_rms": 0.0, "dsnu_rms_e": 0.0}
NO_OPTICS = {
    "distortion": {"k1": 0.0, "k2": 0.0},
    "lateral_colour": {"radial_px_per_nm": [], "uniform_x_px_per_nm": [], "uniform_y_px_per_nm": []},
}


def validate(scn, *, trials=None, tolerance=None, seed=0, workers=1):
    """The seed-000 study through the one runner (values in arcsec, 3 sigma)."""
    return run_study(STUDY, scn, trials=trials, tolerance=tolerance, seed=seed, workers=workers)


def _scn(**sections):
    data = json.loads(json.dumps(BASE))
    for sec, val in sections.items():
        data.setdefault(sec, {}).update(val)
    return from_dict(data)


@pytest.fixture(scope="module")
def small():
    return _scn()


def test_results_identical_with_one_and_two_workers(small):
    a = validate(small, trials=4, seed=3, workers=1)
    b = validate(small, trials=4, seed=3, workers=2)
    for key in a.samples:
        np.testing.assert_array_equal(a.samples[key], b.samples[key])
    # trial k does not depend on which other trials ran
    t2 = run_trial(small, 3, 2)
    f = 3 * small.camera.scale_arcsec_per_px
    for key, v in t2["values"].items():
        assert a.samples[key][2] == v * f  # bit-identical on purpose: reproducibility


def test_te_alone_is_recovered_within_monte_carlo_error():
    """Only temporal noise (no PRNU/DSNU, no distortion or colour): TE's mean matches its truth.

    Tolerance: 3 standard errors of the difference, sqrt(se_mean^2 + se_truth^2), with
    se_mean = sd / sqrt(K) over the trials and se_truth from the truth's own sample of
    frames (sd / sqrt(2 (n - 1)) per star, averaged over the stars).
    """
    scn = _scn(detector=QUIET, optics=NO_OPTICS)
    res = validate(scn, trials=24, seed=11)
    s = res.summary()["te"]
    for ax in ("x", "y"):
        d = s[ax]["improved"]
        # se_bias already combines the trials' and the truth's standard errors
        assert d["truth_se"] > 0 and d["se_bias"] > d["truth_se"]
        assert abs(d["bias"]) < 3 * d["se_bias"], d
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
    # The truth is the static error of the expected centroid under noise. For a Gaussian of
    # sigma = 1.6 px the sampled centre of gravity's pixel-phase error is ~exp(-2 pi^2
    # sigma^2) ~ 1e-22 px (Poisson summation), and the noise smooths the threshold's edge:
    # its mean square (an unbiased split-half estimate) must be 0 within 3 of its own
    # standard errors.
    from budget.starcam.truth import hsfe_truth

    t = hsfe_truth(cam, frames=400, seed=7)
    for ax in ("x", "y"):
        assert abs(t.details[f"mean_square_{ax}_px2"]) < 3 * t.details[f"se_mean_square_{ax}_px2"]


def test_lsfe_c1_on_a_calibrated_camera_with_zero_residual():
    """The camera corrects its centroids with a cubic fitted without error to a pure cubic
    (r^2 radial) distortion: what it still does is nearly 0 (the truth, computed from the
    injected distortion and the camera's correction, no estimator; not exactly 0 because
    the correction is a cubic in the *measured* coordinates and the inverse of a cubic map
    is not a cubic: 1e-3 px here, its square 1e-6 px^2 is added to the tolerances below,
    far under the marker variance 9e-4 px^2). Then at W = 32 points with
    markers of sigma_m (new markers each trial) and temporal noise of variance v per point
    mean, dX = m + n are iid N(0, s^2 = sigma_m^2 + v) per axis, and:

    * eq 29 reports the cubic part of that noise: eq29^2 = |P_9 dX|^2 / (W - 1) with P_9
      the projection on the 9 non-constant cubic columns, so eq29^2 ~ s^2 chi2_9 / 31 and
      E = 9 s^2 / 31 (the marker floor, sqrt(9/31) x 0.5" = 0.27" for 0.5" markers); the
      mean of K trials has sd s^2 sqrt(2 x 9) / 31 / sqrt(K): checked within 4 of those;
    * the improved (remaining displacement) variance before clipping, s_dX^2 - sigma_m^2 -
      mean v_j, is unbiased for 0: its mean over K trials within 4 standard errors of 0.
    """
    from budget.starcam.truth import lsfe_c1_truth
    from budget.starcam.validate import trial_seeds

    scn = _scn(detector=QUIET, optics={"distortion": {"k1": 5e-3, "k2": 0.0}, "lateral_colour": NO_OPTICS["lateral_colour"],
                                       "distortion_correction": {"order": 3, "marker_error_3sigma_arcsec": 0.0,
                                                                 "centroid_noise_px": 0.0}},
               protocols=BASE["protocols"] | {"distortion": {"frames": 10}})
    cam = StarCamera(scn)
    t = lsfe_c1_truth(cam)
    t2 = max(t.x_px, t.y_px) ** 2
    assert t2 < 0.01 * (scn.lab.calibration_target.marker_error_3sigma_arcsec / 3 / scn.camera.scale_arcsec_per_px) ** 2
    ps = scn.camera.scale_arcsec_per_px
    m3 = scn.lab.calibration_target.marker_error_3sigma_arcsec
    k = 40
    pub2, imp2, s2 = [], [], []
    for i in range(k):
        ns, _, ms = trial_seeds(3, i)
        d = simulate(make_plan("distortion", scn), cam, seed=ns, marker_seed=ms)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = estimate("distortion", d.centroids, plate_scale_arcsec=ps, reference=d.reference,
                         marker_3sigma_arcsec=m3, camera_corrects_distortion=True)
        imp = r["improved"].details
        for ax in ("x", "y"):
            pub2.append(r["published"].details[f"sigma_d{ax}_px"] ** 2 - r["published"].details[f"sigma_dd{ax}_px"] ** 2)
            noise = imp[f"temporal_variance_of_means_{ax}_px2"]
            imp2.append(imp[f"sigma_d{ax}_px"] ** 2 - imp["marker_sigma_px"] ** 2 - noise)
            s2.append(imp["marker_sigma_px"] ** 2 + noise)
    pub2, imp2, s2 = map(np.array, (pub2, imp2, s2))
    w = len(d.reference)
    assert w == 32
    expect = 9 * s2.mean() / (w - 1)
    assert abs(pub2.mean() - expect) < 4 * s2.mean() * math.sqrt(2 * 9) / (w - 1) / math.sqrt(pub2.size) + t2
    assert abs(imp2.mean()) < 4 * imp2.std(ddof=1) / math.sqrt(imp2.size) + t2


def test_predictive_interval_coverage_within_binomial_limits():
    """The 95 % interval from the first half of the trials covers the second half's estimates
    at 95 % within binomial limits (99.9 % two-sided)."""
    scn = _scn(detector=QUIET, optics=NO_OPTICS)
    res = validate(scn, trials=80, seed=21)
    v = res.samples[("te", "published", "x")]
    lo, hi = np.quantile(v[:40], [0.025, 0.975])
    inside = int(np.sum((v[40:] >= lo) & (v[40:] <= hi)))
    # The interval's ends are np.quantile's interpolations between order statistics of the
    # first 40 draws: q(0.025) lies between X(1) and X(2), q(0.975) between X(39) and X(40)
    # (positions 0.975 and 38.025, 0-based). For exchangeable continuous draws the coverage
    # of [X(i), X(j)] is Beta(j - i, n + 1 - (j - i)) (Wilks 1962, sec. 11.4), so the count of
    # the next 40 draws inside is beta-binomial. The widest interval [X(1), X(40)] bounds
    # the count from above, the narrowest [X(2), X(39)] from below: 99.9 % two-sided limits.
    lo_k = stats.betabinom.ppf(0.0005, 40, 37, 41 - 37)
    hi_k = stats.betabinom.ppf(0.9995, 40, 39, 41 - 39)
    assert lo_k <= inside <= hi_k


def test_adaptive_stopping_reaches_the_tolerance(small):
    res = validate(small, tolerance=0.05, seed=2)
    assert res.stopped_by == "tolerance"
    for cls in res.summary().values():
        for ax in cls.values():
            for var in ax.values():
                assert var["se_bias"] <= 0.05 and var["se_std"] <= 0.05
    with pytest.raises(ValueError, match="give one of them"):
        validate(small, trials=4, tolerance=0.1)


def test_validate_cli_writes_json_and_report(tmp_path, small):
    from budget.cli import cli
    from simcam.starcam.scenario import scenario_to_toml

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
    """The seed-000 default (calibrated camera, lab with its own spectral model), 200
    trials: the improved TE is unbiased (|bias| within 4 standard errors of the mean and
    the truth combined); eq 29 on the calibrated camera reports the marker floor, above
    the camera's remaining displacement (bias significant and positive), while the
    improved C1's 95 % interval holds the truth; LSFE-C2 is an input."""
    res = validate(default(), trials=200, seed=1, workers=2)
    s = res.summary()
    for ax in ("x", "y"):
        te = s["te"][ax]["improved"]
        assert abs(te["bias"]) < 4 * te["se_bias"]
        c1 = s["lsfe_c1"][ax]
        assert c1["published"]["bias_significant"] and c1["published"]["bias"] > 0
        assert c1["improved"]["truth_in_95"]
        assert s["lsfe_c2"][ax]["published"]["role"] == "input"


def test_default_trial_count_comes_from_the_scenario():
    scn = _scn(validation=BASE["validation"] | {"trials": 3})
    res = validate(scn, seed=1)
    assert res.trials == 3 and res.stopped_by == "trials"
    scn = _scn(validation=BASE["validation"] | {"trials": 100, "tolerance": 0.2, "batch_trials": 10})
    res = validate(scn, seed=1)
    assert res.stopped_by == "tolerance" and res.trials < 100


def test_new_maps_per_trial_changes_trials_and_averages_the_hsfe_truth():
    scn = _scn(validation=BASE["validation"] | {"new_maps_per_trial": True})
    res = validate(scn, trials=2, seed=4)
    assert res.truths[("hsfe", "x")].details["map_realisations"] == 4
    fixed = validate(_scn(), trials=2, seed=4)
    assert res.samples[("hsfe", "published", "x")][1] != fixed.samples[("hsfe", "published", "x")][1]
