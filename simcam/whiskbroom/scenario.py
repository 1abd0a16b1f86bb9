"""Scenario of the whiskbroom TDICCD camera (seed 002): a strict, frozen model.

The embedded default (``data/default.toml``) carries the paper's values with comments;
the focal length, the attitude-rate bounds and the rate-knowledge errors were lost with
the paper's Table 1 and are chosen there (docs/whiskbroom.md shows how the results move).
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from simcam.config_base import (BatchTrials, ScenarioBase, ScenarioError, StrictModel, Trials, ValidationSettings,
                                read_toml, validate_model)

__all__ = ["Distribution", "WhiskbroomScenario", "STATE_VARIABLES", "ERROR_VARIABLES",
           "VARIABLES", "default_text", "from_dict", "load", "default"]

#: the six true-state (operating) values drawn per trial
STATE_VARIABLES = ("roll_deg", "pitch_deg", "yaw_deg", "roll_rate_deg_s", "pitch_rate_deg_s",
                   "yaw_rate_deg_s")
#: the eleven knowledge / control errors
ERROR_VARIABLES = ("roll_knowledge_deg", "pitch_knowledge_deg", "yaw_knowledge_deg",
                   "roll_rate_knowledge_deg_s", "pitch_rate_knowledge_deg_s",
                   "yaw_rate_knowledge_deg_s", "mirror_rate_deg_s", "orbit_speed_km_s",
                   "altitude_km", "latitude_deg", "focal_length_rel")
#: all 17, in draw order
VARIABLES = STATE_VARIABLES + ERROR_VARIABLES


class Distribution(StrictModel):
    """Distribution of one variable: ``uniform`` on +-half_width or ``normal`` (0, sigma)."""

    dist: Literal["uniform", "normal"]
    half_width: float | None = Field(default=None, ge=0)
    sigma: float | None = Field(default=None, ge=0)

    @model_validator(mode="after")
    def _check(self):
        need = "half_width" if self.dist == "uniform" else "sigma"
        other = "sigma" if self.dist == "uniform" else "half_width"
        if getattr(self, need) is None:
            raise ValueError(f"{self.dist} needs {need}")
        if getattr(self, other) is not None:
            raise ValueError(f"{self.dist} takes {need}, not {other}")
        return self

    @property
    def scale(self) -> float:
        """Half-width (uniform) or sigma (normal)."""
        return float(self.half_width if self.dist == "uniform" else self.sigma)

    @property
    def std(self) -> float:
        """Standard deviation: sigma, or half_width / sqrt(3)."""
        return self.scale / math.sqrt(3.0) if self.dist == "uniform" else self.scale

    def from_standard(self, z):
        """Scale standardised draws (uniform on [-1, 1] or N(0, 1)) to this distribution."""
        return self.scale * np.asarray(z)

    def with_scale(self, scale: float) -> "Distribution":
        key = "half_width" if self.dist == "uniform" else "sigma"
        return self.model_copy(update={key: float(scale)})


class Orbit(StrictModel):
    altitude_km: float = Field(gt=0)
    sun_synchronous: bool = True
    inclination_deg: float | None = Field(default=None, ge=0, le=180)
    gamma0_deg: float = 0.0
    gamma_step_deg: float = 0.36
    earth_radius_km: float = Field(default=6378.137, gt=0)
    mu_km3_s2: float = Field(default=398600.4418, gt=0)
    earth_rate_rad_s: float = 7.2921159e-5
    j2: float = Field(default=1.08262668e-3, gt=0)
    nodal_rate_deg_day: float = 0.98564736


class Camera(StrictModel):
    focal_length_mm: float = Field(gt=0)
    pixel_pitch_um: float = Field(gt=0)
    tdi_stages: int = Field(ge=1)
    n_chips: int = Field(default=3, ge=1)
    chip_cols: int = Field(default=4096, ge=2)
    chip_gap_px: float = Field(default=0.0, ge=0)
    n_phase: int = Field(default=4, ge=1)


class Mirror(StrictModel):
    rate_deg_s: float
    rest_angle_deg: float = 45.0
    scan_duration_s: float = Field(default=20.0, gt=0)


class Errors(StrictModel):
    roll_deg: Distribution
    pitch_deg: Distribution
    yaw_deg: Distribution
    roll_rate_deg_s: Distribution
    pitch_rate_deg_s: Distribution
    yaw_rate_deg_s: Distribution
    roll_knowledge_deg: Distribution
    pitch_knowledge_deg: Distribution
    yaw_knowledge_deg: Distribution
    roll_rate_knowledge_deg_s: Distribution
    pitch_rate_knowledge_deg_s: Distribution
    yaw_rate_knowledge_deg_s: Distribution
    mirror_rate_deg_s: Distribution
    orbit_speed_km_s: Distribution
    altitude_km: Distribution
    latitude_deg: Distribution
    focal_length_rel: Distribution


class Synthesis(StrictModel):
    trials: int = Field(default=1000, ge=2)
    field_cols_per_chip: int = Field(default=33, ge=1)
    field_rows: int = Field(default=2, ge=1)
    mirror_rate_errors_deg_s: list[float] = Field(default=[0.001, 0.0005, 0.0004, 0.0003], min_length=1)
    mtf_threshold: float = Field(default=0.95, gt=0, lt=1)
    quantile: float = Field(default=0.997, gt=0, le=1)
    drift_angle: bool = True
    sobol_base_samples: int = Field(default=512, ge=8)


class Tdi(StrictModel):
    columns: int = Field(default=1000, ge=2)
    time_samples_per_phase: int = Field(default=64, ge=1)
    aperture_samples: int = Field(default=16, ge=1)
    signal_e_per_stage: float = Field(default=400.0, gt=0)
    read_noise_e: float = Field(default=30.0, ge=0)
    noise: bool = True
    edge_angle_deg: float = Field(default=5.0, gt=0, lt=45)
    edge_lines: int = Field(default=32, ge=8)
    edge_columns: int = Field(default=128, ge=8)
    edge_oversampling: int = Field(default=4, ge=1)
    edge_time_samples_per_phase: int = Field(default=8, ge=1)


class Validation(ValidationSettings):
    """Monte Carlo settings (:class:`simcam.config_base.ValidationSettings`, this study's defaults)."""

    trials: Trials = 200
    max_trials: Trials = 10000
    batch_trials: BatchTrials = 100


class WhiskbroomScenario(ScenarioBase):
    """The whole scenario (see ``data/default.toml`` for every field's meaning)."""

    orbit: Orbit
    camera: Camera
    mirror: Mirror
    errors: Errors
    synthesis: Synthesis = Synthesis()
    tdi: Tdi = Tdi()
    validation: Validation = Validation()

    @property
    def inclination_rad(self) -> float:
        """Orbit inclination: given, or sun-synchronous from the J2 nodal rate."""
        from simcam.whiskbroom.geometry import sun_synchronous_inclination

        o = self.orbit
        if not o.sun_synchronous:
            return math.radians(o.inclination_deg)
        return sun_synchronous_inclination(
            o.altitude_km, mu_km3_s2=o.mu_km3_s2, earth_radius_km=o.earth_radius_km, j2=o.j2,
            nodal_rate_rad_s=math.radians(o.nodal_rate_deg_day) / 86400.0)

    @property
    def orbit_speed_km_s(self) -> float:
        """Circular orbit speed ``sqrt(mu/a)``, km/s."""
        return math.sqrt(self.orbit.mu_km3_s2 / (self.orbit.earth_radius_km + self.orbit.altitude_km))


def default_text() -> str:
    """The embedded default scenario (TOML with comments)."""
    return resources.files("simcam.whiskbroom").joinpath("data/default.toml").read_text(encoding="utf-8")


def from_dict(data: dict, *, source: str = "scenario") -> WhiskbroomScenario:
    """Validate a mapping; every problem is a line ``source: field.path: message``."""
    scenario = validate_model(WhiskbroomScenario, data, source=source).with_source(source)
    problems = []
    orbit = scenario.orbit
    if orbit.sun_synchronous and orbit.inclination_deg is not None:
        problems.append("orbit.inclination_deg: give it only with sun_synchronous = false")
    if not orbit.sun_synchronous and orbit.inclination_deg is None:
        problems.append("orbit.inclination_deg: required when sun_synchronous = false")
    if scenario.synthesis.drift_angle and scenario.mirror.rate_deg_s == 0.0:
        problems.append("mirror.rate_deg_s: must be nonzero when synthesis.drift_angle = true "
                        "(a whiskbroom drift angle needs a scanning mirror; set "
                        "synthesis.drift_angle = false for the push-broom limit)")
    if orbit.sun_synchronous and not problems:
        try:
            scenario.inclination_rad
        except ValueError as exc:
            problems.append(f"orbit.altitude_km: {exc}")
    if problems:
        raise ScenarioError("\n".join(f"{source}: {p}" for p in problems))
    return scenario


def load(path: str | Path | None = None) -> WhiskbroomScenario:
    """The scenario file at ``path`` (strict: :func:`simcam.config_base.read_toml`) or, for
    None, the embedded default; errors name file and field."""
    if path is None:
        source = "embedded whiskbroom default"
        return from_dict(read_toml(text=default_text(), source=source), source=source)
    return from_dict(read_toml(path=path, source=str(path)), source=str(path))


def default() -> WhiskbroomScenario:
    """The embedded default scenario."""
    return load(None)
