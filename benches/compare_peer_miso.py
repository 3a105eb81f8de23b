#!/usr/bin/env python3
"""Several inputs against the MISO peer (../shared/peer/peer_miso.py), cell by cell: each tool's
least-squares criterion, its Huber W at k, and its wall time per cell (median of --repeat runs,
the two tools interleaved). Both are run on the peer's model: no offset, zero initial state.
Our side is `oesweep fit --json` (the fit's own `seconds`, the estimation without reading the
file); the peer's is its own `seconds` (least squares + Huber). Usage: see compare_peer_miso.sh.
"""
import argparse
import json
import statistics
import subprocess
import sys


def ours(bin_, est, cols, y, nb, nf, d, k):
    out = subprocess.run(
        [bin_, "fit", "--data", est, "--u", ",".join(cols), "--y", y, "--nb", nb, "--nf", nf, "--delay", d,
         "--k", str(k), "--offset", "none", "--initial-state", "zero", "--json"],
        check=True, capture_output=True, text=True).stdout
    r = json.loads(out)
    return r["ls"]["criterion"], r["criterion"], r["seconds"]


def peer(peer_, est, cols, y, nb, nf, d, k):
    out = subprocess.run(
        [sys.executable, peer_, "--est", est, "--u", ",".join(cols), "--y", y, "--nb", nb, "--nf", nf,
         "--delay", d, "--k", str(k)], check=True, capture_output=True, text=True).stdout
    ls, hub = [json.loads(line) for line in out.splitlines()[:2]]
    return ls["mse"] / 2, hub["W"], ls["seconds"] + hub["seconds"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", required=True)
    ap.add_argument("--peer", required=True)
    ap.add_argument("--est", required=True)
    ap.add_argument("--u", required=True, help="input columns, comma-separated")
    ap.add_argument("--y", default="y")
    ap.add_argument("--cell", action="append", required=True, help="NB;NF;DELAY, each comma-separated per input")
    ap.add_argument("--k", type=float, default=1.345)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    cols = a.u.split(",")
    print(f"{'cell':<28}{'LS ours/peer':>14}{'W ours/peer':>13}{'ours s':>9}{'peer s':>9}{'speed-up':>10}")
    ratios = []
    for cell in a.cell:
        nb, nf, d = cell.split(";")
        t_ours, t_peer = [], []
        for _ in range(a.repeat):
            ls_o, w_o, s_o = ours(a.bin, a.est, cols, a.y, nb, nf, d, a.k)
            ls_p, w_p, s_p = peer(a.peer, a.est, cols, a.y, nb, nf, d, a.k)
            t_ours.append(s_o)
            t_peer.append(s_p)
        mo, mp = statistics.median(t_ours), statistics.median(t_peer)
        ratios.append(mp / mo)
        print(f"{cell:<28}{ls_o / ls_p:>14.6f}{w_o / w_p:>13.6f}{mo:>9.4f}{mp:>9.4f}{mp / mo:>9.1f}x")
    print(f"median speed-up over the cells: {statistics.median(ratios):.1f}x "
          f"(range {min(ratios):.1f}-{max(ratios):.1f}x)")


if __name__ == "__main__":
    main()
