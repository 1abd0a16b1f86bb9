"""simcam.noise_processes against its stated spectra (scipy quadrature), closed forms and the
sampling distributions of the estimators. Every Monte Carlo assertion uses a fixed seed and a
tolerance of 4 standard deviations of the estimator, derived in the test.

References: Brown & Hwang, Introduction to Random Signals and Applied Kalman Filtering (4th ed.,
2012); IEEE Std 952-1997 Annex C; Bartlett 1946 / Box & Jenkins (variance of the sample
autocorrelation of an AR(1) series).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from simcam import noise_processes as npr

K_SD = 4.0  # tolerance in standard deviations of each estimator (fixed seeds)


def _rel_sd_variance_ar1(n: int, a: float) -> float:
    """Relative sd of the sample variance of N samples of a stationary AR(1) with coefficient a
    (a Gauss-Markov series sampled every dt, a = exp(-dt/tau)): for Gaussian x,
    Var(s^2) = (2 sigma^4 / N^2) sum_{j,k} a^{2|j-k|} ~ (2 sigma^4 / N) (1 + a^2) / (1 - a^2),
    which tends to sqrt(2 tau / T) for dt << tau (T = N dt; the brief's sqrt(2 tau / T)); a = 0 is
    white noise, sqrt(2 / N)."""
    return math.sqrt(2.0 / n * (1.0 + a * a) / (1.0 - a * a))


# --- variance = integral of the PSD ------------------------------------------------------------

def test_gauss_markov_variance_is_psd_integral():
    sigma, tau, dt, n = 2.0, 5.0, 0.1, 200_000
    t = np.arange(n) * dt
    x = npr.gauss_markov(np.random.default_rng(1), t, sigma, tau)
    integral, err = quad(lambda f: npr.gauss_markov_psd(f, sigma, tau), 0.0, np.inf, epsabs=0, epsrel=1e-10)
    assert abs(integral - sigma**2) < 1e-8 * sigma**2  # the stated PSD integrates to sigma^2
    rel = _rel_sd_variance_ar1(n, math.exp(-dt / tau))  # about sqrt(2 tau / T) = 0.022
    assert abs(np.mean(x**2) / integral - 1.0) < K_SD * rel


def test_white_noise_variance_is_psd_integral():
    sigma, dt, n = 0.7, 0.01, 100_000
    x = npr.white_noise(np.random.default_rng(2), np.arange(n) * dt, sigma)
    integral, _ = quad(lambda f: npr.white_noise_psd(f, sigma, dt), 0.0, 0.5 / dt)
    assert abs(integral - sigma**2) < 1e-10
    assert abs(np.mean(x**2) / integral - 1.0) < K_SD * math.sqrt(2.0 / n)


def test_tone_variance_is_line_power():
    """The time-averaged square of sum A_i sin(2 pi f_i t + phi_i) over T equals sum A_i^2 / 2 up to
    the finite-record terms, bounded here: each sin^2 term's oscillating part averages to at most
    1 / (4 pi f_i T) of A_i^2, each cross term to at most A_i A_j (1/|f_i - f_j| + 1/(f_i + f_j)) / (2 pi T)."""
    a = np.array([0.07, 0.04, 0.04])
    f = np.array([0.21, 0.56, 1.12])  # ZY-3 gyro lines (Tang et al. 2020): a tonal jitter
    dt, n = 0.01, 200_000
    T = n * dt
    x = npr.tones(np.random.default_rng(3), np.arange(n) * dt, a, f)
    power = np.sum(a**2 / 2)  # the PSD's line powers
    bound = np.sum(a**2 / (4 * np.pi * f * T))
    for i in range(a.size):
        for j in range(i + 1, a.size):
            bound += a[i] * a[j] * (1 / abs(f[i] - f[j]) + 1 / (f[i] + f[j])) / (2 * np.pi * T)
    bound += dt * np.sum(a * 2 * np.pi * f) * np.sum(a)  # the rectangle rule's error, |x x'| dt
    assert abs(np.mean(x**2) - power) < bound
    # explicit phases reproduce the formula
    y = npr.tones(np.random.default_rng(0), np.array([0.0, 0.25]), [2.0], [1.0], phases_rad=[0.0])
    np.testing.assert_allclose(y, [0.0, 2.0], atol=1e-15)


def test_bias_is_a_random_constant():
    """One constant per realisation; over R realisations sum (b - value)^2 / sigma^2 ~ chi-square(R)."""
    from scipy.stats import chi2

    sigma, value, r = 3.0, 1.5, 2000
    rng = np.random.default_rng(4)
    t = np.linspace(0.0, 10.0, 5)
    b = np.array([npr.bias(rng, t, sigma, value) for _ in range(r)])
    assert np.all(b == b[:, :1])
    q = np.sum((b[:, 0] - value) ** 2) / sigma**2
    lo, hi = chi2.ppf([0.0005, 0.9995], r)
    assert lo < q < hi


def test_random_walk_variance_grows_linearly():
    """var x(t) = q (t - t0): at the last time over R realisations the normalised sum of squares is
    chi-square(R); the increments of one path over uneven steps are N(0, q dt_k)."""
    from scipy.stats import chi2

    s, r = 0.3, 2000
    rng = np.random.default_rng(5)
    t = np.cumsum(np.random.default_rng(50).uniform(0.1, 2.0, 100))
    last = np.array([npr.random_walk(rng, t, s)[-1] for _ in range(r)])
    q = np.sum(last**2) / (s**2 * (t[-1] - t[0]))
    lo, hi = chi2.ppf([0.0005, 0.9995], r)
    assert lo < q < hi
    x = npr.random_walk(np.random.default_rng(6), t, s)
    assert x[0] == 0.0
    z = np.diff(x) / (s * np.sqrt(np.diff(t)))
    lo, hi = chi2.ppf([0.0005, 0.9995], z.size)
    assert lo < np.sum(z**2) < hi


def test_sum_of_components_variance_is_sum_of_integrals():
    """Independent terms: the variance of the sum is the sum of the PSD integrals (tone line power,
    Gauss-Markov and white-noise quadratures); tolerance from the sd of each term's variance
    estimate added in quadrature (the tone's record term is below 1e-4 of its power here)."""
    dt, n = 0.05, 200_000
    t = np.arange(n) * dt
    comps = [dict(kind="gauss_markov", amplitude=1.0, tau_s=2.0),
             npr.NoiseComponent("white", 0.5),
             npr.NoiseComponent("tone", 0.8, frequency_hz=0.65)]
    x = npr.sample(np.random.default_rng(7), t, comps)
    gm, _ = quad(lambda f: npr.gauss_markov_psd(f, 1.0, 2.0), 0, np.inf)
    wn, _ = quad(lambda f: npr.white_noise_psd(f, 0.5, dt), 0, 0.5 / dt)
    total = gm + wn + 0.8**2 / 2
    sd = math.hypot(gm * _rel_sd_variance_ar1(n, math.exp(-dt / 2.0)), wn * math.sqrt(2.0 / n))
    assert abs(np.mean(x**2) - total) < K_SD * sd
    assert sum(npr.NoiseComponent(**c).variance() if isinstance(c, dict) else c.variance() for c in comps) == \
        pytest.approx(total, rel=1e-9)


# --- Gauss-Markov correlation ----------------------------------------------------------------

def test_gauss_markov_autocorrelation_is_exponential():
    """Sample autocorrelation at lags 0.5, 1, 2 tau against exp(-lag / tau); the sd of r_k for an
    AR(1) series is sqrt(((1 + a^2)(1 - a^(2k)) / (1 - a^2) - 2 k a^(2k)) / N) (Bartlett's formula)."""
    sigma, tau, dt, n = 1.0, 1.0, 0.05, 200_000
    a = math.exp(-dt / tau)
    x = npr.gauss_markov(np.random.default_rng(8), np.arange(n) * dt, sigma, tau)
    x = x - x.mean()
    c0 = np.dot(x, x) / n
    for k in (10, 20, 40):
        r = np.dot(x[:-k], x[k:]) / n / c0
        sd = math.sqrt(((1 + a * a) * (1 - a ** (2 * k)) / (1 - a * a) - 2 * k * a ** (2 * k)) / n)
        assert abs(r - math.exp(-k * dt / tau)) < K_SD * sd, (k, r)


def test_gauss_markov_uneven_times_exact_discretisation():
    """On uneven times the innovations x_{k+1} - e^{-dt_k/tau} x_k, divided by sigma sqrt(1 - e^{-2 dt_k/tau}),
    are N(0, 1): chi-square bound on their sum of squares; the first sample has variance sigma^2."""
    from scipy.stats import chi2

    sigma, tau = 1.5, 3.0
    t = np.cumsum(np.random.default_rng(90).exponential(1.0, 20_000))
    x = npr.gauss_markov(np.random.default_rng(9), t, sigma, tau)
    dt = np.diff(t)
    z = (x[1:] - np.exp(-dt / tau) * x[:-1]) / (sigma * np.sqrt(1 - np.exp(-2 * dt / tau)))
    lo, hi = chi2.ppf([0.0005, 0.9995], z.size)
    assert lo < np.sum(z**2) < hi
    # the uniform-step path (a filter) and the loop are the same recursion
    tu = np.arange(50) * 0.5
    xu = npr.gauss_markov(np.random.default_rng(10), tu, sigma, tau)
    w = np.random.default_rng(10).standard_normal(50)
    ref = np.empty(50)
    ref[0] = sigma * w[0]
    for k in range(1, 50):
        ref[k] = math.exp(-0.5 / tau) * ref[k - 1] + sigma * math.sqrt(1 - math.exp(-1.0 / tau)) * w[k]
    np.testing.assert_allclose(xu, ref, rtol=1e-12, atol=1e-12)


# --- Allan deviation ---------------------------------------------------------------------------

BLOCKS = 16


def _block_slope_test(x, dt, m, expected_slope):
    """Slope of ln adev on ln tau (unweighted least squares over m), measured in BLOCKS independent
    blocks of the series: their mean is compared with the expected slope by a t-test at the
    two-sided 99.9 % level (t with BLOCKS - 1 degrees of freedom). The blocks are independent for
    white noise and for the increments of a random walk (the Allan variance ignores the offset),
    so the block-to-block scatter is the slope's own sampling error, whatever the correlation
    between the estimates at different taus."""
    from scipy.stats import t as student

    taus = m * dt
    slopes = [np.polyfit(np.log(taus), np.log(npr.allan_deviation(blk, dt, taus)), 1)[0]
              for blk in np.array_split(x, BLOCKS)]
    mean, sd = np.mean(slopes), np.std(slopes, ddof=1)
    tol = student.ppf(0.9995, BLOCKS - 1) * sd / np.sqrt(BLOCKS)
    assert abs(mean - expected_slope) < tol, (mean, expected_slope, tol)
    return mean, tol


def test_allan_white_noise_slope_and_level():
    sigma, dt, n = 1.0, 0.1, 2**18
    x = npr.white_noise(np.random.default_rng(11), np.arange(n) * dt, sigma)
    m = 2.0 ** np.arange(0, 8)  # >= 128 windows per block at the largest m
    _, tol = _block_slope_test(x, dt, m, -0.5)
    assert tol < 0.02
    # level over the whole series: sigma^2(tau) = sigma^2 dt / tau (IEEE 952 N^2 / tau); ln adev has
    # sd about 1 / sqrt(2 K), K = N/m - 1 non-overlapping differences (conservative here)
    m = 2.0 ** np.arange(0, 11)
    taus = m * dt
    ad = npr.allan_deviation(x, dt, taus)
    np.testing.assert_array_less(np.abs(np.log(ad / (sigma * np.sqrt(dt / taus)))), K_SD / np.sqrt(2 * (n / m - 1)))
    tau = taus[3]
    avar, _ = quad(lambda f: 2 * npr.white_noise_psd(f, sigma, dt) * np.sin(np.pi * f * tau) ** 4
                   / (np.pi * f * tau) ** 2, 0, 0.5 / dt, limit=500)
    # band-limiting at Nyquist leaves a small part of the sinc^4 tail out: within 5 % at m = 8
    assert avar == pytest.approx(sigma**2 * dt / tau, rel=0.05)


def test_allan_random_walk_slope_and_level():
    s, dt, n = 0.2, 0.1, 2**18
    x = npr.random_walk(np.random.default_rng(12), np.arange(n) * dt, s)
    # exact for a sampled random walk: sigma^2 = q dt (2 m^2 + 1) / (6 m) (sum of the squared
    # weights of the steps in a difference of two m-sample means), -> q tau / 3 for m >> 1
    def exact(m):
        return s**2 * dt * (2 * m**2 + 1) / (6 * m)

    m = 2.0 ** np.arange(2, 8)  # m >= 4: the exact curve's slope is 0.49, +1/2 in the limit
    expected = np.polyfit(np.log(m), np.log(np.sqrt(exact(m))), 1)[0]
    assert abs(expected - 0.5) < 0.015
    _, tol = _block_slope_test(x, dt, m, expected)
    assert tol < 0.03
    # level, as for white noise (the estimate's dof for a random walk are of the order N/m too)
    m = 2.0 ** np.arange(0, 9)
    ad = npr.allan_deviation(x, dt, m * dt)
    np.testing.assert_array_less(np.abs(np.log(ad**2 / exact(m))) / 2, 2 * K_SD / np.sqrt(2 * (n / m - 1)))
    # the PSD route (IEEE 952 eq. C.2 with the one-sided S) gives q tau / 3
    tau = 2.0
    f = lambda u: 2 * npr.random_walk_psd(u, s) * np.sin(np.pi * u * tau) ** 4 / (np.pi * u * tau) ** 2
    avar = sum(quad(f, k / tau, (k + 1) / tau, limit=200)[0] for k in range(2000))
    assert avar == pytest.approx(s**2 * tau / 3, rel=1e-3)  # the tail beyond f = 2000/tau is ~1e-5


def test_allan_of_bias_is_zero_and_tau_checks():
    x = np.full(100, 3.0)
    np.testing.assert_allclose(npr.allan_deviation(x, 1.0, [1.0, 10.0]), 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="taus"):
        npr.allan_deviation(np.zeros(100), 1.0, [1.5])
    with pytest.raises(ValueError, match="taus"):
        npr.allan_deviation(np.zeros(100), 1.0, [50.0])
    with pytest.raises(ValueError, match="dt"):
        npr.allan_deviation(np.zeros(100), -1.0, [1.0])


# --- seeds and parameters ----------------------------------------------------------------------

def test_reproducible_per_seed_and_components_independent():
    t = np.arange(1000) * 0.01
    comps = [npr.NoiseComponent("gauss_markov", 1.0, tau_s=0.5), npr.NoiseComponent("white", 0.1),
             npr.NoiseComponent("random_walk", 0.05), npr.NoiseComponent("bias", 0.2, value=1.0),
             npr.NoiseComponent("tone", 0.3, frequency_hz=2.0)]
    a = npr.sample(np.random.default_rng(42), t, comps)
    b = npr.sample(np.random.default_rng(42), t, comps)
    c = npr.sample(np.random.default_rng(43), t, comps)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    # switching a term off (amplitude 0) leaves the others' draws unchanged (common random numbers)
    off = list(comps)
    off[1] = npr.NoiseComponent("white", 0.0)
    d = npr.sample(np.random.default_rng(42), t, off)
    e = npr.NoiseComponent("white", 0.1).draw(np.random.default_rng(42).spawn(5)[1], t)
    np.testing.assert_allclose(a - d, e, rtol=0, atol=1e-12)
    assert np.all(npr.sample(np.random.default_rng(0), t, []) == 0.0)


@pytest.mark.parametrize("call, name", [
    (lambda r, t: npr.gauss_markov(r, t, 1.0, -1.0), "tau_s"),
    (lambda r, t: npr.gauss_markov(r, t, 1.0, 0.0), "tau_s"),
    (lambda r, t: npr.gauss_markov(r, t, float("nan"), 1.0), "sigma"),
    (lambda r, t: npr.white_noise(r, t, float("nan")), "sigma"),
    (lambda r, t: npr.white_noise(r, t, -1.0), "sigma"),
    (lambda r, t: npr.random_walk(r, t, float("inf")), "sigma_per_sqrt_s"),
    (lambda r, t: npr.bias(r, t, 1.0, float("nan")), "value"),
    (lambda r, t: npr.tones(r, t, [float("nan")], [1.0]), "amplitudes"),
    (lambda r, t: npr.tones(r, t, [1.0], [-1.0]), "frequencies_hz"),
    (lambda r, t: npr.tones(r, t, [1.0, 2.0], [1.0]), "amplitudes"),
    (lambda r, t: npr.white_noise(r, t[::-1], 1.0), "t_s"),
    (lambda r, t: npr.white_noise(0, t, 1.0), "rng"),
    (lambda r, t: npr.NoiseComponent("gauss_markov", float("nan"), tau_s=1.0), "amplitude"),
    (lambda r, t: npr.NoiseComponent("gauss_markov", 1.0, tau_s=-2.0), "tau_s"),
    (lambda r, t: npr.NoiseComponent("gauss_markov", 1.0), "tau_s"),
    (lambda r, t: npr.NoiseComponent("tone", 1.0), "frequency_hz"),
    (lambda r, t: npr.NoiseComponent("white", 1.0, tau_s=1.0), "tau_s"),
    (lambda r, t: npr.NoiseComponent("pink", 1.0), "kind"),
    (lambda r, t: npr.sample(r, t, [dict(kind="gauss_markov", amplitude=1.0, tau_s=float("nan"))]), "tau_s"),
])
def test_bad_parameters_name_the_parameter(call, name):
    with pytest.raises(ValueError, match=rf"^{name}"):
        call(np.random.default_rng(0), np.arange(10.0))
