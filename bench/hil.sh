#!/usr/bin/env bash
# Figures of the closed loop (swg-host hil) on the emulated Cortex-M4F; not a test.
# For each truth physics — the simulator's micro-slip and Bouc–Wen gears (defaults; the pushed
# model is the micro-slip kind fitted to each, and on the Bouc–Wen gear the genetic kind too:
# a model kind of other physics than the gear's) and a passive genetic gear
# (bench/hil-genetic-gear.json; the bundled seed fit runs its loop the active way and a joint
# built on it gains energy) — the model pushed to the joint is the one `swg-host fit` identifies
# from a simulated recording of that truth (random motion of peak 1 mrad, 20-bit encoders,
# 0.02 N·m torque noise), then every scenario runs in every mode for 4 s at 1 kHz, in lockstep
# with the joint firmware in QEMU (mps2-an386) over its TCP-bridged UART.
# Writes bench/out/hil.md (the table), bench/out/hil-*.json and the pictures in bench/out/hil/,
# and copies the contact picture on the micro-slip gear to docs/hil-contact.svg.
# RMS, max and limit cycle are deterministic (lockstep, seeded recordings); the wall time per
# simulated second is the median over the 48 runs (it depends on the machine's load).
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/thumb-toolchain.sh
thumb_firmware_setup
elf_dir=$FIRMWARE_ELF_DIR
# The ELF where thumb_firmware_setup looks for it: the firmware's own target directory.
(cd firmware && unset CARGO_TARGET_DIR && thumb_cargo build --locked --release -p swg-firmware-qemu --bins)
cargo build --locked --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"
echo "toolchain: $(rustc --version) ($THUMB_ROUTE route); $(qemu-system-arm --version | head -1)"

out=bench/out
mkdir -p "$out/hil"
work=$(mktemp -d)
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
# -icount shift=0: virtual time is the instruction count, as in the tests (host/tests/qemu/):
# each lockstep sample runs in the firmware's 20 kHz SysTick tick, and without -icount that
# timer waits for QEMU's I/O thread, which a loaded machine schedules late.
qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -monitor none -icount shift=0 \
    -semihosting-config enable=on,target=native \
    -serial "tcp:127.0.0.1:$port,server=on,wait=off,nodelay=on" \
    -kernel "$elf_dir/joint-qemu" >/dev/null &
qemu=$!
trap 'kill "$qemu" 2>/dev/null || true; rm -rf "$work"' EXIT
for _ in $(seq 100); do
    (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
    sleep 0.05
done
sleep 0.5

recording_options=(--motion random --amplitude 0.001 --frequency 1 --cycles 4 --rate 1000
    --input-bits 20 --output-bits 20 --torque-noise 0.02 --ratio 50 --seed 1)
for truth in micro-slip bouc-wen bouc-wen-genetic genetic; do
    case $truth in
        micro-slip)
            simulate=(--physics micro-slip)
            gear=(--physics micro-slip)
            kind=micro-slip ;;
        bouc-wen)
            simulate=(--physics bouc-wen)
            gear=(--physics bouc-wen)
            kind=micro-slip ;;
        bouc-wen-genetic)
            simulate=(--physics bouc-wen)
            gear=(--physics bouc-wen)
            kind=genetic ;;
        genetic)
            simulate=(--physics genetic --params bench/hil-genetic-gear.json)
            gear=(--gear bench/hil-genetic-gear.json)
            kind=genetic ;;
    esac
    "$swg" simulate --out "$work/$truth.csv" "${simulate[@]}" "${recording_options[@]}" >/dev/null
    "$swg" fit "$work/$truth.csv" --model "$kind" --out "$out/hil-fit-$truth.json" >/dev/null
    # The CLI retries nothing: a first request right after QEMU's boot may be lost, so the
    # version check of one short run comes first.
    for attempt in 1 2 3 4 5; do
        "$swg" hil "$out/hil-fit-$truth.json" --port "tcp://127.0.0.1:$port" "${gear[@]}" \
            --scenario contact --mode open-loop --seconds 0.6 --timeout-ms 500 >/dev/null 2>&1 && break
        sleep 0.5
    done
    # One picture per scenario and gear: the genetic kind on the Bouc–Wen gear has none.
    plot=(--plot "$out/hil")
    [ "$truth" = bouc-wen-genetic ] && plot=()
    "$swg" hil "$out/hil-fit-$truth.json" --port "tcp://127.0.0.1:$port" "${gear[@]}" \
        --seconds 4 --json "${plot[@]}" >"$out/hil-$truth.json"
done
cp "$out/hil/hil-contact-micro-slip.svg" docs/hil-contact.svg

python3 - "$out" <<'PY'
import json, statistics, sys
out = sys.argv[1]
pushed = {"micro-slip": "micro-slip", "bouc-wen": "micro-slip", "bouc-wen-genetic": "genetic", "genetic": "genetic"}
reports = {truth: json.load(open(f"{out}/hil-{truth}.json")) for truth in pushed}
run_name = lambda truth: f"{truth.removesuffix('-genetic')} gear, {pushed[truth]} model"
lines = []
first = reports["micro-slip"]
g = first["gains"]
lines.append(f"{first['seconds']} s per run at {first['rate_hz']:.0f} Hz; errors from {first['settling_s']} s on; "
             f"limit cycle: peak-to-peak true torque over the last {100 * first['hold_fraction']:.0f} % of each window of constant reference.")
lines.append(f"Gains (once, for every run): kp {g['kp']} N·m/N·m, ki {g['ki_per_s']} N·m/(N·m·s) "
             f"(at rest within one encoder count of torque: {g['integral_deadband_nm']:.3f} N·m on the micro-slip fit), "
             f"damping {g['damping_nm_s_per_rad']} and torsion damping {g['torsion_damping_nm_s_per_rad']} N·m·s/rad, "
             f"|u| ≤ {g['command_limit_nm']} N·m (motor side).")
lines.append("")
lines.append("| scenario | physics | pushed model | mode | RMS (N·m) | max (N·m) | limit cycle (N·m) |")
lines.append("|---|---|---|---|---|---|---|")
walls = []
for truth, report in reports.items():
    for run in report["runs"]:
        fmt = lambda key: "diverged" if run["diverged"] else (f"{run[key]:.3f}" if key in run else "—")
        lines.append(f"| {run['scenario']} | {run['physics']} | {pushed[truth]} | {run['mode']} | {fmt('rms_nm')} | {fmt('max_nm')} | {fmt('limit_cycle_nm')} |")
        walls.append(run["wall_s_per_simulated_s"])
lines.append("")
for truth, report in reports.items():
    runs = {(r["scenario"], r["mode"]): r for r in report["runs"]}
    for scenario in ["torque-sine", "contact"]:
        try:
            model = runs[(scenario, "model")]["rms_nm"]
            ratios = [runs[(scenario, m)]["rms_nm"] / model for m in ["open-loop", "linear"]]
            verdict = "met" if min(ratios) >= 3 else "**missed**"
            lines.append(f"- {run_name(truth)}, {scenario}: model RMS is {ratios[0]:.1f}× lower than open-loop, "
                         f"{ratios[1]:.1f}× lower than linear (goal ≥ 3× both: {verdict})")
        except KeyError:
            lines.append(f"- {run_name(truth)}, {scenario}: a run diverged")
    cycles = [r.get("limit_cycle_nm") for r in report["runs"] if "limit_cycle_nm" in r]
    worst = max(cycles) if cycles else float("nan")
    goal = report["two_counts_nm"]
    lines.append(f"- {run_name(truth)}: largest limit cycle of any mode {worst:.3f} N·m; 2 encoder counts at the "
                 f"linear stiffness {report['linear_stiffness_nm_per_rad']:.0f} N·m/rad = {goal:.3f} N·m "
                 f"({'met' if worst <= goal else '**missed**'})")
lines.append(f"- lockstep wall time per simulated second at 1 kHz: median {statistics.median(walls):.2f} s over "
             f"{len(walls)} runs (min {min(walls):.2f}, max {max(walls):.2f}; goal < 2 s: "
             f"{'met' if statistics.median(walls) < 2 else '**missed**'})")
text = "\n".join(lines)
open(f"{out}/hil.md", "w").write(text + "\n")
print(text)
PY
