#!/usr/bin/env bash
# `diagnose`'s stiffness_kinks on `swg-host simulate`'s gears (figures, not a test): the catalogue
# gear (kinks at ±0.500 and ±0.962 mrad, steps +12000 and +10000 N·m/rad) over amplitudes, motions
# and encoders, each named kink checked against the truth (within 0.04 mrad, stiffening); and the
# smooth gears (micro-slip, Bouc–Wen, genetic), where any kink named is wrong physics.
# Usage: cargo build --release -p swg-host && bash bench/kinks.sh   (about 2 min on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${CARGO_TARGET_DIR:-target}/release/swg-host
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run() { # NAME ARGS...: simulate and diagnose, one JSON line per recording
    local name=$1; shift
    "$bin" simulate --out "$work/$name.csv" --frequency 0.5 --input-bits 20 --output-bits 20 "$@" >/dev/null
    printf '%s ' "$name"
    # A diagnosis that fails for another reason is listed with its error, not counted.
    if "$bin" diagnose "$work/$name.csv" --json > "$work/$name.json" 2> "$work/$name.err"; then
        python3 -c 'import json, sys; print(json.dumps(json.load(open(sys.argv[1]))["stiffness_kinks"]))' "$work/$name.json"
    else
        python3 -c 'import json, sys; print(json.dumps({"error": open(sys.argv[1]).read().strip()}))' "$work/$name.err"
    fi
}
{
    for a in 0.00095 0.001 0.0011 0.00115 0.0012 0.0013 0.0014 0.0016 0.0018 0.0022 0.0025; do
        run "catalogue-a$a" --physics catalogue --amplitude "$a" --cycles 4 --seed 1
    done
    for motion in nested random biased hold; do
        run "catalogue-$motion" --physics catalogue --motion "$motion" --cycles 4 --seed 2
    done
    for physics in micro-slip bouc-wen genetic; do
        for a in 0.0008 0.001168 0.0015; do
            for motion in sine nested random; do
                run "smooth-$physics-a$a-$motion" --physics "$physics" --amplitude "$a" --motion "$motion" --cycles 6 --seed 3
            done
        done
    done
} > "$work/results"
python3 - "$work/results" <<'PY'
import json, sys
truth = [(-0.962e-3, 10000.0), (-0.5e-3, 12000.0), (0.5e-3, 12000.0), (0.962e-3, 10000.0)]
counts = {"catalogue": [0, 0, 0, 0], "smooth": [0, 0]}  # named, recordings, right kinks, wrong kinks
for line in open(sys.argv[1]):
    name, text = line.split(" ", 1)
    check = json.loads(text)
    if "error" in check:
        print(f"| {name} | diagnose failed | | {check['error'][-120:]} |")
        continue
    named = check.get("tested") == "yes" and check.get("rejected") is None
    kinks = check.get("kinks", []) if named else []
    shown = " ".join(f"{1e3 * k['at_rad']:+.3f} mrad {k['outer_nm_per_rad'] - k['inner_nm_per_rad']:+.0f}" for k in kinks)
    if name.startswith("catalogue"):
        c = counts["catalogue"]
        c[0] += named; c[1] += 1
        for k in kinks:
            step = k["outer_nm_per_rad"] - k["inner_nm_per_rad"]
            ok = any(abs(k["at_rad"] - x) <= 0.04e-3 for x, _ in truth) and step > 0
            c[2 if ok else 3] += 1
    else:
        counts["smooth"][0] += named; counts["smooth"][1] += 1
    why = "" if named else (check.get("rejected") or check.get("why") or "")[:70]
    print(f"| {name} | {'named' if named else 'not named'} | {shown} | {why} |")
c, s = counts["catalogue"], counts["smooth"]
print(f"\ncatalogue gear: named on {c[0]} of {c[1]}; kinks within 0.04 mrad of a true one and stiffening: {c[2]}, others: {c[3]}")
print(f"smooth gears: named on {s[0]} of {s[1]} (wrong physics)")
PY
