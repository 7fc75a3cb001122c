"""The tendon EKF stepped directly (no sensor-health policy, no widening of the
standard deviations), with the plain or an iterated (Gauss-Newton) measurement update,
at the measurement noise given: how the EKF's tip error and the consistency of its
covariance depend on the assumed noise and on the update's linearisation
(docs/tendon-studies.md, "The standard deviations"). Prints one JSON line: the mean tip
error after ``--skip`` (mm), the tip NEES (mean of ``e^T P^-1 e`` over the tip's 3x3
output covariance; 3 when calibrated), each tip axis's 95% coverage, the tip force's
rms error and rms standard deviation (N), and the largest tip error (mm).

    python tools/tendon_iterated_study.py DIR SCENARIO [--imu tilt|direct]
        [--noise-deg D] [--gyro-std W] [--iterations K] [--set NAME=VALUE]
"""

from __future__ import annotations

import argparse
import ast
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
from tendon_study import _table

from continuum_mhe.estimators.fast import NodeEvaluator, node_functions
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings


def update(node, f, x_pred, P, z, mask, R, iterations, line_search=False):
    """The EKF's update (``iterations`` = 1) or the iterated EKF's: Gauss-Newton on the
    prior and the readings, relinearised at each iterate, ``iterations`` full steps or,
    with ``line_search``, each step halved until the cost falls, until a step under
    1e-9 of the state's scale); Joseph form at the last linearisation."""
    rows = np.flatnonzero(mask)
    zf = np.where(np.isfinite(z), z, 0.0)
    Rv = R[np.ix_(rows, rows)]
    Pinv = np.linalg.inv(P)
    Rinv = np.linalg.inv(Rv)

    def cost(x):
        r = node.evaluate(x, np.zeros(f.nu), 0.0, zf)[3][rows]
        d = x - x_pred
        return float(d @ Pinv @ d + r @ Rinv @ r)

    x = x_pred.copy()
    x_lin = x_pred
    c = cost(x) if line_search else 0.0
    for _ in range(iterations):
        _, _, H, r = node.evaluate(x, np.zeros(f.nu), 0.0, zf)
        H, r = H[rows], r[rows] + H[rows] @ (x - x_pred)
        S = H @ P @ H.T + Rv
        K = np.linalg.solve(S, H @ P).T
        target = x_pred + K @ r
        if not line_search:
            x_lin, x = x, target
            continue
        step, alpha = target - x, 1.0
        while alpha > 1e-3:
            trial = x + alpha * step
            ct = cost(trial)
            if ct <= c:
                break
            alpha /= 2
        else:
            break
        x_lin, x, c = x, trial, ct
        if np.linalg.norm(alpha * step) < 1e-9 * (1 + np.linalg.norm(x)):
            break
    _, _, H, _ = node.evaluate(x_lin, np.zeros(f.nu), 0.0, zf)
    H = H[rows]
    S = H @ P @ H.T + Rv
    K = np.linalg.solve(S, H @ P).T
    ikh = np.eye(len(x)) - K @ H
    global LAST
    LAST = (ikh, K, rows)
    return x, ikh @ P @ ikh.T + K @ Rv @ K.T


LAST = None


def tip_and_force_columns(
    f, names: list[str], truth: np.ndarray
) -> tuple[list[int], list[int], np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """The tip's and the tip force's columns in ``f``'s outputs, and the truth's tip (m)
    and tip force (N) rows (``names`` its columns)."""
    cols = [o.name for o in f.outputs]
    tip = [cols.index(c) for c in "xyz"]
    force = [cols.index(c) for c in ("fx", "fy", "fz")]
    true_tip = truth[:, [names.index(c) for c in "xyz"]]
    true_force = truth[:, [names.index(c) for c in ("fx", "fy", "fz")]]
    return tip, force, true_tip, true_force


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--imu", choices=("tilt", "direct"), default="direct")
    p.add_argument("--noise-deg", type=float, default=2.0)
    p.add_argument("--gyro-std", type=float, default=None, help="default: the model's own")
    p.add_argument("--iterations", type=int, default=1)
    p.add_argument("--line-search", action="store_true", help="iterated: halve steps")
    p.add_argument("--skip", type=float, default=1.0)
    p.add_argument(
        "--actual-noise-deg",
        type=float,
        default=None,
        help="also carry the covariance of the errors of this filter's gains "
        "under this accelerometer-direction noise (and --actual-gyro-std)",
    )
    p.add_argument("--actual-gyro-std", type=float, default=None)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    a = p.parse_args()
    robot = read_robot("tendon-two-section")
    base = make_formulation(
        a.imu if a.imu == "direct" else "bend", robot,
        NoiseSettings(measurement_std=math.radians(a.noise_deg)),
    )  # fmt: skip
    f = tendon_formulation_for(base, InputOptions(gyro_std=a.gyro_std))
    f = replace(f, **{k: ast.literal_eval(v) for k, v in (kv.split("=", 1) for kv in a.set)})
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", robot.n_tendons)
    if a.imu == "tilt":
        _, tilt = _table(a.folder / f"{a.scenario}_tilt.csv")
        t, z_imu = tilt[:, 0], tilt[:, 1:5]
    else:
        _, raw = _table(a.folder / f"{a.scenario}_raw.csv")
        t = raw[:, 0]
        z_imu = np.hstack(
            [raw_to_measurements(t, raw[:, 1 + 6 * k : 4 + 6 * k], raw[:, 4 + 6 * k : 7 + 6 * k],
                                 RawImuSettings(imu_model="direct")) for k in range(2)]
        )  # fmt: skip
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    node = NodeEvaluator(node_functions(f))
    q = ProcessNoiseCache(f)
    R = f.meas_cov()
    tip, force, true_tip, true_force = tip_and_force_columns(f, names, truth)
    x = P = Pc = None
    z_prev, t_prev = np.zeros(f.nz), 0.0
    Ra = R.copy()
    if a.actual_noise_deg is not None:
        fa = replace(
            f,
            accel_direction_std=math.radians(a.actual_noise_deg),
            gyro_std=a.actual_gyro_std or f.gyro_noise_std,
        )
        if a.imu == "tilt":
            fa = replace(f, noise=NoiseSettings(measurement_std=math.radians(a.actual_noise_deg)))
        Ra = fa.meas_cov()
    errs, nees, inside, ferr, fstd = [], [], [], [], []
    for i, ti in enumerate(t):
        z = f.measurement_row(z_imu[i], *tensions.at(ti))
        mask = f.measurement_mask(z)
        if x is None:
            x0, P0 = f.start_prior(z)  # the estimators' start
            x, P = update(
                node,
                f,
                x0,
                P0,
                z,
                mask,
                R,
                a.iterations,
                a.line_search,
            )
            ikh, K, rows = LAST
            Pc = ikh @ P0 @ ikh.T + K @ Ra[np.ix_(rows, rows)] @ K.T
        else:
            xp, F, _, _ = node.evaluate(x, f.inputs(z_prev, z, ti - t_prev), ti - t_prev)
            Pp = F @ P @ F.T + q(ti - t_prev)[0]
            x, P = update(node, f, xp, Pp, z, mask, R, a.iterations, a.line_search)
            ikh, K, rows = LAST
            Pc = F @ Pc @ F.T + q(ti - t_prev)[0]
            Pc = ikh @ Pc @ ikh.T + K @ Ra[np.ix_(rows, rows)] @ K.T
        z_prev, t_prev = z, ti
        if ti < a.skip:
            continue
        y = node.output(x)
        J = np.asarray(f.output_jacobian(x), dtype=float).reshape(f.ny, f.nx)
        C = J @ (P if a.actual_noise_deg is None else Pc) @ J.T
        e = y[tip] - true_tip[i]
        errs.append(np.linalg.norm(e))
        nees.append(float(e @ np.linalg.solve(C[np.ix_(tip, tip)], e)))
        inside.append(np.abs(e) <= 1.96 * np.sqrt(np.diag(C)[tip]))
        ferr.append(y[force] - true_force[i])
        fstd.append(np.sqrt(np.diag(C)[force]))
    print(json.dumps({
        "scenario": a.scenario, "imu": a.imu, "noise_deg": a.noise_deg,
        "gyro_std": f.gyro_noise_std, "iterations": a.iterations, "set": a.set,
        "tip_mean_mm": round(float(np.mean(errs)) * 1e3, 2),
        "tip_max_mm": round(float(np.max(errs)) * 1e3, 2),
        "tip_nees": round(float(np.mean(nees)), 2),
        "coverage_xyz": np.round(np.mean(inside, axis=0), 3).tolist(),
        "force_rms_n": np.round(np.sqrt(np.mean(np.square(ferr), axis=0)), 4).tolist(),
        "force_std_n": np.round(np.sqrt(np.mean(np.square(fstd), axis=0)), 4).tolist(),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
