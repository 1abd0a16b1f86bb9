"""The whiskbroom camera's world beyond the paper's model: the truth route.

What the lab's predictions (the published and improved sinc) and its slanted-edge
measurement never see (``[world.effects]`` of :class:`simcam.whiskbroom.scenario.WhiskbroomEffects`):

* **Earth flattening** (``earth_flattening_scale``): the true image motion ``V_true`` of each
  trial is the ray trace to the rotating ellipsoid of flattening ``scale x`` WGS 84
  (:mod:`simcam.whiskbroom.raytrace`, no code shared with ``geometry.py``); the charge is
  still clocked at the camera's knowledge ``|V_know|`` along ``beta_know`` from the paper's
  chain on its sphere. So the truth's ``(eps, eta)`` no longer comes from the same code as
  the estimates'.
* **Attitude jitter** (``attitude_jitter_arcsec``): a roll angle ``r(t) = sum_i w_i A
  sin(2 pi f_i t + phi_i)`` (:func:`simcam.noise_processes.tones`, phases uniform per
  trial; one-sided PSD lines ``(w_i A)^2 / 2`` at ``f_i``), ZY-3 class tones (Tong et
  al., doi:10.1109/TGRS.2014.2379435; Tang et al., Sensors 20:736, 2020).
* **Reaction-wheel jitter** (``wheel_jitter_arcsec``): one roll tone at ``world.wheel_tone_hz``
  (a structural mode excited by the wheel harmonics, model form of Masterson et al.,
  doi:10.1006/jsvi.2001.3868), phase uniform per trial; its period (10 ms at 100 Hz) is
  comparable to the integration, so it blurs rather than shifts the rate.
* **Mirror-rate ripple** (``mirror_rate_ripple_fraction``): ``omega(t) = omega_x [1 + a
  sin(2 pi omega_x t / theta_p + phi)]``, i.e. a mirror-angle term ``a theta_p / (2 pi)``
  sinusoidal at ``omega_x / theta_p`` (``theta_p`` = ``world.ripple_period_deg``).

  Both move the image within the integration: a perturbation ``delta(t)`` of the roll
  angle (or of the mirror angle) displaces the image by ``g delta(t)`` with ``g = dV/d rate``
  (mm per rad: ``V`` is affine in each rate at a fixed instant, so the ray trace's central
  difference in the rate gives ``g`` to rounding). The displacement over the ``N``-stage
  integration is sampled at every exposure sample of the pixel-level TDI simulation
  (:func:`tdi_mtf_path`), so the motion is non-uniform, not a constant-rate smear.
* **Charge diffusion / crosstalk** (``pixel_crosstalk_fraction``): the pixel response is
  the box convolved with the 3x3 kernel ``[X, 1 - 2X, X]`` per axis (Nyquist MTF ``1 -
  4X`` per axis; Seib, IEEE TED 21:210, 1974 for the physics). It is static and common to
  every stage count, so the motion MTF (output over a static exposure of the same pixels)
  is unchanged (:func:`tdi_modulation` shows it); it changes what the slanted-edge
  measurement sees (:func:`diffuse`), whose lab divides out a box pixel only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from simcam.noise_processes import tones
from simcam.whiskbroom.kernels import _trapezoid_cdf
from simcam.units import RAD_PER_ARCSEC
from simcam.whiskbroom import raytrace as rt

__all__ = ["EFFECTS_SPAWN_KEY", "effects_rng", "world_motion", "rate_sensitivity", "jitter_angle",
           "ripple_angle", "sample_times", "tdi_mtf_path", "tdi_modulation", "crosstalk_mtf", "diffuse",
           "seib_mtf", "edge_image_path", "TRUTH_EFFECTS"]

#: spawn key of the effects' generators: ``SeedSequence(seed, spawn_key=(k, EFFECTS_SPAWN_KEY, j))``
#: for effect ``j`` of trial ``k``, apart from the trial's own stream (which therefore does not
#: move when an effect is switched on)
EFFECTS_SPAWN_KEY = 2**30 + 22
#: the effects that change the truth (the motion MTF); crosstalk changes only the edge image
TRUTH_EFFECTS = frozenset({"earth_flattening_scale", "attitude_jitter_arcsec", "wheel_jitter_arcsec",
                           "mirror_rate_ripple_fraction"})

def effects_rng(seed: int, k: int, j: int) -> np.random.Generator:
    """The generator of effect ``j`` in trial ``k`` (common random numbers across cases)."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(int(k), EFFECTS_SPAWN_KEY, int(j))))


def _world(row, names, flattening):
    return rt.World.from_values(dict(zip(names, row)), flattening=flattening)


def world_motion(true_row, names, x1, x3, flattening: float) -> np.ndarray:
    """The world's image velocity (mm/s, (N, 2)) of the true state (one parameter row of the
    synthesis, ``names`` its columns) at image points (mm), ray-traced to the ellipsoid of
    the given flattening."""
    return rt.image_motion(_world(true_row, names, flattening), x1, x3)[0]


def rate_sensitivity(true_row, names, x1, x3, flattening: float, which: str, h_rad_s: float = 1e-4) -> np.ndarray:
    """``dV/d rate`` (mm per rad, (N, 2)) for ``which`` = ``"roll_rate_rad_s"`` or
    ``"mirror_rate_rad_s"``: central difference of the ray-traced ``V`` (affine in the rate
    at a fixed instant, so exact to rounding)."""
    w = _world(true_row, names, flattening)
    base = getattr(w, which)
    vp = rt.image_motion(w.with_(**{which: base + h_rad_s}), x1, x3)[0]
    vm = rt.image_motion(w.with_(**{which: base - h_rad_s}), x1, x3)[0]
    return (vp - vm) / (2.0 * h_rad_s)


def jitter_angle(rng, t_s, amplitude_arcsec: float, tones_hz, weights) -> np.ndarray:
    """Roll-jitter angle (rad) at ``t_s``: ZY-3 class tones, phases uniform (from ``rng``)."""
    amps = [amplitude_arcsec * RAD_PER_ARCSEC * w for w in weights]
    return tones(rng, t_s, amps, list(tones_hz))


def ripple_angle(rng, t_s, fraction: float, mirror_rate_rad_s: float, period_deg: float) -> np.ndarray:
    """Mirror-angle ripple (rad) at ``t_s``: the integral of ``omega_x a sin(2 pi omega_x t /
    theta_p + phi)``, a tone of amplitude ``a theta_p / (2 pi)`` at ``|omega_x| / theta_p``
    (phase uniform from ``rng``; the integral's constant does not move the image)."""
    theta = math.radians(period_deg)
    return tones(rng, t_s, [fraction * theta / (2.0 * math.pi)], [abs(mirror_rate_rad_s) / theta])


def sample_times(n_stages: int, n_phase: int, n_time: int) -> np.ndarray:
    """Exposure sample times of the pixel-level TDI simulation, in line periods: the
    midpoints ``(q + 1/2)/(n_phase n_time)`` (as :func:`simcam.whiskbroom.kernels.tdi_phasor_kernel`)."""
    return (np.arange(n_stages * n_phase * n_time) + 0.5) / (n_phase * n_time)


def tdi_mtf_path(disp_along, disp_cross, *, n_stages: int, n_phase: int, n_time: int,
                 frequency: float = 0.5):
    """Motion MTF at ``frequency`` cycles/pixel, along and across the TDI direction, for every
    stage count 1..n_stages, of an image whose displacement (pixels, relative to the scene at
    ``t = 0``) at the exposure samples (:func:`sample_times`) is ``(disp_along, disp_cross)``.

    The same detector as :func:`simcam.whiskbroom.tdi.pixel_mtf` (charge packets at ``u = m
    + j/n_phase`` during clock phase ``j`` of line ``m``; scene point under the packet ``u -
    x(t)``; N stages summed), with an arbitrary (non-uniform) image path instead of a
    constant velocity; the samples are summed directly, one column (every column has the
    same modulation: the motion is rigid). For ``x(t) = (1 + eps) t`` it equals ``pixel_mtf``
    to rounding (tested).
    """
    da = np.asarray(disp_along, dtype=float)
    dc = np.asarray(disp_cross, dtype=float)
    per_line = n_phase * n_time
    total = n_stages * per_line
    if da.shape != (total,) or dc.shape != (total,):
        raise ValueError(f"displacements: expected shape ({total},), got {da.shape} and {dc.shape}")
    q = np.arange(total)
    u = (q // n_time) / n_phase                           # m + j / n_phase
    count = np.arange(1, n_stages + 1) * per_line
    out = []
    for ka, kc in ((frequency, 0.0), (0.0, frequency)):
        z = np.exp(2j * np.pi * (ka * (u - da) - kc * dc))
        acc = np.cumsum(z.reshape(n_stages, per_line).sum(axis=1))
        out.append(np.abs(acc) / count)
    return out[0], out[1]


def crosstalk_mtf(frequency, crosstalk: float):
    """MTF of the crosstalk kernel ``[X, 1 - 2X, X]`` at ``frequency`` cycles/pixel:
    ``1 - 2X + 2X cos(2 pi f)`` (``1 - 4X`` at Nyquist)."""
    return 1.0 - 2.0 * crosstalk + 2.0 * crosstalk * np.cos(2.0 * np.pi * np.asarray(frequency, dtype=float))


def tdi_modulation(disp_along, disp_cross, *, n_stages: int, n_phase: int, n_time: int,
                   crosstalk: float = 0.0, frequency: float = 0.5):
    """Absolute output modulation (per unit input modulation) along and across, per stage
    count: the motion MTF of :func:`tdi_mtf_path` times the pixel response (box ``sinc(f)``
    times :func:`crosstalk_mtf`). Its value with no motion and ``N = 0``-free normalisation
    is the static pixel MTF; MTF(N) / static is the motion MTF, whatever the pixel response."""
    a, c = tdi_mtf_path(disp_along, disp_cross, n_stages=n_stages, n_phase=n_phase, n_time=n_time,
                        frequency=frequency)
    pixel = abs(float(np.sinc(frequency))) * abs(float(crosstalk_mtf(frequency, crosstalk)))
    return a * pixel, c * pixel


def diffuse(image, crosstalk: float) -> np.ndarray:
    """An image (lines x columns) through the separable crosstalk kernel ``[X, 1 - 2X, X]``
    on both axes (charge conserved inside; the borders repeat the edge pixel)."""
    from scipy.ndimage import convolve1d

    if crosstalk == 0.0:
        return np.asarray(image, dtype=float)
    k = np.array([crosstalk, 1.0 - 2.0 * crosstalk, crosstalk])
    out = convolve1d(np.asarray(image, dtype=float), k, axis=0, mode="nearest")
    return convolve1d(out, k, axis=1, mode="nearest")


def seib_mtf(frequency_cyc_mm, *, absorption_per_um: float, depletion_um: float, diffusion_length_um: float):
    """Seib's diffusion MTF of a front-illuminated CCD (Seib, IEEE TED 21:210, 1974):
    ``[1 - exp(-a L_D)/(1 + a L(f))] / [1 - exp(-a L_D)/(1 + a L0)]`` with ``L(f) = L0 /
    sqrt(1 + (2 pi f L0)^2)``; ``a`` the absorption coefficient, ``L_D`` the depletion depth,
    ``L0`` the field-free diffusion length. For the docs' range of the crosstalk default."""
    f = np.asarray(frequency_cyc_mm, dtype=float) * 1e-3        # cycles per um
    a, ld, l0 = absorption_per_um, depletion_um, diffusion_length_um
    lf = l0 / np.sqrt(1.0 + (2.0 * np.pi * f * l0) ** 2)
    e = math.exp(-a * ld)
    return (1.0 - e / (1.0 + a * lf)) / (1.0 - e / (1.0 + a * l0))


@njit(parallel=True, cache=True)
def _edge_path_kernel(xa, xc, n_stages, n_phase, n_time, angle, offset, n_lines, n_cols, out):  # pragma: no cover - jitted
    """:func:`simcam.whiskbroom.kernels.tdi_edge_kernel` with an arbitrary image path: ``xa``,
    ``xc`` the displacement (pixels) at ``t_k = (k + 1/2) dt``, ``k`` over ``(n_lines +
    n_stages) n_phase n_time`` samples; output line ``L`` reads samples from ``L n_phase n_time``."""
    ca, sa = math.cos(angle), math.sin(angle)
    a, b = abs(ca), abs(sa)
    if b > a:
        a, b = b, a
    per_line = n_phase * n_time
    total = n_stages * per_line
    for L in prange(n_lines):
        for c in range(n_cols):
            acc = 0.0
            for m in range(n_stages):
                for j in range(n_phase):
                    u = m + j / n_phase
                    for q in range(n_time):
                        kk = (L + m) * per_line + j * n_time + q
                        su = u - xa[kk]
                        sw = c - xc[kk]
                        acc += _trapezoid_cdf(offset - (ca * su + sa * sw), a, b)
            out[L, c] = acc / total


def edge_image_path(disp_along, disp_cross, *, n_stages: int, n_phase: int, n_time: int, angle_deg: float,
                    lines: int, columns: int) -> np.ndarray:
    """Noise-free TDI image of the slanted edge of :func:`simcam.whiskbroom.tdi.edge_image`
    (same geometry, exact pixel area) for an image path sampled at
    ``sample_times(lines + n_stages, n_phase, n_time)``; equal to ``edge_image`` for a
    uniform path (tested)."""
    a = math.radians(angle_deg)
    offset = math.sin(a) * 0.5 * columns - math.cos(a) * 0.5 * lines
    n = (lines + n_stages) * n_phase * n_time
    xa = np.ascontiguousarray(disp_along, dtype=float)
    xc = np.ascontiguousarray(disp_cross, dtype=float)
    if xa.shape != (n,) or xc.shape != (n,):
        raise ValueError(f"displacements: expected shape ({n},), got {xa.shape} and {xc.shape}")
    out = np.empty((lines, columns))
    _edge_path_kernel(xa, xc, n_stages, n_phase, n_time, a, offset, lines, columns, out)
    return out
