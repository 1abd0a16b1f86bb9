"""The one Monte Carlo runner: any study, seeded trials, workers, adaptive stopping, statistics.

``run_study(study, scenario, ...)``:

1. starts the executor (its worker processes import while this process works);
2. computes the study's truths (:meth:`Study.truths`, seeded by
   ``SeedSequence(seed, spawn_key=(2**31,))``): in this process with one worker, otherwise
   piece by piece (:meth:`Study.truth_parts`) as tasks queued after the trials, so that the
   truths' work is spread over the workers too and their many small pieces even out the
   workers' ends. Their precision follows the question
   (``truth_size="adaptive"``, the default): each sampled truth is sized
   (:meth:`Study.truth_size_for`) to a standard error of :data:`TRUTH_SE_FRACTION` (a
   quarter) of the bias standard error the run will give (:func:`truth_targets`): with a
   tolerance, of the tolerance; with a number of trials ``n``, of ``s / sqrt(n)`` with
   ``s`` the spread of the first :data:`PILOT_TRIALS` trials (the run's own trials 0, 1,
   ..., so nothing is computed twice and the size does not depend on the workers; the
   other trials are queued behind the pilot's and run meanwhile, never waiting for it). A
   truth's standard error then adds at most ``sqrt(1 + 1/16) - 1 = 3 %`` to a bias's.
   ``truth_size="fixed"`` keeps the scenario's own sizes; ``truths=`` gives truths
   computed before (a sweep's truth shared by points);
3. runs trials ``0, 1, 2, ...`` in chunks (:meth:`Study.trial_batch`; as many per worker,
   of at most :meth:`Study.chunk_trials`), each trial seeded by
   ``SeedSequence(seed, spawn_key=(k,))`` and so independent of which worker runs it and
   when; trial 0's ``extra`` is kept for the report;
4. with a tolerance, runs batches until every bias and spread standard error is below it
   (JCGM 101:2008, 7.9) or the study's cap;
5. summarises each ``(class, variant, axis)`` (:func:`budget.runner.stats.key_statistics`).

The result, :class:`budget.runner.result.StudyResult`, gives the statistics, the JSON
payload (:meth:`StudyResult.to_json`, schema ``budget.study-result/1``) and the report
(:func:`budget.runner.report.write_report`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from budget.runner.result import SCHEMA, StudyResult
from budget.runner.stats import converged
from budget.runner.study import Study, TrialResult, Truth

__all__ = ["PILOT_TRIALS", "SCHEMA", "TRUTH_SE_FRACTION", "TRUTH_SIZES", "StudyResult", "run_study",
           "sized_truths_scenario", "truth_targets", "with_targets"]

#: a sampled truth's target standard error, as a fraction of the bias standard error the
#: trials give (or of the tolerance): its share of the bias's variance is 1/16
TRUTH_SE_FRACTION = 0.25
#: trials whose spread sizes the truths of a run with a fixed number of trials
PILOT_TRIALS = 20
#: the ways truths are sized (:func:`run_study`'s ``truth_size``)
TRUTH_SIZES = ("adaptive", "fixed")
#: cap of adaptive runs whatever the study says (each trial's values are kept)
MAX_TRIALS = 10_000_000


class _TruthPart:
    """The result of one piece of the truths (:meth:`Study.truth_parts`), and which."""

    def __init__(self, index: int, value: Any):
        self.index, self.value = index, value


def _run_task(args):
    """A worker's task: a chunk of trials, or (``("truth", i, part)``) a piece of the truths."""
    study, scenario, seed, ks = args
    if isinstance(ks, tuple) and ks and ks[0] == "truth":
        return _TruthPart(ks[1], study.truth_part(scenario, seed, ks[2]))
    out = list(zip(ks, study.trial_batch(scenario, seed, list(ks))))
    for k, r in out:
        if k != 0:
            r.extra = {}  # only trial 0's goes to the report: keep the traffic small
    return out


def _worker_init(study: Study) -> None:
    study.worker_init()


def _check_trials(trials: int | None, tolerance: float | None) -> None:
    from simcam.infra.errors import UserInputError

    if trials is not None and tolerance is not None:
        raise UserInputError("--trials and --tolerance: give one of them")
    if trials is not None and trials < 2:
        raise UserInputError(f"--trials: must be at least 2 (got {trials})")
    if tolerance is not None and not (math.isfinite(tolerance) and tolerance > 0):
        raise UserInputError(f"--tolerance: must be a positive number (got {tolerance})")


def truth_targets(classes, *, tolerance: float | None = None, samples: dict | None = None,
                  trial_truths: dict | None = None, trials: int | None = None) -> dict[tuple[str, str], float]:
    """Target standard error of each fixed truth ``(class, axis)``, in the class's unit:
    :data:`TRUTH_SE_FRACTION` of the tolerance, or of the smallest over the variants of
    ``s / sqrt(trials)`` with ``s`` the sample sd of ``samples`` (a pilot's estimates).
    Classes with per-trial truths or of role ``input`` have none; nor has a key whose
    estimates do not scatter (a deterministic estimator: its truth must be exact or as
    the scenario sizes it)."""
    keep = {c.name for c in classes if not c.per_trial_truth and c.role != "input"}
    out: dict[tuple[str, str], float] = {}
    if tolerance is not None:
        return {(c.name, a): TRUTH_SE_FRACTION * float(tolerance) for c in classes if c.name in keep for a in c.axes}
    for (cls, _var, ax), x in (samples or {}).items():
        if cls not in keep or (trial_truths and (cls, _var, ax) in trial_truths) or len(x) < 2:
            continue
        sd = float(np.std(np.asarray(x, dtype=float), ddof=1))
        if not (math.isfinite(sd) and sd > 0):
            continue
        t = TRUTH_SE_FRACTION * sd / math.sqrt(trials)
        out[(cls, ax)] = min(out.get((cls, ax), math.inf), t)
    return out


def sized_truths_scenario(study: Study, scenario: Any, seed: int, targets: dict) -> Any:
    """The scenario the truths are computed on: :meth:`Study.truth_size_for` (no targets: as given)."""
    return study.truth_size_for(scenario, seed, targets) if targets else scenario


def with_targets(truths: dict, targets: dict) -> dict:
    """The sampled truths (``se > 0``) with their target standard error (``target_se``) among
    their details (the JSON shows it); an exact truth needs none and is left as it is."""
    return {k: (Truth(t.value, t.se, {**t.details, "target_se": float(targets[k])}) if k in targets and t.se > 0
                else t)
            for k, t in truths.items()}


def run_study(study: Study, scenario: Any, *, trials: int | None = None, tolerance: float | None = None,
              seed: int = 0, workers: int | None = 1, scheduler: str | None = None,
              dask_local: int | None = None, progress: bool = False, prewarm: bool = True,
              truth_size: str = "adaptive", truths: dict | None = None, executor=None) -> StudyResult:
    """Run ``study`` on ``scenario`` (see the module docstring).

    Parameters
    ----------
    trials : int, optional
        Fixed number of trials (default: the study's, unless a tolerance is given).
    tolerance : float, optional
        Adaptive stopping: every Monte Carlo standard error below this, in the classes' unit.
    seed : int
        Run seed.
    workers, scheduler, dask_local :
        Where trials run (:func:`budget.runner.executors.make_executor`); results do not
        depend on it.
    progress : bool
        A progress bar on stderr.
    prewarm : bool
        Let the study compile its kernels on this machine's cores first on a cold numba
        cache (:meth:`Study.prewarm`; never with ``scheduler``). A caller that runs many
        studies (a sweep) does it once itself and passes False.
    truth_size : {"adaptive", "fixed"}
        ``adaptive``: the truths sized to the run's precision (module docstring);
        ``fixed``: the scenario's own truth sizes.
    truths : dict, optional
        The truths, computed before (with this seed, by :meth:`Study.truths`): nothing is
        computed for them here (a sweep shares one truth among points).
    executor : budget.runner.executors.Executor, optional
        An executor already started by the caller (its workers set up with this study's
        ``worker_init``): the run uses it and leaves it running (a caller that runs many
        candidates starts one pool); ``workers``, ``scheduler`` and ``dask_local`` are then ignored.
    """
    import time

    from budget.runner.executors import make_executor

    _check_trials(trials, tolerance)
    if truth_size not in TRUTH_SIZES:
        raise ValueError(f"truth_size must be one of {TRUTH_SIZES}, got {truth_size!r}")
    t0 = time.perf_counter()
    if trials is None and tolerance is None:
        tolerance = study.default_tolerance(scenario)
        if tolerance is None:
            trials = study.default_trials(scenario)
    cap = min(study.max_trials(scenario), MAX_TRIALS)
    batch = study.batch_trials(scenario)
    classes = tuple(study.classes(scenario))
    # what the trials will hold in memory, refused before any work if it cannot fit: per
    # trial and key an estimate, maybe a truth and a stated sigma (8 bytes each, kept in
    # Python dicts until the end: about 100 bytes a value)
    from simcam.infra.lifecycle import check_memory

    n_values = sum(len(c.axes) for c in classes) * len(study.variants)
    n_max = trials if trials is not None else cap
    check_memory(float(n_max) * (300 + 3 * 100 * n_values),
                 what=f"--trials {n_max}" if trials is not None else f"up to {n_max} trials of {study.name}")
    import contextlib

    own = executor is None
    if own:
        # local processes: this one is a worker too (it runs trials between collecting the
        # others' results), so the first trials start at once and one process fewer imports
        executor = make_executor(workers=workers, scheduler=scheduler, dask_local=dask_local,
                                 initializer=_worker_init, initargs=(study,), work_here=True)
    results: dict[int, TrialResult] = {}
    stopped_by = "trials"
    bar = None
    given = truths is not None
    targets: dict = {}
    # the scenario the truths are computed on, once their size is known (None: after the pilot)
    truth_scn = None
    pilot = min(trials, PILOT_TRIALS) if trials is not None else 0
    parts: list = []
    part_results: dict[int, Any] = {}
    state = {"truths": truths, "started": given}

    def start_truths(tasks: list) -> None:
        """The truths, now that their scenario is known: in this process with one worker,
        otherwise as pieces appended to the task list (after the trials queued so far: many
        small tasks that even out the workers' ends)."""
        if executor.workers <= 1:
            state["truths"] = study.truths(truth_scn, seed)
        else:
            parts[:] = study.truth_parts(truth_scn, seed)
            tasks += [(study, truth_scn, seed, ("truth", i, p)) for i, p in enumerate(parts)]
        state["started"] = True

    # the workers start first: they import while this process does its serial work here
    with executor if own else contextlib.nullcontext(executor):
        if prewarm and scheduler is None:
            # a first run compiles its kernels on this machine's cores before the workers are
            # given a task, so that they load them from numba's cache instead of each
            # compiling them again (a remote cluster's workers have their own caches)
            study.prewarm(scenario)
        if not given:
            if truth_size == "fixed":
                truth_scn = scenario
            elif tolerance is not None:
                targets = truth_targets(classes, tolerance=tolerance)
                truth_scn = sized_truths_scenario(study, scenario, seed, targets)
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=trials if trials else cap, desc=f"{study.name} trials", unit="trial", leave=False)
        try:
            while True:
                done = len(results)
                want = (trials - done) if tolerance is None else min(batch, cap - done)
                if want <= 0:
                    break
                ks = list(range(done, done + want))
                # a fixed number of trials is queued whole: the pilot's chunks first, so that
                # the truths' size is known early and their pieces join the queue while the
                # other trials run (no wait between the pilot and the rest)
                pilot_ks = ks[:pilot] if (truth_scn is None and not state["started"]) else []
                tasks = [(study, scenario, seed, c) for c in (_chunks(pilot_ks, study.chunk_trials(scenario),
                                                                      executor.workers)
                                                              + _chunks(ks[len(pilot_ks):],
                                                                        study.chunk_trials(scenario),
                                                                        executor.workers))]
                if not state["started"] and truth_scn is not None:
                    start_truths(tasks)
                # the executor reads ``tasks`` as it goes: pieces appended below are run too
                for _, part in executor.map_unordered(_run_task, tasks):
                    if isinstance(part, _TruthPart):
                        part_results[part.index] = part.value
                        if len(part_results) == len(parts):
                            state["truths"] = study.truths_from_parts(
                                truth_scn, seed, [part_results[i] for i in range(len(parts))])
                        continue
                    for k, r in part:
                        results[k] = r
                    if bar is not None:
                        bar.update(len(part))
                    if pilot_ks and truth_scn is None and all(k in results for k in pilot_ks):
                        # the pilot is done: the truths' target from its spread (its own trials
                        # only, whichever others have finished too)
                        samples, tt, _ = _collect({k: results[k] for k in pilot_ks})
                        targets = truth_targets(classes, samples=samples, trial_truths=tt, trials=trials)
                        truth_scn = sized_truths_scenario(study, scenario, seed, targets)
                        start_truths(tasks)
                if tolerance is not None:
                    samples, tt, _ = _collect(results)
                    if converged(samples, tt, tolerance) and _truths_within(samples, tt, state["truths"],
                                                                            tolerance):
                        stopped_by = "tolerance"
                        break
                    if len(results) >= cap:
                        stopped_by = "max_trials"
                        break
        finally:
            if bar is not None:
                bar.close()
    truths = state["truths"]
    if targets:
        truths = with_targets(truths, targets)
    samples, trial_truths, sigmas = _collect(results)
    ks = sorted(results)
    aux = {name: np.array([results[k].aux[name] for k in ks], dtype=float) for name in results[ks[0]].aux}
    return StudyResult(study=study, scenario=scenario, seed=seed, trials=len(results), stopped_by=stopped_by,
                       classes=classes, truths=truths, samples=samples, trial_truths=trial_truths,
                       sigmas=sigmas, example=results.get(0), elapsed_s=time.perf_counter() - t0,
                       executor=executor.description, aux=aux,
                       truth_size="given" if given else truth_size)


def _chunks(ks: list, most: int, workers: int) -> list[list]:
    """``ks`` in consecutive chunks of at most ``most`` trials, at least two per worker and a
    multiple of the workers in number, their sizes within one of each other (so that each
    worker gets the same share). Which trials go together never changes a result (each
    trial draws its own streams); only how evenly the workers end."""
    if not ks:
        return []
    w = max(workers, 1)
    n = max(2 * w, w * math.ceil(len(ks) / (w * max(most, 1))))
    n = min(n, len(ks))
    size, extra = divmod(len(ks), n)
    out, i = [], 0
    for j in range(n):
        m = size + (1 if j < extra else 0)
        out.append(ks[i:i + m])
        i += m
    return out


def _truths_within(samples: dict, trial_truths: dict, truths: dict | None, tolerance: float) -> bool:
    """Adaptive stopping with the standard error the report gives: for a fixed truth ``T``
    with its Monte Carlo standard error ``s_T``, the bias's ``sqrt(s^2 / n + s_T^2)``
    (:func:`key_statistics`) must be below ``tolerance`` too, not only ``s / sqrt(n)``
    (:func:`converged`). A truth whose own ``s_T`` exceeds the tolerance never lets a run
    stop by tolerance: it runs to the cap (``stopped_by = "max_trials"``)."""
    if truths is None:
        return False
    for key, x in samples.items():
        if key in trial_truths:
            continue
        t = truths.get((key[0], key[2]))
        if t is None:
            continue
        n = len(x)
        s = float(np.std(np.asarray(x, dtype=float), ddof=1)) if n > 1 else float("inf")
        if math.sqrt(s**2 / n + float(t.se) ** 2) > tolerance:
            return False
    return True


def _collect(results: dict[int, TrialResult]):
    """Arrays per key, ordered by trial number (whatever order the trials finished in)."""
    ks = sorted(results)
    first = results[ks[0]]
    samples = {key: np.array([results[k].estimates[key] for k in ks], dtype=float) for key in first.estimates}
    tt = {key: np.array([results[k].truths[key] for k in ks], dtype=float) for key in first.truths}
    sg = {key: np.array([results[k].sigmas.get(key, np.nan) for k in ks], dtype=float) for key in first.sigmas}
    return samples, tt, sg
