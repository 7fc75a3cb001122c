"""The MHE's window problem as a CasADi NLP for IPOPT: the problem's data
(:class:`WindowProblem`), the NLP built once per formulation, horizon, loss and
objective scale (:func:`build_nlp`), and the parameter vector of one window
(:func:`pack_parameters`). The cost is the one :mod:`continuum_mhe.estimators.mhe`
states; the fast backend solves the same problem (:mod:`.fast`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.loss import rho_sym
from continuum_mhe.model.formulations import Formulation


@dataclass(frozen=True)
class WindowProblem:
    """The window NLP's data for one solve (all numeric, shapes for horizon N)."""

    z: FloatArray  # (N, m) measurements (0 where masked)
    zmask: FloatArray  # (N, m) 1 for a valid, active measurement component
    dt: FloatArray  # (N-1,) s
    u: FloatArray  # (N-1, nu)
    qinv: FloatArray  # (N-1, nx, nx) inverse process covariance per stage (0 if inactive)
    xbar: FloatArray  # (nx,) arrival prior
    arrival: FloatArray  # (N, nx, nx) arrival weight per node (P^-1 on first active node)


@dataclass(frozen=True)
class WindowParameters:
    """The window's parameters as CasADi symbols, for the window NLP and its peers:
    ``Z``, ``zmask`` (nz, N) the readings and their mask; ``DT`` (N - 1) s; ``U``
    (nu, N - 1) inputs; ``QI`` (nx^2, N - 1) and ``AR`` (nx^2, N) the process-noise and
    arrival weights, column-major; ``xbar`` (nx) the arrival state."""

    Z: ca.SX
    zmask: ca.SX
    DT: ca.SX
    U: ca.SX
    QI: ca.SX
    xbar: ca.SX
    AR: ca.SX

    @classmethod
    def symbols(cls, formulation: Formulation, horizon: int, kind: Any = ca.SX) -> WindowParameters:
        """The symbols, ``ca.SX`` (default) or ``ca.MX``."""
        f, n, nx = formulation, horizon, formulation.nx
        return cls(
            Z=kind.sym("Z", f.nz, n),
            zmask=kind.sym("zmask", f.nz, n),
            DT=kind.sym("DT", n - 1),
            U=kind.sym("U", f.nu, n - 1),
            QI=kind.sym("QI", nx * nx, n - 1),
            xbar=kind.sym("xbar", nx),
            AR=kind.sym("AR", nx * nx, n),
        )

    @property
    def vector(self) -> ca.SX:
        """The parameters in one vector, in the order :func:`pack_parameters` packs."""
        return ca.vertcat(
            ca.vec(self.Z), ca.vec(self.zmask), self.DT, ca.vec(self.U), ca.vec(self.QI),
            self.xbar, ca.vec(self.AR),
        )  # fmt: skip


@dataclass(frozen=True)
class Nlp:
    """An IPOPT solver of the window NLP, its bounds and its cost function."""

    solver: ca.Function
    lbx: FloatArray
    ubx: FloatArray
    lbg: FloatArray
    ubg: FloatArray
    cost: ca.Function


#: Largest window weight (an entry of ``Q(dt)^-1``, ``P^-1`` or ``R^-1``) at which IPOPT's
#: objective is left unscaled; above it the objective is divided by a power of ten.
WEIGHT_REFERENCE = 1e6


def objective_scale_exponent(problem: WindowProblem, rinv_max: float) -> int:
    """``e`` such that the window objective divided by ``10**e`` has its largest weight
    at most :data:`WEIGHT_REFERENCE` (0 when it already has).

    IPOPT's tolerance is absolute on the gradient; at a high sample rate ``Q(dt)^-1``
    grows as ``dt^-3`` (2.4e10 at 1 kHz), rounding alone exceeds the tolerance and IPOPT
    stopped with ``Search_Direction_Becomes_Too_Small`` on accurate answers. Scaling
    the objective makes the test relative to the problem's own weights.
    """
    w = max(float(np.abs(problem.qinv).max()), float(np.abs(problem.arrival).max()), rinv_max)
    if not (math.isfinite(w) and w > WEIGHT_REFERENCE):
        return 0
    return int(math.ceil(math.log10(w / WEIGHT_REFERENCE)))


@dataclass(frozen=True)
class _WindowGraph:
    """The window NLP's expressions and its derivative functions, which every objective
    scale's IPOPT solver shares (:func:`build_nlp`)."""

    nlp: dict[str, Any]
    derivatives: dict[str, Any]  # nlpsol's options giving them
    cost: ca.Function
    ng: int


@lru_cache(maxsize=32)
def _window_graph(formulation: Formulation, horizon: int, loss: str, scale: float) -> _WindowGraph:
    """The window NLP of :func:`build_nlp` without IPOPT's options: its expressions, and
    the derivatives IPOPT calls (the exact Hessian of the Lagrangian, the cost's
    gradient and the constraints' Jacobian; a per-node model's Gauss-Newton Hessian or
    none), formed once: forming them is most of the time an NLP takes to build."""
    f, n, nx = formulation, horizon, formulation.nx
    per_node = not f.second_order_residuals
    kind: Any = ca.MX if per_node else ca.SX
    X = kind.sym("X", nx, n)
    par = WindowParameters.symbols(f, n, kind)
    Z, zmask, DT, U, QI, xbar, AR = par.Z, par.zmask, par.DT, par.U, par.QI, par.xbar, par.AR
    residual: Callable[..., Any] = f.measurement_residual_sym
    transition: Callable[..., Any] = f.transition_sym
    constraint: Callable[..., Any] = lambda x: f.constraint_sym(x)[0]  # noqa: E731
    if per_node:
        zs, xs = ca.SX.sym("z", f.nz), ca.SX.sym("x", nx)
        residual = ca.Function("residual", [zs, xs], [f.measurement_residual_sym(zs, xs)])
        transition = f.functions.transition
        constraint = ca.Function("constraint", [xs], [f.constraint_sym(xs)[0]])
    rinv = np.linalg.inv(f.meas_cov())
    cost = kind(0)
    g = []
    for i in range(n):
        r = zmask[:, i] * residual(Z[:, i], X[:, i])
        if loss == "l2":
            cost += 0.5 * ca.bilin(rinv, r, r)
        else:  # one loss per IMU's block (R is block-diagonal); the rest quadratic
            for b in f.measurement_blocks:
                rb = r[b.slice]
                sb = ca.bilin(rinv[b.slice, b.slice], rb, rb)
                cost += 0.5 * (rho_sym(loss, scale, sb) if b.is_imu else sb)
        e = X[:, i] - xbar
        cost += 0.5 * ca.bilin(ca.reshape(AR[:, i], nx, nx), e, e)
        if i < n - 1:
            w = X[:, i + 1] - transition(X[:, i], U[:, i], DT[i])
            cost += 0.5 * ca.bilin(ca.reshape(QI[:, i], nx, nx), w, w)
        g.append(constraint(X[:, i]))
    w, params, constraints = ca.vec(X), par.vector, ca.vertcat(*g)
    ng = int(constraints.numel())
    derivatives: dict[str, Any] = {}
    if per_node and ng == 0:
        derivatives["hess_lag"] = _gauss_newton_hessian(f, X, par, rinv, w, params, loss, scale)
    elif per_node:
        derivatives["ipopt.hessian_approximation"] = "limited-memory"
    else:  # the functions nlpsol would form itself, as it forms them
        sigma, lam_g = ca.SX.sym("lam_f"), ca.SX.sym("lam_g", ng)
        lagrangian = sigma * cost + ca.dot(lam_g, constraints)
        derivatives["hess_lag"] = ca.Function(
            "nlp_hess_l", [w, params, sigma, lam_g], [ca.triu(ca.hessian(lagrangian, w)[0])]
        )
        derivatives["grad_f"] = ca.Function("nlp_grad_f", [w, params], [cost, ca.gradient(cost, w)])
        derivatives["jac_g"] = ca.Function(
            "nlp_jac_g", [w, params], [constraints, ca.jacobian(constraints, w)]
        )
    return _WindowGraph(
        nlp={"x": w, "p": params, "f": cost, "g": constraints},
        derivatives=derivatives,
        cost=ca.Function("cost", [w, params], [cost]),
        ng=ng,
    )


@lru_cache(maxsize=32)
def build_nlp(
    formulation: Formulation,
    horizon: int,
    max_iter: int,
    tol: float,
    loss: str = "l2",
    scale: float = float("inf"),
    scale_exp: int = 0,
) -> Nlp:
    """The window NLP (decision variables the ``(nx, N)`` states, column-major; the
    parameters as :func:`pack_parameters` packs them), solved by IPOPT with ``max_iter``
    and ``tol``, the objective divided by ``10**scale_exp`` (IPOPT's
    ``obj_scaling_factor``). The NLP's expressions and derivatives are formed once per
    formulation, horizon and loss, and shared by the solvers of every scale.

    A model whose second derivatives are too large to form symbolically (a shooting
    model: ``second_order_residuals`` False) keeps each node's residual and transition
    as one function called per node (CasADi MX), and IPOPT takes the Gauss-Newton
    Hessian of its cost, a robust loss's included (:func:`_gauss_newton_hessian`;
    limited-memory BFGS with constraints): expanded over the window with its exact
    Hessian, such a model needs gigabytes a window. Other models are expanded (SX) with the exact
    Hessian."""
    f, n, nx = formulation, horizon, formulation.nx
    graph = _window_graph(f, n, loss, scale)
    opts: dict[str, Any] = {
        "print_time": False,
        "show_eval_warnings": False,  # a NaN in an evaluation is a failed solve: flagged
        "calc_lam_p": False,  # not used; its failure was printed as a warning
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": tol,
        "ipopt.acceptable_tol": 1e-6,
        **graph.derivatives,
    }
    if scale_exp:
        opts["ipopt.obj_scaling_factor"] = 10.0**-scale_exp
    solver = ca.nlpsol("mhe", "ipopt", graph.nlp, opts)
    lo, hi = f.state_bounds()
    _, glo, ghi = f.constraint_sym(ca.SX.sym("x", nx))
    ng = graph.ng
    return Nlp(
        solver=solver,
        lbx=np.tile(lo, n),
        ubx=np.tile(hi, n),
        lbg=np.tile(np.asarray(glo, dtype=float).ravel(), n)[:ng],
        ubg=np.tile(np.asarray(ghi, dtype=float).ravel(), n)[:ng],
        cost=graph.cost,
    )


def _gauss_newton_hessian(
    f: Formulation,
    X: Any,
    par: WindowParameters,
    rinv: Any,
    w: Any,
    params: Any,
    loss: str = "l2",
    scale: float = float("inf"),
) -> ca.Function:
    """IPOPT's ``hess_lag`` for a window without constraints: the Gauss-Newton
    Hessian of its cost (each node's residual Jacobian ``J`` and transition Jacobian
    ``F``, first derivatives only): ``J^T m W m J`` and the arrival weight on the
    diagonal blocks, ``[F^T Q F, -F^T Q; -Q F, Q]`` per stage, times the objective's
    factor (upper triangle, as IPOPT takes it). ``W`` is ``R^-1`` for the quadratic
    loss; with a robust one, an IMU block's ``rho' R_b^-1 + a (R_b^-1 r_b)(R_b^-1
    r_b)^T``, ``a = 2 rho''`` clipped at ``-rho' / s`` so that it stays positive
    semidefinite (as the fast backend's assembly), the other blocks' ``R_b^-1``."""
    n, nx = X.shape[1], f.nx
    innovate, predict = f.functions.innovate, f.functions.predict
    zero = ca.MX(nx, nx)
    blocks: list[list[Any]] = [[zero] * n for _ in range(n)]
    robust = loss != "l2"
    if robust:
        ss = ca.SX.sym("s")
        rho1 = ca.gradient(rho_sym(loss, scale, ss), ss)
        rho_d = ca.Function("rho_d", [ss], [rho1, 2.0 * ca.gradient(rho1, ss)])
    for i in range(n):
        r, J = innovate(par.Z[:, i], X[:, i])
        mJ = ca.diag(par.zmask[:, i]) @ J
        if robust:
            mr = par.zmask[:, i] * r
            weight: Any = ca.MX(rinv.shape[0], rinv.shape[1])
            for b in f.measurement_blocks:
                rb_inv = ca.DM(rinv[b.slice, b.slice])
                if not b.is_imu:
                    weight[b.slice, b.slice] = rb_inv
                    continue
                wr = rb_inv @ mr[b.slice]
                sb = ca.dot(mr[b.slice], wr)
                r1, r2 = rho_d(sb)
                a = ca.if_else(sb > 0, ca.fmax(r2, -r1 / ca.fmax(sb, 1e-300)), r2)
                weight[b.slice, b.slice] = r1 * rb_inv + a * (wr @ wr.T)
            blocks[i][i] = mJ.T @ weight @ mJ + ca.reshape(par.AR[:, i], nx, nx)
        else:
            blocks[i][i] = mJ.T @ rinv @ mJ + ca.reshape(par.AR[:, i], nx, nx)
    for i in range(n - 1):
        _, F, _ = predict(X[:, i], par.U[:, i], par.DT[i])
        Q = ca.reshape(par.QI[:, i], nx, nx)
        blocks[i][i] += F.T @ Q @ F
        blocks[i + 1][i + 1] += Q
        blocks[i][i + 1] = -F.T @ Q
        blocks[i + 1][i] = -Q @ F
    sigma, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", 0)
    hessian = sigma * ca.triu(ca.blockcat(blocks))
    return ca.Function("nlp_hess_l", [w, params, sigma, lam_g], [hessian])


def pack_parameters(problem: WindowProblem) -> FloatArray:
    """Flatten a :class:`WindowProblem` in the NLP's parameter order (column-major)."""
    return np.concatenate(
        [
            problem.z.ravel(),  # (N, m) row-major == (m, N) column-major
            problem.zmask.ravel(),  # (N, m) row-major == (m, N) column-major
            problem.dt,
            problem.u.ravel(),
            problem.qinv.reshape(len(problem.dt), -1).ravel(),
            problem.xbar,
            problem.arrival.reshape(len(problem.zmask), -1).ravel(),
        ]
    )
