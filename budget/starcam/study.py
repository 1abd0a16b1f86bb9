"""Seed 000 as a study of the runner (:mod:`budget.runner`).

The trial is :func:`budget.starcam.validate.run_trial` (every protocol simulated and estimated by
the lab's estimators) and the truths are :func:`budget.starcam.validate.truths`; this module only
states them in the contract's terms: values in arcsec, 3 sigma (3 x sigma_px x the
scenario's plate scale, as seed 000 reports them).
"""

from __future__ import annotations

import math
from itertools import combinations
from pathlib import Path

from budget.figures import figure_markdown
from budget.runner.capabilities import (CheckedScenario, Claims, Plannable, Prepared, Presented, ProtocolShapes,
                                        SeparablePlans, SharedTruths, SizedTruths, SplitTruths, Warmup, WorldEffects)
from budget.runner.numbers import fmt
from budget.runner.study import ClassSpec, Knob, ReportSection, Study, TrialResult, Truth
from budget.starcam.checks import check_geometry
from budget.starcam.claims import CLAIMS
from budget.starcam.report import plot_chromatic_residuals, plot_distortion_residuals, plot_hsfe_residuals
from budget.starcam.setup import CameraSetup, setup_key
from budget.starcam.warm import prewarm
from simcam.infra.errors import ScenarioError
from simcam.starcam.scenario import MAX_PLAN_FILTER_SETS, with_updates

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
#: the lab's protocols (the truths take their own), the HSFE poses (its truth is over
#: sub-pixel phases at the first pose, whatever the step pattern), the chromatic and
#: distortion protocols (their truths read the optics, the population and the calibration
#: grid) and the lab's step times
TRUTH_BLIND_FIELDS = (
    "name", "validation.trials", "validation.tolerance", "validation.max_trials", "validation.batch_trials",
    "validation.new_markers_per_trial", "lab.knowledge", "protocols.te.frames", "protocols.hsfe",
    "protocols.chromatic", "protocols.distortion", "protocols.timing",
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


class StarCameraStudy(Study, Prepared, CheckedScenario, Warmup, SplitTruths, SizedTruths, SharedTruths, WorldEffects,
                      Plannable, ProtocolShapes, SeparablePlans, Presented, Claims):
    """Seed 000: a star camera's TE, HSFE and LSFE lab methods."""

    name = "starcam"
    title = "Star-camera lab methods (seed 000)"
    seed_document = "000"
    variants = ("published", "improved")
    scenario_module = "simcam.starcam.scenario"

    def check(self, scenario, *, where: str) -> None:
        check_geometry(scenario, where=where)

    def claims(self, scenario) -> tuple:
        """Seed 000's claims (:data:`budget.starcam.claims.CLAIMS`); each names the embedded
        scenario that judges it, whatever ``scenario`` is."""
        return CLAIMS

    def classes(self, scenario) -> tuple[ClassSpec, ...]:
        """Seed 000's classes that the scenario's ``validation.protocols`` compute (all seven by
        default; :func:`budget.starcam.validate.computed_classes`)."""
        from budget.starcam.validate import INPUT_CLASSES, RSS_OF, computed_classes, instrument_classes

        computed = computed_classes(scenario)
        own = instrument_classes(scenario)  # each trial's camera: its own LSFE-C1, LSFE, total (TE, HSFE)
        return tuple(ClassSpec(n, label, _UNIT, ("x", "y"), desc, role="input" if n in INPUT_CLASSES else "result",
                               per_trial_truth=n in own, rss_of=RSS_OF.get(n, ()))
                     for n, label, desc in _CLASSES if n in computed)

    def truth_depends_on_effects(self, scenario) -> set[str]:
        """World effects whose magnitude changes a truth (budget.starcam.truth):
        the distortion beyond the cubic (LSFE-C1's truth is what the camera's own correction
        leaves of the world's distortion; it also moves the TE and HSFE targets' stars a
        little) and the detector non-linearity (a static pixel-level error: HSFE's truth, and
        TE's through the compressed signal). The hexapod pose errors and the target drift are
        not in any truth: they move the image, not the camera's own errors (TE's truth is the
        centroid's temporal noise, and a drift is not temporal noise; HSFE's truth is over
        sub-pixel phases, whatever pose reaches them), so a robustness case with only those on
        reuses the ideal world's truths."""
        return {"distortion_r5_px_at_corner", "distortion_r7_px_at_corner", "nonlinearity_beta"}

    def setup(self, scenario) -> CameraSetup:
        """The scenario's camera and spectral design (:class:`budget.starcam.setup.CameraSetup`),
        kept by the runner per process (:func:`budget.runner.capabilities.prepared`)."""
        return CameraSetup(scenario)

    def setup_key(self, scenario) -> str:
        """The scenario's hash without the truths' sampling sizes
        (:func:`budget.starcam.setup.setup_key`): the resized truths share the trials' camera."""
        return setup_key(scenario)

    def prewarm(self, scenario) -> None:
        prewarm(scenario)

    @staticmethod
    def _factor(scenario) -> float:
        return 3.0 * scenario.camera.scale_arcsec_per_px

    def trial(self, scenario, seed: int, k: int) -> TrialResult:
        from budget.starcam.validate import run_trial

        r = run_trial(scenario, seed, k, keep=(k == 0), setup=self.prepared(scenario))
        f = self._factor(scenario)
        est = {key: v * f for key, v in r["values"].items()}
        return TrialResult(estimates=est, truths={key: v * f for key, v in r["truths"].items()},
                           extra={"kept": r["kept"]} if k == 0 else {})

    def truth_size_for(self, scenario, seed: int, target_se: dict):
        """HSFE and TE truth frames sized to ``target_se`` (arcsec, 3 sigma; converted to px, 1 sigma):
        :func:`budget.starcam.validate.truth_size_for`. The other truths are exact."""
        from budget.starcam.validate import truth_size_for

        f = self._factor(scenario)
        return truth_size_for(scenario, seed=seed, target_px={k: v / f for k, v in target_se.items()},
                              setup=self.prepared(scenario))

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

        return truth_part(scenario, seed=seed, part=part, setup=self.prepared(scenario))

    def truths_from_parts(self, scenario, seed: int, results: list) -> dict[tuple[str, str], Truth]:
        from budget.starcam.validate import truths_from_parts

        return self._contract_truths(scenario, truths_from_parts(scenario, seed=seed, results=results,
                                                                 setup=self.prepared(scenario)))

    def truths(self, scenario, seed: int) -> dict[tuple[str, str], Truth]:
        from budget.starcam.validate import truths

        return self._contract_truths(scenario, truths(scenario, seed=seed, setup=self.prepared(scenario)))

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

    # ------------------------------------------------------------ protocol planning
    def protocol_knobs(self, scenario) -> tuple[Knob, ...]:
        """The seed-000 lab's counts (``budget starcam plan``), each a field of ``[protocols]``
        or ``[validation]``: frames of each protocol's conditions, the HSFE poses (in either
        step pattern, :meth:`protocol_shapes`) and the dark frames per condition; those ``protocols.plan_knobs`` names
        (default the six counts; a lab planning one test lists its own, which keeps the search small;
        ``distortion.extent``, the calibration grid's extent, only where listed, so that a default
        plan keeps seed 000's grid). Lower bounds are what the
        estimators need: a star's temporal sd (TE) and each pose's temporal variance (the
        improved HSFE) need 2+ frames; the chromatic and distortion means 2+ frames so that
        their temporal noise is estimable; 3+ diagonal poses so that the HSFE residuals keep
        a degree of freedom after each star's mean. Upper bounds are
        about ten times seed 000's counts (a lab day). The chromatic test's filters are a
        shape, not a count (:meth:`protocol_shapes`); its four corner fields (whose symmetric
        average eqs 13-16 take) are what the chromatic estimators are built on, so they are not
        planned; the frames per field and filter are."""
        knobs = {
            "te.frames": Knob("protocols.te.frames", "int", 2, 300, "frames",
                              "TE: frames of the static target (seed 000: >= 30)"),
            "hsfe.frames": Knob("protocols.hsfe.frames", "int", 2, 300, "frames", "HSFE: frames per pose"),
            "hsfe.poses": Knob("protocols.hsfe.conditions", "int", 3, 48, "poses",
                               "HSFE: poses (along the diagonal, or on the grid, as protocols.hsfe.pattern says)"),
            "chromatic.frames": Knob("protocols.chromatic.frames", "int", 2, 300, "frames",
                                     "LSFE-S: frames per corner field and filter"),
            "distortion.frames": Knob("protocols.distortion.frames", "int", 2, 300, "frames",
                                      "LSFE-C1: frames of the calibration grid"),
            "dark_frames": Knob("validation.dark_frames", "int", 0, 30, "frames",
                                "dark frames per condition subtracted before centroiding (0: the window "
                                "border's background)"),
            "distortion.extent": Knob("lab.calibration_target.extent_fraction", "real", 0.3, 1.0, "of the mosaic",
                                      "LSFE-C1: the calibration grid's extent (its points tile this fraction of "
                                      "the mosaic; seed 000's grid: 0.85)"),
        }
        return tuple(knobs[name] for name in scenario.protocols.plan_knobs)

    def protocol_shapes(self, scenario) -> dict[str, dict]:
        """The shapes of the tests a plan opens (docs/validation.md, "Planning the test"), crossed:

        * the HSFE step patterns, where the plan opens an HSFE count (``hsfe.frames`` or
          ``hsfe.poses`` in ``protocols.plan_knobs``) and the validation runs HSFE: seed 000's
          ``diagonal`` (the scenario's own poses along one direction) and the ``grid`` over
          pixels in both axes (one pose in each row and column of a grid of pitch
          ``1 + 1/conditions`` px unless ``grid_step_px`` is given), which sees the static error
          the diagonal cannot;
        * the chromatic test's filter sets (``protocols.chromatic.filters_nm``), where the plan
          opens ``chromatic.frames`` and the validation runs the chromatic test: those of
          ``protocols.chromatic.plan_filter_sets``, or every set of at least 2 of the lab's
          filters that holds the reference (seed 000: 500/600, 600/800, 500/600/800), at most
          :data:`simcam.starcam.scenario.MAX_PLAN_FILTER_SETS` (a ScenarioError naming
          ``protocols.chromatic.plan_filter_sets`` beyond).

        Names: ``"grid"`` with the HSFE patterns only (as before filter sets were shapes),
        ``"filters 500/600"`` with the filter sets only, ``"grid, filters 500/600/800"`` with
        both (centres in nm, ascending). A test the plan does not open keeps the scenario's
        shape. Every shape takes the same knobs."""
        opened = set(scenario.protocols.plan_knobs)
        run = set(scenario.validation.protocols)
        dims: list[dict[str, dict]] = []
        if "hsfe" in run and opened & {"hsfe.frames", "hsfe.poses"}:
            dims.append({"diagonal": {"protocols.hsfe.pattern": "diagonal"},
                         "grid": {"protocols.hsfe.pattern": "grid"}})
        if "chromatic" in run and "chromatic.frames" in opened:
            c = scenario.protocols.chromatic
            if c.plan_filter_sets:
                sets = [tuple(sorted(fs)) for fs in c.plan_filter_sets]
            else:
                ref = c.reference_filter_nm
                others = sorted(f.center_nm for f in scenario.lab.filters if f.center_nm != ref)
                sets = [tuple(sorted((ref,) + o)) for n in range(1, len(others) + 1)
                        for o in combinations(others, n)]
                if len(sets) > MAX_PLAN_FILTER_SETS:
                    raise ScenarioError(
                        f"{scenario.source}: protocols.chromatic.plan_filter_sets: the lab's {len(others) + 1} "
                        f"filters give {len(sets)} sets with the reference, more than the "
                        f"{MAX_PLAN_FILTER_SETS} a plan compares: list the sets to compare")
            dims.append({"filters " + "/".join(f"{f:g}" for f in fs): {"protocols.chromatic.filters_nm": list(fs)}
                         for fs in sets})
        shapes: dict[str, dict] = {"": {}}
        for dim in dims:
            shapes = {(f"{a}, {b}" if a else b): {**oa, **ob} for a, oa in shapes.items() for b, ob in dim.items()}
        return {} if shapes == {"": {}} else shapes

    def field_classes(self, scenario) -> dict[str, tuple[str, ...]]:
        """The classes each plannable field (every knob's and every shape's field) can change
        (:meth:`~budget.runner.capabilities.SeparablePlans.field_classes`): a protocol's counts and shape change
        its own class and what is built from it (LSFE from LSFE-S and LSFE-C1, the total from
        all), the dark frames every class. Exact in the ideal world (tested: every other
        class's trial values bit for bit the same). In the realistic world a count also moves
        the world's timeline of the protocols after it (:mod:`simcam.starcam.world`: the drift
        at their frames' times, the hexapod draws after its moves), which changes their trials'
        draws (tested); their distribution only through the drift ramp's offset at their time,
        which moves every image of a condition alike (the random part is stationary, the ramp
        within a condition depends on that condition's own duration, each move's error is drawn
        alike; the default 0.05"/h ramp moves an image by under 0.01 px over a run). That
        coupling is left out here: a separable plan searches each test with the others at the
        scenario's counts, and the union's re-validation, which runs the whole protocol on
        fresh seeds, is what measures each test as the union runs it (docs/planning.md,
        "Separable plans")."""
        lsfe_s = ("lsfe_s", "lsfe", "total")
        every = tuple(n for n, _, _ in _CLASSES)
        return {
            "protocols.te.frames": ("te", "total"),
            "protocols.hsfe.frames": ("hsfe", "total"),
            "protocols.hsfe.conditions": ("hsfe", "total"),
            "protocols.hsfe.pattern": ("hsfe", "total"),
            "protocols.chromatic.frames": lsfe_s,
            "protocols.chromatic.filters_nm": lsfe_s,
            "protocols.distortion.frames": ("lsfe_c1", "lsfe", "total"),
            "lab.calibration_target.extent_fraction": ("lsfe_c1", "lsfe", "total"),
            "validation.dark_frames": every,
        }

    def shape_value(self, scenario, field: str):
        """A shape field as the protocol uses it (:meth:`~budget.runner.capabilities.ProtocolShapes.shape_value`):
        the chromatic test's filter set is :meth:`~simcam.starcam.scenario.Scenario.chromatic_filters_nm`
        (an empty ``protocols.chromatic.filters_nm``, seed 000's default, is every lab filter,
        the shape ``filters 500/600/800``); any other field as the scenario holds it."""
        if field == "protocols.chromatic.filters_nm":
            return scenario.chromatic_filters_nm()
        return super().shape_value(scenario, field)

    def uncomputed_class(self, scenario, name: str) -> str | None:
        """A seed-000 class the scenario's ``validation.protocols`` leaves out (its protocols,
        :data:`budget.starcam.validate.CLASS_NEEDS`, not all computed), in words naming the field."""
        from budget.starcam.validate import CLASS_NEEDS, computed_classes

        if name not in CLASS_NEEDS or name in computed_classes(scenario):
            return None
        run = list(scenario.validation.protocols)
        missing = [p for p in CLASS_NEEDS[name] if p not in run]
        return (f"{name} is a {self.name} class this scenario does not compute: validation.protocols "
                f"({', '.join(run)}) leaves out its protocol{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)}; add {'them' if len(missing) > 1 else 'it'} to validation.protocols "
                f"to plan {name}")

    def restrict_classes(self, scenario, classes: frozenset[str]):
        """The scenario with ``validation.protocols`` = the protocols the classes need
        (:func:`budget.starcam.validate.protocols_for`; LSFE-C2 needs none, so a set of it
        alone runs the cheapest protocol, TE); the scenario itself when it runs just those.
        Its trials and truths give the same numbers for those classes as the full scenario on
        the same seed (tests/test_starcam_protocols_subset.py)."""
        from budget.starcam.validate import CLASS_NEEDS, protocols_for

        unknown = set(classes) - set(CLASS_NEEDS)
        if unknown:
            raise ValueError(f"restrict_classes: unknown class(es) {sorted(unknown)}")
        need = protocols_for(classes) or ("te",)
        if set(need) == set(scenario.validation.protocols):
            return scenario
        return with_updates(scenario, {"validation.protocols": list(need)}).with_source(scenario.source)

    def lab_time_s(self, scenario) -> dict[str, float]:
        """Lab seconds of the scenario's four protocols, by item, from its own fields
        (``camera.exposure_s``, ``[protocols]`` and ``protocols.timing``):

        * ``<protocol>.frames``: its lit frames x (exposure + ``frame_readout_s``);
        * ``dark_frames``: ``validation.dark_frames`` per condition of every protocol, each
          condition's dark frames x the frame period plus ``dark_switch_s`` (the shutter);
        * ``<protocol>.changes``: between consecutive conditions of a protocol, in plan order,
          ``hexapod_move_s`` where the pointing changes, ``filter_change_s`` where the filter
          changes, and ``settle_s`` once where either does (the HSFE poses; the chromatic
          filters and corner fields);
        * ``setup``: ``protocol_setup_s`` per protocol (target and alignment);
        * ``warmup``: ``source_warmup_s`` once.
        """
        from budget.starcam.protocols import PROTOCOLS, make_plan

        t = scenario.protocols.timing
        period = scenario.camera.exposure_s + t.frame_readout_s
        dark = scenario.validation.dark_frames
        out: dict[str, float] = {}
        n_conditions = 0
        for proto in PROTOCOLS:
            conds = make_plan(proto, scenario).conditions
            n_conditions += len(conds)
            out[f"{proto}.frames"] = float(sum(c.frames for c in conds)) * period
            changes = 0.0
            for a, b in zip(conds[:-1], conds[1:]):
                moved = ((a.field_center_px, a.platform_dx_px, a.platform_dy_px)
                         != (b.field_center_px, b.platform_dx_px, b.platform_dy_px))
                filtered = a.filter_nm != b.filter_nm
                changes += t.hexapod_move_s * moved + t.filter_change_s * filtered + t.settle_s * (moved or filtered)
            if changes:
                out[f"{proto}.changes"] = changes
        out["dark_frames"] = n_conditions * (dark * period + t.dark_switch_s) if dark else 0.0
        out["setup"] = len(PROTOCOLS) * t.protocol_setup_s
        out["warmup"] = t.source_warmup_s
        return out

    def likely_cause(self, result, key, stats) -> str | None:
        """Seed 000's causes (docs/validation.md), each given only where the run's numbers show
        its pattern; the numbers quoted are computed from this run."""
        cls, var, ax = key
        b = stats["bias"]
        truth = result.truths.get
        if cls == "hsfe" and var == "published":
            p = result.scenario.protocols.hsfe
            te_key = ("te", var, ax)
            if te_key not in result.samples:
                return None
            # TE's truth: the run's, or the mean of each trial's camera's
            floor = result.statistics(te_key)["truth"] * (2.0 / p.frames) ** 0.5
            near = abs(stats["mean"] - floor)
            # at the floor: within 3 standard errors or 15 % of it, and nearer it than the truth
            if near <= max(3.0 * stats.get("se_bias", 0.0), 0.15 * floor) and near < abs(stats["mean"] - stats["truth"]):
                return (f"the published estimator measures temporal noise, not the pixel error: its mean "
                        f"{fmt(stats['mean'], 3)} sits at the temporal-noise floor of the {p.frames}-frame means "
                        f"(TE x sqrt(2/{p.frames}) = {fmt(floor, 3)}), not at the static error {fmt(stats['truth'], 3)}.")
            seen = (f", and the {p.conditions} poses along one diagonal see only part of the static error"
                    if getattr(p, "pattern", "diagonal") == "diagonal" else "")
            return (f"the scatter of the {p.frames}-frame means about the fitted steps holds their temporal noise "
                    f"(about {fmt(floor, 3)}) beside the static error{seen}: its sign depends on which dominates.")
        if cls == "hsfe" and b < 0 and getattr(result.scenario.protocols.hsfe, "pattern", "diagonal") == "diagonal":
            p = result.scenario.protocols.hsfe
            return (f"the improved static estimator removes the temporal noise but cannot see the part of the "
                    f"static error that stays constant over the {p.conditions} poses ({p.step_px:g} px steps "
                    "along one direction), which no estimator of this protocol can separate from the target's "
                    "geometry; measuring HSFE needs steps spanning several pixels in both axes.")
        if cls == "te" and var == "improved" and b > 0:
            return ("the pooled rms sqrt(mean_j sd_j^2) exceeds the truth's mean_j sd_j whenever the stars' sds "
                    "differ (Jensen's inequality).")
        if cls == "lsfe_s" and var == "published":
            return ('averaging signed differences over four symmetric corners cancels any radially symmetric '
                    'lateral colour, and the "/2, /3" factors are not the camera\'s spectral response.')
        if cls == "lsfe_s":
            return ("the lab's imperfect spectral model (its stated QE, filter, lamp and Teff errors) and, on a "
                    "noisy camera, the static pixel error that changes between filters and enters the slope.")
        if cls == "lsfe_c1":
            scn = result.scenario
            tgt = scn.lab.calibration_target
            n_pts = tgt.rows * tgt.cols
            c2, c1 = truth(("lsfe_c2", ax)), truth(("lsfe_c1", ax))
            # the markers' part in eq 29: 9 of a cubic's 10 terms over n - 1 degrees of freedom
            floor = (9 / (n_pts - 1)) ** 0.5 * c2.value if c2 is not None else None
            se = stats.get("se_bias", 0.0)
            # the world's distortion beyond the lab's cubic (r^5, r^7 of [world.effects]) on a camera
            # that corrects its own distortion with a cubic: the truth (the rms over the dense field
            # of what that correction leaves) holds it; an estimate from the calibration points,
            # where the correction was fitted, sees it only in part (docs/validation.md)
            eff = getattr(getattr(scn, "world", None), "effects", None)
            a5 = float(getattr(eff, "distortion_r5_px_at_corner", 0.0) or 0.0)
            a7 = float(getattr(eff, "distortion_r7_px_at_corner", 0.0) or 0.0)
            raw = c1.details.get(f"raw_static_rms_{ax}_px") if c1 is not None else None
            beyond = None
            if (a5 or a7) and raw and c1.details.get("camera_correction") == "fitted":
                f = self._factor(scn)
                cor = scn.optics.distortion_correction
                same = (cor.rows, cor.cols, cor.extent_fraction) == (tgt.rows, tgt.cols, tgt.extent_fraction)
                beyond = (f"the world's distortion beyond the lab's cubic (r^5 {a5:g} px, r^7 {a7:g} px at the "
                          f"corner, [world.effects]) is in the truth: the camera's order-{cor.order} correction "
                          f"leaves {fmt(c1.value, 3)} of the {fmt(raw * f, 3)} raw static displacement "
                          f"({100 * c1.value / (raw * f):.0f} %) over {c1.details.get('dense_points', 'the')} "
                          f"points of the field, but it was fitted at a {cor.rows} x {cor.cols} grid"
                          + (", the lab's own calibration points," if same else "")
                          + " and leaves less of it there")
            if var == "published":
                # eq 29 reports the cubic part of the points' displacements: the markers' floor and,
                # were it seen, the camera's residual beside it (root-sum-square)
                seen = math.hypot(floor, stats["truth"]) if floor is not None else None
                blind = beyond is not None and seen is not None and stats["mean"] < seen - 3.0 * se
                fl = f" (sqrt(9/{n_pts - 1}) x {fmt(c2.value, 3)} = {fmt(floor, 3)})" if floor is not None else ""
                s = f"eq 29 reports the target markers' floor{fl} beside the camera's residual" if b > 0 else ""
                if blind:
                    s += ("; " if s else "") + (
                        f"{beyond}: its mean {fmt(stats['mean'], 3)} stays below the {fmt(seen, 3)} that the floor and "
                        f"the whole truth {fmt(stats['truth'], 3)} give together (root-sum-square)")
                return s + "." if s else None
            if beyond is not None and b < 0 and stats["bias_significant"]:
                return (f"{beyond}; the estimate sees the displacement only at the {n_pts} "
                        f"calibration points: its mean {fmt(stats['mean'], 3)} falls {fmt(-b, 3)} short of the truth.")
            if b > 0 or not stats["bias_significant"]:
                # a sample variance of n points has a relative sd of sqrt(2 / (n - 1))
                return (f"the marker variance it subtracts is known to about +-{100 * (2 / (n_pts - 1)) ** 0.5:.0f} % "
                        f"from {n_pts} points, and its estimate is clipped at 0; on a noisy camera the static "
                        "pixel error at the points adds.")
            return None
        if cls in ("lsfe", "total"):
            parts = ("lsfe_s", "lsfe_c1") if cls == "lsfe" else ("te", "hsfe", "lsfe")
            bad = [p for p in parts if (p, var, ax) in result.samples
                   and result.statistics((p, var, ax))["bias_significant"]]
            rule = " (eq 31 adds C1 and C2 linearly)" if cls == "lsfe" and var == "published" else ""
            if bad or rule:
                return (f"it is built from its parts{rule}" +
                        (f"; biased parts: {', '.join(bad)}." if bad else "."))
        return None

    def report_sections(self, result, out_dir: Path) -> list[ReportSection]:
        ex = (result.example.extra.get("kept", {}) if result.example else {})
        figs = []
        if "hsfe" in ex:
            figs.append(plot_hsfe_residuals(ex["hsfe"]["estimates"]["published"], out_dir / "hsfe_residuals.png",
                                            finding=self._hsfe_finding(result)))
        if "chromatic" in ex:
            figs.append(plot_chromatic_residuals(ex["chromatic"]["data"].centroids, out_dir / "chromatic_residuals.png",
                                                 result.scenario.protocols.chromatic.reference_filter_nm))
        if "distortion" in ex:
            figs.append(plot_distortion_residuals(ex["distortion"]["estimates"]["published"],
                                                  out_dir / "distortion_residuals.png"))
        te = result.truths.get(("te", "x"))
        f = self._factor(result.scenario)
        scn = result.scenario
        c1 = ("still displaces after its own distortion correction"
              if scn.optics.distortion_correction.kind != "none"
              else "a cubic calibration would leave (uncalibrated camera)")
        eff = scn.world.effects
        on = [f"{n} = {getattr(eff, n):g}" for n in eff.active()]
        text = [
            "World effects (`[world.effects]`, what the lab's methods do not model): "
            + ("; ".join(on) + "." if on else "none (the ideal world)."),
            "What is compared. **Truth**: the quantity each method claims to measure, computed from the "
            "injected physics by a route that shares nothing with the estimators (budget.starcam.truth): TE, the mean "
            "temporal centroid sd; HSFE, the rms static error of the expected centroid under the lab's noise; "
            "LSFE-S, the rms chromatic displacement of the stellar population about its reference "
            f"({scn.validation.calibration_spectrum}); LSFE-C1, what the camera {c1}; LSFE-C2, the given "
            "marker error (an input). TE and HSFE truths are Monte Carlo estimates and carry a standard "
            "error" + (", and, like LSFE-C1's, each trial's camera's own (its pixel maps, its calibration): "
                       "the bias is over cameras like it" if scn.validation.maps_per_trial else "")
            + ". **published**: seed 000's own estimator of each class (eqs 1-2, 3-12, 13-16, 17-30, 31). "
            "**improved**: the estimator derived in docs/estimators.md that targets the truth with only what "
            "a lab knows (its own, imperfect spectral model; the marker error it was given).",
            f"Plate scale {scn.camera.scale_arcsec_per_px:g} arcsec/px."]
        if te is not None and "cramer_rao_x_px" in te.details:
            text.append(f"TE truth against the Cramer-Rao bound of an unbiased centroid from the same pixels: "
                        f"x {result.truths[('te', 'x')].value:.3f} vs {te.details['cramer_rao_x_px'] * f:.3f}, "
                        f"y {result.truths[('te', 'y')].value:.3f} vs {te.details['cramer_rao_y_px'] * f:.3f} "
                        f"arcsec (3 sigma).")
        named = [d for proto, d in (("hsfe", "the HSFE residual's rms over stars per step (fig. 6)"),
                                    ("chromatic", "colour differences per corner field (fig. 7)"),
                                    ("distortion", "distortion residuals before and after the cubic fit (fig. 8)"))
                 if proto in ex]
        if named:
            # only the figures of the protocols this run computed (validation.protocols)
            text.append("Figures from trial 0: " + ", ".join(named) + ".")
        if figs:
            text.append(figure_markdown(figs))
        # the figures are placed in the text, each with its caption under it
        return [ReportSection("Seed-000 details", "\n\n".join(text), [])]

    @staticmethod
    def _hsfe_finding(result) -> str:
        """Where each variant's HSFE estimate sits against its truth over the run (from the
        run's statistics; a percentage only where the truth is far from zero against its
        standard error)."""
        parts = []
        for v in result.study.variants:
            for ax in ("x", "y"):
                key = ("hsfe", v, ax)
                if key not in result.samples:
                    continue
                st = result.statistics(key)
                t, b = st["truth"], st["bias"]
                if not (abs(t) > 3 * max(st.get("truth_se", 0.0) or 0.0, 1e-300)):
                    continue
                where = "above" if b > 0 else "below"
                parts.append(f"{v} {abs(100 * b / t):.0f} % {where} ({ax}: {t + b:.4f} vs {t:.4f} arcsec)")
        if not parts:
            return ""
        return (f"Over the {result.trials} trials the HSFE estimates sit against their truth: "
                + "; ".join(parts) + ".")


STUDY = StarCameraStudy()
