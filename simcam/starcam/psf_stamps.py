"""Pixel-integrated polychromatic PSF stamps: the images of pinhole stars that the renderer
adds to a frame (its hot path).

:func:`render_stamps` computes a batch of stamps exactly in the Fourier domain;
:func:`stamp_profiles` and :func:`render_shifted_stamps` the same stamps in two steps, the
wavelength sum once per target and the position, blur and mean lateral colour per frame;
:func:`airy_cutoff_cyc_per_px` the diffraction cutoff of the Airy PSF. The numba kernels
are :mod:`simcam.starcam.kernels.psf`, the radial transfer tables
:mod:`simcam.starcam.psf_transfer`. Coordinates as in :mod:`simcam.starcam.optics`:
detector pixel centres at integers.

The stamps
----------
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from simcam.distortion import OpticsError, _finite_array, _positive_float
from simcam.starcam import psf_transfer as _pt
from simcam.starcam.kernels import psf as _psf

__all__ = [
    "PSF_KINDS",
    "SPECTRUM_EPS",
    "PARALLEL_MIN_TERMS",
    "airy_cutoff_cyc_per_px",
    "render_stamps",
    "StampProfiles",
    "stamp_profiles",
    "render_shifted_stamps",
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

    Each stamp is the star's pinhole disc convolved with the camera PSF at each wavelength,
    displaced by the star's position and lateral colour, summed with the wavelengths'
    weights and integrated over each pixel's unit square, computed exactly in the Fourier
    domain and folded onto the ``L x L`` stamp (physics, method, periodisation and cost: the
    module docstring).

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
    L = _stamp_side(stamp_px)
    if psf_kind not in PSF_KINDS:
        raise OpticsError(f"psf_kind: must be one of {PSF_KINDS}, got {psf_kind!r}")
    x, y = _star_positions(x_px, y_px)
    n = x.shape[0]
    wl = _wavelengths(wavelength_nm)
    n_l = wl.shape[0]
    sig = _broadcast("sigma_px", _finite_array("sigma_px", sigma_px), (n,))
    cutoff, is_airy = _camera_psf(psf_kind, sig, wl, f_number=f_number, pixel_pitch_um=pixel_pitch_um)
    rad = _broadcast("pinhole_radius_px", _finite_array("pinhole_radius_px", pinhole_radius_px), (n,))
    if np.any(rad < 0):
        raise OpticsError("pinhole_radius_px: must be >= 0")
    w, sx, sy = _weights_and_shifts(weights, shift_x_px, shift_y_px, n=n, n_l=n_l)

    origin_x = np.floor(x + 0.5).astype(np.int64) - L // 2
    origin_y = np.floor(y + 0.5).astype(np.int64) - L // 2
    pos_x = x - origin_x
    pos_y = y - origin_y
    if parallel is not None and not isinstance(parallel, (bool, np.bool_)):
        raise OpticsError(f"parallel: expected True, False or None, got {parallel!r}")
    spectra = _folded_spectra(pos_x, pos_y, sx, sy, w, sig, rad, cutoff, is_airy, L=L, n_l=n_l, parallel=parallel)
    stamps = np.fft.ifft2(spectra, axes=(-2, -1)).real
    return stamps, origin_x, origin_y


def _stamp_side(stamp_px) -> int:
    """The stamp side ``L`` (px): an integer >= 4."""
    if isinstance(stamp_px, bool) or not isinstance(stamp_px, (int, np.integer)):
        raise OpticsError(f"stamp_px: expected an integer, got {stamp_px!r}")
    L = int(stamp_px)
    if L < 4:
        raise OpticsError(f"stamp_px: must be >= 4, got {L}")
    return L


def _star_positions(x_px, y_px) -> tuple[np.ndarray, np.ndarray]:
    """The stars' positions (px) as finite float64 arrays of one shape (n,)."""
    x = _finite_array("x_px", x_px)
    y = _finite_array("y_px", y_px)
    if x.ndim != 1:
        raise OpticsError(f"x_px: expected shape (n,), got {x.shape}")
    if y.shape != x.shape:
        raise OpticsError(f"y_px: shape {y.shape} differs from x_px {x.shape}")
    return x, y


def _wavelengths(wavelength_nm) -> np.ndarray:
    """The wavelength samples (nm): a finite, positive float64 array (n_l,), n_l >= 1."""
    wl = _finite_array("wavelength_nm", wavelength_nm)
    if wl.ndim != 1 or wl.shape[0] == 0:
        raise OpticsError(f"wavelength_nm: expected shape (n_l,) with n_l >= 1, got {wl.shape}")
    if np.any(wl <= 0):
        raise OpticsError("wavelength_nm: must be > 0")
    return wl


def _camera_psf(psf_kind: str, sig: np.ndarray, wl: np.ndarray, *, f_number, pixel_pitch_um):
    """The camera PSF's Airy cutoff per wavelength (cycles/px; zeros for a Gaussian PSF) and
    whether it is Airy, with the Gaussian sigma ``sig`` checked for the kind."""
    if psf_kind == "gaussian":
        if np.any(sig <= 0):
            raise OpticsError("sigma_px: the Gaussian PSF sigma must be > 0")
        return np.zeros(wl.shape[0]), False
    if np.any(sig < 0):
        raise OpticsError("sigma_px: the Airy extra blur must be >= 0")
    if f_number is None:
        raise OpticsError("f_number: required for psf_kind='airy'")
    if pixel_pitch_um is None:
        raise OpticsError("pixel_pitch_um: required for psf_kind='airy'")
    cutoff = airy_cutoff_cyc_per_px(
        wavelength_nm=wl, f_number=f_number, pixel_pitch_um=pixel_pitch_um
    )
    return cutoff, True


def _weights_and_shifts(weights, shift_x_px, shift_y_px, *, n: int, n_l: int):
    """The wavelengths' flux fractions (each row summing to 1) and lateral-colour shifts (px)
    of each star, float64 arrays (n, n_l)."""
    w = _broadcast("weights", _finite_array("weights", weights), (n, n_l))
    if np.any(w < 0):
        raise OpticsError("weights: must be >= 0")
    if n and np.any(np.abs(w.sum(axis=1) - 1.0) > 1e-9):
        raise OpticsError("weights: each row must sum to 1 (within 1e-9)")
    sx = _broadcast("shift_x_px", _finite_array("shift_x_px", shift_x_px), (n, n_l))
    sy = _broadcast("shift_y_px", _finite_array("shift_y_px", shift_y_px), (n, n_l))
    return w, sx, sy


def _folded_spectra(pos_x, pos_y, sx, sy, w, sig, rad, cutoff, is_airy: bool, *, L: int, n_l: int, parallel):
    """The stamps' spectra folded onto ``L x L`` frequencies (complex, (n, L, L)) by the
    numba kernel (:func:`simcam.starcam.kernels.psf.folded_stamp_spectra`, over threads when
    ``parallel``, or when ``None`` and the batch is large)."""
    n = pos_x.shape[0]
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
    return spectra


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
