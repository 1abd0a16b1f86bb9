"""The front page of ``budget claims``: "What holds of the five papers", one self-contained
HTML file.

One table per source document (a study's ``seed_document``; the attitude study joins seed
000's), headed by the document's bibliographic citation (:data:`budget.sources.CITATIONS`,
as docs/references.md gives them), one row per claim: the paper's words and section, its
figure, ours in the seed's own world and in the realistic world (each linking to the full
report of the run that judged it), and the verdict in words
(:func:`budget.runner.claims.verdict_words`). Nothing is fetched from a network.
"""

from __future__ import annotations

import html
from pathlib import Path

from budget.runner.claims import WORLD_LABELS, WORLDS, paper_figure, verdict_words
from budget.runner.findings import unit_prose
from budget.sources import citation

__all__ = ["page_html", "write_page"]

_STYLE = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;max-width:1150px;margin:1.5em auto;
padding:0 1.2em;line-height:1.4;color:#1b1b1b}
h1{font-size:1.7em;margin-bottom:.2em}
h2{font-size:1.25em;border-bottom:1px solid #ddd;margin-top:1.8em;margin-bottom:.2em}
p.cite{margin:.2em 0 .6em;color:#444;font-size:.92em}
p.lead{color:#333}
table{border-collapse:collapse;width:100%;table-layout:fixed;font-size:.88em;margin:.4em 0 1em}
td{overflow-wrap:anywhere}
td,th{border:1px solid #d4d4d4;padding:.35em .5em;text-align:left;vertical-align:top}
th{background:#f2f2f2}
small{color:#555}
.holds{background:#e3f4e3}.fails{background:#fbe3e1}.undetermined{background:#fff4d6}.none{background:#f1f1f1}
span.badge{display:inline-block;padding:0 .4em;border-radius:3px;font-weight:600;margin-right:.2em}
span.sec{color:#666;font-size:.9em}
ul.summary{margin:.3em 0}
a{color:#0b5cad}
"""


def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _badge(r) -> str:
    if r is None:
        return '<span class="badge none">not run</span>'
    if r.verdict is None:
        return '<span class="badge none">no verdict</span>'
    o = r.verdict.outcome
    return f'<span class="badge {o}">{o}</span>'


def _ours(led, r) -> str:
    if r is None:
        return "-"
    link = led.report_of(r)
    unit = unit_prose(r.claim.unit)
    text = (_e(f"{r.ours} {unit}") if r.verdict is not None or r.truth is not None else _e(r.no_verdict or "-"))
    cls = r.verdict.outcome if r.verdict is not None else "none"
    more = f' <a href="{_e(link)}">report</a>' if link else ""
    return f'<td class="{cls}">{_badge(r)}<br>{text}{more}</td>'


def _paper_short(c) -> str:
    """The paper's column: its figure, or for a method claim what it claims of its estimate."""
    if c.kind != "method":
        return paper_figure(c)
    figs = " / ".join(f"{f:g}" for f in c.figures)
    return "estimate = truth" + (f" (it measured {figs} {unit_prose(c.unit)})" if figs else "")


def _rows(ledgers) -> list[str]:
    rows = []
    for led in ledgers:
        by_id: dict = {}
        for r in led.results:
            by_id.setdefault(r.claim.id, {})[r.world] = r
        for worlds in by_id.values():
            c = next(iter(worlds.values())).claim
            seed, real = worlds.get("seed"), worlds.get("realistic")
            cells = [f'<td class="claim">{_e(c.words)} <span class="sec">({_e(c.kind)}; {_e(c.section)}'
                     f'{"; " + _e(c.condition) if c.condition else ""})</span></td>',
                     f"<td>{_e(_paper_short(c))}</td>"]
            if c.testable:
                words, _, why = verdict_words(seed, real).partition(" (tolerance")
                why = f"<br><small>tolerance{_e(why[:-1])}</small>" if why else ""
                cells += [_ours(led, seed), _ours(led, real), f"<td><b>{_e(words)}</b>{why}</td>"]
            else:
                cells += ['<td class="none" colspan="2">-</td>', f"<td>untestable: {_e(c.untestable)}</td>"]
            rows.append("<tr>" + "".join(cells) + "</tr>")
    return rows


def _trials(led) -> str:
    n = sorted({run.trials for run in led.runs.values()})
    return f" ({', '.join(map(str, n))} trials per run)" if n else ""


def _paper_section(doc: str, ledgers) -> list[str]:
    short, full = citation(doc)
    studies = ", ".join(f"<code>{_e(led.study)}</code>" + _trials(led) for led in ledgers)
    out = [f"<h2>{_e(short)}</h2>", f'<p class="cite">{_e(full)}. Studies: {studies}.</p>']
    pinned = sorted({f"{led.study}: {run.pinned_instrument}" for led in ledgers for run in led.runs.values()
                     if run.pinned_instrument})
    if pinned:
        out.append("<p>One instrument served every trial (" + _e("; ".join(pinned)) + "): these verdicts hold for "
                   "that instrument, not for instruments like it.</p>")
    rows = _rows(ledgers)
    if not rows:
        return out + ["<p>This paper's studies declare no claims yet.</p>"]
    cols = ('<colgroup><col style="width:31%"><col style="width:13%"><col style="width:17%">'
            '<col style="width:17%"><col style="width:22%"></colgroup>')
    head = (cols + "<tr><th>the paper's claim</th><th>paper's figure</th><th>ours, seed's own world</th>"
            "<th>ours, realistic world</th><th>verdict</th></tr>")
    return out + ["<table>", head, *rows, "</table>"]


def _summary(result) -> str:
    c = result.counts()
    items = []
    for w in WORLDS:
        parts = [f"{c[w].get(k, 0)} {k}" for k in ("holds", "fails", "undetermined") if c[w].get(k)]
        if c[w].get("no verdict"):
            parts.append(f"{c[w]['no verdict']} without a verdict (untestable or estimating nothing)")
        items.append(f"<li>In the {_e(WORLD_LABELS[w])}: {_e(', '.join(parts) or 'no claims')}.</li>")
    return '<ul class="summary">' + "".join(items) + "</ul>"


def page_html(result) -> str:
    """The page's HTML (module docstring)."""
    by_doc: dict = {}
    for led in result.ledgers:
        by_doc.setdefault(led.seed_document, []).append(led)
    trials = (f"{result.trials} trials per run" if result.trials is not None
              else "each study's default trials per run (named beside it)")
    req = ""
    if result.requirements:
        req = (" Your requirements replace the declared tolerances on "
               + ", ".join(f"{_e(k)} (at most {v:g})" for k, v in result.requirements.items()) + ".")
    lead = (f'<p class="lead">Each source document\'s claims, judged by simulation in two worlds: the '
            f"<b>seed's own world</b> (every unmodelled effect off: the world the paper's model assumes) and "
            f"the <b>realistic world</b> (the embedded defaults). A claim <b>holds</b> when the 95 % confidence "
            f"interval of our figure lies wholly inside its tolerance, <b>fails</b> when wholly outside, and is "
            f"<b>undetermined</b> otherwise (the verdict says how many trials would settle it); each tolerance "
            f"states its reason.{req} Seed {result.seed}, {_e(trials)}, {result.elapsed_s:.0f} s in all. "
            f"Each figure of ours links to the full report of its run; the ledger is also in "
            f'<a href="claims.json">claims.json</a>.</p>')
    body = ["<h1>What holds of the five papers</h1>", lead, _summary(result)]
    for doc in sorted(by_doc):
        body += _paper_section(doc, by_doc[doc])
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>What holds of the five papers</title><style>{_STYLE}</style></head>\n<body>\n"
            + "\n".join(body) + "\n</body></html>\n")


def write_page(result, path) -> Path:
    """Write :func:`page_html` to ``path``."""
    path = Path(path)
    path.write_text(page_html(result), encoding="utf-8")
    return path
