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
from typing import Any

from pydantic import BaseModel, ConfigDict, ValidationError


class ScenarioError(ValueError):
    """A scenario (or sweep, or manifest) file is invalid.

    The message names the file (when known), the dotted field path and what is wrong,
    one line per problem, so the CLI can print it without a traceback.
    """


class StrictModel(BaseModel):
    """Frozen model that forbids unknown keys and validates on assignment/creation."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=False, validate_default=True)


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
