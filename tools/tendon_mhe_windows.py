"""The fast MHE's window solver on the tendon robot's windows (docs/tendon-studies.md, "The fast
MHE's window"): the MHE on IPOPT runs the first samples of a shipped recording (tilt
IMUs) and keeps every window it solved; the fast solver then solves each from IPOPT's
own start. Prints one JSON line per window: IPOPT's status and cost, the fast solver's
outcome, iterations and cost, the largest state difference, and the cost of each
measurement block at the start (the tip condition's is the last).

Run it under a memory limit (IPOPT's window NLP of this model is large):

    ulimit -v 6000000; python tools/tendon_mhe_windows.py [--scenario unloaded]
        [--horizon 3] [--samples 6]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import continuum_mhe.estimators.fast.model as fm
from continuum_mhe.estimators.fast import FastOptions, Workspace, solve_window, window_cost
from continuum_mhe.estimators.fast.sqp import _weights
from continuum_mhe.estimators.mhe import MovingHorizonEstimator, WindowProblem
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings
from continuum_mhe.settings import MHESettings

DATA = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenario", default="unloaded")
    p.add_argument("--horizon", type=int, default=3)
    p.add_argument("--samples", type=int, default=6)
    p.add_argument("--max-iter", type=int, default=200)
    a = p.parse_args()
    robot = read_robot("tendon-two-section")
    base = make_formulation("bend", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    tensions = read_tensions(DATA / f"{a.scenario}_tensions.csv", robot.n_tendons)
    lines = (DATA / f"{a.scenario}_tilt.csv").read_text().splitlines()
    rows = np.loadtxt([ln for ln in lines if not ln.startswith("#")][1:], delimiter=",")
    rows = rows[: a.samples]
    z = np.array([f.measurement_row(r[1:5], *tensions.at(r[0])) for r in rows])
    windows: list[tuple[WindowProblem, np.ndarray, np.ndarray, str, float]] = []
    est = MovingHorizonEstimator(f, MHESettings(horizon=a.horizon, solver="ipopt", tol=1e-10))
    solve = est.inference._solve

    def keep(problem: WindowProblem, X0: np.ndarray) -> tuple[np.ndarray, str]:
        start = time.perf_counter()
        X, status = solve(problem, X0)
        kept = WindowProblem(**{k: np.copy(v) for k, v in vars(problem).items()})
        windows.append((kept, X0.copy(), X.copy(), str(status), time.perf_counter() - start))
        return X, status

    est.inference._solve = keep  # type: ignore[method-assign, assignment]
    est.run(rows[:, 0], z)
    model = fm.build_window_model(f, a.horizon)
    rinv = model.rinv
    for k, (problem, X0, X_ipopt, status, seconds) in enumerate(windows):
        ws = Workspace(model)
        ws.load(problem, X0)
        ws.core.evaluate(0, *_weights(problem))
        R = np.asarray(ws.out[0][: a.horizon * f.nz]).reshape(a.horizon, f.nz)
        blocks = [
            0.5 * float(sum(r @ rinv[b.slice, b.slice] @ r for r in R[:, b.slice]))
            for b in f.measurement_blocks
        ]
        start = time.perf_counter()
        res = solve_window(model, problem, X0, FastOptions(max_iter=a.max_iter))
        fast_s = time.perf_counter() - start
        print(json.dumps({
            "window": k, "ipopt_status": status, "ipopt_s": round(seconds, 1),
            "ipopt_cost": window_cost(model, problem, X_ipopt), "fast": res.outcome,
            "iterations": res.iterations, "fast_cost": res.cost, "fast_s": round(fast_s, 2),
            "largest_difference": float(np.max(np.abs(res.X - X_ipopt))),
            "start_block_costs": [f"{c:.4g}" for c in blocks],
        }))  # fmt: skip


if __name__ == "__main__":
    main()
