"""The scan-mirror study (seed 003) on the study contract: does one star dwell recover the
mirror's normal deviation, and what ground error is left in scan 2 after compensation?

Per trial (``trial_seed_sequence(seed, k)``): the deviation's axis, phase and constant part,
the initial attitude of the PD-controlled body, the orbit-determination error, the attitude
knowledge error during the scan, the star tracker's error at each dwell and the centroid noise
are drawn; the lab estimates (dtau_x, dtau_y) from the dwell (published: one star, first order,
no aberration; improved: batch fit with covariance) and compensates the last area scan
(published: first-order corrections with the published estimate; improved: exact iterated
compensation with the improved estimate; without_estimate: exact compensation with dtau = 0,
as the paper does for scan 1).

The world's unmodelled effects (``[world.effects]``, tracker bias and correlated
error, Gaia DR3 stars, deviation drift, inductosyn encoders) are drawn afterwards from a
child of the trial's generator by :mod:`simcam.scanmirror.effects`, the instrument's
properties among them (encoders' drift, tracker bias, the stars' catalogue offsets) from
``instrument_seed_sequence(validation.instrument_seed, seed, k)``: a new instrument per
trial by default, one pinned instrument for an integer; the estimators and their stated
covariance never see them. The default scenario is that realistic world;
``docs/examples/scenarios/scanmirror_ideal.toml`` is the ideal one (docs/scanmirror.md
section 11).

Classes: ``dtau`` (arcsec, per-trial truth: the injected deviation at the dwell), the
ground errors of the last scan after compensation, ``ground_max`` and ``ground_rms`` (deg,
latitude and longitude; the truth is 0: compensation claims to put every point back), and
``compensated_max`` (deg, improved chain only): the lab's own model's largest error against
the world's (per-trial truth), on which the paper's bound of fig. 8 is judged
(:mod:`budget.scanmirror.claims`). Every ground error of the world is computed by the truth's
own route (:mod:`simcam.scanmirror.truth`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget.figures import figure_markdown
from budget.runner.capabilities import CheckedScenario, Claims, Plannable, Prepared, Presented, WorldEffects
from budget.runner.study import (ClassSpec, Knob, ReportSection, Study, TrialResult, Truth, instrument_seed_sequence,
                                 trial_seed_sequence)
from budget.scanmirror.claims import CLAIMS
from budget.scanmirror.plots import plot_dtau_errors, plot_trial_ground_errors
from simcam.scanmirror.scanplan import evaluate_plan
from simcam.units import RAD_PER_ARCSEC

__all__ = ["ScanMirrorStudy", "STUDY"]


class ScanMirrorStudy(Study, Prepared, CheckedScenario, WorldEffects, Plannable, Presented, Claims):
    name = "scanmirror"
    title = "GEO two-axis scan mirror: normal deviation from stars and compensated ground error (seed 003)"
    seed_document = "003"
    variants = ("published", "improved", "without_estimate")
    #: compensation with dtau = 0 (as the paper does for scan 1): a reference, it does not estimate
    reference_variants = ("without_estimate",)
    scenario_module = "simcam.scanmirror.scenario"
    trials_per_task = 50  # about 10 ms a trial

    # ------------------------------------------------------------ scenario

    def check(self, scenario, *, where: str) -> None:
        self._build_setup(scenario, source=where)

    # ------------------------------------------------------------ the method
    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        return (
            ClassSpec("dtau", "mirror normal deviation (dtau_x, dtau_y) from star sensing", "arcsec", ("x", "y"),
                      "estimate from the last star dwell before the last area scan against the injected "
                      "deviation at that dwell", per_trial_truth=True),
            ClassSpec("ground_max", "max |ground error| over the last area scan after compensation", "deg",
                      ("lat", "lon"), "geocentric latitude/longitude error of the line of sight's ground point "
                      "against the nominal one; truth 0", role="residual"),
            ClassSpec("ground_rms", "rms ground error over the last area scan after compensation", "deg",
                      ("lat", "lon"), "as ground_max, root mean square over the scan's samples; truth 0",
                      role="residual"),
            ClassSpec("compensated_max", "max |ground error| over the last area scan after the improved chain: "
                      "the lab's model against the world", "deg", ("lat", "lon"),
                      "estimate: the largest error the lab's own model leaves at its commanded angles (its "
                      "deviation estimate, orbit and attitude knowledge; 0 to the Newton tolerance); truth: the "
                      "world's largest error there, by the truth's own route (simcam.scanmirror.truth); the "
                      "paper's bound (fig. 8) judges the truth", per_trial_truth=True, role="stated"),
        )

    def claims(self, scenario) -> tuple:
        """Seed 003's claims (:data:`budget.scanmirror.claims.CLAIMS`), judged on the embedded
        default's two worlds whatever ``scenario``."""
        return CLAIMS

    def setup(self, scenario):
        """The world's timeline, the ground grid of the last area scan and the dwells' stars
        (:class:`budget.scanmirror.pipeline.Setup`)."""
        return self._build_setup(scenario, source=scenario.source)

    @staticmethod
    def _build_setup(scenario, *, source: str):
        from budget.scanmirror.pipeline import Setup
        from simcam.scanmirror.world import World

        w = World(scenario)
        last = int(evaluate_plan(scenario.effective_plan, np.arange(0.0, w.duration_s, 0.5)).scan.max())
        return Setup(scenario, scenario.validation.ground_step_s, scans=(last,), source=source)

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from budget.scanmirror.pipeline import run

        setup = self.prepared(scenario)
        instrument = instrument_seed_sequence(scenario.validation.instrument_seed, seed, k)
        outcome = run(setup, np.random.default_rng(trial_seed_sequence(seed, k)), instrument=instrument)
        last = outcome.last_scan
        est, truths, sig = {}, {}, {}
        for v in self.variants:
            for j, ax in enumerate(("x", "y")):
                est[("dtau", v, ax)] = float(outcome.dtau_rad[v][j] / RAD_PER_ARCSEC)
                truths[("dtau", v, ax)] = float(outcome.dtau_true_rad[j] / RAD_PER_ARCSEC)
            errors = outcome.errors[last][v]
            for ax, e in (("lat", errors.lat_deg), ("lon", errors.lon_deg)):
                est[("ground_max", v, ax)] = float(np.abs(e).max())
                est[("ground_rms", v, ax)] = float(np.sqrt(np.mean(e * e)))
        for j, ax in enumerate(("x", "y")):
            sig[("dtau", "improved", ax)] = float(outcome.dtau_sigma_rad[j] / RAD_PER_ARCSEC)
        lab = outcome.lab_errors[last]
        for ax, e_lab, e in (("lat", lab.lat_deg, outcome.errors[last]["improved"].lat_deg),
                             ("lon", lab.lon_deg, outcome.errors[last]["improved"].lon_deg)):
            est[("compensated_max", "improved", ax)] = float(np.abs(e_lab).max())
            truths[("compensated_max", "improved", ax)] = float(np.abs(e).max())
        extra = {}
        if k == 0:  # the ground errors of the last scan (budget.scanmirror.pipeline.GroundErrors)
            extra = {"t_s": setup.t_s, "g0": setup.g0,
                     "errors": {v: outcome.errors[last][v] for v in (*self.variants, "uncompensated")}}
        return TrialResult(estimates=est, truths=truths, sigmas=sig, extra=extra)

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        return {(c, ax): Truth(0.0, 0.0) for c in ("ground_max", "ground_rms") for ax in ("lat", "lon")}

    def likely_cause(self, result, key, stats):
        """What the module docstring says of each variant, where the numbers show it."""
        cls, var, ax = key
        if cls == "dtau" and var == "published":
            return "it uses one star, first-order geometry and catalogue directions without aberration."
        if cls.startswith("ground_") and var == "published":
            dt = [result.statistics(("dtau", "published", a)) for a in ("x", "y") if ("dtau", "published", a) in result.samples]
            if any(s["bias_significant"] for s in dt):
                return "first-order corrections with the published deviation estimate, itself biased."
            return "first-order corrections."
        if cls.startswith("ground_") and var == "improved":
            return ("a maximum or rms of an error is positive: the truth 0 is a bound, and what is left is "
                    "what the compensation does not model (orbit-determination and attitude-knowledge "
                    "errors of the trial, the deviation estimate's own error).")
        if cls == "compensated_max":
            return ("the lab's model believes its exact compensation put every point back; the world's error is "
                    "what that model leaves out (the trial's knowledge errors, the deviation estimate's own error "
                    "and, in the realistic world, the effects it does not model).")
        return None

    def truth_depends_on_effects(self, scenario) -> set[str]:
        """No effect changes the study-level truths: the ground classes' truth is 0 whatever
        the world, and the per-trial truths (``dtau``: the world's deviation at the dwell;
        ``compensated_max``: the world's error of the improved chain; effects and the trial's
        instrument included) are returned by each trial."""
        return set()

    # ------------------------------------------------------------ protocol planning
    def protocol_knobs(self, scenario) -> tuple[Knob, ...]:
        """Star dwells per star-sensing segment (``star_sensing.dwells``, 1 to 10: one dwell
        with at least one star is what every estimator needs, the paper flies one; a trial
        costs about 4 ms more per extra dwell), and frames per dwell
        (``star_sensing.frames_per_dwell``, 1 to 20: one frame already determines the
        deviation, the tracker's angles having their stated prior) only where a frame costs
        time (``star_sensing.frame_time_s > 0``): with 0 the dwell lasts as written whatever
        its frames, each at the stated centroid sigma, and more frames would be free."""
        knobs = [Knob("star_sensing.dwells", "int", 1, 10, "dwells",
                      "star-sensing dwells at each star-sensing segment, each after a scan-angle step")]
        if scenario.star_sensing.frame_time_s > 0:
            knobs.append(Knob("star_sensing.frames_per_dwell", "int", 1, 20, "frames",
                              "frames read out in each star dwell (each lasts frames x frame_time_s)"))
        return tuple(knobs)

    def lab_time_s(self, scenario) -> dict[str, float]:
        """The imaging time the star sensing takes, by item: the star dwells (each
        ``frames_per_dwell * frame_time_s``, or as written when ``frame_time_s`` is 0, times
        ``dwells``), the moves between dwells (``dwells - 1`` of ``extra_dwell_move_s``) and
        the slews to and from the star-sensing position (the plan's move segments right
        before and after each star-sensing dwell). The area scans are the mission's, not the
        protocol's."""
        ss = scenario.star_sensing
        segs = scenario.scan_plan.segments
        dwell = move = 0.0
        slews = set()  # a move between two star dwells counts once
        for i, seg in enumerate(segs):
            if seg.kind != "dwell" or not seg.star_sensing:
                continue
            one = ss.frames_per_dwell * ss.frame_time_s if ss.frame_time_s > 0 else seg.duration_s
            dwell += ss.dwells * one
            move += (ss.dwells - 1) * ss.extra_dwell_move_s
            slews.update(j for j in (i - 1, i + 1) if 0 <= j < len(segs) and segs[j].kind == "move")
        slew = sum(segs[j].accel_s + segs[j].const_s + segs[j].decel_s for j in sorted(slews))
        return {"star dwells": dwell, "moves between dwells": move, "slews to and from the stars": slew}

    # ------------------------------------------------------------ report
    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        out_dir = Path(out_dir)
        figs = [plot_dtau_errors(result, out_dir / "scanmirror_dtau_errors.png")]
        md = ["Errors of the deviation estimates (estimate minus injected), all trials. The published "
              "estimator uses one star, first order and catalogue directions without aberration; the "
              "improved one fits every star of the dwell with the tracker's error as nuisance angles."]
        if result.example is not None and result.example.extra:
            figs.append(plot_trial_ground_errors(result.study, result.scenario, result.example.extra,
                                                 out_dir / "scanmirror_ground_errors_trial0.png"))
            md.append("Trial 0: ground errors over the last area scan, uncompensated and after each compensation.")
        md.append(figure_markdown(figs))  # each figure with its caption under it
        return [ReportSection("Scan mirror: deviation estimates and ground errors", "\n\n".join(md), [])]


STUDY = ScanMirrorStudy()
