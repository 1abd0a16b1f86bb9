"""Swept values and seeds: ranges expanded, the grid of points, each point's seed, the
Sobol samples of parameter distributions.

Seeds: point ``p`` of a sweep with seed ``S`` runs with
``SeedSequence(S, spawn_key=(w0, w1))``, where ``(w0, w1)`` are the first two 32-bit
little-endian words of the SHA-256 of the point's canonical identity (its dotted keys,
sorted, with their values; numbers as ``repr(float(v))``). A point's result therefore
depends only on the sweep seed and the point's values: not on the grid it sits in, its
index, the order points run in or the worker. The Sobol samples share one seed,
``SeedSequence(S, spawn_key=(1,))`` (common random numbers), so that the Monte Carlo
noise of an output is not mistaken for sensitivity to a parameter.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from simcam.infra.errors import ScenarioError
from simcam.infra.lifecycle import check_memory

if TYPE_CHECKING:
    from budget.sweeps.models import SensitivitySpec, SweepSpec

__all__ = [
    "RANGE_DIGITS",
    "SENSITIVITY_SPAWN_KEY",
    "expand_values",
    "grid_points",
    "point_identity",
    "point_seed",
    "salib_problem",
    "sensitivity_seed",
    "sobol_samples",
]

#: rounding of generated range values (significant digits): 0.1 + 0.2 is 0.3
RANGE_DIGITS = 12
#: spawn key of the common seed of the Sobol samples (points use two-word keys)
SENSITIVITY_SPAWN_KEY = (1,)


def _is_scalar(v) -> bool:
    return isinstance(v, (bool, int, float, str)) and not (isinstance(v, float) and not math.isfinite(v))


def _round(v: float) -> float:
    return float(f"{v:.{RANGE_DIGITS}g}")


#: memory while a range is expanded (peak, measured: about 160 bytes per value) and
#: a lower bound of what one built point (its scenario) holds (measured: about 9.5 kB)
_BYTES_PER_VALUE = 160
_BYTES_PER_POINT = 8_000


def _value_count(spec: Any) -> float:
    """How many values a parameter's list or range gives, without expanding it (0 if unclear)."""
    if isinstance(spec, list):
        return float(len(spec))
    if isinstance(spec, dict):
        try:
            if "num" in spec:
                return float(spec["num"])
            if "step" in spec:
                return max(0.0, (float(spec["stop"]) - float(spec["start"])) / float(spec["step"])) + 1.0
        except (TypeError, ValueError, ZeroDivisionError, OverflowError, KeyError):
            return 0.0
    return 0.0


def _check_count(n: float, *, what: str, per: int = _BYTES_PER_VALUE, unit: str = "value") -> None:
    """Refuse, before it is built, a list of ``n`` items that cannot fit in memory."""
    check_memory(float(n) * per, what=f"{what}: {float(n):.4g} {unit}s (at least {per} bytes each)")


def expand_values(key: str, spec: Any, *, source: str) -> list:
    """The values of one swept parameter: a list as given, or a range table expanded.

    Range tables: ``{start, stop, num}`` (``num`` values, both ends included;
    ``scale = "log"`` for geometric spacing) or ``{start, stop, step}`` (from ``start`` by
    ``step`` while not past ``stop``, ``stop`` included when reached). Integer ends (and
    step) give integers when every value is one. Generated floats are rounded to 12
    significant digits.
    """
    where = f"{source}: parameters.{key}"
    if isinstance(spec, list):
        vals = spec
        if not vals:
            raise ScenarioError(f"{where}: empty list of values")
    elif isinstance(spec, dict):
        allowed = {"start", "stop", "num", "step", "scale"}
        unknown = sorted(set(spec) - allowed)
        if unknown:
            raise ScenarioError(f"{where}: unknown range key(s) {', '.join(unknown)} "
                                "(a range is start, stop and num or step, optional scale)")
        if "start" not in spec or "stop" not in spec:
            raise ScenarioError(f"{where}: a range needs start and stop")
        start, stop = spec["start"], spec["stop"]
        for nm, v in (("start", start), ("stop", stop)):
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ScenarioError(f"{where}: {nm} must be a finite number (got {v!r})")
        if ("num" in spec) == ("step" in spec):
            raise ScenarioError(f"{where}: a range needs exactly one of num and step")
        scale = spec.get("scale", "linear")
        if scale not in ("linear", "log"):
            raise ScenarioError(f"{where}: scale must be 'linear' or 'log' (got {scale!r})")
        if "num" in spec:
            num = spec["num"]
            if isinstance(num, bool) or not isinstance(num, int):
                raise ScenarioError(f"{where}: num must be an integer (got {num!r})")
            if num < 1:
                raise ScenarioError(f"{where}: empty range (num = {num})")
            _check_count(num, what=f"{where}: num = {num}")
            if scale == "log":
                if start <= 0 or stop <= 0:
                    raise ScenarioError(f"{where}: a log range needs start and stop > 0")
                raw = np.geomspace(start, stop, num)
            else:
                raw = np.linspace(start, stop, num)
            vals = [_round(float(v)) for v in raw]
            if isinstance(start, int) and isinstance(stop, int) and all(v == int(v) for v in vals):
                vals = [int(v) for v in vals]  # integer ends, integer values: counts stay counts
        else:
            step = spec["step"]
            if scale != "linear":
                raise ScenarioError(f"{where}: scale = 'log' needs num, not step")
            if isinstance(step, bool) or not isinstance(step, (int, float)) or not math.isfinite(step) or step == 0:
                raise ScenarioError(f"{where}: step must be a non-zero number (got {step!r})")
            _check_count(max(0.0, (stop - start) / step) + 1, what=f"{where}: start {start}, stop {stop}, step {step}")
            if all(isinstance(v, int) for v in (start, stop, step)):
                vals = list(range(start, stop + (1 if step > 0 else -1), step))
            else:
                n = math.floor((stop - start) / step * (1 + 1e-12) + 1e-9) + 1
                vals = [_round(start + step * i) for i in range(max(n, 0))]
            if not vals:
                raise ScenarioError(f"{where}: empty range (start {start}, stop {stop}, step {step})")
    else:
        raise ScenarioError(f"{where}: expected a list of values or a range table "
                            f"{{start, stop, num|step}}, got {spec!r}")
    bad = [v for v in vals if not _is_scalar(v)]
    if bad:
        raise ScenarioError(f"{where}: swept values must be numbers, booleans or strings (got {bad[0]!r}); "
                            "sweep one element of a list with an index, e.g. 'lab.target_center_px.0'")
    kinds = {("str" if isinstance(v, str) else "bool" if isinstance(v, bool) else "number") for v in vals}
    if len(kinds) > 1:
        raise ScenarioError(f"{where}: values mix {' and '.join(sorted(kinds))}")
    canon = [_canonical(v) for v in vals]
    if len(set(canon)) != len(canon):
        dup = next(v for v, c in zip(vals, canon) if canon.count(c) > 1)
        raise ScenarioError(f"{where}: value {dup!r} appears twice")
    return list(vals)


def _canonical(v):
    if isinstance(v, (bool, str)):
        return v
    return repr(float(v))


def point_identity(values: dict[str, Any]) -> str:
    """Canonical JSON of a point: sorted dotted keys with canonical values."""
    return json.dumps(sorted((k, _canonical(v)) for k, v in values.items()), separators=(",", ":"))


def point_seed(seed: int, values: dict[str, Any]) -> int:
    """Seed of a point (63-bit): ``SeedSequence(seed, spawn_key=(w0, w1))`` of its identity."""
    digest = hashlib.sha256(point_identity(values).encode()).digest()
    key = (int.from_bytes(digest[0:4], "little"), int.from_bytes(digest[4:8], "little"))
    s = np.random.SeedSequence(seed, spawn_key=key).generate_state(1, dtype=np.uint64)
    return int(s[0]) >> 1


def sensitivity_seed(seed: int) -> int:
    """Common seed of the Sobol samples (and of SALib's sampler and bootstrap)."""
    s = np.random.SeedSequence(seed, spawn_key=SENSITIVITY_SPAWN_KEY).generate_state(1, dtype=np.uint64)
    return int(s[0]) >> 1


def grid_indexer(spec: SweepSpec, params: list[tuple[str, list]], source: str) -> tuple[int, Callable[[int], dict]]:
    """The number of grid points and a function giving point ``i``'s values (C order over
    the parameters for ``product``, the ``i``-th of each list for ``zip``), without building
    the list: :func:`grid_points` is ``[values_of(i) for i in range(n)]``."""
    if not params:
        return 0, lambda _i: {}
    keys = [k for k, _ in params]
    lists = [v for _, v in params]
    if spec.mode == "zip":
        lens = {k: len(v) for k, v in params}
        if len(set(lens.values())) > 1:
            raise ScenarioError(f"{source}: mode = 'zip' needs value lists of one length; got "
                                + ", ".join(f"{k}: {n}" for k, n in lens.items()))
        return len(lists[0]), lambda i: {k: v[i] for k, v in zip(keys, lists)}
    shape = [len(v) for v in lists]

    def values_of(i: int) -> dict:
        out = {}
        for k, v, n in zip(reversed(keys), reversed(lists), reversed(shape)):  # C order: the last fastest
            i, j = divmod(i, n)
            out[k] = v[j]
        return {k: out[k] for k in keys}

    return math.prod(shape), values_of


def grid_points(spec: SweepSpec, params: list[tuple[str, list]], source: str) -> list[dict]:
    if not params:
        return []
    if spec.mode == "zip":
        lens = {k: len(v) for k, v in params}
        if len(set(lens.values())) > 1:
            raise ScenarioError(f"{source}: mode = 'zip' needs value lists of one length; got "
                                + ", ".join(f"{k}: {n}" for k, n in lens.items()))
        return [dict(zip([k for k, _ in params], vals)) for vals in zip(*[v for _, v in params])]
    keys = [k for k, _ in params]
    return [dict(zip(keys, vals)) for vals in itertools.product(*[v for _, v in params])]


def sobol_samples(spec: SweepSpec) -> np.ndarray:
    """Saltelli/Sobol sample matrix (N (D + 2), D) of the sensitivity parameters (SALib)."""
    from SALib.sample import sobol as sobol_sample

    sens = spec.sensitivity
    x = sobol_sample.sample(salib_problem(sens), sens.samples, calc_second_order=False,
                            scramble=True, seed=sensitivity_seed(spec.seed) % (2**32))
    for j, d in enumerate(sens.parameters.values()):
        if d.integer:
            x[:, j] = np.rint(x[:, j])
    return x


def salib_problem(sens: SensitivitySpec) -> dict:
    """SALib problem dictionary of the sensitivity parameters."""
    names = list(sens.parameters)
    dists, bounds = zip(*(d.salib() for d in sens.parameters.values()))
    return {"num_vars": len(names), "names": names, "bounds": [list(b) for b in bounds], "dists": list(dists)}
