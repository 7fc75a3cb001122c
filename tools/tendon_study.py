"""Tendon-robot estimates on the generator's recordings (docs/tendon.md): the EKF
(the command line's, compiled), the UKF and the MHE on IPOPT, tilt and raw IMUs, with the
recording's tensions; prints one JSON line per run (tip and mid-robot mean error,
mm; tip-force rms error, N; ms per sample; the rows after ``--skip`` whose tip is over 5 mm
off and whose status is ``ok``; the true tip force at the first row, N), with the
recording's model floor: the mean tip and mid-robot error of the estimator's model
itself, solved with the true tensions and the true tip force (``--floor-only``: that
alone).

The formulation is the command line's (``continuum-mhe estimate --robot ROBOT --inputs
TENSIONS.csv``, with ``--imu-model direct`` for raw IMUs): its defaults, unless
``--set NAME=VALUE`` changes a :class:`TendonFormulation` field (repeatable; a study,
e.g. ``--set force_accel_psd=0.1``; ``--set free_of_load_hypothesis=False``: the single
loaded EKF instead of the two hypotheses, loaded and free of load).

    python tools/tendon_study.py DIR SCENARIO [--method ekf|mhe|ukf] [--imu tilt|direct]
        [--ukf-alpha A]
        [--horizon N] [--skip S] [--set NAME=VALUE] [--tip-imu-only] [--samples N] [--start S]
        [--no-gyro-bias] [--floor-only] [--errors CSV]
"""

from __future__ import annotations

import argparse
import ast
import json
import math
import time
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.kalman import SigmaPointSettings, UnscentedKalmanFilter
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.raw_imu import RawImuSettings, raw_to_measurements
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import Tensions, read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import FormulationName, NoiseSettings
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.model.tendon_statics import Station
from continuum_mhe.settings import MHESettings


def _table(path: Path) -> tuple[list[str], np.ndarray]:
    lines = [ln for ln in path.read_text().splitlines() if not ln.startswith("#")]
    return lines[0].split(","), np.loadtxt(lines[1:], delimiter=",", ndmin=2)


def study_formulation(
    robot_file: str,
    imu: str,
    tip_imu_only: bool,
    noise_deg: float,
    options: InputOptions,
    settings: Sequence[str] = (),
) -> tuple[TendonFormulation, list[int]]:
    """The tendon formulation of ``robot_file`` (its IMUs, or the tip IMU alone), ``imu``
    readings (``direct`` or ``tilt``) of ``noise_deg`` degrees, with ``options`` and the
    ``NAME=VALUE`` ``settings`` replaced in it; and the robot file's IMUs used (0-based)."""
    robot = read_robot(robot_file)
    used = [robot.n_imus - 1] if tip_imu_only else list(range(robot.n_imus))
    robot = replace(robot, imus=tuple(robot.imus[k] for k in used))
    name: FormulationName = "direct" if imu == "direct" else "bend"
    base = make_formulation(
        name,
        robot,
        NoiseSettings(measurement_std=math.radians(noise_deg)),
    )
    changes = {k: ast.literal_eval(v) for k, v in (kv.split("=", 1) for kv in settings)}
    return replace(tendon_formulation_for(base, options), **changes), used


def imu_readings(
    folder: Path, scenario: str, imu: str, used: Sequence[int]
) -> tuple[np.ndarray, np.ndarray]:
    """``(t (n,) s, readings (n, m))`` of a generator recording's IMUs ``used`` (0-based,
    in order) as the tendon formulation reads them: ``tilt`` roll and pitch (rad) from
    ``SCENARIO_tilt.csv``, or ``direct`` the raw ``SCENARIO_raw.csv`` converted (specific
    force direction and gyro, rad/s)."""
    if imu == "tilt":
        _, tilt = _table(folder / f"{scenario}_tilt.csv")
        return tilt[:, 0], np.hstack([tilt[:, 1 + 2 * k : 3 + 2 * k] for k in used])
    _, raw = _table(folder / f"{scenario}_raw.csv")
    t = raw[:, 0]
    settings = RawImuSettings(imu_model="direct")
    z_imu = np.hstack(
        [raw_to_measurements(t, raw[:, 1 + 6 * k : 4 + 6 * k], raw[:, 4 + 6 * k : 7 + 6 * k],
                             settings) for k in used]
    )  # fmt: skip
    return t, z_imu


def model_floor(
    f: TendonFormulation, t: np.ndarray, tensions: Tensions, names: list[str], truth: np.ndarray
) -> tuple[float, float]:
    """Mean tip and mid-robot (first section's end) error, mm, of the model's
    equilibria with the true tensions and tip force at the times ``t``."""
    tip, mid = Station(f.robot.n_sections - 1, 1.0), Station(0, 1.0)
    cols = {c: [names.index(f"{a}{c}") for a in "xyz"] for c in ("", "_1")}
    force = [names.index(n) for n in ("fx", "fy", "fz")]
    k0 = None
    errors = []
    for tk, row in zip(t, truth):
        k0, poses = f.statics.solve(row[force], tensions.at(tk)[0], k0)
        errors.append(
            [np.linalg.norm(poses[s][1] - row[cols[c]]) for s, c in ((tip, ""), (mid, "_1"))]
        )
    e = np.mean(errors, axis=0) * 1e3
    return float(e[0]), float(e[1])


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--method", choices=("ekf", "mhe", "ukf"), default="ekf")
    p.add_argument(
        "--ukf-alpha", type=float, default=None,
        help="the UKF's sigma-point spread (default: TendonFormulation.unscented_alpha)",
    )  # fmt: skip
    p.add_argument("--imu", choices=("tilt", "direct"), default="tilt")
    p.add_argument("--horizon", type=int, default=10)
    p.add_argument("--skip", type=float, default=1.0)
    p.add_argument("--robot", default="tendon-two-section")
    p.add_argument("--noise-deg", type=float, default=2.0, help="as the command line's")
    p.add_argument("--gyro-std", type=float, default=None, help="as the command line's")
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="a TendonFormulation field (repeatable)")  # fmt: skip
    p.add_argument("--tip-imu-only", action="store_true", help="use only the last IMU")
    p.add_argument("--samples", type=int, default=None, help="only the first N samples")
    p.add_argument(
        "--start", type=float, default=0.0,
        help="s: the recording from this time on (a start under the load it has then)",
    )  # fmt: skip
    p.add_argument("--no-gyro-bias", action="store_true", help="raw IMUs: no gyro-bias states")
    p.add_argument("--floor-only", action="store_true", help="only the model floor")
    p.add_argument(
        "--errors",
        type=Path,
        help="write t, tip and mid error (m) and tip-force error (N) per sample here",
    )
    a = p.parse_args()
    if a.ukf_alpha is not None and a.method != "ukf":
        p.error("--ukf-alpha is the UKF's (--method ukf)")
    options = InputOptions(
        gyro_std=a.gyro_std, estimate_gyro_bias=False if a.no_gyro_bias else None
    )
    f, used = study_formulation(a.robot, a.imu, a.tip_imu_only, a.noise_deg, options, a.set)
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", f.robot.n_tendons)
    t, z_imu = imu_readings(a.folder, a.scenario, a.imu, used)
    n = len(t) if a.samples is None else a.samples
    t, z_imu = t[:n], z_imu[:n]
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    truth = truth[:n]
    later = t >= a.start
    t, z_imu, truth = t[later], z_imu[later], truth[later]
    after = t >= a.skip
    floor = model_floor(f, t[after], tensions, names, truth[after])
    if a.floor_only:
        print(json.dumps({"scenario": a.scenario, "floor_tip_mm": round(floor[0], 3),
                          "floor_mid_mm": round(floor[1], 3)}))  # fmt: skip
        return
    z = np.array([f.measurement_row(zi, *tensions.at(ti)) for ti, zi in zip(t, z_imu)])
    if a.method == "ukf":
        est = UnscentedKalmanFilter(f, SigmaPointSettings(alpha=a.ukf_alpha))
    elif a.method == "ekf":
        est = make_estimator("ekf", f)  # the command line's (compiled) EKF
    else:
        # the command line's MHE on IPOPT: both load hypotheses (the loaded one alone
        # with --set free_of_load_hypothesis=False)
        est = make_estimator("mhe", f, MHESettings(horizon=a.horizon, solver="ipopt"))
    start = time.perf_counter()
    series = est.run(t, z)
    ms = (time.perf_counter() - start) / len(t) * 1e3
    out = np.asarray(series.output, dtype=float)
    std = np.asarray(series.std, dtype=float)
    cols = [o.name for o in f.outputs]
    keep = (t >= a.skip) & np.all(np.isfinite(out), axis=1)

    def err(c: tuple[str, ...]) -> np.ndarray:
        e = out[keep][:, [cols.index(n) for n in c]]
        tr = truth[keep][:, [names.index(n) for n in c]]
        return np.asarray(np.linalg.norm(e - tr, axis=1), dtype=float)

    force = [cols.index(n) for n in ("fx", "fy", "fz")]
    force_true = [names.index(n) for n in ("fx", "fy", "fz")]
    if a.errors is not None:
        rows = np.column_stack(
            [t[keep], err(("x", "y", "z")), err(("x_1", "y_1", "z_1")), err(("fx", "fy", "fz"))]
        )
        np.savetxt(a.errors, rows, delimiter=",", header="t,tip,mid,force", comments="")
    tip_error = err(("x", "y", "z"))
    ok_over_5mm = int(np.sum((series.status[keep] == "ok") & (tip_error > 5e-3)))
    statuses: dict[str, int] = {}
    for s in series.status:
        statuses[str(s)] = statuses.get(str(s), 0) + 1
    print(json.dumps({
        "scenario": a.scenario, "method": a.method, "imu": a.imu,
        "horizon": a.horizon if a.method == "mhe" else None, "set": a.set,
        "imus": [k + 1 for k in used],
        "tip_mean_mm": round(float(err(("x", "y", "z")).mean() * 1e3), 2),
        "mid_mean_mm": round(float(err(("x_1", "y_1", "z_1")).mean() * 1e3), 2),
        "force_rms_n": round(float(np.sqrt(np.mean(err(("fx", "fy", "fz")) ** 2))), 4),
        "force_std_mean_n": round(float(np.mean(np.linalg.norm(std[keep][:, force], axis=1))), 4),
        "floor_tip_mm": round(floor[0], 3), "floor_mid_mm": round(floor[1], 3),
        "ms_per_sample": round(ms, 1), "statuses": statuses, "ok_over_5mm": ok_over_5mm,
        "free_of_load_rows": getattr(est.inference, "free_of_load_samples", None),
        "first_row_force_n": round(float(np.linalg.norm(truth[0, force_true])), 4),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
