"""Estimate, truth and measurement CSVs written (docs/formats.md): the columns of an
estimate file (``t``, the formulation's outputs, ``std_c`` for every output ``c``, then
``status,solve_ms``; a robust MHE's ``outlier`` just before ``status``), its rows as
text, and the writers. Outputs are written atomically (:mod:`.output_files`)."""

from __future__ import annotations

import csv
import math
import os
import re
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, time_text
from continuum_mhe.io.output_files import atomic_writer
from continuum_mhe.model.descriptions import (
    OutputSpec,
    angle_beyond_a_turn,
    output_names,
    pcc_outputs,
)
from continuum_mhe.results import STATUS_MEANINGS, EstimateSeries, Status

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


def format_number(v: float) -> str:
    """A number as the estimate and truth files write it: ``"%.10g"``, a negative zero
    as ``0`` (the sign of a zero carries nothing a reader can use)."""
    return f"{v + 0.0:.10g}"


def format_time(t: float) -> str:
    """An estimate row's time ``t`` (s) as written: ``"%.10g"`` where that keeps it to
    half a microsecond (below 1e4 s it always does) or ``|t| >= 1e15``, else six decimals
    without trailing zeros, so that samples a millisecond or less apart on a device clock
    past 1e6 s stay distinct; a negative zero as ``0`` (the compiled writer's rule, to
    the character)."""
    if not math.isfinite(t):
        raise UserError("refusing to write a non-finite time")
    t += 0.0  # a negative zero as 0
    short = f"{t:.10g}"
    if abs(float(short) - t) <= 5e-7 or abs(t) >= TEN_DIGITS_S:
        return short
    return f"{t:.6f}".rstrip("0").rstrip(".")


#: Times further apart than this (s), each below :data:`TEN_DIGITS_S`, are written apart
#: (:func:`format_time` writes each within half a microsecond).
_APART_S = 1e-6
#: From this time on (s), :func:`format_time` writes ten significant digits.
TEN_DIGITS_S = 1e15


class TimesWrittenAsOneError(UserError):
    """Times that the estimate, truth or measurement file would write as one
    (:func:`check_written_times`); ``t`` the later of the two, s."""

    def __init__(self, message: str, t: float) -> None:
        super().__init__(message)
        self.t = t


def check_written_times(
    path: str | os.PathLike[str], t: FloatArray, after: float | None = None, first_row: int = 1
) -> None:
    """A :class:`TimesWrittenAsOneError` naming ``path`` and the row (from 1) of the first time of
    ``t`` (s, finite, increasing) that :func:`format_time` writes as one not after the
    row before's (``after``: the time of the row written before ``t``'s first, by an
    earlier block; ``first_row``: the row of ``t``'s first time in the file): the file's
    readers refuse a time that does not increase. Raised before anything of ``t`` is
    written."""
    t = np.asarray(t, dtype=float)
    prev = t[:-1] if after is None else np.concatenate([[after], t[:-1]])
    cur = t[1:] if after is None else t
    near = (cur - prev <= _APART_S) | (np.maximum(np.abs(prev), np.abs(cur)) >= TEN_DIGITS_S)
    for j in np.flatnonzero(near):
        a, b = format_time(float(prev[j])), format_time(float(cur[j]))
        if float(b) <= float(a):
            row = first_row + int(j) + (0 if after is not None else 1)
            raise TimesWrittenAsOneError(
                f"{path}: row {row}: t = {time_text(float(cur[j]))} s is written {b}, not after "
                f"the row before's {a} (t = {time_text(float(prev[j]))} s), and the file's "
                "readers refuse a time that does not increase: times are written to the "
                f"microsecond (ten significant digits from {TEN_DIGITS_S:g} s): leave out a "
                "sample a microsecond or less after the one before, or give t in seconds",
                float(cur[j]),
            )


def write_table(
    path: str | os.PathLike[str],
    columns: Sequence[str],
    rows: Sequence[Sequence[object]],
    notes: Sequence[tuple[str, str]] = (),
) -> None:
    """Write a CSV atomically; floats must be finite (refuses to write NaN). ``notes``:
    ``(key, value)`` pairs (each value a TOML value) written as ``# key = value`` lines
    above the header, as ``estimate`` writes its options. Column names and notes that
    the readers would not read back (a name empty, repeated or holding a comma, quote or
    line end; a note not a pair of one-line strings, its key not a bare TOML key) are
    refused before anything is written."""
    _check_columns(path, columns)
    _check_notes(path, notes)
    with atomic_writer(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        for key, value in notes:
            fh.write(f"# {key} = {value}\n")
        w.writerow(columns)
        for r in rows:
            w.writerow(format_cells(path, r))


def _check_columns(path: str | os.PathLike[str], columns: Sequence[str]) -> None:
    """A :class:`UserError` for column names the CSV readers would not read back."""
    seen: set[str] = set()
    for name in columns:
        if not isinstance(name, str) or not name.strip() or any(c in name for c in ',"\r\n'):
            raise UserError(
                f"{path}: column name {name!r:.40} is not one the readers take: a non-empty "
                "str without a comma, quote or line end"
            )
        if name in seen:
            raise UserError(f"{path}: column {name!r} is named twice")
        seen.add(name)


def _check_notes(path: str | os.PathLike[str], notes: Sequence[tuple[str, str]]) -> None:
    """A :class:`UserError` for notes that would not be read back as ``# key = value``."""
    for note in notes:
        if not (
            isinstance(note, tuple)
            and len(note) == 2
            and all(
                isinstance(part, str) and "\n" not in part and "\r" not in part for part in note
            )
            and _BARE_KEY.fullmatch(note[0])
        ):
            raise UserError(
                f"{path}: a note must be a (key, value) pair of one-line strings, the key a "
                f"bare TOML key (letters, digits, _ and -), got {note!r:.60}"
            )


#: A bare TOML key, as a note's key must be.
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def format_cells(path: str | os.PathLike[str], row: Sequence[object]) -> list[str]:
    """The CSV cells of one row: floats in 10 significant digits, which must be finite
    (a non-finite value is a bug: refused)."""
    cells = []
    for v in row:
        if isinstance(v, (float, np.floating)):
            if not math.isfinite(v):
                raise UserError(f"refusing to write a non-finite value to {path}")
            cells.append(format_number(float(v)))
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
    if status == Status.NO_ESTIMATE or output is None:
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
    after: float | None = None,
    first_row: int = 1,
) -> str:
    """The estimate CSV lines of several samples, as :func:`estimate_row` and
    :func:`format_cells` write each (``output``, ``output_std`` (n, ny) NaN where there
    is none; ``outlier`` None: no such column); a non-finite output of an estimate is
    refused (a bug), and times written as one not after the row before's
    (:func:`check_written_times`; ``after``: the time of the row written before these,
    ``first_row``: the row of the first of them in the file).
    Written by the compiled core, each number as ``%.10g``."""
    status = list(status)  # str (or Status, a str): numpy's array of them calls __str__
    no_estimate = np.fromiter(map("no-estimate".__eq__, status), dtype=np.bool_, count=len(status))
    estimated = ~np.isnan(output).all(axis=1) & ~no_estimate
    if not (
        np.isfinite(t).all()
        and np.isfinite(solve_ms).all()
        and np.isfinite(output[estimated]).all()
    ):
        raise UserError(f"refusing to write a non-finite value to {path}")
    check_written_times(path, t, after, first_row)
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
    """``t`` (n,) and ``values`` (n, m) as float arrays (lists too), a row per sample,
    or a UserError naming the shapes (or the counts, where they differ)."""
    try:
        t_arr, v_arr = np.asarray(t, dtype=float), np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"t and {name} must be arrays of numbers") from None
    if t_arr.ndim != 1 or v_arr.ndim != 2:
        raise UserError(
            f"t must be (n,) and {name} (n, m); got shapes {t_arr.shape} and {v_arr.shape}"
        )
    if len(t_arr) != len(v_arr):
        raise UserError(f"t has {len(t_arr)} samples and {name} {len(v_arr)} rows: they must match")
    return t_arr, v_arr


def write_estimates(
    path: str | os.PathLike[str],
    series: EstimateSeries,
    notes: Sequence[tuple[str, str]] = (),
) -> None:
    """Write an estimate CSV atomically (columns from ``series.outputs``; an ``outlier``
    column when the series carries outlier flags); ``notes`` as :func:`write_table`'s
    (``("options", '{robot = "two-section"}')``: ``evaluate``, ``plot`` and ``view`` then
    take that robot)."""
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
    check_written_times(path, t)
    unknown = sorted({str(v) for v in series.status} - set(STATUS_MEANINGS))
    if unknown:
        raise UserError(f"{path}: status {unknown[0]!r} is not one of {', '.join(STATUS_MEANINGS)}")
    columns = estimate_columns(series.outputs, outlier=series.outlier is not None)
    write_table(path, columns, estimate_rows(series), notes)


def write_truth(
    path: str | os.PathLike[str],
    t: FloatArray,
    truth: FloatArray,
    outputs: Sequence[OutputSpec] = pcc_outputs(1),
) -> None:
    """Write a truth CSV ``t`` + the output columns atomically (``t`` as
    :func:`format_time` writes it: a device or Unix clock keeps its microseconds)."""
    t, truth = _samples_table(t, truth, "truth")
    if not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
        raise UserError(
            f"{path}: t must be finite and strictly increasing (s): read_state_table "
            "refuses a file whose time does not increase"
        )
    check_written_times(path, t)
    if isinstance(outputs, (str, bytes)) or not all(isinstance(o, OutputSpec) for o in outputs):
        raise UserError(
            f"outputs must be OutputSpecs (a Recording's outputs, or a formulation's), got "
            f"{outputs!r:.60}"
        )
    if truth.shape[1] != len(outputs):
        raise UserError(
            f"truth has {truth.shape[1]} columns, expected {len(outputs)} (the outputs "
            f"{', '.join(output_names(outputs))[:60]}): pass the recording's or the "
            "formulation's outputs (outputs=rec.outputs) for another robot"
        )
    turned = angle_beyond_a_turn(output_names(outputs), truth)
    if turned is not None:
        raise UserError(f"{path}: row {turned[0] + 1}: {turned[1]}")
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
        raise UserError(
            f"z has {z.shape[1]} columns, expected {len(names)} ({', '.join(names)[:60]}): "
            "pass the column names (names=rec.measurement_names) for another robot or IMU "
            "model"
        )
    if len(t) == 0:
        raise UserError(f"{path}: no samples to write (read_measurements refuses a file without)")
    if not np.isfinite(t).all() or np.any(np.diff(t) <= 0):
        raise UserError(
            f"{path}: t must be finite and strictly increasing (s): read_measurements "
            "refuses a file whose time does not increase"
        )
    check_written_times(path, t)
    if np.isinf(z).any():  # NaN is a dropout, written empty; an infinite value is not one
        i, j = np.argwhere(np.isinf(z))[0]
        raise UserError(f"{path}: row {i + 1}: {names[j]} is infinite (a dropout is NaN)")
    rows = [
        [format_time(float(a)), *(float(v) if np.isfinite(v) else "" for v in b)]
        for a, b in zip(t, z)
    ]
    write_table(path, ("t", *names), rows)
