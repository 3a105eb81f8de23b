"""Models: :class:`Model` (a fitted or loaded OE model of one or several inputs) and
:class:`ContinuousModel` (its continuous-time form), with their scipy and python-control views."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

import numpy as np

from . import _oesweep
from ._arrays import ArrayLike, _inputs
from ._oesweep import DataError, JobError

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
