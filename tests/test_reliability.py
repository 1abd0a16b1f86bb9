"""Bad input and faults (docs/reliability.md has the table).

* Fuzz: random bytes and random structures fed to every reader through the command line
  (in this process, through the console scripts' ``main``): exit status 2, every stderr
  line an ``error:`` line, the first naming the file, no traceback (an exception escaping
  ``main`` fails the test), nothing written.
* Faults: SIGTERM / SIGINT in the middle of the long commands (subprocesses on the tiny
  camera of ``tests/tiny_camera.py``): exit status 128 + signal, one line, no partial
  output, no child process left; ``kill -9`` of a sweep with worker processes leaves no
  worker alive after 5 s and the resumed store equals an uninterrupted one; stale partial
  folders of dead runs are removed.
* Sizes, safe names, compressed frames.

The subprocess tests poll for the state they need (files written, workers started, the
signal handler installed) with generous bounded waits, never fixed sleeps, so they hold on
a loaded 2-core machine.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import textwrap
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cli_capture import run_cli
from tiny_camera import TINY

REPO = Path(__file__).resolve().parents[1]
# derandomize: the same examples on every machine and run (CI must not depend on luck or on a
# .hypothesis database left behind); 25 examples per reader keep the suite fast
FUZZ = settings(max_examples=25, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])


# ----------------------------------------------------------------------------- helpers
def _cli(prog: str, argv: list[str]) -> tuple[int, str]:
    """Run ``simcam`` or ``budget`` in this process; (exit status, stderr)."""
    code, _out, err = run_cli(prog, argv)
    return code, err


def _assert_refused(code: int, err: str, named: str, folder: Path, before: set) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, err
    assert lines and all(ln.startswith("error: ") for ln in lines), err
    assert named in lines[0], err
    assert "Traceback" not in err
    assert {p.name for p in folder.iterdir()} == before, "something was written"


def _loads_fine(reader: str, path: Path) -> bool:
    """Whether the reader accepts the file (then it is not bad input: the case is skipped)."""
    try:
        LOADERS[reader](path)
    except Exception:  # noqa: BLE001 - refused (or crashed: the command must then say so in one line)
        return False
    return True


def _fuzz_file(tmp: Path, name: str, payload: bytes, prog: str, argv, *, named=None, reader=None):
    """Write ``payload`` to ``tmp/name``, run the command (FILE and OUT substituted), check refusal."""
    f = tmp / name
    f.write_bytes(payload)
    if reader is not None:
        assume(not _loads_fine(reader, f))
    before = {p.name for p in tmp.iterdir()}
    args = [str(f) if a == "FILE" else str(tmp / "out") if a == "OUT" else
            str(tmp / "out.json") if a == "OUT.json" else str(tmp) if a == "DIR" else a for a in argv]
    code, err = _cli(prog, args)
    _assert_refused(code, err, named or str(f), tmp, before)


def _load_sweep(path):
    from budget.sweeps.spec import load_sweep

    return load_sweep(path)


def _load_scn(path):
    from simcam.starcam.scenario import load

    return load(path)


def _load_ind(path):
    from simcam.encoder.inductosyn import load

    return load(str(path))


def _load_budget(path):
    from budget.starcam.combine import load_budget_toml

    return load_budget_toml(path)


def _load_lens(path):
    from simcam.starcam.lens.prescription import load_prescription

    return load_prescription(path)


def _load_csv(path):
    from budget.inductosyn.harmonics import read_calibration_csv

    return read_calibration_csv(path=path)


LOADERS = {"scenario": _load_scn, "scenario (validate)": _load_scn, "inductosyn scenario": _load_ind,
           "budget combination": _load_budget, "sweep file": _load_sweep, "lens prescription": _load_lens,
           "polygon": _load_csv}

#: every TOML reader and the command that reads it (FILE: the fuzzed file)
TOML_READERS = {
    "scenario": ("simcam", ["render", "FILE", "--out", "OUT", "--no-progress"]),
    "scenario (validate)": ("budget", ["validate", "FILE", "--trials", "2", "--workers", "1", "--no-progress",
                                       "--json", "OUT.json"]),
    "inductosyn scenario": ("budget", ["inductosyn", "validate", "FILE", "--trials", "2", "--workers", "1",
                                               "--json", "OUT.json"]),
    "budget combination": ("budget", ["starcam", "combine", "FILE", "--json", "OUT.json"]),
    "sweep file": ("budget", ["sweep", "FILE", "--out", "OUT", "--no-progress"]),
    "lens prescription": ("simcam", ["optics", "FILE", "--out", "OUT"]),
}

# random structures: real field names mixed with junk, values of every TOML kind
_KEYS = st.sampled_from(["camera", "detector", "optics", "lab", "name", "seed", "chip_cols", "exposure_s",
                         "prnu_rms", "surfaces", "parameters", "base", "encoder", "te", "lsfe", "stars",
                         "radius_mm", "glass", "zz"]) | st.text(min_size=1, max_size=6)
_SCALARS = (st.integers(min_value=-(2**63), max_value=2**63 - 1) | st.floats(allow_nan=True, allow_infinity=True)
            | st.sampled_from([1e308, -1e308, 0.0, 1e-320]) | st.text(max_size=8) | st.booleans())
_VALUES = st.recursive(_SCALARS, lambda inner: st.lists(inner, max_size=3) | st.dictionaries(_KEYS, inner, max_size=3),
                       max_leaves=8)
STRUCTURES = st.dictionaries(_KEYS, _VALUES, min_size=1, max_size=4)


@pytest.mark.parametrize("reader", list(TOML_READERS))
@FUZZ
@given(payload=st.binary(max_size=200))
def test_fuzz_bytes_to_toml_readers(reader, payload):
    prog, argv = TOML_READERS[reader]
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        _fuzz_file(Path(d), "input.toml", payload, prog, argv, reader=reader)


@pytest.mark.parametrize("reader", list(TOML_READERS))
@FUZZ
@given(data=STRUCTURES)
def test_fuzz_structures_to_toml_readers(reader, data):
    try:
        text = tomli_w.dumps(data)
    except (TypeError, ValueError):  # what TOML cannot hold (e.g. NaN keys never arise)
        assume(False)
    prog, argv = TOML_READERS[reader]
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        _fuzz_file(Path(d), "input.toml", text.encode(), prog, argv, reader=reader)


def _csv(rows: list[list]) -> bytes:
    return "\n".join(",".join(str(c) for c in r) for r in rows).encode()


_CELLS = (st.integers(-5, 5) | st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from(["1e308", "", "x", "..", "/etc/passwd", "a\"b"])
          | st.text(alphabet=st.characters(blacklist_characters=",\n\r"), max_size=5))


@FUZZ
@given(payload=st.binary(max_size=300))
def test_fuzz_bytes_to_polygon_csv(payload):
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        _fuzz_file(Path(d), "polygon.csv", payload, "budget",
                   ["inductosyn", "fit", "FILE", "--period", "short", "--json", "OUT.json"], reader="polygon")


@FUZZ
@given(rows=st.lists(st.lists(_CELLS, min_size=1, max_size=3), max_size=6),
       header=st.sampled_from([["angle_deg", "error_arcsec"], ["angle_deg", "error_arcsec", "note"], ["a", "b"]]))
def test_fuzz_structures_to_polygon_csv(rows, header):
    import tempfile

    with tempfile.TemporaryDirectory() as d:  # a table the reader accepts is not bad input: skipped
        _fuzz_file(Path(d), "polygon.csv", _csv([header, *rows]), "budget",
                   ["inductosyn", "fit", "FILE", "--period", "short", "--json", "OUT.json"], reader="polygon")


@FUZZ
@given(payload=st.binary(max_size=300))
def test_fuzz_bytes_to_manifest(payload):
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        # the manifest is DIR/manifest.csv: any message about it or its frames names DIR
        _fuzz_file(Path(d), "manifest.csv", payload, "budget", ["starcam", "measure", "te", "DIR", "--json", "OUT.json",
                                                                 "--no-progress"], named=d)


@FUZZ
@given(cols=st.lists(st.sampled_from(["file", "condition", "frame", "filter_nm", "field", "dark", "junk"]),
                     min_size=1, max_size=6, unique=True),
       rows=st.lists(st.lists(_CELLS, min_size=6, max_size=6), max_size=4))
def test_fuzz_structures_to_manifest(cols, rows):
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        _fuzz_file(Path(d), "manifest.csv", _csv([cols, *[r[:len(cols)] for r in rows]]), "budget",
                   ["starcam", "measure", "te", "DIR", "--json", "OUT.json", "--no-progress"], named=d)


def _good_fits() -> bytes:
    """A valid 64 x 80 uint16 frame (bytes); made once."""
    global _GOOD
    if _GOOD is None:
        from astropy.io import fits

        buf = io.BytesIO()
        fits.PrimaryHDU(np.arange(64 * 80, dtype=np.uint16).reshape(64, 80)).writeto(buf)
        _GOOD = buf.getvalue()
    return _GOOD


_GOOD = None


@FUZZ
@given(payload=st.binary(max_size=400), cut=st.integers(0, 100_000), flip=st.integers(0, 100_000),
       kind=st.sampled_from(["random", "truncated", "damaged"]))
def test_fuzz_fits_frames(payload, cut, flip, kind):
    """Random bytes, a valid frame cut short, or a valid frame with a header byte changed
    (a change that leaves a readable image is not bad input: skipped)."""
    good = _good_fits()
    if kind == "truncated":
        payload = good[:cut % len(good)]
    elif kind == "damaged":
        b = bytearray(good)
        b[flip % 2880] = (b[flip % 2880] + 1 + cut % 200) % 256
        payload = bytes(b)
    import tempfile

    from simcam.infra.errors import UserInputError
    from simcam.io import read_frame

    with tempfile.TemporaryDirectory() as d:
        (Path(d) / "manifest.csv").write_text("file,condition\nf0.fits,0\nf1.fits,0\n")
        (Path(d) / "f1.fits").write_bytes(good)
        (Path(d) / "f0.fits").write_bytes(payload)
        try:
            read_frame(Path(d) / "f0.fits")
            assume(False)
        except UserInputError:
            pass
        _fuzz_file(Path(d), "f0.fits", payload, "budget", ["starcam", "measure", "te", "DIR", "--json", "OUT.json",
                                                           "--no-progress"], named=str(Path(d) / "f0.fits"))


# ----------------------------------------------------------------------------- named cases
def test_issue_cases_are_one_line_naming_file_and_field(tmp_path):
    cases = {
        "exposure.toml": ("[camera]\nexposure_s = 1e308\n", "camera.exposure_s"),
        "prnu.toml": ("[detector]\nprnu_rms = nan\n", "detector.prnu_rms: must be a finite number"),
        "empty.toml": ("", "empty"),
        "huge.toml": ("[detector]\nchip_cols = 1000000000\n", "of memory"),
    }
    for name, (text, needle) in cases.items():
        (tmp_path / name).write_text(text)
        before = {p.name for p in tmp_path.iterdir()}
        code, err = _cli("simcam", ["render", str(tmp_path / name), "--out", str(tmp_path / "o"), "--no-progress"])
        _assert_refused(code, err, str(tmp_path / name), tmp_path, before)
        assert needle in err and len(err.strip().splitlines()) == 1, err
    code, err = _cli("budget", ["validate", "--trials", "1000000000000", "--no-progress"])
    assert code == 2 and "--trials 1000000000000" in err and "of memory" in err and len(err.splitlines()) == 1
    csv = tmp_path / "big.csv"
    csv.write_text("angle_deg,error_arcsec\n0,1\n15,1e308\n30,2\n")
    code, err = _cli("budget", ["inductosyn", "fit", str(csv), "--period", "short"])
    assert code == 2 and f"{csv}:3: out of range" in err
    csv.write_text("angle_deg,error_arcsec\n0,1\n15,2\n375,3\n")
    code, err = _cli("budget", ["inductosyn", "fit", str(csv), "--period", "short"])
    assert code == 2 and f"{csv}:4: duplicated angle: angle_deg 375 repeats line 3's 15" in err


def test_sweep_of_a_billion_values_is_refused_before_expanding(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    p = tmp_path / "big.toml"
    p.write_text('kind = "starcam"\nbase = "tiny.toml"\nseed = 1\nevaluate = "truth"\n[parameters]\n'
                 '"lab.source.match_v_mag" = {start = 6.0, stop = 8.0, num = 1000000000}\n')
    code, err = _cli("budget", ["sweep", str(p), "--out", str(tmp_path / "s"), "--no-progress"])
    # the message names the count of points: refused from the count, before any value is made
    assert code == 2 and f"{p}: parameters: 1e+09 points" in err and "of memory" in err, err
    assert not (tmp_path / "s").exists()


def test_frame_count_that_cannot_fit_on_disk_is_refused(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    code, err = _cli("simcam", ["render", str(tmp_path / "tiny.toml"), "--frames", "1000000000",
                                "--out", str(tmp_path / "r"), "--no-progress"])
    assert code == 2 and "--frames 1000000000" in err and "of disk" in err and "free at" in err, err
    assert not (tmp_path / "r").exists() and not list(tmp_path.glob(".r.partial.*"))


def test_manifest_entries_stay_in_the_dataset_folder(tmp_path):
    d = tmp_path / "data"
    d.mkdir()
    (d / "manifest.csv").write_text("file,condition\n../outside.fits,0\nf1.fits,0\n")
    code, err = _cli("budget", ["starcam", "measure", "te", str(d), "--no-progress"])
    assert code == 2 and "row 2: file '../outside.fits' is outside the dataset folder" in err
    assert "--allow-outside-files" in err
    (d / "manifest.csv").write_text(f"file,condition\n{tmp_path / 'abs.fits'},0\nf1.fits,0\n")
    code, err = _cli("budget", ["starcam", "measure", "te", str(d), "--no-progress"])
    assert code == 2 and "outside the dataset folder" in err
    # allowed explicitly: the entry is read (and here reported missing, by its path)
    code, err = _cli("budget", ["starcam", "measure", "te", str(d), "--no-progress", "--allow-outside-files"])
    assert code == 2 and f"{tmp_path / 'abs.fits'}: frame file not found" in err


def test_names_from_inputs_become_safe_file_names(tmp_path, monkeypatch):
    from simcam.starcam.lens.prescription import load_prescription
    from simcam.starcam.lens.products import cache_dir, cache_path
    from simcam.infra.lifecycle import safe_filename

    assert safe_filename("../../EVIL") == "EVIL" and safe_filename("..") == "unnamed"
    assert safe_filename("a/b\\c d\x00e") == "a_b_c_d_e" and safe_filename(".hidden") == "hidden"
    monkeypatch.setenv("SIMCAM_CACHE_DIR", str(tmp_path / "cache"))
    data = tomllib.loads((REPO / "simcam" / "data" / "lenses" / "star_camera.toml").read_text())
    data["name"] = "../../EVIL"
    evil = tmp_path / "evil.toml"
    evil.write_text(tomli_w.dumps(data))
    p = load_prescription(evil)
    assert p.name == "../../EVIL"
    path = cache_path(p)
    assert path.parent == cache_dir() and path.name.startswith("EVIL-")


def test_compressed_frames_round_trip_exactly_and_are_measured(tmp_path):
    """Rice tile compression is lossless for integer frames: the frames read back equal the
    uncompressed ones bit for bit, so `budget measure` gives identical centroids."""
    from budget.starcam.measure import measure_frames
    from simcam.io import read_frame

    (tmp_path / "tiny.toml").write_text(TINY)
    for tag, extra in (("plain", []), ("rice", ["--compress"])):
        code, err = _cli("budget", ["starcam", "simulate", "te", str(tmp_path / "tiny.toml"), "--frames", "3",
                                    "--out", str(tmp_path / tag), "--no-progress", *extra])
        assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "plain").glob("*.fits"))
    assert names and names == sorted(p.name for p in (tmp_path / "rice").glob("*.fits"))
    for n in names:
        a, ha = read_frame(tmp_path / "plain" / n)
        b, hb = read_frame(tmp_path / "rice" / n)
        np.testing.assert_array_equal(a, b)  # lossless: bit-identical is the point
        assert ha["SCENHASH"] == hb["SCENHASH"] and hb["BITDEPTH"] == ha["BITDEPTH"]
    ca, _, _ = measure_frames("te", tmp_path / "plain")
    cb, _, _ = measure_frames("te", tmp_path / "rice")
    assert ca.equals(cb)


def test_stale_partial_folder_of_a_dead_run_is_removed_and_reported(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".r.partial.{dead.pid}.abcd"
    stale.mkdir()
    (stale / "frame_0000.fits").write_bytes(b"x" * 1000)
    keep = tmp_path / f".r.partial.{os.getppid()}.live"  # a live process: left alone
    keep.mkdir()
    (tmp_path / "tiny.toml").write_text(TINY)
    code, err = _cli("simcam", ["render", str(tmp_path / "tiny.toml"), "--out", str(tmp_path / "r"), "--no-progress"])
    assert code == 0, err
    assert not stale.exists() and f"removed {stale}" in err and f"pid {dead.pid}" in err
    assert keep.exists() and (tmp_path / "r" / "frame_0000.fits").is_file()


# ----------------------------------------------------------------------------- faults (subprocesses)
def _start(args: list[str], cwd: Path, log: Path) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    with open(log, "wb") as fh:  # the child keeps its own copy of the descriptor
        return subprocess.Popen([sys.executable, "-m", *args], cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                                stderr=fh, start_new_session=True)


def _wait_for(cond, timeout: float, proc: subprocess.Popen | None = None, what: str = "") -> None:
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if cond():
            return
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"process ended (rc {proc.returncode}) before {what}")
        time.sleep(0.05)
    pytest.fail(f"timed out waiting for {what}")


def _handler_installed(pid: int) -> bool:
    """Whether the process catches SIGTERM (our handler is in place: the command started)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signal.SIGTERM - 1) & 1)
    except OSError:
        return False
    return False


def _children(pid: int) -> list:
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _all_gone(procs, timeout: float) -> bool:
    import psutil

    _, alive = psutil.wait_procs(procs, timeout=timeout)
    return not alive


def _stop(proc: subprocess.Popen, sig: int, timeout: float = 120) -> int:
    proc.send_signal(sig)
    try:
        return proc.wait(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


@pytest.mark.parametrize("sig", [signal.SIGTERM])  # SIGINT: the same handler (test_sigint_while_starting)
def test_render_interrupted_leaves_no_partial_output(tmp_path, sig):
    (tmp_path / "tiny.toml").write_text(TINY)
    log = tmp_path / "err.txt"
    proc = _start(["simcam", "render", "tiny.toml", "--frames", "2000", "--out", "r", "--no-progress"], tmp_path, log)
    _wait_for(lambda: any(len(list(p.iterdir())) >= 2 for p in tmp_path.glob(".r.partial.*")), 180, proc,
              "two frames written")
    rc = _stop(proc, sig)
    err = log.read_text()
    assert rc == 128 + sig, err
    assert err.strip().splitlines() == [f"interrupted ({signal.Signals(sig).name})"], err
    assert not (tmp_path / "r").exists() and not list(tmp_path.glob(".r.partial.*"))


def test_simulate_sigterm_leaves_no_partial_output(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    log = tmp_path / "err.txt"
    proc = _start(["budget", "starcam", "simulate", "hsfe", "tiny.toml", "--frames", "300", "--out", "lab",
                   "--no-progress"], tmp_path, log)
    _wait_for(lambda: any(len(list(p.iterdir())) >= 2 for p in tmp_path.glob(".lab.partial.*")), 180, proc,
              "two frames written")
    rc = _stop(proc, signal.SIGTERM)
    assert rc == 143, log.read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["err.txt", "tiny.toml"]


def _run_until_workers(args, tmp_path, n_workers: int, what: str):
    log = tmp_path / "err.txt"
    proc = _start(args, tmp_path, log)
    # the pool's workers (beside them, a spawned pool has multiprocessing's resource tracker;
    # a forked one, budget.runner.executors.start_method, has none)
    _wait_for(lambda: len(_pool_workers(proc.pid)) >= n_workers and _handler_installed(proc.pid), 180, proc, what)
    return proc, log, _children(proc.pid)


def _pool_workers(pid: int) -> list:
    """The children of ``pid`` that are not multiprocessing's resource tracker."""
    import psutil

    out = []
    for c in _children(pid):
        try:
            if not any("resource_tracker" in a for a in c.cmdline()):
                out.append(c)
        except psutil.NoSuchProcess:
            pass
    return out


def test_validate_sigterm_ends_its_workers(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    proc, log, kids = _run_until_workers(
        ["budget", "validate", "tiny.toml", "--trials", "100000", "--workers", "2", "--no-progress",
         "--json", "v.json", "--report", "rep"], tmp_path, 1, "its worker")  # the command's process is the other
    rc = _stop(proc, signal.SIGTERM)
    assert rc == 143, log.read_text()
    assert _all_gone(kids, 10), [k.pid for k in kids]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["err.txt", "tiny.toml"]


#: four truth-mode points of the tiny camera (as in tests/test_sweep_run.py, smaller)
GRID = """
    name = "tiny grid"
    kind = "starcam"
    base = "tiny.toml"
    seed = 11
    evaluate = "truth"
    [parameters]
    "lab.source.match_v_mag" = [6.0, 7.0]
    "optics.psf.sigma0_px" = [0.8, 1.1]
"""


@pytest.fixture(scope="module")
def grid_ref(tmp_path_factory):
    from budget.sweeps.run import open_sweep, run_sweep

    d = tmp_path_factory.mktemp("ref")
    (d / "tiny.toml").write_text(TINY)
    (d / "sweep.toml").write_text(textwrap.dedent(GRID))
    run_sweep(str(d / "sweep.toml"), d / "store", inline=True)
    return open_sweep(d / "store")


@pytest.mark.parametrize("sig", [signal.SIGKILL])  # SIGTERM: test_validate_sigterm_ends_its_workers
def test_killed_sweep_leaves_no_worker_and_resumes_exactly(tmp_path, grid_ref, sig):
    """kill -9 of `budget sweep --workers 2` while its workers compute: they (and a
    spawned pool's resource tracker) are gone within 5 s; the next run finishes the
    store, equal to an uninterrupted run's."""
    from budget.sweeps.run import open_sweep, run_sweep

    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "sweep.toml").write_text(textwrap.dedent(GRID))
    proc, log, kids = _run_until_workers(["budget", "sweep", "sweep.toml", "--out", "store", "--workers", "2",
                                          "--no-progress"], tmp_path, 2, "two workers")

    def computing() -> bool:  # a point written: the workers are past their start-up
        import zarr

        if not (tmp_path / "store" / "zarr.json").exists() and not (tmp_path / "store" / ".zattrs").exists():
            return False
        try:
            return int(np.sum(zarr.open_group(str(tmp_path / "store"), mode="r")["done"][...])) >= 1
        except Exception:  # noqa: BLE001 - the store is being created
            return False

    _wait_for(computing, 180, proc, "a point written")
    kids = _children(proc.pid)
    if sig == signal.SIGKILL:
        os.kill(proc.pid, signal.SIGKILL)  # the parent only: its children are not signalled
        proc.wait(60)
        assert proc.returncode == -signal.SIGKILL
    else:
        assert _stop(proc, sig) == 143, log.read_text()
    assert _all_gone(kids, 5.0), f"alive after 5 s: {[k.pid for k in kids if k.is_running()]}"
    run_sweep(str(tmp_path / "sweep.toml"), tmp_path / "store", inline=True)
    ds = open_sweep(tmp_path / "store")
    for v in ("truth", "truth_se", "seed", "done"):  # bit-for-bit: resuming must not change a result
        np.testing.assert_array_equal(ds[v].values, grid_ref[v].values)


def test_sigint_while_starting_is_one_line(tmp_path):
    """Ctrl-C as soon as the command has installed its handler (still importing or
    starting): one line, status 130, no traceback."""
    log = tmp_path / "err.txt"
    proc = _start(["budget", "validate", "--trials", "2", "--workers", "1", "--no-progress"], tmp_path, log)
    _wait_for(lambda: _handler_installed(proc.pid), 120, proc, "the signal handler")
    rc = _stop(proc, signal.SIGINT)
    err = log.read_text()
    assert rc == 130 and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("interrupted (SIGINT)"), err


def test_worker_guard_exits_with_parent(tmp_path):
    """`exit_with_parent` on its own: a grandchild whose parent is SIGKILLed exits."""
    code = textwrap.dedent("""
        import multiprocessing as mp, sys, time
        from simcam.infra.lifecycle import exit_with_parent
        def child():
            exit_with_parent(poll_s=0.1)
            time.sleep(600)
        if __name__ == "__main__":
            p = mp.get_context("spawn").Process(target=child)
            p.start()
            print(p.pid, flush=True)
            time.sleep(600)
    """)
    script = tmp_path / "guard.py"
    script.write_text(code)
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, env=env, start_new_session=True)
    try:
        child_pid = int(proc.stdout.readline())
        import psutil

        child = psutil.Process(child_pid)
        time.sleep(0.5)  # let the child set its guard (it is alive either way)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
        assert _all_gone([child], 5.0)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.stdout.close()


def test_quick_teardown_freezes_the_objects_at_exit():
    """`quick_teardown`: at the process's exit the objects are moved out of the collector's
    reach (so shutdown does not search them for cycles); the output is complete."""
    code = textwrap.dedent("""
        import atexit, gc
        atexit.register(lambda: print("frozen at exit:", gc.get_freeze_count() > 0))  # runs last
        from simcam.infra.lifecycle import quick_teardown
        quick_teardown()
        quick_teardown()
        print("frozen before:", gc.get_freeze_count() > 0)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert out.stdout.splitlines() == ["frozen before: False", "frozen at exit: True"], out.stderr


def test_size_helpers_name_figure_and_limit(tmp_path):
    from simcam.infra.errors import ResourceLimitError
    from simcam.infra.lifecycle import announce_size, check_disk, check_memory, format_bytes

    assert format_bytes(1536) == "1.5 KiB" and format_bytes(3 * 2**40) == "3.0 TiB"
    with pytest.raises(ResourceLimitError, match=r"the request: needs about .* of disk, .* free at"):
        check_disk(tmp_path / "a" / "b", 1e18, what="the request")
    with pytest.raises(ResourceLimitError, match=r"x: needs about 888.2 PiB of memory, .* available"):
        check_memory(1e18, what="x")
    check_disk(tmp_path, 1.0, what="small")
    said = []
    announce_size(2 * 2**30, where="out", echo=said.append)
    announce_size(10, where="out", echo=said.append)
    assert said == ["writing about 2.0 GiB to out"]
