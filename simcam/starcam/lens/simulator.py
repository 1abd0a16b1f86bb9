"""The traced lens as the simulator's optics: its tables reduced to the models of simcam.starcam.optics.

The simulator (:mod:`simcam.starcam.render`) and the truth of the Monte Carlo validation
(:mod:`budget.starcam.truth`) use three optics models: a distortion object (Brown-Conrady then a
full cubic, :class:`simcam.starcam.optics.CompositeDistortion`), a lateral-colour displacement
(:func:`simcam.starcam.optics.lateral_colour_shift_px`) and a PSF (Airy of the aperture with a
Gaussian blur ``sigma0 + sigma_r2 (r / r_norm)^2``). With ``optics.lens`` set in a
scenario, their coefficients come from the traced products (:mod:`simcam.starcam.lens.products`)
by least squares, so that both meet on the traced grid:

* **Frames.** The lens images a star at ``+theta`` (towards +x) at ``x < 0``; the
  focal-plane coordinates of the simulator put it at ``u = +(f/p) tan(theta)``
  (``docs/conventions.md``), i.e. ``u = -x / p``: the detector frame is the lens frame
  turned by 180 deg about the axis, which undoes the inversion. The lens is rotationally
  symmetric, so everything is a function of the field radius.
* **Distortion** at the reference wavelength ``lambda_ref`` (the scenario's
  ``optics.lateral_colour.ref_wavelength_nm``): the centroid radius ``u_f`` (spline
  in wavelength through the traced grid, evaluated at ``lambda_ref``) against the ideal
  gnomonic radius ``u0_f = (f_nom / p) tan(theta_f)`` of the camera's nominal focal
  length. In normalised radii ``rho = u0 / r_norm``, ``u / r_norm = a1 rho + a3 rho^3 + a5 rho^5``
  (least squares), which is exactly Brown-Conrady ``k1 = a3 / a1``, ``k2 = a5 / a1``
  followed by the cubic's linear terms ``cubic_x_px[1] = cubic_y_px[2] = (a1 - 1) r_norm``
  (a plate-scale difference between the lens and the nominal focal length).
* **Lateral colour**: ``u_f(lambda) - u_f(lambda_ref) = (u_f / r_norm) sum_k sum_m c_km
  (lambda - lambda_ref)^k (u_f / r_norm)^(2m)`` with ``u_f = u_f(lambda_ref)`` (the
  simulator's radial model in its table form, :func:`simcam.starcam.optics.lateral_colour_shift_px`,
  evaluated at the distorted position as the renderer does: primary, secondary and
  tertiary lateral colour, ``m = 0, 1, 2``), least squares over the traced field points
  and the wavelengths inside the scenario's render range, ``k = 1 .. min(7, n - 1)``;
  the uniform (decentring) terms are zero for a centred lens.
* **PSF**: ``kind = "airy"`` (diffraction of the camera's aperture, which must equal the
  lens's entrance pupil) with the Gaussian blur of the geometric spot: per field point
  ``sigma_f^2 = mean_lambda (sigma_x^2 + sigma_y^2) / 2`` (rms about each wavelength's
  own centroid: the chromatic displacement is modelled apart), fitted as
  ``sigma0 + sigma_r2 rho^2``.

The fit residuals (rms and max, px) say what the simulator's models leave out of the
traced lens; :func:`simulator_optics` returns them with the coefficients.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import ValidationError
from scipy.interpolate import CubicSpline

from simcam.starcam import optics
from simcam.starcam.instrument import (CameraModel, DetectorModel, DistortionModel, LateralColourModel, OpticsModel,
                                       PSFModel, RenderModel)
from simcam.starcam.lens.errors import LensError
from simcam.starcam.lens.paraxial import paraxial
from simcam.starcam.lens.prescription import Prescription, load_prescription
from simcam.starcam.lens.products import LensProducts, lens_products

__all__ = ["LENS_DERIVED_PATHS", "MATCH_TOL_PX", "SimulatorOptics", "apply_lens", "simulator_optics"]

#: Scenario fields set by ``optics.lens`` (dotted paths), the star camera scenario's
#: derived fields (:meth:`simcam.starcam.scenario.Scenario.derived_paths`): setting values by
#: dotted key drops those not set (:mod:`simcam.dotted`) so that the lens derives them again;
#: a value given for them must be what the lens gives.
LENS_DERIVED_PATHS = (
    "optics.psf",
    "optics.distortion",
    "optics.lateral_colour.radial_px_per_nm",
    "optics.lateral_colour.uniform_x_px_per_nm",
    "optics.lateral_colour.uniform_y_px_per_nm",
    "camera.aperture_diameter_mm",
)

#: A given value matches the lens when its displacements differ by less than this, px.
MATCH_TOL_PX = 1e-6
#: Powers of (lambda - lambda_ref) and of the squared field radius in the lateral-colour fit.
LATERAL_COLOUR_WAVELENGTH_ORDER = 7
LATERAL_COLOUR_FIELD_TERMS = 3
#: Relative tolerance of the camera's nominal focal length against the lens's EFL.
FOCAL_LENGTH_RTOL = 1e-3
#: Margin (px) added to the detector's half diagonal for the field the lens must cover.
FIELD_MARGIN_PX = 16.0


@dataclass(frozen=True, eq=False)
class SimulatorOptics:
    """The lens in the simulator's terms (see module docstring); lengths in px of the camera.

    Attributes
    ----------
    efl_mm, entrance_pupil_diameter_mm : float
        Paraxial focal length and entrance pupil diameter at the reference wavelength.
    k1, k2 : float
        Brown-Conrady radial coefficients.
    cubic_x_px, cubic_y_px : tuple of 10 float
        Cubic distortion coefficients (only the linear scale terms are non-zero).
    radial_px_per_nm : tuple of tuple of float
        Lateral-colour table ``c[k-1][m]`` (px / nm^k at ``(r / r_norm)^(2m)``).
    sigma0_px, sigma_r2_px : float
        Gaussian blur of the Airy PSF.
    distortion_rms_px, distortion_max_px : float
        Fit residual of the distortion at the traced field points.
    lateral_colour_rms_px, lateral_colour_max_px : float
        Fit residual of the lateral colour over field points and wavelengths.
    psf_sigma_rms_px : float
        Fit residual of the blur sigma.
    field_u_px, measured_u_px, ideal_u_px : ndarray
        The traced field points: ideal and measured (at the reference wavelength) radii.
    """

    efl_mm: float
    entrance_pupil_diameter_mm: float
    r_norm_px: float
    ref_wavelength_nm: float
    k1: float
    k2: float
    cubic_x_px: tuple
    cubic_y_px: tuple
    radial_px_per_nm: tuple
    sigma0_px: float
    sigma_r2_px: float
    distortion_rms_px: float
    distortion_max_px: float
    lateral_colour_rms_px: float
    lateral_colour_max_px: float
    psf_sigma_rms_px: float
    ideal_u_px: np.ndarray
    measured_u_px: np.ndarray

    def scenario_sections(self) -> dict:
        """The scenario values the lens sets (``optics.psf``, ``optics.distortion``, the
        lateral-colour coefficients, ``camera.aperture_diameter_mm``), as plain data."""
        return {
            "optics.psf": {"kind": "airy", "sigma0_px": self.sigma0_px, "sigma_r2_px": self.sigma_r2_px},
            "optics.distortion": {"k1": self.k1, "k2": self.k2, "p1": 0.0, "p2": 0.0,
                                  "cubic_x_px": list(self.cubic_x_px), "cubic_y_px": list(self.cubic_y_px)},
            "optics.lateral_colour.radial_px_per_nm": [list(row) for row in self.radial_px_per_nm],
            "optics.lateral_colour.uniform_x_px_per_nm": [],
            "optics.lateral_colour.uniform_y_px_per_nm": [],
            "camera.aperture_diameter_mm": self.entrance_pupil_diameter_mm,
        }

    def distortion(self):
        """The fitted :class:`simcam.starcam.optics.CompositeDistortion`."""
        return optics.CompositeDistortion(
            brown_conrady=optics.BrownConradyDistortion(k1=self.k1, k2=self.k2, r_norm_px=self.r_norm_px),
            cubic=optics.CubicDistortion(coeffs_x=self.cubic_x_px, coeffs_y=self.cubic_y_px, r_norm_px=self.r_norm_px),
        )


def _lstsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    coef, *_ = np.linalg.lstsq(a, b, rcond=None)
    return coef


def simulator_optics(products: LensProducts, prescription: Prescription, *, pixel_pitch_um: float,
                     focal_length_mm: float, r_norm_px: float, ref_wavelength_nm: float,
                     wavelength_min_nm: float, wavelength_max_nm: float) -> SimulatorOptics:
    """Fit the simulator's optics models to traced ``products`` (module docstring).

    Parameters
    ----------
    products : LensProducts
    prescription : Prescription
        The lens (for the paraxial data at ``ref_wavelength_nm``).
    pixel_pitch_um, focal_length_mm : float
        The camera's pixel pitch and nominal focal length (its plate scale).
    r_norm_px : float
        The simulator's field normalisation.
    ref_wavelength_nm : float
        Reference wavelength of the lateral colour (zero shift) and of the distortion.
    wavelength_min_nm, wavelength_max_nm : float
        The render's wavelength range (must lie within the traced range).

    Raises
    ------
    LensError
        A wavelength range outside the traced one.
    """
    wl = products.wavelength_nm
    lo, hi = float(wl.min()), float(wl.max())
    eps = 1e-9 * hi
    for name, v in (("render.wavelength_min_nm", wavelength_min_nm), ("render.wavelength_max_nm", wavelength_max_nm),
                    ("optics.lateral_colour.ref_wavelength_nm", ref_wavelength_nm)):
        if not lo - eps <= v <= hi + eps:
            raise LensError(f"{name}: {v:g} nm is outside the lens's traced range {lo:g}-{hi:g} nm "
                            f"(analysis.wavelength_min_nm / wavelength_max_nm of {prescription.name})")
    p_mm = pixel_pitch_um * 1e-3
    rn = float(r_norm_px)
    u = -products.centroid_x_mm / p_mm  # (nf, nl) radial image position, simulator frame, px
    u_ref = CubicSpline(wl, u, axis=1)(ref_wavelength_nm)
    u0 = focal_length_mm * np.tan(np.radians(products.field_deg)) / p_mm
    rho = u0 / rn
    # distortion: u_ref / rn = a1 rho + a3 rho^3 + a5 rho^5
    a = np.stack([rho, rho**3, rho**5], axis=1)
    a1, a3, a5 = _lstsq(a, u_ref / rn)
    fit_u = rn * (a @ np.array([a1, a3, a5]))
    d_res = u_ref - fit_u
    cubic_x = [0.0] * 10
    cubic_y = [0.0] * 10
    cubic_x[1] = (a1 - 1.0) * rn
    cubic_y[2] = (a1 - 1.0) * rn
    # lateral colour: u(l) - u(l_ref) = (u_ref / rn) sum_k c_k dl^k over the render range
    sel = (wl >= wavelength_min_nm - eps) & (wl <= wavelength_max_nm + eps)
    if sel.sum() < 2:
        raise LensError(f"render wavelength range {wavelength_min_nm:g}-{wavelength_max_nm:g} nm holds fewer than "
                        f"2 traced wavelengths of {prescription.name}; trace a finer grid")
    dl = wl[sel] - ref_wavelength_nm
    deg = int(min(LATERAL_COLOUR_WAVELENGTH_ORDER, sel.sum() - 1))
    n_field = int(min(LATERAL_COLOUR_FIELD_TERMS, max(1, np.count_nonzero(u_ref > 0) - 1)))
    scale = 100.0  # nm: conditioning of the powers
    shift = u[:, sel] - u_ref[:, None]  # (nf, n_sel)
    fld = u_ref / rn
    k_pow = np.arange(1, deg + 1)
    m_pow = np.arange(n_field)
    # design matrix [f, l, k, m] = (u_f / rn) (dl_l / scale)^k (u_f / rn)^(2m)
    rows = (fld[:, None, None, None] * (dl[None, :, None, None] / scale) ** k_pow[None, None, :, None]
            * (fld**2)[:, None, None, None] ** m_pow[None, None, None, :]).reshape(-1, deg * n_field)
    b = _lstsq(rows, shift.ravel()).reshape(deg, n_field)
    radial = tuple(tuple(float(b[k, m] / scale ** (k + 1)) for m in range(n_field)) for k in range(deg))
    c_res = shift.ravel() - rows @ b.ravel()
    # PSF blur: geometric rms per axis about each wavelength's centroid
    sig = np.sqrt(np.mean((products.sigma_x_mm[:, sel] ** 2 + products.sigma_y_mm[:, sel] ** 2) / 2.0, axis=1)) / p_mm
    s0, s2 = _lstsq(np.stack([np.ones_like(rho), rho**2], axis=1), sig)
    if s0 < 0.0:
        s0, s2 = 0.0, float(_lstsq((rho**2)[:, None], sig)[0])
    s_res = sig - (s0 + s2 * rho**2)
    para = paraxial(prescription, wavelength_nm=ref_wavelength_nm)
    return SimulatorOptics(
        efl_mm=para.efl_mm, entrance_pupil_diameter_mm=2.0 * para.entrance_pupil_radius_mm, r_norm_px=rn,
        ref_wavelength_nm=float(ref_wavelength_nm),
        k1=float(a3 / a1), k2=float(a5 / a1), cubic_x_px=tuple(float(c) for c in cubic_x),
        cubic_y_px=tuple(float(c) for c in cubic_y), radial_px_per_nm=radial, sigma0_px=float(s0),
        sigma_r2_px=float(s2),
        distortion_rms_px=float(np.sqrt(np.mean(d_res**2))), distortion_max_px=float(np.abs(d_res).max()),
        lateral_colour_rms_px=float(np.sqrt(np.mean(c_res**2))), lateral_colour_max_px=float(np.abs(c_res).max()),
        psf_sigma_rms_px=float(np.sqrt(np.mean(s_res**2))), ideal_u_px=u0, measured_u_px=u_ref,
    )


# ----------------------------------------------------------------------------------------
# scenario resolution


def _get(container, key, default=None):
    """Value of ``key`` in a dict or a pydantic model (None if absent)."""
    if container is None:
        return default
    if isinstance(container, dict):
        return container.get(key, default)
    return getattr(container, key, default)


def _given(container, key) -> bool:
    """Whether ``key`` was given: present in a dict, or explicitly set on a model."""
    if container is None:
        return False
    if isinstance(container, dict):
        return key in container
    return key in getattr(container, "model_fields_set", set())


def _as_dict(container) -> dict:
    if container is None:
        return {}
    if isinstance(container, dict):
        return dict(container)
    return {k: getattr(container, k) for k in container.model_fields_set}


def _validated(model_cls, raw):
    """``model_cls`` from a dict or instance, or None when invalid (reported by the main validation)."""
    if isinstance(raw, model_cls):
        return raw
    try:
        return model_cls.model_validate(raw if raw is not None else {})
    except (ValidationError, ValueError, TypeError):
        return None


def _max_field_px(detector) -> float:
    half_u = (detector.n_chips * detector.chip_cols + (detector.n_chips - 1) * detector.gap_px) / 2.0
    half_v = detector.chip_rows / 2.0
    return math.hypot(half_u, half_v) + FIELD_MARGIN_PX


def _check_match(name: str, lens_ref: str, diff_px: float, wanted: str) -> None:
    if not diff_px <= MATCH_TOL_PX:
        raise ValueError(
            f"{name}: set by optics.lens = {lens_ref!r} and given a different value (differs by "
            f"{diff_px:.3g} px in the field); remove it to let the lens set it ({wanted})"
        )


def apply_lens(data: dict) -> dict:
    """Resolve ``optics.lens`` in a raw scenario table: trace (or read) the lens's products
    and fill the fields it sets (:data:`LENS_DERIVED_PATHS`).

    Returns ``data`` unchanged when no lens is given or when the camera, optics, detector
    or render sections are invalid (the scenario's own validation then reports them).

    Raises
    ------
    ValueError
        Naming the field: a lens that cannot be loaded or traced, a camera focal length or
        aperture that contradicts the lens, a field or wavelength range the lens does not
        cover, a lens-set value given with another value.
    """
    ctx = _lens_context(data)
    if ctx is None:
        return data
    sections = ctx.fit.scenario_sections()
    out = dict(data)
    # camera aperture = entrance pupil diameter
    camera_out = _lens_aperture(data, ctx, sections["camera.aperture_diameter_mm"])
    if camera_out is not None:
        out["camera"] = camera_out
    optics_out = _as_dict(ctx.optics_raw)
    if not _psf_matches(ctx, sections["optics.psf"]):
        return data
    optics_out["psf"] = sections["optics.psf"]
    if not _distortion_matches(ctx, sections["optics.distortion"]):
        return data
    optics_out["distortion"] = sections["optics.distortion"]
    lc_out = _lens_lateral_colour(ctx, sections)
    if lc_out is None:
        return data
    optics_out["lateral_colour"] = lc_out
    out["optics"] = optics_out
    return out


@dataclass(frozen=True, eq=False)
class _LensContext:
    """What :func:`apply_lens` checks a scenario's lens-set fields against: the lens named by
    ``optics.lens`` (``lens_ref``), the raw ``optics`` and ``optics.lateral_colour`` sections,
    the validated camera and render sections, the field normalisation, reference wavelength
    and the field the detector reaches (px), and the lens fitted to the simulator's models."""

    lens_ref: str
    optics_raw: object
    lc_raw: object
    camera: CameraModel
    render: RenderModel
    r_norm: float
    ref_wl: float
    field_px: float
    fit: SimulatorOptics


def _lens_context(data: dict) -> _LensContext | None:
    """The :class:`_LensContext` of a raw scenario table; ``None`` when no lens is given or
    when the camera, optics, detector or render sections are invalid."""
    optics_raw = _get(data, "optics")
    lens_ref = _get(optics_raw, "lens")
    if lens_ref is None:
        return None
    if not isinstance(lens_ref, str) or not lens_ref.strip():
        raise ValueError(f"optics.lens: expected a lens file path or 'embedded:NAME', got {lens_ref!r}")
    camera = _validated(CameraModel, _get(data, "camera"))
    render = _validated(RenderModel, _get(data, "render"))
    detector = _validated(DetectorModel, _get(data, "detector"))
    lc_raw = _get(optics_raw, "lateral_colour")
    r_norm = _get(optics_raw, "r_norm_px", OpticsModel.model_fields["r_norm_px"].default)
    ref_wl = _get(lc_raw, "ref_wavelength_nm", LateralColourModel.model_fields["ref_wavelength_nm"].default)
    if camera is None or render is None or detector is None or not isinstance(r_norm, (int, float)) \
            or not isinstance(ref_wl, (int, float)) or r_norm <= 0 or ref_wl <= 0:
        return None
    field_px = _max_field_px(detector)
    fit = _lens_fit(lens_ref, camera, render, field_px=field_px, r_norm=r_norm, ref_wl=ref_wl)
    return _LensContext(lens_ref=lens_ref, optics_raw=optics_raw, lc_raw=lc_raw, camera=camera, render=render,
                        r_norm=r_norm, ref_wl=ref_wl, field_px=field_px, fit=fit)


def _lens_fit(lens_ref: str, camera: CameraModel, render: RenderModel, *, field_px: float, r_norm,
              ref_wl) -> SimulatorOptics:
    """The lens ``lens_ref`` traced (or read) and fitted to the simulator's models
    (:func:`simulator_optics`), after checking that it has the camera's focal length and
    covers the detector's field."""
    try:
        presc = load_prescription(lens_ref)
        para = paraxial(presc, wavelength_nm=float(ref_wl))
    except LensError as exc:
        raise ValueError(f"optics.lens: {exc}") from None
    f_nom = camera.focal_length_effective_mm
    if abs(f_nom / para.efl_mm - 1.0) > FOCAL_LENGTH_RTOL:
        raise ValueError(
            f"camera: nominal focal length {f_nom:.6g} mm (plate scale {camera.scale_arcsec_per_px:.6g} "
            f"arcsec/px with {camera.pixel_pitch_um:g} um pixels) differs from the focal length of "
            f"optics.lens = {lens_ref!r}, {para.efl_mm:.6f} mm at {ref_wl:g} nm, by more than "
            f"{FOCAL_LENGTH_RTOL:.1%}; set camera.focal_length_mm = {para.efl_mm:.6f} (without plate_scale_arcsec)"
        )
    need_deg = math.degrees(math.atan(field_px * camera.pixel_pitch_um * 1e-3 / f_nom))
    if need_deg > presc.analysis.field_max_deg * (1 + 1e-12):
        raise ValueError(
            f"optics.lens: {presc.name} is traced to {presc.analysis.field_max_deg:g} deg but the detector "
            f"reaches {need_deg:.4g} deg from the axis; raise analysis.field_max_deg in the prescription"
        )
    try:
        prod = lens_products(presc)
        return simulator_optics(
            prod, presc, pixel_pitch_um=camera.pixel_pitch_um, focal_length_mm=f_nom, r_norm_px=float(r_norm),
            ref_wavelength_nm=float(ref_wl), wavelength_min_nm=render.wavelength_min_nm,
            wavelength_max_nm=render.wavelength_max_nm,
        )
    except LensError as exc:
        raise ValueError(f"optics.lens: {exc}") from None


def _lens_aperture(data: dict, ctx: _LensContext, epd: float) -> dict | None:
    """The ``camera`` section with the lens's entrance pupil diameter ``epd`` (mm) as its
    aperture, or ``None`` when the scenario gives that aperture itself (checked against
    ``epd``)."""
    cam_raw = _get(data, "camera")
    if _given(cam_raw, "aperture_diameter_mm"):
        if abs(ctx.camera.aperture_diameter_mm / epd - 1.0) > 1e-9:
            raise ValueError(
                f"camera.aperture_diameter_mm: {ctx.camera.aperture_diameter_mm:g} mm differs from the entrance "
                f"pupil of optics.lens = {ctx.lens_ref!r} ({epd:.9g} mm); remove it to let the lens set it"
            )
        return None
    cam = _as_dict(cam_raw)
    cam["aperture_diameter_mm"] = epd
    return cam


def _psf_matches(ctx: _LensContext, want_psf: dict) -> bool:
    """Whether a given ``optics.psf`` is valid (``False``: its own validation reports it);
    a valid one that differs from the lens's ``want_psf`` is a ``ValueError``."""
    psf_raw = _get(ctx.optics_raw, "psf")
    if _given(ctx.optics_raw, "psf") and _as_dict(psf_raw):
        psf = _validated(PSFModel, psf_raw)
        if psf is None:
            return False
        given = _as_dict(psf_raw)
        full = {**want_psf, **given}
        diff = max(abs(full["sigma0_px"] - want_psf["sigma0_px"]),
                   abs(full["sigma_r2_px"] - want_psf["sigma_r2_px"]) * (ctx.field_px / ctx.r_norm) ** 2)
        if full["kind"] != "airy":
            diff = math.inf
        _check_match("optics.psf", ctx.lens_ref, diff, f"kind = 'airy', sigma0_px = {want_psf['sigma0_px']!r}, "
                     f"sigma_r2_px = {want_psf['sigma_r2_px']!r}")
    return True


def _distortion_matches(ctx: _LensContext, want_d: dict) -> bool:
    """Whether a given ``optics.distortion`` is valid (``False``: its own validation reports
    it); a valid one whose displacements over the field differ from the lens's is a
    ``ValueError``."""
    dist_raw = _get(ctx.optics_raw, "distortion")
    if _given(ctx.optics_raw, "distortion") and _as_dict(dist_raw):
        given = {**want_d, **_as_dict(dist_raw)}
        dm = _validated(DistortionModel, given)
        if dm is None:
            return False
        r_norm, field_px, fit = ctx.r_norm, ctx.field_px, ctx.fit
        try:
            g = optics.CompositeDistortion(
                brown_conrady=optics.BrownConradyDistortion(k1=dm.k1, k2=dm.k2, p1=dm.p1, p2=dm.p2, r_norm_px=r_norm),
                cubic=optics.CubicDistortion(coeffs_x=dm.cubic_x_px, coeffs_y=dm.cubic_y_px, r_norm_px=r_norm))
        except optics.OpticsError:
            return False
        grid = np.linspace(-field_px, field_px, 21)
        uu, vv = np.meshgrid(grid, grid)
        gu, gv = g.forward(u_px=uu, v_px=vv)
        wu, wv = fit.distortion().forward(u_px=uu, v_px=vv)
        _check_match("optics.distortion", ctx.lens_ref, float(np.max(np.hypot(gu - wu, gv - wv))),
                     f"k1 = {fit.k1!r}, k2 = {fit.k2!r}")
    return True


def _lens_lateral_colour(ctx: _LensContext, sections: dict) -> dict | None:
    """The ``optics.lateral_colour`` section with the lens's coefficients, each given one
    compared with them by the displacements they give over field and band; ``None`` when a
    given one is invalid (its own validation reports it)."""
    lc_raw, ref_wl, r_norm, render = ctx.lc_raw, ctx.ref_wl, ctx.r_norm, ctx.render
    lc_out = _as_dict(lc_raw)
    wl_grid = np.linspace(render.wavelength_min_nm, render.wavelength_max_nm, 61)
    r_grid = np.linspace(0.0, ctx.field_px, 25)
    for key in ("radial_px_per_nm", "uniform_x_px_per_nm", "uniform_y_px_per_nm"):
        want = sections[f"optics.lateral_colour.{key}"]
        if _given(lc_raw, key):
            given = _get(lc_raw, key)
            kw_given = {"radial_coeffs": (), "uniform_x_coeffs": (), "uniform_y_coeffs": ()}
            kw_want = dict(kw_given)
            arg = {"radial_px_per_nm": "radial_coeffs", "uniform_x_px_per_nm": "uniform_x_coeffs",
                   "uniform_y_px_per_nm": "uniform_y_coeffs"}[key]
            kw_given[arg] = given
            kw_want[arg] = want
            try:
                gu, gv = optics.lateral_colour_shift_px(wavelength_nm=wl_grid, u_px=r_grid, v_px=0 * r_grid,
                                                        ref_wavelength_nm=float(ref_wl), r_norm_px=r_norm, **kw_given)
            except optics.OpticsError:
                return None
            wu, wv = optics.lateral_colour_shift_px(wavelength_nm=wl_grid, u_px=r_grid, v_px=0 * r_grid,
                                                    ref_wavelength_nm=float(ref_wl), r_norm_px=r_norm, **kw_want)
            _check_match(f"optics.lateral_colour.{key}", ctx.lens_ref, float(np.max(np.hypot(gu - wu, gv - wv))),
                         f"{want!r}")
        lc_out[key] = want
    return lc_out
