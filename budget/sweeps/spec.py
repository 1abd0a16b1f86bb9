"""Sweep files: what to vary, how to combine it, how to evaluate each point.

A sweep file (TOML) names a base scenario of a registered study (``kind``: ``camera`` or
``starcam`` for the seed-000 star camera and lab, ``inductosyn`` for the seed-001 encoder
and its polygon calibration, and any other study of :mod:`budget.runner.registry`),
the parameters to vary as dotted keys of that scenario with value lists or ranges, the
combination mode (``product`` or ``zip``), how each point is evaluated (the Monte Carlo
``validate``, or the ``truth`` fast mode), and a seed. An optional ``[sensitivity]``
table asks for Sobol indices over parameter distributions. The format is documented in
``docs/sweeps.md``; an example::

    name = "TE against star magnitude and exposure"
    kind = "camera"
    base = "../scenarios/te_only.toml"   # relative to this file; omit for the default
    seed = 1
    mode = "product"
    evaluate = "validate"
    trials = 20

    [fixed]                      # applied to the base before sweeping
    "validation.te_truth_frames" = 500

    [parameters]
    "lab.source.match_v_mag" = [6.0, 7.0, 8.0, 9.0]
    "camera.exposure_s" = { start = 0.05, stop = 0.2, num = 4 }

Everything here runs before any work: :func:`load_sweep` parses and checks the file,
expands the grid, builds and validates the scenario of every point (and of every Sobol
sample) and checks what the simulator would refuse (a star off the detector; a polygon
that cannot separate the harmonics), so that a mistake is one error naming the file,
the key and the point, not a failure hours into a run.

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

import copy
import hashlib
import itertools
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, model_validator

from simcam.config_base import ScenarioError, StrictModel

__all__ = [
    "DistSpec",
    "Point",
    "SensitivitySpec",
    "Sweep",
    "SweepSpec",
    "expand_values",
    "load_sweep",
    "parse_sweep",
    "point_seed",
    "sensitivity_seed",
    "set_dotted",
]

#: rounding of generated range values (significant digits): 0.1 + 0.2 is 0.3
RANGE_DIGITS = 12
#: spawn key of the common seed of the Sobol samples (points use two-word keys)
SENSITIVITY_SPAWN_KEY = (1,)


# --------------------------------------------------------------------------- models
class DistSpec(StrictModel):
    """Distribution of one parameter for the Sobol analysis.

    ``uniform`` (low, high), ``loguniform`` (low, high > 0), ``normal`` (mean, sd),
    ``truncnormal`` (low, high, mean, sd), ``lognormal`` (mean, sd of ln value),
    ``triangular`` (low, high, peak). ``integer = true`` rounds each sample to an integer
    (for counts such as frames).
    """

    dist: Literal["uniform", "loguniform", "normal", "truncnormal", "lognormal", "triangular"]
    low: float | None = None
    high: float | None = None
    mean: float | None = None
    sd: float | None = None
    peak: float | None = None
    integer: bool = False

    @model_validator(mode="after")
    def _fields(self) -> DistSpec:
        need = {"uniform": ("low", "high"), "loguniform": ("low", "high"), "normal": ("mean", "sd"),
                "truncnormal": ("low", "high", "mean", "sd"), "lognormal": ("mean", "sd"),
                "triangular": ("low", "high", "peak")}[self.dist]
        given = {k for k in ("low", "high", "mean", "sd", "peak") if getattr(self, k) is not None}
        missing = [k for k in need if k not in given]
        extra = sorted(given - set(need))
        if missing:
            raise ValueError(f"{self.dist} needs {', '.join(need)} (missing {', '.join(missing)})")
        if extra:
            raise ValueError(f"{self.dist} takes {', '.join(need)}, not {', '.join(extra)}")
        for k in given:
            if not math.isfinite(getattr(self, k)):
                raise ValueError(f"{k} must be finite")
        if "low" in need and not self.low < self.high:
            raise ValueError(f"low ({self.low}) must be below high ({self.high})")
        if self.dist == "loguniform" and self.low <= 0:
            raise ValueError(f"loguniform needs low > 0 (got {self.low})")
        if self.sd is not None and self.sd <= 0:
            raise ValueError(f"sd must be > 0 (got {self.sd})")
        if self.dist == "triangular" and not self.low <= self.peak < self.high:
            raise ValueError(f"triangular needs low <= peak < high (got {self.low}, {self.peak}, {self.high})")
        if self.dist == "truncnormal" and not self.low <= self.mean <= self.high:
            raise ValueError(f"truncnormal needs low <= mean <= high (got {self.low}, {self.mean}, {self.high})")
        return self

    def salib(self) -> tuple[str, list[float]]:
        """(SALib ``dists`` name, ``bounds`` entry)."""
        d = self.dist
        if d == "uniform":
            return "unif", [self.low, self.high]
        if d == "loguniform":
            return "logunif", [self.low, self.high]
        if d == "normal":
            return "norm", [self.mean, self.sd]
        if d == "truncnormal":
            return "truncnorm", [self.low, self.high, self.mean, self.sd]
        if d == "lognormal":
            return "lognorm", [self.mean, self.sd]
        return "triang", [self.low, self.high, (self.peak - self.low) / (self.high - self.low)]


class SensitivitySpec(StrictModel):
    """``[sensitivity]``: Sobol indices (Saltelli sampling, SALib) around the base scenario.

    ``samples`` is SALib's N (a power of 2); the model runs ``N (D + 2)`` times for D
    parameters. ``output``: ``truth`` (the budget itself) or the mean estimate of the
    ``published`` / ``improved`` variant (``evaluate = "validate"`` only).
    """

    samples: int = Field(ge=2)
    evaluate: Literal["truth", "validate"] = "truth"
    trials: int | None = Field(None, ge=2)
    tolerance_3sigma_arcsec: float | None = Field(None, gt=0)
    output: Literal["truth", "published", "improved"] = "truth"
    conf_level: float = Field(0.95, gt=0, lt=1)
    resamples: int = Field(1000, ge=10)
    parameters: dict[str, DistSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _check(self) -> SensitivitySpec:
        n = self.samples
        if n & (n - 1):
            raise ValueError(f"samples: must be a power of 2 for Sobol sequences (got {n})")
        _check_eval(self.evaluate, self.trials, self.tolerance_3sigma_arcsec)
        if self.output != "truth" and self.evaluate != "validate":
            raise ValueError(f"output = {self.output!r} is a mean estimate: it needs evaluate = 'validate'")
        return self


class SweepSpec(StrictModel):
    """A sweep file, as parsed (see module docstring and docs/sweeps.md)."""

    name: str = ""
    kind: str = "camera"
    base: str | None = None
    seed: int = Field(ge=0)
    mode: Literal["product", "zip"] = "product"
    evaluate: Literal["validate", "truth"] = "validate"
    trials: int | None = Field(None, ge=2)
    tolerance_3sigma_arcsec: float | None = Field(None, gt=0)
    dense_step_deg: float | None = Field(None, gt=0, le=1)
    fixed: dict[str, Any] = Field(default_factory=dict)
    parameters: dict[str, Any] = Field(default_factory=dict)
    sensitivity: SensitivitySpec | None = None

    @model_validator(mode="after")
    def _check(self) -> SweepSpec:
        if not self.parameters and self.sensitivity is None:
            raise ValueError("nothing to do: give [parameters] (a grid) and/or [sensitivity]")
        _check_eval(self.evaluate, self.trials, self.tolerance_3sigma_arcsec)
        from budget.runner.registry import STUDIES
        from budget.sweeps.evaluate import KIND_ALIASES, truth_has_variant

        if KIND_ALIASES.get(self.kind, self.kind) not in STUDIES:
            raise ValueError(f"kind: unknown study {self.kind!r} (known: camera, {', '.join(STUDIES)})")
        for ev, where in ((self.evaluate, ""),
                          *(((self.sensitivity.evaluate, "sensitivity."),) if self.sensitivity else ())):
            if ev == "truth" and truth_has_variant(self.kind):
                raise ValueError(f"{where}evaluate = 'truth' is not available for {self.kind} sweeps: a truth "
                                 "of this study is drawn per trial and needs simulated trials")
        return self


def _check_eval(evaluate, trials, tolerance) -> None:
    if trials is not None and tolerance is not None:
        raise ValueError("trials and tolerance_3sigma_arcsec: give one of them")
    if evaluate == "truth" and (trials is not None or tolerance is not None):
        raise ValueError("trials / tolerance_3sigma_arcsec apply to evaluate = 'validate' only "
                         "(the truth mode runs no trials)")


# --------------------------------------------------------------------------- values
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
    from simcam.lifecycle import check_memory

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


# --------------------------------------------------------------------------- dotted keys
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


# --------------------------------------------------------------------------- kinds
def _study(kind: str):
    from budget.sweeps.evaluate import study_for_kind

    return study_for_kind(kind)


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
    """What the simulator would refuse later, checked now (cheaply): :meth:`Study.check`."""
    try:
        _study(kind).check(scenario, where=where)
    except ScenarioError:
        raise
    except ValueError as exc:  # the simulator's own input errors (DesignError, OpticsError, ...)
        raise ScenarioError(f"{where}: {exc}") from None


def check_camera_geometry(scenario, *, where: str) -> None:
    """Seed 000: every star of every protocol condition (and of the HSFE truth's sub-pixel
    phases) lands on a chip at least half a window from its edges and the gap, the test
    :meth:`simcam.starcam.render.StarCamera.scene` applies when it renders."""
    from budget.starcam.protocols import PROTOCOLS, make_plan
    from simcam.starcam import optics
    from simcam.starcam.render import StarCamera
    from simcam.starcam.targets import calibration_grid, star_grid

    cam = StarCamera(scenario, parallel=False)
    scn = scenario
    half = scn.render.window_px // 2
    lc = scn.optics.lateral_colour
    # every star of every condition, grouped by filter (one vectorised test per filter)
    groups: dict = {}
    for proto in PROTOCOLS:
        for c in make_plan(proto, scn).conditions:
            lay = calibration_grid(scn) if c.target == "calibration_grid" else star_grid(scn, center_px=c.field_center_px)
            shifts = [(c.platform_dx_px, c.platform_dy_px)]
            if proto == "hsfe" and c.index == 0:  # the HSFE truth visits phases in [0, 1) px
                shifts.append((c.platform_dx_px + 1.0, c.platform_dy_px + 1.0))
            for dx, dy in shifts:
                g = groups.setdefault(c.filter_nm, ([], [], []))
                g[0].append(lay.u_px + dx)
                g[1].append(lay.v_px + dy)
                g[2].extend((proto, c.label, j) for j in range(lay.n_stars))
    for filter_nm, (us, vs, who) in groups.items():
        wl, rate = cam.spectra.electron_rate_per_nm(filter_nm=filter_nm)
        w = cam.spectra.weights(rate)
        ud, vd = cam.distortion.forward(u_px=np.concatenate(us), v_px=np.concatenate(vs))
        su, sv = optics.lateral_colour_shift_px(
            wavelength_nm=wl, u_px=ud, v_px=vd, ref_wavelength_nm=lc.ref_wavelength_nm,
            radial_coeffs=tuple(lc.radial_px_per_nm), uniform_x_coeffs=tuple(lc.uniform_x_px_per_nm),
            uniform_y_coeffs=tuple(lc.uniform_y_px_per_nm), r_norm_px=scn.optics.r_norm_px)
        chip, _, _ = cam.mosaic.focal_to_chip(ud + su @ w, vd + sv @ w, margin_px=half)
        bad = np.flatnonzero(chip < 0)
        if bad.size:
            k = int(bad[0])
            proto, label, j = who[k]
            raise ScenarioError(
                f"{where}: protocol {proto}, condition {label!r}: star {j} at focal (u, v) = "
                f"({ud[k]:.1f}, {vd[k]:.1f}) px is off the detector or within {half} px of a chip "
                f"edge or gap ({bad.size} star positions of the plans fail)")


# --------------------------------------------------------------------------- resolved sweep
@dataclass(frozen=True)
class Point:
    """One point of a grid (or one Sobol sample): its index, values, scenario and seed."""

    index: int
    values: dict
    scenario: Any
    seed: int


@dataclass
class Sweep:
    """A checked sweep: the spec, its file, the base scenario, every point built."""

    spec: SweepSpec
    path: str
    text: str
    base: Any
    base_raw: dict
    params: list[tuple[str, list]]
    points: list[Point]
    samples: np.ndarray | None = None  # Sobol samples (n, D), parameter values
    sample_points: list[Point] = field(default_factory=list)
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


def parse_sweep(text: str, *, source: str) -> SweepSpec:
    """Parse sweep TOML text into a :class:`SweepSpec` (ScenarioError naming the field)."""
    from simcam.config_base import validate_model

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from None
    return validate_model(SweepSpec, data, source=source)


def _grid(spec: SweepSpec, params: list[tuple[str, list]], source: str) -> list[dict]:
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
    from simcam.config_base import read_toml  # strict: missing, non-UTF-8, empty, invalid

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
    if spec.dense_step_deg is not None:  # shorthand kept from the inductosyn sweeps
        set_dotted(copy.deepcopy(raw), resolved0, "validation.dense_step_deg", None,
                   where=f"{source}: dense_step_deg")
        fixed.setdefault("validation.dense_step_deg", spec.dense_step_deg)
    for key, value in fixed.items():
        set_dotted(raw, resolved0, key, value, where=f"{source}: fixed")
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
        data = copy.deepcopy(raw)
        for k, v in values.items():
            set_dotted(data, resolved, k, v, where=source)
        where = _where(source, label, values)
        sc = validate_scenario(kind, data, source=where)
        if check:
            check_simulable(kind, sc, where=where)
        return sc

    n_points = (math.prod(len(v) for _, v in params) if spec.mode != "zip" else max((len(v) for _, v in params), default=0))
    if sens is not None:
        n_points += sens.samples * (len(sens.parameters) + 2)
    _check_count(n_points, what=f"{source}: parameters", per=_BYTES_PER_POINT, unit="point")
    points = []
    for i, values in enumerate(_grid(spec, params, source)):
        points.append(Point(i, values, build(values, f"point {i}"), point_seed(spec.seed, values)))

    samples = None
    sample_points: list[Point] = []
    if sens is not None:
        samples = sobol_samples(spec)
        names = list(sens.parameters)
        s_seed = sensitivity_seed(spec.seed)
        for i, row in enumerate(samples):
            values = {k: (int(v) if sens.parameters[k].integer else float(v)) for k, v in zip(names, row)}
            sample_points.append(Point(i, values, build(values, f"sensitivity sample {i}"), s_seed))

    sw = Sweep(spec=spec, path=source, text=text, base=base, base_raw=raw, params=params, points=points,
               samples=samples, sample_points=sample_points)
    sw.hash = sweep_hash(spec, kind, base)
    return sw


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


def sweep_hash(spec: SweepSpec, kind: str, base) -> str:
    """Hash of a sweep: its settings (the base's path excluded) and the resolved base scenario.

    Two files that differ only in comments, layout or the path by which they reach the
    same base scenario have the same hash; anything that changes a result changes it.
    """
    payload = {"format": 1, "spec": spec.model_dump(mode="json", exclude={"base"}),
               "base": base.model_dump(mode="json")}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
