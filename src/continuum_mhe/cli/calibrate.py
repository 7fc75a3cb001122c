"""``continuum-mhe calibrate``: each IMU's statistics at rest and its mounting
(:mod:`continuum_mhe.calibration.at_rest` measures)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from continuum_mhe.arrays import FloatArray
from continuum_mhe.calibration.at_rest import STILL_ACC_STD, STILL_GYRO_STD, collect
from continuum_mhe.calibration.robot_calibration import (
    CalibrationNote,
    CalibrationWarning,
    calibrate_readings,
    calibrate_robot,
    check_recordings,
)
from continuum_mhe.cli.held_notes import said_as_lines
from continuum_mhe.cli.options import add_overwrite_option, given_options
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import add_robot_option, robot_from_args
from continuum_mhe.errors import InputError
from continuum_mhe.io.output_files import atomic_writer, check_output_target, refuse_inputs
from continuum_mhe.io.robot_file import robot_source_text, with_imu_calibration
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
    check_recordings(args.source, args.bend, tuple(args.topic or ()))
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
    options: dict[str, Any] = {
        "bend": args.bend,
        "bend_phi_deg": args.bend_phi,
        "still_acc_std": args.still_acc_std,
        "still_gyro_std": args.still_gyro_std,
        "degrees": args.degrees,
        "topics": tuple(args.topic or ()),
        "robot_file": bool(args.robot),
        "require_raw": "--write-robot" if args.write_robot else "",
    }
    with said_as_lines(CalibrationNote, CalibrationWarning):
        if args.source:
            result = calibrate_robot(robot, args.source, **options)
        else:
            result = calibrate_readings(robot, *_recorded(args, robot), from_port=True, **options)
    print(result.report)
    if args.write_robot:
        assert result.robot is not None  # a raw recording (the command requires one)
        _write_robot(args, robot, result.robot, bent=result.yaws is not None)
    return 0


def _recorded(
    args: argparse.Namespace, robot: Robot
) -> tuple[str, FloatArray, FloatArray, LineFormat]:
    """``(port, t, values, format)`` read from the serial port for ``--seconds``."""
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
        args.port, args.baud, fmt, robot.n_imus, args.seconds, stderr_say("calibrate"),
        robot.n_tendons, tuple(raw_limits(p.accel_range, p.gyro_range) for p in robot.imus),
    )  # fmt: skip
    return source, t, values, fmt


def _write_robot(args: argparse.Namespace, robot: Robot, calibrated: Robot, bent: bool) -> None:
    """The robot file (``--robot``'s, comments kept) with the ``calibrated`` robot's
    mountings (the yaw from ``--bend`` where ``bent``, else the file's own) and gyro
    biases, to ``--write-robot``."""
    mounts = [imu.mount_rpy for imu in calibrated.imus]
    biases = [imu.gyro_bias for imu in calibrated.imus]
    text = with_imu_calibration(
        robot_source_text(args.robot, robot), mounts, biases, args.write_robot
    )
    with atomic_writer(Path(args.write_robot)) as fh:
        fh.write(text)
    whence = (
        "from --bend"
        if bent
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
