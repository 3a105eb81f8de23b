#!/usr/bin/env bash
# `oesweep export --to matlab` run in GNU Octave (Debian's octave and octave-control): the
# script must build the `tf` with the coefficients of the JSON export (num, den; Octave drops a
# numerator's leading zeros, which leaves the polynomial as it is) and the covariance of the
# MAT-file's and JSON's; the continuous equivalents of `--continuous zoh|tustin` must be Octave's
# `d2c` of the model without its dead time, and the script's `Gc` must be built from them. The
# run is the bundled piezo example, cut down to a small grid.
#
# Needs root and apt-get to install Octave when it is missing (~30 s); without them it says so
# and exits 0 (1 under CI=true: the export to MATLAB must be checked by a real interpreter).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/oesweep-target}"

skip() {
    if [ "${CI:-}" = true ]; then
        echo "octave_export: FAILED: $1 (under CI the Octave test must run)"
        exit 1
    fi
    echo "octave_export: skipped ($1)"
    exit 0
}
if ! command -v octave-cli >/dev/null || ! octave-cli --no-gui --eval "pkg load control" >/dev/null 2>&1; then
    if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null; then
        skip "no octave-cli with the control package, and no root apt-get to install them"
    fi
    apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends octave octave-control >/dev/null
fi

cargo build --release --quiet
bin="$CARGO_TARGET_DIR/release/oesweep"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# The example job on a 2 x 2 x 2 grid: a run in a second, with a covariance for every pick.
python3 - "$repo/jobs/piezo-demo.json" "$tmp/job.json" "$repo/jobs" <<'EOF'
import json, os, sys
job = json.load(open(sys.argv[1]))
for key in ("data", "validation"):
    if isinstance(job.get(key), dict) and "path" in job[key]:
        job[key]["path"] = os.path.join(sys.argv[3], job[key]["path"])
job["grid"]["nb"] = [2, 3]
job["grid"]["nf"] = [2, 3]
job["grid"]["k"] = [0.5, 1.5]
job["output"] = os.path.join(os.path.dirname(sys.argv[2]), "run")
json.dump(job, open(sys.argv[2], "w"))
EOF
"$bin" run "$tmp/job.json" --quiet --threads 2 >/dev/null
"$bin" export "$tmp/run" --to json --out "$tmp/model.json" >/dev/null
"$bin" export "$tmp/run" --to matlab --out "$tmp/model.m" >/dev/null
"$bin" export "$tmp/run" --to mat --out "$tmp/model.mat" >/dev/null
"$bin" export "$tmp/run" --to json --continuous zoh --out "$tmp/zoh.json" 2>/dev/null
"$bin" export "$tmp/run" --to json --continuous tustin --out "$tmp/tustin.json" 2>/dev/null
"$bin" export "$tmp/run" --to matlab --continuous zoh --out "$tmp/modelc.m" 2>/dev/null

# Octave runs the script and prints what it built, full precision.
cat >"$tmp/check.m" <<'EOF'
model
[n, d] = tfdata(G, 'v');
m = load('model.mat');
printf('num'); printf(' %.17g', n); printf('\n');
printf('den'); printf(' %.17g', d); printf('\n');
printf('Ts %.17g\n', get(G, 'tsam'));
printf('cov'); printf(' %.17g', covariance(:)'); printf('\n');
printf('matcov'); printf(' %.17g', m.covariance(:)'); printf('\n');
modelc
[n, d] = tfdata(Gc, 'v');
printf('gcnum'); printf(' %.17g', n); printf('\n');
printf('gcden'); printf(' %.17g', d); printf('\n');
% The model without its dead time (z^k G), through Octave's own d2c.
k = round(input_delay / Ts);
H = tf(num(k+1:end), den(1:end-k), Ts);
for method = {'zoh', 'tustin'}
  [n, d] = tfdata(d2c(H, method{1}), 'v');
  printf('%snum', method{1}); printf(' %.17g', n); printf('\n');
  printf('%sden', method{1}); printf(' %.17g', d); printf('\n');
end
EOF
(cd "$tmp" && octave-cli --no-gui --quiet --no-window-system check.m >octave.out 2>octave.err) || {
    cat "$tmp/octave.err"
    echo "octave_export: FAILED: Octave could not run the exported script"
    exit 1
}
python3 - "$tmp/model.json" "$tmp/octave.out" "$tmp/zoh.json" "$tmp/tustin.json" <<'EOF'
import cmath, json, math, sys
model = json.load(open(sys.argv[1]))
continuous = {m: json.load(open(p))["continuous"] for m, p in (("zoh", sys.argv[3]), ("tustin", sys.argv[4]))}
got = {}
for line in open(sys.argv[2]):
    key, *vals = line.split()
    got[key] = [float(v) for v in vals]

def strip(p):
    # Leading zeros of a polynomial in descending powers: the delay's, dropped by Octave's tf.
    i = 0
    while i < len(p) - 1 and p[i] == 0.0:
        i += 1
    return p[i:]

def close(name, a, b, tol=1e-12):
    assert len(a) == len(b), f"{name}: {len(a)} values from Octave, {len(b)} exported"
    for x, y in zip(a, b):
        assert abs(x - y) <= tol * max(1.0, abs(y)), f"{name}: Octave {x!r}, exported {y!r}"

close("num", strip(got["num"]), strip(model["num"]))
close("den", strip(got["den"]), strip(model["den"]))
close("Ts", got["Ts"], [model["dt"]])
cov = [x for row in model["covariance"] for x in row]
assert cov, "the pick has no covariance"
# Octave prints column-major; the matrix is symmetric, and the check is that it is.
close("covariance", got["cov"], cov)
close("MAT covariance", got["matcov"], cov)

def response(num, den, s):
    value = lambda p: sum(c * s ** (len(p) - 1 - i) for i, c in enumerate(p))
    return value(num) / value(den)

# The continuous equivalents against Octave's d2c, on the imaginary axis up to 0.9 of Nyquist
# (the coefficients span ten decades); the script's Gc is the exported one, digit for digit.
nyquist = math.pi / model["dt"]
for method, c in continuous.items():
    assert c["method"] == method and c["input_delay"] == c["delay_samples"] * model["dt"], c
    for i in range(1, 31):
        s = 1j * nyquist * 0.9 * i / 30
        ours, octave = response(c["num"], c["den"], s), response(got[method + "num"], got[method + "den"], s)
        assert abs(ours - octave) <= 1e-9 * abs(octave), f"{method} at {s}: exported {ours}, Octave's d2c {octave}"
close("Gc num", got["gcnum"], continuous["zoh"]["num"], 0.0)
close("Gc den", got["gcden"], continuous["zoh"]["den"], 0.0)
print(f"octave_export: ok (tf of OE({len(model['b'])}, {len(model['f'])}) delay {model['delay']}, "
      f"{len(cov)} covariance entries, continuous equivalents as Octave's d2c)")
EOF
