"""The robustness runner (budget.runner.robustness) on a toy world with analytic answers
(tests/toys/toy_world_study.py).

Monte Carlo checks use fixed seeds; each tolerance is stated with the sampling distribution
it follows from.
"""

import json
import math

import numpy as np
import pytest
from toy_world_study import ToyWorldStudy

from budget.runner.robustness import ALL, IDEAL, SCHEMA, build_cases, run_robustness
from budget.runner.robustness_verdicts import (
    COVERAGE_TOLERANCE,
    combine,
    coverage_verdict,
    summary_cell,
)
from budget.runner.study import ClassSpec
from budget.runner.verdicts import Tolerance, judge
from simcam.infra.errors import UserInputError

EPS = np.finfo(float).eps
OFF = {n: 0.0 for n in ("correlation_rho", "extra_noise_units", "drift_units_per_sample",
                        "nonlinearity_per_unit", "scale_error_ratio", "offset_units")}


def _scenario(study, **values):
    data = study.load_scenario().model_dump(mode="json")
    data["world"]["effects"].update(values)
    return study.from_dict(data, source="test")


def test_cases_ideal_each_effect_alone_and_all():
    study = ToyWorldStudy()
    scn = study.load_scenario()
    cases = build_cases(study, scn)
    names = [c.name for c in cases]
    assert names == [IDEAL, "correlation_rho", "extra_noise_units", "drift_units_per_sample",
                     "nonlinearity_per_unit", "scale_error_ratio", "offset_units", ALL]
    assert cases[0].scenario.world.effects.active() == ()
    for c in cases[1:-1]:
        assert c.scenario.world.effects.active() == (c.name,)
        assert getattr(c.scenario.world.effects, c.name) == getattr(scn.world.effects, c.name)
        # everything but the world is the scenario's
        assert c.scenario.model_dump(exclude={"world"}) == scn.model_dump(exclude={"world"})
    assert cases[-1].scenario is scn
    # truths depend on extra_noise_units only: the other single cases take the ideal's
    assert [c.shares_truths for c in cases] == [False, True, False, True, True, True, True, False]
    # fewer than two effects on: no "all" case (it would repeat one)
    one = build_cases(study, _scenario(study, **(OFF | {"offset_units": 0.2})))
    assert [c.name for c in one] == [IDEAL, "offset_units"]


def test_a_study_without_world_effects_is_refused():
    from toy_study import STUDY, Toy

    with pytest.raises(UserInputError, match=r"toy scenario toy: .*no \[world.effects\]"):
        build_cases(STUDY, Toy())


def test_common_random_numbers_make_additive_and_scale_effects_exact():
    study = ToyWorldStudy()
    scn = study.load_scenario()
    res = run_robustness(study, scn, trials=60, seed=4)
    key = ("mean", "published", "a")
    ideal = res.results[IDEAL].samples[key]
    e = scn.world.effects
    # rounding of two means of m = 8 values of magnitude <= max|x|: each sum's error is at
    # most m eps max|x| (sequential bound), the difference of two means twice that
    scale = float(np.max(np.abs(res.results[ALL].samples[key]))) + 1.0
    tol = 2 * scn.m * EPS * scale
    d_off = res.results["offset_units"].samples[key] - ideal
    assert np.max(np.abs(d_off - e.offset_units)) <= tol
    d_drift = res.results["drift_units_per_sample"].samples[key] - ideal
    assert np.max(np.abs(d_drift - e.drift_units_per_sample * (scn.m - 1) / 2)) <= tol
    ratio = res.results["scale_error_ratio"].samples[key] - (1 + e.scale_error_ratio) * ideal
    assert np.max(np.abs(ratio)) <= 2 * tol
    cell = res.cells()["offset_units"][key]
    assert cell["shift"] == pytest.approx(e.offset_units, abs=tol)
    assert cell["se_shift"] <= tol  # the paired differences are constant to rounding
    # the per-trial truths are the same draws in every case
    assert np.array_equal(res.results["offset_units"].trial_truths[key], res.results[IDEAL].trial_truths[key])


def test_biases_of_the_cases_match_their_closed_forms():
    """Expected shifts from the ideal world (toy_world_study's docstring), within 4 paired
    standard errors (fixed seed 7, 3000 trials: a 4-se miss has probability 6e-5 each)."""
    study = ToyWorldStudy()
    scn = study.load_scenario()
    e, m, s2 = scn.world.effects, scn.m, scn.sigma**2
    res = run_robustness(study, scn, trials=3000, seed=7)
    cells = res.cells()
    mean_key, var_key = ("mean", "published", "a"), ("variance", "improved", "a")
    # nonlinearity: E[mean(beta x^2)] = beta (mu_c^2 + mu_s^2 + sigma^2)
    c = cells["nonlinearity_per_unit"][mean_key]
    assert c["shift"] == pytest.approx(e.nonlinearity_per_unit * (scn.mu_center**2 + scn.mu_spread**2 + s2),
                                       abs=4 * c["se_shift"])
    # gain: E[k mean(x)] = k mu_c
    c = cells["scale_error_ratio"][mean_key]
    assert c["shift"] == pytest.approx(e.scale_error_ratio * scn.mu_center, abs=4 * c["se_shift"])
    # gain on the ddof-1 variance: ((1 + k)^2 - 1) sigma^2
    c = cells["scale_error_ratio"][var_key]
    assert c["shift"] == pytest.approx(((1 + e.scale_error_ratio) ** 2 - 1) * s2, abs=4 * c["se_shift"])
    # stationary AR(1) noise: E[s^2] = sigma^2 (1 - 2/(m(m-1)) sum_h (m-h) rho^h)
    rho = e.correlation_rho
    expected = s2 * (1 - 2 / (m * (m - 1)) * sum((m - h) * rho**h for h in range(1, m))) - s2
    c = cells["correlation_rho"][var_key]
    assert c["shift"] == pytest.approx(expected, abs=4 * c["se_shift"])
    # drift on the ddof-1 variance: E = d^2 m (m + 1) / 12 (the noise is independent of i)
    c = cells["drift_units_per_sample"][var_key]
    assert c["shift"] == pytest.approx(e.drift_units_per_sample**2 * m * (m + 1) / 12, abs=4 * c["se_shift"])
    # extra noise: the truth moves with it, the ddof-1 estimate stays unbiased (4 se)
    c = cells["extra_noise_units"][var_key]
    assert c["truth"] == s2 + e.extra_noise_units**2
    assert abs(c["bias"]) <= 4 * c["se_bias"]


def test_verdicts_follow_the_numbers():
    """With a claimed accuracy A = 0.1 on the mean, an offset of A + 5 se fails and no offset
    holds. 2000 trials: the bias's se is sigma / sqrt(m n) = 2 / sqrt(16000) = 0.0158 exactly
    (error N(0, sigma^2/m)); seed 3 is fixed and the ideal bias is one N(0, se^2) draw (checked
    within 2 se), so the 95 % interval (+- 1.96 se = 0.031) lies inside +- 0.1 unshifted and
    wholly above 0.1 when shifted by 0.179. The stated sigma's coverage has se
    sqrt(0.683 0.317 / 2000) = 0.0104: unshifted it lies within 2.8 of them of 68.3 % (checked),
    so its interval (+- 0.020) lies inside 68.3 +- 5 points and the cell holds."""
    n, m, sigma, a = 2000, 8, 2.0, 0.1
    se = sigma / math.sqrt(m * n)
    key = ("mean", "published", "a")
    study = ToyWorldStudy(claims={("mean", "published"): a})
    for offset, verdict in ((a + 5.0 * se, "fails"), (0.0, "holds")):
        # (an offset of 0 would leave no "offset_units" case: 1e-12 keeps it, a shift of 1e-10 se)
        scn = _scenario(study, **(OFF | {"offset_units": offset or 1e-12}))
        res = run_robustness(study, scn, trials=n, seed=3)
        cells = res.cells()
        ideal, shifted = cells[IDEAL][key], cells["offset_units"][key]
        assert abs(ideal["bias"]) < 2 * se and abs(ideal["coverage_1sigma"] - 0.6827) < 2.8 * 0.0104
        assert ideal["verdict"] == "holds" and ideal["claim_holds"] is True
        assert shifted["verdict"] == verdict and shifted["claim_holds"] is (verdict == "holds")
        assert shifted["bias_verdict"].tolerance.high == pytest.approx(a)
        sentence = res.breaks()[("mean", "published")]["sentence"]
        assert ("offset_units breaks its claim first" in sentence) is (verdict == "fails")
        if verdict == "holds":
            assert "its claim holds in every case" in sentence
    # every cell's verdict is the rule applied to its own numbers
    for row in cells.values():
        for c in row.values():
            if c["verdict"] is None:
                continue
            bv = c["bias_verdict"]
            assert bv == judge(c["bias"], c["se_bias"], n, bv.tolerance, unit=bv.unit, quantity=bv.quantity)
            parts = [bv] + ([coverage_verdict(c["coverage_1sigma"], c["coverage_n"])]
                            if c["coverage_1sigma"] is not None else [])
            assert c["verdict"] == combine(parts)[0]


def test_the_cell_rule():
    # coverage over 400 trials: se sqrt(0.6827 * 0.3173 / 400) = 0.0233, interval +- 0.0456
    assert coverage_verdict(0.6827, 400).outcome == "holds"  # 0.637..0.728 inside 0.633..0.733
    assert coverage_verdict(0.55, 400).outcome == "fails"  # up to 0.596, below 0.633
    v = coverage_verdict(0.64, 100)  # se 0.0466: straddles 0.633
    assert v.outcome == "undetermined" and v.n_to_settle > 100
    assert v.tolerance is COVERAGE_TOLERANCE and COVERAGE_TOLERANCE.source == "default"
    # the tolerance's reason: a sigma stated 10 % too large or too small gives a coverage of
    # P(|z| <= 1/1.1) = 0.637 or P(|z| <= 1/0.9) = 0.733, at the edges of 68.3 % +- 5 points
    from scipy.stats import norm

    for ratio in (1.1, 0.9):
        c = 2 * norm.cdf(1 / ratio) - 1
        edge = COVERAGE_TOLERANCE.low if ratio > 1 else COVERAGE_TOLERANCE.high
        assert c == pytest.approx(edge, abs=0.005)
    tol = Tolerance.around(0.0, 1.0, reason="test", source="default")
    holds, fails = judge(0.0, 0.1, 10, tol), judge(5.0, 0.1, 10, tol)
    open_a, open_b = judge(0.9, 0.1, 10, tol), judge(0.95, 0.1, 10, tol)
    assert combine([holds, holds]) == ("holds", None, False)
    assert combine([holds, fails])[0] == "fails" and combine([open_a, fails])[0] == "fails"
    # undetermined: the trials that settle both open parts (the larger)
    assert combine([holds, open_a, open_b]) == ("undetermined", max(open_a.n_to_settle, open_b.n_to_settle), False)
    edge = judge(1.0, 0.1, 10, tol)
    assert combine([edge, open_a]) == ("undetermined", None, True)


class _ResidualToy(ToyWorldStudy):
    """The toy with its variance as a residual (no claim) and a claimed accuracy for the mean."""

    def classes(self, scenario):
        mean, var = super().classes(scenario)
        return mean, ClassSpec(var.name, var.label, var.unit, var.axes, var.description, role="residual")


class _UndeterminedToy(ToyWorldStudy):
    """The toy with its variance's axis declared a gauge freedom (not determined)."""

    def classes(self, scenario):
        mean, var = super().classes(scenario)
        return mean, ClassSpec(var.name, var.label, var.unit, var.axes, var.description, undetermined=var.axes)


def test_an_undetermined_axis_has_no_claim():
    """A gauge freedom's estimate is a convention: no verdict (as the findings' "not
    determined"), never "ok" nor "FAIL", and no sentence says an effect breaks it."""
    study = _UndeterminedToy()
    res = run_robustness(study, study.load_scenario(), trials=20, seed=3)
    payload = res.to_json()
    for case in payload["cases"].values():
        for cell in case["classes"]["variance"]["a"].values():
            assert cell["claim_holds"] is None and cell["claim"] is None and cell["verdict"] is None
        assert isinstance(case["classes"]["mean"]["a"]["published"]["claim_holds"], bool)
    for var in study.variants:
        b = payload["breaks"][f"variance.{var}"]
        assert b["effect"] is None and "not determined" in b["sentence"]


def test_a_table_cell_sums_up_the_axes_of_a_class_and_variant():
    tol = Tolerance.around(0.0, 0.4, reason="test", source="default")

    def cell(bias, se, verdict=True):
        v = judge(bias, se, 100, tol) if verdict else None
        return {"bias": bias, "se_bias": se, "verdict": v.outcome if v else None, "bias_verdict": v,
                "coverage_verdict": None}

    # one axis: its verdict and bias, no axis named
    assert summary_cell([("x", cell(0.9, 0.1))]) == "FAILS +0.9"
    assert summary_cell([("x", cell(0.9, 0.1))], markdown=True) == "**FAILS** +0.9"
    # two of three fail: the one farthest past its tolerance (|bias| / 0.4: 3 for b, 2.25 for a)
    axes = [("a", cell(0.9, 0.1)), ("b", cell(-1.2, 0.1)), ("c", cell(0.0, 0.1))]
    assert summary_cell(axes) == "FAILS 2/3 -1.2 (b)"
    # none fails, one undetermined (0.35 +- 0.196 straddles 0.4): it is named
    axes = [("a", cell(0.1, 0.01)), ("b", cell(0.35, 0.1)), ("c", cell(0.2, 0.01))]
    assert summary_cell(axes) == "undet. 1/3 +0.35 (b)"
    # all hold: the one nearest its edge
    assert summary_cell([("a", cell(0.1, 0.01)), ("b", cell(-0.2, 0.01))]) == "holds -0.2 (b)"
    # an axis without a verdict is not counted; none judged: "--" and the largest |bias|
    assert summary_cell([("a", cell(9.0, 0.1, False)), ("b", cell(0.2, 0.01))]) == "holds +0.2"
    assert summary_cell([("a", cell(0.3, 0.1, False)), ("b", cell(-0.4, 0.1, False))]) == "-- -0.4 (b)"


def test_json_schema_claims_residuals_and_report(tmp_path):
    study = _ResidualToy(claims={("mean", "published"): 0.5})
    res = run_robustness(study, study.load_scenario(), trials=40, seed=2)
    payload = json.loads(json.dumps(res.to_json(), allow_nan=False))
    assert payload["schema"] == SCHEMA == "budget.robustness/2" and payload["study"] == "toyworld"
    assert payload["coverage_tolerance"]["low"] == pytest.approx(0.6327)
    assert list(payload["cases"]) == [c.name for c in res.cases]
    for case in payload["cases"].values():
        assert {"active_effects", "trials", "seed", "scenario_hash", "classes"} <= set(case)
        assert case["trials"] == 40 and case["seed"] == 2
        mean = case["classes"]["mean"]["a"]["published"]
        var = case["classes"]["variance"]["a"]["improved"]
        for cell in (mean, var):
            assert {"bias", "se_bias", "std", "coverage_1sigma", "claim_holds", "verdict", "tolerance",
                    "n_to_settle", "coverage_verdict"} <= set(cell)
        assert mean["claim"] == 0.5 and isinstance(mean["claim_holds"], bool)
        # the claimed accuracy is the tolerance, a declared one (the hook does not say the paper's)
        assert mean["tolerance"] == {"low": -0.5, "high": 0.5, "reason": "the method's claimed accuracy 0.5",
                                     "source": "default"}
        assert mean["verdict"] in ("holds", "fails", "undetermined")
        assert mean["claim_holds"] is (mean["verdict"] == "holds")
        assert (mean["n_to_settle"] is not None) is (mean["verdict"] == "undetermined")
        assert 0.0 <= mean["coverage_1sigma"] <= 1.0
        assert var["coverage_1sigma"] is None  # no sigma stated
        assert var["claim_holds"] is None and var["claim"] is None  # a residual: no claim
        assert var["verdict"] is None and var["tolerance"] is None and "residual" in var["no_verdict"]
    assert payload["cases"][IDEAL]["active_effects"] == []
    assert payload["cases"]["offset_units"]["active_effects"] == ["offset_units"]
    assert payload["cases"][ALL]["scenario_hash"] == payload["scenario_hash"]
    assert len({c["scenario_hash"] for c in payload["cases"].values()}) == len(payload["cases"])
    assert payload["effects"]["offset_units"]["source"] == "a constant offset"
    assert "a residual, no claim" in payload["breaks"]["variance.improved"]["sentence"]
    # the residual's sentence names the effect alone that moves it most, not the case "all":
    # AR(1) noise biases the ddof-1 variance by -sigma^2 (2/(m-1)) sum_k (1 - k/m) rho^k
    # = -0.40 (sigma 2, m 8, rho 0.3), against +0.08 for the 1 % gain error (4 ((1.01)^2 - 1)),
    # about +0.08 for the non-linearity (slope 1 + 2 beta x = 1.01 at x ~ 5), 6e-4 for the
    # drift (d^2 var(i)), 0 for the offset and in expectation for the extra noise (its truth
    # moves with it); the paired shifts' standard errors at 40 trials are <= 0.13, so the
    # gap of 0.48 is over 3 of them (fixed seed)
    var_break = payload["breaks"]["variance.improved"]
    assert var_break["effect"] == "correlation_rho"
    assert "correlation_rho changes it most" in var_break["sentence"] and "all together" in var_break["sentence"]
    rep = res.write_report(tmp_path / "rob")
    text = rep.read_text()
    assert "| case |" in text and "What breaks each claim" in text and "`offset_units` = 0.1" in text
    assert json.loads((tmp_path / "rob" / "robustness.json").read_text())["schema"] == SCHEMA
    table = res.format_table().splitlines()
    assert len(table) == 1 + len(res.cases) and table[0].startswith("case")


def test_results_do_not_depend_on_workers():
    study = ToyWorldStudy()
    scn = study.load_scenario()
    one = run_robustness(study, scn, trials=30, seed=5, workers=1).to_json()
    two = run_robustness(study, scn, trials=30, seed=5, workers=2).to_json()
    for p in (one, two):
        del p["elapsed_s"], p["executor"]
    assert one == two


@pytest.mark.parametrize("depends, calls", [({"extra_noise_units"}, 3), (set(), 1), (None, 8)])
def test_truths_are_shared_where_they_do_not_depend_on_the_effect(depends, calls):
    study = ToyWorldStudy(depends=depends)
    scn = study.load_scenario()
    type(study).truth_calls = 0
    res = run_robustness(study, scn, trials=10, seed=1, workers=1)
    assert type(study).truth_calls == calls
    shared = [c.name for c in res.cases if c.shares_truths]
    for name in shared:
        assert res.results[name].truths is res.results[IDEAL].truths
    # sharing changes no number where the truths really do not depend on the effect (the
    # toy's truth depends on extra_noise_units only: the right declaration)
    if depends == {"extra_noise_units"}:
        full = run_robustness(ToyWorldStudy(depends=None), scn, trials=10, seed=1, workers=1).to_json()
        part = res.to_json()
        assert {n: c["classes"] for n, c in full["cases"].items()} == \
               {n: c["classes"] for n, c in part["cases"].items()}


def test_command_line(tmp_path, monkeypatch, capsys):
    from budget.runner import registry
    from budget.runner.cli import study_group
    from simcam.infra.cli import run_cli

    monkeypatch.setitem(registry._BY_NAME, "toyworld", registry.StudyEntry("toyworld", "toy_world_study:STUDY",
                                                                           "toy world study"))
    out = tmp_path / "r.json"
    run_cli(study_group("toyworld"), ["robustness", "--trials", "12", "--seed", "3", "--workers", "1",
                                      "--json", str(out), "--report", str(tmp_path / "rep"), "--no-progress"])
    text = capsys.readouterr().out
    assert "robustness of scenario toy-world" in text and "offset_units" in text
    assert json.loads(out.read_text())["cases"]["ideal"]["trials"] == 12
    assert (tmp_path / "rep" / "report.md").is_file()
    bad = tmp_path / "bad.toml"
    bad.write_text("[world.effects]\nbogus_units = 1.0\n")
    with pytest.raises(SystemExit) as exc:
        run_cli(study_group("toyworld"), ["robustness", str(bad), "--workers", "1", "--json",
                                          str(tmp_path / "r2.json")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert f"error: {bad}: world.effects.bogus_units: unknown key" in err
    assert not (tmp_path / "r2.json").exists()


def test_every_study_group_has_the_verb(capsys):
    from budget.runner.cli import study_group
    from budget.runner.registry import study_names
    from simcam.infra.cli import run_cli

    for name in study_names():
        run_cli(study_group(name), ["robustness", "--help"])
        assert "--trials" in capsys.readouterr().out


@pytest.mark.parametrize("name", ["starcam", "inductosyn", "whiskbroom", "scanmirror", "linecam", "attitude"])
def test_cases_of_every_study_with_a_world(name):
    """Cases are built generically (dump, set world.effects, from_dict): every case is the
    scenario but for its effects (skipped for a study whose scenario has no world effects yet)."""
    from budget.runner.registry import get_study, study_names
    from simcam.effects import scenario_effects

    if name not in study_names():
        pytest.skip(f"{name} is not installed")
    study = get_study(name)
    scn = study.load_scenario()
    if scenario_effects(scn) is None:
        pytest.skip(f"the {name} scenario has no world effects")
    cases = build_cases(study, scn)
    base = scn.model_dump(mode="json")
    base["world"]["effects"] = None
    for c in cases:
        d = c.scenario.model_dump(mode="json")
        assert d["world"]["effects"] == c.magnitudes
        d["world"]["effects"] = None
        assert d == base
        assert c.scenario.world.effects.active() == c.active


class _ReferenceToy(ToyWorldStudy):
    """The toy world with ``improved`` declared a reference variant (it estimates nothing)."""

    reference_variants = ("improved",)


def test_a_reference_variant_is_never_shown_ok():
    study = _ReferenceToy()
    res = run_robustness(study, study.load_scenario(), trials=10, seed=1, workers=1)
    for case, row in res.cells().items():
        for (cls, var, ax), cell in row.items():
            if var == "improved":
                assert cell["claim_holds"] is None and cell["verdict"] is None, (case, cls, ax)
                assert "reference" in cell["no_verdict"]
            shown = summary_cell([(ax, cell)])
            assert shown.startswith("--" if var == "improved" else ("holds", "FAILS", "undet.")), (case, cls, var, shown)
    for (cls, var), b in res.breaks().items():
        if var == "improved" and cls == "variance":
            assert b["verdict"] is None and "no verdict (a reference variant" in b["sentence"], b
