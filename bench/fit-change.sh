#!/usr/bin/env bash
# How much the default `fit` + `predict` of one recording moves between a git ref (default:
# main) and the working tree (figures, not a test). For each truth physics (the passive genetic
# gear of bench/hil-genetic-gear.json, micro-slip, Bouc–Wen, catalogue) and motion (sine,
# biased, nested, random, hold): `swg-host simulate` records it (0.5 Hz, 4 cycles at 1 kHz,
# 20-bit encoders, 0.05 N·m torque noise) and again without noise (exact angles, no torque
# noise: the true torque). Each version fits the noisy recording (`fit`, the default `auto`)
# and predicts the noise-free one (`predict`); the table gives the kind each chose and the RMS
# of its prediction against the true torque, over the samples the working tree's `predict`
# scores (after the motion's extremes, for a recording that does not start at rest).
#   bash bench/fit-change.sh [REF]
set -euo pipefail
cd "$(dirname "$0")/.."
ref=${1:-main}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$work/src" bench/out
git archive "$ref" | tar -x -C "$work/src"
(cd "$work/src" && CARGO_TARGET_DIR="$work/target" cargo build --release --locked -p swg-host --no-default-features --quiet)
cargo build --release --locked -p swg-host --no-default-features --quiet
old=$work/target/release/swg-host
new=${CARGO_TARGET_DIR:-target}/release/swg-host
score() { # truth.csv prediction.csv mask.csv: RMS of prediction − truth where mask's `scored` is 1
    python3 - "$@" <<'EOF'
import csv, math, sys
def rows(path):
    lines = [l for l in open(path) if not l.startswith('#')]
    return list(csv.DictReader(lines))
truth, predicted, mask = (rows(p) for p in sys.argv[1:4])
pairs = [(float(t['torque_nm']), float(p['torque_nm'])) for t, p, m in zip(truth, predicted, mask) if m['scored'] == '1']
print(f"{math.sqrt(sum((a - b) ** 2 for a, b in pairs) / len(pairs)):.4f}")
EOF
}
fit_predict() { # BINARY TAG: fits rec.csv, predicts clean.csv into pred-TAG.csv, prints the kind
    "$1" fit "$work/rec.csv" --out "$work/params-$2.json" >/dev/null
    "$1" predict "$work/params-$2.json" "$work/clean.csv" --out "$work/pred-$2.csv" >/dev/null
    python3 -c "import json, sys; print(json.load(open(sys.argv[1]))['model'])" "$work/params-$2.json"
}
{
    echo "| physics | motion | $ref: model | $ref: RMS vs truth N·m | working tree: model | working tree: RMS vs truth N·m | tree / $ref |"
    echo "|---|---|---|---|---|---|---|"
    for physics in genetic micro-slip bouc-wen catalogue; do
        gear=()
        if [ "$physics" = genetic ]; then gear=(--params bench/hil-genetic-gear.json); fi
        for motion in sine biased nested random hold; do
            common=(--physics "$physics" --motion "$motion" "${gear[@]}")
            "$new" simulate --out "$work/rec.csv" "${common[@]}" --output-bits 20 --input-bits 20 >/dev/null
            "$new" simulate --out "$work/clean.csv" "${common[@]}" --torque-noise 0 >/dev/null
            kind_old=$(fit_predict "$old" old)
            kind_new=$(fit_predict "$new" new)
            # Both scored on the samples the working tree's `predict` scores.
            rms_old=$(score "$work/clean.csv" "$work/pred-old.csv" "$work/pred-new.csv")
            rms_new=$(score "$work/clean.csv" "$work/pred-new.csv" "$work/pred-new.csv")
            ratio=$(python3 -c "import sys; print(f'{float(sys.argv[2]) / float(sys.argv[1]):.2f}')" "$rms_old" "$rms_new")
            echo "| $physics | $motion | $kind_old | $rms_old | $kind_new | $rms_new | $ratio |"
        done
    done
} | tee bench/out/fit-change.md
