#!/usr/bin/env python3
"""How hard the OpenSees corpus is for swg-host: fit on one motion, predict the others.

    python score.py CORPUS_DIR [--swg-host PATH] [--training sine random] [--model auto]

As the prediction benchmark (tests/prediction_bench.rs) does for our own simulator's gears: for
each material and training motion, `swg-host fit MATERIAL-TRAINING.csv --model MODEL --out P.json`,
then for every other motion `swg-host predict P.json MATERIAL-MOTION.csv --out PRED.csv` (the model
run from rest along the measured angles). Figures per case:
  floor RMS      RMS of the floor (the material on the measured angles) against the truth, N·m;
  RMS / floor    RMS of the prediction against the noise-free truth, over the floor's;
  step / floor   the prediction's largest per-sample torque step over the floor's;
  K err          RMS of the predicted stiffness minus the truth's tangent, over the RMS of the
                 tangent (the tangent is OpenSees' getTangent along the true deflection).
Prints a markdown table and the worst case per material and training, and writes both to
CORPUS_DIR/score.md.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from drive import InputError, parse_number, read_table
from generate import MOTIONS, default_swg_host


def columns(path: Path, names: list[str]) -> dict[str, np.ndarray]:
    rows, index, _ = read_table(path, {name: name for name in names})
    return {n: np.array([parse_number(c[index[n]], f"{path}:{line}: column {n}") for line, c in rows]) for n in names}


def run(command: list[str]) -> str:
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr.strip()}")
    return done.stdout


def rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def max_step(t: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(t))))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("corpus", type=Path, help="a directory written by generate.py")
    parser.add_argument("--swg-host", type=Path, default=default_swg_host())
    parser.add_argument("--training", nargs="+", default=["sine", "random"], choices=MOTIONS)
    parser.add_argument("--model", default="auto", help="fit --model (default auto)")
    args = parser.parse_args()
    try:
        manifest = json.loads((args.corpus / "MANIFEST.json").read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as e:
        print(f"error: {args.corpus / 'MANIFEST.json'}: {e}", file=sys.stderr)
        return 1
    swg = str(args.swg_host)
    lines = ["| material | trained on | kind | predicts | floor RMS N·m | RMS / floor | step / floor | K err |",
             "|---|---|---|---|---|---|---|---|"]
    worst = ["| material | trained on | kind | worst RMS / floor (motion) | worst step / floor | worst K err |",
             "|---|---|---|---|---|---|"]
    try:
        with tempfile.TemporaryDirectory() as scratch:
            params, prediction = Path(scratch) / "params.json", Path(scratch) / "prediction.csv"
            for material in manifest["materials"]:
                for training in args.training:
                    stem = args.corpus / f"{material}-"
                    fitted = json.loads(run([swg, "fit", f"{stem}{training}.csv", "--model", args.model,
                                             "--json", "--out", str(params)]))
                    kind = fitted["model"]
                    cases = []
                    for motion in [m for m in manifest["motions"] if m != training]:
                        run([swg, "predict", str(params), f"{stem}{motion}.csv", "--out", str(prediction)])
                        predicted = columns(prediction, ["torque_nm", "stiffness_nm_per_rad"])
                        truth = columns(Path(f"{stem}{motion}.truth.csv"), ["torque_nm", "tangent_nm_per_rad"])
                        floor = columns(Path(f"{stem}{motion}.floor.csv"), ["torque_nm"])
                        floor_rms = rms(floor["torque_nm"], truth["torque_nm"])
                        ratio = rms(predicted["torque_nm"], truth["torque_nm"]) / floor_rms
                        step = max_step(predicted["torque_nm"]) / max_step(floor["torque_nm"])
                        tangent = truth["tangent_nm_per_rad"]
                        k_err = rms(predicted["stiffness_nm_per_rad"], tangent) / float(np.sqrt(np.mean(tangent**2)))
                        cases.append((motion, ratio, step, k_err))
                        lines.append(f"| {material} | {training} | {kind} | {motion} | {floor_rms:.4f} | "
                                     f"{ratio:.2f} | {step:.2f} | {100 * k_err:.1f} % |")
                    motion, ratio, _, _ = max(cases, key=lambda c: c[1])
                    worst.append(f"| {material} | {training} | {kind} | {ratio:.2f} ({motion}) | "
                                 f"{max(c[2] for c in cases):.2f} | {100 * max(c[3] for c in cases):.1f} % |")
    except (InputError, RuntimeError, OSError, json.JSONDecodeError, KeyError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    text = "\n".join(lines) + "\n\nworst over the predicted motions:\n\n" + "\n".join(worst) + "\n"
    print(text, end="")
    (args.corpus / "score.md").write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
