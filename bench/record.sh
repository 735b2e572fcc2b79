#!/usr/bin/env bash
# `swg-host record` over QEMU's TCP link, the joint board (mps2-an386, `-icount shift=0`) in
# lockstep with the simulated joint: bench/record-60s.json (60 s: two sines, a dithered hold)
# at 1 kHz and at 10 kHz. Prints what `record` reports: the samples, the samples lost (a gap
# fails the command), the batches, the samples a second over the link, and the joint's sample
# queue's high-water mark. In lockstep each tick is one request and its reply, so a run takes
# about 2 minutes per 60,000 ticks; SECONDS_10K (default 60) shortens the 10 kHz run.
#   bash bench/record.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/thumb-toolchain.sh
thumb_firmware_setup
(cd firmware && thumb_cargo build --locked --release -p swg-firmware-qemu --bin joint-qemu)
cargo build --locked --release -p swg-host
swg="${CARGO_TARGET_DIR:-target}/release/swg-host"
mkdir -p bench/out
plan=bench/record-60s.json
for rate in 1000 10000; do
    if [ "$rate" = 10000 ] && [ "${SECONDS_10K:-60}" != 60 ]; then
        # The same plan, its hold shortened so that it lasts SECONDS_10K s.
        short=bench/out/record-plan-10k.json
        python3 - "$plan" "$short" "$SECONDS_10K" <<'PY'
import json, sys
plan = json.load(open(sys.argv[1]))
hold = plan["segments"][3]["hold"]
hold["seconds"] = max(1.0, hold["seconds"] - (60 - float(sys.argv[3])))
plan["segments"][2]["sine"]["cycles"] = max(3, int(plan["segments"][2]["sine"]["cycles"] * float(sys.argv[3]) / 60))
plan["segments"][1]["sine"]["cycles"] = max(3, int(plan["segments"][1]["sine"]["cycles"] * float(sys.argv[3]) / 60))
json.dump(plan, open(sys.argv[2], "w"))
PY
        run_plan=$short
    else
        run_plan=$plan
    fi
    thumb_joint_qemu
    echo "== $rate Hz: $run_plan"
    start=$(date +%s.%N)
    "$swg" record --port "$JOINT_PORT" --out "bench/out/record-$rate.csv" --plan "$run_plan" --rate "$rate" \
        --params data/seed/lht-20-50-fit.json --ratio 50 --simulated-joint micro-slip
    echo "wall: $(python3 -c "print(f'{$(date +%s.%N) - $start:.1f} s')")"
    kill "$JOINT_QEMU" 2>/dev/null || true
    wait "$JOINT_QEMU" 2>/dev/null || true
done
