"""One-sided ("at most") claims (ClassSpec.at_most): a stated bound holds when the actual is at or
below it, not only when the two are equal; the findings (budget.runner.findings) and the
robustness verdicts (budget.runner.robustness.claim_holds) both read it. On the toy world
(tests/toys/toy_world_study.py), whose offset effect moves the sample mean by exactly its value."""

import tomllib

import pytest

from budget.runner.findings import findings
from budget.runner.robustness import claim_holds, run_robustness
from budget.runner.run import run_study
from budget.runner.study import ClassSpec

from toy_world_study import DEFAULT_TEXT, ToyWorldStudy


class _BoundToy(ToyWorldStudy):
    """The toy with its mean's claim one-sided: the estimate a bound of the trial's level."""

    role = "result"

    def classes(self, scenario):
        mean, var = super().classes(scenario)
        return (ClassSpec(mean.name, mean.label, mean.unit, mean.axes, mean.description, per_trial_truth=True,
                          role=self.role, at_most=True), var)


class _StatedBoundToy(_BoundToy):
    role = "stated"


def _scenario(study, offset):
    """Every effect off but the offset: the mean's estimate moves by exactly ``offset``."""
    data = tomllib.loads(DEFAULT_TEXT)
    data["world"]["effects"] = {k: 0.0 for k in data["world"]["effects"]} | {"offset_units": offset}
    return study.from_dict(data, source="one-sided test")


def test_claim_holds_one_sided():
    # two-sided: a bias of 10 se either way fails
    assert not claim_holds(bias=1.0, se_bias=0.1) and not claim_holds(bias=-1.0, se_bias=0.1)
    # one-sided (the estimate a bound): above the truth by any amount holds; below only within 3 se
    assert claim_holds(bias=1.0, se_bias=0.1, at_most=True)
    assert claim_holds(bias=-0.29, se_bias=0.1, at_most=True)
    assert not claim_holds(bias=-0.31, se_bias=0.1, at_most=True)
    # with a claimed accuracy A: the shortfall -b + 3 se within it
    assert claim_holds(bias=-0.1, se_bias=0.01, claim=0.14, at_most=True)
    assert not claim_holds(bias=-0.1, se_bias=0.01, claim=0.12, at_most=True)
    assert claim_holds(bias=5.0, se_bias=0.01, claim=0.12, at_most=True)
    # a deterministic bound (se 0) above its truth holds; below by more than rounding fails
    assert claim_holds(bias=0.5, se_bias=0.0, scale=5.0, at_most=True)
    assert not claim_holds(bias=-1e-6, se_bias=0.0, scale=5.0, at_most=True)


# 1000 trials, seed fixed: the mean's error has sd sigma / sqrt(m) = 2 / sqrt(8) = 0.707 per
# trial, so its bias has se 0.0224 and the offset 0.15 is 6.7 se from zero; the stated sigma's
# coverage moves to P(|z + 0.212| <= 1) = 0.672, inside the band 0.683 +- 0.044
TRIALS = 1000


@pytest.mark.parametrize("offset, holds_one_sided", [(0.15, True), (-0.15, False)])
def test_robustness_reads_the_side(offset, holds_one_sided):
    cells = {}
    for study in (ToyWorldStudy(), _BoundToy()):
        res = run_robustness(study, _scenario(study, offset), trials=TRIALS, seed=11)
        cells[type(study).__name__] = res.to_json()["cases"]["offset_units"]["classes"]["mean"]["a"]["published"]
    two, one = cells["ToyWorldStudy"], cells["_BoundToy"]
    assert two["bias"] == pytest.approx(offset, abs=5 * two["se_bias"])
    assert two["claim_holds"] is False  # significant either way: not equal
    assert one["bias"] == two["bias"] and one["claim_holds"] is holds_one_sided


@pytest.mark.parametrize("study_cls", [_BoundToy, _StatedBoundToy])
def test_findings_read_the_side(study_cls):
    study = study_cls()
    # the truth is about 5 units, so the default tolerance is about -0.5: 0.15 above holds, and
    # 1.0 below fails far beyond the bias's standard error (0.022 at these trials)
    for offset in (0.15, -1.0):
        res = run_study(study, _scenario(study, offset), trials=TRIALS, seed=11, workers=1, prewarm=False)
        (f,) = [f for f in findings(res) if f["class"] == "mean"]
        st = res.statistics(("mean", "published", "a"))
        assert st["bias_significant"]  # the statistics are the same as for a two-sided claim
        lo, hi = f["tolerance"]["low"], f["tolerance"]["high"]
        assert hi is None and lo < 0  # one-sided: the bound at or above the truth, less the tolerance
        if offset > 0:
            assert f["recovered"] and f["rule"] == "holds"
        else:
            assert not f["recovered"] and f["rule"] == "fails", f["text"]


def test_linecam_los_max_is_a_bound():
    from budget.linecam.study import STUDY

    scn = STUDY.load_scenario()
    spec = {c.name: c for c in STUDY.classes(scn)}
    assert spec["los_max"].at_most and spec["los_max"].role == "stated"
    assert not any(c.at_most for n, c in spec.items() if n != "los_max")
    # its likely cause only where the actual exceeds the stated bound
    key = ("los_max", "improved", "along")
    assert STUDY.likely_cause(None, key, {"bias": -0.17}) and "exceeds" in STUDY.likely_cause(None, key, {"bias": -0.17})
    assert STUDY.likely_cause(None, key, {"bias": 0.3}) is None
