"""Transfer functions of the stamp renderer, vectorised in numpy.

The radial factors of a star's spectrum that do not depend on the star's position (the
Airy OTF of each wavelength, the pinhole's disc OTF) are tabulated here once per batch
on the integer ``r2 = qx^2 + qy^2`` of the stamp's frequency lattice, and handed to the
numba kernel :func:`simcam.starcam.kernels.psf.folded_stamp_spectra` as arrays. They were
numba functions inside the kernel; as numpy they cost the same per batch (a few thousand
values) and numba no longer compiles them on a first run.

Functions
---------
bessel_j1
    Bessel function of the first kind, order one (Cephes rational approximations).
airy_otf
    Incoherent OTF of a circular aperture, Goodman's "chat" function.
disc_otf
    Fourier transform of a unit-flux uniform disc, ``2 J1(2 pi a rho) / (2 pi a rho)``.
freq_extent_cyc_per_px
    Frequency beyond which a star's spectrum is dropped.
radial_tables
    The tables the kernel reads.
stamp_work
    Cost model (number of spectral terms) used to choose serial or threaded stamps.
"""

from __future__ import annotations

import math

import numpy as np

# Cephes Math Library (S. L. Moshier, release 2.8, 2000), j1.c: rational approximations
# of J1(x). 0 <= x <= 5: J1(x) = x (x^2 - Z1)(x^2 - Z2) RP(x^2) / RQ(x^2), with Z1, Z2 the
# squares of the first two zeros of J1. x > 5: Hankel form
# J1(x) = sqrt(2 / (pi x)) [P(x) cos(x - 3 pi / 4) - (5 / x) Q(x) sin(x - 3 pi / 4)],
# P = PP(25/x^2) / PQ(25/x^2), Q = QP(25/x^2) / QQ(25/x^2). Cephes quotes a peak absolute
# error of 2.6e-16 on [0, 30] in IEEE double; tests/test_optics.py checks it against
# scipy.special.j1.
_J1_RP = (-8.99971225705559398224e8, 4.52228297998194034323e11, -7.27494245221818276015e13,
          3.68295732863852883286e15)
_J1_RQ = (  # leading coefficient 1 implied
    6.20836478118054335476e2, 2.56987256757748830383e5, 8.35146791431949253037e7,
    2.21511595479792499675e10, 4.74914122079991414898e12, 7.84369607876235854894e14,
    8.95222336184627338078e16, 5.32278620332680085395e18)
_J1_PP = (7.62125616208173112003e-4, 7.31397056940917570436e-2, 1.12719608129684925192e0,
          5.11207951146807644818e0, 8.42404590141772420927e0, 5.21451598682361504063e0,
          1.00000000000000000254e0)
_J1_PQ = (5.71323128072548699714e-4, 6.88455908754495404082e-2, 1.10514232634061696926e0,
          5.07386386128601488557e0, 8.39985554327604159757e0, 5.20982848682361821619e0,
          9.99999999999999997461e-1)
_J1_QP = (5.10862594750176621635e-2, 4.98213872951233449420e0, 7.58238284132545283818e1,
          3.66779609360150777800e2, 7.10856304998926107277e2, 5.97489612400613639965e2,
          2.11688757100572135698e2, 2.52070205858023719784e1)
_J1_QQ = (  # leading coefficient 1 implied
    7.42373277035675149943e1, 1.05644886038262816351e3, 4.98641058337653607651e3,
    9.56231892404756170795e3, 7.99704160447350683650e3, 2.82619278517639096600e3,
    3.36093607810698293419e2)
_J1_Z1 = 1.46819706421238932572e1
_J1_Z2 = 4.92184563216946036703e1
_THPIO4 = 2.35619449019234492885  # 3 pi / 4
_SQ2OPI = 0.79788456080286535588  # sqrt(2 / pi)


def _polevl(x: np.ndarray, coef) -> np.ndarray:
    """Horner's rule, ``coef[0] x^(n-1) + ... + coef[n-1]`` (Cephes ``polevl``)."""
    ans = np.full_like(x, coef[0])
    for c in coef[1:]:
        ans = ans * x + c
    return ans


def _p1evl(x: np.ndarray, coef) -> np.ndarray:
    """Horner's rule with an implied leading coefficient 1 (Cephes ``p1evl``)."""
    ans = x + coef[0]
    for c in coef[1:]:
        ans = ans * x + c
    return ans


def bessel_j1(x) -> np.ndarray:
    """Bessel function of the first kind of order one, ``J1(x)``, elementwise.

    Cephes ``j1`` (Moshier 2000): a rational approximation times the factored first two
    zeros for ``|x| <= 5`` and the Hankel asymptotic form with rational ``P``, ``Q`` for
    ``|x| > 5`` (Abramowitz & Stegun 9.2.5 structure). Absolute error about 3e-16.
    ``J1`` is odd: ``J1(-x) = -J1(x)``.
    """
    x = np.asarray(x, dtype=np.float64)
    w = np.abs(x)
    out = np.empty_like(w)
    small = w <= 5.0
    xs = x[small]
    z = xs * xs
    out[small] = _polevl(z, _J1_RP) / _p1evl(z, _J1_RQ) * xs * (z - _J1_Z1) * (z - _J1_Z2)
    big = ~small
    wb = w[big]
    w5 = 5.0 / wb
    z = w5 * w5
    p = _polevl(z, _J1_PP) / _polevl(z, _J1_PQ)
    q = _polevl(z, _J1_QP) / _p1evl(z, _J1_QQ)
    xn = wb - _THPIO4
    r = (p * np.cos(xn) - w5 * q * np.sin(xn)) * _SQ2OPI / np.sqrt(wb)
    out[big] = np.where(x[big] > 0.0, r, -r)
    return out


def disc_otf(radius_px, rho_cyc_per_px) -> np.ndarray:
    """Normalised Fourier transform of a uniform disc, elementwise (broadcast).

    ``OTF(rho) = 2 J1(2 pi a rho) / (2 pi a rho)`` (Goodman, Introduction to Fourier
    Optics, Sec. 2.1 table of transforms: ``circ(r/a)`` <-> ``a J1(2 pi a rho) / rho``,
    divided by the area ``pi a^2``). Equals 1 at ``rho = 0`` and for ``a = 0``.

    Parameters
    ----------
    radius_px : float or array
        Disc radius ``a`` in px (>= 0).
    rho_cyc_per_px : float or array
        Radial spatial frequency in cycles/px (>= 0).
    """
    a, rho = np.broadcast_arrays(np.asarray(radius_px, dtype=np.float64),
                                 np.asarray(rho_cyc_per_px, dtype=np.float64))
    t = 2.0 * math.pi * a * rho
    out = np.empty_like(t)
    series = t < 1e-4
    # 1 - t^2/8 + t^4/192; truncation error < t^6/9216 < 1e-27
    t2 = t[series] * t[series]
    out[series] = 1.0 - t2 / 8.0 + t2 * t2 / 192.0
    tb = t[~series]
    out[~series] = 2.0 * bessel_j1(tb) / tb
    return out


def airy_otf(rho_cyc_per_px, cutoff_cyc_per_px) -> np.ndarray:
    """Incoherent OTF of an aberration-free circular pupil (Goodman's "chat"), elementwise.

    ``H(v) = (2/pi) [acos(v) - v sqrt(1 - v^2)]`` for ``v = rho / rho_c < 1``, else 0
    (Goodman, Introduction to Fourier Optics, Sec. 6.3, OTF of a diffraction-limited
    system with a circular pupil), with incoherent cutoff ``rho_c = 1 / (lambda N)``.
    """
    v = np.asarray(rho_cyc_per_px, dtype=np.float64) / np.asarray(cutoff_cyc_per_px, dtype=np.float64)
    inside = v < 1.0
    vi = np.where(inside, v, 0.0)
    return np.where(inside, (2.0 / math.pi) * (np.arccos(vi) - vi * np.sqrt(1.0 - vi * vi)), 0.0)


def freq_extent_cyc_per_px(sigma_px, weights, cutoff_cyc_per_px, is_airy: bool, neg_log_eps: float) -> np.ndarray:
    """Frequency (cycles/px) beyond which each star's spectrum is dropped.

    The Gaussian factor ``exp(-2 pi^2 s^2 rho^2)`` bounds every other factor (``|sinc|``,
    ``|disc OTF|``, ``|chat| <= 1``) and falls below ``eps`` at
    ``rho_g = sqrt(-ln eps / (2 pi^2 s^2))``; the Airy OTF vanishes beyond the largest
    cutoff of the wavelengths with non-zero weight. ``sigma_px`` (n,), ``weights`` (n, n_l),
    ``cutoff_cyc_per_px`` (n_l,); returns (n,), ``inf`` for a Gaussian of zero width.
    """
    s = np.asarray(sigma_px, dtype=np.float64)
    with np.errstate(divide="ignore"):
        fmax = np.where(s > 0.0, np.sqrt(neg_log_eps / (2.0 * math.pi * math.pi * s * s)), np.inf)
    if is_airy:
        cmax = np.max(np.where(np.asarray(weights) > 0.0, np.asarray(cutoff_cyc_per_px)[None, :], 0.0),
                      axis=1, initial=0.0)
        fmax = np.minimum(fmax, cmax)
    return fmax


def radial_tables(qmax, radius_px, cutoff_cyc_per_px, is_airy: bool, L: int):
    """The radial factors of every star's spectrum on the integer ``r2 = qx^2 + qy^2``.

    ``qmax`` (n,) is each star's frequency extent in lattice units (``f_max L``); the
    tables cover ``r2`` up to the largest star's ``min(floor(qmax^2), 2 K^2)``,
    ``K = floor(qmax)``, which is what the kernel reads, at ``rho = sqrt(r2) / L``.

    Returns
    -------
    chat : (n_l, nr2) float64
        The Airy OTF of each wavelength (``(n_l, 1)`` zeros for a Gaussian PSF: unused).
    disc : (1, nr2) or (n, nr2) float64
        The pinhole's disc OTF: one row when every star has the same radius, else one
        per star; ones for a zero radius (a multiplication by 1.0 is exact).
    """
    q = np.asarray(qmax, dtype=np.float64)
    rad = np.asarray(radius_px, dtype=np.float64)
    cutoff = np.asarray(cutoff_cyc_per_px, dtype=np.float64)
    if q.size:
        top = float(q.max())
        kmax = math.floor(top)
        nr2 = min(math.floor(top * top), 2 * kmax * kmax) + 1
    else:
        nr2 = 1
    rho = np.sqrt(np.arange(nr2, dtype=np.float64)) / L
    chat = airy_otf(rho[None, :], cutoff[:, None]) if is_airy else np.zeros((cutoff.size, 1))
    if rad.size == 0 or np.all(rad == rad[0]):
        r = rad[:1] if rad.size else np.zeros(1)
    else:
        r = rad
    disc = np.where(r[:, None] > 0.0, disc_otf(r[:, None], rho[None, :]), 1.0)
    return np.ascontiguousarray(chat), np.ascontiguousarray(disc)


def stamp_work(qmax, n_wavelengths: int) -> float:
    """Number of (frequency, wavelength) terms the stamp kernels will evaluate:
    ``sum_i n_l (pi / 2) qmax_i^2``, the cost model that decides whether spreading stars
    over threads is worth its start-up cost."""
    q = np.asarray(qmax, dtype=np.float64)
    return float(np.sum(0.5 * math.pi * q * q) * n_wavelengths)
