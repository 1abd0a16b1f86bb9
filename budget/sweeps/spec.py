"""Sweep files loaded: a sweep file read, checked and expanded into its points before any
work, and its hash.

The rooms: :mod:`budget.sweeps.models` (the file's settings), :mod:`budget.sweeps.values`
(ranges, the grid, point seeds, Sobol samples) and :mod:`simcam.dotted` (dotted keys set
in a scenario, shared with the planner and robustness); this module puts them together.
Their names stay importable from here.

:func:`load_sweep` parses and checks the file, expands the grid, builds and validates the
scenario of every point (and of every Sobol sample) and checks what the simulator would
refuse (the study's :meth:`~budget.runner.capabilities.CheckedScenario.check`), so that a mistake is one
error naming the file, the key and the point, not a failure hours into a run. The sweep's
``kind`` names a registered study (:mod:`budget.runner.registry`); nothing here knows one
study from another.
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import operator
import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from budget.runner.capabilities import CheckedScenario, capability
from budget.runner.registry import get_study
from budget.sweeps.models import DistSpec, SensitivitySpec, SweepSpec, parse_sweep
from budget.sweeps.values import (
    _BYTES_PER_POINT,
    _check_count,
    _value_count,
    expand_values,
    grid_indexer,
    point_identity,
    point_seed,
    salib_problem,
    sensitivity_seed,
    sobol_samples,
)
from simcam.allocation import check_allocations
from simcam.config_base import read_toml  # strict: missing, non-UTF-8, empty, invalid
from simcam.dotted import derived_paths, set_dotted, set_values
from simcam.infra.errors import ScenarioError

__all__ = [
    "DistSpec",
    "Point",
    "SensitivitySpec",
    "Sweep",
    "SweepSpec",
    "check_simulable",
    "expand_values",
    "load_sweep",
    "parse_sweep",
    "point_identity",
    "point_seed",
    "salib_problem",
    "scenario_hash",
    "scenario_text",
    "sensitivity_seed",
    "set_dotted",
    "sobol_samples",
    "sweep_hash",
    "validate_scenario",
]


# --------------------------------------------------------------------------- the study of a kind
def _study(kind: str):
    return get_study(kind)


def _default_raw(kind: str) -> tuple[dict, str]:
    return tomllib.loads(_study(kind).default_text()), f"<embedded {kind} default>"


def validate_scenario(kind: str, data: dict, *, source: str):
    """Validate raw scenario data of ``kind`` into its model (ScenarioError naming fields)."""
    return _study(kind).from_dict(data, source=source)


def scenario_hash(kind: str, scenario) -> str:
    """Hash of a resolved scenario (the study's rule)."""
    return _study(kind).scenario_hash(scenario)


def scenario_text(kind: str, scenario) -> str:
    """Resolved scenario as TOML (the study's ``load_scenario`` accepts it back)."""
    return _study(kind).scenario_text(scenario)


def check_simulable(kind: str, scenario, *, where: str) -> None:
    """What the simulator would refuse later, checked now (cheaply): :meth:`~budget.runner.capabilities.CheckedScenario.check`."""
    check_allocations(scenario, source=where)  # its largest arrays fit (simcam.allocation)
    try:
        capability(_study(kind), CheckedScenario).check(scenario, where=where)
    except ScenarioError:
        raise
    except ValueError as exc:  # the simulator's own input errors (DesignError, OpticsError, ...)
        raise ScenarioError(f"{where}: {exc}") from None


# --------------------------------------------------------------------------- resolved sweep
@dataclass(frozen=True)
class Point:
    """One point of a grid (or one Sobol sample): its index, values, scenario and seed."""

    index: int
    values: dict
    scenario: Any
    seed: int


#: a sweep of at most this many points (and samples) has every point built and checked when
#: it is read; a larger one builds and checks each point when it is reached (lazily), so that
#: its first points are written within seconds and its memory does not grow with its points
EAGER_POINTS = 64


class LazyPoints(Sequence):
    """The points of a sweep (or its Sobol samples), built when they are asked for.

    ``points[i]`` builds point ``i`` (its values from the index, its scenario validated and
    checked, its seed): nothing is held per point, so a 1,000,000-point axis costs no more
    memory than a 10-point one. With ``keep`` (small sweeps) each point is built once and kept.
    """

    def __init__(self, n: int, values_of: Callable[[int], dict], build: Callable[[dict, str], Any],
                 seed_of: Callable[[dict], int], label: str, *, keep: bool = False):
        self._n, self._values_of, self._build, self._seed_of, self._label = n, values_of, build, seed_of, label
        self._kept: dict[int, Point] | None = {} if keep else None

    def __len__(self) -> int:
        return self._n

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[j] for j in range(*i.indices(self._n))]
        i = operator.index(i)
        if i < 0:
            i += self._n
        if not 0 <= i < self._n:
            raise IndexError(f"point {i} of {self._n}")
        if self._kept is not None and i in self._kept:
            return self._kept[i]
        values = self._values_of(i)
        p = Point(i, values, self._build(values, f"{self._label} {i}"), self._seed_of(values))
        if self._kept is not None:
            self._kept[i] = p
        return p


@dataclass
class Sweep:
    """A checked sweep: the spec, its file, the base scenario, its points (built and checked
    when read for up to :data:`EAGER_POINTS`, else when reached: :class:`LazyPoints`)."""

    spec: SweepSpec
    path: str
    text: str
    base: Any
    base_raw: dict
    params: list[tuple[str, list]]
    points: Sequence[Point]
    samples: np.ndarray | None = None  # Sobol samples (n, D), parameter values
    sample_points: Sequence[Point] = field(default_factory=list)
    hash: str = ""

    @property
    def kind(self) -> str:
        return self.spec.kind

    @property
    def dims(self) -> tuple[str, ...]:
        """Point dimensions of the grid dataset: the parameters (product) or ``point`` (zip)."""
        if not self.params:
            return ()
        if self.spec.mode == "product" or len(self.params) == 1:
            return tuple(k for k, _ in self.params)
        return ("point",)

    @property
    def shape(self) -> tuple[int, ...]:
        if not self.params:
            return ()
        if self.dims == ("point",):
            return (len(self.params[0][1]),)
        return tuple(len(v) for _, v in self.params)

    def grid_index(self, index: int) -> tuple[int, ...]:
        """Index of point ``index`` along the point dimensions (C order)."""
        return tuple(int(i) for i in np.unravel_index(index, self.shape))

    @property
    def sensitivity_names(self) -> list[str]:
        return list(self.spec.sensitivity.parameters) if self.spec.sensitivity else []


def _where(source: str, label: str, values: dict) -> str:
    return f"{source}: {label} (" + ", ".join(f"{k} = {v!r}" for k, v in values.items()) + ")"


def load_sweep(path: str | Path, *, check: bool = True) -> Sweep:
    """Read, check and expand a sweep file; build and check every point's scenario.

    Raises
    ------
    ScenarioError
        Unreadable file, unknown or ill-typed setting, unknown dotted key, empty range,
        mismatched zip lengths, a point or Sobol sample the scenario rejects (naming the
        point, the key and what is wrong) or that the simulator could not run.
    """
    p = Path(path)
    if not p.is_file():
        raise ScenarioError(f"{p}: sweep file not found")
    source = str(p)
    read_toml(path=p, source=source)  # refuses, naming the file, what the text cannot be
    text = p.read_text(encoding="utf-8")
    spec = parse_sweep(text, source=source)
    kind = spec.kind
    if spec.base is None:
        raw, base_src = _default_raw(kind)
    else:
        bp = Path(spec.base)
        if not bp.is_absolute():
            bp = p.parent / bp
        if not bp.is_file():
            raise ScenarioError(f"{source}: base: {bp}: scenario file not found")
        raw = read_toml(path=bp, source=f"{source}: base: {bp}")
        base_src = str(bp)
    base0 = validate_scenario(kind, raw, source=base_src)
    resolved0 = base0.model_dump(mode="python")
    fixed = dict(spec.fixed)
    if fixed:
        raw = set_values(raw, resolved0, fixed, where=f"{source}: fixed", derived=derived_paths(base0))
    base = validate_scenario(kind, raw, source=f"{source}: fixed (applied to {base_src})") if fixed else base0
    resolved = base.model_dump(mode="python")

    counts = [_value_count(v) for v in spec.parameters.values()]
    n_grid = (math.prod(counts) if spec.mode != "zip" else max(counts, default=0.0)) if counts else 0.0
    _check_count(n_grid, what=f"{source}: parameters", per=_BYTES_PER_POINT, unit="point")
    params = [(k, expand_values(k, v, source=source)) for k, v in spec.parameters.items()]
    for k, _ in params:  # unknown keys once, before any point is built
        set_dotted(copy.deepcopy(raw), resolved, k, None, where=f"{source}: parameters")
    sens = spec.sensitivity
    if sens is not None:
        for k in sens.parameters:
            set_dotted(copy.deepcopy(raw), resolved, k, None, where=f"{source}: sensitivity.parameters")

    def build(values: dict, label: str) -> Any:
        data = set_values(raw, resolved, values, where=source, derived=derived_paths(base))
        where = _where(source, label, values)
        sc = validate_scenario(kind, data, source=where)
        if check:
            check_simulable(kind, sc, where=where)
        return sc

    n_points = (math.prod(len(v) for _, v in params) if spec.mode != "zip" else max((len(v) for _, v in params), default=0))
    if sens is not None:
        n_points += sens.samples * (len(sens.parameters) + 2)
    eager = n_points <= EAGER_POINTS
    n_grid_points, values_of = grid_indexer(spec, params, source)
    points = LazyPoints(n_grid_points, values_of, build, lambda v: point_seed(spec.seed, v), "point", keep=eager)

    samples = None
    sample_points: Sequence[Point] = []
    if sens is not None:
        samples = sobol_samples(spec)
        names = list(sens.parameters)
        s_seed = sensitivity_seed(spec.seed)

        def sample_values(i: int) -> dict:
            return {k: (int(v) if sens.parameters[k].integer else float(v)) for k, v in zip(names, samples[i])}

        sample_points = LazyPoints(len(samples), sample_values, build, lambda _v: s_seed, "sensitivity sample",
                                   keep=eager)
    if eager:  # a small sweep: every point built and checked before any work
        for pts in (points, sample_points):
            for _ in pts:
                pass

    sw = Sweep(spec=spec, path=source, text=text, base=base, base_raw=raw, params=params, points=points,
               samples=samples, sample_points=sample_points)
    sw.hash = sweep_hash(spec, kind, base)
    return sw


def sweep_hash(spec: SweepSpec, kind: str, base) -> str:
    """Hash of a sweep: its settings (the base's path excluded) and the resolved base scenario.

    Two files that differ only in comments, layout or the path by which they reach the
    same base scenario have the same hash; anything that changes a result changes it.
    Format 2: ``kind`` required, ``tolerance`` (was ``tolerance_3sigma_arcsec``), no
    ``dense_step_deg`` shorthand; a store written by format 1 is another sweep.
    """
    payload = {"format": 2, "spec": spec.model_dump(mode="json", exclude={"base"}),
               "base": base.model_dump(mode="json")}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
