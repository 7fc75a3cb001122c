"""Shared test helpers: the five estimators of the recovery tests, the fast MHE
against IPOPT on the same samples, and the windows a fast MHE solves."""

from __future__ import annotations

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Estimator, Measurement
from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.fast.sqp import FastResult
from continuum_mhe.estimators.kalman import ExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator, WindowProblem
from continuum_mhe.model.formulations import BendFormulation, Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings


def recovery_estimators(recovery: RecoverySettings) -> list[Estimator]:
    """Compiled EKF, CasADi EKF, UKF, fast MHE and IPOPT MHE (N = 10) on the default
    bend formulation, all with ``recovery``."""
    f = BendFormulation()
    out: list[Estimator] = [
        make_estimator("ekf", f, recovery=recovery),
        ExtendedKalmanFilter(f),
        make_estimator("ukf", f, recovery=recovery),
        make_estimator("mhe", f, MHESettings(horizon=10), recovery),
        make_estimator("mhe", f, MHESettings(horizon=10, solver="ipopt"), recovery),
    ]
    out[1].recovery = recovery  # the CasADi EKF too
    return out


def fast_and_ipopt_states(
    f: Formulation, t: np.ndarray, z: np.ndarray, horizon: int
) -> dict[str, np.ndarray]:
    """``{"fast": states, "ipopt": states}`` (n, nx) of the MHE on both backends (the
    fast one on CasADi's VM), every sample asserted ``ok``."""
    states = {}
    for solver in ("fast", "ipopt"):
        est = MovingHorizonEstimator(
            f, MHESettings(horizon=horizon, solver=solver), FastOptions(compile=False)
        )
        res = [est.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
        assert {r.status for r in res} == {"ok"}
        states[solver] = np.array([r.state for r in res])
    return states


def fast_windows(
    est: MovingHorizonEstimator, t: np.ndarray, z: np.ndarray
) -> list[tuple[WindowProblem, np.ndarray, np.ndarray | None, FastResult]]:
    """Run the fast MHE ``est`` on its Python path over ``(t, z)`` and return every
    window it solved: ``(problem copy, initial guess, multipliers given, result)``."""
    import continuum_mhe.estimators.mhe as mhe_module

    windows = []
    solve_window = mhe_module.solve_window

    def keep(model, problem, X0, options=None, lam0=None, workspace=None):  # type: ignore[no-untyped-def]
        res = solve_window(model, problem, X0, options, lam0, workspace)
        copy = WindowProblem(**{k: np.copy(v) for k, v in vars(problem).items()})
        windows.append((copy, X0.copy(), None if lam0 is None else lam0.copy(), res))
        return res

    est._steps = None  # the Python path, whose windows can be kept
    mhe_module.solve_window = keep  # type: ignore[assignment]
    try:
        est.run(t, z)
    finally:
        mhe_module.solve_window = solve_window  # type: ignore[assignment]
    return windows


class RaisingFunction:
    """A CasADi function whose evaluation raises ``ValueError(message)`` (for
    :func:`continuum_mhe.estimators.fast.codegen._vm_function`); otherwise ``fn``."""

    def __init__(self, fn: object, message: str) -> None:
        self._fn = fn
        self._message = message

    def __getattr__(self, name: str) -> object:
        return getattr(self._fn, name)

    def call(self, args: object) -> object:
        raise ValueError(self._message)
