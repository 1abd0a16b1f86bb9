"""The sweep file's settings, as models: what to vary, how to combine it, how to evaluate
each point.

A sweep file (TOML) names a registered study (``kind``, required: a name of
:mod:`budget.runner.registry`, the same as its CLI group), a base scenario of it (the
study's default, or ``base``), the parameters to vary as dotted keys of that scenario with
value lists or ranges (:mod:`budget.sweeps.values`), the combination mode (``product`` or
``zip``), how each point is evaluated (the Monte Carlo ``validate``, or the ``truth``
fast mode), and a seed. An optional ``[sensitivity]`` table asks for Sobol indices over
parameter distributions (:class:`DistSpec`). ``tolerance`` (adaptive stopping: every Monte
Carlo standard error below it) is in the unit of the study's classes. The format is
documented in ``docs/sweeps.md``; an example::

    name = "TE against star magnitude and exposure"
    kind = "starcam"
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
"""

from __future__ import annotations

import math
import tomllib
from typing import Any, Literal

from pydantic import Field, model_validator

from budget.runner.registry import renamed, study_names
from budget.sweeps.layout import fixed_truth_classes
from simcam.config_base import StrictModel, validate_model
from simcam.infra.errors import ScenarioError

__all__ = ["RENAMED", "DistSpec", "SensitivitySpec", "SweepSpec", "parse_sweep"]

#: settings of earlier sweep files -> what to write instead (a one-line error says so)
RENAMED = {
    "tolerance_3sigma_arcsec": "tolerance (in the unit of the study's classes)",
    "dense_step_deg": '[fixed] "validation.dense_step_deg" = ... (a field of the scenario)',
}


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
    tolerance: float | None = Field(None, gt=0)
    output: Literal["truth", "published", "improved"] = "truth"
    conf_level: float = Field(0.95, gt=0, lt=1)
    resamples: int = Field(1000, ge=10)
    parameters: dict[str, DistSpec] = Field(min_length=1)

    @model_validator(mode="after")
    def _check(self) -> SensitivitySpec:
        n = self.samples
        if n & (n - 1):
            raise ValueError(f"samples: must be a power of 2 for Sobol sequences (got {n})")
        _check_eval(self.evaluate, self.trials, self.tolerance)
        if self.output != "truth" and self.evaluate != "validate":
            raise ValueError(f"output = {self.output!r} is a mean estimate: it needs evaluate = 'validate'")
        return self


class SweepSpec(StrictModel):
    """A sweep file, as parsed (see the module docstring and docs/sweeps.md)."""

    name: str = ""
    kind: str
    base: str | None = None
    seed: int = Field(ge=0)
    mode: Literal["product", "zip"] = "product"
    evaluate: Literal["validate", "truth"] = "validate"
    trials: int | None = Field(None, ge=2)
    tolerance: float | None = Field(None, gt=0)
    fixed: dict[str, Any] = Field(default_factory=dict)
    parameters: dict[str, Any] = Field(default_factory=dict)
    sensitivity: SensitivitySpec | None = None

    @model_validator(mode="after")
    def _check(self) -> SweepSpec:
        if not self.parameters and self.sensitivity is None:
            raise ValueError("nothing to do: give [parameters] (a grid) and/or [sensitivity]")
        _check_eval(self.evaluate, self.trials, self.tolerance)
        known = study_names(available_only=False)
        if self.kind not in known:
            raise ValueError(f"kind: {self.kind!r} is not a registered study (known: {', '.join(known)})")
        for ev, where in ((self.evaluate, ""),
                          *(((self.sensitivity.evaluate, "sensitivity."),) if self.sensitivity else ())):
            if ev == "truth" and not fixed_truth_classes(self.kind):
                raise ValueError(f"{where}evaluate = 'truth' is not available for {self.kind} sweeps: every truth "
                                 "of this study is drawn per trial and needs simulated trials")
        return self


def _check_eval(evaluate, trials, tolerance) -> None:
    if trials is not None and tolerance is not None:
        raise ValueError("trials and tolerance: give one of them")
    if evaluate == "truth" and (trials is not None or tolerance is not None):
        raise ValueError("trials / tolerance apply to evaluate = 'validate' only "
                         "(the truth mode runs no trials)")


def parse_sweep(text: str, *, source: str) -> SweepSpec:
    """Parse sweep TOML text into a :class:`SweepSpec` (ScenarioError naming the field)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from None
    # settings and kinds of earlier sweep files: one line saying what to write instead
    for where, table in (("", data), ("sensitivity.", data.get("sensitivity"))):
        if isinstance(table, dict):
            for old, new in RENAMED.items():
                if old in table and not (where and old == "dense_step_deg"):
                    raise ScenarioError(f"{source}: {where}{old}: no longer a sweep setting; write {new}")
    kind = data.get("kind")
    known = ", ".join(study_names(available_only=False))
    if kind is None:
        raise ScenarioError(f"{source}: kind: required, the registered study the sweep runs ({known})")
    if isinstance(kind, str) and renamed(kind) is not None:
        raise ScenarioError(f"{source}: kind = {kind!r} is a former name: write kind = {renamed(kind)!r}")
    if isinstance(kind, str) and kind not in known.split(", "):
        raise ScenarioError(f"{source}: kind: {kind!r} is not a registered study ({known})")
    spec = validate_model(SweepSpec, data, source=source)
    _check_fixed_not_varied(spec, source=source)
    return spec


def _check_fixed_not_varied(spec: SweepSpec, *, source: str) -> None:
    """Refuse a field both in ``[fixed]`` and varied (``[parameters]``, ``[sensitivity.parameters]``),
    itself or through a table holding it: the varied values would silently replace the fixed one."""
    varied = [("parameters", k) for k in spec.parameters]
    if spec.sensitivity is not None:
        varied += [("sensitivity.parameters", k) for k in spec.sensitivity.parameters]
    for fixed in spec.fixed:
        for table, key in varied:
            if key == fixed or key.startswith(fixed + ".") or fixed.startswith(key + "."):
                raise ScenarioError(f"{source}: {table}: {key!r} is also in [fixed] ({fixed!r} = "
                                    f"{spec.fixed[fixed]!r}); a field is either fixed or varied: remove one")
