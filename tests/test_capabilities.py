"""The capabilities (budget.runner.capabilities) through the machinery, on the full toy
(tests/toys/full_toy.py), which has every one: each is checked to be used, and its answer
against the toy's analytic one; and the study contract's refusals and defaults.

Monte Carlo assertions use fixed seeds and tolerances derived from the sampling distribution
(stated at each)."""

from __future__ import annotations

import json
import math
import os
from collections import Counter

import numpy as np
import pytest
from scipy import stats

from budget.runner import registry
from budget.runner.capabilities import (CAPABILITIES, BatchedTrials, CheckedScenario, Plannable, Prepared, Presented,
                                        ProtocolShapes, SeparablePlans, SharedTruths, SizedTruths, SplitTruths, Warmup,
                                        WorldEffects, capability, declared_capabilities)
from budget.runner.plan import plan_protocol, resolution
from budget.runner.report import write_report
from budget.runner.robustness import run_robustness
from budget.runner.run import run_study
from budget.runner.scheduler import PILOT_TRIALS, truth_targets
from budget.sweeps.run import open_sweep, run_sweep
from budget.sweeps.spec import load_sweep
from full_toy import CLAIM_PX, LINE_FACTOR, STARTED, FullToyStudy
from plan_stats import quantile_rel_se
from simcam.infra.errors import ScenarioError
from toy_study import STUDY as CORE
from toy_study import Toy, ToyStudy

STUDY = FullToyStudy()

#: setup calls per (process, scenario hash), in the process that counts them
SETUPS: Counter = Counter()
#: the targets each truth_size_for call was given (this process)
TARGETS: list[dict] = []
#: the trials each trial_batch call was given (this process)
BATCHES: list[list[int]] = []


class Watched(FullToyStudy):
    """The full toy telling what the machinery asked of it: the counts above, and in each
    trial's aux its process, whether the study's worker_init ran there and how many times
    setup ran there for the trial's scenario (workers import this module by name)."""

    def setup(self, scenario):
        SETUPS[(os.getpid(), scenario.hash)] += 1
        return super().setup(scenario)

    def truth_size_for(self, scenario, seed, target_se):
        TARGETS.append(dict(target_se))
        return super().truth_size_for(scenario, seed, target_se)

    def trial_batch(self, scenario, seed, ks):
        BATCHES.append(list(ks))
        out = super().trial_batch(scenario, seed, ks)
        pid, h = os.getpid(), scenario.hash
        for r in out:
            r.aux.update(pid=float(pid), started=float(pid in STARTED), setups=float(SETUPS[(pid, h)]))
        return out


class PartsOnly(FullToyStudy):
    """The full toy whose truths() must not run whole: a run on several workers computes the
    truths in parts."""

    def truths(self, scenario, seed):
        raise AssertionError("truths() ran whole")


def _scenario(offset_px: float = 0.5, **effects):
    """The default scenario with another true offset (a set-up no earlier test has cached) and
    the effects given (the rest at their defaults)."""
    return STUDY.from_dict({"offset_px": offset_px, "world": {"effects": effects}}, source="test")


def _variance(scenario) -> float:
    """The noise truth: the variance of a frame's noise, sigma^2 + extra^2."""
    return scenario.sigma_px**2 + scenario.world.effects.extra_noise_px**2


def test_the_full_toy_declares_every_capability():
    assert declared_capabilities(FullToyStudy) == CAPABILITIES


# ------------------------------------------------------------------ running
def test_setup_runs_once_per_process_and_scenario():
    """The runner's cache: one setup for a run of 60 trials in this process, none for a second
    run of the same scenario, one for another scenario."""
    study, a, b = Watched(), _scenario(0.61), _scenario(0.62)
    run_study(study, a, trials=60, seed=1, workers=1)
    run_study(study, a, trials=60, seed=2, workers=1)
    run_study(study, b, trials=60, seed=1, workers=1)
    me = os.getpid()
    assert (SETUPS[(me, a.hash)], SETUPS[(me, b.hash)]) == (1, 1)


def test_setup_key_lets_scenarios_it_does_not_tell_apart_share_one_setup():
    """Prepared.setup_key: the toy's leaves out truth_draws (what truth_size_for resizes), so
    the resized scenario shares the run's set-up; another sigma_px gets its own."""
    study, a = Watched(), _scenario(0.66)
    b, c = a.model_copy(update={"truth_draws": 777}), a.model_copy(update={"sigma_px": 0.3})
    assert a.hash != b.hash and study.setup_key(a) == study.setup_key(b) != study.setup_key(c)
    assert study.prepared(a) == study.prepared(b) == a.sigma_px and study.prepared(c) == 0.3
    me = os.getpid()
    assert (SETUPS[(me, a.hash)], SETUPS[(me, b.hash)], SETUPS[(me, c.hash)]) == (1, 0, 1)
    assert Prepared.setup_key(study, a) == a.hash  # the protocol's default: every field


def test_two_workers_each_started_by_worker_init_and_set_up_once():
    """Two processes (this one and the one the runner starts) ran trials; in each the study's
    worker_init had run and setup had run once for the scenario."""
    res = run_study(Watched(), _scenario(0.63), trials=40, seed=3, workers=2)
    assert len(set(res.aux["pid"])) == 2
    assert set(res.aux["started"]) == {1.0}
    assert set(res.aux["setups"]) == {1.0}


def test_trial_batch_equals_trial_per_k_and_the_runner_batches():
    scn = _scenario()
    ks = [0, 3, 4, 11]
    for k, r in zip(ks, STUDY.trial_batch(scn, 7, ks)):
        assert r.estimates == STUDY.trial(scn, 7, k).estimates, k  # exactly
    BATCHES.clear()
    res = run_study(Watched(), scn, trials=30, seed=7, workers=1)
    assert sorted(k for b in BATCHES for k in b) == list(range(30)) and max(map(len, BATCHES)) > 1
    for k in (0, 29):
        for key, v in STUDY.trial(scn, 7, k).estimates.items():
            assert res.samples[key][k] == v


def test_truth_parts_equal_the_truths_whole_on_one_and_two_workers():
    """One worker computes truths() whole, two the parts as tasks (truths() is never called):
    the same truths to the bit.
    The sampled truth is the noise variance v = sigma^2 + extra^2 within 4 of its standard
    errors (the mean of n squared normal draws: se v sqrt(2 / n))."""
    scn = _scenario(0.64)
    one = run_study(STUDY, scn, trials=30, seed=5, workers=1)
    two = run_study(PartsOnly(), scn, trials=30, seed=5, workers=2)
    assert one.truths == two.truths
    t = one.truths[("noise", "x")]
    assert abs(t.value - _variance(scn)) <= 4 * t.se
    assert STUDY.truths(scn, 5) == STUDY.truths_from_parts(scn, 5, [STUDY.truth_part(scn, 5, p)
                                                                    for p in STUDY.truth_parts(scn, 5)])


def test_truth_size_for_is_asked_with_the_runners_targets():
    """With a fixed number of trials the targets are a quarter of the pilot's s / sqrt(n)
    (budget.runner.scheduler.truth_targets); the toy draws n = 2 (v / target)^2, so the truth's
    standard error is the target within the sampling of the sample sd of the squared draws
    (relative sd sqrt((kurtosis - 1) / 4n), kurtosis 15 for a squared normal: 5 of them)."""
    TARGETS.clear()
    n = 80
    res = run_study(Watched(), _scenario(0.65), trials=n, seed=9, workers=1)
    pilot = {k: v[:PILOT_TRIALS] for k, v in res.samples.items()}
    assert TARGETS == [truth_targets(res.classes, samples=pilot, trials=n)]
    target = TARGETS[0][("noise", "x")]
    t = res.truths[("noise", "x")]
    draws = math.ceil(2 * (_variance(res.scenario) / target) ** 2)
    assert t.se == pytest.approx(target, rel=5 * math.sqrt(14 / (4 * draws)))
    assert res.to_json()["truths"]["noise.x"]["target_se"] == target


# ------------------------------------------------------------------ sweeps (a registered kind)
@pytest.fixture
def registered(monkeypatch):
    """The full toy registered as the sweep kind ``fulltoy`` for one test."""
    entry = registry.StudyEntry("fulltoy", "full_toy:STUDY", "full toy")
    monkeypatch.setattr(registry, "REGISTRY", registry.REGISTRY + (entry,))
    monkeypatch.setitem(registry._BY_NAME, "fulltoy", entry)


def _sweep_file(tmp_path, parameters: str) -> str:
    p = tmp_path / "sweep.toml"
    p.write_text(f'kind = "fulltoy"\nseed = 4\nevaluate = "truth"\n[parameters]\n{parameters}\n')
    return str(p)


def test_truth_fields_make_a_sweep_share_truths(registered, tmp_path):
    """Four points, two frame counts by two noises: the frames are not among the truth fields,
    so two truths serve the four points, the store equal to one with a truth per point."""
    path = _sweep_file(tmp_path, '"frames" = [10, 20]\n"sigma_px" = [0.1, 0.2]')
    shared = run_sweep(path, tmp_path / "shared", inline=True)
    alone = run_sweep(path, tmp_path / "alone", inline=True, truths_shared=False)
    assert (shared.truths_computed, alone.truths_computed) == (2, 4)
    a, b = open_sweep(tmp_path / "shared"), open_sweep(tmp_path / "alone")
    np.testing.assert_array_equal(a.truth.values, b.truth.values)
    t = a.truth.sel({"class": "noise", "axis": "x"})
    np.testing.assert_array_equal(t.isel(frames=0).values, t.isel(frames=1).values)


def test_check_refuses_a_bad_point_before_any_work(registered, tmp_path):
    path = _sweep_file(tmp_path, '"truth_draws" = [3, 100]')
    with pytest.raises(ScenarioError, match=r"point 0 .*truth_draws: 3 draws for the truth's 7 parts"):
        load_sweep(path)
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ robustness
def test_robustness_reads_truth_depends_on_effects_and_the_claim():
    """The drift moves the offset's estimate by exactly itself and leaves the truths (shared with
    the ideal world); the extra noise changes the noise truth (computed again). The offset's
    claim (CLAIM_PX) holds in the ideal world and the drift breaks it first."""
    res = run_robustness(STUDY, _scenario(), trials=60, seed=3, workers=1)
    j = res.to_json()
    assert j["truth_depends_on_effects"] == ["extra_noise_px"]
    assert {n: c["truths_from"] for n, c in j["cases"].items()} == {
        "ideal": "own", "drift_px": "ideal", "extra_noise_px": "own", "all": "own"}
    ideal = j["cases"]["ideal"]["classes"]["offset"]["x"]["improved"]
    drift = j["cases"]["drift_px"]["classes"]["offset"]["x"]["improved"]
    assert ideal["claim"] == drift["claim"] == CLAIM_PX and ideal["claim_holds"] and not drift["claim_holds"]
    assert drift["shift"] == pytest.approx(0.05, abs=1e-12)
    assert j["cases"]["ideal"]["classes"]["noise"]["x"]["improved"]["claim"] is None
    assert j["breaks"]["offset.improved"]["effect"] == "drift_px"


# ------------------------------------------------------------------ planning
def test_plan_splits_compares_the_shapes_and_finds_the_analytic_optimum():
    """offset.x <= 0.04 and noise.x <= 0.03 (ideal world): two groups (the frames and pattern
    change the offset only, the dark frames the noise only); the offset's two patterns each
    searched, the line recommended (a line frame: twice the variance in a quarter of the time,
    so half the cost), with F* = (z s / V)^2 frames, s = sigma sqrt(2): within 3 standard
    errors of the 95 % quantile of 200 trials (a relative error moves F by twice it), the
    search's cost resolution and one frame."""
    scn = _scenario(drift_px=0.0, extra_noise_px=0.0)
    res = plan_protocol(STUDY, scn, ["offset.x<=0.04", "noise.x<=0.03"], seed=0, sure=0.5)
    groups = {g["name"]: g for g in res.to_json()["groups"]}
    assert set(groups) == {"offset", "noise"}
    assert groups["offset"]["knobs"] == ["frames"] and groups["noise"]["knobs"] == ["dark_frames"]
    assert set(groups["offset"]["shapes"]) == {"grid", "line"}
    assert res.recommended.shape == "line"
    n = scn.validation.trials
    f_star = (stats.norm.ppf(0.975) * scn.sigma_px * math.sqrt(LINE_FACTOR) / 0.04) ** 2
    tol = 3 * 2 * quantile_rel_se(n, 0.95) + resolution(n) + 1 / f_star
    assert abs(res.recommended.knobs["frames"] / f_star - 1) <= tol, (res.recommended.knobs, f_star, tol)


# ------------------------------------------------------------------ the report
def test_report_sections_details_and_likely_cause_in_the_report_and_json(tmp_path):
    """The published noise variance (ddof 0 over D = 4 dark frames) is biased by -v / 4: 0.0125
    against a standard error of v sqrt(2 (D - 1)) / D / sqrt(200) = 0.0022 (5.7 of them), so it
    is not recovered and the toy's likely cause is quoted."""
    res = run_study(STUDY, _scenario(), trials=200, seed=2, workers=1)
    details = {"dark_frames": 4, "noise_bias_published_px2": -res.truths[("noise", "x")].value / 4}
    assert res.to_json()["details"] == details
    found = {(f["class"], f["variant"]): f for f in res.to_json()["findings"]}
    cause = found[("noise", "published")]["likely_cause"]
    assert cause.startswith("it divides by the 4 dark frames, not 3")
    assert "likely_cause" not in found[("noise", "improved")]
    write_report(res, tmp_path / "rep")
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "## Dark frames" in md and "The published variance divides by the 4 dark frames" in md
    assert f"Likely cause: {cause}" in md
    assert json.loads((tmp_path / "rep" / "summary.json").read_text())["details"] == details


# ------------------------------------------------------------------ the contract
def test_a_declared_capability_without_its_methods_is_refused():
    with pytest.raises(TypeError, match="declares capabilities without implementing "
                                        "Plannable.protocol_knobs, Plannable.lab_time_s"):
        type("NoKnobs", (ToyStudy, Plannable), {})
    with pytest.raises(TypeError, match="SplitTruths.truth_part, SplitTruths.truths_from_parts"):
        type("HalfSplit", (ToyStudy, SplitTruths), {"truth_parts": lambda self, scenario, seed: [0]})


def test_a_capability_method_without_the_capability_is_refused():
    with pytest.raises(TypeError, match=r"without declaring them: setup \(declare Prepared\)"):
        type("Undeclared", (ToyStudy,), {"setup": lambda self, scenario: None})
    with pytest.raises(TypeError, match=r"claim \(declare WorldEffects\)"):
        type("Claims", (ToyStudy,), {"claim": lambda self, scenario, c, v: None})


@pytest.mark.parametrize("hook", ["default_trials", "max_trials", "chunk_trials", "commands"])
def test_a_retired_hook_is_refused(hook):
    with pytest.raises(TypeError, match=f"no longer has: {hook} \\(now "):
        type("Retired", (ToyStudy,), {hook: lambda self: 100})


def test_a_core_only_study_gets_the_documented_defaults():
    """The capabilities module's table, 'without it', on the core toy."""
    scn, seed = Toy(trials=5), 4
    assert declared_capabilities(ToyStudy) == ()
    assert capability(CORE, Prepared).setup(scn) is None and CORE.prepared(scn) is None
    assert capability(CORE, CheckedScenario).check(scn, where="here") is None
    batch = capability(CORE, BatchedTrials).trial_batch(scn, seed, [0, 2])
    assert [r.estimates for r in batch] == [CORE.trial(scn, seed, k).estimates for k in (0, 2)]
    assert capability(CORE, Warmup).prewarm(scn) is None and capability(CORE, Warmup).worker_init() is None
    split = capability(CORE, SplitTruths)
    assert split.truth_parts(scn, seed) == [None]
    whole = split.truth_part(scn, seed, None)
    assert whole == CORE.truths(scn, seed) and split.truths_from_parts(scn, seed, [whole]) == whole
    assert capability(CORE, SizedTruths).truth_size_for(scn, seed, {("variance", "a"): 0.1}) is scn
    assert capability(CORE, SharedTruths).truth_fields(scn) is None
    effects = capability(CORE, WorldEffects)
    assert effects.truth_depends_on_effects(scn) is None and effects.claim(scn, "variance", "published") is None
    assert not isinstance(CORE, Plannable)
    with pytest.raises(TypeError, match="does not have Plannable"):
        capability(CORE, Plannable)
    shapes = capability(CORE, ProtocolShapes)
    assert shapes.protocol_shapes(scn) == {} and shapes.shape_value(scn, "m") == scn.m
    sep = capability(CORE, SeparablePlans)
    assert sep.field_classes(scn) == {} and sep.restrict_classes(scn, frozenset({"mean"})) is None
    assert sep.uncomputed_class(scn, "mean") is None
    shown = capability(CORE, Presented)
    res = run_study(CORE, scn, trials=5, seed=seed, workers=1)
    assert shown.report_sections(res, None) == [] and shown.details(res) == {}
    assert shown.likely_cause(res, ("variance", "published", "a"), {}) is None


def test_claims_are_judged_in_both_worlds():
    """Claims: the toy's one claim (the offset measured to 10 % of its truth) judged from a run of
    each world. The seed's world has no drift, so the estimate's bias is 0 within its standard
    error (0.2 / sqrt(100) / sqrt(40) = 0.003 px against a tolerance of 0.05 px: holds); the
    realistic world's drift of 0.05 px is exactly at the tolerance's edge (10 % of 0.5 px), so the
    verdict there is whatever the interval says, never contradicting its numbers."""
    from budget.runner.claims import evaluate_claims, ledger_runs, study_claims, world_scenario

    study, scn = FullToyStudy(), _scenario(0.5)
    claims = study_claims(study, scn)
    runs = {(c, w): run_study(study, world_scenario(study, scn, w), trials=40, seed=3, workers=1)
            for c, w in ledger_runs(claims)}
    seed_world, realistic = evaluate_claims(claims, runs)
    assert seed_world.world == "seed" and seed_world.verdict.outcome == "holds"
    assert realistic.world == "realistic" and realistic.verdict is not None
