"""Write reference.json: what the cargo-built `oesweep` binary prints for a few fits and a small
sweep of the checkout's records, for test_estimates.py to hold the package to.

    cargo build --release --bin oesweep
    python3 python/tests/freeze_reference.py "$CARGO_TARGET_DIR/release/oesweep"

Run it when the engine's numbers change on purpose (test_the_frozen_numbers_are_what_the_cargo_
binary_gives_now fails until then), and say so in the commit."""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
OUT = Path(__file__).with_name("reference.json")

# Each fit as the command line and as the package call it (the record read as a job reads it).
FITS = [
    {
        "name": "heater OE(2,2) delay 2 with validation",
        "args": ["fit", "--data", "jobs/data/heater.dat", "--u", "1", "--y", "2", "--rows", "1:1500",
                 "--val-rows", "1501:2000", "--val-y", "2", "--nb", "2", "--nf", "2", "--delay", "2",
                 "--k", "1.0", "--ts", "1", "--json"],
        "python": {"data": {"path": "jobs/data/heater.dat", "u": 1, "y": 2, "rows": [1, 1500]},
                   "validation": {"path": "jobs/data/heater.dat", "u": 1, "y": 2, "rows": [1501, 2000]},
                   "nb": 2, "nf": 2, "k": 1.0, "delay": 2, "ts": 1.0},
    },
    {
        "name": "piezo OE(4,4) at k = 0.5",
        "args": ["fit", "--data", "jobs/data/piezo_est.csv", "--rows", "1:2000", "--nb", "4", "--nf", "4",
                 "--k", "0.5", "--ts", "1e-4", "--json"],
        "python": {"data": {"path": "jobs/data/piezo_est.csv", "rows": [1, 2000]},
                   "nb": 4, "nf": 4, "k": 0.5, "delay": 1, "ts": 1e-4},
    },
]

# A small grid of the heater record; REPO/ stands for the checkout.
SWEEP_JOB = {
    "name": "heater-small",
    "data": {"path": "REPO/jobs/data/heater.dat", "u": 1, "y": 2, "ts": 1.0, "rows": [1, 1500]},
    "validation": {"rows": [1501, 2000]},
    "grid": {"nb": [1, 3], "nf": [1, 3], "delay": [1, 3], "k": [0.25, 0.5, 1.0, 2.0]},
}
SELECTION_KEYS = ("rule", "m1", "m2", "picks")


def frozen_selection(selection):
    """What reference.json keeps of a selection.json: the picks, and M1 and M2 without the
    lists of candidates they were chosen from."""
    kept = {k: selection[k] for k in SELECTION_KEYS}
    for k in ("m1", "m2"):
        kept[k] = {key: v for key, v in kept[k].items() if key != "candidates"}
    return kept


def main(binary):
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, cwd=REPO).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], capture_output=True, text=True,
                           cwd=REPO).stdout.strip()
    fits = []
    for entry in FITS:
        o = subprocess.run([binary, *entry["args"]], capture_output=True, text=True, cwd=REPO, check=True)
        report = json.loads(o.stdout)
        report.pop("seconds", None)
        fits.append({**entry, "report": report})
    with tempfile.TemporaryDirectory() as tmp:
        job = json.loads(json.dumps(SWEEP_JOB).replace("REPO/", f"{REPO}/"))
        (Path(tmp) / "job.json").write_text(json.dumps({**job, "output": f"{tmp}/out"}))
        subprocess.run([binary, "run", f"{tmp}/job.json", "--quiet"], check=True, stdout=subprocess.DEVNULL)
        selection = json.loads((Path(tmp) / "out" / "selection.json").read_text())
    doc = {
        "about": "Made by python/tests/freeze_reference.py with the cargo-built oesweep binary of commit "
                 f"{commit}{' (with changes to src/)' if dirty else ''}; read by test_estimates.py.",
        "fits": fits,
        "sweep": {"job": SWEEP_JOB, "selection": frozen_selection(selection)},
    }
    OUT.write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1])
