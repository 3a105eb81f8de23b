#!/usr/bin/env bash
# Several inputs: criteria and speed of `oesweep fit` against the MISO scipy peer
# (../shared/peer/peer_miso.py) on the same cells of tests/fixtures/miso/three.csv (three
# inputs, N = 1000, 5 % spikes), the peer's model (no offset, zero initial state).
#
#   bash benches/compare_peer_miso.sh [--repeat R]
#
# Environment: CARGO_TARGET_DIR (default $HOME/.cache/oesweep-target), PEER (path of
# peer_miso.py). Both tools are single-threaded; run on an otherwise idle machine.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
peer=${PEER:-$root/../shared/peer/peer_miso.py}
[[ -f $peer ]] || { echo "compare_peer_miso: peer not found at $peer (set PEER=)" >&2; exit 1; }
python3 -c 'import numpy, scipy' 2>/dev/null || python3 -m pip install --quiet numpy scipy
# The peer's BLAS as a user has it (benches/ratio.sh): no kernel or cache override.
unset OPENBLAS_CORETYPE OPENBLAS_L2_SIZE
(cd "$root" && cargo build --release --quiet --bin oesweep)
exec python3 "$root/benches/compare_peer_miso.py" --bin "$CARGO_TARGET_DIR/release/oesweep" --peer "$peer" \
    --est "$root/tests/fixtures/miso/three.csv" --u u1,u2,u3 --y y \
    --cell "2,1,2;2,1,1;1,2,0" --cell "1,1,1;1,1,1;1,2,0" --cell "2,2,2;2,1,1;1,2,0" --cell "3,2,3;3,2,2;1,2,0" \
    "$@"
