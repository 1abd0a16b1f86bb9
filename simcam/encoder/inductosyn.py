"""Round inductosyn read by amplitude discrimination: the physical angle-error model.

The world side of seed 001 (Dong et al., Infrared and Laser Engineering 48(10) 1013007,
2019). A round inductosyn with ``P`` pole pairs (default 360) is read by an
amplitude-discrimination tracking loop (seed 001 eqs 1-6): the segmented (stator)
windings are excited with ``u_s = U cos(theta_d) sin(wt)`` and
``u_c = -U sin(theta_d) sin(wt)`` (eqs 1-2); the continuous (rotor) winding then carries

    e = k U cos(wt) [cos(theta_d) sin(theta_e) - sin(theta_d) cos(theta_e)]
      = k U cos(wt) sin(theta_e - theta_d)                                    (eq 5)

and the loop drives ``theta_d`` until the demodulated ``e`` is null, so ``theta_d``
follows the electrical angle ``theta_e = P * theta`` (eq 6 and the text below it).

Error sources are *physical imperfections*, never coefficients typed in:

* mechanical (period 360 deg, the "long-period" error of eq 7): eccentricity of the scale
  about the axis of rotation, ellipticity (an elliptical strain of the disk) and tilt of
  the disk; each is the exact geometric angle map given in :func:`mechanical_error_rad`;
* electrical (period one pole pitch, the "short-period" error of eq 8): excitation and
  coupling amplitude imbalance, quadrature (phase) error of the second winding,
  in-phase carrier feed-through ("DC offsets" of the demodulated channels), an offset of
  the phase-sensitive demodulator, and odd spatial harmonics of the windings' coupling
  (the same shape in both windings); the readout null is solved exactly
  (:func:`tracking_null_rad`), and its small-parameter expansion
  (:func:`first_order_electrical_error_rad`) is derived in ``docs/inductosyn.md``;
* optional manufacturing pitch harmonics (the paper's "< 1 arcsec, negligible" term),
  resolution (0.0001 deg in the paper) and reading noise; and a drift of the physical
  parameters (temperature cycling, vibration: seed 001 section 4.3).

The truth is exact at any angle: :meth:`Inductosyn.error_arcsec` (continuous reading
minus true angle at a true shaft angle) and :meth:`Inductosyn.error_at_reading_arcsec`
(the same error as a function of the reading, which is what a calibration in which the
servo holds the encoder reading at the nominal face angle measures, and what eq 9's
compensation ``theta_hat = theta - e(theta)`` needs).
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator
from scipy.optimize import brentq

from simcam.infra.errors import ScenarioError
from simcam.config_base import (BatchTrials, ScenarioBase, StrictModel, Trials, ValidationSettings, load_scenario_file, validate_model)
from simcam.effects import EffectsBase, WorldBase
from simcam.units import ARCSEC_PER_DEG

__all__ = [
    "AutocollimatorParams",
    "CalibrationParams",
    "DriftParams",
    "ElectricalErrors",
    "Inductosyn",
    "InductosynEffects",
    "InductosynParams",
    "InductosynScenario",
    "InductosynWorld",
    "MechanicalErrors",
    "PitchHarmonic",
    "PolygonParams",
    "ValidationParams",
    "WindingHarmonic",
    "apply_drift",
    "channel_signals",
    "default",
    "default_text",
    "demodulated_error",
    "drifted_params",
    "first_order_electrical_error_rad",
    "from_dict",
    "load",
    "mechanical_error_rad",
    "tracking_null_numeric_rad",
    "tracking_null_rad",
    "winding_harmonic_order_map",
    "INSTRUMENT_SPAWN_KEY",
    "instrument_rng",
    "pinned_instrument",
    "world_encoder_params",
    "world_pitch_phases_deg",
    "world_pitch_terms",
]


# --------------------------------------------------------------------------- models
class MechanicalErrors(StrictModel):
    """Imperfections of the scale's geometry (long-period error, seed 001 eq 7).

    Parameters
    ----------
    radius_mm : mean radius of the scale's track.
    eccentricity_um : effective offset of the scale centre from the axis of rotation
        (the part that the full-circle winding does not average out).
    eccentricity_azimuth_deg : shaft angle at which the offset points.
    ellipticity_ppm : elliptical strain ``k`` of the disk (semi-axes ``R(1 +- k)``).
    ellipticity_azimuth_deg : direction of the long semi-axis.
    tilt_deg : tilt of the scale plane to the plane of rotation.
    tilt_azimuth_deg : azimuth of the tilt axis.
    """

    radius_mm: float = Field(100.0, gt=0)
    eccentricity_um: float = Field(0.0, ge=0)
    eccentricity_azimuth_deg: float = 0.0
    ellipticity_ppm: float = Field(0.0, ge=0, lt=1e5)
    ellipticity_azimuth_deg: float = 0.0
    tilt_deg: float = Field(0.0, ge=0, lt=45)
    tilt_azimuth_deg: float = 0.0

    @model_validator(mode="after")
    def _ecc_small(self):
        if self.eccentricity_um * 1e-3 >= 0.5 * self.radius_mm:
            raise ValueError("eccentricity_um must be well below the radius (< radius/2)")
        return self


class WindingHarmonic(StrictModel):
    """Odd spatial harmonic of the windings' coupling function.

    Both windings share the coupling shape ``f(x) = sin x + h sin(n x + phi)``
    (the sine winding sees ``f(theta_e)``, the cosine winding ``f(theta_e + 90 deg)``).

    Parameters
    ----------
    order : odd harmonic number ``n >= 3``.
    amplitude : ``h``, relative to the fundamental.
    phase_deg : ``phi``.
    """

    order: int = Field(ge=3)
    amplitude: float = Field(ge=0, lt=0.2)
    phase_deg: float = 0.0

    @field_validator("order")
    @classmethod
    def _odd(cls, v: int) -> int:
        if v % 2 == 0:
            raise ValueError("winding harmonics of a symmetric winding are odd (3, 5, 7, ...)")
        return v


class ElectricalErrors(StrictModel):
    """Imperfections of the windings and the readout electronics (short-period error).

    All amplitudes are relative to the fundamental coupling ``k U`` (dimensionless).

    Parameters
    ----------
    excitation_imbalance : relative amplitude error of the function transformer that
        makes ``u_s`` and ``u_c`` (eqs 1-2): ``u_s`` scaled by ``1 + a_x/2``, ``u_c`` by
        ``1 - a_x/2``.
    coupling_imbalance : relative mismatch of the two windings' coupling ``k``.
    quadrature_error_deg : the cosine winding sits at ``90 deg + gamma`` electrical.
    offset_sin, offset_cos : in-phase carrier feed-through of each channel (an angle
        independent coupling; after demodulation a DC offset).
    demodulator_offset : offset of the phase-sensitive demodulator output.
    winding_harmonics : odd spatial harmonics of the coupling function.
    """

    excitation_imbalance: float = Field(0.0, gt=-0.5, lt=0.5)
    coupling_imbalance: float = Field(0.0, gt=-0.5, lt=0.5)
    quadrature_error_deg: float = Field(0.0, gt=-20, lt=20)
    offset_sin: float = Field(0.0, gt=-0.4, lt=0.4)
    offset_cos: float = Field(0.0, gt=-0.4, lt=0.4)
    demodulator_offset: float = Field(0.0, gt=-0.4, lt=0.4)
    winding_harmonics: tuple[WindingHarmonic, ...] = ()


class PitchHarmonic(StrictModel):
    """Optional manufacturing (pitch) error of the scale, one harmonic.

    ``amplitude_arcsec * sin(order * phase + phase_deg)`` with phase the mechanical angle
    (domain "mechanical") or the electrical angle (domain "electrical").
    """

    domain: Literal["mechanical", "electrical"]
    order: int = Field(ge=1)
    amplitude_arcsec: float = Field(ge=0, le=3600, description="at most 1 deg: a scale's pitch error")
    phase_deg: float = 0.0


class InductosynParams(StrictModel):
    """A round inductosyn and its amplitude-discrimination readout.

    Parameters
    ----------
    pole_pairs : electrical periods per turn (seed 001: 360).
    resolution_deg : reading quantum (seed 001: 0.0001 deg); 0 for a continuous reading.
    reading_noise_arcsec : 1-sigma white noise of a reading.
    """

    pole_pairs: int = Field(360, ge=1, le=100000)
    resolution_deg: float = Field(0.0001, ge=0, lt=1)
    reading_noise_arcsec: float = Field(0.0, ge=0, le=3600, description="at most 1 deg, 10 pole pitches of the scale")
    mechanical: MechanicalErrors = MechanicalErrors()
    electrical: ElectricalErrors = ElectricalErrors()
    pitch_harmonics: tuple[PitchHarmonic, ...] = ()


class DriftParams(StrictModel):
    """1-sigma random change of the physical parameters after environmental testing.

    Seed 001 section 4.3: temperature cycling and vibration grew the compensated error
    from 2.7 to 5.4 arcsec (3 sigma). Each parameter moves by a normal draw of this size.
    """

    offset_std: float = Field(0.0, ge=0, le=0.4, description="at most the offsets' own range (0.4)")
    imbalance_std: float = Field(0.0, ge=0, le=0.5, description="at most the imbalances' own range (0.5)")
    quadrature_std_deg: float = Field(0.0, ge=0, le=20, description="at most the quadrature error's range (20 deg)")
    eccentricity_std_um: float = Field(0.0, ge=0, le=1e4, description="at most 1 cm: a scale's centring")
    ellipticity_std_ppm: float = Field(0.0, ge=0, le=1e5, description="at most the ellipticity's range (1e5 ppm)")


class PolygonParams(StrictModel):
    """Optical polygon used as the angle standard.

    Parameters
    ----------
    faces : number of faces (seed 001: 24 for eq 7, 23 for eq 8).
    face_error_arcsec : 1-sigma uncertainty of the face angles after the certificate
        correction (what remains unknown).
    mount_offset_arcsec : angle between face 0 and the encoder zero.
    """

    faces: int = Field(ge=3, le=720)
    face_error_arcsec: float = Field(0.0, ge=0, le=3600, description="at most 1 deg: a polygon face's angle")
    mount_offset_arcsec: float = 0.0


class AutocollimatorParams(StrictModel):
    """Autocollimator: 1-sigma noise and reading resolution (0 = continuous)."""

    noise_arcsec: float = Field(0.0, ge=0, le=3600, description="at most 1 deg, beyond an autocollimator's field")
    resolution_arcsec: float = Field(0.0, ge=0, le=3600, description="at most 1 deg, as noise_arcsec")


class CalibrationParams(StrictModel):
    """The calibration protocol of seed 001 section 3.

    Parameters
    ----------
    requirement_arcsec : the pointing requirement; a compensation is accepted when its
        verification 3 sigma is within ``requirement_arcsec / 3`` (section 3.1).
    repeats : rounds of each pass (the lab's choice): the polygon is read round ``repeats``
        times in a row and each face's table entry is the mean of its rounds (fresh stops,
        quantisation phases, reading and autocollimator noise each round; the same polygon
        and mounting). Seed 001 reads each face once (1).
    face_time_s : lab time per face reading: rotate to the next face, settle, read.
    pass_setup_s : lab time between two passes: compensation upload, polygon change.
        Seed 001 gives no times; 60 s and 900 s are stated-typical values for a manual
        polygon calibration (engineering estimate). The world's drifts run on this timeline
        (:func:`simcam.encoder.polygon.pass_times_s`); the planner's lab time is its sum.
    """

    requirement_arcsec: float = Field(10.0, gt=0)
    repeats: int = Field(1, ge=1, le=100)
    face_time_s: float = Field(60.0, gt=0)
    pass_setup_s: float = Field(900.0, ge=0)
    long_polygon: PolygonParams = PolygonParams(faces=24)
    short_polygon: PolygonParams = PolygonParams(faces=23)
    autocollimator: AutocollimatorParams = AutocollimatorParams()


class ValidationParams(ValidationSettings):
    """Monte Carlo settings (:class:`simcam.config_base.ValidationSettings`; trials are
    vectorised, hence the large cap and batch) and ``dense_step_deg``, the step of the
    truth's grid of readings over the turn (its Fourier analysis,
    :mod:`budget.inductosyn.truth`; at most 360 / (16 pole pairs) is used)."""

    trials: Trials = 1000
    max_trials: Trials = 1_000_000
    batch_trials: BatchTrials = 1000
    dense_step_deg: float = Field(0.01, gt=0, le=1)


class InductosynEffects(EffectsBase):
    """What the real rig and encoder have and the seed-001 lab model leaves out (``[world.effects]``).

    Each field is one effect's magnitude, 0 = off; the default is the sourced realistic value,
    so the default scenario is the realistic world. Model forms: :mod:`simcam.encoder.polygon`
    (the rig: :func:`~simcam.encoder.polygon.world_alpha_arcsec`) and
    :func:`world_encoder_params` (the encoder). How each differs from the lab-known fields
    (``calibration.*.face_error_arcsec``, ``calibration.autocollimator.noise_arcsec``,
    ``encoder.pitch_harmonics``, ``drift``) is in docs/inductosyn.md, "World effects". The
    ranges beside the fields: angles at most 1 deg (3600 arcsec; the rig's small-angle
    models, a hundred times the sourced sizes and more), the polygon's centring at most 1 cm.
    """

    polygon_face_error_arcsec: float = Field(
        0.05, ge=0, description="residual face-angle error of THE polygon after its certificate correction, 1 sigma "
        "per face, closure sum = 0, the same in every calibration: NMI polygon uncertainties 0.02-0.1 arcsec "
        "(EUROMET project 371 comparison; Estler, J. Res. NIST 103:141, 1998)", le=3600)
    autocollimator_drift_arcsec_per_sqrt_h: float = Field(
        0.05, ge=0, description="autocollimator zero drift, random walk, rms change after 1 h: 0.02-0.1 arcsec/h "
        "for an electronic autocollimator in a laboratory (EURAMET cg-22, 2017; engineering estimate)", le=3600)
    polygon_eccentricity_um: float = Field(
        20.0, ge=0, description="centring of the polygon on its adapter, 10-50 um, remounted each calibration: a "
        "translation leaves a flat face's reading unchanged, a face's curvature turns it into beam walk "
        "<= 0.01-0.03 arcsec (geometry; engineering estimate)", le=1e4)
    polygon_tilt_arcsec: float = Field(
        20.0, ge=0, description="tilt of the polygon's axis to the axis of rotation, remounted each calibration; "
        "with the faces' pyramidal errors (world.pyramidal_error_arcsec) it gives -tau gamma_i cos(theta_i - phi) "
        "(small-angle rotation of the face normal; tau = 20 arcsec, gamma = 5 arcsec: 2.4e-9 rad)", le=3600)
    electrical_harmonic_3_arcsec: float = Field(
        0.5, ge=0, description="3rd electrical harmonic of the reading error, outside the published eq 8 orders: "
        "resolver/inductosyn signal harmonics give 3rd/4th electrical errors of 0.3-2 arcsec (Kuntz et al., "
        "arXiv:2205.08472; HEIDENHAIN, Position Encoders for Servo Drives, interpolation error)", le=3600)
    nonharmonic_arcsec: float = Field(
        0.3, ge=0, le=3600, description="rms of an irregular pitch error of the scale, mechanical orders 3 to "
        "world.nonharmonic_max_order with 1/m amplitudes: graduation errors not periodic in a fitted order "
        "(HEIDENHAIN, Position Encoders for Servo Drives, position error within one revolution; engineering "
        "estimate)")
    thermal_drift_arcsec_per_sqrt_h: float = Field(
        0.05, ge=0, description="random walk of each fitted harmonic coefficient (mechanical 1-2, electrical 1-2) "
        "during the calibration, rms change after 1 h: seed 001 sec. 4.3 gives 1.1 arcsec per coefficient "
        "after temperature cycling over tens of K; a lab holding +-1 K over a few hours gives a few percent of "
        "that (engineering estimate)", le=3600)


class InductosynWorld(WorldBase):
    """The inductosyn rig's world beyond the lab's model: ``effects`` (magnitudes) and the
    settings of their model forms. The lab side (:mod:`budget.inductosyn.harmonics`) never
    reads it; the simulator (:mod:`simcam.encoder.polygon`) and the truth
    (:func:`world_encoder_params`) do.

    * The drifts run over the session the protocol's times give (``calibration.face_time_s``,
      ``calibration.pass_setup_s``; the four passes in the order long raw, long verify,
      short raw, short verify) and start at 0 at the first reading (the truth is the
      encoder at the start of the calibration).
    * ``pyramidal_error_arcsec``: 1 sigma of the faces' pyramidal errors gamma_i.
    * ``face_curvature_arcsec_per_mm``: change of a face's normal per mm along the face
      (1/R of a spherical face; lambda/10 over a 20 mm face is about 0.25 arcsec/mm).
    * ``nonharmonic_max_order``: highest mechanical order of the irregular pitch error.

    Which polygon and encoder of the population (their certificate residuals, pyramidal
    errors and harmonic phases) is ``validation.instrument_seed``'s (unset: each trial draws
    its own; :func:`instrument_rng`); the per-calibration draws (mounting azimuths, drifts)
    come from the trial's seed. The former ``world.instrument_seed`` is refused with a line
    pointing there.
    """

    effects: InductosynEffects = InductosynEffects()
    pyramidal_error_arcsec: float = Field(5.0, ge=0, le=3600, description="at most 1 deg: the small-angle model")
    face_curvature_arcsec_per_mm: float = Field(0.5, ge=0)
    nonharmonic_max_order: int = Field(72, ge=3, le=2000)

    @model_validator(mode="before")
    @classmethod
    def _moved_instrument_seed(cls, data):
        if isinstance(data, dict) and "instrument_seed" in data:
            raise ScenarioError("world.instrument_seed: moved to validation.instrument_seed (unset: each trial "
                                "draws its own polygon and encoder; an integer pins one)")
        return data


class InductosynScenario(ScenarioBase):
    """A whole inductosyn scenario: the encoder, its drift, the calibration, the MC, and the
    world's effects beyond the lab's model (``world``; never read by the lab side)."""

    encoder: InductosynParams = InductosynParams()
    drift: DriftParams = DriftParams()
    calibration: CalibrationParams = CalibrationParams()
    world: InductosynWorld = InductosynWorld()
    validation: ValidationParams = ValidationParams()


def default_text() -> str:
    """Text of the embedded default scenario (resembles seed 001's unit), with comments."""
    return resources.files("simcam.data").joinpath("inductosyn_default.toml").read_text()


def from_dict(data: dict, *, source: str = "scenario") -> InductosynScenario:
    """Validate a mapping into :class:`InductosynScenario`.

    Raises
    ------
    ScenarioError
        Unknown key, wrong type, out-of-range value (message names ``source`` and field),
        or a parameter set whose reading is not monotonic.
    """
    scenario = validate_model(InductosynScenario, data, source=source).with_source(source)
    Inductosyn(params=scenario.encoder, source=source)  # monotonicity check
    return scenario


def load(path: str | Path | None = None) -> InductosynScenario:
    """The scenario file at ``path`` (strict TOML, :func:`simcam.config_base.read_toml`) or,
    for None or ``"embedded:default"`` (the name a claims ledger gives), the embedded default."""
    if isinstance(path, str) and path.startswith("embedded:"):
        if path != "embedded:default":
            raise ScenarioError(f"{path}: no embedded inductosyn scenario {path.split(':', 1)[1]!r} (have default)")
        path = None
    return load_scenario_file(path, from_dict=from_dict, default_text=default_text, study="inductosyn")


def default() -> InductosynScenario:
    """The embedded default scenario, validated."""
    return load(None)


# ------------------------------------------------------------------ physical models
def mechanical_error_rad(*, theta_rad, mech: MechanicalErrors):
    """Angle error of the scale (scale angle minus shaft angle), exact geometric maps.

    * Eccentricity ``eps`` at azimuth ``phi`` (reading at radius ``R``, ``r = eps/R``):
      ``atan2(r sin u, 1 - r cos u) = sum_n r^n/n sin(n u)``, ``u = theta - phi``
      (plane geometry of a circle read off-centre: the angle at the scale centre of
      the point under a fixed head; series from ``Im log(1 - r e^{iu})``).
    * Ellipticity ``k`` with long axis at ``psi``: a graduation at ``u`` moves to
      ``atan2((1 - k) sin u, (1 + k) cos u)``; error ``= -k sin 2u + O(k^2)``.
    * Tilt ``alpha`` about an axis at ``psi``: projection ``atan2(cos(alpha) sin u,
      cos u)``; error ``= -(alpha^2/4) sin 2u + O(alpha^4)``.

    The three maps are added (their cross terms are of the order of the products of the
    small parameters, below 1e-10 rad for realistic values).

    Parameters
    ----------
    theta_rad : array_like, shaft angle (rad).
    mech : the mechanical imperfections.

    Returns
    -------
    ndarray, error in rad (mechanical).
    """
    theta = np.asarray(theta_rad, dtype=float)
    out = np.zeros_like(theta)
    if mech.eccentricity_um > 0:
        r = mech.eccentricity_um * 1e-3 / mech.radius_mm
        u = theta - math.radians(mech.eccentricity_azimuth_deg)
        out += np.arctan2(r * np.sin(u), 1.0 - r * np.cos(u))
    if mech.ellipticity_ppm > 0:
        k = mech.ellipticity_ppm * 1e-6
        u = theta - math.radians(mech.ellipticity_azimuth_deg)
        out += _wrap(np.arctan2((1 - k) * np.sin(u), (1 + k) * np.cos(u)) - u)
    if mech.tilt_deg > 0:
        ca = math.cos(math.radians(mech.tilt_deg))
        u = theta - math.radians(mech.tilt_azimuth_deg)
        out += _wrap(np.arctan2(ca * np.sin(u), np.cos(u)) - u)
    return out


def _wrap(x):
    """Wrap an angle (rad) into [-pi, pi)."""
    return (np.asarray(x) + math.pi) % (2 * math.pi) - math.pi


def _gains(elec: ElectricalErrors) -> tuple[float, float]:
    gs = (1 + elec.excitation_imbalance / 2) * (1 + elec.coupling_imbalance / 2)
    gc = (1 - elec.excitation_imbalance / 2) * (1 - elec.coupling_imbalance / 2)
    return gs, gc


def _coupling(x, elec: ElectricalErrors):
    """Coupling shape f(x) = sin x + sum h_n sin(n x + phi_n) of both windings."""
    out = np.sin(x)
    for wh in elec.winding_harmonics:
        out = out + wh.amplitude * np.sin(wh.order * x + math.radians(wh.phase_deg))
    return out


def channel_signals(*, theta_e_rad, elec: ElectricalErrors):
    """Demodulated amplitudes of the two winding channels at electrical angle theta_e.

    Generalises seed 001 eqs 3-4 with the imperfections of :class:`ElectricalErrors`::

        V_s = g_s [f(theta_e) + o_s]
        V_c = g_c [f(theta_e + pi/2 + gamma) + o_c]

    with ``f`` the coupling shape, ``g_s/g_c`` the excitation and coupling gains,
    ``gamma`` the quadrature error and ``o_s, o_c`` the carrier feed-through.
    The loop error (eq 5) is then ``E = V_s cos(theta_d) - V_c sin(theta_d) + o_d``.

    Returns
    -------
    (V_s, V_c) : ndarrays, relative to ``k U``.
    """
    te = np.asarray(theta_e_rad, dtype=float)
    gs, gc = _gains(elec)
    gamma = math.radians(elec.quadrature_error_deg)
    vs = gs * (_coupling(te, elec) + elec.offset_sin)
    vc = gc * (_coupling(te + math.pi / 2 + gamma, elec) + elec.offset_cos)
    return vs, vc


def tracking_null_rad(*, theta_e_rad, elec: ElectricalErrors):
    """Stable null ``theta_d`` of the amplitude-discrimination loop (exact, closed form).

    ``E(theta_d) = V_s cos(theta_d) - V_c sin(theta_d) + o_d = R sin(phi - theta_d) + o_d``
    with ``phi = atan2(V_s, V_c)`` and ``R = hypot(V_s, V_c)`` (eq 5 generalised), so
    ``theta_d = phi + asin(o_d / R)`` (the root at which dE/dtheta_d < 0, the one the loop
    locks to). Unwrapped to lie within pi of ``theta_e``.

    Returns
    -------
    ndarray, theta_d in rad (electrical).
    """
    te = np.asarray(theta_e_rad, dtype=float)
    vs, vc = channel_signals(theta_e_rad=te, elec=elec)
    phi = np.arctan2(vs, vc)
    rr = np.hypot(vs, vc)
    td = phi + np.arcsin(np.clip(elec.demodulator_offset / rr, -1, 1))
    return te + _wrap(td - te)


def demodulated_error(*, theta_e_rad: float, theta_d_rad: float, elec: ElectricalErrors,
                      carrier_samples: int = 64, carrier_periods: int = 4,
                      quadrature_pickup: float = 0.05) -> float:
    """Direct simulation of the loop error: synthesise ``e(t)`` and demodulate it.

    The rotor EMF is synthesised over ``carrier_periods`` periods of the excitation
    (eq 5 with the imperfections, plus a quadrature pick-up ``sin(wt)`` that a
    phase-sensitive demodulator must reject), multiplied by the reference ``cos(wt)``
    and averaged (synchronous demodulation): ``2 <e(t) cos(wt)>``.

    Returns
    -------
    float, demodulated loop error relative to ``k U``.
    """
    vs, vc = channel_signals(theta_e_rad=np.array([theta_e_rad]), elec=elec)
    n = carrier_samples * carrier_periods
    wt = 2 * math.pi * np.arange(n) / carrier_samples
    # eqs 3-5: the two windings' EMFs (excited by cos/sin(theta_d)) add in the rotor
    e_s = vs[0] * math.cos(theta_d_rad) * np.cos(wt)
    e_c = -vc[0] * math.sin(theta_d_rad) * np.cos(wt)
    e_t = e_s + e_c + elec.demodulator_offset * np.cos(wt) + quadrature_pickup * np.sin(wt)
    return float(2.0 * np.mean(e_t * np.cos(wt)))


def tracking_null_numeric_rad(*, theta_e_rad: float, elec: ElectricalErrors,
                              carrier_samples: int = 64) -> float:
    """Null of the demodulated loop error found numerically (brentq), the reference.

    Brackets ``theta_e +- 1 rad`` (the stable root: ``E`` falls through zero as
    ``theta_d`` increases) and solves ``demodulated_error(theta_d) = 0``.
    """
    def f(td):
        return demodulated_error(theta_e_rad=theta_e_rad, theta_d_rad=td, elec=elec,
                                 carrier_samples=carrier_samples)

    return brentq(f, theta_e_rad - 1.0, theta_e_rad + 1.0, xtol=1e-15, rtol=1e-15, maxiter=200)


def winding_harmonic_order_map(*, order: int) -> int:
    """Electrical error harmonic produced by odd winding harmonic ``order``.

    ``n = 4m + 1 -> n - 1``; ``n = 4m + 3 -> n + 1`` (so 3 -> 4, 5 -> 4, 7 -> 8, 9 -> 8);
    derived in docs/inductosyn.md.
    """
    if order % 2 == 0 or order < 3:
        raise ValueError("order must be odd and >= 3")
    return order - 1 if order % 4 == 1 else order + 1


def first_order_electrical_error_rad(*, theta_e_rad, elec: ElectricalErrors):
    """Small-parameter expansion of ``theta_d - theta_e`` (first order), rad electrical.

    ``delta = (a/2) sin 2t + (gamma/2)(1 - cos 2t) + o_s cos t - o_c sin t + o_d
    + sum_n h_n sin(m_n t + phi_n)``, with ``a = g_s/g_c - 1`` (imbalance),
    ``gamma`` the quadrature error, ``m_n`` from :func:`winding_harmonic_order_map`.
    Derived in docs/inductosyn.md; the error of this expansion is second order in the
    small parameters.
    """
    t = np.asarray(theta_e_rad, dtype=float)
    gs, gc = _gains(elec)
    a = gs / gc - 1
    gamma = math.radians(elec.quadrature_error_deg)
    out = (a / 2) * np.sin(2 * t) + (gamma / 2) * (1 - np.cos(2 * t))
    out = out + elec.offset_sin * np.cos(t) - elec.offset_cos * np.sin(t) + elec.demodulator_offset
    for wh in elec.winding_harmonics:
        m = winding_harmonic_order_map(order=wh.order)
        out = out + wh.amplitude * np.sin(m * t + math.radians(wh.phase_deg))
    return out


# --------------------------------------------------------------------------- encoder
class Inductosyn:
    """The encoder: exact truth, quantised noisy readings and the inverse map.

    Parameters
    ----------
    params : the encoder's physical parameters.
    source : name of the scenario file (for error messages).

    Raises
    ------
    ScenarioError
        If the imperfections are so large that the reading is not a monotonic function
        of the shaft angle (the loop would jump between electrical periods).
    """

    def __init__(self, *, params: InductosynParams, source: str | None = None):
        self.params = params
        grid = np.linspace(0.0, 1.0 / params.pole_pairs * 360.0, 2049)
        # slope of the reading over one electrical period at a few mechanical places
        for base in (0.0, 90.0, 180.0, 270.0):
            r = self.continuous_reading_deg(angle_deg=base + grid)
            if np.any(np.diff(r) <= 0):
                where = f"{source}: " if source else ""
                raise ScenarioError(
                    f"{where}encoder.electrical: imperfections so large that the reading is "
                    "not monotonic in the shaft angle (reduce offsets/imbalance/harmonics)")

    @property
    def pole_pairs(self) -> int:
        return self.params.pole_pairs

    def _delta_deg(self, angle_deg):
        """Reading minus true angle (deg), continuous, exact."""
        p = self.params
        th = np.asarray(angle_deg, dtype=float)
        th_rad = np.radians(th)
        dm = mechanical_error_rad(theta_rad=th_rad, mech=p.mechanical)
        scale_deg = th + np.degrees(dm)
        # electrical angle: P times the scale angle; keep the fractional cycle for accuracy
        cycles = p.pole_pairs * scale_deg / 360.0
        te = 2 * math.pi * (cycles - np.floor(cycles))
        de = tracking_null_rad(theta_e_rad=te, elec=p.electrical) - te
        out = np.degrees(dm) + np.degrees(de) / p.pole_pairs
        return out + self._pitch_deg(scale_deg, te, p.pitch_harmonics)

    @staticmethod
    def _pitch_deg(scale_deg, te, harmonics):
        out = 0.0
        for ph in harmonics:
            arg = np.radians(scale_deg) * ph.order
            if ph.domain == "electrical":
                arg = te * ph.order
            out = out + ph.amplitude_arcsec / ARCSEC_PER_DEG * np.sin(arg + math.radians(ph.phase_deg))
        return out

    def pitch_arcsec(self, *, angle_deg, harmonics, separate: bool = False) -> np.ndarray:
        """The error (arcsec) that pitch harmonics ``harmonics`` (:class:`PitchHarmonic`) would
        add at true shaft angles ``angle_deg`` on this encoder: their arguments are its scale
        angle and electrical phase there, as in :meth:`error_arcsec`. ``separate``: one
        column per harmonic (last axis) rather than their sum."""
        p = self.params
        th = np.asarray(angle_deg, dtype=float)
        scale_deg = th + np.degrees(mechanical_error_rad(theta_rad=np.radians(th), mech=p.mechanical))
        cycles = p.pole_pairs * scale_deg / 360.0
        te = 2 * math.pi * (cycles - np.floor(cycles))
        if separate:
            return np.stack([np.zeros_like(th) + self._pitch_deg(scale_deg, te, (h,)) * ARCSEC_PER_DEG
                             for h in harmonics], axis=-1) if harmonics else np.zeros(th.shape + (0,))
        return np.zeros_like(th) + self._pitch_deg(scale_deg, te, harmonics) * ARCSEC_PER_DEG

    def continuous_reading_deg(self, *, angle_deg):
        """Noise-free, unquantised reading (deg) at true shaft angle ``angle_deg``."""
        th = np.asarray(angle_deg, dtype=float)
        return th + self._delta_deg(th)

    def error_arcsec(self, *, angle_deg):
        """Truth: continuous reading minus true angle (arcsec) at true shaft angles."""
        return self._delta_deg(angle_deg) * ARCSEC_PER_DEG

    def quantise_deg(self, *, reading_deg):
        """Round a reading to the resolution (counter quantum); identity if 0."""
        q = self.params.resolution_deg
        r = np.asarray(reading_deg, dtype=float)
        return r if q == 0 else np.round(r / q) * q

    def reading_deg(self, *, angle_deg, rng: np.random.Generator | None = None):
        """Quantised reading (deg) with reading noise drawn from ``rng`` (none if None)."""
        r = self.continuous_reading_deg(angle_deg=angle_deg)
        if rng is not None and self.params.reading_noise_arcsec > 0:
            r = r + rng.standard_normal(np.shape(r)) * self.params.reading_noise_arcsec / ARCSEC_PER_DEG
        return self.quantise_deg(reading_deg=r)

    def true_angle_deg(self, *, reading_deg, tol_arcsec: float = 1e-9):
        """Inverse of :meth:`continuous_reading_deg` (deg): the shaft angle at a reading.

        Safeguarded Newton iteration (the reading is strictly increasing, checked at
        construction), converged to ``tol_arcsec``.
        """
        r = np.asarray(reading_deg, dtype=float)
        th = r - self._delta_deg(r)
        h = 1e-7
        for _ in range(60):
            f = self.continuous_reading_deg(angle_deg=th) - r
            if np.all(np.abs(f) * ARCSEC_PER_DEG < tol_arcsec):
                return th
            slope = (self.continuous_reading_deg(angle_deg=th + h)
                     - self.continuous_reading_deg(angle_deg=th - h)) / (2 * h)
            th = th - f / np.maximum(slope, 1e-3)
        raise RuntimeError("inverse reading map did not converge")  # pragma: no cover

    def error_at_reading_arcsec(self, *, reading_deg):
        """Truth as a function of the reading: reading minus true angle (arcsec)."""
        r = np.asarray(reading_deg, dtype=float)
        return (r - self.true_angle_deg(reading_deg=r)) * ARCSEC_PER_DEG


def apply_drift(*, params: InductosynParams, drift: DriftParams, seed: int) -> InductosynParams:
    """Encoder parameters after environmental testing (seed 001 section 4.3).

    Each drifting physical parameter moves by a normal draw of the size in ``drift``
    (order: offset_sin, offset_cos, excitation_imbalance, coupling_imbalance,
    quadrature_error_deg, eccentricity_um, ellipticity_ppm).
    """
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    return drifted_params(params=params, drift=drift, z=rng.standard_normal(7))


def drifted_params(*, params: InductosynParams, drift: DriftParams, z) -> InductosynParams:
    """Encoder parameters moved by the standard normal draws ``z`` (7, in the order of
    :func:`apply_drift`) times the sizes in ``drift`` (seed 001 section 4.3)."""
    z = np.asarray(z, dtype=float)
    el = params.electrical
    me = params.mechanical
    el2 = el.model_copy(update=dict(
        offset_sin=el.offset_sin + drift.offset_std * z[0],
        offset_cos=el.offset_cos + drift.offset_std * z[1],
        excitation_imbalance=el.excitation_imbalance + drift.imbalance_std * z[2],
        coupling_imbalance=el.coupling_imbalance + drift.imbalance_std * z[3],
        quadrature_error_deg=el.quadrature_error_deg + drift.quadrature_std_deg * z[4]))
    me2 = me.model_copy(update=dict(
        eccentricity_um=abs(me.eccentricity_um + drift.eccentricity_std_um * z[5]),
        ellipticity_ppm=abs(me.ellipticity_ppm + drift.ellipticity_std_ppm * z[6])))
    data = params.model_dump()
    data["electrical"] = el2.model_dump()
    data["mechanical"] = me2.model_dump()
    return validate_model(InductosynParams, data, source="drift")


#: first spawn key of the instruments' seed sequences: the same number as
#: :data:`budget.runner.study.INSTRUMENT_SPAWN_KEY` (the world package cannot import the lab's)
INSTRUMENT_SPAWN_KEY = 2**31 + 1


def pinned_instrument(*, scenario: InductosynScenario) -> np.random.SeedSequence:
    """The instrument ``validation.instrument_seed`` pins (0 when unset):
    ``SeedSequence(instrument_seed, spawn_key=(INSTRUMENT_SPAWN_KEY,))``, the sequence
    :func:`budget.runner.study.instrument_seed_sequence` gives every trial of a pinned run."""
    return np.random.SeedSequence(scenario.validation.instrument_seed or 0, spawn_key=(INSTRUMENT_SPAWN_KEY,))


def instrument_rng(instrument: np.random.SeedSequence, stream: int) -> np.random.Generator:
    """Draws of one instrument (``instrument``: its seed sequence, one per trial or pinned,
    :func:`budget.runner.study.instrument_seed_sequence`); stream 0: the polygons, 1: the
    encoder. Independent of the trial's measurement and world draws."""
    return np.random.default_rng(np.random.SeedSequence(instrument.entropy,
                                                        spawn_key=tuple(instrument.spawn_key) + (stream,)))


def world_pitch_terms(*, scenario: InductosynScenario) -> tuple[PitchHarmonic, ...]:
    """The world's encoder effects as :class:`PitchHarmonic` terms of phase 0, one per phase
    :func:`world_pitch_phases_deg` draws (the instrument sets only the phases).

    ``electrical_harmonic_3_arcsec``: ``A3 sin(3 theta_e + phi3)``; ``nonharmonic_arcsec``:
    ``sum_{m=3}^{M} a_m sin(m theta + phi_m)`` with ``a_m = c/m``, ``c`` such that the rms
    over a turn, ``sqrt(sum a_m^2 / 2)``, is the magnitude (Parseval). A magnitude 0 gives
    no term."""
    w = scenario.world
    eff = w.effects
    out = []
    if eff.electrical_harmonic_3_arcsec > 0:
        out.append(PitchHarmonic(domain="electrical", order=3, amplitude_arcsec=eff.electrical_harmonic_3_arcsec))
    if eff.nonharmonic_arcsec > 0:
        orders = np.arange(3, w.nonharmonic_max_order + 1)
        c = eff.nonharmonic_arcsec * math.sqrt(2.0 / float(np.sum(1.0 / orders**2.0)))
        out += [PitchHarmonic(domain="mechanical", order=int(m), amplitude_arcsec=float(c / m)) for m in orders]
    return tuple(out)


def world_pitch_phases_deg(*, scenario: InductosynScenario, instrument: np.random.SeedSequence) -> np.ndarray:
    """The phases (deg) of :func:`world_pitch_terms` for ``instrument``: from
    ``instrument_rng(instrument, 1)``, ``phi3`` then ``phi_3 .. phi_M``, all drawn whatever the
    magnitudes (common numbers), those of the terms present returned in their order."""
    w = scenario.world
    eff = w.effects
    rng = instrument_rng(instrument, 1)
    phi3 = rng.uniform(0.0, 360.0)
    phis = rng.uniform(0.0, 360.0, w.nonharmonic_max_order - 2)
    out = ([phi3] if eff.electrical_harmonic_3_arcsec > 0 else []) + (list(phis) if eff.nonharmonic_arcsec > 0 else [])
    return np.asarray(out, dtype=float)


def world_encoder_params(*, scenario: InductosynScenario,
                         instrument: np.random.SeedSequence | None = None) -> InductosynParams:
    """The encoder of the world: ``scenario.encoder`` plus the world's encoder effects
    (:func:`world_pitch_terms` with the phases of ``instrument``,
    :func:`world_pitch_phases_deg`; None: :func:`pinned_instrument`), so the truth
    (:meth:`Inductosyn.error_arcsec`) includes them exactly. With both magnitudes 0 the
    scenario's encoder is returned unchanged (the same object).
    """
    terms = world_pitch_terms(scenario=scenario)
    if not terms:
        return scenario.encoder
    inst = pinned_instrument(scenario=scenario) if instrument is None else instrument
    phases = world_pitch_phases_deg(scenario=scenario, instrument=inst)
    extra = tuple(t.model_copy(update={"phase_deg": float(ph)}) for t, ph in zip(terms, phases))
    return scenario.encoder.model_copy(update={"pitch_harmonics": tuple(scenario.encoder.pitch_harmonics) + extra})
