# Sourced by the test and bench scripts: makes `thumb_cargo ARGS…` build for
# thumbv7em-none-eabihf. Normal path: rustup's target. Fallback where rustup cannot download
# it: Debian's Rust with the standard library's source builds `core` itself
# (see shared/TOOLCHAIN.md).
THUMB_TARGET=thumbv7em-none-eabihf

thumb_apt_install() {
    local missing=()
    for package in "$@"; do
        dpkg -s "$package" >/dev/null 2>&1 || missing+=("$package")
    done
    if ((${#missing[@]})); then
        local sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
}

if command -v rustup >/dev/null && rustup target add "$THUMB_TARGET" >/dev/null 2>&1; then
    THUMB_ROUTE=rustup
    thumb_cargo() { cargo "$@" --target "$THUMB_TARGET"; }
else
    echo "rustup cannot add $THUMB_TARGET here; using Debian's Rust with build-std" >&2
    thumb_apt_install rustc-web cargo-web rust-web-src binutils-arm-none-eabi
    THUMB_ROUTE=debian
    thumb_cargo() {
        RUSTC_BOOTSTRAP=1 RUSTC=/usr/bin/rustc CARGO_TARGET_DIR=target/debian-rust \
            /usr/bin/cargo "$@" --target "$THUMB_TARGET" -Z build-std=core
    }
fi
export THUMB_ROUTE

# For firmware builds, run from the repository root: QEMU and binutils, the Debian route's
# linker, and FIRMWARE_ELF_DIR, where the release ELFs land.
thumb_firmware_setup() {
    thumb_apt_install qemu-system-arm gcc-arm-none-eabi
    if [ "$THUMB_ROUTE" = debian ]; then
        # Debian's Rust has no rust-lld: link with binutils' ld (see shared/TOOLCHAIN.md).
        export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_LINKER=arm-none-eabi-ld
        # Added to the link scripts of firmware/.cargo/config.toml (cargo merges the two).
        export CARGO_TARGET_THUMBV7EM_NONE_EABIHF_RUSTFLAGS="-C linker-flavor=ld"
        FIRMWARE_ELF_DIR="$PWD/firmware/target/debian-rust/$THUMB_TARGET/release"
    else
        FIRMWARE_ELF_DIR="$PWD/firmware/target/$THUMB_TARGET/release"
    fi
}

# The firmware's budgets (firmware/joint/src/budget.rs), checked on the release ELFs in
# FIRMWARE_ELF_DIR: runs the instruction-count benchmark under QEMU (`-icount shift=0`; it exits
# with status 1 when a figure exceeds its budget and prints the budgets of the build's size),
# its output also written to $1, then compares joint-qemu's flash with the budget. Prints each
# figure; sets FIRMWARE_RAM_BUDGET (the RAM budget, checked with the stack by
# bench/firmware.sh) and FIRMWARE_OVER_BUDGET (an array, empty when every figure is within).
thumb_firmware_budgets() {
    local out=$1 status=0 flash_budget flash
    FIRMWARE_OVER_BUDGET=()
    timeout 300 qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -nographic -icount shift=0 \
        -semihosting-config enable=on,target=native -kernel "$FIRMWARE_ELF_DIR/bench" | tee "$out" || status=$?
    if [ "$status" -ne 0 ]; then
        FIRMWARE_OVER_BUDGET+=("instructions per tick (benchmark status $status; see the OVER BUDGET lines)")
    fi
    read -r flash_budget FIRMWARE_RAM_BUDGET < <(sed -n \
        's/^budgets of the QEMU build: flash \([0-9]*\) B, RAM \([0-9]*\) B$/\1 \2/p' "$out") || true
    if [ -z "${flash_budget:-}" ] || [ -z "${FIRMWARE_RAM_BUDGET:-}" ]; then
        FIRMWARE_OVER_BUDGET+=("the benchmark printed no flash and RAM budgets")
        return 0
    fi
    flash=$(arm-none-eabi-size "$FIRMWARE_ELF_DIR/joint-qemu" | awk 'NR == 2 { print $1 + $2 }')
    if [ "$flash" -gt "$flash_budget" ]; then
        echo "budget: joint-qemu flash (text + data) $flash B of $flash_budget B, OVER BUDGET"
        FIRMWARE_OVER_BUDGET+=("flash $flash B > $flash_budget B")
    else
        echo "budget: joint-qemu flash (text + data) $flash B of $flash_budget B, within"
    fi
}

# Boots the joint firmware (joint-qemu of FIRMWARE_ELF_DIR) under QEMU with `-icount shift=0`
# and its serial link on a free TCP port; sets JOINT_PORT (tcp://127.0.0.1:N) and JOINT_QEMU
# (QEMU's pid; the caller kills it, e.g. in an EXIT trap), once the port accepts.
thumb_joint_qemu() {
    local port
    port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
    qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -icount shift=0 \
        -semihosting-config enable=on,target=native \
        -serial "tcp:127.0.0.1:$port,server=on,wait=off,nodelay=on" \
        -kernel "$FIRMWARE_ELF_DIR/joint-qemu" >/dev/null &
    JOINT_QEMU=$!
    for _ in $(seq 100); do
        (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
        sleep 0.05
    done
    JOINT_PORT="tcp://127.0.0.1:$port"
}
