"""Scan-mirror scenario: strict frozen pydantic models and the embedded default
(``simcam/scanmirror/data/default.toml``, commented)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from simcam.config_base import (BatchTrials, ScenarioBase, StrictModel, Trials, ValidationSettings, load_scenario_file,
                                validate_model)
from simcam.infra.errors import ScenarioError
from simcam.limits import check_epoch_utc
from simcam.scanmirror.effects import ScanMirrorEffects, ScanMirrorWorld
from simcam.scanmirror.scanplan import evaluate_plan, segment_durations
from simcam.units import JGM3_RADIUS_KM

__all__ = ["EMBEDDED_DEFAULT", "ScanMirrorScenario", "default_text", "from_dict", "load", "default", "OrbitConfig",
           "AttitudeConfig",
           "MirrorConfig", "StarSensingConfig", "ScanPlan", "ScanMirrorEffects", "ScanMirrorWorld"]

Finite = Annotated[float, Field(allow_inf_nan=False)]
Vec3 = tuple[Finite, Finite, Finite]
Pos = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0, allow_inf_nan=False)]


class OrbitConfig(StrictModel):
    nominal_longitude_deg: Annotated[float, Field(ge=-180, le=360)] = 105.0
    nominal_radius_km: Annotated[float, Field(gt=JGM3_RADIUS_KM * 1.5)] = 42164.0
    semi_major_axis_km: Annotated[float, Field(gt=JGM3_RADIUS_KM)] = 42164.0
    eccentricity: Annotated[float, Field(ge=0, lt=1)] = 0.001
    inclination_deg: Annotated[float, Field(ge=0, le=180)] = 0.5
    raan_deg: Annotated[float, Field(ge=-360, le=360)] = 105.5
    arg_perigee_deg: Annotated[float, Field(ge=-360, le=360)] = 0.0
    true_anomaly_deg: Annotated[float, Field(ge=-360, le=360)] = 0.1
    greenwich_angle_deg: Annotated[float, Field(ge=-360, le=360)] = 0.0
    zonal_degree: Literal[0, 2, 3, 4] = 4
    epoch_utc: str = "2012-03-01T00:00:00"
    earth_shape: Literal["sphere", "ellipsoid"] = "sphere"
    knowledge_sigma_km: NonNeg = Field(0.1, le=1000.0, description="at most 1000 km: beyond it no orbit is known")

    @model_validator(mode="after")
    def _perigee_above_earth(self):
        if self.semi_major_axis_km * (1 - self.eccentricity) <= JGM3_RADIUS_KM:
            raise ValueError("semi_major_axis_km * (1 - eccentricity): perigee inside the Earth")
        return self

    @field_validator("epoch_utc")
    @classmethod
    def _epoch(cls, v: str) -> str:
        return check_epoch_utc(v)  # one line (astropy's message listed every format: 11 lines)


class AttitudeConfig(StrictModel):
    mode: Literal["pd", "profile"] = "pd"
    # physical ranges
    inertia_kg_m2: tuple[Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)]] = (1800.0, 1500.0, 2200.0)
    kp_n_m_rad: tuple[Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)]] = (4.5, 3.75, 5.5)
    kd_n_m_s_rad: tuple[Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)], Annotated[float, Field(gt=0, le=1000000000000.0, allow_inf_nan=False)]] = (126.0, 105.0, 154.0)
    disturbance_torque_n_m: Vec3 = (1e-4, -5e-5, 8e-5)
    initial_deg: Vec3 = (0.02, -0.015, 0.025)
    initial_sigma_deg: Annotated[float, Field(ge=0, le=90, allow_inf_nan=False)] = 0.005
    profile_constant_deg: Vec3 = (0.005, -0.003, 0.004)
    profile_amplitude_deg: Vec3 = (0.001, 0.001, 0.001)
    profile_period_s: Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)] = 300.0
    knowledge_sigma_arcsec: Annotated[float, Field(ge=0, le=3600.0, allow_inf_nan=False)] = 1.0


class MirrorConfig(StrictModel):
    deviation_constant_deg: Annotated[float, Field(ge=0, le=1)] = 0.0115
    deviation_variable_deg: Annotated[float, Field(ge=0, le=1)] = 0.0057
    deviation_period_s: Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)] = 86164.0
    deviation_phase_deg: Annotated[float, Field(ge=-3600, le=3600, allow_inf_nan=False)] = 0.0
    deviation_axis_deg: Annotated[float, Field(ge=-3600, le=3600, allow_inf_nan=False)] = 30.0
    random_axis: bool = True
    constant_sigma_deg: Annotated[float, Field(ge=0, le=1, allow_inf_nan=False)] = 0.003


class StarSensingConfig(StrictModel):
    field_half_width_deg: Annotated[float, Field(gt=0, le=5)] = 1.0
    mag_limit: Annotated[float, Field(ge=-2, le=12, allow_inf_nan=False)] = 7.5
    #: star-sensing dwells per star-sensing segment of the plan: each one after the first
    #: follows a move of ``extra_dwell_beta_step_deg`` in scan angle (a sweepable count;
    #: :meth:`ScanMirrorScenario.effective_plan`)
    dwells: Annotated[int, Field(ge=1, le=20)] = 1
    extra_dwell_beta_step_deg: Annotated[float, Field(ge=-10, le=10)] = 1.0
    extra_dwell_move_s: Annotated[float, Field(gt=0, le=60)] = 2.0
    centroid_sigma_arcsec: Annotated[float, Field(gt=0, le=3600, allow_inf_nan=False)] = 1.0
    tracker_sigma_arcsec: Annotated[float, Field(gt=0, le=3600, allow_inf_nan=False)] = 1.0
    frames_per_dwell: Annotated[int, Field(ge=1, le=100)] = 4
    #: lab time of one star-sensing frame (exposure and readout at the stated centroid
    #: sigma), s: 0 = each star dwell lasts as written in the plan and its frames share it
    #: (today's); > 0 = each star-sensing dwell lasts ``frames_per_dwell * frame_time_s``
    #: (:meth:`ScanMirrorScenario.effective_plan`), so a frame costs time, as it does when
    #: each frame has the centroid sigma stated. 5 s is the paper's 20 s dwell over 4 frames.
    frame_time_s: Annotated[float, Field(ge=0, le=3600, allow_inf_nan=False)] = 0.0
    published_uses_aberration: bool = False


class CompensationConfig(StrictModel):
    ground_step_s: Annotated[float, Field(gt=0, le=10)] = 0.1


class ValidationConfig(ValidationSettings):
    """Monte Carlo settings (:class:`simcam.config_base.ValidationSettings`, this study's
    defaults) and the sampling step of the ground track inside a trial."""

    trials: Trials = 1000
    max_trials: Trials = 4000
    batch_trials: BatchTrials = 200
    ground_step_s: Annotated[float, Field(gt=0, le=10)] = 0.5


class DwellSegment(StrictModel):
    kind: Literal["dwell"]
    duration_s: Annotated[float, Field(gt=0, le=1000000.0, allow_inf_nan=False)]
    star_sensing: bool = False


class MoveSegment(StrictModel):
    kind: Literal["move"]
    to_alpha_deg: Annotated[float, Field(ge=-30, le=30)]
    to_beta_deg: Annotated[float, Field(ge=-90, le=0)]
    accel_s: NonNeg
    const_s: NonNeg
    decel_s: NonNeg

    @model_validator(mode="after")
    def _nonzero(self):
        if self.accel_s + self.const_s + self.decel_s <= 0:
            raise ValueError("accel_s + const_s + decel_s must be > 0")
        return self


class AreaScanSegment(StrictModel):
    kind: Literal["area_scan"]
    lines: Annotated[int, Field(ge=1, le=100000)]
    line_deg: Annotated[float, Field(ge=-180, le=180, allow_inf_nan=False)]
    line_s: Annotated[float, Field(gt=0, le=100000.0, allow_inf_nan=False)]
    step_deg: Annotated[float, Field(ge=-90, le=90, allow_inf_nan=False)]
    turnaround_s: NonNeg

    @model_validator(mode="after")
    def _turn(self):
        if self.turnaround_s >= self.line_s:
            raise ValueError("turnaround_s must be shorter than line_s")
        return self


Segment = Annotated[Union[DwellSegment, MoveSegment, AreaScanSegment], Field(discriminator="kind")]


class ScanPlan(StrictModel):
    initial_alpha_deg: Annotated[float, Field(ge=-30, le=30)] = 1.0
    initial_beta_deg: Annotated[float, Field(ge=-90, le=0)] = -46.5
    segments: tuple[Segment, ...] = Field(min_length=1)


class ScanMirrorScenario(ScenarioBase):
    orbit: OrbitConfig = OrbitConfig()
    attitude: AttitudeConfig = AttitudeConfig()
    mirror: MirrorConfig = MirrorConfig()
    star_sensing: StarSensingConfig = StarSensingConfig()
    compensation: CompensationConfig = CompensationConfig()
    validation: ValidationConfig = ValidationConfig()
    scan_plan: ScanPlan
    #: the world's unmodelled effects (simcam.scanmirror.effects): read by the simulator
    #: and the truth only, never by the lab
    world: ScanMirrorWorld = ScanMirrorWorld()

    @property
    def effective_plan(self) -> ScanPlan:
        """The scan plan as flown: each star-sensing dwell followed by
        ``star_sensing.dwells - 1`` more, each after a move of
        ``star_sensing.extra_dwell_beta_step_deg`` in scan angle (``extra_dwell_move_s``,
        half accelerating, half decelerating) at the same step angle; with
        ``star_sensing.frame_time_s > 0`` every star-sensing dwell lasts
        ``frames_per_dwell * frame_time_s``; the plan as written when ``dwells = 1`` and
        ``frame_time_s = 0``."""
        ss = self.star_sensing
        if ss.frame_time_s > 0:
            plan = ScanPlan(initial_alpha_deg=self.scan_plan.initial_alpha_deg,
                            initial_beta_deg=self.scan_plan.initial_beta_deg,
                            segments=tuple(DwellSegment(kind="dwell", duration_s=ss.frames_per_dwell * ss.frame_time_s,
                                                        star_sensing=True)
                                           if seg.kind == "dwell" and seg.star_sensing else seg
                                           for seg in self.scan_plan.segments))
        else:
            plan = self.scan_plan
        if ss.dwells == 1:
            return plan
        segs = list(plan.segments)
        starts = np.concatenate([[0.0], np.cumsum(segment_durations(segs))])
        out = []
        for seg, t0, t1 in zip(segs, starts[:-1], starts[1:]):
            out.append(seg)
            if seg.kind != "dwell" or not seg.star_sensing:
                continue
            p = evaluate_plan(plan, np.array([0.5 * (t0 + t1)]))
            a, b = float(np.rad2deg(p.alpha_rad[0])), float(np.rad2deg(p.beta_rad[0]))
            for j in range(1, ss.dwells):
                half = 0.5 * ss.extra_dwell_move_s
                out.append(MoveSegment(kind="move", to_alpha_deg=a, to_beta_deg=b + j * ss.extra_dwell_beta_step_deg,
                                       accel_s=half, const_s=0.0, decel_s=half))
                out.append(DwellSegment(kind="dwell", duration_s=seg.duration_s, star_sensing=True))
        return ScanPlan(initial_alpha_deg=plan.initial_alpha_deg,
                        initial_beta_deg=plan.initial_beta_deg, segments=tuple(out))


def default_text() -> str:
    """The embedded default scenario (TOML with comments)."""
    return files("simcam.scanmirror").joinpath("data/default.toml").read_text(encoding="utf-8")


def from_dict(data: dict, *, source: str = "scenario") -> ScanMirrorScenario:
    """Validate a mapping; errors are :class:`ScenarioError` lines naming ``source`` and field."""
    scenario = validate_model(ScanMirrorScenario, data, source=source).with_source(source)
    n_scan = sum(1 for s in scenario.scan_plan.segments if s.kind == "area_scan")
    if n_scan < 1:
        raise ScenarioError(f"{source}: scan_plan.segments: at least one area_scan is needed")
    return scenario


#: the embedded default's name (as the star camera's ``embedded:NAME``)
EMBEDDED_DEFAULT = "embedded:default"


def load(path: str | Path | None = None) -> ScanMirrorScenario:
    """The scenario file at ``path`` (strict TOML, :func:`simcam.config_base.read_toml`) or,
    for None or :data:`EMBEDDED_DEFAULT` (the name a claim gives it), the embedded default."""
    if path == EMBEDDED_DEFAULT:
        path = None
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="scanmirror")


def default() -> ScanMirrorScenario:
    """The embedded default scenario."""
    return load(None)
