# Sourced (from the repository root) by tests/python_package.sh and benches/python_overhead.sh:
# a fresh virtual environment in $venv, removed on exit, with the packages named as arguments
# and the package built from this checkout as a user installs it (maturin builds the native
# module in release, into $CARGO_TARGET_DIR).
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
venv="$(mktemp -d)/venv"
trap 'rm -rf "$(dirname "$venv")"' EXIT
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet "$@"
"$venv/bin/pip" install --quiet ./python
