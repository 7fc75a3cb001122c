"""The array types of the package's signatures (imports nothing from the package)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: a float64 NumPy array of any shape (the shape and units are given where it is used)
FloatArray = NDArray[np.float64]
