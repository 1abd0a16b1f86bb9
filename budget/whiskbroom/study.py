"""Seed 002 as a study of the runner: the MTF a whiskbroom TDICCD delivers under its
image-motion residual, predicted as the paper does and better, and measured as a lab would.

Trial ``k`` (``SeedSequence(seed, spawn_key=(k,))``: the 17 variables first, then the
edge image's noise from the same generator) draws one operating point and its errors
(:mod:`simcam.whiskbroom.synthesis`), finds the worst column of the three arrays (largest
along-TDI smear per stage ``eps``) and its cross-TDI smear ``eta``, and then

* **truth** (per trial, :mod:`budget.whiskbroom.truth`): the pixel-level TDI simulation of a
  Nyquist sinusoid moving with that column's residual over 4-phase clocked charge
  (:func:`simcam.whiskbroom.tdi.pixel_mtf`), the residual ray-traced from the true and the
  knowledge states (no code of the paper's chain that gives the predictions' ``eps, eta``);
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

from budget.runner.capabilities import CheckedScenario, Claims, Prepared, Presented, WorldEffects
from budget.runner.study import ClassSpec, ReportSection, Study, TrialResult, Truth
from budget.whiskbroom import claims as ledger
from budget.whiskbroom import draws
from budget.whiskbroom import estimators as est
from budget.whiskbroom import plots
from budget.whiskbroom import truth as wtruth
from simcam.infra.errors import ScenarioError
from simcam.whiskbroom import geometry as geo

__all__ = ["STUDY", "WhiskbroomStudy", "STAGE_CAP_FACTOR"]

#: stage limits are searched up to this multiple of the array's stage count
STAGE_CAP_FACTOR = 4


def _mtf_floor(scenario) -> float:
    """The truth's quadrature error, an MTF below which a bias is numerical: the pixel-level
    simulation averages ``exp(i 2 pi f x(t))`` over each clock phase with ``m`` midpoint
    samples while the charge moves ``1/n_phase`` px, a phase advance ``phi = pi / n_phase`` at
    Nyquist; the midpoint rule's relative error is ``phi^2 / (24 m^2)`` (its error term
    ``h^2 (b - a) f'' / 24``); twice that (the motion's own advance adds to the clocking's)."""
    phi = np.pi / scenario.camera.n_phase
    return float(2.0 * phi**2 / (24.0 * scenario.tdi.time_samples_per_phase**2))


class WhiskbroomStudy(Study, CheckedScenario, Prepared, WorldEffects, Presented, Claims):
    """Seed 002: whiskbroom TDICCD image-motion residual and the MTF it leaves."""

    name = "whiskbroom"
    title = "Whiskbroom TDICCD camera: image-motion residual and TDI MTF (seed 002)"
    seed_document = "002"
    variants = ("published", "improved", "edge")
    scenario_module = "simcam.whiskbroom.scenario"
    trials_per_task = 20

    def check(self, scenario, *, where: str) -> None:
        """An instrument cannot be pinned: every one of the 17 variables is the trial's operating
        point or a knowledge error of that pass (seed 002), so the study draws no instrument
        property that ``validation.instrument_seed`` could fix."""
        if scenario.validation.instrument_seed is not None:
            raise ScenarioError(f"{where}: validation.instrument_seed: the whiskbroom study draws no instrument "
                                "property (its 17 variables are drawn per trial); leave it unset")

    # ------------------------------------------------------------ the method
    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        n = scenario.camera.tdi_stages
        thr = scenario.synthesis.mtf_threshold
        return (
            ClassSpec("mtf_nyquist", f"motion MTF at Nyquist, N = {n} stages", "1", ("along", "cross"),
                      "truth: pixel-level TDI simulation of the trial's residual motion; estimates: "
                      "the published sinc, the improved sinc (clocking, drift direction), the slanted-edge "
                      "measurement", per_trial_truth=True, numerical_floor=_mtf_floor(scenario)),
            ClassSpec("stage_limit", f"largest N with MTF >= {thr}", "stages", ("along",),
                      f"searched up to {STAGE_CAP_FACTOR} x {n}; truth from the pixel-level prefix sums",
                      per_trial_truth=True),
        )

    def setup(self, scenario):
        """The field points the worst column is searched over (the centre first,
        :func:`simcam.whiskbroom.synthesis.field_points`), after :meth:`check`."""
        self.check(scenario, where=getattr(scenario, "source", None) or "scenario")
        return draws.field_points(scenario)

    def _draw(self, scenario, seed: int, k: int):
        return draws.trial_draw(scenario, seed, k, *self.prepared(scenario))

    def motion(self, scenario, seed: int, k: int):
        """The trial's generator (after the 17 draws) and its worst-column residual."""
        rng, _, _, r = self._draw(scenario, seed, k)
        return rng, r

    def claims(self, scenario) -> tuple:
        """Seed 002's claims (:func:`budget.whiskbroom.claims.ledger_claims`): the testable ones
        name ``embedded:default``, judged in its two worlds."""
        return ledger.ledger_claims(scenario)

    def truth_depends_on_effects(self, scenario) -> set[str]:
        """The effects that change the truth (the motion MTF): the world's image motion
        (flattening, jitter, ripple); the pixel crosstalk is common to moving and static
        exposures, so it changes only the edge image."""
        from simcam.whiskbroom.world import TRUTH_EFFECTS

        return set(TRUTH_EFFECTS)

    def claim(self, scenario, class_name: str, variant: str) -> float:
        """The accuracy a prediction of this study claims, in the class's unit (this
        project's reading; the paper states no tolerance on its formula): the MTF at Nyquist
        to 0.005, a tenth of the paper's 5 % MTF-drop budget; the stage limit to 5 % of
        the array's stage count."""
        if class_name == "stage_limit":
            return 0.05 * scenario.camera.tdi_stages
        return 0.005

    def _edge(self, scenario, motion, rng):
        """The lab's slanted-edge image made by the world: ``motion`` = uniform ``(eps, eta)``
        or an image path (the crosstalk applied before the noise)."""
        from simcam.whiskbroom import tdi
        from simcam.whiskbroom import world as wd

        cam, t = scenario.camera, scenario.tdi
        x = scenario.world.effects.pixel_crosstalk_fraction
        kw = dict(n_stages=cam.tdi_stages, n_phase=cam.n_phase, n_time=t.edge_time_samples_per_phase,
                  angle_deg=t.edge_angle_deg, lines=t.edge_lines, columns=t.edge_columns)
        if callable(motion):
            da, dc = motion(wd.sample_times(t.edge_lines + cam.tdi_stages, cam.n_phase, t.edge_time_samples_per_phase))
            mean = wd.edge_image_path(da, dc, **kw)
        else:
            mean = tdi.edge_image(motion[0], motion[1], **kw)
        mean = wd.diffuse(mean, x)
        if not t.noise:
            return mean
        img = rng.poisson(mean * t.signal_e_per_stage * cam.tdi_stages).astype(float)
        if t.read_noise_e > 0:
            img += rng.normal(0.0, t.read_noise_e, img.shape)
        return img

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from simcam.whiskbroom import tdi

        cam, t, thr = scenario.camera, scenario.tdi, scenario.synthesis.mtf_threshold
        n = cam.tdi_stages
        cap = STAGE_CAP_FACTOR * n
        rng, know, true, r = self._draw(scenario, seed, k)
        eps, eta = float(r.eps[0]), float(r.eta[0])
        eps_pub = float(r.dv_mm_s[0] / r.speed_mm_s[0])
        stages = np.arange(1, cap + 1)
        pub_curve = est.published_mtf(eps_pub, 1.0, stages)
        imp_along, imp_cross = est.improved_mtf(eps, eta, stages, cam.n_phase)
        # truth: the pixel-level simulation of the world's image motion, every stage count up to the
        # cap in one pass, by the ray-traced route of budget.whiskbroom.truth (nothing of eps, eta above)
        i = int(r.worst[0])
        x1, x3 = self.prepared(scenario)
        along_px, cross_px, motion = wtruth.trial_truth(scenario, seed, k, geo.PARAMS, know[0], true[0],
                                                        x1[i], x3[i], cap)
        if scenario.world.effects.active():
            img = self._edge(scenario, motion, rng)
        else:
            # the lab's slanted-edge image of the world's motion at the array's stage count
            img = tdi.edge_image(motion[0], motion[1], n_stages=n, n_phase=cam.n_phase,
                                 n_time=t.edge_time_samples_per_phase, angle_deg=t.edge_angle_deg,
                                 lines=t.edge_lines, columns=t.edge_columns,
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
        truth_n = float(wtruth.stage_limit_truth(along_px, thr))
        truths = {key: (truth_mtf[key[2]] if key[0] == "mtf_nyquist" else truth_n) for key in est_}
        extra = {"eps": eps, "eta": eta, "eps_published": eps_pub, "dv_mm_s": float(r.dv_mm_s[0]),
                 "dbeta_deg": float(r.dbeta_deg[0]), "beta_deg": float(r.beta_deg[0]),
                 "stages": stages, "truth_along": along_px, "truth_cross": cross_px,
                 "published": pub_curve, "improved_along": imp_along, "improved_cross": imp_cross,
                 "edge_image": img}
        return TrialResult(estimates=est_, truths=truths, extra=extra)

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        return {}   # every class's truth is drawn per trial

    def likely_cause(self, result, key, stats):
        """The published sinc's omissions (module docstring), where the numbers show them."""
        cls, var, ax = key
        if var == "published" and cls == "mtf_nyquist" and ax == "along" and stats["bias"] > 0:
            n = result.scenario.camera.n_phase
            return (f"the published sinc ignores the charge clocking (a factor sinc(pi/{2 * n}) = "
                    f"{float(np.sinc(0.5 / n)):.4f} at Nyquist), so it overstates the MTF.")
        if var == "published" and cls == "mtf_nyquist" and ax == "cross":
            return "the published model has no cross-track drift: it states an MTF of 1 across track."
        if var == "published" and cls == "stage_limit" and stats["bias"] > 0:
            return "it follows from the published MTF, which is too high: more stages pass the threshold."
        if var == "edge":
            return ("the slanted-edge measurement's own errors on a noisy simulated edge image "
                    "(noise, the edge's sampling and the aperture correction).")
        return None

    # ------------------------------------------------------------ report
    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        out_dir = Path(out_dir)
        figs = []
        ex = result.example.extra if result.example is not None else {}
        if ex:
            figs.append(plots.plot_trial_mtf(ex, result.scenario, out_dir / "whiskbroom_trial0_mtf.png"))
        key_t = ("mtf_nyquist", "published", "along")
        if key_t in result.trial_truths:
            figs.append(plots.plot_mtf_errors(result, out_dir / "whiskbroom_mtf_errors.png"))
        sc = result.scenario
        eff = sc.world.effects
        on = ", ".join(f"{n} = {getattr(eff, n):g}" for n in eff.active()) or "none (the ideal world)"
        md = (f"Truth: the pixel-level TDI simulation ({sc.camera.n_phase}-phase clocking, "
              f"{sc.tdi.time_samples_per_phase} exposure samples per phase, {sc.tdi.columns} columns) "
              f"of each trial's worst-column residual motion in the world (effects on: {on}). The "
              f"published sinc predicts the MTF loss caused by the motion residual (the paper's criterion); "
              f"the {sc.camera.n_phase}-phase charge clocking is a separate static factor of the detector, "
              f"sinc(pi/{2 * sc.camera.n_phase}) = {float(np.sinc(0.5 / sc.camera.n_phase)):.4f} at Nyquist "
              f"for every N, which the truth includes and the published formula does not claim; "
              f"the improved prediction multiplies it in and adds the cross-track drift; the edge variant "
              f"is the slanted-edge measurement of a noisy simulated TDI edge image (`budget whiskbroom "
              f"synthesize` judges the published sinc by its own criterion and gives the paper's headline "
              f"figures over 20 seeds).")
        # the figures are placed in the text, each with its caption under it
        return [ReportSection("Whiskbroom TDI MTF", md + ("\n\n" + plots.figure_markdown(figs) if figs else ""), [])]


STUDY = WhiskbroomStudy()
