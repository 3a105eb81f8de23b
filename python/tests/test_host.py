"""What the package does to the Python process that calls it: the GIL let go by every native
call, Ctrl-C during a sweep (in the package and in the wheel's command), and the signal
handler of the in-process `oesweep` command. Each state is reached by a handshake, not a wait."""

import json
import os
import re
import signal
import subprocess
import sys
import textwrap

import oesweep
import polars as pl
import pytest
from oesweep import _cli, _oesweep

from support import BIN, job_for, record

# Each native call run over and over on a thread while the main thread waits for the GIL. With
# a switch interval longer than the test, the interpreter never takes the GIL from its holder:
# the main thread runs again only when the looping thread lets it go, which a call that holds
# it never does (the child then hangs, and its timeout fails the test). So the main thread's
# first step, reading the loop's counters, happens inside a call: entered = left + 1.
GIL_CHILD = textwrap.dedent(
    """
    import json, sys, threading
    import numpy as np
    from oesweep import _oesweep

    a = json.loads(sys.argv[1])
    u, y = np.array(a["u"]), np.array(a["y"])
    calls = {
        "fit": lambda: _oesweep.fit([u], y, [2], [2], 0.5, [1], 0.01, "estimate", "estimate"),
        "spectrum": lambda: _oesweep.spectrum(u, y, 0.01, "robust"),
        "read": lambda: _oesweep.read(json.dumps({"path": a["csv"]})),
        "read_inputs": lambda: _oesweep.read_inputs(json.dumps({"path": a["csv"], "u": ["u"]})),
        "run": lambda: _oesweep.run(a["job"], None, 1, False, True),
        "report": lambda: _oesweep.report(a["folder"]),
        "export": lambda: _oesweep.export(a["folder"], "m2"),
        "write_model": lambda: _oesweep.write_model(a["doc"], "matlab"),
        "to_continuous": lambda: _oesweep.to_continuous(a["doc"], "tustin"),
        "cli": lambda: _oesweep.cli(["oesweep", "spectrum", "--data", a["csv"], "--ts", "0.01", "--json"]),
    }
    sys.setswitchinterval(1e4)
    seen = {}
    for name, call in calls.items():
        counts = {"entered": 0, "left": 0, "seen": None}

        def loop():
            while counts["seen"] is None:
                counts["entered"] += 1
                call()
                counts["left"] += 1

        t = threading.Thread(target=loop)
        t.start()  # waits for the thread to start, letting the GIL go: the loop holds it then
        counts["seen"] = (counts["entered"], counts["left"])
        t.join()
        seen[name] = counts["seen"]
        print(name, file=sys.stderr, flush=True)
    print(json.dumps(seen))
    """
)


def test_every_native_call_lets_a_python_thread_run_while_it_works(tmp_path):
    u, y = record(600)
    job = job_for(tmp_path, u, y, "gil")
    (tmp_path / "job.json").write_text(json.dumps(job))
    done = oesweep.sweep(job, progress=False)
    args = {
        "u": list(u), "y": list(y), "csv": str(tmp_path / "d.csv"), "job": str(tmp_path / "job.json"),
        "folder": str(done.folder), "doc": done.pick("m2").export(to="json"),
    }
    try:
        o = subprocess.run([sys.executable, "-c", GIL_CHILD, json.dumps(args)], capture_output=True, text=True,
                           timeout=300, cwd=tmp_path)
    except subprocess.TimeoutExpired as e:
        passed = (e.stderr or b"").decode().split()
        pytest.fail(f"a native call held the GIL: the main thread never ran during it (passed: {passed})")
    assert o.returncode == 0, o.stderr
    seen = json.loads(o.stdout.splitlines()[-1])
    natives = {n for n in dir(_oesweep) if callable(getattr(_oesweep, n)) and not isinstance(getattr(_oesweep, n), type)}
    assert set(seen) == natives, "a native call the test does not make"
    for name, (entered, left) in seen.items():
        assert entered == left + 1, name


def interrupting(after=1):
    """A progress callback that sends this process a real SIGINT once `after` cells are
    reported: `signal.raise_signal` delivers it to this thread before it returns, and Python's
    own handler raises KeyboardInterrupt there, in the middle of the run: its workers cannot
    finish more than 32 cells past a report the callback has not seen, and then the cells in
    flight."""
    calls = []

    def callback(done, total):
        calls.append((done, total))
        if done >= after:
            signal.raise_signal(signal.SIGINT)

    callback.calls = calls
    return callback


def big_job(tmp_path, out):
    u, y = record(1000)
    job = job_for(tmp_path, u, y, out)
    # 200 cells: far more than the first report and the cells that may finish after it.
    job["grid"] = {"nb": [1, 5], "nf": [1, 5], "k": {"from": 0.1, "to": 2.0, "count": 8, "spacing": "log"}}
    return job


def huber_rows_saved(out):
    parts = sorted((out / "parts").glob("*.parquet"))
    return sum(pl.read_parquet(p).filter(pl.col("k").is_not_null()).height for p in parts)


def test_ctrl_c_mid_sweep_raises_keyboard_interrupt_keeps_the_checkpoint_and_the_same_call_resumes(tmp_path):
    job = big_job(tmp_path, "interrupted")
    ctrl_c = interrupting()
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt, match=r"^interrupted: (\d+) of (\d+) cells finished") as e:
        oesweep.sweep(job, progress=ctrl_c, threads=1)
    finished, total = map(int, re.match(r"interrupted: (\d+) of (\d+)", str(e.value)).groups())
    # Stopped mid-run, after the one report: the finished cells are in the checkpoint, and no
    # result file is written.
    assert ctrl_c.calls[-1][0] >= 1 and all(d < 1 for d, _ in ctrl_c.calls[:-1])
    assert 0 < finished < total == 200
    out = tmp_path / "interrupted"
    assert huber_rows_saved(out) == finished
    assert not (out / "cells.parquet").exists() and not (out / "selection.json").exists()
    seen = []
    resumed = oesweep.sweep(job, progress=lambda d, t: seen.append((d, t)), threads=2)
    whole = oesweep.sweep(job, output=tmp_path / "whole", progress=False)
    assert resumed.cells.drop("seconds").equals(whole.cells.drop("seconds"))
    assert resumed.selection == whole.selection
    # The progress callback ends on every cell done, after a Ctrl-C as without one.
    assert seen[-1] == (total, total)
    # Python's SIGINT handling is Python's again: a Ctrl-C after the sweep is a plain
    # KeyboardInterrupt, not an exit of the process.
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt):
        signal.raise_signal(signal.SIGINT)


def test_ctrl_c_stops_the_command_resumably(tmp_path):
    """The wheel's `oesweep run` after Ctrl-C: exit 130, the checkpoint kept and the same
    command resumes. The signal comes while the command reads its job file, a named pipe: the
    command arms its handler before, and the sweep starts only once the job is read, so it
    starts stopped. The checkpoint holds the cells of a sweep interrupted in Python before."""
    job = big_job(tmp_path, "stopped")
    job_file = tmp_path / "job.json"
    job_file.write_text(json.dumps(job))
    with pytest.raises(KeyboardInterrupt, match=r"^interrupted: (\d+) of 200"):
        oesweep.sweep(job_file, progress=interrupting(), threads=1)
    before = huber_rows_saved(tmp_path / "stopped")
    assert 0 < before < 200
    job_file.unlink()
    os.mkfifo(job_file)
    args = [BIN, "run", str(job_file), "--threads", "1"]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    with open(job_file, "w") as fh:  # returns once the command opened it
        p.send_signal(signal.SIGINT)
        fh.write(json.dumps(job))
    out, err = p.communicate()
    assert p.returncode == 130, err
    assert f"interrupted: {before} of 200 cells finished (0 in this run)" in err, err
    assert f"to resume, run `oesweep run {job_file}`" in err and "Traceback" not in err
    assert not (tmp_path / "stopped" / "cells.parquet").exists()
    assert huber_rows_saved(tmp_path / "stopped") == before
    job_file.unlink()
    job_file.write_text(json.dumps(job))
    o = subprocess.run(args + ["--quiet"], capture_output=True, text=True)
    assert o.returncode == 0, o.stderr
    whole = oesweep.sweep(job, output=tmp_path / "whole", progress=False)
    assert oesweep.load(tmp_path / "stopped").cells.drop("seconds").equals(whole.cells.drop("seconds"))


def test_the_in_process_command_leaves_the_sigint_handler_as_it_found_it(tmp_path, monkeypatch, capfd):
    """`oesweep._cli.main` sets the binary's dispositions for the command only: afterwards the
    caller's handler is in place, in Python's record and in the process (a SIGINT reaches it)."""
    u, y = record(600)
    job = job_for(tmp_path, u, y, "cli")
    (tmp_path / "job.json").write_text(json.dumps(job))
    heard = []

    def mine(signum, frame):
        heard.append(signum)

    previous = signal.signal(signal.SIGINT, mine)
    try:
        for argv, code in (
            (["oesweep", "run", str(tmp_path / "job.json"), "--quiet"], 0),
            (["oesweep", "fit", "--data", str(tmp_path / "missing.csv"), "--nb", "2", "--nf", "2", "--k", "1"], 2),
        ):
            monkeypatch.setattr(sys, "argv", argv)
            assert _cli.main() == code, capfd.readouterr().err
            assert signal.getsignal(signal.SIGINT) is mine
            signal.raise_signal(signal.SIGINT)
            assert heard == [signal.SIGINT]
            heard.clear()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert "missing.csv" in capfd.readouterr().err
