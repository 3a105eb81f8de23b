# Shared by the bench scripts (sourced): the simulated records and the scipy peer's grids they
# compare on, made once here so that every script measures on the same recipe.

# spiky_record BIN ROOT OUT SEED [N]: a piezo record simulated from jobs/data/piezo_system.json
# with the paper's spikes (noise 0.1, 5 % spikes of 20-60), N samples (the simulator's default
# when not given).
spiky_record() {
    local bin=$1 root=$2 out=$3 seed=$4 n=${5:-}
    "$bin" simulate --system "$root/jobs/data/piezo_system.json" --out "$out" ${n:+--n "$n"} --seed "$seed" \
        --noise-std 0.1 --outlier-prob 0.05 --outlier-range 20,60 >/dev/null
}

# heldout_record BIN ROOT DIR: the held-out record, DIR/est.csv and DIR/val.csv (seeds 21 and
# 22), each made unless present.
heldout_record() {
    local bin=$1 root=$2 dir=$3
    mkdir -p "$dir"
    [[ -s $dir/est.csv ]] || spiky_record "$bin" "$root" "$dir/est.csv" 21
    [[ -s $dir/val.csv ]] || spiky_record "$bin" "$root" "$dir/val.csv" 22
}

# peer_grid PEER EST VAL OUT [JOBS]: the peer's 8-k grid of the paper grid's 96 pairs
# (nB 7..14 x nF 4..15 x k in {0.05, ..., 2}; ~3 min on one process for 5 000 samples) unless
# OUT exists; written to OUT.part first, so that a stopped run leaves no partial grid behind.
peer_grid() {
    local peer=$1 est=$2 val=$3 out=$4 jobs=${5:-1}
    [[ -s $out ]] && return 0
    python3 "$peer" --est "$est" --val "$val" --grid nb=7..14 nf=4..15 k=0.05,0.0625,0.0875,0.15,0.3,0.6,1.0,2.0 \
        --jobs "$jobs" --out "$out.part" >/dev/null 2>&1
    mv "$out.part" "$out"
}

# scaling_record BIN ROOT WORK N: benches/scaling.sh's record of N samples, WORK/rN.csv (the
# piezo system, noise 0.02, 5 % spikes of 1-3, seed 7), and its job WORK/jN.json (estimation on
# the first three quarters, validation on the rest; nB, nF 2..5 x 5 log-spaced k in [0.1, 2];
# output WORK/outN).
scaling_record() {
    local bin=$1 root=$2 work=$3 n=$4
    local est=$((n * 3 / 4))
    "$bin" simulate --system "$root/jobs/data/piezo_system.json" --out "$work/r$n.csv" --n "$n" --seed 7 \
        --noise-std 0.02 --outlier-prob 0.05 --outlier-range 1,3 >/dev/null 2>&1
    cat >"$work/j$n.json" <<JOB
{"name": "scaling-$n", "data": {"path": "$work/r$n.csv", "ts": 1e-4, "rows": [1, $est]},
 "validation": {"rows": [$((est + 1)), $n]},
 "grid": {"nb": [2, 5], "nf": [2, 5], "k": {"from": 0.1, "to": 2.0, "count": 5, "spacing": "log"}},
 "output": "$work/out$n"}
JOB
}
