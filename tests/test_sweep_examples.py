"""The committed sweep examples (docs/examples/sweeps/*.toml) give the same stores whatever
runs their points: a tiny version of an example, run in this process and on 2 local worker
processes, holds identical values.

test_sweep_run.py checks the same property on a made-up truth-mode grid of the star
camera; these tests start from the example files themselves (so an example that stops
loading, or a study whose validation depends on the worker, fails here) and cover the
validation mode of two studies: seed 001's inductosyn (``polygon_faces.toml``) and seed
000's camera (``te_magnitude_exposure.toml`` on the tiny test camera).

Exact equality is right here, not a tolerance: the same sweep file, the same point seeds
(a point's seed depends only on the sweep seed and its values), the same code on the
same machine, and every point computed by the same sequence of floating-point
operations (one worker per point, trials in a fixed order); only where it runs differs.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w
import xarray as xr

from budget.sweeps.run import open_sweep, run_sweep
from budget.sweeps.spec import load_sweep
from tiny_camera import TINY

EXAMPLES = Path(__file__).resolve().parent.parent / "docs" / "examples" / "sweeps"


def _tiny_example(name: str, d: Path, *, keep: dict[str, int], set_: dict, fixed: dict | None = None,
                  base: str | None = None) -> Path:
    """A tiny variant of the example ``name`` written into ``d``: its parameters cut to
    their first ``keep[key]`` values, the settings ``set_`` replaced, ``fixed`` added to
    its [fixed] table and, if given, ``base`` (TOML text) as its base scenario."""
    spec = tomllib.loads((EXAMPLES / name).read_text())
    assert set(keep) == set(spec["parameters"]), "every swept parameter is cut"
    spec["parameters"] = {k: v[: keep[k]] for k, v in spec["parameters"].items()}
    spec.pop("sensitivity", None)
    spec.update(set_)
    if fixed:
        spec["fixed"] = {**spec.get("fixed", {}), **fixed}
    if base is not None:
        (d / "base.toml").write_text(base)
        spec["base"] = "base.toml"
    path = d / f"tiny_{name}"
    path.write_bytes(tomli_w.dumps(spec).encode())
    return path


def _assert_identical_stores(a: Path, b: Path) -> None:
    da, db = open_sweep(a), open_sweep(b)
    # compute_s is a wall time (information, not a result); every other variable is a result
    names = [v for v in da.data_vars if v != "compute_s"]
    assert set(names) == {v for v in db.data_vars if v != "compute_s"}
    for v in names:
        xr.testing.assert_identical(da[v].drop_attrs(), db[v].drop_attrs())
    assert bool(da.done.all()) and bool(db.done.all())
    # something was computed: on each class's own axes (the store holds the union of the
    # classes' axes, NaN where a class has no such axis) the truths and means are numbers
    from budget.sweeps.layout import study_for_kind

    study = study_for_kind(da.attrs["kind"])
    for spec in study.classes(study.load_scenario()):
        own = da.sel({"class": spec.name, "axis": list(spec.axes)})
        # a variant may not estimate every axis (seed 001's published fit has 8 of the 12
        # coefficients): at least one variant does, and has its truth there (a per-trial
        # truth, e.g. of each trial's instrument, exists where its variant estimates)
        for var in ("truth", "mean"):
            finite = np.isfinite(own[var])
            if "variant" in finite.dims:  # a store with per-trial truths keeps them per variant
                finite = finite.any("variant")
            assert bool(finite.all()), (spec.name, var)


@pytest.mark.parametrize("name", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_every_example_sweep_file_loads(name):
    """Every committed example is a valid sweep file: all its points (and Sobol samples)
    build and pass the scenario's and the simulator's checks."""
    sw = load_sweep(EXAMPLES / name)
    assert sw.points


@pytest.fixture(scope="module")
def polygon_faces(tmp_path_factory):
    """Seed 001's example cut to 2 face counts x 8 simulated calibrations on a coarse truth
    grid, run in this process (a truth of about 0.5 s per point): its path and store."""
    d = tmp_path_factory.mktemp("polygon_faces")
    path = _tiny_example("polygon_faces.toml", d, keep={"calibration.short_polygon.faces": 2},
                         set_={"trials": 8}, fixed={"validation.dense_step_deg": 0.05})
    assert run_sweep(path, d / "inline", inline=True).computed == 2
    return path, d / "inline"


@pytest.mark.parametrize("case", ["polygon_faces", "te_magnitude_exposure"])
def test_example_sweep_gives_the_same_store_inline_and_on_two_processes(case, tmp_path, request):
    if case == "polygon_faces":
        # seed 001: 2 face counts x 8 simulated calibrations, a coarse truth grid
        path, inline = request.getfixturevalue("polygon_faces")
    else:
        # seed 000 on the tiny camera: 2 magnitudes x 1 exposure, 2 trials each
        path = _tiny_example("te_magnitude_exposure.toml", tmp_path,
                             keep={"lab.source.match_v_mag": 2, "camera.exposure_s": 1},
                             set_={"trials": 2}, base=TINY)
        inline = tmp_path / "inline"
        assert run_sweep(path, inline, inline=True).computed == 2
    two = run_sweep(path, tmp_path / "two", workers=2)
    assert two.computed == 2
    assert two.runner == "2 local processes"
    _assert_identical_stores(inline, tmp_path / "two")


def test_store_carries_each_class_unit_and_plots_only_classes_on_the_axis(polygon_faces, tmp_path):
    """Seed 001's classes have different units and axes (3 sigma on ``angle``; coefficients
    in arcsec on ``A_L1c``...): the store names each class's unit, and a plot of one axis
    draws only the classes that have it (no empty panel)."""
    from budget.sweeps.layout import study_for_kind
    from budget.sweeps.plot import _classes_on, plot_store

    _, store = polygon_faces
    ds = open_sweep(store)
    study = study_for_kind("inductosyn")
    specs = study.classes(study.load_scenario())
    assert ds.attrs["class_units"] == {c.name: c.unit for c in specs}
    for axis in ("angle", "A_S1s"):
        want = [c.name for c in specs if axis in c.axes]
        assert [str(c) for c in _classes_on(ds.sel(axis=axis))] == want
    files = plot_store(store, tmp_path / "plots", axis="A_S1s")
    assert files and all(Path(f).stat().st_size > 0 for f in files)
