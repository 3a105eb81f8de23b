"""The Python package against its own `oesweep` command (the wheel's console script, or
OESWEEP_BIN: the same native module, so these check the Python layer), that command against the
binary cargo builds from the same checkout (OESWEEP_CARGO_BIN), and the model's forms against
scipy. test_estimates.py holds the numbers to references the package did not make,
test_host.py what the package does to its process."""

import json
import re
import subprocess
import sys
from importlib.metadata import metadata
from pathlib import Path

import numpy as np
import polars as pl
import pytest
import scipy.signal

import oesweep
from support import BIN, cargo_bin, cli, job_for, record, without_seconds, write_csv


def test_fit_equals_the_command_line_bit_for_bit(tmp_path):
    u, y = record()
    write_csv(tmp_path / "d.csv", u, y)
    o = cli("fit", "--data", str(tmp_path / "d.csv"), "--nb", "2", "--nf", "2", "--k", "0.5", "--ts", "0.01", "--json")
    assert o.returncode == 0, o.stderr
    want = json.loads(o.stdout)
    m = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01)
    got = m.to_dict()
    for key in ("b", "f", "offset", "criterion", "gamma", "l1c", "fit", "iterations", "termination", "b_std", "f_std",
                "resid_white_p", "resid_indep_p", "raic", "rbic", "sigma", "input_level"):
        assert got[key] == want[key], key
    assert got["least_squares"]["b"] == want["ls"]["b"]
    assert "OE(2, 2)" in repr(m)


def test_the_model_simulates_and_responds_like_scipy(tmp_path):
    u, y = record()
    m = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01)
    sys = m.to_scipy()
    ys = scipy.signal.dlsim(sys, u - m.input_level)[1]
    np.testing.assert_allclose(ys[:, 0] + m.offset, m.simulate(u), rtol=0, atol=1e-10)
    freq = np.linspace(0.1, 40.0, 17)
    _, h = scipy.signal.dfreqresp(sys, w=2 * np.pi * freq * 0.01)
    np.testing.assert_allclose(h, m.frequency_response(freq), rtol=1e-10, atol=1e-12)
    # A JSON round trip keeps every field.
    assert oesweep.Model(json.loads(json.dumps(m.to_dict()))).to_dict() == m.to_dict()
    try:
        import control
    except ImportError:
        with pytest.raises(ImportError, match="python-control"):
            m.to_control()
    else:
        g = m.to_control()
        assert g.dt == 0.01
        np.testing.assert_allclose(g(np.exp(2j * np.pi * freq * 0.01)), m.frequency_response(freq), rtol=1e-9)


def test_sweep_gives_the_table_and_picks_of_oesweep_run_and_load_reads_it(tmp_path):
    u, y = record()
    job = job_for(tmp_path, u, y, "cli")
    (tmp_path / "job.json").write_text(json.dumps(job))
    o = cli("run", str(tmp_path / "job.json"), "--quiet")
    assert o.returncode == 0, o.stderr
    s = oesweep.sweep(job, output=tmp_path / "py", progress=False)
    cli_run = oesweep.load(tmp_path / "cli")
    drop = ["seconds"]
    assert s.cells.drop(drop).equals(cli_run.cells.drop(drop))
    sel = lambda d: json.loads((tmp_path / d / "selection.json").read_text())  # noqa: E731
    assert sel("py") == sel("cli")
    assert s.m2.b == cli_run.selection["m2"]["b"]
    assert len(s.m2.covariance) == len(s.m2.parameters)
    assert s.pick("rbic").b == cli_run.selection["picks"]["rbic"]["model"]["b"]
    assert s.report().name == "report.html"
    # Elsewhere: the page with its figures beside it and its table links into the run.
    page = s.report(tmp_path / "review" / "orders.html")
    html = page.read_text()
    figures = re.findall(r'src="(report-[^"]+\.svg)"', html)
    assert figures and all((page.parent / f).is_file() for f in figures)
    assert (tmp_path / "py" / "cells.parquet").resolve().as_uri() in html


def test_load_reads_a_run_merged_from_shards(tmp_path):
    u, y = record()
    job = job_for(tmp_path, u, y, "sharded")
    (tmp_path / "job.json").write_text(json.dumps(job))
    for shard in ("0/2", "1/2"):
        o = cli("run", str(tmp_path / "job.json"), "--quiet", "--shard", shard)
        assert o.returncode == 0, o.stderr
    o = cli("merge", str(tmp_path / "sharded"))
    assert o.returncode == 0, o.stderr
    merged = oesweep.load(tmp_path / "sharded")
    single = oesweep.sweep(job, output=tmp_path / "single", progress=False)
    assert merged.cells.drop("seconds").equals(single.cells.drop("seconds"))
    assert merged.m2.b == single.m2.b and merged.selection["picks"] == single.selection["picks"]


def test_bad_inputs_raise_the_typed_errors_and_write_nothing(tmp_path):
    u, y = record()
    # NaN is a missing sample (METHOD.md 21); an infinite one is refused.
    y_inf = y.copy()
    y_inf[7] = np.inf
    with pytest.raises(oesweep.DataError, match="sample 7 of y is inf"):
        oesweep.fit(u, y_inf, 2, 2, 0.5)
    with pytest.raises(oesweep.DataError, match="must be equal"):
        oesweep.fit(u, y[:-1], 2, 2, 0.5)
    # A 2-D array is one input per column: the same column twice cannot be told apart.
    with pytest.raises(oesweep.DataError, match="perfectly collinear"):
        oesweep.fit(np.c_[u, u], y, 2, 2, 0.5)
    with pytest.raises(oesweep.DataError, match="1-D"):
        oesweep.fit(np.zeros((len(u), 2, 2)), y, 2, 2, 0.5)
    with pytest.raises(oesweep.JobError, match="offset"):
        oesweep.fit(u, y, 2, 2, 0.5, offset="bogus")
    assert issubclass(oesweep.JobError, ValueError) and issubclass(oesweep.DataError, ValueError)
    job = job_for(tmp_path, u, y)
    job["grdi"] = {}
    with pytest.raises(oesweep.JobError, match="grdi"):
        oesweep.sweep(job, progress=False)
    assert not (tmp_path / "out").exists()


def test_the_readme_quick_start_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    src = Path(__file__).parent.parent / "examples" / "quickstart.py"
    exec(compile(src.read_text(), str(src), "exec"), {"__name__": "__main__"})
    assert (tmp_path / "qs-out" / "cells.parquet").is_file()


def test_progress_in_a_notebook_is_one_updating_line(tmp_path, monkeypatch, capsys):
    u, y = record()
    job = job_for(tmp_path, u, y)
    monkeypatch.setattr(oesweep, "_on_terminal", lambda: False)
    s = oesweep.sweep(job)
    err = capsys.readouterr().err
    total = s.cells.filter(pl.col("k").is_not_null()).height
    assert err.startswith("\r") and err.endswith("\n") and "\n" not in err[:-1]
    assert f"{total}/{total} cells" in err.split("\r")[-1]
    oesweep.sweep(job, progress=False, force=True)
    assert capsys.readouterr().err == ""


def test_spectrum_equals_the_command_line(tmp_path):
    u, y = record(4096)
    write_csv(tmp_path / "d.csv", u, y)
    for method in ("robust", "welch"):
        o = cli("spectrum", "--data", str(tmp_path / "d.csv"), "--ts", "0.01", "--method", method, "--json")
        assert o.returncode == 0, o.stderr
        want = json.loads(o.stdout)
        got = oesweep.spectrum(pl.Series(u), y, 0.01, method=method)
        for key in ("freq_hz", "re", "im", "coherence", "mag_lower", "mag_upper"):
            assert got[key].to_list() == want[key], (method, key)
        np.testing.assert_allclose(got["magnitude"], np.hypot(want["re"], want["im"]))
    with pytest.raises(oesweep.JobError, match="method"):
        oesweep.spectrum(u, y, 0.01, method="periodogram")
    with pytest.raises(oesweep.JobError, match="ts"):
        oesweep.spectrum(u, y, -1.0)


def test_a_job_file_with_several_experiments_runs_from_python_as_from_the_cli(tmp_path):
    # Two experiments (different records of the same system), by paths relative to the job
    # file, run from another directory: the table of `oesweep run`, and each experiment's fit.
    (tmp_path / "jobs").mkdir()
    for i, seed in enumerate((3, 4)):
        write_csv(tmp_path / "jobs" / f"e{i}.csv", *record(800, seed=seed))
    job = {
        "name": "two",
        "data": [{"path": "e0.csv", "u": "u", "y": "y", "ts": 0.01}, {"path": "e1.csv"}],
        "grid": {"nb": [1, 2], "nf": [1, 2], "k": [1.0]},
        "output": "two-cli",
    }
    (tmp_path / "jobs" / "job.json").write_text(json.dumps(job))
    o = cli("run", str(tmp_path / "jobs" / "job.json"), "--quiet")
    assert o.returncode == 0, o.stderr
    s = oesweep.sweep(tmp_path / "jobs" / "job.json", output=tmp_path / "two-py", progress=False)
    want = oesweep.load(tmp_path / "jobs" / "two-cli")
    assert s.cells.drop("seconds").equals(want.cells.drop("seconds"))
    assert all(len(f) == 2 for f in s.cells["fit_exp"].to_list())
    assert s.m2.b == want.selection["m2"]["b"]


def test_models_leave_as_the_command_line_exports_them_and_the_mat_file_reads_back(tmp_path):
    import scipy.io

    u, y = record()
    job = job_for(tmp_path, u, y, "exp")
    s = oesweep.sweep(job, progress=False)
    out = tmp_path / "exp"
    for pick in ("m2", "rbic"):
        m = s.pick(pick)
        o = cli("export", str(out), "--pick", pick, "--to", "json")
        assert o.returncode == 0, o.stderr
        assert m.export(to="json") == o.stdout
        o = cli("export", str(out), "--pick", pick, "--to", "matlab")
        assert m.export(to="matlab") == o.stdout
        # The continuous equivalent: the same numbers, or the same refusal.
        for method in ("zoh", "tustin"):
            o = cli("export", str(out), "--pick", pick, "--to", "json", "--continuous", method)
            try:
                c = m.to_continuous(method)
            except ValueError as e:
                assert o.returncode == 2 and str(e) in o.stderr, o.stderr
            else:
                assert o.returncode == 0, o.stderr
                doc = json.loads(o.stdout)["continuous"]
                assert (doc["num"], doc["den"], doc["input_delay"]) == (list(c.num), list(c.den), c.input_delay)
        o = cli("export", str(out), "--pick", pick, "--to", "mat", "--out", str(tmp_path / f"{pick}.mat"))
        assert o.returncode == 0, o.stderr
        m.export(tmp_path / f"{pick}-py.mat", to="mat")
        doc = json.loads(m.export(to="json"))
        cov = np.array(doc["covariance"])
        for f in (f"{pick}.mat", f"{pick}-py.mat"):
            mat = scipy.io.loadmat(tmp_path / f)
            np.testing.assert_array_equal(mat["B"].ravel(), [0.0] * doc["delay"] + doc["b"])
            np.testing.assert_array_equal(mat["F"].ravel(), [1.0] + doc["f"])
            np.testing.assert_array_equal(mat["covariance"], cov)
            assert mat["Ts"].item() == doc["dt"]
    # A model from `fit` carries its covariance and leaves the same way.
    m = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01)
    assert m.parameters == ["b1", "b2", "f1", "f2", "offset"]
    assert np.allclose(np.sqrt(np.diag(m.covariance))[:4], list(m.b_std) + list(m.f_std), rtol=1e-6)
    doc = json.loads(m.export(to="json"))
    assert doc["b"] == m.b and doc["dt"] == 0.01 and len(doc["covariance"]) == 5
    m.export(tmp_path / "fit.mat", to="mat")
    np.testing.assert_array_equal(scipy.io.loadmat(tmp_path / "fit.mat")["covariance"], np.array(m.covariance))
    with pytest.raises(oesweep.JobError, match="path"):
        m.export(to="mat")
    with pytest.raises(oesweep.JobError, match="expected json, matlab or mat"):
        m.export(to="csv")


def lightly_damped(delay=3, ts=1e-3):
    """An OE(4,4) model with two lightly damped modes (poles at radius 0.99 and 0.95)."""
    poles = [0.99 * np.exp(0.3j), 0.99 * np.exp(-0.3j), 0.95 * np.exp(1.1j), 0.95 * np.exp(-1.1j)]
    f = [float(v) for v in np.real(np.poly(poles))[1:]]
    return oesweep.Model({"b": [0.02, -0.011, 0.004, 0.007], "f": f, "delay": delay, "ts": ts, "input_level": 0.0})


def test_continuous_equivalents_sample_back_to_the_model_in_python_control():
    control = pytest.importorskip("control")
    m = lightly_damped()
    freq = np.linspace(1.0, 450.0, 31)  # up to 0.9 of Nyquist
    z = np.exp(2j * np.pi * freq * m.ts)
    for method in ("zoh", "tustin"):
        c = m.to_continuous(method)
        # Delay 3: two samples of dead time and the hold's one.
        assert (c.method, c.delay_samples, c.den[0], len(c.den)) == (method, 2, 1.0, 5)
        assert c.input_delay == pytest.approx(2e-3, rel=1e-15)
        gd = control.sample_system(c.to_control(), m.ts, method=method)
        np.testing.assert_allclose(gd(z) * z ** -c.delay_samples, m.frequency_response(freq), rtol=1e-8)
        # scipy's continuous system is the same transfer function.
        _, h = scipy.signal.freqresp(c.to_scipy(), w=2 * np.pi * freq)
        np.testing.assert_allclose(h, c.to_control()(2j * np.pi * freq), rtol=1e-12)
    assert "zoh" in repr(m.to_continuous())


def test_the_zoh_equivalent_is_scipys_matrix_logarithm():
    """The engine's logarithm (inverse scaling and squaring) against scipy.linalg.logm of
    [[A, B], [0, 1]] for the model without its dead time, compared on the imaginary axis."""
    import scipy.linalg

    m = lightly_damped()
    num, den = m.num_den
    # z^2 G: the two samples of dead time off.
    h_num, h_den = np.trim_zeros(num, "f"), den[: len(den) - 2]
    a, b, cc, d = scipy.signal.tf2ss(h_num, h_den)
    n = a.shape[0]
    block = np.block([[a, b], [np.zeros((1, n)), np.ones((1, 1))]])
    log = np.real(scipy.linalg.logm(block)) / m.ts
    want = scipy.signal.ss2tf(log[:n, :n], log[:n, n:], cc, d)
    c = m.to_continuous("zoh")
    s = 2j * np.pi * np.linspace(1.0, 450.0, 31)
    np.testing.assert_allclose(
        np.polyval(c.num, s) / np.polyval(c.den, s), np.polyval(want[0][0], s) / np.polyval(want[1], s), rtol=1e-8
    )


def test_a_method_whose_package_is_missing_names_the_extra_that_brings_it(monkeypatch):
    m = lightly_damped()
    c = m.to_continuous("tustin")
    extras = metadata("oesweep").get_all("Provides-Extra")
    assert "scipy" in extras and "control" in extras
    # None in sys.modules: the import raises ImportError, as without the package.
    for name in ("scipy", "scipy.signal"):
        monkeypatch.setitem(sys.modules, name, None)
    for call in (lambda: m.simulate([1.0, 0.0]), m.to_scipy, c.to_scipy):
        with pytest.raises(ImportError, match=r"pip install 'oesweep\[scipy\]'"):
            call()
    monkeypatch.setitem(sys.modules, "control", None)
    for call in (m.to_control, c.to_control):
        with pytest.raises(ImportError, match=r"python-control package: pip install 'oesweep\[control\]'"):
            call()


def test_models_without_a_continuous_equivalent_say_which_pole():
    m = oesweep.Model({"b": [1.0], "f": [0.5], "delay": 1, "ts": 0.1})
    with pytest.raises(ValueError, match=r"z = -0\.5.*negative real axis"):
        m.to_continuous("zoh")
    assert m.to_continuous("tustin").den[-1] > 0  # Tustin maps it
    with pytest.raises(ValueError, match="s = infinity"):
        oesweep.Model({"b": [1.0], "f": [1.0], "delay": 1, "ts": 0.1}).to_continuous("tustin")
    with pytest.raises(ValueError, match="origin"):
        oesweep.Model({"b": [1.0, 0.5], "f": [0.0], "delay": 1, "ts": 0.1}).to_continuous("zoh")
    with pytest.raises(oesweep.JobError, match="expected zoh or tustin"):
        m.to_continuous("foh")


def test_read_takes_a_file_as_a_job_names_a_record(tmp_path):
    u, y = record(1200)
    path = tmp_path / "run.csv"
    with open(path, "w") as fh:  # ;-separated, quoted header, columns in another order
        fh.write('"time";"y out";"u in"\n')
        for i, (a, b) in enumerate(zip(u, y)):
            fh.write(f"{i};{float(b)!r};{float(a)!r}\n")
    ru, ry = oesweep.read(path, u="u in", y=2, rows=[1, 1000])
    np.testing.assert_array_equal(ru, u[:1000])
    np.testing.assert_array_equal(ry, y[:1000])
    m = oesweep.fit(*oesweep.read(path, u=3, y="y out"), 2, 2, 0.5, ts=0.01)
    assert m.b == oesweep.fit(u, y, 2, 2, 0.5, ts=0.01).b
    with pytest.raises(oesweep.JobError, match="rows"):
        oesweep.read(path, u=3, y=2, rows=[5, 1])
    with pytest.raises(oesweep.DataError, match="no such column|column"):
        oesweep.read(path, u="volts", y=2)
    with pytest.raises(oesweep.DataError, match="missing.csv"):
        oesweep.read(tmp_path / "missing.csv")


def test_nan_in_the_arrays_is_a_missing_sample_as_in_a_file(tmp_path):
    # docs/METHOD.md 21.1: a file with an input gap and missing outputs (a marker and empty
    # fields) read with `read` gives every row, NaN where a sample is missing, and `fit` of those
    # arrays is `oesweep fit` of the file, bit for bit.
    u, y = record(1500)
    u[700:703] = np.nan
    y[[40, 41, 900]] = np.nan
    path = tmp_path / "gaps.csv"
    with open(path, "w") as fh:
        fh.write("u,y\n")
        for i, (a, b) in enumerate(zip(u, y)):
            fa = "" if np.isnan(a) else repr(float(a))
            fb = ("NA" if i == 900 else "") if np.isnan(b) else repr(float(b))
            fh.write(f"{fa},{fb}\n")
    ru, ry = oesweep.read(path, missing=["NA"])
    assert len(ru) == 1500 and np.isnan(ru[700:703]).all() and np.isnan(ry[[40, 41, 900]]).all()
    with pytest.raises(oesweep.DataError, match="'NA' is not a number"):
        oesweep.read(path)
    m = oesweep.fit(ru, ry, 2, 2, 0.5, ts=0.01)
    cleaned = tmp_path / "cleaned.csv"
    write_csv(cleaned, u, y)  # NaN written as "nan"
    o = cli("fit", "--data", str(cleaned), "--nb", "2", "--nf", "2", "--k", "0.5", "--ts", "0.01", "--json")
    assert o.returncode == 0, o.stderr
    want = json.loads(o.stdout)
    assert m.b == want["b"] and m.f == want["f"] and m.criterion == want["criterion"]
    with pytest.raises(oesweep.DataError, match="inf"):
        oesweep.fit(np.where(np.isnan(u), np.inf, u), y, 2, 2, 0.5, ts=0.01)


def test_unknown_model_attributes_raise_and_absent_fields_read_as_none():
    u, y = record()
    m = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01)
    with pytest.raises(AttributeError, match="offest"):
        m.offest  # noqa: B018
    assert not hasattr(m, "fit_vall")
    # A model of a source that lacks a field (here without k and covariance) reads it as None.
    ls = oesweep.Model({"b": m.b, "f": m.f, "delay": 1, "ts": 0.01})
    assert ls.k is None and ls.covariance is None and "least squares" in repr(ls)


def test_arrays_cross_the_boundary_only_as_float64_buffers():
    from oesweep import _oesweep

    u, y = record()
    # The native call takes one array per input and one order per input.
    def native(u, y):
        return _oesweep.fit([u], y, [2], [2], 0.5, [1], 0.01, "estimate", "estimate")

    # An address and a length are no array: the engine reads nothing it was not handed.
    with pytest.raises((oesweep.DataError, TypeError)):
        native((u.ctypes.data, u.size), (y.ctypes.data, y.size))
    with pytest.raises(oesweep.DataError, match="u: expected a 1-D float64 array"):
        native(u.astype(np.float32), y)
    with pytest.raises(oesweep.DataError, match="2 dimensions"):
        native(np.c_[u, u], y)
    # Strided views are copied through the buffer protocol as the values they show.
    uu, yy = np.repeat(u, 2), np.repeat(y, 2)
    assert json.loads(native(uu[::2], yy[::2]))["b"] == oesweep.fit(u, y, 2, 2, 0.5, ts=0.01).b


def test_a_dict_job_writes_nothing_but_its_output_folder(tmp_path, monkeypatch):
    u, y = record(600)
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    write_csv(tmp_path / "cwd" / "d.csv", u, y)
    job = {"name": "rel", "data": {"path": "d.csv", "ts": 0.01}, "grid": {"nb": [1, 2], "nf": [1, 2], "k": [1.0]},
           "output": "out"}
    s = oesweep.sweep(job, progress=False)
    assert s.folder.resolve() == (tmp_path / "cwd" / "out").resolve()
    assert sorted(p.name for p in (tmp_path / "cwd").iterdir()) == ["d.csv", "out"]
    # With another output folder, a job file's relative paths stay relative to the job file.
    (tmp_path / "cwd" / "job.json").write_text(json.dumps(job))
    monkeypatch.chdir(tmp_path)
    oesweep.sweep(tmp_path / "cwd" / "job.json", output=tmp_path / "elsewhere", progress=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cwd", "elsewhere"]
    assert sorted(p.name for p in (tmp_path / "cwd").iterdir()) == ["d.csv", "job.json", "out"]
    # A bad dict job is named as such.
    with pytest.raises(oesweep.JobError, match="<job dict>: invalid job"):
        oesweep.sweep({**job, "grdi": {}}, progress=False)


def test_errors_come_by_kind_with_the_command_lines_message(tmp_path):
    import fcntl

    u, y = record(600)
    job = job_for(tmp_path, u, y)
    (tmp_path / "job.json").write_text(json.dumps(job))

    def same_as_cli(exc, *args, code):
        o = cli(*args)
        pid = lambda text: re.sub(r"tmp-\d+", "tmp-PID", text)  # noqa: E731 (a temporary file's name)
        assert o.returncode == code, o.stderr
        assert pid(o.stderr.strip()).endswith(pid(f"error: {exc.value}")), (o.stderr, str(exc.value))

    # A locked output folder: another run holds it (this process, through the lock file).
    (tmp_path / "out").mkdir()
    with open(tmp_path / "out" / ".oesweep.lock", "w") as holder:
        fcntl.flock(holder, fcntl.LOCK_EX)
        with pytest.raises(oesweep.LockError, match="in use by another oesweep run") as e:
            oesweep.sweep(job, progress=False)
        same_as_cli(e, "run", str(tmp_path / "job.json"), "--quiet", code=2)
    assert issubclass(oesweep.LockError, oesweep.OutputError) and issubclass(oesweep.OutputError, OSError)
    # A result file that cannot be written (a folder is in its place): the CLI's exit code 1.
    blocked = {**job, "output": str(tmp_path / "blocked")}
    (tmp_path / "blocked" / "selection.json").mkdir(parents=True)
    (tmp_path / "blocked.json").write_text(json.dumps(blocked))
    with pytest.raises(oesweep.OutputError, match="selection.json") as e:
        oesweep.sweep(blocked, progress=False)
    same_as_cli(e, "run", str(tmp_path / "blocked.json"), "--quiet", code=1)
    # A data file is a data error whatever its name, the job file's own faults a job error.
    bad_data = {**job, "data": {**job["data"], "path": str(tmp_path / "missing.json")}}
    (tmp_path / "bad-data.json").write_text(json.dumps(bad_data))
    with pytest.raises(oesweep.DataError, match="missing.json") as e:
        oesweep.sweep(tmp_path / "bad-data.json", progress=False)
    same_as_cli(e, "run", str(tmp_path / "bad-data.json"), "--quiet", code=2)
    (tmp_path / "bad-job.json").write_text(json.dumps({**job, "grid": {**job["grid"], "k": [-1.0]}}))
    with pytest.raises(oesweep.JobError, match="bad-job.json") as e:
        oesweep.sweep(tmp_path / "bad-job.json", progress=False)
    same_as_cli(e, "run", str(tmp_path / "bad-job.json"), "--quiet", code=2)


def test_the_command_behaves_as_the_binary_cargo_builds(tmp_path):
    cargo = cargo_bin()
    u, y = record()
    write_csv(tmp_path / "d.csv", u, y)
    (tmp_path / "job.json").write_text(json.dumps(job_for(tmp_path, u, y, "run-OUT")))
    runs = {}
    for name, binary in (("wheel", BIN), ("cargo", cargo)):
        def run(*args):
            return subprocess.run([binary, *args], capture_output=True, text=True, cwd=tmp_path)

        runs[name] = [
            run("--help"),
            run("fit", "--nb", "2"),  # a usage error
            run("fit", "--data", "missing.csv", "--nb", "2", "--nf", "2", "--k", "0.5"),
            run("spectrum", "--data", "d.csv", "--ts", "0.01", "--json"),
            run("export", str(tmp_path / "nowhere")),
        ]
        runs[name].append(run("fit", "--data", "d.csv", "--nb", "2", "--nf", "2", "--k", "0.5", "--json"))
        job = (tmp_path / "job.json").read_text().replace("run-OUT", f"run-{name}")
        (tmp_path / f"job-{name}.json").write_text(job)
        runs[name].append(run("run", f"job-{name}.json", "--quiet"))
    codes = [o.returncode for o in runs["wheel"]]
    assert codes == [o.returncode for o in runs["cargo"]] == [0, 2, 2, 0, 2, 0, 0]
    for w, c in zip(runs["wheel"][:-2], runs["cargo"][:-2]):
        assert (w.stdout, w.stderr) == (c.stdout, c.stderr)
    assert without_seconds(runs["wheel"][-2].stdout) == without_seconds(runs["cargo"][-2].stdout)
    wheel_run, cargo_run = oesweep.load(tmp_path / "run-wheel"), oesweep.load(tmp_path / "run-cargo")
    assert wheel_run.cells.drop("seconds").equals(cargo_run.cells.drop("seconds"))
    assert wheel_run.selection == cargo_run.selection
