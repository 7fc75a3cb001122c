"""The QP subproblem of the SQP: a primal active-set method (numba kernels).

``min 1/2 d^T H d + g^T d`` over the window's step ``d`` (n, nx), ``H`` block-tridiagonal,
subject to the box ``lo <= X + d <= hi`` and each ball ``sum_{S_b} x_j^2 <= r_b^2``
linearised at ``X``. Box-fixed coordinates are removed; every active ball of a node is
eliminated by a Householder reflection on its own coordinates (the balls are disjoint,
so a node's reflections commute and their product is one symmetric orthogonal ``T``),
so each equality-constrained step is one block-tridiagonal Cholesky solve.
"""

from __future__ import annotations

import numba
import numpy as np

from continuum_mhe.estimators.fast.linalg import btd_solve, householder, matvec

#: Solver outcomes of the QP and of :func:`~continuum_mhe.estimators.fast.sqp.solve_window`.
CONVERGED, MAX_ITER, LINE_SEARCH_FAILED, QP_FAILED, NOT_PD = 0, 1, 2, 3, 4
OUTCOMES = ("converged", "max-iter", "line-search-failed", "qp-failed", "not-positive-definite")


@numba.njit(cache=True)
def _eqp(D, E, grad, wbox, wball, nrm, ball_idx, p, Dt, Et, b, L, M, T):
    """Equality-constrained Newton step ``H p = -grad`` on the working set.

    Box-fixed coordinates get ``p = 0``; each active ball ``b`` of a node gets
    ``n_b . p = 0``, eliminated by a Householder reflection on its coordinates. The
    balls of a node are disjoint, so their reflections commute and their product ``T``
    is symmetric and orthogonal; the blocks keep their structure.
    """
    n, nx = grad.shape
    nb = ball_idx.shape[0]
    anyb = np.zeros(n, dtype=np.bool_)
    fixed = np.zeros((n, nx), dtype=np.bool_)
    tmp = np.empty((nx, nx))
    Tb = np.empty((nx, nx))
    for i in range(n):
        for bb in range(nb):
            if wball[i, bb] != 0:
                if not anyb[i]:
                    for j in range(nx):
                        for k in range(nx):
                            T[i, j, k] = 1.0 if j == k else 0.0
                    anyb[i] = True
                piv = householder(nrm[i, bb], ball_idx[bb], Tb)
                fixed[i, piv] = True
                for j in ball_idx[bb]:
                    for k in ball_idx[bb]:
                        T[i, j, k] = Tb[j, k]
    for i in range(n):
        if anyb[i]:
            for j in range(nx):
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += D[i, j, a] * T[i, a, k]
                    tmp[j, k] = s
            for j in range(nx):
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += T[i, j, a] * tmp[a, k]
                    Dt[i, j, k] = s
                s = 0.0
                for a in range(nx):
                    s += T[i, j, a] * grad[i, a]
                b[i, j] = -s
        else:
            for j in range(nx):
                b[i, j] = -grad[i, j]
                for k in range(nx):
                    Dt[i, j, k] = D[i, j, k]
        if i < n - 1:
            for j in range(nx):
                for k in range(nx):
                    Et[i, j, k] = E[i, j, k]
            if anyb[i]:
                for j in range(nx):
                    for k in range(nx):
                        s = 0.0
                        for a in range(nx):
                            s += T[i, j, a] * Et[i, a, k]
                        tmp[j, k] = s
                Et[i] = tmp
            if anyb[i + 1]:
                for j in range(nx):
                    for k in range(nx):
                        s = 0.0
                        for a in range(nx):
                            s += Et[i, j, a] * T[i + 1, a, k]
                        tmp[j, k] = s
                Et[i] = tmp
    for i in range(n):
        for c in range(nx):
            if wbox[i, c] != 0 or fixed[i, c]:
                for k in range(nx):
                    Dt[i, c, k] = 0.0
                    Dt[i, k, c] = 0.0
                    if i < n - 1:
                        Et[i, c, k] = 0.0
                    if i > 0:
                        Et[i - 1, k, c] = 0.0
                Dt[i, c, c] = 1.0
                b[i, c] = 0.0
    if not btd_solve(Dt, Et, b, L, M, p):
        return False
    for i in range(n):
        if anyb[i]:
            for j in range(nx):
                s = 0.0
                for a in range(nx):
                    s += T[i, j, a] * p[i, a]
                tmp[0, j] = s
            for j in range(nx):
                p[i, j] = tmp[0, j]
        for c in range(nx):
            if wbox[i, c] != 0:
                p[i, c] = 0.0
    return True


@numba.njit(cache=True)
def solve_qp(X, D, E, g, lo, hi, ball_idx, ball_r2, max_it, d, lam):
    """Primal active-set solution ``d`` of the SQP subproblem at ``X``.

    ``min 1/2 d^T H d + g^T d`` s.t. ``lo <= X + d <= hi`` and every ball linearised at
    ``X``. Starts from ``d = 0`` with the constraints active at ``X``. On success
    ``lam`` (n, nb) holds the ball multipliers. Returns ``(status, iterations, number
    of active constraints)``.
    """
    n, nx = X.shape
    nb = ball_idx.shape[0]
    wbox = np.zeros((n, nx), dtype=np.int8)
    wball = np.zeros((n, max(nb, 1)), dtype=np.int8)
    nrm = np.zeros((n, max(nb, 1), nx))
    gnorm = np.zeros((n, max(nb, 1)))
    slack = np.zeros((n, max(nb, 1)))
    for i in range(n):
        for j in range(nx):
            if X[i, j] <= lo[j]:
                wbox[i, j] = -1
            elif X[i, j] >= hi[j]:
                wbox[i, j] = 1
        for bb in range(nb):
            q = 0.0
            for s_ in ball_idx[bb]:
                q += X[i, s_] * X[i, s_]
            if q > 0.0:
                rq = np.sqrt(q)
                for s_ in ball_idx[bb]:
                    nrm[i, bb, s_] = X[i, s_] / rq
                gnorm[i, bb] = 2.0 * rq
                slack[i, bb] = max(ball_r2[bb] - q, 0.0) / gnorm[i, bb]
                if q >= ball_r2[bb] * (1.0 - 1e-12):
                    wball[i, bb] = 1
                    slack[i, bb] = 0.0
    gscale = 1.0
    for i in range(n):
        for j in range(nx):
            gscale = max(gscale, abs(g[i, j]))
    mu_tol = 1e-12 * gscale
    d[:] = 0.0
    p = np.empty((n, nx))
    grad = np.empty((n, nx))
    b = np.empty((n, nx))
    L = np.empty_like(D)
    M = np.empty_like(E)
    Dt = np.empty((0, nx, nx))  # the equality-constrained step's, allocated when needed
    Et = np.empty((0, nx, nx))
    T = np.empty((0, nx, nx))
    for it in range(max_it):
        nfix = np.count_nonzero(wbox) + np.count_nonzero(wball)
        if nfix and Dt.shape[0] == 0:
            Dt = np.empty_like(D)
            Et = np.empty_like(E)
            T = np.empty_like(D)
        if it == 0:  # d = 0
            grad[:] = g
        else:
            matvec(D, E, d, grad)
            for i in range(n):
                for j in range(nx):
                    grad[i, j] += g[i, j]
        if nfix == 0:  # nothing fixed: the plain Newton system
            for i in range(n):
                for j in range(nx):
                    b[i, j] = -grad[i, j]
            if not btd_solve(D, E, b, L, M, p):
                return NOT_PD, it, 0
        elif not _eqp(D, E, grad, wbox, wball, nrm, ball_idx, p, Dt, Et, b, L, M, T):
            return NOT_PD, it, 0
        alpha = 1.0
        kind, bi, bj = 0, -1, -1
        for i in range(n):
            for j in range(nx):
                if wbox[i, j] == 0:
                    pij = p[i, j]
                    if pij > 0.0 and hi[j] < np.inf:
                        a = max((hi[j] - X[i, j] - d[i, j]) / pij, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, 1, i, j
                    elif pij < 0.0 and lo[j] > -np.inf:
                        a = max((lo[j] - X[i, j] - d[i, j]) / pij, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, -1, i, j
            for bb in range(nb):
                if wball[i, bb] == 0 and gnorm[i, bb] > 0.0:
                    sp = 0.0
                    sd = 0.0
                    for s_ in ball_idx[bb]:
                        sp += nrm[i, bb, s_] * p[i, s_]
                        sd += nrm[i, bb, s_] * d[i, s_]
                    if sp > 0.0:
                        a = max((slack[i, bb] - sd) / sp, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, 2, i, bb
        for i in range(n):
            for j in range(nx):
                d[i, j] += alpha * p[i, j]
        if kind != 0:
            if kind == 2:
                wball[bi, bj] = 1
            else:
                wbox[bi, bj] = kind
                d[bi, bj] = (hi[bj] if kind == 1 else lo[bj]) - X[bi, bj]
            continue
        # at the minimiser on the working set: check the multipliers' signs
        if nfix == 0:
            lam[:] = 0.0
            return CONVERGED, it + 1, 0
        matvec(D, E, d, grad)
        worst, wi, wj = -mu_tol, -1, 0
        for i in range(n):
            for j in range(nx):
                if wbox[i, j] != 0:
                    mu = -grad[i, j] - g[i, j] if wbox[i, j] == 1 else grad[i, j] + g[i, j]
                    if mu < worst:
                        worst, wi, wj = mu, i, j
            for bb in range(nb):
                lam[i, bb] = 0.0
                if wball[i, bb] != 0:
                    s = 0.0
                    for s_ in ball_idx[bb]:
                        s += (grad[i, s_] + g[i, s_]) * nrm[i, bb, s_]
                    lam[i, bb] = -s / gnorm[i, bb]
                    if lam[i, bb] < worst:
                        worst, wi, wj = lam[i, bb], i, -1 - bb
        if wi < 0:
            return CONVERGED, it + 1, np.count_nonzero(wbox) + np.count_nonzero(wball)
        if wj < 0:
            wball[wi, -1 - wj] = 0
        else:
            wbox[wi, wj] = 0
    return QP_FAILED, max_it, 0


@numba.njit(cache=True)
def project(X, lo, hi, ball_idx, ball_r2):
    """Project each node onto the box and the balls, in place (bounds hold exactly)."""
    n, nx = X.shape
    for i in range(n):
        for j in range(nx):
            X[i, j] = min(max(X[i, j], lo[j]), hi[j])
        for bb in range(ball_idx.shape[0]):
            r2 = ball_r2[bb]
            q = 0.0
            for s_ in ball_idx[bb]:
                q += X[i, s_] * X[i, s_]
            if q > r2:
                c = np.sqrt(r2 / q)
                for _ in range(4):  # rounding: shrink by ulps until it holds exactly
                    q = 0.0
                    for s_ in ball_idx[bb]:
                        q += (c * X[i, s_]) ** 2
                    if q <= r2:
                        break
                    c = np.nextafter(c, 0.0) * (1.0 - 2e-16)
                for s_ in ball_idx[bb]:
                    X[i, s_] *= c
