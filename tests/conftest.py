"""pytest's set-up of the tests: the toy studies importable by their own module names, and the
detector kernels compiled on a spare core.

* The toy studies of ``tests/toys/`` (``import toy_study``, ``from plan_toy import TOY``): the
  folder goes on ``sys.path`` of the test process before any test module is collected. Worker
  processes find the toys the same way: a forked worker inherits the path, and a spawned one (a
  local process or a Dask worker) receives the parent's ``sys.path`` from :mod:`multiprocessing`
  before it unpickles a study, so it imports the toy's module by the same name. A child
  interpreter a test starts itself (``subprocess``) has neither: such a test puts
  ``tests/toys`` on its child's path itself.
* On a cold numba cache (a fresh clone, as in CI) the first test that calls a kernel with a
  new signature compiles it, and the detector's parallel kernels are most of that: about 75 s
  of a full run, on one core. At the start of a session whose cache is cold, with a second
  core usable, :func:`pytest_sessionstart` starts :func:`numba_prewarm.compile_all`
  (``tests/numba_prewarm.py``) in a child process that writes numba's cache while the tests
  run; :func:`pytest_sessionfinish` stops it if it is still running (a run of a few test
  files does not wait for it). With a warm cache, or one core, nothing is started. Results do
  not depend on it: numba compiles the same machine code for a signature wherever it does so.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: the folder of the toy studies
TOYS = Path(__file__).resolve().parent / "toys"

if str(TOYS) not in sys.path:
    sys.path.insert(0, str(TOYS))

_CHILD: list[subprocess.Popen] = []


def pytest_sessionstart(session) -> None:
    if hasattr(session.config, "workerinput"):
        return  # a pytest-xdist worker: the controlling process starts the one child
    from simcam.kernels import detector as kd
    from simcam.numba_warm import is_cached, usable_cores

    if usable_cores() < 2 or all(is_cached(d) for d in (kd.expose_block, kd.expose_block_maps)):
        return
    code = (
        "import sys\n"
        f"sys.path[:0] = {[os.path.dirname(__file__), *(p or os.getcwd() for p in sys.path)]!r}\n"
        "from simcam.infra.lifecycle import exit_with_parent\n"
        "exit_with_parent()\n"
        "import numba_prewarm\n"
        "numba_prewarm.compile_all()\n"
    )
    try:
        _CHILD.append(subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.DEVNULL,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    except OSError:
        pass  # no child: each kernel is compiled where it is first called


def pytest_sessionfinish(session, exitstatus) -> None:
    while _CHILD:
        proc = _CHILD.pop()
        if proc.poll() is None:
            proc.kill()
        proc.wait()
