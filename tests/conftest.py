"""What every test session shares: the detector kernels compiled on a spare core.

On a cold numba cache (a fresh clone, as in CI) the first test that calls a kernel with a
new signature compiles it, and the detector's parallel kernels are most of that: about
75 s of a full run, on one core. At the start of a session whose cache is cold, with a
second core usable, :func:`pytest_sessionstart` starts
:func:`numba_prewarm.compile_all` (``tests/numba_prewarm.py``) in a child process that
writes numba's cache while the tests run; :func:`pytest_sessionfinish` stops it if it is
still running (a run of a few test files does not wait for it). With a warm cache, or
one core, nothing is started. Results do not depend on it: numba compiles the same
machine code for a signature wherever it does so.
"""

from __future__ import annotations

import os
import subprocess
import sys

_CHILD: list[subprocess.Popen] = []


def pytest_sessionstart(session) -> None:
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
