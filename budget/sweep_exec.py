"""Where sweep points run: this process, local processes, or a Dask distributed cluster.

Each runner takes a list of :class:`budget.sweep_eval.PointTask` and yields
:class:`budget.sweep_eval.PointResult` in the order they finish. Points are independent
(each carries its scenario and seed), so the results do not depend on the runner, the
number of workers or the order.

* :class:`InlineRunner`: one after the other in this process (tests, debugging);
* :class:`ProcessRunner`: a pool of local processes, started with ``spawn`` (numba's
  thread pools must not be forked), each initialised like the validation's own workers
  (:func:`budget.validate.worker_init`: one numba thread per process: the processes
  are the parallelism);
* :class:`DaskRunner`: an existing Dask distributed scheduler (``tcp://host:port``) or a
  :class:`distributed.LocalCluster` of ``n`` single-threaded worker processes; each task
  sets one numba thread in its worker thread (:func:`budget.sweep_eval.evaluate_in_worker`).
  Remote workers need this package installed (same version: checked on every result).
"""

from __future__ import annotations

import multiprocessing
import uuid
from abc import ABC, abstractmethod
from collections.abc import Iterator
from typing import Self

from simcam.cli_common import UserInputError

__all__ = ["DaskRunner", "InlineRunner", "ProcessRunner", "Runner", "make_runner"]


class Runner(ABC):
    """Runs point tasks; a context manager that owns its workers."""

    #: what it is, for messages
    description: str = ""
    #: worker count (0: unknown until connected)
    workers: int = 1

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release the workers."""

    @abstractmethod
    def run(self, tasks: list) -> Iterator:
        """Yield a :class:`PointResult` per task, in the order they finish."""


class InlineRunner(Runner):
    """Points one after the other in this process."""

    description = "this process"

    def run(self, tasks):
        from budget.sweep_eval import evaluate_point

        for t in tasks:
            yield evaluate_point(t)


class ProcessRunner(Runner):
    """A pool of ``workers`` local processes (spawn, one numba thread each)."""

    def __init__(self, workers: int):
        if workers < 1:
            raise UserInputError(f"--workers: must be >= 1 (got {workers})")
        self.workers = workers
        self.description = f"{workers} local process{'es' if workers > 1 else ''}"
        self._pool = None

    def __enter__(self):
        from concurrent.futures import ProcessPoolExecutor

        from simcam.lifecycle import worker_initializer

        # guarded before the heavy imports: a killed parent leaves no worker (simcam.lifecycle)
        self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=multiprocessing.get_context("spawn"),
                                         initializer=worker_initializer("budget.validate:worker_init"))
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc is not None and not isinstance(exc, Exception) and self._pool is not None:
            # interrupted (SIGINT/SIGTERM): end the workers now rather than finish their points
            from simcam.lifecycle import stop_pool

            stop_pool(self._pool)
            self._pool = None
        self.close()

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def run(self, tasks):
        from concurrent.futures import FIRST_COMPLETED, wait

        from budget.sweep_eval import evaluate_point

        if self._pool is None:
            self.__enter__()
        # a bounded number in flight: an interruption leaves little queued work behind
        todo = list(reversed(tasks))
        running = set()
        try:
            while todo or running:
                while todo and len(running) < 2 * self.workers:
                    running.add(self._pool.submit(evaluate_point, todo.pop()))
                finished, running = wait(running, return_when=FIRST_COMPLETED)
                for f in finished:
                    yield f.result()
        finally:
            for f in running:
                f.cancel()


class DaskRunner(Runner):
    """Points as tasks on a Dask distributed cluster (existing, or a LocalCluster)."""

    def __init__(self, *, scheduler: str | None = None, local_workers: int | None = None):
        if (scheduler is None) == (local_workers is None):
            raise ValueError("DaskRunner: give scheduler or local_workers")
        if local_workers is not None and local_workers < 1:
            raise UserInputError(f"--dask-local: must be >= 1 (got {local_workers})")
        self.scheduler = scheduler
        self.local_workers = local_workers
        self.client = None
        self.cluster = None
        self.workers = local_workers or 0
        self.description = (f"Dask LocalCluster of {local_workers} worker process(es)" if local_workers
                            else f"Dask scheduler {scheduler}")

    def __enter__(self):
        from distributed import Client, LocalCluster

        if self.local_workers is not None:
            self.cluster = LocalCluster(n_workers=self.local_workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            try:
                self.client = Client(self.scheduler, timeout="20s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise UserInputError(f"--scheduler {self.scheduler}: cannot connect: {exc}") from None
            self.workers = sum(self.client.nthreads().values())
            if self.workers == 0:
                self.client.close()
                raise UserInputError(f"--scheduler {self.scheduler}: the cluster has no workers")
        return self

    def close(self):
        if self.client is not None:
            self.client.close()
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def run(self, tasks):
        from distributed import as_completed

        from budget.sweep_eval import evaluate_in_worker

        if self.client is None:
            self.__enter__()
        tag = uuid.uuid4().hex[:8]
        futures = [self.client.submit(evaluate_in_worker, t, key=f"sweep-{t.group}-{t.index}-{tag}", pure=False)
                   for t in tasks]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        finally:
            self.client.cancel([f for f in futures if not f.done()])


def make_runner(*, workers: int | None = None, scheduler: str | None = None,
                dask_local: int | None = None, inline: bool = False) -> Runner:
    """The runner asked for (at most one of the options; default: all local cores)."""
    given = [n for n, v in (("--workers", workers), ("--scheduler", scheduler), ("--dask-local", dask_local))
             if v is not None]
    if len(given) > 1:
        raise UserInputError(f"{' and '.join(given)}: give one of them")
    if inline:
        return InlineRunner()
    if scheduler is not None:
        if not scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")):
            raise UserInputError(f"--scheduler {scheduler}: expected an address like tcp://HOST:PORT")
        return DaskRunner(scheduler=scheduler)
    if dask_local is not None:
        return DaskRunner(local_workers=dask_local)
    from budget.runner.executors import default_workers

    return ProcessRunner(workers if workers is not None else default_workers())
