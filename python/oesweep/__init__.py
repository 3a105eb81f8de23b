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
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from . import _oesweep
from ._oesweep import DataError, JobError, LockError, OutputError

__all__ = [
    "fit", "read", "sweep", "load", "spectrum", "Model", "ContinuousModel", "Sweep",
    "JobError", "DataError", "OutputError", "LockError", "__version__",
]
__version__ = _oesweep.__version__

ArrayLike = Union[np.ndarray, Sequence[float], Any]


def _f64(name: str, x: ArrayLike) -> np.ndarray:
    """Any 1-D float or int array (numpy, pandas or polars Series, list) as a float64 numpy
    array, which the native module reads through the buffer protocol: the array itself when it
    already is one (no copy)."""
    if hasattr(x, "to_numpy"):
        x = x.to_numpy()
    a = np.asarray(x)
    if a.ndim != 1:
        raise DataError(f"{name}: expected a 1-D array, got {a.ndim} dimensions")
    if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
        raise DataError(f"{name}: expected numbers, got dtype {a.dtype}")
    return np.require(a, dtype=np.float64, requirements=["C", "A"])


# The fields a model can have, from any of its sources (`fit`, a results folder's pick, an
# export): one a source lacks reads as None (a least-squares model has no k); any other name
# is a typo and raises AttributeError.
_MODEL_FIELDS = frozenset(
    """aic aicc b b_std band_hz basis bic bootstrap cancellations converged covariance criterion
    data delay den dt f f_std fit fit_band fit_exp fit_val fit_val_exp fpe gamma initial_state
    input_level iterations k k_index l1c least_squares max_pole_radius max_rel_std method model
    n nb nf noise_variance num offset offset_mode offset_std parameters quadratic raic rbic reason
    reflections resid_indep_p resid_white_p score seconds sigma start status termination ts
    validation validation_column warnings""".split()
)


def _scipy_signal():
    try:
        import scipy.signal
    except ImportError as e:
        raise ImportError("this needs scipy: pip install 'oesweep[scipy]'") from e
    return scipy.signal


def _control():
    try:
        import control
    except ImportError as e:
        raise ImportError("this needs the python-control package: pip install 'oesweep[control]'") from e
    return control


class Model:
    """An OE model ``y = q^-delay B(q^-1)/F(q^-1) (u - input_level) + offset``.

    Attributes mirror the result table's columns: ``b``, ``f``, ``delay``, ``offset``, ``ts``,
    ``k``, ``gamma``, ``criterion``, ``l1c``, ``fit``, ``fit_val``, ``b_std``, ``f_std``,
    ``resid_white_p``, ``resid_indep_p``, ``termination``, ``iterations``, and
    ``covariance`` (over b, f and an estimated offset) when it is known.
    """

    # One input: scalars and flat lists; several: one entry per input (``inputs``). Set from
    # the source's fields (a field the source lacks reads as None).
    nb: Union[int, List[int]]
    nf: Union[int, List[int]]
    delay: Union[int, List[int]]
    b: Union[List[float], List[List[float]]]
    f: Union[List[float], List[List[float]]]
    b_std: Optional[Union[List[float], List[List[float]]]]
    f_std: Optional[Union[List[float], List[List[float]]]]
    input_level: Optional[Union[float, List[float]]]

    def __init__(self, fields: Dict[str, Any]):
        self._fields = dict(fields)
        for key, value in fields.items():
            setattr(self, key, value)

    def __getattr__(self, name: str) -> Any:
        # Only called for names that are not set: a known field this model's source lacks.
        if name in _MODEL_FIELDS:
            return None
        raise AttributeError(f"'Model' object has no attribute {name!r}")

    @property
    def inputs(self) -> int:
        """The number of inputs m (a several-input model's ``b``, ``f`` hold one list per input)."""
        return len(self.nb) if isinstance(self.nb, list) else 1

    def _parts(self) -> List[tuple]:
        """(b, f, delay, input level) of each input."""
        if self.inputs == 1:
            return [(list(self.b), list(self.f), int(self.delay), float(self.input_level or 0.0))]
        levels = self.input_level if isinstance(self.input_level, list) else [0.0] * self.inputs
        return [(list(b), list(f), int(d), float(u0)) for b, f, d, u0 in zip(self.b, self.f, self.delay, levels)]

    @staticmethod
    def _num_den(b: List[float], f: List[float], d: int):
        n = max(d + len(b), len(f) + 1)
        num = [0.0] * n
        num[d : d + len(b)] = b
        den = [1.0] + f + [0.0] * (n - 1 - len(f))
        return np.array(num), np.array(den)

    @property
    def num_den(self):
        """``num``, ``den`` in descending powers of z, of equal length (delay as leading zeros);
        with several inputs a list of one such pair per input."""
        pairs = [self._num_den(b, f, d) for b, f, d, _ in self._parts()]
        return pairs[0] if self.inputs == 1 else pairs

    def simulate(self, u: ArrayLike, initial_state: Optional[ArrayLike] = None) -> np.ndarray:
        """The model output for input ``u`` (data units), from zero initial state unless
        ``initial_state`` (``scipy.signal.lfilter``'s ``zi``; one input only) is given. Several
        inputs: ``u`` as ``fit`` takes it (2-D, one column per input, or a list). Needs scipy."""
        lfilter = _scipy_signal().lfilter

        parts = self._parts()
        us = _inputs("u", u)
        if len(us) != len(parts):
            raise DataError(f"u: {len(us)} inputs for a model of {len(parts)}")
        if initial_state is not None and len(parts) > 1:
            raise JobError("initial_state: one input's lfilter state; not for a model of several inputs")
        y = np.zeros(len(us[0]))
        for ui, (b, f, d, u0) in zip(us, parts):
            num, den = self._num_den(b, f, d)
            if initial_state is None:
                y = y + lfilter(num, den, ui - u0)
            else:
                y = y + lfilter(num, den, ui - u0, zi=np.asarray(initial_state, dtype=np.float64))[0]
        return y + float(self.offset or 0.0)

    def frequency_response(self, freq_hz: ArrayLike) -> np.ndarray:
        """G(e^{j 2 pi f ts}) at the frequencies ``freq_hz`` (complex); several inputs: one
        column per input."""
        w = 2.0 * np.pi * np.asarray(freq_hz, dtype=np.float64) * float(self.ts)
        z1 = np.exp(-1j * w)
        columns = []
        for b, f, d, _ in self._parts():
            num, den = self._num_den(b, f, d)
            powers = np.arange(len(num))
            columns.append((num[None, :] * z1[:, None] ** powers).sum(1) / (den[None, :] * z1[:, None] ** powers).sum(1))
        return columns[0] if self.inputs == 1 else np.stack(columns, axis=1)

    def to_scipy(self):
        """``scipy.signal.dlti`` with ``dt = ts`` (several inputs: a list of one per input).
        Needs scipy."""
        import warnings

        dlti = _scipy_signal().dlti

        systems = []
        with warnings.catch_warnings():
            # The delay's leading zeros of num are exact, not a badly conditioned numerator.
            warnings.filterwarnings("ignore", message="Badly conditioned filter coefficients")
            for b, f, d, _ in self._parts():
                num, den = self._num_den(b, f, d)
                systems.append(dlti(num, den, dt=float(self.ts)))
        return systems[0] if self.inputs == 1 else systems

    def to_control(self):
        """A python-control ``TransferFunction`` with ``dt = ts``: several inputs give one with
        one output and one input per model input. Needs python-control."""
        tf = _control().tf

        pairs = [self._num_den(b, f, d) for b, f, d, _ in self._parts()]
        if self.inputs == 1:
            return tf(pairs[0][0], pairs[0][1], float(self.ts))
        return tf([[list(n) for n, _ in pairs]], [[list(d) for _, d in pairs]], float(self.ts))

    def to_continuous(self, method: str = "zoh") -> Union["ContinuousModel", List["ContinuousModel"]]:
        """The continuous-time equivalent for control design, as ``oesweep export --continuous``
        computes it: ``"zoh"`` (the continuous system whose zero-order-hold sampling is the
        model) or ``"tustin"`` (the inverse bilinear map). The delay leaves as a dead time
        (``input_delay``, seconds), never as poles. ValueError, naming the pole, when there is no
        equivalent: under ZOH a pole at or near z = 0 or on the negative real axis, under
        Tustin a pole at z = -1. At high orders or short sample times use the result's
        ``zeros``, ``poles``, ``gain`` or ``state_space`` rather than ``num``, ``den``. Several
        inputs: a list of one equivalent per input, each input's filter converted on its own
        (the error names the input)."""
        doc = json.loads(_oesweep.to_continuous(json.dumps(self._document()), method))
        return [ContinuousModel(d) for d in doc] if isinstance(doc, list) else ContinuousModel(doc)

    def to_dict(self) -> Dict[str, Any]:
        """The model's fields (JSON-serialisable); ``Model(d)`` rebuilds it."""
        return json.loads(json.dumps(self._fields))

    def export(self, path: Optional[Union[str, os.PathLike]] = None, to: str = "json") -> Optional[str]:
        """The model as ``oesweep export --to json|matlab|mat`` writes it: ``"json"`` (``num``,
        ``den``, ``dt``, offset, delay, covariance), ``"matlab"`` (a script that builds the
        ``tf`` and, with the System Identification Toolbox, the ``idpoly``) or ``"mat"`` (a
        level-5 MAT-file, ``path`` required). Writes ``path`` when given, else returns the text.
        Several inputs: ``num``, ``den``, ``b``, ``f``, ``delay``, ``input_level`` hold one entry
        per input (``control.tf([num], [den], dt)`` is the 1 x m system), the script builds
        MATLAB's MISO ``idpoly`` (``B``, ``F`` cell arrays) and the MAT-file holds cell arrays."""
        doc = self._document()
        if to == "mat":
            if path is None:
                raise JobError('to="mat" writes a binary file: give its path')
            _oesweep.write_model(json.dumps(doc), to, str(path))
            return None
        text = _oesweep.write_model(json.dumps(doc), to)
        if path is None:
            return text
        Path(path).write_text(text)
        return None

    def _document(self) -> Dict[str, Any]:
        """The model as the document of ``oesweep export --to json`` (what the engine reads back)."""
        k = f" at k = {self.k}" if self.k is not None else " (least squares)"
        parts = self._parts()
        if self.inputs == 1:
            b, f, delay, level = parts[0]
            orders = f"OE({len(b)},{len(f)}) delay {delay}"
        else:
            b, f, delay, level = (list(x) for x in zip(*parts))
            orders = "OE(" + "; ".join(f"{len(bi)},{len(fi)} d{d}" for bi, fi, d, _ in parts) + ")"
        return {
            "model": self.model or f"{orders}{k}",
            "dt": float(self.ts),
            "b": b,
            "f": f,
            "delay": delay,
            "k": self.k,
            "offset": self.offset,
            "input_level": level,
            "parameters": list(self.parameters or []),
            "covariance": self.covariance,
            "noise_variance": self.noise_variance
            if self.noise_variance is not None
            else (float(self.sigma) ** 2 if self.sigma is not None else None),
        }

    def __repr__(self) -> str:
        k = f" k = {self.k}" if self.k is not None else " (least squares)"
        fits = [f"{name} = {v:.2f} %" for name, v in (("fit", self.fit), ("fit_val", self.fit_val)) if v is not None]
        if self.inputs == 1:
            orders = f"OE({len(self.b)}, {len(self.f)}) delay {self.delay}"
        else:
            orders = "OE(" + "; ".join(f"{len(b)},{len(f)} d{d}" for b, f, d, _ in self._parts()) + ")"
        return f"Model({orders}{k}{', ' if fits else ''}{', '.join(fits)})"


class ContinuousModel:
    """``Gc(s) = exp(-input_delay s) num(s)/den(s)``, a model's continuous-time equivalent
    (:meth:`Model.to_continuous`): ``num``, ``den`` in descending powers of s (``den`` monic),
    ``input_delay`` in seconds (``delay_samples`` of the sample time), ``method``; the same
    transfer function as ``zeros``, ``poles`` (complex, rad/s) and ``gain``, and as
    ``state_space`` ``(A, B, C, D)`` in scaled second-order sections. ``num`` and ``den`` span
    about ``ts**-n`` and are ill-conditioned at high orders and short sample times (a 9th-order
    model at ``ts = 1e-4`` sampled back through them is off by orders of magnitude): for those
    use ``to_control("ss")``, ``to_scipy("ss")`` or ``to_scipy("zpk")`` (docs/METHOD.md 18)."""

    def __init__(self, fields: Dict[str, Any]):
        self.method = fields["method"]
        self.num = np.array(fields["num"], dtype=np.float64)
        self.den = np.array(fields["den"], dtype=np.float64)
        self.input_delay = float(fields["input_delay"])
        self.delay_samples = int(fields["delay_samples"])
        self.zeros = np.array([complex(re, im) for re, im in fields["zeros"]], dtype=np.complex128)
        self.poles = np.array([complex(re, im) for re, im in fields["poles"]], dtype=np.complex128)
        self.gain = float(fields["gain"])
        ss = fields["state_space"]
        n = len(ss["b"])
        self.state_space = (
            np.array(ss["a"], dtype=np.float64).reshape(n, n),
            np.array(ss["b"], dtype=np.float64).reshape(n, 1),
            np.array(ss["c"], dtype=np.float64).reshape(1, n),
            np.array([[ss["d"]]], dtype=np.float64),
        )

    def to_scipy(self, form: str = "tf"):
        """A scipy continuous system without the dead time ``input_delay``, which scipy's systems
        do not hold: ``form="tf"`` ``lti(num, den)``, ``"zpk"`` ``lti(zeros, poles, gain)``,
        ``"ss"`` ``lti(A, B, C, D)``. scipy samples a ``zpk`` system through ``tf``: give
        ``cont2discrete`` the ``"ss"`` form. Needs scipy."""
        lti = _scipy_signal().lti

        if form == "tf":
            return lti(self.num, self.den)
        if form == "zpk":
            return lti(self.zeros, self.poles, self.gain)
        if form == "ss":
            return lti(*self.state_space)
        raise ValueError(f"form {form!r}: expected tf, zpk or ss")

    def to_control(self, form: str = "tf"):
        """A continuous python-control system without the dead time ``input_delay``, which
        python-control's systems do not hold (``control.pade`` gives a rational approximation to
        multiply in): ``form="tf"`` a ``TransferFunction`` of ``num``, ``den``, ``"ss"`` a
        ``StateSpace`` of ``state_space``, the well-conditioned one (python-control's ``zpk``
        builds a ``tf``). Needs python-control."""
        control = _control()
        if form == "tf":
            return control.tf(self.num, self.den)
        if form == "ss":
            return control.ss(*self.state_space)
        raise ValueError(f"form {form!r}: expected tf or ss")

    def __repr__(self) -> str:
        return (f"ContinuousModel({self.method}, order {len(self.den) - 1}, "
                f"input_delay = {self.input_delay:g} s)")


def _inputs(name: str, u: Any) -> List[np.ndarray]:
    """``u`` as one float64 array per input: a 1-D array is one input, a 2-D array (samples in
    rows, one column per input, as a DataFrame's values) or a list of 1-D arrays several."""
    if isinstance(u, (list, tuple)) and len(u) > 0 and np.ndim(u[0]) == 1:
        return [_f64(f"{name}[{i}]", x) for i, x in enumerate(u)]
    if hasattr(u, "to_numpy"):
        u = u.to_numpy()
    a = np.asarray(u)
    if a.ndim == 2:
        return [_f64(f"{name}[:, {i}]", a[:, i]) for i in range(a.shape[1])]
    return [_f64(name, a)]


def _per_input(name: str, v: Union[int, Sequence[int]], m: int) -> List[int]:
    """An order or delay for every input: one number for all, or a list of one per input."""
    if np.ndim(v) == 0:
        return [int(v)] * m
    v = [int(x) for x in v]
    if len(v) != m:
        raise JobError(f"{name}: {len(v)} entries for {m} inputs: give one per input, or one number")
    return v


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
