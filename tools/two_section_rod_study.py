"""Estimators on the two-section Cosserat-rod recordings (data the PCC model did not
generate): tip and section-end errors of MHE, EKF and UKF with raw IMUs (``direct``)
and with tilt only (``bend``), beside the PCC-model floor, a one-section model of the
whole robot driven by the tip IMU, and the rod's twist about the tangent at each
section end. Raw-IMU cases (``CASES``): with and without the gyro bias estimated
(``raw``, ``raw+bias``), the accelerometer bias too (``+acc``), each IMU's mounting
from the recording's rest recording (``cal``, as ``continuum-mhe calibrate --from
NAME_rest.csv`` prints it; ``cal3``: with each IMU's yaw from the bend recording too,
``calibrate --from NAME_rest.csv --bend NAME_bend.csv``) and the IMUs' own acceleration
modelled (``+own``).

    python tools/two_section_rod_study.py [FOLDER] [--only NAME ...]
    # FOLDER default: the shipped src/continuum_mhe/data/rod2
"""

from __future__ import annotations

import argparse
import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.robot import Robot

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
#: (label, input file suffix, imu model, estimate gyro bias, estimate accelerometer
#: bias, mounting, own acceleration). Mounting: ``""`` none; ``"rest"`` (``cal``
#: cases): the robot file's ``mount_rpy`` roll and pitch from ``continuum-mhe calibrate
#: --from NAME_rest.csv`` (the recommended workflow); ``"bend"`` (``cal3``): with the
#: yaw from ``--bend NAME_bend.csv`` too. ``+own``: ``--own-acceleration``.
CASES = (
    ("raw", "raw", "direct", False, False, "", False),
    ("raw+bias", "raw", "direct", True, False, "", False),
    ("raw+acc", "raw", "direct", True, True, "", False),
    ("cal+bias", "raw", "direct", True, False, "rest", False),
    ("cal+acc", "raw", "direct", True, True, "rest", False),
    ("raw+bias+own", "raw", "direct", True, False, "", True),
    ("cal+bias+own", "raw", "direct", True, False, "rest", True),
    ("cal+acc+own", "raw", "direct", True, True, "rest", True),
    ("cal3+bias", "raw", "direct", True, False, "bend", False),
    ("cal3+bias+own", "raw", "direct", True, False, "bend", True),
    ("cal3+acc+own", "raw", "direct", True, True, "bend", True),
    ("tilt", "tilt", "tilt", False, False, "", False),
    ("cal+tilt", "raw", "tilt", False, False, "rest", False),
)
DEFAULT_CASES = (
    "raw", "raw+bias", "raw+acc", "cal+bias", "cal+acc", "raw+bias+own", "cal+bias+own",
    "cal+acc+own", "tilt",
)  # fmt: skip


def calibrated_robot(robot: Robot, rest: Path, bend: Path | None = None) -> Robot:
    """``robot`` with each IMU's ``mount_rpy`` from a rest recording, as ``continuum-mhe
    calibrate --from REST --robot ...`` prints it (rounded to 0.01 degree as printed);
    with ``bend``, the yaw from that recording of a bend towards ``phi = 0`` too
    (``--bend BEND``)."""
    from continuum_mhe.calibration.at_rest import bend_yaws, calibrate
    from continuum_mhe.io.inputs import read_recording

    fmt, t, values = read_recording(str(rest), robot.n_imus)
    cal = calibrate(t, values, fmt, robot.n_imus, robot.mounting)
    rpys = [c.mount_rpy for c in cal.imus]
    if bend is not None:
        yaws = bend_yaws(str(bend), 0.0, cal, robot)
        rpys = [(r[0], r[1], y.yaw_deg) for r, y in zip(rpys, yaws)]  # type: ignore[index]
    imus = tuple(
        replace(imu, mount_rpy=tuple(round(v, 2) for v in rpy))  # type: ignore[arg-type, union-attr]
        for imu, rpy in zip(robot.imus, rpys)
    )
    return replace(robot, imus=imus)


def evaluate(
    robot: Robot,
    path: Path,
    imu_model: str,
    bias: bool,
    accel_bias: bool,
    truth_path: Path,
    bias_psd: float,
    methods: tuple[str, ...] = ("mhe", "ekf", "ukf"),
    mhe: MHESettings | None = None,
    fit: tuple[int, int] | None = None,
    own: bool = False,
) -> dict[str, tuple[float, float, float, int]]:
    """``method -> (tip mean, tip max, section 1 end mean, bad-start restarts)``, mm
    (MHE: N = 30 unless ``mhe`` says otherwise). With ``fit`` (tilt only), also prints
    the measurement cost ``sum r^T R^-1 r`` over samples ``fit[0]:fit[1]`` of each
    method's bends and of the rod's true PCC bends."""
    truth = read_state_table(truth_path)
    opts = InputOptions(
        raw=RawImuSettings(imu_model=imu_model),  # type: ignore[arg-type]
        estimate_gyro_bias=bias,
        estimate_accel_bias=accel_bias,
        own_acceleration=own,
    )
    data = load_input(path, opts, make_formulation("bend", robot))
    if bias:
        data = replace(data, formulation=replace(data.formulation, gyro_bias_psd=bias_psd))
    if FORMULATION_SETTINGS:  # --set KEY=VALUE on the raw-IMU formulation
        data = replace(data, formulation=replace(data.formulation, **FORMULATION_SETTINGS))
    f = data.formulation
    names = [o.name for o in f.outputs]
    out = {}
    costs = {}
    for m in methods:
        est = make_estimator(m, f, mhe or MHESettings(horizon=30))  # type: ignore[arg-type]
        s = est.run(data.t, data.z)
        branch = getattr(getattr(est, "inference", None), "branch", None)  # the MHE's
        if branch is not None:
            b = branch.stats
            print(
                f"   branch check ({f.name}): {b.checked} windows, {b.fired} implausible, "
                f"{b.restarted} restarted (stage 1 by start: {b.sources}; stage 2, prior "
                f"forgotten: {b.prior_forgotten})"
            )
        met = compute_metrics(s.output, truth.values, robot.length, names, truth.names)
        end1 = met.section_end_mean_mm.get("1", float("nan"))
        restarts = s.diagnostics.bad_starts if s.diagnostics is not None else 0
        out[m] = (met.tip_mean_mm, met.tip_max_mm, end1, restarts)
        if fit and f.name == "bend":
            costs[m] = fit_cost(f, data.z, s.output, names, fit)
    if costs and fit:
        costs["truth"] = fit_cost(f, data.z, truth.values, list(truth.names), fit)
        print(
            f"   measurement cost over samples {fit[0]}-{fit[1]}: "
            + ", ".join(f"{k} {v:.0f}" for k, v in costs.items())
        )
    return out


def fit_cost(
    f: Formulation, z: np.ndarray, table: np.ndarray, names: list[str], fit: tuple[int, int]
) -> float:
    """``sum r^T R^-1 r`` of the tilt measurements over samples ``fit[0]:fit[1]`` for
    the bends in the columns ``theta_k, phi_k`` of ``table`` (rates do not enter)."""
    n = f.robot.n_sections
    cols = [(names.index(f"theta_{k}"), names.index(f"phi_{k}")) for k in range(1, n + 1)]
    r_inv = np.linalg.inv(f.meas_cov())
    total = 0.0
    for i in range(*fit):
        bends = [
            (table[i, a] * np.cos(table[i, b]), table[i, a] * np.sin(table[i, b])) for a, b in cols
        ]
        x = np.concatenate([np.ravel(bends), np.zeros(f.nx - 2 * n)])
        r = np.asarray(f.functions.innovate(z[i], x)[0], dtype=float).ravel()
        total += float(r @ r_inv @ r)
    return total


def one_section_mhe(robot: Robot, folder: Path, name: str) -> float:
    """Tip error (mm, mean) of a one-section model of the whole robot, driven by the
    tip IMU's tilt (columns ``_2``), MHE N = 30."""
    tilt = read_measurements(folder / f"{name}_tilt.csv", n_imus=2)
    f1 = make_formulation("bend", Robot.single(robot.length, 3.0))
    s = make_estimator("mhe", f1, MHESettings(horizon=30)).run(tilt.t, tilt.z[:, 2:4])
    truth = read_state_table(folder / f"{name}_truth.csv")
    return float(np.mean(np.linalg.norm(s.output[:, :3] - truth.values[:, :3], axis=1)) * 1e3)


#: Fields of the raw-IMU formulation set with ``--set KEY=VALUE``.
FORMULATION_SETTINGS: dict[str, float] = {}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", nargs="?", type=Path, default=DATA)
    p.add_argument("--only", nargs="+", metavar="NAME", help="recordings to run (default all)")
    p.add_argument(
        "--bias-psd",
        type=float,
        default=DirectFormulation.gyro_bias_psd,
        help="gyro-bias random walk, (rad/s)^2/s (default: the formulation's)",
    )
    p.add_argument("--methods", nargs="+", default=["mhe", "ekf", "ukf"])
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a field of the raw-IMU formulation (e.g. bend_jerk_psd=4, accel_direction_std=0.01)",
    )
    p.add_argument("--solver", default="fast", choices=["fast", "ipopt"], help="the MHE's")
    p.add_argument(
        "--branch-check", action="store_true", help="the MHE's branch check (estimators/branch.py)"
    )
    p.add_argument("--horizon", type=int, default=30, help="the MHE's N (default 30)")
    p.add_argument(
        "--fit-cost",
        nargs=2,
        type=int,
        metavar=("FIRST", "STOP"),
        help="tilt only: print the measurement cost of each method's bends and of the "
        "true bends over samples FIRST:STOP",
    )
    p.add_argument(
        "--theta-max", type=float, help="every section's bend bound, rad (default: the robot's)"
    )
    p.add_argument(
        "--cases",
        nargs="+",
        default=list(DEFAULT_CASES),
        choices=[c[0] for c in CASES],
        help=f"default: {' '.join(DEFAULT_CASES)}",
    )
    args = p.parse_args()
    for item in args.set:
        key, _, value = item.partition("=")
        FORMULATION_SETTINGS[key] = float(value)
    warnings.simplefilter("ignore")
    robot = read_robot("two-section")
    if args.theta_max is not None:
        sections = tuple(replace(sec, theta_max=args.theta_max) for sec in robot.sections)
        robot = replace(robot, sections=sections)
    mhe = MHESettings(horizon=args.horizon, solver=args.solver, branch_check=args.branch_check)
    for info_path in sorted(args.folder.glob("*_info.json")):
        name = info_path.name[: -len("_info.json")]
        if args.only and name not in args.only:
            continue
        info = json.loads(info_path.read_text())
        floor = info["pcc_floor_mean_mm"]
        twist = info.get("tangent_twist_max_deg", [float("nan")] * 2)
        print(
            f"== {name} ({info.get('drive', 'base')} drive, G/E = {info['shear_ratio']:.3g}): "
            f"PCC floor {floor:.2f} mm mean ({info['pcc_floor_max_mm']:.2f} max), "
            f"one-section arc through the true tip tangent "
            f"{info['one_section_mean_mm']:.1f} mm; bends up to "
            f"{', '.join(f'{v:.0f}' for v in info['theta_max_deg'])} deg; twist about the "
            f"tangent up to {twist[0]:.1f} deg (section 1 end), {twist[1]:.1f} deg (tip); "
            f"material twist up to {info['twist_max_deg']:.1f} deg"
        )
        for label, suffix, imu_model, bias, accel_bias, cal, own in CASES:
            if label not in args.cases:
                continue
            rest = args.folder / f"{name}_rest.csv"
            bend = args.folder / f"{name}_bend.csv"
            missing = [p.name for p in (rest, bend)[: ("", "rest", "bend").index(cal)]]
            if any(not (args.folder / m).exists() for m in missing):
                print(f"   {label:13s} skipped: no {' or '.join(missing)}")
                continue
            res = evaluate(
                calibrated_robot(robot, rest, bend if cal == "bend" else None) if cal else robot,
                args.folder / f"{name}_{suffix}.csv", imu_model, bias, accel_bias,
                args.folder / f"{name}_truth.csv", args.bias_psd, tuple(args.methods),
                mhe,
                tuple(args.fit_cost) if args.fit_cost else None, own,
            )  # fmt: skip
            for m, (mean, mx, end1, restarts) in res.items():
                print(
                    f"   {label:13s} {m}: tip {mean:6.2f} mm mean ({mean / floor:.2f}x floor), "
                    f"max {mx:6.1f} mm; section 1 end {end1:5.2f} mm; {restarts} bad-start "
                    "restarts"
                )
        if "mhe" in args.methods:
            one = one_section_mhe(robot, args.folder, name)
            print(f"   one-section model (tip IMU, tilt, MHE): tip {one:6.2f} mm mean")


if __name__ == "__main__":
    main()
