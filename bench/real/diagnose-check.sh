#!/usr/bin/env bash
# Check (figures, not a test): what `swg-host diagnose` makes of every measured run of
# data/real/, with the release swg-host. Prints a markdown table (python3, stdlib only).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --locked -q -p swg-host
host=./target/release/swg-host
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

echo '| run | θ0 read at rest, mrad | genetic baseline RMS, N·m | model form named (its RMS, N·m) | effects named | held-out RMS (last quarter), N·m | passivity |'
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
named = f"{form['model']} ({form['rms_after']:.3f})" if form else 'no'
effects = ', '.join(f"{f['effect']} {f['magnitude']:.3g} {f['unit']}" for f in d['findings']) or 'none'
held = d.get('held_out')
held = f"{held['rms_before']:.3g} → {held['rms_after']:.3g}" if held else '—'
p = d.get('passivity') or {}
energy = p.get('mean_energy_j')
passivity = 'no closed cycle' if energy is None else ('active' if p.get('active') else 'passive') + f" ({energy:.2g} J)"
print(f"| {name} | {zero} | {d['baseline']['rms']:.3f} | {named} | {effects} | {held} | {passivity} |")
EOF
done
