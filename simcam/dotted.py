"""Dotted keys: a scenario field named by its path (``detector.read_noise_e``,
``world.effects.hexapod_repeatability_arcsec``, ``detector.chips.0.read_noise_e``).

One module reads and sets them for every caller (sweeps, the planner, robustness, a
scenario's ``with_updates``), with one rule:

* components are table keys, list indices and ``*`` (every element of a list, when setting);
* the keys that exist are those of the validated scenario (its dump, ``resolved``): an unknown
  key, an index out of range or a path through a value is one :class:`ScenarioError` naming
  where the key came from (a file, a sweep, a plan), the key and the known keys at that level;
* a table (a mapping) given where the scenario holds a value, or a value given where it holds
  a table, is refused the same way (a list stays a list, a value a value);
* fields a scenario derives from its others (:meth:`simcam.config_base.ScenarioBase.derived_paths`,
  e.g. what a traced lens sets) are dropped before setting, unless a key sets them (or a field
  inside or around them), so that the validation derives them again from the new values.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Mapping
from typing import Any, TypeVar

from pydantic import BaseModel

from simcam.config_base import ScenarioBase
from simcam.infra.errors import ScenarioError

__all__ = ["covers", "derived_paths", "drop_derived", "get_dotted", "scenario_with", "set_dotted", "set_values"]

#: the scenario model a :func:`scenario_with` caller's ``from_dict`` returns
S = TypeVar("S", bound=BaseModel)

_MISSING = object()


def _parts(key: str, where: str) -> list[str]:
    """The components of dotted ``key``; an empty one is a :class:`ScenarioError`."""
    if not isinstance(key, str):
        raise ScenarioError(f"{where}: {key!r}: a dotted key must be text (e.g. 'detector.read_noise_e')")
    parts = key.split(".")
    if any(p == "" for p in parts):
        raise ScenarioError(f"{where}: {key!r}: empty component in dotted key")
    return parts


def _known(node: Any) -> str:
    """The keys one may name at ``node``, for an error message."""
    if isinstance(node, Mapping):
        return "known keys: " + ", ".join(sorted(str(k) for k in node))
    if isinstance(node, BaseModel):
        return "known keys: " + ", ".join(sorted(type(node).model_fields))
    if isinstance(node, (list, tuple)):
        return f"a list of {len(node)}: use an index 0..{len(node) - 1} or *" if node else "an empty list"
    return "not a table"


def _index(node: list | tuple, part: str, *, key: str, path: str, where: str) -> int:
    """Component ``part`` as an index of the list ``node`` at ``path``."""
    try:
        j = int(part)
    except ValueError:
        raise ScenarioError(f"{where}: {key!r}: {path} is a list: {part!r} is not an index ({_known(node)})") from None
    if not 0 <= j < len(node):
        raise ScenarioError(f"{where}: {key!r}: index {j} out of range at {path} ({_known(node)})")
    return j


def get_dotted(obj: Any, key: str, *, where: str = "scenario", default: Any = _MISSING) -> Any:
    """The value of dotted ``key`` in ``obj``: a model (its attributes, properties included),
    a mapping (its keys) or a list (its indices), at every level.

    Parameters
    ----------
    obj : pydantic model, mapping or list
        What to read (a scenario, its dump, a section of either).
    key : str
        The dotted key, e.g. ``"camera.exposure_s"`` or ``"lab.filters.0.center_nm"``.
    where : str
        Where the key came from, first in an error message.
    default : optional
        Returned when the key does not lead to a value (unknown key, index out of range,
        a path through a value); without it that is an error.

    Raises
    ------
    ScenarioError
        Naming ``where``, the key and the known keys at the level where it went wrong
        (only without ``default``).
    """
    parts = _parts(key, where)
    node = obj
    for i, part in enumerate(parts):
        path = ".".join(parts[:i]) or "top level"
        try:
            node = _child(node, part, key=key, path=path, where=where)
        except ScenarioError:
            if default is _MISSING:
                raise
            return default
    return node


def _child(node: Any, part: str, *, key: str, path: str, where: str) -> Any:
    """Component ``part`` of ``node`` (at ``path`` of ``key``): a mapping's key, a list's index,
    a model's (or another object's) attribute."""
    if isinstance(node, Mapping):
        if part not in node:
            raise ScenarioError(f"{where}: {key!r}: unknown key {part!r} at {path} ({_known(node)})")
        return node[part]
    if isinstance(node, (list, tuple)):
        return node[_index(node, part, key=key, path=path, where=where)]
    if node is None or isinstance(node, (str, bytes, int, float, complex)):
        raise ScenarioError(f"{where}: {key!r}: {path} is a value, not a table")
    if part.startswith("_") or not hasattr(node, part):
        raise ScenarioError(f"{where}: {key!r}: unknown key {part!r} at {path} ({_known(node)})")
    return getattr(node, part)


def _check_kind(old: Any, value: Any, *, key: str, path: str, where: str) -> None:
    """Refuse a table where the scenario holds a value or a list, and a value or a list where
    it holds a table (``None`` on either side: an unset field, or a key only checked)."""
    if old is None or value is None:
        return
    if isinstance(old, Mapping) and not isinstance(value, (Mapping, BaseModel)):
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        raise ScenarioError(f"{where}: {key!r}: {path} is a table ({_known(old)}): give a table, "
                            f"or set one of its keys (got {shown})")
    if not isinstance(old, Mapping) and isinstance(value, (Mapping, BaseModel)):
        what = "a list" if isinstance(old, (list, tuple)) else "a value"
        raise ScenarioError(f"{where}: {key!r}: {path} is {what}, not a table (got a table)")


def set_dotted(raw: dict, resolved: Mapping, key: str, value: Any, *, where: str) -> None:
    """Set dotted ``key`` to ``value`` in ``raw`` (a scenario's data), in place.

    Parameters
    ----------
    raw : dict
        The scenario's data as it will be validated: as written (a TOML file's table) or a
        dump. A table missing from it is created (its other keys keep their defaults); a list
        is copied from ``resolved`` before one of its elements is changed.
    resolved : mapping
        The validated scenario's dump (``model_dump``): which keys exist and what kind of thing
        (table, list, value) each holds.
    key : str
        Table keys, list indices (``detector.chips.0.read_noise_e``) and ``*`` (every element
        of a list: ``detector.chips.*.read_noise_e``).
    value : any
        The new value; ``None`` only checks the key (and sets ``None``).
    where : str
        Where the key came from (a file, a sweep, a plan), first in an error message.

    Raises
    ------
    ScenarioError
        An empty component, an unknown key (listing the known keys at that level), an index out
        of range, a path through a value, a table where a value or a list is, a value or a list
        where a table is; ``raw`` is then unchanged.
    """
    parts = _parts(key, where)
    _set(None, resolved, parts, 0, value, key=key, where=where)  # refused: nothing set
    _set(raw, resolved, parts, 0, value, key=key, where=where)


def _set(raw: Any, res: Any, parts: list[str], i: int, value: Any, *, key: str, where: str) -> None:
    """Set ``parts[i:]`` under ``raw``, checked against ``res`` (the same level of the dump);
    ``raw`` None: only check (every error is found before anything is set)."""
    part = parts[i]
    last = i == len(parts) - 1
    path = ".".join(parts[:i]) or "top level"
    here = ".".join(parts[:i + 1])
    if isinstance(res, Mapping):
        if part not in res:
            raise ScenarioError(f"{where}: {key!r}: unknown key {part!r} at {path} ({_known(res)})")
        child = res[part]
        if last:
            _check_kind(child, value, key=key, path=here, where=where)
            if raw is not None:
                raw[part] = value
            return
        if not isinstance(child, (Mapping, list, tuple)):
            raise ScenarioError(f"{where}: {key!r}: {here} is a value, not a table")
        if raw is not None:
            if isinstance(child, Mapping) and not isinstance(raw.get(part), dict):
                raw[part] = {}
            elif isinstance(child, (list, tuple)) and (not isinstance(raw.get(part), list)
                                                      or len(raw[part]) != len(child)):
                raw[part] = _as_lists(copy.deepcopy(child))
        _set(None if raw is None else raw[part], child, parts, i + 1, value, key=key, where=where)
    elif isinstance(res, (list, tuple)):
        idx = range(len(res)) if part == "*" else [_index(res, part, key=key, path=path, where=where)]
        for j in idx:
            child = res[j]
            if last:
                _check_kind(child, value, key=key, path=f"{path}.{j}", where=where)
                if raw is not None:
                    raw[j] = value
                continue
            if not isinstance(child, (Mapping, list, tuple)):
                raise ScenarioError(f"{where}: {key!r}: {path}.{j} is a value, not a table")
            if raw is not None and isinstance(child, Mapping) and not isinstance(raw[j], dict):
                raw[j] = {}
            _set(None if raw is None else raw[j], child, parts, i + 1, value, key=key, where=where)
    else:
        raise ScenarioError(f"{where}: {key!r}: {path} is a value, not a table")


def _as_lists(obj: Any) -> Any:
    """``obj`` with every tuple a list (a dump's lists as a TOML table holds them)."""
    if isinstance(obj, (list, tuple)):
        return [_as_lists(v) for v in obj]
    if isinstance(obj, Mapping):
        return {k: _as_lists(v) for k, v in obj.items()}
    return obj


def covers(key: str, path: str) -> bool:
    """Whether setting dotted ``key`` sets (part of) the field at dotted ``path``: the same
    field, a field inside it, or a table around it."""
    return key == path or key.startswith(path + ".") or path.startswith(key + ".")


def derived_paths(scenario: Any) -> tuple[str, ...]:
    """The dotted paths of the fields ``scenario`` derives from its others: those its
    :meth:`~simcam.config_base.ScenarioBase.derived_paths` declares; none for another model."""
    return tuple(scenario.derived_paths()) if isinstance(scenario, ScenarioBase) else ()


def drop_derived(raw: dict, derived: Iterable[str], keys: Iterable[str]) -> tuple[str, ...]:
    """Remove from ``raw``, in place, each derived field (dotted ``derived`` paths) that none of
    ``keys`` sets (:func:`covers`), so that validating ``raw`` derives it again.

    Returns
    -------
    tuple of str
        The paths removed (those present in ``raw``).
    """
    keys = tuple(keys)
    dropped = []
    for path in derived:
        if any(covers(k, path) for k in keys):
            continue
        *parents, leaf = path.split(".")
        node: Any = raw
        for part in parents:
            node = node.get(part) if isinstance(node, dict) else None
        if isinstance(node, dict) and leaf in node:
            del node[leaf]
            dropped.append(path)
    return tuple(dropped)


def set_values(raw: Mapping, resolved: Mapping, values: Mapping[str, Any], *, where: str,
               derived: Iterable[str] = ()) -> dict:
    """A copy of ``raw`` with the dotted ``values`` set (:func:`set_dotted`, in their order)
    and the ``derived`` fields they do not set dropped (:func:`drop_derived`).

    ``raw`` and ``resolved`` are as for :func:`set_dotted`; ``raw`` is not changed.
    """
    data = copy.deepcopy(dict(raw))
    drop_derived(data, derived, values)
    for key, value in values.items():
        set_dotted(data, resolved, key, value, where=where)
    return data


def scenario_with(scenario: S, values: Mapping[str, Any], *, from_dict: Callable[..., S], where: str) -> S:
    """``scenario`` with dotted ``values`` set, validated again: its data as its TOML holds it
    (``model_dump(mode="json", exclude_none=True)``), the fields it derives
    (:meth:`~simcam.config_base.ScenarioBase.derived_paths`) dropped unless set,
    :func:`set_values`, then ``from_dict(data, source=where)``.

    Parameters
    ----------
    scenario : pydantic model
        The validated scenario (a :class:`~simcam.config_base.ScenarioBase` says what it
        derives; another model derives nothing).
    values : mapping of str to any
        ``{dotted key: new value}``.
    from_dict : callable
        The scenario module's (or study's) ``from_dict(data, *, source)``.
    where : str
        Where the values came from: first in a key's error and the new scenario's source.
    """
    raw = scenario.model_dump(mode="json", exclude_none=True)
    resolved = scenario.model_dump(mode="json")
    data = set_values(raw, resolved, values, where=where, derived=derived_paths(scenario))
    return from_dict(data, source=where)
