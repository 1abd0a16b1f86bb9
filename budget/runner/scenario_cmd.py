"""``budget <study> scenario [SCENARIO] [--resolved]``: a study's scenario as TOML.

Without ``--resolved`` it prints the text with its comments (the embedded default, or the
file given, after checking that it is valid), a header line first; with ``--resolved`` every
field, defaults filled in, as the JSON result carries it (no comments).
"""

from __future__ import annotations

import click

from budget.runner.registry import get_study

__all__ = ["scenario_command_for"]


def scenario_command_for(study_name: str) -> click.Command:
    """The ``scenario`` command of the study registered as ``study_name``."""

    @click.command("scenario", help=f"Print the {study_name} scenario SCENARIO (default: the embedded one) "
                                    "as TOML with its comments; --resolved: every field, defaults filled in.")
    @click.argument("scenario", required=False, type=click.Path(dir_okay=False))
    @click.option("--resolved", is_flag=True, help="Every field, defaults filled in (no comments).")
    def scenario(scenario, resolved):
        from pathlib import Path

        study = get_study(study_name)
        scn = study.load_scenario(scenario)  # a mistake is one error line naming file and field
        click.echo(f"# {study_name} scenario {getattr(scn, 'name', '') or ''} (hash {study.scenario_hash(scn)})"
                   .replace("scenario  (", "scenario ("))
        if resolved:
            click.echo(study.scenario_text(scn), nl=False)
        else:
            if scenario is None:
                text = study.default_text()
            elif Path(scenario).is_file():
                text = Path(scenario).read_text(encoding="utf-8")
            else:  # a named embedded scenario ("embedded:NAME"): resolved
                text = study.scenario_text(scn)
            click.echo(text if text.endswith("\n") else text + "\n", nl=False)

    return scenario
