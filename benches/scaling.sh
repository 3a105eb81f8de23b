#!/usr/bin/env bash
# Long records linear in N (issue 30): one small grid (nB 2..5 x nF 2..5 x 5 k = 80 Huber cells +
# 16 least-squares fits, job defaults: offset and initial state estimated, 3/4 of the record for
# estimation, the rest for validation) on simulated piezo records of N = 5 000 ... 1 000 000
# samples (`oesweep simulate`, 5 % spikes), each length RUNS times, the lengths interleaved.
# Prints per N the median wall time, the time per estimation sample per cell (microseconds per
# 1000 samples per cell), its ratio to the shortest record's, and the peak memory (max RSS).
#
#   RUNS=3 bash benches/scaling.sh
#   NS="5000 100000" RUNS=1 bash benches/scaling.sh     # other lengths
#
# Run on an otherwise idle machine (nothing compiling). Environment: CARGO_TARGET_DIR (default
# $HOME/.cache/oesweep-target), THREADS (default 2), NS, RUNS (default 3).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck source=benches/common.sh
source "$root/benches/common.sh"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
threads=${THREADS:-2}
runs=${RUNS:-3}
ns=${NS:-5000 20000 100000 300000 1000000}

cargo build --release --quiet --manifest-path "$root/Cargo.toml" --bin oesweep
bin=$CARGO_TARGET_DIR/release/oesweep
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

for n in $ns; do
    scaling_record "$bin" "$root" "$work" "$n"
done

for i in $(seq "$runs"); do
    for n in $ns; do
        /usr/bin/time -f "%e %M" -o "$work/t_${n}_$i" "$bin" run "$work/j$n.json" --threads "$threads" --quiet \
            --force >/dev/null 2>&1
    done
done

python3 - "$work" "$runs" $ns <<'PY'
import statistics, sys
work, runs, ns = sys.argv[1], int(sys.argv[2]), [int(n) for n in sys.argv[3:]]
cells = 80
base = None
print(f"{'N':>9} {'est rows':>9} {'wall s (median [min, max])':>28} {'us / 1k samples / cell':>23} {'vs first':>9} {'max RSS MB':>11}")
for n in ns:
    t = [tuple(map(float, open(f"{work}/t_{n}_{i}").read().split())) for i in range(1, runs + 1)]
    wall = [x[0] for x in t]
    rss = max(x[1] for x in t) / 1024
    est = n * 3 // 4
    per = statistics.median(wall) / (est / 1000) / cells * 1e6
    base = base or per
    print(f"{n:>9} {est:>9} {statistics.median(wall):>10.2f} [{min(wall):.2f}, {max(wall):.2f}]{'':>6} {per:>23.1f} {per / base:>9.2f} {rss:>11.0f}")
PY
