"""The star camera's protocol planning hooks (StarCameraStudy.protocol_knobs, protocol_shapes,
lab_time_s) and the HSFE grid step pattern (protocols.hsfe.pattern = "grid")."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from budget.starcam.study import STUDY
from simcam.infra.errors import ScenarioError
from simcam.config_base import read_toml
from simcam.starcam.scenario import default, with_updates


# ------------------------------------------------------------------ lab time
def test_lab_time_of_the_default_protocol_by_hand():
    """The seed-000 protocol counted by hand from the embedded scenario's values (0.1 s
    exposure + 0.05 s readout; move 2 s, filter 2 s, settle 8 s; setup 300 s x 4; warm-up 900 s)."""
    lt = STUDY.lab_time_s(default())
    frame = 0.1 + 0.05
    assert lt["te.frames"] == pytest.approx(30 * frame, rel=1e-12)
    assert lt["hsfe.frames"] == pytest.approx(12 * 30 * frame, rel=1e-12)
    # 11 moves between the 12 poses, each a move and its settling
    assert lt["hsfe.changes"] == pytest.approx(11 * (2.0 + 8.0), rel=1e-12)
    # 4 fields x 3 filters; in each field 2 filter changes (500 -> 600 -> 800); between
    # fields 3 moves, each with the filter back to 500 nm (one settling for both)
    assert lt["chromatic.frames"] == pytest.approx(4 * 3 * 30 * frame, rel=1e-12)
    assert lt["chromatic.changes"] == pytest.approx(4 * 2 * (2.0 + 8.0) + 3 * (2.0 + 2.0 + 8.0), rel=1e-12)
    assert lt["distortion.frames"] == pytest.approx(30 * frame, rel=1e-12)
    assert lt["dark_frames"] == 0.0
    assert lt["setup"] == 4 * 300.0 and lt["warmup"] == 900.0
    assert sum(lt.values()) == pytest.approx(4.5 + 54 + 110 + 54 + 116 + 4.5 + 1200 + 900, rel=1e-12)


def test_lab_time_of_the_grid_pattern_and_dark_frames_by_hand():
    scn = with_updates(default(), {"protocols.hsfe.pattern": "grid", "protocols.hsfe.conditions": 16,
                                   "protocols.hsfe.frames": 10, "validation.dark_frames": 5,
                                   "camera.exposure_s": 0.2, "protocols.timing.hexapod_move_s": 3.0})
    lt = STUDY.lab_time_s(scn)
    frame = 0.2 + 0.05
    assert lt["hsfe.frames"] == pytest.approx(16 * 10 * frame, rel=1e-12)
    assert lt["hsfe.changes"] == pytest.approx(15 * (3.0 + 8.0), rel=1e-12)   # 16 poses, 15 moves
    # conditions: TE 1, HSFE 16, chromatic 12, distortion 1; each K dark frames and a shutter cycle
    assert lt["dark_frames"] == pytest.approx((1 + 16 + 12 + 1) * (5 * frame + 2.0), rel=1e-12)


# ------------------------------------------------------------------ knobs and shapes
def test_knobs_and_shapes_are_scenario_fields_the_sweeps_can_set():
    from simcam.dotted import set_dotted

    base = default()
    resolved = base.model_dump(mode="python")
    for shape, keys in STUDY.protocol_shapes(base).items():
        raw: dict = {}
        for k, v in keys.items():
            set_dotted(raw, resolved, k, v, where="t")
        shaped = STUDY.from_dict(copy.deepcopy(raw), source="t")
        # names: "<pattern>, filters <centres>" (the default plan opens both tests)
        pattern, filters = shape.split(", filters ")
        assert shaped.protocols.hsfe.pattern == pattern
        assert "/".join(f"{f:g}" for f in shaped.chromatic_filters_nm()) == filters
        knobs = STUDY.protocol_knobs(shaped)
        # the same knobs in every shape (the planner searches each shape over the base's knobs)
        assert knobs == STUDY.protocol_knobs(base)
        for kb in knobs:
            assert kb.kind == "int" and kb.low <= kb.high
            for v in (int(kb.low), int(kb.high)):
                r = copy.deepcopy(raw)
                set_dotted(r, resolved, kb.field, v, where="t")
                s = STUDY.from_dict(r, source="t")
                STUDY.check(s, where="t")
                node = s
                for part in kb.field.split("."):
                    node = getattr(node, part)
                assert node == v
                # every knob costs lab time (none is free, or the planner would max it out)
                assert sum(STUDY.lab_time_s(s).values()) > 0


def test_plan_knobs_name_the_counts_a_plan_may_change():
    full = [k.field for k in STUDY.protocol_knobs(default())]
    assert full == ["protocols.te.frames", "protocols.hsfe.frames", "protocols.hsfe.conditions",
                    "protocols.chromatic.frames", "protocols.distortion.frames", "validation.dark_frames"]
    s = with_updates(default(), {"protocols.plan_knobs": ["hsfe.poses", "hsfe.frames"]})
    assert [k.field for k in STUDY.protocol_knobs(s)] == ["protocols.hsfe.conditions", "protocols.hsfe.frames"]
    g = with_updates(s, {"protocols.hsfe.pattern": "grid"})
    assert STUDY.protocol_knobs(g) == STUDY.protocol_knobs(s)
    with pytest.raises(ScenarioError, match=r"protocols\.plan_knobs"):
        with_updates(default(), {"protocols.plan_knobs": ["hsfe.frames", "hsfe.frames"]})
    with pytest.raises(ScenarioError, match=r"protocols\.plan_knobs"):
        with_updates(default(), {"protocols.plan_knobs": ["hsfe.pose"]})


def test_a_wrong_pattern_is_one_error_naming_the_field():
    with pytest.raises(ScenarioError, match=r"protocols\.hsfe\.pattern"):
        with_updates(default(), {"protocols.hsfe.pattern": "spiral"})


# ------------------------------------------------------------------ the grid pattern
def test_default_diagonal_poses_are_seed_000s():
    from budget.starcam.protocols import make_plan

    plan = make_plan("hsfe", default())
    d = 0.2 / math.sqrt(2.0)
    assert len(plan.conditions) == 12
    for k, c in enumerate(plan.conditions):
        assert c.platform_dx_px == pytest.approx(k * d, abs=1e-12)
        assert c.platform_dy_px == pytest.approx(k * d, abs=1e-12)


@pytest.mark.parametrize("m", [2, 3, 5, 12, 25, 48])
def test_grid_poses_span_pixels_and_phases_in_both_axes(m):
    """M poses, pitch 1 + 1/M px, one in each column and row: per axis M different pixels at
    phases k/M (uniform over the pixel); the world points where the plan says."""
    from budget.starcam.protocols import make_plan
    from simcam.starcam.world import commanded_pointing_px

    scn = with_updates(default(), {"protocols.hsfe.pattern": "grid", "protocols.hsfe.conditions": m})
    plan = make_plan("hsfe", scn)
    xy = np.array([(c.platform_dx_px, c.platform_dy_px) for c in plan.conditions])
    assert xy.shape == (m, 2) and np.all(xy[0] == 0.0)
    step = 1.0 + 1.0 / m
    for ax in (0, 1):
        cells = np.round(xy[:, ax] / step, 9)
        np.testing.assert_array_equal(np.sort(cells), np.arange(m))           # one pose per row / column
        assert np.unique(np.floor(xy[:, ax] + 1e-9)).size == m                 # m different pixels
        phases = np.sort(np.round(np.mod(xy[:, ax], 1.0), 9) % 1.0)
        np.testing.assert_allclose(phases, np.arange(m) / m, atol=1e-9)        # phases k/M
    a = scn.protocols.hsfe.grid_multiplier
    assert math.gcd(a, m) == 1 and abs(a - m / ((1 + 5**0.5) / 2)) < 1.5
    cu, cv = scn.lab.target_center_px
    pts = commanded_pointing_px(scn)
    for k, (dx, dy) in enumerate(xy):
        assert pts[("hsfe", k)] == pytest.approx((cu + dx, cv + dy), abs=1e-12)
    # an explicit pitch is kept
    s2 = with_updates(scn, {"protocols.hsfe.grid_step_px": 0.5})
    xy2 = np.array([(c.platform_dx_px, c.platform_dy_px) for c in make_plan("hsfe", s2).conditions])
    assert xy2[:, 0].max() == pytest.approx(0.5 * (m - 1))


def _pixel_dominated_tiny(pattern: str) -> dict:
    """The tiny camera (tests/tiny_camera.py) with seed 000's own pixel errors (12 % PRNU,
    11 e- DSNU) on the default bright source, so the static pixel error dominates the
    temporal noise; ideal world; new PRNU/DSNU maps in every trial (the truth then averages
    4 map realisations, the trials sample the maps as the estimator does)."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from tiny_camera import TINY

    d = read_toml(text=TINY, source="tiny")
    d["detector"].update(prnu_rms=0.12, dsnu_rms_e=11.0)
    d["world"] = {"effects": {k: 0.0 for k in (
        "distortion_r5_px_at_corner", "distortion_r7_px_at_corner", "nonlinearity_beta",
        "hexapod_repeatability_arcsec", "hexapod_backlash_arcsec", "drift_rate_arcsec_per_h",
        "drift_random_arcsec")}}
    d["validation"].update(new_maps_per_trial=True, hsfe_phase_grid=4, hsfe_truth_frames=200)
    d["protocols"]["hsfe"].update(frames=10, conditions=12, pattern=pattern)
    return d


def test_grid_pattern_recovers_the_hsfe_truth_where_the_diagonal_sees_part():
    """Pixel errors dominate: the improved (static) HSFE estimator on seed 000's diagonal (12
    poses 0.2 px apart) recovers about two thirds of the truth; on the grid pattern with as many
    poses (pitch 1 + 1/12 px, one pose in each row and column) it recovers the truth. Each
    trial's camera draws its pixel maps, and its HSFE truth is its own (run_trial's route:
    hsfe_trial_truth with the trial's truth stream, the same for both patterns). Fixed seed 0,
    16 trials; tolerance 3 standard errors of the mean per-trial error (its sd / sqrt(16),
    which holds the trial truth's own scatter). The HSFE protocol is run alone, through the
    same make_plan / simulate / estimate calls as a validation trial
    (budget.starcam.validate.run_trial)."""
    from budget.starcam import validate as V
    from budget.starcam.protocols import estimate, make_plan, simulate
    from budget.starcam.truth import hsfe_trial_truth

    scns = {p: STUDY.from_dict(_pixel_dominated_tiny(p), source="t") for p in ("diagonal", "grid")}
    from budget.runner.study import truth_identity

    # the truth does not depend on the pattern (sub-pixel phases at the first pose), and the
    # study says so (a sweep or a plan over the patterns shares it)
    assert truth_identity(STUDY, scns["grid"]) == truth_identity(STUDY, scns["diagonal"])
    trials = 16
    setup = STUDY.prepared(scns["diagonal"])
    truths = []
    for k in range(trials):
        t = hsfe_trial_truth(setup.instrument(0, k), seed=V.trial_truth_seed(0, k, "hsfe"))
        truths.append((t.x_px, t.y_px))
    truths = np.array(truths)
    for p, scn in scns.items():
        est = []
        for k in range(trials):
            noise_seed, _, _ = V.trial_seeds(0, k)
            cam = STUDY.prepared(scn).instrument(0, k)
            data = simulate(make_plan("hsfe", scn, seed=noise_seed), cam, seed=noise_seed)
            r = estimate("hsfe", data.centroids, plate_scale_arcsec=5.5, extra_variants=False)["improved"]
            est.append((r.sigma_x_px, r.sigma_y_px))
        e = np.array(est) - truths
        for i, ax in enumerate(("x", "y")):
            m, tol = e[:, i].mean(), 3.0 * e[:, i].std(ddof=1) / math.sqrt(trials)
            t = truths[:, i].mean()
            if p == "grid":
                assert abs(m) <= tol, (ax, p, m, t, tol)
            else:
                assert -m > tol and (t + m) / t < 0.8, (ax, p, m, t, tol)


# ------------------------------------------------------------------ the planner's answer on seed 000
#: what ``budget starcam plan docs/examples/scenarios/plan_hsfe.toml --require 'hsfe.x<=0.01'
#: --require 'hsfe.y<=0.01' --trials 60`` (seed 0, ``--sure 0.9``) recommends, re-validated by the
#: plan itself on 60 fresh trials (docs/validation.md, "Planning the test"): the grid, 3 poses x
#: 106 frames
RECOMMENDED = {"protocols.hsfe.pattern": "grid", "protocols.hsfe.conditions": 3, "protocols.hsfe.frames": 106}
#: seed 000's own counts (12 poses x 30 frames) on the grid: measured feasible in the plan's search too
PAPER_COUNTS_ON_GRID = {"protocols.hsfe.pattern": "grid", "protocols.hsfe.conditions": 12, "protocols.hsfe.frames": 30}
#: the boundary protocol of an earlier plan run with 20 trials a validation and no --sure margin
#: (grid 3 x 41): its own re-validation did not confirm it
BOUNDARY_20_TRIALS = {"protocols.hsfe.pattern": "grid", "protocols.hsfe.conditions": 3, "protocols.hsfe.frames": 41}
REQUIRED_ARCSEC = 0.01
CONFIDENCE = 0.95


def _planned(protocol: dict):
    from pathlib import Path

    scn = STUDY.load_scenario(str(Path(__file__).parents[1] / "docs/examples/scenarios/plan_hsfe.toml"))
    return with_updates(scn, protocol)


def _allowed_exceedances(n: int) -> int:
    """The planner's criterion: the C-quantile of n errors (order statistic ceil(C n)) within
    the bound, i.e. at most n - ceil(C n) of them beyond it."""
    return n - math.ceil(CONFIDENCE * n - 1e-9)


def _hsfe_exceedances(protocol: dict, n: int) -> np.ndarray:
    """Trials (of ``n``, run seed 7919, which no plan used) whose improved HSFE estimate is more
    than 0.01" (3 sigma) from the truth, per axis: the HSFE protocol alone, through the same
    make_plan / simulate / estimate calls as a validation trial; the truth from 400 noisy
    frames per sub-pixel phase (truth seed 7; standard error 0.0003", a thirtieth of the bound)."""
    from budget.starcam import validate as V
    from budget.starcam.protocols import estimate, make_plan, simulate
    from budget.starcam.truth import hsfe_truth

    scn = _planned(protocol)
    f = 3.0 * scn.camera.scale_arcsec_per_px
    cam = STUDY.prepared(scn).camera()
    truth = hsfe_truth(cam, frames=400, seed=7)
    assert max(truth.se_x_px, truth.se_y_px) * f < REQUIRED_ARCSEC / 20
    err = []
    for k in range(n):
        noise_seed, _, _ = V.trial_seeds(7919, k)
        data = simulate(make_plan("hsfe", scn, seed=noise_seed), cam, seed=noise_seed)
        r = estimate("hsfe", data.centroids, plate_scale_arcsec=scn.camera.scale_arcsec_per_px,
                     extra_variants=False)["improved"]
        err.append(((r.sigma_x_px - truth.x_px) * f, (r.sigma_y_px - truth.y_px) * f))
    return (np.abs(np.array(err)) > REQUIRED_ARCSEC).sum(axis=0)


def test_the_planners_protocol_meets_the_requirement_on_20_new_seeds():
    """The fast twin of the 100-trial test below (``slow``): the plan's answer (grid 3 x 106) on
    the first 20 of those fresh trials. A protocol meeting the planner's criterion has at most a
    5 % exceedance rate per axis; more than 3 of 20 beyond 0.01" happens to such a protocol with
    probability below 0.016 (binomial tail, asserted), so that is the fixed-seed test."""
    from scipy import stats

    n, most = 20, 3
    assert stats.binom.sf(most, n, 1 - CONFIDENCE) < 0.016
    assert np.all(_hsfe_exceedances(RECOMMENDED, n) <= most)


@pytest.mark.slow
def test_the_planners_protocol_meets_the_requirement_on_new_seeds():
    """Seed 000 (the default camera, ideal world), 100 trials on seeds no plan used (run seed
    7919). The plan's answer (grid 3 x 106, aimed 90 % sure) meets the bound on them: at most
    5 of 100 beyond 0.01" per axis (the 95 % quantile of |error| within it), as does seed 000's
    own 12 x 30 on the grid. The boundary answer of a 20-trial plan without the margin (3 x 41)
    does not: the margin is what makes the answer hold on new seeds."""
    n = 100
    allowed = _allowed_exceedances(n)
    assert np.all(_hsfe_exceedances(RECOMMENDED, n) <= allowed)
    assert np.all(_hsfe_exceedances(PAPER_COUNTS_ON_GRID, n) <= allowed)
    assert np.any(_hsfe_exceedances(BOUNDARY_20_TRIALS, n) > allowed)


@pytest.mark.slow
def test_the_planners_protocol_meets_the_requirement_in_full_validations():
    """The plan's answer (grid 3 x 106) through the runner: every protocol, the study's own
    truths, 200 trials on a seed no plan used."""
    from budget.runner.run import run_study

    n = 200
    res = run_study(STUDY, _planned(RECOMMENDED), trials=n, seed=7919, workers=2)
    for ax in ("x", "y"):
        e = np.asarray(res.samples[("hsfe", "improved", ax)]) - res.truths[("hsfe", ax)].value
        assert (np.abs(e) > REQUIRED_ARCSEC).sum() <= _allowed_exceedances(n), ax


# ------------------------------------------------------------------ the chromatic test's filter sets
#: what ``budget starcam plan docs/examples/scenarios/plan_chromatic.toml --require 'lsfe_s.x<=0.05'
#: --require 'lsfe_s.y<=0.05' --trials 40 --workers 2`` (seed 0, ``--sure 0.9``) recommends
#: (docs/validation.md, "Planning the test"): filters 600/800, 3 frames per field and filter
CHROMATIC_RECOMMENDED = {"protocols.chromatic.filters_nm": [600.0, 800.0], "protocols.chromatic.frames": 3}
CHROMATIC_BOUND_ARCSEC = 0.05


def _lsfe_s_exceedances(protocol: dict, n: int) -> np.ndarray:
    """Trials (of ``n``, run seed 7919, which no plan used) whose improved LSFE-S estimate is
    more than 0.05" (3 sigma) from the truth (exact), per axis: the example scenario (ideal
    world, the chromatic test alone) through the validation's own trial."""
    from pathlib import Path

    from budget.starcam import validate as V

    scn = with_updates(STUDY.load_scenario(str(Path(__file__).parents[1]
                                               / "docs/examples/scenarios/plan_chromatic.toml")), protocol)
    f = 3.0 * scn.camera.scale_arcsec_per_px
    t = V.truths(scn, seed=7919)["lsfe_s"]
    err = [[V.run_trial(scn, 7919, k)["values"][("lsfe_s", "improved", ax)] * f - getattr(t, f"{ax}_px") * f
            for ax in ("x", "y")] for k in range(n)]
    return (np.abs(np.array(err)) > CHROMATIC_BOUND_ARCSEC).sum(axis=0)


def test_the_chromatic_plan_holds_and_a_close_pair_misses_far_on_20_new_seeds():
    """The fast twin of the 100-trial test below (``slow``), on its first 20 trials: the plan's
    answer (filters 600/800 x 3 frames) has at most 3 of 20 beyond 0.05" per axis (a protocol
    meeting the criterion exceeds that with probability below 0.016, binomial tail); the 500/600
    pair misses far: at least 10 of 20 on y, which a protocol at a 5 % rate gives with
    probability below 1e-7."""
    from scipy import stats

    n, most, far = 20, 3, 10
    assert stats.binom.sf(most, n, 1 - CONFIDENCE) < 0.016 and stats.binom.sf(far - 1, n, 1 - CONFIDENCE) < 1e-7
    assert np.all(_lsfe_s_exceedances(CHROMATIC_RECOMMENDED, n) <= most)
    assert _lsfe_s_exceedances({"protocols.chromatic.filters_nm": [500.0, 600.0]}, n)[1] >= far


@pytest.mark.slow
def test_the_chromatic_plan_meets_the_requirement_on_new_seeds():
    """100 trials on seeds no plan used: the plan's answer (filters 600/800 x 3 frames) and seed
    000's own test (3 filters x 30 frames) each have at most 5 of 100 beyond 0.05" per axis (the
    95 % quantile of |error| within the bound, the planner's criterion); the 500/600 pair at seed
    000's 30 frames does not, by far (its y estimate reads the static centroid difference between
    two close filters as a slope, about 0.15" off: docs/validation.md, "Planning the test"; more
    than 5 of 100 beyond is what a protocol whose true exceedance rate were 5 % gives with
    probability 0.38, so only the far miss is asserted: at least 50, which such a protocol gives
    with probability below 1e-25)."""
    from scipy import stats

    n = 100
    allowed = _allowed_exceedances(n)
    assert np.all(_lsfe_s_exceedances(CHROMATIC_RECOMMENDED, n) <= allowed)
    assert np.all(_lsfe_s_exceedances({}, n) <= allowed)
    far = n // 2
    assert stats.binom.sf(far - 1, n, 1 - CONFIDENCE) < 1e-25
    assert _lsfe_s_exceedances({"protocols.chromatic.filters_nm": [500.0, 600.0]}, n)[1] >= far


def test_a_plan_searches_every_filter_set_and_recommends_the_cheapest():
    """The planner on the small test camera (tests/tiny_camera.py, ideal world, the chromatic
    test alone in two of its fields, two filter sets given, seed 0, 20 trials a validation, a
    loose bound: kept small, the search reaches 300 frames): each filter set is a shape
    searched on its own, the recommendation is the cheapest shape's best protocol, and its
    cost is the study's lab time of that protocol."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from tiny_camera import TINY

    from budget.runner.plan import plan_protocol

    d = read_toml(text=TINY, source="tiny")
    d["protocols"]["plan_knobs"] = ["chromatic.frames"]
    d["validation"]["protocols"] = ["chromatic"]
    d["protocols"]["chromatic"].update(field_centers_px=[[-150.0, -60.0], [150.0, 60.0]],
                                       field_names=["upper-left", "lower-right"],
                                       plan_filter_sets=[[500.0, 600.0], [500.0, 600.0, 800.0]])
    d["world"] = {"effects": {k: 0.0 for k in (
        "distortion_r5_px_at_corner", "distortion_r7_px_at_corner", "nonlinearity_beta",
        "hexapod_repeatability_arcsec", "hexapod_backlash_arcsec", "drift_rate_arcsec_per_h",
        "drift_random_arcsec")}}
    scn = STUDY.from_dict(d, source="tiny")
    res = plan_protocol(STUDY, scn, ["lsfe_s.x<=0.5"], trials=20, seed=0, workers=1)
    assert set(res.shapes) == {"filters 500/600", "filters 500/600/800"}
    bests = {k: v.best for k, v in res.shapes.items() if v.best is not None}
    assert res.recommended is not None and bests
    assert res.recommended.cost_s == min(b.cost_s for b in bests.values())
    rec = with_updates(scn, {**res.recommended.knobs,
                             **STUDY.protocol_shapes(scn)[res.recommended.shape]})
    assert res.recommended.cost_s == pytest.approx(sum(STUDY.lab_time_s(rec).values()), rel=1e-12)


# ------------------------------------------------------------------ separable plans: the field classes
#: the ideal world: every world effect off (docs/validation.md, "What its claim survives")
_IDEAL = {f"world.effects.{e}": 0.0 for e in (
    "distortion_r5_px_at_corner", "distortion_r7_px_at_corner", "nonlinearity_beta",
    "hexapod_repeatability_arcsec", "hexapod_backlash_arcsec", "drift_rate_arcsec_per_h", "drift_random_arcsec")}
#: a value other than the default's for every plannable field but the dark frames (which change every class)
_CHANGED = {"protocols.te.frames": 7, "protocols.hsfe.frames": 9, "protocols.hsfe.conditions": 5,
            "protocols.hsfe.pattern": "grid", "protocols.chromatic.frames": 4,
            "protocols.chromatic.filters_nm": [600.0, 800.0], "protocols.distortion.frames": 6}


def _changed_classes(scn, field: str, seed: int = 11, k: int = 2) -> set[str]:
    """The classes whose trial values (every variant and axis, trial ``k`` of run seed
    ``seed``) change when ``field`` takes its :data:`_CHANGED` value."""
    from budget.starcam import validate as V

    base = V.run_trial(scn, seed, k)["values"]
    other = V.run_trial(with_updates(scn, {field: _CHANGED[field]}), seed, k)["values"]
    assert set(other) == set(base)
    return {key[0] for key in base if other[key] != base[key]}


def test_each_plannable_field_changes_only_its_declared_classes_in_the_ideal_world():
    """The default camera in the ideal world (run seed 11, trial 2): each plannable field moves
    exactly the classes StarCameraStudy.field_classes declares for it, the others bit for bit
    the same, and no truth (the protocols' fields are among those no truth reads): the
    separable plan's groups are independent there."""
    from budget.runner.study import truth_identity

    scn = with_updates(default(), _IDEAL)
    fc = STUDY.field_classes(scn)
    assert set(_CHANGED) | {"validation.dark_frames", "lab.calibration_target.extent_fraction"} == set(fc)
    assert set(fc["validation.dark_frames"]) == {c.name for c in STUDY.classes(scn)}
    for field in _CHANGED:
        assert _changed_classes(scn, field) == set(fc[field]), field
        assert truth_identity(STUDY, with_updates(scn, {field: _CHANGED[field]})) == truth_identity(STUDY, scn)


def test_in_the_realistic_world_a_count_moves_the_later_protocols_draws():
    """The default (realistic) world, run seed 11, trial 2: the world's drift and hexapod follow
    the lab run's timeline (TE, HSFE, chromatic, distortion; simcam.starcam.world), so a count of
    one protocol also moves the trial values of every protocol after it (their drift and pose
    draws shift), never of one before it; field_classes leaves this out (StarCameraStudy.field_classes).
    A separable plan searches each group with the other groups' counts at the scenario's values,
    so its union's figures are not the groups' search figures: the union's re-validation, which
    runs the whole protocol on fresh seeds, is what measures it
    (tests/test_plan_separable.py::test_the_re_validation_runs_the_union_as_one_protocol)."""
    from simcam.starcam.world import RUN_ORDER

    own = {"te": {"te"}, "hsfe": {"hsfe"}, "chromatic": {"lsfe_s"}, "distortion": {"lsfe_c1"}}
    scn = default()
    fc = STUDY.field_classes(scn)
    for field in ("protocols.te.frames", "protocols.hsfe.conditions", "protocols.chromatic.frames",
                  "protocols.distortion.frames"):
        proto = field.split(".")[1]
        later = set().union(*(own[p] for p in RUN_ORDER[RUN_ORDER.index(proto) + 1:]))
        changed = _changed_classes(scn, field)
        # its own classes, and (a count adds frames or moves to the timeline) every later protocol's
        assert changed - {"lsfe", "total"} == own[proto] | later, field
        # the declared classes cover it only where no protocol follows (the distortion test, last)
        assert (changed <= set(fc[field])) == (not later), field


def test_a_separable_plan_keeps_the_scenarios_filter_set_where_no_requirement_depends_on_it():
    """The default scenario with only hsfe.x required: one group (the HSFE counts, its pattern,
    the dark frames), whose "grid" stands for the three declared grid shapes; its answer put in
    one protocol keeps the scenario's filter set (its empty filters_nm: every lab filter,
    500/600/800), as an unsearched knob keeps its value, not the cheapest set: 500/600 and
    600/800 cost the same, and 500/600 misreads LSFE-S y about five times (docs/validation.md)."""
    from budget.runner.plan import Evaluation, PlanRun, decompose, parse_requirements, union_protocol

    scn = default()
    reqs, variant = parse_requirements(STUDY, scn, ["hsfe.x<=0.01"])
    knobs = STUDY.protocol_knobs(scn)
    declared = STUDY.protocol_shapes(scn)
    groups, _ = decompose(STUDY, scn, reqs, knobs, declared)
    assert [g.name for g in groups] == ["hsfe"] and list(groups[0].shapes) == ["diagonal", "grid"]
    members = groups[0].members["grid"]
    assert members == ["grid, filters 500/600", "grid, filters 600/800", "grid, filters 500/600/800"]
    cost = {m: sum(STUDY.lab_time_s(with_updates(scn, declared[m])).values()) for m in members}
    assert cost["grid, filters 500/600"] == cost["grid, filters 600/800"] < cost["grid, filters 500/600/800"]
    part = Evaluation("grid", {"protocols.hsfe.frames": 30, "protocols.hsfe.conditions": 12}, 0.0, {}, 0, 60, {},
                      "search")
    run = PlanRun(STUDY, scn, reqs, variant, 0.95, None, None, 0, 60, 1, False, None, knobs, 0.9, {}, 0.0, 0.0)
    union = union_protocol(run, declared, groups, [part], False)
    assert union.shape == "grid, filters 500/600/800"
    assert union.scenario.chromatic_filters_nm() == (500.0, 600.0, 800.0)
    assert union.scenario.protocols.hsfe.pattern == "grid"
    assert union.cost_s == cost["grid, filters 500/600/800"]


def test_requiring_a_class_the_scenario_does_not_compute_names_the_field():
    """validation.protocols = ["chromatic"]: TE is a star-camera class this scenario leaves out
    (its protocol not run), not an unknown one; the error names the field and the protocol."""
    from budget.runner.plan import parse_requirements
    from simcam.infra.errors import UserInputError

    scn = with_updates(default(), {"validation.protocols": ["chromatic"]})
    with pytest.raises(UserInputError, match=r"te is a starcam class this scenario does not compute: "
                                             r"validation\.protocols \(chromatic\) leaves out its protocol te; "
                                             r"add it to validation\.protocols"):
        parse_requirements(STUDY, scn, ["te.x<=0.01"])
    with pytest.raises(UserInputError, match=r"lsfe.*leaves out its protocol distortion"):
        parse_requirements(STUDY, scn, ["lsfe.x<=0.01"])
    with pytest.raises(UserInputError, match=r"unknown class 'tee'; the starcam classes are lsfe_s, lsfe_c2"):
        parse_requirements(STUDY, scn, ["tee.x<=0.01"])


def test_the_calibration_grid_extent_is_a_knob_only_where_listed():
    """``distortion.extent`` (lab.calibration_target.extent_fraction) is a real knob a plan opens
    by naming it; the default plan keeps seed 000's grid (the six counts); it changes LSFE-C1 and
    what is built on it only."""
    base = default()
    assert "distortion.extent" not in base.protocols.plan_knobs
    assert "lab.calibration_target.extent_fraction" not in {k.field for k in STUDY.protocol_knobs(base)}
    scn = with_updates(base, {"protocols.plan_knobs": ["distortion.frames", "distortion.extent"]})
    knobs = {k.field: k for k in STUDY.protocol_knobs(scn)}
    k = knobs["lab.calibration_target.extent_fraction"]
    assert (k.kind, k.low, k.high) == ("real", 0.3, 1.0) and k.low <= base.lab.calibration_target.extent_fraction <= k.high
    assert STUDY.field_classes(scn)["lab.calibration_target.extent_fraction"] == ("lsfe_c1", "lsfe", "total")
    STUDY.check(with_updates(scn, {"lab.calibration_target.extent_fraction": k.high}), where="t")
    STUDY.check(with_updates(scn, {"lab.calibration_target.extent_fraction": k.low}), where="t")
    # in the ideal world (run seed 11, trial 2) it moves exactly the classes declared; unlike the
    # counts it moves a truth too: LSFE-C1's box details (and, uncalibrated, its value)
    from budget.starcam import validate as V

    ideal = with_updates(base, _IDEAL)
    one = V.run_trial(ideal, 11, 2)["values"]
    two = V.run_trial(with_updates(ideal, {"lab.calibration_target.extent_fraction": 0.95}), 11, 2)["values"]
    assert {key[0] for key in one if two[key] != one[key]} == {"lsfe_c1", "lsfe", "total"}
