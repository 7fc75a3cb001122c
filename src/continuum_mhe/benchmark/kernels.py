"""The bare compiled kernels of one EKF step and one fast-MHE step, timed alone.

``continuum-mhe benchmark`` times every estimator through its ``step`` (input checks,
sensor masks, divergence check, the ``Estimate``). These two runners time only the
compiled calls of one step, the inputs (sensor mask, ``u``, ``Q(dt)``) computed
outside the timed part, so that the two methods' arithmetic can be compared without
the interface both share (:mod:`continuum_mhe.benchmark.harness`'s rows ``ekf-kernel`` and
``mhe-kernel``).
"""

from __future__ import annotations

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.results import Status
from continuum_mhe.simulation.scenarios import Recording


def run_ekf_kernel(formulation: Formulation, rec: Recording) -> tuple[FloatArray, FloatArray]:
    """The EKF as the bare compiled kernel: per sample one compiled call of the EKF step
    (prediction and masked update) with the new state's outputs and their standard
    deviations (:meth:`NodeEvaluator.ekf_step_outputs`: the products
    :func:`run_mhe_kernel`'s call hands back too), timed inside the core as the MHE's
    step is (:attr:`NodeEvaluator.step_seconds`: not the call's array conversion); the
    inputs, the sensor mask and ``Q(dt)`` are computed outside the timed part. The
    first sample (prior, then its update) is the EKF's own and not timed. Returns
    ``(output (n, ny), seconds per sample (n,))``; the outputs are the EKF's."""
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
    x, P = ekf_update(f, *f.start_prior(rec.z[0]), rec.z[0], R, mask)
    out[0] = node.output(x)
    z_prev = rec.z[0]
    for i in range(1, n):
        z = rec.z[i]
        dt = float(rec.t[i] - rec.t[i - 1])
        u = f.inputs(z_prev, z, dt)
        mask = f.measurement_mask(z)
        Q = noise(dt)[0]
        x, P, y, _ = node.ekf_step_outputs(x, P, u, dt, z, mask, R, Q)
        sec[i] = node.step_seconds
        out[i] = y
        if mask.any():
            z_prev = z
    return out, sec


def run_mhe_kernel(
    formulation: Formulation, rec: Recording, horizon: int
) -> tuple[FloatArray, FloatArray, int]:
    """The fast MHE (quadratic loss, default :class:`FastOptions`) with only its
    compiled step timed: per sample the core's ``MovingHorizon`` step (the arrival
    prior's slide, the warm start, the SQP on the window, the covariance and the
    outputs with their standard deviations: the work of :func:`run_ekf_kernel`'s call),
    without the estimator's interface and sensor-health policy around it. A window the
    SQP does not certify is counted (the estimator hands it to IPOPT, whose time is not
    counted).
    Returns ``(output (n, ny), seconds per sample (n,), uncertified windows)``; the
    outputs are the fast MHE's."""
    from continuum_mhe.estimators.mhe import MovingHorizonEstimator
    from continuum_mhe.results import Measurement
    from continuum_mhe.settings import MHESettings

    est = MovingHorizonEstimator(formulation, MHESettings(horizon=horizon))
    est.reset()
    n = len(rec.t)
    out = np.full((n, formulation.ny), np.nan)
    sec = np.zeros(n)
    uncertified = 0
    for i in range(n):
        e = est.step(Measurement(float(rec.t[i]), rec.z[i]))
        sec[i] = est.inference.step_seconds
        if e.output is not None:
            out[i] = e.output
        uncertified += e.status == Status.FALLBACK_IPOPT
    return out, sec, uncertified
