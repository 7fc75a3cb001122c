"""The bare MHE kernel against the bare EKF kernel, timed alone in one process.

Runs :func:`~continuum_mhe.benchmark.kernels.run_mhe_kernel` and
:func:`~continuum_mhe.benchmark.kernels.run_ekf_kernel` (the compiled calls of one step,
inputs prepared outside the timed part) on a 20 s ``paper3d`` recording, three rounds
after a warm-up, and prints each round's medians (us per sample) and their ratio:

    python tools/kernel_timing.py        # N = 30
    python tools/kernel_timing.py 100
"""

from __future__ import annotations

import argparse

import numpy as np

from continuum_mhe.benchmark.kernels import run_ekf_kernel, run_mhe_kernel
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("horizon", nargs="?", type=int, default=30, help="the window N (default 30)")
    a = p.parse_args()
    horizon = a.horizon
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=20, noise_deg=2.0, seed=0)
    run_mhe_kernel(f, rec, horizon)  # compiles, fills caches
    run_ekf_kernel(f, rec)
    for _ in range(3):
        _, ekf = run_ekf_kernel(f, rec)
        _, mhe, uncertified = run_mhe_kernel(f, rec, horizon)
        e, m = np.median(ekf[1:]) * 1e6, np.median(mhe[horizon:]) * 1e6
        print(f"N = {horizon}: EKF kernel {e:.1f} us, MHE kernel {m:.1f} us, "
              f"ratio {m / e:.2f}, uncertified windows {uncertified}")  # fmt: skip


if __name__ == "__main__":
    main()
