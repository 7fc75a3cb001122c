"""Shared test helpers: the five estimators of the recovery tests, the fast MHE
against IPOPT on the same samples, the windows a fast MHE solves, the MHE backends and
settings, the tilt measurement and process noise written independently for the peers,
and the linear Gaussian model (its recording is the ``linear_recording`` fixture of
``conftest.py``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.fast.sqp import FastResult
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator, WindowProblem
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings


def bare(**changes: Any) -> RecoverySettings:
    """:meth:`RecoverySettings.off` with ``changes``: one recovery mechanism tested
    alone, the others off."""
    return replace(RecoverySettings.off(), **changes)


def recovery_estimators(
    recovery: RecoverySettings, f: Formulation | None = None
) -> list[Estimator]:
    """Compiled EKF, CasADi EKF, UKF, fast MHE and IPOPT MHE (N = 10) on ``f`` (the
    default bend formulation when None), all with ``recovery``."""
    f = BendFormulation() if f is None else f
    out: list[Estimator] = [
        make_estimator("ekf", f, recovery=recovery),
        CasadiExtendedKalmanFilter(f),
        make_estimator("ukf", f, recovery=recovery),
        make_estimator("mhe", f, MHESettings(horizon=10), recovery),
        make_estimator("mhe", f, MHESettings(horizon=10, solver="ipopt"), recovery),
    ]
    out[1].recovery = recovery  # the CasADi EKF too
    return out


def assert_ok_after_the_start(statuses: Any, allowed: frozenset[str] = frozenset({"ok"})) -> None:
    """The first row of a run is ``uncertain`` (a start fits its one reading; a later
    reading confirms it) and every later row's status is in ``allowed`` (``ok``)."""
    got = [str(s) for s in statuses]
    assert got[0] == "uncertain", got[:3]
    assert set(got[1:]) <= set(allowed), sorted(set(got[1:]))


def fast_and_ipopt_states(
    f: Formulation, t: np.ndarray, z: np.ndarray, horizon: int
) -> dict[str, np.ndarray]:
    """``{"fast": states, "ipopt": states}`` (n, nx) of the MHE on both backends (the
    fast one on CasADi's VM), every sample asserted ``ok`` or ``uncertain`` (a wide
    standard deviation, which changes no state): no restart."""
    states = {}
    for solver in ("fast", "ipopt"):
        est = MovingHorizonEstimator(f, MHESettings(horizon=horizon, solver=solver), FastOptions())
        res = [est.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
        assert_ok_after_the_start([r.status for r in res], frozenset({"ok", "uncertain"}))
        states[solver] = np.array([r.state for r in res])
    return states


def worst_certified_error(
    model: Any, windows: list[Any], options: FastOptions | None = None
) -> float:
    """The largest distance, in the certificate's norm (``model.step_scale``), of a
    window's certified answer (with ``options``) from the answer iterated to 1e-13 with
    the same steps, over ``windows`` (of :func:`fast_windows`), each window's two solves
    asserted converged."""
    from continuum_mhe.estimators.fast.sqp import solve_window

    options = options or FastOptions()
    tight = replace(options, step_tol=1e-13, err_tol=1e-13, max_iter=200)
    worst = 0.0
    for problem, X0, lam0, _ in windows:
        res = solve_window(model, problem, X0, options, lam0=lam0)
        ref = solve_window(model, problem, X0, tight, lam0=lam0)
        assert res.converged and ref.converged
        worst = max(worst, float(np.max(np.abs(res.X - ref.X) * model.step_scale)))
    return worst


def fast_windows(
    est: MovingHorizonEstimator, t: np.ndarray, z: np.ndarray
) -> list[tuple[WindowProblem, np.ndarray, np.ndarray | None, FastResult]]:
    """Run the fast MHE ``est`` over ``(t, z)`` and return every window it solved:
    ``(problem copy, initial guess, multipliers given, result)``, each sample's own
    window (solved again here from the compiled step's start, which gives the same
    result) before those of its hooks (branch check, second start)."""
    import continuum_mhe.estimators.mhe as mhe_module

    windows: list[tuple[WindowProblem, np.ndarray, np.ndarray | None, FastResult]] = []
    hooks: list[tuple[WindowProblem, np.ndarray, np.ndarray | None, FastResult]] = []
    solve_window = mhe_module.solve_window

    def keep(model, problem, X0, options=None, lam0=None, workspace=None):  # type: ignore[no-untyped-def]
        res = solve_window(model, problem, X0, options, lam0, workspace)
        copy = WindowProblem(**{k: np.copy(v) for k, v in vars(problem).items()})
        hooks.append((copy, X0.copy(), None if lam0 is None else lam0.copy(), res))
        return res

    inference = est.inference
    model, window = inference._fast, inference._window
    assert model is not None and isinstance(window, _core.MovingHorizon)
    mhe_module.solve_window = keep  # type: ignore[assignment]
    try:
        est.reset()
        for i in range(len(t)):
            hooks.clear()
            est.step(Measurement(float(t[i]), np.asarray(z[i], dtype=float)))
            if window.solved:
                problem = inference.window_problem()
                X0, lam0 = np.array(window.X0), np.array(window.lam0)
                res = solve_window(model, problem, X0, inference.fast_options, lam0)
                windows.append((problem, X0, lam0, res))
            windows.extend(hooks)
    finally:
        mhe_module.solve_window = solve_window  # type: ignore[assignment]
    return windows


# --- MHE backends and settings ---------------------------------------------------------
def ipopt_settings(**kwargs: Any) -> MHESettings:
    """MHESettings that select the IPOPT backend."""
    return MHESettings(solver="ipopt", **kwargs)


SOLVERS = ("fast", "ipopt")  # every MHE behaviour below holds for both backends


def solver_settings(solver: str, **kwargs: Any) -> MHESettings:
    """MHESettings for backend ``solver`` ("fast" is the default)."""
    return ipopt_settings(**kwargs) if solver == "ipopt" else MHESettings(**kwargs)


def step_all(estimator: Estimator, t: np.ndarray, z: np.ndarray) -> list:
    estimator.reset()
    return [estimator.step(Measurement(float(ti), np.asarray(zi, float))) for ti, zi in zip(t, z)]


# --- the measurement and the process noise, written independently for the peers ---------
def tilt_tangent_basis(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Measured gravity direction f(z) and the tangent basis E = [e_roll, e_pitch] (3x2)."""
    g, b = float(z[0]), float(z[1])
    f_z = np.array([-math.sin(b), math.cos(b) * math.sin(g), math.cos(b) * math.cos(g)])
    e_roll = np.array([0.0, math.cos(g), -math.sin(g)])
    e_pitch = np.array(
        [-math.cos(b), -math.sin(b) * math.sin(g), -math.sin(b) * math.cos(g)]
    )  # d f_z / d pitch
    return f_z, np.column_stack([e_roll, e_pitch])


def bend_process_cov(q: float, dt: float) -> np.ndarray:
    """White-noise-acceleration covariance for state (a, b, a_dot, b_dot)."""
    block = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    Q = np.zeros((4, 4))
    Q[np.ix_([0, 2], [0, 2])] = block
    Q[np.ix_([1, 3], [1, 3])] = block
    return Q


# --- linear Gaussian model: MHE == batch least squares == Kalman filter -----------------
@dataclass(frozen=True)
class LinearBend(BendFormulation):
    """Constant-velocity model with a linear measurement ``z = x[:2]`` and no bounds."""

    def measurement_sym(self, x):
        return x[:2]

    def measurement_residual_sym(self, z, x):
        return z - x[:2]

    def constraint_sym(self, x):
        return ca.SX(0, 1), -np.inf, np.inf

    def initial_state(self, z0):
        return np.array([z0[0], z0[1], 0.0, 0.0])

    def project(self, x):
        return np.array(x, dtype=float)

    def is_feasible(self, x, tol=1e-7):
        return True


LIN_DT = 0.05
LIN_N = 15
LIN_H = np.hstack([np.eye(2), np.zeros((2, 2))])


def lin_transition(dt: float) -> np.ndarray:
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    return F


def reading_by_reading(z: np.ndarray, length: float = 0.2) -> np.ndarray:
    """The shape read from each tilt reading alone, no filter: ``(theta, phi, x, y, z)``
    per row (rad, m) by the closed-form inverse tilt and the arc's tip. An estimator
    that filters the readings must beat it; one that follows each reading equals it."""
    from continuum_mhe.model.imu import shape_from_tilt
    from continuum_mhe.model.kinematics import tip_position

    theta, phi = shape_from_tilt(z[:, 0], z[:, 1])
    return np.column_stack([theta, phi, tip_position(theta, phi, length)])
