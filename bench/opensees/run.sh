#!/usr/bin/env bash
# The OpenSees gear corpus, end to end: builds swg-host (release), installs requirements.txt into
# bench/opensees/.venv, checks the catalogue against its targets (verify.py), writes the corpus
# (generate.py, default bench/out/opensees, kept out of git), scores fit + predict on it
# (score.py, also kept in OUT/score.md) and the diagnosis on its materials with concealed effects
# (diagnose.py: recordings and diagnoses in OUT/diagnose, the table in OUT/diagnose.md).
#     bash bench/opensees/run.sh [OUT_DIR] [--seed N]
set -euo pipefail
cd "$(dirname "$0")/../.."

cargo build --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"

# openseespy's Linux build links the system's BLAS and LAPACK ("Failed to import openseespy on
# Linux" without them).
if command -v dpkg >/dev/null && ! dpkg -s libblas3 liblapack3 >/dev/null 2>&1; then
    sudo=""
    [ "$(id -u)" -eq 0 ] || sudo=sudo
    $sudo apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq libblas3 liblapack3 >/dev/null
fi

venv=bench/opensees/.venv
if [ ! -x "$venv/bin/python" ]; then
    "$(command -v python3.11 || command -v python3)" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check -r bench/opensees/requirements.txt

out="${1:-bench/out/opensees}"
shift || true
"$venv/bin/python" bench/opensees/verify.py
"$venv/bin/python" bench/opensees/generate.py --out "$out" --swg-host "$swg" "$@"
"$venv/bin/python" bench/opensees/score.py "$out" --swg-host "$swg"
"$venv/bin/python" bench/opensees/diagnose.py "$out/diagnose" --swg-host "$swg" | tee "$out/diagnose.md"
