"""The core toy: a study of the three core methods only (classes, trial, truths) whose answers
are known analytically, to test the runner, the statistics, the findings and the reports
(tests/test_runner.py, test_api.py, test_scheduler.py and others); not a physical model.

Each trial draws ``m`` values from N(mu_k, sigma^2), with mu_k itself drawn per trial:

* class ``mean`` (per-trial truth mu_k): estimate the sample mean; stated 1-sigma
  uncertainty sigma / sqrt(m) (sigma known), so the error is exactly N(0, sigma^2/m) and
  the 1-sigma interval covers the truth in 68.27 % of trials;
* class ``variance`` (fixed truth sigma^2): ``published`` is the variance with
  ddof = 0, biased by exactly -sigma^2 / m; ``improved`` is the unbiased ddof = 1. The truth
  is exact; ``truth_se`` gives it a stated Monte Carlo standard error (as a truth computed
  from finitely many frames has), to test that the runner carries it into ``se_bias`` and
  into adaptive stopping.
"""

import numpy as np
from pydantic import model_validator

from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ScenarioBase, ValidationSettings


class Toy(ScenarioBase):
    """The toy's scenario: ``Toy(m=8, sigma=2.0, trials=50, truth_se=0.0, max_trials=20000)``
    (``trials`` and ``max_trials`` go to its ``validation``; 100 trials between two
    convergence checks)."""

    name: str = "toy"
    m: int = 8
    sigma: float = 2.0
    truth_se: float = 0.0
    validation: ValidationSettings = ValidationSettings(trials=50, max_trials=20000, batch_trials=100)

    @model_validator(mode="before")
    @classmethod
    def _counts_to_validation(cls, data):
        if isinstance(data, dict) and ({"trials", "max_trials"} & data.keys()):
            data = dict(data)
            counts = {k: data.pop(k) for k in ("trials", "max_trials") if k in data}
            data["validation"] = {"trials": 50, "max_trials": 20000, "batch_trials": 100, **counts}
        return data


def default_text() -> str:
    """The toy's embedded default scenario."""
    return "m = 8\n"


def from_dict(data: dict, *, source: str) -> Toy:
    """The toy scenario of a mapping."""
    return Toy(**data)



class ToyStudy(Study):
    name = "toy"
    title = "toy study"
    seed_document = "none"
    scenario_module = __name__  # this module: default_text and from_dict above

    def classes(self, scenario):
        return (ClassSpec("mean", "sample mean", "1", ("a",), "mean of m draws", per_trial_truth=True),
                ClassSpec("variance", "sample variance", "1", ("a",), "variance of m draws"))

    def trial(self, scenario, seed, k):
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        mu = rng.normal(0.0, 10.0)
        x = rng.normal(mu, scenario.sigma, scenario.m)
        key = ("mean", "published", "a")
        return TrialResult(
            estimates={key: float(x.mean()), ("variance", "published", "a"): float(x.var(ddof=0)),
                       ("variance", "improved", "a"): float(x.var(ddof=1))},
            truths={key: mu}, sigmas={key: scenario.sigma / np.sqrt(scenario.m)})

    def truths(self, scenario, seed):
        return {("variance", "a"): Truth(scenario.sigma**2, scenario.truth_se)}


STUDY = ToyStudy()
