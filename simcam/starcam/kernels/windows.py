"""Numba kernel: the noise-free charge of star windows, summed from the scene's stamps.

:func:`add_stamps_windows` does what :meth:`simcam.starcam.render.StarCamera._add_stamps`
does once per window (every star of the window's chip, in star order, clipped to the chip
and the window), with the same floating-point operations in the same order
(``sig += electrons_i * stamp_i`` pixel by pixel), so its windows are bit for bit those of
the Python loop (``tests/test_render.py``); it saves the W^2 Python iterations a scene's
windows cost.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def add_stamps_windows(sig, stamps, electrons, star_chip, stamp_row0, stamp_col0, win_chip, win_row0,
                       win_col0, chip_rows, chip_cols):
    """Add every star's image into every window of its chip.

    Parameters
    ----------
    sig : float64 (n, h, w)
        Windows (background already in), modified in place.
    stamps : float64 (W, L, L)
        Flux fractions; ``stamps[i, 0, 0]`` is chip px ``(stamp_col0[i], stamp_row0[i])``.
    electrons : float64 (W,)
    star_chip, stamp_row0, stamp_col0 : int64 (W,)
        Chip of each star and its stamp's chip-pixel origin.
    win_chip, win_row0, win_col0 : int64 (n,)
        Chip of each window and its origin in that chip's pixels.
    chip_rows, chip_cols : int
        Chip size: stamp pixels outside the chip are dropped.
    """
    n, rows, cols = sig.shape
    L = stamps.shape[2]
    for j in range(n):
        k = win_chip[j]
        row0 = win_row0[j]
        col0 = win_col0[j]
        for i in range(stamps.shape[0]):
            if star_chip[i] != k:
                continue
            sr = stamp_row0[i]
            sc = stamp_col0[i]
            r_lo = max(sr, row0, 0)
            r_hi = min(sr + L, row0 + rows, chip_rows)
            c_lo = max(sc, col0, 0)
            c_hi = min(sc + L, col0 + cols, chip_cols)
            if r_lo >= r_hi or c_lo >= c_hi:
                continue
            e = electrons[i]
            for r in range(r_lo, r_hi):
                for c in range(c_lo, c_hi):
                    sig[j, r - row0, c - col0] += e * stamps[i, r - sr, c - sc]
