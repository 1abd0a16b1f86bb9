"""Plots of the whiskbroom study and synthesis (matplotlib, Agg; labelled axes with units)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_beta_hist", "plot_dv_hist", "plot_ground_trace", "plot_mtf_vs_stages",
           "plot_motion_field", "plot_trial_mtf", "plot_mtf_errors"]


def _fig(figsize=(6.4, 4.2)):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt, *plt.subplots(figsize=figsize)


def _save(plt, fig, path):
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_beta_hist(result, path):
    """Fig. 3 analogue: drift angle of the worst column over the trials."""
    plt, fig, ax = _fig()
    level = next(iter(result.residuals))
    ax.hist(result.residuals[level].beta_deg, bins=40, color="tab:blue")
    ax.set_xlabel("drift angle beta (deg)")
    ax.set_ylabel("trials")
    ax.set_title(f"Drift angle, {result.trials.size} trials (array turned {result.array_angle_deg:.2f} deg)")
    return _save(plt, fig, path)


def plot_dv_hist(result, path):
    """Fig. 5 analogue: Delta V_P for each mirror-rate error."""
    plt, fig, ax = _fig()
    for level, r in result.residuals.items():
        ax.hist(r.dv_mm_s, bins=50, histtype="step", label=f"{level:g} deg/s")
    ax.set_xlabel("image-motion velocity residual Delta V_P (mm/s)")
    ax.set_ylabel("trials")
    ax.legend(title="mirror-rate error")
    return _save(plt, fig, path)


def plot_ground_trace(lat, lon, path):
    """Fig. 4 analogue: ground trace of the array ends and centre while the mirror scans."""
    plt, fig, ax = _fig()
    names = ("first column", "centre", "last column")
    for j in range(lat.shape[1]):
        ax.plot(lon[:, j], lat[:, j], label=names[j] if j < 3 else None)
    ax.set_xlabel("Earth-fixed longitude east of the ascending node (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.legend()
    ax.set_title("Ground trace of one scan (one side)")
    return _save(plt, fig, path)


def plot_mtf_vs_stages(result, path, *, threshold=0.95, n_phase=4, max_stages=192):
    """Fig. 6 analogue: predicted MTF at Nyquist at the quantile of |eps| against N."""
    from simcam.whiskbroom.synthesis import mtf_sinc

    plt, fig, ax = _fig()
    n = np.arange(1, max_stages + 1)
    for row in result.table:
        line, = ax.plot(n, mtf_sinc(n * row["eps_quantile"]),
                        label=f"{row['mirror_rate_error_deg_s']:g} deg/s (N <= {row['n_max_published']})")
        ax.plot(n, mtf_sinc(n * row["eps_quantile"]) * mtf_sinc(1.0 / n_phase) * mtf_sinc(n * row["eta_quantile"]),
                ls="--", color=line.get_color())
    ax.axhline(threshold, color="k", lw=0.8)
    ax.set_xlabel("TDI stages N")
    ax.set_ylabel(f"MTF at Nyquist ({100 * result.quantile:g} % quantile)")
    ax.set_title("solid: published sinc; dashed: with clocking and cross-track drift")
    ax.legend(title="mirror-rate error", fontsize=8)
    return _save(plt, fig, path)


def plot_motion_field(x1, x3, v, path):
    """Image-motion speed over the three arrays (nominal state)."""
    plt, fig, ax = _fig((7.5, 3.6))
    s = np.hypot(v[:, 0], v[:, 1])
    centre = s[np.argmin(np.hypot(x1, x3))]
    sc = ax.scatter(x1, x3, c=1e3 * (s - centre), s=4, cmap="viridis")
    fig.colorbar(sc, ax=ax, label=f"|V_P| - {centre:.3f} mm/s (um/s)")
    step = max(1, x1.size // 60)
    ax.quiver(x1[::step], x3[::step], v[::step, 0], v[::step, 1], angles="xy", width=0.002)
    ax.set_xlabel("image x_P1 (mm)")
    ax.set_ylabel("image x_P3 (mm)")
    ax.set_aspect("equal")
    ax.set_title("Image-motion field over the arrays")
    return _save(plt, fig, path)


def plot_trial_mtf(extra, scenario, path):
    """One trial: pixel-level MTF against N beside the two predictions."""
    plt, fig, ax = _fig()
    n = extra["stages"]
    ax.plot(n, extra["truth_along"], "k", label="pixel-level (truth), along")
    ax.plot(n, extra["published"], label="published sinc")
    ax.plot(n, extra["improved_along"], "--", label="improved, along")
    ax.plot(n, extra["truth_cross"], "k:", label="pixel-level, cross")
    ax.axhline(scenario.synthesis.mtf_threshold, color="grey", lw=0.8)
    ax.axvline(scenario.camera.tdi_stages, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("TDI stages N")
    ax.set_ylabel("motion MTF at Nyquist")
    ax.set_title(f"trial 0: eps = {extra['eps']:.2e} px/stage, eta = {extra['eta']:.2e} px/stage")
    ax.legend(fontsize=8)
    return _save(plt, fig, path)


def plot_mtf_errors(result, path):
    """Estimate minus truth of the along-track MTF, per variant, over the trials."""
    plt, fig, ax = _fig()
    for var in result.study.variants:
        key = ("mtf_nyquist", var, "along")
        if key in result.samples:
            ax.hist(result.samples[key] - result.trial_truths[key], bins=40, histtype="step", label=var)
    ax.set_xlabel("estimated minus pixel-level MTF at Nyquist (along)")
    ax.set_ylabel("trials")
    ax.legend()
    return _save(plt, fig, path)
