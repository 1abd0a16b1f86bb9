"""The world toy: a study with a world richer than its lab (WorldEffects), whose answers are
known analytically, to test the robustness runner (budget.runner.robustness:
tests/test_robustness.py, test_one_sided_claim.py) and to give benchmarks/bench_robustness.py
a study of chosen cost per trial. Not a physical model.

Each trial draws a level ``mu_k ~ N(mu_center, mu_spread^2)`` and ``m`` samples of it with
noise ``sigma``; the lab knows ``sigma`` and nothing of the world's effects. The world
(``[world.effects]``, 0 = off) changes the data, in this order (sample ``i = 0..m-1``,
``n_i`` the unit noise, ``w_i`` a second unit-normal draw that is always made, so that
every case consumes the same random numbers: common random numbers):

1. ``correlation_rho``: the noise is AR(1), ``n_0 = z_0``, ``n_i = rho n_(i-1) +
   sqrt(1 - rho^2) z_i`` (stationary, unit variance: the stated sigma still holds per
   sample, the mean's variance does not);
2. ``extra_noise_units``: ``+ extra * w_i``, noise the stated sigma leaves out;
3. ``drift_units_per_sample``: ``+ d * i``, so the mean is biased by ``d (m - 1) / 2``;
4. ``nonlinearity_per_unit``: ``x -> x + beta x^2``;
5. ``scale_error_ratio``: ``x -> (1 + k) x``, so the mean's estimate is ``(1 + k)`` times
   the one without it (exactly, to rounding);
6. ``offset_units``: ``x -> x + b``, so the mean's estimate moves by exactly ``b``.

Classes:

* ``mean`` (per-trial truth ``mu_k``): the sample mean, stated 1-sigma ``sigma / sqrt(m)``;
* ``variance`` (fixed truth: the variance of the noise, ``sigma^2 + extra^2``, exact):
  ``published`` with ddof 0 (biased by ``-truth / m`` in the ideal world), ``improved``
  with ddof 1. Only ``extra_noise_units`` changes a truth
  (:meth:`ToyWorldStudy.truth_depends_on_effects`).

``busy_work`` repeats a small matrix computation per trial that changes no result: it
gives the toy a real study's cost per trial for benchmarks.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from budget.runner.capabilities import WorldEffects
from budget.runner.study import ClassSpec, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import StrictModel, ValidationSettings, model_hash, validate_model
from simcam.effects import EffectsBase, WorldBase


class ToyEffects(EffectsBase):
    correlation_rho: float = Field(0.3, ge=0.0, lt=1.0, description="AR(1) correlation of successive samples")
    extra_noise_units: float = Field(0.5, ge=0.0, description="noise the stated sigma leaves out")
    drift_units_per_sample: float = Field(0.01, description="a linear drift over the samples")
    nonlinearity_per_unit: float = Field(0.001, description="a quadratic response")
    scale_error_ratio: float = Field(0.01, description="a gain error")
    offset_units: float = Field(0.1, description="a constant offset")


class ToyWorld(WorldBase):
    effects: ToyEffects = ToyEffects()


class ToyWorldScenario(StrictModel):
    name: str = "toy-world"
    m: int = Field(8, ge=2)
    sigma: float = Field(2.0, gt=0.0)
    mu_center: float = 5.0
    mu_spread: float = Field(1.0, ge=0.0)
    trials: int = Field(50, ge=2)
    busy_work: int = Field(0, ge=0)
    world: ToyWorld = ToyWorld()

    @property
    def hash(self) -> str:
        return model_hash(self)

    @property
    def validation(self) -> ValidationSettings:
        """The run settings: ``trials`` of the scenario, 100 between two convergence checks."""
        return ValidationSettings(trials=self.trials, max_trials=20000, batch_trials=100)

    @property
    def source(self) -> str:
        return "toy world"

    def to_toml(self) -> str:
        import tomli_w

        return tomli_w.dumps(self.model_dump(mode="json"))


DEFAULT_TEXT = """\
name = "toy-world"
m = 8
sigma = 2.0

[world.effects]               # 0 = off
correlation_rho = 0.3         # AR(1) correlation of successive samples
extra_noise_units = 0.5       # noise the stated sigma leaves out
drift_units_per_sample = 0.01 # a linear drift over the samples
nonlinearity_per_unit = 0.001 # a quadratic response
scale_error_ratio = 0.01      # a gain error
offset_units = 0.1            # a constant offset
"""


def _busy(n: int) -> None:
    """Work that changes no result (a real trial's cost for benchmarks)."""
    a = np.full((48, 48), 0.5)
    for _ in range(n):
        a = np.tanh(a @ a * 0.01)


def default_text() -> str:
    """The toy world's embedded default scenario."""
    return DEFAULT_TEXT


def from_dict(data: dict, *, source: str) -> ToyWorldScenario:
    """The toy world scenario of a mapping."""
    return validate_model(ToyWorldScenario, data, source=source)



class ToyWorldStudy(Study, WorldEffects):
    name = "toyworld"
    title = "toy world study"
    seed_document = "none"
    scenario_module = __name__  # this module: default_text and from_dict above

    def __init__(self, *, depends: set[str] | None = frozenset({"extra_noise_units"}),
                 claims: dict | None = None):
        self.depends = None if depends is None else set(depends)
        self.claims = dict(claims or {})

    def classes(self, scenario):
        return (ClassSpec("mean", "sample mean", "units", ("a",), "mean of m samples", per_trial_truth=True),
                ClassSpec("variance", "sample variance", "units^2", ("a",), "variance of the noise"))

    def truth_depends_on_effects(self, scenario):
        return None if self.depends is None else set(self.depends)

    def claim(self, scenario, class_name, variant):
        return self.claims.get((class_name, variant))

    @staticmethod
    def data(scenario, seed, k):
        """The trial's level ``mu`` and samples ``x`` (see the module docstring)."""
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        mu = rng.normal(scenario.mu_center, scenario.mu_spread)
        z = rng.standard_normal(scenario.m)
        w = rng.standard_normal(scenario.m)
        e = scenario.world.effects
        if e.correlation_rho != 0.0:
            n = np.empty_like(z)
            n[0] = z[0]
            c = np.sqrt(1.0 - e.correlation_rho**2)
            for i in range(1, z.size):
                n[i] = e.correlation_rho * n[i - 1] + c * z[i]
        else:
            n = z
        x = mu + scenario.sigma * n
        if e.extra_noise_units != 0.0:
            x = x + e.extra_noise_units * w
        if e.drift_units_per_sample != 0.0:
            x = x + e.drift_units_per_sample * np.arange(x.size)
        if e.nonlinearity_per_unit != 0.0:
            x = x + e.nonlinearity_per_unit * x * x
        if e.scale_error_ratio != 0.0:
            x = (1.0 + e.scale_error_ratio) * x
        if e.offset_units != 0.0:
            x = x + e.offset_units
        return mu, x

    def trial(self, scenario, seed, k):
        _busy(scenario.busy_work)
        mu, x = self.data(scenario, seed, k)
        key = ("mean", "published", "a")
        return TrialResult(
            estimates={key: float(x.mean()), ("variance", "published", "a"): float(x.var(ddof=0)),
                       ("variance", "improved", "a"): float(x.var(ddof=1))},
            truths={key: float(mu)}, sigmas={key: scenario.sigma / np.sqrt(scenario.m)})

    #: how many times :meth:`truths` ran in this process (tests count the sharing)
    truth_calls = 0

    def truths(self, scenario, seed):
        type(self).truth_calls += 1
        _busy(10 * scenario.busy_work)
        return {("variance", "a"): Truth(scenario.sigma**2 + scenario.world.effects.extra_noise_units**2, 0.0)}


STUDY = ToyWorldStudy()
