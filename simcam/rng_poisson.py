"""Exact Poisson variates of the counter-based generator (:mod:`simcam.rng`).

A Poisson count is a pure function of its mean, a stream key and a counter, as every
variate of :mod:`simcam.rng`: it reads the words ``random_bits64(key, counter)``,
``counter + 1``, ... of its slot (see the counter layout there).

* :func:`poisson`: exact Poisson: inversion (Devroye 1986, "Non-Uniform Random Variate
  Generation", Springer, ch. III on inversion of discrete laws and ch. X.3 on the
  Poisson law; tabulated CDFs with a guide table, see
  :func:`poisson`) for ``lam < 10`` and Hoermann's
  PTRS transformed rejection with squeeze (W. Hoermann 1993, "The transformed rejection
  method for generating Poisson random variables", Insurance: Mathematics and Economics
  12, 39-45) for ``lam >= 10``.
* :func:`poisson_setup` and :func:`poisson_prepared`: the same draw with the constants of
  one mean computed once; :func:`poisson_from_word` and :func:`poisson_from_words`: the
  same draws given their first words (for kernels that compute a run of words first).
* :func:`poisson_array`: the vectorised wrapper, with its arguments checked.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from simcam.rng import (
    RngParameterError,
    as_counters,
    as_key,
    random_bits64,
    uniform01,
    uniform01_from_word,
)

__all__ = [
    "POISSON_PTRS_MIN_LAM",
    "POISSON_MAX_LAM",
    "POISSON_TABLE_LEVELS_PER_E",
    "log_factorial",
    "poisson",
    "poisson_setup",
    "poisson_prepared",
    "poisson_from_word",
    "poisson_from_words",
    "poisson_array",
]

_ONE_U64 = np.uint64(1)

#: Inversion is used below this mean, PTRS at and above it (Hoermann 1993 uses 10).
POISSON_PTRS_MIN_LAM = 10.0
#: Largest Poisson mean accepted by the public wrappers (counts stay exact in float64).
POISSON_MAX_LAM = 1e15

#: 1/k for the inversion search, k = 0..63 (entry 0 unused).
_INV_K = np.array([0.0] + [1.0 / k for k in range(1, 64)])
_INV_K.flags.writeable = False

#: Grid of tabulated Poisson means for ``lam < 10``: ``lam0 = j / 16``.
POISSON_TABLE_LEVELS_PER_E = 16
_PT_K = 64  # tabulated counts 0..63
_PT_GUIDE = 256  # guide-table cells per level


def _poisson_tables():
    """CDF and guide tables of Poisson(j / 16), j = 0..159, for indexed search.

    ``cdf[j, k] = P(X <= k)`` from the pmf recursion ``p_k = p_{k-1} * lam0 / k``
    (cumulative sums in double precision, clipped at 1); the last column is set to 1,
    which moves a tail mass below 1e-28 onto k = 63. ``guide[j, i] = min{k : cdf[j, k]
    >= i / 256}`` is the Chen & Asau (1974) guide table: the search for ``u`` starts
    there.
    """
    n_lev = int(POISSON_PTRS_MIN_LAM * POISSON_TABLE_LEVELS_PER_E)
    cdf = np.ones((n_lev, _PT_K), dtype=np.float64)
    guide = np.zeros((n_lev, _PT_GUIDE), dtype=np.int8)
    for j in range(n_lev):
        lam0 = j / POISSON_TABLE_LEVELS_PER_E
        p = math.exp(-lam0)
        acc = p
        for k in range(_PT_K - 1):
            cdf[j, k] = min(acc, 1.0)
            p *= lam0 / (k + 1)
            acc += p
        cdf[j, _PT_K - 1] = 1.0
        # first k with cdf >= i / G (cdf is non-decreasing)
        guide[j] = np.searchsorted(cdf[j], np.arange(_PT_GUIDE) / _PT_GUIDE, side="left")
    cdf.flags.writeable = False
    guide.flags.writeable = False
    return cdf, guide


_PT_CDF, _PT_GUIDE_TABLE = _poisson_tables()

#: log(k!) for k = 0..1023 (from math.lgamma); larger k use the Stirling series.
_LOG_FACT_N = 1024
_LOG_FACT = np.array([math.lgamma(k + 1.0) for k in range(_LOG_FACT_N)])
_LOG_FACT.flags.writeable = False
_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)


@njit(cache=True)
def log_factorial(k):
    """``log(k!)`` for a non-negative integer-valued float ``k``.

    Table of ``math.lgamma`` below 1024; above, the Stirling series
    ``log Gamma(x) = (x - 1/2) log x - x + log(2 pi)/2 + 1/(12x) - 1/(360x^3) + 1/(1260x^5)``
    with ``x = k + 1`` (Abramowitz & Stegun 6.1.41), whose truncation error is below
    ``1/(1680 x^7) < 1e-23`` there.
    """
    if k < _LOG_FACT_N:
        return _LOG_FACT[np.int64(k)]
    x = k + 1.0
    ix2 = 1.0 / (x * x)
    return ((x - 0.5) * math.log(x) - x + _HALF_LOG_2PI
            + (1.0 / 12.0 - ix2 * (1.0 / 360.0 - ix2 * (1.0 / 1260.0))) / x)


@njit(cache=True)
def poisson(lam, key, counter):
    """Exact Poisson variate with mean ``lam``.

    ``lam < 10``: ``X = X0 + X1`` with independent ``X0 ~ Poisson(lam0)``,
    ``lam0 = floor(16 lam) / 16``, and ``X1 ~ Poisson(r)``, ``r = lam - lam0 < 1/16``;
    their sum is exactly Poisson(lam) by the additivity of independent Poisson
    variables. ``X0`` is found by inversion with indexed search in a precomputed CDF
    table (Chen & Asau 1974, "On generating random variates from an empirical
    distribution", AIIE Trans. 6, 163-166; Devroye 1986, ch. III) from the uniform ``u``
    made of the top 53 bits of the word at ``counter``. ``X1`` by sequential-search
    inversion (Devroye 1986, ch. X.3) of a second uniform ``u1 = (b + u2) / 2048``,
    where ``b`` is the low 11 bits of the same word (independent of its top 53 bits) and
    ``u2`` the uniform at ``counter + 1``; since ``u1 <= 1 - r`` implies
    ``u1 <= exp(-r)``, i.e. ``X1 = 0``, and ``u1 < (b + 1) / 2048``, the second word is
    drawn only when ``(b + 1) / 2048 > 1 - r`` (probability ``r + 1/2048``). Both
    inversions are exact up to double-precision rounding of the CDFs (below 1e-15).
    ``lam >= 10``: PTRS, transformed rejection with squeeze (Hoermann 1993, algorithm
    PTRS, constants as published), two uniforms per trial at ``counter, counter + 1``,
    then ``counter + 2, counter + 3``, ...

    The constants that depend on ``lam`` only are computed by :func:`poisson_setup`
    and the draw by :func:`poisson_prepared`; a caller drawing many variates of one
    mean (a pixel in many frames) calls the setup once and gets the same values.

    Parameters
    ----------
    lam : float
        Mean (electrons), ``0 <= lam <= POISSON_MAX_LAM`` (callers validate). Outside:
        ``lam <= 0`` or NaN gives 0 and ``lam > POISSON_MAX_LAM`` (or +inf) returns
        ``int(min(lam, 2**62))`` without noise, so that a kernel never loops forever.
    key : uint64
        Stream key.
    counter : uint64
        First counter of the pixel's reserved block of draws.

    Returns
    -------
    int
        Poisson(lam) count.
    """
    mode, j, r, b, a, vr = poisson_setup(lam)
    return poisson_prepared(lam, mode, j, r, b, a, vr, key, counter)


#: :func:`poisson_setup` modes
_PM_ZERO = 0
_PM_HUGE = 1
_PM_TABLE = 2
_PM_PTRS = 3
_LOW11_MASK = np.uint64(0x7FF)
_INV_2048 = 1.0 / 2048.0


@njit(cache=True, inline="always")
def poisson_setup(lam):
    """Constants of :func:`poisson` that depend on the mean only.

    Returns ``(mode, j, r, b, a, vr)``: ``mode`` 0 (``lam <= 0`` or NaN), 1 (above
    ``POISSON_MAX_LAM``), 2 (table inversion: level ``j = floor(16 lam)`` and residual
    mean ``r = lam - j / 16``) or 3 (PTRS constants ``b = 0.931 + 2.53 sqrt(lam)``,
    ``a = -0.059 + 0.02483 b``, ``v_r = 0.9277 - 3.6224 / (b - 2)``, Hoermann 1993).
    """
    if not (lam > 0.0):
        return _PM_ZERO, 0, 0.0, 0.0, 0.0, 0.0
    if lam > POISSON_MAX_LAM:
        return _PM_HUGE, 0, 0.0, 0.0, 0.0, 0.0
    if lam < POISSON_PTRS_MIN_LAM:
        j = np.int64(lam * POISSON_TABLE_LEVELS_PER_E)
        return _PM_TABLE, j, lam - j * (1.0 / POISSON_TABLE_LEVELS_PER_E), 0.0, 0.0, 0.0
    b, a, vr = _ptrs_constants(lam)
    return _PM_PTRS, 0, 0.0, b, a, vr


@njit(cache=True, inline="always")
def _ptrs_constants(lam):
    """PTRS constants of the mean ``lam`` (Hoermann 1993): ``b = 0.931 + 2.53 sqrt(lam)``,
    ``a = -0.059 + 0.02483 b``, ``v_r = 0.9277 - 3.6224 / (b - 2)``."""
    b = 0.931 + 2.53 * math.sqrt(lam)
    return b, -0.059 + 0.02483 * b, 0.9277 - 3.6224 / (b - 2.0)


@njit(cache=True, inline="always")
def _ptrs_trial(lam, b, a, word_u, word_v):
    """One PTRS trial on the words at counters ``c`` and ``c + 1``: the candidate
    ``kf = floor((2 a / us + b) u + lam + 0.43)`` (a float), ``us = 0.5 - |u|`` and ``v``,
    with ``u`` and ``v`` the uniforms of the two words (:func:`simcam.rng.uniform01_from_word`, ``u``
    less 0.5)."""
    u = uniform01_from_word(word_u) - 0.5
    v = uniform01_from_word(word_v)
    us = 0.5 - abs(u)
    return math.floor((2.0 * a / us + b) * u + lam + 0.43), us, v


@njit(cache=True, inline="always")
def _ptrs_squeeze(us, v, vr):
    """PTRS's squeeze: the trial is accepted without the density (``us >= 0.07``, ``v <= v_r``)."""
    return (us >= 0.07) & (v <= vr)


@njit(cache=True, inline="always")
def _ptrs_outside(kf, us, v):
    """PTRS's quick rejection: ``kf < 0``, or ``us < 0.013`` and ``v > us``."""
    return (kf < 0.0) | ((us < 0.013) & (v > us))


@njit(cache=True, inline="always")
def _ptrs_log_constants(lam, b):
    """``log(lam)`` and ``log(1 / alpha) = log(1.1239 + 1.1328 / (b - 3.4))``, the constants of
    PTRS's density test (:func:`_ptrs_density`)."""
    return math.log(lam), math.log(1.1239 + 1.1328 / (b - 3.4))


@njit(cache=True, inline="always")
def _ptrs_density(lam, b, a, kf, us, v, loglam, log_invalpha):
    """PTRS's density test of a trial that neither the squeeze accepted nor the quick test
    rejected: ``log(v) + log(1 / alpha) - log(a / us^2 + b) <= -lam + kf log(lam) - log(kf!)``,
    the left side with one logarithm."""
    return (math.log(v / (a / (us * us) + b)) + log_invalpha
            <= -lam + kf * loglam - log_factorial(kf))


@njit(cache=True, inline="always")
def _poisson_table_word(j, r, word, key, counter):
    """The table path of :func:`poisson` (``0 < lam < 10``: level ``j``, residual mean ``r``)
    given its first word ``word = random_bits64(key, counter)``."""
    u = uniform01_from_word(word)
    k = _PT_GUIDE_TABLE[j, np.int64(u * _PT_GUIDE)]
    while u > _PT_CDF[j, k]:
        k += 1
    if r > 0.0:
        low = np.float64(np.int64(word & _LOW11_MASK))
        if (low + 1.0) * _INV_2048 > 1.0 - r:  # else X1 = 0 (u1 <= 1 - r <= exp(-r))
            u1 = (low + uniform01(key, np.uint64(counter) + _ONE_U64)) * _INV_2048
            if u1 > 1.0 - r:
                p = math.exp(-r)
                cdf = p
                m = 0
                while u1 > cdf:
                    m += 1
                    p *= r * (_INV_K[m] if m < 64 else 1.0 / m)
                    nxt = cdf + p
                    if nxt == cdf:  # remaining tail mass below double rounding
                        break
                    cdf = nxt
                k += m
    return k


@njit(cache=True, inline="always")
def poisson_from_word(lam, word, key, counter):
    """:func:`poisson` ``(lam, key, counter)`` given its first word ``word =
    random_bits64(key, counter)``, as :func:`simcam.rng.uniform01_from_word`: the table path
    (``0 < lam < 10``) on that word; any other mean (PTRS, 0, NaN, huge) by :func:`poisson`
    itself, which draws its own words."""
    if not (lam > 0.0 and lam < POISSON_PTRS_MIN_LAM):
        return poisson(lam, key, counter)
    j = np.int64(lam * POISSON_TABLE_LEVELS_PER_E)
    return _poisson_table_word(j, lam - j * (1.0 / POISSON_TABLE_LEVELS_PER_E), word, key, counter)


@njit(cache=True)
def poisson_prepared(lam, mode, j, r, b, a, vr, key, counter):
    """Poisson(lam) draw at ``counter`` given ``poisson_setup(lam)`` (see :func:`poisson`)."""
    if mode == _PM_TABLE:
        return _poisson_table_word(j, r, random_bits64(key, np.uint64(counter)), key, counter)
    if mode == _PM_ZERO:
        return 0
    if mode == _PM_HUGE:
        return np.int64(min(lam, 4.611686018427388e18))
    c = np.uint64(counter)
    loglam = 0.0
    log_invalpha = 0.0
    setup_done = False
    while True:
        kf, us, v = _ptrs_trial(lam, b, a, random_bits64(key, c), random_bits64(key, c + _ONE_U64))
        c += np.uint64(2)
        if _ptrs_squeeze(us, v, vr):
            return np.int64(kf)
        if _ptrs_outside(kf, us, v):
            continue
        if not setup_done:  # constants of the exact test, only when needed
            loglam, log_invalpha = _ptrs_log_constants(lam, b)
            setup_done = True
        if _ptrs_density(lam, b, a, kf, us, v, loglam, log_invalpha):
            return np.int64(kf)


@njit(cache=True)
def poisson_from_words(lam, words, key, counters, out, scratch):
    """:func:`poisson` ``(lam[i], key, counters[i])`` for every ``i``, as float64 (whole
    numbers, exact) into ``out``, given each first word ``words[i] = random_bits64(key,
    counters[i])``; ``scratch``: int64, at least ``2 n``.

    The same variates, drawn in another order: each mean below 10 (and 0, NaN, huge) by
    :func:`poisson_from_word` on its word, the PTRS means (``10 <= lam <= POISSON_MAX_LAM``,
    :func:`poisson_prepared`) together, in rounds of one trial each (round ``r`` on the
    words at ``counters[i] + 2 r`` and ``+ 2 r + 1``: the trials each one makes alone). A
    round decides every pending trial's squeeze and quick rejection in one pass without
    branches, then the density tests of the rest in a pass of their own (three logarithms
    each; near ``lam = 10``, where ``v_r`` is small, almost half the trials), so that the
    processor overlaps independent draws instead of mispredicting each one's branches; the
    trials neither accepted make the next round.
    """
    n = lam.shape[0]
    pending = scratch[:n]
    dense = scratch[n:2 * n]
    n_pending = 0
    for i in range(n):
        m = lam[i]
        if m >= POISSON_PTRS_MIN_LAM and m <= POISSON_MAX_LAM:
            pending[n_pending] = i
            n_pending += 1
        else:
            out[i] = np.float64(poisson_from_word(m, words[i], key, counters[i]))
    step = np.uint64(0)
    while n_pending > 0:
        n_dense = 0
        n_next = 0
        for q in range(n_pending):
            i = pending[q]
            b, a, vr = _ptrs_constants(lam[i])
            c = np.uint64(counters[i]) + step
            kf, us, v = _ptrs_trial(lam[i], b, a, random_bits64(key, c), random_bits64(key, c + _ONE_U64))
            out[i] = np.float64(np.int64(kf))
            sq = _ptrs_squeeze(us, v, vr)
            outside = _ptrs_outside(kf, us, v)
            dense[n_dense] = i
            n_dense += (not sq) & (not outside)
            pending[n_next] = i  # n_next <= q: the pending list compacted in place
            n_next += (not sq) & outside
        for q in range(n_dense):
            i = dense[q]
            m = lam[i]
            b, a, _ = _ptrs_constants(m)
            c = np.uint64(counters[i]) + step
            kf, us, v = _ptrs_trial(m, b, a, random_bits64(key, c), random_bits64(key, c + _ONE_U64))
            loglam, log_invalpha = _ptrs_log_constants(m, b)
            pending[n_next] = i
            n_next += not _ptrs_density(m, b, a, kf, us, v, loglam, log_invalpha)
        n_pending = n_next
        step += np.uint64(2)


# --------------------------------------------------------------------------------------
# Array loop (numba) and its Python wrapper
# --------------------------------------------------------------------------------------


@njit(cache=True)
def _poisson_fill(lam, key, counters, out):
    for i in range(counters.size):
        out[i] = poisson(lam[i], key, counters[i])


def poisson_array(*, lam, key, counter) -> np.ndarray:
    """Vectorised :func:`poisson`.

    Element ``i`` consumes counters ``counter[i], counter[i] + 1, ...``; space the
    counters by ``2**SLOT_BITS`` or more (use :func:`pixel_counter`) for independent elements.

    Parameters
    ----------
    lam : float or array_like of float
        Means in ``[0, POISSON_MAX_LAM]``; broadcast against ``counter``.
    key : int or numpy.uint64
        Stream key, ``0 <= key < 2**64``.
    counter : array_like of int
        Non-negative counters.

    Returns
    -------
    numpy.ndarray of int64
        Poisson counts, shape of the broadcast of ``lam`` and ``counter``.
    """
    k = as_key(key)
    lam_a = np.asarray(lam, dtype=np.float64)
    if lam_a.size and not (lam_a.min() >= 0.0 and lam_a.max() <= POISSON_MAX_LAM):
        raise RngParameterError(f"lam: must be in [0, {POISSON_MAX_LAM:g}] (no NaN)")
    c = as_counters(counter)
    lam_b, c_b = np.broadcast_arrays(lam_a, c)
    lam_f = np.array(lam_b, dtype=np.float64, order="C").reshape(-1)  # fresh, writeable
    c_f = np.array(c_b, dtype=np.uint64, order="C").reshape(-1)
    out = np.empty(lam_f.shape, dtype=np.int64)
    _poisson_fill(lam_f, k, c_f, out)
    return out.reshape(lam_b.shape)
