"""The layers point one way: the simulated world (simcam) never imports the lab (budget), and
no two modules import each other at module top level.

Every module of both packages is parsed with :mod:`ast` (nothing is imported or run); the
import statements are resolved to module names of the two packages (relative imports
included; ``from pkg import name`` counts as importing ``pkg.name`` when that is a module).
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("simcam", "budget")


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


def _imports(name: str, *, top_level_only: bool) -> set[str]:
    """Modules of simcam/budget that module ``name`` imports (all of them, or only those
    executed when it is imported: statements at module level, outside functions and
    ``if TYPE_CHECKING`` blocks)."""
    tree = ast.parse(MODULES[name].read_text(encoding="utf-8"), filename=str(MODULES[name]))
    package = name if _is_package(name) else name.rpartition(".")[0]

    def nodes(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)) and top_level_only:
                continue
            if isinstance(node, ast.If) and top_level_only and "TYPE_CHECKING" in ast.unparse(node.test):
                yield from nodes(node.orelse)
                continue
            yield node
            for field in ("body", "orelse", "finalbody", "handlers"):
                child = getattr(node, field, None)
                if isinstance(child, list):
                    yield from nodes(child)

    found = set()
    stream = nodes(tree.body) if top_level_only else ast.walk(tree)
    for node in stream:
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            targets = [mod] + [f"{mod}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            if target.split(".")[0] in PACKAGES and target in MODULES:
                found.add(target)
    return found


def test_every_module_is_found():
    assert "simcam.config_base" in MODULES and "budget.runner.study" in MODULES


def test_simcam_never_imports_budget():
    offenders = {name: sorted(m for m in _imports(name, top_level_only=False) if m.startswith("budget"))
                 for name in MODULES if name.split(".")[0] == "simcam"}
    assert {k: v for k, v in offenders.items() if v} == {}


def test_no_top_level_import_cycles():
    # a package's __init__ runs before its submodules: importing ``a.b`` imports ``a`` first,
    # so ``a.b`` naming its own package ``a`` (``from a import c``) is no edge to ``a``
    graph = {name: {m for m in _imports(name, top_level_only=True) if m != name and not name.startswith(m + ".")}
             for name in MODULES}
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    cycles = []

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                cycles.append(path[path.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [name])
    assert cycles == [], "top-level import cycles: " + "; ".join(" -> ".join(c) for c in cycles)
