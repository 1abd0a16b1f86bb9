"""Faults, round three (issue #35, part two; docs/reliability.md, "Bounded waiting and size"
and "Interruption without noise").

* Workers: a pool that breaks after the caller cancelled queued tasks prints no thread
  traceback (the race behind ``InvalidStateError: CANCELLED`` on SIGINT, reproduced
  deterministically); ``kill -9`` of one local worker is one line and exit status 3; a
  signal mid-run is one line (the default suite once; loops behind ``slow`` catch the
  1-in-5 race the issue saw).
* Dask: a wrong scheduler address is refused in seconds; a cluster killed whole, or whose
  workers are all killed, mid-run ends the command within 60 s in one line, and a sweep's
  store resumes to the uninterrupted result (``slow``: a real scheduler and two workers).
* One writer per sweep store: a second ``budget sweep`` of a held store is refused in one
  line; two runs that both created the store resume it.
* Allocation estimates from the scenario (:mod:`simcam.allocation`), against the
  simulator's own tables and analytic formulas, and the refusals naming the field.
"""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from test_reliability import (GRID, _all_gone, _cli, _pool_workers, _run_until_workers, _start, _stop,
                              _wait_for)
from tiny_camera import TINY

REPO = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------------- pools
def _sleep(s):
    time.sleep(s)
    return s


def _broken_pool_thread_errors(quiet: bool) -> list[str]:
    """Ten tasks on two workers, the seven queued ones cancelled (as an interrupted
    ``map_unordered`` does), then the workers ended: the exceptions the pool's manager thread
    raised (Python 3.11's pool calls ``set_exception`` on the cancelled futures:
    ``InvalidStateError: CANCELLED``), with :func:`simcam.infra.lifecycle.quiet_pool_breakage`
    applied or not."""
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    from simcam.infra.lifecycle import quiet_pool_breakage

    seen: list = []
    previous = threading.excepthook
    threading.excepthook = lambda a: seen.append(type(a.exc_value).__name__)
    try:
        pool = ProcessPoolExecutor(2, mp_context=mp.get_context("fork" if sys.platform == "linux" else "spawn"))
        fs = [pool.submit(_sleep, 30) for _ in range(10)]
        _wait_for(lambda: sum(f.running() for f in fs) >= 2, 60, what="two tasks running")
        assert sum(f.cancel() for f in fs) >= 5  # those beyond the pool's call queue
        if quiet:
            quiet_pool_breakage(pool)
        for p in pool._processes.values():
            p.terminate()
        _wait_for(lambda: all(f.done() for f in fs), 30, what="every future done")
        pool.shutdown(wait=True)
    finally:
        threading.excepthook = previous
    return seen


def test_a_pool_broken_after_cancels_prints_no_thread_traceback():
    """The race first without the fix (the control: it must reproduce, else the fixed case
    proves nothing and the test skips, saying so; on a loaded machine the manager thread can
    see the workers' end before the cancellations), then with it: no thread traceback."""
    control = _broken_pool_thread_errors(quiet=False)
    if control != ["InvalidStateError"]:
        pytest.skip(f"the pool's race did not reproduce on this machine (thread errors {control}): "
                    "the quiet case would prove nothing")
    assert _broken_pool_thread_errors(quiet=True) == []


def test_killed_local_worker_is_one_line_and_status_3(tmp_path):
    """``kill -9`` of one worker of ``budget validate --workers 2``: one line naming the
    worker and its signal, exit status 3, no child left, nothing written."""
    (tmp_path / "tiny.toml").write_text(TINY)
    proc, log, kids = _run_until_workers(
        ["budget", "validate", "tiny.toml", "--trials", "100000", "--workers", "2", "--no-progress",
         "--json", "v.json"], tmp_path, 1, "its worker")
    victim = _pool_workers(proc.pid)[0]
    victim.kill()
    try:
        rc = proc.wait(60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    err = log.read_text()
    assert rc == 3, err
    assert re.fullmatch(rf"error: a worker process ended abruptly \(pid {victim.pid}, killed by SIGKILL\); the run "
                        r"stopped and its workers were ended \(.*\)\n", err), err
    assert _all_gone(kids, 10)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["err.txt", "tiny.toml"]


#: the long commands, each started on the tiny camera and signalled once its pool works
SIGNALLED = {
    "validate": (["budget", "validate", "tiny.toml", "--trials", "100000", "--workers", "2", "--no-progress"],
                 signal.SIGINT),
    "robustness": (["budget", "starcam", "robustness", "tiny.toml", "--trials", "100000", "--workers", "2",
                    "--no-progress"], signal.SIGINT),
    "plan": (["budget", "starcam", "plan", "tiny.toml", "--require", "te.x<=0.001", "--trials", "100000",
              "--workers", "2"], signal.SIGINT),
    "sweep": (["budget", "sweep", "sweep.toml", "--out", "store", "--workers", "2", "--no-progress"],
              signal.SIGTERM),
}


def _signal_mid_run(tmp_path: Path, name: str) -> None:
    args, sig = SIGNALLED[name]
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    proc, log, kids = _run_until_workers(args, tmp_path, 1, "its worker")
    time.sleep(1.0)  # tasks queued and running: the state in which the race happened
    rc = _stop(proc, sig)
    err = log.read_text()
    assert rc == 128 + sig, err
    assert err.strip().splitlines()[-1:] == [f"interrupted ({signal.Signals(sig).name})"], err
    assert "Traceback" not in err and "Exception in thread" not in err, err
    assert _all_gone(kids, 10)


def test_sigint_mid_validate_is_one_line(tmp_path):
    """The fast version of the loops below: once."""
    _signal_mid_run(tmp_path, "validate")


@pytest.mark.slow
@pytest.mark.parametrize("name", list(SIGNALLED))
@pytest.mark.parametrize("repeat", range(6))
def test_signal_mid_run_is_one_line_every_time(tmp_path, name, repeat):
    """The issue saw the thread traceback once in 5-6 runs of each: six runs each (a race
    of probability 1/5 escapes six runs with probability (4/5)^6 = 0.26 per command, all
    four with 0.005; the deterministic test above is the proof, these the regression net)."""
    _signal_mid_run(tmp_path, name)


# ----------------------------------------------------------------------------- Dask
@pytest.mark.parametrize("address, says", [
    ("tcp://127.0.0.1:1", "cannot connect to 127.0.0.1:1 (Connection refused); is a Dask scheduler running there?"),
    ("tcp://nosuchhost.invalid:8786", "unknown host nosuchhost.invalid"),
    ("tcp://127.0.0.1", "give the port too"),
])
def test_a_wrong_scheduler_address_is_refused_in_seconds(address, says):
    from budget.runner.executors import make_executor
    from simcam.infra.errors import UserInputError

    t0 = time.monotonic()
    with pytest.raises(UserInputError) as err:
        with make_executor(scheduler=address):
            pass
    assert time.monotonic() - t0 < 10.0  # was 21 s (Dask's connect timeout)
    assert str(err.value).startswith(f"--scheduler {address}: ") and says in str(err.value)
    assert "\n" not in str(err.value)


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_cluster(tmp_path: Path, n_workers: int = 2):
    """A scheduler and ``n_workers`` single-threaded ``dask worker`` processes (with their
    nannies), each in its own session; returns (address, scheduler, workers)."""
    port = _free_port()
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    kw = dict(cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    sched = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--port", str(port),
                              "--no-dashboard", "--host", "127.0.0.1"], **kw)
    address = f"tcp://127.0.0.1:{port}"
    workers = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads", "1",
                                 "--no-dashboard"], **kw) for _ in range(n_workers)]

    def ready() -> bool:
        from distributed import Client

        try:
            with Client(address, timeout="2s") as c:
                return len(c.nthreads()) >= n_workers
        except (OSError, TimeoutError):
            return False

    _wait_for(ready, 120, sched, f"{n_workers} workers at {address}")
    return address, sched, workers


def _kill_session(p: subprocess.Popen) -> None:
    try:
        os.killpg(p.pid, signal.SIGKILL)  # the worker's nanny and its worker process
    except ProcessLookupError:
        pass
    p.wait()


@pytest.mark.slow
@pytest.mark.parametrize("whole", [True, False])
def test_a_dask_cluster_killed_mid_sweep_ends_in_one_line_and_the_store_resumes(tmp_path, grid_ref, whole):
    """The issue's check: a local scheduler and two workers, killed whole (or the workers
    only: the run then waits NO_WORKER_GRACE_S = 10 s for one to come back) once a point
    is written: the sweep ends within 60 s with one line and exit status 3; the store
    keeps its points and resumes to the uninterrupted result, bit for bit."""
    from budget.sweeps.run import open_sweep, run_sweep

    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    address, sched, workers = _dask_cluster(tmp_path)
    try:
        log = tmp_path / "err.txt"
        proc = _start(["budget", "sweep", "sweep.toml", "--out", "store", "--scheduler", address, "--no-progress"],
                      tmp_path, log)
        _wait_for(lambda: _points_done(tmp_path / "store") >= 1, 240, proc, "a point written")
        t0 = time.monotonic()
        for w in workers:
            _kill_session(w)
        if whole:
            _kill_session(sched)
        try:
            rc = proc.wait(60)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
        took = time.monotonic() - t0
    finally:
        for p in (*workers, sched):
            _kill_session(p)
    err = log.read_text().strip().splitlines()
    assert rc == 3 and len(err) == 1 and err[0].startswith(f"error: --scheduler {address}: "), err
    assert "the points finished are kept in store: the same command computes the rest" in err[0], err
    assert took < 60.0
    run_sweep(str(tmp_path / "sweep.toml"), tmp_path / "store", inline=True)
    ds = open_sweep(tmp_path / "store")
    for v in ("truth", "truth_se", "seed", "done"):
        np.testing.assert_array_equal(ds[v].values, grid_ref[v].values)


def _points_done(store: Path) -> int:
    import zarr

    try:
        return int(np.sum(zarr.open_group(str(store), mode="r")["done"][...]))
    except Exception:  # noqa: BLE001 - not created yet, or being created
        return 0


@pytest.fixture(scope="module")
def grid_ref(tmp_path_factory):
    from budget.sweeps.run import open_sweep, run_sweep

    d = tmp_path_factory.mktemp("ref")
    (d / "tiny.toml").write_text(TINY)
    (d / "sweep.toml").write_text(textwrap.dedent(GRID))
    run_sweep(str(d / "sweep.toml"), d / "store", inline=True)
    return open_sweep(d / "store")


# ----------------------------------------------------------------------------- one writer per store
def test_a_store_held_by_another_run_is_refused_in_one_line(tmp_path, monkeypatch):
    """A second ``budget sweep ... --out store`` while the first holds it (was: ``OSError:
    Directory not empty`` from one of the two). The lock is an ``flock``: two opens of the
    file conflict even in one process, so the test holds it here."""
    from budget.sweeps.store import lock_path, store_lock

    monkeypatch.chdir(tmp_path)
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    with store_lock("store"):
        assert lock_path("store").read_text() == f"{os.getpid()}\n"
        code, err = _cli("budget", ["sweep", "sweep.toml", "--out", "store", "--workers", "1", "--no-progress"])
    assert code == 2, err
    assert err.splitlines() == [f"error: --out store: another budget sweep (pid {os.getpid()}) is writing this "
                                f"store (it holds .store.lock); wait for it to end, or give another --out"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep.toml", "tiny.toml"]  # lock removed, no store


def test_two_runs_that_both_create_a_store_share_it(tmp_path):
    """Where no lock could be taken (the store's folder did not exist yet), the second
    creation resumes the store the first renamed into place instead of failing."""
    from budget.sweeps.spec import load_sweep
    from budget.sweeps.store import check_store, create_store

    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    sw = load_sweep(tmp_path / "sweep.toml")
    out = tmp_path / "sub" / "store"
    assert check_store(out, sw) == "new"
    create_store(out, sw)
    create_store(out, sw)  # the other run's: ENOTEMPTY on its rename, then resumed
    assert check_store(out, sw) == "resume"
    assert sorted(p.name for p in out.parent.iterdir()) == ["store"]


# ----------------------------------------------------------------------------- allocation estimates
@pytest.mark.parametrize("sigma_px, stamp_px", [(0.8, 32), (0.05, 16), (0.01, 8)])
def test_psf_support_agrees_with_the_simulator_and_the_gaussian_otf(sigma_px, stamp_px):
    """The frequency extent solves ``exp(-2 pi^2 sigma^2 rho^2) = eps`` (scipy's brentq on
    the OTF itself, an independent route); the table entries are those of the simulator's
    own :func:`simcam.starcam.psf_transfer.radial_tables` (the peer that allocates them)."""
    from scipy.optimize import brentq

    from simcam import allocation
    from simcam.starcam import psf_stamps, psf_transfer

    assert allocation.SPECTRUM_EPS == psf_stamps.SPECTRUM_EPS
    rho = brentq(lambda r: math.exp(-2 * math.pi ** 2 * sigma_px ** 2 * r * r) - allocation.SPECTRUM_EPS,
                 0.0, 100.0 / sigma_px, xtol=1e-12, rtol=1e-14)
    assert allocation.psf_frequency_extent_cyc_per_px(sigma_px) == pytest.approx(rho, rel=1e-12)
    qmax = psf_transfer.freq_extent_cyc_per_px(np.array([sigma_px]), np.ones((1, 1)), np.zeros(1), False,
                                               -math.log(psf_stamps.SPECTRUM_EPS)) * stamp_px
    _chat, disc = psf_transfer.radial_tables(qmax, np.zeros(1), np.zeros(1), False, stamp_px)
    table = allocation.psf_support_bytes(sigma_px=sigma_px, stamp_px=stamp_px)
    assert table == 8.0 * allocation.PSF_TABLE_ARRAYS * disc.shape[1]
    k = math.floor(qmax[0])
    assert allocation.psf_support_bytes(sigma_px=sigma_px, stamp_px=stamp_px, profile_route=True) == \
        table + 16.0 * (k + 1) * (2 * k + 1)
    assert allocation.psf_support_bytes(sigma_px=1e-300, stamp_px=32) == math.inf


def test_dense_grid_and_window_estimates():
    from simcam import allocation

    assert allocation.dense_grid_bytes(1e-9) == 8.0 * allocation.DENSE_ARRAYS * 360e9  # 360 deg / step
    assert allocation.window_bytes(100001) == 8.0 * 100001 ** 2
    assert allocation.window_bytes(11, stars=30, frames=10) == 8.0 * 121 * 300


@pytest.fixture
def small_memory(monkeypatch):
    """1 GiB available, whatever the machine (the refusals must not depend on it)."""
    from simcam.infra import lifecycle

    monkeypatch.setattr(lifecycle, "available_memory_bytes", lambda: 1 << 30)


@pytest.mark.parametrize("sigma, says", [
    ("1e-300", "optics.psf.sigma0_px = 1e-300: a Gaussian PSF of sigma 1e-300 px spans 1.18e+300 cycles/px: "
               "spectrum tables of a render.stamp_px = 16 stamp: needs more memory than any machine has"),
    ("1e-3", "optics.psf.sigma0_px = 0.001: a Gaussian PSF of sigma 0.001 px spans 1.18e+03 cycles/px: "
             "spectrum tables of a render.stamp_px = 16 stamp: needs about 18.7 GiB of memory, 1.0 GiB available"),
])
def test_a_psf_too_narrow_for_memory_is_refused_naming_the_field(tmp_path, monkeypatch, small_memory, sigma, says):
    """(was: past 4-7 GiB and growing, no estimate)"""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.toml").write_text(TINY + f"\n[optics.psf]\nsigma0_px = {sigma}\n")
    code, err = _cli("simcam", ["render", "t.toml", "--frames", "1", "--out", "r", "--no-progress"])
    assert code == 2 and err.splitlines() == [f"error: t.toml: {says}"], err
    code, err = _cli("budget", ["starcam", "validate", "t.toml", "--trials", "4", "--workers", "1", "--no-progress"])
    assert code == 2 and err.splitlines() == [f"error: t.toml: {says}"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.toml"]


def test_a_dense_truth_grid_and_a_window_too_large_are_refused_naming_them(tmp_path, monkeypatch, small_memory):
    """``validation.dense_step_deg = 1e-9`` and ``measure --window 100001`` (was: a 2.6 TiB
    allocation attempted, naming neither)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ind.toml").write_text("[validation]\ndense_step_deg = 1e-9\n")
    code, err = _cli("budget", ["inductosyn", "validate", "ind.toml", "--trials", "4", "--workers", "1",
                                "--no-progress"])
    assert code == 2 and err.splitlines() == [
        "error: ind.toml: validation.dense_step_deg = 1e-09: a truth grid of 3.6e+11 angles: needs about "
        "10.5 TiB of memory, 1.0 GiB available"], err
    # the planner too, before any truth or trial (it used to start computing its truths)
    code, err = _cli("budget", ["inductosyn", "plan", "ind.toml", "--require", "residual.angle<=5", "--trials", "20",
                                "--workers", "1"])
    assert code == 2 and err.splitlines() == [
        "error: ind.toml: validation.dense_step_deg = 1e-09: a truth grid of 3.6e+11 angles: needs about "
        "10.5 TiB of memory, 1.0 GiB available"], err
    (tmp_path / "lab").mkdir()
    code, err = _cli("budget", ["starcam", "measure", "te", "lab", "--window", "100001"])
    assert code == 2 and err.splitlines() == [
        "error: --window 100001: one window of 100001 x 100001 float64 px per star and frame: needs about "
        "74.5 GiB of memory, 1.0 GiB available"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ind.toml", "lab"]


# ----------------------------------------------------------------------------- streaming sweeps
def test_a_long_axis_is_read_without_building_its_points(tmp_path, monkeypatch):
    """A 100,000-point axis is read without building a point (was: every point built and
    checked first, 97 s for 2,000); a point is built when asked for, with the values and seed
    the eager build gave (``grid_points``, ``point_seed``)."""
    from budget.sweeps import spec as spec_mod
    from budget.sweeps.values import point_seed

    built = []
    real = spec_mod.validate_scenario
    monkeypatch.setattr(spec_mod, "validate_scenario", lambda kind, data, *, source: (built.append(source),
                                                                                      real(kind, data, source=source))[1])
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "s.toml").write_text(textwrap.dedent("""
        kind = "starcam"
        base = "tiny.toml"
        seed = 11
        evaluate = "truth"
        [parameters]
        "lab.source.match_v_mag" = {start = 6.0, stop = 7.0, num = 100000}
    """))
    sw = spec_mod.load_sweep(tmp_path / "s.toml")
    assert len(built) == 1  # the base scenario only
    assert len(sw.points) == 100_000
    p = sw.points[-1]
    assert p.index == 99_999 and p.values == {"lab.source.match_v_mag": 7.0}
    assert p.seed == point_seed(11, p.values)
    assert p.scenario.lab.source.match_v_mag == 7.0 and len(built) == 2


def test_grid_indexer_is_the_product_in_c_order():
    """Against itertools.product (the eager list it replaces) and zip."""
    import itertools
    from types import SimpleNamespace

    from budget.sweeps.values import grid_indexer

    params = [("a", [1, 2]), ("b", [4.0, 5.0, 6.0]), ("c", ["x", "y"])]
    n, values_of = grid_indexer(SimpleNamespace(mode="product"), params, "s")
    assert [values_of(i) for i in range(n)] == [dict(zip("abc", v)) for v in itertools.product(*[v for _, v in params])]
    n, values_of = grid_indexer(SimpleNamespace(mode="zip"), [("a", [1, 2]), ("b", [3, 4])], "s")
    assert [values_of(i) for i in range(n)] == [{"a": 1, "b": 3}, {"a": 2, "b": 4}]


def test_windows_cover_every_point_once_starting_small():
    from budget.sweeps.run import WINDOW_MIN, WINDOW_PER_WORKER, _windows

    for workers, n in ((1, 1), (2, 100), (16, 1000)):
        w = list(_windows(np.arange(n), workers))
        np.testing.assert_array_equal(np.concatenate(w), np.arange(n))
        assert len(w[0]) == min(n, workers)
        assert max(len(x) for x in w) <= max(WINDOW_MIN, WINDOW_PER_WORKER * workers)


def test_done_flags_from_chunk_names_equal_zarrs_read(tmp_path):
    """The flags read from the chunk files' names (one listing; a 1,000,000-point store
    took minutes through Zarr) are those Zarr reads, for a new and a partly done store."""
    from budget.sweeps.spec import load_sweep
    from budget.sweeps.store import StoreWriter, _flags_from_chunk_names, create_store

    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    sw = load_sweep(tmp_path / "sweep.toml")
    create_store(tmp_path / "new", sw)
    w = StoreWriter(tmp_path / "new", sw)
    np.testing.assert_array_equal(w.done("grid"), np.zeros(4, bool))
    flags = _flags_from_chunk_names(tmp_path / "new" / "done", (2, 2))
    np.testing.assert_array_equal(flags, np.zeros(4, bool))
    # mark two points done as the writer does (value 1, the chunk file appears)
    import zarr

    arr = zarr.open_group(str(tmp_path / "new"), mode="r+")["done"]
    arr[0, 1] = 1
    arr[1, 1] = 1
    expect = np.asarray(arr[...]).reshape(-1).astype(bool)
    np.testing.assert_array_equal(expect, [False, True, False, True])
    np.testing.assert_array_equal(StoreWriter(tmp_path / "new", sw).done("grid"), expect)
