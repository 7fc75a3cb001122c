"""Reading an input for an estimator: one pipeline from a path and the input options
to estimator-ready measurements and the input's own description.

Every command that estimates from a recording reads it here (``estimate``; ``live``'s
serial line formats through :func:`serial_input`; ``calibrate``'s recordings through
:func:`read_recording`). The steps, in order:

1. **which input**: a ROS bag or MCAP file (:func:`~continuum_mhe.io.robot_logs.is_robot_log`),
   else a text table (a file, ``-``, a pipe or a FIFO), tilt or raw by its header;
2. **how it is read** (:func:`resolve`, the one place the options meet the input): an
   option that would do nothing on this input is refused, the IMU model is decided
   (raw input with gyros takes the direct model unless ``--imu-model`` says otherwise),
   and the formulation the measurements are for is made;
3. **the samples**: a text table is read once, front to back, :data:`CHUNK` rows at a
   time, validated (units, time steps, ranges) and converted (raw vectors per IMU, with
   the robot file's mounting and gyro bias); the first readings are checked against the
   robot's stated mounting; which IMUs reported is counted. Bags and MCAP files are read
   whole (their readers index the file). Memory stays flat in a table's length;
4. **tendon tensions** (``InputOptions.tensions``, else the recording's own
   ``tension_1..k`` columns, as ``live --record`` writes them): where the robot has a
   backbone, the tensions are read and checked before the recording, and each sample
   gets the tensions at its time appended (:mod:`continuum_mhe.io.tensions`).

:func:`open_input` gives a :class:`MeasurementStream` (one sample at a time, with its
:class:`InputDescription`); :func:`load_input` reads an input whole.
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, expect_type, time_text
from continuum_mhe.io.csv_files import (
    DegreesCheck,
    ReadingCounts,
    UnitWarning,
    check_time_units,
    read_measurements,
    tilt_sample_columns,
    tilt_values,
)
from continuum_mhe.io.imu_columns import ROBOT_FIX, TENDON_ROBOT_FIX
from continuum_mhe.io.imu_topics import read_imu_topics
from continuum_mhe.io.input_options import (
    InputOptions,
    MountingTally,
    OptionWarning,
    check_mounting,
    check_options_apply,
    formulation_for,
    imu_settings_for,
    note_mounting_checked,
    refuse_uncalibrated_madgwick,
    with_imu_model,
)
from continuum_mhe.io.raw_imu import (
    RawImuConverter,
    RawImuSettings,
    csv_input_kind,
    impossible_readings,
    raw_blocks,
    raw_layout,
    read_raw_imus,
    sample_kind,
    warn_clipped,
)
from continuum_mhe.io.raw_units import (
    ACCEL_READING_MAX,
    GYRO_READING_MAX,
    MotionUnitWatch,
    check_accel_range,
    check_accel_units,
    check_gyro_units,
)
from continuum_mhe.io.robot_logs import (
    ImuLog,
    is_robot_log,
    read_imu_log,
    refuse_bag_metadata,
    tilt_from_quaternion,
)
from continuum_mhe.io.sample_rows import RowProblems, SampleBlock, sample_blocks
from continuum_mhe.io.tensions import (
    Tensions,
    on_log_clock,
    read_tensions,
    tendon_formulation_for,
    tension_columns,
    tension_columns_in,
)
from continuum_mhe.io.text_rows import TextRows, open_rows
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.robot import Robot, mount_taken
from continuum_mhe.model.tendon import TendonFormulation

#: Rows validated and converted together (bounds the memory of a streamed input).
CHUNK = 4096

#: What an input is: a tilt table, a raw table, or a robot log (bag, MCAP). ``live``'s
#: line formats are the table kinds.
InputKind = Literal["tilt-csv", "raw-csv", "log"]

Convert = Callable[[FloatArray, FloatArray, Sequence[int]], FloatArray]


@dataclass
class InputDescription:
    """What an input is and how it was read.

    Attributes:
        name: the input as shown in messages (``<stdin>`` for ``-``).
        kind: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"``.
        columns: the columns read (``t`` first), or for a log the Imu topics read.
        units: the units the values are read in (one phrase, e.g. ``t in s; roll,
            pitch in deg``).
        imu_model: how the IMUs are measured: ``tilt`` (roll and pitch, read or
            computed from raw vectors) or ``direct`` (raw accelerometer and gyro
            vectors, :mod:`continuum_mhe.model.direct`).
        tensions: the tendon tensions file appended to each sample, if any.
        problems: rows skipped or read as dropouts with ``skip_bad`` (count and the
            first few), filled as the samples are read.
        readings: which IMUs reported, counted as the samples are read (once they are
            all read, a :class:`~continuum_mhe.io.csv_files.DropoutWarning` names an
            IMU that never reported).
        notes: lines for the user about how the input was read (e.g. how the samples
            of several IMU topics paired).
    """

    name: str
    kind: InputKind
    columns: tuple[str, ...]
    units: str
    imu_model: str
    tensions: str | None = None
    problems: RowProblems = field(default_factory=RowProblems)
    readings: ReadingCounts | None = None
    notes: tuple[str, ...] = ()

    @property
    def time_in_ms(self) -> bool:
        """The table's time column is ``t_ms`` (read in milliseconds)."""
        return self.units.startswith("t in ms")

    def summary(self) -> tuple[str, ...]:
        """Clauses for a run's summary line: the IMUs' readings and the bad rows (none
        where there is nothing to say)."""
        clauses = (self.readings.summary() if self.readings else "", self.problems.summary())
        return tuple(c for c in clauses if c)


@dataclass
class MeasurementStream:
    """Measurements of one input, produced one at a time; a context manager.

    Attributes:
        description: what the input is and how it was read (its skip counts are
            complete once ``blocks`` is exhausted).
        formulation: the formulation the measurements are for.
        blocks: ``(t, z)``: (n,) s, (n, nz) measurements (C-contiguous float64), a
            block of samples at a time, up to :data:`CHUNK`; read once (``blocks`` or
            ``samples``).
        t0_ns: absolute time of ``t = 0``, ns (0 for a text table).
    """

    description: InputDescription
    formulation: Formulation
    blocks: Iterator[tuple[FloatArray, FloatArray]]
    t0_ns: int = 0
    _rows: TextRows | None = None

    @property
    def samples(self) -> Iterator[tuple[float, FloatArray]]:
        """``(t, z)``: s, (nz,) measurement, one sample at a time (of :attr:`blocks`)."""
        for t, z in self.blocks:
            yield from zip(t.tolist(), z)

    @property
    def name(self) -> str:
        return self.description.name

    @property
    def kind(self) -> InputKind:
        return self.description.kind

    def close(self) -> None:
        if self._rows is not None:
            self._rows.close()

    def __enter__(self) -> MeasurementStream:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class EstimateInput:
    """An input read whole: measurements ready for an estimator.

    Attributes:
        kind: ``"tilt-csv"``, ``"raw-csv"`` or ``"log"``.
        t: (n,) s; z: (n, nz) measurements for ``formulation``.
        t0_ns: absolute time of ``t = 0``, ns (0 for CSV input).
        skipped: descriptions of skipped samples.
        notes: one-line reports for the user (e.g. how samples of several topics paired).
        clock: what a robot log's ``t`` was read from
            (:attr:`~continuum_mhe.io.robot_logs.ImuLog.clock`).
        dropouts: a robot log's messages whose bad reading ``skip_bad`` read as a
            dropout of their IMU (a CSV's are among ``skipped``).
    """

    kind: str
    t: FloatArray
    z: FloatArray
    formulation: Formulation
    t0_ns: int = 0
    skipped: list[str] = field(default_factory=list)
    notes: tuple[str, ...] = ()
    clock: str = "header stamps"
    dropouts: list[str] = field(default_factory=list)


# --- step 2: the options against this input ----------------------------------------------
def resolve(
    name: str, kind: InputKind, has_gyro: bool, options: InputOptions, base: Formulation
) -> tuple[InputOptions, Formulation]:
    """The options and formulation for an input of ``kind`` (raw vectors with gyros
    where ``has_gyro``): an option that does nothing on it is refused
    (:func:`~continuum_mhe.io.input_options.check_options_apply`), then
    :func:`decide_model`. One line naming ``name`` and the problem for each. A robot
    log runs the two apart: the first before its topics are read, the second after."""
    check_options_apply(name, kind, options, base.robot)
    return decide_model(name, kind, has_gyro, options, base)


def decide_model(
    name: str, kind: InputKind, has_gyro: bool, options: InputOptions, base: Formulation
) -> tuple[InputOptions, Formulation]:
    """The IMU model decided (:func:`~continuum_mhe.io.input_options.with_imu_model`:
    raw vectors with gyros take the direct model unless ``--imu-model`` says otherwise),
    the formulation made (:func:`~continuum_mhe.io.input_options.formulation_for`),
    an IMU model or attitude filter that needs gyros refused without them, and
    ``--attitude madgwick`` on IMUs without a calibrated gyro bias refused
    (:func:`~continuum_mhe.io.input_options.refuse_uncalibrated_madgwick`)."""
    raw_input = kind != "tilt-csv"
    if raw_input and has_gyro and not options.use_orientation:  # before any warning
        refuse_uncalibrated_madgwick(name, options, base.robot)
    options = with_imu_model(options, base, raw_input, has_gyro)
    f = formulation_for(options, base, raw_input, Path(name))
    if raw_input and not options.use_orientation and options.raw.needs_gyro and not has_gyro:
        raise InputError(f"{name}: {_gyro_user(options.raw)} needs gyro columns gx, gy, gz")
    return options, f


def _gyro_user(raw: RawImuSettings) -> str:
    return "--imu-model direct" if raw.imu_model == "direct" else f"--attitude {raw.attitude}"


@dataclass(frozen=True)
class SerialInput:
    """How ``live`` reads its stream of lines.

    Attributes:
        formulation: the formulation the measurements are for (a robot with a backbone:
            its tendon formulation, as ``estimate`` makes it).
        converters: one raw converter per IMU (None for tilt lines).
        tensions: the tensions file (``--inputs``) of a tendon robot, if given.
        tensions_on_line: the tendon tensions each line carries after the IMUs' values
            (a tendon robot without a tensions file; else 0).
    """

    formulation: Formulation
    converters: list[RawImuConverter] | None
    tensions: Tensions | None = None
    tensions_on_line: int = 0


def serial_input(
    port: str, fmt: Literal["raw", "tilt"], options: InputOptions, base: Formulation
) -> SerialInput:
    """``live``'s stream of ``fmt`` lines (every raw line carries the gyros): the
    formulation (:func:`resolve`, as for a table of that kind), one raw converter per
    IMU (None for tilt lines) and, for a tendon robot, where its tensions come from:
    the tensions file of ``options`` (read and checked here, as ``estimate`` reads it),
    else every line's fields after the IMUs'."""
    if options.raw.imu_model == "direct" and fmt != "raw":
        check_options_apply(port, "tilt-csv", options, base.robot)
        raise InputError("--imu-model direct needs --format raw")
    kind: InputKind = "raw-csv" if fmt == "raw" else "tilt-csv"
    resolved, f = resolve(port, kind, fmt == "raw", options, base)
    converters = imu_converters(resolved.raw, base.robot) if fmt == "raw" else None
    robot = base.robot
    tensions = _tensions(options, robot, None, None) if options.tensions else None
    if tensions is not None:
        tensions.check_steps()
    if not robot.has_mechanics:
        return SerialInput(f, converters)
    on_line = 0 if tensions is not None else robot.n_tendons
    return SerialInput(tendon_formulation_for(f, options), converters, tensions, on_line)


def raw_measurements(
    robot: Robot,
    t: FloatArray,
    acc: FloatArray,
    gyr: FloatArray | None = None,
    *,
    raw: RawImuSettings | None = None,
) -> FloatArray:
    """A robot's raw IMU arrays as the measurements (n, nz) its formulation takes, as the
    command line converts a raw recording: ``acc`` (n, n_imus, 3) specific force, m/s^2,
    and ``gyr`` (n, n_imus, 3) rad/s or None, in each sensor's frame; each IMU's
    ``mount_rpy`` turns it into its disk's frame and its ``gyro_bias`` is removed
    (:func:`imu_converters`). The IMU model is ``raw.imu_model``, else ``direct`` with
    gyros (``make_formulation("direct", robot)``) and ``tilt`` without. NaN in any axis
    of a sample's accelerometer or gyro reading is that IMU's dropout there (both its
    readings NaN in the result), and so is an accelerometer reading of exactly zero on
    every axis (no gravity direction: a sensor that returned nothing); an infinite
    reading, or one beyond any IMU's range (an acceleration of more than 1e4 m/s^2, a
    rate of more than 1e3 rad/s), is a :class:`UserError` naming the sample and the
    IMU."""
    expect_type("robot", robot, Robot, "a Robot (read_robot(NAME) reads a robot file)")
    acc = np.asarray(acc, dtype=float)
    n_imus = robot.n_imus
    if acc.ndim != 3 or acc.shape[1:] != (n_imus, 3):
        raise UserError(
            f"acc must be (n, {n_imus}, 3): each sample's specific force per IMU, got shape "
            f"{acc.shape}"
        )
    gyro = None if gyr is None else np.asarray(gyr, dtype=float)
    if gyro is not None and gyro.shape != acc.shape:
        raise UserError(f"gyr must have acc's shape {acc.shape}, got {gyro.shape}")
    t = np.asarray(t, dtype=float)
    if t.shape != (len(acc),):
        raise UserError(f"t must be (n,) = ({len(acc)},), one time per sample, got {t.shape}")
    _check_reading_range("acc", acc, ACCEL_READING_MAX, "m/s^2")
    if gyro is not None:
        _check_reading_range("gyr", gyro, GYRO_READING_MAX, "rad/s")
    settings = raw if raw is not None else RawImuSettings()
    if settings.imu_model is None:
        settings = replace(settings, imu_model="direct" if gyro is not None else "tilt")
    converters = imu_converters(settings, robot)
    z = np.hstack(
        [
            c.convert_many(t, acc[:, i], None if gyro is None else gyro[:, i])
            for i, c in enumerate(converters)
        ]
    )
    warn_clipped("raw_measurements", converters)
    return z


def _check_reading_range(name: str, values: FloatArray, limit: float, unit: str) -> None:
    """A :class:`UserError` naming the first sample and IMU of ``values`` (n, n_imus,
    3) whose reading is infinite or of a magnitude beyond ``limit`` (NaN: a dropout)."""
    magnitude = np.hypot.reduce(values, axis=2)  # hypot: no overflow of a finite 1e200
    beyond = np.argwhere(magnitude > limit)
    if len(beyond):
        j, i = (int(v) for v in beyond[0])
        raise UserError(
            f"{name}[{j}, {i}] (sample {j}, IMU {i + 1}): a reading beyond any IMU's range "
            f"(|{name}| {magnitude[j, i]:.3g} {unit}, limit {limit:g}): a corrupt value; "
            "NaN marks a dropout"
        )


def imu_converters(raw: RawImuSettings, robot: Robot) -> list[RawImuConverter]:
    """One converter per IMU of ``robot``: its robot-file mounting and gyro bias where it
    gives them, else ``raw``'s (:func:`~continuum_mhe.io.input_options.imu_settings_for`);
    the robot's readings are then in its disks' frames (:func:`mount_taken`)."""
    mount_taken(robot)
    return [RawImuConverter(imu_settings_for(raw, imu)) for imu in robot.imus]


# --- the pipeline ----------------------------------------------------------------------------
def _check_arguments(path: object, options: object, formulation: object) -> None:
    """A :class:`UserError` naming the argument of :func:`open_input` or
    :func:`load_input` that is not of its type."""
    expect_type("path", path, (str, os.PathLike), "a file path (a str or pathlib.Path)")
    expect_type("options", options, InputOptions, "an InputOptions (continuum_mhe.io.InputOptions)")
    expect_type("formulation", formulation, Formulation, "a Formulation (make_formulation)")


def open_input(
    path: str | os.PathLike[str],
    options: InputOptions,
    formulation: Formulation,
    robot_name: str | None = None,
    *,
    python: bool = False,
) -> MeasurementStream:
    """Open any input of ``estimate`` (tilt or raw CSV, ``-``, bag, MCAP) as a stream of
    measurements for ``formulation``'s robot, tendon tensions appended where it has a
    backbone (``robot_name``: the robot file as named in messages, whose keys they name
    as the fix; None: the command line's one-section options, ``--mounting`` and
    ``--theta-max``; ``python``: a caller in Python, whose messages name the Robot's
    fields instead)."""
    _check_arguments(path, options, formulation)
    tensions = _tensions(options, formulation.robot, robot_name, path)
    stream = _open_measurements(path, options, formulation, robot_name, python)
    _say_unused_tension_columns(path, formulation.robot, robot_name)
    if formulation.robot.has_mechanics:
        _append_tensions(stream, tensions, options)
    return stream


def load_input(
    path: str | os.PathLike[str], options: InputOptions, formulation: Formulation
) -> EstimateInput:
    """Read any supported input (tilt CSV, raw CSV, bag, MCAP) whole, as measurements
    for ``formulation``'s robot, as :func:`open_input` streams them: a robot with
    tendons is read with its tensions (``options.tensions``, or the recording's own
    tension columns; without them an :class:`InputError` says how to give them), and
    the formulation returned is its mechanics model. The first readings are checked
    against the robot's mounting, as ``estimate`` checks them; the messages name the
    Robot's fields."""
    _check_arguments(path, options, formulation)
    p = Path(path)
    if is_robot_log(p) and options.tensions is None and not formulation.robot.n_tendons:
        data = _load_log(p, options, formulation)
        check_mounting(str(p), data.z, data.formulation, python=True)
        tally = MountingTally(data.formulation)
        tally.add(data.z)
        tally.warn(str(p), python=True)
        note_mounting_checked(data.z, data.formulation.robot)
        return data
    with open_input(path, options, formulation, python=True) as stream:
        problems = stream.description.problems
        problems.keep = sys.maxsize
        blocks = list(stream.blocks)
    nz = stream.formulation.nz
    t = np.concatenate([b[0] for b in blocks]) if blocks else np.empty(0)
    z = np.vstack([b[1] for b in blocks]) if blocks else np.empty((0, nz))
    note_mounting_checked(z, stream.formulation.robot)  # the stream checked them
    return EstimateInput(
        stream.kind, t, z, stream.formulation, stream.t0_ns, problems.first,
        stream.description.notes,
    )  # fmt: skip


def read_recording(
    path: str, n_imus: int, degrees: bool = False, topics: Sequence[str] = ()
) -> tuple[Literal["raw", "tilt"], FloatArray, FloatArray]:
    """``(format, t, values)`` of a raw or tilt CSV as recorded (``live --record``), or
    of a ROS bag or MCAP file's Imu ``topics`` (one per IMU, in the robot file's order;
    none for a log with one Imu topic), unconverted: tilt values in rad (``degrees``:
    the file's are in degrees), raw ``ax, ay, az, gx, gy, gz`` per IMU (m/s^2, rad/s);
    the raw form needs every IMU's gyro. ``degrees`` for a raw recording, and
    ``topics`` for a CSV file, are refused in one line. Small angles read as degrees are
    not said to look like radians: a robot at rest, straight, reads them."""
    if is_robot_log(Path(path)):
        if degrees:
            raise InputError(f"{path}: --degrees is for a tilt CSV recording's roll and pitch")
        return "raw", *_raw_log_recording(Path(path), n_imus, topics)
    refuse_bag_metadata(path)
    if topics:
        raise InputError(f"{path}: --topic chooses the IMUs of a ROS bag or MCAP file")
    if csv_input_kind(path) == "tilt":
        with warnings.catch_warnings():  # a still, straight robot's angles are small
            warnings.filterwarnings("ignore", r".*: read in degrees \(--degrees", UnitWarning)
            tilt = read_measurements(path, n_imus=n_imus, degrees=degrees)
        return "tilt", tilt.t, tilt.z
    if degrees:
        raise InputError(
            f"{path}: --degrees is for a tilt recording's roll and pitch; this one is raw "
            "(accelerometer in m/s^2, gyro in rad/s)"
        )
    # an impossible reading (a zero acceleration, one beyond any IMU's range): left out,
    # and said by the caller, of one IMU as of several
    tables = read_raw_imus(path, n_imus, fix=ROBOT_FIX, range_dropouts=True).imus
    for i, tab in enumerate(tables, start=1):
        if tab.gyr is None:
            raise InputError(f"{path}: IMU {i} has no gyro columns (gx, gy, gz)")
    values = np.hstack([np.hstack([tab.acc, tab.gyr]) for tab in tables])  # type: ignore[list-item]
    return "raw", tables[0].t, values


def _raw_log_recording(
    path: Path, n_imus: int, topics: Sequence[str]
) -> tuple[FloatArray, FloatArray]:
    """``(t, values)`` of a robot log's Imu ``topics``, paired as ``estimate`` pairs
    them: ``ax, ay, az, gx, gy, gz`` per IMU, NaN where a topic has no sample, and where
    a message's acceleration is zero or its reading beyond any IMU's range (its
    acceleration; its rates too for a reading beyond range), as a multi-IMU table's."""
    if n_imus > 1 or len(topics) > 1:
        paired = read_imu_topics(path, topics, n_imus)
        logs, t = paired.logs, paired.t
    else:
        log = read_imu_log(path, topics[0] if topics else None)
        logs, t = (log,), log.t
    blocks = []
    for i, log in enumerate(logs, start=1):
        if log.gyr is None:
            raise InputError(
                f"{path}: topic {log.topic} (IMU {i}) has no angular rates "
                "(angular_velocity_covariance[0] = -1 in every message): calibrate needs "
                "every IMU's gyro"
            )
        name = f"{path}: topic {log.topic}"
        # a zero or impossible reading is left out, as a multi-IMU table's is (said by
        # the caller), not averaged into the rest
        acc, gyr = np.array(log.acc, dtype=float), np.array(log.gyr, dtype=float)
        _, _, zero, huge = impossible_readings(acc, gyr)
        acc[zero | huge] = np.nan
        gyr[huge] = np.nan
        check_accel_units(name, acc)
        check_gyro_units(name, gyr, True, t, acc)
        blocks.append(np.hstack([acc, gyr]))
    return t, np.hstack(blocks)


def _open_measurements(
    path: str | os.PathLike[str],
    options: InputOptions,
    formulation: Formulation,
    robot_name: str | None = None,
    python: bool = False,
) -> MeasurementStream:
    expect_type("formulation", formulation, Formulation, "a Formulation (make_formulation)")
    if isinstance(formulation, TendonFormulation):
        raise InputError(
            f"{path}: the input is read for the robot's kinematic formulation "
            f"(make_formulation('bend', robot)), not {formulation.name!r}: the model it "
            "calls for (direct for raw IMUs, tendon with the tensions) is made from it"
        )
    if str(path) != "-" and is_robot_log(Path(path)):
        return _log_stream(Path(path), options, formulation, robot_name, python)
    refuse_bag_metadata(path)
    _refuse_folder(path)
    rows = open_rows(path)
    try:
        return _table_stream(rows, options, formulation, robot_name, python)
    except BaseException:
        rows.close()
        raise


def _refuse_folder(path: str | os.PathLike[str]) -> None:
    """One line for a folder given as the recording that is not a ROS 2 bag (the
    caller has asked :func:`is_robot_log`), naming the logs it holds."""
    if str(path) != "-" and Path(path).is_dir():  # not a bag folder: is_robot_log said so
        # a ROS 2 recorder killed before it wrote metadata.yaml leaves its storage file:
        # an MCAP (or a ROS 1 bag) reads alone, a SQLite .db3 needs its metadata
        logs = sorted(f for f in Path(path).iterdir() if f.is_file() and is_robot_log(f))
        alone = [f.name for f in logs if f.suffix.lower() != ".db3"]
        hint = ""
        if alone:
            named = ", ".join(alone[:3]) + (", ..." if len(alone) > 3 else "")
            one = "the file itself" if len(alone) == 1 else "one of them"
            hint = f"; it holds {named}: give {one} (a recorder that stopped?)"
        elif logs:
            hint = (
                f"; it holds {logs[0].name}, a ROS 2 bag's SQLite file, which needs the "
                "metadata.yaml: a recorder that stopped? ros2 bag reindex writes it"
            )
        raise InputError(
            f"{path}: is a directory without metadata.yaml, expected a CSV file or a ROS 2 "
            f"bag folder{hint}"
        )


# --- step 4: tendon tensions -----------------------------------------------------------------
def _tensions(
    options: InputOptions,
    robot: Robot,
    robot_name: str | None,
    recording: str | os.PathLike[str] | None,
) -> Tensions | None:
    """The tensions file, read and checked for the robot's tendons (before the input):
    ``--inputs``, else the ``recording``'s own tension columns (whose times are the
    recording's). Its times are checked against the recording's by
    :func:`_append_tensions` (:meth:`Tensions.check_span`), or, for ``live``, which has
    no recording before it runs, by the caller (:meth:`Tensions.check_steps`)."""
    given = options.tensions
    k = robot.n_tendons
    if not k:
        if given:
            raise InputError(
                f"{given}: --inputs gives tendon tensions, but the robot has no [[tendon]]"
            )
        return None
    columns = _own_tension_columns(recording)
    own = set(tension_columns(k)) <= set(columns)
    if given:
        table = read_tensions(given, k, skip_bad=options.skip_bad, time_warning=False)
        if own:
            assert recording is not None
            warnings.warn(
                f"{recording}: the recording carries tension columns, but the tensions "
                f"of --inputs {given} are the ones used{_tensions_compared(recording, k, table)}",
                OptionWarning,
                stacklevel=2,
            )
        table.check_scale(robot)
        if recording is None:  # else once the recording's span is known (_append_tensions)
            table.warn_suspect()
        table.warn_smoothed()
        table.warn_held()
        return table
    if own:
        assert recording is not None
        table = read_tensions(
            recording, k, other_columns=True, skip_bad=options.skip_bad, time_warning=False
        )
        table.check_scale(robot)
        table.warn_suspect()
        table.warn_slower_log()
        return table
    if columns:  # some of the tension columns, not all
        missing = [c for c in tension_columns(k) if c not in columns]
        raise InputError(
            f"{recording}: line 1: the robot has {k} tendons, but the recording's tension "
            f"columns are {','.join(columns)}: no {','.join(missing)} (or give the tensions "
            "with --inputs TENSIONS.csv)"
        )
    log = recording is not None and is_robot_log(Path(recording))
    if recording is not None and str(recording) != "-" and not log:
        # the recording's own fault first: a name with no file behind it is no pipe
        if not os.path.exists(recording):
            raise InputError(f"{recording}: no such file")
        refuse_bag_metadata(recording)  # a bag's metadata file has no tension columns
        _refuse_folder(recording)
    where = (
        "a robot log's topics do not carry them"
        if log
        else f"or as the recording's columns tension_1..tension_{k}"
        if recording is None or os.path.isfile(recording)
        else f"or as the columns tension_1..tension_{k} of a recording read from a file: "
        "from standard input or a pipe they are not read (the tensions are read ahead of "
        "the samples)"
    )
    raise InputError(
        f"{robot_name or 'the robot file'}: the robot has {k} tendons: give their tensions "
        f"with --inputs TENSIONS.csv (t,tension_1,...; InputOptions(tensions=...) in Python), "
        f"{where}"
    )


def _own_tension_columns(recording: str | os.PathLike[str] | None) -> list[str]:
    """The tension columns of the recording ``recording``, a table file (none for a
    robot log, standard input or no recording)."""
    if (
        recording is None
        or is_robot_log(Path(recording))
        or str(recording) == "-"
        or not os.path.isfile(recording)
    ):
        return []
    return tension_columns_in(recording)


def _say_unused_tension_columns(
    recording: str | os.PathLike[str], robot: Robot, robot_name: str | None
) -> None:
    """An :class:`OptionWarning` naming the recording's own tension columns where the
    robot has no tendons to take them."""
    columns = _own_tension_columns(recording) if not robot.n_tendons else []
    if columns:
        several = len(columns) > 1
        warnings.warn(
            f"{recording}: its column{'s' if several else ''} {_column_span(columns)} "
            f"{'are' if several else 'is'} not used: the robot "
            f"({robot_name or robot.describe()}) has no [[tendon]] (a tendon robot's "
            "file, with [backbone] and its [[tendon]]s, takes them)",
            OptionWarning,
            stacklevel=3,
        )


def _column_span(columns: list[str]) -> str:
    """``a..b`` for more than two column names, else them joined by commas."""
    return f"{columns[0]}..{columns[-1]}" if len(columns) > 2 else ",".join(columns)


def _tensions_compared(recording: str | os.PathLike[str], k: int, given: Tensions) -> str:
    """How the recording's own tension columns compare with the ``given`` file's at the
    recording's rows the file covers: `` (the same tensions)``, `` (they differ by up
    to X N)``, or ``""`` where they cannot be compared."""
    try:
        own = read_tensions(recording, k, other_columns=True, time_warning=False)
    except InputError:
        return ""
    inside = (own.t >= given.t[0]) & (own.t <= given.t[-1])
    if not inside.any():
        return ""
    at = np.column_stack([np.interp(own.t[inside], given.t, v) for v in given.rows.T])
    gap = float(np.abs(own.values[inside] - at).max())
    if gap <= 1e-6 * max(1.0, float(np.abs(at).max())):
        return " (the same tensions)"
    return f" (they differ by up to {gap:.3g} N)"


def _append_tensions(
    stream: MeasurementStream, tensions: Tensions | None, options: InputOptions
) -> None:
    """Switch ``stream`` to the tendon formulation of its robot, each sample with the
    tensions (interpolated at its time) and their rates appended. Once the stream has
    given its last block (the recording's span known), the tensions' span is checked
    and the rows of ``--inputs`` the recording used are checked for a frozen logger or
    a hole (:meth:`Tensions.warn_suspect`): a reader that stops early sees neither."""
    f = tendon_formulation_for(stream.formulation, options)
    k = f.robot.n_tendons
    blocks = stream.blocks
    if tensions is not None:
        # a robot log's tensions on its clock (times since 1970, as the log's stamps):
        # the log's t = 0 is its first sample's stamp, t0_ns
        tensions, note = on_log_clock(tensions, stream.t0_ns)
        if note:
            stream.description.notes += (note,)

    def with_tensions() -> Iterator[tuple[FloatArray, FloatArray]]:
        first = last = math.nan
        n = 0  # the recording's samples
        for t, z in blocks:
            if len(t):
                first = t[0] if math.isnan(first) else first
                last = t[-1]
                n += len(t)
            rows = []
            for tv, zv in zip(t.tolist(), z):
                given = tensions.at(tv, stream.name) if tensions is not None else (np.zeros(k),) * 3
                rows.append(f.measurement_row(zv, *given))
            yield t, np.array(rows, dtype=np.float64).reshape(len(t), f.nz)
        if tensions is not None:  # the recording's whole span known: milliseconds?
            tensions.check_span(float(first), float(last))
            if options.tensions and n:  # the rows of --inputs that the recording used
                tensions.warn_suspect(float(first), float(last))
            if n >= 2:
                tensions.warn_sparse((float(last) - float(first)) / (n - 1), stream.name)

    stream.formulation, stream.blocks = f, with_tensions()
    stream.description.tensions = None if tensions is None else tensions.name


# --- step 3: the samples of a text table -----------------------------------------------------
def _table_units(rows: TextRows, kind: InputKind, options: InputOptions) -> str:
    t_unit = "ms" if rows.time_scale == 1e-3 else "s"
    if kind == "tilt-csv":
        return f"t in {t_unit}; roll, pitch in {'deg' if options.degrees else 'rad'}"
    return f"t in {t_unit}; acceleration in m/s^2, gyro in rad/s"


def _table_stream(
    rows: TextRows,
    options: InputOptions,
    base: Formulation,
    robot_name: str | None = None,
    python: bool = False,
) -> MeasurementStream:
    n_imus, name = base.robot.n_imus, rows.name
    fix = TENDON_ROBOT_FIX if getattr(base.robot, "n_tendons", 0) else ROBOT_FIX  # count off
    problems = RowProblems()
    convert: Convert
    kind: InputKind
    finish: Callable[[], None] | None = None  # what to say once every sample is read
    mounting_hint: Callable[[], str | None] | None = None  # what a mounting refusal adds
    notes: tuple[str, ...] = ()
    if sample_kind(rows) == "raw":
        kind = "raw-csv"
        cols, has_gyro = raw_layout(rows, n_imus, fix)
        options, f = resolve(name, kind, has_gyro, options, base)
        if not has_gyro:
            notes = (NO_GYRO_NOTE,)
        convs = imu_converters(options.raw, base.robot)

        read = [0]  # the blocks read so far
        motion_watch = MotionUnitWatch(rows.time_scale)

        def convert(t: FloatArray, values: FloatArray, lines: Sequence[int]) -> FloatArray:
            blocks = raw_blocks(
                name, values, lines, n_imus, has_gyro, options.skip_bad, problems,
                options.raw.needs_gyro, first_block=read[0] == 0, t=t,
                motion_watch=motion_watch,
            )  # fmt: skip
            read[0] += 1
            return np.hstack(
                [conv.convert_many(t, acc, gyr) for conv, (acc, gyr) in zip(convs, blocks)]
            )

        finish = partial(warn_clipped, name, convs)  # the clipped readings, said once

    else:
        kind = "tilt-csv"
        if n_imus > 1 and options.raw.imu_model == "direct":  # before the column checks
            raise InputError(f"{name}: --imu-model direct needs raw accelerometer and gyro input")
        if base.name == "direct":  # a caller in Python who made the raw model
            raise InputError(
                f"{name}: tilt readings (roll, pitch) are read for the robot's kinematic "
                "formulation (make_formulation('bend', robot)), not 'direct', which takes raw "
                "accelerometer and gyro readings"
            )
        cols = tilt_sample_columns(rows, n_imus, fix)
        options, f = resolve(name, kind, False, options, base)

        degrees_seen = DegreesCheck()

        def convert(t: FloatArray, values: FloatArray, lines: Sequence[int]) -> FloatArray:
            out_of_range: list[str] | None = [] if options.skip_bad else None
            z = tilt_values(
                name, values, lines, options.degrees, n_imus, out_of_range,
                [rows.as_written(c) for c in cols[1:]],
            )  # fmt: skip
            for what in out_of_range or ():
                problems.add(what)
            if options.degrees:
                degrees_seen.add(np.where(np.isfinite(z), values, np.nan))
            return z

        if options.degrees:
            finish = partial(degrees_seen.warn, name)
            mounting_hint = degrees_seen.mounting_hint

    found = sample_blocks(
        rows, cols, CHUNK, skip_bad=options.skip_bad, empty_is_dropout=True,
        problems=problems,
    )  # fmt: skip
    readings = _readings(f)
    description = InputDescription(
        name, kind, tuple(cols), _table_units(rows, kind, options), _imu_model(f),
        problems=problems, readings=readings, notes=notes,
    )  # fmt: skip
    samples = _chunked(rows, found, convert, readings, f, finish, robot_name, mounting_hint, python)
    return MeasurementStream(description, f, samples, 0, rows)


#: What a run of a raw table without gyro columns says (a note, not a warning: the
#: accelerometers alone are a valid input).
NO_GYRO_NOTE = (
    "no gyro columns (gx_i, gy_i, gz_i): each IMU's tilt from its accelerometer alone; "
    "with a gyro's rates too the estimate takes the direct model, the better one where "
    "the robot moves (docs: options)"
)


def _imu_model(formulation: Formulation) -> str:
    return "direct" if formulation.name == "direct" else "tilt"


def _readings(formulation: Formulation) -> ReadingCounts:
    return ReadingCounts(tuple(b.slice for b in formulation.measurement_blocks))


def _chunked(
    rows: TextRows,
    found: Iterator[SampleBlock],
    convert: Convert,
    readings: ReadingCounts,
    formulation: Formulation,
    finish: Callable[[], None] | None = None,
    robot_name: str | None = None,
    mounting_hint: Callable[[], str | None] | None = None,
    python: bool = False,
) -> Iterator[tuple[FloatArray, FloatArray]]:
    """Convert the blocks of :data:`CHUNK` rows, one at a time. Counts which IMUs
    reported in ``readings``, and warns at the end for one that never did, then calls
    ``finish``. The first block's readings are checked against the robot's mounting
    (:func:`~continuum_mhe.io.input_options.check_mounting`; ``robot_name``: the robot
    file its messages name, None: the command line's one-section options; ``python``:
    the Robot's fields); a refusal
    ends with ``mounting_hint()`` where that gives another reading of it."""
    first = True
    tally = MountingTally(formulation)
    for block in found:
        if first:
            check_time_units(rows, block.t)
        z = np.ascontiguousarray(convert(block.t, block.values, block.lines), dtype=np.float64)
        if first:
            try:
                check_mounting(rows.name, z, formulation, robot_name, python)
            except InputError as err:
                hint = mounting_hint() if mounting_hint is not None else None
                if hint is None:
                    raise
                raise InputError(f"{err}; {hint}") from None
            first = False
        readings.add(z)
        tally.add(z)
        yield block.t, z
    readings.warn_silent(rows.name)
    tally.warn(rows.name, robot_name, python)
    if finish is not None:
        finish()


# --- step 3: the samples of a robot log ------------------------------------------------------
def _log_stream(
    p: Path,
    options: InputOptions,
    formulation: Formulation,
    robot_name: str | None = None,
    python: bool = False,
) -> MeasurementStream:
    data = _load_log(p, options, formulation)
    said = data.skipped + data.dropouts
    problems = RowProblems(len(said), said[:20], dropped=len(data.skipped))
    check_mounting(str(p), data.z, data.formulation, robot_name, python)
    readings = _readings(data.formulation)
    readings.add(data.z)
    readings.warn_silent(str(p))
    tally = MountingTally(data.formulation)
    tally.add(data.z)
    tally.warn(str(p), robot_name, python)
    units = (
        "roll, pitch from the orientation quaternion"
        if options.use_orientation
        else "linear_acceleration in m/s^2, angular_velocity in rad/s"
    )
    description = InputDescription(
        str(p), "log", options.topics or ((options.topic,) if options.topic else ()),
        f"t from the {data.clock}, s; {units}", _imu_model(data.formulation),
        problems=problems, readings=readings, notes=data.notes,
    )  # fmt: skip
    blocks = (
        (data.t[i : i + CHUNK], np.ascontiguousarray(data.z[i : i + CHUNK], dtype=np.float64))
        for i in range(0, len(data.t), CHUNK)
    )
    return MeasurementStream(description, data.formulation, blocks, data.t0_ns)


def _load_log(p: Path, options: InputOptions, formulation: Formulation) -> EstimateInput:
    """A ROS bag or MCAP file as measurements: one Imu topic, or one per IMU paired by
    header stamp (:mod:`~continuum_mhe.io.imu_topics`)."""
    check_options_apply(str(p), "log", options, formulation.robot)
    robot = formulation.robot
    if robot.n_imus > 1 or len(options.topics) > 1:
        paired = read_imu_topics(
            p, options.topics, robot.n_imus, options.pair_tolerance, options.skip_bad
        )
        logs, t, t0_ns, skipped = paired.logs, paired.t, paired.t0_ns, paired.skipped
        notes: tuple[str, ...] = (paired.report(),)
    else:
        log = read_imu_log(p, options.topic, options.skip_bad)
        logs, t, t0_ns, skipped, notes = (log,), log.t, log.t0_ns, log.skipped, ()
    for log in logs:
        no_accel = ~np.isfinite(log.acc).all(axis=1) | ~(np.abs(log.acc) > 0).any(axis=1)
        oriented = np.isfinite(log.orientation).all(axis=1)
        if not options.use_orientation and no_accel.all() and oriented.any():
            raise InputError(
                f"{p}: topic {log.topic}: linear_acceleration is zero or absent in every "
                "message while its orientation is given (an orientation-only IMU): "
                "--orientation reads its roll and pitch"
                + ("" if oriented.all() else " (with --skip-bad: some messages have none)")
            )
        if not options.use_orientation and no_accel.all():
            raise InputError(
                f"{p}: topic {log.topic}: linear_acceleration is zero or absent "
                "(linear_acceleration_covariance[0] = -1) in every message: no reading "
                "of gravity to estimate from"
            )
    has_gyro = all(log.gyr is not None for log in logs)
    with_rates = [log.topic for log in logs if log.gyr is not None]
    tilt_asked = options.raw.imu_model == "tilt" and options.raw.attitude == "accel"
    if with_rates and not has_gyro and not (options.use_orientation or tilt_asked):
        without = [log.topic for log in logs if log.gyr is None]
        raise InputError(
            f"{p}: topic {', '.join(without)} has no angular rates (angular_velocity_"
            f"covariance[0] = -1 in every message) while {', '.join(with_rates)} has them: "
            "give every IMU's gyro or none (as a table's columns), or --imu-model tilt to "
            "leave the gyros out"
        )
    options, f = decide_model(str(p), "log", has_gyro, options, formulation)
    blocks = []
    # the messages skip_bad read as dropouts (their time, what was bad), said in the summary
    dropouts: list[tuple[float, str]] = []
    converters: list[RawImuConverter] = []  # their clipped readings said once, below
    for log, place in zip(logs, robot.imus):
        if options.use_orientation:
            blocks.append(
                tilt_from_quaternion(_orientations(p, t, log, options.skip_bad, dropouts))
            )
        else:
            raw = imu_settings_for(options.raw, place)  # as a table's (and live's)
            _refuse_a_missing_value(p, t, log, options.skip_bad, dropouts)
            acc, gyr = _readings_in_range(p, t, log, options.skip_bad, dropouts)
            converters.append(RawImuConverter(raw))
            blocks.append(_convert_log(p, t, acc, gyr, converters[-1], log.topic))
    warn_clipped(str(p), converters)
    clock = " and ".join(sorted({log.clock for log in logs}))
    notes += tuple(
        (
            f"{p}: {log.topic}: the header stamps do not advance ({log.stale_stamps} "
            "messages at or before the stamp of the one before: a driver that does not set "
            "header.stamp?): t from the log's times (when each message was logged)"
            if log.stale_stamps
            else f"{p}: {log.topic}: every header stamp is zero: t from the log's times "
            "(when each message was logged)"
        )
        for log in logs
        if log.clock == "log times"
    )
    notes += tuple(f"{p}: {log.topic}: {log.cut}" for log in logs if log.cut)
    notes += tuple(
        f"{p}: {log.topic}: {log.reordered} message(s) logged after one stamped later "
        "(delivered late): put in their place by their header stamps"
        for log in logs
        if log.reordered
    )
    z, said = np.hstack(blocks), [what for _, what in sorted(dropouts, key=lambda d: d[0])]
    return EstimateInput("log", t, z, f, t0_ns, skipped, notes, clock, said)


def _orientations(
    path: Path, t: FloatArray, log: ImuLog, skip_bad: bool, dropouts: list[tuple[float, str]]
) -> FloatArray:
    """``log``'s orientations for ``--orientation``: a topic without any is refused in one
    line; a message without one (``orientation_covariance[0] = -1``, a zero or
    non-finite quaternion: a filter still starting) is named in one line, or with
    ``skip_bad`` a dropout (NaN), described in ``dropouts`` with its time."""
    unpaired = _unpaired(log)  # a sample without this topic's message: a dropout
    absent = np.asarray(~np.isfinite(log.orientation).all(axis=1), dtype=bool) & ~unpaired
    if (absent | unpaired).all():
        raise InputError(
            f"{path}: topic {log.topic} carries no orientation in any message "
            "(orientation_covariance[0] = -1, or a zero quaternion): --orientation needs it"
        )
    if absent.any() and not skip_bad:
        i = int(np.argmax(absent))
        raise InputError(
            f"{path}: topic {log.topic}: the message at t = {time_text(float(t[i]))} s "
            f"({_message_number(log, i)}) has no orientation (orientation_covariance[0] = -1, "
            f"or a zero or non-finite quaternion; {int(absent.sum())} such): --skip-bad keeps "
            "them as dropouts (skip_bad=True in Python)"
        )
    dropouts += [
        (
            float(t[i]),
            f"topic {log.topic}: {_message_number(log, int(i))}: no orientation "
            "(orientation_covariance[0] = -1, or a zero or non-finite quaternion)",
        )
        for i in np.flatnonzero(absent)
    ]
    return np.where((absent | unpaired)[:, None], np.nan, log.orientation)


def _unpaired(log: ImuLog) -> NDArray[np.bool_]:
    """(n,) True where the sample has no message of ``log``'s topic (IMU 1's sample
    without a partner in it: a dropout of that IMU, not a bad reading)."""
    if log.numbers is None:
        return np.zeros(len(log.t), dtype=bool)
    return np.asarray(log.numbers == 0)


def _message_number(log: ImuLog, i: int) -> str:
    """How an error names sample ``i`` of ``log``: its message number in the topic
    (paired samples skip messages), else its sample number."""
    if log.numbers is not None:
        return f"message {int(log.numbers[i])}"
    return f"sample {i + 1}"


def _refuse_a_missing_value(
    path: Path, t: FloatArray, log: ImuLog, skip_bad: bool, dropouts: list[tuple[float, str]]
) -> None:
    """One line for the first message of ``log`` whose acceleration or angular rate
    holds a NaN or an infinity, as a CSV's nan field is; with ``skip_bad`` (a dropout)
    each such message is described in ``dropouts`` with its time."""
    unpaired = _unpaired(log)
    counted = np.zeros(len(t), dtype=bool)
    for name, values in (("linear_acceleration", log.acc), ("angular_velocity", log.gyr)):
        if values is None:
            continue
        bad = ~np.isfinite(values).all(axis=1) & ~unpaired & ~counted
        counted |= bad  # a message said once, for its first field that is bad
        for i in np.flatnonzero(bad):
            shown = values[i].tolist()
            if np.isnan(values[i]).all():
                shown = f"absent (NaN, or marked absent: {name}_covariance[0] = -1)"
            if skip_bad:
                said = f"topic {log.topic}: {_message_number(log, int(i))}: {name} is {shown}"
                dropouts.append((float(t[i]), said))
                continue
            raise InputError(
                f"{path}: topic {log.topic}: the message at t = {time_text(float(t[i]))} s "
                f"({_message_number(log, int(i))}): {name} is {shown} (a dropout; --skip-bad "
                "keeps it, skip_bad=True in Python)"
            )


def _readings_in_range(
    path: Path, t: FloatArray, log: ImuLog, skip_bad: bool, dropouts: list[tuple[float, str]]
) -> tuple[FloatArray, FloatArray | None]:
    """``log``'s accelerations and rates, a message whose acceleration is zero (no
    gravity direction, as a CSV row's zero is) or whose reading lies beyond any IMU's
    range (:data:`ACCEL_READING_MAX`, :data:`GYRO_READING_MAX`: a corrupt value) named in
    one line as a CSV's row is, or with ``skip_bad`` a dropout (NaN), as a message with
    a NaN is, described in ``dropouts`` with its time."""
    acc = np.array(log.acc, dtype=float)
    gyr = None if log.gyr is None else np.array(log.gyr, dtype=float)
    acc_norm, gyr_norm, zero, huge = impossible_readings(acc, gyr)
    # an accelerometer in another unit is said as a CSV's is, not as a corrupt message:
    # raw counts (most readings beyond range), or mm/s^2 (its median about 9810)
    label = f"{path}: topic {log.topic}"
    check_accel_range(label, acc_norm)
    check_accel_units(label, acc)
    finite = np.isfinite(acc).all(axis=1) & (gyr is None or np.isfinite(gyr).all(axis=1))
    # (a message with a NaN is said by _refuse_a_missing_value)
    for i in np.flatnonzero((huge | zero) & finite & ~_unpaired(log)):
        what = (
            f"linear_acceleration is zero (|a| {acc_norm[i]:.3g} m/s^2: no gravity direction)"
            if zero[i]
            else f"a reading beyond any IMU's range (|a| {acc_norm[i]:.3g} m/s^2, limit "
            f"{ACCEL_READING_MAX:g}; |omega| {gyr_norm[i]:.3g} rad/s, limit "
            f"{GYRO_READING_MAX:g}): a corrupt value"
        )
        if skip_bad:
            dropouts.append(
                (float(t[i]), f"topic {log.topic}: {_message_number(log, int(i))}: {what}")
            )
            continue
        raise InputError(
            f"{label}: the message at t = {time_text(float(t[i]))} s "
            f"({_message_number(log, int(i))}): {what} (a dropout; --skip-bad keeps it, "
            "skip_bad=True in Python)"
        )
    acc[huge | zero] = np.nan  # a zero acceleration's rates kept, as a CSV row's are
    if gyr is not None:
        gyr[huge] = np.nan
    return acc, gyr


def _convert_log(
    path: Path,
    t: FloatArray,
    acc: FloatArray,
    gyr: FloatArray | None,
    converter: RawImuConverter,
    topic: str,
) -> FloatArray:
    raw = converter.settings
    if raw.needs_gyro and gyr is None:
        raise InputError(f"{path}: {_gyro_user(raw)} needs gyro columns gx, gy, gz")
    # the gyro's units where it is used (the accelerometer's: _readings_in_range)
    if gyr is not None:
        check_gyro_units(f"{path}: topic {topic}", gyr, raw.needs_gyro, t, acc)
    return converter.convert_many(t, acc, gyr)
