"""The runner's scheduler (budget.runner.scheduler) on its own: a fake executor runs the tasks
in this process in an order the test chooses (no processes), and records what it was given.

What is pinned: the pilot's trials are queued first; the truths' pieces join the queue once,
when the pilot has sized them; the trials come back in trial order whatever order they
finished in; adaptive stopping stops at the first whole batch whose standard errors meet the
tolerance (or at the cap); an exception in a task ends the run with it."""

from __future__ import annotations

import random

import numpy as np
import pytest
from parted_toy_study import N_PARTS
from parted_toy_study import STUDY as PARTED
from toy_study import STUDY, Toy, ToyStudy

from budget.runner.scheduler import (PILOT_TRIALS, Scheduler, Stopping, TrialChunk, TruthPart, run_task,
                                     truth_targets)
from budget.runner.stats import key_statistics
from budget.runner.study import TrialResult


class FakeExecutor:
    """Runs tasks in this process, one at a time, in ``order`` among those queued so far:
    ``forward`` (as queued), ``reverse`` (the last queued first) or ``shuffled`` (seeded).
    ``workers`` is what the scheduler is told. Records, for each task it runs, the task and
    how many tasks were queued then (:attr:`seen`)."""

    description = "fake"

    def __init__(self, workers: int = 2, order: str = "forward", seed: int = 0):
        self.workers, self.order = workers, order
        self._rng = random.Random(seed)
        self.seen: list[tuple[object, int]] = []

    def map_unordered(self, fn, tasks):
        pending: list[int] = []
        given = 0
        while given < len(tasks) or pending:
            pending += range(given, len(tasks))  # those the caller appended meanwhile too
            given = len(tasks)
            if self.order == "forward":
                i = pending.pop(0)
            elif self.order == "reverse":
                i = pending.pop()
            else:
                i = pending.pop(self._rng.randrange(len(pending)))
            self.seen.append((tasks[i], len(tasks)))
            yield i, fn(tasks[i])


def _scheduler(study, scn, *, trials=None, tolerance=None, seed=4, truth_size="adaptive", truths=None):
    stopping = Stopping.of(study, scn, trials, tolerance)
    return Scheduler(study, scn, seed, stopping, classes=tuple(study.classes(scn)), truth_size=truth_size,
                     truths=truths)


def test_the_pilot_goes_first_and_the_truths_pieces_join_once_it_has_sized_them():
    trials = 45
    sched = _scheduler(PARTED, Toy(), trials=trials)
    ex = FakeExecutor(workers=2)
    done = sched.run(ex)
    tasks = [t for t, _ in ex.seen]
    chunks = [t for t in tasks if isinstance(t, TrialChunk)]
    pieces = [t for t in tasks if isinstance(t, TruthPart)]
    # the pilot's chunks first, exactly trials 0 .. PILOT_TRIALS - 1, then the others
    firsts = [k for c in chunks for k in c.trials]
    assert firsts == list(range(trials))
    n_pilot = next(i for i, c in enumerate(chunks) if c.trials[0] >= PILOT_TRIALS)
    assert [k for c in chunks[:n_pilot] for k in c.trials] == list(range(PILOT_TRIALS))
    # the pieces: queued once (all of them, in order), when the pilot's last chunk came back
    assert [p.index for p in pieces] == list(range(N_PARTS))
    queued = [n for _, n in ex.seen]
    n_trial_chunks = len(chunks)
    assert queued[:n_pilot] == [n_trial_chunks] * n_pilot  # no piece while the pilot runs
    assert queued[n_pilot] == n_trial_chunks + N_PARTS
    assert set(queued[n_pilot:]) == {n_trial_chunks + N_PARTS}
    # their scenario is the one the pilot's spread sized
    arrays = {k: sched.state.trials[k] for k in range(PILOT_TRIALS)}
    samples = {key: np.array([arrays[k].estimates[key] for k in range(PILOT_TRIALS)]) for key in arrays[0].estimates}
    tt = {key: np.array([arrays[k].truths[key] for k in range(PILOT_TRIALS)]) for key in arrays[0].truths}
    targets = truth_targets(PARTED.classes(Toy()), samples=samples, trial_truths=tt, trials=trials)
    assert sched.state.targets == targets and targets
    sized = PARTED.truth_size_for(Toy(), 4, targets)
    assert all(p.scenario.truth_se == sized.truth_se for p in pieces)
    assert done.truths[("variance", "a")].value == PARTED.truths(sized, 4)[("variance", "a")].value
    assert done.truths[("variance", "a")].details["target_se"] == targets[("variance", "a")]
    assert done.truth_size == "adaptive" and done.stopped_by == "trials" and done.trials == trials
    assert sched.state.tasks_in_flight == 0


def test_one_worker_computes_the_truths_here_once_the_pilot_is_done():
    ex = FakeExecutor(workers=1)
    done = _scheduler(PARTED, Toy(), trials=30).run(ex)
    assert not any(isinstance(t, TruthPart) for t, _ in ex.seen)
    two = _scheduler(PARTED, Toy(), trials=30).run(FakeExecutor(workers=2))
    assert done.truths == two.truths


def test_fixed_or_given_truths_need_no_pilot():
    ex = FakeExecutor(workers=2)
    fixed = _scheduler(PARTED, Toy(truth_se=0.01), trials=30, truth_size="fixed").run(ex)
    # pieces queued with the first trials, on the scenario's own sizes
    assert ex.seen[0][1] == len([t for t, _ in ex.seen if isinstance(t, TrialChunk)]) + N_PARTS
    assert fixed.truths == PARTED.truths(Toy(truth_se=0.01), 4) and fixed.truth_size == "fixed"
    given = PARTED.truths(Toy(), 9)
    ex = FakeExecutor(workers=2)
    got = _scheduler(PARTED, Toy(), trials=30, truths=given).run(ex)
    assert got.truths is given and got.truth_size == "given"
    assert not any(isinstance(t, TruthPart) for t, _ in ex.seen)


@pytest.mark.parametrize("order", ["reverse", "shuffled"])
def test_results_come_out_in_trial_order_whatever_the_completion_order(order):
    class AuxToy(ToyStudy):
        def trial(self, scenario, seed, k):
            r = super().trial(scenario, seed, k)
            r.aux = {"trial_number": float(k)}
            r.extra = {"k": k}
            return r

    ref = _scheduler(AuxToy(), Toy(), trials=57).run(FakeExecutor(workers=3))
    got = _scheduler(AuxToy(), Toy(), trials=57).run(FakeExecutor(workers=3, order=order, seed=7))
    assert got.arrays.aux["trial_number"].tolist() == list(range(57))
    for field in ("samples", "trial_truths", "sigmas"):
        a, b = getattr(ref.arrays, field), getattr(got.arrays, field)
        assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    # the samples are those of the trials themselves, in trial order
    key = ("variance", "improved", "a")
    assert np.array_equal(got.arrays.samples[key],
                          [AuxToy().trial(Toy(), 4, k).estimates[key] for k in range(57)])
    assert got.truths == ref.truths
    assert got.example.extra == {"k": 0}  # trial 0 keeps its extra for the report


def _first_meeting(study, scn, seed, tol, batch, cap):
    """The trials a run with tolerance ``tol`` must have: the first whole batch at which every
    key's se_bias and se_std (the report's, the truth's own standard error included) are at
    most ``tol``, or the cap; worked out here from the trials themselves."""
    truths = study.truths(scn, seed)
    results: list[TrialResult] = []
    while len(results) < cap:
        results += [study.trial(scn, seed, k) for k in range(len(results), min(cap, len(results) + batch))]
        ok = True
        for key in results[0].estimates:
            x = np.array([r.estimates[key] for r in results])
            if key in results[0].truths:
                st = key_statistics(x, trial_truths=np.array([r.truths[key] for r in results]))
            else:
                t = truths[(key[0], key[2])]
                st = key_statistics(x, truth=t.value, truth_se=t.se)
            ok = ok and st["se_bias"] <= tol and st["se_std"] <= tol
        if ok:
            return len(results), "tolerance"
    return len(results), "max_trials"


@pytest.mark.parametrize("scn, tol", [(Toy(truth_se=0.05), 0.1), (Toy(m=4, sigma=1.0), 0.08),
                                      (Toy(truth_se=0.15, max_trials=700), 0.1)],
                         ids=["truth-se", "plain", "to-the-cap"])
@pytest.mark.parametrize("order", ["forward", "shuffled"])
def test_adaptive_stopping_stops_at_the_first_batch_meeting_the_tolerance(scn, tol, order):
    sched = _scheduler(STUDY, scn, tolerance=tol, seed=2)
    done = sched.run(FakeExecutor(workers=2, order=order, seed=3))
    want = _first_meeting(STUDY, scn, 2, tol, scn.validation.batch_trials, scn.validation.max_trials)
    assert (done.trials, done.stopped_by) == want
    assert sorted(sched.state.trials) == list(range(done.trials))


def test_stopping_defaults_to_the_scenarios_tolerance_then_its_trials():
    with_tolerance = Toy(trials=33).model_copy(update={"validation": Toy().validation.model_copy(update={"tolerance": 0.3})})

    assert Stopping.of(STUDY, Toy(trials=33), None, None) == Stopping(33, None, 20000, 100)
    assert Stopping.of(STUDY, with_tolerance, None, None) == Stopping(None, 0.3, 20000, 100)
    assert Stopping.of(STUDY, with_tolerance, 12, None).trials == 12
    assert Stopping(33, None, 20000, 100).pilot_trials == PILOT_TRIALS
    assert Stopping(5, None, 20000, 100).pilot_trials == 5
    assert Stopping(None, 0.3, 20000, 100).pilot_trials == 0
    with pytest.raises(ValueError, match="truth_size must be one of"):
        _scheduler(STUDY, Toy(), trials=5, truth_size="sized")


class _Failing(PARTED.__class__):
    """The parted toy failing at trial ``bad_trial`` or in truth piece ``bad_part``."""

    def __init__(self, bad_trial=None, bad_part=None):
        self.bad_trial, self.bad_part = bad_trial, bad_part

    def trial(self, scenario, seed, k):
        if k == self.bad_trial:
            raise ZeroDivisionError(f"trial {k} failed")
        return super().trial(scenario, seed, k)

    def truth_part(self, scenario, seed, part):
        if part == self.bad_part:
            raise FloatingPointError(f"piece {part} failed")
        return super().truth_part(scenario, seed, part)


@pytest.mark.parametrize("order", ["forward", "reverse"])
def test_a_failing_task_ends_the_run_with_its_exception(order):
    with pytest.raises(ZeroDivisionError, match="trial 31 failed"):
        _scheduler(_Failing(bad_trial=31), Toy(), trials=40).run(FakeExecutor(workers=2, order=order))
    with pytest.raises(FloatingPointError, match="piece 3 failed"):
        _scheduler(_Failing(bad_part=3), Toy(), trials=40).run(FakeExecutor(workers=2, order=order))


def test_a_task_is_a_small_frozen_record_its_worker_runs():
    task = TrialChunk(STUDY, Toy(), 5, (0, 1, 2))
    with pytest.raises(AttributeError):
        task.trials = (3,)
    done = run_task(task)
    assert done.trials == (0, 1, 2)
    assert [r.estimates for r in done.results] == [STUDY.trial(Toy(), 5, k).estimates for k in range(3)]
    piece = run_task(TruthPart(PARTED, Toy(), 5, 2, 2))
    assert piece.index == 2 and np.array_equal(piece.value, PARTED.truth_part(Toy(), 5, 2))
