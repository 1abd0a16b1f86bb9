"""The study contract: what one lab method on one instrument gives the shared machinery.

A *study* (seed 000's star-camera lab methods, seed 001's inductosyn calibration, ...) subclasses
:class:`Study` and writes three methods:

* :meth:`Study.classes`: its error classes (:class:`ClassSpec`: label, unit, axes, whether the
  truth is drawn per trial, and the role: an estimate of a truth, an input, a residual or a
  stated uncertainty);
* :meth:`Study.trial`: the estimates of one simulated measurement by the same estimators that
  run on real data, keyed ``(class, variant, axis)``; where the truth is drawn per trial, the
  trial's own truth under the same key; where the estimator states an uncertainty, its 1-sigma
  value (:class:`TrialResult`);
* :meth:`Study.truths`: the truth of each class that is a property of the scenario, keyed
  ``(class, axis)``, with its own standard error (:class:`Truth`).

and sets its identity: ``name`` (registry key and CLI group), ``title``, ``seed_document``,
``variants`` (report order), ``reference_variants`` (variants that estimate nothing and so never
"recover"), ``scenario_module`` (its instrument's scenario module in :mod:`simcam`, with
``default_text()``, ``from_dict(data, *, source)``, ``load(path=None)``, ``default()`` and a
model subclassing :class:`simcam.config_base.ScenarioBase`, the typed scenario every method
receives) and ``trials_per_task`` (most trials in one task sent to a worker).

Everything else is an opt-in capability (:mod:`budget.runner.capabilities`: a set-up built once
per process, truths in parts, sized or shared, world effects, planning, report sections). The
run settings come from the scenario's ``[validation]`` table
(:class:`simcam.config_base.ValidationSettings`). A study's commands besides ``validate`` live
in its ``cli`` module, which the command line finds through the registry.

Randomness: trial ``k`` of a run with ``seed`` draws only from
``numpy.random.SeedSequence(seed, spawn_key=(k,))`` (:func:`trial_seed_sequence`) and the
truths from ``SeedSequence(seed, spawn_key=(TRUTH_SPAWN_KEY,))``, so results do not depend on
the number of workers or the order in which trials finish.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from budget.runner.capabilities import SharedTruths, capability, missing_members, prepared, undeclared_members
from simcam.config_base import ScenarioBase, load_scenario_file
from simcam.dotted import get_dotted

__all__ = ["CLASS_ROLES", "ClassSpec", "Key", "Knob", "ReportSection", "Study", "TRUTH_SPAWN_KEY", "TrialResult",
           "Truth", "INSTRUMENT_SPAWN_KEY", "instrument_seed_sequence", "trial_seed_sequence", "truth_identity", "truth_seed_sequence"]

#: spawn key of the truths' seed sequence (trials use 0, 1, 2, ...)
TRUTH_SPAWN_KEY = 2**31
#: first spawn key of the instruments' seed sequences (distinct from the trials' and the truths')
INSTRUMENT_SPAWN_KEY = 2**31 + 1

#: (class, variant, axis)
Key = tuple[str, str, str]

#: what a class's figures are (:attr:`ClassSpec.role`)
CLASS_ROLES = ("result", "input", "residual", "stated")


def trial_seed_sequence(seed: int, k: int) -> np.random.SeedSequence:
    """The seed sequence of trial ``k``: ``SeedSequence(seed, spawn_key=(k,))``."""
    return np.random.SeedSequence(seed, spawn_key=(k,))


def instrument_seed_sequence(instrument_seed: int | None, seed: int, k: int) -> np.random.SeedSequence:
    """The seed sequence of trial ``k``'s instrument (``validation.instrument_seed``,
    :class:`simcam.config_base.ValidationSettings`).

    ``instrument_seed`` None: a new instrument per trial,
    ``SeedSequence(seed, spawn_key=(INSTRUMENT_SPAWN_KEY, k))``; an integer: the same pinned
    instrument for every trial and every run seed,
    ``SeedSequence(instrument_seed, spawn_key=(INSTRUMENT_SPAWN_KEY,))``. Neither shares a
    stream with :func:`trial_seed_sequence` or :func:`truth_seed_sequence`.
    """
    if instrument_seed is None:
        return np.random.SeedSequence(seed, spawn_key=(INSTRUMENT_SPAWN_KEY, k))
    return np.random.SeedSequence(instrument_seed, spawn_key=(INSTRUMENT_SPAWN_KEY,))


def truth_seed_sequence(seed: int) -> np.random.SeedSequence:
    """The seed sequence of the truths: ``SeedSequence(seed, spawn_key=(2**31,))``."""
    return np.random.SeedSequence(seed, spawn_key=(TRUTH_SPAWN_KEY,))


def truth_identity(study: "Study", scenario: ScenarioBase) -> str:
    """Hash (16 hex digits) of what :meth:`Study.truths` depends on besides the seed: the values
    of the fields :meth:`~budget.runner.capabilities.SharedTruths.truth_fields` names (every
    field for a study without that capability). Two scenarios with the same identity have the
    same truths with the same seed."""
    data = scenario.model_dump(mode="json", exclude_none=True)
    data.pop("name", None)
    fields = capability(study, SharedTruths).truth_fields(scenario)
    if fields is not None:
        data = {f: get_dotted(data, f, default=None) for f in sorted(set(fields))}
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
    rss_of : tuple of str
        The classes whose truths this one's is the root-sum-square of (independent sources:
        seed 000's LSFE of S, C1 and C2, its total of TE, HSFE and LSFE). With
        ``per_trial_truth`` the trials give none for it: the runner combines the parts' truths,
        per trial or fixed, once the fixed ones are known
        (:func:`budget.runner.combined_truths.combined_trial_truths`).
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
    rss_of: tuple[str, ...] = ()
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
    """One knob of a lab protocol (:meth:`~budget.runner.capabilities.Plannable.protocol_knobs`): a scenario field the lab
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


#: hooks of the earlier contract and what replaced them (a study still defining one is refused)
RETIRED_HOOKS = {
    "default_trials": "the scenario's validation.trials", "default_tolerance": "the scenario's validation.tolerance",
    "max_trials": "the scenario's validation.max_trials", "batch_trials": "the scenario's validation.batch_trials",
    "chunk_trials": "the class attribute trials_per_task", "commands": "commands() of the study's cli module",
}


class Study(ABC):
    """One lab method on one instrument: identity, scenario, and the three methods of the core
    (see the module docstring); capabilities are named among the bases."""

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
    #: most trials in one task sent to a worker (a few seconds of work at most)
    trials_per_task: int = 10

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        missing = missing_members(cls)
        if missing:
            raise TypeError(f"{cls.__name__} declares capabilities without implementing {', '.join(missing)}")
        retired = [f"{name} (now {RETIRED_HOOKS[name]})" for name in RETIRED_HOOKS if hasattr(cls, name)]
        if retired:
            raise TypeError(f"{cls.__name__} defines hooks the study contract no longer has: {', '.join(retired)}")
        undeclared = undeclared_members(cls)
        if undeclared:
            raise TypeError(f"{cls.__name__} defines capability methods without declaring them: {', '.join(undeclared)}")

    # ------------------------------------------------------------ scenario
    def _scenario_module(self):
        if not self.scenario_module:
            raise TypeError(f"{type(self).__name__}: set scenario_module")
        return importlib.import_module(self.scenario_module)

    def default_text(self) -> str:
        """The embedded default scenario, as TOML text with its comments."""
        return self._scenario_module().default_text()

    def from_dict(self, data: dict, *, source: str) -> ScenarioBase:
        """Validate a scenario mapping into the study's frozen model.

        Raises :class:`simcam.infra.errors.ScenarioError` naming ``source`` and the field.
        """
        return self._scenario_module().from_dict(data, source=source)

    def load_scenario(self, path: str | Path | None = None) -> ScenarioBase:
        """The scenario at ``path`` (strict TOML) or, for None, the embedded default: the scenario
        module's ``load`` where it has one, else :meth:`default_text` and :meth:`from_dict`
        through :func:`simcam.config_base.load_scenario_file`."""
        module = self._scenario_module() if self.scenario_module else None
        if module is not None and hasattr(module, "load"):
            return module.load(path)
        return load_scenario_file(path, from_dict=self.from_dict, default_text=self.default_text, study=self.name)

    def scenario_hash(self, scenario: ScenarioBase) -> str:
        """Hash of the scenario's canonical content."""
        return scenario.hash

    def scenario_text(self, scenario: ScenarioBase) -> str:
        """The resolved scenario as TOML (what the JSON result carries)."""
        return scenario.to_toml()

    def prepared(self, scenario: ScenarioBase) -> Any:
        """The scenario's set-up (:class:`budget.runner.capabilities.Prepared`), built once per
        process by the runner's cache; None for a study without a set-up."""
        return prepared(self, scenario)

    # ------------------------------------------------------------ the method
    @abstractmethod
    def classes(self, scenario: ScenarioBase) -> tuple[ClassSpec, ...]:
        """The error classes this study reports, in report order."""

    @abstractmethod
    def trial(self, scenario: ScenarioBase, seed: int, k: int) -> TrialResult:
        """One simulated measurement and its estimates (see the module docstring)."""

    @abstractmethod
    def truths(self, scenario: ScenarioBase, seed: int) -> dict[tuple[str, str], Truth]:
        """The truth of every class without ``per_trial_truth``, keyed ``(class, axis)``."""
