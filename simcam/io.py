"""FITS and CSV output of rendered exposures, and reading them back.

Layout of a render directory (``simcam render --out DIR``)::

    DIR/frame_0000.fits ...   full mode: one mosaic frame per file (primary HDU, uint16)
    DIR/windows.fits          windows mode: primary cube (frames, stars, h, w) + table WINDOWS
    DIR/truth.csv             one row per (frame, star): x_true, y_true and each component
    DIR/manifest.csv          file, frame, condition, filter_nm, field (as a lab manifest)
    DIR/scenario.toml         the resolved scenario that made it

Headers carry what an astronomer expects (EXPTIME, GAIN, FILTER, BUNIT) and what makes
the file reproducible (SEED, SCENHASH, SIMCAMV, the hexapod pose PLATDX/PLATDY).
Output is written into a temporary sibling directory and renamed into place at the end,
so an interrupted render never leaves a directory that looks complete.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from astropy.io import fits

from simcam import __version__
from simcam.infra.errors import UserInputError
from simcam.allocation import check_allocations
from simcam.infra.lifecycle import announce_size, check_disk, check_memory, partial_prefix, remove_stale_partials
from simcam.infra.outputs import apply_umask, check_output_dir, failed_write, input_file_problem, is_earlier_output


def frame_header(
    *, scenario, seed: int, frame: int, condition: int, filter_nm: float | None,
    platform_dx_px: float, platform_dy_px: float, label: str = "",
) -> fits.Header:
    """FITS header of one simulated exposure."""
    scn = scenario
    h = fits.Header()
    h["BUNIT"] = ("adu", "data unit: ADC counts (DN)")
    h["EXPTIME"] = (scn.camera.exposure_s, "[s] exposure time")
    for k, chip in enumerate(scn.detector.chips):
        h[f"GAIN{k + 1}"] = (chip.gain_e_per_dn, f"[e-/DN] gain of chip {k + 1}")
        h[f"RDNOIS{k + 1}"] = (chip.read_noise_e, f"[e-] read noise of chip {k + 1}")
        h[f"OFFSET{k + 1}"] = (chip.offset_dn, f"[DN] ADC offset of chip {k + 1}")
    h["GAIN"] = (scn.detector.chips[0].gain_e_per_dn, "[e-/DN] gain of chip 1")
    h["NCHIPS"] = (scn.detector.n_chips, "chips side by side along x")
    h["CHIPCOLS"] = (scn.detector.chip_cols, "columns per chip")
    h["BITDEPTH"] = (scn.detector.bits, "ADC bits")
    h["PLTSCALE"] = (scn.camera.scale_arcsec_per_px, "[arcsec/px] plate scale")
    h["FILTER"] = ("none" if filter_nm is None else f"{filter_nm:g}nm", "lab filter before target")
    if filter_nm is not None:
        h["FILTNM"] = (float(filter_nm), "[nm] filter centre")
    h["PLATDX"] = (platform_dx_px, "[px] hexapod image shift x")
    h["PLATDY"] = (platform_dy_px, "[px] hexapod image shift y")
    h["CONDITN"] = (condition, "acquisition condition index")
    h["FIELD"] = (label, "condition label")
    h["FRAME"] = (frame, "frame index within the condition")
    h["SEED"] = (seed, "run seed (temporal noise)")
    h["SCNSEED"] = (scn.seed, "scenario seed (FPN maps)")
    h["SCENHASH"] = (scn.hash, "scenario hash (sha256 prefix)")
    h["SIMCAMV"] = (__version__, "simcam version")
    h["ORIGIN"] = "simcam"
    h["COORDS"] = ("0-based, centres at integers", "pixel coords")
    return h


@contextmanager
def atomic_directory(out: str | os.PathLike, *, overwrite: bool = False, inputs=()):
    """Yield a temporary directory that replaces ``out`` only if the block completes.

    The temporary folder ``.NAME.partial.<pid>.*`` is removed on any exception, SIGINT,
    and (under :func:`simcam.infra.lifecycle.handle_termination`) SIGTERM; folders of this kind
    left by a run that was killed outright (SIGKILL, power cut) are removed here, with a
    line on stderr (:func:`simcam.infra.lifecycle.remove_stale_partials`). ``out`` never is
    nor holds one of ``inputs`` (the files the command read).
    """

    out = Path(out)
    # the one rule (simcam.infra.outputs.check_output_dir): empty, an earlier output, or --overwrite
    check_output_dir(out, option="--out", replaceable=is_earlier_output, overwrite=overwrite, inputs=inputs)
    out.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(out)
    tmp = Path(tempfile.mkdtemp(prefix=partial_prefix(out), dir=out.parent))
    apply_umask(tmp, is_dir=True)  # mkdtemp makes it 0700; the output gets the user's umask
    try:
        yield tmp
    except BaseException as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if (err := failed_write(exc, out, tmp=tmp)) is not None:  # the disk filled: name the file under out
            raise err from None
        raise
    if out.exists():
        shutil.rmtree(out)
    os.replace(tmp, out)


#: lossless tile compression of integer frames (FITS tiled image convention, astropy)
COMPRESSION = "RICE_1"


def write_frame(path: str | os.PathLike, data: np.ndarray, header: fits.Header, *, compress: bool = False) -> None:
    """Write one mosaic frame: a primary HDU, or (``compress``) a Rice tile-compressed
    image extension after an empty primary HDU (lossless for integer frames; read back
    by :func:`read_frame`)."""
    if not compress:
        fits.PrimaryHDU(data=data, header=header).writeto(path, overwrite=False)
        return
    if not np.issubdtype(np.asarray(data).dtype, np.integer):
        raise ValueError("compress: only integer frames are compressed (Rice is lossless for integers only)")
    comp = fits.CompImageHDU(data=data, header=header, compression_type=COMPRESSION)
    fits.HDUList([fits.PrimaryHDU(), comp]).writeto(path, overwrite=False)


def write_windows(path: str | os.PathLike, pixels: np.ndarray, col0: np.ndarray, row0: np.ndarray,
                  header: fits.Header) -> None:
    """Write windows (frames, stars, h, w) with their mosaic origins as a WINDOWS table."""
    prim = fits.PrimaryHDU(data=pixels, header=header)
    tab = fits.BinTableHDU.from_columns(
        [
            fits.Column(name="STAR", format="J", array=np.arange(len(col0))),
            fits.Column(name="COL0", format="K", array=np.asarray(col0, dtype=np.int64)),
            fits.Column(name="ROW0", format="K", array=np.asarray(row0, dtype=np.int64)),
        ],
        name="WINDOWS",
    )
    fits.HDUList([prim, tab]).writeto(path, overwrite=False)


def read_frame(path: str | os.PathLike) -> tuple[np.ndarray, fits.Header]:
    """Read a frame: the first 2-D image of the file (the primary HDU, or a tile-compressed
    image extension), as float64, and its header.

    Raises
    ------
    UserInputError
        Missing file, not FITS, truncated or damaged, no 2-D image, or every pixel NaN;
        the message names the file.
    """
    path = Path(path)
    if (why := input_file_problem(path)) is not None:  # a FIFO would block the reader forever
        raise UserInputError(f"{path}: {why}")
    if not path.is_file():
        raise UserInputError(f"{path}: frame file not found")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with fits.open(path, memmap=False) as hdul:
                data = header = None
                for hdu in hdul:
                    if hdu.is_image and hdu.header.get("NAXIS", 0) == 2:
                        data = np.array(hdu.data, dtype=np.float64)
                        header = hdu.header.copy()
                        break
                if data is None and len(hdul) and hdul[0].data is not None:
                    raise UserInputError(f"{path}: primary HDU holds no 2-D image (shape {hdul[0].data.shape})")
    except UserInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - astropy reports damage in many ways; all are bad input here
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UserInputError(f"{path}: not a readable FITS file ({msg})") from None
    truncated = [w for w in caught if "truncated" in str(w.message).lower()]
    if truncated:
        raise UserInputError(f"{path}: truncated FITS file ({str(truncated[0].message).splitlines()[0]})")
    if data is None:
        raise UserInputError(f"{path}: holds no 2-D image")
    if not np.isfinite(data).any():
        raise UserInputError(f"{path}: every pixel is NaN or infinite")
    return data, header


def read_windows(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, fits.Header]:
    """Read a windows file: pixels (frames, stars, h, w) float64, col0, row0, header."""
    path = Path(path)
    if (why := input_file_problem(path)) is not None:
        raise UserInputError(f"{path}: {why}")
    if not path.is_file():
        raise UserInputError(f"{path}: windows file not found")
    try:
        with fits.open(path, memmap=False) as hdul:
            pix = np.asarray(hdul[0].data, dtype=np.float64)
            tab = hdul["WINDOWS"].data
            return pix, np.asarray(tab["COL0"]), np.asarray(tab["ROW0"]), hdul[0].header.copy()
    except Exception as exc:  # noqa: BLE001 - damaged or not a windows file: bad input
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UserInputError(f"{path}: not a readable windows file ({msg})") from None


def frame_bytes(scenario, *, compress: bool = False) -> int:
    """Bytes of one full frame file (uncompressed upper bound: header + padded data)."""
    rows, cols = scenario.detector.mosaic_shape
    per_px = 2 if scenario.detector.bits <= 16 else 4
    block = 2880
    data = -(-rows * cols * per_px // block) * block
    return 2 * block + data


#: float64 work arrays per pixel while one full frame is rendered (expected signal, a
#: fixed-pattern map, the noisy frame): a lower bound, so nothing feasible is refused
FULL_FRAME_WORK_ARRAYS = 3


def check_render_request(scenario, *, frames: int, out, source: str, mode: str = "full",
                         n_stars: int = 0, compress: bool = False, echo=None) -> int:
    """Refuse, before any work, a render that cannot fit in memory or on disk; announce a
    large one. Returns the estimated bytes written.

    Memory: one full frame needs ``FULL_FRAME_WORK_ARRAYS`` float64 arrays of the mosaic
    (windows mode: the float64 window cube of all frames). Disk: ``frames`` frame files of
    :func:`frame_bytes` (an upper bound when compressed) or the uint16 window cube.
    """
    check_allocations(scenario, source=source)  # the PSF's spectrum (simcam.allocation)
    rows, cols = scenario.detector.mosaic_shape
    det = scenario.detector
    if mode == "full":
        check_memory(FULL_FRAME_WORK_ARRAYS * 8.0 * rows * cols,
                     what=f"{source}: detector: one full frame of {rows} x {cols} px "
                          f"({det.n_chips} chips of {det.chip_rows} x {det.chip_cols})")
        need = float(frames) * frame_bytes(scenario, compress=compress)
    else:
        w = scenario.render.window_px
        cube = float(frames) * n_stars * w * w
        check_memory(8.0 * cube, what=f"{source}: --frames {frames} x {n_stars} windows of {w} x {w} px")
        need = 2.0 * cube
    need += float(frames) * max(n_stars, 1) * 200.0  # truth.csv rows, about 200 bytes each
    check_disk(out, need, what=f"--frames {frames} ({mode}{', compressed at most' if compress else ''})")
    announce_size(need, where=out, echo=echo)
    return int(need)
