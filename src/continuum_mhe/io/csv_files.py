"""Measurement CSVs read: tilt readings with their times, and the checks of their
times and angle units.

Format (docs/formats.md): a header with at least ``t,roll,pitch`` (one IMU) or
``t,roll_1,pitch_1,roll_2,pitch_2,...`` (IMUs numbered from the base in the robot
file's order, :mod:`.imu_columns`); ``t`` in seconds, strictly increasing; angles in
radians (``degrees=True`` for degrees), in the convention of
:mod:`continuum_mhe.model.imu`. Other columns are ignored. With several IMUs an empty
field is a dropout of that IMU. Measurement, estimate and truth files written:
:mod:`.estimate_csv`; estimate and truth files read: :mod:`.state_tables`.

Every problem in an input file raises :class:`~continuum_mhe.errors.InputError` with a
one-line message naming the file and line.
"""

from __future__ import annotations

import math
import os
import sys
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, expect_type, is_integer
from continuum_mhe.io.imu_columns import READER_FIX, ROBOT_FIX, TILT_IMU_COLUMNS, imu_suffixes
from continuum_mhe.io.sample_rows import RowProblems, read_samples
from continuum_mhe.io.text_rows import MEASUREMENT_HEADER_HINT, TextRows, open_rows
from continuum_mhe.model.descriptions import (
    imu_suffix,
    tilt_blocks,
)
from continuum_mhe.model.imu import PITCH_LIMIT, ROLL_LIMIT


@dataclass(frozen=True)
class MeasurementTable:
    """Measurements read from a file.

    Attributes:
        t: (n,) s, strictly increasing.
        z: (n, 2 n_imus) ``[roll, pitch]`` of each IMU, rad; NaN marks a skipped (bad)
            sample, kept as a dropout so the output still has its row.
        skipped: descriptions of rows dropped or turned into dropouts (``skip_bad``).
    """

    t: FloatArray
    z: FloatArray
    skipped: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class SampleRows:
    """Validated rows of a sample CSV: ``t`` (n,), ``values`` (n, k) with NaN for a
    bad value kept as a dropout, the file's line number of each row, and ``skipped``."""

    t: FloatArray
    values: FloatArray
    lines: list[int]
    skipped: list[str]


def read_sample_rows(
    rows: TextRows,
    columns: Sequence[str],
    *,
    skip_bad: bool = False,
    empty_is_dropout: bool = False,
) -> SampleRows:
    """All validated rows of a sample table (see :func:`~continuum_mhe.io.sample_rows.
    read_samples`); every skipped row is listed in ``skipped``."""
    problems = RowProblems(keep=sys.maxsize)
    lines: list[int] = []
    t: list[float] = []
    values: list[list[float]] = []
    for line, tv, vals in read_samples(
        rows, columns, skip_bad=skip_bad, empty_is_dropout=empty_is_dropout, problems=problems
    ):
        lines.append(line)
        t.append(tv)
        values.append(vals)
    arr = np.array(values, dtype=float).reshape(len(t), len(columns) - 1)
    return SampleRows(np.array(t, dtype=float), arr, lines, problems.first)


def tilt_columns(n_imus: int) -> tuple[str, ...]:
    """``roll, pitch`` for one IMU; ``roll_1, pitch_1, roll_2, ...`` for several."""
    return tuple(f"{c}{imu_suffix(i, n_imus)}" for i in range(n_imus) for c in ("roll", "pitch"))


def read_measurements(
    path: str | os.PathLike[str],
    *,
    degrees: bool = False,
    skip_bad: bool = False,
    n_imus: int = 1,
) -> MeasurementTable:
    """Read a measurement CSV (``t,roll,pitch``, or ``t,roll_1,pitch_1,...`` for
    ``n_imus`` IMUs), validating every row.

    With ``skip_bad``, rows whose angles are missing, non-numeric, NaN or out of range
    become dropouts (kept, NaN angles) and rows with a bad or non-increasing ``t`` are
    dropped; each is recorded in ``skipped``. Without it, the first bad row raises.
    An empty field is a dropout of its IMU only (an IMU without any valid reading gives
    a :class:`DropoutWarning`). A file with columns
    for another number of IMUs than ``n_imus`` (``roll_1 ... roll_2`` for one) is an
    error, never read in part.
    """
    expect_type("degrees", degrees, bool, "True or False")
    expect_type("skip_bad", skip_bad, bool, "True or False")
    if not (is_integer(n_imus) and n_imus >= 1):
        raise UserError(f"n_imus must be a positive integer (the IMUs in the file), got {n_imus!r}")
    with open_rows(path) as rows:
        columns = tilt_sample_columns(rows, int(n_imus), fix=READER_FIX)
        got = read_sample_rows(rows, columns, skip_bad=skip_bad, empty_is_dropout=True)
    check_time_units(rows, got.t)
    z = tilt_values(
        rows.name,
        got.values,
        got.lines,
        degrees,
        n_imus,
        got.skipped if skip_bad else None,
        [rows.as_written(c) for c in columns[1:]],
    )
    if degrees:
        seen = DegreesCheck()
        seen.add(np.where(np.isfinite(z), got.values, np.nan))  # out-of-range rows skipped
        seen.warn(rows.name)
    readings = ReadingCounts(tuple(b.slice for b in tilt_blocks(n_imus)))
    readings.add(z)
    readings.warn_silent(rows.name)
    return MeasurementTable(t=got.t, z=z, skipped=got.skipped)


def tilt_sample_columns(rows: TextRows, n_imus: int, fix: str = ROBOT_FIX) -> tuple[str, ...]:
    """The columns read from a tilt table: ``t`` and the IMUs' roll and pitch. A header
    with a column missing from an IMU's set, or with columns for another number of IMUs
    (an error ending in ``fix``, ``{found}`` replaced by the file's IMU count), is a
    one-line error (:func:`imu_suffixes`); so is a tensions file's header (``t,tension_1,
    ...`` without a tilt column: :func:`refuse_tensions_file`)."""
    refuse_tensions_file(rows)
    suffixes = imu_suffixes(rows, n_imus, TILT_IMU_COLUMNS, fix)
    return ("t", *(c + s for s in suffixes for c in TILT_IMU_COLUMNS.fields))


def refuse_tensions_file(rows: TextRows) -> None:
    """A one-line error for a tensions file (``t,tension_1,...``: tension columns and no
    roll or pitch column) given where the IMU readings go: it belongs to ``--inputs``."""
    tensions = [h for h in rows.header if h.startswith("tension_")]
    if not tensions or any(h.split("_")[0] in ("roll", "pitch") for h in rows.header):
        return
    span = rows.as_written(tensions[0])
    if len(tensions) > 1:
        span += f" ... {rows.as_written(tensions[-1])}"
    raise InputError(
        f"{rows.name}: line 1: this looks like a tensions file (columns {span}), not IMU "
        "readings: it belongs to --inputs (InputOptions(tensions=...) in Python); the "
        f"measurement file holds the IMU readings, e.g. {MEASUREMENT_HEADER_HINT}"
    )


def tilt_values(
    name: str,
    values: FloatArray,
    lines: Sequence[int],
    degrees: bool,
    n_imus: int,
    skipped: list[str] | None,
    names: Sequence[str],
) -> FloatArray:
    """Measurements (n, 2 n_imus) in rad from the file's values, range-checked: an angle
    out of range is a one-line error, or with ``skipped`` (``skip_bad``) a dropout of its
    IMU described there. ``names``: the angles' columns as the file writes them (roll,
    pitch of each IMU), for the messages."""
    z = np.radians(values) if degrees else np.array(values, dtype=float)
    for i in range(n_imus):
        columns = (names[2 * i], names[2 * i + 1])
        _check_angle_units(name, z[:, 2 * i : 2 * i + 2], lines, degrees, skipped, columns)
    return z


class DropoutWarning(UserWarning):
    """An IMU of several that gave no valid reading in a whole recording, or a recording
    none of whose samples gave an estimate."""


@dataclass
class ReadingCounts:
    """Which IMUs reported, over the samples read: ``missing[i]`` samples without a
    valid reading of IMU ``i + 1`` (a NaN in its block), ``partial`` samples with some
    IMUs missing and at least one reporting: estimated from those (their status is the
    update's, e.g. ``ok``; ``dropout`` is a sample without any reading)."""

    blocks: tuple[slice, ...]
    samples: int = 0
    partial: int = 0
    missing: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.missing = self.missing or [0] * len(self.blocks)

    def add(self, z: FloatArray) -> None:
        """Count the samples ``z`` (n, nz)."""
        finite = np.isfinite(np.asarray(z, dtype=float).reshape(-1, self.blocks[-1].stop))
        gone = np.column_stack([~finite[:, b].all(axis=1) for b in self.blocks])
        self.samples += len(gone)
        self.partial += int((gone.any(axis=1) & ~gone.all(axis=1)).sum())
        self.missing = [m + int(g) for m, g in zip(self.missing, gone.sum(axis=0))]

    def summary(self) -> str:
        """One clause for a run's summary line (``""`` when every sample had every IMU
        or none)."""
        if not self.partial:
            return ""
        per = ", ".join(
            f"IMU {i} in {m} sample{'s' * (m != 1)}"
            for i, m in enumerate(self.missing, start=1)
            if m
        )
        return f"{self.partial} sample(s) estimated without every IMU (missing: {per})"

    def warn_silent(self, name: str) -> None:
        """Warn once when some, not all, IMUs never reported (all: no estimate at all,
        said as an error by ``estimate``)."""
        silent = [i for i, m in enumerate(self.missing, start=1) if m == self.samples]
        if self.samples and silent and len(silent) < len(self.blocks):
            others = [i for i in range(1, len(self.blocks) + 1) if i not in silent]
            warnings.warn(
                f"{name}: IMU {', '.join(map(str, silent))} never reported (no valid reading in "
                f"{self.samples} samples): estimated from IMU {', '.join(map(str, others))} "
                "only; check its wiring or the file's columns",
                DropoutWarning,
                stacklevel=3,
            )


#: ``t`` read in seconds whose median step exceeds this looks like milliseconds.
MS_LIKE_STEP_S = 2.0
#: Times whose median step is below this (s: over 10 kHz, faster than any IMU stream
#: read here) are in a unit too small (microseconds stamped as nanoseconds).
TOO_FAST_STEP_S = 1e-4
#: ... unless their mean step is this many times longer: most steps tiny and a usual rate
#: on average are samples stamped in bursts (:func:`check_time_steps`).
BURST_MEAN_STEPS = 10


def check_time_steps(name: str, what: str, t: FloatArray, slow_fix: str, fast_fix: str) -> None:
    """Warn once (:class:`TimeStepWarning`) when times ``t`` (s, increasing) step like another
    unit: a median step over :data:`MS_LIKE_STEP_S` (milliseconds read as seconds) or
    under :data:`TOO_FAST_STEP_S`; ``name: what by a median of ... s per sample; fix``;
    or, a median step under :data:`TOO_FAST_STEP_S` but a mean step :data:`BURST_MEAN_STEPS`
    times over it, that the samples come stamped in bursts (not a unit to fix)."""
    if len(t) < 3:
        return
    step = float(np.median(np.diff(t)))
    mean = float(t[-1] - t[0]) / (len(t) - 1)
    if step > MS_LIKE_STEP_S:
        rate, fix = "", slow_fix
    elif 0 <= step < TOO_FAST_STEP_S and mean >= BURST_MEAN_STEPS * TOO_FAST_STEP_S:
        # most steps tiny, a usual rate on average: samples stamped in bursts
        warnings.warn(
            f"{name}: {what} by a median of {step:g} s per sample but {mean:g} s on "
            "average: the samples come stamped in bursts (a driver that stamps a batch of "
            "readings when it arrives?), and each is estimated at the time it is given: "
            "stamp each reading when it is taken",
            TimeStepWarning,
            stacklevel=3,
        )
        return
    elif 0 < step < TOO_FAST_STEP_S:
        rate, fix = f" ({1 / step:.3g} samples per second)", fast_fix
    else:
        return
    warnings.warn(
        f"{name}: {what} by a median of {step:g} s per sample{rate}; {fix}",
        TimeStepWarning,
        stacklevel=3,
    )


class TimeStepWatch:
    """The first few sample times of a stream handed over one sample or one block at a
    time (an estimator's ``step`` and ``continue_run``), checked as
    :func:`check_time_steps` checks a whole recording once it holds
    :data:`WATCHED_STEPS` steps: :meth:`see` returns the warning's text once, then
    None until :meth:`reset`."""

    #: steps seen before the median step is judged
    WATCHED_STEPS = 3

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the times seen: the next sample starts a new stream."""
        self._times: list[float] = []
        self.done = False
        #: the median of the first :data:`WATCHED_STEPS` steps, s, once judged (else None)
        self.step: float | None = None

    def see(self, t: FloatArray, what: str) -> str | None:
        """Take the sample times ``t`` (s; those not after the last one seen, handed over
        again, are left out); the text of a warning (``what: t advances by a median of
        ... s per sample ...``) the first time the first :data:`WATCHED_STEPS` steps look
        like milliseconds, else None."""
        for v in t:
            if self.done or len(self._times) > self.WATCHED_STEPS:
                break
            if not self._times or float(v) > self._times[-1]:
                self._times.append(float(v))
        if self.done or len(self._times) <= self.WATCHED_STEPS:
            return None
        self.done = True
        self.step = step = float(np.median(np.diff(self._times)))
        if step <= MS_LIKE_STEP_S:
            return None
        return (
            f"{what}: t advances by a median of {step:g} s per sample over the first "
            "samples: t must be in seconds (milliseconds? every step longer than the gap "
            "reset restarts the estimate)"
        )


def check_time_units(rows: TextRows, t: FloatArray) -> None:
    """Warn once when a ``t`` column in seconds, or a ``t_ms`` column in milliseconds,
    steps like another unit (:func:`check_time_steps`), naming the likely cause and the
    fix."""
    if rows.time_scale == 1e-3:  # t_ms: t (s) is t_ms / 1000
        check_time_steps(
            rows.name, "t_ms advances", t,
            "t_ms must be in milliseconds: microseconds? give milliseconds",
            "t_ms must be in milliseconds: seconds? name the column t",
        )  # fmt: skip
        return
    if rows.time_scale != 1.0:
        return
    check_time_steps(
        rows.name, "t advances", t,
        "t is read in seconds: if it is in milliseconds, name the column t_ms; if in "
        "microseconds or nanoseconds, give seconds",
        "t must be in seconds",
    )  # fmt: skip


class UnitWarning(UserWarning):
    """A value whose unit looks wrong (milliseconds for seconds, mm for m...)."""


class TimeStepWarning(UnitWarning):
    """Sample times whose steps look like another unit's, or stamped in bursts
    (:func:`check_time_steps`)."""


#: The share of a block's rows whose angles are beyond the radian range above which the
#: file is taken to be in degrees (fewer such rows are glitches).
DEGREES_LIKE_SHARE = 0.1
#: ... and with ``--skip-bad`` (whose rows out of range are dropouts) so many rows of a
#: block at least, or half of a short block's, make it the file's unit, refused.
SKIP_BAD_UNIT_ROWS = 5


#: With ``degrees``, a recording whose every roll and pitch is within this (in the
#: file's numbers) over at least :data:`RADIANS_LIKE_ROWS` rows reads like radians: in
#: degrees no IMU would tilt more than about 3 degrees in the whole recording.
RADIANS_LIKE_MAX = math.pi
RADIANS_LIKE_ROWS = 10


@dataclass
class DegreesCheck:
    """Whether tilt angles read with ``degrees`` look like radians: the largest
    magnitude of the file's numbers and the rows with a full reading, over the blocks
    read (:meth:`add`); :meth:`warn` at the end."""

    largest: float = 0.0
    rows: int = 0

    def add(self, values: FloatArray) -> None:
        """Count the file's angle values (n, 2 n_imus), as written (degrees)."""
        v = np.asarray(values, dtype=float)
        full = np.isfinite(v).all(axis=1)
        if full.any():
            self.largest = max(self.largest, float(np.abs(v[full]).max()))
            self.rows += int(full.sum())

    def radians_like(self) -> bool:
        """Whether the angles counted so far look like radians (over enough rows)."""
        return self.rows >= RADIANS_LIKE_ROWS and self.largest <= RADIANS_LIKE_MAX

    def mounting_hint(self) -> str | None:
        """What a refusal of the robot's mounting adds where the angles counted so far
        look like radians: radians read as degrees look like an upright robot."""
        if not self.radians_like():
            return None
        return (
            f"or are the angles radians? every roll and pitch of its first {self.rows} rows "
            f"is within {self.largest:.3g}: leave out --degrees (degrees=False in Python)"
        )

    def warn(self, path: str) -> None:
        """A :class:`UnitWarning` naming ``path`` where the angles look like radians."""
        if self.radians_like():
            warnings.warn(
                f"{path}: read in degrees (--degrees; degrees=True in Python), but every "
                f"roll and pitch of its {self.rows} rows is within {self.largest:.3g}: "
                f"radians? in degrees no IMU tilts more than {self.largest:.3g} degrees in "
                "the whole recording; without --degrees the angles are read as radians",
                UnitWarning,
                stacklevel=3,
            )


def _check_angle_units(
    path: str,
    z: FloatArray,
    lines: Sequence[int],
    degrees: bool,
    skipped: list[str] | None,
    columns: tuple[str, str],
) -> None:
    """Refuse angles (n, 2) beyond their range in one line naming the first; with
    ``skipped`` (``skip_bad``) such a row's angles become a dropout (NaN, in place) and
    its description is appended there instead, unless so many rows are (a share of
    :data:`DEGREES_LIKE_SHARE` at least) that the file's unit or columns are wrong
    (degrees, roll and pitch swapped): refused with ``skip_bad`` too. ``columns``: the
    angles' column names."""
    with np.errstate(invalid="ignore"):
        over = (np.abs(z[:, 0]) > ROLL_LIMIT) | (np.abs(z[:, 1]) > PITCH_LIMIT)
    if not over.any():
        return
    unit = "deg" if degrees else "rad"
    roll_name, pitch_name = columns
    valid = int(np.isfinite(z).all(axis=1).sum())
    many = over.sum() >= DEGREES_LIKE_SHARE * max(valid, 1)  # not a few glitches
    # with skip_bad, the file's unit or columns are refused where several rows, or half
    # of a short block's, are out (a file read in blocks: one glitch in a last block
    # of a few rows is a glitch)
    wrong_unit = many and (over.sum() >= SKIP_BAD_UNIT_ROWS or over.sum() >= 0.5 * max(valid, 1))
    if skipped is not None and not wrong_unit:
        for row in np.flatnonzero(over).tolist():
            shown = np.degrees(z[row]) if degrees else z[row]
            skipped.append(
                f"line {lines[row]}: {roll_name}={shown[0]:.4g}, {pitch_name}={shown[1]:.4g} "
                f"{unit} out of range"
            )
            z[row] = np.nan
        return
    i = int(np.argmax(over))
    roll, pitch = z[i]
    where = f"{path}: line {lines[i]}: {roll_name}={roll:.4g}, {pitch_name}={pitch:.4g}"
    if degrees or max(abs(roll), abs(pitch)) > 360:
        shown = np.degrees(z[i]) if degrees else z[i]
        where = f"{path}: line {lines[i]}: {roll_name}={shown[0]:.4g}, {pitch_name}={shown[1]:.4g}"
        raise InputError(f"{where} is out of range even in degrees (|roll| <= 180, |pitch| <= 90)")
    roll_most, pitch_most = (float(np.nanmax(np.abs(z[:, k]), initial=0.0)) for k in (0, 1))
    if many and roll_most <= PITCH_LIMIT < pitch_most <= ROLL_LIMIT:
        # a pitch column with a roll's range beside a roll column with a pitch's
        hint = (
            f"the columns {roll_name} and {pitch_name} look swapped: {pitch_name} reaches "
            f"{pitch_most:.3g} rad, beyond pi/2, while {roll_name} stays within pi/2 (swap "
            "their names in the header); if the angles are degrees, pass --degrees "
            "(degrees=True in Python)"
        )
    elif many:
        hint = "the angles look like degrees: pass --degrees (degrees=True in Python)"
    else:
        hint = (
            f"{int(over.sum())} of {valid} rows read here are; if they are glitches, "
            "--skip-bad reads them as dropouts (skip_bad=True in Python)"
        )
    raise InputError(f"{where} rad is out of range (|roll| <= pi, |pitch| <= pi/2); {hint}")
