"""The toy study (tests/toy_study.py) with a truth whose size follows the runner's target:
its ``truth_size_for`` returns a scenario whose truth standard error *is* the target, so a
test reads back exactly what the runner asked for. Imported by spawned workers too."""

import copy

from toy_study import ToyStudy


class SizedToyStudy(ToyStudy):
    name = "sized_toy"

    def truth_size_for(self, scenario, seed, target_se):
        out = copy.copy(scenario)
        out.truth_se = float(target_se[("variance", "a")])
        return out


STUDY = SizedToyStudy()
