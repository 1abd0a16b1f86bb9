"""Process lifecycle shared by every long command: signals, workers, partial output, sizes.

One small module so that every command (``simcam render``, ``budget starcam simulate``,
``budget validate``, ``budget sweep``, the generic runner of ``budget.runner``) behaves the
same under faults:

* :func:`handle_termination`: SIGTERM and SIGHUP (and SIGINT) raise :class:`Interrupted`
  in the main thread, so the ``except BaseException`` / ``finally`` clean-up that already
  runs on Ctrl-C (temporary folders, worker pools) also runs when ``timeout`` or a batch
  system stops the run. :func:`simcam.infra.cli.run_cli` wraps every command in it and
  turns the interruption into one line and exit status ``128 + signal``.
* :func:`exit_with_parent`: called from a worker's initializer, the worker dies when its
  parent does (``kill -9`` of the parent leaves no orphan burning a core).
  :func:`stop_pool` ends a :class:`concurrent.futures.ProcessPoolExecutor`'s workers at once.
* :func:`partial_prefix`, :func:`remove_stale_partials`: temporary output folders carry the
  PID of the run that writes them (``.OUT.partial.<pid>.<random>``), so a later run knows
  whether their owner is dead and removes them, saying so.
* :func:`check_disk`, :func:`check_memory`, :func:`announce_size`: estimate what a request
  needs before starting and refuse, naming the figure and the limit, what cannot fit.
* :func:`progress`: a tqdm bar on a terminal, nothing when stderr is not one.
* :func:`guarded_entry`: the console scripts' entry, so that Ctrl-C even while the heavy
  modules are being imported ends in one line, not a traceback.
* :func:`quick_teardown`: a command's process (and each worker it starts) skips the
  interpreter's final garbage collections, a fixed half second of CPU at every exit.

Only the standard library is imported at module level (it runs before anything else in
the console scripts).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from simcam.infra.errors import Interrupted, ResourceLimitError

__all__ = [
    "Interrupted", "ResourceLimitError", "announce_size", "available_memory_bytes", "check_disk", "check_memory",
    "exit_with_parent", "format_bytes", "guarded_entry", "handle_termination", "partial_prefix", "pid_alive",
    "lost_worker_message", "progress", "quick_teardown", "quiet_pool_breakage", "raise_pending_interruption",
    "remove_stale_partials",
    "safe_filename", "stop_pool", "worker_initializer",
    "cap_workers", "usable_cores",
]

#: outputs at least this large are announced before they are written
ANNOUNCE_BYTES = 1 << 30
#: a request may use at most this fraction of the free disk / available memory
SAFETY_FRACTION = 0.9


# ----------------------------------------------------------------------------- signals
_STOP_SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None),
                                  signal.SIGINT) if s is not None)


#: signals whose :class:`Interrupted` was raised inside :func:`handle_termination` and has not
#: yet been seen leaving it (one raised where C code or a library swallowed it stays here)
_PENDING: list = []


def _raise_interrupted(signum, _frame):
    # one-shot: a second signal during the clean-up must not interrupt the clean-up itself
    # (a supervisor that insists sends SIGKILL)
    for s in _STOP_SIGNALS:
        try:
            signal.signal(s, signal.SIG_IGN)
        except (ValueError, OSError):
            pass
    _PENDING.append(signum)
    raise Interrupted(signum)


def raise_pending_interruption() -> None:
    """Raise the :class:`Interrupted` of a stop signal that arrived in this block but was
    swallowed where it was raised (a C callback that reports nothing, a library's
    ``except BaseException``): a command is never left running to its end, or ending with
    status 0, deaf to a signal it received. A long loop calls this at each step; the end of
    :func:`handle_termination` calls it too."""
    if _PENDING:
        signum = _PENDING[0]
        _PENDING.clear()
        raise Interrupted(signum)


#: seconds after which an interruption swallowed by a C callback is delivered again
REDELIVER_S = 0.05


def _redeliver_swallowed(unraisable) -> None:
    """``sys.unraisablehook`` inside :func:`handle_termination`: an :class:`Interrupted` raised
    by the stop handler while the main thread ran a C callback (numba's cache notifications go
    through ctypes, which cannot propagate an exception and only reports it) is delivered
    again once the main thread is back in Python code, instead of being lost with the
    handler already disarmed (the command would then run to its end, deaf to the signal).
    Anything else goes to the previous hook."""
    exc = unraisable.exc_value
    if not isinstance(exc, Interrupted):
        _PREVIOUS_UNRAISABLE[-1](unraisable)
        return
    try:
        signal.signal(exc.signum, _raise_interrupted)
    except (ValueError, OSError):
        return
    timer = threading.Timer(REDELIVER_S, os.kill, (os.getpid(), exc.signum))
    timer.daemon = True
    timer.start()


#: the unraisable hooks that :func:`handle_termination` replaced, innermost last
_PREVIOUS_UNRAISABLE: list = []


def default_stop_handlers() -> None:
    """This process's stop signals back to Python's defaults (SIGINT raises
    KeyboardInterrupt, SIGTERM and SIGHUP end the process), as a freshly started worker
    has them: a forked worker inherits its parent's handlers (a command's: the signal
    raises :class:`Interrupted`, the command's own clean-up), and the parent, which ends
    its workers itself on an interruption, is the one to handle it. Main thread only."""
    for s in _STOP_SIGNALS:
        signal.signal(s, signal.default_int_handler if s == signal.SIGINT else signal.SIG_DFL)


@contextmanager
def handle_termination(signals: tuple = _STOP_SIGNALS) -> Iterator[None]:
    """Within the block, the given signals raise :class:`Interrupted` (main thread only); one
    raised inside a C callback, which cannot propagate it, is delivered again after it
    (:func:`_redeliver_swallowed`), and one swallowed anywhere else is raised at the block's
    end at the latest (:func:`raise_pending_interruption`), in place of any error it caused
    on its way.

    The previous handlers are restored on exit. Outside the main thread (where Python
    cannot set handlers) the block runs unchanged.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    for s in signals:
        try:
            previous[s] = signal.signal(s, _raise_interrupted)
        except (ValueError, OSError):
            pass
    _PREVIOUS_UNRAISABLE.append(sys.unraisablehook)
    sys.unraisablehook = _redeliver_swallowed
    try:
        yield
        raise_pending_interruption()  # one swallowed on its way: delivered now, not lost
    except Interrupted:
        _PENDING.clear()  # seen leaving the block
        raise
    except GeneratorExit:  # the context manager itself closed unfinished: nothing to translate
        raise
    except BaseException:
        # an error the swallowed interruption caused on its way (numba, interrupted while it
        # saved a compiled kernel to its cache, raises "no compiled object yet"): the signal
        # is what ended the command
        if _PENDING:
            signum = _PENDING[0]
            _PENDING.clear()
            raise Interrupted(signum) from None
        raise
    finally:
        sys.unraisablehook = _PREVIOUS_UNRAISABLE.pop()
        for s, h in previous.items():
            try:
                signal.signal(s, h if h is not None else signal.SIG_DFL)
            except (ValueError, OSError):
                pass


def quick_teardown() -> None:
    """At this process's exit, skip the interpreter's final garbage collections.

    Python's shutdown clears every module and runs full collections over every object
    still tracked: in a process that has imported numpy, numba, pandas and pydantic and
    run a study (about 170,000 tracked objects) that costs 0.3-0.5 s of CPU after the
    command's last line, at the end of every command and of every worker process, which
    the command then waits for. An exit handler registered here, first (so it runs last,
    after every other exit handler: ``weakref.finalize`` clean-ups, multiprocessing's),
    moves the objects to the collector's permanent generation (:func:`gc.freeze`):
    shutdown still frees each object by its reference count, only the reference cycles
    left at exit are not searched for (the process's memory goes back to the system all
    the same). A command writes and closes its outputs before it returns, so nothing it
    writes waits on such a cycle. Idempotent; call it first thing in a process.
    """
    global _QUICK_TEARDOWN
    if _QUICK_TEARDOWN:
        return
    _QUICK_TEARDOWN = True
    import atexit
    import gc

    atexit.register(gc.freeze)


_QUICK_TEARDOWN = False


def guarded_entry(module: str, attr: str = "main") -> None:
    """Import ``module`` and call its ``attr()``; Ctrl-C or SIGTERM while importing ends
    in one line on stderr and exit status 128 + signal instead of a traceback.

    Used by the console scripts (``simcam``, ``budget``); the command itself runs under
    :func:`simcam.infra.cli.run_cli`, which handles signals from then on. The process
    skips the final garbage collections at its exit (:func:`quick_teardown`).
    """
    import importlib

    quick_teardown()
    try:
        with handle_termination():
            fn = getattr(importlib.import_module(module), attr)
    except (Interrupted, KeyboardInterrupt) as exc:
        signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
        sys.stderr.write(f"interrupted ({signal.Signals(signum).name}) while starting; nothing was written\n")
        sys.exit(128 + signum)
    fn()


# ----------------------------------------------------------------------------- workers
_PR_SET_PDEATHSIG = 1


def _set_pdeathsig(sig: int) -> bool:
    """Linux: ask the kernel to send ``sig`` to this process when its parent dies."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def exit_with_parent(*, poll_s: float = 0.5, use_pdeathsig: bool = True) -> None:
    """Make this (worker) process exit when its parent process dies.

    Call it first thing in a worker pool's ``initializer``. Two guards:

    * on Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)``: the kernel kills the worker as
      soon as the parent dies, even while a compiled kernel holds the GIL. (The kernel
      ties it to the parent *thread* that started the worker: pools that start workers
      from a thread that ends before the process should pass ``use_pdeathsig=False``;
      :class:`concurrent.futures.ProcessPoolExecutor` starts them from the submitting
      thread.)
    * everywhere, a daemon thread that polls :func:`os.getppid` every ``poll_s`` seconds
      and calls :func:`os._exit` once the worker has been re-parented.

    When the workers are gone, multiprocessing's resource tracker (which holds a pipe
    from the parent and each worker) sees end-of-file and exits too. The guard is set
    once per process: a forked worker inherits its parent's memory but neither the
    parent's kernel setting nor its threads, so it sets its own.
    """
    global _GUARDED
    if _GUARDED == os.getpid():
        return
    _GUARDED = os.getpid()
    import multiprocessing

    owner = multiprocessing.parent_process()
    parent = owner.pid if owner is not None and owner.pid else os.getppid()
    if use_pdeathsig:
        _set_pdeathsig(signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before the guard was set
        os._exit(1)

    def watch():
        import time

        while True:
            time.sleep(poll_s)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()


#: the process that set the guard (a forked child inherits the value, not the guard)
_GUARDED: int | None = None


def _guarded_init(target: str) -> None:
    exit_with_parent()
    quick_teardown()
    import importlib

    module, _, name = target.partition(":")
    getattr(importlib.import_module(module), name)()


def worker_initializer(target: str):
    """A pool ``initializer`` that guards the worker (:func:`exit_with_parent`) *before*
    importing and calling ``target`` (``"package.module:function"``); the worker skips the
    final garbage collections at its exit (:func:`quick_teardown`).

    The guard then holds from the worker's first moments: a parent killed while its
    workers are still importing numerical libraries (seconds on a loaded machine) leaves
    no worker behind either. Picklable (a :func:`functools.partial` of this light module).
    """
    import functools

    return functools.partial(_guarded_init, target)


def quiet_pool_breakage(pool) -> None:
    """Let a :class:`~concurrent.futures.ProcessPoolExecutor` break without a thread traceback.

    When a pool's worker dies (``kill -9``, or :func:`stop_pool` ending them on an
    interruption), the pool's manager thread marks every pending task failed with
    ``set_exception``; a task the caller cancelled meanwhile (an interrupted
    ``map_unordered`` cancels what it queued) raises ``InvalidStateError: CANCELLED`` there,
    printed as ``Exception in thread ...`` before the command's own line (CPython 3.11
    does not skip cancelled futures). The pool's manager thread is given a
    ``terminate_broken`` that first drops the cancelled tasks (it runs in that thread, the
    only one that reads the pending tasks then), then does the rest as before. Call it
    once the thread exists (after the first ``submit``); without that thread (another
    Python's pool layout) nothing is changed.
    """
    thread = getattr(pool, "_executor_manager_thread", None)
    original = getattr(thread, "terminate_broken", None)
    if thread is None or original is None or getattr(original, "_quiet", False):
        return

    def terminate_broken(cause):
        pending = getattr(thread, "pending_work_items", None)
        if isinstance(pending, dict):
            for work_id in [w for w, item in list(pending.items()) if item.future.cancelled()]:
                pending.pop(work_id, None)
        original(cause)

    terminate_broken._quiet = True
    thread.terminate_broken = terminate_broken


def lost_worker_message(pool, *, what: str = "the run") -> str:
    """One line for a pool that broke because a worker died: its PID and how it ended."""
    dead = []
    for p in list((getattr(pool, "_processes", None) or {}).values()):
        code = getattr(p, "exitcode", None)
        if code is not None and code != 0:
            how = f"killed by {signal.Signals(-code).name}" if code < 0 and -code in signal.valid_signals() \
                else f"exit status {code}"
            dead.append(f"pid {p.pid}, {how}")
    # the pool ends its other workers with SIGTERM once one has died: name the one that died
    first = [d for d in dead if not d.endswith("killed by SIGTERM")] or dead
    who = f" ({'; '.join(first)})" if first else ""
    return (f"a worker process ended abruptly{who}; {what} stopped and its workers were ended "
            f"(was it killed, or out of memory?)")


def stop_pool(pool) -> None:
    """End a :class:`~concurrent.futures.ProcessPoolExecutor` now (on an interruption).

    Queued work is cancelled, the worker processes are terminated (SIGTERM, then SIGKILL
    after 2 s) and joined, so the caller leaves no child process behind; the pool breaks
    without a thread traceback (:func:`quiet_pool_breakage`).
    """
    quiet_pool_breakage(pool)
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        try:
            p.terminate()
        except (OSError, ValueError, AttributeError):
            pass
    for p in procs:
        try:
            p.join(2.0)
            if p.is_alive():
                p.kill()
                p.join(2.0)
        except (OSError, ValueError, AttributeError, AssertionError):
            pass
    try:
        pool.shutdown(wait=True, cancel_futures=True)
    except Exception:  # noqa: BLE001 - a broken pool is what we expect here
        pass


# ----------------------------------------------------------------------------- partial output
_PARTIAL_RE = re.compile(r"\.partial\.(\d+)\.")


def partial_prefix(out: str | os.PathLike) -> str:
    """Name prefix of the temporary sibling folder of ``out`` written by this process:
    ``.NAME.partial.<pid>.`` (the PID tells a later run whether its owner is alive)."""
    return f".{Path(out).name}.partial.{os.getpid()}."


def pid_alive(pid: int) -> bool:
    """Whether a process with this PID exists (on this machine)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # exists, owned by someone else
    return True


def remove_stale_partials(out: str | os.PathLike, *, echo: Callable[[str], None] | None = None) -> list[Path]:
    """Remove the temporary folders ``.NAME.partial.<pid>.*`` beside ``out`` whose run is dead.

    A folder whose PID is alive (another run writing the same output) is left alone, as
    is one without a PID (an older format: its owner cannot be told). Each removal is
    reported through ``echo`` (default: a line on stderr).

    Returns
    -------
    list of pathlib.Path
        The folders removed.
    """
    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        return []
    say = echo or (lambda msg: print(msg, file=sys.stderr))
    removed = []
    head = f".{out.name}.partial."
    for p in parent.iterdir():
        if not p.name.startswith(head):
            continue
        m = _PARTIAL_RE.match(p.name[len(out.name) + 1:])
        if m is None or int(m.group(1)) == os.getpid() or pid_alive(int(m.group(1))):
            continue
        size = _tree_bytes(p)
        shutil.rmtree(p, ignore_errors=True)
        if not p.exists():
            removed.append(p)
            say(f"removed {p} ({format_bytes(size)}), left by an interrupted run (pid {m.group(1)}, no longer running)")
    return removed


def _tree_bytes(path: Path) -> int:
    total = 0
    for root, _dirs, files in os.walk(path):
        for f in files:
            try:
                total += os.lstat(os.path.join(root, f)).st_size
            except OSError:
                pass
    return total


_UNSAFE_RE = re.compile(r"[^A-Za-z0-9._+-]+")


def safe_filename(name: str, *, default: str = "unnamed", max_len: int = 64) -> str:
    """A file-name component made from an input string (a lens name, a sweep label).

    Path separators, ``..``, control and other unusual characters become ``_``; leading
    dots are removed (no hidden files, no ``..``); the result is never empty and at most
    ``max_len`` characters. ``"../../EVIL"`` gives ``"EVIL"``; ``"f/4 lens"`` gives ``"f_4_lens"``.
    """
    s = _UNSAFE_RE.sub("_", str(name)).strip("_")
    s = re.sub(r"\.{2,}", "_", s).lstrip("._-")
    return s[:max_len] or default


# ----------------------------------------------------------------------------- sizes
def format_bytes(n: float) -> str:
    """``1536`` -> ``'1.5 KiB'``; beyond 1024 PiB ``'3.2e+300 B'`` (not a 300-digit PiB figure)."""
    n = float(n)
    if not math.isfinite(n) or abs(n) >= 1024.0 ** 6:
        return f"{n:.2g} B"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024.0 or unit == "PiB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024.0
    return f"{n:.1f} EiB"  # pragma: no cover


def _existing_ancestor(path: Path) -> Path:
    p = path.absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def check_disk(path: str | os.PathLike, need_bytes: float, *, what: str) -> None:
    """Refuse (:class:`ResourceLimitError`) when ``need_bytes`` exceed the free space there.

    Parameters
    ----------
    path : where the output goes (need not exist yet)
    need_bytes : the estimate, bytes
    what : the request, for the message (e.g. ``"--frames 1000000000 full frames"``)
    """
    free = shutil.disk_usage(_existing_ancestor(Path(path))).free
    if need_bytes > SAFETY_FRACTION * free:
        raise ResourceLimitError(f"{what}: needs about {format_bytes(need_bytes)} of disk, "
                                 f"{format_bytes(free)} free at {_existing_ancestor(Path(path))}")


def _system_available_bytes() -> int | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        import psutil

        return int(psutil.virtual_memory().available)
    except Exception:  # noqa: BLE001 - optional
        return None


def _address_space_left() -> int | None:
    """What ``RLIMIT_AS`` (``ulimit -v``, a batch system's memory limit) leaves to this
    process: the soft limit less the current virtual size; None when unlimited."""
    try:
        import resource

        soft, _hard = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, AttributeError, OSError, ValueError):
        return None
    if soft == resource.RLIM_INFINITY or soft < 0:
        return None
    used = 0
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    used = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    return max(0, int(soft) - used)


def available_memory_bytes() -> int | None:
    """Memory available to a new allocation, bytes: the system's ``MemAvailable`` (else
    psutil), or less where the process's address-space limit (``RLIMIT_AS``) leaves less;
    ``None`` when unknown."""
    known = [v for v in (_system_available_bytes(), _address_space_left()) if v is not None]
    return min(known) if known else None


def check_memory(need_bytes: float, *, what: str) -> None:
    """Refuse (:class:`ResourceLimitError`) when ``need_bytes`` exceed the available memory."""
    avail = available_memory_bytes()
    if avail is not None and need_bytes > SAFETY_FRACTION * avail:
        raise ResourceLimitError(f"{what}: needs about {format_bytes(need_bytes)} of memory, "
                                 f"{format_bytes(avail)} available")


def announce_size(need_bytes: float, *, where: str | os.PathLike,
                  echo: Callable[[str], None] | None = None, threshold: float = ANNOUNCE_BYTES) -> None:
    """Say (stderr by default) how much will be written to ``where`` when it is large."""
    if need_bytes >= threshold:
        say = echo or (lambda msg: print(msg, file=sys.stderr))
        say(f"writing about {format_bytes(need_bytes)} to {where}")


#: memory one worker needs once it has imported numpy, scipy and numba and holds its chunk
#: (measured on spawned workers: 150-250 MiB resident on the default scenarios; a forked
#: one shares its parent's pages until it writes them); a lower bound
WORKER_BYTES = 200 * 1024 * 1024


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity)."""
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1))


def cap_workers(requested: int, *, tasks: int | None = None, option: str = "--workers",
                echo: Callable[[str], None] | None = None, quiet: bool = False) -> int:
    """The number of worker processes to start for ``requested``: at most the usable
    cores, the number of tasks (when known), and what the available memory holds at
    :data:`WORKER_BYTES` each; at least 1. A capped request is said in one line on
    stderr (unless ``quiet``). Results never depend on the worker count, so capping
    only avoids starting processes that would wait (``--workers 1000`` started 186
    processes and took 5.9 GB in 13 s before this).
    """
    n = max(1, int(requested))
    limits = [(usable_cores(), "the cores this process may use")]
    if tasks is not None:
        limits.append((max(1, int(tasks)), "the tasks to run"))
    avail = available_memory_bytes()
    if avail is not None:
        limits.append((max(1, int(SAFETY_FRACTION * avail // WORKER_BYTES)),
                       f"what {format_bytes(avail)} of available memory holds at {format_bytes(WORKER_BYTES)} each"))
    cap, why = min(limits, key=lambda t: t[0])
    if n <= cap:
        return n
    if not quiet:
        say = echo or (lambda msg: print(msg, file=sys.stderr))
        say(f"note: {option} {requested}: using {cap} ({why})")
    return cap


# ----------------------------------------------------------------------------- progress
def progress(*, total: int | None, desc: str, unit: str = "it", enabled: bool = True):
    """A tqdm bar on stderr when it is a terminal (and ``enabled``); a silent one otherwise.

    Use as ``with progress(total=n, desc="frames") as bar: ... bar.update(1)``.
    """
    from tqdm import tqdm

    on = bool(enabled) and sys.stderr.isatty()
    return tqdm(total=total, desc=desc, unit=unit, leave=False, disable=not on, file=sys.stderr)
