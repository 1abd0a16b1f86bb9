"""Worker processes that do not outlive their parent.

:func:`exit_with_parent` is called first in every worker process of the runner: on Linux
the kernel sends SIGKILL to the worker when the process that started it dies
(``prctl(PR_SET_PDEATHSIG)``); elsewhere a daemon thread polls the parent's PID and exits
when it changes (the worker has been re-parented).
"""

from __future__ import annotations

import os
import signal
import sys
import threading

__all__ = ["exit_with_parent"]

_PR_SET_PDEATHSIG = 1


def exit_with_parent(poll_s: float = 1.0) -> None:
    """Make this process exit when its parent dies (see the module docstring)."""
    parent = os.getppid()
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
                # the parent may have died before prctl took effect
                if os.getppid() != parent:
                    os._exit(1)
                return
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        import time

        while True:
            time.sleep(poll_s)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="exit-with-parent", daemon=True).start()
