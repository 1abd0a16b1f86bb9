"""Numba kernels for pixel-integrated polychromatic PSF stamps.

Only arrays and scalars cross this boundary; validation, unit conversion, the radial
transfer-function tables (:mod:`simcam.starcam.psf_transfer`) and the final inverse FFT
live in :mod:`simcam.starcam.optics`.

Functions
---------
folded_stamp_spectra, folded_stamp_spectra_parallel
    The aliased (folded) spectrum of each star's pixel-integrated image on an
    ``L x L`` periodic stamp; ``Re(ifft2(spectrum))`` is the stamp (serial, and over
    threads with bit-identical results).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True, inline="always")
def _extent(qm, Kp):
    """A star's frequency extent on a lattice of half-width ``Kp``: ``K = min(floor(qm), Kp)``
    (``|q| <= K`` along each axis), ``qm^2`` and the row length ``2 K + 1``."""
    K = int(math.floor(qm))
    if K > Kp:
        K = Kp
    return K, qm * qm, 2 * K + 1


@njit(cache=True, inline="always")
def _row_range(qmax2, qy, K):
    """Columns ``k_lo .. k_hi - 1`` (``qx = k - K``) of row ``qy`` inside the disc ``qx^2 + qy^2
    <= qmax2`` on the Hermitian half plane (``qx > 0`` on ``qy = 0``)."""
    kxlim = int(math.floor(math.sqrt(max(qmax2 - qy * qy, 0.0))))
    if kxlim > K:
        kxlim = K
    return K + (1 if qy == 0 else -kxlim), K + kxlim + 1


@njit(cache=True)
def _sinc(t):
    if t == 0.0:
        return 1.0
    a = math.pi * t
    return math.sin(a) / a


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


@njit(cache=True, inline="always")
def _ramps(phx, phy, weight, K, ex_re, ex_im, ey_re, ey_im):
    """One wavelength's phase ramps: ``weight exp(i phx q)`` for ``q = -K .. K`` into
    ``ex_re``/``ex_im`` (the ramp from 0, turned by ``exp(-i phx K)`` to start at ``-K``) and
    ``exp(i phy q)`` for ``q = 0 .. K`` into ``ey_re``/``ey_im`` (:func:`_phase_ramp`)."""
    nq = 2 * K + 1
    _phase_ramp(phx, weight, nq, ex_re, ex_im)
    c0 = math.cos(-phx * K)
    s0 = math.sin(-phx * K)
    for k in range(nq):
        t = ex_re[k] * c0 - ex_im[k] * s0
        ex_im[k] = ex_re[k] * s0 + ex_im[k] * c0
        ex_re[k] = t
    _phase_ramp(phy, 1.0, K + 1, ey_re, ey_im)


@njit(cache=True)
def _one_star_spectrum(pos_x, pos_y, shift_x, shift_y, weight, sigma, qmax, cutoff,
                       is_airy, chat, disc, acc):
    L = acc.shape[0]
    n_l = weight.shape[0]
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
        _ramps(phx, phy, weight[j], K, ex_re[j], ex_im[j], ey_re[j], ey_im[j])
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
        k_lo, k_hi = _row_range(qmax2, qy, K)
        if k_lo >= k_hi:
            continue
        for k in range(k_lo, k_hi):
            qx = k - K
            r2 = qx * qx + qy * qy
            row_r2[k] = r2
            if not rad_done[r2]:
                rho = math.sqrt(r2) / L
                rad[r2] = math.exp(gfac * rho * rho) * disc[r2]
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
def folded_stamp_spectra(pos_x, pos_y, shift_x, shift_y, weights, sigma, qmax, cutoff,
                         is_airy, chat, disc, out):
    """Folded spectra of pixel-integrated polychromatic star images on periodic stamps.

    For star ``i`` the continuous spectrum of its pixel-integrated image is
    ``G(f) = sum_l w_l OTF_disc(rho) OTF_cam(rho, l) sinc(fx) sinc(fy)
    exp(-2 pi i (fx x_l + fy y_l))`` and, by the Poisson summation formula, the stamp
    values at integer pixel offsets of an ``L``-periodic stamp are
    ``I[r, c] = Re( (1/L^2) sum_k A[k] exp(2 pi i (ky r + kx c) / L) )`` with
    ``A[k] = sum over q = k (mod L) of G(q / L)``. This kernel writes ``A`` (only the
    Hermitian half plane, doubled), so ``Re(numpy.fft.ifft2(out))`` is the stamp.

    The Airy OTF and the pinhole's disc OTF depend only on ``|q|^2`` (an integer), so
    they arrive tabulated (:func:`simcam.starcam.psf_transfer.radial_tables`); the
    Gaussian factor is tabulated per star, lazily. Serial;
    :func:`folded_stamp_spectra_parallel` is the same over threads.

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
    qmax : ndarray, shape (n,)
        Frequency extent of each star in lattice units, ``f_max L``
        (:func:`simcam.starcam.psf_transfer.freq_extent_cyc_per_px`).
    cutoff : ndarray, shape (n_l,)
        Airy incoherent cutoff frequency in cycles/px (ignored unless ``is_airy``).
    is_airy : bool
        Camera PSF kind: Airy (times Gaussian blur) if true, Gaussian otherwise.
    chat : ndarray, shape (n_l, nr2)
        Airy OTF of each wavelength at ``rho = sqrt(r2) / L`` (unused unless ``is_airy``).
    disc : ndarray, shape (1, nr2) or (n, nr2)
        Pinhole disc OTF at the same ``rho``: one row for all stars, or one per star.
    out : ndarray of complex128, shape (n, L, L)
        Zero-filled on entry; receives the folded spectra.
    """
    per_star = disc.shape[0] > 1
    for i in range(pos_x.shape[0]):
        _one_star_spectrum(pos_x[i], pos_y[i], shift_x[i], shift_y[i], weights[i], sigma[i],
                           qmax[i], cutoff, is_airy, chat, disc[i if per_star else 0], out[i])


@njit(cache=True, parallel=True)
def folded_stamp_spectra_parallel(pos_x, pos_y, shift_x, shift_y, weights, sigma, qmax,
                                  cutoff, is_airy, chat, disc, out):
    """:func:`folded_stamp_spectra` with the stars spread over numba threads.

    Each star is computed independently by the same serial code, so the result is
    bit-identical to the serial kernel whatever the number of threads.
    """
    per_star = disc.shape[0] > 1
    for ii in prange(pos_x.shape[0]):
        i = np.int64(ii)
        _one_star_spectrum(pos_x[i], pos_y[i], shift_x[i], shift_y[i], weights[i], sigma[i],
                           qmax[i], cutoff, is_airy, chat, disc[i if per_star else 0], out[i])


# ----------------------------------------------------------------------------------------
# Shifted stamps from a position-free spectral profile (the "profile" stamp route)


@njit(cache=True)
def stamp_profiles(shift_x, shift_y, weights, qmax, cutoff, is_airy, chat, disc, L, out):
    """Position-free half-plane spectra of pixel-integrated polychromatic star images.

    For star ``i`` and lattice frequency ``q = (qx, qy)`` (``qy >= 0``; ``qx > 0`` on
    ``qy = 0``; ``|q| <= qmax_i``) writes, at ``out[i, qy, K + qx]`` (``K = out.shape[2] // 2``),
    ``sinc(qx / L) sinc(qy / L) OTF_disc(|q| / L) sum_l w_l [chat_l(|q| / L)]
    exp(-2 pi i (qx sx_l + qy sy_l) / L)``: the spectrum ``G(q / L)`` of
    :func:`folded_stamp_spectra` without its position phase and without its Gaussian
    factor, which :func:`shifted_stamp_spectra` applies for the star's actual position and
    width. Other entries are left as they are (zero-filled on entry).

    Wavelengths of zero weight are skipped: their terms are signed zeros (the weight
    multiplies the x ramp), and adding a zero to the running sum, which starts at +0 and
    can never become -0 (round to nearest), leaves it as it is: the result is the same bit
    for bit, at the cost of the wavelengths a filter passes.
    """
    n = shift_x.shape[0]
    n_l = weights.shape[1]
    Kp = out.shape[2] // 2
    act = np.empty(n_l, dtype=np.int64)
    for i in range(n):
        qm = qmax[i]
        K, qmax2, nq = _extent(qm, Kp)
        na = 0
        for j in range(n_l):
            if weights[i, j] != 0.0:
                act[na] = j
                na += 1
        ex_re = np.empty((na, nq))
        ex_im = np.empty((na, nq))
        ey_re = np.empty((na, K + 1))
        ey_im = np.empty((na, K + 1))
        for a in range(na):
            j = act[a]
            phx = -2.0 * math.pi * shift_x[i, j] / L
            phy = -2.0 * math.pi * shift_y[i, j] / L
            _ramps(phx, phy, weights[i, j], K, ex_re[a], ex_im[a], ey_re[a], ey_im[a])
        drow = disc[i if disc.shape[0] > 1 else 0]
        row_re = np.empty(nq)
        row_im = np.empty(nq)
        for qy in range(K + 1):
            q_y = qy % L
            if qy != 0 and q_y == 0:
                continue  # exact zero of the pixel transfer function
            sy_ = _sinc(qy / L)
            k_lo, k_hi = _row_range(qmax2, qy, K)
            # the row's sums over wavelengths, wavelength outer, frequency inner: each
            # frequency's sum takes its terms in the same order as one frequency at a
            # time, so the same bits, as independent sums the processor overlaps
            for k in range(k_lo, k_hi):
                row_re[k] = 0.0
                row_im[k] = 0.0
            for a in range(na):
                eyr = ey_re[a, qy]
                eyi = ey_im[a, qy]
                if is_airy:
                    j = act[a]
                    for k in range(k_lo, k_hi):
                        qx = k - K
                        c = chat[j, qx * qx + qy * qy]
                        if c == 0.0:
                            continue
                        row_re[k] += c * (ex_re[a, k] * eyr - ex_im[a, k] * eyi)
                        row_im[k] += c * (ex_re[a, k] * eyi + ex_im[a, k] * eyr)
                else:  # c = 1: a product by 1.0 is exact, so it is left out
                    for k in range(k_lo, k_hi):
                        row_re[k] += ex_re[a, k] * eyr - ex_im[a, k] * eyi
                        row_im[k] += ex_re[a, k] * eyi + ex_im[a, k] * eyr
            for k in range(k_lo, k_hi):
                qx = k - K
                if qx != 0 and qx % L == 0:
                    continue
                r2 = qx * qx + qy * qy
                f = _sinc(qx / L) * sy_ * drow[r2]
                out[i, qy, Kp + qx] = complex(f * row_re[k], f * row_im[k])


@njit(cache=True)
def shifted_stamp_spectra(prof, qmax, zero, pos_x, pos_y, sigma, L, out):
    """Hermitian half spectra (``numpy.fft.irfft2`` input) of stars at ``(pos_x, pos_y)``
    px from their stamp origin, from their profiles (:func:`stamp_profiles`).

    ``G(q) = prof[q] exp(-2 pi^2 sigma^2 |q|^2 / L^2) exp(-2 pi i (qx pos_x + qy pos_y) / L)``
    on the half plane, folded (aliased) onto the ``L x L`` lattice as ``A``; the full
    spectrum is ``F(k) = A(k) + conj(A(-k))`` (``G(-q) = conj(G(q))``) plus the zero
    frequency ``zero[i]`` (the sum of the weights), and only its columns ``0 .. L // 2`` are
    written. ``out`` (n, L, L // 2 + 1) complex128, zero-filled on entry. The Gaussian and
    the phase are separable products (``exp(a (qx^2 + qy^2)) = exp(a qx^2) exp(a qy^2)``),
    so a row ``qy`` is ``ey(qy) sum_qx prof(qx, qy) ex(qx)``: one complex product per frequency.
    """
    n = pos_x.shape[0]
    Kp = prof.shape[2] // 2
    H = L // 2
    A = np.empty((L, L), dtype=np.complex128)
    row = np.empty(L, dtype=np.complex128)
    for i in range(n):
        qm = qmax[i]
        K, qmax2, nq = _extent(qm, Kp)
        gfac = -2.0 * math.pi * math.pi * sigma[i] * sigma[i] / (L * L)
        ex_re = np.empty(nq)
        ex_im = np.empty(nq)
        ey_re = np.empty(K + 1)
        ey_im = np.empty(K + 1)
        phx = -2.0 * math.pi * pos_x[i] / L
        _phase_ramp(phx, 1.0, nq, ex_re, ex_im)
        c0 = math.cos(-phx * K)
        s0 = math.sin(-phx * K)
        ex = np.empty(nq, dtype=np.complex128)
        fold = np.empty(nq, dtype=np.int64)
        for k in range(nq):
            qx = k - K
            gx = math.exp(gfac * qx * qx)
            ex[k] = complex((ex_re[k] * c0 - ex_im[k] * s0) * gx, (ex_re[k] * s0 + ex_im[k] * c0) * gx)
            fold[k] = qx % L
        _phase_ramp(-2.0 * math.pi * pos_y[i] / L, 1.0, K + 1, ey_re, ey_im)
        A[:, :] = 0.0
        pi_ = prof[i]
        for qy in range(K + 1):
            k_lo, k_hi = _row_range(qmax2, qy, K)
            if k_lo >= k_hi:
                continue
            row[:] = 0.0
            for k in range(k_lo, k_hi):
                row[fold[k]] += pi_[qy, Kp - K + k] * ex[k]
            gy = math.exp(gfac * qy * qy)
            ey = complex(ey_re[qy] * gy, ey_im[qy] * gy)
            fy = qy % L
            for c in range(L):
                A[fy, c] += row[c] * ey
        o = out[i]
        for r in range(L):
            rn = (L - r) % L
            for c in range(H + 1):
                cn = (L - c) % L
                o[r, c] += A[r, c] + A[rn, cn].conjugate()
        o[0, 0] += zero[i]
