"""Bad input and faults, round two (docs/reliability.md has the table): outputs,
devices, sizes, observation tables, all-or-nothing runs, sweeps.

Everything runs in this process (the commands through their ``main``/``run_cli``) except
one memory-limit test, which needs ``resource.setrlimit(RLIMIT_AS)`` in a subprocess.
Device nodes are made with ``mknod`` only when the test runs as root; a FIFO and a
symbolic link stand for them otherwise.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import stat
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cli_capture import one_error, run_budget
from simcam.infra.errors import UserInputError
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import ScenarioError
from simcam.infra.errors import Interrupted, ResourceLimitError
from simcam.infra.lifecycle import cap_workers, format_bytes
from simcam.infra.outputs import (StagedOutputs, check_input_file, check_output_dir, check_output_file,
                            check_run_outputs)

IS_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0




@pytest.fixture
def device(tmp_path):
    """A character device (a private /dev/null made with mknod as root), else a FIFO."""
    p = tmp_path / "devnull"
    if IS_ROOT:
        try:
            os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
            yield p, "a character device"
            return
        except (PermissionError, OSError):
            pass
    os.mkfifo(p)
    yield p, "a FIFO"


# ----------------------------------------------------------------------------- outputs
def test_output_to_a_device_is_refused_and_the_device_kept(device):
    dev, kind = device
    for fn in (lambda: check_output_file(dev), lambda: write_json_atomic(dev, {"a": 1})):
        with pytest.raises(UserInputError, match=f"is {kind}"):
            fn()
        st = os.stat(dev)
        assert not stat.S_ISREG(st.st_mode)  # the node is still a node, not a JSON file
    with pytest.raises(UserInputError, match="not a folder"):
        check_output_dir(dev, option="--report")


@pytest.mark.skipif(not IS_ROOT, reason="mknod of a character device needs root")
def test_json_to_a_real_device_path_is_refused_before_the_work(tmp_path):
    # the case: `--json /dev/full` replaced the device node by a JSON file
    table = tmp_path / "t.csv"
    table.write_text("angle_deg,error_arcsec\n" + "".join(f"{a},{0.01 * a}\n" for a in range(0, 360, 15)))
    for dev in ("/dev/full", "/dev/null"):
        before = os.stat(dev)
        code, _, err = run_budget(["harmonics", "fit", str(table), "--period", "long", "--json", dev])
        one_error(code, err, f"--json {dev}", "character device")
        after = os.stat(dev)
        assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev


def test_fifo_and_symlinks_as_outputs(tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(UserInputError, match="FIFO"):
        check_output_file(fifo)
    folder = tmp_path / "folder"
    folder.mkdir()
    (tmp_path / "to_folder").symlink_to(folder)
    with pytest.raises(UserInputError, match="is a folder .through a symbolic link"):
        check_output_file(tmp_path / "to_folder")
    with pytest.raises(UserInputError, match="symbolic link"):
        check_output_dir(tmp_path / "to_folder", option="--report")
    # a link to a regular file is written through: the link stays a link
    target = tmp_path / "target.json"
    target.write_text("{}")
    (tmp_path / "link.json").symlink_to(target)
    write_json_atomic(tmp_path / "link.json", {"x": 1})
    assert (tmp_path / "link.json").is_symlink() and '"x": 1' in target.read_text()


def test_output_locations_are_checked_before_the_work(tmp_path, monkeypatch):
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(UserInputError, match="afile is a regular file, not a folder"):
        check_output_file(afile / "out.json")
    with pytest.raises(UserInputError, match="this file system allows at most"):
        check_output_file(tmp_path / ("n" * 300 + ".json"))
    with pytest.raises(UserInputError, match="is an input of this command"):
        check_output_file(afile, inputs=[afile])
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "scn.toml").write_text("")
    with pytest.raises(UserInputError, match="holds an input"):
        check_output_dir(tmp_path / "d", inputs=[tmp_path / "d" / "scn.toml"], replaceable=lambda _p: True)
    with pytest.raises(UserInputError, match="the same path"):
        check_run_outputs(json_out=tmp_path / "a.json", files={"--csv": tmp_path / "a.json"})
    with pytest.raises(UserInputError, match="exists, is not empty"):
        check_output_dir(tmp_path, option="--report")
    # a read-only file system (statvfs flag), and not enough free space
    real = os.statvfs

    class RO:
        def __init__(self, v):
            self._v = v

        def __getattr__(self, k):
            return os.ST_RDONLY | self._v.f_flag if k == "f_flag" else getattr(self._v, k)

    monkeypatch.setattr(os, "statvfs", lambda p: RO(real(p)))
    with pytest.raises(UserInputError, match="read-only file system"):
        check_output_file(tmp_path / "new.json")
    monkeypatch.setattr(os, "statvfs", real)
    with pytest.raises(ResourceLimitError, match="of disk"):
        check_output_file(tmp_path / "new.json", need_bytes=1e30)


@pytest.mark.skipif(IS_ROOT, reason="root writes into a folder without write permission")
def test_output_in_a_folder_without_write_permission_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(UserInputError, match="not writable"):
            check_output_file(ro / "x.json")
    finally:
        ro.chmod(0o755)


def test_outputs_get_the_users_umask(tmp_path):
    from simcam.io import atomic_directory

    old = os.umask(0o022)
    try:
        write_json_atomic(tmp_path / "o.json", {"a": 1})
        with atomic_directory(tmp_path / "r") as d:
            (d / "x").write_text("1")
        with StagedOutputs() as st:
            st.folder(tmp_path / "rep").mkdir()
    finally:
        os.umask(old)
    # was: -rw------- and drwx------ (mkstemp / mkdtemp)
    assert stat.S_IMODE(os.stat(tmp_path / "o.json").st_mode) == 0o644
    assert stat.S_IMODE(os.stat(tmp_path / "r").st_mode) == 0o755
    assert stat.S_IMODE(os.stat(tmp_path / "rep").st_mode) == 0o755


def test_inputs_that_are_not_regular_files_are_named(tmp_path, device):
    dev, kind = device
    with pytest.raises(UserInputError, match=f"is {kind}, not a regular file"):
        check_input_file(dev, what="table")
    with pytest.raises(UserInputError, match="is a folder"):
        check_input_file(tmp_path, what="table")
    # a FIFO as a scenario blocked forever; /dev/null read as "file not found"
    from simcam.config_base import read_toml

    with pytest.raises(ScenarioError, match=f"is {kind}"):
        read_toml(path=dev)
    code, _, err = run_budget(["harmonics", "fit", str(dev), "--period", "long"])
    one_error(code, err, str(dev), kind)


# ----------------------------------------------------------------------------- all or nothing
def test_sigterm_during_report_writing_leaves_neither_report_nor_json(tmp_path, monkeypatch):
    import budget.runner.report as report
    from budget.runner.validate_cmd import run_and_write
    from toy_study import STUDY, Toy

    def interrupted_report(result, out_dir):
        Path(out_dir).mkdir()
        (Path(out_dir) / "report.md").write_text("half")
        raise Interrupted(signal.SIGTERM)

    monkeypatch.setattr(report, "write_report", interrupted_report)
    with contextlib.redirect_stdout(io.StringIO()), pytest.raises(Interrupted):
        run_and_write(STUDY, Toy(trials=20), trials=20, workers=1, json_out=tmp_path / "out.json",
                      report_dir=tmp_path / "rep", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no JSON, no report, no partial


def test_validate_refuses_a_non_report_folder_before_running(tmp_path, monkeypatch):
    import budget.runner.run as run
    from budget.runner.validate_cmd import run_and_write
    from toy_study import STUDY, Toy

    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "mine.txt").write_text("keep")
    monkeypatch.setattr(run, "run_study", lambda *a, **k: pytest.fail("the trials ran"))
    with pytest.raises(UserInputError, match="--report .*exists, is not empty.*--overwrite"):
        run_and_write(STUDY, Toy(), report_dir=tmp_path / "notes", workers=1)
    with pytest.raises(UserInputError, match="--json .*is a folder"):
        run_and_write(STUDY, Toy(), json_out=tmp_path / "notes", workers=1)
    assert (tmp_path / "notes" / "mine.txt").read_text() == "keep"


# ----------------------------------------------------------------------------- workers, sizes
def test_workers_are_capped_with_a_note(monkeypatch):
    import simcam.infra.lifecycle as lc

    said = []
    assert cap_workers(1000, echo=said.append) == lc.usable_cores() or lc.available_memory_bytes() is not None
    assert len(said) == 1 and said[0].startswith("note: --workers 1000: using ")
    assert cap_workers(1000, tasks=3, echo=said.append) <= 3
    monkeypatch.setattr(lc, "available_memory_bytes", lambda: 2 * lc.WORKER_BYTES)
    monkeypatch.setattr(lc, "usable_cores", lambda: 64)
    said.clear()
    assert cap_workers(16, echo=said.append) == 1 and "available memory" in said[0]
    said.clear()
    assert cap_workers(1, echo=said.append) == 1 and said == []


def test_sizes_are_readable_figures():
    assert format_bytes(1e300) == "1e+300 B"  # not a 300-digit PiB figure
    assert format_bytes(1536) == "1.5 KiB"


def test_memory_limit_of_the_process_refuses_before_allocating(tmp_path):
    # RLIMIT_AS 3 GiB: the synthesis of 150000 trials needs ~6.7 GB (more than the limit,
    # less than a developer machine's memory): refused from the estimate, one line
    code = textwrap.dedent("""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, resource.RLIM_INFINITY))
        from budget.cli import main
        main(sys.argv[1:])
    """)
    p = subprocess.run([sys.executable, "-c", code, "whiskbroom", "synthesize", "--trials", "150000"],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parents[1]),
                                                                        os.environ.get("PYTHONPATH", "")])})
    one_error(p.returncode, p.stderr, "--trials 150000", "of memory")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- scenarios
def _whisk(**changes):
    import tomllib

    from simcam.whiskbroom import scenario as wsc

    d = tomllib.loads(wsc.default_text())
    for k, v in changes.items():
        sect, field = k.split("__")
        d[sect][field] = v
    return wsc.from_dict(d, source="w.toml")


@pytest.mark.parametrize("change,named", [
    ({"mirror__rate_deg_s": float("inf")}, "mirror.rate_deg_s: must be a finite number"),
    ({"camera__focal_length_mm": 1e308}, "camera.focal_length_mm"),
    ({"camera__chip_cols": 10**9}, "camera.chip_cols"),
    ({"camera__n_chips": 10**9}, "camera.n_chips"),
    ({"synthesis__field_cols_per_chip": 10**8}, "synthesis.field_cols_per_chip"),
    ({"tdi__columns": 10**11}, "tdi.columns"),
    ({"synthesis__sobol_base_samples": 10**11}, "synthesis.sobol_base_samples"),
    ({"synthesis__trials": 10**10}, "synthesis.trials"),
])
def test_whiskbroom_fields_finite_in_range_and_sized(change, named):
    with pytest.raises(ValueError) as ei:  # ScenarioError or ResourceLimitError: both one line
        _whisk(**change)
    msg = str(ei.value)
    assert msg.startswith("w.toml: ") and named in msg and len(msg.splitlines()) == 1, msg


def test_bad_epochs_are_one_line_when_the_scenario_loads():
    from budget.linecam.study import STUDY as LINECAM
    from simcam.linecam.scenario import from_dict as linecam_from_dict

    for bad in ("2025-13-45T00:00:00", "yesterday", ""):
        with pytest.raises(ScenarioError) as ei:
            linecam_from_dict({"orbit": {"epoch_utc": bad}}, source="l.toml")
        assert str(ei.value).count("\n") == 0 and "l.toml: orbit.epoch_utc" in str(ei.value)
    assert LINECAM.load_scenario(None).orbit.epoch_utc  # the default still loads
    from simcam.scanmirror.scenario import OrbitConfig

    with pytest.raises(Exception) as ei:
        OrbitConfig(epoch_utc="2025-13-45T00:00:00")
    assert len([e for e in ei.value.errors()]) == 1 and "\n" not in ei.value.errors()[0]["msg"]


def test_scanmirror_ground_step_too_fine_is_refused_naming_the_field(monkeypatch):
    import simcam.infra.lifecycle as lc
    from budget.scanmirror.pipeline import Setup
    from budget.scanmirror.study import STUDY

    sc = STUDY.load_scenario(None)
    monkeypatch.setattr(lc, "available_memory_bytes", lambda: 1 << 16)  # 64 KiB: any plan is too large
    with pytest.raises(ResourceLimitError, match="validation.ground_step_s = 0.5 s"):
        Setup(sc, sc.validation.ground_step_s, source="s.toml")


# ----------------------------------------------------------------------------- tables
def _obs_arrays(n=40, seed=1):
    from budget.linecam.table import CSV_COLUMNS

    rng = np.random.default_rng(seed)
    a = {c: rng.normal(size=n) for c in CSV_COLUMNS}
    a["time_s"] = np.arange(n) * 1.0
    a["sample_px"] = rng.uniform(0, 6000, n)
    a["hip"] = np.arange(1, n + 1, dtype=float)
    a["pos_x_km"], a["pos_y_km"], a["pos_z_km"] = np.full(n, 6978.0), np.zeros(n), np.zeros(n)
    a["vel_x_km_s"], a["vel_y_km_s"], a["vel_z_km_s"] = np.zeros(n), np.full(n, 7.5), np.zeros(n)
    return a


@pytest.mark.parametrize("mutate,named", [
    (lambda a: {k: np.concatenate([v, v[:1]]) for k, v in a.items()}, "rows: row 42 repeats row 2"),
    (lambda a: {k: np.repeat(v[:1], 364) for k, v in a.items()}, "rows: row 3 repeats row 2"),
    (lambda a: {**a, "hip": np.tile([1.0, 2.0, 3.0, 4.0], 10)}, "rows: 4 distinct star(s)"),
    (lambda a: {**a, "sample_px": np.full(40, 6143.0)}, "sample_px: every observation is at pixel 6143"),
    (lambda a: {**a, "time_s": np.full(40, 1e300)}, "time_s: 1e+300 s in row 2"),
    (lambda a: {**a, "pos_x_km": np.zeros(40)}, "pos_x_km: the position in row 2 is 0 km"),
    (lambda a: {**a, "vel_x_km_s": np.full(40, 4e5)}, "vel_x_km_s: the speed in row 2"),
])
def test_observation_tables_that_make_a_calibration_meaningless(mutate, named):
    from budget.linecam.table import check_observation_values

    check_observation_values("obs.csv", _obs_arrays(), n_pixels=6144)  # the good table passes
    with pytest.raises(UserInputError) as ei:
        check_observation_values("obs.csv", mutate(_obs_arrays()), n_pixels=6144)
    assert str(ei.value).startswith("obs.csv: ") and named in str(ei.value), str(ei.value)


def test_singular_fit_is_an_error_not_plus_minus_zero():
    from types import SimpleNamespace

    from budget.linecam.calibrate import check_determined

    good = SimpleNamespace(condition=1e3, cov=np.eye(10))
    check_determined({"published": good, "improved": good}, source="obs.csv")
    for bad in (SimpleNamespace(condition=np.inf, cov=np.zeros((10, 10))),
                SimpleNamespace(condition=1e16, cov=np.eye(10))):
        with pytest.raises(UserInputError, match="obs.csv: rows: the published fit is singular"):
            check_determined({"published": bad}, source="obs.csv")
    with pytest.raises(UserInputError, match="no finite uncertainty"):
        check_determined({"improved": SimpleNamespace(condition=1.0, cov=np.full((10, 10), np.nan))},
                         source="obs.csv")


def test_linecam_calibrate_never_writes_over_its_table_and_names_empty_cells(tmp_path):
    from budget.linecam.table import CSV_COLUMNS

    obs = tmp_path / "obs.csv"
    a = _obs_arrays()
    lines = [",".join(CSV_COLUMNS)] + [",".join(repr(float(a[c][i])) for c in CSV_COLUMNS) for i in range(40)]
    obs.write_text("\n".join(lines) + "\n")
    before = obs.read_bytes()
    code, _, err = run_budget(["linecam", "calibrate", str(obs), "--json", str(obs)])
    one_error(code, err, f"--json {obs}", "is an input of this command")
    assert obs.read_bytes() == before
    lines[3] = lines[3].replace(lines[3].split(",")[0], "", 1)
    obs.write_text("\n".join(lines) + "\n")
    code, _, err = run_budget(["linecam", "calibrate", str(obs)])
    one_error(code, err, f"{obs}: time_s: not a finite number in row 4 (got an empty cell)")


def test_polygon_table_bom_size_and_empty_cell(tmp_path):
    from budget.inductosyn.harmonics import MAX_TABLE_BYTES, read_calibration_csv

    body = "angle_deg,error_arcsec\n" + "".join(f"{a},{0.01 * a}\n" for a in range(0, 360, 15))
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + body.encode())
    a, _ = read_calibration_csv(path=bom)  # was: "header lacks column(s) angle_deg (found \ufeffangle_deg...)"
    assert a.size == 24
    big = tmp_path / "big.csv"
    with open(big, "wb") as fh:  # sparse: 200 MB on paper, nothing on disk
        fh.truncate(200 * 2**20)
    with pytest.raises(UserInputError, match=r"big.csv: 200 MiB; a calibration table is at most"):
        read_calibration_csv(path=big)
    assert MAX_TABLE_BYTES < 200 * 2**20
    empty = tmp_path / "empty.csv"
    empty.write_text("angle_deg,error_arcsec\n0,\n")
    with pytest.raises(UserInputError, match="empty.csv:2: empty cell in error_arcsec"):
        read_calibration_csv(path=empty)


def test_fits_plate_scale_and_non_finite_pixels():
    from budget.starcam.measure import _check_pixels, header_plate_scale

    for raw in ("abc", 0, -1.0, float("nan"), True):
        with pytest.raises(UserInputError, match=r"f0.fits: header PLTSCALE = .* not a positive number"):
            header_plate_scale({"plate_scale_arcsec": raw, "plate_scale_file": "d/f0.fits"})
    with pytest.raises(UserInputError, match="d/f0.fits: no PLTSCALE"):
        header_plate_scale({"plate_scale_arcsec": None, "plate_scale_file": "d/f0.fits"})
    assert header_plate_scale({"plate_scale_arcsec": 5.5}) == 5.5
    img = np.ones((8, 8))
    _check_pixels("f", img)
    img[3, 3] = np.nan
    _check_pixels("f", img)  # one marked bad pixel: flagged later, not refused
    img[5, :] = np.nan
    with pytest.raises(UserInputError, match="f: 1 row.* entirely NaN"):
        _check_pixels("f", img)
    img = np.ones((8, 8))
    img[2, 4] = np.inf
    with pytest.raises(UserInputError, match="infinite pixel.*row 2, column 4"):
        _check_pixels("f", img)


# ----------------------------------------------------------------------------- sweeps
GRID = """
    name = "tiny grid"
    base = "tiny.toml"
    kind = "starcam"
    seed = 11
    evaluate = "truth"
    [parameters]
    "lab.source.match_v_mag" = [6.0, 6.5]
"""


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    from budget.sweeps.run import run_sweep
    from tiny_camera import TINY

    d = tmp_path_factory.mktemp("sw")
    (d / "tiny.toml").write_text(TINY)
    (d / "s.toml").write_text(textwrap.dedent(GRID))
    run_sweep(d / "s.toml", d / "st", inline=True)
    return d


def _first_chunk(array_dir):
    """The first chunk file of a Zarr array's folder (``0.0.0`` for three dimensions, ``0.0.0.0`` for four)."""
    return min(p for p in array_dir.iterdir() if p.name[:1].isdigit())


def test_damaged_stores_are_one_error_and_leave_no_plots_folder(store, tmp_path):
    import shutil

    from budget.sweeps.plot import plot_store

    cases = {"missing chunk": lambda s: os.remove(_first_chunk(s / "truth")),
             "corrupt chunk": lambda s: _first_chunk(s / "truth").write_bytes(b"garbage" * 9),
             "no truth": lambda s: shutil.rmtree(s / "truth"),
             "nothing done": lambda s: [os.remove(p) for p in (s / "done").glob("[0-9]*")]}
    expect = {"missing chunk": "marked done have no truth values", "corrupt chunk": "cannot be read",
              "no truth": "has no truth array", "nothing done": "no point of the sweep is done"}
    for name, damage in cases.items():
        s = tmp_path / name.replace(" ", "_")
        shutil.copytree(store / "st", s)
        damage(s)
        with pytest.raises(UserInputError, match=expect[name]) as ei:
            plot_store(s, tmp_path / "pl")
        assert str(ei.value).startswith(str(s)), ei.value
        assert not (tmp_path / "pl").exists()  # was: an empty pl/ left behind


def test_sweep_cleans_its_dead_partial_store_and_refuses_before_creating(store, tmp_path, capsys):
    from budget.sweeps.spec import load_sweep
    from budget.sweeps.store import check_store, create_store

    sw = load_sweep(store / "s.toml")
    dead = tmp_path / ".new.partial.999999999.abc"  # a run killed in its first second (pid gone)
    dead.mkdir()
    (dead / ".zgroup").write_text("{}")
    create_store(tmp_path / "new", sw)
    assert not dead.exists() and "left by an interrupted run (pid 999999999" in capsys.readouterr().err
    afile = tmp_path / "afile"
    afile.write_text("")
    with pytest.raises(UserInputError, match="is a regular file, not a folder"):
        check_store(afile / "st", sw)
    assert not (afile.parent / "st").exists()



def test_sweep_store_too_large_for_the_disk_is_refused_before_creating(store, tmp_path, monkeypatch):
    import budget.sweeps.store as st_mod
    from budget.sweeps.spec import load_sweep

    sw = load_sweep(store / "s.toml")
    monkeypatch.setattr(st_mod, "_BLOCK_BYTES", 1e18)  # every chunk file an exabyte: no disk holds it
    with pytest.raises(ResourceLimitError, match="parameters: a store of 2 point.*of disk"):
        st_mod.create_store(tmp_path / "big", sw)
    assert list(tmp_path.iterdir()) == []


def test_whiskbroom_synthesis_outside_the_models_domain_is_an_error(tmp_path):
    # was: an all-NaN table with "N pub 100000" at exit status 0
    import tomllib

    import tomli_w

    from simcam.whiskbroom import scenario as wsc

    d = tomllib.loads(wsc.default_text())
    d["mirror"]["rest_angle_deg"] = 90.0  # the line of sight grazes: the image motion divides by zero
    f = tmp_path / "w.toml"
    f.write_text(tomli_w.dumps(d))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        code, _, err = run_budget(["whiskbroom", "synthesize", str(f), "--trials", "20", "--json",
                                str(tmp_path / "o.json")])
    one_error(code, err, f"{f}: the image motion is not finite in 20 of 20 trials")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["w.toml"]


def test_disk_full_while_writing_is_one_error_line(tmp_path, monkeypatch, capsys):
    import errno
    import json

    import click

    from simcam.infra.cli import run_cli

    def full(*a, **k):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(json, "dump", full)
    with pytest.raises(UserInputError, match="--json .*o.json: no space left on the device"):
        write_json_atomic(tmp_path / "o.json", {"a": 1})
    assert list(tmp_path.iterdir()) == []  # the temporary file is removed

    @click.group()
    def g():
        pass

    @g.command()
    def report():
        # a figure saved into a full disk (matplotlib raises the OSError itself)
        raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "rep" / "fig.png"))

    with pytest.raises(SystemExit) as ei:
        run_cli(g, ["report"])
    assert ei.value.code == 2
    err = capsys.readouterr().err
    one_error(2, err, "fig.png: no space left on the device")


def test_fifo_as_a_frame_or_manifest_is_named_not_read(tmp_path):
    from budget.starcam.measure import read_manifest
    from simcam.io import read_frame

    fifo = tmp_path / "f0.fits"
    os.mkfifo(fifo)
    with pytest.raises(UserInputError, match="f0.fits: is a FIFO"):
        read_frame(fifo)
    man = tmp_path / "manifest.csv"
    os.mkfifo(man)
    with pytest.raises(UserInputError, match="manifest.csv: is a FIFO"):
        read_manifest(man, protocol="te")
