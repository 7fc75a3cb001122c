"""How many SQP iterations the fast MHE's windows take, and their solve times.

The fast MHE (N = 30, defaults) over ``continuum-mhe simulate paper3d --duration D``
(2 deg noise, seed 0), or with ``--sections K`` (2 or 3) ``spatial`` on a K-section
robot of 0.3 m with a tilt IMU at each section's end (as ``tools/sections_ratio.py``),
one sample at a time; from the first full window on, prints the count of windows by
SQP iterations, the median solve time of each count (the compiled step's
``solve_seconds``, us) and its share, and the mean over the median. ``--gauss-newton``:
without the residuals' second-order term (``FastOptions(newton=False)``)::

    python tools/sqp_iterations.py          # 500 s: 10,001 samples
    python tools/sqp_iterations.py 40
    python tools/sqp_iterations.py 20 --sections 3
"""

from __future__ import annotations

import argparse
import collections

import numpy as np
from sections_ratio import sections_case

from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.results import Measurement
from continuum_mhe.settings import MHESettings

N = 30


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "duration", nargs="?", type=float, default=500.0, help="the recording, s (default 500.0)"
    )
    p.add_argument("--sections", type=int, choices=(1, 2, 3), default=1)
    p.add_argument("--gauss-newton", action="store_true", help="FastOptions(newton=False)")
    a = p.parse_args()
    f, rec = sections_case(a.sections, a.duration)
    est = MovingHorizonEstimator(
        f, MHESettings(horizon=N, solver="fast"),
        fast_options=FastOptions(newton=not a.gauss_newton),
    )  # fmt: skip
    est.reset()
    iterations, seconds = [], []
    for t, z in zip(rec.t, rec.z):
        est.step(Measurement(float(t), z))
        iterations.append(est.inference.sqp_iterations)
        seconds.append(est.inference.solve_seconds)
    its, us = np.array(iterations[N:]), np.array(seconds[N:]) * 1e6
    print(f"{len(its)} full windows: {dict(sorted(collections.Counter(its.tolist()).items()))}")
    for k in sorted(set(its.tolist())):
        share = float(np.mean(its == k))
        print(f"  {k} iterations: median {np.median(us[its == k]):.1f} us, {share:.3f} of them")
    print(f"mean / median solve time {us.mean() / np.median(us):.3f}")


if __name__ == "__main__":
    main()
