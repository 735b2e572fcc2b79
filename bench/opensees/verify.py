#!/usr/bin/env python3
"""Checks every material of the catalogue against the gear-like targets and prints its figures.

Each material is driven from rest along the benchmark's sine (A = 1.168 mrad, 0.5 Hz, 4 cycles,
1 kHz) and measured on its last cycle:
  peak      max |T| over the last cycle, N·m (target: about 28);
  width     falling minus rising torque at θ = 0, relative to the peak (target: 2–4 %);
  K0, K+, K−  slope of the loop's centre curve at |θ| ≤ 0.05·A, and over 0.85–0.95 A each side;
  stiffening  K± / K0 (target: 2–4 on each side);
  asym      K+ / K− (the asymmetric gear: 0.75–0.80, the others: 1);
and its tangent is checked (`loops.tangent_checks`): finite, positive, each step's secant within
the tangents at its ends, no torque jump at a reversal. Also run along the nested motion
(reversals at many levels). Exit status 1 if a target is missed.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from loops import centre_slope, loop_width, tangent_checks
from materials import AMPLITUDE_RAD, MATERIALS, drive

FREQUENCY_HZ, CYCLES, RATE_HZ = 0.5, 4, 1000.0


def sine_and_nested() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t = np.arange(int(CYCLES / FREQUENCY_HZ * RATE_HZ) + 1) / RATE_HZ
    phase = 2 * np.pi * FREQUENCY_HZ * t
    return t, AMPLITUDE_RAD * np.sin(phase), AMPLITUDE_RAD * (0.75 * np.sin(phase) + 0.25 * np.sin(9 * phase))


def measure(name: str) -> dict:
    t, sine, nested = sine_and_nested()
    torque, tangent = drive(name, sine)
    last = t >= t[-1] - 1.25 / FREQUENCY_HZ  # the last cycle, with both crossings of 0 inside
    theta, T = sine[last], torque[last]
    peak = float(np.max(np.abs(torque[t >= t[-1] - 1 / FREQUENCY_HZ])))
    a = AMPLITUDE_RAD
    k0 = centre_slope(theta, T, -0.05 * a, 0.05 * a)
    k_pos = centre_slope(theta, T, 0.85 * a, 0.95 * a)
    k_neg = centre_slope(theta, T, -0.95 * a, -0.85 * a)
    nested_torque, nested_tangent = drive(name, nested)
    checks = [tangent_checks(sine, torque, tangent), tangent_checks(nested, nested_torque, nested_tangent)]
    width = loop_width(theta, T, 0.0)
    return {
        "peak_nm": peak,
        "peak_pos_nm": float(np.max(T)),
        "peak_neg_nm": float(-np.min(T)),
        "width_nm": width,
        "width_rel": width / peak,
        "k0_nm_per_rad": k0,
        "k_pos_nm_per_rad": k_pos,
        "k_neg_nm_per_rad": k_neg,
        "stiffening_pos": k_pos / k0,
        "stiffening_neg": k_neg / k0,
        "asymmetry": k_pos / k_neg,
        "checks": {key: max(c[key] for c in checks) if key != "min_tangent" else min(c[key] for c in checks)
                   for key in checks[0]},
    }


def target_misses(name: str, m: dict) -> list[str]:
    """The gear-like targets a material misses."""
    out = []
    if not 24.0 <= m["peak_nm"] <= 32.0:
        out.append(f"peak {m['peak_nm']:.2f} N·m is not about 28")
    if not 0.02 <= m["width_rel"] <= 0.04:
        out.append(f"loop width {100 * m['width_rel']:.2f} % is not 2–4 %")
    for side in ("pos", "neg"):
        if not 2.0 <= m[f"stiffening_{side}"] <= 4.0:
            out.append(f"stiffening {m[f'stiffening_{side}']:.2f}× ({side}) is not 2–4×")
    wanted = (0.75, 0.80) if name == "asymmetric" else (0.97, 1.03)
    if not wanted[0] <= m["asymmetry"] <= wanted[1]:
        out.append(f"K+/K− {m['asymmetry']:.3f} is not within {wanted}")
    return out


def tangent_misses(c: dict) -> list[str]:
    """What is wrong with OpenSees' torque and tangent (`loops.tangent_checks`, worst over runs)."""
    out = []
    if not c["finite"]:
        out.append("torque or tangent not finite")
    if c["min_tangent"] <= 0:
        out.append(f"tangent {c['min_tangent']:.1f} ≤ 0")
    if c["secant_outside_tangents_max_rel"] > 0.05:
        out.append(f"a step's secant is {100 * c['secant_outside_tangents_max_rel']:.1f} % outside its tangents")
    if c["reversal_jump_over_tangent_step_max"] > 1.05:
        out.append(f"torque jumps at a reversal ({c['reversal_jump_over_tangent_step_max']:.2f}× the tangent's step)")
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("materials", nargs="*", default=list(MATERIALS), help="names (default: all)")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    figures, failed = {}, False
    if not args.json:
        print("| material | peak N·m (+/−) | width at θ=0 | K0 N·m/rad | K+/K0 | K−/K0 | K+/K− | tangent |")
        print("|---|---|---|---|---|---|---|---|")
    for name in args.materials:
        if name not in MATERIALS:
            print(f"error: unknown material {name!r}: expected one of {', '.join(MATERIALS)}", file=sys.stderr)
            return 2
        m = measure(name)
        figures[name] = m
        bad_tangent = tangent_misses(m["checks"])
        missed = target_misses(name, m) + bad_tangent
        failed |= bool(missed)
        if not args.json:
            c = m["checks"]
            tangent = "BAD" if bad_tangent else "ok"
            print(
                f"| {name} | {m['peak_nm']:.2f} ({m['peak_pos_nm']:.2f}/{m['peak_neg_nm']:.2f}) | "
                f"{m['width_nm']:.3f} N·m ({100 * m['width_rel']:.2f} %) | {m['k0_nm_per_rad']:.0f} | "
                f"{m['stiffening_pos']:.2f} | {m['stiffening_neg']:.2f} | {m['asymmetry']:.3f} | {tangent} "
                f"(min {c['min_tangent']:.0f}, secant off ≤ {100 * c['secant_outside_tangents_max_rel']:.2f} %, "
                f"reversal step ≤ {c['reversal_jump_over_tangent_step_max']:.2f}×) |"
            )
            for miss in missed:
                print(f"  MISSED {name}: {miss}", file=sys.stderr)
    if args.json:
        print(json.dumps(figures, indent=1))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
