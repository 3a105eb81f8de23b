"""What the package's tests share: records of a known system, the command lines to compare
with, and the checkout's own data."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import scipy.signal

# The wheel's `oesweep` command (its console script: the same native module as the package),
# and the binary cargo builds from the same checkout (tests/python_package.sh sets it).
BIN = os.environ.get("OESWEEP_BIN") or shutil.which("oesweep")
CARGO_BIN = os.environ.get("OESWEEP_CARGO_BIN")
REPO = Path(__file__).resolve().parents[2]

# The system of `record`: y = q^-1 B/F u + offset + noise.
TRUE_B, TRUE_F, TRUE_OFFSET = [0.5, 0.3], [-1.2, 0.6], 0.3


def record(n=1500, seed=3, spikes=0.05, noise=0.05, symmetric=False):
    """An OE(2,2) system (TRUE_B, TRUE_F, delay 1, TRUE_OFFSET) with Gaussian noise and a share
    `spikes` of outliers of size 2 (upwards, or of either sign when `symmetric`), as numpy
    arrays."""
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 1.0], n // 3 + 1), 3)[:n]
    y = scipy.signal.lfilter([0.0] + TRUE_B, [1.0] + TRUE_F, u)
    sign = rng.choice([-1.0, 1.0], n) if symmetric else 1.0
    y = y + noise * rng.standard_normal(n) + np.where(rng.random(n) < spikes, 2.0 * sign, 0.0) + TRUE_OFFSET
    return u, y


def write_csv(path, u, y):
    with open(path, "w") as fh:
        fh.write("u,y\n")
        for a, b in zip(u, y):
            fh.write(f"{float(a)!r},{float(b)!r}\n")


def job_for(tmp_path, u, y, out="out"):
    write_csv(tmp_path / "d.csv", u, y)
    return {
        "name": "py",
        "data": {"path": str(tmp_path / "d.csv"), "u": "u", "y": "y", "ts": 0.01},
        "grid": {"nb": [1, 3], "nf": [1, 3], "k": [0.5, 1.5]},
        "output": str(tmp_path / out),
    }


def cli(*args):
    """The wheel's own `oesweep` command: the package's wrapper, not an independent reference."""
    assert BIN, "set OESWEEP_BIN to the oesweep binary of this checkout"
    return subprocess.run([BIN, *args], capture_output=True, text=True)


def cargo_bin():
    """The cargo-built binary: an independent build of the engine. Without it a test skips,
    except under CI, where that is a failure."""
    if not CARGO_BIN:
        assert os.environ.get("CI") != "true", "OESWEEP_CARGO_BIN is not set"
        pytest.skip("OESWEEP_CARGO_BIN (the cargo-built binary) is not set")
    return CARGO_BIN


def without_seconds(text):
    """A `--json` report without its timing, which is the only field two runs may differ in."""
    doc = json.loads(text)
    doc.pop("seconds", None)
    return doc
