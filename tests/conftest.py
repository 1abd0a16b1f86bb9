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
  of one core. At the start of a session whose cache is cold, with a second core usable,
  :func:`pytest_sessionstart` first compiles the kernels most tests call, a star-camera trial's
  and truths' and an attitude pointing's (:func:`numba_prewarm.warm_studies`, about 12 s on
  both cores), before pytest-xdist starts its workers (else each worker compiles them beside
  the other); then it starts :func:`numba_prewarm.compile_all`
  (``tests/numba_prewarm.py``) in a child process that writes numba's cache while the tests
  run, and the test files that call those kernels (:data:`PREWARMED_FILES`) are collected last,
  so that they load what the child compiled instead of compiling it beside the child;
  :func:`pytest_sessionfinish` stops the child if it is still running (a run of a few test
  files does not wait for it). With a warm cache, or one core, nothing is started and the order
  is the files'. Results do not depend on either: the tests are independent, and numba compiles
  the same machine code for a signature wherever it does so.
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
#: set (to "1") by the controlling process when it started the child, before pytest-xdist starts
#: its workers (they inherit it), so that every process collects the tests in the same order
COLD_CACHE_ENV = "SIMCAM_TESTS_COLD_NUMBA_CACHE"
#: the test files that call the kernels the child compiles (tests/numba_prewarm.py): on a cold
#: cache they run last, so that they load what the child compiled meanwhile instead of
#: compiling the same signatures beside it
PREWARMED_FILES = ("test_detector.py", "test_detector_frame.py", "test_detector_maps.py", "test_cli_simcam.py",
                   "test_protocols.py", "test_attitude_study_solve.py", "test_attitude_chain.py",
                   "test_attitude_study.py")


def pytest_sessionstart(session) -> None:
    if hasattr(session.config, "workerinput"):
        return  # a pytest-xdist worker: the controlling process starts the one child
    from simcam.kernels import detector as kd
    from simcam.numba_warm import is_cached, usable_cores

    if usable_cores() < 2 or all(is_cached(d) for d in (kd.expose_block, kd.expose_block_maps)):
        return
    head = (
        "import sys\n"
        f"sys.path[:0] = {[os.path.dirname(__file__), *(p or os.getcwd() for p in sys.path)]!r}\n"
        "from simcam.infra.lifecycle import exit_with_parent\n"
        "exit_with_parent()\n"
        "import numba_prewarm\n"
    )
    # the kernels most tests call, compiled once on both cores before the workers start (else
    # each worker compiles them beside the other in its first tests); a failure here only
    # leaves them to the tests
    subprocess.run([sys.executable, "-c", head + "numba_prewarm.warm_studies()\n"], stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False, timeout=600)
    code = head + "numba_prewarm.compile_all()\n"
    try:
        _CHILD.append(subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.DEVNULL,
                                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    except OSError:
        return  # no child: each kernel is compiled where it is first called
    os.environ[COLD_CACHE_ENV] = "1"


def pytest_collection_modifyitems(session, config, items) -> None:
    if os.environ.get(COLD_CACHE_ENV) != "1":
        return
    # a stable partition: the files of the child's kernels last, each in its own order
    items[:] = ([it for it in items if it.path.name not in PREWARMED_FILES]
                + [it for it in items if it.path.name in PREWARMED_FILES])


def pytest_sessionfinish(session, exitstatus) -> None:
    while _CHILD:
        proc = _CHILD.pop()
        if proc.poll() is None:
            proc.kill()
        proc.wait()
