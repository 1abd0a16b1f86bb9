"""Each class's truth is computed without the estimator's own model (point 8).

The guard reads the source (``ast``), since budget/starcam/truth.py binds its imports when
it loads: replacing the estimators in their module at test time would not show that the
truth never calls one. Checked in truth.py, inside functions too, and in every function of
the ``budget`` package that truth.py imports, followed through what those call in their own
module and import in turn: no import of budget.starcam.estimators (nor of a name it
exports), no use of the protocol-level estimate() or the lab's spectral model
(spectral_design, lab_spectral_scenario), no dynamic import. Plus independent references
for the LSFE-S truth.
"""

from __future__ import annotations

import ast
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

import budget.starcam.estimators as E
import budget.starcam.protocols as P
from budget.starcam import truth as T
from simcam import spectra
from simcam.starcam.render import StarCamera
from simcam.starcam.scenario import from_dict
import tomllib

from tiny_camera import TINY

_ESTIMATOR_MODULE = "budget.starcam.estimators"
#: what a truth must not name: the estimators' exports and the protocol's estimator model
_FORBIDDEN_NAMES = frozenset(E.__all__) | {"estimate", "spectral_design", "lab_spectral_scenario"}
_DYNAMIC = {"importlib", "__import__", "import_module", "exec", "eval"}


def _source_tree(module: str) -> ast.Module:
    origin = importlib.util.find_spec(module).origin
    return ast.parse(Path(origin).read_text(), filename=origin)


def _absolute(module: str | None, level: int, here: str) -> str:
    if not level:
        return module or ""
    base = here.split(".")[: -level] if not here.endswith("__init__") else here.split(".")[: -level + 1]
    return ".".join(base + ([module] if module else []))


def _violations(node: ast.AST, here: str) -> tuple[list[str], list[tuple[str, str]]]:
    """What ``node`` (a module or a function) does that a truth must not, and the
    ``(module, name)`` of the ``budget`` functions it imports (to be followed)."""
    bad, follow = [], []
    for n in ast.walk(node):
        if isinstance(n, ast.Import):
            for a in n.names:
                if (a.name == _ESTIMATOR_MODULE or a.name.startswith(_ESTIMATOR_MODULE + ".")
                        or a.name in _DYNAMIC):
                    bad.append(f"{here}:{n.lineno}: import {a.name}")
        elif isinstance(n, ast.ImportFrom):
            mod = _absolute(n.module, n.level, here)
            for a in n.names:
                full = f"{mod}.{a.name}"
                if (mod == _ESTIMATOR_MODULE or mod.startswith(_ESTIMATOR_MODULE + ".")
                        or full == _ESTIMATOR_MODULE or a.name in _FORBIDDEN_NAMES or mod in _DYNAMIC):
                    bad.append(f"{here}:{n.lineno}: from {mod} import {a.name}")
                elif mod.split(".")[0] == "budget":
                    follow.append((mod, a.name))
        elif isinstance(n, ast.Name) and (n.id in _FORBIDDEN_NAMES or n.id in _DYNAMIC):
            bad.append(f"{here}:{n.lineno}: uses {n.id}")
        elif isinstance(n, ast.Attribute) and (n.attr in _FORBIDDEN_NAMES or n.attr in _DYNAMIC):
            bad.append(f"{here}:{n.lineno}: uses .{n.attr}")
    return bad, follow


def _audit(module: str, name: str | None, seen: set) -> list[str]:
    """Violations in ``module`` (all of it when ``name`` is None, else its top-level
    ``name`` and, transitively, the module-level functions it calls and the ``budget``
    functions it imports)."""
    if (module, name) in seen:
        return []
    seen.add((module, name))
    tree = _source_tree(module)
    if name is None:
        bad, follow = _violations(tree, module)
    else:
        defs = {d.name: d for d in tree.body if isinstance(d, (ast.FunctionDef, ast.ClassDef))}
        if name in defs:
            node = defs[name]
            bad, follow = _violations(node, f"{module}.{name}")
            called = {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} & set(defs)
            follow += [(module, c) for c in called if c != name]
        else:
            # not defined here: a re-export (follow the module's own import of it) or a submodule
            bad, follow = [], []
            for n in tree.body:
                if isinstance(n, ast.ImportFrom) and any((a.asname or a.name) == name for a in n.names):
                    orig = next(a.name for a in n.names if (a.asname or a.name) == name)
                    follow.append((_absolute(n.module, n.level, module), orig))
            if not follow:
                try:
                    sub = importlib.util.find_spec(f"{module}.{name}")
                except ModuleNotFoundError:  # ``module`` is not a package: a constant or class
                    sub = None
                if sub is not None:
                    follow.append((f"{module}.{name}", None))
    for mod, nm in follow:
        bad += _audit(mod, nm, seen)
    return bad


def test_truth_module_never_reaches_an_estimator():
    assert _audit("budget.starcam.truth", None, set()) == []


def test_the_import_guard_sees_imports_inside_functions_and_through_helpers():
    """The guard itself can fail: an estimator imported inside a function, the estimator
    module imported as a name, the protocol's estimate() reached through a module alias, and
    a package function that calls the estimators (protocols.estimate, followed from an
    import of it) are all reported."""
    inside = "def t():\n    from budget.starcam.estimators import temporal_error\n    return temporal_error\n"
    assert _violations(ast.parse(inside), "fake")[0]
    assert _violations(ast.parse("from budget.starcam import estimators\n"), "fake")[0]
    assert _violations(ast.parse("import budget.starcam.estimators.hsfe\n"), "fake")[0]
    alias = "import budget.starcam.protocols as P\ndef t():\n    return P.estimate()\n"
    assert _violations(ast.parse(alias), "fake")[0]
    assert _violations(ast.parse("import importlib\n"), "fake")[0]
    # a helper of the package is followed into its module: protocols.estimate imports the
    # estimators inside its body
    assert _audit("budget.starcam.protocols", "estimate", set())
    assert _violations(ast.parse("from budget.starcam.protocols import make_plan\n"), "fake")[1] == [
        ("budget.starcam.protocols", "make_plan")]


@pytest.fixture(scope="module")
def cam():
    return StarCamera(from_dict(tomllib.loads(TINY)))


@pytest.mark.parametrize("cls", ["te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2"])
def test_each_truth_computes(cam, cls):
    scn = cam.scenario
    t = {"te": lambda: T.te_truth(cam, frames=20, seed=1),
         "hsfe": lambda: T.hsfe_truth(cam, frames=8, seed=1),
         "lsfe_s": lambda: T.lsfe_s_truth(cam),
         "lsfe_c1": lambda: T.lsfe_c1_truth(cam),
         "lsfe_c2": lambda: T.lsfe_c2_truth(scn)}[cls]()
    assert math.isfinite(t.x_px) and math.isfinite(t.y_px) and t.se_x_px >= 0


def _mean_wavelength_nm(st, scn):
    """Electron-weighted mean wavelength of a blackbody star through the true QE and optics,
    by trapezoidal quadrature on a 1 nm grid (independent of the render grid and of
    simcam.starcam.sources)."""
    wl = np.arange(scn.render.wavelength_min_nm, scn.render.wavelength_max_nm + 0.5, 1.0)
    q = scn.detector.qe
    qe = spectra.cmos_qe_array(wavelength_nm=wl, peak_qe=q.peak_qe, peak_nm=q.peak_nm,
                               blue_cutoff_nm=q.blue_cutoff_nm, red_cutoff_nm=q.red_cutoff_nm)
    flux = spectra.star_photon_flux_per_nm(v_mag=0.0, temperature_k=spectra.star_teff_k(spectral_type=st),
                                           wavelength_nm=wl)
    w = flux * qe
    return np.trapezoid(w * wl, wl) / np.trapezoid(w, wl)


def test_lsfe_s_truth_for_uniform_linear_colour_is_c_times_the_population_sd():
    """Uniform lateral colour c px/nm, no radial term: a star is displaced by c (lambda_bar -
    lambda_ref), so about the population mean the rms is |c| sd(lambda_bar) (ddof 0) at every
    field point. The render grid (10 nm) against the 1 nm quadrature differ by < 0.5 %."""
    c = 6e-4
    scn = from_dict({"optics": {"lateral_colour": {"radial_px_per_nm": [], "uniform_x_px_per_nm": [c],
                                                             "uniform_y_px_per_nm": []}}})
    t = T.lsfe_s_truth(StarCamera(scn))
    lam = np.array([_mean_wavelength_nm(st, scn) for st in scn.validation.lsfe_spectral_types])
    assert t.x_px == pytest.approx(c * lam.std(), rel=5e-3)
    assert t.y_px < 1e-12


def test_lab_knowledge_is_the_lab_s_not_the_simulator_s():
    """With every stated error 0 the lab's effective wavelengths equal the quadrature of the
    true spectra (to the render grid's 0.5 %); with the default stated errors they differ
    (the QE peak moved by 20 nm and Teff by 3 % shift the mean wavelengths by nm)."""
    zero = {"qe_peak_nm_error": 0.0, "filter_center_nm_error": 0.0, "filter_width_nm_error": 0.0,
            "lamp_temperature_k_error": 0.0, "star_teff_fraction_error": 0.0}
    exact = from_dict({"lab": {"knowledge": zero}})
    d0 = P.spectral_design(exact)
    lam = np.array([_mean_wavelength_nm(st, exact) for st in exact.validation.lsfe_spectral_types])
    np.testing.assert_allclose(d0["star_wavelengths_nm"], lam, rtol=5e-3)
    assert d0["calibration_wavelength_nm"] == pytest.approx(np.mean(d0["star_wavelengths_nm"]), rel=1e-12)
    d1 = P.spectral_design(from_dict({}))
    assert np.max(np.abs(np.array(d1["star_wavelengths_nm"]) - d0["star_wavelengths_nm"])) > 1.0


def test_embedded_noisy_scenario_is_the_default_with_the_seed_s_noise():
    """`embedded:seed000_noisy` is the default camera and lab with three noise values
    changed (source V, PRNU, DSNU); an unknown embedded name is a scenario error."""
    from simcam.infra.errors import ScenarioError
    from simcam.starcam.scenario import default, load

    noisy = load("embedded:seed000_noisy")
    base = default()
    assert load("embedded:default") == base
    assert noisy.lab.source.match_v_mag > base.lab.source.match_v_mag
    assert noisy.detector.prnu_rms > base.detector.prnu_rms and noisy.detector.dsnu_rms_e > base.detector.dsnu_rms_e
    a = noisy.model_dump(mode="json")
    b = base.model_dump(mode="json")
    for key in ("name",):
        a.pop(key), b.pop(key)
    a["detector"].pop("prnu_rms"), b["detector"].pop("prnu_rms")
    a["detector"].pop("dsnu_rms_e"), b["detector"].pop("dsnu_rms_e")
    a["lab"]["source"].pop("match_v_mag"), b["lab"]["source"].pop("match_v_mag")
    assert a == b
    with pytest.raises(ScenarioError, match="no embedded scenario 'nope'"):
        load("embedded:nope")
