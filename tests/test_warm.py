"""A first run's numba compilation in two processes (simcam.numba_warm, budget.starcam.warm).

The targets must compile exactly the signatures a trial and the truths then call, or the
first run compiles them twice: checked in a fresh process with an empty numba cache by
listening to numba's compile events. The mechanism (children started only on a cold
cache and with a spare core, waited for, stopped on an interruption) is checked with a
stand-in target.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import tomllib
from pathlib import Path
from types import SimpleNamespace

import pytest
from tiny_camera import TINY

import simcam.numba_warm as nw

_SCRIPT = r"""
import json, sys, warnings
from numba.core import event as ev
from simcam.numba_warm import is_cached
from simcam.starcam.kernels import psf
from budget.starcam import kernels_trial as kt, warm
from budget.runner.registry import get_study

st = get_study("starcam")
scn = st.load_scenario(sys.argv[1])
before = [is_cached(psf.folded_stamp_spectra), is_cached(kt.expose_centroid_frames_serial)]
opts = json.dumps({"fused": True, "windows": True})
warm.compile_support(opts)
warm.compile_stamps_and_exposure(opts)
after = [is_cached(psf.folded_stamp_spectra), is_cached(kt.expose_centroid_frames_serial)]
compiled = []

class Listener(ev.Listener):
    def on_start(self, e):
        f = e.data["dispatcher"].py_func
        if f.__module__.split(".")[0] in ("simcam", "budget"):
            compiled.append(f"{f.__module__}.{f.__qualname__}{e.data['args']}")

    def on_end(self, e):
        "nothing to record when a compile ends"

ev.register("numba:compile", Listener())
from budget.runner.executors import worker_setup
worker_setup(st.worker_init)  # as in a worker of the runner: one numba thread
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    st.trial(scn, 0, 1)
    st.truths(scn, 0)
print(json.dumps({"before": before, "after": after, "compiled": compiled}))
"""


def test_warm_targets_compile_what_a_trial_and_the_truths_call(tmp_path):
    # with dark frames a trial calls every kernel it calls without them, and the window
    # exposure besides (one fresh process and empty cache: about 15 s)
    scn = tmp_path / "tiny.toml"
    scn.write_text(TINY.replace("[validation]\n", "[validation]\ndark_frames = 2\n"))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    run = subprocess.run([sys.executable, "-c", _SCRIPT, str(scn)], env=env, capture_output=True, text=True,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["before"] == [False, False]  # an empty cache reads as cold
    assert out["after"] == [True, True]
    assert out["compiled"] == [], "compiled again after the warm targets:\n" + "\n".join(out["compiled"])


# ------------------------------------------------------------------ the mechanism


def _cold():
    """A stand-in dispatcher whose numba cache index is empty (not cached)."""
    return SimpleNamespace(_cache=SimpleNamespace(_enabled=True, _cache_file=SimpleNamespace(_load_index=dict)))


def _warm():
    return SimpleNamespace(_cache=SimpleNamespace(_enabled=True, _cache_file=SimpleNamespace(
        _load_index=lambda: {"sig": "data"})))


def touch(arg: str) -> None:
    """Child target: write this process's PID to ``arg``, then idle (stand-in for compiling)."""
    path = Path(arg)
    path.write_text(str(os.getpid()))
    time.sleep(float(os.environ.get("WARM_TEST_SLEEP_S", "0")))


def test_is_cached_reads_numba_index_and_treats_the_unknown_as_cached():
    assert nw.is_cached(_cold()) is False
    assert nw.is_cached(_warm()) is True
    assert nw.is_cached(object()) is True  # not a numba dispatcher: nothing to warm
    off = SimpleNamespace(_cache=SimpleNamespace(_enabled=False))
    assert nw.is_cached(off) is True


def test_children_start_only_on_a_cold_cache_with_a_spare_core(tmp_path, monkeypatch):
    monkeypatch.setattr(nw, "usable_cores", lambda: 2)
    marker = tmp_path / "pid"
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_warm()]) as started:
        assert started is False
    assert not marker.exists()
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_cold(), _warm()]) as started:
        assert started is True
    assert marker.exists()  # waited for at the end of the block
    marker.unlink()
    monkeypatch.setattr(nw, "usable_cores", lambda: 1)
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_cold()]) as started:
        assert started is False
    assert not marker.exists()


def test_an_interruption_stops_the_children_and_goes_on(tmp_path, monkeypatch):
    monkeypatch.setattr(nw, "usable_cores", lambda: 2)
    monkeypatch.setenv("WARM_TEST_SLEEP_S", "60")
    marker = tmp_path / "pid"
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt), nw.compiling_in_parallel([("test_warm:touch", str(marker))],
                                                                      check=[_cold()]):
        while not marker.exists() or not marker.read_text():
            assert time.monotonic() - t0 < 60, "the child never started"
            time.sleep(0.05)
        raise KeyboardInterrupt
    pid = int(marker.read_text())
    with pytest.raises(ProcessLookupError):  # killed and reaped
        os.kill(pid, 0)
    assert time.monotonic() - t0 < 30


def test_targets_run_for_every_option():
    # (in this process, usually with a warm cache: checks that each branch calls its
    # kernels without error; what they compile is checked above)
    from budget.starcam import warm

    for fused in (True, False):
        for windows in (True, False):
            warm.compile_stamps_and_exposure(json.dumps({"fused": fused, "windows": windows}))
    warm.compile_support("{}")


def test_prewarm_options_follow_the_scenario(monkeypatch):
    # the fused kernel only for the centre of gravity; the window exposure for dark frames
    # or another method
    from budget.runner.registry import get_study
    from budget.starcam import warm

    seen = []

    class Recorder:
        def __init__(self, children, *, check):
            seen.append(([json.loads(a) for _, a in children], [d.py_func.__name__ for d in check]))

        def __enter__(self):
            return False

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(nw, "compiling_in_parallel", Recorder)
    st = get_study("starcam")
    base = st.default_text()
    assert 'centroid_method = "cog"' in base and "dark_frames = 0" in base
    for method, dark in (("cog", 0), ("cog", 2), ("iwcog", 0)):
        text = base.replace('centroid_method = "cog"', f'centroid_method = "{method}"').replace(
            "dark_frames = 0", f"dark_frames = {dark}")
        warm.prewarm(st.from_dict(tomllib.loads(text), source="test"))
    assert seen[0] == ([{"fused": True, "windows": False}], ["folded_stamp_spectra", "expose_centroid_frames_serial"])
    assert seen[1] == ([{"fused": True, "windows": True}],
                       ["folded_stamp_spectra", "expose_centroid_frames_serial", "expose_windows_frames_serial"])
    assert seen[2] == ([{"fused": False, "windows": True}], ["folded_stamp_spectra", "expose_windows_frames_serial"])
