#!/usr/bin/env bash
# The Python package's overhead over the engine (benches/python_overhead.py): installs the
# release wheel of this checkout into a fresh venv, then runs the benchmark against the CLI of the
# same checkout. Time on an idle machine only. Usage: bash benches/python_overhead.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
source python/venv.sh numpy scipy polars
cargo build --release --quiet --bin oesweep --example fit_arrays_time
OESWEEP_FIT_EXAMPLE="$CARGO_TARGET_DIR/release/examples/fit_arrays_time" \
    OESWEEP_BIN="$CARGO_TARGET_DIR/release/oesweep" "$venv/bin/python" benches/python_overhead.py "$@"
