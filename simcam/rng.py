"""Counter-based random numbers for pixel noise: a key and a counter give a number.

This module holds the generator (stream keys, counters, the 64-bit word) and its uniform
and normal variates; :mod:`simcam.rng_poisson` its Poisson variates.

Every random number in the detector chain is a pure function of a 64-bit *key* (one
per stream: a detector, a frame) and a 64-bit *counter* (which pixel, which draw).
There is no generator state, so a full frame, a window cut around a star and any split
of the work over threads or processes give bit-identical values where they overlap.

Construction
------------
The 64-bit word for ``(key, counter)`` is output number ``counter`` of SplitMix64
seeded with ``key``::

    z = key + (counter + 1) * 0x9E3779B97F4A7C15          (mod 2**64)
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9
    z = (z ^ (z >> 27)) * 0x94D049BB133111EB
    bits = z ^ (z >> 31)

i.e. the golden-gamma Weyl sequence of Steele, Lea & Flood (2014), "Fast splittable
pseudorandom number generators", OOPSLA '14, pp. 453-472, doi:10.1145/2660193.2660195,
passed through D. Stafford's "Mix13" 64-bit finaliser (the variant used by
``java.util.SplittableRandom`` and by Vigna's reference ``splitmix64.c``). The paper
reports that this generator passes TestU01 BigCrush (L'Ecuyer & Simard 2007); because
the output is a bijective hash of ``key + counter * gamma`` it can be evaluated at any
counter in O(1), which makes it a counter-based generator in the sense of Salmon et al.
(2011), "Parallel random numbers: as easy as 1, 2, 3", SC '11, doi:10.1145/2063384.2063405.
It costs two 64-bit multiplies per word (about 1 ns), several times cheaper than
Philox4x32-10, which is why it was chosen for the per-pixel hot loop.

Statistical standing and its limits: distinct streams are distinct keys drawn from
:class:`numpy.random.SeedSequence` (uniform 64-bit values). Two streams produce the
same numbers (shifted copies) only if their keys differ by ``delta * gamma`` (mod
``2**64``) for a difference ``delta`` of two counters in use. A frame's counters are
``pixel * 2**16 + draw`` with fewer than ``2**23`` pixels and a few dozen draw numbers
in use, so there are fewer than ``2**32`` such differences and the chance for a pair
of random keys is below ``2**32 / 2**64 = 2**-32``. The generator is not
cryptographic.

Counter layout
--------------
``counter = pixel_index * 2**DRAW_BITS + slot * 2**SLOT_BITS + j`` with
``DRAW_BITS = 16`` and ``SLOT_BITS = 12``: each mosaic pixel owns 65536 consecutive
counters, split into 16 *slots* of 4096, one slot per variate (PRNU, DSNU, read noise,
shot noise, ...; assigned in :mod:`simcam.kernels.detector`). A variate starts at
``j = 0`` and a rejection method moves on to ``j = 1, 2, ...`` inside its slot:
:func:`std_normal` needs a second word with probability 0.012,
:func:`simcam.rng_poisson.poisson` uses one word (inversion; a second with probability
below 1/16) or two per PTRS trial (acceptance above 0.89), so a slot is never
exhausted in practice (the probability of needing 2048 PTRS trials is below
``0.11**2048``).

Variates
--------
* :func:`uniform01`: top 53 bits ``k`` mapped to ``k * 2**-53`` (``k = 0`` to
  ``2**-54``), in the open interval (0, 1).
* :func:`std_normal`: exact standard normal by the ziggurat method with 256 layers,
  G. Marsaglia & W. W. Tsang (2000), "The ziggurat method for generating random
  variables", Journal of Statistical Software 5(8), doi:10.18637/jss.v005.i08, in the
  64-bit form used by numpy's ``Generator.standard_normal`` (8 bits pick the layer, 1
  the sign, 52 the abscissa); 98.8 % of draws cost one 64-bit word and a table look-up.
  Rare rejections and the tail (Marsaglia 1964) use the following counters.
* :func:`std_normal_ppf`: the inverse normal CDF by Wichura's algorithm AS 241 (PPND16),
  M. J. Wichura (1988), "The percentage points of the normal distribution", Applied
  Statistics 37(3), 477-484; relative accuracy about 1e-16 (for quantiles, or a normal
  from a single uniform where exactly one counter must be consumed).

The exact Poisson variates of the same generator (table inversion below a mean of 10,
Hoermann's PTRS above) are in :mod:`simcam.rng_poisson`.
"""

from __future__ import annotations

import math
import operator

import numpy as np
from numba import njit

from simcam.infra.errors import ScenarioError

__all__ = [
    "DRAW_BITS",
    "SLOT_BITS",
    "RngParameterError",
    "key_from_seed",
    "child_keys",
    "pixel_counter",
    "random_bits64",
    "uniform01",
    "uniform01_from_word",
    "std_normal_from_word",
    "std_normal_ppf",
    "std_normal",
    "as_key",
    "as_counters",
    "uniform_array",
    "normal_array",
]

#: Number of counter bits reserved per pixel for its successive draws.
DRAW_BITS = 16
#: Number of counter bits of one slot (one variate and its rejection retries).
SLOT_BITS = 12
#: Largest mosaic pixel index whose counters fit in 64 bits.
MAX_PIXEL_INDEX = (1 << (64 - DRAW_BITS)) - 1

_GOLDEN_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX_M1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_M2 = np.uint64(0x94D049BB133111EB)
_ONE_U64 = np.uint64(1)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO_M53 = 1.0 / 9007199254740992.0  # 2**-53


def _ziggurat_tables():
    """Tables of the 256-layer normal ziggurat (Marsaglia & Tsang 2000, ``zigset``).

    ``r = 3.6541528853610088`` is the start of the tail and ``v = 4.92867323399e-3``
    the area of each layer, the 256-layer values of Marsaglia & Tsang; abscissae are
    scaled to 52-bit integers as in numpy's ``ziggurat_constants.h``.
    """
    m1 = 2.0**52
    dn = _ZIG_R
    tn = dn
    vn = 4.92867323399e-3
    ki = np.zeros(256, dtype=np.uint64)
    wi = np.zeros(256, dtype=np.float64)
    fi = np.zeros(256, dtype=np.float64)
    q = vn / math.exp(-0.5 * dn * dn)
    ki[0] = np.uint64(int((dn / q) * m1))
    ki[1] = np.uint64(0)
    wi[0] = q / m1
    wi[255] = dn / m1
    fi[0] = 1.0
    fi[255] = math.exp(-0.5 * dn * dn)
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(vn / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = np.uint64(int((dn / tn) * m1))
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / m1
    return ki, wi, fi


_ZIG_R = 3.6541528853610088
_ZIG_INV_R = 1.0 / _ZIG_R
_ZIG_KI, _ZIG_WI, _ZIG_FI = _ziggurat_tables()
_ZIG_KI.flags.writeable = False
_ZIG_WI.flags.writeable = False
_ZIG_FI.flags.writeable = False
_U8_MASK = np.uint64(0xFF)
_S8 = np.uint64(8)
_S1 = np.uint64(1)
_U52_MASK = np.uint64(0x000FFFFFFFFFFFFF)

class RngParameterError(ScenarioError):
    """A seed, key, counter or distribution parameter is invalid (names the parameter)."""


# --------------------------------------------------------------------------------------
# Key derivation (Python)
# --------------------------------------------------------------------------------------


def key_from_seed(seed: int, *path: int) -> np.uint64:
    """Derive a 64-bit stream key from an integer seed and a spawn path.

    Parameters
    ----------
    seed : int
        Non-negative entropy of the scenario (the user's seed).
    *path : int
        Non-negative integers naming the stream, e.g. ``(frame_index,)`` or
        ``(DETECTOR_STREAM, chip)``; used as ``spawn_key`` so that
        ``key_from_seed(s, *p)`` equals the key of the child that
        ``SeedSequence(s).spawn`` would produce along the same path.

    Returns
    -------
    numpy.uint64
        ``SeedSequence(seed, spawn_key=path).generate_state(1, dtype=np.uint64)[0]``
        (O'Neill's seed_seq hashing as implemented by numpy).

    Raises
    ------
    RngParameterError
        If ``seed`` or an element of ``path`` is not a non-negative integer.
    """
    seed_i = _as_nonneg_int(seed, "seed")
    path_i = tuple(_as_nonneg_int(p, f"path[{i}]") for i, p in enumerate(path))
    ss = np.random.SeedSequence(seed_i, spawn_key=path_i)
    return ss.generate_state(1, dtype=np.uint64)[0]


def child_keys(key, count: int, *, start: int = 0) -> np.ndarray:
    """Keys of ``count`` child streams of ``key``: outputs ``start .. start+count-1`` of
    SplitMix64(key), i.e. ``random_bits64(key, i)`` (vectorised; used for frame keys).

    Distinct children of one key are distinct (the finaliser is a bijection of distinct
    Weyl-sequence states), and as 64-bit values they behave like fresh random keys.
    """
    i = np.arange(start, start + count, dtype=np.uint64)
    with np.errstate(over="ignore"):
        z = np.uint64(key) + (i + _ONE_U64) * _GOLDEN_GAMMA
        z = (z ^ (z >> _S30)) * _MIX_M1
        z = (z ^ (z >> _S27)) * _MIX_M2
    return z ^ (z >> _S31)


def pixel_counter(*, pixel_index, draw):
    """Counter of draw ``draw`` of pixel ``pixel_index``: ``pixel_index * 2**16 + draw``.

    Parameters
    ----------
    pixel_index : int or array_like of int
        Mosaic pixel index ``row * mosaic_cols + col``, ``0 <= pixel_index < 2**48``.
    draw : int
        Draw number inside the pixel, ``0 <= draw < 2**16``.

    Returns
    -------
    numpy.uint64 or numpy.ndarray of uint64
    """
    d = _as_nonneg_int(draw, "draw")
    if d >= (1 << DRAW_BITS):
        raise RngParameterError(f"draw: must be < 2**{DRAW_BITS} (got {d})")
    p = np.asarray(pixel_index)
    if p.dtype.kind not in "iu" or (p.size and (p.min() < 0 or p.max() > MAX_PIXEL_INDEX)):
        raise RngParameterError(
            f"pixel_index: must be integers in [0, 2**{64 - DRAW_BITS}) (got dtype {p.dtype})"
        )
    out = (p.astype(np.uint64) << np.uint64(DRAW_BITS)) | np.uint64(d)
    return out if out.ndim else np.uint64(out)


def _as_nonneg_int(value, name: str) -> int:
    try:
        iv = operator.index(value)
    except TypeError:
        raise RngParameterError(f"{name}: must be an integer (got {value!r})") from None
    if iv < 0:
        raise RngParameterError(f"{name}: must be >= 0 (got {iv})")
    return iv


def as_key(key, name: str = "key") -> np.uint64:
    """``key`` as a stream key, a ``numpy.uint64``; :class:`RngParameterError` naming ``name``
    unless it is an integer in ``[0, 2**64)``."""
    iv = _as_nonneg_int(key, name)
    if iv >= 1 << 64:
        raise RngParameterError(f"{name}: must be < 2**64 (got {iv})")
    return np.uint64(iv)


# --------------------------------------------------------------------------------------
# Device functions (numba)
# --------------------------------------------------------------------------------------


@njit(cache=True)
def random_bits64(key, counter):
    """64 random bits for ``(key, counter)``: output ``counter`` of SplitMix64(key).

    Parameters
    ----------
    key : uint64
        Stream key.
    counter : uint64
        Position in the stream.

    Returns
    -------
    uint64
        ``mix13(key + (counter + 1) * 0x9E3779B97F4A7C15)`` (Steele, Lea & Flood 2014).
    """
    z = np.uint64(key) + (np.uint64(counter) + _ONE_U64) * _GOLDEN_GAMMA
    z = (z ^ (z >> _S30)) * _MIX_M1
    z = (z ^ (z >> _S27)) * _MIX_M2
    return z ^ (z >> _S31)


@njit(cache=True)
def uniform01(key, counter):
    """Uniform variate on the open interval (0, 1) with 53-bit resolution.

    Parameters
    ----------
    key : uint64
        Stream key.
    counter : uint64
        Position in the stream.

    Returns
    -------
    float
        ``max(k, 1/2) * 2**-53`` with ``k = bits >> 11``: the 53-bit grid of numpy's
        ``random()``, with ``k = 0`` (probability ``2**-53``) moved to ``2**-54`` so
        that the value is never 0; the largest value is ``1 - 2**-53``, so never 1.
        (Midpoints ``(k + 1/2) * 2**-53`` would need 54 significant bits above 1/2 and
        round to 1.)
    """
    return uniform01_from_word(random_bits64(key, counter))


@njit(cache=True, inline="always")
def uniform01_from_word(word):
    """:func:`uniform01` of the word ``word = random_bits64(key, counter)``: ``max(word >> 11,
    1/2) * 2**-53``. For kernels that compute a run of words first, in a loop the compiler
    vectorises (the SplitMix64 multiplies), and the variates after it."""
    return max(np.float64(np.int64(word >> _S11)), 0.5) * _TWO_M53


@njit(cache=True)
def std_normal_ppf(p):
    """Inverse of the standard normal CDF, Wichura's AS 241 (PPND16).

    M. J. Wichura (1988), "Algorithm AS 241: The percentage points of the normal
    distribution", Applied Statistics 37(3), 477-484. Rational approximations in three
    regions; relative accuracy about 1e-16.

    Parameters
    ----------
    p : float
        Probability, ``0 < p < 1`` (returns -inf / +inf at 0 / 1, nan outside).

    Returns
    -------
    float
        ``z`` with ``Phi(z) = p``.
    """
    q = p - 0.5
    if abs(q) <= 0.425:
        r = 0.180625 - q * q
        num = (((((((2.5090809287301226727e3 * r + 3.3430575583588128105e4) * r
                    + 6.7265770927008700853e4) * r + 4.5921953931549871457e4) * r
                  + 1.3731693765509461125e4) * r + 1.9715909503065514427e3) * r
                + 1.3314166789178437745e2) * r + 3.3871328727963666080e0)
        den = (((((((5.2264952788528545610e3 * r + 2.8729085735721942674e4) * r
                    + 3.9307895800092710610e4) * r + 2.1213794301586595867e4) * r
                  + 5.3941960214247511077e3) * r + 6.8718700749205790830e2) * r
                + 4.2313330701600911252e1) * r + 1.0)
        return q * num / den
    if not (p > 0.0 and p < 1.0):
        if p == 0.0:
            return -np.inf
        if p == 1.0:
            return np.inf
        return np.nan
    r = p if q < 0.0 else 1.0 - p
    r = math.sqrt(-math.log(r))
    if r <= 5.0:
        r -= 1.6
        num = (((((((7.74545014278341407640e-4 * r + 2.27238449892691845833e-2) * r
                    + 2.41780725177450611770e-1) * r + 1.27045825245236838258e0) * r
                  + 3.64784832476320460504e0) * r + 5.76949722146069140550e0) * r
                + 4.63033784615654529590e0) * r + 1.42343711074968357734e0)
        den = (((((((1.05075007164441684324e-9 * r + 5.47593808499534494600e-4) * r
                    + 1.51986665636164571966e-2) * r + 1.48103976427480074590e-1) * r
                  + 6.89767334985100004550e-1) * r + 1.67638483018380384940e0) * r
                + 2.05319162663775882187e0) * r + 1.0)
    else:
        r -= 5.0
        num = (((((((2.01033439929228813265e-7 * r + 2.71155556874348757815e-5) * r
                    + 1.24266094738807843860e-3) * r + 2.65321895265761230930e-2) * r
                  + 2.96560571828504891230e-1) * r + 1.78482653991729133580e0) * r
                + 5.46378491116411436990e0) * r + 6.65790464350110377720e0)
        den = (((((((2.04426310338993978564e-15 * r + 1.42151175831644588870e-7) * r
                    + 1.84631831751005468180e-5) * r + 7.86869131145613259100e-4) * r
                  + 1.48753612908506148525e-2) * r + 1.36929880922735805310e-1) * r
                + 5.99832206555887937690e-1) * r + 1.0)
    x = num / den
    return -x if q < 0.0 else x


@njit(cache=True)
def std_normal(key, counter):
    """Exact standard normal variate N(0, 1) by the 256-layer ziggurat.

    Marsaglia & Tsang (2000), J. Stat. Softw. 5(8), in numpy's 64-bit layout; the tail
    beyond ``r = 3.654`` by Marsaglia's (1964) method. The first word is taken at
    ``counter``; a rejection (probability about 0.012) continues at ``counter + 1``,
    ``counter + 2``, ... (stay inside one slot of ``2**SLOT_BITS`` counters).

    Parameters
    ----------
    key : uint64
        Stream key.
    counter : uint64
        First counter of the variate's slot.

    Returns
    -------
    float
        Standard normal deviate.
    """
    return std_normal_from_word(random_bits64(key, counter), key, counter)


@njit(cache=True, inline="always")
def std_normal_from_word(word, key, counter):
    """:func:`std_normal` at ``(key, counter)`` given its first word ``word =
    random_bits64(key, counter)`` (the ziggurat's fast path on it; a rejection continues at
    ``counter + 1``, ...), as :func:`uniform01_from_word`."""
    idx = np.int64(word & _U8_MASK)
    r = word >> _S8
    sign = 1.0 - 2.0 * np.float64(np.int64(r & _S1))  # branch-free: +1 or -1
    rabs = (r >> _S1) & _U52_MASK
    x = np.float64(np.int64(rabs)) * _ZIG_WI[idx] * sign
    if rabs < _ZIG_KI[idx]:
        return x
    return _std_normal_reject(key, np.uint64(counter), idx, x, sign)


@njit(cache=True)
def _std_normal_reject(key, counter, idx, x, sign):
    """Ziggurat slow path: wedge test or tail for the word at ``counter`` (then retry)."""
    c = counter + _ONE_U64
    while True:
        if idx == 0:
            while True:
                xx = -_ZIG_INV_R * math.log(uniform01(key, c))
                yy = -math.log(uniform01(key, c + _ONE_U64))
                c += np.uint64(2)
                if yy + yy > xx * xx:
                    return sign * (_ZIG_R + xx)
        f1 = _ZIG_FI[idx]
        f0 = _ZIG_FI[idx - 1]
        u = uniform01(key, c)
        c += _ONE_U64
        if (f0 - f1) * u + f1 < math.exp(-0.5 * x * x):
            return x
        # rejected: a fresh ziggurat word
        r = random_bits64(key, c)
        c += _ONE_U64
        idx = np.int64(r & _U8_MASK)
        r = r >> _S8
        sign = 1.0 - 2.0 * np.float64(np.int64(r & _S1))
        rabs = (r >> _S1) & _U52_MASK
        x = np.float64(np.int64(rabs)) * _ZIG_WI[idx] * sign
        if rabs < _ZIG_KI[idx]:
            return x


# --------------------------------------------------------------------------------------
# Array loops (numba) and their Python wrappers (Poisson: simcam.rng_poisson)
# --------------------------------------------------------------------------------------


@njit(cache=True)
def _uniform_fill(key, counters, out):
    for i in range(counters.size):
        out[i] = uniform01(key, counters[i])


@njit(cache=True)
def _normal_fill(key, counters, out):
    for i in range(counters.size):
        out[i] = std_normal(key, counters[i])


def as_counters(counter) -> np.ndarray:
    """``counter`` as a contiguous ``uint64`` array; :class:`RngParameterError` unless it holds
    non-negative integers."""
    c = np.asarray(counter)
    if c.dtype.kind not in "iu":
        raise RngParameterError(f"counter: must be integers (got dtype {c.dtype})")
    if c.dtype.kind == "i" and c.size and c.min() < 0:
        raise RngParameterError("counter: must be >= 0")
    return np.ascontiguousarray(c, dtype=np.uint64)


def uniform_array(*, key, counter) -> np.ndarray:
    """Vectorised :func:`uniform01`.

    Parameters
    ----------
    key : int or numpy.uint64
        Stream key, ``0 <= key < 2**64``.
    counter : array_like of int
        Non-negative counters.

    Returns
    -------
    numpy.ndarray of float64
        Same shape as ``counter``; values in (0, 1).
    """
    k = as_key(key)
    c = as_counters(counter)
    out = np.empty(c.shape, dtype=np.float64)
    _uniform_fill(k, c.reshape(-1), out.reshape(-1))
    return out


def normal_array(*, key, counter) -> np.ndarray:
    """Vectorised :func:`std_normal` (standard normal, AS 241 inversion).

    Parameters
    ----------
    key : int or numpy.uint64
        Stream key, ``0 <= key < 2**64``.
    counter : array_like of int
        Non-negative counters; a rejection consumes the following counters, so space
        them by ``2**SLOT_BITS`` for independent values (:func:`pixel_counter`).

    Returns
    -------
    numpy.ndarray of float64
        Same shape as ``counter``.
    """
    k = as_key(key)
    c = as_counters(counter)
    out = np.empty(c.shape, dtype=np.float64)
    _normal_fill(k, c.reshape(-1), out.reshape(-1))
    return out

