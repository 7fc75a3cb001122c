"""Covariance of the MHE's estimate: the last block of the window Hessian's inverse.

At the window's solution ``X`` the cost's Gauss-Newton Hessian ``H = J^T W J`` (the
block-tridiagonal ``(D, E)`` the SQP assembles, without the exact second-order and
ball-curvature terms) is the inverse covariance of the window's states under the
linearised model (a Laplace approximation). Its inverse's last block is the
covariance of the estimate. Active bounds are conditioned on: a coordinate on its box
bound, and the normal of an active ball, carry no variance (the reduced Hessian on
the active constraints' null space, the same elimination as the QP's
:func:`~continuum_mhe.estimators.fast.qp._eqp`).

The last block needs no full inverse: with ``H = L L^T`` block-bidiagonal, ``L^-1`` is
lower triangular and its last block column is ``(0, ..., L_n^-1)``, so
``(H^-1)_nn = L_n^-T L_n^-1``. One block-tridiagonal Cholesky, ``O(n nx^3)``.
On a linear Gaussian model without active bounds this is the Kalman filter's ``P``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.estimators.fast.linalg import btd_factor, householder, inverse_gram, mul
from continuum_mhe.estimators.fast.model import Feasible, LossKernel, WindowModel
from continuum_mhe.estimators.fast.qp import _eqp
from continuum_mhe.estimators.fast.sqp import Workspace, _assemble, _evaluate, stage_buffers
from continuum_mhe.estimators.loss import LOSS_CODES, block_array
from continuum_mhe.model.formulations import Formulation

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem as WindowProblemLike

FloatArray = NDArray[np.float64]


@numba.njit(cache=True)
def active_constraints(X, lo, hi, ball_idx, ball_r2, tol, wbox, wball, nrm):
    """Mark the box bounds (``wbox`` -1/+1) and balls (``wball``, unit normals ``nrm``)
    active at ``X``: within ``tol`` (relative to ``1 + |bound|`` for boxes, to ``r^2``
    for balls)."""
    n, nx = X.shape
    for i in range(n):
        for j in range(nx):
            wbox[i, j] = 0
            if X[i, j] <= lo[j] + tol * (1.0 + abs(lo[j])):
                wbox[i, j] = -1
            elif X[i, j] >= hi[j] - tol * (1.0 + abs(hi[j])):
                wbox[i, j] = 1
        for bb in range(ball_idx.shape[0]):
            wball[i, bb] = 0
            q = 0.0
            for s_ in ball_idx[bb]:
                q += X[i, s_] * X[i, s_]
            if q > 0.0 and q >= ball_r2[bb] * (1.0 - tol):
                wball[i, bb] = 1
                rq = np.sqrt(q)
                for s_ in ball_idx[bb]:
                    nrm[i, bb, s_] = X[i, s_] / rq


@numba.njit(cache=True)
def last_block_covariance(X, D, E, lo, hi, ball_idx, ball_r2, tol, out):
    """``out`` (nx, nx): the last diagonal block of ``H^-1`` for ``H = (D, E)``,
    conditioned on the bounds active at ``X`` (see the module doc). False if the
    reduced Hessian is not positive definite."""
    n, nx = X.shape
    nb = ball_idx.shape[0]
    wbox = np.zeros((n, nx), dtype=np.int8)
    wball = np.zeros((n, max(nb, 1)), dtype=np.int8)
    nrm = np.zeros((n, max(nb, 1), nx))
    active_constraints(X, lo, hi, ball_idx, ball_r2, tol, wbox, wball, nrm)
    L = np.empty_like(D)
    M = np.empty_like(E)
    if np.count_nonzero(wbox) + np.count_nonzero(wball) == 0:  # the factor alone
        if not btd_factor(D, E, L, M):
            return False
    else:  # the reduced Hessian, factored as the QP's equality-constrained step does
        p = np.empty((n, nx))
        b = np.empty((n, nx))
        T = np.empty_like(D)
        if not _eqp(D, E, np.zeros((n, nx)), wbox, wball, nrm, ball_idx, p, np.empty_like(D),
                    np.empty_like(E), b, L, M, T):  # fmt: skip
            return False
    C = inverse_gram(L[n - 1])  # (L_n L_n^T)^-1
    # fixed coordinates of the last node carry no variance (in the rotated frame)
    fixed = np.zeros(nx, dtype=np.bool_)
    Tn = np.eye(nx)
    Tb = np.empty((nx, nx))
    any_ball = False
    for bb in range(nb):
        if wball[n - 1, bb] != 0:
            any_ball = True
            piv = householder(nrm[n - 1, bb], ball_idx[bb], Tb)
            fixed[piv] = True
            for j in ball_idx[bb]:
                for k in ball_idx[bb]:
                    Tn[j, k] = Tb[j, k]
    for j in range(nx):
        if wbox[n - 1, j] != 0:
            fixed[j] = True
    for j in range(nx):
        if fixed[j]:
            for k in range(nx):
                C[j, k] = 0.0
                C[k, j] = 0.0
    if any_ball:  # x = T y with T symmetric and orthogonal
        C = mul(mul(Tn, C), Tn)
    for j in range(nx):
        for k in range(nx):
            out[j, k] = 0.5 * (C[j, k] + C[k, j])
    return True


def _blocks(n: int, nx: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    return np.empty((n, nx, nx)), np.empty((max(n - 1, 0), nx, nx)), np.empty((n, nx))


def window_covariance(
    model: WindowModel,
    problem: WindowProblemLike,
    X: FloatArray,
    workspace: Workspace | None = None,
    tol: float = 1e-6,
    hessian: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray | None:
    """Covariance (nx, nx) of the last node of ``X`` (N, nx), the window's solution:
    the Gauss-Newton Hessian from one call of the compiled window model, then
    :func:`last_block_covariance`. ``hessian``: its blocks ``(D, E)`` already at hand
    (the SQP's at its last evaluated iterate, :attr:`FastResult.hessian`), so no
    evaluation. None if the reduced Hessian is not positive definite.
    """
    fs, nx = model.feasible, model.nx
    out = np.empty((nx, nx))
    if hessian is not None:
        ok = last_block_covariance(X, *hessian, fs.lo, fs.hi, fs.ball_idx, fs.ball_r2, tol, out)
        return out if ok else None
    ws = workspace or Workspace(model)
    ws.z[:] = problem.z
    ws.m[:] = problem.zmask
    ws.u[:] = problem.u
    ws.dt[:] = problem.dt
    ws.Xb[0] = X
    ws.stage[0][:] = 0  # this problem's Q^-1: form the stage products anew
    node_mask = np.any(ws.m != 0.0, axis=1).astype(np.float64)
    D, E, g = ws.D[0], ws.E[0], ws.g[0]
    cost = _evaluate(
        ws.window, ws.ptrs[0], ws.out[0], ws.Xb[0], node_mask, model.rinv, problem.qinv,
        problem.xbar, problem.arrival, D, E, g, model.loss, ws.wgt[0], ws.extra[0], ws.gb[0],
        ws.ncost[0], ws.stage,
    )  # fmt: skip
    if not np.isfinite(cost):
        return None
    ok = last_block_covariance(X, D, E, fs.lo, fs.hi, fs.ball_idx, fs.ball_r2, tol, out)
    return out if ok else None


def casadi_window_covariance(
    formulation: Formulation,
    problem: WindowProblemLike,
    X: FloatArray,
    feasible: Feasible | None,
    tol: float = 1e-6,
    loss: LossKernel | None = None,
) -> FloatArray | None:
    """The same quantity as :func:`window_covariance`, with the Jacobians from the
    formulation's CasADi functions (the IPOPT backend's; no compiled model).
    ``feasible`` None: no bound is conditioned on. IPOPT's answers lie within its
    tolerance of a bound, hence the looser default ``tol``. ``loss``: the measurement
    loss (None: quadratic), whose weights enter the Hessian as in the fast backend."""
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
    node_mask = np.any(zmask != 0.0, axis=1).astype(np.float64)
    if feasible is None:
        lo, hi = np.full(nx, -np.inf), np.full(nx, np.inf)
        ball_idx, ball_r2 = np.zeros((0, 1), dtype=np.int64), np.zeros(0)
    else:
        lo, hi, ball_idx, ball_r2 = feasible.lo, feasible.hi, feasible.ball_idx, feasible.ball_r2
    D, E, g = _blocks(n, nx)
    rinv = np.asarray(np.linalg.inv(f.meas_cov()), dtype=np.float64)
    Xc = np.ascontiguousarray(X, dtype=float)
    if loss is None:
        loss = LossKernel(block_array(f.measurement_blocks), LOSS_CODES["l2"], np.inf)
    nblk = loss.blocks.shape[0]
    wgt, extra, gb = np.empty((n, nblk)), np.empty((n, nblk)), np.empty((n, nblk, nx))
    ncost = np.empty(n)
    _assemble(
        Xc, R, JR, W, FJ, node_mask, rinv, np.ascontiguousarray(problem.qinv, float),
        np.asarray(problem.xbar, float), np.ascontiguousarray(problem.arrival, float), D, E, g,
        loss, wgt, extra, gb, ncost, stage_buffers(n, nx, False),
        (D, E, g, wgt, extra, gb, ncost), False,
    )  # fmt: skip
    out = np.empty((nx, nx))
    ok = last_block_covariance(Xc, D, E, lo, hi, ball_idx, ball_r2, tol, out)
    return out if ok else None
