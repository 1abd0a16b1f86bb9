"""A toy study that declares claims (the :class:`~budget.runner.capabilities.Claims`
capability) on tests/toys/toy_world_study.py's world, for ``budget claims``, the reports'
ledger and ``--tolerance CLASS=VALUE`` (tests/test_claims_cmd.py).

Its realistic world is the toy world with one effect on, the extra noise (0.5 units): its
answers are analytic. The noise variance is ``sigma^2 = 4`` in the seed's own world and
``4 + 0.5^2 = 4.25`` in the realistic one; the sample variance with ``ddof=0``
(``published``) is biased by ``-v / m`` (``m = 8``: -12.5 %), with ``ddof=1`` (``improved``)
unbiased; either has a per-trial sd of ``v sqrt(2 / 7)``.
"""

from __future__ import annotations

from toy_world_study import ToyWorldStudy

from budget.runner.capabilities import Claims
from budget.runner.claims import Claim, ToleranceRule

#: the one scenario its claims name
SCENARIO = "embedded:default"
REL10 = ToleranceRule(reason="10 % of the truth", relative=0.10)
REL2 = ToleranceRule(reason="2 % of the truth", relative=0.02)

CLAIMS = (
    Claim(id="variance.figure", words="the noise variance is 4 units^2", figures=(4.0,), unit="units^2", axis="a",
          condition="the toy's sensor", section="eq 1", kind="performance", scenario=SCENARIO,
          class_name="variance", tolerance=ToleranceRule(reason="2 % of the figure", relative=0.02)),
    Claim(id="variance.published", words="the variance of the samples (ddof 0) measures the noise variance",
          figures=(), unit="units^2", axis="a", condition="m = 8 samples", section="eq 2", kind="method",
          scenario=SCENARIO, class_name="variance", variant="published", tolerance=REL2),
    Claim(id="variance.improved", words="the unbiased sample variance measures the noise variance", figures=(),
          unit="units^2", axis="a", condition="m = 8 samples", section="eq 3", kind="method", scenario=SCENARIO,
          class_name="variance", variant="improved", tolerance=REL10),
    Claim(id="mean.bound", words="the mean is known to 1 unit", figures=(1.0,), unit="units", axis="a",
          condition="", section="eq 4", kind="bound", untestable="the toy has no such figure"),
)


class ClaimsToyStudy(ToyWorldStudy, Claims):
    name = "claimstoy"
    title = "claims toy study"
    seed_document = "999"

    def __init__(self):
        super().__init__()
        del self.claims  # the capability's method, not the robustness claims' dict

    def claim(self, scenario, class_name, variant):
        return None

    def claims(self, scenario):
        return CLAIMS

    def load_scenario(self, path=None):
        """The embedded default (also by the name the claims give it) with the extra noise the
        only effect on."""
        if path not in (None, SCENARIO):
            return super().load_scenario(path)
        data = super().load_scenario(None).model_dump(mode="json")
        data["world"]["effects"] = {k: 0.0 for k in data["world"]["effects"]} | {"extra_noise_units": 0.5}
        return self.from_dict(data, source="embedded claims toy default")


STUDY = ClaimsToyStudy()
