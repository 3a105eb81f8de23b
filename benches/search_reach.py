#!/usr/bin/env python3
"""The coordinate search against the full product (METHOD.md 20, PERFORMANCE.md "Several
inputs"): on R realisations of the Monte Carlo systems of `miso_monte_carlo.py` (2 or 3 inputs,
N samples, Gaussian noise with a share of spikes, nB and nF in 1..3 per input, delays fixed
at the truth or searched over `--delays`), runs each job twice, `grid.search` "product" and
"coordinate", and counts how often the search's lead pick is the product's and the share of
the product's fits (Huber cells and least-squares fits) it took.

    python3 benches/search_reach.py --bin target/release/oesweep --inputs 3 --spikes 0.05 [--runs 10] [--validation]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from miso_monte_carlo import SYSTEM, record, write  # noqa: E402


def lead(out, m):
    with open(os.path.join(out, "selection.json")) as fh:
        sel = json.load(fh)
    model = sel["picks"][sel["rule"]]["model"]
    return [(model[f"nb_{i + 1}"], model[f"nf_{i + 1}"], model[f"delay_{i + 1}"]) for i in range(m)], model.get("k")


def count_fits(out):
    try:
        import polars as pl

        t = pl.read_parquet(os.path.join(out, "cells.parquet"))
        return t.height
    except ImportError:
        import pyarrow.parquet as pq

        return pq.read_metadata(os.path.join(out, "cells.parquet")).num_rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--inputs", type=int, default=3)
    ap.add_argument("--n", type=int, default=3000)
    ap.add_argument("--spikes", type=float, default=0.05)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--first", type=int, default=0, help="first realisation (seeds 100 + r)")
    ap.add_argument("--validation", action="store_true")
    ap.add_argument("--delays", default=None, help="delay range searched per input, e.g. 0,2 (default: the truth)")
    a = ap.parse_args()
    m = a.inputs
    same, ratios = 0, []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(a.first, a.first + a.runs):
            est, val = os.path.join(tmp, f"e{r}.csv"), os.path.join(tmp, f"v{r}.csv")
            write(est, *record(m, a.n, 100 + r, a.spikes))
            job = {
                "name": f"reach{r}",
                "data": {"path": est, "u": [f"u{i + 1}" for i in range(m)], "y": "y", "ts": 1.0},
                "grid": {"nb": [1, 3], "nf": [1, 3], "k": {"from": 0.1, "to": 2.0, "count": 4, "spacing": "log"}},
                "offset": "none",
            }
            if a.delays:
                lo, hi = (int(x) for x in a.delays.split(","))
                job["grid"]["delay"] = [lo, hi]
            else:
                job["delay"] = [d for _, _, d in SYSTEM[:m]]
            if a.validation:
                write(val, *record(m, a.n, 500 + r, a.spikes))
                job["validation"] = {"path": val, "u": [f"u{i + 1}" for i in range(m)], "y": "y0"}
            got = {}
            for search in ("coordinate", "product"):
                out = os.path.join(tmp, f"out{r}-{search}")
                job["grid"]["search"] = search
                job["output"] = out
                path = os.path.join(tmp, f"job{r}-{search}.json")
                with open(path, "w") as fh:
                    json.dump(job, fh)
                t = time.perf_counter()
                subprocess.run([a.bin, "run", path, "--quiet"], check=True, capture_output=True)
                got[search] = (*lead(out, m), count_fits(out), time.perf_counter() - t)
            (pc, kc, fc, tc), (pp, kp, fp, tp) = got["coordinate"], got["product"]
            hit = pc == pp and kc == kp
            same += hit
            ratios.append(fc / fp)
            print(f"{r}: product {pp} k {kp} ({fp} fits, {tp:.0f} s); coordinate {pc} k {kc} ({fc} fits, {tc:.0f} s)"
                  f"{'' if hit else '  DIFFERENT'}", flush=True)
    print(f"{m} inputs, N = {a.n}, spikes {a.spikes:.0%}, {'with' if a.validation else 'without'} validation, "
          f"delays {a.delays or 'fixed'}: coordinate search's lead pick = the product's in {same} of {a.runs}; "
          f"its fits {min(ratios):.3f}-{max(ratios):.3f} of the product's (mean {sum(ratios) / len(ratios):.3f})")


if __name__ == "__main__":
    main()
