"""The tendon EKF's inference stepped directly (without the sensor-health policy) on a
generator recording with raw IMUs, its IMU-error states against the generator's true
ones (docs/tendon-studies.md, "Under load"): prints the states every ``--every`` samples and
one JSON line with the mean tip and mid-robot error (mm) and the tip-force rms error (N)
over the samples after the first second.

Starts: the formulation's own (default); ``--truth-start``: the true state, IMU errors
included, with the initial covariance times ``--start-cov-scale``; ``--force-start``:
the own start with the tip force and base curvature replaced by the true ones;
``--pin GROUP`` (``mis``, ``ba``, ``bg``; repeatable): that group of IMU-error states
held at the truth (its covariance 1e-12).

    python tools/tendon_filter_states.py DIR SCENARIO --seed S [--set NAME=VALUE]
        [--truth-start [--start-cov-scale C]] [--force-start] [--pin GROUP] [--every N]
"""

from __future__ import annotations

import json
import math

import numpy as np
from tendon_truth_residual import read_raw_recording, recording_parser, true_imu_errors

from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference


def main() -> None:
    p = recording_parser()
    p.add_argument("--truth-start", action="store_true")
    p.add_argument("--start-cov-scale", type=float, default=1.0)
    p.add_argument("--force-start", action="store_true")
    p.add_argument("--pin", action="append", default=[], choices=("mis", "ba", "bg"))
    p.add_argument("--every", type=int, default=50)
    a = p.parse_args()
    f, tensions, t, z_imu, names, truth = read_raw_recording(a.folder, a.scenario, a.set)
    robot = f.robot
    cols = [o.name for o in f.outputs]
    sn = list(f.state_names)
    errors = true_imu_errors(a.seed, len(t), robot.n_imus)

    def group(key: str) -> list[int]:
        return [sn.index(f"{key}{c}_{k + 1}") for k in range(robot.n_imus) for c in "xyz"]

    groups = [g for g in ("mis", "ba", "bg") if f"{g}x_1" in sn]
    force = [names.index(c) for c in ("fx", "fy", "fz")]
    inference = CompiledExtendedKalmanInference(f)
    rows = []
    for i, tk in enumerate(t):
        x, P, _ = inference.infer(Measurement(tk, f.measurement_row(z_imu[i], *tensions.at(tk))))
        assert x is not None and P is not None
        if i == 0 and (a.truth_start or a.force_start or a.pin):
            x, P = x.copy(), P.copy()
            if a.truth_start or a.force_start:
                x[3:6] = truth[0, force]
                x[:3], _ = f.statics.solve(x[3:6], tensions.at(tk)[0])
            if a.truth_start:
                x[6 + robot.n_tendons :] = 0.0
                x[6 : 6 + robot.n_tendons] = tensions.at(tk)[0]
                for g in groups:
                    x[group(g)] = errors[g]
                P = f.initial_cov() * a.start_cov_scale
            for g in a.pin:
                j = group(g)
                x[j] = errors[g]
                P[j, :], P[:, j] = 0.0, 0.0
                P[j, j] = 1e-12
            inference._x, inference._P = x.copy(), P.copy()
        y = inference.output(x)
        err = [
            np.linalg.norm(y[[cols.index(c + s) for c in "xyz"]] - truth[i, [names.index(c + s)
                                                                               for c in "xyz"]])
            for s in ("", "_1")
        ]  # fmt: skip
        rows.append([tk, *err, np.linalg.norm(y[[cols.index(n) for n in ("fx", "fy", "fz")]]
                                              - truth[i, force])])  # fmt: skip
        if i % a.every == 0 or i == len(t) - 1:
            shown = {"t": round(float(tk), 2), "tip_mm": round(err[0] * 1e3, 2)}
            for g in groups:
                scale = 1.0 if g == "ba" else math.degrees(1.0)
                shown[f"{g}_error"] = np.round((x[group(g)] - errors[g]) * scale, 3).tolist()
            print(json.dumps(shown))
    r = np.array(rows)
    keep = r[:, 0] >= 1.0
    print(json.dumps({
        "scenario": a.scenario, "seed": a.seed, "set": a.set,
        "tip_mean_mm": round(float(r[keep, 1].mean() * 1e3), 2),
        "mid_mean_mm": round(float(r[keep, 2].mean() * 1e3), 2),
        "force_rms_n": round(float(np.sqrt(np.mean(r[keep, 3] ** 2))), 4),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
