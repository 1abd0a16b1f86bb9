"""Numba kernels for pixel-integrated polychromatic PSF stamps.

Only arrays and scalars cross this boundary; validation, unit conversion and the final
inverse FFT live in :mod:`simcam.starcam.optics`.

Functions
---------
bessel_j1
    Bessel function of the first kind, order one (Cephes rational approximations).
airy_otf
    Incoherent OTF of a circular aperture, Goodman's "chat" function.
disc_otf
    Fourier transform of a unit-flux uniform disc, ``2 J1(2 pi a rho) / (2 pi a rho)``.
folded_stamp_spectra, folded_stamp_spectra_parallel
    The aliased (folded) spectrum of each star's pixel-integrated image on an
    ``L x L`` periodic stamp; ``Re(ifft2(spectrum))`` is the stamp (serial, and over
    threads with bit-identical results).
stamp_work
    Cost model (number of spectral terms) used to choose between the two.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

# Cephes Math Library (S. L. Moshier, release 2.8, 2000), j1.c: rational approximations
# of J1(x). 0 <= x <= 5: J1(x) = x (x^2 - Z1)(x^2 - Z2) RP(x^2) / RQ(x^2), with Z1, Z2 the
# squares of the first two zeros of J1. x > 5: Hankel form
# J1(x) = sqrt(2 / (pi x)) [P(x) cos(x - 3 pi / 4) - (5 / x) Q(x) sin(x - 3 pi / 4)],
# P = PP(25/x^2) / PQ(25/x^2), Q = QP(25/x^2) / QQ(25/x^2). Cephes quotes a peak absolute
# error of 2.6e-16 on [0, 30] in IEEE double; tests/test_optics.py checks it against
# scipy.special.j1.
_J1_RP = np.array(
    [-8.99971225705559398224e8, 4.52228297998194034323e11, -7.27494245221818276015e13,
     3.68295732863852883286e15]
)
_J1_RQ = np.array(  # leading coefficient 1 implied
    [6.20836478118054335476e2, 2.56987256757748830383e5, 8.35146791431949253037e7,
     2.21511595479792499675e10, 4.74914122079991414898e12, 7.84369607876235854894e14,
     8.95222336184627338078e16, 5.32278620332680085395e18]
)
_J1_PP = np.array(
    [7.62125616208173112003e-4, 7.31397056940917570436e-2, 1.12719608129684925192e0,
     5.11207951146807644818e0, 8.42404590141772420927e0, 5.21451598682361504063e0,
     1.00000000000000000254e0]
)
_J1_PQ = np.array(
    [5.71323128072548699714e-4, 6.88455908754495404082e-2, 1.10514232634061696926e0,
     5.07386386128601488557e0, 8.39985554327604159757e0, 5.20982848682361821619e0,
     9.99999999999999997461e-1]
)
_J1_QP = np.array(
    [5.10862594750176621635e-2, 4.98213872951233449420e0, 7.58238284132545283818e1,
     3.66779609360150777800e2, 7.10856304998926107277e2, 5.97489612400613639965e2,
     2.11688757100572135698e2, 2.52070205858023719784e1]
)
_J1_QQ = np.array(  # leading coefficient 1 implied
    [7.42373277035675149943e1, 1.05644886038262816351e3, 4.98641058337653607651e3,
     9.56231892404756170795e3, 7.99704160447350683650e3, 2.82619278517639096600e3,
     3.36093607810698293419e2]
)
_J1_Z1 = 1.46819706421238932572e1
_J1_Z2 = 4.92184563216946036703e1
_THPIO4 = 2.35619449019234492885  # 3 pi / 4
_SQ2OPI = 0.79788456080286535588  # sqrt(2 / pi)


@njit(cache=True)
def _polevl(x, coef):
    ans = coef[0]
    for k in range(1, coef.shape[0]):
        ans = ans * x + coef[k]
    return ans


@njit(cache=True)
def _p1evl(x, coef):
    ans = x + coef[0]
    for k in range(1, coef.shape[0]):
        ans = ans * x + coef[k]
    return ans


@njit(cache=True)
def bessel_j1(x):
    """Bessel function of the first kind of order one, ``J1(x)``.

    Cephes ``j1`` (Moshier 2000): a rational approximation times the factored first two
    zeros for ``|x| <= 5`` and the Hankel asymptotic form with rational ``P``, ``Q`` for
    ``|x| > 5`` (Abramowitz & Stegun 9.2.5 structure). Absolute error about 3e-16.

    Parameters
    ----------
    x : float
        Argument (dimensionless). ``J1`` is odd: ``J1(-x) = -J1(x)``.

    Returns
    -------
    float
        ``J1(x)``.
    """
    w = abs(x)
    if w <= 5.0:
        z = x * x
        p = _polevl(z, _J1_RP) / _p1evl(z, _J1_RQ)
        return p * x * (z - _J1_Z1) * (z - _J1_Z2)
    w5 = 5.0 / w
    z = w5 * w5
    p = _polevl(z, _J1_PP) / _polevl(z, _J1_PQ)
    q = _polevl(z, _J1_QP) / _p1evl(z, _J1_QQ)
    xn = w - _THPIO4
    r = (p * math.cos(xn) - w5 * q * math.sin(xn)) * _SQ2OPI / math.sqrt(w)
    return r if x > 0.0 else -r


@njit(cache=True)
def disc_otf(radius_px, rho_cyc_per_px):
    """Normalised Fourier transform of a uniform disc.

    ``OTF(rho) = 2 J1(2 pi a rho) / (2 pi a rho)`` (Goodman, Introduction to Fourier
    Optics, Sec. 2.1 table of transforms: ``circ(r/a)`` <-> ``a J1(2 pi a rho) / rho``,
    divided by the area ``pi a^2``). Equals 1 at ``rho = 0`` and for ``a = 0``.

    Parameters
    ----------
    radius_px : float
        Disc radius ``a`` in px (>= 0).
    rho_cyc_per_px : float
        Radial spatial frequency in cycles/px (>= 0).

    Returns
    -------
    float
        The dimensionless transfer function value.
    """
    t = 2.0 * math.pi * radius_px * rho_cyc_per_px
    if t < 1e-4:
        # series 1 - t^2/8 + t^4/192; truncation error < t^6/9216 < 1e-27
        t2 = t * t
        return 1.0 - t2 / 8.0 + t2 * t2 / 192.0
    return 2.0 * bessel_j1(t) / t


@njit(cache=True)
def airy_otf(rho_cyc_per_px, cutoff_cyc_per_px):
    """Incoherent OTF of an aberration-free circular pupil (Goodman's "chat").

    ``H(v) = (2/pi) [acos(v) - v sqrt(1 - v^2)]`` for ``v = rho / rho_c <= 1``, else 0
    (Goodman, Introduction to Fourier Optics, Sec. 6.3, OTF of a diffraction-limited
    system with a circular pupil), with incoherent cutoff ``rho_c = 1 / (lambda N)``.

    Parameters
    ----------
    rho_cyc_per_px : float
        Radial spatial frequency in cycles/px.
    cutoff_cyc_per_px : float
        Cutoff ``rho_c = pixel_pitch / (wavelength * f_number)`` in cycles/px (> 0).

    Returns
    -------
    float
        The dimensionless OTF, 1 at zero frequency.
    """
    v = rho_cyc_per_px / cutoff_cyc_per_px
    if v >= 1.0:
        return 0.0
    return (2.0 / math.pi) * (math.acos(v) - v * math.sqrt(1.0 - v * v))


@njit(cache=True)
def _sinc(t):
    if t == 0.0:
        return 1.0
    a = math.pi * t
    return math.sin(a) / a


@njit(cache=True)
def _freq_extent(sigma, weight, cutoff, is_airy, neg_log_eps):
    # The Gaussian factor exp(-2 pi^2 s^2 rho^2) bounds every other factor (|sinc|,
    # |disc OTF|, |chat| <= 1) and falls below eps at rho_g; the Airy OTF vanishes
    # beyond its largest cutoff (of the wavelengths with non-zero weight).
    fmax = np.inf
    if sigma > 0.0:
        fmax = math.sqrt(neg_log_eps / (2.0 * math.pi * math.pi * sigma * sigma))
    if is_airy:
        cmax = 0.0
        for j in range(weight.shape[0]):
            if weight[j] > 0.0 and cutoff[j] > cmax:
                cmax = cutoff[j]
        if cmax < fmax:
            fmax = cmax
    return fmax


@njit(cache=True)
def _phase_ramp(phase, weight, n, re, im):
    # re[k] + i im[k] = weight exp(i phase k), k = 0..n-1, by complex recurrence,
    # re-anchored on direct cos/sin every 16 steps (rounding error < 1e-15).
    c1 = math.cos(phase)
    s1 = math.sin(phase)
    cr = weight
    ci = 0.0
    for k in range(n):
        if k % 16 == 0:
            cr = weight * math.cos(phase * k)
            ci = weight * math.sin(phase * k)
        re[k] = cr
        im[k] = ci
        t = cr * c1 - ci * s1
        ci = cr * s1 + ci * c1
        cr = t


@njit(cache=True)
def _one_star_spectrum(pos_x, pos_y, shift_x, shift_y, weight, sigma, radius, cutoff,
                       is_airy, neg_log_eps, chat, disc_tab, use_disc_tab, acc):
    L = acc.shape[0]
    n_l = weight.shape[0]
    qmax = _freq_extent(sigma, weight, cutoff, is_airy, neg_log_eps) * L
    K = int(math.floor(qmax))  # |q| <= K along each axis, q^2 <= qmax^2 overall
    qmax2 = qmax * qmax
    nq = 2 * K + 1
    # per-wavelength phase ramps exp(-2 pi i q x_l / L), weights folded into the x ramp;
    # index [j, K + qx] so that the loops over qx run over contiguous memory
    ex_re = np.empty((n_l, nq))
    ex_im = np.empty((n_l, nq))
    ey_re = np.empty((n_l, K + 1))
    ey_im = np.empty((n_l, K + 1))
    for j in range(n_l):
        phx = -2.0 * math.pi * (pos_x + shift_x[j]) / L
        phy = -2.0 * math.pi * (pos_y + shift_y[j]) / L
        # q = -K..K: start the ramp at -K
        _phase_ramp(phx, weight[j], nq, ex_re[j], ex_im[j])
        c0 = math.cos(-phx * K)
        s0 = math.sin(-phx * K)
        for k in range(nq):
            t = ex_re[j, k] * c0 - ex_im[j, k] * s0
            ex_im[j, k] = ex_re[j, k] * s0 + ex_im[j, k] * c0
            ex_re[j, k] = t
        _phase_ramp(phy, 1.0, K + 1, ey_re[j], ey_im[j])
    sinc_tab = np.empty(nq)
    fold = np.empty(nq, dtype=np.int64)  # folded (aliased) index of each q
    for k in range(nq):
        q = k - K
        fold[k] = q % L
        if q != 0 and fold[k] == 0:
            sinc_tab[k] = 0.0  # exact zero of the pixel transfer function
        else:
            sinc_tab[k] = _sinc(q / L)
    # star-dependent radial factor (Gaussian x pinhole disc), lazily on integer r2
    nr2 = min(int(math.floor(qmax2)), 2 * K * K) + 1
    rad = np.empty(nr2)
    rad_done = np.zeros(nr2, dtype=np.bool_)
    gfac = -2.0 * math.pi * math.pi * sigma * sigma
    row_re = np.empty(nq)
    row_im = np.empty(nq)
    row_r2 = np.empty(nq, dtype=np.int64)
    # zero frequency: G(0) = sum of the weights, counted once (no conjugate partner)
    s0 = 0.0
    for j in range(n_l):
        s0 += weight[j]
    acc[0, 0] += s0
    for qy in range(K + 1):
        sy_ = sinc_tab[qy + K]
        if sy_ == 0.0:
            continue
        # qx range inside the disc qx^2 + qy^2 <= qmax^2, Hermitian half plane
        kxlim = int(math.floor(math.sqrt(max(qmax2 - qy * qy, 0.0))))
        if kxlim > K:
            kxlim = K
        k_lo = K + (1 if qy == 0 else -kxlim)
        k_hi = K + kxlim + 1
        if k_lo >= k_hi:
            continue
        for k in range(k_lo, k_hi):
            qx = k - K
            r2 = qx * qx + qy * qy
            row_r2[k] = r2
            if not rad_done[r2]:
                rho = math.sqrt(r2) / L
                val = math.exp(gfac * rho * rho)
                if use_disc_tab:
                    val *= disc_tab[r2]
                elif radius > 0.0:
                    val *= disc_otf(radius, rho)
                rad[r2] = val
                rad_done[r2] = True
            row_re[k] = 0.0
            row_im[k] = 0.0
        # sum over wavelengths of w_l [chat_l] exp(-2 pi i (qx x_l + qy y_l) / L)
        for j in range(n_l):
            eyr = ey_re[j, qy]
            eyi = ey_im[j, qy]
            if is_airy:
                # chat_j vanishes beyond this wavelength's own cutoff: skip those terms
                qj2 = cutoff[j] * L * cutoff[j] * L - qy * qy
                if qj2 <= 0.0:
                    continue
                kj = int(math.floor(math.sqrt(qj2)))
                kj_lo = max(k_lo, K - kj)
                kj_hi = min(k_hi, K + kj + 1)
                for k in range(kj_lo, kj_hi):
                    c = chat[j, row_r2[k]]
                    row_re[k] += c * (ex_re[j, k] * eyr - ex_im[j, k] * eyi)
                    row_im[k] += c * (ex_re[j, k] * eyi + ex_im[j, k] * eyr)
            else:
                for k in range(k_lo, k_hi):
                    row_re[k] += ex_re[j, k] * eyr - ex_im[j, k] * eyi
                    row_im[k] += ex_re[j, k] * eyi + ex_im[j, k] * eyr
        row = fold[qy + K]
        for k in range(k_lo, k_hi):
            # q and -q together give 2 Re(G(q) e^{...}) once the real part is taken
            f = 2.0 * sinc_tab[k] * sy_ * rad[row_r2[k]]
            acc[row, fold[k]] += complex(f * row_re[k], f * row_im[k])


@njit(cache=True)
def _shared_tables(weights, sigma, radius, cutoff, is_airy, neg_log_eps, L):
    # Shared radial tables on the integer r2 = qx^2 + qy^2 (only values that are a sum
    # of two squares within the largest frequency disc are evaluated): the Airy OTF of
    # each wavelength, and the pinhole disc OTF when every star has the same radius.
    n = sigma.shape[0]
    n_l = cutoff.shape[0]
    qmax = 0.0
    for i in range(n):
        q = _freq_extent(sigma[i], weights[i], cutoff, is_airy, neg_log_eps) * L
        if q > qmax:
            qmax = q
    kmax = int(math.floor(qmax))
    nr2 = min(int(math.floor(qmax * qmax)), 2 * kmax * kmax) + 1 if n > 0 else 1
    same_radius = n > 0
    for i in range(n):
        if radius[i] != radius[0]:
            same_radius = False
    use_disc_tab = same_radius and radius[0] > 0.0
    chat = np.zeros((n_l, nr2 if is_airy else 1))
    disc_tab = np.ones(nr2 if use_disc_tab else 1)
    if is_airy or use_disc_tab:
        need = np.zeros(nr2, dtype=np.bool_)
        for qy in range(kmax + 1):
            for qx in range(qy, kmax + 1):
                r2 = qx * qx + qy * qy
                if r2 < nr2:
                    need[r2] = True
        for r2 in range(nr2):
            if need[r2]:
                rho = math.sqrt(r2) / L
                if is_airy:
                    for j in range(n_l):
                        chat[j, r2] = airy_otf(rho, cutoff[j])
                if use_disc_tab:
                    disc_tab[r2] = disc_otf(radius[0], rho)
    return chat, disc_tab, use_disc_tab


@njit(cache=True)
def folded_stamp_spectra(pos_x, pos_y, shift_x, shift_y, weights, sigma, radius, cutoff,
                         is_airy, neg_log_eps, out):
    """Folded spectra of pixel-integrated polychromatic star images on periodic stamps.

    For star ``i`` the continuous spectrum of its pixel-integrated image is
    ``G(f) = sum_l w_l OTF_disc(rho) OTF_cam(rho, l) sinc(fx) sinc(fy)
    exp(-2 pi i (fx x_l + fy y_l))`` and, by the Poisson summation formula, the stamp
    values at integer pixel offsets of an ``L``-periodic stamp are
    ``I[r, c] = Re( (1/L^2) sum_k A[k] exp(2 pi i (ky r + kx c) / L) )`` with
    ``A[k] = sum over q = k (mod L) of G(q / L)``. This kernel writes ``A`` (only the
    Hermitian half plane, doubled), so ``Re(numpy.fft.ifft2(out))`` is the stamp.

    The Airy OTF depends only on ``|q|^2`` (an integer) and the wavelength, so it is
    tabulated once per call for all stars, as is the pinhole OTF when all stars share
    one radius; the Gaussian factor (and the pinhole OTF otherwise) is tabulated per
    star. Serial; :func:`folded_stamp_spectra_parallel` is the same over threads.

    Parameters
    ----------
    pos_x, pos_y : ndarray, shape (n,)
        Star position at the reference wavelength relative to the stamp origin, px.
    shift_x, shift_y : ndarray, shape (n, n_l)
        Displacement of each wavelength's image, px.
    weights : ndarray, shape (n, n_l)
        Flux weight of each wavelength (rows sum to 1).
    sigma : ndarray, shape (n,)
        Gaussian sigma in px (PSF for the Gaussian kind, extra blur for Airy; >= 0).
    radius : ndarray, shape (n,)
        Pinhole (uniform disc) radius in px (>= 0).
    cutoff : ndarray, shape (n_l,)
        Airy incoherent cutoff frequency in cycles/px (ignored unless ``is_airy``).
    is_airy : bool
        Camera PSF kind: Airy (times Gaussian blur) if true, Gaussian otherwise.
    neg_log_eps : float
        ``-ln(eps)``: frequencies where the Gaussian envelope is below ``eps`` are dropped.
    out : ndarray of complex128, shape (n, L, L)
        Zero-filled on entry; receives the folded spectra.
    """
    L = out.shape[1]
    chat, disc_tab, use_disc_tab = _shared_tables(weights, sigma, radius, cutoff, is_airy,
                                                  neg_log_eps, L)
    for i in range(pos_x.shape[0]):
        _one_star_spectrum(pos_x[i], pos_y[i], shift_x[i], shift_y[i], weights[i],
                           sigma[i], radius[i], cutoff, is_airy, neg_log_eps, chat,
                           disc_tab, use_disc_tab, out[i])


@njit(cache=True, parallel=True)
def folded_stamp_spectra_parallel(pos_x, pos_y, shift_x, shift_y, weights, sigma, radius,
                                  cutoff, is_airy, neg_log_eps, out):
    """:func:`folded_stamp_spectra` with the stars spread over numba threads.

    Each star is computed independently by the same serial code, so the result is
    bit-identical to the serial kernel whatever the number of threads.
    """
    L = out.shape[1]
    chat, disc_tab, use_disc_tab = _shared_tables(weights, sigma, radius, cutoff, is_airy,
                                                  neg_log_eps, L)
    for i in prange(pos_x.shape[0]):
        _one_star_spectrum(pos_x[i], pos_y[i], shift_x[i], shift_y[i], weights[i],
                           sigma[i], radius[i], cutoff, is_airy, neg_log_eps, chat,
                           disc_tab, use_disc_tab, out[i])


@njit(cache=True)
def stamp_work(weights, sigma, cutoff, is_airy, neg_log_eps, L):
    """Number of (frequency, wavelength) terms the stamp kernels will evaluate.

    ``sum_i n_l (pi / 2) (L f_max,i)^2``: the cost model used to decide whether
    spreading stars over threads is worth its start-up cost.
    """
    total = 0.0
    for i in range(sigma.shape[0]):
        q = _freq_extent(sigma[i], weights[i], cutoff, is_airy, neg_log_eps) * L
        total += 0.5 * math.pi * q * q * weights.shape[1]
    return total
