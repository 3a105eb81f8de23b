#!/usr/bin/env bash
# Wall time and peak memory (max RSS) of a long-record sweep (issue 19): a 131 072-sample
# simulated piezo record (100 000 estimation rows, the rest validation), nB 1..8 x nF 1..8 x
# 10 k, job defaults (offset and initial state estimated), on 2 threads.
#
#   bash benches/long_record.sh                 # solver.method = lm (the default)
#   bash benches/long_record.sh separable       # variable projection
#   N=262144 bash benches/long_record.sh        # another length (estimation rows: 3/4 of N)
#
# Run it on an otherwise idle machine: it reports wall-clock time. Environment: CARGO_TARGET_DIR
# (default $HOME/.cache/oesweep-target), THREADS (default 2).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
method=${1:-lm}
n=${N:-131072}
threads=${THREADS:-2}
est=$(( n == 131072 ? 100000 : n * 3 / 4 ))

cargo build --release --quiet --manifest-path "$root/Cargo.toml"
bin=$CARGO_TARGET_DIR/release/oesweep
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

"$bin" simulate --system "$root/jobs/data/piezo_system.json" --out "$work/long.csv" --n "$n" --seed 7 \
    --noise-std 0.02 --outlier-prob 0.05 --outlier-range 1,3
cat > "$work/long.json" <<JOB
{"name": "long-record", "data": {"path": "$work/long.csv", "ts": 1e-4, "rows": [1, $est]},
 "validation": {"rows": [$((est + 1)), $n]},
 "grid": {"nb": [1, 8], "nf": [1, 8], "k": {"from": 0.05, "to": 2.0, "count": 10, "spacing": "log"}},
 "solver": {"method": "$method"}, "output": "$work/out"}
JOB
/usr/bin/time -f "long_record: N = $n, method = $method, $threads threads: %e s wall, %M KB max RSS" \
    "$bin" run "$work/long.json" --threads "$threads" --quiet
python3 - "$work/out/selection.json" <<'PY' 2>/dev/null || true
import json, sys
s = json.load(open(sys.argv[1]))
for m in ("m1", "m2"):
    c = s[m]
    print(f"long_record: {m} OE({c['nb']},{c['nf']}) k = {c['k']:.4g}, fit_val {c['fit_val']:.3f} %")
PY
