"""A formulation's process noise ``Q(dt)`` and its inverse, cached per time step: the
EKF, the MHE's process weights and the consistency check's prediction use it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.formulations import Formulation


def process_noise(formulation: Formulation, dt: float) -> tuple[FloatArray, FloatArray]:
    """``(Q(dt), Q(dt)^-1)`` (nx, nx) of ``formulation`` for a time step ``dt`` (s),
    uncached (the compiled core keeps its own cache); a one-line
    :class:`~continuum_mhe.errors.UserError` for a step so short that Q is singular."""
    f, nx = formulation, formulation.nx
    Q = np.asarray(f.functions.predict(np.zeros(nx), np.zeros(f.nu), dt)[2], float)
    Q = Q.reshape(nx, nx)
    try:
        return Q, np.linalg.inv(Q)
    except np.linalg.LinAlgError:  # a step so short that Q underflows
        raise UserError(
            f"a time step of {dt:g} s is too short for the process noise (its "
            "covariance is singular): t must be in seconds"
        ) from None


def bend_accel_psd_applies(formulation: Formulation) -> bool:
    """Whether ``formulation``'s process noise depends on ``noise.bend_accel_psd`` (the
    command line's ``--accel-psd``): its covariance over one 0.05 s step at two values
    of it."""
    doubled = replace(
        formulation,
        noise=replace(formulation.noise, bend_accel_psd=2.0 * formulation.noise.bend_accel_psd),
    )
    return not np.array_equal(formulation.process_cov(0.05), doubled.process_cov(0.05))


class ProcessNoiseCache:
    """:func:`process_noise` of a formulation, cached per time step rounded to 1e-9 s
    (Q depends on the time step only; at most 4096 distinct steps are kept). ``held``:
    states without process noise, their rows and columns of ``Q`` and ``Q^-1`` zero (a
    state held where it is, such as the tip force of a robot taken as free of load;
    ``Q^-1`` there is that of the other states, as on an inactive term)."""

    def __init__(self, formulation: Formulation, held: tuple[int, ...] = ()) -> None:
        self._f = formulation
        self._held = np.asarray(held, dtype=np.intp)
        self._cache: dict[float, tuple[FloatArray, FloatArray]] = {}

    def __call__(self, dt: float) -> tuple[FloatArray, FloatArray]:
        key = round(dt, 9)
        w = self._cache.get(key)
        if w is None:
            w = process_noise(self._f, dt)
            if len(self._held):
                for a in w:
                    a[self._held, :] = 0.0
                    a[:, self._held] = 0.0
            if len(self._cache) < 4096:
                self._cache[key] = w
        return w
