#!/usr/bin/env bash
# The paper grid (jobs/paper-grid.json: 3840 Huber cells + 96 least-squares fits, N = 5000,
# --threads 2) against the scipy peer (../shared/peer/peer.py) on the same cells, in one run on
# one machine (issue 39):
#
#   ratio    the peer's whole grid (nB 7..14 x nF 4..15 x the same 40 k: 3936 fits on 2
#            processes, one BLAS thread each) over our run, interleaved RUNS times (ours, then
#            the peer); medians and ranges;
#   quality  cell by cell, our cells.parquet against the peer's first run
#            (benches/compare_table.py): each Huber cell's W against the peer's parameters at
#            our gamma, each least-squares fit against the peer's, at relative 1e-6, 1e-5 and
#            1e-4, over all fits and over the peer's fits inside the stability boundary;
#   where    the last run's `--profile`: solver fits and iterations by role, worker time by
#            phase (solver, evidence, judging, the rest), reading and writing.
#
#   RUNS=3 bash benches/ratio.sh                 # 4-8 min per peer run on 2 cores
#   SAMPLE=1 RUNS=5 bash benches/ratio.sh        # a quick look only, see below
#
# SAMPLE=1 is the former quick look, labelled as such: the peer on a stratified sample (9 pairs
# x 8 k, one process) extrapolated to the whole grid on two processes. The extrapolation flatters
# us (issue 39: 75-100x extrapolated against 35x measured on the whole grid): never quote it as
# the ratio.
#
# The peer runs with the BLAS a user's numpy has: OPENBLAS_CORETYPE and OPENBLAS_L2_SIZE (which
# some machines set for old OpenBLAS builds, and which make a current numpy run a slower kernel)
# are unset for the peer's command alone, and the kernel it runs is printed (threadpoolctl).
#
# Run on an otherwise idle machine (nothing compiling). Environment: CARGO_TARGET_DIR (default
# $HOME/.cache/oesweep-target), PEER (default ../shared/peer/peer.py), RUNS (default 3), KEEP (a
# folder that keeps the peer's grids, our table and profiles; default a temporary one).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
peer=${PEER:-$root/../shared/peer/peer.py}
runs=${RUNS:-3}
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1

if ! python3 -c 'import numpy, scipy, polars, threadpoolctl' 2>/dev/null; then
    python3 -m pip install --quiet numpy scipy polars threadpoolctl
fi
# The peer's environment: ours, less the variables that pin an old OpenBLAS kernel.
peer_env=(env -u OPENBLAS_CORETYPE -u OPENBLAS_L2_SIZE)
for v in OPENBLAS_CORETYPE OPENBLAS_L2_SIZE; do
    if [[ -n ${!v:-} ]]; then echo "== $v=${!v} is set here: unset for the peer's command"; fi
done
"${peer_env[@]}" python3 - <<'PY'
import numpy, scipy, threadpoolctl
numpy.ones((64, 64)) @ numpy.ones((64, 64))  # load the BLAS
blas = [i for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"]
for i in blas:
    print(f"== the peer's BLAS: {i['internal_api']} {i['version']}, kernel {i.get('architecture')}, "
          f"{i['num_threads']} thread(s) (numpy {numpy.__version__}, scipy {scipy.__version__})")
if not blas:
    print("== the peer's BLAS: none found by threadpoolctl")
PY
(cd "$root" && cargo build --release --quiet --bin oesweep)
bin=$CARGO_TARGET_DIR/release/oesweep
if [[ -n ${KEEP:-} ]]; then
    work=$KEEP
    mkdir -p "$work"
else
    work=$(mktemp -d)
    trap 'rm -rf "$work"' EXIT
fi
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

# ours RUN: the paper grid on 2 threads, its wall time in ours_RUN, its profile in profile_RUN.json.
ours() {
    local s e
    s=$(date +%s.%N)
    "$bin" run "$work/pg.json" --threads 2 --quiet --force --profile "$work/profile_$1.json" >/dev/null 2>&1
    e=$(date +%s.%N)
    echo "$s $e" >"$work/ours_$1"
}

if [[ -z ${SAMPLE:-} ]]; then
    ks=$(python3 -c "print(','.join(repr(0.05 * (2 / 0.05) ** (i / 39)) for i in range(40)))")
    for i in $(seq "$runs"); do
        ours "$i"
        s=$(date +%s.%N)
        "${peer_env[@]}" python3 "$peer" --est "$est" --val "$val" --grid nb=7..14 nf=4..15 "k=$ks" --jobs 2 \
            --out "$work/peer_$i.jsonl" >/dev/null 2>&1
        e=$(date +%s.%N)
        echo "$s $e" >"$work/peer_time_$i"
    done
    python3 - "$work" "$runs" <<'PY'
import statistics, sys
work, runs = sys.argv[1], int(sys.argv[2])
def span(path):
    s, e = map(float, open(path).read().split())
    return e - s
ours = [span(f"{work}/ours_{i}") for i in range(1, runs + 1)]
peer = [span(f"{work}/peer_time_{i}") for i in range(1, runs + 1)]
ratios = [p / o for p, o in zip(peer, ours)]
for i, (o, p) in enumerate(zip(ours, peer), 1):
    print(f"run {i}: paper grid (ours, --threads 2) {o:.2f} s; the peer's whole grid (3936 fits, 2 processes) "
          f"{p:.1f} s; ratio {p / o:.1f}x")
def rng(xs, f="{:.2f}"):
    return f"median {f.format(statistics.median(xs))} [{f.format(min(xs))}, {f.format(max(xs))}]"
print(f"ours {rng(ours)} s; peer {rng(peer, '{:.1f}')} s; ratio peer / ours, same run: {rng(ratios, '{:.1f}')}x")
PY
    echo "== quality, cell by cell (our table against the peer's first run; benches/compare_table.py)"
    python3 "$root/benches/compare_table.py" "$work/pg/cells.parquet" "$work/peer_1.jsonl" "$est"
else
    echo "== SAMPLE=1: a quick look; the peer extrapolated from a stratified sample flatters us, not the ratio"
    ks=$(python3 -c "print(','.join(repr(0.05 * (2 / 0.05) ** (i / 39)) for i in range(2, 40, 5)))")
    for i in $(seq "$runs"); do
        ours "$i"
        "${peer_env[@]}" python3 "$peer" --est "$est" --val "$val" --grid nb=8,10,13 nf=6,10,14 "k=$ks" --jobs 1 \
            --out "$work/peer_$i.jsonl" >/dev/null
    done
    # Stratified: nB's strata 7-8, 9-11, 12-14 by 8, 10, 13 and nF's 4-7, 8-11, 12-15 by 6, 10,
    # 14 (each weighing its stratum's share of the 96 pairs) x the middle k of each block of 5 of
    # the grid's 40 (equal weights); peer = 96 x (least-squares s per pair + 40 x Huber s per
    # cell) / 2 processes, assuming perfect scaling (which favours the peer).
    python3 - "$work" "$runs" <<'PY'
import json, statistics, sys
work, runs = sys.argv[1], int(sys.argv[2])
ratios = []
for i in range(1, runs + 1):
    s, e = map(float, open(f"{work}/ours_{i}").read().split())
    lines = [json.loads(l) for l in open(f"{work}/peer_{i}.jsonl")]
    w = lambda l: {8: 2, 10: 3, 13: 3}[l["nb"]] / 8 / 3
    ls_pair = sum(w(l) * l["seconds"] for l in lines if l["method"] == "ls")
    hub_cell = sum(w(l) * l["seconds"] for l in lines if l["method"] == "huber") / 8
    peer = 96 * (ls_pair + 40 * hub_cell) / 2
    ratios.append(peer / (e - s))
    print(f"run {i}: ours {e - s:.2f} s; peer extrapolated {peer:.1f} s; {peer / (e - s):.1f}x (quick look)")
print(f"quick look, extrapolated: median {statistics.median(ratios):.1f}x [{min(ratios):.1f}, {max(ratios):.1f}]")
PY
fi
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
# Since issue 48 the spectral estimate is a task of the sweep (worker time, beside the solver's
# phases), no longer part of the reading.
print(f"the spectral estimate (a task of the sweep, worker time) {ph['spectrum']:.2f} s")
print(f"outside the sweep (wall): reading {ph['read']:.2f} s, reducing and writing {ph['write']:.2f} s")
PY
python3 - "$work/pg/selection.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
for m in ("m1", "m2"):
    c = s[m]
    print(f"picks: {m} OE({c['nb']},{c['nf']}) k = {c['k']:.4g}, W = {c['criterion']:.6g}, fit_val {c['fit_val']:.4f} %")
PY
