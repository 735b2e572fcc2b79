#!/usr/bin/env bash
# Check (figures, not a test): every measured run of data/real/ loads with the release swg-host,
# and what today's `fit --model auto` makes of it. Prints a markdown table.
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
