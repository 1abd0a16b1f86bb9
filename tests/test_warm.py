"""A first run's numba compilation in two processes (simcam.numba_warm, budget.starcam.warm).

The targets must compile exactly the signatures a trial and the truths then call, or the
first run compiles them twice: checked in a fresh process with an empty numba cache by
listening to numba's compile events (slow: it compiles every star-camera kernel, twice),
and in the default suite in a fresh process on numba's usual cache by comparing the
signatures each kernel holds before and after the trial. The mechanism (children started only on a cold
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
opts = json.dumps(warm.options(scn))
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


def _tiny_scenario(tmp_path, dark_frames):
    scn = tmp_path / "tiny.toml"
    scn.write_text(TINY.replace("[validation]\n", f"[validation]\ndark_frames = {dark_frames}\n"))
    return scn


@pytest.mark.slow
@pytest.mark.parametrize("dark_frames", [2, 0])
def test_warm_targets_compile_what_a_trial_and_the_truths_call(tmp_path, dark_frames):
    # with dark frames a trial calls every kernel it calls without them, and the window
    # exposure besides; without, the truths their control-variate kernels (each case one
    # fresh process and empty cache: about 15 s of compiling; the fast twin is
    # test_warm_targets_load_every_signature_a_trial_and_the_truths_call)
    scn = _tiny_scenario(tmp_path, dark_frames)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    run = subprocess.run([sys.executable, "-c", _SCRIPT, str(scn)], env=env, capture_output=True, text=True,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["before"] == [False, False]  # an empty cache reads as cold
    assert out["after"] == [True, True]
    assert out["compiled"] == [], "compiled again after the warm targets:\n" + "\n".join(out["compiled"])


_LOADED_SCRIPT = r"""
import json, sys, warnings
from numba.core.registry import CPUDispatcher
from budget.starcam import warm
from budget.runner.registry import get_study


def loaded():
    # numba's public Dispatcher.signatures of every kernel of the two packages: what this
    # process compiled or loaded from the cache
    out = set()
    for name, mod in list(sys.modules.items()):
        if name.split(".")[0] in ("simcam", "budget"):
            for d in list(vars(mod).values()):
                if isinstance(d, CPUDispatcher):
                    out |= {f"{d.py_func.__module__}.{d.py_func.__qualname__}{s}" for s in d.signatures}
    return out


st = get_study("starcam")
scn = st.load_scenario(sys.argv[1])
opts = json.dumps(warm.options(scn))
warm.compile_support(opts)
warm.compile_stamps_and_exposure(opts)
before = loaded()
from budget.runner.executors import worker_setup
worker_setup(st.worker_init)  # as in a worker of the runner: one numba thread
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    st.trial(scn, 0, 1)
    st.truths(scn, 0)
print(json.dumps(sorted(loaded() - before)))
"""


@pytest.mark.parametrize("dark_frames", [2, 0])
def test_warm_targets_load_every_signature_a_trial_and_the_truths_call(tmp_path, dark_frames):
    """The fast twin of the check above, on numba's usual cache (warm after the first run):
    after the warm targets, a trial and the truths add no signature to any kernel of the
    two packages. Stricter than the cold-cache check in one respect: a kernel the targets
    compile only inside another (its machine code then lives in its caller's cache entry)
    and the trial calls directly reads as missed here."""
    scn = _tiny_scenario(tmp_path, dark_frames)
    run = subprocess.run([sys.executable, "-c", _LOADED_SCRIPT, str(scn)], capture_output=True, text=True,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    added = json.loads(run.stdout.strip().splitlines()[-1])
    assert added == [], "loaded after the warm targets:\n" + "\n".join(added)


# ------------------------------------------------------------------ the mechanism

_KERNEL = """
import numba

@numba.njit(cache=True)
def f(x):
    return x + {k}
"""

_PROBE = r"""
import json, sys
sys.path.insert(0, sys.argv[1])
import probe_kernel
from simcam.numba_warm import is_cached
before = is_cached(probe_kernel.f)
if sys.argv[2] == "call":
    probe_kernel.f(1.0)
print(json.dumps([before, is_cached(probe_kernel.f)]))
"""


def _probe(tmp_path, action):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    run = subprocess.run([sys.executable, "-c", _PROBE, str(tmp_path), action], env=env, capture_output=True,
                         text=True, timeout=300, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_is_cached_follows_numba_s_cache_of_a_real_kernel(tmp_path):
    """On a real ``njit(cache=True)`` kernel in an empty cache folder (numba's own
    behaviour, not a stand-in of its internals): cold before the first call, cached after
    it and in a fresh process, cold again once the kernel's source changed (a stale entry).
    Anything that is not a numba dispatcher reads as cached (nothing to warm)."""
    kernel = tmp_path / "probe_kernel.py"
    kernel.write_text(_KERNEL.format(k=1.0))
    assert _probe(tmp_path, "call") == [False, True]
    assert _probe(tmp_path, "look") == [True, True]
    kernel.write_text(_KERNEL.format(k=2.0))
    assert _probe(tmp_path, "look") == [False, False]
    assert nw.is_cached(object()) is True


#: stand-ins for the dispatchers the mechanism checks; which of them read as cached is
#: decided by a replaced ``is_cached`` (its reading of numba's cache is checked above)
_COLD, _WARM = object(), object()


def _stand_in_cache(monkeypatch):
    monkeypatch.setattr(nw, "is_cached", lambda d: d is not _COLD)


def touch(arg: str) -> None:
    """Child target: write this process's PID to ``arg``, idle (stand-in for compiling),
    then append ``done`` (a child stopped early never writes it)."""
    path = Path(arg)
    path.write_text(str(os.getpid()))
    time.sleep(float(os.environ.get("WARM_TEST_SLEEP_S", "0")))
    with path.open("a") as f:
        f.write("\ndone")


def test_children_start_only_on_a_cold_cache_with_a_spare_core(tmp_path, monkeypatch):
    _stand_in_cache(monkeypatch)
    monkeypatch.setattr(nw, "usable_cores", lambda: 2)
    marker = tmp_path / "pid"
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_WARM]) as started:
        assert started is False
    assert not marker.exists()
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_COLD, _WARM]) as started:
        assert started is True
    assert marker.read_text().endswith("done")  # waited for at the end of the block
    marker.unlink()
    monkeypatch.setattr(nw, "usable_cores", lambda: 1)
    with nw.compiling_in_parallel([("test_warm:touch", str(marker))], check=[_COLD]) as started:
        assert started is False
    assert not marker.exists()


def test_an_interruption_stops_the_children_and_goes_on(tmp_path, monkeypatch):
    # the child would idle 60 s and then write "done": stopped on the interruption, it never
    # does (this replaces a wall-clock bound, which a slow machine could break)
    _stand_in_cache(monkeypatch)
    monkeypatch.setattr(nw, "usable_cores", lambda: 2)
    monkeypatch.setenv("WARM_TEST_SLEEP_S", "60")
    marker = tmp_path / "pid"
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt), nw.compiling_in_parallel([("test_warm:touch", str(marker))],
                                                                      check=[_COLD]):
        while not marker.exists() or not marker.read_text():
            assert time.monotonic() - t0 < 60, "the child never started"
            time.sleep(0.05)
        raise KeyboardInterrupt
    text = marker.read_text()
    pid = int(text.splitlines()[0])
    with pytest.raises(ProcessLookupError):  # killed and reaped
        os.kill(pid, 0)
    assert "done" not in text


_OPTIONS_SCRIPT = r"""
import json
from budget.starcam import kernels_trial as kt, warm
from simcam.kernels import detector as kd
from simcam.starcam.kernels import psf as kp
from simcam import rng_poisson
from budget.centroid import kernels as ck

watched = {"stamps": kp.folded_stamp_spectra, "fused": kt.expose_centroid_frames_serial,
           "windows": kd.expose_windows_frames_serial}
support = {"poisson": rng_poisson.poisson_prepared, "cog_one": ck.cog_one}
def loaded():
    # numba's public Dispatcher.signatures: what this process compiled or loaded
    return sorted(k for k, d in watched.items() if d.signatures)
out = [loaded()]
for fused, windows in ((False, False), (True, False), (False, True), (True, True)):
    warm.compile_stamps_and_exposure(json.dumps({"fused": fused, "windows": windows}))
    out.append(loaded())
warm.compile_support("{}")
out.append(sorted(k for k, d in support.items() if d.signatures))
print(json.dumps(out))
"""


def test_targets_run_for_every_option():
    """Each option of compile_stamps_and_exposure loads exactly the top-level kernels it
    names, and compile_support the random-number and centroid kernels (in a fresh process
    with numba's usual cache, warm or cold: which signatures are loaded, not how long it
    takes; a cold fused kernel also compiles its callees, so the support kernels are
    checked only after compile_support)."""
    run = subprocess.run([sys.executable, "-c", _OPTIONS_SCRIPT], capture_output=True, text=True,
                         timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-3000:]
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out[0] == []
    assert out[1] == ["stamps"]  # neither option: the stamps only
    assert out[2] == ["fused", "stamps"]
    assert out[3] == ["fused", "stamps", "windows"]
    assert out[4] == out[3]
    assert out[5] == ["cog_one", "poisson"]


def test_prewarm_options_follow_the_scenario(monkeypatch):
    # the fused kernel only for the centre of gravity; the window exposure for dark frames
    # or another method; the truths' kernels where their control variates apply
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
    # the stamps (both routes) and the windows summed from them always; the fused kernel and
    # its twin for a drifting condition for the centre of gravity; the truths' control-variate
    # kernels for the centre of gravity without dark frames
    stamps = ["folded_stamp_spectra", "stamp_profiles", "shifted_stamp_spectra", "add_stamps_windows"]
    fused = ["expose_centroid_frames_serial", "expose_centroid_drift_serial"]
    truth = ["cv_tables", "expose_centroid_cv_serial"]
    assert seen[0] == ([{"fused": True, "windows": False, "truth": True}], stamps + fused + truth)
    assert seen[1] == ([{"fused": True, "windows": True, "truth": False}],
                       stamps + fused + ["expose_windows_frames_serial"])
    assert seen[2] == ([{"fused": False, "windows": True, "truth": False}], stamps + ["expose_windows_frames_serial"])
