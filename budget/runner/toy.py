"""A toy study whose cost-accuracy trade is analytic: the planner's reference (docs/planning.md).

The lab measures one offset (class ``offset``, axis ``x``, in px) by averaging ``frames``
frames taken over ``positions`` stage positions. Each frame carries white noise
``sigma_frame_px``; each position carries its own offset error ``sigma_position_px``
(a systematic of that position, the same for every frame taken there), averaged over the
positions. The error of the ``debiased`` estimate of trial ``k`` is

    e = sigma_frame_px * z1 / sqrt(frames) + sigma_position_px * z2 / sqrt(positions),

``z1, z2`` independent standard normals drawn from ``SeedSequence(seed, spawn_key=(k,))``
(the runner's rule), so ``e ~ N(0, s^2)`` with ``s^2 = sigma_f^2 / F + sigma_p^2 / P``. The
``naive`` variant adds a fixed bias ``naive_bias_px`` (a floor no count removes); ``none``
is a reference (no estimate: the offset taken as 0). The lab time is linear in the knobs:

    cost = F * frame_time_s + P * move_time_s + setup_time_s     (t_f, t_m below).

The centroid window ``window_px`` ``W`` (knob ``window``, 1 to 9 px) costs no lab time: a
frame's noise is ``sigma_f sqrt(1 + ((W - W*) / W*)^2)`` (``W*``: ``best_window_px``, 5 px;
the default window is 5 px, so the formulas below hold with ``sigma_f`` as stated), least at
``W*`` (an interior value; a ``W*`` beyond 9 px puts the best window at the range's end). The
formulas below hold at any window with ``sigma_f`` that of the window.

Protocol shapes (``ToyStudy(shapes=True)``): ``protocol.pattern`` ``grid`` (as above) or
``line`` (positions along one axis: a move takes ``line_move_fraction`` of the time, but
neighbouring positions share error, so a position's variance is ``line_position_factor``
times larger); the formulas below hold for either with ``sigma_p`` and ``t_m`` those of the
pattern.

The cheapest protocol whose C-quantile of ``|e|`` is at most ``V`` is, with
``z = Phi^-1((1 + C) / 2)`` and ``v = (V / z)^2`` the variance allowed:

* one knob (positions fixed at ``P``; :data:`TOY_ONE_KNOB`): ``F* = ceil(sigma_f^2 / (v - sigma_p^2 / P))``;
* two knobs (:data:`TOY`), by Lagrange (minimise cost subject to ``s^2 = v``):
  ``F* = sigma_f sqrt(lambda / t_f)``, ``P* = sigma_p sqrt(lambda / t_m)`` with
  ``sqrt(lambda) = (sigma_f sqrt(t_f) + sigma_p sqrt(t_m)) / v``, so that
  ``cost* = (sigma_f sqrt(t_f) + sigma_p sqrt(t_m))^2 / v + setup`` (:func:`analytic_optimum`).

It is not registered as a CLI study (it measures nothing real); tests, the docs and the
benchmark use it through the Python API (``budget.plan(TOY, ...)``).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from budget.runner.study import ClassSpec, Knob, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ScenarioBase, StrictModel, ValidationSettings, load_scenario_file, validate_model

__all__ = ["TOY", "TOY_FLAT", "TOY_ONE_KNOB", "ToyScenario", "ToyStudy", "analytic_optimum"]

DEFAULT_TEXT = """\
# The planner's toy study (budget.runner.toy): one offset averaged over frames and positions.
name = "toy offset"

[world]
offset_px = 0.5            # the true offset
sigma_frame_px = 0.05      # white noise of one frame
sigma_position_px = 0.01   # offset error of one stage position (a systematic of that position)
naive_bias_px = 0.004      # the naive variant's fixed bias
line_position_factor = 2.0 # a line's positions share error: their variance is this many times a grid's
best_window_px = 5.0       # the centroid window at which a frame's noise is least

[protocol]
frames = 100               # frames, spread over the positions
positions = 4              # stage positions
pattern = "grid"           # "grid" (positions over both axes) or "line" (along one axis)
window_px = 5.0            # the centroid window the lab's software uses (costs no lab time)

[lab]
frame_time_s = 2.0         # one exposure and read-out
move_time_s = 30.0         # one stage move and settling
line_move_fraction = 0.25  # a move along a line takes this fraction of a grid move
setup_time_s = 600.0       # mounting and alignment, once

[validation]
trials = 200
"""


class ToyWorld(StrictModel):
    offset_px: float = 0.5
    sigma_frame_px: float = Field(0.05, ge=0.0)
    sigma_position_px: float = Field(0.01, ge=0.0)
    naive_bias_px: float = 0.004
    line_position_factor: float = Field(2.0, ge=0.0)
    best_window_px: float = Field(5.0, gt=0.0)


class ToyProtocol(StrictModel):
    frames: int = Field(100, ge=1)
    positions: int = Field(4, ge=1)
    pattern: Literal["grid", "line"] = "grid"
    window_px: float = Field(5.0, gt=0.0)


class ToyLab(StrictModel):
    frame_time_s: float = Field(2.0, ge=0.0)
    move_time_s: float = Field(30.0, ge=0.0)
    setup_time_s: float = Field(600.0, ge=0.0)
    line_move_fraction: float = Field(0.25, ge=0.0)


class ToyScenario(ScenarioBase):
    world: ToyWorld = ToyWorld()
    protocol: ToyProtocol = ToyProtocol()
    lab: ToyLab = ToyLab()
    validation: ValidationSettings = ValidationSettings()


def default_text() -> str:
    return DEFAULT_TEXT


def from_dict(data: dict, *, source: str) -> ToyScenario:
    scn = validate_model(ToyScenario, data, source=source)
    scn._source = source
    return scn


def load(path=None) -> ToyScenario:
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="toy")


class ToyStudy(Study):
    """The toy study (module docstring); ``knobs`` names the knobs it offers the planner."""

    name = "toy"
    title = "Toy offset (planner reference)"
    seed_document = "-"
    variants = ("naive", "debiased", "none")
    reference_variants = ("none",)
    scenario_module = "budget.runner.toy"

    def __init__(self, knobs: tuple[str, ...] = ("frames", "positions"), *, shapes: bool = False,
                 record: bool = False):
        self.knobs = tuple(knobs)
        #: when True, the planner compares the grid and line patterns (:meth:`protocol_shapes`)
        self.shapes = shapes
        #: when True, every trial run appends ``(seed, k)`` to :attr:`calls` (tests count trials)
        self.record = record
        self.calls: list[tuple[int, int]] = []

    def classes(self, scenario: Any) -> tuple[ClassSpec, ...]:
        return (ClassSpec("offset", "offset", "px", ("x",), "the offset the lab measures"),
                ClassSpec("frame_noise", "frame noise (given)", "px", ("x",), "the frame noise, given",
                          role="input"))

    def protocol_knobs(self, scenario: Any) -> tuple[Knob, ...]:
        all_knobs = {"frames": Knob("protocol.frames", "int", 1, 100_000, "frames", "frames averaged"),
                     "positions": Knob("protocol.positions", "int", 1, 1000, "positions", "stage positions"),
                     "window": Knob("protocol.window_px", "real", 1.0, 9.0, "px", "centroid window (no lab time)")}
        return tuple(all_knobs[k] for k in self.knobs)

    def protocol_shapes(self, scenario: Any) -> dict[str, dict[str, Any]]:
        if not self.shapes:
            return {}
        return {"grid": {"protocol.pattern": "grid"}, "line": {"protocol.pattern": "line"}}

    def lab_time_s(self, scenario: Any) -> dict[str, float]:
        p, lab = scenario.protocol, scenario.lab
        return {"setup": lab.setup_time_s, "exposure": p.frames * lab.frame_time_s,
                "moves": p.positions * _move_s(scenario)}

    def truth_fields(self, scenario: Any) -> tuple[str, ...]:
        return ("world",)  # the protocol changes the estimates, never the truth

    def truths(self, scenario: Any, seed: int) -> dict[tuple[str, str], Truth]:
        return {("offset", "x"): Truth(scenario.world.offset_px),
                ("frame_noise", "x"): Truth(scenario.world.sigma_frame_px)}

    def trial(self, scenario: Any, seed: int, k: int) -> TrialResult:
        if self.record:
            self.calls.append((seed, k))
        w, p = scenario.world, scenario.protocol
        z1, z2 = np.random.default_rng(trial_seed_sequence(seed, k)).standard_normal(2)
        e = _sigma_f(scenario) * z1 / math.sqrt(p.frames) + _sigma_p(scenario) * z2 / math.sqrt(p.positions)
        est = w.offset_px + e
        return TrialResult({("offset", "debiased", "x"): est, ("offset", "naive", "x"): est + w.naive_bias_px,
                            ("offset", "none", "x"): 0.0,
                            ("frame_noise", "debiased", "x"): w.sigma_frame_px,
                            ("frame_noise", "naive", "x"): w.sigma_frame_px,
                            ("frame_noise", "none", "x"): w.sigma_frame_px})


def _sigma_f(scenario) -> float:
    """A frame's noise with the centroid window ``W``: ``sigma_f sqrt(1 + ((W - W*) / W*)^2)``,
    least (``sigma_f``) at the world's best window ``W*`` (module docstring)."""
    w = scenario.world
    d = (scenario.protocol.window_px - w.best_window_px) / w.best_window_px
    return w.sigma_frame_px * math.sqrt(1.0 + d * d)


def _sigma_p(scenario) -> float:
    """A position's offset error: a line's positions share error (variance x line_position_factor)."""
    w = scenario.world
    f = w.line_position_factor if scenario.protocol.pattern == "line" else 1.0
    return w.sigma_position_px * math.sqrt(f)


def _move_s(scenario) -> float:
    lab = scenario.lab
    return lab.move_time_s * (lab.line_move_fraction if scenario.protocol.pattern == "line" else 1.0)


def analytic_optimum(scenario: ToyScenario, value_px: float, confidence: float = 0.95, *,
                     knobs: tuple[str, ...] = ("frames", "positions"), bias_px: float = 0.0) -> dict:
    """The cheapest protocol whose ``confidence``-quantile of ``|e|`` is ``value_px`` (module
    docstring), continuous (before rounding up to whole frames and positions). ``bias_px``: a
    fixed bias (the naive variant's), for one knob only: the quantile of ``|b + s z|``."""
    from scipy import optimize, stats

    lab = scenario.lab
    sp, tm, sf = _sigma_p(scenario), _move_s(scenario), _sigma_f(scenario)
    z = float(stats.norm.ppf(0.5 + confidence / 2.0))
    if knobs == ("frames",):
        p = scenario.protocol.positions

        def quantile(f):
            s = math.sqrt(sf**2 / f + sp**2 / p)
            # P(|b + s Z| <= q) = confidence
            return optimize.brentq(lambda q: stats.norm.cdf((q - bias_px) / s) - stats.norm.cdf((-q - bias_px) / s)
                                   - confidence, 0.0, abs(bias_px) + 10 * s)

        if bias_px == 0.0:
            v = (value_px / z) ** 2 - sp**2 / p
            f = sf**2 / v if v > 0 else math.inf
        else:
            f = optimize.brentq(lambda f: quantile(f) - value_px, 1e-6, 1e12)
        return {"frames": f, "positions": p, "cost_s": lab.setup_time_s + f * lab.frame_time_s + p * tm}
    v = (value_px / z) ** 2
    root = (sf * math.sqrt(lab.frame_time_s) + sp * math.sqrt(tm)) / v
    f = sf * root / math.sqrt(lab.frame_time_s)
    p = sp * root / math.sqrt(tm)
    return {"frames": f, "positions": p, "cost_s": lab.setup_time_s + f * lab.frame_time_s + p * tm}


#: the two-knob toy (frames and positions)
TOY = ToyStudy()
#: the one-knob toy (frames; positions as the scenario says)
TOY_ONE_KNOB = ToyStudy(("frames",))
#: frames and the cost-flat centroid window
TOY_FLAT = ToyStudy(("frames", "window"))
