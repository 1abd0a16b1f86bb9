"""A study written against the core contract alone, in this module and registered nowhere: the
length of a ruler measured from N noisy readings (the truth known), run through
``budget.validate`` and ``run_study`` on two workers (the same numbers), its report written,
and its findings checked against the analytic answers.

Each trial reads the ruler ``N`` times, ``x_i = L + sigma z_i``:

* ``length`` (mm, truth ``L``): the readings' mean, both variants; unbiased, spread
  ``sigma / sqrt(N)``;
* ``reading_noise`` (mm, truth ``sigma``): ``published`` the sample standard deviation
  (ddof 1), whose mean is ``c4(N) sigma`` with ``c4(N) = sqrt(2 / (N - 1)) G(N / 2) / G((N - 1) / 2)``,
  so biased by ``(c4 - 1) sigma``; ``improved`` divides it by ``c4`` (unbiased).
"""

from __future__ import annotations

import json
import math

import numpy as np
from pydantic import Field

import budget
from budget.runner import registry
from budget.runner.report import write_report
from budget.runner.run import run_study
from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ScenarioBase, ValidationSettings, validate_model


class RulerScenario(ScenarioBase):
    """A ruler of ``length_mm`` read ``readings`` times with noise ``sigma_mm`` each."""

    name: str = "ruler"
    length_mm: float = Field(300.0, gt=0.0)
    sigma_mm: float = Field(0.5, gt=0.0)
    readings: int = Field(4, ge=2)
    validation: ValidationSettings = ValidationSettings(trials=1000)


def default_text() -> str:
    """The embedded default: the model's defaults."""
    return 'name = "ruler"\n'


def from_dict(data: dict, *, source: str) -> RulerScenario:
    """The ruler scenario of a mapping."""
    return validate_model(RulerScenario, data, source=source)


def c4(n: int) -> float:
    """The mean of the sample standard deviation of ``n`` normal draws, in units of sigma."""
    return math.sqrt(2.0 / (n - 1)) * math.exp(math.lgamma(n / 2) - math.lgamma((n - 1) / 2))


class RulerStudy(Study):
    name = "ruler"
    title = "ruler length from noisy readings"
    seed_document = "none"
    scenario_module = __name__  # this module: default_text and from_dict above

    def classes(self, scenario):
        return (ClassSpec("length", "ruler length", "mm", ("l",), "the mean of the readings"),
                ClassSpec("reading_noise", "reading noise", "mm", ("l",), "the readings' standard deviation"))

    def trial(self, scenario, seed, k):
        x = np.random.default_rng(trial_seed_sequence(seed, k)).normal(scenario.length_mm, scenario.sigma_mm,
                                                                       scenario.readings)
        s = float(x.std(ddof=1))
        return TrialResult({("length", "published", "l"): float(x.mean()), ("length", "improved", "l"): float(x.mean()),
                            ("reading_noise", "published", "l"): s,
                            ("reading_noise", "improved", "l"): s / c4(scenario.readings)})

    def truths(self, scenario, seed):
        return {("length", "l"): Truth(scenario.length_mm), ("reading_noise", "l"): Truth(scenario.sigma_mm)}


STUDY = RulerStudy()
N_TRIALS = 1000


def test_a_study_on_the_core_alone_validates_on_one_and_two_workers_and_finds_the_analytic_answers(tmp_path):
    """1000 trials, N = 4 readings of sigma = 0.5 mm (seed 3). The published noise is biased by
    (c4(4) - 1) sigma = -0.0394 mm against a standard error of sigma sqrt(1 - c4^2) / sqrt(1000)
    = 0.0061 mm (6.4 of them): found, and equal to the analytic bias within 4 of its standard
    errors; the other keys recovered (their biases within 4 standard errors of 0). The length's
    spread is sigma / sqrt(N) within 4 standard errors of a sample sd (its sd / sqrt(2 (n - 1)))."""
    assert registry.entry(STUDY.name) is None  # registered nowhere
    scn = RulerScenario()
    one = budget.validate(STUDY, scn, trials=N_TRIALS, seed=3, workers=1)
    two = run_study(STUDY, scn, trials=N_TRIALS, seed=3, workers=2)
    assert one.trials == two.trials == N_TRIALS
    for key, x in one.samples.items():
        assert np.array_equal(x, two.samples[key]), key
    # as JSON text: a NaN (a statistic with no value) equals itself there
    assert json.dumps(one.to_json()["classes"]) == json.dumps(two.to_json()["classes"])
    assert one.to_json()["findings"] == two.to_json()["findings"]

    sigma, n_read = scn.sigma_mm, scn.readings
    pub = one.statistics(("reading_noise", "published", "l"))
    assert pub["bias_significant"]
    assert abs(pub["bias"] - (c4(n_read) - 1.0) * sigma) <= 4 * pub["se_bias"]
    for key in (("length", "published", "l"), ("length", "improved", "l"), ("reading_noise", "improved", "l")):
        st = one.statistics(key)
        assert not st["bias_significant"] and abs(st["bias"]) <= 4 * st["se_bias"], key
    length = one.statistics(("length", "improved", "l"))
    expected_sd = sigma / math.sqrt(n_read)
    assert abs(length["std"] - expected_sd) <= 4 * expected_sd / math.sqrt(2 * (N_TRIALS - 1))

    found = {(f["class"], f["variant"]): f["recovered"] for f in one.to_json()["findings"]}
    assert found == {("length", "published"): True, ("length", "improved"): True,
                     ("reading_noise", "published"): False, ("reading_noise", "improved"): True}

    write_report(one, tmp_path / "rep")
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "ruler length from noisy readings" in md and "## Findings" in md and "reading noise" in md
    assert json.loads((tmp_path / "rep" / "summary.json").read_text())["classes"] == \
        json.loads(json.dumps(one.to_json()["classes"]))
    assert (tmp_path / "rep" / "report.html").is_file()
