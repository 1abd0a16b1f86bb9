"""Camera optics: pixel-integrated PSF stamps, PSF width over the field, lateral colour
and geometric distortion.

Coordinates follow ``docs/conventions.md``: detector (mosaic) pixel coordinates have
pixel centres at integers; focal-plane coordinates ``(u, v)`` are in nominal px from the
optical axis. Every displacement returned here is in px of the focal plane.

Public API
----------
render_stamps
    Pixel-integrated, polychromatic images of pinhole stars (the renderer's hot path).
airy_cutoff_cyc_per_px
    Incoherent diffraction cutoff ``pixel_pitch / (wavelength * f_number)``.
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

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numba
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
from simcam.starcam import psf_transfer as _pt
from simcam.starcam.kernels import psf as _psf

__all__ = [
    "PSF_KINDS",
    "SPECTRUM_EPS",
    "PARALLEL_MIN_TERMS",
    "OpticsError",
    "NonInvertibleDistortionError",
    "airy_cutoff_cyc_per_px",
    "render_stamps",
    "StampProfiles",
    "stamp_profiles",
    "render_shifted_stamps",
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

#: Camera PSF kinds understood by :func:`render_stamps`.
PSF_KINDS = ("gaussian", "airy")

#: Batches with more spectral terms than this run over numba threads when
#: ``render_stamps(parallel=None)``: about 5-10 ms of serial work (1.5-2.5 ns per term).
PARALLEL_MIN_TERMS = 4e6

#: Spectral components whose Gaussian envelope is below this are dropped (the omitted
#: flux per pixel is below ``SPECTRUM_EPS / (2 pi sigma^2)``).
SPECTRUM_EPS = 1e-12


def _broadcast(name: str, arr: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    try:
        return np.ascontiguousarray(np.broadcast_to(arr, shape), dtype=np.float64)
    except ValueError:
        raise OpticsError(f"{name}: shape {arr.shape} does not match {shape}") from None


# ----------------------------------------------------------------------------------------
# A. pixel-integrated polychromatic PSF stamps


def airy_cutoff_cyc_per_px(*, wavelength_nm, f_number: float, pixel_pitch_um: float) -> np.ndarray:
    """Incoherent diffraction cutoff frequency of a circular aperture, in cycles/px.

    ``rho_c = 1 / (lambda N)`` (Goodman, Introduction to Fourier Optics, Sec. 6.3), here
    expressed per pixel: ``rho_c = pixel_pitch_um / (wavelength_um * f_number)``.

    Parameters
    ----------
    wavelength_nm : array_like
        Wavelength(s) in nm (> 0).
    f_number : float
        Working f-number ``N`` (> 0).
    pixel_pitch_um : float
        Pixel pitch in micrometres (> 0).

    Returns
    -------
    ndarray
        Cutoff in cycles/px, same shape as ``wavelength_nm``.
    """
    wl = _finite_array("wavelength_nm", wavelength_nm)
    if np.any(wl <= 0):
        raise OpticsError("wavelength_nm: must be > 0")
    n = _positive_float("f_number", f_number)
    p = _positive_float("pixel_pitch_um", pixel_pitch_um)
    return p / (wl * 1e-3 * n)


def render_stamps(
    *,
    x_px,
    y_px,
    stamp_px: int = 32,
    psf_kind: str,
    sigma_px,
    pinhole_radius_px,
    f_number: float | None = None,
    pixel_pitch_um: float | None = None,
    wavelength_nm,
    weights,
    shift_x_px,
    shift_y_px,
    parallel: bool | None = None,
):
    """Pixel-integrated polychromatic images of pinhole stars, one stamp per star.

    Physics. The irradiance of star ``i`` on the detector is, for each wavelength
    ``l``, the pinhole (uniform disc of radius ``a`` px) convolved with the camera PSF,
    displaced by ``(x_i + sx_il, y_i + sy_il)``; the stamps hold the sum over
    wavelengths with weights ``w_il`` (rows sum to 1), integrated over each pixel's unit
    square (not sampled at pixel centres). In the Fourier domain (Goodman, Introduction
    to Fourier Optics, Secs. 2.1 and 6.3) the pixel-integrated image ``g`` has spectrum::

        G(fx, fy) = sum_l w_l OTF_disc(rho) OTF_cam(rho, l) sinc(fx) sinc(fy)
                    exp(-2 pi i (fx x_l + fy y_l)),

    with ``rho = sqrt(fx^2 + fy^2)`` in cycles/px, ``sinc(t) = sin(pi t)/(pi t)`` the
    transfer function of the unit pixel, ``OTF_disc = 2 J1(2 pi a rho)/(2 pi a rho)``
    and

    * ``"gaussian"``: ``OTF_cam = exp(-2 pi^2 sigma^2 rho^2)`` (same for all ``l``);
    * ``"airy"``: ``OTF_cam = chat(rho / rho_c(l)) exp(-2 pi^2 sigma^2 rho^2)``,
      Goodman's circular-pupil OTF ``chat(v) = (2/pi)[acos v - v sqrt(1 - v^2)]``
      (0 for ``v >= 1``), cutoff ``rho_c = pixel_pitch_um / (wavelength_um f_number)``,
      and ``sigma`` an extra Gaussian blur (defocus, jitter; may be 0).

    Method. By the Poisson summation formula the ``L``-periodic sum
    ``sum_{m,n} g(c + mL - x, r + nL - y)`` at integer pixel offsets ``(c, r)`` equals
    ``(1/L^2) sum_q G(q/L) exp(2 pi i q.(c, r)/L)``: the continuous spectrum sampled at
    multiples of ``1/L`` and folded (aliased) onto ``L x L`` frequencies, then one
    inverse DFT. The sum over ``q`` is truncated where the integrand is negligible:
    at the Airy cutoff, and where the Gaussian envelope falls below
    :data:`SPECTRUM_EPS` = 1e-12 (omitted flux per pixel below
    ``1e-12 / (2 pi sigma^2)``). Within that, the result is exact: no sampling of the
    PSF at pixel centres, no sub-pixel grid, no interpolation. The kernel
    (:func:`simcam.starcam.kernels.psf.folded_stamp_spectra`) uses Hermitian symmetry,
    reads the radial factors tabulated on integer ``qx^2 + qy^2``
    (:func:`simcam.starcam.psf_transfer.radial_tables`), and for large batches runs
    in parallel over stars (each star independent, so results do not depend on the
    thread count). The final ``L x L`` inverse DFT is ``numpy.fft.ifft2`` (pocketfft, as
    ``scipy.fft``, without its 0.13 s import).

    Periodisation. The stamp is one period of the periodic image: flux that falls
    outside the ``L x L`` box wraps around into the opposite edge, so each stamp sums
    to exactly 1 (flux is conserved) and a pixel value carries an error equal to the
    PSF flux in the pixels one or more periods away. For a Gaussian this is
    ``~ exp(-(L/2)^2 / (2 sigma^2))``, negligible for ``L >= 12 sigma``. The Airy
    pattern's wings fall only as ``r^-3``: its mean intensity far out is
    ``1 / (pi^3 rho_c r^3)`` per px^2 (from ``J1(x)^2 ~ 1/(pi x)`` on average), so a
    pixel near the core receives about ``9.03 / (pi^3 rho_c L^3)`` of wrapped flux
    (9.03 = sum over the non-zero integer lattice of ``|m|^-3``): 3.9e-6 of the
    star's flux for ``rho_c = 2.29`` (600 nm, f/4, 5.5 um), ``L = 32``; 4.9e-7 at
    ``L = 64``; pixels near the stamp edge receive more (up to the wing intensity
    itself). ``tests/test_optics.py`` checks this estimate against quadrature. Choose
    ``stamp_px`` accordingly; a pinhole radius or blur comparable to ``L/2`` needs a
    larger stamp.

    Cost grows as ``n * n_l * (L f_max)^2`` with ``f_max`` the frequency extent
    (about ``1.18 / sigma`` cycles/px for a Gaussian, ``rho_c`` for a sharp Airy).

    Parameters
    ----------
    x_px, y_px : array_like, shape (n,)
        Star position at the reference wavelength, detector px (pixel centres at
        integers).
    stamp_px : int
        Stamp side ``L`` in px (>= 4). Default 32.
    psf_kind : {"gaussian", "airy"}
        Camera PSF kind.
    sigma_px : float or array_like, shape (n,)
        Gaussian sigma in px: the PSF width for ``"gaussian"`` (> 0), the extra blur for
        ``"airy"`` (>= 0). Evaluated per star by the caller (see :func:`psf_sigma_px`).
    pinhole_radius_px : float or array_like, shape (n,)
        Radius of the pinhole's geometric image in px (>= 0; 0 is a point source).
    f_number : float, optional
        Working f-number (``"airy"`` only, required there).
    pixel_pitch_um : float, optional
        Pixel pitch in micrometres (``"airy"`` only, required there).
    wavelength_nm : array_like, shape (n_l,)
        Wavelength samples in nm (> 0).
    weights : array_like, shape (n, n_l) or (n_l,)
        Flux fraction of each wavelength (>= 0, each row sums to 1 within 1e-9).
    shift_x_px, shift_y_px : array_like, broadcastable to (n, n_l)
        Lateral-colour displacement of each wavelength relative to ``(x_px, y_px)``,
        px (see :func:`lateral_colour_shift_px`).
    parallel : bool or None
        Spread the stars over numba threads. ``None`` (default): only when the batch
        holds more than :data:`PARALLEL_MIN_TERMS` spectral terms (see
        :func:`simcam.starcam.psf_transfer.stamp_work`) and more than one thread is available;
        small batches run serially, which is faster than waking threads and immune to
        stalls on a busy machine. The result is bit-identical either way.

    Returns
    -------
    stamps : ndarray, shape (n, L, L), float64
        Fraction of the star's flux landing in each pixel; ``stamps[i, r, c]`` is
        detector pixel ``(x = origin_x[i] + c, y = origin_y[i] + r)``.
    origin_x, origin_y : ndarray, shape (n,), int64
        Detector pixel of ``stamps[:, 0, 0]``: ``floor(x_px + 0.5) - L // 2`` (the
        nearest pixel, halves rounded up, minus ``L // 2``), same for ``y``.

    Raises
    ------
    OpticsError
        A parameter is missing, of the wrong shape, non-finite or out of range.
    """
    if isinstance(stamp_px, bool) or not isinstance(stamp_px, (int, np.integer)):
        raise OpticsError(f"stamp_px: expected an integer, got {stamp_px!r}")
    L = int(stamp_px)
    if L < 4:
        raise OpticsError(f"stamp_px: must be >= 4, got {L}")
    if psf_kind not in PSF_KINDS:
        raise OpticsError(f"psf_kind: must be one of {PSF_KINDS}, got {psf_kind!r}")
    x = _finite_array("x_px", x_px)
    y = _finite_array("y_px", y_px)
    if x.ndim != 1:
        raise OpticsError(f"x_px: expected shape (n,), got {x.shape}")
    if y.shape != x.shape:
        raise OpticsError(f"y_px: shape {y.shape} differs from x_px {x.shape}")
    n = x.shape[0]
    wl = _finite_array("wavelength_nm", wavelength_nm)
    if wl.ndim != 1 or wl.shape[0] == 0:
        raise OpticsError(f"wavelength_nm: expected shape (n_l,) with n_l >= 1, got {wl.shape}")
    if np.any(wl <= 0):
        raise OpticsError("wavelength_nm: must be > 0")
    n_l = wl.shape[0]
    sig = _broadcast("sigma_px", _finite_array("sigma_px", sigma_px), (n,))
    if psf_kind == "gaussian":
        if np.any(sig <= 0):
            raise OpticsError("sigma_px: the Gaussian PSF sigma must be > 0")
        cutoff = np.zeros(n_l)
        is_airy = False
    else:
        if np.any(sig < 0):
            raise OpticsError("sigma_px: the Airy extra blur must be >= 0")
        if f_number is None:
            raise OpticsError("f_number: required for psf_kind='airy'")
        if pixel_pitch_um is None:
            raise OpticsError("pixel_pitch_um: required for psf_kind='airy'")
        cutoff = airy_cutoff_cyc_per_px(
            wavelength_nm=wl, f_number=f_number, pixel_pitch_um=pixel_pitch_um
        )
        is_airy = True
    rad = _broadcast("pinhole_radius_px", _finite_array("pinhole_radius_px", pinhole_radius_px), (n,))
    if np.any(rad < 0):
        raise OpticsError("pinhole_radius_px: must be >= 0")
    w = _broadcast("weights", _finite_array("weights", weights), (n, n_l))
    if np.any(w < 0):
        raise OpticsError("weights: must be >= 0")
    if n and np.any(np.abs(w.sum(axis=1) - 1.0) > 1e-9):
        raise OpticsError("weights: each row must sum to 1 (within 1e-9)")
    sx = _broadcast("shift_x_px", _finite_array("shift_x_px", shift_x_px), (n, n_l))
    sy = _broadcast("shift_y_px", _finite_array("shift_y_px", shift_y_px), (n, n_l))

    origin_x = np.floor(x + 0.5).astype(np.int64) - L // 2
    origin_y = np.floor(y + 0.5).astype(np.int64) - L // 2
    pos_x = x - origin_x
    pos_y = y - origin_y
    if parallel is not None and not isinstance(parallel, (bool, np.bool_)):
        raise OpticsError(f"parallel: expected True, False or None, got {parallel!r}")
    spectra = np.zeros((n, L, L), dtype=np.complex128)
    cutoff = np.array(cutoff, dtype=np.float64)
    if n:
        qmax = _pt.freq_extent_cyc_per_px(sig, w, cutoff, is_airy, -math.log(SPECTRUM_EPS)) * L
        chat, disc = _pt.radial_tables(qmax, rad, cutoff, is_airy, L)
        if parallel is None:
            parallel = numba.get_num_threads() > 1 and _pt.stamp_work(qmax, n_l) > PARALLEL_MIN_TERMS
        kernel = _psf.folded_stamp_spectra_parallel if parallel else _psf.folded_stamp_spectra
        # writable contiguous copies (a few numbers per star): the kernel sees one type
        # whatever the caller passed (a broadcast view is read-only), so numba compiles it once
        a = [np.array(v, dtype=np.float64) for v in (pos_x, pos_y, sx, sy, w, sig, qmax)]
        kernel(*a, cutoff, bool(is_airy), chat, disc, spectra)
    stamps = np.fft.ifft2(spectra, axes=(-2, -1)).real
    return stamps, origin_x, origin_y


@dataclass(frozen=True)
class StampProfiles:
    """Position-free spectra of a batch of star images (:func:`stamp_profiles`): what
    :func:`render_shifted_stamps` moves to each star's actual position and width."""

    stamp_px: int
    spectra: np.ndarray  # (n, K + 1, 2 K + 1) complex128, half plane, no position, no Gaussian
    qmax: np.ndarray  # (n,) frequency extent, lattice units
    zero: np.ndarray  # (n,) zero-frequency term (the sum of the weights)
    mean_shift_x_px: np.ndarray  # (n,) weighted mean lateral-colour shift built into the spectra
    mean_shift_y_px: np.ndarray
    sigma_px: np.ndarray  # (n,) the Gaussian sigma the extents were sized for


def stamp_profiles(*, stamp_px: int = 32, psf_kind: str, sigma_px, pinhole_radius_px, f_number=None,
                   pixel_pitch_um=None, wavelength_nm, weights, shift_x_px, shift_y_px) -> StampProfiles:
    """The spectra of :func:`render_stamps` without the star's position and Gaussian factor.

    :func:`render_stamps` writes, per star, ``G(q) = P(q) exp(-2 pi^2 s^2 |q|^2 / L^2)
    exp(-2 pi i q.x / L)`` with ``P(q) = sinc sinc OTF_disc sum_l w_l [chat_l]
    exp(-2 pi i q.s_l / L)``: only ``P`` costs a sum over the ``n_l`` wavelengths, and it
    depends on the position only through the lateral-colour shifts ``s_l``, which vary
    slowly over the field. This computes ``P`` once (same arguments as
    :func:`render_stamps` without the positions); :func:`render_shifted_stamps` then
    places each star at any position and width for one term per frequency.
    """
    L = int(stamp_px)
    if psf_kind not in PSF_KINDS:
        raise OpticsError(f"psf_kind: must be one of {PSF_KINDS}, got {psf_kind!r}")
    sig = np.ascontiguousarray(sigma_px, dtype=np.float64)
    n = sig.shape[0]
    wl = np.asarray(wavelength_nm, dtype=np.float64)
    n_l = wl.shape[0]
    # writable contiguous copies: the kernel sees one type whatever the caller passed (a
    # broadcast view is read-only), so numba compiles it once
    w, sx, sy = (np.array(_broadcast(name, np.asarray(v, dtype=np.float64), (n, n_l)))
                 for name, v in (("weights", weights), ("shift_x_px", shift_x_px), ("shift_y_px", shift_y_px)))
    rad = _broadcast("pinhole_radius_px", np.asarray(pinhole_radius_px, dtype=np.float64), (n,))
    is_airy = psf_kind == "airy"
    cutoff = (airy_cutoff_cyc_per_px(wavelength_nm=wl, f_number=f_number, pixel_pitch_um=pixel_pitch_um)
              if is_airy else np.zeros(n_l))
    cutoff = np.array(cutoff, dtype=np.float64)
    qmax = _pt.freq_extent_cyc_per_px(sig, w, cutoff, is_airy, -math.log(SPECTRUM_EPS)) * L
    if n and not np.all(np.isfinite(qmax)):
        raise OpticsError("sigma_px: the profile route needs a finite frequency extent (sigma > 0 or an Airy PSF)")
    K = int(math.floor(qmax.max())) if n else 0
    chat, disc = _pt.radial_tables(qmax, rad, cutoff, is_airy, L)
    spectra = np.zeros((n, K + 1, 2 * K + 1), dtype=np.complex128)
    if n:
        _psf.stamp_profiles(sx, sy, w, np.array(qmax), cutoff, bool(is_airy), chat, disc, L, spectra)
    return StampProfiles(stamp_px=L, spectra=spectra, qmax=np.array(qmax), zero=w.sum(axis=1),
                         mean_shift_x_px=np.einsum("ij,ij->i", w, sx), mean_shift_y_px=np.einsum("ij,ij->i", w, sy),
                         sigma_px=sig.copy())


def render_shifted_stamps(profiles: StampProfiles, *, x_px, y_px, sigma_px, mean_shift_x_px, mean_shift_y_px):
    """:func:`render_stamps` of the profiled stars (:func:`stamp_profiles`) at new positions.

    Each star ``i`` is placed at ``(x_i, y_i) + (mean_shift_i - profile mean shift_i)``
    with Gaussian sigma ``sigma_px[i]``; both exactly (a phase ramp and the Gaussian
    factor, separable products). What is approximated is the lateral colour: the shifts
    ``s_l`` of each wavelength keep the profile's values apart from their weighted mean,
    which follows the star (``mean_shift_*_px``: ``sum_l w_l s_l`` at the new position).
    The change of ``s_l - mean`` between the profile's position and the new one is a
    first-order change of the image by ``sum_l w_l (ds_l - mean ds) . grad I_l``, which
    ``tests/test_render.py`` bounds and checks against :func:`render_stamps`.
    Returns ``(stamps, origin_x, origin_y)`` as :func:`render_stamps`.
    """
    L = profiles.stamp_px
    x = np.asarray(x_px, dtype=np.float64)
    y = np.asarray(y_px, dtype=np.float64)
    origin_x = np.floor(x + 0.5).astype(np.int64) - L // 2
    origin_y = np.floor(y + 0.5).astype(np.int64) - L // 2
    px = x - origin_x + (np.asarray(mean_shift_x_px, dtype=np.float64) - profiles.mean_shift_x_px)
    py = y - origin_y + (np.asarray(mean_shift_y_px, dtype=np.float64) - profiles.mean_shift_y_px)
    half = np.zeros((x.shape[0], L, L // 2 + 1), dtype=np.complex128)
    if x.shape[0]:
        _psf.shifted_stamp_spectra(profiles.spectra, profiles.qmax, profiles.zero, px, py,
                                   np.array(sigma_px, dtype=np.float64), L, half)
    stamps = np.fft.irfft2(half, s=(L, L), axes=(-2, -1))
    return stamps, origin_x, origin_y


# ----------------------------------------------------------------------------------------
# B. PSF width over the field


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
# C. lateral colour


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
# D. distortion


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
