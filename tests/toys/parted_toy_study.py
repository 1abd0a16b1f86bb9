"""The sized toy (tests/toys/sized_toy_study.py) with truths in parts (SplitTruths), to test
how the scheduler spreads a truth over the workers (tests/test_scheduler.py,
test_runner_scheduling.py). Its truths are computed in pieces, as the star camera's are:
each piece a seeded draw whose count follows the runner's target, the truth their mean.
``truths`` computes the same pieces in one go, so a run on one worker (``truths``) and on
several (pieces as tasks, ``truth_parts``) must agree bit for bit. Imported by spawned
workers too."""

import numpy as np

from budget.runner.capabilities import SplitTruths
from budget.runner.study import Truth
from sized_toy_study import SizedToyStudy

#: pieces of the truth
N_PARTS = 7


class PartedToyStudy(SizedToyStudy, SplitTruths):
    name = "parted_toy"

    def _draws(self, scenario) -> int:
        # more draws for a smaller target (any rule will do: the test compares runs)
        return int(min(2000, max(10, 1.0 / max(scenario.truth_se, 1e-6))))

    def truth_parts(self, scenario, seed):
        return list(range(N_PARTS))

    def truth_part(self, scenario, seed, part):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(2**31, part)))
        return rng.normal(scenario.sigma**2, 1.0, self._draws(scenario))

    def truths_from_parts(self, scenario, seed, results):
        x = np.concatenate(results)
        return {("variance", "a"): Truth(float(x.mean()), float(x.std(ddof=1) / np.sqrt(x.size)))}

    def truths(self, scenario, seed):
        return self.truths_from_parts(scenario, seed, [self.truth_part(scenario, seed, p)
                                                       for p in self.truth_parts(scenario, seed)])


STUDY = PartedToyStudy()
