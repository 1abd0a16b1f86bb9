"""How the runner queues its work (budget.runner.scheduler, budget.runner.executors): the trials
in even chunks, the pilot's first, the truths' pieces queued after the trials once the
pilot has sized them; results bit for bit the same whatever the number of workers."""

from __future__ import annotations

import json

import numpy as np
import pytest
from parted_toy_study import N_PARTS
from parted_toy_study import STUDY as PARTED
from toy_study import Toy

from budget.runner.executors import InlineExecutor, ProcessExecutor
from budget.runner.run import run_study
from budget.runner.scheduler import PILOT_TRIALS, split_trials


@pytest.mark.parametrize("n, most, workers", [(20, 10, 2), (180, 10, 2), (50, 10, 2), (2, 10, 2), (7, 3, 1),
                                              (1, 10, 4), (101, 7, 3)])
def test_chunks_cover_every_trial_once_evenly(n, most, workers):
    ks = list(range(5, 5 + n))
    chunks = split_trials(ks, most, workers)
    assert [k for c in chunks for k in c] == ks  # every trial once, in order
    sizes = [len(c) for c in chunks]
    assert max(sizes) - min(sizes) <= 1 and min(sizes) >= 1
    if n >= 2 * workers:
        assert len(chunks) % workers == 0 and len(chunks) >= 2 * workers
    assert max(sizes) <= max(most, -(-n // (2 * workers)))  # at most ``most`` unless fewer than 2 per worker
    assert split_trials([], most, workers) == []


@pytest.mark.parametrize("make", [InlineExecutor, lambda: ProcessExecutor(2),
                                  lambda: ProcessExecutor(2, work_here=True)],
                         ids=["inline", "processes", "processes-working-here"])
def test_tasks_appended_while_mapping_are_run(make):
    tasks = [1, -2, 3]
    got = {}
    with make() as ex:
        for i, r in ex.map_unordered(abs, tasks):
            got[i] = r
            if i == 0:
                tasks += [-4, 5]  # as the runner appends the truths' pieces
    assert got == {0: 1, 1: 2, 2: 3, 3: 4, 4: 5}


def _pid_after(seconds: float) -> int:
    import os
    import time

    time.sleep(seconds)
    return os.getpid()


def test_working_here_this_process_takes_the_first_task_and_starts_one_worker_fewer():
    """``work_here``: of 2 workers this process is one (it runs the first task, the pool
    started one process, which runs others); every task runs once."""
    import multiprocessing
    import os

    tasks = [0.2] * 8
    with ProcessExecutor(2, work_here=True) as ex:
        got = dict(ex.map_unordered(_pid_after, tasks))
        assert len(multiprocessing.active_children()) == 1
    assert sorted(got) == list(range(8))
    assert got[0] == os.getpid()
    assert len(set(got.values())) == 2


@pytest.mark.parametrize("trials", [2, PILOT_TRIALS, 45])
def test_pieced_truths_sized_by_the_pilot_do_not_depend_on_workers(trials):
    one = run_study(PARTED, Toy(), trials=trials, seed=4, workers=1)
    two = run_study(PARTED, Toy(), trials=trials, seed=4, workers=2)
    assert one.trials == two.trials == trials
    assert one.truths == two.truths
    # and they are the truths of the scenario the pilot sized, computed in one go
    target = one.truths[("variance", "a")].details["target_se"]
    assert one.truths[("variance", "a")].value == PARTED.truths(
        PARTED.truth_size_for(Toy(), 4, {("variance", "a"): target}), 4)[("variance", "a")].value
    for key in one.samples:
        assert np.array_equal(one.samples[key], two.samples[key])
    # the same statistics (compared as JSON text: a NaN is equal to itself there)
    assert json.dumps(one.to_json()["classes"], sort_keys=True) == json.dumps(two.to_json()["classes"],
                                                                               sort_keys=True)


def test_pieced_truths_fixed_and_tolerance_do_not_depend_on_workers():
    for kw in ({"trials": 30, "truth_size": "fixed"}, {"tolerance": 0.5}):
        one = run_study(PARTED, Toy(truth_se=0.01), seed=6, workers=1, **kw)
        two = run_study(PARTED, Toy(truth_se=0.01), seed=6, workers=2, **kw)
        assert one.trials == two.trials and one.stopped_by == two.stopped_by
        assert one.truths == two.truths
        for key in one.samples:
            assert np.array_equal(one.samples[key], two.samples[key])
    assert N_PARTS > 2  # several pieces: they are spread over the workers


def test_pieced_truths_on_dask_match_one_worker():
    # a Dask LocalCluster of two processes: the truths' pieces are submitted when the
    # pilot is done, beside the trials already running
    pytest.importorskip("distributed")
    one = run_study(PARTED, Toy(), trials=PILOT_TRIALS + 10, seed=8, workers=1)
    dask = run_study(PARTED, Toy(), trials=PILOT_TRIALS + 10, seed=8, workers=None, dask_local=2)
    assert "Dask" in dask.executor
    assert one.truths == dask.truths
    for key in one.samples:
        assert np.array_equal(one.samples[key], dask.samples[key])
