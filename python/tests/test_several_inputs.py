"""Several inputs through the package: `fit` with a 2-D array or a list of inputs, the model's
per-input fields and methods, `read` of several columns, `spectrum` per input, and the clear
errors (issue 46)."""

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


def test_what_is_not_written_for_several_inputs_says_so():
    u, y = miso_record()
    m = oesweep.fit(u, y, 1, 1, 1.0, delay=[1, 2])
    with pytest.raises(oesweep.JobError, match="2 inputs"):
        m.export()
    with pytest.raises(oesweep.JobError, match="2 inputs"):
        m.to_continuous()


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
        low = frame.filter(frame["freq_hz"] < 0.15)  # below the held inputs' first notch, 0.2
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
