"""``continuum-mhe simulate``: a synthetic measurement CSV and its truth."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from continuum_mhe.cli.options import add_overwrite_option, given_options
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import add_robot_option, robot_from_args
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.estimate_csv import write_measurements, write_table, write_truth
from continuum_mhe.io.output_files import check_output_target, refuse_inputs
from continuum_mhe.model.descriptions import robot_outputs
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.robot import Robot
from continuum_mhe.simulation.scenarios import (
    NOISE_MODELS,
    REST_NOISE_DEG,
    SCENARIOS,
    simulate_robot,
)

#: The suffixes the recording and its truth may have: they are CSV files.
CSV_SUFFIXES = (".csv", ".txt", "")
#: Most samples ``simulate`` writes (``--duration / --dt``).
MAX_SIMULATED_SAMPLES = 10_000_000


def run(args: argparse.Namespace) -> int:
    n = args.duration / args.dt
    if n < 1:  # a recording of one sample (t = 0) estimates nothing
        raise InputError(
            f"--duration {args.duration:g} s is shorter than --dt {args.dt:g} s: the "
            "recording would hold its first sample alone"
        )
    given = given_options(args)
    tilt_noise = next((o for o in ("noise_deg", "noise_model") if o in given), None)
    if args.imu == "raw" and tilt_noise is not None:
        flag = "--" + tilt_noise.replace("_", "-")
        raise InputError(
            f"{flag} is for the noise of tilt readings; --imu raw simulates the IMUs' own "
            "accelerometer and gyro noise (docs/hardware.md), so it would do nothing"
        )
    if n > MAX_SIMULATED_SAMPLES:
        raise InputError(
            f"--duration {args.duration:g} / --dt {args.dt:g} is {n:.3g} samples; at most "
            f"{MAX_SIMULATED_SAMPLES:,} (write longer recordings in parts)"
        )
    for target in (args.output, args.truth):  # before --overwrite is asked for
        if target:
            refuse_inputs(target, [("the robot file --robot", getattr(args, "robot", None))])
    check_output_target(args.output, args.overwrite)  # both before writing either
    for flag, target in (("-o", args.output), ("--truth", args.truth)):
        suffix = Path(target).suffix if target else ""
        if suffix.lower() not in CSV_SUFFIXES:  # a name another reader would misread
            raise InputError(
                f"{target}: {flag} is written as CSV (.csv or .txt, or no suffix), not {suffix}"
            )
    if args.truth:
        truth = check_output_target(args.truth, args.overwrite, "--truth")
        if truth.resolve() == Path(args.output).resolve():
            raise InputError(
                f"{args.truth}: --truth names the measurement file -o too; give two files"
            )
    robot = robot_from_args(args)
    tensions = None
    if robot.tendons and args.scenario == "rest":  # straight, still, its tendons slack:
        tensions = tensions_path(args.output)
        check_output_target(tensions, args.overwrite)
        if args.truth and Path(args.truth).resolve() == tensions.resolve():
            raise InputError(
                f"{args.truth}: --truth names the tensions file that rest writes beside -o "
                "for a tendon robot; give another"
            )
        n_tendons, mechanics = robot.n_tendons, robot
        robot = robot.without_tendons()  # its sections' geometry reads it
    try:
        rec = simulate_robot(
            args.scenario,
            robot,
            duration=args.duration,
            dt=args.dt,
            noise_deg=args.noise_deg if "noise_deg" in given else None,  # the scenario's
            seed=args.seed,
            noise_model=args.noise_model,
        )
    except UserError as exc:  # about the robot: its file named
        if args.robot is None:
            raise
        raise InputError(f"{args.robot}: {exc}") from None
    if args.imu == "raw":
        from continuum_mhe.simulation.raw_readings import raw_readings

        try:
            values, names = raw_readings(rec, robot, seed=args.seed)
        except UserError as exc:
            raise InputError(f"--imu raw: {exc}") from None
        write_measurements(args.output, rec.t, values, names)
    else:
        write_measurements(args.output, rec.t, rec.z, rec.measurement_names)
    true_values, outputs = rec.truth, rec.outputs
    if tensions is not None:  # the tendon robot's outputs: no twist, no tip force
        outputs = robot_outputs(mechanics)
        pcc_names = [o.name for o in rec.outputs]
        # one section: the constant-curvature outputs are theta, phi and the tip, and
        # section 1's end is the tip
        alias = {"theta_1": "theta", "phi_1": "phi", "x_1": "x", "y_1": "y", "z_1": "z"}
        named = [o.name if o.name in pcc_names else alias.get(o.name, o.name) for o in outputs]
        true_values = np.column_stack(
            [rec.truth[:, pcc_names.index(n)] if n in pcc_names
             else np.zeros(len(rec.t)) for n in named]
        )  # fmt: skip
    try:
        if args.truth:
            write_truth(args.truth, rec.t, true_values, outputs)
        if tensions is not None:
            columns = ["t", *(f"tension_{i}" for i in range(1, n_tendons + 1))]
            write_table(tensions, columns, [[t, *[0.0] * n_tendons] for t in rec.t[[0, -1]]])
    except BaseException:  # (a full disk, a signal): no measurements without truth
        Path(args.output).unlink(missing_ok=True)
        raise
    print(f"wrote {len(rec.t)} samples of {args.scenario} to {args.output}", file=sys.stderr)
    if tensions is not None:
        print(
            f"{PROG}: note: the tendons are slack at rest: wrote their tensions, 0 N, to "
            f"{tensions} (estimate --inputs {tensions})",
            file=sys.stderr,
        )
    beyond = _bends_beyond_bounds(rec.truth, [o.name for o in rec.outputs], robot)
    if beyond:
        print(
            f"{PROG}: note: the {args.scenario} motion bends {beyond}: estimates there are "
            "at-bound (theta_max is the robot's limit; estimate --theta-max, or the robot "
            "file's theta_max, raises it)",
            file=sys.stderr,
        )
    mounted = [str(i + 1) for i, place in enumerate(robot.imus) if any(place.mount_rpy)]
    if mounted and args.imu != "raw":  # as estimate takes tilt input (raw: rotated by it)
        print(
            f"{PROG}: note: the robot file's mount_rpy of IMU {', '.join(mounted)} is not "
            "applied: the roll and pitch written are those of each IMU's disk, as estimate "
            "takes tilt input",
            file=sys.stderr,
        )
    return 0


def tensions_path(output: str) -> Path:
    """The tensions file ``simulate rest`` writes beside ``output`` for a tendon robot:
    ``NAME_tensions.csv``."""
    p = Path(output)
    return p.with_name(f"{p.stem}_tensions.csv")


def _bends_beyond_bounds(truth: np.ndarray, names: list[str], robot: Robot) -> str:
    """The sections the true motion bends past their ``theta_max`` ("section 1 to 1.44
    rad, beyond its theta_max 1"), or ``""``."""
    said = []
    for k, section in enumerate(robot.sections, start=1):
        name = "theta" if "theta" in names else f"theta_{k}"
        if name not in names:
            continue
        most = float(np.max(truth[:, names.index(name)]))
        if most > section.theta_max + 1e-9:
            said.append(
                f"section {k} to {most:.3g} rad, beyond its theta_max {section.theta_max:g}"
            )
    return "; ".join(said)


DESCRIPTION = (
    "Write a synthetic recording of a constant-curvature robot's motion (noisy tilt or "
    "raw IMU readings) and, with --truth, its true shape, to try the tool without a "
    "robot. Its readings follow the model the estimators use (raw ones with each IMU's "
    "own acceleration, which estimate leaves out without --own-acceleration); the "
    "Cosserat-rod recordings shipped in the package (data/rod2, data/tendon) do not."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "scenario",
        choices=SCENARIOS,
        help="the motion: one section: paper3d (the paper's 3D motion), planar-overbend "
        "(one plane, past 90 degrees), straight (through the straight pose); two or more "
        "sections (--robot): s-curve (neighbours bent opposite ways), spatial (turning "
        "bending planes); any robot: rest (straight and still, for calibrate --from)",
    )
    p.add_argument("-o", "--output", required=True, help="measurement CSV to write")
    p.add_argument("--truth", help="truth CSV to write")
    add_overwrite_option(p, "-o or --truth")
    p.add_argument(
        "--imu",
        choices=("tilt", "raw"),
        default="tilt",
        help="tilt: roll and pitch per IMU (default); raw: accelerometer (m/s^2) and gyro "
        "(rad/s) per IMU, as a raw-IMU robot sends them (MEMS-like noise and gyro bias; "
        "--noise-deg is for tilt): each in its sensor's frame, turned by the robot file's "
        "mount_rpy, its gyro biased by the file's gyro_bias plus a bias drawn per axis "
        "(0.01 rad/s standard deviation), as calibrate then finds them",
    )
    p.add_argument(
        "--noise-deg",
        type=float,
        default=2.0,
        help="the readings' noise std in degrees (default 2; for rest "
        f"{REST_NOISE_DEG:g}, a still IMU's, as calibrate --from takes it)",
    )
    p.add_argument(
        "--noise-model",
        choices=NOISE_MODELS,
        default="tilt",
        help="tilt: on roll and pitch independently (default, the paper's); tangent: "
        "isotropic on the tangent plane of gravity (what the estimators' R assumes)",
    )
    p.add_argument("--seed", type=int, default=0, help="the noise's random seed (default 0)")
    p.add_argument("--duration", type=float, default=20.0, help="seconds (default 20)")
    p.add_argument("--dt", type=float, default=0.05, help="sample time in s (default 0.05)")
    p.add_argument("--length", type=float, default=0.2, help="section length in m (default 0.2)")
    p.add_argument(
        "--mounting", choices=MOUNTINGS, default="z-up", help="the base's z axis (default z-up)"
    )
    add_robot_option(p, replaces=("--length", "--mounting"), tendons=False)
