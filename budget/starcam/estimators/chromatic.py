"""Chromatic low-frequency error LSFE-S: seed 000 eqs 13-16 and the "/3" of section 1.4.1
(:func:`chromatic_error`), and the improved variants of docs/estimators.md (chromatic):
uniform and radial parts kept apart (:func:`chromatic_error_decomposed`), and a stellar
population through the camera's spectral response instead of "/2" and "/3"
(:func:`chromatic_error_population`)."""

from __future__ import annotations

from functools import partial
from typing import Any, NamedTuple

import numpy as np
import pandas as pd

from simcam.infra.errors import UserInputError

from .common import _check_plate_scale, _Log, _memo_last, _prepare, _Rows, _unique
from .results import ChromaticEstimate


class _FilterMeans(NamedTuple):
    """What every LSFE-S variant starts from (eqs 13-14): per (field, star) point seen through
    every filter, sorted by field then star, and per filter (sorted), the mean x and y (px)
    and the number of frames; the rows excluded, the points excluded, the reference filter
    and the filter pairs (short, long) the published estimator differences."""

    n_bad: int
    n_excl: int
    filters: np.ndarray
    ref: int
    pairs: list
    field_code: np.ndarray      # each point's field, codes into the sorted field_labels
    field_labels: Any
    star: np.ndarray
    mean_x: np.ndarray          # (points, filters)
    mean_y: np.ndarray
    count: np.ndarray

    def column(self, filter_nm) -> int:
        """The column of filter ``filter_nm`` in the (points, filters) arrays."""
        return int(np.searchsorted(self.filters, filter_nm))

    def stars_per_field(self) -> np.ndarray:
        """Number of points (stars) of each field."""
        return np.unique(self.field_code, return_counts=True)[1]

    def field(self) -> np.ndarray:
        """Each point's field label."""
        return np.asarray(self.field_labels)[self.field_code]


@_memo_last
def _chromatic_means(table, *, reference_filter_nm, what, log) -> _FilterMeans:
    if not isinstance(table, (pd.DataFrame, _Rows)):
        raise UserInputError(f"{what}: expected a pandas DataFrame, got {type(table).__name__}")
    rows, df, n_bad = _prepare(table, required=("star", "field", "filter_nm", "x", "y"),
                               key=tuple(c for c in ("star", "field", "filter_nm", "condition", "frame")
                                         if c in table.columns), what=what, log=log)
    filters = np.unique(df["filter_nm"])
    if filters.size < 2:
        raise UserInputError(f"{what}: needs at least 2 filters in column 'filter_nm', got {filters.tolist()}")
    if reference_filter_nm is None:
        ref = int(filters[(filters.size - 1) // 2])
    else:
        ref = int(reference_filter_nm)
        if ref not in filters:
            raise UserInputError(f"{what}: reference_filter_nm={ref} is not in the data's filters {filters.tolist()}")
    # per (field, star) and filter: mean x, y and count, by bincount on integer codes
    # (every (field, star) pair of the table is kept, sorted, NaN where a filter is missing)
    s_uni, s_codes = _unique(rows["star"], return_inverse=True)
    n_s = len(s_uni)
    present = _unique(rows["field"] * n_s + s_codes.reshape(-1))        # sorted by (field, star)
    point_field, point_star = present // n_s, s_uni[present % n_s]
    row = np.searchsorted(present, df["field"] * n_s + np.searchsorted(s_uni, df["star"]))
    col = np.searchsorted(filters, df["filter_nm"])
    cell = row * filters.size + col
    size = len(present) * filters.size
    count = np.bincount(cell, minlength=size).astype(np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = np.bincount(cell, weights=df["x"], minlength=size) / count
        my = np.bincount(cell, weights=df["y"], minlength=size) / count
    count[count == 0] = np.nan
    mx, my, count = (a.reshape(len(present), filters.size) for a in (mx, my, count))
    complete = np.isfinite(count).all(axis=1)
    n_excl = int((~complete).sum())
    if n_excl:
        lost = [f"{f}/{s}" for f, s in zip(np.asarray(rows.field_labels)[point_field[~complete][:10]],
                                           point_star[~complete][:10].tolist())]
        log.warn(f"{what}: {n_excl} (field, star) pair(s) lack a filter and are excluded ({', '.join(lost)})")
        point_field, point_star, mx, my, count = (a[complete] for a in (point_field, point_star, mx, my, count))
    if not complete.any():
        raise UserInputError(f"{what}: no (field, star) seen through every filter")
    pairs = []
    for f in filters:
        if f == ref:
            continue
        lo, hi = (int(f), ref) if f < ref else (ref, int(f))
        pairs.append((lo, hi))
    return _FilterMeans(n_bad, n_excl, filters, ref, pairs, point_field, rows.field_labels, point_star, mx, my, count)


def chromatic_error(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    reference_filter_nm: int | None = None,
    spectrum_factor: float = 3.0,
) -> ChromaticEstimate:
    """Chromatic low-frequency error LSFE-S as published (seed 000 eqs 13-16).

    Per field ``k`` and filter, per-star means (eqs 13-14). Each filter is paired with
    the reference filter, longer minus shorter wavelength: ``delta_j(600-500) =
    Xbar_600 - Xbar_500``, ``delta_j(800-600) = Xbar_800 - Xbar_600`` (eq 15). Then
    ``delta_bar = sum_k sum_j delta_j / (2 W K)`` (eq 16; ``W K`` = the number of
    (field, star) pairs seen through every filter, K = 4 in the seed). The seed's text:
    the largest ``|delta_bar|`` "divided by 3" approximates the chromatic error of a
    star: ``sigma_LSFE-S = max_pairs |delta_bar| / spectrum_factor`` (px), reported as
    ``3 sigma * plate_scale`` arcsec like every other class. See docs/estimators.md
    for how this reproduces (and does not reproduce) the seed's table 1 and section 2.3.1.

    Any number of filters: each filter but the reference gives one difference (``n - 1`` in
    all), each halved as in eq 16; the "2" of eq 16 is not the seed's count of differences
    (its table 1 gives one ``delta_bar`` per pair), so a two-filter test has one difference,
    divided by ``2 W K`` the same way (docs/validation.md, "Planning the test").

    Parameters
    ----------
    table : pandas.DataFrame
        Columns ``star``, ``field``, ``filter_nm``, ``x``, ``y`` (px), optional
        ``frame``, ``flag``.
    plate_scale_arcsec : float
    reference_filter_nm : int, optional
        Default: the middle filter (the lower middle for an even count).
    spectrum_factor : float
        The seed's 3 (filter band versus stellar spectrum).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` columns: ``pair``, ``filter_short_nm``, ``filter_long_nm``,
        ``delta_bar_x_px``, ``delta_bar_y_px``, ``delta_bar_x_arcsec``,
        ``delta_bar_y_arcsec``.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    if not spectrum_factor > 0:
        raise UserInputError(f"spectrum_factor: must be > 0, got {spectrum_factor}")
    log = _Log()
    fm = _chromatic_means(table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    n_pts = len(fm.star)                              # W * K
    per_field = fm.stars_per_field()
    k = per_field.size
    rows = []
    ax, ay = fm.mean_x, fm.mean_y
    for lo, hi in fm.pairs:
        dxb = float((ax[:, fm.column(hi)] - ax[:, fm.column(lo)]).sum()) / (2.0 * n_pts)
        dyb = float((ay[:, fm.column(hi)] - ay[:, fm.column(lo)]).sum()) / (2.0 * n_pts)
        rows.append({"pair": f"{hi}-{lo}", "filter_short_nm": lo, "filter_long_nm": hi,
                     "delta_bar_x_px": dxb, "delta_bar_y_px": dyb,
                     "delta_bar_x_arcsec": dxb * ps, "delta_bar_y_arcsec": dyb * ps})
    mx = float(np.max(np.abs([r["delta_bar_x_px"] for r in rows])))
    my = float(np.max(np.abs([r["delta_bar_y_px"] for r in rows])))
    return ChromaticEstimate(
        quantity="LSFE-S", method="published", equations="seed 000 eqs 13-16, section 1.4.1",
        sigma_x_px=mx / spectrum_factor, sigma_y_px=my / spectrum_factor, plate_scale_arcsec=ps,
        n_stars=int(per_field.min()), n_frames=int(fm.count.min()), n_conditions=int(k),
        n_stars_excluded=fm.n_excl, n_rows_excluded=fm.n_bad, warnings=tuple(log.messages),
        details={"max_abs_delta_bar_x_px": mx, "max_abs_delta_bar_y_px": my,
                 "max_abs_delta_bar_x_arcsec": mx * ps, "max_abs_delta_bar_y_arcsec": my * ps,
                 "max_over_factor_x_px": mx / spectrum_factor,
                 "max_over_factor_y_px": my / spectrum_factor,
                 "max_over_factor_x_arcsec": mx / spectrum_factor * ps,
                 "max_over_factor_y_arcsec": my / spectrum_factor * ps,
                 "reference_filter_nm": fm.ref, "n_filters": int(fm.filters.size),
                 "n_fields": int(k), "n_field_star_pairs": int(n_pts),
                 "spectrum_factor": float(spectrum_factor)},
        pairs=partial(pd.DataFrame, rows),
    )


def chromatic_error_decomposed(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    reference_filter_nm: int | None = None,
    spectrum_factor: float = 3.0,
    optical_axis_xy: tuple[float, float] | None = None,
) -> ChromaticEstimate:
    """Chromatic error with the uniform and radial (lateral-colour) parts kept apart.

    For each filter pair the signed per-star differences ``d_j`` (eq 15, all fields)
    are fitted by least squares with ``d_j = u + c r_j``, ``r_j`` the star's position
    (reference filter) relative to the optical axis: ``u`` is the field-uniform shift
    (what eq 16 averages), ``c r_j`` the radial lateral colour (linear in field radius),
    which averages to zero over fields placed symmetrically about the axis and so
    escapes eq 16 (docs/estimators.md, chromatic). The error of a star is the rms over
    the measured positions of ``u + c r_j`` per axis; as in the seed it is halved
    (shift from the midpoint of the band pair) and divided by ``spectrum_factor``;
    ``sigma`` is the largest over the pairs.

    Parameters
    ----------
    table, plate_scale_arcsec, reference_filter_nm, spectrum_factor
        As in :func:`chromatic_error`.
    optical_axis_xy : (float, float), optional
        Optical axis on the mosaic (px); default: the mean position of all measured
        stars (the centre of symmetrically placed fields).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` columns: ``pair``, ``filter_short_nm``, ``filter_long_nm``,
        ``uniform_x_px``, ``uniform_y_px``, ``radial_coefficient`` (px per px of field
        radius), ``radial_shift_at_mean_radius_px``, ``fit_residual_rms_px``,
        ``rms_x_px``, ``rms_y_px``.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    if not spectrum_factor > 0:
        raise UserInputError(f"spectrum_factor: must be > 0, got {spectrum_factor}")
    log = _Log()
    fm = _chromatic_means(table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    n_pts = len(fm.star)
    if n_pts < 3:
        raise UserInputError(f"LSFE-S: the decomposition needs 3+ (field, star) points, got {n_pts}")
    px = fm.mean_x[:, fm.column(fm.ref)]
    py = fm.mean_y[:, fm.column(fm.ref)]
    if optical_axis_xy is None:
        ax0, ay0 = float(px.mean()), float(py.mean())
    else:
        ax0, ay0 = (float(v) for v in optical_axis_xy)
    rx, ry = px - ax0, py - ay0
    rmean = float(np.mean(np.hypot(rx, ry)))
    if not rmean > 0:
        raise UserInputError("LSFE-S: all stars sit on the optical axis; no radial part to fit")
    # stacked system [dx; dy] = [[1, 0, rx], [0, 1, ry]] @ (ux, uy, c)
    a = np.zeros((2 * n_pts, 3))
    a[:n_pts, 0] = 1.0
    a[n_pts:, 1] = 1.0
    a[:n_pts, 2] = rx
    a[n_pts:, 2] = ry
    rows = []
    for lo, hi in fm.pairs:
        dx = fm.mean_x[:, fm.column(hi)] - fm.mean_x[:, fm.column(lo)]
        dy = fm.mean_y[:, fm.column(hi)] - fm.mean_y[:, fm.column(lo)]
        b = np.concatenate([dx, dy])
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        ux, uy, c = (float(v) for v in coef)
        res = b - a @ coef
        mod_x, mod_y = ux + c * rx, uy + c * ry
        rows.append({"pair": f"{hi}-{lo}", "filter_short_nm": lo, "filter_long_nm": hi,
                     "uniform_x_px": ux, "uniform_y_px": uy, "radial_coefficient": c,
                     "radial_shift_at_mean_radius_px": c * rmean,
                     "fit_residual_rms_px": float(np.sqrt(np.mean(res**2))),
                     "rms_x_px": float(np.sqrt(np.mean(mod_x**2))),
                     "rms_y_px": float(np.sqrt(np.mean(mod_y**2)))})
    sx = float(np.max([r["rms_x_px"] for r in rows])) / (2.0 * spectrum_factor)
    sy = float(np.max([r["rms_y_px"] for r in rows])) / (2.0 * spectrum_factor)
    per_field = fm.stars_per_field()
    k = per_field.size
    return ChromaticEstimate(
        quantity="LSFE-S", method="decomposed", equations="docs/estimators.md (chromatic decomposed)",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=int(per_field.min()), n_frames=int(fm.count.min()), n_conditions=int(k),
        n_stars_excluded=fm.n_excl, n_rows_excluded=fm.n_bad, warnings=tuple(log.messages),
        details={"reference_filter_nm": fm.ref, "optical_axis_x_px": ax0, "optical_axis_y_px": ay0,
                 "mean_field_radius_px": rmean, "n_fields": int(k),
                 "spectrum_factor": float(spectrum_factor)},
        pairs=partial(pd.DataFrame, rows),
    )


def chromatic_error_population(
    table: pd.DataFrame,
    *,
    plate_scale_arcsec: float,
    filter_wavelength_nm: dict,
    star_wavelengths_nm: Any,
    calibration_wavelength_nm: float,
    reference_filter_nm: int | None = None,
) -> ChromaticEstimate:
    """LSFE-S for a stellar population, from the filter measurements (improved variant).

    The centroid of a polychromatic image moves by the spectrum-weighted mean of the
    per-wavelength lateral shifts; for lateral colour linear in wavelength that is the
    shift at the image's electron-weighted mean wavelength ``lambda_bar``. So each
    (field, star)'s filter means are fitted with ``X = a + b lambda_bar_f`` (least
    squares over the filters, ``lambda_bar_f`` the effective wavelength of the lamp
    through filter ``f``, optics and QE), the slopes are averaged per field (``b_F``,
    its mean square debiased by the slopes' sampling variance over the field's ``W``
    stars), and a star of effective wavelength ``lambda_p`` is displaced from the
    calibration spectrum's position by ``b_F (lambda_p - lambda_cal)``. The error is the
    rms over the population and the fields, per axis (docs/estimators.md, chromatic
    population). It replaces
    the seed's "/2" and "/3" by the camera's own spectral response: the effective
    wavelengths are design data (filters, lamp, optics transmission, QE, stellar types).
    Two filters determine the line exactly (the slope is their difference over their
    effective-wavelength separation, so whatever else differs between them is read as
    lateral colour, amplified by one over that separation: docs/validation.md, "Planning
    the test"); more are a least-squares fit.

    Parameters
    ----------
    table : pandas.DataFrame
        As for :func:`chromatic_error`.
    plate_scale_arcsec : float
    filter_wavelength_nm : dict
        Filter centre (as in ``filter_nm``) -> effective wavelength of the lamp through it, nm.
    star_wavelengths_nm : array_like
        Effective wavelengths of the stellar population (one per star type), nm.
    calibration_wavelength_nm : float
        Effective wavelength of the calibration spectrum (e.g. the unfiltered lamp), nm.
    reference_filter_nm : int, optional
        As in :func:`chromatic_error` (only checked here; every filter enters the fit).

    Returns
    -------
    ChromaticEstimate
        ``pairs`` holds one row per (field, star): slopes ``b_x``, ``b_y`` in px/nm.
    """
    ps = _check_plate_scale(plate_scale_arcsec)
    lam_p = np.asarray(star_wavelengths_nm, dtype=float).ravel()
    if lam_p.size == 0 or not np.isfinite(lam_p).all():
        raise UserInputError("star_wavelengths_nm: needs one or more finite wavelengths")
    log = _Log()
    fm = _chromatic_means(table, reference_filter_nm=reference_filter_nm, what="LSFE-S", log=log)
    filters = fm.filters
    missing = [int(f) for f in filters if int(f) not in {int(k) for k in filter_wavelength_nm}]
    if missing:
        raise UserInputError(f"filter_wavelength_nm: no effective wavelength for filter(s) {missing}")
    lam_f = np.array([float({int(k): v for k, v in filter_wavelength_nm.items()}[int(f)]) for f in filters])
    a = np.column_stack([np.ones_like(lam_f), lam_f - lam_f.mean()])
    pinv = np.linalg.pinv(a)
    # (filters, points), C-ordered: the layout the product's rounding was recorded with
    bx = (pinv @ np.ascontiguousarray(fm.mean_x.T))[1]
    by = (pinv @ np.ascontiguousarray(fm.mean_y.T))[1]
    dl = lam_p - float(calibration_wavelength_nm)
    # Per field, the slope is averaged over its stars (lateral colour varies little across
    # one target); the mean square of that average is debiased by its sampling variance
    # s_b^2 / W (temporal noise in the filter means), clipped at 0.
    fcode = np.unique(fm.field_code, return_inverse=True)[1]
    cnt = np.bincount(fcode).astype(float)
    msq = {}
    for ax, b in (("x", bx), ("y", by)):
        mean_b = np.bincount(fcode, weights=b) / cnt
        ss = np.bincount(fcode, weights=(b - mean_b[fcode]) ** 2)
        var_b = np.where(cnt > 1, ss / np.maximum(cnt - 1.0, 1.0), 0.0) / cnt   # s_b^2 / W (0 for W = 1)
        msq[ax] = np.clip(mean_b**2 - var_b, 0.0, None)
    sx = float(np.sqrt(np.mean(msq["x"]) * np.mean(dl**2)))
    sy = float(np.sqrt(np.mean(msq["y"]) * np.mean(dl**2)))
    per_field = fm.stars_per_field()
    return ChromaticEstimate(
        quantity="LSFE-S", method="population", equations="docs/estimators.md (chromatic population)",
        sigma_x_px=sx, sigma_y_px=sy, plate_scale_arcsec=ps,
        n_stars=int(per_field.min()), n_frames=int(fm.count.min()), n_conditions=int(per_field.size),
        n_stars_excluded=fm.n_excl, n_rows_excluded=fm.n_bad, warnings=tuple(log.messages),
        details={"calibration_wavelength_nm": float(calibration_wavelength_nm),
                 "population_wavelengths_nm": lam_p.tolist(),
                 "filter_effective_wavelengths_nm": lam_f.tolist(),
                 "mean_slope_x_px_per_nm": float(bx.mean()), "mean_slope_y_px_per_nm": float(by.mean())},
        pairs=partial(pd.DataFrame, {"field": fm.field(), "star": fm.star, "b_x_px_per_nm": bx,
                                     "b_y_px_per_nm": by}),
    )
