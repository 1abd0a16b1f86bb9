"""The shared machinery knows no study by name: budget/runner and budget/sweeps
reach every study through the registry's table, and nothing else in them names one.

A scan of the code (identifiers and string literals; docstrings and comments are prose and
are not scanned) of every module of the two packages, the registry's table excepted.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NAMES = ("starcam", "camera", "inductosyn", "whiskbroom", "scanmirror", "linecam", "harmonics")
_WORD = re.compile(r"(?<![a-z])(" + "|".join(NAMES) + r")(?![a-z])", re.IGNORECASE)
MODULES = sorted([*(ROOT / "budget" / "runner").glob("*.py"), *(ROOT / "budget" / "sweeps").glob("*.py")])


def _docstrings(tree: ast.AST) -> set[int]:
    ids = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                    and isinstance(body[0].value.value, str):
                ids.add(id(body[0].value))
    return ids


def _table_nodes(tree: ast.AST) -> set[int]:
    """The nodes of registry.py's ``REGISTRY = (...)`` table."""
    ids = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if any(isinstance(t, ast.Name) and t.id == "REGISTRY" for t in targets):
                ids.update(id(n) for n in ast.walk(node))
    return ids


def _mentions(path: Path, root: Path = ROOT) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    skip = _docstrings(tree) | (_table_nodes(tree) if path.name == "registry.py" else set())
    found = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        texts = []
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            texts.append(node.value)
        elif isinstance(node, ast.Name):
            texts.append(node.id)
        elif isinstance(node, ast.Attribute):
            texts.append(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            texts.append(node.name)
        elif isinstance(node, ast.arg):
            texts.append(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:
            texts.append(node.arg)
        elif isinstance(node, ast.alias):
            texts.append(node.name)
        for t in texts:
            # identifiers: split at underscores and dots, so check_camera_geometry counts
            for m in _WORD.finditer(t.replace("_", " ")):
                found.append(f"{path.relative_to(root)}:{getattr(node, 'lineno', '?')}: {m.group(0)!r} in {t!r}")
    return found


def test_scan_sees_the_packages():
    names = {p.name for p in MODULES}
    assert {"registry.py", "run.py", "executors.py", "spec.py", "evaluate.py"} <= names


@pytest.mark.parametrize("path", MODULES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_study_named_outside_the_registry_table(path):
    assert _mentions(path) == []


def test_scan_finds_a_mention(tmp_path):
    """The scan is not blind: a planted name in code (not in a docstring) is found."""
    f = tmp_path / "m.py"
    f.write_text('"""The starcam study (prose: not scanned)."""\n\nKIND = {"camera": 1}\n\n'
                 'def check_whiskbroom_x():\n    """whiskbroom"""\n', encoding="utf-8")
    found = sorted(_mentions(f, tmp_path))
    assert found == ["m.py:3: 'camera' in 'camera'", "m.py:5: 'whiskbroom' in 'check_whiskbroom_x'"]
