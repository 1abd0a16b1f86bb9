"""Run every benchmark and write ``docs/benchmarks.md`` from what they measured in this run.

Each ``benchmarks/bench_*.py`` (discovered, not listed here) runs as a subprocess from the
repository root, one after the other, with the repository first on ``PYTHONPATH``. Its
standard output is kept verbatim for the page (a code block per benchmark), the system
load is read before and after it, and its last ``RESULT {json}`` line (written by
``_common.emit_result``) gives the key figures: ours, the peer measured in the same run,
the issue's target. From those the page's summary table gives, for every figure, the
ratio to the peer (above 1: ours is better) and whether the target is met.

A peer library that is not installed is reported as "not installed" by the benchmark
(never a crash). A benchmark that fails, times out or prints no ``RESULT`` line is
reported as such on the page, and the others still run.

The peer libraries come with the ``bench`` extra: ``pip install -e '.[bench]'``.

Usage (from the repository root)::

    python benchmarks/run_all.py                      # full settings -> docs/benchmarks.md
    python benchmarks/run_all.py --quick --out /tmp/benchmarks.md   # smoke run
    python benchmarks/run_all.py --only centroid,render --out /tmp/b.md
    python benchmarks/run_all.py --list

A full run onto the default page (no ``--quick``, no ``--out``) also rewrites the marked
block of ``README.md`` that states the main job's wall time (from ``bench_runner.py``'s
figures of the same run), so that every speed figure of the docs comes from one run; the
other pages link to the benchmarks' sections (anchors ``#bench-<name>``).

``--quick`` passes ``--quick`` to every benchmark that has it (fewer repeats and trials:
the figures are then not meaningful, and the page says so); a benchmark without it runs
with its own defaults. Exit status: 0 when every benchmark ran and printed its
``RESULT`` line, 1 otherwise (the page is written in both cases), 2 on bad arguments.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if not __package__:  # run as a file (python benchmarks/run_all.py): the repository root on the path
    sys.path.insert(0, str(ROOT))
from benchmarks._common import RESULT_PREFIX, format_table  # noqa: E402

#: Distributions whose versions the page records (absent ones are listed as such).
VERSIONED = ("simcam-budget", "numpy", "scipy", "numba", "astropy", "pandas", "photutils",
             "galsim", "pyxel-sim", "sep", "mitsuba", "drjit", "dask", "zarr", "colour-science")

#: Options a benchmark gets in a full run (beside its defaults); none in a --quick run.
FULL_ARGS: dict[str, list[str]] = {"sweep": ["--dask"]}

#: Explanation written around each benchmark's measured table (the template text of the
#: page). A discovered benchmark without an entry here gets its script's docstring.
EXPLANATION: dict[str, tuple[str, str]] = {
    "render": ("Simulator: rendering", """\
The embedded seed-000 scenario: a full 2048 x 4096 two-chip frame with the 25-star target
and every detector effect (PRNU, dark + DSNU, shot, read, full well, per-chip ADC), from a
cached scene (PSF stamps computed once, as for a sequence of frames), beside plain numpy
doing the same noise with one `Generator`, and beside GalSim drawing 25 Airy stars and
adding its CCD noise on a frame of the same size. The detector's PRNU and DSNU maps are
computed once per camera (134 MB, kept) and each frame draws only its own noise; numpy's
maps likewise once (its every-frame figure kept, labelled). The detector chain alone per
frame (realistic and ideal), the maps alone, the fused chain drawing the maps every frame,
and the random-number floor: the frame's draws alone (Poisson + read normal, maps
precomputed; the old floor with the maps' draws too, labelled). The scene (spectra,
distortion, colour and 25 exact pixel-integrated PSF stamps), noisy 11x11 windows per
second (`render_windows`, serial and threaded), and the peak memory of one full frame
with the maps kept and of a camera's first frame that computes them.
Targets: a full frame in at most 0.15 s, the detector chain alone in at most 60 ms, at
least 100,000 windows per second, peak memory under 300 MB. GalSim's CCD noise and pyxel do fewer or other effects than our
chain; they are the peers the project names, not the same computation."""),
    "detector_noise": ("Simulator: detector chain alone", """\
The detector chain alone on a full 2048 x 4096 two-chip mosaic (PRNU, dark + DSNU + hot
pixels, Poisson shot noise, full-well clip, read noise, per-chip gain/offset ADC to
uint16), simcam's counter-based numba kernel with all threads and with one, per frame with
the detector's maps (PRNU, DSNU, hot pixels) computed once (`detector_maps`, the marginal
frame; the first frame with the maps, the maps alone, and the fused chain that draws them
every frame, labelled), beside plain numpy doing the same with one `Generator` (its maps
drawn once; its every-frame figure kept, labelled), GalSim's `CCDNoise` (shot + read noise
+ gain only) on the same expected image, and one pyxel 3 exposure of a CMOS of the same size
through an 11-model pipeline (configuration built in code in the script). Target: 60 ms
per frame. CPU time (all threads) is the steadier measure on a shared machine; wall time
is what a user waits."""),
    "centroid": ("Centroiding", """\
The same noisy 11x11 windows (Gaussian PSF sigma 1 px, 2e4 e-, background 100 e-, read
noise 5 e-) through each method: our CoG (given or border-median background), IWCoG and
Gaussian least-squares fit; photutils `centroid_com` in a loop, `centroid_sources` on the
windows tiled into one image, `centroid_2dg` on a subset; SEP `winpos`. The rms position
difference to photutils `centroid_com` is zero up to rounding for the identical
definitions. Then one 4096 x 2048 frame with 25 stars: our full-frame path with a
reference list (`budget.centroid.frames.centroid_frames([frame], reference_xy=ref)`) and without
one, beside photutils (sigma-clipped level and noise, threshold, `centroid_sources` at the
references) and SEP (background + extraction). Targets: at most 2 us per window for CoG;
at most 10 ms for the full frame with a reference list."""),
    "validate": ("Monte Carlo validation", """\
One full seed-000 protocol trial (TE + HSFE + chromatic + distortion, about 20,000
star-windows, centroided, published and improved estimators) on one core, best and
median; then K trials with the worker processes, wall time including the truths and the
workers' start-up. Targets: one trial in at most 30 ms on one core (0.1 s before), 1000 trials
in at most 2 minutes using both cores. Where a trial's time goes: the exact shot and read
noise of the window pixels with their ADC, the border medians and the centres of gravity
in one fused numba pass (`budget.starcam.kernels_trial`), most of it the Poisson draw; then the
scenes of the conditions (in the realistic world every condition's pose is new), the
published and improved estimators, tables and bookkeeping. The anatomy table measures the
floor under all of it: the trial's window-pixel draws (pixels x frames), the per-draw cost
of the exact sampler alone on the trial's own mean charges (`simcam.rng`: table inversion
below 10 e-, Hoermann's PTRS at and above, the ziggurat normal for the read noise), and
the product, the trial's random-number floor, beside numpy's `Generator` drawing the same
variates. A trial can be no faster than that floor while it draws these variates."""),
    "runner": ("Study machinery: start-up and workers", """\
The README's main job (`budget validate --trials 200` on the embedded seed-000 scenario)
end to end with 1 and with 2 worker processes (a new process each, as a user runs it;
the two counts' runs alternate, so that the machine's drift falls on both, and each
count's best is taken), and
the fixed cost of `budget validate` (the wall time of a 2-trial run minus two warm trials
and the truths' work, both measured in the same run) with a warm numba cache and with an
empty one (a fresh install). The fixed-cost runs use the default scenario with
`hsfe_truth_frames = 16`: the default's HSFE truth is many times the fixed cost in real
work (its time is printed below), and subtracting that much, measured in another process,
would drown the fixed cost in its noise. Targets: two workers give at least 1.8x the throughput of
one, and the main job ends within 5 s on 2 workers; fixed cost at most 2 s warm and at most 8 s with an empty cache. With an empty cache
numba compiles the kernels a trial and the truths call (about 30 functions); the study's
warm-up (`budget/starcam/warm.py`) splits them over two processes before the trials
start, so the run waits about half their compile time."""),
    "sweep": ("Sweeps", """\
Truth-mode points of the default camera (PSF width x PRNU; each point a new camera:
scenes, stamps and every class's truth) on 1 and 2 local worker processes, end to end and
in steady state, best over the repeats into a fresh store. Steady state counts all of a
point's work: the runner splits each truth into pieces and runs them as tasks of their
own before the points; from the moment as many tasks (of either kind) have finished as
there are workers (start-up, imports and JIT warm-up behind), the rate is the points
finished after it (a point when its last task is) over the time to the last point. Also
the cost of one validation point as its trial count grows (a least-squares line: fixed
cost plus cost per trial); in a full run also on a Dask
LocalCluster of 2 workers. The points use a light HSFE truth (100 noisy frames per
sub-pixel phase instead of the scenario's 400, which make a point dearer): the figures
measure the machinery; one point with the full truth is timed once for scale. Target:
at least 1.7x with 2 workers. More in [sweeps.md](sweeps.md)."""),
    "lens": ("Lens tracing", """\
A bundle of 100,000 rays of one field point and wavelength through the embedded 9-surface
star-camera lens (Mitsuba `llvm_ad_rgb` intersections, double-precision refinement and
refraction), beside the plain-numpy reference tracer of the tests on the same rays and
Mitsuba's `scalar_rgb` fallback; and the full table of 10 fields x 15 wavelengths x
100,000 rays with the focus pass and PSFs. Targets: a bundle in at most 50 ms
after warm-up, the table in at most 10 s. More in [lens.md](lens.md)."""),
    "harmonics": ("Inductosyn calibration", """\
Full seed-001 calibration trials: polygon face errors and four passes of noise, the lab
tables, the in-sequence and joint harmonic fits and the verification of both
compensations over 3600 points of the circle. Target: 10,000 trials in at most
2 s. Details in [inductosyn.md](inductosyn.md)."""),
    "whiskbroom": ("Whiskbroom TDI camera", """\
The two speed figures of seed 002's study, numba beside plain numpy: the 1000-trial
Monte Carlo synthesis over the arrays (draws, knowledge and true states, complex-step
image motion at the sampled field, residuals, worst column; target at most 1 s) and the
pixel-level MTF of one trial (96 stages, 4 clock phases, 1000 columns, along and across;
target at most 5 ms); for reference one state's image motion at every pixel and the
slanted-edge image of one trial. More in [whiskbroom.md](whiskbroom.md)."""),
    "scanmirror": ("GEO scan mirror", """\
The full default timeline of seed 003 (two area scans and the star dwell) with ground
points every 0.1 s: world construction, plan, attitude, deviation, nominal and true ground
points (target at most 0.5 s), with PROJ's `geos` inverse (pyproj) beside our
nominal mapping; one validation trial, and 1000 trials on 2 processes through the shared
runner, worker start-up included (target at most 20 s). More in [scanmirror.md](scanmirror.md)."""),
    "linecam": ("Line-camera star calibration", """\
The three figures of the line-camera study (seed 004): star selection (Hipparcos cone, apparent places
through astropy/ERFA) and identification of one pass of a 10 deg strip (target at most
50 ms), beside a numpy brute-force identification; one calibration of a few hundred star
observations, published and improved (target at most 20 ms), beside scipy
`least_squares` on the same residuals; and 1000 validation trials on 2 cores (target at
most 60 s). More in [linecam.md](linecam.md)."""),
    "robustness": ("Robustness against validate", """\
Issue 22's check: `budget <study> robustness` (the ideal world, each world effect alone and
all together, common random numbers, all cases in one worker pool, the truths shared
between cases whose effects leave them unchanged) costs at most 8 times the study's plain
`validate`. Measured on a real study with six or more effects (default the scan mirror,
seed 003: seven effects, nine cases, truths independent of every effect), on its embedded
default scenario, beside its plain `validate` of the same trials (200), seed and workers
(2), in one run, after an untimed warm-up. The primary figure is the CPU time of all
processes (this one and its joined workers); the wall time, what a user waits, is printed
with the load average before and after, since on a shared machine it measures the other
jobs as much as the code. With `c` cases every case still runs its own trials, so the
ratio's floor is about `c` times a validate's per-trial share; what one pool and shared
truths save is the fixed cost (worker start-up, world construction, truths) paid once
instead of `c` times. `--study toy` measures the toy world study of the tests instead,
with the cases also run as separate validates. More in
[architecture.md](architecture.md) (Robustness)."""),
    "plan": ("Protocol planning", """\
`budget <study> plan` searches a study's protocol knobs for the cheapest protocol whose
estimates meet required error quantiles, with common random numbers across candidates,
screening trials with adaptive stopping, a fitted averaging model proposing candidates and
bisection along lab time, then re-validates its answer on fresh trials. Target: a plan over
two knobs costs at most the trials of 20 validations, the re-validation included. Measured
on the planner's toy study (an offset averaged over frames and stage positions, lab time
linear in both, so that the cheapest protocol is known in closed form by Lagrange) for
several seeds: the trials each plan ran, counted by the study, over one validation's; the
plan's lab time above setup over the analytic optimum's (the 95 % quantile of 200 trials
moves the answer by about 13 % either way); the CPU time of a plan over one validation of
its answer (the toy's trials take microseconds: this is the planner's own work). More in
[planning.md](planning.md)."""),
}

INTRO = """\
Scripts in `benchmarks/`, each timing our code and its peers (the libraries the project
names, or plain numpy) side by side in one run, after a warm-up call (numba JIT / cache
load), best of several repeats. This page is generated: `python benchmarks/run_all.py`
runs every `benchmarks/bench_*.py` in turn and writes it from what they printed; edit the
template text in `benchmarks/run_all.py`, not this page. Each benchmark's last line,
`RESULT {json}`, carries its key figures, from which the summary table below is built.
The peers install with `pip install -e '.[bench]'` (photutils, GalSim, pyxel-sim, SEP); one
that is missing is reported as "not installed". `benchmarks/` is a package: the scripts share
their parser, machine line, timers and `RESULT` line through `benchmarks/_common.py`, and each
runs as a file (`python benchmarks/bench_render.py`) or as a module
(`python -m benchmarks.bench_render`). The harness's own tests (`benchmarks/test_run_all.py`)
run with the project's test command; timings are never asserted in the test suite. On a shared virtual machine repeated runs
vary by 10-40 % (more when other jobs run): the load before and after each benchmark is
recorded below; compare figures only within one run."""


@dataclass
class BenchRun:
    """Outcome of one benchmark script in this run."""

    name: str
    script: Path
    args: list[str]
    status: str = "not run"            # "ok", "failed (exit N)", "timed out", "no RESULT line"
    wall_s: float = 0.0
    load_before: tuple[float, float, float] | None = None
    load_after: tuple[float, float, float] | None = None
    stdout: str = ""
    stderr: str = ""
    result: dict | None = None
    notes: list[str] = field(default_factory=list)


def _interpreter() -> str:
    """The interpreter, named relative to the repository when it lives there (a page that is
    committed names no machine's paths)."""
    exe = Path(sys.executable)
    try:
        return str(exe.relative_to(ROOT))
    except ValueError:
        return exe.name


def discover(bench_dir: Path = HERE) -> dict[str, Path]:
    """Benchmark scripts ``bench_<name>.py`` of ``bench_dir`` by ``<name>``: those with an
    explanation first, in the page's order, then any others alphabetically."""
    found = {p.stem[len("bench_"):]: p for p in sorted(bench_dir.glob("bench_*.py"))}
    order = [n for n in EXPLANATION if n in found] + sorted(n for n in found if n not in EXPLANATION)
    return {n: found[n] for n in order}


def supports_quick(script: Path) -> bool:
    """Whether the script accepts ``--quick`` (it calls ``bench_parser`` or ``add_quick_flag``,
    or names it)."""
    text = script.read_text(encoding="utf-8")
    return "bench_parser(" in text or "add_quick_flag(" in text or '"--quick"' in text


def parse_result(stdout: str) -> dict | None:
    """The JSON of the last ``RESULT {json}`` line of ``stdout``; None if there is none.

    Raises
    ------
    ValueError
        When the last such line is not a JSON object.
    """
    lines = [ln for ln in stdout.splitlines() if ln.startswith(RESULT_PREFIX)]
    if not lines:
        return None
    payload = json.loads(lines[-1][len(RESULT_PREFIX):])
    if not isinstance(payload, dict) or not isinstance(payload.get("figures", []), list):
        raise ValueError("RESULT line: expected a JSON object with a 'figures' list")
    return payload


def _load() -> tuple[float, float, float] | None:
    try:
        return os.getloadavg()
    except OSError:  # pragma: no cover - not on Linux
        return None


def run_one(name: str, script: Path, *, quick: bool, timeout_s: float) -> BenchRun:
    """Run one benchmark script in a subprocess; capture its output, load and RESULT."""
    args = [] if quick else list(FULL_ARGS.get(name, []))
    run = BenchRun(name=name, script=script, args=args)
    if quick:
        if supports_quick(script):
            args.append("--quick")
        else:
            run.notes.append("has no --quick option: ran with its own defaults")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONUNBUFFERED"] = "1"
    run.load_before = _load()
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, str(script), *args], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout_s)
        code = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)        # the script and the workers it started
        out, err = proc.communicate()
        code = None
    run.wall_s = time.perf_counter() - t0
    run.load_after = _load()
    run.stdout, run.stderr = out, err
    if code is None:
        run.status = f"timed out after {timeout_s:.0f} s"
    elif code != 0:
        run.status = f"failed (exit {code})"
    else:
        try:
            run.result = parse_result(out)
            run.status = "ok" if run.result is not None else "no RESULT line"
        except (ValueError, json.JSONDecodeError) as exc:
            run.status = f"bad RESULT line ({exc})"
    return run


def machine_info() -> dict[str, str]:
    """CPU, cores, memory, OS, Python and the versions of the measured libraries."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    mem = "unknown"
    try:
        with open("/proc/meminfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    mem = f"{int(line.split()[1]) / 1024**2:.1f} GiB"
                    break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    info = {"cpu": cpu, "logical cores": f"{os.cpu_count()} ({usable} usable)", "memory": mem,
            "os": f"{platform.system()} {platform.release()}",
            "python": f"{platform.python_version()} ({_interpreter()})"}
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, check=True).stdout.strip()
        info["commit"] = head + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        info["commit"] = "unknown"
    return info


def versions() -> dict[str, str]:
    out = {}
    for dist in VERSIONED:
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def _fmt(v: float | None) -> str:
    """Four significant digits (thousands separators from 10,000 on)."""
    if v is None:
        return ""
    if abs(v) >= 1e4:
        return f"{v:,.0f}"
    return f"{v:.4g}"


def summary_rows(runs: list[BenchRun], *, quick: bool = False) -> list[list[str]]:
    """Rows: benchmark, what, ours, peer, peer value, ratio (>1: ours better), target, met.

    With ``quick`` the verdicts carry "(quick)": a smoke run measures nothing.
    """
    rows = []
    for run in runs:
        if run.result is None:
            rows.append([run.name, run.status, "", "", "", "", "", ""])
            continue
        for f in run.result.get("figures", []):
            unit = f.get("unit", "")
            ours, peer_v, target = f.get("ours"), f.get("peer_value"), f.get("target")
            lower = f.get("better", "lower") == "lower"
            ratio = ""
            if ours is not None and peer_v is not None and ours > 0 and peer_v > 0:
                r = peer_v / ours if lower else ours / peer_v
                ratio = f"{r:.2f}x" if r < 10 else f"{r:.0f}x"
            peer_cell = ""
            if f.get("peer"):
                peer_cell = (f"{_fmt(peer_v)} {unit}" if peer_v is not None
                             else (f.get("peer_status") or "not measured"))
            met = ""
            if target is not None:
                if ours is None:
                    met = "not measured"
                else:
                    met = "yes" if (ours <= target if lower else ours >= target) else "**no**"
                    met += " (quick)" if quick else ""
            tgt = ""
            if target is not None:
                tgt = f"{'<=' if lower else '>='} {_fmt(target)} {unit}"
                if f.get("target_source"):
                    tgt += f" ({f['target_source']})"
            rows.append([run.name, f.get("what", f.get("key", "")),
                         f"{_fmt(ours)} {unit}" if ours is not None else "not measured",
                         f.get("peer") or "", peer_cell, ratio, tgt, met])
    return rows


def _md_table(headers: list[str], rows: list[list[str]]) -> str:
    def cell(c: str) -> str:
        return str(c).replace("|", "\\|").replace("\n", " ")

    out = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    out += ["| " + " | ".join(cell(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _load_str(load: tuple[float, float, float] | None) -> str:
    return " / ".join(f"{x:.2f}" for x in load) if load else "n/a"


def _docstring_paragraph(script: Path) -> str:
    import ast

    try:
        doc = ast.get_docstring(ast.parse(script.read_text(encoding="utf-8"))) or ""
    except (OSError, SyntaxError, UnicodeDecodeError):
        doc = ""
    paras = [p.strip() for p in doc.split("\n\n") if p.strip()]
    return "\n\n".join(paras[:2]) if paras else "(no description)"


def render_page(runs: list[BenchRun], *, quick: bool, only: list[str] | None,
                started: _dt.datetime, finished: _dt.datetime, command: str) -> str:
    """The Markdown page."""
    info = machine_info()
    vers = versions()
    lines = ["# Benchmarks", "",
             "<!-- Generated by benchmarks/run_all.py: edit its template text, not this page. -->",
             "", INTRO, ""]
    if quick:
        lines += ["> **Smoke run (`--quick`)**: fewer repeats and trials; the figures below only "
                  "show that every benchmark runs end to end and are not measurements.", ""]
    if only:
        lines += [f"> **Partial run**: only {', '.join(only)}.", ""]
    lines += ["## Machine and run", "",
              f"Measured on {started:%Y-%m-%d} from {started:%H:%M} to {finished:%H:%M} UTC "
              f"with `{command}`.", ""]
    lines += [_md_table(["machine", ""], [[k, v] for k, v in info.items()]), ""]
    lines += ["Versions: " + ", ".join(f"{k} {v}" for k, v in vers.items()) + ".", ""]
    lines += ["System load (1 / 5 / 15 min averages) before and after each benchmark; a load "
              f"above the {os.cpu_count()} logical cores means other jobs competed for them:", ""]
    lines += [_md_table(["benchmark", "options", "wall s", "load before", "load after", "status"],
                        [[f"`{r.script.name}`", " ".join(r.args) or "(defaults)", f"{r.wall_s:.0f}",
                          _load_str(r.load_before), _load_str(r.load_after),
                          r.status + ("; " + "; ".join(r.notes) if r.notes else "")]
                         for r in runs]), ""]
    lines += ["## Summary: ours against the peers measured in the same run, and the project's targets",
              "",
              "The ratio is the peer's time over ours (or our rate over the peer's): above 1, ours "
              "is faster or smaller. The peer is measured by the same script in the same run; "
              "peers that do fewer or other effects are named with what they do.", ""]
    lines += [_md_table(["benchmark", "what", "ours", "peer", "peer value", "ratio", "target", "met?"],
                        summary_rows(runs, quick=quick)), ""]
    for r in runs:
        title, text = EXPLANATION.get(r.name, (r.name, _docstring_paragraph(r.script)))
        # a stable anchor per benchmark, which the other pages link to (docs/x.md -> benchmarks.md#bench-NAME)
        lines += [f'<a id="{anchor(r.name)}"></a>', "", f"## {title} (`{r.script.name}`)", "", text, ""]
        if r.notes:
            lines += ["Note: " + "; ".join(r.notes) + ".", ""]
        body = "\n".join(ln for ln in r.stdout.splitlines() if not ln.startswith(RESULT_PREFIX)).rstrip()
        cmd = " ".join(["python", f"benchmarks/{r.script.name}", *r.args])
        lines += [f"Output of `{cmd}`:", "",
                  "```text", body or "(no output)", "```", ""]
        if r.status != "ok":
            tail = "\n".join(r.stderr.rstrip().splitlines()[-20:])
            lines += [f"Status: **{r.status}**." + (" Last lines of its standard error:" if tail else ""), ""]
            if tail:
                lines += ["```text", tail, "```", ""]
    return "\n".join(lines).rstrip() + "\n"


def anchor(name: str) -> str:
    """The anchor of benchmark ``name``'s section of the page: ``bench-<name>``."""
    return f"bench-{name}"


#: The README's generated block: the main job's wall time, from ``bench_runner.py`` in this run.
README_BEGIN = "<!-- generated by benchmarks/run_all.py: main-job time -->"
README_END = "<!-- end of generated block -->"


def readme_main_job(runs: list[BenchRun], *, date: str | None = None,
                    page: str = "docs/benchmarks.md") -> str | None:
    """The README's sentence on the main job's wall time, from this run's ``runner`` figures;
    None when ``bench_runner.py`` did not run or lacks them.

    The first run after an install also compiles the numba kernels: its extra time is
    the difference of the fixed costs with an empty and with a warm cache, both measured
    by the same script.
    """
    run = next((r for r in runs if r.name == "runner" and r.result is not None), None)
    if run is None:
        return None
    figs = {f.get("key"): f.get("ours") for f in run.result.get("figures", [])}
    two, cold, warm = figs.get("two_workers_s"), figs.get("fixed_cost_cold_s"), figs.get("fixed_cost_warm_s")
    if two is None:
        return None
    trials = run.result.get("trials", 200)
    text = f"{trials} trials: {two:.0f} s on 2 cores, the report aside"
    if cold is not None and warm is not None:
        text += f", about {two + cold - warm:.0f} s the first time after the install, when numba compiles its kernels"
    return (text + f" (measured by [`benchmarks/run_all.py`]({page}#{anchor('runner')})"
            + (f" on {date}" if date else "") + ")")


def rewrite_block(text: str, content: str, *, begin: str = README_BEGIN, end: str = README_END) -> str:
    """``text`` with what lies between the markers ``begin`` and ``end`` replaced by ``content``.

    Raises
    ------
    ValueError
        When the markers are not both present once, in that order.
    """
    if text.count(begin) != 1 or text.count(end) != 1 or text.index(begin) > text.index(end):
        raise ValueError(f"expected one {begin!r} followed by one {end!r}")
    head, rest = text.split(begin)
    _, tail = rest.split(end)
    return head + begin + content + end + tail


def main(argv: list[str] | None = None) -> int:
    available = discover()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: pass --quick to every benchmark that has it")
    ap.add_argument("--only", default=None,
                    help=f"comma-separated subset of: {', '.join(available)}")
    ap.add_argument("--out", default=str(ROOT / "docs" / "benchmarks.md"),
                    help="page to write (default: docs/benchmarks.md)")
    ap.add_argument("--timeout", type=float, default=None,
                    help="seconds allowed to each benchmark (default 3600, 900 with --quick)")
    ap.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    args = ap.parse_args(argv)
    if args.list:
        for name, path in available.items():
            print(f"{name:16s} {path.relative_to(ROOT)}"
                  f"{'' if supports_quick(path) else '  (no --quick)'}")
        return 0
    only = None
    if args.only:
        only = [re.sub(r"^bench_|\.py$", "", s.strip()) for s in args.only.split(",") if s.strip()]
        unknown = [s for s in only if s not in available]
        if unknown:
            print(f"error: --only: unknown benchmark(s) {', '.join(unknown)}; "
                  f"available: {', '.join(available)}", file=sys.stderr)
            return 2
    if args.timeout is not None and args.timeout <= 0:
        print("error: --timeout: must be > 0", file=sys.stderr)
        return 2
    timeout_s = args.timeout or (900.0 if args.quick else 3600.0)
    out_path = Path(args.out)
    if not out_path.parent.is_dir():
        print(f"error: --out: folder {out_path.parent} does not exist", file=sys.stderr)
        return 2
    names = only or list(available)
    started = _dt.datetime.now(_dt.timezone.utc)
    runs = []
    for name in names:
        print(f"[run_all] {available[name].name}: running"
              f"{' (quick)' if args.quick else ''}, load {_load_str(_load())}", flush=True)
        run = run_one(name, available[name], quick=args.quick, timeout_s=timeout_s)
        print(f"[run_all] {available[name].name}: {run.status} in {run.wall_s:.0f} s, "
              f"load after {_load_str(run.load_after)}", flush=True)
        runs.append(run)
    finished = _dt.datetime.now(_dt.timezone.utc)
    command = "python benchmarks/run_all.py" + "".join(
        f" {a}" for a in (["--quick"] if args.quick else []) + ([f"--only {','.join(only)}"] if only else []))
    page = render_page(runs, quick=args.quick, only=only, started=started, finished=finished,
                       command=command)
    tmp = out_path.with_name(out_path.name + ".tmp")
    tmp.write_text(page, encoding="utf-8")
    tmp.replace(out_path)
    readme = ROOT / "README.md"
    sentence = readme_main_job(runs, date=f"{started:%Y-%m-%d}")
    if not args.quick and out_path.resolve() == (ROOT / "docs" / "benchmarks.md").resolve() and sentence:
        # the README's main-job time comes from this run too (a full run onto the page only)
        try:
            readme.write_text(rewrite_block(readme.read_text(encoding="utf-8"), sentence), encoding="utf-8")
            print(f"[run_all] updated the main-job time in {readme}")
        except ValueError as exc:
            print(f"[run_all] README.md not updated: {exc}", file=sys.stderr)
    rows = summary_rows(runs, quick=args.quick)
    print()
    print(format_table(["benchmark", "what", "ours", "peer", "peer value", "ratio", "target", "met?"],
                       [[c.replace("**", "") for c in r] for r in rows]))
    print(f"\n[run_all] wrote {out_path}")
    return 0 if all(r.status == "ok" for r in runs) else 1


if __name__ == "__main__":
    raise SystemExit(main())
