#!/usr/bin/env bash
# Quality against the scipy peer on records of several lengths (issue 30; METHOD.md 5.2 step 5):
# which records explore on a head (`solver.explore_rows`, at least 4 heads long) and whether the
# fits stay no worse than the peer's. For each length N: a simulated piezo record with the
# paper's spikes (`oesweep simulate --system jobs/data/piezo_system.json --noise-std 0.1
# --outlier-prob 0.05 --outlier-range 20,60`, seed SEED + N) and a 5 000-sample validation
# record; the peer's 8-k grid of the paper grid's 96 pairs (`../shared/peer/peer.py`, 2
# processes; 5-15 min per record on 2 cores, kept in PEER_DIR and reused); then
# `examples/compare_peer_grid.rs`, which walks every pair as the sweep does (the head walk and
# the whole-record refits included) and counts the least-squares fits and Huber cells no worse
# than the peer's to a relative 1e-4.
#
#   bash benches/peer_records.sh                                  # N = 12288 24576 65536 100000
#   NS="65536" OESWEEP_EXPLORE_ROWS=16384 bash benches/peer_records.sh
#
# Environment: NS, SEED (default 0), PEER_DIR (default /tmp/oesweep-peer-records), PEER (default
# ../shared/peer/peer.py), CARGO_TARGET_DIR (default $HOME/.cache/oesweep-target); the
# OESWEEP_* overrides of compare_peer_grid.rs pass through. Measures quality, not time.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck source=benches/common.sh
source "$root/benches/common.sh"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
ns=${NS:-12288 24576 65536 100000}
seed=${SEED:-0}
dir=${PEER_DIR:-/tmp/oesweep-peer-records}
peer=${PEER:-$root/../shared/peer/peer.py}
[ -f "$peer" ] || { echo "peer_records: no peer at $peer (set PEER)" >&2; exit 2; }
cargo build --release --quiet --manifest-path "$root/Cargo.toml" --bin oesweep --example compare_peer_grid
bin=$CARGO_TARGET_DIR/release/oesweep
compare=$CARGO_TARGET_DIR/release/examples/compare_peer_grid
mkdir -p "$dir"
for n in $ns; do
    s=$((seed + n))
    est=$dir/est_${n}_$s.csv val=$dir/val_${n}_$s.csv grid=$dir/peer_${n}_$s.jsonl
    if [ ! -s "$grid" ]; then
        spiky_record "$bin" "$root" "$est" "$s" "$n"
        spiky_record "$bin" "$root" "$val" "$((s + 1))" 5000
        echo "peer_records: the peer's grid of N = $n (seed $s) ..." >&2
        peer_grid "$peer" "$est" "$val" "$grid" 2
    fi
    echo "== N = $n (seed $s)"
    "$compare" "$est" "$grid" | tail -4
done
