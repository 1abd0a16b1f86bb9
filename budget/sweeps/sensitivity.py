"""Sobol sensitivity of the budget to design parameters (SALib).

The ``[sensitivity]`` table of a sweep file declares a distribution per parameter
(:class:`budget.sweeps.spec.DistSpec`). The samples are SALib's Saltelli scheme on a
scrambled Sobol sequence (``N (D + 2)`` model runs for D parameters, first and total
order), each run through the same point evaluation as a grid point (usually the fast
``truth`` mode) with one common seed. For every output (each class and axis, and each
variant where the output has one) :func:`sobol_indices` returns the first-order index
``S1`` (the share of the output's variance due to the parameter alone) and the total
index ``ST`` (including its interactions), with bootstrap confidence intervals
(``conf_level``, ``resamples``) from :func:`SALib.analyze.sobol.analyze`.

An output that does not vary over the samples (e.g. LSFE-C2 when only the PSF changes)
has no indices: they are NaN, with ``note`` saying why; so are outputs that are not
finite at some sample.
"""

from __future__ import annotations

import numpy as np

from budget.sweeps.spec import salib_problem, sensitivity_seed

__all__ = ["analyze_samples", "sobol_indices"]


def sobol_indices(problem: dict, y: np.ndarray, *, conf_level: float = 0.95, resamples: int = 1000,
                  seed: int = 0) -> dict:
    """First and total Sobol indices of one output ``y`` (one value per sample).

    Returns
    -------
    dict with arrays (one per parameter) ``S1``, ``S1_conf``, ``ST``, ``ST_conf`` (the
    half-width of the ``conf_level`` bootstrap interval) and ``note`` ("" when computed).
    """
    from SALib.analyze import sobol

    d = problem["num_vars"]
    y = np.asarray(y, dtype=float)
    nan = {k: np.full(d, np.nan) for k in ("S1", "S1_conf", "ST", "ST_conf")}
    if not np.all(np.isfinite(y)):
        return {**nan, "note": f"output not finite at {int(np.sum(~np.isfinite(y)))} sample(s)"}
    if np.ptp(y) <= 1e-12 * max(1.0, float(np.max(np.abs(y)))):
        return {**nan, "note": "output does not vary over the samples"}
    si = sobol.analyze(problem, y, calc_second_order=False, num_resamples=resamples,
                       conf_level=conf_level, print_to_console=False, seed=seed)
    return {"S1": np.asarray(si["S1"]), "S1_conf": np.asarray(si["S1_conf"]),
            "ST": np.asarray(si["ST"]), "ST_conf": np.asarray(si["ST_conf"]), "note": ""}


def analyze_samples(samples, sweep):
    """Sobol indices of every output of a complete ``sensitivity`` dataset.

    Returns
    -------
    xarray.Dataset with ``S1``, ``S1_conf``, ``ST``, ``ST_conf`` over the output's
    dimensions (class, axis[, variant]) and ``parameter``, and ``note``.
    """
    import xarray as xr

    sens = sweep.spec.sensitivity
    problem = salib_problem(sens)
    var = "truth" if sens.output == "truth" else "mean"
    y = samples[var]
    if sens.output != "truth":
        y = y.sel(variant=sens.output)
    out_dims = [d for d in y.dims if d != "sample"]
    y = y.transpose("sample", *out_dims)
    shape = tuple(y.sizes[d] for d in out_dims)
    names = list(sens.parameters)
    res = {k: np.full(shape + (len(names),), np.nan) for k in ("S1", "S1_conf", "ST", "ST_conf")}
    notes = np.full(shape, "", dtype=object)
    seed = sensitivity_seed(sweep.spec.seed) % (2**32)
    vals = y.values
    for idx in np.ndindex(*shape):
        r = sobol_indices(problem, vals[(slice(None),) + idx], conf_level=sens.conf_level,
                          resamples=sens.resamples, seed=seed)
        for k, arr in res.items():
            arr[idx] = r[k]
        notes[idx] = r["note"]
    coords = {d: y[d].values for d in out_dims}
    coords["parameter"] = names
    dims = tuple(out_dims) + ("parameter",)
    long = {"S1": "first-order Sobol index", "ST": "total Sobol index",
            "S1_conf": f"half-width of the {sens.conf_level:.0%} bootstrap interval of S1",
            "ST_conf": f"half-width of the {sens.conf_level:.0%} bootstrap interval of ST"}
    ds = xr.Dataset({k: (dims, v, {"long_name": long[k]}) for k, v in res.items()}, coords=coords)
    ds["note"] = (tuple(out_dims), notes.astype(str))
    ds.attrs.update(output=sens.output, output_variable=var, conf_level=sens.conf_level,
                    resamples=sens.resamples, samples_N=sens.samples, evaluations=int(vals.shape[0]),
                    method="SALib.analyze.sobol (Saltelli 2010 / Jansen estimators), bootstrap intervals")
    return ds
