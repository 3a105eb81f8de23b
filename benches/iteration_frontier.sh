#!/usr/bin/env bash
# What the paper grid's iterations per table row cost in quality (issue 30's "<= 12" target):
# for each setting of the solver knobs that cut iterations, the paper grid's iterations (all
# minimisations, from --profile, and the winning fits the table reports) next to the quality
# against the scipy peer's 8-k grid (examples/compare_peer_grid.rs, the same knobs) on the
# bundled record and on the held-out record of benches/frontier.sh.
#
#   bash benches/iteration_frontier.sh
#   PEER_GRID=/tmp/peer_grid.jsonl HELDOUT=/tmp/heldout bash benches/iteration_frontier.sh
#
# Counts only, no clock: it may run on a busy machine. The peer's grids take ~3 min per record;
# PEER_GRID (bundled) and HELDOUT/peer_grid.jsonl are reused when present, made otherwise
# (HELDOUT defaults to a temporary directory; its record is simulated as frontier.sh does).
# Environment: CARGO_TARGET_DIR (default $HOME/.cache/oesweep-target), PEER (default
# ../shared/peer/peer.py).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck source=benches/common.sh
source "$root/benches/common.sh"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
peer=${PEER:-$root/../shared/peer/peer.py}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1

if ! python3 -c 'import numpy, scipy, polars' 2>/dev/null; then
    python3 -m pip install --quiet numpy scipy polars
fi
(cd "$root" && cargo build --release --quiet --bin oesweep --example compare_peer_grid)
bin=$CARGO_TARGET_DIR/release/oesweep
ex=$CARGO_TARGET_DIR/release/examples
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
heldout=${HELDOUT:-$work/heldout}
bundled_grid=${PEER_GRID:-$work/peer_grid.jsonl}

heldout_record "$bin" "$root" "$heldout"
peer_grid "$peer" "$root/jobs/data/piezo_est.csv" "$root/jobs/data/piezo_val.csv" "$bundled_grid"
peer_grid "$peer" "$heldout/est.csv" "$heldout/val.csv" "$heldout/peer_grid.jsonl"

printf '%-44s %9s %7s %9s %8s %8s %8s %8s\n' setting iters per_row reported L2_bund L2_held Hub_bund Hub_held
# name huber_extra_starts huber_tol nested_starts
while read -r name extra tol nested; do
    python3 - "$root/jobs/paper-grid.json" "$work" "$extra" "$tol" "$nested" <<'PY'
import json, sys, os
job = json.load(open(sys.argv[1]))
base = os.path.dirname(os.path.abspath(sys.argv[1]))
for part in ("data", "validation"):
    job[part]["path"] = os.path.join(base, job[part]["path"])
job["output"] = os.path.join(sys.argv[2], "pg")
job["solver"] = {"huber_extra_starts": int(sys.argv[3]), "huber_tol": float(sys.argv[4]),
                 "nested_starts": sys.argv[5] == "true"}
json.dump(job, open(os.path.join(sys.argv[2], "pg.json"), "w"))
PY
    "$bin" run "$work/pg.json" --threads 2 --quiet --force --profile "$work/prof.json" >/dev/null 2>&1
    read -r iters rows reported < <(python3 - "$work/prof.json" "$work/pg/cells.parquet" <<'PY'
import json, sys
import polars as pl
prof = json.load(open(sys.argv[1]))
cells = pl.read_parquet(sys.argv[2])
print(sum(r["iterations"] for r in prof["roles"]), cells.height, cells["iterations"].sum())
PY
)
    counts=()
    for rec in "$root/jobs/data/piezo_est.csv:$bundled_grid" "$heldout/est.csv:$heldout/peer_grid.jsonl"; do
        out=$(OESWEEP_EXTRA_STARTS=$extra OESWEEP_HUBER_TOL=$tol OESWEEP_NESTED_STARTS=$nested \
            "$ex/compare_peer_grid" "${rec%%:*}" "${rec##*:}" 2>&1)
        counts+=("$(grep '^least squares' <<<"$out" | grep -o '[0-9]*/96')")
        counts+=("$(grep '^Huber' <<<"$out" | grep -o '[0-9]*/768')")
    done
    printf '%-44s %9d %7.1f %9d %8s %8s %8s %8s\n' "$name" "$iters" "$(awk -v a="$iters" -v b="$rows" 'BEGIN { print a / b }')" "$reported" \
        "${counts[0]}" "${counts[2]}" "${counts[1]}" "${counts[3]}"
done <<'SETTINGS'
defaults(extra_starts=2,huber_tol=1e-8,nested) 2 1e-8 true
huber_extra_starts=1 1 1e-8 true
huber_extra_starts=0 0 1e-8 true
huber_tol=1e-7 2 1e-7 true
nested_starts=false 2 1e-8 false
all_three(0,1e-7,false) 0 1e-7 false
SETTINGS
echo "per_row: all minimisations' iterations / table rows; reported: the table's iterations column"
echo "(the winning fits); L2/Hub: least-squares fits / Huber cells no worse than the peer (rel 1e-4)"
