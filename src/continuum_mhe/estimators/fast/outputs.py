"""The outputs of one state and their standard deviations, as numba kernels.

Shared by the fused MHE step (:func:`~continuum_mhe.estimators.fast.step.finish`) and
the fused EKF step (:func:`~continuum_mhe.estimators.fast.arrival.ekf_step_outputs`), so
that both estimators hand back the same products from one compiled call. ``outputs =
(output, jacobian, optrs, ox, oout, jout, wrapped)``: the addresses of the compiled
output function and its Jacobian, their argument pointers (to ``ox``, (nx,)), their
outputs ``oout`` (ny,) and ``jout`` (ny * nx, column-major) and the indices of the
outputs that are angles wrapped into ``[-pi, pi)``
(:class:`~continuum_mhe.estimators.fast.model.NodeEvaluator` owns the buffers).
"""

from __future__ import annotations

import numba
import numpy as np

from continuum_mhe.estimators.fast.ccall import call_model

#: The kernels' errors when the compiled output function or its Jacobian fails (they
#: cannot format the function's own message; the wrappers do).
OUTPUT_FAILED = "output evaluation failed"
OUTPUT_JACOBIAN_FAILED = "output Jacobian evaluation failed"


@numba.njit(cache=True)
def output_values(outputs, x, y):
    """The outputs ``y`` (ny,) of state ``x``; leaves ``x`` in the functions' input
    buffer for :func:`output_std`. Raises ``RuntimeError(OUTPUT_FAILED)``."""
    ofn, _, optrs, ox, oout, _, wrapped = outputs
    ox[:] = x
    if call_model(ofn, optrs.ctypes.data, oout.ctypes.data) != 0:
        raise RuntimeError(OUTPUT_FAILED)
    y[:] = oout
    for i in wrapped:
        y[i] = (y[i] + np.pi) % (2 * np.pi) - np.pi


@numba.njit(cache=True)
def output_std(outputs, cov, std):
    """``std = sqrt(diag(J cov J^T))`` (ny,), ``J`` the output Jacobian at the state
    that :func:`output_values` was last given. Raises
    ``RuntimeError(OUTPUT_JACOBIAN_FAILED)``."""
    _, jfn, optrs, _, _, jout, _ = outputs
    if call_model(jfn, optrs.ctypes.data, jout.ctypes.data) != 0:
        raise RuntimeError(OUTPUT_JACOBIAN_FAILED)
    ny, nx = std.shape[0], cov.shape[0]
    for i in range(ny):
        s = 0.0
        for j in range(nx):
            for k in range(nx):
                s += jout[i + ny * j] * cov[j, k] * jout[i + ny * k]
        std[i] = np.sqrt(max(s, 0.0))
