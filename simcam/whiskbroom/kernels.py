"""Numba kernels of the whiskbroom camera (arrays and scalars only; no orchestration).

* :func:`image_motion_kernel`: per (state, image point) the ray cast at t = 0 and the
  complex-step image velocity, from the chain matrices evaluated at ``t = i h`` by
  :func:`simcam.whiskbroom.geometry.chain_matrices` (same equations as the numpy path).
* :func:`tdi_phasor_kernel`: the pixel-level TDI integration of a sinusoid.
* :func:`tdi_edge_kernel`: the pixel-level TDI integration of a slanted edge.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(parallel=True, cache=True)
def image_motion_kernel(A, rs, E, f, re, x1, x3, h, out):  # pragma: no cover - jitted
    """Image velocity (mm/s) of points ``(x1, x3)`` for each state, by the complex step.

    ``A``, ``rs``, ``E``: chain matrices at ``t = i h`` (complex, shapes (S,3,3), (S,3),
    (S,3,3)); ``f``, ``re``: (S,) focal length mm and Earth radius km; ``out`` (S, N, 2).
    The ray cast uses the real parts (the t = 0 values, exact to ``h**2``).
    """
    S = A.shape[0]
    N = x1.shape[0]
    for s in prange(S):
        a0 = A[s].real
        r0 = rs[s].real
        fs = f[s]
        cc = r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2] - re[s] * re[s]
        for n in range(N):
            d0, d1, d2 = x1[n], -fs, x3[n]
            l0 = a0[0, 0] * d0 + a0[1, 0] * d1 + a0[2, 0] * d2
            l1 = a0[0, 1] * d0 + a0[1, 1] * d1 + a0[2, 1] * d2
            l2 = a0[0, 2] * d0 + a0[1, 2] * d1 + a0[2, 2] * d2
            nrm = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            l0 /= nrm
            l1 /= nrm
            l2 /= nrm
            b = r0[0] * l0 + r0[1] * l1 + r0[2] * l2
            disc = b * b - cc
            if disc < 0.0:
                out[s, n, 0] = np.nan
                out[s, n, 1] = np.nan
                continue
            sd = -b - math.sqrt(disc)
            g0 = r0[0] + sd * l0
            g1 = r0[1] + sd * l1
            g2 = r0[2] + sd * l2
            # complex chain: d = A (E g - r_s)
            e = E[s]
            q0 = e[0, 0] * g0 + e[0, 1] * g1 + e[0, 2] * g2 - rs[s, 0]
            q1 = e[1, 0] * g0 + e[1, 1] * g1 + e[1, 2] * g2 - rs[s, 1]
            q2 = e[2, 0] * g0 + e[2, 1] * g1 + e[2, 2] * g2 - rs[s, 2]
            a = A[s]
            c0 = a[0, 0] * q0 + a[0, 1] * q1 + a[0, 2] * q2
            c1 = a[1, 0] * q0 + a[1, 1] * q1 + a[1, 2] * q2
            c2 = a[2, 0] * q0 + a[2, 1] * q1 + a[2, 2] * q2
            out[s, n, 0] = (-fs * c0 / c1).imag / h
            out[s, n, 1] = (-fs * c2 / c1).imag / h


@njit(cache=True)
def tdi_phasor_kernel(v_along, v_cross, n_stages, n_phase, n_time, k_along, k_cross,
                      col0, n_cols, out):  # pragma: no cover - jitted
    """Pixel-level TDI integration of the phasor ``exp(i 2 pi (k_a u + k_c w))``.

    Time in line periods: during clock phase ``j`` of line ``m`` (``t`` in
    ``[m + j/n_phase, m + (j+1)/n_phase)``) the charge packet of column ``c`` sits at
    ``u = m + j/n_phase`` along the TDI direction and at column ``c``; the image moves
    continuously at ``(v_along, v_cross)`` pixels per line period, so the scene point under
    the packet is ``(u - v_along t, c - v_cross t)``. The exposure is sampled at
    ``n_time`` midpoints per clock phase; within a phase the samples' phasors form a
    geometric sequence (ratio ``r``), summed exactly as ``z (1 - r^n)/(1 - r)``, so
    ``n_time`` can be made large at no cost. ``out[m, c]`` is the sum over the samples of
    the first ``m + 1`` stages (prefix sums: every stage count in one pass). Columns are
    the inner loop (independent, vectorisable).
    """
    two_pi = 2.0 * math.pi
    dt = 1.0 / (n_phase * n_time)
    th = -two_pi * (k_along * v_along + k_cross * v_cross) * dt      # phase step per sample
    rr, ri = math.cos(th), math.sin(th)
    if abs(th) < 1e-300:
        gr, gi = float(n_time), 0.0
    else:
        # (1 - r^n) / (1 - r)
        nr, ni = 1.0 - math.cos(n_time * th), -math.sin(n_time * th)
        dr, di = 1.0 - rr, -ri
        den = dr * dr + di * di
        gr, gi = (nr * dr + ni * di) / den, (ni * dr - nr * di) / den
    # advance over one clock phase: r^n, then the clock step +2 pi k_a / n_phase
    ph_q = n_time * th + two_pi * k_along / n_phase
    qr, qi = math.cos(ph_q), math.sin(ph_q)
    zr = np.empty(n_cols)
    zi = np.empty(n_cols)
    ar = np.zeros(n_cols)
    ai = np.zeros(n_cols)
    t0 = 0.5 * dt
    for ci in range(n_cols):
        ph0 = two_pi * (k_cross * (col0 + ci - v_cross * t0) - k_along * v_along * t0)
        zr[ci] = math.cos(ph0)
        zi[ci] = math.sin(ph0)
    for m in range(n_stages):
        for _ in range(n_phase):
            for ci in range(n_cols):
                xr, xi = zr[ci], zi[ci]
                ar[ci] += xr * gr - xi * gi
                ai[ci] += xr * gi + xi * gr
                zr[ci] = xr * qr - xi * qi
                zi[ci] = xr * qi + xi * qr
        for ci in range(n_cols):
            out[m, ci] = complex(ar[ci], ai[ci])


@njit(cache=True)
def _trapezoid_cdf(s, a, b):  # pragma: no cover - jitted
    """CDF at ``s`` of the sum of U(-a/2, a/2) and U(-b/2, b/2) (``a >= b >= 0``): the
    fraction of a unit pixel on the side ``n.x <= s`` of a line with normal
    ``n = (cos, sin)``, ``a = |cos|``, ``b = |sin|`` (exact pixel-aperture integral)."""
    h = 0.5 * (a + b)
    if s <= -h:
        return 0.0
    if s >= h:
        return 1.0
    d = 0.5 * (a - b)
    if b == 0.0:
        return (s + 0.5 * a) / a
    if s < -d:
        x = s + h
        return x * x / (2.0 * a * b)
    if s <= d:
        return (s + 0.5 * a) / a
    x = h - s
    return 1.0 - x * x / (2.0 * a * b)


@njit(parallel=True, cache=True)
def tdi_edge_kernel(v_along, v_cross, n_stages, n_phase, n_time, angle, offset, n_lines,
                    n_cols, out):  # pragma: no cover - jitted
    """Pixel-level TDI image of a slanted bright half-plane moving with the image.

    The scene is 1 where ``cos(angle) s_u + sin(angle) s_w <= offset`` (scene
    coordinates in pixels); output line ``L`` was integrated by the packet that entered
    stage 0 at ``t = L`` and was read after ``n_stages`` lines; at time ``t`` the packet
    at ``(u, c)`` sees the scene point ``(u - v_along t, c - v_cross t)``. Packet and clocking as in
    :func:`tdi_phasor_kernel`; the pixel aperture is integrated exactly
    (:func:`_trapezoid_cdf`). ``out[L, c]``: collected signal per unit exposure sample,
    averaged over the samples (1 = fully bright).
    """
    ca, sa = math.cos(angle), math.sin(angle)
    a, b = abs(ca), abs(sa)
    if b > a:
        a, b = b, a
    dt = 1.0 / (n_phase * n_time)
    total = n_stages * n_phase * n_time
    for L in prange(n_lines):
        for c in range(n_cols):
            acc = 0.0
            for m in range(n_stages):
                for j in range(n_phase):
                    u = m + j / n_phase
                    for q in range(n_time):
                        t = L + m + (j * n_time + q + 0.5) * dt
                        su = u - v_along * t
                        sw = c - v_cross * t
                        acc += _trapezoid_cdf(offset - (ca * su + sa * sw), a, b)
            out[L, c] = acc / total
