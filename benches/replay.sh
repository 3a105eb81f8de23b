#!/usr/bin/env bash
# The speed-up bound on more cores than this machine has (issue 39): runs the paper grid
# (jobs/paper-grid.json) and the 1 000 000-sample record of benches/scaling.sh (its 16-pair grid,
# 750 000 estimation rows) with `--threads 2 --profile`, and replays each profile onto
# T = 1, 2, 4, 8, 16, 32 workers (benches/replay.py: the sweep's own schedule, the one before
# issue 39, longest-measured-first, and the lower bound). Then the peak memory (max RSS) of the
# 1M-sample record at --threads 2 and 16 (memory needs no cores; 16 threads on 2 cores take
# about as long as 2).
#
#   bash benches/replay.sh
#   MEMORY=0 bash benches/replay.sh       # no --threads 16 run
#
# The replay assumes every task takes on T cores what it took here; the numbers are a bound,
# not a measurement of a many-core run. Environment: CARGO_TARGET_DIR (default
# $HOME/.cache/oesweep-target), MEMORY (default 1), KEEP (a folder to keep the profiles in).
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
# shellcheck source=benches/common.sh
source "$root/benches/common.sh"
export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}
memory=${MEMORY:-1}

cargo build --release --quiet --manifest-path "$root/Cargo.toml" --bin oesweep
bin=$CARGO_TARGET_DIR/release/oesweep
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The paper grid with its records by absolute path and the results in $work.
python3 - "$root/jobs/paper-grid.json" "$work/paper.json" "$work/paper-out" <<'PY'
import json, os, sys
src, dst, out = sys.argv[1:]
job = json.load(open(src))
base = os.path.dirname(src)
for part in ("data", "validation"):
    job[part]["path"] = os.path.join(base, job[part]["path"])
job["output"] = out
json.dump(job, open(dst, "w"))
PY
timeout 1200 "$bin" run "$work/paper.json" --threads 2 --quiet --force --profile "$work/paper-profile.json" \
    >/dev/null 2>&1

# benches/scaling.sh's record and grid at N = 1 000 000.
n=1000000
scaling_record "$bin" "$root" "$work" "$n"
/usr/bin/time -f "%M" -o "$work/rss2" timeout 1200 "$bin" run "$work/j$n.json" --threads 2 --quiet --force \
    --profile "$work/long-profile.json" >/dev/null 2>&1

python3 "$root/benches/replay.py" "$work/paper-profile.json" --label "paper grid (jobs/paper-grid.json), profiled on 2 threads"
echo
python3 "$root/benches/replay.py" "$work/long-profile.json" --label "1 000 000-sample record (benches/scaling.sh's grid), profiled on 2 threads"

if [[ $memory == 1 ]]; then
    /usr/bin/time -f "%M" -o "$work/rss16" timeout 1200 "$bin" run "$work/j$n.json" --threads 16 --quiet --force \
        >/dev/null 2>&1
    echo
    echo "peak memory of the 1M-sample record: --threads 2 $(($(cat "$work/rss2") / 1024)) MB," \
        "--threads 16 $(($(cat "$work/rss16") / 1024)) MB"
fi
if [[ -n ${KEEP:-} ]]; then
    mkdir -p "$KEEP"
    cp "$work/paper-profile.json" "$work/long-profile.json" "$KEEP/"
fi
