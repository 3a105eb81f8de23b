#!/usr/bin/env bash
# Issue 30's headline, measured in one run on one machine: the paper grid (jobs/paper-grid.json,
# 3840 Huber cells + 96 least-squares fits, --threads 2) against the scipy peer
# (../shared/peer/peer.py) on a stratified sample of the same grid, extrapolated to the grid on
# two processes:
#
#   sample   stratified: nB's strata 7-8, 9-11, 12-14 by 8, 10, 13 and nF's 4-7, 8-11, 12-15 by
#            6, 10, 14 (9 pairs, each weighing its stratum's share of the 96 pairs) x the middle
#            k of each block of 5 of the grid's 40 (8 k, equal weights): 9 least-squares fits
#            + 72 Huber cells, one process;
#   peer     96 x (weighted mean least-squares seconds per pair + 40 x weighted mean Huber
#            seconds per cell) / 2 processes;
#            (also printed: the same to 8 k per pair, 768 cells, for reading older figures);
#   ratio    peer / ours, per run (ours and the peer's sample interleaved RUNS times);
#   quality  the sample's cells where oesweep's criterion is no worse than the peer's at the
#            same gamma, relative 1e-4 (examples/compare_peer_grid.rs, sweep start strategy);
#   where    the last run's `--profile`: solver fits and iterations by role, worker time by
#            phase (solver, evidence, judging, the rest), reading and writing.
#
#   RUNS=5 bash benches/ratio.sh
#
# Run on an otherwise idle machine (nothing compiling). The peer runs with one BLAS thread; its
# two-process figure assumes perfect scaling, which favours the peer. Environment:
# CARGO_TARGET_DIR (default $HOME/.cache/oesweep-target), PEER (default ../shared/peer/peer.py).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
peer=${PEER:-$root/../shared/peer/peer.py}
runs=${RUNS:-3}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1

if ! python3 -c 'import numpy, scipy' 2>/dev/null; then
    python3 -m pip install --quiet numpy scipy
fi
(cd "$root" && cargo build --release --quiet --bin oesweep --example compare_peer_grid)
bin=$CARGO_TARGET_DIR/release/oesweep
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
est=$root/jobs/data/piezo_est.csv
val=$root/jobs/data/piezo_val.csv

python3 - "$root/jobs/paper-grid.json" "$work" <<'PY'
import json, os, sys
job = json.load(open(sys.argv[1]))
base = os.path.dirname(os.path.abspath(sys.argv[1]))
for key in ("data", "validation"):
    job[key]["path"] = os.path.join(base, job[key]["path"])
job["output"] = os.path.join(sys.argv[2], "pg")
json.dump(job, open(os.path.join(sys.argv[2], "pg.json"), "w"))
PY
ks=$(python3 -c "print(','.join(repr(0.05 * (2 / 0.05) ** (i / 39)) for i in range(2, 40, 5)))")

for i in $(seq "$runs"); do
    s=$(date +%s.%N)
    "$bin" run "$work/pg.json" --threads 2 --quiet --force --profile "$work/profile_$i.json" >/dev/null 2>&1
    e=$(date +%s.%N)
    echo "$s $e" >"$work/ours_$i"
    python3 "$peer" --est "$est" --val "$val" --grid nb=8,10,13 nf=6,10,14 "k=$ks" --jobs 1 \
        --out "$work/peer_$i.jsonl" >/dev/null
done

python3 - "$work" "$runs" <<'PY'
import json, statistics, sys
work, runs = sys.argv[1], int(sys.argv[2])
ratios, ours_all, peer_all, peer8 = [], [], [], []
for i in range(1, runs + 1):
    s, e = map(float, open(f"{work}/ours_{i}").read().split())
    ours = e - s
    lines = [json.loads(l) for l in open(f"{work}/peer_{i}.jsonl")]
    # Stratum weights: nB 8 stands for 7-8, 10 for 9-11, 13 for 12-14; nF 6, 10, 14 for 4 each.
    w = lambda l: {8: 2, 10: 3, 13: 3}[l["nb"]] / 8 / 3
    ls = [l["seconds"] for l in lines if l["method"] == "ls"]
    hub = [l["seconds"] for l in lines if l["method"] == "huber"]
    ls_pair = sum(w(l) * l["seconds"] for l in lines if l["method"] == "ls")
    hub_cell = sum(w(l) * l["seconds"] for l in lines if l["method"] == "huber") / 8
    peer = 96 * (ls_pair + 40 * hub_cell) / 2
    peer8.append(96 * (ls_pair + 8 * hub_cell) / 2)
    ours_all.append(ours)
    peer_all.append(peer)
    ratios.append(peer / ours)
    print(f"run {i}: paper grid {ours:.2f} s; peer sample {len(ls)} ls + {len(hub)} huber fits, "
          f"{sum(ls) + sum(hub):.1f} s -> grid on 2 processes {peer:.1f} s; ratio {peer / ours:.1f}x")
def rng(xs, f="{:.2f}"):
    return f"median {f.format(statistics.median(xs))} [{f.format(min(xs))}, {f.format(max(xs))}]"
print(f"paper grid (ours, --threads 2): {rng(ours_all)} s")
print(f"peer extrapolated (2 processes): {rng(peer_all, '{:.1f}')} s")
print(f"ratio peer / ours: {rng(ratios, '{:.1f}')}x")
# For reading older figures: the same extrapolation to 8 k per pair (768 cells, the peer's own
# 8-k grid) instead of the paper grid's 40.
print(f"(peer extrapolated to 8 k per pair, 2 processes: {rng(peer8, '{:.1f}')} s)")
PY
echo "== quality on the sample (the peer's first run; relative 1e-4, the sweep's chains)"
"$CARGO_TARGET_DIR/release/examples/compare_peer_grid" "$est" "$work/peer_1.jsonl" 2>&1 | tail -5
echo "== where the time goes (the last run's --profile; worker seconds summed over 2 threads)"
python3 - "$work/profile_$runs.json" "$work/pg/cells.parquet" <<'PY'
import json, sys
p = json.load(open(sys.argv[1]))
fits = sum(r["fits"] for r in p["roles"])
its = sum(r["iterations"] for r in p["roles"])
print(f"{'role':<14} {'fits':>6} {'iterations':>11} {'per fit':>8} {'solver s':>9}")
for r in p["roles"]:
    if r["fits"]:
        print(f"{r['role']:<14} {r['fits']:>6} {r['iterations']:>11} {r['iterations'] / r['fits']:>8.1f} {r['solver_seconds']:>9.2f}")
print(f"{'all':<14} {fits:>6} {its:>11} {its / fits:>8.1f}")
print(f"iterations per table row (3840 Huber cells + 96 least-squares fits): {its / 3936:.1f}")
ph = {x["phase"]: x["seconds"] for x in p["phases"]}
work = ph["least_squares_phase"] + ph["huber_phase"]
solver = sum(r["solver_seconds"] for r in p["roles"])
print(f"sweep wall {ph['sweep']:.2f} s, worker time {work:.2f} s: solver {solver:.2f} ({100 * solver / work:.0f} %), "
      f"evidence {ph['evidence']:.2f} ({100 * ph['evidence'] / work:.0f} %), judging (fit %, validation, band) "
      f"{ph['judge']:.2f} ({100 * ph['judge'] / work:.0f} %), rest (initial guesses, bookkeeping) "
      f"{work - solver - ph['evidence'] - ph['judge']:.2f}")
print(f"outside the sweep (wall): reading {ph['read']:.2f} s (of which the spectrum {ph['spectrum']:.2f}), "
      f"reducing and writing {ph['write']:.2f} s")
PY
python3 - "$work/pg/selection.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for m in ("m1", "m2"):
    c = s[m]
    print(f"picks: {m} OE({c['nb']},{c['nf']}) k = {c['k']:.4g}, W = {c['criterion']:.6g}, fit_val {c['fit_val']:.4f} %")
PY
