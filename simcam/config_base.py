"""Shared base for every typed scenario model (star camera, inductosyn, sweeps).

All scenario models are frozen, keyword-only pydantic models that refuse unknown keys
and coerce nothing silently: a wrong type, an unknown key or an out-of-range value is
a :class:`ScenarioError` naming the dotted field path. Scenario files of every kind are
read by :func:`read_toml` (strict: a missing, unreadable, non-UTF-8, empty or invalid
file is one error naming it).
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError, model_serializer

from simcam.infra.errors import ScenarioError
from simcam.infra.outputs import input_file_problem


class StrictModel(BaseModel):
    """Frozen model that forbids unknown keys and validates on assignment/creation."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=False, validate_default=True)


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
    * ``batch_trials``: trials between two convergence checks (>= 1).

    The runner reads them through the study's run-settings hooks
    (:mod:`budget.runner.study`); subclasses may change the defaults, not the limits (use
    :data:`Trials`, :data:`BatchTrials`, :data:`Tolerance`).
    """

    trials: Trials = 200
    tolerance: Tolerance = None
    max_trials: Trials = 5000
    batch_trials: BatchTrials = 50


class ScenarioBase(StrictModel):
    """What every instrument's scenario has, whatever its physics:

    * ``name``: one line naming the scenario (printed in the validate header and carried by
      the JSON result; each embedded default has one);
    * ``validation``: the Monte Carlo settings (:class:`ValidationSettings` or a subclass);
    * :attr:`hash`: SHA-256 prefix of the canonical content (:func:`model_hash`; a model may
      override the rule, as the star camera does for an unset lens);
    * :attr:`source`: where the scenario was loaded from (a file name, ``embedded ...
      default``), named in errors found later, e.g. in a worker process; not part of the
      content or the hash. Set by the instrument module's ``from_dict``.

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

    def with_source(self, source: str):
        """Record ``source`` on this (otherwise frozen) model and return it."""
        self._source = source
        return self


#: pydantic's bound checks: a NaN or infinity fails them with a misleading message
_BOUND_TYPES = ("greater_than", "greater_than_equal", "less_than", "less_than_equal", "multiple_of")


def format_validation_error(err: ValidationError, *, source: str | None = None) -> str:
    """Render a pydantic ValidationError as lines ``file: field.path: message``."""
    lines = []
    prefix = f"{source}: " if source else ""
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(top level)"
        msg = e["msg"]
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        inp = e.get("input")
        if isinstance(inp, float) and not math.isfinite(inp) and e["type"] in _BOUND_TYPES:
            msg = "must be a finite number"  # not "should be less than 1" for a NaN
        shown = "" if e["type"] in ("extra_forbidden", "missing") else f" (got {inp!r})"
        if len(shown) > 80:
            shown = shown[:77] + "...)"
        lines.append(f"{prefix}{loc}: {msg}{shown}")
    return "\n".join(lines)


def validate_model(model_cls: type[BaseModel], data: dict[str, Any], *, source: str | None = None):
    """Validate ``data`` into ``model_cls`` or raise :class:`ScenarioError` naming fields."""
    try:
        return model_cls.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(format_validation_error(err, source=source)) from None


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
