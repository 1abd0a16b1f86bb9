"""Plots of the scan-mirror study and of ``budget scanmirror simulate`` (matplotlib, Agg)."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from budget import figures  # figures.save: looked up when called (a test spies on it)
from budget.runner.numbers import fmt
from simcam.units import ARCSEC_PER_RAD

__all__ = ["plot_dtau_errors", "plot_trial_ground_errors", "plot_ground_error_maps", "plot_deviation_timeline",
           "plot_scan_pattern"]


def _plt():
    return figures.plt()


def plot_dtau_errors(result, path: Path) -> Path:
    """Histograms of estimate minus injected deviation (arcsec), per axis and variant; the
    caption compares the variants' rms errors (from the samples drawn)."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    rms = {}
    for ax, axis in zip(axes, ("x", "y")):
        errs = {}
        for v in ("published", "improved"):
            key = ("dtau", v, axis)
            if key in result.samples:
                err = result.samples[key] - result.trial_truths[key]
                errs[f"{v} (mean {err.mean():+.2f}, std {err.std():.2f})"] = err
                rms[(v, axis)] = float(np.sqrt(np.mean(err ** 2)))
        if errs:
            figures.overlaid_hist(ax, errs, bins=40)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_xlabel(f"estimated - injected dtau_{axis} (arcsec)")
        ax.set_ylabel("trials")
        ax.set_title(f"deviation error, axis {axis}", fontsize=9)
        ax.legend(fontsize=8)
    parts = []
    for axis in ("x", "y"):
        p, i = rms.get(("published", axis)), rms.get(("improved", axis))
        if p is not None and i is not None and i > 0:
            better = "improved" if i < p else "published"
            ratio = p / i if i < p else i / p
            parts.append(f"on {axis} the {better} estimate's rms error is {fmt(ratio, 2)} times smaller "
                         f"({fmt(i, 3)} vs {fmt(p, 3)} arcsec, improved vs published)")
        elif p is not None or i is not None:
            v, r = ("published", p) if p is not None else ("improved", i)
            parts.append(f"on {axis} the {v} estimate's rms error is {fmt(r, 3)} arcsec")
    caption = (f"Estimate minus injected deviation over {result.trials} trials (0 = exact): "
               + "; ".join(parts) + ".") if parts else "No deviation estimates in this run."
    return figures.save(fig, path, caption)


def _nominal_latlon(world, g0):
    lat, lon = world.latlon(g0)
    return np.rad2deg(lat), np.rad2deg(lon)


def _max_errors_caption(errors: dict) -> str:
    """Each compensation's largest |error| (deg), smallest first, from the arrays drawn."""
    m = {n: float(max(np.abs(e.lat_deg).max(), np.abs(e.lon_deg).max())) for n, e in errors.items()}
    order = sorted(m, key=m.get)
    return ", ".join(f"{n} {fmt(m[n], 3)} deg" for n in order), m


def plot_trial_ground_errors(study, scenario, extra: dict, path: Path) -> Path:
    """Latitude and longitude errors (deg) against time over the last scan, for each variant:
    ``extra`` holds the sample times ``t_s`` and ``errors``, each variant's
    :class:`budget.scanmirror.pipeline.GroundErrors`."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    t = extra["t_s"]
    for name, e in extra["errors"].items():
        axes[0].plot(t, e.lat_deg, lw=0.8, label=name)
        axes[1].plot(t, e.lon_deg, lw=0.8, label=name)
    axes[0].set_ylabel("latitude error (deg)")
    axes[1].set_ylabel("longitude error (deg)")
    axes[1].set_xlabel("time (s)")
    axes[0].set_yscale("symlog", linthresh=1e-3)
    axes[1].set_yscale("symlog", linthresh=1e-3)
    axes[0].legend(fontsize=8, ncol=4)
    axes[0].set_title("trial 0: ground errors over the last area scan (symmetric log scale, linear "
                      "within +-0.001 deg)", fontsize=9)
    text, _ = _max_errors_caption(extra["errors"])
    caption = f"Trial 0, last area scan; largest |latitude or longitude error|, smallest first: {text}."
    return figures.save(fig, path, caption)


def plot_ground_error_maps(world, setup, errors: Mapping, path: Path) -> Path:
    """Ground error maps of every area scan: |error| (deg) at the nominal ground points, one row
    per scan, one column per compensation (uncompensated, without estimate, published, improved),
    all panels on one colour scale (one colour bar) so that they compare. ``errors``: per
    scan number, each compensation's :class:`budget.scanmirror.pipeline.GroundErrors`
    (:attr:`budget.scanmirror.pipeline.ScanOutcome.errors`)."""
    from matplotlib.colors import LogNorm

    plt = _plt()
    scans = sorted(errors)
    names = ("uncompensated", "without_estimate", "published", "improved")
    fig, axes = plt.subplots(len(scans), len(names), figsize=(4 * len(names), 3.4 * len(scans) + 0.6),
                             squeeze=False)
    lat0, lon0 = _nominal_latlon(world, setup.g0)
    mags = {(s, n): np.hypot(errors[s][n].lat_deg, errors[s][n].lon_deg) for s in scans for n in names}
    # one colour scale for every panel (they are compared), logarithmic: the compensations
    # differ by orders of magnitude; at most 6 decades below the largest error
    vmax = max(float(np.max(m)) for m in mags.values()) or 1.0
    pos = np.concatenate([m[m > 0] for m in mags.values()])
    vmin = max(float(pos.min()) if pos.size else vmax * 1e-6, vmax * 1e-6)
    norm = LogNorm(vmin=vmin, vmax=vmax)
    sc = None
    for i, s in enumerate(scans):
        sel = setup.scan == s
        for j, n in enumerate(names):
            ax = axes[i, j]
            sc = ax.scatter(lon0[sel], lat0[sel], c=np.clip(mags[(s, n)], vmin, vmax), s=2, cmap="viridis",
                            norm=norm)
            ax.set_title(f"scan {s}: {n}\nmax |error| {np.max(mags[(s, n)]):.4f} deg", fontsize=8)
            ax.set_xlabel("nominal longitude (deg E)", fontsize=8)
            if j == 0:
                ax.set_ylabel("nominal latitude (deg N)", fontsize=8)
            ax.tick_params(labelsize=7)
    fig.tight_layout(rect=(0, 0, 0.93, 1))
    cax = fig.add_axes((0.945, 0.12, 0.012, 0.76))
    fig.colorbar(sc, cax=cax, label="|error| (deg), one scale for every panel")
    last = scans[-1]
    worst = {n: float(np.max(mags[(last, n)])) for n in names}
    order = sorted(worst, key=worst.get)
    caption = ("Ground error |(lat, lon) error| at the nominal ground points, every panel on one "
               f"logarithmic colour scale ({fmt(vmin, 2)} to {fmt(vmax, 2)} deg). Largest error in the last scan "
               f"({last}), smallest first: "
               + ", ".join(f"{n} {fmt(worst[n], 3)} deg" for n in order)
               + (f"; the best compensation ({order[0]}) is {fmt(worst['uncompensated'] / worst[order[0]], 3)} "
                  "times below uncompensated." if worst[order[0]] > 0 and order[0] != "uncompensated"
                  else "."))
    return figures.save(fig, path, caption, dpi=100, layout=False)


def plot_deviation_timeline(t_s, dtau_x, dtau_y, estimates: dict, dwell_end_s: float, path: Path) -> Path:
    """The injected deviation (arcsec) over the timeline and the estimates from the star dwell,
    held from the dwell's end on; the caption gives each estimate's error at the dwell's end
    and the largest drift of the deviation after it (from the curves drawn)."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    i_end = int(np.clip(np.searchsorted(t_s, dwell_end_s), 0, len(t_s) - 1))
    parts = []
    for ax, d, j, lab in ((axes[0], dtau_x, 0, "x"), (axes[1], dtau_y, 1, "y")):
        ax.plot(t_s, d * ARCSEC_PER_RAD, "k", lw=1, label="injected")
        for k, (name, e) in enumerate(estimates.items()):
            ax.hlines(e[j] * ARCSEC_PER_RAD, dwell_end_s, t_s[-1], lw=1.4, ls=("-", "--", ":")[k % 3],
                      label=f"{name} estimate", color={"published": "C1", "improved": "C2"}.get(name, "C3"))
            parts.append(f"{name} {lab} {(e[j] - d[i_end]) * ARCSEC_PER_RAD:+.2f}")
        ax.axvline(dwell_end_s, color="grey", ls=":", lw=0.8)
        ax.set_ylabel(f"dtau_{lab} (arcsec)")
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # outside: never over a line
    axes[0].set_title("injected deviation and the estimates held from the star dwell's end (dotted line)",
                      fontsize=9)
    axes[1].set_xlabel("time (s)")
    after = slice(i_end, None)
    drift = max(float(np.ptp(dtau_x[after])), float(np.ptp(dtau_y[after]))) * ARCSEC_PER_RAD
    caption = (f"Estimate minus injected deviation at the dwell's end (t = {dwell_end_s:.0f} s), arcsec: "
               + ", ".join(parts) + f"; after the dwell the injected deviation still moves by up to "
               f"{drift:.2f} arcsec (peak to peak), which a held estimate cannot follow.")
    return figures.save(fig, path, caption)


def plot_scan_pattern(world, t_s, alpha_rad, beta_rad, scan, star, path: Path) -> Path:
    """The scan pattern in optical scan angles (E-W 2 (beta + 45 deg), N-S alpha) with the Earth
    disc seen from the nominal orbit, the area scans and the star dwell."""
    plt = _plt()
    ew = np.rad2deg(2 * (beta_rad + np.pi / 4))
    ns = np.rad2deg(alpha_rad)
    rdisc = np.rad2deg(np.arcsin(world.earth.radius_km / world.R0_km))
    fig, ax = plt.subplots(figsize=(7, 6))
    th = np.linspace(0, 2 * np.pi, 361)
    ax.fill(rdisc * np.cos(th), rdisc * np.sin(th), color="#cfe3f5", label="Earth disc")
    ax.plot(ew, ns, color="0.7", lw=0.5, label="mirror path")
    scans = np.unique(scan[scan > 0])
    boxes = []
    for k, s in enumerate(scans):
        m = scan == s
        if k == 0:
            ax.plot(ew[m], ns[m], lw=0.3, color="C1", alpha=0.5)
        # each scan's outline, in its own style: scans over the same field stay visible
        x0, x1, y0, y1 = ew[m].min(), ew[m].max(), ns[m].min(), ns[m].max()
        boxes.append((x0, x1, y0, y1))
        pad = 0.15 * k
        ax.plot([x0 - pad, x1 + pad, x1 + pad, x0 - pad, x0 - pad], [y0 - pad, y0 - pad, y1 + pad, y1 + pad, y0 - pad],
                lw=1.4, ls=("-", "--", ":", "-.")[k % 4], color=f"C{1 + k}", label=f"area scan {s} (outline)")
    if (star > 0).any():
        ax.plot(ew[star > 0], ns[star > 0], "r*", ms=10, label="star dwell")
    ax.set_aspect("equal")
    ax.set_xlabel("east-west optical angle 2 (beta + 45 deg) (deg)")
    ax.set_ylabel("north-south optical angle alpha (deg)")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("scan pattern in optical angles", fontsize=10)
    on = scan > 0
    span_ew = float(np.ptp(ew[on])) if on.any() else 0.0
    span_ns = float(np.ptp(ns[on])) if on.any() else 0.0
    dwell = ""
    if (star > 0).any():
        r = float(np.max(np.hypot(ew[star > 0], ns[star > 0])))
        dwell = (f"; the star dwell lies {r - rdisc:+.2f} deg from the Earth's limb "
                 f"({'off' if r > rdisc else 'on'} the disc)")
    same = len(boxes) > 1 and all(np.allclose(b, boxes[0], atol=1e-3) for b in boxes)
    caption = (f"{len(scans)} area scans " + ("cover the same field (their outlines drawn a little apart), "
                                               if same else "cover ")
               + f"{span_ew:.1f} x {span_ns:.1f} deg (E-W x N-S) of optical angle; the Earth disc has a radius of {rdisc:.2f} deg{dwell}.")
    return figures.save(fig, path, caption)
