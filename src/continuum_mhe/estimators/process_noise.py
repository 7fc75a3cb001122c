"""A formulation's process noise ``Q(dt)`` and its inverse, cached per time step: the
EKF, the MHE's process weights and the consistency check's prediction use it. The
compiled core computes it from the tape of the covariance (:func:`compiled_process_noise`)
for the estimators' compiled steps; :class:`ProcessNoiseCache` gives CasADi's and
LAPACK's for the steps in Python (the MHE on IPOPT, the reference filters)."""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property, lru_cache, partial

import casadi as ca
import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.tape import tape_function


def process_noise(formulation: Formulation, dt: float) -> tuple[FloatArray, FloatArray]:
    """``(Q(dt), Q(dt)^-1)`` (nx, nx) of ``formulation`` for a time step ``dt`` (s),
    uncached, evaluated by CasADi and inverted by LAPACK: the reference of
    :func:`compiled_process_noise`, and its answer where ``Q`` is not positive definite;
    a one-line :class:`~continuum_mhe.errors.UserError` for a step so short that Q is
    singular."""
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


def _held_process_noise(
    formulation: Formulation, held: tuple[int, ...], dt: float
) -> tuple[FloatArray, FloatArray]:
    """:func:`process_noise` with the rows and columns of the ``held`` states zero."""
    w = process_noise(formulation, dt)
    for a in w:
        a[list(held), :] = 0.0
        a[:, list(held)] = 0.0
    return w


@lru_cache(maxsize=32)
def process_noise_tape(formulation: Formulation) -> _core.TapeFunction:
    """``dt -> Q(dt)`` (nx, nx) of ``formulation`` as the core evaluates it: the
    covariance of its ``predict`` function (at a zero state and input, as
    :func:`process_noise` takes it), read once per formulation."""
    f = formulation
    dt = ca.SX.sym("dt")
    Q = f.functions.predict(ca.DM.zeros(f.nx), ca.DM.zeros(f.nu), dt)[2]
    return tape_function(ca.Function("process_noise", [dt], [ca.densify(Q)]))


def compiled_process_noise(
    formulation: Formulation, held: tuple[int, ...] = ()
) -> _core.ProcessNoise:
    """``dt -> (Q(dt), Q(dt)^-1)`` of ``formulation`` in compiled code (``Q^-1`` from
    ``Q``'s Cholesky factor), with the rows and columns of the ``held`` states zero (see
    :class:`ProcessNoiseCache`); :func:`process_noise` answers where ``Q`` is not
    positive definite. The estimators' compiled steps take it without calling Python."""
    return _core.ProcessNoise(
        process_noise_tape(formulation),
        formulation.nx,
        list(held),
        partial(_held_process_noise, formulation, tuple(held)),
    )


class ProcessNoiseCache:
    """:func:`process_noise` of a formulation, cached per time step rounded to 1e-9 s
    (Q depends on the time step only; at most 4096 distinct steps are kept). ``held``:
    states without process noise, their rows and columns of ``Q`` and ``Q^-1`` zero (a
    state held where it is, such as the tip force of a robot taken as free of load;
    ``Q^-1`` there is that of the other states, as on an inactive term)."""

    def __init__(self, formulation: Formulation, held: tuple[int, ...] = ()) -> None:
        self._f = formulation
        self._held = tuple(held)
        self._cache: dict[float, tuple[FloatArray, FloatArray]] = {}

    @cached_property
    def compiled(self) -> _core.ProcessNoise:
        """The same in compiled code (:func:`compiled_process_noise`), which the
        estimators' compiled steps take; its ``Q^-1`` agrees with this one's to
        rounding."""
        return compiled_process_noise(self._f, self._held)

    def __call__(self, dt: float) -> tuple[FloatArray, FloatArray]:
        key = round(dt, 9)
        w = self._cache.get(key)
        if w is None:
            w = _held_process_noise(self._f, self._held, dt)
            if len(self._cache) < 4096:
                self._cache[key] = w
        return w
