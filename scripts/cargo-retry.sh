# Sourced by scripts/test.sh and scripts/test-firmware.sh: `cargo` run once more when its query of
# rustc's target information fails on input it was never given.
#
# Why: cargo asks `rustc - --print=cfg …` about each target, with an empty pipe as the source. On
# our sandboxed test machines that pipe has handed rustc stale bytes of an earlier compiler's
# output, which rustc parses as Rust and rejects (4 clean runs on 2026-11-28, at different
# steps: heapless's `clrex` probe, a `#![feature]` probe, cargo's own "Finished" line). cargo
# keeps the failure in target/.rustc_info.json, so a plain rerun fails the same way: the retry
# drops those caches first. Any other failure is returned as it is.
cargo_retry_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)

cargo() {
    local log status=0
    log=$(mktemp)
    # stderr through tee (kept for the check below), stdout as it is.
    { command cargo "$@" 2>&1 1>&3 3>&- | tee "$log" >&2; } 3>&1 || status=$?
    if [ "$status" -ne 0 ] && grep -q "to learn about target-specific information" "$log"; then
        echo "== cargo's rustc query read input it was not given (scripts/cargo-retry.sh): once more" >&2
        find "$cargo_retry_root" -maxdepth 4 -name .rustc_info.json -path '*target*' -delete
        status=0
        command cargo "$@" || status=$?
    fi
    rm -f "$log"
    return "$status"
}
