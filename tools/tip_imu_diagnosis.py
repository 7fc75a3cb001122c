"""The tip IMU alone (raw) on a tendon recording: the single loaded EKF stepped directly
(no free-of-load hypothesis, no sensor-health policy), with the plain or an iterated
measurement update; where its tip error comes from. Prints, per second: the mean tip
error (mm); the rms of its azimuthal (about the base's vertical axis), radial and
vertical parts (mm); the tip's mean output standard deviation (mm, root of the 3x3
trace); the tip NEES (3 when the covariance is honest); the mean tip-force error and its
standard deviation (N, norms) and the error's components (N); the tip IMU's gyro-bias
error (deg/s, against the bias the generator drew for ``--seed``); the tip's distance
from the base axis (mm). Then one JSON line over the samples after ``--skip``.

``--truth-start``: the start with the true tip force; ``--pin GROUP`` (``mis``, ``ba``,
``bg``, repeatable): that group of the tip IMU's error states held at the truth.

    python tools/tip_imu_diagnosis.py DIR SCENARIO [--seed S] [--iterations K]
        [--line-search] [--set NAME=VALUE] [--truth-start] [--pin GROUP] [--quiet]
"""

from __future__ import annotations

import argparse
import ast
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import tendon_iterated_study as its
from tendon_study import _table, imu_readings
from tendon_truth_residual import true_imu_errors

from continuum_mhe.estimators.fast import NodeEvaluator, node_functions
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--iterations", type=int, default=1)
    p.add_argument("--line-search", action="store_true")
    p.add_argument("--skip", type=float, default=1.0)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--truth-start", action="store_true", help="start at the true force")
    p.add_argument("--quiet", action="store_true")
    p.add_argument(
        "--pin",
        action="append",
        default=[],
        choices=("mis", "ba", "bg"),
        help="hold the tip IMU's group of error states at the truth",
    )
    a = p.parse_args()
    robot = read_robot("tendon-two-section")
    n_all = robot.n_imus
    robot = replace(robot, imus=(robot.imus[-1],))
    base = make_formulation("direct", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    f = replace(f, **{k: ast.literal_eval(v) for k, v in (kv.split("=", 1) for kv in a.set)})
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", robot.n_tendons)
    t, z_imu = imu_readings(a.folder, a.scenario, "direct", [n_all - 1])
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    errors = true_imu_errors(a.seed, len(t), n_all)
    sn = list(f.state_names)
    bg = [sn.index(f"bg{c}_1") for c in "xyz"] if "bgx_1" in sn else []
    node = NodeEvaluator(node_functions(f))
    q = ProcessNoiseCache(f)
    R = f.meas_cov()
    tip, force, true_tip, true_force = its.tip_and_force_columns(f, names, truth)
    x = P = None
    z_prev, t_prev = np.zeros(f.nz), 0.0
    rows = []
    for i, ti in enumerate(t):
        z = f.measurement_row(z_imu[i], *tensions.at(ti))
        mask = f.measurement_mask(z)
        if x is None:
            x0, P0 = f.start_prior(z)
            if a.truth_start:
                x0 = x0.copy()
                x0[3:6] = true_force[0]
            for g in a.pin:
                x0 = x0.copy()
                j = [sn.index(f"{g}{c}_1") for c in "xyz"]
                x0[j] = errors[g][3 * (n_all - 1) :]
                P0 = P0.copy()
                P0[j, :], P0[:, j] = 0.0, 0.0
                P0[np.ix_(j, j)] = np.eye(3) * 1e-14
            x, P = its.update(node, f, x0, P0, z, mask, R, a.iterations, a.line_search)
        else:
            xp, F, _, _ = node.evaluate(x, f.inputs(z_prev, z, ti - t_prev), ti - t_prev)
            Pp = F @ P @ F.T + q(ti - t_prev)[0]
            x, P = its.update(node, f, xp, Pp, z, mask, R, a.iterations, a.line_search)
        z_prev, t_prev = z, ti
        y = node.output(x)
        J = np.asarray(f.output_jacobian(x), dtype=float).reshape(f.ny, f.nx)
        C = J @ P @ J.T
        e = y[tip] - true_tip[i]
        tt = true_tip[i]
        rho = math.hypot(tt[0], tt[1])
        radial = np.array([tt[0], tt[1], 0.0]) / max(rho, 1e-9)
        azim = np.array([-radial[1], radial[0], 0.0])
        ef = y[force] - true_force[i]
        rows.append([
            ti, np.linalg.norm(e), e @ azim, e @ radial, e[2],
            math.sqrt(np.trace(C[np.ix_(tip, tip)])),
            float(e @ np.linalg.pinv(C[np.ix_(tip, tip)]) @ e),
            np.linalg.norm(ef), math.sqrt(np.trace(C[np.ix_(force, force)])),
            *ef,
            np.degrees(np.linalg.norm(x[bg] - errors["bg"][3 * (n_all - 1):])) if bg else 0.0,
            rho,
        ])  # fmt: skip
    r = np.array(rows)
    keep = r[:, 0] >= a.skip
    if not a.quiet:
        print("  t   tip  azim radial  vert  std  nees |dF|  Fstd   dFx    dFy    dFz  dbg rho")
        for s in range(int(t[-1]) + 1):
            w = (r[:, 0] >= s) & (r[:, 0] < s + 1)
            m = r[w].mean(axis=0)
            ma = np.sqrt(np.mean(r[w] ** 2, axis=0))
            print(
                f"{s:3d} {m[1] * 1e3:5.1f} {ma[2] * 1e3:5.1f} {ma[3] * 1e3:5.1f} "
                f"{ma[4] * 1e3:5.1f} {m[5] * 1e3:5.1f} {m[6]:5.1f} {m[7]:.3f} {m[8]:.3f} "
                f"{m[9]:+.3f} {m[10]:+.3f} {m[11]:+.3f} {m[12]:.2f} {m[13] * 1e3:4.0f}"
            )
    print(json.dumps({
        "scenario": a.scenario, "seed": a.seed, "iterations": a.iterations, "set": a.set,
        "tip_mean_mm": round(float(r[keep, 1].mean() * 1e3), 2),
        "azim_rms_mm": round(float(np.sqrt(np.mean(r[keep, 2] ** 2)) * 1e3), 2),
        "radial_rms_mm": round(float(np.sqrt(np.mean(r[keep, 3] ** 2)) * 1e3), 2),
        "vert_rms_mm": round(float(np.sqrt(np.mean(r[keep, 4] ** 2)) * 1e3), 2),
        "tip_std_mean_mm": round(float(r[keep, 5].mean() * 1e3), 2),
        "tip_nees": round(float(r[keep, 6].mean()), 1),
        "force_rms_n": round(float(np.sqrt(np.mean(r[keep, 7] ** 2))), 4),
        "force_std_rms_n": round(float(np.sqrt(np.mean(r[keep, 8] ** 2))), 4),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
