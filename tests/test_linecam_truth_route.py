"""The line camera's truths share nothing with the lab's model (issue #33 item 2): the world's
camera (simcam/linecam/camera.py and what it imports) imports nothing of the lab, the study's
truths never pass through the lab's nominal model or its calibrated parameters, and the world's
design look angles are the analytic pinhole's."""

from __future__ import annotations

import ast
import importlib.util
from pathlib import Path

import numpy as np

from budget.linecam.model import NominalCamera, los_angles, los_grid
from budget.linecam.study import STUDY
from simcam.linecam.camera import camera_truth
from simcam.linecam.scenario import PARAMETERS

ROOT = Path(__file__).resolve().parents[1]
#: dynamic imports and code execution (importlib.resources, which reads data files, is not one)
_DYNAMIC = {"importlib.import_module", "__import__", "exec", "eval"}


def _imports(module: str) -> set[str]:
    """What ``module`` imports (inside functions too): each module and each ``module.name``
    it imports from, and the dynamic calls it makes (:data:`_DYNAMIC`)."""
    path = Path(importlib.util.find_spec(module).origin)
    out = set()
    for n in ast.walk(ast.parse(path.read_text())):
        if isinstance(n, ast.Import):
            out |= {a.name for a in n.names}
        elif isinstance(n, ast.ImportFrom):
            base = module.rsplit(".", n.level)[0] if n.level else ""
            mod = ".".join(p for p in (base, n.module) if p)
            out.add(mod)
            out |= {f"{mod}.{a.name}" for a in n.names}
        elif isinstance(n, ast.Name) and n.id in _DYNAMIC:
            out.add(n.id)
    return out


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ModuleNotFoundError, ValueError):
        return False


def test_the_worlds_camera_imports_nothing_of_the_lab():
    seen, todo, bad = set(), ["simcam.linecam.camera"], []
    while todo:
        mod = todo.pop()
        if mod in seen:
            continue
        seen.add(mod)
        for name in _imports(mod):
            if name.split(".")[0] == "budget" or name in _DYNAMIC:
                bad.append(f"{mod}: {name}")
            elif (name.startswith("simcam.linecam") or name == "simcam.distortion") and _is_module(name):
                todo.append(name)
    assert "simcam.linecam.effects" in seen and not bad, bad


def test_study_truths_never_use_the_labs_model():
    """In ``trial_result`` no truth is computed from the lab's nominal field (``los_before``),
    the calibrated parameters (``theta``) or a stated sigma."""
    tree = ast.parse((ROOT / "budget/linecam/study.py").read_text())
    fn = next(n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.name == "trial_result")
    forbidden = {"nominal", "nominal_along", "nominal_across", "theta", "theta_sd", "sigma", "sigma_along",
                 "sigma_across", "los_before"}
    seen = 0
    for n in ast.walk(fn):
        if (isinstance(n, ast.Assign) and isinstance(n.targets[0], ast.Subscript)
                and isinstance(n.targets[0].value, ast.Name) and n.targets[0].value.id == "truths"):
            seen += 1
            names = {m.id for m in ast.walk(n.value) if isinstance(m, ast.Name)}
            names |= {m.attr for m in ast.walk(n.value) if isinstance(m, ast.Attribute)}
            assert not names & forbidden, (n.lineno, names & forbidden)
    assert seen >= 5


def test_design_look_angles_are_the_pinholes_and_the_labs():
    """Zero errors: along = atan(x_line / f) and across = atan(y / f), y = (s - (n - 1)/2) p
    (one rotation and one atan2 of rounding, 1e-15 rad); the lab's model at zero parameters gives
    the same field by its own code (to 1e-13 rad, a few ulps of its px-based arithmetic)."""
    sc = STUDY.load_scenario(None)
    cam = sc.camera
    grid = los_grid(sc)
    truth = camera_truth(sc.model_copy(update={"world": sc.world.model_copy(
        update={"effects": sc.world.effects.ideal()})}), np.zeros(len(PARAMETERS)))
    along, across = truth.los_angles(grid)
    y = (grid - 0.5 * (cam.n_pixels - 1)) * cam.pitch_mm
    np.testing.assert_allclose(across, np.arctan(y / cam.focal_length_mm), rtol=0, atol=1e-15)
    np.testing.assert_allclose(along, np.arctan(cam.x_line_mm / cam.focal_length_mm), rtol=0, atol=1e-15)
    lab_along, lab_across = los_angles(NominalCamera.from_model(cam), np.zeros(len(PARAMETERS)), grid)
    np.testing.assert_allclose(lab_along, along, rtol=0, atol=1e-13)
    np.testing.assert_allclose(lab_across, across, rtol=0, atol=1e-13)
