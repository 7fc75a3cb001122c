"""Per-sample time of the fast MHE (N = 30) and the compiled EKF on 1, 2 and 3 sections.

Tilt IMUs at each section's end, ``paper3d`` for one section and ``spatial`` for more
(20 s), interleaved rounds in one process; prints the medians of the per-sample step
time (the estimates' ``solve_ms``) from sample N on, their ratio, and the wall time per
sample of ``run()``::

    python tools/sections_ratio.py      # 3 rounds
    python tools/sections_ratio.py 2
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.results import Measurement
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import Recording, simulate, simulate_robot

N = 30


def sections_case(k: int, duration: float = 20.0) -> tuple[Formulation, Recording]:
    """The ``bend`` formulation of ``k`` sections and its recording (seed 0, 2 degrees of
    noise): one section, the paper's robot on ``paper3d``; more, sections of ``0.3 / k``
    m (``theta_max`` 3 rad) with a tilt IMU at each end, on ``spatial``."""
    if k == 1:
        return make_formulation("bend"), simulate("paper3d", duration=duration, seed=0)
    robot = Robot(
        tuple(Section(0.3 / k, 3.0) for _ in range(k)), tuple(ImuPlacement(i) for i in range(k))
    )
    return make_formulation("bend", robot), simulate_robot(
        "spatial", robot, duration=duration, seed=0
    )


def full_windows(
    f: Formulation, rec: Recording, settings: MHESettings
) -> tuple[Any, Any, Iterator[tuple[Any, np.ndarray, np.ndarray]]]:
    """``(model, options, windows)`` of the fast MHE (``settings``) run over ``rec``: its
    compiled window model and solver options, and each full window the compiled step
    solved, as ``(problem, X0, lam0)`` (the window's problem and the step's start), made
    as the run goes."""
    est = MovingHorizonEstimator(f, settings)
    inference = est.inference
    model, window = inference._fast, inference._window
    assert model is not None and isinstance(window, _core.MovingHorizon)

    def windows() -> Iterator[tuple[Any, np.ndarray, np.ndarray]]:
        est.reset()
        for i, (t, z) in enumerate(zip(rec.t, rec.z)):
            est.step(Measurement(float(t), z))
            if i >= settings.horizon and window.solved:
                X0, lam0 = np.array(window.X0), np.array(window.lam0)
                yield inference.window_problem(), X0, lam0

    return model, inference.fast_options, windows()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("rounds", nargs="?", type=int, default=3, help="rounds, interleaved (default 3)")
    a = p.parse_args()
    rounds = a.rounds
    for k in (1, 2, 3):
        f, rec = sections_case(k)
        steps: dict[str, list[np.ndarray]] = {"mhe": [], "ekf": []}
        wall: dict[str, list[float]] = {"mhe": [], "ekf": []}
        for _ in range(rounds):
            for method in ("mhe", "ekf"):
                est = make_estimator(method, f, MHESettings(horizon=N))
                t0 = time.perf_counter()
                series = est.run(rec.t, rec.z)
                wall[method].append((time.perf_counter() - t0) / len(rec.t))
                steps[method].append(np.asarray(series.solve_ms)[N:])
        med = {m: float(np.median(np.median(np.array(v), axis=0))) * 1e3 for m, v in steps.items()}
        per = {m: float(np.median(v)) * 1e6 for m, v in wall.items()}
        print(
            f"{k} section(s): step median MHE {med['mhe']:.0f} us, EKF {med['ekf']:.0f} us, "
            f"ratio {med['mhe'] / med['ekf']:.2f}; run() wall per sample MHE "
            f"{per['mhe']:.0f} us, EKF {per['ekf']:.0f} us"
        )


if __name__ == "__main__":
    main()
