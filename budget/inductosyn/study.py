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
"""

from __future__ import annotations

from budget.runner.study import ClassSpec, Study, TrialResult, Truth

__all__ = ["STUDY", "InductosynStudy"]

_UNIT = "arcsec, 3 sigma"
_PREPARED: dict = {}


class InductosynStudy(Study):
    """Seed 001: polygon calibration of an inductosyn's long- and short-period errors."""

    name = "inductosyn"
    title = "Inductosyn polygon calibration (seed 001)"
    seed_document = "001"
    variants = ("published", "improved")

    def default_text(self) -> str:
        from simcam.encoder.inductosyn import default_scenario_toml

        return default_scenario_toml()

    def from_dict(self, data: dict, *, source: str):
        from simcam.config_base import validate_model
        from simcam.encoder.inductosyn import Inductosyn, InductosynScenario

        scn = validate_model(InductosynScenario, data, source=source)
        Inductosyn(params=scn.encoder, source=source)  # monotonicity check
        return scn

    def load_scenario(self, path=None):
        from simcam.encoder.inductosyn import load_scenario

        return load_scenario(path)

    def scenario_hash(self, scenario) -> str:
        from simcam.config_base import model_hash

        return model_hash(scenario)

    def check(self, scenario, *, where: str) -> None:
        # the calibration designs (24-face long, short and joint) separate the harmonics
        from budget.inductosyn.validate import prepare

        prepare(scenario=scenario, dense_step_deg=1.0)

    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        return (
            ClassSpec("before", "short-period error before compensation", _UNIT, ("angle",),
                      "the 23-face table's 3 sigma after the long-period fit, against the 3 sigma of the "
                      "error over the whole circle"),
            ClassSpec("residual", "error after compensation", _UNIT, ("angle",),
                      "the 23-face verification's 3 sigma, against the 3 sigma over the whole circle of "
                      "the trial's compensated error", per_trial_truth=True),
        )

    def max_trials(self, scenario) -> int:
        return 1_000_000

    def batch_trials(self, scenario) -> int:
        return 1000

    def chunk_trials(self, scenario) -> int:
        return 2000  # vectorised: a chunk costs little more than one trial

    def _prepared(self, scenario):
        from budget.inductosyn.validate import prepare
        from simcam.config_base import model_hash

        key = model_hash(scenario)
        if key not in _PREPARED:
            _PREPARED.clear()
            _PREPARED[key] = prepare(scenario=scenario, dense_step_deg=scenario.validation.dense_step_deg)
        return _PREPARED[key]

    def trial_batch(self, scenario, seed: int, ks: list[int]) -> list[TrialResult]:
        from budget.inductosyn.validate import run_trials

        if list(ks) != list(range(ks[0], ks[0] + len(ks))):
            return [self.trial(scenario, seed, k) for k in ks]
        r = run_trials(prepared=self._prepared(scenario), trials=len(ks), seed=seed, first_trial=ks[0])
        out = []
        for i in range(len(ks)):
            before = float(r["short_sigma3_before_arcsec"][i])
            out.append(TrialResult(
                estimates={("before", "published", "angle"): before, ("before", "improved", "angle"): before,
                           ("residual", "published", "angle"): float(r["short_sigma3_after_arcsec"][i]),
                           ("residual", "improved", "angle"): float(r["joint_short_sigma3_after_arcsec"][i])},
                truths={("residual", "published", "angle"): float(r["dense_sigma3_after_arcsec"][i]),
                        ("residual", "improved", "angle"): float(r["joint_dense_sigma3_after_arcsec"][i])}))
        return out

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        return self.trial_batch(scenario, seed, [k])[0]

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        from budget.inductosyn.harmonics import sigma3_arcsec

        p = self._prepared(scenario)
        return {("before", "angle"): Truth(float(sigma3_arcsec(error_arcsec=p.dense_before_arcsec)), 0.0,
                                           {"dense_points": int(p.dense_true_deg.size)})}


STUDY = InductosynStudy()
