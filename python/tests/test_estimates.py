"""The package's numbers against references it did not make: the system that made the data,
numbers frozen from the cargo-built binary, and the same record in another memory layout."""

import json
import subprocess
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import oesweep
from freeze_reference import frozen_selection
from support import REPO, TRUE_B, TRUE_F, TRUE_OFFSET, cargo_bin, record, without_seconds

REFERENCE = Path(__file__).with_name("reference.json")


def theta(m):
    return np.array(list(m.b) + list(m.f) + [m.offset])


def std(m):
    return np.array(list(m.b_std) + list(m.f_std) + [m.offset_std])


def error(m):
    """The estimate less the system that made the data. The model takes the input's level out
    (`u - input_level`), so its offset is the system's plus the static gain times that level."""
    gain = sum(TRUE_B) / (1.0 + sum(TRUE_F))
    return theta(m) - np.array(TRUE_B + TRUE_F + [TRUE_OFFSET + gain * m.input_level])


def test_an_estimate_holds_the_true_system_within_its_reported_std():
    # Noise, and 5 % outliers of either sign that least squares would follow.
    u, y = record(3000, seed=11, noise=0.1, spikes=0.05, symmetric=True)
    m = oesweep.fit(u, y, 2, 2, 1.0, ts=0.01)
    assert m.parameters == ["b1", "b2", "f1", "f2", "offset"]
    assert m.input_level == pytest.approx(u.mean(), rel=1e-12)
    z = error(m) / std(m)
    assert np.all(np.abs(z) <= 4.0), dict(zip(m.parameters, z))


def test_the_reported_std_is_the_spread_of_the_estimates_over_noise_realisations():
    """Not only covering the truth (an absurdly large std would): over 40 records of the same
    system the estimates scatter as much as each fit says they do."""
    fits = [oesweep.fit(*record(1500, seed=100 + s, noise=0.1, spikes=0.05, symmetric=True), 2, 2, 1.0)
            for s in range(40)]
    errors = np.array([error(m) for m in fits])
    reported = np.median([std(m) for m in fits], axis=0)
    spread = errors.std(axis=0, ddof=1)
    ratio = spread / reported
    assert np.all((ratio > 0.7) & (ratio < 1.4)), dict(zip(fits[0].parameters, ratio))
    # And centred on the truth: the mean's own std is spread / sqrt(40).
    bias = errors.mean(axis=0) / (spread / np.sqrt(len(fits)))
    assert np.all(np.abs(bias) <= 4.0), dict(zip(fits[0].parameters, bias))


def test_arrays_of_any_layout_and_type_give_the_float64_contiguous_result():
    u, y = record()
    # Values that float32 and the integers hold exactly, so every form is the same record.
    y = y.astype(np.float32).astype(np.float64)
    want = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01).to_dict()
    want.pop("seconds", None)

    def same(uu, yy):
        got = oesweep.fit(uu, yy, 2, 2, 0.5, ts=0.01).to_dict()
        got.pop("seconds", None)
        assert got == want

    strided = np.repeat(y, 2)[::2]
    reversed_view = y[::-1].copy()[::-1]
    column = np.ascontiguousarray(np.c_[u, y])[:, 1]
    for a in (strided, reversed_view, column):
        assert not a.flags.c_contiguous and a.dtype == np.float64
        np.testing.assert_array_equal(a, y)
        same(u, a)
    y32 = y.astype(np.float32)
    assert y32.dtype == np.float32 and y32[::3].dtype == np.float32
    same(u, y32)
    same(u, y32[::-1].copy()[::-1])
    for dtype in (np.int8, np.int64):
        ui = u.astype(dtype)
        assert ui.dtype == dtype and np.issubdtype(ui.dtype, np.integer)
        same(ui, y)
    same(list(u), pl.Series(y))
    # The validation record and the spectrum take the same conversion.
    want_val = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01, validation=(u, y)).fit_val
    got_val = oesweep.fit(u, y, 2, 2, 0.5, ts=0.01, validation=(u.astype(np.int16), strided)).fit_val
    assert got_val == want_val
    np.testing.assert_array_equal(
        oesweep.spectrum(u.astype(np.int32), y32, 0.01)["re"], oesweep.spectrum(u, y, 0.01)["re"]
    )


# Numbers of the cargo-built binary, frozen in reference.json by freeze_reference.py.


def close(got, want, path="", rtol=1e-9):
    """`got` equals the frozen `want`: floats within `rtol` (a CPU of another kernel flavour
    rounds otherwise), everything else exactly."""
    if isinstance(want, dict):
        assert isinstance(got, dict) and sorted(got) == sorted(want), (path, sorted(got), sorted(want))
        for key in want:
            close(got[key], want[key], f"{path}.{key}", rtol)
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), (path, got, want)
        for i, (g, w) in enumerate(zip(got, want)):
            close(g, w, f"{path}[{i}]", rtol)
    elif isinstance(want, float) and not isinstance(got, bool):
        assert isinstance(got, (int, float)) and got == pytest.approx(want, rel=rtol, abs=1e-300), (path, got, want)
    else:
        assert got == want, (path, got, want)


def reference():
    return json.loads(REFERENCE.read_text())


def fit_from_python(entry):
    """The entry's fit by the package: its record read as the command line reads it."""
    p = entry["python"]
    u, y = oesweep.read(REPO / p["data"]["path"], **{k: v for k, v in p["data"].items() if k != "path"})
    val = None
    if "validation" in p:
        val = oesweep.read(REPO / p["validation"]["path"], **{k: v for k, v in p["validation"].items() if k != "path"})
    return oesweep.fit(u, y, p["nb"], p["nf"], p["k"], delay=p["delay"], ts=p["ts"], validation=val)


FROZEN_FIT_KEYS = ("b", "f", "offset", "b_std", "f_std", "offset_std", "criterion", "gamma", "sigma", "fit",
                   "fit_val", "covariance", "parameters", "termination", "raic", "rbic")


@pytest.mark.parametrize("name", [e["name"] for e in json.loads(REFERENCE.read_text())["fits"]])
def test_fit_gives_the_numbers_frozen_from_the_cargo_binary(name):
    entry = next(e for e in reference()["fits"] if e["name"] == name)
    got = fit_from_python(entry).to_dict()
    for key in FROZEN_FIT_KEYS:
        close(got[key], entry["report"][key], key)
    close(got["least_squares"]["b"], entry["report"]["ls"]["b"], "ls.b")


def test_sweep_gives_the_picks_frozen_from_the_cargo_binary(tmp_path):
    ref = reference()["sweep"]
    job = json.loads(json.dumps(ref["job"]).replace("REPO/", f"{REPO}/"))
    s = oesweep.sweep({**job, "output": str(tmp_path / "out")}, progress=False)
    close(frozen_selection(s.selection), ref["selection"], "selection")


def test_the_frozen_numbers_are_what_the_cargo_binary_gives_now(tmp_path):
    """reference.json is what the cargo-built binary of this checkout prints (under CI this
    runs): a change of the engine's numbers is a change of the fixture too."""
    binary = cargo_bin()
    ref = reference()
    for entry in ref["fits"]:
        o = subprocess.run([binary, *entry["args"]], capture_output=True, text=True, cwd=REPO)
        assert o.returncode == 0, o.stderr
        close(without_seconds(o.stdout), entry["report"], entry["name"])
    job = json.loads(json.dumps(ref["sweep"]["job"]).replace("REPO/", f"{REPO}/"))
    (tmp_path / "job.json").write_text(json.dumps({**job, "output": str(tmp_path / "out")}))
    o = subprocess.run([binary, "run", str(tmp_path / "job.json"), "--quiet"], capture_output=True, text=True)
    assert o.returncode == 0, o.stderr
    selection = json.loads((tmp_path / "out" / "selection.json").read_text())
    close(frozen_selection(selection), ref["sweep"]["selection"], "selection")
