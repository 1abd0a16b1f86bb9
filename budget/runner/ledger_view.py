"""The ledger a run's report and terminal output open with: the study's claims judged in the
world this run simulated (:func:`budget.runner.claims.evaluate_run`), the other world shown
as not run here, and what the run speaks for (every trial its own instrument, or the one
pinned by ``validation.instrument_seed``).
"""

from __future__ import annotations

from dataclasses import dataclass

from budget.runner.claims import (
    NOT_RUN_HERE,
    WORLD_LABELS,
    Claim,
    ClaimResult,
    evaluate_run,
    ledger_markdown,
    paper_figure,
    study_claims,
)

__all__ = ["RunLedger", "instrument_line", "ledger_lines", "ledger_section", "pinned_instrument", "run_ledger"]


@dataclass(frozen=True)
class RunLedger:
    """A run's ledger: ``results`` (the claims on its scenario, in the world(s) it ran) and
    ``elsewhere`` (testable claims judged on another scenario, not by this run)."""

    results: tuple[ClaimResult, ...]
    elsewhere: tuple[Claim, ...]
    untestable: tuple[Claim, ...]


def run_ledger(result, claims=None) -> RunLedger:
    """The ledger of ``result`` (its study's declared claims unless ``claims`` is given)."""
    study = result.study
    claims = tuple(study_claims(study, result.scenario) if claims is None else claims)
    judged = evaluate_run(study, claims, result)
    ids = {r.claim.id for r in judged}
    return RunLedger(judged, tuple(c for c in claims if c.testable and c.id not in ids),
                     tuple(c for c in claims if not c.testable))


def pinned_instrument(scenario) -> str | None:
    """What fixed one instrument for every trial of ``scenario``, in words, or None
    (:meth:`simcam.config_base.ScenarioBase.pinned_instrument`; a scenario without it, such as
    a plug-in study's own model, reads ``validation.instrument_seed`` alone)."""
    if hasattr(scenario, "pinned_instrument"):
        return scenario.pinned_instrument()
    seed = getattr(getattr(scenario, "validation", None), "instrument_seed", None)
    return None if seed is None else f"instrument seed {seed}"


def instrument_line(scenario) -> str | None:
    """When one instrument served every trial (``validation.instrument_seed`` set, or a
    scenario that pins its instrument otherwise:
    :meth:`simcam.config_base.ScenarioBase.pinned_instrument`): the results hold for that
    instrument only."""
    val = getattr(scenario, "validation", None)
    pinned = pinned_instrument(scenario)
    if pinned is None:
        return None
    if getattr(val, "instrument_seed", None) is not None:
        return (f"One instrument ({pinned}) served every trial: these results hold for that instrument "
                f"only, not for instruments like it (leave the instrument seed unset to draw one per trial).")
    return (f"Part of the instrument is one draw for every trial ({pinned}): what depends on it holds "
            f"for that draw only, not for instruments like it.")


def ledger_section(result, claims=None) -> list[str]:
    """Markdown lines of the report's first section, "What holds of the paper's claims" (with
    a pinned instrument, :func:`instrument_line` in bold, also without claims)."""
    led = run_ledger(result, claims)
    note = instrument_line(result.scenario)
    if not (led.results or led.elsewhere or led.untestable):
        return [f"**{note}**", ""] if note is not None else []
    lines = ["## What holds of the paper's claims", ""]
    if note is not None:
        lines += [f"**{note}**", ""]
    if led.results:
        worlds = sorted({r.world for r in led.results})
        lines += [f"Judged in the {' and the '.join(WORLD_LABELS[w] for w in worlds)}, the world this run "
                  f"simulated; a world not simulated here reads \"{NOT_RUN_HERE}\".", "",
                  ledger_markdown(led.results), ""]
    else:
        lines += ["This run's scenario is neither world of the scenarios the study's claims name: "
                  "`budget claims` judges them.", ""]
    if led.elsewhere:
        names = sorted({c.scenario for c in led.elsewhere})
        lines += [f"{len(led.elsewhere)} more claims are judged on {', '.join(f'`{n}`' for n in names)}: "
                  "`budget claims` runs them.", ""]
    if led.untestable:
        lines += ["Untestable here: " + "; ".join(f"{c.words} ({c.untestable})" for c in led.untestable) + ".", ""]
    return lines


def _short(r: ClaimResult) -> str:
    if r.verdict is None:
        return f"no verdict ({r.no_verdict})"
    return f"{r.verdict.outcome} (tolerance {r.verdict.tolerance.describe()}, {r.verdict.tolerance.reason})"


def ledger_lines(result, claims=None) -> list[str]:
    """Terminal lines of the same ledger: one per claim and world judged here."""
    led = run_ledger(result, claims)
    note = instrument_line(result.scenario)
    if not (led.results or led.elsewhere):
        return [note] if note is not None else []
    out = ["claims of the paper (this run's world; `budget claims` runs both):"]
    if note is not None:
        out.append(f"  {note}")
    for r in led.results:
        paper = "" if r.claim.kind == "method" else f"paper {paper_figure(r.claim)}; "
        out.append(f"  {r.claim.id} [{WORLD_LABELS[r.world]}]: {paper}ours {r.ours}: {_short(r)}")
    if led.elsewhere:
        out.append(f"  {len(led.elsewhere)} more claims on "
                   f"{', '.join(sorted({c.scenario for c in led.elsewhere}))}: `budget claims` runs them")
    return out
