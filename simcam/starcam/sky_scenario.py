"""The attitude study's scenario: a star camera flown on the real sky (issue #34).

A :class:`SkyScenario` names the star camera it flies (a star-camera scenario of
:mod:`simcam.starcam.scenario`: ``embedded:NAME`` or a file path, relative to the working
directory as every path of a command line), the sky (epoch, observer, the onboard
catalogue's limit), how the camera observes onboard (frames per pointing, centroid threshold,
an optional angular rate that smears each exposure and moves the frames along a slew), the
lab's published per-star budget that the study judges (seed 000's eq 32 and its components),
the attitude requirement of the report and the Monte Carlo settings. The embedded default
(``simcam/data/attitude_default.toml``) documents every key.

The star camera's scenario is loaded once when the sky scenario is validated and kept with it
(:attr:`SkyScenario.camera_scenario`, pickled with it to worker processes); its hash is part
of the sky scenario's hash, so a changed camera file is a different scenario.

The world (``[world.effects]``, :class:`AttitudeEffects`): the star camera's world effects
that act in orbit (the distortion beyond the cubic, which the onboard correction fitted in the
camera's lab calibration leaves in part; the detector's non-linearity), at the camera's
sourced realistic magnitudes. They replace the flown camera scenario's own values of the same
effects (:attr:`SkyScenario.camera_scenario`), so that the claims ledger judges eq 32 in the
seed's own world (all 0) and the realistic world. The camera's lab-only effects (hexapod,
target drift) move nothing on the sky: this chain never reads them.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
from importlib import resources
from pathlib import Path
from typing import Annotated

from annotated_types import Interval
from pydantic import Field, PrivateAttr, field_validator, model_validator

from simcam.config_base import (
    BatchTrials,
    ScenarioBase,
    StrictModel,
    Trials,
    ValidationSettings,
    load_scenario_file,
    model_hash,
    validate_model,
)
from simcam.effects import EffectsBase, WorldBase
from simcam.infra.errors import ScenarioError
from simcam.limits import check_epoch_utc
from simcam.starcam import scenario as starcam_scenario

__all__ = ["DEFAULT_RESOURCE", "IN_ORBIT_EFFECTS", "AttitudeEffects", "AttitudeWorld", "BudgetConfig", "OnboardConfig", "RequirementConfig", "SkyConfig", "SkyScenario",
           "SkyValidation", "default", "default_text", "from_dict", "load"]

DEFAULT_RESOURCE = "attitude_default.toml"

#: a per-axis (x, y) figure in arcsec, 3 sigma: at most 3600" (a budget beyond a degree is no star camera's);
#: an ``Interval`` so that the range is read beside the tuple's elements (simcam.config_base.declared_range)
Arcsec3Sigma = Annotated[float, Interval(ge=0.0, le=3600.0)]
XY = tuple[Arcsec3Sigma, Arcsec3Sigma]
#: an observer coordinate: within 1e7 km of the geocentre (beyond the Moon's orbit x 25)
PositionKm = Annotated[float, Field(ge=-1e7, le=1e7)]
#: an observer velocity component: at most 100 km/s (the Earth's orbit is 30 km/s)
VelocityKmS = Annotated[float, Field(ge=-100.0, le=100.0)]
#: an angular rate component: at most 10 deg/s (a star camera's tracking limit is about 1-5 deg/s)
RateDegS = Annotated[float, Field(ge=-10.0, le=10.0)]

# loaded star-camera scenarios by reference (and, for a file, its size and modification time)
_CAMERAS: dict = {}


def _camera_key(ref: str):
    if ref.startswith("embedded:"):
        return (ref,)
    try:
        st = os.stat(ref)
    except OSError:
        return (ref, None)
    return (ref, st.st_size, st.st_mtime_ns)


def load_camera(ref: str) -> starcam_scenario.Scenario:
    """The star-camera scenario ``ref`` names (``embedded:NAME`` or a file path), loaded once
    per process and content; :class:`ScenarioError` naming it where it cannot be loaded."""
    key = _camera_key(ref)
    hit = _CAMERAS.get(key)
    if hit is None:
        hit = starcam_scenario.load(ref)
        if len(_CAMERAS) > 8:
            _CAMERAS.clear()
        _CAMERAS[key] = hit
    return hit


class SkyConfig(StrictModel):
    """The sky the camera sees: the epoch of the stars' apparent places, the observer (its
    geocentric GCRS position and velocity: the velocity gives the orbital aberration) and the
    onboard catalogue's limit (only its stars are rendered and solved with)."""

    epoch_utc: str = "2026-03-21T00:00:00"
    observer_position_km: tuple[PositionKm, PositionKm, PositionKm] = (0.0, 0.0, 0.0)
    observer_velocity_km_s: tuple[VelocityKmS, VelocityKmS, VelocityKmS] = (0.0, 0.0, 0.0)
    catalogue_v_max_mag: float = Field(7.5, ge=-2.0, le=14.0,
                                       description="Hipparcos is complete to V 7.3-9 and ends near V 14")

    @field_validator("epoch_utc")
    @classmethod
    def _epoch(cls, v: str) -> str:
        return check_epoch_utc(v)


class OnboardConfig(StrictModel):
    """How the camera observes each pointing onboard: ``frames`` frames (at least 2: their
    spread is the temporal noise), centroided at ``threshold_sigma`` times the pixel noise
    (which also sets the detection limit), and an angular rate of the camera frame
    (``angular_rate_deg_per_s``: about camera x, y and the boresight z) that smears each
    exposure and moves frame ``f`` to the attitude ``A exp([w] t_f)``,
    ``t_f = (f - (frames - 1) / 2) frame_interval_s``: a slew whose consecutive frames share
    most of their stars. All zero: the camera stares."""

    frames: Annotated[int, Field(ge=2, le=10000)] = 10
    threshold_sigma: float = Field(3.0, gt=0.0, le=1000.0,
                                   description="at most 1000 noise sigmas: above it no pixel is kept")
    angular_rate_deg_per_s: tuple[RateDegS, RateDegS, RateDegS] = (0.0, 0.0, 0.0)
    frame_interval_s: float = Field(1.0, gt=0.0, le=86400.0, description="at most a day between frames")

    @property
    def staring(self) -> bool:
        """Whether the camera does not move (every frame at the pointing's attitude, no smear)."""
        return not any(self.angular_rate_deg_per_s)


class BudgetConfig(StrictModel):
    """The lab's published per-star budget (3 sigma, arcsec, x and y; seed 000 section 2.4):
    the single-star error and the star count of eq 32 (the published prediction,
    ``single_star / sqrt(n_stars)``), and its components (TE, HSFE, LSFE-S, LSFE-C1, LSFE-C2,
    eqs 31-32), from which the study's improved prediction is built. TE was measured with the
    lab's own source (the flown camera's ``lab.source``), whose electrons set its scale.
    ``lsfe_c_correlation_px`` is the length ``L`` of a Gaussian correlogram
    ``exp(-d^2 / (2 L^2))`` of the lab's distortion residual map (px; 0: independent from star
    to star), with which the prediction treats LSFE-C as a field the stars share."""

    single_star_3sigma_arcsec: XY = (1.76, 1.95)
    n_stars: Annotated[int, Field(ge=1, le=10000)] = 10
    te_3sigma_arcsec: XY = (1.14, 1.23)
    hsfe_3sigma_arcsec: XY = (1.08, 1.01)
    lsfe_s_3sigma_arcsec: XY = (0.03, 0.66)
    lsfe_c1_3sigma_arcsec: XY = (0.29, 0.41)
    lsfe_c2_3sigma_arcsec: XY = (0.5, 0.5)
    lsfe_c_correlation_px: float = Field(200.0, ge=0.0, le=1e6, description="correlation length of the smooth "
                                         "field (LSFE-C) over the focal plane, the lab's from its residual map")


class RequirementConfig(StrictModel):
    """An attitude requirement the report checks each pointing against: at least ``min_stars``
    stars in view and its error (3 times the rms over its frames) within the 3-sigma
    figure on each axis."""

    x_3sigma_arcsec: float = Field(1.5, gt=0.0, le=3600.0)
    y_3sigma_arcsec: float = Field(1.5, gt=0.0, le=3600.0)
    roll_3sigma_arcsec: float = Field(15.0, gt=0.0, le=36000.0)
    min_stars: Annotated[int, Field(ge=2, le=10000)] = 5


#: the star camera's world effects that act in orbit (fields of
#: :class:`simcam.starcam.scenario.StarCameraEffects`, the same names here)
IN_ORBIT_EFFECTS = ("distortion_r5_px_at_corner", "distortion_r7_px_at_corner", "nonlinearity_beta")
_CAMERA_FIELDS = starcam_scenario.StarCameraEffects.model_fields


class AttitudeEffects(EffectsBase):
    """The flown camera's world beyond the lab's model that acts on the sky (module
    docstring): the star camera's own effects of the same names
    (:class:`simcam.starcam.scenario.StarCameraEffects`, their model forms in
    :class:`simcam.starcam.optics.HigherOrderRadialDistortion` and :mod:`simcam.detector`),
    at its sourced realistic magnitudes; 0 is off. They replace the flown camera scenario's
    values."""

    # the same fields as the star camera's (default, range and sourced description), so the
    # two cannot drift apart
    distortion_r5_px_at_corner: float = copy.copy(_CAMERA_FIELDS["distortion_r5_px_at_corner"])
    distortion_r7_px_at_corner: float = copy.copy(_CAMERA_FIELDS["distortion_r7_px_at_corner"])
    nonlinearity_beta: float = copy.copy(_CAMERA_FIELDS["nonlinearity_beta"])


class AttitudeWorld(WorldBase):
    """The attitude study's world: the in-orbit effects' magnitudes (:class:`AttitudeEffects`)."""

    effects: AttitudeEffects = AttitudeEffects()


def flown_camera(camera: starcam_scenario.Scenario, effects: AttitudeEffects) -> starcam_scenario.Scenario:
    """``camera`` with its in-orbit world effects (:data:`IN_ORBIT_EFFECTS`) set to ``effects``'
    (itself when they already are), re-validated; kept per camera and effects."""
    own = camera.world.effects
    values = {n: float(getattr(effects, n)) for n in IN_ORBIT_EFFECTS}
    if all(float(getattr(own, n)) == v for n, v in values.items()):
        return camera
    key = ("flown", camera.hash, tuple(values.values()))
    hit = _CAMERAS.get(key)
    if hit is None:
        hit = starcam_scenario.with_updates(camera, {f"world.effects.{n}": v for n, v in values.items()})
        if len(_CAMERAS) > 8:
            _CAMERAS.clear()
        _CAMERAS[key] = hit
    return hit


class SkyValidation(ValidationSettings):
    """Monte Carlo settings (:class:`simcam.config_base.ValidationSettings`, this study's
    defaults): one trial is one pointing."""

    trials: Trials = 1000
    max_trials: Trials = 20000
    batch_trials: BatchTrials = 250


class SkyScenario(ScenarioBase):
    """A star camera on the real sky, its attitude solved (module docstring)."""

    name: str = "seed-000 camera on the real sky, attitude solved"
    camera: str = "embedded:seed000_noisy"
    sky: SkyConfig = SkyConfig()
    onboard: OnboardConfig = OnboardConfig()
    budget: BudgetConfig = BudgetConfig()
    requirement: RequirementConfig = RequirementConfig()
    validation: SkyValidation = SkyValidation()
    world: AttitudeWorld = AttitudeWorld()

    _camera_scenario: starcam_scenario.Scenario | None = PrivateAttr(default=None)

    @field_validator("camera")
    @classmethod
    def _camera_loads(cls, v: str) -> str:
        if not v.strip():
            raise ValueError("name a star-camera scenario: 'embedded:NAME' or a file path")
        try:
            load_camera(v)
        except ScenarioError as exc:
            raise ValueError(f"the star-camera scenario {v!r} cannot be loaded: {exc}") from None
        return v

    @model_validator(mode="after")
    def _keep_camera(self) -> SkyScenario:
        self._camera_scenario = flown_camera(load_camera(self.camera), self.world.effects)
        return self

    def pinned_instrument(self) -> str | None:
        """The flown camera's pixel maps serve every pointing unless its
        ``validation.new_maps_per_trial`` draws them per trial (its onboard calibration's
        errors are each pointing's own unless ``validation.instrument_seed`` pins them)."""
        own = super().pinned_instrument()
        if own is not None or self.camera_scenario.validation.new_maps_per_trial:
            return own
        return ("the flown camera's pixel maps, one draw of its scenario seed (each pointing draws its onboard "
                "calibration)")

    @property
    def camera_scenario(self) -> starcam_scenario.Scenario:
        """The flown star camera's scenario (loaded when this scenario was validated), with this
        scenario's in-orbit world effects (:func:`flown_camera`)."""
        return self._camera_scenario

    @property
    def hash(self) -> str:
        """SHA-256 prefix of this scenario's canonical JSON together with the flown camera's
        scenario hash (a changed camera file is a different scenario)."""
        payload = json.dumps({"sky": model_hash(self), "camera": self.camera_scenario.hash}, sort_keys=True)
        return hashlib.sha256(payload.encode()).hexdigest()[:16]


def default_text() -> str:
    """The embedded default scenario (TOML with comments)."""
    return resources.files("simcam.data").joinpath(DEFAULT_RESOURCE).read_text(encoding="utf-8")


def from_dict(data: dict, *, source: str = "scenario") -> SkyScenario:
    """Validate a mapping; errors are :class:`ScenarioError` lines naming ``source`` and the field."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: top level must be a table")
    return validate_model(SkyScenario, data, source=source).with_source(source)


#: the name of the embedded default (``budget attitude validate embedded:default``, a claim's scenario)
EMBEDDED_DEFAULT = "embedded:default"


def load(path: str | Path | None = None) -> SkyScenario:
    """The scenario file at ``path`` (strict TOML, :func:`simcam.config_base.read_toml`) or,
    for None or :data:`EMBEDDED_DEFAULT`, the embedded default."""
    if isinstance(path, str) and path == EMBEDDED_DEFAULT:
        path = None
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="attitude")


def default() -> SkyScenario:
    """The embedded default scenario."""
    return load(None)
