"""What a plan says (:mod:`budget.runner.plan`): its answer and findings in words, derived
from its numbers by the rules below; its JSON (schema ``budget.plan/1``); ``report.md``,
its HTML twin (:mod:`budget.runner.html`), the trade-curve figure (:mod:`budget.figures`,
its caption computed from the points it draws) and ``recommended.toml``.

Rules of the words:

* the answer: "meets R at C % (re-validated on N fresh trials; sure at S %)" where the
  re-validation meets every requirement; "the re-validation does not confirm" otherwise
  (the search's verdict came from trials the verdict does not share, so a protocol at the
  boundary may fail it: the sureness says how close); "no protocol ... meets" with the best
  achievable figure where the search found none;
* the premium: "aiming P sure to pass the real test [on each requirement] costs Fx the
  boundary protocol's lab time", where the search judged by the ``--sure`` prediction bound
  (F: the recommendation's lab time over the fitted model's cheapest protocol whose predicted
  quantiles equal the bounds; the margin is per requirement, hence "on each requirement" where
  there are several);
* a shape's sentence: its cheapest protocol meeting every requirement and its cost, or
  its best figure where none met;
* a separable plan (:attr:`PlanResult.groups`): one sentence per group (its requirements,
  knobs and shapes searched, its answer or its best figure, the trials it spent, whether its
  trials were restricted to its classes), one per knob no requirement depends on (left at the
  scenario's value), and, where every group met but their protocols together exceed
  ``--budget-hours``, "no protocol within B meets ...: the cheapest that does ... takes T"
  (lab time being additive over the groups, none cheaper meets) and what that protocol's run
  on fresh trials says ("it meets every requirement", or "it does not confirm R"); where a
  group meets nothing, the plan's best achievable is every group's answer with the failing
  groups' most accurate protocols, run as one protocol on fresh trials, and the answer says so.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["answer_text", "findings_sentences", "plan_json", "plot_trade_curve", "summary_markdown",
           "write_plan_report"]


def _fmt(v) -> str:
    from budget.runner.findings import fmt

    return fmt(v)


def _unit(r) -> str:
    from budget.runner.findings import with_unit

    return with_unit(r.value, r.unit)


def _hours(s: float) -> str:
    from budget.runner.plan import _hours as h

    return h(s)


def _knobs(ev) -> str:
    from budget.runner.plan import _knobs_text

    return _knobs_text(ev.knobs)


def _knobs_text_raw(knobs: dict) -> str:
    from budget.runner.plan import _knobs_text

    return _knobs_text(knobs)


def _req_list(res) -> str:
    return " and ".join(f"{r.name} <= {_unit(r)}" for r in res.requirements)


def pct(p: float) -> str:
    """``0.95`` -> ``"95 %"``."""
    return f"{100 * p:.0f} %"


def answer_text(res) -> str:
    """The plan's answer in one paragraph (module docstring)."""
    st = res.study
    conf = pct(res.confidence)
    budget = "" if res.budget_hours is None else f" within {res.budget_hours:g} h"
    if res.recommended is None and getattr(res, "over_budget", False):
        b = res.best_achievable
        failed = [name for name, f in b.figures.items() if not f["met"]]
        verdict = (f"it meets every requirement ({_sure_text(res, b)})" if not failed else
                   f"it does not confirm {', '.join(failed)} ({_sure_text(res, b)})")
        return (f"{st.title}: no protocol{budget} meets {_req_list(res)} ({res.variant}, {conf} of tests): the "
                f"cheapest that does, {_knobs(b)}{'' if _is_any(b.shape) else f' ({b.shape})'}, takes "
                f"{_hours(b.cost_s)} of lab time (its {len(res.groups)} independent parts' cheapest protocols "
                f"together; lab time is additive, so none cheaper meets every requirement). Run as one protocol "
                f"on {b.trials} fresh trials, {verdict}.")
    if res.recommended is None:
        b = res.best_achievable
        if b is None:
            return f"{st.title}: no protocol{budget} could be run for {_req_list(res)}."
        worst = max(b.figures.values(), key=lambda f: f["quantile"] / f["bound"])
        name = next(n for n, f in b.figures.items() if f is worst)
        tail = ""
        if getattr(res, "best_achievable_revalidated", False):
            fails = [go["group"].name for go in res.groups if go["best"] is None]
            which = f"group{'s' if len(fails) > 1 else ''} {', '.join(fails)}"
            others = " with every other group's answer" if len(fails) < len(res.groups) else ""
            tail = (f": the most accurate protocol of {which} (no protocol of {'them' if len(fails) > 1 else 'it'} "
                    f"meets){others}, run as one protocol on {b.trials} fresh trials")
            if worst["quantile"] <= worst["bound"]:
                tail += f"; within the bound on these trials, but no protocol of {which} met it in the search"
        elif worst["quantile"] <= worst["bound"] and "upper" in worst:
            tail = (f"; within the bound, but not {pct(worst['upper_sure'])} sure to stay there on the real test "
                    f"(its prediction bound {_fmt(worst['upper'])}; --sure)")
        return (f"{st.title}: no protocol{budget} meets {_req_list(res)} ({res.variant}, {conf} of tests). "
                f"Best achievable: {name} {_fmt(worst['quantile'])} +- {_fmt(worst['se_quantile'])} "
                f"{next(r.unit for r in res.requirements if r.name == name)} "
                f"(the {conf} quantile of |error|, bound {_fmt(worst['bound'])}) with {_knobs(b)} "
                f"({'' if _is_any(b.shape) else f'{b.shape}, '}{_hours(b.cost_s)} of lab time){tail}.")
    rec, val = res.recommended, res.validation
    head = (f"{st.title}: the cheapest protocol found{budget} is {_knobs(rec)}"
            f"{'' if _is_any(rec.shape) else f' ({rec.shape})'}, {_hours(rec.cost_s)} of lab time.")
    n = val.trials
    prem = res.premium
    aim = "" if prem is None or res.sure_level <= 0.5 else (
        f" Aiming {pct(res.sure_level)} sure to pass the real test"
        f"{' on each requirement' if len(res.requirements) > 1 else ''} costs {prem['factor']:.2f}x the boundary "
        f"protocol's lab time ({_knobs_text_raw(prem['boundary_knobs'])}, {_hours(prem['boundary_cost_s'])}).")
    if res.confirmed:
        tail = (f" It meets {_req_list(res)} at {conf} (re-validated on {n} fresh trials; "
                f"{_sure_text(res)}).")
    else:
        failed = [name for name, f in val.figures.items() if not f["met"]]
        why = ("the protocol sits at the boundary; take the next larger one or plan for a tighter bound"
               if res.sure_level <= 0.5 else
               f"a protocol aimed {pct(res.sure_level)} sure fails about {pct(1 - res.sure_level)} of "
               "re-validations; plan with a higher --sure or a tighter bound")
        tail = (f" The re-validation on {n} fresh trials does not confirm {', '.join(failed)} "
                f"({_sure_text(res)}): {why}.")
    return head + tail + aim


def _sure_text(res, ev=None) -> str:
    """How sure a run on fresh seeds (``ev``; default the re-validation) is of every requirement
    at once: the Bonferroni bound ``1 - sum (1 - sure_r)`` (:attr:`PlanResult.sure`), named as
    such where there is more than one requirement (each requirement's own sureness is in its
    sentence)."""
    k = len(res.requirements)
    sure = res.sure if ev is None else max(0.0, 1.0 - sum(1.0 - f["sure"] for f in ev.figures.values()))
    if k == 1:
        return f"sure at {pct(sure)}"
    if pct(sure) == pct(1.0):
        return f"sure of all {k} requirements together at {pct(1.0)} (Bonferroni)"
    return f"sure of all {k} requirements together at {pct(sure)} at least (Bonferroni)"


def findings_sentences(res) -> list[str]:
    """One sentence per requirement (the re-validated figures) and per shape (its best)."""
    out = []
    conf = pct(res.confidence)
    fresh = res.fresh_run
    if fresh is not None:
        for r in res.requirements:
            f = fresh.figures[r.name]
            out.append(f"{r.name} ({r.label}, {res.variant}): {conf} of |error| within {_fmt(f['quantile'])} +- "
                       f"{_fmt(f['se_quantile'])} {r.unit} (bound {_fmt(r.value)}; {f['exceed']} of {f['n']} "
                       f"fresh trials beyond it, {f['allowed']} allowed); bias {_fmt(f['bias'])} +- "
                       f"{_fmt(f['se_bias'])}, sd {_fmt(f['sd'])} +- {_fmt(f['se_sd'])}; "
                       f"sure at {pct(f['sure'])}.")
    if getattr(res, "groups", None):
        out += _group_sentences(res)
    elif len(res.shapes) > 1 or res.recommended is None:
        for name, s in res.shapes.items():
            b = s["best"]
            if b is not None:
                rel = "" if res.recommended is None else (
                    " (recommended)" if b is res.recommended else
                    f" ({100 * (b.cost_s / res.recommended.cost_s - 1):.0f} % more lab time than "
                    f"{res.recommended.shape})")
                out.append(f"Shape {name}: cheapest meeting every requirement {_knobs(b)}, "
                           f"{_hours(b.cost_s)}{rel}; {len(s['evaluations'])} protocols run, {s['trials']} trials.")
            else:
                a = s.get("best_achievable")
                best = "" if a is None else (f"; its most accurate, {_knobs(a)} ({_hours(a.cost_s)}), reaches "
                                             f"{a.ratio:.3g} times the bound")
                out.append(f"Shape {name}: no protocol meets every requirement{best}.")
    for name, s in res.shapes.items():
        if s.get("refused"):
            r = s["refused"]
            out.append(f"{len(r)} protocol{'s' if len(r) > 1 else ''} of shape {name} refused by the study "
                       f"(first: {_knobs_text_raw(r[0]['knobs'])}: {r[0]['error']}).")
    per_val = res.trials_per_validation
    out.append(f"The search ran {len(res.evaluations)} protocols with common random numbers, "
               f"{res.search_trials} trials ({res.search_trials / per_val:.3g} validations of {per_val}); "
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
    for r in go["group"].requirements:
        fl = {k: res.shapes[k]["model"]["floor"].get(r.name) for k in go["shapes"]
              if res.shapes[k].get("model") and res.shapes[k]["model"]["floor"].get(r.name) is not None}
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
    not searched (module docstring)."""
    out = []
    for go in res.groups:
        g = go["group"]
        keys = go["shapes"]
        shapes = "" if len(g.shapes) < 2 else f"; shapes {', '.join(g.shapes)}"
        what = f"Group {g.name} ({', '.join(r.text for r in g.requirements)}{shapes})"
        b, a = go["best"], go["best_achievable"]
        if b is not None:
            sname = go["best_sname"]
            ans = f"{_knobs(b)}{'' if _is_any(sname) else f' ({sname})'}, {_hours(b.cost_s)} of lab time"
        elif a is not None:
            fl = _floor(res, go)
            worst = max(a.figures, key=lambda n: a.figures[n]["quantile"] / a.figures[n]["bound"])
            f = a.figures[worst]
            meas = (f"{_knobs(a)} measured {worst} {_fmt(f['quantile'])} +- {_fmt(f['se_quantile'])} "
                    f"({a.trials} trials)")
            if fl is not None:
                r, v, within = fl
                ans = (f"no count reaches {r.text}: the fitted floor is {_fmt(v)} {r.unit}, what no count removes"
                       + (" (every protocol run within two standard errors of it)" if within else
                          f"; the most accurate by the fitted model, {meas}"))
            else:
                ans = f"none meets; the most accurate by the fitted model, {meas}, bound {_fmt(f['bound'])}"
        else:
            ans = "no protocol could be run"
        out.append(f"{what}: {ans}; {go['protocols']} protocols, {go['trials']} trials.")
        if len(keys) > 1 and b is not None:
            for k in keys:
                sb = res.shapes[k]["best"]
                if sb is None:
                    out.append(f"Shape {k}: none meets.")
                elif sb is not b:
                    out.append(f"Shape {k}: {_knobs(sb)}, {_hours(sb.cost_s)} "
                               f"({100 * (sb.cost_s / b.cost_s - 1):.0f} % more lab time).")
    for k in getattr(res, "unsearched", ()):
        v = res.fixed.get(k.field) if k.field in (res.fixed or {}) else None
        if v is None:
            from budget.runner.plan import _dotted_get

            v = _dotted_get(res.scenario, k.field)
        out.append(f"Not searched: `{k.field}` ({k.description}) changes no required class; left at {v} {k.unit}.")
    return out


def _groups_json(res) -> list[dict]:
    """The sub-plans (a plan that does not decompose: one, every requirement, knob and shape)."""
    n = res.trials_per_validation

    def ev(e):
        return None if e is None else {"shape": e.shape, "knobs": dict(e.knobs), "cost_s": e.cost_s,
                                       "met": e.met, "ratio": e.ratio}

    if not getattr(res, "groups", None):
        free = [k.field for k in res.knobs if k.field not in (res.fixed or {})]
        return [{"name": ",".join(dict.fromkeys(r.cls for r in res.requirements)),
                 "classes": list(dict.fromkeys(r.cls for r in res.requirements)),
                 "requirements": [r.text for r in res.requirements], "knobs": free,
                 "shape_fields": sorted({f for s in res.shapes.values() for f in s.get("overrides", {})}),
                 "shapes": {k: [k] for k in res.shapes}, "restricted": False, "feasible": res.feasible,
                 "best_shape": None if res.recommended is None else res.recommended.shape,
                 "best": ev(res.recommended), "best_achievable": ev(res.best_achievable),
                 "trials": res.search_trials, "validations": res.search_trials / n,
                 "protocols": len(res.evaluations)}]
    out = []
    for go in res.groups:
        g = go["group"]
        out.append({"name": g.name, "classes": list(g.classes), "requirements": [r.text for r in g.requirements],
                    "knobs": [k.field for k in g.knobs], "shape_fields": list(g.shape_fields),
                    "shapes": {k: list(v) for k, v in g.members.items()}, "restricted": go["restricted"],
                    "feasible": go["best"] is not None, "best_shape": go["best_shape"], "best": ev(go["best"]),
                    "best_achievable": ev(go["best_achievable"]), "trials": go["trials"],
                    "validations": go["trials"] / n, "protocols": go["protocols"]})
    return out


def plan_json(res) -> dict:
    """The plan as JSON (schema ``budget.plan/1``)."""
    from budget.runner.plan import SCHEMA, validation_seed
    from simcam import __version__

    st = res.study
    return {
        "schema": SCHEMA, "study": st.name, "title": st.title, "version": __version__,
        "scenario_name": getattr(res.scenario, "name", None), "scenario_hash": st.scenario_hash(res.scenario),
        "seed": res.seed, "validation_seed": validation_seed(res.seed), "confidence": res.confidence,
        "variant": res.variant, "budget_hours": res.budget_hours,
        "requirements": [{"class": r.cls, "axis": r.axis, "value": r.value, "unit": r.unit, "text": r.text}
                         for r in res.requirements],
        "knobs": [{"field": k.field, "kind": k.kind, "low": k.low, "high": k.high, "unit": k.unit,
                   "description": k.description} for k in res.knobs],
        "fixed": dict(getattr(res, "fixed", {}) or {}),
        "flat_knobs": [k.field for k in getattr(res, "flat", ())],
        "feasible": res.feasible, "confirmed": res.confirmed,
        "sure": None if res.validation is None else res.sure,
        "sure_level": res.sure_level, "premium": res.premium,
        "answer": answer_text(res), "findings": findings_sentences(res),
        "recommended": None if res.recommended is None else {
            **res.recommended.to_json(), "scenario_hash": st.scenario_hash(res.recommended.scenario),
            "scenario_toml": res.recommended_toml()},
        "validation": None if res.validation is None else res.validation.to_json(),
        "best_achievable": None if res.best_achievable is None else res.best_achievable.to_json(),
        "shapes": {name: {"overrides": s.get("overrides", {}), "trials": s["trials"],
                          "refused": s.get("refused", []), "model": _thin_model(s.get("model")),
                          "protocols": len(s["evaluations"]),
                          "best": None if s["best"] is None else s["best"].to_json(),
                          "best_achievable": None if s.get("best_achievable") is None
                          else s["best_achievable"].to_json()}
                   for name, s in res.shapes.items()},
        "evaluations": [e.to_json() for e in res.evaluations],
        "best_achievable_revalidated": bool(getattr(res, "best_achievable_revalidated", False)),
        "trials": {"per_validation": res.trials_per_validation, "search": res.search_trials,
                   "validation": 0 if res.fresh_run is None else res.fresh_run.trials,
                   "total": res.total_trials},
        "truths_computed": res.truth_runs, "elapsed_s": res.elapsed_s, "cpu_s": res.cpu_s,
        "groups": _groups_json(res), "unsearched_knobs": [k.field for k in getattr(res, "unsearched", ())],
        "over_budget": bool(getattr(res, "over_budget", False)),
    }


def _thin_model(m: dict | None, most: int = 200) -> dict | None:
    """The fitted model's frontier for the JSON, at most ``most`` protocols (evenly by index)."""
    if not m:
        return None
    n = len(m["cost_s"])
    idx = sorted(set(round(i * (n - 1) / (most - 1)) for i in range(most))) if n > most else list(range(n))
    return {"cost_s": [m["cost_s"][i] for i in idx], "knobs": [m["knobs"][i] for i in idx],
            "quantile": {k: [v[i] for i in idx] for k, v in m["quantile"].items()},
            "floor": m["floor"], "b": m["b"]}


def plot_trade_curve(res, path: Path):
    """Cost against each required figure: every protocol run (by shape; filled: met), the
    bound, the recommendation's re-validated figure with its standard error. Returns the
    :class:`budget.figures.Figure` with its caption."""
    import numpy as np

    from budget.figures import plt, save

    from matplotlib.lines import Line2D
    from matplotlib.ticker import FormatStrFormatter, NullFormatter

    p = plt()
    reqs = res.requirements
    shapes = list(res.shapes)
    markers = "osD^v<>"
    groups = getattr(res, "groups", None) or []
    by_req = {}  # a separable plan: each requirement's panel shows its group's shapes and protocols
    for go in groups:
        for rr in go["group"].requirements:
            by_req[rr.name] = go
    # the grid: one row per group (its requirements across), else the requirements three to a row
    if len(groups) > 1:
        rows = [[r for r in reqs if by_req.get(r.name) is go] for go in groups]
    else:
        rows = [reqs[i:i + 3] for i in range(0, len(reqs), 3)]
    rows = [row[i:i + 3] for row in rows for i in range(0, len(row), 3) if row]
    ncols = max(len(row) for row in rows)
    fig, axes = p.subplots(len(rows), ncols, figsize=(3.4 * ncols + 2.4, 2.9 * len(rows) + 0.6), squeeze=False,
                           layout="constrained")
    for ri, row in enumerate(rows):
        go = by_req.get(row[0].name)
        names = [n for n in shapes if go is None or n in go["shapes"]]
        for ci in range(len(row), ncols):
            axes[ri][ci].set_visible(False)
        for ci, r in enumerate(row):
            ax = axes[ri][ci]
            for name in names:
                j = shapes.index(name)
                m = res.shapes[name].get("model")
                if m and m["cost_s"]:
                    ax.plot(np.array(m["cost_s"]) / 3600, m["quantile"][r.name], lw=1.2, color=f"C{j}")
                evs = [e for e in res.evaluations if e.shape == name]
                if not evs:
                    continue
                c = np.array([e.cost_s / 3600 for e in evs])
                q = np.array([e.figures[r.name]["quantile"] for e in evs])
                met = np.array([e.met for e in evs])
                mk = markers[j % len(markers)]
                ax.scatter(c[met], q[met], marker=mk, s=22, color=f"C{j}", zorder=3)
                ax.scatter(c[~met], q[~met], marker=mk, s=22, facecolors="none", edgecolors=f"C{j}", zorder=3)
            ax.axhline(r.value, color="k", lw=1.0, ls="--")
            if res.validation is not None:
                f = res.validation.figures[r.name]
                # a group's panel: at its part of the recommendation (the lab time its protocols are drawn at)
                x = res.validation.cost_s if go is None or len(groups) == 1 else go["best"].cost_s
                ax.errorbar([x / 3600], [f["quantile"]], yerr=[f["se_quantile"]], fmt="*",
                            ms=11, color="crimson", zorder=4)
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
            if ci == 0:
                ax.set_ylabel(f"{pct(res.confidence)} quantile of |error|\n({r.unit})", fontsize=8)
            ax.set_title(r.name if go is None or len(groups) == 1 else f"{r.name} (group {go['group'].name})",
                         fontsize=9)
        # one legend per row, right of its last panel: a line and marker per shape (filled: meets
        # every bound; open: fails one), the bound, the re-validated recommendation
        handles = [Line2D([], [], color=f"C{shapes.index(n)}", marker=markers[shapes.index(n) % len(markers)],
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
        axes[ri][len(row) - 1].legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.03, 1.0),
                                      borderaxespad=0.0, title="shape" if len(names) > 1 else None,
                                      title_fontsize=7)
    fig.suptitle(f"{res.variant} estimates against lab time" + ("" if len(groups) < 2 else ", a row per group"),
                 fontsize=9)
    # the caption from the numbers drawn
    parts = []
    for r in reqs:
        evs = sorted((e for e in res.evaluations if r.name in e.figures), key=lambda e: e.cost_s)
        if not evs:
            continue
        meets = [e for e in evs if e.met]
        s = f"{r.name}: measured from {_fmt(max(e.figures[r.name]['quantile'] for e in evs))} to " \
            f"{_fmt(min(e.figures[r.name]['quantile'] for e in evs))} {r.unit} over {_hours(evs[0].cost_s)} to " \
            f"{_hours(evs[-1].cost_s)} of lab time"
        if meets:
            best = meets[0]
            fails = [e for e in evs if not e.met and e.cost_s < best.cost_s and e.stage == "search"]
            s += (f"; the cheapest meeting every bound, {_knobs(best)} at {_hours(best.cost_s)}, reaches "
                  f"{_fmt(best.figures[r.name]['quantile'])}")
            if fails:
                f = fails[-1]
                s += f", the dearest failing below it, {_knobs(f)} at {_hours(f.cost_s)}, " \
                     f"{_fmt(f.figures[r.name]['quantile'])}"
        floors = [res.shapes[n]["model"]["floor"][r.name] for n in shapes if res.shapes[n].get("model")
                  and r.name in res.shapes[n]["model"]["floor"]]
        if floors and min(floors) > 0:
            s += f"; the fitted model's floor (what no count removes) {_fmt(min(floors))} {r.unit}"
        elif floors:
            s += "; the fitted model has no floor (every count averages the error down)"
        parts.append(s)
    rec = "" if res.validation is None else (
        f" The star: the recommended protocol, {_knobs(res.validation)}, {_hours(res.validation.cost_s)}, "
        "re-validated on fresh trials (error bar: one standard error of the quantile).")
    if len(groups) > 1:
        rec += (f" Each panel shows its requirement's group ({len(groups)} independent groups) at the whole "
                "protocol's lab time with the other groups' knobs at the scenario's values; its star at its "
                "group's answer.")
    caption = (f"The trade curve: each marker a protocol the search ran ({len(res.evaluations)} in all, "
               f"{res.search_trials} trials with common random numbers; filled: meets every bound), each line "
               "the fitted model's best protocol at each lab time. " + "; ".join(parts) + "." + rec)
    return save(fig, path, caption, layout=False)


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
            [_hours(e.cost_s), str(e.trials)] + \
            [f"{_fmt(e.figures[r.name]['quantile'])} +- {_fmt(e.figures[r.name]['se_quantile'])}"
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
        g = go["group"]
        b, a = go["best"], go["best_achievable"]
        # a collapsed shape: its label and how many declared shapes it stands for (the JSON lists them)
        shapes = "; ".join(k if len(v) == 1 or _is_any(k) else f"{k} ({len(v)} declared)" for k, v in g.members.items())
        fl = _floor(res, go) if b is None else None
        ans = (_knobs(b) + ("" if _is_any(go["best_sname"]) else f" ({go['best_sname']})") if b is not None
               else "none meets" + (f"; floor {_fmt(fl[1])} > {_fmt(fl[0].value)} ({fl[0].name})" if fl is not None
                                    else "" if a is None else f"; most accurate {_knobs(a)}"))
        cost = _hours(b.cost_s) if b is not None else ""
        cells = [g.name, ", ".join(g.classes), ", ".join(r.text for r in g.requirements),
                 ", ".join(f"`{k.field}`" for k in g.knobs) or "none", shapes, ans, cost,
                 f"{go['trials']} ({go['trials'] / n:.3g}){' restricted' if go['restricted'] else ''}"]
        rows.append("| " + " | ".join(cells) + " |")
    rows += ["", "*the whole protocol's lab time with the other groups' knobs at the scenario's values; lab time "
             "is additive over the groups, so the recommendation (every group's answer) costs the scenario's lab "
             "time plus each group's change."]
    if getattr(res, "unsearched", ()):
        rows += ["", "Not searched (no required class depends on them; left at the scenario's value): " +
                 ", ".join(f"`{k.field}`" for k in res.unsearched) + "."]
    return rows


def write_plan_report(res, out_dir) -> Path:
    """``report.md``, ``report.html``, ``trade_curve.png``, ``plan.json`` and (where a protocol
    meets) ``recommended.toml`` into ``out_dir`` (a staged folder or a new one)."""
    from budget.figures import figure_markdown
    from budget.runner.html import write_html
    from budget.runner.report import staged_report
    from simcam.infra.cli import write_json_atomic

    with staged_report(out_dir) as tmp:
        st = res.study
        conf = pct(res.confidence)
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
                      "Lab time by item: " + ", ".join(f"{n} {_hours(v)}" for n, v in
                                                      res.recommended.cost_items.items())
                      + f"; total {_hours(res.recommended.cost_s)}.", "",
                      f"Ready to run: `budget {st.name} validate recommended.toml` (written beside this report).",
                      ""]
        if getattr(res, "groups", None):
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
                  f"most {pct(1 - res.confidence)}" +
                  " given the re-validation (Jeffreys prior), over the truth's own uncertainty; over several "
                  "requirements the Bonferroni bound. See docs/planning.md.", ""]
        flat, fixed = getattr(res, "flat", ()), getattr(res, "fixed", {}) or {}
        if flat:
            lines += ["Cost-flat knobs (their lab time does not change with them), outside the model: " +
                      ", ".join(f"`{k.field}`" for k in flat) + "; at each protocol searched, set where the worst "
                      "requirement is best by direct evaluation (a coarse grid and refinement, screening trials, "
                      "stage `flat search`).", ""]
        if fixed:
            lines += ["Fixed (`--fix`): " + ", ".join(f"`{f}` = {v}" for f, v in fixed.items()) + ".", ""]
        (tmp / "report.md").write_text("\n".join(lines))
        write_json_atomic(tmp / "plan.json", plan_json(res))
        toml = res.recommended_toml()
        if toml is not None:
            (tmp / "recommended.toml").write_text(toml)
        write_html(tmp / "report.md")
    return Path(out_dir) / "report.md"
