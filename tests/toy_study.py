"""A study whose answers are known analytically, to test the runner (not a physical model).

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

from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence


class Toy:
    hash = "toy"
    name = "toy"

    def __init__(self, m=8, sigma=2.0, trials=50, truth_se=0.0, max_trials=20000):
        self.m, self.sigma, self.trials = m, sigma, trials
        self.truth_se, self.max_trials = truth_se, max_trials

    def model_dump(self, mode="json", exclude_none=True):
        return {"m": self.m, "sigma": self.sigma, "trials": self.trials,
                "truth_se": self.truth_se, "max_trials": self.max_trials}


class ToyStudy(Study):
    name = "toy"
    title = "toy study"
    seed_document = "none"

    def default_text(self):
        return "m = 8\n"

    def from_dict(self, data, *, source):
        return Toy(**data)

    def classes(self, scenario):
        return (ClassSpec("mean", "sample mean", "1", ("a",), "mean of m draws", per_trial_truth=True),
                ClassSpec("variance", "sample variance", "1", ("a",), "variance of m draws"))

    def default_trials(self, scenario):
        return scenario.trials

    def max_trials(self, scenario):
        return scenario.max_trials

    def batch_trials(self, scenario):
        return 100

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
