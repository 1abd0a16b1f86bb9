"""The attitude study's report: what a pointing engineer reads (issue #34 item 4).

Findings in words first (:func:`findings_markdown`), then the figures, each caption stating
its point with numbers computed from what it draws:

* the error against the star count N, per axis (x, y, roll side by side), with the budget's
  eq 32 (N = 10) and its ``1 / sqrt(N)`` line and the improved prediction;
* the temporal / spatial split (ECSS-E-ST-60-20C: the spread over the frames, the pointing's
  bias), roll beside the cross-boresight axes;
* the fraction of pointings meeting the scenario's attitude requirement with at least K stars;
* sky maps (galactic coordinates) of N and of the error over the trials' pointings.

Everything is read from the run's own result (:class:`budget.runner.result.StudyResult`): its
samples and per-trial truths (:mod:`budget.attitude.study` names them) and its ``aux``.
The figures use 3 sigma, as seed 000 states its budget.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np

from budget import figures
from budget.runner.numbers import fmt
from budget.runner.study import ReportSection

__all__ = ["SkyRun", "details", "findings_markdown", "likely_cause", "report_sections", "sky_run"]

AXES = ("x", "y", "roll")
#: star-count bins of the figures (left edges; the last is open)
N_EDGES = (2, 4, 6, 8, 10, 12, 15, 20, 30, 50)


@dataclass(frozen=True)
class SkyRun:
    """One run's per-pointing figures (arrays over the trials, axes (x, y, roll) in the
    columns; arcsec, 1 sigma): the star count, the boresight, the blind draws; per variant
    the actual rms and mean square of one frame's error, the predicted 1-sigma, the spatial
    (frame mean) and temporal (spread) parts; the improved prediction's temporal and spatial
    1-sigma; the scenario's requirement."""

    n_stars: np.ndarray
    ra_deg: np.ndarray
    dec_deg: np.ndarray
    blind_draws: np.ndarray
    actual_ms: dict
    stated_rms: dict
    spatial: dict
    fov: dict
    pixel: dict
    temporal: dict
    pred_temporal: np.ndarray
    pred_spatial: np.ndarray
    pred_fov: np.ndarray
    requirement: object
    budget_3sigma: np.ndarray
    budget_n: int

    @property
    def drawn(self) -> int:
        """Attitudes drawn: the trials and the blind draws before them."""
        return int(self.n_stars.size + self.blind_draws.sum())

    def actual_rms(self, variant: str) -> np.ndarray:
        """Per pointing, the rms over its frames of the actual error (T, 3)."""
        return np.sqrt(self.actual_ms[variant])


def _column(result, cls: str, variant: str) -> np.ndarray:
    """The samples of ``(cls, variant, axis)`` per axis (T, 3); NaN for an axis the variant lacks."""
    cols = [result.samples.get((cls, variant, ax)) for ax in AXES]
    n = result.trials
    return np.column_stack([np.full(n, np.nan) if c is None else np.asarray(c, float) for c in cols])


def sky_run(result) -> SkyRun:
    """The per-pointing figures of ``result`` (:class:`SkyRun`)."""
    variants = ("published", "improved")
    aux = result.aux
    scn = result.scenario
    f = scn.onboard.frames
    return SkyRun(
        n_stars=np.asarray(aux["n_stars"], float), ra_deg=np.asarray(aux["ra_deg"], float),
        dec_deg=np.asarray(aux["dec_deg"], float), blind_draws=np.asarray(aux["blind_draws"], float),
        # one frame's mean square over the pointing's F frames: mean^2 + (F - 1) / F sd^2 (exact)
        actual_ms={v: _column(result, "spatial", v) ** 2
                   + (f - 1) / f * _column(result, "temporal", v) ** 2 for v in variants},
        stated_rms={v: _column(result, "stated_rms", v) for v in variants},
        spatial={v: _column(result, "spatial", v) for v in variants},
        fov={v: _column(result, "spatial_fov", v) for v in variants},
        pixel={v: _column(result, "spatial_pixel", v) for v in variants},
        temporal={v: _column(result, "temporal", v) for v in variants},
        pred_temporal=np.column_stack([np.asarray(aux[f"pred_temporal_{ax}"], float) for ax in AXES]),
        pred_spatial=np.column_stack([np.sqrt(np.maximum(np.asarray(result.sigmas[("spatial", "improved", ax)]) ** 2
                                                         - np.asarray(aux[f"pred_temporal_{ax}"]) ** 2 / f, 0.0))
                                      for ax in AXES]),
        pred_fov=np.column_stack([np.asarray(result.sigmas[("spatial_fov", "improved", ax)], float) for ax in AXES]),
        requirement=scn.requirement, budget_3sigma=np.array(scn.budget.single_star_3sigma_arcsec, float),
        budget_n=int(scn.budget.n_stars))


def _rms(a, axis=0):
    return np.sqrt(np.mean(np.asarray(a, float) ** 2, axis=axis))


def _per_axis(a) -> dict:
    """rms over the pointings per axis (a column of NaN, an axis without figures: None)."""
    a = np.asarray(a, float)
    return {ax: (float(_rms(a[:, j])) if np.isfinite(a[:, j]).all() else None) for j, ax in enumerate(AXES)}


def requirement_met(run: SkyRun, *, scale: float = 1.0, min_stars: int | None = None) -> float:
    """The fraction of the attitudes drawn (blind draws count as failing) whose pointing has at
    least ``min_stars`` stars (the requirement's by default) and 3 times its rms error
    (improved solve) within ``scale`` times the requirement on every axis."""
    req = run.requirement
    k = req.min_stars if min_stars is None else min_stars
    limit = scale * np.array([req.x_3sigma_arcsec, req.y_3sigma_arcsec, req.roll_3sigma_arcsec])
    ok = (run.n_stars >= k) & np.all(3.0 * run.actual_rms("improved") <= limit[None, :], axis=1)
    return float(np.count_nonzero(ok) / run.drawn)


def _share(run: SkyRun, variant: str) -> np.ndarray:
    """Per axis, the spatial part's share of one frame's mean square over the sky."""
    return np.mean(run.spatial[variant] ** 2, axis=0) / np.mean(run.actual_ms[variant], axis=0)


def summary(run: SkyRun) -> dict:
    """The headline figures of a run (arcsec, 1 sigma unless named), JSON-ready."""
    n = run.n_stars
    low, high = n <= 6, n >= 15
    out = {
        "pointings": int(n.size), "blind_draws": int(run.blind_draws.sum()),
        "n_stars": {"median": float(np.median(n)), "p05": float(np.percentile(n, 5)),
                    "p95": float(np.percentile(n, 95)), "below_budget_n": float(np.mean(n < run.budget_n))},
        "published_sigma_arcsec": (run.budget_3sigma / 3.0 / math.sqrt(run.budget_n)).tolist(),
        "requirement_met_fraction": requirement_met(run),
        "requirement_met_fraction_any_n": requirement_met(run, min_stars=2),
    }
    for v in ("published", "improved"):
        out[v] = {
            "actual_rms_arcsec": _per_axis(run.actual_rms(v)), "stated_rms_arcsec": _per_axis(run.stated_rms[v]),
            "spatial_share": dict(zip(AXES, _share(run, v).tolist())),
            "spatial_rms_arcsec": _per_axis(run.spatial[v]), "temporal_rms_arcsec": _per_axis(run.temporal[v]),
            "fov_rms_arcsec": _per_axis(run.fov[v]), "pixel_rms_arcsec": _per_axis(run.pixel[v]),
            "actual_rms_n_le_6": _per_axis(run.actual_rms(v)[low]) if low.any() else None,
            "actual_rms_n_ge_15": _per_axis(run.actual_rms(v)[high]) if high.any() else None,
        }
    cross = _rms(run.actual_rms("improved")[:, :2].ravel())
    out["roll_over_cross_boresight"] = float(_rms(run.actual_rms("improved")[:, 2]) / cross) if cross > 0 else None
    return out


def details(result) -> dict:
    """The study's figures for the JSON (under ``details``): :func:`summary` of the run."""
    return {"sky": summary(sky_run(result))}


def _x3(values) -> str:
    """Per-axis figures as ``a"/b"`` at 3 sigma."""
    return "/".join(f'{fmt(3.0 * v, 3)}"' for v in values)


def findings_markdown(run: SkyRun) -> str:
    """The findings in words, each sentence from the run's own numbers."""
    s = summary(run)
    ns = s["n_stars"]
    pub, imp = s["published"], s["improved"]
    act_p = [pub["actual_rms_arcsec"][a] for a in ("x", "y")]
    req = run.requirement
    lines = [
        (f"* **Stars in view.** Over {s['pointings']} pointings ({s['blind_draws']} more drawn had a frame with "
         f"fewer than 2 stars and were drawn again) the camera saw a median of {fmt(ns['median'], 3)} stars "
         f"(5-95 %: {fmt(ns['p05'], 3)}-{fmt(ns['p95'], 3)}); {fmt(100 * ns['below_budget_n'], 3)} % of pointings "
         f"have fewer than the budget's N = {run.budget_n}."),
        (f"* **Seed 000's eq 32** states {_x3(s['published_sigma_arcsec'])} (3 sigma, x/y) for every pointing; "
         f"one frame's actual error over the sky (equal weights, as eq 32 assumes) is {_x3(act_p)}: "
         f"{fmt(act_p[0] / s['published_sigma_arcsec'][0], 3)} and {fmt(act_p[1] / s['published_sigma_arcsec'][1], 3)} "
         "times the statement."),
        (f"* **Roll**, absent from the budget, is {fmt(s['roll_over_cross_boresight'], 3)} times the "
         f"cross-boresight error ({_x3([imp['actual_rms_arcsec']['roll']])} against "
         f"{_x3([imp['actual_rms_arcsec']['x'], imp['actual_rms_arcsec']['y']])}, 3 sigma, improved solve)."),
        ("* **Temporal and spatial.** The pointing's bias (the frames' mean error) holds "
         + ", ".join(f"{fmt(100 * imp['spatial_share'][a], 3)} %" for a in AXES)
         + " of one frame's mean square on x, y and roll; the spread over the frames the rest: frames at one "
         "pointing do not average it away. Of the bias, the smooth fields (FOV spatial error: the correction's "
         "residual, the lateral colour) give "
         + "/".join(f"{fmt(3 * imp['fov_rms_arcsec'][a], 3)}\"" for a in AXES)
         + " and the pixel-scale errors "
         + "/".join(f"{fmt(3 * imp['pixel_rms_arcsec'][a], 3)}\"" for a in AXES) + " (3 x rms, x/y/roll)."),
        (f"* **Improved prediction** (each star's TE for its electrons, this pointing's stars and geometry with "
         f"the roll lever arm, LSFE-S common to the stars) states "
         f"{_x3([imp['stated_rms_arcsec'][a] for a in AXES])} (x/y/roll) against an actual "
         f"{_x3([imp['actual_rms_arcsec'][a] for a in AXES])}."),
        (f"* **Requirement** ({fmt(req.x_3sigma_arcsec, 3)}\"/{fmt(req.y_3sigma_arcsec, 3)}\"/"
         f"{fmt(req.roll_3sigma_arcsec, 3)}\" 3 sigma on x/y/roll with at least {req.min_stars} stars): met at "
         f"{fmt(100 * s['requirement_met_fraction'], 3)} % of the pointings drawn "
         f"({fmt(100 * s['requirement_met_fraction_any_n'], 3)} % without the star minimum)."),
    ]
    if pub["actual_rms_n_le_6"] and pub["actual_rms_n_ge_15"]:
        lo, hi = pub["actual_rms_n_le_6"], pub["actual_rms_n_ge_15"]
        nl = float(np.mean(run.n_stars[run.n_stars <= 6]))
        nh = float(np.mean(run.n_stars[run.n_stars >= 15]))
        lines.insert(2, f"* **Not 1 / sqrt(N).** From N <= 6 (mean {fmt(nl, 3)}) to N >= 15 (mean {fmt(nh, 3)}) "
                        f"the error goes from {_x3([lo['x'], lo['y']])} to {_x3([hi['x'], hi['y']])} (x/y): a ratio "
                        f"of {fmt(lo['x'] / hi['x'], 3)} and {fmt(lo['y'] / hi['y'], 3)} where 1 / sqrt(N) gives "
                        f"{fmt(math.sqrt(nh / nl), 3)}.")
    return "\n".join(lines)


def _bins(n: np.ndarray):
    for lo, hi in pairwise([*N_EDGES, math.inf]):
        m = (n >= lo) & (n < hi)
        if np.count_nonzero(m) >= 3:
            yield lo, hi, m


def plot_error_vs_n(run: SkyRun, path: Path) -> Path:
    """One frame's error (3 x rms) against N per axis, binned, with the budget's lines and the
    improved prediction."""
    plt = figures.plt()
    from matplotlib.ticker import NullFormatter

    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    nb, lines = [], {"published": [], "improved": [], "pred": []}
    for lo, hi, m in _bins(run.n_stars):
        nb.append(float(np.mean(run.n_stars[m])))
        for v in ("published", "improved"):
            lines[v].append(3.0 * np.sqrt(np.mean(run.actual_ms[v][m], axis=0)))
        lines["pred"].append(3.0 * _rms(run.stated_rms["improved"][m]))
    nb = np.array(nb)
    grid = np.linspace(max(2.0, float(run.n_stars.min())), float(run.n_stars.max()), 100)
    for j, (ax, name) in enumerate(zip(axes, AXES)):
        ax.scatter(run.n_stars, 3.0 * run.actual_rms("published")[:, j], s=4, color="0.75", label="each pointing")
        ax.plot(nb, [r[j] for r in lines["published"]], "o-", color="C0", label="actual, equal weights")
        ax.plot(nb, [r[j] for r in lines["improved"]], "s--", color="C2", label="actual, weighted")
        ax.plot(nb, [r[j] for r in lines["pred"]], "^:", color="C3", label="improved prediction")
        if j < 2:
            b = run.budget_3sigma[j]
            ax.axhline(b / math.sqrt(run.budget_n), color="C1", lw=1.2, label=f"eq 32 (N = {run.budget_n})")
            ax.plot(grid, b / np.sqrt(grid), color="C1", ls="--", lw=1.0, label="single star / sqrt(N)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ticks = [t for t in (2, 3, 5, 10, 20, 50, 100) if t <= max(3.0, float(run.n_stars.max()) * 1.2)]
        ax.set_xticks(ticks, [str(t) for t in ticks])
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.set_xlabel("stars in view N")
        ax.set_ylabel(f"{name} error, 3 sigma (arcsec)")
        ax.set_title(f"{name}: one frame's error against N", fontsize=9)
        ax.legend(fontsize=7)
    i10 = int(np.argmin(np.abs(nb - run.budget_n))) if nb.size else None
    if i10 is None:
        return figures.save(fig, path, "Too few pointings to bin by star count.")
    a = lines["published"][i10]
    caption = (f"One frame's attitude error (3 x rms over the pointings in each bin of N) against the star count. "
               f"At N near {run.budget_n} (bin mean {fmt(nb[i10], 3)}) the actual error is "
               f"{fmt(a[0], 3)}\"/{fmt(a[1], 3)}\" on x/y against eq 32's "
               f"{fmt(run.budget_3sigma[0] / math.sqrt(run.budget_n), 3)}\"/"
               f"{fmt(run.budget_3sigma[1] / math.sqrt(run.budget_n), 3)}\"; roll reaches {fmt(a[2], 3)}\" there. "
               f"Over the bins the actual x error ranges {fmt(min(r[0] for r in lines['published']), 3)}-"
               f"{fmt(max(r[0] for r in lines['published']), 3)}\" where the sqrt(N) line spans "
               f"{fmt(run.budget_3sigma[0] / math.sqrt(nb.max()), 3)}-{fmt(run.budget_3sigma[0] / math.sqrt(nb.min()), 3)}\".")
    return figures.save(fig, path, caption)


def plot_split(run: SkyRun, path: Path) -> Path:
    """The spatial and temporal parts per axis (rms over the sky, 3 sigma), actual and predicted."""
    plt = figures.plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    x = np.arange(len(AXES))
    sp = 3.0 * _rms(run.spatial["improved"])
    fp = 3.0 * _rms(run.fov["improved"])
    pp = 3.0 * _rms(run.pixel["improved"])
    tp = 3.0 * _rms(run.temporal["improved"])
    psp = 3.0 * _rms(run.pred_spatial)
    pfp = 3.0 * _rms(run.pred_fov)
    ptp = 3.0 * _rms(run.pred_temporal)
    ax.bar(x - 0.3, sp, 0.19, color="C0", label="spatial (the pointing's bias), actual")
    ax.bar(x - 0.1, fp, 0.19, color="C1", label="of which FOV (smooth fields)")
    ax.bar(x + 0.1, pp, 0.19, color="C4", label="of which pixel")
    ax.bar(x + 0.3, tp, 0.19, color="C2", label="temporal (spread over frames), actual")
    ax.plot(x - 0.3, psp, "v", color="k", ms=8, label="improved prediction")
    ax.plot(x - 0.1, pfp, "v", color="k", ms=8)
    ax.plot(x + 0.3, ptp, "v", color="k", ms=8)
    ax.set_xticks(x, AXES)
    ax.set_yscale("log")
    ax.set_ylabel("rms over the pointings, 3 sigma (arcsec)")
    ax.set_title("temporal and spatial error per axis (weighted solve)", fontsize=9)
    ax.legend(fontsize=8)
    caption = ("The attitude error split as ECSS-E-ST-60-20C does, rms over the pointings (3 sigma, weighted solve): "
               + "; ".join(f"{a}: spatial {fmt(sp[j], 3)}\" (predicted {fmt(psp[j], 3)}\"; FOV {fmt(fp[j], 3)}\", "
                           f"predicted {fmt(pfp[j], 3)}\"; pixel {fmt(pp[j], 3)}\"), temporal "
                           f"{fmt(tp[j], 3)}\" (predicted {fmt(ptp[j], 3)}\")" for j, a in enumerate(AXES))
               + f". Roll's spatial part is {fmt(sp[2] / np.sqrt(np.mean(sp[:2] ** 2)), 3)} times the "
               "cross-boresight one.")
    return figures.save(fig, path, caption)


def plot_requirement(run: SkyRun, path: Path) -> Path:
    """The fraction of pointings meeting the requirement against a scale on it, with and
    without the star minimum."""
    plt = figures.plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    scales = np.geomspace(0.1, 10.0, 81)
    req = run.requirement
    with_k = [requirement_met(run, scale=s) for s in scales]
    any_n = [requirement_met(run, scale=s, min_stars=2) for s in scales]
    ax.plot(scales, with_k, color="C0", label=f"N >= {req.min_stars}")
    ax.plot(scales, any_n, color="C1", ls="--", label="any N >= 2")
    ax.axvline(1.0, color="k", lw=0.8)
    ax.set_xscale("log")
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("requirement scale (1 = the scenario's)")
    ax.set_ylabel("fraction of pointings meeting it")
    ax.set_title(f"requirement {fmt(req.x_3sigma_arcsec, 3)}\"/{fmt(req.y_3sigma_arcsec, 3)}\"/"
                 f"{fmt(req.roll_3sigma_arcsec, 3)}\" (x/y/roll, 3 sigma)", fontsize=9)
    ax.legend(fontsize=8)
    at = requirement_met(run)
    half = next((s for s, f in zip(scales, with_k) if f >= 0.95), None)
    enough = float(np.count_nonzero(run.n_stars >= req.min_stars) / run.drawn)
    caption = (f"The fraction of pointings (blind draws counted as failing) where the weighted solve's 3 x rms error "
               f"is within the requirement scaled on every axis: {fmt(100 * at, 3)} % at the scenario's requirement "
               f"with at least {req.min_stars} stars, which {fmt(100 * enough, 3)} % of the pointings have"
               + (f"; 95 % is reached at {fmt(half, 3)} times it." if half
                  else "; 95 % is not reached within 10 times it."))
    return figures.save(fig, path, caption)


def _galactic(ra_deg, dec_deg):
    from astropy.coordinates import SkyCoord

    g = SkyCoord(ra=ra_deg, dec=dec_deg, unit="deg", frame="icrs").galactic
    lon = np.radians(g.l.wrap_at("180d").deg)
    return -lon, np.radians(g.b.deg)  # longitude increasing to the left, as the sky is seen


def plot_sky_maps(run: SkyRun, path: Path) -> Path:
    """Two galactic Mollweide maps over the pointings: the star count and the error."""
    plt = figures.plt()
    fig = plt.figure(figsize=(13, 4.4))
    lon, lat = _galactic(run.ra_deg, run.dec_deg)
    err = 3.0 * np.sqrt(np.mean(run.actual_ms["improved"][:, :2], axis=1))
    panels = ((run.n_stars, "stars in view N"), (err, "cross-boresight error, 3 x rms (arcsec)"))
    for i, (values, label) in enumerate(panels):
        ax = fig.add_subplot(1, 2, i + 1, projection="mollweide")
        top = float(np.percentile(values, 95))  # a few sparse pointings would wash out the rest
        sc = ax.scatter(lon, lat, c=np.minimum(values, top), s=6, cmap="viridis", vmax=top)
        ax.grid(True, lw=0.3)
        ax.set_xticklabels([])
        ax.set_title(label + " (galactic)", fontsize=9)
        fig.colorbar(sc, ax=ax, orientation="horizontal", fraction=0.05, pad=0.05, extend="max")
    b = np.degrees(np.abs(lat))
    plane, pole = b < 20.0, b > 60.0
    parts = []
    if plane.any() and pole.any():
        parts.append(f"Near the galactic plane (|b| < 20 deg) the median N is {fmt(np.median(run.n_stars[plane]), 3)} "
                     f"against {fmt(np.median(run.n_stars[pole]), 3)} near the poles (|b| > 60 deg), and the "
                     f"cross-boresight error {fmt(_rms(err[plane]), 3)}\" against {fmt(_rms(err[pole]), 3)}\"")
    caption = ("The trials' boresights in galactic coordinates, coloured by the star count and by the weighted "
               "solve's cross-boresight error (3 x rms over the frames; colours end at the 95th percentile). "
               + ("; ".join(parts) + "." if parts else ""))
    return figures.save(fig, path, caption.strip())


def report_sections(result, out_dir: Path) -> list[ReportSection]:
    """The study's sections: the findings in words, then the figures with their captions."""
    run = sky_run(result)
    figs = [plot_error_vs_n(run, out_dir / "attitude_error_vs_n.png"),
            plot_split(run, out_dir / "attitude_temporal_spatial.png"),
            plot_requirement(run, out_dir / "attitude_requirement.png"),
            plot_sky_maps(run, out_dir / "attitude_sky_maps.png")]
    intro = ("Each trial is one pointing: a random attitude (boresight uniform on the sphere, random roll), "
             f"{result.scenario.onboard.frames} frames observed as onboard and each solved twice (equal weights, "
             "as eq 32 assumes: `published`; each star weighted by the lab's per-star error for its brightness: "
             "`improved`). Errors are the solved against the true attitude, never the solver's covariance; "
             "figures at 3 sigma, as seed 000 states its budget.")
    return [ReportSection("Attitude on the sky: findings", findings_markdown(run)),
            ReportSection("Attitude on the sky: figures", intro + "\n\n" + figures.figure_markdown(figs))]


def likely_cause(result, key, stats) -> str | None:
    """Why a class is past its truth, one sentence from the run's numbers (None elsewhere)."""
    cls, variant, ax = key
    run = sky_run(result)
    if cls == "spatial":
        return (f"a static error common to the sky (mean {fmt(stats['mean'], 3)}\" over the pointings): what the "
                "camera's onboard correction leaves for the sky's stars (their colours against the lamp it was "
                "fitted with, its own calibration), which no number of stars or frames averages.")
    if cls == "spatial_fov":
        return (f"the smooth fields' bias (mean {fmt(stats['mean'], 3)}\" over the pointings): the onboard "
                "correction's residual and the lateral colour of the sky's stars against the lamp it was fitted with.")
    if cls == "spatial_pixel":
        return (f"the pixel-scale bias (mean {fmt(stats['mean'], 3)}\" over the pointings): pixel phase, PRNU and "
                "non-linearity of this pointing's stars, and the frames' mean temporal noise.")
    if cls == "temporal":
        return "a spread over the frames is positive by definition: its truth 0 is a bound; this is the temporal noise."
    share = _share(run, variant)[AXES.index(ax)]
    if variant == "published":
        return (f"eq 32 assumes {run.budget_n} equal, independent stars; the pointings have a median of "
                f"{fmt(np.median(run.n_stars), 3)}, and the pointing's bias, which does not fall as 1 / sqrt(N), "
                f"holds {fmt(100 * share, 3)} % of the error on {ax}.")
    j = AXES.index(ax)
    ratio = _rms(run.spatial["improved"][:, j]) / _rms(run.pred_spatial[:, j])
    return (f"the pointing's actual bias on {ax} (rms {fmt(_rms(run.spatial['improved'][:, j]), 3)}\") is "
            f"{fmt(ratio, 3)} times its predicted 1-sigma: the lab's static figures (HSFE, LSFE) do not describe "
            "this camera's static error on the sky.")
