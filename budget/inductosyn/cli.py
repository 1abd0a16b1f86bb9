"""`budget inductosyn ...` (alias `budget harmonics`): calibration fits, design analysis
and validation of the seed-001 inductosyn.

The commands of the inductosyn study's group (:func:`commands`, one group under both names). User mistakes raise :class:`simcam.infra.errors.ScenarioError` or
:class:`simcam.infra.errors.UserInputError`; ``budget.cli.main`` prints them as one line
each and exits 2.
"""

from __future__ import annotations

import math

import click
import numpy as np
import tomli_w

import simcam
from budget.figures import plt as _plt
from budget.figures import save
from budget.inductosyn.harmonics import (
    HarmonicSpec,
    accept,
    alias_order,
    analyse_design,
    calibrate_in_sequence,
    fit_joint,
    fit_long_period,
    fit_short_period,
    read_calibration_csv,
    sigma3_arcsec,
)
from budget.inductosyn.report import summary_lines
from budget.runner.numbers import fmt
from budget.runner.validate_cmd import validate_command_for
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_distinct_inputs, check_run_outputs, naming_failed_writes

__all__ = ["commands", "design_command", "fit_command", "scenario_command", "validate_command"]


def _orders(text: str, what: str) -> tuple[int, ...]:
    text = text.strip()
    if not text:
        return ()
    try:
        out = tuple(int(t) for t in text.split(","))
    except ValueError:
        raise UserInputError(f"--{what}: expected comma-separated positive integers, got {text!r}") from None
    if any(o < 1 for o in out) or len(set(out)) != len(out):
        raise UserInputError(f"--{what}: orders must be distinct positive integers, got {text!r}")
    return out


@click.command("scenario")
def scenario_command() -> None:
    """Print the resolved default inductosyn scenario (TOML, all fields)."""
    from simcam.encoder.inductosyn import default

    click.echo(tomli_w.dumps(default().model_dump(mode="json", exclude_none=True)), nl=False)


@click.command("design")
@click.option("--faces", type=int, required=True, help="Polygon face count.")
@click.option("--pole-pairs", type=int, default=360, show_default=True)
@click.option("--mech-orders", default="1,2", show_default=True)
@click.option("--elec-orders", default="1,2", show_default=True)
@click.option("--no-constant", is_flag=True, help="Fit without a constant term.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), default=None)
def design_command(faces, pole_pairs, mech_orders, elec_orders, no_constant, json_out) -> None:
    """Rank, condition number and aliasing of a polygon calibration design."""
    from simcam.encoder.polygon import nominal_face_angles_deg

    if faces < 3:
        raise UserInputError("--faces: a polygon has at least 3 faces")
    if pole_pairs < 1:
        raise UserInputError("--pole-pairs: must be >= 1")
    spec = HarmonicSpec(mech_orders=_orders(mech_orders, "mech-orders"),
                        elec_orders=_orders(elec_orders, "elec-orders"), pole_pairs=pole_pairs,
                        n_constants=0 if no_constant else 1)
    an = analyse_design(angle_deg=nominal_face_angles_deg(faces=faces), spec=spec)
    click.echo(f"{faces} faces, {pole_pairs} pole pairs: {len(an.names)} coefficients, "
               f"rank {an.rank}, condition number {fmt(an.condition_number)}")
    for m in spec.mech_orders:
        o, sg = alias_order(faces=faces, cycles_per_rev=m)
        click.echo(f"  mechanical {m}: appears as mechanical order {o}" + (" (sine sign flipped)" if sg < 0 else ""))
    for n in spec.elec_orders:
        o, sg = alias_order(faces=faces, cycles_per_rev=n * pole_pairs)
        click.echo(f"  electrical {n} ({n * pole_pairs}/turn): appears as mechanical order {o}"
                   + (" (a constant)" if o == 0 else "") + (" (sine sign flipped)" if sg < 0 else ""))
    if an.dependent_groups:
        click.echo("  inseparable: " + "; ".join("{" + ", ".join(g) + "}" for g in an.dependent_groups))
    if json_out:
        write_json_atomic(json_out, {"faces": faces, "pole_pairs": pole_pairs, **an.as_dict()})


@click.command("fit")
@click.argument("csv_files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--period", type=click.Choice(["long", "short", "both", "sequence"]), required=True,
              help="long: eq 7; short: eq 8 (sorted by fractional degree); both: joint fit of "
                   "mechanical and electrical harmonics (one constant per table); sequence: the "
                   "published procedure, eq 7 on the first table then eq 8 on the second.")
@click.option("--pole-pairs", type=int, default=360, show_default=True)
@click.option("--mech-orders", default="1,2", show_default=True, help="For --period both.")
@click.option("--elec-orders", default="1,2", show_default=True, help="For --period both.")
@click.option("--requirement-arcsec", type=float, default=None,
              help="Pointing requirement: report acceptance (3 sigma after <= requirement/3).")
@click.option("--json", "json_out", type=click.Path(dir_okay=False), default=None)
@click.option("--plot", "plot_out", type=click.Path(dir_okay=False), default=None)
def fit_command(csv_files, period, pole_pairs, mech_orders, elec_orders, requirement_arcsec,
                json_out, plot_out) -> None:
    """Fit harmonics to calibration table(s) CSV (columns angle_deg, error_arcsec)."""
    if pole_pairs < 1:
        raise UserInputError("--pole-pairs: must be >= 1")
    # before the work: the outputs, the same table given twice, a figure format for --plot
    check_distinct_inputs(csv_files, what="calibration table")  # counted twice, the sigmas would shrink
    check_run_outputs(json_out=json_out, files={"--plot": plot_out}, inputs=csv_files)
    if plot_out:
        _check_figure_format(plot_out)
    tables = [read_calibration_csv(path=f) for f in csv_files]
    _check_distinct_tables(tables, csv_files)
    nfiles = len(csv_files)
    if period in ("long", "short") and nfiles != 1:
        raise UserInputError(f"--period {period} takes one CSV file, got {nfiles}")
    if period == "sequence" and nfiles != 2:
        raise UserInputError("--period sequence takes two CSV files: the long-period (24-face) "
                             "table, then the short-period (23-face) table")
    fits = []
    if period == "long":
        fits.append(("eq 7", fit_long_period(angle_deg=tables[0][0], error_arcsec=tables[0][1],
                                             source=csv_files[0])))
    elif period == "short":
        fits.append(("eq 8", fit_short_period(angle_deg=tables[0][0], error_arcsec=tables[0][1],
                                              pole_pairs=pole_pairs, source=csv_files[0])))
    elif period == "both":
        fits.append(("joint", fit_joint(tables=tables, pole_pairs=pole_pairs,
                                        mech_orders=_orders(mech_orders, "mech-orders"),
                                        elec_orders=_orders(elec_orders, "elec-orders"),
                                        sources=list(csv_files))))
    else:
        seq = calibrate_in_sequence(long_angle_deg=tables[0][0], long_error_arcsec=tables[0][1],
                                    short_angle_deg=tables[1][0], short_error_arcsec=tables[1][1],
                                    pole_pairs=pole_pairs)
        fits += [("eq 7", seq["long"]), ("eq 8", seq["short"])]

    coefficients = {}
    for label, f in fits:
        click.echo(f"{label} fit: {f.angle_deg.size} points, {len(f.names)} coefficients, "
                   f"residual sigma {fmt(f.sigma_arcsec)} arcsec ({f.dof} dof)")
        for nm, v, s in zip(f.names, f.coefficients_arcsec, f.standard_errors_arcsec):
            click.echo(f"  {nm:>7s} = {v:10.4f} +- {s:.4f} arcsec")
            coefficients[nm] = {"value_arcsec": float(v), "std_arcsec": float(s)}
    final = fits[-1][1]
    if period == "sequence":
        before = float(sigma3_arcsec(error_arcsec=tables[1][1]))
    else:
        before = final.sigma3_before_arcsec
    after = final.sigma3_after_arcsec
    mx = final.max_abs_after_arcsec
    click.echo(f"3 sigma before: {before:.3f} arcsec   3 sigma after: {after:.3f} arcsec   "
               f"max |residual|: {mx:.3f} arcsec")
    payload = {"period": period, "inputs": list(csv_files), "pole_pairs": pole_pairs,
               "coefficients": coefficients, "sigma3_before_arcsec": before,
               "sigma3_after_arcsec": after, "max_abs_after_arcsec": mx,
               "fits": {label: f.as_dict() for label, f in fits},
               "version": simcam.__version__}
    if requirement_arcsec is not None:
        if not (requirement_arcsec > 0 and math.isfinite(requirement_arcsec)):
            raise UserInputError("--requirement-arcsec: must be a positive number")
        ok = accept(sigma3_after_arcsec=after, requirement_arcsec=requirement_arcsec)
        payload["accepted"] = ok
        payload["requirement_arcsec"] = requirement_arcsec
        click.echo(f"acceptance (3 sigma after <= {requirement_arcsec / 3:.3f} arcsec): "
                   f"{'yes' if ok else 'no'}")
    if json_out:
        write_json_atomic(json_out, payload)
    if plot_out:
        with naming_failed_writes(plot_out, option="--plot"):  # the disk filled: name the figure
            figure = _plot_fit(fits, plot_out, pole_pairs)
        click.echo(f"plot: {figure}")
        click.echo(f"  {figure.caption}")


def _check_figure_format(path) -> None:
    """Refuse, before the fit, a ``--plot`` name whose suffix names no figure format
    matplotlib writes (``out.txt``, or no suffix)."""
    from pathlib import Path

    from matplotlib.backend_bases import FigureCanvasBase  # only with --plot: matplotlib is heavy

    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in formats:
        got = f"the suffix .{suffix} is no figure format" if suffix else "no suffix names the figure format"
        raise UserInputError(f"--plot {path}: {got}; give one of .{', .'.join(sorted(formats))} (e.g. fit.png)")


def _check_distinct_tables(tables, paths) -> None:
    """Refuse two tables with the same angles and errors (a copy of one table): the fit would
    count every point twice and shrink its stated sigmas by sqrt(2)."""
    for j in range(1, len(tables)):
        for i in range(j):
            (a1, e1), (a2, e2) = tables[i], tables[j]
            if a1.shape == a2.shape and np.array_equal(a1, a2) and np.array_equal(e1, e2):
                raise UserInputError(f"{paths[j]}: the same table as {paths[i]} (every angle and error equal); "
                                     "give each calibration table once")


def _plot_fit(fits, path, pole_pairs):
    """The measured errors, the fitted model and the residuals of each fit (one row each);
    returns the path with its caption (:func:`budget.figures.save`), from the numbers drawn:
    per fit the points, the 3 sigma before and after and the largest residual with where it
    lies, and a nuisance offset drawn with the model (fitted, not compensated)."""
    plt = _plt()
    fig, axes = plt.subplots(len(fits), 2, figsize=(10, 3.6 * len(fits)), squeeze=False)
    parts = []
    for row, (label, f) in enumerate(fits):
        a = f.angle_deg
        short = not f.spec.mech_orders
        # a nuisance offset (eq 8's table zero) is fitted, so it is in the model at the points;
        # the curve carries it too, so that it passes through them
        offset = float(f.coefficients_arcsec[0]) if f.spec.nuisance_offset else 0.0
        if short:
            cyc = pole_pairs * a / 360.0
            x = (cyc - np.floor(cyc)) * 360.0
            grid = np.linspace(0, 360, 721)
            model = f.evaluate_arcsec(angle_deg=grid / pole_pairs) + offset
            xl, xname = "electrical phase (deg)", "electrical phase"
        else:
            x = a
            grid = np.linspace(0, 360, 721)
            model = f.evaluate_arcsec(angle_deg=grid) if not f.spec.elec_orders else None
            xl, xname = "angle (deg)", "angle"
        ax = axes[row, 0]
        ax.plot(x, f.error_arcsec, "o", ms=4, label="measured")
        ax.plot(x, f.error_arcsec - f.residual_arcsec, "x", ms=5, label="model at the points")
        if model is not None:
            ax.plot(grid, model, lw=0.8, label="model" + (f" (with offset {offset:.2f})" if offset else ""))
        ax.set_xlabel(xl)
        ax.set_ylabel("error (arcsec)")
        ax.set_title(f"{label}: 3 sigma before {f.sigma3_before_arcsec:.2f} arcsec")
        ax.legend(fontsize=7)
        ax = axes[row, 1]
        ax.plot(x, f.residual_arcsec, "o", ms=4)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel(xl)
        ax.set_ylabel("residual (arcsec)")
        ax.set_title(f"after: 3 sigma {f.sigma3_after_arcsec:.2f}, max {f.max_abs_after_arcsec:.2f} arcsec")
        i = int(np.argmax(np.abs(f.residual_arcsec)))
        s = (f"{label} ({len(f.names)} coefficients) on {a.size} points against the {xname}: 3 sigma "
             f"{f.sigma3_before_arcsec:.2f} arcsec before the fit, {f.sigma3_after_arcsec:.2f} after "
             f"({100 * f.sigma3_after_arcsec / f.sigma3_before_arcsec:.1f} % of it), the largest residual "
             f"{f.residual_arcsec[i]:+.2f} arcsec at {x[i]:.1f} deg")
        if offset:
            s += (f"; the model is drawn with the fitted offset {offset:+.2f} arcsec (the table's zero, "
                  "fitted but not compensated)")
        elif model is None:
            s += "; no model curve (mechanical and electrical harmonics together have no single phase axis)"
        parts.append(s)
    return save(fig, path, "; ".join(parts[:1]) + "".join(f". {p}" for p in parts[1:]) + ".")


def _summary_lines(result) -> list[str]:
    return summary_lines(result)


def _validate_command() -> click.Command:
    return validate_command_for(
        "inductosyn", more_lines=_summary_lines,
        help_text="Monte Carlo validation of the polygon calibration on SCENARIO (default: the embedded "
                  "seed-001 scenario); the seed-001 figures are printed after the table. The truth grid's "
                  "step is the scenario's validation.dense_step_deg.")


validate_command = _validate_command()


def commands() -> list[click.Command]:
    """The inductosyn study's own commands (its ``validate`` replaces the runner's)."""
    return [scenario_command, design_command, fit_command, validate_command]
