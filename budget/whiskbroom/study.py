"""Seed 002 as a study of the runner: the MTF a whiskbroom TDICCD delivers under its
image-motion residual, predicted as the paper does and better, and measured as a lab would.

Trial ``k`` (``SeedSequence(seed, spawn_key=(k,))``: the 17 variables first, then the
edge image's noise from the same generator) draws one operating point and its errors
(:mod:`simcam.whiskbroom.synthesis`), finds the worst column of the three arrays (largest
along-TDI smear per stage ``eps``) and its cross-TDI smear ``eta``, and then

* **truth** (per trial): the pixel-level TDI simulation of a Nyquist sinusoid moving with
  that residual over 4-phase clocked charge (:func:`simcam.whiskbroom.tdi.pixel_mtf`);
* ``published``: ``sinc(pi N eps/2)`` with ``eps = Delta V_P / V_P`` (the paper's fig. 6),
  nothing across the TDI direction;
* ``improved``: the smear along the TDI direction (``Delta beta`` projected), the
  charge-clocking factor and the cross-track drift (:func:`budget.whiskbroom.estimators.improved_mtf`);
* ``edge``: the slanted-edge measurement of a simulated noisy TDI edge image (along only).

Classes: ``mtf_nyquist`` (axes along, cross) at the scenario's stage count, and
``stage_limit`` (the largest N, up to 4x the array's stages, keeping MTF >= threshold).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget.runner.study import ClassSpec, ReportSection, Study, TrialResult, Truth, trial_seed_sequence

__all__ = ["STUDY", "WhiskbroomStudy", "STAGE_CAP_FACTOR"]

#: stage limits are searched up to this multiple of the array's stage count
STAGE_CAP_FACTOR = 4


class WhiskbroomStudy(Study):
    """Seed 002: whiskbroom TDICCD image-motion residual and the MTF it leaves."""

    name = "whiskbroom"
    title = "Whiskbroom TDICCD camera: image-motion residual and TDI MTF (seed 002)"
    seed_document = "002"
    variants = ("published", "improved", "edge")
    scenario_module = "simcam.whiskbroom.scenario"

    # ------------------------------------------------------------ the method
    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        n = scenario.camera.tdi_stages
        thr = scenario.synthesis.mtf_threshold
        return (
            ClassSpec("mtf_nyquist", f"motion MTF at Nyquist, N = {n} stages", "1", ("along", "cross"),
                      "truth: pixel-level TDI simulation of the trial's residual motion; estimates: "
                      "the published sinc, the improved sinc (clocking, drift direction), the slanted-edge "
                      "measurement", per_trial_truth=True),
            ClassSpec("stage_limit", f"largest N with MTF >= {thr}", "stages", ("along",),
                      f"searched up to {STAGE_CAP_FACTOR} x {n}; truth from the pixel-level prefix sums",
                      per_trial_truth=True),
        )

    def chunk_trials(self, scenario) -> int:
        return 20

    def _field(self, scenario):
        from simcam.whiskbroom import synthesis as sy

        key = scenario.hash
        cache = self.__dict__.setdefault("_field_cache", {})
        if key not in cache:
            x1, x3 = sy.field_points(scenario)
            cache[key] = (np.concatenate([[0.0], x1]), np.concatenate([[0.0], x3]))
        return cache[key]

    def motion(self, scenario, seed: int, k: int):
        """The trial's generator (after the 17 draws) and its worst-column residual."""
        from simcam.whiskbroom import synthesis as sy
        from simcam.whiskbroom.scenario import VARIABLES

        rng = np.random.default_rng(trial_seed_sequence(seed, k))
        u = np.clip(rng.random(len(VARIABLES)), 1e-300, None)[None, :]
        draws = sy.standard_draws(scenario, u)
        know, true = sy.trial_params(scenario, draws, [k])
        x1, x3 = self._field(scenario)
        r = sy.evaluate(know, true, x1, x3, backend="numpy")   # one state: numpy is faster
        # a scenario outside the model's domain is one error line, not NaN estimates (issue 24)
        sy.check_finite_residuals(scenario, r, scenario.errors.mirror_rate_deg_s.scale,
                                  f"{getattr(scenario, 'source', 'scenario')}: trial {k} of seed {seed}")
        return rng, r

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from budget.whiskbroom import estimators as est
        from simcam.whiskbroom import tdi

        cam, t, thr = scenario.camera, scenario.tdi, scenario.synthesis.mtf_threshold
        n = cam.tdi_stages
        cap = STAGE_CAP_FACTOR * n
        rng, r = self.motion(scenario, seed, k)
        eps, eta = float(r.eps[0]), float(r.eta[0])
        eps_pub = float(r.dv_mm_s[0] / r.speed_mm_s[0])
        # truth: the pixel-level simulation, every stage count up to the cap in one pass
        along_px, cross_px = tdi.pixel_mtf(eps, eta, n_stages=cap, n_phase=cam.n_phase,
                                           n_time=t.time_samples_per_phase, columns=t.columns,
                                           aperture_samples=t.aperture_samples)
        stages = np.arange(1, cap + 1)
        pub_curve = est.published_mtf(eps_pub, 1.0, stages)
        imp_along, imp_cross = est.improved_mtf(eps, eta, stages, cam.n_phase)
        # the lab's slanted-edge measurement at the array's stage count
        img = tdi.edge_image(eps, eta, n_stages=n, n_phase=cam.n_phase, n_time=t.edge_time_samples_per_phase,
                             angle_deg=t.edge_angle_deg, lines=t.edge_lines, columns=t.edge_columns,
                             signal_e_per_stage=t.signal_e_per_stage,
                             read_noise_e=t.read_noise_e if t.noise else 0.0,
                             rng=rng if t.noise else None)
        edge = est.slanted_edge_mtf(img, oversampling=t.edge_oversampling)["mtf"]
        est_ = {
            ("mtf_nyquist", "published", "along"): float(pub_curve[n - 1]),
            ("mtf_nyquist", "published", "cross"): 1.0,
            ("mtf_nyquist", "improved", "along"): float(imp_along[n - 1]),
            ("mtf_nyquist", "improved", "cross"): float(imp_cross[n - 1]),
            ("mtf_nyquist", "edge", "along"): float(edge),
            ("stage_limit", "published", "along"): float(est.stage_limit_from_curve(pub_curve, thr)),
            ("stage_limit", "improved", "along"): float(est.stage_limit_from_curve(imp_along, thr)),
        }
        truth_mtf = {"along": float(along_px[n - 1]), "cross": float(cross_px[n - 1])}
        truth_n = float(est.stage_limit_from_curve(along_px, thr))
        truths = {key: (truth_mtf[key[2]] if key[0] == "mtf_nyquist" else truth_n) for key in est_}
        extra = {"eps": eps, "eta": eta, "eps_published": eps_pub, "dv_mm_s": float(r.dv_mm_s[0]),
                 "dbeta_deg": float(r.dbeta_deg[0]), "beta_deg": float(r.beta_deg[0]),
                 "stages": stages, "truth_along": along_px, "truth_cross": cross_px,
                 "published": pub_curve, "improved_along": imp_along, "improved_cross": imp_cross,
                 "edge_image": img}
        return TrialResult(estimates=est_, truths=truths, extra=extra)

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        return {}   # every class's truth is drawn per trial

    # ------------------------------------------------------------ report
    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        from budget.whiskbroom import plots

        out_dir = Path(out_dir)
        figs = []
        ex = result.example.extra if result.example is not None else {}
        if ex:
            figs.append(plots.plot_trial_mtf(ex, result.scenario, out_dir / "whiskbroom_trial0_mtf.png"))
        key_t = ("mtf_nyquist", "published", "along")
        if key_t in result.trial_truths:
            figs.append(plots.plot_mtf_errors(result, out_dir / "whiskbroom_mtf_errors.png"))
        sc = result.scenario
        md = (f"Truth: the pixel-level TDI simulation ({sc.camera.n_phase}-phase clocking, "
              f"{sc.tdi.time_samples_per_phase} exposure samples per phase, {sc.tdi.columns} columns) "
              f"of each trial's worst-column residual motion. The published sinc ignores the charge "
              f"clocking (factor sinc(pi/{2 * sc.camera.n_phase}) = "
              f"{float(np.sinc(0.5 / sc.camera.n_phase)):.4f} at Nyquist) and the cross-track drift; the "
              f"improved prediction includes both; the edge variant is the slanted-edge measurement of "
              f"a noisy simulated TDI edge image.")
        # the figures are placed in the text, each with its caption under it
        return [ReportSection("Whiskbroom TDI MTF", md + ("\n\n" + plots.figure_markdown(figs) if figs else ""), [])]

    def commands(self) -> list:
        from budget.whiskbroom.cli import synthesize_command

        return [synthesize_command]


STUDY = WhiskbroomStudy()
