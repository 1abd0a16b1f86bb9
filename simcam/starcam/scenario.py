"""Star-camera scenario: typed, frozen models of the camera, lab and run, loaded from TOML.

A scenario describes the camera (plate scale or focal length and pixel pitch, aperture,
exposure), its optics (camera PSF, distortion, lateral colour), the detector (two-chip
mosaic, noise, ADC), the lab (light source, filters, collimator and targets, hexapod)
and how to render (window and stamp sizes, wavelength sampling). Every key has a
documented default: the seed-000 camera and lab (``simcam scenario`` prints the resolved
values as TOML that ``simcam render`` accepts back).

The camera's own sections (camera, optics, detector, render) are defined in
:mod:`simcam.starcam.instrument`. Errors are :class:`simcam.infra.errors.ScenarioError`
naming the file and the dotted field, e.g. ``scenario.toml: detector.read_noise_e: Input
should be greater than or equal to 0 (got -1.0)``.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import tomli_w
from pydantic import ConfigDict, Field, field_validator, model_validator

from simcam.config_base import ScenarioBase, ValidationSettings, model_hash, read_toml, validate_model
from simcam.dotted import scenario_with
from simcam.effects import EffectsBase, WorldBase
from simcam.infra.errors import ScenarioError
from simcam.spectra import SpectraError, star_teff_k

# the camera's own sections live in their own module (the lens simulator validates them)
from simcam.starcam.instrument import CameraModel, DetectorModel, Finite, NonNeg, OpticsModel, Pair, Pos, RenderModel
from simcam.starcam.instrument import SectionModel as _Model


# --------------------------------------------------------------------------- lab
class SourceModel(_Model):
    """Light behind the target: a lamp (blackbody) or a star-like spectrum.

    The source is scaled so that, with no filter, each pinhole gives the camera as many
    electrons per exposure as a star of ``match_v_mag`` and ``match_spectral_type``.
    ``kind = "star"`` gives the pinholes that star's own spectrum: a blackbody at the
    Teff of ``match_spectral_type``, or at ``star_temperature_k`` when given.
    """

    kind: Literal["lamp", "star"] = "lamp"
    temperature_k: Annotated[float, Field(ge=1000.0, le=60000.0)] = 2856.0
    match_v_mag: Finite = 7.5
    match_spectral_type: str = "G2V"
    star_temperature_k: Annotated[float, Field(ge=1000.0, le=60000.0)] | None = None

    @model_validator(mode="after")
    def _known_type(self) -> SourceModel:
        try:
            star_teff_k(spectral_type=self.match_spectral_type)
        except SpectraError as exc:
            raise ValueError(f"match_spectral_type: {exc}") from None
        return self


class FilterModel(_Model):
    """Interference filter in front of the target (flat top, smooth edges, FWHM = width)."""

    center_nm: Pos
    width_nm: Pos
    peak_transmission: Annotated[float, Field(gt=0.0, le=1.0)] = 0.9


class CollimatorModel(_Model):
    """Collimator that projects the target to infinity."""

    focal_length_mm: Pos = 1000.0


class PinholeGridModel(_Model):
    """Back-lit pinhole target in the collimator focal plane (seed 000: 5 x 5)."""

    rows: Annotated[int, Field(ge=1, le=64)] = 5
    cols: Annotated[int, Field(ge=1, le=64)] = 5
    spacing_mm: Pos = 2.0
    pinhole_diameter_um: NonNeg = 15.0
    marker_error_3sigma_um: NonNeg = Field(0.0, le=1e4, description="at most 1 cm: a pinhole's position on its plate")


class CalibrationGridModel(_Model):
    """Pre-calibrated grid target for the distortion test (seed 000: 32 points).

    Points on a ``rows x cols`` grid spanning ``extent_fraction`` of the mosaic; their
    reference coordinates carry a marker calibration error of ``marker_error_3sigma_arcsec``
    (seed 000's C2: 0.5" 3 sigma from a total station).
    """

    rows: Annotated[int, Field(ge=2, le=64)] = 4
    cols: Annotated[int, Field(ge=2, le=64)] = 8
    extent_fraction: Annotated[float, Field(gt=0.0, le=1.0)] = 0.85
    pinhole_diameter_um: NonNeg = 15.0
    marker_error_3sigma_arcsec: NonNeg = Field(0.5, le=3600.0, description="at most 1 deg: a marker's position")


class PlatformModel(_Model):
    """Hexapod carrying the camera (seed 000: PI H-840).

    Poses are image displacements in px; the positioning error is Gaussian with the given
    rms per axis, drawn per pose from the run seed.
    """

    positioning_noise_px: NonNeg = Field(0.0, le=1000.0, description="at most 1000 px: a pose error on the chip")


class LabKnowledgeModel(_Model):
    """What the lab *believes* about the camera's spectral response.

    The improved LSFE-S estimator needs effective wavelengths of the lamp through each
    filter, of the calibration spectrum and of the stellar population; a lab computes them
    from its own models (data sheets, filter certificates, a spectral library), which
    differ from the camera's true ones. Each field is a stated error, the lab's value minus
    the true one: ``qe_peak_nm_error`` (the QE curve's peak wavelength), ``filter_center_nm_error``
    (every filter's centre), ``filter_width_nm_error`` (every filter's FWHM),
    ``lamp_temperature_k_error`` (the lamp's colour temperature) and
    ``star_teff_fraction_error`` (the spectral model's effective temperature of each
    stellar type, as a fraction: Teff_lab = Teff (1 + e)). All zero: the lab knows the
    camera exactly (the estimator then shares the simulator's spectral inputs).
    """

    qe_peak_nm_error: Finite = Field(20.0, ge=-1000.0, le=1000.0, description="within +-1000 nm: the lab's curves")
    filter_center_nm_error: Finite = Field(3.0, ge=-1000.0, le=1000.0, description="within +-1000 nm, as qe_peak")
    filter_width_nm_error: Finite = Field(2.0, ge=-1000.0, le=1000.0, description="within +-1000 nm, as qe_peak")
    lamp_temperature_k_error: Finite = Field(50.0, ge=-1e4, le=1e4, description="within +-10000 K: a lamp's colour")
    star_teff_fraction_error: Annotated[float, Field(gt=-0.5, lt=0.5, allow_inf_nan=False)] = 0.03


class LabModel(_Model):
    """The lab: source, filters, collimator, targets, platform, target placement, and the
    lab's own (imperfect) knowledge of the camera's spectral response (``knowledge``)."""

    source: SourceModel = SourceModel()
    filters: Annotated[tuple[FilterModel, ...], Field(strict=False)] = (
        FilterModel(center_nm=500.0, width_nm=100.0),
        FilterModel(center_nm=600.0, width_nm=100.0),
        FilterModel(center_nm=800.0, width_nm=100.0),
    )
    collimator: CollimatorModel = CollimatorModel()
    target: PinholeGridModel = PinholeGridModel()
    calibration_target: CalibrationGridModel = CalibrationGridModel()
    platform: PlatformModel = PlatformModel()
    target_center_px: Pair = (-1024.0, 0.0)
    knowledge: LabKnowledgeModel = LabKnowledgeModel()

    @model_validator(mode="after")
    def _filters(self) -> LabModel:
        centres = [f.center_nm for f in self.filters]
        if len(set(centres)) != len(centres):
            raise ValueError(f"filters: two filters share a centre wavelength ({centres})")
        return self


class TEProtocolModel(_Model):
    """TE plan (seed 000 eqs 1-2): a static target, ``frames`` >= 2 (the seed asks N >= 30)."""

    frames: Annotated[int, Field(ge=2)] = 30


class HSFEProtocolModel(_Model):
    """HSFE plan (seed 000 eqs 3-12): ``conditions`` hexapod poses of the target's image,
    ``frames`` frames each, in one of two step patterns (``pattern``):

    * ``"diagonal"`` (seed 000, the default): each pose moves the image by ``step_px`` along
      ``direction_deg`` (from +x toward +y) from the previous one;
    * ``"grid"``: the poses lie on a square grid of pitch ``grid_step_px`` in x and y from the
      first pose (unset: ``1 + 1/conditions`` px), one pose in each column and each row: pose
      ``k`` (0-based) in column ``k`` and row ``(a k) mod M`` (``M = conditions``; ``a`` the
      integer nearest ``M / phi``, golden ratio ``phi``, that is coprime with ``M``: a rank-1
      Fibonacci-type lattice, Korobov's construction, which spreads the poses evenly over the
      square). With the default pitch the ``M`` poses fall on ``M`` different pixels in x and
      in y, at sub-pixel phases ``1/M`` apart in each axis, so both the pixel-phase error and
      each pixel's own response (PRNU, DSNU) vary over the poses and no part of the static
      error stays constant over them (docs/validation.md, "Planning the test"). ``step_px``
      and ``direction_deg`` are not used.
    """

    pattern: Literal["diagonal", "grid"] = "diagonal"
    conditions: Annotated[int, Field(ge=2)] = 12
    frames: Annotated[int, Field(ge=1)] = 30
    step_px: Finite = 0.2
    direction_deg: Finite = 45.0
    grid_step_px: Finite | None = None

    @property
    def grid_pitch_px(self) -> float:
        """The grid's pitch in px (``grid_step_px``, or ``1 + 1/conditions`` when unset)."""
        return float(self.grid_step_px) if self.grid_step_px is not None else 1.0 + 1.0 / self.conditions

    @property
    def grid_multiplier(self) -> int:
        """The lattice's multiplier ``a``: the integer nearest ``M / phi`` coprime with ``M``
        (the nearer of the two candidates on either side, the smaller on a tie)."""
        m = self.conditions
        target = m / ((1.0 + math.sqrt(5.0)) / 2.0)
        cands = [a for a in range(1, m) if math.gcd(a, m) == 1] or [1]
        return min(cands, key=lambda a: (abs(a - target), a))

    def grid_offsets_px(self) -> tuple[tuple[float, float], ...]:
        """Commanded image offsets (px) of the grid pattern's poses, in acquisition order:
        pose ``k`` at ``(k, (a k) mod M)`` grid steps."""
        m, s, a = self.conditions, self.grid_pitch_px, self.grid_multiplier
        return tuple((k * s, ((a * k) % m) * s) for k in range(m))


#: most filter sets ``budget starcam plan`` compares (``protocols.chromatic.plan_filter_sets``)
MAX_PLAN_FILTER_SETS = 8


def _filter_list(v: tuple, what: str = "") -> tuple:
    at = f"{what}: " if what else ""
    if len(set(v)) != len(v):
        raise ValueError(f"{at}a filter is listed twice")
    if len(v) < 2:
        raise ValueError(f"{at}needs at least 2 filters (a difference to the reference filter)")
    return v


class ChromaticProtocolModel(_Model):
    """Chromatic plan (seed 000 eqs 13-16): the target at each field centre, behind each of
    the test's filters (``filters_nm``: centre wavelengths among ``lab.filters``; empty, the
    default: every lab filter, seed 000's 500, 600 and 800 nm), ``frames`` frames each.

    ``plan_filter_sets``: the filter sets ``budget starcam plan`` compares as protocol shapes
    (each a list of centres as ``filters_nm``); empty (the default): every set of at least 2
    lab filters that holds the reference, at most :data:`MAX_PLAN_FILTER_SETS` of them.
    Membership in ``lab.filters`` and the reference are checked against the whole scenario
    (:func:`check_chromatic_filters`).
    """

    frames: Annotated[int, Field(ge=1)] = 30
    field_centers_px: Annotated[tuple[Pair, ...], Field(strict=False, min_length=1)] = (
        (-1700.0, -700.0),
        (1700.0, -700.0),
        (-1700.0, 700.0),
        (1700.0, 700.0),
    )
    field_names: Annotated[tuple[str, ...], Field(strict=False)] = (
        "upper-left",
        "upper-right",
        "lower-left",
        "lower-right",
    )
    reference_filter_nm: Pos = 600.0
    filters_nm: Annotated[tuple[Pos, ...], Field(strict=False)] = ()
    plan_filter_sets: Annotated[tuple[Annotated[tuple[Pos, ...], Field(strict=False)], ...],
                                Field(strict=False)] = ()

    @field_validator("filters_nm")
    @classmethod
    def _filters_nm(cls, v: tuple) -> tuple:
        return _filter_list(v) if v else v

    @field_validator("plan_filter_sets")
    @classmethod
    def _plan_sets(cls, v: tuple) -> tuple:
        for k, fs in enumerate(v):
            _filter_list(fs, f"set {k}")
        seen = [frozenset(fs) for fs in v]
        if len(set(seen)) != len(seen):
            raise ValueError(f"a filter set is listed twice ({[list(fs) for fs in v]})")
        if len(v) > MAX_PLAN_FILTER_SETS:
            raise ValueError(f"{len(v)} filter sets: a plan compares at most {MAX_PLAN_FILTER_SETS}")
        return v

    @model_validator(mode="after")
    def _names(self) -> ChromaticProtocolModel:
        if len(self.field_names) != len(self.field_centers_px):
            raise ValueError(
                f"field_names has {len(self.field_names)} names for "
                f"{len(self.field_centers_px)} field_centers_px"
            )
        return self


class DistortionProtocolModel(_Model):
    """Distortion plan (seed 000 eqs 17-30): the calibration grid, ``frames`` frames."""

    frames: Annotated[int, Field(ge=1)] = 30


class LabTimingModel(_Model):
    """How long the lab's steps take, in seconds: the lab time of a protocol
    (:meth:`budget.starcam.study.StarCameraStudy.lab_time_s`, what ``budget starcam plan``
    minimises). Seed 000 gives no times; these are typical values. The simulated world never
    reads them (the drift's timeline has its own ``world.frame_overhead_s``, ``settle_s``,
    ``setup_s``, whose defaults these match).

    * ``frame_readout_s``: readout and transfer of a frame beyond ``camera.exposure_s`` (a
      2048 x 2048 CMOS at 12 bit reads out in 25-50 ms; the world's 0.05 s);
    * ``hexapod_move_s``: one hexapod move between poses (a micro-radian rotation of a PI
      H-840 class hexapod, commanding included: about 1-3 s);
    * ``settle_s``: the wait after a move or a filter change before the first frame (the
      hexapod's and the mount's settling to sub-arcsecond; with a move, the world's 10 s);
    * ``filter_change_s``: one change of the filter in front of the target (a motorised
      filter wheel: 1-3 s);
    * ``dark_switch_s``: closing and reopening the source's shutter around a condition's
      dark frames (``validation.dark_frames > 0``);
    * ``protocol_setup_s``: changing target and aligning between protocols (the world's 300 s);
    * ``source_warmup_s``: warm-up of the lamp before the first frame of a run (a
      quartz-tungsten-halogen source stabilises in 15-30 min).
    """

    frame_readout_s: NonNeg = 0.05
    hexapod_move_s: NonNeg = 2.0
    settle_s: NonNeg = 8.0
    filter_change_s: NonNeg = 2.0
    dark_switch_s: NonNeg = 2.0
    protocol_setup_s: NonNeg = 300.0
    source_warmup_s: NonNeg = 900.0


#: the counts of the seed-000 protocols a plan may change (``protocols.plan_knobs``): TE frames,
#: HSFE frames per pose, HSFE poses (``protocols.hsfe.conditions``, in either pattern),
#: chromatic frames per field and filter, distortion frames, dark frames per condition
#: (``validation.dark_frames``); and, named only where a plan lists it, the calibration grid's
#: extent (``distortion.extent``, ``lab.calibration_target.extent_fraction``)
PLAN_KNOBS = ("te.frames", "hsfe.frames", "hsfe.poses", "chromatic.frames", "distortion.frames", "dark_frames",
              "distortion.extent")
#: the knobs a plan changes by default: the counts (seed 000's grid extent stays as published)
DEFAULT_PLAN_KNOBS = PLAN_KNOBS[:6]


class ProtocolsModel(_Model):
    """Acquisition plans of the seed-000 lab tests (data, read by budget.starcam.protocols),
    how long the lab's steps take (``timing``) and which counts ``budget starcam plan`` may
    change (``plan_knobs``, a list of names of :data:`PLAN_KNOBS`; default the six counts,
    :data:`DEFAULT_PLAN_KNOBS`; the others stay as the scenario gives them, e.g. a lab that plans
    only its HSFE test, or keeps seed 000's calibration grid extent)."""

    te: TEProtocolModel = TEProtocolModel()
    hsfe: HSFEProtocolModel = HSFEProtocolModel()
    chromatic: ChromaticProtocolModel = ChromaticProtocolModel()
    distortion: DistortionProtocolModel = DistortionProtocolModel()
    timing: LabTimingModel = LabTimingModel()
    plan_knobs: Annotated[tuple[Literal[PLAN_KNOBS], ...], Field(strict=False)] = DEFAULT_PLAN_KNOBS

    @field_validator("plan_knobs")
    @classmethod
    def _unique_knobs(cls, v: tuple) -> tuple:
        if not v:
            raise ValueError("name at least one count to plan")
        if len(set(v)) != len(v):
            raise ValueError(f"a name is listed twice ({list(v)})")
        return v


#: the seed-000 lab protocols, in acquisition order (``validation.protocols`` names those a
#: validation computes; :data:`budget.starcam.protocols.PROTOCOLS`)
LAB_PROTOCOLS = ("te", "hsfe", "chromatic", "distortion")


class ValidationModel(ValidationSettings):
    """Monte Carlo validation settings (read by budget.starcam.validate).

    * ``trials`` / ``tolerance`` / ``max_trials`` / ``batch_trials``: as every scenario
      (:class:`simcam.config_base.ValidationSettings`): a fixed number of trials, or batches
      until the Monte Carlo standard error of every bias and spread (arcsec, 3 sigma) is
      below the tolerance (JCGM 101 section 7.9), with a cap;
    * ``instrument_seed`` (:class:`simcam.config_base.ValidationSettings`): None (the
      default), every trial draws its own camera: its PRNU/DSNU maps (with
      ``new_maps_per_trial``, the default) and the errors of its onboard distortion
      calibration (``budget.starcam.setup.instrument_seeds``); an integer pins one camera,
      maps and calibration, for every trial and run seed (the pin fixes the maps whatever
      ``new_maps_per_trial`` says: :attr:`maps_per_trial`);
    * ``new_maps_per_trial``: draw the PRNU/DSNU maps with each trial's camera (the default):
      TE's and HSFE's truths are then each trial's camera's own (HSFE's over
      ``hsfe_trial_phases`` sub-pixel phases of the ``hsfe_phase_grid`` grid drawn per trial,
      an unbiased sample of the grid's mean square, docs/validation.md); False keeps the
      scenario seed's maps for every trial, and the report says the pixels are that one draw;
    * ``new_markers_per_trial``: draw the calibration grid target's marker errors in every
      trial (default; else fixed by the scenario seed: the target is the lab's, not the
      camera's); the hexapod positioning error is drawn per trial whenever
      ``lab.platform.positioning_noise_px > 0``;
    * ``centroid_method``, ``threshold_sigma``, ``dark_frames``: how the lab centroids;
    * truth sampling: ``te_truth_frames`` noise-only frames, ``hsfe_phase_grid`` sub-pixel
      phases per axis with ``hsfe_truth_frames`` noisy frames each (even: two halves; a
      trial's own HSFE truth takes ``hsfe_trial_phases`` of those phases),
      ``lsfe_spectral_types`` (the stellar population, equal weights) and
      ``calibration_spectrum`` (the reference of the chromatic displacement:
      ``population_mean``, the default, the mean over the population at each field point,
      since the population's common offset is calibrated at system level (seed 000); or
      ``lamp``, the lab source without filter; or a spectral type), ``field_grid``
      points per axis for the field averages;
    * ``protocols``: the protocols a validation runs (default all four, :data:`LAB_PROTOCOLS`);
      a subset computes only the classes they give (TE: te; HSFE: hsfe; chromatic: lsfe_s;
      distortion: lsfe_c1; LSFE needs chromatic and distortion, the total all four; LSFE-C2,
      an input, always), with the same numbers for them as a run of all four on the same seed,
      and only those classes' truths. What the lab does is unchanged (its lab time, the
      world's timeline): it says what is computed, not what the lab runs.
    """

    model_config = _Model.model_config

    new_maps_per_trial: bool = True
    new_markers_per_trial: bool = True
    centroid_method: Literal["cog", "iwcog", "gauss"] = "cog"
    threshold_sigma: Pos = Field(3.0, le=1000.0, description="at most 1000 noise sigmas: above it no pixel is kept")
    dark_frames: Annotated[int, Field(ge=0)] = 0
    te_truth_frames: Annotated[int, Field(ge=10)] = 1000
    hsfe_truth_frames: Annotated[int, Field(ge=4, multiple_of=2)] = 400
    hsfe_phase_grid: Annotated[int, Field(ge=2, le=32)] = 8
    hsfe_trial_phases: Annotated[int, Field(ge=1)] = 4
    lsfe_spectral_types: Annotated[tuple[str, ...], Field(strict=False, min_length=1)] = (
        "B5V", "A0V", "A5V", "F0V", "F5V", "G0V", "G5V", "K0V", "K5V", "M0V", "M5V",
    )
    calibration_spectrum: str = "population_mean"
    field_grid: Annotated[int, Field(ge=2, le=64)] = 9
    protocols: Annotated[tuple[Literal[LAB_PROTOCOLS], ...], Field(strict=False)] = LAB_PROTOCOLS

    @field_validator("protocols")
    @classmethod
    def _protocols(cls, v: tuple) -> tuple:
        if not v:
            raise ValueError(f"name at least one protocol (of {', '.join(LAB_PROTOCOLS)})")
        if len(set(v)) != len(v):
            raise ValueError(f"a protocol is listed twice ({list(v)})")
        return v

    @property
    def maps_per_trial(self) -> bool:
        """Whether every trial draws its camera's PRNU/DSNU maps: ``new_maps_per_trial`` and no
        ``instrument_seed`` pinning one camera (whose maps serve every trial)."""
        return self.new_maps_per_trial and self.instrument_seed is None

    def pinned_instrument(self) -> str | None:
        """The pixel maps of the scenario seed serve every trial when ``new_maps_per_trial`` is
        false (the calibration errors are each trial's own unless ``instrument_seed`` pins them)."""
        pinned = super().pinned_instrument()
        if pinned is not None or self.new_maps_per_trial:
            return pinned
        return ("the scenario seed's pixel maps, PRNU and DSNU (validation.new_maps_per_trial = false); "
                "each trial draws its onboard calibration")

    @model_validator(mode="after")
    def _trial_phases_in_grid(self) -> ValidationModel:
        if self.hsfe_trial_phases > self.hsfe_phase_grid**2:
            raise ValueError(f"hsfe_trial_phases: {self.hsfe_trial_phases} is more than the "
                             f"{self.hsfe_phase_grid**2} phases of hsfe_phase_grid = {self.hsfe_phase_grid}")
        return self

    @model_validator(mode="after")
    def _known_types(self) -> ValidationModel:
        names = list(self.lsfe_spectral_types) + ([] if self.calibration_spectrum in ("lamp", "population_mean")
                                                   else [self.calibration_spectrum])
        for st in names:
            try:
                star_teff_k(spectral_type=st)
            except SpectraError as exc:
                raise ValueError(f"spectral type {st!r}: {exc}") from None
        return self


# --------------------------------------------------------------------------- world
class StarCameraEffects(EffectsBase):
    """What the simulated star camera and lab have and the seed-000 lab methods do not model.

    Each field is one effect's magnitude (0 = off); the default is the sourced realistic
    value, so the default scenario is the realistic world and ``budget validate`` answers the
    real question. The model forms are in :mod:`simcam.starcam.world` (hexapod, drift),
    :class:`simcam.starcam.optics.HigherOrderRadialDistortion` (distortion beyond the cubic)
    and :mod:`simcam.detector` (non-linearity). Sources: Janesick, *Photon Transfer*,
    SPIE PM170 (2007), ch. 7; Gpixel GSENSE4040 data sheet; Andor sCMOS architecture notes;
    the project's traced lens ``embedded:star_camera`` (docs/lens.md). The ranges beside the
    fields: the distortion terms within +-100 px at the corner (beyond, stars leave the
    mosaic), beta in (-1, 1) (``s (1 - beta s / FW)`` stays monotonic), the hexapod's and
    the drift's sizes at most 60 arcsec (10 px per move at the plate scale, 100 x the data sheets).
    """

    distortion_r5_px_at_corner: float = Field(
        1.47, ge=-100.0, le=100.0, description="traced embedded lens (embedded:star_camera): fifth-order radial distortion 1.47 px at "
        "the mosaic corner (3.5 deg) in a r, r^3, r^5, r^7 fit of its traced image heights, which no cubic removes "
        "(sized at the corner of the scenario's mosaic; not added when optics.lens traces a lens, which has its own)")
    distortion_r7_px_at_corner: float = Field(
        0.081, ge=-100.0, le=100.0, description="traced embedded lens (embedded:star_camera): seventh-order radial distortion 0.081 px "
        "at the mosaic corner in the same fit")
    nonlinearity_beta: float = Field(
        0.008, gt=-1.0, lt=1.0, description="CMOS integral non-linearity 0.2 % of full scale typical (Gpixel GSENSE4040 data "
        "sheet; Janesick, Photon Transfer, ch. 7): s_out = s (1 - beta s / FW), INL = beta / 4, so beta = 0.008")
    hexapod_repeatability_arcsec: float = Field(
        0.5, ge=0.0, le=60.0, description="hexapod rotation repeatability per move, 1 sigma per axis (PI H-840 class: 2-5 urad, "
        "0.4-1 arcsec; engineering estimate, data sheet not retrieved)")
    hexapod_backlash_arcsec: float = Field(
        1.0, ge=0.0, le=60.0, description="hexapod rotation backlash b (error b sign(move) per commanded axis): about 1 um of "
        "strut lost motion over a 0.2 m joint separation, 5 urad (engineering estimate)")
    drift_rate_arcsec_per_h: float = Field(
        0.05, ge=0.0, le=60.0, description="collimator/target thermal drift ramp, 0.02-0.2 arcsec/h at 20 +- 1 C (an Al mount, "
        "50 mm lever, 0.1 K/h in a 1 m collimator gives 0.024 arcsec/h; engineering estimate)")
    drift_random_arcsec: float = Field(
        0.03, ge=0.0, le=60.0, description="collimator/target drift, first-order Gauss-Markov part: stationary sigma per axis "
        "(same thermal budget as the ramp, wandering over world.drift_time_constant_s; engineering estimate)")


class StarCameraWorld(WorldBase):
    """The star camera's world beyond the lab's model: ``effects`` (magnitudes,
    :class:`StarCameraEffects`) and the settings of their model forms. The lab side (the
    protocols' plans and the estimators) never reads it; the simulator and the truths do.

    * ``drift_time_constant_s``: correlation time of the drift's Gauss-Markov part (0.5-2 h);
    * the frame timeline of a lab run, from which each frame's time follows (the drift is a
      function of time): a frame takes ``camera.exposure_s + frame_overhead_s`` (readout);
      each condition starts ``settle_s`` after the previous one ends (a hexapod move or a
      filter change and the wait for it to settle); each protocol ``setup_s`` after the
      previous protocol (target change, alignment). The protocols run in the order TE, HSFE,
      chromatic, distortion (:data:`budget.starcam.protocols.PROTOCOLS`).
    """

    effects: StarCameraEffects = StarCameraEffects()
    drift_time_constant_s: Pos = 3600.0
    frame_overhead_s: NonNeg = 0.05
    settle_s: NonNeg = 10.0
    setup_s: NonNeg = 300.0


class Scenario(ScenarioBase):
    """A complete star-camera + lab scenario (see module docstring)."""

    name: str = "seed-000 sub-arcsec star camera, lab"
    seed: Annotated[int, Field(ge=0)] = 20180405
    camera: CameraModel = CameraModel()
    optics: OpticsModel = OpticsModel()
    detector: DetectorModel = DetectorModel()
    lab: LabModel = LabModel()
    render: RenderModel = RenderModel()
    protocols: ProtocolsModel = ProtocolsModel()
    validation: ValidationModel = ValidationModel()
    world: StarCameraWorld = StarCameraWorld()

    @model_validator(mode="before")
    @classmethod
    def _lens(cls, data: Any) -> Any:
        # optics.lens: trace the lens (or read its cached tables) and fill what it sets
        if isinstance(data, dict):
            optics = data.get("optics")
            lens = optics.get("lens") if isinstance(optics, dict) else getattr(optics, "lens", None)
            if lens is not None:
                from simcam.starcam.lens.simulator import apply_lens

                return apply_lens(data)
        return data

    @model_validator(mode="after")
    def _cross(self) -> Scenario:
        refs = [f.center_nm for f in self.lab.filters]
        if self.lab.filters and self.protocols.chromatic.reference_filter_nm not in refs:
            raise ValueError(
                f"protocols.chromatic.reference_filter_nm = {self.protocols.chromatic.reference_filter_nm} "
                f"is not one of lab.filters centres {refs}"
            )
        return self

    def chromatic_filters_nm(self) -> tuple[float, ...]:
        """The chromatic test's filter centres, in ``lab.filters`` order: those of
        ``protocols.chromatic.filters_nm``, or every lab filter when it is empty."""
        chosen = self.protocols.chromatic.filters_nm
        return tuple(f.center_nm for f in self.lab.filters if not chosen or f.center_nm in chosen)

    @model_validator(mode="after")
    def _world_hexapod_once(self) -> Scenario:
        # lab.platform.positioning_noise_px and the world's hexapod repeatability describe the
        # same tip/tilt pose error: give it once (docs/validation.md, "World effects")
        if self.lab.platform.positioning_noise_px > 0 and self.world.effects.hexapod_repeatability_arcsec != 0:
            raise ValueError(
                "lab.platform.positioning_noise_px and world.effects.hexapod_repeatability_arcsec both describe "
                "the hexapod's pose error: set one of them to 0 (the world effect also has the rotation about "
                "the optical axis, backlash and an error on every move)")
        return self

    def derived_paths(self) -> tuple[str, ...]:
        """What ``optics.lens`` sets (:data:`simcam.starcam.lens.simulator.LENS_DERIVED_PATHS`)
        when a lens is given; nothing without one."""
        if self.optics.lens is None:
            return ()
        from simcam.starcam.lens.simulator import LENS_DERIVED_PATHS

        return LENS_DERIVED_PATHS

    def to_toml(self) -> str:
        """The resolved scenario as TOML that :func:`load` accepts back (:func:`scenario_to_toml`)."""
        return scenario_to_toml(self)

    @cached_property
    def hash(self) -> str:
        """Scenario hash: SHA-256 prefix of the canonical JSON of the resolved scenario
        (without ``optics.lens`` when it is unset, so analytic scenarios keep their hash)."""
        if self.optics.lens is not None:
            return model_hash(self)
        payload = json.dumps(self.model_dump(mode="json", exclude={"optics": {"lens"}}), sort_keys=True,
                             separators=(",", ":"))
        return hashlib.sha256(payload.encode()).hexdigest()[:16]

    model_config = ConfigDict(
        extra="forbid", frozen=True, strict=True, validate_default=True, ignored_types=(cached_property,)
    )


# --------------------------------------------------------------------------- I/O
DEFAULT_RESOURCE = "default_scenario.toml"


def _strip_none(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _strip_none(v) for k, v in obj.items() if v is not None}
    if isinstance(obj, (list, tuple)):
        return [_strip_none(v) for v in obj]
    return obj


def default_text() -> str:
    """The embedded seed-000 default scenario (TOML with comments)."""
    return resources.files("simcam.data").joinpath(DEFAULT_RESOURCE).read_text()


def from_dict(data: dict[str, Any], *, source: str = "scenario") -> Scenario:
    """Validate a dict (parsed TOML) into a :class:`Scenario`, or raise ScenarioError."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source or 'scenario'}: top level must be a table")
    optics = data.get("optics")
    if isinstance(optics, dict) and optics.get("lens") is not None:
        # resolve the lens here too, so that its errors read "file: field: message"
        from simcam.starcam.lens.simulator import apply_lens

        try:
            data = apply_lens(data)
        except ValueError as exc:
            raise ScenarioError(f"{source or 'scenario'}: {exc}") from None
    scn = validate_model(Scenario, data, source=source).with_source(source)
    _check_derived_finite(scn, source=source)
    check_chromatic_filters(scn, source=source)
    return scn


def check_chromatic_filters(scn: "Scenario", *, source: str | None = None) -> None:
    """``protocols.chromatic.filters_nm`` and ``plan_filter_sets`` against the lab: every centre
    one of ``lab.filters``' and every set holding ``reference_filter_nm`` (the differences of
    eqs 13-16 are taken to it); one ScenarioError naming the field."""
    c = scn.protocols.chromatic
    lab = [f.center_nm for f in scn.lab.filters]
    ref = c.reference_filter_nm
    where = f"{source or 'scenario'}: protocols.chromatic"
    for name, sets in (("filters_nm", [c.filters_nm] if c.filters_nm else []),
                       ("plan_filter_sets", list(c.plan_filter_sets))):
        for k, fs in enumerate(sets):
            at = f"{where}.{name}" + (f" (set {k})" if name == "plan_filter_sets" else "")
            bad = [f for f in fs if f not in lab]
            if bad:
                raise ScenarioError(f"{at}: {bad} not among lab.filters centres {lab}")
            if ref not in fs:
                raise ScenarioError(f"{at}: {list(fs)} lacks the reference filter "
                                    f"(protocols.chromatic.reference_filter_nm = {ref:g})")


def _check_derived_finite(scn: "Scenario", *, source: str | None) -> None:
    """Input check: products of fields that overflow (e.g. ``exposure_s = 1e308``) are
    reported against the fields, not as a derived quantity deep in the simulator."""
    dark = scn.detector.dark_current_e_per_s * scn.camera.exposure_s
    if not math.isfinite(dark):
        raise ScenarioError(f"{source or 'scenario'}: camera.exposure_s = {scn.camera.exposure_s:g}: the dark charge "
                            f"per exposure (x detector.dark_current_e_per_s = {scn.detector.dark_current_e_per_s:g}) "
                            "overflows; give an exposure in seconds")


#: embedded scenarios selectable as ``embedded:NAME`` (resources of simcam.data)
EMBEDDED_SCENARIOS = {"default": DEFAULT_RESOURCE, "seed000_noisy": "seed000_noisy.toml",
                      "seed000_ideal": "seed000_ideal.toml"}


def load(path: str | Path | None = None) -> Scenario:
    """Load a scenario TOML file (strict: :func:`simcam.config_base.read_toml`); ``None``
    gives the embedded seed-000 default, and ``"embedded:NAME"`` an embedded scenario of
    :data:`EMBEDDED_SCENARIOS` (``default``; ``seed000_noisy``: the seed-000 camera with the
    seed's own noise and pixel errors)."""
    if isinstance(path, str) and path.startswith("embedded:"):
        name = path.split(":", 1)[1]
        if name not in EMBEDDED_SCENARIOS:
            raise ScenarioError(f"{path}: no embedded scenario {name!r} "
                                f"(have {', '.join(sorted(EMBEDDED_SCENARIOS))})")
        text = resources.files("simcam.data").joinpath(EMBEDDED_SCENARIOS[name]).read_text()
        source = f"<embedded {EMBEDDED_SCENARIOS[name]}>"
    elif path is None:
        text = default_text()
        source = f"<embedded {DEFAULT_RESOURCE}>"
    else:
        source = str(path)
        return from_dict(read_toml(path=path, source=source), source=source)
    return from_dict(read_toml(text=text, source=source), source=source)


def scenario_source_text(path: str | Path | None = None) -> str | None:
    """The TOML text of a scenario with its comments as :func:`load_scenario` reads it
    (the embedded resource or the file), or None where there is no such text."""
    if path is None:
        return resources.files("simcam.data").joinpath(DEFAULT_RESOURCE).read_text()
    if isinstance(path, str) and path.startswith("embedded:"):
        name = path.split(":", 1)[1]
        return resources.files("simcam.data").joinpath(EMBEDDED_SCENARIOS[name]).read_text() \
            if name in EMBEDDED_SCENARIOS else None
    p = Path(path)
    return p.read_text(encoding="utf-8") if p.is_file() else None


def default() -> Scenario:
    """The embedded seed-000 scenario."""
    return load(None)


def scenario_to_toml(scenario: Scenario) -> str:
    """Resolved scenario as TOML text that :func:`load` accepts back."""
    data = _strip_none(scenario.model_dump(mode="json"))
    text = tomli_w.dumps(data)
    # tomli_w writes every array one item per line; fold arrays of scalars onto one line.
    return _ARRAY_RE.sub(lambda m: "[" + ", ".join(x.strip().rstrip(",") for x in m.group(1).split("\n") if x.strip()) + "]", text)


_ARRAY_RE = re.compile(r"\[\n((?: +[^\[\]{}\n]+,\n)+) *\]")


def with_updates(scenario: Scenario, dotted: dict[str, Any]) -> Scenario:
    """Return a copy with dotted keys replaced (``{"detector.read_noise_e": 5}``), re-validated
    (:func:`simcam.dotted.scenario_with`: what a traced lens sets is derived again unless a key
    sets it; an unknown key is an error naming the scenario's source)."""
    return scenario_with(scenario, dotted, from_dict=from_dict, where=f"{scenario.source}: updated")
