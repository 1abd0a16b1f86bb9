"""numba kernels of the variance-reduced truths (:mod:`budget.starcam.truth`): windows
exposed and centroided as a trial does, with a control variate of each frame's centroid
beside it whose expectation is exactly zero.

**Exposure and centroid.** :func:`expose_centroid_cv_serial` computes each pixel with the
steps and counters of :func:`simcam.kernels.detector._noise_adc_prepared` (Poisson draw,
full-well clip, read noise, conversion, rounding and clipping to ``[0, max_dn]``) and
centroids it as :func:`budget.starcam.kernels_trial.expose_centroid_frames_serial` does
(border median background, threshold above it, no threshold subtraction, no saturation
flag): the same pixels and centroids bit for bit (``tests/test_truth_variance_reduction.py``).

**The pixel deviates.** Pixel ``p`` of mean charge ``mu_p`` (e-, the chain's ``mean_e``, after
any non-linearity) draws ``P_p ~ Poisson(mu_p)`` and ``r z_p`` (read noise); its deviate
``n_p = (P_p - mu_p) + r z_p`` (e-) is taken *before* every non-linear step of the chain, so
its distribution is known exactly: a Poisson of mean ``mu_p`` shifted by ``-mu_p``, plus an
independent normal of sd ``r``; the pixels are independent. (A pixel of mean 0 draws 0: a
Poisson of mean 0.) The unrounded value is ``Y_p = (mu_p + n_p) / G + offset`` (DN) and the
pixel read is ``V_p = round(Y_p)`` (unless clipped).

**The control variate.** The thresholded centre of gravity is ``x_c = x_0 + sum_p j_p w_p /
sum_p w_p`` with ``w_p = (V_p - b) 1{V_p - b > t}``; about the centre ``x_e`` and sum ``S`` of
the expected weights, its first-order part in the numerator is ``sum_p a_p w_p`` with
``a_p = (j_p - x_e) / S``. The control variate keeps that part's threshold exact and is
built so that its expectation is known:

``phi = sum_(interior p) a_p (Y_p - b) 1{n_p >= tau_p(d(b))}
      + sum_(border q) a_q (Y_q - b_-q) 1{n_q >= tau_q(d(b_-q))}``

with ``d(c) = floor(c + t) + 1`` (``V - c > t`` for an integer ``V`` is ``V >= d(c)``, and
``V_p >= d`` is ``n_p >= tau_p(d) = G (d - 1/2 - offset) - mu_p``), ``b`` the window's
border median (the lab's background) and ``b_-q`` the median of the border without pixel
``q``. The interior pixels are independent of the border, so of ``b``; pixel ``q`` is
independent of ``b_-q``. Hence, given those medians, each term's expectation is a
function of one pixel's known distribution,
``E[a (Y - c) 1{n >= tau}] = a ((m - c) Q(d) + M_1(d) / G)``, ``m = mu / G + offset``,
``Q(d) = P(n >= tau(d))``, ``M_k(d) = E[n^k 1{n >= tau(d)}]`` (:func:`cv_tables`), and

``psi = phi - E[phi | b, b_-q for every q]``

has ``E[psi | the medians] = 0``, so ``E[psi] = 0`` exactly (a term whose ``d`` falls outside
the tabulated range is left out of both, which keeps this). The HSFE truth subtracts
``psi`` from each frame's centroid error: same expectation, much smaller variance.

**The square.** For the TE truth (a variance), ``kappa = psi_int^2 - Var(phi_int | b) + 2 psi_int psi_bord
+ sum_q (psi_q^2 - Var(phi_q | b_-q))`` has expectation exactly 0 too: the interior's
terms are independent given the border (so ``E[psi_int^2 | border] = Var(phi_int | b)``, a sum
over pixels, and ``E[psi_int psi_bord | border] = psi_bord E[psi_int | border] = 0``), and
``E[psi_q^2 | b_-q] = Var(phi_q | b_-q)``. So ``psi^2 - kappa`` is an unbiased estimate of
``Var(psi)``, and :func:`budget.starcam.truth.te_variance_cv` estimates the centroid's variance
as ``Var(x) - Var(psi)`` from the frames (which scatter little: ``psi`` follows ``x``) plus
that; only the border terms' cross products ``psi_q psi_q'`` (two border pixels above
threshold in one frame) are left to the frames.

``Q``, ``M_1``, ``M_2`` are sums over the Poisson's values ``k`` of its probabilities times the
normal's integrals ``Phi^c(u)``, ``r phi(u)``, ``r^2 (u phi(u) + Phi^c(u))``,
``u = (G (d - 1/2 - offset) - k) / r``; the terms with ``|u| > U_CUT`` (8) are taken as their limits
(an error below 7e-16 of each probability), the rest are exact sums.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from budget.centroid.kernels import FLAG_LOST, border_one, cog_one
from simcam.kernels.detector import SLOT_READ, SLOT_SHOT, _chip_segment, slot_counter
from simcam.rng import std_normal
from simcam.rng_poisson import POISSON_MAX_LAM, poisson_prepared, poisson_setup

#: tabulated thresholds ``d`` either side of that of the noise-free background (DN): the
#: border median's sd is a fraction of a DN; a frame whose median falls beyond drops the
#: term (and its expectation): no bias
D_HALF_RANGE = 3
#: ``|u|`` beyond which the normal's tail is taken as its limit (an error below 7e-16)
U_CUT = 8.0
_SQRT2 = math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)


@njit(cache=True)
def _normal_table(g, off, r, dlo, nd, klo, khi, t0, t1, t2):
    """``t0 = Phi^c(u)``, ``t1 = k Phi^c + r phi``, ``t2 = k^2 Phi^c + 2 k r phi + r^2 (u phi + Phi^c)``
    at ``u = (G (d - 1/2 - offset) - k) / r`` for ``d = dlo + di``, ``k = klo .. khi``: the
    expectations of ``1``, ``P + r z``, ``(P + r z)^2`` times ``1{P + r z >= G (d - 1/2 - offset)}``
    given ``P = k`` (``r = 0``: the step)."""
    for di in range(nd):
        th = g * (dlo + di - 0.5 - off)
        for k in range(klo, khi + 1):
            if r > 0.0:
                u = (th - k) / r
                if u > U_CUT:
                    sc = 0.0
                    ph = 0.0
                elif u < -U_CUT:
                    sc = 1.0
                    ph = 0.0
                else:
                    sc = 0.5 * math.erfc(u / _SQRT2)
                    ph = _INV_SQRT2PI * math.exp(-0.5 * u * u)
                t0[di, k - klo] = sc
                t1[di, k - klo] = k * sc + r * ph
                t2[di, k - klo] = k * k * sc + 2.0 * k * r * ph + r * r * (u * ph + sc)
            else:
                sc = 1.0 if k >= th else 0.0
                t0[di, k - klo] = sc
                t1[di, k - klo] = k * sc
                t2[di, k - klo] = k * k * sc


@njit(cache=True)
def cv_tables(mean_e, chip, gain, offset, read_noise, dlo, nd, out_q, out_m1, out_m2):
    """``Q``, ``M_1``, ``M_2`` (module docstring) of every pixel of ``n`` windows (``out_*``
    (n, h, w, nd)) for ``d = dlo[k] .. dlo[k] + nd - 1``; ``chip`` (n, w) the chip of each
    window column.

    For each pixel: the Poisson's probabilities ``p_k`` for ``k = 0 .. k_hi`` (by the
    recurrence ``p_(k+1) = p_k mu / (k + 1)`` from the mode), the normal's integrals given
    ``k`` (:func:`_normal_table`, where ``|u| <= U_CUT``) summed with them, and the mass above
    ``k_hi`` (where ``Phi^c = 1``) in closed form from the Poisson's moments ``E P = mu``,
    ``E P^2 = mu^2 + mu``. ``M_1 = E[(P + r z) 1] - mu Q``, ``M_2 = E[(P + r z)^2 1] - 2 mu E[(P + r z) 1] + mu^2 Q``.
    """
    n, h, w = mean_e.shape
    # the normal's tables depend on the chip and d only: kept while they stay the same
    # (from one window to the next too: most windows share their chip and d range)
    last = -1
    last_dl = 0
    klo = 0
    khi = 0
    t0 = np.empty((0, 0))
    t1 = np.empty((0, 0))
    t2 = np.empty((0, 0))
    for k in range(n):
        dl = dlo[k]
        for j in range(w):
            c = chip[k, j]
            g = gain[c]
            off = offset[c]
            r = read_noise[c]
            if c != last or dl != last_dl:
                klo = max(0, int(math.floor(g * (dl - 0.5 - off) - U_CUT * r)))
                khi = max(0, int(math.ceil(g * (dl + nd - 1 - 0.5 - off) + U_CUT * r)))
                t0 = np.empty((nd, khi - klo + 1))
                t1 = np.empty((nd, khi - klo + 1))
                t2 = np.empty((nd, khi - klo + 1))
                _normal_table(g, off, r, dl, nd, klo, khi, t0, t1, t2)
                last = c
                last_dl = dl
            pm = np.zeros(khi + 1)
            for i in range(h):
                mu = mean_e[k, i, j]
                pm[:] = 0.0
                if mu > 0.0:
                    k0 = min(khi, int(mu))
                    p0 = math.exp(k0 * math.log(mu) - mu - math.lgamma(k0 + 1.0))
                    pm[k0] = p0
                    p = p0
                    for kk in range(k0, 0, -1):
                        p = p * kk / mu
                        pm[kk - 1] = p
                    p = p0
                    for kk in range(k0 + 1, khi + 1):
                        p = p * mu / kk
                        pm[kk] = p
                else:
                    pm[0] = 1.0
                c0 = 0.0
                c1 = 0.0
                c2 = 0.0
                for kk in range(khi + 1):
                    c0 += pm[kk]
                    c1 += kk * pm[kk]
                    c2 += kk * kk * pm[kk]
                u0 = max(1.0 - c0, 0.0)
                u1 = mu - c1
                u2 = mu * mu + mu - c2
                inband = 0.0
                for kk in range(klo, khi + 1):
                    inband += pm[kk]
                # two d at a time: six independent sums, each over k in the same order as
                # one d at a time (the same bits), which the processor overlaps
                for di in range(0, nd - 1, 2):
                    s0 = u0
                    s1 = u1
                    s2 = u2 + r * r * u0
                    q0 = u0
                    q1 = u1
                    q2 = u2 + r * r * u0
                    if inband > 0.0:
                        for kk in range(klo, khi + 1):
                            p = pm[kk]
                            s0 += p * t0[di, kk - klo]
                            s1 += p * t1[di, kk - klo]
                            s2 += p * t2[di, kk - klo]
                            q0 += p * t0[di + 1, kk - klo]
                            q1 += p * t1[di + 1, kk - klo]
                            q2 += p * t2[di + 1, kk - klo]
                    out_q[k, i, j, di] = s0
                    out_m1[k, i, j, di] = s1 - mu * s0
                    out_m2[k, i, j, di] = s2 - 2.0 * mu * s1 + mu * mu * s0
                    out_q[k, i, j, di + 1] = q0
                    out_m1[k, i, j, di + 1] = q1 - mu * q0
                    out_m2[k, i, j, di + 1] = q2 - 2.0 * mu * q1 + mu * mu * q0
                if nd % 2:
                    di = nd - 1
                    s0 = u0
                    s1 = u1
                    s2 = u2 + r * r * u0
                    if inband > 0.0:
                        for kk in range(klo, khi + 1):
                            p = pm[kk]
                            s0 += p * t0[di, kk - klo]
                            s1 += p * t1[di, kk - klo]
                            s2 += p * t2[di, kk - klo]
                    out_q[k, i, j, di] = s0
                    out_m1[k, i, j, di] = s1 - mu * s0
                    out_m2[k, i, j, di] = s2 - 2.0 * mu * s1 + mu * mu * s0


@njit(cache=True)
def _median_with_top(srt, nb, vq):
    """Median of the sorted border ``srt[:nb]`` with one copy of ``vq`` replaced by a value
    above all: a function of the other border pixels only, equal to the border's median
    whenever ``vq`` is in its upper half (so whenever the pixel is above threshold)."""
    i1 = (nb - 1) // 2
    i2 = nb // 2
    # the others, in order: srt[i] below the first copy of vq, srt[i + 1] from it on
    a = srt[i1] if srt[i1] < vq else srt[i1 + 1]
    b = srt[i2] if srt[i2] < vq else srt[i2 + 1]
    return 0.5 * (a + b)


@njit(cache=True)
def expose_centroid_cv_serial(mean_e, row0, col0, mosaic_cols, chip_cols, gain, offset, read_noise,
                              full_well, frame_keys, max_dn, threshold, ax, ay, udn, tq, tm1, tm2, dlo,
                              b0, sint, out_x, out_y, out_flag, out_psi_x, out_psi_y, out_kap_x, out_kap_y):
    """Expose ``n`` windows in ``F`` frames, centroid each and give its control variates
    (module docstring). ``ax``/``ay`` (n, h, w) the coefficients ``a_p`` (px per DN), ``udn``
    (n, h, w) the pixels' means less the noise-free border median ``b0`` (n,) (DN),
    ``tq``/``tm1``/``tm2`` (n, h, w, nd) and ``dlo`` (n,) the tables of :func:`cv_tables`,
    ``sint`` (n, 2, nd, 5) the interior's sums (:func:`cv_prepare`); ``out_*`` (F, n)."""
    n, h, w = mean_e.shape
    nf = frame_keys.shape[0]
    nd = tq.shape[3]
    wins = np.empty((nf, h, w))
    dev = np.empty((nf, h, w))
    buf = np.empty(2 * w + 2 * max(h - 2, 0))
    nb = 2 * w + 2 * max(h - 2, 0)
    bi = np.empty(nb, dtype=np.int64)
    bj = np.empty(nb, dtype=np.int64)
    m = 0
    for i in range(h):
        for j in range(w):
            if i == 0 or j == 0 or i == h - 1 or j == w - 1:
                bi[m] = i
                bj[m] = j
                m += 1
    srt = np.empty(nb)
    gpix = np.empty(w)
    opix = np.empty(w)
    tau = np.empty((nd, h, w))
    for k in range(n):
        j = 0
        while j < w:
            chip, j_end = _chip_segment(col0[k], j, w, chip_cols)
            g = gain[chip]
            off = offset[chip]
            rn = read_noise[chip]
            fw = full_well[chip]
            for jj in range(j, j_end):
                gpix[jj] = g
                opix[jj] = off
            for i in range(h):
                base = (row0[k] + i) * mosaic_cols + col0[k]
                for jj in range(j, j_end):
                    mu = mean_e[k, i, jj]
                    for di in range(nd):
                        tau[di, i, jj] = g * (dlo[k] + di - 0.5 - off) - mu
                    mode, pj, pr, pb, pa, pvr = poisson_setup(mu)
                    pixel = base + jj
                    for f in range(nf):
                        key = frame_keys[f]
                        # the steps of simcam.kernels.detector._noise_adc_prepared, in order
                        v = np.float64(poisson_prepared(mu, mode, pj, pr, pb, pa, pvr, key,
                                                        slot_counter(pixel, SLOT_SHOT)))
                        d = v - mu if mode >= 2 else 0.0
                        if v > fw:
                            v = fw
                        rd = rn * std_normal(key, slot_counter(pixel, SLOT_READ))
                        v += rd
                        dev[f, i, jj] = d + rd
                        v = v / g + off
                        v = math.floor(v + 0.5)
                        if v < 0.0:
                            v = 0.0
                        elif v > max_dn:
                            v = max_dn
                        wins[f, i, jj] = v
            j = j_end
        thr = threshold[k]
        bk = b0[k]
        for f in range(nf):
            win = wins[f]
            b, _ = border_one(win, buf, np.bool_(False))
            t = thr
            pre = 0
            if not (math.isfinite(b) and math.isfinite(t)):
                pre = FLAG_LOST
                if not math.isfinite(t):
                    t = np.inf
            x, y, _, flag = cog_one(win, np.float64(col0[k]), np.float64(row0[k]), b, t, False, np.inf)
            out_x[f, k] = x
            out_y[f, k] = y
            out_flag[f, k] = flag | pre
            psx = 0.0
            psy = 0.0
            kx = 0.0
            ky = 0.0
            if pre == 0:
                # interior, given b: sum over the pixels at or above tau of a (Y - b), less
                # its expectation E = SB - delta SA and with Var = C0 + C1 delta + C2 delta^2
                di = int(math.floor(b + t)) + 1 - dlo[k]
                pix = 0.0
                piy = 0.0
                vx = 0.0
                vy = 0.0
                if 0 <= di < nd:
                    dl = b - bk
                    for i in range(1, h - 1):
                        for jj in range(1, w - 1):
                            dv = dev[f, i, jj]
                            if dv >= tau[di, i, jj]:
                                yv = udn[k, i, jj] + dv / gpix[jj] - dl
                                pix += ax[k, i, jj] * yv
                                piy += ay[k, i, jj] * yv
                    s = sint[k, 0, di]
                    pix -= s[0] - dl * s[1]
                    vx = s[2] + dl * (s[3] + dl * s[4])
                    s = sint[k, 1, di]
                    piy -= s[0] - dl * s[1]
                    vy = s[2] + dl * (s[3] + dl * s[4])
                # border, each given the median of the others (with it on top)
                for q in range(nb):
                    srt[q] = win[bi[q], bj[q]]
                srt.sort()
                pbx = 0.0
                pby = 0.0
                sqx = 0.0
                sqy = 0.0
                for q in range(nb):
                    i = bi[q]
                    jj = bj[q]
                    c = _median_with_top(srt, nb, win[i, jj])
                    dq = int(math.floor(c + t)) + 1 - dlo[k]
                    if not (0 <= dq < nd):
                        continue
                    g = gpix[jj]
                    u = udn[k, i, jj] - (c - bk)        # m - c
                    qv = tq[k, i, jj, dq]
                    be = tm1[k, i, jj, dq] / g
                    ga = tm2[k, i, jj, dq] / (g * g)
                    ev = u * qv + be                    # E[(Y - c) 1]
                    var = u * u * (qv - qv * qv) + 2.0 * u * be * (1.0 - qv) + ga - be * be
                    dv = dev[f, i, jj]
                    z = (u + dv / g) - ev if dv >= tau[dq, i, jj] else -ev
                    px_ = ax[k, i, jj] * z
                    py_ = ay[k, i, jj] * z
                    pbx += px_
                    pby += py_
                    sqx += px_ * px_ - ax[k, i, jj] ** 2 * var
                    sqy += py_ * py_ - ay[k, i, jj] ** 2 * var
                psx = pix + pbx
                psy = piy + pby
                kx = pix * pix - vx + 2.0 * pix * pbx + sqx
                ky = piy * piy - vy + 2.0 * piy * pby + sqy
            out_psi_x[f, k] = psx
            out_psi_y[f, k] = psy
            out_kap_x[f, k] = kx
            out_kap_y[f, k] = ky


def _chip_of(chain) -> np.ndarray:
    """Chip index (n, w) of each window column."""
    W, h, w = chain.mean_e.shape
    return np.ascontiguousarray((chain.col0[:, None] + np.arange(w)[None, :]) // chain.chip_cols, dtype=np.int64)


def _border_mask(h: int, w: int) -> np.ndarray:
    border = np.zeros((h, w), dtype=bool)
    border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
    return border


def cv_prepare(chain, *, threshold_dn) -> dict:
    """What :func:`expose_centroid_cv` needs besides the frames: the coefficients ``a_p``
    (px per DN) of each window, its pixels' means ``m_p`` (DN) and the tables of
    :func:`cv_tables` over ``d`` within :data:`D_HALF_RANGE` of the noise-free background's.

    ``a_p = (j_p - x_e) / S`` about the expected weights ``E[s 1{s > t}] = s Phi(z) + sigma phi(z)``
    of a Gaussian pixel (``s`` its noise-free signal above the noise-free border median,
    ``sigma^2 = Var(n_p) / G^2 + 1/12``, ``z = (s - t) / sigma``). The coefficients only choose
    the control variate; its expectation is 0 whatever they are (module docstring).
    """
    from scipy.special import ndtr

    mu = np.ascontiguousarray(chain.mean_e, dtype=np.float64)
    if np.any(mu > POISSON_MAX_LAM):
        raise ValueError("control variate: a pixel's mean is beyond the Poisson sampler's range")
    W, h, w = mu.shape
    chip = _chip_of(chain)
    g = chain.gain[chip][:, None, :]
    rn = chain.read_noise[chip][:, None, :]
    m = mu / g + chain.offset[chip][:, None, :]
    border = _border_mask(h, w)
    b0 = np.median(m[:, border], axis=1)
    t = np.asarray(threshold_dn, dtype=np.float64).reshape(-1)
    s = m - b0[:, None, None]
    sig = np.sqrt((mu + rn**2) / g**2 + 1.0 / 12.0)
    z = (s - t[:, None, None]) / sig
    ew = s * ndtr(z) + sig * np.exp(-0.5 * z * z) / math.sqrt(2 * math.pi)
    S = ew.sum(axis=(1, 2))
    jj = np.arange(w)[None, None, :]
    ii = np.arange(h)[None, :, None]
    ax = (jj - ((ew * jj).sum(axis=(1, 2)) / S)[:, None, None]) / S[:, None, None]
    ay = (ii - ((ew * ii).sum(axis=(1, 2)) / S)[:, None, None]) / S[:, None, None]
    d0 = np.floor(b0 + t).astype(np.int64) + 1
    nd = 2 * D_HALF_RANGE + 1
    dlo = np.ascontiguousarray(d0 - D_HALF_RANGE, dtype=np.int64)
    tq, tm1, tm2 = (np.empty((W, h, w, nd)) for _ in range(3))
    cv_tables(mu, chip, np.asarray(chain.gain, dtype=np.float64), np.asarray(chain.offset, dtype=np.float64),
              np.asarray(chain.read_noise, dtype=np.float64), dlo, nd, tq, tm1, tm2)
    ax = np.ascontiguousarray(np.broadcast_to(ax, mu.shape))
    ay = np.ascontiguousarray(np.broadcast_to(ay, mu.shape))
    # the interior's sums (per window, axis and d), in delta = b - b0 (u = m - b0):
    # E = SB - delta SA; Var = C0 + C1 delta + C2 delta^2 with, per pixel (alpha = Q,
    # beta = M_1 / G, gamma = M_2 / G^2, A = alpha - alpha^2),
    # Var = a^2 ((u - delta)^2 A + 2 (u - delta) beta (1 - alpha) + gamma - beta^2)
    inner = ~border
    u = s[..., None]
    al = tq
    be = tm1 / g[..., None]
    ga = tm2 / g[..., None] ** 2
    A = al - al * al
    sint = np.empty((W, 2, nd, 5))
    for axis, a in enumerate((ax, ay)):
        aa = (a * inner)[..., None]
        a2 = aa * aa
        sint[:, axis, :, 0] = (aa * (u * al + be)).sum(axis=(1, 2))
        sint[:, axis, :, 1] = (aa * al).sum(axis=(1, 2))
        sint[:, axis, :, 2] = (a2 * (u * u * A + 2 * u * be * (1 - al) + ga - be * be)).sum(axis=(1, 2))
        sint[:, axis, :, 3] = (a2 * (-2 * u * A - 2 * be * (1 - al))).sum(axis=(1, 2))
        sint[:, axis, :, 4] = (a2 * A).sum(axis=(1, 2))
    return {"ax": ax, "ay": ay, "udn": np.ascontiguousarray(s), "tq": tq, "tm1": tm1, "tm2": tm2, "dlo": dlo,
            "b0": np.ascontiguousarray(b0, dtype=np.float64), "sint": sint,
            "threshold": np.ascontiguousarray(t * np.ones(W))}


def expose_centroid_cv(chain, keys, prep: dict):
    """:func:`expose_centroid_cv_serial` for a :class:`simcam.detector.WindowChain` and its
    :func:`cv_prepare`: x, y, flag, psi_x, psi_y, kappa_x, kappa_y as (frames, W)."""
    frames = keys.shape[0]
    W = chain.mean_e.shape[0]
    out = [np.empty((frames, W)) for _ in range(6)]
    flag = np.zeros((frames, W), dtype=np.int64)
    expose_centroid_cv_serial(np.ascontiguousarray(chain.mean_e, dtype=np.float64), chain.row0, chain.col0,
                              chain.mosaic_cols, chain.chip_cols, chain.gain, chain.offset, chain.read_noise,
                              chain.full_well, np.ascontiguousarray(keys, dtype=np.uint64), chain.max_dn,
                              prep["threshold"], prep["ax"], prep["ay"], prep["udn"], prep["tq"], prep["tm1"],
                              prep["tm2"], prep["dlo"], prep["b0"], prep["sint"], out[0], out[1], flag, out[2], out[3],
                              out[4], out[5])
    return out[0], out[1], flag, out[2], out[3], out[4], out[5]
