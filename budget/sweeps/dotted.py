"""Dotted keys: a swept or fixed parameter set in the scenario as written.

``"detector.chips.0.read_noise_e"`` or ``"detector.chips.*.read_noise_e"``: table keys,
list indices and ``*`` (every element of a list), checked against the validated base
scenario so that an unknown key is one error listing the known keys at that level.
"""

from __future__ import annotations

import copy

from simcam.infra.errors import ScenarioError

__all__ = ["set_dotted"]


def _known(node) -> str:
    if isinstance(node, dict):
        return "known keys: " + ", ".join(sorted(node))
    if isinstance(node, (list, tuple)):
        return f"a list of {len(node)}: use an index 0..{len(node) - 1} or *"
    return "not a table"


def set_dotted(raw: dict, resolved: dict, key: str, value, *, where: str) -> None:
    """Set dotted ``key`` to ``value`` in ``raw`` (the scenario as written), in place.

    ``resolved`` (the validated base, ``model_dump``) says which keys exist: an unknown
    key is a :class:`ScenarioError` listing the known keys at that level. A missing table
    in ``raw`` is created (its other keys keep their defaults); a list is copied from
    ``resolved`` before one of its elements is changed. Components: table keys, list
    indices (``detector.chips.0.read_noise_e``) and ``*`` (every element of a list).
    """
    parts = key.split(".")
    if any(p == "" for p in parts):
        raise ScenarioError(f"{where}: {key!r}: empty component in dotted key")
    _set(raw, resolved, parts, 0, value, key=key, where=where)


def _set(raw, res, parts, i, value, *, key, where):
    part = parts[i]
    last = i == len(parts) - 1
    path = ".".join(parts[:i]) or "top level"
    if isinstance(res, dict):
        if part not in res:
            raise ScenarioError(f"{where}: {key!r}: unknown key {part!r} at {path} ({_known(res)})")
        if last:
            raw[part] = value
            return
        child = res[part]
        if isinstance(child, dict):
            if not isinstance(raw.get(part), dict):
                raw[part] = {}
        elif isinstance(child, (list, tuple)):
            if not isinstance(raw.get(part), list) or len(raw[part]) != len(child):
                raw[part] = _as_lists(copy.deepcopy(child))
        else:
            raise ScenarioError(f"{where}: {key!r}: {'.'.join(parts[:i + 1])} is a value, not a table")
        _set(raw[part], child, parts, i + 1, value, key=key, where=where)
    elif isinstance(res, (list, tuple)):
        if part == "*":
            idx = range(len(res))
        else:
            try:
                j = int(part)
            except ValueError:
                raise ScenarioError(f"{where}: {key!r}: {path} is a list: {part!r} is not an index "
                                    f"({_known(res)})") from None
            if not 0 <= j < len(res):
                raise ScenarioError(f"{where}: {key!r}: index {j} out of range at {path} ({_known(res)})")
            idx = [j]
        for j in idx:
            if last:
                raw[j] = value
                continue
            child = res[j]
            if not isinstance(child, (dict, list, tuple)):
                raise ScenarioError(f"{where}: {key!r}: {path}.{j} is a value, not a table")
            _set(raw[j], child, parts, i + 1, value, key=key, where=where)
    else:
        raise ScenarioError(f"{where}: {key!r}: {path} is a value, not a table")


def _as_lists(obj):
    if isinstance(obj, (list, tuple)):
        return [_as_lists(v) for v in obj]
    if isinstance(obj, dict):
        return {k: _as_lists(v) for k, v in obj.items()}
    return obj
