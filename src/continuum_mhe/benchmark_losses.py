"""The cost of each MHE measurement loss, for ``continuum-mhe benchmark``.

On the benchmark's recording, clean and with 2 % of the samples hit by +-30 deg spikes
on roll and pitch (pitch clipped to +-90 deg), the fast MHE and IPOPT run with the
``l2``, ``huber`` and ``cauchy`` losses (default scales). Per loss: the median time per
sample from sample ``N`` on, its ratio to the same backend's ``l2`` time on the same
data, the largest output difference between the two backends, and the fast backend's
fallbacks to IPOPT.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any

import numpy as np

from continuum_mhe.estimators.base import Estimator, FloatArray, Measurement
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import wrap_angle
from continuum_mhe.settings import MHE_LOSSES, MHESettings
from continuum_mhe.simulation.scenarios import Recording


def with_spikes(rec: Recording, fraction: float = 0.02, deg: float = 30.0) -> Recording:
    """``rec`` with +-``deg`` spikes on every angle of a share ``fraction`` of the samples
    (fixed seed; roll wrapped, pitch clipped to +-90 deg)."""
    rng = np.random.default_rng(1)
    z = np.array(rec.z, dtype=float)
    n = len(z)
    idx = rng.choice(np.arange(1, n), size=max(1, round(fraction * n)), replace=False)
    z[idx] += math.radians(deg) * rng.choice([-1.0, 1.0], size=(len(idx), z.shape[1]))
    z[:, 0::2] = wrap_angle(z[:, 0::2])
    z[:, 1::2] = np.clip(z[:, 1::2], -math.pi / 2, math.pi / 2)
    return replace(rec, z=z)


def _timed(est: Estimator, rec: Recording) -> tuple[FloatArray, FloatArray, int]:
    """``(output (n, ny), seconds per sample (n,), fallbacks)`` from a reset."""
    est.reset()
    out = np.full((len(rec.t), est.formulation.ny), np.nan)
    sec = np.empty(len(rec.t))
    fallbacks = 0
    for i, (t, z) in enumerate(zip(rec.t, rec.z)):
        t0 = time.perf_counter()
        e = est.step(Measurement(float(t), z))
        sec[i] = time.perf_counter() - t0
        if e.output is not None:
            out[i] = e.output
        fallbacks += e.status == "fallback-ipopt"
    return out, sec, fallbacks


def run_loss_benchmark(
    formulation: Formulation, rec: Recording, horizons: list[int]
) -> list[dict[str, Any]]:
    """Rows ``{horizon, data, loss, fast_median_us, ipopt_median_us, fast_over_l2,
    ipopt_over_l2, max_diff_vs_ipopt, fallbacks}`` (see the module docstring)."""
    f = formulation
    wrapped = [i for i, o in enumerate(f.outputs) if o.wrapped]
    rows: list[dict[str, Any]] = []
    for n in horizons:
        for data, r in (("clean", rec), ("spikes", with_spikes(rec))):
            base: dict[str, float] = {}
            for loss in MHE_LOSSES:
                fast = MovingHorizonEstimator(f, MHESettings(horizon=n, loss=loss))
                _timed(fast, r)  # compile and warm up
                out_f, sec_f, fb = _timed(fast, r)
                ipopt = MovingHorizonEstimator(f, MHESettings(n, loss=loss, solver="ipopt"))
                out_i, sec_i, _ = _timed(ipopt, r)
                d = np.abs(out_f - out_i)
                d[:, wrapped] = np.abs(wrap_angle(d[:, wrapped]))
                med_f = float(np.median(sec_f[n:]) * 1e6)
                med_i = float(np.median(sec_i[n:]) * 1e6)
                if loss == "l2":
                    base = {"fast": med_f, "ipopt": med_i}
                rows.append(
                    {
                        "horizon": n,
                        "data": data,
                        "loss": loss,
                        "scale": fast.settings.scale,
                        "fast_median_us": med_f,
                        "ipopt_median_us": med_i,
                        "fast_over_l2": med_f / base["fast"],
                        "ipopt_over_l2": med_i / base["ipopt"],
                        "max_diff_vs_ipopt": float(np.nanmax(d)),
                        "fallbacks": fb,
                    }
                )
    return rows


def print_loss_report(rows: list[dict[str, Any]]) -> None:
    """Rich table of :func:`run_loss_benchmark`'s rows."""
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title="Cost of each MHE loss (median us per sample from sample N on; / l2: over "
        "the same backend's l2 time on the same data; max|d|: fast vs IPOPT, m and rad)"
    )
    for col in ("N", "data", "loss", "fast us", "fast / l2", "IPOPT us", "IPOPT / l2",
                "max|d|", "fallbk"):  # fmt: skip
        table.add_column(col, justify="right", no_wrap=True)
    for r in rows:
        table.add_row(
            str(r["horizon"]),
            r["data"],
            r["loss"] if r["loss"] == "l2" else f"{r['loss']} {r['scale']:g}",
            f"{r['fast_median_us']:.0f}",
            f"{r['fast_over_l2']:.2f}",
            f"{r['ipopt_median_us']:.0f}",
            f"{r['ipopt_over_l2']:.2f}",
            f"{r['max_diff_vs_ipopt']:.1e}",
            str(r["fallbacks"]),
        )
    console = Console()
    console.width = max(console.width, 110)
    console.print(table)
