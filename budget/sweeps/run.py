"""Design-trade sweeps: many Monte Carlo validations, labelled, resumable, scaled out.

``budget sweep SWEEP.toml --out STORE`` reads a sweep file (:mod:`budget.sweeps.spec`),
checks every point before any work, and runs each point's evaluation
(:mod:`budget.sweeps.evaluate`: the Monte Carlo validation, or the fast truth-only mode) on
local processes (default: all cores), an existing Dask cluster (``--scheduler``) or a
Dask LocalCluster (``--dask-local N``) (:mod:`budget.sweeps.execute`). Each point is written
to the Zarr store as it finishes (:mod:`budget.sweeps.store`); running the same command
again computes only the points not yet done. A ``[sensitivity]`` table adds Sobol
indices (:mod:`budget.sweeps.sensitivity`). ``budget plot STORE`` draws the results
(:mod:`budget.sweeps.plot`). See ``docs/sweeps.md``.

Python API::

    from budget.sweeps.run import run_sweep, open_sweep
    report = run_sweep("docs/examples/sweeps/hsfe_psf_prnu.toml", "out/hsfe", workers=2)
    ds = open_sweep("out/hsfe")          # xarray.Dataset, parameters as dimensions
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import click
import numpy as np

import simcam
from budget.runner.capabilities import SplitTruths, Warmup, capability
from budget.runner.numbers import fmt
from budget.runner.scheduler import with_targets
from budget.runner.study import truth_identity
from budget.sweeps.evaluate import PointTask, TruthPartTask, truth_seed_of, truths_scenario
from budget.sweeps.execute import make_runner
from budget.sweeps.layout import study_for_kind
from budget.sweeps.sensitivity import analyze_samples
from budget.sweeps.spec import Sweep, load_sweep
from budget.sweeps.store import (StoreWriter, check_store, create_store, open_sensitivity, open_sobol, open_sweep,
                                 store_lock)
from simcam.infra.errors import UserInputError, WorkersLost

__all__ = [
    "SweepReport",
    "load_sweep",
    "open_sensitivity",
    "open_sobol",
    "open_sweep",
    "plan_tasks",
    "point_task",
    "run_sweep",
    "share_truths",
    "sweep_command",
]


@dataclass
class SweepReport:
    """What a run did."""

    store: str
    sweep_hash: str
    runner: str
    points: int
    already_done: int
    computed: int
    samples: int = 0
    samples_already_done: int = 0
    samples_computed: int = 0
    sobol: bool = False
    truths_computed: int = 0  # distinct truths computed for the points of this run (shared)
    wall_s: float = 0.0
    compute_s: list = field(default_factory=list)
    cpu_s: list = field(default_factory=list)
    completed: list = field(default_factory=list)  # (group, index, t since start, pid) per point

    @property
    def points_per_s(self) -> float:
        n = self.computed + self.samples_computed
        return n / self.wall_s if self.wall_s > 0 else float("nan")


def point_task(sweep: Sweep, group: str, index: int) -> PointTask:
    """The task of point ``index`` of ``group`` (``"grid"`` or ``"sensitivity"``), with its
    truth seed (:func:`budget.sweeps.evaluate.truth_seed_of`); the point is built now."""
    s = sweep.spec
    if group == "grid":
        p = sweep.points[index]
        return PointTask("grid", p.index, s.kind, s.evaluate, p.scenario, p.seed, s.trials, s.tolerance,
                         truth_seed_of(study_for_kind(s.kind), p.scenario, s.seed, p.values, p.seed, common=False))
    t = s.sensitivity
    p = sweep.sample_points[index]
    return PointTask("sensitivity", p.index, s.kind, t.evaluate, p.scenario, p.seed, t.trials, t.tolerance, p.seed)


def plan_tasks(sweep: Sweep) -> tuple[list, list]:
    """Point tasks of the grid and of the Sobol samples, each with its truth seed (every
    point built: small sweeps and tests; a run builds them window by window)."""
    return ([point_task(sweep, "grid", i) for i in range(len(sweep.points))],
            [point_task(sweep, "sensitivity", i) for i in range(len(sweep.sample_points))])


#: points built, sent and written at a time: about this many per worker (at least
#: :data:`WINDOW_MIN`); the next window is built once the last one's tasks are all sent
WINDOW_PER_WORKER = 8
WINDOW_MIN = 16


#: a shared truth's pieces run as about this many tasks per worker (runs of consecutive pieces)
TRUTH_TASKS_PER_WORKER = 8


def share_truths(runner, tasks: list, *, share: bool = True, cache: dict | None = None) -> tuple[list, int]:
    """The tasks with their truths (``PointTask.truths``), each distinct truth computed once.

    Points whose truth-relevant fields (:func:`budget.runner.study.truth_identity`), truth
    seed and truth sizing are equal share one truth; its pieces (:meth:`~budget.runner.capabilities.SplitTruths.truth_parts`)
    run as tasks on ``runner``'s workers, in runs of consecutive pieces (about
    :data:`TRUTH_TASKS_PER_WORKER` tasks per worker in all). ``share=False`` computes one per point (the same
    numbers: tests). ``cache``: the truths of earlier calls by key (a streaming run's
    windows), reused and completed. Returns the tasks and the number of truths computed.
    """
    if not tasks:
        return tasks, 0
    study = study_for_kind(tasks[0].kind)
    cache = {} if cache is None else cache
    groups: dict = {}
    keys = []
    for t in tasks:
        size = t.tolerance if t.evaluate == "validate" else None
        key = (truth_identity(study, t.scenario), t.truth_seed, size)
        if not share:
            key += (t.group, t.index)
        if key not in groups and key not in cache:
            scn, targets = truths_scenario(study, t)
            groups[key] = (len(groups), scn, targets, capability(study, SplitTruths).truth_parts(scn, t.truth_seed), t.truth_seed)
        keys.append(key)
    # the pieces in runs of consecutive pieces of one truth, about TRUTH_TASKS_PER_WORKER runs
    # per worker in all: a task per piece would be thousands of tasks of milliseconds (16 camera
    # points x 65 pieces), whose scheduling and scenario pickling a Dask scheduler pays per task
    n_pieces = sum(len(parts) for _, _, _, parts, _ in groups.values())
    run_len = max(1, math.ceil(n_pieces / (TRUTH_TASKS_PER_WORKER * max(1, runner.workers))))
    part_tasks = [TruthPartTask(g, j, tasks[0].kind, scn, seed, tuple(parts[j:j + run_len]))
                  for g, scn, _, parts, seed in groups.values() for j in range(0, len(parts), run_len)]
    got: dict = {}
    for res in runner.run(part_tasks):
        for k, part in enumerate(res.parts):
            got.setdefault(res.group, {})[res.index + k] = part
    for key, (g, scn, targets, parts, seed) in groups.items():
        t = capability(study, SplitTruths).truths_from_parts(scn, seed, [got[g][j] for j in range(len(parts))])
        cache[key] = with_targets(t, targets) if targets else t
    return [replace(t, truths=cache[k]) for t, k in zip(tasks, keys)], len(groups)


def run_sweep(sweep: Sweep | str | Path, out: str | Path, *, workers: int | None = None,
              scheduler: str | None = None, dask_local: int | None = None, inline: bool = False,
              progress: bool = False, on_point: Callable | None = None,
              echo: Callable[[str], None] | None = None, truths_shared: bool = True) -> SweepReport:
    """Run (or resume) a sweep into the store ``out``.

    Parameters
    ----------
    sweep : Sweep or path of a sweep file
    out : path of the Zarr store (created, or resumed if it holds this sweep)
    workers : local processes (default: all cores)
    scheduler : address of an existing Dask scheduler (``tcp://host:port``)
    dask_local : start a Dask LocalCluster of this many single-threaded workers
    inline : run the points in this process (tests, debugging)
    progress : show a progress bar (stderr)
    on_point : called as ``on_point(group, index)`` after each point is written (hook)
    echo : where to print one-line messages (default: nowhere)
    truths_shared : compute each distinct truth once for the points that share it
        (:func:`share_truths`); False: one per point (the same numbers, more work)

    Raises
    ------
    ScenarioError, UserInputError
        Before any work: bad sweep file, a point the scenario or simulator rejects, a
        store of another sweep or held by another run (:func:`~budget.sweeps.store.store_lock`),
        an unreachable scheduler.
    WorkersLost
        A killed worker, a Dask cluster without workers: the points finished stay in the store.
    """
    say = echo or (lambda _msg: None)
    with store_lock(out):  # one writer of a store at a time (refused before the sweep is read)
        sw = sweep if isinstance(sweep, Sweep) else load_sweep(sweep)
        try:
            return _run_locked(sw, out, workers=workers, scheduler=scheduler, dask_local=dask_local,
                               inline=inline, progress=progress, on_point=on_point, say=say,
                               truths_shared=truths_shared)
        except WorkersLost as exc:  # each point is written as it finishes: the store resumes
            raise WorkersLost(f"{exc}; the points finished are kept in {out}: the same command "
                              f"computes the rest") from None


def _run_locked(sw: Sweep, out, *, workers, scheduler, dask_local, inline, progress, on_point, say,
                truths_shared) -> SweepReport:
    """:func:`run_sweep` once the store is held: the points not yet done, window by window
    (:func:`_windows`), each window's truths shared and its points written as they finish."""
    n_grid, n_sens = len(sw.points), len(sw.sample_points)
    state = check_store(out, sw)
    runner = make_runner(kind=sw.spec.kind, workers=workers, scheduler=scheduler, dask_local=dask_local,
                         inline=inline)
    t0 = time.perf_counter()
    report = SweepReport(store=str(out), sweep_hash=sw.hash, runner=runner.description,
                         points=n_grid, already_done=0, computed=0, samples=n_sens)
    with runner:
        if state == "new":
            create_store(out, sw)
        writer = StoreWriter(out, sw)
        # a new store has nothing done (reading a flag per point of a 1,000,000-point store
        # reads as many chunk files); a resumed one reads its flags
        todo = {g: (np.arange(n) if state == "new" else np.flatnonzero(~writer.done(g))) if n else np.zeros(0, int)
                for g, n in (("grid", n_grid), ("sensitivity", n_sens))}
        report.already_done = n_grid - todo["grid"].size
        report.samples_already_done = n_sens - todo["sensitivity"].size
        say(f"{sw.spec.name or sw.path} (hash {sw.hash}): {n_grid} point(s)"
            + (f", {n_sens} Sobol sample(s)" if n_sens else "")
            + (f"; resuming: {report.already_done + report.samples_already_done} already in {out}"
               if state == "resume" else "") + f"; on {runner.description}")
        first = next((point_task(sw, g, int(todo[g][0])) for g in ("grid", "sensitivity") if todo[g].size), None)
        if scheduler is None and first is not None:
            # a first run's kernels compiled once on this machine's cores, before the workers
            # need them (each point then loads them from numba's cache)
            capability(study_for_kind(sw.spec.kind), Warmup).prewarm(first.scenario)
        cache: dict = {}
        shared_points = 0
        for label, group in (("points", "grid"), ("Sobol samples", "sensitivity")):
            if not todo[group].size:
                continue
            bar = None
            if progress:
                from tqdm import tqdm

                bar = tqdm(total=todo[group].size, desc=label, unit="pt", leave=False,
                           disable=not sys.stderr.isatty())  # quiet when not on a terminal
            try:
                for window in _windows(todo[group], runner.workers):
                    tasks = [point_task(sw, group, int(i)) for i in window]
                    tasks, n_truths = share_truths(runner, tasks, share=truths_shared, cache=cache)
                    report.truths_computed += n_truths
                    shared_points += len(tasks)
                    _forget_oldest(cache, TRUTHS_KEPT)
                    for res in runner.run(tasks):
                        _write_result(writer, res, report, t0)
                        if bar:
                            bar.update(1)
                        if on_point is not None:
                            on_point(res.group, res.index)
            finally:
                if bar:
                    bar.close()
        if report.truths_computed < shared_points:
            say(f"truths shared: {report.truths_computed} distinct truth(s) for {shared_points} point(s)")
        if n_sens and not writer.sobol_complete():
            writer.write_sobol(analyze_samples(open_sensitivity(out), sw))
            report.sobol = True
    report.wall_s = time.perf_counter() - t0
    return report


#: distinct truths kept for the windows that follow (a streaming run's memory stays flat)
TRUTHS_KEPT = 256


def _forget_oldest(cache: dict, keep: int) -> None:
    while len(cache) > keep:
        cache.pop(next(iter(cache)))


def _windows(indices: np.ndarray, workers: int):
    """``indices`` in consecutive windows: the first of one point per worker (the first
    points written soon), each next twice the last, up to ``max(WINDOW_MIN,
    WINDOW_PER_WORKER x workers)``."""
    most = max(WINDOW_MIN, WINDOW_PER_WORKER * max(1, workers))
    size, lo = max(1, workers), 0
    while lo < indices.size:
        yield indices[lo:lo + size]
        lo += size
        size = min(most, 2 * size)


def _write_result(writer, res, report: SweepReport, t0: float) -> None:
    """One finished point into the store and the report."""
    if res.version != simcam.__version__:
        raise UserInputError(
            f"a worker ({res.host}, pid {res.pid}) runs simcam {res.version}, this client "
            f"{simcam.__version__}: install the same version on every worker")
    writer.write(res)
    report.compute_s.append(float(res.values["compute_s"]))
    report.cpu_s.append(res.cpu_s)
    report.completed.append((res.group, res.index, time.perf_counter() - t0, res.pid))
    if res.group == "grid":
        report.computed += 1
    else:
        report.samples_computed += 1


# --------------------------------------------------------------------------- CLI
@click.command("sweep")
@click.argument("sweep_file", type=click.Path(dir_okay=False))
@click.option("--out", "out", required=True, type=click.Path(),
              help="Zarr store of the results (created, or resumed when it holds this sweep).")
@click.option("--workers", type=int, default=None, help="Local worker processes (default: all cores).")
@click.option("--scheduler", default=None, help="Send the points to an existing Dask scheduler, tcp://HOST:PORT.")
@click.option("--dask-local", "dask_local", type=int, default=None,
              help="Start a Dask LocalCluster of N single-threaded workers.")
@click.option("--progress/--no-progress", default=True, show_default=True, help="Progress bar on stderr.")
def sweep_command(sweep_file, out, workers, scheduler, dask_local, progress) -> None:
    """Run the design-trade sweep SWEEP_FILE into the store --out (resumable; docs/sweeps.md)."""
    rep = run_sweep(sweep_file, out, workers=workers, scheduler=scheduler, dask_local=dask_local,
                    progress=progress, echo=click.echo)
    n = rep.computed + rep.samples_computed
    click.echo(f"{n} point(s) computed in {rep.wall_s:.1f} s"
               + (f" ({rep.points_per_s:.2f} points/s)" if n else "")
               + f"; store: {out} (xarray.open_zarr, or budget plot {out})")
    sob = open_sobol(out) if rep.samples else None
    if sob is not None:
        sel = {d: sob[d].values[0] for d in sob.S1.dims if d not in ("class", "parameter")}
        click.echo(f"Sobol indices ({sob.attrs['output']}, {int(sob.attrs['conf_level'] * 100)} % intervals"
                   + "".join(f", {d} {v}" for d, v in sel.items()) + "):")
        s1, st = sob.S1.sel(sel), sob.ST.sel(sel)
        s1c, stc = sob.S1_conf.sel(sel), sob.ST_conf.sel(sel)
        notes = sob.note.sel(sel)
        skipped = [f"{c} ({notes.sel({'class': c}).item()})" for c in s1["class"].values
                   if notes.sel({"class": c}).item()]
        for cls in s1["class"].values:
            if notes.sel({"class": cls}).item():
                continue
            cells = []
            for p in s1.parameter.values:
                a = dict(**{"class": cls}, parameter=p)
                cells.append(f"{p}: S1 {fmt(float(s1.sel(a)), 3)} +- {fmt(float(s1c.sel(a)), 3)}, "
                             f"ST {fmt(float(st.sel(a)), 3)} +- {fmt(float(stc.sel(a)), 3)}")
            click.echo(f"  {cls:>12s}  " + "; ".join(cells))
        if skipped:
            click.echo("  no indices: " + "; ".join(skipped))
