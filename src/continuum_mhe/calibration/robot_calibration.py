"""A robot calibrated from recordings: :func:`calibrate_robot` reads a recording of the
robot straight and still (and, where given, one of it bent in a known plane), makes
``continuum-mhe calibrate --from``'s checks and returns the robot with each IMU's
measured ``mount_rpy`` and ``gyro_bias``, as ``--write-robot`` writes them, beside the
statistics the command prints. A problem is a one-line
:class:`~continuum_mhe.errors.InputError`; what it measured that may not be what was
meant arrives as a :class:`CalibrationWarning`, how it took the readings as a
:class:`CalibrationNote`.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.calibration.at_rest import (
    STILL_ACC_STD,
    STILL_GYRO_STD,
    Calibration,
    bend_yaws,
    calibrate,
    check_rest_mounting,
    creep_at_rest,
    format_report,
    frozen_at_rest,
    gyro_deg_s_at_rest,
    knocks_at_rest,
    motion_at_rest,
    rest_gravity_note,
    rest_gravity_problem,
    rest_tilt_warning,
    rolls_kept,
)
from continuum_mhe.calibration.bend import YawCalibration, bend_plane_warning, tilt_order_warning
from continuum_mhe.errors import (
    InputError,
    UserError,
    expect_type,
    outside_stacklevel,
    real_number,
    time_text,
)
from continuum_mhe.io.inputs import read_recording
from continuum_mhe.io.raw_units import check_gyro_units
from continuum_mhe.io.robot_logs import is_robot_log, refuse_bag_metadata
from continuum_mhe.io.sample_rows import DROPOUT_HINT
from continuum_mhe.io.text_rows import READINGS_READER
from continuum_mhe.model.robot import Robot
from continuum_mhe.stream.protocol import LineFormat


class CalibrationWarning(UserWarning):
    """What a calibration measured that may not be what was meant: readings left out of
    the statistics (dropouts, knocks, a pose that crept), a board upside down, IMUs not
    straight at rest, a gyro whose spread at rest reads as deg/s, a bend's plane that
    looks given in radians, IMUs whose tilts in the bend are not in the robot's order,
    yaws from the bend that read as a bend in another plane. The command line says it as a warning
    (``continuum-mhe: warning: ...``)."""


class CalibrationNote(UserWarning):
    """How a calibration took its readings, where it is not what a reader would assume:
    an accelerometer whose magnitude is more than 2 % from g (a scale or offset error),
    a board's roll that a rest does not show kept from the robot. The command line says it as a note
    (``continuum-mhe: note: ...``)."""


@dataclass(frozen=True)
class RobotCalibration:
    """What :func:`calibrate_robot` measured.

    Attributes:
        robot: the robot given with each IMU's ``mount_rpy`` (roll and pitch from the
            rest; yaw from the bend, else the robot's own) and ``gyro_bias`` (the gyro's
            mean at rest) set, rounded as a robot file written by ``calibrate
            --write-robot`` holds them (0.001 degree, 1e-6 rad/s); None for a tilt
            recording (roll and pitch, without a gyro), which calibrates no mounting.
        rest: each IMU's statistics at rest (its mean and noise per value, its
            ``mount_rpy`` with yaw 0) and the recording's rate.
        yaws: each IMU's yaw from the bend (``bend``), else None.
        report: the calibration as ``continuum-mhe calibrate`` prints it.
    """

    robot: Robot | None
    rest: Calibration
    yaws: tuple[YawCalibration, ...] | None
    report: str


def check_recordings(rest: str, bend: str | None = None, topics: Sequence[str] = ()) -> None:
    """Refuse, in one line, a rest recording ``rest`` or bent one ``bend`` that is not
    there or not a file (a robot log's folder aside: standard input, a pipe, a folder),
    and ``topics`` without a robot log to choose from."""
    for option, name in (("--from", rest), ("--bend", bend)):
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
    logs = [n for n in (rest, bend) if n is not None and is_robot_log(Path(n))]
    if topics and not logs:
        raise InputError(
            "--topic chooses the IMUs of a ROS bag or MCAP file given to --from or --bend"
        )


#: The still robot's spreads the calibration takes: above 0, and at most this much
#: (an accelerometer's, m/s^2: a spread of 1 g is no robot at rest; a gyro's, rad/s:
#: beyond it, degrees); the command's ``--still-acc-std`` and ``--still-gyro-std``.
STILL_ACC_STD_MAX = 10.0
STILL_GYRO_STD_MAX = 5.0


def _check_arguments(
    robot: object, bend_phi_deg: object, acc_std: object, gyro_std: object, topics: object
) -> None:
    """A one-line :class:`~continuum_mhe.errors.UserError` naming the argument of
    :func:`calibrate_robot` that is not what it takes."""
    expect_type("robot", robot, Robot, "a Robot (read_robot(NAME) reads a robot file)")
    if isinstance(topics, (str, bytes)):
        raise UserError(f"topics must be a sequence of topic names, one per IMU, got {topics!r}")
    if bend_phi_deg is not None:
        real_number("bend_phi_deg", bend_phi_deg)  # its range: the bend's own check
    for name, value, most, unit in (
        ("still_acc_std", acc_std, STILL_ACC_STD_MAX, "m/s^2"),
        ("still_gyro_std", gyro_std, STILL_GYRO_STD_MAX, "rad/s"),
    ):
        if value is not None and not 0.0 < real_number(name, value) <= most:
            raise UserError(f"{name} must be above 0 and at most {most:g} {unit}, got {value!r}")


def calibrate_robot(
    robot: Robot,
    rest: str | os.PathLike[str],
    *,
    bend: str | os.PathLike[str] | None = None,
    bend_phi_deg: float | None = None,
    still_acc_std: float = STILL_ACC_STD,
    still_gyro_std: float | None = None,
    degrees: bool = False,
    topics: Sequence[str] = (),
    robot_file: bool = True,
    require_raw: str = "",
) -> RobotCalibration:
    """``robot`` calibrated from ``rest``, a recording of it straight and still (a raw
    or tilt CSV file, or a ROS bag or MCAP file's Imu ``topics``, one per IMU in the
    robot's order), as ``continuum-mhe calibrate --from REST`` calibrates it.

    Args:
        robot: the robot recorded (its IMUs' order, mounting, and each IMU's yaw, kept
            where no bend measures it).
        rest: the recording of the robot straight and still.
        bend: a raw recording of the robot bent slowly in one known plane: each IMU's
            yaw about the tangent (:mod:`continuum_mhe.calibration.bend`).
        bend_phi_deg: that plane, the direction the robot bends towards, degrees (None:
            0, towards base -x); needs ``bend``.
        still_acc_std: largest accelerometer spread (standard deviation per axis,
            m/s^2) of a still robot; for a tilt recording, this over g in rad.
        still_gyro_std: largest gyro spread (rad/s) of a still robot, raw recordings
            only (None: :data:`~continuum_mhe.calibration.at_rest.STILL_GYRO_STD`).
        degrees: a tilt recording's roll and pitch are in degrees (else radians).
        topics: a robot log's Imu topics, one per IMU.
        robot_file: ``robot`` is a robot file's (a refusal of its mounting says to
            change the file), else the command line's ``--mounting``.
        require_raw: where not empty, what needs a raw recording (the command's
            ``--write-robot``): a tilt one is refused for it once it is known still.

    Returns:
        The robot with its measured mounting and gyro biases, and the statistics.

    Raises:
        InputError: a recording that cannot be read, or that is not of the robot
            straight and still (moving, frozen, mounted the other way, too short), or
            a bend that does not give the yaws; the line names the file and the
            likely cause.

    Warns:
        CalibrationWarning: readings left out, a board upside down, IMUs not straight
            at rest, a gyro spread that reads as deg/s, a plane that looks given in
            radians, tilts in the bend out of the IMUs' order, every yaw a quarter or
            half turn from the robot's (a bend in another plane than ``bend_phi_deg``).
        CalibrationNote: an accelerometer whose magnitude is more than 2 % from g (a
            scale or offset error), a roll kept from the robot.
    """
    _check_arguments(robot, bend_phi_deg, still_acc_std, still_gyro_std, topics)
    expect_type("robot_file", robot_file, bool, "True or False")
    expect_type("require_raw", require_raw, str, "what needs a raw recording, or ''")
    source = os.fspath(rest)
    bend_path = None if bend is None else os.fspath(bend)
    check_recordings(source, bend_path, topics)
    if bend_phi_deg is not None and bend_path is None:
        raise InputError("--bend-phi needs --bend BEND.csv")
    try:
        log_topics = tuple(topics) if is_robot_log(Path(source)) else ()
        fmt, t, values = read_recording(source, robot.n_imus, degrees, log_topics)
    except InputError as exc:
        raise _without_skip_bad(exc, "the still robot") from None
    if still_gyro_std is not None and fmt != "raw":
        raise InputError(f"{source}: --still-gyro-std needs a raw recording (this one is {fmt})")
    return calibrate_readings(
        robot,
        source,
        t,
        values,
        fmt,
        bend=bend_path,
        bend_phi_deg=bend_phi_deg,
        still_acc_std=still_acc_std,
        still_gyro_std=still_gyro_std,
        degrees=degrees,
        topics=topics,
        robot_file=robot_file,
        require_raw=require_raw,
    )


def _check_port_gyro_units(source: str, t: FloatArray, values: FloatArray, n_imus: int) -> None:
    """Each IMU's gyro read from the port ``source`` checked for deg/s as ``estimate``
    checks a raw file's and ``live`` a port's (its median rate, and the turn of gravity's
    direction that its rates would make), before the stillness bounds: a still gyro in
    deg/s spreads by its noise in deg/s, which read as rad/s is a motion."""
    for i in range(n_imus):
        block = values[:, 6 * i : 6 * i + 6]
        full = np.isfinite(block).all(axis=1)  # an IMU's unreadable lines left out
        label = source if n_imus == 1 else f"{source}: IMU {i + 1}"
        check_gyro_units(label, block[full, 3:], True, t[full], block[full, :3])


def calibrate_readings(
    robot: Robot,
    source: str,
    t: FloatArray,
    values: FloatArray,
    fmt: LineFormat,
    *,
    bend: str | None = None,
    bend_phi_deg: float | None = None,
    still_acc_std: float = STILL_ACC_STD,
    still_gyro_std: float | None = None,
    degrees: bool = False,
    topics: Sequence[str] = (),
    robot_file: bool = True,
    require_raw: str = "",
    from_port: bool = False,
) -> RobotCalibration:
    """:func:`calibrate_robot` of readings already read: times ``t`` (s) and ``values``
    (n, 6 per IMU raw, n, 2 per IMU tilt: ``fmt``) from ``source`` (a file, or the
    serial port where ``from_port``: its readings are not counted for dropouts, and a
    tilt recording in degrees is the board's to fix)."""
    # what it warns of, said once the calibration holds: a refusal is its one error alone
    held: list[tuple[str, type[Warning]]] = []
    left_out = ""  # said once the calibration holds
    if not from_port:
        missing = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if len(missing):  # an empty field, a zero or impossible reading: a dropout
            left_out = (
                f"{source}: {len(missing)} of {len(t)} row(s) with a reading missing, zero "
                f"or beyond any IMU's range (the first at t = "
                f"{time_text(float(t[missing[0]]))} s): that IMU's reading is left out of its "
                "mean and noise there"
            )
    gyro_std = STILL_GYRO_STD if still_gyro_std is None else still_gyro_std
    if unit := rest_gravity_problem(values, fmt, robot.n_imus):
        raise InputError(f"{source}: {unit}")
    if scaled := rest_gravity_note(values, fmt, robot.n_imus):
        held.append((f"{source}: {scaled}", CalibrationNote))
    if from_port and fmt == "raw":  # a file's units are checked as it is read
        _check_port_gyro_units(source, t, values, robot.n_imus)
    fix = "the board must send radians" if from_port else "pass --degrees"
    moved = motion_at_rest(
        values, fmt, robot.n_imus, still_acc_std, gyro_std, None if degrees else fix
    )
    if moved:
        raise InputError(f"{source}: {moved}")
    frozen = frozen_at_rest(t, values, robot.n_imus) if fmt == "raw" else None
    if frozen:
        raise InputError(f"{source}: {frozen}")
    if require_raw and fmt != "raw":
        raise InputError(f"{source}: {require_raw} needs a raw recording (this one is {fmt})")
    flipped = check_rest_mounting(source, values, robot, robot_file, fmt)
    if flipped:  # raw: a board upside down, said (tilt ones are refused or left alone)
        if not bend:  # gravity does not tell a board turned over about x from one about y
            flipped += (
                "; its yaw is the robot file's, right for a board turned over about its x "
                "axis: one turned over about its y axis reads gravity alike and lies 180 "
                "degrees from that yaw (its section's bending plane turned half a turn): a "
                "bend in a known plane (--bend) measures it"
            )
        held.append((f"{source}: {flipped}", CalibrationWarning))
    knocks: list[str] = []
    if fmt == "raw":
        values, knocks = knocks_at_rest(t, values, robot.n_imus, still_acc_std, gyro_std)
        knocks += creep_at_rest(values, robot.n_imus)
    try:
        cal = calibrate(t, values, fmt, robot.n_imus, robot.mounting)
    except InputError as exc:  # name the recording
        raise InputError(f"{source}: {exc}") from None
    if left_out:
        held.append((left_out, CalibrationWarning))
    for knock in knocks:
        held.append((f"{source}: {knock}", CalibrationWarning))
    if fmt == "raw":
        for deg_s in gyro_deg_s_at_rest(cal):
            held.append((f"{source}: {deg_s}", CalibrationWarning))
    file_yaws = [imu.mount_rpy[2] for imu in robot.imus]
    tilted = rest_tilt_warning(cal, robot.mounting, fix, file_yaws)
    if tilted:
        held.append((f"{source}: {tilted}", CalibrationWarning))
    if fmt == "raw":
        cal, kept = rolls_kept(cal, [imu.mount_rpy[0] for imu in robot.imus])
        for i in kept:
            rpy = cal.imus[i - 1].mount_rpy
            assert rpy is not None
            roll_from = (
                f"the robot file's roll ({rpy[0]:g} degrees) is kept"
                if robot_file
                else f"its roll is taken as {rpy[0]:g} (no robot file gives one)"
            )
            held.append(
                (
                    f"{source}: IMU {i}'s x axis lies within {90 - abs(rpy[1]):.1f} degrees of "
                    f"gravity at rest (pitch {rpy[1]:.2f} degrees): its roll turns it about "
                    f"gravity, which a rest does not show, so {roll_from} (--bend measures the "
                    "turn about gravity)",
                    CalibrationNote,
                )
            )
    bent = None
    if bend:
        phi = 0.0 if bend_phi_deg is None else bend_phi_deg
        if radians_like_degrees(phi):
            held.append(
                (
                    f"--bend-phi {phi:g} is in degrees: radians? ({phi:g} rad is "
                    f"{math.degrees(phi):.4g} degrees: give --bend-phi {math.degrees(phi):.4g})",
                    CalibrationWarning,
                )
            )
        try:
            bend_topics = tuple(topics) if is_robot_log(Path(bend)) else ()
            bent = (bend, phi, bend_yaws(bend, phi, cal, robot, bend_topics))
        except InputError as exc:
            raise _without_skip_bad(exc, "the bent robot") from None
        places = [(imu.section, imu.at) for imu in robot.imus]
        reach = [s.theta_max for s in robot.sections]
        if order := tilt_order_warning(places, bent[2], reach):
            held.append((f"{bend}: {order}", CalibrationWarning))
        if plane := bend_plane_warning(bent[2], file_yaws, phi, robot_file):
            held.append((f"{bend}: {plane}", CalibrationWarning))
    report = format_report(cal, source, bent, file_yaws, robot.mounting)
    yaws = None if bent is None else tuple(bent[2])
    for message, category in held:
        warnings.warn(message, category, stacklevel=outside_stacklevel())
    return RobotCalibration(_calibrated(robot, cal, yaws), cal, yaws, report)


def _calibrated(
    robot: Robot, cal: Calibration, yaws: tuple[YawCalibration, ...] | None
) -> Robot | None:
    """``robot`` with each IMU's measured ``mount_rpy`` (the yaw from ``yaws``, else its
    own) and gyro bias, rounded as a written robot file holds them; None for a tilt
    calibration."""
    if cal.fmt != "raw":
        return None
    imus = []
    for i, (place, imu) in enumerate(zip(robot.imus, cal.imus)):
        assert imu.mount_rpy is not None  # raw
        roll, pitch, _ = imu.mount_rpy
        yaw = yaws[i].yaw_deg if yaws else place.mount_rpy[2]
        gx, gy, gz = (_written(float(v), 6) for v in imu.mean[3:6])
        mount = (_written(roll, 3), _written(pitch, 3), _written(yaw, 3))
        imus.append(replace(place, mount_rpy=mount, gyro_bias=(gx, gy, gz)))
    return replace(robot, imus=tuple(imus))


def _written(value: float, decimals: int) -> float:
    """``value`` as a robot file written by ``calibrate --write-robot`` holds it
    (:func:`~continuum_mhe.io.robot_file.with_imu_calibration`): rounded, no -0.0."""
    return round(value, decimals) + 0.0


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
