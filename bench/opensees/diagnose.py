#!/usr/bin/env python3
"""The diagnosis on gears from an independent simulator: every OpenSees material of the catalogue
with one concealed effect or none, recorded as our bench would, then `swg-host diagnose`.

    python diagnose.py OUT_DIR [--swg-host PATH] [--seed 11]

The motion is the diagnosis corpus' (tests/diagnose_corpus.rs) two-rate sine: from rest, 3 cycles
at 0.2 Hz then 3 at 0.6 Hz, A = 1.168 mrad, 1 kHz, 20-bit encoders on both sides (`swg-host
simulate`'s, as generate.py takes them), Gaussian torque noise σ = 0.05 N·m. The effects, added to
the material's torque along the true deflection (or, for backlash, driving the material through
the dead band), with the magnitudes of the corpus' gears of other physics where it has them:

  torque_offset     +0.15 N·m
  coulomb_friction  0.10 N·m · sign(dθ/dt)
  viscous_damping   40 N·m·s/rad · dθ/dt
  channel_delay     τ = −2 ms: the torque channel read 2 ms early (linear interpolation)
  backlash          a dead band 20 µrad wide: the material driven by sign(θ)·max(|θ| − w/2, 0)

Scored as the corpus scores its gears of other physics: right when exactly the truth is named
(or kept undecided between it and its rival, nothing else named); an effect named that is not
there stands in for the material's shape: wrong physics; a rate effect named for its rival:
wrong physics. A finding of form counts as wrong physics where the material cannot have it
(asymmetry but on `asymmetric`; stiffness_kinks but on `catalogue`, the only spring that steps
away from zero; non_masing on `iwan`, `catalogue`, `asymmetric`, whose elements are
elastic-perfectly-plastic, Masing's; ratcheting but on `bouc-wen`). A miss whose effect the
report lists as one that cannot be told from this data (`not_revealable`) is counted apart: an
honest "cannot tell", not a right answer. Prints a markdown table
and the counts; writes the recordings and each diagnosis (JSON) to OUT_DIR.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from drive import write_atomically
from generate import ENCODER_BITS, RATIO, default_swg_host, deflection
from materials import AMPLITUDE_RAD, MATERIALS, drive

FREQUENCIES_HZ, CYCLES, RATE_HZ, NOISE_NM = "0.2,0.6", 3, 1000.0, 0.05
EFFECTS = {
    "none": None,
    "torque_offset": 0.15,
    "coulomb_friction": 0.10,
    "viscous_damping": 40.0,
    "channel_delay": -2e-3,
    "backlash": 20e-6,
}
RIVAL = {"viscous_damping": "channel_delay", "channel_delay": "viscous_damping"}
# Findings of form each material may show.
MAY_SHOW = {
    "asymmetry": {"asymmetric"},
    "stiffness_kinks": {"catalogue"},
    "non_masing": {"steel02", "bouc-wen", "hysteretic"},
    "ratcheting": {"bouc-wen"},
}


def simulate(swg_host: Path, encoders: bool, seed: int, out: Path) -> dict[str, np.ndarray]:
    """time_s, theta_in_rad, theta_out_rad of the two-rate sine as `swg-host simulate` records it."""
    command = [str(swg_host), "simulate", "--out", str(out), "--amplitude", repr(AMPLITUDE_RAD),
               "--frequency", FREQUENCIES_HZ, "--cycles", str(CYCLES), "--rate", repr(RATE_HZ),
               "--ratio", repr(RATIO), "--torque-noise", "0", "--seed", str(seed)]
    if encoders:
        command += ["--input-bits", str(ENCODER_BITS), "--output-bits", str(ENCODER_BITS)]
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr.strip()}")
    rows = [line for line in out.read_text().splitlines() if line and not line.startswith("#")]
    header = rows[0].split(",")
    values = np.array([[float(cell) for cell in row.split(",")] for row in rows[1:]])
    return {name: values[:, header.index(name)] for name in ("time_s", "theta_in_rad", "theta_out_rad")}


def recording_csv(material: str, effect: str, value, seed: int, angles: dict, torque: np.ndarray) -> str:
    lines = [
        "# swg-recording v1",
        f"# ratio: {RATIO:g}",
        "# start: rest",
        f"# physics: opensees {material}",
        "# source: bench/opensees/diagnose.py (motion and encoders from swg-host simulate)",
        f"# motion: sine, {CYCLES} cycles at each of {FREQUENCIES_HZ} Hz",
        f"# amplitude_rad: {AMPLITUDE_RAD!r}",
        f"# concealed: {effect}" + ("" if value is None else f" {value!r}"),
        f"# seed: {seed}",
        f"# torque_noise_nm: {NOISE_NM!r}",
        f"# encoder_bits: {ENCODER_BITS} {ENCODER_BITS}",
        "time_s,theta_in_rad,theta_out_rad,torque_nm",
    ]
    columns = [angles["time_s"], angles["theta_in_rad"], angles["theta_out_rad"], torque]
    lines += [",".join(repr(float(v)) for v in row) for row in zip(*columns)]
    return "\n".join(lines) + "\n"


def with_effect(name: str, effect: str, value, t: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """The material's torque along the true deflection `theta` with `effect` of magnitude `value`."""
    if effect == "backlash":
        elastic = np.sign(theta) * np.maximum(np.abs(theta) - value / 2, 0.0)
        return drive(name, elastic)[0]
    torque = drive(name, theta)[0]
    rate = np.gradient(theta, t)
    if effect == "torque_offset":
        return torque + value
    if effect == "coulomb_friction":
        return torque + value * np.sign(rate)
    if effect == "viscous_damping":
        return torque + value * rate
    if effect == "channel_delay":
        return np.interp(t - value, t, torque)
    return torque


def score(material: str, truth: str, report: dict) -> dict:
    named = [f["effect"] for f in report.get("findings", [])]
    undecided = [u["effects"] for u in report.get("undecided", [])]
    truth_set = [] if truth == "none" else [truth]
    found = [e for e in truth_set if e in named or any(e in pair for pair in undecided)]
    wrong = [e for e in named if e not in truth_set]
    forms = []
    for finding, allowed in MAY_SHOW.items():
        check = report.get(finding, {})
        if check.get("tested") == "yes" and check.get("rejected") is None:
            forms.append(finding)
            if material not in allowed:
                wrong.append(finding)
    kept = [u for u in undecided if truth in u]
    untold = [u["effect"] for u in report.get("not_revealable", [])]
    missed = [e for e in truth_set if e not in found]
    return {
        "named": named, "undecided": undecided, "forms": forms, "wrong": wrong,
        "right": len(found) == len(truth_set) and not [e for e in named if e not in truth_set],
        "miss": len(missed),
        # Missed, but the report says it cannot be told from this data: honest, not right.
        "cannot_tell": bool(missed) and all(e in untold for e in missed),
        "told_as_either": bool(kept) and truth not in named,
        "rival": any(RIVAL.get(truth) == e for e in named),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="directory for the recordings and diagnoses (created)")
    parser.add_argument("--swg-host", type=Path, default=default_swg_host(), help="the release binary")
    parser.add_argument("--seed", type=int, default=11, help="torque noise (default 11)")
    args = parser.parse_args()
    if not args.swg_host.is_file():
        print(f"error: {args.swg_host}: no such binary (cargo build --release -p swg-host)", file=sys.stderr)
        return 1
    started = time.perf_counter()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as scratch:
        exact = simulate(args.swg_host, False, args.seed, Path(scratch) / "exact.csv")
        angles = simulate(args.swg_host, True, args.seed, Path(scratch) / "encoders.csv")
    t, theta = exact["time_s"], deflection(exact)
    noise = np.random.default_rng(args.seed).normal(0.0, NOISE_NM, len(t))
    rows = []
    for material in MATERIALS:
        for effect, value in EFFECTS.items():
            torque = with_effect(material, effect, value, t, theta) + noise
            stem = f"{material}-{effect}"
            path = args.out / f"{stem}.csv"
            text = recording_csv(material, effect, value, args.seed, angles, torque)
            write_atomically(path, text)
            done = subprocess.run([str(args.swg_host), "diagnose", str(path), "--json"], capture_output=True,
                                  text=True)
            if done.returncode != 0:
                print(f"error: diagnose {path}: {done.stderr.strip()}", file=sys.stderr)
                return 1
            write_atomically(args.out / f"{stem}.diagnosis.json", done.stdout)
            rows.append((material, effect, value, score(material, effect, json.loads(done.stdout))))
    print(f"**OpenSees diagnosis corpus** ({len(rows)} recordings: 6 materials × none or one concealed effect, "
          f"two-rate sine; `bash bench/opensees/run.sh OUT`, OUT/diagnose)\n")
    print("| material | concealed | named | undecided | findings of form | verdict |")
    print("|---|---|---|---|---|---|")
    for material, effect, value, s in rows:
        verdict = ("wrong physics: " + ", ".join(s["wrong"])) if s["wrong"] else (
            "right" if s["right"] else "missed")
        if s["right"] and s["told_as_either"]:
            verdict = "right (either of two)"
        if not s["wrong"] and s["cannot_tell"]:
            verdict = "missed: said it cannot be told"
        undecided = "; ".join(" or ".join(pair) for pair in s["undecided"]) or "—"
        print(f"| {material} | {effect}{'' if value is None else f' {value:g}'} | {', '.join(s['named']) or '—'} | "
              f"{undecided} | {', '.join(s['forms']) or '—'} | {verdict} |")
    right = sum(s["right"] for *_, s in rows)
    wrong = sum(len(s["wrong"]) for *_, s in rows)
    misses = sum(s["miss"] for *_, s in rows)
    either = sum(s["told_as_either"] for *_, s in rows)
    cannot_tell = sum(s["cannot_tell"] and not s["wrong"] for *_, s in rows)
    print(f"\n{right}/{len(rows)} right ({either} of them kept as either of two), {wrong} wrong physics named, "
          f"{misses} misses ({cannot_tell} of them said to be untellable from this data) "
          f"({time.perf_counter() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
