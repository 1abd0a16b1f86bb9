"""Where sweep points run: the runner's executors (:mod:`budget.runner.executors`).

Each point is a :class:`budget.sweeps.evaluate.PointTask` evaluated by
:func:`budget.sweeps.evaluate.evaluate_point`; points are independent (each carries its
scenario and seed), so the results do not depend on the executor, the number of workers
or the order in which they finish. The executors are the same as the Monte Carlo
runner's (this process; local processes, forked or spawned
(:func:`budget.runner.executors.start_method`), guarded against outliving their parent
and stopped on an interruption; a Dask scheduler or LocalCluster), each worker set up by
the runner (:func:`budget.runner.executors.worker_setup`: one numba thread per worker, the
workers are the parallelism) and then by the sweep's study (:meth:`~budget.runner.capabilities.Warmup.worker_init`).
Remote Dask workers need this package installed (same version: checked on every result).
"""

from __future__ import annotations

from collections.abc import Iterator

from budget.runner.capabilities import Warmup, capability
from budget.runner.executors import InlineExecutor, make_executor, worker_setup
from budget.sweeps.evaluate import TruthPartTask, evaluate_point, evaluate_truth_part
from budget.sweeps.layout import study_for_kind

__all__ = ["SweepRunner", "make_runner"]


def _init_for_kind(kind: str) -> None:
    capability(study_for_kind(kind), Warmup).worker_init()


def _evaluate(task):
    if isinstance(task, TruthPartTask):  # a piece of a truth shared by points
        return evaluate_truth_part(task)
    return evaluate_point(task)


class SweepRunner:
    """Runs sweep points on an executor; a context manager that owns its workers."""

    def __init__(self, executor):
        self.executor = executor

    @property
    def description(self) -> str:
        return self.executor.description

    @property
    def workers(self) -> int:
        return self.executor.workers

    def __enter__(self):
        self.executor.__enter__()
        return self

    def __exit__(self, *exc) -> None:
        self.executor.__exit__(*exc)

    def run(self, tasks: list) -> Iterator:
        """Yield a :class:`PointResult` per task (a :class:`TruthPartTask` with its result for
        a piece of a shared truth), in the order they finish."""
        for _, res in self.executor.map_unordered(_evaluate, tasks):
            yield res


def make_runner(*, kind: str, workers: int | None = None, scheduler: str | None = None,
                dask_local: int | None = None, inline: bool = False) -> SweepRunner:
    """The runner asked for (at most one option; default all local cores), set up for ``kind``."""
    if inline:
        worker_setup(_init_for_kind, (kind,))
        return SweepRunner(InlineExecutor())
    return SweepRunner(make_executor(workers=workers, scheduler=scheduler, dask_local=dask_local,
                                     initializer=_init_for_kind, initargs=(kind,)))
