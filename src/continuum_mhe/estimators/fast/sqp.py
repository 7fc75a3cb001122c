"""The window solve: Newton-type SQP with a projected line search, in the compiled core.

Each iteration evaluates the whole window's model in one call (residuals, Jacobians and
the measurement residuals' second-order term), assembles the block-tridiagonal Hessian
of the Lagrangian (Gauss-Newton ``J^T W J``, plus the exact second-order term where
that keeps it positive definite, plus ``2 lam_b I`` on the coordinates of each ball
``b`` with a positive multiplier), and solves the QP subproblem by a primal active-set
method. Iterates stay exactly feasible (projection). The core's
:class:`~continuum_mhe._core.WindowSolver` does all of it (``csrc/sqp.cpp``, ``csrc/qp.hpp``,
``csrc/btd.hpp``); :func:`solve_window` and :func:`window_cost` call it, and
:class:`Workspace` holds its buffers. See ``docs/fast-solver.md``.

The numba kernels :func:`_assemble` and :func:`_evaluate` (the same assembly as the
core's) remain for :mod:`.covariance`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.fast.ccall import address, call_model
from continuum_mhe.estimators.fast.memory import shift_rows
from continuum_mhe.estimators.fast.model import LossKernel, WindowModel
from continuum_mhe.estimators.fast.qp import CONVERGED, OUTCOMES
from continuum_mhe.estimators.loss import LOSS_CODES, rho_derivatives

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem as WindowProblemLike

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FastOptions:
    """Options of the fast backend.

    Attributes:
        max_iter: SQP (Gauss-Newton) iterations per window before falling back.
        step_tol: convergence certificate: max-norm of the QP step, state units
            (rad, rad/s, m).
        err_tol: convergence certificate: error bound of the answer estimated from
            the contraction of successive steps, state units.
        max_qp_iter: active-set changes allowed per QP subproblem.
        newton: add the measurement residuals' second-order term to the Hessian
            (exact Newton; Gauss-Newton where that is not positive definite).
    """

    max_iter: int = 30
    step_tol: float = 1e-8
    err_tol: float = 1e-8
    newton: bool = True
    max_qp_iter: int = 500

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise UserError(f"max_iter must be a positive integer, got {self.max_iter!r}")
        if not (isinstance(self.max_qp_iter, int) and self.max_qp_iter >= 1):
            raise UserError(f"max_qp_iter must be a positive integer, got {self.max_qp_iter!r}")
        if not (isinstance(self.step_tol, float) and 0 < self.step_tol < 1e-3):
            raise UserError(f"step_tol must lie in (0, 1e-3), got {self.step_tol!r}")
        if not (isinstance(self.err_tol, float) and 0 < self.err_tol < 1e-3):
            raise UserError(f"err_tol must lie in (0, 1e-3), got {self.err_tol!r}")


def quadratic_rate(model: WindowModel, options: FastOptions) -> bool:
    """Whether the SQP may certify by Newton's quadratic rate: exact Newton steps
    (``options.newton``), a transition affine in the state (else the Hessian the
    backend forms lacks the process model's second-order term), and not the Huber
    loss, whose second derivative jumps at its scale (with the estimate, Huber's worst
    certified window was 4.3e-8 from the converged answer)."""
    huber = model.loss.code == LOSS_CODES["huber"]
    exact = options.newton and model.second_order_residuals
    return exact and model.linear_transition and not huber


@numba.njit(cache=True)
def _stage_product(qinv, F, eq, fqf, qf):
    """One process stage's constant products: ``eq = -(Q^-1 F)^T`` (the Hessian's
    off-diagonal block) and the upper triangle of ``fqf = F^T Q^-1 F``; ``qf`` scratch."""
    nx = F.shape[0]
    for j in range(nx):
        for k in range(nx):
            s = 0.0
            for a in range(nx):
                s += qinv[j, a] * F[a, k]
            qf[j, k] = s
    for j in range(nx):
        for k in range(nx):
            eq[j, k] = -qf[k, j]
        for k in range(j, nx):
            s = 0.0
            for a in range(nx):
                s += F[a, j] * qf[a, k]
            fqf[j, k] = s


@numba.njit(cache=True)
def _stage_products(FJ, qinv, stage):
    """:func:`_stage_product` of every stage not yet done (``stage = (done, eq, fqf)``;
    ``done`` (N-1,) 0/1, set here). Valid across iterations and windows only for a
    transition affine in the state (``F`` then does not depend on the iterate)."""
    done, eq, fqf = stage
    qf = np.empty((FJ.shape[1], FJ.shape[1]))
    for i in range(done.shape[0]):
        if done[i] == 0:
            _stage_product(qinv[i], FJ[i], eq[i], fqf[i], qf)
            done[i] = 1


def stage_buffers(
    n: int, nx: int, linear: bool
) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """``(done, eq, fqf)`` for :func:`_stage_products` of a window of ``n`` nodes: empty
    (products formed in each assembly) unless the transition is ``linear`` (affine in
    the state, :attr:`WindowModel.linear_transition`)."""
    m = n - 1 if linear and n > 1 else 0
    return np.zeros(m, dtype=np.int64), np.zeros((m, nx, nx)), np.zeros((m, nx, nx))


@numba.njit(cache=True)
def _assemble(
    X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt, extra, gb, ncost,
    stage, prev, shifted,
):  # fmt: skip
    """Gauss-Newton Hessian blocks ``D`` (diagonal), ``E`` (``(i, i+1)``), exact
    gradient ``g`` and the cost (the balls' curvature: :func:`_add_balls`).

    ``stage``: the process stages' constant products (:func:`stage_buffers`), used when
    present (an affine transition); else they are formed here. An arrival block whose
    diagonal is zero is skipped: the arrival weights are positive semidefinite, so the
    whole block is zero. ``ncost`` (n,) receives each node's cost (its measurement,
    arrival and outgoing stage terms, in that order); the cost is their sum in node
    order.

    ``shifted``: ``X`` is the previous window's iterate shifted by one node, and
    ``prev = (D, E, g, wgt, extra, gb, ncost)`` that iterate's assembly (its
    Gauss-Newton ``D``; the arrays may be these): its nodes 2 to N-1 become nodes 1 to
    N-2, and only node 0 (the new arrival term), the new last stage and the new last
    node are formed. The same bits as the whole assembly where the previous window's
    arrival weighted only its node 0 and this one's weights only node 0 (else, or below
    3 nodes, the whole assembly runs): node N-2's incoming stage and measurement are the
    previous window's node N-1, whose block, gradient and cost had nothing else. (One
    function for both: each function that holds the unrolled bodies adds to the first
    run's compile.)

    Measurement block ``b`` of node ``i`` (``loss.blocks``; ``R`` block-diagonal)
    costs ``1/2 rho(s)``, ``s = r_b^T R_b^-1 r_b``: gradient ``rho' J_b^T R_b^-1 r_b``
    and Hessian ``J_b^T (rho' R_b^-1 + a R_b^-1 r_b r_b^T R_b^-1) J_b`` with ``a``
    the exact ``2 rho''`` clipped at ``-rho'/s`` so that the block stays positive
    semidefinite (a Triggs-type correction; Cauchy beyond its scale). Kept for the
    exact Newton term (:func:`_add_curvature`): ``wgt = m rho'``, ``extra = m (2 rho''
    - a)`` and ``gb = J_b^T R_b^-1 r_b``.
    """
    n, nx = X.shape
    if shifted:
        for i in range(1, n):
            for j in range(nx):
                shifted = shifted and arrival[i, j, j] == 0.0
        shifted = shifted and n >= 3
    if shifted:
        Dp, Ep, gp, wgtp, extrap, gbp, ncostp = prev
        shift_rows(D, Dp, 1, n - 1)
        shift_rows(g, gp, 1, n - 1)
        shift_rows(ncost, ncostp, 1, n - 1)
        shift_rows(E, Ep, 1, n - 2)
        shift_rows(wgt, wgtp, 0, n - 1)
        shift_rows(extra, extrap, 0, n - 1)
        shift_rows(gb, gbp, 0, n - 1)
    if nx == 4:
        return _assemble_sized(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g,
                               loss, wgt, extra, gb, ncost, stage, 4, shifted)  # fmt: skip
    if nx == 8:
        return _assemble_sized(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g,
                               loss, wgt, extra, gb, ncost, stage, 8, shifted)  # fmt: skip
    return _assemble_sized(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g, loss,
                           wgt, extra, gb, ncost, stage, nx, shifted)  # fmt: skip


@numba.njit(cache=True, inline="always")
def _assemble_sized(
    X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt, extra, gb, ncost,
    stage, nx, shifted,
):  # fmt: skip
    """:func:`_assemble` for state size ``nx`` (a constant where inlined with one: see
    :mod:`.linalg`); with ``shifted``, only what the shifted assembly forms: node
    0 without its stage's terms of node 1, the last stage, then the last node.

    One body for both, in one order of additions (the helpers a loop would call cost
    more than the shift saves: their arguments' reference counts): node ``i``'s block
    is its incoming stage's, then its measurement's, arrival's and outgoing stage's
    terms, and its cost the sum of its measurement's, arrival's and outgoing stage's.
    """
    n = X.shape[0]
    if shifted:
        for i in (0, n - 1):
            D[i] = 0.0
            g[i] = 0.0
    else:
        D[:] = 0.0
        E[:] = 0.0
        g[:] = 0.0
    blocks, code, scale = loss.blocks, loss.code, loss.scale
    nblk = blocks.shape[0]
    wr = np.empty(R.shape[1])
    wj = np.empty((R.shape[1], nx))
    qw = np.empty(nx)
    qf = np.empty((nx, nx))
    e = np.empty(nx)
    done, eq, fqf = stage
    pre = done.shape[0] > 0
    eql = np.empty((nx, nx))
    fqfl = np.empty((nx, nx))
    for node in range(3 if shifted else n):
        i = node
        measured = True  # node i's measurement and arrival terms are formed
        push = True  # stage i's terms of node i + 1 are added
        if shifted:
            i = (0, n - 2, n - 1)[node]
            measured = i != n - 2  # node N-2 is the previous window's node N-1
            push = i != 0  # node 1 came with them
        m = zmask[i]
        cost = 0.0
        if not measured:
            cost = ncost[i]
            m = 0.0
        else:
            for bk in range(nblk):
                wgt[i, bk] = 0.0
                extra[i, bk] = 0.0
                gb[i, bk, :] = 0.0
        if m != 0.0:
            for bk in range(nblk):
                b0, nb_ = blocks[bk, 0], blocks[bk, 1]
                ssq = 0.0
                for a in range(nb_):
                    t = 0.0
                    for c in range(nb_):
                        t += rinv[b0 + a, b0 + c] * R[i, b0 + c]
                    wr[a] = t
                    ssq += R[i, b0 + a] * t
                    for k in range(nx):  # (R_b^-1 J_b)[a, k]
                        t = 0.0
                        for c in range(nb_):
                            t += rinv[b0 + a, b0 + c] * JR[i, b0 + c, k]
                        wj[a, k] = t
                rho, rho1, rho2 = rho_derivatives(code, scale, ssq)
                cost += 0.5 * m * rho
                a2 = 2.0 * rho2
                if ssq > 0.0 and a2 < -rho1 / ssq:
                    a2 = -rho1 / ssq
                wgt[i, bk] = m * rho1
                extra[i, bk] = m * (2.0 * rho2 - a2)
                for j in range(nx):
                    t = 0.0
                    for a in range(nb_):
                        t += JR[i, b0 + a, j] * wr[a]
                    gb[i, bk, j] = t
                    g[i, j] += m * rho1 * t
                for j in range(nx):  # J_b^T (rho' R_b^-1 + a2 ...) J_b, upper triangle
                    for k in range(j, nx):
                        t = 0.0
                        for a in range(nb_):
                            t += JR[i, b0 + a, j] * wj[a, k]
                        D[i, j, k] += m * (rho1 * t + a2 * gb[i, bk, j] * gb[i, bk, k])
        weighted = False
        for j in range(nx):
            e[j] = X[i, j] - xbar[j]
            weighted = weighted or (measured and arrival[i, j, j] != 0.0)
        if weighted:
            for j in range(nx):
                s = 0.0
                for k in range(nx):
                    s += arrival[i, j, k] * e[k]
                g[i, j] += s
                cost += 0.5 * e[j] * s
                for k in range(j, nx):
                    D[i, j, k] += arrival[i, j, k]
        if i < n - 1:
            for j in range(nx):
                s = 0.0
                for k in range(nx):
                    s += qinv[i, j, k] * W[i, k]
                qw[j] = s
                cost += 0.5 * W[i, j] * s
            if pre:
                eqi, fqfi = eq[i], fqf[i]
            else:
                eqi, fqfi = eql, fqfl
                _stage_product(qinv[i], FJ[i], eqi, fqfi, qf)
            for j in range(nx):
                s = 0.0
                for a in range(nx):
                    s += FJ[i, a, j] * qw[a]
                g[i, j] -= s
                for k in range(nx):
                    E[i, j, k] = eqi[j, k]
                for k in range(j, nx):
                    D[i, j, k] += fqfi[j, k]
                if push:
                    g[i + 1, j] += qw[j]
                    for k in range(j, nx):
                        D[i + 1, j, k] += qinv[i, j, k]
        for j in range(nx):  # D[i] is complete: mirror its upper triangle
            for k in range(j):
                D[i, j, k] = D[i, k, j]
        ncost[i] = cost
    total = 0.0
    for i in range(n):
        total += ncost[i]
    return total


@numba.njit(cache=True)
def _evaluate(
    fn, ptrs, out, X, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt, extra, gb, ncost,
    stage,
):  # fmt: skip
    """Evaluate the model at ``X`` (one C call of the function at address ``fn``) and
    assemble the Gauss-Newton blocks; inf cost on failure. ``stage``: the stages'
    constant products (:func:`stage_buffers`; those not done yet are formed here)."""
    if call_model(fn, ptrs.ctypes.data, out.ctypes.data) != 0:
        return np.inf
    prev = (D, E, g, wgt, extra, gb, ncost)  # (not read: nothing shifts)
    return _assemble_outputs(out, X, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt,
                             extra, gb, ncost, stage, prev, False)  # fmt: skip


@numba.njit(cache=True)
def _split_outputs(out, n, nx, nz):
    """``(R, JR, W, FJ)``: views of the window model's outputs (measurement residuals and
    their Jacobians, process residuals and their Jacobians)."""
    o1, o2, o3 = nz * n, nz * n + nz * nx * n, nz * n + nz * nx * n + nx * (n - 1)
    o4 = o3 + nx * nx * (n - 1)
    R = out[:o1].reshape(n, nz)
    JR = out[o1:o2].reshape(n, nz, nx)
    W = out[o2:o3].reshape(n - 1, nx)
    FJ = out[o3:o4].reshape(n - 1, nx, nx)
    return R, JR, W, FJ


@numba.njit(cache=True)
def _assemble_outputs(out, X, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt, extra, gb,
                      ncost, stage, prev, shifted):  # fmt: skip
    """:func:`_assemble` from the window model's outputs ``out`` at ``X``."""
    R, JR, W, FJ = _split_outputs(out, X.shape[0], X.shape[1], rinv.shape[0])
    if stage[0].shape[0] > 0:
        _stage_products(FJ, qinv, stage)
    return _assemble(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, D, E, g, loss, wgt,
                     extra, gb, ncost, stage, prev, shifted)  # fmt: skip


@dataclass(frozen=True)
class FastResult:
    """Outcome of :func:`solve_window`.

    Attributes:
        X: (N, nx) the answer; feasible exactly.
        converged: True if the KKT certificate holds at ``X``.
        outcome: one of :data:`OUTCOMES`.
        iterations: SQP iterations (QP solves).
        step: max-norm of the last QP step, state units.
        cost: the window cost at the last evaluated iterate (the answer minus the last
            step when certified).
        lam: (N, nb) multipliers of the ball constraints at ``X``.
        hessian: when certified, the Gauss-Newton blocks ``(D, E)`` at the last
            evaluated iterate (within the convergence tolerance of ``X``), for
            :func:`~continuum_mhe.estimators.fast.covariance.window_covariance`; else None.
        X_last: when certified, that last evaluated iterate (N, nx), the next window's
            warm start (its model outputs are then known: ``WindowSolver.shift_outputs``).
    """

    X: FloatArray
    converged: bool
    outcome: str
    iterations: int
    step: float
    cost: float
    lam: FloatArray
    hessian: tuple[FloatArray, FloatArray] | None = None
    X_last: FloatArray | None = None


class Workspace:
    """Buffers of :func:`solve_window`, reusable across windows of one model: those of
    the compiled core's :class:`~continuum_mhe._core.WindowSolver` (NumPy views of its
    memory, so the model's argument pointers are fixed and the core solves in place).

    ``loss`` and ``linear`` replace the model's measurement loss and its
    :attr:`~.model.WindowModel.linear_transition` (whether the stage products are kept
    across iterations and windows).
    """

    def __init__(
        self, model: WindowModel, loss: LossKernel | None = None, linear: bool | None = None
    ) -> None:
        fs, lossk = model.feasible, loss or model.loss
        self.tail = address(model.tail) if model.tail is not None else 0
        self.window = address(model.window)  # of the window function (the model keeps it)
        self.core = core = _core.WindowSolver(
            model.horizon, model.nx, model.nz, model.nu, self.window, self.tail, fs.lo, fs.hi,
            np.ascontiguousarray(fs.ball_idx, dtype=np.int64), fs.ball_r2, model.rinv,
            np.ascontiguousarray(lossk.blocks, dtype=np.int64), lossk.code, lossk.scale,
            model.linear_transition if linear is None else linear,
        )  # fmt: skip
        self.z, self.m, self.u, self.dt = core.z, core.m, core.u, core.dt
        self.Xb, self.out, self.D, self.E, self.g = core.Xb, core.out, core.D, core.E, core.g
        self.d, self.lam_qp, self.wgt, self.extra = core.d, core.lam_qp, core.wgt, core.extra
        self.gb = core.gb
        self.Dgn = core.Dgn  # Gauss-Newton diagonal blocks per iterate
        self.ncost = core.ncost  # each node's cost per iterate
        self.stage = (core.stage_done, core.stage_eq, core.stage_fqf)
        # the tail function's arguments (``WindowSolver.shift_outputs``): buffer 0's last stage
        self.tail_out, self.tail_ptrs, self.ptrs = core.tail_out, core.tail_ptrs, core.ptrs

    def load(self, problem: WindowProblemLike, X: FloatArray) -> None:
        """Copy ``problem``'s data and the iterate ``X`` (N, nx) into buffer 0, and mark
        the stage products to be formed anew (for this problem's ``Q^-1``)."""
        self.z[:] = problem.z
        self.m[:] = problem.zmask
        self.u[:] = problem.u
        self.dt[:] = problem.dt
        self.Xb[0] = X
        self.stage[0][:] = 0


def _weights(problem: WindowProblemLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(qinv, xbar, arrival)`` of ``problem`` as the core takes them."""
    return (
        np.ascontiguousarray(problem.qinv, dtype=np.float64),
        np.ascontiguousarray(problem.xbar, dtype=np.float64),
        np.ascontiguousarray(problem.arrival, dtype=np.float64),
    )


def solve_window(
    model: WindowModel,
    problem: WindowProblemLike,
    X0: FloatArray,
    options: FastOptions | None = None,
    lam0: FloatArray | None = None,
    workspace: Workspace | None = None,
) -> FastResult:
    """Solve one window problem from the initial guess ``X0`` (N, nx).

    ``problem.zmask`` (N, nz) masks the measurement components of sensors that dropped
    out. ``lam0`` (N, nb) warm-starts the ball multipliers (the curvature term). The guess is
    projected onto the feasible set first. ``workspace`` (of this model) saves the
    allocations. See the module docstring for the method.
    """
    opt = options or FastOptions()
    n, nb = model.horizon, len(model.feasible.ball_r2)
    ws = workspace or Workspace(model)
    ws.load(problem, X0)
    lam = np.zeros((n, nb)) if lam0 is None else np.array(lam0, dtype=float).reshape(n, nb)
    outcome, it, step, cost, cur = ws.core.solve(
        *_weights(problem), lam, opt.max_iter, opt.step_tol, opt.err_tol, opt.max_qp_iter,
        opt.newton, quadratic_rate(model, opt),
    )  # fmt: skip
    converged = outcome == CONVERGED
    return FastResult(
        X=ws.Xb[cur].copy(),
        converged=converged,
        outcome=OUTCOMES[outcome],
        iterations=int(it),
        step=float(step),
        cost=float(cost),
        lam=lam,
        hessian=(ws.Dgn[1 - cur].copy(), ws.E[1 - cur].copy()) if converged else None,
        X_last=ws.Xb[1 - cur].copy() if converged else None,
    )


def window_cost(model: WindowModel, problem: WindowProblemLike, X: FloatArray) -> float:
    """The window cost at ``X`` (N, nx), from the compiled model."""
    ws = Workspace(model)
    ws.load(problem, np.asarray(X, dtype=np.float64))
    return float(ws.core.evaluate(0, *_weights(problem)))
