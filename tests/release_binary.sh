#!/usr/bin/env bash
# The release binary carries no test hook: built as a user builds it (`cargo build --release`,
# without the `failpoints` feature that the test suite turns on), a run with
# OESWEEP_FAILPOINT=panic:... set completes with no failed cell, where the test build's
# tests/fault_isolation.rs makes that very cell panic.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
cargo build --release --quiet --bin oesweep
bin="$CARGO_TARGET_DIR/release/oesweep"
# README's command form: `cargo run` picks the `oesweep` binary (default-run), not the test one.
cargo run --release --quiet -- --help > /dev/null

work=$(mktemp -d /tmp/oesweep-release.XXXXXX)
trap 'rm -rf "$work"' EXIT
cd "$work"
echo '{"b": [0.5, 0.3], "f": [-1.2, 0.5], "delay": 1}' > sys.json
"$bin" simulate --system sys.json --out est.csv --n 1500 --noise-std 0.05 >/dev/null 2>&1
echo '{"name": "release", "data": {"path": "est.csv", "ts": 1e-3},
       "grid": {"nb": [1, 2], "nf": [1, 2], "k": [0.1, 1.0]}, "output": "out"}' > job.json
status=0
OESWEEP_FAILPOINT=panic:2,2,1 "$bin" run job.json --quiet > run.out 2>&1 || status=$?
if [ "$status" -ne 0 ] || ! grep -q "(0 failed)" run.out; then
    echo "release_binary: FAILED: a release run with OESWEEP_FAILPOINT set exited $status:"
    cat run.out
    exit 1
fi
echo "release_binary: ok (OESWEEP_FAILPOINT ignored by the release build)"
