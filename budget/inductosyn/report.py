"""Seed 001's own figures in the runner's result: the ``details`` of its JSON and the
sections and plots of its report (:meth:`~budget.runner.capabilities.Presented.report_sections`).

Everything here is computed from what the runner kept of the trials of
:class:`budget.inductosyn.study.InductosynStudy`: the estimates and per-trial truths of
its classes, the per-trial figures in ``aux`` and trial 0's tables in ``extra``. Nothing
is simulated again, except the Fourier truth of the drifted encoder (seed 001
section 4.3), which is a property of the scenario and the seed, and the emcee posterior
of trial 0's joint fit for the band plot.

3 sigma is 3 x the sample standard deviation (ddof = 1), as seed 001 computes it
(:func:`budget.inductosyn.harmonics.sigma3_arcsec`); a figure over trials is given as
mean [5 %, 95 %].
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget.figures import figure_markdown, overlaid_hist, save
from budget.figures import plt as pyplot  # matplotlib.pyplot, set up on first use
from budget.inductosyn.harmonics import COEFFICIENTS, PUBLISHED_COEFFICIENTS, fit_joint, posterior_band
from budget.runner.numbers import fmt
from budget.runner.study import ReportSection
from simcam.units import ARCSEC_PER_DEG

__all__ = ["FIGURES", "details", "drift_figures", "figure_arrays", "report_sections",
           "sequence_coefficients", "summary_lines"]

#: per-trial figures: name -> what it is, in words (report rows, JSON keys of ``details``)
FIGURES = {
    "long_sigma3_before_arcsec": "24-face table before compensation (paper Table 1, before)",
    "long_sigma3_after_arcsec": "24-face re-measurement after the eq 7 compensation (Table 1, after)",
    "short_sigma3_before_arcsec": "23-face table, long period compensated, before eq 8 (Table 2, before)",
    "short_sigma3_after_arcsec": "23-face re-measurement after eq 7 + eq 8 (Table 2, after)",
    "joint_short_sigma3_after_arcsec": "23-face re-measurement after the joint fit (improved)",
    "dense_sigma3_after_arcsec": "true error over the whole turn after eq 9 (in sequence)",
    "joint_dense_sigma3_after_arcsec": "true error over the whole turn after the joint fit",
    "dense_maxabs_after_arcsec": "max |true error - mean| over the turn after eq 9 (in sequence)",
    "joint_dense_maxabs_after_arcsec": "max |true error - mean| over the turn after the joint fit",
}

E0_NOTE = ("zero offset: includes the polygon mounting offset and the short-period error at integer "
           "degrees; not observable with a polygon (eq 8's own table offset is a nuisance term, not listed)")


def _stat(x) -> dict:
    """mean, sample std (ddof 1), 5 %, 50 % and 95 % quantiles of a per-trial figure."""
    x = np.asarray(x, dtype=float)
    return {"mean": float(np.mean(x)), "std": float(np.std(x, ddof=1)) if x.size > 1 else 0.0,
            "p05": float(np.quantile(x, 0.05)), "p50": float(np.median(x)),
            "p95": float(np.quantile(x, 0.95))}


def figure_arrays(result) -> dict[str, np.ndarray]:
    """Each figure of :data:`FIGURES` per trial, from the run's classes and ``aux``."""
    s, t, a = result.samples, result.trial_truths, result.aux
    return {
        "long_sigma3_before_arcsec": a["long_sigma3_before_arcsec"],
        "long_sigma3_after_arcsec": a["long_sigma3_after_arcsec"],
        "short_sigma3_before_arcsec": s[("before", "published", "angle")],
        "short_sigma3_after_arcsec": s[("residual", "published", "angle")],
        "joint_short_sigma3_after_arcsec": s[("residual", "improved", "angle")],
        "dense_sigma3_after_arcsec": t[("residual", "published", "angle")],
        "joint_dense_sigma3_after_arcsec": t[("residual", "improved", "angle")],
        "dense_maxabs_after_arcsec": a["dense_maxabs_after_arcsec"],
        "joint_dense_maxabs_after_arcsec": a["joint_dense_maxabs_after_arcsec"],
    }


def sequence_coefficients(result) -> np.ndarray:
    """The in-sequence coefficient vector of every trial (e0, A_L1c..A_L2s, A_S1c..A_S2s),
    the same numbers as ``run_trials``' ``c_long`` and ``c_short`` side by side."""
    cols = [result.aux["e0_in_sequence_arcsec"]]
    cols += [result.samples[("coefficient", "published", nm)] for nm in PUBLISHED_COEFFICIENTS]
    return np.stack(cols, axis=1)


def _fits(c_seq: np.ndarray) -> np.ndarray:
    """The in-sequence coefficients (e0, A_L.., A_S1c..A_S2s; rows) in the truth's layout
    (A_L1c .. A_S4s, electrical 3-4 not fitted: 0)."""
    c = np.atleast_2d(c_seq)
    return np.concatenate([c[:, 1:], np.zeros((c.shape[0], 4))], axis=1)


def drift_figures(prepared, c_seq: np.ndarray, seed: int) -> dict:
    """3 sigma and max |error - mean| over the turn of the encoder after drift (seed 001
    section 4.3), compensated by each trial's in-sequence coefficients.

    The drift is one realisation, the draws of :func:`simcam.encoder.inductosyn.apply_drift`
    seeded by the run seed (``drift_seed``), of trial 0's instrument; the truth is the Fourier
    truth with the drift's columns (:mod:`budget.inductosyn.truth`). (Class ``environment``
    draws a drift per trial.)
    """
    from budget.inductosyn.validate import instrument_draws

    p = prepared
    a0 = instrument_draws(scenario=p.scenario, seed=seed, trials=[0])[1]
    z = np.random.default_rng(np.random.SeedSequence(seed)).standard_normal(7)  # apply_drift's draws
    fits = _fits(c_seq)
    a = np.repeat(np.concatenate([a0, z[None, :]], axis=1), fits.shape[0], axis=0)
    return {"drift_seed": seed, "dense_sigma3_after_drift_arcsec": _stat(p.truth.sigma3_after_arcsec(a, fits)),
            "dense_maxabs_after_drift_arcsec": _stat(p.truth.maxabs_after_arcsec(a, fits)[0])}


def details(result, prepared) -> dict:
    """The seed-001 figures of a run (JSON-ready; the result JSON's ``details``).

    Keys: ``dense_step_deg``, ``dense_points`` (the truth's grid of readings),
    ``dense_sigma3_before_arcsec`` (the class ``before``'s truth: the mean over the trials'
    instruments, or the pinned one's), ``dense_maxabs_before_arcsec`` (trial 0's instrument);
    each key of :data:`FIGURES` with its mean, std and 5/50/95 % quantiles over trials; ``e0``
    (the constant, per variant, against each trial's true mean error); ``acceptance_rate``
    (seed 001 section 3.1: the 23-face verification within requirement/3); the drift figures
    (:func:`drift_figures`). The per-coefficient bias and spread are the runner's statistics
    of class ``coefficient``.
    """
    from budget.inductosyn.validate import instrument_draws

    p = prepared
    sc = p.scenario
    figs = figure_arrays(result)
    a0 = instrument_draws(scenario=sc, seed=result.seed, trials=[0])[1]
    before = p.truth.series_arcsec(a0[0])
    before_truth = result.trial_truths.get(("before", "published", "angle"))
    out = {"dense_step_deg": float(360.0 / p.truth.n), "dense_points": int(p.truth.n),
           "dense_sigma3_before_arcsec": float(np.mean(before_truth)) if before_truth is not None
           else float(result.truths[("before", "angle")].value),
           "dense_maxabs_before_arcsec": float(np.max(np.abs(before - before.mean())))}
    out.update({k: _stat(v) for k, v in figs.items()})
    ref = result.aux["true_e0_arcsec"]
    out["e0"] = {"reference_arcsec": float(np.mean(ref)), "note": E0_NOTE}
    for lab, key in (("in_sequence", "e0_in_sequence_arcsec"), ("joint", "e0_joint_arcsec")):
        x = result.aux[key] - ref
        out["e0"][lab] = {"bias_arcsec": float(x.mean()),
                          "spread_arcsec": float(result.aux[key].std(ddof=1)) if x.size > 1 else 0.0}
    req = sc.calibration.requirement_arcsec
    out["acceptance_rate"] = {
        "in_sequence": float(np.mean(figs["short_sigma3_after_arcsec"] <= req / 3)),
        "joint": float(np.mean(figs["joint_short_sigma3_after_arcsec"] <= req / 3)),
        "requirement_arcsec": req}
    out.update(drift_figures(p, sequence_coefficients(result), result.seed))
    return out


def _band(v: dict) -> str:
    """A figure's mean and 5 % - 95 % band over the trials, ``mean [p05, p95]``, in arcsec to
    0.001 (fixed decimals: the resolution the paper's figures are read at)."""
    return f"{v['mean']:.3f} [{v['p05']:.3f}, {v['p95']:.3f}]"


def summary_lines(result) -> list[str]:
    """What ``budget harmonics validate`` prints after the runner's table."""
    d = result.details()
    return [
        f"truth points {d['dense_points']} (step {d['dense_step_deg']:g} deg); 3 sigma, arcsec: mean [5%, 95%]",
        f"3 sigma before (dense truth): {d['dense_sigma3_before_arcsec']:.3f} arcsec",
        f"long  period 24 faces: before {_band(d['long_sigma3_before_arcsec'])}  "
        f"after {_band(d['long_sigma3_after_arcsec'])}",
        f"short period 23 faces: before {_band(d['short_sigma3_before_arcsec'])}  "
        f"after {_band(d['short_sigma3_after_arcsec'])}",
        f"dense residual 3 sigma: in sequence {_band(d['dense_sigma3_after_arcsec'])}  "
        f"joint {_band(d['joint_dense_sigma3_after_arcsec'])}",
        f"dense max |residual - mean|: in sequence {_band(d['dense_maxabs_after_arcsec'])}  "
        f"joint {_band(d['joint_dense_maxabs_after_arcsec'])}",
        f"after drift (in sequence): {d['dense_sigma3_after_drift_arcsec']['mean']:.3f} arcsec 3 sigma",
    ]


def _figures_markdown(result, d: dict) -> str:
    lines = [f"Truth on {d['dense_points']} readings (step {d['dense_step_deg']:g} deg). "
             "3 sigma (3 x sample std, as the paper computes it), arcsec: mean [5%, 95%] over trials.", "",
             "| figure | value |", "|---|---|",
             f"| dense truth before | {d['dense_sigma3_before_arcsec']:.2f} |"]
    lines += [f"| {label} | {_band(d[k])} |" for k, label in FIGURES.items()]
    a = d["acceptance_rate"]
    lines += [f"| dense 3 sigma after drift (in sequence, drift seed {d['drift_seed']}) | "
              f"{_band(d['dense_sigma3_after_drift_arcsec'])} |", "",
              f"Acceptance (23-face verification within requirement/3 = {a['requirement_arcsec'] / 3:.2f} "
              f"arcsec): in sequence {a['in_sequence']:.3f}, joint {a['joint']:.3f}."]
    return "\n".join(lines)


def _coefficients_markdown(result, d: dict) -> str:
    lines = ["Bias (mean - truth, +- its standard error) and spread (sample std) over trials, arcsec; the "
             "truth is the projection of the continuous true error, as a function of the reading, on "
             "the same harmonics. A `*` marks a bias beyond 3 standard errors.", "",
             "| coefficient | truth | in-seq bias | in-seq spread | joint bias | joint spread |",
             "|---|---|---|---|---|---|"]
    e0 = d["e0"]
    lines.append(f"| e0 | {e0['reference_arcsec']:.3f} | {e0['in_sequence']['bias_arcsec']:.3f} | "
                 f"{e0['in_sequence']['spread_arcsec']:.3f} | {e0['joint']['bias_arcsec']:.3f} | "
                 f"{e0['joint']['spread_arcsec']:.3f} |")
    for nm in COEFFICIENTS:
        cells = []
        truth = None
        for var in ("published", "improved"):
            key = ("coefficient", var, nm)
            if key not in result.samples:
                cells += ["-", "-"]
                continue
            st = result.statistics(key)
            truth = st["truth"]
            cells += [f"{st['bias']:.4f} +- {st['se_bias']:.4f}" + (" *" if st["bias_significant"] else ""),
                      f"{st['std']:.3f}"]
        lines.append(f"| {nm} | {truth:.3f} | " + " | ".join(cells) + " |")
    lines += ["", "e0 is a zero offset (polygon mounting offset; short-period error at integer degrees); it is "
              "not observable with a polygon and not part of the 3 sigma, so it is not validated (no standard "
              "error given). Eq 8 is fitted with a nuisance offset of the 23-face table (relative to its first "
              "face), which is not compensated. The published procedure does not fit electrical 3 and 4 (-)."]
    return "\n".join(lines)


def _plt():
    return pyplot()


def _s3(x) -> float:
    """3 x sample sd (ddof 1), as seed 001 computes 3 sigma."""
    return float(3 * np.std(np.asarray(x, dtype=float), ddof=1))


def _plot_error_curves(before, t, rs, rj, path: Path) -> Path:
    plt = _plt()
    fig, ax = plt.subplots(3, 1, figsize=(9, 9))
    ax[0].plot(t, before, lw=0.3, color="C0", label="before (truth, trial 0's instrument)")
    ax[0].set_xlabel("reading (deg)")
    ax[0].set_ylabel("error (arcsec)")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].set_title(f"error before compensation: 3 sigma {_s3(before):.2f} arcsec", fontsize=9)
    ax[1].plot(t, rs, lw=0.3, color="C1", label="after, in sequence (trial 0)")
    ax[1].plot(t, rj, lw=0.3, color="C2", label="after, joint fit (trial 0)")
    ax[1].set_xlabel("reading (deg)")
    ax[1].set_ylabel("residual - mean (arcsec)")
    ax[1].legend(loc="upper right", fontsize=8)
    ax[1].set_title(f"trial 0 after compensation: 3 sigma {_s3(rs):.2f} (in sequence), {_s3(rj):.2f} (joint) "
                    "arcsec", fontsize=9)
    sel = (t >= 100) & (t <= 103)
    ax[2].plot(t[sel], rs[sel], lw=0.8, color="C1", label="after, in sequence")
    ax[2].plot(t[sel], rj[sel], lw=0.8, color="C2", label="after, joint")
    ax[2].set_xlabel("reading (deg), three electrical periods")
    ax[2].set_ylabel("residual - mean (arcsec)")
    ax[2].legend(fontsize=8)
    before, a_s, a_j = _s3(before), _s3(rs), _s3(rj)
    caption = (f"Dense truth over the whole turn: 3 sigma {before:.2f} arcsec before compensation; trial 0 "
               f"leaves {a_s:.2f} arcsec in sequence (eq 7 + eq 8) and {a_j:.2f} arcsec after the joint fit "
               f"({fmt(a_s / a_j, 2)} times less)." if a_j > 0 else
               f"Dense truth: 3 sigma {before:.2f} arcsec before compensation, {a_s:.2f} after (in sequence).")
    return save(fig, path, caption)


def _plot_residual_distribution(rs, rj, figs: dict, path: Path) -> Path:
    plt = _plt()
    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    overlaid_hist(ax[0], {"in sequence": rs, "joint": rj}, bins=80, density=True)
    ax[0].set_xlabel("dense residual about its mean, trial 0 (arcsec)")
    ax[0].set_ylabel("probability density (1/arcsec)")
    ax[0].legend(fontsize=8)
    ax[0].set_title("trial 0: residual over the turn", fontsize=9)
    per_trial = {"in sequence": figs["dense_sigma3_after_arcsec"],
                 "joint": figs["joint_dense_sigma3_after_arcsec"],
                 "23-face verify (paper)": figs["short_sigma3_after_arcsec"]}
    overlaid_hist(ax[1], per_trial, bins=40)
    ax[1].set_xlabel("3 sigma after compensation, per trial (arcsec)")
    ax[1].set_ylabel("trials")
    ax[1].legend(fontsize=8)
    ax[1].set_title("3 sigma after compensation, every trial", fontsize=9)
    m = {k: float(np.mean(v)) for k, v in per_trial.items()}
    caption = ("Mean 3 sigma after compensation over the trials: "
               + ", ".join(f"{k} {v:.2f} arcsec" for k, v in m.items())
               + f"; the paper's 23-face verification reads {m['23-face verify (paper)'] - m['in sequence']:+.2f} "
                 "arcsec against the in-sequence truth over the whole turn.")
    return save(fig, path, caption)


def _posterior_band(p, ex: dict, r_joint_mean: float, seed: int, steps: int, path: Path) -> tuple[Path, str]:
    """emcee 90 % band of trial 0's joint-fit residual over three electrical periods, with
    the true residual (continuous reading of trial 0's encoder) overlaid; the text says how
    much of it is inside."""
    from budget.inductosyn.validate import JOINT_ELEC, instrument_draws
    from simcam.encoder.inductosyn import Inductosyn, world_encoder_params

    instrument = instrument_draws(scenario=p.scenario, seed=seed, trials=[0])[0][0]
    plt = _plt()
    jf = fit_joint(tables=[(p.angles_long_deg, ex["y_long"]), (p.angles_short_deg, ex["y_short"])],
                   pole_pairs=p.scenario.encoder.pole_pairs, elec_orders=JOINT_ELEC)
    cal = p.scenario.calibration
    band_t = np.linspace(100, 103, 601)
    # continuous readings: the band is for the fitted model; quantisation (uniform,
    # +-q/2) is a separate, known term of the residual
    enc = Inductosyn(params=world_encoder_params(scenario=p.scenario, instrument=instrument))
    band_r = enc.continuous_reading_deg(angle_deg=band_t)
    post = posterior_band(fit=jf, angle_deg=band_r, seed=seed, level=0.9, n_steps=steps,
                          burn=min(500, steps // 3),
                          face_error_arcsec=max(cal.long_polygon.face_error_arcsec,
                                                cal.short_polygon.face_error_arcsec))
    true_r = (band_r - band_t) * ARCSEC_PER_DEG - jf.evaluate_arcsec(angle_deg=band_r)
    true_r = true_r - r_joint_mean  # zero offset is unobservable: compare about the mean
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.fill_between(band_t, post["lower_arcsec"], post["upper_arcsec"], alpha=0.3,
                    label="90% credible band (emcee)")
    ax.plot(band_t, true_r, lw=0.8, color="k", label="true residual, continuous reading (about its mean)")
    ax.set_xlabel("shaft angle (deg)")
    ax.set_ylabel("residual after joint compensation (arcsec)")
    ax.legend(fontsize=8)
    covered = float(np.mean((true_r >= post["lower_arcsec"]) & (true_r <= post["upper_arcsec"])))
    ax.set_title(f"trial 0, joint fit: {covered:.0%} of the true residual inside the 90 % band", fontsize=9)
    path = save(fig, path, f"Trial 0, joint fit: {covered:.0%} of the plotted true residual lies inside the 90 % "
                f"credible band (nominal 90 %).")
    text = (f"Trial 0, joint fit: fraction of the plotted true residual (continuous reading, without the "
            f"quantisation's uniform +-q/2) inside the 90% band: {covered:.2f}. One trial; the band holds the "
            f"fitted harmonics' uncertainty, not the unmodelled higher harmonics; its coverage rate over many "
            f"trials, for an error inside the model, is tested in tests/test_harmonics.py. emcee "
            f"{steps} steps, acceptance {post['acceptance']:.2f}.")
    return path, text


def report_sections(result, prepared, out_dir, *, posterior_steps: int = 1500) -> list[ReportSection]:
    """The seed-001 sections: the 3 sigma figures of the paper's tables and of the truth,
    the recovered coefficients, and the plots of trial 0 (error curves before and after,
    residual distribution, emcee posterior band)."""
    out_dir = Path(out_dir)
    p = prepared
    d = result.details()
    secs = [ReportSection("Seed 001: 3 sigma of the calibration stages", _figures_markdown(result, d)),
            ReportSection("Seed 001: recovered coefficients", _coefficients_markdown(result, d))]
    ex = result.example.extra if result.example is not None else {}
    if not ex:
        return secs
    a0 = ex["instrument_a"]
    t = p.truth.reading_deg
    r_seq = p.truth.series_arcsec(a0, _fits(np.concatenate([ex["c_long"], ex["c_short"]]))[0])
    r_joint = p.truth.series_arcsec(a0, ex["c_joint"][2:])
    # residuals about their mean: the zero offset (mounting offset) is not observable
    rs, rj = r_seq - r_seq.mean(), r_joint - r_joint.mean()
    curves = _plot_error_curves(p.truth.series_arcsec(a0), t, rs, rj, out_dir / "error_curves.png")
    dist = _plot_residual_distribution(rs, rj, figure_arrays(result), out_dir / "residual_distribution.png")
    band, text = _posterior_band(p, ex, float(np.mean(r_joint)), result.seed, posterior_steps,
                                 out_dir / "posterior_band.png")
    # the figures are placed in the text, each with its caption under it
    secs.append(ReportSection(
        "Seed 001: error curves, residual distribution, posterior band",
        "Error before compensation (the truth over the turn, trial 0's instrument) and trial 0's residual after each "
        "compensation, over the whole turn and over three electrical periods; the dense residual of "
        "trial 0 and the 3 sigma after compensation of every trial; the emcee band of trial 0's joint "
        "fit.\n\n" + text + "\n\n" + figure_markdown([curves, dist, band]), []))
    return secs
