#!/usr/bin/env bash
# Figures of the joint firmware on the emulated Cortex-M4F (QEMU mps2-an386), against the
# budgets of firmware/joint/src/budget.rs: every figure is printed, and the script exits
# non-zero at the end when one exceeds its budget.
#   1. instructions per T_ff + K evaluation on a symmetric loop (direct and fast path); per
#      tick of each stateful kind (fast path) and of the torque controller with its evaluator
#      (model mode, `Controller::tick`) on every tick of two motions from rest, each tick
#      measured alone from a copy of the state before it: the largest and the mean (a nested
#      motion, the compensator tests' A·(0.75·sin φ + 0.25·sin 9φ), and a zigzag that fills the
#      16 turning points, then wipes them out); the mean along the nested motion from
#      consecutive ticks as a check; chosen ticks from a full memory (on the branch, a
#      reversal, a wipe-out of all 16 points; the genetic kind on both paths). The benchmark
#      binary exits with status 1 when an instruction count exceeds its budget.
#      QEMU -icount shift=0 makes one instruction 1 ns of virtual time and SysTick run at
#      25 MHz, so SysTick ticks × 40 = instructions, exactly repeatable (shared/TOOLCHAIN.md).
#      Instruction counts depend on the compiler version: the toolchain is printed below.
#   2. flash and RAM of the QEMU build (arm-none-eabi-size): flash = text + data, RAM = data + bss;
#      the stack on top of that is measured in 3: the firmware paints it at boot, and after the
#      pushes, replays and an experiment (`record`) its deepest overwritten word is read through
#      QEMU's monitor.
#   3. time for `swg-host push` (version check, write, read back, commit) over QEMU's TCP link.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/thumb-toolchain.sh
thumb_firmware_setup
elf_dir=$FIRMWARE_ELF_DIR
# The QEMU board only: one board per cargo invocation (see scripts/test-firmware.sh).
(cd firmware && thumb_cargo build --locked --release -p swg-firmware-qemu --bins)
echo "toolchain: $(rustc --version) ($THUMB_ROUTE route)"

echo "== 1. instructions per evaluation, per tick, per controller tick (QEMU -icount shift=0, SysTick), and flash"
mkdir -p bench/out
thumb_firmware_budgets bench/out/firmware-bench.txt
over_budget=("${FIRMWARE_OVER_BUDGET[@]}")
ram_budget=$FIRMWARE_RAM_BUDGET

echo "== 2. flash and RAM of the QEMU build (RAM budget $ram_budget B with the stack)"
read -r flash static_ram < <(arm-none-eabi-size "$elf_dir/joint-qemu" | awk 'NR == 2 { print $1 + $2, $2 + $3 }')
awk -v flash="$flash" -v ram="$static_ram" 'BEGIN {
    printf "joint-qemu: flash %d B (%.1f KiB), RAM %d B (%.1f KiB) + stack (measured in 3)\n",
        flash, flash / 1024, ram, ram / 1024 }'

echo "== 3. swg-host push over the link"
cargo build --locked --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
monitor="$(mktemp -d)/monitor.sock"
qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none \
    -monitor "unix:$monitor,server=on,wait=off" -semihosting-config enable=on,target=native \
    -serial "tcp:127.0.0.1:$port,server=on,wait=off,nodelay=on" \
    -kernel "$elf_dir/joint-qemu" >/dev/null &
qemu=$!
trap 'kill "$qemu" 2>/dev/null || true' EXIT
for _ in $(seq 100); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
    sleep 0.05
done
for run in 1 2 3 4 5; do
    "$swg" push data/seed/lht-20-50-fit.json --port "tcp://127.0.0.1:$port" --ratio 50 | grep committed
done

echo "== stack high-water mark after the pushes, two replays and an experiment"
"$swg" simulate --out bench/out/replay-loops.csv --cycles 2 --frequency 1 --rate 1000 \
    --input-bits 20 --output-bits 20 >/dev/null
for path in fast direct; do
    "$swg" replay bench/out/replay-loops.csv --port "tcp://127.0.0.1:$port" --path "$path" | grep "worst error"
done
# And an experiment: the link's deepest path is a fetch's batch.
"$swg" record --port "tcp://127.0.0.1:$port" --out bench/out/firmware-record.csv --params data/seed/lht-20-50-fit.json \
    --ratio 50 --amplitude 1e-3 --frequency 5 --simulated-joint micro-slip | grep "samples lost"
# The painted area is the 16 KiB below the top of RAM (0x2040_0000); see firmware/qemu/src/lib.rs.
ram=$(python3 - "$monitor" "$static_ram" <<'PY'
import re, socket, sys, time
top, painted, pattern = 0x2040_0000, 16 * 1024, 0x5AFE57AC
monitor = socket.socket(socket.AF_UNIX)
monitor.connect(sys.argv[1])
monitor.sendall(f"xp /{painted // 4}wx {top - painted:#x}\n".encode())
text, deadline = b"", time.time() + 10
while text.count(b"(qemu)") < 2 and time.time() < deadline:
    text += monitor.recv(65536)
words = []
for line in text.decode(errors="replace").splitlines():
    match = re.match(r"\s*([0-9a-f]+):((?:\s+0x[0-9a-f]+)+)", line)
    if match:
        base = int(match.group(1), 16)
        words += [(base + 4 * i, int(w, 16)) for i, w in enumerate(match.group(2).split())]
if len(words) != painted // 4:
    sys.exit(f"monitor returned {len(words)} of {painted // 4} words")
deepest = next(address for address, word in words if word != pattern)
used, static = top - deepest, int(sys.argv[2])
print(f"joint-qemu RAM: {static} B data + bss, {used} B stack at most "
      f"(of {painted} B painted) = {static + used} B ({(static + used) / 1024:.1f} KiB)", file=sys.stderr)
print(static + used)
PY
)
if [ -z "$ram_budget" ]; then
    over_budget+=("RAM: no budget printed")
elif [ "$ram" -gt "$ram_budget" ]; then
    echo "budget: RAM $ram B of $ram_budget B, OVER BUDGET"
    over_budget+=("RAM $ram B > $ram_budget B")
else
    echo "budget: RAM $ram B of $ram_budget B, within"
fi

if ((${#over_budget[@]})); then
    printf 'OVER BUDGET: %s\n' "${over_budget[@]}" >&2
    exit 1
fi
echo "== every figure within its budget"
