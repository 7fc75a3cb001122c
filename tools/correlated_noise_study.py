"""Readings whose noise is correlated in time (an IMU's internal low-pass filter at a
high output rate): the shares of rows ``inconsistent`` and the mean tip error of the EKF
and the MHE with the defaults, on ``paper3d`` (20 s, noise-free, seed 1) with 2 degrees
of first-order autoregressive noise added to each reading (``e_k = a e_(k-1) + sqrt(1 -
a^2) w_k``: the same standard deviation, correlated by ``a`` from sample to sample)::

    python tools/correlated_noise_study.py                 # 200 and 100 Hz, a = 0 .. 0.9
    python tools/correlated_noise_study.py --hz 200 --a 0.5
"""

from __future__ import annotations

import argparse
import collections

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.simulation.scenarios import simulate


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--hz", type=float, nargs="+", default=[200.0, 100.0])
    p.add_argument("--a", type=float, nargs="+", default=[0.0, 0.5, 0.8, 0.9])
    args = p.parse_args()
    f = make_formulation("bend")
    for hz in args.hz:
        clean = simulate("paper3d", duration=20, dt=1.0 / hz, noise_deg=0.0, seed=1)
        rng = np.random.default_rng(3)
        for a in args.a:
            w = rng.normal(0.0, np.radians(2.0), clean.z.shape)
            e = np.zeros_like(w)
            for k in range(len(w)):
                e[k] = (a * e[k - 1] if k else 0.0) + np.sqrt(1.0 - a * a) * w[k]
            row = []
            for method in ("ekf", "mhe"):
                s = make_estimator(method, f, MHESettings()).run(clean.t, clean.z + e)
                share = collections.Counter(s.status).get("inconsistent", 0) / len(e)
                tip = np.linalg.norm(s.output[:, :3] - clean.truth[:, :3], axis=1) * 1e3
                row.append(f"{method}: inconsistent {share:.2f}, tip {tip.mean():.2f} mm")
            print(f"{hz:g} Hz, a = {a:g}: " + "; ".join(row), flush=True)


if __name__ == "__main__":
    main()
