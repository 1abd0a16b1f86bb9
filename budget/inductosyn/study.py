"""Seed 001 as a study of the runner (:mod:`budget.runner`).

Trials are :func:`budget.inductosyn.validate.run_trials` (vectorised: a chunk of trials at
once, each drawn from ``SeedSequence(seed, spawn_key=(k,))`` so a chunk equals its trials
run one by one). Classes, in arcsec (3 sigma), variants ``published`` (the in-sequence
procedure, eqs 7-9) and ``improved`` (the joint fit):

* ``before``: the short-period error before compensation. The lab's figure is the 3 sigma
  of the 23-face table once the long-period fit is removed (seed 001 reports 145.6");
  the truth is the 3 sigma of the error over the whole circle (a dense grid of true
  angles), a property of the encoder.
* ``residual``: the error left after compensation. The lab's figure is the 23-face
  verification table after compensation; the truth of each trial is the 3 sigma over the
  whole circle of that trial's compensated error (it changes with each calibration's
  polygon errors and noise).
* ``coefficient``: the harmonic coefficients the fits recover (axes ``A_L1c`` ... ``A_S4s``;
  the published procedure fits mechanical 1-2 and electrical 1-2, the joint fit electrical
  1-4 as well), against the projection of the continuous true error, as a function of the
  reading, on the same harmonics (:func:`budget.inductosyn.validate.reference_coefficients`).
  The constant ``e0`` is not a class: it holds the polygon's mounting offset and is not
  observable with a polygon; it is kept per trial in ``aux`` for the report.

Per trial the study also keeps (``aux``) the other figures of the seed-001 report: the
24-face table's 3 sigma before and after the eq 7 compensation, the largest true residual
over the turn of either variant, the constants ``e0``; trial 0's tables and coefficients
(``extra``) feed the report's plots. :mod:`budget.inductosyn.report` turns them into the
seed-001 sections of the runner's report and the ``details`` of its JSON.
"""

from __future__ import annotations

import numpy as np

from budget.inductosyn.claims import CLAIMS
from budget.inductosyn.harmonics import COEFFICIENTS, PUBLISHED_COEFFICIENTS
from budget.inductosyn.report import details, report_sections
from budget.runner.capabilities import (
    BatchedTrials,
    CheckedScenario,
    Claims,
    Plannable,
    Prepared,
    Presented,
    ProtocolShapes,
    WorldEffects,
)
from budget.runner.study import ClassSpec, Knob, Study, TrialResult, Truth

#: the coefficients validated (:data:`budget.inductosyn.harmonics.COEFFICIENTS`) are axes of its classes
__all__ = ["COEFFICIENTS", "POLYGON_PAIRS", "PUBLISHED_COEFFICIENTS", "STUDY", "InductosynStudy"]

_UNIT = "arcsec, 3 sigma"

#: The polygon pairs the planner compares (``protocol_shapes``): (long faces, short faces).
#: Long: a face count dividing the 360 pole pairs, so that every electrical harmonic samples
#: as the table's constant and eq 7 sees the mechanical orders alone (seed 001's 24-face
#: design); 12, 18, 24 and 36 faces are stock polygons. Short: a count the electrical orders
#: 1-4 alias on to distinct non-zero mechanical orders below N/2, clear of the mechanical
#: 1-2 the long table pins, so the eq 8 and joint designs are full rank
#: (:func:`budget.inductosyn.harmonics.check_design`, which :meth:`InductosynStudy.check`
#: runs): 11 is the fewest such faces (a table of N faces holds at most (N - 1) / 2
#: harmonics besides its constant, and electrical 1-4 need 4; 9 and 10 faces fold two of
#: them together: 360 = 0 mod 9 and 720 = 0 mod 10), 13, 17, 23 and 37 are others.
POLYGON_PAIRS = ((12, 11), (12, 13), (18, 17), (24, 23), (36, 37))


class InductosynStudy(Study, Prepared, CheckedScenario, BatchedTrials, WorldEffects, Plannable, ProtocolShapes,
                      Presented, Claims):
    """Seed 001: polygon calibration of an inductosyn's long- and short-period errors."""

    name = "inductosyn"
    title = "Inductosyn polygon calibration (seed 001)"
    seed_document = "001"
    variants = ("published", "improved")
    scenario_module = "simcam.encoder.inductosyn"
    trials_per_task = 2000  # vectorised: a chunk costs little more than one trial

    def check(self, scenario, *, where: str) -> None:
        # the calibration designs (24-face long, short and joint) separate the harmonics
        from budget.inductosyn.validate import prepare

        prepare(scenario=scenario, dense_step_deg=1.0)

    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        # the instrument's truths are per trial unless validation.instrument_seed pins one
        per_instrument = scenario.validation.instrument_seed is None
        return (
            ClassSpec("before", "short-period error before compensation", _UNIT, ("angle",),
                      "the 23-face table's 3 sigma after the long-period fit, against the 3 sigma of the "
                      "error over the whole circle", per_trial_truth=per_instrument),
            ClassSpec("residual", "error after compensation", _UNIT, ("angle",),
                      "the 23-face verification's 3 sigma, against the 3 sigma over the whole circle of "
                      "the trial's compensated error", per_trial_truth=True, role="residual"),
            ClassSpec("environment", "error after the environment test", _UNIT, ("angle",),
                      "the 23-face re-measurement's 3 sigma after the drift of temperature cycling and "
                      "vibration (seed 001 section 4.3, table 3), compensated as calibrated, against the 3 "
                      "sigma over the whole circle of the trial's drifted, compensated error",
                      per_trial_truth=True, role="residual"),
            ClassSpec("coefficient", "harmonic coefficient", "arcsec", COEFFICIENTS,
                      "each fitted coefficient (eq 7 mechanical A_L, eq 8 electrical A_S; the joint fit "
                      "also electrical 3-4), against the Fourier coefficient of the continuous true error "
                      "(as a function of the reading) over the whole turn", per_trial_truth=per_instrument),
        )

    def truth_depends_on_effects(self, scenario) -> set[str]:
        """World effects that change the truths: those of the encoder (they change its error
        on the dense grid and its Fourier projection). The rig's effects (polygon,
        autocollimator, mounting) and the thermal drift (the truth is the encoder at the
        start of the calibration, where the drift is 0) change only the measured tables."""
        return {"electrical_harmonic_3_arcsec", "nonharmonic_arcsec"}

    def setup(self, scenario):
        """The calibration designs and the dense truth grid (:func:`budget.inductosyn.validate.prepare`)."""
        from budget.inductosyn.validate import prepare

        return prepare(scenario=scenario, dense_step_deg=scenario.validation.dense_step_deg)

    #: emcee steps of the posterior band in the report (trial 0's joint fit)
    posterior_steps = 1500

    def trial_batch(self, scenario, seed: int, ks: list[int]) -> list[TrialResult]:
        from budget.inductosyn.validate import run_trials

        if list(ks) != list(range(ks[0], ks[0] + len(ks))):
            return [self.trial(scenario, seed, k) for k in ks]
        r = run_trials(prepared=self.prepared(scenario), trials=len(ks), seed=seed, first_trial=ks[0])
        per_instrument = scenario.validation.instrument_seed is None
        # the same columns in both variants' coefficient vectors: c_long = e0, A_L..;
        # c_short = A_S1c..A_S2s; c_joint = e0 of each table, A_L.., A_S1c..A_S4s
        seq = np.concatenate([r["c_long"][:, 1:], r["c_short"]], axis=1)
        joint = r["c_joint"][:, 2:]
        out = []
        for i, k in enumerate(ks):
            before = float(r["short_sigma3_before_arcsec"][i])
            est = {("before", "published", "angle"): before, ("before", "improved", "angle"): before,
                   ("residual", "published", "angle"): float(r["short_sigma3_after_arcsec"][i]),
                   ("residual", "improved", "angle"): float(r["joint_short_sigma3_after_arcsec"][i]),
                   ("environment", "published", "angle"): float(r["environment_sigma3_arcsec"][i]),
                   ("environment", "improved", "angle"): float(r["joint_environment_sigma3_arcsec"][i])}
            est.update({("coefficient", "published", nm): float(v) for nm, v in zip(PUBLISHED_COEFFICIENTS, seq[i])})
            est.update({("coefficient", "improved", nm): float(v) for nm, v in zip(COEFFICIENTS, joint[i])})
            aux = {name: float(r[name][i]) for name in _AUX}
            aux["e0_in_sequence_arcsec"] = float(r["c_long"][i, 0])
            aux["e0_joint_arcsec"] = float(r["c_joint"][i, 0])
            aux["true_e0_arcsec"] = float(r["true_mean_arcsec"][i])
            extra = {}
            if k == 0:  # the report's plots: trial 0's raw tables, coefficients and instrument
                extra = {name: r[name][i].copy() for name in ("y_long", "y_short", "c_long", "c_short", "c_joint",
                                                              "instrument_a")}
            truths = {("residual", "published", "angle"): float(r["dense_sigma3_after_arcsec"][i]),
                      ("residual", "improved", "angle"): float(r["joint_dense_sigma3_after_arcsec"][i]),
                      ("environment", "published", "angle"): float(r["true_environment_sigma3_arcsec"][i]),
                      ("environment", "improved", "angle"): float(r["true_joint_environment_sigma3_arcsec"][i])}
            if per_instrument:
                for var, names in (("published", PUBLISHED_COEFFICIENTS), ("improved", COEFFICIENTS)):
                    truths[("before", var, "angle")] = float(r["true_sigma3_before_arcsec"][i])
                    truths.update({("coefficient", var, nm): float(r["true_coefficients"][i, COEFFICIENTS.index(nm)])
                                   for nm in names})
            out.append(TrialResult(estimates=est, truths=truths, extra=extra, aux=aux))
        return out

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        return self.trial_batch(scenario, seed, [k])[0]

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        """The pinned instrument's truths (``validation.instrument_seed`` set; otherwise
        every instrument truth is per trial): its Fourier truth (:mod:`budget.inductosyn.truth`)."""
        from budget.inductosyn.validate import instrument_draws

        if scenario.validation.instrument_seed is None:
            return {}
        p = self.prepared(scenario)
        a = instrument_draws(scenario=scenario, seed=seed, trials=[0])[1]
        out = {("before", "angle"): Truth(float(p.truth.sigma3_before_arcsec(a)[0]), 0.0,
                                          {"truth_points": int(p.truth.n)})}
        out.update({("coefficient", nm): Truth(float(v)) for nm, v in zip(COEFFICIENTS, p.truth.coefficients(a)[0])})
        return out

    # ------------------------------------------------------------ protocol planning
    def protocol_knobs(self, scenario) -> tuple[Knob, ...]:
        """The count the lab chooses: rounds of each pass (``calibration.repeats``), each
        face's entry the mean of its rounds. Each round adds fresh stops, quantisation
        phases, reading and autocollimator noise (the part of a coefficient's error that
        averages as 1/sqrt(rounds)); the polygon's own errors and its mounting repeat. The
        face counts are offered as polygon pairs (:meth:`protocol_shapes`): which counts
        a design can fit is not monotone in the count (aliasing), and a polygon is bought,
        not dialled."""
        return (Knob("calibration.repeats", "int", 1, 16, "rounds",
                     "rounds of each polygon pass, each face's table entry the mean of its rounds"),)

    def protocol_shapes(self, scenario) -> dict[str, dict]:
        """The polygon pairs of :data:`POLYGON_PAIRS`, named ``"<long>/<short> faces"``."""
        return {f"{nl}/{ns} faces": {"calibration.long_polygon.faces": nl, "calibration.short_polygon.faces": ns}
                for nl, ns in POLYGON_PAIRS}

    def lab_time_s(self, scenario) -> dict[str, float]:
        """The session of :func:`simcam.encoder.polygon.pass_times_s`, by item: every face
        read (rotate, settle, read: ``calibration.face_time_s``) in the four passes (long raw
        and verify, short raw and verify), each ``calibration.repeats`` rounds, and the three
        set-ups between passes (``calibration.pass_setup_s``: compensation upload, polygon
        change). The same timeline the world's drifts run on."""
        cal = scenario.calibration
        return {"long polygon readings": 2 * cal.repeats * cal.long_polygon.faces * cal.face_time_s,
                "short polygon readings": 2 * cal.repeats * cal.short_polygon.faces * cal.face_time_s,
                "pass set-ups": 3 * cal.pass_setup_s}

    # ------------------------------------------------------------ claims
    def claims(self, scenario) -> tuple:
        """Seed 001's claims (:data:`budget.inductosyn.claims.CLAIMS`); each names the embedded
        default, whatever ``scenario``."""
        return CLAIMS

    # ------------------------------------------------------------ report
    def details(self, result) -> dict:
        return details(result, self.prepared(result.scenario))

    def report_sections(self, result, out_dir) -> list:
        return report_sections(result, self.prepared(result.scenario), out_dir,
                               posterior_steps=self.posterior_steps)


#: per-trial figures of run_trials kept in ``aux`` (no truth: the report summarises them)
_AUX = ("long_sigma3_before_arcsec", "long_sigma3_after_arcsec", "dense_maxabs_after_arcsec",
        "joint_dense_maxabs_after_arcsec")


STUDY = InductosynStudy()
