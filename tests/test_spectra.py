"""Tests of simcam.spectra against independent references.

References used (never the module's own output alone):
* Planck law: astropy.modeling.models.BlackBody with astropy constants, and
  colour-science's planck_law (CIE constants), both converted to photons here.
* Total photon radiance: 4 zeta(3) k^3 T^3 / (h^3 c^2) with astropy constants versus
  scipy.integrate.quad of the module's spectral radiance.
* Teff: values of Pecaut & Mamajek (2013) Table 5 typed here; the Sun's nominal
  Teff (IAU 2015 Resolution B3, 5772 K) for G2V.
* V normalisation: the Bessell, Castelli & Plez (1998) zero point 363.1e-11
  erg s^-1 cm^-2 A^-1 converted to photons here with astropy units, and quad of the
  band integrals on the Bessell (1990) table.
* Filters, QE: numerical root finding of the half maximum; analytic Gaussian integrals.
* Chain: scipy.integrate.quad of the analytic integrand.
* Lamp: colour-science's CIE standard illuminant A formula.
"""

from __future__ import annotations

import math

import astropy.constants as ac
import astropy.units as u
import colour
import numpy as np
import pytest
from astropy.modeling.models import BlackBody
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import integrate, optimize, special

from simcam import spectra as sp

H = ac.h.value
C = ac.c.value
K = ac.k_B.value

def test_si_defining_constants_equal_scipy_and_astropy():
    """The four SI 2019 defining constants written in simcam.spectra are the exact values
    scipy.constants and astropy.constants hold (the same decimal literals, so equal floats)."""
    from scipy import constants as sc

    assert (sp.H_PLANCK_J_S, sp.C_LIGHT_M_S, sp.K_BOLTZMANN_J_K, sp.ELEMENTARY_CHARGE_C) == (
        sc.h, sc.c, sc.k, sc.e)
    assert (sp.H_PLANCK_J_S, sp.C_LIGHT_M_S, sp.K_BOLTZMANN_J_K, sp.ELEMENTARY_CHARGE_C) == (
        H, C, K, ac.e.si.value)


# Zero point of V = 0 (Bessell, Castelli & Plez 1998, Table A2), converted here.
F0_V = (363.1e-11 * u.erg / (u.s * u.cm**2 * u.AA)).to(u.W / (u.m**2 * u.nm)).value


def photons_per_nm_at(lam_nm: float, f_lambda_w_m2_nm: float) -> float:
    return f_lambda_w_m2_nm * lam_nm * 1e-9 / (H * C)


# ----------------------------------------------------------------------------- grid


def test_wavelength_grid_inclusive_and_uniform():
    g = sp.wavelength_grid_nm(start_nm=400.0, end_nm=700.0, step_nm=0.5)
    # the end point is start + 600 * step: one multiply and one add, each within half an ulp
    assert g[0] == 400.0 and g[-1] == pytest.approx(700.0, rel=4 * np.finfo(float).eps) and g.size == 601
    np.testing.assert_allclose(np.diff(g), 0.5, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(start_nm=400, end_nm=700, step_nm=7), "step_nm"),
        (dict(start_nm=700, end_nm=400, step_nm=1), "end_nm"),
        (dict(start_nm=-1, end_nm=400, step_nm=1), "start_nm"),
        (dict(start_nm=400, end_nm=700, step_nm=0), "step_nm"),
        (dict(start_nm=float("nan"), end_nm=700, step_nm=1), "start_nm"),
    ],
)
def test_wavelength_grid_rejects_bad_input(kwargs, name):
    with pytest.raises(sp.SpectraError, match=name):
        sp.wavelength_grid_nm(**kwargs)


def test_spectra_error_is_value_error():
    assert issubclass(sp.SpectraError, ValueError)


# ----------------------------------------------------------------------------- Planck


@pytest.mark.parametrize("temperature_k", [2856.0, 5770.0, 9700.0, 41500.0])
def test_planck_photon_radiance_matches_astropy(temperature_k):
    lam = np.linspace(200.0, 2500.0, 47)
    bb = BlackBody(temperature=temperature_k * u.K, scale=1.0 * u.W / (u.m**2 * u.nm * u.sr))
    energy = bb(lam * u.nm)
    expected = (energy * lam * u.nm / (ac.h * ac.c)).to(1 / (u.s * u.m**2 * u.nm * u.sr)).value
    got = sp.planck_photon_radiance(wavelength_nm=lam, temperature_k=temperature_k)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_planck_photon_radiance_matches_colour_planck_law():
    # colour uses the CIE constants c1 = 3.741771e-16, c2 = 1.4388e-2 (rounded), so
    # agreement is limited to ~x * 1.6e-5 with x = c2 / (lambda T) < 30 here.
    lam = np.linspace(300.0, 1100.0, 81)
    for t in (3000.0, 6000.0, 20000.0):
        energy_w_m2_sr_m = colour.colorimetry.planck_law(lam * 1e-9, t)
        expected = energy_w_m2_sr_m * 1e-9 / (H * C / (lam * 1e-9))
        got = sp.planck_photon_radiance(wavelength_nm=lam, temperature_k=t)
        np.testing.assert_allclose(got, expected, rtol=1e-3)


def test_planck_photon_radiance_broadcasts_and_handles_overflow():
    lam = np.array([[30.0], [1000.0]])  # x = hc/(lambda k T) = 1600 at 30 nm, 300 K
    out = sp.planck_photon_radiance(wavelength_nm=lam, temperature_k=np.array([300.0, 6000.0]))
    assert out.shape == (2, 2)
    assert out[0, 0] == 0.0  # exp overflow -> exactly zero, no warning
    assert np.all(np.isfinite(out))


@pytest.mark.parametrize("temperature_k", [2856.0, 5770.0, 30000.0])
def test_total_photon_radiance_quad(temperature_k):
    analytic = 4.0 * special.zeta(3.0) * K**3 * temperature_k**3 / (H**3 * C**2)

    # integrate in ln(lambda): integral f dlambda = integral f lambda dln(lambda)
    def integrand(ln_lam):
        lam = math.exp(ln_lam)
        return float(sp.planck_photon_radiance(wavelength_nm=lam, temperature_k=temperature_k)) * lam

    # 1 nm .. 1 m: the Rayleigh-Jeans tail beyond 1 m is < 1e-9 of the total
    val, err = integrate.quad(integrand, math.log(1.0), math.log(1e9), limit=400,
                              epsabs=0, epsrel=1e-11)
    assert val == pytest.approx(analytic, rel=1e-7)
    assert sp.total_photon_radiance(temperature_k=temperature_k) == pytest.approx(analytic, rel=1e-12)


@pytest.mark.parametrize("bad", [0.0, -5.0, float("nan")])
def test_planck_rejects_bad_temperature(bad):
    with pytest.raises(sp.SpectraError, match="temperature_k"):
        sp.planck_photon_radiance(wavelength_nm=[500.0], temperature_k=bad)


def test_planck_rejects_bad_wavelength():
    with pytest.raises(sp.SpectraError, match="wavelength_nm"):
        sp.planck_photon_radiance(wavelength_nm=[0.0, 500.0], temperature_k=5000.0)


# ----------------------------------------------------------------------------- Teff

# Pecaut & Mamajek (2013) Table 5 / Mamajek online table (v2017.10.19), typed here.
PM13 = {
    "O5V": 41500.0, "O9V": 32500.0, "B0V": 31500.0, "B5V": 15700.0, "A0V": 9700.0,
    "A5V": 8080.0, "F0V": 7220.0, "F5V": 6510.0, "G0V": 5920.0, "G2V": 5770.0,
    "K0V": 5280.0, "K5V": 4410.0, "M0V": 3870.0, "M5V": 3030.0,
}


@pytest.mark.parametrize(("spt", "teff"), sorted(PM13.items()))
def test_star_teff_published_values(spt, teff):
    assert sp.star_teff_k(spectral_type=spt) == teff


def test_g2v_is_near_nominal_sun():
    # IAU 2015 Resolution B3 nominal solar Teff 5772 K
    assert abs(sp.star_teff_k(spectral_type="G2V") - 5772.0) < 10.0


def test_star_teff_interpolates_and_defaults_to_dwarf():
    g2, g3 = PM13["G2V"], 5720.0
    assert sp.star_teff_k(spectral_type="G2.5V") == pytest.approx((g2 + g3) / 2)
    assert sp.star_teff_k(spectral_type="G2") == g2
    # K9V (3940 K) -> M0V (3870 K): the K/M boundary is continuous
    assert sp.star_teff_k(spectral_type="K9.5V") == pytest.approx(3905.0)
    table = sp.spectral_type_table()
    assert list(table)[0] == "O3V" and list(table)[-1] == "M9.5V"
    assert np.all(np.diff(list(table.values())) < 0)


@pytest.mark.parametrize("spt", ["X5V", "G2III", "O2V", "M9.7V", "G10V", "", "sun"])
def test_star_teff_unknown_type(spt):
    with pytest.raises(sp.SpectraError, match="spectral_type"):
        sp.star_teff_k(spectral_type=spt)


def test_star_teff_rejects_non_string():
    with pytest.raises(sp.SpectraError, match="spectral_type"):
        sp.star_teff_k(spectral_type=5770)


# ----------------------------------------------------------------------------- V band


def _bessell_v_table():
    lam = np.arange(470.0, 701.0, 10.0)
    resp = sp.bessell_v_response(wavelength_nm=lam)
    return lam, resp


def test_bessell_v_table_transcription():
    lam, resp = _bessell_v_table()
    # Bessell (1990) Table 2, V: a few values typed here (no arithmetic: exact look-ups)
    assert resp[lam == 500.0][0] == 0.458
    assert resp[lam == 530.0][0] == 1.0
    assert resp[lam == 600.0][0] == 0.359
    assert resp[0] == 0.0 and resp[-1] == 0.0
    # photon-weighted mean wavelength of the Bessell V curve is ~551 nm
    mean = np.sum(lam * resp) / np.sum(resp)
    assert 545.0 < mean < 557.0
    sd = sp.bessell_v_sd()
    assert isinstance(sd, colour.SpectralDistribution)
    np.testing.assert_array_equal(sd.values, resp)


def test_v0_a0v_photon_flux_at_550nm():
    # documented: V = 0 -> 3.631e-11 W m^-2 nm^-1 -> 1.005e8 photons s^-1 m^-2 nm^-1
    # at 550 nm (~1000 photons s^-1 cm^-2 A^-1)
    expected = photons_per_nm_at(550.0, F0_V)
    assert expected == pytest.approx(1.005e8, rel=1e-3)
    teff = sp.star_teff_k(spectral_type="A0V")
    got = sp.star_photon_flux_per_nm(v_mag=0.0, temperature_k=teff, wavelength_nm=[550.0])[0]
    assert got == pytest.approx(expected, rel=0.03)
    per_cm2_A = got * 1e-4 * 0.1
    assert per_cm2_A == pytest.approx(1000.0, rel=0.03)


def test_v_normalisation_band_integral_quad():
    lam_tab, resp_tab = _bessell_v_table()

    def s_v(x):
        return float(np.interp(x, lam_tab, resp_tab))

    ref, _ = integrate.quad(lambda x: photons_per_nm_at(x, F0_V) * s_v(x), 470, 700,
                            points=lam_tab[1:-1], limit=200, epsrel=1e-10)
    assert sp.v_zero_point_photon_rate() == pytest.approx(ref, rel=1e-6)
    for v_mag, t in ((0.0, 9700.0), (7.5, 5770.0), (3.2, 3030.0), (-1.0, 31500.0)):
        star, _ = integrate.quad(
            lambda x: float(sp.star_photon_flux_per_nm(v_mag=v_mag, temperature_k=t,
                                                       wavelength_nm=x)) * s_v(x),
            470, 700, points=lam_tab[1:-1], limit=200, epsrel=1e-10)
        assert star == pytest.approx(10 ** (-0.4 * v_mag) * ref, rel=1e-6)


@given(v1=st.floats(-2, 15), dv=st.floats(-5, 5), t=st.floats(2500, 40000))
@settings(max_examples=25, deadline=None)
def test_magnitude_scaling_exact(v1, dv, t):
    lam = np.linspace(350.0, 1050.0, 15)
    a = sp.star_photon_flux_per_nm(v_mag=v1, temperature_k=t, wavelength_nm=lam)
    b = sp.star_photon_flux_per_nm(v_mag=v1 + dv, temperature_k=t, wavelength_nm=lam)
    np.testing.assert_allclose(b / a, 10 ** (-0.4 * dv), rtol=1e-12)


def test_star_spectrum_shape_is_planck():
    lam = np.linspace(300.0, 1100.0, 9)
    f = sp.star_photon_flux_per_nm(v_mag=5.0, temperature_k=4410.0, wavelength_nm=lam)
    bb = BlackBody(temperature=4410 * u.K, scale=1.0 * u.W / (u.m**2 * u.nm * u.sr))(lam * u.nm).value
    ratio = f / (bb * lam)
    np.testing.assert_allclose(ratio / ratio[0], 1.0, rtol=1e-10)


def test_star_sd_and_v_band_rate_consistent():
    sd = sp.star_photon_flux_sd(v_mag=2.0, temperature_k=5770.0, start_nm=400, end_nm=800, step_nm=1)
    assert isinstance(sd, colour.SpectralDistribution)
    rate = sp.v_band_photon_rate(photon_flux_per_nm=sd.values, wavelength_nm=sd.wavelengths)
    assert rate == pytest.approx(10 ** (-0.8) * sp.v_zero_point_photon_rate(), rel=1e-5)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(v_mag=float("nan"), temperature_k=5000.0), "v_mag"),
        (dict(v_mag=1.0, temperature_k=-3.0), "temperature_k"),
    ],
)
def test_star_flux_rejects_bad_input(kwargs, name):
    with pytest.raises(sp.SpectraError, match=name):
        sp.star_photon_flux_per_nm(wavelength_nm=[500.0], **kwargs)


# ----------------------------------------------------------------------------- filters


def _half_max_crossings(center, width, shape, edge, peak):
    def f(x):
        return float(sp.bandpass_array(wavelength_nm=x, center_nm=center, width_nm=width,
                                       shape=shape, edge_nm=edge, peak_transmission=peak)) - peak / 2

    lo = optimize.brentq(f, center - width / 2 - edge, center, xtol=1e-12)
    hi = optimize.brentq(f, center, center + width / 2 + edge, xtol=1e-12)
    return lo, hi


@pytest.mark.parametrize("shape", ["raised_cosine", "erf"])
@pytest.mark.parametrize("center", [500.0, 600.0, 800.0])
def test_lab_filters_fwhm_exact(shape, center):
    lo, hi = _half_max_crossings(center, 100.0, shape, 10.0, 0.9)
    assert hi - lo == pytest.approx(100.0, abs=1e-8)
    assert (hi + lo) / 2 == pytest.approx(center, abs=1e-8)
    peak = sp.bandpass_array(wavelength_nm=[center], center_nm=center, width_nm=100.0,
                             shape=shape, edge_nm=10.0, peak_transmission=0.9)[0]
    assert peak == pytest.approx(0.9, rel=1e-12)


@given(
    center=st.floats(350, 950), width=st.floats(10, 200), frac=st.floats(0.02, 0.55),
    shape=st.sampled_from(["raised_cosine", "erf"]), peak=st.floats(0.05, 1.0),
)
@settings(max_examples=25, deadline=None)
def test_fwhm_property(center, width, frac, shape, peak):
    edge = frac * width
    lo, hi = _half_max_crossings(center, width, shape, edge, peak)
    assert hi - lo == pytest.approx(width, rel=1e-9, abs=1e-8)


@pytest.mark.parametrize("shape", ["raised_cosine", "erf"])
def test_edge_10_90_width(shape):
    c, w, e = 600.0, 100.0, 12.0

    def level(q):
        return optimize.brentq(
            lambda x: float(sp.bandpass_array(wavelength_nm=x, center_nm=c, width_nm=w,
                                              shape=shape, edge_nm=e)) - q,
            c, c + w, xtol=1e-12)

    # erf: exact for an isolated edge; the opposite edge is 100 nm (20 sigma) away
    assert level(0.1) - level(0.9) == pytest.approx(e, rel=1e-6)


def test_raised_cosine_flat_top_and_compact_support():
    lam = np.linspace(400.0, 800.0, 4001)
    t = sp.bandpass_array(wavelength_nm=lam, center_nm=600.0, width_nm=100.0,
                          shape="raised_cosine", edge_nm=10.0, peak_transmission=0.85)
    r = 10.0 / ((math.acos(-0.8) - math.acos(0.8)) / math.pi)
    inside = np.abs(lam - 600.0) <= 50.0 - r / 2
    outside = np.abs(lam - 600.0) >= 50.0 + r / 2
    # flat top: peak_transmission times a cosine factor of 1 (a few roundings); outside the
    # band the curve is set to zero, exactly
    np.testing.assert_allclose(t[inside], 0.85, rtol=8 * np.finfo(float).eps, atol=0)
    assert np.all(t[outside] == 0.0)
    assert np.all((t >= 0) & (t <= 0.85))


@pytest.mark.parametrize("shape", ["raised_cosine", "erf"])
def test_bandpass_sd_matches_array(shape):
    sd = sp.bandpass_sd(center_nm=800.0, width_nm=100.0, shape=shape, edge_nm=8.0,
                        peak_transmission=0.9)
    assert isinstance(sd, colour.SpectralDistribution)
    arr = sp.bandpass_array(wavelength_nm=sd.wavelengths, center_nm=800.0, width_nm=100.0,
                            shape=shape, edge_nm=8.0, peak_transmission=0.9)
    np.testing.assert_allclose(sd.values, arr, rtol=0, atol=1e-15)
    assert sd.values[0] < 1e-5 and sd.values[-1] < 1e-5
    lam = np.array([600.0, 800.0, 1200.0])
    np.testing.assert_allclose(sp.sd_to_array(sd=sd, wavelength_nm=lam), [0.0, 0.9, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(shape="boxcar"), "shape"),
        (dict(edge_nm=80.0), "edge_nm"),
        (dict(peak_transmission=1.2), "peak_transmission"),
        (dict(width_nm=-1.0), "width_nm"),
    ],
)
def test_bandpass_rejects_bad_input(kwargs, name):
    args = dict(wavelength_nm=[600.0], center_nm=600.0, width_nm=100.0)
    args.update(kwargs)
    with pytest.raises(sp.SpectraError, match=name):
        sp.bandpass_array(**args)


# ----------------------------------------------------------------------------- QE


QE_ARGS = dict(peak_qe=0.6, peak_nm=550.0, blue_cutoff_nm=400.0, red_cutoff_nm=800.0)


def test_qe_shape_points():
    qe = sp.cmos_qe_array(wavelength_nm=[400.0, 550.0, 800.0, 1200.0], **QE_ARGS)
    np.testing.assert_allclose(qe, [0.3, 0.6, 0.3, 0.0], rtol=1e-12)
    lam = np.linspace(300, 1100, 801)
    q = sp.cmos_qe_array(wavelength_nm=lam, **QE_ARGS)
    assert q.max() <= 0.6 and q.argmax() == 250
    gap_nm = (ac.h * ac.c / (1.12 * u.eV)).to(u.nm).value
    assert sp.cmos_qe_array(wavelength_nm=[gap_nm - 0.01, gap_nm + 0.01], **QE_ARGS)[1] == 0.0


def test_qe_integral_matches_split_gaussian():
    gap_nm = (ac.h * ac.c / (1.12 * u.eV)).to(u.nm).value
    sb = 150.0 / math.sqrt(2 * math.log(2))
    sr = 250.0 / math.sqrt(2 * math.log(2))
    full = 0.6 * math.sqrt(math.pi / 2) * (sb + sr)
    red_tail = 0.6 * sr * math.sqrt(math.pi / 2) * special.erfc((gap_nm - 550.0) / (sr * math.sqrt(2)))
    blue_tail = 0.6 * sb * math.sqrt(math.pi / 2) * special.erfc((550.0 - 1.0) / (sb * math.sqrt(2)))
    val, _ = integrate.quad(lambda x: float(sp.cmos_qe_array(wavelength_nm=x, **QE_ARGS)),
                            1.0, gap_nm, points=[550.0], limit=200, epsrel=1e-11)
    assert val == pytest.approx(full - red_tail - blue_tail, rel=1e-8)
    sd = sp.cmos_qe_sd(**QE_ARGS)
    assert isinstance(sd, colour.SpectralDistribution) and sd.shape.interval == 1.0


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        (dict(peak_qe=1.2), "peak_qe"),
        (dict(peak_qe=0.0), "peak_qe"),
        (dict(blue_cutoff_nm=600.0), "blue_cutoff_nm"),
        (dict(red_cutoff_nm=500.0), "red_cutoff_nm"),
    ],
)
def test_qe_rejects_bad_input(kwargs, name):
    args = dict(QE_ARGS)
    args.update(kwargs)
    with pytest.raises(sp.SpectraError, match=name):
        sp.cmos_qe_array(wavelength_nm=[500.0], **args)


# ----------------------------------------------------------------------------- tables


def test_table_csv_round_trip(tmp_path):
    path = tmp_path / "optics.csv"
    path.write_text("# measured\nwavelength_nm,value\n400,0.70\n600,0.82\n900,0.75\n")
    sd = sp.read_table_csv(path=path)
    np.testing.assert_array_equal(sd.wavelengths, [400.0, 600.0, 900.0])
    got = sp.sd_to_array(sd=sd, wavelength_nm=[500.0, 750.0, 1000.0])
    np.testing.assert_allclose(got, [0.76, 0.785, 0.0], rtol=1e-12)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("wavelength_nm,value\n400,0.7\n600,1.2\n", "value"),
        ("wavelength_nm,value\n600,0.7\n400,0.8\n", "increasing"),
        ("lambda,t\n400,0.7\n600,0.8\n", "header"),
        ("wavelength_nm,value\n400,0.7\n600,abc\n", "not a number"),
        ("wavelength_nm,value\n400,0.7\n", "2 data rows"),
    ],
)
def test_table_csv_errors(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(sp.SpectraError, match=match):
        sp.read_table_csv(path=path)


def test_table_sd_validates():
    with pytest.raises(sp.SpectraError, match="value"):
        sp.table_sd(wavelength_nm=[400, 500], value=[-0.1, 0.5])
    with pytest.raises(sp.SpectraError, match="transmission"):
        sp.flat_transmission_array(wavelength_nm=[500.0], transmission=1.5)
    np.testing.assert_array_equal(sp.flat_transmission_array(wavelength_nm=[400.0, 500.0],
                                                             transmission=0.8), [0.8, 0.8])


# ----------------------------------------------------------------------------- chain


def test_detected_rate_is_product():
    lam = sp.wavelength_grid_nm(start_nm=400, end_nm=500, step_nm=10)
    flux = np.linspace(1.0, 2.0, lam.size)
    qe = np.linspace(0.2, 0.5, lam.size)
    r = sp.detected_electron_rate_per_nm(photon_flux_per_nm=flux, aperture_area_m2=2.0,
                                         transmission=0.5, filter_transmission=0.9, qe=qe,
                                         wavelength_nm=lam)
    np.testing.assert_allclose(r, flux * 2.0 * 0.5 * 0.9 * qe, rtol=1e-15)
    with pytest.raises(sp.SpectraError, match="qe"):
        sp.detected_electron_rate_per_nm(photon_flux_per_nm=flux, aperture_area_m2=2.0,
                                         transmission=0.5, filter_transmission=1.0,
                                         qe=qe[:-1], wavelength_nm=lam)
    with pytest.raises(sp.SpectraError, match="aperture_area_m2"):
        sp.detected_electron_rate_per_nm(photon_flux_per_nm=flux, aperture_area_m2=0.0,
                                         transmission=0.5, filter_transmission=1.0,
                                         qe=qe, wavelength_nm=lam)


@pytest.mark.parametrize("filt", [None, ("raised_cosine", 500.0), ("erf", 600.0),
                                  ("raised_cosine", 800.0)])
def test_electrons_trapezoid_vs_quad(filt):
    lam = sp.wavelength_grid_nm(start_nm=300, end_nm=1100, step_nm=1)
    area = sp.circular_aperture_area_m2(diameter_mm=60.0)
    exposure_s = 0.1

    def ftrans(x):
        if filt is None:
            return np.ones_like(np.asarray(x, float))
        return sp.bandpass_array(wavelength_nm=x, center_nm=filt[1], width_nm=100.0,
                                 shape=filt[0], edge_nm=10.0, peak_transmission=0.9)

    def integrand(x):
        return float(
            sp.star_photon_flux_per_nm(v_mag=7.5, temperature_k=5770.0, wavelength_nm=x)
            * area * 0.8 * ftrans(x) * sp.cmos_qe_array(wavelength_nm=x, **QE_ARGS)
        ) * exposure_s

    points = [550.0] if filt is None else [550.0, filt[1] - 60, filt[1] - 40, filt[1] + 40,
                                           filt[1] + 60]
    ref, _ = integrate.quad(integrand, 300.0, 1100.0, points=points, limit=400, epsrel=1e-10)
    rate = sp.detected_electron_rate_per_nm(
        photon_flux_per_nm=sp.star_photon_flux_per_nm(v_mag=7.5, temperature_k=5770.0,
                                                      wavelength_nm=lam),
        aperture_area_m2=area, transmission=0.8, filter_transmission=ftrans(lam),
        qe=sp.cmos_qe_array(wavelength_nm=lam, **QE_ARGS), wavelength_nm=lam)
    got = sp.electrons_per_exposure(electron_rate_per_nm=rate, wavelength_nm=lam,
                                    exposure_s=exposure_s)
    assert got == pytest.approx(ref, rel=1e-4)  # brief: 1e-4; measured ~4e-9 on a 1 nm grid
    assert got == pytest.approx(ref, rel=1e-6)


def test_normalised_weights():
    lam = np.array([400.0, 410.0, 430.0, 460.0, 500.0])
    rate = np.array([1.0, 2.0, 0.0, 4.0, 3.0])
    w = sp.normalised_weights(electron_rate_per_nm=rate, wavelength_nm=lam)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(w >= 0) and w[2] == 0.0
    # weighted mean wavelength equals the trapezoid ratio integral(l r) / integral(r)
    expected = np.trapezoid(lam * rate, lam) / np.trapezoid(rate, lam)
    assert np.dot(w, lam) == pytest.approx(expected, rel=1e-14)
    with pytest.raises(sp.SpectraError, match="electron_rate_per_nm"):
        sp.normalised_weights(electron_rate_per_nm=np.zeros(5), wavelength_nm=lam)
    with pytest.raises(sp.SpectraError, match="wavelength_nm"):
        sp.normalised_weights(electron_rate_per_nm=rate, wavelength_nm=lam[::-1])


def test_aperture_area():
    assert sp.circular_aperture_area_m2(diameter_mm=60.0) == pytest.approx(math.pi * 0.03**2)
    assert sp.circular_aperture_area_m2(diameter_mm=60.0, obstruction_diameter_mm=20.0) == (
        pytest.approx(math.pi * (0.03**2 - 0.01**2)))
    with pytest.raises(sp.SpectraError, match="obstruction_diameter_mm"):
        sp.circular_aperture_area_m2(diameter_mm=60.0, obstruction_diameter_mm=60.0)


# ----------------------------------------------------------------------------- lamp


def test_lamp_matches_cie_illuminant_a():
    # CIE A: S(l) = 100 (560/l)^5 (exp(1.435e7/(2848*560)) - 1) / (exp(1.435e7/(2848 l)) - 1)
    # (c2 = 1.435e-2 m K). With the CODATA c2 the same curve is a Planckian at
    # T = 2848 * c2_codata / 1.435e-2 (about 2855.5 K).
    t_equiv = 2848.0 * (H * C / K) / 1.435e-2
    shape = colour.SpectralShape(300, 780, 5)
    cie_a = colour.colorimetry.sd_CIE_standard_illuminant_A(shape)
    lam = np.asarray(cie_a.wavelengths, float)
    photons = sp.lamp_photon_spectrum_per_nm(temperature_k=t_equiv, wavelength_nm=lam)
    energy_rel = photons * 560.0 / lam  # photon -> energy spectrum, still 1 at 560 nm
    np.testing.assert_allclose(energy_rel, np.asarray(cie_a.values) / 100.0, rtol=1e-10)
    # 1 at 560 nm up to rounding: the ratio of two evaluations of the Planck formula
    # (scalar and array paths, ~10 rounded operations each, exp's error included) may differ
    # by a few ulp on another machine (1.0000000000000002 was seen), so allow 16 eps.
    assert sp.lamp_photon_spectrum_per_nm(wavelength_nm=[560.0])[0] == pytest.approx(1.0, rel=16 * np.finfo(float).eps, abs=0)


def test_lamp_scaled_matches_star_electrons():
    lam = sp.wavelength_grid_nm(start_nm=350, end_nm=1100, step_nm=1)
    qe = sp.cmos_qe_array(wavelength_nm=lam, **QE_ARGS)
    optics = 0.8
    k = sp.lamp_scale_to_match_star(v_mag=7.5, star_temperature_k=5770.0,
                                    lamp_temperature_k=2856.0, wavelength_nm=lam,
                                    transmission=optics, qe=qe)
    area = sp.circular_aperture_area_m2(diameter_mm=60.0)

    def electrons(flux):
        r = sp.detected_electron_rate_per_nm(photon_flux_per_nm=flux, aperture_area_m2=area,
                                             transmission=optics, filter_transmission=1.0,
                                             qe=qe, wavelength_nm=lam)
        return sp.electrons_per_exposure(electron_rate_per_nm=r, wavelength_nm=lam, exposure_s=0.1)

    star = sp.star_photon_flux_per_nm(v_mag=7.5, temperature_k=5770.0, wavelength_nm=lam)
    lamp = k * sp.lamp_photon_spectrum_per_nm(temperature_k=2856.0, wavelength_nm=lam)
    assert electrons(lamp) == pytest.approx(electrons(star), rel=1e-9)
    # the redder lamp puts more of its matched signal beyond 700 nm than the star
    red = lam > 700
    assert (lamp * qe)[red].sum() / (lamp * qe).sum() > (star * qe)[red].sum() / (star * qe).sum()


# ----------------------------------------------------------------------------- sanity


def test_v75_g2v_electrons_against_independent_quadrature():
    """V = 7.5 G2V, 60 mm aperture, optics 0.8, QE peak 0.6, 0.1 s, on a 1 nm grid over
    300-1100 nm: the package's electrons against the same signal equation written here from
    its definitions and integrated by adaptive quadrature (scipy.integrate.quad), with
    astropy's BlackBody for the star's shape, the Bessell (1990) V table read from the data
    file and linearly interpolated (its definition), the V = 0 flat f_lambda = 3.631e-11
    W m^-2 nm^-1 (BCP98) and the split-Gaussian QE from its formula.

    Tolerance: the package integrates with the trapezoid rule, on 1 nm here (error about
    h^2 / 12 f'' / f ~ (1 nm)^2 / 12 / (100 nm)^2 ~ 1e-5 at most for these smooth spectra,
    whose curvature scale is the QE's 150-250 nm widths) and on 0.1 nm for the V band (its
    table's kinks at the 10 nm knots fall on grid points); the two routes' constants are
    CODATA in both. 2e-5 relative bounds that (the two agree to 3e-7 here). The
    flat-spectrum estimate (photon flux at 550 nm times the QE integral)
    stays as an order-of-magnitude check (within 20 %: a G2V is not flat over 400-800 nm)."""
    from pathlib import Path

    lam = sp.wavelength_grid_nm(start_nm=300, end_nm=1100, step_nm=1)
    area = math.pi * 0.030**2
    qe = sp.cmos_qe_array(wavelength_nm=lam, **QE_ARGS)
    teff = sp.star_teff_k(spectral_type="G2V")
    star = sp.star_photon_flux_per_nm(v_mag=7.5, temperature_k=teff, wavelength_nm=lam)
    rate = sp.detected_electron_rate_per_nm(photon_flux_per_nm=star, aperture_area_m2=area,
                                            transmission=0.8, filter_transmission=1.0, qe=qe,
                                            wavelength_nm=lam)
    got = sp.electrons_per_exposure(electron_rate_per_nm=rate, wavelength_nm=lam, exposure_s=0.1)

    lines = (Path(sp.__file__).parents[1] / "data" / "bessell_v.csv").read_text().splitlines()  # simcam/data
    rows = [ln.split(",") for ln in lines if ln and ln[0].isdigit()]
    v_lam = np.array([float(r[0]) for r in rows])
    v_resp = np.array([float(r[1]) for r in rows])
    bb = BlackBody(temperature=teff * u.K)

    def bb_photons(x_nm):  # photon radiance, arbitrary constant factor (it cancels)
        return bb(x_nm * u.nm).to_value(u.W / (u.m**2 * u.Hz * u.sr)) / x_nm**2 * x_nm / (H * C)

    def v_resp_at(x):
        return np.interp(x, v_lam, v_resp, left=0.0, right=0.0)

    def qe_at(x):
        w = (550.0 - 400.0) if x <= 550.0 else (800.0 - 550.0)
        return 0.6 * math.exp(-math.log(2) * ((x - 550.0) / w) ** 2)

    knots = list(v_lam)
    band_bb = integrate.quad(lambda x: bb_photons(x) * v_resp_at(x), 470, 700, points=knots, limit=200,
                             epsrel=1e-10)[0]
    band_0 = integrate.quad(lambda x: photons_per_nm_at(x, F0_V) * v_resp_at(x), 470, 700, points=knots,
                            limit=200, epsrel=1e-10)[0]
    scale = 10 ** (-0.4 * 7.5) * band_0 / band_bb
    signal = integrate.quad(lambda x: bb_photons(x) * qe_at(x), 300, 1100, points=[550.0], limit=200,
                            epsrel=1e-10)[0]
    ref = 0.1 * area * 0.8 * scale * signal
    assert got == pytest.approx(ref, rel=2e-5)
    qe_integral_nm = 0.6 * math.sqrt(math.pi / math.log(2)) / 2 * (800.0 - 400.0)
    approx = photons_per_nm_at(550.0, F0_V) * 10 ** (-0.4 * 7.5) * area * 0.8 * qe_integral_nm * 0.1
    assert got == pytest.approx(approx, rel=0.2)
