"""The fast MHE backend against the IPOPT reference, on the very same window problems.

Each window problem is recorded while the IPOPT estimator runs (same data, same
arrival prior, same initial guess); the fast solver then solves that problem and is
compared with IPOPT's answer: states, cost, active bounds, exact feasibility.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from estimator_helpers import bare
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators import fast as fm
from continuum_mhe.estimators.kalman import ekf_predict, ekf_update
from continuum_mhe.estimators.mhe import (
    BackendFallbackWarning,
    MovingHorizonEstimator,
    WindowProblem,
)
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import SINGLE_SECTION_SCENARIOS, simulate

#: agreement with IPOPT: angles (rad, rad/s), and positions (m) of the paper
#: formulation. Those are tied to the angles only by the process penalty (W = 10 per
#: step), so the cost is flat along them and IPOPT stops up to ~1e-3 m away from
#: its own optimum (the fast answer then has the lower cost, which is checked).
ANGLE_TOL = 1e-6
POSITION_TOL = 1e-3


@dataclass
class Window:
    problem: WindowProblem
    X0: FloatArray
    X_ipopt: FloatArray
    status: str


@dataclass
class Recorded:
    estimator: MovingHorizonEstimator
    windows: list[Window] = field(default_factory=list)


def record_ipopt(
    formulation: Formulation, horizon: int, t: FloatArray, z: FloatArray, tol: float = 1e-8
) -> Recorded:
    """Run the IPOPT estimator (tolerance ``tol``) and keep every window problem it solved."""
    settings = MHESettings(horizon=horizon, solver="ipopt", tol=tol)
    est = MovingHorizonEstimator(formulation, settings, recovery=bare())
    rec = Recorded(est)
    solve = est.inference._solve

    def recording_solve(problem: WindowProblem, X0: FloatArray) -> tuple[FloatArray, str]:
        X, status = solve(problem, X0)
        kept = WindowProblem(**{k: np.copy(v) for k, v in vars(problem).items()})
        rec.windows.append(Window(kept, X0.copy(), X.copy(), status))
        return X, status

    est.inference._solve = recording_solve  # type: ignore[method-assign, assignment]
    est.run(t, z)
    return rec


def tolerance(formulation: Formulation) -> FloatArray:
    """Per-state agreement tolerance."""
    if formulation.name == "paper":
        return np.array([POSITION_TOL] * 3 + [ANGLE_TOL] * 2)
    return np.full(formulation.nx, ANGLE_TOL)


#: :func:`feasible` 's answers, by the formulation object's id (the formulation kept alive)
_FEASIBLE: dict[int, tuple[Formulation, fm.Feasible]] = {}


def feasible(formulation: Formulation) -> fm.Feasible:
    """:func:`fm.feasible_set` of ``formulation``, read once per formulation object: it
    checks the CasADi constraint anew at each call (3 ms), and :func:`check_window` asks
    for it three times per window (2.5 s of the 201 windows of the two-section test)."""
    kept = _FEASIBLE.get(id(formulation))
    if kept is None or kept[0] is not formulation:
        kept = _FEASIBLE[id(formulation)] = (formulation, fm.feasible_set(formulation))
    return kept[1]


def assert_feasible_exactly(formulation: Formulation, X: FloatArray) -> None:
    fs = feasible(formulation)
    assert np.all(X >= fs.lo) and np.all(X <= fs.hi)
    for idx, r2 in zip(fs.ball_idx, fs.ball_r2):
        assert np.all(np.sum(X[:, idx] ** 2, axis=1) <= r2)


def at_bounds(formulation: Formulation, X: FloatArray, tol: FloatArray | float) -> FloatArray:
    """(N, nx + nb) flags: box coordinates within ``tol`` (per coordinate) of a bound,
    and each ball within ``max(tol)`` of its boundary (1e-14 relative for rounding)."""
    fs = feasible(formulation)
    box = (X <= fs.lo + tol) | (X >= fs.hi - tol)
    balls = [
        np.sqrt(np.sum(X[:, idx] ** 2, axis=1)) >= math.sqrt(r2) * (1 - 1e-14) - np.max(tol)
        for idx, r2 in zip(fs.ball_idx, fs.ball_r2)
    ]
    return np.column_stack([box, *balls])


def check_window(formulation: Formulation, rec: Recorded, w: Window, res: fm.FastResult) -> bool:
    """Check one fast answer against IPOPT's; True if the states agree.

    The answer must be certified and exactly feasible, and either agree with IPOPT
    (states and active bounds) or reach a cost no higher than IPOPT's answer made
    feasible (degenerate windows of the paper formulation, near ``theta = 0`` or with
    ``phi`` on its +-pi bound, where IPOPT's answer violates the bounds by its
    relaxation (~1e-8) and the positions are weakly determined). A higher cost is
    accepted only for the paper formulation, on ``theta = 0``, at a KKT point there
    (:func:`assert_first_order_minimum`): a different local minimum.
    """
    assert res.converged, res.outcome
    assert_feasible_exactly(formulation, res.X)
    tol = tolerance(formulation)
    if np.all(np.abs(res.X - w.X_ipopt) <= tol):
        # same active set: active here <=> IPOPT's answer within tolerance of the bound
        fast_active = at_bounds(formulation, res.X, 0.0)
        assert np.all(at_bounds(formulation, w.X_ipopt, tol)[fast_active])
        assert np.all(fast_active[at_bounds(formulation, w.X_ipopt, 1e-9)])
        return True
    X_feasible = np.array([formulation.project(x) for x in w.X_ipopt])
    ipopt_cost = rec.estimator.inference.window_cost(w.problem, X_feasible)
    if res.cost <= ipopt_cost + 1e-9:
        return False
    # the one documented exception (docs/fast-solver.md): the paper formulation has local
    # minima on theta = 0 (phi is free there and a first-order penalty keeps theta on its
    # bound); an active-set solver with feasible iterates can stop in one where IPOPT's
    # interior path avoids it. Then the answer must lie on theta = 0 and be such a minimum.
    on_theta_zero = formulation.name == "paper" and bool(np.any(res.X[:, 3] == 0.0))
    assert on_theta_zero, (res.cost, ipopt_cost)
    assert_first_order_minimum(formulation, rec, w, res.X)
    return False


#: First-order optimality of a window answer, by differences of step ``KKT_STEP`` of
#: IPOPT's objective, relative to ``max(1, cost)``. The fast answers that stop on
#: ``theta = 0`` above IPOPT's cost meet it to 3e-10 (26 windows of the straight,
#: planar-overbend and paper3d recordings, N = 2, 4, 12); their initial guesses, and
#: the answers with ``phi`` turned by 0.05 rad, miss it by 6e-6 or more.
KKT_TOL = 1e-7
KKT_STEP = 1e-6


def assert_first_order_minimum(
    formulation: Formulation, rec: Recorded, w: Window, X: FloatArray
) -> None:
    """``X`` is a KKT point of the window problem on its box: along every state
    coordinate of every node, IPOPT's objective (:meth:`window_cost`, not the fast
    model) has zero slope by central differences or, on a bound, does not descend into
    the box (a second-order one-sided difference). Box bounds only (no balls)."""
    assert fm.feasible_set(formulation).ball_idx.size == 0
    lo, hi = formulation.state_bounds()
    c0 = rec.estimator.inference.window_cost(w.problem, X)
    h = KKT_STEP

    def cost(k: int, j: int, step: float) -> float:
        Y = X.copy()
        Y[k, j] += step
        return rec.estimator.inference.window_cost(w.problem, Y)

    worst = 0.0
    for k, j in np.ndindex(*X.shape):
        if X[k, j] <= lo[j]:  # the slope into the box may be positive, not negative
            v = max(0.0, (3 * c0 - 4 * cost(k, j, h) + cost(k, j, 2 * h)) / (2 * h))
        elif X[k, j] >= hi[j]:
            v = max(0.0, (3 * c0 - 4 * cost(k, j, -h) + cost(k, j, -2 * h)) / (2 * h))
        else:
            v = abs(cost(k, j, h) - cost(k, j, -h)) / (2 * h)
        worst = max(worst, v)
    assert worst <= KKT_TOL * max(1.0, abs(c0)), (worst, c0)


def compare_windows(
    formulation: Formulation, rec: Recorded, min_agree: float = 1.0, min_certified: float = 1.0
) -> None:
    """Fast vs IPOPT on every recorded window, from IPOPT's own initial guess.

    Windows the fast solver does not certify (they go to IPOPT in the estimator)
    must be at most ``1 - min_certified`` of all; the others are checked.
    """
    model = fm.build_window_model(formulation, rec.estimator.inference.settings.horizon)
    results = [fm.solve_window(model, w.problem, w.X0) for w in rec.windows]
    certified = [(w, r) for w, r in zip(rec.windows, results) if r.converged]
    assert len(certified) >= min_certified * len(rec.windows)
    agree = sum(check_window(formulation, rec, w, r) for w, r in certified)
    assert agree >= min_agree * len(certified)


@settings(
    max_examples=6,
    deadline=None,
    phases=[Phase.explicit, Phase.generate],  # no shrinking: failures stay quick
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(
    name=st.sampled_from(["bend", "paper"]),
    scenario=st.sampled_from(SINGLE_SECTION_SCENARIOS),
    noise_deg=st.floats(0.2, 6.0),
    seed=st.integers(0, 10_000),
    horizon=st.sampled_from([2, 4, 12]),
)
def test_agrees_with_ipopt(
    name: str, scenario: str, noise_deg: float, seed: int, horizon: int
) -> None:
    f = make_formulation(name)  # type: ignore[arg-type]
    rec_data = simulate(scenario, duration=3.0, noise_deg=noise_deg, seed=seed)  # type: ignore[arg-type]
    rec = record_ipopt(f, horizon, rec_data.t, rec_data.z)
    # the paper formulation's degenerate windows (theta ~ 0, phi on +-pi, theta on its
    # bound) converge slowly under Gauss-Newton, a few go to IPOPT (see
    # test_fallback_to_ipopt...), and on its bound the fast answer may differ from
    # IPOPT's at no higher cost (check_window; 43 of 61 windows of planar-overbend, seed
    # 4096, N = 4); the bend formulation has no such windows: every one agrees
    exact = name == "bend"
    compare_windows(f, rec, min_agree=1.0 if exact else 0.0, min_certified=1.0 if exact else 0.9)


def test_estimator_backends_agree_with_dropouts() -> None:
    """Whole recordings, default formulation: the same estimates to 1e-6."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=4.0, seed=3)
    z = rec.z.copy()
    z[20:24] = np.nan  # a dropout
    z[50, 1] = np.nan  # one missing channel
    out = {}
    for solver in ("ipopt", "fast"):
        est = MovingHorizonEstimator(f, MHESettings(horizon=15, solver=solver))
        out[solver] = est.run(rec.t, z)
    fast, ipopt = out["fast"], out["ipopt"]
    assert list(fast.status) == list(ipopt.status)
    assert {"dropout", "ok"} <= set(fast.status)
    np.testing.assert_allclose(fast.output, ipopt.output, atol=1e-6, rtol=0)


def test_paper_formulation_recording_is_feasible_and_flagged() -> None:
    """The paper formulation over a recording: every estimate feasible, statuses known.

    Whole recordings of the paper formulation are not compared: its windows near
    ``theta = 0`` and on ``phi = +-pi`` are non-convex, and two exact solvers may
    pick different minima and then follow different arrival priors. Each window is
    compared in :func:`test_agrees_with_ipopt`.
    """
    f = make_formulation("paper")
    rec = simulate("planar-overbend", duration=8.0, seed=3)
    z = rec.z.copy()
    z[20:24] = np.nan
    est = MovingHorizonEstimator(f, MHESettings(horizon=15))
    series = est.run(rec.t, z)
    # uncertain: its weight W makes its position std grow past the robot's length
    assert set(series.status) <= {"ok", "dropout", "fallback-ipopt", "drifted", "uncertain"}
    lo, hi = f.state_bounds()
    own = series.status != "fallback-ipopt"  # IPOPT relaxes its bounds by ~1e-8
    assert np.all(series.output[own] >= lo) and np.all(series.output[own] <= hi)
    assert np.all(series.output >= lo - 1e-7) and np.all(series.output <= hi + 1e-7)


def test_straight_configuration() -> None:
    """The bend vector passes through zero (phi undefined there): the estimators start
    at 3.5 s and every full window up to 5.75 s is compared (the robot is straight
    around 5 s)."""
    rec = simulate("straight", duration=6.0, seed=1)
    for name in ("bend", "paper"):
        f = make_formulation(name)
        windows = record_ipopt(f, 10, rec.t[70:115], rec.z[70:115])
        windows.windows = windows.windows[10:]
        exact = name == "bend"  # no degenerate windows: every one agrees with IPOPT's
        compare_windows(f, windows, min_agree=1.0 if exact else 0.9, min_certified=0.9)


def test_bounds_active_over_the_whole_window() -> None:
    """planar-overbend after 7 s: the truth lies beyond theta_max on every node, and
    the bound is active on most of the window: the fast backend has IPOPT's active set,
    and holds the bound exactly where it is active (the estimators start at 5.5 s)."""
    rec = simulate("planar-overbend", duration=8.5, seed=2)
    for name in ("bend", "paper"):
        f = make_formulation(name)
        recd = record_ipopt(f, 10, rec.t[110:], rec.z[110:])
        late = [w for w in recd.windows[-20:]]  # windows ending after 7.5 s
        recd.windows = late
        compare_windows(f, recd)
        model = fm.build_window_model(f, 10)
        theta_max = f.robot.theta_max
        for w in late:
            X = fm.solve_window(model, w.problem, w.X0).X
            if name == "bend":
                theta, theta_ipopt = np.hypot(X[:, 0], X[:, 1]), np.hypot(*w.X_ipopt[:, :2].T)
            else:
                theta, theta_ipopt = X[:, 3], w.X_ipopt[:, 3]
            active = theta_ipopt >= theta_max - 1e-7
            assert active.sum() >= len(active) // 2 and active[-1]
            if name == "bend":
                np.testing.assert_allclose(theta[active], theta_max, rtol=1e-14)
            else:
                assert np.all(theta[active] == theta_max)
            if name == "bend":  # the disk holds exactly in the solver's own terms
                assert np.all(X[:, 0] ** 2 + X[:, 1] ** 2 <= theta_max**2)
            else:
                assert np.all(theta <= theta_max)


def test_missing_samples_whole_window() -> None:
    """A window with no valid measurement at all: prior and process model only."""
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=3.0, seed=4)
    z = rec.z.copy()
    z[10:25] = np.nan
    recd = record_ipopt(f, 8, rec.t, z)
    assert any(w.problem.zmask.sum() == 0 for w in recd.windows)
    compare_windows(f, recd)


@pytest.mark.parametrize("name", ["bend", "paper"])
def test_badly_wrong_initial_guess(name: str) -> None:
    f = make_formulation(name)  # type: ignore[arg-type]
    rec = simulate("paper3d", duration=3.0, seed=5)
    recd = record_ipopt(f, 12, rec.t, rec.z)
    model = fm.build_window_model(f, 12)
    rng = np.random.default_rng(0)
    tol = tolerance(f)
    for w in recd.windows[20::10]:
        far = w.X0 + rng.normal(size=w.X0.shape) * np.where(tol > ANGLE_TOL, 0.05, 0.8)
        res = fm.solve_window(model, w.problem, far)
        agrees = check_window(f, recd, w, res)  # else asserts the documented alternative
        if name == "bend":  # no minima on a bound (docs/fast-solver.md): the same answer
            assert agrees


def test_a_paper_minimum_on_theta_zero_is_accepted_only_as_a_minimum() -> None:
    """The documented exception of :func:`check_window`, on a window where it occurs
    (straight, 6 deg noise, seed 3, N = 2, its 14th window): the fast
    answer lies on theta = 0, far above IPOPT's cost, and is accepted as a first-order
    minimum there; the same check rejects the window's initial guess and the answer
    with phi turned by 0.05 rad."""
    f = make_formulation("paper")
    rec = simulate("straight", duration=3.0, noise_deg=6.0, seed=3)
    recd = record_ipopt(f, 2, rec.t, rec.z)
    w = recd.windows[13]
    res = fm.solve_window(fm.build_window_model(f, 2), w.problem, w.X0)
    X_feasible = np.array([f.project(x) for x in w.X_ipopt])
    assert np.all(res.X[:, 3] == 0.0)
    assert res.cost > recd.estimator.inference.window_cost(w.problem, X_feasible) + 1.0
    assert not check_window(f, recd, w, res)  # not the same answer, and no error
    turned = res.X.copy()
    turned[:, 4] += 0.05
    for X in (np.array([f.project(x) for x in w.X0]), np.array([f.project(x) for x in turned])):
        with pytest.raises(AssertionError):
            assert_first_order_minimum(f, recd, w, X)


def test_fallback_to_ipopt_is_flagged() -> None:
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=2.0, seed=6)
    fast = MovingHorizonEstimator(f, MHESettings(horizon=10), fm.FastOptions(max_iter=1))
    ipopt = MovingHorizonEstimator(f, MHESettings(horizon=10, solver="ipopt"))
    a, b = fast.run(rec.t, rec.z), ipopt.run(rec.t, rec.z)
    assert "fallback-ipopt" in set(a.status)
    assert a.status[0] == "uncertain" and set(a.status[1:]) <= {"ok", "fallback-ipopt"}
    np.testing.assert_allclose(a.output, b.output, atol=1e-6, rtol=0)


def test_default_backend_is_fast_and_settings_validate() -> None:
    assert MHESettings().solver == "fast"
    with pytest.raises(ValueError, match="solver"):
        MHESettings(solver="qp")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="max_iter"):
        fm.FastOptions(max_iter=0)
    for beyond in (2**31, 2**32 + 5, 10**30):  # IPOPT's C int: refused, wrapped to 5, stuck
        with pytest.raises(ValueError, match=r"max_iter must be an integer from 1 to 100,000"):
            MHESettings(max_iter=beyond)
    with pytest.raises(ValueError, match="step_tol"):
        fm.FastOptions(step_tol=1.0)


def test_the_certificate_weighs_a_rate_by_the_time_its_error_moves_its_angle() -> None:
    """``step_scale``: 1 for angles, gyro biases and positions; 0.1 s for a rate named
    ``NAME_dot`` beside ``NAME``, its square for ``NAME_ddot``; and the window solver
    the workspace builds carries it into the core."""
    from continuum_mhe.estimators.fast.model import step_scale
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot((Section(0.15, 3.0), Section(0.15, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("direct", robot, own_acceleration=True)
    by_name = dict(zip(f.state_names, step_scale(f).tolist()))
    assert by_name["a_1"] == by_name["b_2"] == by_name["bgz_2"] == 1.0
    assert by_name["a_1_dot"] == by_name["b_2_dot"] == 0.1
    assert by_name["a_2_ddot"] == pytest.approx(0.01, rel=1e-15)
    assert step_scale(make_formulation("paper")).tolist() == [1.0] * 5
    model = fm.build_window_model(BendFormulation(), 5)
    assert np.array(fm.Workspace(model).core.step_scale).tolist() == [1.0, 1.0, 0.1, 0.1]


def test_cost_matches_the_ipopt_objective() -> None:
    f = make_formulation("paper")
    rec = simulate("paper3d", duration=1.5, seed=8)
    recd = record_ipopt(f, 6, rec.t, rec.z)
    model = fm.build_window_model(f, 6)
    for w in recd.windows[::5]:
        for X in (w.X0, w.X_ipopt):
            assert fm.window_cost(model, w.problem, X) == pytest.approx(
                recd.estimator.inference.window_cost(w.problem, X), rel=1e-12, abs=1e-14
            )


def test_arrival_step_is_the_ekf_step() -> None:
    """The core's arrival-prior step (update with the leaving sample, then predict)
    against the CasADi EKF's update and prediction."""
    for name in ("bend", "paper"):
        f = make_formulation(name)
        node = fm.NodeEvaluator(fm.build_window_model(f, 4))
        x = f.initial_state(np.array([0.3, -0.2]))
        P = f.initial_cov()
        u, dt = np.full(f.nu, 0.1), 0.05
        z = np.array([0.31, -0.19])
        Q = np.asarray(f.functions.predict(x, u, dt)[2], float).reshape(f.nx, f.nx)
        xn, got, got_inv = node.arrival_step(x, P, u, dt, z, np.ones(2), f.meas_cov(), Q)
        np.testing.assert_allclose(got @ got_inv, np.eye(f.nx), atol=1e-9)
        x_ref, ref = ekf_update(f, x, P, z, f.meas_cov())
        xn_ref, ref = ekf_predict(f.functions, x_ref, ref, u, dt)
        np.testing.assert_allclose(xn, xn_ref, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(got, 0.5 * (ref + ref.T), rtol=1e-12, atol=1e-15)


def test_small_dense_kernels_match_numpy() -> None:
    """The written-out products, Cholesky and inverse against numpy, and the EKF update
    and prediction on the LAPACK path where the matrix is not positive definite."""
    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(3, 5)), rng.normal(size=(5, 4))
    G = rng.normal(size=(5, 5))
    S = G @ G.T + np.eye(5)
    out, Lc = np.empty((3, 4)), np.empty((5, 5))
    _core.dense_mul(A, B, out)
    np.testing.assert_allclose(out, A @ B, rtol=1e-13)
    assert _core.dense_cholesky(S, Lc)
    np.testing.assert_allclose(Lc, np.linalg.cholesky(S), rtol=1e-12)
    inv = np.empty((5, 5))
    _core.dense_inverse_gram(Lc, inv)
    np.testing.assert_allclose(inv, np.linalg.inv(S), rtol=1e-10)
    assert not _core.dense_cholesky(-S, Lc)
    nx, nz = 4, 2
    P, H = np.diag([1.0, 2.0, 3.0, 4.0]), rng.normal(size=(nz, nx))
    R, r, x = -10.0 * np.eye(nz), rng.normal(size=nz), rng.normal(size=nx)  # S indefinite
    xu, Pu = _core.ekf_update(x, P, r, H, R)
    K = np.linalg.solve(H @ P @ H.T + R, H @ P).T
    ikh = np.eye(nx) - K @ H
    np.testing.assert_allclose(xu, x + K @ r, rtol=1e-10)
    np.testing.assert_allclose(Pu, ikh @ P @ ikh.T + K @ R @ K.T, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("solver", ["btd_solve", "btd_solve_two_ended"])
@pytest.mark.parametrize(
    ("n", "nx"),
    [(9, 1), (9, 4), (9, 5), (9, 7), (9, 8), (9, 12), (9, 14), (9, 16), (9, 21)]
    + [(1, 4), (2, 4), (3, 5), (30, 4)],
)
def test_block_tridiagonal_solve_matches_numpy(solver: str, n: int, nx: int) -> None:
    """The block-tridiagonal solves (forwards, and from both ends; every specialised
    block size, run-time sizes 1 and 5, windows of 1, 2, 3, 9 and 30 nodes) against
    numpy's dense solve of the same matrix; a matrix with a negative definite block at
    either end or in the middle is refused (False)."""
    solve = getattr(_core, solver)
    rng = np.random.default_rng(100 * n + nx)
    D = rng.normal(size=(n, nx, nx))
    E = rng.normal(size=(n - 1, nx, nx))
    D = np.einsum("nij,nkj->nik", D, D) + (2.0 * nx + 4.0) * np.eye(nx)
    H = np.zeros((n * nx, n * nx))
    for i in range(n):
        H[i * nx : (i + 1) * nx, i * nx : (i + 1) * nx] = D[i]
        if i < n - 1:
            H[i * nx : (i + 1) * nx, (i + 1) * nx : (i + 2) * nx] = E[i]
            H[(i + 1) * nx : (i + 2) * nx, i * nx : (i + 1) * nx] = E[i].T
    assert np.linalg.eigvalsh(H).min() > 0.0
    b = rng.normal(size=(n, nx))
    y = np.empty((n, nx))
    assert solve(D, E, b, y)
    np.testing.assert_allclose(y.ravel(), np.linalg.solve(H, b.ravel()), rtol=1e-11, atol=1e-12)
    for bad in (0, n // 2, n - 1):  # a negative definite block at an end or in the middle
        D_bad = D.copy()
        D_bad[bad] -= (np.linalg.eigvalsh(H).max() + 1.0) * np.eye(nx)
        assert not solve(D_bad, E, b, y)


@pytest.mark.parametrize("nx", [4, 7, 8, 12])
def test_the_specialised_block_solves_give_the_generic_ones_bits(nx: int) -> None:
    """The kernels specialised for a block size (unrolled rows; for 4 states, rows of
    AVX2 registers where the processor has them) make the generic kernel's operations in
    its order: the same bits, on windows of 1 to 30 nodes."""
    for n in (1, 2, 3, 9, 30):
        rng = np.random.default_rng(7 * n + nx)
        D = rng.normal(size=(n, nx, nx))
        # not exactly symmetric: a kernel that read a block's rows for its columns differs
        D = np.einsum("nij,nkj->nik", D, D) + nx * np.eye(nx) + 1e-3 * rng.normal(size=D.shape)
        E = 0.5 * rng.normal(size=(n - 1, nx, nx))
        b = rng.normal(size=(n, nx))
        y, y_generic = np.empty((n, nx)), np.empty((n, nx))
        assert _core.btd_solve_two_ended(D, E, b, y)
        assert _core.btd_solve_two_ended(D, E, b, y_generic, generic=True)
        assert y.tobytes() == y_generic.tobytes(), n


def test_householder_reflection_and_projection() -> None:
    """The reflection that eliminates a linearised ball is symmetric, orthogonal and
    maps the ball's unit normal to -+ a unit vector on its largest coordinate; the
    projection puts every node inside the box and exactly inside each ball."""
    rng = np.random.default_rng(4)
    nrm = np.zeros(6)
    nrm[[1, 2, 4]] = rng.normal(size=3)
    nrm /= np.linalg.norm(nrm)
    T = np.empty((6, 6))
    piv = _core.householder(nrm, np.array([1, 2, 4]), T)
    assert piv == [1, 2, 4][int(np.argmax(np.abs(nrm[[1, 2, 4]])))]
    np.testing.assert_allclose(T, T.T, atol=1e-15)
    np.testing.assert_allclose(T @ T, np.eye(6), atol=1e-14)
    want = np.zeros(6)
    want[piv] = -np.sign(nrm[piv])
    np.testing.assert_allclose(T @ nrm, want, atol=1e-14)
    X = rng.normal(scale=2.0, size=(50, 6))
    lo, hi = np.array([-1.0, -np.inf, -np.inf, 0.0, -np.inf, -0.5]), np.array([1.0] * 5 + [0.5])
    ball, r2 = np.array([[1, 2], [4, 3]]), np.array([0.3, 0.7])
    lo[3], hi[3] = -np.inf, np.inf  # ball coordinates carry no box bounds
    _core.project(X, lo, hi, ball, r2)
    assert np.all(X >= lo) and np.all(X <= hi)
    for idx, rr in zip(ball, r2):
        assert np.all(np.sum(X[:, idx] ** 2, axis=1) <= rr)
        assert np.any(np.sum(X[:, idx] ** 2, axis=1) > rr * (1 - 1e-12))  # some on the sphere


def test_box_qp_matches_bounded_least_squares() -> None:
    """The active-set QP against scipy's lsq_linear: min 1/2 |A d - c|^2, lo <= d <= hi."""
    rng = np.random.default_rng(1)
    n, nx = 6, 2
    m = n * nx
    # a block-bidiagonal A gives a block-tridiagonal H = A^T A
    A = np.zeros((m + nx, m))
    for i in range(n):
        A[i * nx : (i + 1) * nx, i * nx : (i + 1) * nx] = rng.normal(size=(nx, nx)) + 2 * np.eye(nx)
        A[(i + 1) * nx : (i + 2) * nx, i * nx : (i + 1) * nx] = rng.normal(size=(nx, nx))
    c = rng.normal(size=m + nx) * 3
    H, g = A.T @ A, -A.T @ c
    D = np.array([H[i * nx : (i + 1) * nx, i * nx : (i + 1) * nx] for i in range(n)])
    E = np.array([H[i * nx : (i + 1) * nx, (i + 1) * nx : (i + 2) * nx] for i in range(n - 1)])
    lo, hi = np.array([-0.5, -np.inf]), np.array([0.4, 0.6])
    X = np.zeros((n, nx))
    d = np.empty((n, nx))
    no_balls = np.zeros((0, 1), np.int64), np.zeros(0)
    status, _, _ = _core.solve_qp(X, D, E, g.reshape(n, nx), lo, hi, *no_balls, 200, d,
                                  np.zeros((n, 0)))  # fmt: skip
    assert status == fm.CONVERGED
    ref = lsq_linear(A, c, bounds=(np.tile(lo, n), np.tile(hi, n)), tol=1e-14, method="bvls")
    np.testing.assert_allclose(d.ravel(), ref.x, atol=1e-10)


@dataclass(frozen=True)
class _NonBall(BendFormulation):
    def constraint_sym(self, x):
        return x[0] ** 2 + 2 * x[1] ** 2, -np.inf, 1.0


def test_unsupported_constraint_uses_ipopt_and_says_so() -> None:
    with pytest.raises(NotImplementedError):
        fm.feasible_set(_NonBall())
    with pytest.warns(BackendFallbackWarning) as seen:
        est = MovingHorizonEstimator(_NonBall(), MHESettings(horizon=4))
    said = [str(w.message) for w in seen]
    assert any("cannot take this problem" in m for m in said), said
    # the covariance cannot use the constraint either: said, and recorded
    assert any("leaves this problem's constraints out" in m for m in said), said
    assert (
        est.inference._fast is None and est.inference.backend_note and est.inference.covariance_note
    )
    with pytest.warns(BackendFallbackWarning, match="leaves this problem's constraints out"):
        by_ipopt = MovingHorizonEstimator(_NonBall(), MHESettings(horizon=4, solver="ipopt"))
    assert by_ipopt.inference.covariance_note and by_ipopt.inference.backend_note is None
    assert (
        MovingHorizonEstimator(BendFormulation(), MHESettings(horizon=4)).inference.covariance_note
        is None
    )
    rec = simulate("paper3d", duration=0.3)
    status = est.run(rec.t, rec.z).status  # never a silent "ok"
    assert status[0] == "uncertain" and set(status[1:]) == {"fallback-ipopt"}


def test_feasible_set_from_the_model() -> None:
    bend = fm.feasible_set(make_formulation("bend"))
    assert bend.ball_idx.tolist() == [[0, 1]]
    assert bend.ball_r2 == pytest.approx([(math.pi / 2) ** 2])
    paper = fm.feasible_set(make_formulation("paper"))
    assert paper.ball_idx.size == 0 and paper.hi[3] == pytest.approx(math.pi / 2)


def test_direct_formulation_agrees() -> None:
    """The raw-IMU formulation (nz = 6, no angle wrapping) through the same backend."""
    from continuum_mhe.model.direct import direct_measurements, raw_imu_readings

    rec = simulate("planar-overbend", duration=8.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], rec.length)
    rng = np.random.default_rng(0)
    z = direct_measurements(
        acc + rng.normal(size=acc.shape) * 0.3, gyr + rng.normal(size=gyr.shape) * 0.02
    )
    f = make_formulation("direct")
    out = {
        s: MovingHorizonEstimator(f, MHESettings(horizon=12, solver=s)).run(rec.t, z)
        for s in ("ipopt", "fast")
    }
    # the overbend sits on theta_max part of the time (the bound active in the windows
    # compared): those rows say so (at-bound)
    assert set(out["fast"].status[1:]) <= {"ok", "at-bound"}
    assert list(out["fast"].status).count("at-bound") >= 10
    assert list(out["fast"].status) == list(out["ipopt"].status)
    np.testing.assert_allclose(out["fast"].output, out["ipopt"].output, atol=1e-6, rtol=0)


def test_compiled_arrival_step_and_output_match_the_python_model() -> None:
    for name in ("bend", "paper"):
        f = make_formulation(name)
        node = fm.NodeEvaluator(fm.build_window_model(f, 4))
        x = f.initial_state(np.array([0.3, -0.2]))
        P, R = f.initial_cov(), f.meas_cov()
        u, dt, z = np.full(f.nu, 0.1), 0.05, np.array([0.31, -0.19])
        Q = np.asarray(f.functions.predict(x, u, dt)[2], float).reshape(f.nx, f.nx)
        for valid in (True, False):
            xn, Pn, Pinv = node.arrival_step(x, P, u, dt, z, np.full(2, float(valid)), R, Q)
            x_ref, P_ref = ekf_update(f, x, P, z, R) if valid else (x, P)
            x_ref, P_ref = ekf_predict(f.functions, x_ref, P_ref, u, dt)
            np.testing.assert_allclose(xn, x_ref, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(Pn, 0.5 * (P_ref + P_ref.T), rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(Pn @ Pinv, np.eye(f.nx), atol=1e-9)
        states = [x, f.initial_state(np.array([0.0, 0.0]))]
        if name == "bend":
            states.append(np.array([-0.5, 0.0, 0.0, 0.0]))  # phi = pi: wrapped to -pi
        for s in states:
            np.testing.assert_allclose(node.output(s), f.output(s), rtol=1e-13, atol=1e-15)


# --- several sections: one ball per section, per-IMU masks -------------------------------


def _two_section(theta_max: float = 0.5, imus: tuple[int, ...] = (0, 1)) -> Formulation:
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot(
        (Section(0.16, theta_max), Section(0.14, theta_max)), tuple(ImuPlacement(k) for k in imus)
    )
    return make_formulation("bend", robot)


def _two_section_recording(f: Formulation, duration: float = 3.0) -> tuple[FloatArray, FloatArray]:
    """The s-curve on two sections: both bends go beyond ``theta_max = 0.5`` (active
    balls from about 1.6 s on); IMU 2 drops out for 0.5 s, IMU 1 for two samples."""
    from continuum_mhe.simulation.scenarios import simulate_robot

    loose = _two_section(3.0, tuple(imu.section for imu in f.robot.imus)).robot
    rec = simulate_robot("s-curve", loose, duration=duration, dt=0.05, seed=3)
    z = rec.z.copy()
    z[30:40, f.measurement_blocks[1].slice] = np.nan
    z[45:47, f.measurement_blocks[0].slice] = np.nan
    return rec.t, z


def test_two_sections_with_active_balls_agree_with_ipopt_window_by_window() -> None:
    """Every window IPOPT solves on a two-section robot (two balls on disjoint
    coordinates, both active on many nodes, one IMU dropping out at a time): the fast
    backend certifies it and agrees to 1e-6 rad with the same active set."""
    f = _two_section()
    fs = fm.feasible_set(f)
    assert fs.ball_idx.tolist() == [[0, 1], [2, 3]]
    np.testing.assert_allclose(fs.ball_r2, [0.25, 0.25])
    t, z = _two_section_recording(f)
    # IPOPT to 1e-10: at its default 1e-8 two windows' rates differed by 1.07e-6 rad/s
    # (bends within 1.4e-7 rad), IPOPT's answer 1e-8 outside the balls, the fast cost lower
    rec = record_ipopt(f, 10, t, z, tol=1e-10)
    partial = [w for w in rec.windows if 0 < w.problem.zmask.sum(axis=1).min() < f.nz]
    assert partial  # windows with one IMU masked and the other valid
    compare_windows(f, rec)  # all certified, all agree (states and active sets)
    model = fm.build_window_model(f, 10)
    active = np.zeros(2, dtype=int)
    both = 0
    for w in rec.windows:
        res = fm.solve_window(model, w.problem, w.X0)
        on = np.column_stack([np.sum(res.X[:, idx] ** 2, axis=1) >= r2 * (1 - 1e-12)
                              for idx, r2 in zip(fs.ball_idx, fs.ball_r2)])  # fmt: skip
        active += on.any(axis=0)
        both += int(np.any(on.all(axis=1)))
        assert res.lam.shape == (10, 2) and np.all(res.lam >= 0)
        assert np.all(res.lam[~on] == 0.0)  # a multiplier only on an active ball
    assert np.all(active >= 10) and both >= 10  # each ball, and both on one node


def test_masked_imu_block_is_dropped_from_the_window() -> None:
    """Masking one IMU's block equals leaving its residual out: with IMU 2 masked on
    every node the two-IMU problem is the robot without IMU 2 (same answer, same
    cost); masked on some nodes, the cost drops by exactly those nodes' IMU-2 terms."""
    f2, f1 = _two_section(), _two_section(imus=(0,))
    t, z = _two_section_recording(f2, duration=1.5)
    rec = record_ipopt(f2, 8, t, z)
    m2, m1 = fm.build_window_model(f2, 8), fm.build_window_model(f1, 8)
    sl = f2.measurement_blocks[1].slice
    rinv = np.linalg.inv(f2.meas_cov())[sl, sl]
    for w in rec.windows[8::5]:
        p = w.problem
        mask = p.zmask.copy()
        mask[:, sl] = 0.0
        masked = WindowProblem(**{**vars(p), "zmask": mask})
        dropped = WindowProblem(**{**vars(p), "z": p.z[:, :2], "zmask": p.zmask[:, :2]})
        a, b = fm.solve_window(m2, masked, w.X0), fm.solve_window(m1, dropped, w.X0)
        assert a.converged and b.converged
        np.testing.assert_allclose(a.X, b.X, rtol=0, atol=1e-12)
        assert fm.window_cost(m2, masked, a.X) == pytest.approx(
            fm.window_cost(m1, dropped, a.X), rel=1e-13
        )
        # on some nodes only: the unmasked cost minus those nodes' IMU-2 terms
        some = p.zmask.copy()
        some[1::2, sl] = 0.0
        half = WindowProblem(**{**vars(p), "zmask": some})
        terms = 0.0
        for i in np.flatnonzero(p.zmask[:, sl].all(axis=1)):
            if i % 2 == 1:
                r = np.asarray(f2.functions.innovate(p.z[i], w.X0[i])[0], float).ravel()[sl]
                terms += 0.5 * r @ rinv @ r
        assert terms > 1e-3  # the dropped terms matter
        assert fm.window_cost(m2, half, w.X0) == pytest.approx(
            fm.window_cost(m2, p, w.X0) - terms, rel=1e-12
        )
        assert fm.window_cost(m2, half, w.X0) == pytest.approx(
            rec.estimator.inference.window_cost(half, w.X0), rel=1e-12
        )  # the IPOPT NLP has the same masked residual


def test_node_function_masks_rows_for_the_arrival_step() -> None:
    """The arrival EKF step with IMU 2 masked is the step of the robot without IMU 2."""
    f2, f1 = _two_section(), _two_section(imus=(0,))
    n2 = fm.NodeEvaluator(fm.build_window_model(f2, 3))
    n1 = fm.NodeEvaluator(fm.build_window_model(f1, 3))
    x = np.array([0.3, -0.2, 0.5, 0.1, 0.2, 0.1, -0.3, 0.05])
    P = np.diag(np.linspace(0.05, 0.3, 8))
    z2 = np.array([0.31, -0.19, 0.7, 0.2])
    Q = np.eye(8) * 1e-3
    R2, R1 = f2.meas_cov(), f1.meas_cov()
    got = n2.arrival_step(x, P, np.zeros(0), 0.05, z2, np.array([1.0, 1, 0, 0]), R2, Q)
    ref = n1.arrival_step(x, P, np.zeros(0), 0.05, z2[:2], np.ones(2), R1, Q)
    for a, b in zip(got, ref):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-15)
    _, _, H, r = n2.evaluate(x, np.zeros(0), 0.05, z2, np.array([1.0, 1, 0, 0]))
    assert np.all(H[2:] == 0.0) and np.all(r[2:] == 0.0)


def test_outputs_of_any_size_with_the_formulations_wrapped_angles() -> None:
    f = _two_section()
    node = fm.NodeEvaluator(fm.build_window_model(f, 3))
    assert node.output(np.zeros(8)).shape == (f.ny,) == (13,)
    wrapped = [i for i, o in enumerate(f.outputs) if o.wrapped]
    assert len(wrapped) == 2  # phi_1, phi_2
    for x in (
        np.array([-0.5, 0.0, 0.3, 0.4, 0, 0, 0, 0]),
        np.array([0.2, -0.1, -0.4, 0, 0, 0, 0, 0]),
    ):
        np.testing.assert_allclose(node.output(x), f.output(x), rtol=1e-13, atol=1e-15)


@dataclass(frozen=True)
class _ScalarBall(BendFormulation):
    """A ``constraint_sym`` in its scalar form: ``(g, lo, hi)`` with floats."""

    def constraint_sym(self, x):
        return x[0] ** 2 + x[1] ** 2, -np.inf, 1.0


def test_feasible_set_accepts_the_scalar_constraint_form() -> None:
    fs = fm.feasible_set(_ScalarBall())
    assert fs.ball_idx.tolist() == [[0, 1]] and fs.ball_r2.tolist() == [1.0]


def test_compiled_step_keeps_the_window_as_the_reference_does() -> None:
    """The compiled per-sample step (``_core.MovingHorizon``) against the IPOPT backend's
    Python window (``ReferenceWindow``, the prior's EKF step on CasADi's functions), fed
    the same samples (two sections, a dropout of one IMU, then of both, the window growing
    and sliding) and keeping the same answers: the same window data and arrival weights,
    prior, warm start and outputs to 1e-12, the outputs' standard deviations those of
    the step's covariance, and that covariance of the last node within
    1e-4 of its largest entry (the step's Hessian is at the SQP's last evaluated
    iterate, which differs from the answer by the certificate's last step)."""
    from continuum_mhe.estimators.mhe import MovingHorizonInference, ReferenceWindow
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.results import Measurement
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=2.0, seed=0)
    z = rec.z.copy()
    z[15:19, :2] = np.nan  # the first IMU drops out
    z[25:28] = np.nan  # both do
    settings = MHESettings(horizon=8)
    fast = MovingHorizonInference(f, settings)
    ref = ReferenceWindow(f, settings, fm.feasible_set(f))
    compiled = fast._window
    for i in range(len(rec.t)):
        m = Measurement(float(rec.t[i]), z[i])
        first = not compiled.has_prior
        state, cov, _ = fast.infer(m)
        if first:
            ref.set_prior(compiled.xbar, compiled.P, compiled.Pinv)
        k = ref.k
        dt = m.t - ref.tw[-1]
        Q, Qinv = fast._process_weight(dt) if k else (np.zeros((f.nx, f.nx)),) * 2
        ref.step(m.t, z[i], f.measurement_mask(z[i]), np.zeros(0), Q, Qinv, False)
        for name in ("zw", "zmask", "dt", "qinvw", "arrival", "xbar", "P", "Pinv", "X0"):
            got, want = getattr(compiled, name), getattr(ref, name)
            # to rounding of the array's largest entry: a matrix's small entries are
            # sums of large ones, whose order of operations the compiler may change
            scale = max(1.0, float(np.max(np.abs(want), initial=0.0)))
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-14 * scale, err_msg=name)
        assert state is not None and cov is not None
        ref_state, ref_cov, ref_y, ref_std = ref.finish(np.array(compiled.X), False, None, False)
        np.testing.assert_array_equal(state, ref_state)
        np.testing.assert_allclose(fast.output(state), ref_y, rtol=0, atol=1e-12)
        assert ref_cov is not None and ref_std is not None
        scale = np.abs(ref_cov).max()
        np.testing.assert_allclose(cov, ref_cov, rtol=0, atol=1e-4 * scale)
        assert fast._node is not None  # the step's standard deviations are the core's of cov
        np.testing.assert_array_equal(
            fast.output_std(state, cov), fast._node.output_std(state, cov)
        )
        # and close to the reference's own (from its covariance, which the step's
        # matches to 1e-4 of its largest entry)
        np.testing.assert_allclose(fast.output_std(state, cov), ref_std, rtol=5e-4)
        ref.X_last[:], ref.has_X_last = compiled.X_last, compiled.has_X_last
