"""Seed 000 as a study of the runner (:mod:`budget.runner`).

The trial is :func:`budget.starcam.validate.run_trial` (every protocol simulated and estimated by
the lab's estimators) and the truths are :func:`budget.starcam.validate.truths`; this module only
states them in the contract's terms: values in arcsec, 3 sigma (3 x sigma_px x the
scenario's plate scale, as seed 000 reports them).
"""

from __future__ import annotations

from pathlib import Path

from budget.runner.study import ClassSpec, ReportSection, Study, TrialResult, Truth

__all__ = ["STUDY", "StarCameraStudy"]

_UNIT = "arcsec, 3 sigma"
_CLASSES = (
    ("te", "temporal error (TE)", "eqs 1-2: the mean over stars of each star's temporal centroid sd"),
    ("hsfe", "high spatial frequency error (HSFE)", "eqs 3-12: the static, position-dependent centroid error "
     "(pixel response, S-curve) as the 0.2 px stepped target sees it"),
    ("lsfe_s", "chromatic LSFE (LSFE-S)", "eqs 13-16: the colour-dependent displacement of stars"),
    ("lsfe_c1", "distortion calibration residual (LSFE-C1)", "eqs 17-30: what the distortion calibration leaves"),
    ("lsfe_c2", "target marker error (LSFE-C2)", "the calibration target's marker error: an input of the lab "
     "(both variants are set to it), not a result"),
    ("lsfe", "low spatial frequency error (LSFE)", "eq 31 (published: C1 and C2 added linearly) or root-sum-square"),
    ("total", "single-star total", "root-sum-square of TE, HSFE and LSFE"),
)


#: scenario fields no truth of :mod:`budget.starcam.truth` reads (the truth seed aside): the
#: run settings, what only the trials draw (new markers), the lab's own imperfect
#: knowledge (the improved estimators' models; tests/test_truth_routes.py), the frames of
#: the lab's protocols (the truths take their own), the chromatic and distortion
#: protocols (their truths read the optics, the population and the calibration grid)
TRUTH_BLIND_FIELDS = (
    "name", "validation.trials", "validation.tolerance", "validation.max_trials", "validation.batch_trials",
    "validation.new_markers_per_trial", "lab.knowledge", "protocols.te.frames", "protocols.hsfe.frames",
    "protocols.chromatic", "protocols.distortion",
)


def _paths(prefix: str, node: dict) -> list[str]:
    """Dotted prefixes of the second level (``camera.exposure_s``; a blind field may sit deeper)."""
    out = []
    for k, v in node.items():
        p = f"{prefix}.{k}"
        if isinstance(v, dict) and any(b.startswith(p + ".") for b in TRUTH_BLIND_FIELDS):
            out += _paths(p, v)
        else:
            out.append(p)
    return out


class StarCameraStudy(Study):
    """Seed 000: a star camera's TE, HSFE and LSFE lab methods."""

    name = "starcam"
    title = "Star-camera lab methods (seed 000)"
    seed_document = "000"
    variants = ("published", "improved")
    scenario_module = "simcam.starcam.scenario"

    def scenario_text(self, scenario) -> str:
        from simcam.starcam.scenario import scenario_to_toml

        return scenario_to_toml(scenario)

    def check(self, scenario, *, where: str) -> None:
        from budget.starcam.checks import check_geometry

        check_geometry(scenario, where=where)

    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        from budget.starcam.validate import INPUT_CLASSES

        return tuple(ClassSpec(n, label, _UNIT, ("x", "y"), desc, role="input" if n in INPUT_CLASSES else "result")
                     for n, label, desc in _CLASSES)

    def worker_init(self) -> None:
        from budget.starcam.validate import worker_init

        worker_init()

    def prewarm(self, scenario) -> None:
        from budget.starcam.warm import prewarm

        prewarm(scenario)

    @staticmethod
    def _factor(scenario) -> float:
        return 3.0 * scenario.camera.scale_arcsec_per_px

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from budget.starcam.validate import run_trial

        r = run_trial(scenario, seed, k, keep=(k == 0))
        f = self._factor(scenario)
        est = {key: v * f for key, v in r["values"].items()}
        return TrialResult(estimates=est, extra={"kept": r["kept"]} if k == 0 else {})

    def truth_size_for(self, scenario, seed: int, target_se: dict):
        """HSFE and TE truth frames sized to ``target_se`` (arcsec, 3 sigma; converted to px, 1 sigma):
        :func:`budget.starcam.validate.truth_size_for`. The other truths are exact."""
        from budget.starcam.validate import truth_size_for

        f = self._factor(scenario)
        return truth_size_for(scenario, seed=seed, target_px={k: v / f for k, v in target_se.items()})

    def truth_fields(self, scenario) -> tuple[str, ...]:
        """Every scenario field but those the truths cannot see (:data:`TRUTH_BLIND_FIELDS`),
        with ``world`` narrowed to the effects of :meth:`truth_depends_on_effects` (and the
        world's settings), so the two hooks agree."""
        data = scenario.model_dump(mode="json", exclude_none=True)
        out = []
        for top, sub in data.items():
            if top in TRUTH_BLIND_FIELDS:
                continue
            if top == "world" and isinstance(sub, dict):
                depends = self.truth_depends_on_effects(scenario)
                for k, v in sub.items():
                    if k == "effects" and depends is not None and isinstance(v, dict):
                        out += [f"world.effects.{e}" for e in v if e in depends]
                    else:
                        out.append(f"world.{k}")
                continue
            if isinstance(sub, dict):
                out += [_leaf for _leaf in _paths(top, sub) if _leaf not in TRUTH_BLIND_FIELDS
                        and not any(_leaf.startswith(b + ".") for b in TRUTH_BLIND_FIELDS)]
            else:
                out.append(top)
        return tuple(out)

    def truth_parts(self, scenario, seed: int) -> list:
        from budget.starcam.validate import truth_parts

        return truth_parts(scenario, seed=seed)

    def truth_part(self, scenario, seed: int, part):
        from budget.starcam.validate import truth_part

        return truth_part(scenario, seed=seed, part=part)

    def truths_from_parts(self, scenario, seed: int, results: list) -> dict[tuple[str, str], Truth]:
        from budget.starcam.validate import truths_from_parts

        return self._contract_truths(scenario, truths_from_parts(scenario, seed=seed, results=results))

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        from budget.starcam.validate import truths

        return self._contract_truths(scenario, truths(scenario, seed=seed))

    def _contract_truths(self, scenario, class_truths: dict) -> dict[tuple[str, str], Truth]:
        f = self._factor(scenario)
        out = {}
        for cls, t in class_truths.items():
            for ax in ("x", "y"):
                # each ClassTruth carries its own Monte Carlo standard error (LSFE and the
                # total propagate their parts'; budget.starcam.truth)
                details = {k: v for k, v in t.details.items() if not isinstance(v, (list, dict))}
                out[(cls, ax)] = Truth(getattr(t, f"{ax}_px") * f, getattr(t, f"se_{ax}_px") * f, details)
        return out

    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        from budget.starcam.report import plot_chromatic_residuals, plot_distortion_residuals, plot_hsfe_residuals

        ex = (result.example.extra.get("kept", {}) if result.example else {})
        figs = []
        if "hsfe" in ex:
            plot_hsfe_residuals(ex["hsfe"]["estimates"]["published"], out_dir / "hsfe_residuals.png")
            figs.append(out_dir / "hsfe_residuals.png")
        if "chromatic" in ex:
            plot_chromatic_residuals(ex["chromatic"]["data"].centroids, out_dir / "chromatic_residuals.png",
                                     result.scenario.protocols.chromatic.reference_filter_nm)
            figs.append(out_dir / "chromatic_residuals.png")
        if "distortion" in ex:
            plot_distortion_residuals(ex["distortion"]["estimates"]["published"], out_dir / "distortion_residuals.png")
            figs.append(out_dir / "distortion_residuals.png")
        te = result.truths.get(("te", "x"))
        f = self._factor(result.scenario)
        scn = result.scenario
        c1 = ("still displaces after its own distortion correction"
              if scn.optics.distortion_correction.kind != "none"
              else "a cubic calibration would leave (uncalibrated camera)")
        text = [
            "What is compared. **Truth**: the quantity each method claims to measure, computed from the "
            "injected physics by a route that shares nothing with the estimators (budget.starcam.truth): TE, the mean "
            "temporal centroid sd; HSFE, the rms static error of the expected centroid under the lab's noise; "
            "LSFE-S, the rms chromatic displacement of the stellar population about its reference "
            f"({scn.validation.calibration_spectrum}); LSFE-C1, what the camera {c1}; LSFE-C2, the given "
            "marker error (an input). TE and HSFE truths are Monte Carlo estimates and carry a standard "
            "error. **published**: seed 000's own estimator of each class (eqs 1-2, 3-12, 13-16, 17-30, 31). "
            "**improved**: the estimator derived in docs/estimators.md that targets the truth with only what "
            "a lab knows (its own, imperfect spectral model; the marker error it was given).",
            f"Plate scale {scn.camera.scale_arcsec_per_px:g} arcsec/px."]
        if te is not None and "cramer_rao_x_px" in te.details:
            text.append(f"TE truth against the Cramer-Rao bound of an unbiased centroid from the same pixels: "
                        f"x {result.truths[('te', 'x')].value:.3f} vs {te.details['cramer_rao_x_px'] * f:.3f}, "
                        f"y {result.truths[('te', 'y')].value:.3f} vs {te.details['cramer_rao_y_px'] * f:.3f} "
                        f"arcsec (3 sigma).")
        text.append("Figures from trial 0: HSFE residuals per star and step (seed 000 fig. 6), colour "
                    "differences per corner field (fig. 7), distortion residuals before and after the cubic "
                    "fit (fig. 8).")
        return [ReportSection("Seed-000 details", "\n\n".join(text), figs)]

    def commands(self) -> list:
        """``budget starcam simulate|measure|combine`` beside ``validate``: the lab's data."""
        from budget.starcam.combine import combine_command
        from budget.starcam.measure import measure_command
        from budget.starcam.simulate import simulate_command

        return [simulate_command, measure_command, combine_command]


STUDY = StarCameraStudy()
