"""A first run's numba compilation, spread over processes.

numba compiles a kernel the first time it is called with a new signature and keeps the
machine code in its on-disk cache (``cache=True``), so only the first run after an
install (or after a kernel's source changed) pays for compiling, and it compiles every
kernel it meets one after the other, in one process: about 8 s of a star-camera
validation. :func:`compiling_in_parallel` spreads that over the machine's cores: while
the calling process compiles what it needs first by doing its own work, each *child
target* (a function that calls other kernels on tiny arrays of the production types)
compiles in a child process of its own; all write numba's cache, and afterwards every
process (this one, the workers of a pool) loads the kernels from it instead of
compiling them again.

Nothing is started when the cache already holds the kernels named in ``check`` (the
usual case: the cost is reading one small index file per kernel), on a machine with one
usable core, or when numba's cache cannot be used; and nothing depends on a child
succeeding: a kernel that a child did not compile in time is compiled where it is called,
as without this module. Results are the same either way: numba compiles the same code
for the same signature wherever it does so.

Only the standard library is imported at module level.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager

__all__ = ["compiling_in_parallel", "is_cached", "usable_cores"]

#: a child that has not finished compiling after this long is stopped (its kernels are
#: then compiled where they are called)
CHILD_TIMEOUT_S = 120.0


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS reports one)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def is_cached(dispatcher) -> bool:
    """Whether numba's on-disk cache holds a valid entry for ``dispatcher`` (a
    ``numba.njit(cache=True)`` function) for its current source.

    Reads numba's own index file through its cache object (``FunctionCache``, not public
    API: any failure to read it counts as cached, so that nothing is started on a numba
    this module does not understand). A kernel whose source changed since it was cached
    has a stale index, which numba reports as empty: not cached.
    """
    try:
        cache = dispatcher._cache
        if not getattr(cache, "_enabled", False):
            return True  # caching off (NUMBA_DISABLE_JIT, no writable folder): nothing to warm
        return bool(cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - numba internals changed: read as cached, start nothing
        return True


def _child(target: str, arg: str) -> subprocess.Popen | None:
    """Start ``python -c`` running ``target`` (``module:function``) with ``arg`` (guarded by
    :func:`simcam.infra.lifecycle.exit_with_parent`; its exit, which the caller waits for, skips
    the final garbage collections: :func:`simcam.infra.lifecycle.quick_teardown`)."""
    module, _, func = target.partition(":")
    code = (
        "import sys\n"
        f"sys.path[:0] = {[p or os.getcwd() for p in sys.path]!r}\n"
        "from simcam.infra.lifecycle import exit_with_parent, quick_teardown\n"
        "exit_with_parent()\n"
        "quick_teardown()\n"
        "import importlib\n"
        f"getattr(importlib.import_module({module!r}), {func!r})({arg!r})\n"
    )
    try:
        return subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.DEVNULL,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    except OSError:
        return None


@contextmanager
def compiling_in_parallel(children: Sequence[tuple[str, str]], *, check: Iterable) -> Iterator[bool]:
    """Compile kernels in child processes while the ``with`` body runs; wait for them at
    its end.

    Parameters
    ----------
    children : sequence of (target, arg)
        ``target`` is ``"module:function"``; each runs as ``function(arg)`` in a child
        process of its own (``arg`` a string, e.g. JSON). At most ``usable_cores() - 1``
        are started.
    check : iterable of numba dispatchers
        The kernels the children compile: when every one is cached, nothing is started.

    Yields
    ------
    bool
        Whether children were started (the cache was cold).
    """
    procs: list[subprocess.Popen] = []
    room = usable_cores() - 1
    if room > 0 and children and not all(is_cached(d) for d in check):
        for target, arg in list(children)[:room]:
            p = _child(target, arg)
            if p is not None:
                procs.append(p)
    try:
        yield bool(procs)
    except BaseException:
        _stop(procs)  # the run is failing or interrupted: its children go now
        raise
    _reap(procs)


def _reap(procs: list[subprocess.Popen]) -> None:
    """Wait for the children (at most :data:`CHILD_TIMEOUT_S` in all); stop any still
    running then, or when the wait is interrupted (the interruption goes on)."""
    deadline = time.monotonic() + CHILD_TIMEOUT_S
    try:
        for p in procs:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                break  # past the deadline: the finally stops every child still running
    finally:
        _stop(procs)


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.kill()
            p.wait()
