"""Covariance of the MHE's estimate: the last block of the window Hessian's inverse.

At the window's solution ``X`` the cost's Gauss-Newton Hessian ``H = J^T W J`` (the
block-tridiagonal ``(D, E)`` the SQP assembles, without the exact second-order and
ball-curvature terms) is the inverse covariance of the window's states under the
linearised model (a Laplace approximation). Its inverse's last block is the
covariance of the estimate. Active bounds are conditioned on: a coordinate on its box
bound, and the normal of an active ball, carry no variance (the reduced Hessian on
the active constraints' null space, the same elimination as the QP's
equality-constrained step, ``csrc/qp.hpp``). That covariance is the one the
sensor-health checks judge an estimate with (an estimate on a bound cannot leave it).
Where the newest node sits on a ball (a section's bending bound, which may not be the
robot's: status ``at-bound``), the covariance not conditioned on the balls
(``condition_balls=False``) is kept beside it for the standard deviations written.

The last block needs no full inverse: with ``H = L L^T`` block-bidiagonal, ``L^-1`` is
lower triangular and its last block column is ``(0, ..., L_n^-1)``, so
``(H^-1)_nn = L_n^-T L_n^-1``. One block-tridiagonal Cholesky, ``O(n nx^3)``.
On a linear Gaussian model without active bounds this is the Kalman filter's ``P``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.estimators.fast.model import Feasible, LossKernel, WindowModel
from continuum_mhe.estimators.fast.sqp import Workspace
from continuum_mhe.estimators.loss import LOSS_CODES, block_array
from continuum_mhe.model.formulations import Formulation

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem as WindowProblemLike

from continuum_mhe.arrays import FloatArray


def last_block_covariance(
    X: FloatArray,
    D: FloatArray,
    E: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    ball_idx: NDArray[np.int64],
    ball_r2: FloatArray,
    tol: float,
    out: FloatArray,
    condition_balls: bool = True,
) -> bool:
    """``out`` (nx, nx): the last diagonal block of ``H^-1`` for ``H = (D, E)``,
    conditioned on the bounds active at ``X`` (see the module doc; the compiled core's
    ``last_block_covariance``), the balls only where ``condition_balls``. False if the
    reduced Hessian is not positive definite."""
    f64 = np.ascontiguousarray
    balls = f64(ball_idx, dtype=np.int64)
    balls = balls.reshape(len(ball_r2), -1) if len(ball_r2) else np.zeros((0, 1), np.int64)
    return bool(
        _core.last_block_covariance(
            f64(X, dtype=float), f64(D, dtype=float), f64(E, dtype=float), f64(lo, dtype=float),
            f64(hi, dtype=float), balls,
            f64(ball_r2, dtype=float), float(tol), out, condition_balls,
        )
    )  # fmt: skip


def window_covariance(
    model: WindowModel,
    problem: WindowProblemLike,
    X: FloatArray,
    workspace: Workspace | None = None,
    tol: float = 1e-6,
) -> FloatArray | None:
    """Covariance (nx, nx) of the last node of ``X`` (N, nx), the window's solution:
    the Gauss-Newton Hessian from one call of the compiled window model, then
    :func:`last_block_covariance` (the fast MHE's step does the same in the core,
    ``csrc/horizon.cpp``). None if the reduced Hessian is not positive definite.
    """
    fs, nx = model.feasible, model.nx
    out = np.empty((nx, nx))
    ws = workspace or Workspace(model)
    ws.load(problem, X)
    cost = ws.core.evaluate(
        0, np.ascontiguousarray(problem.qinv, dtype=float), np.asarray(problem.xbar, float),
        np.ascontiguousarray(problem.arrival, dtype=float),
    )  # fmt: skip
    if not np.isfinite(cost):
        return None
    ok = last_block_covariance(
        X, ws.Dgn[0], ws.E[0], fs.lo, fs.hi, fs.ball_idx, fs.ball_r2, tol, out
    )
    return out if ok else None


def casadi_window_covariance(
    formulation: Formulation,
    problem: WindowProblemLike,
    X: FloatArray,
    feasible: Feasible | None,
    tol: float = 1e-6,
    loss: LossKernel | None = None,
    condition_balls: bool = True,
) -> FloatArray | None:
    """The same quantity as :func:`window_covariance`, with the Jacobians from the
    formulation's CasADi functions (the IPOPT backend's; no compiled model).
    ``feasible`` None: no bound is conditioned on; ``condition_balls`` False: no ball.
    IPOPT's answers lie within its tolerance of a bound, hence the looser default
    ``tol``. ``loss``: the measurement loss (None: quadratic), whose weights enter the
    Hessian as in the fast backend."""
    f = formulation
    n, nx, nz = X.shape[0], f.nx, f.nz
    fns = f.functions
    zmask = np.asarray(problem.zmask, dtype=float)
    r, jr = fns.innovate(np.asarray(problem.z, float).T, X.T)
    R = np.asarray(r, dtype=float).reshape(nz, n).T * zmask
    JR = np.asarray(jr, dtype=float).reshape(nz, n, nx).transpose(1, 0, 2) * zmask[:, :, None]
    W = np.empty((max(n - 1, 0), nx))
    FJ = np.empty((max(n - 1, 0), nx, nx))
    for i in range(n - 1):
        xn, F, _ = fns.predict(X[i], problem.u[i], float(problem.dt[i]))
        W[i] = X[i + 1] - np.asarray(xn, dtype=float).ravel()
        FJ[i] = np.asarray(F, dtype=float).reshape(nx, nx)
    if feasible is None:
        lo, hi = np.full(nx, -np.inf), np.full(nx, np.inf)
        ball_idx, ball_r2 = np.zeros((0, 1), dtype=np.int64), np.zeros(0)
    else:
        lo, hi, ball_idx, ball_r2 = feasible.lo, feasible.hi, feasible.ball_idx, feasible.ball_r2
    rinv = np.asarray(np.linalg.inv(f.meas_cov()), dtype=np.float64)
    Xc = np.ascontiguousarray(X, dtype=float)
    if loss is None:
        loss = LossKernel(block_array(f.measurement_blocks), LOSS_CODES["l2"], np.inf)
    # the core's assembly on these residuals and Jacobians (its window layout; the
    # second-order part is not used by the Gauss-Newton blocks)
    free = np.full(nx, np.inf)
    solver = _core.WindowSolver(
        n, nx, nz, f.nu, None, None, -free, free, np.zeros((0, 1), dtype=np.int64), np.zeros(0),
        rinv, np.ascontiguousarray(loss.blocks, dtype=np.int64), loss.code, loss.scale, False,
        None, None if loss.robust is None else np.ascontiguousarray(loss.robust, dtype=np.int64),
    )  # fmt: skip
    solver.m[:] = zmask
    solver.Xb[0] = Xc
    window = solver.out[0]
    window[:] = 0.0
    parts = (R, JR, W, FJ)
    start = 0
    for part in parts:
        window[start : start + part.size] = part.ravel()
        start += part.size
    solver.assemble(
        0, np.ascontiguousarray(problem.qinv, float), np.asarray(problem.xbar, float),
        np.ascontiguousarray(problem.arrival, float),
    )  # fmt: skip
    D, E = solver.Dgn[0], solver.E[0]
    out = np.empty((nx, nx))
    ok = last_block_covariance(Xc, D, E, lo, hi, ball_idx, ball_r2, tol, out, condition_balls)
    return out if ok else None
