"""The runner's scheduler: which trials and pieces of the truths run when, and when a run stops.

A :class:`Scheduler` runs one study on one scenario with one seed on an executor
(:mod:`budget.runner.executors`), and returns a :class:`ScheduledRun` (the trials' arrays in
trial order, the truths, why it stopped); :func:`budget.runner.run.run_study` builds it
and turns its outcome into a :class:`budget.runner.result.StudyResult`. Its state while it
runs is a :class:`RunState`; each step is a method.

* The workers are sent small frozen tasks (:class:`TrialChunk`, :class:`TruthPart`) that
  carry everything they need, run by the module-level :func:`run_task`; each trial ``k``
  is seeded by ``SeedSequence(seed, spawn_key=(k,))``, so no result depends on which worker
  ran it or when.
* Trials ``0, 1, 2, ...`` run in chunks (:func:`split_trials`: as many per worker, of at
  most the study's ``trials_per_task`` trials). A fixed number of trials is queued whole, in one
  batch; with a tolerance, batches of the scenario's ``validation.batch_trials`` run until every bias and
  spread standard error is below it (JCGM 101:2008, 7.9; the bias's with its truth's own
  standard error, :func:`truths_within`) or the cap is reached (``stopped_by`` says which).
  The check comes after each whole batch, so the trials run are always ``0 .. n - 1``.
* The truths (:meth:`Study.truths`, seeded by ``SeedSequence(seed, spawn_key=(2**31,))``)
  are computed in this process with one worker, otherwise piece by piece
  (:meth:`~budget.runner.capabilities.SplitTruths.truth_parts`) as tasks queued after the trials queued so far, so that the
  truths' work is spread over the workers too and their many small pieces even out the
  workers' ends. Their precision follows the question (``truth_size="adaptive"``): each
  sampled truth is sized (:meth:`~budget.runner.capabilities.SizedTruths.truth_size_for`) to a standard error of
  :data:`TRUTH_SE_FRACTION` (a quarter) of the bias standard error the run will give
  (:func:`truth_targets`): with a tolerance, of the tolerance; with a number of trials
  ``n``, of ``s / sqrt(n)`` with ``s`` the spread of the *pilot*, the first
  :data:`PILOT_TRIALS` trials (the run's own trials 0, 1, ..., queued first, so nothing is
  computed twice and the size does not depend on the workers; the other trials are queued
  behind the pilot's and run meanwhile, never waiting for it). A truth's standard error
  then adds at most ``sqrt(1 + 1/16) - 1 = 3 %`` to a bias's. ``truth_size="fixed"`` keeps
  the scenario's own sizes; truths given to the scheduler (computed before: a sweep's truth
  shared by points) are used as they are.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from budget.runner.capabilities import BatchedTrials, SizedTruths, SplitTruths, Warmup, capability
from budget.runner.combined_truths import combined_trial_truths
from budget.runner.stats import converged
from budget.runner.study import ClassSpec, Key, Study, TrialResult, Truth
from simcam.infra.lifecycle import raise_pending_interruption

__all__ = ["MAX_TRIALS", "init_worker", "PILOT_TRIALS", "TRUTH_SE_FRACTION", "TRUTH_SIZES", "RunState", "ScheduledRun",
           "Scheduler", "Stopping", "TrialArrays", "TrialChunk", "TrialChunkDone", "TruthPart", "TruthPartDone",
           "run_task", "sized_truths_scenario", "split_trials", "trial_arrays", "truth_targets", "truths_within",
           "with_targets"]

#: a sampled truth's target standard error, as a fraction of the bias standard error the
#: trials give (or of the tolerance): its share of the bias's variance is 1/16
TRUTH_SE_FRACTION = 0.25
#: trials whose spread sizes the truths of a run with a fixed number of trials
PILOT_TRIALS = 20
#: the ways truths are sized (:class:`Scheduler`'s ``truth_size``)
TRUTH_SIZES = ("adaptive", "fixed")
#: cap of adaptive runs whatever the study says (each trial's values are kept)
MAX_TRIALS = 10_000_000


def init_worker(study: Study) -> None:
    """What a worker runs for ``study`` once it starts, after the runner's own set-up
    (:func:`budget.runner.executors.worker_setup`): the study's
    :meth:`~budget.runner.capabilities.Warmup.worker_init`."""
    capability(study, Warmup).worker_init()


# ------------------------------------------------------------------ the workers' tasks
@dataclass(frozen=True)
class TrialChunkDone:
    """What a worker returns for a :class:`TrialChunk`: the results of its trials, in its order."""

    trials: tuple[int, ...]
    results: tuple[TrialResult, ...]


@dataclass(frozen=True)
class TruthPartDone:
    """What a worker returns for a :class:`TruthPart`: the piece's index and its value."""

    index: int
    value: Any


@dataclass(frozen=True)
class TrialChunk:
    """A worker's task: trials ``trials`` of ``study`` on ``scenario`` with the run's ``seed``."""

    study: Study
    scenario: Any
    seed: int
    trials: tuple[int, ...]

    def run(self) -> TrialChunkDone:
        """The trials (:meth:`~budget.runner.capabilities.BatchedTrials.trial_batch`); only trial 0 keeps its ``extra`` (the
        report's), so that little travels back."""
        results = tuple(capability(self.study, BatchedTrials).trial_batch(self.scenario, self.seed, list(self.trials)))
        for k, r in zip(self.trials, results):
            if k != 0:
                r.extra = {}
        return TrialChunkDone(self.trials, results)


@dataclass(frozen=True)
class TruthPart:
    """A worker's task: piece ``index`` of the truths of ``scenario`` (``part``, the
    :meth:`~budget.runner.capabilities.SplitTruths.truth_parts` entry), with the run's ``seed``."""

    study: Study
    scenario: Any
    seed: int
    index: int
    part: Any

    def run(self) -> TruthPartDone:
        """The piece (:meth:`~budget.runner.capabilities.SplitTruths.truth_part`)."""
        return TruthPartDone(self.index, capability(self.study, SplitTruths).truth_part(self.scenario, self.seed, self.part))


def run_task(task: TrialChunk | TruthPart) -> TrialChunkDone | TruthPartDone:
    """What a worker runs: ``task.run()`` (a module-level function, which executors send by name)."""
    return task.run()


# ------------------------------------------------------------------ chunks and arrays
def split_trials(ks: list[int], most: int, workers: int) -> list[tuple[int, ...]]:
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
        out.append(tuple(ks[i:i + m]))
        i += m
    return out


@dataclass(frozen=True)
class TrialArrays:
    """The trials' values as arrays in trial order (whatever order the trials finished in):
    estimates, per-trial truths and stated sigmas by ``(class, variant, axis)``, and the
    per-trial scalars of :attr:`TrialResult.aux` by name."""

    samples: dict[Key, np.ndarray]
    trial_truths: dict[Key, np.ndarray]
    sigmas: dict[Key, np.ndarray]
    aux: dict[str, np.ndarray]


def _estimates(results: dict[int, TrialResult]) -> tuple[dict[Key, np.ndarray], dict[Key, np.ndarray]]:
    """The estimates and per-trial truths of :func:`trial_arrays` (what the checks read)."""
    ks = sorted(results)
    first = results[ks[0]]
    samples = {key: np.array([results[k].estimates[key] for k in ks], dtype=float) for key in first.estimates}
    tt = {key: np.array([results[k].truths[key] for k in ks], dtype=float) for key in first.truths}
    return samples, tt


def trial_arrays(results: dict[int, TrialResult]) -> TrialArrays:
    """:class:`TrialArrays` of ``results`` (trial number -> result)."""
    ks = sorted(results)
    first = results[ks[0]]
    samples, tt = _estimates(results)
    sg = {key: np.array([results[k].sigmas.get(key, np.nan) for k in ks], dtype=float) for key in first.sigmas}
    aux = {name: np.array([results[k].aux[name] for k in ks], dtype=float) for name in first.aux}
    return TrialArrays(samples, tt, sg, aux)


# ------------------------------------------------------------------ truth sizing
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
    """The scenario the truths are computed on: :meth:`~budget.runner.capabilities.SizedTruths.truth_size_for` (no targets: as given)."""
    return capability(study, SizedTruths).truth_size_for(scenario, seed, targets) if targets else scenario


def with_targets(truths: dict, targets: dict) -> dict:
    """The sampled truths (``se > 0``) with their target standard error (``target_se``) among
    their details (the JSON shows it); an exact truth needs none and is left as it is."""
    return {k: (Truth(t.value, t.se, {**t.details, "target_se": float(targets[k])}) if k in targets and t.se > 0
                else t)
            for k, t in truths.items()}


def truths_within(samples: dict, trial_truths: dict, truths: dict | None, tolerance: float) -> bool:
    """Adaptive stopping with the standard error the report gives: for a fixed truth ``T``
    with its Monte Carlo standard error ``s_T``, the bias's ``sqrt(s^2 / n + s_T^2)``
    (:func:`budget.runner.stats.key_statistics`) must be below ``tolerance`` too, not only
    ``s / sqrt(n)`` (:func:`budget.runner.stats.converged`). A truth whose own ``s_T``
    exceeds the tolerance never lets a run stop by tolerance: it runs to the cap
    (``stopped_by = "max_trials"``). No truths yet: not within."""
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


# ------------------------------------------------------------------ the scheduler
@dataclass(frozen=True)
class Stopping:
    """How many trials a run has: ``trials`` (a fixed number), or batches of ``batch`` trials
    until every standard error is below ``tolerance`` or ``cap`` trials have run."""

    trials: int | None
    tolerance: float | None
    cap: int
    batch: int

    @classmethod
    def of(cls, study: Study, scenario: Any, trials: int | None, tolerance: float | None) -> Stopping:
        """The run's stopping: ``trials`` or ``tolerance`` as asked (at most one), else the
        scenario's tolerance, else its number of trials; the cap is the study's, at most
        :data:`MAX_TRIALS`."""
        if trials is None and tolerance is None:
            tolerance = scenario.validation.tolerance
            if tolerance is None:
                trials = scenario.validation.trials
        return cls(trials=trials, tolerance=tolerance, cap=min(scenario.validation.max_trials, MAX_TRIALS),
                   batch=scenario.validation.batch_trials)

    @property
    def most_trials(self) -> int:
        """The most trials the run can have (what its memory is checked for)."""
        return self.trials if self.trials is not None else self.cap

    @property
    def pilot_trials(self) -> int:
        """Trials of the pilot that sizes the truths of a fixed number of trials (0 with a tolerance)."""
        return min(self.trials, PILOT_TRIALS) if self.trials is not None else 0


@dataclass
class RunState:
    """What a :class:`Scheduler` knows while its run goes on."""

    #: the current batch's tasks, in the order given to the executor, which walks this list
    #: while it grows (the truths' pieces are appended to it)
    queue: list[TrialChunk | TruthPart] = field(default_factory=list)
    #: how many tasks of :attr:`queue` have come back
    tasks_done: int = 0
    #: the trials done, by trial number
    trials: dict[int, TrialResult] = field(default_factory=dict)
    #: the current batch's pilot (empty: none, or the truths' size already known)
    pilot: tuple[int, ...] = ()
    #: target standard error of each sampled truth ``(class, axis)`` (empty: none sized)
    targets: dict[tuple[str, str], float] = field(default_factory=dict)
    #: the scenario the truths are computed on (None until known: after the pilot)
    truth_scenario: Any = None
    #: whether the truths are started: computed, queued as pieces or given
    truths_started: bool = False
    #: the pieces (:meth:`~budget.runner.capabilities.SplitTruths.truth_parts`) queued, and the values of those done by index
    truth_parts: list = field(default_factory=list)
    truth_part_values: dict[int, Any] = field(default_factory=dict)
    #: the truths, once computed (or given)
    truths: dict[tuple[str, str], Truth] | None = None
    #: why the trials stopped: "trials", "tolerance" or "max_trials"
    stopped_by: str = "trials"

    @property
    def tasks_in_flight(self) -> int:
        """Tasks of :attr:`queue` given to the executor and not yet back."""
        return len(self.queue) - self.tasks_done


@dataclass(frozen=True)
class ScheduledRun:
    """A finished run: its trials' arrays in trial order, trial 0's result (the report's
    example), the truths (with their targets among their details) and why it stopped."""

    trials: int
    arrays: TrialArrays
    example: TrialResult | None
    truths: dict[tuple[str, str], Truth]
    stopped_by: str
    #: "adaptive", "fixed" or "given" (computed before the run)
    truth_size: str


class Scheduler:
    """Runs the trials and truths of ``study`` on ``scenario`` with ``seed`` until
    ``stopping`` says so (module docstring); ``classes`` are the study's on the scenario,
    ``truth_size`` one of :data:`TRUTH_SIZES`, ``truths`` the truths computed before (then
    none are computed). Built before the executor is started (bad settings are refused
    first), run once on it (:meth:`run`).
    """

    def __init__(self, study: Study, scenario: Any, seed: int, stopping: Stopping, *,
                 classes: tuple[ClassSpec, ...], truth_size: str = "adaptive", truths: dict | None = None):
        if truth_size not in TRUTH_SIZES:
            raise ValueError(f"truth_size must be one of {TRUTH_SIZES}, got {truth_size!r}")
        self.study, self.scenario, self.seed = study, scenario, seed
        self.stopping, self.classes, self.truth_size = stopping, classes, truth_size
        self.chunk = study.trials_per_task
        self.state = RunState(truths=truths, truths_started=truths is not None)
        self._given = truths is not None
        #: where the tasks run (:mod:`budget.runner.executors`), given to :meth:`run`
        self.executor = None

    def run(self, executor, on_trials: Callable[[int], None] | None = None) -> ScheduledRun:
        """Run to the end on ``executor`` (entered by the caller); ``on_trials(n)`` is told
        each time ``n`` more trials are done."""
        self.executor = executor
        self.plan_truths()
        while ks := self.next_batch():
            self.queue_batch(ks)
            self.drain(on_trials)
            if self.should_stop():
                break
        return self.outcome()

    def plan_truths(self) -> None:
        """The truths' scenario where it is known before any trial: the scenario's own sizes
        (``fixed``) or sized for the tolerance; otherwise the pilot sizes them."""
        s = self.state
        if s.truths_started:
            return
        if self.truth_size == "fixed":
            s.truth_scenario = self.scenario
        elif self.stopping.tolerance is not None:
            s.targets = truth_targets(self.classes, tolerance=self.stopping.tolerance)
            s.truth_scenario = sized_truths_scenario(self.study, self.scenario, self.seed, s.targets)

    def next_batch(self) -> list[int]:
        """The trials to run next: the rest of a fixed number, or the next batch up to the cap."""
        done = len(self.state.trials)
        st = self.stopping
        want = (st.trials - done) if st.tolerance is None else min(st.batch, st.cap - done)
        return list(range(done, done + want)) if want > 0 else []

    def queue_batch(self, ks: list[int]) -> None:
        """A new queue of the trials ``ks`` in chunks: the pilot's chunks first while the
        truths' size is unknown (so that their pieces join the queue while the other trials
        run); then the truths, if their scenario is known and they are not started."""
        s = self.state
        workers = self.executor.workers
        s.pilot = tuple(ks[:self.stopping.pilot_trials]) if not s.truths_started and s.truth_scenario is None else ()
        chunks = split_trials(list(s.pilot), self.chunk, workers) + split_trials(ks[len(s.pilot):], self.chunk,
                                                                                 workers)
        s.queue = [TrialChunk(self.study, self.scenario, self.seed, c) for c in chunks]
        s.tasks_done = 0
        if not s.truths_started and s.truth_scenario is not None:
            self.start_truths()

    def start_truths(self) -> None:
        """The truths, now that their scenario is known: in this process with one worker,
        otherwise as pieces appended to the queue (after the trials queued so far: many small
        tasks that even out the workers' ends)."""
        s = self.state
        if self.executor.workers <= 1:
            s.truths = self.study.truths(s.truth_scenario, self.seed)
        else:
            s.truth_parts = list(capability(self.study, SplitTruths).truth_parts(s.truth_scenario, self.seed))
            s.queue.extend(TruthPart(self.study, s.truth_scenario, self.seed, i, p)
                           for i, p in enumerate(s.truth_parts))
        s.truths_started = True

    def drain(self, on_trials: Callable[[int], None] | None = None) -> None:
        """Run the queue to its end (the tasks appended meanwhile too), taking each result as
        it comes back; a task's exception ends the run with it."""
        s = self.state
        for _, done in self.executor.map_unordered(run_task, s.queue):
            raise_pending_interruption()  # a stop signal swallowed where it landed ends the run here
            s.tasks_done += 1
            if isinstance(done, TruthPartDone):
                self.truth_part_done(done)
            else:
                self.trials_done(done, on_trials)

    def trials_done(self, done: TrialChunkDone, on_trials: Callable[[int], None] | None = None) -> None:
        """Keep a chunk's trials; once the pilot's are all in, size and start the truths."""
        s = self.state
        pairs = list(zip(done.trials, done.results))
        for k, r in pairs:
            s.trials[k] = r
        if on_trials is not None:
            on_trials(len(pairs))
        if s.pilot and s.truth_scenario is None and all(k in s.trials for k in s.pilot):
            self.size_truths_from_pilot()

    def size_truths_from_pilot(self) -> None:
        """The truths' targets from the pilot's spread (its own trials only, whichever others
        have finished too), their scenario sized for them, and the truths started."""
        s = self.state
        samples, tt = _estimates({k: s.trials[k] for k in s.pilot})
        s.targets = truth_targets(self.classes, samples=samples, trial_truths=tt, trials=self.stopping.trials)
        s.truth_scenario = sized_truths_scenario(self.study, self.scenario, self.seed, s.targets)
        self.start_truths()

    def truth_part_done(self, done: TruthPartDone) -> None:
        """Keep a piece of the truths; with the last, the truths from their pieces in order."""
        s = self.state
        s.truth_part_values[done.index] = done.value
        if len(s.truth_part_values) == len(s.truth_parts):
            s.truths = capability(self.study, SplitTruths).truths_from_parts(s.truth_scenario, self.seed,
                                                    [s.truth_part_values[i] for i in range(len(s.truth_parts))])

    def should_stop(self) -> bool:
        """After a whole batch, with a tolerance: stop once every standard error (the truths'
        own included) is below it, or at the cap; ``stopped_by`` says which."""
        s, st = self.state, self.stopping
        if st.tolerance is None:
            return False
        samples, tt = _estimates(s.trials)
        # a combined per-trial truth exists once the fixed truths do (before, truths_within is False)
        tt, _ = combined_trial_truths(self.classes, s.truths, samples, tt)
        if converged(samples, tt, st.tolerance) and truths_within(samples, tt, s.truths, st.tolerance):
            s.stopped_by = "tolerance"
            return True
        if len(s.trials) >= st.cap:
            s.stopped_by = "max_trials"
            return True
        return False

    def outcome(self) -> ScheduledRun:
        """The finished run (the truths with their targets, :func:`with_targets`)."""
        s = self.state
        truths = with_targets(s.truths, s.targets) if s.targets else s.truths
        return ScheduledRun(trials=len(s.trials), arrays=trial_arrays(s.trials), example=s.trials.get(0),
                            truths=truths, stopped_by=s.stopped_by,
                            truth_size="given" if self._given else self.truth_size)
