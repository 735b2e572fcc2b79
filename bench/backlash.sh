#!/usr/bin/env bash
# `diagnose`'s backlash on `swg-host simulate`'s gears (figures, not a test): gears without a
# dead band, where any backlash named is wrong physics (the catalogue gear's soft first segment
# and a Bouc–Wen gear with damping under nested motion were taken for one), and gears with
# one of 20, 40 and 100 µrad, each named width against the truth.
# Usage: cargo build --release -p swg-host && bash bench/backlash.sh   (about 1 min on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${CARGO_TARGET_DIR:-target}/release/swg-host
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
jobs() { # NAME WIDTH ARGS...: one line a recording
    for physics in catalogue micro-slip bouc-wen preisach; do
        for a in 0.0008 0.0015 0.002 0.003; do
            for motion in sine nested; do
                echo "none-$physics-$a-$motion 0 --physics $physics --amplitude $a --motion $motion --frequency 0.2,0.6 --cycles 4 --seed 1"
            done
        done
    done
    for seed in 1 2 3; do
        echo "none-bouc-wen-damped-$seed 0 --physics bouc-wen --amplitude 0.0025 --motion nested --frequency 0.5 --cycles 6 --seed $seed --effect viscous_damping=40"
    done
    for physics in catalogue micro-slip bouc-wen; do
        for w in 2e-5 4e-5 1e-4; do
            for motion in sine nested; do
                echo "with-$physics-$w-$motion $w --physics $physics --amplitude 0.0012 --motion $motion --frequency 0.2,0.6 --cycles 4 --seed 7 --effect backlash=$w"
            done
        done
    done
}
run() { # NAME WIDTH ARGS...: simulate and diagnose, one JSON line
    local name=$1 width=$2; shift 2
    "$bin" simulate --out "$work/$name.csv" --input-bits 20 --output-bits 20 "$@" >/dev/null
    if "$bin" diagnose "$work/$name.csv" --json > "$work/$name.json" 2> "$work/$name.err"; then
        python3 -c 'import json, sys; j = json.load(open(sys.argv[1])); b = [f["magnitude"] for f in j["findings"] if f["effect"] == "backlash"]; print(sys.argv[2], sys.argv[3], json.dumps(b[0] if b else None))' "$work/$name.json" "$name" "$width"
    else
        echo "$name $width \"error\""
    fi
}
export -f run
export bin work
jobs | xargs -P 2 -L 1 bash -c 'run "$@"' _ > "$work/results"
sort "$work/results" > "$work/sorted"
python3 - "$work/sorted" <<'PY'
import json, statistics, sys
wrong, errors, named, total_with, total_without, failed = [], [], 0, 0, 0, []
for line in open(sys.argv[1]):
    name, width, found = line.split(" ", 2)
    width, found = float(width), json.loads(found)
    if found == "error":
        failed.append(name)
        continue
    if width == 0:
        total_without += 1
        if found is not None:
            wrong.append(f"{name} ({found:.3e} rad)")
        continue
    total_with += 1
    shown = "missed" if found is None else f"{found:.3e} rad ({100 * (found - width) / width:+.0f} %)"
    print(f"| {name} | {width:.0e} | {shown} |")
    if found is not None:
        named += 1
        errors.append(abs(found - width) / width)
listed = ": " + ", ".join(wrong) if wrong else ""
print(f"\nwithout a backlash: {len(wrong)} of {total_without} named one (wrong physics){listed}")
spread = f"; width error median {100 * statistics.median(errors):.0f} %, worst {100 * max(errors):.0f} %" if errors else ""
print(f"with a backlash: named on {named} of {total_with}{spread}")
if failed:
    print(f"diagnose failed on: {', '.join(failed)}")
PY
