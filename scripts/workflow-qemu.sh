#!/usr/bin/env bash
# The workflow from the joint's own recording, on the emulated joint board (QEMU mps2-an386)
# in lockstep with swg-host's simulated joint (the simulator's micro-slip gear, its output
# clamped, a torque sensor with 0.05 N·m of noise and a 0.3 N·m offset): record, fit,
# diagnose, push, hil. Installs what it needs as scripts/test.sh does. Writes into DIR
# (default: workflow/).
#   bash scripts/workflow-qemu.sh [DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-workflow}

source scripts/thumb-toolchain.sh
thumb_firmware_setup
(cd firmware && thumb_cargo build --locked --release -p swg-firmware-qemu --bin joint-qemu)
cargo build --locked --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"
thumb_joint_qemu
trap 'kill "$JOINT_QEMU" 2>/dev/null || true' EXIT
mkdir -p "$out"

step() {
    echo "\$ swg-host $*"
    "$swg" "$@"
    echo
}
# The joint needs a set for its gear ratio: the seed fit's. The default plan at 1 mrad, 2 Hz.
step record --port "$JOINT_PORT" --out "$out/rec.csv" --params data/seed/lht-20-50-fit.json --ratio 50 \
    --amplitude 1e-3 --frequency 2 --simulated-joint micro-slip
step fit "$out/rec.csv" --out "$out/fit.json" --plot "$out/fit.svg"
step diagnose "$out/rec.csv"
step push "$out/fit.json" --port "$JOINT_PORT" --ratio 50
step hil "$out/fit.json" --port "$JOINT_PORT" --scenario torque-sine --seconds 2
