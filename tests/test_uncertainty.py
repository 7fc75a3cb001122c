"""Uncertainty and recovery: covariances against known answers, std columns, calibration,
gap reset, frozen sensors and the ``uncertain`` status.

* On a linear Gaussian model the MHE's covariance (last block of the window Hessian's
  inverse) equals the Kalman filter's ``P`` at every sample, and with the full horizon
  the last block of the dense batch covariance.
* The filters' output standard deviations equal ``sqrt(diag(J P J^T))`` with ``J`` from
  central finite differences of the outputs (independent of the CasADi Jacobian).
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
from estimator_helpers import (
    LIN_DT,
    LIN_H,
    LIN_N,
    SOLVERS,
    LinearBend,
    bare,
    bend_process_cov,
    fast_windows,
    lin_transition,
    recovery_estimators,
    solver_settings,
    step_all,
)
from numpy.testing import assert_allclose

from continuum_mhe.cli import main
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.branch import BranchStats
from continuum_mhe.estimators.fast.model import NodeEvaluator, node_functions
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, UnscentedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.evaluation.metrics import Z95, compute_calibration, nees_band
from continuum_mhe.io.estimate_csv import write_estimates
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.pcc import free_sections
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.results import Diagnostics, Estimate, EstimateSeries, Measurement, Status
from continuum_mhe.settings import (
    FREEZE_MIN_SAMPLES,
    FREEZE_S,
    FREEZE_TOLERANCE,
    SILENT_AFTER,
    MHESettings,
    NoiseSettings,
    RecoverySettings,
    RobotSettings,
)
from continuum_mhe.simulation.scenarios import simulate


def kalman_covariances(f: LinearBend, n: int) -> list[np.ndarray]:
    """Textbook KF covariances from ``P0``, updating on every sample (z does not matter)."""
    F, Q, R = lin_transition(LIN_DT), bend_process_cov(f.noise.bend_accel_psd, LIN_DT), f.meas_cov()
    P, out = f.initial_cov(), []
    for k in range(n):
        if k:
            P = F @ P @ F.T + Q
        S = LIN_H @ P @ LIN_H.T + R
        K = P @ LIN_H.T @ np.linalg.inv(S)
        P = (np.eye(4) - K @ LIN_H) @ P
        out.append(P)
    return out


def batch_covariance(f: LinearBend, n: int) -> np.ndarray:
    """Dense inverse of the batch information matrix over n states (4n x 4n)."""
    F, Qi = lin_transition(LIN_DT), np.linalg.inv(bend_process_cov(f.noise.bend_accel_psd, LIN_DT))
    Ri, P0i = np.linalg.inv(f.meas_cov()), np.linalg.inv(f.initial_cov())
    info = np.zeros((4 * n, 4 * n))
    info[:4, :4] += P0i
    for k in range(n):
        s = slice(4 * k, 4 * k + 4)
        info[s, s] += LIN_H.T @ Ri @ LIN_H
        if k < n - 1:
            A = np.zeros((4, 4 * n))  # x_{k+1} - F x_k
            A[:, 4 * k : 4 * k + 4] = -F
            A[:, 4 * k + 4 : 4 * k + 8] = np.eye(4)
            info += A.T @ Qi @ A
    return np.linalg.inv(info)


@pytest.mark.parametrize("solver", SOLVERS)
def test_linear_mhe_covariance_equals_kalman_p_at_every_sample(linear_recording, solver) -> None:
    f, t, z = linear_recording
    mhe = step_all(MovingHorizonEstimator(f, solver_settings(solver, horizon=4)), t, z)
    kf = kalman_covariances(f, len(t))
    assert len(t) > 3 * 4  # the window slides
    for e, P in zip(mhe, kf):
        assert_allclose(e.covariance, P, rtol=1e-7, atol=1e-12)
    ekf = step_all(CasadiExtendedKalmanFilter(f), t, z)
    assert_allclose(ekf[-1].covariance, kf[-1], rtol=1e-9, atol=1e-14)


@pytest.mark.parametrize("solver", SOLVERS)
def test_full_horizon_mhe_covariance_equals_batch_covariance(linear_recording, solver) -> None:
    f, t, z = linear_recording
    mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=LIN_N + 5))
    last = step_all(mhe, t, z)[-1]
    assert_allclose(last.covariance, batch_covariance(f, LIN_N)[-4:, -4:], rtol=1e-7, atol=1e-12)


def fd_output_jacobian(f: BendFormulation, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    cols = []
    for j in range(len(x)):
        d = np.zeros(len(x))
        d[j] = h
        cols.append((f.output(x + d) - f.output(x - d)) / (2 * h))
    return np.array(cols).T


def sigma_point_std(f: BendFormulation, x: np.ndarray, P: np.ndarray) -> np.ndarray:
    """The outputs' root mean square change over the sigma points ``x +- sqrt(2) L e_j``,
    ``L = cholesky(P[:2, :2])`` on a one-section robot's bend ``(a, b)`` (numpy's
    Cholesky; phi's differences wrapped)."""
    L = np.linalg.cholesky(P[:2, :2])
    y0 = f.output(x)
    diffs = []
    for j in range(2):
        for sign in (1.0, -1.0):
            p = x.copy()
            p[:2] += sign * math.sqrt(2.0) * L[:, j]
            d = f.output(p) - y0
            d[4] = (d[4] + math.pi) % (2 * math.pi) - math.pi
            diffs.append(d)
    return np.sqrt(np.mean(np.square(diffs), axis=0))


@pytest.mark.parametrize("cls", [CasadiExtendedKalmanFilter, UnscentedKalmanFilter])
def test_filter_output_std_is_the_propagated_covariance(cls) -> None:
    """With no constant reading error nor model error (``reading_bias_std`` and
    ``model_error_std`` 0) the std is the covariance through the outputs at its sigma
    points (on the bend, the states the outputs depend on), and, on a bent robot, within
    a few percent of the covariance through the output Jacobian (finite differences)."""
    rec = simulate("paper3d", duration=3)
    f = BendFormulation(noise=NoiseSettings(reading_bias_std=0.0, model_error_std=0.0))
    assert f.sigma_states == (0, 1)
    est = step_all(cls(f), rec.t, rec.z)
    checked = 0
    for e in est[5:]:
        assert_allclose(e.output_std, sigma_point_std(f, e.state, e.covariance), rtol=1e-9)
        if abs(e.output[4]) > 3.0 or e.output[3] < 0.3:  # phi near the wrap; nearly straight
            continue
        J = fd_output_jacobian(f, e.state)
        linear = np.sqrt(np.diag(J @ e.covariance @ J.T))
        assert_allclose(e.output_std[:3], linear[:3], rtol=0.05)
        checked += 1
    assert checked > 20


def test_a_straight_sections_end_has_the_spread_of_its_curvature() -> None:
    """Known answers at the straight pose, where the outputs' first derivatives in the
    bend's magnitude vanish: with ``P = sigma^2 I`` on the bend the sigma points lie at
    ``sqrt(2) sigma`` from straight, so the tip's ``z`` (``L sin(t) / t`` at bend ``t``)
    has the standard deviation ``L (1 - sin(t) / t)`` with ``t = sqrt(2) sigma`` (a
    linearised one is 0), ``theta`` exactly ``t``; with the variance along one direction
    ``n`` alone (rank one, a state held at a bound) half the points stay at the estimate
    and ``z``'s is that over ``sqrt(2)``. The compiled node (the EKF's and the fast
    MHE's) and the formulation (IPOPT's, the UKF's) give the same."""
    f = BendFormulation()
    node = NodeEvaluator(node_functions(f))
    sigma = 0.05
    t = math.sqrt(2.0) * sigma
    x = np.zeros(f.nx)
    full = np.diag([sigma**2, sigma**2, 1.0, 1.0])
    n = np.array([0.6, 0.8])
    rank_one = np.zeros((f.nx, f.nx))
    rank_one[:2, :2] = sigma**2 * np.outer(n, n)
    length = f.robot.length
    for std in (node.output_std(x, full), f.output_std(x, full)):
        assert std[2] == pytest.approx(length * (1.0 - math.sin(t) / t), rel=1e-12)
        assert std[3] == pytest.approx(t, rel=1e-12)
        assert std[0] == pytest.approx(length * (1.0 - math.cos(t)) / t / math.sqrt(2), rel=1e-9)
    for std in (node.output_std(x, rank_one), f.output_std(x, rank_one)):
        assert std[2] == pytest.approx(length * (1.0 - math.sin(t) / t) / math.sqrt(2), rel=1e-9)


def test_nearly_straight_rows_at_1_hz_are_not_ok_far_outside_their_std() -> None:
    """``paper3d`` sampled at 1 Hz (seed 0), the EKF with its defaults: a nearly straight
    estimate (0.004 rad of bend) whose ``z`` is 0.065 mm off has a linearised ``std_z``
    of 0.01 mm (4.5 of them, ``ok``). With the outputs' curvature in their standard
    deviations no ``ok`` row is 4 of its standard deviations off on a tip axis."""
    rec = simulate("paper3d", duration=120, dt=1.0, seed=0)
    series = make_estimator("ekf", BendFormulation()).run(rec.t, rec.z)
    ok = np.asarray(series.status) == "ok"
    assert ok.sum() >= 10
    off = np.abs(series.output[:, :3] - rec.truth[:, :3]) / series.output_std[:, :3]
    assert np.max(off[ok]) < 4.0


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_output_std_carries_the_readings_constant_errors(method: str) -> None:
    """With the default ``reading_bias_std`` and ``model_error_std`` the output
    standard deviations are those of the covariance and of the estimate's least-squares
    sensitivity to a constant reading error, ``A B A^T``, added in quadrature, with
    ``A = (H^T R^-1 H + G)^+ H^T R^-1``, ``G`` the bends' range as information
    (``1 / theta_max^2`` on both bend coordinates)
    (``H`` by finite differences of the residual: one IMU, two readings, two bends,
    two rates) and ``B`` both variances (the readings show no model error larger than
    the floor on this recording, which the model generated)."""
    rec = simulate("paper3d", duration=3)
    f = BendFormulation()
    est = step_all(make_estimator(method, f), rec.t, rec.z)  # type: ignore[arg-type]
    noise = f.noise
    R = f.meas_cov()
    B = np.eye(f.nz) * (noise.reading_bias_std**2 + noise.model_error_std**2)
    checked = 0
    for e, z in zip(est[10:], rec.z[10:]):
        if abs(e.output[4]) > 3.0:  # phi near the wrap: finite differences would jump
            continue
        x = e.state
        H = np.column_stack(
            [
                np.asarray(
                    f.functions.innovate(z, x + 1e-7 * d)[0]
                    - f.functions.innovate(z, x - 1e-7 * d)[0],
                    dtype=float,
                ).ravel()
                / 2e-7
                for d in np.eye(f.nx)
            ]
        )
        info = H.T @ np.linalg.inv(R) @ H
        info[:2, :2] += np.eye(2) / f.robot.theta_max**2
        A = np.linalg.pinv(info, rcond=1e-9) @ H.T @ np.linalg.inv(R)
        expected = np.hypot(sigma_point_std(f, x, e.covariance), sigma_point_std(f, x, A @ B @ A.T))
        assert_allclose(e.output_std, expected, rtol=1e-5, atol=1e-9)
        checked += 1
    assert checked > 20


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_compiled_output_std_equals_the_casadi_one(method: str) -> None:
    """The compiled EKF and the fast MHE use the compiled output Jacobian."""
    rec = simulate("paper3d", duration=2)
    f = BendFormulation(noise=NoiseSettings(reading_bias_std=0.0, model_error_std=0.0))
    est = step_all(make_estimator(method, f), rec.t, rec.z)  # type: ignore[arg-type]
    for e in est:
        assert_allclose(e.output_std, f.output_std(e.state, e.covariance), rtol=1e-12)


@pytest.mark.parametrize("solver", SOLVERS)
def test_covariance_conditioned_on_an_active_disk_bound(solver) -> None:
    """At theta_max the radial direction of the bend vector carries no variance; the
    tangential one does. Both backends give the same covariance. (The estimate reaches
    the bound at about 6.4 s: the first 7.5 s hold over 10 samples on it.)"""
    rec = simulate("planar-overbend", duration=10)
    f = BendFormulation()
    first = rec.t < 7.5
    mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=10))
    est = step_all(mhe, rec.t[first], rec.z[first])
    at_bound = [e for e in est if math.hypot(*e.state[:2]) >= f.robot.theta_max * (1 - 1e-9)]
    assert len(at_bound) > 10
    for e in at_bound:
        n = e.state[:2] / np.linalg.norm(e.state[:2])
        C = e.covariance[:2, :2]
        assert abs(n @ C @ n) < 1e-12
        assert np.array([-n[1], n[0]]) @ C @ np.array([-n[1], n[0]]) > 1e-8


def test_at_bound_rows_std_grows_with_the_bend_beyond_the_bound(tmp_path: Path) -> None:
    """The MHE held at a theta_max the robot bends past (planar-overbend bends to 2.2
    rad; the bound 1 rad): its rows on the bound are `at-bound`, and their standard
    deviations come from the covariance not conditioned on the bound, grown until the
    shift that fits the readings lies within it, so that the true bend lies within 4 of
    them on every such row (the conditioned covariance puts it up to 43 away)."""
    meas, truth, out = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "planar-overbend", "-o", str(meas), "--truth", str(truth),
                 "--seed", "1"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "--theta-max", "1", "-o", str(out)]) == 0
    est, true = read_state_table(out), read_state_table(truth)
    on = est.status == Status.AT_BOUND.value
    assert on.sum() > 100
    k = est.names.index("theta")
    assert est.std is not None
    off = np.abs(est.values[on, k] - true.values[on, true.names.index("theta")])
    assert off.max() > 0.8  # the truth lies far beyond the bound
    assert np.all(off < 4 * est.std[on, k])


SHIPPED_DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"


def _two_section_held_to(folder: Path, theta_max: float) -> Path:
    """The shipped two-section robot file with each section's ``theta_max`` (rad), in
    ``folder``."""
    robot = folder / "tight.toml"
    shipped = (SHIPPED_DATA / "robots" / "two_section.toml").read_text()
    robot.write_text(shipped.replace("theta_max = 3.0", f"theta_max = {theta_max}"))
    return robot


def _planar_s_first_8_s(folder: Path) -> Path:
    """The first 8 s (401 samples) of the shipped planar-s rod's tilt readings, in
    ``folder``: its bends past a tight bound and back, with the restarts on the bound
    (the rest of the recording holds the bound again, then lets it go)."""
    path = folder / "planar-s_tilt.csv"
    lines = (SHIPPED_DATA / "rod2" / "planar-s_tilt.csv").read_text().splitlines()
    path.write_text("\n".join(lines[:402]) + "\n")
    return path


def test_rows_held_on_the_bound_of_a_two_section_rod_cover_its_bend(tmp_path: Path) -> None:
    """The shipped planar-s rod (tilt, its first 8 s) with both sections held to 0.5
    rad, which it bends past: on every row the MHE holds on the bound, the rows of its
    restarts (`reset`) among them, the true bend of section 1 lies within 4 of the
    written standard deviations (a covariance conditioned on the bound puts it up to 37
    away)."""
    data = SHIPPED_DATA
    robot = _two_section_held_to(tmp_path, 0.5)
    out = tmp_path / "e.csv"
    assert main(["estimate", str(_planar_s_first_8_s(tmp_path)), "--robot", str(robot),
                 "-o", str(out)]) == 0  # fmt: skip
    est, true = read_state_table(out), read_state_table(data / "rod2" / "planar-s_truth.csv", ())
    k = est.names.index("theta_1")
    held = np.abs(est.values[:, k] - 0.5) < 1e-3
    assert np.count_nonzero(held & (est.status == Status.RESET.value)) > 20
    assert np.count_nonzero(held & (est.status == Status.AT_BOUND.value)) > 100
    assert est.std is not None
    true_bend = true.column("theta_1")[: len(est.t)]
    assert_allclose(true.t[: len(est.t)], est.t)
    off = np.abs(est.values[held, k] - true_bend[held])
    assert off.max() > 0.3  # the truth lies far beyond the bound
    assert np.all(off < 4 * est.std[held, k])


@pytest.mark.parametrize("loss", ["l2", "huber"])
def test_at_bound_standard_deviations_change_no_status_nor_estimate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, loss: str
) -> None:
    """The shipped planar-s rod (tilt, its first 8 s) with both sections held to 0.8
    rad: the estimate with the at-bound rows' unconditioned standard deviations, and
    the same through the policy's Python path with none (every row's from the
    covariance conditioned on the bound): the same statuses and outputs on every row,
    and standard deviations that differ on the rows held on the bound only (at-bound,
    and a restart's)."""
    import continuum_mhe.estimators.mhe as mhe_module

    robot = _two_section_held_to(tmp_path, 0.8)
    argv = ["estimate", str(_planar_s_first_8_s(tmp_path)), "--robot", str(robot),
            "--loss", loss, "-o"]  # fmt: skip
    assert main([*argv, str(tmp_path / "free.csv")]) == 0
    with monkeypatch.context() as m:
        m.setattr(mhe_module.MovingHorizonInference, "policy_inference", lambda self: None)
        m.setattr(mhe_module.MovingHorizonInference, "bound_free_covariance", lambda self: None)
        assert main([*argv, str(tmp_path / "held.csv")]) == 0
    free, held = read_state_table(tmp_path / "free.csv"), read_state_table(tmp_path / "held.csv")
    assert free.std is not None and held.std is not None
    assert list(free.status) == list(held.status)
    assert_allclose(free.values, held.values, rtol=0, atol=1e-12)
    on = free.status == Status.AT_BOUND.value
    assert on.sum() > 20
    on |= free.status == Status.RESET.value  # (a restart's row on the bound, as the MHE's)
    assert_allclose(free.std[~on], held.std[~on], rtol=1e-9)
    assert np.any(free.std[on] > 2 * held.std[on])


def test_the_bound_free_covariance_is_the_unconstrained_one_on_both_backends() -> None:
    """On the rows whose estimate sits on theta_max, each backend's covariance not
    conditioned on the bound equals the last block of the inverse Gauss-Newton Hessian
    with no bound at all (from the formulation's CasADi functions, at the same window
    answer), and the two backends' written standard deviations agree."""
    from continuum_mhe.estimators.fast.covariance import casadi_window_covariance

    rec = simulate("planar-overbend", duration=7.5)
    f = BendFormulation()
    stds = {}
    for solver in SOLVERS:
        mhe = MovingHorizonEstimator(f, solver_settings(solver, horizon=10))
        inference = mhe.inference
        rows = []
        for k in range(len(rec.t)):
            e = mhe.step(Measurement(float(rec.t[k]), rec.z[k]))
            free = inference.bound_free_covariance()
            on = float(e.state[0] ** 2 + e.state[1] ** 2) >= f.robot.theta_max**2 * (1 - 1e-6)
            assert (free is not None) == on
            if free is None:
                continue
            X, problem = np.array(inference._window.X), inference.window_problem()
            plain = casadi_window_covariance(f, problem, X, None)
            assert plain is not None
            # (the fast backend's at its SQP's last iterate, a certified step from it)
            assert_allclose(free, plain, rtol=1e-3, atol=1e-12)
            rows.append(k)
        assert len(rows) > 10
        series = step_all(MovingHorizonEstimator(f, solver_settings(solver, horizon=10)),
                          rec.t, rec.z)  # fmt: skip
        stds[solver] = {k: series[k].output_std for k in rows}
    both = sorted(set(stds["fast"]) & set(stds["ipopt"]))  # (a row may touch one's bound)
    assert len(both) > 10
    for k in both:
        assert_allclose(stds["fast"][k], stds["ipopt"][k], rtol=1e-3)


def test_fast_and_ipopt_covariances_agree() -> None:
    rec = simulate("paper3d", duration=3)
    f = BendFormulation()
    a = step_all(MovingHorizonEstimator(f, MHESettings(horizon=10)), rec.t, rec.z)
    b = step_all(MovingHorizonEstimator(f, MHESettings(horizon=10, solver="ipopt")), rec.t, rec.z)
    for ea, eb in zip(a, b):  # the fast Hessian: at the SQP's last iterate (see below)
        assert_allclose(ea.output_std, eb.output_std, rtol=1e-4)


@functools.cache
def _spiked_paper3d_run(loss: str, solver: str) -> tuple[Estimate, ...]:
    """The MHE's estimates (horizon 10, ``solver``, ``loss``) over 3 s of paper3d whose
    newest sample carries a 30 degree spike: the quadratic cost's runs are the same for
    every robust loss compared with them, so they are made once (frozen estimates)."""
    t, z, f = _spiked_paper3d()
    # the quadratic cost takes the spike (not skipped as a glitch): the costs are compared
    taken = RecoverySettings(glitch=None)
    est = MovingHorizonEstimator(
        f, MHESettings(horizon=10, solver=solver, loss=loss), recovery=taken
    )
    return tuple(step_all(est, t, z))


@functools.cache
def _spiked_paper3d() -> tuple[np.ndarray, np.ndarray, BendFormulation]:
    rec = simulate("paper3d", duration=3)
    z = rec.z.copy()
    z[-1] += np.radians(30.0)  # a spike on the newest sample
    return rec.t, z, BendFormulation()


@pytest.mark.parametrize("loss", ["huber", "cauchy"])
def test_robust_covariance_down_weights_an_outlier_alike_on_both_backends(loss: str) -> None:
    """With a robust loss the Hessian carries the loss weights: both backends give the
    same covariance, and a spike in the newest sample (down-weighted) leaves the
    estimate's covariance wider than the quadratic cost's, which trusts it fully. (The
    quadratic estimate's standard deviations are wider still: its readings disagree
    with it, and the policy widens them by the shift they ask for; the robust row is
    not widened: its rejected reading is not judged.)"""
    runs = {
        (name, solver): _spiked_paper3d_run(name, solver)
        for name, solver in ((loss, "fast"), (loss, "ipopt"), ("l2", "fast"))
    }
    # fast: the Hessian at the SQP's last iterate (measured up to 6.6e-5 relative for
    # Cauchy, 1.6e-6 for Huber); the formula itself: ..._at_the_same_window_solution
    for ea, eb in zip(runs[(loss, "fast")], runs[(loss, "ipopt")]):
        assert_allclose(ea.output_std, eb.output_std, rtol=3e-4)
    robust, quadratic = runs[(loss, "fast")][-1], runs[("l2", "fast")][-1]
    assert robust.outlier and robust.covariance is not None
    assert quadratic.covariance is not None
    assert np.all(np.diag(robust.covariance)[:2] > np.diag(quadratic.covariance)[:2])
    # both rows inconsistent: the quadratic estimate disagrees with its readings, the
    # robust one rejected its newest
    assert quadratic.status == "inconsistent" and robust.status == "inconsistent"
    assert np.all(quadratic.output_std[:3] > robust.output_std[:3])


def test_fast_and_ipopt_covariances_agree_on_two_sections_with_one_imu_dropped() -> None:
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=1.5)
    f = make_formulation("bend", robot)
    z = rec.z.copy()
    z[10:20, 2:4] = np.nan  # the second IMU drops out: its residual is masked
    a = make_estimator("mhe", f, MHESettings(horizon=8)).run(rec.t, z)
    b = make_estimator("mhe", f, MHESettings(horizon=8, solver="ipopt")).run(rec.t, z)
    assert np.isfinite(a.std).all()
    # the fast backend's Hessian is its SQP's at the last evaluated iterate, which lies
    # within the last (certified) step of the answer (up to ~1e-4 rad): 2.5e-5 relative
    assert_allclose(a.std, b.std, rtol=1e-4)


def test_the_sections_the_imus_leave_free() -> None:
    from dataclasses import replace

    from continuum_mhe.io.robot_file import read_robot

    two = read_robot("two-section")
    assert free_sections(two) == ()
    assert free_sections(replace(two, imus=two.imus[1:])) == (0, 1)  # the tip IMU alone
    assert free_sections(replace(two, imus=two.imus[:1])) == (1,)  # nothing beyond IMU 1
    assert free_sections(_three_sections_imus_1_and_3()) == (1, 2)
    # an IMU a thousandth of the way along section 1 turns by a few hundredths of a
    # degree across the section's reach, less than the noise of the mean of 100
    # readings: of full rank, but no reading pins the split
    from continuum_mhe.model.robot import ImuPlacement

    near_base = replace(two, imus=(ImuPlacement(section=0, at=1e-3), two.imus[1]))
    assert free_sections(near_base) == ()
    assert free_sections(near_base, math.radians(2.0)) == (0, 1)
    halfway = replace(two, imus=(ImuPlacement(section=0, at=0.5), two.imus[1]))
    assert free_sections(halfway, math.radians(2.0)) == ()
    assert make_formulation("bend", near_base).free_bends() == ((0, 1, 3.0), (2, 3, 3.0))
    assert make_formulation("direct", halfway).free_bends() == ()


def test_robots_with_an_imu_on_each_section_leave_no_bend_free() -> None:
    # random robots of one to four sections, bends up to 1 to 3.1 rad, each section's IMU
    # at 0.2 to 1 of it, standing or hanging: at some shapes one sample barely sees a
    # direction (a scaled singular value of 0.006 on a three-section robot at 3 rad),
    # which a motion model holds; no section is free (a free one would make every row
    # uncertain, with standard deviations of the whole reach)
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    rng = np.random.default_rng(1)
    for n in (1, 2, 3, 4):
        for theta_max in (1.0, 2.0, 3.0, 3.1):
            for mounting in ("z-up", "z-down"):
                robot = Robot(
                    tuple(Section(float(rng.uniform(0.05, 0.3)), theta_max) for _ in range(n)),
                    tuple(
                        ImuPlacement(section=k, at=float(rng.choice([0.2, 0.3, 0.5, 1.0])))
                        for k in range(n)
                    ),
                    mounting=mounting,
                )
                assert free_sections(robot, math.radians(2.0)) == (), robot


def _three_sections_imus_1_and_3():  # type: ignore[no-untyped-def]
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    return Robot(
        sections=tuple(Section(length=0.1, theta_max=3.0) for _ in range(3)),
        imus=(ImuPlacement(section=0, at=1.0), ImuPlacement(section=2, at=1.0)),
    )


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_a_section_without_its_own_imu_has_the_spread_of_its_reach(method: str) -> None:
    # IMUs at the ends of sections 1 and 3 of three: the tip IMU sees how far sections 2
    # and 3 bend together, not how they share it, and the estimate lands on any of the
    # shapes that fit. Its covariance holds only what the motion model kept of the start
    # (alone: tip x / y / z coverage 0.19 to 0.33 and NEES 361 with the EKF, 0.09 to
    # 0.15 with the MHE); with the free bends' spread the written ones cover the truth
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = _three_sections_imus_1_and_3()
    rec = simulate_robot("spatial", robot, duration=8.0, dt=0.02, seed=0)
    with pytest.warns(UserWarning, match="not observable"):
        est = make_estimator(method, make_formulation("bend", robot)).run(rec.t, rec.z)
    names = [o.name for o in est.outputs]
    cal = compute_calibration(
        est.output, est.output_std, rec.truth, names, [o.name for o in rec.outputs]
    )
    # (the MHE holds many of these rows on a bend bound, a curled shape further from
    # the robot's than the reach's spread says: 0.81 to 0.97 of its rows covered)
    for axis in ("x", "y", "z"):
        assert cal.coverage[axis] >= 0.8, (axis, cal.coverage)
    assert cal.tip_nees < 2 * 3, cal.tip_nees
    # section 1 carries its own IMU: the free bends do not move its end
    std = {c: np.median(est.output_std[:, names.index(c)]) for c in ("x", "x_1")}
    assert std["x_1"] < 0.1 * std["x"], std


def test_an_imu_that_barely_turns_with_its_section_leaves_no_row_ok_far_off() -> None:
    # an IMU a thousandth of the way along section 1 (of full rank, but turning by less
    # than its noise across the section's reach): the covariance alone gives a 61 mm tip
    # standard deviation 167 mm off; the free bends' spread makes it wide, so uncertain
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot(
        sections=tuple(Section(length=0.15, theta_max=1.5) for _ in range(2)),
        imus=(ImuPlacement(section=0, at=1e-3), ImuPlacement(section=1, at=1.0)),
    )
    rec = simulate_robot("spatial", robot, duration=20.0, dt=0.05, seed=0)
    est = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, rec.z)
    names = [o.name for o in est.outputs]
    tip = [names.index(c) for c in ("x", "y", "z")]
    err = np.linalg.norm(est.output[:, tip] - rec.truth[:, tip], axis=1)
    assert err.mean() > 0.1  # the estimate is far off: the readings do not place it
    assert not np.any((est.status == Status.OK) & (err > 0.1 * robot.length))
    cal = compute_calibration(
        est.output, est.output_std, rec.truth, names, [o.name for o in rec.outputs]
    )
    assert min(cal.coverage[c] for c in ("x", "y", "z")) >= 0.9, cal.coverage


def test_the_sections_a_set_of_imus_leaves_free() -> None:
    """What the core asks while some IMUs are silent (``free_bends(imus)``), against the
    robot's geometry: of two sections with an IMU at each end, IMU 1 alone pins section
    1 and leaves section 2 free; IMU 2 alone (the tip's direction: the two bends' sum)
    leaves both free; both IMUs, as every IMU (None), leave none. The rows are each
    section's bend coordinates and the reach its theta_max."""
    from continuum_mhe.io.robot_file import read_robot

    robot = read_robot("two-section")
    f = make_formulation("bend", robot)
    reach = [s.theta_max for s in robot.sections]
    assert f.free_bends((0,)) == ((2, 3, reach[1]),)
    assert f.free_bends((1,)) == ((0, 1, reach[0]), (2, 3, reach[1]))
    assert f.free_bends((0, 1)) == f.free_bends() == ()


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_a_silent_imu_leaves_the_sections_it_pinned_the_spread_of_their_reach(
    method: str,
) -> None:
    # two sections, IMU 2 silent for the first 4 s (a board that never reported yet):
    # IMU 1 pins section 1, nothing pins section 2. Its covariance holds only what the
    # motion model kept of the start (the EKF's tip x coverage over those rows 0.1 to
    # 0.3); its standard deviations carry section 2's spread over its reach, computed
    # here on the forward kinematics of the estimate's section 1 with section 2 drawn
    # uniformly over its disk of bends. Once IMU 2 reports again, the spread goes.
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.pcc import pose_at
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=8.0, dt=0.02, seed=1)
    z = rec.z.copy()
    silent = rec.t < 4.0
    z[silent, 2:4] = np.nan
    est = make_estimator(method, make_formulation("bend", robot)).run(rec.t, z)
    names = [o.name for o in est.outputs]
    tip = [names.index(c) for c in ("x", "y", "z")]
    assert est.output_std is not None
    rng = np.random.default_rng(0)
    reach = robot.sections[1].theta_max
    radius, angle = reach * np.sqrt(rng.uniform(size=4000)), rng.uniform(0, 2 * np.pi, 4000)
    bends = np.zeros((len(radius), 2, 2))
    bends[:, 1] = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    for k in np.flatnonzero(silent & (rec.t > 1.5))[::25]:
        theta, phi = est.output[k, names.index("theta_1")], est.output[k, names.index("phi_1")]
        bends[:, 0] = theta * np.cos(phi), theta * np.sin(phi)
        msd = ((pose_at(bends, robot.lengths, 1)[1] - est.output[k, tip]) ** 2).mean(axis=0)
        var = est.output_std[k, tip] ** 2
        assert np.all(var >= 0.8 * msd), (k, var, msd)
    back = rec.t > 6.0  # IMU 2 has reported again for 2 s: its section pinned
    assert np.median(est.output_std[back][:, tip]) < 0.02


def test_a_dropout_shorter_than_the_unobserved_window_frees_no_section(monkeypatch) -> None:
    # IMU 2 silent for 0.6 s mid-recording: its covariance still holds section 2 (the
    # motion model over 0.6 s), so the standard deviations and statuses are those of the
    # same run with no section ever freed; a silence of 1.5 s, past the unobserved
    # window (1 s), widens them
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=6.0, dt=0.02, seed=2)
    f = make_formulation("bend", robot)
    runs = {}
    for gap in (0.6, 1.5):
        z = rec.z.copy()
        z[(rec.t >= 3.0) & (rec.t < 3.0 + gap), 2:4] = np.nan
        runs[gap] = make_estimator("ekf", f).run(rec.t, z)
    with monkeypatch.context() as m:
        m.setattr(BendFormulation, "free_bends", lambda self, imus=None: ())
        z = rec.z.copy()
        z[(rec.t >= 3.0) & (rec.t < 3.6), 2:4] = np.nan
        never = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, z)
    assert_allclose(runs[0.6].output_std, never.output_std, rtol=1e-12)
    assert list(runs[0.6].status) == list(never.status)
    late = (rec.t > 4.1) & (rec.t < 4.5)  # IMU 2 silent for more than the window
    assert np.all(runs[1.5].output_std[late, 0] > 0.05), runs[1.5].output_std[late, 0]


# --- std columns and calibration -------------------------------------------------------------
def test_std_columns_written_read_back_and_evaluated(tmp_path, capsys) -> None:
    rec = simulate("paper3d", duration=4)
    series = make_estimator("ekf", BendFormulation()).run(rec.t, rec.z)
    est_path, truth_path = tmp_path / "e.csv", tmp_path / "t.csv"
    write_estimates(est_path, series)
    from continuum_mhe.io.estimate_csv import write_truth

    write_truth(truth_path, rec.t, rec.truth, series.outputs)
    header = est_path.read_text().splitlines()[0].split(",")
    assert header == ["t", "x", "y", "z", "theta", "phi"] + [
        f"std_{c}" for c in ("x", "y", "z", "theta", "phi")
    ] + ["status", "solve_ms"]
    table = read_state_table(est_path)
    assert table.names == ("x", "y", "z", "theta", "phi")
    assert_allclose(table.std, series.std, rtol=1e-9)
    assert main(["evaluate", str(est_path), str(truth_path), "--json"]) == 0
    import json

    got = json.loads(capsys.readouterr().out)["calibration"]
    want = compute_calibration(
        series.output, series.std, rec.truth, ["x", "y", "z", "theta", "phi"]
    )
    assert got["coverage"] == pytest.approx(want.coverage)
    assert got["tip_nees"] == pytest.approx(want.tip_nees)
    # a file without std columns: read, evaluated without calibration
    lines = est_path.read_text().splitlines()
    keep = [i for i, c in enumerate(lines[0].split(",")) if not c.startswith("std_")]
    (tmp_path / "plain.csv").write_text(
        "\n".join(",".join(r.split(",")[i] for i in keep) for r in lines) + "\n"
    )
    plain = read_state_table(tmp_path / "plain.csv")
    assert not plain.has_std and np.isnan(plain.std).all()
    assert main(["evaluate", str(tmp_path / "plain.csv"), str(truth_path)]) == 0
    assert "no std_ columns" in capsys.readouterr().out
    # std_ columns, all empty (a first run's MHE file): said as such
    std = [i for i, c in enumerate(lines[0].split(",")) if c.startswith("std_")]
    rows = [r.split(",") for r in lines[1:]]
    empty = [lines[0]] + [",".join("" if i in std else v for i, v in enumerate(r)) for r in rows]
    (tmp_path / "empty.csv").write_text("\n".join(empty) + "\n")
    assert read_state_table(tmp_path / "empty.csv").std_columns and not plain.std_columns
    assert main(["evaluate", str(tmp_path / "empty.csv"), str(truth_path)]) == 0
    assert "the std_ columns of the estimate file are empty" in capsys.readouterr().out


def test_unknown_std_is_written_empty_and_read_as_nan(tmp_path) -> None:
    t = np.array([0.0, 0.1])
    out = np.array([[0.0, 0.0, 0.2, 0.0, 0.0], [0.01, 0.0, 0.2, 0.05, 0.0]])
    std = np.array([[np.nan] * 5, [0.001, 0.002, 0.003, 0.01, 0.2]])
    s = EstimateSeries("x", t, out, np.array(["ok", "ok"]), np.zeros(2), output_std=std)
    write_estimates(tmp_path / "e.csv", s)
    assert_allclose(read_state_table(tmp_path / "e.csv").std, std)


def test_calibration_on_a_hand_made_case() -> None:
    names = ["x", "y", "z", "phi"]
    truth = np.zeros((4, 4))
    std = np.ones((4, 4))
    est = np.array(
        [
            [0.0, 1.0, 2.5, 2 * math.pi + 0.5],  # phi wraps to 0.5: inside
            [1.9, -1.9, 0.0, -1.0],
            [2.0, 0.0, 0.0, 3.0],
            [np.nan, 0.0, 0.0, 0.0],  # no estimate of x here
        ]
    )
    c = compute_calibration(est, std, truth, names)
    assert c.coverage == pytest.approx({"x": 2 / 3, "y": 1.0, "z": 3 / 4, "phi": 3 / 4})
    assert c.n == {"x": 3, "y": 4, "z": 4, "phi": 4}
    # tip NEES over the rows with x, y, z: (0+1+6.25), (3.61+3.61+0), (4+0+0)
    assert c.tip_n == 3
    assert c.tip_nees == pytest.approx((7.25 + 7.22 + 4.0) / 3)
    z = np.array([[0.0, 1.0, 2.5], [1.9, -1.9, 0.0], [2.0, 0.0, 0.0]])
    lo, hi = nees_band(3, 3, corr=np.corrcoef(z, rowvar=False))
    assert c.tip_nees_band == pytest.approx((lo, hi), rel=1e-12) and lo < 3 < hi
    assert Z95 == pytest.approx(scipy.stats.norm.ppf(0.975), abs=1e-6)


def test_calibration_refuses_what_does_not_fit() -> None:
    """One truth row for four estimates (numpy would broadcast it: a NEES of the wrong
    rows), rows that differ, a column short and a negative standard deviation: each a
    UserError naming it."""
    names = ["x", "y", "z"]
    est, std = np.zeros((4, 3)), np.ones((4, 3))
    with pytest.raises(UserError, match="4, 4 and 1 rows"):
        compute_calibration(est, std, np.zeros((1, 3)), names)
    with pytest.raises(UserError, match="4, 3 and 4 rows"):
        compute_calibration(est, std[:3], np.zeros((4, 3)), names)
    with pytest.raises(UserError, match="std has 2 columns"):
        compute_calibration(est, std[:, :2], np.zeros((4, 3)), names)
    with pytest.raises(UserError, match="negative"):
        compute_calibration(est, -std, np.zeros((4, 3)), names)


def test_evaluate_gives_the_coverage_of_the_ok_rows_alone(tmp_path, capsys) -> None:
    """``evaluate``: the coverage over every row, and over the rows marked ``ok`` (what
    the status promises). Four rows 0.5 std off, each ``ok``, and two 5 std off marked
    ``uncertain``: every row 4/6 inside, the ``ok`` rows all inside."""
    n = 6
    t = np.arange(n) * 0.02
    offsets = np.array([0.5, 0.5, 0.5, 0.5, 5.0, 5.0]) * 0.001
    status = ["ok"] * 4 + ["uncertain"] * 2
    est = EstimateSeries(
        method="ekf", t=t, output=np.column_stack([offsets, offsets, offsets + 0.2, 0 * t, 0 * t]),
        status=np.array(status), solve_ms=np.zeros(n), output_std=np.full((n, 5), 0.001),
    )  # fmt: skip
    write_estimates(tmp_path / "e.csv", est)
    truth = tmp_path / "t.csv"
    rows = "".join(f"{tk},0,0,0.2,0,0\n" for tk in t)
    truth.write_text("t,x,y,z,theta,phi\n" + rows)
    assert main(["evaluate", str(tmp_path / "e.csv"), str(truth)]) == 0
    out = capsys.readouterr().out
    assert "95% interval coverage x 0.667, y 0.667, z 0.667" in out
    assert "ok rows              4 of 6: tip 95% interval coverage x 1.000, y 1.000, z 1.000" in out
    assert main(["evaluate", str(tmp_path / "e.csv"), str(truth), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["ok_rows"] == 4 and report["calibration_ok"]["coverage"]["x"] == 1.0
    # no row ok: said, not left out
    est.status[:] = "uncertain"
    write_estimates(tmp_path / "u.csv", est)
    assert main(["evaluate", str(tmp_path / "u.csv"), str(truth)]) == 0
    assert "ok rows              0 of 6: no coverage of the ok rows" in capsys.readouterr().out
    # ok rows, none with a std: said too
    est.status[:4] = "ok"
    est.output_std[:4] = np.nan
    write_estimates(tmp_path / "n.csv", est)
    assert main(["evaluate", str(tmp_path / "n.csv"), str(truth)]) == 0
    assert "ok rows              4 of 6 (no std on them: no coverage)" in capsys.readouterr().out


# --- recovery ---------------------------------------------------------------------------------
estimators = recovery_estimators


def test_evaluate_counts_the_ok_rows_far_outside_their_std(tmp_path, capsys) -> None:
    # ok rows 0.5, 4.5, 0.5 and 6 std off in x (1 mm std) and an uncertain one 10 std
    # off: two ok rows far off, the largest at 6 std (t = 0.06 s); then an ok row with a
    # zero std and an error: infinitely far off, the largest
    n = 6
    t = np.arange(n) * 0.02
    dx = np.array([0.5, 4.5, 0.5, 6.0, 10.0, 1.0]) * 0.001
    status = np.array(["ok", "ok", "ok", "ok", "uncertain", "uncertain"])
    std = np.full((n, 5), 0.001)
    std[5, 0] = 0.0
    truth = tmp_path / "t.csv"
    truth.write_text("t,x,y,z,theta,phi\n" + "".join(f"{tk},0,0,0.2,0,0\n" for tk in t))

    def evaluate(status: np.ndarray) -> tuple[str, dict]:
        est = EstimateSeries(
            method="ekf", t=t, output=np.column_stack([dx, 0 * t, 0 * t + 0.2, 0 * t, 0 * t]),
            status=status, solve_ms=np.zeros(n), output_std=std,
        )  # fmt: skip
        write_estimates(tmp_path / "e.csv", est)
        assert main(["evaluate", str(tmp_path / "e.csv"), str(truth)]) == 0
        out = capsys.readouterr().out
        assert main(["evaluate", str(tmp_path / "e.csv"), str(truth), "--json"]) == 0
        return out, json.loads(capsys.readouterr().out)

    out, report = evaluate(status)
    far = "ok rows far off      2 of 4 more than 4 std off on a tip axis (the largest 6.0 std"
    assert far + " at t = 0.06 s;" in out
    ok = report["calibration_ok"]
    assert (ok["tip_far"], ok["tip_far_of"], ok["tip_far_worst_row"]) == (2, 4, 3)
    assert ok["tip_far_worst"] == pytest.approx(6.0)
    every = report["calibration"]  # the uncertain rows too; the zero std is the largest
    assert (every["tip_far"], every["tip_far_of"], every["tip_far_worst_row"]) == (4, 6, 5)
    assert every["tip_far_worst"] is None  # infinite: null in JSON
    status[5] = "ok"
    out, report = evaluate(status)
    assert "3 of 5 more than 4 std off on a tip axis (the largest a zero std at t = 0.1 s;" in out
    assert report["calibration_ok"]["tip_far_worst_row"] == 4


@pytest.mark.parametrize(
    ("ratio", "text"),
    [(0.358094, "0.4"), (3.984188, "3.98"), (3.99996, "3.99996"), (4.0, "4.0"), (4.03, "4.03")],
)
def test_evaluate_gives_the_largest_ratio_to_the_digits_that_place_it(
    tmp_path, capsys, ratio, text
) -> None:
    # the ok rows' largest |error| / std, within 4 std or beyond it, is printed to one
    # decimal, or to as many more as keep it on its side of 4 (never six decimals for
    # a ratio well within, nor a 3.98 rounded up to the 4.0 of the bound)
    n = 3
    t = np.arange(n) * 0.02
    dx = np.array([0.1, ratio, 0.2]) * 0.001
    est = EstimateSeries(
        method="ekf", t=t, output=np.column_stack([dx, 0 * t, 0 * t + 0.2, 0 * t, 0 * t]),
        status=np.full(n, "ok"), solve_ms=np.zeros(n), output_std=np.full((n, 5), 0.001),
    )  # fmt: skip
    write_estimates(tmp_path / "e.csv", est)
    truth = tmp_path / "t.csv"
    truth.write_text("t,x,y,z,theta,phi\n" + "".join(f"{tk},0,0,0.2,0,0\n" for tk in t))
    assert main(["evaluate", str(tmp_path / "e.csv"), str(truth)]) == 0
    assert f"(the largest {text} std at t = 0.02 s;" in capsys.readouterr().out


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_rows_are_not_ok_while_an_imu_is_silent_and_the_others_cannot_see_its_part(
    method: str,
) -> None:
    """The shipped spatial-tendon rod, tilt, its tip IMU silent (no readings) from 3 to
    5 s: extrapolated at its last rates, the second section drifts beyond its standard
    deviation (22 mm off at 1.7 of them after 0.24 s, 72 mm at 3.9 after 0.56 s), and
    within the unobserved window's second the rows would be ``ok``. From
    ``SILENT_AFTER`` on no row of the silence is ``ok``, no ``ok`` row of the recording
    is more than 20 mm and 3 standard deviations off, and the rows after its return are
    ``ok`` again; the status's meaning states the time."""
    from continuum_mhe.io.csv_files import read_measurements
    from continuum_mhe.io.robot_file import read_robot

    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    meas = read_measurements(data / "spatial-tendon_tilt.csv", n_imus=2)
    truth = read_state_table(data / "spatial-tendon_truth.csv")
    f = make_formulation("bend", read_robot("two-section"))
    t, z = meas.t, meas.z.copy()
    silent = (t >= 3.0) & (t < 5.0)
    z[silent, f.measurement_blocks[1].slice] = np.nan
    s = make_estimator(method, f).run(t, z)
    tip = np.column_stack([truth.column(c) for c in "xyz"])
    err = np.linalg.norm(s.output[:, :3] - tip, axis=1)
    std = np.linalg.norm(s.output_std[:, :3], axis=1)
    ok = s.status == "ok"
    assert not ok[silent & (t > 3.0 + SILENT_AFTER + 1e-9)].any()
    assert not (ok & (err > 0.02) & (err > 3 * std)).any()
    assert ok[t > 6.5].mean() > 0.8
    assert f"SILENT_AFTER, {SILENT_AFTER:g} s," in Status.UNCERTAIN.meaning


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_a_stuck_imu_that_jitters_far_below_its_noise_is_frozen(method: str) -> None:
    """The tip IMU of a two-section robot stuck from 3 to 5 s, its driver adding 1e-6 rad
    of jitter (3e-5 of the 2-degree noise): a freeze as an exact repeat is (with the
    default freeze), and no row from its discovery on is ``ok`` (as an exact repeat's;
    without the tolerance 40 such rows are, up to 68 mm off). Ten times the tolerance (a
    live IMU a hundred times quieter than its noise model) is no freeze."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=7.0, seed=1)
    f = make_formulation("bend", robot)
    stuck = (rec.t >= 3.0) & (rec.t < 5.0)
    tip = f.measurement_blocks[1].slice
    noise = np.random.default_rng(0).standard_normal((int(stuck.sum()), 2))
    std = f.noise.measurement_std
    for jitter, frozen in ((1e-6, True), (10 * FREEZE_TOLERANCE * std, False)):
        z = rec.z.copy()
        z[stuck, tip] = z[np.flatnonzero(stuck)[0], tip] + jitter * noise
        est = make_estimator(method, f)
        s = est.run(rec.t, z)
        if frozen:
            assert est.diagnostics.first_freezes == {1: 3.0}
            found = stuck & (rec.t > 3.0 + FREEZE_S + 1e-9)
            assert found.sum() >= 30 and "ok" not in set(s.status[found])
        else:
            assert est.diagnostics.first_freezes == {}


@pytest.mark.parametrize("index", range(5), ids=["ekf-c", "ekf", "ukf", "mhe-fast", "mhe-ipopt"])
def test_gap_reset_restarts_every_estimator_from_the_measurements(index: int) -> None:
    rec = simulate("paper3d", duration=12, seed=1)
    keep = (rec.t < 3) | (rec.t >= 10)  # a 7 s gap
    t, z, truth = rec.t[keep], rec.z[keep], rec.truth[keep]
    first_after = int(np.flatnonzero(t >= 10)[0])
    est = estimators(bare(gap_reset=1.0))[index]
    s = est.run(t, z)
    assert s.status[first_after] == "reset"
    assert list(s.status).count("reset") == 1 and est.diagnostics.gap_resets == 1
    # restarted from the reading: the shape the first reading gives, not a blind prediction
    x0 = est.formulation.initial_state(z[first_after])
    assert np.linalg.norm(s.output[first_after, :3] - est.formulation.output(x0)[:3]) < 0.01
    tip = np.linalg.norm(s.output[first_after:, :3] - truth[first_after:, :3], axis=1)
    assert tip.mean() < 0.01
    plain_est = estimators(bare())[index]
    plain = plain_est.run(t, z)
    assert plain_est.diagnostics.gap_resets == 0  # without it
    if plain_est.name == "ukf":  # its sigma points span a half turn after 7 s blind
        assert plain_est.diagnostics.restarts == list(plain.status).count("reset") == 1
        assert "half turn" in str(plain_est.diagnostics.last_failure)
    else:
        assert "reset" not in set(plain.status)


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_a_frozen_sensor_is_treated_as_a_dropout(method: str) -> None:
    rec = simulate("paper3d", duration=6, seed=2)
    z = rec.z.copy()
    frozen = (rec.t >= 2) & (rec.t < 4)
    z[frozen] = z[np.flatnonzero(frozen)[0]]
    est = make_estimator(method, BendFormulation(), recovery=bare(freeze=0.5))
    s = est.run(rec.t, z)
    late = frozen & (rec.t > 2 + 0.5 + 1e-9)
    assert set(s.status[late]) == {"dropout"}
    assert set(s.status[frozen & ~late]) <= {"ok"}
    assert est.diagnostics.frozen_samples == int(late.sum())
    assert set(s.status[rec.t >= 4]) <= {"ok", "uncertain"}  # the reading changes: used again


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_a_frozen_imu_is_silent_from_its_freezes_start(method: str) -> None:
    """A two-section robot whose tip IMU sticks at t = 3 s for the rest of the
    recording: once its freeze is found (1 s of the same reading) the IMU left cannot
    determine the shape, and its silence dates from the freeze's start, so no row from
    then on is ``ok`` (counted from its discovery, the IMU would be silent for less
    than the unobserved window, count as reporting, and leave rows up to 58 mm off
    ``ok``)."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=6.0, seed=1)
    f = make_formulation("bend", robot)
    z = rec.z.copy()
    stuck = rec.t >= 3.0
    tip = f.measurement_blocks[1].slice
    z[stuck, tip] = z[np.flatnonzero(stuck)[0], tip]
    est = make_estimator(method, f, recovery=bare(freeze=1.0))
    s = est.run(rec.t, z)
    found = rec.t > 3.0 + 1.0 + 1e-9
    assert est.diagnostics.first_freezes == {1: 3.0}
    assert "ok" not in set(s.status[found])
    assert set(s.status[found]) <= {"uncertain", "inconsistent", "reset", "at-bound"}


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_a_frozen_imu_observes_nothing_from_its_freezes_discovery(method: str) -> None:
    """The same robot with the default freeze (0.2 s): the freeze is found 0.2 s after
    it began, when the IMU's silence is shorter than the unobserved window (1 s); a
    frozen IMU observes nothing however recent its last reading, so every row from the
    discovery on is not ``ok``; once its readings move again (at 5 s) it reports, and
    rows are ``ok`` again."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("spatial", robot, duration=9.0, seed=1)
    f = make_formulation("bend", robot)
    z = rec.z.copy()
    stuck = (rec.t >= 3.0) & (rec.t < 5.0)
    tip = f.measurement_blocks[1].slice
    z[stuck, tip] = z[np.flatnonzero(stuck)[0], tip]
    est = make_estimator(method, f, recovery=bare(freeze=0.2))
    s = est.run(rec.t, z)
    found = stuck & (rec.t > 3.0 + 0.2 + 1e-9)
    assert est.diagnostics.first_freezes == {1: 3.0}
    assert found.sum() >= 30 and "ok" not in set(s.status[found])
    assert "ok" in set(s.status[rec.t > 5.0 + 2.0])  # the flag clears


@pytest.mark.parametrize("index", range(5), ids=["ekf-c", "ekf", "ukf", "mhe-fast", "mhe-ipopt"])
def test_each_run_counts_its_own_recording(index: int) -> None:
    """Each ``run`` counts its own recording: the counts (gap resets, frozen samples,
    first freezes) start again at every run, not at the estimator's construction, so a
    second ``run`` reports the same counts, not the totals over both runs."""
    rec = simulate("paper3d", duration=6, seed=2)
    z = rec.z.copy()
    frozen = (rec.t >= 4) & (rec.t < 5)
    z[frozen] = z[np.flatnonzero(frozen)[0]]
    keep = (rec.t < 1) | (rec.t >= 3)  # a 2 s gap
    t, z = rec.t[keep], z[keep]
    est = estimators(bare(gap_reset=1.0, freeze=0.5))[index]
    first = est.run(t, z).diagnostics
    assert first is not None and first == est.diagnostics  # returned with the estimates
    assert first.gap_resets == 1 and first.frozen_samples > 0 and list(first.first_freezes) == [0]
    assert est.run(t, z).diagnostics == first
    est.reset(keep_counts=True)  # a restart within the recording (as live's)
    assert est.diagnostics == first
    est.reset()  # so does a reset before stepping by hand
    assert est.diagnostics == Diagnostics()  # every count zero, no failure
    assert first.gap_resets == 1 and list(first.first_freezes) == [0]  # the copy run returned


def test_a_reset_zeroes_the_second_start_and_branch_check_counts() -> None:
    rec = simulate("paper3d", duration=4, seed=3)
    z = rec.z.copy()
    z[30:33] += 0.5  # rejected readings: second starts are tried
    est = MovingHorizonEstimator(
        BendFormulation(), MHESettings(horizon=10, loss="welsch", branch_check=True)
    )
    est.run(rec.t, z)
    assert est.inference.second_start is not None and est.inference.branch is not None
    counts = (
        est.inference.branch.stats.checked,
        est.inference.second_start.tried,
        est.inference.second_start.kept,
    )
    assert counts[0] > 0 and counts[1] > 0
    est.reset(keep_counts=True)
    assert (
        est.inference.branch.stats.checked,
        est.inference.second_start.tried,
        est.inference.second_start.kept,
    ) == counts
    est.reset()
    assert (est.inference.second_start.tried, est.inference.second_start.kept) == (0, 0)
    assert est.inference.branch.stats == BranchStats()


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_two_equal_readings_with_a_long_gap_between_are_not_a_freeze(method: str) -> None:
    """The freeze rule looks at more than how long a reading stays the same, so the
    second of two equal readings 60 s apart (tests/data/fuzz/long_gap.csv) is not taken
    as frozen and dropped. A gap is not a sensor seen stuck: both readings are used
    (the gap reset restarts from the second)."""
    est = make_estimator(method, BendFormulation(), recovery=bare(gap_reset=1.0, freeze=1.0))
    s = est.run(np.array([0.0, 60.0, 60.05]), np.array([[0.1, 0.1], [0.1, 0.1], [0.5, -0.2]]))
    assert est.diagnostics.frozen_samples == 0 and est.diagnostics.first_freezes == {}
    assert "dropout" not in set(s.status) and "no-estimate" not in set(s.status)
    assert s.status[1] == "reset" and est.diagnostics.gap_resets == 1


@pytest.mark.parametrize(("dt", "first"), [(0.01, 21), (0.5, 4), (1.0, 4), (2.0, None)])
def test_the_default_freeze_finds_slow_data_frozen_as_fast(dt: float, first: int | None) -> None:
    """With the defaults (a freeze after 0.2 s, a gap reset after 1 s) a step up to the
    gap reset's 1 s is no gap in the data, so a reading repeated at 1 or 2 Hz is found
    frozen at its fifth sample, as a 100 Hz one is after 0.2 s; steps of 2 s are gaps
    (each restarts the estimator), never a freeze."""
    t = dt * np.arange(30)
    z = np.tile([0.1, -0.2], (30, 1))
    est = make_estimator("ekf", BendFormulation(), recovery=RecoverySettings())
    est.run(t, z)
    if first is None:
        assert est.diagnostics.first_freezes == {}
    else:
        assert est.diagnostics.first_freezes == {0: 0.0}  # IMU 0 (0-based), from t = 0
        assert est.diagnostics.frozen_samples == 30 - first


@pytest.mark.parametrize(("dt", "first"), [(0.05, 21), (0.5, 4), (0.9, 4), (20.0, None)])
def test_a_freeze_needs_both_the_duration_and_the_repeated_samples(
    dt: float, first: int | None
) -> None:
    """The same reading at FREEZE_MIN_SAMPLES consecutive samples spanning more than
    ``freeze`` s, none more than ``freeze`` s after the one before, is a freeze from the
    sample at which all hold (index ``first``; the duration alone would say 3 at 2 Hz
    and 1 at 0.05 Hz); one sample fewer, however long it spans, is not; at 20 Hz the
    duration decides, as it would without the count; samples 20 s apart (each a gap) are
    never one."""
    n = FREEZE_MIN_SAMPLES  # 5, as documented: (0.5, 4) fails for any other default
    k = 30
    t = dt * np.arange(k)
    z = np.tile([0.1, -0.2], (k, 1))
    est = make_estimator("ekf", BendFormulation(), recovery=bare(freeze=1.0))
    s = est.run(t, z)
    if first is None:
        assert est.diagnostics.frozen_samples == 0 and est.diagnostics.first_freezes == {}
    else:
        assert s.status[0] == "uncertain" and set(s.status[1:first]) <= {"ok"}
        assert set(s.status[first:]) <= {"dropout", "no-estimate"}
        assert est.diagnostics.frozen_samples == k - first and est.diagnostics.first_freezes == {
            0: 0.0
        }
    # n - 1 equal readings 0.5 s apart (2 s in all, longer than the freeze), then a
    # change: never a freeze
    est = make_estimator("ekf", BendFormulation(), recovery=bare(freeze=1.0))
    z2 = z[: n + 1].copy()
    z2[n - 1 :] = [0.3, 0.0]
    est.run(0.5 * np.arange(n + 1), z2)
    assert est.diagnostics.frozen_samples == 0


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_equal_readings_on_both_sides_of_a_gap_are_not_a_freeze(method: str) -> None:
    """Five equal readings in 0.2 s, a 60 s gap, the same reading again: the count is
    reached and the span is 60 s, but nobody saw the sensor stuck through the gap, so
    it is not a freeze (the gap reset restarts from the reading after it)."""
    t = np.r_[0.05 * np.arange(5), 60.0, 60.05]
    z = np.r_[np.tile([0.1, 0.1], (6, 1)), [[0.5, -0.2]]]
    est = make_estimator(method, BendFormulation(), recovery=bare(gap_reset=1.0, freeze=1.0))
    s = est.run(t, z)
    assert est.diagnostics.frozen_samples == 0 and est.diagnostics.first_freezes == {}
    assert s.status[5] == "reset" and "dropout" not in set(s.status)


def test_freeze_samples_are_validated() -> None:
    assert RecoverySettings(freeze_samples=np.int64(3)).freeze_samples == 3
    for bad in (1, 0, 2.5, True, np.int64(1), 2**32 + 2):  # (a C int held the last as 4)
        with pytest.raises(ValueError, match="freeze_samples"):
            RecoverySettings(freeze_samples=bad)  # type: ignore[arg-type]
    t, z = np.array([0.0, 0.6, 1.2]), np.tile([0.1, 0.1], (3, 1))
    for samples, frozen in ((2, 1), (None, 0)):  # a caller may ask for fewer repeats
        kw = {} if samples is None else {"freeze_samples": samples}
        est = make_estimator("ekf", BendFormulation(), recovery=bare(freeze=1.0, **kw))
        est.run(t, z)
        assert est.diagnostics.frozen_samples == frozen, samples  # (the default sees none)


def test_uncertain_status_when_the_tip_std_exceeds_the_fraction() -> None:
    rec = simulate("paper3d", duration=4)
    # the status judges the estimator's own std: without the readings' constant errors
    noise = NoiseSettings(reading_bias_std=0, model_error_std=0)
    f = BendFormulation(robot=RobotSettings(length=0.2), noise=noise)
    base = make_estimator("ekf", f).run(rec.t, rec.z)
    tip_std = np.sqrt(np.sum(base.std[:, :3] ** 2, axis=1))
    # wide while the start settles (up to 1.5 s), narrow after
    frac = 1.01 * float(np.max(tip_std[rec.t > 1.5])) / 0.2
    s = make_estimator("ekf", f, recovery=bare(uncertain_fraction=frac)).run(rec.t, rec.z)
    assert_allclose(s.std, base.std)
    # uncertain while the tip std exceeds the fraction, and for the unobserved window
    # after it (1 s without a gap reset): the estimate that narrows again is held
    # until the readings have gone on agreeing with it
    wide = tip_std > frac * 0.2
    last_wide = np.maximum.accumulate(np.where(wide, s.t, -np.inf))
    expected = rec.t - last_wide < 1.0
    assert np.array_equal(s.status == "uncertain", expected)
    assert np.any(expected & ~wide) and 0 < np.sum(expected) < len(s.t)
    # the paper formulation's W is a weight, not a noise model: the fraction changes no
    # status (only a tip std past the robot's length does:
    # test_no_ok_row_of_the_paper_formulation_has_a_std_past_the_robot)
    paper = make_formulation("paper")
    runs = [
        make_estimator("ekf", paper, recovery=bare(uncertain_fraction=frac)).run(rec.t, rec.z)
        for frac in (1e-6, 100.0)
    ]
    assert list(runs[0].status) == list(runs[1].status) and np.isfinite(runs[0].std).all()


def test_no_ok_row_of_the_paper_formulation_has_a_std_past_the_robot() -> None:
    """The paper formulation's ``W = 10 I`` is a weight: its position variance grows by
    1/10 m^2 a step, past the 0.2 m robot's reach (std 0.32 m) after one step. No row
    of any method whose written tip standard deviation is past the robot's length is
    ``ok``: the EKF's first row is ``ok`` (its prior, 0.02 m a coordinate), every later
    one ``uncertain``, its standard deviations as the weight implies them (0.32 m and
    more)."""
    rec = simulate("paper3d", duration=5)
    paper = make_formulation("paper")
    for method in ("ekf", "ukf", "mhe"):
        s = make_estimator(method, paper).run(rec.t, rec.z)
        tip_std = np.linalg.norm(s.std[:, :3], axis=1)
        wide = tip_std > 0.2
        assert wide.sum() > 0 and not np.any(wide & (s.status == "ok")), method
        # only the width makes a row uncertain here (no consistency or start check)
        others = np.isin(s.status, ["drifted", "at-bound", "reset"])
        assert np.array_equal(s.status == "uncertain", wide & ~others), method
        if method == "ekf":
            assert list(s.status) == ["ok"] + ["uncertain"] * (len(rec.t) - 1)
            assert_allclose(s.std[0, :3], 0.02, rtol=1e-9)
            assert np.all(s.std[1:, :3] > math.sqrt(0.1))
        # sample by sample (as live steps) the same statuses
        stepper = make_estimator(method, paper)
        stepped = [stepper.step(Measurement(float(tk), zk)).status for tk, zk in zip(rec.t, rec.z)]
        assert stepped == list(s.status), method


def test_no_ok_row_has_a_written_tip_std_beyond_the_fraction() -> None:
    """With the readings' constant errors in the written std (the defaults), a row
    whose written tip std exceeds the fraction is not ``ok``, though the estimator's
    own std (without them) is within it: the fraction is of the std a user reads."""
    rec = simulate("paper3d", duration=4)
    f = BendFormulation(robot=RobotSettings(length=0.2))
    base = make_estimator("ekf", f, recovery=bare(uncertain_fraction=100.0)).run(rec.t, rec.z)
    tip_std = np.sqrt(np.sum(base.std[:, :3] ** 2, axis=1))
    frac = float(np.median(tip_std[rec.t > 1.5])) / 0.2  # half the settled rows beyond
    s = make_estimator("ekf", f, recovery=bare(uncertain_fraction=frac)).run(rec.t, rec.z)
    assert_allclose(s.std, base.std)
    beyond = tip_std > frac * 0.2
    assert np.sum(beyond & (rec.t > 1.5)) > 10
    assert not np.any(beyond & (s.status == "ok"))
    assert np.any(~beyond & (s.status == "ok"))


def test_recovery_settings_are_validated() -> None:
    with pytest.raises(ValueError, match="gap_reset"):
        RecoverySettings(gap_reset=-1.0)
    with pytest.raises(ValueError, match="uncertain_fraction"):
        RecoverySettings(uncertain_fraction=0.0)


def test_a_repeated_reading_is_not_frozen_without_freeze() -> None:
    est = make_estimator("ekf", BendFormulation(), recovery=bare())
    t = np.arange(100) * 0.05
    series = est.run(t, np.tile([0.1, 0.1], (100, 1)))
    assert est.diagnostics.frozen_samples == 0 and set(series.status[1:]) == {"ok"}


@pytest.mark.parametrize("case", ["cauchy", "two-sections"])
def test_compiled_and_casadi_covariance_agree_at_the_same_window_solution(case: str) -> None:
    """The covariance formula itself, without the backends' different evaluation points
    (the fast SQP's last iterate against IPOPT's answer, compared to 1e-4 above): at the
    same window and the same ``X``, the compiled model's Gauss-Newton Hessian
    (``window_covariance`` without ``hessian``) and the CasADi one agree to 1e-9."""
    from continuum_mhe.estimators.fast.covariance import (
        casadi_window_covariance,
        window_covariance,
    )
    from continuum_mhe.estimators.fast.model import LossKernel
    from continuum_mhe.estimators.loss import LOSS_CODES, block_array
    from continuum_mhe.estimators.mhe import MHESettings as Settings
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    if case == "cauchy":
        f = BendFormulation()
        rec = simulate("paper3d", duration=3)
        z = rec.z.copy()
        z[[20, 41]] += np.radians(30.0)
        settings = Settings(horizon=10, loss="cauchy")
    else:
        robot = read_robot("two-section")
        f = make_formulation("bend", robot)
        rec = simulate_robot("spatial", robot, duration=1.5)
        z = rec.z.copy()
        z[10:20, 2:4] = np.nan
        settings = Settings(horizon=8)
    est = MovingHorizonEstimator(f, settings)
    windows = fast_windows(est, rec.t, z)
    s = est.inference.settings
    loss = LossKernel(block_array(f.measurement_blocks), LOSS_CODES[s.loss], float(s.scale))
    compared = 0
    model = est.inference._fast
    assert model is not None
    for problem, _, _, res in windows:
        X = res.X
        a = window_covariance(model, problem, X)
        b = casadi_window_covariance(f, problem, X, model.feasible, loss=loss)
        assert (a is None) == (b is None)
        if a is not None:
            assert_allclose(a, b, rtol=1e-9, atol=1e-15)
            compared += 1
    assert compared > 20


def test_half_a_second_of_a_frozen_raw_imu_at_100_hz_is_caught_by_default(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The default ``--freeze`` catches a raw IMU that repeats its six readings for 0.5 s
    at 100 Hz (a 1 s threshold would not), from 0.2 s into the freeze."""
    rec = tmp_path / "rec.csv"
    argv = ["simulate", "spatial", "--robot", "two-section", "--imu", "raw", "--dt", "0.01",
            "--duration", "3", "-o", str(rec)]  # fmt: skip
    assert main(argv) == 0
    lines = rec.read_text().splitlines()
    names = lines[0].split(",")
    cols = [names.index(f"{c}_2") for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    rows = [ln.split(",") for ln in lines[1:]]
    for row in rows[151:200]:  # IMU 2 repeats its reading of t = 1.5 s until 1.99 s
        for c in cols:
            row[c] = rows[150][c]
    rec.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    capsys.readouterr()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(rec), "--robot", "two-section", "-o", str(out),
                 "--method", "ekf"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "IMU 2 repeated the same reading for more than 0.2 s from t=1.5 s" in err
    assert "29 of the 301 estimates had a frozen IMU" in err  # 1.71 to 1.99 s


def test_estimate_says_once_that_a_still_recording_is_frozen(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hand-written recording of a still robot (the same roll and pitch for 10 s at
    20 Hz): one note when the freeze begins, and a summary that counts the frozen samples
    by status (t = 1.05 s on: 179) and the restart behind the no-estimate rows, not
    `dropout: 75, no-estimate: 104` alone; --freeze 0 estimates every row."""
    meas = tmp_path / "still.csv"
    meas.write_text("t,roll,pitch\n" + "".join(f"{0.05 * i:.2f},0.1,-0.2\n" for i in range(200)))
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--method", "ekf"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == (
        "continuum-mhe: note: IMU 1 repeated the same reading for more than 0.2 s from t=0 s: "
        "treated as frozen (a dropout) while it repeats; --freeze 0 turns this off "
        "(RecoverySettings(freeze=None) in Python)"
    )
    assert len(err) == 2
    assert err[1].startswith(
        f"wrote 200 estimates to {tmp_path / 'e.csv'} "
        "(dropout: 74, no-estimate: 121, ok: 4, uncertain: 1); "
        "195 of the 200 estimates had a frozen IMU (the same reading for over 0.2 s, treated "
        "as a dropout): "
        "dropout: 74, no-estimate: 121; restarted 1 time(s) after the estimate diverged"
    )
    args = ["estimate", str(meas), "-o", str(tmp_path / "e0.csv"), "--freeze", "0"]
    assert main([*args, "--method", "ekf"]) == 0
    assert capsys.readouterr().err.splitlines() == [
        f"wrote 200 estimates to {tmp_path / 'e0.csv'} (ok: 199, uncertain: 1)"
    ]


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_a_dropout_does_not_narrow_the_standard_deviations(
    tmp_path: Path, method: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 1 missing for two samples of the shipped spatial-tendon recording (raw): the
    standard deviations there are not those of IMU 2's constant reading errors alone (up
    to 3.2 times narrower than with both IMUs, std_theta_2 0.057 -> 0.018 rad, rows
    0.027 rad off), since IMU 1's errors are in the estimate through the samples before.
    Losing a reading never narrows them: within 3 % of the run without the dropout (the
    estimates differ a little). The recording's first 6 s (300 rows) are estimated: the
    rows up to the dropout's are those of the whole recording's estimates."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    lines = (data / "spatial-tendon_raw.csv").read_text().splitlines()[:301]
    header = lines[0].split(",")
    cut = [lines[0]]
    for i, line in enumerate(lines[1:]):
        fields = line.split(",")
        if i in (250, 251):
            for name in ("ax_1", "ay_1", "az_1", "gx_1", "gy_1", "gz_1"):
                fields[header.index(name)] = "nan"
        cut.append(",".join(fields))
    dropped, clean = tmp_path / "dropped.csv", tmp_path / "clean.csv"
    dropped.write_text("\n".join(cut) + "\n")
    clean.write_text("\n".join(lines) + "\n")
    runs = []
    for src, extra in ((clean, []), (dropped, ["--skip-bad"])):
        out = tmp_path / f"est_{src.stem}.csv"
        argv = ["estimate", str(src), "--robot", "two-section", "--method", method, "-o", str(out)]
        assert main([*argv, *extra]) == 0
        runs.append(read_state_table(out))
    capsys.readouterr()
    clean, with_dropout = runs
    for name in ("theta_1", "theta_2", "x", "y", "z"):
        narrow = with_dropout.std_column(name)[250:252] / clean.std_column(name)[250:252]
        assert np.all(narrow >= 0.97), (name, narrow)


def test_the_nees_band_holds_the_average_nees_of_axes_correlated_with_each_other() -> None:
    """Errors whose standard deviations are right but whose tip axes are correlated (x
    and z at -0.9, as a bent section's can be): each row's ``sum (e / std)^2`` still
    averages 3 but varies more than ``chi2(3)``, so the band of uncorrelated axes holds
    the average of 200 rows in too few recordings (0.92 here); the band for the
    correlation the errors show holds it in 95 % or a little more (the effective count
    of independent rows comes out a little low)."""
    rng = np.random.default_rng(11)
    n, trials = 200, 600
    C = np.array([[1.0, 0.0, -0.9], [0.0, 1.0, 0.0], [-0.9, 0.0, 1.0]])
    L = np.linalg.cholesky(C)
    inside = inside_naive = 0
    for _ in range(trials):
        e = rng.standard_normal((n, 3)) @ L.T
        c = compute_calibration(e, np.ones((n, 3)), np.zeros((n, 3)), ["x", "y", "z"])
        lo, hi = c.tip_nees_band
        inside += lo <= c.tip_nees <= hi
        lo, hi = nees_band(3, c.tip_n_eff)
        inside_naive += lo <= c.tip_nees <= hi
    assert 0.94 <= inside / trials <= 0.99, inside / trials
    assert inside_naive / trials <= 0.935, inside_naive / trials
    assert nees_band(3, 50.0, corr=np.eye(3)) == pytest.approx(nees_band(3, 50.0), rel=1e-12)


def test_the_nees_band_holds_the_average_nees_of_errors_correlated_in_time() -> None:
    """Errors whose standard deviation is right but which are correlated in time (an
    AR(1) series, as a filter's are): the average NEES falls inside its band in about
    95 % of recordings with the effective sample count, far less often with the band of
    independent samples; the count is n (1 - a^2) / (1 + a^2) for coefficient a (the
    NEES of such errors is correlated as a^2 per lag)."""
    from continuum_mhe.evaluation.metrics import effective_samples

    rng = np.random.default_rng(5)
    n, a, trials = 400, 0.9, 300
    inside = inside_naive = 0
    counts = []
    for _ in range(trials):
        e = np.empty((n, 3))
        e[0] = rng.standard_normal(3)
        for k in range(1, n):  # unit variance throughout
            e[k] = a * e[k - 1] + np.sqrt(1 - a * a) * rng.standard_normal(3)
        c = compute_calibration(e, np.ones((n, 3)), np.zeros((n, 3)), ["x", "y", "z"])
        counts.append(c.tip_n_eff)
        lo, hi = c.tip_nees_band
        inside += lo <= c.tip_nees <= hi
        lo, hi = nees_band(3, n)
        inside_naive += lo <= c.tip_nees <= hi
    assert 0.88 <= inside / trials <= 0.99, inside / trials
    assert inside_naive / trials < 0.6, inside_naive / trials
    want = n * (1 - a * a) / (1 + a * a)
    assert np.median(counts) == pytest.approx(want, rel=0.3)
    assert effective_samples(rng.standard_normal(2000)) == pytest.approx(2000, rel=0.15)
    anti = np.empty(2000)  # anti-correlated: no fewer samples than independent ones
    anti[0] = 0.0
    for k in range(1, 2000):
        anti[k] = -0.9 * anti[k - 1] + rng.standard_normal()
    assert effective_samples(anti) == 2000
    assert effective_samples(np.array([1.0, np.nan, 2.0, np.inf, 3.0, 4.0, 2.5])) <= 5


@pytest.mark.parametrize("method", ["ekf", "ukf", "mhe"])
def test_no_written_std_exceeds_half_its_outputs_range(method: str) -> None:
    """On the shipped torsion-stiff rod (tilt IMUs), the rows whose readings the estimate
    cannot explain have their covariance widened until the shift that fits the readings
    lies within it: the EKF's written ``std_x`` reached 7.6 m on this 0.3 m robot, and
    ``std_theta_2`` 121 rad. No distribution within a range has a standard deviation
    beyond half its width, so each written one is held to that (the backbone's length up
    to the point for a coordinate, pi for a wrapped angle, half of ``theta_max`` for a
    bend, half of pi for an MHE's estimate held on its bound, which may not be the
    robot's): the limit is reached on rows that are not ``ok``, and the ``ok`` rows are
    within it by themselves."""
    from continuum_mhe.io import load_input, read_robot
    from continuum_mhe.io.input_options import InputOptions

    f = make_formulation("bend", read_robot("two-section"))  # 0.16 m + 0.14 m, theta_max 3
    want = {"x": 0.3, "y": 0.3, "z": 0.3, "theta_1": 1.5, "phi_1": math.pi, "x_1": 0.16,
            "theta_2": 1.5, "phi_2": math.pi, "x_2": 0.3}  # fmt: skip
    limit = f.output_std_limit()
    names = [o.name for o in f.outputs]
    for name, value in want.items():
        assert limit[names.index(name)] == pytest.approx(value, rel=1e-12)
    path = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2/spatial-stiff-torsion_tilt.csv"
    data = load_input(str(path), InputOptions(), f)
    s = make_estimator(method, data.formulation).run(data.t, data.z)
    written = np.nan_to_num(s.std)
    # an estimate held on a bending bound: its bend within 0 and pi
    on = np.asarray(s.status) == Status.AT_BOUND.value
    limits = np.where(on[:, None], f.output_std_limit(beyond_bound=True), limit)
    if method != "mhe":  # (the filters do not hold the bound)
        limits = np.broadcast_to(limit, written.shape)
    assert np.all(written <= limits)
    at_limit = np.isclose(written, limits, rtol=1e-12).any(axis=1)
    assert at_limit.sum() >= (1 if method == "mhe" else 20)
    assert not np.any(at_limit & (s.status == "ok"))


def test_the_paper_formulations_std_is_written_as_its_weight_implies() -> None:
    """``--formulation paper``: its ``W`` is a weight, not a noise model, and its position
    std grows to metres as the model implies; it is not held to the robot's range (0.2 m
    here), which would write every row's std as that limit."""
    rec = simulate("paper3d", duration=4)
    f = make_formulation("paper")
    for method in ("ekf", "mhe"):
        s = make_estimator(method, f).run(rec.t, rec.z)
        assert np.nanmedian(s.std[:, 0]) > 1.0
