"""The one Monte Carlo runner: any study, seeded trials, workers, adaptive stopping, statistics.

``run_study(study, scenario, ...)`` checks the request, starts the executor (its worker
processes import while this process works), lets the study compile its kernels
(:meth:`~budget.runner.capabilities.Warmup.prewarm`), and runs a :class:`budget.runner.scheduler.Scheduler`: the trials
``0, 1, 2, ...`` in chunks, each seeded by ``SeedSequence(seed, spawn_key=(k,))``, a fixed
number of them or batches until a tolerance (JCGM 101:2008, 7.9) or the study's cap, and
the study's truths sized to the run's precision (a pilot of the first
:data:`~budget.runner.scheduler.PILOT_TRIALS` trials, or the tolerance) and spread over the
workers in pieces; the scheduler's module docstring says how. Results do not depend on the
executor or the number of workers.

The result, :class:`budget.runner.result.StudyResult`, gives the statistics of each
``(class, variant, axis)``, the JSON payload (:meth:`StudyResult.to_json`, schema
``budget.study-result/1``) and the report (:func:`budget.runner.report.write_report`).

The truths' sizing (:func:`~budget.runner.scheduler.truth_targets`,
:func:`~budget.runner.scheduler.sized_truths_scenario`, :func:`~budget.runner.scheduler.with_targets`,
:data:`~budget.runner.scheduler.TRUTH_SE_FRACTION`) lives with the scheduler; import it from there.
"""

from __future__ import annotations

import contextlib
import math
import time
from typing import Any

from tqdm import tqdm

from budget.runner.capabilities import Warmup, capability
from budget.runner.executors import make_executor
from budget.runner.result import SCHEMA, StudyResult
from budget.runner.scheduler import Scheduler, Stopping, init_worker
from budget.runner.study import Study
from simcam.infra.errors import UserInputError
from simcam.allocation import check_allocations
from simcam.infra.lifecycle import check_memory

__all__ = ["SCHEMA", "StudyResult", "run_study"]


def _check_trials(trials: int | None, tolerance: float | None) -> None:
    if trials is not None and tolerance is not None:
        raise UserInputError("--trials and --tolerance: give one of them")
    if trials is not None and trials < 2:
        raise UserInputError(f"--trials: must be at least 2 (got {trials})")
    if tolerance is not None and not (math.isfinite(tolerance) and tolerance > 0):
        raise UserInputError(f"--tolerance: must be a positive number (got {tolerance})")


def _check_memory(study: Study, classes, stopping: Stopping) -> None:
    """What the trials will hold in memory, refused before any work if it cannot fit: per
    trial and key an estimate, maybe a truth and a stated sigma (8 bytes each, kept in
    Python dicts until the end: about 100 bytes a value)."""
    n_values = sum(len(c.axes) for c in classes) * len(study.variants)
    n_max = stopping.most_trials
    check_memory(float(n_max) * (300 + 3 * 100 * n_values),
                 what=f"--trials {n_max}" if stopping.trials is not None else f"up to {n_max} trials of {study.name}")


@contextlib.contextmanager
def _progress(show: bool, study: Study, stopping: Stopping):
    """A progress bar on stderr while the trials run (``show``), as the scheduler's
    ``on_trials``; None without one."""
    if not show:
        yield None
        return
    bar = tqdm(total=stopping.most_trials, desc=f"{study.name} trials", unit="trial", leave=False)
    try:
        yield bar.update
    finally:
        bar.close()


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
        cache (:meth:`~budget.runner.capabilities.Warmup.prewarm`; never with ``scheduler``). A caller that runs many
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
    _check_trials(trials, tolerance)
    t0 = time.perf_counter()
    stopping = Stopping.of(study, scenario, trials, tolerance)
    classes = tuple(study.classes(scenario))
    plan = Scheduler(study, scenario, seed, stopping, classes=classes, truth_size=truth_size, truths=truths)
    _check_memory(study, classes, stopping)
    check_allocations(scenario, source=getattr(scenario, "source", "scenario"))  # its largest arrays (simcam.allocation)
    own = executor is None
    if own:
        # local processes: this one is a worker too (it runs trials between collecting the
        # others' results), so the first trials start at once and one process fewer imports
        executor = make_executor(workers=workers, scheduler=scheduler, dask_local=dask_local,
                                 initializer=init_worker, initargs=(study,), work_here=True)
    # the workers start first: they import while this process does its serial work here
    with executor if own else contextlib.nullcontext(executor):
        if prewarm and scheduler is None:
            # a first run compiles its kernels on this machine's cores before the workers are
            # given a task, so that they load them from numba's cache instead of each
            # compiling them again (a remote cluster's workers have their own caches)
            capability(study, Warmup).prewarm(scenario)
        with _progress(progress, study, stopping) as on_trials:
            done = plan.run(executor, on_trials)
    a = done.arrays
    return StudyResult(study=study, scenario=scenario, seed=seed, trials=done.trials, stopped_by=done.stopped_by,
                       classes=classes, truths=done.truths, samples=a.samples, trial_truths=a.trial_truths,
                       sigmas=a.sigmas, example=done.example, elapsed_s=time.perf_counter() - t0,
                       executor=executor.description, aux=a.aux, truth_size=done.truth_size)
