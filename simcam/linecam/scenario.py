"""Scenario of the TDI line camera and its star-observation calibration (seed 004).

Frozen strict pydantic models (unknown key = error naming it); the embedded default
``simcam/linecam/data/default.toml`` carries the comments that say why each number was
chosen (the patent gives none).
"""

from __future__ import annotations

from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated, ClassVar, Literal

from pydantic import ConfigDict, Field, field_validator, model_validator

from simcam.config_base import (BatchTrials, ScenarioBase, StrictModel, Trials, ValidationSettings, load_scenario_file,
                                model_hash, validate_model)
from simcam.infra.errors import ScenarioError
from simcam.limits import check_epoch_utc

from simcam.units import ARCSEC_PER_DEG

from .effects import LineCamWorld

__all__ = ["LineCamScenario", "default_text", "from_dict", "load", "default",
           "PARAMETERS"]

#: calibration parameters in order: exterior rotation vector (3), interior (7)
PARAMETERS = ("roll", "pitch", "yaw", "dx0", "dy0", "df", "k1", "k2", "p1", "p2")

NonNeg = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
Pos = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Unit = Annotated[float, Field(gt=0.0, le=1.0, allow_inf_nan=False)]


class _M(StrictModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, validate_default=True)


class QEModel(_M):
    """Parametric QE (:func:`simcam.spectra.cmos_qe_array`)."""

    peak_qe: Unit = 0.6
    peak_nm: Annotated[float, Field(gt=0, le=100000.0, allow_inf_nan=False)] = 650.0
    blue_cutoff_nm: Annotated[float, Field(gt=0, le=100000.0, allow_inf_nan=False)] = 420.0
    red_cutoff_nm: Annotated[float, Field(gt=0, le=100000.0, allow_inf_nan=False)] = 900.0


class LineCameraModel(_M):
    """TDI line camera: geometry, timing, photometry."""

    # physical ranges: beyond them the geometry overflows (tracebacks before)
    focal_length_mm: Annotated[float, Field(gt=0, le=100000.0, allow_inf_nan=False)] = 1000.0
    pixel_pitch_um: Annotated[float, Field(gt=0, le=1000.0, allow_inf_nan=False)] = 10.0
    n_pixels: Annotated[int, Field(ge=64, le=100000)] = 6144
    tdi_stages: Annotated[int, Field(ge=1, le=256)] = 32
    line_period_s: Annotated[float, Field(gt=0, le=10.0, allow_inf_nan=False)] = 0.0005
    x_line_mm: Annotated[float, Field(ge=-1e3, le=1e3, allow_inf_nan=False)] = 0.0
    aperture_mm: Annotated[float, Field(gt=0, le=10000.0, allow_inf_nan=False)] = 125.0
    transmission: Unit = 0.7
    psf_sigma_px: Annotated[float, Field(gt=0.1, le=5.0)] = 0.8
    background_e: Annotated[float, Field(ge=0, le=1000000000.0, allow_inf_nan=False)] = 5.0
    qe: QEModel = QEModel()

    @property
    def pitch_mm(self) -> float:
        return self.pixel_pitch_um * 1e-3

    @property
    def matched_rate_rad_s(self) -> float:
        """Scan rate that keeps a star in step with the TDI charge: ``p / (f T)`` (rad/s)."""
        return self.pitch_mm / (self.focal_length_mm * self.line_period_s)

    @property
    def exposure_s(self) -> float:
        return self.tdi_stages * self.line_period_s


class DetectorModel(_M):
    gain_e_per_dn: Annotated[float, Field(gt=0, le=1000000.0, allow_inf_nan=False)] = 4.0
    offset_dn: Annotated[float, Field(ge=0, le=4294967296.0, allow_inf_nan=False)] = 100.0
    read_noise_e: Annotated[float, Field(ge=0, le=1000000.0, allow_inf_nan=False)] = 25.0
    full_well_e: Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)] = 120000.0
    adc_bits: Annotated[int, Field(ge=8, le=32)] = 16
    prnu_rms: Annotated[float, Field(ge=0, le=1.0, allow_inf_nan=False)] = 0.005
    dark_e: Annotated[float, Field(ge=0, le=1000000000.0, allow_inf_nan=False)] = 2.0
    dsnu_rms_e: Annotated[float, Field(ge=0, le=1000000000.0, allow_inf_nan=False)] = 0.5


class OrbitModel(_M):
    epoch_utc: str = "2025-06-01T00:00:00"

    @field_validator("epoch_utc")
    @classmethod
    def _epoch(cls, v: str) -> str:
        """Parsed when the scenario loads (was: a 79-line astropy traceback at the first use)."""
        return check_epoch_utc(v)
    altitude_km: Annotated[float, Field(gt=100.0, lt=100000.0)] = 600.0
    inclination_deg: Annotated[float, Field(ge=0.0, le=180.0)] = 97.8
    raan_deg: Annotated[float, Field(ge=-3600.0, le=3600.0, allow_inf_nan=False)] = 0.0
    arg_latitude_deg: Annotated[float, Field(ge=-3600.0, le=3600.0, allow_inf_nan=False)] = 0.0


class AttitudeModel(_M):
    rate_mismatch: Annotated[float, Field(gt=-0.5, lt=0.5)] = 0.0
    cross_rate_deg_s: Annotated[float, Field(ge=-10.0, le=10.0, allow_inf_nan=False)] = 0.0
    yaw_rate_deg_s: Annotated[float, Field(ge=-10.0, le=10.0, allow_inf_nan=False)] = 0.0
    knowledge_noise_arcsec: Annotated[float, Field(ge=0, le=3600.0, allow_inf_nan=False)] = 0.5


class StarsModel(_M):
    mag_limit: Annotated[float, Field(ge=-2.0, le=12.0)] = 8.0
    world_mag_limit: Annotated[float, Field(ge=-2.0, le=12.0)] = 8.5
    region: Literal["auto", "manual"] = "auto"
    ra_deg: Annotated[float, Field(ge=0.0, lt=360.0)] = 280.0
    dec_deg: Annotated[float, Field(ge=-90.0, le=90.0)] = -5.0
    scan_pa_deg: Annotated[float, Field(ge=-3600.0, le=3600.0, allow_inf_nan=False)] = 0.0
    strip_length_deg: Annotated[float, Field(gt=0.0, le=90.0)] = 10.0

    @model_validator(mode="after")
    def _world_fainter(self):
        if self.world_mag_limit < self.mag_limit:
            raise ValueError("world_mag_limit must be >= mag_limit (the world images at least the lab's stars)")
        return self


class ObservationModel(_M):
    passes: Annotated[int, Field(ge=1, le=200)] = 4
    shift_px: Annotated[float, Field(ge=0, le=1000000.0, allow_inf_nan=False)] = 1280.0
    pass_interval_s: Annotated[float, Field(gt=0, le=1000000.0, allow_inf_nan=False)] = 30.0


class ErrorDist(_M):
    """An injected error: ``value + sigma * N(0, 1)`` per trial."""

    value: Annotated[float, Field(ge=-1e6, le=1e6, allow_inf_nan=False)] = 0.0
    sigma: Annotated[float, Field(ge=0, le=1000000.0, allow_inf_nan=False)] = 0.0


class ErrorsModel(_M):
    dx0_px: ErrorDist = ErrorDist(sigma=2.0)
    dy0_px: ErrorDist = ErrorDist(sigma=2.0)
    df_mm: ErrorDist = ErrorDist(sigma=0.1)
    k1: ErrorDist = ErrorDist(sigma=2e-4)
    k2: ErrorDist = ErrorDist(sigma=1e-4)
    p1: ErrorDist = ErrorDist(sigma=1e-4)
    p2: ErrorDist = ErrorDist(sigma=1e-4)
    roll_arcsec: ErrorDist = ErrorDist(sigma=30.0)
    pitch_arcsec: ErrorDist = ErrorDist(sigma=30.0)
    yaw_arcsec: ErrorDist = ErrorDist(sigma=30.0)

    #: field name of each calibration parameter (order of PARAMETERS)
    FIELDS: ClassVar[tuple] = ("roll_arcsec", "pitch_arcsec", "yaw_arcsec", "dx0_px", "dy0_px", "df_mm",
                     "k1", "k2", "p1", "p2")


class LabModel(_M):
    aberration: bool = True
    parallax: bool = True
    proper_motion: bool = True
    time_tag: Literal["mid_exposure", "readout"] = "mid_exposure"
    match_radius_arcsec: Annotated[float, Field(gt=0, le=180.0 * ARCSEC_PER_DEG, allow_inf_nan=False)] = 120.0
    coverage_bins: Annotated[int, Field(ge=2, le=1000)] = 24
    max_iter: Annotated[int, Field(ge=1, le=1000)] = 30
    rcond: Annotated[float, Field(gt=0.0, lt=1e-2)] = 1e-6
    gauge_sigma_px: Annotated[float, Field(gt=0, le=1000000000.0, allow_inf_nan=False)] = 10.0
    lookangle_degree_along: Annotated[int, Field(ge=0, le=9)] = 4
    lookangle_degree_across: Annotated[int, Field(ge=1, le=9)] = 5
    grid_step_px: Annotated[int, Field(ge=1, le=4096)] = 16


class ValidationModel(ValidationSettings):
    """Monte Carlo settings (:class:`simcam.config_base.ValidationSettings`, this study's
    defaults; strict types like the rest of the scenario). ``tolerance`` is None by default:
    the classes mix units (arcsec, px, mm, 1e-4), so a run uses a fixed number of trials
    unless a tolerance is given (in the scenario or by ``--tolerance``)."""

    model_config = _M.model_config

    trials: Trials = 200
    max_trials: Trials = 2000
    batch_trials: BatchTrials = 50


class LineCamScenario(ScenarioBase):
    """The whole scenario: camera, detector, orbit, attitude, stars, plan, errors, lab."""

    camera: LineCameraModel = LineCameraModel()
    detector: DetectorModel = DetectorModel()
    orbit: OrbitModel = OrbitModel()
    attitude: AttitudeModel = AttitudeModel()
    stars: StarsModel = StarsModel()
    observation: ObservationModel = ObservationModel()
    errors: ErrorsModel = ErrorsModel()
    lab: LabModel = LabModel()
    validation: ValidationModel = ValidationModel()
    #: the world's unmodelled effects; read by the world only, never by the lab
    world: LineCamWorld = LineCamWorld()

    model_config = _M.model_config

    @cached_property
    def hash(self) -> str:
        """SHA-256 prefix of the canonical content."""
        return model_hash(self)


def default_text() -> str:
    """The embedded default scenario (TOML with comments)."""
    return resources.files("simcam.linecam").joinpath("data/default.toml").read_text(encoding="utf-8")


def from_dict(data: dict, *, source: str = "scenario") -> LineCamScenario:
    """Validate a mapping into :class:`LineCamScenario` (errors name ``source`` and field)."""
    return validate_model(LineCamScenario, data, source=source).with_source(source)


def load(path: str | Path | None = None) -> LineCamScenario:
    """The scenario file at ``path`` (strict TOML, :func:`simcam.config_base.read_toml`) or,
    for None or ``"embedded:default"`` (the name a claims ledger gives), the embedded default."""
    if isinstance(path, str) and path.startswith("embedded:"):
        if path != "embedded:default":
            raise ScenarioError(f"{path}: no embedded linecam scenario {path[9:]!r} (have default)")
        path = None
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="linecam")


def default() -> LineCamScenario:
    """The embedded default scenario."""
    return load(None)
