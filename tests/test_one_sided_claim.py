"""One-sided ("at most") claims (ClassSpec.at_most): a stated bound holds when the actual is at or
below it, not only when the two are equal; the findings (budget.runner.findings) and the
robustness verdicts (budget.runner.robustness_verdicts, the findings' class verdict) both read it. On the toy world
(tests/toys/toy_world_study.py), whose offset effect moves the sample mean by exactly its value."""

import tomllib

import pytest
from toy_world_study import DEFAULT_TEXT, ToyWorldStudy

from budget.runner.findings import findings
from budget.runner.robustness import run_robustness
from budget.runner.run import run_study
from budget.runner.study import ClassSpec


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


# 1000 trials, seed fixed: the mean's error has sd sigma / sqrt(m) = 2 / sqrt(8) = 0.707 per
# trial, so its bias has se 0.0224 and its 95 % interval +- 0.044; the truths' rms is about
# 5.1, so the tolerance is 10 % of it, 0.51: an offset of 1.0 lies wholly outside it (two-sided
# either way; one-sided only below the truth), and the bias part's verdict says so
TRIALS = 1000


@pytest.mark.parametrize("offset, one_sided", [(1.0, "holds"), (-1.0, "fails")])
def test_robustness_reads_the_side(offset, one_sided):
    cells = {}
    for study in (ToyWorldStudy(), _BoundToy()):
        res = run_robustness(study, _scenario(study, offset), trials=TRIALS, seed=11)
        cells[type(study).__name__] = res.to_json()["cases"]["offset_units"]["classes"]["mean"]["a"]["published"]
    two, one = cells["ToyWorldStudy"], cells["_BoundToy"]
    assert two["bias"] == pytest.approx(offset, abs=5 * two["se_bias"])
    assert two["bias_verdict"] == "fails"  # outside the tolerance either way
    assert one["bias"] == two["bias"] and one["bias_verdict"] == one_sided
    assert one["tolerance"]["high"] is None and one["tolerance"]["low"] < 0  # one-sided


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
