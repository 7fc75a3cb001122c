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
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, finite_reals
from continuum_mhe.io.csv_files import (
    DropoutWarning,
    UnitWarning,
    check_time_units,
    read_sample_rows,
)
from continuum_mhe.io.imu_columns import READER_FIX, ROBOT_FIX, ImuColumns, imu_suffixes
from continuum_mhe.io.raw_units import (
    ACCEL_READING_MAX,
    GYRO_READING_MAX,
    UNIT_CHECK_SAMPLES,
    MotionUnitWatch,
    check_accel_range,
    check_accel_units,
    check_gyro_units,
)
from continuum_mhe.io.sample_rows import RowProblems
from continuum_mhe.io.text_rows import TextRows, open_rows
from continuum_mhe.model.descriptions import imu_suffix
from continuum_mhe.model.direct import direct_measurements
from continuum_mhe.model.imu import STANDARD_GRAVITY, tilt_from_accelerometer
from continuum_mhe.model.robot import full_scale_problem, mount_rpy_hint

ImuModel = Literal["tilt", "direct"]
IMU_MODELS: tuple[ImuModel, ...] = ("tilt", "direct")
Attitude = Literal["accel", "madgwick", "mahony"]
ATTITUDES: tuple[Attitude, ...] = ("accel", "madgwick", "mahony")

ACC_COLUMNS = ("ax", "ay", "az")
GYRO_COLUMNS = ("gx", "gy", "gz")
#: One IMU's raw columns, unnumbered (``ax_k``... for IMU ``k`` of several).
RAW_FIELDS = (*ACC_COLUMNS, *GYRO_COLUMNS)


@dataclass(frozen=True)
class RawImuSettings:
    """How raw samples become measurements.

    Attributes:
        imu_model: ``"tilt"`` (roll, pitch) or ``"direct"`` (gravity direction, gyro);
            None: decided by the input (raw input with gyros takes ``"direct"``, other
            input ``"tilt"``; :func:`continuum_mhe.io.input_options.with_imu_model`).
            A converter treats None as ``"tilt"``.
        attitude: for ``tilt``: ``"accel"`` (accelerometer only), ``"madgwick"`` or
            ``"mahony"`` (gyro fusion by the ``ahrs`` package; needs the gyro). Madgwick
            estimates no gyro bias: reading an input refuses it without a calibrated
            ``gyro_bias`` for every IMU
            (:func:`~continuum_mhe.io.input_options.refuse_uncalibrated_madgwick`).
        mount_rpy: sensor mounting ``(roll, pitch, yaw)`` in degrees, Z-Y-X:
            ``v_tip = Rz(yaw) Ry(pitch) Rx(roll) v_sensor``. Zero when the sensor
            axes already match the tip frame.
        gyro_bias: the gyro's bias at rest ``(gx, gy, gz)`` in rad/s, sensor frame
            (``continuum-mhe calibrate`` measures it), subtracted from every reading
            before the mounting; an estimated bias then starts from it.
        accel_range: the accelerometer's full scale, m/s^2, or None (not known): a
            reading with an axis at it or beyond is clipped (:class:`ClipWatch`).
        gyro_range: the gyro's full scale, rad/s, or None: the same for its rates.
    """

    imu_model: ImuModel | None = None
    attitude: Attitude = "accel"
    mount_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_range: float | None = None
    gyro_range: float | None = None

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
        for key in ("accel_range", "gyro_range"):
            value = getattr(self, key)
            if value is not None:
                if problem := full_scale_problem(key, value):
                    raise UserError(problem)
                object.__setattr__(self, key, float(value))

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


#: A raw reading within this fraction of a declared full scale is at it: a driver's
#: scaling (+32767 of 32768 counts, 9.81 for 9.80665) and an offset it subtracts after
#: the sensor clipped leave a clipped reading just inside the range.
CLIP_TOLERANCE = 0.01
#: A reading beyond this multiple of a full scale is no clipped one: no sensor reads
#: past its range, so the range declared (or the flat top taken for it) is not the
#: sensor's. Such readings are kept, and counted (:attr:`ClipWatch.beyond`).
BEYOND_SCALE = 1.05
#: The automatic rule (no full scale declared): an axis that reads the same value in
#: this many consecutive readings ...
FLAT_TOP_READINGS = 3
#: ... beyond 1.5 g (m/s^2; no robot at rest or moving slowly reads it) or beyond 2 rad/s
#: (below every common gyro range, +-125 deg/s and up) ...
FLAT_TOP_ACCEL = 1.5 * STANDARD_GRAVITY
FLAT_TOP_GYRO = 2.0
#: ... while no axis of that sensor has read more (within :data:`CLIP_TOLERANCE`), and
#: at a value within FULL_SCALE_MATCH of a common MEMS full scale (+-2 to 32 g; +-125 to
#: 4000 deg/s: a smooth peak in readings rounded to a few decimals is a flat top at any
#: value), is at its full scale, which the rule then takes as that sensor's for the rest
#: of the run.
_COMMON_SCALES = (
    tuple(g * STANDARD_GRAVITY for g in (2, 4, 6, 8, 12, 16, 24, 32)),
    tuple(math.radians(d) for d in (125, 245, 250, 500, 1000, 2000, 4000)),
)
FULL_SCALE_MATCH = 0.03
#: ClipWatch's two sensors (index 0 and 1): their names, keys' prefixes and units
_SENSORS = ("accelerometer", "gyro")
_KEYS = ("accel", "gyro")
_UNITS = ("m/s^2", "rad/s")


class ClipWatch:
    """The clipped raw readings of one IMU, sample by sample (:meth:`see`): a reading
    with an accelerometer or gyro axis at (within :data:`CLIP_TOLERANCE`) or beyond its
    declared full scale (``accel_range`` m/s^2, ``gyro_range`` rad/s), or, where none is
    declared, at a flat top: the same value on one axis in :data:`FLAT_TOP_READINGS`
    consecutive readings beyond :data:`FLAT_TOP_ACCEL` (:data:`FLAT_TOP_GYRO`) while
    no axis of that sensor read more, at a common MEMS full scale; the flat top's value
    is then that sensor's full scale for the rest of the run (the first readings of the
    first flat top are taken). A reading beyond :data:`BEYOND_SCALE` times the full
    scale is kept and counted: the full scale is not the sensor's. Counts what it found
    (:meth:`notice`). A flat top runs across a gap: the readings are watched as they
    come, in ``estimate`` and ``live`` alike."""

    def __init__(self, accel_range: float | None, gyro_range: float | None) -> None:
        self.declared = (accel_range, gyro_range)
        #: the full scale each sensor's flat tops showed (None: none seen)
        self.learned: list[float | None] = [None, None]
        #: readings clipped, per sensor (a reading of both counts in each), and in all
        self.counts = [0, 0]
        self.clipped = 0
        self.first_t: float | None = None
        #: readings beyond :data:`BEYOND_SCALE` times each sensor's full scale (kept),
        #: and the largest of them
        self.beyond = [0, 0]
        self.beyond_max = [0.0, 0.0]
        self._peak = [0.0, 0.0]  # the largest magnitude each sensor read so far
        #: a flat top's value that a later reading beyond it showed to be no full scale
        #: (no longer taken; none is learned again for that sensor)
        self.refuted: list[float | None] = [None, None]
        self._history = np.full((FLAT_TOP_READINGS - 1, 6), np.nan)

    def see(self, t: FloatArray, acc: FloatArray, gyr: FloatArray | None) -> NDArray[np.bool_]:
        """Whether each of the readings ``acc`` (n, 3), ``gyr`` (n, 3) or None (raw, as
        read, at times ``t`` (n,) s) that follow those seen is clipped."""
        n = len(t)
        values = np.full((n, 6), np.nan)
        values[:, :3] = np.asarray(acc, dtype=float).reshape(n, 3)
        if gyr is not None:
            values[:, 3:] = np.asarray(gyr, dtype=float).reshape(n, 3)
        size = np.abs(values)
        clipped = np.zeros(n, dtype=bool)
        ext = np.vstack([self._history, values])
        self._history = ext[len(ext) - (FLAT_TOP_READINGS - 1) :].copy()
        rows_at = np.arange(n)
        for k, cols in enumerate((slice(0, 3), slice(3, 6))):
            mag = size[:, cols]
            largest = np.fmax.reduce(mag, axis=1)  # NaN where the sensor gave none
            scale, since = self.declared[k], 0
            if scale is None:
                if self.learned[k] is None and self.refuted[k] is None:
                    since = self._find_flat_top(k, ext[:, cols], mag, largest)
                scale = self.learned[k]
                if n:
                    self._peak[k] = float(np.fmax(self._peak[k], np.fmax.reduce(largest)))
            if scale is None:
                continue
            with np.errstate(invalid="ignore"):
                beyond = (rows_at >= since) & (largest > BEYOND_SCALE * scale)
                hit = (rows_at >= since) & (largest >= (1 - CLIP_TOLERANCE) * scale) & ~beyond
            if self.declared[k] is None and beyond.any():
                # a reading past the flat top taken as the full scale: it was none; the
                # readings from this one on are kept (as they are sample by sample)
                first = int(np.argmax(beyond))
                hit &= rows_at < first
                beyond &= rows_at == first
                self.refuted[k], self.learned[k] = self.learned[k], None
            if hit.any():
                self.counts[k] += int(hit.sum())
                clipped |= hit
            if beyond.any():
                self.beyond[k] += int(beyond.sum())
                self.beyond_max[k] = max(self.beyond_max[k], float(np.max(largest[beyond])))
        if clipped.any():
            self.clipped += int(clipped.sum())
            if self.first_t is None:
                self.first_t = float(np.asarray(t, dtype=float)[int(np.argmax(clipped))])
        return clipped

    def _find_flat_top(self, k: int, ext: FloatArray, mag: FloatArray, largest: FloatArray) -> int:
        """The first reading of the new readings (``ext`` (FLAT_TOP_READINGS - 1 + n, 3),
        the sensor ``k``'s axes after the readings before; ``mag`` (n, 3) their
        magnitudes, ``largest`` (n,) each reading's largest) that ends a flat top, whose
        value it learns as the sensor's full scale; ``n`` (none) where none does."""
        n = len(mag)
        flat_limit = (FLAT_TOP_ACCEL, FLAT_TOP_GYRO)[k]
        peak = np.fmax.accumulate(np.concatenate([[self._peak[k]], largest]))[1:]
        same = np.ones((n, 3), dtype=bool)
        for j in range(FLAT_TOP_READINGS - 1):
            same &= ext[j : j + n] == ext[FLAT_TOP_READINGS - 1 :]
        with np.errstate(invalid="ignore"):
            flat = same & (mag > flat_limit) & (mag >= (1 - CLIP_TOLERANCE) * peak[:, None])
            common = np.zeros_like(flat)
            for scale in _COMMON_SCALES[k]:
                common |= np.abs(mag - scale) <= FULL_SCALE_MATCH * scale
            flat &= common
        rows = np.flatnonzero(flat.any(axis=1))
        if not len(rows):
            return n
        i = int(rows[0])
        self.learned[k] = float(mag[i][flat[i]].max())
        return i

    def _how(self, k: int) -> str:
        """Which full scale sensor ``k`` (0 accelerometer, 1 gyro) is judged by."""
        unit = _UNITS[k]
        if (declared := self.declared[k]) is not None:
            return f"its {_KEYS[k]}_range, {declared:g} {unit}"
        if (refuted := self.refuted[k]) is not None:
            return f"a flat top at {refuted:.4g} {unit}, taken as its full scale until then"
        return f"a flat top at {self.learned[k]:.4g} {unit}, taken as its full scale"

    def notice(self) -> str | None:
        """What was clipped, as a clause for a warning (without the IMU), or None."""
        if not self.clipped:
            return None
        sensors = [
            f"{self.counts[k]} at its {_SENSORS[k]}'s full scale ({self._how(k)})"
            for k in (0, 1)
            if self.counts[k]
        ]
        return (
            f"{self.clipped} reading(s) clipped, from t = {self.first_t:g} s: "
            f"{' and '.join(sensors)}"
        )

    def beyond_notice(self) -> str | None:
        """What read beyond a full scale, as a clause (without the IMU), or None."""
        said = [
            f"{self.beyond[k]} {_SENSORS[k]} reading(s) up to {self.beyond_max[k]:.4g} "
            f"{_UNITS[k]} beyond {self._how(k)}"
            for k in (0, 1)
            if self.beyond[k]
        ]
        return " and ".join(said) or None


def clip_notice(converters: Sequence[RawImuConverter]) -> str | None:
    """The readings the ``converters`` (one per IMU) skipped as clipped, and those that
    read beyond a full scale (:class:`ClipWatch`), as one line, or None where none was."""

    def each(notes: list[str | None]) -> list[str]:
        return [
            (f"IMU {i}: " if len(converters) > 1 else "") + note
            for i, note in enumerate(notes, start=1)
            if note
        ]

    clipped = each([conv.clips.notice() for conv in converters])
    beyond = each([conv.clips.beyond_notice() for conv in converters])
    said = []
    if clipped:
        said.append(
            "; ".join(clipped) + ": skipped (each that IMU's dropout for the sample): a knock "
            "or a motion beyond the sensor's range, whose reading says nothing of the shape; "
            "a wider range in the IMU's configuration keeps them (accel_range and gyro_range "
            "in the robot file's [[imu]] declare the range)"
        )
    if beyond:
        said.append(
            "; ".join(beyond) + ": kept: no sensor reads past its full scale, so that is not "
            "the sensor's (a declared one: check accel_range and gyro_range in the robot "
            "file's [[imu]]; a flat top: the readings after it are kept)"
        )
    return "; ".join(said) or None


def warn_clipped(name: str, converters: Sequence[RawImuConverter]) -> None:
    """One :class:`~continuum_mhe.io.csv_files.DropoutWarning` naming ``name`` with
    :func:`clip_notice`, where a reading was clipped."""
    if note := clip_notice(converters):
        warnings.warn(f"{name}: {note}", DropoutWarning, stacklevel=3)


class RawImuConverter:
    """Stateful conversion of raw samples, one at a time (the attitude filters keep a
    quaternion). Call :meth:`reset` after a gap in time. A clipped reading
    (:class:`ClipWatch`, in :attr:`clips`) is a dropout (NaN)."""

    def __init__(self, settings: RawImuSettings) -> None:
        self.settings = settings
        self._mount = mount_rotation(settings.mount_rpy)
        self._bias = np.asarray(settings.gyro_bias, dtype=float)
        self._filter: Any = None
        if settings.imu_model != "direct" and settings.attitude != "accel":
            from ahrs.filters import Madgwick, Mahony

            self._filter = Madgwick() if settings.attitude == "madgwick" else Mahony()
        # a gyro the conversion does not use (tilt from the accelerometer) is not watched:
        # its clipped rates would drop good accelerometer readings
        self._gyro_used = settings.needs_gyro
        self.clips = ClipWatch(
            settings.accel_range, settings.gyro_range if self._gyro_used else None
        )
        self.reset()

    @property
    def nz(self) -> int:
        return 6 if self.settings.imu_model == "direct" else 2

    def reset(self) -> None:
        self._q: FloatArray | None = None
        self._t: float | None = None

    def convert(self, t: float, acc: FloatArray, gyr: FloatArray | None) -> FloatArray:
        """Measurement (nz,) for one sample; NaN (a dropout) if the sample is unusable
        or clipped.

        ``acc`` specific force (3,) in any unit, ``gyr`` (3,) rad/s or None.
        """
        acc = np.asarray(acc, dtype=float)
        gyr_row = (
            None
            if gyr is None or not self._gyro_used
            else np.asarray(gyr, dtype=float).reshape(1, 3)
        )
        if self.clips.see(np.array([t], dtype=float), acc.reshape(1, 3), gyr_row)[0]:
            return np.full(self.nz, np.nan)
        return self._convert(t, acc, gyr)

    def _convert(self, t: float, acc: FloatArray, gyr: FloatArray | None) -> FloatArray:
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
        clipped = self.clips.see(t, acc, gyr if self._gyro_used else None)
        if self._filter is not None:
            nan = np.full(self.nz, np.nan)
            rows = [
                nan
                if clipped[i]
                else self._convert(float(t[i]), acc[i], None if gyr is None else gyr[i])
                for i in range(n)
            ]
            return np.array(rows, dtype=float).reshape(n, self.nz)
        acc = np.asarray(acc, dtype=float).reshape(n, 3) @ self._mount.T
        if self.settings.imu_model == "direct":
            if gyr is None:
                raise UserError("the direct IMU model needs gyro readings (gx, gy, gz)")
            gyro = (np.asarray(gyr, dtype=float).reshape(n, 3) - self._bias) @ self._mount.T
            z = direct_measurements(acc, gyro).reshape(n, 6)
            z[clipped] = np.nan
            return z
        usable = np.all(np.isfinite(acc), axis=1) & (np.linalg.norm(acc, axis=1) > 0)
        with np.errstate(invalid="ignore"):
            tilt = tilt_from_accelerometer(acc).reshape(n, 2)
        tilt[~usable | clipped] = np.nan
        return tilt


def raw_to_measurements(
    t: FloatArray, acc: FloatArray, gyr: FloatArray | None, settings: RawImuSettings
) -> FloatArray:
    """Measurements (n, nz) for a whole recording (``t`` s, ``acc`` (n, 3), ``gyr``
    (n, 3) rad/s or None); clipped readings (:class:`ClipWatch`) are dropouts (NaN),
    said in one :class:`~continuum_mhe.io.csv_files.DropoutWarning`."""
    converter = RawImuConverter(settings)
    z = converter.convert_many(t, acc, gyr)
    warn_clipped("raw_to_measurements", [converter])
    return z


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


#: An IMU number before a column's name, as loggers write it (``imu1_ax``, ``IMU_2.gx``).
_IMU_PREFIX = r"(?:imu[_. -]?(?P<before>\d+)[_. -]?)?"
#: A unit after a column's name, which the readers do not read (``ax_1 [m/s^2]``,
#: ``gx_1 (deg/s)``, ``gx_1_rad_s``, ``gz_dps``, ``ax_mps2``).
_UNIT_TAIL = (
    r"(?P<unit>\s*[\[(][^\])]*[\])]"
    r"|[_ ](?:rad_?s|rad_per_s|dps|deg_?s|deg_per_s|mps2|m_s2|m_s_2|ms2|rad|deg))?"
)
#: A header column that names an accelerometer or gyro axis in another spelling
#: (``ax1``, ``acc_x``, ``accel_x_2``, ``gyro_z1``, ``wx``, ``imu1_ax``, ``gx_1_dps``): its
#: sensor, axis and IMU number.
_OTHER_RAW_NAME = re.compile(
    rf"^{_IMU_PREFIX}(?:(?P<acc>a|acc|accel|accelerometer)|(?P<gyro>g|gyr|gyro|w|omega))"
    rf"[_. -]?(?P<axis>[xyz])(?:[_. -]?(?P<after>\d+))?{_UNIT_TAIL}$",
    re.IGNORECASE,
)
#: A header column that names a tilt angle in another spelling (``imu1_roll``,
#: ``roll_1 [rad]``, ``pitch1``): its angle and IMU number.
_OTHER_TILT_NAME = re.compile(
    rf"^{_IMU_PREFIX}(?P<angle>roll|pitch)(?:[_. -]?(?P<after>\d+))?{_UNIT_TAIL}$",
    re.IGNORECASE,
)


def _imu_number(m: re.Match[str]) -> int | None:
    """The IMU number a column's name gives (:data:`_OTHER_RAW_NAME`,
    :data:`_OTHER_TILT_NAME`), before or after its axis; None without one."""
    number = m.group("before") or m.group("after")
    return int(number) if number else None


def _renames(rows: TextRows, matches: Sequence[tuple[str, re.Match[str], str]]) -> list[str]:
    """``"ax1 -> ax_1"`` for each ``(column, match, name)`` whose column is not named
    ``name`` with its IMU's number (a file's numbers from 0 read from 1; one IMU
    numbered 0 unnumbered)."""
    numbers = [k for _, m, _ in matches if (k := _imu_number(m)) is not None]
    first = min(numbers, default=1)  # IMUs count from 1: a file's 0 is IMU 1
    several = len(set(numbers)) > 1
    renames = []
    for h, m, name in matches:
        k = _imu_number(m)
        if k is not None and (several or first != 0):
            name += f"_{k + 1 - min(first, 1)}"
        if name != h:
            renames.append(f"{rows.as_written(h)} -> {name}")
    return renames


def _other_raw_renames(rows: TextRows) -> list[str]:
    """``"ax1 -> ax_1"`` for each header column that names an accelerometer or gyro axis
    (:data:`_OTHER_RAW_NAME`), or a tilt angle (:data:`_OTHER_TILT_NAME`), otherwise
    than this reader takes."""
    matches = [
        (h, m, ("a" if m.group("acc") else "g") + m.group("axis").lower())
        for h in rows.header
        if (m := _OTHER_RAW_NAME.match(h))
    ]
    matches += [
        (h, m, m.group("angle").lower()) for h in rows.header if (m := _OTHER_TILT_NAME.match(h))
    ]
    return _renames(rows, matches)


def _other_gyro_renames(rows: TextRows, suffixes: Sequence[str]) -> list[str]:
    """``"gyro_x -> gx"`` for each header column that names a gyro axis
    (:data:`_OTHER_RAW_NAME`, ``gx_1`` included) but is not one of the gyro columns of
    the IMUs ``suffixes`` (``[""]`` for one IMU's, ``["_1", ...]``) that the reader
    takes: its name for the robot's IMUs (a file's numbers from 0 read from 1)."""
    wanted = {c + s for s in suffixes for c in GYRO_COLUMNS}
    matches = [
        (h, m)
        for h in rows.header
        if h not in wanted and (m := _OTHER_RAW_NAME.match(h)) and m.group("gyro")
    ]
    numbers = [k for _, m in matches if (k := _imu_number(m)) is not None]
    shift = 1 if numbers and min(numbers) == 0 else 0
    renames = []
    for h, m in matches:
        axis = "g" + m.group("axis").lower()
        k = _imu_number(m)
        number = k + shift if k is not None else 1
        name = axis if suffixes == [""] else f"{axis}_{number}"
        renames.append(f"{rows.as_written(h)} -> {name}")
    return renames


def _refuse_other_raw_names(rows: TextRows) -> None:
    """A one-line error for a header with neither tilt nor raw columns but with columns
    that name accelerometer or gyro axes or tilt angles otherwise (:data:`_OTHER_RAW_NAME`,
    :data:`_OTHER_TILT_NAME`: another spelling, an IMU number before the name, a unit
    after it): the names this reader takes, and what each such column would be called
    (``ax1`` -> ``ax_1``). Any other header is left to the tilt reader's message."""
    renames = _other_raw_renames(rows)
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
    which = "accelerometer column" if gyros else "column"  # the gyros' are named so
    raise InputError(
        f"{rows.name}: line 1: no {which} is named as this reader takes IMU readings: raw "
        "columns are t,ax,ay,az,gx,gy,gz for one IMU and ax_1 ... gz_1, ax_2 ... for "
        f"several (m/s^2, rad/s), tilt ones roll, pitch (roll_1, pitch_1 ...); rename the "
        f"columns ({shown})"
    )


def raw_columns(i: int, n_imus: int, gyro: bool = True) -> tuple[str, ...]:
    """Raw columns of IMU ``i`` (0-based): ``ax..gz`` for one IMU, ``ax_1..gz_1``..."""
    names = RAW_FIELDS if gyro else ACC_COLUMNS
    return tuple(f"{c}{imu_suffix(i, n_imus)}" for c in names)


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
    if not gyro and (renames := _other_gyro_renames(rows, suffixes)):
        shown = ", ".join(renames[:3]) + (", ..." if len(renames) > 3 else "")
        raise InputError(
            f"{rows.name}: line 1: columns named like gyro readings that this reader does "
            f"not take, which would be left out: rename them ({shown}; gx, gy, gz in "
            "rad/s, gx_1 ... for several IMUs), or remove them to estimate from the "
            "accelerometers alone"
        )
    fields = RAW_IMU_COLUMNS.names if gyro else ACC_COLUMNS
    return ("t", *(c + s for s in suffixes for c in fields)), bool(gyro)


def impossible_readings(
    acc: FloatArray, gyr: FloatArray | None
) -> tuple[FloatArray, FloatArray, NDArray[np.bool_], NDArray[np.bool_]]:
    """``(|a|, |omega|, zero, huge)`` of each row of ``acc`` (n, 3) m/s^2 and ``gyr``
    (n, 3) rad/s, or None without gyros: an acceleration with no gravity direction (a
    zero, or a magnitude whose square underflows, under about 1e-162 m/s^2, which the
    conversions' norm takes as zero), and a reading beyond any IMU's range
    (:data:`ACCEL_READING_MAX`, :data:`GYRO_READING_MAX`); a NaN row (a dropout) is
    neither."""
    with np.errstate(invalid="ignore", under="ignore"):
        acc_norm = np.hypot.reduce(acc, axis=1)  # hypot: no overflow of a finite 1e200
        gyr_norm = np.zeros(len(acc)) if gyr is None else np.hypot.reduce(gyr, axis=1)
        huge = (acc_norm > ACCEL_READING_MAX) | (gyr_norm > GYRO_READING_MAX)
        zero = (acc_norm == 0.0) | (np.einsum("ij,ij->i", acc, acc) == 0.0)
    return acc_norm, gyr_norm, zero, huge


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
    motion_watch: MotionUnitWatch | None = None,
    range_dropouts: bool = False,
) -> list[tuple[FloatArray, FloatArray | None]]:
    """``(acc, gyr)`` of each IMU from a raw table's values (n, k), unit-checked (a gyro
    in deg/s: an error if ``gyro_used``, else a warning; :func:`check_gyro_units`; on a
    later block of a file read in blocks (not ``first_block``), only where it has
    :data:`UNIT_CHECK_SAMPLES` readings or more: a short last block of a fast turn is
    no deg/s; with the rows' times ``t`` (n,) s, the first block's gyros are also held
    against the accelerometers: :func:`gyro_gravity_problem`; with ``motion_watch`` (a
    whole table's, or a stream's, which gathers its first blocks' rows), the times are
    checked against the gyros, and from the second block on a gyro the estimate uses
    against the turns of the motion: :class:`MotionUnitWatch`).

    A zero acceleration, or a reading beyond any IMU's range (:data:`ACCEL_READING_MAX`,
    :data:`GYRO_READING_MAX`), is an error naming the line (and, of several IMUs, the
    IMU), or with ``skip_bad`` a dropout of that IMU's sample (recorded); of several
    IMUs, a non-finite value that reached here makes that IMU's sample a dropout
    (NaN), and so does a zero or out-of-range reading where ``range_dropouts`` (one IMU
    or several, for a caller that counts and says them: ``calibrate``'s rest
    recording)."""
    k = 6 if has_gyro else 3
    out: list[tuple[FloatArray, FloatArray | None]] = []
    for i in range(n_imus):
        label = name if n_imus == 1 else f"{name}: IMU {i + 1}"
        block = values[:, k * i : k * (i + 1)].copy()
        if has_gyro and first_block:
            _refuse_a_gyro_never_given(name, block, i, n_imus)
        if n_imus > 1:
            block[~np.all(np.isfinite(block), axis=1)] = np.nan
        acc = block[:, :3]
        acc_norm, gyr_norm, zero, huge = impossible_readings(
            acc, block[:, 3:6] if has_gyro else None
        )
        check_accel_range(label, acc_norm)
        which = "" if n_imus == 1 else f"IMU {i + 1}: "
        said_here = not range_dropouts  # else the caller counts them
        for j in np.flatnonzero(zero | huge) if said_here else ():
            msg = f"line {lines[int(j)]}: {which}" + (
                "acceleration is zero (no gravity direction)"
                if zero[j] and acc_norm[j] == 0.0
                else f"acceleration is zero to double precision (|a| {acc_norm[j]:.3g} "
                "m/s^2: no gravity direction)"
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
        check_accel_units(label, acc)
        # the times first: times a thousand times too long would make the gyro's
        # gravity check below read a rad/s gyro as deg/s
        if has_gyro and t is not None and motion_watch is not None:
            motion_watch.add(label, t, acc, block[:, 3:6], gyro_used)
        judged = first_block or int(np.isfinite(gyr_norm).sum()) >= UNIT_CHECK_SAMPLES
        if has_gyro and judged:
            gravity = t is not None and first_block
            check_gyro_units(
                label, block[:, 3:6], gyro_used, t if gravity else None, acc if gravity else None
            )
        out.append((acc, block[:, 3:6] if has_gyro else None))
    return out


#: A first block of at least this many rows in which an IMU's accelerometer reads and
#: its gyro columns are empty in every row is a file of an IMU without a gyro.
NO_GYRO_ROWS = 10


def _refuse_a_gyro_never_given(name: str, block: FloatArray, i: int, n_imus: int) -> None:
    """A one-line :class:`InputError` where IMU ``i``'s gyro columns (``block`` (n, 6),
    the first block's rows) are empty in every row while its accelerometer reads in
    some (:data:`NO_GYRO_ROWS` rows at least): each such row would be a dropout of the
    IMU (its reading needs all six values), the accelerometer thrown away with it."""
    acc_read = np.all(np.isfinite(block[:, :3]), axis=1)
    if len(block) < NO_GYRO_ROWS or acc_read.sum() < NO_GYRO_ROWS:
        return
    if np.isfinite(block[:, 3:6]).any():
        return
    gyro = ", ".join(raw_columns(i, n_imus)[3:6])
    which = "the IMU" if n_imus == 1 else f"IMU {i + 1}"
    raise InputError(
        f"{name}: {gyro} are empty in every row while {which}'s accelerometer reads: an "
        f"IMU without a gyro? A reading needs all six values (each row would be a dropout); "
        "leave every IMU's gyro columns out of the file (the accelerometers are then read "
        "alone, with the tilt model)"
    )


def read_raw_imus(
    path: str | os.PathLike[str],
    n_imus: int,
    *,
    skip_bad: bool = False,
    fix: str = READER_FIX,
    range_dropouts: bool = False,
) -> MultiRawImuTable:
    """Read a raw CSV of ``n_imus`` IMUs: ``t,ax_1,ay_1,az_1[,gx_1,gy_1,gz_1],ax_2,...``
    (m/s^2, rad/s, each IMU in its own sensor frame). A file of another number of IMUs
    is a one-line error that names ``fix`` (the command line names ``--robot``). A
    reading beyond any IMU's range is an error naming its line and IMU, or with
    ``skip_bad`` that IMU's dropout there (in ``skipped``), or with ``range_dropouts``
    that IMU's dropout, for the caller to count (:func:`raw_blocks`)."""
    with open_rows(path) as rows:
        cols, has_gyro = raw_layout(rows, n_imus, fix)
        got = read_sample_rows(rows, cols, skip_bad=skip_bad, empty_is_dropout=True)
    check_time_units(rows, got.t)
    skipped = list(got.skipped)
    blocks = raw_blocks(
        rows.name, got.values, got.lines, n_imus, has_gyro, skip_bad, skipped, t=got.t,
        motion_watch=MotionUnitWatch(rows.time_scale), range_dropouts=range_dropouts,
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
        motion_watch=MotionUnitWatch(rows.time_scale),
    )  # fmt: skip
    return RawImuTable(t=got.t, acc=acc, gyr=gyr, skipped=skipped)
