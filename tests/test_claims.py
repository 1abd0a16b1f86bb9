"""The claims ledger's types and evaluation (budget.runner.claims) on the toy studies, whose
answers are known analytically (tests/toy_study.py, tests/toy_world_study.py), and its
Markdown table on hand-built results."""

from __future__ import annotations

import math

import pytest
from toy_study import STUDY as TOY
from toy_study import Toy, ToyStudy
from toy_world_study import STUDY as WORLD_TOY

from budget.runner.capabilities import CAPABILITIES, Claims, capability
from budget.runner.claims import (KINDS, WORLDS, Claim, ClaimResult, ToleranceRule, evaluate_claims,
                                  ledger_markdown, ledger_runs, study_claims, world_scenario)
from budget.runner.numbers import fmt
from budget.runner.run import run_study
from budget.runner.verdicts import Tolerance, judge

Z95 = 1.959963984540054
REL10 = ToleranceRule(reason="10 % of the truth", relative=0.10)


def _claim(**kw) -> Claim:
    base = dict(id="variance.method", words="the unbiased sample variance measures the variance", figures=(),
                unit="1", axis="a", condition="m = 8 draws", section="eq 1", kind="method", scenario="toy",
                class_name="variance", variant="improved", tolerance=REL10)
    return Claim(**{**base, **kw})


def _agrees(v) -> None:
    """The verdict's outcome recomputed from its own numbers (not with judge)."""
    lo, hi = v.estimate - Z95 * v.se, v.estimate + Z95 * v.se
    t = v.tolerance
    want = "holds" if (t.low <= lo and hi <= t.high) else "fails" if (lo > t.high or hi < t.low) else "undetermined"
    assert v.outcome == want
    assert v.low == pytest.approx(lo) and v.high == pytest.approx(hi)


# ----------------------------------------------------------------------------- types
@pytest.mark.parametrize("kw,field", [
    (dict(id=""), "claim id"),
    (dict(words="two\nlines"), "words"),
    (dict(unit=""), "unit"),
    (dict(section=""), "section"),
    (dict(kind="folklore"), "kind"),
    (dict(figures=[1.0]), "figures"),
    (dict(figures=(float("nan"),)), "figures"),
    (dict(scenario=""), "scenario"),
    (dict(class_name=None), "class_name"),
    (dict(tolerance=None), "tolerance"),
    (dict(variant=None), "variant"),
    (dict(kind="performance", figures=(4.0,)), "variant"),
    (dict(kind="performance", variant=None, figures=()), "figures"),
    (dict(kind="bound", variant=None, figures=(1.0, 2.0)), "figures"),
    (dict(untestable="not simulated"), "untestable"),      # but maps a class: refused
    (dict(untestable="", class_name=None, variant=None, tolerance=None, scenario=""), "untestable"),
])
def test_bad_claims_name_the_field(kw, field):
    with pytest.raises(ValueError, match=field):
        _claim(**kw)


@pytest.mark.parametrize("kw,field", [
    (dict(reason=""), "tolerance reason"),
    (dict(reason="r", source="hearsay"), "tolerance source"),
    (dict(reason="r", relative=-0.1), "tolerance relative"),
    (dict(reason="r", absolute=float("inf")), "tolerance absolute"),
])
def test_bad_tolerance_rules_name_the_field(kw, field):
    with pytest.raises(ValueError, match=f"^{field}"):
        ToleranceRule(**kw)


def test_tolerance_rule_resolves_per_kind():
    rule = ToleranceRule(reason="10 %, at least 0.1", relative=0.10, absolute=0.1)
    perf = rule.resolve("performance", figure=1.14, truth=1.17)
    assert (perf.low, perf.high, perf.target) == pytest.approx((1.026, 1.254, 1.14))
    assert rule.resolve("performance", figure=0.03, truth=0.49).high == pytest.approx(0.13)  # the floor
    meth = rule.resolve("method", figure=None, truth=-2.0)
    assert (meth.low, meth.high, meth.target) == pytest.approx((-0.2, 0.2, 0.0))
    bound = rule.resolve("bound", figure=0.56, truth=0.5)
    assert math.isinf(bound.low) and bound.high == pytest.approx(0.66) and bound.target is None
    assert ToleranceRule(reason="the figure itself").resolve("bound", figure=0.56, truth=None).high == 0.56
    with pytest.raises(ValueError, match="no tolerance"):
        ToleranceRule(reason="10 %", relative=0.1).resolve("method", figure=None, truth=0.0)
    assert rule.resolve("method", figure=None, truth=1.0).reason == rule.reason


def test_untestable_claim_and_kinds():
    c = Claim(id="attitude", words="ten stars give 0.56 / 0.62", figures=(0.56, 0.62), unit="1", axis="x, y",
              condition="", section="eq 32", kind="bound", untestable="judged by another study")
    assert not c.testable and KINDS == ("method", "performance", "bound") and WORLDS == ("seed", "realistic")
    assert ledger_runs([c]) == ()
    res = evaluate_claims([c], {})
    why = "untestable: judged by another study"
    assert [(r.world, r.verdict, r.no_verdict) for r in res] == [("seed", None, why), ("realistic", None, why)]


def test_claim_result_has_a_verdict_or_says_why_not():
    c = _claim()
    v = judge(0.0, 0.1, 10, Tolerance.around(0.0, 1.0, reason="r", source="user"))
    with pytest.raises(ValueError, match="never both or neither"):
        ClaimResult(c, "seed", None)
    with pytest.raises(ValueError, match="never both or neither"):
        ClaimResult(c, "seed", v, no_verdict="because")
    with pytest.raises(ValueError, match="world"):
        ClaimResult(c, "mars", v)


# ----------------------------------------------------------------------------- the capability
class ClaimingToy(ToyStudy, Claims):
    name = "claimingtoy"

    def claims(self, scenario):
        return (_claim(), _claim(id="variance.published", variant="published"))


def test_claims_capability_and_its_default():
    assert Claims in CAPABILITIES
    assert capability(TOY, Claims).claims(Toy()) == ()            # no claims: an empty ledger
    assert study_claims(TOY, Toy()) == ()
    mine = ClaimingToy()
    assert capability(mine, Claims) is mine
    assert [c.id for c in study_claims(mine, Toy())] == ["variance.method", "variance.published"]


def test_duplicate_claim_ids_are_refused():
    class Twice(ToyStudy, Claims):
        name = "twice"

        def claims(self, scenario):
            return (_claim(), _claim())

    with pytest.raises(ValueError, match="given twice"):
        study_claims(Twice(), Toy())


# ----------------------------------------------------------------------------- evaluation
@pytest.fixture(scope="module")
def toy_runs():
    """The toy has no world effects: one run is both its worlds (400 trials)."""
    res = run_study(TOY, Toy(), trials=400, seed=5)
    return {("toy", "seed"): res, ("toy", "realistic"): res}


def test_method_claims_judge_the_bias_against_the_truth(toy_runs):
    improved = _claim()
    published = _claim(id="variance.published", variant="published",
                       tolerance=ToleranceRule(reason="5 % of the truth", relative=0.05))
    res = evaluate_claims([improved, published], toy_runs)
    assert [(r.claim.id, r.world) for r in res] == [("variance.method", "seed"), ("variance.method", "realistic"),
                                                   ("variance.published", "seed"),
                                                   ("variance.published", "realistic")]
    st = toy_runs[("toy", "seed")].statistics(("variance", "improved", "a"))
    v = res[0].verdict
    assert (v.estimate, v.se, v.n) == (st["bias"], st["se_bias"], 400)
    assert (v.tolerance.low, v.tolerance.high) == pytest.approx((-0.4, 0.4))   # 10 % of sigma^2 = 4
    assert v.outcome == "holds" and res[0].mean == st["mean"] and res[0].truth == 4.0
    # ddof 0 is biased by -sigma^2 / m = -0.5 (12.5 %), against a 5 % tolerance: fails
    w = res[2].verdict
    assert w.outcome == "fails" and w.estimate == pytest.approx(-0.5, abs=4 * w.se)
    for r in res:
        _agrees(r.verdict)
        assert r.sentence == r.verdict.sentence


def test_performance_and_bound_claims_judge_the_truth(toy_runs):
    perf = _claim(id="variance.figure", kind="performance", variant=None, figures=(4.1,),
                  tolerance=ToleranceRule(reason="5 % of the figure", relative=0.05))
    bound = _claim(id="variance.bound", kind="bound", variant=None, figures=(3.9,),
                   tolerance=ToleranceRule(reason="the figure"))
    per_trial = _claim(id="mean.figure", class_name="mean", kind="performance", variant=None, figures=(0.0,),
                       tolerance=ToleranceRule(reason="2 units", absolute=2.0))
    res = evaluate_claims([perf, bound, per_trial], toy_runs)
    p, b, m = res[0], res[2], res[4]
    assert p.verdict.estimate == 4.0 and p.verdict.se == 0.0 and p.verdict.n is None
    assert p.verdict.outcome == "holds" and p.truth == 4.0 and p.ours == "4"  # an unsampled truth: no "+- 0"
    assert b.verdict.outcome == "fails" and "wholly above" in b.sentence and "at most 3.9" in b.sentence
    # per-trial truths (mu_k ~ N(0, 10^2)): their mean over the run's trials, sd / sqrt(n)
    mus = toy_runs[("toy", "seed")].trial_truths[("mean", "published", "a")]
    assert m.verdict.estimate == pytest.approx(float(mus.mean()))
    assert m.verdict.se == pytest.approx(float(mus.std(ddof=1)) / 20.0) and m.verdict.n == 400
    for r in res:
        _agrees(r.verdict)


def test_a_sampled_truth_gives_the_growth_that_settles_it():
    runs = {("toy", w): run_study(TOY, Toy(truth_se=0.1), trials=20, seed=1) for w in WORLDS}
    perf = _claim(id="variance.figure", kind="performance", variant=None, figures=(4.1,),
                  tolerance=ToleranceRule(reason="5 % of the figure", relative=0.05))
    v = evaluate_claims([perf], runs)[0].verdict
    # 4 +- 1.96 x 0.1 straddles 4.1 - 0.205 = 3.895, 0.105 from the truth
    assert v.outcome == "undetermined" and v.n is None and v.n_to_settle is None
    assert v.growth_to_settle == pytest.approx((Z95 * 0.1 / 0.105) ** 2)
    assert "times the truth's samples would settle it" in ledger_markdown(evaluate_claims([perf], runs))


def test_reference_variant_and_input_have_no_verdict(toy_runs):
    class RefToy(ToyStudy):
        name = "reftoy"
        reference_variants = ("published",)

    res = run_study(RefToy(), Toy(), trials=30, seed=2)
    out = evaluate_claims([_claim(variant="published")], {("toy", w): res for w in WORLDS})
    assert all(r.verdict is None and r.no_verdict == "a reference variant: it estimates nothing" for r in out)
    assert out[0].mean == res.statistics(("variance", "published", "a"))["mean"]
    assert "no verdict: a reference variant" in out[0].sentence


@pytest.mark.parametrize("kw,message", [
    (dict(class_name="median"), "class_name: the run has no class 'median'"),
    (dict(axis="b"), "axis: class 'variance' has axes"),
    (dict(unit="px"), "unit: 'px' is not the class's unit '1'"),
    (dict(variant="clever"), "variant: the run has no estimates"),
    (dict(scenario="other"), r"no run of other in the seed's own world"),
])
def test_a_claim_the_runs_cannot_judge_is_refused(toy_runs, kw, message):
    with pytest.raises(ValueError, match=message):
        evaluate_claims([_claim(**kw)], toy_runs)


# ----------------------------------------------------------------------------- two worlds
@pytest.fixture(scope="module")
def world_runs():
    scn = WORLD_TOY.load_scenario(None)
    return {("tw", w): run_study(WORLD_TOY, world_scenario(WORLD_TOY, scn, w), trials=200, seed=3) for w in WORLDS}


def test_world_scenario():
    scn = WORLD_TOY.load_scenario(None)
    assert world_scenario(WORLD_TOY, scn, "realistic") is scn
    seed = world_scenario(WORLD_TOY, scn, "seed")
    assert seed.world.effects.active() == () and scn.world.effects.active()
    assert seed.model_dump(exclude={"world"}) == scn.model_dump(exclude={"world"})
    assert world_scenario(WORLD_TOY, seed, "seed") is seed
    assert world_scenario(TOY, Toy(), "seed") == Toy()        # no world effects: one world
    with pytest.raises(ValueError, match="world"):
        world_scenario(TOY, Toy(), "ideal")


def test_claims_judged_in_both_worlds(world_runs):
    # the noise variance: sigma^2 = 4 in the ideal world, 4 + 0.5^2 with the world's extra noise
    perf = _claim(id="variance.figure", scenario="tw", unit="units^2", kind="performance", variant=None,
                  figures=(4.0,), tolerance=ToleranceRule(reason="2 % of the figure", relative=0.02))
    meth = _claim(scenario="tw", unit="units^2")
    res = evaluate_claims([perf, meth], world_runs)
    assert [r.verdict.outcome for r in res[:2]] == ["holds", "fails"]
    assert res[1].truth == pytest.approx(4.25)
    for r in res:
        _agrees(r.verdict)
    table = ledger_markdown(res)
    assert "holds in the seed's own world, fails in the realistic world" in table


def test_seed_world_run_with_effects_on_is_refused(world_runs):
    runs = {("tw", "seed"): world_runs[("tw", "realistic")], ("tw", "realistic"): world_runs[("tw", "realistic")]}
    with pytest.raises(ValueError, match=r"runs\['tw', 'seed'\]: the seed's own world has every world effect off"):
        evaluate_claims([_claim(scenario="tw", unit="units^2")], runs)


# ----------------------------------------------------------------------------- the table
def _result(claim, world, outcome_args, *, truth=None, mean=None, no_verdict=""):
    v = judge(*outcome_args) if outcome_args else None
    return ClaimResult(claim, world, v, no_verdict, truth=truth, truth_se=0.002 if truth is not None else None,
                       mean=mean, trials=outcome_args[2] if outcome_args else None)


def test_ledger_markdown_table():
    perf = Claim(id="te.x", words="the camera's TE is 1.14 in x | 3 sigma", figures=(1.14,), unit="arcsec, 3 sigma",
                 axis="x", condition="", section="eqs 1-2", kind="performance", scenario="s", class_name="te",
                 tolerance=ToleranceRule(reason="10 %", relative=0.1))
    meth = Claim(id="te.x.m", words="eq 1 measures TE", figures=(1.14,), unit="arcsec, 3 sigma", axis="x",
                 condition="", section="eqs 1-2", kind="method", scenario="s", class_name="te", variant="published",
                 tolerance=ToleranceRule(reason="10 % of the truth", relative=0.1))
    bound = Claim(id="att", words="ten stars give 0.56 / 0.62", figures=(0.56, 0.62), unit="arcsec, 3 sigma",
                  axis="x, y", condition="", section="eq 32", kind="bound", untestable="judged by the attitude study")
    tol_p = Tolerance.around(1.14, 0.114, reason="10 %", source="default")
    tol_m = Tolerance.around(0.0, 0.021, reason="10 % of the truth", source="default")
    results = [
        _result(perf, "seed", (1.17, 0.002, None, tol_p), truth=1.17),
        _result(perf, "realistic", (1.171, 0.002, None, tol_p), truth=1.171),
        _result(meth, "seed", (-0.001, 0.001, 30, tol_m), truth=0.21, mean=0.209),
        _result(meth, "realistic", (0.015, 0.004, 30, tol_m), truth=0.21, mean=0.225),
        ClaimResult(bound, "seed", None, "untestable: judged by the attitude study"),
        ClaimResult(bound, "realistic", None, "untestable: judged by the attitude study"),
    ]
    lines = ledger_markdown(results).splitlines()
    assert lines[0] == "| claim | paper's figure | ours (seed's own world) | ours (realistic world) | verdict |"
    assert lines[1] == "|---|---|---|---|---|"
    assert len(lines) == 2 + 3
    cells = [line[2:-2].split(" | ") for line in (ln.replace("\\|", "¦") for ln in lines[2:])]
    assert all(len(c) == 5 for c in cells)
    p, m, b = cells
    assert p[0].startswith("the camera's TE is 1.14 in x ¦ 3 sigma (performance, x; eqs 1-2)")  # "|" escaped
    assert p[1] == "1.14 arcsec (3 sigma)"
    assert p[2] == "1.17 +- 0.002" and p[3] == "1.171 +- 0.002"
    assert p[4] == "holds in both worlds (tolerance 1.026 to 1.254: 10 %)"
    assert m[1] == "its estimate equals the truth (the paper measured 1.14 arcsec (3 sigma) with it)"
    assert m[2] == f"0.209 vs truth 0.21: bias {fmt(0.209 - 0.21, sign=True)} +- 0.001 (-0.5 %)"
    v = results[3].verdict
    assert v.outcome == "undetermined"
    assert m[4] == (f"holds in the seed's own world, undetermined in the realistic world; realistic world: about "
                    f"{v.n_to_settle} trials would settle it (tolerance -0.021 to 0.021: 10 % of the truth)")
    assert b[1] == "0.56 / 0.62 arcsec (3 sigma)" and b[2] == b[3] == "-"
    assert b[4] == "untestable: judged by the attitude study"
