#!/usr/bin/env bash
# Tests of the joint firmware, on a fresh machine too (installs what it needs):
#   1. the board-independent firmware library (firmware/joint) on the host: cargo test
#   2. clippy over the firmware workspace (lints: firmware/Cargo.toml, firmware/clippy.toml):
#      joint on the host, each board on thumbv7em
#   3. the firmware for both boards (QEMU mps2-an386 and STM32F405) builds for thumbv7em
#   4. model-core's checks and the fast path's error bound on the emulated Cortex-M4F, a deliberate
#      panic that must end QEMU with status 1, and the
#      firmware's budgets: instructions per tick (the benchmark binary, every tick of its motions)
#      and flash (firmware/joint/src/budget.rs; RAM with the stack is bench/firmware.sh's)
#   5. end to end under QEMU: push, read back, replay, bad traffic (host/tests/firmware_e2e.rs)
#   6. the closed loop in lockstep under QEMU: the firmware's torque controller on the host's
#      simulated joint, library and `swg-host hil` (host/tests/hil_e2e.rs)
#   7. the joint's identification experiment under QEMU: record, then fit, predict, diagnose,
#      push and hil on the recording; bad plans and a stopped experiment write nothing
#      (host/tests/record_e2e.rs)
#   8. the control tick under a burst of link traffic during a lockstep run: no overrun, no late
#      tick, no missed period (host/tests/tick_e2e.rs; QEMU with -icount, see host/tests/qemu/)
# Exits non-zero on the first failure.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/thumb-toolchain.sh
thumb_firmware_setup
elf_dir=$FIRMWARE_ELF_DIR
host_triple=$(rustc -vV | sed -n 's/^host: //p')

echo "== firmware library (firmware/joint) on the host"
# From firmware/, where .cargo/config.toml would otherwise build for the Cortex-M4F.
(cd firmware && cargo test --locked -p swg-joint --target "$host_triple")

# One board per cargo invocation, for clippy as for the builds below: each board's build sees
# its own features only (see firmware/Cargo.toml).
if [ "$THUMB_ROUTE" = rustup ]; then
    echo "== clippy over the firmware workspace (-D warnings)"
    cargo clippy --version >/dev/null 2>&1 || rustup component add clippy
    (cd firmware && cargo clippy --locked -p swg-joint --all-targets --target "$host_triple" -- -D warnings)
    for board in swg-firmware-qemu swg-firmware-stm32f405; do
        (cd firmware && cargo clippy --locked -p "$board" --all-targets --target "$THUMB_TARGET" -- -D warnings)
    done
else
    # The fallback of scripts/thumb-toolchain.sh: Debian's Rust, set up without clippy.
    echo "== clippy SKIPPED: rustup cannot add $THUMB_TARGET here (Debian Rust route, no clippy)" >&2
fi

echo "== firmware for both boards (thumbv7em-none-eabihf)"
(cd firmware && thumb_cargo build --locked --release -p swg-firmware-qemu --bins)
(cd firmware && thumb_cargo build --locked --release -p swg-firmware-stm32f405)
for elf in joint-qemu joint-stm32f405; do
    arm-none-eabi-size "$elf_dir/$elf"
done

qemu_run() {
    timeout 300 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic \
        -semihosting-config enable=on,target=native "$@"
}

echo "== model-core on the emulated Cortex-M4F (QEMU mps2-an386)"
qemu_run -kernel "$elf_dir/model-core-checks"

echo "== a panic under QEMU ends the emulation with a failure status (the board's panic handler)"
panic_status=0
qemu_run -kernel "$elf_dir/panic-check" >/dev/null 2>&1 || panic_status=$?
if [ "$panic_status" -ne 1 ]; then
    echo "panic-check exited with status $panic_status, not 1: a panic would pass for success" >&2
    exit 1
fi
echo "panic-check: status 1, as it must be"

echo "== the firmware's budgets: instructions per tick and flash (firmware/joint/src/budget.rs)"
mkdir -p target
thumb_firmware_budgets target/firmware-budgets.txt
if ((${#FIRMWARE_OVER_BUDGET[@]})); then
    printf 'OVER BUDGET: %s\n' "${FIRMWARE_OVER_BUDGET[@]}" >&2
    exit 1
fi

echo "== end to end under QEMU"
# --nocapture shows the CLI runs with their replay figures (worst and RMS difference).
# --release: scripts/test.sh has just built the host tests in that profile.
SWG_FIRMWARE_ELF="$elf_dir/joint-qemu" cargo test --locked --release -p swg-host --test firmware_e2e -- --ignored --nocapture

echo "== closed loop in lockstep under QEMU (swg-host hil)"
SWG_FIRMWARE_ELF="$elf_dir/joint-qemu" cargo test --locked --release -p swg-host --test hil_e2e -- --ignored --nocapture

echo "== the joint records, then fit, predict, diagnose, push and hil on its recording (swg-host record)"
SWG_FIRMWARE_ELF="$elf_dir/joint-qemu" cargo test --locked --release -p swg-host --test record_e2e -- --ignored --nocapture

echo "== the control tick under link traffic (QEMU -icount shift=0)"
SWG_FIRMWARE_ELF="$elf_dir/joint-qemu" cargo test --locked --release -p swg-host --test tick_e2e -- --ignored --nocapture

echo "== firmware tests passed"
