"""The start's fit with the equilibrium rows met exactly (``model/equilibrium_fit.py``):
a known answer, the tendon robot's start under load against IPOPT on the same
objective with those rows as constraints, and the evaluations a start takes."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import minimize_scalar

import continuum_mhe._core as core
from continuum_mhe.model.equilibrium_fit import (
    SETTLE_TOLERANCE,
    EquilibriumFit,
    fit_on_equilibrium,
)
from continuum_mhe.model.tendon import START_PRIOR_WEIGHT

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def test_a_known_answer_meets_its_equilibrium_exactly() -> None:
    """States ``(s, o)``, the equilibrium ``s = o^3 + 1`` and two readings ``s = 9``
    and ``o = 2.1``: the fit is the minimiser of ``(o^3 - 8)^2 + (o - 2.1)^2`` (found
    here by a scalar search), with ``s`` on the equilibrium to its tolerance."""

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        s, o = x
        r = np.array([s - 9.0, o - 2.1, s - o**3 - 1.0])
        J = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, -3.0 * o**2]])
        return r, J

    spec = EquilibriumFit(
        free=np.array([0, 1]),
        settled=np.array([0]),
        equilibrium_rows=np.array([2]),
        rows=np.array([0, 1]),
        weights=np.ones(3),
        prior=np.zeros(2),
        prior_weights=np.zeros(2),
        scale=np.ones(2),
    )
    x, converged = fit_on_equilibrium(evaluate, np.array([0.0, 1.0]), spec, 200)
    best = minimize_scalar(lambda o: (o**3 - 8.0) ** 2 + (o - 2.1) ** 2, bracket=(1.0, 3.0),
                           tol=1e-12).x  # fmt: skip
    assert converged
    assert x[1] == pytest.approx(best, abs=1e-7)
    assert abs(x[0] - x[1] ** 3 - 1.0) <= SETTLE_TOLERANCE


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
    """Fitted with the tip condition as rows of its tiny standard deviation, the start
    at 5 s of ``force-29`` took 400 to 600 evaluations of the model (the most allowed);
    with the condition solved at each trial point, a few tens, and it holds exactly."""
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


def _residual(f, x, z0):  # type: ignore[no-untyped-def]
    xs, zs = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    fn = ca.Function("r", [xs, zs], [f.measurement_residual_sym(zs, xs)])
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
