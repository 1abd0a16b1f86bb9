"""Camera optics: PSF width over the field, lateral colour and geometric distortion.

The pixel-integrated PSF stamps that the renderer draws with these are in
:mod:`simcam.starcam.psf_stamps`.

Coordinates follow ``docs/conventions.md``: detector (mosaic) pixel coordinates have
pixel centres at integers; focal-plane coordinates ``(u, v)`` are in nominal px from the
optical axis. Every displacement returned here is in px of the focal plane.

Public API
----------
psf_sigma_px
    Parametric PSF width over the field.
lateral_colour_shift_px, lateral_colour
    Chromatic lateral displacement (radial lateral colour + uniform prism-like term); its
    model at fixed wavelengths, for many positions.
BrownConradyDistortion, CubicDistortion, CompositeDistortion, HigherOrderRadialDistortion
    Geometric distortion with analytic Jacobian and Newton inverse (the Brown-Conrady model,
    the shared forward/inverse machinery and the errors live in :mod:`simcam.distortion`,
    which the line camera imports too; they are re-exported here).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from simcam.distortion import (  # noqa: F401  (shared with the line camera; re-exported here)
    BrownConradyDistortion,
    NonInvertibleDistortionError,
    OpticsError,
    _coords,
    _Distortion,
    _finite_array,
    _finite_float,
    _positive_float,
)

__all__ = [
    "OpticsError",
    "NonInvertibleDistortionError",
    "psf_sigma_px",
    "lateral_colour_shift_px",
    "LateralColour",
    "lateral_colour",
    "CUBIC_MONOMIALS",
    "BrownConradyDistortion",
    "CubicDistortion",
    "CompositeDistortion",
    "HigherOrderRadialDistortion",
]

# ----------------------------------------------------------------------------------------
# A. PSF width over the field


def psf_sigma_px(*, u_px, v_px, sigma0_px: float, sigma_r2_px: float, r_norm_px: float) -> np.ndarray:
    """Gaussian PSF sigma over the field, a parametric stand-in for field curvature.

    ``sigma(u, v) = sigma0 + sigma_r2 (r / r_norm)^2`` with ``r = sqrt(u^2 + v^2)``:
    the lowest-order rotationally symmetric growth of the blur with field (defocus from
    Petzval field curvature and astigmatism grow as field^2, Seidel third order).

    Parameters
    ----------
    u_px, v_px : array_like
        Focal-plane coordinates in px from the optical axis (broadcast together).
    sigma0_px : float
        On-axis sigma in px (> 0).
    sigma_r2_px : float
        Change of sigma at ``r = r_norm_px``, px (may be negative if the result stays > 0).
    r_norm_px : float
        Normalising radius in px (> 0).

    Returns
    -------
    ndarray
        Sigma in px at each point.

    Raises
    ------
    OpticsError
        Invalid parameters, or a non-positive sigma somewhere in the given field.
    """
    u = _finite_array("u_px", u_px)
    v = _finite_array("v_px", v_px)
    s0 = _positive_float("sigma0_px", sigma0_px)
    s2 = _finite_float("sigma_r2_px", sigma_r2_px)
    rn = _positive_float("r_norm_px", r_norm_px)
    try:
        r2 = (u * u + v * v) / (rn * rn)
    except ValueError:
        raise OpticsError(f"v_px: shape {v.shape} does not broadcast with u_px {u.shape}") from None
    sigma = s0 + s2 * r2
    if (sigma <= 0).any():
        raise OpticsError("sigma_r2_px: gives sigma <= 0 in part of the field")
    return sigma


# ----------------------------------------------------------------------------------------
# B. lateral colour


def _poly_no_constant(dl: np.ndarray, coeffs: tuple[float, ...]) -> np.ndarray:
    out = np.zeros_like(dl)
    for c in reversed(coeffs):  # Horner on sum_{k>=1} c_k dl^k = dl (c_1 + dl (c_2 + ...))
        out = (out + c) * dl
    return out


def _coeff_tuple(name: str, coeffs) -> tuple[float, ...]:
    arr = _finite_array(name, coeffs)
    if arr.ndim != 1:
        raise OpticsError(f"{name}: expected a 1-D sequence of coefficients, got shape {arr.shape}")
    return tuple(float(c) for c in arr)


def lateral_colour_shift_px(
    *,
    wavelength_nm,
    u_px,
    v_px,
    ref_wavelength_nm: float,
    radial_coeffs=(),
    uniform_x_coeffs=(),
    uniform_y_coeffs=(),
    r_norm_px: float,
):
    """Chromatic lateral displacement of each star's image at each wavelength.

    With ``dl = lambda - lambda_ref`` in nm and ``P(dl) = sum_{k=1..K} c_k dl^k``
    (coefficients in px / nm^k)::

        du = (u / r_norm) P_r(dl) + P_x(dl)
        dv = (v / r_norm) P_r(dl) + P_y(dl)

    ``radial_coeffs`` may also be a table ``c[k-1][m]`` (K rows, M columns): the radial
    polynomial then depends on the field radius ``r = sqrt(u^2 + v^2)`` too,
    ``P_r(dl, r) = sum_k sum_m c_km dl^k (r / r_norm)^(2m)``: the expansion of transverse
    chromatic aberration in odd powers of the field (primary, secondary, ... lateral
    colour, ``du`` proportional to ``h, h^3, h^5``; Welford 1986, Sec. 14.4), as fitted to a
    traced lens by :mod:`simcam.starcam.lens.simulator`. One column is the first form.

    The radial term is transverse chromatic aberration (lateral colour, a Seidel
    chromatic term proportional to field height; e.g. Welford, Aberrations of Optical
    Systems, 1986, on transverse chromatic aberration); the uniform term is
    the field-independent chromatic displacement of a decentred or tilted element
    (thin-prism dispersion, ``delta(lambda) = (n(lambda) - 1) A``, linearised in
    ``dl``). Sign convention: a positive ``radial_coeffs[0]`` moves longer wavelengths
    away from the axis; a positive ``uniform_x_coeffs[0]`` moves them towards ``+u``.
    Seed 000's 4-corner chromatic test averages the radial term out and sees only
    the uniform one.

    Parameters
    ----------
    wavelength_nm : array_like, shape (n_l,)
        Wavelengths in nm (> 0).
    u_px, v_px : array_like, shape (n,)
        Focal-plane position of each star, px.
    ref_wavelength_nm : float
        Reference wavelength (zero displacement) in nm (> 0).
    radial_coeffs, uniform_x_coeffs, uniform_y_coeffs : sequence of float
        ``c_1, c_2, ...`` in px / nm^k (may be empty). ``radial_coeffs`` may be a
        rectangular table ``c[k-1][m]`` (px / nm^k at ``(r / r_norm)^(2m)``).
    r_norm_px : float
        Normalising field radius in px (> 0).

    Returns
    -------
    du_px, dv_px : ndarray, shape (n, n_l)
        Displacement of each wavelength's image relative to the reference, px.
    """
    colour = lateral_colour(wavelength_nm=wavelength_nm, ref_wavelength_nm=ref_wavelength_nm,
                            radial_coeffs=radial_coeffs, uniform_x_coeffs=uniform_x_coeffs,
                            uniform_y_coeffs=uniform_y_coeffs, r_norm_px=r_norm_px)
    u = _finite_array("u_px", u_px)
    v = _finite_array("v_px", v_px)
    if u.ndim != 1:
        raise OpticsError(f"u_px: expected shape (n,), got {u.shape}")
    if v.shape != u.shape:
        raise OpticsError(f"v_px: shape {v.shape} differs from u_px {u.shape}")
    return colour.shift_px(u, v)


@dataclass(frozen=True, eq=False)
class LateralColour:
    """The model of :func:`lateral_colour_shift_px` at fixed wavelengths (:func:`lateral_colour`):
    its polynomials in ``dl`` evaluated once, so that :meth:`shift_px` costs a few products per
    star (a renderer's scenes share their spectrum's wavelengths)."""

    r_norm_px: float
    #: ``c[k-1][m]`` of a radial polynomial that depends on the field (more than one column), else None
    field_table: np.ndarray | None
    #: ``P_r(dl)`` (1, n_l); with a field table the powers ``dl^k`` (K, n_l)
    radial: np.ndarray
    uniform_x: np.ndarray  # P_x(dl), (1, n_l)
    uniform_y: np.ndarray  # P_y(dl), (1, n_l)

    def shift_px(self, u, v):
        """``(du_px, dv_px)`` (n, n_l) of images at focal ``u``, ``v`` (n,) px (validated float64
        arrays; :func:`lateral_colour_shift_px` checks them)."""
        rn = self.r_norm_px
        pr = self.radial
        if self.field_table is not None:
            # P_r(dl, r) = sum_k dl^k sum_m c_km s^m with s = (r / r_norm)^2, per star
            s = (u * u + v * v) / (rn * rn)
            pr = (np.power.outer(s, np.arange(self.field_table.shape[1])) @ self.field_table.T) @ pr
        return (u / rn)[:, None] * pr + self.uniform_x, (v / rn)[:, None] * pr + self.uniform_y


def lateral_colour(*, wavelength_nm, ref_wavelength_nm: float, radial_coeffs=(), uniform_x_coeffs=(),
                   uniform_y_coeffs=(), r_norm_px: float) -> LateralColour:
    """The lateral colour of :func:`lateral_colour_shift_px` (same arguments, without the
    positions) at the wavelengths ``wavelength_nm``: ``LateralColour.shift_px(u, v)`` then gives
    the same values as :func:`lateral_colour_shift_px` at ``(u, v)``.

    Raises
    ------
    OpticsError
        An argument is non-finite, of the wrong shape or out of range.
    """
    wl = _finite_array("wavelength_nm", wavelength_nm)
    if wl.ndim != 1:
        raise OpticsError(f"wavelength_nm: expected shape (n_l,), got {wl.shape}")
    if np.any(wl <= 0):
        raise OpticsError("wavelength_nm: must be > 0")
    lref = _positive_float("ref_wavelength_nm", ref_wavelength_nm)
    rn = _positive_float("r_norm_px", r_norm_px)
    cx = _coeff_tuple("uniform_x_coeffs", uniform_x_coeffs)
    cy = _coeff_tuple("uniform_y_coeffs", uniform_y_coeffs)
    dl = wl - lref
    table = _finite_array("radial_coeffs", radial_coeffs)
    if table.ndim > 2 or (table.ndim == 2 and table.shape[1] == 0):
        raise OpticsError(f"radial_coeffs: expected a sequence or a table with rows of equal length >= 1, "
                          f"got shape {table.shape}")
    field_table = None
    if table.ndim == 2 and table.shape[1] > 1:
        field_table = table
        radial = np.power.outer(dl, np.arange(1, table.shape[0] + 1)).T  # (K, n_l)
    elif table.ndim == 2:
        radial = _poly_no_constant(dl, tuple(float(c) for c in table[:, 0]))[None, :]
    else:
        radial = _poly_no_constant(dl, _coeff_tuple("radial_coeffs", table))[None, :]
    return LateralColour(r_norm_px=rn, field_table=field_table, radial=radial,
                         uniform_x=_poly_no_constant(dl, cx)[None, :], uniform_y=_poly_no_constant(dl, cy)[None, :])


# ----------------------------------------------------------------------------------------
# C. distortion


#: Order of the 10 monomials of :class:`CubicDistortion` in normalised coordinates.
CUBIC_MONOMIALS = ("1", "x", "y", "x^2", "xy", "y^2", "x^3", "x^2y", "xy^2", "y^3")


def _monomials(x, y):
    one = np.ones_like(x)
    xx, xy, yy = x * x, x * y, y * y  # x * x * y is (x * x) * y: the same products
    return (one, x, y, xx, xy, yy, xx * x, xx * y, xy * y, yy * y)


def _terms(coeffs, monomials):
    """``sum_k c_k m_k`` over the non-zero coefficients (Python's ``sum``, from 0). A zero
    coefficient's term is a signed zero, and adding one leaves the running sum as it is (the
    sum starts at +0 and round to nearest makes -0 only of two -0 terms, so it is never -0):
    the same values as the full sum for finite monomials, without computing what is zero."""
    return sum(c * m for c, m in zip(coeffs, monomials) if c != 0.0)


def _monomials_dx(x, y):
    z = np.zeros_like(x)
    one = np.ones_like(x)
    return (z, one, z, 2 * x, y, z, 3 * x * x, 2 * x * y, y * y, z)


def _monomials_dy(x, y):
    z = np.zeros_like(x)
    one = np.ones_like(x)
    return (z, z, one, z, x, 2 * y, z, x * x, 2 * x * y, 3 * y * y)


@dataclass(frozen=True, kw_only=True)
class CubicDistortion(_Distortion):
    """Full bivariate cubic distortion polynomial.

    With ``x = u / r_norm``, ``y = v / r_norm`` and the 10 monomials ``m_k`` in the
    order of :data:`CUBIC_MONOMIALS` (``1, x, y, x^2, xy, y^2, x^3, x^2y, xy^2, y^3``)::

        u' = u + sum_k cx_k m_k(x, y),    v' = v + sum_k cy_k m_k(x, y)

    (the general third-order plate model of astrometric reduction, and the polynomial
    that seed 000 eqs 17-30 fit to distortion residuals). Coefficients are in px. The
    constant and linear terms are an offset, scale and shear/rotation.

    Parameters
    ----------
    coeffs_x, coeffs_y : sequence of 10 float
        Coefficients of ``du`` and ``dv`` in px.
    r_norm_px : float
        Normalising radius in px (> 0).
    """

    coeffs_x: tuple = field(default=(0.0,) * 10)
    coeffs_y: tuple = field(default=(0.0,) * 10)
    r_norm_px: float = 2048.0

    N_COEFFS: ClassVar[int] = 10

    def __post_init__(self):
        for name in ("coeffs_x", "coeffs_y"):
            c = _coeff_tuple(name, getattr(self, name))
            if len(c) != self.N_COEFFS:
                raise OpticsError(f"{name}: expected {self.N_COEFFS} coefficients, got {len(c)}")
            object.__setattr__(self, name, c)
        object.__setattr__(self, "r_norm_px", _positive_float("r_norm_px", self.r_norm_px))

    @classmethod
    def identity(cls, *, r_norm_px: float = 2048.0) -> "CubicDistortion":
        """The zero distortion."""
        return cls(r_norm_px=r_norm_px)

    def _map(self, u, v, jacobian=True):
        rn = self.r_norm_px
        cx, cy = self.coeffs_x, self.coeffs_y
        x = u / rn
        y = v / rn
        # monomials only for a polynomial that has terms (the embedded default's is zero)
        nonzero = any(cx) or any(cy)
        m = _monomials(x, y) if nonzero else ()
        du = _terms(cx, m)
        dv = _terms(cy, m)
        if not jacobian:
            return u + du, v + dv, None
        mx = _monomials_dx(x, y) if nonzero else ()
        my = _monomials_dy(x, y) if nonzero else ()
        jac = np.empty(u.shape + (2, 2))
        jac[..., 0, 0] = 1.0 + _terms(cx, mx) / rn
        jac[..., 0, 1] = _terms(cx, my) / rn
        jac[..., 1, 0] = _terms(cy, mx) / rn
        jac[..., 1, 1] = 1.0 + _terms(cy, my) / rn
        return u + du, v + dv, jac


@dataclass(frozen=True, kw_only=True)
class CompositeDistortion(_Distortion):
    """Lens distortion followed by a cubic field polynomial.

    ``forward = cubic(brown_conrady(u, v))``: the Brown-Conrady model describes the
    lens itself; the cubic then adds whatever field-dependent displacement remains
    (mounting, detector flatness, a fitted residual). Jacobian by the chain rule,
    ``J = J_cubic(brown_conrady(p)) J_brown_conrady(p)``.

    Parameters
    ----------
    brown_conrady : BrownConradyDistortion
    cubic : CubicDistortion
    """

    brown_conrady: BrownConradyDistortion = field(default_factory=BrownConradyDistortion)
    cubic: CubicDistortion = field(default_factory=CubicDistortion)

    def __post_init__(self):
        if not isinstance(self.brown_conrady, BrownConradyDistortion):
            raise OpticsError("brown_conrady: expected a BrownConradyDistortion")
        if not isinstance(self.cubic, CubicDistortion):
            raise OpticsError("cubic: expected a CubicDistortion")

    @classmethod
    def identity(cls, *, r_norm_px: float = 2048.0) -> "CompositeDistortion":
        """The zero distortion."""
        return cls(
            brown_conrady=BrownConradyDistortion.identity(r_norm_px=r_norm_px),
            cubic=CubicDistortion.identity(r_norm_px=r_norm_px),
        )

    def _map(self, u, v, jacobian=True):
        bu, bv, jb = self.brown_conrady._map(u, v, jacobian)
        cu, cv, jc = self.cubic._map(bu, bv, jacobian)
        return cu, cv, (np.matmul(jc, jb) if jacobian else None)


@dataclass(frozen=True, kw_only=True)
class HigherOrderRadialDistortion(_Distortion):
    """A distortion plus radial terms of fifth and seventh order in the field.

    The lab calibrates distortion with a cubic polynomial; a real lens has higher orders
    too (the traced ``embedded:star_camera``: 1.47 px of ``r^5`` and 0.081 px of ``r^7`` at the
    mosaic corner, docs/lens.md). Added to ``base``'s displacement at the same ideal point::

        u' = base_u(u, v) + u g(q),   v' = base_v(u, v) + v g(q),
        g(q) = (a5 q^2 + a7 q^3) / r_c,   q = (u^2 + v^2) / r_c^2,

    i.e. a radial displacement ``a5 (r / r_c)^5 + a7 (r / r_c)^7`` px (Seidel/Buchdahl
    expansion of distortion in odd powers of the field height, e.g. Welford, *Aberrations
    of Optical Systems*, 1986, ch. 8), with ``a5``, ``a7`` the displacements at ``r = r_c``.
    Jacobian: ``J_base + g I + 2 g'(q) / r_c^2 [u; v][u, v]`` with ``g' = (2 a5 q + 3 a7 q^2) / r_c``.

    Parameters
    ----------
    base : _Distortion
        The scenario's distortion (:class:`CompositeDistortion`).
    a5_px, a7_px : float
        Radial displacement of each term at ``r_corner_px``, px (signed: > 0 outward).
    r_corner_px : float
        Reference radius (> 0): the mosaic's half diagonal.
    """

    base: _Distortion = field(default_factory=CompositeDistortion)
    a5_px: float = 0.0
    a7_px: float = 0.0
    r_corner_px: float = 2048.0

    def __post_init__(self):
        if not isinstance(self.base, _Distortion):
            raise OpticsError("base: expected a distortion object")
        for name in ("a5_px", "a7_px"):
            object.__setattr__(self, name, _finite_float(name, getattr(self, name)))
        object.__setattr__(self, "r_corner_px", _positive_float("r_corner_px", self.r_corner_px))

    def _map(self, u, v, jacobian=True):
        bu, bv, jb = self.base._map(u, v, jacobian)
        rc = self.r_corner_px
        q = (u * u + v * v) / (rc * rc)
        g = (self.a5_px * q * q + self.a7_px * q * q * q) / rc
        if not jacobian:
            return bu + u * g, bv + v * g, None
        gp = (2.0 * self.a5_px * q + 3.0 * self.a7_px * q * q) / rc * 2.0 / (rc * rc)
        jac = jb.copy()
        jac[..., 0, 0] += g + gp * u * u
        jac[..., 0, 1] += gp * u * v
        jac[..., 1, 0] += gp * u * v
        jac[..., 1, 1] += g + gp * v * v
        return bu + u * g, bv + v * g, jac
