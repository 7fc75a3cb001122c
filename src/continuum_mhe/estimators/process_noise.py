"""A formulation's process noise ``Q(dt)`` and its inverse, cached per time step: the
EKF, the MHE's process weights and the consistency check's prediction use it."""

from __future__ import annotations

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.formulations import Formulation


class ProcessNoiseCache:
    """``(Q(dt), Q(dt)^-1)`` of a formulation, cached per time step (Q depends on the
    time step only; at most 4096 distinct steps are kept)."""

    def __init__(self, formulation: Formulation) -> None:
        self._f = formulation
        self._cache: dict[float, tuple[FloatArray, FloatArray]] = {}

    def __call__(self, dt: float) -> tuple[FloatArray, FloatArray]:
        key = round(dt, 9)
        w = self._cache.get(key)
        if w is None:
            f, nx = self._f, self._f.nx
            Q = np.asarray(f.functions.predict(np.zeros(nx), np.zeros(f.nu), dt)[2], float)
            Q = Q.reshape(nx, nx)
            try:
                w = (Q, np.linalg.inv(Q))
            except np.linalg.LinAlgError:  # a step so short that Q underflows
                raise UserError(
                    f"a time step of {dt:g} s is too short for the process noise (its "
                    "covariance is singular): t must be in seconds"
                ) from None
            if len(self._cache) < 4096:
                self._cache[key] = w
        return w
