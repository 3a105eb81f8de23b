#!/usr/bin/env bash
# The Python package's overhead over the engine (benches/python_overhead.py): builds the
# package from this checkout into a fresh venv, then runs the benchmark against the CLI of the
# same checkout. Time on an idle machine only. Usage: bash benches/python_overhead.sh [RUNS]
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
venv="$(mktemp -d)/venv"
trap 'rm -rf "$(dirname "$venv")"' EXIT
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet numpy scipy polars
"$venv/bin/pip" install --quiet ./python
cargo build --release --quiet --bin oesweep --example fit_arrays_time
OESWEEP_FIT_EXAMPLE="$CARGO_TARGET_DIR/release/examples/fit_arrays_time" \
    OESWEEP_BIN="$CARGO_TARGET_DIR/release/oesweep" "$venv/bin/python" benches/python_overhead.py "$@"
