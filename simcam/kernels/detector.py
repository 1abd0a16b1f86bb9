"""numba kernels of the detector signal chain (arrays and scalars in, no orchestration).

Each pixel's value is a pure function of its expected signal, its mosaic pixel index
and two stream keys, evaluated with the counter-based generator of :mod:`simcam.rng`:

* detector key (fixed for a camera, "drawn once from the scenario seed"):
  slot ``SLOT_PRNU`` (gain non-uniformity), ``SLOT_DSNU`` (dark non-uniformity),
  ``SLOT_HOT`` (hot-pixel selection);
* frame key (one per exposure): slot ``SLOT_READ`` (read noise), ``SLOT_SHOT``
  (photon + dark shot noise).

The counter of slot ``s`` of mosaic pixel ``p = row * mosaic_cols + col`` is
``p * 2**16 + s * 2**12`` (see :mod:`simcam.rng`). Because nothing else enters, a full
frame, a window and any thread split give bit-identical pixels.

Physics (per pixel, chip ``k = col // chip_cols``), following the photon-transfer
definitions of J. R. Janesick, *Photon Transfer* (SPIE Press, 2007), and
EMVA Standard 1288 release 4.0 (2021) (linear camera model):

* PRNU: ``g = max(0, 1 + prnu_rms * z1)``, ``z1 ~ N(0, 1)``;
* dark signal with DSNU: ``d = max(0, dark_e + dsnu_rms_e * z2)`` plus
  ``hot_dark_e`` if ``u3 < hot_fraction`` (``u3 ~ U(0, 1)``);
* integral non-linearity of the mean charge ``s = signal_e * g + d`` when ``beta != 0``:
  ``s (1 - beta min(s, FW) / FW)`` (:func:`simcam.detector.apply_nonlinearity`);
* charge: ``n = Poisson(s)`` (or its mean without shot noise), clipped at
  the full well ``full_well_e[k]`` (the pixel's charge capacity, Janesick 2007);
* read noise added at the output amplifier: ``n + read_noise_e[k] * z4``;
* ADC: ``DN = n / gain_e_per_dn[k] + offset_dn[k]``, quantised as
  ``floor(DN + 0.5)`` and clipped to ``[0, max_dn]`` (EMVA 1288 linear model, with the
  quantisation noise variance 1/12 DN^2).

Note for developers: numba's on-disk cache (``cache=True``) keys a kernel on its own
source file only; after editing :mod:`simcam.rng` or :mod:`simcam.rng_poisson`, delete the ``detector.*.nbi/nbc``
files under ``simcam/kernels/__pycache__`` or the kernels keep the old generator
(``tests/test_detector.py::test_kernel_equals_composition_of_rng_primitives`` fails
if they do).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from simcam.rng import (
    SLOT_BITS,
    DRAW_BITS,
    random_bits64,
    std_normal,
    std_normal_from_word,
    uniform01,
    uniform01_from_word,
)
from simcam.rng_poisson import (
    poisson,
    poisson_from_word,
    poisson_from_words,
    poisson_prepared,
    poisson_setup,
)

SLOT_PRNU = 0
SLOT_DSNU = 1
SLOT_HOT = 2
SLOT_READ = 0
SLOT_SHOT = 1

_DRAW_SHIFT = np.uint64(DRAW_BITS)
_SLOT_SHIFT = np.uint64(SLOT_BITS)


@njit(cache=True, inline="always")
def slot_counter(pixel, slot):
    """First counter of slot ``slot`` of mosaic pixel ``pixel``: ``p * 2**16 + s * 2**12``.

    Parameters
    ----------
    pixel : int
        Mosaic pixel index ``row * mosaic_cols + col``.
    slot : int
        Slot number, 0..15.

    Returns
    -------
    uint64
    """
    return (np.uint64(pixel) << _DRAW_SHIFT) | (np.uint64(slot) << _SLOT_SHIFT)


@njit(cache=True, inline="always")
def prnu_value(detector_key, pixel, prnu_rms):
    """PRNU gain factor ``max(0, 1 + prnu_rms * z)`` of one pixel (dimensionless)."""
    if prnu_rms == 0.0:
        return 1.0
    g = 1.0 + prnu_rms * std_normal(detector_key, slot_counter(pixel, SLOT_PRNU))
    return g if g > 0.0 else 0.0


@njit(cache=True, inline="always")
def dark_value(detector_key, pixel, dark_e, dsnu_rms_e, hot_fraction, hot_dark_e):
    """Mean dark signal of one pixel (e-): DSNU-perturbed level plus hot-pixel excess."""
    d = dark_e
    if dsnu_rms_e > 0.0:
        d = dark_e + dsnu_rms_e * std_normal(detector_key, slot_counter(pixel, SLOT_DSNU))
        if d < 0.0:
            d = 0.0
    if hot_fraction > 0.0:
        if uniform01(detector_key, slot_counter(pixel, SLOT_HOT)) < hot_fraction:
            d += hot_dark_e
    return d


@njit(cache=True)
def expose_row(signal_row, out_row, row, col0, mosaic_cols, chip_cols, gain_e_per_dn,
               offset_dn, read_noise_e, full_well_e, prnu_rms, dark_e, dsnu_rms_e,
               hot_fraction, hot_dark_e, frame_key, detector_key, shot_noise, read_noise,
               quantize, max_dn):
    """One row segment ``signal_row[w]`` starting at mosaic ``(row, col0)`` into ``out_row``.

    Two passes over a row-sized scratch buffer: the mean charge ``S g + d``; then
    (:func:`_noise_adc_row`), chip by chip so that the per-chip constants are loaded
    once, the Poisson draw, full well, read noise and ADC. Every value is a function of
    the pixel index and the keys only, so the pass structure does not change the result.
    """
    w = signal_row.shape[0]
    base = row * mosaic_cols + col0
    e = np.empty(w, dtype=np.float64)
    for jj in range(w):
        e[jj] = (signal_row[jj] * prnu_value(detector_key, base + jj, prnu_rms)
                 + dark_value(detector_key, base + jj, dark_e, dsnu_rms_e, hot_fraction,
                              hot_dark_e))
    _noise_adc_row(e, out_row, row, col0, mosaic_cols, chip_cols, gain_e_per_dn, offset_dn,
                   read_noise_e, full_well_e, frame_key, shot_noise, read_noise, quantize,
                   max_dn)


#: Pixels per chunk of :func:`expose_block` (three float64 scratch rows of 4 kB: L1-resident).
_CHUNK = 512


# not inlined into the parallel kernels that call it once per 512-pixel chunk: the same
# speed (a full frame 176 ms either way), and each parallel signature compiles about 2 s
# faster on a cold cache (numba inlines at the IR level, so the parfor body would carry it)
@njit(cache=True)
def _chain_chunk(sig, out, pixel0, m, z, n, g, off, rn, fw, prnu_rms, dark_e, dsnu_rms_e, hot_fraction,
                 hot_dark_e, beta, max_signal_e, frame_key, detector_key, shot_noise, read_noise,
                 quantize, max_dn):
    """The chain of :func:`expose_block` for ``len(sig)`` consecutive pixels of one chip from
    mosaic pixel ``pixel0``: the random draws in loops of their own (the generator's
    branches and table look-ups), the arithmetic between them in plain loops that the
    compiler vectorises. The operations on each pixel and their order are those of
    :func:`prnu_value`, :func:`dark_value`, :func:`nonlinearity_windows` and
    :func:`_noise_adc_prepared` (so the same values). Returns 1 if a ``sig`` value is
    outside ``[0, max_signal_e]`` or NaN, else 0."""
    k = sig.shape[0]
    bad = False
    for jj in range(k):
        s = sig[jj]
        bad |= not (s >= 0.0 and s <= max_signal_e)
    # mean charge S g + d (prnu_value, dark_value)
    if prnu_rms == 0.0:
        for jj in range(k):
            m[jj] = sig[jj] * 1.0
    else:
        for jj in range(k):
            z[jj] = std_normal(detector_key, slot_counter(pixel0 + jj, SLOT_PRNU))
        for jj in range(k):
            gg = 1.0 + prnu_rms * z[jj]
            m[jj] = sig[jj] * (gg if gg > 0.0 else 0.0)
    if dsnu_rms_e > 0.0:
        for jj in range(k):
            z[jj] = std_normal(detector_key, slot_counter(pixel0 + jj, SLOT_DSNU))
        for jj in range(k):
            d = dark_e + dsnu_rms_e * z[jj]
            z[jj] = 0.0 if d < 0.0 else d
    else:
        for jj in range(k):
            z[jj] = dark_e
    if hot_fraction > 0.0:
        for jj in range(k):
            if uniform01(detector_key, slot_counter(pixel0 + jj, SLOT_HOT)) < hot_fraction:
                z[jj] += hot_dark_e
    for jj in range(k):
        m[jj] = m[jj] + z[jj]
    if beta != 0.0:
        for jj in range(k):
            v = m[jj]
            mn = v if v <= fw else fw
            m[jj] = v * (1.0 - beta * mn / fw)
    # temporal noise (_noise_adc_prepared): count, full well, read noise, ADC
    if shot_noise:
        for jj in range(k):
            n[jj] = np.float64(poisson(m[jj], frame_key, slot_counter(pixel0 + jj, SLOT_SHOT)))
    else:
        for jj in range(k):
            n[jj] = m[jj]
    for jj in range(k):
        v = n[jj]
        n[jj] = v if not v > fw else fw
    if read_noise:
        for jj in range(k):
            z[jj] = std_normal(frame_key, slot_counter(pixel0 + jj, SLOT_READ))
        for jj in range(k):
            n[jj] += rn * z[jj]
    if quantize:
        for jj in range(k):
            v = math.floor(n[jj] / g + off + 0.5)
            if v < 0.0:
                v = 0.0
            elif v > max_dn:
                v = max_dn
            out[jj] = v
    else:
        for jj in range(k):
            out[jj] = n[jj] / g + off
    return 1 if bad else 0


@njit(parallel=True, cache=True)
def expose_block(signal_e, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn, offset_dn,
                 read_noise_e, full_well_e, prnu_rms, dark_e, dsnu_rms_e, hot_fraction,
                 hot_dark_e, nonlinearity_beta, max_signal_e, frame_key, detector_key, shot_noise,
                 read_noise, quantize, max_dn, out):
    """Whole detector chain of a rectangular block in one pass over it; rows in parallel.

    Per pixel, with nothing stored but the output (512-pixel chunks of a row through L1
    scratch, :func:`_chain_chunk`): the mean charge ``S g + d`` (PRNU, dark, DSNU, hot
    pixels), the integral non-linearity ``s (1 - beta min(s, FW) / FW)`` when
    ``nonlinearity_beta`` is not 0 (:func:`nonlinearity_windows`, same operations), then
    the Poisson draw, full well, read noise, gain, quantisation and clipping
    (:func:`_noise_adc_pixel`). The same expressions in the same order as the window
    route (:func:`mean_charge_windows`, :func:`nonlinearity_windows`,
    :func:`noise_adc_frames`), so the same pixels bit for bit; the random numbers are
    functions of the pixel index and the keys only, so the row split over threads does
    not change them.

    Parameters
    ----------
    signal_e : ndarray, shape (h, w), float
        Expected photo-electrons before PRNU.
    row0, col0 : int
        Mosaic coordinates of ``signal_e[0, 0]``.
    mosaic_cols, chip_cols : int
        Mosaic width and chip width (columns).
    gain_e_per_dn, offset_dn, read_noise_e, full_well_e : ndarray, shape (n_chips,)
        Per-chip conversion gain (e-/DN), offset (DN), read noise (e- rms), full well (e-).
    prnu_rms, dark_e, dsnu_rms_e, hot_fraction, hot_dark_e : float
        PRNU rms (fraction), mean dark (e-), DSNU rms (e-), hot-pixel fraction and
        excess dark (e-).
    nonlinearity_beta : float
        Integral non-linearity coefficient (0: the linear camera).
    max_signal_e : float
        Largest valid ``signal_e``; the input check rides on the same pass.
    frame_key, detector_key : uint64
        Stream keys.
    shot_noise, read_noise, quantize : bool
        Switches of the temporal noise terms and of the ADC rounding/clipping.
    max_dn : float
        ``2**adc_bits - 1``.
    out : ndarray, shape (h, w)
        Output (uint16/uint32 when quantising, float64 otherwise).

    Returns
    -------
    int
        Number of rows with a value of ``signal_e`` outside ``[0, max_signal_e]`` or NaN
        (the caller rejects the input then; every pixel is still computed, the generator
        being total: no loop runs forever on such a value).
    """
    h, w = signal_e.shape
    bad_row = np.zeros(h, dtype=np.int64)
    for i in prange(h):
        base = (row0 + i) * mosaic_cols + col0
        # scratch of one chunk (L1-sized): mean charge, a normal (or the dark signal), the count
        m = np.empty(_CHUNK)
        z = np.empty(_CHUNK)
        n = np.empty(_CHUNK)
        bad = 0
        j = 0
        while j < w:
            chip, j_end = _chip_segment(col0, j, w, chip_cols)
            j_end = min(j_end, j + _CHUNK)
            bad += _chain_chunk(signal_e[i, j:j_end], out[i, j:j_end], base + j, m, z, n,
                                gain_e_per_dn[chip], offset_dn[chip], read_noise_e[chip],
                                full_well_e[chip], prnu_rms, dark_e, dsnu_rms_e, hot_fraction,
                                hot_dark_e, nonlinearity_beta, max_signal_e, frame_key, detector_key,
                                shot_noise, read_noise, quantize, max_dn)
            j = j_end
        bad_row[i] = bad
    return bad_row.sum()


@njit(parallel=True, cache=True)
def fixed_pattern_maps(row0, col0, mosaic_cols, prnu_rms, dark_e, dsnu_rms_e, hot_fraction,
                       hot_dark_e, detector_key, gain_out, dark_out):
    """The detector's fixed pattern of a block at mosaic ``(row0, col0)``, rows in parallel:
    ``gain_out[i, j]`` the PRNU factor ``g`` (:func:`prnu_value`) and ``dark_out[i, j]`` the
    mean dark signal ``d`` (e-, :func:`dark_value`: DSNU and hot pixels) of each pixel;
    the same operations on the same variates (their first words computed in a loop of
    their own, :func:`simcam.rng.std_normal_from_word`, :func:`simcam.rng.uniform01_from_word`), so the same
    values as the chain's own (:func:`_chain_chunk`). Computed once for a sequence of
    frames of one camera and read by :func:`expose_block_maps`."""
    h, w = gain_out.shape
    for i in prange(h):
        base = (row0 + i) * mosaic_cols + col0
        wd = np.empty(_CHUNK, dtype=np.uint64)
        j = 0
        while j < w:
            j_end = min(w, j + _CHUNK)
            k = j_end - j
            p0 = base + j
            g = gain_out[i, j:j_end]
            d = dark_out[i, j:j_end]
            if prnu_rms == 0.0:
                for jj in range(k):
                    g[jj] = 1.0
            else:
                for jj in range(k):
                    wd[jj] = random_bits64(detector_key, slot_counter(p0 + jj, SLOT_PRNU))
                for jj in range(k):
                    gg = 1.0 + prnu_rms * std_normal_from_word(wd[jj], detector_key,
                                                                slot_counter(p0 + jj, SLOT_PRNU))
                    g[jj] = gg if gg > 0.0 else 0.0
            if dsnu_rms_e > 0.0:
                for jj in range(k):
                    wd[jj] = random_bits64(detector_key, slot_counter(p0 + jj, SLOT_DSNU))
                for jj in range(k):
                    dd = dark_e + dsnu_rms_e * std_normal_from_word(wd[jj], detector_key,
                                                                     slot_counter(p0 + jj, SLOT_DSNU))
                    d[jj] = 0.0 if dd < 0.0 else dd
            else:
                for jj in range(k):
                    d[jj] = dark_e
            if hot_fraction > 0.0:
                for jj in range(k):
                    wd[jj] = random_bits64(detector_key, slot_counter(p0 + jj, SLOT_HOT))
                for jj in range(k):
                    if uniform01_from_word(wd[jj]) < hot_fraction:
                        d[jj] += hot_dark_e
            j = j_end


@njit(cache=True, inline="always")
def _adc(v, g, off, max_dn):
    """DN code of ``v`` e-: ``floor(v / g + off + 0.5)`` clipped to ``[0, max_dn]`` (as
    :func:`_chain_chunk`)."""
    v = math.floor(v / g + off + 0.5)
    if v < 0.0:
        v = 0.0
    elif v > max_dn:
        v = max_dn
    return v


# not inlined, as :func:`_chain_chunk` (the maps route: 156 ms a frame either way, 2 s less
# compilation per parallel signature)
@njit(cache=True)
def _frame_chunk(sig, gm, dm, out, pixel0, m, z, n, wp, wr, g, off, rn, fw, beta, max_signal_e, frame_key,
                 shot_noise, read_noise, quantize, max_dn):
    """:func:`_chain_chunk` given the pixels' fixed pattern ``gm`` (PRNU factor ``g``) and
    ``dm`` (dark signal ``d``) from :func:`fixed_pattern_maps`: the mean charge ``S g + d``
    (the same two operations, so the same value), then the non-linearity, Poisson draw,
    full well, read noise and ADC as there. Only the frame key's draws are made, their
    first words (``wp``, ``wr``: uint64 scratch) in a loop of their own
    (:func:`simcam.rng_poisson.poisson_from_word`, :func:`simcam.rng.std_normal_from_word`: the same variates).
    Returns 1 if a ``sig`` value is outside ``[0, max_signal_e]`` or NaN, else 0."""
    k = sig.shape[0]
    bad = False
    for jj in range(k):
        s = sig[jj]
        bad |= not (s >= 0.0 and s <= max_signal_e)
        m[jj] = s * gm[jj] + dm[jj]
    if beta != 0.0:
        for jj in range(k):
            v = m[jj]
            mn = v if v <= fw else fw
            m[jj] = v * (1.0 - beta * mn / fw)
    # first words of the frame's draws (vectorised), then the count clipped at the full well
    if shot_noise and read_noise:
        for jj in range(k):
            wp[jj] = random_bits64(frame_key, slot_counter(pixel0 + jj, SLOT_SHOT))
            wr[jj] = random_bits64(frame_key, slot_counter(pixel0 + jj, SLOT_READ))
    elif shot_noise:
        for jj in range(k):
            wp[jj] = random_bits64(frame_key, slot_counter(pixel0 + jj, SLOT_SHOT))
    elif read_noise:
        for jj in range(k):
            wr[jj] = random_bits64(frame_key, slot_counter(pixel0 + jj, SLOT_READ))
    if shot_noise:
        for jj in range(k):
            v = np.float64(poisson_from_word(m[jj], wp[jj], frame_key, slot_counter(pixel0 + jj, SLOT_SHOT)))
            n[jj] = v if not v > fw else fw
    else:
        for jj in range(k):
            v = m[jj]
            n[jj] = v if not v > fw else fw
    # read noise n + rn z (the sum rounded as in _chain_chunk's n += rn z), then the ADC
    if read_noise:
        for jj in range(k):
            z[jj] = std_normal_from_word(wr[jj], frame_key, slot_counter(pixel0 + jj, SLOT_READ))
        if quantize:
            for jj in range(k):
                out[jj] = _adc(n[jj] + rn * z[jj], g, off, max_dn)
        else:
            for jj in range(k):
                out[jj] = (n[jj] + rn * z[jj]) / g + off
    elif quantize:
        for jj in range(k):
            out[jj] = _adc(n[jj], g, off, max_dn)
    else:
        for jj in range(k):
            out[jj] = n[jj] / g + off
    return 1 if bad else 0


@njit(parallel=True, cache=True)
def expose_block_maps(signal_e, gain_map, dark_map, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn,
                      offset_dn, read_noise_e, full_well_e, nonlinearity_beta, max_signal_e, frame_key,
                      shot_noise, read_noise, quantize, max_dn, out):
    """:func:`expose_block` with the fixed pattern read from maps: ``gain_map``/``dark_map``
    (h, w) float64, the PRNU factor and dark signal of the block's pixels
    (:func:`fixed_pattern_maps` with the same detector key and parameters). The same
    pixels bit for bit (:func:`_frame_chunk`); per pixel only the frame's draws (Poisson,
    read noise). Arguments otherwise as :func:`expose_block`; returns the number of rows
    with an invalid ``signal_e`` value."""
    h, w = signal_e.shape
    bad_row = np.zeros(h, dtype=np.int64)
    for i in prange(h):
        base = (row0 + i) * mosaic_cols + col0
        m = np.empty(_CHUNK)
        z = np.empty(_CHUNK)
        n = np.empty(_CHUNK)
        wp = np.empty(_CHUNK, dtype=np.uint64)
        wr = np.empty(_CHUNK, dtype=np.uint64)
        bad = 0
        j = 0
        while j < w:
            chip, j_end = _chip_segment(col0, j, w, chip_cols)
            j_end = min(j_end, j + _CHUNK)
            bad += _frame_chunk(signal_e[i, j:j_end], gain_map[i, j:j_end], dark_map[i, j:j_end],
                                out[i, j:j_end], base + j, m, z, n, wp, wr, gain_e_per_dn[chip], offset_dn[chip],
                                read_noise_e[chip], full_well_e[chip], nonlinearity_beta, max_signal_e,
                                frame_key, shot_noise, read_noise, quantize, max_dn)
            j = j_end
        bad_row[i] = bad
    return bad_row.sum()


@njit(parallel=True, cache=True)
def expose_windows(signal_e, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn, offset_dn,
                   read_noise_e, full_well_e, prnu_rms, dark_e, dsnu_rms_e, hot_fraction,
                   hot_dark_e, frame_key, detector_key, shot_noise, read_noise, quantize,
                   max_dn, out):
    """Detector chain for ``n`` equal windows ``signal_e[n, h, w]`` at ``(row0[n], col0[n])``.

    Same arguments as :func:`expose_block`, with ``row0``/``col0`` int64 arrays of
    length ``n``; (window, row) pairs run in parallel.
    """
    n, h, w = signal_e.shape
    for t in prange(n * h):
        k = t // h
        i = t - k * h
        expose_row(signal_e[k, i], out[k, i], row0[k] + i, col0[k], mosaic_cols, chip_cols,
                   gain_e_per_dn, offset_dn, read_noise_e, full_well_e, prnu_rms, dark_e,
                   dsnu_rms_e, hot_fraction, hot_dark_e, frame_key, detector_key,
                   shot_noise, read_noise, quantize, max_dn)


@njit(cache=True)
def mean_charge_windows(signal_e, row0, col0, mosaic_cols, prnu_rms, dark_e, dsnu_rms_e,
                        hot_fraction, hot_dark_e, detector_key, out):
    """Mean charge ``S g + d`` (e-) of ``n`` windows: the fixed-pattern part of
    :func:`expose_row`, computed once for many frames (same operations, same values).

    ``signal_e``, ``out``: (n, h, w) float64; ``row0``, ``col0``: (n,) int64.
    """
    n, h, w = signal_e.shape
    for k in range(n):
        for i in range(h):
            base = (row0[k] + i) * mosaic_cols + col0[k]
            for jj in range(w):
                out[k, i, jj] = (signal_e[k, i, jj] * prnu_value(detector_key, base + jj, prnu_rms)
                                 + dark_value(detector_key, base + jj, dark_e, dsnu_rms_e,
                                              hot_fraction, hot_dark_e))


@njit(cache=True)
def nonlinearity_windows(mean, col0, chip_cols, full_well_e, beta, out):
    """Integral non-linearity ``s (1 - beta min(s, FW) / FW)`` of ``n`` windows' mean charge
    ``mean[n, h, w]`` (window ``k`` starting at mosaic column ``col0[k]``, ``FW`` the full well of
    each column's chip) into ``out`` (:func:`simcam.detector.apply_nonlinearity`): the same
    operations in the same order as its numpy expression, so the same values, in one pass
    without temporaries (an 8-Mpx frame: five 64-MB passes fewer)."""
    n, h, w = mean.shape
    fwc = np.empty(w)
    for k in range(n):
        for j in range(w):
            fwc[j] = full_well_e[(col0[k] + j) // chip_cols]
        for i in range(h):
            for j in range(w):
                s = mean[k, i, j]
                fw = fwc[j]
                mn = s if s <= fw else fw
                out[k, i, j] = s * (1.0 - beta * mn / fw)


@njit(cache=True, inline="always")
def _noise_adc_pixel(v, pixel, g, off, rn, fw, frame_key, shot_noise, read_noise, quantize, max_dn):
    """Temporal noise and ADC of one pixel of mean charge ``v`` (e-): Poisson, full well,
    read noise, conversion and quantisation (module docstring). Returns DN (float)."""
    mode, pj, pr, pb, pa, pvr = poisson_setup(v)
    return _noise_adc_prepared(v, mode, pj, pr, pb, pa, pvr, pixel, g, off, rn, fw, frame_key,
                               shot_noise, read_noise, quantize, max_dn)


@njit(cache=True, inline="always")
def _noise_adc_prepared(v, mode, pj, pr, pb, pa, pvr, pixel, g, off, rn, fw, frame_key,
                        shot_noise, read_noise, quantize, max_dn):
    """:func:`_noise_adc_pixel` given ``simcam.rng_poisson.poisson_setup(v)`` (same value)."""
    if shot_noise:
        v = np.float64(poisson_prepared(v, mode, pj, pr, pb, pa, pvr, frame_key,
                                        slot_counter(pixel, SLOT_SHOT)))
    if v > fw:
        v = fw
    if read_noise:
        v += rn * std_normal(frame_key, slot_counter(pixel, SLOT_READ))
    if quantize:
        return _adc(v, g, off, max_dn)
    return v / g + off


@njit(cache=True, inline="always")
def _chip_segment(col0, j, w, chip_cols):
    """Chip of column ``j`` of a segment of ``w`` columns starting at mosaic column
    ``col0``, and the end (exclusive) of the run of the segment's columns on that chip."""
    chip = (col0 + j) // chip_cols
    return chip, min(w, (chip + 1) * chip_cols - col0)


@njit(cache=True, inline="always")
def _chip_run(col0, j, w, chip_cols, gain_e_per_dn, offset_dn, read_noise_e, full_well_e):
    """The end of the run of columns from ``j`` on one chip (:func:`_chip_segment`) and that
    chip's gain, offset, read noise and full well."""
    chip, j_end = _chip_segment(col0, j, w, chip_cols)
    return j_end, gain_e_per_dn[chip], offset_dn[chip], read_noise_e[chip], full_well_e[chip]


@njit(cache=True)
def _noise_adc_row(mean_row, out_row, row, col0, mosaic_cols, chip_cols, gain_e_per_dn,
                   offset_dn, read_noise_e, full_well_e, frame_key, shot_noise, read_noise,
                   quantize, max_dn):
    """Temporal noise and ADC of one window row given its mean charge (as :func:`expose_row`)."""
    w = mean_row.shape[0]
    base = row * mosaic_cols + col0
    j = 0
    while j < w:
        j_end, g, off, rn, fw = _chip_run(col0, j, w, chip_cols, gain_e_per_dn, offset_dn, read_noise_e, full_well_e)
        for jj in range(j, j_end):
            out_row[jj] = _noise_adc_pixel(mean_row[jj], base + jj, g, off, rn, fw, frame_key,
                                           shot_noise, read_noise, quantize, max_dn)
        j = j_end


@njit(cache=True)
def noise_adc_frames(mean, out, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn, offset_dn,
                     read_noise_e, full_well_e, frame_keys, shot_noise, read_noise, quantize,
                     max_dn):
    """:func:`_noise_adc_row` for a block ``mean[h, w]`` at mosaic ``(row0, col0)`` in ``F``
    frames, into ``out[F, h, w]``: the same value per pixel and frame, computed pixel by
    pixel with the frames innermost, so that the chip constants and the Poisson set-up
    of each pixel's mean (:func:`simcam.rng_poisson.poisson_setup`) are computed once."""
    h, w = mean.shape
    nf = frame_keys.shape[0]
    j = 0
    while j < w:
        j_end, g, off, rn, fw = _chip_run(col0, j, w, chip_cols, gain_e_per_dn, offset_dn, read_noise_e, full_well_e)
        for i in range(h):
            base = (row0 + i) * mosaic_cols + col0
            for jj in range(j, j_end):
                v = mean[i, jj]
                mode, pj, pr, pb, pa, pvr = poisson_setup(v)
                for f in range(nf):
                    out[f, i, jj] = _noise_adc_prepared(v, mode, pj, pr, pb, pa, pvr, base + jj, g, off,
                                                        rn, fw, frame_keys[f], shot_noise, read_noise,
                                                        quantize, max_dn)
        j = j_end


@njit(cache=True)
def noise_adc_window(mean, out, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn, offset_dn, read_noise_e,
                     full_well_e, frame_key, max_dn, words, scratch):
    """:func:`noise_adc_frames` of one frame with shot and read noise, quantised (the chain of a
    Monte Carlo trial's windows): ``mean[h, w]`` (e-, C-contiguous) at mosaic ``(row0, col0)``
    into ``out[h, w]`` (float64, C-contiguous), the same value per pixel, in passes over the
    block: the words of the pixels' Poisson and read-noise draws in one loop the compiler
    vectorises (the SplitMix64 multiplies), the counts from them
    (:func:`simcam.rng_poisson.poisson_from_words`: PTRS means together), then, chip by chip, the
    full well, read noise (:func:`simcam.rng.std_normal_from_word`) and ADC
    (:func:`_noise_adc_prepared`'s operations in its order). ``words``: uint64 scratch
    (3, h w); ``scratch``: int64 scratch of 2 h w."""
    h, w = mean.shape
    shot_counter = words[0]
    shot_word = words[1]
    read_word = words[2]
    for i in range(h):
        base = (row0 + i) * mosaic_cols + col0
        for j in range(w):
            p = i * w + j
            c = slot_counter(base + j, SLOT_SHOT)
            shot_counter[p] = c
            shot_word[p] = random_bits64(frame_key, c)
            read_word[p] = random_bits64(frame_key, slot_counter(base + j, SLOT_READ))
    poisson_from_words(mean.reshape(h * w), shot_word, frame_key, shot_counter, out.reshape(h * w), scratch)
    j = 0
    while j < w:
        j_end, g, off, rn, fw = _chip_run(col0, j, w, chip_cols, gain_e_per_dn, offset_dn, read_noise_e, full_well_e)
        for i in range(h):
            base = (row0 + i) * mosaic_cols + col0
            for jj in range(j, j_end):
                v = out[i, jj]
                if v > fw:
                    v = fw
                z = std_normal_from_word(read_word[i * w + jj], frame_key, slot_counter(base + jj, SLOT_READ))
                out[i, jj] = _adc(v + rn * z, g, off, max_dn)
        j = j_end


@njit(cache=True)
def _store_window(src, out, k):
    """``out[:, k] = src`` for a window's frames ``src`` (F, h, w) float64; ``out`` is
    (F, n, h, w) of the output dtype (the quantised values are whole numbers in
    ``[0, max_dn]``, so the conversion is exact)."""
    nf, h, w = src.shape
    for f in range(nf):
        for i in range(h):
            for j in range(w):
                out[f, k, i, j] = src[f, i, j]


@njit(parallel=True, cache=True)
def expose_windows_frames(mean_e, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn,
                          offset_dn, read_noise_e, full_well_e, frame_keys, shot_noise,
                          read_noise, quantize, max_dn, out):
    """Temporal noise and ADC of ``n`` windows in ``F`` frames, windows in parallel.

    ``mean_e`` (n, h, w) from :func:`mean_charge_windows`; ``frame_keys`` (F,) uint64;
    ``out`` (F, n, h, w). Pixel values equal :func:`expose_windows` with each frame key.
    Each window goes through a float64 scratch (F, h, w), so :func:`noise_adc_frames` has
    one signature whatever the output dtype: numba compiles it once.
    """
    n, h, w = mean_e.shape
    for kk in prange(n):
        k = np.int64(kk)
        scratch = np.empty((frame_keys.shape[0], h, w))
        noise_adc_frames(mean_e[k], scratch, row0[k], col0[k], mosaic_cols, chip_cols,
                         gain_e_per_dn, offset_dn, read_noise_e, full_well_e, frame_keys,
                         shot_noise, read_noise, quantize, max_dn)
        _store_window(scratch, out, k)


@njit(cache=True)
def expose_windows_frames_serial(mean_e, row0, col0, mosaic_cols, chip_cols, gain_e_per_dn,
                                 offset_dn, read_noise_e, full_well_e, frame_keys, shot_noise,
                                 read_noise, quantize, max_dn, out):
    """Single-threaded twin of :func:`expose_windows_frames` (small batches, worker processes)."""
    n, h, w = mean_e.shape
    scratch = np.empty((frame_keys.shape[0], h, w))
    for k in range(n):
        noise_adc_frames(mean_e[k], scratch, row0[k], col0[k], mosaic_cols, chip_cols,
                         gain_e_per_dn, offset_dn, read_noise_e, full_well_e, frame_keys,
                         shot_noise, read_noise, quantize, max_dn)
        _store_window(scratch, out, k)
