# The native module (python/src/lib.rs). Arrays are one-dimensional float64 buffers (numpy
# arrays; `oesweep._f64` converts anything else); models and reports cross as JSON text.
from os import PathLike
from typing import Any, Callable, Optional, Tuple, Union

import numpy as np
from numpy.typing import NDArray
from typing_extensions import Buffer

# What the package hands over (a float64 ndarray); the module takes any buffer of float64.
_Floats = Union[NDArray[np.float64], Buffer]

__version__: str

class JobError(ValueError): ...
class DataError(ValueError): ...
class OutputError(OSError): ...
class LockError(OutputError): ...

# One array and one order of each kind per input (`oesweep.fit` turns a single int into the
# list of one); the JSON's `nb`, `nf`, `delay`, `b`, `f`, `b_std`, `f_std`, `input_level` are
# scalars and flat lists for one input and hold one entry per input for several.
def fit(
    u: list[_Floats],
    y: _Floats,
    nb: list[int],
    nf: list[int],
    k: float,
    delay: list[int],
    ts: float,
    offset: str,
    initial_state: str,
    val_u: Optional[list[_Floats]] = None,
    val_y: Optional[_Floats] = None,
    interpolate_inputs: int = 0,
) -> str: ...
def run(
    job: Union[str, PathLike[str]],
    text: Optional[str] = None,
    threads: Optional[int] = None,
    progress: bool = True,
    force: bool = False,
    on_progress: Optional[Callable[[int, int], Any]] = None,
) -> str: ...
def spectrum(u: list[_Floats], y: _Floats, ts: float, method: str) -> str: ...
def report(folder: Union[str, PathLike[str]]) -> str: ...
def export(folder: Union[str, PathLike[str]], pick: Optional[str] = None) -> str: ...
def write_model(doc: str, to: str, out: Optional[Union[str, PathLike[str]]] = None) -> str: ...
def read(spec: str) -> Tuple[bytes, bytes]: ...
def cli(argv: list[str]) -> int: ...
def to_continuous(doc: str, method: str) -> str: ...
