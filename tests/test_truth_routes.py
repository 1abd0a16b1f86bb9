"""Each class's truth is computed without the estimator's own model (issue 12, point 8).

Every public estimator of budget.starcam.estimators, the protocol-level estimate() and the lab's
spectral model (spectral_design, lab_spectral_scenario) are replaced by functions that
fail; each truth must still be computed. Plus independent references for the LSFE-S truth.
"""

from __future__ import annotations

import math

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


def _forbid(monkeypatch):
    def boom(*a, **k):
        raise AssertionError("a truth used the estimator's own model")

    for name in E.__all__:
        if callable(getattr(E, name)) and not isinstance(getattr(E, name), type):
            monkeypatch.setattr(E, name, boom)
    for name in ("estimate", "spectral_design", "lab_spectral_scenario"):
        monkeypatch.setattr(P, name, boom)


@pytest.fixture(scope="module")
def cam():
    return StarCamera(from_dict(tomllib.loads(TINY)))


@pytest.mark.parametrize("cls", ["te", "hsfe", "lsfe_s", "lsfe_c1", "lsfe_c2"])
def test_truth_does_not_use_the_estimators(monkeypatch, cam, cls):
    _forbid(monkeypatch)
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
    from simcam.starcam.scenario import ScenarioError, default, load

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
