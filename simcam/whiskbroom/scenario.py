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

from simcam.config_base import (BatchTrials, ScenarioBase, StrictModel, Trials, ValidationSettings, load_scenario_file,
                                validate_model)
from simcam.effects import EffectsBase, WorldBase
from simcam.infra.errors import ScenarioError
from simcam.infra.lifecycle import check_memory
from simcam.limits import nonfinite_fields
from simcam.units import EARTH_RATE_RAD_S, MU_EARTH_KM3_S2, SECONDS_PER_DAY, WGS84_A_KM
from simcam.whiskbroom.geometry import sun_synchronous_inclination

__all__ = ["Distribution", "WhiskbroomEffects", "WhiskbroomWorld", "WhiskbroomScenario", "STATE_VARIABLES", "ERROR_VARIABLES",
           "VARIABLES", "check_sizes", "default_text", "from_dict", "load", "default"]

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
    # at most 1000 of the variable's unit: beyond, the draws overflow the geometry
    half_width: float | None = Field(default=None, ge=0, le=1e3)
    sigma: float | None = Field(default=None, ge=0, le=1e3)

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
    altitude_km: float = Field(gt=0, le=1e6)
    sun_synchronous: bool = True
    inclination_deg: float | None = Field(default=None, ge=0, le=180)
    # physical ranges: the Earth's constants within a factor of ~10 of theirs
    gamma0_deg: float = Field(default=0.0, ge=-3600, le=3600)
    gamma_step_deg: float = Field(default=0.36, ge=-3600, le=3600)
    earth_radius_km: float = Field(default=WGS84_A_KM, ge=1000, le=70000)
    mu_km3_s2: float = Field(default=MU_EARTH_KM3_S2, gt=0, le=4e6)
    earth_rate_rad_s: float = Field(default=EARTH_RATE_RAD_S, ge=-1e-3, le=1e-3)
    j2: float = Field(default=1.08262668e-3, gt=0, le=0.1)
    nodal_rate_deg_day: float = Field(default=0.98564736, ge=-10, le=10)


class Camera(StrictModel):
    # physical ranges: a 100 m focal length, a 1 mm pixel, 10^4 stages, 1000
    # chips of 10^6 columns are beyond any camera; beyond them the image motion overflows
    focal_length_mm: float = Field(ge=1, le=1e5, description="1 mm to 100 m: no imaging camera is outside it")
    pixel_pitch_um: float = Field(ge=0.1, le=1e3, description="0.1 um (below the wavelength) to 1 mm")
    tdi_stages: int = Field(ge=1, le=10000)
    n_chips: int = Field(default=3, ge=1, le=1000)
    chip_cols: int = Field(default=4096, ge=2, le=1_000_000)
    chip_gap_px: float = Field(default=0.0, ge=0, le=1e6)
    n_phase: int = Field(default=4, ge=1, le=64)


class Mirror(StrictModel):
    rate_deg_s: float = Field(ge=-360, le=360)  # a turn per second is beyond any scan mirror
    rest_angle_deg: float = Field(default=45.0, ge=-360, le=360)
    scan_duration_s: float = Field(default=20.0, gt=0, le=1e5)


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
    field_cols_per_chip: int = Field(default=33, ge=1, le=1_000_000)
    field_rows: int = Field(default=2, ge=1, le=10000)
    mirror_rate_errors_deg_s: list[float] = Field(default=[0.001, 0.0005, 0.0004, 0.0003], min_length=1)
    mtf_threshold: float = Field(default=0.95, gt=0, lt=1)
    quantile: float = Field(default=0.997, gt=0, le=1)
    drift_angle: bool = True
    sobol_base_samples: int = Field(default=512, ge=8)


class Tdi(StrictModel):
    columns: int = Field(default=1000, ge=2)
    time_samples_per_phase: int = Field(default=64, ge=1)
    aperture_samples: int = Field(default=16, ge=1)
    signal_e_per_stage: float = Field(default=400.0, gt=0, le=1e9)
    read_noise_e: float = Field(default=30.0, ge=0, le=1e5, description="at most 1e5 e: no CCD reads with more")
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


class WhiskbroomEffects(EffectsBase):
    """Unmodelled effects of the whiskbroom camera's world (0 = off). Only the
    simulator's truth route (:mod:`simcam.whiskbroom.world`) reads them; the lab's predictions
    (published and improved sinc) and its slanted-edge measurement never do. The ranges beside
    the fields: the attitude jitter at most 100 arcsec (40 x ZY-3's, about 20 px of image
    motion: beyond it the slanted edge is smeared past its bins), the wheel's at most 10 arcsec
    (100 x the sourced upper end)."""

    earth_flattening_scale: float = Field(
        default=1.0, ge=0, le=1.5,
        description="WGS 84 flattening 1/298.257223563 (NIMA TR8350.2, 2000) x this scale; the world's "
                    "image motion is ray-traced to that ellipsoid (simcam.whiskbroom.raytrace); 0 = the "
                    "paper's sphere through the paper's own V_P chain")
    attitude_jitter_arcsec: float = Field(
        default=2.4, ge=0, le=100,
        description="roll amplitude of the dominant ZY-3 jitter tone, 0.65 Hz, 0.5-1.5 px cross-track "
                    "= 1.2-3.6 arcsec (Tong et al., IEEE TGRS, 2015, doi:10.1109/TGRS.2014.2379435); "
                    "the gyro tones 0.21/0.56/1.12 Hz at 0.07/0.04/0.04 arcsec (Tang et al., Sensors "
                    "20:736, 2020, Table 1) scale with it (world.jitter_tone_weights)")
    wheel_jitter_arcsec: float = Field(
        default=0.03, ge=0, le=10,
        description="roll amplitude of a reaction-wheel structural-mode tone (world.wheel_tone_hz): "
                    "0.01-0.1 arcsec at 10-200 Hz, an engineering estimate (structural modes dominate the "
                    "rigid-body 1e-9 rad; QuickBird's 4.3 Hz line 0.1 m, Tang et al. 2020; model form "
                    "Masterson et al., J. Sound Vib. 249:575, 2002, doi:10.1006/jsvi.2001.3868); 0.03 the "
                    "geometric middle")
    mirror_rate_ripple_fraction: float = Field(
        default=0.0022, ge=0, lt=1,
        description="scan-mirror rate ripple a in omega(t) = omega_x [1 + a sin(2 pi omega_x t / 1 deg + phi)]: "
                    "an inductosyn periodic error of 1.3 arcsec per 1 deg pitch after seed-001 "
                    "compensation, 2 pi 1.3 / 3600 = 0.22 % (69 arcsec uncompensated: 12 %)")
    pixel_crosstalk_fraction: float = Field(
        default=0.02, ge=0, lt=0.25,
        description="charge diffusion / crosstalk of a front-illuminated CCD, fraction X of the charge "
                    "to each of the 4 neighbours (3x3 kernel, Nyquist MTF 1 - 4X): X = 1-3 % "
                    "(opticks detector-MTF notes; Seib, IEEE TED 21:210, 1974, gives 0.81-0.95 at "
                    "600 nm for L_D = 2-5 um, L0 = 20-100 um)")


class WhiskbroomWorld(WorldBase):
    """The world's effects and the settings of their model forms (never a switch)."""

    effects: WhiskbroomEffects = WhiskbroomEffects()
    jitter_tones_hz: list[float] = Field(default=[0.65, 0.21, 0.56, 1.12], min_length=1)
    jitter_tone_weights: list[float] = Field(default=[1.0, 0.07 / 2.4, 0.04 / 2.4, 0.04 / 2.4], min_length=1)
    ripple_period_deg: float = Field(default=1.0, gt=0)
    wheel_tone_hz: float = Field(default=100.0, gt=0)

    @model_validator(mode="after")
    def _check_tones(self):
        if len(self.jitter_tones_hz) != len(self.jitter_tone_weights):
            raise ValueError("jitter_tone_weights: give one weight per entry of jitter_tones_hz")
        if any(f <= 0 for f in self.jitter_tones_hz):
            raise ValueError("jitter_tones_hz: frequencies must be > 0")
        return self


class WhiskbroomScenario(ScenarioBase):
    """The whole scenario (see ``data/default.toml`` for every field's meaning)."""

    orbit: Orbit
    camera: Camera
    mirror: Mirror
    errors: Errors
    synthesis: Synthesis = Synthesis()
    tdi: Tdi = Tdi()
    validation: Validation = Validation()
    world: WhiskbroomWorld = WhiskbroomWorld()

    @property
    def inclination_rad(self) -> float:
        """Orbit inclination: given, or sun-synchronous from the J2 nodal rate."""
        o = self.orbit
        if not o.sun_synchronous:
            return math.radians(o.inclination_deg)
        return sun_synchronous_inclination(
            o.altitude_km, mu_km3_s2=o.mu_km3_s2, earth_radius_km=o.earth_radius_km, j2=o.j2,
            nodal_rate_rad_s=math.radians(o.nodal_rate_deg_day) / SECONDS_PER_DAY)

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
    problems = nonfinite_fields(scenario)  # NaN and +-inf in any float field
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
    check_sizes(scenario, source=source)  # sizes refused before any allocation, naming the field
    return scenario


#: float64 work arrays per (trial, field point) of one mirror-rate level in
#: :func:`simcam.whiskbroom.synthesis.synthesize` (parameters, motion, residuals, quantiles),
#: plus the two kept per level (beta and Delta V_P): a lower bound, so nothing feasible is refused
_SYNTH_ARRAYS, _SYNTH_KEPT = 12, 4
#: bytes per Sobol sample row (17 variables drawn, their parameter rows, the motion)
_SOBOL_ROW_BYTES = 8 * 60


def check_sizes(sc: WhiskbroomScenario, *, source: str = "scenario", trials: int | None = None,
                trials_what: str | None = None) -> None:
    """Refuse, before any allocation, a scenario whose arrays cannot fit in memory, naming
    the fields (:class:`simcam.infra.errors.ResourceLimitError`, one line).

    Estimates: the synthesis holds ``trials x field points`` float64 arrays
    (:data:`_SYNTH_ARRAYS` of them, and :data:`_SYNTH_KEPT` per mirror-rate level); the
    Sobol analysis ``sobol_base_samples x 19`` rows; one validation trial the TDI
    accumulators (``tdi_stages x tdi.columns`` complex, twice) and the edge image
    (``edge_lines x edge_columns x edge_oversampling^2`` float64, three arrays).
    """
    cam, syn, t = sc.camera, sc.synthesis, sc.tdi
    k = float(syn.trials if trials is None else trials)
    points = float(cam.n_chips) * syn.field_cols_per_chip * syn.field_rows + 1.0
    levels = len(syn.mirror_rate_errors_deg_s)
    tw = trials_what or f"synthesis.trials = {syn.trials}"
    check_memory(8.0 * k * points * (_SYNTH_ARRAYS + _SYNTH_KEPT * levels),
                 what=f"{source}: {tw} x {points:.0f} field points (camera.n_chips x "
                      "synthesis.field_cols_per_chip x synthesis.field_rows)")
    # the report's motion field: every 64th column of every chip x about 5 rows, ~10 arrays
    check_memory(8.0 * 10 * (float(cam.n_chips) * cam.chip_cols / 64.0 + 1) * 5,
                 what=f"{source}: camera.n_chips x camera.chip_cols = {cam.n_chips} x {cam.chip_cols}")
    check_memory(float(syn.sobol_base_samples) * (len(VARIABLES) + 2) * _SOBOL_ROW_BYTES,
                 what=f"{source}: synthesis.sobol_base_samples = {syn.sobol_base_samples}")
    check_memory(2.0 * 16.0 * cam.tdi_stages * t.columns,
                 what=f"{source}: camera.tdi_stages x tdi.columns = {cam.tdi_stages} x {t.columns}")
    check_memory(3.0 * 8.0 * t.edge_lines * t.edge_columns * float(t.edge_oversampling) ** 2,
                 what=f"{source}: tdi.edge_lines x tdi.edge_columns = {t.edge_lines} x {t.edge_columns}")


def load(path: str | Path | None = None) -> WhiskbroomScenario:
    """The scenario file at ``path`` (strict: :func:`simcam.config_base.read_toml`) or, for
    None or ``"embedded:default"`` (the name a claims ledger gives), the embedded default;
    errors name file and field."""
    if isinstance(path, str) and path.startswith("embedded:"):
        if path != "embedded:default":
            raise ScenarioError(f"{path}: no embedded whiskbroom scenario {path[9:]!r} (have default)")
        path = None
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="whiskbroom")


def default() -> WhiskbroomScenario:
    """The embedded default scenario."""
    return load(None)
