"""MTF estimators of the whiskbroom TDI camera (lab side: no simulator objects).

* :func:`published_mtf`: the paper's prediction (its fig. 6, [R], docs/whiskbroom.md):
  ``MTF(N) = sinc(pi N eps / 2)`` at Nyquist with ``eps = Delta V_P / V_P`` (eq. 7),
  nothing across the TDI direction.
* :func:`improved_mtf`: the same smear model with what the paper leaves out: the charge
  moves in ``1/n_phase``-pixel steps while the image moves continuously (a sawtooth of
  width ``(1 + eps)/n_phase``: factor ``sinc(pi (1 + eps)/(2 n_phase))``), the along-TDI
  projection of the residual ``eps = |V_t| cos(Delta beta)/|V_k| - 1``, and the cross-TDI
  drift ``eta = |V_t| sin(Delta beta)/|V_k|`` for the cross-track MTF.
* :func:`slanted_edge_mtf`: the MTF measured from an image of a slanted edge, as a lab
  would (ISO 12233:2017 e-SFR, simplified): edge located per column, line fit,
  4x-oversampled edge-spread function, central-difference line-spread function,
  Hamming window, DFT; the known filters (pixel aperture projected on the edge normal,
  the derivative) divided out so what remains is the motion MTF.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["sinc_smear", "published_mtf", "improved_mtf", "stage_limit_from_curve",
           "slanted_edge_mtf"]


def sinc_smear(x):
    """``|sin(pi x/2)/(pi x/2)|``: Nyquist MTF of a uniform smear of ``x`` pixels
    (Kopeika 1998 eq. 14.3.3)."""
    return np.abs(np.sinc(0.5 * np.asarray(x, dtype=float)))


def published_mtf(dv_mm_s, speed_mm_s, n_stages):
    """Paper's MTF at Nyquist: ``sinc(pi N eps/2)``, ``eps = Delta V_P / V_P`` (along only)."""
    eps = np.asarray(dv_mm_s) / np.asarray(speed_mm_s)
    return sinc_smear(np.multiply.outer(np.asarray(n_stages), eps) if np.ndim(n_stages) else n_stages * eps)


def improved_mtf(eps, eta, n_stages, n_phase: int):
    """Improved MTF at Nyquist, along and across the TDI direction.

    ``along = sinc(pi N eps/2) sinc(pi (1 + eps)/(2 n_phase))``,
    ``cross = sinc(pi N eta/2)``.
    """
    n = np.asarray(n_stages, dtype=float)
    along = sinc_smear(n * eps) * sinc_smear((1.0 + eps) / n_phase)
    cross = sinc_smear(n * eta)
    return along, cross


def stage_limit_from_curve(mtf_by_stage, threshold: float) -> int:
    """Largest N (1-based) such that every stage count up to N keeps MTF >= threshold."""
    bad = np.nonzero(np.asarray(mtf_by_stage) < threshold)[0]
    return int(len(mtf_by_stage) if bad.size == 0 else bad[0])


def slanted_edge_mtf(image, *, oversampling: int = 4, frequency: float = 0.5,
                     half_window_px: int = 8) -> dict:
    """Motion MTF at ``frequency`` (cycles/pixel) along the lines from a slanted-edge image.

    Parameters
    ----------
    image : (lines, columns) array
        An edge running roughly along the columns (dark above, bright below or the
        reverse), tilted by a few degrees.
    oversampling : int
        ESF bins per pixel.
    half_window_px : int
        ESF kept within this distance of the edge (the DFT then samples multiples of
        ``1/(2 half_window_px)`` cycles/pixel, so Nyquist falls on a bin).

    Returns
    -------
    dict with ``mtf`` (the motion MTF at ``frequency``), ``system_mtf`` (before the
    filter corrections), ``angle_deg`` (fitted edge tilt), ``frequencies``, ``curve``.
    """
    img = np.asarray(image, dtype=float)
    n_lines, n_cols = img.shape
    # 1. edge position in each column: centroid of the line-to-line difference within
    #    +-4 lines of its largest value (ISO: centroid of the derivative)
    d = np.diff(img, axis=0)
    sign = np.sign(np.sum(d))
    d = d * sign
    lines = np.arange(n_lines - 1) + 0.5
    peak = np.argmax(d, axis=0)
    mask = np.abs(lines[:, None] - lines[peak][None, :]) <= 4.0
    w = np.clip(d, 0, None) * mask
    pos = np.sum(w * lines[:, None], axis=0) / np.sum(w, axis=0)
    cols = np.arange(n_cols)
    # 2. straight-line fit (two passes: drop columns more than 1 px off the first fit)
    p1, p0 = np.polyfit(cols, pos, 1)
    keep = np.abs(pos - (p0 + p1 * cols)) < 1.0
    p1, p0 = np.polyfit(cols[keep], pos[keep], 1)
    a = math.atan(p1)
    # 3. perpendicular distance of every pixel centre from the edge, binned; only the
    #    first columns spanning a whole number of phase cycles (ISO 12233:2017 6.3), so
    #    every sub-pixel phase is sampled equally often
    cycles = math.floor(n_cols * abs(p1))
    if cycles < 1:
        raise ValueError("slanted edge: the edge spans less than one pixel phase cycle (tilt too small)")
    n_use = min(n_cols, int(round(cycles / abs(p1))))
    dist = ((np.arange(n_lines)[:, None] - p0 - p1 * cols[None, :n_use]) * math.cos(a)).ravel()
    vals = img[:, :n_use].ravel() * sign
    nb = 2 * half_window_px * oversampling
    idx = np.floor((dist + half_window_px) * oversampling).astype(int)
    ok = (idx >= 0) & (idx < nb)
    cnt = np.bincount(idx[ok], minlength=nb)
    if np.any(cnt == 0):
        raise ValueError("slanted edge: empty ESF bins (edge too steep, too flat or too close to the border)")
    esf = np.bincount(idx[ok], weights=vals[ok], minlength=nb) / cnt
    # 4. LSF by central difference, Hamming window centred on the LSF centroid
    lsf = np.gradient(esf)
    x = np.arange(nb)
    c0 = np.sum(x * lsf) / np.sum(lsf)
    win = 0.54 + 0.46 * np.cos(np.pi * (x - c0) / (nb / 2))
    win[np.abs(x - c0) > nb / 2] = 0.08
    lsf = lsf * win
    spec = np.abs(np.fft.rfft(lsf))
    spec = spec / spec[0]
    freqs = np.arange(spec.size) / (nb / oversampling)
    sys_mtf = float(np.interp(frequency, freqs, spec))
    # 5. known filters: the central difference over +-1 bin (the ISO 12233 derivative
    #    correction; ISO does not correct the binning, and neither does this lab) and
    #    the pixel aperture projected on the edge normal (boxes of widths cos a, sin a)
    delta = 1.0 / oversampling
    aperture = abs(np.sinc(frequency * math.cos(a)) * np.sinc(frequency * math.sin(a)))
    deriv = abs(np.sinc(2.0 * frequency * delta))
    return {"mtf": sys_mtf / (aperture * deriv), "system_mtf": sys_mtf,
            "angle_deg": math.degrees(a), "frequencies": freqs, "curve": spec}
