"""``continuum-mhe calibrate``: what docs/hardware.md asks the user to measure, with
the robot straight and still (checked: :func:`motion_at_rest`), per IMU: the
accelerometer's mean and noise per axis, the gyro's bias (what remains after the
firmware's start-up bias) and noise, the sample rate achieved, and the sensor mounting
that makes the straight robot read ``theta = 0`` (``--mount-rpy`` / the robot file's
``mount_rpy``). From the port (``--port``) or a recording (``--from RAW.csv``, e.g.
written by ``live --record``). With ``--bend BEND.csv``, a raw recording of the robot
bent slowly in a known plane, also each IMU's yaw about the tangent
(:mod:`continuum_mhe.calibration.bend`) and so the full ``mount_rpy``.
"""

from __future__ import annotations

import math
import queue
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.calibration.bend import YawCalibration, yaws_from_bend
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.extras import MissingExtraError
from continuum_mhe.io.csv_files import MS_LIKE_STEP_S, TOO_FAST_STEP_S
from continuum_mhe.io.input_options import MOUNTING_FLIPPED, flipped_mounting
from continuum_mhe.io.inputs import read_recording
from continuum_mhe.io.raw_imu import csv_input_kind, mount_rotation
from continuum_mhe.io.robot_logs import is_robot_log
from continuum_mhe.model.imu import STANDARD_GRAVITY, Mounting
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import FREEZE_MIN_SAMPLES, FREEZE_S
from continuum_mhe.stream.clock import DeviceClock, MicrosecondsCheck
from continuum_mhe.stream.protocol import (
    VALUES_PER_IMU,
    GarbledLine,
    LineFormat,
    RawLimits,
    field_count_hint,
    line_fields,
    parse_line,
)
from continuum_mhe.stream.reader import Event, SerialReader, open_port, port_hint

#: stillness bounds of a rest recording, per axis, on the standard deviation of the
#: samples (the spread). The firmware's MPU9250 (accelerometer low-pass 44.8 Hz, gyro
#: 41 Hz) is within about 0.025 m/s^2 and 0.0015 rad/s at rest (the shipped rest
#: recordings: 0.02 m/s^2 and 0.0018 rad/s); the bounds are 8 and 30 times that, and a
#: robot moving by a degree (rms) reaches the accelerometer's. The gyro's mean is not
#: a sign of motion: it is the bias that calibrate measures. The defaults of
#: ``--still-acc-std`` and ``--still-gyro-std``: a noisier IMU raises them.
STILL_ACC_STD = 0.2  # m/s^2 (0.2 / 9.81 rad = 1.2 deg of tilt)
STILL_GYRO_STD = 0.05  # rad/s (2.9 deg/s)
STILL_TILT_STD = STILL_ACC_STD / STANDARD_GRAVITY  # rad, for tilt (roll, pitch) recordings


@dataclass(frozen=True)
class ImuCalibration:
    """Statistics of one IMU at rest (raw: m/s^2 and rad/s; tilt: rad).

    Attributes:
        mean, std: per value (raw: ``ax,ay,az,gx,gy,gz``; tilt: ``roll,pitch``).
        mount_rpy: raw only: ``(roll, pitch, 0)`` degrees that rotate the mean
            accelerometer vector onto the straight robot's gravity reading.
    """

    mean: FloatArray
    std: FloatArray
    mount_rpy: tuple[float, float, float] | None


@dataclass(frozen=True)
class Calibration:
    """A calibration: ``n`` samples over ``span_s`` s of device time, one entry per IMU."""

    fmt: LineFormat
    n: int
    span_s: float
    median_period_s: float
    longest_step_s: float
    imus: list[ImuCalibration]

    @property
    def rate_hz(self) -> float:
        return (self.n - 1) / self.span_s if self.span_s > 0 else math.nan


def mounting_from_gravity(mean_acc: FloatArray, mounting: Mounting) -> tuple[float, float, float]:
    """``(roll, pitch, 0)`` degrees with ``Ry(pitch) Rx(roll) m`` along the straight
    robot's reading ``(0, 0, +|m|)`` (base z up) or ``(0, 0, -|m|)`` (z down); yaw is
    invisible to gravity."""
    m = np.asarray(mean_acc, dtype=float) * (1.0 if mounting == "z-up" else -1.0)
    roll = math.atan2(m[1], m[2])
    pitch = math.atan2(-m[0], math.hypot(m[1], m[2]))
    return (math.degrees(roll), math.degrees(pitch), 0.0)


#: A board's roll is taken as unseen at rest where gravity's component across its x axis
#: (the roll turns it about that axis) is so small that its mean's noise turns the roll
#: by more than this (deg): a board on its side, its x axis within a degree or so of
#: gravity.
ROLL_UNSEEN_DEG = 10.0


def rolls_kept(cal: Calibration, file_rolls: Sequence[float]) -> tuple[Calibration, list[int]]:
    """``cal`` with the roll of each IMU whose roll gravity does not show (its x axis
    within a hair of vertical, so that the mean's noise turns the measured roll by over
    :data:`ROLL_UNSEEN_DEG`) taken from ``file_rolls`` (deg, the robot file's), and
    those IMUs (1-based): about gravity a rest recording sees no turn, and such a
    board's roll is one."""
    imus, kept = [], []
    for i, imu in enumerate(cal.imus):
        if imu.mount_rpy is None:
            imus.append(imu)
            continue
        across = float(np.hypot(imu.mean[1], imu.mean[2]))  # gravity's part the roll turns
        noise = float(np.hypot(imu.std[1], imu.std[2])) / math.sqrt(max(cal.n, 1))
        if noise <= across * math.radians(ROLL_UNSEEN_DEG):
            imus.append(imu)
            continue
        _, pitch, yaw = imu.mount_rpy
        imus.append(replace(imu, mount_rpy=(float(file_rolls[i]), pitch, yaw)))
        kept.append(i + 1)
    return replace(cal, imus=imus), kept


def check_rest_mounting(
    source: str, values: FloatArray, robot: Robot, robot_file: bool, fmt: LineFormat = "raw"
) -> str | None:
    """Refuse, in one line naming ``mounting``, readings at rest (n, 6 n_imus raw, or
    n, 2 n_imus tilt: ``fmt``) in
    which gravity puts most IMUs (every one, or more than half of two or more) more than
    the estimate's own threshold (:data:`~continuum_mhe.io.input_options.MOUNTING_FLIPPED`)
    from their reading on the straight robot as the robot file describes it (the robot's
    ``mounting``, each IMU's ``mount_rpy``): the robot is mounted the other way (a
    hanging robot described as standing, its tip board upside down, reads so in all but
    that board; calibrated, every board but one got a roll of 180 degrees and the
    estimates were mirrored, every row ``ok``). The line says to change the robot file's
    ``mounting`` (``robot_file``), else ``--mounting``. Fewer such IMUs get a warning,
    returned: each is calibrated as a board mounted upside down, which a robot mounted
    the other way reads as well; a board declared upside down (its ``mount_rpy``) is
    not one of them. Tilt readings are the disks' (``mount_rpy`` does not apply to
    them, and no board is calibrated): the refusal names the mounting alone, and fewer
    such IMUs are left to ``estimate``'s own check (None)."""
    up = 1.0 if robot.mounting == "z-up" else -1.0
    angles = []
    for i, place in enumerate(robot.imus):
        if fmt != "raw":  # roll and pitch in rad, about their circular means
            tilt = values[:, 2 * i : 2 * i + 2]
            tilt = tilt[np.all(np.isfinite(tilt), axis=1)]
            if not len(tilt):
                return None
            roll, pitch = angle_mean_std(tilt)[0]
            cos = up * math.cos(float(roll)) * math.cos(float(pitch))
            angles.append(math.acos(min(1.0, max(-1.0, cos))))
            continue
        acc = values[:, 6 * i : 6 * i + 3]
        acc = acc[np.all(np.isfinite(acc), axis=1)]
        if not len(acc):
            return None
        m = acc.mean(axis=0)
        expected = mount_rotation(place.mount_rpy).T @ np.array([0.0, 0.0, up])
        cos = float(m @ expected / max(float(np.linalg.norm(m)), 1e-12))
        angles.append(math.acos(min(1.0, max(-1.0, cos))))
    flipped = [i for i, a in enumerate(angles) if a > MOUNTING_FLIPPED]
    if not flipped:
        return None
    other, pose = flipped_mounting(robot.mounting)
    fix = f'set mounting = "{other}" in the robot file' if robot_file else f"--mounting {other}"
    shown = [angles[i] for i in flipped]
    lo, hi = (round(math.degrees(a)) for a in (min(shown), max(shown)))
    spread = f"{lo}" if lo == hi else f"{lo} to {hi}"
    if fmt != "raw":
        if 2 * len(flipped) <= len(angles):
            return None
        who = ", ".join(str(i + 1) for i in flipped)
        imus = "every IMU" if len(flipped) == len(angles) else f"IMUs {who} (of {len(angles)})"
        raise InputError(
            f"{source}: mounting: the robot is described as {robot.mounting}, but at rest "
            f"gravity puts {imus} {spread} degrees from where that mounting puts it: the "
            f"robot {pose}? {fix}"
        )
    if len(flipped) == len(angles):
        boards, each = (
            ("its board is", "its") if len(angles) == 1 else ("its boards are", "each one's")
        )
        raise InputError(
            f"{source}: mounting: the robot is described as {robot.mounting}, but at rest "
            f"gravity puts every IMU {spread} degrees from where that mounting puts it: the "
            f"robot {pose}? {fix}; or, where the robot is mounted as described, {boards} "
            f"upside down on it: give {each} mount_rpy (a roll of 180 degrees) in the robot file"
        )
    who = " and ".join(", ".join(str(i + 1) for i in flipped).rsplit(", ", 1))
    imus = f"IMU {who}" if len(flipped) == 1 else f"IMUs {who}"
    if 2 * len(flipped) > len(angles):
        raise InputError(
            f"{source}: mounting: the robot is described as {robot.mounting}, but at rest "
            f"gravity puts {imus} (of {len(angles)}) {spread} degrees from where that "
            f"mounting puts them: the robot {pose}? {fix} (a board then upside down on it reads "
            "so, the others not); or, where the robot is mounted as described, give each "
            "upside-down board's mount_rpy (a roll of 180 degrees) in the robot file"
        )
    reads, taken = (
        ("reads", "is calibrated as a board")
        if len(flipped) == 1
        else ("read", "are calibrated as boards")
    )
    return (
        f"{imus} (of {len(angles)}) {reads} gravity {spread} degrees from where mounting = "
        f'"{robot.mounting}" puts it, and {taken} mounted upside down; if instead the robot '
        f"{pose}, {fix} and calibrate again (a mount_rpy roll of 180 degrees in the robot "
        "file says a board is upside down, and silences this)"
    )


def frozen_at_rest(t: FloatArray, values: FloatArray, n_imus: int) -> str | None:
    """Why a raw rest recording ``values`` (n, 6 n_imus) at times ``t`` (s) holds a frozen
    IMU, or None: one whose six values repeat exactly for longer than
    :data:`~continuum_mhe.settings.FREEZE_S` and over at least
    :data:`~continuum_mhe.settings.FREEZE_MIN_SAMPLES` samples (a still IMU's noise
    changes its raw readings every sample; tilt angles of an attitude output can repeat
    at rest, so they are not judged). Exact repeats only, where ``estimate``'s
    ``--freeze`` allows :data:`~continuum_mhe.settings.FREEZE_TOLERANCE` of the noise
    model's standard deviation: a rest recording is where that noise is measured."""
    for i in range(n_imus):
        block = values[:, 6 * i : 6 * i + 6]
        repeats = np.concatenate([[False], np.all(block[1:] == block[:-1], axis=1)])
        start, best = 0, (0, 0)  # the longest run of one reading: first and last sample
        for j in range(1, len(repeats)):
            if not repeats[j]:
                start = j
            elif j - start > best[1] - best[0]:
                best = (start, j)
        samples = best[1] - best[0] + 1
        span = float(t[best[1]] - t[best[0]]) if samples > 1 else 0.0
        if samples >= FREEZE_MIN_SAMPLES and span > FREEZE_S:
            return (
                f"IMU {i + 1} repeats one reading exactly for {samples} samples ({span:.3g} s "
                f"from t = {time_text(float(t[best[0]]))} s): a frozen sensor, whose noise and "
                "offsets would be the freeze's; record the rest again"
            )
    return None


#: A rest in which every IMU reads more than this (deg) from the straight robot's
#: gravity direction gets a warning: a robot not straight, or a base not level, reads
#: so in every IMU, where IMUs mounted tilted on their disks read so one by one.
REST_TILT_WARN_DEG = 5.0
#: A tilt rest in which every IMU, its angles read as radians, tilts more than this
#: (deg), and read as degrees less than :data:`REST_TILT_WARN_DEG`, gets a warning that
#: says degrees: no IMU is mounted so far off straight.
DEGREES_LIKE_TILT_DEG = 30.0
#: A raw rest in which an IMU reads more than this (deg) from the straight robot's
#: gravity direction, and more than :data:`BOARD_POSE_DEG` from a board on its side (90)
#: or upside down (180), gets a warning, whatever the others read: a board is mounted
#: flat, on its side or upside down, and a robot left bent at rest reads angles between.
FAR_OFF_MOUNT_DEG = 30.0
BOARD_POSE_DEG = 15.0


def common_lean(
    cal: Calibration, yaws_deg: Sequence[float], first: int = 0
) -> tuple[float, list[float]]:
    """The lean that the flat boards of a raw calibration ``cal`` (those within
    :data:`FAR_OFF_MOUNT_DEG` of the straight robot's gravity direction) from IMU
    ``first`` (from 0, in the robot file's order, base to tip) on share: each one's
    gravity direction, its horizontal part turned about the backbone by its yaw
    ``yaws_deg`` (the robot file's, degrees) into the backbone's frame, averaged; as the
    mean's angle (deg) and each board's lean along the mean's direction (deg). A base not
    level, or a section bent at rest, leans every board after it the same way by as
    much; boards tilted on their disks lean each its own way, and their mean stays
    small. ``(0.0, [])`` with fewer than two such boards."""
    leans = []
    for imu, yaw in zip(cal.imus[first:], yaws_deg[first:]):
        if imu.mount_rpy is None:
            return 0.0, []
        roll, pitch = (math.radians(a) for a in imu.mount_rpy[:2])
        if math.degrees(math.acos(min(1.0, math.cos(roll) * math.cos(pitch)))) > FAR_OFF_MOUNT_DEG:
            continue  # a board on its side or upside down: its axes are not the backbone's
        m = np.asarray(imu.mean[:3], dtype=float)
        m = m / max(float(np.linalg.norm(m)), 1e-12)
        c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        leans.append(np.array([c * m[0] - s * m[1], s * m[0] + c * m[1]]))
    if len(leans) < 2:
        return 0.0, []
    mean = np.mean(leans, axis=0)
    size = float(np.linalg.norm(mean))
    if size == 0.0:
        return 0.0, [0.0] * len(leans)
    along = [math.degrees(math.asin(max(-1.0, min(1.0, float(v @ mean) / size)))) for v in leans]
    return math.degrees(math.asin(min(1.0, size))), along


def rest_tilt_warning(
    cal: Calibration,
    mounting: Mounting = "z-up",
    degrees_fix: str = "pass --degrees",
    yaws_deg: Sequence[float] | None = None,
) -> str | None:
    """A warning where every IMU of a calibration ``cal`` reads more than
    :data:`REST_TILT_WARN_DEG` from the straight robot's gravity direction (``mounting``
    says which), or None: for two or more IMUs of a raw one (calibrate takes each tilt
    as its IMU's mounting, which a bent robot or a tilted base at rest puts into every
    estimate; one IMU alone cannot tell its own tilted mounting from a tilted base), and
    for any IMU of a raw one that reads more than :data:`FAR_OFF_MOUNT_DEG` from it and
    is not a board on its side or upside down (:data:`BOARD_POSE_DEG`); with the IMUs'
    yaws ``yaws_deg`` (the robot file's), also where two or more flat boards lean the
    same way (:func:`common_lean`) by over :data:`REST_TILT_WARN_DEG` on average, each
    by over half of it along that direction (a bent robot or a base not level whose
    lean some boards' own tilts on their disks hide from the first test);
    and where every IMU of a tilt one reads more than :data:`DEGREES_LIKE_TILT_DEG`,
    but its angles, read as degrees, would each lie within :data:`REST_TILT_WARN_DEG`
    (degrees given for radians: ``degrees_fix`` says what to do)."""
    up = 1.0 if mounting == "z-up" else -1.0  # a straight robot's cos(roll) cos(pitch)

    def off_straight(roll: float, pitch: float) -> float:
        """Degrees from the straight robot's gravity direction, roll and pitch in rad."""
        return math.degrees(math.acos(max(-1.0, min(1.0, up * math.cos(roll) * math.cos(pitch)))))

    if cal.fmt != "raw":
        means = [(float(imu.mean[0]), float(imu.mean[1])) for imu in cal.imus]
        as_radians = [off_straight(r, p) for r, p in means]
        as_degrees = [off_straight(math.radians(r), math.radians(p)) for r, p in means]
        if min(as_radians) <= DEGREES_LIKE_TILT_DEG or max(as_degrees) > REST_TILT_WARN_DEG:
            return None
        each = ", ".join(f"IMU {i + 1} {a:.1f}" for i, a in enumerate(as_radians))
        return (
            f"every IMU reads more than {DEGREES_LIKE_TILT_DEG:g} degrees from the straight "
            f"robot's gravity direction ({each} degrees) if its roll and pitch are in "
            f"radians, and within {REST_TILT_WARN_DEG:g} if they are in degrees: degrees? "
            f"{degrees_fix}"
        )
    tilts = []
    for imu in cal.imus:
        if imu.mount_rpy is None:
            return None
        roll, pitch = (math.radians(a) for a in imu.mount_rpy[:2])
        tilts.append(math.degrees(math.acos(min(1.0, math.cos(roll) * math.cos(pitch)))))
    # each IMU's angle from the nearest pose a board is mounted in (flat, on its side,
    # upside down): a robot bent, or its base not level, turns every board off its pose
    off_pose = [min(a, abs(a - 90.0), abs(a - 180.0)) for a in tilts]
    if len(tilts) < 2 or min(off_pose) <= REST_TILT_WARN_DEG:
        far = [
            (i + 1, a)
            for i, a in enumerate(tilts)
            if a > FAR_OFF_MOUNT_DEG and min(abs(a - 90.0), abs(a - 180.0)) > BOARD_POSE_DEG
        ]
        if not far:
            return _common_lean_warning(cal, yaws_deg)
        who = ", ".join(str(i) for i, _ in far)
        angles = ", ".join(f"{a:.1f}" for _, a in far)
        reads = f"IMU {who} reads" if len(far) == 1 else f"IMUs {who} read"
        return (
            f"{reads} {angles} degrees from the straight robot's gravity direction, which "
            "mount_rpy takes as its mounting: a board is mounted flat, on its side or upside "
            "down, seldom in between; was the robot straight and its "
            "base level at rest? If not, every estimate is off by as much; record the rest "
            "again (an IMU that is mounted so is calibrated right)"
        )
    each = ", ".join(f"IMU {i + 1} {a:.1f}" for i, a in enumerate(off_pose))
    posed = off_pose != tilts  # a board on its side or upside down among them
    pose = "; a board on its side or upside down from that pose" if posed else ""
    return (
        f"every IMU reads more than {REST_TILT_WARN_DEG:g} degrees from the straight robot's "
        f"gravity direction ({each} degrees{pose}), and mount_rpy takes that as its mounting: "
        "was the robot straight and its base level at rest? If not, every estimate is off "
        "by as much; record the rest again (IMUs mounted tilted on their disks are "
        "calibrated right)"
    )


def _common_lean_warning(cal: Calibration, yaws_deg: Sequence[float] | None) -> str | None:
    """:func:`rest_tilt_warning`'s warning of a lean that the boards share, or None."""
    if yaws_deg is None:
        return None
    # every board, then the boards from IMU 2, 3, ... on: a section bent at rest leans
    # the boards after it, not those before
    for first in range(len(cal.imus) - 1):
        lean, along = common_lean(cal, yaws_deg, first)
        if lean <= REST_TILT_WARN_DEG or min(along, default=0.0) <= REST_TILT_WARN_DEG / 2:
            continue
        each = ", ".join(f"{a:.1f}" for a in along)
        n = len(cal.imus)
        joined = "and" if n - first == 2 else "to"
        boards = (
            "the IMUs' gravity directions"
            if first == 0
            else f"the gravity directions of IMUs {first + 1} {joined} {n}"
        )
        section = (
            ""
            if first == 0
            else f" (the IMUs before IMU {first + 1} do not: a section "
            f"bent between IMU {first} and IMU {first + 1}?)"
        )
        return (
            f"{boards} lean {lean:.1f} degrees the same way on average, "
            f"turned into the backbone's frame by the robot file's yaws (each board {each} "
            f"degrees that way){section}, and mount_rpy takes that as their mountings: was "
            "the robot straight and its base level at rest? A base not level, or a section "
            "bent, leans every board after it the same way, where boards tilted on their "
            "disks lean each its own way; if it was not, every estimate is off by as much: "
            "record the rest again"
        )
    return None


def angle_mean_std(angles: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per column of ``angles`` (n, k) rad: the circular mean (in (-pi, pi]) and the
    standard deviation of the angles' wrapped differences from it (``ddof=1``)."""
    mean = np.arctan2(np.sin(angles).mean(axis=0), np.cos(angles).mean(axis=0))
    spread = np.angle(np.exp(1j * (angles - mean)))
    return mean, spread.std(axis=0, ddof=1)


#: The least time at rest calibration takes, s, and valid samples of each IMU.
MIN_REST_S = 0.5
MIN_REST_SAMPLES = 20


def calibrate(
    t: FloatArray, values: FloatArray, fmt: LineFormat, n_imus: int, mounting: Mounting
) -> Calibration:
    """Statistics of samples at rest: ``t`` (n,) s, ``values`` (n, k * n_imus); a
    one-line :class:`InputError` for under :data:`MIN_REST_S` of them (times whose
    median step looks like milliseconds, :data:`~continuum_mhe.io.csv_files.
    MS_LIKE_STEP_S`, judged as milliseconds) or an IMU with under
    :data:`MIN_REST_SAMPLES` valid ones (its mean and spread would be noise)."""
    span = float(t[-1] - t[0]) if len(t) else 0.0
    step = float(np.median(np.diff(t))) if len(t) > 1 else math.inf
    # times that look like milliseconds read as seconds (warned of): their span in s
    in_ms = len(t) > 1 and step > MS_LIKE_STEP_S
    if len(t) < 2 or (span / 1000.0 if in_ms else span) < MIN_REST_S:
        if in_ms:
            cause = f" (its times look like milliseconds: {span / 1000.0:.3g} s read so)"
        elif step < TOO_FAST_STEP_S:  # the span is short because the times are in another unit
            cause = (
                f": its samples are {step:.2g} s apart, faster than any IMU: times in "
                "another unit (seconds in a t_ms column?)"
            )
        else:
            cause = " (a few seconds)"
        raise InputError(
            f"{len(t)} sample(s) over {span:.3g} s: calibration needs the robot still for "
            f"at least {MIN_REST_S:g} s{cause}"
        )
    k = VALUES_PER_IMU[fmt]
    steps = np.diff(t)
    imus = []
    for i in range(n_imus):
        block = values[:, k * i : k * (i + 1)]
        block = block[np.all(np.isfinite(block), axis=1)]
        if len(block) < MIN_REST_SAMPLES:
            raise InputError(
                f"IMU {i + 1}: {len(block)} valid sample(s); calibration needs at least "
                f"{MIN_REST_SAMPLES} of each IMU"
            )
        if fmt == "raw":
            mean, std = block.mean(axis=0), block.std(axis=0, ddof=1)
        else:  # angles: roll near +-pi (a hanging robot) would average to about 0
            mean, std = angle_mean_std(block)
        rpy = mounting_from_gravity(mean[:3], mounting) if fmt == "raw" else None
        imus.append(ImuCalibration(mean, std, rpy))
    return Calibration(
        fmt, len(t), float(t[-1] - t[0]), float(np.median(steps)), float(steps.max()), imus
    )


#: A raw sample at rest that leaves its axis's median by more than this many times the
#: axis's noise (1.4826 times the median absolute deviation, at least
#: :data:`KNOCK_NOISE_FLOOR` of the stillness bound) is a knock: Gaussian noise gets
#: there about once in 1e15 samples.
KNOCK_SIGMAS = 8.0
#: The least noise a knock is judged against, as a fraction of the axis's stillness
#: bound (an axis quantised to one value has no spread to judge by).
KNOCK_NOISE_FLOOR = 0.02
#: Knocks on more than this share of an IMU's samples are left in: not a knock but the
#: readings' own scatter (a vibrating bench), which the stillness bounds judge.
KNOCK_SHARE_MAX = 0.05
#: After a knock the robot may rest in another pose: an IMU whose gravity direction
#: before its first knock and after its last one are more than this apart (deg), and
#: more than :data:`SETTLE_SIGMAS` standard errors of that difference, gets the warning
#: that its mounting is a mix of the two poses.
SETTLE_DEG = 0.2
SETTLE_SIGMAS = 6.0


def knocks_at_rest(
    t: FloatArray,
    values: FloatArray,
    n_imus: int,
    acc_std: float = STILL_ACC_STD,
    gyro_std: float = STILL_GYRO_STD,
) -> tuple[FloatArray, list[str]]:
    """The raw samples ``values`` (n, 6 * n_imus) at ``t`` (n,) s with each IMU's
    knocks left out (NaN), and one line per IMU that had some: a sample with an axis
    beyond :data:`KNOCK_SIGMAS` times that axis's noise from its median, on at most
    :data:`KNOCK_SHARE_MAX` of the IMU's samples (a knock that the stillness bounds
    ``acc_std`` m/s^2 and ``gyro_std`` rad/s let pass would move the means: a gyro's
    bias most)."""
    out = values.copy()
    said = []
    bounds = np.array([acc_std] * 3 + [gyro_std] * 3)
    for i in range(n_imus):
        block = values[:, 6 * i : 6 * (i + 1)]
        valid = np.all(np.isfinite(block), axis=1)
        if valid.sum() < MIN_REST_SAMPLES:
            continue
        median = np.median(block[valid], axis=0)
        noise = 1.4826 * np.median(np.abs(block[valid] - median), axis=0)
        noise = np.maximum(noise, KNOCK_NOISE_FLOOR * bounds)
        knocked = valid & np.any(np.abs(block - median) > KNOCK_SIGMAS * noise, axis=1)
        count = int(knocked.sum())
        if not count or count > KNOCK_SHARE_MAX * valid.sum():
            continue
        out[knocked, 6 * i : 6 * (i + 1)] = np.nan
        at = t[knocked]
        said.append(
            f"IMU {i + 1}: {count} of {int(valid.sum())} sample(s) from t = "
            f"{time_text(float(at[0]))} to {time_text(float(at[-1]))} s left out of its means "
            f"and noise: a reading more than {KNOCK_SIGMAS:g} times its axis's noise from "
            "the rest (a knock?)" + _settled(block, valid, knocked, float(np.median(noise[:3])))
        )
    return out, said


def pose_turn_deg(before: FloatArray, after: FloatArray, noise: float) -> float | None:
    """The angle (deg) between the mean accelerometer vectors of the samples ``before``
    and ``after`` (each (m, 3), m/s^2), where it exceeds :data:`SETTLE_DEG` and
    :data:`SETTLE_SIGMAS` standard errors of that difference (``noise``: the
    accelerometer's noise per axis, m/s^2); else None: the IMU rests in one pose."""
    a, b = before.mean(axis=0), after.mean(axis=0)
    g = max(float(np.linalg.norm(a)), 1e-12)
    cos = float(a @ b) / max(g * float(np.linalg.norm(b)), 1e-12)
    angle = math.degrees(math.acos(min(1.0, max(-1.0, cos))))
    error = math.degrees(noise / g * math.sqrt(1.0 / len(before) + 1.0 / len(after)))
    return angle if angle > max(SETTLE_DEG, SETTLE_SIGMAS * error) else None


def _settled(block: FloatArray, valid: FloatArray, knocked: FloatArray, noise: float) -> str:
    """``""``, or what to add to a knock's warning where one IMU's samples ``block``
    (n, 6) rest in another pose after its knocks than before them: the angle between the
    mean accelerometer vectors of the ``valid`` samples before the first ``knocked`` one
    and after the last, beyond :data:`SETTLE_DEG` and :data:`SETTLE_SIGMAS` standard
    errors (``noise``: the accelerometer's noise per axis, m/s^2)."""
    first, last = np.flatnonzero(knocked)[[0, -1]]
    before = block[: int(first)][valid[: int(first)], :3]
    after = block[int(last) + 1 :][valid[int(last) + 1 :], :3]
    if len(before) < MIN_REST_SAMPLES or len(after) < MIN_REST_SAMPLES:
        return ""
    angle = pose_turn_deg(before, after, noise)
    if angle is None:
        return ""
    return (
        f"; after it the IMU rests {angle:.2f} degrees from its pose before it: the robot "
        "settled in another pose, and the mounting is a mix of the two; record the rest again"
    )


def creep_at_rest(values: FloatArray, n_imus: int) -> list[str]:
    """One line per IMU whose raw samples ``values`` (n, 6 * n_imus; knocks left out as
    NaN) turn while their spreads pass as still: the angle between the mean
    accelerometer vectors of the first and the last third of its valid samples beyond
    :data:`SETTLE_DEG` and :data:`SETTLE_SIGMAS` standard errors of that difference (the
    accelerometer's noise from each third's spread). A robot that creeps through a rest
    recording puts its motion's mean rate into the gyro bias and its mean tilt into the
    mounting; the stillness bounds judge each axis's spread, which a slow, steady turn
    stays within. An IMU with samples left out (a knock: :func:`knocks_at_rest`, whose
    warning compares the poses before and after it) is not judged here."""
    said = []
    for i in range(n_imus):
        acc = values[:, 6 * i : 6 * i + 3]
        if not np.all(np.isfinite(acc)):
            continue
        third = len(acc) // 3
        if third < MIN_REST_SAMPLES:
            continue
        first, last = acc[:third], acc[-third:]
        noise = float(np.median(np.concatenate([first.std(axis=0), last.std(axis=0)])))
        angle = pose_turn_deg(first, last, noise)
        if angle is not None:
            said.append(
                f"IMU {i + 1}'s gravity direction turned by {angle:.2f} degrees from the "
                "first third of the rest to the last, slowly enough to pass as still: the "
                "robot crept (its gyro bias and mounting take in the motion: hold it still "
                "and record the rest again), or the accelerometer drifted as it warmed up "
                "(record after a few minutes powered)"
            )
    return said


#: A gyro spread this many times its bound, with every accelerometer still, reads as a
#: gyro in deg/s: a MEMS gyro's noise at rest is a few hundredths of a deg/s to half a
#: deg/s, which read as rad/s is many times :data:`STILL_GYRO_STD`.
DEG_S_SPREAD_RATIO = 3.0


def gyro_deg_s_at_rest(cal: Calibration) -> list[str]:
    """What to say of each IMU of a raw calibration ``cal`` whose gyro spread beyond
    :data:`STILL_GYRO_STD` (a raised ``--still-gyro-std`` let it pass) while its
    accelerometer stayed within :data:`STILL_ACC_STD`: a MEMS gyro's noise in deg/s
    (0.05 to 0.3), read as rad/s, spreads so, and its mean, the ``gyro_bias`` written,
    is then 57 times too large. Below :data:`DEG_S_SPREAD_RATIO` times the bound the
    refusal cannot tell a noisy gyro from one in deg/s, and says to raise the bound."""
    said = []
    for i, imu in enumerate(cal.imus, start=1):
        gyro, acc = imu.std[3:6], imu.std[:3]
        j = int(np.argmax(gyro))
        if gyro[j] > STILL_GYRO_STD and acc.max() <= STILL_ACC_STD:
            said.append(
                f"IMU {i}'s gyro spread (std of {('gx', 'gy', 'gz')[j]}) is {gyro[j]:.3g} "
                f"rad/s at rest, above the {STILL_GYRO_STD:g} rad/s of a still robot, while "
                f"its accelerometer stayed still: a gyro in deg/s reads so (its noise, "
                f"{gyro[j]:.3g} deg/s, a MEMS gyro's), and its gyro_bias would then be "
                f"{180 / math.pi:.1f} times too large: give rad/s (gx, gy, gz times pi/180 "
                f"= {math.pi / 180:.7f}) and calibrate again"
            )
    return said


#: A still accelerometer reads gravity alone: a mean magnitude outside these multiples
#: of g is another unit (cm/s^2 reads about 981 at rest, milli-g about 1000).
REST_GRAVITY_RANGE = (0.5, 2.0)


def _accel_magnitudes(values: FloatArray, fmt: LineFormat, n_imus: int) -> list[float | None]:
    """Each IMU's mean accelerometer magnitude (m/s^2) over the raw samples ``values``
    whose three accelerations are finite, or None for an IMU without one."""
    k = VALUES_PER_IMU[fmt]
    means: list[float | None] = []
    for i in range(n_imus):
        acc = values[:, k * i : k * i + 3]
        norm = np.linalg.norm(acc[np.all(np.isfinite(acc), axis=1)], axis=1)
        means.append(float(norm.mean()) if len(norm) else None)
    return means


def rest_gravity_problem(values: FloatArray, fmt: LineFormat, n_imus: int) -> str | None:
    """Why the raw samples ``values`` (n, 6 * n_imus, or 3 without gyros) cannot be a
    still robot's in m/s^2, or None: an IMU whose mean accelerometer magnitude is
    outside :data:`REST_GRAVITY_RANGE` times g (before the spreads are compared, so
    that a unit's larger numbers are not read as a motion). Tilt readings: None."""
    if fmt != "raw":
        return None
    for i, mean in enumerate(_accel_magnitudes(values, fmt, n_imus)):
        low, high = REST_GRAVITY_RANGE
        if mean is not None and not low * STANDARD_GRAVITY <= mean <= high * STANDARD_GRAVITY:
            return (
                f"IMU {i + 1}'s accelerometer magnitude at rest is {mean:.4g}, not about "
                f"{STANDARD_GRAVITY:.2f} m/s^2: another unit? (at rest cm/s^2 reads about "
                "981, milli-g 1000, raw counts thousands); give ax, ay, az in m/s^2"
            )
    return None


#: A still accelerometer whose mean magnitude lies further than this share from g has a
#: scale or offset error a rest does not separate from its mounting (MEMS
#: accelerometers are specified to about 1 to 3 % in sensitivity; g varies by 0.5 % over
#: the Earth's surface).
REST_GRAVITY_NOTE_SHARE = 0.02


def rest_gravity_note(values: FloatArray, fmt: LineFormat, n_imus: int) -> str | None:
    """A note naming the IMUs of the raw samples ``values`` (n, 6 * n_imus, or 3 without
    gyros) whose mean accelerometer magnitude lies more than
    :data:`REST_GRAVITY_NOTE_SHARE` from g, or None: a scale or offset error, which tilts
    the readings by up to about its share of g in radians and which a rest does not
    measure. Tilt readings: None."""
    if fmt != "raw":
        return None
    off = [
        f"IMU {i + 1} {mean:.3f} m/s^2 ({100 * (mean / STANDARD_GRAVITY - 1.0):+.1f} %)"
        for i, mean in enumerate(_accel_magnitudes(values, fmt, n_imus))
        if mean is not None and abs(mean / STANDARD_GRAVITY - 1.0) > REST_GRAVITY_NOTE_SHARE
    ]
    if not off:
        return None
    return (
        f"the accelerometer magnitude at rest is more than "
        f"{100 * REST_GRAVITY_NOTE_SHARE:g} % from g ({STANDARD_GRAVITY:.2f} m/s^2): "
        f"{'; '.join(off)}: a scale or offset error, which tilts the readings by up to "
        "about that share of g in radians and which a rest does not measure (mount_rpy "
        "takes its tilt at this pose); calibrate the accelerometers with the six-position "
        "method (docs/hardware.md) where that matters"
    )


#: A tilt axis whose sample-to-sample steps spread by at least this share of white
#: noise's (sqrt(2) times its spread) scatters as noise; a robot's motion, smooth over
#: many samples, steps by far less.
NOISE_LIKE_STEP = 0.5


def motion_at_rest(
    values: FloatArray,
    fmt: LineFormat,
    n_imus: int,
    acc_std: float = STILL_ACC_STD,
    gyro_std: float = STILL_GYRO_STD,
    degrees_fix: str | None = None,
) -> str | None:
    """Why the samples ``values`` (n, k * n_imus) are not of a still robot, or None:
    the largest spread (standard deviation of one axis over the recording) beyond its
    bound (``acc_std`` m/s^2, ``gyro_std`` rad/s, and for tilt ``acc_std`` / g rad:
    :data:`STILL_ACC_STD`, :data:`STILL_GYRO_STD`, :data:`STILL_TILT_STD` by default),
    named with the IMU and axis, and the option that raises that bound. Tilt angles
    are compared on the circle (a hanging robot's roll near +-pi is still). With
    ``degrees_fix`` (what to do about tilt angles in degrees; None where they were read
    as degrees already), a tilt recording whose every spread, read as degrees, lies
    within the bound and whose every axis beyond it scatters from sample to sample as
    noise does (not a motion's smooth course: :data:`NOISE_LIKE_STEP`) is said to be
    possibly in degrees too (a still IMU's 0.3 degrees of noise, read as radians,
    spreads by 17 degrees)."""
    k = VALUES_PER_IMU[fmt]
    checks: list[tuple[str, int, str, float, tuple[str, ...], str]]
    tilt_std = acc_std / STANDARD_GRAVITY
    if fmt == "raw":
        checks = [
            ("accelerometer", 0, "m/s^2", acc_std, ("ax", "ay", "az"), "--still-acc-std"),
            ("gyro", 3, "rad/s", gyro_std, ("gx", "gy", "gz"), "--still-gyro-std"),
        ]
    else:
        checks = [
            ("tilt", 0, "rad", tilt_std, ("roll", "pitch"), "--still-acc-std (bound: it / g)")
        ]
    worst: tuple[float, str, str] | None = None
    accelerometers_moved = False
    widest_tilt = 0.0  # rad, the largest tilt spread of any IMU and axis
    noise_like = True  # every tilt axis beyond its bound steps as white noise does
    for i in range(n_imus):
        block = values[:, k * i : k * (i + 1)]
        block = block[np.all(np.isfinite(block), axis=1)]
        if len(block) < 2:
            continue
        for what, first, unit, bound, names, option in checks:
            part = block[:, first : first + len(names)]
            if fmt == "tilt":  # about the circular mean (roll near +-pi: a hanging robot)
                spread = angle_mean_std(part)[1]
                widest_tilt = max(widest_tilt, float(spread.max()))
                steps = np.angle(np.exp(1j * np.diff(part, axis=0))).std(axis=0, ddof=1)
                noise_like &= bool(
                    np.all((spread <= bound) | (steps >= NOISE_LIKE_STEP * math.sqrt(2) * spread))
                )
            else:
                spread = part.std(axis=0, ddof=1)
            j = int(np.argmax(spread))
            ratio = float(spread[j]) / bound
            accelerometers_moved |= what != "gyro" and ratio > 1.0
            if ratio > 1.0 and (worst is None or ratio > worst[0]):
                worst = (
                    ratio,
                    f"IMU {i + 1}'s {what} spread (std of {names[j]}) is "
                    f"{spread[j]:.3g} {unit}, above the {bound:.3g} {unit} of a still robot",
                    option,
                )
    if worst is None:
        return None
    if (
        worst[2] == "--still-gyro-std"
        and worst[0] >= DEG_S_SPREAD_RATIO
        and not accelerometers_moved
    ):
        return (
            f"{worst[1]}, while every accelerometer stayed still: a gyro in deg/s? give "
            f"rad/s (gx, gy, gz times pi/180 = {math.pi / 180:.7f}); if the robot did "
            f"move, calibrate needs it straight and still; if it was still, raise {worst[2]}"
        )
    degrees = ""
    if fmt == "tilt" and degrees_fix and noise_like and math.radians(widest_tilt) <= tilt_std:
        degrees = (
            f"; or are the angles in degrees? (read as degrees, every spread is within the "
            f"bound, {widest_tilt:.3g} degrees at most) {degrees_fix}"
        )
    return (
        f"the robot moved: {worst[1]}; calibrate needs it straight and still "
        f"(a bend in a known plane goes to --bend BEND.csv); if the robot was still, raise "
        f"{worst[2]}{degrees}"
    )


def _rounded(value: float, decimals: int) -> float:
    """``value`` rounded to ``decimals`` (as ``--write-robot`` writes a mounting and a
    bias), a negative zero (a value that rounds to 0 from below) as 0."""
    return round(float(value), decimals) + 0.0


def _written(value: float, decimals: int) -> str:
    """:func:`_rounded` with ``decimals`` digits after the point."""
    return f"{_rounded(value, decimals):.{decimals}f}"


def format_report(
    cal: Calibration,
    source: str,
    bend: tuple[str, float, list[YawCalibration]] | None = None,
    yaws_deg: Sequence[float] | None = None,
    mounting: Mounting = "z-up",
) -> str:
    """The calibration as text for the terminal; ``bend``: ``(file, phi deg, yaws)``
    from a bend in a known plane (each IMU's yaw, and the full mounting); ``yaws_deg``:
    each IMU's yaw as the robot file gives it (gravity does not see it), kept in the
    mounting printed without a bend (else 0); ``mounting``: what a straight robot's
    tilt reads."""
    if cal.median_period_s > MS_LIKE_STEP_S:  # milliseconds read as seconds: no rate
        timing = (
            f"{cal.n} samples whose times look like milliseconds (t steps by a median of "
            f"{cal.median_period_s:g} per sample, read as seconds): no sample rate is said "
            "(name the column t_ms for one); the means, noise and mountings below do not "
            "depend on the times"
        )
    else:
        timing = (
            f"{cal.n} samples over {cal.span_s:.3f} s of device time: {cal.rate_hz:.1f} Hz "
            f"(median step {cal.median_period_s * 1e3:.2f} ms, longest "
            f"{cal.longest_step_s * 1e3:.2f} ms)"
        )
    lines = [f"calibration from {source}: {timing}"]
    for i, imu in enumerate(cal.imus, start=1):
        m, s = imu.mean, imu.std
        if cal.fmt == "raw":
            g = float(np.linalg.norm(m[:3]))
            lines += [
                f"IMU {i}: accelerometer mean (m/s^2) ax={_written(m[0], 4)} "
                f"ay={_written(m[1], 4)} az={_written(m[2], 4)} "
                f"(|a| = {g:.4f}); noise std ax={s[0]:.4f} ay={s[1]:.4f} az={s[2]:.4f}",
                f"IMU {i}: gyro bias (rad/s) gx={_written(m[3], 5)} gy={_written(m[4], 5)} "
                f"gz={_written(m[5], 5)} (robot "
                f"file: gyro_bias = [{_written(m[3], 6)}, {_written(m[4], 6)}, "
                f"{_written(m[5], 6)}]); noise std "
                f"gx={s[3]:.5f} gy={s[4]:.5f} gz={s[5]:.5f}",
            ]
            assert imu.mount_rpy is not None
            # as --write-robot writes them (3 decimals; a negative zero as 0)
            r, p = (_rounded(v, 3) for v in imu.mount_rpy[:2])
            tilt_noise = math.degrees(float(np.hypot(s[0], s[1])) / g) if g > 0 else math.nan
            yaw = 0.0 if yaws_deg is None else float(yaws_deg[i - 1])
            if bend:
                yaw_hint = "from --bend below"
            elif yaw:
                yaw_hint = "the robot file's (a bend in a known plane measures it: --bend)"
            else:
                yaw_hint = "see docs/hardware.md"
            lines.append(
                f"IMU {i}: mounting with the robot straight: --mount-rpy {r:g},{p:g},"
                f"{yaw:g} (robot file: mount_rpy = [{r:g}, {p:g}, {yaw:g}]); yaw: "
                f"{yaw_hint}; accelerometer noise as tilt: {tilt_noise:.2f} deg at rest "
                "(not estimate's --noise-deg, the scatter in motion: keep its default)"
            )
            if bend:
                y = bend[2][i - 1]
                yaw_w = _rounded(y.yaw_deg, 3)
                lines += [
                    f"IMU {i}: yaw from the bend towards phi = {bend[1]:g} deg in {bend[0]}: "
                    f"{y.yaw_deg:.2f} deg (gyro rate axis, standard error "
                    f"{y.yaw_std_deg:.3f} deg; the gravity direction gives "
                    f"{y.gravity_yaw_deg:.2f} deg); tilt up to {y.tilt_deg:.0f} deg, rates "
                    f"across the bending axis {100 * y.off_axis:.1f} %",
                    f"IMU {i}: mounting: --mount-rpy {r:g},{p:g},{yaw_w:g} (robot "
                    f"file: mount_rpy = [{r:g}, {p:g}, {yaw_w:g}])",
                ]
        else:
            lines.append(
                f"IMU {i}: roll mean {math.degrees(m[0]):.3f} deg (std {math.degrees(s[0]):.3f}),"
                f" pitch mean {math.degrees(m[1]):.3f} deg (std {math.degrees(s[1]):.3f}); a "
                f"straight robot should read {'0' if mounting == 'z-up' else '+-180'}, 0"
            )
    return "\n".join(lines)


#: How long calibrate waits beyond its ``--seconds`` for the board's start-up (it resets
#: and calibrates its gyro when the port opens), s.
BOOT_S = 15.0
#: ... and, once garbled lines arrive with no valid one, beyond ``--seconds`` from the
#: first of them: a board streaming another format does not change it later, s.
GARBLED_ONLY_S = 2.0
#: After this much arrival time (s) the device clock must have advanced at least
#: :data:`CLOCK_SLOW` times as much, else its ``t_ms`` are seconds.
CLOCK_CHECK_S = 2.0
CLOCK_SLOW = 0.1
#: Samples further apart than this (s of device time, the median step) are not an IMU
#: stream's: ``t_ms`` in microseconds (a clock that fast fills ``--seconds`` in a few
#: samples, long before the arrival time could say so).
SLOWEST_STEP_S = 1.0


def collect(
    port: str,
    baud: int,
    fmt: LineFormat,
    n_imus: int,
    seconds: float,
    say: Any,
    n_tensions: int = 0,
    limits: Sequence[RawLimits] = (),
) -> tuple[FloatArray, FloatArray]:
    """Samples from the port over ``seconds`` of device time (device messages shown);
    ``limits``: each IMU's plausibility limits of a raw line (``live``'s, from its
    robot file's full scales), or empty for the default's.

    A robot with ``n_tensions`` tendons may send its tensions after the IMUs' fields
    (as ``live`` reads them) or not: a line of either length is a sample, and its
    tensions are not needed here."""
    with_tensions = len(line_fields(fmt, n_imus, n_tensions)) if n_tensions else -1
    try:
        conn = open_port(port, baud, "calibrate")
    except MissingExtraError:
        raise
    except Exception as exc:
        raise InputError(
            port_hint(
                port, exc, "a recording is calibrated with continuum-mhe calibrate --from FILE"
            )
        ) from None
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader(port, baud, conn, events, 1.0)
    clock = DeviceClock()
    t: list[float] = []
    rows: list[FloatArray] = []
    garbled, first_garbled = 0, ""
    out_of_order = 0
    unended = 0  # the most bytes seen arriving with no line end
    jumped: Any = None  # a sample whose t_ms jumped back: a restart if the next follows it
    host_first = host_last = math.nan  # arrival of the first and last samples kept, s
    give_up = time.monotonic() + seconds + BOOT_S  # the board resets and calibrates first
    garbled_since = math.inf  # when the first garbled line came
    microseconds = MicrosecondsCheck()
    reader.start()
    say(f"reading {port} for {seconds:g} s: keep the robot straight and still")
    try:
        while time.monotonic() < give_up and not (t and t[-1] - t[0] >= seconds):
            if not t and time.monotonic() - garbled_since > seconds + GARBLED_ONLY_S:
                break  # streaming, but not one valid line: it will not start now
            host = host_last - host_first  # between the first and last samples' arrivals
            device = t[-1] - t[0] if t else 0.0
            if len(t) >= 2 and host >= CLOCK_CHECK_S and device < CLOCK_SLOW * host:
                raise InputError(
                    f"{port}: the device clock advanced {1e3 * device:.3g} ms in "
                    f"{host:.3g} s of arrival time: t_ms in seconds? (the first field is "
                    "milliseconds, as millis() gives)"
                )
            try:
                kind, payload, arrival = events.get(timeout=0.1)
            except queue.Empty:
                continue
            if kind == "failed":  # a defect in the reader thread
                raise payload
            if kind == "unended":  # bytes with no line end so far
                unended = max(unended, payload)
            if kind == "lost":  # unplugged: the reader reopens it, and the board restarts
                say(f"device lost ({payload}): waiting for it to come back")
            elif kind == "back":  # a board that reset with the port restarts its gyro too
                say("device back: the samples start over")
                clock.expect_restart()
                t, rows, jumped = [], [], None
            if kind != "line":
                continue
            try:
                text = payload.decode("ascii")
                carried = n_tensions if text.count(",") + 1 == with_tensions else 0
                sample = parse_line(text, fmt, n_imus, carried, limits)
                if sample is not None and sample.problems:  # calibration needs every IMU
                    raise GarbledLine(sample.problems[0])
            except (UnicodeDecodeError, GarbledLine) as exc:
                garbled += 1
                garbled_since = min(garbled_since, arrival)
                if not first_garbled:
                    first_garbled = (
                        "not ASCII"
                        if isinstance(exc, UnicodeDecodeError)
                        else str(exc) + field_count_hint(text, fmt, n_imus)
                    )
                continue
            if sample is None:
                if text.strip().startswith("#"):
                    say(f"device says: {text.strip()}")
                continue
            if (problem := microseconds.add(sample.t_ms, arrival)) is not None:
                raise InputError(f"{port}: {problem}")  # each line would be out of order
            if jumped is not None:  # the held sample: the device's restart, or corrupted
                (held, held_arrival), jumped = jumped, None
                if clock.confirms_jump(held.t_ms, sample.t_ms):
                    restart = clock.place(held.t_ms, held_arrival, None, confirmed=True)
                    say(f"device clock restart at t_ms={held.t_ms:.0f}: starting over")
                    t, rows = [restart.t], [held.values]
                    host_first = host_last = held_arrival
                else:
                    out_of_order += 1
            if clock.jumps_back(sample.t_ms):
                jumped = (sample, arrival)
                continue
            # the usual period, once known: an equal stamp is then a repeated line
            period = float(np.median(np.diff(t[-50:]))) if len(t) >= 3 else None
            placed = clock.place(sample.t_ms, arrival, period)
            if placed.event == "out-of-order":  # a repeated, late or corrupted line
                out_of_order += 1
                continue
            if placed.event == "restart":  # after a reconnect: the board started again
                say(f"device clock restart at t_ms={sample.t_ms:.0f}: starting over")
                t, rows = [], []
            if not t:
                host_first = arrival
            host_last = arrival
            t.append(placed.t)
            rows.append(sample.values)
    finally:
        reader.stop.set()
    if jumped is not None:  # held for jumping back, and no line came after it
        out_of_order += 1
    if garbled:
        say(f"{garbled} garbled line(s) skipped")
    if out_of_order:
        say(f"{out_of_order} line(s) out of order skipped (a repeated, late or corrupted t_ms)")
    if len(t) < 2:
        if garbled:
            why = (
                f"{garbled} garbled line(s), the first: {first_garbled}; check --format, "
                "--robot and --baud"
            )
            waited = f"{seconds + GARBLED_ONLY_S:g} s of garbled lines"
        elif unended:
            why = (
                f"{unended} bytes arrived without a line end (LF or CR): check --baud, or "
                "how the device ends its lines"
            )
            waited = f"{seconds + BOOT_S:g} s"
        else:
            why, waited = "is it streaming?", f"{seconds + BOOT_S:g} s"
        raise InputError(f"{port}: {len(t)} valid sample(s) in {waited}; {why}")
    step = float(np.median(np.diff(t)))
    if step > SLOWEST_STEP_S:
        raise InputError(
            f"{port}: {len(t)} samples over {t[-1] - t[0]:.3g} s of device time, {step:.3g} s "
            "apart: t_ms in microseconds? (the first field is milliseconds, as millis() "
            "gives)"
        )
    if t[-1] - t[0] < seconds:
        say(
            f"warning: {port}: {t[-1] - t[0]:.3f} s of the {seconds:g} s asked arrived "
            "(the device stopped sending: unplugged?); the calibration is of those"
        )
    return np.asarray(t), np.asarray(rows)


def bend_yaws(
    path: str, phi_deg: float, cal: Calibration, robot: Robot, topics: Sequence[str] = ()
) -> list[YawCalibration]:
    """Each IMU's yaw from the raw recording ``path`` (a CSV file, or a robot log's Imu
    ``topics``) of a bend towards ``phi_deg``, with the rest calibration ``cal``'s roll,
    pitch and gyro bias."""
    if cal.fmt != "raw":
        raise InputError("--bend needs a raw rest recording (ax, ..., gz columns)")
    if not is_robot_log(Path(path)) and csv_input_kind(path) != "raw":
        raise InputError(f"{path}: line 1: --bend needs a raw recording (ax, ..., gz columns)")
    _, _, values = read_recording(path, robot.n_imus, topics=topics)
    rest = [(imu.mount_rpy, imu.mean[3:], imu.std[3:]) for imu in cal.imus]
    return yaws_from_bend(path, values, rest, phi_deg, robot.mounting)  # type: ignore[arg-type]
