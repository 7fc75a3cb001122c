"""CSV files: measurements in, estimates and truth out.

Formats (see README "File formats"):

* Measurement CSV: a header with at least ``t,roll,pitch`` (one IMU) or
  ``t,roll_1,pitch_1,roll_2,pitch_2,...`` (IMUs numbered from the base in the robot
  file's order); ``t`` in seconds, strictly increasing; angles in radians
  (``degrees=True`` for degrees), in the convention of :mod:`continuum_mhe.model.imu`.
  Other columns are ignored. With several IMUs an empty field is a dropout of that IMU.
* Estimate CSV: ``t``, the formulation's outputs (one section: ``x,y,z,theta,phi``;
  several: ``x,y,z`` then ``theta_k,phi_k,x_k,y_k,z_k`` per section), then
  ``status,solve_ms`` (m, rad, ms); rows without an estimate leave the outputs empty.
  A robust MHE's file has a column ``outlier`` (1: the sample's measurement was
  down-weighted, else 0) just before ``status``.
  Truth CSV: ``t,x,y,z`` and any of the per-section columns.

Every problem in an input file raises :class:`InputError` with a one-line message
naming the file and line. Outputs are written atomically: a temporary file in the same
folder is renamed over the target only once it is complete.
"""

from __future__ import annotations

import contextlib
import csv
import math
import os
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from glob import escape as glob_escape
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.descriptions import OutputSpec, output_names, pcc_outputs
from continuum_mhe.results import EstimateSeries

FloatArray = NDArray[np.float64]

#: The tip position columns every estimate and truth file has.
TIP_COLUMNS = ("x", "y", "z")
#: One section's state columns (the paper's robot); several sections: see
#: :func:`~continuum_mhe.model.descriptions.pcc_outputs`.
STATE_COLUMNS = ("t", *output_names(pcc_outputs(1)))
MEASUREMENT_COLUMNS = ("t", "roll", "pitch")


def estimate_columns(outputs: Sequence[OutputSpec], outlier: bool = False) -> tuple[str, ...]:
    """Header of an estimate CSV: ``t``, the outputs, ``outlier`` (with ``outlier``:
    a robust MHE's flags), ``status``, ``solve_ms``."""
    flags = ("outlier",) if outlier else ()
    return ("t", *output_names(outputs), *flags, "status", "solve_ms")


ESTIMATE_COLUMNS = estimate_columns(pcc_outputs(1))

#: Largest plausible |roll| and |pitch| in radians; beyond these, the file is in degrees.
_ROLL_LIMIT = math.pi + 0.05
_PITCH_LIMIT = math.pi / 2 + 0.05


class InputError(ValueError):
    """A problem with user input; the message is one line, naming file and line."""


@dataclass(frozen=True)
class MeasurementTable:
    """Measurements read from a file.

    Attributes:
        t: (n,) s, strictly increasing.
        z: (n, 2) ``[roll, pitch]`` rad; NaN marks a skipped (bad) sample, kept as a
            dropout so the output still has its row.
        skipped: descriptions of rows dropped or turned into dropouts (``skip_bad``).
    """

    t: FloatArray
    z: FloatArray
    skipped: list[str] = field(default_factory=list)


def _open_text(path: Path) -> IO[str]:
    if not path.exists():
        raise InputError(f"{path}: no such file")
    if path.is_dir():
        raise InputError(f"{path}: is a directory, expected a CSV file")
    try:
        return path.open(newline="", encoding="utf-8-sig")  # tolerate a BOM (Excel)
    except OSError as exc:
        raise InputError(f"{path}: cannot open ({exc.strerror})") from None


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and ``(line_number, fields)`` rows; blank lines are ignored."""
    with _open_text(path) as fh:
        reader = csv.reader(fh)
        try:
            rows = [
                (reader.line_num, [c.strip() for c in r])
                for r in reader
                if any(c.strip() for c in r)
            ]
        except UnicodeDecodeError:
            raise InputError(f"{path}: not a UTF-8 text file") from None
        except csv.Error as exc:
            raise InputError(f"{path}: line {reader.line_num}: malformed CSV ({exc})") from None
    if not rows:
        raise InputError(f"{path}: line 1: file is empty, expected a header such as t,roll,pitch")
    (_, header), body = rows[0], rows[1:]
    return [h.lower() for h in header], body


def _column_indices(path: Path, header: list[str], required: Sequence[str]) -> list[int]:
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"{path}: line 1: missing column(s) {', '.join(missing)} "
            f"(header has: {', '.join(header) or 'nothing'})"
        )
    return [header.index(c) for c in required]


def _parse_float(path: Path, line: int, name: str, text: str) -> float:
    try:
        return float(text)
    except ValueError:
        shown = text if len(text) <= 20 else text[:20] + "..."
        raise InputError(f"{path}: line {line}: column {name}: {shown!r} is not a number") from None


@dataclass(frozen=True)
class SampleRows:
    """Validated rows of a sample CSV: ``t`` (n,), ``values`` (n, k) with NaN for a
    bad value kept as a dropout, the file's line number of each row, and ``skipped``."""

    t: FloatArray
    values: FloatArray
    lines: list[int]
    skipped: list[str]


def read_sample_rows(
    path: Path,
    header: list[str],
    body: list[tuple[int, list[str]]],
    columns: Sequence[str],
    *,
    skip_bad: bool = False,
    empty_is_dropout: bool = False,
) -> SampleRows:
    """Validate the rows of a sample CSV whose ``columns[0]`` is the time ``t`` (s).

    A missing, non-numeric or non-finite value is an error, or with ``skip_bad`` a
    dropout (NaN, row kept); a bad, duplicate or decreasing ``t`` is an error, or with
    ``skip_bad`` the row is dropped. Each skip is recorded as ``"line N: problem"``.
    With ``empty_is_dropout`` an empty value is a dropout (NaN) without complaint (one
    sensor of several that did not report).
    """
    idx = _column_indices(path, header, columns)
    if not body:
        raise InputError(f"{path}: line 2: no data rows after the header")
    t_list: list[float] = []
    values: list[list[float]] = []
    lines: list[int] = []
    skipped: list[str] = []

    def bad(line: int, msg: str) -> None:
        if not skip_bad:
            raise InputError(f"{path}: line {line}: {msg}")
        if not skipped or not skipped[-1].startswith(f"line {line}: "):  # one per row
            skipped.append(f"line {line}: {msg}")

    truncated = "expected {} fields, found {} (truncated row?)"
    for line, row in body:
        if len(row) <= idx[0]:
            bad(line, truncated.format(len(header), len(row)))
            continue
        try:
            t = _parse_float(path, line, columns[0], row[idx[0]])
        except InputError as exc:
            bad(line, str(exc).split(": ", 2)[-1])
            continue
        if not math.isfinite(t):
            bad(line, f"t is {row[idx[0]]}")
            continue
        if t_list and t <= t_list[-1]:
            kind = "duplicate" if t == t_list[-1] else "decreasing"
            bad(line, f"{kind} timestamp t={t:g} after t={t_list[-1]:g} (t must strictly increase)")
            continue
        vals: list[float] = []
        for name, j in zip(columns[1:], idx[1:]):
            if j >= len(row):
                bad(line, truncated.format(len(header), len(row)))
                vals = [math.nan] * (len(columns) - 1)
                break
            if empty_is_dropout and row[j] == "":
                vals.append(math.nan)
                continue
            try:
                v = _parse_float(path, line, name, row[j])
            except InputError as exc:
                bad(line, str(exc).split(": ", 2)[-1])
                v = math.nan
            else:
                if not math.isfinite(v):
                    bad(line, f"column {name} is {row[j]} (a dropout; --skip-bad keeps it)")
                    v = math.nan  # with --skip-bad: a dropout, as the message says
            vals.append(v)
        t_list.append(t)
        values.append(vals)
        lines.append(line)
    if not t_list:
        raise InputError(f"{path}: no usable rows ({len(skipped)} skipped)")
    return SampleRows(np.array(t_list), np.array(values, dtype=float), lines, skipped)


def tilt_columns(n_imus: int) -> tuple[str, ...]:
    """``roll, pitch`` for one IMU; ``roll_1, pitch_1, roll_2, ...`` for several."""
    if n_imus == 1:
        return ("roll", "pitch")
    return tuple(f"{c}_{i}" for i in range(1, n_imus + 1) for c in ("roll", "pitch"))


def read_measurements(
    path: str | os.PathLike[str],
    *,
    degrees: bool = False,
    skip_bad: bool = False,
    n_imus: int = 1,
) -> MeasurementTable:
    """Read a measurement CSV (``t,roll,pitch``, or ``t,roll_1,pitch_1,...`` for
    ``n_imus`` IMUs), validating every row.

    With ``skip_bad``, rows whose angles are missing, non-numeric or NaN become
    dropouts (kept, NaN angles) and rows with a bad or non-increasing ``t`` are
    dropped; each is recorded in ``skipped``. Without it, the first bad row raises.
    With several IMUs an empty field is a dropout of that IMU only.
    """
    p = Path(path)
    header, body = _read_rows(p)
    columns = ("t", *tilt_columns(n_imus))
    if n_imus == 1 and "roll" not in header and "roll_1" in header:
        columns = ("t", "roll_1", "pitch_1")
    if n_imus > 1:
        _check_imu_count(p, header, n_imus)
    rows = read_sample_rows(
        p, header, body, columns, skip_bad=skip_bad, empty_is_dropout=n_imus > 1
    )
    z = np.radians(rows.values) if degrees else rows.values
    for i in range(n_imus):
        _check_angle_units(p, z[:, 2 * i : 2 * i + 2], rows.lines, degrees)
    return MeasurementTable(t=rows.t, z=z, skipped=rows.skipped)


def _check_imu_count(path: Path, header: list[str], n_imus: int) -> None:
    """The file's numbered IMU columns must match the robot's IMU count."""
    have = sorted(
        int(h.rsplit("_", 1)[1])
        for h in header
        if "_" in h and h.rsplit("_", 1)[1].isdigit() and h.rsplit("_", 1)[0] in _IMU_FIELDS
    )
    found = max(have, default=0)
    if found and found != n_imus:
        raise InputError(
            f"{path}: line 1: the file has columns for {found} IMU(s) but the robot file "
            f"describes {n_imus}"
        )


_IMU_FIELDS = {"roll", "pitch", "ax", "ay", "az", "gx", "gy", "gz"}


def _check_angle_units(path: Path, z: FloatArray, lines: list[int], degrees: bool) -> None:
    with np.errstate(invalid="ignore"):
        over = (np.abs(z[:, 0]) > _ROLL_LIMIT) | (np.abs(z[:, 1]) > _PITCH_LIMIT)
    if not over.any():
        return
    i = int(np.argmax(over))
    roll, pitch = z[i]
    where = f"{path}: line {lines[i]}: roll={roll:.4g}, pitch={pitch:.4g}"
    if degrees:
        raise InputError(f"{where} is out of range even in degrees (|roll| <= 180, |pitch| <= 90)")
    raise InputError(
        f"{where} rad is out of range (|roll| <= pi, |pitch| <= pi/2); "
        "the angles look like degrees: pass --degrees"
    )


@dataclass(frozen=True)
class StateTable:
    """An estimate or truth CSV: ``t`` (n,), ``values`` (n, k) with NaN where empty,
    ``names`` (k,) the columns (outputs such as ``x``, ``theta_2``), ``status`` (n,)
    (``"ok"`` where the file has no status column), and ``outlier`` (n,) bool where the
    file has an ``outlier`` column (else None)."""

    t: FloatArray
    names: tuple[str, ...]
    values: FloatArray
    status: NDArray[np.str_]
    outlier: NDArray[np.bool_] | None = None

    def column(self, name: str) -> FloatArray:
        return self.values[:, self.names.index(name)]


_NOT_STATES = {"t", "status", "solve_ms", "outlier"}


def read_state_table(
    path: str | os.PathLike[str], required: Sequence[str] = TIP_COLUMNS
) -> StateTable:
    """Read an estimate or truth CSV with at least ``t`` and ``required`` columns; every
    other numeric output column (``theta``, ``phi_2``, ``std_x``...) is kept."""
    p = Path(path)
    header, body = _read_rows(p)
    _column_indices(p, header, ("t", *required))
    names = tuple(h for h in header if h not in _NOT_STATES and h)
    idx = [header.index(c) for c in names]
    t_idx = header.index("t")
    if not body:
        raise InputError(f"{p}: line 2: no data rows after the header")
    s_idx = header.index("status") if "status" in header else None
    o_idx = header.index("outlier") if "outlier" in header else None
    flags: list[bool] = []
    t: list[float] = []
    out: list[list[float]] = []
    status: list[str] = []
    for line, row in body:
        if len(row) < len(header):
            raise InputError(
                f"{p}: line {line}: expected {len(header)} fields, found {len(row)} (truncated?)"
            )
        st = row[s_idx] if s_idx is not None else "ok"
        tv = _parse_float(p, line, "t", row[t_idx])
        vals = [
            math.nan if (row[j] == "" and st == "no-estimate") else _parse_float(p, line, c, row[j])
            for c, j in zip(names, idx)
        ]
        if st != "no-estimate" and not all(map(math.isfinite, [tv, *vals])):
            raise InputError(f"{p}: line {line}: NaN or infinite value")
        if t and tv <= t[-1]:
            raise InputError(f"{p}: line {line}: t={tv:g} does not increase (previous t={t[-1]:g})")
        if o_idx is not None:
            if row[o_idx] not in ("0", "1"):
                raise InputError(f"{p}: line {line}: outlier must be 0 or 1, got {row[o_idx]!r}")
            flags.append(row[o_idx] == "1")
        t.append(tv)
        out.append(vals)
        status.append(st)
    return StateTable(
        np.array(t), names, np.array(out, dtype=float).reshape(len(t), len(names)),
        np.array(status, dtype=str), None if o_idx is None else np.array(flags, dtype=bool),
    )  # fmt: skip


def read_states(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """Read a one-section estimate or truth CSV: ``t`` (n,), states (n, 5)
    ``x, y, z, theta, phi`` with NaN where empty, and status (n,)."""
    cols = STATE_COLUMNS[1:]
    table = read_state_table(path, cols)
    values = np.column_stack([table.column(c) for c in cols])
    return table.t, values, table.status


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _current_umask()


@contextlib.contextmanager
def _atomic(path: str | os.PathLike[str], binary: bool) -> Iterator[IO[Any]]:
    target = Path(path)
    if str(path) == "-":
        raise InputError("-: writing to standard output is not supported; give a file name")
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise InputError(f"{target}: folder {folder} does not exist")
    if target.is_dir():
        raise InputError(f"{target}: is a directory, expected a file name")
    if target.exists() and not target.is_file():
        raise InputError(f"{target}: not a regular file; give a file name")
    _remove_stale_temporaries(folder, target.name)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.{os.getpid()}.", suffix=".tmp", dir=folder)
    os.chmod(tmp, 0o666 & ~_UMASK)  # mkstemp makes 0600; give the file the usual mode
    try:
        if binary:
            with os.fdopen(fd, "wb") as fb:
                yield fb
        else:
            with os.fdopen(fd, "w", newline="", encoding="utf-8") as fh:
                yield fh
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def _remove_stale_temporaries(folder: Path, name: str) -> None:
    """Remove ``.NAME.PID.*.tmp`` files left by a killed writer (SIGKILL) of the same
    target, once their process is gone."""
    for stale in folder.glob(f".{glob_escape(name)}.*.tmp"):
        parts = stale.name[len(name) + 2 :].split(".")
        if not parts or not parts[0].isdigit():
            continue
        pid = int(parts[0])
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                stale.unlink()
        except PermissionError:  # alive, another user's
            continue


def atomic_writer(path: str | os.PathLike[str]) -> contextlib.AbstractContextManager[IO[str]]:
    """Open a temporary text file next to ``path``; rename it over ``path`` on success
    only, so an error never leaves a partial file (or touches an existing one)."""
    return _atomic(path, binary=False)


def atomic_binary_writer(
    path: str | os.PathLike[str],
) -> contextlib.AbstractContextManager[IO[bytes]]:
    """Binary counterpart of :func:`atomic_writer`."""
    return _atomic(path, binary=True)


def _fmt(v: float) -> str:
    return f"{v:.10g}"


def write_table(
    path: str | os.PathLike[str], columns: Sequence[str], rows: Sequence[Sequence[object]]
) -> None:
    """Write a CSV atomically; floats must be finite (refuses to write NaN)."""
    with atomic_writer(path) as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            cells = []
            for v in r:
                if isinstance(v, (float, np.floating)):
                    if not math.isfinite(v):
                        raise ValueError(f"refusing to write non-finite value to {path}")
                    cells.append(_fmt(float(v)))
                else:
                    cells.append(str(v))
            w.writerow(cells)


def estimate_row(
    t: float,
    output: Sequence[float] | FloatArray | None,
    status: str,
    solve_ms: float,
    ny: int,
    outlier: bool | None = None,
) -> list[object]:
    """One estimate CSV row; a row without an estimate leaves the outputs empty.
    ``outlier`` (None: no such column) is written as 0 or 1 before the status."""
    flag = [] if outlier is None else [int(bool(outlier))]
    if status == "no-estimate" or output is None:
        return [float(t), *([""] * ny), *flag, str(status), float(solve_ms)]
    return [float(t), *(float(v) for v in output), *flag, str(status), float(solve_ms)]


def estimate_rows(series: EstimateSeries) -> list[list[object]]:
    """Rows of the estimate CSV; no-estimate rows leave the outputs empty."""
    ny = len(series.outputs)
    flags = [None] * len(series.t) if series.outlier is None else list(series.outlier)
    return [
        estimate_row(t, out, str(st), ms, ny, fl)
        for t, out, st, ms, fl in zip(
            series.t, series.output, series.status, series.solve_ms, flags
        )
    ]


def write_estimates(path: str | os.PathLike[str], series: EstimateSeries) -> None:
    """Write an estimate CSV atomically (columns from ``series.outputs``; an ``outlier``
    column when the series carries outlier flags)."""
    columns = estimate_columns(series.outputs, outlier=series.outlier is not None)
    write_table(path, columns, estimate_rows(series))


def write_truth(
    path: str | os.PathLike[str],
    t: FloatArray,
    truth: FloatArray,
    outputs: Sequence[OutputSpec] = pcc_outputs(1),
) -> None:
    """Write a truth CSV ``t`` + the output columns atomically."""
    if truth.shape[1] != len(outputs):
        raise ValueError(f"truth has {truth.shape[1]} columns, expected {len(outputs)}")
    write_table(
        path,
        ("t", *output_names(outputs)),
        [[float(a), *map(float, b)] for a, b in zip(t, truth)],
    )


def write_measurements(
    path: str | os.PathLike[str],
    t: FloatArray,
    z: FloatArray,
    names: Sequence[str] = ("roll", "pitch"),
) -> None:
    """Write a measurement CSV ``t`` + ``names`` (rad) atomically; NaN (a dropout of
    that sensor) is written as an empty field."""
    if z.shape[1] != len(names):
        raise ValueError(f"z has {z.shape[1]} columns, expected {len(names)}")
    rows = [[float(a), *(float(v) if np.isfinite(v) else "" for v in b)] for a, b in zip(t, z)]
    write_table(path, ("t", *names), rows)
