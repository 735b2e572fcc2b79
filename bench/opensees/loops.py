"""Figures of a driven material: loop width at a level, the stiffness of the loop's centre curve,
and the sanity of OpenSees' tangent."""
from __future__ import annotations

import math

import numpy as np


def crossings(theta: np.ndarray, torque: np.ndarray, level: float) -> tuple[list[float], list[float]]:
    """Torques where θ passes `level` rising and falling, interpolated between samples (a sample
    exactly at the level counts once, for the direction of the motion through it)."""
    rising, falling = [], []
    offset = theta - level
    for i in range(len(theta) - 1):
        a, b = offset[i], offset[i + 1]
        if a == b or a * b > 0 or b == 0:  # b == 0: counted as the next step's a
            continue
        if a == 0 and (i == 0 or offset[i - 1] * b >= 0):  # touched, not passed
            continue
        w = a / (a - b)
        (rising if b > a else falling).append(torque[i] + w * (torque[i + 1] - torque[i]))
    return rising, falling


def loop_width(theta: np.ndarray, torque: np.ndarray, level: float) -> float | None:
    """Mean rising torque minus mean falling torque (positive for a passive loop) where θ passes `level`; None if it is not
    passed both ways."""
    rising, falling = crossings(theta, torque, level)
    if not rising or not falling:
        return None
    return float(np.mean(rising) - np.mean(falling))


def branches(theta: np.ndarray, torque: np.ndarray) -> tuple[tuple, tuple]:
    """The (θ, T) samples of a window split into its rising and falling steps, each sorted by θ."""
    step = np.diff(theta)
    mid_theta = theta[1:]
    mid_torque = torque[1:]
    out = []
    for mask in (step > 0, step < 0):
        order = np.argsort(mid_theta[mask])
        out.append((mid_theta[mask][order], mid_torque[mask][order]))
    return out[0], out[1]


def centre_slope(theta: np.ndarray, torque: np.ndarray, low: float, high: float) -> float:
    """Slope of the loop's centre curve (mean of its rising and falling branch) over [low, high],
    by a least-squares line through 21 points."""
    (rt, rT), (ft, fT) = branches(theta, torque)
    grid = np.linspace(low, high, 21)
    centre = 0.5 * (np.interp(grid, rt, rT) + np.interp(grid, ft, fT))
    return float(np.polyfit(grid, centre, 1)[0])


def tangent_checks(theta: np.ndarray, torque: np.ndarray, tangent: np.ndarray) -> dict:
    """What OpenSees' getTangent says against the torque it returns: finite and positive
    everywhere; each step's secant ΔT/Δθ within the tangents at its two ends (±5 %, widened by
    the knots of a tabulated spring); the torque continuous at reversals (the step there no
    larger than the tangent allows)."""
    finite = bool(np.all(np.isfinite(torque)) and np.all(np.isfinite(tangent)))
    step = np.diff(theta)
    moving = step != 0
    secant = np.diff(torque)[moving] / step[moving]
    lo = np.minimum(tangent[:-1], tangent[1:])[moving]
    hi = np.maximum(tangent[:-1], tangent[1:])[moving]
    outside = np.maximum(lo * 0.95 - secant, secant - hi * 1.05)
    scale = np.maximum(hi, 1.0)
    reversal = np.flatnonzero(step[1:] * step[:-1] < 0) + 1  # sample i where the motion turns
    jump = [abs(torque[i + 1] - torque[i]) / (max(tangent[i], tangent[i + 1]) * abs(step[i]))
            for i in reversal if step[i] != 0]
    return {
        "finite": finite,
        "min_tangent": float(np.min(tangent)),
        "secant_outside_tangents_max_rel": float(np.max(np.maximum(outside, 0.0) / scale)),
        "reversal_jump_over_tangent_step_max": float(max(jump)) if jump else math.nan,
    }
