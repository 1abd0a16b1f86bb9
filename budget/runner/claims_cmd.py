"""``budget claims``: every registered study's claims ledger in both worlds, on one page
(:func:`budget.runner.claims_run.run_claims`, the same work as :func:`budget.claims`)."""

from __future__ import annotations

import click

from budget.runner.claims_run import run_claims
from budget.runner.executors import default_workers
from budget.runner.registry import study_names
from simcam.infra.cli import overwrite_option
from simcam.infra.errors import UserInputError

__all__ = ["claims_command"]

_HELP = """Judge every paper's claims by simulation and write one page, OUT/index.html, "What holds
of the five papers": a table per paper, a sentence per claim (the paper's figure beside ours in
the seed's own world and in the realistic world, the verdict in words), each row linking to the
full report of the run behind it (OUT/<study>/...), and the ledger as OUT/claims.json.

--tolerance CLASS=VALUE (repeatable): your requirement on a class (in its unit) replaces the
declared tolerance of every claim on it (a method's bias within -+VALUE, a figure within
-+VALUE of the paper's). See docs/claims.md."""


@click.command("claims", help=_HELP)
@click.option("--out", "out", type=click.Path(file_okay=False), default="claims", show_default=True,
              help="The folder to write (an earlier output of this command is replaced; anything else needs "
                   "--overwrite).")
@overwrite_option
@click.option("--trials", type=click.IntRange(min=2), default=None,
              help="Trials per run (default: each study's own, sized so that every study together takes "
                   "under 10 minutes on 2 cores).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Local worker processes (default: all cores). Results do not depend on it.")
@click.option("--study", "studies", multiple=True, metavar="NAME",
              help="Only this study (repeatable; default: every registered study).")
@click.option("--tolerance", "tolerances", multiple=True, metavar="CLASS=VALUE",
              help="Your requirement on CLASS, in its unit: it replaces the declared tolerance of the claims on "
                   "CLASS (repeatable).")
@click.option("--progress/--no-progress", default=False, help="A progress bar per run.")
def claims_command(out, overwrite, trials, seed, workers, studies, tolerances, progress):
    known = study_names()
    for s in studies:
        if s not in known:
            raise UserInputError(f"--study {s}: unknown study; known: {', '.join(known)}")
    res = run_claims(out, studies=studies, trials=trials, seed=seed,
                     workers=default_workers() if workers is None else workers, tolerances=tolerances,
                     overwrite=overwrite, progress=progress, echo=click.echo)
    c = res.counts()
    for w, label in (("seed", "seed's own world"), ("realistic", "realistic world")):
        click.echo(f"{label}: " + ", ".join(f"{n} {k}" for k, n in sorted(c[w].items())))
    click.echo(f"page: {res.page} ({res.elapsed_s:.0f} s)")
