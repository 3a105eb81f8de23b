#!/usr/bin/env bash
# Criteria and speed of oesweep against the scipy peer (../shared/peer/peer.py), cell by cell.
#
#   bash benches/compare_peer.sh                                  # default cells and k
#   bash benches/compare_peer.sh --cells 9,12 12,12 --k 0.0625 --repeat 3
#
# Options are those of benches/compare_peer.py (--cells NB,NF ..., --k K (repeatable),
# --repeat R (default 3, median time), --raw FILE, --est/--val to use other records). Environment: CARGO_TARGET_DIR
# (default $HOME/.cache/oesweep-target, where the project keeps its build), PEER (path of
# peer.py, default ../shared/peer/peer.py next to the clone).
#
# Both tools are single-threaded; run this on an otherwise idle machine, since the two
# measure wall-clock time.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
peer=${PEER:-$root/../shared/peer/peer.py}

if [[ ! -f $peer ]]; then
    echo "compare_peer: peer not found at $peer (set PEER=/path/to/peer.py)" >&2
    exit 1
fi

# The peer needs numpy and scipy; install them for this user only if they are missing.
if ! python3 -c 'import numpy, scipy' 2>/dev/null; then
    echo "compare_peer: installing numpy and scipy" >&2
    python3 -m pip install --user --quiet numpy scipy || python3 -m pip install --quiet numpy scipy
fi

# Always rebuild: a stale binary would silently compare old code.
(cd "$root" && cargo build --release --quiet --bin oesweep)

exec python3 "$root/benches/compare_peer.py" \
    --bin "$CARGO_TARGET_DIR/release/oesweep" \
    --peer "$peer" \
    --est "$root/jobs/data/piezo_est.csv" \
    --val "$root/jobs/data/piezo_val.csv" \
    "$@"
