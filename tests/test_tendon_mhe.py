"""The fast MHE's window on the tendon robot's mechanics model: the window's residuals
and Jacobians from the residual's instructions alone (forward mode in the core,
Gauss-Newton steps) and its gradient against finite differences of its cost. (Its
answer against the MHE on IPOPT on the same windows, 2.7e-6 apart where 1e-6 is the
target: ``python tools/tendon_mhe_windows.py``, docs/tendon-studies.md.)"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

import continuum_mhe.estimators.fast.model as fm
from continuum_mhe.estimators.fast import Workspace, window_cost
from continuum_mhe.estimators.fast.sqp import _weights
from continuum_mhe.estimators.mhe import WindowProblem
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.results import Status

DATA = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
HORIZON = 3


@lru_cache(maxsize=1)
def _formulation() -> TendonFormulation:
    """The shipped robot with tilt IMUs, as the command line makes it."""
    robot = read_robot("tendon-two-section")
    base = make_formulation("bend", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    assert isinstance(f, TendonFormulation)
    return f


def _window(first: int, tension_offset: float) -> tuple[WindowProblem, np.ndarray]:
    """The window of samples ``first .. first + HORIZON - 1`` of ``twist-08`` (tilt),
    every node active, the arrival prior on node 0 (the start's covariance), and a
    trajectory: each node the start's fit to its own sample, the tension states
    ``tension_offset`` N above the given tensions (a slack tendon's clipped tension has
    a kink at zero, where no derivative matches a finite difference)."""
    f = _formulation()
    lines = (DATA / "twist-08_tilt.csv").read_text().splitlines()
    rows = np.loadtxt([ln for ln in lines if not ln.startswith("#")][1:], delimiter=",")
    rows = rows[first : first + HORIZON]
    tensions = read_tensions(DATA / "twist-08_tensions.csv", f.robot.n_tendons)
    z = np.array([f.measurement_row(r[1:5], *tensions.at(r[0])) for r in rows])
    X = np.array([f.initial_state(zk) for zk in z])
    k = f.robot.n_tendons
    X[:, 6 : 6 + k] += tension_offset
    dt = np.diff(rows[:, 0])
    qinv = np.array([ProcessNoiseCache(f)(float(h))[1] for h in dt])
    arrival = np.zeros((HORIZON, f.nx, f.nx))
    arrival[0] = np.linalg.inv(f.initial_cov())
    problem = WindowProblem(
        z=z, zmask=np.ones_like(z), dt=dt, u=np.zeros((HORIZON - 1, f.nu)), qinv=qinv,
        xbar=X[0].copy(), arrival=arrival,
    )  # fmt: skip
    return problem, X


def _core_gradient_norm(model: fm.WindowModel, problem: WindowProblem, X: np.ndarray) -> float:
    """The norm of the window cost's gradient at ``X`` as the compiled core assembles it
    (from its own forward-mode Jacobians)."""
    ws = Workspace(model)
    ws.load(problem, X)
    ws.core.evaluate(0, *_weights(problem))
    return float(np.linalg.norm(np.asarray(ws.g[0]).ravel()))


def test_the_window_gradient_is_the_derivative_of_its_cost() -> None:
    """The gradient the window solver assembles (from the forward-mode Jacobians)
    against central differences of the window cost along random directions."""
    f = _formulation()
    model = fm.build_window_model(f, HORIZON)
    assert not model.second_order_residuals
    problem, X = _window(200, 0.05)
    X[1:] += 0.01 * np.random.default_rng(0).normal(size=X[1:].shape)  # off the start
    ws = Workspace(model)
    ws.load(problem, X)
    ws.core.evaluate(0, *_weights(problem))
    g = np.asarray(ws.g[0]).ravel()
    rng = np.random.default_rng(1)
    for _ in range(4):
        v = rng.normal(size=X.shape)
        v /= np.linalg.norm(v)
        h = 1e-6
        fd = (window_cost(model, problem, X + h * v) - window_cost(model, problem, X - h * v)) / (
            2 * h
        )
        assert abs(fd - g @ v.ravel()) <= 1e-6 * np.linalg.norm(g)


def test_the_ipopt_window_of_the_shooting_model_is_per_node_with_the_same_cost() -> None:
    """The MHE on IPOPT keeps the shooting model a function called per node (CasADi MX,
    with a Gauss-Newton Hessian: expanded, with its exact Hessian, a window takes 7 GB at
    N = 5 and more than 11 GB at N = 10), its cost is the window cost the compiled
    solver evaluates, on the same window, and IPOPT solves that window."""
    from continuum_mhe.estimators.window_nlp import build_nlp, pack_parameters

    f = _formulation()
    nlp = build_nlp(f, HORIZON, 10, 1e-8)
    assert nlp.cost.is_a("MXFunction")  # not expanded over the window (SX)
    problem, X = _window(200, 0.05)
    X[1:] += 0.01 * np.random.default_rng(2).normal(size=X[1:].shape)
    # the decision variables are the (nx, N) states column-major: X (N, nx) row by row
    ipopt_cost = float(nlp.cost(X.ravel(), pack_parameters(problem)))
    model = fm.build_window_model(f, HORIZON)
    assert ipopt_cost == pytest.approx(window_cost(model, problem, X), rel=1e-12)
    # with the Gauss-Newton Hessian (the residuals' first derivatives) IPOPT converges
    # on the window (with limited-memory BFGS it stops at its iteration limit)
    solved = build_nlp(f, HORIZON, 100, 1e-8)
    out = solved.solver(x0=X.ravel(), p=pack_parameters(problem), lbx=solved.lbx,
                        ubx=solved.ubx, lbg=solved.lbg, ubg=solved.ubg)  # fmt: skip
    assert solved.solver.stats()["return_status"] == "Solve_Succeeded"
    best = np.asarray(out["x"]).reshape(HORIZON, f.nx)
    # IPOPT's answer is a stationary point of the compiled solver's window cost: the
    # gradient the core assembles there (from its own forward-mode Jacobians) is a
    # vanishing fraction of the one at the start (4e9, the tip condition's 1e8 weights)
    assert _core_gradient_norm(model, problem, best) < 1e-7 * _core_gradient_norm(model, problem, X)
    assert window_cost(model, problem, best) < window_cost(model, problem, X)


def test_a_robust_loss_weighs_the_imus_alone_and_ipopt_solves_its_window() -> None:
    """A robust loss acts on the IMUs' readings alone: the tip condition (a constraint
    the shape must keep, its residuals here far beyond the loss's scale) and the given
    tensions keep their quadratic cost, in the MHE on IPOPT's window and in the compiled
    window cost alike; IPOPT solves the window with the loss's Gauss-Newton Hessian, and
    its answer is a stationary point of the compiled cost (the core's gradient there, its
    per-block loss included, vanishes). With the loss on every block the tip condition
    would be down-weighted and the estimate drift off (``force-29`` raw, N = 3: 43 mm off
    at the 24th sample, every window ``not-converged``)."""
    from continuum_mhe.estimators.window_nlp import build_nlp, pack_parameters

    f = _formulation()
    scale = 1.345
    problem, X = _window(200, 0.05)
    X[1:] += 0.01 * np.random.default_rng(2).normal(size=X[1:].shape)
    p = pack_parameters(problem)
    quadratic = float(build_nlp(f, HORIZON, 10, 1e-8).cost(X.ravel(), p))
    rinv = np.linalg.inv(f.meas_cov())
    expected, beyond = quadratic, []
    for i in range(HORIZON):
        r = np.asarray(f.functions.innovate(problem.z[i], X[i])[0], dtype=float).ravel()
        for b in f.measurement_blocks:
            s = float(r[b.slice] @ rinv[b.slice, b.slice] @ r[b.slice])
            if b.is_imu:
                huber = s if s <= scale**2 else 2.0 * scale * math.sqrt(s) - scale**2
                expected += 0.5 * (huber - s)
            elif s > scale**2:
                beyond.append(b.kind)
    assert "equilibrium" in beyond
    robust = build_nlp(f, HORIZON, 100, 1e-8, "huber", scale)
    assert float(robust.cost(X.ravel(), p)) == pytest.approx(expected, rel=1e-12)
    model = fm.build_window_model(f, HORIZON, "huber", scale)
    assert window_cost(model, problem, X) == pytest.approx(expected, rel=1e-12)
    out = robust.solver(x0=X.ravel(), p=p, lbx=robust.lbx, ubx=robust.ubx, lbg=robust.lbg,
                        ubg=robust.ubg)  # fmt: skip
    assert robust.solver.stats()["return_status"] == "Solve_Succeeded"
    best = np.asarray(out["x"]).reshape(HORIZON, f.nx)
    assert _core_gradient_norm(model, problem, best) < 1e-7 * _core_gradient_norm(model, problem, X)


def test_the_branch_check_judges_the_readings_alone() -> None:
    """The branch check's chi-square test counts the rows the consistency check judges:
    a tendon robot's IMU readings and tensions, not its tension rates (inputs, a zero
    residual at every state) nor its tip condition (a pseudo-measurement with a tiny
    standard deviation, whose residual far exceeds it off the equilibrium), in its
    degrees of freedom and in its measurement cost, from the residuals and from the
    window cost alike; and the shortcut that passes a window on its window cost alone
    takes the same degrees of freedom."""
    from continuum_mhe.estimators.branch import BranchCheck

    f = _formulation()
    problem, X = _window(200, 0.0)
    # off the equilibrium: the tip condition's residuals are thousands of its standard
    # deviations (its share of every row's cost: 1e4 against the readings' 3)
    X[1:] += 1e-4 * np.random.default_rng(2).normal(size=X[1:].shape)
    problem.zmask[1, 0] = 0.0  # one IMU reading missing
    readings = f.n_imu_measurements + f.robot.n_tendons  # 4 tilt angles, 6 tensions
    assert readings == 10 and f.nz == 25
    rinv = np.linalg.inv(f.meas_cov())
    expected = 0.0  # r^T R^-1 r over the valid readings (R diagonal)
    for i in range(HORIZON):
        r = np.asarray(f.functions.innovate(problem.z[i], X[i])[0], dtype=float).ravel()
        r = r[:readings] * problem.zmask[i, :readings]
        expected += float(r @ rinv[:readings, :readings] @ r)
    check = BranchCheck(f, HORIZON, quadratic=False)
    c, dof = check.measurement_cost(problem, X)
    assert dof == HORIZON * readings - 1
    assert c == pytest.approx(expected, rel=1e-9)
    model = fm.build_window_model(f, HORIZON)
    quadratic = BranchCheck(f, HORIZON)
    c, dof = quadratic.measurement_cost(problem, X, lambda p, Xc: window_cost(model, p, Xc))
    assert dof == HORIZON * readings - 1
    assert c == pytest.approx(expected, rel=1e-9)
    # a window cost whose twice lies between the limits of 29 and 74 degrees of freedom:
    # evaluated, not passed on it alone
    limits = quadratic.plausible_limits
    assert limits is not None
    window = 0.25 * (limits[HORIZON * readings - 1] + limits[HORIZON * f.nz - 1])
    quadratic.check(problem, X, Status.OK, _no_solve, lambda p, Xc: 0.0, window_cost=window)
    assert quadratic.stats.evaluated == 1


def _no_solve(problem: WindowProblem, X0: np.ndarray) -> tuple[np.ndarray, Status, object]:
    raise AssertionError("the window is plausible: no restart")
