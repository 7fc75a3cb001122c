"""The array types of the package's signatures, and the one conversion the compiled
core's calls take (imports nothing from the package)."""

from __future__ import annotations

import sys
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray

#: a float64 NumPy array of any shape (the shape and units are given where it is used)
FloatArray = NDArray[np.float64]


def contiguous_f64(a: object) -> FloatArray:
    """``a`` as a C-contiguous float64 array (no copy when it is one already): the
    compiled core's argument type."""
    return np.ascontiguousarray(a, dtype=np.float64)


def holds_bools(values: object) -> bool:
    """Whether ``values`` (a number, a nested sequence, an array) holds a bool, Python's
    or numpy's: numpy reads True beside numbers as 1.0 (``[True, 0.1]`` becomes a float
    array), so a reading given as a bool would pass for the number 1."""
    if isinstance(values, np.ndarray):
        kinds = {values.dtype.kind}
    else:
        dtypes = getattr(values, "dtypes", None)  # a pandas Series's, a DataFrame's columns'
        if dtypes is None:  # a list, a tuple, a number: its items are looked at
            kinds = {"O"}
        else:
            each = dtypes if hasattr(dtypes, "__iter__") else [dtypes]
            kinds = {getattr(d, "kind", "O") for d in each}
    if "b" in kinds:
        return True
    if "O" not in kinds:
        return False
    return any(isinstance(v, (bool, np.bool_)) for v in np.asarray(values, dtype=object).flat)


#: Steps of a time axis shorter than this (s) are rows written twice or a logger's
#: burst, not its period (:func:`typical_step`).
BURST_STEP_S = 1e-4


def typical_step(t: FloatArray) -> float:
    """The median step (s) of the increasing times ``t`` (n >= 2), of the steps of at
    least :data:`BURST_STEP_S` where there are such: rows written twice, or stamped in
    bursts a microsecond apart, do not make the period look like a microsecond."""
    return typical_of_steps(np.diff(np.asarray(t, dtype=float)))


def typical_of_steps(steps: FloatArray) -> float:
    """:func:`typical_step` of the steps ``steps`` (s, at least one) themselves."""
    longer = steps[steps >= BURST_STEP_S]
    return float(np.median(longer if len(longer) else steps))


@overload
def longer(span: float, limit: float, t: float) -> bool: ...
@overload
def longer(span: FloatArray, limit: float, t: FloatArray) -> NDArray[np.bool_]: ...
def longer(span: Any, limit: float, t: Any) -> Any:
    """Whether the time ``span`` (s) between two samples, the later at ``t`` (s), is
    longer than ``limit`` (s) by more than the times' rounding, as the compiled
    sensor-health policy decides it (``longer`` in ``csrc/sensor_health.cpp``): 1 us (a
    file's times kept to the microsecond) and a few units in the last place of ``t``
    (2e-7 s at a Unix time of 1.7e9 s), so that a step of exactly the limit, as the
    times subtract, is not longer. Element by element for arrays ``span`` and ``t``."""
    return span > limit + 1e-6 + 8.0 * sys.float_info.epsilon * abs(t)
