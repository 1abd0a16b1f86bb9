"""The study runner (budget.runner) on a study with analytic answers (tests/toys/toy_study.py)."""

import json
import os
import math

import numpy as np
import pytest
from toy_study import STUDY, Toy

from budget.runner.capabilities import Presented, Warmup
from budget.runner.report import format_table, write_report
from budget.runner.run import run_study
from budget.runner.stats import key_statistics
from simcam.infra.errors import UserInputError


def test_statistics_match_the_analytic_answers():
    scn = Toy(m=8, sigma=2.0)
    n = 4000
    res = run_study(STUDY, scn, trials=n, seed=11)
    s = res.summary()
    # ddof=0 variance: E = sigma^2 (m-1)/m, bias -sigma^2/m = -0.5; sd of s^2 (ddof 0) is
    # sigma^2 sqrt(2(m-1))/m = 1.87, so the mean's standard error is 1.87/sqrt(4000) = 0.030:
    # 4 standard errors (fixed seed) bound the check
    pub = s["variance"]["a"]["published"]
    assert pub["bias"] == pytest.approx(-0.5, abs=4 * pub["se_bias"])
    assert pub["bias_significant"]
    imp = s["variance"]["a"]["improved"]
    assert abs(imp["bias"]) < 4 * imp["se_bias"]
    # the mean's error is exactly N(0, sigma^2/m): coverage 0.6827 +- binomial se 0.0074
    cov = s["mean"]["a"]["published"]["coverage"]
    assert cov["within_1sigma"] == pytest.approx(0.6827, abs=4 * cov["se_1sigma"])
    assert cov["within_2sigma"] == pytest.approx(0.9545, abs=4 * cov["se_2sigma"])
    # sd of the normalised error is 1 with a standard error of 1/sqrt(2(n-1)) = 0.011
    assert cov["sd_normalised_error"] == pytest.approx(1.0, abs=4 / math.sqrt(2 * (n - 1)))
    assert s["mean"]["a"]["published"]["std"] == pytest.approx(2.0 / math.sqrt(8), rel=4 / math.sqrt(2 * (n - 1)))


def test_truth_standard_error_enters_the_significance_test():
    x = np.full(100, 1.0) + np.linspace(-1e-3, 1e-3, 100)
    assert key_statistics(x, truth=0.99, truth_se=0.0)["bias_significant"]
    st = key_statistics(x, truth=0.99, truth_se=0.01)
    assert not st["bias_significant"]
    assert st["se_bias"] == pytest.approx(math.sqrt(x.std(ddof=1) ** 2 / 100 + 0.01**2), rel=1e-12)


def test_results_do_not_depend_on_workers():
    scn = Toy()
    one = run_study(STUDY, scn, trials=40, seed=3, workers=1)
    two = run_study(STUDY, scn, trials=40, seed=3, workers=2)
    for key in one.samples:
        assert np.array_equal(one.samples[key], two.samples[key])
    for key in one.trial_truths:
        assert np.array_equal(one.trial_truths[key], two.trial_truths[key])


def test_adaptive_stopping_meets_the_tolerance():
    res = run_study(STUDY, Toy(), tolerance=0.1, seed=2)
    assert res.stopped_by == "tolerance"
    for key in res.samples:
        st = res.statistics(key)
        assert st["se_bias"] <= 0.1 and st["se_std"] <= 0.1


def test_adaptive_stopping_counts_the_truths_standard_error():
    """A truth with a Monte Carlo standard error s_T: the report's se_bias is
    sqrt(s^2/n + s_T^2), and a run stopped "by tolerance" must meet the tolerance with that
    figure. Toy numbers: the ddof=1 variance of m = 8 draws of sigma = 2 has
    sd sigma^2 sqrt(2/(m-1)) = 2.14, so s/sqrt(n) <= 0.1 needs n >= 458; with s_T = 0.05 a
    stop on s/sqrt(n) alone would report se_bias = sqrt(0.1^2 + 0.05^2) = 0.112 > 0.1, the
    runner must go on to s/sqrt(n) <= sqrt(0.1^2 - 0.05^2) = 0.087 (n >= about 610)."""
    tol, truth_se = 0.1, 0.05
    res = run_study(STUDY, Toy(truth_se=truth_se), tolerance=tol, seed=2)
    assert res.stopped_by == "tolerance"
    variance_keys = [k for k in res.samples if k[0] == "variance"]
    assert variance_keys
    for key in res.samples:
        st = res.statistics(key)
        assert st["se_bias"] <= tol and st["se_std"] <= tol
    for key in variance_keys:
        assert res.statistics(key)["truth_se"] == truth_se
    # it took the trials the truth's error asks for (batches of 100: at least 600)
    assert res.trials >= 600


def test_truth_error_above_the_tolerance_runs_to_the_cap():
    """s_T above the tolerance: no number of trials brings se_bias = sqrt(s^2/n + s_T^2)
    below it, so the run ends at the study's cap, says so, and the reported se_bias shows
    why (it exceeds the tolerance)."""
    tol = 0.1
    res = run_study(STUDY, Toy(truth_se=0.15, max_trials=1000), tolerance=tol, seed=2)
    assert res.stopped_by == "max_trials"
    assert res.trials == 1000  # without s_T it would stop near 460
    for key in res.samples:
        if key[0] == "variance":
            assert res.statistics(key)["se_bias"] > tol


def test_bad_requests_are_refused_before_work():
    with pytest.raises(UserInputError, match="give one of them"):
        run_study(STUDY, Toy(), trials=5, tolerance=0.1)
    from simcam.infra.errors import ResourceLimitError

    with pytest.raises(ResourceLimitError, match="--trials 10000000000000: needs about"):
        run_study(STUDY, Toy(), trials=10**13)


def test_json_and_report(tmp_path):
    res = run_study(STUDY, Toy(), trials=30, seed=1)
    payload = res.to_json()
    json.dumps(payload, allow_nan=True)
    assert payload["classes"]["variance"]["a"]["improved"]["truth"] == 4.0
    assert payload["class_info"]["mean"]["per_trial_truth"] is True
    rep = write_report(res, tmp_path / "rep")
    text = rep.read_text()
    assert "## Findings" in text and "### published" in text and "sample variance (a)" in text
    assert (tmp_path / "rep" / "estimates.png").is_file() and (tmp_path / "rep" / "report.html").is_file()
    assert not list(tmp_path.glob(".rep.partial.*"))
    assert "variance" in format_table(res)
    # a folder that is not an earlier report is never replaced
    other = tmp_path / "precious"
    other.mkdir()
    (other / "data.txt").write_text("keep")
    with pytest.raises(UserInputError, match="not an earlier report"):
        write_report(res, other)
    assert (other / "data.txt").read_text() == "keep"


class _AuxToy(type(STUDY), Presented):
    """The toy study with per-trial auxiliary figures (its trial number, a copy of an estimate) and details."""

    def trial(self, scenario, seed, k):
        r = super().trial(scenario, seed, k)
        r.aux = {"trial_number": float(k), "variance_ddof1": r.estimates[("variance", "improved", "a")]}
        return r

    def details(self, result):
        return {"mean_trial_number": float(result.aux["trial_number"].mean())}


@pytest.mark.parametrize("workers", [1, 2])
def test_aux_kept_for_every_trial_in_order_and_details_in_the_json(workers):
    """TrialResult.aux comes back as one array per name in trial order, whoever ran the
    trial; Study.details goes under "details" in the JSON (computed once)."""
    study = _AuxToy()
    res = run_study(study, Toy(), trials=25, seed=3, workers=workers)
    assert res.aux["trial_number"].tolist() == list(range(25))
    # the same float carried twice (estimate and aux) of the same trial: identical bits
    assert np.array_equal(res.aux["variance_ddof1"], res.samples[("variance", "improved", "a")])
    payload = res.to_json()
    assert payload["details"] == {"mean_trial_number": 12.0}  # mean of 0..24, exact in binary
    assert res.details() is res.details()
    assert run_study(STUDY, Toy(), trials=3, seed=3).to_json()["details"] == {}


#: numba's thread count when the study's own worker_init ran (in that worker process)
_THREADS_AT_INIT: list[int] = []


class _ThreadsToy(type(STUDY), Warmup):
    """The toy study reporting, per trial, the numba threads of the thread that runs it
    and those it had when the study's own worker set-up ran."""

    def worker_init(self):
        import numba

        _THREADS_AT_INIT.append(numba.get_num_threads())

    def trial(self, scenario, seed, k):
        import os

        import numba

        r = super().trial(scenario, seed, k)
        r.aux.update(numba_threads=float(numba.get_num_threads()), pid=float(os.getpid()),
                     threads_at_init=float(_THREADS_AT_INIT[-1]) if _THREADS_AT_INIT else -1.0)
        return r


@pytest.mark.parametrize("where", [{"workers": 2}, {"workers": None, "dask_local": 1}], ids=["processes", "dask"])
def test_every_worker_the_runner_starts_has_one_numba_thread(where):
    """The runner owns the worker set-up: one numba thread in every worker it
    starts, local process or Dask worker, and in this process where it runs trials too
    (local processes), already when the study's own worker_init runs; a study sets
    nothing itself (the toy's worker_init only records)."""
    import numba

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one core: numba's default is already one thread, nothing to tell apart")
    res = run_study(_ThreadsToy(), Toy(), trials=12, seed=1, **where)
    assert set(res.aux["numba_threads"]) == {1.0}
    assert set(res.aux["threads_at_init"]) == {1.0}
    pids = set(res.aux["pid"])
    assert pids - {float(os.getpid())}  # run in started workers (and here, with local processes)
    if where.get("workers") == 2:
        assert len(pids) == 2  # this process and the one it started


_FORK_CHILD = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
from budget.runner import executors
from budget.runner.run import run_study
from toy_study import STUDY, Toy

before = executors.start_method()
res = run_study(STUDY, Toy(), trials=40, seed=3, workers=2)
after_run = executors.start_method()  # this process ran trials: numba's pool is launched
print(json.dumps({"before": before, "after_run": after_run,
                  "samples": {"|".join(k): v.tolist() for k, v in res.samples.items()}}))
"""


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="workers fork on Linux only")
def test_forked_workers_give_the_spawned_and_inline_results():
    """A fresh process forks its workers (no thread, numba's pool not launched), and the
    run's numbers are those of one process, bit for bit; once this process has launched
    numba's thread pool (it ran trials itself), the next pool is spawned. A test session's
    process has usually launched it (any test that ran trials in it), so the fork is
    checked in a child interpreter."""
    import subprocess
    import sys
    from pathlib import Path

    out = subprocess.run([sys.executable, "-c", _FORK_CHILD, str(Path(__file__).parent / "toys")], capture_output=True,
                         text=True, timeout=300, check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["before"] == "fork"
    assert got["after_run"] == "spawn"
    one = run_study(STUDY, Toy(), trials=40, seed=3, workers=1)
    assert set(got["samples"]) == {"|".join(k) for k in one.samples}
    for key, v in one.samples.items():
        assert np.array_equal(np.array(got["samples"]["|".join(key)]), v)


def test_start_method_spawns_beside_a_running_thread():
    """A process with a second thread spawns (a fork would copy any lock that thread holds)."""
    import threading

    from budget.runner.executors import start_method

    stop = threading.Event()
    t = threading.Thread(target=stop.wait)
    t.start()
    try:
        assert start_method() == "spawn"
    finally:
        stop.set()
        t.join()


_FORK_STATE_CHILD = r"""
import json, os, signal, sys
from simcam.infra import lifecycle
from budget.runner import executors


def state(_):
    return {"term_default": signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
            "int_default": signal.getsignal(signal.SIGINT) is signal.default_int_handler,
            "guard_here": lifecycle._GUARDED == os.getpid(), "pid": os.getpid()}


signal.signal(signal.SIGTERM, lambda *a: None)  # a command's own handlers, as run_cli sets them
signal.signal(signal.SIGINT, lambda *a: None)
lifecycle._GUARDED = os.getpid()  # as in a guarded process (its thread aside): a forked child sets its own
method = executors.start_method()
with executors.ProcessExecutor(1) as pool:
    got = [r for _, r in pool.map_unordered(state, [0])][0]
print(json.dumps({"method": method, "parent": os.getpid(), **got}))
"""


@pytest.mark.skipif(not __import__("sys").platform.startswith("linux"), reason="workers fork on Linux only")
def test_a_forked_worker_starts_as_a_spawned_one():
    """A forked worker does not keep what it inherits of this process's set-up: its stop
    signals are Python's defaults (not the command's handlers) and it sets its own
    parent-death guard (the flag it inherits names its parent)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _FORK_STATE_CHILD], capture_output=True, text=True, timeout=300,
                         check=True)
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["method"] == "fork" and got["pid"] != got["parent"]
    assert got["term_default"] and got["int_default"] and got["guard_here"]


def test_start_method_reads_numbas_pool_flag_and_spawns_without_it(monkeypatch):
    """Fork only while numba's pool is down; a numba without the (private) flag counts as
    launched: spawn."""
    import sys
    import threading

    from numba.np.ufunc import parallel

    from budget.runner.executors import start_method

    if not sys.platform.startswith("linux"):
        pytest.skip("workers fork on Linux only")
    # this test session may run other threads (a Dask cluster's, a progress bar's): the
    # thread rule is test_start_method_spawns_beside_a_running_thread's; here, one thread
    monkeypatch.setattr(threading, "active_count", lambda: 1)
    monkeypatch.setattr(parallel, "_is_initialized", False)
    assert start_method() == "fork"
    monkeypatch.setattr(parallel, "_is_initialized", True)
    assert start_method() == "spawn"
    monkeypatch.delattr(parallel, "_is_initialized")
    assert start_method() == "spawn"
