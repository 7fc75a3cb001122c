"""The QP subproblem of the SQP: its outcomes, and the equality-constrained step.

``min 1/2 d^T H d + g^T d`` over the window's step ``d`` (n, nx), ``H`` block-tridiagonal,
subject to the box ``lo <= X + d <= hi`` and each ball ``sum_{S_b} x_j^2 <= r_b^2``
linearised at ``X``, is solved by a primal active-set method in the compiled core
(``csrc/qp.hpp``; :func:`continuum_mhe._core.solve_qp`). Box-fixed coordinates are removed;
every active ball of a node is eliminated by a Householder reflection on its own
coordinates (the balls are disjoint, so a node's reflections commute and their product
is one symmetric orthogonal ``T``), so each equality-constrained step is one
block-tridiagonal Cholesky solve. The numba :func:`_eqp` (that step) remains for
:mod:`.covariance`.
"""

from __future__ import annotations

import numba
import numpy as np

from continuum_mhe.estimators.fast.linalg import btd_solve, householder

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
