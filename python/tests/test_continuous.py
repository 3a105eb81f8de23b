"""The continuous-time equivalent at a high order and a short sample time (docs/METHOD.md 18):
python-control's ``sample_system`` of the exported state space gives the model back, and the
zeros, poles and gain are the same transfer function."""

import numpy as np
import pytest
import scipy.signal

import oesweep

TS = 1e-4


def pair(hz, zeta):
    w = 2 * np.pi * hz
    return [complex(-zeta * w, w * np.sqrt(1 - zeta**2)), complex(-zeta * w, -w * np.sqrt(1 - zeta**2))]


# Four resonances from 150 Hz to 3 kHz, a real pole at 80 Hz, zeros at 400 Hz, 900 Hz and a
# right-half-plane one at 5 kHz: a 9th-order system, unit DC gain.
POLES = np.array(pair(150, 0.02) + pair(600, 0.05) + pair(1500, 0.03) + pair(3000, 0.1) + [-2 * np.pi * 80])
ZEROS = np.array(pair(400, 0.1) + [-2 * np.pi * 900, 2 * np.pi * 5000])
GAIN = float(np.real(np.prod(-POLES) / np.prod(-ZEROS)))


def sampled_model():
    """The ZOH sampling of the system above as an OE(9,9) model with delay 1, through its
    partial fractions: r/(s - p) samples to r (e^(p Ts) - 1)/p / (z - e^(p Ts))."""
    residues = np.array([GAIN * np.prod(p - ZEROS) / np.prod([p - q for q in POLES if q != p]) for p in POLES])
    discrete = np.exp(POLES * TS)
    weights = residues * (discrete - 1) / POLES
    den = np.real(np.poly(discrete))
    num = sum(w * np.poly([d for d in discrete if d != e]) for w, e in zip(weights, discrete))
    return oesweep.Model({"b": [float(v) for v in np.real(num)], "f": [float(v) for v in den[1:]],
                          "delay": 1, "ts": TS, "input_level": 0.0})


def test_a_ninth_order_model_at_a_short_sample_time_samples_back_through_the_state_space():
    control = pytest.importorskip("control")
    m = sampled_model()
    freq = np.linspace(10.0, 4500.0, 60)  # up to 0.9 of Nyquist
    z = np.exp(2j * np.pi * freq * TS)
    want = m.frequency_response(freq)
    c = m.to_continuous("zoh")
    assert (len(c.poles), c.delay_samples, c.state_space[0].shape) == (9, 0, (9, 9))
    # The poles are the system's own, each to 1e-8.
    for p in POLES:
        assert np.min(np.abs(c.poles - p)) <= 1e-8 * abs(p), (p, c.poles)
    # python-control's ZOH sampling of the state space is the model.
    gd = control.sample_system(c.to_control("ss"), TS, method="zoh")
    np.testing.assert_allclose(gd(z), want, rtol=1e-8)
    # Tustin's state space, sampled back by Tustin.
    t = m.to_continuous("tustin")
    np.testing.assert_allclose(control.sample_system(t.to_control("ss"), TS, method="tustin")(z), want, rtol=1e-8)
    # The zeros, poles and gain are the same transfer function as the state space, and as the
    # continuous system the model was sampled from, on the imaginary axis.
    s = 2j * np.pi * freq
    zpk = c.gain * np.prod([s - q for q in c.zeros], axis=0) / np.prod([s - p for p in c.poles], axis=0)
    np.testing.assert_allclose(c.to_control("ss")(s), zpk, rtol=1e-10)
    _, h = scipy.signal.freqresp(c.to_scipy("zpk"), w=2 * np.pi * freq)
    np.testing.assert_allclose(h, zpk, rtol=1e-10)
    system = GAIN * np.prod([s - q for q in ZEROS], axis=0) / np.prod([s - p for p in POLES], axis=0)
    np.testing.assert_allclose(zpk, system, rtol=1e-8)
    # The same system through `num`, `den` (`to_control()`, a TransferFunction) is not safe to
    # sample: the coefficients span some 1e32, and python-control 0.10.2's ZOH sampling of it
    # (tf -> companion ss -> expm) is off by 15 times the response (docs/METHOD.md 18).
    assert np.max(np.abs(c.num)) / np.min(np.abs(c.num[c.num != 0])) > 1e20


def test_forms_are_named():
    c = sampled_model().to_continuous("zoh")
    with pytest.raises(ValueError, match="expected tf, zpk or ss"):
        c.to_scipy("sos")
    with pytest.raises(ValueError, match="expected tf or ss"):
        c.to_control("zpk")
    assert c.zeros.dtype == np.complex128 and isinstance(c.gain, float)
