"""The sweep store: one Zarr directory, written point by point, resumable.

Layout (Zarr format 2, the stable specification that every Zarr reader knows; xarray's
``_ARRAY_DIMENSIONS`` convention, so ``xarray.open_zarr(STORE)`` gives the labelled
dataset):

* root group: the grid. Dimensions: the swept parameters (``mode = "product"``, or a
  single parameter) or ``point`` with each parameter as a coordinate along it (``zip``),
  then ``class``, ``axis`` and ``variant``. Variables: see
  :func:`budget.sweeps.layout.schema`, plus ``done`` (1 once a point is complete).
  Attributes: the sweep file's text, its hash, name, seed, the package version, the
  base scenario (TOML) and its hash, kind, mode, evaluation settings.
* group ``sensitivity``: the Sobol samples (dimension ``sample``; ``X`` the parameter
  values) with the same variables per sample and ``done``;
* group ``sobol``: the indices (``S1``, ``S1_conf``, ``ST``, ``ST_conf`` by output and
  ``parameter``), written once every sample is done (attribute ``complete``).

Atomicity: the store is created in a temporary directory and renamed into place; every
point is its own chunk of every variable, and Zarr writes each chunk to a temporary file
renamed over the old one; ``done`` is written last. A kill at any moment therefore leaves
each point either complete and marked done, or not marked done (its chunks are rewritten,
identically, by the next run). Only the process that runs the sweep writes (workers
return their arrays), so there is one writer and remote workers need no access to it.
"""

from __future__ import annotations

import errno
import fcntl
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

import simcam
from budget.sweeps.layout import class_units, labels, schema
from budget.sweeps.spec import scenario_hash, scenario_text
from simcam.infra.errors import UserInputError
from simcam.infra.lifecycle import announce_size, check_disk, partial_prefix, remove_stale_partials
from simcam.infra.outputs import apply_umask, check_output_dir

__all__ = [
    "FORMAT",
    "StoreWriter",
    "check_store",
    "create_store",
    "open_sensitivity",
    "open_sobol",
    "open_sweep",
    "store_attrs",
    "store_lock",
]

FORMAT = 1
#: how point seeds are made (stored in the attributes)
SEED_RULE = ("point seed = SeedSequence(seed, spawn_key=(w0, w1)).generate_state(1, uint64) >> 1, with (w0, w1) "
             "the first two little-endian uint32 words of sha256 of the point's canonical identity "
             "(sorted [key, value] pairs, numbers as repr(float)); Sobol samples share "
             "SeedSequence(seed, spawn_key=(1,))")


def _fill(dtype: str):
    return np.nan if dtype.startswith("f") else 0


def store_attrs(sweep) -> dict:
    """Root attributes of a sweep's store."""
    s = sweep.spec
    return {
        "title": s.name or Path(sweep.path).stem, "sweep_format": FORMAT, "sweep_hash": sweep.hash,
        "sweep_file": sweep.text, "sweep_path": str(sweep.path), "seed": s.seed,
        "version": simcam.__version__, "kind": s.kind, "mode": s.mode, "evaluate": s.evaluate,
        "trials": -1 if s.trials is None else s.trials,
        "tolerance": -1.0 if s.tolerance is None else s.tolerance,
        "parameters": [k for k, _ in sweep.params], "point_dims": list(sweep.dims),
        "points": len(sweep.points), "base_scenario": scenario_text(s.kind, sweep.base),
        "base_scenario_hash": scenario_hash(s.kind, sweep.base), "seed_rule": SEED_RULE,
        "class_units": class_units(s.kind),
    }


def _coord_array(values: list) -> np.ndarray:
    if all(isinstance(v, bool) for v in values):
        return np.array(values, dtype=bool)
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.int64)
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        return np.array(values, dtype=np.float64)
    return np.array([str(v) for v in values])


def _template(point_dims, point_shape, point_coords, kind, evaluate, attrs):
    import dask.array as da
    import xarray as xr

    lab = labels(kind)
    data_vars, enc = {}, {}
    for name, (dims, dtype, vattrs) in schema(kind, evaluate).items():
        shape = tuple(point_shape) + tuple(len(lab[d]) for d in dims)
        chunks = (1,) * len(point_shape) + tuple(len(lab[d]) for d in dims)
        # one Dask chunk (only the metadata is written: compute=False), one Zarr chunk per
        # point: a graph of one task per variable, however many points (a 1,000,000-point
        # axis built a graph of millions of tasks and 5 GiB before its store existed)
        data_vars[name] = (tuple(point_dims) + dims, da.full(shape, _fill(dtype), dtype=dtype, chunks=-1), vattrs)
        enc[name] = ({"_FillValue": np.nan} if dtype.startswith("f") else {"_FillValue": None}) | {"chunks": chunks}
    data_vars["done"] = (tuple(point_dims), da.zeros(point_shape, dtype="i1", chunks=-1),
                         {"long_name": "1 once the point is complete (written last)"})
    enc["done"] = {"_FillValue": None, "chunks": (1,) * len(point_shape)}
    used = {d for v in schema(kind, evaluate).values() for d in v[0]}
    coords = {d: list(lab[d]) for d in ("class", "axis", "variant") if d in used}
    coords.update(point_coords)
    return xr.Dataset(data_vars, coords=coords, attrs=attrs), enc


#: the disk a chunk file takes at least (one file system block)
_BLOCK_BYTES = 4096


def store_bytes(sweep) -> float:
    """Disk the finished store takes, at least: one chunk file per point (and Sobol sample)
    per variable, each at least one file-system block."""
    def per_point(kind, evaluate):
        lab = labels(kind)
        total = _BLOCK_BYTES  # the done flag
        for dims, dtype, _ in schema(kind, evaluate).values():
            n = float(np.prod([len(lab[d]) for d in dims])) if dims else 1.0
            total += max(_BLOCK_BYTES, n * np.dtype(dtype).itemsize)
        return total

    s = sweep.spec
    need = float(len(sweep.points)) * per_point(s.kind, s.evaluate) if sweep.params else 0.0
    if s.sensitivity is not None:
        need += float(len(sweep.sample_points)) * per_point(s.kind, s.sensitivity.evaluate)
    return need


def check_store_size(path, sweep) -> None:
    """Refuse a store that cannot fit on the disk at ``path`` (before it is created)."""
    need = store_bytes(sweep)
    check_disk(path, need, what=f"{getattr(sweep, 'path', 'sweep')}: parameters: a store of "
                                 f"{len(sweep.points)} point(s)")
    announce_size(need, where=path)


def create_store(path: str | os.PathLike, sweep) -> None:
    """Create the (empty) store of ``sweep`` at ``path``, atomically (temp dir + rename)."""
    import xarray as xr

    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    check_store_size(path, sweep)  # refused before anything is created
    parent.mkdir(parents=True, exist_ok=True)
    # a store a killed run left half-created (.NAME.partial.<pid>.*, its PID gone) is
    # removed here and said so on stderr; this run's own is removed on any failure below
    remove_stale_partials(path)
    tmp = Path(tempfile.mkdtemp(prefix=partial_prefix(path), dir=parent))
    apply_umask(tmp, is_dir=True)  # mkdtemp makes it 0700; the store gets the user's umask
    try:
        attrs = store_attrs(sweep)
        s = sweep.spec
        if sweep.params:
            dims = sweep.dims
            if dims == ("point",):
                pc = {k: ("point", _coord_array(v)) for k, v in sweep.params}
                pc["point"] = np.arange(len(sweep.points))
            else:
                pc = {k: _coord_array(v) for k, v in sweep.params}
            ds, enc = _template(dims, sweep.shape, pc, s.kind, s.evaluate, attrs)
        else:
            ds, enc = xr.Dataset(attrs=attrs), {}
        ds.to_zarr(tmp, mode="w", zarr_format=2, consolidated=False, compute=False, encoding=enc)
        if s.sensitivity is not None:
            sens = s.sensitivity
            n = len(sweep.sample_points)
            names = sweep.sensitivity_names
            sattrs = {"samples_N": sens.samples, "evaluate": sens.evaluate, "output": sens.output,
                      "trials": -1 if sens.trials is None else sens.trials,
                      "tolerance": -1.0 if sens.tolerance is None else sens.tolerance,
                      "conf_level": sens.conf_level, "resamples": sens.resamples,
                      "distributions": {k: d.model_dump(mode="json", exclude_none=True)
                                        for k, d in sens.parameters.items()},
                      "sampling": "SALib sobol.sample (Saltelli scheme, scrambled Sobol sequence), "
                                  "calc_second_order = false: N (D + 2) samples"}
            sds, senc = _template(("sample",), (n,), {"sample": np.arange(n), "parameter": names},
                                  s.kind, sens.evaluate, sattrs)
            sds["X"] = (("sample", "parameter"), np.asarray(sweep.samples, dtype=np.float64),
                        {"long_name": "parameter values of each sample"})
            sds.to_zarr(tmp, group="sensitivity", mode="w", zarr_format=2, consolidated=False,
                        compute=False, encoding=senc)
            # X is known now: write it (the template above only wrote metadata)
            import zarr

            zarr.open_group(str(tmp), mode="r+")["sensitivity/X"][...] = np.asarray(sweep.samples, dtype=np.float64)
        import zarr

        # the metadata never changes after this (points only write chunks): consolidated,
        # so that plain xarray.open_zarr(STORE) reads it in one go
        zarr.consolidate_metadata(str(tmp), zarr_format=2)
        try:
            os.rename(tmp, path)
        except OSError as exc:
            # another run created it meanwhile (no lock where the folder did not exist yet):
            # that store is this sweep's (checked), and this run resumes it
            if exc.errno not in (errno.ENOTEMPTY, errno.EEXIST) or check_store(path, sweep) != "resume":
                raise
            shutil.rmtree(tmp, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def lock_path(path: str | os.PathLike) -> Path:
    """The lock file of the store ``path``: ``.NAME.lock`` beside it."""
    path = Path(path)
    return path.parent / f".{path.name}.lock"


@contextmanager
def store_lock(path: str | os.PathLike) -> Iterator[None]:
    """Hold the store ``path`` for this run: one writer at a time.

    An exclusive ``flock`` on ``.NAME.lock`` beside the store (the kernel releases it when
    the process ends, however it ends); the file holds the writer's PID and is removed
    when the run ends. A second ``budget sweep ... --out`` of the same store while the
    first runs is refused at once, naming the other writer (was: ``OSError: Directory not
    empty`` when both created it). Where the store's folder does not exist yet, there is
    nothing to lock and nothing another run can have written: the run goes on (its
    creation then resumes a store another run created meanwhile: :func:`create_store`).
    """
    lock = lock_path(path)
    if not lock.parent.is_dir():
        yield
        return
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:  # a read-only folder: no other run can create the store there either
            yield
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            try:
                who = f" (pid {int(lock.read_text().strip())})"
            except (OSError, ValueError):
                who = ""
            raise UserInputError(f"--out {path}: another budget sweep{who} is writing this store "
                                 f"(it holds {lock}); wait for it to end, or give another --out") from None
        try:  # the file locked is still the one at that name (not one its last holder removed)
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        try:
            os.unlink(lock)
        except OSError:
            pass
        os.close(fd)


def _flags_from_chunk_names(folder: Path, shape: tuple[int, ...]) -> np.ndarray | None:
    """The flat done flags from the chunk files' names (``i.j.k``, Zarr format 2's "."
    separator, one element per chunk), or None where the folder is laid out otherwise."""
    if not shape:
        return None
    try:
        names = [n for n in os.listdir(folder) if not n.startswith(".")]
    except OSError:
        return None
    idx = []
    for name in names:
        parts = name.split(".")
        if len(parts) != len(shape) or not all(p.isdigit() for p in parts):
            return None
        idx.append([int(p) for p in parts])
    flags = np.zeros(math.prod(shape), dtype=bool)
    if idx:
        flags[np.ravel_multi_index(np.array(idx).T, shape)] = True
    return flags


def _read_attrs(path: Path) -> dict | None:
    import zarr

    try:
        g = zarr.open_group(str(path), mode="r", use_consolidated=False)
    except (OSError, ValueError):  # not a Zarr group (zarr NodeNotFoundError is a ValueError)
        return None
    return dict(g.attrs)


def check_store(path: str | os.PathLike, sweep) -> str:
    """``"new"`` (nothing there), ``"resume"`` (this sweep's store), or a UserInputError.

    A store made from a different sweep file (another hash), by another package
    version, or a path that holds something else, is refused before any work.
    """
    path = Path(path)
    if not path.exists() or (path.is_dir() and not any(path.iterdir())):
        # a new store (or an empty folder it is renamed onto): its location is checked
        # before any work (parent a writable folder, name length, not a device or an input)
        check_output_dir(path, option="--out", inputs=(getattr(sweep, "path", None),))
        return "new"
    if not path.is_dir():
        check_output_dir(path, option="--out")  # a file or a device: refused, naming it
    attrs = _read_attrs(path) if path.is_dir() else None
    if not attrs or "sweep_hash" not in attrs:
        raise UserInputError(f"--out {path}: exists and is not a sweep store; choose another path")
    if attrs["sweep_hash"] != sweep.hash:
        raise UserInputError(
            f"--out {path}: written by a different sweep file (hash {attrs['sweep_hash']}, "
            f"{attrs.get('sweep_path', '?')}); {sweep.path} has hash {sweep.hash}. "
            "Use another --out, or delete the store to start again")
    if attrs.get("version") != simcam.__version__:
        raise UserInputError(f"--out {path}: written by version {attrs.get('version')}, this is "
                             f"{simcam.__version__}; results of two versions are not mixed: use another --out")
    return "resume"


class StoreWriter:
    """Writes finished points into the store (single writer; see module docstring)."""

    def __init__(self, path: str | os.PathLike, sweep):
        import zarr

        self.path = Path(path)
        self.sweep = sweep
        self.root = zarr.open_group(str(self.path), mode="r+")
        self._arrays: dict = {}
        self._schema = {"grid": schema(sweep.kind, sweep.spec.evaluate)}
        if sweep.spec.sensitivity is not None:
            self._schema["sensitivity"] = schema(sweep.kind, sweep.spec.sensitivity.evaluate)

    def _array(self, group: str, name: str):
        key = (group, name)
        if key not in self._arrays:
            self._arrays[key] = self.root[name if group == "grid" else f"sensitivity/{name}"]
        return self._arrays[key]

    def _index(self, group: str, index: int) -> tuple[int, ...]:
        return self.sweep.grid_index(index) if group == "grid" else (index,)

    def done(self, group: str) -> np.ndarray:
        """Flat boolean array: which points of ``group`` are complete.

        Read from the names of the ``done`` array's chunk files (Zarr format 2: one file per
        point, named by its grid index, written only by :meth:`write`, last, with the value
        1): one folder listing instead of a read per point (a 1,000,000-point store took
        more than 5 minutes to read its flags). Any other layout is read through Zarr."""
        arr = self._array(group, "done")
        flags = _flags_from_chunk_names(self.path / ("done" if group == "grid" else "sensitivity/done"), arr.shape)
        if flags is None:
            flags = np.asarray(arr[...]).reshape(-1).astype(bool)
        return flags

    def write(self, result) -> None:
        """Write one point's arrays, then mark it done."""
        idx = self._index(result.group, result.index)
        for name in self._schema[result.group]:
            self._array(result.group, name)[idx] = result.values[name]
        self._array(result.group, "done")[idx] = 1

    def write_sobol(self, indices) -> None:
        """Write the Sobol indices dataset as group ``sobol``, then mark it complete."""
        import zarr

        indices.to_zarr(str(self.path), group="sobol", mode="w", zarr_format=2, consolidated=False)
        zarr.open_group(str(self.path), mode="r+", path="sobol", use_consolidated=False).attrs["complete"] = True
        zarr.consolidate_metadata(str(self.path), zarr_format=2)

    def sobol_complete(self) -> bool:
        import zarr

        try:
            g = zarr.open_group(str(self.path), mode="r", path="sobol", use_consolidated=False)
        except (OSError, ValueError):  # not a Zarr group (zarr NodeNotFoundError is a ValueError)
            return False
        return bool(g.attrs.get("complete", False))


def _open(path, group=None):
    import xarray as xr

    path = Path(path)
    attrs = _read_attrs(path) if path.is_dir() else None
    if not attrs or "sweep_hash" not in attrs:
        raise UserInputError(f"{path}: not a sweep store (made by `budget sweep ... --out {path}`)")
    return xr.open_zarr(str(path), group=group, consolidated=False)


def open_sweep(path: str | os.PathLike):
    """The grid of a sweep store as an xarray Dataset (loaded; undone points are NaN).

    A damaged store is one ``UserInputError`` naming it: a chunk that cannot be decoded,
    the ``truth`` or ``done`` array missing, or a point marked done whose truth chunk is
    gone (Zarr would read a missing chunk as its fill value, NaN, silently).
    """
    ds = _load_checked(path)
    if "done" in ds:
        ds["done"] = ds["done"].astype(bool)
        if ds.attrs.get("point_dims"):
            if "truth" not in ds:
                raise UserInputError(f"{path}: the store has no truth array (damaged store; run the sweep "
                                     "again into a new --out)")
            pdims = list(ds["done"].dims)
            other = [d for d in ds["truth"].dims if d not in pdims]
            lost = ds["done"] & ds["truth"].isnull().all(dim=other)
            if bool(lost.any()):
                n = int(lost.sum())
                raise UserInputError(f"{path}: {n} point(s) marked done have no truth values (a chunk of "
                                     "truth is missing: damaged store; delete those points' done flags or "
                                     "run the sweep again into a new --out)")
    elif ds.attrs.get("point_dims"):
        raise UserInputError(f"{path}: the store has no done array (damaged store)")
    return ds


def _load_checked(path, group=None):
    try:
        return _open(path, group=group).load()
    except UserInputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged chunk fails in the codec in many ways
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise UserInputError(f"{path}: a chunk of the store cannot be read ({type(exc).__name__}: {msg[:200]}); "
                             "damaged store") from None


def open_sensitivity(path: str | os.PathLike):
    """The Sobol samples and their outputs, or None when the sweep has no sensitivity."""
    import zarr

    _open(path)
    g = zarr.open_group(str(path), mode="r", use_consolidated=False)
    if "sensitivity" not in g:
        return None
    ds = _load_checked(path, group="sensitivity")
    ds["done"] = ds["done"].astype(bool)
    return ds


def open_sobol(path: str | os.PathLike):
    """The Sobol indices dataset, or None when not (yet) computed."""
    import zarr

    _open(path)
    try:
        g = zarr.open_group(str(path), mode="r", path="sobol", use_consolidated=False)
    except (OSError, ValueError):  # not a Zarr group (zarr NodeNotFoundError is a ValueError)
        return None
    if not g.attrs.get("complete", False):
        return None
    return _open(path, group="sobol").load()

