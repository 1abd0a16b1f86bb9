"""Detector signal chain: PRNU, dark signal with DSNU and hot pixels, shot noise, full
well, read noise and ADC, for any block or set of windows of the mosaic.

Definitions follow J. R. Janesick, *Photon Transfer: DN -> lambda* (SPIE Press, 2007)
(conversion gain K in e-/DN, read noise, full well, PRNU as the rms of the pixel gain
relative to its mean, DSNU as the rms of the dark signal across pixels) and EMVA
Standard 1288 release 4.0 (2021), linear camera model (``mu_y = mu_e/K + offset``,
``sigma_y^2 = (sigma_e^2 + sigma_read^2)/K^2 + 1/12`` with the quantisation variance
1/12 DN^2, electrons ``mu_e`` = photo-electrons + dark). The per-pixel model and its
counter-based random numbers are described in :mod:`simcam.kernels.detector`; the
maps (PRNU, DSNU, hot pixels) are keyed by the detector key and so are fixed for a
camera, the temporal noise is keyed by the frame key.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from simcam.infra.errors import ScenarioError
from simcam.kernels import detector as _k
from simcam.rng import MAX_PIXEL_INDEX, as_key

__all__ = [
    "DetectorParameterError",
    "DetectorMaps",
    "DetectorParams",
    "detector_maps",
    "expose",
    "expose_windows",
    "prnu_map",
    "dsnu_map",
    "apply_nonlinearity",
]

#: Largest accepted expected signal per pixel (e-): far above any full well, and small
#: enough that PRNU x signal stays inside the exact range of the Poisson generator.
MAX_SIGNAL_E = 1e12

_PER_CHIP = ("gain_e_per_dn", "offset_dn", "read_noise_e", "full_well_e")


class DetectorParameterError(ScenarioError):
    """An invalid detector parameter or exposure argument (the message names it)."""


def _fail(name: str, msg: str, value) -> None:
    raise DetectorParameterError(f"{name}: {msg} (got {value!r})")


def _finite_float(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        _fail(name, "must be a real number", value)
    v = float(value)
    if not math.isfinite(v):
        _fail(name, "must be finite", value)
    return v


@dataclass(frozen=True, kw_only=True)
class DetectorParams:
    """Parameters of the detector chain, validated on creation.

    Per-chip parameters are sequences of length ``n_chips`` (chip ``k`` holds mosaic
    columns ``k * chip_cols`` to ``(k + 1) * chip_cols - 1``).

    Parameters
    ----------
    gain_e_per_dn : sequence of float
        Conversion gain K of each chip, e-/DN, > 0 (Janesick 2007).
    offset_dn : sequence of float
        ADC offset (bias) of each chip, DN, in ``[0, 2**adc_bits - 1]``.
    read_noise_e : sequence of float
        Read noise of each chip, e- rms, >= 0.
    full_well_e : sequence of float
        Full-well capacity of each chip, e-, > 0.
    adc_bits : int
        ADC resolution, 8..32; quantised output is uint16 up to 16 bits, else uint32.
    prnu_rms : float
        Photo-response non-uniformity, rms of the pixel gain relative to 1, >= 0.
    dark_e : float
        Mean dark signal of the exposure (dark current x exposure time), e-, >= 0.
    dsnu_rms_e : float
        Dark-signal non-uniformity, rms across pixels, e-, >= 0.
    hot_pixel_fraction : float
        Fraction of hot pixels, in [0, 1].
    hot_pixel_dark_e : float
        Extra dark signal of a hot pixel in the exposure, e-, >= 0.
    nonlinearity_beta : float
        Integral non-linearity of the charge-to-signal conversion, in (-1, 1): the mean
        charge ``s`` of a pixel becomes ``s (1 - beta min(s, FW) / FW)`` (:func:`apply_nonlinearity`);
        0 (default) is the linear camera.

    Raises
    ------
    DetectorParameterError
        Naming the first invalid field.
    """

    gain_e_per_dn: tuple[float, ...]
    offset_dn: tuple[float, ...]
    read_noise_e: tuple[float, ...]
    full_well_e: tuple[float, ...]
    adc_bits: int = 16
    prnu_rms: float = 0.0
    dark_e: float = 0.0
    dsnu_rms_e: float = 0.0
    hot_pixel_fraction: float = 0.0
    hot_pixel_dark_e: float = 0.0
    nonlinearity_beta: float = 0.0

    def __post_init__(self):
        bits = self.adc_bits
        if isinstance(bits, bool) or not isinstance(bits, numbers.Integral):
            _fail("adc_bits", "must be an integer", bits)
        if not 8 <= int(bits) <= 32:
            _fail("adc_bits", "must be in 8..32", bits)
        object.__setattr__(self, "adc_bits", int(bits))
        n_chips = None
        for name in _PER_CHIP:
            raw = getattr(self, name)
            if isinstance(raw, (str, bytes)) or np.ndim(raw) != 1:
                _fail(name, "must be a 1-D sequence with one value per chip", raw)
            vals = tuple(_finite_float(f"{name}[{i}]", v) for i, v in enumerate(raw))
            if not vals:
                _fail(name, "must have at least one chip", raw)
            if n_chips is None:
                n_chips = len(vals)
            elif len(vals) != n_chips:
                _fail(name, f"must have {n_chips} values (one per chip), like gain_e_per_dn",
                      raw)
            object.__setattr__(self, name, vals)
        max_dn = float(2**self.adc_bits - 1)
        for i, v in enumerate(self.gain_e_per_dn):
            if v <= 0.0:
                _fail(f"gain_e_per_dn[{i}]", "must be > 0", v)
        for i, v in enumerate(self.offset_dn):
            if not 0.0 <= v <= max_dn:
                _fail(f"offset_dn[{i}]", f"must be in [0, {max_dn:.0f}] for {self.adc_bits} bits",
                      v)
        for i, v in enumerate(self.read_noise_e):
            if v < 0.0:
                _fail(f"read_noise_e[{i}]", "must be >= 0", v)
        for i, v in enumerate(self.full_well_e):
            if v <= 0.0:
                _fail(f"full_well_e[{i}]", "must be > 0", v)
        for name in ("prnu_rms", "dark_e", "dsnu_rms_e", "hot_pixel_dark_e"):
            v = _finite_float(name, getattr(self, name))
            if v < 0.0:
                _fail(name, "must be >= 0", v)
            object.__setattr__(self, name, v)
        v = _finite_float("hot_pixel_fraction", self.hot_pixel_fraction)
        if not 0.0 <= v <= 1.0:
            _fail("hot_pixel_fraction", "must be in [0, 1]", v)
        object.__setattr__(self, "hot_pixel_fraction", v)
        v = _finite_float("nonlinearity_beta", self.nonlinearity_beta)
        if not -1.0 < v < 1.0:
            _fail("nonlinearity_beta", "must be in (-1, 1)", v)
        object.__setattr__(self, "nonlinearity_beta", v)

    @property
    def n_chips(self) -> int:
        """Number of chips (length of the per-chip parameters)."""
        return len(self.gain_e_per_dn)

    @property
    def max_dn(self) -> int:
        """Largest ADC code, ``2**adc_bits - 1``."""
        return 2**self.adc_bits - 1

    @property
    def output_dtype(self) -> np.dtype:
        """dtype of quantised frames: uint16 up to 16 bits, else uint32."""
        return np.dtype(np.uint16 if self.adc_bits <= 16 else np.uint32)

    def _chip_arrays(self):
        """The per-chip parameters as float64 arrays (gain, offset, read noise, full well), made
        once per parameter set (the fields are frozen) and shared by the chains built from it,
        which only read them."""
        arrays = self.__dict__.get("_chip_arrays_f8")
        if arrays is None:
            arrays = self.__dict__["_chip_arrays_f8"] = tuple(np.asarray(getattr(self, n), dtype=np.float64)
                                                              for n in _PER_CHIP)
        return arrays


def _int_arg(name: str, value, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        _fail(name, "must be an integer", value)
    iv = int(value)
    if iv < minimum:
        _fail(name, f"must be >= {minimum}", value)
    return iv


def _check_geometry(*, rows_hi: int, cols_lo: int, cols_hi: int, mosaic_cols, chip_cols,
                    params: DetectorParams) -> tuple[int, int]:
    """Validate the mosaic geometry for a region; return (mosaic_cols, chip_cols)."""
    if not isinstance(params, DetectorParams):
        _fail("params", "must be a DetectorParams", type(params).__name__)
    mc = _int_arg("mosaic_cols", mosaic_cols, minimum=1)
    cc = _int_arg("chip_cols", chip_cols, minimum=1)
    n_needed = -(-mc // cc)
    if n_needed > params.n_chips:
        _fail("chip_cols", f"mosaic_cols={mc} needs {n_needed} chips but params has "
              f"{params.n_chips}", cc)
    if cols_lo < 0 or cols_hi > mc:
        _fail("col0", f"block columns [{cols_lo}, {cols_hi}) must lie inside [0, {mc})",
              cols_lo)
    if rows_hi * mc - 1 > MAX_PIXEL_INDEX:
        _fail("row0", "block rows too far for the 48-bit pixel index", rows_hi)
    return mc, cc


def _signal_range_error():
    _fail("signal_e", f"must be in [0, {MAX_SIGNAL_E:g}] e- everywhere", "negative/NaN/inf/huge values")


def _signal(signal_e, ndim: int, *, check_range: bool = True) -> np.ndarray:
    a = np.asarray(signal_e)
    if a.ndim != ndim:
        _fail("signal_e", f"must be a {ndim}-D array", a.shape)
    if a.dtype not in (np.float32, np.float64):
        if a.dtype.kind not in "biuf":
            _fail("signal_e", "must be real numbers", a.dtype)
        a = a.astype(np.float64)
    a = np.ascontiguousarray(a)
    # min and max propagate NaN, and NaN fails both comparisons (numpy's reductions: no
    # kernel for numba to compile on a first run, 2 ms more on an 8-Mpx frame)
    if check_range and a.size and not (a.min() >= 0.0 and a.max() <= MAX_SIGNAL_E):
        _signal_range_error()
    return a


def _keys(frame_key, detector_key):
    try:
        return as_key(frame_key, "frame_key"), as_key(detector_key, "detector_key")
    except ValueError as err:
        raise DetectorParameterError(str(err)) from None


def apply_nonlinearity(mean_e: np.ndarray, *, col0, chip_cols: int, params: DetectorParams) -> np.ndarray:
    """Integral non-linearity of the pixel's charge-to-signal conversion, on the mean charge.

    ``s_out = s (1 - beta min(s, FW) / FW)`` per pixel, ``FW`` the full well of the pixel's
    chip: the quadratic compression of a CMOS pixel's response (source-follower gain and
    photodiode capacitance changing with the collected charge; J. R. Janesick, *Photon
    Transfer*, SPIE PM170, 2007, ch. 7). Against the end-point line through 0 and FW its
    largest deviation is ``beta FW / 4`` at ``s = FW / 2``: an integral non-linearity (INL)
    of ``beta / 4`` of full scale (0.2 % typical for a GSENSE4040-class sensor, Gpixel data
    sheet, so ``beta = 0.008``). The signal is clipped at FW in the factor only (a saturated
    pixel is clipped at FW after the shot noise anyway).

    Applied to the mean charge ``S g + d`` before the temporal noise is drawn (the static
    transfer curve, which is what moves a centroid or a flux); the shot noise is then that
    of the compressed mean, where a per-frame compression would scale it by ``(1 - 2 beta s /
    FW)``: the noise variance differs by ``3 beta s / FW`` relative, 1.2 % for the default's
    brightest pixel at half full well. ``mean_e`` (n, h, w) or (h, w), ``col0`` the mosaic
    column of each window's (or the block's) first column. Returns a new array.
    """
    beta = params.nonlinearity_beta
    m = np.asarray(mean_e, dtype=np.float64)
    squeeze = m.ndim == 2
    if squeeze:
        m = m[None]
    c0 = np.ascontiguousarray(np.atleast_1d(np.asarray(col0, dtype=np.int64)))
    m = np.ascontiguousarray(m)
    out = np.empty_like(m)
    # one numba pass, the numpy expression's operations in its order (same values):
    # m * (1 - beta * minimum(m, fw) / fw), fw the full well of each column's chip
    _k.nonlinearity_windows(m, c0, int(chip_cols), np.asarray(params.full_well_e, dtype=np.float64),
                            float(beta), out)
    return out[0] if squeeze else out


def _fixed_pattern_fields(params: DetectorParams) -> tuple[float, ...]:
    """The parameters the fixed-pattern maps depend on (PRNU, dark, DSNU, hot pixels)."""
    return (params.prnu_rms, params.dark_e, params.dsnu_rms_e, params.hot_pixel_fraction,
            params.hot_pixel_dark_e)


@dataclass(frozen=True, eq=False)
class DetectorMaps:
    """The fixed pattern of a block of the mosaic, computed once for many frames.

    ``gain`` (h, w) float64 is the PRNU factor ``g = max(0, 1 + prnu_rms z1)`` and ``dark_e``
    (h, w) float64 the mean dark signal ``d = max(0, dark_e + dsnu_rms_e z2)`` (plus
    ``hot_pixel_dark_e`` on the hot pixels) of each pixel: the values the chain draws
    per pixel from the detector key (:func:`simcam.kernels.detector.prnu_value`,
    :func:`simcam.kernels.detector.dark_value`), so :func:`expose` with ``maps`` gives the
    same pixels bit for bit while drawing only the frame's noise. Memory: 16 bytes per
    pixel (134 MB for a 2048 x 4096 mosaic). Built by :func:`detector_maps`; the key
    fields (``detector_key``, ``fixed``: the five fixed-pattern parameters, the block's
    origin and ``mosaic_cols``) are checked by :func:`expose` against its own arguments,
    so a map is never used for another detector or block.
    """

    gain: np.ndarray
    dark_e: np.ndarray
    row0: int
    col0: int
    mosaic_cols: int
    detector_key: np.uint64
    fixed: tuple[float, ...]

    @property
    def shape(self) -> tuple[int, int]:
        """``(h, w)`` of the block."""
        return self.gain.shape

    @property
    def nbytes(self) -> int:
        """Memory of the two maps, bytes."""
        return self.gain.nbytes + self.dark_e.nbytes

    def matches(self, *, params: DetectorParams, detector_key, mosaic_cols) -> bool:
        """Whether these maps are those of ``params`` and ``detector_key`` on this mosaic."""
        _, dk = _keys(0, detector_key)
        return (dk == self.detector_key and int(mosaic_cols) == self.mosaic_cols
                and _fixed_pattern_fields(params) == self.fixed)


def detector_maps(*, shape, row0, col0, mosaic_cols, params: DetectorParams, detector_key) -> DetectorMaps:
    """The fixed-pattern maps (PRNU factor and dark signal) of a block, for :func:`expose`.

    One numba pass, rows in parallel (:func:`simcam.kernels.detector.fixed_pattern_maps`).
    A sequence of frames of one camera builds them once (e.g. for the whole mosaic,
    ``shape=(rows, cols)`` at ``(0, 0)``) and passes them to every :func:`expose` call.

    Parameters
    ----------
    shape : tuple of int
        ``(h, w)`` of the block.
    row0, col0 : int
        Mosaic origin of the block.
    mosaic_cols : int
        Mosaic width in columns.
    params : DetectorParams
        Detector parameters (``prnu_rms``, ``dark_e``, ``dsnu_rms_e``, ``hot_pixel_*`` are used).
    detector_key : int or numpy.uint64
        Key of the detector's fixed maps.

    Returns
    -------
    DetectorMaps
    """
    h, w, r0, c0, mc = _block_args(shape, row0, col0, mosaic_cols)
    if not isinstance(params, DetectorParams):
        _fail("params", "must be a DetectorParams", type(params).__name__)
    _, dk = _keys(0, detector_key)
    gain = np.empty((h, w))
    dark = np.empty((h, w))
    if gain.size:
        _k.fixed_pattern_maps(r0, c0, mc, *(float(v) for v in _fixed_pattern_fields(params)), dk, gain, dark)
    return DetectorMaps(gain, dark, r0, c0, mc, dk, _fixed_pattern_fields(params))


def _maps_view(maps, *, r0, c0, h, w, mosaic_cols, params, detector_key):
    """The part of ``maps`` under the block ``[r0, r0 + h) x [c0, c0 + w)`` (C-contiguous); an
    error if the maps are another detector's (key or fixed-pattern parameters) or do not cover it."""
    if not isinstance(maps, DetectorMaps):
        _fail("maps", "must be a DetectorMaps (simcam.detector.detector_maps)", type(maps).__name__)
    if not maps.matches(params=params, detector_key=detector_key, mosaic_cols=mosaic_cols):
        _fail("maps", "were made for another detector key, fixed-pattern parameters or mosaic width",
              (int(maps.detector_key), maps.fixed, maps.mosaic_cols))
    mh, mw = maps.shape
    i0, j0 = r0 - maps.row0, c0 - maps.col0
    if i0 < 0 or j0 < 0 or i0 + h > mh or j0 + w > mw:
        _fail("maps", f"cover rows [{maps.row0}, {maps.row0 + mh}) x cols [{maps.col0}, {maps.col0 + mw}), "
              f"not the block at ({r0}, {c0}) of {h} x {w}", (maps.row0, maps.col0, mh, mw))
    if (i0, j0, h, w) == (0, 0, mh, mw):
        return maps.gain, maps.dark_e
    # a contiguous copy of the part (2 x 8 bytes a pixel of the block): the kernel then has one
    # array layout, so numba compiles one signature for whole and partial maps alike
    return (np.ascontiguousarray(maps.gain[i0:i0 + h, j0:j0 + w]),
            np.ascontiguousarray(maps.dark_e[i0:i0 + h, j0:j0 + w]))


def expose(*, signal_e, row0, col0, mosaic_cols, chip_cols, params: DetectorParams,
           frame_key, detector_key, shot_noise=True, read_noise=True,
           quantize=True, maps: DetectorMaps | None = None) -> np.ndarray:
    """Turn expected electrons of a block of mosaic pixels into detector output.

    Per pixel (Janesick 2007; EMVA 1288 linear model): ``n = Poisson(mu)`` with
    ``mu = S * g + d``, the PRNU factor ``g`` and the dark signal ``d`` (DSNU, hot pixels) of
    :func:`prnu_map` and :func:`dsnu_map` (with ``params.nonlinearity_beta`` not 0, ``mu`` is
    first compressed by :func:`apply_nonlinearity`), ``n`` clipped at the full well, plus
    ``N(0, read_noise_e**2)``, then ``DN = floor(n / K + offset + 0.5)`` clipped to
    ``[0, 2**adc_bits - 1]``. The random numbers depend only on the keys and the mosaic
    pixel index, so any block, window or thread count gives identical pixels. The whole
    chain runs in one numba pass per pixel, rows in parallel
    (:func:`simcam.kernels.detector.expose_block`), with the window route's operations.

    Parameters
    ----------
    signal_e : array_like, shape (h, w)
        Expected photo-electrons per pixel in the exposure (stars + background), before
        PRNU; in ``[0, MAX_SIGNAL_E]``. C-contiguous float32 or float64 arrays are used
        without a copy.
    row0, col0 : int
        Mosaic row and column of ``signal_e[0, 0]``.
    mosaic_cols : int
        Width of the mosaic in columns (defines the pixel index ``row * mosaic_cols +
        col``).
    chip_cols : int
        Width of one chip; the chip of column ``c`` is ``c // chip_cols``.
    params : DetectorParams
        Detector parameters.
    frame_key : int or numpy.uint64
        Key of this exposure's temporal noise (e.g. ``key_from_seed(seed, frame)``).
    detector_key : int or numpy.uint64
        Key of the fixed PRNU/DSNU/hot-pixel maps.
    shot_noise, read_noise : bool
        Include Poisson shot noise / read noise (off: the mean is used).
    quantize : bool
        Round and clip to ADC codes (uint16 or uint32); off: float64 DN, only the full
        well applied.
    maps : DetectorMaps, optional
        The fixed pattern (PRNU factor, dark signal) of a block covering this one, from
        :func:`detector_maps` with the same ``detector_key``, parameters and
        ``mosaic_cols`` (checked): the pass then reads it instead of drawing it
        (:func:`simcam.kernels.detector.expose_block_maps`), with the same pixels bit for
        bit. For a sequence of frames of one camera.

    Returns
    -------
    numpy.ndarray, shape (h, w)
        Output in DN.

    Raises
    ------
    DetectorParameterError
        On an invalid argument, naming it.
    """
    # the range check rides on the kernel's pass (numpy's min and max are two more passes
    # over a full frame); a bad value is reported after it, nothing is returned
    sig = _signal(signal_e, 2, check_range=False)
    r0 = _int_arg("row0", row0, minimum=0)
    c0 = _int_arg("col0", col0, minimum=0)
    h, w = sig.shape
    mc, cc = _check_geometry(rows_hi=r0 + h, cols_lo=c0, cols_hi=c0 + w, mosaic_cols=mosaic_cols,
                             chip_cols=chip_cols, params=params)
    fk, dk = _keys(frame_key, detector_key)
    if maps is not None:
        gmap, dmap = _maps_view(maps, r0=r0, c0=c0, h=h, w=w, mosaic_cols=mc, params=params,
                                detector_key=dk)
    out = np.empty((h, w), dtype=params.output_dtype if quantize else np.float64)
    if sig.size:
        g, off, rn, fw = params._chip_arrays()
        # one pass per pixel: fixed pattern, non-linearity (the linear camera at beta = 0),
        # temporal noise and ADC; the same pixels as the window route (window_chain and
        # expose_windows_frames) bit for bit
        if maps is None:
            bad_rows = _k.expose_block(sig, r0, c0, mc, cc, g, off, rn, fw, params.prnu_rms, params.dark_e,
                                       params.dsnu_rms_e, params.hot_pixel_fraction, params.hot_pixel_dark_e,
                                       params.nonlinearity_beta, MAX_SIGNAL_E, fk, dk, bool(shot_noise),
                                       bool(read_noise), bool(quantize), float(params.max_dn), out)
        else:
            # the fixed pattern read from the maps (the same values): only the frame's draws
            bad_rows = _k.expose_block_maps(sig, gmap, dmap, r0, c0, mc, cc, g, off, rn, fw,
                                            params.nonlinearity_beta, MAX_SIGNAL_E, fk, bool(shot_noise),
                                            bool(read_noise), bool(quantize), float(params.max_dn), out)
        if bad_rows:
            _signal_range_error()
    return out


def expose_windows(*, signal_e, row0, col0, mosaic_cols, chip_cols, params: DetectorParams,
                   frame_key, detector_key, shot_noise=True, read_noise=True,
                   quantize=True) -> np.ndarray:
    """Batched :func:`expose` for ``n`` equal windows (e.g. cut around stars).

    Window ``k`` covers mosaic rows ``row0[k] .. row0[k] + h - 1`` and columns
    ``col0[k] .. col0[k] + w - 1``; its pixels equal those of a full-frame
    :func:`expose` with the same keys. Windows may overlap.

    Parameters
    ----------
    signal_e : array_like, shape (n, h, w)
        Expected photo-electrons (before PRNU) of each window, in ``[0, MAX_SIGNAL_E]``.
    row0, col0 : array_like of int, shape (n,)
        Mosaic origin of each window.
    mosaic_cols, chip_cols, params, frame_key, detector_key, shot_noise, read_noise, quantize
        As in :func:`expose`.

    Returns
    -------
    numpy.ndarray, shape (n, h, w)
        Output in DN (uint16/uint32 when quantising, else float64).

    Raises
    ------
    DetectorParameterError
        On an invalid argument, naming it.
    """
    sig = _signal(signal_e, 3)
    n, h, w = sig.shape
    r0 = np.asarray(row0)
    c0 = np.asarray(col0)
    for name, arr in (("row0", r0), ("col0", c0)):
        if arr.shape != (n,) or (n and arr.dtype.kind not in "iu"):
            _fail(name, f"must be {n} integers (one per window)", arr)
        if n and arr.min() < 0:
            _fail(name, "must be >= 0", int(arr.min()))
    r0 = np.ascontiguousarray(r0, dtype=np.int64)
    c0 = np.ascontiguousarray(c0, dtype=np.int64)
    mc, cc = _check_geometry(rows_hi=int(r0.max()) + h if n else 0,
                             cols_lo=int(c0.min()) if n else 0,
                             cols_hi=int(c0.max()) + w if n else 0,
                             mosaic_cols=mosaic_cols, chip_cols=chip_cols, params=params)
    fk, dk = _keys(frame_key, detector_key)
    if params.nonlinearity_beta != 0.0:
        chain = window_chain(signal_e=sig, row0=r0, col0=c0, mosaic_cols=mc, chip_cols=cc, params=params,
                             detector_key=dk)
        return expose_windows_frames(chain=chain, frame_keys=[fk], shot_noise=shot_noise, read_noise=read_noise,
                                     quantize=quantize, parallel=False)[0]
    out = np.empty((n, h, w), dtype=params.output_dtype if quantize else np.float64)
    if sig.size:
        g, off, rn, fw = params._chip_arrays()
        _k.expose_windows(sig, r0, c0, mc, cc, g, off, rn, fw, params.prnu_rms,
                          params.dark_e, params.dsnu_rms_e, params.hot_pixel_fraction,
                          params.hot_pixel_dark_e, fk, dk, bool(shot_noise),
                          bool(read_noise), bool(quantize), float(params.max_dn), out)
    return out


def _block_args(shape, row0, col0, mosaic_cols):
    if np.ndim(shape) != 1 or len(shape) != 2:
        _fail("shape", "must be (rows, cols)", shape)
    h = _int_arg("shape[0]", shape[0], minimum=0)
    w = _int_arg("shape[1]", shape[1], minimum=0)
    r0 = _int_arg("row0", row0, minimum=0)
    c0 = _int_arg("col0", col0, minimum=0)
    mc = _int_arg("mosaic_cols", mosaic_cols, minimum=1)
    if c0 + w > mc:
        _fail("col0", f"block columns [{c0}, {c0 + w}) must lie inside [0, {mc})", c0)
    if (r0 + h) * mc - 1 > MAX_PIXEL_INDEX:
        _fail("row0", "block rows too far for the 48-bit pixel index", r0)
    return h, w, r0, c0, mc


def prnu_map(*, shape, row0, col0, mosaic_cols, params: DetectorParams,
             detector_key) -> np.ndarray:
    """PRNU gain factors ``max(0, 1 + prnu_rms * z)`` of a block (dimensionless).

    The map is a fixed function of ``detector_key`` and the mosaic pixel index
    (Janesick 2007: PRNU as the relative rms of the pixel response), so any block
    can be evaluated without building the full map.

    Parameters
    ----------
    shape : tuple of int
        ``(h, w)`` of the block.
    row0, col0 : int
        Mosaic origin of the block.
    mosaic_cols : int
        Mosaic width in columns.
    params : DetectorParams
        Detector parameters (``prnu_rms`` is used).
    detector_key : int or numpy.uint64
        Key of the detector's fixed maps.

    Returns
    -------
    numpy.ndarray of float64, shape ``shape``
    """
    # S g + d with S = 1 and no dark signal is g itself (1.0 * g + 0.0, exact)
    return _fixed_pattern_block(1.0, shape, row0, col0, mosaic_cols, params, detector_key, dark=False)


def dsnu_map(*, shape, row0, col0, mosaic_cols, params: DetectorParams,
             detector_key) -> np.ndarray:
    """Mean dark signal of each pixel of a block, e- per exposure.

    ``max(0, dark_e + dsnu_rms_e * z)`` plus ``hot_pixel_dark_e`` on the hot pixels
    (EMVA 1288: DSNU as the spatial rms of the dark signal); a fixed function of
    ``detector_key`` and the mosaic pixel index.

    Parameters
    ----------
    shape : tuple of int
        ``(h, w)`` of the block.
    row0, col0 : int
        Mosaic origin of the block.
    mosaic_cols : int
        Mosaic width in columns.
    params : DetectorParams
        Detector parameters (``dark_e``, ``dsnu_rms_e``, ``hot_pixel_*`` are used).
    detector_key : int or numpy.uint64
        Key of the detector's fixed maps.

    Returns
    -------
    numpy.ndarray of float64, shape ``shape``
    """
    # S g + d with S = 0 is d itself (exact: 0.0 * g + d)
    return _fixed_pattern_block(0.0, shape, row0, col0, mosaic_cols, params, detector_key, dark=True)


def _fixed_pattern_block(signal_e: float, shape, row0, col0, mosaic_cols, params, detector_key, *,
                         dark: bool) -> np.ndarray:
    """``S g + d`` (e-) of a block with uniform signal ``signal_e``, by the window
    fixed-pattern kernel :func:`simcam.kernels.detector.mean_charge_windows` (one
    kernel for numba to compile, not one per map); ``dark=False`` leaves the dark signal
    out (``d = 0``), ``True`` the PRNU (``g = 1``)."""
    h, w, r0, c0, mc = _block_args(shape, row0, col0, mosaic_cols)
    if not isinstance(params, DetectorParams):
        _fail("params", "must be a DetectorParams", type(params).__name__)
    _, dk = _keys(0, detector_key)
    out = np.empty((1, h, w))
    if out.size:
        prnu = 0.0 if dark else params.prnu_rms
        d = (params.dark_e, params.dsnu_rms_e, params.hot_pixel_fraction, params.hot_pixel_dark_e) if dark \
            else (0.0, 0.0, 0.0, 0.0)
        _k.mean_charge_windows(np.full((1, h, w), signal_e), np.array([r0], dtype=np.int64),
                               np.array([c0], dtype=np.int64), mc, float(prnu), *(float(v) for v in d), dk, out)
    return out[0]


@dataclass(frozen=True)
class WindowChain:
    """Validated inputs of the window noise kernels for a set of ``n`` windows.

    ``mean_e`` (n, h, w) is the mean charge ``S g + d`` (PRNU, dark, DSNU and hot pixels
    applied, e-); ``row0``/``col0`` (n,) int64 the mosaic origins; ``gain``, ``offset``,
    ``read_noise``, ``full_well`` the per-chip constants (float64 arrays); ``max_dn`` the
    ADC maximum. Built by :func:`window_chain`; consumed by
    :func:`simcam.kernels.detector._noise_adc_row` (through :func:`expose_windows_frames`
    or a caller's own fused kernel, which then gives the same pixels bit for bit).
    """

    mean_e: np.ndarray
    row0: np.ndarray
    col0: np.ndarray
    mosaic_cols: int
    chip_cols: int
    gain: np.ndarray
    offset: np.ndarray
    read_noise: np.ndarray
    full_well: np.ndarray
    max_dn: float
    output_dtype: np.dtype


def window_chain(*, signal_e, row0, col0, mosaic_cols, chip_cols, params: DetectorParams,
                 detector_key) -> WindowChain:
    """Validate a window batch and evaluate its fixed pattern once (see :class:`WindowChain`)."""
    sig = _signal(signal_e, 3)
    n, h, w = sig.shape
    r0 = np.ascontiguousarray(np.asarray(row0), dtype=np.int64)
    c0 = np.ascontiguousarray(np.asarray(col0), dtype=np.int64)
    if r0.shape != (n,) or c0.shape != (n,):
        _fail("row0/col0", f"must be {n} integers (one per window)", (r0.shape, c0.shape))
    if n and (r0.min() < 0 or c0.min() < 0):
        _fail("row0/col0", "must be >= 0", (int(r0.min()), int(c0.min())))
    mc, cc = _check_geometry(rows_hi=int(r0.max()) + h if n else 0,
                             cols_lo=int(c0.min()) if n else 0,
                             cols_hi=int(c0.max()) + w if n else 0,
                             mosaic_cols=mosaic_cols, chip_cols=chip_cols, params=params)
    _, dk = _keys(0, detector_key)
    mean = np.empty_like(sig, dtype=np.float64)
    if sig.size:
        _k.mean_charge_windows(sig, r0, c0, mc, float(params.prnu_rms), float(params.dark_e),
                               float(params.dsnu_rms_e), float(params.hot_pixel_fraction),
                               float(params.hot_pixel_dark_e), dk, mean)
        if params.nonlinearity_beta != 0.0:
            # apply_nonlinearity in place (the kernel reads each pixel before writing it):
            # no second full-size array for a full frame
            _k.nonlinearity_windows(mean, c0, int(cc), np.asarray(params.full_well_e, dtype=np.float64),
                                    float(params.nonlinearity_beta), mean)
    g, off, rn, fw = params._chip_arrays()
    return WindowChain(mean, r0, c0, mc, cc, g, off, rn, fw, float(params.max_dn), params.output_dtype)


def expose_windows_frames(*, signal_e=None, row0=None, col0=None, mosaic_cols=None, chip_cols=None,
                          params: DetectorParams | None = None, frame_keys, detector_key=None,
                          shot_noise=True, read_noise=True, quantize=True,
                          parallel: bool | None = None, chain: WindowChain | None = None) -> np.ndarray:
    """:func:`expose_windows` for many frames at once: output (F, n, h, w).

    Frame ``f`` uses ``frame_keys[f]``; its pixels equal ``expose_windows(...,
    frame_key=frame_keys[f])`` bit for bit. The fixed-pattern part (PRNU, dark, DSNU, hot
    pixels) is evaluated once for all frames (or given as ``chain`` from
    :func:`window_chain`, instead of the window and detector arguments). ``parallel``
    (default: when there are more than 20,000 window rows) runs (frame, window, row)
    tasks on numba threads; the result does not depend on it.
    """
    if chain is None:
        chain = window_chain(signal_e=signal_e, row0=row0, col0=col0, mosaic_cols=mosaic_cols,
                             chip_cols=chip_cols, params=params, detector_key=detector_key)
    keys = np.ascontiguousarray(np.asarray(frame_keys, dtype=np.uint64).ravel())
    _keys(keys[0] if keys.size else 0, 0)
    n, h, w = chain.mean_e.shape
    out = np.empty((keys.size, n, h, w), dtype=chain.output_dtype if quantize else np.float64)
    if chain.mean_e.size and keys.size:
        if parallel is None:
            parallel = keys.size * n * h > 20_000
        kern = _k.expose_windows_frames if parallel else _k.expose_windows_frames_serial
        kern(chain.mean_e, chain.row0, chain.col0, chain.mosaic_cols, chain.chip_cols, chain.gain,
             chain.offset, chain.read_noise, chain.full_well, keys, bool(shot_noise), bool(read_noise),
             bool(quantize), chain.max_dn, out)
    return out
