"""Shared base for every typed scenario model (star camera, inductosyn, sweeps).

All scenario models are frozen, keyword-only pydantic models that refuse unknown keys
and coerce nothing silently: a wrong type, an unknown key or an out-of-range value is
a :class:`ScenarioError` naming the dotted field path. Scenario files of every kind are
read by :func:`read_toml` (strict: a missing, unreadable, non-UTF-8, empty or invalid
file is one error naming it).
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import tomllib
import types
import typing
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_serializer, model_validator
from pydantic_core import PydanticCustomError

from simcam.infra.errors import ScenarioError
from simcam.infra.outputs import input_file_problem


class StrictModel(BaseModel):
    """Frozen model that forbids unknown keys and validates on assignment/creation.

    A boolean is never a number: ``true`` where a field (or an element of a list, tuple or
    mapping field) takes an int or a float is refused, naming the field (pydantic would
    read it as 1; :func:`bool_where_number`). Every float is finite (``allow_inf_nan``
    off: a NaN or an infinity is refused, naming the field); a field's physical range is
    declared beside it (``Field(ge=..., le=...)``, the reason in its description) and a
    value outside it is refused with the range (:func:`format_validation_error`).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=False, validate_default=True,
                              allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _no_boolean_for_a_number(cls, data: Any) -> Any:
        # a model-level check (a field validator may not sit on a union's discriminator);
        # format_validation_error puts the field named in the context on the error's path
        if isinstance(data, dict):
            for name, value in data.items():
                if isinstance(value, (bool, np.bool_, list, tuple, dict)) and bool_where_number(
                        value, _field_annotation(cls, name)):
                    raise PydanticCustomError(BOOL_NOT_NUMBER, "a boolean (true/false) is not a number; give a number",
                                              {"field": str(name), "value": value})
        return data


#: the pydantic error type of a boolean given for a number (its context names the field)
BOOL_NOT_NUMBER = "bool_not_number"


@functools.cache
def _field_annotation(cls: type[BaseModel], name: str) -> Any:
    info = cls.model_fields.get(name)
    return None if info is None else info.annotation


def _alternatives(ann: Any) -> list[Any]:
    """The types ``ann`` admits at its top level: through ``Annotated`` and unions."""
    origin = typing.get_origin(ann)
    if origin is Annotated:
        return _alternatives(typing.get_args(ann)[0])
    if origin in (typing.Union, types.UnionType):
        return [t for a in typing.get_args(ann) for t in _alternatives(a)]
    return [ann]


def _elements(alts: list[Any], value: Any) -> list[list[Any]] | None:
    """For a list/tuple ``value``: the annotations its elements may have, per element (None
    when no alternative is a sequence)."""
    per: list[list[Any]] = [[] for _ in value]
    found = False
    for a in alts:
        origin, args = typing.get_origin(a), typing.get_args(a)
        if origin in (list, tuple, set, frozenset, typing.Sequence) or a in (list, tuple):
            found = True
            if origin is tuple and args and args[-1] is not Ellipsis:
                for i in range(min(len(value), len(args))):
                    per[i].append(args[i])
            else:
                for i in range(len(value)):
                    per[i].append(args[0] if args else Any)
    return per if found else None


def bool_where_number(value: Any, ann: Any) -> bool:
    """Whether ``value`` holds a boolean where the annotation ``ann`` takes a number (an int
    or a float, and not a bool), at the top level or inside a list, tuple or mapping."""
    if ann is None:
        return False
    alts = _alternatives(ann)
    if isinstance(value, (bool, np.bool_)):
        return any(a in (int, float) for a in alts) and not any(a in (bool, Any) for a in alts)
    if isinstance(value, (list, tuple)):
        per = _elements(alts, value)
        return per is not None and any(bool_where_number(v, typing.Union[tuple(p)] if len(p) > 1 else p[0])
                                       for v, p in zip(value, per) if p)
    if isinstance(value, dict):
        vals = [typing.get_args(a)[1] for a in alts if typing.get_origin(a) is dict and len(typing.get_args(a)) == 2]
        return bool(vals) and any(bool_where_number(v, typing.Union[tuple(vals)] if len(vals) > 1 else vals[0])
                                  for v in value.values())
    return False


#: a number of Monte Carlo trials: at least 2 (a spread needs two; the CLI's ``--trials`` too)
Trials = Annotated[int, Field(ge=2)]
#: trials between two convergence checks of adaptive stopping
BatchTrials = Annotated[int, Field(ge=1)]
#: adaptive-stopping tolerance in the classes' own unit (> 0), or None for a fixed count
Tolerance = Annotated[float, Field(gt=0.0, allow_inf_nan=False)] | None


class ValidationSettings(StrictModel):
    """Monte Carlo validation settings of a scenario (its ``[validation]`` table), the same
    for every instrument; a study's own model subclasses this and adds only what its truth
    computation needs (e.g. the star camera's truth frames, the inductosyn's truth grid).

    * ``trials``: the number of trials when neither ``--trials`` nor ``--tolerance`` is given
      (>= 2, as ``--trials``);
    * ``tolerance``: when set, the run goes on in batches of ``batch_trials`` until the Monte
      Carlo standard error of every bias and spread is below it (JCGM 101 section 7.9), in
      each class's own unit (arcsec, px, ...); None (the default): ``trials`` trials;
    * ``max_trials``: the cap on trials under adaptive stopping (>= 2);
    * ``batch_trials``: trials between two convergence checks (>= 1);
    * ``instrument_seed``: None (the default): each trial draws its own instrument (the
      properties of one instrument: its maps, markers, encoder, lens, biases), so a verdict
      speaks for the population of instruments like the one simulated; an integer pins one
      instrument for every trial, and the results then speak for that instrument only. A
      study draws its instrument from
      :func:`budget.runner.study.instrument_seed_sequence`.

    The runner reads them through the study's run-settings hooks
    (:mod:`budget.runner.study`); subclasses may change the defaults, not the limits (use
    :data:`Trials`, :data:`BatchTrials`, :data:`Tolerance`).
    """

    trials: Trials = 200
    tolerance: Tolerance = None
    max_trials: Trials = 5000
    batch_trials: BatchTrials = 50
    instrument_seed: Annotated[int, Field(ge=0)] | None = None

    def pinned_instrument(self) -> str | None:
        """What fixes one instrument for every trial, in words (None: each trial draws its own).
        Here ``instrument_seed``; a study whose scenario pins its instrument otherwise says so
        by overriding this."""
        return None if self.instrument_seed is None else f"instrument seed {self.instrument_seed}"


class ScenarioBase(StrictModel):
    """What every instrument's scenario has, whatever its physics:

    * ``name``: one line naming the scenario (printed in the validate header and carried by
      the JSON result; each embedded default has one);
    * ``validation``: the Monte Carlo settings (:class:`ValidationSettings` or a subclass);
    * :attr:`hash`: SHA-256 prefix of the canonical content (:func:`model_hash`; a model may
      override the rule, as the star camera does for an unset lens);
    * :attr:`source`: where the scenario was loaded from (a file name, ``embedded ...
      default``), named in errors found later, e.g. in a worker process; not part of the
      content or the hash. Set by the instrument module's ``from_dict``;
    * :meth:`derived_paths`: the fields the scenario derives from its others (none by
      default), which setting values by dotted key (:mod:`simcam.dotted`) lets it derive again.

    Each instrument's scenario module provides the same four functions: ``default_text()``,
    ``from_dict(data, *, source)``, ``load(path=None)`` and ``default()``.
    """

    name: str = ""
    validation: ValidationSettings = ValidationSettings()

    _source: str = PrivateAttr(default="scenario")

    @property
    def hash(self) -> str:
        """SHA-256 prefix (16 hex digits) of the canonical JSON of the scenario."""
        return model_hash(self)

    @property
    def source(self) -> str:
        """Where the scenario came from (not part of its content)."""
        return self._source

    def pinned_instrument(self) -> str | None:
        """What fixes one instrument for every trial, in words, or None when each trial draws
        its own (:meth:`ValidationSettings.pinned_instrument`)."""
        return self.validation.pinned_instrument()

    def to_toml(self) -> str:
        """The resolved scenario as TOML text (what a JSON result carries)."""
        import tomli_w

        return tomli_w.dumps(self.model_dump(mode="json", exclude_none=True))

    @model_serializer(mode="wrap")
    def _validation_last(self, handler):
        # the base's fields come first in pydantic's order; a dump (a scenario's TOML) reads
        # better with the physics first and the Monte Carlo settings last
        data = handler(self)
        if isinstance(data, dict) and "validation" in data:
            data["validation"] = data.pop("validation")
        return data

    def __eq__(self, other: object) -> bool:
        # the content decides, not where it was read from (``source`` is a private attribute,
        # which pydantic would compare too)
        if not isinstance(other, BaseModel):
            return NotImplemented
        fields = type(self).model_fields
        return type(self) is type(other) and all(self.__dict__.get(k) == other.__dict__.get(k) for k in fields)

    __hash__ = StrictModel.__hash__

    def derived_paths(self) -> tuple[str, ...]:
        """The dotted paths of the fields this scenario derives from its others (none here; the
        star camera's traced lens sets its optics, :meth:`simcam.starcam.scenario.Scenario.derived_paths`).
        Setting values (:mod:`simcam.dotted`) drops those it does not set, so that the
        validation derives them again from the new values."""
        return ()

    def with_source(self, source: str):
        """Record ``source`` on this (otherwise frozen) model and return it."""
        self._source = source
        return self


#: pydantic's bound checks: a NaN or infinity fails them with a misleading message
_BOUND_TYPES = ("greater_than", "greater_than_equal", "less_than", "less_than_equal", "multiple_of")
#: the errors of a value outside its field's range (or not finite): shown with the range
_RANGE_TYPES = (*_BOUND_TYPES, "finite_number")


def format_validation_error(err: ValidationError, *, source: str | None = None,
                            model: type[BaseModel] | None = None) -> str:
    """Render a pydantic ValidationError as lines ``file: field.path: message``; a value out
    of its field's range (or not finite) names the range declared beside the field in
    ``model``, e.g. ``must be a finite number; its range is [0, 3600] (got inf)``."""
    lines = []
    prefix = f"{source}: " if source else ""
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(top level)"
        msg = e["msg"]
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        inp = e.get("input")
        if e["type"] == BOOL_NOT_NUMBER:  # raised by the model for one of its fields
            loc = ".".join(str(p) for p in (*e["loc"], e["ctx"]["field"]))
            inp = e["ctx"]["value"]
        if e["type"] == "finite_number" or (isinstance(inp, float) and not math.isfinite(inp)
                                             and e["type"] in _BOUND_TYPES):
            msg = "must be a finite number"  # not "should be less than 1" for a NaN
        if e["type"] in _RANGE_TYPES and model is not None and (rng := declared_range(model, e["loc"])):
            msg += f"; its range is {rng}"
        shown = "" if e["type"] in ("extra_forbidden", "missing") else f" (got {inp!r})"
        if len(shown) > 80:
            shown = shown[:77] + "...)"
        lines.append(f"{prefix}{loc}: {msg}{shown}")
    return "\n".join(lines)


def _leaf_types(ann: Any) -> list[Any]:
    """Every type inside ``ann``: through ``Annotated``, unions and containers."""
    if typing.get_origin(ann) is Annotated:
        return _leaf_types(typing.get_args(ann)[0])
    args = typing.get_args(ann)
    return [t for a in args if a is not Ellipsis for t in _leaf_types(a)] if args else [ann]


def _bounds(ann: Any, metadata: list) -> dict[str, float]:
    """The ``ge``/``gt``/``le``/``lt`` bounds of a field: its metadata and the ``Annotated``
    metadata inside its annotation (an element's bounds for a list or tuple field)."""
    found: dict[str, float] = {}
    todo, items = [ann], list(metadata)
    while todo:
        a = todo.pop()
        if typing.get_origin(a) is Annotated:
            items += list(typing.get_args(a)[1:])
        todo += [x for x in typing.get_args(a) if x is not Ellipsis]
    for m in items:
        for k in ("ge", "gt", "le", "lt"):
            v = getattr(m, k, None)
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                found.setdefault(k, v)
    return found


def declared_range(model: type[BaseModel], loc: tuple) -> str | None:
    """The range declared beside the field at ``loc`` (a pydantic error's location) in
    ``model``: ``[0, 3600]``, ``(0, 1)``; None when it has not two bounds."""
    models: list[Any] = [model]
    field = None
    for part in loc:
        hit = next((m.model_fields[part] for m in models if isinstance(part, str) and part in m.model_fields), None)
        if hit is None:  # a list index, a union's tag, a validator's name
            continue
        field = hit
        models = [t for t in _leaf_types(hit.annotation) if isinstance(t, type) and issubclass(t, BaseModel)]
    if field is None:
        return None
    b = _bounds(field.annotation, field.metadata)
    lo = ("[", b["ge"]) if "ge" in b else ("(", b["gt"]) if "gt" in b else None
    hi = ("]", b["le"]) if "le" in b else (")", b["lt"]) if "lt" in b else None
    if lo is None or hi is None:
        return None
    return f"{lo[0]}{lo[1]:g}, {hi[1]:g}{hi[0]}"


def validate_model(model_cls: type[BaseModel], data: dict[str, Any], *, source: str | None = None):
    """Validate ``data`` into ``model_cls`` or raise :class:`ScenarioError` naming fields
    (and, for a value out of range, the range declared beside the field)."""
    try:
        return model_cls.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(format_validation_error(err, source=source, model=model_cls)) from None


def model_hash(model: BaseModel) -> str:
    """SHA-256 (first 16 hex digits) of the model's canonical JSON: the scenario hash."""
    payload = json.dumps(model.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def read_toml(*, path: str | Path | None = None, text: str | None = None, source: str | None = None) -> dict:
    """Parse TOML from ``path`` or ``text``; a missing, unreadable, non-UTF-8 or invalid
    file raises :class:`ScenarioError` naming it."""
    if (path is None) == (text is None):
        raise TypeError("read_toml: give path or text")
    if path is not None:
        source = source or str(path)
        p = Path(path)
        if p.is_dir():
            raise ScenarioError(f"{source}: is a folder, not a scenario file")

        if (why := input_file_problem(p)) is not None:
            raise ScenarioError(f"{source}: {why}")
        try:
            raw = p.read_bytes()
        except FileNotFoundError:
            raise ScenarioError(f"{source}: file not found") from None
        except OSError as exc:
            raise ScenarioError(f"{source}: cannot read ({exc.strerror})") from None
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ScenarioError(f"{source}: not UTF-8 text (byte {exc.start}): is this a scenario file?") from None
        if not text.strip():
            raise ScenarioError(f"{source}: the file is empty (omit the argument to use the embedded default)")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from None


def load_scenario_file(path, *, from_dict, default_text, study: str):
    """The ``load(path=None)`` of an instrument's scenario module, written once: the file at
    ``path`` read strictly (:func:`read_toml`: missing, not UTF-8, empty, invalid TOML, a FIFO
    or a device is one line naming the file) and validated by ``from_dict``; for None, the
    embedded default ``default_text()`` (named ``embedded STUDY default`` in errors)."""
    if path is None:
        source = f"embedded {study} default"
        return from_dict(read_toml(text=default_text(), source=source), source=source)
    return from_dict(read_toml(path=path, source=str(path)), source=str(path))
