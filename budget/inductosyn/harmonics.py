"""Harmonic fits of angle-encoder calibration tables (seed 001 eqs 7-9) and their analysis.

The lab side of seed 001: it accepts what a lab writes down (nominal angle, measured
error), never a simulator object.

* :func:`fit_long_period`: eq 7, ``e_L = e0 + A_L1c cos t + A_L1s sin t + A_L2c cos 2t
  + A_L2s sin 2t`` by least squares (24-face polygon in the paper);
* :func:`fit_short_period`: eq 8, ``e_S = A_S1c cos t_e + A_S1s sin t_e + A_S2c cos 2t_e
  + A_S2s sin 2t_e`` on the data sorted by the fractional degree, ``t_e = P t`` (23-face
  polygon), plus a constant ``offset`` fitted as a nuisance term: a polygon and
  autocollimator table is relative to its first face, so an offset is always in the data
  (eq 8 as printed has none; without it seed 001's own Table 2 leaves a max residual of
  21.3" instead of the published 2.7"). The offset is not part of the compensation;
* :func:`calibrate_in_sequence`: the published procedure (long fit, compensate, short fit
  on the long-compensated data, eq 9 model);
* :func:`fit_joint`: the improved variant, one least-squares fit of the mechanical and
  electrical harmonics on all tables, with one constant (mounting offset) per table;
* :func:`analyse_design` / :func:`check_design`: rank, condition number and aliasing of a
  calibration design; a design that cannot separate what is asked raises
  :class:`DesignError`;
* :func:`posterior_band`: emcee posterior of the coefficients (noise level unknown, the
  polygon's face errors as Gaussian nuisance parameters, marginalised analytically) and
  the credible band of the residual after compensation.

The 3 sigma figures are computed as the paper does: ``3 x`` the sample standard
deviation (``ddof=1``; with it the paper's Table 1 and 2 columns give 2.66 and 145.57
arcsec, printed there as 2.7 and 145.6).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field

import numpy as np

from simcam.infra.errors import UserInputError
from simcam.infra.outputs import check_input_file
from simcam.units import ARCSEC_PER_DEG

#: one full turn in arcsec: no calibration reading errs by that much
FULL_TURN_ARCSEC = 360.0 * ARCSEC_PER_DEG
#: calibration angles beyond ten turns are not readings of one rotation
MAX_ANGLE_DEG = 3600.0
#: the harmonic coefficients the study validates (the constant e0 is not observable with a polygon)
COEFFICIENTS = ("A_L1c", "A_L1s", "A_L2c", "A_L2s", "A_S1c", "A_S1s", "A_S2c", "A_S2s",
                "A_S3c", "A_S3s", "A_S4c", "A_S4s")
#: those the published procedure fits (eq 7: mechanical 1-2; eq 8: electrical 1-2)
PUBLISHED_COEFFICIENTS = COEFFICIENTS[:8]

__all__ = [
    "COEFFICIENTS",
    "PUBLISHED_COEFFICIENTS",
    "CompensationModel",
    "DesignAnalysis",
    "DesignError",
    "HarmonicFit",
    "HarmonicSpec",
    "accept",
    "alias_order",
    "analyse_design",
    "analytic_residual_band",
    "calibrate_in_sequence",
    "check_design",
    "design_matrix",
    "fit_harmonics",
    "fit_joint",
    "fit_long_period",
    "fit_short_period",
    "posterior_band",
    "read_calibration_csv",
    "sigma3_arcsec",
]


class DesignError(UserInputError):
    """A calibration design that cannot determine the harmonics asked for."""


# ------------------------------------------------------------------------- designs
@dataclass(frozen=True)
class HarmonicSpec:
    """Which harmonics a model holds.

    Parameters
    ----------
    mech_orders : mechanical harmonic orders (cycles per turn).
    elec_orders : electrical harmonic orders (``n`` means ``n * pole_pairs`` per turn).
    pole_pairs : electrical periods per turn.
    n_constants : number of constant terms (one per table: a mounting offset each).
    nuisance_offset : with ``n_constants == 1``: the constant is a nuisance term (named
        ``offset``), fitted but left out of :meth:`HarmonicFit.evaluate_arcsec` (the
        table's zero is its first face, not a property of the encoder).
    """

    mech_orders: tuple[int, ...] = (1, 2)
    elec_orders: tuple[int, ...] = ()
    pole_pairs: int = 360
    n_constants: int = 1
    nuisance_offset: bool = False

    def names(self) -> list[str]:
        """Coefficient names (the paper's: e0, A_L1c, ..., A_S2s; ``offset`` for a nuisance constant)."""
        if self.nuisance_offset and self.n_constants != 1:
            raise ValueError("nuisance_offset: needs exactly one constant (n_constants=1)")
        out = (["offset"] if self.nuisance_offset else ["e0"]) if self.n_constants == 1 else [
            f"e0_{k}" for k in range(self.n_constants)]
        for m in self.mech_orders:
            out += [f"A_L{m}c", f"A_L{m}s"]
        for n in self.elec_orders:
            out += [f"A_S{n}c", f"A_S{n}s"]
        return out


def _harmonic_columns(angle_deg, spec: HarmonicSpec):
    """Columns cos/sin of the mechanical and electrical harmonics at ``angle_deg``."""
    a = np.asarray(angle_deg, dtype=float)
    t = np.radians(a)
    cols = []
    for m in spec.mech_orders:
        cols += [np.cos(m * t), np.sin(m * t)]
    if spec.elec_orders:
        cyc = spec.pole_pairs * a / 360.0
        te = 2 * math.pi * (cyc - np.floor(cyc))  # fractional degree -> electrical phase
        for n in spec.elec_orders:
            cols += [np.cos(n * te), np.sin(n * te)]
    return cols


def design_matrix(*, angle_deg, spec: HarmonicSpec, table_index=None) -> np.ndarray:
    """Least-squares design matrix (rows: points; columns: :meth:`HarmonicSpec.names`).

    Parameters
    ----------
    angle_deg : nominal angles (deg).
    spec : the harmonics.
    table_index : for ``spec.n_constants > 1``, which table (0..) each point comes from.
    """
    a = np.asarray(angle_deg, dtype=float)
    cols = []
    if spec.n_constants == 1:
        cols.append(np.ones_like(a))
    elif spec.n_constants > 1:
        idx = np.asarray(table_index)
        cols += [(idx == k).astype(float) for k in range(spec.n_constants)]
    cols += _harmonic_columns(a, spec)
    return np.stack(cols, axis=-1) if cols else np.zeros(a.shape + (0,))


def alias_order(*, faces: int, cycles_per_rev: int) -> tuple[int, int]:
    """Mechanical order a harmonic appears at on an evenly spaced ``faces``-face polygon.

    Sampling ``cos(f t)`` at ``t_i = 2 pi i / N`` gives ``cos(2 pi (f mod N) i / N)``; an
    order ``r = f mod N`` above ``N/2`` folds to ``N - r`` with the sine's sign flipped.

    Returns
    -------
    (order, sine_sign) : e.g. ``faces=23, cycles_per_rev=360 -> (8, -1)``;
    ``faces=24, 360 -> (0, 1)`` (a constant).
    """
    r = cycles_per_rev % faces
    if 2 * r > faces:
        return faces - r, -1
    return r, 1


@dataclass
class DesignAnalysis:
    """Rank, conditioning and aliasing of a calibration design."""

    names: list[str]
    n_points: int
    rank: int
    condition_number: float
    aliases: dict[str, str] = field(default_factory=dict)
    dependent_groups: list[list[str]] = field(default_factory=list)

    @property
    def full_rank(self) -> bool:
        return self.rank == len(self.names)

    def as_dict(self) -> dict:
        return {"names": self.names, "n_points": self.n_points, "rank": self.rank,
                "condition_number": self.condition_number, "aliases": self.aliases,
                "dependent_groups": self.dependent_groups}


def _alias_on_samples(a_deg, f_cycles, spec_tol=1e-9):
    """Lowest mechanical order whose sampled cos/sin span holds cos/sin(f t) on a_deg."""
    t = np.radians(np.asarray(a_deg, dtype=float))
    n = t.size
    cyc = f_cycles * np.asarray(a_deg, dtype=float) / 360.0
    te = 2 * math.pi * (cyc - np.floor(cyc))
    x = np.stack([np.cos(te), np.sin(te)], axis=1)
    for h in range(0, n // 2 + 1):
        b = np.stack([np.cos(h * t), np.sin(h * t)], axis=1) if h else np.ones((n, 1))
        coef, *_ = np.linalg.lstsq(b, x, rcond=None)
        res = np.linalg.norm(x - b @ coef)
        if res < spec_tol * max(1.0, np.linalg.norm(x)) * math.sqrt(n):
            return h
    return None


def analyse_design(*, angle_deg, spec: HarmonicSpec, table_index=None,
                   with_aliases: bool = True) -> DesignAnalysis:
    """Rank, condition number and aliasing of the design ``spec`` on ``angle_deg``.

    The condition number is that of the column-normalised design (a scale-free measure).
    Each harmonic is reported with the mechanical order it is indistinguishable from on
    these samples (e.g. on 24 faces every electrical harmonic looks like a constant; on
    23 faces electrical 1 and 2 look like mechanical 8 and 7).
    """
    a = np.asarray(angle_deg, dtype=float)
    x = design_matrix(angle_deg=a, spec=spec, table_index=table_index)
    names = spec.names()
    norms = np.linalg.norm(x, axis=0)
    xn = x / np.where(norms > 0, norms, 1.0)
    s = np.linalg.svd(xn, compute_uv=False) if x.size else np.zeros(0)
    tol = max(x.shape) * np.finfo(float).eps * (s[0] if s.size else 0) * 1e3
    rank = int(np.sum(s > tol)) if x.shape[0] else 0
    rank = min(rank, int(np.sum(norms > 0)))
    cond = float(s[0] / s[-1]) if s.size and s[-1] > tol and x.shape[0] >= x.shape[1] else math.inf
    aliases = {}
    for m in (spec.mech_orders if with_aliases else ()):
        h = _alias_on_samples(a, m)
        aliases[f"mechanical {m}"] = "unaliased" if h == m else (f"mechanical {h}" if h is not None else "no low order")
    for nord in (spec.elec_orders if with_aliases else ()):
        h = _alias_on_samples(a, nord * spec.pole_pairs)
        aliases[f"electrical {nord}"] = (f"mechanical {h}" if h is not None else "no low order")
    groups = []
    if x.shape[0] and rank < x.shape[1]:
        _, sv, vt = np.linalg.svd(xn, full_matrices=True)
        sv_full = np.zeros(vt.shape[0])
        sv_full[: sv.size] = sv
        for k in range(vt.shape[0]):
            if sv_full[k] <= tol:
                idx = np.flatnonzero(np.abs(vt[k]) > 1e-6)
                grp = [names[i] for i in idx]
                if grp and grp not in groups:
                    groups.append(grp)
    return DesignAnalysis(names=names, n_points=int(a.size), rank=rank, condition_number=cond,
                          aliases=aliases, dependent_groups=groups)


def check_design(*, angle_deg, spec: HarmonicSpec, table_index=None, source: str = "data",
                 max_condition: float = 1e8) -> DesignAnalysis:
    """Analyse a design and raise :class:`DesignError` if it cannot be fitted.

    Raises
    ------
    DesignError
        Too few points (need more points than coefficients, for a noise estimate), a
        rank-deficient design (naming the inseparable coefficients and the aliasing), or
        a condition number above ``max_condition``.
    """
    a = np.asarray(angle_deg, dtype=float)
    names = spec.names()
    if a.size <= len(names):
        raise DesignError(f"{source}: {a.size} points for {len(names)} coefficients "
                          f"({', '.join(names)}): need at least {len(names) + 1}")
    an = analyse_design(angle_deg=a, spec=spec, table_index=table_index, with_aliases=False)
    if not an.full_rank:
        an = analyse_design(angle_deg=a, spec=spec, table_index=table_index)
        alias_txt = "; ".join(f"{k} -> {v}" for k, v in an.aliases.items() if v != "unaliased")
        grp_txt = "; ".join("{" + ", ".join(g) + "}" for g in an.dependent_groups)
        raise DesignError(f"{source}: design cannot separate the harmonics asked (rank {an.rank} "
                          f"of {len(names)}): inseparable {grp_txt}; on these angles {alias_txt}")
    if an.condition_number > max_condition:
        raise DesignError(f"{source}: design is ill-conditioned (condition number "
                          f"{an.condition_number:.3g} > {max_condition:.3g})")
    return an


# ---------------------------------------------------------------------------- fits
def sigma3_arcsec(*, error_arcsec, axis=-1):
    """3 x the sample standard deviation (ddof=1), as seed 001 computes its 3 sigma."""
    return 3.0 * np.std(np.asarray(error_arcsec, dtype=float), axis=axis, ddof=1)


@dataclass
class HarmonicFit:
    """A least-squares harmonic fit and its statistics.

    Attributes
    ----------
    spec : the harmonics fitted.
    coefficients_arcsec : fitted coefficients (arcsec), in ``spec.names()`` order.
    covariance_arcsec2 : ``s^2 (X^T X)^-1`` with ``s^2 = RSS / (n - p)``.
    angle_deg, error_arcsec, table_index : the data.
    residual_arcsec : data minus model.
    """

    spec: HarmonicSpec
    coefficients_arcsec: np.ndarray
    covariance_arcsec2: np.ndarray
    angle_deg: np.ndarray
    error_arcsec: np.ndarray
    residual_arcsec: np.ndarray
    table_index: np.ndarray | None = None

    @property
    def names(self) -> list[str]:
        return self.spec.names()

    @property
    def dof(self) -> int:
        return self.angle_deg.size - len(self.names)

    @property
    def sigma_arcsec(self) -> float:
        """Residual standard error ``sqrt(RSS/(n-p))``."""
        return float(math.sqrt(np.sum(self.residual_arcsec**2) / self.dof))

    @property
    def standard_errors_arcsec(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance_arcsec2))

    @property
    def sigma3_before_arcsec(self) -> float:
        return float(sigma3_arcsec(error_arcsec=self.error_arcsec))

    @property
    def sigma3_after_arcsec(self) -> float:
        return float(sigma3_arcsec(error_arcsec=self.residual_arcsec))

    @property
    def max_abs_after_arcsec(self) -> float:
        return float(np.max(np.abs(self.residual_arcsec)))

    def design(self, *, angle_deg, table: int = 0) -> np.ndarray:
        a = np.asarray(angle_deg, dtype=float)
        return design_matrix(angle_deg=a, spec=self.spec,
                             table_index=np.full(a.shape, table) if self.spec.n_constants > 1 else None)

    def evaluate_arcsec(self, *, angle_deg, table: int = 0):
        """Model error ``e(theta)`` (arcsec) with table ``table``'s constant (a nuisance
        ``offset`` is left out: it is the table's zero, not the encoder's error)."""
        c = self.coefficients_arcsec
        if self.spec.nuisance_offset:
            c = c.copy()
            c[0] = 0.0
        return self.design(angle_deg=angle_deg, table=table) @ c

    def as_dict(self) -> dict:
        return {
            "coefficients": {n: {"value_arcsec": float(v), "std_arcsec": float(s)}
                             for n, v, s in zip(self.names, self.coefficients_arcsec,
                                                self.standard_errors_arcsec)},
            "n_points": int(self.angle_deg.size),
            "dof": self.dof,
            "residual_sigma_arcsec": self.sigma_arcsec,
            "sigma3_before_arcsec": self.sigma3_before_arcsec,
            "sigma3_after_arcsec": self.sigma3_after_arcsec,
            "max_abs_after_arcsec": self.max_abs_after_arcsec,
        }


def fit_harmonics(*, angle_deg, error_arcsec, spec: HarmonicSpec, table_index=None,
                  source: str = "data") -> HarmonicFit:
    """Least-squares fit of ``spec`` (design checked first: :func:`check_design`)."""
    a = np.asarray(angle_deg, dtype=float)
    y = np.asarray(error_arcsec, dtype=float)
    if a.shape != y.shape or a.ndim != 1:
        raise UserInputError(f"{source}: angle_deg and error_arcsec must be 1-D of equal length")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(y))):
        raise UserInputError(f"{source}: non-finite angle or error")
    check_design(angle_deg=a, spec=spec, table_index=table_index, source=source)
    x = design_matrix(angle_deg=a, spec=spec, table_index=table_index)
    coef, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ coef
    dof = a.size - x.shape[1]
    s2 = float(np.sum(res**2) / dof)
    cov = s2 * np.linalg.inv(x.T @ x)
    return HarmonicFit(spec=spec, coefficients_arcsec=coef, covariance_arcsec2=cov, angle_deg=a,
                       error_arcsec=y, residual_arcsec=res,
                       table_index=None if table_index is None else np.asarray(table_index))


def fit_long_period(*, angle_deg, error_arcsec, source: str = "data") -> HarmonicFit:
    """Seed 001 eq 7: constant plus 1st and 2nd mechanical harmonics."""
    return fit_harmonics(angle_deg=angle_deg, error_arcsec=error_arcsec,
                         spec=HarmonicSpec(mech_orders=(1, 2), elec_orders=(), n_constants=1),
                         source=source)


def fit_short_period(*, angle_deg, error_arcsec, pole_pairs: int = 360,
                     source: str = "data") -> HarmonicFit:
    """Seed 001 eq 8: 1st and 2nd electrical harmonics plus a nuisance offset, data sorted.

    As published: the points are sorted by the fractional part of ``P theta / 360``
    (the fractional degree for P = 360) and fitted in the electrical phase. Unlike the
    printed eq 8 a constant ``offset`` is fitted too: the table is relative to its first
    face (seed 001 Table 2 starts at 0), so its mean is an arbitrary zero; leaving the
    constant out forces the harmonics to explain it (Table 2: max residual 21.3" and
    coefficient errors +-6.07" without it; 2.69" and +-0.48" with it, the paper's 2.7").
    The offset is reported but not compensated (:meth:`HarmonicFit.evaluate_arcsec`).
    """
    a = np.asarray(angle_deg, dtype=float)
    y = np.asarray(error_arcsec, dtype=float)
    cyc = pole_pairs * a / 360.0
    order = np.argsort(cyc - np.floor(cyc), kind="stable")
    return fit_harmonics(angle_deg=a[order], error_arcsec=y[order],
                         spec=HarmonicSpec(mech_orders=(), elec_orders=(1, 2),
                                           pole_pairs=pole_pairs, n_constants=1,
                                           nuisance_offset=True),
                         source=source)


def fit_joint(*, tables, pole_pairs: int = 360, mech_orders=(1, 2), elec_orders=(1, 2),
              sources=None) -> HarmonicFit:
    """Improved variant: one fit of mechanical and electrical harmonics on all tables.

    Each table (a polygon set-up) gets its own constant (mounting offset).

    Parameters
    ----------
    tables : sequence of (angle_deg, error_arcsec) pairs, raw (uncompensated) data.
    """
    angles = np.concatenate([np.asarray(t[0], dtype=float) for t in tables])
    errs = np.concatenate([np.asarray(t[1], dtype=float) for t in tables])
    idx = np.concatenate([np.full(len(t[0]), k) for k, t in enumerate(tables)])
    spec = HarmonicSpec(mech_orders=tuple(mech_orders), elec_orders=tuple(elec_orders),
                        pole_pairs=pole_pairs, n_constants=len(tables))
    src = " + ".join(sources) if sources else "data"
    return fit_harmonics(angle_deg=angles, error_arcsec=errs, spec=spec,
                         table_index=idx if len(tables) > 1 else None, source=src)


@dataclass
class CompensationModel:
    """Eq 9: ``e(theta) = sum of fitted parts``; ``theta_hat = theta - e(theta)``."""

    parts: list[HarmonicFit]

    def error_arcsec(self, *, angle_deg):
        """Modelled error (arcsec) at readings ``angle_deg``."""
        a = np.asarray(angle_deg, dtype=float)
        return sum((p.evaluate_arcsec(angle_deg=a) for p in self.parts), np.zeros_like(a))


def accept(*, sigma3_after_arcsec: float, requirement_arcsec: float) -> bool:
    """Seed 001 section 3.1: accept when the compensated 3 sigma <= requirement / 3."""
    return bool(sigma3_after_arcsec <= requirement_arcsec / 3.0)


def calibrate_in_sequence(*, long_angle_deg, long_error_arcsec, short_angle_deg,
                          short_error_arcsec, pole_pairs: int = 360,
                          short_is_compensated: bool = False) -> dict:
    """The published procedure (seed 001 section 3): eq 7, compensate, eq 8, eq 9.

    Parameters
    ----------
    long_angle_deg, long_error_arcsec : the 24-face table (raw).
    short_angle_deg, short_error_arcsec : the 23-face table, raw, or already taken with
        the long-period compensation applied (``short_is_compensated=True``).

    Returns
    -------
    dict with ``long`` (eq 7 fit), ``short`` (eq 8 fit) and ``model``
    (:class:`CompensationModel`, eq 9).
    """
    long_fit = fit_long_period(angle_deg=long_angle_deg, error_arcsec=long_error_arcsec,
                               source="long-period table")
    sa = np.asarray(short_angle_deg, dtype=float)
    sy = np.asarray(short_error_arcsec, dtype=float)
    if not short_is_compensated:
        sy = sy - long_fit.evaluate_arcsec(angle_deg=sa)
    short_fit = fit_short_period(angle_deg=sa, error_arcsec=sy, pole_pairs=pole_pairs,
                                 source="short-period table")
    return {"long": long_fit, "short": short_fit,
            "model": CompensationModel(parts=[long_fit, short_fit])}


# ---------------------------------------------------------------------- uncertainty
def _compensated_design(fit: HarmonicFit, angle_deg) -> np.ndarray:
    """Design rows of the compensated model (a nuisance offset column zeroed)."""
    b = fit.design(angle_deg=angle_deg)
    if fit.spec.nuisance_offset:
        b = b.copy()
        b[:, 0] = 0.0
    return b


def analytic_residual_band(*, fit: HarmonicFit, angle_deg, level: float = 0.9):
    """Exact credible band of the residual when face errors are absent.

    With a flat prior on the coefficients and ``p(sigma) ~ 1/sigma`` the posterior of
    any linear functional ``b.(c - c_hat)`` is Student-t with ``n - p`` degrees of
    freedom and scale ``s sqrt(b (X^T X)^-1 b)`` (Gelman et al., BDA3, sec. 14.2).

    Returns
    -------
    (lower, upper) arrays in arcsec.
    """
    from scipy.stats import t as student_t

    b = _compensated_design(fit, angle_deg)
    sd = np.sqrt(np.einsum("ij,jk,ik->i", b, fit.covariance_arcsec2, b))
    k = student_t.ppf(0.5 + level / 2, fit.dof)
    return -k * sd, k * sd


def posterior_band(*, fit: HarmonicFit, angle_deg, seed: int, face_error_arcsec: float = 0.0,
                   level: float = 0.9, n_walkers: int = 32, n_steps: int = 1500,
                   burn: int = 500) -> dict:
    """emcee posterior of the coefficients and the band of the residual after compensation.

    Model: ``y = X c + f + n`` with ``n ~ N(0, sigma^2)`` (sigma unknown, prior
    ``p(log sigma)`` uniform on [-12, 10]) and the polygon face errors ``f ~ N(0,
    face_error_arcsec^2)`` as nuisance parameters, marginalised analytically (the model
    is linear-Gaussian in them, so the marginal likelihood is Gaussian with variance
    ``sigma^2 + face_error^2``). Flat prior on ``c``. The residual after compensating with
    the point estimate is ``r(theta) = B(theta) (c - c_hat)``.

    Returns
    -------
    dict with ``lower_arcsec``, ``upper_arcsec``, ``median_arcsec`` (at ``angle_deg``),
    ``samples`` (coefficients, arcsec), ``sigma_arcsec`` (samples), ``acceptance``.
    """
    import emcee

    x = fit.design(angle_deg=fit.angle_deg) if fit.table_index is None else design_matrix(
        angle_deg=fit.angle_deg, spec=fit.spec, table_index=fit.table_index)
    y = fit.error_arcsec
    n, p = x.shape
    sf2 = float(face_error_arcsec) ** 2
    chat = fit.coefficients_arcsec

    def log_prob(theta):
        c = theta[:, :p]
        ls = theta[:, p]
        r = y[None, :] - c @ x.T
        var = np.exp(2 * ls) + sf2
        lp = -0.5 * np.sum(r * r, axis=1) / var - 0.5 * n * np.log(var)
        return np.where((ls > -12) & (ls < 10), lp, -np.inf)

    ss = np.random.SeedSequence(seed)
    rng = np.random.default_rng(ss.spawn(1)[0])
    sd = np.sqrt(np.diag(fit.covariance_arcsec2))
    s0 = max(fit.sigma_arcsec, 1e-6)
    start = np.empty((n_walkers, p + 1))
    start[:, :p] = chat + 0.1 * sd * rng.standard_normal((n_walkers, p))
    start[:, p] = math.log(s0) + 0.1 * rng.standard_normal(n_walkers)
    sampler = emcee.EnsembleSampler(n_walkers, p + 1, log_prob, vectorize=True)
    sampler.random_state = np.random.RandomState(int(ss.generate_state(1)[0])).get_state()
    sampler.run_mcmc(start, n_steps, progress=False)
    chain = sampler.get_chain(discard=burn, flat=True)
    c = chain[:, :p]
    b = _compensated_design(fit, angle_deg)
    r = (c - chat) @ b.T
    lo, med, hi = np.quantile(r, [0.5 - level / 2, 0.5, 0.5 + level / 2], axis=0)
    return {"lower_arcsec": lo, "upper_arcsec": hi, "median_arcsec": med, "samples": c,
            "sigma_arcsec": np.exp(chain[:, p]),
            "acceptance": float(np.mean(sampler.acceptance_fraction))}


# ----------------------------------------------------------------------- real tables
#: the largest calibration table read (bytes): a million readings at ~30 bytes a row; a
#: larger file is refused before it is read (a 200 MB table took 5.2 GB before this)
MAX_TABLE_BYTES = 64 * 2**20


def _row_problem(path, ln, r, cols, ia, ie) -> str | None:
    """Why row ``r`` (line ``ln``) of a calibration table is not a reading, or None."""
    if len(r) != len(cols):
        return f"{path}:{ln}: expected {len(cols)} fields, got {len(r)}"
    sa, se = r[ia].strip(), r[ie].strip()
    if not sa or not se:
        return f"{path}:{ln}: empty cell in {'angle_deg' if not sa else 'error_arcsec'}"
    try:
        a, e = float(sa), float(se)
    except ValueError:
        return f"{path}:{ln}: not a number: {sa!r}, {se!r}"
    if not (math.isfinite(a) and math.isfinite(e)):
        return f"{path}:{ln}: non-finite value"
    if abs(e) >= FULL_TURN_ARCSEC or abs(a) > MAX_ANGLE_DEG:
        # an angle error of a full turn or more, or an angle beyond a few turns, is
        # not a calibration reading (and squares of such values overflow)
        return (f"{path}:{ln}: out of range: angle_deg {sa} (|angle| <= {MAX_ANGLE_DEG:g}), "
                f"error_arcsec {se} (|error| < {FULL_TURN_ARCSEC:g}, one turn)")
    return None


def read_calibration_csv(*, path) -> tuple[np.ndarray, np.ndarray]:
    """Read a calibration table: header with ``angle_deg`` and ``error_arcsec`` columns.

    Other columns are allowed and ignored; blank lines are skipped.

    Returns
    -------
    (angle_deg, error_arcsec) arrays.

    Raises
    ------
    UserInputError
        Missing file or columns, a row with the wrong number of fields, a value that is
        not a finite number, a duplicated angle, or no data; the message names the file
        and the line.
    """
    path = str(path)
    check_input_file(path, what="calibration table")  # a FIFO or a device is not read (it would block)
    size = os.path.getsize(path)
    if size > MAX_TABLE_BYTES:
        raise UserInputError(f"{path}: {size / 2**20:.0f} MiB; a calibration table is at most "
                             f"{MAX_TABLE_BYTES / 2**20:.0f} MiB (about a million readings)")
    try:
        # utf-8-sig: a byte-order mark (spreadsheets write one) is not part of the first column's name
        fh = open(path, newline="", encoding="utf-8-sig")
    except FileNotFoundError:
        raise UserInputError(f"{path}: file not found") from None
    except OSError as exc:
        raise UserInputError(f"{path}: cannot read ({exc.strerror})") from None
    ang, err, problems, lines = [], [], [], []
    n_problems = 0
    hdr_ln = cols = None
    try:
        with fh:
            for i, r in enumerate(csv.reader(fh)):
                ln = i + 1
                if not any(c.strip() for c in r):
                    continue
                if cols is None:
                    hdr_ln, cols = ln, [c.strip() for c in r]
                    missing = [c for c in ("angle_deg", "error_arcsec") if c not in cols]
                    if missing:
                        raise UserInputError(f"{path}:{hdr_ln}: header lacks column(s) {', '.join(missing)} "
                                             f"(found {', '.join(cols) or 'nothing'})")
                    ia, ie = cols.index("angle_deg"), cols.index("error_arcsec")
                    continue
                msg = _row_problem(path, ln, r, cols, ia, ie)
                if msg is not None:
                    n_problems += 1
                    if len(problems) < 20:
                        problems.append(msg)
                    continue
                ang.append(float(r[ia]))
                err.append(float(r[ie]))
                lines.append(ln)
    except UnicodeDecodeError as exc:
        raise UserInputError(f"{path}: not UTF-8 text (byte {exc.start}): is this a CSV table?") from None
    except csv.Error as exc:
        raise UserInputError(f"{path}: not a readable CSV table ({exc})") from None
    if cols is None:
        raise UserInputError(f"{path}: empty file (expected a header angle_deg,error_arcsec)")
    if problems:
        raise UserInputError("\n".join(problems) + (
            f"\n{path}: ... and {n_problems - 20} more bad rows" if n_problems > 20 else ""))
    if not ang:
        raise UserInputError(f"{path}: no data rows")
    a = np.array(ang)
    wrapped = np.round(np.mod(a, 360.0), 9)
    if np.unique(wrapped).size != a.size:
        seen: dict = {}
        for i, w in enumerate(wrapped):
            if w in seen:
                j = seen[w]
                raise UserInputError(f"{path}:{lines[i]}: duplicated angle: angle_deg {ang[i]:g} repeats line {lines[j]}'s "
                                     f"{ang[j]:g} (modulo 360 deg)")
            seen[w] = i
    return a, np.array(err)
