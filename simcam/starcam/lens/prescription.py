"""Lens prescription: typed model of a sequential, rotationally symmetric lens, from TOML.

A prescription lists the surfaces in the order light meets them, object (at infinity)
on the left, image on the right, light travelling along +z::

    name = "star_camera"
    [analysis]
    field_max_deg = 3.8            # products are traced from 0 to this field angle
    [[surfaces]]
    name = "stop"
    radius_mm = inf                # inf: a plane
    thickness_mm = 5.0             # to the next surface (the last: to the image plane)
    glass = "air"                  # the medium after this surface
    semi_diameter_mm = 30.0        # clear aperture radius; rays outside are vignetted
    stop = true                    # exactly one aperture stop
    [[surfaces]]
    radius_mm = 120.0
    conic = 0.0                    # optional conic constant
    aspheric_coeffs = []           # optional A4, A6, ... (mm^-3, mm^-5, ...)
    ...
    [[glasses]]                    # optional glasses defined by Sellmeier coefficients
    name = "MY-GLASS"
    sellmeier_b = [1.0, 0.2, 1.0]
    sellmeier_c_um2 = [0.006, 0.02, 100.0]
    source = "vendor data sheet, 2024"

Radii follow the usual sign convention (positive: centre of curvature to the right of
the vertex). Glass names come from :mod:`simcam.starcam.lens.glass` or the ``[[glasses]]``
tables. Errors name the file and the surface: ``surfaces.3.thickness_mm: Input should be
greater than or equal to 0`` (indices are 0-based, as in the TOML array), an unknown
glass, surfaces that cross inside their clear apertures, a semi-diameter outside a
conic's domain, no or several stops.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import ConfigDict, Field, field_validator, model_validator

from simcam.config_base import StrictModel, read_toml, validate_model
from simcam.infra.errors import ScenarioError
from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.glass import AIR, Glass, get_glass
from simcam.starcam.lens.surface import SurfaceShape

__all__ = [
    "EMBEDDED_PREFIX",
    "PRODUCTS_VERSION",
    "AnalysisModel",
    "GlassModel",
    "Prescription",
    "SurfaceModel",
    "embedded_lens_names",
    "load_prescription",
    "prescription_from_dict",
]

#: Bumped whenever the traced products change meaning or format (part of the cache key).
PRODUCTS_VERSION = 1

#: Prefix of a reference to a lens shipped in ``simcam/data/lenses`` (``embedded:star_camera``).
EMBEDDED_PREFIX = "embedded:"

Pos = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
NonNeg = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]


class _Model(StrictModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, validate_default=True)


class GlassModel(_Model):
    """A glass defined in the prescription by its Sellmeier coefficients (see simcam.starcam.lens.glass)."""

    name: Annotated[str, Field(min_length=1)]
    sellmeier_b: Annotated[tuple[Finite, Finite, Finite], Field(strict=False)]
    sellmeier_c_um2: Annotated[tuple[Finite, Finite, Finite], Field(strict=False)]
    source: Annotated[str, Field(min_length=1)]
    valid_nm: Annotated[tuple[Pos, Pos], Field(strict=False)] = (300.0, 2500.0)

    def to_glass(self) -> Glass:
        """The :class:`~simcam.starcam.lens.glass.Glass` (checked: no pole, n > 1 over its range)."""
        return Glass(name=self.name.upper(), b=tuple(self.sellmeier_b), c_um2=tuple(self.sellmeier_c_um2),
                     source=self.source, valid_nm=tuple(self.valid_nm))


class SurfaceModel(_Model):
    """One refracting surface and the gap after it.

    ``radius_mm``: vertex radius of curvature (``inf`` or ``-inf`` for a plane; 0 is
    refused). ``thickness_mm``: axial distance to the next surface (for the last
    surface, to the image plane used when ``analysis.focus = "prescription"``).
    ``glass``: the medium after the surface (``air`` or a glass name).
    ``semi_diameter_mm``: clear-aperture radius. ``conic``, ``aspheric_coeffs``: see
    :mod:`simcam.starcam.lens.surface`.
    """

    name: str = ""
    radius_mm: float = Field(allow_inf_nan=True)  # inf or -inf: a plane (the one infinite value of a scenario)
    thickness_mm: NonNeg
    glass: Annotated[str, Field(min_length=1)] = "air"
    semi_diameter_mm: Pos
    stop: bool = False
    conic: Finite = 0.0
    aspheric_coeffs: Annotated[tuple[Finite, ...], Field(strict=False)] = ()

    @field_validator("radius_mm")
    @classmethod
    def _radius(cls, v: float) -> float:
        if math.isnan(v):
            raise ValueError("must be a number (inf for a plane), got NaN")
        if v == 0.0:
            raise ValueError("must not be 0 (use inf for a plane)")
        return v

    @property
    def curvature_per_mm(self) -> float:
        """``1 / radius_mm`` (0 for a plane)."""
        return 0.0 if math.isinf(self.radius_mm) else 1.0 / self.radius_mm

    @property
    def shape(self) -> SurfaceShape:
        """The surface's :class:`~simcam.starcam.lens.surface.SurfaceShape`."""
        return SurfaceShape(curvature_per_mm=self.curvature_per_mm, conic=self.conic,
                            aspheric_coeffs=tuple(self.aspheric_coeffs))


class AnalysisModel(_Model):
    """How the products are traced (part of the cache key).

    * ``field_max_deg``, ``field_points``: field angles ``0 .. field_max_deg`` (equally
      spaced), in the meridional plane (the lens is rotationally symmetric);
    * ``wavelength_min_nm``, ``wavelength_max_nm``, ``wavelength_points``: the wavelength
      grid; ``reference_wavelength_nm``: where the paraxial data are quoted;
    * ``rays_per_bundle``: rays per field point and wavelength (entrance pupil sampled
      uniformly by a Vogel spiral); ``focus_rays_per_bundle``: rays per bundle of the
      pass that locates the best focus;
    * ``focus``: the image plane of the products: ``best`` (least mean-square spot radius
      over every field point and wavelength), ``paraxial`` (paraxial focus at the
      reference wavelength) or ``prescription`` (the last surface's thickness);
    * ``pixel_pitch_um``, ``psf_stamp_px``: pixel pitch and size of the PSF stamps.
    """

    field_max_deg: Annotated[float, Field(gt=0.0, lt=60.0, allow_inf_nan=False)]
    field_points: Annotated[int, Field(ge=2, le=200)] = 10
    wavelength_min_nm: Pos = 400.0
    wavelength_max_nm: Pos = 1000.0
    wavelength_points: Annotated[int, Field(ge=2, le=200)] = 15
    reference_wavelength_nm: Pos = 600.0
    rays_per_bundle: Annotated[int, Field(ge=64, le=10_000_000)] = 100_000
    focus_rays_per_bundle: Annotated[int, Field(ge=64, le=10_000_000)] = 8192
    focus: Literal["best", "paraxial", "prescription"] = "best"
    pixel_pitch_um: Pos = 5.5
    psf_stamp_px: Annotated[int, Field(ge=8, le=256)] = 32

    @model_validator(mode="after")
    def _ranges(self) -> AnalysisModel:
        if self.wavelength_max_nm <= self.wavelength_min_nm:
            raise ValueError("wavelength_max_nm must exceed wavelength_min_nm")
        if not self.wavelength_min_nm <= self.reference_wavelength_nm <= self.wavelength_max_nm:
            raise ValueError(
                f"reference_wavelength_nm = {self.reference_wavelength_nm:g} lies outside "
                f"{self.wavelength_min_nm:g}-{self.wavelength_max_nm:g} nm"
            )
        return self

    @property
    def field_deg(self) -> np.ndarray:
        """Field angles of the products, deg."""
        return np.linspace(0.0, self.field_max_deg, self.field_points)

    @property
    def wavelength_nm(self) -> np.ndarray:
        """Wavelengths of the products, nm."""
        return np.linspace(self.wavelength_min_nm, self.wavelength_max_nm, self.wavelength_points)


class Prescription(_Model):
    """A sequential lens with its object at infinity (see module docstring).

    Derived quantities: :attr:`vertex_z_mm` (surface vertices, first at 0),
    :meth:`media` (the glass of every space), :attr:`stop_index`, :attr:`hash`.
    """

    name: Annotated[str, Field(min_length=1)]
    description: str = ""
    analysis: AnalysisModel
    surfaces: Annotated[tuple[SurfaceModel, ...], Field(strict=False, min_length=1)]
    glasses: Annotated[tuple[GlassModel, ...], Field(strict=False)] = ()

    model_config = ConfigDict(
        extra="forbid", frozen=True, strict=True, validate_default=True, ignored_types=(cached_property,)
    )

    @model_validator(mode="after")
    def _consistent(self) -> Prescription:
        stops = [i for i, s in enumerate(self.surfaces) if s.stop]
        if len(stops) != 1:
            raise ValueError(
                f"surfaces: exactly one surface needs stop = true (found {len(stops)}"
                + (f": surfaces {stops}" if stops else "") + ")"
            )
        extra = self._extra_glasses()
        for i, s in enumerate(self.surfaces):
            try:
                g = get_glass(s.glass, extra)
            except LensError as exc:
                raise ValueError(f"surfaces.{i}.glass: {exc}") from None
            aw = self.analysis
            if not g.is_air:
                lo, hi = g.valid_nm
                if aw.wavelength_min_nm < lo or aw.wavelength_max_nm > hi:
                    raise ValueError(
                        f"surfaces.{i}.glass: {g.name}'s Sellmeier fit is valid over {lo:g}-{hi:g} nm, "
                        f"analysis asks {aw.wavelength_min_nm:g}-{aw.wavelength_max_nm:g} nm"
                    )
        if not get_glass(self.surfaces[-1].glass, extra).is_air:
            raise ValueError(f"surfaces.{len(self.surfaces) - 1}.glass: the image space must be air "
                             f"(got {self.surfaces[-1].glass!r})")
        for i, s in enumerate(self.surfaces):
            smax = s.shape.max_s_mm2()
            if s.semi_diameter_mm**2 > smax * (1.0 + 1e-12):
                raise ValueError(
                    f"surfaces.{i}.semi_diameter_mm: {s.semi_diameter_mm:g} mm exceeds the surface's "
                    f"domain (radius {s.radius_mm:g} mm, conic {s.conic:g}: at most {math.sqrt(smax):.6g} mm)"
                )
        # surfaces must not cross inside the common clear aperture (negative edge gap)
        z = self.vertex_z_mm
        for i in range(len(self.surfaces) - 1):
            a, b = self.surfaces[i], self.surfaces[i + 1]
            rho = np.linspace(0.0, min(a.semi_diameter_mm, b.semi_diameter_mm), 129)
            s2 = rho * rho
            gap = (z[i + 1] + b.shape.sag(s2)) - (z[i] + a.shape.sag(s2))
            k = int(np.argmin(gap))
            if gap[k] < -1e-9:
                raise ValueError(
                    f"surfaces.{i + 1}: crosses surface {i} inside the clear aperture (gap "
                    f"{gap[k]:.4g} mm at radius {rho[k]:.4g} mm); increase surfaces.{i}.thickness_mm "
                    "or reduce the semi-diameters"
                )
        return self

    def _extra_glasses(self) -> dict[str, Glass]:
        out: dict[str, Glass] = {}
        for j, gm in enumerate(self.glasses):
            try:
                out[gm.name.upper()] = gm.to_glass()
            except LensError as exc:
                raise ValueError(f"glasses.{j}: {exc}") from None
        return out

    # ------------------------------------------------------------------ derived
    @cached_property
    def vertex_z_mm(self) -> np.ndarray:
        """Axial position of every surface vertex, mm (the first at 0)."""
        t = np.array([s.thickness_mm for s in self.surfaces[:-1]], dtype=np.float64)
        return np.concatenate([[0.0], np.cumsum(t)])

    @property
    def image_distance_mm(self) -> float:
        """Thickness after the last surface: the prescription's image plane distance, mm."""
        return float(self.surfaces[-1].thickness_mm)

    @cached_property
    def stop_index(self) -> int:
        """Index of the aperture stop surface."""
        return next(i for i, s in enumerate(self.surfaces) if s.stop)

    def media(self) -> list[Glass]:
        """The glass of each space: ``[object space (air), after surface 0, ..., image space]``."""
        extra = self._extra_glasses()
        return [AIR] + [get_glass(s.glass, extra) for s in self.surfaces]

    def indices(self, wavelength_nm) -> np.ndarray:
        """Refractive index of every space at each wavelength, shape ``(n_surfaces + 1, n_wl)``."""
        wl = np.atleast_1d(np.asarray(wavelength_nm, dtype=np.float64))
        return np.array([g.refractive_index(wl) for g in self.media()])

    @cached_property
    def hash(self) -> str:
        """SHA-256 prefix over the prescription, the Sellmeier data of its glasses and
        :data:`PRODUCTS_VERSION`: the key of the products' disk cache."""
        payload = {
            "version": PRODUCTS_VERSION,
            "prescription": _canonical(self.model_dump(mode="python")),
            "glasses": [[g.name, list(g.b), list(g.c_um2)] for g in self.media()],
        }
        text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _canonical(obj: Any) -> Any:
    """JSON-safe copy in which infinities are spelled out (pydantic's json mode would null them)."""
    if isinstance(obj, dict):
        return {k: _canonical(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    if isinstance(obj, float) and math.isinf(obj):
        return "inf" if obj > 0 else "-inf"
    return obj


def prescription_from_dict(data: dict[str, Any], *, source: str | None = None) -> Prescription:
    """Validate a parsed TOML table into a :class:`Prescription`, or raise :class:`LensError`."""
    if not isinstance(data, dict):
        raise LensError(f"{source or 'prescription'}: top level must be a table")
    try:
        return validate_model(Prescription, data, source=source)
    except ScenarioError as exc:
        # whole-prescription checks name their field themselves: drop pydantic's
        # "(top level): Value error, " and the echo of the whole table
        lines = []
        for line in str(exc).splitlines():
            if "(top level): Value error, " in line:
                line = line.replace("(top level): Value error, ", "")
                line = re.sub(r" \(got \{.*$", "", line)
            lines.append(line)
        raise LensError("\n".join(lines)) from None


def embedded_lens_names() -> list[str]:
    """Names of the lenses shipped with simcam (``embedded:NAME``)."""
    root = resources.files("simcam.data").joinpath("lenses")
    return sorted(p.name[:-5] for p in root.iterdir() if p.name.endswith(".toml"))


def load_prescription(ref: str | Path) -> Prescription:
    """Load a prescription: ``"embedded:NAME"`` (a lens shipped with simcam) or a TOML path.

    Raises
    ------
    LensError
        Unknown embedded name, missing file, invalid TOML or an invalid prescription.
    """
    if isinstance(ref, Prescription):
        return ref
    ref_s = str(ref)
    if ref_s.startswith(EMBEDDED_PREFIX):
        name = ref_s[len(EMBEDDED_PREFIX):]
        names = embedded_lens_names()
        if name not in names:
            raise LensError(f"{ref_s}: no embedded lens {name!r} (embedded: {', '.join(names)})")
        text = resources.files("simcam.data").joinpath("lenses").joinpath(f"{name}.toml").read_text()
        source = f"<embedded lens {name}>"
    else:
        path = Path(ref_s)
        if not path.is_file():
            raise LensError(f"{path}: lens prescription file not found (or use embedded:NAME, one of "
                            f"{', '.join(embedded_lens_names())})")
        source = str(path)
        try:
            return prescription_from_dict(read_toml(path=path, source=source), source=source)  # strict TOML
        except ScenarioError as exc:
            raise LensError(str(exc)) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise LensError(f"{source}: not valid TOML: {exc}") from None
    return prescription_from_dict(data, source=source)
