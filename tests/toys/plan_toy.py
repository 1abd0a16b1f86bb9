"""The planner's toy studies, whose cost-accuracy trade is analytic: the reference that
tests/test_plan*.py, benchmarks/bench_plan.py and docs/planning.md check the planner against
(not a physical model; not shipped with the package).

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

The separable toy (:class:`SplitToyStudy`, :data:`SPLIT_TOY`): three independent lab
protocols ``a``, ``b`` and ``c``, each measuring its own offset (classes ``a``, ``b``, ``c``)
by averaging its own ``frames`` (knobs ``a.frames``, ``b.frames``, ``c.frames``), and the class
``ab``, the sum of the ``a`` and ``b`` offsets, which depends on both. Trial ``k`` draws
``z_a, z_b, z_c`` (standard normals, in that order, from ``SeedSequence(seed, spawn_key=(k,))``)
whatever it computes, and the error of protocol ``p`` is ``e_p = sigma_p z_p / sqrt(F_p)``
(``e_ab = e_a + e_b``); a frame of ``b`` or ``c`` in the ``line`` pattern has ``line_factor``
times the variance and ``line_time_fraction`` of the time of a ``grid`` frame. The lab time is
additive, ``setup + F_a t_a + F_b t_b + F_c t_c`` (``t_p`` the pattern's frame time), so the
cheapest protocol meeting ``p.x <= V_p`` for each required ``p`` is, with
``z = Phi^-1((1 + C) / 2)``, ``F_p* = (z sigma_p / V_p)^2`` for each (:func:`split_optimum`),
and the pattern of least ``sigma_p^2 t_p`` (the line for ``b``, at the defaults: 2 x 0.25).
It declares :meth:`~budget.runner.capabilities.SeparablePlans.field_classes` (``separable=False``:
none, the whole-test plan) and restricts
(:meth:`~budget.runner.capabilities.SeparablePlans.restrict_classes`: ``[compute] protocols``, the protocols whose trials
and truths are computed; ``restrict=False``: it cannot), counting the protocols a trial
computed in :attr:`SplitToyStudy.computed` (``record=True``).

Neither is registered as a CLI study (they measure nothing real); tests, the docs and the
benchmark import this module as ``plan_toy`` (``tests/toys`` on ``sys.path``: tests/conftest.py)
and use them through the Python API (``budget.plan(TOY, ...)``).
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from pydantic import Field

from budget.runner.capabilities import Plannable, ProtocolShapes, SeparablePlans, SharedTruths
from budget.runner.study import ClassSpec, Knob, Study, TrialResult, Truth, trial_seed_sequence
from simcam.config_base import ScenarioBase, StrictModel, ValidationSettings, load_scenario_file, validate_model

__all__ = ["SPLIT_TOY", "TOY", "TOY_FLAT", "TOY_ONE_KNOB", "SplitToyScenario", "SplitToyStudy", "ToyScenario",
           "ToyStudy", "analytic_optimum", "split_optimum"]

DEFAULT_TEXT = """\
# The planner's toy study (tests/toys/plan_toy.py): one offset averaged over frames and positions.
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


class ToyStudy(Study, Plannable, ProtocolShapes, SharedTruths):
    """The toy study (module docstring); ``knobs`` names the knobs it offers the planner."""

    name = "toy"
    title = "Toy offset (planner reference)"
    seed_document = "-"
    variants = ("naive", "debiased", "none")
    reference_variants = ("none",)
    scenario_module = __name__  # this module: default_text, from_dict and load above

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


# ---------------------------------------------------------------------- the separable toy
SPLIT_TEXT = """\
# The planner's separable toy (tests/toys/plan_toy.py): three independent protocols a, b and c.
name = "toy split"

[world]
offset_a_px = 0.5          # the offset protocol a measures
offset_b_px = -0.2         # protocol b's
offset_c_px = 0.1          # protocol c's
sigma_a_px = 0.05          # white noise of one frame of protocol a
sigma_b_px = 0.04          # of protocol b (a grid frame)
sigma_c_px = 0.02          # of protocol c (a grid frame)
line_factor = 2.0          # a line frame's variance is this many times a grid frame's

[a]
frames = 100
[b]
frames = 100
pattern = "grid"           # "grid" or "line"
[c]
frames = 10
pattern = "grid"

[lab]
a_frame_time_s = 2.0
b_frame_time_s = 3.0
c_frame_time_s = 1.0
line_time_fraction = 0.25  # a line frame takes this fraction of a grid frame's time
setup_time_s = 600.0       # mounting and alignment, once

[compute]
protocols = ["a", "b", "c"] # the protocols whose trials and truths are computed

[validation]
trials = 200
"""

_PROTOCOLS = ("a", "b", "c")
#: what each class needs computed
_NEEDS = {"a": ("a",), "b": ("b",), "c": ("c",), "ab": ("a", "b")}


class SplitWorld(StrictModel):
    offset_a_px: float = 0.5
    offset_b_px: float = -0.2
    offset_c_px: float = 0.1
    sigma_a_px: float = Field(0.05, ge=0.0)
    sigma_b_px: float = Field(0.04, ge=0.0)
    sigma_c_px: float = Field(0.02, ge=0.0)
    line_factor: float = Field(2.0, ge=0.0)


class SplitA(StrictModel):
    frames: int = Field(100, ge=1)


class SplitPatterned(StrictModel):
    frames: int = Field(100, ge=1)
    pattern: Literal["grid", "line"] = "grid"


class SplitLab(StrictModel):
    a_frame_time_s: float = Field(2.0, ge=0.0)
    b_frame_time_s: float = Field(3.0, ge=0.0)
    c_frame_time_s: float = Field(1.0, ge=0.0)
    line_time_fraction: float = Field(0.25, ge=0.0)
    setup_time_s: float = Field(600.0, ge=0.0)


class SplitCompute(StrictModel):
    protocols: list[Literal["a", "b", "c"]] = ["a", "b", "c"]


class SplitToyScenario(ScenarioBase):
    world: SplitWorld = SplitWorld()
    a: SplitA = SplitA()
    b: SplitPatterned = SplitPatterned()
    c: SplitPatterned = SplitPatterned(frames=10)
    lab: SplitLab = SplitLab()
    compute: SplitCompute = SplitCompute()
    validation: ValidationSettings = ValidationSettings()


class SplitToyStudy(Study, Plannable, ProtocolShapes, SharedTruths, SeparablePlans):
    """The separable toy (module docstring). ``knobs``: the protocols whose frames are knobs;
    ``shapes``: the four patterns of ``b`` and ``c`` (``bgrid-cgrid``, ``bgrid-cline``, ...);
    ``separable``: declare :meth:`field_classes`; ``restrict``: support :meth:`restrict_classes`;
    ``record``: count trials (:attr:`calls`) and the protocols each computed (:attr:`computed`)."""

    name = "toy-split"
    title = "Toy offsets of three independent protocols (planner reference)"
    seed_document = "-"
    variants = ("debiased",)
    reference_variants = ()
    scenario_module = ""

    def __init__(self, knobs: tuple[str, ...] = _PROTOCOLS, *, shapes: bool = False, separable: bool = True,
                 restrict: bool = True, record: bool = False):
        self.knobs, self.shapes, self.separable, self.restrict = tuple(knobs), shapes, separable, restrict
        self.record = record
        self.calls: list[tuple[int, int]] = []
        self.computed: dict[str, int] = {p: 0 for p in _PROTOCOLS}

    def default_text(self) -> str:
        return SPLIT_TEXT

    def from_dict(self, data: dict, *, source: str) -> SplitToyScenario:
        scn = validate_model(SplitToyScenario, data, source=source)
        scn._source = source
        return scn

    def classes(self, scenario: Any) -> tuple[ClassSpec, ...]:
        run = set(scenario.compute.protocols)
        specs = [ClassSpec(p, f"offset {p}", "px", ("x",), f"the offset protocol {p} measures") for p in _PROTOCOLS]
        specs.append(ClassSpec("ab", "offset a + b", "px", ("x",), "the sum of the a and b offsets"))
        return tuple(c for c in specs if set(_NEEDS[c.name]) <= run)

    def protocol_knobs(self, scenario: Any) -> tuple[Knob, ...]:
        return tuple(Knob(f"{p}.frames", "int", 1, 100_000, "frames", f"frames of protocol {p}") for p in self.knobs)

    def protocol_shapes(self, scenario: Any) -> dict[str, dict[str, Any]]:
        if not self.shapes:
            return {}
        pats = ("grid", "line")
        return {f"b{pb}-c{pc}": {"b.pattern": pb, "c.pattern": pc} for pb in pats for pc in pats}

    def field_classes(self, scenario: Any) -> dict[str, tuple[str, ...]]:
        if not self.separable:
            return {}
        return {"a.frames": ("a", "ab"), "b.frames": ("b", "ab"), "b.pattern": ("b", "ab"),
                "c.frames": ("c",), "c.pattern": ("c",)}

    def restrict_classes(self, scenario: Any, classes: frozenset[str]):
        if not self.restrict:
            return None
        need = {p for c in classes for p in _NEEDS[c]}
        data = scenario.model_dump(mode="json", exclude_none=True)
        data["compute"] = {"protocols": [p for p in _PROTOCOLS if p in need]}
        return self.from_dict(data, source="restricted")

    def lab_time_s(self, scenario: Any) -> dict[str, float]:
        lab = scenario.lab
        return {"setup": lab.setup_time_s, "a": scenario.a.frames * lab.a_frame_time_s,
                "b": scenario.b.frames * lab.b_frame_time_s * _split_time(scenario, "b"),
                "c": scenario.c.frames * lab.c_frame_time_s * _split_time(scenario, "c")}

    def truth_fields(self, scenario: Any) -> tuple[str, ...]:
        return ("world", "compute")

    def truths(self, scenario: Any, seed: int) -> dict[tuple[str, str], Truth]:
        w = scenario.world
        t = {"a": w.offset_a_px, "b": w.offset_b_px, "c": w.offset_c_px, "ab": w.offset_a_px + w.offset_b_px}
        return {(c.name, "x"): Truth(t[c.name]) for c in self.classes(scenario)}

    def trial(self, scenario: Any, seed: int, k: int) -> TrialResult:
        run = tuple(scenario.compute.protocols)
        if self.record:
            self.calls.append((seed, k))
            for p in run:
                self.computed[p] += 1
        z = np.random.default_rng(trial_seed_sequence(seed, k)).standard_normal(3)  # every trial draws all three
        w = scenario.world
        est = {}
        for i, p in enumerate(_PROTOCOLS):
            if p in run:
                est[p] = getattr(w, f"offset_{p}_px") + split_sigma(scenario, p) * z[i] / math.sqrt(
                    getattr(scenario, p).frames)
        if "a" in est and "b" in est:
            est["ab"] = est["a"] + est["b"]
        return TrialResult({(c, "debiased", "x"): v for c, v in est.items()})


def _split_time(scenario, p: str) -> float:
    return scenario.lab.line_time_fraction if getattr(scenario, p).pattern == "line" else 1.0


def split_sigma(scenario, p: str) -> float:
    """One frame's noise of protocol ``p``: a line frame's variance ``line_factor`` times a grid's."""
    w = scenario.world
    s = getattr(w, f"sigma_{p}_px")
    return s * math.sqrt(w.line_factor) if p != "a" and getattr(scenario, p).pattern == "line" else s


def split_optimum(scenario: SplitToyScenario, protocol: str, value_px: float, confidence: float = 0.95) -> dict:
    """The separable toy's cheapest frames of ``protocol`` whose ``confidence``-quantile of
    ``|e_p|`` is ``value_px`` (continuous): ``F* = (z sigma_p / V)^2``, and its lab time
    ``F* t_p`` (module docstring)."""
    from scipy import stats

    z = float(stats.norm.ppf(0.5 + confidence / 2.0))
    f = (z * split_sigma(scenario, protocol) / value_px) ** 2
    t = getattr(scenario.lab, f"{protocol}_frame_time_s")
    if protocol != "a":
        t *= _split_time(scenario, protocol)
    return {"frames": f, "time_s": f * t}


#: the two-knob toy (frames and positions)
TOY = ToyStudy()
#: the one-knob toy (frames; positions as the scenario says)
TOY_ONE_KNOB = ToyStudy(("frames",))
#: frames and the cost-flat centroid window
TOY_FLAT = ToyStudy(("frames", "window"))
#: the separable toy: protocols a, b and c, each its own frames
SPLIT_TOY = SplitToyStudy()
