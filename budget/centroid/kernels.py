"""numba kernels for window centroiding (arrays and scalars in, arrays out).

No orchestration here: `budget.centroid.core` validates the inputs, chooses background and
threshold, and turns the outputs into tables.

Conventions (``docs/conventions.md``): the centre of window pixel ``[i, j]`` lies at
``x = x0 + j``, ``y = y0 + i`` in mosaic px, where ``(x0, y0)`` is the mosaic position of
the window's pixel ``[0, 0]``.

Flag bits are the integers below; `budget.centroid.core.CentroidFlag` names the same values.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: a pixel of the window is not finite (NaN/inf); it is left out of every sum
FLAG_NONFINITE = 1
#: a pixel reaches the saturation level (ADC maximum or a given DN)
FLAG_SATURATED = 2
#: no pixel above threshold (or non-positive weight sum): no centroid, x = y = NaN
FLAG_LOST = 4
#: the brightest pixel lies on the window border, or the window was cut by the frame edge
FLAG_EDGE = 8
#: an iterative estimator did not converge within its iteration limit
FLAG_NOT_CONVERGED = 16
#: a reference star had no detection within the matching radius in this frame
FLAG_UNMATCHED = 32


@njit(cache=True)
def border_stats(windows, out_median, out_sigma):
    """Median and MAD-based standard deviation of each window's border pixels.

    Parameters
    ----------
    windows : float64 array (n, h, w)
        Pixel values (any unit).
    out_median, out_sigma : float64 arrays (n,)
        Filled with the border median and ``1.4826 * MAD`` (same unit); NaN when the
        border holds no finite pixel.
    """
    n, h, w = windows.shape
    nb = 2 * w + 2 * max(h - 2, 0)
    buf = np.empty(nb)
    for k in range(n):
        med, sig = border_one(windows[k], buf, np.bool_(True))
        out_median[k] = med
        out_sigma[k] = sig


@njit(cache=True)
def border_one(win, buf, with_sigma):
    """Border median and ``1.4826 * MAD`` of one window ``win`` (h, w).

    ``buf`` is scratch of at least ``2 w + 2 (h - 2)`` elements. With ``with_sigma``
    False the MAD is skipped (sigma returned as NaN): callers that know the noise need
    only the median. Both are NaN when the border holds no finite pixel. The median is
    the exact order statistic (the mean of the two middle values for an even count), by
    counting or selection instead of sorting (:func:`_median`).

    Callers inside numba pass ``np.bool_(...)``, not a bare ``True``/``False``: numba types
    a constant argument as a literal and would compile one specialisation per value.
    """
    h, w = win.shape
    m = np.int64(0)  # not the literal 0: numba would compile _median_select for Literal[int](0) too
    for j in range(w):
        v = win[0, j]
        if math.isfinite(v):
            buf[m] = v
            m += 1
        if h > 1:
            v = win[h - 1, j]
            if math.isfinite(v):
                buf[m] = v
                m += 1
    for i in range(1, h - 1):
        v = win[i, 0]
        if math.isfinite(v):
            buf[m] = v
            m += 1
        if w > 1:
            v = win[i, w - 1]
            if math.isfinite(v):
                buf[m] = v
                m += 1
    if m == 0:
        return np.nan, np.nan
    med = _median(buf, m)
    if not with_sigma:
        return med, np.nan
    for q in range(m):
        buf[q] = abs(buf[q] - med)
    return med, 1.482602218505602 * _median(buf, m)


#: Largest spread (max - min) of whole values that :func:`_median` counts instead of selecting.
MEDIAN_COUNT_SPAN = 64


@njit(cache=True)
def _median(buf, m):
    """Median of the finite values ``buf[:m]`` (may reorder them), as :func:`_median_select`.

    When they are positive whole numbers spanning less than `MEDIAN_COUNT_SPAN` (a window
    border's ADC codes: read noise and sky spread them over some tens of DN), by counting:
    a histogram of the values, then its cumulative count up to the two middle order
    statistics, ``min + d`` each (exact: the values are whole numbers, so the differences
    ``d`` and their sums are). Otherwise by selection. The order statistics are the same
    numbers whichever way they are found (positive: no signed zero to tell apart), so the
    median is the same to the bit; counting avoids selection's unpredictable branches.
    """
    lo = buf[0]
    hi = buf[0]
    whole = True
    for q in range(m):
        v = buf[q]
        lo = min(lo, v)
        hi = max(hi, v)
        whole &= v == math.floor(v)
    if not (whole and lo > 0.0 and hi - lo < MEDIAN_COUNT_SPAN):
        return _median_select(buf, m)
    counts = np.zeros(np.int64(hi - lo) + 1, dtype=np.int64)
    for q in range(m):
        counts[np.int64(buf[q] - lo)] += 1
    # seen: how many values are <= lo + d; order statistic q (0-based) is the first lo + d
    # with seen > q
    k = m // 2
    d = 0
    seen = counts[0]
    while seen <= k - 1:
        d += 1
        seen += counts[d]
    below = d
    while seen <= k:
        d += 1
        seen += counts[d]
    if m % 2 == 1:
        return lo + d
    return 0.5 * ((lo + below) + (lo + d))


@njit(cache=True)
def _select_kth(buf, m, k):
    """``k``-th smallest of ``buf[:m]`` (0-based), partially reordering ``buf[:m]`` so that
    ``buf[:k] <= buf[k] <= buf[k+1:m]``: Hoare's FIND as given by N. Wirth, *Algorithms +
    Data Structures = Programs* (Prentice-Hall, 1976), section 2.3.4; O(m) on average."""
    lo = 0
    hi = m - 1
    while lo < hi:
        x = buf[k]
        i = lo
        j = hi
        while True:
            while buf[i] < x:
                i += 1
            while x < buf[j]:
                j -= 1
            if i <= j:
                t = buf[i]
                buf[i] = buf[j]
                buf[j] = t
                i += 1
                j -= 1
            if i > j:
                break
        if j < k:
            lo = i
        if k < i:
            hi = j
    return buf[k]


@njit(cache=True)
def _median_select(buf, m):
    """Median of ``buf[:m]`` (reorders ``buf[:m]``): the middle order statistic, or for
    even ``m`` the mean of the two middle ones (the largest of the lower half after
    selection)."""
    k = m // 2
    hi = _select_kth(buf, m, k)
    if m % 2 == 1:
        return hi
    lo = buf[0]
    for q in range(1, k):
        if buf[q] > lo:
            lo = buf[q]
    return 0.5 * (lo + hi)


@njit(cache=True)
def cog_one(win, x0, y0, b, t, subtract_threshold, saturation):
    """Thresholded centre of gravity of one window ``win`` (h, w): see :func:`thresholded_cog`.

    Returns ``(x, y, flux, flag)``; ``x = y = flux = NaN`` with `FLAG_LOST` when no pixel
    is above threshold.
    """
    h, w = win.shape
    flag = 0
    sw = 0.0
    sx = 0.0
    sy = 0.0
    flux = 0.0
    npos = 0
    peak = -np.inf
    pi = 0
    pj = 0
    for i in range(h):
        for j in range(w):
            v = win[i, j]
            if not math.isfinite(v):
                flag |= FLAG_NONFINITE
                continue
            if v >= saturation:
                flag |= FLAG_SATURATED
            s = v - b
            if s > t:
                wgt = s - t if subtract_threshold else s
                sw += wgt
                sx += wgt * j
                sy += wgt * i
                flux += s
                npos += 1
                if s > peak:
                    peak = s
                    pi = i
                    pj = j
    if npos == 0 or not sw > 0.0:
        return np.nan, np.nan, np.nan, flag | FLAG_LOST
    if pi == 0 or pj == 0 or pi == h - 1 or pj == w - 1:
        flag |= FLAG_EDGE
    return x0 + sx / sw, y0 + sy / sw, flux, flag


@njit(cache=True, inline="always")
def border_cog_one(win, buf, x0, y0, t):
    """:func:`cog_one` of one window ``win`` (h, w) over its border median (:func:`border_one`,
    ``buf`` its scratch), ``t`` above it, without threshold subtraction or saturation flag;
    `FLAG_LOST` as well when the median or ``t`` is not finite (an infinite ``t``: no pixel
    counts). Returns ``(x, y, flux, flag)``."""
    b, _ = border_one(win, buf, np.bool_(False))
    pre = 0
    if not (math.isfinite(b) and math.isfinite(t)):
        pre = FLAG_LOST
        if not math.isfinite(t):
            t = np.inf
    x, y, flux, flag = cog_one(win, x0, y0, b, t, False, np.inf)
    return x, y, flux, flag | pre


@njit(cache=True)
def thresholded_cog(windows, x0, y0, background, threshold, subtract_threshold,
                    saturation, out_x, out_y, out_flux, out_flag):
    """Thresholded centre of gravity of a batch of windows.

    For each window with background ``b`` and threshold ``t`` (same unit as the pixels),
    the weight of pixel ``[i, j]`` with signal ``s = I - b`` is ``s`` (or ``s - t`` when
    ``subtract_threshold``) if ``s > t`` and 0 otherwise;
    ``x = x0 + sum(w j) / sum(w)``, ``y = y0 + sum(w i) / sum(w)``.
    ``flux`` is the sum of ``s`` over the pixels above threshold.

    Parameters
    ----------
    windows : float64 array (n, h, w)
    x0, y0 : float64 arrays (n,)
        Mosaic position (px) of each window's pixel ``[0, 0]``.
    background, threshold : float64 arrays (n,)
    subtract_threshold : bool
    saturation : float
        Pixels ``>= saturation`` set `FLAG_SATURATED` (they still count).
    out_x, out_y, out_flux : float64 arrays (n,)
    out_flag : int64 array (n,)
        OR-ed with the flags found (callers may pre-set bits such as `FLAG_EDGE`).
    """
    n = windows.shape[0]
    for k in range(n):
        x, y, f, flag = cog_one(windows[k], x0[k], y0[k], background[k], threshold[k],
                                subtract_threshold, saturation)
        out_x[k] = x
        out_y[k] = y
        out_flux[k] = f
        out_flag[k] |= flag


@njit(cache=True)
def iterative_weighted_cog(windows, x0, y0, background, x_start, y_start,
                           weight_sigma, gain, max_iter, tol, saturation,
                           out_x, out_y, out_flux, out_flag, out_niter):
    """Iteratively weighted centre of gravity (Gaussian weight), batch.

    Iterates ``c = sum(g s r) / sum(g s)`` with ``g = exp(-|r - r_k|^2 / (2 sw^2))``
    centred on the current estimate ``r_k`` and updates ``r_{k+1} = r_k + gain (c - r_k)``
    until the step is below ``tol`` (Baker & Moallem 2007; Vyas et al. 2009). The fixed
    point ``c = r_k`` does not depend on ``gain``; ``gain`` only sets the speed.

    Parameters
    ----------
    windows : float64 array (n, h, w)
    x0, y0 : float64 arrays (n,)
        Mosaic position (px) of each window's pixel ``[0, 0]``.
    background : float64 array (n,)
    x_start, y_start : float64 arrays (n,)
        Starting point in window coordinates (px); NaN gives `FLAG_LOST`.
    weight_sigma : float
        Standard deviation of the Gaussian weight (px).
    gain : float
        Step gain (> 0, < 2 / contraction rate for convergence).
    max_iter : int
    tol : float
        Convergence tolerance on the step length (px).
    saturation : float
    out_x, out_y, out_flux : float64 arrays (n,)
        Mosaic position (px) and background-subtracted window sum.
    out_flag : int64 array (n,)
        OR-ed with the flags found.
    out_niter : int64 array (n,)
    """
    n, h, w = windows.shape
    inv2s2 = 0.5 / (weight_sigma * weight_sigma)
    for k in range(n):
        b = background[k]
        flag = 0
        flux = 0.0
        for i in range(h):
            for j in range(w):
                v = windows[k, i, j]
                if not math.isfinite(v):
                    flag |= FLAG_NONFINITE
                    continue
                if v >= saturation:
                    flag |= FLAG_SATURATED
                flux += v - b
        xc = x_start[k]
        yc = y_start[k]
        if not (math.isfinite(xc) and math.isfinite(yc)):
            out_x[k] = np.nan
            out_y[k] = np.nan
            out_flux[k] = np.nan
            out_flag[k] |= flag | FLAG_LOST
            out_niter[k] = 0
            continue
        converged = False
        lost = False
        it = 0
        while it < max_iter:
            it += 1
            sw = 0.0
            sx = 0.0
            sy = 0.0
            for i in range(h):
                dy2 = (i - yc) * (i - yc)
                for j in range(w):
                    v = windows[k, i, j]
                    if not math.isfinite(v):
                        continue
                    g = math.exp(-((j - xc) * (j - xc) + dy2) * inv2s2) * (v - b)
                    sw += g
                    sx += g * j
                    sy += g * i
            if not sw > 0.0:
                lost = True
                break
            nx = xc + gain * (sx / sw - xc)
            ny = yc + gain * (sy / sw - yc)
            step = math.sqrt((nx - xc) ** 2 + (ny - yc) ** 2)
            xc = nx
            yc = ny
            if xc < -0.5 or yc < -0.5 or xc > w - 0.5 or yc > h - 0.5:
                flag |= FLAG_EDGE
                break
            if step < tol:
                converged = True
                break
        out_niter[k] = it
        if lost:
            out_x[k] = np.nan
            out_y[k] = np.nan
            out_flux[k] = np.nan
            flag |= FLAG_LOST
        else:
            out_x[k] = x0[k] + xc
            out_y[k] = y0[k] + yc
            out_flux[k] = flux
            if not converged:
                flag |= FLAG_NOT_CONVERGED
        out_flag[k] |= flag


@njit(cache=True)
def _pixel_profile(n, c, s, e, de_dc, de_ds):
    """Pixel-integrated unit 1-D Gaussian on pixels 0..n-1 and its derivatives.

    ``e[j] = Phi((j + 0.5 - c)/s) - Phi((j - 0.5 - c)/s)``; ``de_dc``, ``de_ds`` its
    derivatives with respect to the centre ``c`` and the width ``s`` (px).
    """
    k = 1.0 / (math.sqrt(2.0) * s)
    norm = 1.0 / (math.sqrt(2.0 * math.pi) * s)
    for j in range(n):
        a = j + 0.5 - c
        b = j - 0.5 - c
        ga = norm * math.exp(-0.5 * (a / s) ** 2)
        gb = norm * math.exp(-0.5 * (b / s) ** 2)
        e[j] = 0.5 * (math.erf(a * k) - math.erf(b * k))
        de_dc[j] = gb - ga
        de_ds[j] = -(a * ga - b * gb) / s


@njit(cache=True)
def _solve_small(a, b, out):
    """Solve ``a out = b`` by Gaussian elimination with partial pivoting (a, b copied).

    Returns False (``out`` undefined) when a pivot is not finite or is below 1e-300
    times the largest diagonal element: the system is singular.
    """
    n = b.shape[0]
    m = a.copy()
    r = b.copy()
    scale = 0.0
    for q in range(n):
        scale = max(scale, abs(m[q, q]))
    if not scale > 0.0:
        return False
    for c in range(n):
        piv = c
        for q in range(c + 1, n):
            if abs(m[q, c]) > abs(m[piv, c]):
                piv = q
        if not (abs(m[piv, c]) > 1e-300 * scale) or not math.isfinite(m[piv, c]):
            return False
        if piv != c:
            for q in range(n):
                tmp = m[c, q]
                m[c, q] = m[piv, q]
                m[piv, q] = tmp
            tmp = r[c]
            r[c] = r[piv]
            r[piv] = tmp
        for q in range(c + 1, n):
            f = m[q, c] / m[c, c]
            for e in range(c, n):
                m[q, e] -= f * m[c, e]
            r[q] -= f * r[c]
    for c in range(n - 1, -1, -1):
        acc = r[c]
        for e in range(c + 1, n):
            acc -= m[c, e] * out[e]
        out[c] = acc / m[c, c]
    return True


@njit(cache=True)
def _gauss_chi2(win, h, w, p, ex, dxe, dse, ey, dye, dsey):
    _pixel_profile(w, p[1], p[3], ex, dxe, dse)
    _pixel_profile(h, p[2], p[3], ey, dye, dsey)
    chi2 = 0.0
    for i in range(h):
        for j in range(w):
            v = win[i, j]
            if not math.isfinite(v):
                continue
            r = v - (p[0] * ex[j] * ey[i] + p[4])
            chi2 += r * r
    return chi2


@njit(cache=True)
def gaussian_fit(windows, x0, y0, x_start, y_start, sigma_start, background_start,
                 max_iter, tol, saturation, out_x, out_y, out_flux, out_sigma,
                 out_background, out_flag, out_niter):
    """Least-squares fit of a pixel-integrated circular 2-D Gaussian plus a constant.

    Model ``m_ab = F E(b; x, s) E(a; y, s) + B`` with ``E`` the pixel-integrated unit
    Gaussian (:func:`_pixel_profile`); Levenberg-Marquardt on the 5 parameters
    ``(F, x, y, s, B)``, unweighted, non-finite pixels left out (Stone 1989, AJ 97,
    1227, Gaussian fitting; Press et al., Numerical Recipes, section 15.5).

    Parameters
    ----------
    windows : float64 array (n, h, w)
    x0, y0 : float64 arrays (n,)
        Mosaic position (px) of each window's pixel ``[0, 0]``.
    x_start, y_start : float64 arrays (n,)
        Start position in window coordinates (px); NaN gives `FLAG_LOST`.
    sigma_start : float
        Start width (px).
    background_start : float64 array (n,)
    max_iter : int
    tol : float
        Convergence when a step moves the centre by less than ``tol`` px.
    saturation : float
    out_x, out_y, out_flux, out_sigma, out_background : float64 arrays (n,)
        Position (mosaic px), total flux ``F``, width ``s`` (px) and background ``B``.
    out_flag : int64 array (n,)
    out_niter : int64 array (n,)
    """
    n, h, w = windows.shape
    ex = np.empty(w)
    dxe = np.empty(w)
    dse = np.empty(w)
    ey = np.empty(h)
    dye = np.empty(h)
    dsey = np.empty(h)
    jac = np.empty(5)
    d = np.empty(5)
    p = np.empty(5)
    trial = np.empty(5)
    for k in range(n):
        win = windows[k]
        flag = 0
        total = 0.0
        b0 = background_start[k]
        for i in range(h):
            for j in range(w):
                v = win[i, j]
                if not math.isfinite(v):
                    flag |= FLAG_NONFINITE
                    continue
                if v >= saturation:
                    flag |= FLAG_SATURATED
                total += v - b0
        if not (math.isfinite(x_start[k]) and math.isfinite(y_start[k])) or not total > 0.0:
            out_x[k] = np.nan
            out_y[k] = np.nan
            out_flux[k] = np.nan
            out_sigma[k] = np.nan
            out_background[k] = np.nan
            out_flag[k] |= flag | FLAG_LOST
            out_niter[k] = 0
            continue
        p[0] = total
        p[1] = x_start[k]
        p[2] = y_start[k]
        p[3] = sigma_start
        p[4] = b0
        lam = 1e-3
        chi2 = _gauss_chi2(win, h, w, p, ex, dxe, dse, ey, dye, dsey)
        converged = False
        it = 0
        while it < max_iter:
            it += 1
            _pixel_profile(w, p[1], p[3], ex, dxe, dse)
            _pixel_profile(h, p[2], p[3], ey, dye, dsey)
            a = np.zeros((5, 5))
            g = np.zeros(5)
            for i in range(h):
                for j in range(w):
                    v = win[i, j]
                    if not math.isfinite(v):
                        continue
                    r = v - (p[0] * ex[j] * ey[i] + p[4])
                    jac[0] = ex[j] * ey[i]
                    jac[1] = p[0] * dxe[j] * ey[i]
                    jac[2] = p[0] * ex[j] * dye[i]
                    jac[3] = p[0] * (dse[j] * ey[i] + ex[j] * dsey[i])
                    jac[4] = 1.0
                    for q in range(5):
                        g[q] += jac[q] * r
                        for m in range(5):
                            a[q, m] += jac[q] * jac[m]
            accepted = False
            singular = False
            step = np.inf
            for _ in range(30):
                aa = a.copy()
                for q in range(5):
                    aa[q, q] += lam * a[q, q]
                if not _solve_small(aa, g, d):
                    singular = True
                    break
                for q in range(5):
                    trial[q] = p[q] + d[q]
                if trial[3] > 0.05 and math.isfinite(trial[1]) and math.isfinite(trial[2]):
                    c2 = _gauss_chi2(win, h, w, trial, ex, dxe, dse, ey, dye, dsey)
                    if c2 <= chi2:
                        step = math.sqrt(d[1] * d[1] + d[2] * d[2])
                        for q in range(5):
                            p[q] = trial[q]
                        chi2 = c2
                        lam = max(lam * 0.1, 1e-12)
                        accepted = True
                        break
                lam *= 10.0
            if singular:
                break
            if not accepted:
                # no downhill step left: at the minimum to machine precision
                converged = True
                break
            if p[1] < -0.5 or p[2] < -0.5 or p[1] > w - 0.5 or p[2] > h - 0.5:
                flag |= FLAG_EDGE
                break
            if step < tol:
                converged = True
                break
        out_niter[k] = it
        out_x[k] = x0[k] + p[1]
        out_y[k] = y0[k] + p[2]
        out_flux[k] = p[0]
        out_sigma[k] = p[3]
        out_background[k] = p[4]
        if not converged:
            flag |= FLAG_NOT_CONVERGED
        out_flag[k] |= flag
