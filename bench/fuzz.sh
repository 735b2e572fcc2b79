#!/usr/bin/env bash
# Long fuzz runs (figures, not a test) of the targets in fuzz/: the CSV readers (loop table,
# recording), the params-file and plan-file parsers and the protocol's frame decoder. Needs a nightly
# toolchain and cargo-fuzz (`rustup toolchain install nightly; cargo install cargo-fuzz`).
# Each target runs SECONDS (default 300) from the checked-in corpus (fuzz/corpus/<target>/,
# which it grows in a copy under bench/out/fuzz/); a crash is kept in fuzz/artifacts/<target>/.
# The short seeded replay on stable is `cargo test -p swg-host --test fuzz_corpus`.
#   bash bench/fuzz.sh [SECONDS] [TARGET...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-300}
shift || true
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
    targets=(csv_loop_table csv_recording params plan frame_decode)
fi
if ! cargo +nightly fuzz --version >/dev/null 2>&1; then
    echo "bench/fuzz.sh needs nightly and cargo-fuzz: rustup toolchain install nightly && cargo install cargo-fuzz" >&2
    exit 2
fi
mkdir -p bench/out/fuzz
for target in "${targets[@]}"; do
    work=bench/out/fuzz/$target
    mkdir -p "$work"
    cp -n fuzz/corpus/"$target"/* "$work"/ 2>/dev/null || true
    echo "== $target, ${seconds} s"
    (cd fuzz && cargo +nightly fuzz run "$target" "../$work" -- -max_total_time="$seconds" -max_len=4096 2>&1) |
        grep -E '^(#[0-9]+.*(DONE|pulse)|Done|==[0-9]+==|SUMMARY|artifact_prefix|Test unit written)' | tail -n 3
done
