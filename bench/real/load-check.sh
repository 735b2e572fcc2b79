#!/usr/bin/env bash
# Check (figures, not a test): every measured run of data/real/ loads with the release swg-host,
# and what today's `fit --model auto` and `diagnose` make of it: two markdown tables, run by run, then
# `diagnose` of several runs together (python3, stdlib only).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --locked -q -p swg-host
host=./target/release/swg-host
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

echo '| run | rows | samples fitted | chosen | held-out RMS (N·m): genetic / micro-slip / bouc-wen / preisach | fit s |'
echo '|---|---|---|---|---|---|'
for csv in data/real/sea-spring-2/*.csv; do
    name=$(basename "$csv" .csv)
    rows=$(grep -cv '^#' "$csv")
    start=$(date +%s.%N)
    if ! "$host" fit "$csv" --model auto --json >"$out/$name.json" 2>"$out/$name.err"; then
        echo "| $name | $((rows - 1)) | rejected: $(head -c 200 "$out/$name.err" | tr '\n' ' ') | | | |"
        continue
    fi
    seconds=$(echo "$(date +%s.%N) - $start" | bc)
    python3 - "$out/$name.json" "$name" "$((rows - 1))" "$seconds" <<'EOF'
import json, sys
path, name, rows, seconds = sys.argv[1:]
d = json.load(open(path))
held = {c['model']: c['held_out_rms'] for c in d['candidates']}
kinds = ('genetic-hysteresis', 'micro-slip', 'bouc-wen', 'preisach')
figures = ' / '.join(f"{held.get(k, float('nan')):.3f}" for k in kinds)
print(f"| {name} | {rows} | {d['n']} | {d['model']} | {figures} | {float(seconds):.2f} |")
EOF
done

echo
echo '| run | θ0 read at rest, mrad | genetic baseline RMS, N·m | model form named (its RMS, N·m) | effects named | held-out RMS (interleaved cycles; one cycle: its middle leg), N·m | passivity |'
echo '|---|---|---|---|---|---|---|'
for csv in data/real/sea-spring-2/*.csv; do
    name=$(basename "$csv" .csv | cut -d- -f2,3)
    if ! "$host" diagnose "$csv" --json >"$out/report.json" 2>"$out/err"; then
        echo "| $name | rejected: $(head -c 200 "$out/err" | tr '\n' ' ') | | | | | |"
        continue
    fi
    python3 - "$out/report.json" "$name" <<'EOF'
import json, sys
path, name = sys.argv[1:]
d = json.load(open(path))
origin = d.get('origin')
zero = f"{1e3 * origin['zero_rad']:.3f}" if origin else 'no rest'
form = d.get('model_form')
unexplained = d.get('unexplained')
named = f"{form['model']} ({form['rms_after']:.3f})" if form else (
    f"no; structure remains ({unexplained['rms'] / unexplained['noise_rms']:.0f}× the noise)" if unexplained else 'no')
effects = ', '.join(f"{f['effect']} {f['magnitude']:.3g} {f['unit']}" for f in d['findings']) or 'none'
held = d.get('held_out')
held = f"{held['rms_before']:.3g} → {held['rms_after']:.3g}" if held else '—'
p = d.get('passivity') or {}
energy = p.get('mean_energy_j')
passivity = 'no closed cycle' if energy is None else ('active' if p.get('active') else 'passive') + f" ({energy:.2g} J)"
print(f"| {name} | {zero} | {d['baseline']['rms']:.3f} | {named} | {effects} | {held} | {passivity} |")
EOF
done

# The runs together: the 1–3 A runs (elastic, each from near its own rest), then all 15.
for runs in 'kt-[123]-*' 'kt-*'; do
    echo
    echo "\`swg-host diagnose data/real/sea-spring-2/$runs.csv\`, the runs together:"
    # shellcheck disable=SC2086 # the glob is the point
    "$host" diagnose data/real/sea-spring-2/$runs.csv | sed -n '/^the runs together/,/^$/p' | sed '1d;/^$/d'
done
