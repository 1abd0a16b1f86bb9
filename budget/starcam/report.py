"""Seed 000's own figures for the validation report (the common report, table and
estimates plot are :mod:`budget.runner.report`'s; these are the study's sections).

Figures (matplotlib, Agg backend):

* ``hsfe_residuals.png``: the rms over stars of the HSFE residuals ``delta_j(k)`` at each
  condition step of one trial (seed 000 fig. 6 draws one line per star; the rms states the
  point);
* ``chromatic_residuals.png``: the per-star colour differences in each corner field of one
  trial (as fig. 7);
* ``distortion_residuals.png``: the distortion residual map at the grid points, before
  and after the cubic fit, of one trial (as fig. 8).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget.figures import plt as pyplot  # matplotlib.pyplot, set up on first use
from budget.figures import save


def _plt():
    return pyplot()


def _rms(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x ** 2))) if x.size else float("nan")


def plot_hsfe_residuals(est, path: Path, *, finding: str = ""):
    """HSFE residuals delta_j(k) of one trial (seed 000 fig. 6) summarised per condition step:
    the rms over the stars at each step k, per axis, beside the rms of all of them (the HSFE
    the method reads, eqs 3-12), so the figure states its point (is the residual the same at
    every step, or driven by a few?) rather than drawing one line per star. The caption
    gives the rms per axis (from the residuals drawn) and ``finding`` (the run's verdict)."""
    plt = _plt()
    r = est.residuals
    fig, ax_ = plt.subplots(figsize=(7.5, 3.2))
    rms = {}
    for i, ax in enumerate(("x", "y")):
        col = f"delta_{ax}_px"
        per_k = r.groupby("k")[col].apply(_rms)
        rms[ax] = _rms(r[col])
        ax_.plot(per_k.index, per_k.values, "o-", color=f"C{i}", ms=4, lw=1.0, label=f"{ax}: rms over stars at each step")
        ax_.axhline(rms[ax], color=f"C{i}", ls="--", lw=0.9, label=f"{ax}: rms of every residual, {rms[ax]:.4f} px")
    ax_.set_xlabel("condition step k")
    ax_.set_ylabel("residual rms (px)")
    ax_.set_ylim(bottom=0)
    ax_.legend(fontsize=7)
    ax_.set_title(f"HSFE: residual about the smooth motion, {r['star'].nunique()} stars, "
                  f"rms {rms['x']:.4f} px (x), {rms['y']:.4f} px (y)", fontsize=9)
    caption = (f"Trial 0: the rms over the {r['star'].nunique()} stars of each star's centroid residual against "
               f"its smooth motion, at each of the {r['k'].nunique()} condition steps (solid), and over every "
               f"step (dashed: {rms['x']:.4f} px in x, {rms['y']:.4f} px in y). " + finding).rstrip()
    return save(fig, path, caption, dpi=90)


def plot_chromatic_residuals(centroids, path: Path, reference_filter_nm: float):
    """Per-star colour differences per corner field, one trial (seed 000 fig. 7); the caption
    gives the mean shift of each filter against the reference (from the points drawn)."""
    plt = _plt()
    good = centroids[centroids["flag"] == 0]
    m = good.groupby(["field", "filter_nm", "star"])[["x", "y"]].mean()
    filters = sorted(good["filter_nm"].unique())
    fields = list(dict.fromkeys(good["field"]))
    fig, axs = plt.subplots(1, len(fields), figsize=(3.2 * len(fields), 3.2), sharex=True, sharey=True)
    axs = np.atleast_1d(axs)
    shifts: dict = {}
    for a, fld in zip(axs, fields):
        ref = m.loc[(fld, reference_filter_nm)]
        for fnm in filters:
            if fnm == reference_filter_nm:
                continue
            d = m.loc[(fld, fnm)] - ref
            shifts.setdefault(fnm, []).append(d)
            a.plot(d["x"], d["y"], "o", ms=3, label=f"{fnm:g} - {reference_filter_nm:g} nm")
        a.axhline(0, color="0.7", lw=0.5)
        a.axvline(0, color="0.7", lw=0.5)
        a.set_title(fld, fontsize=9)
        a.set_xlabel("dx (px)")
    axs[0].set_ylabel("dy (px)")
    axs[0].legend(fontsize=7)
    parts = []
    for fnm, ds in shifts.items():
        import pandas as pd

        d = pd.concat(ds)
        parts.append(f"{fnm:g} nm: mean ({d['x'].mean():+.3f}, {d['y'].mean():+.3f}) px, star-to-star rms "
                     f"({d['x'].std():.3f}, {d['y'].std():.3f}) px")
    caption = (f"Trial 0: each star's centroid in a filter minus its centroid in {reference_filter_nm:g} nm, "
               f"over the {len(fields)} corner fields; " + "; ".join(parts) + ".")
    return save(fig, path, caption, dpi=90)


def plot_distortion_residuals(est, path: Path):
    """Residual vectors at the grid points before and after the cubic fit (seed 000 fig. 8),
    both panels on one arrow scale; the caption gives the rms before and after."""
    plt = _plt()
    r = est.residuals
    fig, axs = plt.subplots(1, 2, figsize=(11, 3.8))
    pairs = (("dx_px", "dy_px", "measured - reference (eqs 19-20)"),
             ("ddx_px", "ddy_px", "after the cubic fit (eqs 25-26)"))
    # one scale for both panels (they are compared): the longest arrow of either is 8 % of
    # the grid's extent
    longest = float(max(np.nanmax(np.hypot(r[u], r[v])) for u, v, _ in pairs)) or 1.0
    extent = float(max(np.ptp(r["x_ref"]), np.ptp(r["y_ref"]), 1.0))
    rms = {}
    for a, (u, v, title) in zip(axs, pairs):
        q = a.quiver(r["x_ref"], r["y_ref"], r[u], r[v], angles="xy", scale_units="xy",
                     scale=longest / (0.08 * extent))
        a.quiverkey(q, 0.80, 1.08, longest, f"{longest:.3f} px", labelpos="E", fontproperties={"size": 7})
        a.set_xlim(r["x_ref"].min() - 0.12 * extent, r["x_ref"].max() + 0.12 * extent)
        a.set_ylim(r["y_ref"].min() - 0.12 * extent, r["y_ref"].max() + 0.12 * extent)
        rms[u] = float(np.sqrt(np.nanmean(r[u] ** 2 + r[v] ** 2)))
        a.set_title(f"{title}: rms {rms[u]:.3f} px", fontsize=9, loc="left")
        a.set_xlabel("x (px)")
        a.set_aspect("equal")
    axs[0].set_ylabel("y (px)")
    before, after = rms["dx_px"], rms["ddx_px"]
    change = (f"the cubic fit takes out {100 * (1 - after / before):.0f} % of it" if after < before
              else "the cubic fit does not reduce it")
    caption = (f"Trial 0: residual vectors at the grid points, one arrow scale for both panels; rms length "
               f"{before:.3f} px before, {after:.3f} px after: {change}.")
    return save(fig, path, caption, dpi=90)
