#!/usr/bin/env bash
# Counts the places that branch on a model kind outside model-core and the firmware's evaluator
# dispatch (firmware/joint/src/compensator.rs, where each kind's per-tick cost is budgeted):
# match arms, `matches!`, `if let` and `let … else` on a kind's variant of the model enums,
# (and matches on the enums that had kind variants before model-core's GearModel: JointModel,
# ModelKind, replay's Host). Tests are counted apart (a test may take one kind
# apart to check its values). Usage: bash scripts/kind-branches.sh [DIR] (default: the repo).
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"
files=$(git ls-files '*.rs' | grep -v '^model-core/' | grep -v '^firmware/joint/src/compensator.rs$')
kinds='(GearModel|Evaluator|Kind|ModelKind|JointModel|Host|Installed)::(Genetic|MicroSlip)\b'
branch="(${kinds}[^=;]*=>|matches!\([^;]*${kinds}|if let ${kinds}|let ${kinds}[^;]*else)"
count() { # $1: files
    [ -n "$1" ] && grep -EnH "$branch" $1 2>/dev/null | wc -l || echo 0
}
is_test() { grep -Eq '(^|/)tests?(/|\.rs$)|/tests\.rs$|fuzz/' <<<"$1"; }
library="" tests=""
for f in $files; do
    if is_test "$f"; then tests="$tests $f"; else library="$library $f"; fi
done
# Inline #[cfg(test)] modules of library files count as tests: cut each file there.
lib_branches=0
for f in $library; do
    n=$(awk '/^#\[cfg\(test\)\]/ { exit } { print }' "$f" | grep -Ec "$branch" || true)
    lib_branches=$((lib_branches + n))
done
all=$(count "$library$tests")
echo "branches on a model kind outside model-core and the firmware's dispatch: $lib_branches in library code, $((all - lib_branches)) in tests"
echo "where (library code):"
for f in $library; do
    awk '/^#\[cfg\(test\)\]/ { exit } { print FILENAME ":" FNR ": " $0 }' "$f" | grep -E "$branch" | sed 's/^/  /' || true
done
