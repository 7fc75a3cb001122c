"""The bare compiled kernels of one EKF step and one fast-MHE step, timed alone.

``continuum-mhe benchmark`` times every estimator through its ``step`` (input checks,
sensor masks, divergence check, the ``Estimate``). These two runners time only the
compiled calls of one step, the inputs (sensor mask, ``u``, ``Q(dt)``) computed
outside the timed part, so that the two methods' arithmetic can be compared without
the interface both share (:mod:`continuum_mhe.benchmark.harness`'s rows ``ekf-kernel`` and
``mhe-kernel``).
"""

from __future__ import annotations

import time

import numpy as np

from continuum_mhe.estimators.base import FloatArray
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.simulation.scenarios import Recording


def run_ekf_kernel(formulation: Formulation, rec: Recording) -> tuple[FloatArray, FloatArray]:
    """The EKF as the bare compiled kernel: per sample one compiled call of the EKF step
    (prediction and masked update) with the new state's outputs and their standard
    deviations (:meth:`NodeEvaluator.ekf_step_outputs`: the products
    :func:`run_mhe_kernel`'s call hands back too), timed alone; the inputs, the sensor
    mask and ``Q(dt)`` are computed outside the timed part. The first sample (prior,
    then its update) is the EKF's own and not timed. Returns ``(output (n, ny), seconds
    per sample (n,))``; the outputs are the EKF's."""
    from continuum_mhe.estimators.fast import NodeEvaluator, build_window_model
    from continuum_mhe.estimators.kalman import ProcessNoiseCache, ekf_update

    f = formulation
    node = NodeEvaluator(build_window_model(f, 2))
    noise = ProcessNoiseCache(f)
    R = f.meas_cov()
    n = len(rec.t)
    out = np.full((n, f.ny), np.nan)
    sec = np.zeros(n)
    mask = f.measurement_mask(rec.z[0])
    x, P = ekf_update(f, f.initial_state(rec.z[0]), f.initial_cov(), rec.z[0], R, mask)
    out[0] = node.output(x)
    z_prev = rec.z[0]
    for i in range(1, n):
        z = rec.z[i]
        dt = float(rec.t[i] - rec.t[i - 1])
        u = f.inputs(z_prev, z, dt)
        mask = f.measurement_mask(z)
        Q = noise(dt)[0]
        t0 = time.perf_counter()
        x, P, y, _ = node.ekf_step_outputs(x, P, u, dt, z, mask, R, Q)
        sec[i] = time.perf_counter() - t0
        out[i] = y
        if mask.any():
            z_prev = z
    return out, sec


def run_mhe_kernel(
    formulation: Formulation, rec: Recording, horizon: int
) -> tuple[FloatArray, FloatArray, int]:
    """The fast MHE (quadratic loss, default :class:`FastOptions`) as its bare compiled
    kernel: per sample the compiled call of
    :mod:`continuum_mhe.estimators.fast.step` that slides the arrival prior, shifts
    the window, forms the initial guess, solves the window and, once certified, keeps
    the answer for the next warm start and computes the covariance, the outputs and
    their standard deviations (:func:`~continuum_mhe.estimators.fast.step.advance_finish`),
    timed alone; the sensor mask,
    ``u`` and ``Q(dt)`` are computed outside the timed part, as for
    :func:`run_ekf_kernel`. Every sample is timed (the first too). A window the SQP
    does not certify is counted (the estimator would hand it to IPOPT); its output is
    the kernel's. Returns ``(output (n, ny), seconds per sample (n,), uncertified
    windows)``; the outputs are the fast MHE's."""
    from continuum_mhe.estimators.fast import FastOptions, NodeEvaluator, build_window_model
    from continuum_mhe.estimators.fast.qp import CONVERGED
    from continuum_mhe.estimators.fast.sqp import quadratic_rate
    from continuum_mhe.estimators.fast.step import StepBuffers
    from continuum_mhe.estimators.kalman import ProcessNoiseCache

    f = formulation
    model = build_window_model(f, horizon)
    steps = StepBuffers(model, NodeEvaluator(model))
    noise = ProcessNoiseCache(f)
    R = f.meas_cov()
    o = FastOptions()
    options = (True, o.max_iter, o.step_tol, o.err_tol, o.max_qp_iter, o.newton,
               quadratic_rate(model, o))  # fmt: skip
    n = len(rec.t)
    out = np.full((n, f.ny), np.nan)
    sec = np.zeros(n)
    first = next(i for i in range(n) if f.measurement_mask(rec.z[i]).any())
    xbar = np.array(f.project(f.initial_state(rec.z[first])), dtype=np.float64)
    P = np.array(f.initial_cov(), dtype=np.float64)
    prior = (xbar, P, np.asarray(np.linalg.inv(P), dtype=np.float64))
    X = np.empty((horizon, f.nx))
    lam = np.zeros_like(steps.lam)
    uncertified = 0
    z_prev: FloatArray | None = None
    for i in range(first, n):
        z = rec.z[i]
        mask = f.measurement_mask(z)
        k = int(steps.k[0])
        dt = float(rec.t[i] - rec.t[i - 1]) if k else 1.0
        u = f.inputs(z_prev, z, dt) if k and f.nu else steps.u0
        Q, Qinv = noise(dt) if k else (steps.zeros, steps.zeros)
        new = (float(rec.t[i]), z, mask, u, dt, Q, Qinv)
        t0 = time.perf_counter()
        (outcome, _, _, _, cur), done = steps.advance_finish(
            prior, new, R, X if k else None, lam, options, X
        )
        if done is None:  # not certified: the kernel's own last iterate
            X[:] = steps.workspace.Xb[cur]
            done = steps.finish(X, xbar)
        sec[i] = time.perf_counter() - t0
        out[i] = done[0]
        uncertified += outcome != CONVERGED
        if mask.any():
            z_prev = z
    return out, sec, uncertified
