#!/usr/bin/env bash
# Benchmark (figures, not a test): prediction of motions a model was not fitted on, for gears
# of five truth physics (genetic, micro-slip, Bouc–Wen, catalogue, Preisach), against the floor of
# the truth physics on the same measured angles.
# Prints the table, keeps it in bench/out/prediction.md, and redraws docs/prediction-*.svg.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p bench/out
cargo bench --locked -p swg-system-tests --bench prediction 2>/dev/null | tee bench/out/prediction.md
