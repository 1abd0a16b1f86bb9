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
    # one camera's pixel maps for every trial (the run's TE and HSFE truths, which these tests
    # check against closed forms); the maps drawn per trial are tested where a test sets them
    "validation": {"te_truth_frames": 300, "hsfe_phase_grid": 3, "hsfe_truth_frames": 200, "field_grid": 5,
                   "batch_trials": 4, "new_maps_per_trial": False},
    # the ideal world: these tests check the lab's methods against closed forms;
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
    # sigma^2) ~ 1e-22 px (Poisson summation); what is left is the threshold's, which the
    # noise smooths but does not remove (a pixel's expected weight s Phi(z) + sigma phi(z) is
    # not linear in its signal): ~2e-4 px rms here, which the variance-reduced truth
    # resolves (a plain estimate of 20000 frames per phase agrees: 4.7e-8 +- 0.24e-8 px^2
    # against 4.2e-8 +- 0.04e-8). It must stay far below any pixel-phase error worth
    # measuring (the default camera's is 0.04 px): below 1e-3 px, by 3 of its standard errors.
    from budget.starcam.truth import hsfe_truth

    t = hsfe_truth(cam, frames=400, seed=7)
    for ax in ("x", "y"):
        assert getattr(t, f"{ax}_px") + 3 * getattr(t, f"se_{ax}_px") < 1e-3


def test_lsfe_c1_on_a_calibrated_camera_with_zero_residual():
    """The camera corrects its centroids with a cubic fitted without error to a pure cubic
    (r^2 radial) distortion: what it still does is nearly 0 (the truth, computed from the
    injected distortion and the camera's correction, no estimator; not exactly 0 because
    the correction is a cubic in the *measured* coordinates and the inverse of a cubic map
    is not a cubic: 1e-3 px over the grid's box, the truth's ``box_*`` detail, where the test's
    32 points are; its square 1e-6 px^2 is added to the tolerances below, far under the marker
    variance 9e-4 px^2; over the whole field, where the correction is extrapolated to the
    corners, 0.005 px). Then at W = 32 points with
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
    t2 = max(t.details["box_x_px"], t.details["box_y_px"]) ** 2
    assert max(t.x_px, t.y_px) ** 2 < 0.03 * (scn.lab.calibration_target.marker_error_3sigma_arcsec / 3
                                               / scn.camera.scale_arcsec_per_px) ** 2
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


def test_published_te_follows_the_c4_distribution_of_per_star_sds():
    """What is specific to the published TE (seed 000 eqs 1-2, the mean over W stars of each
    star's sd over N frames), with temporal noise alone: each s_j has (N - 1) s_j^2 /
    sigma_j^2 ~ chi2(N - 1), so E[s_j] = c4(N) sigma_j and Var[s_j] = (1 - c4^2) sigma_j^2
    (Gaussian centroid noise). The trials' estimates then have mean c4(N) sigma_bar (low by
    2.7 % for N = 10) and sd sqrt(sum_j (1 - c4^2) sigma_j^2) / W. sigma_bar is the
    truth's mean per-star sd from 3000 frames (its own c4(3000) = 0.99992 corrected).

    Checks, at this fixed seed: (a) the mean of K = 80 trials within 3 standard errors of
    c4(N) sigma_bar, the se combining the trials' sd / sqrt(K) and the truth's se (an
    unbiased-sd model, c4 = 1, is off by 2.7 %, about 6 of those standard errors here);
    (b) the fraction of trials inside the analytic central 95 % interval (normal: the mean
    of W = 25 near-chi variables) within 99.9 % binomial limits."""
    from budget.starcam.estimators import c4

    # 3000 truth frames: the truth's se (sigma_bar / sqrt(2 x 2999 x 25)) well under the bias
    scn = _scn(detector=QUIET, optics=NO_OPTICS, validation=BASE["validation"] | {"te_truth_frames": 3000})
    k = 80
    res = validate(scn, trials=k, seed=21)
    n = scn.protocols.te.frames
    truth = res.truths[("te", "x")]  # already in the study's unit
    sigma_bar = truth.value / c4(truth.details["frames"])
    w = truth.details["stars"]
    mean_pred = c4(n) * sigma_bar
    # the stars are alike (same magnitude; sigma_j differ by their pixel phase by a few %):
    # sum_j sigma_j^2 = W sigma_bar^2 to that order's square, < 0.1 % of the sd
    sd_pred = math.sqrt(1 - c4(n) ** 2) * sigma_bar / math.sqrt(w)
    v = res.samples[("te", "published", "x")]
    se = math.sqrt(v.var(ddof=1) / k + (truth.se / c4(truth.details["frames"])) ** 2)
    assert abs(v.mean() - mean_pred) < 3 * se, (v.mean(), mean_pred, se)
    assert abs(v.mean() - sigma_bar) > 3 * se  # the c4 bias is resolved at this size
    lo, hi = mean_pred - 1.96 * sd_pred, mean_pred + 1.96 * sd_pred
    inside = int(np.sum((v >= lo) & (v <= hi)))
    assert stats.binom.ppf(0.0005, k, 0.95) <= inside <= stats.binom.ppf(0.9995, k, 0.95), inside


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


def test_a_trials_hsfe_truth_is_unbiased_for_its_cameras_whole_grid_truth():
    """hsfe_trial_truth samples ``hsfe_trial_phases`` (4) of the grid's 9 phases without
    replacement (4 frames each, control variate): its mean square is unbiased for the mean
    square over the whole grid (simple random sampling, Cochran thm 2.1; the split-half
    product keeps each phase's unbiased). Against ``hsfe_truth`` of the same camera (all 9
    phases, 200 frames, independent streams), the mean over 40 independent draws of the
    sample's square must agree within 4 standard errors: that of the 40 draws' mean
    (their sample sd / sqrt(40), fixed seeds) and the full truth's own, in quadrature
    (false alarm below 1e-4 for a normal mean). The draws also scatter, so the sample is not
    the whole grid in disguise, and each draw's phases are 4 distinct grid phases."""
    from budget.starcam.truth import hsfe_trial_phases, hsfe_trial_truth, hsfe_truth

    scn = _scn(detector={"prnu_rms": 0.03})
    cam = STUDY.prepared(scn).instrument(2, 0)
    full = hsfe_truth(cam, frames=scn.validation.hsfe_truth_frames, seed=77)
    draws = [hsfe_trial_truth(cam, seed=1000 + j) for j in range(40)]
    for ax in ("x", "y"):
        sq = np.array([getattr(d, f"{ax}_px") ** 2 for d in draws])
        f2 = getattr(full, f"{ax}_px") ** 2
        se = math.hypot(sq.std(ddof=1) / math.sqrt(sq.size), 2 * getattr(full, f"{ax}_px") * getattr(full, f"se_{ax}_px"))
        assert abs(sq.mean() - f2) < 4 * se, (ax, sq.mean(), f2, se)
        assert sq.std(ddof=1) > 0.01 * f2
    for j in range(5):
        ph = hsfe_trial_phases(scn, 1000 + j)
        assert ph.size == scn.validation.hsfe_trial_phases == len(set(ph.tolist()))
        assert ph.min() >= 0 and ph.max() < scn.validation.hsfe_phase_grid**2


def test_a_trials_te_truth_is_unbiased_for_its_cameras_truth():
    """te_trial_truth takes 50 frames (control variate) where the run's TE truth takes
    te_truth_frames (here 3000): each star's variance estimate is unbiased whatever the
    frames, and the square root's bias is below 1e-4 of the truth at 50 (docstring), so over
    30 independent draws the mean agrees with the 3000-frame truth of the same camera within
    4 standard errors (the draws' sd / sqrt(30) and the long truth's own, in quadrature;
    fixed seeds)."""
    from budget.starcam.truth import TRIAL_TE_FRAMES, te_trial_truth, te_truth

    scn = _scn(detector={"prnu_rms": 0.03})
    cam = STUDY.prepared(scn).instrument(2, 0)
    long = te_truth(cam, frames=3000, seed=91, cramer_rao=False)
    draws = [te_trial_truth(cam, seed=2000 + j) for j in range(30)]
    assert draws[0].details["frames"] == TRIAL_TE_FRAMES and "cramer_rao_x_px" not in draws[0].details
    for ax in ("x", "y"):
        v = np.array([getattr(d, f"{ax}_px") for d in draws])
        se = math.hypot(v.std(ddof=1) / math.sqrt(v.size), getattr(long, f"se_{ax}_px"))
        assert abs(v.mean() - getattr(long, f"{ax}_px")) < 4 * se, (ax, v.mean(), getattr(long, f"{ax}_px"), se)


def test_hsfe_trial_phases_cannot_exceed_the_grid():
    with pytest.raises(Exception, match="hsfe_trial_phases: 10 is more than the 9 phases"):
        _scn(validation=BASE["validation"] | {"hsfe_trial_phases": 10})


def test_new_maps_per_trial_hsfe_truth_follows_the_prnu_statistics():
    """New PRNU maps per trial, PRNU alone (no DSNU, a wide Gaussian PSF: no pixel-phase
    error): each map's HSFE truth is the rms static centroid error its PRNU makes.
    Centre of gravity with gains 1 + eps_i, eps_i iid N(0, p^2): dx = sum_i (x_i - x_c) I_i
    eps_i / sum_i I_i to first order, so Var dx = p^2 sum_i (x_i - x_c)^2 I_i^2 / (sum I)^2
    = p^2 / (8 pi) for a Gaussian image of any width (int x^2 g^2 = 1 / (8 pi) for the
    unit-integral 2-D Gaussian; pixel sums of the sampled sigma = 1.6 px Gaussian give the
    same to 2e-4), and removing the common motion of W stars leaves (W - 1) / W of it. So
    each map and axis gives h^2 ~ (p^2 / (8 pi)) chi2(W - 1) / W, independent between maps
    (new pixels) and between axes (x and y weights are uncorrelated by symmetry).

    Checks at this fixed seed (p = 0.05, W = 25, 4 maps x 2 axes = 8 values of h^2):
    * their mean over p^2 (W - 1) / (8 pi W): relative sd sqrt(2 / (8 (W - 1))) = 0.10;
      3 of those, plus 0.10 for what the model leaves out (the pinhole's finite image and
      the centroid threshold make the image not a pure Gaussian; measured over seeds 4-7:
      ratio 0.98-1.20, mean 1.12): within 0.41 of 1;
    * their spread between maps: per axis the sample variance of 4 values of relative
      variance 2 / (W - 1), pooled over the axes, is a chi2(6) / 6 multiple of it: relative
      sd of h^2 between 0.073 and 0.56 (99.8 %); with the same maps in every trial it
      would be the frame noise's ~1 % (the behaviour this option changes).
    * the run's truths have no TE or HSFE (each trial's camera has its own), and each trial
      returns its camera's, :func:`budget.starcam.truth.hsfe_trial_truth` and
      :func:`budget.starcam.truth.te_trial_truth` with the trial's streams."""
    from budget.starcam import validate as V
    from budget.starcam.truth import hsfe_trial_truth, hsfe_truth, te_trial_truth

    p = 0.05
    scn = _scn(detector={"prnu_rms": p, "dsnu_rms_e": 0.0},
               optics=NO_OPTICS | {"psf": {"sigma0_px": 1.6, "sigma_r2_px": 0.0}},
               validation=BASE["validation"] | {"new_maps_per_trial": True})
    seed = 4
    assert V.truth_parts(scn, seed=seed) == [("rest",)]
    setup = STUDY.prepared(scn)
    per_map = [hsfe_truth(setup.instrument(seed, m), frames=scn.validation.hsfe_truth_frames, seed=40 + m)
               for m in range(4)]
    w = per_map[0].details["stars"]
    h2 = np.array([[h.x_px**2, h.y_px**2] for h in per_map]).ravel()
    pred = p**2 / (8 * math.pi) * (w - 1) / w
    assert abs(h2.mean() / pred - 1) < 3 * math.sqrt(2 / (8 * (w - 1))) + 0.10, h2.mean() / pred
    # spread between maps, per axis (x and y of one map differ by that map's pixels too,
    # so only the maps are compared): the pooled relative variance of the 4 maps' h^2 of
    # each axis, 2 x 3 degrees of freedom
    by_axis = h2.reshape(4, 2)
    rel_sd = math.sqrt(np.mean(by_axis.var(axis=0, ddof=1) / by_axis.mean(axis=0) ** 2))
    expect = math.sqrt(2 / (w - 1))
    lo, hi = (expect * math.sqrt(stats.chi2.ppf(q, 6) / 6) for q in (0.001, 0.999))
    assert lo <= rel_sd <= hi, (rel_sd, lo, hi)
    assert not {"te", "hsfe"} & set(V.truths(scn, seed=seed, setup=setup))
    got = V.run_trial(scn, seed, 2, setup=setup)["truths"]
    own = {"hsfe": hsfe_trial_truth(setup.instrument(seed, 2), seed=V.trial_truth_seed(seed, 2, "hsfe")),
           "te": te_trial_truth(setup.instrument(seed, 2), seed=V.trial_truth_seed(seed, 2, "te"))}
    for cls, t in own.items():
        for var in V.VARIANTS:
            assert (got[(cls, var, "x")], got[(cls, var, "y")]) == (t.x_px, t.y_px)
