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
from continuum_mhe.estimators.fast.linalg import cholesky, inverse_gram, mul, mul_t
from continuum_mhe.estimators.fast.outputs import output_std, output_values


@numba.njit(cache=True)
def arrival_update(x, P, r, H, R):
    """EKF measurement update of the arrival prior, Joseph form: ``(x, P)``.

    Same equations as :func:`continuum_mhe.estimators.kalman.ekf_update`, with the
    residual ``r`` (nz,) and ``H = -dr/dx`` (nz, nx) from
    :meth:`WindowModel.evaluate_node`. The gain from the Cholesky factor of the
    innovation covariance ``S`` (LAPACK's solve where ``S`` is not positive definite);
    the products written out (:func:`~.linalg.mul`).
    """
    nx, nz = P.shape[0], R.shape[0]
    HP = mul(H, P)
    S = mul_t(HP, H)
    for a in range(nz):
        for b in range(nz):
            S[a, b] += R[a, b]
    Ls = cholesky(S)
    if Ls.shape[0] == 0:
        Kt = np.linalg.solve(S, HP)
    else:
        Kt = mul(inverse_gram(Ls), HP)  # S^-1 H P (nz, nx)
    xn = x.copy()
    ikh = np.empty((nx, nx))
    for j in range(nx):
        for a in range(nz):
            xn[j] += Kt[a, j] * r[a]
        for k in range(nx):
            s = 1.0 if j == k else 0.0
            for a in range(nz):
                s -= Kt[a, j] * H[a, k]
            ikh[j, k] = s
    K = Kt.T.copy()
    return xn, mul_t(mul(ikh, P), ikh) + mul_t(mul(K, R), K)


@numba.njit(cache=True)
def predict_covariance(P, F, Q):
    """``F P F^T + Q`` (nx, nx), the products written out (:func:`~.linalg.mul`): the
    EKF's and the arrival prior's prediction."""
    return mul_t(mul(F, P), F) + Q


@numba.njit(cache=True)
def arrival_predict(P, F, Q):
    """EKF covariance prediction of the arrival prior: ``(P, P^-1)``, ``P = F P F^T + Q``
    symmetrised; the inverse from the Cholesky factor, or LAPACK's where ``P`` is not
    positive definite."""
    Pn = predict_covariance(P, F, Q)
    nx = Pn.shape[0]
    for j in range(nx):
        for k in range(j):
            m = 0.5 * (Pn[j, k] + Pn[k, j])
            Pn[j, k] = m
            Pn[k, j] = m
    L = cholesky(Pn)
    if L.shape[0] == 0:
        return Pn, np.linalg.inv(Pn)
    return Pn, inverse_gram(L)


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
