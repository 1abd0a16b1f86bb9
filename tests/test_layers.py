"""The layers point one way: the simulated world (simcam) never imports the lab (budget),
the infrastructure (simcam.infra) imports neither, and no two modules import each other,
counting the imports inside functions.

Every module of both packages is parsed with :mod:`ast` (nothing is imported or run); the
import statements are resolved to module names of the two packages (relative imports
included; ``from pkg import name`` counts as importing ``pkg.name`` when that is a module).
A string ``"package.module:attribute"`` naming a module of the two packages (the registry's
table of studies, the ``budget`` command's table of sub-commands) is an import too: the
module holding it imports that one when the entry is used; and the CLI's group builder
(budget.runner.cli) imports each study's command module the registry's table names. Imports
under ``if TYPE_CHECKING:`` are never executed and are no edge.

A package's ``__init__`` runs before its submodules: importing ``a.b`` imports ``a`` first,
so ``a.b`` naming its own package ``a`` (``from a import c``) is no edge to ``a``.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("simcam", "budget")
#: third-party libraries slow to import (a third of a second or more each on the lab's
#: machines) or optional: a module of ours that imports one of them (at its top level, or
#: through the modules of ours it imports there) is *heavy*, and only a heavy module may be
#: imported inside a function, so that a command pays for it only when it uses it
HEAVY_LIBRARIES = frozenset({
    "numba",  # the JIT compiler (and every kernel module compiled with it)
    "scipy", "pandas", "astropy", "colour",  # numerical and astronomical libraries
    "matplotlib",  # figures, only when a report is written
    "xarray", "dask", "distributed", "zarr", "SALib",  # the sweeps' stores and sensitivity analysis
    "emcee",  # the inductosyn report's posterior band
    "mitsuba",  # lens tracing (optional)
    "tqdm", "psutil",  # a progress bar on a terminal, memory probes
})
#: ``"package.module:attribute"``: a module imported by name when the entry is used
_TARGET = re.compile(r"((?:simcam|budget)(?:\.\w+)*):\w+")


def _modules() -> dict[str, Path]:
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


MODULES = _modules()


def _is_package(name: str) -> bool:
    return MODULES.get(name, Path()).name == "__init__.py"


def _statements(body: list, *, into_functions: bool):
    """The statements of ``body`` and of the blocks nested in it, ``if TYPE_CHECKING:``
    blocks left out (their ``else`` kept); function bodies only if ``into_functions``."""
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not into_functions:
            continue
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            yield from _statements(node.orelse, into_functions=into_functions)
            continue
        yield node
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            child = getattr(node, field, None)
            if isinstance(child, list):
                yield from _statements(child, into_functions=into_functions)


def _import_lines(name: str, *, top_level_only: bool) -> dict[str, list[int]]:
    """Modules of simcam/budget that module ``name`` imports -> the lines that import them:
    all of them, or only those executed when it is imported (statements at module level,
    outside functions and ``if TYPE_CHECKING:`` blocks)."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"), filename=str(MODULES[name]))
    found: dict[str, list[int]] = {}

    def add(target: str, line: int) -> None:
        if target.split(".")[0] in PACKAGES and target in MODULES:
            found.setdefault(target, []).append(line)

    for stmt in _statements(tree.body, into_functions=not top_level_only):
        for node in ast.iter_child_nodes(stmt) if not isinstance(stmt, (ast.Import, ast.ImportFrom)) else [stmt]:
            if not top_level_only and isinstance(node, ast.expr):
                for const in ast.walk(node):  # "module:attribute" entries
                    if isinstance(const, ast.Constant) and isinstance(const.value, str):
                        m = _TARGET.fullmatch(const.value)
                        if m:
                            add(m.group(1), const.lineno)
        for target in _import_lines_of(name, stmt):
            add(target, stmt.lineno)
    return found


def _import_lines_of(name: str, stmt: ast.stmt) -> set[str]:
    """The modules of simcam/budget that the statement ``stmt`` of module ``name`` imports
    (none when it is no import statement)."""
    package = name if _is_package(name) else name.rpartition(".")[0]
    if isinstance(stmt, ast.Import):
        targets = [alias.name for alias in stmt.names]
    elif isinstance(stmt, ast.ImportFrom):
        if stmt.level:
            base = package.split(".")
            base = base[: len(base) - (stmt.level - 1)]
            mod = ".".join(base + ([stmt.module] if stmt.module else []))
        else:
            mod = stmt.module or ""
        targets = [mod] + [f"{mod}.{alias.name}" for alias in stmt.names]
    else:
        return set()
    return {t for t in targets if t.split(".")[0] in PACKAGES and t in MODULES}


def _imports(name: str, *, top_level_only: bool) -> set[str]:
    """Modules of simcam/budget that module ``name`` imports (:func:`_import_lines`)."""
    return set(_import_lines(name, top_level_only=top_level_only))


def _command_modules() -> dict[str, list[int]]:
    """The study command modules the registry's table names (``cli_module="..."``) -> the lines
    of registry.py naming them: the CLI's group builder (:mod:`budget.runner.cli`) imports
    them by that name."""
    tree = ast.parse(MODULES["budget.runner.registry"].read_text(encoding="utf-8"))
    found: dict[str, list[int]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.keyword) and node.arg == "cli_module" and isinstance(node.value, ast.Constant) \
                and node.value.value in MODULES:
            found.setdefault(node.value.value, []).append(node.value.lineno)
    return found


def _graph(*, top_level_only: bool) -> dict[str, dict[str, list[int]]]:
    """module -> {module it imports -> lines}, without a module's edges to itself and to the
    packages it lies in; with every import, the group builder's imports of the study command
    modules (:func:`_command_modules`, lines of registry.py)."""
    graph = {name: {m: lines for m, lines in _import_lines(name, top_level_only=top_level_only).items()
                    if m != name and not name.startswith(m + ".")}
             for name in MODULES}
    if not top_level_only:
        graph["budget.runner.cli"].update(_command_modules())
    return graph


def _components(graph: dict[str, dict]) -> list[list[str]]:
    """The strongly connected components of ``graph`` of more than one module (Tarjan's
    algorithm, iterative), each sorted, in the order of their first module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    comp.append(m)
                    if m == node:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return sorted(out)


def _describe(graph: dict[str, dict[str, list[int]]], comp: list[str]) -> str:
    inside = set(comp)
    edges = [f"    {a} -> {b} (line {', '.join(map(str, lines))})"
             for a in comp for b, lines in sorted(graph[a].items()) if b in inside]
    return f"{len(comp)} modules: {', '.join(comp)}\n" + "\n".join(edges)


def _top_level_libraries(name: str) -> set[str]:
    """The heavy third-party libraries module ``name`` imports at its top level."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    roots = set()
    for stmt in _statements(tree.body, into_functions=False):
        if isinstance(stmt, ast.Import):
            roots |= {alias.name.split(".")[0] for alias in stmt.names}
        elif isinstance(stmt, ast.ImportFrom) and not stmt.level and stmt.module:
            roots.add(stmt.module.split(".")[0])
    return roots & HEAVY_LIBRARIES


def _heavy_modules() -> set[str]:
    """The modules of ours whose import loads a heavy library (:data:`HEAVY_LIBRARIES`): their
    own top-level imports, those of the modules of ours they import there, and of the
    packages they lie in."""
    graph = _graph(top_level_only=True)
    for name in MODULES:  # importing a.b.c imports a and a.b first
        parts = name.split(".")
        graph[name] = {**graph[name], **{".".join(parts[:i]): [] for i in range(1, len(parts))
                                         if ".".join(parts[:i]) in MODULES}}
    heavy = {name for name in MODULES if _top_level_libraries(name)}
    changed = True
    while changed:
        grown = {name for name in MODULES if name not in heavy and set(graph[name]) & heavy}
        heavy |= grown
        changed = bool(grown)
    return heavy


def _function_level_imports(name: str) -> list[tuple[int, list[str]]]:
    """The import statements inside functions of module ``name`` that name modules of ours:
    (line, the modules it names)."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"))
    top = {id(stmt) for stmt in _statements(tree.body, into_functions=False)}
    # a package's module-level __getattr__ (PEP 562) imports on first use by design: it keeps
    # ``import budget`` from importing the lab (the console script's start stays light)
    lazy = [range(f.lineno, f.end_lineno + 1) for f in tree.body
            if isinstance(f, ast.FunctionDef) and f.name == "__getattr__"]
    out = []
    for stmt in _statements(tree.body, into_functions=True):
        if id(stmt) in top or not isinstance(stmt, (ast.Import, ast.ImportFrom)):
            continue
        if any(stmt.lineno in span for span in lazy):
            continue
        named = sorted(_import_lines_of(name, stmt))
        if named:
            out.append((stmt.lineno, named))
    return out


def test_every_module_is_found():
    assert "simcam.config_base" in MODULES and "budget.runner.study" in MODULES


def test_simcam_never_imports_budget():
    offenders = {name: sorted(m for m in _imports(name, top_level_only=False) if m.startswith("budget"))
                 for name in MODULES if name.split(".")[0] == "simcam"}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_infra_imports_nothing_of_simcam_or_budget():
    # simcam.infra is the bottom layer: errors, outputs, lifecycle, the command-line helpers
    offenders = {name: sorted(m for m in _imports(name, top_level_only=False)
                              if m != "simcam" and not m.startswith("simcam.infra"))
                 for name in MODULES if name.startswith("simcam.infra")}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_no_top_level_import_cycles():
    graph = _graph(top_level_only=True)
    comps = _components(graph)
    assert comps == [], "top-level import cycles:\n" + "\n".join(_describe(graph, c) for c in comps)


def test_no_import_cycles_counting_imports_inside_functions():
    # an import inside a function is still a dependency: it only runs later
    graph = _graph(top_level_only=False)
    comps = _components(graph)
    for comp in comps:
        print(_describe(graph, comp))
    assert comps == [], "import cycles (imports inside functions included):\n" + "\n".join(
        _describe(graph, c) for c in comps)


def test_components_are_found():
    # the check itself: a cycle through a function-level import and a "module:attribute" entry
    graph = {"a": {"b": [1]}, "b": {"c": [2]}, "c": {"a": [3]}, "d": {"a": [4]}, "e": {"e": [5]}}
    assert _components(graph) == [["a", "b", "c"]]
    assert "budget.starcam.study" in _import_lines("budget.runner.registry", top_level_only=False)
    assert "budget.starcam.study" not in _import_lines("budget.runner.registry", top_level_only=True)
    assert "budget.starcam.cli" in _graph(top_level_only=False)["budget.runner.cli"]


def test_imports_inside_functions_are_of_heavy_modules():
    # an import inside a function hides a dependency and runs on every call: only a heavy
    # module (HEAVY_LIBRARIES: a study's simulator and kernels, the plots, the stores) is
    # imported there, never a light one, never to dodge a cycle
    heavy = _heavy_modules()
    offenders = {}
    for name in MODULES:
        light = [f"line {line}: {', '.join(named)}" for line, named in _function_level_imports(name)
                 if not set(named) & heavy]
        if light:
            offenders[name] = light
    for name, lines in sorted(offenders.items()):
        print(f"{name}: " + "; ".join(lines))
    assert offenders == {}, "light modules imported inside functions (move them to the top):\n" + "\n".join(
        f"  {name}: " + "; ".join(lines) for name, lines in sorted(offenders.items()))


def test_heavy_modules_are_found():
    heavy = _heavy_modules()
    assert {"budget.starcam.validate", "simcam.starcam.lens.simulator", "budget.centroid.core"} <= heavy
    assert not {"budget.runner.registry", "budget.figures", "simcam.infra.errors"} & heavy


def test_the_estimators_import_no_click():
    # the lab's estimators are a library: importing them loads no command line
    code = "import sys, budget.starcam.estimators; print('click' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


#: the house's size limits: lines of a module of simcam/budget, lines of a function (numba
#: kernels excepted: a kernel is one loop nest the compiler sees whole)
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 100


def test_modules_and_functions_stay_small():
    # every module under 800 lines, every function (but a numba kernel) under 100: a module
    # is one concept, a function one step a reader holds in view
    offenders = []
    for name, path in sorted(MODULES.items()):
        src = path.read_text(encoding="utf-8")
        rel = path.relative_to(ROOT).as_posix()
        n_lines = src.count("\n")
        if n_lines > MAX_MODULE_LINES:
            offenders.append(f"{rel}: {n_lines} lines")
        for f in ast.walk(ast.parse(src, filename=str(path))):
            if not isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            length = f.end_lineno - f.lineno + 1
            if length > MAX_FUNCTION_LINES and not any("jit" in ast.unparse(d) for d in f.decorator_list):
                offenders.append(f"{rel}: {f.name} (line {f.lineno}) {length} lines")
    assert offenders == [], "over the size limits:\n  " + "\n  ".join(offenders)
