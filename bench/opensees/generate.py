#!/usr/bin/env python3
"""Generates the OpenSees gear corpus: every catalogued material under every motion of the
prediction benchmark (tests/prediction_corpus.rs), as our simulator would record it.

    python generate.py --out DIR [--swg-host PATH] [--seed 11]

For each MATERIAL and MOTION it writes
  MATERIAL-MOTION.csv        the measured recording, format v1 (time_s,theta_in_rad,theta_out_rad,
                             torque_nm): the truth torque plus Gaussian torque noise, the angles
                             as the 20-bit encoders read them;
  MATERIAL-MOTION.truth.csv  the material along the true deflection, noise-free;
  MATERIAL-MOTION.floor.csv  the material along the measured deflection θ_in/N − θ_out: what the
                             encoders' quantisation leaves, which no model can beat by much;
(the last two as drive.py writes: time_s,deflection_rad,torque_nm,tangent_nm_per_rad), and
MANIFEST.json and README.md listing materials, parameters, motions and each file's figures.

The motions and the encoders are our simulator's own, not a copy: `swg-host simulate` plays
each motion twice with the benchmark's settings, once with exact encoders (its θ_out is minus
the true deflection, the input being locked) and once with 20-bit encoders on both sides (its
quantised θ_in, θ_out are the recording's angles). So the random motion's seeded frequencies
and phases, the ramps and the encoder rounding are bit for bit what the benchmark records; a
Python port of host/src/simulate/motion.rs would have to reproduce its ChaCha8 stream. The
simulator's own torque column (its genetic gear) is discarded.

Torque noise: as our simulator, Gaussian with σ = --torque-noise added to the torque at the
true deflection, from a generator seeded with --seed for every recording (so every file has the
same noise sequence, as ours do); numpy's default_rng(seed), not the simulator's ChaCha8.
Output is deterministic for a seed.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from importlib.metadata import version
from pathlib import Path

import numpy as np

from drive import InputError, parse_number, read_table, series_csv, write_atomically
from loops import loop_width, tangent_checks
from materials import AMPLITUDE_RAD, MATERIALS, drive
from verify import measure

REPO = Path(__file__).resolve().parents[2]
MOTIONS = ["sine", "biased", "nested", "random", "hold"]
# The prediction benchmark's recording (tests/prediction_corpus.rs `simulation(noisy)`).
FREQUENCY_HZ, CYCLES, RATE_HZ, RATIO, ENCODER_BITS, TORQUE_NOISE_NM, SEED = 0.5, 4, 1000.0, 50.0, 20, 0.05, 11
# Period of each motion's innermost repeated loop, s (hold's dither runs at 10× the frequency);
# random has none. Biased and hold ramp from rest for one period 1/f first.
RAMP_S = {"biased": 1 / FREQUENCY_HZ, "hold": 1 / FREQUENCY_HZ}
LOOP_PERIOD_S = {"sine": 1 / FREQUENCY_HZ, "biased": 1 / FREQUENCY_HZ, "nested": 1 / FREQUENCY_HZ,
                 "hold": 0.1 / FREQUENCY_HZ}


def simulate(swg_host: Path, motion: str, encoders: bool, seed: int, out: Path) -> dict[str, np.ndarray]:
    """The columns time_s, theta_in_rad, theta_out_rad of `motion` as `swg-host simulate` records it."""
    command = [
        str(swg_host), "simulate", "--motion", motion, "--out", str(out), "--amplitude", repr(AMPLITUDE_RAD),
        "--frequency", repr(FREQUENCY_HZ), "--cycles", str(CYCLES), "--rate", repr(RATE_HZ),
        "--ratio", repr(RATIO), "--torque-noise", "0", "--seed", str(seed),
    ]
    if encoders:
        command += ["--input-bits", str(ENCODER_BITS), "--output-bits", str(ENCODER_BITS)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr.strip()}")
    names = {"time_s": "s", "theta_in_rad": "rad", "theta_out_rad": "rad"}
    rows, columns, _ = read_table(out, names)
    values = {
        name: np.array([parse_number(cells[columns[name]], f"{out}:{line}: column {name}") for line, cells in rows])
        for name in names
    }
    return values


def deflection(angles: dict[str, np.ndarray]) -> np.ndarray:
    """θ = θ_in/N − θ_out, as host/src/input/mod.rs computes it."""
    return angles["theta_in_rad"] / RATIO - angles["theta_out_rad"]


def recording_csv(material: str, motion: str, seed: int, noise_nm: float, angles: dict, torque) -> str:
    lines = [
        "# swg-recording v1",
        f"# ratio: {RATIO:g}",
        "# start: rest",
        f"# physics: opensees {material}",
        f"# source: bench/opensees/generate.py (OpenSeesPy {version('openseespy')}, motion and encoders "
        "from swg-host simulate)",
        f"# motion: {motion}",
        f"# amplitude_rad: {AMPLITUDE_RAD!r}",
        f"# frequencies_hz: {FREQUENCY_HZ!r}",
        f"# seed: {seed}",
        f"# torque_noise_nm: {noise_nm!r}",
        f"# encoder_bits: {ENCODER_BITS} {ENCODER_BITS}",
        "time_s,theta_in_rad,theta_out_rad,torque_nm",
    ]
    columns = [angles["time_s"], angles["theta_in_rad"], angles["theta_out_rad"], torque]
    lines += [",".join(repr(float(v)) for v in row) for row in zip(*columns)]
    return "\n".join(lines) + "\n"


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def file_figures(motion: str, t: np.ndarray, theta: np.ndarray, truth: np.ndarray, floor: np.ndarray) -> dict:
    """Peak torque; the width of the last repeated loop at its mid deflection (None for random);
    after a ramp, the drift of the loops' mean torque from the second loop to the last (the first
    still leaves the virgin curve): ratcheting, which return-point memory forbids."""
    peak = float(np.max(np.abs(truth)))
    figures = {"samples": len(t), "deflection_range_rad": [float(theta.min()), float(theta.max())],
               "torque_range_nm": [float(truth.min()), float(truth.max())], "peak_torque_nm": peak}
    period = LOOP_PERIOD_S.get(motion)
    if period is None:
        figures.update(loop_width_nm=None, loop_width_at_rad=None, loop_width_rel=None)
    else:
        last = t >= t[-1] - 1.25 * period  # the last loop, with its crossings of the mid level inside
        level = 0.5 * (theta[t >= t[-1] - period].min() + theta[t >= t[-1] - period].max())
        width = loop_width(theta[last], truth[last], level)
        figures.update(loop_width_nm=width, loop_width_at_rad=float(level), loop_width_rel=width / peak)
    if motion in RAMP_S:
        second = (t >= RAMP_S[motion] + period) & (t < RAMP_S[motion] + 2 * period)
        figures["loop_drift_nm"] = float(np.mean(truth[t > t[-1] - period]) - np.mean(truth[second]))
    figures["floor_rms_nm"] = rms(floor, truth)
    return figures


def readme(manifest: dict) -> str:
    out = [
        "# OpenSees gear corpus",
        "",
        f"Generated by `{manifest['generator']}` (OpenSeesPy {manifest['openseespy']}); see bench/opensees/README.md.",
        f"Motions: {', '.join(manifest['motions'])}, from `swg-host simulate` with {json.dumps(manifest['settings'])}.",
        "",
        "## Materials (sine from rest, last cycle)",
        "",
        "| material | peak N·m | loop width at θ = 0 | K+/K0 | K−/K0 | K+/K− | what |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, m in manifest["materials"].items():
        s = m["sine"]
        out.append(
            f"| {name} | {s['peak_nm']:.2f} | {s['width_nm']:.3f} N·m ({100 * s['width_rel']:.2f} %) | "
            f"{s['stiffening_pos']:.2f} | {s['stiffening_neg']:.2f} | {s['asymmetry']:.3f} | {m['summary']} |"
        )
    out += ["", "Parameters: MANIFEST.json (`materials.NAME.params`, SI units in the names).", "",
            "## Files", "",
            "| recording | peak N·m | loop width N·m (at θ, rad) | width / peak | loop drift N·m | floor RMS N·m |",
            "|---|---|---|---|---|---|"]
    for f in manifest["files"]:
        width = "—" if f["loop_width_nm"] is None else f"{f['loop_width_nm']:.3f} ({f['loop_width_at_rad']:.3e})"
        rel = "—" if f["loop_width_rel"] is None else f"{100 * f['loop_width_rel']:.2f} %"
        drift = f"{f['loop_drift_nm']:+.4f}" if "loop_drift_nm" in f else "—"
        out.append(f"| {f['recording']} | {f['peak_torque_nm']:.2f} | {width} | {rel} | {drift} | "
                   f"{f['floor_rms_nm']:.4f} |")
    return "\n".join(out) + "\n"


def default_swg_host() -> Path:
    return Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target")) / "release" / "swg-host"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", required=True, type=Path, help="directory for the corpus (created)")
    parser.add_argument("--swg-host", type=Path, default=default_swg_host(), help="the release binary")
    parser.add_argument("--seed", type=int, default=SEED, help="random motion and torque noise (default 11)")
    parser.add_argument("--torque-noise", type=float, default=TORQUE_NOISE_NM, help="σ, N·m (default 0.05)")
    parser.add_argument("--materials", nargs="+", default=list(MATERIALS), choices=list(MATERIALS))
    parser.add_argument("--motions", nargs="+", default=MOTIONS, choices=MOTIONS)
    args = parser.parse_args()
    if not args.swg_host.is_file():
        print(f"error: {args.swg_host}: no such binary (cargo build --release -p swg-host)", file=sys.stderr)
        return 1
    started = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    manifest = {
        "generator": "bench/opensees/generate.py",
        "openseespy": version("openseespy"),
        "numpy": version("numpy"),
        "settings": {"amplitude_rad": AMPLITUDE_RAD, "frequency_hz": FREQUENCY_HZ, "cycles": CYCLES,
                     "rate_hz": RATE_HZ, "ratio": RATIO, "encoder_bits": ENCODER_BITS, "input": "locked",
                     "torque_noise_nm": args.torque_noise, "seed": args.seed},
        "noise": "numpy default_rng(seed).normal(0, torque_noise_nm), the same sequence in every recording",
        "motions": args.motions,
        "materials": {name: {"summary": MATERIALS[name].summary, "params": MATERIALS[name].params,
                             "sine": measure(name)} for name in args.materials},
        "files": [],
    }
    try:
        with tempfile.TemporaryDirectory() as scratch:
            for motion in args.motions:
                true_angles = simulate(args.swg_host, motion, False, args.seed, Path(scratch) / "exact.csv")
                angles = simulate(args.swg_host, motion, True, args.seed, Path(scratch) / "encoders.csv")
                t = angles["time_s"]
                if not np.array_equal(t, true_angles["time_s"]):
                    raise RuntimeError(f"{motion}: the two simulations' times differ")
                exact, measured = deflection(true_angles), deflection(angles)
                noise = np.random.default_rng(args.seed).normal(0.0, args.torque_noise, len(t))
                for name in args.materials:
                    truth, truth_tangent = drive(name, exact)
                    floor, floor_tangent = drive(name, measured)
                    for path, theta, torque, tangent in [("truth", exact, truth, truth_tangent),
                                                         ("floor", measured, floor, floor_tangent)]:
                        checks = tangent_checks(theta, torque, tangent)
                        if not checks["finite"] or checks["min_tangent"] <= 0:
                            raise RuntimeError(f"{name} {motion} {path}: OpenSees misbehaves: {checks}")
                    stem = f"{name}-{motion}"
                    write_atomically(args.out / f"{stem}.csv",
                                     recording_csv(name, motion, args.seed, args.torque_noise, angles, truth + noise))
                    about = [f"physics: opensees {name}", f"motion: {motion}", f"seed: {args.seed}"]
                    write_atomically(args.out / f"{stem}.truth.csv",
                                     series_csv([*about, "truth: along the true deflection, noise-free"],
                                                t, exact, truth, truth_tangent))
                    write_atomically(args.out / f"{stem}.floor.csv",
                                     series_csv([*about, "floor: along the measured deflection (20-bit encoders)"],
                                                t, measured, floor, floor_tangent))
                    manifest["files"].append({
                        "recording": f"{stem}.csv", "truth": f"{stem}.truth.csv", "floor": f"{stem}.floor.csv",
                        "material": name, "motion": motion, **file_figures(motion, t, exact, truth, floor),
                    })
    except (InputError, RuntimeError, OSError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    write_atomically(args.out / "MANIFEST.json", json.dumps(manifest, indent=1, ensure_ascii=False) + "\n")
    write_atomically(args.out / "README.md", readme(manifest))
    size = sum(f.stat().st_size for f in args.out.iterdir() if f.is_file())
    print(f"{len(manifest['files'])} recordings (+ truth and floor) in {args.out}: {size / 1e6:.1f} MB, "
          f"{time.perf_counter() - started:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
