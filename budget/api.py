"""The Python face of the lab, for notebooks and scripts (docs/api.md).

::

    import budget

    res = budget.validate("whiskbroom", trials=40, workers=2)
    res                      # a short summary; in a notebook, the findings and the table
    df = res.to_dataframe()  # tidy: class, axis, variant, statistic, value, unit
    res.to_json()            # what ``budget <study> validate --json`` writes

* :func:`validate` runs a study's Monte Carlo validation (the runner,
  :func:`budget.runner.run.run_study`) and returns its
  :class:`~budget.runner.result.StudyResult` (its repr, notebook view, table and JSON
  payload are the result's own: :mod:`budget.runner.result`);
* :func:`robustness` runs a study's robustness cases (the world's effects) and returns them;
* :func:`plan` finds the cheapest lab protocol that meets required accuracies
  (:func:`budget.runner.plan.plan_protocol`, docs/planning.md) and returns its ``PlanResult``;
* :func:`sweep` runs a design-trade sweep file into a Zarr store and returns it opened
  (:func:`budget.sweeps.run.run_sweep`).

Both work from a plain script without an ``if __name__ == "__main__":`` guard. On Linux a
fresh process forks its workers (:func:`budget.runner.executors.start_method`), which
start with the script's modules and classes and run nothing again. Otherwise (macOS, a
process with other threads or with numba's thread pool launched, which must not be
forked) they are spawned, and spawn re-runs the main script in each worker unless told
otherwise; the workers need only budget's own functions, so while they start, the main
module is not announced to them (:func:`_workers_skip_main`). Where the study itself is
defined in the script, spawned workers do need it: then a script without the guard gets
one line saying what to do.
"""

from __future__ import annotations

import contextlib
import sys
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

from budget.arguments import check_arguments, check_path
from budget.runner.claims_run import run_claims
from budget.runner.executors import default_workers
from budget.runner.registry import get_study, study_names
from budget.runner.study import Study
from simcam.infra.errors import WorkersLost

__all__ = ["claims", "plan", "robustness", "scenario_text", "studies", "sweep", "validate"]


def studies() -> list[str]:
    """The registered study names (``"starcam"``, ``"inductosyn"``, ...)."""
    return study_names()


def scenario_text(study) -> str:
    """The study's embedded default scenario as TOML, with its comments (what
    ``budget <study> scenario`` prints); ``tomllib.loads`` of it is a dict to edit and pass
    to :func:`validate`."""
    return _study(study).default_text()


def _study(study):
    if isinstance(study, Study):
        return study
    if isinstance(study, str):
        return get_study(study)
    raise TypeError(f"study: a registered name ({', '.join(studies())}) or a Study, not {type(study).__name__}")


def _scenario(study, scenario):
    """``None`` (the embedded default), a path, a mapping (validated like a file) or a model."""
    if scenario is None:
        return study.load_scenario()
    if isinstance(scenario, (str, Path)):
        return study.load_scenario(scenario)
    if isinstance(scenario, dict):
        return study.from_dict(scenario, source="scenario (dict)")
    return scenario


@contextlib.contextmanager
def _workers_skip_main(*objects):
    """While worker processes start, hide the main module's file and spec from
    :mod:`multiprocessing`'s spawn preparation, so the workers do not re-run the user's
    script (they unpickle budget's functions and studies by their own modules). Nothing is
    hidden when one of ``objects`` is defined in the main module (the workers need it)."""
    main = sys.modules.get("__main__")
    if main is None or any(type(o).__module__ == "__main__" or getattr(o, "__module__", None) == "__main__"
                           for o in objects):
        yield
        return
    sentinel = object()
    saved_file = main.__dict__.get("__file__", sentinel)
    saved_spec = main.__dict__.get("__spec__", sentinel)
    try:
        if saved_file is not sentinel:
            del main.__file__
        if saved_spec is not sentinel:
            main.__spec__ = None
        yield
    finally:
        if saved_file is not sentinel:
            main.__file__ = saved_file
        if saved_spec is not sentinel:
            main.__spec__ = saved_spec


@contextlib.contextmanager
def _on_workers(*objects):
    """Around a call that starts worker processes: :func:`_workers_skip_main` while they
    start, and a pool that could not start (spawned workers that re-ran a script defining
    the study) turned into one line saying what to do."""
    in_main = any(type(o).__module__ == "__main__" or getattr(o, "__module__", None) == "__main__" for o in objects)
    with _workers_skip_main(*objects):
        try:
            yield
        except (BrokenProcessPool, WorkersLost) as e:
            if isinstance(e, WorkersLost) and not in_main:
                raise  # a worker lost in the run, not at the start of a script's workers
            raise RuntimeError("budget: the worker processes could not start (they re-ran your script, which "
                               "defines the study): put the call under `if __name__ == \"__main__\":`, "
                               "or pass workers=1") from None


def validate(study, scenario=None, *, trials: int | None = None, seed: int = 0, workers: int | None = None,
             tolerance: float | None = None, progress: bool = False):
    """The Monte Carlo validation of ``study`` on ``scenario``; returns a
    :class:`~budget.runner.result.StudyResult`.

    Parameters
    ----------
    study : str or Study
        A registered name (:func:`studies`) or a :class:`~budget.runner.study.Study`.
    scenario : None, path, dict or model
        The embedded default (None), a TOML file, a mapping validated as a file would be, or
        the study's scenario model.
    trials : int, optional
        Number of trials (default: the scenario's, or adaptive stopping where it gives a
        tolerance); ``tolerance`` instead stops when every standard error is below it.
    seed : int
        Run seed; results do not depend on ``workers``.
    workers : int, optional
        Local worker processes (default: all cores).
    progress : bool
        A progress bar on stderr.
    """
    check_arguments(locals())  # each argument's type and range, named, before any work
    from budget.runner.run import run_study

    st = _study(study)
    scn = _scenario(st, scenario)
    if workers is None:
        workers = default_workers()
    with _on_workers(st):
        return run_study(st, scn, trials=trials, tolerance=tolerance, seed=seed, workers=workers,
                         progress=progress)


def robustness(study, scenario=None, *, trials: int | None = None, seed: int = 0, workers: int | None = None,
               progress: bool = False):
    """What each method's claim survives of the world's effects
    (:func:`budget.runner.robustness.run_robustness`); ``study`` and ``scenario`` as for
    :func:`validate`. Returns its ``RobustnessResult`` (``write_report(folder)``, ``to_json()``)."""
    check_arguments(locals())  # each argument's type and range, named, before any work
    from budget.runner.robustness import run_robustness

    st = _study(study)
    scn = _scenario(st, scenario)
    with _on_workers(st):
        return run_robustness(st, scn, trials=trials, seed=seed,
                              workers=default_workers() if workers is None else workers, progress=progress,
                              source=str(scenario) if isinstance(scenario, (str, Path)) else "")


def plan(study, scenario=None, *, require=(), variant: str | None = None, confidence: float = 0.95,
         budget_hours: float | None = None, trials: int | None = None, seed: int = 0, workers: int | None = 1,
         progress: bool = False, sure: float = 0.9, fix=None):
    """The cheapest protocol of ``study`` (its :meth:`~budget.runner.capabilities.Plannable.protocol_knobs`
    and shapes) whose ``variant`` estimates meet every requirement of ``require``
    (``"CLASS.AXIS<=VALUE"``: the ``confidence`` quantile of ``|estimate - truth|``), re-validated
    on fresh trials (:func:`budget.runner.plan.plan_protocol`, docs/planning.md); ``study`` and
    ``scenario`` as for :func:`validate`. Returns a ``PlanResult`` (``answer()``,
    ``to_dataframe()``, ``to_json()``, ``write_report(folder)``, ``recommended_toml()``).
    ``workers`` defaults to 1: a plan runs many short validations. ``sure``: how sure the
    recommended protocol is to pass the re-validation (0.5: the boundary protocol). ``fix``:
    knobs pinned, ``{field: value}`` (or texts ``"FIELD=VALUE"``)."""
    check_arguments(locals())  # each argument's type and range, named, before any work
    from budget.runner.plan import plan_protocol

    st = _study(study)
    scn = _scenario(st, scenario)
    if isinstance(require, str):
        require = [require]
    with _on_workers(st):
        return plan_protocol(st, scn, list(require), variant=variant, confidence=confidence,
                             budget_hours=budget_hours, trials=trials, seed=seed,
                             workers=default_workers() if workers is None else workers, progress=progress,
                             sure=sure, fix=fix)


def claims(out, *, studies=(), trials: int | None = None, seed: int = 0, workers: int | None = None,
           tolerances=(), overwrite: bool = False, progress: bool = False):
    """Every study's claims ledger in both worlds, written to the folder ``out`` as one page
    (``index.html``), the ledger's JSON and each run's report: what ``budget claims`` does
    (:func:`budget.runner.claims_run.run_claims`). ``studies``: names (default: every
    registered study); ``tolerances``: texts ``"CLASS=VALUE"``, a user's requirement in place
    of the declared tolerances. Returns a ``ClaimsResult`` (``ledgers``, ``page``,
    ``counts()``, ``to_json()``)."""
    check_path(out, "out", what="output folder")
    check_arguments({k: v for k, v in locals().items() if k != "out"})  # each argument, named, before any work
    if isinstance(studies, str):
        studies = [studies]
    if isinstance(tolerances, str):
        tolerances = [tolerances]
    with _on_workers(*[s for s in studies if isinstance(s, Study)]):
        return run_claims(out, studies=tuple(studies), trials=trials, seed=seed,
                          workers=default_workers() if workers is None else workers, tolerances=tuple(tolerances),
                          overwrite=overwrite, progress=progress)


def sweep(sweep_file, out, *, workers: int | None = None, progress: bool = False):
    """Run the design-trade sweep ``sweep_file`` (docs/sweeps.md) into the Zarr store ``out``
    (resumed when it holds this sweep) and return the store opened as an
    :class:`xarray.Dataset`."""
    check_arguments(locals())  # each argument's type and range, named, before any work
    import xarray as xr

    from budget.sweeps.run import run_sweep

    with _on_workers():
        run_sweep(sweep_file, out, workers=workers, progress=progress, echo=lambda *a, **k: None)
    return xr.open_zarr(out)
