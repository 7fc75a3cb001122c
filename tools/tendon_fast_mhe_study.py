"""A study of the fast MHE on the tendon robot, which the library refuses
(docs/tendon-studies.md, "The fast MHE's window"): this script lifts the refusal for its own
run and replaces the IPOPT fallback of an uncertified window by the fast solver with
more iterations (``--fallback-iter``, a QP step below 1e-7), keeping its last iterate
when that does not certify either (status ``not-converged``). The compiled EKF runs
the same samples in the same run. Prints one JSON line per estimator: mean tip and
mid-robot error after the first second (mm), tip-force rms error (N), the median
solve time per sample of the samples after the first ``--horizon`` (ms), the SQP
iterations there (median and largest), the statuses.

    ulimit -v 6000000; python tools/tendon_fast_mhe_study.py [--scenario unloaded]
        [--horizon 5] [--samples N]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import FastOptions, solve_window
from continuum_mhe.estimators.mhe import (
    MovingHorizonEstimator,
    MovingHorizonInference,
    WindowProblem,
)
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.results import Status
from continuum_mhe.settings import MHESettings

DATA = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "tendon"


def _table(path: Path) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenario", default="unloaded")
    p.add_argument("--horizon", type=int, default=5)
    p.add_argument("--samples", type=int, default=None)
    p.add_argument("--fallback-iter", type=int, default=300)
    a = p.parse_args()
    TendonFormulation.fast_mhe_obstacle = None  # this run only
    fallback = FastOptions(max_iter=a.fallback_iter, step_tol=1e-7)

    def fast_fallback(
        self: MovingHorizonInference, problem: WindowProblem, X0: np.ndarray
    ) -> tuple[np.ndarray, Status]:
        assert self._fast is not None
        res = solve_window(self._fast, problem, X0, fallback)
        return res.X, Status.OK if res.converged else Status.NOT_CONVERGED

    MovingHorizonInference._solve_ipopt = fast_fallback  # type: ignore[method-assign]
    robot = read_robot("tendon-two-section")
    base = make_formulation("bend", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    tensions = read_tensions(DATA / f"{a.scenario}_tensions.csv", robot.n_tendons)
    _, tilt = _table(DATA / f"{a.scenario}_tilt.csv")
    names, truth = _table(DATA / f"{a.scenario}_truth.csv")
    n = len(tilt) if a.samples is None else a.samples
    t, truth = tilt[:n, 0], truth[:n]
    z = np.array([f.measurement_row(r[1:5], *tensions.at(r[0])) for r in tilt[:n]])
    cols = [o.name for o in f.outputs]
    for method in ("ekf", "mhe"):
        est = make_estimator(method, f, MHESettings(horizon=a.horizon))
        out, seconds, iterations = [], [], []
        statuses: dict[str, int] = {}
        for i in range(n):
            start = time.perf_counter()
            r = est.step(Measurement(float(t[i]), z[i]))
            seconds.append(time.perf_counter() - start)
            if isinstance(est, MovingHorizonEstimator):
                iterations.append(est.inference.sqp_iterations)
            out.append(r.output)
            statuses[str(r.status)] = statuses.get(str(r.status), 0) + 1
        y = np.asarray(out, dtype=float)
        keep = (t >= 1.0) & np.all(np.isfinite(y), axis=1)

        def err(c: tuple[str, ...], y: np.ndarray = y, keep: np.ndarray = keep) -> np.ndarray:
            e = y[keep][:, [cols.index(k) for k in c]]
            tr = truth[keep][:, [names.index(k) for k in c]]
            return np.asarray(np.linalg.norm(e - tr, axis=1), dtype=float)

        late = slice(a.horizon, None)
        print(json.dumps({
            "scenario": a.scenario, "method": method,
            "horizon": a.horizon if method == "mhe" else None, "samples": n,
            "tip_mean_mm": round(float(err(("x", "y", "z")).mean() * 1e3), 2),
            "mid_mean_mm": round(float(err(("x_1", "y_1", "z_1")).mean() * 1e3), 2),
            "force_rms_n": round(float(np.sqrt(np.mean(err(("fx", "fy", "fz")) ** 2))), 4),
            "median_ms": round(float(np.median(seconds[late])) * 1e3, 1),
            "iterations_median": float(np.median(iterations[late])) if iterations else None,
            "iterations_max": int(max(iterations[late])) if iterations else None,
            "statuses": statuses,
        }), flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
