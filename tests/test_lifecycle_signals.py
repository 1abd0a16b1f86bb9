"""A stop signal that arrives while the main thread runs a C callback (numba's cache
notifications reach Python through ctypes) raises Interrupted where ctypes cannot propagate
it: the handler, already disarmed, would lose the interruption and the command run on, deaf
to the signal (a validation of 100,000 trials did, under load). The interruption must be
delivered again once the main thread is back in Python code."""

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SCRIPT = textwrap.dedent("""
    import ctypes, os, signal, time
    from simcam.infra.errors import Interrupted
    from simcam.infra.lifecycle import handle_termination

    def callback():
        os.kill(os.getpid(), signal.SIGTERM)   # its handler runs here, inside the C callback
        time.sleep(0.2)

    swallowing = ctypes.CFUNCTYPE(None)(callback)
    try:
        with handle_termination():
            swallowing()                       # ctypes reports the Interrupted and goes on
            print("AFTER THE CALLBACK", flush=True)
            time.sleep(10)                     # the interruption must arrive here
        print("NOT INTERRUPTED")
    except Interrupted as exc:
        print("INTERRUPTED", exc.signum)
""")


def test_an_interruption_swallowed_by_a_c_callback_is_delivered_again():
    p = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=60, cwd=REPO)
    assert p.stdout.split("\n")[:2] == ["AFTER THE CALLBACK", "INTERRUPTED 15"], (p.stdout, p.stderr)
    assert "Traceback" not in p.stderr, p.stderr  # the swallowed one is not printed either
