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
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pandas as pd
from astropy.io import fits

from simcam import __version__
from simcam.cli_common import UserInputError


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
def atomic_directory(out: str | os.PathLike, *, overwrite: bool = False):
    """Yield a temporary directory that replaces ``out`` only if the block completes."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UserInputError(f"--out {out}: exists and is not a directory")
    if out.exists() and any(out.iterdir()) and not overwrite:
        raise UserInputError(f"--out {out}: directory is not empty (use --overwrite to replace it)")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.partial.", dir=out.parent))
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if out.exists():
        shutil.rmtree(out)
    os.replace(tmp, out)


def write_frame(path: str | os.PathLike, data: np.ndarray, header: fits.Header) -> None:
    """Write one mosaic frame as a primary HDU."""
    fits.PrimaryHDU(data=data, header=header).writeto(path, overwrite=False)


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
    """Read a frame (any FITS primary image): data as float64 and its header."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"{path}: frame file not found")
    try:
        with fits.open(path, memmap=False) as hdul:
            data = hdul[0].data
            header = hdul[0].header.copy()
    except OSError as exc:
        raise UserInputError(f"{path}: not a readable FITS file ({exc})") from None
    if data is None or data.ndim != 2:
        raise UserInputError(f"{path}: primary HDU holds no 2-D image")
    return np.asarray(data, dtype=np.float64), header


def read_windows(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, fits.Header]:
    """Read a windows file: pixels (frames, stars, h, w) float64, col0, row0, header."""
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"{path}: windows file not found")
    with fits.open(path, memmap=False) as hdul:
        pix = np.asarray(hdul[0].data, dtype=np.float64)
        tab = hdul["WINDOWS"].data
        return pix, np.asarray(tab["COL0"]), np.asarray(tab["ROW0"]), hdul[0].header.copy()


def read_truth(path: str | os.PathLike) -> pd.DataFrame:
    """Read a truth.csv written by ``simcam render``."""
    return pd.read_csv(path)
