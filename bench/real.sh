#!/usr/bin/env bash
# Issue 16's protocol on the measured spring (data/real/sea-spring-2) with the release swg-host:
#   1. one fit on 1-4, 3-4, 5-1 (auto, and each kind), `predict` of every other run against the
#      prototype's goals; 2. repeatability per amplitude; 3. no blow-up against a straight line;
#   4. θ0 fitted with the rest window cut away; 5. each fitted run held out in turn. Prints
#   markdown tables (python3, stdlib only).
# Usage: cargo build --release -p swg-host && bash bench/real.sh [--write-readme] [--auto-timeout S]
#   --write-readme replaces README.md between <!-- real.sh begin --> and <!-- real.sh end -->.
set -euo pipefail
cd "$(dirname "$0")/.."
exec python3 bench/real/protocol.py "$@"
