"""Seed 001's truths by Fourier analysis of the world's encoder over a full turn.

Shares nothing with the lab's fits (:mod:`budget.inductosyn.harmonics`, the designs of
:mod:`budget.inductosyn.validate`; an ast test holds it to that): the error of the world's
encoder as a function of the reading, ``e(r) = r - f^-1(r)`` (what eq 9's compensation
``theta_hat = r - e_hat(r)`` removes), sampled on ``N`` evenly spaced readings over the turn,
and its discrete Fourier transform ``X_m = (1/N) sum_n e(r_n) exp(-i m r_n)``
(:func:`numpy.fft.rfft` over ``N``). On a whole turn the harmonics are orthogonal, so

* the coefficient of ``cos(m r)`` is ``2 Re X_m`` and of ``sin(m r)`` is ``-2 Im X_m`` (the
  mechanical orders ``m = 1, 2`` of eq 7; electrical order ``j`` of eq 8 is ``m = j P``);
* the variance over the turn is ``sum_{m>=1} w_m |X_m|^2``, ``w_m = 2`` (``1`` at ``N/2``)
  (Parseval's theorem);
* a compensation by harmonics with coefficients ``F_m`` at orders ``M`` leaves the variance
  ``sum_m w_m |X_m|^2 - sum_{m in M} 2 (|X_m|^2 - |X_m - F_m|^2)``.

The reading is quantised (``encoder.resolution_deg = q``): the quantisation error is uniform
and independent of the angle, adding ``q^2 / 12`` to every variance (Widrow and Kollar,
*Quantization Noise*, 2008, ch. 4).

**The instrument.** The world's encoder effects are pitch harmonics
(:func:`simcam.encoder.inductosyn.world_pitch_terms`) whose phases the instrument draws
(:func:`simcam.encoder.inductosyn.world_pitch_phases_deg`). ``A sin(x + phi) = cos(phi) A sin x
+ sin(phi) A cos x``, so instrument ``k`` adds ``sum_j a_jk g_j(theta)`` (basis ``g_j`` the
terms at phases 0 and 90 deg, ``a_k`` the cosines and sines of its phases) to the error as a
function of the true angle. As a function of the reading this is, to first order,
``e_k(r) = e_0(r) + sum_j a_jk g_j(theta_0(r)) (1 - e_0'(r))`` (``theta_0 = r - e_0(r)`` the
scenario encoder's inverse; implicit differentiation of ``r = theta + delta(theta)``), with
an error of order ``|g| |g'|``: below 2e-3 arcsec for the default 0.5 arcsec third
electrical harmonic (tested against each instrument's exact encoder). So every truth is a
quadratic form in ``a_k``, precomputed once per scenario (:func:`fourier_truth`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from simcam.encoder.inductosyn import Inductosyn, InductosynParams, PitchHarmonic
from simcam.units import ARCSEC_PER_DEG, ARCSEC_PER_RAD

__all__ = ["FourierTruth", "basis_terms", "fourier_truth", "instrument_coefficients", "truth_orders"]

#: harmonics the ledger's coefficients name: mechanical 1-2, electrical 1-4 (cos, sin each)
MECH_ORDERS = (1, 2)
ELEC_ORDERS = (1, 2, 3, 4)


def truth_orders(pole_pairs: int) -> np.ndarray:
    """Orders per turn of A_L1, A_L2, A_S1 .. A_S4: ``1, 2, P, 2P, 3P, 4P``."""
    return np.array([*MECH_ORDERS, *(j * pole_pairs for j in ELEC_ORDERS)])


def basis_terms(terms) -> tuple[PitchHarmonic, ...]:
    """Each world pitch term at phase 0 (its sine) and at phase 90 deg (its cosine), in that
    order: the basis ``g_j`` of the module docstring."""
    out = []
    for t in terms:
        out += [t.model_copy(update={"phase_deg": 0.0}), t.model_copy(update={"phase_deg": 90.0})]
    return tuple(out)


def instrument_coefficients(phases_deg) -> np.ndarray:
    """``a`` of an instrument (rows: instruments) from its phases: ``cos phi_j, sin phi_j``
    interleaved, matching :func:`basis_terms`."""
    ph = np.radians(np.atleast_2d(np.asarray(phases_deg, dtype=float)))
    out = np.empty((ph.shape[0], 2 * ph.shape[1]))
    out[:, 0::2] = np.cos(ph)
    out[:, 1::2] = np.sin(ph)
    return out


@dataclass
class FourierTruth:
    """The precomputed Fourier truth of one scenario's encoder population (module docstring).

    Attributes
    ----------
    n : readings over the turn.
    orders : the orders of :func:`truth_orders`.
    x0 : ``X_m`` of the scenario's encoder at ``orders`` (complex).
    var0 : its variance over the turn (Parseval, no quantisation).
    hx : ``(orders, J)`` the basis terms' ``X_m`` at ``orders``.
    v, gram : ``sum w_m Re(conj(X0_m) H_mj)`` and ``sum w_m Re(conj(H_mi) H_mj)``.
    q_var : ``q^2 / 12`` of the reading's quantum.
    reading_deg, e0_arcsec, h_arcsec : the grid, ``e_0`` and the basis ``h_j`` (columns) on it.
    slope : ``1 - e_0'(r)`` on the grid.
    mean0, hmean : ``X_0`` of the scenario's encoder and of each basis term.
    mech_order, mech_amp_arcsec : per term (pair of basis columns), its mechanical order and
        amplitude (order 0: an electrical term), for :meth:`maxabs_after_arcsec`.
    n_drift : the drift's columns at the end of the basis (0 or 7).
    """

    n: int
    orders: np.ndarray
    x0: np.ndarray
    var0: float
    hx: np.ndarray
    v: np.ndarray
    gram: np.ndarray
    q_var: float
    reading_deg: np.ndarray
    e0_arcsec: np.ndarray
    h_arcsec: np.ndarray
    slope: np.ndarray
    mean0: float
    hmean: np.ndarray
    mech_order: np.ndarray
    mech_amp_arcsec: np.ndarray
    n_drift: int = 0

    def _a(self, a) -> np.ndarray:
        """``a`` as rows of the full basis: the drift's columns 0 where not given."""
        a = np.atleast_2d(np.asarray(a, dtype=float))
        if a.shape[1] == self.h_arcsec.shape[1] - self.n_drift and self.n_drift:
            a = np.concatenate([a, np.zeros((a.shape[0], self.n_drift))], axis=1)
        return a

    def spectrum(self, a) -> np.ndarray:
        """``X_m`` at :attr:`orders` of instruments ``a`` (rows), complex ``(K, orders)``."""
        a = self._a(a)
        if a.shape[1] == 0:
            return np.repeat(self.x0[None, :], a.shape[0], axis=0)
        return self.x0[None, :] + np.einsum("kj,mj->km", a, self.hx)

    def mean(self, a) -> np.ndarray:
        """The error's mean over the turn (``X_0``, the constant e0 would estimate), ``(K,)``."""
        a = self._a(a)
        return self.mean0 + (a @ self.hmean if a.shape[1] else np.zeros(a.shape[0]))

    def coefficients(self, a) -> np.ndarray:
        """Coefficients ``(cos, sin)`` of each order, ``(K, 2 orders)``: A_L1c, A_L1s, ..., A_S4s."""
        x = self.spectrum(a)
        out = np.empty((x.shape[0], 2 * x.shape[1]))
        out[:, 0::2] = 2 * x.real
        out[:, 1::2] = -2 * x.imag
        return out

    def variance(self, a) -> np.ndarray:
        """Variance over the turn of instruments ``a`` (no quantisation), ``(K,)``."""
        a = self._a(a)
        if a.shape[1] == 0:
            return np.full(a.shape[0], self.var0)
        return self.var0 + 2 * np.einsum("kj,j->k", a, self.v) + np.einsum("ki,ij,kj->k", a, self.gram, a)

    def sigma3_before_arcsec(self, a) -> np.ndarray:
        """3 sigma over the turn of the quantised reading's error, ``(K,)``."""
        return 3 * np.sqrt(self.variance(a) + self.q_var)

    def sigma3_after_arcsec(self, a, fit) -> np.ndarray:
        """3 sigma over the turn of the compensated reading's error: ``fit`` ``(K, 2 orders)``
        the compensation's coefficients (:meth:`coefficients`' layout; 0 where not fitted)."""
        x = self.spectrum(a)
        fit = np.atleast_2d(np.asarray(fit, dtype=float))
        f = (fit[:, 0::2] - 1j * fit[:, 1::2]) / 2
        var = self.variance(a) - 2 * np.sum(np.abs(x) ** 2 - np.abs(x - f) ** 2, axis=1)
        return 3 * np.sqrt(np.maximum(var, 0.0) + self.q_var)

    def series_arcsec(self, a, fit=None) -> np.ndarray:
        """The error over the turn (``reading_deg``) of instrument ``a`` (one row), less the
        compensation ``fit`` (one row, :meth:`coefficients`' layout) if given."""
        e = self.e0_arcsec + (self.h_arcsec @ self._a(a)[0] if self.h_arcsec.shape[1] else 0.0)
        if fit is not None:
            r = np.radians(self.reading_deg)
            for i, m in enumerate(self.orders):
                e = e - fit[2 * i] * np.cos(m * r) - fit[2 * i + 1] * np.sin(m * r)
        return e

    def maxabs_after_arcsec(self, a, *fits) -> tuple[np.ndarray, ...]:
        """max |e - mean| over the grid of each instrument's (rows of ``a``) error less each
        compensation (rows of each of ``fits``), one ``(K,)`` array per compensation. The mechanical pitch terms are summed by one
        inverse FFT at the reading (``g_j(theta_0(r)) = g_j(r) + O(|g_j'| |e_0|)``, below 2e-3
        arcsec for the default irregular pitch error); the other columns and the compensation's
        harmonics by one product with their values on the grid."""
        import scipy.fft

        a = self._a(a)
        fits = [np.atleast_2d(np.asarray(f, dtype=float)) for f in fits]
        mech = self.mech_order > 0
        cols = np.r_[np.flatnonzero(np.repeat(~mech, 2)), np.arange(self.n_drift) + 2 * mech.size].astype(int)
        if not hasattr(self, "_max_table"):
            r = np.radians(self.reading_deg)
            harm = np.stack([f(m * r) for m in self.orders for f in (np.cos, np.sin)], axis=1)
            self._max_table = np.ascontiguousarray(np.concatenate([self.h_arcsec[:, cols], -harm], axis=1))
        out = [np.empty(a.shape[0]) for _ in fits]
        spec = np.zeros(self.n // 2 + 1, complex)
        w = np.zeros(self.n)
        for k in range(a.shape[0]):
            if np.any(mech):
                pa = a[k, :2 * mech.size]
                spec[self.mech_order[mech]] = self.mech_amp_arcsec[mech] * (pa[1::2][mech] - 1j * pa[0::2][mech]) / 2
                w = scipy.fft.irfft(spec * self.n, n=self.n)
            for o, fit in zip(out, fits):
                o[k] = _maxabs_about_mean(self.e0_arcsec, self._max_table, np.r_[a[k, cols], fit[k]], self.slope, w)
        return tuple(out)


@numba.njit(cache=True)
def _maxabs_about_mean(e0, table, v, slope, w):  # pragma: no cover - compiled
    """max_j |e_j - mean e| of ``e = e0 + table @ v + slope * w``, in a fixed order."""
    n, p = table.shape
    e = np.empty(n)
    total = 0.0
    for j in range(n):
        x = e0[j] + slope[j] * w[j]
        for i in range(p):
            x += table[j, i] * v[i]
        e[j] = x
        total += x
    mean = total / n
    best = 0.0
    for j in range(n):
        d = abs(e[j] - mean)
        best = max(best, d)
    return best


def drift_columns_arcsec(*, encoder: InductosynParams, drift, theta0_deg, slope) -> np.ndarray:
    """The error, as a function of the reading, that one standard deviation of each of the 7
    drifting parameters (:func:`simcam.encoder.inductosyn.drifted_params`, seed 001 section
    4.3) adds: ``(delta_+(theta_0) - delta_-(theta_0)) / 2 * slope`` at the readings whose
    true angles under ``encoder`` are ``theta0_deg`` (``slope = dtheta_0 / dr``), the central
    difference of the error as a function of the true angle (its second-order terms cancel)
    carried to the reading to first order, as the pitch terms are (module docstring).
    Columns in the drift's order."""
    from simcam.encoder.inductosyn import drifted_params

    cols = []
    for i in range(7):
        z = np.zeros(7)
        z[i] = 1.0
        up = Inductosyn(params=drifted_params(params=encoder, drift=drift, z=z))
        dn = Inductosyn(params=drifted_params(params=encoder, drift=drift, z=-z))
        cols.append((up.error_arcsec(angle_deg=theta0_deg) - dn.error_arcsec(angle_deg=theta0_deg)) / 2 * slope)
    return np.stack(cols, axis=-1)


def fourier_truth(*, encoder: InductosynParams, terms=(), step_deg: float = 0.01, drift=None) -> FourierTruth:
    """The Fourier truth of ``encoder`` (the scenario's, without the world's pitch terms) and
    the instrument basis of the world's ``terms`` (phase 0, :func:`basis_terms`), on readings
    ``step_deg`` apart over the turn (module docstring). With ``drift``
    (:class:`simcam.encoder.inductosyn.DriftParams`) the basis goes on with the 7 drift
    columns (:func:`drift_columns_arcsec`): ``a`` then holds the instrument's coefficients and
    the drift's standard normal draws, and an ``a`` without the drift's columns is padded
    with zeros (the encoder before the environment)."""
    enc = Inductosyn(params=encoder)
    n = int(round(360.0 / step_deg))
    n += n % 2
    r = np.arange(n) * (360.0 / n)
    e0 = enc.error_at_reading_arcsec(reading_deg=r)
    x_all = np.fft.rfft(e0) / n
    w = np.full(x_all.size, 2.0)
    w[0] = 0.0
    w[-1] = 1.0  # N even: the Nyquist term once
    # d e0 / d r (arcsec per arcsec) by the spectral derivative
    m_all = np.arange(x_all.size)
    slope = 1.0 - np.fft.irfft(x_all * n * 1j * m_all, n=n) / ARCSEC_PER_RAD
    basis = basis_terms(terms)
    theta0 = r - e0 / ARCSEC_PER_DEG
    h = enc.pitch_arcsec(angle_deg=theta0, harmonics=basis, separate=True) * slope[:, None]
    if drift is not None:
        h = np.concatenate([h, drift_columns_arcsec(encoder=encoder, drift=drift, theta0_deg=theta0, slope=slope)],
                           axis=1)
    # the basis' spectrum at the fitted orders and the constant only (a direct DFT there)
    orders_and_0 = np.r_[0, truth_orders(encoder.pole_pairs)]
    hx_some = np.exp(-1j * np.outer(orders_and_0, np.radians(r))) @ h / n if h.shape[1] else np.zeros(
        (orders_and_0.size, 0), complex)
    orders = truth_orders(encoder.pole_pairs)
    var0 = float(np.sum(w * np.abs(x_all) ** 2))
    # Parseval on the grid: sum_{m>=1} w_m Re(conj(X_mi) X_mj) = <h_i h_j> - <h_i><h_j> (real signals)
    hmean = hx_some[0].real.copy()
    v = h.T @ e0 / n - hmean * x_all[0].real
    gram = h.T @ h / n - np.outer(hmean, hmean)
    q = encoder.resolution_deg * ARCSEC_PER_DEG
    terms = tuple(terms)
    mech_order = np.array([t.order if t.domain == "mechanical" else 0 for t in terms], dtype=int)
    mech_amp = np.array([t.amplitude_arcsec for t in terms], dtype=float)
    n_drift = h.shape[1] - 2 * len(terms)
    return FourierTruth(n=n, orders=orders, x0=x_all[orders], var0=var0, hx=hx_some[1:], v=v, gram=gram,
                        q_var=q * q / 12.0, reading_deg=r, e0_arcsec=e0, h_arcsec=h, slope=slope,
                        mean0=float(x_all[0].real), hmean=hmean,
                        mech_order=mech_order, mech_amp_arcsec=mech_amp, n_drift=n_drift)
