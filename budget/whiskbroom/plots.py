"""Plots of the whiskbroom study and synthesis (matplotlib, Agg; labelled axes with units)."""

from __future__ import annotations


import numpy as np

from budget import figures  # figures.save: looked up when called (a test spies on it)
from budget.figures import figure_markdown
from budget.runner.numbers import fmt

__all__ = ["plot_beta_hist", "plot_dv_hist", "plot_ground_trace", "plot_mtf_vs_stages",
           "plot_motion_field", "plot_trial_mtf", "plot_mtf_errors", "figure_markdown"]


def _fig(figsize=(6.4, 4.2)):
    p = figures.plt()
    return p, *p.subplots(figsize=figsize)


def _save(plt, fig, path, caption: str = ""):
    return figures.save(fig, path, caption)


def plot_beta_hist(result, path):
    """Fig. 3 analogue: drift angle of the worst column over the trials."""
    plt, fig, ax = _fig()
    level = next(iter(result.residuals))
    beta = np.asarray(result.residuals[level].beta_deg)
    ax.hist(beta, bins=40, color="tab:blue")
    ax.set_xlabel("drift angle beta (deg)")
    ax.set_ylabel("trials")
    ax.set_title(f"Drift angle, {result.trials.size} trials (array turned {result.array_angle_deg:.2f} deg)",
                 fontsize=10)
    caption = (f"Drift angle of the worst column over {beta.size} trials: mean {fmt(beta.mean(), 3, sign=True)} deg, "
               f"sd {fmt(beta.std(ddof=1), 3)} deg, |beta| up to {fmt(np.abs(beta).max(), 3)} deg, with the array "
               f"turned by {result.array_angle_deg:.2f} deg.")
    return _save(plt, fig, path, caption)


def plot_dv_hist(result, path):
    """Fig. 5 analogue: Delta V_P for each mirror-rate error (overlaid, each one outlined)."""
    plt, fig, ax = _fig()
    samples = {f"{level:g} deg/s": np.asarray(r.dv_mm_s) for level, r in result.residuals.items()}
    figures.overlaid_hist(ax, samples, bins=50)
    ax.set_xlabel("image-motion velocity residual Delta V_P (mm/s)")
    ax.set_ylabel("trials")
    ax.legend(title="mirror-rate error")
    ax.set_title("image-motion velocity residual per mirror-rate error", fontsize=10)
    sd = {k: float(np.std(v, ddof=1)) for k, v in samples.items()}
    caption = ("Delta V_P over the trials; its sd per mirror-rate error: "
               + ", ".join(f"{k} {fmt(v, 3)} mm/s" for k, v in sd.items())
               + (f" (the largest {fmt(max(sd.values()) / min(sd.values()), 2)} times the smallest)."
                  if len(sd) > 1 and min(sd.values()) > 0 else "."))
    return _save(plt, fig, path, caption)


def plot_ground_trace(lat, lon, path):
    """Fig. 4 analogue: ground trace of the array ends and centre while the mirror scans."""
    plt, fig, ax = _fig()
    names = ("first column", "centre", "last column")
    for j in range(lat.shape[1]):
        ax.plot(lon[:, j], lat[:, j], label=names[j] if j < 3 else None)
    ax.set_xlabel("Earth-fixed longitude east of the ascending node (deg)")
    ax.set_ylabel("latitude (deg)")
    ax.legend()
    ax.set_title("Ground trace of one scan (one side)", fontsize=10)
    width = float(np.max(np.abs(lat[:, 0] - lat[:, -1])))
    caption = (f"One scan sweeps {fmt(np.ptp(lon[:, lat.shape[1] // 2]), 3)} deg of longitude; the array's "
               f"ends are up to {fmt(width, 3)} deg of latitude apart.")
    return _save(plt, fig, path, caption)


def _last_n_above(curve, n, threshold):
    """The largest N from which on the curve never again reaches ``threshold`` (the curve is
    drawn for N = 1..max): the last N with MTF >= threshold, 0 where none."""
    ok = np.nonzero(curve >= threshold)[0]
    return int(n[ok[-1]]) if ok.size else 0


def plot_mtf_vs_stages(result, path, *, threshold=0.95, n_phase=4, max_stages=192):
    """Fig. 6 analogue: predicted MTF at Nyquist at the quantile of |eps| against N; the
    caption gives the most stages that keep the threshold, per level, for each curve drawn."""
    from simcam.whiskbroom.synthesis import mtf_sinc

    plt, fig, ax = _fig()
    n = np.arange(1, max_stages + 1)
    parts = []
    for row in result.table:
        pub = mtf_sinc(n * row["eps_quantile"])
        full = pub * mtf_sinc(1.0 / n_phase) * mtf_sinc(n * row["eta_quantile"])
        line, = ax.plot(n, pub, label=f"{row['mirror_rate_error_deg_s']:g} deg/s (N <= {row['n_max_published']})")
        ax.plot(n, full, ls="--", color=line.get_color())
        parts.append(f"{row['mirror_rate_error_deg_s']:g} deg/s: N <= {_last_n_above(pub, n, threshold)} "
                     f"(published) vs {_last_n_above(full, n, threshold)} (with clocking and drift)")
    ax.axhline(threshold, color="k", lw=0.8)
    ax.set_xlabel("TDI stages N")
    ax.set_ylabel(f"MTF at Nyquist ({100 * result.quantile:g} % quantile)")
    ax.set_title("solid: published sinc; dashed: with clocking and cross-track drift", fontsize=10)
    ax.legend(title="mirror-rate error", fontsize=8)
    caption = (f"Most TDI stages that keep the MTF at Nyquist >= {threshold:g} (black line) at the "
               f"{100 * result.quantile:g} % quantile: " + "; ".join(parts) + ".")
    return _save(plt, fig, path, caption)


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
    ax.set_title("Image-motion field over the arrays", fontsize=10)
    d = 1e3 * (s - centre)
    caption = (f"Nominal image-motion speed {centre:.3f} mm/s at the centre; over the arrays it differs by "
               f"{fmt(d.min(), 3, sign=True)} to {fmt(d.max(), 3, sign=True)} um/s ({fmt(100 * np.ptp(s) / centre, 3)} % of it).")
    return _save(plt, fig, path, caption)


def plot_trial_mtf(extra, scenario, path):
    """One trial: pixel-level MTF against N beside the two predictions."""
    plt, fig, ax = _fig()
    n = np.asarray(extra["stages"])
    ax.plot(n, extra["truth_along"], "k", label="pixel-level (truth), along")
    ax.plot(n, extra["published"], label="published sinc")
    ax.plot(n, extra["improved_along"], "--", label="improved, along")
    ax.plot(n, extra["truth_cross"], "k:", label="pixel-level, cross")
    ax.axhline(scenario.synthesis.mtf_threshold, color="grey", lw=0.8)
    ax.axvline(scenario.camera.tdi_stages, color="grey", lw=0.8, ls=":")
    ax.set_xlabel("TDI stages N")
    ax.set_ylabel("motion MTF at Nyquist")
    ax.set_title(f"trial 0: eps = {extra['eps']:.2e} px/stage, eta = {extra['eta']:.2e} px/stage", fontsize=10)
    ax.legend(fontsize=8)
    i = int(np.argmin(np.abs(n - scenario.camera.tdi_stages)))
    t, p, im = (float(np.asarray(extra[k])[i]) for k in ("truth_along", "published", "improved_along"))
    caption = (f"Trial 0 at N = {n[i]:g} stages (dotted line): pixel-level MTF {t:.4f} along track; the "
               f"published sinc predicts {p:.4f} ({fmt(p - t, 2, sign=True)}), the improved prediction {im:.4f} "
               f"({fmt(im - t, 2, sign=True)}).")
    return _save(plt, fig, path, caption)


def plot_mtf_errors(result, path):
    """Estimate minus truth of the along-track MTF, per variant, over the trials (overlaid,
    each outlined; variants whose errors are orders apart get their own panels' scale through
    the common bins only where they overlap)."""
    plt, fig, ax = _fig()
    errs = {}
    for var in result.study.variants:
        key = ("mtf_nyquist", var, "along")
        if key in result.samples:
            errs[var] = np.asarray(result.samples[key] - result.trial_truths[key])
    if errs:
        figures.overlaid_hist(ax, errs, bins=40)
    ax.axvline(0.0, color="k", lw=0.8)
    ax.set_xlabel("estimated minus pixel-level MTF at Nyquist (along)")
    ax.set_ylabel("trials")
    ax.set_title("error of each MTF prediction over the trials", fontsize=10)
    ax.legend()
    caption = ("Estimate minus pixel-level MTF at Nyquist (along track) over the trials: "
               + "; ".join(f"{v} mean {fmt(e.mean(), 2, sign=True)}, sd {fmt(e.std(ddof=1) if e.size > 1 else 0.0, 2)}"
                           for v, e in errs.items()) + ".")
    return _save(plt, fig, path, caption)
