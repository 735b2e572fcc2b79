#!/usr/bin/env bash
# Benchmark of `swg-host fit` against scipy least_squares (multi-start), scipy
# differential_evolution and pyswarms GlobalBestPSO, on the seed's loop table and on a
# simulated 20,001-sample recording. Prints the tables and writes bench/out/results.md.
# Extra arguments go to bench/peers.py (e.g. --runs 5, --de-maxiter 100).
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"

venv=bench/.venv
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r bench/requirements.txt

mkdir -p bench/out
recording=bench/out/recording-20k.csv
"$swg" simulate --out "$recording" --cycles 5 --frequency 0.25 --rate 1000 \
    --output-bits 20 --input-bits 20 --torque-noise 0.05 --seed 3

"$venv/bin/python" bench/peers.py --swg-host "$swg" --out bench/out \
    --truth data/seed/lht-20-50-fit.json \
    "$@" data/seed/lht-20-50.csv "$recording"
