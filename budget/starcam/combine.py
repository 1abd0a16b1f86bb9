"""``budget starcam combine``: combine per-class errors into LSFE, single-star and attitude totals.

Seed 000: ``LSFE = sqrt(S^2 + (C1 + C2)^2)`` (eq 31), single star = RSS(TE, HSFE, LSFE)
(section 2.4), attitude = single star / sqrt(N) (eq 32), per axis, in arcsec (3 sigma).

Input TOML::

    stars = 10
    [te]      x = 1.14   y = 1.23
    [hsfe]    x = 1.08   y = 1.01
    [lsfe_s]  x = 0.03   y = 0.66
    [lsfe_c1] x = 0.29   y = 0.41
    [lsfe_c2] x = 0.5    y = 0.5
    # optional given totals, checked against their components:
    [lsfe]        x = 0.91  y = 1.12
    [single_star] x = 1.76  y = 1.95
    [attitude]    x = 0.56  y = 0.62
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import click

from budget.starcam.estimators import attitude_error, low_spatial_frequency_error, single_star_error
from simcam.config_base import read_toml
from simcam.infra.cli import write_json_atomic
from simcam.infra.errors import ScenarioError
from simcam.infra.outputs import check_run_outputs

__all__ = ["BudgetCombination", "combine_budget", "format_budget", "load_budget_toml", "combine_command"]

COMPONENTS = ("te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2")
TOTALS = ("lsfe", "single_star", "attitude")
_LABELS = {
    "te": "TE (temporal)",
    "hsfe": "HSFE (high spatial freq.)",
    "lsfe_s": "LSFE-S (chromatic)",
    "lsfe_c1": "LSFE-C1 (distortion resid.)",
    "lsfe_c2": "LSFE-C2 (target marker)",
    "lsfe": "LSFE  = sqrt(S^2+(C1+C2)^2)",
    "single_star": "single star = RSS(TE,HSFE,LSFE)",
    "attitude": "attitude = single / sqrt(N)",
}


@dataclass(frozen=True, kw_only=True)
class BudgetCombination:
    """Components and computed totals, per axis, arcsec (3 sigma).

    Attributes
    ----------
    components : dict
        ``{name: {"x": ..., "y": ...}}`` for te, hsfe, lsfe_s, lsfe_c1, lsfe_c2.
    n_stars : int
    lsfe, single_star, attitude : dict
        ``{"x": ..., "y": ...}`` computed from the components.
    given : dict
        Totals given in the input (may be empty).
    warnings : tuple of str
        One per given total that does not follow from its components.
    tolerance_arcsec : float
    """

    components: dict[str, dict[str, float]]
    n_stars: int
    lsfe: dict[str, float]
    single_star: dict[str, float]
    attitude: dict[str, float]
    given: dict[str, dict[str, float]]
    warnings: tuple[str, ...]
    tolerance_arcsec: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return {
            "components": self.components,
            "stars": self.n_stars,
            "lsfe": self.lsfe,
            "single_star": self.single_star,
            "attitude": self.attitude,
            "given": self.given,
            "tolerance_arcsec": self.tolerance_arcsec,
            "warnings": list(self.warnings),
        }


def _number(source: str, key: str, value: Any, *, integer: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScenarioError(f"{source}: {key}: expected a number, got {value!r}")
    if not math.isfinite(value) or value < 0:
        raise ScenarioError(f"{source}: {key}: must be finite and >= 0, got {value!r}")
    if integer and (not float(value).is_integer() or value < 1):
        raise ScenarioError(f"{source}: {key}: expected an integer >= 1, got {value!r}")
    return float(value)


def _pair(source: str, data: dict[str, Any], name: str) -> dict[str, float]:
    if name not in data:
        raise ScenarioError(f"{source}: {name}: missing table (with keys x and y, arcsec 3 sigma)")
    table = data[name]
    if not isinstance(table, dict):
        raise ScenarioError(f"{source}: {name}: expected a table with keys x and y, got {table!r}")
    unknown = sorted(set(table) - {"x", "y"})
    if unknown:
        raise ScenarioError(f"{source}: {name}.{unknown[0]}: unknown key")
    out = {}
    for ax in ("x", "y"):
        if ax not in table:
            raise ScenarioError(f"{source}: {name}.{ax}: missing")
        out[ax] = _number(source, f"{name}.{ax}", table[ax])
    return out


def load_budget_toml(path: str | Path) -> tuple[dict[str, dict[str, float]], int, dict[str, dict[str, float]]]:
    """Read and validate a budget TOML file.

    Returns
    -------
    components, n_stars, given_totals
    """
    path = Path(path)
    source = str(path)
    data = read_toml(path=path, source=source)  # strict: missing, non-UTF-8, empty, invalid
    allowed = set(COMPONENTS) | set(TOTALS) | {"stars"}
    unknown = sorted(set(data) - allowed)
    if unknown:
        raise ScenarioError(f"{source}: {unknown[0]}: unknown key (expected {', '.join(sorted(allowed))})")
    components = {name: _pair(source, data, name) for name in COMPONENTS}
    if "stars" not in data:
        raise ScenarioError(f"{source}: stars: missing (number of stars in the attitude solution)")
    n_stars = int(_number(source, "stars", data["stars"], integer=True))
    given = {name: _pair(source, data, name) for name in TOTALS if name in data}
    return components, n_stars, given


def combine_budget(
    *,
    components: dict[str, dict[str, float]],
    n_stars: int,
    given: dict[str, dict[str, float]] | None = None,
    tolerance_arcsec: float = 0.01,
) -> BudgetCombination:
    """Combine components (arcsec, 3 sigma) and check given totals.

    Parameters
    ----------
    components : dict
        ``{"te"|"hsfe"|"lsfe_s"|"lsfe_c1"|"lsfe_c2": {"x": ..., "y": ...}}``.
    n_stars : int
        Stars in the attitude solution (eq 32).
    given : dict, optional
        Totals to check (``lsfe``, ``single_star``, ``attitude``).
    tolerance_arcsec : float
        A given total farther than this from the computed one gets a warning (the
        rounding of the inputs; the seed prints 0.01").

    Returns
    -------
    BudgetCombination
    """
    given = dict(given or {})
    c = components
    lsfe, single, att = {}, {}, {}
    for ax in ("x", "y"):
        lsfe[ax] = low_spatial_frequency_error(chromatic=c["lsfe_s"][ax],
                                               distortion=c["lsfe_c1"][ax], marker=c["lsfe_c2"][ax])
        single[ax] = single_star_error(temporal=c["te"][ax], high_frequency=c["hsfe"][ax],
                                       low_frequency=lsfe[ax])
        att[ax] = attitude_error(single_star=single[ax], n_stars=n_stars)
    computed = {"lsfe": lsfe, "single_star": single, "attitude": att}
    msgs = []
    for name in TOTALS:
        if name not in given:
            continue
        for ax in ("x", "y"):
            g, v = given[name][ax], computed[name][ax]
            if abs(g - v) <= tolerance_arcsec + 1e-12:
                continue
            text = (f"{name}.{ax}: given {g:g}\" does not follow from its components: "
                    f"{_LABELS[name].split('=')[0].strip()} = {v:.4f}\"")
            # say whether it follows from the given intermediate total instead
            if name == "single_star" and "lsfe" in given:
                alt = single_star_error(temporal=c["te"][ax], high_frequency=c["hsfe"][ax],
                                        low_frequency=given["lsfe"][ax])
                text += f" ({alt:.4f}\" with the given lsfe.{ax})"
            if name == "attitude" and "single_star" in given:
                alt = attitude_error(single_star=given["single_star"][ax], n_stars=n_stars)
                text += f" ({alt:.4f}\" with the given single_star.{ax})"
            msgs.append(text)
    return BudgetCombination(components=c, n_stars=n_stars, lsfe=lsfe, single_star=single,
                             attitude=att, given=given, warnings=tuple(msgs),
                             tolerance_arcsec=float(tolerance_arcsec))


def format_budget(result: BudgetCombination) -> str:
    """Readable table (seed 000 section 2 layout): components, LSFE, single, attitude."""
    width = 34
    lines = [f"{'error class (arcsec, 3 sigma)':<{width}} {'x':>8} {'y':>8}   given x/y",
             "-" * (width + 30)]
    for name in COMPONENTS:
        v = result.components[name]
        lines.append(f"{_LABELS[name]:<{width}} {v['x']:>8.3f} {v['y']:>8.3f}")
    lines.append("-" * (width + 30))
    computed = {"lsfe": result.lsfe, "single_star": result.single_star, "attitude": result.attitude}
    for name in TOTALS:
        v = computed[name]
        label = _LABELS[name] if name != "attitude" else f"attitude, N = {result.n_stars} stars"
        g = result.given.get(name)
        gtext = f"   {g['x']:g} / {g['y']:g}" if g else ""
        lines.append(f"{label:<{width}} {v['x']:>8.3f} {v['y']:>8.3f}{gtext}")
    if result.warnings:
        lines.append("")
        lines.extend(f"warning: {w}" for w in result.warnings)
    return "\n".join(lines)


@click.command("combine")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Write the result as JSON to this file.")
@click.option("--tolerance", "tolerance_arcsec", type=float, default=0.01, show_default=True,
              help="Tolerance (arcsec) when checking given totals against their components.")
def combine_command(file: Path, json_out: Path | None, tolerance_arcsec: float) -> None:
    """Combine TE, HSFE, LSFE-S, LSFE-C1, LSFE-C2 (arcsec, 3 sigma) of FILE (TOML).

    LSFE = sqrt(S^2 + (C1 + C2)^2) (seed 000 eq 31), single star = RSS(TE, HSFE, LSFE),
    attitude = single / sqrt(stars) (eq 32). Given totals (tables lsfe, single_star,
    attitude) are checked against their components.
    """
    if not (math.isfinite(tolerance_arcsec) and tolerance_arcsec >= 0):
        raise click.BadParameter("must be finite and >= 0", param_hint="--tolerance")
    if not file.is_file():
        raise FileNotFoundError(2, "No such file", str(file))
    check_run_outputs(json_out=json_out, inputs=(file,))  # before the work: never over FILE (or a link to it)
    components, n_stars, given = load_budget_toml(file)
    result = combine_budget(components=components, n_stars=n_stars, given=given,
                            tolerance_arcsec=tolerance_arcsec)
    click.echo(format_budget(result))
    if json_out is not None:
        write_json_atomic(json_out, result.to_dict())
