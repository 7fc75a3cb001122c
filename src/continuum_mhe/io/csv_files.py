"""CSV files: measurements in, estimates and truth out.

Formats (docs/formats.md):

* Measurement CSV: a header with at least ``t,roll,pitch`` (one IMU) or
  ``t,roll_1,pitch_1,roll_2,pitch_2,...`` (IMUs numbered from the base in the robot
  file's order); ``t`` in seconds, strictly increasing; angles in radians
  (``degrees=True`` for degrees), in the convention of :mod:`continuum_mhe.model.imu`.
  Other columns are ignored. With several IMUs an empty field is a dropout of that IMU.
* Estimate CSV: ``t``, the formulation's outputs (one section: ``x,y,z,theta,phi``;
  several: ``x,y,z`` then ``theta_k,phi_k,x_k,y_k,z_k`` per section), then
  ``std_c`` for every output ``c`` (one standard deviation, same unit; empty where
  unknown), then ``status,solve_ms`` (m, rad, ms); rows without an estimate leave the
  outputs empty. Files without the ``std_`` columns are read too. A robust MHE's file
  has a column ``outlier`` (1: the sample's measurement was down-weighted, else 0)
  just before ``status``.
  Truth CSV: ``t,x,y,z`` and any of the per-section columns.

Every problem in an input file raises :class:`InputError` with a one-line message
naming the file and line. Outputs are written atomically (:mod:`.output_files`).
"""

from __future__ import annotations

import csv
import difflib
import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, UserError, expect_type, is_integer, time_text
from continuum_mhe.io.output_files import atomic_writer
from continuum_mhe.io.text_rows import (
    MEASUREMENT_HEADER_HINT,
    RowProblems,
    TextRows,
    column_indices,
    has_extra_fields,
    iter_samples,
    open_rows,
    parse_float,
)
from continuum_mhe.model.descriptions import (
    TIP_COLUMNS,
    OutputSpec,
    output_names,
    pcc_outputs,
    tilt_blocks,
)
from continuum_mhe.model.imu import PITCH_LIMIT, ROLL_LIMIT
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import STATUS_MEANINGS, EstimateSeries

#: One section's state columns (the paper's robot); several sections: see
#: :func:`~continuum_mhe.model.descriptions.pcc_outputs`.
STATE_COLUMNS = ("t", *output_names(pcc_outputs(1)))
MEASUREMENT_COLUMNS = ("t", "roll", "pitch")


#: Prefix of the standard-deviation column of an output (``std_x``, ``std_theta_2``).
STD_PREFIX = "std_"


def std_columns(outputs: Sequence[OutputSpec]) -> tuple[str, ...]:
    """``std_c`` for every output ``c``."""
    return tuple(STD_PREFIX + n for n in output_names(outputs))


def estimate_columns(outputs: Sequence[OutputSpec], outlier: bool = False) -> tuple[str, ...]:
    """Header of an estimate CSV: ``t``, the outputs, their ``std_`` columns, ``outlier``
    (with ``outlier``: a robust MHE's flags), ``status``, ``solve_ms``."""
    flags = ("outlier",) if outlier else ()
    return ("t", *output_names(outputs), *std_columns(outputs), *flags, "status", "solve_ms")


ESTIMATE_COLUMNS = estimate_columns(pcc_outputs(1))


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


def _read_rows(path: str | os.PathLike[str]) -> tuple[TextRows, list[tuple[int, list[str]]]]:
    """The opened table and all its ``(line_number, fields)`` rows (a small file)."""
    with open_rows(path) as rows:
        return rows, list(rows.rows)


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
    """All validated rows of a sample table (see :func:`~continuum_mhe.io.text_rows.
    iter_samples`); every skipped row is listed in ``skipped``."""
    problems = RowProblems(keep=sys.maxsize)
    lines: list[int] = []
    t: list[float] = []
    values: list[list[float]] = []
    for line, tv, vals in iter_samples(
        rows, columns, skip_bad=skip_bad, empty_is_dropout=empty_is_dropout, problems=problems
    ):
        lines.append(line)
        t.append(tv)
        values.append(vals)
    arr = np.array(values, dtype=float).reshape(len(t), len(columns) - 1)
    return SampleRows(np.array(t, dtype=float), arr, lines, problems.first)


def tilt_columns(n_imus: int) -> tuple[str, ...]:
    """``roll, pitch`` for one IMU; ``roll_1, pitch_1, roll_2, ...`` for several."""
    if n_imus == 1:
        return ("roll", "pitch")
    return tuple(f"{c}_{i}" for i in range(1, n_imus + 1) for c in ("roll", "pitch"))


#: The fix named when a file's IMU count is not the robot's (``{found}``: the file's).
ROBOT_FIX = "pass --robot FILE with a robot file of {found} IMU(s)"
#: The same for :func:`read_measurements`, called from Python and from ``calibrate``.
READER_FIX = "pass the robot of {found} IMU(s) (--robot FILE; n_imus={found} in Python)"
#: Added to a fix naming ``--robot`` when the file has one IMU.
ONE_IMU_FIX = ", or leave --robot out: one section with its IMU at the tip needs no robot file"


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
        rows.name, got.values, got.lines, degrees, n_imus, got.skipped if skip_bad else None
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
    skipped: list[str] | None = None,
) -> FloatArray:
    """Measurements (n, 2 n_imus) in rad from the file's values, range-checked: an angle
    out of range is a one-line error, or with ``skipped`` (``skip_bad``) a dropout of its
    IMU described there."""
    z = np.radians(values) if degrees else np.array(values, dtype=float)
    for i in range(n_imus):
        _check_angle_units(name, z[:, 2 * i : 2 * i + 2], lines, degrees, skipped)
    return z


class DropoutWarning(UserWarning):
    """An IMU of several that gave no valid reading in a whole recording."""


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
        per = ", ".join(f"IMU {i} on {m}" for i, m in enumerate(self.missing, start=1) if m)
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


def check_time_steps(name: str, what: str, t: FloatArray, slow_fix: str, fast_fix: str) -> None:
    """Warn once (:class:`UnitWarning`) when times ``t`` (s, increasing) step like another
    unit: a median step over :data:`MS_LIKE_STEP_S` (milliseconds read as seconds) or
    under :data:`TOO_FAST_STEP_S`; ``name: what by a median of ... s per sample; fix``."""
    if len(t) < 3:
        return
    step = float(np.median(np.diff(t)))
    if step > MS_LIKE_STEP_S:
        rate, fix = "", slow_fix
    elif 0 < step < TOO_FAST_STEP_S:
        rate, fix = f" ({1 / step:.3g} samples per second)", fast_fix
    else:
        return
    warnings.warn(
        f"{name}: {what} by a median of {step:g} s per sample{rate}; {fix}",
        UnitWarning,
        stacklevel=3,
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
        "microseconds, give seconds",
        "t must be in seconds",
    )  # fmt: skip


class UnitWarning(UserWarning):
    """A value whose unit looks wrong (milliseconds for seconds, mm for m...)."""


def numbered_imus(rows: TextRows, fields: Sequence[str]) -> int:
    """The highest IMU number ``k`` of a ``<field>_k`` column in the header (0: none).
    IMUs are numbered from 1, as in the robot file: a ``<field>_0`` column is a one-line
    error saying so (never read as another IMU count)."""
    numbers = {
        h: int(number)
        for h in rows.header
        for base, _, number in [h.rpartition("_")]
        if base in fields and number.isdigit()
    }
    zero = [h for h, k in numbers.items() if k == 0]
    if zero:
        first = "_1, ".join(fields[:2]) + "_1"
        raise InputError(
            f"{rows.name}: line 1: column {rows.as_written(zero[0])}: IMU columns are numbered "
            f"from 1 ({first} ... for the robot file's first IMU); renumber the file's columns"
        )
    return max(numbers.values(), default=0)


def numbered_span(first: str, found: int, shown: Callable[[str], str] = str) -> str:
    """``roll_1 ... roll_3`` (``roll_1`` for one IMU), each name as ``shown`` gives it
    (:meth:`~continuum_mhe.io.text_rows.TextRows.as_written`: as the file writes it)."""
    span = shown(f"{first}_1")
    return span + (f" ... {shown(f'{first}_{found}')}" if found > 1 else "")


def imu_count_error(
    name: str, kind: str, columns: str, found: int, n_imus: int, fix: str = ROBOT_FIX
) -> InputError:
    """The one-line error of a file whose ``kind`` columns (``columns``, as shown) are
    for ``found`` IMUs when the robot has ``n_imus``; ``fix`` ends it (for one IMU with
    :data:`ONE_IMU_FIX` where it names ``--robot``)."""
    more = ONE_IMU_FIX if found == 1 and "--robot" in fix else ""
    if found > n_imus and "--robot" in fix:  # a robot of some of the recording's IMUs
        more += (
            "; a robot file of fewer of them takes the file cut to their columns, "
            "numbered from 1 in its order"
        )
    return InputError(
        f"{name}: line 1: the file has {kind} columns for {found} IMU(s) ({columns}) "
        f"but the robot describes {n_imus}; {fix.format(found=found)}{more}"
    )


#: An unknown header column at least this similar to a column missing from an IMU's set
#: (difflib's ratio) is named as a likely typo of it: ``ay2`` or ``ay_`` for ``ay_2`` or
#: ``ay``, ``roll_4`` or ``roll_0`` for ``roll_3`` or ``roll_1``, ``rol`` for ``roll``.
TYPO_SIMILARITY = 0.75


@dataclass(frozen=True)
class ImuColumns:
    """One IMU's columns in a sample file's header: ``fields`` (every IMU has them) and
    ``optional`` ones (a gyro's: an IMU has all or none of them), named ``<field>`` for
    the one IMU of an unnumbered file and ``<field>_k`` for IMU ``k``. ``kind`` names
    them in messages (``"raw"``); ``holds`` (``{k}``: ``""`` or ``"_k"``) says what a
    set holds where a missing column has no look-alike in the header, or is None for
    :func:`~continuum_mhe.io.text_rows.column_indices`' message (with the header)."""

    kind: str
    fields: tuple[str, ...]
    optional: tuple[str, ...] = ()
    holds: str | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return (*self.fields, *self.optional)

    def number(self, column: str) -> tuple[str, int]:
        """``("ax", 2)`` for the numbered column ``ax_2``; ``("", -1)`` for any other."""
        base, _, number = column.rpartition("_")
        return (base, int(number)) if base in self.names and number.isdigit() else ("", -1)

    def numbered(self, header: Sequence[str]) -> dict[int, set[str]]:
        """The fields of each numbered IMU in the header (``ax_2`` -> ``{2: {"ax"}}``)."""
        numbers: dict[int, set[str]] = {}
        for base, k in map(self.number, header):
            if base:
                numbers.setdefault(k, set()).add(base)
        return numbers

    def whole(self, fields: set[str]) -> bool:
        """An IMU's fields are a whole set: all ``fields``, with all or none of
        ``optional``."""
        optional = fields & set(self.optional)
        return set(self.fields) <= fields and optional in (set(), set(self.optional))

    def missing(
        self, header: Sequence[str], suffixes: Sequence[str]
    ) -> tuple[dict[str, list[str]], list[str]]:
        """The columns missing from each IMU's set (``suffixes``: ``""`` for the one IMU
        of an unnumbered file, ``"_k"`` for IMU ``k``), and the header's unknown columns
        that look like typos of them (:data:`TYPO_SIMILARITY`). An IMU's set is its
        ``fields``, and its ``optional`` ones where the header has one of them or a
        look-alike. A column of another IMU's whole set is never taken for a typo."""
        whole = [k for k, fields in self.numbered(header).items() if self.whole(fields)]
        known = {c + s for s in [*suffixes, *(f"_{k}" for k in whole)] for c in self.names}
        unknown = [h for h in header if h not in known]
        most = max(len(unknown), 1)
        missing: dict[str, list[str]] = {}
        typos: list[str] = []
        for s in suffixes:
            near = {
                c + s: difflib.get_close_matches(c + s, unknown, most, TYPO_SIMILARITY)
                for c in self.names
                if c + s not in header
            }
            optional = [c + s for c in self.optional]
            wanted = [c + s for c in self.fields]
            if any(o in header or near.get(o) for o in optional):
                wanted += optional
            gone = [c for c in wanted if c not in header]
            if gone:
                missing[s] = gone
            typos += [u for c in gone for u in near[c] if u not in typos]
        return missing, typos

    def missing_error(
        self, rows: TextRows, missing: dict[str, list[str]], typos: Sequence[str]
    ) -> InputError:
        """``line 1: IMU 2 has no ay_2 column; the header has ay2 (a typo?)`` for
        :meth:`missing`' result; without look-alikes, what a set holds (:attr:`holds`)."""
        if not typos and self.holds is None:
            try:
                column_indices(rows, [c for gone in missing.values() for c in gone])
            except InputError as error:
                return error
        said: list[str] = []
        for s, gone in missing.items():
            who = f"IMU {s[1:]}" if s else "the IMU"
            cols = f"{', '.join(gone)} column{'s' if len(gone) > 1 else ''}"
            said.append(f"{who} has no {cols}" if not said else f"{who} no {cols}")
        if typos:
            guess = "a typo" if len(typos) == 1 else "typos"
            what = f"the header has {', '.join(map(rows.as_written, typos))} ({guess}?)"
            return InputError(f"{rows.name}: line 1: {', '.join(said)}; {what}")
        k = "" if "" in missing else "_k"  # "": the one IMU of an unnumbered file
        holds = str(self.holds).format(k=k)
        return InputError(f"{rows.name}: line 1: {', '.join(said)} ({holds})")


#: The tilt columns of an IMU: ``roll, pitch`` (``roll_k, pitch_k`` for IMU ``k``).
TILT_IMU_COLUMNS = ImuColumns("tilt", ("roll", "pitch"))


def imu_suffixes(
    rows: TextRows, n_imus: int, columns: ImuColumns, fix: str = ROBOT_FIX
) -> list[str]:
    """The suffix of each of ``n_imus`` IMUs' columns in the header: ``[""]`` for one
    IMU's unnumbered columns, else ``["_1", ..., "_n"]``.

    A header with a column missing from an IMU's set is a one-line error naming it and
    the columns that look like a typo of it (:meth:`ImuColumns.missing`); one whose
    columns are whole sets for another number of IMUs, an error naming both counts
    (:func:`imu_count_error`, ending in ``fix``); ``<field>_0`` columns, an error saying
    IMUs are numbered from 1 (:func:`numbered_imus`)."""
    header = rows.header
    if all(f"{c}_0" in header for c in columns.fields):
        numbered_imus(rows, columns.names)  # raises: IMUs are numbered from 1
    sets = columns.numbered(header)
    numbers = [k for k in sets if k > 0]
    plain = any(c in header for c in columns.names)  # unnumbered columns
    unnumbered = not numbers or (
        n_imus == 1 and plain and not any(columns.whole(f) for k, f in sets.items() if k > 0)
    )
    found = 1 if unnumbered else max(numbers)

    def suffixes(count: int) -> list[str]:
        return [""] if unnumbered else [f"_{k}" for k in range(1, count + 1)]

    missing, typos = columns.missing(header, suffixes(n_imus))
    if found != n_imus and not typos:
        own = columns.missing(header, suffixes(found))  # the file's sets, for its count
        if not own[0]:
            shown = (
                ", ".join(map(rows.as_written, columns.fields))
                if unnumbered
                else numbered_span(columns.fields[0], found, rows.as_written)
            )
            raise imu_count_error(rows.name, columns.kind, shown, found, n_imus, fix)
        if not missing:  # whole sets for the robot, broken ones beyond its IMUs
            missing, typos = own
    whole = sorted(k for k, f in sets.items() if k > 0 and columns.whole(f))
    by_section = (  # whole sets, none broken, no typo: numbered otherwise than 1..n
        missing and not typos and len(whole) == n_imus == len(numbers)
        and whole != list(range(1, n_imus + 1))
    )  # fmt: skip
    if by_section:
        shown = ", ".join(rows.as_written(f"{columns.fields[0]}_{k}") for k in whole)
        first = columns.fields[0]
        want = f"1 to {n_imus}" if n_imus > 1 else f"1 ({first}_1..., or {first}... unnumbered)"
        raise InputError(
            f"{rows.name}: line 1: the header's IMU columns are numbered {shown}, but IMUs "
            f"are numbered in the robot file's [[imu]] order, not by section: name them {want}"
        )
    if missing:
        raise columns.missing_error(rows, missing, typos)
    numbered_imus(rows, columns.names)  # a stray roll_0 beside whole sets: numbered from 1
    return suffixes(n_imus)


#: The share of a block's rows whose angles are beyond the radian range above which the
#: file is taken to be in degrees (fewer such rows are glitches).
DEGREES_LIKE_SHARE = 0.1


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
    skipped: list[str] | None = None,
) -> None:
    """Refuse angles (n, 2) beyond their range in one line naming the first; with
    ``skipped`` (``skip_bad``) such a row's angles become a dropout (NaN, in place) and
    its description is appended there instead."""
    with np.errstate(invalid="ignore"):
        over = (np.abs(z[:, 0]) > ROLL_LIMIT) | (np.abs(z[:, 1]) > PITCH_LIMIT)
    if not over.any():
        return
    unit = "deg" if degrees else "rad"
    if skipped is not None:
        for row in np.flatnonzero(over).tolist():
            shown = np.degrees(z[row]) if degrees else z[row]
            skipped.append(
                f"line {lines[row]}: roll={shown[0]:.4g}, pitch={shown[1]:.4g} {unit} out of range"
            )
            z[row] = np.nan
        return
    i = int(np.argmax(over))
    roll, pitch = z[i]
    where = f"{path}: line {lines[i]}: roll={roll:.4g}, pitch={pitch:.4g}"
    if degrees or max(abs(roll), abs(pitch)) > 360:
        shown = np.degrees(z[i]) if degrees else z[i]
        where = f"{path}: line {lines[i]}: roll={shown[0]:.4g}, pitch={shown[1]:.4g}"
        raise InputError(f"{where} is out of range even in degrees (|roll| <= 180, |pitch| <= 90)")
    valid = int(np.isfinite(z).all(axis=1).sum())
    if over.sum() >= DEGREES_LIKE_SHARE * max(valid, 1):
        hint = "the angles look like degrees: pass --degrees (degrees=True in Python)"
    else:
        hint = (
            f"{int(over.sum())} of {valid} rows read here are; if they are glitches, "
            "--skip-bad reads them as dropouts (skip_bad=True in Python)"
        )
    raise InputError(f"{where} rad is out of range (|roll| <= pi, |pitch| <= pi/2); {hint}")


@dataclass(frozen=True)
class StateTable:
    """An estimate or truth CSV: ``t`` (n,), ``values`` (n, k) with NaN where empty,
    ``names`` (k,) the columns (outputs such as ``x``, ``theta_2``), ``status`` (n,)
    (``"ok"`` where the file has no status column), ``std`` (n, k) the ``std_``
    columns of the outputs (NaN where empty or absent), and ``outlier`` (n,) bool where
    the file has an ``outlier`` column (else None)."""

    t: FloatArray
    names: tuple[str, ...]
    values: FloatArray
    status: NDArray[np.str_]
    std: FloatArray | None = None
    outlier: NDArray[np.bool_] | None = None
    #: the file has ``std_`` columns (perhaps all empty)
    std_columns: bool = False
    #: the file has a ``status`` column (an estimate's)
    status_column: bool = False

    @property
    def has_std(self) -> bool:
        """The file has a finite standard deviation somewhere."""
        return self.std is not None and bool(np.isfinite(self.std).any())

    def column(self, name: str) -> FloatArray:
        return self.values[:, self.names.index(name)]


_NOT_STATES = {"t", "status", "solve_ms", "outlier"}


#: the suffix of a truth column kept beside the measurements of a recording
TRUE_SUFFIX = "_true"


def truth_named(header: list[str], required: Sequence[str]) -> list[str]:
    """``header`` with each ``NAME_true`` column renamed ``NAME`` when the ``required``
    columns are absent and their ``_true`` columns present (a recording with its truth
    beside the measurements); else ``header`` itself."""
    if all(c in header for c in required) or not all(c + TRUE_SUFFIX in header for c in required):
        return header
    return [h[: -len(TRUE_SUFFIX)] if h.endswith(TRUE_SUFFIX) else h for h in header]


#: The largest magnitude of a value in an estimate or truth file (m, rad, N): none of a
#: robot's; beyond it errors and their squares lose meaning or overflow. (A standard
#: deviation may be larger: an estimate that says it knows nothing.)
STATE_LIMIT = 1e9


def read_state_table(
    path: str | os.PathLike[str], required: Sequence[str] = TIP_COLUMNS
) -> StateTable:
    """Read an estimate or truth CSV with at least ``t`` and ``required`` columns; every
    other numeric output column (``theta``, ``phi_2``, ``std_x``...) is kept. A
    recording that carries its truth beside the measurements (``x_true, y_true, z_true``,
    as the shipped ``rod_planar.csv``) is read as that truth: each ``NAME_true`` column
    is the output ``NAME``."""
    table, body = _read_rows(path)
    table.header = truth_named(table.header, required)
    p, header = table.name, table.header
    column_indices(table, ("t", *required))
    names = tuple(h for h in header if h not in _NOT_STATES and h and not h.startswith(STD_PREFIX))
    idx = [header.index(c) for c in names]
    sd_idx = [header.index(STD_PREFIX + c) if STD_PREFIX + c in header else -1 for c in names]
    sd: list[list[float]] = []
    t_idx = header.index("t")
    if not body:
        raise InputError(f"{p}: line 2: no data rows after the header")
    s_idx = header.index("status") if "status" in header else None
    o_idx = header.index("outlier") if "outlier" in header else None
    flags: list[bool] = []
    t: list[float] = []
    out: list[list[float]] = []
    status: list[str] = []
    lines: list[int] = []
    for line, row in body:
        if len(row) < len(header):
            raise InputError(
                f"{p}: line {line}: expected {len(header)} fields, found {len(row)} (truncated?)"
            )
        if has_extra_fields(row, len(header)):
            raise InputError(
                f"{p}: line {line}: expected {len(header)} fields, found {len(row)} (an extra "
                "field or separator?)"
            )
        st = row[s_idx] if s_idx is not None else "ok"
        if st not in STATUS_MEANINGS:
            known = ", ".join(STATUS_MEANINGS)
            raise InputError(f"{p}: line {line}: status {st!r} is not one of {known}")
        tv = parse_float(p, line, table.as_written("t"), row[t_idx]) * table.time_scale
        vals = [
            math.nan
            if (row[j] == "" and st == "no-estimate")
            else parse_float(p, line, table.as_written(c), row[j])
            for c, j in zip(names, idx)
        ]
        if st != "no-estimate" and not all(map(math.isfinite, [tv, *vals])):
            raise InputError(f"{p}: line {line}: NaN or infinite value")
        sd.append(
            [
                math.nan if j < 0 or row[j] == "" else _parse_std(p, line, c, row[j])
                for c, j in zip(names, sd_idx)
            ]
        )
        if t and tv <= t[-1]:
            raise InputError(
                f"{p}: line {line}: t={time_text(tv)} does not increase (previous "
                f"t={time_text(t[-1])})"
            )
        if o_idx is not None:
            if row[o_idx] not in ("0", "1"):
                raise InputError(f"{p}: line {line}: outlier must be 0 or 1, got {row[o_idx]!r}")
            flags.append(row[o_idx] == "1")
        t.append(tv)
        out.append(vals)
        status.append(st)
        lines.append(line)
    values = np.array(out, dtype=float).reshape(len(t), len(names))
    beyond = np.argwhere(np.abs(values) > STATE_LIMIT)  # squares would overflow the metrics
    if len(beyond):
        i, j = beyond[0]
        raise InputError(
            f"{p}: line {lines[i]}: {names[j]}={values[i, j]:.6g} out of range (|value| <= "
            f"{STATE_LIMIT:g} in m, rad and N)"
        )
    return StateTable(
        np.array(t), names, values,
        np.array(status, dtype=str), np.array(sd, dtype=float).reshape(len(t), len(names)),
        None if o_idx is None else np.array(flags, dtype=bool), any(j >= 0 for j in sd_idx),
        s_idx is not None,
    )  # fmt: skip


#: The per-section columns of a state table: ``theta, phi`` (one section), or
#: ``theta_k, phi_k, x_k, y_k, z_k``.
SECTION_FIELDS = ("theta", "phi", "x", "y", "z")


def _is_section_column(name: str) -> bool:
    base, _, k = name.rpartition("_")
    return name in ("theta", "phi") or (base in SECTION_FIELDS and k.isdigit())


def robot_misfit(names: Sequence[str], robot: Robot, complete: bool) -> str:
    """``""`` when a state table's per-section columns fit ``robot``'s outputs, else
    what does not (``missing theta_3; extra theta``). ``complete``: every output must be
    there (an estimate, as ``estimate`` writes it); else any subset (a truth). A tendon
    robot's (a ``[backbone]``) are its mechanics model's (``theta_k`` even for one
    section, and each section's twist ``psi_k``)."""
    outputs = output_names(pcc_outputs(robot.n_sections))
    if robot.backbone is not None:
        from continuum_mhe.model.tendon import tendon_outputs  # its CasADi statics: on use

        outputs = output_names(tendon_outputs(robot.n_sections))
    extra = [n for n in names if _is_section_column(n) and n not in outputs]
    missing = [n for n in outputs if n not in names] if complete else []
    if not (extra or missing):
        return ""
    parts = [
        f"{what} {', '.join([n for n in cols if n.startswith('theta')] or cols)}"
        for what, cols in (("missing", missing), ("extra", extra))
        if cols
    ]  # a section named by its theta column, where there is one
    has = [n for n in names if n.startswith("theta")]
    return (
        f"its columns ({', '.join(has) or 'no theta'}) do not fit the robot "
        f"({robot.describe()}): {'; '.join(parts)}"
    )


def check_estimate_fits(path: str | os.PathLike[str], names: Sequence[str], robot: Robot) -> None:
    """A one-line :class:`InputError` unless an estimate CSV's columns are ``robot``'s
    outputs (estimated on another robot, or ``--robot`` forgotten)."""
    misfit = robot_misfit(names, robot, complete=True)
    if misfit:
        raise InputError(f"{path}: {misfit}; pass --robot with the robot it was estimated on")


def check_same_robot(
    estimates: str | os.PathLike[str], estimate: StateTable,
    truth: str | os.PathLike[str], truth_table: StateTable, robot: Robot,
) -> str:  # fmt: skip
    """``evaluate``'s check that the estimate and the truth are of ``robot``: an estimate
    with section columns of another robot is a one-line :class:`InputError` (one with the
    tip only passes); a truth with columns of another robot, or one whose section ``k``
    ends at its tip where the robot has more sections (:func:`tip_section`), gives the
    warning returned (``""`` when it fits: any other subset of the robot's columns
    does)."""
    if any(_is_section_column(n) for n in estimate.names):
        check_estimate_fits(estimates, estimate.names, robot)
    misfit = robot_misfit(truth_table.names, robot, complete=False)
    if not misfit:
        ends = tip_section(truth_table)
        if ends is None or ends >= robot.n_sections:
            return ""
        misfit = (
            f"section {ends}'s end is its tip in every row: a robot of {ends} section(s), "
            f"not {robot.n_sections}"
        )
    return f"{truth}: {misfit}: the truth is of another robot (pass --robot with its robot)"


#: The largest distance, m, between a section's end and the tip in every row of a file
#: for that section to be the file's last (rounding of the written digits only).
TIP_SECTION_TOLERANCE = 1e-6


def tip_section(table: StateTable) -> int | None:
    """The first section ``k`` (1-based) whose end (``x_k, y_k, z_k``) is the file's tip
    (``x, y, z``) in every row that has both, within :data:`TIP_SECTION_TOLERANCE`: the
    last section of the robot the file was made for; None where no section's is (or
    none is given). A truth of a robot of fewer sections fits a subset of another
    robot's columns, and this tells it apart."""
    names = list(table.names)
    if not all(c in names for c in ("x", "y", "z")):
        return None
    tip = table.values[:, [names.index(c) for c in ("x", "y", "z")]]
    given = sorted(
        int(n[2:]) for n in names if n.startswith("x_") and n[2:].isdigit() and int(n[2:]) > 0
    )  # a truth may have some sections' ends and not others'
    for k in given:
        if not all(f"{c}_{k}" in names for c in ("y", "z")):
            continue
        end = table.values[:, [names.index(f"{c}_{k}") for c in ("x", "y", "z")]]
        both = np.all(np.isfinite(tip), axis=1) & np.all(np.isfinite(end), axis=1)
        if both.any() and np.abs(end[both] - tip[both]).max() <= TIP_SECTION_TOLERANCE:
            return k
    return None


def misspelt_columns(names: Sequence[str], outputs: Sequence[str]) -> str:
    """``""``, or a line naming each column of ``names`` that is none of ``outputs`` but
    one letter off one of them that ``names`` lacks (``xx_2 for x_2``): a typo in a
    truth's header leaves that column out of the comparison."""
    lacking = [o for o in outputs if o not in names]
    pairs = []
    for n in names:
        if n in outputs:
            continue
        close = next((o for o in lacking if _edit_distance_one(n, o)), None)
        if close is not None:
            pairs.append(f"{n} for {close}")
    if not pairs:
        return ""
    return f"column(s) {', '.join(pairs)}? (a typo: such a column is left out)"


def _edit_distance_one(a: str, b: str) -> bool:
    """Whether ``a`` becomes ``b`` by one inserted, deleted or replaced character."""
    if abs(len(a) - len(b)) > 1:
        return False
    if len(a) == len(b):
        return sum(x != y for x, y in zip(a, b)) == 1
    short, long_ = (a, b) if len(a) < len(b) else (b, a)
    return any(long_[:i] + long_[i + 1 :] == short for i in range(len(long_)))


def _parse_std(path: str, line: int, name: str, text: str) -> float:
    v = parse_float(path, line, STD_PREFIX + name, text)
    if not (math.isfinite(v) and v >= 0):
        raise InputError(f"{path}: line {line}: {STD_PREFIX}{name} must be >= 0, got {text!r}")
    return v


def read_states(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """Read a one-section estimate or truth CSV: ``t`` (n,), states (n, 5)
    ``x, y, z, theta, phi`` with NaN where empty, and status (n,)."""
    cols = STATE_COLUMNS[1:]
    table = read_state_table(path, cols)
    values = np.column_stack([table.column(c) for c in cols])
    return table.t, values, table.status


def _fmt(v: float) -> str:
    return f"{v:.10g}"


def format_time(t: float) -> str:
    """An estimate row's time ``t`` (s) as written: ``"%.10g"`` where that keeps it to
    half a microsecond (below 1e4 s it always does) or ``|t| >= 1e15``, else six decimals
    without trailing zeros, so that samples a millisecond or less apart on a device clock
    past 1e6 s stay distinct (the compiled writer's rule, to the character)."""
    if not math.isfinite(t):
        raise UserError("refusing to write a non-finite time")
    short = f"{t:.10g}"
    if abs(float(short) - t) <= 5e-7 or abs(t) >= 1e15:
        return short
    return f"{t:.6f}".rstrip("0").rstrip(".")


def write_table(
    path: str | os.PathLike[str], columns: Sequence[str], rows: Sequence[Sequence[object]]
) -> None:
    """Write a CSV atomically; floats must be finite (refuses to write NaN)."""
    with atomic_writer(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow(format_cells(path, r))


def format_cells(path: str | os.PathLike[str], row: Sequence[object]) -> list[str]:
    """The CSV cells of one row: floats in 10 significant digits, which must be finite
    (a non-finite value is a bug: refused)."""
    cells = []
    for v in row:
        if isinstance(v, (float, np.floating)):
            if not math.isfinite(v):
                raise UserError(f"refusing to write a non-finite value to {path}")
            cells.append(_fmt(float(v)))
        else:
            cells.append(str(v))
    return cells


def estimate_row(
    t: float,
    output: Sequence[float] | FloatArray | None,
    status: str,
    solve_ms: float,
    ny: int,
    std: Sequence[float] | FloatArray | None = None,
    outlier: bool | None = None,
) -> list[object]:
    """One estimate CSV row; a row without an estimate leaves the outputs empty, and an
    unknown standard deviation is empty too. ``outlier`` (None: no such column) is
    written as 0 or 1 before the status."""
    flag = [] if outlier is None else [int(bool(outlier))]
    if status == "no-estimate" or output is None:
        return [format_time(t), *([""] * (2 * ny)), *flag, str(status), float(solve_ms)]
    sd: list[object] = [""] * ny
    if std is not None:
        sd = [float(v) if math.isfinite(v) else "" for v in std]
    return [format_time(t), *(float(v) for v in output), *sd, *flag, str(status), float(solve_ms)]


def estimate_lines(
    path: str | os.PathLike[str],
    t: FloatArray,
    output: FloatArray,
    output_std: FloatArray,
    outlier: NDArray[np.bool_] | None,
    status: Sequence[str],
    solve_ms: FloatArray,
) -> str:
    """The estimate CSV lines of several samples, as :func:`estimate_row` and
    :func:`format_cells` write each (``output``, ``output_std`` (n, ny) NaN where there
    is none; ``outlier`` None: no such column); a non-finite output of an estimate is
    refused (a bug). Written by the compiled core, each number as ``%.10g``."""
    status = list(status)  # str (or Status, a str): numpy's array of them calls __str__
    no_estimate = np.fromiter(map("no-estimate".__eq__, status), dtype=np.bool_, count=len(status))
    estimated = ~np.isnan(output).all(axis=1) & ~no_estimate
    if not (
        np.isfinite(t).all()
        and np.isfinite(solve_ms).all()
        and np.isfinite(output[estimated]).all()
    ):
        raise UserError(f"refusing to write a non-finite value to {path}")
    flags = None if outlier is None else np.ascontiguousarray(outlier, dtype=np.uint8)
    t, output, output_std, solve_ms = (
        np.ascontiguousarray(a, dtype=np.float64) for a in (t, output, output_std, solve_ms)
    )
    return _core.estimate_lines(
        t, output, output_std, estimated.view(np.uint8), flags, status, solve_ms
    )


def estimate_rows(series: EstimateSeries) -> list[list[object]]:
    """Rows of the estimate CSV; no-estimate rows leave the outputs empty."""
    ny = len(series.outputs)
    flags = [None] * len(series.t) if series.outlier is None else list(series.outlier)
    return [
        estimate_row(t, out, str(st), ms, ny, sd, fl)
        for t, out, st, ms, sd, fl in zip(
            series.t, series.output, series.status, series.solve_ms, series.std, flags
        )
    ]


def _samples_table(t: ArrayLike, values: ArrayLike, name: str) -> tuple[FloatArray, FloatArray]:
    """``t`` (n,) and ``values`` (n, m) as float arrays (lists too), or a UserError
    naming the shapes."""
    try:
        t_arr, v_arr = np.asarray(t, dtype=float), np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"t and {name} must be arrays of numbers") from None
    if t_arr.ndim != 1 or v_arr.ndim != 2:
        raise UserError(
            f"t must be (n,) and {name} (n, m); got shapes {t_arr.shape} and {v_arr.shape}"
        )
    return t_arr, v_arr


def write_estimates(path: str | os.PathLike[str], series: EstimateSeries) -> None:
    """Write an estimate CSV atomically (columns from ``series.outputs``; an ``outlier``
    column when the series carries outlier flags)."""
    if not isinstance(series, EstimateSeries):
        raise UserError(
            f"series must be an EstimateSeries (what run() returns), got a {type(series).__name__}"
        )
    t = np.asarray(series.t, dtype=float)
    if not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
        raise UserError(
            f"{path}: t must be finite and strictly increasing (s): the estimate files' "
            "readers refuse a file whose time does not increase"
        )
    unknown = sorted({str(v) for v in series.status} - set(STATUS_MEANINGS))
    if unknown:
        raise UserError(f"{path}: status {unknown[0]!r} is not one of {', '.join(STATUS_MEANINGS)}")
    columns = estimate_columns(series.outputs, outlier=series.outlier is not None)
    write_table(path, columns, estimate_rows(series))


def write_truth(
    path: str | os.PathLike[str],
    t: FloatArray,
    truth: FloatArray,
    outputs: Sequence[OutputSpec] = pcc_outputs(1),
) -> None:
    """Write a truth CSV ``t`` + the output columns atomically (``t`` as
    :func:`format_time` writes it: a device or Unix clock keeps its microseconds)."""
    t, truth = _samples_table(t, truth, "truth")
    if not np.isfinite(t).all():
        raise UserError(f"{path}: t must be finite (s)")
    if truth.shape[1] != len(outputs):
        raise UserError(f"truth has {truth.shape[1]} columns, expected {len(outputs)}")
    write_table(
        path,
        ("t", *output_names(outputs)),
        [[format_time(float(a)), *map(float, b)] for a, b in zip(t, truth)],
    )


def write_measurements(
    path: str | os.PathLike[str],
    t: FloatArray,
    z: FloatArray,
    names: Sequence[str] = ("roll", "pitch"),
) -> None:
    """Write a measurement CSV ``t`` + ``names`` (rad) atomically; NaN (a dropout of
    that sensor) is written as an empty field, ``t`` as :func:`format_time` writes it
    (a device or Unix clock keeps its microseconds)."""
    if isinstance(names, str):  # "rp" would be the columns r, p
        raise UserError(f"names must be a sequence of column names, got the string {names!r}")
    t, z = _samples_table(t, z, "z")
    if z.shape[1] != len(names):
        raise UserError(f"z has {z.shape[1]} columns, expected {len(names)}")
    if len(t) != len(z):
        raise UserError(f"t has {len(t)} samples and z {len(z)} rows: they must match")
    if len(t) == 0:
        raise UserError(f"{path}: no samples to write (read_measurements refuses a file without)")
    if not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
        raise UserError(
            f"{path}: t must be finite and strictly increasing (s): read_measurements "
            "refuses a file whose time does not increase"
        )
    if np.isinf(z).any():  # NaN is a dropout, written empty; an infinite value is not one
        i, j = np.argwhere(np.isinf(z))[0]
        raise UserError(f"{path}: row {i + 1}: {names[j]} is infinite (a dropout is NaN)")
    rows = [
        [format_time(float(a)), *(float(v) if np.isfinite(v) else "" for v in b)]
        for a, b in zip(t, z)
    ]
    write_table(path, ("t", *names), rows)
