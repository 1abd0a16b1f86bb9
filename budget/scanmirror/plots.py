"""Plots of the scan-mirror study and of ``budget scanmirror simulate`` (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_dtau_errors", "plot_trial_ground_errors", "plot_ground_error_maps", "plot_deviation_timeline",
           "plot_scan_pattern"]


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_dtau_errors(result, path: Path) -> Path:
    """Histograms of estimate minus injected deviation (arcsec), per axis and variant."""
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, axis in zip(axes, ("x", "y")):
        for v in ("published", "improved"):
            key = ("dtau", v, axis)
            if key in result.samples:
                err = result.samples[key] - result.trial_truths[key]
                ax.hist(err, bins=40, histtype="step", label=f"{v} (mean {err.mean():+.2f}, std {err.std():.2f})")
        ax.set_xlabel(f"estimated - injected dtau_{axis} (arcsec)")
        ax.set_ylabel("trials")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _nominal_latlon(world, g0):
    lat, lon = world.latlon(g0)
    return np.rad2deg(lat), np.rad2deg(lon)


def plot_trial_ground_errors(study, scenario, extra: dict, path: Path) -> Path:
    """Latitude and longitude errors (deg) against time over the last scan, for each variant."""
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    t = extra["t_s"]
    for name, (lat, lon) in extra["errors"].items():
        axes[0].plot(t, lat, lw=0.8, label=name)
        axes[1].plot(t, lon, lw=0.8, label=name)
    axes[0].set_ylabel("latitude error (deg)")
    axes[1].set_ylabel("longitude error (deg)")
    axes[1].set_xlabel("time (s)")
    axes[0].set_yscale("symlog", linthresh=1e-3)
    axes[1].set_yscale("symlog", linthresh=1e-3)
    axes[0].legend(fontsize=8, ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_ground_error_maps(world, setup, out: dict, path: Path) -> Path:
    """Ground error maps of every area scan: |error| (deg) at the nominal ground points, one row
    per scan, one column per compensation (uncompensated, without estimate, published, improved)."""
    plt = _plt()
    scans = sorted(out["errors"])
    names = ("uncompensated", "without_estimate", "published", "improved")
    fig, axes = plt.subplots(len(scans), len(names), figsize=(4 * len(names), 3.4 * len(scans)), squeeze=False)
    lat0, lon0 = _nominal_latlon(world, setup.g0)
    # panels that are compared share one colour scale (logarithmic: the compensations differ
    # by orders of magnitude), with one colour bar
    from matplotlib.colors import LogNorm

    mags = np.concatenate([np.hypot(*out["errors"][s][n]).ravel() for s in scans for n in names])
    pos = mags[mags > 0]
    norm = LogNorm(vmin=max(float(pos.min()), float(pos.max()) * 1e-6), vmax=float(pos.max())) if pos.size else None
    sc = None
    for i, s in enumerate(scans):
        sel = setup.scan == s
        for j, n in enumerate(names):
            ax = axes[i, j]
            lat, lon = out["errors"][s][n]
            mag = np.hypot(lat, lon)
            sc = ax.scatter(lon0[sel], lat0[sel], c=np.maximum(mag, norm.vmin) if norm else mag, s=2,
                            cmap="viridis", norm=norm)
            ax.set_title(f"scan {s}: {n}\nmax lat {np.abs(lat).max():.4f}, lon {np.abs(lon).max():.4f} deg", fontsize=8)
            ax.set_xlabel("nominal longitude (deg E)")
            ax.set_ylabel("nominal latitude (deg N)")
    fig.tight_layout()
    if sc is not None:
        fig.colorbar(sc, ax=axes.ravel().tolist(), label="|error| (deg), one scale for every panel", shrink=0.8)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return Path(path)


def plot_deviation_timeline(t_s, dtau_x, dtau_y, estimates: dict, dwell_end_s: float, path: Path) -> Path:
    """The injected deviation (arcsec) over the timeline and the estimates from the star dwell,
    held from the dwell's end on."""
    plt = _plt()
    arc = 180 / np.pi * 3600
    fig, axes = plt.subplots(2, 1, figsize=(10, 5), sharex=True)
    for ax, d, j, lab in ((axes[0], dtau_x, 0, "x"), (axes[1], dtau_y, 1, "y")):
        ax.plot(t_s, d * arc, "k", lw=1, label="injected")
        for name, e in estimates.items():
            ax.hlines(e[j] * arc, dwell_end_s, t_s[-1], lw=1.2, label=f"{name} estimate",
                      color={"published": "C1", "improved": "C2"}.get(name, "C3"))
        ax.axvline(dwell_end_s, color="grey", ls=":", lw=0.8)
        ax.set_ylabel(f"dtau_{lab} (arcsec)")
        ax.legend(fontsize=8)
    axes[1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


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
    for s in np.unique(scan[scan > 0]):
        ax.plot(ew[scan == s], ns[scan == s], lw=0.4, label=f"area scan {s}")
    if (star > 0).any():
        ax.plot(ew[star > 0], ns[star > 0], "r*", ms=10, label="star dwell")
    ax.set_aspect("equal")
    ax.set_xlabel("east-west optical angle 2 (beta + 45 deg) (deg)")
    ax.set_ylabel("north-south optical angle alpha (deg)")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
