"""Running sweeps: exact results whatever the workers, resume after an interruption or a kill,
the inductosyn kind, Sobol indices, plots and the command line.

Tiny scenarios (two 256 x 256 chips, short plans) and the fast truth mode keep these
tests short; the equality tests are bit-for-bit.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
import xarray as xr

from budget.sweeps.run import open_sensitivity, open_sobol, open_sweep, run_sweep
from budget.sweeps.spec import load_sweep
from simcam.infra.errors import UserInputError
from tiny_camera import TINY



#: six truth-mode points (3 magnitudes x 2 PSF widths)
GRID = """
    name = "tiny grid"
    base = "tiny.toml"
    kind = "starcam"
    seed = 11
    evaluate = "truth"
    [parameters]
    "lab.source.match_v_mag" = [6.0, 6.5, 7.0]
    "optics.psf.sigma0_px" = [0.8, 1.1]
"""
#: results, not timings: every variable but compute_s must match bit for bit
RESULT_VARS = ("truth", "truth_se", "seed", "done")


def _write(d, body: str, name: str = "sweep.toml") -> str:
    (d / "tiny.toml").write_text(TINY)
    p = d / name
    p.write_text(textwrap.dedent(body))
    return str(p)


def _assert_same(a: xr.Dataset, b: xr.Dataset, names=None):
    names = names or [v for v in a.data_vars if v != "compute_s"]
    assert set(names) <= set(b.data_vars)
    for v in names:
        xr.testing.assert_identical(a[v].drop_attrs(), b[v].drop_attrs())


@pytest.fixture(scope="module")
def grid(tmp_path_factory):
    """The GRID sweep run in this process (the reference of the equality tests)."""
    d = tmp_path_factory.mktemp("grid")
    path = _write(d, GRID)
    rep = run_sweep(path, d / "ref", inline=True)
    assert rep.computed == 6 and rep.already_done == 0
    return {"dir": d, "path": path, "store": d / "ref", "ds": open_sweep(d / "ref")}


# --------------------------------------------------------------------------- exactness
def test_grid_point_is_the_truth_of_its_scenario_and_seed(grid):
    from budget.runner.registry import get_study

    ds = grid["ds"]
    sw = load_sweep(grid["path"])
    p = sw.points[3]
    assert p.values == {"lab.source.match_v_mag": 6.5, "optics.psf.sigma0_px": 1.1}
    t = get_study("starcam").truths(p.scenario, p.seed)
    classes = list(ds["class"].values)
    nan = float("nan")
    # the run's truths, the same for each variant; a truth drawn per trial (each trial's
    # camera's LSFE-C1, LSFE, total) needs trials: NaN in the truth mode
    truth = np.array([[[t[(c, a)].value if (c, a) in t else nan] * 2 for a in ("x", "y")] for c in classes])
    se = np.array([[[t[(c, a)].se if (c, a) in t else nan] * 2 for a in ("x", "y")] for c in classes])
    assert {c for c in classes if (c, "x") not in t} == {"lsfe_c1", "lsfe", "total"}
    sel = {"lab.source.match_v_mag": 6.5, "optics.psf.sigma0_px": 1.1}
    assert ds.truth.sel(sel).dims == ("class", "axis", "variant")
    np.testing.assert_array_equal(ds.truth.sel(sel).values, truth)
    np.testing.assert_array_equal(ds.truth_se.sel(sel).values, se)
    assert int(ds.seed.sel(sel)) == p.seed
    assert bool(ds.done.all())
    assert ds.attrs["sweep_hash"] == sw.hash and ds.attrs["seed"] == 11 and ds.attrs["version"]
    assert "lab.source.match_v_mag" in ds.attrs["sweep_file"]
    # physics sanity: a fainter star has a larger temporal error
    te = ds.truth.sel({"class": "te", "axis": "x", "variant": "published", "optics.psf.sigma0_px": 0.8}).values
    assert te[0] < te[1] < te[2]


def test_results_identical_in_one_process_two_processes_and_a_dask_cluster(grid, tmp_path, capsys):
    """Same store content (bit for bit) run in this process, on 2 local processes (points
    finish out of order) and on an existing Dask cluster (a LocalCluster on loopback,
    reached through the command line's --scheduler)."""
    from distributed import LocalCluster

    from budget.cli import main

    path = _write(tmp_path, GRID)
    rep = run_sweep(path, tmp_path / "p2", workers=2)
    assert rep.runner == "2 local processes" and len(rep.completed) == 6
    assert all(pid != os.getpid() for *_, pid in rep.completed)  # computed in the pool, not here
    _assert_same(grid["ds"], open_sweep(tmp_path / "p2"))
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        main(["sweep", path, "--out", str(tmp_path / "dask"), "--scheduler", address, "--no-progress"])
    out = capsys.readouterr().out
    assert f"Dask scheduler {address}" in out and "6 point(s) computed" in out
    _assert_same(grid["ds"], open_sweep(tmp_path / "dask"))


def test_dask_local_cluster_started_by_the_command_gives_the_same_store(grid, tmp_path, capsys):
    """--dask-local N starts its own LocalCluster (on loopback) and closes it: same store."""
    from budget.cli import main

    path = _write(tmp_path, GRID)
    main(["sweep", path, "--out", str(tmp_path / "local"), "--dask-local", "1", "--no-progress"])
    out = capsys.readouterr().out
    assert "6 point(s) computed" in out
    _assert_same(grid["ds"], open_sweep(tmp_path / "local"))


ZIP = """
    name = "tiny frames"
    base = "tiny.toml"
    kind = "starcam"
    seed = 4
    mode = "zip"
    trials = 3
    [parameters]
    "protocols.te.frames" = [6, 12]
    "protocols.hsfe.frames" = [4, 8]
"""


@pytest.fixture(scope="module")
def zipped(tmp_path_factory):
    """A validation sweep (3 trials per point) of two zipped frame counts, in this process."""
    d = tmp_path_factory.mktemp("zip")
    path = _write(d, ZIP)
    run_sweep(path, d / "v", inline=True)
    return {"dir": d, "path": path, "store": d / "v", "ds": open_sweep(d / "v")}


def test_validate_mode_point_equals_the_monte_carlo_validation(zipped, tmp_path):
    """A validation sweep's point holds validate(scenario, trials, seed).summary() with the
    truths of its truth seed (the protocols' frame counts cannot change the truths, so both
    points share one: the point seed of no swept value); its truth equals the truth mode's
    for the same point."""
    from budget.runner.run import run_study
    from budget.starcam.study import STUDY
    from budget.starcam.validate import AXES, CLASSES, VARIANTS
    from budget.sweeps.values import point_seed

    ds = zipped["ds"]
    assert ds.truth.dims == ds["mean"].dims == ("point", "class", "axis", "variant")
    assert list(ds["protocols.te.frames"].values) == [6, 12]
    p = load_sweep(zipped["path"]).points[1]
    truths = STUDY.truths(p.scenario, point_seed(4, {}))
    s = run_study(STUDY, p.scenario, trials=3, seed=p.seed, workers=1, truths=truths).summary()
    d = ds.isel(point=1)
    for c in CLASSES:
        for a in AXES:
            for v in VARIANTS:
                e = d.sel({"class": c, "axis": a, "variant": v})
                r = s[c][a][v]
                assert (float(e["mean"]), float(e.bias), float(e.spread)) == (r["mean"], r["bias"], r["std"])
                # exact on purpose: a sweep point is the same run stored in another container
                assert float(e.se_bias) == r["se_bias"]
                assert [float(e.ci95_low), float(e.ci95_high)] == r["interval_95"]
                assert float(e.truth) == r["truth"]
    assert int(d.trials) == 3 and int(d.stopped_by) == 0
    fixed = {"class": ["te", "hsfe", "lsfe_s", "lsfe_c2"]}  # the run's truths (the rest: each trial's camera's)
    np.testing.assert_array_equal(ds.truth.sel(fixed).values[0], ds.truth.sel(fixed).values[1])  # one truth, shared
    # the truth mode gives the same truths for the same point and seed
    t = _write(tmp_path, ZIP.replace("trials = 3", 'evaluate = "truth"'), "truth.toml")
    run_sweep(t, tmp_path / "t", inline=True)
    np.testing.assert_array_equal(open_sweep(tmp_path / "t").truth.sel(fixed).values, ds.truth.sel(fixed).values)


# --------------------------------------------------------------------------- resume
class _Stop(Exception):
    pass


def test_interrupted_run_resumes_with_no_point_lost_or_computed_twice(grid, tmp_path):
    path = _write(tmp_path, GRID)
    first: list = []

    def stop_after_two(group, index):
        first.append(index)
        if len(first) == 2:
            raise _Stop

    with pytest.raises(_Stop):
        run_sweep(path, tmp_path / "s", inline=True, on_point=stop_after_two)
    done = open_sweep(tmp_path / "s").done.values.reshape(-1)
    assert sorted(np.flatnonzero(done)) == sorted(first) and len(first) == 2
    second: list = []
    rep = run_sweep(path, tmp_path / "s", inline=True, on_point=lambda g, i: second.append(i))
    assert rep.already_done == 2 and rep.computed == 4
    assert sorted(first + second) == list(range(6)) and not set(first) & set(second)
    _assert_same(grid["ds"], open_sweep(tmp_path / "s"))
    # a third run has nothing to do
    assert run_sweep(path, tmp_path / "s", inline=True).computed == 0


def test_killed_run_resumes_with_no_point_lost_or_computed_twice(grid, tmp_path):
    """SIGKILL a sweep process after its second point is written; the next run computes
    exactly the points not marked done, and the store equals an uninterrupted run's."""
    import zarr

    path = _write(tmp_path, GRID)
    store = tmp_path / "k"
    # the child pauses 0.5 s after writing each point, so that the kill lands between its
    # second and last points even when this process is slow to see the second (a loaded
    # machine: a tiny point takes about 0.1 s)
    code = ("import time; from budget.sweeps.run import run_sweep; "
            f"run_sweep({path!r}, {str(store)!r}, inline=True, on_point=lambda g, i: time.sleep(0.5))")
    log = open(tmp_path / "stderr.txt", "wb")  # noqa: SIM115 - closed below
    proc = subprocess.Popen([sys.executable, "-c", code], start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=log)
    n_done = 0
    t_end = time.monotonic() + 120
    try:
        while time.monotonic() < t_end and proc.poll() is None:
            if (store / ".zattrs").exists():
                n_done = int(np.sum(zarr.open_group(str(store), mode="r")["done"][...]))
                if n_done >= 2:
                    break
            time.sleep(0.02)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        log.close()
    assert proc.returncode == -signal.SIGKILL, (tmp_path / "stderr.txt").read_text()[-2000:]
    done_at_kill = set(np.flatnonzero(open_sweep(store).done.values.reshape(-1)))
    assert 2 <= len(done_at_kill) < 6
    again: list = []
    rep = run_sweep(path, store, inline=True, on_point=lambda g, i: again.append(i))
    assert set(again) == set(range(6)) - done_at_kill and len(again) == len(set(again))
    assert rep.already_done == len(done_at_kill)
    _assert_same(grid["ds"], open_sweep(store))


def test_store_of_another_sweep_file_is_refused_before_any_work(grid, tmp_path):
    other = _write(tmp_path, GRID.replace("7.0]", "7.5]"), "other.toml")
    before = sorted(p.name for p in grid["store"].rglob("*"))
    with pytest.raises(UserInputError, match="written by a different sweep file"):
        run_sweep(other, grid["store"], inline=True, on_point=lambda g, i: pytest.fail("computed a point"))
    assert sorted(p.name for p in grid["store"].rglob("*")) == before
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "x.txt").write_text("x")
    with pytest.raises(UserInputError, match="not a sweep store"):
        run_sweep(other, tmp_path / "junk", inline=True)


# --------------------------------------------------------------------------- inductosyn
def test_inductosyn_sweep_holds_the_calibration_validation(tmp_path):
    from budget.inductosyn.study import STUDY
    from budget.runner.run import run_study

    path = _write(tmp_path, """
        kind = "inductosyn"
        seed = 3
        trials = 8
        [fixed]
        "validation.dense_step_deg" = 0.02
        [parameters]
        "calibration.short_polygon.faces" = [19, 23]
        [sensitivity]
        samples = 2
        evaluate = "validate"
        trials = 4
        [sensitivity.parameters]
        "calibration.autocollimator.noise_arcsec" = {dist = "uniform", low = 0.0, high = 0.5}
    """)
    run_sweep(path, tmp_path / "i", inline=True)
    ds = open_sweep(tmp_path / "i")
    assert list(ds["class"].values) == ["before", "residual", "environment", "coefficient"]
    p = load_sweep(path).points[1]
    assert p.scenario.validation.dense_step_deg == 0.02  # [fixed], set as given
    s = run_study(STUDY, p.scenario, trials=8, seed=p.seed, workers=1).details()
    d = ds.sel({"calibration.short_polygon.faces": 23, "axis": "angle"})
    # the sweep store holds what a direct run of the study gives: its statistics equal the
    # seed-001 figures of the same calibrations (the same numbers summed in another order:
    # a relative 1e-12 covers the rounding)
    rel = 1e-12
    assert float(d.truth.sel({"class": "residual", "variant": "published"})) == \
        pytest.approx(s["dense_sigma3_after_arcsec"]["mean"], rel=rel)
    assert float(d.truth.sel({"class": "residual", "variant": "improved"})) == \
        pytest.approx(s["joint_dense_sigma3_after_arcsec"]["mean"], rel=rel)
    assert float(d["mean"].sel({"class": "residual", "variant": "published"})) == \
        pytest.approx(s["short_sigma3_after_arcsec"]["mean"], rel=rel)
    assert float(d.truth.sel({"class": "before", "variant": "published"})) == \
        pytest.approx(s["dense_sigma3_before_arcsec"], rel=rel)
    assert int(d.trials) == 8
    # the joint fit leaves less than the published sequence on this encoder (seed 001 finding;
    # each trial's instrument: the mean over 8 of them)
    r = d.truth.sel({"class": "residual"})
    assert float(r.sel(variant="improved")) < float(r.sel(variant="published"))
    # Sobol indices of a truth that has a variant dimension; the error before compensation
    # does not depend on the autocollimator (the store's shape and notes, not the indices'
    # values: two base samples, 6 evaluations of a truth of about 0.5 s each, suffice)
    sob = open_sobol(tmp_path / "i")
    assert sob.S1.dims == ("class", "axis", "variant", "parameter")
    assert "does not vary" in str(sob.note.sel({"class": "before", "axis": "angle", "variant": "published"}).values)
    assert np.isfinite(float(sob.ST.sel({"class": "residual", "axis": "angle", "variant": "published",
                                         "parameter": "calibration.autocollimator.noise_arcsec"})))
    from budget.sweeps.plot import plot_store

    files = plot_store(tmp_path / "i", tmp_path / "plots", axis="angle")
    assert {f.name for f in files} == {"classes_vs_calibration.short_polygon.faces__angle.png",
                                       "relative_spread_vs_calibration.short_polygon.faces__angle.png",
                                       "sobol__angle.png"}


# --------------------------------------------------------------------------- sensitivity
def test_sobol_indices_find_the_parameter_that_drives_each_class(tmp_path):
    """TE depends on the PSF width and not on the marker error; LSFE-C2 is the marker
    error. With common random numbers these are exact functional facts, so the estimated
    total index of the parameter a class does not depend on is exactly 0, and the first
    order index of the one it wholly depends on is 1 within 3 bootstrap standard errors
    (SALib's conf is 1.96 of them at 95 %)."""
    path = _write(tmp_path, """
        base = "tiny.toml"
        kind = "starcam"
        seed = 5
        [sensitivity]
        samples = 8
        resamples = 200
        [sensitivity.parameters]
        "optics.psf.sigma0_px" = {dist = "uniform", low = 0.7, high = 1.3}
        "lab.calibration_target.marker_error_3sigma_arcsec" = {dist = "triangular", low = 0.2, high = 0.8, peak = 0.5}
    """)
    rep = run_sweep(path, tmp_path / "sob", inline=True)
    assert rep.samples == rep.samples_computed == 8 * 4 and rep.sobol
    s = open_sobol(tmp_path / "sob").sel(axis="x", variant="published")  # the truths: equal for each variant
    psf, mark = "optics.psf.sigma0_px", "lab.calibration_target.marker_error_3sigma_arcsec"
    te, c2 = s.sel({"class": "te"}), s.sel({"class": "lsfe_c2"})
    # exact on purpose: a parameter the class does not read leaves its output bit-identical,
    # so its total index is exactly 0 (a non-zero value means hidden coupling)
    assert float(te.ST.sel(parameter=mark)) == 0.0
    assert abs(float(te.S1.sel(parameter=psf)) - 1) <= 3 * float(te.S1_conf.sel(parameter=psf)) / 1.96
    assert float(c2.ST.sel(parameter=psf)) == 0.0
    assert abs(float(c2.S1.sel(parameter=mark)) - 1) <= 3 * float(c2.S1_conf.sel(parameter=mark)) / 1.96
    # LSFE-S does not vary with either: no indices, and it says so
    assert np.isnan(float(s.sel({"class": "lsfe_s"}).S1.sel(parameter=psf)))
    assert "does not vary" in str(s.sel({"class": "lsfe_s"}).note.values)
    smp = open_sensitivity(tmp_path / "sob")
    assert smp.X.shape == (32, 2) and bool(smp.done.all())
    from budget.sweeps.plot import plot_store

    files = plot_store(tmp_path / "sob", tmp_path / "plots", axis="x")
    assert [f.name for f in files] == ["sobol__x.png"] and files[0].stat().st_size > 20_000


# --------------------------------------------------------------------------- plots, CLI
@pytest.fixture(scope="module")
def grid_plots(grid, tmp_path_factory):
    """``budget plot``'s default figures of the GRID store (six figures, about 1 s each),
    drawn once for the tests that read them."""
    from budget.sweeps.plot import plot_store

    return plot_store(grid["store"], tmp_path_factory.mktemp("grid_plots"))


def test_plots_of_grids_and_zips(grid_plots, zipped, tmp_path):
    from budget.sweeps.plot import plot_store, precision_table

    files = grid_plots
    names = {f.name for f in files}
    # every axis by default
    assert names == {f"{n}__{a}.png" for a in ("x", "y") for n in (
        "classes_vs_lab.source.match_v_mag", "classes_vs_optics.psf.sigma0_px", "heatmap_truth")}
    assert all(f.stat().st_size > 20_000 for f in files)
    files = plot_store(zipped["store"], tmp_path / "zp", axis="y", precision=0.1)
    assert {f.name for f in files} == {"classes_vs_protocols.te.frames__y.png",
                                       "relative_spread_vs_protocols.te.frames__y.png"}
    rows = precision_table(zipped["ds"], axis="y", precision=0.1)
    te = next(r for r in rows if r["class"] == "te" and r["variant"] == "improved")
    ds = zipped["ds"].sel({"class": "te", "axis": "y", "variant": "improved"})
    np.testing.assert_allclose(te["relative_spread"], (ds.spread / abs(ds["mean"])).values)
    with pytest.raises(UserInputError, match="--axis z"):
        plot_store(zipped["store"], tmp_path / "zp", axis="z")


def test_cli_bad_input_is_one_error_line_exit_2_and_no_store(tmp_path, capsys):
    from budget.cli import main

    path = _write(tmp_path, GRID.replace("optics.psf.sigma0_px", "optics.psf.sigma_px"))
    with pytest.raises(SystemExit) as ei:
        main(["sweep", path, "--out", str(tmp_path / "never"), "--no-progress"])
    assert ei.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "unknown key 'sigma_px'" in err[0], err
    assert path in err[0] and "Traceback" not in "".join(err)
    assert not (tmp_path / "never").exists()
    with pytest.raises(SystemExit) as ei:
        main(["sweep", _write(tmp_path, GRID, "ok.toml"), "--out", str(tmp_path / "never"),
              "--scheduler", "localhost:1", "--no-progress"])
    assert ei.value.code == 2 and "expected an address like tcp://" in capsys.readouterr().err
    with pytest.raises(SystemExit) as ei:
        main(["plot", str(tmp_path / "never")])
    assert ei.value.code == 2 and "not a sweep store" in capsys.readouterr().err


def test_every_class_and_axis_of_a_store_is_plotted_with_its_label_and_unit(grid, grid_plots):
    """Default ``budget plot``: one line figure per swept parameter for every axis of the
    store; each class with values on an axis is named by its label in that figure's caption,
    either with its change along the sweep or among the flat ones."""
    from budget.runner.registry import get_study
    from budget.sweeps.plot import _classes_on

    ds = grid["ds"]
    study = get_study("starcam")
    labels = {c.name: c.label for c in study.classes(study.load_scenario())}
    by_name = {f.name: f for f in grid_plots}
    for axis in ds["axis"].values:
        for xname in ds.attrs["parameters"]:
            f = by_name[f"classes_vs_{xname}__{axis}.png"]
            classes = [str(c) for c in _classes_on(ds.sel(axis=axis))]
            assert classes
            for c in classes:
                assert labels[c] in f.caption, (c, f.name)
            assert ("Flat over this range" in f.caption) or ("No class is flat" in f.caption)


# --------------------------------------------------------------------------- shared truths
SHARED = """
    name = "tiny shared truths"
    base = "tiny.toml"
    kind = "starcam"
    seed = 9
    trials = 2
    [parameters]
    "lab.knowledge.qe_peak_nm_error" = [0.0, 40.0]
    "optics.psf.sigma0_px" = [0.8, 1.1]
"""


def test_truths_shared_across_points_equal_truths_computed_per_point(tmp_path):
    """Four points, two PSF widths: the lab's QE knowledge cannot change the truths, so two
    truths serve the four points; the store is bit-identical to one computed with a truth
    per point, and the points of one width hold one truth."""
    path = _write(tmp_path, SHARED)
    shared = run_sweep(path, tmp_path / "shared", inline=True)
    alone = run_sweep(path, tmp_path / "alone", inline=True, truths_shared=False)
    assert (shared.truths_computed, alone.truths_computed) == (2, 4)
    a, b = open_sweep(tmp_path / "shared"), open_sweep(tmp_path / "alone")
    _assert_same(a, b)
    # the run's truths (each trial's camera's LSFE-C1, LSFE and total follow the point's trials)
    t = a.truth.sel({"class": ["te", "hsfe", "lsfe_s", "lsfe_c2"]})
    np.testing.assert_array_equal(t.isel({"lab.knowledge.qe_peak_nm_error": 0}).values,
                                  t.isel({"lab.knowledge.qe_peak_nm_error": 1}).values)
    assert not np.array_equal(t.isel({"optics.psf.sigma0_px": 0}).values, t.isel({"optics.psf.sigma0_px": 1}).values)


def test_truth_pieces_give_the_same_truths_however_they_are_batched(tmp_path, monkeypatch):
    """share_truths runs a truth's pieces in runs of consecutive pieces, their length set by
    the worker count: one piece per task and a few long runs give identical truths (each
    piece is a pure function of the scenario, the seed and the piece)."""
    import budget.sweeps.run as R
    from budget.runner.executors import InlineExecutor
    from budget.sweeps.execute import SweepRunner
    from budget.sweeps.run import plan_tasks, share_truths

    tasks, _ = plan_tasks(load_sweep(_write(tmp_path, SHARED)))
    seen = {}
    for name, per_worker in (("one piece a task", 10**6), ("long runs", 1)):
        monkeypatch.setattr(R, "TRUTH_TASKS_PER_WORKER", per_worker)
        lengths = []
        runner = SweepRunner(InlineExecutor())
        orig = runner.run

        def run(part_tasks, _orig=orig, _lengths=lengths):
            _lengths.extend(len(t.parts) for t in part_tasks)
            return _orig(part_tasks)

        runner.run = run
        out, n = share_truths(runner, tasks)
        assert n == 2
        seen[name] = (out, lengths)
    assert set(seen["one piece a task"][1]) == {1} and max(seen["long runs"][1]) > 1
    for a, b in zip(seen["one piece a task"][0], seen["long runs"][0]):
        assert a.truths.keys() == b.truths.keys()
        for k in a.truths:
            assert a.truths[k] == b.truths[k], k
