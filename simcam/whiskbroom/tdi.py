"""Pixel-level TDI simulation: the MTF a TDICCD delivers under a residual image motion.

The paper predicts image quality from the continuous smear formula
``MTF = sinc(pi N eps / 2)`` at Nyquist. Here the detector is simulated instead
(docs/whiskbroom.md, "pixel-level TDI truth"): an image moving at ``(1 + eps, eta)``
pixels per line period (along the TDI direction, across it) relative to the clocked
charge, charge packets that stay put during each of the ``n_phase`` clock phases of a
line period and then jump ``1/n_phase`` pixel, ``N`` stages summed, the exposure sampled
at ``n_time`` midpoints per clock phase, and the pixel aperture integrated (midpoint
quadrature of the sinusoid over the pixel; exact area for the edge). Nothing here uses
the sinc formula; the tests check that it comes out where its assumptions hold
(continuous clocking: ``N eps = 0.3514 -> 0.95``, ``N eps = 1 -> 2/pi``) and that the
4-phase clocking adds ``sinc(pi/(2 n_phase))`` (Kopeika 1998, sec. 14.3).

Coordinates: ``u`` along the TDI (charge-transfer) direction and ``w`` across it, in
pixels; time in line periods (the line period is ``p / |V_know|``).
"""

from __future__ import annotations

import math

import numpy as np

from simcam.whiskbroom.kernels import tdi_edge_kernel, tdi_phasor_kernel

__all__ = ["aperture_factor", "sinusoid_accumulators", "pixel_mtf", "pixel_mtf_numpy",
           "edge_image", "smear_per_stage"]


def smear_per_stage(v_true, v_know):
    """Smear per TDI stage, pixels, of an image moving at ``v_true`` over charge clocked at
    ``|v_know|`` along ``v_know`` (image-plane vectors, any unit): ``(eps, eta)`` with
    ``eps = |V_t| cos(db)/|V_k| - 1`` along and ``eta = |V_t| sin(db)/|V_k|`` across."""
    vt, vk = np.asarray(v_true, dtype=float), np.asarray(v_know, dtype=float)
    sk = np.hypot(vk[..., 0], vk[..., 1])
    along = (vt[..., 0] * vk[..., 0] + vt[..., 1] * vk[..., 1]) / sk
    cross = (vk[..., 0] * vt[..., 1] - vk[..., 1] * vt[..., 0]) / sk
    return along / sk - 1.0, cross / sk


class TdiError(ValueError):
    """A TDI computation asked for something outside its physics (non-finite rates,
    impossible charge): one ``error:`` line at the command line."""


def aperture_factor(k_along: float, k_cross: float, samples: int) -> complex:
    """Mean of ``exp(i 2 pi k.x)`` over a unit square pixel, by ``samples x samples``
    midpoint quadrature (the pixel aperture integral of a unit-amplitude phasor)."""
    x = (np.arange(samples) + 0.5) / samples - 0.5
    return complex(np.mean(np.exp(2j * np.pi * k_along * x)) * np.mean(np.exp(2j * np.pi * k_cross * x)))


def sinusoid_accumulators(eps: float, eta: float, *, n_stages: int, n_phase: int, n_time: int,
                          columns: int, k_along: float, k_cross: float) -> np.ndarray:
    """(n_stages, columns) complex: the phasor summed over the exposure samples of the
    first ``m + 1`` stages for each column (numba kernel :func:`tdi_phasor_kernel`)."""
    out = np.empty((n_stages, columns), dtype=np.complex128)
    tdi_phasor_kernel(1.0 + eps, eta, n_stages, n_phase, n_time, k_along, k_cross, 0, columns, out)
    return out


def pixel_mtf(eps: float, eta: float, *, n_stages: int, n_phase: int, n_time: int = 64,
              columns: int = 1000, aperture_samples: int = 16, frequency: float = 0.5):
    """Motion MTF of the TDI output at ``frequency`` cycles/pixel (Nyquist by default),
    along and across the TDI direction, for every stage count 1..n_stages.

    The output modulation of each column (the aperture-integrated sinusoid accumulated
    over the exposure) divided by that of a static exposure of the same pixels (no
    motion, no clocking): ``|sum of samples| / (count |aperture|)`` after the aperture;
    averaged over the columns.

    Returns
    -------
    along, cross : (n_stages,) arrays; entry ``N - 1`` is the MTF with N stages.
    """
    count = np.arange(1, n_stages + 1) * n_phase * n_time
    res = []
    for ka, kc in ((frequency, 0.0), (0.0, frequency)):
        acc = sinusoid_accumulators(eps, eta, n_stages=n_stages, n_phase=n_phase, n_time=n_time,
                                    columns=columns, k_along=ka, k_cross=kc)
        ap = abs(aperture_factor(ka, kc, aperture_samples))
        moving = np.abs(acc).mean(axis=1) * ap       # |aperture x accumulated phasor|
        static = count * ap
        res.append(moving / static)
    return res[0], res[1]


def pixel_mtf_numpy(eps: float, eta: float, *, n_stages: int, n_phase: int, n_time: int = 64,
                    columns: int = 1000, aperture_samples: int = 16, frequency: float = 0.5):
    """The same as :func:`pixel_mtf` in plain numpy (vectorised over stages, clock phases
    and columns; the samples within a clock phase summed as the same geometric series).
    Used by the benchmark and as a cross-check of the kernel."""
    m = np.arange(n_stages)[:, None]
    j = np.arange(n_phase)[None, :]
    dt = 1.0 / (n_phase * n_time)
    t_first = m + j / n_phase + 0.5 * dt          # first sample of each clock phase
    u = m + j / n_phase
    c = np.arange(columns)
    count = np.arange(1, n_stages + 1) * n_phase * n_time
    res = []
    for ka, kc in ((frequency, 0.0), (0.0, frequency)):
        th = -2 * np.pi * (ka * (1.0 + eps) + kc * eta) * dt
        g = n_time if th == 0 else (1 - np.exp(1j * n_time * th)) / (1 - np.exp(1j * th))
        ph = 2 * np.pi * (ka * (u - (1.0 + eps) * t_first) - kc * eta * t_first)
        z = np.exp(1j * (ph[:, :, None] + 2 * np.pi * kc * c[None, None, :])) * g
        acc = np.cumsum(z.sum(axis=1), axis=0)
        ap = aperture_factor(ka, kc, aperture_samples)
        res.append(np.abs(acc * ap).mean(axis=1) / (count * abs(ap)))
    return res[0], res[1]


def edge_image(eps: float, eta: float, *, n_stages: int, n_phase: int, n_time: int,
               angle_deg: float, lines: int, columns: int, signal_e_per_stage: float = 0.0,
               read_noise_e: float = 0.0, rng: np.random.Generator | None = None) -> np.ndarray:
    """TDI output image (lines x columns, electrons) of a slanted bright edge.

    The edge is tilted by ``angle_deg`` from the line direction (so its profile is
    sampled along the TDI direction, measuring the along-track MTF) and crosses the
    middle of the image. Without ``rng`` the noise-free mean (in units of the bright
    level) is returned; with it, shot noise (Poisson on the collected electrons,
    ``signal_e_per_stage`` per stage when bright) and Gaussian read noise.
    """
    if not (math.isfinite(eps) and math.isfinite(eta)):
        raise TdiError(f"edge_image: the rate mismatch is not finite (eps {eps}, eta {eta}); check the scenario's "
                       "mirror.rate_deg_s and camera.focal_length_mm")
    if rng is not None and not (math.isfinite(signal_e_per_stage) and 0.0 <= signal_e_per_stage * n_stages < 1e15):
        raise TdiError(f"edge_image: tdi.signal_e_per_stage x stages = {signal_e_per_stage * n_stages:.3g} e-: "
                       "beyond any pixel's charge (< 1e15 e-)")
    a = math.radians(angle_deg)
    offset = math.sin(a) * 0.5 * columns - math.cos(a) * 0.5 * lines
    # scene rows seen by output line L are near -L: the edge n.s <= offset lies at
    # L ~ (sin a c - offset)/cos a, through the middle of the image
    out = np.empty((lines, columns))
    tdi_edge_kernel(1.0 + eps, eta, n_stages, n_phase, n_time, a, offset, lines, columns, out)
    if rng is None:
        return out
    electrons = out * signal_e_per_stage * n_stages
    img = rng.poisson(electrons).astype(float)
    if read_noise_e > 0:
        img += rng.normal(0.0, read_noise_e, img.shape)
    return img
