#!/usr/bin/env bash
# The release wheel of the Python package: dist/oesweep-VERSION-cp311-abi3-manylinux_2_28_x86_64.whl,
# one file for every CPython >= 3.11 on x86-64 Linux with glibc >= 2.28, holding the native
# module and the `oesweep` command. Usage, from anywhere: bash python/build-wheel.sh
#
# The native module is linked by zig against glibc 2.28's symbol versions, whatever glibc the
# build machine has; the dependencies are the host build that `pip install ./python` makes too.
# (maturin's own --zig cross-compiles, a second cold build of polars and every other dependency
# for the same machine; only the link needs zig.) maturin refuses a module that needs a newer
# glibc than the tag, and auditwheel must agree with the tag too.
#
# The tools (maturin, ziglang, auditwheel) are installed with pip into $OESWEEP_WHEEL_TOOLS
# (default ~/.cache/oesweep-wheel-tools) once; the Rust build goes to $CARGO_TARGET_DIR (default
# ~/.cache/oesweep-target, outside the checkout, so that later builds reuse it).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"
tools="${OESWEEP_WHEEL_TOOLS:-$HOME/.cache/oesweep-wheel-tools}"
glibc=2.28
tag="manylinux_${glibc/./_}"
if [ ! -x "$tools/bin/maturin" ] || [ ! -x "$tools/bin/auditwheel" ] || [ ! -x "$tools/bin/python-zig" ]; then
    python3 -m venv "$tools"
    "$tools/bin/pip" install --quiet --upgrade pip
    "$tools/bin/pip" install --quiet "maturin>=1.7,<2" "ziglang>=0.13" "auditwheel>=6"
fi
# The linker: maturin's wrapper of `zig cc`, which adapts rustc's linker arguments to zig.
linker="$tools/zigcc-x86_64-linux-gnu.$glibc.sh"
cat >"$linker" <<SH
#!/bin/sh
export CARGO_ZIGBUILD_ZIG_COMMAND="$tools/bin/python3" CARGO_ZIGBUILD_ZIG_COMMAND_ARGS="-m ziglang"
exec "$tools/bin/maturin" zig cc -- -g -fno-sanitize=all -target x86_64-linux-gnu.$glibc "\$@"
SH
chmod +x "$linker"
rm -f dist/oesweep-*.whl
# Byte code a test or an editor left in the package folder is no part of the wheel.
rm -rf python/oesweep/__pycache__
(cd python && "$tools/bin/maturin" build --release --compatibility "$tag" --out ../dist -- -C linker="$linker")
wheel=$(ls dist/oesweep-*.whl)
# auditwheel reads the wheel's ELF files and names the oldest tag their symbols allow: it must
# be the wheel's own or an older one.
show=$(PATH="$tools/bin:$PATH" auditwheel show "$wheel")
echo "$show"
allowed=$(grep -o '"manylinux_2_[0-9]*_x86_64"' <<<"$show" | head -1 | tr -d '"')
minor=${allowed#manylinux_2_}
minor=${minor%_x86_64}
if [ -z "$allowed" ] || [ "$minor" -gt "${glibc#2.}" ]; then
    echo "error: auditwheel does not agree with the tag $tag (it allows ${allowed:-none})" >&2
    exit 1
fi
echo "wrote $wheel ($(du -k "$wheel" | cut -f1) KiB)"
