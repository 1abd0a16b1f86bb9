"""Seed 000's own figures for the validation report (the common report, table and
estimates plot are :mod:`budget.runner.report`'s; these are the study's sections).

Figures (matplotlib, Agg backend):

* ``hsfe_residuals.png``: the HSFE residuals ``delta_j(k)`` per star and condition of one
  trial (as seed 000 fig. 6);
* ``chromatic_residuals.png``: the per-star colour differences in each corner field of one
  trial (as fig. 7);
* ``distortion_residuals.png``: the distortion residual map at the grid points, before
  and after the cubic fit, of one trial (as fig. 8).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np



def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_hsfe_residuals(est, path: Path) -> None:
    """HSFE residuals delta_j(k) of one trial (seed 000 fig. 6)."""
    plt = _plt()
    r = est.residuals
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.5), sharey=True)
    for a, ax in zip(axs, ("x", "y")):
        for star, g in r.groupby("star"):
            a.plot(g["k"], g[f"delta_{ax}_px"], ".-", lw=0.6, ms=3)
        a.set_xlabel("condition step k")
        a.set_title(f"HSFE residual delta_{ax} (px), {r['star'].nunique()} stars")
    axs[0].set_ylabel("px")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_chromatic_residuals(centroids, path: Path, reference_filter_nm: float) -> None:
    """Per-star colour differences per corner field, one trial (seed 000 fig. 7)."""
    plt = _plt()
    good = centroids[centroids["flag"] == 0]
    m = good.groupby(["field", "filter_nm", "star"])[["x", "y"]].mean()
    filters = sorted(good["filter_nm"].unique())
    fields = list(dict.fromkeys(good["field"]))
    fig, axs = plt.subplots(1, len(fields), figsize=(3.2 * len(fields), 3.2), sharex=True, sharey=True)
    axs = np.atleast_1d(axs)
    for a, fld in zip(axs, fields):
        ref = m.loc[(fld, reference_filter_nm)]
        for fnm in filters:
            if fnm == reference_filter_nm:
                continue
            d = m.loc[(fld, fnm)] - ref
            a.plot(d["x"], d["y"], "o", ms=3, label=f"{fnm:g} - {reference_filter_nm:g} nm")
        a.axhline(0, color="0.7", lw=0.5)
        a.axvline(0, color="0.7", lw=0.5)
        a.set_title(fld, fontsize=9)
        a.set_xlabel("dx (px)")
    axs[0].set_ylabel("dy (px)")
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_distortion_residuals(est, path: Path) -> None:
    """Residual vectors at the grid points before and after the cubic fit (seed 000 fig. 8)."""
    plt = _plt()
    r = est.residuals
    fig, axs = plt.subplots(1, 2, figsize=(11, 3.6))
    for a, (u, v, title) in zip(axs, (("dx_px", "dy_px", "measured - reference (eqs 19-20)"),
                                      ("ddx_px", "ddy_px", "after the cubic fit (eqs 25-26)"))):
        longest = float(np.nanmax(np.hypot(r[u], r[v]))) or 1.0
        extent = float(max(np.ptp(r["x_ref"]), np.ptp(r["y_ref"]), 1.0))
        # the longest arrow drawn as 8 % of the grid's extent, and margins that hold it
        q = a.quiver(r["x_ref"], r["y_ref"], r[u], r[v], angles="xy", scale_units="xy",
                     scale=longest / (0.08 * extent))
        a.quiverkey(q, 0.80, 1.12, longest, f"{longest:.3f} px", labelpos="E", fontproperties={"size": 7})
        a.set_xlim(r["x_ref"].min() - 0.12 * extent, r["x_ref"].max() + 0.12 * extent)
        a.set_ylim(r["y_ref"].min() - 0.12 * extent, r["y_ref"].max() + 0.12 * extent)
        a.set_title(title, fontsize=9, loc="left")
        a.set_xlabel("x (px)")
        a.set_aspect("equal")
    axs[0].set_ylabel("y (px)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
