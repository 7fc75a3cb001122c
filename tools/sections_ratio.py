#!/usr/bin/env python3
"""Per-sample time of the fast MHE (N = 30) and the compiled EKF on 1, 2 and 3 sections,
tilt IMUs, the spatial scenario, interleaved rounds; medians of the per-sample step time
(the estimate's solve_ms) from sample N on, and wall time per sample of run()."""

import sys
import time

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate, simulate_robot

N = 30
rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 3
for k in (1, 2, 3):
    robot = Robot(
        tuple(Section(0.3 / k, 3.0) for _ in range(k)), tuple(ImuPlacement(i) for i in range(k))
    )
    f = make_formulation("bend", robot)
    rec = (
        simulate("paper3d", duration=20, seed=0)
        if k == 1
        else simulate_robot("spatial", robot, duration=20, seed=0)
    )
    if k == 1:
        f = make_formulation("bend")
    res = {"mhe": [], "ekf": []}
    wall = {"mhe": [], "ekf": []}
    for _ in range(rounds):
        for m in ("mhe", "ekf"):
            est = make_estimator(m, f, MHESettings(horizon=N))
            t0 = time.perf_counter()
            s = est.run(rec.t, rec.z)
            wall[m].append((time.perf_counter() - t0) / len(rec.t))
            res[m].append(np.asarray(s.solve_ms)[N:])
    med = {m: float(np.median(np.median(np.array(v), axis=0))) * 1e3 for m, v in res.items()}
    w = {m: float(np.median(v)) * 1e6 for m, v in wall.items()}
    print(
        f"{k} section(s): step median MHE {med['mhe']:.0f} us, EKF {med['ekf']:.0f} us, ratio {med['mhe'] / med['ekf']:.2f}; "
        f"run() wall per sample MHE {w['mhe']:.0f} us, EKF {w['ekf']:.0f} us"
    )
