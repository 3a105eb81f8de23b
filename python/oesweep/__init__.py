"""oesweep: robust (Huber) output-error identification and model-order search.

The engine is the Rust library of this repository; this package calls it in-process and
returns Python objects: ``fit`` gives a :class:`Model`, ``sweep`` and ``load`` a :class:`Sweep`
whose ``cells`` is a polars DataFrame. Every call releases the GIL while the engine works.
Errors are raised by kind, with the command line's one-line message: :class:`JobError` (a job,
setting or results folder), :class:`DataError` (a data file or array), :class:`OutputError`
(an output that cannot be written) and its :class:`LockError` (an output folder another run
holds).
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Sequence, Union

import numpy as np

from . import _oesweep
from ._oesweep import DataError, JobError, LockError, OutputError
from ._arrays import ArrayLike, _f64, _inputs, _per_input
from ._model import ContinuousModel, Model

__all__ = [
    "fit", "read", "sweep", "load", "spectrum", "Model", "ContinuousModel", "Sweep",
    "JobError", "DataError", "OutputError", "LockError", "__version__",
]
__version__ = _oesweep.__version__

def fit(
    u: ArrayLike,
    y: ArrayLike,
    nb: Union[int, Sequence[int]],
    nf: Union[int, Sequence[int]],
    k: float,
    *,
    delay: Union[int, Sequence[int]] = 1,
    ts: float = 1.0,
    offset: str = "estimate",
    initial_state: str = "estimate",
    validation: Optional[tuple] = None,
    interpolate_inputs: int = 0,
) -> Model:
    """Fit OE(nb, nf) with delay by least squares and then Huber's criterion at k: the same
    numbers as ``oesweep fit --json``. ``validation`` is a ``(u, y)`` pair that only judges.

    NaN marks a missing sample, as a job's record has it (docs/METHOD.md 21.1): a missing
    output is left out of the criterion; a missing input cuts the record into segments fitted
    together as experiments, unless ``interpolate_inputs`` (a number of samples) lets gaps that
    short be filled by linear interpolation. Infinite values raise ``DataError``.

    Several inputs: ``u`` a 2-D array (one column per input) or a list of 1-D arrays, and
    ``nb``, ``nf``, ``delay`` one number for every input or a list of one per input; the
    model's ``nb``, ``nf``, ``delay``, ``b``, ``f``, ``b_std``, ``f_std``, ``input_level`` then
    hold one entry per input."""
    us, y = _inputs("u", u), _f64("y", y)
    m = len(us)
    val_u = val_y = None
    if validation is not None:
        val_u, val_y = _inputs("validation u", validation[0]), _f64("validation y", validation[1])
    text = _oesweep.fit(
        us, y, _per_input("nb", nb, m), _per_input("nf", nf, m), float(k), _per_input("delay", delay, m),
        float(ts), offset, initial_state, val_u, val_y, int(interpolate_inputs),
    )
    report = json.loads(text)
    fields = {key: report[key] for key in report if key not in ("ls",)}
    fields["ts"] = float(ts)
    fields["least_squares"] = report["ls"]
    return Model(fields)


def read(
    path: Union[str, os.PathLike],
    *,
    u: Union[str, int, Sequence[Union[str, int]]] = "u",
    y: Union[str, int] = "y",
    rows: Optional[Sequence[int]] = None,
    delimiter: Optional[str] = None,
    header: Union[bool, str, None] = None,
    missing: Optional[Sequence[Union[str, float]]] = None,
) -> tuple:
    """The input and output columns of a data file as ``(u, y)`` float64 arrays, read as a job
    file's record is (text with any delimiter and quoting, Parquet, MAT): ``u``, ``y`` a column
    name or a 1-based position, ``rows`` ``[first, last]`` (1-based, inclusive), ``delimiter``
    ``","``, ``";"``, ``"tab"`` or ``"whitespace"`` (default: sniffed), ``header`` ``True``,
    ``False`` or ``"auto"``. ``oesweep.fit(*oesweep.read("run.csv", rows=[1, 5000]), ...)``.
    ``u`` a list of columns reads several inputs: ``u`` is then an N x m array. Every row of
    the file is returned; a missing sample (an empty field, ``NaN``, or one of the markers
    ``missing``, such as ``["NA", -999]``) is NaN, which ``fit`` reads as a job reads the file."""
    spec: Dict[str, Any] = {"path": os.fspath(path), "u": u, "y": y}
    if rows is not None:
        spec["rows"] = list(rows)
    if missing is not None:
        spec["missing"] = list(missing)
    for key, value in (("delimiter", delimiter), ("header", header)):
        if value is not None:
            spec[key] = value
    if isinstance(u, (list, tuple)):
        # Several inputs: (N x m array, one column per input, y), as ``fit`` takes them.
        spec["u"] = list(u)
        _names, bu, by = _oesweep.read_inputs(json.dumps(spec))
        y_arr = np.frombuffer(by, dtype="<f8").copy()
        return np.frombuffer(bu, dtype="<f8").reshape(len(u), len(y_arr)).T.copy(), y_arr
    bu, by = _oesweep.read(json.dumps(spec))
    return np.frombuffer(bu, dtype="<f8").copy(), np.frombuffer(by, dtype="<f8").copy()


class Sweep:
    """A finished run: ``cells`` (polars DataFrame of cells.parquet), ``selection`` (the parsed
    selection.json), ``m1``, ``m2`` and ``pick(rule)`` as :class:`Model`, ``warnings``."""

    def __init__(self, folder: Union[str, os.PathLike]):
        self.folder = Path(folder)
        with open(self.folder / "selection.json") as fh:
            self.selection = json.load(fh)
        self.warnings = list(self.selection.get("warnings", []))

    @property
    def cells(self):
        import polars as pl

        return pl.read_parquet(self.folder / "cells.parquet")

    def pick(self, rule: Optional[str] = None) -> Model:
        """The model a rule picked (default: the lead rule), with its covariance."""
        doc = json.loads(_oesweep.export(str(self.folder), rule))
        # The row's columns (fits, criteria, evidence) from selection.json, the model's form and
        # covariance from the export.
        name = {"m1": "paper_m1", "m2": "paper_m2", None: self.selection.get("rule")}.get(rule, rule)
        row = ((self.selection.get("picks") or {}).get(name) or {}).get("model") or {}
        if isinstance(doc["delay"], list):
            # Several inputs: the row names its orders nb_1, nb_2, ...; the model has lists.
            row = {**row, "nb": [len(b) for b in doc["b"]], "nf": [len(f) for f in doc["f"]]}
        return Model({**row, **doc, "ts": doc["dt"]})

    @property
    def m1(self) -> Optional[Model]:
        return self.pick("m1") if self.selection.get("m1") else None

    @property
    def m2(self) -> Optional[Model]:
        return self.pick("m2") if self.selection.get("m2") else None

    def report(self, path: Optional[Union[str, os.PathLike]] = None) -> Path:
        """Write ``report.html`` and its figures (``report-*.svg``) into the results folder, as
        ``oesweep report`` does; returns the page's path. With ``path``, the page is also
        written there, its figures copied beside it and its links to the run's tables pointing
        back into the results folder."""
        page = Path(_oesweep.report(str(self.folder)))
        if path is None:
            return page
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        html = page.read_text()
        for figure in sorted(self.folder.glob("report-*.svg")):
            shutil.copyfile(figure, path.parent / figure.name)
        for name in ("cells.parquet", "selection.json", "job.json"):
            html = html.replace(f'href="{name}"', f'href="{(self.folder / name).resolve().as_uri()}"')
        path.write_text(html)
        return path

    def __repr__(self) -> str:
        return f"Sweep({str(self.folder)!r}, rule = {self.selection.get('rule')})"


class _LineProgress:
    """A plain line that rewrites itself (``\\r``), for notebooks and other non-terminals."""

    def __init__(self, stream=None, every: float = 0.5):
        self.stream = stream if stream is not None else sys.stderr
        self.every = every
        self.start = time.monotonic()
        self.last = -every
        self.first: Optional[int] = None

    def __call__(self, done: int, total: int) -> None:
        now = time.monotonic() - self.start
        if self.first is None:
            self.first = done  # cells of a resumed checkpoint do not count towards the rate
        first = self.first
        if total == 0 or (now - self.last < self.every and done < total):
            return
        self.last = now
        rate = (done - first) / max(now, 1e-9)
        eta = f", ETA {(total - done) / rate:.0f} s" if 0 < rate and done < total else ""
        self.stream.write(f"\r{done}/{total} cells, {rate:.1f} cells/s, {now:.0f} s{eta}   ")
        self.stream.flush()

    def close(self) -> None:
        if self.last >= 0:
            self.stream.write("\n")
            self.stream.flush()


def _json_value(x: Any) -> Any:
    """A job dict's paths (``pathlib.Path``) as the strings a job file holds."""
    if isinstance(x, os.PathLike):
        return os.fspath(x)
    raise JobError(f"job: {x!r} ({type(x).__name__}) is not a JSON value")


def _on_terminal() -> bool:
    try:
        return sys.stderr.isatty() and os.isatty(2)
    except (AttributeError, ValueError, OSError):
        return False


def sweep(
    job: Union[str, os.PathLike, Dict[str, Any]],
    *,
    threads: Optional[int] = None,
    progress: Union[bool, Callable[[int, int], None]] = True,
    output: Optional[Union[str, os.PathLike]] = None,
    force: bool = False,
) -> Sweep:
    """Run a job (a job file's path, or a dict with its schema; relative paths in a dict are
    relative to the current directory) as ``oesweep run`` does; returns the finished run.

    ``progress``: ``True`` draws the engine's bar on a terminal and a plain updating line
    elsewhere (a notebook); ``False`` is silent; a callable is called as ``progress(done,
    total)`` (Huber cells) on the calling thread as cells finish (those that finish together
    in one call) and once at the end. The workers never run more than 32 finished cells ahead
    of it, so an exception it raises stops the run as Ctrl-C does, within those cells and the
    ones in flight.

    Ctrl-C raises ``KeyboardInterrupt`` once the cells in flight are saved (well within a
    second); the checkpoint stays in the output folder and the same call resumes. ``force``
    starts over instead.
    """
    if callable(progress):
        engine_bar, callback = False, progress
    elif progress and _on_terminal():
        engine_bar, callback = True, None
    else:
        engine_bar, callback = False, (_LineProgress() if progress else None)
    # The job goes to the engine as text when it is a dict or its output is replaced: no file
    # is written for it. A job file's relative paths stay relative to its folder, a dict's to
    # the current directory (the folder of the name "<job dict>").
    if isinstance(job, dict):
        name, doc = "<job dict>", json.loads(json.dumps(job, default=_json_value))
    else:
        name, doc = os.fspath(job), None
        if output is not None:
            try:
                with open(job, encoding="utf-8-sig") as fh:
                    doc = json.load(fh)
            except (OSError, ValueError):
                doc = None  # the engine reads it again and reports it as the command line does
    text = None
    if isinstance(doc, dict):
        if output is not None:
            doc["output"] = str(Path(output).resolve())
        text = json.dumps(doc)
    try:
        folder = _oesweep.run(name, text, threads, engine_bar, force, callback)
    finally:
        if isinstance(callback, _LineProgress):
            callback.close()
    return Sweep(folder)


def spectrum(u: ArrayLike, y: ArrayLike, ts: float, method: str = "robust"):
    """The nonparametric frequency response ``G(f) = S_yu / S_uu`` of a record, as ``oesweep
    spectrum`` computes it (``method``: ``"robust"`` cleans the output's spikes first,
    ``"welch"`` is plain Welch). Returns a polars DataFrame with one row per frequency bin where
    the input has power: ``freq_hz``, ``re``, ``im``, ``magnitude``, ``phase_deg``,
    ``coherence`` and an approximate 95 % band of the magnitude, ``mag_lower``, ``mag_upper``
    (``.to_pandas()`` with pandas installed).

    Several inputs: ``u`` a 2-D array (samples in rows, one column per input) or a list of 1-D
    arrays, as ``fit`` takes them; the result is then a list of DataFrames, one per input, of
    the same columns and bins: input i's ``G_i`` of ``H = P^-1 s`` (the inputs' cross-spectral
    matrix P, docs/METHOD.md 19), its band, and in every one the multiple coherence."""
    import polars as pl

    us, y = _inputs("u", u), _f64("y", y)
    report = json.loads(_oesweep.spectrum(us, y, float(ts), method))

    def frame(re, im, lower, upper):
        g = np.array(re) + 1j * np.array(im)
        return pl.DataFrame(
            {
                "freq_hz": report["freq_hz"],
                "re": re,
                "im": im,
                "magnitude": np.abs(g),
                "phase_deg": np.degrees(np.angle(g)),
                "coherence": report["coherence"],
                "mag_lower": lower,
                "mag_upper": upper,
            }
        )

    keys = ("re", "im", "mag_lower", "mag_upper")
    if len(us) == 1:
        return frame(*(report[k] for k in keys))
    return [frame(*(report[k][i] for k in keys)) for i in range(len(us))]


def load(folder: Union[str, os.PathLike]) -> Sweep:
    """Open a finished run (made by ``sweep``, ``oesweep run`` or ``oesweep merge``)."""
    if not (Path(folder) / "selection.json").is_file():
        raise JobError(f"{folder}: not a finished results folder (no selection.json)")
    return Sweep(folder)
