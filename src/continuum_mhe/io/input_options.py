"""The input options and the decisions made from them: :class:`InputOptions` holds
the command-line options of reading an input; :func:`check_options_apply` refuses one
that would do nothing on an input; :func:`with_imu_model` and :func:`formulation_for`
decide the IMU model and formulation; :func:`imu_settings_for` gives one IMU's raw
conversion; :func:`check_mounting` checks the first readings against the robot's
mounting. The pipeline that applies them, in order, is :mod:`continuum_mhe.io.inputs`.
"""

from __future__ import annotations

import math
import os
import warnings
import weakref
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, expect_type
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import shipped_robots
from continuum_mhe.model.direct import DEFAULT_GYRO_STD
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, mount_taken
from continuum_mhe.model.settings import check_positive


@dataclass(frozen=True)
class InputOptions:
    """How ``estimate`` reads its input (command-line options).

    Attributes:
        raw: raw-IMU conversion (raw CSV, bags, MCAP).
        mount_rpy_given: ``--mount-rpy`` was given (even as 0,0,0): refused where it
            applies to no IMU (:func:`check_options_apply`).
        gyro_std_given: ``--gyro-std`` was given on the command line: refused where no
            gyro is read (:func:`formulation_for`); an options file's value is not.
        gyro_bias_off_given: ``--no-estimate-gyro-bias`` was given on the command line:
            refused where no gyro is read, as ``gyro_std_given``.
        topic: Imu topic in a bag or MCAP file (None: the only one).
        topics: one Imu topic per IMU, in the robot file's order, for a robot with
            several IMUs (see :mod:`continuum_mhe.io.imu_topics`).
        pair_tolerance: largest header-stamp difference of paired samples, s (None:
            half of IMU 1's median sample period).
        use_orientation: use the Imu message's orientation (roll, pitch) instead of
            its raw accelerometer and gyro.
        gyro_std: gyro white noise, rad/s (None, the default: the model's own:
            :data:`DEFAULT_GYRO_STD` for the direct model, and for a tendon robot the
            value it resolves from its IMUs, less for one IMU; a value given, 0.01
            included, is kept).
        estimate_gyro_bias: the direct model estimates each gyro's bias (None: yes,
            the default; False: the bias counts as gyro noise).
        estimate_accel_bias: the direct model estimates each accelerometer's bias.
        own_acceleration: the direct model includes each IMU's own acceleration
            (bend accelerations as states).
        imu_twist: the direct model turns each IMU about the backbone's tangent by a
            twist state (a rod that twists); where every IMU of the robot has a
            calibrated gyro bias, the biases are then held at it unless
            ``estimate_gyro_bias`` is True (elsewhere a warning says what estimating
            them costs).
        degrees: a tilt CSV is in degrees.
        skip_bad: skip bad samples instead of stopping.
        tensions: a tendon tensions file (``--inputs``) for a robot with tendons.
        estimate_tension_gain: a tendon robot's formulation estimates a gain per
            section on the tensions given (``--estimate-tension-gain``).
        from_profile: the options (``degrees``, ``mount_rpy``, ``attitude``,
            ``pair_tolerance``) that an options file set, not the command line: a
            profile's options apply where they can, so :func:`check_options_apply`
            passes over them where they do not.
    """

    raw: RawImuSettings = field(default_factory=RawImuSettings)
    mount_rpy_given: bool = False
    gyro_std_given: bool = False
    gyro_bias_off_given: bool = False
    topic: str | None = None
    topics: tuple[str, ...] = ()
    pair_tolerance: float | None = None
    use_orientation: bool = False
    gyro_std: float | None = None
    estimate_gyro_bias: bool | None = None
    estimate_accel_bias: bool = False
    own_acceleration: bool = False
    imu_twist: bool = False
    degrees: bool = False
    skip_bad: bool = False
    tensions: str | None = None
    estimate_tension_gain: bool = False
    from_profile: frozenset[str] = frozenset()

    def __post_init__(self) -> None:
        """Each field of its kind (a :class:`UserError` naming it): a switch is a bool
        (a string such as ``"no"`` would read as true), a file or topic a str, a
        tolerance or noise a positive finite number; ``topics`` taken as a tuple."""
        expect_type("InputOptions raw", self.raw, RawImuSettings, "a RawImuSettings")
        switches = (
            "mount_rpy_given", "gyro_std_given", "gyro_bias_off_given", "use_orientation",
            "estimate_accel_bias", "own_acceleration", "imu_twist", "degrees", "skip_bad",
            "estimate_tension_gain",
        )  # fmt: skip
        for name in switches:
            expect_type(f"InputOptions {name}", getattr(self, name), bool, "True or False")
        if self.estimate_gyro_bias is not None:
            expect_type(
                "InputOptions estimate_gyro_bias", self.estimate_gyro_bias, bool,
                "True, False or None (the default: yes)",
            )  # fmt: skip
        for name in ("topic", "tensions"):
            value = getattr(self, name)
            if value is not None:
                expect_type(f"InputOptions {name}", value, (str, os.PathLike), "a str or None")
        if isinstance(self.topics, (str, bytes)) or not hasattr(self.topics, "__iter__"):
            raise UserError(
                f"InputOptions topics must be a sequence of str, got {self.topics!r:.60}"
            )
        object.__setattr__(self, "topics", tuple(self.topics))
        for topic in self.topics:
            expect_type("InputOptions topics item", topic, str, "a str (an Imu topic)")
        if self.gyro_std is not None:
            check_positive("InputOptions gyro_std", self.gyro_std)
        if self.pair_tolerance is not None:
            check_positive("InputOptions pair_tolerance", self.pair_tolerance)


def with_imu_model(
    options: InputOptions, base: Formulation, raw_input: bool, has_gyro: bool
) -> InputOptions:
    """``options`` with the IMU model decided: where ``raw.imu_model`` is None (no
    ``--imu-model``), raw
    input with gyro columns (and the ``bend`` formulation, accelerometer attitude, no
    ``--orientation``) uses the direct model, which fuses the gyros (with their bias
    estimated unless ``estimate_gyro_bias`` is False); other input takes ``tilt``. A
    model already chosen stays."""
    if options.raw.imu_model is not None:
        return options
    gyro_input = raw_input and has_gyro and not options.use_orientation
    direct = gyro_input and options.raw.attitude == "accel" and base.name in ("bend", "direct")
    if gyro_input and options.raw.attitude != "accel" and base.name in ("bend", "direct"):
        warnings.warn(
            f"--attitude {options.raw.attitude} takes the tilt model (roll and pitch from "
            "the fused attitude) instead of the direct model, the default for raw input "
            "with gyros and measurably better (docs/options.md); add --imu-model tilt to "
            "choose it without this warning",
            OptionWarning,
            stacklevel=3,
        )
    return replace(options, raw=replace(options.raw, imu_model="direct" if direct else "tilt"))


def formulation_for(
    options: InputOptions, base: Formulation, raw_input: bool, path: Path
) -> Formulation:
    if options.raw.imu_model != "direct":
        for flag, on in (
            ("--estimate-gyro-bias", options.estimate_gyro_bias),
            ("--estimate-accel-bias", options.estimate_accel_bias),
            ("--own-acceleration", options.own_acceleration),
            ("--imu-twist", options.imu_twist),
            ("--no-estimate-gyro-bias", options.gyro_bias_off_given),
            ("--gyro-std", options.gyro_std_given),
        ):
            if on:
                raise InputError(f"{flag} needs --imu-model direct (raw gyros)")
        return base
    if not raw_input or options.use_orientation:
        raise InputError(f"{path}: --imu-model direct needs raw accelerometer and gyro input")
    if base.name not in ("bend", "direct"):
        raise InputError(
            f"--imu-model direct uses the bend state; --formulation {base.name} does not apply"
        )
    from continuum_mhe.model.direct import DirectFormulation, gyro_biases_calibrated

    held = options.imu_twist and gyro_biases_calibrated(base.robot)
    # (a tendon robot is refused --imu-twist by its own formulation)
    if options.imu_twist and not held and not base.robot.has_mechanics:
        treated = (
            "held at zero (--no-estimate-gyro-bias)"
            if options.estimate_gyro_bias is False
            else "estimated, and a bias about an IMU's z axis turns the estimated bending "
            "plane (the shipped spatial rod, EKF: 18.7 mm at the tip, 125 ok rows over 20 "
            "mm off, against 8.8 mm and 32 calibrated; docs/model.md)"
        )
        warnings.warn(
            "--imu-twist without a calibrated gyro_bias for every IMU in the robot file: "
            f"their biases are {treated}; calibrate at rest first (continuum-mhe "
            "calibrate --from REST.csv --write-robot)",
            OptionWarning,
            stacklevel=2,
        )
    return DirectFormulation(
        robot=base.robot,
        noise=base.noise,
        gyro_std=DEFAULT_GYRO_STD if options.gyro_std is None else options.gyro_std,
        estimate_gyro_bias=(
            not held if options.estimate_gyro_bias is None else options.estimate_gyro_bias
        ),
        estimate_accel_bias=options.estimate_accel_bias,
        own_acceleration=options.own_acceleration,
        imu_twist=options.imu_twist,
    )


#: The largest gyro bias (rad/s, across gravity) the ``ahrs`` Madgwick filter's
#: correction takes up: its gradient step turns the attitude by at most twice its gain
#: (0.033) per second.
MADGWICK_CORRECTION_RATE = 2 * 0.033


def refuse_uncalibrated_madgwick(name: str, options: InputOptions, robot: Robot) -> None:
    """Refuse ``--attitude madgwick`` (one line naming ``name`` and the IMUs) where an
    IMU has no calibrated ``gyro_bias`` in the robot file. The Madgwick filter estimates
    no gyro bias: one across gravity beyond :data:`MADGWICK_CORRECTION_RATE` turns its
    roll and pitch by the excess every second, without bound, so no widening of the
    readings' noise covers it. The tilt model fits two sections' bends to two IMUs'
    readings exactly, so the readings' fit does not show it, and the rows would stay
    ``ok`` however far off. Mahony estimates the bias, and a calibrated bias is
    subtracted before either filter."""
    raw = options.raw
    if raw.imu_model == "direct" or raw.attitude != "madgwick":  # None: tilt, decided later
        return
    bare = [str(i) for i, imu in enumerate(robot.imus, start=1) if not any(imu.gyro_bias)]
    if not bare:
        return
    which = f"IMU {', '.join(bare)}" if robot.n_imus > 1 else "the IMU"
    given = "--attitude madgwick" + (
        " (from the options file)" if "attitude" in options.from_profile else ""
    )
    raise InputError(
        f"{name}: {given} needs a calibrated gyro_bias for {which} in the robot file: "
        "the Madgwick filter estimates no gyro bias, and one beyond "
        f"{MADGWICK_CORRECTION_RATE:.3f} rad/s across gravity turns its roll and pitch "
        "further every second, an error no reading shows and no standard deviation "
        "carries (the shipped planar-s rod: 33 mm at the tip, 405 of 600 ok rows more than "
        "4 standard deviations off); calibrate at rest first (continuum-mhe calibrate "
        "--from REST.csv --write-robot), or use --attitude mahony, which estimates the bias"
    )


class OptionWarning(UserWarning):
    """A robot-file entry or option that has no effect on this input, or one measured
    to mislead on such input."""


def check_options_apply(name: str, kind: str, options: InputOptions, robot: Robot) -> None:
    """Refuse an option that would do nothing on this input, in one line naming it and
    why; warn, once, where a robot file's ``mount_rpy`` is not applied.

    ``kind``: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"`` (a bag or MCAP: raw vectors,
    or roll and pitch from its orientation with ``use_orientation``); ``live`` passes
    the CSV kinds of its line formats. Roll and pitch are taken as already in the
    backbone's frame at each IMU; ``mount_rpy`` rotates raw accelerometer and gyro
    vectors only (docs/hardware.md). ``--mount-rpy`` counts as given where it is not
    zero or :attr:`InputOptions.mount_rpy_given` says so."""
    raw = options.raw
    mount_given = options.mount_rpy_given or any(raw.mount_rpy)
    if options.estimate_tension_gain and not robot.n_tendons:
        raise InputError(
            f"{name}: --estimate-tension-gain does not apply: it is for a tendon robot "
            "(a robot file with [[tendon]] entries and a [backbone])"
        )
    if kind != "log":  # a bag's or MCAP's options
        for flag, given in (
            ("--topic", bool(options.topics) or options.topic is not None),
            ("--orientation", options.use_orientation),
            ("--pair-tolerance", options.pair_tolerance is not None),
        ):
            if given:
                raise InputError(
                    f"{name}: {flag} does not apply to this input: it is for ROS bags and "
                    "MCAP files (sensor_msgs/Imu topics), and this is a CSV file"
                )
    if (
        options.pair_tolerance is not None
        and robot.n_imus == 1
        and len(options.topics) < 2
        and "pair_tolerance" not in options.from_profile
    ):
        raise InputError(
            f"{name}: --pair-tolerance does not apply to one IMU's topic: it pairs the "
            "samples of several topics, one per IMU"
        )
    tilt_input = kind == "tilt-csv" or (kind == "log" and options.use_orientation)
    profile = options.from_profile
    if options.degrees and kind != "tilt-csv" and "degrees" not in profile:
        units = (
            "the orientation is a quaternion"
            if tilt_input
            else "accelerations are read in m/s^2 and gyro rates in rad/s"
        )
        raise InputError(
            f"{name}: --degrees does not apply to this input: it is for roll and pitch in "
            f"tilt CSV files; {units}"
        )
    mounted = [str(i) for i, imu in enumerate(robot.imus, start=1) if any(imu.mount_rpy)]
    mount_taken(robot)  # turned by the raw readings' conversion, or said below
    if not tilt_input:
        if mount_given and len(mounted) == robot.n_imus and "mount_rpy" not in profile:
            raise InputError(
                f"{name}: --mount-rpy applies to no IMU: the robot file gives every IMU its "
                "own mount_rpy, which wins (leave --mount-rpy out, or edit the robot file)"
            )
        return
    why = "roll and pitch are used as they are, taken as already in the backbone's frame"
    if mount_given and "mount_rpy" not in profile:
        raise InputError(
            f"{name}: --mount-rpy does not apply to tilt input: it rotates raw "
            f"accelerometer and gyro vectors, and {why}"
        )
    if raw.attitude != "accel" and "attitude" not in profile:
        raise InputError(
            f"{name}: --attitude {raw.attitude} does not apply to tilt input: it fuses raw "
            f"accelerometer and gyro readings, and {why}"
        )
    if mounted:
        warnings.warn(
            f"{name}: the robot file's mount_rpy of IMU {', '.join(mounted)} is not applied "
            f"to tilt input: it rotates raw readings, and {why} (as simulate writes them); "
            "roll and pitch in an IMU's own frame need turning into its disk's first "
            "(docs/formats.md#tilt), or give its raw readings",
            OptionWarning,
            stacklevel=3,
        )


def imu_settings_for(raw: RawImuSettings, place: ImuPlacement) -> RawImuSettings:
    """The conversion settings of one IMU: the robot file's mounting where it gives one,
    else ``--mount-rpy``; the robot file's gyro bias and full scales."""
    if any(place.mount_rpy):
        raw = replace(raw, mount_rpy=place.mount_rpy)
    if place.accel_range is not None or place.gyro_range is not None:
        raw = replace(raw, accel_range=place.accel_range, gyro_range=place.gyro_range)
    return replace(raw, gyro_bias=place.gyro_bias) if any(place.gyro_bias) else raw


#: Valid readings whose median the mounting check uses (half a second at 50 Hz): of the
#: IMU nearest the base, and of each pair of IMUs one after the other.
MOUNTING_START_SAMPLES = 25
#: A start further than this from the straight pose of the stated mounting (and so
#: within 45 degrees of the opposite mounting's straight pose) is refused, rad.
MOUNTING_FLIPPED = math.radians(135.0)
#: Between two IMUs one after the other, a start bent more than this (rad) is said even
#: where the sections' theta_max allow it: an IMU mounted upside down on a robot that
#: starts near straight reads about pi.
UPSIDE_DOWN_LIKE = math.radians(160.0)
#: A start more than 90 degrees plus this from the stated mounting's straight pose
#: warns; the warning says so where it is further than the sections' theta_max let the
#: IMU bend by more than this too, rad (the readings' noise and the IMU's misalignment
#: are far below it).
MOUNTING_MARGIN = math.radians(10.0)


class MountingWarning(UserWarning):
    """A start that gravity puts closer to the other mounting's straight pose than to
    the stated one's (a robot bent past 90 degrees, or described the wrong way up)."""


class MountingError(InputError):
    """A start that gravity puts near the other mounting's straight pose: the robot is
    mounted the other way (:func:`check_mounting`)."""


#: Of a recording's valid readings, the share (and at least the count below) that puts
#: the IMU nearest the base beyond the sections' reach from the stated mounting's
#: straight pose, every one within it from the other's, for :class:`MountingTally` to
#: say the mounting.
FLIPPED_SHARE, FLIPPED_SAMPLES = 0.05, 5


class MountingTally:
    """The mounting over a whole recording, where :func:`check_mounting` sees its start
    alone: a recording that starts bent (or is cut from a longer one) and stays within
    90 degrees of the wrong mounting's straight pose passes that check, and a robot
    described the wrong way up is then estimated bent the other way, every row far off.
    Counts, over the readings given to :meth:`add`, those that put the IMU nearest the
    base further from the stated mounting's straight pose than the sections' ``theta_max``
    let it bend (by :data:`MOUNTING_MARGIN`), and those that put it so far from the other
    mounting's; :meth:`warn` says the mounting where the first are many
    (:data:`FLIPPED_SHARE`, :data:`FLIPPED_SAMPLES`) and the second none, unless the
    start check said the mounting already (a start past 90 degrees). Not for a tendon
    robot, whose mechanics model has no bend bound."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        self.k = base_imu(formulation.robot)
        self.reach = bend_reach(formulation.robot, self.k)
        self.valid = self.beyond = self.beyond_other = 0
        self._start: list[float] = []  # the first readings' angles, as check_mounting's

    def add(self, z: FloatArray) -> None:
        """Count the readings ``z`` (n, nz)."""
        angles = _imu_angles(z, self.formulation, self.k)
        angles = angles[np.isfinite(angles)]
        self._start += angles[: MOUNTING_START_SAMPLES - len(self._start)].tolist()
        limit = self.reach + MOUNTING_MARGIN
        self.valid += len(angles)
        self.beyond += int(np.sum(angles > limit))
        self.beyond_other += int(np.sum(math.pi - angles > limit))

    def warn(self, name: str, robot_file: str | None = None, python: bool = False) -> None:
        """A :class:`MountingWarning` where the readings counted say the other mounting
        (``robot_file`` and ``python`` choose the fix it names, as :func:`check_mounting`)."""
        robot = self.formulation.robot
        many = max(FLIPPED_SAMPLES, FLIPPED_SHARE * self.valid)
        if robot.has_mechanics or self.beyond < many or self.beyond_other:
            return
        if self._start and float(np.median(self._start)) > math.pi / 2 + MOUNTING_MARGIN:
            return  # check_mounting said it of the start
        other, pose = flipped_mounting(robot.mounting)
        fix = robot_fix("mounting", robot_file, other, python)
        raise_it = robot_fix("theta_max", robot_file, python=python)
        warnings.warn(
            f"{name}: mounting: {self.beyond} of its {self.valid} readings put IMU "
            f"{self.k + 1} further from the {robot.mounting} straight pose than the "
            f"{math.degrees(self.reach):.0f} degrees the sections' theta_max let it bend, "
            f"and every one within them as {other}: if the robot {pose}, {fix} (the "
            "estimates of a robot described the wrong way up are far off, and its rows "
            f"can say ok); if it does bend so far, {raise_it}",
            MountingWarning,
            stacklevel=3,
        )


class MountingWatch:
    """:func:`check_mounting` of samples handed over one at a time or in blocks
    (``Estimator.step`` and ``continue_run``): the first
    :data:`MOUNTING_START_SAMPLES` samples with a reading since :meth:`reset` are
    checked once they have arrived. Its :class:`MountingError` is raised again for every
    later sample until :meth:`reset` (the robot is still mounted the other way).

    ``name`` (else the method given to :meth:`see`) begins the messages;
    ``robot_file`` and ``python`` choose the fix they name, as :func:`check_mounting`'s
    (the Robot's field by default; a command line's option or robot file key)."""

    def __init__(
        self,
        formulation: Formulation,
        name: str | None = None,
        robot_file: str | None = None,
        python: bool = True,
    ) -> None:
        self.formulation = formulation
        self.name, self.robot_file, self.python = name, robot_file, python
        self.reset()

    def reset(self) -> None:
        """Watch a new recording."""
        self._rows: list[FloatArray] = []
        self._seen = 0
        self.done = False
        self.error: MountingError | None = None

    def see(self, z: FloatArray, what: str) -> None:
        """Take the samples ``z`` (n, nz) handed over to ``what`` (the method, for the
        message); check the first ones once there are enough. Raises the
        :class:`MountingError` where they put the robot the other way up; warns as
        :func:`check_mounting` does."""
        if self.error is not None:
            raise self.error
        if self.done:
            return
        valid = np.asarray(z, dtype=float)[np.isfinite(z).any(axis=1)]  # a reading in it
        take = valid[: MOUNTING_START_SAMPLES - self._seen]  # (a copy: a boolean index)
        self._rows.append(take)
        self._seen += len(take)
        if self._seen < MOUNTING_START_SAMPLES:
            return
        self.done = True
        first, self._rows = np.vstack(self._rows), []
        try:
            check_mounting(self.name or what, first, self.formulation, self.robot_file, self.python)
        except MountingError as exc:
            self.error = exc
            raise


def start_bend_angle(z: FloatArray, formulation: Formulation) -> tuple[int, float] | None:
    """``(imu, angle)``: the IMU nearest the base (0-based) and the median angle, rad,
    between its tangent and the base axis over its first
    :data:`MOUNTING_START_SAMPLES` valid readings in ``z`` (n, nz), with the robot's
    stated mounting (``z-up``: the base axis points up; ``z-down``: down); None
    without a valid reading. A robot that starts near straight reads about 0; one
    whose mounting is stated upside down reads about pi."""
    k = base_imu(formulation.robot)
    angle = imu_start_angle(z, formulation, k)
    return None if angle is None else (k, angle)


def base_imu(robot: Robot) -> int:
    """The IMU nearest the base (0-based): the first section's, lowest ``at`` first."""
    return min(range(robot.n_imus), key=lambda i: (robot.imus[i].section, robot.imus[i].at))


def bend_reach(robot: Robot, k: int) -> float:
    """The largest angle, rad, the sections up to IMU ``k`` (0-based) can bend it
    through from the straight pose: their ``theta_max``, in part where it sits inside a
    section (a tendon robot's mechanics model has no such bound)."""
    imu = robot.imus[k]
    reach = sum(s.theta_max for s in robot.sections[: imu.section])
    return reach + imu.at * robot.sections[imu.section].theta_max


def imu_start_angle(z: FloatArray, formulation: Formulation, k: int) -> float | None:
    """IMU ``k``'s (0-based) median angle from the stated mounting's base axis over its
    first valid readings, rad, as :func:`start_bend_angle` (None without one)."""
    angles = _imu_angles(z, formulation, k)
    valid = angles[np.isfinite(angles)][:MOUNTING_START_SAMPLES]
    return float(np.median(valid)) if len(valid) else None


def _imu_angles(z: FloatArray, formulation: Formulation, k: int) -> FloatArray:
    """IMU ``k``'s (0-based) angle from the stated mounting's base axis at every row of
    ``z`` (n, nz), rad; NaN where it has no valid reading."""
    block = formulation.measurement_blocks[k]
    zb = np.asarray(z, dtype=float)[:, block.slice]
    with np.errstate(invalid="ignore", divide="ignore"):
        if block.kind == "tilt":  # the up direction in the IMU frame is f = R^T u
            f_axis = np.cos(zb[:, 0]) * np.cos(zb[:, 1])
        else:
            f_axis = zb[:, 2] / np.linalg.norm(zb[:, :3], axis=1)
    up = 1.0 if formulation.robot.mounting == "z-up" else -1.0
    angles = np.arccos(np.clip(up * f_axis, -1.0, 1.0))
    angles[~np.all(np.isfinite(zb), axis=1)] = np.nan
    return angles


def flipped_mounting(mounting: str) -> tuple[str, str]:
    """``(other, pose)``: the mounting opposite ``mounting`` and how a robot mounted that
    way stands (for the messages of a contradicted mounting)."""
    other = "z-down" if mounting == "z-up" else "z-up"
    return other, "hangs from its base" if other == "z-down" else "stands on its base"


def robot_fix(
    key: str, robot_file: str | None, value: str | None = None, python: bool = False
) -> str:
    """How a message says to change the robot's ``key`` (``mounting``, ``theta_max``):
    to ``value`` (``set mounting = "z-down" in the robot file R``), or up where it is
    None (``raise theta_max in the robot file R``); in the robot file where
    ``robot_file`` (as named on the command line) describes the robot, else by the
    one-section option (``give --mounting z-down``, ``raise --theta-max``), the only
    place each is given. A shipped robot named by its name (``two-section``) is changed
    in a copy of its file (:func:`~continuum_mhe.io.robot_file.shipped_robots`). For a
    caller in Python (``python``), the robot's field: ``make the Robot with
    mounting="z-down"`` (or its robot file's line), ``raise the Sections' theta_max``."""
    if python:
        if value:
            return (
                f'make the Robot with {key}="{value}" (or set {key} = "{value}" in its robot file)'
            )
        return f"raise the Sections' {key}"
    if robot_file:
        shipped = shipped_robots().get(robot_file)
        where = (
            f"in a copy of the shipped robot file {shipped} (given as --robot {robot_file})"
            if shipped is not None and not Path(robot_file).exists()
            else f"in the robot file {robot_file}"
        )
        return f'set {key} = "{value}" {where}' if value else f"raise {key} {where}"
    option = "--" + key.replace("_", "-")
    return f"give {option} {value}" if value else f"raise {option}"


#: Where an IMU further out reads upright and the one nearest the base does not, the
#: readings may be those of IMUs given in another order.
ORDER_HINT = (
    "or the IMUs in another order? IMU 1 is the one nearest the base: the columns' order, "
    "or the --topic order of a bag"
)


#: readings whose reader checked them against a robot's mounting (a recording read
#: whole by ``load_input``): ``id(z) -> (a weak reference to z, the robot)``, so that an
#: estimator's ``run`` on the same array does not say the same again
_MOUNTING_CHECKED: dict[int, tuple[weakref.ref[FloatArray], Robot]] = {}


def note_mounting_checked(z: FloatArray, robot: Robot) -> None:
    """Note that the readings ``z`` were checked against ``robot``'s mounting (their
    first readings, :func:`check_mounting`, and the whole recording,
    :class:`MountingTally`), for as long as the array lives."""
    key = id(z)
    _MOUNTING_CHECKED[key] = (
        weakref.ref(z, lambda _gone: _MOUNTING_CHECKED.pop(key, None)),
        robot,
    )


def mounting_checked(z: object, robot: Robot) -> bool:
    """Whether the array ``z`` itself was checked against ``robot``'s mounting
    (:func:`note_mounting_checked`)."""
    got = _MOUNTING_CHECKED.get(id(z))
    return got is not None and got[0]() is z and got[1] == robot


def check_mounting(
    name: str,
    z: FloatArray,
    formulation: Formulation,
    robot_file: str | None = None,
    python: bool = False,
) -> None:
    """Refuse, in one line naming ``mounting``, a recording whose first readings put
    the IMU nearest the base more than :data:`MOUNTING_FLIPPED` from the straight pose
    of the robot's stated mounting: gravity says the robot is mounted the other way
    (a hanging robot described as ``z-up``, or the reverse). Past 90 degrees (by
    :data:`MOUNTING_MARGIN`) but within it, a :class:`MountingWarning` says which
    mounting the start is closer to, and whether the sections' ``theta_max`` let the
    stated mounting reach it at all; each names the fix as the robot file's key, or
    without ``robot_file`` the option (:func:`robot_fix`; ``python``: the Robot's field).
    The IMUs further out are checked against the one before them
    (:func:`check_imu_mountings`)."""
    _check_base_mounting(name, z, formulation, robot_file, python)
    check_imu_mountings(name, z, formulation)


def check_imu_mountings(name: str, z: FloatArray, formulation: Formulation) -> None:
    """A :class:`MountingWarning` for each IMU whose first readings (where it and the
    nearest IMU before it that reads then, base first, both read) put it further from
    (or nearer to) the straight pose than that IMU by more than :data:`MOUNTING_FLIPPED`
    and more than the sections between them can bend (their ``theta_max``), or by more
    than :data:`UPSIDE_DOWN_LIKE` in any case: the difference of the two angles from the
    vertical bounds the bend between them from below, and an IMU mounted upside down
    reads such a start."""
    robot = formulation.robot
    order = sorted(range(robot.n_imus), key=lambda i: (robot.imus[i].section, robot.imus[i].at))
    angles = {k: _imu_angles(z, formulation, k) for k in order}
    for i, k in enumerate(order[1:], 1):
        # the nearest IMU before it that reads in the same rows
        pairs = ((j, np.isfinite(angles[j]) & np.isfinite(angles[k])) for j in order[i - 1 :: -1])
        found = next(((j, both) for j, both in pairs if both.any()), None)
        if found is None:
            continue
        before, both = found
        a = float(np.median(angles[before][both][:MOUNTING_START_SAMPLES]))
        b = float(np.median(angles[k][both][:MOUNTING_START_SAMPLES]))
        limit = max(MOUNTING_FLIPPED, min(_reach_between(robot, before, k), UPSIDE_DOWN_LIKE))
        if abs(b - a) <= limit:
            continue
        warnings.warn(
            f"{name}: mounting: at the start gravity puts IMU {k + 1} {math.degrees(b):.0f} "
            f"degrees from the straight pose and IMU {before + 1} {math.degrees(a):.0f} "
            "degrees: the robot between them would start bent "
            f"{math.degrees(abs(b - a)):.0f} degrees or more; is IMU {k + 1} mounted upside "
            "down? (its mount_rpy; the estimates of a "
            "robot whose IMU is mounted otherwise than its robot file says are far off)",
            MountingWarning,
            stacklevel=3,
        )


def _reach_between(robot: Robot, before: int, k: int) -> float:
    """The largest bend, rad, the sections between IMU ``before`` and IMU ``k`` (0-based,
    ``k`` further out) let the robot make between them (their ``theta_max``, in part
    where an IMU sits inside a section)."""
    first, last = robot.imus[before], robot.imus[k]
    if first.section == last.section:
        return (last.at - first.at) * robot.sections[first.section].theta_max
    reach = (1.0 - first.at) * robot.sections[first.section].theta_max
    reach += sum(s.theta_max for s in robot.sections[first.section + 1 : last.section])
    return reach + last.at * robot.sections[last.section].theta_max


def _check_base_mounting(
    name: str, z: FloatArray, formulation: Formulation, robot_file: str | None, python: bool
) -> None:
    """:func:`check_mounting`'s check of the IMU nearest the base."""
    got = start_bend_angle(z, formulation)
    if got is None or got[1] <= math.pi / 2 + MOUNTING_MARGIN:  # not clearly closer to
        return  # the other mounting's straight pose
    k, angle = got
    robot = formulation.robot
    mounting = robot.mounting
    other, pose = flipped_mounting(mounting)
    where = (
        f"{name}: mounting: the robot is described as {mounting}, but at the start gravity "
        f"puts IMU {k + 1} {math.degrees(angle):.0f} degrees from that mounting's straight "
        f"pose ({180 - math.degrees(angle):.0f} from {other}'s)"
    )
    # IMUs that read within 90 degrees of the stated mounting: then the IMUs that read
    # more than 90 degrees off it, this one and any other, may be the ones mounted
    # upside down
    starts = {j: imu_start_angle(z, formulation, j) for j in range(robot.n_imus) if j != k}
    upright = [j + 1 for j, a in starts.items() if a is not None and a < math.pi / 2]
    off = sorted([k + 1, *(j + 1 for j, a in starts.items() if a is not None and a >= math.pi / 2)])
    imu = robot.imus[k]
    reach = bend_reach(robot, k)
    alone = ""
    if upright:
        reads = "reads" if len(upright) == 1 else "read"
        said = f"IMU {', '.join(map(str, upright))} {reads} upright"
        if len(off) == 1:
            boards, question = f"IMU {k + 1} alone", f"is IMU {k + 1} alone"
            their = "its"
        else:
            said += f", IMU {', '.join(map(str, off))} the other way"
            boards = f"IMU {', '.join(map(str, off))}"
            question, their = f"are {boards}", "their"
        # a robot that starts bent this far, within its theta_max, reads so as well
        bent = (
            "; or a start bent this far, within the sections' theta_max? start the "
            "recording where the robot is nearer straight"
            if angle <= reach + MOUNTING_MARGIN or robot.has_mechanics
            else ""
        )
        alone = f" ({said}: {question} mounted upside down? {their} mount_rpy; {ORDER_HINT}{bent})"
    # a board the robot file mounts upside down (its mount_rpy turns it past 90
    # degrees): another IMU's readings in its columns read upside down too
    turned = [
        j + 1
        for j, place in enumerate(robot.imus)
        if math.cos(math.radians(place.mount_rpy[0])) * math.cos(math.radians(place.mount_rpy[1]))
        < 0.0
    ]
    if turned and not upright and len(turned) < robot.n_imus:
        boards = "IMU " + ", ".join(map(str, turned))
        alone = (
            f" ({ORDER_HINT}; {boards} is mounted upside down in the robot file's mount_rpy, "
            "so another IMU's readings in its columns read upside down too)"
        )
    fix = robot_fix("mounting", robot_file, other, python)
    # an IMU beyond the first section of a robot whose IMUs do not determine its shape:
    # the sections before it may have bent it this far, within their theta_max (a start
    # bent, not a robot mounted the other way)
    unread = (
        f"; IMU {k + 1} is on section {imu.section + 1}, and the sections before it, whose "
        "bends the robot's IMUs do not determine, may bend it this far"
        if imu.section > 0
        and angle <= reach + MOUNTING_MARGIN
        and not formulation.imus_determine_shape(tuple(range(robot.n_imus)))
        else ""
    )
    if angle > MOUNTING_FLIPPED and not unread:
        # no IMU reads upright to tell, and the sections can bend this far: a start
        # curled past 135 degrees reads the same as the other mounting
        curled = (
            f"; or a start bent {math.degrees(angle):.0f} degrees, within the sections' "
            f"theta_max ({math.degrees(reach):.0f} degrees)? the other mounting would then "
            "put every estimate far off: start the recording where the robot is nearer "
            "straight (in Python, continue_run(..., check_mounting_start=False) skips this "
            "check)"
            if not upright and angle <= reach and not robot.has_mechanics
            else ""
        )
        raise MountingError(f"{where}: the robot {pose}? {fix}{alone}{curled}")
    bound = ""
    if angle > reach + MOUNTING_MARGIN and not robot.has_mechanics:
        raise_it = robot_fix("theta_max", robot_file, python=python)
        bound = (
            f"; it is beyond the {math.degrees(reach):.0f} degrees the sections' theta_max "
            f"let it bend (if the robot does bend so far, {raise_it})"
        )
    if upright:  # a start bent this far is the likelier reading of a warning's angle
        alone = (
            f" ({said}: a start bent this way, or {boards} mounted upside down, "
            f"{their} mount_rpy; {ORDER_HINT})"
        )
    warnings.warn(  # a bend past 90 degrees at the start, or the other mounting
        f"{where}: if the robot {pose}, {fix} (the estimates of a robot described the "
        f"wrong way up are far off){alone}{bound}{unread}",
        MountingWarning,
        stacklevel=4,
    )
