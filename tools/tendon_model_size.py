"""The tendon model's size and speed (docs/tendon-studies.md, "The model's size and speed"): CasADi
instructions of the statics and the measurement residual, the compiled node's residual
and Jacobian (forward mode) against CasADi's symbolic Jacobian (values and time), the
compiled EKF's build and step, the start, and the statics against a converged shooting
over the shipped recordings. Prints one JSON line.

    python tools/tendon_model_size.py [--imu tilt|direct] [--samples N] [--symbolic]

``--symbolic`` also builds the symbolic Jacobian (over a million instructions; seconds
and a few hundred MB) to count it and compare with it.
"""

from __future__ import annotations

import argparse
import json
import time
from importlib.resources import files

import casadi as ca
import numpy as np

from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import NodeEvaluator, node_functions
from continuum_mhe.estimators.kalman import ExtendedKalmanFilter
from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.model.tendon_statics import TendonStatics

DATA = files("continuum_mhe") / "data" / "tendon"


def _table(name: str) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in (DATA / name).read_text().splitlines() if not ln.startswith("#")]
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def _median_ms(fn, repeats: int = 30) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3)


def statics_difference(robot, scenarios=("unloaded", "force-08", "force-29")) -> float:  # type: ignore[no-untyped-def]
    """The largest distance, mm, of any station between the model's shooting and a
    converged one (32 steps per section), at every sample's true tensions and force."""
    coarse, fine = TendonStatics(robot), TendonStatics(robot, steps_per_section=32)
    worst = 0.0
    for sc in scenarios:
        names, truth = _table(f"{sc}_truth.csv")
        tensions = read_tensions(DATA / f"{sc}_tensions.csv", robot.n_tendons)
        force = [names.index(n) for n in ("fx", "fy", "fz")]
        k_c = k_f = None
        for row in truth:
            tau = tensions.at(row[0])[0]
            k_c, a = coarse.solve(row[force], tau, k_c)
            k_f, b = fine.solve(row[force], tau, k_f)
            worst = max(worst, max(float(np.linalg.norm(a[s][1] - b[s][1])) for s in a))
    return worst * 1e3


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--imu", choices=("tilt", "direct"), default="tilt")
    p.add_argument("--samples", type=int, default=60, help="EKF samples of unloaded")
    p.add_argument("--symbolic", action="store_true")
    p.add_argument("--no-statics", action="store_true", help="skip the statics comparison")
    a = p.parse_args()
    robot = read_robot("tendon-two-section")
    f = TendonFormulation(robot=robot, imu_model=a.imu, estimate_gyro_bias=a.imu == "direct")
    x_s, z_s = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    res = f.measurement_residual_sym(z_s, x_s)
    report: dict[str, object] = {
        "imu": a.imu,
        "statics_instructions": f.statics.function.n_instructions(),
        "residual_instructions": ca.Function("r", [x_s, z_s], [res]).n_instructions(),
    }
    tensions = read_tensions(DATA / "unloaded_tensions.csv", robot.n_tendons)
    if a.imu == "tilt":
        _, tab = _table("unloaded_tilt.csv")
        t, z_imu = tab[:, 0], tab[:, 1:5]
    else:
        _, tab = _table("unloaded_raw.csv")
        t, s = tab[:, 0], RawImuSettings(imu_model="direct")
        z_imu = np.hstack([raw_to_measurements(t, tab[:, 1 + 6 * k : 4 + 6 * k],
                                               tab[:, 4 + 6 * k : 7 + 6 * k], s)
                           for k in range(robot.n_imus)])  # fmt: skip
    z = np.array([f.measurement_row(zi, *tensions.at(ti)) for ti, zi in zip(t, z_imu)])
    start = time.perf_counter()
    node = NodeEvaluator(node_functions(f))
    report["node_build_s"] = round(time.perf_counter() - start, 2)
    x = f.initial_state(z[150])
    u, mask = np.zeros(f.nu), np.ones(f.nz)
    # three states in turn: the node remembers its last two evaluations and would return them
    states = [x + np.r_[1e-6 * k, np.zeros(f.nx - 1)] for k in range(3)]
    turn = iter(range(10**6))
    report["node_ms"] = round(
        _median_ms(lambda: node.evaluate(states[next(turn) % 3], u, 0.02, z[150], mask)), 3
    )
    if a.symbolic:
        fn = ca.Function("rj", [x_s, z_s], [res, ca.jacobian(res, x_s)])
        report["symbolic_jacobian_instructions"] = fn.n_instructions()
        report["casadi_symbolic_ms"] = round(_median_ms(lambda: fn(x, z[150]), 10), 2)
        _, _, H, _ = node.evaluate(x, u, 0.02, z[150], mask)
        J = np.asarray(fn(x, z[150])[1], dtype=float)
        report["jacobian_difference_relative"] = float(
            np.abs(np.asarray(H).reshape(J.shape) + J).max() / np.abs(J).max()
        )
    report["start_ms"] = [round(_median_ms(lambda k=k: f.initial_state(z[k]), 3))
                          for k in (0, 50, 150, 300)]  # fmt: skip
    start = time.perf_counter()
    ekf = ExtendedKalmanFilter(f)
    report["ekf_build_s"] = round(time.perf_counter() - start, 2)
    steps = []
    for k in range(a.samples):
        start = time.perf_counter()
        ekf.step(Measurement(float(t[k]), z[k]))
        steps.append(time.perf_counter() - start)
    report["ekf_step_ms_median"] = round(float(np.median(steps[1:]) * 1e3), 2)  # after the start
    if not a.no_statics:
        report["statics_vs_converged_mm"] = round(statics_difference(robot), 4)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
