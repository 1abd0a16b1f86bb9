"""The toy study (tests/toy_study.py) with a truth whose size follows the runner's target:
its ``truth_size_for`` returns a scenario whose truth standard error *is* the target, so a
test reads back exactly what the runner asked for. Imported by spawned workers too."""

from budget.runner.capabilities import SizedTruths
from toy_study import ToyStudy


class SizedToyStudy(ToyStudy, SizedTruths):
    name = "sized_toy"

    def truth_size_for(self, scenario, seed, target_se):
        return scenario.model_copy(update={"truth_se": float(target_se[("variance", "a")])})


STUDY = SizedToyStudy()
