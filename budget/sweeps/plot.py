"""``budget plot STORE``: the results of a sweep as figures.

* one figure per swept parameter: each error class against the parameter, the truth as a
  line (with a band of +-2 Monte Carlo standard errors where it has one) and, for a
  validation sweep, the mean estimate of each variant with error bars of +-2 Monte Carlo
  standard errors and a shaded band of +-1 spread (what one lab measurement scatters
  by). In a 2-D sweep the other parameter's values are the colours (one variant);
* 2-D (and larger) product sweeps: heatmaps of the truth of each class, and of the bias
  of a variant, over the first two parameters (any further ones at their first value);
* a validation sweep: the relative spread (spread / |mean|, the precision of one
  measurement) against each parameter, with ``--precision`` drawn and the first value
  from which each class and variant stays within it printed;
* a sweep with ``[sensitivity]``: the Sobol indices (first order and total, with their
  confidence intervals) of each class, as bars per parameter.
"""

from __future__ import annotations

import functools
import math
import re
import shutil
import textwrap
from pathlib import Path

import click
import numpy as np

from budget.figures import figure_markdown, save
from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.sweeps.layout import study_for_kind
from budget.sweeps.store import open_sobol, open_sweep
from simcam.infra.cli import overwrite_option
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_output_dir, is_earlier_plots, naming_failed_writes

__all__ = ["plot_command", "plot_store", "precision_table"]

VARIANT_STYLE = {"published": ("C0", "o"), "improved": ("C3", "s")}


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name.replace("*", "all"))


def _x_axes(ds):
    """(dimension, x coordinate name) pairs to plot against."""
    dims = list(ds.attrs.get("point_dims", []))
    if dims == ["point"]:
        return [("point", ds.attrs["parameters"][0])]
    return [(d, d) for d in dims if ds.sizes[d] > 1]


def _panels(n: int):
    import matplotlib.pyplot as plt

    ncol = min(4, n)
    nrow = math.ceil(n / ncol)
    # at least 6 inches wide: the suptitle (title, axis, notes) must fit over one panel
    fig, axes = plt.subplots(nrow, ncol, figsize=(max(3.6 * ncol, 6.0), 3.0 * nrow), squeeze=False)
    for k in range(n, nrow * ncol):
        axes.flat[k].set_visible(False)
    return fig, list(axes.flat)


def _suptitle(fig, text: str, fontsize: float = 9) -> None:
    """A figure title wrapped to the figure's width (a long sweep title is cut otherwise)."""
    width_chars = max(40, int(fig.get_figwidth() * 72 / (0.55 * fontsize)))
    lines = [textwrap.fill(line, width_chars) for line in text.split("\n")]
    fig.suptitle("\n".join(lines), fontsize=fontsize)


def _legend_first(axes, **kw) -> None:
    """Legend on the first panel that has labelled artists (none: no legend)."""
    for ax in axes:
        if ax.get_visible() and ax.get_legend_handles_labels()[0]:
            ax.legend(**kw)
            return


def _fixed_note(ds, keep: list[str]) -> tuple[dict, str]:
    """Select index 0 of every point dimension not in ``keep``; and a caption of it."""
    sel, txt = {}, []
    for d in ds.attrs.get("point_dims", []):
        if d not in keep and d in ds.dims:
            sel[d] = 0
            txt.append(f"{d} = {ds[d].values[0]}")
    return sel, ("; ".join(txt))


def _label(ds, xname: str) -> str:
    if ds.attrs.get("point_dims") == ["point"] and len(ds.attrs["parameters"]) > 1:
        return f"{xname} (+{len(ds.attrs['parameters']) - 1} zipped)"
    return xname


def _zip_note(ds) -> str:
    if ds.attrs.get("point_dims") == ["point"] and len(ds.attrs["parameters"]) > 1:
        return "\nzip: " + ", ".join(ds.attrs["parameters"])
    return ""


def _truth_band(ax, x, t, se, color, label, ls="-"):
    ax.plot(x, t, ls, color=color, lw=1.3, label=label)
    if se is not None and np.any(np.nan_to_num(se) > 0):
        ax.fill_between(x, t - 2 * se, t + 2 * se, color=color, alpha=0.15, lw=0)


def _classes_on(d) -> list:
    """The classes with a value on the selected axis (a study's classes may have different
    axes: the store holds their union, NaN where a class has no such axis)."""
    out = []
    for cls in d["class"].values:
        c = d.sel({"class": cls})
        if any(q in c and np.any(np.isfinite(c[q].values)) for q in ("truth", "mean")):
            out.append(cls)
    return out


def _unit(ds, cls) -> str:
    """The unit of class ``cls`` (stores before ``class_units`` had one ``units`` for all)."""
    return str(ds.attrs.get("class_units", {}).get(str(cls), ds.attrs.get("units", "")))


def _class_label(ds, cls) -> str:
    """The class's label as its study names it (e.g. "temporal error (TE)"); its name where the
    store's kind is not a registered study."""
    return _labels(str(ds.attrs.get("kind", ""))).get(str(cls), str(cls))


@functools.lru_cache(maxsize=None)
def _labels(kind: str) -> dict:
    """Class name -> label of the study ``kind`` (empty where it is not a registered study)."""
    try:
        study = study_for_kind(kind)
        return {c.name: c.label or c.name for c in study.classes(study.load_scenario())}
    except Exception:  # noqa: BLE001 - a label is a courtesy: the name stands in
        return {}


def _panel_title(ds, cls, axis=None) -> str:
    """A panel's title: the class's label, its axis and its unit."""
    ax = f", axis {axis}" if axis is not None else ""
    return f"{_class_label(ds, cls)}{ax} ({_unit(ds, cls)})"


def _pair(a: float, b: float) -> tuple[str, str]:
    """Two values with enough significant digits to tell them apart (up to 6)."""
    for n in (3, 4, 5, 6):
        sa, sb = fmt(a, n), fmt(b, n)
        if sa != sb:
            break
    return sa, sb


def _flat(series: list, ses: list) -> tuple[bool, float]:
    """Whether every drawn series of a panel is flat over the sweep: its range (max - min)
    within 2 Monte Carlo standard errors of the values (or exactly constant); and the
    largest range. ``series``: arrays along x; ``ses``: their standard errors (or None)."""
    rng, ok = 0.0, True
    for y, se in zip(series, ses):
        y = np.asarray(y, dtype=float)
        f = np.isfinite(y)
        if f.sum() < 2:
            continue
        r = float(np.ptp(y[f]))
        rng = max(rng, r)
        tol = 2 * float(np.nanmax(np.asarray(se, dtype=float)[f])) if se is not None else 0.0
        # a constant to rounding (relative 1e-9 of the values) counts as flat
        if r > max(tol, 1e-9 * float(np.max(np.abs(y[f])))):
            ok = False
    return ok, rng


def _mark_flat(ax, flat: bool, rng: float, unit: str) -> bool:
    if flat:
        ax.text(0.5, 0.92, f"flat: varies by {rng:.2g}\n(within +-2 MC s.e.)",
                ha="center", va="top", fontsize=6, transform=ax.transAxes,
                bbox=dict(boxstyle="round", fc="w", ec="0.6", alpha=0.9))
    return flat


def _line_figure(ds, xdim, xname, axis, variant, out_dir):
    import matplotlib.pyplot as plt

    others = [d for d in ds.attrs.get("point_dims", []) if d not in (xdim,) and ds.sizes.get(d, 1) > 1]
    series = others[0] if others and xdim != "point" else None
    sel, note = _fixed_note(ds, [xdim] + ([series] if series else []))
    d = ds.isel(sel).sel(axis=axis)
    classes = _classes_on(d)
    fig, axes = _panels(len(classes))
    x = d[xname].values
    has_mean = "mean" in d
    tv = "variant" in d["truth"].dims
    flat_classes, changes = [], []
    for ax, cls in zip(axes, classes):
        c = d.sel({"class": cls})
        drawn, drawn_se = [], []
        if series is None:
            if tv:
                for k, v in enumerate(c["variant"].values):
                    col = VARIANT_STYLE.get(str(v), ("k", "o"))[0]
                    t, tse = c.truth.sel(variant=v).values, c.truth_se.sel(variant=v).values
                    # line styles differ: truths that coincide stay visible
                    _truth_band(ax, x, t, tse, col, f"truth ({v})", ls=("-", "--", ":")[k % 3])
                    drawn.append(t)
                    drawn_se.append(tse)
            else:
                _truth_band(ax, x, c.truth.values, c.truth_se.values, "k", "truth")
                drawn.append(c.truth.values)
                drawn_se.append(c.truth_se.values)
            if has_mean:
                for v in c["variant"].values:
                    m = c["mean"].sel(variant=v).values
                    if not np.any(np.isfinite(m)):
                        continue
                    col, mk = VARIANT_STYLE.get(str(v), ("C2", "^"))
                    s = c["spread"].sel(variant=v).values
                    ax.fill_between(x, m - s, m + s, color=col, alpha=0.12, lw=0)
                    ax.errorbar(x, m, yerr=2 * c["se_bias"].sel(variant=v).values, fmt=mk, ms=4, color=col,
                                capsize=2, lw=1, label=f"{v} mean", mfc="none" if mk == "s" else None)
                    drawn.append(m)
                    drawn_se.append(c["se_bias"].sel(variant=v).values)
        else:
            sv = d[series].values
            cmap = plt.get_cmap("viridis")
            for i, val in enumerate(sv):
                col = cmap(i / max(1, len(sv) - 1))
                ci = c.isel({series: i})
                t = ci.truth.sel(variant=variant) if tv else ci.truth
                se = ci.truth_se.sel(variant=variant) if tv else ci.truth_se
                _truth_band(ax, x, t.values, se.values, col, f"{val:g}" if isinstance(val, (float, np.floating))
                            else str(val), ls=("-", "--", ":", "-.")[i % 4])  # coinciding lines stay visible
                drawn.append(t.values)
                drawn_se.append(se.values)
                if has_mean:
                    m = ci["mean"].sel(variant=variant).values
                    if np.any(np.isfinite(m)):
                        ax.errorbar(x, m, yerr=2 * ci["se_bias"].sel(variant=variant).values, fmt="o", ms=3.5,
                                    color=col, capsize=2, lw=0.8)
        flat, rng = _flat(drawn, drawn_se)
        if _mark_flat(ax, flat, rng, _unit(ds, cls)):
            flat_classes.append(_class_label(ds, cls))
        else:
            t0 = np.asarray(drawn[0], dtype=float)
            f = np.isfinite(t0)
            if f.sum() >= 2:
                a_, b_ = _pair(t0[f][0], t0[f][-1])
                changes.append(f"{_class_label(ds, cls)} from {a_} to {b_} {_unit(ds, cls)}")
        ax.set_title(_panel_title(ds, cls), fontsize=8)
        ax.set_xlabel(_label(ds, xname), fontsize=7)
        ax.set_ylabel(f"axis {axis} ({_unit(ds, cls)})", fontsize=7)
        ax.tick_params(labelsize=7)
        if np.issubdtype(np.asarray(x).dtype, np.number):
            ax.locator_params(axis="x", nbins=5)  # tick labels that do not run into each other
    _legend_first(axes, fontsize=6, title=(series if series else None), title_fontsize=6)
    head = f"{ds.attrs.get('title', '')}: axis {axis}"
    if series and has_mean:
        head += f"; lines: truth, markers: {variant} mean (+-2 MC s.e.)"
    elif has_mean:
        head += "; markers: mean (+-2 MC s.e.), band: +-1 spread; truth band +-2 s.e."
    if note:
        head += f"\n({note})"
    _suptitle(fig, head + _zip_note(ds))
    what = "the truth" + (f" (at {series} = {d[series].values[0]})" if series else "")
    caption = (f"Each class against {_label(ds, xname)}, axis {axis}, over {x[0]} to {x[-1]}. "
               + (f"Along the sweep {what} goes " + "; ".join(changes) + ". " if changes else "")
               + ("Flat over this range (within +-2 Monte Carlo standard errors): "
                  + ", ".join(flat_classes) + "." if flat_classes else "No class is flat over this range."))
    path = Path(out_dir) / f"classes_vs_{_safe(xname)}__{axis}.png"
    return save(fig, path, caption)


def _heatmaps(ds, axis, variant, out_dir):
    dims = [d for d in ds.attrs.get("point_dims", []) if d != "point" and ds.sizes[d] > 1]
    if len(dims) < 2:
        return []
    d0, d1 = dims[:2]
    sel, note = _fixed_note(ds, [d0, d1])
    d = ds.isel(sel).sel(axis=axis)
    out = []
    quantities = [("truth", "truth")]
    if "bias" in d:
        quantities.append(("bias", f"bias of the {variant} estimate"))
    for q, title in quantities:
        classes = _classes_on(d)
        if not classes:
            continue
        fig, axes = _panels(len(classes))
        found = []
        for ax, cls in zip(axes, classes):
            a = d[q].sel({"class": cls})
            if "variant" in a.dims:
                a = a.sel(variant=variant)
            z = a.transpose(d1, d0).values
            if np.any(np.isfinite(z)):
                iy, ix = np.unravel_index(np.nanargmax(np.abs(z)), z.shape)
                lo_, hi_ = float(np.nanmin(z)), float(np.nanmax(z))
                a_, b_ = _pair(lo_, hi_)
                is_flat = hi_ - lo_ <= 1e-9 * max(abs(hi_), abs(lo_), 1e-300)
                if is_flat:
                    ax.text(0.5, 0.97, "flat over the grid", ha="center", va="top", fontsize=7,
                            transform=ax.transAxes, bbox=dict(boxstyle="round", fc="w", ec="0.6", alpha=0.9))
                fl = (f"flat at {fmt(lo_, 3)} {_unit(ds, cls)}" if is_flat
                      else f"{a_} to {b_} {_unit(ds, cls)} (largest |value| at {d0} = {d[d0].values[ix]}, "
                           f"{d1} = {d[d1].values[iy]})")
                found.append(f"{_class_label(ds, cls)} {fl}")
            if q == "bias":
                lim = np.nanmax(np.abs(z)) if np.any(np.isfinite(z)) else 1.0
                im = ax.imshow(z, origin="lower", aspect="auto", cmap="RdBu_r", vmin=-lim, vmax=lim)
            else:
                im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis")
            fig.colorbar(im, ax=ax, shrink=0.85).ax.tick_params(labelsize=6)
            ax.set_xticks(range(d.sizes[d0]), [f"{v:g}" if isinstance(v, (float, np.floating)) else str(v)
                                               for v in d[d0].values], fontsize=6, rotation=45)
            ax.set_yticks(range(d.sizes[d1]), [f"{v:g}" if isinstance(v, (float, np.floating)) else str(v)
                                               for v in d[d1].values], fontsize=6)
            # cell values only where they fit: at most 8 columns and 12 rows, 2 significant digits
            if z.shape[1] <= 8 and z.shape[0] <= 12:
                lo, hi = im.get_clim()
                for (iy, ix), val in np.ndenumerate(z):
                    if np.isfinite(val):
                        light = q == "truth" and hi > lo and (val - lo) / (hi - lo) > 0.6
                        ax.text(ix, iy, f"{val:.2g}", ha="center", va="center", fontsize=5,
                                color="k" if (light or q == "bias") else "w")
            ax.set_title(_panel_title(ds, cls), fontsize=8)
            ax.set_xlabel(d0, fontsize=7)
            ax.set_ylabel(d1, fontsize=7)
        _suptitle(fig, f"{ds.attrs.get('title', '')}: {title}, axis {axis}" + (f"\n({note})" if note else ""))
        path = Path(out_dir) / f"heatmap_{q}{'_' + variant if q == 'bias' else ''}__{axis}.png"
        out.append(save(fig, path, f"{title[0].upper() + title[1:]} over {d0} and {d1}, axis {axis}: "
                        + "; ".join(found) + "."))
    return out


def precision_table(ds, *, axis: str, precision: float) -> list[dict]:
    """For a 1-D (or zip) validation sweep: per class and variant, the relative spread
    (spread / |mean|) at each point and the first x from which it stays <= ``precision``."""
    if "spread" not in ds:
        return []
    xs = _x_axes(ds)
    if len(xs) != 1 or len(ds.attrs.get("point_dims", [])) != 1:
        return []
    xdim, xname = xs[0]
    d = ds.sel(axis=axis).sortby(xname) if xdim == xname else ds.sel(axis=axis)
    x = d[xname].values
    rows = []
    for cls in _classes_on(d):
        for v in d["variant"].values:
            m = d["mean"].sel({"class": cls, "variant": v}).values
            s = d["spread"].sel({"class": cls, "variant": v}).values
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(np.abs(m) > 0, s / np.abs(m), np.nan)
            ok = np.isfinite(rel) & (rel <= precision)
            first = None
            for i in range(len(x)):
                if ok[i:].all():
                    first = x[i]
                    break
            t = d["truth"].sel({"class": cls, "variant": v} if "variant" in d["truth"].dims else {"class": cls})
            with np.errstate(divide="ignore", invalid="ignore"):
                bias_pct = np.where(np.abs(t.values) > 0, 100 * (m - t.values) / np.abs(t.values), np.nan)
            rows.append({"class": str(cls), "variant": str(v), "x": xname, "x_values": x.tolist(),
                         "relative_spread": rel.tolist(), "bias_percent": bias_pct.tolist(),
                         "constant": bool(np.all(np.isfinite(s)) and np.all(s == 0)),
                         "no_estimate": bool(np.all(np.isnan(m))),
                         "first_within": None if first is None else float(first)})
    return rows


def _relative_spread_figure(ds, axis, precision, out_dir):
    if "spread" not in ds:
        return None
    xs = _x_axes(ds)
    if len(xs) != 1 or len(ds.attrs.get("point_dims", [])) != 1:
        return None
    xname = xs[0][1]
    d = ds.sel(axis=axis)
    x = d[xname].values
    classes = _classes_on(d)
    if not classes:
        return None
    fig, axes = _panels(len(classes))
    found = []
    for ax, cls in zip(axes, classes):
        for v in d["variant"].values:
            col, mk = VARIANT_STYLE.get(str(v), ("C2", "^"))
            m = d["mean"].sel({"class": cls, "variant": v}).values
            s = d["spread"].sel({"class": cls, "variant": v}).values
            se = d["se_spread"].sel({"class": cls, "variant": v}).values
            with np.errstate(divide="ignore", invalid="ignore"):
                rel = np.where(np.abs(m) > 0, s / np.abs(m), np.nan)
                rel_se = np.where(np.abs(m) > 0, se / np.abs(m), np.nan)
            if np.any(np.isfinite(rel) & (rel > 0)):
                ax.errorbar(x, 100 * rel, yerr=200 * rel_se, fmt=mk + "-", ms=4, color=col, capsize=2, lw=1,
                            label=str(v), mfc="none" if mk == "s" else None)
                f = np.isfinite(rel)
                found.append(f"{_class_label(ds, cls)} ({v}) {fmt(100 * rel[f][0], 3)} % to {fmt(100 * rel[f][-1], 3)} %")
            elif np.all(np.isnan(m)):
                ax.text(0.5, 0.5, "no lab estimate (truth only)", ha="center", va="center",
                        fontsize=7, transform=ax.transAxes)
            elif np.all(np.isfinite(s)) and np.all(s == 0):
                ax.text(0.5, 0.5, "no spread: a constant of the scenario", ha="center", va="center",
                        fontsize=7, transform=ax.transAxes)
        if precision is not None:
            ax.axhline(100 * precision, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.set_title(_panel_title(ds, cls), fontsize=8)
        ax.set_xlabel(_label(ds, xname), fontsize=7)
        ax.set_ylabel("spread / |mean| (%)", fontsize=7)
        ax.tick_params(labelsize=7)
    _legend_first(axes, fontsize=6)
    _suptitle(fig, f"{ds.attrs.get('title', '')}: precision of one measurement, axis {axis} "
              "(error bars +-2 MC s.e.)" + (f"; dashed: {100 * precision:g} %" if precision else "")
              + _zip_note(ds))
    path = Path(out_dir) / f"relative_spread_vs_{_safe(xname)}__{axis}.png"
    caption = (f"Spread of one measurement relative to its mean, axis {axis}, from {xname} = {x[0]} to {x[-1]}: "
               + ("; ".join(found) if found else "no class has a spread") + "."
               + (f" Dashed: the {100 * precision:g} % precision asked for." if precision else ""))
    return save(fig, path, caption)


def _sobol_figure(sob, title, axis, out_dir, ds=None):
    s = sob.sel(axis=axis) if "axis" in sob.dims else sob
    extra = [dd for dd in s.S1.dims if dd not in ("class", "parameter")]
    lab = (lambda c: _class_label(ds, c)) if ds is not None else str
    panels = [(lab(c), {"class": c}) for c in s["class"].values]
    if extra:
        panels = [(f"{lab(c)} ({extra[0]} {v})", {"class": c, extra[0]: v})
                  for c in s["class"].values for v in s[extra[0]].values]
    fig, axes = _panels(len(panels))
    params = list(s.parameter.values)
    xi = np.arange(len(params))
    legend = False
    found = []
    for ax, (name, sel) in zip(axes, panels):
        r = s.sel(sel)
        st = np.asarray(r.ST.values, dtype=float)
        if not str(r["note"].values) and np.any(np.isfinite(st)):
            j = int(np.nanargmax(st))
            found.append(f"{name}: {params[j]} (ST {st[j]:.2f})")
        elif str(r["note"].values):
            found.append(f"{name}: {r['note'].values}")
        if str(r["note"].values):
            ax.text(0.5, 0.5, str(r["note"].values), ha="center", va="center", fontsize=7, wrap=True,
                    transform=ax.transAxes)
        else:
            ax.bar(xi - 0.18, r.S1.values, 0.36, yerr=r.S1_conf.values, capsize=2, color="C0", label="S1")
            ax.bar(xi + 0.18, r.ST.values, 0.36, yerr=r.ST_conf.values, capsize=2, color="C1", label="ST")
            if not legend:
                ax.legend(fontsize=6)
                legend = True
        ax.axhline(0, color="k", lw=0.5)
        # the limits hold the whole error bars (indices estimated from few evaluations can
        # leave [0, 1] by more than the usual margin)
        if str(r["note"].values):
            ax.set_ylim(-0.15, 1.15)
        else:
            lo = np.nanmin(np.r_[r.S1.values - r.S1_conf.values, r.ST.values - r.ST_conf.values, 0.0])
            hi = np.nanmax(np.r_[r.S1.values + r.S1_conf.values, r.ST.values + r.ST_conf.values, 1.0])
            ax.set_ylim(min(-0.15, lo - 0.05), max(1.15, hi + 0.05))
        ax.set_ylabel("Sobol index", fontsize=7)
        ax.set_xticks(xi, params, fontsize=6, rotation=20, ha="right")
        ax.set_title(name, fontsize=9)
        ax.tick_params(labelsize=7)
    _suptitle(fig, f"{title}: Sobol indices of the {sob.attrs.get('output', 'truth')} (axis {axis}), "
              f"{int(100 * sob.attrs.get('conf_level', 0.95))} % intervals, "
              f"{sob.attrs.get('evaluations', '?')} evaluations")
    path = Path(out_dir) / f"sobol__{axis}.png"
    return save(fig, path, f"The parameter with the largest total Sobol index of each class (axis {axis}): "
                + "; ".join(found) + ".")


def plot_store(store, out_dir, *, axis: str | None = None, variant: str = "improved",
               precision: float | None = None, overwrite: bool = False) -> list[Path]:
    """Write the figures of a sweep store into ``out_dir``; return their paths.

    ``out_dir`` must be new, empty, hold only earlier figures, or ``overwrite`` be given
    (:func:`simcam.infra.outputs.check_output_dir`)."""
    import matplotlib

    matplotlib.use("Agg")
    if precision is not None and not (math.isfinite(precision) and precision > 0):
        raise UserInputError(f"--precision {precision}: must be a finite number > 0 (a relative spread, e.g. 0.1)")
    ds = open_sweep(store)
    out_dir = Path(out_dir)
    files: list[Path] = []
    axes_all = list(ds["axis"].values) if "axis" in ds.coords else []
    sob = open_sobol(store)
    if not axes_all and sob is not None and "axis" in sob.coords:
        axes_all = list(sob["axis"].values)
    if axis is not None and axes_all and axis not in axes_all:
        raise UserInputError(f"--axis {axis}: this store has axes {', '.join(map(str, axes_all))}")
    # every axis unless one is asked for
    ax_names = [axis] if axis is not None else (axes_all or [None])
    if "variant" in ds.coords and variant not in ds["variant"].values:
        raise UserInputError(f"--variant {variant}: this store has {', '.join(map(str, ds['variant'].values))}")
    if ds.attrs.get("point_dims") and "done" in ds and not bool(ds["done"].any()) and sob is None:
        raise UserInputError(f"{store}: no point of the sweep is done yet; run `budget sweep` into it first")
    # the folder is checked before, and created only when a figure is drawn; a failure
    # removes a folder this call created (no empty plots folder left behind)
    check_output_dir(out_dir, option="--out", replaceable=is_earlier_plots, overwrite=overwrite, inputs=(store,))
    created = not out_dir.exists()
    try:
        with naming_failed_writes(out_dir, option="--out"):  # the disk filled: name the figure
            out_dir.mkdir(parents=True, exist_ok=True)
            files = [f for a in ax_names for f in _draw(ds, sob, a, variant, precision, out_dir)]
            _write_page(ds, files, out_dir)
    except BaseException:
        if created:
            shutil.rmtree(out_dir, ignore_errors=True)
        raise
    return files


def _write_page(ds, files, out_dir) -> None:
    """``report.md`` (each figure with its caption under it) and its self-contained twin
    ``report.html`` beside the figures."""
    md = [f"# {ds.attrs.get('title', 'Sweep')}: figures", "",
          f"Sweep `{ds.attrs.get('kind', '')}` ({ds.attrs.get('evaluate', '')}), hash "
          f"`{ds.attrs.get('sweep_hash', '')}`, seed {ds.attrs.get('seed', '')}.", "", figure_markdown(files), ""]
    page = Path(out_dir) / "report.md"
    page.write_text("\n".join(md))
    write_html(page)


def _draw(ds, sob, ax_name, variant, precision, out_dir) -> list[Path]:
    files: list[Path] = []
    if ds.attrs.get("point_dims"):
        if ax_name is not None and "axis" in ds.coords and not _classes_on(ds.sel(axis=ax_name)):
            return files  # no class has this axis at the drawn points
        for xdim, xname in _x_axes(ds):
            files.append(_line_figure(ds, xdim, xname, ax_name, variant, out_dir))
        files += _heatmaps(ds, ax_name, variant, out_dir)
        rs = _relative_spread_figure(ds, ax_name, precision, out_dir)
        if rs is not None:
            files.append(rs)
    if sob is not None:
        files.append(_sobol_figure(sob, ds.attrs.get("title", ""), ax_name, out_dir, ds))
    return files


@click.command("plot")
@click.argument("store", type=click.Path(file_okay=False))
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Folder of the PNG files (default: STORE_plots beside the store).")
@click.option("--axis", default=None,
              help="Axis to draw (one of the store's axis labels, e.g. x or y; default every axis).")
@click.option("--variant", default="improved", show_default=True,
              help="Variant drawn in 2-D line plots and bias heatmaps.")
@click.option("--precision", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Relative precision to mark (e.g. 0.1) and report the first value that reaches it.")
@overwrite_option
def plot_command(store, out_dir, axis, variant, precision, overwrite) -> None:
    """Draw the results of the sweep store STORE (budget sweep ... --out STORE)."""
    store_p = Path(store)
    out = Path(out_dir) if out_dir else store_p.parent / f"{store_p.name}_plots"
    files = plot_store(store, out, axis=axis, variant=variant, precision=precision, overwrite=overwrite)
    ds = open_sweep(store)
    if "done" in ds and not bool(ds["done"].all()):
        click.echo(f"note: {int((~ds['done']).sum())} of {ds['done'].size} points are not done yet "
                   "(run the sweep again to complete them)")
    for f in files:
        click.echo(str(f))
        if getattr(f, "caption", ""):
            click.echo(f"  {f.caption}")
    if precision is not None:
        rows = precision_table(ds, axis=axis or str(ds["axis"].values[0]), precision=precision)
        if not rows:
            click.echo("--precision: needs a validation sweep along one parameter (or a zip)")
        for r in rows:
            if r["no_estimate"]:
                click.echo(f"{r['class']:>12s} {r['variant']:>9s}: no lab estimate (truth only)")
                continue
            if r["constant"]:
                click.echo(f"{r['class']:>12s} {r['variant']:>9s}: no spread (a constant of the scenario)")
                continue
            if r["first_within"] is None:
                when = f"never in this range; at {r['x']} = {r['x_values'][-1]:g}"
                i = -1
            else:
                i = r["x_values"].index(r["first_within"])
                when = (f"already at the smallest {r['x']} = {r['first_within']:g}" if i == 0
                        else f"from {r['x']} = {r['first_within']:g} on")
            b, rel = r["bias_percent"][i], r["relative_spread"][i]
            click.echo(f"{r['class']:>12s} {r['variant']:>9s}: spread/|mean| <= {precision:g} {when} "
                       f"(spread/|mean| {100 * rel:.1f} %" + (f", bias {b:+.0f} % of the truth)" if np.isfinite(b)
                                                             else ")"))
