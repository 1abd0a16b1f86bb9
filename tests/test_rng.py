"""Tests of the counter-based generator :mod:`simcam.rng` against independent references.

References: the published SplitMix64 output stream (Vigna's ``splitmix64.c`` as quoted
by the ``rand_xoshiro`` crate's ``reference`` test), ``scipy.special.ndtri`` for AS 241,
``scipy.stats`` distributions for KS and chi-square goodness-of-fit tests, and analytic
moments. Every Monte Carlo assertion uses a fixed key; its tolerance is a multiple of
the standard error of the statistic (stated next to it), or a p-value threshold of
1e-4 for KS/chi-square tests.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import special, stats

from simcam import rng, rng_poisson
from simcam.infra.errors import ScenarioError

N = 200_000
KEY = rng.key_from_seed(20240611, 7)
P_MIN = 1e-4  # goodness-of-fit tests fail below this p-value
Z = 5.0  # moment tests allow 5 standard errors


def _slots(n, slot=0):
    """Counters of ``n`` successive pixels, slot ``slot`` (as the detector uses them)."""
    return rng.pixel_counter(pixel_index=np.arange(n), draw=slot << rng.SLOT_BITS)


# ---------------------------------------------------------------------- keys & bits


def test_key_from_seed_matches_seedsequence_spawn():
    # the spawned child along path (3,) of SeedSequence(42) is SeedSequence(42, spawn_key=(3,))
    child = np.random.SeedSequence(42).spawn(4)[3]
    assert rng.key_from_seed(42, 3) == child.generate_state(1, dtype=np.uint64)[0]
    assert rng.key_from_seed(42, 3) != rng.key_from_seed(42, 2)
    assert rng.key_from_seed(42) != rng.key_from_seed(43)
    assert isinstance(rng.key_from_seed(1, 2, 3), np.uint64)


@pytest.mark.parametrize("bad", [-1, 1.5, "3", None])
def test_key_from_seed_rejects_bad_seed(bad):
    with pytest.raises(rng.RngParameterError, match="seed"):
        rng.key_from_seed(bad)
    with pytest.raises(ScenarioError, match=r"path\[1\]"):
        rng.key_from_seed(1, 0, bad)


def test_random_bits64_is_the_published_splitmix64_stream():
    # rand_xoshiro (rust-random/rngs) src/splitmix64.rs, test `reference`, produced with
    # the reference implementation http://xoshiro.di.unimi.it/splitmix64.c
    expected = [1985237415132408290, 2979275885539914483, 13511426838097143398,
                8488337342461049707, 15141737807933549159, 17093170987380407015]
    key = np.uint64(1477776061723855037)
    got = [int(rng.random_bits64(key, np.uint64(i))) for i in range(len(expected))]
    assert got == expected


def test_uniform_uses_top_53_bits_and_open_interval():
    key = np.uint64(1477776061723855037)
    for i in range(4):
        bits = int(rng.random_bits64(key, np.uint64(i)))
        assert rng.uniform01(key, np.uint64(i)) == (bits >> 11) * 2.0**-53
    # the extremes of the mapping, k = 0 and k = 2**53 - 1: keys producing them are
    # found by inverting the (bijective) finaliser
    for k in (0, 2**53 - 1):
        key0 = _key_giving_top_bits(k)
        u = rng.uniform01(key0, np.uint64(0))
        assert 0.0 < u < 1.0
        assert u == (2.0**-54 if k == 0 else 1.0 - 2.0**-53)


def _unmix13(z: int) -> int:
    """Inverse of Stafford's Mix13 finaliser (xor-shifts and odd multipliers invert)."""
    m = (1 << 64) - 1

    def unxorshift(y, s):
        x = y
        for _ in range(64 // s + 1):
            x = y ^ (x >> s)
        return x & m

    z = unxorshift(z, 31)
    z = (z * pow(0x94D049BB133111EB, -1, 1 << 64)) & m
    z = unxorshift(z, 27)
    z = (z * pow(0xBF58476D1CE4E5B9, -1, 1 << 64)) & m
    return unxorshift(z, 30)


def _key_giving_top_bits(k: int) -> np.uint64:
    """A key whose word at counter 0 has top-53 bits ``k`` (low 11 bits zero)."""
    state = _unmix13(k << 11)
    return np.uint64((state - 0x9E3779B97F4A7C15) % (1 << 64))


def test_reproducible_and_counter_addressable():
    c = np.array([0, 5, 2**40 + 3, 2**63 + 11], dtype=np.uint64)
    a = rng.uniform_array(key=KEY, counter=c)
    b = np.array([rng.uniform01(KEY, x) for x in c])
    assert np.array_equal(a, b)  # element-wise evaluation == vectorised evaluation
    assert np.array_equal(a, rng.uniform_array(key=KEY, counter=c))
    assert np.array_equal(rng.normal_array(key=KEY, counter=c),
                          rng.normal_array(key=KEY, counter=c))
    lam = np.array([0.5, 5.0, 50.0, 5e3])
    assert np.array_equal(rng_poisson.poisson_array(lam=lam, key=KEY, counter=c),
                          rng_poisson.poisson_array(lam=lam, key=KEY, counter=c))
    # a different key gives different numbers
    assert not np.array_equal(a, rng.uniform_array(key=KEY + np.uint64(1), counter=c))


def test_poisson_array_broadcasts_lam_against_counter():
    c = _slots(4, 1)
    x = rng_poisson.poisson_array(lam=np.array([[0.5], [50.0]]), key=KEY, counter=c)
    assert x.shape == (2, 4)
    assert np.array_equal(x[1], rng_poisson.poisson_array(lam=50.0, key=KEY, counter=c))
    one = rng_poisson.poisson_array(lam=np.array([4.7, 3.0]), key=KEY, counter=c[:1])
    assert one.shape == (2,)


def test_pixel_counter_layout():
    assert rng.pixel_counter(pixel_index=3, draw=5) == np.uint64(3 * 2**16 + 5)
    assert np.array_equal(rng.pixel_counter(pixel_index=np.array([0, 1]), draw=2),
                          np.array([2, 65538], np.uint64))
    with pytest.raises(rng.RngParameterError, match="draw"):
        rng.pixel_counter(pixel_index=0, draw=2**16)
    with pytest.raises(rng.RngParameterError, match="pixel_index"):
        rng.pixel_counter(pixel_index=np.array([-1]), draw=0)


def test_array_wrappers_validate():
    with pytest.raises(rng.RngParameterError, match="key"):
        rng.uniform_array(key=-1, counter=[0])
    with pytest.raises(rng.RngParameterError, match="key"):
        rng.uniform_array(key=2**64, counter=[0])
    with pytest.raises(rng.RngParameterError, match="counter"):
        rng.normal_array(key=1, counter=[0.5])
    with pytest.raises(rng.RngParameterError, match="counter"):
        rng.normal_array(key=1, counter=[-3])
    with pytest.raises(rng.RngParameterError, match="lam"):
        rng_poisson.poisson_array(lam=[-1.0], key=1, counter=[0])
    with pytest.raises(rng.RngParameterError, match="lam"):
        rng_poisson.poisson_array(lam=[np.nan], key=1, counter=[0])
    with pytest.raises(rng.RngParameterError, match="lam"):
        rng_poisson.poisson_array(lam=[np.inf], key=1, counter=[0])
    with pytest.raises(TypeError):
        rng.uniform_array(1, [0])  # keyword-only


# ---------------------------------------------------------------------- uniforms


def test_uniform_ks_and_moments():
    u = rng.uniform_array(key=KEY, counter=np.arange(N))
    assert u.min() > 0.0 and u.max() < 1.0
    assert stats.kstest(u, stats.uniform.cdf).pvalue > P_MIN
    # mean: SE = sqrt(1/12 / n); variance: SE = sqrt((mu4 - sigma^4) / n) with
    # mu4 = 1/80, sigma^4 = 1/144 for U(0, 1)
    assert abs(u.mean() - 0.5) < Z * np.sqrt(1 / 12 / N)
    assert abs(u.var(ddof=1) - 1 / 12) < Z * np.sqrt((1 / 80 - 1 / 144) / N)


@pytest.mark.parametrize(
    "offset",
    [1, rng.pixel_counter(pixel_index=1, draw=0), 1 << rng.SLOT_BITS],
    ids=["lag1", "pixel", "slot"],
)
def test_uniform_correlations_are_zero(offset):
    # correlation of the value at counter c with c + offset: successive counters (lag 1),
    # neighbouring pixels (same draw), and two slots of one pixel. Under independence the
    # sample correlation has SE 1/sqrt(n).
    base = _slots(N)
    a = rng.uniform_array(key=KEY, counter=base)
    b = rng.uniform_array(key=KEY, counter=base + np.uint64(offset))
    r = np.corrcoef(a, b)[0, 1]
    assert abs(r) < Z / np.sqrt(N)


def test_streams_of_different_keys_are_uncorrelated():
    c = _slots(N)
    a = rng.uniform_array(key=rng.key_from_seed(1, 0), counter=c)
    b = rng.uniform_array(key=rng.key_from_seed(1, 1), counter=c)
    assert abs(np.corrcoef(a, b)[0, 1]) < Z / np.sqrt(N)


def test_uniform_pairs_fill_the_square_evenly():
    # 2-D equidistribution of consecutive pairs: chi-square on a 16 x 16 grid
    u = rng.uniform_array(key=KEY, counter=np.arange(2 * N))
    h, _, _ = np.histogram2d(u[0::2], u[1::2], bins=16, range=[[0, 1], [0, 1]])
    assert stats.chisquare(h.ravel()).pvalue > P_MIN


# ---------------------------------------------------------------------- normals


def test_as241_matches_scipy_ndtri():
    p = np.concatenate([np.linspace(1e-6, 1 - 1e-6, 2001), np.logspace(-300, -1, 300),
                        1 - np.logspace(-15, -1, 100), [0.5, 0.075, 0.925]])
    got = np.array([rng.std_normal_ppf(x) for x in p])
    ref = special.ndtri(p)
    # AS 241 claims about 1 part in 1e16; allow a few ulps of scipy's cephes result
    assert np.allclose(got, ref, rtol=1e-14, atol=1e-15)
    assert rng.std_normal_ppf(0.0) == -np.inf and rng.std_normal_ppf(1.0) == np.inf
    assert np.isnan(rng.std_normal_ppf(1.5))


def test_normal_ks_and_moments():
    z = rng.normal_array(key=KEY, counter=_slots(N))
    assert stats.kstest(z, stats.norm.cdf).pvalue > P_MIN
    # mean SE 1/sqrt(n); variance SE sqrt(2/(n-1)); skewness SE sqrt(6/n); excess
    # kurtosis SE sqrt(24/n)
    assert abs(z.mean()) < Z / np.sqrt(N)
    assert abs(z.var(ddof=1) - 1.0) < Z * np.sqrt(2 / (N - 1))
    assert abs(stats.skew(z)) < Z * np.sqrt(6 / N)
    assert abs(stats.kurtosis(z)) < Z * np.sqrt(24 / N)


def test_normal_tails_and_wedges():
    # The ziggurat's rare paths: the tail beyond r = 3.654 and the wedges. Chi-square of
    # counts in bins of |z| against scipy.stats.norm over 1e6 draws, with the tail bin
    # beyond r (expected 1e6 * 2.58e-4 = 258 counts) kept separate.
    n = 1_000_000
    z = rng.normal_array(key=rng.key_from_seed(5, 5), counter=_slots(n, 3))
    edges = np.array([0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.3, 3.654152885361009, 4.0, np.inf])
    obs, _ = np.histogram(np.abs(z), bins=edges)
    exp = n * 2 * np.diff(stats.norm.cdf(edges))
    assert exp.min() > 5
    chi2 = ((obs - exp) ** 2 / exp).sum()
    assert stats.chi2.sf(chi2, len(obs) - 1) > P_MIN
    # sign symmetry: binomial(n, 1/2), SE sqrt(n)/2
    assert abs((z > 0).sum() - n / 2) < Z * np.sqrt(n) / 2


# ---------------------------------------------------------------------- Poisson


@pytest.mark.parametrize("lam", [0.3, 3.0, 9.9, 10.1, 25.0, 50.0, 63.9, 64.0, 200.0, 1e4])
def test_poisson_chi_square_and_moments(lam):
    n = N
    x = rng_poisson.poisson_array(lam=lam, key=rng.key_from_seed(11, int(lam * 10)),
                                  counter=_slots(n, 1))
    assert x.min() >= 0
    # chi-square against scipy.stats.poisson.pmf on bins with >= 20 expected counts;
    # the two tails are pooled into end bins
    lo = int(stats.poisson.ppf(1e-4, lam))
    hi = int(stats.poisson.isf(1e-4, lam))
    ks = np.arange(lo, hi + 1)
    pmf = stats.poisson.pmf(ks, lam)
    pmf[0] = stats.poisson.cdf(lo, lam)
    pmf[-1] = stats.poisson.sf(hi - 1, lam)
    obs = np.bincount(np.clip(x, lo, hi) - lo, minlength=len(ks)).astype(float)
    exp = n * pmf
    # merge adjacent bins until every bin expects >= 20
    o_m, e_m, acc_o, acc_e = [], [], 0.0, 0.0
    for o, e in zip(obs, exp):
        acc_o += o
        acc_e += e
        if acc_e >= 20:
            o_m.append(acc_o)
            e_m.append(acc_e)
            acc_o = acc_e = 0.0
    o_m[-1] += acc_o
    e_m[-1] += acc_e
    o_m, e_m = np.array(o_m), np.array(e_m)
    chi2 = ((o_m - e_m) ** 2 / e_m).sum()
    assert stats.chi2.sf(chi2, len(o_m) - 1) > P_MIN
    # mean SE sqrt(lam/n); variance SE sqrt((mu4 - sigma^4)/n) with mu4 = lam(1 + 3 lam)
    assert abs(x.mean() - lam) < Z * np.sqrt(lam / n)
    assert abs(x.var(ddof=1) - lam) < Z * np.sqrt((lam + 2 * lam**2) / n)


def test_poisson_table_levels_and_residuals():
    # means spread over the tabulated range exercise every table level and the residual
    # Poisson(lam - lam0): the standardised sum over draws must be N(0, 1)-like.
    n = N
    lam = np.linspace(0.0, 9.999, n)
    x = rng_poisson.poisson_array(lam=lam, key=rng.key_from_seed(3), counter=_slots(n, 1))
    z = (x.sum() - lam.sum()) / np.sqrt(lam.sum())
    assert abs(z) < Z
    # probability integral transform: for discrete X, V = F(X-1) + W * p(X) with an
    # independent W ~ U(0, 1) is exactly U(0, 1) (Brockwell 2007); KS test against U(0,1)
    w = np.random.default_rng(1).random(n)
    v = stats.poisson.cdf(x - 1, lam) + w * stats.poisson.pmf(x, lam)
    assert stats.kstest(v, stats.uniform.cdf).pvalue > P_MIN


def test_poisson_from_words_draws_what_poisson_draws():
    # the batched sampler (table means on their words, PTRS means in rounds of one trial,
    # the rest by poisson itself) gives each mean the variate poisson gives it, on every
    # path: table means, PTRS means just above 10 (half their trials reach the density
    # test, some several trials) and far above, 0, NaN, above POISSON_MAX_LAM, +inf
    g = np.random.default_rng(5)
    lam = np.concatenate([g.uniform(0.0, 10.0, 600), g.uniform(10.0, 10.5, 600), 10.0 ** g.uniform(1, 15, 300),
                          [0.0, -1.0, np.nan, 10.0, 9.999999999999998, rng_poisson.POISSON_MAX_LAM, 1e16, np.inf]])
    g.shuffle(lam)
    counters = _slots(lam.size, 1) + np.uint64(5 << 16)
    words = np.array([rng.random_bits64(KEY, c) for c in counters], dtype=np.uint64)
    out = np.full(lam.size, -1.0)
    rng_poisson.poisson_from_words(lam, words, KEY, counters, out, np.empty(2 * lam.size, dtype=np.int64))
    expected = [float(rng_poisson.poisson(m, KEY, c)) for m, c in zip(lam, counters)]
    assert np.array_equal(out, expected)


def test_poisson_zero_mean_and_tiny_mean():
    c = _slots(1000, 1)
    assert np.all(rng_poisson.poisson_array(lam=0.0, key=KEY, counter=c) == 0)
    x = rng_poisson.poisson_array(lam=1e-9, key=KEY, counter=_slots(N, 1))
    # P(X > 0) = 1 - exp(-1e-9): expecting 2e-4 events in 2e5 draws
    assert x.sum() <= 3


def test_poisson_of_neighbouring_pixels_uncorrelated():
    # counts of adjacent pixels (counters 2**16 apart): sample correlation SE 1/sqrt(n)
    c = _slots(N, 1)
    a = rng_poisson.poisson_array(lam=5.0, key=KEY, counter=c)
    next_pixel = np.uint64(rng.pixel_counter(pixel_index=1, draw=0))
    b = rng_poisson.poisson_array(lam=5.0, key=KEY, counter=c + next_pixel)
    assert abs(np.corrcoef(a, b)[0, 1]) < Z / np.sqrt(N)


def test_poisson_cdf_tables_match_scipy():
    # the tabulated CDFs of Poisson(j/16) used by the inversion, against scipy.stats
    ks = np.arange(rng_poisson._PT_CDF.shape[1] - 1)
    for j in range(rng_poisson._PT_CDF.shape[0]):
        ref = stats.poisson.cdf(ks, j / rng_poisson.POISSON_TABLE_LEVELS_PER_E)
        assert np.allclose(rng_poisson._PT_CDF[j, :-1], ref, rtol=0, atol=1e-14)
    assert np.all(rng_poisson._PT_CDF[:, -1] == 1.0)
    # the mass moved onto the last column is negligible: P(X >= 63 | lam < 10) < 1e-28
    assert stats.poisson.sf(rng_poisson._PT_CDF.shape[1] - 2, 10.0) < 1e-28


def test_log_factorial_matches_scipy_gammaln():
    # table below 1024, Stirling series above (PTRS acceptance test)
    ks = np.concatenate([np.arange(0.0, 3000.0), [1e4, 1e5, 1e6, 1e9, 1e12]])
    got = np.array([rng_poisson.log_factorial(k) for k in ks])
    assert np.allclose(got, special.gammaln(ks + 1.0), rtol=1e-14, atol=1e-14)
