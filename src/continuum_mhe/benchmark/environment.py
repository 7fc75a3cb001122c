"""Where a benchmark's numbers come from (the machine and the numeric packages'
versions) and the fast MHE's memory over a long recording (allocation and RSS slopes)."""

from __future__ import annotations

import gc
import math
import os
import platform
import tracemalloc
from dataclasses import dataclass
from typing import Any

import numpy as np

from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import (
    simulate,
)


@dataclass(frozen=True)
class Memory:
    """Memory of the fast MHE over a long recording.

    Attributes:
        samples: recording length.
        tracemalloc_slope_bytes_per_sample: slope of Python-allocated memory (after
            a garbage collection) over the second half of the run.
        tracemalloc_peak_kib: peak Python-allocated memory during the run, KiB.
        rss_slope_bytes_per_sample: slope of the resident set size over the second
            half (Linux only; nan elsewhere).
    """

    samples: int
    tracemalloc_slope_bytes_per_sample: float
    tracemalloc_peak_kib: float
    rss_slope_bytes_per_sample: float


def rss_bytes() -> float:
    try:
        with open("/proc/self/statm") as fh:
            return float(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError):
        return math.nan


def memory_profile(formulation: Formulation, horizon: int, samples: int) -> Memory:
    """Run the fast MHE over ``samples`` samples; slopes of allocated memory and RSS."""
    rec = simulate("paper3d", duration=(samples - 1) * 0.05, seed=1)
    est = MovingHorizonEstimator(formulation, MHESettings(horizon=horizon))
    warm = min(2 * horizon + 50, samples // 4)
    for t, z in zip(rec.t[:warm], rec.z[:warm]):
        est.step(Measurement(float(t), z))
    tracemalloc.start()
    k, traced, rss = [], [], []
    every = max(samples // 40, 1)
    for i in range(warm, samples):
        est.step(Measurement(float(rec.t[i]), rec.z[i]))
        if (i - warm) % every == 0:
            gc.collect()  # count what is retained, not cycles waiting for the collector
            k.append(i)
            traced.append(tracemalloc.get_traced_memory()[0])
            rss.append(rss_bytes())
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    half = len(k) // 2  # fit the second half: allocator free lists settle in the first
    slope = float(np.polyfit(k[half:], traced[half:], 1)[0])
    rss_ok = np.all(np.isfinite(rss))
    rss_slope = float(np.polyfit(k[half:], rss[half:], 1)[0]) if rss_ok else math.nan
    return Memory(samples, slope, peak / 1024, rss_slope)


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def environment(formulation: Formulation) -> dict[str, Any]:
    """Where the numbers come from: the machine and the versions of the numeric
    packages."""
    from importlib import metadata

    def version(name: str) -> str | None:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return None

    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        usable = os.cpu_count() or 0
    return {
        "machine": {
            "platform": platform.platform(),
            "cpu": cpu_model(),
            "cores": os.cpu_count(),
            "usable_cores": usable,
            "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
            # (the executable sets 1 where it is not set; every contender runs under it)
            "openblas_num_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
        },
        "versions": {
            "python": platform.python_version(),
            **{k: version(k) for k in ("continuum-mhe", "numpy", "casadi", "nanobind", "do-mpc")},
        },
    }


def environment_line(report: dict[str, Any]) -> str:
    """One line of the :func:`environment` record in ``report``, for the printed report."""
    m, v = report["machine"], report["versions"]
    return (
        f"machine: {m['cpu']}, "
        f"{m['cores']} cores ({m['usable_cores']} usable), {m['platform']}, "
        f"OPENBLAS_NUM_THREADS {m.get('openblas_num_threads') or 'unset'}; "
        + ", ".join(f"{k} {val}" for k, val in v.items() if val)
    )
