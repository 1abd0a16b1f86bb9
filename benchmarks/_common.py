"""Shared helpers of the benchmark scripts: machine description, best-of-N timer, table.

Run the scripts from the repository root, e.g. ``python benchmarks/bench_detector_noise.py``
or ``python -m benchmarks.bench_detector_noise``, or all of them through
``python benchmarks/run_all.py``, which writes ``docs/benchmarks.md`` from the
``RESULT {json}`` line that each script prints last (see :func:`emit_result`).

What every script shares comes from here: the argument parser with ``--quick``
(:func:`bench_parser`), the machine line (:func:`print_machine`), timers, the table, the
figures and the RESULT line. The only lines a script repeats are the two that put the
repository root on ``sys.path`` when it runs as a file (``if not __package__: ...``), since
this module cannot be imported before them.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
import tracemalloc
from collections.abc import Callable, Sequence
from pathlib import Path

__all__ = ["machine_description", "print_machine", "best_of", "best_of_wall_cpu", "peak_traced_mb",
           "format_table", "add_quick_flag", "bench_parser", "figure", "emit_result",
           "optional_import", "RESULT_PREFIX", "REPO_ROOT"]

#: The repository root (the folder holding ``benchmarks/``, ``tests/``, ``docs/``).
REPO_ROOT = Path(__file__).resolve().parent.parent

#: Prefix of the one machine-readable line a benchmark prints last (parsed by run_all.py).
RESULT_PREFIX = "RESULT "


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_description() -> dict[str, str]:
    """CPU model, logical cores (and those usable by this process), load, versions."""
    import numpy

    info = {
        "cpu": _cpu_model(),
        "cores": str(os.cpu_count()),
        "usable_cores": str(len(os.sched_getaffinity(0))) if hasattr(os, "sched_getaffinity")
        else str(os.cpu_count()),
        "python": platform.python_version(),
        "numpy": numpy.__version__,
    }
    try:
        import numba

        info["numba"] = numba.__version__
        info["numba_threads"] = str(numba.get_num_threads())
    except ImportError:  # pragma: no cover - numba is a dependency
        info["numba"] = "absent"
    try:
        info["load_1_5_15min"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:  # pragma: no cover
        pass
    return info


def print_machine(**extra: object) -> None:
    """Print the ``machine: k=v, ...`` line of :func:`machine_description`, then ``extra``
    (e.g. the versions of the peers a benchmark measured)."""
    info = machine_description() | {k: str(v) for k, v in extra.items()}
    print("machine: " + ", ".join(f"{k}={v}" for k, v in info.items()), flush=True)


def best_of(fn: Callable[[], object], *, repeat: int = 5,
            warmup: int = 1) -> tuple[float, list[float]]:
    """Call ``fn`` ``warmup`` times untimed, then ``repeat`` times; return (best s, all s)."""
    if repeat < 1:
        raise ValueError(f"repeat: must be >= 1 (got {repeat})")
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times), times


def best_of_wall_cpu(fn: Callable[[], object], *, repeat: int = 5,
                     warmup: int = 1) -> tuple[float, float]:
    """Best wall-clock time and best process CPU time (all threads) of ``fn``, s.

    On a machine shared with other jobs the CPU time is the steadier measure of the
    work done; wall time is what a user waits.
    """
    if repeat < 1:
        raise ValueError(f"repeat: must be >= 1 (got {repeat})")
    for _ in range(warmup):
        fn()
    walls, cpus = [], []
    for _ in range(repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
    return min(walls), min(cpus)


def peak_traced_mb(fn: Callable[[], object]) -> float:
    """Peak Python/numpy heap allocated while ``fn`` runs (tracemalloc), in MB (1e6 B).

    numpy reports its array buffers to tracemalloc, so this counts the temporaries of
    a numpy pipeline and the output arrays of a numba one (numba kernels that allocate
    nothing inside add nothing).
    """
    was = tracemalloc.is_tracing()
    if not was:
        tracemalloc.start()
    tracemalloc.reset_peak()
    base, _ = tracemalloc.get_traced_memory()
    result = fn()
    _, peak = tracemalloc.get_traced_memory()
    del result
    if not was:
        tracemalloc.stop()
    return (peak - base) / 1e6


def format_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """Plain-text table with right-aligned columns."""
    cells = [[str(h) for h in headers]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def add_quick_flag(ap: argparse.ArgumentParser) -> None:
    """Add ``--quick``: a smoke run with fewer repeats/trials (figures not meaningful)."""
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: fewer repeats and trials (timings not meaningful)")


def bench_parser(doc: str) -> argparse.ArgumentParser:
    """The parser of a benchmark script: described by its docstring's first line, with
    ``--quick`` (:func:`add_quick_flag`) already added."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    add_quick_flag(ap)
    return ap


def optional_import(name: str):
    """Import an optional peer library; ``None`` when it is not installed.

    Only a missing module counts as "not installed"; any other import error propagates.
    """
    import importlib

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and name.split(".")[0] != exc.name.split(".")[0]:
            # the peer is installed but one of its own dependencies is missing
            print(f"note: {name} is installed but cannot be imported: {exc}")
        return None


def figure(key: str, what: str, ours: float | None, unit: str, *, better: str = "lower",
           peer: str | None = None, peer_value: float | None = None,
           peer_status: str | None = None, target: float | None = None,
           target_source: str | None = None) -> dict:
    """One key figure of a benchmark for the summary table of ``docs/benchmarks.md``.

    Parameters
    ----------
    key : str
        Stable identifier (e.g. ``"cog_us"``).
    what : str
        Human description, with the inputs.
    ours : float or None
        Our measured value, in ``unit``.
    unit : str
        Unit of ``ours``, ``peer_value`` and ``target`` (``"ms"``, ``"windows/s"``...).
    better : {"lower", "higher"}
        Whether a lower (a time, memory) or a higher (a rate, a speed-up) value is better;
        sets the sense of the ratio and of the target.
    peer, peer_value : str, float, optional
        The peer measured in the same run and its value in ``unit``.
    peer_status : str, optional
        Why there is no peer value (e.g. ``"not installed"``).
    target, target_source : float, str, optional
        The issue's target in ``unit`` and where it is stated (``"project target"``).
    """
    if better not in ("lower", "higher"):
        raise ValueError(f"better: must be 'lower' or 'higher' (got {better!r})")

    def clean(v):
        return None if v is None or not math.isfinite(float(v)) else float(v)

    return {"key": key, "what": what, "ours": clean(ours), "unit": unit, "better": better,
            "peer": peer, "peer_value": clean(peer_value), "peer_status": peer_status,
            "target": clean(target), "target_source": target_source}


def emit_result(bench: str, figures: Sequence[dict], *, quick: bool = False,
                **extra: object) -> None:
    """Print the final machine-readable line: ``RESULT {json}`` (one line, parsed by run_all).

    ``extra`` holds further named values (versions of the peers, settings).
    """
    payload = {"bench": bench, "quick": bool(quick), "figures": list(figures), **extra}
    print(RESULT_PREFIX + json.dumps(payload, sort_keys=False), flush=True)
