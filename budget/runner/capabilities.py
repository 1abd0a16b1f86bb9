"""What a study may do beyond the core: small opt-in protocols the machinery recognises.

A study (:class:`budget.runner.study.Study`) writes three methods, ``classes``, ``trial`` and
``truths``. Everything else is a *capability*: a protocol of one to three methods that a study
opts into by naming it among its bases (``class StarCameraStudy(Study, SplitTruths, ...)``)
and implementing its methods. The runner, the planner, the sweeps and the reports ask for a
capability with :func:`capability`, which returns the study itself when it has it and the
default behaviour otherwise, so no caller tests for a method's presence.

========================  =====================================================  ===============================
capability                methods                                                without it
========================  =====================================================  ===============================
:class:`Prepared`         ``setup(scenario)``: the set-up trials share, built     nothing is prepared
                          once per process and set-up key (:func:`prepared`);
                          ``setup_key(scenario)``: what the set-up depends on
:class:`CheckedScenario`  ``check(scenario, where=)``: what the simulator would   no early check
                          refuse later, checked cheaply (sweeps check each point)
:class:`BatchedTrials`    ``trial_batch(scenario, seed, ks)``: many trials at     one ``trial`` per k
                          once, equal to ``trial`` per k
:class:`Warmup`           ``prewarm(scenario)`` once in the run's process,        nothing
                          ``worker_init()`` once in each worker
:class:`SplitTruths`      ``truth_parts``, ``truth_part``, ``truths_from_parts``: one part, ``truths`` whole
                          a heavy truth spread over the workers
:class:`SizedTruths`      ``truth_size_for(scenario, seed, target_se)``: truth     the scenario's own sizes
                          sampling sized to a target standard error
:class:`SharedTruths`     ``truth_fields(scenario)``: the fields the truths       every field
                          depend on (sweeps share truths across points)
:class:`WorldEffects`     ``truth_depends_on_effects(scenario)``,                 truths depend on every effect;
                          ``claim(scenario, class, variant)``                    unbiased claims
:class:`Plannable`        ``protocol_knobs(scenario)``, ``lab_time_s(scenario)``  no ``plan`` command
:class:`ProtocolShapes`   ``protocol_shapes(scenario)``, ``shape_value(...)``     the scenario's own shape
:class:`SeparablePlans`   ``field_classes``, ``restrict_classes``,                one joint plan
                          ``uncomputed_class``
:class:`Presented`        ``report_sections``, ``likely_cause``, ``details``      the common report only
:class:`Claims`           ``claims(scenario)``: the source document's claims     no claims
                          (:mod:`budget.runner.claims`)
========================  =====================================================  ===============================

The contract of each method is in its protocol's docstring below; ``docs/architecture.md``
shows the toy study (``tests/toys/full_toy.py``) implementing every one of them.
"""

from __future__ import annotations

from collections import OrderedDict
from pathlib import Path
from collections.abc import Hashable
from typing import TYPE_CHECKING, Any, Protocol, TypeVar, runtime_checkable

from simcam.dotted import get_dotted

if TYPE_CHECKING:
    from budget.runner.claims import Claim
    from budget.runner.study import Key, Knob, ReportSection, Study, TrialResult, Truth
    from simcam.config_base import ScenarioBase

__all__ = ["BatchedTrials", "CAPABILITIES", "CheckedScenario", "Claims", "Plannable", "Prepared", "Presented",
           "ProtocolShapes", "SeparablePlans", "SharedTruths", "SizedTruths", "SplitTruths", "Warmup",
           "WorldEffects", "capability", "declared_capabilities", "has_capability", "missing_members", "prepared",
           "undeclared_members"]


@runtime_checkable
class Prepared(Protocol):
    """A set-up shared by every trial of a scenario (tables, a design matrix, a camera's maps),
    built by :meth:`setup` once per process and scenario and handed back by :func:`prepared`."""

    def setup(self, scenario: ScenarioBase) -> Any:
        """What the trials and truths of ``scenario`` share; it must depend on ``scenario`` only
        (no seed) and change no result."""

    def setup_key(self, scenario: ScenarioBase) -> Hashable:
        """What :meth:`setup` depends on: two scenarios with equal keys share one set-up in
        :func:`prepared`'s cache (a key that leaves out fields the set-up never reads, such as
        the truths' sampling sizes, lets the scenario that :class:`SizedTruths` resized share
        the run's set-up). It must change wherever the set-up would. Optional: by default the
        scenario's hash (every field)."""
        return scenario.hash


@runtime_checkable
class CheckedScenario(Protocol):
    """Cheap checks of what the simulator would refuse later."""

    def check(self, scenario: ScenarioBase, *, where: str) -> None:
        """Raise :class:`simcam.infra.errors.ScenarioError` (or the simulator's ValueError)
        naming ``where`` when ``scenario`` cannot be run; sweeps check every point first."""


@runtime_checkable
class BatchedTrials(Protocol):
    """Vectorised trials."""

    def trial_batch(self, scenario: ScenarioBase, seed: int, ks: list[int]) -> list[TrialResult]:
        """Trials ``ks`` at once; for each ``k`` exactly what ``trial(scenario, seed, k)`` gives."""


@runtime_checkable
class Warmup(Protocol):
    """Start-up work that changes no result (compiling numba kernels, setting threads)."""

    def prewarm(self, scenario: ScenarioBase) -> None:
        """Once in the run's own process before any trial or truth (e.g. compile kernels in
        parallel processes, :func:`simcam.numba_warm.compiling_in_parallel`). Optional."""
        return None

    def worker_init(self) -> None:
        """Once in each worker process, after the runner has set one numba thread there.
        Optional."""
        return None


@runtime_checkable
class SplitTruths(Protocol):
    """A heavy truth computed in independent parts spread over the workers."""

    def truth_parts(self, scenario: ScenarioBase, seed: int) -> list:
        """The independent parts of ``truths(scenario, seed)`` (small picklable descriptions)."""

    def truth_part(self, scenario: ScenarioBase, seed: int, part: Any) -> Any:
        """The result of one part."""

    def truths_from_parts(self, scenario: ScenarioBase, seed: int, results: list) -> dict[tuple[str, str], Truth]:
        """``truths(scenario, seed)`` from its parts' results, in :meth:`truth_parts` order; must
        equal it."""


@runtime_checkable
class SizedTruths(Protocol):
    """Sampled truths whose sampling is sized to the precision the run needs."""

    def truth_size_for(self, scenario: ScenarioBase, seed: int,
                       target_se: dict[tuple[str, str], float]) -> ScenarioBase:
        """``scenario`` with its truth sampling sized so that each sampled truth's standard error
        is about ``target_se[(class, axis)]`` (class unit) or below; keys may be missing. Only the
        truths' sampling sizes may change, and any pilot it draws comes from the truths' seed
        sequence of ``seed``, so the size is reproducible."""


@runtime_checkable
class SharedTruths(Protocol):
    """Truths that depend on some fields only, so sweeps share them across points."""

    def truth_fields(self, scenario: ScenarioBase) -> tuple[str, ...]:
        """Dotted prefixes of the scenario fields the truths depend on (with the truth seed); two
        scenarios equal on them have the same truths. It must agree with
        :meth:`WorldEffects.truth_depends_on_effects`."""


@runtime_checkable
class WorldEffects(Protocol):
    """A world with named effects the lab's model leaves out (``budget <study> robustness``)."""

    def truth_depends_on_effects(self, scenario: ScenarioBase) -> set[str] | None:
        """Names of the ``world.effects`` whose change changes the truths (None: all); a
        robustness run reuses the ideal world's truths for cases outside this set."""

    def claim(self, scenario: ScenarioBase, class_name: str, variant: str) -> float | None:
        """The accuracy the method claims for a class with a variant, in the class's unit (a
        bound on the bias); None: unbiased within the Monte Carlo uncertainty. For a class with
        :attr:`~budget.runner.study.ClassSpec.at_most` it bounds how far the estimate may fall
        below the truth. Optional: by default None for every class."""
        return None


@runtime_checkable
class Plannable(Protocol):
    """A lab protocol the planner (``budget <study> plan``) can search."""

    def protocol_knobs(self, scenario: ScenarioBase) -> tuple[Knob, ...]:
        """The protocol's knobs a lab chooses (frames, poses, faces, passes), each a scenario
        field with bounds."""

    def lab_time_s(self, scenario: ScenarioBase) -> dict[str, float]:
        """The lab time of the scenario's protocol in seconds, by item (exposure, moves,
        settling, dwell), from the scenario's own fields; the planner's cost is their sum."""


@runtime_checkable
class ProtocolShapes(Protocol):
    """Named protocol geometries the planner compares besides the counts."""

    def protocol_shapes(self, scenario: ScenarioBase) -> dict[str, dict[str, Any]]:
        """Named geometries, each a mapping of dotted scenario keys to values."""

    def shape_value(self, scenario: ScenarioBase, field: str) -> Any:
        """A shape field's value as the protocol uses it: two scenarios with equal values run
        the same shape (two spellings of one shape give one value). Optional: by default the
        field's value as the validated scenario holds it."""
        return get_dotted(scenario, field, where=getattr(scenario, "source", "scenario"))


@runtime_checkable
class SeparablePlans(Protocol):
    """A plan that splits into independent sub-plans (docs/planning.md, "Separable plans")."""

    def field_classes(self, scenario: ScenarioBase) -> dict[str, tuple[str, ...]]:
        """For each plannable field, the classes whose estimates or truths it can change (a
        field not listed may change every class)."""

    def restrict_classes(self, scenario: ScenarioBase, classes: frozenset[str]) -> ScenarioBase | None:
        """A scenario computing only what ``classes`` need, with the same numbers for them on
        the same seed; None where the study cannot restrict. Optional: None by default."""
        return None

    def uncomputed_class(self, scenario: ScenarioBase, name: str) -> str | None:
        """Why a class of the study is not computed by ``scenario``, naming the field that leaves
        it out; None when ``name`` is not a class of the study. Optional: None by default."""
        return None


@runtime_checkable
class Presented(Protocol):
    """What a study adds to the common report and JSON; each method is optional."""

    def report_sections(self, result: Any, out_dir: Path) -> list[ReportSection]:
        """Sections and figures the study adds to its report (none by default)."""
        return []

    def likely_cause(self, result: Any, key: Key, stats: dict) -> str | None:
        """The most likely cause of a class a variant does not recover, one sentence quoting
        only numbers of ``result``, or None where ``stats`` do not show the pattern (the
        default)."""
        return None

    def details(self, result: Any) -> dict:
        """JSON-ready figures beyond the per-class statistics (under ``details`` in the JSON;
        none by default)."""
        return {}


@runtime_checkable
class Claims(Protocol):
    """The claims of the study's source document, for the claims ledger."""

    def claims(self, scenario: ScenarioBase) -> tuple[Claim, ...]:
        """The source document's claims (:class:`budget.runner.claims.Claim`), each mapped to a
        class, variant and axis of the study with its tolerance rule, or untestable with its
        reason; ids unique."""


#: every capability, in the order of the module docstring's table
CAPABILITIES: tuple[type, ...] = (Prepared, CheckedScenario, BatchedTrials, Warmup, SplitTruths, SizedTruths,
                                  SharedTruths, WorldEffects, Plannable, ProtocolShapes, SeparablePlans, Presented,
                                  Claims)


# ------------------------------------------------------------------ what a study without one gets
class _Default:
    """The behaviour of a capability a study does not have; wraps the study."""

    def __init__(self, study: Study):
        self.study = study


class _NoSetup(_Default):
    def setup(self, scenario):
        return None


class _NoCheck(_Default):
    def check(self, scenario, *, where):
        return None


class _OneByOne(_Default):
    def trial_batch(self, scenario, seed, ks):
        return [self.study.trial(scenario, seed, k) for k in ks]


class _NoWarmup(_Default, Warmup):
    """No start-up work (:class:`Warmup`'s defaults)."""


class _WholeTruths(_Default):
    def truth_parts(self, scenario, seed):
        return [None]

    def truth_part(self, scenario, seed, part):
        return self.study.truths(scenario, seed)

    def truths_from_parts(self, scenario, seed, results):
        return results[0]


class _OwnSizes(_Default):
    def truth_size_for(self, scenario, seed, target_se):
        return scenario


class _AllFields(_Default):
    def truth_fields(self, scenario):
        return None


class _NoEffects(_Default, WorldEffects):
    def truth_depends_on_effects(self, scenario):
        return None


class _OwnShape(_Default, ProtocolShapes):
    def protocol_shapes(self, scenario):
        return {}


class _Joint(_Default, SeparablePlans):
    def field_classes(self, scenario):
        return {}


class _CommonReport(_Default, Presented):
    """The common report only (:class:`Presented`'s defaults)."""


class _NoClaims(_Default):
    def claims(self, scenario):
        return ()


_DEFAULTS: dict[type, type[_Default]] = {
    Prepared: _NoSetup, CheckedScenario: _NoCheck, BatchedTrials: _OneByOne, Warmup: _NoWarmup,
    SplitTruths: _WholeTruths, SizedTruths: _OwnSizes, SharedTruths: _AllFields, WorldEffects: _NoEffects,
    ProtocolShapes: _OwnShape, SeparablePlans: _Joint, Presented: _CommonReport, Claims: _NoClaims,
}

C = TypeVar("C")


def has_capability(study: Study, protocol: type) -> bool:
    """Whether ``study`` names ``protocol`` among its bases (a method of the same name alone does
    not declare it)."""
    return protocol in type(study).__mro__


def capability(study: Study, protocol: type[C]) -> C:
    """``study`` itself where it declares ``protocol``, otherwise the default behaviour of that
    capability (the table in the module docstring). :class:`Plannable` has no default: a
    study without it has no plan (ask :func:`has_capability`)."""
    if has_capability(study, protocol):
        return study
    if protocol not in _DEFAULTS:
        raise TypeError(f"study {getattr(study, 'name', study)!r} does not have {protocol.__name__}")
    return _DEFAULTS[protocol](study)


def declared_capabilities(cls: type) -> tuple[type, ...]:
    """The capabilities a study class names among its bases (directly or through a parent)."""
    return tuple(p for p in CAPABILITIES if p in cls.__mro__)  # named, not matched by shape


#: members a capability's protocol implements itself (the rest each study must write)
OPTIONAL_MEMBERS = frozenset({"Prepared.setup_key", "Warmup.prewarm", "Warmup.worker_init", "WorldEffects.claim",
                              "ProtocolShapes.shape_value", "SeparablePlans.restrict_classes",
                              "SeparablePlans.uncomputed_class",
                              "Presented.report_sections", "Presented.likely_cause", "Presented.details"})


def missing_members(cls: type) -> list[str]:
    """Required methods of a declared capability that ``cls`` leaves to the protocol's empty
    body (:class:`budget.runner.study.Study` refuses such a class when it is defined)."""
    missing = []
    for proto in declared_capabilities(cls):
        for name, member in vars(proto).items():
            qual = f"{proto.__name__}.{name}"
            if name.startswith("_") or not callable(member) or qual in OPTIONAL_MEMBERS:
                continue
            if getattr(cls, name) is member:
                missing.append(qual)
    return missing


def undeclared_members(cls: type) -> list[str]:
    """Methods ``cls`` defines under a capability's member name without declaring that
    capability: the machinery would never call them, so :class:`budget.runner.study.Study`
    refuses such a class instead of ignoring the method."""
    declared = declared_capabilities(cls)
    out = []
    for proto in CAPABILITIES:
        if proto in declared:
            continue
        for name, member in vars(proto).items():
            if not name.startswith("_") and callable(member) and hasattr(cls, name):
                out.append(f"{name} (declare {proto.__name__})")
    return out


# ------------------------------------------------------------------ the set-up cache
#: set-ups kept per process (a sweep or a robustness run alternates among a few scenarios)
SETUPS_KEPT = 4
_SETUPS: OrderedDict = OrderedDict()


def prepared(study: Study, scenario: ScenarioBase) -> Any:
    """The set-up of ``scenario`` (:meth:`Prepared.setup`), built once per process: the runner
    owns this cache, keyed by the study's class and its :meth:`Prepared.setup_key` of the
    scenario (by default the scenario's hash), and keeps the :data:`SETUPS_KEPT` most recently
    used. None for a study without :class:`Prepared`."""
    if not has_capability(study, Prepared):
        return None
    key = (type(study).__module__, type(study).__qualname__, study.setup_key(scenario))
    if key in _SETUPS:
        _SETUPS.move_to_end(key)
        return _SETUPS[key]
    value = study.setup(scenario)
    _SETUPS[key] = value
    while len(_SETUPS) > SETUPS_KEPT:
        _SETUPS.popitem(last=False)
    return value
