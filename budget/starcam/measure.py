"""`budget starcam measure PROTOCOL DIR`: the lab's estimators on real (or simulated) FITS frames.

The directory holds FITS frames and a manifest that says which file is which condition.
Manifest (``manifest.csv`` in DIR, or ``--manifest FILE``), one row per frame::

    file,condition,frame,filter_nm,field,dark
    frame_0000.fits,0,0,,,0
    ...

* ``file`` (required): FITS file name relative to DIR (primary HDU, a 2-D image in DN);
  several rows may name one multi-frame file only in the simulator's windows format, so
  for real data keep one frame per file;
* ``condition`` (required): integer condition index (HSFE pose 0..M-1; chromatic: any
  integer per field x filter; TE, distortion: 0);
* ``frame`` (optional): frame number within the condition (default: order of the rows);
* ``filter_nm`` (chromatic: required): centre wavelength of the filter;
* ``field`` (chromatic: required): name of the field (e.g. ``upper-left``);
* ``dark`` (optional, 0/1): a star-free frame (lamp off or shutter closed) of that
  condition; the mean of a condition's dark frames is subtracted from its lit frames
  (seed 000's inter-frame differencing). Dark rows with an empty condition apply to all.

Distortion also needs the grid target's reference coordinates, ``--reference FILE`` (CSV
with columns ``star,x_ref,y_ref`` in mosaic px); stars are identified with the nearest
reference point. Elsewhere stars are numbered in raster order (by row of 40 px bands, then
x) of the first frame of the first condition, and followed through conditions by nearest
position (HSFE moves them by a fraction of a pixel per condition; chromatic fields are
numbered each in their own raster order).
"""

from __future__ import annotations

import math
import warnings
from contextlib import contextmanager
from pathlib import Path

import click
import numpy as np
import pandas as pd

from simcam.allocation import check_window
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import progress as progress_bar
from simcam.infra.outputs import (CommandInputs, StagedOutputs, apply_umask, check_run_outputs, command_inputs,
                                  input_file_problem)
from simcam.starcam.scenario import ValidationModel
from simcam.units import ARCSEC_PER_DEG

MANIFEST_COLUMNS = ("file", "condition", "frame", "filter_nm", "field", "dark")
#: the centroid threshold (noise sigmas) of budget validate's default scenario: one path
DEFAULT_THRESHOLD_SIGMA = float(ValidationModel.model_fields["threshold_sigma"].default)


def read_manifest(path: str | Path, *, protocol: str) -> pd.DataFrame:
    """Read and validate a manifest CSV (see module docstring)."""
    path = Path(path)
    if (why := input_file_problem(path)) is not None:  # a FIFO would block, /dev/null read as empty
        raise UserInputError(f"{path}: {why}")
    if not path.is_file():
        raise UserInputError(f"{path}: manifest not found (write manifest.csv in the frame directory "
                             "or pass --manifest; see `budget starcam measure --help`)")
    try:
        m = pd.read_csv(path, dtype={"file": str, "field": str}, encoding="utf-8")
    except pd.errors.EmptyDataError:
        raise UserInputError(f"{path}: empty manifest (expected a header line: {','.join(MANIFEST_COLUMNS)})") from None
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}): is this a manifest CSV?") from None
    except (pd.errors.ParserError, ValueError, OverflowError) as exc:
        raise UserInputError(f"{path}: not a readable CSV ({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    unknown = [c for c in m.columns if c not in MANIFEST_COLUMNS]
    if unknown:
        raise UserInputError(f"{path}: unknown column(s) {', '.join(unknown)} (allowed: {', '.join(MANIFEST_COLUMNS)})")
    for c in ("file", "condition"):
        if c not in m.columns:
            raise UserInputError(f"{path}: missing column {c!r}")
    if m.empty:
        raise UserInputError(f"{path}: no rows")
    if m["file"].isna().any():
        raise UserInputError(f"{path}: row {int(np.flatnonzero(m['file'].isna())[0]) + 2}: empty file name")
    if m.duplicated().any():  # the same frame twice would be measured twice
        row = int(np.flatnonzero(m.duplicated())[0])
        text = m.astype(str)  # NaN equal to NaN
        first = int(np.flatnonzero((text == text.iloc[row]).all(axis=1))[0])
        raise UserInputError(f"{path}: row {row + 2} repeats row {first + 2} ({m['file'].iloc[row]}); "
                             "list each frame once")
    for c in ("dark", "frame", "filter_nm"):
        if c in m.columns:
            v = pd.to_numeric(m[c], errors="coerce")
            bad = (v.isna() & m[c].notna()) | ~np.isfinite(v.fillna(0).astype(float))
            if c != "filter_nm":
                bad |= v.notna() & (v != np.round(v.fillna(0)))
            if c == "dark":
                bad |= v.notna() & ~v.isin([0, 1])
            if bad.any():
                row = int(np.flatnonzero(bad)[0])
                want = {"dark": "0 or 1", "frame": "an integer", "filter_nm": "a finite number (nm)"}[c]
                raise UserInputError(f"{path}: row {row + 2}: {c} must be {want}, got {m[c].iloc[row]!r}")
            m[c] = v
    m["dark"] = m["dark"].fillna(0).astype(int) if "dark" in m.columns else 0
    lit = m["dark"] == 0
    cond = pd.to_numeric(m["condition"], errors="coerce")
    bad = lit & (cond.isna() | (cond != np.round(cond)))
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise UserInputError(f"{path}: row {row + 2}: condition must be an integer, got {m['condition'].iloc[row]!r}")
    m["condition"] = cond.astype("Int64")
    if protocol == "chromatic":
        for c in ("filter_nm", "field"):
            if c not in m.columns or m.loc[lit, c].isna().any():
                raise UserInputError(f"{path}: chromatic needs column {c!r} on every lit frame")
    if "frame" not in m.columns:
        m["frame"] = m.groupby(["condition", "dark"]).cumcount()
    return m


def dataset_inputs(protocol: str, directory: str | Path, *, manifest: str | Path | None = None,
                   reference: str | Path | None = None, allow_outside: bool = False) -> CommandInputs:
    """Every file ``measure`` reads: the manifest, each frame it lists (lit and dark) and the
    reference table; no output may be one of them (:mod:`simcam.infra.outputs`). The manifest
    is read and checked here (a bad one is refused before anything else)."""
    directory = Path(directory)
    if not directory.is_dir():
        raise UserInputError(f"{directory}: frame directory not found")
    mpath = Path(manifest) if manifest else directory / "manifest.csv"
    m = read_manifest(mpath, protocol=protocol)
    _confine(m, directory, mpath, allow_outside=allow_outside)
    return command_inputs(mpath, reference, [directory / str(f) for f in m["file"]])


def _confine(m: pd.DataFrame, directory: Path, manifest, *, allow_outside: bool) -> None:
    """Refuse manifest entries that lead out of the dataset folder (unless allowed)."""
    root = directory.resolve()
    for i, f in enumerate(m["file"]):
        try:
            target = (directory / str(f)).resolve()
        except (ValueError, OSError, RuntimeError) as exc:  # NUL byte, symlink loop
            raise UserInputError(f"{manifest}: row {i + 2}: file {f!r} is not a usable path ({exc})") from None
        if not allow_outside and target != root and root not in target.parents:
            raise UserInputError(f"{manifest}: row {i + 2}: file {f!r} is outside the dataset folder {directory} "
                                 "(pass --allow-outside-files to read it anyway)")


def _check_pixels(path, data: np.ndarray) -> None:
    """A NaN pixel is a marked bad pixel: the star it touches is flagged and left out (the
    documented rule). An infinite pixel, or a whole row or column of NaN, is no camera
    frame: centroids and noise over them are meaningless, so the frame is refused."""
    inf = np.isinf(data)
    if inf.any():
        r, c = np.argwhere(inf)[0]
        raise UserInputError(f"{path}: {int(inf.sum())} infinite pixel(s) (first at row {r}, column {c}); "
                             "a camera frame has none")
    nan = np.isnan(data)
    if nan.any():
        rows, cols = np.flatnonzero(nan.all(axis=1)), np.flatnonzero(nan.all(axis=0))
        if rows.size or cols.size:
            what = f"row {rows[0]}" if rows.size else f"column {cols[0]}"
            raise UserInputError(f"{path}: {rows.size} row(s) and {cols.size} column(s) entirely NaN (first: "
                                 f"{what}); mark bad pixels one by one, not whole lines")


def _load(directory: Path, files, scale: dict) -> list[np.ndarray]:
    """The frames ``files`` of ``directory``, checked: finite pixels, one shape, and one plate
    scale (``scale`` holds the first frame's header ``PLTSCALE`` and file: frames of two
    plate scales measured with one would scale every estimate wrongly)."""
    from simcam.io import read_frame

    out = []
    shape = None
    for f in files:
        data, header = read_frame(directory / f)
        _check_pixels(directory / f, data)
        if shape is not None and data.shape != shape:
            raise UserInputError(f"{directory / f}: shape {data.shape} differs from the first frame's {shape}")
        shape = data.shape
        _check_plate_scale(directory / f, header.get("PLTSCALE"), scale)
        out.append(data)
    return out


def _check_plate_scale(path: Path, value, scale: dict) -> None:
    """Refuse a frame whose header ``PLTSCALE`` differs from the first frame's that has one."""
    if value is None:
        return
    if "value" not in scale:
        scale.update(value=value, file=path)
    elif value != scale["value"]:
        raise UserInputError(f"{path}: header PLTSCALE = {value!r} differs from {scale['file']}'s "
                             f"{scale['value']!r}; the frames of one dataset have one plate scale")


def _read_reference(reference) -> pd.DataFrame:
    """The distortion protocol's ``--reference`` table (star, x_ref, y_ref; finite positions)."""
    if reference is None:
        raise UserInputError("distortion: --reference FILE (star,x_ref,y_ref) is required")
    rp = Path(reference)
    if (why := input_file_problem(rp)) is not None:
        raise UserInputError(f"--reference {rp}: {why}")
    if not rp.is_file():
        raise UserInputError(f"{rp}: reference file not found")
    try:
        ref_table = pd.read_csv(rp, encoding="utf-8")
    except (pd.errors.EmptyDataError, pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise UserInputError(f"{rp}: not a readable CSV table ({str(exc).splitlines()[0] if str(exc) else ''})") from None
    miss = [c for c in ("star", "x_ref", "y_ref") if c not in ref_table.columns]
    if miss:
        raise UserInputError(f"{rp}: missing column(s) {', '.join(miss)}")
    for c in ("x_ref", "y_ref"):
        v = pd.to_numeric(ref_table[c], errors="coerce")
        if not np.isfinite(v.to_numpy(float)).all():
            row = int(np.flatnonzero(~np.isfinite(v.to_numpy(float)))[0])
            raw = ref_table[c].iloc[row]
            got = "an empty cell" if pd.isna(raw) else repr(str(raw))
            raise UserInputError(f"{rp}: row {row + 2}: {c} must be a finite number, got {got}")
        ref_table[c] = v
    return ref_table


def _method_options(method: str, weight_sigma_px) -> dict:
    """The centroid method's own options: IWCoG needs the PSF's Gaussian sigma."""
    if method != "iwcog":
        return {}
    if weight_sigma_px is None:
        raise UserInputError("--method iwcog needs --weight-sigma-px (the PSF's Gaussian sigma, px)")
    return {"weight_sigma_px": float(weight_sigma_px)}


def _check_condition_count(mpath, protocol: str, conditions: list) -> None:
    """TE and distortion take one condition, HSFE at least two (hexapod poses)."""
    if protocol in ("te", "distortion") and len(conditions) != 1:
        raise UserInputError(f"{mpath}: {protocol}: expected one condition, the manifest has {len(conditions)}")
    if protocol == "hsfe" and len(conditions) < 2:
        raise UserInputError(f"{mpath}: hsfe: needs at least 2 conditions (hexapod poses), the manifest has {len(conditions)}")


def _adc_max(path, header) -> int | None:
    """The ADC's largest value from the frame's ``BITDEPTH`` keyword (None without one)."""
    try:
        return 2 ** int(header["BITDEPTH"]) - 1 if "BITDEPTH" in header else None
    except (TypeError, ValueError, OverflowError):
        raise UserInputError(f"{path}: header BITDEPTH = {header['BITDEPTH']!r} is not a number of bits") from None


def _check_condition_rows(mpath, cond, rows: pd.DataFrame) -> None:
    """A condition has at least 2 lit frames, each frame number once."""
    if len(rows) < 2:
        raise UserInputError(f"{mpath}: condition {cond}: {len(rows)} frame(s) "
                             f"({', '.join(map(str, rows['file']))}); at least 2 are needed")
    if rows["frame"].duplicated().any():
        dup = rows[rows["frame"].duplicated(keep=False)]
        raise UserInputError(f"{mpath}: condition {cond}: frame {int(dup['frame'].iloc[0])} listed twice (rows "
                             f"{', '.join(str(int(i) + 2) for i in dup.index[:2])}: "
                             f"{', '.join(map(str, dup['file'].iloc[:2]))})")


@contextmanager
def _frame_context(path, cond):
    """The centroid core names its own arguments (``noise_dn``, ``threshold_dn``), which
    are no options of this command: say which frame and condition, and what it means."""
    try:
        yield
    except UserInputError as exc:
        if str(exc).startswith("noise_dn:"):
            raise UserInputError(f"{path}: condition {cond}: the frames' noise is zero (constant pixels); no star "
                                 "can be told from the background") from None
        raise


def _raster_order(xy: np.ndarray, band_px: float = 40.0) -> np.ndarray:
    return np.lexsort((xy[:, 0], np.round(xy[:, 1] / band_px)))


def measure_frames(
    protocol: str,
    directory: str | Path,
    *,
    manifest: str | Path | None = None,
    reference: str | Path | None = None,
    method: str = "cog",
    window_px: int = 11,
    threshold_sigma: float = DEFAULT_THRESHOLD_SIGMA,
    match_radius_px: float = 3.0,
    saturation_dn: float | None = None,
    weight_sigma_px: float | None = None,
    allow_outside: bool = False,
    progress: bool = False,
) -> tuple[pd.DataFrame, pd.DataFrame | None, dict]:
    """Centroid the frames of DIR per its manifest; return (centroids, reference, header info).

    Manifest entries must name files inside DIR (no absolute paths, no ``..`` out of it,
    no symbolic link leading out) unless ``allow_outside``.

    ``threshold_sigma`` is the centroid threshold in the windows (default the same as
    ``budget validate``'s, ``validation.threshold_sigma``). Stars are found on the mean of
    a condition's frames (dark subtracted) with :func:`budget.centroid.frames.detect_stars`'s own
    detection threshold, so a noise excursion of one frame cannot become a "star" that
    then enters an estimate (at 3 sigma on single frames two spurious stars
    turned TE y into 0.77" instead of 0.20").
    """
    from budget.centroid.core import subtract_dark
    from budget.centroid.frames import centroid_frames, detect_stars
    from simcam.io import read_frame

    directory = Path(directory)
    if not directory.is_dir():
        raise UserInputError(f"{directory}: frame directory not found")
    method_options = _method_options(method, weight_sigma_px)
    mpath = manifest or directory / "manifest.csv"
    m = read_manifest(mpath, protocol=protocol)
    _confine(m, directory, mpath, allow_outside=allow_outside)
    lit = m[m["dark"] == 0]
    conditions = sorted(lit["condition"].dropna().unique().tolist())
    _check_condition_count(mpath, protocol, conditions)
    _, header = read_frame(directory / lit["file"].iloc[0])
    adc_max = _adc_max(directory / lit["file"].iloc[0], header)
    ref_table = None
    ref_xy_by_field: dict = {}
    if protocol == "distortion":
        ref_table = _read_reference(reference)
    tables = []
    prev_xy = None
    scale: dict = {}  # the first header PLTSCALE and its file: every frame must have the same
    bar = progress_bar(total=len(m), desc="frames", unit="frame", enabled=progress)
    for cond in conditions:
        rows = lit[lit["condition"] == cond].sort_values("frame")
        _check_condition_rows(mpath, cond, rows)
        frames = _load(directory, rows["file"], scale)
        darks = m[(m["dark"] == 1) & ((m["condition"] == cond) | m["condition"].isna())]
        dark = np.mean(_load(directory, darks["file"], scale), axis=0) if len(darks) else None
        stack = np.mean(np.asarray(frames, dtype=np.float64), axis=0)
        first = subtract_dark(stack, dark=dark) if dark is not None else stack
        field = str(rows["field"].iloc[0]) if "field" in rows.columns and protocol == "chromatic" else ""
        if protocol == "distortion":
            ref_xy = ref_table[["x_ref", "y_ref"]].to_numpy(float)
        elif protocol == "chromatic" and field in ref_xy_by_field:
            ref_xy = ref_xy_by_field[field]
        elif protocol == "hsfe" and prev_xy is not None:
            ref_xy = prev_xy
        else:
            with _frame_context(directory / rows["file"].iloc[0], cond):
                det = detect_stars(first)
            if det.empty:
                raise UserInputError(f"{directory / rows['file'].iloc[0]}: condition {cond}: no star "
                                     f"detected in the mean of its frames")
            xy = det[["x_peak", "y_peak"]].to_numpy(float)
            ref_xy = xy[_raster_order(xy)]
        extra = {"condition": int(cond)}
        if protocol == "chromatic":
            extra["filter_nm"] = float(rows["filter_nm"].iloc[0])
            extra["field"] = field
        with _frame_context(directory / rows["file"].iloc[0], cond):
            t = centroid_frames(
                frames, dark=dark, reference_xy=ref_xy, frame_ids=rows["frame"].astype(int).tolist(),
                window_size_px=window_px, threshold_sigma=threshold_sigma, match_radius_px=match_radius_px,
                method=method, saturation_dn=saturation_dn, adc_max_dn=adc_max, extra_columns=extra,
                **method_options,
            )
        if protocol == "chromatic" and field not in ref_xy_by_field:
            ref_xy_by_field[field] = ref_xy
        if protocol == "hsfe":
            good = t[t["flag"] == 0].groupby("star")[["x", "y"]].mean()
            prev_xy = ref_xy.copy()
            prev_xy[good.index.to_numpy()] = good.to_numpy()
        tables.append(t)
        bar.update(len(rows) + len(darks))
    bar.close()
    info = {"plate_scale_arcsec": header.get("PLTSCALE"), "files": int(len(m)),
            "plate_scale_file": str(directory / lit["file"].iloc[0])}
    return pd.concat(tables, ignore_index=True), ref_table, info


def format_estimates(protocol: str, results: dict) -> str:
    """Readable table of an estimate per variant: px (1 sigma) and arcsec (3 sigma) per axis."""
    head = ("variant", "quantity", "x px (1s)", "y px (1s)", 'x 3s (")', 'y 3s (")')
    lines = ["{:<10} {:<9} {:>11} {:>11} {:>10} {:>10}  W  N  M  excluded".format(*head),
             "-" * 86]
    for name, r in results.items():
        lines.append(
            f"{name:<10} {r.quantity:<9} {r.sigma_x_px:>11.5f} {r.sigma_y_px:>11.5f} "
            f"{r.x_3sigma_arcsec:>10.3f} {r.y_3sigma_arcsec:>10.3f} {r.n_stars:>2} {r.n_frames:>2} "
            f"{r.n_conditions:>2}  {r.n_stars_excluded} stars, {r.n_rows_excluded} rows"
        )
    for name, r in results.items():
        for w in r.warnings:
            lines.append(f"warning ({name}): {w}")
    return "\n".join(lines)


@click.command("measure")
@click.argument("protocol", type=click.Choice(["te", "hsfe", "chromatic", "distortion"]))
@click.argument("directory", type=click.Path(file_okay=False))
@click.option("--manifest", type=click.Path(dir_okay=False), help="Manifest CSV (default DIR/manifest.csv).")
@click.option("--reference", type=click.Path(dir_okay=False),
              help="Distortion: CSV star,x_ref,y_ref of the grid target (mosaic px).")
@click.option("--plate-scale", "plate_scale", type=click.FloatRange(min=0, min_open=True),
              help="arcsec per px (default: the PLTSCALE header keyword).")
@click.option("--method", type=click.Choice(["cog", "iwcog", "gauss"]), default="cog", show_default=True,
              help="Centroid estimator (cog is seed 000's).")
@click.option("--weight-sigma-px", type=click.FloatRange(min=0, min_open=True), default=None,
              help="IWCoG: width of the Gaussian weight (the PSF's sigma), px.")
@click.option("--window", "window_px", type=click.IntRange(min=3), default=11, show_default=True)
@click.option("--threshold-sigma", type=click.FloatRange(min=0, min_open=True), default=DEFAULT_THRESHOLD_SIGMA,
              show_default=True, help="Centroid threshold in the windows, in noise sigmas (as budget validate).")
@click.option("--saturation-dn", type=float, default=None, help="Flag pixels at or above this level.")
@click.option("--marker-3sigma", "marker_3sigma", type=click.FloatRange(min=0), default=0.0, show_default=True,
              help="Distortion: the grid target's marker calibration error, arcsec 3 sigma (seed 000's C2), "
                   "removed from the improved (after-calibration) LSFE-C1.")
@click.option("--centroids", "centroids_out", type=click.Path(dir_okay=False), help="Write the centroid table (CSV).")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), help="Write the estimates as JSON.")
@click.option("--allow-outside-files", "allow_outside", is_flag=True,
              help="Let manifest entries name files outside DIRECTORY (absolute paths, '..').")
@click.option("--progress/--no-progress", default=True, show_default=True,
              help="Progress bar on stderr (only on a terminal).")
def measure_command(protocol, directory, manifest, reference, plate_scale, method, weight_sigma_px, window_px,
                    threshold_sigma, saturation_dn, marker_3sigma, centroids_out, json_out, allow_outside,
                    progress) -> None:
    """Centroid the FITS frames in DIRECTORY and run the PROTOCOL's estimators (published and improved)."""
    from budget.starcam.protocols import estimate

    if window_px % 2 == 0:
        raise UserInputError(f"--window {window_px}: must be odd")
    check_window(window_px)  # one window per star and frame must fit (simcam.allocation)
    # before any frame is read: the outputs are files (not a device), none of the inputs (the
    # manifest, the frames it lists, the reference), in a writable folder
    inputs = dataset_inputs(protocol, directory, manifest=manifest, reference=reference, allow_outside=allow_outside)
    check_run_outputs(json_out=json_out, files={"--centroids": centroids_out}, inputs=inputs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cen, ref, info = measure_frames(protocol, directory, manifest=manifest, reference=reference, method=method,
                                        window_px=window_px, threshold_sigma=threshold_sigma,
                                        saturation_dn=saturation_dn, weight_sigma_px=weight_sigma_px,
                                        allow_outside=allow_outside, progress=progress)
        ps = plate_scale if plate_scale is not None else header_plate_scale(info)
        results = estimate(protocol, cen, plate_scale_arcsec=float(ps), reference=ref,
                           marker_3sigma_arcsec=marker_3sigma)
    # centroid warnings (flagged stars) are printed here; estimator warnings are in the table
    from budget.centroid.core import CentroidWarning

    for w in caught:
        if issubclass(w.category, CentroidWarning):
            click.echo(f"warning: {w.message}", err=True)
    click.echo(f"{protocol}: {info['files']} files, {cen['star'].nunique()} stars, "
               f"{cen['condition'].nunique()} condition(s), plate scale {float(ps):g} arcsec/px, centroid {method}")
    click.echo(format_estimates(protocol, results))
    with StagedOutputs() as staged:  # both outputs or neither
        _write_measure_outputs(staged, cen, results, protocol, directory, method, ps, centroids_out, json_out)


def header_plate_scale(info: dict) -> float:
    """The plate scale from the first frame's PLTSCALE keyword: a finite positive number of
    arcsec/px, else one error naming the file (was: a traceback for ``'abc'``, an error
    without the file for 0)."""
    raw, where = info.get("plate_scale_arcsec"), info.get("plate_scale_file", "the first frame")
    if raw is None:
        raise UserInputError(f"{where}: no PLTSCALE keyword in the header; pass --plate-scale (arcsec/px)")
    try:
        ps = float(raw)
    except (TypeError, ValueError):
        ps = float("nan")
    if isinstance(raw, bool) or not math.isfinite(ps) or ps <= 0 or ps > ARCSEC_PER_DEG * 360:
        raise UserInputError(f"{where}: header PLTSCALE = {raw!r} is not a positive number of arcsec/px "
                             "(pass --plate-scale to give it)")
    return ps


def _write_measure_outputs(staged, cen, results, protocol, directory, method, ps, centroids_out, json_out):
    if centroids_out:
        tmp = staged.file(centroids_out)
        cen.to_csv(tmp, index=False)
        apply_umask(tmp, is_dir=False)
    if json_out:
        write_json_atomic(staged.file(json_out), {"protocol": protocol, "directory": str(directory), "method": method,
                                     "plate_scale_arcsec": float(ps),
                                     "estimates": {k: v.to_dict() for k, v in results.items()}})
