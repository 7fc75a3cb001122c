"""``continuum-mhe calibrate``: each IMU's statistics at rest and its mounting
(:mod:`continuum_mhe.calibration.at_rest` measures)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

from continuum_mhe.calibration.at_rest import (
    STILL_ACC_STD,
    STILL_GYRO_STD,
    Calibration,
    bend_yaws,
    calibrate,
    check_rest_mounting,
    collect,
    creep_at_rest,
    format_report,
    frozen_at_rest,
    knocks_at_rest,
    motion_at_rest,
    rest_gravity_note,
    rest_gravity_problem,
    rest_tilt_warning,
    rolls_kept,
)
from continuum_mhe.calibration.bend import YawCalibration, tilt_order_warning
from continuum_mhe.cli.options import add_overwrite_option, given_options
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import add_robot_option, robot_from_args
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.io.inputs import read_recording
from continuum_mhe.io.output_files import atomic_writer, check_output_target, refuse_inputs
from continuum_mhe.io.robot_file import robot_source_text, with_imu_calibration
from continuum_mhe.io.robot_logs import is_robot_log, refuse_bag_metadata
from continuum_mhe.io.sample_rows import DROPOUT_HINT
from continuum_mhe.io.text_rows import READINGS_READER
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.robot import DEFAULT_THETA_MAX, Robot
from continuum_mhe.stream.protocol import LINE_FORMATS, LineFormat, raw_limits
from continuum_mhe.stream.reader import stderr_say


def _check_gyro_bound_applies(args: argparse.Namespace, fmt: LineFormat, source: str) -> None:
    """Refuse ``--still-gyro-std`` on a recording without a gyro (it would do nothing)."""
    if args.still_gyro_std is not None and fmt != "raw":
        raise InputError(f"{source}: --still-gyro-std needs a raw recording (this one is {fmt})")


def run(args: argparse.Namespace) -> int:
    robot = robot_from_args(args)
    if args.source:  # the serial line's options do nothing on a recording
        given: frozenset[str] = getattr(args, "given_options", frozenset())
        unused = [f"--{d}" for d in ("seconds", "baud", "format", "port") if d in given]
        if unused:
            raise InputError(
                f"{args.source}: {', '.join(unused)} does not apply with --from: it is for "
                "reading the serial line (--port)"
            )
    if not args.write_robot:  # they describe the robot file it writes, and nothing else
        unused = [
            f"--{d.replace('_', '-')}" for d in ("length", "theta_max") if d in given_options(args)
        ]
        if unused:
            verb = "does" if len(unused) == 1 else "do"
            raise InputError(
                f"{' and '.join(unused)} {verb} nothing without --write-robot: they describe "
                "the robot file that --write-robot writes"
            )
    for option, name in (("--from", args.source), ("--bend", args.bend)):
        if name is not None and not Path(name).exists() and name != "-":
            raise InputError(f"{name}: no such file")
        if name is not None:
            refuse_bag_metadata(name)
        if name is not None and is_robot_log(Path(name)):
            continue  # a ROS bag (a folder) or MCAP file, read by its topics
        if name is not None and not Path(name).is_file():  # read twice: the kind, then it
            raise InputError(
                f"{name}: {option} reads a file (not standard input, a pipe or a folder "
                "other than a ROS 2 bag's): save the recording first"
            )
    logs = [n for n in (args.source, args.bend) if n is not None and is_robot_log(Path(n))]
    if args.topic and not logs:
        raise InputError(
            "--topic chooses the IMUs of a ROS bag or MCAP file given to --from or --bend"
        )
    if args.write_robot:  # before recording or reading
        refuse_inputs(args.write_robot, [("the recording --from", args.source),
                                         ("the bent recording --bend", args.bend),
                                         ("the robot file --robot", args.robot)])  # fmt: skip
        check_output_target(args.write_robot, args.overwrite, "--write-robot")
        if Path(args.write_robot).suffix.lower() != ".toml":
            raise InputError(f"{args.write_robot}: --write-robot writes a robot file (.toml)")
        if not args.source and args.format != "raw":
            raise InputError("--write-robot needs raw readings (--format raw)")
    if args.bend_phi is not None and not args.bend:
        raise InputError("--bend-phi needs --bend BEND.csv")
    say = stderr_say("calibrate")
    left_out = ""  # said once the calibration holds
    if args.source:
        try:
            topics = tuple(args.topic or ()) if is_robot_log(Path(args.source)) else ()
            fmt, t, values = read_recording(args.source, robot.n_imus, args.degrees, topics)
        except InputError as exc:
            raise _without_skip_bad(exc, "the still robot") from None
        source = args.source
        missing = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if len(missing):  # an empty field, a zero or impossible reading: a dropout
            left_out = (
                f"{PROG}: warning: {source}: {len(missing)} of {len(t)} row(s) with a reading "
                f"missing, zero or beyond any IMU's range (the first at t = "
                f"{time_text(float(t[missing[0]]))} s): that IMU's reading is left out of its "
                "mean and noise there"
            )
        _check_gyro_bound_applies(args, fmt, source)
    else:
        if args.port is None:
            raise InputError("give --port DEVICE or --from RAW.csv")
        if args.degrees:
            raise InputError(
                "--degrees reads a tilt recording in degrees (--from TILT.csv); a board's "
                "tilt lines are in radians"
            )
        if not (math.isfinite(args.seconds) and args.seconds > 0):
            raise InputError(f"--seconds must be positive, got {args.seconds}")
        fmt, source = args.format, args.port
        _check_gyro_bound_applies(args, fmt, source)  # before recording for --seconds
        t, values = collect(
            args.port, args.baud, fmt, robot.n_imus, args.seconds, say, robot.n_tendons,
            tuple(raw_limits(p.accel_range, p.gyro_range) for p in robot.imus),
        )  # fmt: skip
    gyro_std = STILL_GYRO_STD if args.still_gyro_std is None else args.still_gyro_std
    if unit := rest_gravity_problem(values, fmt, robot.n_imus):
        raise InputError(f"{source}: {unit}")
    if scaled := rest_gravity_note(values, fmt, robot.n_imus):
        print(f"{PROG}: note: {source}: {scaled}", file=sys.stderr)
    fix = "pass --degrees" if args.source else "the board must send radians"
    moved = motion_at_rest(
        values, fmt, robot.n_imus, args.still_acc_std, gyro_std, None if args.degrees else fix
    )
    if moved:
        raise InputError(f"{source}: {moved}")
    frozen = frozen_at_rest(t, values, robot.n_imus) if fmt == "raw" else None
    if frozen:
        raise InputError(f"{source}: {frozen}")
    if args.write_robot and fmt != "raw":
        raise InputError(f"{source}: --write-robot needs a raw recording (this one is {fmt})")
    flipped = check_rest_mounting(source, values, robot, bool(args.robot), fmt)
    if flipped:  # raw: a board upside down, said (tilt ones are refused or left alone)
        if not args.bend:  # gravity does not tell a board turned over about x from one about y
            flipped += (
                "; its yaw is the robot file's, right for a board turned over about its x "
                "axis: one turned over about its y axis reads gravity alike and lies 180 "
                "degrees from that yaw (its section's bending plane turned half a turn): a "
                "bend in a known plane (--bend) measures it"
            )
        print(f"{PROG}: warning: {source}: {flipped}", file=sys.stderr)
    knocks: list[str] = []
    if fmt == "raw":
        values, knocks = knocks_at_rest(t, values, robot.n_imus, args.still_acc_std, gyro_std)
        knocks += creep_at_rest(values, robot.n_imus)
    try:
        cal = calibrate(t, values, fmt, robot.n_imus, robot.mounting)
    except InputError as exc:  # name the recording
        raise InputError(f"{source}: {exc}") from None
    if left_out:
        print(left_out, file=sys.stderr)
    for knock in knocks:
        print(f"{PROG}: warning: {source}: {knock}", file=sys.stderr)
    tilted = rest_tilt_warning(cal, robot.mounting, fix, [imu.mount_rpy[2] for imu in robot.imus])
    if tilted:
        print(f"{PROG}: warning: {source}: {tilted}", file=sys.stderr)
    if fmt == "raw":
        cal, kept = rolls_kept(cal, [imu.mount_rpy[0] for imu in robot.imus])
        for i in kept:
            imu = cal.imus[i - 1]
            assert imu.mount_rpy is not None
            roll_from = (
                f"the robot file's roll ({imu.mount_rpy[0]:g} degrees) is kept"
                if args.robot
                else f"its roll is taken as {imu.mount_rpy[0]:g} (no robot file gives one)"
            )
            print(
                f"{PROG}: note: {source}: IMU {i}'s x axis lies within "
                f"{90 - abs(imu.mount_rpy[1]):.1f} degrees of gravity at rest (pitch "
                f"{imu.mount_rpy[1]:.2f} degrees): its roll turns it about gravity, which a "
                f"rest does not show, so {roll_from} (--bend measures the turn about gravity)",
                file=sys.stderr,
            )
    bend = None
    if args.bend:
        phi = 0.0 if args.bend_phi is None else args.bend_phi
        if radians_like_degrees(phi):
            print(
                f"{PROG}: warning: --bend-phi {phi:g} is in degrees: radians? ({phi:g} rad "
                f"is {math.degrees(phi):.4g} degrees: give --bend-phi {math.degrees(phi):.4g})",
                file=sys.stderr,
            )
        try:
            topics = tuple(args.topic or ()) if is_robot_log(Path(args.bend)) else ()
            bend = (args.bend, phi, bend_yaws(args.bend, phi, cal, robot, topics))
        except InputError as exc:
            raise _without_skip_bad(exc, "the bent robot") from None
        places = [(imu.section, imu.at) for imu in robot.imus]
        reach = [s.theta_max for s in robot.sections]
        if order := tilt_order_warning(places, bend[2], reach):
            print(f"{PROG}: warning: {args.bend}: {order}", file=sys.stderr)
    yaws = [imu.mount_rpy[2] for imu in robot.imus]
    print(format_report(cal, source, bend, yaws, robot.mounting))
    if args.write_robot:
        _write_robot(args, robot, cal, bend)
    return 0


def radians_like_degrees(angle: float) -> bool:
    """An angle given in degrees that looks like radians: within 2 pi, not zero, and
    not a whole number of degrees (a plane's angle is 90, or 45, not 1.5708)."""
    return 0.0 < abs(angle) <= 2.0 * math.pi and abs(angle - round(angle)) > 1e-9


def _without_skip_bad(exc: InputError, robot: str) -> InputError:
    """A reading error as calibrate says it: it has no --skip-bad (the readings of
    ``robot``, each of them, make the calibration), and a file of another kind (an
    estimate or truth) is told what calibrate reads, not what estimate reads."""
    return InputError(
        str(exc)
        .replace(DROPOUT_HINT, f"calibrate needs every reading of {robot}")
        .replace(READINGS_READER, f"calibrate reads a recording of the IMUs on {robot}")
    )


def _write_robot(
    args: argparse.Namespace,
    robot: Robot,
    cal: Calibration,
    bend: tuple[str, float, list[YawCalibration]] | None,
) -> None:
    """The robot file (``--robot``'s, comments kept) with each IMU's measured mounting
    (the yaw from ``--bend``, else the file's own) and gyro bias, to ``--write-robot``."""
    mounts = []
    for i, imu in enumerate(cal.imus):
        assert imu.mount_rpy is not None  # a raw recording (checked before)
        roll, pitch, _ = imu.mount_rpy
        yaw = bend[2][i].yaw_deg if bend else robot.imus[i].mount_rpy[2]
        mounts.append((roll, pitch, yaw))
    biases = [tuple(float(v) for v in imu.mean[3:6]) for imu in cal.imus]
    text = with_imu_calibration(
        robot_source_text(args.robot, robot), mounts, biases, args.write_robot
    )
    with atomic_writer(Path(args.write_robot)) as fh:
        fh.write(text)
    whence = (
        "from --bend"
        if bend
        else "kept from the robot file: gravity does not show it, --bend measures it; a "
        "board turned about the backbone by a yaw the file does not give reads its "
        "section's bending plane turned by as much"
        if args.robot
        else "0: gravity does not show it, --bend measures it"
    )
    assumed = (
        ""
        if args.robot
        else f"; its section's length = {robot.lengths[0]:g} m (--length) and theta_max = "
        f"{robot.sections[0].theta_max:g} rad (--theta-max) are not measured: set them to "
        "your robot's"
    )
    print(
        f"{PROG}: wrote {args.write_robot}: each IMU's mount_rpy (roll and pitch measured, yaw "
        f"{whence}) and gyro_bias{assumed}",
        file=sys.stderr,
    )


DESCRIPTION = (
    "With the robot straight and still (a recording whose accelerometer "
    f"spreads over {STILL_ACC_STD:g} m/s^2 or gyro over {STILL_GYRO_STD:g} rad/s, "
    "standard deviation per axis, is refused; --still-acc-std and --still-gyro-std "
    "raise the bounds for a noisier IMU): per IMU, the accelerometer's mean "
    "and noise per axis, the gyro bias and noise, the sample rate achieved and the "
    "mounting (--mount-rpy) that makes the straight robot read theta = 0; with "
    "--bend, each IMU's yaw about the tangent from a bend in a known plane too."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--port", help="serial device, e.g. /dev/ttyACM0")
    src.add_argument(
        "--from",
        dest="source",
        metavar="RAW.csv",
        help="a recording instead: a CSV file (raw or tilt), or a ROS bag or MCAP file (--topic)",
    )
    p.add_argument(
        "--topic",
        action="append",
        metavar="TOPIC",
        help="a ROS bag's or MCAP file's sensor_msgs/Imu topic, once per IMU in the robot "
        "file's order (paired by header stamp as estimate pairs them); not needed for a "
        "log with one Imu topic and a robot with one IMU",
    )
    p.add_argument(
        "--bend",
        metavar="BEND.csv",
        help="a raw recording of the robot bent slowly in one known plane (--bend-phi): "
        "each IMU's yaw about the tangent, and the full mount_rpy",
    )
    p.add_argument(
        "--bend-phi",
        type=float,
        metavar="DEG",
        help="the plane of --bend: the direction the robot bends towards, degrees "
        "(default 0: towards base -x)",
    )
    p.add_argument(
        "--degrees",
        action="store_true",
        help="the tilt recording of --from gives roll and pitch in degrees (default radians)",
    )
    p.add_argument("--seconds", type=float, default=10.0, help="device seconds to read (10)")
    p.add_argument("--baud", type=int, default=115200, help="baud rate (default 115200)")
    p.add_argument("--format", choices=LINE_FORMATS, default="raw", help="line format (raw)")
    add_robot_option(p, replaces=("--length", "--theta-max", "--mounting"))
    p.add_argument(
        "--write-robot",
        metavar="OUT.toml",
        help="write the robot file (--robot's, its comments kept) with each IMU's measured "
        "mount_rpy and gyro_bias",
    )
    add_overwrite_option(p, "--write-robot")
    p.add_argument(
        "--length",
        type=float,
        default=0.2,
        metavar="M",
        help="without --robot: the section length of the one-section robot (m, default "
        "0.2), which --write-robot writes",
    )
    p.add_argument(
        "--theta-max",
        type=float,
        default=DEFAULT_THETA_MAX,
        metavar="RAD",
        help="without --robot: its bound on the bend that --write-robot writes (rad, "
        f"default {DEFAULT_THETA_MAX:g}, as a robot file without theta_max)",
    )
    p.add_argument(
        "--mounting", choices=MOUNTINGS, default="z-up",
        help="base orientation: z-up (default), its z axis up, or z-down, hanging from it",
    )  # fmt: skip
    p.add_argument(
        "--still-acc-std",
        type=float,
        default=STILL_ACC_STD,
        metavar="M/S2",
        help="largest accelerometer spread (standard deviation per axis, m/s^2) of a still "
        "robot; for a tilt recording, this over g in rad (default "
        f"{STILL_ACC_STD:g} m/s^2: 8 times the firmware's MPU9250 at rest)",
    )
    p.add_argument(
        "--still-gyro-std",
        type=float,
        default=None,
        metavar="RAD/S",
        help="largest gyro spread (standard deviation per axis, rad/s) of a still robot, "
        f"raw recordings only (default {STILL_GYRO_STD:g} rad/s: 30 times the firmware's "
        "MPU9250 at rest)",
    )
