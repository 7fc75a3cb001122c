"""The window solve: Newton-type SQP with a projected line search (numba kernels).

Each iteration evaluates the whole window's model in one call (residuals, Jacobians and
the measurement residuals' second-order term), assembles the block-tridiagonal Hessian
of the Lagrangian (:func:`_assemble`: Gauss-Newton ``J^T W J``, plus the exact
second-order term where that keeps it positive definite, plus ``2 lam_b I`` on the
coordinates of each ball ``b`` with a positive multiplier), and solves the QP subproblem
(:func:`~continuum_mhe.estimators.fast.qp.solve_qp`). Iterates stay exactly feasible
(projection). See ``docs/fast-solver.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.errors import UserError
from continuum_mhe.estimators.fast.ccall import address, call_model
from continuum_mhe.estimators.fast.memory import copy_into, move, shift_rows
from continuum_mhe.estimators.fast.model import WindowModel
from continuum_mhe.estimators.fast.qp import (
    CONVERGED,
    LINE_SEARCH_FAILED,
    MAX_ITER,
    NOT_PD,
    OUTCOMES,
    project,
    solve_qp,
)
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


#: Safety factor on the quadratic-rate error estimate of :func:`_sqp`. On the 494
#: windows of the benchmark's recording (``paper3d``, N = 30) that needed a third
#: iteration under the contraction bound alone, the true next step was at most 4.8
#: times the estimate ``|d_1|^3 / |d_0|^2`` (median 0.7).
QUADRATIC_SAFETY = 10.0


def quadratic_rate(model: WindowModel, options: FastOptions) -> bool:
    """Whether the SQP may certify by Newton's quadratic rate: exact Newton steps
    (``options.newton``), a transition affine in the state (else the Hessian the
    backend forms lacks the process model's second-order term), and not the Huber
    loss, whose second derivative jumps at its scale (with the estimate, Huber's worst
    certified window was 4.3e-8 from the converged answer)."""
    huber = model.loss.code == LOSS_CODES["huber"]
    return options.newton and model.linear_transition and not huber


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
def _step_to(out, X, alpha, d):
    """``out = X + alpha d`` (no temporaries)."""
    for i in range(X.shape[0]):
        for j in range(X.shape[1]):
            out[i, j] = X[i, j] + alpha * d[i, j]


@numba.njit(cache=True)
def _dot_diff(g, a, b):
    """``sum(g * (a - b))``."""
    s = 0.0
    for i in range(g.shape[0]):
        for j in range(g.shape[1]):
            s += g[i, j] * (a[i, j] - b[i, j])
    return s


@numba.njit(cache=True)
def _max_abs(d):
    """``max |d|``."""
    m = 0.0
    for i in range(d.shape[0]):
        for j in range(d.shape[1]):
            m = max(m, abs(d[i, j]))
    return m


@numba.njit(cache=True)
def _add_balls(D, Dgn, lam, ball_idx):
    """``Dgn = D`` (the Gauss-Newton blocks, kept for the covariance), then ``D_i +=
    2 lam_ib I_{S_b}``: each ball's curvature with its multiplier (n, nb) where positive."""
    copy_into(Dgn, D)
    for i in range(D.shape[0]):
        for bb in range(ball_idx.shape[0]):
            if lam[i, bb] > 0.0:
                for s_ in ball_idx[bb]:
                    D[i, s_, s_] += 2.0 * lam[i, bb]


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
def shift_outputs(tail, tptrs, tout, src, dst, n, nx, nz, nblk):
    """``dst``: the window model's outputs (:func:`~.codegen.window_function`'s
    layout) at the iterate shifted by one node: ``src``'s (the outputs at the previous
    window's iterate; may be ``dst``) without its first node and stage, then the
    tail function's (address ``tail``, argument pointers ``tptrs``, output ``tout``;
    :func:`~.codegen.tail_function`) for the new last node and stage. Returns False
    if the tail function failed."""
    if call_model(tail, tptrs.ctypes.data, tout.ctypes.data) != 0:
        return False
    off = 0  # section start in the window's outputs
    toff = 0  # ... and in the tail's
    sections = ((n, nz), (n, nz * nx), (n - 1, nx), (n - 1, nx * nx), (n, nblk * nx * nx))
    for count, chunk in sections:
        move(dst, off, src, off + chunk, (count - 1) * chunk)  # dst may be src
        move(dst, off + (count - 1) * chunk, tout, toff, chunk)
        off += count * chunk
        toff += chunk
    return True


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


@numba.njit(cache=True)
def _add_curvature(out, D, sign, wgt, extra, gb):
    """``D_i += sign * sum_b (wgt_ib S_ib + extra_ib gb_ib gb_ib^T)``: the exact Hessian's
    terms that Gauss-Newton leaves out (see :func:`_assemble`); ``S`` (n, nblocks, nx,
    nx) is the model's last output, the residuals' second-order term per block."""
    n, nx, nblk = D.shape[0], D.shape[1], wgt.shape[1]
    S = out[out.shape[0] - n * nblk * nx * nx :].reshape(n, nblk, nx, nx)
    for i in range(n):
        for bk in range(nblk):
            w, x2 = wgt[i, bk], extra[i, bk]
            if w != 0.0 or x2 != 0.0:
                for j in range(nx):
                    for k in range(nx):
                        D[i, j, k] += sign * (w * S[i, bk, j, k] + x2 * gb[i, bk, j] * gb[i, bk, k])


@numba.njit(cache=True)
def _sqp(
    fn,
    ptrs,
    Xb,
    out,
    zmask,
    rinv,
    qinv,
    xbar,
    arrival,
    lo,
    hi,
    bidx,
    r2,
    lam,
    max_iter,
    step_tol,
    err_tol,
    max_qp,
    newton,
    D,
    E,
    g,
    d,
    lam_qp,
    loss,
    wgt,
    extra,
    gb,
    Dgn,
    quadratic,
    stage,
    evaluated,
    ncost,
    shifted,
):
    """Newton-type SQP on two buffers (current, trial); returns
    ``(outcome, iterations, step, cost, index of the buffer with the answer)``.
    ``Dgn[b]`` keeps the Gauss-Newton diagonal blocks of buffer ``b``'s iterate
    (``E[b]`` are its off-diagonal ones): on certification the other buffer holds the
    last evaluated iterate ``X_k``, whose blocks give the answer's covariance.

    Certified when the QP step ``d`` is below ``step_tol``, or, with no constraint
    active, when the observed contraction ``rho = |d_k| / |d_k-1| <= 1/2`` of two
    full steps bounds the error of ``X_k + d_k`` by ``rho / (1 - rho) |d_k| <= err_tol``;
    when both steps were exact Newton steps, by the smaller quadratic-rate estimate
    ``QUADRATIC_SAFETY |d_k|^3 / |d_k-1|^2`` (the error ``K |d_k|^2`` with the rate
    ``K = |d_k| / |d_k-1|^2`` observed on the previous step), if ``quadratic``
    (:func:`quadratic_rate`) and neither QP had an active constraint.
    The answer is then the projection of ``X_k + d_k`` (not evaluated again);
    ``cost`` is at ``X_k``. ``evaluated``: ``out[0]`` already holds the model's
    outputs at ``Xb[0]`` (:func:`shift_outputs`), so the first iterate is not evaluated;
    ``shifted >= 0`` (with ``evaluated``): ``Xb[0]`` is buffer ``shifted``'s iterate of
    the previous window (with the same data, a node later) shifted by one node, whose
    assembly (``Dgn``, ``E``, ``g``, ... of that buffer) shifts with it
    (:func:`_assemble` with ``shifted``). ``ncost`` (2, N): each buffer's node costs.
    """
    cur = 0
    project(Xb[0], lo, hi, bidx, r2)
    if evaluated:  # out[0] holds the model's outputs at Xb[0] (:func:`shift_outputs`)
        b = shifted if shifted >= 0 else 0  # ... and buffer b the assembly that shifts
        prev = (Dgn[b], E[b], g[b], wgt[b], extra[b], gb[b], ncost[b])
        cost = _assemble_outputs(
            out[0], Xb[0], zmask, rinv, qinv, xbar, arrival, D[0], E[0], g[0], loss, wgt[0],
            extra[0], gb[0], ncost[0], stage, prev, shifted >= 0,
        )  # fmt: skip
    else:
        cost = _evaluate(
            fn, ptrs[0], out[0], Xb[0], zmask, rinv, qinv, xbar, arrival, D[0], E[0], g[0],
            loss, wgt[0], extra[0], gb[0], ncost[0], stage,
        )  # fmt: skip
    _add_balls(D[0], Dgn[0], lam, bidx)
    exact = newton  # exact Hessian at the current iterate (else Gauss-Newton)
    if exact:
        _add_curvature(out[0], D[0], 1.0, wgt[0], extra[0], gb[0])
    step = np.inf
    prev = np.inf  # previous full step (inf after a shortened one)
    prev_exact = False  # ... and whether it was an exact Newton step
    prev_active = 1  # ... and its QP's number of active constraints
    for it in range(1, max_iter + 1):
        if not np.isfinite(cost):
            return LINE_SEARCH_FAILED, it, step, cost, cur
        status, _, active = solve_qp(
            Xb[cur], D[cur], E[cur], g[cur], lo, hi, bidx, r2, max_qp, d, lam_qp
        )
        if status == NOT_PD and exact:  # indefinite: fall back to Gauss-Newton here
            _add_curvature(out[cur], D[cur], -1.0, wgt[cur], extra[cur], gb[cur])
            exact = False
            status, _, active = solve_qp(
                Xb[cur], D[cur], E[cur], g[cur], lo, hi, bidx, r2, max_qp, d, lam_qp
            )
        if status != CONVERGED:
            return status, it, step, cost, cur
        step_exact = exact  # d is an exact Newton step
        step = _max_abs(d)
        tr = 1 - cur
        contracted = active == 0 and prev < np.inf and step <= 0.5 * prev
        err = np.inf  # the estimated error of X_k + d_k
        if contracted:
            err = step * step / (prev - step)
            if quadratic and exact and prev_exact and prev_active == 0:  # two Newton steps
                err = min(err, QUADRATIC_SAFETY * step**3 / prev**2)
        if step <= step_tol or err <= err_tol:
            lam[:] = lam_qp
            _step_to(Xb[tr], Xb[cur], 1.0, d)
            project(Xb[tr], lo, hi, bidx, r2)
            return CONVERGED, it, step, cost, tr
        alpha = 1.0
        slack = 1e-13 * (1.0 + abs(cost))
        accepted = False
        for _ in range(30):
            _step_to(Xb[tr], Xb[cur], alpha, d)
            project(Xb[tr], lo, hi, bidx, r2)
            ct = _evaluate(
                fn, ptrs[tr], out[tr], Xb[tr], zmask, rinv, qinv, xbar, arrival, D[tr], E[tr],
                g[tr], loss, wgt[tr], extra[tr], gb[tr], ncost[tr], stage,
            )  # fmt: skip
            _add_balls(D[tr], Dgn[tr], lam_qp, bidx)
            if ct <= cost + 1e-4 * _dot_diff(g[cur], Xb[tr], Xb[cur]) + slack:
                accepted = True
                exact = newton
                if exact:
                    _add_curvature(out[tr], D[tr], 1.0, wgt[tr], extra[tr], gb[tr])
                break
            alpha *= 0.5
        if not accepted:
            return LINE_SEARCH_FAILED, it, step, cost, cur
        prev = step if alpha == 1.0 else np.inf
        prev_exact = step_exact
        prev_active = active
        cur, cost = tr, ct
        lam[:] = lam_qp
    return MAX_ITER, max_iter, step, cost, cur


@dataclass(frozen=True)
class FastResult:
    """Outcome of :func:`solve_window`.

    Attributes:
        X: (N, nx) the answer (see :func:`_sqp`); feasible exactly.
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
            warm start (its model outputs are then known: :func:`shift_outputs`).
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


def _pointers(
    X: FloatArray, z: FloatArray, m: FloatArray, u: FloatArray, dt: FloatArray
) -> NDArray[np.uintp]:
    return np.array(
        [
            X.ctypes.data,
            z.ctypes.data,
            m.ctypes.data,
            u.ctypes.data if u.size else 0,
            dt.ctypes.data,
        ],
        dtype=np.uintp,
    )


class Workspace:
    """Buffers of :func:`solve_window`, reusable across windows of one model.

    The window data are copied into fixed buffers, so the C model's argument
    pointers are computed once.
    """

    def __init__(self, model: WindowModel) -> None:
        n, nx, nz, nu = model.horizon, model.nx, model.nz, model.nu
        self.z = np.zeros((n, nz))
        self.m = np.zeros((n, nz))
        self.u = np.zeros((n - 1, nu))
        self.dt = np.zeros(n - 1)
        self.Xb = np.empty((2, n, nx))
        self.out = np.empty((2, model.window_size))
        self.D = np.empty((2, n, nx, nx))
        self.E = np.empty((2, n - 1, nx, nx))
        self.g = np.empty((2, n, nx))
        self.d = np.empty((n, nx))
        self.lam_qp = np.zeros((n, len(model.feasible.ball_r2)))
        nblk = len(model.loss.blocks)
        self.wgt = np.empty((2, n, nblk))
        self.extra = np.empty((2, n, nblk))
        self.gb = np.empty((2, n, nblk, nx))
        self.Dgn = np.empty((2, n, nx, nx))  # Gauss-Newton diagonal blocks per iterate
        self.ncost = np.empty((2, n))  # each node's cost per iterate
        self.stage = stage_buffers(n, nx, model.linear_transition)
        # the tail function's arguments (:func:`shift_outputs`): buffer 0's last stage
        self.tail_out = np.empty(nz + nz * nx + nx + nx * nx + nblk * nx * nx)
        self.tail_ptrs = np.array(
            [self.Xb[0, max(n - 2, 0)].ctypes.data, self.Xb[0, n - 1].ctypes.data,
             self.z[n - 1].ctypes.data, self.m[n - 1].ctypes.data,
             self.u[max(n - 2, 0)].ctypes.data if nu and n > 1 else 0,
             self.dt[max(n - 2, 0) :].ctypes.data if n > 1 else 0],
            dtype=np.uintp,
        )  # fmt: skip
        self.tail = address(model.tail) if model.tail is not None else 0
        self.ptrs = np.stack([_pointers(x, self.z, self.m, self.u, self.dt) for x in self.Xb])
        self.window = address(model.window)  # of the window function (the model keeps it)


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
    fs, n = model.feasible, model.horizon
    ws = workspace or Workspace(model)
    ws.z[:] = problem.z
    ws.m[:] = problem.zmask
    ws.u[:] = problem.u
    ws.dt[:] = problem.dt
    ws.Xb[0] = X0
    ws.stage[0][:] = 0  # this problem's Q^-1: form the stage products anew
    nb = len(fs.ball_r2)
    lam = np.zeros((n, nb)) if lam0 is None else np.array(lam0, dtype=float).reshape(n, nb)
    node_mask = np.any(ws.m != 0.0, axis=1).astype(np.float64)  # the residuals are masked
    outcome, it, step, cost, cur = _sqp(
        ws.window, ws.ptrs, ws.Xb, ws.out, node_mask, model.rinv, problem.qinv,
        problem.xbar, problem.arrival, fs.lo, fs.hi, fs.ball_idx, fs.ball_r2, lam,
        opt.max_iter, opt.step_tol, opt.err_tol, opt.max_qp_iter, opt.newton, ws.D, ws.E,
        ws.g, ws.d, ws.lam_qp, model.loss, ws.wgt, ws.extra, ws.gb, ws.Dgn,
        quadratic_rate(model, opt), ws.stage, False, ws.ncost, -1,
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
    n, nx = model.horizon, model.nx
    Xc = np.array(X, dtype=float)
    z, u = np.ascontiguousarray(problem.z, float), np.ascontiguousarray(problem.u, float)
    dt = np.ascontiguousarray(problem.dt, float)
    m = np.ascontiguousarray(problem.zmask, float)
    node_mask = np.any(m != 0.0, axis=1).astype(np.float64)
    nblk = len(model.loss.blocks)
    return float(
        _evaluate(
            address(model.window), _pointers(Xc, z, m, u, dt), np.empty(model.window_size), Xc,
            node_mask, model.rinv, problem.qinv, problem.xbar, problem.arrival,
            np.empty((n, nx, nx)),
            np.empty((n - 1, nx, nx)), np.empty((n, nx)), model.loss, np.empty((n, nblk)),
            np.empty((n, nblk)), np.empty((n, nblk, nx)), np.empty(n),
            stage_buffers(n, nx, False),
        )
    )  # fmt: skip
