"""Dense and block-tridiagonal linear algebra (numba kernels) of the arrival prior and
the covariance.

The window Hessian is symmetric block-tridiagonal, ``H = (D, E)`` with diagonal blocks
``D`` (n, nx, nx) and super-diagonal blocks ``E`` (n-1, nx, nx) (``E_i`` couples node
``i`` with node ``i+1``). The window solve's copies of these kernels are the compiled
core's (``csrc/btd.hpp``: :func:`continuum_mhe._core.btd_solve` and its siblings); the
ones here serve :mod:`.arrival` and :mod:`.covariance`: the block Cholesky and its
substitutions (compiled once more for the block sizes 4 and 8: their bodies are inlined
with ``nx`` a constant, so the compiler unrolls the ``nx``-loops), the Householder
reflection that eliminates one linearised ball, and small dense products
(:func:`mul`, :func:`mul_t`, :func:`cholesky`, :func:`inverse_gram`) written out: on
few-by-few matrices a BLAS or LAPACK call costs more than its arithmetic, and its code
evicts the caller's from the caches.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, inline="always")
def _factor(D, E, L, M, rd, nx):
    """:func:`btd_factor` for block size ``nx`` (a constant where inlined with one);
    ``rd`` (n, nx) receives the reciprocals of ``L``'s diagonal."""
    n = D.shape[0]
    a = np.empty((nx, nx))
    for i in range(n):
        for j in range(nx):
            for k in range(j + 1):  # the Schur complement's lower triangle
                s = D[i, j, k]
                if i > 0:
                    for c in range(nx):
                        s -= M[i - 1, j, c] * M[i - 1, k, c]
                a[j, k] = s
        for j in range(nx):  # dense Cholesky of the nx x nx block
            s = a[j, j]
            for c in range(j):
                s -= L[i, j, c] * L[i, j, c]
            if not s > 0.0:
                return False
            ljj = np.sqrt(s)
            L[i, j, j] = ljj
            r = 1.0 / ljj
            rd[i, j] = r
            for k in range(j + 1, nx):
                t = a[k, j]
                for c in range(j):
                    t -= L[i, k, c] * L[i, j, c]
                L[i, k, j] = t * r
            for k in range(j):
                L[i, k, j] = 0.0
        if i < n - 1:  # M_i L_i^T = E_i^T, row by row (forward substitution)
            for r_ in range(nx):
                for j in range(nx):
                    t = E[i, j, r_]
                    for c in range(j):
                        t -= M[i, r_, c] * L[i, j, c]
                    M[i, r_, j] = t * rd[i, j]
    return True


@numba.njit(cache=True, inline="always")
def _substitute(L, M, rd, b, y, nx):
    """``y = (L L^T)^-1 b`` from :func:`_factor`'s ``L``, ``M`` and ``rd``, block size
    ``nx``."""
    n = b.shape[0]
    for i in range(n):  # L z = b
        for j in range(nx):
            t = b[i, j]
            if i > 0:
                for c in range(nx):
                    t -= M[i - 1, j, c] * y[i - 1, c]
            for c in range(j):
                t -= L[i, j, c] * y[i, c]
            y[i, j] = t * rd[i, j]
    for i in range(n - 1, -1, -1):  # L^T y = z
        for j in range(nx - 1, -1, -1):
            t = y[i, j]
            if i < n - 1:
                for c in range(nx):
                    t -= M[i, c, j] * y[i + 1, c]
            for c in range(j + 1, nx):
                t -= L[i, c, j] * y[i, c]
            y[i, j] = t * rd[i, j]


@numba.njit(cache=True)
def factor_into(D, E, L, M, rd):
    """Block-tridiagonal Cholesky ``H = L L^T`` of ``H = (D, E)``; False if not PD.

    ``L`` (n, nx, nx) receives the diagonal factors, ``M`` (n-1, nx, nx) the
    sub-diagonal blocks ``M_i = E_i^T L_i^-T``, ``rd`` (n, nx) the reciprocals of
    ``L``'s diagonal. (Divisions by the pivots are multiplications by their
    reciprocals, computed once: they are the factor's critical path.)
    """
    nx = D.shape[1]
    if nx == 4:
        return _factor(D, E, L, M, rd, 4)
    if nx == 8:
        return _factor(D, E, L, M, rd, 8)
    return _factor(D, E, L, M, rd, nx)


@numba.njit(cache=True)
def btd_factor(D, E, L, M):
    """:func:`factor_into` without the reciprocals."""
    return factor_into(D, E, L, M, np.empty((D.shape[0], D.shape[1])))


@numba.njit(cache=True)
def substitute(L, M, rd, b, y):
    """``y = H^-1 b`` from :func:`factor_into`'s ``L``, ``M`` and ``rd``."""
    nx = b.shape[1]
    if nx == 4:
        _substitute(L, M, rd, b, y, 4)
    elif nx == 8:
        _substitute(L, M, rd, b, y, 8)
    else:
        _substitute(L, M, rd, b, y, nx)


@numba.njit(cache=True)
def btd_solve(D, E, b, L, M, y):
    """Solve ``H y = b`` by block-tridiagonal Cholesky ``H = L L^T`` (:func:`factor_into`,
    into ``L`` and ``M``); False if not PD."""
    rd = np.empty(b.shape)
    if not factor_into(D, E, L, M, rd):
        return False
    substitute(L, M, rd, b, y)
    return True


@numba.njit(cache=True)
def householder(nrm, ball_idx, T):
    """Symmetric orthogonal ``T`` with ``T n = -+e_c``; returns the pivot coordinate c."""
    nx = T.shape[0]
    for j in range(nx):
        for k in range(nx):
            T[j, k] = 1.0 if j == k else 0.0
    piv = ball_idx[0]
    for s_ in ball_idx:
        if abs(nrm[s_]) > abs(nrm[piv]):
            piv = s_
    sg = 1.0 if nrm[piv] >= 0.0 else -1.0
    v = np.zeros(nx)
    for s_ in ball_idx:
        v[s_] = nrm[s_]
    v[piv] += sg
    vv = 0.0
    for j in range(nx):
        vv += v[j] * v[j]
    for j in range(nx):
        for k in range(nx):
            T[j, k] -= 2.0 * v[j] * v[k] / vv
    return piv


@numba.njit(cache=True)
def mul(A, B):
    """``A @ B`` written out: for the few-by-few matrices of one node a BLAS call costs
    more in the call than in its arithmetic (and its code evicts the caller's from the
    caches)."""
    m, k, n = A.shape[0], A.shape[1], B.shape[1]
    out = np.empty((m, n))
    for i in range(m):
        for j in range(n):
            s = 0.0
            for a in range(k):
                s += A[i, a] * B[a, j]
            out[i, j] = s
    return out


@numba.njit(cache=True)
def mul_t(A, B):
    """``A @ B.T`` written out: :func:`mul` on the transposed view (no copy)."""
    return mul(A, B.T)


@numba.njit(cache=True)
def cholesky(A):
    """Lower Cholesky factor of a symmetric positive definite ``A`` (n, n); an empty
    (0, 0) array if ``A`` is not positive definite."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        s = A[j, j]
        for c in range(j):
            s -= L[j, c] * L[j, c]
        if not s > 0.0:
            return np.empty((0, 0))
        L[j, j] = np.sqrt(s)
        for k in range(j + 1, n):
            t = A[k, j]
            for c in range(j):
                t -= L[k, c] * L[j, c]
            L[k, j] = t / L[j, j]
    return L


@numba.njit(cache=True)
def inverse_gram(L):
    """``(L L^T)^-1 = L^-T L^-1`` (n, n), symmetric, for a lower-triangular ``L`` with a
    nonzero diagonal."""
    n = L.shape[0]
    Li = np.zeros((n, n))  # L^-1, lower triangular
    for c in range(n):
        for j in range(c, n):
            t = 1.0 if j == c else 0.0
            for k in range(c, j):
                t -= L[j, k] * Li[k, c]
            Li[j, c] = t / L[j, j]
    out = np.empty((n, n))
    for j in range(n):
        for k in range(j, n):
            s = 0.0
            for a in range(k, n):
                s += Li[a, j] * Li[a, k]
            out[j, k] = s
            out[k, j] = s
    return out
