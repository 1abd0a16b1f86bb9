"""Seeded stochastic processes for the worlds' unmodelled effects (jitter, tracker errors, drifts).

Each process takes a numpy :class:`~numpy.random.Generator` and an array of sample times
``t_s`` (seconds, strictly increasing) and returns one sample per time, in the unit of its
amplitude. Each docstring states the process's one-sided power spectral density S(f)
(unit^2/Hz, 0 <= f), whose integral over f is the variance where the process is stationary.

Sources
-------
* Brown R. G., Hwang P. Y. C., *Introduction to Random Signals and Applied Kalman
  Filtering*, 4th ed., Wiley 2012: ch. 2-3 (power spectral density, first-order
  Gauss-Markov process, Wiener process / random walk, random constant) and sec. 3.9-3.10
  (exact discretisation of a continuous linear system driven by white noise).
* IEEE Std 952-1997 (R2008), *IEEE Standard Specification Format Guide and Test Procedure for
  Single-Axis Interferometric Fiber Optic Gyros*, Annex C (Allan variance: definition from
  cluster averages, eq. C.1-C.7; relation to the PSD, eq. C.2; white noise sigma^2 = N^2 / tau,
  rate random walk sigma^2 = K^2 tau / 3).
* IEEE Std 1139-2008, *Definitions of Physical Quantities for Fundamental Frequency and Time
  Metrology*: the overlapping Allan variance estimator.

The PSD convention: for a stationary process with autocovariance R(u),
S(f) = 4 integral_0^inf R(u) cos(2 pi f u) du (one-sided, so that integral_0^inf S df = R(0)).
White noise of intensity q (E[w(t) w(s)] = q delta(t - s)) has S = 2 q.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["KINDS", "NoiseComponent", "allan_deviation", "bias", "gauss_markov", "gauss_markov_psd",
           "random_walk", "random_walk_psd", "sample", "tones", "white_noise", "white_noise_psd"]

#: the kinds of :class:`NoiseComponent`
KINDS = ("tone", "gauss_markov", "random_walk", "white", "bias")


def _finite(value, name: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {v}")
    if positive and v <= 0.0:
        raise ValueError(f"{name}: must be > 0, got {v}")
    if nonnegative and v < 0.0:
        raise ValueError(f"{name}: must be >= 0, got {v}")
    return v


def _times(t_s) -> np.ndarray:
    t = np.asarray(t_s, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise ValueError(f"t_s: must be a non-empty 1-D array of times, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t_s: must be finite")
    if t.size > 1 and np.any(np.diff(t) <= 0.0):
        raise ValueError("t_s: must be strictly increasing")
    return t


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


# --- the processes ----------------------------------------------------------------------------

def tones(rng: np.random.Generator, t_s, amplitudes, frequencies_hz, phases_rad=None) -> np.ndarray:
    """Sum of tones ``sum_i A_i sin(2 pi f_i t + phi_i)``, phases uniform on [0, 2 pi) unless given.

    One-sided PSD: a line of power A_i^2 / 2 at f_i, S(f) = sum_i (A_i^2 / 2) delta(f - f_i)
    (Brown & Hwang 2012, ch. 2, the random-phase sinusoid: autocovariance
    (A^2 / 2) cos(2 pi f u)); the variance is sum_i A_i^2 / 2.
    """
    rng = _check_rng(rng)
    t = _times(t_s)
    a = np.atleast_1d(np.asarray(amplitudes, dtype=float))
    f = np.atleast_1d(np.asarray(frequencies_hz, dtype=float))
    if a.shape != f.shape or a.ndim != 1:
        raise ValueError(f"amplitudes, frequencies_hz: must be 1-D of one length, got {a.shape} and {f.shape}")
    for i in range(a.size):
        _finite(a[i], f"amplitudes[{i}]", nonnegative=True)
        _finite(f[i], f"frequencies_hz[{i}]", nonnegative=True)
    if phases_rad is None:
        phi = rng.uniform(0.0, 2.0 * np.pi, a.size)
    else:
        phi = np.atleast_1d(np.asarray(phases_rad, dtype=float))
        if phi.shape != a.shape:
            raise ValueError(f"phases_rad: must have the shape of amplitudes {a.shape}, got {phi.shape}")
        for i in range(phi.size):
            _finite(phi[i], f"phases_rad[{i}]")
    return np.sin(2.0 * np.pi * np.outer(t, f) + phi) @ a


def gauss_markov_psd(f_hz, sigma: float, tau_s: float) -> np.ndarray:
    """One-sided PSD of a first-order Gauss-Markov process: S(f) = 4 sigma^2 tau / (1 + (2 pi f tau)^2)."""
    f = np.asarray(f_hz, dtype=float)
    return 4.0 * sigma**2 * tau_s / (1.0 + (2.0 * np.pi * f * tau_s) ** 2)


def gauss_markov(rng: np.random.Generator, t_s, sigma: float, tau_s: float) -> np.ndarray:
    """First-order Gauss-Markov process of standard deviation ``sigma`` and correlation time ``tau_s``.

    Autocovariance sigma^2 exp(-|u| / tau); one-sided PSD
    S(f) = 4 sigma^2 tau / (1 + (2 pi f tau)^2), whose integral over f >= 0 is sigma^2
    (Brown & Hwang 2012, sec. 2.9, Table 2.1 with the two-sided 2 sigma^2 beta / (omega^2 + beta^2),
    beta = 1 / tau). Exact discretisation (ibid. sec. 3.9) at any time steps dt_k:
    x_{k+1} = e^{-dt_k / tau} x_k + sqrt(1 - e^{-2 dt_k / tau}) sigma w_k, w_k ~ N(0, 1), with a
    stationary start x_0 ~ N(0, sigma^2): every sample has variance sigma^2 exactly.
    """
    rng = _check_rng(rng)
    sigma = _finite(sigma, "sigma", nonnegative=True)
    tau_s = _finite(tau_s, "tau_s", positive=True)
    t = _times(t_s)
    w = rng.standard_normal(t.size)
    x = np.empty(t.size)
    x[0] = sigma * w[0]
    if t.size == 1:
        return x
    dt = np.diff(t)
    a = np.exp(-dt / tau_s)
    b = sigma * np.sqrt(-np.expm1(-2.0 * dt / tau_s))
    e = b * w[1:]
    if np.allclose(dt, dt[0], rtol=1e-12, atol=0.0):
        from scipy.signal import lfilter

        # x_k = a x_{k-1} + e_k as a first-order IIR filter, started from x_0
        x[1:] = lfilter([1.0], [1.0, -a[0]], e, zi=[a[0] * x[0]])[0]
    else:
        for k in range(1, t.size):
            x[k] = a[k - 1] * x[k - 1] + e[k - 1]
    return x


def random_walk_psd(f_hz, sigma_per_sqrt_s: float) -> np.ndarray:
    """One-sided PSD of a random walk (Wiener process) x' = w, E[w w] = q delta, q = sigma_per_sqrt_s^2:
    S(f) = 2 q / (2 pi f)^2 = q / (2 pi^2 f^2)."""
    f = np.asarray(f_hz, dtype=float)
    return sigma_per_sqrt_s**2 / (2.0 * np.pi**2 * f**2)


def random_walk(rng: np.random.Generator, t_s, sigma_per_sqrt_s: float) -> np.ndarray:
    """Random walk (Wiener process) starting at 0 at ``t_s[0]``: x(t) - x(t') ~ N(0, q (t - t')),
    q = ``sigma_per_sqrt_s``^2 (unit^2 / s).

    Not stationary: var x(t) = q (t - t_0) (Brown & Hwang 2012, sec. 2.11). Its one-sided PSD
    S(f) = q / (2 pi^2 f^2) (white noise of two-sided density q integrated) has no finite
    integral; its Allan variance is q tau / 3 (IEEE Std 952-1997, Annex C, rate random walk
    K^2 tau / 3 with K^2 = q).
    """
    rng = _check_rng(rng)
    q = _finite(sigma_per_sqrt_s, "sigma_per_sqrt_s", nonnegative=True) ** 2
    t = _times(t_s)
    steps = rng.standard_normal(t.size - 1) * np.sqrt(q * np.diff(t))
    return np.concatenate([[0.0], np.cumsum(steps)])


def white_noise_psd(f_hz, sigma: float, dt_s: float) -> np.ndarray:
    """One-sided PSD of white samples of variance sigma^2 taken every ``dt_s``: S(f) = 2 sigma^2 dt
    for 0 <= f <= 1 / (2 dt) (the Nyquist frequency), 0 above."""
    f = np.asarray(f_hz, dtype=float)
    return np.where(f <= 0.5 / dt_s, 2.0 * sigma**2 * dt_s, 0.0)


def white_noise(rng: np.random.Generator, t_s, sigma: float) -> np.ndarray:
    """Independent N(0, sigma^2) samples, one per time.

    Sampled every dt its one-sided PSD is flat, S(f) = 2 sigma^2 dt up to the Nyquist
    frequency 1 / (2 dt), integral sigma^2 (Brown & Hwang 2012, sec. 2.10, band-limited
    white noise); Allan variance sigma^2 dt / tau (IEEE Std 952-1997, Annex C: N^2 / tau with
    N^2 = sigma^2 dt).
    """
    rng = _check_rng(rng)
    sigma = _finite(sigma, "sigma", nonnegative=True)
    t = _times(t_s)
    return sigma * rng.standard_normal(t.size)


def bias(rng: np.random.Generator, t_s, sigma: float, value: float = 0.0) -> np.ndarray:
    """A bias: one constant ``value + sigma * N(0, 1)`` for all times (Brown & Hwang 2012, sec. 2.11,
    the random constant). One-sided PSD: all its power sigma^2 (about the mean ``value``) at
    f = 0, S(f) = sigma^2 delta(f); its Allan variance is 0.
    """
    rng = _check_rng(rng)
    sigma = _finite(sigma, "sigma", nonnegative=True)
    value = _finite(value, "value")
    t = _times(t_s)
    return np.full(t.size, value + sigma * rng.standard_normal())


# --- a sum of components from a spec -----------------------------------------------------------

@dataclass(frozen=True)
class NoiseComponent:
    """One term of a noise model.

    ``kind``: one of :data:`KINDS`. ``amplitude``, in the unit of the samples (the caller's
    table names that unit, e.g. ``jitter_arcsec``): the tone's amplitude A (not rms), the
    Gauss-Markov, white-noise or bias standard deviation, or for ``random_walk`` the
    diffusion in unit per sqrt(second). ``frequency_hz``: the tone's frequency (tone only).
    ``tau_s``: the Gauss-Markov correlation time (gauss_markov only). ``value``: the bias's
    fixed part (bias only). An amplitude of 0 turns the term off.
    """

    kind: str
    amplitude: float
    frequency_hz: float | None = None
    tau_s: float | None = None
    value: float = 0.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"kind: must be one of {', '.join(KINDS)}, got {self.kind!r}")
        _finite(self.amplitude, "amplitude", nonnegative=True)
        if self.kind == "tone":
            if self.frequency_hz is None:
                raise ValueError("frequency_hz: required for a tone")
            _finite(self.frequency_hz, "frequency_hz", nonnegative=True)
        elif self.frequency_hz is not None:
            raise ValueError(f"frequency_hz: only for a tone, not {self.kind}")
        if self.kind == "gauss_markov":
            if self.tau_s is None:
                raise ValueError("tau_s: required for gauss_markov")
            _finite(self.tau_s, "tau_s", positive=True)
        elif self.tau_s is not None:
            raise ValueError(f"tau_s: only for gauss_markov, not {self.kind}")
        _finite(self.value, "value")
        if self.value != 0.0 and self.kind != "bias":
            raise ValueError(f"value: only for a bias, not {self.kind}")

    def variance(self) -> float:
        """The stationary variance (tone A^2/2, sigma^2 otherwise); ``inf`` for a random walk."""
        if self.kind == "random_walk":
            return math.inf if self.amplitude > 0 else 0.0
        if self.kind == "tone":
            return self.amplitude**2 / 2.0
        return self.amplitude**2

    def draw(self, rng: np.random.Generator, t_s) -> np.ndarray:
        """Samples of this term at ``t_s``."""
        if self.kind == "tone":
            return tones(rng, t_s, [self.amplitude], [self.frequency_hz])
        if self.kind == "gauss_markov":
            return gauss_markov(rng, t_s, self.amplitude, self.tau_s)
        if self.kind == "random_walk":
            return random_walk(rng, t_s, self.amplitude)
        if self.kind == "white":
            return white_noise(rng, t_s, self.amplitude)
        return bias(rng, t_s, self.amplitude, self.value)


def sample(rng: np.random.Generator, t_s, components) -> np.ndarray:
    """The sum of ``components`` (:class:`NoiseComponent` or dicts of its fields) at ``t_s``.

    Each component draws from its own child generator (``rng.spawn``), in order, so a
    component's samples do not depend on the components after it; terms of amplitude 0 draw
    nothing but still take their child (switching a term off does not move the others').
    The components are independent, so the PSD of the sum is the sum of their PSDs.
    """
    rng = _check_rng(rng)
    t = _times(t_s)
    comps = [c if isinstance(c, NoiseComponent) else NoiseComponent(**c) for c in components]
    children = rng.spawn(len(comps)) if comps else []
    out = np.zeros(t.size)
    for c, child in zip(comps, children):
        if c.amplitude == 0.0 and c.value == 0.0:
            continue
        out += c.draw(child, t)
    return out


# --- Allan deviation ---------------------------------------------------------------------------

def allan_deviation(x, dt: float, taus) -> np.ndarray:
    """Overlapping Allan deviation of the series ``x`` sampled every ``dt`` at averaging times ``taus``.

    With cluster averages xbar_k(m) of m = tau / dt consecutive samples starting at every k,
    sigma^2(tau) = 1 / (2 (N - 2m + 1)) sum_k (xbar_{k+m} - xbar_k)^2 (IEEE Std 952-1997, Annex C,
    eq. C.1-C.3, with the fully overlapping estimator of IEEE Std 1139-2008), computed from
    the running sum theta_k = dt sum_{j<k} x_j as
    sigma^2 = sum_k (theta_{k+2m} - 2 theta_{k+m} + theta_k)^2 / (2 tau^2 (N - 2m + 1)).
    Related to the one-sided PSD by sigma^2(tau) = 2 integral_0^inf S(f) sin^4(pi f tau) / (pi f tau)^2 df
    (IEEE Std 952-1997, eq. C.2, written for a one-sided S). Slopes on log-log: white noise
    -1/2, random walk +1/2.

    ``taus`` must be integer multiples of ``dt`` with 1 <= m <= (N - 1) / 2.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1 or x.size < 3:
        raise ValueError(f"x: must be a 1-D series of at least 3 samples, got shape {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError("x: must be finite")
    dt = _finite(dt, "dt", positive=True)
    taus = np.atleast_1d(np.asarray(taus, dtype=float))
    m = np.rint(taus / dt)
    if not np.all(np.isfinite(taus)) or np.any(np.abs(taus / dt - m) > 1e-9 * np.maximum(m, 1.0)):
        raise ValueError("taus: must be integer multiples of dt")
    n = x.size
    if np.any(m < 1) or np.any(2 * m > n - 1):
        raise ValueError(f"taus: must lie between dt and (N - 1) dt / 2 = {(n - 1) * dt / 2:g}")
    theta = np.concatenate([[0.0], np.cumsum(x - x.mean())]) * dt
    out = np.empty(m.size)
    for i, mi in enumerate(m.astype(int)):
        d = theta[2 * mi:] - 2.0 * theta[mi:n + 1 - mi] + theta[:n + 1 - 2 * mi]
        out[i] = np.sqrt(np.sum(d * d) / (2.0 * (mi * dt) ** 2 * d.size))
    return out
