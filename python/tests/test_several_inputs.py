"""Several inputs through the package: `fit` with a 2-D array or a list of inputs, the model's
per-input fields and methods, `read` of several columns, `spectrum` per input, and the clear
errors (issue 46)."""

import json

import json

import numpy as np
import pytest
import scipy.signal

import oesweep
from support import cli

# Per input: b, f, delay (a second-order input and a slow first-order one).
SYSTEM = [([0.5, 0.3], [-1.2, 0.6], 1), ([0.8], [-0.9], 2)]


def miso_record(n=1500, seed=5, noise=0.0):
    rng = np.random.default_rng(seed)
    us = [np.repeat(rng.choice([-1.0, 1.0], n // h + 1), h)[:n] for h in (3, 5)]
    y = sum(scipy.signal.lfilter([0.0] * d + b, [1.0] + f, u) for u, (b, f, d) in zip(us, SYSTEM))
    return np.stack(us, axis=1), y + noise * rng.standard_normal(n)


def test_a_two_input_record_recovers_every_input_s_system():
    u, y = miso_record()
    m = oesweep.fit(u, y, [2, 1], [2, 1], 1.0, delay=[1, 2], offset="none", initial_state="zero")
    assert m.inputs == 2 and m.nb == [2, 1] and m.nf == [2, 1] and m.delay == [1, 2]
    for (b, f, _), got_b, got_f in zip(SYSTEM, m.b, m.f):
        np.testing.assert_allclose(got_b, b, atol=1e-6)
        np.testing.assert_allclose(got_f, f, atol=1e-6)
    assert len(m.b_std) == 2 and [len(s) for s in m.b_std] == [2, 1]
    # The model's own simulation is the record.
    np.testing.assert_allclose(m.simulate(u), y, atol=1e-6)
    assert m.fit > 99.999


def test_a_list_of_inputs_is_the_2d_array_and_one_order_serves_every_input():
    u, y = miso_record(noise=0.05)
    as_array = oesweep.fit(u, y, 2, 2, 1.0, delay=[1, 2])
    as_list = oesweep.fit([u[:, 0], u[:, 1]], y, [2, 2], [2, 2], 1.0, delay=[1, 2])
    assert as_array.nb == [2, 2]
    np.testing.assert_array_equal(np.concatenate(as_array.b), np.concatenate(as_list.b))
    assert as_array.criterion == as_list.criterion


def test_per_input_responses_and_python_control_has_one_input_per_model_input():
    u, y = miso_record()
    m = oesweep.fit(u, y, [2, 1], [2, 1], 1.0, delay=[1, 2], offset="none")
    g = m.frequency_response([0.01, 0.1])
    assert g.shape == (2, 2)
    w = 2 * np.pi * np.array([0.01, 0.1])
    for i, (b, f, d) in enumerate(SYSTEM):
        _, want = scipy.signal.freqz([0.0] * d + b, [1.0] + f, worN=w)
        np.testing.assert_allclose(g[:, i], want, rtol=1e-5)
    assert len(m.to_scipy()) == 2
    control = pytest.importorskip("control")
    sys = m.to_control()
    assert (sys.noutputs, sys.ninputs) == (1, 2)
    assert control is not None


# dlsim warns of the delay's exact leading zeros of num.
@pytest.mark.filterwarnings("ignore:Badly conditioned filter coefficients")
def test_the_export_of_several_inputs_has_one_filter_per_input_that_simulates_the_model():
    u, y = miso_record(noise=0.05)
    m = oesweep.fit(u, y, [2, 1], [2, 1], 1.0, delay=[1, 2], offset="estimate")
    doc = json.loads(m.export())
    assert doc["delay"] == [1, 2] and len(doc["num"]) == 2 and len(doc["input_level"]) == 2
    assert [len(b) for b in doc["b"]] == [2, 1]
    # scipy: each input's transfer function simulated on its input (less its level), summed.
    got = np.full(len(y), float(doc["offset"] or 0.0))
    for i, (num, den) in enumerate(zip(doc["num"], doc["den"])):
        _, yi = scipy.signal.dlsim((num, den, doc["dt"]), u[:, i] - doc["input_level"][i])
        got += yi[:, 0]
    np.testing.assert_allclose(got, m.simulate(u), rtol=1e-9, atol=1e-9)
    # python-control: the document's lists make the 1 x m system.
    control = pytest.importorskip("control")
    sys = control.tf([doc["num"]], [doc["den"]], doc["dt"])
    assert (sys.noutputs, sys.ninputs) == (1, 2)
    np.testing.assert_allclose(sys(np.exp(0.3j))[0], m.frequency_response([0.3 / (2 * np.pi * m.ts)])[0], rtol=1e-9)


def test_the_matlab_script_and_mat_file_of_several_inputs(tmp_path):
    u, y = miso_record()
    m = oesweep.fit(u, y, [2, 1], [2, 1], 1.0, delay=[1, 2], offset="none")
    script = m.export(to="matlab")
    assert "nk = [1, 2];" in script and "b = {[" in script and "G = tf(num, den, Ts); % 1 x 2" in script
    m.export(tmp_path / "m.mat", to="mat")
    assert (tmp_path / "m.mat").stat().st_size > 0


def test_each_input_has_its_own_continuous_equivalent():
    u, y = miso_record()
    m = oesweep.fit(u, y, [2, 1], [2, 1], 1.0, delay=[1, 2], offset="none")
    for method in ("tustin", "zoh"):
        cs = m.to_continuous(method)
        assert isinstance(cs, list) and len(cs) == 2
        for i, c in enumerate(cs):
            assert c.method == method
            if method == "zoh":
                # The dead time: input i's delay less the hold's own sample.
                assert c.delay_samples == SYSTEM[i][2] - 1
            ts = float(m.ts)
            for hz in (0.001, 0.01):
                w = 2 * np.pi * hz * ts
                g = m.frequency_response([hz])[0, i]
                wc = 2 / ts * np.tan(w / 2) if method == "tustin" else w / ts
                gc = np.polyval(c.num, 1j * wc) / np.polyval(c.den, 1j * wc)
                np.testing.assert_allclose(abs(gc), abs(g), rtol=1e-9 if method == "tustin" else 1e-2)


def test_a_several_input_run_picks_and_exports_per_input(tmp_path):
    u, y = miso_record(n=600, noise=0.02)
    path = tmp_path / "d.csv"
    with open(path, "w") as fh:
        fh.write("a,b,y\n")
        for a, b, c in zip(u[:, 0], u[:, 1], y):
            fh.write(f"{float(a)!r},{float(b)!r},{float(c)!r}\n")
    job = {
        "name": "two", "data": {"path": str(path), "u": ["a", "b"], "y": "y", "ts": 1},
        "grid": {"nb": [[1, 2], [1, 1]], "nf": [[1, 2], [1, 1]], "k": [1.0]}, "delay": [1, 2],
        "output": str(tmp_path / "out"),
    }
    run = oesweep.sweep(job, progress=False)
    m = run.pick()
    assert m.inputs == 2 and m.nb == [len(b) for b in m.b] and m.delay == [1, 2]
    np.testing.assert_allclose(m.simulate(u), m.simulate([u[:, 0], u[:, 1]]))
    doc = json.loads(m.export())
    assert doc["b"] == m.b and len(doc["covariance"]) == len(doc["parameters"])
    assert len(m.to_continuous("tustin")) == 2
    page = run.report()
    assert "report-bode-" in page.read_text() and (tmp_path / "out" / "report-heat-u2.svg").exists()


def test_bad_several_input_calls_name_the_fault():
    u, y = miso_record()
    with pytest.raises(oesweep.JobError, match="3 entries for 2 inputs"):
        oesweep.fit(u, y, [1, 1, 1], 1, 1.0)
    with pytest.raises(oesweep.DataError, match="u2|u\\[1\\]"):
        oesweep.fit([u[:, 0], u[:-1, 1]], y, 1, 1, 1.0)
    with pytest.raises(oesweep.DataError, match="collinear"):
        oesweep.fit(np.stack([u[:, 0], 2 * u[:, 0]], axis=1), y, 1, 1, 1.0)


def test_read_gives_several_input_columns_as_one_array(tmp_path):
    u, y = miso_record(n=200)
    path = tmp_path / "r.csv"
    with open(path, "w") as fh:
        fh.write("fuel,fan,temp\n")
        for a, b, c in zip(u[:, 0], u[:, 1], y):
            fh.write(f"{float(a)!r},{float(b)!r},{float(c)!r}\n")
    got_u, got_y = oesweep.read(path, u=["fuel", "fan"], y="temp")
    assert got_u.shape == (200, 2)
    np.testing.assert_array_equal(got_u, u)
    np.testing.assert_array_equal(got_y, y)


def test_spectrum_of_several_inputs_is_one_frame_per_input_as_the_command_line_gives(tmp_path):
    # Noise-free, 8192 samples: each input's estimate lies on its own system's response where
    # the inputs have power, and the numbers are those of `oesweep spectrum --u u1,u2`.
    u, y = miso_record(n=8192, seed=9)
    frames = oesweep.spectrum(u, y, 1.0, method="welch")
    assert isinstance(frames, list) and len(frames) == 2
    assert frames[0]["freq_hz"].to_list() == frames[1]["freq_hz"].to_list()
    assert frames[0]["coherence"].to_list() == frames[1]["coherence"].to_list()
    for frame, (b, f, d) in zip(frames, SYSTEM):
        assert frame.columns == ["freq_hz", "re", "im", "magnitude", "phase_deg", "coherence", "mag_lower", "mag_upper"]
        # Below the held inputs' first notch (0.2 Hz), without the zero-frequency bin, which the
        # segments' window leaks into from the inputs' levels.
        low = frame.filter((frame["freq_hz"] > 0) & (frame["freq_hz"] < 0.15))
        _, want = scipy.signal.freqz([0.0] * d + b, [1.0] + f, worN=2 * np.pi * low["freq_hz"].to_numpy())
        got = low["re"].to_numpy() + 1j * low["im"].to_numpy()
        assert np.all(np.abs(got - want) <= 0.1 * np.abs(want)), np.max(np.abs(got - want) / np.abs(want))
    # A list of inputs is the 2-D array.
    as_list = oesweep.spectrum([u[:, 0], u[:, 1]], y, 1.0, method="welch")
    assert all(a.equals(b) for a, b in zip(frames, as_list))
    # The command line on the same record.
    path = tmp_path / "r.csv"
    with open(path, "w") as fh:
        fh.write("u1,u2,y\n")
        for a, b, c in zip(u[:, 0], u[:, 1], y):
            fh.write(f"{float(a)!r},{float(b)!r},{float(c)!r}\n")
    o = cli("spectrum", "--data", str(path), "--u", "u1,u2", "--ts", "1", "--method", "welch", "--json")
    assert o.returncode == 0, o.stderr
    want = json.loads(o.stdout)
    for i, frame in enumerate(frames):
        for key in ("re", "im", "mag_lower", "mag_upper"):
            assert frame[key].to_list() == want[key][i], (i, key)
        assert frame["coherence"].to_list() == want["coherence"]
    # One column of a 2-D array is one input: one frame, not a list.
    one = oesweep.spectrum(u[:, :1], y, 1.0, method="welch")
    assert one.columns[0] == "freq_hz"
