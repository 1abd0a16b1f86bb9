"""Numba kernels of the scan-mirror compensation (the lab's forward model on a sphere, point by
point): the same equations as :func:`simcam.scanmirror.world.ground_point_r0` (eqs. 2-7, 19,
23 [R]) written as scalar loops, so the exact iterated compensation of a whole scan costs
microseconds. Arrays and scalars only; no randomness."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _ground_xy(a, b, tx, ty, Abr, Arr, R, Re, out):
    """x, y of the ground point in r0 (km) into out[0:2]; returns False when the LOS misses."""
    t = math.hypot(tx, ty)
    sinc = math.sin(t) / t if t > 0.0 else 1.0
    mx, my, mz = ty * sinc, -tx * sinc, math.cos(t)
    cb, sb, ca, sa = math.cos(b), math.sin(b), math.cos(a), math.sin(a)
    gx, gy, gz = cb * mx + sb * mz, my, -sb * mx + cb * mz
    wx, wy, wz = gx, ca * gy - sa * gz, sa * gy + ca * gz
    sx, sy, sz = 1.0 - 2.0 * wx * wx, -2.0 * wx * wy, -2.0 * wx * wz
    # s^r = A_br^T s^b
    rx = Abr[0, 0] * sx + Abr[1, 0] * sy + Abr[2, 0] * sz
    ry = Abr[0, 1] * sx + Abr[1, 1] * sy + Abr[2, 1] * sz
    rz = Abr[0, 2] * sx + Abr[1, 2] * sy + Abr[2, 2] * sz
    disc = Re * Re - R * R * (1.0 - rz * rz)
    if disc < 0.0 or rz <= 0.0:
        return False
    Rs = R * rz - math.sqrt(disc)
    vx, vy, vz = Rs * rx, Rs * ry, Rs * rz - R
    out[0] = Arr[0, 0] * vx + Arr[0, 1] * vy + Arr[0, 2] * vz
    out[1] = Arr[1, 0] * vx + Arr[1, 1] * vy + Arr[1, 2] * vz
    return True


@njit(cache=True)
def exact_compensation_sphere(alpha0, beta0, tx, ty, A_br, A_r0r, R, Re, target, iterations, tol, h):
    """Newton iterations per point (central-difference Jacobian, step ``h`` rad) until the
    modelled x, y equal ``target`` (N, 2); returns the commanded (alpha, beta) (N,) each (NaN
    where the LOS misses the Earth)."""
    n = alpha0.shape[0]
    a_out = np.empty(n)
    b_out = np.empty(n)
    f = np.empty(2)
    fp = np.empty(2)
    fm = np.empty(2)
    for i in range(n):
        a, b = alpha0[i], beta0[i]
        ok = True
        for _ in range(iterations):
            ok = _ground_xy(a, b, tx[i], ty[i], A_br[i], A_r0r[i], R[i], Re, f)
            ok &= _ground_xy(a + h, b, tx[i], ty[i], A_br[i], A_r0r[i], R[i], Re, fp)
            ok &= _ground_xy(a - h, b, tx[i], ty[i], A_br[i], A_r0r[i], R[i], Re, fm)
            if not ok:
                break
            ja0, ja1 = (fp[0] - fm[0]) / (2 * h), (fp[1] - fm[1]) / (2 * h)
            ok &= _ground_xy(a, b + h, tx[i], ty[i], A_br[i], A_r0r[i], R[i], Re, fp)
            ok &= _ground_xy(a, b - h, tx[i], ty[i], A_br[i], A_r0r[i], R[i], Re, fm)
            if not ok:
                break
            jb0, jb1 = (fp[0] - fm[0]) / (2 * h), (fp[1] - fm[1]) / (2 * h)
            r0, r1 = f[0] - target[i, 0], f[1] - target[i, 1]
            det = ja0 * jb1 - jb0 * ja1
            da = (jb1 * r0 - jb0 * r1) / det
            db = (-ja1 * r0 + ja0 * r1) / det
            a -= da
            b -= db
            if abs(da) < tol and abs(db) < tol:
                break
        a_out[i] = a if ok else np.nan
        b_out[i] = b if ok else np.nan
    return a_out, b_out
