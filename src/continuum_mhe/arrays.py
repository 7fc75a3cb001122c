"""The array types of the package's signatures, and the one conversion the compiled
core's calls take (imports nothing from the package)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: a float64 NumPy array of any shape (the shape and units are given where it is used)
FloatArray = NDArray[np.float64]


def contiguous_f64(a: object) -> FloatArray:
    """``a`` as a C-contiguous float64 array (no copy when it is one already): the
    compiled core's argument type."""
    return np.ascontiguousarray(a, dtype=np.float64)
