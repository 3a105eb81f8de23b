"""Arrays as the native module takes them: any 1-D numbers (numpy, pandas, polars, lists) as
float64 numpy arrays, inputs of several columns as a list of them."""

from __future__ import annotations

from typing import Any, List, Sequence, Union

import numpy as np

from ._oesweep import DataError, JobError

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
