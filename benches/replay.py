#!/usr/bin/env python3
"""Replays a run's `--profile` onto T = 1, 2, 4, 8, 16, 32 workers (issue 39).

The profile lists the tasks the worker pool ran (kind, pair, the tasks each one waited for, its
priority, its worker seconds; a whole run's nested checks, METHOD.md 5.6, are tasks of kind
`nested`, one per cell; since issue 48 the spectral estimate is a task, kind `spectrum`) and
the run's serial parts (reading, spectrum in profiles before issue 48, setup, the sweep's own
serial work, reducing and writing; wall seconds; `nested` for a profile whose nested pass ran
in waves after the sweep, before the checks were tasks). A replay lays the tasks on T workers by
list scheduling: whenever a worker is free it starts the ready task that comes first, a task
being ready once the tasks it waits for are done. The makespan is the serial parts plus the
tasks' schedule; makespan(1) / makespan(T) bounds the speed-up on T cores, assuming each task
takes as long as it did in the profiled run (no memory-bandwidth or frequency effects).

Schedules (one column each):
  sweep    the sweep's own rule: ready tasks by the sweep's priority (largest first, ties the
           lower id), at most `live` tasks at once (the workspace cap of sweep::live_workspaces,
           from the profile's `workers`);
  no-cap   the same without the workspace cap (what the cap costs; shown when it binds);
  waves    the schedule before issue 39: a pair's least-squares phase one task (its own minima
           and its finish), in waves of equal nB + nF with a barrier after each wave and before
           the Huber tasks, a wave's pairs in plan order, the Huber tasks by nB + nF (largest
           first, ties plan order), the nested checks (if any) after their own dependencies
           too; no cap;
  lpt      longest measured task first among the ready ones (the sweep's dependencies, no cap):
           what a perfect cost estimate would add to `sweep`.
Also printed: the lower bound max(serial + critical path, serial + work / T) that no schedule
beats.

    python3 benches/replay.py PROFILE.json [--label NAME]
"""

import argparse
import heapq
import json
import sys

WORKERS = [1, 2, 4, 8, 16, 32]


def load(path):
    with open(path) as f:
        d = json.load(f)
    s = d.get("schedule")
    if not s or not s.get("tasks"):
        sys.exit(f"{path}: no schedule.tasks (a profile of `oesweep run --profile` from issue 39 on)")
    return s


def list_schedule(seconds, after, key, workers):
    """Makespan of list scheduling: `key(i)` orders the ready tasks (smallest first)."""
    n = len(seconds)
    before = [[] for _ in range(n)]
    waiting = [0] * n
    for i, a in enumerate(after):
        waiting[i] = len(a)
        for j in a:
            before[j].append(i)
    ready = [(key(i), i) for i in range(n) if waiting[i] == 0]
    heapq.heapify(ready)
    running = []
    t, done = 0.0, 0
    while done < n:
        while ready and len(running) < workers:
            _, i = heapq.heappop(ready)
            heapq.heappush(running, (t + seconds[i], i))
        if not running:
            sys.exit("the profile's task graph has a cycle")
        t, i = heapq.heappop(running)
        finished = [i]
        # Tasks ending at the same instant free their workers together.
        while running and running[0][0] <= t:
            finished.append(heapq.heappop(running)[1])
        for i in finished:
            done += 1
            for j in before[i]:
                waiting[j] -= 1
                if waiting[j] == 0:
                    heapq.heappush(ready, (key(j), j))
    return t


def critical_path(seconds, after):
    order, seen = [], [False] * len(seconds)

    def visit(i):
        stack = [(i, False)]
        while stack:
            v, expanded = stack.pop()
            if expanded:
                order.append(v)
                continue
            if seen[v]:
                continue
            seen[v] = True
            stack.append((v, True))
            stack.extend((j, False) for j in after[v] if not seen[j])

    for i in range(len(seconds)):
        visit(i)
    finish = [0.0] * len(seconds)
    for i in order:
        finish[i] = seconds[i] + max((finish[j] for j in after[i]), default=0.0)
    return max(finish, default=0.0)


def waves(tasks):
    """The pre-issue-39 structure: (seconds, after, key) with zero-length barrier tasks."""
    seconds = [t["seconds"] for t in tasks]
    after = [list(t["after"]) for t in tasks]
    # Then a pair's least-squares phase was one task: its own minima join the finish.
    finish = {(t["nb"], t["nf"], t["delay"]): t["id"] for t in tasks if t["kind"] == "least_squares"}
    for t in tasks:
        if t["kind"] == "least_squares_own":
            seconds[finish[(t["nb"], t["nf"], t["delay"])]] += seconds[t["id"]]
            seconds[t["id"]] = 0.0
    ls = [t for t in tasks if t["kind"] == "least_squares"]
    rest = [t for t in tasks if t["kind"] != "least_squares"]
    by_size = {}
    for t in ls:
        by_size.setdefault(t["nb"] + t["nf"], []).append(t["id"])
    barrier = None
    for size in sorted(by_size):
        for i in by_size[size]:
            after[i] = [barrier] if barrier is not None else []
        seconds.append(0.0)
        after.append(list(by_size[size]))
        barrier = len(seconds) - 1
    for t in rest:
        # A nested check also waits for its cell's Huber task and its sub-models' checks.
        own = list(t["after"]) if t["kind"] == "nested" else []
        if t["kind"] == "spectrum":
            # The spectral estimate (a task since issue 48): beside the first wave.
            after[t["id"]] = []
            continue
        after[t["id"]] = own + ([barrier] if barrier is not None else [])
    n = len(tasks)

    def key(i):
        if i >= n:
            return (0, 0, i)
        t = tasks[i]
        # Least-squares tasks in plan order (their ids); Huber tasks by nB + nF, largest first.
        return (0, 0, i) if t["kind"] == "least_squares" else (1, -(t["nb"] + t["nf"]), i)

    return seconds, after, key


def replay(s):
    tasks = s["tasks"]
    serial = sum(p["seconds"] for p in s["serial"])
    seconds = [t["seconds"] for t in tasks]
    after = [t["after"] for t in tasks]
    w = s["workers"]
    cap = max(w["min_live"], w["budget_bytes"] // max(w["workspace_bytes"], 1))
    sweep_key = lambda i: (-tasks[i]["priority"], i)  # noqa: E731
    lpt_key = lambda i: (-seconds[i], i)  # noqa: E731
    wave_seconds, wave_after, wave_key = waves(tasks)
    work, path = sum(seconds), critical_path(seconds, after)
    rows = []
    for T in WORKERS:
        rows.append(
            {
                "T": T,
                "sweep": serial + list_schedule(seconds, after, sweep_key, min(T, cap)),
                "no-cap": serial + list_schedule(seconds, after, sweep_key, T),
                "waves": serial + list_schedule(wave_seconds, wave_after, wave_key, T),
                "lpt": serial + list_schedule(seconds, after, lpt_key, T),
                "lower": serial + max(path, work / T),
            }
        )
    return rows, dict(serial=serial, work=work, path=path, cap=cap, tasks=len(tasks), w=w, wall=s["wall_seconds"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("profile")
    ap.add_argument("--label", default=None)
    a = ap.parse_args()
    s = load(a.profile)
    rows, info = replay(s)
    w = info["w"]
    print(f"== {a.label or a.profile}")
    print(
        f"{info['tasks']} tasks, {info['work']:.3f} worker s, critical path {info['path']:.3f} s, "
        f"serial parts {info['serial']:.3f} s ("
        + ", ".join(f"{p['part']} {p['seconds']:.3f}" for p in s["serial"])
        + ")"
    )
    print(
        f"profiled on {w['threads']} threads ({w['live']} live workspaces), tasks' wall {info['wall']:.3f} s; "
        f"record {w['record_rows']} rows, workspace cap {info['cap']} "
        f"(max({w['min_live']}, {w['budget_bytes']} / {w['workspace_bytes']} bytes))"
    )
    cols = ["sweep", "no-cap", "waves", "lpt", "lower"]
    show = [c for c in cols if c != "no-cap" or info["cap"] < WORKERS[-1]]
    print(f"{'T':>3} " + " ".join(f"{c + ' s':>9}" for c in show) + "   " + " ".join(f"{c + ' /1':>9} {c + ' /2':>9}" for c in show))
    base1 = {c: rows[0][c] for c in show}
    base2 = {c: rows[1][c] for c in show}
    for r in rows:
        print(
            f"{r['T']:>3} "
            + " ".join(f"{r[c]:>9.3f}" for c in show)
            + "   "
            + " ".join(f"{base1[c] / r[c]:>9.2f} {base2[c] / r[c]:>9.2f}" for c in show)
        )


if __name__ == "__main__":
    main()
