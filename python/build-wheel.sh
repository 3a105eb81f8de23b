#!/usr/bin/env bash
# The release wheel of the Python package: dist/oesweep-VERSION-cp311-abi3-manylinux_2_28_x86_64.whl,
# one file for every CPython >= 3.11 on x86-64 Linux with glibc >= 2.28, holding the native
# module and the `oesweep` command. Built with maturin's --zig (zig links against glibc 2.28
# whatever the build machine's glibc is), then checked with auditwheel. The tools (maturin,
# ziglang, auditwheel) are installed with pip into $OESWEEP_WHEEL_TOOLS once; the Rust build
# goes to $CARGO_TARGET_DIR (default ~/.cache/oesweep-target, outside the checkout, so that
# later builds reuse it). Usage, from anywhere: bash python/build-wheel.sh
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
tools="${OESWEEP_WHEEL_TOOLS:-$HOME/.cache/oesweep-wheel-tools}"
tag=manylinux_2_28
if [ ! -x "$tools/bin/maturin" ] || [ ! -x "$tools/bin/auditwheel" ] || [ ! -x "$tools/bin/python-zig" ]; then
    python3 -m venv "$tools"
    "$tools/bin/pip" install --quiet --upgrade pip
    "$tools/bin/pip" install --quiet "maturin>=1.7,<2" "ziglang>=0.13" "auditwheel>=6"
fi
rm -f dist/oesweep-*.whl
# maturin finds zig through the ziglang package of its own environment.
PATH="$tools/bin:$PATH"
(cd python && maturin build --release --zig --compatibility "$tag" --target x86_64-unknown-linux-gnu --out ../dist)
wheel=$(ls dist/oesweep-*.whl)
# auditwheel reads the wheel's ELF files and names the oldest tag their symbols allow.
show=$(auditwheel show "$wheel")
echo "$show"
if ! grep -q "\"$tag" <<<"$show" && ! grep -q "$tag" <<<"$show"; then
    echo "error: auditwheel does not agree with the tag $tag" >&2
    exit 1
fi
echo "wrote $wheel ($(du -k "$wheel" | cut -f1) KiB)"
