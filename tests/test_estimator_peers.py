"""Estimators against independent peers and known answers.

* EKF and UKF against filterpy on identical inputs (same Q, R, initial state and
  covariance; the measurement written independently: roll and pitch from elementary
  rotations for ``paper`` (the residual wrapped), the gravity direction projected
  stereographically on the measured tangent plane for ``bend``).
* MHE against a plain CasADi ``Opti`` problem written here from the kinematics and
  IMU symbolic functions only (not the estimator's NLP builder).
* On a linear Gaussian model, the full-horizon MHE equals dense batch least squares,
  and its last node equals a Kalman filter.
* Bounds, the straight configuration, position consistency, solver failures and
  dropouts.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np
import pytest
from estimator_helpers import (
    LIN_DT,
    LIN_H,
    LIN_N,
    SOLVERS,
    LinearBend,
    assert_ok_after_the_start,
    bend_process_cov,
    ipopt_settings,
    lin_transition,
    reading_by_reading,
    solver_settings,
    step_all,
    tilt_tangent_basis,
)
from filterpy.kalman import ExtendedKalmanFilter as FilterpyEKF
from filterpy.kalman import MerweScaledSigmaPoints
from filterpy.kalman import UnscentedKalmanFilter as FilterpyUKF
from numpy.testing import assert_allclose

from continuum_mhe.estimators import EstimateSeries
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, UnscentedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator, WindowProblem
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import shape_from_tilt, wrap_angle
from continuum_mhe.model.kinematics import rotation_bend_sym, tip_position
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings, RobotSettings
from continuum_mhe.simulation.scenarios import Recording, simulate

FORMULATIONS = ("bend", "paper")
MOUNTINGS = ("z-up", "z-down")  # z-down puts roll near +-pi: the angle wrap is active


def window_states(mhe: MovingHorizonEstimator) -> np.ndarray:
    """The last solved window, (N, nx) (private attribute; the last row is the estimate)."""
    X = mhe.inference._X
    assert X is not None
    return np.asarray(X, dtype=float)


@pytest.fixture(scope="module")
def paper3d() -> Recording:
    return simulate("paper3d", duration=3)


@pytest.fixture(scope="module")
def paper3d_down() -> Recording:
    return simulate("paper3d", duration=3, mounting="z-down")


def recording_for(mounting: str, up: Recording, down: Recording) -> Recording:
    return up if mounting == "z-up" else down


# --- the measurement, written independently for the peers ---------------------------------
def _gravity_jacobian_fn(mounting: str) -> ca.Function:
    x = ca.SX.sym("x", 4)
    up = 1.0 if mounting == "z-up" else -1.0
    g = ca.mtimes(rotation_bend_sym(x[0], x[1]).T, ca.DM([0.0, 0.0, up]))
    return ca.Function("g", [x], [g, ca.jacobian(g, x)])


def _paper_tilt_fn(mounting: str) -> ca.Function:
    """The paper state's (x, y, z, theta, phi) roll and pitch and their Jacobian: the
    accelerometer's reading of gravity ``f = R^T up`` with ``R = Rz(phi) Ry(-theta)
    Rz(-phi)`` from elementary rotations, then ``roll = atan2(f_y, f_z)``, ``pitch =
    atan2(-f_x, hypot(f_y, f_z))``."""
    x = ca.SX.sym("x", 5)
    theta, phi = x[3], x[4]

    def rz(a: ca.SX) -> ca.SX:
        return ca.blockcat([[ca.cos(a), -ca.sin(a), 0], [ca.sin(a), ca.cos(a), 0], [0, 0, 1]])

    def ry(a: ca.SX) -> ca.SX:
        return ca.blockcat([[ca.cos(a), 0, ca.sin(a)], [0, 1, 0], [-ca.sin(a), 0, ca.cos(a)]])

    rot = rz(phi) @ ry(-theta) @ rz(-phi)
    up = 1.0 if mounting == "z-up" else -1.0
    fa = rot.T @ ca.DM([0.0, 0.0, up])
    h = ca.vertcat(ca.atan2(fa[1], fa[2]), ca.atan2(-fa[0], ca.sqrt(fa[1] ** 2 + fa[2] ** 2)))
    return ca.Function("tilt", [x], [h, ca.jacobian(h, x)])


def peer_measurement(f: Formulation, z: np.ndarray) -> tuple[Any, Any, Any, Any]:
    """``(z_eff, hx, H, residual)`` such that the library's residual r(z, x) equals
    ``residual(z_eff, hx(x))`` and ``H = d hx / dx``, for filterpy.

    ``paper``: roll and pitch from elementary rotations (:func:`_paper_tilt_fn`), the
    residual wrapped. ``bend``: the gravity direction
    ``g = R(a, b)^T up`` (from the rotation, not the tilt code), stereographically
    projected from ``-f(z)`` onto the tangent plane of the measured direction ``f(z)``:
    ``hx = 2 E^T g / (1 + f(z) . g)``, measured value 0.
    """
    nx = f.nx
    if f.name == "paper":
        tilt = _paper_tilt_fn(f.robot.mounting)

        def hx(x: np.ndarray) -> np.ndarray:
            return np.asarray(tilt(x)[0], dtype=float).ravel()

        def H(x: np.ndarray) -> np.ndarray:
            return np.asarray(tilt(x)[1], dtype=float).reshape(2, nx)

        return z, hx, H, lambda a, b: wrap_angle(np.subtract(a, b))
    gfn = _gravity_jacobian_fn(f.robot.mounting)
    f_z, E = tilt_tangent_basis(z)

    def hx_b(x: np.ndarray) -> np.ndarray:
        g = np.asarray(gfn(x)[0], dtype=float).ravel()
        return 2 * E.T @ g / (1 + f_z @ g)

    def H_b(x: np.ndarray) -> np.ndarray:  # chain rule through the projection
        g = np.asarray(gfn(x)[0], dtype=float).ravel()
        dg = np.asarray(gfn(x)[1], dtype=float).reshape(3, nx)
        c = 1 + f_z @ g
        dp = 2 * E.T / c - 2 * np.outer(E.T @ g, f_z) / c**2
        return dp @ dg

    return np.zeros(2), hx_b, H_b, np.subtract


def test_bend_residual_is_the_stereographic_projection_of_the_gravity_direction(paper3d) -> None:
    f = BendFormulation()
    rng = np.random.default_rng(3)
    for z in paper3d.z[::7]:
        x = np.array([*rng.uniform(-1.0, 1.0, 2), 0.0, 0.0])
        z_eff, hx, H, res = peer_measurement(f, z)
        r, Jr = (np.asarray(v, dtype=float) for v in f.functions.innovate(z, x))
        assert_allclose(r.ravel(), res(z_eff, hx(x)), atol=1e-12)
        assert_allclose(-Jr.reshape(2, 4), H(x), atol=1e-12)


def test_bend_residual_is_angle_difference_to_first_order() -> None:
    # small errors: r = (cos(pitch) d_roll, d_pitch) + O(d^2)
    f = BendFormulation()
    x = np.array([0.4, -0.7, 0.0, 0.0])
    z0 = np.asarray(f.functions.observe(x), dtype=float).ravel()
    d = np.array([1e-6, -2e-6])
    r = np.asarray(f.functions.innovate(z0 + d, x)[0], dtype=float).ravel()
    assert_allclose(r, [math.cos(z0[1]) * d[0], d[1]], rtol=1e-5)


# --- EKF vs filterpy -----------------------------------------------------------------------
def filterpy_ekf_states(f: Formulation, rec: Recording) -> np.ndarray:
    fns, nx = f.functions, f.nx

    def update(ekf: FilterpyEKF, z: np.ndarray) -> None:
        z_eff, hx, H, res = peer_measurement(f, z)
        ekf.update(z_eff, H, hx, residual=res)

    ekf = FilterpyEKF(dim_x=nx, dim_z=f.nz, dim_u=max(f.nu, 1))
    # first sample: prior from the measurement's inverse, then updated with it
    ekf.x = f.initial_state(rec.z[0])
    ekf.P = f.initial_cov()
    ekf.R = f.meas_cov()
    update(ekf, rec.z[0])
    states = [np.array(ekf.x, dtype=float).ravel()]
    z_prev = rec.z[0]
    for k in range(1, len(rec.t)):
        dt = float(rec.t[k] - rec.t[k - 1])
        u = f.inputs(z_prev, rec.z[k], dt)
        xn, F, Q = (np.asarray(v, dtype=float) for v in fns.predict(ekf.x, u, dt))
        ekf.F = F.reshape(nx, nx)
        ekf.Q = Q.reshape(nx, nx)
        ekf.predict_x = lambda u=0, xn=xn: setattr(ekf, "x", xn.ravel())  # f(x, u, dt)
        ekf.predict()
        update(ekf, rec.z[k])
        z_prev = rec.z[k]
        states.append(np.array(ekf.x, dtype=float).ravel())
    return np.array(states)


@pytest.mark.parametrize("mounting", MOUNTINGS)
@pytest.mark.parametrize("name", FORMULATIONS)
@pytest.mark.parametrize("compiled", [False, True])
def test_ekf_matches_filterpy(
    name: str, mounting: str, compiled: bool, paper3d, paper3d_down
) -> None:
    """The CasADi EKF and the compiled one (``ExtendedKalmanFilter``, the command
    line's) against filterpy's EKF on identical inputs."""
    from continuum_mhe.estimators import ExtendedKalmanFilter

    rec = recording_for(mounting, paper3d, paper3d_down)
    f = make_formulation(name, robot=RobotSettings(mounting=mounting))
    est = ExtendedKalmanFilter(f) if compiled else CasadiExtendedKalmanFilter(f)
    assert type(est).__name__ == (
        "ExtendedKalmanFilter" if compiled else "CasadiExtendedKalmanFilter"
    )
    ours = np.array([e.state for e in step_all(est, rec.t, rec.z)])
    assert_allclose(ours, filterpy_ekf_states(f, rec), rtol=0, atol=1e-9)


# --- UKF vs filterpy -----------------------------------------------------------------------
def filterpy_ukf_states(f: Formulation, rec: Recording) -> np.ndarray:
    fns, nx = f.functions, f.nx

    def fx(x: np.ndarray, dt: float, u: np.ndarray) -> np.ndarray:
        return np.asarray(fns.transition(x, u, dt), dtype=float).ravel()

    def update(ukf: FilterpyUKF, z: np.ndarray) -> None:
        z_eff, hx, _, res = peer_measurement(f, z)

        def z_mean(sigmas: np.ndarray, wm: np.ndarray) -> np.ndarray:
            # predicted measurement as the measurement minus the mean residual
            return z_eff - wm @ np.array([res(z_eff, s) for s in np.atleast_2d(sigmas)])

        def residual_z(a: np.ndarray, b: np.ndarray) -> np.ndarray:
            # differences of residuals taken against the measurement, as our UKF does
            return res(z_eff, b) - res(z_eff, a)

        ukf.residual_z, ukf.z_mean = residual_z, z_mean
        ukf.update(z_eff, hx=hx)

    points = MerweScaledSigmaPoints(nx, alpha=0.5, beta=2.0, kappa=0.0)
    ukf = FilterpyUKF(
        dim_x=nx,
        dim_z=f.nz,
        dt=float(rec.t[1] - rec.t[0]),
        hx=lambda x: x[:2],
        fx=fx,
        points=points,
    )
    ukf.x = f.initial_state(rec.z[0])
    ukf.P = f.initial_cov()
    ukf.R = f.meas_cov()
    ukf.sigmas_f = points.sigma_points(ukf.x, ukf.P)  # no predict before the first update
    update(ukf, rec.z[0])
    states = [ukf.x.copy()]
    z_prev = rec.z[0]
    for k in range(1, len(rec.t)):
        dt = float(rec.t[k] - rec.t[k - 1])
        u = f.inputs(z_prev, rec.z[k], dt)
        ukf.Q = np.asarray(fns.predict(ukf.x, u, dt)[2], dtype=float).reshape(nx, nx)
        ukf.predict(dt=dt, u=u)
        update(ukf, rec.z[k])
        z_prev = rec.z[k]
        states.append(ukf.x.copy())
    return np.array(states)


@pytest.mark.parametrize("mounting", MOUNTINGS)
@pytest.mark.parametrize("name", FORMULATIONS)
def test_ukf_matches_filterpy(name: str, mounting: str, paper3d, paper3d_down) -> None:
    rec = recording_for(mounting, paper3d, paper3d_down)
    f = make_formulation(name, robot=RobotSettings(mounting=mounting))
    ours = np.array([e.state for e in step_all(UnscentedKalmanFilter(f), rec.t, rec.z)])
    assert_allclose(ours, filterpy_ukf_states(f, rec), rtol=0, atol=1e-8)


def test_z_down_recording_exercises_the_angle_wrap(paper3d_down) -> None:
    # guards the z-down peer tests above: roll must actually cross +-pi
    roll = paper3d_down.z[:, 0]
    assert roll.min() < -3.0 and roll.max() > 3.0


# --- MHE vs an independent Opti formulation ---------------------------------------------------
def solve_bend_window_independently(
    f: BendFormulation, problem: WindowProblem, active: int
) -> np.ndarray:
    """The bend-formulation window NLP from scratch: returns the active nodes (k, 4)."""
    n = len(problem.zmask)
    off = n - active
    rinv = 1.0 / f.noise.measurement_std**2
    opti = ca.Opti()
    X = opti.variable(4, active)
    cost = 0
    for j in range(active):
        i = off + j
        a, b = X[0, j], X[1, j]
        if problem.zmask[i].all():
            # stereographic tilt residual, from the rotation and the measured direction
            f_z, E = tilt_tangent_basis(problem.z[i])
            up = 1.0 if f.robot.mounting == "z-up" else -1.0
            g = ca.mtimes(rotation_bend_sym(a, b).T, ca.DM([0.0, 0.0, up]))
            p = 2 * ca.mtimes(E.T, g) / (1 + ca.dot(ca.DM(f_z), g))
            cost += 0.5 * rinv * ca.sumsqr(p)
        if j > 0:
            dt = float(problem.dt[i - 1])
            prev = X[:, j - 1]
            pred = ca.vertcat(prev[0] + dt * prev[2], prev[1] + dt * prev[3], prev[2], prev[3])
            w = X[:, j] - pred
            cost += 0.5 * ca.bilin(np.linalg.inv(bend_process_cov(f.noise.bend_accel_psd, dt)), w)
        opti.subject_to(a**2 + b**2 <= f.robot.theta_max**2)
        theta, phi = shape_from_tilt(*problem.z[i], f.robot.mounting)  # own initial guess
        theta = min(float(theta), 0.95 * f.robot.theta_max)
        opti.set_initial(X[:, j], [theta * math.cos(phi), theta * math.sin(phi), 0.0, 0.0])
    e = X[:, 0] - problem.xbar
    cost += 0.5 * ca.bilin(problem.arrival[off], e)
    opti.minimize(cost)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "sb": "yes", "tol": 1e-10})
    sol = opti.solve()
    return np.asarray(sol.value(X), dtype=float).reshape(4, active).T


def run_mhe_and_compare_window(
    f: BendFormulation, rec: Recording, horizon: int, upto: int, solver: str = "ipopt",
    status: str = "ok",
):  # fmt: skip
    mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=horizon))
    mhe.reset()
    for k in range(upto + 1):
        est = mhe.step(Measurement(float(rec.t[k]), rec.z[k]))
    assert est.status == status
    active = min(upto + 1, horizon)
    ours = window_states(mhe)[-active:]
    peer = solve_bend_window_independently(f, mhe.inference.window_problem(), active)
    return est, ours, peer


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("upto", [6, 39], ids=["growing-window", "full-window"])
def test_mhe_matches_independent_opti_problem(upto: int, solver: str, paper3d) -> None:
    f = BendFormulation()
    est, ours, peer = run_mhe_and_compare_window(f, paper3d, 15, upto, solver)
    assert_allclose(ours, peer, rtol=0, atol=1e-6)
    assert_allclose(est.state, peer[-1], rtol=0, atol=1e-6)


@pytest.mark.parametrize("solver", SOLVERS)
def test_mhe_matches_independent_opti_problem_with_active_disk_bound(solver: str) -> None:
    rec = simulate("planar-overbend", duration=8.5)
    # from 5 s on (the MHE's time grows with the samples): the estimate starts 1.45 s
    # before the truth reaches pi/2 and ends on the bound with a full window
    rec = dataclasses.replace(rec, t=rec.t[100:], z=rec.z[100:], truth=rec.truth[100:])
    f = BendFormulation()
    upto = len(rec.t) - 1  # truth theta > pi/2 at the end
    assert upto + 1 > 15 and rec.truth[0, 3] < math.pi / 2 < rec.truth[-1, 3]
    # the estimate on the bound says so
    est, ours, peer = run_mhe_and_compare_window(f, rec, 15, upto, solver, "at-bound")
    assert_allclose(np.hypot(peer[-1, 0], peer[-1, 1]), math.pi / 2, atol=1e-6)  # bound active
    assert_allclose(ours, peer, rtol=0, atol=1e-6)


def test_mhe_window_process_weight_is_inverse_white_noise_acceleration_cov(paper3d) -> None:
    f = BendFormulation()
    mhe = MovingHorizonEstimator(f, ipopt_settings(horizon=8))
    step_all(mhe, paper3d.t[:8], paper3d.z[:8])
    problem = mhe.inference.window_problem()
    for dt, qinv in zip(problem.dt, problem.qinv):
        expected = np.linalg.inv(bend_process_cov(f.noise.bend_accel_psd, float(dt)))
        assert_allclose(qinv, expected, rtol=1e-9)


# --- linear Gaussian model: MHE == batch least squares == Kalman filter -----------------------
def batch_least_squares(f: LinearBend, z: np.ndarray) -> np.ndarray:
    """Dense weighted least squares over all states: prior on x0, process, measurements."""
    n = len(z)
    F = lin_transition(LIN_DT)
    Qi = np.linalg.inv(bend_process_cov(f.noise.bend_accel_psd, LIN_DT))
    Ri = np.linalg.inv(f.meas_cov())
    P0i = np.linalg.inv(f.initial_cov())
    xbar = np.array([z[0, 0], z[0, 1], 0.0, 0.0])
    # stack residual blocks r = A X - c with weights W; solve (A^T W A) X = A^T W c
    rows, rhs, weights = [], [], []
    sel = np.zeros((4, 4 * n))
    sel[:, :4] = np.eye(4)
    rows.append(sel)
    rhs.append(xbar)
    weights.append(P0i)
    for k in range(n):
        a = np.zeros((2, 4 * n))
        a[:, 4 * k : 4 * k + 4] = LIN_H
        rows.append(a)
        rhs.append(z[k])
        weights.append(Ri)
        if k < n - 1:
            a = np.zeros((4, 4 * n))
            a[:, 4 * k + 4 : 4 * k + 8] = np.eye(4)
            a[:, 4 * k : 4 * k + 4] = -F
            rows.append(a)
            rhs.append(np.zeros(4))
            weights.append(Qi)
    A = np.vstack(rows)
    c = np.concatenate(rhs)
    W = np.zeros((len(c), len(c)))
    i = 0
    for w in weights:
        W[i : i + len(w), i : i + len(w)] = w
        i += len(w)
    return np.linalg.solve(A.T @ W @ A, A.T @ W @ c).reshape(n, 4)


def kalman_filter_with_prior(f: LinearBend, z: np.ndarray) -> np.ndarray:
    """Textbook KF from the prior (xbar, P0), updating on every sample including the first."""
    F, Q, R = lin_transition(LIN_DT), bend_process_cov(f.noise.bend_accel_psd, LIN_DT), f.meas_cov()
    x, P = np.array([z[0, 0], z[0, 1], 0.0, 0.0]), f.initial_cov()
    for k in range(len(z)):
        if k > 0:
            x, P = F @ x, F @ P @ F.T + Q
        S = LIN_H @ P @ LIN_H.T + R
        K = P @ LIN_H.T @ np.linalg.inv(S)
        x, P = x + K @ (z[k] - LIN_H @ x), (np.eye(4) - K @ LIN_H) @ P
    return x


@pytest.fixture(scope="module")
def full_horizon_mhe(linear_recording) -> Callable[[str], tuple[list, np.ndarray]]:
    """``run(solver)``: (estimates, last window) of the MHE whose window holds all of
    ``linear_recording`` (it only grows), computed once for the module."""
    f, t, z = linear_recording

    @functools.cache
    def run(solver: str) -> tuple[list, np.ndarray]:
        mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=LIN_N + 5))
        estimates = step_all(mhe, t, z)
        return estimates, window_states(mhe)[-len(z) :]

    return run


@pytest.mark.parametrize("solver", SOLVERS)
def test_linear_full_horizon_mhe_equals_batch_least_squares(
    linear_recording, full_horizon_mhe, solver
) -> None:
    f, t, z = linear_recording
    estimates, window = full_horizon_mhe(solver)
    assert_ok_after_the_start([e.status for e in estimates])
    assert_allclose(window, batch_least_squares(f, z), rtol=0, atol=1e-8)


def test_linear_mhe_last_node_equals_kalman_filter_with_same_prior(
    linear_recording, full_horizon_mhe
) -> None:
    f, t, z = linear_recording
    estimates, _ = full_horizon_mhe("ipopt")
    assert_allclose(estimates[-1].state, kalman_filter_with_prior(f, z), rtol=0, atol=1e-8)


@pytest.mark.parametrize("filter_cls", [CasadiExtendedKalmanFilter, UnscentedKalmanFilter])
def test_linear_mhe_last_node_equals_library_filter(
    linear_recording, full_horizon_mhe, filter_cls
) -> None:
    f, t, z = linear_recording
    estimates, _ = full_horizon_mhe("ipopt")
    filtered = step_all(filter_cls(f), t, z)
    assert_allclose(estimates[-1].state, filtered[-1].state, rtol=0, atol=1e-8)


# --- bounds --------------------------------------------------------------------------------
#: The window of the bound, straight-configuration and dropout tests below: what they check
#: does not depend on its length, and the IPOPT MHE's time grows with it.
HORIZON = 10


@pytest.fixture(scope="module")
def overbend() -> Recording:
    return simulate("planar-overbend", duration=10)


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("name", FORMULATIONS)
def test_mhe_never_exceeds_theta_max(name: str, solver: str, overbend) -> None:
    # from 3 s on (the truth at 0.45 rad; the IPOPT MHE's time grows with the samples)
    rec = dataclasses.replace(
        overbend, t=overbend.t[60:], z=overbend.z[60:], truth=overbend.truth[60:]
    )
    assert rec.truth[:, 3].max() > 2.0  # the truth goes well past pi/2
    f = make_formulation(name)
    mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=HORIZON))
    series = mhe.run(rec.t, rec.z)
    assert series.output[0, 3] < 1.0  # the estimate starts well below the bound
    assert np.all(np.isfinite(series.output))
    # IPOPT's default bound relaxation (1e-8 relative) allows ~1.6e-8 rad
    assert series.output[:, 3].max() <= f.robot.theta_max + 1e-7
    late = rec.t > 7.0  # truth beyond the bound: the estimate sits on it
    assert_allclose(series.output[late, 3], f.robot.theta_max, rtol=0, atol=1e-3)


@pytest.mark.parametrize("solver", SOLVERS)
def test_mhe_with_larger_theta_max_tracks_further_bending(solver: str, overbend) -> None:
    f = make_formulation("bend", robot=RobotSettings(theta_max=3.0))
    mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=HORIZON))
    series = mhe.run(overbend.t, overbend.z)
    assert series.output[:, 3].max() > 2.0
    assert series.output[:, 3].max() <= 3.0 + 1e-7
    err = np.abs(series.output[:, 3] - overbend.truth[:, 3])
    unfiltered = np.abs(reading_by_reading(overbend.z)[:, 0] - overbend.truth[:, 3])
    assert np.mean(err) < 0.8 * np.mean(unfiltered)  # 0.66 of it; a bound-clipped 1.0+


# --- straight configuration -----------------------------------------------------------------
@pytest.fixture(scope="module")
def straight() -> Recording:
    return simulate("straight", duration=10)


def make_estimator(kind: str, f: Formulation) -> Estimator:
    if kind == "mhe":
        return MovingHorizonEstimator(f, MHESettings(horizon=HORIZON))
    if kind == "mhe-ipopt":
        return MovingHorizonEstimator(f, ipopt_settings(horizon=HORIZON))
    return {"ekf": CasadiExtendedKalmanFilter, "ukf": UnscentedKalmanFilter}[kind](f)


ESTIMATORS = ("ekf", "ukf", "mhe", "mhe-ipopt")
# a successful sample with the default MHE backend (a fast backend may hand over to IPOPT)
SOLVED = ["ok", "fallback-ipopt"]


def solved(name: str) -> list[str]:
    """Statuses of a solved sample: the paper formulation's may be ``drifted`` (its
    separate position state away from its own angles' kinematics), ``at-bound`` (its
    phi held on the state bound -pi or pi, which its MHE cannot wrap past: paper3d's
    bending plane turns to 3.06 rad) or ``uncertain`` (its weight ``W`` makes its
    position's standard deviation grow past the robot's length)."""
    return SOLVED + (["drifted", "at-bound", "uncertain"] if name == "paper" else [])


def started(name: str) -> str:
    """The status of a start's first row: ``uncertain`` (one reading's fit, which a
    later reading confirms), but ``ok`` with the paper formulation (no consistency
    check)."""
    return "ok" if name == "paper" else "uncertain"


@pytest.fixture(scope="module")
def straight_run(straight) -> Callable[[str, str], EstimateSeries]:
    """``run(name, kind)``: estimator ``kind`` on formulation ``name`` over the
    ``straight`` recording, computed once for the module (several tests read one run)."""

    @functools.cache
    def run(name: str, kind: str) -> EstimateSeries:
        return make_estimator(kind, make_formulation(name)).run(straight.t, straight.z)

    return run


@pytest.mark.parametrize("kind", ESTIMATORS)
@pytest.mark.parametrize("name", FORMULATIONS)
def test_straight_configuration_gives_finite_estimates(
    name: str, kind: str, straight, straight_run
) -> None:
    # the recording passes through straight after its start (at 5 s and 10 s)
    assert straight.truth[len(straight.t) // 4 :, 3].min() < 1e-2
    series = straight_run(name, kind)
    assert np.all(np.isfinite(series.output))
    # the paper formulation's separate position may drift from its angles: flagged
    assert series.status[0] == started(name)
    assert np.all(np.isin(series.status[1:], solved(name)))


@pytest.mark.parametrize("kind", ESTIMATORS)
def test_straight_configuration_tip_error_is_small_for_bend(
    kind: str, straight, straight_run
) -> None:
    series = straight_run("bend", kind)
    err = np.linalg.norm(series.output[:, :3] - straight.truth[:, :3], axis=1)
    assert err.mean() < 0.02 * straight.length


# --- position consistency (bend formulation) ---------------------------------------------------
@pytest.mark.parametrize("kind", ESTIMATORS)
def test_bend_output_position_equals_kinematics_of_its_own_shape(kind: str, straight_run) -> None:
    f = make_formulation("bend")
    series = straight_run("bend", kind)
    theta, phi = series.output[:, 3], series.output[:, 4]
    # the arc's tip in closed form: (L / theta) (cos phi (cos theta - 1), sin phi (cos
    # theta - 1), sin theta), written with sinc so that theta = 0 is the straight rod
    length = f.robot.length
    bow = -length * np.sin(theta / 2) * np.sinc(theta / (2 * np.pi))  # L (cos t - 1) / t
    arc = np.column_stack([bow * np.cos(phi), bow * np.sin(phi), length * np.sinc(theta / np.pi)])
    assert_allclose(series.output[:, :3], arc, rtol=0, atol=1e-12)


# --- solver failures ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", FORMULATIONS)
def test_mhe_iteration_limit_is_flagged_and_finite(name: str, paper3d) -> None:
    f = make_formulation(name)
    series = MovingHorizonEstimator(f, ipopt_settings(horizon=10, max_iter=1)).run(
        paper3d.t[:25], paper3d.z[:25]
    )
    assert np.all(np.isfinite(series.output))
    assert set(series.status) <= {"not-converged", "solver-failed"}
    assert np.all(series.output[:, 3] <= f.robot.theta_max + 1e-6)


class FlakySolver:
    """Wraps a CasADi nlpsol: raises or returns NaN on chosen calls, else delegates."""

    def __init__(self, solver: ca.Function, raise_on: set[int], nan_on: set[int]) -> None:
        self.solver, self.raise_on, self.nan_on, self.calls = solver, raise_on, nan_on, 0

    def __call__(self, **kwargs: Any) -> dict:
        k = self.calls
        self.calls += 1
        if k in self.raise_on:
            raise RuntimeError("injected IPOPT failure")
        sol = self.solver(**kwargs)
        if k in self.nan_on:
            sol = dict(sol)
            sol["x"] = sol["x"] * np.nan
        return sol

    def stats(self) -> dict:
        return self.solver.stats()


@pytest.fixture(scope="module")
def injected_failures(paper3d) -> Callable[[str], tuple[list, list]]:
    """``run(name)``: (estimates of the IPOPT MHE on formulation ``name`` over the first
    40 samples of ``paper3d`` with IPOPT failing at samples 12-14, estimates of a clean
    run), computed once for the module."""
    rec, n = paper3d, 40

    @functools.cache
    def run(name: str) -> tuple[list, list]:
        f = make_formulation(name)
        clean = step_all(
            MovingHorizonEstimator(f, ipopt_settings(horizon=10)), rec.t[:n], rec.z[:n]
        )
        mhe = MovingHorizonEstimator(f, ipopt_settings(horizon=10))
        mhe.inference._nlp = dataclasses.replace(
            mhe.inference._nlp,
            solver=FlakySolver(mhe.inference._nlp.solver, raise_on={12, 13}, nan_on={14}),
        )
        return step_all(mhe, rec.t[:n], rec.z[:n]), clean

    return run


FAILING = [12, 13, 14]


@pytest.mark.parametrize("name", FORMULATIONS)
def test_mhe_injected_solver_failures_are_flagged_and_finite(name: str, injected_failures) -> None:
    estimates, _ = injected_failures(name)
    status = np.array([e.status for e in estimates])
    assert np.all(np.isfinite([e.output for e in estimates]))
    assert list(status[FAILING]) == ["solver-failed"] * 3
    assert status[0] == started(name)
    assert np.all(np.isin(np.delete(status, FAILING)[1:], ["ok", *solved(name)[2:]]))


@pytest.mark.parametrize("name", FORMULATIONS)
def test_mhe_shape_recovers_after_injected_solver_failures(name: str, injected_failures) -> None:
    estimates, clean = injected_failures(name)
    later = slice(FAILING[-1] + 10, 40)  # once the failed samples have left the window
    out = np.array([e.output for e in estimates])[later]
    ref = np.array([e.output for e in clean])[later]
    assert_allclose(out[:, 3], ref[:, 3], rtol=0, atol=1e-6)
    assert_allclose(wrap_angle(out[:, 4] - ref[:, 4]), 0.0, rtol=0, atol=1e-6)


def test_mhe_bend_position_recovers_after_injected_solver_failures(injected_failures) -> None:
    # (the paper formulation's x, y, z are unobservable integrator states: an offset
    # left by a failure persists, so only the bend formulation is checked here)
    estimates, clean = injected_failures("bend")
    later = slice(FAILING[-1] + 10, 40)
    out = np.array([e.output for e in estimates])[later]
    ref = np.array([e.output for e in clean])[later]
    assert_allclose(out[:, :3], ref[:, :3], rtol=0, atol=1e-6)  # metres


@pytest.mark.parametrize("name", FORMULATIONS)
def test_mhe_survives_wildly_inconsistent_measurements(name: str, paper3d) -> None:
    z = paper3d.z[:40].copy()
    z[10:14] = [[3.0, -1.5], [-3.0, 1.5], [2.0, 1.4], [-2.5, -1.4]]  # garbage burst
    f = make_formulation(name)
    series = MovingHorizonEstimator(f, ipopt_settings(horizon=10)).run(paper3d.t[:40], z)
    assert np.all(np.isfinite(series.output))
    assert np.all(series.output[:, 3] <= f.robot.theta_max + 1e-6)
    # recovers once the burst leaves the window
    assert np.all(np.isin(series.status[-10:], ["ok", *solved(name)[2:]]))


# --- dropouts ---------------------------------------------------------------------------------
DROPOUTS = [5, 6, 7, 20, 33]


@pytest.mark.parametrize("kind", ESTIMATORS)
@pytest.mark.parametrize("name", FORMULATIONS)
def test_dropouts_are_flagged_and_finite(name: str, kind: str, paper3d) -> None:
    z = paper3d.z[:40].copy()
    z[DROPOUTS] = np.nan
    z[25, 1] = np.nan  # a partial reading is a dropout too
    series = make_estimator(kind, make_formulation(name)).run(paper3d.t[:40], z)
    dropped = np.zeros(40, dtype=bool)
    dropped[[*DROPOUTS, 25]] = True
    assert np.all(series.status[dropped] == "dropout")
    assert series.status[0] == started(name)
    assert np.all(np.isin(series.status[~dropped][1:], solved(name)))
    assert np.all(np.isfinite(series.output))


@pytest.mark.parametrize("kind", ESTIMATORS)
def test_leading_dropouts_give_no_estimate_then_start(kind: str, paper3d) -> None:
    z = paper3d.z[:15].copy()
    z[:3] = np.nan
    series = make_estimator(kind, make_formulation("bend")).run(paper3d.t[:15], z)
    assert list(series.status[:3]) == ["no-estimate"] * 3
    assert np.all(np.isnan(series.output[:3]))
    assert series.status[3] == "uncertain"  # the start, from the first reading
    assert np.all(np.isin(series.status[4:], SOLVED))
    assert np.all(np.isfinite(series.output[3:]))


@pytest.mark.parametrize(
    "cls", [CasadiExtendedKalmanFilter, UnscentedKalmanFilter, MovingHorizonEstimator]
)
def test_non_increasing_time_is_a_clear_error(cls) -> None:
    est = cls(BendFormulation())
    z = np.array([0.1, 0.2])
    est.step(Measurement(0.0, z))
    est.step(Measurement(0.05, z))
    for bad in (0.05, 0.01, math.nan):
        with pytest.raises(ValueError, match="must be finite and later than the previous"):
            est.step(Measurement(bad, z))
    assert est.step(Measurement(0.1, z)).status == "ok"  # the estimator is still usable
    est.reset()
    # a reset starts a new time axis (and a start, unconfirmed)
    assert est.step(Measurement(0.0, z)).status == "uncertain"
    with pytest.raises(ValueError, match=r"must have shape \(2,\)"):
        est.step(Measurement(1.0, np.array([0.1, 0.2, 0.3])))


def _overbend_in_xz_plane() -> Recording:
    """Planar bending in the base x-z plane (phi = 0): pitch passes -90 deg (gimbal
    lock) when theta crosses pi/2, and roll jumps to +-pi beyond it."""
    from continuum_mhe.model.imu import tilt

    t = np.arange(301) * 0.05
    theta = 1.1 * (1 - np.cos(np.pi * t / 10.0))
    phi = np.zeros_like(t)
    truth = np.column_stack([tip_position(theta, phi, 0.2), theta, phi])
    z = wrap_angle(tilt(theta, phi) + np.random.default_rng(0).normal(size=(301, 2)) * 0.035)
    return Recording(t=t, z=z, truth=truth, length=0.2)


@pytest.mark.parametrize("solver", ["fast", "ipopt"])
def test_mhe_converges_through_gimbal_lock_and_tracks_beyond(solver: str) -> None:
    rec = _overbend_in_xz_plane()
    f = BendFormulation(robot=RobotSettings(theta_max=3.0))
    # a window of 10 (HORIZON below), not the default 30: its mean tip error is the
    # longer window's to 0.01 %, and the IPOPT MHE's time grows with the window
    s = MovingHorizonEstimator(f, solver_settings(solver, horizon=10)).run(rec.t, rec.z)
    assert_ok_after_the_start(s.status)
    tip = np.linalg.norm(s.output[:, :3] - rec.truth[:, :3], axis=1)
    assert tip.mean() < 0.015 * 0.2 and tip.max() < 0.06 * 0.2
    assert s.output[:, 3].max() > 2.0


def test_mhe_holds_the_bound_at_gimbal_lock() -> None:
    rec = _overbend_in_xz_plane()
    s = MovingHorizonEstimator(BendFormulation()).run(rec.t, rec.z)
    # the truth bends past the bound: the rows the bound holds say so, and where the
    # readings then disagree with the held shape, they say that
    assert_ok_after_the_start(
        s.status, frozenset({"ok", "fallback-ipopt", "at-bound", "inconsistent"})
    )
    assert "at-bound" in set(s.status)
    assert not np.any((s.output[:, 3] > math.pi / 2 - 1e-3) & (s.status == "ok"))
    assert s.output[:, 3].max() <= math.pi / 2 + 1e-9


@pytest.mark.parametrize("solver", ["fast", "ipopt"])
def test_linear_sliding_window_mhe_equals_kalman_filter_at_every_sample(
    linear_recording, solver: str
) -> None:
    """Once the window slides, the arrival prior carries exactly the samples that left
    it (no double counting): the MHE's estimate equals the filter's at every sample."""
    f, t, z = linear_recording
    settings = ipopt_settings(horizon=4) if solver == "ipopt" else MHESettings(horizon=4)
    mhe = step_all(MovingHorizonEstimator(f, settings), t, z)
    kf = step_all(CasadiExtendedKalmanFilter(f), t, z)
    assert len(t) > 3 * 4
    assert_allclose([e.state for e in mhe], [e.state for e in kf], rtol=0, atol=1e-7)


def test_bend_tilt_cost_grows_monotonically_with_the_tilt_error() -> None:
    """No spurious minimum: the residual's norm is 2 tan(alpha/2) for a tilt error alpha,
    up to (and beyond) the antipode of the measured gravity direction."""
    f = BendFormulation(robot=RobotSettings(theta_max=3.0))
    z = np.asarray(f.functions.observe(np.array([0.9, 0.0, 0.0, 0.0])), dtype=float).ravel()
    alphas = np.linspace(0.0, 3.0, 61)  # bend further in the same plane: error = alpha
    norms = [
        np.linalg.norm(np.asarray(f.functions.innovate(z, [0.9 + a, 0.0, 0, 0])[0])) for a in alphas
    ]
    assert_allclose(norms, 2 * np.tan(alphas / 2), rtol=1e-9, atol=1e-12)


def test_mhe_recovers_after_a_long_gap_in_the_data() -> None:
    rec = simulate("paper3d", seed=0)
    keep = (rec.t < 5) | (rec.t >= 15)  # a 10 s gap
    s = MovingHorizonEstimator(BendFormulation()).run(rec.t[keep], rec.z[keep])
    tip = np.linalg.norm(s.output[:, :3] - rec.truth[keep, :3], axis=1)
    unfiltered = np.linalg.norm(
        reading_by_reading(rec.z[keep])[:, 2:] - rec.truth[keep, :3], axis=1
    )
    after = rec.t[keep] >= 15  # filtering again after the gap: 0.59 of the readings' error
    assert tip[after].mean() < 0.8 * unfiltered[after].mean()


@pytest.mark.parametrize(
    "cls", [CasadiExtendedKalmanFilter, UnscentedKalmanFilter, MovingHorizonEstimator]
)
def test_list_measurements_and_mismatched_lengths(cls, paper3d) -> None:
    est = cls(BendFormulation())
    assert est.step(Measurement(0.0, [0.1, 0.1])).status == "uncertain"  # a list is fine
    with pytest.raises(ValueError, match="t has 5 samples but z has 4"):
        est.run(paper3d.t[:5], paper3d.z[:4])


@pytest.mark.parametrize("gap", [1e-9, 1e-7, 1e-6])
def test_two_samples_microseconds_apart_leave_every_window_solved(gap: float, paper3d) -> None:
    """A sample stamped ``gap`` s after the one before (a logger's near-duplicate time):
    its process noise is that of a 10 us step, so the MHE's process weights (``Q^-1``,
    of order ``1 / dt^3``) stay within its window's conditioning. Every window is
    solved (no ``not-converged``, no IPOPT fallback), and the estimates are the EKF's
    to the MHE's own accuracy."""
    t = np.insert(paper3d.t[:80], 11, paper3d.t[10] + gap)
    z = np.insert(paper3d.z[:80], 11, paper3d.z[10], axis=0)
    truth = np.insert(paper3d.truth[:80], 11, paper3d.truth[10], axis=0)
    f = make_formulation("bend")
    mhe = MovingHorizonEstimator(f).run(t, z)
    assert_ok_after_the_start(mhe.status)
    tip = np.linalg.norm(mhe.output[:, :3] - truth[:, :3], axis=1)
    ekf = make_estimator("ekf", f).run(t, z)
    ekf_tip = np.linalg.norm(ekf.output[:, :3] - truth[:, :3], axis=1)
    assert tip.max() < 1.5 * ekf_tip.max()


def test_an_estimate_series_has_a_length_statuses_and_row_subsets() -> None:
    """``len``, ``statuses()`` (Status values) and ``rows()`` (a mask, a slice or
    indices) of a run's series: the rows after the first second are those
    ``evaluate --skip-start 1`` scores, each column cut alike."""
    from continuum_mhe import Status
    from continuum_mhe.errors import UserError

    rec = simulate("paper3d", duration=2.0, seed=0)
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    assert len(series) == len(rec.t) == 41
    statuses = series.statuses()
    assert statuses[0] is Status.UNCERTAIN and all(isinstance(s, Status) for s in statuses)
    late = series.rows(series.t >= 1.0)
    assert len(late) == 21 and late.t[0] == 1.0
    np.testing.assert_array_equal(late.output, series.output[20:])
    np.testing.assert_array_equal(late.std, series.std[20:])
    assert list(late.status) == list(series.status[20:]) and late.names == series.names
    np.testing.assert_array_equal(series.rows(slice(20, None)).output, late.output)
    np.testing.assert_array_equal(series.rows(np.arange(20, 41)).solve_ms, late.solve_ms)
    with pytest.raises(UserError, match="one per sample"):
        series.rows(np.ones(3, dtype=bool))


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_a_paper_estimate_held_on_phis_bound_is_at_bound(method: str) -> None:
    """The paper formulation's phi is a state bounded by -pi and pi, which the MHE's box
    cannot wrap: where the bending plane turns past it (``straight``, seed 1) the MHE
    holds phi on the bound, 58 rows with a zero std_phi, up to 0.36 rad off, that must
    not be ``ok``: such rows are ``at-bound``, in every estimator; no bent ``ok`` row has a
    zero standard deviation, and at most one is 0.3 rad off in phi."""
    from continuum_mhe import make_estimator, make_formulation

    rec = simulate("straight", duration=10.0, seed=1)
    s = make_estimator(method, make_formulation("paper")).run(rec.t, rec.z)
    ok = s.status == "ok"
    bent = s.output[:, 3] > 0.1  # (nearly straight, phi hardly moves the shape)
    on_bound = np.abs(s.output[:, 4]) >= math.pi - 1e-3
    assert not np.any(ok & bent & on_bound)
    assert not np.any(ok & bent & (s.std[:, 4] == 0))
    off = np.abs(np.angle(np.exp(1j * (s.output[:, 4] - rec.truth[:, 4])))) > 0.3
    assert np.sum(ok & off & (rec.truth[:, 3] > 0.3)) <= 1
    if method == "mhe":
        assert np.sum(s.status == "at-bound") > 40
