"""The line protocol of the serial IMU stream, for any number of IMUs.

ASCII lines ending in LF, CR or CRLF, one sample per line:

* ``raw``:  ``t_ms`` then ``ax,ay,az,gx,gy,gz`` per IMU: device time in ms, specific
  force in m/s^2 and angular rate in rad/s, each IMU in its own sensor frame;
* ``tilt``: ``t_ms`` then ``roll,pitch`` per IMU, rad.

IMUs come in the robot file's order. A tendon robot's line carries the tendon
tensions after the IMUs' values: ``tension_1,...,tension_k`` in N, in the robot file's
``[[tendon]]`` order (unless they come from a file). Lines starting with ``#`` are comments (the
firmware's banner, its ``# fields: ...`` line naming the fields, errors); blank lines
are ignored. A line longer than :data:`MAX_LINE_BYTES` is dropped and counted.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.io.csv_files import tilt_columns
from continuum_mhe.io.raw_imu import raw_columns
from continuum_mhe.io.slack_readings import take_slack_readings
from continuum_mhe.io.tensions import tension_columns
from continuum_mhe.io.text_rows import declared_fields
from continuum_mhe.model.descriptions import imu_suffix
from continuum_mhe.model.imu import PITCH_LIMIT, ROLL_LIMIT, STANDARD_GRAVITY

LineFormat = Literal["raw", "tilt"]
LINE_FORMATS: tuple[LineFormat, ...] = ("raw", "tilt")
#: Values per IMU on a line.
VALUES_PER_IMU: dict[str, int] = {"raw": 6, "tilt": 2}
#: The margin of a raw line's plausibility limits over a full scale.
RANGE_MARGIN = 1.5
#: Plausibility limits of a raw line's values (m/s^2, rad/s) where the robot file
#: declares no larger full scale: the firmware's MPU9250 (16 g, 2000 deg/s) with the
#: margin.
ACC_LIMIT = 16 * STANDARD_GRAVITY * RANGE_MARGIN
GYRO_LIMIT = math.radians(2000) * RANGE_MARGIN
TILT_LIMITS = (ROLL_LIMIT, PITCH_LIMIT)


@dataclass(frozen=True)
class RawLimits:
    """The largest magnitude an IMU's accelerometer axis (``accel``, m/s^2) and gyro axis
    (``gyro``, rad/s) may send on a raw line; a value beyond is not a reading (raw
    counts, deg/s, a garbled field). ``accel_range``, ``gyro_range``: the robot file's
    full scales they come from, or None for the default's."""

    accel: float = ACC_LIMIT
    gyro: float = GYRO_LIMIT
    accel_range: float | None = None
    gyro_range: float | None = None


#: The limits of an IMU whose robot file declares no full scale beyond the default's.
DEFAULT_RAW_LIMITS = RawLimits()


def raw_limits(accel_range: float | None, gyro_range: float | None) -> RawLimits:
    """The limits of an IMU whose robot file declares these full scales (m/s^2, rad/s,
    or None): the margin over a declared full scale beyond the default's, else the
    default (a reading beyond a smaller declared scale is the conversion's to judge, as
    a file's: clipped or named, ``continuum_mhe.io.raw_imu``)."""
    accel = RANGE_MARGIN * accel_range if accel_range is not None else 0.0
    gyro = RANGE_MARGIN * gyro_range if gyro_range is not None else 0.0
    return RawLimits(
        max(ACC_LIMIT, accel),
        max(GYRO_LIMIT, gyro),
        accel_range if accel > ACC_LIMIT else None,
        gyro_range if gyro > GYRO_LIMIT else None,
    )


#: Longest accepted line, bytes (a sample of 8 raw IMUs is under 500).
MAX_LINE_BYTES = 4096


class GarbledLine(ValueError):
    """A line that is not a valid sample (the message says why); ``kind``: the cause
    without the line's own values, under which such lines are counted (the message
    where None); ``degrees_for_radians``: a tilt angle beyond the radians' range (a
    board sending degrees)."""

    def __init__(
        self, message: str, kind: str | None = None, degrees_for_radians: bool = False
    ) -> None:
        super().__init__(message)
        self.kind = kind if kind is not None else message
        self.degrees_for_radians = degrees_for_radians


@dataclass(frozen=True)
class Sample:
    """One parsed line: device time ``t_ms`` in ms and the values, IMU after IMU
    (raw: 6 per IMU, tilt: 2 per IMU); an IMU whose fields were not a valid reading
    (on a line whose other IMUs' were) has NaN values, a dropout, and ``problems``
    says why (``"IMU 2: non-numeric field"``). ``tensions``: the tendon tensions the
    line carried, N (empty for a line without them)."""

    t_ms: float
    values: FloatArray
    problems: tuple[str, ...] = ()
    tensions: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def t(self) -> float:
        """Device time, s."""
        return self.t_ms / 1e3


def value_columns(fmt: LineFormat, n_imus: int, n_tensions: int = 0) -> tuple[str, ...]:
    """The value names of ``n_imus`` IMUs, as the CSV files of ``estimate`` name them:
    ``ax..gz`` or ``roll,pitch`` for one IMU, ``ax_1..gz_1,ax_2..`` for several; then
    ``tension_1..tension_k`` for a line with ``n_tensions`` tensions."""
    imus = (
        tilt_columns(n_imus)
        if fmt == "tilt"
        else tuple(c for i in range(n_imus) for c in raw_columns(i, n_imus))
    )
    return (*imus, *tension_columns(n_tensions))


def line_fields(fmt: LineFormat, n_imus: int, n_tensions: int = 0) -> tuple[str, ...]:
    """The fields of a protocol line: ``t_ms`` and :func:`value_columns`."""
    return ("t_ms", *value_columns(fmt, n_imus, n_tensions))


def _number(text: str) -> float:
    """A finite field value, or :class:`GarbledLine`."""
    if not text.isascii() or "_" in text:  # what float reads beyond CSV's numbers
        raise GarbledLine("non-numeric field")
    try:
        v = float(text)
    except ValueError:
        raise GarbledLine("non-numeric field") from None
    if not math.isfinite(v):
        raise GarbledLine("non-finite value")
    return v


#: the problem a tilt angle beyond its range names (a board sending degrees)
DEGREES_FOR_RADIANS = "degrees given for radians?"


def _imu_values(
    fields: list[str], fmt: LineFormat, imu: int, n_imus: int, limits: RawLimits
) -> list[float]:
    """One IMU's values of a line, checked (plausible within ``limits``, finite), or
    :class:`GarbledLine`."""
    v = [_number(f) for f in fields]
    if fmt == "raw":
        ax, ay, az, gx, gy, gz = v
        if (
            max(abs(ax), abs(ay), abs(az)) > limits.accel
            or max(abs(gx), abs(gy), abs(gz)) > limits.gyro
        ):
            raise GarbledLine(beyond_range(v, imu, n_imus, limits))
        if ax == 0.0 and ay == 0.0 and az == 0.0:
            raise GarbledLine("accelerometer reads exactly zero")
        if ax * ax + ay * ay + az * az == 0.0:  # a square underflows: no direction either
            raise GarbledLine("accelerometer reads zero to double precision")
    else:
        suffix = imu_suffix(imu, n_imus)
        for name, value, limit, bound in zip(("roll", "pitch"), v, TILT_LIMITS, ("pi", "pi/2")):
            if abs(value) > limit:
                raise GarbledLine(
                    f"{name}{suffix} = {value:g}, beyond {bound}: {DEGREES_FOR_RADIANS}",
                    kind=f"{name}{suffix} beyond {bound}: {DEGREES_FOR_RADIANS}",
                    degrees_for_radians=True,
                )
    return v


def parse_line(
    text: str,
    fmt: LineFormat,
    n_imus: int = 1,
    n_tensions: int = 0,
    limits: Sequence[RawLimits] = (),
) -> Sample | None:
    """Parse one protocol line (``n_tensions`` tendon tensions after the IMUs' values);
    None for comments and blank lines. ``limits``: each IMU's (:func:`raw_limits`, from
    its robot file's full scales), or empty for the default's.

    Raises :class:`GarbledLine` for anything else that is not a complete, plausible
    sample (wrong field count, a bad time, non-numbers, non-finite or out-of-range
    values, an accelerometer that reads zero or so near it that its square underflows, a
    negative tension). On a line of
    several IMUs, an IMU whose values are bad is a dropout (NaN, said in
    :attr:`Sample.problems`) and the others are kept; a line with no good IMU is
    garbled, and so is one with a bad tension (the model cannot predict the IMUs
    without every tension).
    """
    line = text.strip()
    if not line or line.startswith("#"):
        return None
    parts = line.split(",")
    k = VALUES_PER_IMU[fmt]
    n_fields = 1 + k * n_imus + n_tensions
    if len(parts) != n_fields:
        trailing = (
            " (the last one empty: a separator at the end of the line?)"
            if len(parts) == n_fields + 1 and not parts[-1].strip()
            else ""
        )
        raise GarbledLine(f"expected {n_fields} fields, found {len(parts)}{trailing}")
    t_ms = _number(parts[0])
    if t_ms < 0:
        raise GarbledLine("negative time")
    tensions = _tensions(parts[1 + k * n_imus :])
    values: list[float] = []
    problems: list[str] = []
    first_kind = ""  # the first problem's cause, without its values
    first_degrees = False  # ... and whether it is a tilt angle beyond the radians' range
    for i in range(n_imus):
        try:
            limit = limits[i] if limits else DEFAULT_RAW_LIMITS
            values += _imu_values(parts[1 + k * i : 1 + k * (i + 1)], fmt, i, n_imus, limit)
        except GarbledLine as exc:
            if n_imus == 1:
                raise
            problems.append(f"IMU {i + 1}: {exc}")
            if not first_kind:
                first_kind = f"IMU {i + 1}: {exc.kind}"
                first_degrees = exc.degrees_for_radians
            values += [math.nan] * k
    if len(problems) == n_imus:
        raise GarbledLine(problems[0], kind=first_kind, degrees_for_radians=first_degrees)
    return Sample(t_ms, np.array(values), tuple(problems), tensions)


def _tensions(fields: list[str]) -> FloatArray:
    """A line's tendon tensions, N: finite and not below zero by more than a slack
    tendon's load cell reads (:mod:`~continuum_mhe.io.slack_readings`), or
    :class:`GarbledLine`."""
    try:
        v = np.array([_number(f) for f in fields])
    except GarbledLine as exc:
        raise GarbledLine(f"a tension: {exc}") from None
    taken = take_slack_readings(v[None, :])
    if taken.too_negative.any():
        raise GarbledLine(
            "a negative tension (a tendon cannot push; a slack one's is 0, read down to "
            f"-{taken.limit[0]:.3g} N)"
        )
    return v  # a slack tendon's reading below zero: the estimator's step takes it as 0


def beyond_range(
    values: list[float], imu: int, n_imus: int, limits: RawLimits | None = None
) -> str:
    """Why raw ``values`` (one IMU's six, ``imu`` 0-based) are beyond the sensor's range
    (``limits``, the default's where None): the first field out of range, the limit and
    the likely unit mistake."""
    lim = limits if limits is not None else DEFAULT_RAW_LIMITS
    gyro_scale = (
        f"the robot file's gyro_range {lim.gyro_range:g} rad/s"
        if lim.gyro_range is not None
        else "2000 deg/s"
    )
    accel_scale = (
        f"the robot file's accel_range {lim.accel_range:g} m/s^2"
        if lim.accel_range is not None
        else "16 g"
    )
    for name, v in zip(raw_columns(imu, n_imus), values):
        if name.startswith("g") and abs(v) > lim.gyro:
            return (
                f"{name} beyond the gyro's range (|{name}| > {lim.gyro:.1f} rad/s, {gyro_scale} "
                "and a margin): deg/s given for rad/s?"
            )
        if name.startswith("a") and abs(v) > lim.accel:
            return (
                f"{name} beyond the accelerometer's range (|{name}| > {lim.accel:.0f} m/s^2, "
                f"{accel_scale} and a margin): raw counts or mg given for m/s^2?"
            )
    return "value beyond the sensor's range"


def field_count_hint(
    text: str, fmt: LineFormat, n_imus: int, n_tensions: int = 0, file_tensions: int = 0
) -> str:
    """A likely cause of a line with the wrong number of fields, or "": the tensions
    left out (a line of the IMUs alone where ``n_tensions`` tensions follow them), the
    tensions on the line where ``file_tensions`` tensions come from a file (``--inputs``),
    ``--format`` (another format with the robot's IMU count), then the IMU count of
    ``--robot`` (another whole number of IMUs in this format), then both."""
    found = len(text.strip().split(","))
    if found == 1 + VALUES_PER_IMU[fmt] * n_imus + n_tensions:  # garbled otherwise
        return ""
    if file_tensions and found == 1 + VALUES_PER_IMU[fmt] * n_imus + file_tensions:
        return (
            f": a line of the IMUs and the robot's {file_tensions} tendon tensions, which "
            "--inputs gives too; leave --inputs out (live then reads the line's), or send "
            "the IMUs' fields alone"
        )
    if n_tensions and found == 1 + VALUES_PER_IMU[fmt] * n_imus:
        return (
            f": a line without the robot's {n_tensions} tendon tensions; send "
            f"tension_1..tension_{n_tensions} (N) after the IMUs' fields, or give --inputs "
            "TENSIONS.csv"
        )
    found -= n_tensions  # the IMUs' part of a line that carries the tensions
    others = [g for g in LINE_FORMATS if g != fmt]
    for g in others:
        if found == 1 + VALUES_PER_IMU[g] * n_imus:
            return f": a line of {n_imus} IMU(s) in --format {g}; --format {g}?"
    for f in (fmt, *others):
        m, rest = divmod(found - 1, VALUES_PER_IMU[f])
        if m >= 1 and not rest and (f, m) != (fmt, n_imus):
            option = f"--robot with {m} IMU(s)" if f == fmt else f"--format {f} with {m} IMU(s)"
            return f": a line of {m} IMU(s) in --format {f}; {option}?"
    return ""


def header_hint(
    names: tuple[str, ...],
    fmt: LineFormat,
    n_imus: int,
    n_tensions: int = 0,
    file_tensions: int = 0,
) -> str:
    """What to check where a device's ``# fields:`` line names other ``names`` than a line
    of ``n_tensions`` tensions expects: the tensions left out of the names (a controller
    that adds its tensions to the IMU board's lines and forwards the board's ``# fields:``
    line as it is), the tensions named where ``file_tensions`` come from ``--inputs``, else
    ``--format`` and ``--robot``."""
    imus = line_fields(fmt, n_imus)
    if n_tensions and names == imus:
        return (
            f"it names no tendon tensions: each line must carry tension_1..tension_{n_tensions} "
            "(N) after the IMUs' fields, and a controller that adds them to the IMU board's "
            "lines adds their names to its '# fields:' line too; or give --inputs TENSIONS.csv"
        )
    if file_tensions and names == line_fields(fmt, n_imus, file_tensions):
        return (
            f"it names the robot's {file_tensions} tendon tensions, which --inputs gives too; "
            "leave --inputs out (live then reads the line's), or send the IMUs' fields alone"
        )
    expected = line_fields(fmt, n_imus, n_tensions)
    if names != expected and sorted(names) == sorted(expected):
        return (
            "the same fields in another order: the device must send them in live's order, "
            f"{','.join(expected)} (live reads fields by place, and would take one for another)"
        )
    return "check --format and --robot"


def header_fields(comment: str) -> tuple[str, ...] | None:
    """The field names of a ``# fields: t_ms,ax,... (units)`` comment (or ``# format:``,
    ``# columns:``), or None for any other line: the same reading as a file's
    (:func:`~continuum_mhe.io.text_rows.declared_fields`)."""
    if not comment.lstrip().startswith("#"):
        return None
    return declared_fields(comment)


_EOL = re.compile(rb"\r\n|\r|\n")


class LineSplitter:
    """Bytes in, whole lines out: LF, CR and CRLF end a line; a line longer than
    ``max_bytes`` is dropped (its length is reported) up to its end, never buffered.
    The first line after a (re)open may be the tail of a cut one: the session decides
    (:class:`~continuum_mhe.live.session.LiveSession` checks it against the next).

    Attributes:
        too_long: lengths (bytes) of the lines dropped since the last :meth:`feed`.
    """

    def __init__(self, max_bytes: int = MAX_LINE_BYTES) -> None:
        self.max_bytes = max_bytes
        self._buf = bytearray()
        self._skipping = 0  # bytes of an over-long line dropped so far (0: not dropping)
        self._after_cr = False
        self.too_long: list[int] = []

    def feed(self, chunk: bytes) -> list[bytes]:
        """The non-empty lines completed by ``chunk`` (without their line ends)."""
        lines: list[bytes] = []
        self.too_long = []
        pos = 0
        if self._after_cr and chunk[:1] == b"\n":  # a CRLF split across two reads
            pos = 1
        self._after_cr = chunk[-1:] == b"\r"
        for m in _EOL.finditer(chunk, pos):
            self._take(chunk[pos : m.start()], lines, end=True)
            pos = m.end()
        self._take(chunk[pos:], lines, end=False)
        return lines

    def _take(self, piece: bytes, lines: list[bytes], end: bool) -> None:
        if self._skipping:
            self._skipping += len(piece)
        elif len(self._buf) + len(piece) > self.max_bytes:
            self._skipping = len(self._buf) + len(piece)
            self._buf.clear()
        else:
            self._buf += piece
        if not end:
            return
        if self._skipping:
            self.too_long.append(self._skipping)
            self._skipping = 0
        elif self._buf:
            lines.append(bytes(self._buf))
            self._buf.clear()

    @property
    def unended(self) -> int:
        """Bytes of the line being dropped for its length so far (0: none): bytes that
        arrive with no line end (another baud rate, or another line end)."""
        return self._skipping

    def resync(self) -> None:
        """The port was (re)opened mid-stream: what was buffered belongs to the old
        connection and is forgotten."""
        self._buf.clear()
        self._skipping = 0
        self._after_cr = False

    def pending(self) -> bytes:
        """Take the unfinished line (when the device goes away mid-line)."""
        left = bytes(self._buf)
        self._buf.clear()
        self._skipping = 0
        self._after_cr = False
        return left
