#!/usr/bin/env bash
# How `fit` (the default, `--model auto`), `fit --model KIND` for each kind, `fit --model
# genetic-loop` and `diagnose` scale
# (figures, not a test): wall time and peak memory (max RSS, /usr/bin/time -v) on recordings of
# 10 k, 100 k, 1 M, 2 M and 10 M samples made by `swg-host simulate` (the seed gear, 0.5 Hz sine
# at 1 kHz, 20-bit encoders; 10 M samples are ~500 MB of CSV; check `df -h /tmp` first). The
# goal of `fit` at 2 M samples is ≤ 3 s and ≤ 120 MB, for auto and for each kind. Prints a Markdown table and keeps it in
# bench/out/scale.md.
#   bash bench/scale.sh [SIZES...]      e.g. bash bench/scale.sh 10000 100000
set -euo pipefail
cd "$(dirname "$0")/.."
sizes=("$@")
if [ ${#sizes[@]} -eq 0 ]; then
    sizes=(10000 100000 1000000 2000000 10000000)
fi
cargo build --release --locked -p swg-host --no-default-features --quiet
bin=${CARGO_TARGET_DIR:-target}/release/swg-host
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p bench/out
measure() { # prints "seconds MB" of the command, or "failed"
    if /usr/bin/time -v "$@" >/dev/null 2>"$work/time"; then
        awk -F': ' '/Elapsed \(wall clock\)/ { n = split($2, p, ":"); s = 0; for (i = 1; i <= n; i++) s = s * 60 + p[i] }
                    /Maximum resident/ { kb = $2 } END { printf "%.1f s, %.0f MB", s, kb / 1024 }' "$work/time"
    else
        echo "failed: $(grep -m1 error "$work/time")"
    fi
}
{
    kinds=(genetic micro-slip bouc-wen preisach)
    echo "| samples | CSV | fit | $(printf 'fit --model %s | ' "${kinds[@]}")fit --model genetic-loop | diagnose |"
    echo "|---:|---:|---|$(printf -- '---|%.0s' "${kinds[@]}")---|---|"
    for n in "${sizes[@]}"; do
        rec=$work/rec-$n.csv
        # 0.5 Hz at 1 kHz: 2000 samples a cycle.
        "$bin" simulate --out "$rec" --cycles $(((n + 1999) / 2000)) --output-bits 20 --input-bits 20 >/dev/null
        size=$(du -m "$rec" | cut -f1)
        per_kind=""
        for kind in "${kinds[@]}"; do
            per_kind+="$(measure "$bin" fit "$rec" --model "$kind") | "
        done
        echo "| $n | ${size} MB | $(measure "$bin" fit "$rec") | ${per_kind}$(measure "$bin" fit "$rec" --model genetic-loop) | $(measure "$bin" diagnose "$rec") |"
        rm -f "$rec"
    done
} | tee bench/out/scale.md
