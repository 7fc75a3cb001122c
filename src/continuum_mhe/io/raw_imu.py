"""Raw IMU input: accelerometer and gyro samples to estimator measurements.

Raw CSV format: a header with at least ``t,ax,ay,az`` and optionally ``gx,gy,gz``;
``t`` in seconds, strictly increasing; ``a*`` the specific force in m/s^2 and ``g*``
the angular rate in rad/s, both in the *sensor* frame. Other columns are ignored.

Sensor frame: once the mounting rotation is applied (``mount_rpy``), the sensor z axis
lies along the tip tangent (pointing away from the base) and x, y are the tip frame's
axes of :mod:`continuum_mhe.model.kinematics`. A sensor mounted differently is
described by the fixed rotation ``R_mount = Rz(yaw) Ry(pitch) Rx(roll)`` that maps
sensor-frame vectors into the tip frame (``v_tip = R_mount v_sensor``).

Two measurement models (``imu_model``):

* ``"tilt"``: ``[roll, pitch]`` (rad) from the accelerometer alone (``attitude=
  "accel"``) or from the gyro-fused attitude of the ``ahrs`` package's Madgwick or
  Mahony filter; then any formulation (``bend``, ``paper``) applies.
* ``"direct"``: ``[f/|f|, omega]`` for :class:`~continuum_mhe.model.direct.
  DirectFormulation` (needs the gyro columns).
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, finite_reals
from continuum_mhe.io.csv_files import UnitWarning, check_time_units, read_sample_rows
from continuum_mhe.io.imu_columns import READER_FIX, ROBOT_FIX, ImuColumns, imu_suffixes
from continuum_mhe.io.sample_rows import RowProblems
from continuum_mhe.io.text_rows import TextRows, open_rows
from continuum_mhe.model.direct import direct_measurements
from continuum_mhe.model.imu import STANDARD_GRAVITY, tilt_from_accelerometer
from continuum_mhe.model.robot import mount_rpy_hint

ImuModel = Literal["tilt", "direct"]
IMU_MODELS: tuple[ImuModel, ...] = ("tilt", "direct")
Attitude = Literal["accel", "madgwick", "mahony"]
ATTITUDES: tuple[Attitude, ...] = ("accel", "madgwick", "mahony")

ACC_COLUMNS = ("ax", "ay", "az")
GYRO_COLUMNS = ("gx", "gy", "gz")
#: One IMU's raw columns, unnumbered (``ax_k``... for IMU ``k`` of several).
RAW_FIELDS = (*ACC_COLUMNS, *GYRO_COLUMNS)

#: Median |a| in this band (in the file's unit) means the file is in g, not m/s^2.
_LOOKS_LIKE_G = (0.5, 2.0)
#: Median |omega| above this (rad/s, 286 deg/s: turning most of the time faster than
#: most continuum robots ever do; the shipped rod recordings' largest median is 2.7)
#: means the gyro is in deg/s, not rad/s. A deg/s file whose median rate stays below
#: 5 deg/s is not caught (its rates are small either way).
GYRO_MEDIAN_MAX = 5.0
#: A stream's units are checked on the medians of its first samples, at least this many
#: (1 s at 100 Hz) over at least :data:`UNIT_CHECK_SPAN_S`, where a recording's are
#: checked on all of them.
UNIT_CHECK_SAMPLES = 100
UNIT_CHECK_SPAN_S = 1.0
#: The gravity check of a gyro's units (:func:`gyro_gravity_problem`) compares the
#: accelerometer's direction with the gyro's turn over stretches of this length (s), of
#: at least :data:`GRAVITY_TURN_ROWS` readings, ...
GRAVITY_TURN_SPAN_S = 0.5
GRAVITY_TURN_ROWS = 5
#: ... where the IMU is still: its specific force's magnitude spreads by at most this
#: fraction of its mean over the stretch (the noise of a MEMS accelerometer at rest is
#: about 0.5 %; a swing's own acceleration is more) ...
GRAVITY_TURN_ACCEL_SPREAD = 0.01
#: ... and its rates are steady, as a bias: their spread (the norm of the axes' standard
#: deviations) at most this fraction of their mean rate's magnitude ...
GRAVITY_TURN_RATE_SPREAD = 0.5
#: ... and finds deg/s where the gyro, read as rad/s, misses the accelerometer's turn by
#: more than this (rad, 20 deg) in the median stretch: a MEMS gyro's bias in rad/s
#: (under 0.05) turns a direction by about 1.5 deg in a stretch, one of 1 deg/s read
#: as rad/s by 29 deg.
GRAVITY_TURN_MISMATCH = math.radians(20.0)
#: An acceleration (m/s^2) or a rate (rad/s) of a larger magnitude is beyond any IMU's
#: range (high-g accelerometers end near 4,000 m/s^2, MEMS gyros near 70 rad/s): a
#: corrupt value, not a reading.
ACCEL_READING_MAX = 1e4
GYRO_READING_MAX = 1e3
#: :func:`check_accel_range` judges an accelerometer's unit on at least this many rows
#: (a block of fewer, such as a file's last rows, holds corrupt values at most).
ACCEL_RANGE_ROWS = 10


@dataclass(frozen=True)
class RawImuSettings:
    """How raw samples become measurements.

    Attributes:
        imu_model: ``"tilt"`` (roll, pitch) or ``"direct"`` (gravity direction, gyro);
            None: decided by the input (raw input with gyros takes ``"direct"``, other
            input ``"tilt"``; :func:`continuum_mhe.io.input_options.with_imu_model`).
            A converter treats None as ``"tilt"``.
        attitude: for ``tilt``: ``"accel"`` (accelerometer only), ``"madgwick"`` or
            ``"mahony"`` (gyro fusion by the ``ahrs`` package; needs the gyro).
        mount_rpy: sensor mounting ``(roll, pitch, yaw)`` in degrees, Z-Y-X:
            ``v_tip = Rz(yaw) Ry(pitch) Rx(roll) v_sensor``. Zero when the sensor
            axes already match the tip frame.
        gyro_bias: the gyro's bias at rest ``(gx, gy, gz)`` in rad/s, sensor frame
            (``continuum-mhe calibrate`` measures it), subtracted from every reading
            before the mounting; an estimated bias then starts from it.
    """

    imu_model: ImuModel | None = None
    attitude: Attitude = "accel"
    mount_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if self.imu_model is not None and self.imu_model not in IMU_MODELS:
            raise UserError(f"imu model must be one of {IMU_MODELS}, got {self.imu_model!r}")
        if self.attitude not in ATTITUDES:
            raise UserError(f"attitude must be one of {ATTITUDES}, got {self.attitude!r}")
        if self.imu_model == "direct" and self.attitude != "accel":
            raise UserError(
                f"attitude={self.attitude!r} is for imu_model='tilt' (how roll and pitch "
                "are made from the raw readings); imu_model='direct' puts the readings into "
                "the model itself, with no attitude filter: leave one out"
            )
        rpy = finite_reals("mount_rpy", self.mount_rpy, 3, "three finite angles in degrees")
        bias = finite_reals("gyro_bias", self.gyro_bias, 3, "three finite rates in rad/s")
        object.__setattr__(self, "mount_rpy", rpy)
        object.__setattr__(self, "gyro_bias", bias)

    @property
    def needs_gyro(self) -> bool:
        return self.imu_model == "direct" or self.attitude != "accel"


def parse_mount_rpy(text: str) -> tuple[float, float, float]:
    """``"roll,pitch,yaw"`` in degrees (e.g. ``"0,0,90"``) to a tuple; a
    :class:`~continuum_mhe.io.csv_files.UnitWarning` where they look like radians
    (:func:`~continuum_mhe.model.robot.mount_rpy_hint`)."""
    parts = [p.strip() for p in text.split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= 360 for v in values):
        raise InputError(
            f"--mount-rpy must be three angles in degrees within +-360, e.g. 0,0,90; got {text!r}"
        )
    hint = mount_rpy_hint(values, "--mount-rpy")
    if hint:
        warnings.warn(f"--mount-rpy {text} is read in degrees: {hint}", UnitWarning, stacklevel=2)
    return values[0], values[1], values[2]


def mount_rotation(rpy_deg: tuple[float, float, float]) -> FloatArray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (3x3) from degrees: sensor frame to tip frame."""
    r, p, y = np.radians(rpy_deg)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return np.asarray(rz @ ry @ rx, dtype=float)


def gravity_from_quaternion(q: FloatArray) -> FloatArray:
    """Up direction in the sensor frame, ``R(q)^T e_z``, for a sensor-to-world ``q``
    ``(w, x, y, z)`` as the ``ahrs`` filters return it."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([2 * (x * z - w * y), 2 * (w * x + y * z), 1 - 2 * (x * x + y * y)])


class RawImuConverter:
    """Stateful conversion of raw samples, one at a time (the attitude filters keep a
    quaternion). Call :meth:`reset` after a gap in time."""

    def __init__(self, settings: RawImuSettings) -> None:
        self.settings = settings
        self._mount = mount_rotation(settings.mount_rpy)
        self._bias = np.asarray(settings.gyro_bias, dtype=float)
        self._filter: Any = None
        if settings.imu_model != "direct" and settings.attitude != "accel":
            from ahrs.filters import Madgwick, Mahony

            self._filter = Madgwick() if settings.attitude == "madgwick" else Mahony()
        self.reset()

    @property
    def nz(self) -> int:
        return 6 if self.settings.imu_model == "direct" else 2

    def reset(self) -> None:
        self._q: FloatArray | None = None
        self._t: float | None = None

    def convert(self, t: float, acc: FloatArray, gyr: FloatArray | None) -> FloatArray:
        """Measurement (nz,) for one sample; NaN (a dropout) if the sample is unusable.

        ``acc`` specific force (3,) in any unit, ``gyr`` (3,) rad/s or None.
        """
        acc = self._mount @ np.asarray(acc, dtype=float)
        gyro = None if gyr is None else self._mount @ (np.asarray(gyr, dtype=float) - self._bias)
        if self.settings.imu_model == "direct":
            if gyro is None:
                raise UserError("the direct IMU model needs gyro readings (gx, gy, gz)")
            return direct_measurements(acc, gyro)[0]
        if not (np.all(np.isfinite(acc)) and np.linalg.norm(acc) > 0):
            return np.full(2, np.nan)
        if self._filter is None:
            return tilt_from_accelerometer(acc)
        if gyro is None:
            raise UserError(f"attitude {self.settings.attitude!r} needs gyro readings")
        if not np.all(np.isfinite(gyro)):
            return np.full(2, np.nan)
        if self._q is None or self._t is None:
            from ahrs.common.orientation import acc2q

            self._q = np.asarray(acc2q(acc), dtype=float)
        else:
            self._q = np.asarray(
                self._filter.updateIMU(self._q, gyro, acc, dt=t - self._t), dtype=float
            )
        self._t = t
        return tilt_from_accelerometer(gravity_from_quaternion(self._q))

    def convert_many(self, t: FloatArray, acc: FloatArray, gyr: FloatArray | None) -> FloatArray:
        """Measurements (n, nz) for consecutive samples (``t`` (n,) s, ``acc`` (n, 3),
        ``gyr`` (n, 3) rad/s or None), as :meth:`convert` gives them one at a time: in
        one pass over the arrays where the conversion keeps no state (the direct model,
        tilt from the accelerometer), sample by sample through an attitude filter."""
        n = len(t)
        if self._filter is not None:
            rows = [
                self.convert(float(t[i]), acc[i], None if gyr is None else gyr[i]) for i in range(n)
            ]
            return np.array(rows, dtype=float).reshape(n, self.nz)
        acc = np.asarray(acc, dtype=float).reshape(n, 3) @ self._mount.T
        if self.settings.imu_model == "direct":
            if gyr is None:
                raise UserError("the direct IMU model needs gyro readings (gx, gy, gz)")
            gyro = (np.asarray(gyr, dtype=float).reshape(n, 3) - self._bias) @ self._mount.T
            return direct_measurements(acc, gyro).reshape(n, 6)
        usable = np.all(np.isfinite(acc), axis=1) & (np.linalg.norm(acc, axis=1) > 0)
        with np.errstate(invalid="ignore"):
            tilt = tilt_from_accelerometer(acc).reshape(n, 2)
        tilt[~usable] = np.nan
        return tilt


def raw_to_measurements(
    t: FloatArray, acc: FloatArray, gyr: FloatArray | None, settings: RawImuSettings
) -> FloatArray:
    """Measurements (n, nz) for a whole recording (``t`` s, ``acc`` (n, 3), ``gyr``
    (n, 3) rad/s or None)."""
    return RawImuConverter(settings).convert_many(t, acc, gyr)


@dataclass(frozen=True)
class RawImuTable:
    """Raw samples read from a file.

    Attributes:
        t: (n,) s, strictly increasing.
        acc: (n, 3) specific force, m/s^2, sensor frame; NaN rows are dropouts.
        gyr: (n, 3) rad/s, or None when the file has no gyro columns.
        skipped: descriptions of rows dropped or turned into dropouts (``skip_bad``).
    """

    t: FloatArray
    acc: FloatArray
    gyr: FloatArray | None
    skipped: list[str] = field(default_factory=list)


def is_raw_header(header: list[str]) -> bool:
    """True when a (lower-case) CSV header names the accelerometer columns (``ax,ay,az``,
    or ``ax_1,ay_1,az_1`` for several IMUs; ``ax_0...``, numbered from 0, too, so that
    :func:`raw_layout` can say IMUs are numbered from 1)."""
    return any(all(f"{c}{suffix}" in header for c in ACC_COLUMNS) for suffix in ("", "_1", "_0"))


def sample_kind(rows: TextRows) -> Literal["tilt", "raw"]:
    """``"raw"`` if the header names the accelerometer columns (:func:`is_raw_header`),
    or names one of them and no tilt column (a raw header with a typo, which
    :func:`raw_layout` names); else ``"tilt"``. A header with both tilt (``roll``,
    ``pitch``, ``roll_1``...) and raw columns is a one-line error (which ones should be
    estimated from?)."""
    tilt = [h for h in rows.header if h.split("_")[0] in ("roll", "pitch")]
    if not is_raw_header(rows.header):
        number = RAW_IMU_COLUMNS.number
        accel = any(h in ACC_COLUMNS or number(h)[0] in ACC_COLUMNS for h in rows.header)
        if not accel and not tilt:
            _refuse_other_raw_names(rows)
        return "raw" if accel and not tilt else "tilt"
    if tilt:
        raise InputError(
            f"{rows.name}: line 1: the header has both tilt "
            f"({', '.join(map(rows.as_written, tilt[:2]))}) and raw "
            "IMU columns (ax, ay, az); give one kind: remove the tilt or the raw columns"
        )
    return "raw"


#: A header column that names an accelerometer or gyro axis in another spelling
#: (``ax1``, ``acc_x``, ``accel_x_2``, ``gyro_z1``, ``wx``): its sensor, axis and IMU number.
_OTHER_RAW_NAME = re.compile(
    r"^(?:(a|acc|accel|accelerometer)|(g|gyr|gyro|w|omega))[_. -]?([xyz])[_. -]?(\d*)$",
    re.IGNORECASE,
)


def _refuse_other_raw_names(rows: TextRows) -> None:
    """A one-line error for a header with neither tilt nor raw columns but with columns
    that name accelerometer or gyro axes otherwise (:data:`_OTHER_RAW_NAME`): the names
    this reader takes, and what each such column would be called (``ax1`` -> ``ax_1``).
    Any other header is left to the tilt reader's message."""
    matches = [(h, m) for h in rows.header if (m := _OTHER_RAW_NAME.match(h))]
    numbers = [int(m.group(4)) for _, m in matches if m.group(4)]
    first = min(numbers, default=1)  # IMUs count from 1: a file's 0 is IMU 1
    several = len(set(numbers)) > 1
    renames = []
    for h, m in matches:
        name = ("a" if m.group(1) else "g") + m.group(3).lower()
        if m.group(4) and (several or first != 0):
            name += f"_{int(m.group(4)) + 1 - min(first, 1)}"
        if name != h:
            renames.append(f"{rows.as_written(h)} -> {name}")
    gyros = [h for h in rows.header if h in GYRO_COLUMNS or RAW_IMU_COLUMNS.number(h)[0]]
    if not renames and gyros:
        raise InputError(
            f"{rows.name}: line 1: gyro columns ({', '.join(map(rows.as_written, gyros[:3]))}) "
            "but no accelerometer columns (ax, ay, az; ax_1 ... for several IMUs): raw "
            "readings need the accelerometer (m/s^2); the gyro is optional"
        )
    if not renames:
        return
    shown = ", ".join(renames[:3]) + (", ..." if len(renames) > 3 else "")
    raise InputError(
        f"{rows.name}: line 1: no column is named as this reader takes IMU readings: raw "
        "columns are t,ax,ay,az,gx,gy,gz for one IMU and ax_1 ... gz_1, ax_2 ... for "
        f"several (m/s^2, rad/s), tilt ones roll, pitch (roll_1, pitch_1 ...); rename the "
        f"columns ({shown})"
    )


def raw_columns(i: int, n_imus: int, gyro: bool = True) -> tuple[str, ...]:
    """Raw columns of IMU ``i`` (0-based): ``ax..gz`` for one IMU, ``ax_1..gz_1``..."""
    names = RAW_FIELDS if gyro else ACC_COLUMNS
    return names if n_imus == 1 else tuple(f"{c}_{i + 1}" for c in names)


@dataclass(frozen=True)
class MultiRawImuTable:
    """Raw samples of several IMUs on one time axis.

    Attributes:
        t: (n,) s, strictly increasing.
        imus: one :class:`RawImuTable` per IMU (sharing ``t``); an empty field makes
            that IMU's sample a dropout (NaN), the other IMUs' samples are kept.
        skipped: descriptions of skipped rows or values.
    """

    t: FloatArray
    imus: list[RawImuTable]
    skipped: list[str] = field(default_factory=list)


#: The raw columns of an IMU: ``ax, ay, az``, and ``gx, gy, gz`` for its gyro
#: (``ax_k``... for IMU ``k`` of several).
RAW_IMU_COLUMNS = ImuColumns(
    "raw",
    ACC_COLUMNS,
    GYRO_COLUMNS,
    holds="an IMU's raw columns: ax{k}, ay{k}, az{k}, and gx{k}, gy{k}, gz{k} for its gyro",
)


def _imu_list(numbers: Sequence[str]) -> str:
    """``1``, ``1 and 3``, ``1, 2 and 4``."""
    return " and ".join(filter(None, [", ".join(numbers[:-1]), numbers[-1]]))


def raw_layout(rows: TextRows, n_imus: int, fix: str = ROBOT_FIX) -> tuple[tuple[str, ...], bool]:
    """The columns to read from a raw table (``t`` first) and whether it has gyros.

    A header with a column missing from an IMU's set (with the columns that look like a
    typo of it), or with whole sets for another number of IMUs than ``n_imus``, is a
    one-line error (:func:`~continuum_mhe.io.imu_columns.imu_suffixes`, which names
    ``fix``); so is one that gives some IMUs' gyro columns and not the others'."""
    suffixes = imu_suffixes(rows, n_imus, RAW_IMU_COLUMNS, fix)
    gyro = [s for s in suffixes if all(c + s in rows.header for c in GYRO_COLUMNS)]
    if gyro and len(gyro) < len(suffixes):
        without = [s[1:] for s in suffixes if s not in gyro]
        if len(without) == 1:
            cols = ", ".join(f"{c}_{without[0]}" for c in GYRO_COLUMNS)
            lacks = f"IMU {without[0]} has no {cols} columns"
        else:
            lacks = f"IMU {_imu_list(without)} have no gyro columns (gx_k, gy_k, gz_k)"
        have = "has" if len(gyro) == 1 else "have"
        raise InputError(
            f"{rows.name}: line 1: {lacks}, IMU {_imu_list([s[1:] for s in gyro])} {have} "
            "them: give every IMU's gyro or none"
        )
    fields = RAW_IMU_COLUMNS.names if gyro else ACC_COLUMNS
    return ("t", *(c + s for s in suffixes for c in fields)), bool(gyro)


def raw_blocks(
    name: str,
    values: FloatArray,
    lines: Sequence[int],
    n_imus: int,
    has_gyro: bool,
    skip_bad: bool,
    skipped: list[str] | RowProblems,
    gyro_used: bool = True,
    first_block: bool = True,
    t: FloatArray | None = None,
    time_watch: TimeUnitWatch | None = None,
) -> list[tuple[FloatArray, FloatArray | None]]:
    """``(acc, gyr)`` of each IMU from a raw table's values (n, k), unit-checked (a gyro
    in deg/s: an error if ``gyro_used``, else a warning; :func:`check_gyro_units`; on a
    later block of a file read in blocks (not ``first_block``), only where it has
    :data:`UNIT_CHECK_SAMPLES` readings or more: a short last block of a fast turn is
    no deg/s; with the rows' times ``t`` (n,) s, the first block's gyros are also held
    against the accelerometers: :func:`gyro_gravity_problem`; with ``time_watch`` (a
    whole table's, or a stream's, which gathers its first blocks' rows), the times are
    checked against the gyros: :class:`TimeUnitWatch`).

    One IMU: a zero acceleration, or a reading beyond any IMU's range
    (:data:`ACCEL_READING_MAX`, :data:`GYRO_READING_MAX`), is an error, or with
    ``skip_bad`` a dropout (recorded); several: any bad value makes that IMU's sample a
    dropout (NaN)."""
    k = 6 if has_gyro else 3
    out: list[tuple[FloatArray, FloatArray | None]] = []
    for i in range(n_imus):
        label = name if n_imus == 1 else f"{name}: IMU {i + 1}"
        block = values[:, k * i : k * (i + 1)].copy()
        if n_imus > 1:
            block[~np.all(np.isfinite(block), axis=1)] = np.nan
        acc = block[:, :3]
        # hypot: no overflow to inf for a corrupt 1e200
        acc_norm = np.hypot.reduce(acc, axis=1)
        gyr_norm = np.hypot.reduce(block[:, 3:6], axis=1) if has_gyro else np.zeros(len(acc))
        zero = acc_norm == 0.0  # no gravity direction to read
        huge = (acc_norm > ACCEL_READING_MAX) | (gyr_norm > GYRO_READING_MAX)
        check_accel_range(label, acc_norm)
        if n_imus == 1:
            for j in np.flatnonzero(zero | huge):
                msg = f"line {lines[int(j)]}: " + (
                    "acceleration is zero (no gravity direction)"
                    if zero[j]
                    else f"a reading beyond any IMU's range (|a| {acc_norm[j]:.3g} m/s^2, "
                    f"limit {ACCEL_READING_MAX:g}; |omega| {gyr_norm[j]:.3g} rad/s, limit "
                    f"{GYRO_READING_MAX:g})"
                )
                if not skip_bad:
                    raise InputError(f"{name}: {msg}")
                if isinstance(skipped, RowProblems):
                    skipped.add(msg)
                else:
                    skipped.append(msg)
        acc[zero] = np.nan
        block[huge] = np.nan
        check_accel_units(name, acc)
        judged = first_block or int(np.isfinite(gyr_norm).sum()) >= UNIT_CHECK_SAMPLES
        if has_gyro and judged:
            gravity = t is not None and first_block
            check_gyro_units(
                label, block[:, 3:6], gyro_used, t if gravity else None, acc if gravity else None
            )
        if has_gyro and t is not None and time_watch is not None:
            time_watch.add(label, t, acc, block[:, 3:6])
        out.append((acc, block[:, 3:6] if has_gyro else None))
    return out


def read_raw_imus(
    path: str | os.PathLike[str], n_imus: int, *, skip_bad: bool = False, fix: str = READER_FIX
) -> MultiRawImuTable:
    """Read a raw CSV of ``n_imus`` IMUs: ``t,ax_1,ay_1,az_1[,gx_1,gy_1,gz_1],ax_2,...``
    (m/s^2, rad/s, each IMU in its own sensor frame). A file of another number of IMUs
    is a one-line error that names ``fix`` (the command line names ``--robot``)."""
    with open_rows(path) as rows:
        cols, has_gyro = raw_layout(rows, n_imus, fix)
        got = read_sample_rows(rows, cols, skip_bad=skip_bad, empty_is_dropout=True)
    check_time_units(rows, got.t)
    skipped = list(got.skipped)
    blocks = raw_blocks(
        rows.name, got.values, got.lines, n_imus, has_gyro, skip_bad, skipped, t=got.t,
        time_watch=TimeUnitWatch(rows.time_scale),
    )  # fmt: skip
    imus = [RawImuTable(got.t, acc, gyr) for acc, gyr in blocks]
    return MultiRawImuTable(got.t, imus, skipped)


def csv_input_kind(path: str | os.PathLike[str]) -> Literal["tilt", "raw"]:
    """``"raw"`` if the CSV header has ``ax,ay,az``, else ``"tilt"`` (``t,roll,pitch``).
    Reads the input: for a pipe, open it once with :func:`open_rows` and use
    :func:`sample_kind` instead."""
    with open_rows(path) as rows:
        return sample_kind(rows)


def read_raw_imu(path: str | os.PathLike[str], *, skip_bad: bool = False) -> RawImuTable:
    """Read a raw IMU CSV (``t,ax,ay,az[,gx,gy,gz]``), validating every row.

    Errors are one line naming the file and line. With ``skip_bad``, rows with bad
    values become dropouts and rows with a bad or non-increasing ``t`` are dropped,
    each recorded in ``skipped``.
    """
    with open_rows(path) as rows:
        cols, has_gyro = raw_layout(rows, 1)
        got = read_sample_rows(rows, cols, skip_bad=skip_bad)
    check_time_units(rows, got.t)
    skipped = list(got.skipped)
    ((acc, gyr),) = raw_blocks(
        rows.name, got.values, got.lines, 1, has_gyro, skip_bad, skipped, t=got.t,
        time_watch=TimeUnitWatch(rows.time_scale),
    )  # fmt: skip
    return RawImuTable(t=got.t, acc=acc, gyr=gyr, skipped=skipped)


def check_accel_range(label: str, acc_norm: FloatArray) -> None:
    """An accelerometer most of whose readings (magnitudes ``acc_norm`` of its finite
    rows, m/s^2; at least :data:`ACCEL_RANGE_ROWS` of them) are beyond any IMU's range
    is in another unit (raw counts): a one-line :class:`InputError` naming ``label``,
    rather than every reading a dropout (a few corrupt values stay dropouts)."""
    finite = acc_norm[np.isfinite(acc_norm)]
    if len(finite) < ACCEL_RANGE_ROWS or 2 * int((finite > ACCEL_READING_MAX).sum()) <= len(finite):
        return
    raise InputError(
        f"{label}: accelerometer magnitude is about {float(np.median(finite)):.3g} (median), "
        f"beyond any IMU's range in m/s^2 (limit {ACCEL_READING_MAX:g}): raw counts? "
        "give m/s^2 (counts times g over the counts per g, e.g. 9.81 / 16384 at +-2 g)"
    )


def check_accel_units(path: Path | str, acc: FloatArray) -> None:
    """An accelerometer whose median magnitude is about 1 (within :data:`_LOOKS_LIKE_G`)
    is in g, not m/s^2: a one-line :class:`InputError` naming ``path``."""
    norm = np.linalg.norm(acc, axis=1)
    norm = norm[np.isfinite(norm)]
    if len(norm) and _LOOKS_LIKE_G[0] < float(np.median(norm)) < _LOOKS_LIKE_G[1]:
        raise InputError(
            f"{path}: accelerometer magnitude is about {float(np.median(norm)):.2f}: the "
            f"values look like g; ax, ay, az must be in m/s^2 (multiply by {STANDARD_GRAVITY})"
        )


def gyro_units_problem(gyr: FloatArray, names: str = "gx, gy, gz") -> str | None:
    """Where the median magnitude of a gyro's readings ``gyr`` (n, 3) exceeds
    :data:`GYRO_MEDIAN_MAX` rad/s (deg/s given for rad/s): what to say, naming the
    columns ``names``; else None. Non-finite rows are left out."""
    norm = np.linalg.norm(gyr, axis=1)
    norm = norm[np.isfinite(norm)]
    if not len(norm) or float(np.median(norm)) <= GYRO_MEDIAN_MAX:
        return None
    return (
        f"gyro magnitude is about {float(np.median(norm)):.3g} (median), implausible in "
        f"rad/s (above {GYRO_MEDIAN_MAX:g}): deg/s? give rad/s ({names} times pi/180 = "
        f"{math.pi / 180:.7f})"
    )


def _turn_errors(t: FloatArray, acc: FloatArray, gyr: FloatArray) -> FloatArray:
    """Per still stretch of :data:`GRAVITY_TURN_SPAN_S`: the angle (rad) between the
    accelerometer's last direction and its first one turned by the gyro's summed rates
    (one rotation vector: exact for a rate of constant direction, such as a resting
    gyro's bias), the gyro read as rad/s (column 0) and as deg/s (column 1); (k, 2).

    A stretch is judged where it has at least :data:`GRAVITY_TURN_ROWS` finite rows, its
    specific force's magnitude spreads by at most :data:`GRAVITY_TURN_ACCEL_SPREAD` of
    its mean (no acceleration of the IMU's own: a swinging IMU's specific force turns
    with it) and its rates by at most :data:`GRAVITY_TURN_RATE_SPREAD` of their mean (a
    steady rate, as a bias; a swing's rates change sign). Rows are paired with the next
    row of their own stretch only (a gap or a short stretch adds nothing)."""
    ok = np.isfinite(t) & np.isfinite(acc).all(axis=1) & np.isfinite(gyr).all(axis=1)
    t, acc, gyr = t[ok], acc[ok], gyr[ok]
    norm = np.linalg.norm(acc, axis=1)
    t, acc, gyr, norm = t[norm > 0], acc[norm > 0], gyr[norm > 0], norm[norm > 0]
    if len(t) < GRAVITY_TURN_ROWS:
        return np.zeros((0, 2))
    direction = acc / norm[:, None]
    stretch = np.floor((t - t[0]) / GRAVITY_TURN_SPAN_S).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, np.diff(stretch) != 0])
    stops = np.r_[starts[1:], len(t)]
    count = (stops - starts).astype(float)
    # each row's rate over the step to the next row of its own stretch
    step = np.r_[np.diff(t), 0.0]
    step[stops - 1] = 0.0
    turn = np.add.reduceat(gyr * step[:, None], starts, axis=0)
    norm_mean = np.add.reduceat(norm, starts) / count
    norm_var = np.add.reduceat(norm**2, starts) / count - norm_mean**2
    rate_mean = np.add.reduceat(gyr, starts, axis=0) / count[:, None]
    rate_var = np.add.reduceat(gyr**2, starts, axis=0) / count[:, None] - rate_mean**2
    still = (
        (count >= GRAVITY_TURN_ROWS)
        & (np.sqrt(np.maximum(norm_var, 0.0)) <= GRAVITY_TURN_ACCEL_SPREAD * norm_mean)
        & (
            np.sqrt(np.maximum(rate_var, 0.0).sum(axis=1))
            <= GRAVITY_TURN_RATE_SPREAD * np.linalg.norm(rate_mean, axis=1)
        )
    )
    if not still.any():
        return np.zeros((0, 2))
    first, last, turn = direction[starts[still]], direction[stops[still] - 1], turn[still]
    from scipy.spatial.transform import Rotation  # here: a tilt run imports no SciPy

    errors = np.empty((len(first), 2))
    for col, scale in enumerate((1.0, math.pi / 180.0)):
        # a direction fixed in the world turns in the IMU's frame as dv/dt = -w x v
        turned = Rotation.from_rotvec(-scale * turn).apply(first)
        errors[:, col] = np.arccos(np.clip(np.sum(turned * last, axis=1), -1.0, 1.0))
    return errors


def gyro_gravity_problem(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, names: str = "gx, gy, gz"
) -> str | None:
    """A gyro in deg/s whose rates are too small for :func:`gyro_units_problem` (an IMU
    at rest with its bias), told by the accelerometer: where, over the still stretches
    of the times ``t`` (n,) s (:func:`_turn_errors`: the specific force ``acc`` (n, 3;
    any unit) steady in magnitude, the rates ``gyr`` (n, 3) steady), the rates read as
    rad/s would turn the gravity direction by more than :data:`GRAVITY_TURN_MISMATCH`
    rad in the median stretch, while read as deg/s they follow it at least three times
    as closely: what to say, naming the columns ``names``; else None (also with fewer
    than two still stretches). A turn about the vertical moves no accelerometer and
    says nothing."""
    errors = _turn_errors(np.asarray(t, float), np.asarray(acc, float), np.asarray(gyr, float))
    if len(errors) < 2:
        return None
    as_rad, as_deg = (float(v) for v in np.median(errors, axis=0))
    if as_rad <= GRAVITY_TURN_MISMATCH or as_deg * 3.0 > as_rad:
        return None
    return (
        "the accelerometer's gravity direction turns as the gyro says only with the gyro "
        f"in deg/s (read as rad/s it misses by {math.degrees(as_rad):.0f} deg every "
        f"{GRAVITY_TURN_SPAN_S:g} s, median; read as deg/s by {math.degrees(as_deg):.1f} "
        f"deg): give rad/s ({names} times pi/180 = {math.pi / 180:.7f})"
    )


#: The time check of a raw recording (:func:`time_unit_problem`) cuts the rows into
#: windows, each as long as the gyro's rates, taken over a thousandth of each step of
#: ``t``, need to turn the gravity direction by this (rad) ...
TIME_CHECK_MIN_TURN = 0.1
#: ... and judges at least this many such windows ...
TIME_CHECK_WINDOWS = 5
#: ... where the accelerometer's direction follows that turn to within this fraction of
#: it (median), while the turn over each step as given misses it by more than
#: :data:`TIME_CHECK_MIN_TURN` and by this factor more than the thousandth's.
TIME_CHECK_FOLLOW = 0.35
TIME_CHECK_RATIO = 5.0
#: The rows examined, at most (the first ones), and the longest window.
TIME_CHECK_ROWS = 100_000
TIME_CHECK_WINDOW_ROWS = 20_000


def _angles(a: FloatArray, b: FloatArray) -> FloatArray:
    """The angles (rad) between the unit vectors of the rows of ``a`` and ``b``."""
    return np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))


def time_unit_problem(t: FloatArray, acc: FloatArray, gyr: FloatArray) -> str | None:
    """Times ``t`` (n,) a thousand times too long (milliseconds read as seconds), told by
    the gyro against the accelerometer, on positive evidence only: the rows (finite,
    the first :data:`TIME_CHECK_ROWS`) are cut into consecutive windows over which the
    rates ``gyr`` (n, 3; rad/s, the mean of a step's two rows), taken over a thousandth
    of each step, turn the specific force's direction ``acc`` (n, 3; any unit) by
    :data:`TIME_CHECK_MIN_TURN` across it; with at least :data:`TIME_CHECK_WINDOWS` of
    them, where the accelerometer's direction at a window's end follows that turn
    (median miss within :data:`TIME_CHECK_FOLLOW` of the turn) and the turn over the
    steps as given misses it by more than :data:`TIME_CHECK_MIN_TURN` and
    :data:`TIME_CHECK_RATIO` times as much: what to say (the two misses), else None. A
    gyro that reads more than the IMU turns (a bias, deg/s, counts) or an accelerometer
    that does not follow gravity (a swing's own acceleration) gives no such evidence."""
    t, acc, gyr = (np.asarray(a, float) for a in (t, acc, gyr))
    norm = np.linalg.norm(acc, axis=1)
    ok = np.isfinite(t) & np.isfinite(acc).all(axis=1) & np.isfinite(gyr).all(axis=1) & (norm > 0)
    keep = np.flatnonzero(ok)[:TIME_CHECK_ROWS]
    if len(keep) < 2 * TIME_CHECK_WINDOWS:
        return None
    t, direction, gyr = t[keep], acc[keep] / norm[keep, None], gyr[keep]
    step = np.diff(t)
    if not (step > 0).all():
        return None
    # the turn of a direction fixed in the world, seen in the IMU's frame: dv/dt = -w x v;
    # the summed rotation vector from row 0 (exact for a turn about one axis)
    turn = np.vstack(
        [np.zeros(3), np.cumsum(-1e-3 * 0.5 * (gyr[:-1] + gyr[1:]) * step[:, None], axis=0)]
    )
    ends: list[tuple[int, int]] = []
    i = 0
    while i < len(t) - 1:
        ahead = turn[i + 1 : i + 1 + TIME_CHECK_WINDOW_ROWS] - turn[i]
        reached = np.flatnonzero(
            np.linalg.norm(np.cross(ahead, direction[i]), axis=1) >= TIME_CHECK_MIN_TURN
        )
        if not len(reached):
            if i + 1 + TIME_CHECK_WINDOW_ROWS >= len(t):
                break
            i += TIME_CHECK_WINDOW_ROWS  # a still stretch: the next window starts after it
            continue
        j = i + 1 + int(reached[0])
        ends.append((i, j))
        i = j
    if len(ends) < TIME_CHECK_WINDOWS:
        return None
    from scipy.spatial.transform import Rotation  # here: a tilt run imports no SciPy

    first, last = (np.asarray(ix) for ix in zip(*ends))
    rotvec = turn[last] - turn[first]
    start = direction[first]
    medians = []
    for scale in (1.0, 1e3):
        predicted = Rotation.from_rotvec(scale * rotvec).apply(start)
        medians.append(float(np.median(_angles(predicted, direction[last]))))
    as_thousandth, as_given = medians
    turned = float(np.median(_angles(Rotation.from_rotvec(rotvec).apply(start), start)))
    if (
        as_thousandth > TIME_CHECK_FOLLOW * turned
        or as_given <= TIME_CHECK_MIN_TURN
        or as_thousandth * TIME_CHECK_RATIO > as_given
    ):
        return None
    return (
        f"over {len(ends)} stretches the accelerometer's gravity direction turns as the "
        "gyro's rates say over a thousandth of the steps of t (to a median of "
        f"{math.degrees(as_thousandth):.1f} deg of a {math.degrees(turned):.1f}-deg turn), "
        f"not over the steps as given (to {math.degrees(as_given):.0f} deg)"
    )


class TimeUnitWatch:
    """:func:`check_time_unit` over the first :data:`TIME_CHECK_ROWS` rows of a stream
    read in blocks, each IMU's rows gathered from block to block (a still start longer
    than a block gives no evidence in its first one)."""

    def __init__(self, time_scale: float) -> None:
        self.time_scale = time_scale
        self._rows: dict[str, list[FloatArray]] = {}
        self._count: dict[str, int] = {}

    def add(self, label: str, t: FloatArray, acc: FloatArray, gyr: FloatArray) -> None:
        """Take a block of IMU ``label``'s rows (``t`` s, ``acc``, ``gyr`` as
        :func:`time_unit_problem` takes them) and check its rows so far: a one-line
        :class:`InputError` where they are a thousand times too long."""
        seen = self._count.get(label, 0)
        if seen >= TIME_CHECK_ROWS:
            return
        take = TIME_CHECK_ROWS - seen  # the rows beyond are never judged
        self._rows.setdefault(label, []).append(np.column_stack([t, acc, gyr])[:take])
        self._count[label] = seen + min(len(t), take)
        rows = np.vstack(self._rows[label])
        check_time_unit(label, rows[:, 0], rows[:, 1:4], rows[:, 4:7], self.time_scale)
        if self._count[label] >= TIME_CHECK_ROWS:
            del self._rows[label]  # judged: the memory goes


def check_time_unit(
    name: str, t: FloatArray, acc: FloatArray, gyr: FloatArray, time_scale: float
) -> None:
    """A one-line :class:`InputError` where :func:`time_unit_problem` finds the times of
    ``name`` (s; read from a ``t`` column, or ``t_ms`` where ``time_scale`` is 1e-3) a
    thousand times too long."""
    problem = time_unit_problem(t, acc, gyr)
    if problem is None:
        return
    fix = (
        "t_ms looks like microseconds: give milliseconds"
        if time_scale == 1e-3
        else "t looks like milliseconds: name the column t_ms (t is read in seconds)"
    )
    raise InputError(f"{name}: {problem}: {fix}")


def check_gyro_units(
    path: Path | str,
    gyr: FloatArray,
    used: bool = True,
    t: FloatArray | None = None,
    acc: FloatArray | None = None,
) -> None:
    """A gyro whose median magnitude exceeds :data:`GYRO_MEDIAN_MAX` rad/s looks like deg/s
    (:func:`gyro_units_problem`), and so does one whose rates, given its times ``t`` and
    accelerometer ``acc``, turn the gravity direction as deg/s would
    (:func:`gyro_gravity_problem`): an error where the estimate uses it (``used``), else
    one warning (it is ignored)."""
    problem = gyro_units_problem(gyr)
    if problem is None and t is not None and acc is not None:
        problem = gyro_gravity_problem(t, acc, gyr)
    if problem is not None:
        msg = f"{path}: {problem}"
        if used:
            raise InputError(msg)
        warnings.warn(
            f"{msg}; these options do not use the gyro, so the estimate is unaffected",
            UnitWarning,
            stacklevel=2,
        )
