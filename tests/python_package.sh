#!/usr/bin/env bash
# The Python package (python/): built from this checkout with pip into a fresh virtual
# environment, then its pytest suite against the `oesweep` binary of the same checkout.
# Needs python3 with venv and the Python package registry; under CI=true nothing may skip.
set -euo pipefail
cd "$(dirname "$0")/.."
source python/venv.sh numpy scipy polars pytest control
cargo build --release --quiet
# Run from outside the source tree so the installed package, not python/oesweep, is imported.
cd "$(dirname "$venv")"
OESWEEP_BIN="$CARGO_TARGET_DIR/release/oesweep" "$venv/bin/python" -m pytest -q "$OLDPWD/python/tests"
echo "python_package: ok"
