"""The full toy: a small study with every capability of :mod:`budget.runner.capabilities`, each
answering what is known analytically, so that tests/test_capabilities.py can check that the
machinery uses each one (not a physical model).

* ``offset`` (px): the mean of ``frames`` frames, each ``offset_px`` plus noise ``sigma_px``
  (``sqrt(LINE_FACTOR)`` times more in the line pattern); truth ``offset_px``. Plan optimum
  ``(z s / V)^2`` frames; the world's drift moves the estimate by itself, past :data:`CLAIM_PX`.
* ``noise`` (px^2): the variance of ``D`` dark frames, ``published`` ddof 0 (bias ``-v / D``),
  ``improved`` ddof 1; truth ``v = sigma^2 + extra^2`` (the world's extra noise), sampled from
  ``truth_draws`` draws in :data:`N_PARTS` parts (standard error ``v sqrt(2 / n)``).
"""

import math
import os
from typing import Literal

import numpy as np
from pydantic import Field

from budget.runner.capabilities import (BatchedTrials, CheckedScenario, Claims, Plannable, Prepared, Presented,
                                        ProtocolShapes, SeparablePlans, SharedTruths, SizedTruths, SplitTruths,
                                        Warmup, WorldEffects)
from budget.runner.claims import Claim, ToleranceRule
from budget.runner.numbers import fmt
from budget.runner.study import (TRUTH_SPAWN_KEY, ClassSpec, Knob, ReportSection, Study, TrialResult, Truth,
                                 trial_seed_sequence)
from simcam.config_base import ScenarioBase, validate_model
from simcam.effects import EffectsBase, WorldBase
from simcam.infra.errors import ScenarioError

#: the offset's claim (px); the truth's parts; a line frame's noise variance and time over a grid
#: frame's; the lab's times (s) of a grid frame, a dark frame and the set-up
CLAIM_PX, N_PARTS, LINE_FACTOR, LINE_TIME, FRAME_S, DARK_FRAME_S, SETUP_S = 0.02, 7, 2.0, 0.25, 2.0, 1.0, 600.0
#: processes where ``worker_init`` ran (the toy's start-up work is noting its process)
STARTED: set[int] = set()


class FullEffects(EffectsBase):
    drift_px: float = Field(0.05, description="the offset's drift during the frames (a toy's value)")
    extra_noise_px: float = Field(0.1, description="frame noise the lab leaves out (a toy's value)")


class FullWorld(WorldBase):
    effects: FullEffects = FullEffects()


class FullToy(ScenarioBase):
    offset_px: float = 0.5
    sigma_px: float = Field(0.2, gt=0.0)
    frames: int = Field(100, ge=1)
    dark_frames: int = Field(4, ge=2)
    pattern: Literal["grid", "line"] = "grid"
    truth_draws: int = Field(20_000, ge=1)
    world: FullWorld = FullWorld()


def default_text() -> str:
    """The embedded default: the model's defaults."""
    return 'name = "full toy"\n'


def from_dict(data: dict, *, source: str) -> FullToy:
    """The scenario of a mapping (a ScenarioError naming ``source`` and the field)."""
    return validate_model(FullToy, data, source=source)


class FullToyStudy(Study, Prepared, CheckedScenario, BatchedTrials, Warmup, SplitTruths, SizedTruths, SharedTruths,
                   WorldEffects, Plannable, ProtocolShapes, SeparablePlans, Presented, Claims):
    name, title, seed_document = "fulltoy", "full toy (every capability)", "none"
    scenario_module = __name__  # this module: default_text and from_dict above

    def classes(self, scenario):
        return (ClassSpec("offset", "offset", "px", ("x",), "the offset the frames average"),
                ClassSpec("noise", "noise variance", "px^2", ("x",), "the variance of a frame's noise"))

    @staticmethod
    def _data(scenario, seed, k, frame_sigma):
        """Trial ``k``'s frames and dark frames (the same draws whatever the effects)."""
        e, f, d = scenario.world.effects, scenario.frames, scenario.dark_frames
        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        z, zx, zd, zdx = np.split(rng.standard_normal(2 * (f + d)), [f, 2 * f, 2 * f + d])
        frames = scenario.offset_px + e.drift_px + frame_sigma * z + e.extra_noise_px * zx
        return frames, scenario.sigma_px * zd + e.extra_noise_px * zdx

    @staticmethod
    def _result(mean, var0, var1) -> TrialResult:
        return TrialResult({("offset", "published", "x"): float(mean), ("offset", "improved", "x"): float(mean),
                            ("noise", "published", "x"): float(var0), ("noise", "improved", "x"): float(var1)})

    def trial(self, scenario, seed, k):
        x, d = self._data(scenario, seed, k, self.prepared(scenario))
        return self._result(x.mean(), d.var(ddof=0), d.var(ddof=1))

    def truths(self, scenario, seed):
        return self.truths_from_parts(scenario, seed, [self.truth_part(scenario, seed, p) for p in range(N_PARTS)])

    def setup(self, scenario):  # a frame's noise in the scenario's pattern
        return scenario.sigma_px * math.sqrt(LINE_FACTOR if scenario.pattern == "line" else 1.0)

    def setup_key(self, scenario):  # every field but the truth's sampling size, which setup never reads
        return scenario.model_copy(update={"truth_draws": 0}).hash

    def check(self, scenario, *, where):
        if scenario.truth_draws < N_PARTS:
            raise ScenarioError(f"{where}: truth_draws: {scenario.truth_draws} draws for the truth's {N_PARTS} "
                                "parts: every part needs one at least")

    def trial_batch(self, scenario, seed, ks):  # the draws trial by trial, the statistics at once
        s = self.prepared(scenario)
        x, d = (np.array(a) for a in zip(*(self._data(scenario, seed, k, s) for k in ks)))
        return [self._result(*v) for v in zip(x.mean(axis=1), d.var(axis=1, ddof=0), d.var(axis=1, ddof=1))]

    def worker_init(self):
        STARTED.add(os.getpid())

    def truth_parts(self, scenario, seed):
        return list(range(N_PARTS))

    def truth_part(self, scenario, seed, part):  # draws of variance v, part of n in N_PARTS
        n, sd = scenario.truth_draws, math.hypot(scenario.sigma_px, scenario.world.effects.extra_noise_px)
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(TRUTH_SPAWN_KEY, part)))
        return sd * rng.standard_normal(n * (part + 1) // N_PARTS - n * part // N_PARTS)

    def truths_from_parts(self, scenario, seed, results):
        sq = np.concatenate(results) ** 2
        return {("offset", "x"): Truth(scenario.offset_px),
                ("noise", "x"): Truth(float(sq.mean()), float(sq.std(ddof=1) / math.sqrt(sq.size)))}

    def truth_size_for(self, scenario, seed, target_se):
        if ("noise", "x") not in target_se:
            return scenario
        v = scenario.sigma_px**2 + scenario.world.effects.extra_noise_px**2
        n = math.ceil(2 * (v / target_se[("noise", "x")]) ** 2)
        return scenario.model_copy(update={"truth_draws": max(N_PARTS, n)})

    def truth_fields(self, scenario):
        return ("offset_px", "sigma_px", "world.effects.extra_noise_px", "truth_draws")

    def truth_depends_on_effects(self, scenario):
        return {"extra_noise_px"}

    def claim(self, scenario, class_name, variant):
        return CLAIM_PX if class_name == "offset" else None

    def protocol_knobs(self, scenario):
        return (Knob("frames", "int", 1, 100_000, "frames", "frames averaged for the offset"),
                Knob("dark_frames", "int", 2, 100_000, "frames", "dark frames for the noise"))

    def lab_time_s(self, scenario):
        frame_s = FRAME_S * (LINE_TIME if scenario.pattern == "line" else 1.0)
        return {"setup": SETUP_S, "frames": scenario.frames * frame_s, "dark": scenario.dark_frames * DARK_FRAME_S}

    def protocol_shapes(self, scenario):
        return {"grid": {"pattern": "grid"}, "line": {"pattern": "line"}}

    def field_classes(self, scenario):
        return {"frames": ("offset",), "pattern": ("offset",), "dark_frames": ("noise",)}

    def details(self, result):
        d = result.scenario.dark_frames
        return {"dark_frames": d, "noise_bias_published_px2": -result.truths[("noise", "x")].value / d}

    def report_sections(self, result, out_dir):
        d = result.details()
        return [ReportSection("Dark frames", f"The published variance divides by the {d['dark_frames']} dark "
                              f"frames: its expected bias is {fmt(d['noise_bias_published_px2'])} px^2.")]

    def likely_cause(self, result, key, stats):
        d = result.details()
        return None if key[:2] != ("noise", "published") else (
            f"it divides by the {d['dark_frames']} dark frames, not {d['dark_frames'] - 1}: expected bias "
            f"{fmt(d['noise_bias_published_px2'])}, measured {fmt(stats['bias'])} px^2")

    def claims(self, scenario):  # the offset measured to 10 % of its truth, in the scenario's world
        return (Claim(id="offset.x.method", words="the mean of the frames measures the offset", figures=(),
                      unit="px", axis="x", condition="any frames", section="the toy", kind="method", scenario="toy",
                      class_name="offset", variant="published",
                      tolerance=ToleranceRule(reason="10 % of the truth", relative=0.10)),)


STUDY = FullToyStudy()
