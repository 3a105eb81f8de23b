# Sourced (from the repository root) by tests/python_package.sh and benches/python_overhead.sh:
# the release wheel of this checkout (python/build-wheel.sh, into $CARGO_TARGET_DIR) installed
# as a user installs it, with pip into a fresh virtual environment in $venv (removed on exit),
# with the packages named as arguments; $wheel is the wheel's path.
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
bash python/build-wheel.sh
wheel="$(ls "$PWD"/dist/oesweep-*.whl)"
venv="$(mktemp -d)/venv"
trap 'rm -rf "$(dirname "$venv")"' EXIT
python3 -m venv "$venv"
"$venv/bin/pip" install --quiet --upgrade pip
"$venv/bin/pip" install --quiet "$wheel" "$@"
