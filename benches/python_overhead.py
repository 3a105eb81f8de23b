"""What the Python package adds to the engine's time (a benchmark, not a test).

1. ``oesweep.fit`` against the library's time for the same call (``Record::from_arrays`` and
   ``engine::fit_arrays`` timed in Rust by ``examples/fit_arrays_time.rs``), interleaved
   repeats: the target is python <= 1.05 * library + 1 ms, as the median over the pairs.
2. ``oesweep.sweep`` against ``oesweep run`` on the same job, interleaved: cells per second.
3. Copies: a float64 array reaches the engine without a conversion copy (the engine copies it
   once into its record).

Usage: python benches/python_overhead.py [RUNS]   (OESWEEP_BIN: the CLI of the same checkout;
OESWEEP_FIT_EXAMPLE: the fit_arrays_time example built from it)
Run by benches/python_overhead.sh, which builds the package into a fresh venv first.
"""

import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
import scipy.signal

import oesweep

RUNS = int(sys.argv[1]) if len(sys.argv) > 1 else 15
BIN = os.environ.get("OESWEEP_BIN") or shutil.which("oesweep")
EXAMPLE = os.environ.get("OESWEEP_FIT_EXAMPLE")  # target/release/examples/fit_arrays_time


def record(n, seed=1):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 1.0], n // 3 + 1), 3)[:n]
    y = scipy.signal.lfilter([0.0, 0.5, 0.3, 0.1], [1.0, -1.2, 0.6, -0.1], u)
    y += 0.05 * rng.standard_normal(n) + np.where(rng.random(n) < 0.05, 2.0, 0.0)
    return u, y


def med(xs):
    return f"{statistics.median(xs) * 1e3:.2f} ms [{min(xs) * 1e3:.2f}, {max(xs) * 1e3:.2f}]"


print(f"oesweep {oesweep.__version__}, {RUNS} interleaved runs per row; medians [min, max]")

# 1. fit: Python's wall time against the library's time for the same call, measured by the
#    Rust example `fit_arrays_time` (its own process, its second call) between the Python calls.
for n, (nb, nf) in ((2_000, (3, 3)), (20_000, (3, 3)), (20_000, (8, 8))):
    u, y = record(n)
    raw = tempfile.NamedTemporaryFile(suffix=".f64", delete=False)
    raw.write(np.concatenate([u, y]).astype("<f8").tobytes())
    raw.close()
    walls, library = [], []
    oesweep.fit(u, y, nb, nf, 0.5, ts=0.01)  # warm-up, as the example's
    for _ in range(RUNS):
        out = subprocess.run([EXAMPLE, raw.name, str(nb), str(nf), "0.5", "0.01"], check=True, capture_output=True)
        library.append(float(out.stdout))
        t0 = time.perf_counter()
        oesweep.fit(u, y, nb, nf, 0.5, ts=0.01)
        walls.append(time.perf_counter() - t0)
    os.unlink(raw.name)
    over = [w - e for w, e in zip(walls, library)]
    # Paired: each Python call against the library call next to it, so that the machine's drift
    # (up to +-30 % between neighbouring minutes on a shared VM) cancels.
    excess = statistics.median(w - (1.05 * e + 1e-3) for w, e in zip(walls, library))
    verdict = "met" if excess <= 0 else "NOT met"
    print(f"fit N={n} OE({nb},{nf}): python {med(walls)}, library {med(library)}, difference {med(over)}; "
          f"target python <= 1.05 library + 1 ms (median over pairs): {verdict}")

# 2. sweep against the CLI, the same job, interleaved.
if BIN:
    tmp = tempfile.mkdtemp()
    u, y = record(5_000)
    np.savetxt(os.path.join(tmp, "d.csv"), np.c_[u, y], delimiter=",", header="u,y", comments="", fmt="%.17g")
    job = {
        "name": "overhead",
        "data": {"path": os.path.join(tmp, "d.csv"), "ts": 0.01},
        "grid": {"nb": [1, 6], "nf": [1, 6], "k": {"from": 0.1, "to": 2.0, "count": 8, "spacing": "log"}},
        "output": os.path.join(tmp, "cli"),
    }
    path = os.path.join(tmp, "job.json")
    with open(path, "w") as fh:
        json.dump(job, fh)
    cli, py = [], []
    for _ in range(max(3, RUNS // 3)):
        t0 = time.perf_counter()
        subprocess.run([BIN, "run", path, "--force", "--quiet", "--threads", "2"], check=True, capture_output=True)
        cli.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        s = oesweep.sweep(job, output=os.path.join(tmp, "py"), force=True, progress=False, threads=2)
        py.append(time.perf_counter() - t0)
    cells = s.cells.height
    print(f"sweep {cells} rows: oesweep run {med(cli)}, oesweep.sweep {med(py)}; "
          f"cells/s ratio python/CLI = {statistics.median(cli) / statistics.median(py):.3f}")
    shutil.rmtree(tmp)
else:
    print("sweep: skipped (set OESWEEP_BIN)")

# 3. copies on the way in.
u, _ = record(1000)
print("a float64 array reaches the engine without a conversion copy:", oesweep._f64("u", u) is u)
print("a float32 array is converted once by numpy:", oesweep._f64("u", u.astype(np.float32)).dtype)
