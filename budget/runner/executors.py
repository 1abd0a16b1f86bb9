"""Where independent tasks run: this process, local processes, or a Dask distributed cluster.

An executor maps a picklable module-level function over a list of tasks and yields
``(index, result)`` in the order tasks finish. Tasks carry everything they need (scenario,
seed, trial numbers), so results do not depend on the executor, the number of workers or
the order of completion.

* :class:`InlineExecutor`: one after the other in this process;
* :class:`ProcessExecutor`: a pool of local processes, and this process among them where
  the caller asks (``work_here``). The pool is started on entering the context, so its
  workers import while this process works; it forks where that is safe (Linux, no thread
  started here yet, numba's thread pool not launched: :func:`start_method`), so a worker
  starts with this process's imports instead of importing them again, and spawns otherwise;
* :class:`DaskExecutor`: an existing scheduler (``tcp://host:port``) or a
  :class:`distributed.LocalCluster` of single-threaded worker processes.

The runner owns the set-up of every worker it starts (:func:`worker_setup`): one numba
thread and one BLAS thread (the workers are the parallelism; a study's ``parallel=True``
kernel or a matrix product would otherwise start a thread per core in each worker and
oversubscribe the cores), then the
caller's ``initializer`` (a study's own :meth:`~budget.runner.capabilities.Warmup.worker_init`). This process, where
it runs tasks (with one worker, or ``work_here``), is set up the same way.
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os
import socket
import time
import uuid
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from typing import Any, Self
from urllib.parse import urlsplit

from simcam.infra.errors import UserInputError, WorkersLost
from simcam.infra.lifecycle import (cap_workers, default_stop_handlers, exit_with_parent, lost_worker_message,
                                    quick_teardown, quiet_pool_breakage, stop_pool)

__all__ = ["DaskExecutor", "Executor", "InlineExecutor", "ProcessExecutor", "default_workers", "make_executor",
           "start_method", "worker_setup"]


def default_workers() -> int:
    """All cores this process may use."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


class Executor(ABC):
    """Runs tasks; a context manager that owns its workers."""

    description: str = ""
    workers: int = 1

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Release the workers."""

    @abstractmethod
    def map_unordered(self, fn: Callable, tasks: list) -> Iterator[tuple[int, Any]]:
        """Yield ``(index, fn(tasks[index]))`` as tasks finish. ``tasks`` may grow while this
        runs: tasks the caller appends (between two results) are run too, after those before."""


class InlineExecutor(Executor):
    """Tasks one after the other in this process; ``limits``: the thread limits
    :func:`worker_setup` set here, given back on :meth:`close`."""

    description = "this process"

    def __init__(self, limits=None):
        self._limits = limits

    def close(self) -> None:
        _restore(self._limits)
        self._limits = None

    def map_unordered(self, fn, tasks):
        i = 0
        while i < len(tasks):  # the caller may append tasks between results
            yield i, fn(tasks[i])
            i += 1


def worker_setup(initializer: Callable | None = None, args: tuple = ()):
    """What runs first in every worker the runner starts: one numba thread and one BLAS
    thread, then ``initializer(*args)``. Returns the BLAS limits
    (:func:`threadpoolctl.threadpool_limits`), which this process gives back with
    :func:`_restore` where it is not a worker of its own (the caller's process).

    numba's thread count is per calling thread (``numba.set_num_threads`` is thread-local),
    so it is set in the thread that runs the tasks: a process pool's worker runs its
    initializer and its tasks in one thread; a Dask worker runs tasks in its own threads,
    so there it is set before each task (:func:`_dask_call`). BLAS's is per process: a
    trial's small matrix products (a star camera's distortion correction at 10,000 field
    points) on OpenBLAS's threads took twice the CPU for no less wall time, and two workers
    each starting a thread per core made a 200-trial run 1.2 times faster than one worker
    instead of 2.
    """
    import numba
    from threadpoolctl import threadpool_limits

    numba.set_num_threads(1)
    limits = threadpool_limits(limits=1, user_api="blas")
    if initializer is not None:
        initializer(*args)
    return limits


def _restore(limits) -> None:
    """Give back thread limits :func:`worker_setup` set (None: nothing)."""
    if limits is not None:
        limits.restore_original_limits()


def _init_worker(initializer, args):
    # a forked worker's stop handlers are its parent's (they raise Interrupted): Python's own
    # first, so that the pool's SIGTERM ends it quietly even while it sets up; then the
    # parent-death guard (simcam.infra.lifecycle): a parent killed while its workers still
    # import leaves no worker behind; the worker's exit, which the pool's shutdown waits for,
    # skips the final garbage collections
    default_stop_handlers()
    exit_with_parent()
    quick_teardown()
    worker_setup(initializer, args)


def start_method() -> str:
    """How :class:`ProcessExecutor` starts its workers: ``"fork"`` on Linux while this process
    has no thread but its main one and numba has not launched its thread pool here, else
    ``"spawn"``.

    A forked worker begins with this process's imported modules (numpy, pandas, numba and
    the study's code: 1-1.5 s of CPU that a spawned worker spends importing them again);
    a validation starts its pool before any task or kernel runs, and every task carries
    its scenario, seed and trials, so the results are the same whichever way the workers
    start (``tests/test_runner.py``). Forking a process that runs other threads can copy a
    lock held by one of them, and numba's thread pool does not survive a fork, so a
    process that has either (a caller that ran a parallel kernel first, a test session)
    spawns. macOS forks unsafely (its system libraries), so it spawns too. Whether numba's
    pool is up is read from numba's own flag (not public API: a numba that no longer has
    it counts as launched, and the pool spawns).
    """
    import sys
    import threading

    if sys.platform != "linux" or threading.active_count() > 1:
        return "spawn"
    try:
        from numba.np.ufunc import parallel

        launched = bool(getattr(parallel, "_is_initialized", True))
    except ImportError:  # numba's layout changed: assume its pool is up
        launched = True
    return "spawn" if launched else "fork"


class ProcessExecutor(Executor):
    """A pool of ``workers`` local processes (forked or spawned: :func:`start_method`); with
    ``work_here``, ``workers`` counts this process too and the pool starts ``workers - 1``.

    ``work_here``: this process runs the next task itself between collecting the others'
    results (a caller's own work between results, the truths' sizing say, is done in the
    same gaps). The started workers are not idle meanwhile: each holds two tasks, the one
    it runs and the next, and this process tops them up before it runs one of its own.
    This process is the first ready (it has imported what the tasks need; a spawned
    worker imports it all again, 1.5-2 s, a forked one loads only its kernels), so it
    takes the first task; and one process fewer is started and set up for the same
    number of workers. A caller that must stay free between results (a sweep writing
    each point as it comes) leaves it off.
    """

    def __init__(self, workers: int, *, initializer: Callable | None = None, initargs: tuple = (),
                 work_here: bool = False):
        if workers < 1:
            raise ValueError(f"workers: must be >= 1, got {workers}")
        self.workers = workers
        self.description = f"{workers} local process{'es' if workers > 1 else ''}"
        self._initializer = initializer
        self._initargs = initargs
        self._pool = None
        #: processes the pool starts; whether this process is set up as a worker (work_here)
        self._started = workers - 1 if work_here else workers
        self._work_here = work_here
        self._set_up = not work_here
        self._limits = None  # this process's BLAS limits while it works too

    def __enter__(self):
        from concurrent.futures import ProcessPoolExecutor

        if self._started > 0:
            context = multiprocessing.get_context(start_method())
            self._pool = ProcessPoolExecutor(max_workers=self._started, mp_context=context,
                                             initializer=_init_worker, initargs=(self._initializer, self._initargs))
            # start every worker now (a pool spawns lazily): they import while the caller works
            for _ in range(self._started):
                self._pool.submit(int)
            quiet_pool_breakage(self._pool)  # a worker's death: no thread traceback
        if not self._set_up:  # this process is a worker too, set up as the others
            self._limits = worker_setup(self._initializer, self._initargs)
            self._set_up = True
        return self

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        _restore(self._limits)
        self._limits = None

    def __exit__(self, exc_type, *exc) -> None:
        if exc_type is not None and self._pool is not None:
            # an interruption or an error: end the workers now, leave no child behind

            stop_pool(self._pool)
            self._pool = None
        self.close()

    def map_unordered(self, fn, tasks):
        """As :meth:`Executor.map_unordered`; a worker that dies (``kill -9``, out of memory)
        ends the run with :class:`~simcam.infra.errors.WorkersLost`, one line naming it."""
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        if not self._set_up or (self._pool is None and self._started > 0):
            self.__enter__()
        # a bounded number in flight in the pool: an interruption leaves little queued work
        # behind, and tasks the caller appends between results still find workers
        depth = 2 * self._started
        nxt = 0
        running: dict = {}
        try:
            while nxt < len(tasks) or running:
                mine = None
                if self._work_here and nxt < len(tasks):  # this process's: the first not given out
                    mine, nxt = nxt, nxt + 1
                while nxt < len(tasks) and len(running) < depth:
                    running[self._pool.submit(fn, tasks[nxt])] = nxt
                    nxt += 1
                if mine is not None:
                    yield mine, fn(tasks[mine])
                    finished = [f for f in running if f.done()]
                else:  # nothing to run here: wait for the pool's
                    finished, _ = wait(list(running), return_when=FIRST_COMPLETED)
                for f in finished:
                    i = running.pop(f)
                    yield i, f.result()
        except BrokenProcessPool:  # a submit to, or a result of, a pool whose worker died
            raise WorkersLost(lost_worker_message(self._pool)) from None
        finally:
            for f in running:
                f.cancel()


def _dask_call(fn, task, initializer, initargs):
    # one numba thread in the Dask worker thread that runs this task (thread-local), then
    # the study's own worker set-up
    worker_setup(initializer, initargs)
    return fn(task)


#: seconds to reach a scheduler (a plain TCP connection first, then Dask's handshake)
DASK_CONNECT_S = 5.0
#: seconds a run waits with no worker in its cluster before it stops (a nanny restarts a
#: killed worker within a few seconds; a cluster whose workers are all gone stays empty)
NO_WORKER_GRACE_S = 10.0
#: how often a waiting run looks at the cluster's workers, seconds
WORKER_POLL_S = 1.0


def _reachable(address: str) -> None:
    """Refuse at once a ``tcp://HOST:PORT`` where nothing listens (Dask itself retries until
    its connect timeout, 20 s and more, before saying so)."""
    if not address.startswith("tcp://"):
        return
    try:
        parts = urlsplit(address)
        host, port = parts.hostname, parts.port
    except ValueError as exc:
        raise UserInputError(f"--scheduler {address}: not an address like tcp://HOST:PORT ({exc})") from None
    if not host or port is None:
        raise UserInputError(f"--scheduler {address}: give the port too, like tcp://HOST:8786")
    try:
        with socket.create_connection((host, port), timeout=DASK_CONNECT_S):
            pass
    except socket.gaierror as exc:
        raise UserInputError(f"--scheduler {address}: unknown host {host} ({exc.strerror})") from None
    except TimeoutError:
        raise UserInputError(f"--scheduler {address}: no answer from {host}:{port} within "
                             f"{DASK_CONNECT_S:g} s") from None
    except OSError as exc:
        raise UserInputError(f"--scheduler {address}: cannot connect to {host}:{port} "
                             f"({exc.strerror or exc}); is a Dask scheduler running there?") from None


class _ReconnectionNoise:
    """A logging filter: a client whose scheduler is gone logs each failed reconnection (and
    its cancellation at close) as an ERROR with a traceback; the run says what happened in
    its own line (:class:`~simcam.infra.errors.WorkersLost`), so these records are dropped."""

    def filter(self, record) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if isinstance(exc, (OSError, TimeoutError, asyncio.CancelledError)):
            return False
        return not str(record.msg).startswith("Failed to reconnect")


_RECONNECTION_NOISE = _ReconnectionNoise()


def _quiet_reconnection(on: bool) -> None:
    log = logging.getLogger("distributed.client")
    (log.addFilter if on else log.removeFilter)(_RECONNECTION_NOISE)


class DaskExecutor(Executor):
    """Tasks on a Dask distributed cluster (an existing scheduler, or a LocalCluster).

    Bounded waiting: an unreachable scheduler is said within :data:`DASK_CONNECT_S`; a run
    whose cluster has had no worker for :data:`NO_WORKER_GRACE_S` (every worker killed),
    or whose scheduler is gone, stops with :class:`~simcam.infra.errors.WorkersLost`, one
    line with the tasks finished (a sweep keeps its finished points: it resumes)."""

    def __init__(self, *, scheduler: str | None = None, local_workers: int | None = None,
                 initializer: Callable | None = None, initargs: tuple = ()):
        if (scheduler is None) == (local_workers is None):
            raise ValueError("DaskExecutor: give scheduler or local_workers")
        self.scheduler = scheduler
        self.local_workers = local_workers
        self.client = None
        self.cluster = None
        self.workers = local_workers or 0
        self._initializer = initializer
        self._initargs = initargs
        self.description = (f"Dask LocalCluster of {local_workers} worker process(es)" if local_workers
                            else f"Dask scheduler {scheduler}")

    def __enter__(self):
        from distributed import Client, LocalCluster

        _quiet_reconnection(True)
        if self.local_workers is not None:
            self.cluster = LocalCluster(n_workers=self.local_workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            _reachable(self.scheduler)
            try:
                self.client = Client(self.scheduler, timeout=f"{DASK_CONNECT_S:g}s")
            except (OSError, TimeoutError, ValueError) as exc:
                raise UserInputError(f"--scheduler {self.scheduler}: cannot connect: {exc}") from None
            except MemoryError:  # a frame length read from a service that is no Dask scheduler
                raise UserInputError(f"--scheduler {self.scheduler}: what answers there is not a Dask "
                                     f"scheduler") from None
            self.workers = sum(self.client.nthreads().values())
            if self.workers == 0:
                self.client.close()
                raise UserInputError(f"--scheduler {self.scheduler}: the cluster has no workers")
        return self

    def close(self):
        if self.client is not None:
            try:
                self.client.close(timeout=DASK_CONNECT_S)
            except Exception:  # noqa: BLE001 - a scheduler already gone: nothing left to close
                pass
            self.client = None
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None
        _quiet_reconnection(False)

    def _where(self) -> str:
        return f"--scheduler {self.scheduler}" if self.scheduler else self.description

    def _workers_now(self) -> int | None:
        """The cluster's workers now (None: the scheduler cannot be asked)."""
        if self.client is None or self.client.status != "running":
            return None
        try:
            return len(self.client.scheduler_info(n_workers=-1).get("workers", {}))
        except Exception:  # noqa: BLE001 - a scheduler going away mid-call
            return None

    def map_unordered(self, fn, tasks):
        from distributed import as_completed

        if self.client is None:
            self.__enter__()
        tag = uuid.uuid4().hex[:8]
        futures: list = []
        index: dict = {}
        finished = 0

        def submit_new() -> list:
            new = []
            for i in range(len(futures), len(tasks)):  # the caller may append tasks between results
                f = self.client.submit(_dask_call, fn, tasks[i], self._initializer, self._initargs,
                                       key=f"task-{i}-{tag}", pure=False)
                futures.append(f)
                index[f.key] = i
                new.append(f)
            return new

        def lost(why: str) -> WorkersLost:
            return WorkersLost(f"{self._where()}: {why}; the run stopped after {finished} of {len(tasks)} "
                               f"task(s)")

        try:
            done = as_completed(submit_new())
            empty_since = None
            next_look = time.monotonic() + WORKER_POLL_S
            while not done.is_empty():
                if not done.has_ready():
                    if self.client.status not in ("running", "newly-created"):
                        raise lost("the connection to the scheduler was lost")
                    now = time.monotonic()
                    if now >= next_look:
                        next_look = now + WORKER_POLL_S
                        n = self._workers_now()
                        empty_since = (empty_since or now) if n == 0 else None
                        if empty_since is not None and now - empty_since >= NO_WORKER_GRACE_S:
                            raise lost(f"the cluster has had no worker for {NO_WORKER_GRACE_S:g} s "
                                       f"(were they killed?)")
                    with done.thread_condition:
                        done.thread_condition.wait(timeout=0.1)
                    continue
                fut = next(done)
                if fut.status == "cancelled":
                    raise lost("the scheduler cancelled a task (the connection to it was lost?)")
                value = fut.result()
                finished += 1
                yield index[fut.key], value
                for f in submit_new():
                    done.add(f)
        finally:
            if self.client is not None and self.client.status == "running":
                self.client.cancel([f for f in futures if not f.done()])


def make_executor(*, workers: int | None = None, scheduler: str | None = None, dask_local: int | None = None,
                  initializer: Callable | None = None, initargs: tuple = (), work_here: bool = False) -> Executor:
    """The executor asked for (at most one option; default all local cores; 1 worker: inline).
    ``work_here``: local processes count this one, which runs tasks too (:class:`ProcessExecutor`)."""

    given = [n for n, v in (("--workers", workers), ("--scheduler", scheduler), ("--dask-local", dask_local))
             if v is not None]
    if len(given) > 1:
        raise UserInputError(f"{' and '.join(given)}: give one of them")
    if scheduler is not None:
        if not scheduler.startswith(("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")):
            raise UserInputError(f"--scheduler {scheduler}: expected an address like tcp://HOST:PORT")
        return DaskExecutor(scheduler=scheduler, initializer=initializer, initargs=initargs)
    if dask_local is not None:
        if dask_local < 1:
            raise UserInputError(f"--dask-local: must be >= 1 (got {dask_local})")
        return DaskExecutor(local_workers=dask_local, initializer=initializer, initargs=initargs)
    n = workers if workers is not None else default_workers()
    if n < 1:
        raise UserInputError(f"--workers: must be >= 1 (got {n})")

    n = cap_workers(n, quiet=workers is None)
    if n == 1:
        return InlineExecutor(limits=worker_setup(initializer, initargs))
    return ProcessExecutor(n, initializer=initializer, initargs=initargs, work_here=work_here)
