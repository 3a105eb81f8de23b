#!/usr/bin/env bash
# The Python package as users get it: the release wheel (python/build-wheel.sh) installed with
# pip into a fresh virtual environment, then its pytest suite run there with a PATH that holds
# no cargo or rustc, against the wheel's own `oesweep` command, which must behave as the binary
# cargo builds from the same checkout. Needs python3 with venv and the Python package registry
# (for maturin, ziglang, auditwheel and the test's packages); under CI=true nothing may skip.
set -euo pipefail
cd "$(dirname "$0")/.."
source python/venv.sh numpy scipy polars pytest control
cargo build --release --quiet --bin oesweep
cargo_bin="$CARGO_TARGET_DIR/release/oesweep"
# Only the virtual environment and the system's own folders: no toolchain from ~/.cargo.
path="$venv/bin:/usr/local/bin:/usr/bin:/bin"
for tool in cargo rustc; do
    if PATH="$path" command -v "$tool" >/dev/null; then
        echo "python_package: $tool is on the test's PATH ($(PATH="$path" command -v "$tool"))" >&2
        exit 1
    fi
done
# Run from outside the source tree so the installed package, not python/oesweep, is imported.
cd "$(dirname "$venv")"
[ "$(PATH="$path" command -v oesweep)" = "$venv/bin/oesweep" ]
PATH="$path" oesweep --help >/dev/null
PATH="$path" OESWEEP_CARGO_BIN="$cargo_bin" "$venv/bin/python" -m pytest -q "$OLDPWD/python/tests"
echo "python_package: ok ($(basename "$wheel"), $(du -k "$wheel" | cut -f1) KiB)"
