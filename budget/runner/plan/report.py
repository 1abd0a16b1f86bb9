"""What a plan says: its answer and findings in words, derived from its numbers by the rules
in docs/planning.md ("Output"); ``report.md``, its HTML twin (:mod:`budget.runner.html`), the
trade-curve figure (:mod:`budget.figures`, its caption computed from the points it draws) and
``recommended.toml``. Its functions take a :class:`budget.runner.plan.result.PlanResult`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from budget.figures import figure_markdown, plt, save
from budget.runner.findings import with_unit
from budget.runner.html import write_html
from budget.runner.numbers import fmt
from budget.runner.plan.protocols import dotted_value
from budget.runner.plan.text import knobs_text, lab_time_text, percent_text
from budget.runner.report import staged_report
from simcam.infra.cli import write_json_atomic
from simcam.units import SECONDS_PER_HOUR

__all__ = ["answer_text", "findings_sentences", "plot_trade_curve", "summary_markdown", "write_plan_report"]

#: the trade curve's marker per shape, in the order of the plan's shapes
MARKERS = "osD^v<>"


def _req_list(res) -> str:
    return " and ".join(f"{r.name} <= {with_unit(r.value, r.unit)}" for r in res.requirements)


def answer_text(res) -> str:
    """The plan's answer in one paragraph (docs/planning.md, "Output")."""
    st = res.study
    conf = percent_text(res.confidence)
    budget = "" if res.budget_hours is None else f" within {res.budget_hours:g} h"
    if res.recommended is None and res.over_budget:
        b = res.best_achievable
        failed = [name for name, f in b.figures.items() if not f["met"]]
        verdict = (f"it meets every requirement ({_sure_text(res, b)})" if not failed else
                   f"it does not confirm {', '.join(failed)} ({_sure_text(res, b)})")
        return (f"{st.title}: no protocol{budget} meets {_req_list(res)} ({res.variant}, {conf} of tests): the "
                f"cheapest that does, {knobs_text(b.knobs)}{'' if _is_any(b.shape) else f' ({b.shape})'}, takes "
                f"{lab_time_text(b.cost_s)} of lab time (its {len(res.groups)} independent parts' cheapest protocols "
                f"together; lab time is additive, so none cheaper meets every requirement). Run as one protocol "
                f"on {b.trials} fresh trials, {verdict}.")
    if res.recommended is None:
        b = res.best_achievable
        if b is None:
            return f"{st.title}: no protocol{budget} could be run for {_req_list(res)}."
        worst = max(b.figures.values(), key=lambda f: f["quantile"] / f["bound"])
        name = next(n for n, f in b.figures.items() if f is worst)
        tail = ""
        if res.best_achievable_revalidated:
            fails = [go.group.name for go in res.groups if go.best is None]
            which = f"group{'s' if len(fails) > 1 else ''} {', '.join(fails)}"
            others = " with every other group's answer" if len(fails) < len(res.groups) else ""
            tail = (f": the most accurate protocol of {which} (no protocol of {'them' if len(fails) > 1 else 'it'} "
                    f"meets){others}, run as one protocol on {b.trials} fresh trials")
            if worst["quantile"] <= worst["bound"]:
                tail += f"; within the bound on these trials, but no protocol of {which} met it in the search"
        elif worst["quantile"] <= worst["bound"] and "upper" in worst:
            tail = (f"; within the bound, but not {percent_text(worst['upper_sure'])} sure to be (its upper bound "
                    f"{fmt(worst['upper'])}; --sure)")
        return (_undetermined_text(res, budget) or
                f"{st.title}: no protocol{budget} meets {_req_list(res)} ({res.variant}, {conf} of tests). "
                f"Best achievable: {name} {fmt(worst['quantile'])} +- {fmt(worst['se_quantile'])} "
                f"{next(r.unit for r in res.requirements if r.name == name)} "
                f"(the {conf} quantile of |error|, bound {fmt(worst['bound'])}) with {knobs_text(b.knobs)} "
                f"({'' if _is_any(b.shape) else f'{b.shape}, '}{lab_time_text(b.cost_s)} of lab time){tail}.")
    rec, val = res.recommended, res.validation
    head = (f"{st.title}: the cheapest protocol found{budget} is {knobs_text(rec.knobs)}"
            f"{'' if _is_any(rec.shape) else f' ({rec.shape})'}, {lab_time_text(rec.cost_s)} of lab time.")
    n = val.trials
    prem = res.premium
    aim = "" if prem is None or res.sure_level <= 0.5 else (
        f" Aiming {percent_text(res.sure_level)} sure to meet the bound"
        f"{' on each requirement' if len(res.requirements) > 1 else ''} costs {prem['factor']:.2f}x the boundary "
        f"protocol's lab time ({knobs_text(prem['boundary_knobs'])}, {lab_time_text(prem['boundary_cost_s'])}).")
    if res.confirmed:
        tail = (f" It meets {_req_list(res)} at {conf} (re-validated on {n} fresh trials; "
                f"{_sure_text(res)}).")
    else:
        failed = [name for name, f in val.figures.items() if not f["met"]]
        why = ("the protocol sits at the boundary; take the next larger one or plan for a tighter bound"
               if res.sure_level <= 0.5 else
               f"a protocol {percent_text(res.sure_level)} sure to meet the bound can still fail a re-validation "
               f"of {n} fresh trials, up to about half the time where its quantile lies close to the bound; "
               f"plan with a higher --sure or a tighter bound")
        tail = (f" The re-validation on {n} fresh trials does not confirm {', '.join(failed)} "
                f"({_sure_text(res)}): {why}.")
    return head + tail + aim


def _undetermined_text(res, budget: str) -> str:
    """Where the search ended with a protocol still undetermined (its trial budget spent): the
    answer says "undetermined", the protocol, its figure and the trials that would settle it,
    then the best achievable (docs/planning.md, "Deciding a requirement")."""
    u = res.undetermined
    if u is None:
        return ""
    name, f = max(((n, f) for n, f in u.figures.items() if f.get("verdict") == "undetermined"),
                  key=lambda nf: nf[1]["quantile"] / nf[1]["bound"])
    unit = next(r.unit for r in res.requirements if r.name == name)
    settle = (f"about {u.n_to_settle} trials of it would settle it" if u.n_to_settle is not None else
              "its quantile sits on the bound, so no number of trials settles it")
    b = res.best_achievable
    best = "" if b is None else (f" The best achievable (the cheapest protocol within one standard error of the "
                                 f"most accurate) is {knobs_text(b.knobs)} "
                                 f"({lab_time_text(b.cost_s)}).")
    return (f"{res.study.title}: undetermined: no protocol{budget} was decided to meet {_req_list(res)} "
            f"({res.variant}, {percent_text(res.confidence)} of tests) within the trial budget. The cheapest that "
            f"may, {knobs_text(u.knobs)}{'' if _is_any(u.shape) else f' ({u.shape})'} "
            f"({lab_time_text(u.cost_s)} of lab time), measures {name} {fmt(f['quantile'])} +- "
            f"{fmt(f['se_quantile'])} {unit} on {u.trials} trials, its {percent_text(f['upper_sure'])} upper bound "
            f"{fmt(f['upper'])} beyond the bound {fmt(f['bound'])}; {settle} (--trials).{best}")


def _sure_text(res, ev=None) -> str:
    """How sure a run on fresh seeds (``ev``; default the re-validation) is of every requirement
    at once: the Bonferroni bound ``1 - sum (1 - sure_r)`` (:attr:`PlanResult.sure`), named as
    such where there is more than one requirement (each requirement's own sureness is in its
    sentence)."""
    k = len(res.requirements)
    sure = res.sure if ev is None else max(0.0, 1.0 - sum(1.0 - f["sure"] for f in ev.figures.values()))
    if k == 1:
        return f"sure at {percent_text(sure)}"
    if percent_text(sure) == percent_text(1.0):
        return f"sure of all {k} requirements together at {percent_text(1.0)} (Bonferroni)"
    return f"sure of all {k} requirements together at {percent_text(sure)} at least (Bonferroni)"


def findings_sentences(res) -> list[str]:
    """One sentence per requirement (the re-validated figures) and per shape (its best)."""
    out = []
    conf = percent_text(res.confidence)
    fresh = res.fresh_run
    if fresh is not None:
        for r in res.requirements:
            f = fresh.figures[r.name]
            out.append(f"{r.name} ({r.label}, {res.variant}): {conf} of |error| within {fmt(f['quantile'])} +- "
                       f"{fmt(f['se_quantile'])} {r.unit} (bound {fmt(r.value)}; {f['exceed']} of {f['n']} "
                       f"fresh trials beyond it, {f['allowed']} allowed); bias {fmt(f['bias'])} +- "
                       f"{fmt(f['se_bias'])}, sd {fmt(f['sd'])} +- {fmt(f['se_sd'])}; "
                       f"sure at {percent_text(f['sure'])}.")
    if res.groups:
        out += _group_sentences(res)
    elif len(res.shapes) > 1 or res.recommended is None:
        for name, s in res.shapes.items():
            b = s.best
            if b is not None:
                rel = "" if res.recommended is None else (
                    " (recommended)" if b is res.recommended else
                    f" ({100 * (b.cost_s / res.recommended.cost_s - 1):.0f} % more lab time than "
                    f"{res.recommended.shape})")
                out.append(f"Shape {name}: cheapest meeting every requirement {knobs_text(b.knobs)}, "
                           f"{lab_time_text(b.cost_s)}{rel}; {len(s.evaluations)} protocols run, {s.trials} trials.")
            else:
                a = s.best_achievable
                best = "" if a is None else (f"; its best achievable (the cheapest within one standard error of "
                                             f"the most accurate), {knobs_text(a.knobs)} "
                                             f"({lab_time_text(a.cost_s)}), reaches "
                                             f"{fmt(a.ratio, 3)} times the bound")
                out.append(f"Shape {name}: no protocol meets every requirement{best}.")
    for name, s in res.shapes.items():
        if s.refused:
            r = s.refused
            out.append(f"{len(r)} protocol{'s' if len(r) > 1 else ''} of shape {name} refused by the study "
                       f"(first: {knobs_text(r[0].knobs)}: {r[0].error}).")
    per_val = res.trials_per_validation
    out.append(f"The search ran {len(res.evaluations)} protocols with common random numbers, "
               f"{res.search_trials} trials ({fmt(res.search_trials / per_val, 3)} validations of {per_val}); "
               f"{res.truth_runs} truth{'' if res.truth_runs == 1 else 's'} computed (shared by protocols "
               "with the same truth identity).")
    return out


def _is_any(sname: str) -> bool:
    """The shape label of a plan or group no shape field touches (no shape to name)."""
    return sname in ("scenario", "(any)") or sname.endswith("/(any)")


def _floor(res, go) -> tuple | None:
    """An infeasible group's requirement the fitted model puts out of reach of every count:
    ``(requirement, floor, all_within)`` for the requirement whose smallest floor over the
    group's shapes is furthest above its bound (None where every floor is below its bound);
    ``all_within``: every protocol run has that requirement's quantile within two standard
    errors of the floor (its shape's)."""
    worst = None
    for r in go.group.requirements:
        fl = {k: res.shapes[k].model.floor.get(r.name) for k in go.shapes
              if res.shapes[k].model is not None and res.shapes[k].model.floor.get(r.name) is not None}
        if not fl or min(fl.values()) < r.value:
            continue
        if worst is None or min(fl.values()) / r.value > worst[1] / worst[0].value:
            evs = [e for e in res.evaluations if e.shape in fl and r.name in e.figures]
            within = bool(evs) and all(abs(e.figures[r.name]["quantile"] - fl[e.shape])
                                       <= 2 * e.figures[r.name]["se_quantile"] for e in evs)
            worst = (r, min(fl.values()), within)
    return worst


def _group_sentences(res) -> list[str]:
    """A separable plan's sentences: per group, per shape of a group with several, the knobs
    not searched (docs/planning.md, "Output")."""
    out = []
    for go in res.groups:
        g = go.group
        keys = go.shapes
        shapes = "" if len(g.shapes) < 2 else f"; shapes {', '.join(g.shapes)}"
        what = f"Group {g.name} ({', '.join(r.text for r in g.requirements)}{shapes})"
        b, a = go.best, go.best_achievable
        if b is not None:
            sname = go.best_label
            ans = (f"{knobs_text(b.knobs)}{'' if _is_any(sname) else f' ({sname})'}, {lab_time_text(b.cost_s)} "
                   "of lab time")
        elif a is not None:
            fl = _floor(res, go)
            worst = max(a.figures, key=lambda n: a.figures[n]["quantile"] / a.figures[n]["bound"])
            f = a.figures[worst]
            meas = (f"{knobs_text(a.knobs)} measured {worst} {fmt(f['quantile'])} +- {fmt(f['se_quantile'])} "
                    f"({a.trials} trials)")
            if fl is not None:
                r, v, within = fl
                ans = (f"no count reaches {r.text}: the fitted floor is {fmt(v)} {r.unit}, what no count removes"
                       + (" (every protocol run within two standard errors of it)" if within else
                          f"; the best achievable (the cheapest within one standard error of the most accurate "
                          f"by the fitted model), {meas}"))
            else:
                ans = (f"none meets; the best achievable (the cheapest within one standard error of the most "
                       f"accurate by the fitted model), {meas}, bound {fmt(f['bound'])}")
        else:
            ans = "no protocol could be run"
        out.append(f"{what}: {ans}; {go.protocols} protocols, {go.trials} trials.")
        if len(keys) > 1 and b is not None:
            for k in keys:
                sb = res.shapes[k].best
                if sb is None:
                    out.append(f"Shape {k}: none meets.")
                elif sb is not b:
                    out.append(f"Shape {k}: {knobs_text(sb.knobs)}, {lab_time_text(sb.cost_s)} "
                               f"({100 * (sb.cost_s / b.cost_s - 1):.0f} % more lab time).")
    for k in res.unsearched:
        v = res.fixed.get(k.field) if k.field in (res.fixed or {}) else None
        if v is None:
            v = dotted_value(res.scenario, k.field)
        out.append(f"Not searched: `{k.field}` ({k.description}) changes no required class; left at {v} {k.unit}.")
    return out


def _panel_rows(res) -> tuple[list[list], dict]:
    """The trade curve's grid: one row per group (its requirements across), else the
    requirements three to a row, at most three panels a row; and each requirement's group."""
    reqs, groups = res.requirements, res.groups
    by_req = {}  # a separable plan: each requirement's panel shows its group's shapes and protocols
    for go in groups:
        for rr in go.group.requirements:
            by_req[rr.name] = go
    if len(groups) > 1:
        rows = [[r for r in reqs if by_req.get(r.name) is go] for go in groups]
    else:
        rows = [reqs[i:i + 3] for i in range(0, len(reqs), 3)]
    return [row[i:i + 3] for row in rows for i in range(0, len(row), 3) if row], by_req


def _draw_panel(ax, res, r, go, names: list[str], first: bool) -> None:
    """Requirement ``r``'s panel: per shape of ``names`` the fitted model's line and every
    protocol run (filled: meets every bound), the bound, the re-validated recommendation, the
    budget; ``first``: the row's first panel (its y label)."""
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    shapes = list(res.shapes)
    for name in names:
        j = shapes.index(name)
        m = res.shapes[name].model
        if m is not None and m.cost_s:
            ax.plot(np.array(m.cost_s) / SECONDS_PER_HOUR, m.quantile[r.name], lw=1.2, color=f"C{j}")
        evs = [e for e in res.evaluations if e.shape == name]
        if not evs:
            continue
        c = np.array([e.cost_s / SECONDS_PER_HOUR for e in evs])
        q = np.array([e.figures[r.name]["quantile"] for e in evs])
        met = np.array([e.met for e in evs])
        mk = MARKERS[j % len(MARKERS)]
        ax.scatter(c[met], q[met], marker=mk, s=22, color=f"C{j}", zorder=3)
        ax.scatter(c[~met], q[~met], marker=mk, s=22, facecolors="none", edgecolors=f"C{j}", zorder=3)
    ax.axhline(r.value, color="k", lw=1.0, ls="--")
    one = go is None or len(res.groups) == 1
    if res.validation is not None:
        f = res.validation.figures[r.name]
        # a group's panel: at its part of the recommendation (the lab time its protocols are drawn at)
        x = res.validation.cost_s if one else go.best.cost_s
        ax.errorbar([x / SECONDS_PER_HOUR], [f["quantile"]], yerr=[f["se_quantile"]], fmt="*", ms=11, color="crimson", zorder=4)
    if res.budget_hours is not None:
        ax.axvline(res.budget_hours, color="grey", lw=1.0, ls="-.")
    ax.set_xscale("log")
    ax.set_yscale("log")
    # lab time in plain numbers (0.7, 0.8, 1), not the log axis' default 7 x 10^-1
    # (minor ticks labelled only where the axis spans less than a decade, thinned so
    # labels never overlap)
    lo, hi = ax.get_xlim()
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(FormatStrFormatter("%g") if hi < 3 * lo else NullFormatter())
    ax.tick_params(labelsize=7)
    ax.set_xlabel("lab time (h)", fontsize=8)
    if first:
        ax.set_ylabel(f"{percent_text(res.confidence)} quantile of |error|\n({r.unit})", fontsize=8)
    ax.set_title(r.name if one else f"{r.name} (group {go.group.name})", fontsize=9)


def _row_legend(ax, res, go, names: list[str]) -> None:
    """One legend per row, right of its last panel ``ax``: a line and marker per shape (filled:
    meets every bound; open: fails one), the bound, the re-validated recommendation."""
    from matplotlib.lines import Line2D

    shapes = list(res.shapes)
    handles = [Line2D([], [], color=f"C{shapes.index(n)}", marker=MARKERS[shapes.index(n) % len(MARKERS)],
                      lw=1.2, ms=5, label=n.split("/", 1)[-1] if go is not None else n)
               for n in names if len(names) > 1]
    handles += [Line2D([], [], color="grey", lw=1.2, label="fitted model"),
                Line2D([], [], color="grey", marker="o", lw=0, ms=5, label="run: meets all"),
                Line2D([], [], color="grey", marker="o", lw=0, ms=5, mfc="none", label="run: fails one"),
                Line2D([], [], color="k", ls="--", lw=1.0, label="bound")]
    if res.validation is not None:
        handles.append(Line2D([], [], color="crimson", marker="*", lw=0, ms=9, label="recommended,\nre-validated"))
    if res.budget_hours is not None:
        handles.append(Line2D([], [], color="grey", ls="-.", lw=1.0, label=f"budget {res.budget_hours:g} h"))
    ax.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.03, 1.0), borderaxespad=0.0,
              title="shape" if len(names) > 1 else None, title_fontsize=7)


def _requirement_caption(res, r) -> str | None:
    """What the trade curve shows of requirement ``r``, from the numbers drawn (None: no protocol ran)."""
    evs = sorted((e for e in res.evaluations if r.name in e.figures), key=lambda e: e.cost_s)
    if not evs:
        return None
    meets = [e for e in evs if e.met]
    s = f"{r.name}: measured from {fmt(max(e.figures[r.name]['quantile'] for e in evs))} to " \
        f"{fmt(min(e.figures[r.name]['quantile'] for e in evs))} {r.unit} over {lab_time_text(evs[0].cost_s)} to " \
        f"{lab_time_text(evs[-1].cost_s)} of lab time"
    if meets:
        best = meets[0]
        fails = [e for e in evs if not e.met and e.cost_s < best.cost_s and e.stage == "search"]
        s += (f"; the cheapest meeting every bound, {knobs_text(best.knobs)} at {lab_time_text(best.cost_s)}, "
              f"reaches {fmt(best.figures[r.name]['quantile'])}")
        if fails:
            f = fails[-1]
            s += f", the dearest failing below it, {knobs_text(f.knobs)} at {lab_time_text(f.cost_s)}, " \
                 f"{fmt(f.figures[r.name]['quantile'])}"
    floors = [res.shapes[n].model.floor[r.name] for n in res.shapes if res.shapes[n].model is not None
              and r.name in res.shapes[n].model.floor]
    if floors and min(floors) > 0:
        s += f"; the fitted model's floor (what no count removes) {fmt(min(floors))} {r.unit}"
    elif floors:
        s += "; the fitted model has no floor (every count averages the error down)"
    return s


def _trade_caption(res) -> str:
    """The trade curve's caption, computed from the points it draws."""
    parts = [s for s in (_requirement_caption(res, r) for r in res.requirements) if s is not None]
    groups = res.groups
    rec = "" if res.validation is None else (
        f" The star: the recommended protocol, {knobs_text(res.validation.knobs)}, "
        f"{lab_time_text(res.validation.cost_s)}, re-validated on fresh trials (error bar: one standard error of "
        "the quantile).")
    if len(groups) > 1:
        rec += (f" Each panel shows its requirement's group ({len(groups)} independent groups) at the whole "
                "protocol's lab time with the other groups' knobs at the scenario's values; its star at its "
                "group's answer.")
    return (f"The trade curve: each marker a protocol the search ran ({len(res.evaluations)} in all, "
            f"{res.search_trials} trials with common random numbers; filled: meets every bound), each line "
            "the fitted model's best protocol at each lab time. " + "; ".join(parts) + "." + rec)


def plot_trade_curve(res, path: Path):
    """Cost against each required figure: every protocol run (by shape; filled: met), the
    bound, the recommendation's re-validated figure with its standard error. Returns the
    :class:`budget.figures.Figure` with its caption."""
    rows, by_req = _panel_rows(res)
    ncols = max(len(row) for row in rows)
    fig, axes = plt().subplots(len(rows), ncols, figsize=(3.4 * ncols + 2.4, 2.9 * len(rows) + 0.6),
                               squeeze=False, layout="constrained")
    for ri, row in enumerate(rows):
        go = by_req.get(row[0].name)
        names = [n for n in res.shapes if go is None or n in go.shapes]
        for ci in range(len(row), ncols):
            axes[ri][ci].set_visible(False)
        for ci, r in enumerate(row):
            _draw_panel(axes[ri][ci], res, r, go, names, ci == 0)
        _row_legend(axes[ri][len(row) - 1], res, go, names)
    fig.suptitle(f"{res.variant} estimates against lab time" + ("" if len(res.groups) < 2 else ", a row per group"),
                 fontsize=9)
    return save(fig, path, _trade_caption(res), layout=False)


def summary_markdown(res) -> str:
    lines = [answer_text(res), ""] + [f"* {s}" for s in findings_sentences(res)]
    return "\n".join(lines)


def _table(res) -> list[str]:
    head = ["shape", "stage"] + [k.field.rsplit(".", 1)[-1] for k in res.knobs] + ["lab time", "trials"] + \
        [f"{r.name} q ({r.unit})" for r in res.requirements] + ["meets"]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    evs = sorted(res.evaluations, key=lambda e: (e.shape, e.cost_s))
    if res.fresh_run is not None:
        evs.append(res.fresh_run)
    for e in evs:
        # a separable plan's protocol carries its group's requirements only (the others: blank)
        cells = [e.shape, e.stage] + [str(e.knobs.get(k.field, "")) for k in res.knobs] + \
            [lab_time_text(e.cost_s), str(e.trials)] + \
            [f"{fmt(e.figures[r.name]['quantile'])} +- {fmt(e.figures[r.name]['se_quantile'])}"
             if r.name in e.figures else "" for r in res.requirements] + ["yes" if e.met else "no"]
        rows.append("| " + " | ".join(cells) + " |")
    return rows


def _groups_table(res) -> list[str]:
    """A separable plan's groups: classes, requirements, knobs and shapes searched, its answer,
    the trials it spent."""
    n = res.trials_per_validation
    rows = ["| group | classes | requirements | knobs searched | shapes searched (declared shapes) | answer | "
            "lab time* | trials (validations) |", "|---|---|---|---|---|---|---|---|"]
    for go in res.groups:
        g = go.group
        b, a = go.best, go.best_achievable
        # a collapsed shape: its label and how many declared shapes it stands for (the JSON lists them)
        shapes = "; ".join(k if len(v) == 1 or _is_any(k) else f"{k} ({len(v)} declared)" for k, v in g.members.items())
        fl = _floor(res, go) if b is None else None
        ans = (knobs_text(b.knobs) + ("" if _is_any(go.best_label) else f" ({go.best_label})") if b is not None
               else "none meets" + (f"; floor {fmt(fl[1])} > {fmt(fl[0].value)} ({fl[0].name})" if fl is not None
                                    else "" if a is None else f"; most accurate {knobs_text(a.knobs)}"))
        cost = lab_time_text(b.cost_s) if b is not None else ""
        cells = [g.name, ", ".join(g.classes), ", ".join(r.text for r in g.requirements),
                 ", ".join(f"`{k.field}`" for k in g.knobs) or "none", shapes, ans, cost,
                 f"{go.trials} ({fmt(go.trials / n, 3)}){' restricted' if go.restricted else ''}"]
        rows.append("| " + " | ".join(cells) + " |")
    rows += ["", "*the whole protocol's lab time with the other groups' knobs at the scenario's values; lab time "
             "is additive over the groups, so the recommendation (every group's answer) costs the scenario's lab "
             "time plus each group's change."]
    if res.unsearched:
        rows += ["", "Not searched (no required class depends on them; left at the scenario's value): " +
                 ", ".join(f"`{k.field}`" for k in res.unsearched) + "."]
    return rows


def write_plan_report(res, out_dir) -> Path:
    """``report.md``, ``report.html``, ``trade_curve.png``, ``plan.json`` and (where a protocol
    meets) ``recommended.toml`` into ``out_dir`` (a staged folder or a new one)."""
    with staged_report(out_dir) as tmp:
        st = res.study
        conf = percent_text(res.confidence)
        figs = [plot_trade_curve(res, tmp / "trade_curve.png")]
        lines = [f"# {st.title}: test plan", "",
                 f"Study `{st.name}`; scenario `{getattr(res.scenario, 'name', '')}` (hash "
                 f"`{st.scenario_hash(res.scenario)}`); requirements {_req_list(res)} on the `{res.variant}` "
                 f"estimates, each met when {conf} of tests land within the bound (the {conf} quantile of "
                 f"|estimate - truth|)" + ("" if res.budget_hours is None else
                                           f"; lab time at most {res.budget_hours:g} h") + ".", "",
                 "## Findings", "", summary_markdown(res), ""]
        if res.recommended is not None:
            lines += ["## The recommended protocol", "",
                      "Knobs: " + "; ".join(f"`{k.field}` = {res.recommended.knobs[k.field]} {k.unit} "
                                             f"({k.description})" for k in res.knobs) + ".", "",
                      "Lab time by item: " + ", ".join(f"{n} {lab_time_text(v)}" for n, v in
                                                      res.recommended.cost_items.items())
                      + f"; total {lab_time_text(res.recommended.cost_s)}.", "",
                      f"Ready to run: `budget {st.name} validate recommended.toml` (written beside this report).",
                      ""]
        if res.groups:
            lines += ["## Independent sub-plans", "",
                      f"The requirements split into {len(res.groups)} group{'s' if len(res.groups) > 1 else ''} that "
                      "no knob or shape field links (the study's field_classes); each was searched on its own "
                      "(its own trial budget per shape, its trials computing only its classes where the study "
                      "can), and their answers together re-validated as one protocol.", ""] + \
                _groups_table(res) + [""]
        lines += ["## Trade curve", "", figure_markdown(figs), "",
                  "## Every protocol run", "",
                  f"Search seed {res.seed} for every protocol (common random numbers); the re-validation "
                  f"(stage `validation`) seed {res.validation_seed}, from "
                  "`SeedSequence(seed, spawn_key=(2**31 + 1,))`, shares no trial with the search. "
                  "q: the quantile of |error| +- its standard error.", ""] + _table(res) + [""]
        lines += ["## How the plan was made", "",
                  "Design protocols over the knobs' bounds, a fitted model of averaging (quantile^2 = a + "
                  "sum b_i / knob_i) proposing the cheapest protocol predicted to meet, and bisection along lab "
                  "time between the cheapest protocol measured meeting and the dearest measured failing, until "
                  "their lab times are within the sampling resolution; then the answer re-validated on fresh "
                  "trials. Sureness: the posterior probability that the share of tests beyond the bound is at "
                  f"most {percent_text(1 - res.confidence)}" +
                  " given the re-validation (Jeffreys prior), over the truth's own uncertainty; over several "
                  "requirements the Bonferroni bound. See docs/planning.md.", ""]
        flat, fixed = res.flat, res.fixed or {}
        if flat:
            lines += ["Cost-flat knobs (their lab time does not change with them), outside the model: " +
                      ", ".join(f"`{k.field}`" for k in flat) + "; at each protocol searched, set where the worst "
                      "requirement is best by direct evaluation (a coarse grid and refinement, screening trials, "
                      "stage `flat search`).", ""]
        if fixed:
            lines += ["Fixed (`--fix`): " + ", ".join(f"`{f}` = {v}" for f, v in fixed.items()) + ".", ""]
        (tmp / "report.md").write_text("\n".join(lines))
        write_json_atomic(tmp / "plan.json", res.to_json())
        toml = res.recommended_toml()
        if toml is not None:
            (tmp / "recommended.toml").write_text(toml)
        write_html(tmp / "report.md")
    return Path(out_dir) / "report.md"
