"""Validation report: a Markdown page with PNG figures, and the terminal table.

Figures (matplotlib, Agg backend):

* ``estimates.png``: for each class and axis, the distribution of the published and
  improved estimates over the trials, against the truth;
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

CLASS_TITLES = {
    "te": "TE (temporal)", "hsfe": "HSFE (pixel spatial)", "lsfe_s": "LSFE-S (chromatic)",
    "lsfe_c1": "LSFE-C1 (distortion)", "lsfe_c2": "LSFE-C2 (marker)", "lsfe": "LSFE (combined)",
    "total": "single-star total",
}


def format_table(summary: dict) -> str:
    """Terminal table: truth, then mean +- std and bias % of each variant (arcsec, 3 sigma)."""
    head = f"{'class':<10}{'axis':<5}{'truth':>8}  {'published mean+-std':>22} {'bias':>8}  {'improved mean+-std':>22} {'bias':>8}"
    lines = [head, "-" * len(head)]
    for cls, axes in summary.items():
        for ax, d in axes.items():
            p, i = d["published"], d["improved"]

            def pct(v):
                if v.get("role") == "input":
                    return "   input "
                b = v["bias_percent"]
                mark = "*" if v["bias_significant"] else " "
                return f"{b:+7.0f}%{mark}" if np.isfinite(b) else "     n/a "

            lines.append(
                f"{cls:<10}{ax:<5}{p['truth']:>8.3f}  {p['mean']:>12.3f} +- {p['std']:<6.3f} {pct(p)}"
                f"  {i['mean']:>12.3f} +- {i['std']:<6.3f} {pct(i)}"
            )
    lines.append("arcsec, 3 sigma; * = bias significant (|bias| > 3 standard errors of the mean estimate and "
                 "the truth combined); input = given to the lab (LSFE-C2), not a result")
    return "\n".join(lines)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_estimates(result, path: Path) -> None:
    """Histograms of the estimates of each class against the truth."""
    plt = _plt()
    classes = ["te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe", "total"]
    f = 3.0 * result.scenario.camera.scale_arcsec_per_px
    fig, axs = plt.subplots(len(classes), 2, figsize=(10, 2.3 * len(classes)))
    for r, cls in enumerate(classes):
        for c, ax in enumerate(("x", "y")):
            a = axs[r, c]
            truth = getattr(result.truths[cls], f"{ax}_px") * f
            for var, col in (("published", "tab:red"), ("improved", "tab:blue")):
                v = np.asarray(result.samples[(cls, var, ax)]) * f
                a.hist(v, bins=30, alpha=0.5, color=col, label=var)
            a.axvline(truth, color="k", lw=2, label="truth")
            a.set_title(f"{CLASS_TITLES[cls]}, {ax}", fontsize=9)
            a.tick_params(labelsize=8)
            a.set_ylabel("trials", fontsize=8)
            a.set_xlabel("estimate (arcsec, 3 sigma)", fontsize=8)
    axs[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


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


def finding_sentences(classes: dict, truth_details: dict) -> list[str]:
    """One sentence per class, axis and variant: what the estimator reports against its truth."""
    out = []
    for cls, axes in classes.items():
        for ax, d in axes.items():
            for var in ("published", "improved"):
                v = d[var]
                name = f"{CLASS_TITLES[cls]}, {ax}, {var}"
                if v.get("role") == "input":
                    out.append(f"* {name}: {v['mean']:.3f} arcsec is the given marker error, an input, "
                               "not validated.")
                    continue
                truth = f"{v['truth']:.3f}" + (f" +- {v['se_truth']:.3f}" if v.get("se_truth", 0) > 0 else "")
                if np.isfinite(v["bias_percent"]):
                    rel = f"{v['bias_percent']:+.0f} %"
                else:
                    rel = f"{v['bias']:+.3f} arcsec"
                verdict = ("a significant bias" if v["bias_significant"]
                           else "no significant bias")
                out.append(f"* {name}: mean {v['mean']:.3f} +- {v['std']:.3f} (sd over trials) against a "
                           f"truth of {truth}: {rel}, {verdict} (standard error {v['se_bias']:.3f}); the "
                           f"truth is {'inside' if v['truth_in_95'] else 'outside'} the 95 % interval "
                           "of the estimates.")
    return out


def write_report(result, out_dir: str | Path) -> Path:
    """Write report.md, the figures, scenario.toml and summary.json into ``out_dir``."""
    from simcam.cli_common import write_json_atomic
    from simcam.io import atomic_directory
    from simcam.scenario import scenario_to_toml

    out = Path(out_dir)
    payload = result.to_json()
    with atomic_directory(out, overwrite=True) as tmp:
        plot_estimates(result, tmp / "estimates.png")
        ex = result.example
        figs = ["estimates.png"]
        if "hsfe" in ex:
            plot_hsfe_residuals(ex["hsfe"]["estimates"]["published"], tmp / "hsfe_residuals.png")
            figs.append("hsfe_residuals.png")
        if "chromatic" in ex:
            plot_chromatic_residuals(ex["chromatic"]["data"].centroids, tmp / "chromatic_residuals.png",
                                     result.scenario.protocols.chromatic.reference_filter_nm)
            figs.append("chromatic_residuals.png")
        if "distortion" in ex:
            plot_distortion_residuals(ex["distortion"]["estimates"]["published"], tmp / "distortion_residuals.png")
            figs.append("distortion_residuals.png")
        (tmp / "scenario.toml").write_text(scenario_to_toml(result.scenario))
        write_json_atomic(tmp / "summary.json", payload)
        t = payload["truth_details"]
        lines = [
            f"# Validation of the seed-000 lab methods: {result.scenario.name}",
            "",
            f"* scenario hash `{result.scenario.hash}`, seed {result.seed}, simcam/budget {payload['version']}",
            f"* {result.trials} trials (stopped by {result.stopped_by}); plate scale "
            f"{result.scenario.camera.scale_arcsec_per_px:g} arcsec/px; all values arcsec, 3 sigma",
            f"* TE truth from {t['te'].get('frames', '?')} noise-only frames: x {t['te']['x']:.3f}, y {t['te']['y']:.3f}; "
            f"Cramer-Rao bound x {t['te']['cramer_rao_x_px'] * 3 * result.scenario.camera.scale_arcsec_per_px:.3f}, "
            f"y {t['te']['cramer_rao_y_px'] * 3 * result.scenario.camera.scale_arcsec_per_px:.3f}",
            "",
            "## What is compared",
            "",
            "* **truth**: the quantity each method claims to measure, computed from the injected physics "
            "by a route that shares nothing with the estimators (budget.truth): TE, the mean temporal "
            "centroid sd; HSFE, the rms static error of the expected centroid under the lab's noise; "
            "LSFE-S, the rms chromatic displacement of the stellar population about its reference "
            f"({result.scenario.validation.calibration_spectrum}); LSFE-C1, what the camera "
            + ("still displaces after its own distortion correction"
               if result.scenario.optics.distortion_correction.kind != "none"
               else "a cubic calibration would leave (uncalibrated camera)")
            + "; LSFE-C2, the given marker error (an input). TE and HSFE truths are Monte Carlo "
            "estimates and carry a standard error (se).",
            "* **published**: seed 000's own estimator of each class (eqs 1-2, 3-12, 13-16, 17-30, 31).",
            "* **improved**: the estimator derived in docs/estimators.md that targets the truth with "
            "only what a lab knows (its own, imperfect spectral model; the marker error it was given).",
            "",
            "## Summary",
            "",
            "| class | axis | truth | variant | mean | bias | bias % | std | 95 % interval | significant |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for cls, axes in payload["classes"].items():
            for ax, d in axes.items():
                for var in ("published", "improved"):
                    v = d[var]
                    lines.append(
                        f"| {CLASS_TITLES[cls]} | {ax} | {v['truth']:.3f} | {var} | {v['mean']:.3f} | {v['bias']:+.3f} | "
                        f"{v['bias_percent']:+.0f} | {v['std']:.3f} | [{v['interval_95'][0]:.3f}, {v['interval_95'][1]:.3f}] | "
                        f"{'yes' if v['bias_significant'] else 'no'} |"
                    )
        lines += ["", "## Findings", ""] + finding_sentences(payload["classes"], payload["truth_details"])
        lines += ["", "## Figures", ""]
        captions = {
            "estimates.png": "Distribution of each estimate over the trials (published red, improved blue) against the truth (black); LSFE-C2 is an input and not shown.",
            "hsfe_residuals.png": "HSFE residuals per star and condition step, one trial (seed 000 fig. 6).",
            "chromatic_residuals.png": "Colour differences of each star per corner field, one trial (seed 000 fig. 7).",
            "distortion_residuals.png": "Distortion residuals at the grid points before and after the cubic fit, one trial (seed 000 fig. 8); the key gives the longest arrow.",
        }
        for f_ in figs:
            lines += [f"![{f_}]({f_})", "", captions[f_], ""]
        lines += ["## Scenario", "", "```toml", scenario_to_toml(result.scenario).rstrip(), "```", ""]
        (tmp / "report.md").write_text("\n".join(lines))
    return out / "report.md"
