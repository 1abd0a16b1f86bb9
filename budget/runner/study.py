"""The study contract: what one lab method on one instrument provides to the shared machinery.

This docstring is the one definition of the contract (``docs/architecture.md`` points here).
A *study* (seed 000's star-camera lab methods, seed 001's inductosyn calibration, the
whiskbroom TDI camera of seed 002, ...) implements :class:`Study` and nothing more. The
runner (:mod:`budget.runner.run`) turns any study into seeded trials on processes or a
Dask cluster, adaptive stopping, statistics with their standard errors, a JSON result
and a report; the sweep engine varies any of its scenario fields; the CLI is built from
the registry (:mod:`budget.runner.registry`).

What a study must provide
-------------------------
* ``name`` (the registry key and CLI group, e.g. ``"whiskbroom"``), ``title``,
  ``seed_document`` (the seed document it implements) and ``variants`` (its estimators:
  ``published``, ``improved``, ...; report order);
* ``scenario_module``: the dotted name of its instrument's scenario module in
  :mod:`simcam` (e.g. ``"simcam.whiskbroom.scenario"``). Every such module has the same
  four functions, ``default_text()`` (the embedded default, TOML with comments),
  ``from_dict(data, *, source)``, ``load(path=None)`` (strict TOML through
  :func:`simcam.config_base.read_toml`; None: the embedded default) and ``default()``, and
  a frozen model subclassing :class:`simcam.config_base.ScenarioBase` (``name``,
  ``validation``, ``hash``, ``source``). :meth:`Study.default_text`,
  :meth:`Study.from_dict` (what sweeps use after setting dotted keys) and
  :meth:`Study.load_scenario` delegate to it; errors are
  :class:`simcam.infra.errors.ScenarioError` naming file and field;
* :meth:`Study.classes`: its error classes (:class:`ClassSpec`: label, unit, axes, whether
  the truth is drawn per trial, and the role: an estimate of a truth, an input, a residual
  or a stated uncertainty);
* :meth:`Study.trial`: the estimates of one simulated measurement, computed by the same
  estimators that run on real data, keyed ``(class, variant, axis)``; where the truth
  changes from trial to trial (an injected error drawn per trial), the trial's own truth
  under the same key, and where the estimator states an uncertainty, its 1-sigma value
  (the runner reports coverage);
* :meth:`Study.truths`: the truth of each class that is a property of the scenario, keyed
  ``(class, axis)``, with its own standard error (0 when exact).

What a study may override (each has a default)
-----------------------------------------------
Scenario: :meth:`Study.check` (cheap checks of what the simulator would refuse later; sweeps
run it on every point first), :meth:`Study.scenario_hash` (the model's ``hash``),
:meth:`Study.scenario_text` (the resolved scenario as TOML in the JSON result).

The method: :meth:`Study.trial_batch` (many trials at once, for vectorised studies; it must
give, for each ``k``, exactly what :meth:`Study.trial` gives).

Run settings (how many trials, where they run):

* :meth:`Study.default_trials`, :meth:`Study.default_tolerance`, :meth:`Study.max_trials`,
  :meth:`Study.batch_trials`: read from the scenario's ``[validation]`` table
  (:class:`simcam.config_base.ValidationSettings`: ``trials``, ``tolerance``,
  ``max_trials``, ``batch_trials``);
* :meth:`Study.chunk_trials`: most trials in one task sent to a worker (10);
* :meth:`Study.prewarm`: once in the run's own process before any work (compile numba
  kernels in parallel; nothing by default);
* :meth:`Study.worker_init`: once in each worker process, after the runner has set one numba
  thread there (a study sets no threads itself).

Truth distribution (a heavy truth spread over the workers): :meth:`Study.truth_parts`,
:meth:`Study.truth_part`, :meth:`Study.truths_from_parts` (default: one part, the whole of
:meth:`Study.truths`; the result must equal it).

Truth sizing and sharing (what a truth costs follows the question):

* :meth:`Study.truth_size_for` ``(scenario, seed, target_se) -> scenario``: the scenario with its
  truth sampling sized so that each sampled truth's standard error is about
  ``target_se[(class, axis)]`` (in the class's unit) or below. The runner asks for a
  stated fraction (:data:`budget.runner.run.TRUTH_SE_FRACTION`, a quarter) of the bias
  standard error the run's trials will give (from a pilot of its first trials), or of the
  tolerance when it stops adaptively; ``--truth-size fixed`` keeps the scenario's own
  sizes. The result must change nothing but the truths' sampling sizes (same seeds, the
  trials untouched); the truths then report their actual standard error, which the
  significance test uses. Default: the scenario unchanged (exact or cheap truths).
* :meth:`Study.truth_fields` ``(scenario) -> tuple of dotted prefixes | None``: the scenario
  fields the truths depend on (``"camera"``, ``"validation.threshold_sigma"``); a sweep
  computes one truth per distinct set of their values and reuses it for every point
  that has them (:mod:`budget.sweeps.run`). None (the default): every field. It must
  agree with :meth:`Study.truth_depends_on_effects` (an effect outside that set is not
  among these fields).

World effects (``budget <study> robustness``, :mod:`budget.runner.robustness`):
:meth:`Study.truth_depends_on_effects` (the effects whose change changes the truths; default
all) and :meth:`Study.claim` (the accuracy a method claims for a class; default: unbiased).
A claim is two-sided (the estimate equals the truth within its uncertainty) unless the class
says ``ClassSpec(at_most=True)``: the estimate is a stated bound (a largest error, a 3-sigma
maximum) and the claim is one-sided, the truth (the actual) at or below it. It then holds
when the estimate is not significantly *below* the truth (``-bias <= 3 se``; with a claimed
accuracy ``A``, ``-bias + 3 se <= A``), however far above; the findings
(:mod:`budget.runner.findings`) and the robustness verdicts
(:func:`budget.runner.robustness.claim_holds`) both read it.

Protocol planning (``budget <study> plan``, :mod:`budget.runner.plan`):
:meth:`Study.protocol_knobs` (the fields a lab chooses, :class:`Knob`, with bounds; none by
default, and then the study has no ``plan`` command), :meth:`Study.protocol_shapes` (named
protocol geometries to compare) and :meth:`Study.lab_time_s` (the lab time of a protocol, in
seconds by item, from the scenario's own fields: exposures, frames, moves, settling, dwells);
for a plan that splits into independent sub-plans, :meth:`Study.field_classes` (which classes
each knob and shape field can change) and :meth:`Study.restrict_classes` (a scenario that
computes only some classes); :meth:`Study.shape_value` (a shape field's value as the protocol
uses it, where two spellings mean one shape) and :meth:`Study.uncomputed_class` (why a class of
the study is not computed by a scenario, for the planner's error).

Presentation: :meth:`Study.report_sections` (sections and plots its report adds),
:meth:`Study.details` (the study's own figures in the JSON result, under ``details``). The
study's own click commands live in its command module (:mod:`budget.runner.registry`), which
imports the study, not the reverse.

Randomness: trial ``k`` of a run with ``seed`` must draw only from
``numpy.random.SeedSequence(seed, spawn_key=(k,))`` (see :func:`trial_seed_sequence`),
and the truths from ``SeedSequence(seed, spawn_key=(TRUTH_SPAWN_KEY,))``, so results do
not depend on the number of workers or the order in which trials finish.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["CLASS_ROLES", "ClassSpec", "Key", "Knob", "ReportSection", "Study", "TRUTH_SPAWN_KEY", "TrialResult",
           "Truth", "trial_seed_sequence", "truth_identity", "truth_seed_sequence"]

#: spawn key of the truths' seed sequence (trials use 0, 1, 2, ...)
TRUTH_SPAWN_KEY = 2**31

#: (class, variant, axis)
Key = tuple[str, str, str]

#: what a class's figures are (:attr:`ClassSpec.role`)
CLASS_ROLES = ("result", "input", "residual", "stated")


def trial_seed_sequence(seed: int, k: int) -> np.random.SeedSequence:
    """The seed sequence of trial ``k``: ``SeedSequence(seed, spawn_key=(k,))``."""
    return np.random.SeedSequence(seed, spawn_key=(k,))


def truth_seed_sequence(seed: int) -> np.random.SeedSequence:
    """The seed sequence of the truths: ``SeedSequence(seed, spawn_key=(2**31,))``."""
    return np.random.SeedSequence(seed, spawn_key=(TRUTH_SPAWN_KEY,))


def truth_identity(study: "Study", scenario: Any) -> str:
    """Hash (16 hex digits) of what :meth:`Study.truths` depends on besides the seed: the values
    of the fields :meth:`Study.truth_fields` names (every field when it names none). Two
    scenarios with the same identity have the same truths with the same seed."""
    import hashlib
    import json

    data = scenario.model_dump(mode="json", exclude_none=True)
    data.pop("name", None)
    fields = study.truth_fields(scenario)
    if fields is not None:
        picked = {}
        for f in sorted(set(fields)):
            node: Any = data
            for part in f.split("."):
                node = node.get(part) if isinstance(node, dict) else None
            picked[f] = node
        data = picked
    payload = json.dumps({"study": study.name, "fields": data}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ClassSpec:
    """One error class of a study: what it is called and in which unit it is reported.

    Parameters
    ----------
    name : str
        Key used in trials, JSON and sweeps (``"te"``, ``"delta_vp"``).
    label : str
        What a reader sees (``"temporal error (TE)"``).
    unit : str
        Unit of every value of the class (``"arcsec, 3 sigma"``, ``"mm/s"``).
    axes : tuple of str
        Axes of the class (``("x", "y")``, ``("angle",)``).
    description : str
        One sentence: what the truth is and what the estimate measures.
    per_trial_truth : bool
        True when each trial carries its own truth (an error drawn per trial): the
        runner then compares estimate and truth trial by trial.
    role : {"result", "input", "residual", "stated"}
        What the class's figures are, so that the summary names a difference rightly:

        * ``"result"``: an estimate of a truth (a difference is a bias of the estimator);
        * ``"input"``: a figure the method takes as given rather than measures (seed 000's
          target marker error): reported, never called biased;
        * ``"residual"``: what a calibration or compensation leaves (the scan mirror's ground
          error after compensation, the inductosyn's error after compensation): its mean is
          the residual reached, not the bias of an estimate;
        * ``"stated"``: an uncertainty the method states, compared with the actual error
          (the line camera's rms LOS error): a difference says the statement is optimistic
          or pessimistic.
    numerical_floor : float
        In the class's unit: a bias below it is numerical (quadrature, rounding), reported as
        "exact to numerical precision", never significant (:mod:`budget.runner.findings`).
    undetermined : tuple of str
        Axes the data cannot determine (a gauge freedom): reported "not determined", no sigma.
    at_most : bool
        The claim is one-sided: the estimate is a stated bound on the truth (the line camera's
        largest stated 3-sigma against the largest actual error), so it holds when the truth is
        at or below the estimate within the Monte Carlo uncertainty, not only when they are
        equal. False (the default): two-sided, the estimate claims to equal the truth.
    """

    name: str
    label: str
    unit: str
    axes: tuple[str, ...] = ("x", "y")
    description: str = ""
    per_trial_truth: bool = False
    role: str = "result"
    numerical_floor: float = 0.0
    undetermined: tuple[str, ...] = ()
    at_most: bool = False

    def __post_init__(self) -> None:
        if self.role not in CLASS_ROLES:
            raise ValueError(f"ClassSpec {self.name!r}: role must be one of {CLASS_ROLES}, got {self.role!r}")


@dataclass(frozen=True)
class Truth:
    """The truth of one class and axis, with its Monte Carlo standard error (0: exact)."""

    value: float
    se: float = 0.0
    details: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.se) and self.se >= 0.0):
            raise ValueError(f"Truth.se must be finite and >= 0, got {self.se}")


@dataclass(frozen=True)
class Knob:
    """One knob of a lab protocol (:meth:`Study.protocol_knobs`): a scenario field the lab
    chooses, with the range the planner may search.

    Parameters
    ----------
    field : str
        Dotted scenario key (``"validation.te_frames"``, ``"protocol.faces"``).
    kind : {"int", "real"}
        Integer knobs take whole values only.
    low, high : float
        Inclusive bounds, in the field's unit (``low <= high``).
    unit : str
        What one step of the knob is (``"frames"``, ``"faces"``, ``"mag"``).
    description : str
        One sentence a report prints beside the chosen value.
    """

    field: str
    kind: str
    low: float
    high: float
    unit: str = ""
    description: str = ""

    def __post_init__(self) -> None:
        if self.kind not in ("int", "real"):
            raise ValueError(f"Knob {self.field!r}: kind must be 'int' or 'real', got {self.kind!r}")
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low <= self.high):
            raise ValueError(f"Knob {self.field!r}: bounds must be finite with low <= high, got {self.low}, {self.high}")


@dataclass
class TrialResult:
    """What one trial returns.

    ``estimates[(class, variant, axis)]`` is the estimate; ``truths`` holds the trial's
    own truth under the same key for classes with ``per_trial_truth``; ``sigmas`` the
    estimator's stated 1-sigma uncertainty where it states one. ``extra`` may carry
    anything small and picklable that the study's report wants (kept for trial 0 only).
    ``aux`` holds per-trial scalars that the study's own report and details summarise
    but that are not validated against a truth (a verification table's 3 sigma, a
    nuisance constant): kept for every trial, as arrays in trial order
    (:attr:`budget.runner.run.StudyResult.aux`); keep them few.
    """

    estimates: dict[Key, float]
    truths: dict[Key, float] = field(default_factory=dict)
    sigmas: dict[Key, float] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)
    aux: dict[str, float] = field(default_factory=dict)


@dataclass
class ReportSection:
    """A section a study adds to its report: Markdown text and the figures it refers to."""

    title: str
    markdown: str
    figures: list[Path] = field(default_factory=list)


class Study(ABC):
    """One lab method on one instrument (see the module docstring for the contract).

    The members come in the module docstring's groups, as sections of this one class
    (not mixins: a study overrides a hook by name, and one class keeps every default in
    one place to read): identity, scenario, the method, run settings, truth distribution,
    presentation.
    """

    # ------------------------------------------------------------ identity (required)
    #: registry key and CLI group name
    name: str = ""
    #: one line for humans
    title: str = ""
    #: source document (``"000"`` ... ``"004"``)
    seed_document: str = ""
    #: estimator variants, in report order
    variants: tuple[str, ...] = ("published", "improved")
    #: variants that do not estimate (a reference such as "without_estimate"): never "recover"
    reference_variants: tuple[str, ...] = ()
    #: the instrument's scenario module (``default_text``, ``from_dict``, ``load``, ``default``)
    scenario_module: str = ""

    # ------------------------------------------------------------ scenario
    def _scenario_module(self):
        import importlib

        if not self.scenario_module:
            raise NotImplementedError(f"{type(self).__name__}: set scenario_module (or override the scenario methods)")
        return importlib.import_module(self.scenario_module)

    def default_text(self) -> str:
        """The embedded default scenario, as TOML text with its comments."""
        return self._scenario_module().default_text()

    def from_dict(self, data: dict, *, source: str) -> Any:
        """Validate a scenario mapping into the study's frozen model.

        Raises :class:`simcam.infra.errors.ScenarioError` naming ``source`` and the field.
        """
        return self._scenario_module().from_dict(data, source=source)

    def load_scenario(self, path: str | Path | None = None) -> Any:
        """The scenario at ``path`` (strict TOML) or, for None, the embedded default."""
        if self.scenario_module:
            return self._scenario_module().load(path)
        from simcam.config_base import read_toml

        if path is None:
            source = f"embedded {self.name} default"
            return self.from_dict(read_toml(text=self.default_text(), source=source), source=source)
        return self.from_dict(read_toml(path=path), source=str(path))

    def check(self, scenario: Any, *, where: str) -> None:
        """What the simulator would refuse later, checked now and cheaply (sweeps check every
        point before any work); raise ScenarioError (or the simulator's ValueError) naming ``where``."""

    def scenario_hash(self, scenario: Any) -> str:
        """Hash of the scenario's canonical content (the models' ``hash`` by default)."""
        return scenario.hash

    def scenario_text(self, scenario: Any) -> str:
        """The resolved scenario as TOML (what the JSON result carries)."""
        import tomli_w

        return tomli_w.dumps(scenario.model_dump(mode="json", exclude_none=True))

    # ------------------------------------------------------------ the method
    @abstractmethod
    def classes(self, scenario: Any) -> tuple[ClassSpec, ...]:
        """The error classes this study reports, in report order."""

    @abstractmethod
    def trial(self, scenario: Any, seed: int, k: int) -> TrialResult:
        """One simulated measurement and its estimates (see the module docstring)."""

    def trial_batch(self, scenario: Any, seed: int, ks: list[int]) -> list[TrialResult]:
        """Trials ``ks`` at once (override with a vectorised path; must equal :meth:`trial` per k)."""
        return [self.trial(scenario, seed, k) for k in ks]

    @abstractmethod
    def truths(self, scenario: Any, seed: int) -> dict[tuple[str, str], Truth]:
        """The truth of every class without ``per_trial_truth``, keyed ``(class, axis)``."""

    # ------------------------------------------------------------ run settings
    # (from the scenario's [validation] table, simcam.config_base.ValidationSettings)
    def default_trials(self, scenario: Any) -> int:
        """Trials when the user gives neither a count nor a tolerance (``validation.trials``)."""
        return int(scenario.validation.trials)

    def default_tolerance(self, scenario: Any) -> float | None:
        """Adaptive-stopping tolerance when the user gives neither trials nor a tolerance
        (``validation.tolerance``; None: a fixed number of trials)."""
        return getattr(getattr(scenario, "validation", None), "tolerance", None)

    def max_trials(self, scenario: Any) -> int:
        """Cap on trials under adaptive stopping (``validation.max_trials``)."""
        return int(getattr(scenario.validation, "max_trials", 10 * self.default_trials(scenario)))

    def batch_trials(self, scenario: Any) -> int:
        """Trials between two convergence checks under adaptive stopping (``validation.batch_trials``)."""
        return int(getattr(scenario.validation, "batch_trials", 50))

    def chunk_trials(self, scenario: Any) -> int:
        """Most trials in one task sent to a worker (a few seconds of work at most)."""
        return 10

    def prewarm(self, scenario: Any) -> None:
        """Called once in the run's own process before any trial or truth: a study whose
        first run on a fresh install compiles many numba kernels may compile them here in
        parallel processes (:func:`simcam.numba_warm.compiling_in_parallel`), so that this
        process and every worker load them from numba's cache. Nothing by default; it must
        not change any result.
        """

    def worker_init(self) -> None:
        """Called once in each worker process (e.g. one numba thread per process)."""

    # ------------------------------------------------------------ truth distribution
    def truth_parts(self, scenario: Any, seed: int) -> list:
        """Independent pieces of :meth:`truths` a runner may spread over its workers
        (default: one piece, the whole of :meth:`truths`)."""
        return [None]

    def truth_part(self, scenario: Any, seed: int, part: Any) -> Any:
        """One piece (see :meth:`truth_parts`); by default the whole of :meth:`truths`."""
        return self.truths(scenario, seed)

    def truths_from_parts(self, scenario: Any, seed: int, results: list) -> dict[tuple[str, str], Truth]:
        """:meth:`truths` from its pieces' results, in :meth:`truth_parts` order; must equal it."""
        return results[0]

    # ------------------------------------------------------------ truth sizing and sharing
    def truth_size_for(self, scenario: Any, seed: int, target_se: dict[tuple[str, str], float]) -> Any:
        """``scenario`` with its truth sampling sized so that the standard error of each sampled
        truth ``(class, axis)`` is about ``target_se[(class, axis)]`` (class unit) or below; keys
        may be missing (no requirement). Only the truths' sampling sizes may change; any pilot
        it draws comes from the truths' seed sequence of ``seed`` (not from a truth's own
        streams), so the size is reproducible. Default: ``scenario`` unchanged."""
        return scenario

    def truth_fields(self, scenario: Any) -> tuple[str, ...] | None:
        """Dotted prefixes of the scenario fields :meth:`truths` depends on (with the truth
        seed); two scenarios equal on them have the same truths. None (the default): all."""
        return None

    # ------------------------------------------------------------ world effects (robustness)
    def truth_depends_on_effects(self, scenario: Any) -> set[str] | None:
        """Names of the world effects (``world.effects``) whose change changes :meth:`truths`;
        None (the default): all of them. A robustness run reuses the ideal world's truths for
        every case whose active effects are outside this set (:mod:`budget.runner.robustness`)."""
        return None

    def claim(self, scenario: Any, class_name: str, variant: str) -> float | None:
        """The accuracy the method claims for ``class_name`` with ``variant``, in the class's
        unit (a bound on the bias); None (the default): it claims to be unbiased within its
        Monte Carlo uncertainty (:func:`budget.runner.robustness.claim_holds`). For a class with
        :attr:`ClassSpec.at_most` the bound is on how far the estimate may fall below the truth."""
        return None

    # ------------------------------------------------------------ protocol planning
    def protocol_knobs(self, scenario: Any) -> tuple["Knob", ...]:
        """The protocol's knobs a lab chooses before booking the lab (frames per condition,
        poses, dark frames, polygon faces, passes, ...), each a scenario field with bounds
        (:class:`Knob`); ``budget <study> plan`` searches them. Empty (the default): the study
        has no plannable protocol."""
        return ()

    def protocol_shapes(self, scenario: Any) -> dict[str, dict[str, Any]]:
        """Named protocol geometries the planner compares besides the counts, each a mapping of
        dotted scenario keys to values (e.g. an HSFE step pattern along one diagonal or over a
        grid spanning both axes). Empty (the default): the scenario's own shape only."""
        return {}

    def shape_value(self, scenario: Any, field: str) -> Any:
        """The value of a :meth:`protocol_shapes` field as the protocol uses it: two scenarios
        with equal values run the same shape there. The planner keeps the scenario's own value
        of a shape field no requirement depends on by comparing it (docs/planning.md,
        "Separable plans"). Default: the field's value as the validated scenario holds it; a
        study whose field has another spelling of the same shape (an empty list meaning every
        filter) says so here."""
        obj = scenario
        for part in field.split("."):
            obj = obj[part] if isinstance(obj, dict) else getattr(obj, part)
        return obj

    def lab_time_s(self, scenario: Any) -> dict[str, float]:
        """The lab time the scenario's protocol takes, in seconds, by item (``"exposure"``,
        ``"moves"``, ``"settling"``, ``"dwell"``, ...), from the scenario's own fields; the
        planner's cost is their sum. Empty (the default): no lab time model, which a study with
        :meth:`protocol_knobs` must give (``plan`` refuses it otherwise)."""
        return {}

    def field_classes(self, scenario: Any) -> dict[str, tuple[str, ...]]:
        """For each plannable dotted scenario field (every :attr:`Knob.field` and every field a
        :meth:`protocol_shapes` override sets), the names of the classes (:attr:`ClassSpec.name`)
        whose estimates or truths it can change. A field not listed may change every class.
        The planner splits a plan into independent sub-plans along it (docs/planning.md).
        Default: ``{}`` (every field may change every class: no decomposition)."""
        return {}

    def restrict_classes(self, scenario: Any, classes: frozenset[str]) -> Any | None:
        """A scenario whose trials and truths compute only what the classes ``classes`` need
        (at least those classes, with the same numbers for them as ``scenario`` on the same
        seed), or None when the study cannot restrict (the default). The planner runs a
        sub-plan's trials on it and still takes the lab time from the unrestricted scenario
        (:meth:`lab_time_s` is never called on a restricted one)."""
        return None

    def uncomputed_class(self, scenario: Any, name: str) -> str | None:
        """Where ``name`` is one of the study's classes that ``scenario`` does not compute (not
        among :meth:`classes`), why, naming the scenario field that leaves it out (a sentence
        the planner's error quotes); None (the default): not a class of the study."""
        return None

    # ------------------------------------------------------------ presentation
    def report_sections(self, result: Any, out_dir: Path) -> list[ReportSection]:
        """Sections and plots this study adds to the common report (none by default)."""
        return []

    def likely_cause(self, result: Any, key: Key, stats: dict) -> str | None:
        """The most likely cause of a class a variant does not recover (``stats``: its
        statistics), one sentence, or None where the study does not know. Any number it quotes
        must come from ``result``; it should return None where ``stats`` do not show the
        pattern the cause explains."""
        return None

    def details(self, result: Any) -> dict:
        """JSON-ready figures of this study beyond the per-class statistics (from the run's
        samples, truths and :attr:`TrialResult.aux`); they go under ``details`` in the
        result's JSON (:meth:`budget.runner.run.StudyResult.to_json`). None by default."""
        return {}
