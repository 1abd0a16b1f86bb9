"""The star camera's own sections of a scenario: ``camera``, ``optics``, ``detector`` and
``render``, as typed, frozen models (:mod:`simcam.starcam.scenario` puts them together with the
lab, the protocols and the world).

They live apart from the scenario because resolving ``optics.lens``
(:func:`simcam.starcam.lens.simulator.apply_lens`) validates these sections while the
scenario is being validated: the lens simulator imports them, the scenario imports the lens
simulator.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import ConfigDict, Field, model_validator

from simcam.config_base import StrictModel
from simcam.units import ARCSEC_PER_RAD

__all__ = ["CameraModel", "ChipModel", "DetectorModel", "DistortionCorrectionModel",
           "DistortionModel", "Finite", "FloatSeq", "FloatTable", "Fraction", "LateralColourModel", "NonNeg",
           "OpticsModel", "PSFModel", "Pair", "Pos", "QEModel", "RenderModel", "SectionModel"]

#: arcsec per radian (exact: 180 * 3600 / pi)

NonNeg = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
Pos = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]
Fraction = Annotated[float, Field(ge=0.0, le=1.0, allow_inf_nan=False)]
FloatSeq = Annotated[tuple[Finite, ...], Field(strict=False)]
Pair = Annotated[tuple[Finite, Finite], Field(strict=False)]
FloatTable = Annotated[tuple[FloatSeq, ...], Field(strict=False, min_length=1)]


class SectionModel(StrictModel):
    """Scenario base: strict types (no '5' for 5.0), frozen, unknown keys refused."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, validate_default=True)


# --------------------------------------------------------------------------- camera
class CameraModel(SectionModel):
    """Camera geometry and exposure.

    Give either ``plate_scale_arcsec`` or ``focal_length_mm``; the other follows from
    ``pixel_pitch_um`` (plate scale = pitch / focal length, in arcsec per px).
    """

    plate_scale_arcsec: Pos | None = None
    focal_length_mm: Pos | None = None
    pixel_pitch_um: Pos = 5.5
    aperture_diameter_mm: Pos = 60.0
    exposure_s: Pos = 0.1

    @model_validator(mode="before")
    @classmethod
    def _default_scale(cls, data: Any) -> Any:
        # Documented default: 5.5 arcsec/px (seed 000) unless a focal length is given.
        if isinstance(data, dict) and data.get("plate_scale_arcsec") is None and data.get("focal_length_mm") is None:
            data = {**data, "plate_scale_arcsec": 5.5}
        return data

    @model_validator(mode="after")
    def _one_scale(self) -> CameraModel:
        if self.plate_scale_arcsec is None and self.focal_length_mm is None:
            raise ValueError("give plate_scale_arcsec or focal_length_mm")
        if self.plate_scale_arcsec is not None and self.focal_length_mm is not None:
            implied = self.pixel_pitch_um * 1e-3 / self.focal_length_mm * ARCSEC_PER_RAD
            if abs(implied - self.plate_scale_arcsec) > 1e-6 * implied:
                raise ValueError(
                    f"plate_scale_arcsec={self.plate_scale_arcsec} contradicts focal_length_mm="
                    f"{self.focal_length_mm} with pixel_pitch_um={self.pixel_pitch_um} "
                    f"(implies {implied:.6f}); give only one of them"
                )
        return self

    @property
    def scale_arcsec_per_px(self) -> float:
        """Plate scale in arcsec per px at the optical axis."""
        if self.plate_scale_arcsec is not None:
            return float(self.plate_scale_arcsec)
        return self.pixel_pitch_um * 1e-3 / self.focal_length_mm * ARCSEC_PER_RAD

    @property
    def focal_length_effective_mm(self) -> float:
        """Focal length in mm (given, or from plate scale and pitch)."""
        if self.focal_length_mm is not None:
            return float(self.focal_length_mm)
        return self.pixel_pitch_um * 1e-3 / (self.plate_scale_arcsec / ARCSEC_PER_RAD)

    @property
    def f_number(self) -> float:
        """Focal ratio N = f / D."""
        return self.focal_length_effective_mm / self.aperture_diameter_mm


# --------------------------------------------------------------------------- optics
class PSFModel(SectionModel):
    """Camera PSF. ``gaussian``: sigma varies over the field as sigma0 + sigma_r2 (r/r_norm)^2.

    ``airy``: diffraction by the circular aperture at each wavelength (f-number from the
    camera), convolved with a Gaussian blur of the same field-dependent sigma (defocus,
    jitter); set ``sigma0_px = 0`` for a pure Airy pattern.
    """

    kind: Literal["gaussian", "airy"] = "gaussian"
    sigma0_px: NonNeg = Field(0.8, le=100.0, description="at most 100 px: a wider core is no star image on a chip")
    sigma_r2_px: Finite = Field(0.1, ge=-100.0, le=100.0, description="within +-100 px, as sigma0_px")

    @model_validator(mode="after")
    def _width(self) -> PSFModel:
        if self.kind == "gaussian" and self.sigma0_px <= 0:
            raise ValueError("sigma0_px must be > 0 for a gaussian PSF")
        if self.sigma0_px + self.sigma_r2_px * 2.0 < 0:
            raise ValueError("sigma0_px + sigma_r2_px (r/r_norm)^2 becomes negative in the field")
        return self


class DistortionModel(SectionModel):
    """Polynomial distortion (px) of focal-plane coordinates normalised by ``r_norm_px``.

    Brown-Conrady (k1, k2, p1, p2) then a full bivariate cubic (10 coefficients per axis,
    monomials 1, x, y, x^2, xy, y^2, x^3, x^2 y, x y^2, y^3).
    """

    k1: Finite = 2.0e-4
    k2: Finite = 5.0e-5
    p1: Finite = 0.0
    p2: Finite = 0.0
    cubic_x_px: FloatSeq = (0.0,) * 10
    cubic_y_px: FloatSeq = (0.0,) * 10

    @model_validator(mode="after")
    def _ten(self) -> DistortionModel:
        for name in ("cubic_x_px", "cubic_y_px"):
            if len(getattr(self, name)) != 10:
                raise ValueError(f"{name} needs 10 coefficients, got {len(getattr(self, name))}")
        return self


class LateralColourModel(SectionModel):
    """Chromatic lateral shift (px) as a polynomial in (lambda - lambda_ref) [nm].

    du = (u / r_norm) P_radial + P_x, dv = (v / r_norm) P_radial + P_y, P(d) = sum c_k d^k,
    k = 1.., coefficients in px per nm^k. The radial term is Seidel lateral colour; the
    uniform term the prism-like shift of a decentred element. ``radial_px_per_nm`` may
    also be a table (rows of equal length) ``c[k-1][m]``: ``P_radial = sum_k sum_m c_km
    d^k (r / r_norm)^(2m)``, lateral colour growing as odd powers of the field radius ``r``
    (what a traced lens gives, see ``optics.lens``).
    """

    ref_wavelength_nm: Pos = 600.0
    radial_px_per_nm: FloatSeq | FloatTable = (1.0e-4,)
    uniform_x_px_per_nm: FloatSeq = (6.0e-4,)
    uniform_y_px_per_nm: FloatSeq = (3.5e-5,)

    @model_validator(mode="after")
    def _rectangular(self) -> LateralColourModel:
        rows = self.radial_px_per_nm
        if rows and isinstance(rows[0], tuple):
            widths = {len(r) for r in rows}
            if len(widths) != 1 or 0 in widths:
                raise ValueError(f"radial_px_per_nm: table rows must have the same length >= 1 (got lengths "
                                 f"{[len(r) for r in rows]})")
        return self


class DistortionCorrectionModel(SectionModel):
    """The distortion correction the camera applies to its own centroids.

    A camera under the seed-000 LSFE-C1 test already carries a distortion model from an
    earlier calibration, with that calibration's own errors. ``kind = "fitted"`` (default):
    at a ``rows x cols`` grid spanning ``extent_fraction`` of the mosaic (as
    ``lab.calibration_target`` lays out its grid), the displacement of each point (true
    distortion plus the lamp's lateral colour, in mosaic px) was measured with a marker
    error of ``marker_error_3sigma_arcsec`` (3 sigma, per axis) and a centroid noise of
    ``centroid_noise_px`` (1 sigma, per axis, of each point's mean), and a full bivariate
    polynomial of total degree ``order`` in the measured coordinates was fitted to it by
    least squares; the camera reports ``x - c_x(x, y)``, ``y - c_y(x, y)``. The errors are
    drawn once from the scenario seed (one physical camera). ``kind = "none"``: the camera
    reports raw centroids (an uncalibrated camera). The defaults (cubic, 32 points, 0.5"
    markers, 0.002 px centroid noise ~ the default camera's TE over 30 frames) leave a
    remaining displacement near the marker floor of eq 29, sqrt(9/31) x 0.5" = 0.27".
    """

    kind: Literal["fitted", "none"] = "fitted"
    rows: Annotated[int, Field(ge=2, le=64)] = 4
    cols: Annotated[int, Field(ge=2, le=64)] = 8
    extent_fraction: Annotated[float, Field(gt=0.0, le=1.0)] = 0.85
    order: Annotated[int, Field(ge=1, le=7)] = 3
    marker_error_3sigma_arcsec: NonNeg = Field(0.5, le=3600.0, description="at most 1 deg: a marker's position")
    centroid_noise_px: NonNeg = Field(0.002, le=100.0, description="at most 100 px: a centroid of a star image")

    @model_validator(mode="after")
    def _determined(self) -> DistortionCorrectionModel:
        if self.kind == "fitted":
            if self.order >= self.rows or self.order >= self.cols:
                raise ValueError(f"order {self.order} needs more than {self.order} rows and columns of points "
                                 f"(got rows = {self.rows}, cols = {self.cols})")
            n_terms = (self.order + 1) * (self.order + 2) // 2
            if self.rows * self.cols <= n_terms:
                raise ValueError(f"order {self.order} has {n_terms} terms: needs more than {n_terms} points "
                                 f"(got {self.rows * self.cols})")
        return self


class OpticsModel(SectionModel):
    """Camera optics: transmission, PSF, distortion, lateral colour; ``r_norm_px`` normalises field.

    ``lens`` (optional, default none: the analytic coefficients below): a lens prescription,
    ``"embedded:star_camera"`` or a TOML file path (relative to the working directory).
    The lens is ray traced (simcam.starcam.lens, cached on disk) and sets ``psf`` (Airy with the
    geometric blur), ``distortion``, the lateral-colour coefficients and
    ``camera.aperture_diameter_mm`` (its entrance pupil), fitted to the traced tables
    (docs/lens.md); values given for those must equal what the lens gives. The camera's
    nominal focal length must agree with the lens's within 0.1 %.
    """

    transmission: Fraction = 0.8
    r_norm_px: Pos = 2048.0
    lens: Annotated[str, Field(min_length=1)] | None = None
    psf: PSFModel = PSFModel()
    distortion: DistortionModel = DistortionModel()
    distortion_correction: DistortionCorrectionModel = DistortionCorrectionModel()
    lateral_colour: LateralColourModel = LateralColourModel()


# --------------------------------------------------------------------------- detector
class ChipModel(SectionModel):
    """One sensor of the mosaic: placement error and its own ADC chain."""

    offset_x_px: Finite = 0.0
    offset_y_px: Finite = 0.0
    rotation_deg: Finite = 0.0
    gain_e_per_dn: Pos = 1.0
    offset_dn: NonNeg = 100.0
    read_noise_e: NonNeg = Field(3.0, le=1e5, description="at most 1e5 e: beyond any full well, no sensor's noise")
    full_well_e: Pos = 4000.0


class QEModel(SectionModel):
    """Parametric quantum-efficiency curve of a monochrome CMOS (see simcam.spectra)."""

    peak_qe: Annotated[float, Field(gt=0.0, le=1.0)] = 0.6
    peak_nm: Pos = 550.0
    blue_cutoff_nm: Pos = 350.0
    red_cutoff_nm: Pos = 1050.0


class DetectorModel(SectionModel):
    """Mosaic of identical-format chips side by side along x, with a gap between them."""

    n_chips: Annotated[int, Field(ge=1, le=8)] = 2
    chip_cols: Annotated[int, Field(ge=16)] = 2048
    chip_rows: Annotated[int, Field(ge=16)] = 2048
    gap_px: NonNeg = 20.0
    bits: Annotated[int, Field(ge=8, le=16)] = 12
    prnu_rms: Annotated[float, Field(ge=0.0, lt=1.0)] = 0.01
    dark_current_e_per_s: NonNeg = 20.0
    dsnu_rms_e: NonNeg = Field(1.0, le=1e6, description="at most 1e6 e: beyond any full well, no sensor's pattern")
    background_e_per_s: NonNeg = 10.0
    qe: QEModel = QEModel()
    chips: Annotated[tuple[ChipModel, ...], Field(strict=False)] = (
        ChipModel(),
        ChipModel(gain_e_per_dn=1.05),
    )

    @model_validator(mode="after")
    def _chips(self) -> DetectorModel:
        if len(self.chips) != self.n_chips:
            raise ValueError(f"chips lists {len(self.chips)} chip(s) but n_chips = {self.n_chips}")
        return self

    @property
    def mosaic_shape(self) -> tuple[int, int]:
        """(rows, cols) of the mosaic array."""
        return self.chip_rows, self.chip_cols * self.n_chips


# --------------------------------------------------------------------------- render
class RenderModel(SectionModel):
    """Rendering controls: windows, PSF stamps, wavelength sampling."""

    window_px: Annotated[int, Field(ge=3, le=63)] = 11
    stamp_px: Annotated[int, Field(ge=8, le=128)] = 32
    wavelength_min_nm: Pos = 400.0
    wavelength_max_nm: Pos = 1000.0
    wavelength_step_nm: Pos = 10.0
    #: how PSF stamps are computed (simcam.starcam.render, docs/simulator.md): "exact" sums the
    #: wavelengths for every scene; "profile" sums them once per target, filter and hexapod pose
    #: rounded to ``stamp_profile_step_px`` and moves the stars to their actual positions and
    #: PSF widths exactly (only the lateral colour's spread about its mean keeps the rounded pose's)
    stamp_route: Literal["exact", "profile"] = "profile"
    stamp_profile_step_px: Annotated[float, Field(gt=0.0, le=64.0)] = 1.0

    @model_validator(mode="after")
    def _sizes(self) -> RenderModel:
        if self.window_px % 2 == 0:
            raise ValueError(f"window_px must be odd (a window centred on a pixel), got {self.window_px}")
        if self.window_px > self.stamp_px:
            raise ValueError(f"window_px ({self.window_px}) larger than stamp_px ({self.stamp_px})")
        if self.wavelength_max_nm <= self.wavelength_min_nm:
            raise ValueError("wavelength_max_nm must exceed wavelength_min_nm")
        return self
