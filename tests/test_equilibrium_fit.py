"""The start's fit with the equilibrium rows met exactly (``model/equilibrium_fit.py``):
a known answer, the tendon robot's start under load against IPOPT on the same
objective with those rows as constraints, and the evaluations a start takes."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import continuum_mhe._core as core
from continuum_mhe.model.equilibrium_fit import (
    SETTLE_STALLS,
    SETTLE_TOLERANCE,
    EquilibriumFit,
    fit_on_equilibrium,
)
from continuum_mhe.model.tendon import START_PRIOR_WEIGHT

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def _cubic(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """States ``(s, o)``: the readings ``s = 9`` and ``o = 2.1``, the equilibrium
    ``s = o^3 + 1`` (rows 0, 1, 2) and its Jacobian."""
    s, o = x
    r = np.array([s - 9.0, o - 2.1, s - o**3 - 1.0])
    J = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, -3.0 * o**2]])
    return r, J


def _cubic_spec(prior_weights: tuple[float, float] = (0.0, 0.0)) -> EquilibriumFit:
    return EquilibriumFit(
        free=np.array([0, 1]),
        settled=np.array([0]),
        equilibrium_rows=np.array([2]),
        rows=np.array([0, 1]),
        weights=np.ones(3),
        prior=np.zeros(2),
        prior_weights=np.array(prior_weights),
        scale=np.ones(2),
    )


@pytest.mark.parametrize("prior_on_s", [0.0, 0.3])
def test_a_known_answer_meets_its_equilibrium_exactly(prior_on_s: float) -> None:
    """The readings and the equilibrium of :func:`_cubic`, and a prior ``0.3 s`` on the
    settled state or none: the fit is the minimiser of ``(o^3 - 8)^2 + (o - 2.1)^2 +
    (0.3 (o^3 + 1))^2`` (found here by a scalar search), with ``s`` on the equilibrium
    to its tolerance."""
    got = fit_on_equilibrium(_cubic, np.array([0.0, 1.0]), _cubic_spec((prior_on_s, 0.0)), 200)

    def cost(o: float) -> float:
        return (o**3 - 8.0) ** 2 + (o - 2.1) ** 2 + (prior_on_s * (o**3 + 1.0)) ** 2

    best = minimize_scalar(cost, bracket=(1.0, 3.0), tol=1e-12).x
    assert got.converged and got.settled
    assert got.x[1] == pytest.approx(best, abs=1e-7)
    assert abs(got.x[0] - got.x[1] ** 3 - 1.0) <= SETTLE_TOLERANCE
    np.testing.assert_array_equal(got.residual, _cubic(got.x)[0])


@pytest.mark.parametrize("budget", [4, 5, 8, 13])
def test_a_fit_cut_short_keeps_its_best_settled_point(budget: int) -> None:
    """With too few evaluations the fit ends at the settled point of lowest cost it met
    (never above the start's), says it did not converge, and spends no more than it
    was given."""
    spec = _cubic_spec()
    start = np.array([0.0, 1.0])
    got = fit_on_equilibrium(_cubic, start, spec, budget)

    def cost(x: np.ndarray) -> float:
        r = _cubic(x)[0]
        return float(r[0] ** 2 + r[1] ** 2)

    assert not got.converged and got.settled and got.evaluations <= budget
    assert abs(got.x[0] - got.x[1] ** 3 - 1.0) <= SETTLE_TOLERANCE
    assert cost(got.x) <= cost(np.array([start[1] ** 3 + 1.0, start[1]]))


def test_an_equilibrium_that_does_not_settle_is_said_and_costs_little() -> None:
    """``s^2 + 1 = 0`` has no solution: Newton's method stops after a few steps that do
    not lower it, and the result is the start, not settled; a model that fails
    (``ArithmeticError``) is the same."""

    def no_root(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, o = x
        return np.array([s - 9.0, o - 2.1, s**2 + 1.0]), np.array(
            [[1.0, 0.0], [0.0, 1.0], [2.0 * s, 0.0]]
        )

    def failing(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise ArithmeticError("no equilibrium")

    start = np.array([0.5, 1.0])
    for evaluate in (no_root, failing):
        got = fit_on_equilibrium(evaluate, start, _cubic_spec(), 600)
        assert not got.settled and not got.converged and got.residual is None
        np.testing.assert_array_equal(got.x, start)
        assert got.evaluations <= SETTLE_STALLS + 2, got.evaluations


def test_a_spec_that_cannot_be_solved_is_refused() -> None:
    """A settled state that is not free, or settled states and equilibrium rows of
    different numbers: a ValueError naming it."""
    with pytest.raises(ValueError, match="every settled state must be free"):
        replace(_cubic_spec(), settled=np.array([2]))
    with pytest.raises(ValueError, match="as many settled states as equilibrium rows"):
        replace(_cubic_spec(), equilibrium_rows=np.array([1, 2]))
    with pytest.raises(ValueError, match="prior needs one value per free state"):
        replace(_cubic_spec(), prior=np.zeros(3))


class _Counting:
    """``ResidualNodeFunction`` that counts its evaluations."""

    calls = 0

    def __init__(self, *args: object, **kwargs: object) -> None:
        self._f = _Real(*args, **kwargs)
        self.output_size = self._f.output_size

    def evaluate(self, inputs: object, out: object) -> object:
        _Counting.calls += 1
        return self._f.evaluate(inputs, out)


_Real = core.ResidualNodeFunction


def _start_under_load(imu: str = "raw"):  # type: ignore[no-untyped-def]
    """The shipped ``force-29`` (``raw`` or ``tilt`` IMUs) read as the command line
    reads it, and its reading at 5 s (bent under 0.29 N): ``(formulation, z0)``."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation

    options = InputOptions(tensions=str(DATA / "force-29_tensions.csv"))
    base = make_formulation("bend", read_robot("tendon-two-section"))
    with open_input(DATA / f"force-29_{imu}.csv", options, base) as stream:
        f = stream.formulation
        blocks = list(stream.blocks)
    t = np.concatenate([b[0] for b in blocks])
    z = np.vstack([b[1] for b in blocks])
    return f, z[int(np.searchsorted(t, 5.0 - 1e-9))]


@pytest.mark.parametrize("imu", ["raw", "tilt"])
def test_a_start_under_load_takes_few_evaluations(
    imu: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The start at 5 s of ``force-29`` takes a few tens of the model's evaluations with
    the tip condition solved at each trial point (400 to 600, the most allowed, with
    the condition fitted as rows of its tiny standard deviation), and the condition
    holds exactly."""
    f, z0 = _start_under_load(imu)
    monkeypatch.setattr(core, "ResidualNodeFunction", _Counting)
    _Counting.calls = 0
    x, misfit, limit = f._start_fit(z0, f.force_prior_std)
    assert _Counting.calls <= 60, _Counting.calls
    assert np.isfinite(misfit) and misfit <= limit  # the wide prior fits the load
    monkeypatch.setattr(core, "ResidualNodeFunction", _Real)
    _, r = _residual(f, x, z0)
    n_eq = f.measurement_blocks[-1].size
    assert np.abs(r[f.nz - n_eq :]).max() <= SETTLE_TOLERANCE


@functools.cache
def _residual_function(f):  # type: ignore[no-untyped-def]
    """The measurement residual ``(x, z) -> r`` of the formulation ``f`` (a CasADi
    function, immutable): built once a process for equal formulations (the raw start's
    two tests)."""
    xs, zs = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    return ca.Function("r", [xs, zs], [f.measurement_residual_sym(zs, xs)])


def _residual(f, x, z0):  # type: ignore[no-untyped-def]
    fn = _residual_function(f)
    z = np.nan_to_num(np.asarray(z0, dtype=float))
    return fn, np.asarray(fn(x, z), dtype=float).ravel()


def test_the_start_under_load_is_ipopts_answer_on_the_same_objective() -> None:
    """The start's objective (the readings and the priors of ``_start_fit``, raw IMUs)
    minimised by IPOPT (exact Hessian) with the tip condition and its rate as equality
    constraints, from the same point: the same minimum."""
    f, z0 = _start_under_load()
    x, _, _ = f._start_fit(z0, f.force_prior_std)
    n, k = f.n_imu_measurements, f.robot.n_tendons
    tau = np.maximum(np.nan_to_num(z0[n : n + k]), 0.0)
    x0 = np.zeros(f.nx)
    x0[:3], x0[6 : 6 + k] = f.statics.solve(np.zeros(3), tau)[0], tau
    bias = f._n_motion
    free = np.r_[0:6, 6 + k : 9 + k, bias : bias + f.n_gyro_bias]
    w = np.sqrt(1.0 / np.diag(f.meas_cov()))
    prior_w = START_PRIOR_WEIGHT / np.sqrt(np.diag(f.initial_cov()))[free]
    prior_w[3:6] = 1.0 / f.force_prior_std
    fn, _ = _residual(f, x, z0)
    z = np.nan_to_num(np.asarray(z0, dtype=float))
    z[n : n + k] = tau
    v = ca.SX.sym("v", len(free))
    xv = ca.SX(x0)
    for j, state in enumerate(free):
        xv[int(state)] = v[j]
    r = fn(xv, z)
    valid = np.flatnonzero(np.isfinite(z0[:n])).tolist()
    n_eq = f.measurement_blocks[-1].size
    cost = 0.5 * (
        ca.sumsqr(ca.DM(w[valid]) * r[valid]) + ca.sumsqr(ca.DM(prior_w) * (v - x0[free]))
    )
    nlp = ca.nlpsol("start", "ipopt", {"x": v, "f": cost, "g": r[f.nz - n_eq : f.nz]},
                    {"ipopt.print_level": 0, "print_time": 0, "ipopt.tol": 1e-12,
                     "ipopt.sb": "yes"})  # fmt: skip
    sol = nlp(x0=x0[free], lbg=0, ubg=0)
    assert nlp.stats()["success"] or nlp.stats()["return_status"] == "Solved_To_Acceptable_Level"
    ours = float(ca.Function("c", [v], [cost])(x[free]))
    assert ours <= float(sol["f"]) * (1 + 1e-8)
    assert np.abs(np.asarray(sol["x"]).ravel() - x[free]).max() < 1e-5
