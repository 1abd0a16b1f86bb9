"""The scan plan as data (seed 003, section 4 of the paper): segments evaluated on any time grid.

Segment kinds (all times in s, angles in deg):

* ``dwell``: hold the current angles for ``duration_s`` (``star_sensing = true`` marks a
  star-sensing dwell);
* ``move``: both axes to (``to_alpha_deg``, ``to_beta_deg``) with a trapezoidal velocity
  profile (``accel_s`` uniform acceleration, ``const_s`` uniform speed, ``decel_s`` uniform
  deceleration): the paper's retrace and star slew;
* ``area_scan``: ``lines`` east-west lines of ``line_deg`` of beta in ``line_s`` each
  (bidirectional: every second line runs back), each with a trapezoidal profile whose acceleration and
  deceleration last ``turnaround_s / 2``; alpha steps by ``step_deg`` during the deceleration
  at the end of every line but the last (the paper: "the step is made while the east-west
  motion decelerates and accelerates").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["trapezoid_fraction", "PlanSamples", "evaluate_plan"]


def trapezoid_fraction(tau_s, accel_s: float, const_s: float, decel_s: float):
    """Fraction (0..1) of a move done at ``tau_s`` into a trapezoidal-velocity profile
    (uniform acceleration, constant speed, uniform deceleration; peak speed
    ``1 / (accel/2 + const + decel/2)``)."""
    tau = np.clip(np.asarray(tau_s, float), 0.0, accel_s + const_s + decel_s)
    v = 1.0 / (0.5 * accel_s + const_s + 0.5 * decel_s)
    t1, t2 = accel_s, accel_s + const_s
    with np.errstate(divide="ignore", invalid="ignore"):
        f_acc = 0.5 * v * tau**2 / accel_s if accel_s > 0 else np.zeros_like(tau)
        d = accel_s + const_s + decel_s - tau
        f_dec = 1.0 - (0.5 * v * d**2 / decel_s if decel_s > 0 else np.zeros_like(tau))
    f_con = 0.5 * v * accel_s + v * (tau - t1)
    return np.where(tau < t1, f_acc, np.where(tau <= t2, f_con, f_dec))


@dataclass(frozen=True)
class PlanSamples:
    """The plan evaluated on a grid: angles (rad) and labels per sample."""

    t_s: np.ndarray
    alpha_rad: np.ndarray
    beta_rad: np.ndarray
    segment: np.ndarray      # segment index (-1 after the plan: static)
    scan: np.ndarray         # area-scan number 1, 2, ... (0 outside area scans)
    star_dwell: np.ndarray   # star-sensing dwell number 1, 2, ... (0 elsewhere)


def segment_durations(segments) -> list[float]:
    """Duration (s) of each segment."""
    out = []
    for seg in segments:
        if seg.kind == "dwell":
            out.append(seg.duration_s)
        elif seg.kind == "move":
            out.append(seg.accel_s + seg.const_s + seg.decel_s)
        else:
            out.append(seg.lines * seg.line_s)
    return out


def evaluate_plan(plan, t_s) -> PlanSamples:
    """Evaluate the scan plan (a :class:`simcam.scanmirror.scenario.ScanPlan`) at ``t_s``."""
    t = np.asarray(t_s, float)
    alpha = np.full(t.shape, np.deg2rad(plan.initial_alpha_deg))
    beta = np.full(t.shape, np.deg2rad(plan.initial_beta_deg))
    segment = np.full(t.shape, -1, dtype=np.int64)
    scan = np.zeros(t.shape, dtype=np.int64)
    star = np.zeros(t.shape, dtype=np.int64)
    a0, b0 = plan.initial_alpha_deg, plan.initial_beta_deg
    start = 0.0
    n_scan = n_star = 0
    for j, (seg, dur) in enumerate(zip(plan.segments, segment_durations(plan.segments))):
        m = (t >= start) & (t < start + dur)
        tau = t[m] - start
        if seg.kind == "dwell":
            a1, b1 = a0, b0
            alpha[m], beta[m] = np.deg2rad(a0), np.deg2rad(b0)
            if seg.star_sensing:
                n_star += 1
                star[m] = n_star
        elif seg.kind == "move":
            a1, b1 = seg.to_alpha_deg, seg.to_beta_deg
            f = trapezoid_fraction(tau, seg.accel_s, seg.const_s, seg.decel_s)
            alpha[m] = np.deg2rad(a0 + (a1 - a0) * f)
            beta[m] = np.deg2rad(b0 + (b1 - b0) * f)
        else:
            n_scan += 1
            scan[m] = n_scan
            k = np.minimum((tau // seg.line_s).astype(np.int64), seg.lines - 1)
            tl = tau - k * seg.line_s
            half = 0.5 * seg.turnaround_s
            f = trapezoid_fraction(tl, half, seg.line_s - seg.turnaround_s, half)
            sign = np.where(k % 2 == 0, 1.0, -1.0)
            start_b = np.where(sign > 0, b0, b0 + seg.line_deg)
            beta[m] = np.deg2rad(start_b + sign * seg.line_deg * f)
            fs = trapezoid_fraction(tl - (seg.line_s - half), half / 2, 0.0, half / 2)
            fs = np.where(k < seg.lines - 1, fs, 0.0)
            alpha[m] = np.deg2rad(a0 + seg.step_deg * (k + fs))
            a1 = a0 + seg.step_deg * (seg.lines - 1)
            b1 = b0 + (seg.line_deg if seg.lines % 2 == 1 else 0.0)
        segment[m] = j
        a0, b0 = a1, b1
        start += dur
    after = t >= start
    alpha[after], beta[after] = np.deg2rad(a0), np.deg2rad(b0)
    return PlanSamples(t, alpha, beta, segment, scan, star)


def plan_duration_s(plan) -> float:
    """Total duration of the plan's segments (s)."""
    return float(sum(segment_durations(plan.segments)))


__all__ += ["segment_durations", "plan_duration_s"]
