"""The EKF step of the arrival prior (and of the compiled EKF), as numba kernels.

When the window slides, the arrival prior ``(xbar, P)`` takes one EKF step: an update
with the sample that leaves the window (its valid components only: the node function's
residual and Jacobian are masked) and a prediction to the new first sample. These
kernels call the compiled node model (:func:`~continuum_mhe.estimators.fast.codegen.node_function`)
directly, so one step is one call from Python; the compiled EKF's step with its outputs
and their standard deviations is one call too (:func:`ekf_step_outputs`). A failed
model evaluation raises ``RuntimeError("model evaluation failed")``; the caller adds
the model's own message
(:meth:`~continuum_mhe.estimators.fast.model.NodeEvaluator.arrival_step`).
"""

from __future__ import annotations

import numba
import numpy as np

from continuum_mhe.estimators.fast.ccall import call_model
from continuum_mhe.estimators.fast.outputs import output_std, output_values


@numba.njit(cache=True)
def arrival_update(x, P, r, H, R):
    """EKF measurement update of the arrival prior, Joseph form: ``(x, P)``.

    Same equations as :func:`continuum_mhe.estimators.kalman.ekf_update`, with the
    residual ``r`` (nz,) and ``H = -dr/dx`` (nz, nx) from
    :meth:`WindowModel.evaluate_node`.
    """
    nx = P.shape[0]
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    ikh = np.eye(nx) - K @ H
    return x + K @ r, ikh @ P @ ikh.T + K @ R @ K.T


@numba.njit(cache=True)
def predict_covariance(P, F, Q):
    """``F P F^T + Q`` (nx, nx), written out: for matrices this small an ``nx x nx``
    product through BLAS costs more in its call than in its arithmetic. The EKF's and
    the arrival prior's prediction."""
    nx = P.shape[0]
    fp = np.empty((nx, nx))
    for j in range(nx):
        for k in range(nx):
            s = 0.0
            for a in range(nx):
                s += F[j, a] * P[a, k]
            fp[j, k] = s
    Pn = np.empty((nx, nx))
    for j in range(nx):
        for k in range(nx):
            s = 0.0
            for a in range(nx):
                s += fp[j, a] * F[k, a]
            Pn[j, k] = s + Q[j, k]
    return Pn


@numba.njit(cache=True)
def arrival_predict(P, F, Q):
    """EKF covariance prediction of the arrival prior: ``(P, P^-1)``, ``P = F P F^T + Q``
    symmetrised; the inverse from the Cholesky factor (:func:`spd_inverse`), or LAPACK's
    where ``P`` is not positive definite."""
    Pn = predict_covariance(P, F, Q)
    nx = Pn.shape[0]
    for j in range(nx):
        for k in range(j):
            m = 0.5 * (Pn[j, k] + Pn[k, j])
            Pn[j, k] = m
            Pn[k, j] = m
    Pinv = spd_inverse(Pn)
    if Pinv.shape[0] == 0:
        Pinv = np.linalg.inv(Pn)
    return Pn, Pinv


@numba.njit(cache=True)
def spd_inverse(A):
    """``A^-1`` of a symmetric positive definite ``A`` (n, n) by Cholesky, symmetric; an
    empty (0, 0) array if ``A`` is not positive definite."""
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
    Li = np.zeros((n, n))  # L^-1, lower triangular
    for c in range(n):
        for j in range(c, n):
            t = 1.0 if j == c else 0.0
            for k in range(c, j):
                t -= L[j, k] * Li[k, c]
            Li[j, c] = t / L[j, j]
    out = np.empty((n, n))  # L^-T L^-1
    for j in range(n):
        for k in range(j, n):
            s = 0.0
            for a in range(k, n):
                s += Li[a, j] * Li[a, k]
            out[j, k] = s
            out[k, j] = s
    return out


@numba.njit(cache=True)
def arrival_step(fn, ptrs, out, xin, x, P, valid, R, Q, nx):
    """:meth:`NodeEvaluator.arrival_step` in one compiled call (two model calls)."""
    nz = R.shape[0]
    k = nx + nx * nx
    if valid:
        xin[:] = x
        if call_model(fn, ptrs.ctypes.data, out.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        H = out[k : k + nz * nx].copy().reshape(nz, nx)
        r = out[k + nz * nx : k + nz * nx + nz].copy()
        x, P = arrival_update(x, P, r, H, R)
    xin[:] = x
    if call_model(fn, ptrs.ctypes.data, out.ctypes.data) != 0:
        raise RuntimeError("model evaluation failed")
    xn = out[:nx].copy()
    F = out[nx:k].copy().reshape(nx, nx)
    P, Pinv = arrival_predict(P, F, Q)
    return xn, P, Pinv


@numba.njit(cache=True)
def ekf_step(fn, ptrs, out, xin, x, P, valid, R, Q, nx):
    """The EKF step of :func:`ekf_step_outputs`: EKF prediction, then (if ``valid``)
    the update on the masked residual (two model calls)."""
    nz = R.shape[0]
    k = nx + nx * nx
    xin[:] = x
    if call_model(fn, ptrs.ctypes.data, out.ctypes.data) != 0:
        raise RuntimeError("model evaluation failed")
    xn = out[:nx].copy()
    F = out[nx:k].copy().reshape(nx, nx)
    P = predict_covariance(P, F, Q)
    if valid:
        xin[:] = xn
        if call_model(fn, ptrs.ctypes.data, out.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        H = out[k : k + nz * nx].copy().reshape(nz, nx)
        r = out[k + nz * nx : k + nz * nx + nz].copy()
        xn, P = arrival_update(xn, P, r, H, R)
    return xn, P


@numba.njit(cache=True)
def ekf_step_outputs(fn, ptrs, out, inputs, x, P, sample, R, Q, outputs, y, std):
    """:func:`ekf_step` on ``sample = (z, mask, u, dt)`` (the node model's input
    buffers ``inputs = (x, u, dt, z, mask)`` filled here, masked readings zeroed), then
    the new state's outputs ``y`` and their standard deviations ``std``
    (:mod:`.outputs`): everything the EKF reports for a sample, in one compiled call,
    as the fused MHE step hands back its own. Returns ``(x, P)``."""
    xin, uin, dtin, zin, min_ = inputs
    z, mask, u, dt = sample
    valid = False
    for i in range(z.shape[0]):
        on = mask[i] > 0.0
        zin[i] = z[i] if on else 0.0
        min_[i] = mask[i]
        valid = valid or on
    uin[:] = u
    dtin[0] = dt
    xn, Pn = ekf_step(fn, ptrs, out, xin, x, P, valid, R, Q, x.shape[0])
    output_values(outputs, xn, y)
    output_std(outputs, Pn, std)
    return xn, Pn
