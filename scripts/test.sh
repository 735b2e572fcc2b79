#!/usr/bin/env bash
# Runs every test of the project on a fresh machine, installing what it needs:
# host workspace (model-core, protocol, swg-host, system tests) and its clippy, model-core for
# the Cortex-M4F, then the firmware (clippy, host-side library tests, QEMU runs) via
# scripts/test-firmware.sh.
set -euo pipefail
cd "$(dirname "$0")/.."

if ! command -v cargo >/dev/null; then
    echo "cargo not found: install Rust (https://rustup.rs) first" >&2
    exit 1
fi

echo "== host workspace: cargo test"
cargo test --workspace --locked --release

echo "== host workspace: clippy (-D warnings; lints in Cargo.toml and clippy.toml)"
if ! cargo clippy --version >/dev/null 2>&1; then
    command -v rustup >/dev/null && rustup component add clippy
fi
cargo clippy --workspace --all-targets --locked --release -- -D warnings

echo "== model-core builds for thumbv7em-none-eabihf"
source scripts/thumb-toolchain.sh
thumb_cargo build --locked --release -p model-core --features defmt,serde

echo "== firmware"
bash scripts/test-firmware.sh
