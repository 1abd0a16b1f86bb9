"""How soon a long sweep writes its first point, and the memory it holds meanwhile.

``python -m benchmarks.sweep_stream N LIMIT_S`` runs ``budget sweep --workers 2`` of the
tiny camera of ``tests/tiny_camera.py`` in truth mode, one axis
``lab.source.match_v_mag = {start = 6, stop = 7, num = N}``, in a temporary folder, and
prints the time from the command's start to its first line on stdout and to its first point
marked done in the store, and the peak resident memory of its process tree (psutil, sampled
every 0.5 s); the command is stopped (SIGTERM) after its first point or after ``LIMIT_S``.
docs/reliability.md ("Bounded size") has the figures for N = 2,000 and 1,000,000.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _tree_rss(pid: int) -> int:
    import psutil

    try:
        root = psutil.Process(pid)
        procs = [root, *root.children(recursive=True)]
    except psutil.NoSuchProcess:
        return 0
    total = 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.NoSuchProcess:
            pass
    return total


def _any_point_done(store: Path) -> bool:
    """Whether a point is marked done: a chunk file of the ``done`` array exists (Zarr
    format 2 writes one file per chunk; listing the folder reads no chunk)."""
    try:
        return any(not name.startswith(".") for name in os.listdir(store / "done"))
    except OSError:  # not created yet
        return False


def measure(n: int, limit_s: float) -> dict:
    """First line, first point (s, None if not within ``limit_s``) and peak RSS (bytes)."""
    sys.path.insert(0, str(REPO / "tests"))
    from tiny_camera import TINY

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "tiny.toml").write_text(TINY)
        (d / "s.toml").write_text(textwrap.dedent(f"""
            name = "axis {n}"
            kind = "starcam"
            base = "tiny.toml"
            seed = 11
            evaluate = "truth"
            [parameters]
            "lab.source.match_v_mag" = {{start = 6.0, stop = 7.0, num = {n}}}
        """))
        env = dict(os.environ, PYTHONPATH=str(REPO))
        t0 = time.monotonic()
        proc = subprocess.Popen([sys.executable, "-m", "budget", "sweep", "s.toml", "--out", "st", "--workers", "2",
                                 "--no-progress"], cwd=d, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL, start_new_session=True)
        os.set_blocking(proc.stdout.fileno(), False)
        first_line = first_point = None
        peak = 0
        while time.monotonic() - t0 < limit_s and proc.poll() is None:
            if first_line is None and proc.stdout.read():
                first_line = time.monotonic() - t0
            peak = max(peak, _tree_rss(proc.pid))
            if _any_point_done(d / "st"):
                first_point = time.monotonic() - t0
                break
            time.sleep(0.5)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(60)
    return {"points": n, "first_line_s": first_line, "first_point_s": first_point, "peak_rss": peak,
            "load": os.getloadavg()[0]}


def main() -> None:
    n, limit = int(sys.argv[1]), float(sys.argv[2])
    r = measure(n, limit)
    def fmt(v):
        return "none" if v is None else f"{v:.1f} s"

    print(f"{r['points']} points: first line {fmt(r['first_line_s'])}, first point {fmt(r['first_point_s'])}, "
          f"peak RSS {r['peak_rss'] / 2**20:.0f} MiB (load average {r['load']:.1f})")


if __name__ == "__main__":
    main()
