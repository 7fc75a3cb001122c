"""The tension gain states (:attr:`TendonFormulation.estimate_tension_gain`) on the
generator's recordings, with the recording's tensions or those tensions scaled by a
factor (a sensor's gain, tendon friction, kgf entered as N): the command line's EKF
(compiled) with the gains off and on; prints one JSON line per run: the mean tip error
after ``--skip`` s (mm), the tip force's rms error (N), the statuses, the ``ok`` rows
(all rows) whose tip is over 20 mm off, and the tension gains at the end with their
standard deviations (the acting tension over the given one: tensions given 1.2 times too
large read 1/1.2).

    python tools/tension_gain_study.py DIR SCENARIO [--imu tilt|direct]
        [--scale S ...] [--gain off|on|both] [--set NAME=VALUE]

Results: docs/tendon-studies.md, "Tension gains".
"""

from __future__ import annotations

import argparse
import ast
import json
import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
from tendon_study import _table, imu_readings

from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings
from continuum_mhe.results import Measurement
from continuum_mhe.settings import RecoverySettings


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--imu", choices=("tilt", "direct"), default="direct")
    p.add_argument("--scale", type=float, nargs="+", default=[1.0],
                   help="the given tensions are the recording's times this")  # fmt: skip
    p.add_argument("--gain", choices=("off", "on", "both"), default="both")
    p.add_argument("--skip", type=float, default=1.0)
    p.add_argument("--robot", default="tendon-two-section")
    p.add_argument("--drift-reset", type=float, default=RecoverySettings.drift_reset,
                   help="RecoverySettings.drift_reset, s (0: never)")  # fmt: skip
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a TendonFormulation field (repeatable)")  # fmt: skip
    a = p.parse_args()
    robot = read_robot(a.robot)
    base = make_formulation(
        a.imu if a.imu == "direct" else "bend",
        robot,
        NoiseSettings(measurement_std=math.radians(2.0)),
    )
    changes = {k: ast.literal_eval(v) for k, v in (kv.split("=", 1) for kv in a.set)}
    default = replace(tendon_formulation_for(base, InputOptions()),
                      **changes)  # fmt: skip
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", robot.n_tendons)
    t, z_imu = imu_readings(a.folder, a.scenario, a.imu, range(robot.n_imus))
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    gains = {"off": [False], "on": [True], "both": [False, True]}[a.gain]
    for scale in a.scale:
        for on in gains:
            f = replace(default, estimate_tension_gain=on)
            z = np.array(
                [f.measurement_row(zi, *(scale * v for v in tensions.at(ti)))
                 for ti, zi in zip(t, z_imu)]
            )  # fmt: skip
            recovery = RecoverySettings(drift_reset=a.drift_reset or None)
            est = make_estimator("ekf", f, recovery=recovery)
            est.reset()
            cols = [o.name for o in f.outputs]
            out = np.full((len(t), len(cols)), np.nan)
            status = []
            last = None
            for i, (ti, zi) in enumerate(zip(t, z)):
                e = est.step(Measurement(float(ti), zi))
                status.append(str(e.status))
                if e.output is not None:
                    out[i] = e.output
                if e.state is not None:
                    last = e
            after = t >= a.skip
            keep = after & np.all(np.isfinite(out), axis=1)

            def err(c: tuple[str, ...], rows: np.ndarray, out: np.ndarray = out,
                    cols: list[str] = cols) -> np.ndarray:  # fmt: skip
                e = out[rows][:, [cols.index(n) for n in c]]
                tr = truth[rows][:, [names.index(n) for n in c]]
                return np.asarray(np.linalg.norm(e - tr, axis=1), dtype=float)

            tip = err(("x", "y", "z"), keep)
            has = np.all(np.isfinite(out), axis=1)
            tip_all = np.full(len(t), np.nan)
            tip_all[has] = err(("x", "y", "z"), has)
            ok = np.array(status) == "ok"
            force_rms = float(np.sqrt(np.mean(err(("fx", "fy", "fz"), keep) ** 2)))
            ok_tip = round(float(np.nanmean(tip_all[ok]) * 1e3), 2) if ok.any() else None
            statuses = dict(Counter(status))
            row: dict[str, object] = {
                "scenario": a.scenario, "imu": a.imu, "scale": scale, "gain": on,
                "tip_mean_mm": round(float(tip.mean() * 1e3), 2),
                "force_rms_n": round(force_rms, 4),
                "statuses": statuses,
                "ok_over_20mm": int(np.sum(ok & (tip_all > 0.02))),
                "ok_tip_mean_mm": ok_tip,
            }  # fmt: skip
            if on and last is not None and last.covariance is not None:
                g0, n = f.tension_gain_start, f.n_tension_gain
                row["gains"] = [round(float(v), 4) for v in last.state[g0 : g0 + n]]
                row["gain_std"] = [
                    round(float(math.sqrt(last.covariance[i, i])), 4) for i in range(g0, g0 + n)
                ]
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
