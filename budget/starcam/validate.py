"""The seed-000 trial and truths: what the study (:mod:`budget.starcam.study`) gives the runner.

Each trial (:func:`run_trial`) runs the four protocols (TE, HSFE, chromatic, distortion)
on its own camera (pixel maps and onboard calibration errors drawn per trial unless
``validation.instrument_seed`` pins one, :mod:`budget.starcam.setup`) with independent
temporal noise (and, where the scenario says so, new marker errors, new hexapod positioning
errors), through the same
estimators as real data (:func:`budget.starcam.protocols.estimate`). :func:`truths` computes each
class's truth (:mod:`budget.starcam.truth`), in independent pieces (:func:`truth_parts`) that the
runner spreads over its workers. The runner (:mod:`budget.runner.run`) does the rest:
trials on workers, adaptive stopping, statistics, JSON, report.

Randomness: trial ``k`` draws its noise and markers from ``SeedSequence(seed, spawn_key=(k,))``
and its camera from :func:`budget.runner.study.instrument_seed_sequence`, so a trial's result
does not depend on how many workers run or in which order they finish.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from budget.starcam.protocols import PROTOCOLS, estimate, make_plan, simulate
from budget.starcam.setup import CameraSetup, per_instrument

CLASSES = ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2", "lsfe", "total")
VARIANTS = ("published", "improved")
AXES = ("x", "y")
#: classes whose value is given to the lab, not measured by it: reported, never "validated"
#: (LSFE-C2, the marker calibration error of the grid target, seed 000 section 1.4.3)
INPUT_CLASSES = ("lsfe_c2",)
#: protocol producing each measured class
CLASS_PROTOCOL = {"te": "te", "hsfe": "hsfe", "lsfe_s": "chromatic", "lsfe_c1": "distortion"}
#: the protocols each class needs (LSFE-C2 is an input: none; LSFE eq 31 needs S and C1, the
#: total TE, HSFE and LSFE)
CLASS_NEEDS = {"te": ("te",), "hsfe": ("hsfe",), "lsfe_s": ("chromatic",), "lsfe_c1": ("distortion",),
               "lsfe_c2": (), "lsfe": ("chromatic", "distortion"), "total": PROTOCOLS}
#: the classes whose truth is each camera's own when every trial draws its camera
#: (:func:`budget.starcam.setup.per_instrument`): LSFE-C1 is what the trial's camera's onboard
#: correction leaves (computed in the trial), LSFE and the total combine it with the fixed
#: truths (:mod:`budget.runner.combined_truths`); TE and HSFE too when the trial's camera
#: draws its pixel maps (:func:`instrument_classes`)
INSTRUMENT_CLASSES = ("lsfe_c1", "lsfe", "total")


def instrument_classes(scenario) -> tuple[str, ...]:
    """The classes whose truth is each trial's camera's own, computed in the trial: none for a
    pinned camera, else :data:`INSTRUMENT_CLASSES`, and TE and HSFE when every trial draws its
    pixel maps (``validation.maps_per_trial``: :func:`budget.starcam.truth.te_trial_truth`,
    :func:`budget.starcam.truth.hsfe_trial_truth`)."""
    if not per_instrument(scenario):
        return ()
    return INSTRUMENT_CLASSES + (("te", "hsfe") if scenario.validation.maps_per_trial else ())


#: the classes each combined class is the root-sum-square of (seed 000 eq 31, eq 32)
RSS_OF = {"lsfe": ("lsfe_s", "lsfe_c1", "lsfe_c2"), "total": ("te", "hsfe", "lsfe")}


def computed_classes(scenario) -> tuple[str, ...]:
    """The classes a validation of ``scenario`` computes: those whose protocols
    (:data:`CLASS_NEEDS`) are all among ``validation.protocols``, in :data:`CLASSES` order."""
    run = set(scenario.validation.protocols)
    return tuple(c for c in CLASSES if set(CLASS_NEEDS[c]) <= run)


def protocols_for(classes) -> tuple[str, ...]:
    """The protocols (acquisition order) that the classes ``classes`` need."""
    need = {p for c in classes for p in CLASS_NEEDS[c]}
    return tuple(p for p in PROTOCOLS if p in need)


def trial_seeds(seed: int, k: int) -> tuple[int, int, int]:
    """(noise seed, unused, marker seed) of trial ``k``: ``SeedSequence(seed, spawn_key=(k,))``
    (the second word drew the pixel maps before each trial drew its camera,
    :func:`budget.starcam.setup.instrument_seeds`; kept so that noise and markers are unchanged)."""
    s = np.random.SeedSequence(seed, spawn_key=(k,)).generate_state(3, dtype=np.uint32)
    return int(s[0]), int(s[1]), int(s[2])


def _setup(scenario, setup: CameraSetup | None) -> CameraSetup:
    """``setup`` (the runner's, :meth:`budget.starcam.study.StarCameraStudy.setup`), or a new one
    for a direct call."""
    return setup if setup is not None else CameraSetup(scenario)


def run_trial(scenario, seed: int, k: int, *, keep: bool = False, setup: CameraSetup | None = None,
              camera=None) -> dict:
    """One validation trial: every protocol of ``validation.protocols`` (default all four)
    through the published and improved estimators.

    Returns ``{"k": k, "values": {(class, variant, axis): sigma_px}, "truths": {...}}`` for the
    classes :func:`computed_classes` names; ``truths`` holds the truths of the trial's own
    camera (px) of :func:`instrument_classes`: LSFE-C1's (:func:`budget.starcam.truth.lsfe_c1_truth`)
    when every trial draws its camera, TE's and HSFE's (:func:`budget.starcam.truth.te_trial_truth`,
    :func:`budget.starcam.truth.hsfe_trial_truth`, streams :func:`trial_truth_seed`) when it
    draws its pixel maps too; with ``keep`` also
    ``"kept"``: the estimate objects and data of each protocol (for the report). A protocol's
    numbers do not depend on which
    others run: its frames draw from their own noise streams of the trial's noise seed
    (:func:`budget.starcam.protocols.simulate`), its pose errors from the trial's seeds, and
    the world's timeline is the whole lab run's (:mod:`simcam.starcam.world`). ``setup``: the
    scenario's camera set-up (:class:`budget.starcam.setup.CameraSetup`; a new one by default);
    ``camera``: the camera to measure (default the trial's own, :meth:`CameraSetup.instrument`;
    ``setup.camera()`` is the scenario seed's, the one every trial used before cameras were
    drawn per trial).
    """
    noise_seed, _, marker_seed = trial_seeds(seed, k)
    val = scenario.validation
    setup = _setup(scenario, setup)
    cam = setup.instrument(seed, k) if camera is None else camera
    ps = scenario.camera.scale_arcsec_per_px
    values: dict = {}
    kept: dict = {}
    run = [p for p in PROTOCOLS if p in val.protocols]
    spectral = setup.spectral() if "chromatic" in run else None
    with warnings.catch_warnings():
        # clipped variances and flagged stars are expected in some trials; counted via flags
        warnings.simplefilter("ignore")
        for proto in run:
            plan = make_plan(proto, scenario, seed=noise_seed, dark_frames=val.dark_frames)
            data = simulate(plan, cam, seed=noise_seed, method=val.centroid_method,
                            threshold_sigma=val.threshold_sigma,
                            marker_seed=marker_seed if val.new_markers_per_trial else None)
            res = estimate(proto, data.rows, plate_scale_arcsec=ps, reference=data.reference_rows,
                           reference_filter_nm=scenario.protocols.chromatic.reference_filter_nm,
                           marker_3sigma_arcsec=scenario.lab.calibration_target.marker_error_3sigma_arcsec,
                           spectral=spectral, extra_variants=keep,
                           camera_corrects_distortion=scenario.optics.distortion_correction.kind != "none")
            cls = {"te": "te", "hsfe": "hsfe", "chromatic": "lsfe_s", "distortion": "lsfe_c1"}[proto]
            for var in VARIANTS:
                values[(cls, var, "x")] = res[var].sigma_x_px
                values[(cls, var, "y")] = res[var].sigma_y_px
            if keep:
                kept[proto] = {"estimates": res, "data": data}
    c2 = scenario.lab.calibration_target.marker_error_3sigma_arcsec / 3.0 / ps
    classes = computed_classes(scenario)
    for var in VARIANTS:
        for ax in AXES:
            values[("lsfe_c2", var, ax)] = c2
            if "lsfe" not in classes:
                continue
            s, c1 = values[("lsfe_s", var, ax)], values[("lsfe_c1", var, ax)]
            if var == "published":  # seed 000 eq 31: C1 and C2 added linearly
                lsfe = math.sqrt(s**2 + (c1 + c2) ** 2)
            else:  # independent sources: root-sum-square
                lsfe = math.sqrt(s**2 + c1**2 + c2**2)
            values[("lsfe", var, ax)] = lsfe
            if "total" in classes:
                values[("total", var, ax)] = math.sqrt(values[("te", var, ax)] ** 2
                                                       + values[("hsfe", var, ax)] ** 2 + lsfe**2)
    out = {"k": k, "values": values, "truths": {}}
    from budget.starcam.truth import hsfe_trial_truth, lsfe_c1_truth, te_trial_truth

    # the trial's camera's own truths (LSFE-C1 exact; TE and HSFE from the trial's truth streams)
    routes = {"lsfe_c1": lambda: lsfe_c1_truth(cam),
              "te": lambda: te_trial_truth(cam, seed=trial_truth_seed(seed, k, "te")),
              "hsfe": lambda: hsfe_trial_truth(cam, seed=trial_truth_seed(seed, k, "hsfe"))}
    own = instrument_classes(scenario)
    for cls, route in routes.items():
        if cls in own and cls in classes:
            t = route()
            out["truths"].update({(cls, var, ax): getattr(t, f"{ax}_px") for var in VARIANTS for ax in AXES})
    if keep:
        out["kept"] = kept
    return out


def _truth_seed(seed: int) -> int:
    return int(np.random.SeedSequence(seed, spawn_key=(2**31,)).generate_state(1)[0])


#: the word of :func:`trial_truth_seed` of each class whose truth a trial computes with noise
_TRIAL_TRUTH_STREAM = {"hsfe": 0, "te": 1}


def trial_truth_seed(seed: int, k: int, cls: str) -> int:
    """The stream of trial ``k``'s own truth of ``cls`` (TE's and HSFE's, with the camera's own
    maps): word ``0`` (HSFE) or ``1`` (TE) of ``SeedSequence(truth seed, spawn_key=(7, k))``,
    apart from the trial's noise and from the run's truths."""
    words = np.random.SeedSequence(_truth_seed(seed), spawn_key=(7, k)).generate_state(2)
    return int(words[_TRIAL_TRUTH_STREAM[cls]])


def truth_parts(scenario, *, seed: int) -> list[tuple]:
    """The independent pieces of :func:`truths`, computable anywhere and in any order:
    ``("rest",)`` (LSFE-S, LSFE-C2, and LSFE-C1 of a pinned camera), ``("te",)`` and one
    ``("hsfe", phase)`` per sub-pixel phase of the HSFE truth, on the camera every trial's pixels
    share (trial 0's: the scenario seed's maps, or the pinned camera), none where those
    truths are each trial's camera's own (:func:`instrument_classes`). Only the truths of the
    classes the scenario computes (:func:`computed_classes`): no HSFE pieces without the HSFE
    protocol, no TE pieces without the TE protocol."""
    classes = computed_classes(scenario)
    own = instrument_classes(scenario)
    parts: list[tuple] = [("rest",)]
    if "te" in classes and "te" not in own:
        parts.append(("te",))
    if "hsfe" in classes and "hsfe" not in own:
        parts += [("hsfe", p) for p in range(scenario.validation.hsfe_phase_grid**2)]
    return parts


def truth_part(scenario, *, seed: int, part: tuple, control_variate: bool = True, setup: CameraSetup | None = None):
    """One piece of :func:`truths` (see :func:`truth_parts`); ``control_variate`` False: the
    plain estimators (:func:`budget.starcam.truth.te_truth`, :func:`budget.starcam.truth.hsfe_truth`).
    Streams: TE the truth seed itself, HSFE its ``spawn_key=(2,)``."""
    from budget.starcam.truth import hsfe_phase_cell, lsfe_c1_truth, lsfe_c2_truth, lsfe_s_truth, te_truth

    ts = _truth_seed(seed)
    val = scenario.validation
    setup = _setup(scenario, setup)
    if part[0] == "rest":
        classes = computed_classes(scenario)
        out = {}
        if "lsfe_s" in classes:
            out["lsfe_s"] = lsfe_s_truth(setup.camera())  # the optics' lateral colour: every camera's
        if "lsfe_c1" in classes and not per_instrument(scenario):
            out["lsfe_c1"] = lsfe_c1_truth(setup.instrument(seed, 0))
        out["lsfe_c2"] = lsfe_c2_truth(scenario)
        return out
    cam = setup.instrument(seed, 0)  # the pixels every trial shares (their truths do not read the calibration)
    if part[0] == "te":
        return te_truth(cam, frames=val.te_truth_frames, seed=ts, control_variate=control_variate)
    hs = int(np.random.SeedSequence(ts, spawn_key=(2,)).generate_state(1)[0])
    return hsfe_phase_cell(cam, frames=val.hsfe_truth_frames, seed=hs, phase=part[1], control_variate=control_variate)


def truths_from_parts(scenario, *, seed: int, results: list, control_variate: bool = True,
                      setup: CameraSetup | None = None) -> dict:
    """:func:`truths` from the results of :func:`truth_parts`, in their order."""
    from budget.starcam.truth import combine, hsfe_from_cells

    parts = truth_parts(scenario, seed=seed)
    val = scenario.validation
    setup = _setup(scenario, setup)
    out = dict(results[0])
    for part, r in zip(parts, results):
        if part[0] == "te":
            out["te"] = r
    cells = [r for part, r in zip(parts, results) if part[0] == "hsfe"]
    if cells:
        out["hsfe"] = hsfe_from_cells(setup.instrument(seed, 0), cells, frames=val.hsfe_truth_frames,
                                      control_variate=control_variate)
    if per_instrument(scenario):
        return out  # LSFE-C1, LSFE and the total (TE and HSFE with maps per trial): each trial's camera's own
    return combine({k: out[k] for k in ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2") if k in out})


#: noisy frames of the pilot that measures the centroid scatter the truth sizes follow
SIZE_PILOT_FRAMES = 64
#: fewest frames a sized truth takes: HSFE per phase (two halves), TE
MIN_HSFE_TRUTH_FRAMES = 20
MIN_TE_TRUTH_FRAMES = 50


def truth_size_for(scenario, *, seed: int, target_px: dict, setup: CameraSetup | None = None) -> object:
    """``scenario`` with ``validation.hsfe_truth_frames`` and ``te_truth_frames`` sized so that
    the HSFE and TE truths' standard errors are about ``target_px[(class, axis)]`` (px, 1
    sigma) or below; a class without a target keeps the scenario's size.

    The sizes follow the truths' own standard-error formulas (:mod:`budget.starcam.truth`)
    with the per-frame centroid scatter ``v`` (px^2, per star and axis, common motion
    removed) of a pilot of :data:`SIZE_PILOT_FRAMES` noisy frames of the HSFE target at its
    first phase (its own stream, ``SeedSequence(truth seed, spawn_key=(5,))``, so the
    truths' streams are untouched):

    * HSFE, ``P`` phases x ``W`` stars (:func:`budget.starcam.truth.hsfe_from_cells`): to
      first order ``se = sqrt(mean v / (F P W))``, and the split-half product's second-order
      term ``mean v / (F sqrt(P W T))`` (``T`` the pilot's mean square error, when positive),
      so ``F`` is the larger of ``mean v / (P W t^2)`` and ``2 mean v / (t sqrt(P W T))``;
    * TE, plain route (:func:`budget.starcam.truth._se_mean_of_sd`): ``se = sd / sqrt(2 (F - 1) W)`` with
      ``sd^2 = mean v W / (W - 1)`` (the scatter before the common motion was removed), so
      ``F = sd^2 / (2 W t^2) + 1``, and at least ``sd / (2 t)`` so that the sample sd's own
      bias (``sd / (4 F)``, normal theory) stays below half the target;
    * TE with the control variate (:func:`budget.starcam.truth.te_truth`): ``se^2 = sum_j
      Var(D_j) / (4 V_j F) / W^2`` (``D`` the per-frame terms of :func:`budget.starcam.truth.te_variance_cv`,
      ``V_j`` the star's variance), both from a pilot of :data:`SIZE_PILOT_FRAMES` frames of the
      TE target (stream ``spawn_key=(6,)``), so ``F = sum_j Var(D_j) / (4 V_j) / (W^2 t^2)``.

    Where the control variates apply (:func:`budget.starcam.truth.control_variate_applies`)
    the HSFE pilot's scatter ``v`` is that of the corrected errors, so the same formula gives
    the far smaller sizes the variance-reduced truths need.

    Each is rounded up (HSFE to even), at least :data:`MIN_HSFE_TRUTH_FRAMES` /
    :data:`MIN_TE_TRUTH_FRAMES` and at most the scenario's own size, which is the ceiling
    of the truths' work (raise ``validation.hsfe_truth_frames`` / ``te_truth_frames`` to
    let a long run have more precise truths: on the embedded default, 200 trials already
    ask for more than the ceiling, docs/architecture.md). The truths then report their
    actual standard error, and the JSON their target beside it.
    """
    from budget.starcam.truth import _cv_frames, control_variate_applies, hsfe_phase_cell, te_scene, te_variance_cv

    val = scenario.validation
    own = instrument_classes(scenario)  # a trial's own truth has no run-level size
    want = {c: [target_px[(c, a)] for a in AXES if (c, a) in target_px and target_px[(c, a)] > 0 and c not in own]
            for c in ("hsfe", "te")}
    if not want["hsfe"] and not want["te"]:
        return scenario
    ts = _truth_seed(seed)
    setup = _setup(scenario, setup)
    ps = int(np.random.SeedSequence(ts, spawn_key=(5,)).generate_state(1)[0])
    ma, mb, va, vb = hsfe_phase_cell(setup.instrument(seed, 0), frames=SIZE_PILOT_FRAMES, seed=ps, phase=0)
    v = va * (SIZE_PILOT_FRAMES // 2)               # (2, W): per-frame variance per axis and star
    w = v.shape[1]
    upd = {}
    if want["hsfe"]:
        t = min(want["hsfe"])
        ncell = val.hsfe_phase_grid**2 * w
        vm = float(np.max(v.mean(axis=1)))
        f = vm / (ncell * t * t)
        t2 = float(np.max(np.mean(ma * mb, axis=1)))
        if t2 > 0:
            f = max(f, 2.0 * vm / (t * math.sqrt(ncell * t2)))
        f = min(max(MIN_HSFE_TRUTH_FRAMES, math.ceil(f)), val.hsfe_truth_frames)
        upd["hsfe_truth_frames"] = int(f + (f % 2))
    if want["te"] and control_variate_applies(scenario):
        t = min(want["te"])
        cam = setup.instrument(seed, 0)
        ps6 = int(np.random.SeedSequence(ts, spawn_key=(6,)).generate_state(1)[0])
        (x, y, flag, px, py, kx, ky), _ = _cv_frames(cam, te_scene(cam), frames=SIZE_PILOT_FRAMES, seed=ps6)
        good = (flag == 0).all(axis=0)
        f = 0.0
        for c, p, k in ((x, px, kx), (y, py, ky)):
            var, se_var = te_variance_cv(c[:, good], p[:, good], k[:, good])
            var_d = se_var**2 * SIZE_PILOT_FRAMES
            f = max(f, float(np.sum(var_d / (4 * np.clip(var, 1e-300, None)))) / (int(good.sum()) ** 2 * t * t))
        upd["te_truth_frames"] = int(min(max(MIN_TE_TRUTH_FRAMES, math.ceil(f)), val.te_truth_frames))
    elif want["te"]:
        t = min(want["te"])
        sd2 = float(np.max(v.mean(axis=1))) * w / max(w - 1, 1)
        f = max(sd2 / (2 * w * t * t) + 1.0, math.sqrt(sd2) / (2 * t))
        upd["te_truth_frames"] = int(min(max(MIN_TE_TRUTH_FRAMES, math.ceil(f)), val.te_truth_frames))
    return scenario.model_copy(update={"validation": val.model_copy(update=upd)})


def truths(scenario, *, seed: int, control_variate: bool = True, setup: CameraSetup | None = None) -> dict:
    """Every class's truth (:class:`budget.starcam.truth.ClassTruth`) of a validation run with ``seed``.

    The truth seed is ``SeedSequence(seed, spawn_key=(2**31,))``. When every trial draws its
    camera (the default, :func:`budget.starcam.setup.per_instrument`), LSFE-C1, LSFE and the
    total are each trial's camera's own (:func:`instrument_classes`: not here); with new pixel
    maps per trial too (the default), TE's and HSFE's as well. A pinned camera
    (``validation.instrument_seed``) has every truth here, its own. Computed piece by piece (:func:`truth_parts`), so that a runner can spread the pieces
    over its workers and get the same numbers. ``control_variate`` False: the plain HSFE and
    TE estimators on the same frames (for comparison; the runner uses the variance-reduced).
    """
    parts = truth_parts(scenario, seed=seed)
    setup = _setup(scenario, setup)
    return truths_from_parts(scenario, seed=seed, control_variate=control_variate, setup=setup,
                             results=[truth_part(scenario, seed=seed, part=p, control_variate=control_variate,
                                                 setup=setup) for p in parts])
