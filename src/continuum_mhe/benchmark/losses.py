"""The cost of each MHE measurement loss, for ``continuum-mhe benchmark``.

On the benchmark's recording, clean and with 2 % of the samples hit by +-30 deg spikes
on roll and pitch (as a sensor reports the offset orientation), the fast MHE and IPOPT run with the
``l2``, ``huber``, ``cauchy`` and ``welsch`` losses (default scales). Per loss: the median time per
sample from sample ``N`` on (the smallest of three interleaved runs), its ratio to the
same backend's ``l2`` time on the same data, the fast backend's mean SQP iterations per
sample (a cost that does not depend on the machine's load), the largest output
difference between the two backends, and the fast backend's fallbacks to IPOPT.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import as_sensor_reads, wrap_angle
from continuum_mhe.results import Status
from continuum_mhe.settings import MHE_LOSSES, MHESettings
from continuum_mhe.signals import between_samples
from continuum_mhe.simulation.scenarios import Recording


def with_spikes(rec: Recording, fraction: float = 0.02, deg: float = 30.0) -> Recording:
    """``rec`` with +-``deg`` spikes on every angle of a share ``fraction`` of the samples
    (fixed seed), as a sensor reports them (:func:`.model.imu.as_sensor_reads`)."""
    rng = np.random.default_rng(1)
    z = np.array(rec.z, dtype=float)
    n = len(z)
    idx = rng.choice(np.arange(1, n), size=max(1, round(fraction * n)), replace=False)
    z[idx] += math.radians(deg) * rng.choice([-1.0, 1.0], size=(len(idx), z.shape[1]))
    return replace(rec, z=as_sensor_reads(z))


def _timed(
    est: MovingHorizonEstimator, rec: Recording
) -> tuple[FloatArray, FloatArray, int, float]:
    """``(output (n, ny), seconds per sample (n,), fallbacks, mean SQP iterations)``
    from a reset."""
    est.reset()
    out = np.full((len(rec.t), est.formulation.ny), np.nan)
    sec = np.empty(len(rec.t))
    fallbacks = 0
    iterations = 0
    for i, (t, z) in between_samples(enumerate(zip(rec.t, rec.z))):  # (see _run_timed)
        t0 = time.perf_counter()
        e = est.step(Measurement(float(t), z))
        sec[i] = time.perf_counter() - t0
        if e.output is not None:
            out[i] = e.output
        fallbacks += e.status == Status.FALLBACK_IPOPT
        iterations += est.inference.sqp_iterations
    return out, sec, fallbacks, iterations / len(rec.t)


def run_loss_benchmark(
    formulation: Formulation, rec: Recording, horizons: list[int], repeats: int = 3
) -> list[dict[str, Any]]:
    """Rows ``{horizon, data, loss, scale, fast_median_us, ipopt_median_us, fast_over_l2,
    fast_iterations, ipopt_over_l2, max_diff_vs_ipopt, fallbacks}`` (see the module
    docstring).

    The losses run interleaved ``repeats`` times and each keeps its smallest median, so
    that a load that comes and goes on a shared machine does not decide the ratios."""
    f = formulation
    wrapped = [i for i, o in enumerate(f.outputs) if o.wrapped]
    rows: list[dict[str, Any]] = []
    for n in horizons:
        for data, r in (("clean", rec), ("spikes", with_spikes(rec))):
            fast = {
                loss: MovingHorizonEstimator(f, MHESettings(n, loss=loss)) for loss in MHE_LOSSES
            }
            ipopt = {
                loss: MovingHorizonEstimator(f, MHESettings(n, loss=loss, solver="ipopt"))
                for loss in MHE_LOSSES
            }
            for est in fast.values():
                _timed(est, r)  # compile and warm up
            med: dict[tuple[str, str], float] = {}
            outs: dict[tuple[str, str], tuple[FloatArray, int, float]] = {}
            for _ in range(repeats):
                for loss in MHE_LOSSES:
                    for backend, est in (("fast", fast[loss]), ("ipopt", ipopt[loss])):
                        out, sec, fb, its = _timed(est, r)
                        m = float(np.median(sec[n:]) * 1e6)
                        med[backend, loss] = min(med.get((backend, loss), math.inf), m)
                        outs[backend, loss] = (out, fb, its)
            for loss in MHE_LOSSES:
                (out_f, fb, its), (out_i, _, _) = outs["fast", loss], outs["ipopt", loss]
                d = np.abs(out_f - out_i)
                d[:, wrapped] = np.abs(wrap_angle(d[:, wrapped]))
                rows.append(
                    {
                        "horizon": n,
                        "data": data,
                        "loss": loss,
                        "scale": fast[loss].inference.settings.scale,
                        "fast_median_us": med["fast", loss],
                        "ipopt_median_us": med["ipopt", loss],
                        "fast_over_l2": med["fast", loss] / med["fast", "l2"],
                        "fast_iterations": its,
                        "ipopt_over_l2": med["ipopt", loss] / med["ipopt", "l2"],
                        "max_diff_vs_ipopt": float(np.nanmax(d)),
                        "fallbacks": fb,
                    }
                )
    return rows
