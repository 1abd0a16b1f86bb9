"""The core toy (tests/toys/toy_study.py) with sized truths (SizedTruths), to test the
runner's truth sizing (tests/test_truth_sizing.py): its ``truth_size_for`` returns a scenario
whose truth standard error *is* the target, so a test reads back exactly what the runner
asked for. Imported by spawned workers too."""

from budget.runner.capabilities import SizedTruths
from toy_study import ToyStudy


class SizedToyStudy(ToyStudy, SizedTruths):
    name = "sized_toy"

    def truth_size_for(self, scenario, seed, target_se):
        return scenario.model_copy(update={"truth_se": float(target_se[("variance", "a")])})


STUDY = SizedToyStudy()
