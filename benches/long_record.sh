#!/usr/bin/env bash
# Wall time and peak memory (max RSS) of a long-record sweep (issue 19): a 131 072-sample
# simulated piezo record (100 000 estimation rows, the rest validation), nB 1..8 x nF 1..8 x
# 10 k, job defaults (offset and initial state estimated), on 2 threads.
#
#   bash benches/long_record.sh                 # solver.method = lm (the default)
#   bash benches/long_record.sh separable       # variable projection
#   N=262144 bash benches/long_record.sh        # another length (estimation rows: 3/4 of N)
#   OLD=/tmp/oesweep_old RUNS=3 bash benches/long_record.sh
#                                               # against an older build (its binary copied aside
#                                               # first), RUNS interleaved pairs, medians and ratio
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
if [ -n "${OLD:-}" ]; then
    runs=${RUNS:-3}
    for i in $(seq "$runs"); do
        for b in old new; do
            exe=$bin
            [ "$b" = old ] && exe=$OLD
            /usr/bin/time -f "%e %M" -o "$work/t_${b}_$i" "$exe" run "$work/long.json" --threads "$threads" \
                --quiet --force >/dev/null
        done
    done
    python3 - "$work" "$runs" "$OLD" <<'PY'
import statistics, sys
work, runs, old = sys.argv[1], int(sys.argv[2]), sys.argv[3]
t = {b: [tuple(map(float, open(f"{work}/t_{b}_{i}").read().split())) for i in range(1, runs + 1)] for b in ("old", "new")}
for b, name in (("old", old), ("new", "this build")):
    w = [x[0] for x in t[b]]
    print(f"long_record {name}: median {statistics.median(w):.2f} s [{min(w):.2f}, {max(w):.2f}], "
          f"max RSS {max(x[1] for x in t[b]) / 1024:.0f} MB")
ratios = [n[0] / o[0] for n, o in zip(t["new"], t["old"])]
print(f"long_record new / old per pair: median {statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}]")
PY
else
    /usr/bin/time -f "long_record: N = $n, method = $method, $threads threads: %e s wall, %M KB max RSS" \
        "$bin" run "$work/long.json" --threads "$threads" --quiet
fi
python3 - "$work/out/selection.json" <<'PY' 2>/dev/null || true
import json, sys
s = json.load(open(sys.argv[1]))
for m in ("m1", "m2"):
    c = s[m]
    print(f"long_record: {m} OE({c['nb']},{c['nf']}) k = {c['k']:.4g}, fit_val {c['fit_val']:.3f} %")
PY
