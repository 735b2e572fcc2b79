#!/usr/bin/env bash
# Figures, not a test: issue 16's protocol on the measured spring with swg-host. One micro-slip
# fit on the first run of 1, 3 and 5 A together (1-4, 3-4, 5-1; `fit --model auto` picks the
# same kind), then `predict` every other run; prints the fit's time and each run's RMS, N·m.
#     bash bench/real/protocol.sh [SWG_HOST]     (default: target/release/swg-host, built)
set -euo pipefail
cd "$(dirname "$0")/../.."
if [ $# -eq 0 ]; then
    cargo build --release --locked -q -p swg-host
fi
swg="${1:-target/release/swg-host}"
runs=data/real/sea-spring-2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
run() { ls "$runs"/kt-"$1"-*.csv; }
start=$(date +%s.%N)
"$swg" fit "$(run 1-4)" "$(run 3-4)" "$(run 5-1)" --model micro-slip --out "$out/params.json" </dev/null >/dev/null
echo "fit: $(echo "$(date +%s.%N) - $start" | bc) s"
echo '| run | RMS N·m |'
echo '|---|---|'
for r in 1-5 1-6 2-4 2-5 2-6 3-5 3-6 4-4 4-5 4-6 5-2 5-3; do
    rms=$("$swg" predict "$out/params.json" "$(run "$r")" --json | python3 -c 'import json, sys; print("%.3f" % json.load(sys.stdin)["rms"])')
    echo "| $r | $rms |"
done
