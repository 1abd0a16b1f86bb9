"""numba kernels of the line camera: a star imaged through the TDI stages with its motion.

Arrays and scalars only, ``@njit(cache=True)``; no random numbers (the detector noise is
added afterwards by :mod:`simcam.detector`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["render_tdi_windows"]


@njit(cache=True)
def _phi(z):
    return 0.5 * (1.0 + math.erf(z * 0.7071067811865476))


_TABLE_HALF = 16
_TABLE_RES = 512


@njit(cache=True, inline="always")
def _lookup(table, d):
    u = (d + _TABLE_HALF) * _TABLE_RES
    if u < 0.0 or u >= table.size - 2:
        return 0.0
    i = int(u)
    f = u - i
    return table[i] * (1.0 - f) + table[i + 1] * f


@njit(cache=True)
def render_tdi_windows(out, line0, col0, t_cross, xc, s_c, vx, ax, vs, as_, flux_e_s,
                       t_pass0, line_period, n_stages, sdir, sigma_px, substeps):
    """Expected electrons of TDI output windows of moving stars.

    The charge packet read out at line ``L`` (time ``t_L = t_pass0 + L T``) sat in stage
    ``j`` during ``[t_L - (N - j) T, t_L - (N - j - 1) T)``, at along-track position
    ``sdir (j - (N - 1)/2)`` px from the line centre; during that time the star's image
    (Gaussian PSF of rms ``sigma_px``, integrated over the pixel) moves along
    ``x(t) = xc + vx tau + ax tau^2`` (px from the line centre) and
    ``s(t) = s_c + vs tau + as_ tau^2`` (sample), ``tau = t - t_cross``. Each line period
    is integrated with ``substeps`` midpoint steps along track (the across-track profile is
    taken at the middle of each period).

    Parameters
    ----------
    out : float64 array (n, h, w)
        Filled with electrons per pixel (line, sample) of each window.
    line0, col0 : int64 arrays (n,)
        First output line (counted from the pass start) and first sample of each window.
    t_cross, xc, s_c, vx, ax, vs, as_ : float64 arrays (n,)
        Motion of each star's image about ``t_cross`` (s, px, px/s, px/s^2).
    flux_e_s : float64 array (n,)
        Photo-electron rate of each star, e-/s.
    t_pass0, line_period : float
        Readout time of line 0 and line period, s.
    n_stages : int
        TDI stages N.
    sdir : float
        +1 or -1: direction of charge transfer along ``x``.
    sigma_px : float
        PSF rms width, px.
    substeps : int
        Midpoint steps per line period.
    """
    n, h, w = out.shape
    # pixel-integrated Gaussian g(d) = Phi((d + 1/2)/s) - Phi((d - 1/2)/s) tabulated on
    # |d| <= _TABLE_HALF px at 1/_TABLE_RES px, linear interpolation (error < 2e-6 of the peak)
    nt = 2 * _TABLE_HALF * _TABLE_RES + 1
    table = np.empty(nt + 1)
    inv_s = 1.0 / sigma_px
    for i in range(nt):
        d = -_TABLE_HALF + i / _TABLE_RES
        table[i] = _phi((d + 0.5) * inv_s) - _phi((d - 0.5) * inv_s)
    table[nt] = 0.0
    dt = line_period / substeps
    across = np.empty(w)
    for k in range(n):
        for i in range(h):
            for c in range(w):
                out[k, i, c] = 0.0
        # the window's packets are exposed from t_{line0} - N T to t_{line0 + h - 1}
        t_first = t_pass0 + (line0[k] - n_stages) * line_period
        n_periods = h + n_stages - 1
        weight = flux_e_s[k] * dt
        for m in range(n_periods):
            # across-track profile at the middle of the line period (the drift within one
            # period is far below a pixel)
            tm = t_first + (m + 0.5) * line_period - t_cross[k]
            ss = s_c[k] + vs[k] * tm + as_[k] * tm * tm
            for c in range(w):
                cc = col0[k] + c
                across[c] = _lookup(table, cc - ss)
            for q in range(substeps):
                t = t_first + m * line_period + (q + 0.5) * dt
                tau = t - t_cross[k]
                xs = xc[k] + vx[k] * tau + ax[k] * tau * tau
                for i in range(h):
                    t_l = t_pass0 + (line0[k] + i) * line_period
                    if t < t_l - n_stages * line_period or t >= t_l:
                        continue
                    j = n_stages - 1 - int(math.floor((t_l - t) / line_period))
                    xp = sdir * (j - 0.5 * (n_stages - 1))
                    along = _lookup(table, xp - xs)
                    if along < 1e-12:
                        continue
                    a = weight * along
                    for c in range(w):
                        out[k, i, c] += a * across[c]
