"""Text tables read once, row by row: files, ``-`` (standard input), pipes and FIFOs.

Dialects read (the same for every CSV reader of the package):

* separators ``,`` ``;`` or tab, taken from the header line;
* ``#`` comment lines anywhere and blank lines are skipped; a file without a header
  line whose comments name one (``# fields: t_ms,ax,ay,az,gx,gy,gz``, as the
  ``continuum_imu`` firmware prints) uses that header, so a plain capture of the
  serial line reads as it is;
* a ``t_ms`` column (milliseconds) instead of ``t`` (seconds) is converted;
* a UTF-8 byte-order mark is tolerated (as in robot files); lines end in LF or CRLF,
  and a file whose lines end in CR alone is refused in one line;
* lines are read whole; a line longer than :data:`MAX_LINE_BYTES` or with a NUL byte
  is refused (a binary file, or ``/dev/zero``);
* a header that names a column twice is refused (which one holds the data?);
* numbers are ASCII, as CSV tools write them: what Python's ``float`` reads beyond
  that (``1_0`` as 10, fullwidth digits, Unicode spaces) is not a number.

The input is opened once and read front to back once, so pipes, ``<(...)`` process
substitution and named FIFOs work, and rows stream without being held in memory.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import os
import re
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, expect_type, time_text

#: Longest line accepted, bytes (a sample row is well under 1 kB; a comment line may be
#: long, so the limit is generous: it stops a binary file, not a wide table).
MAX_LINE_BYTES = 1 << 20
#: Longest piece of an input quoted in a message, characters.
SHOWN_CHARS = 40
#: Separators recognised in the header line, in order of preference.
SEPARATORS = (",", ";", "\t")
_SEPARATOR_NAMES = {",": "comma", ";": "semicolon", "\t": "tab"}


#: The inputs held by :func:`held_for_rereading` while it lasts: the name as given ->
#: (the name shown in messages, the bytes).
_HELD: dict[str, tuple[str, bytes]] = {}


@contextlib.contextmanager
def held_for_rereading(*paths: str | os.PathLike[str] | None) -> Iterator[None]:
    """Within the block, each of ``paths`` that cannot be read twice (``-``, a pipe,
    ``<(...)``, a named FIFO) is read whole once, at entry, and :func:`open_rows` opens
    it again from memory: for a command that reads one input more than once (an estimate
    file: its header, its options line, its rows). A regular file, a missing one (which
    its reader names) or None is left to be opened as usual. Released at exit, so that a
    later read of the same name (another ``-`` in the same process) reads anew. Readers
    that stream their input (``estimate`` of a recording, ``live``) do not use it."""
    held: list[str] = []
    try:
        for path in paths:
            if path is None:
                continue
            key = str(path)
            if key in _HELD or (key != "-" and (not os.path.exists(key) or os.path.isfile(key))):
                continue
            if os.path.isdir(key):
                continue  # its reader says so
            name, fh = _open(path)
            with fh:
                _HELD[key] = (name, fh.read())
            held.append(key)
        yield
    finally:
        for key in held:
            _HELD.pop(key, None)


def _open(path: str | os.PathLike[str]) -> tuple[str, IO[bytes]]:
    """``(name shown in messages, binary stream)``; ``-`` is standard input."""
    expect_type("path", path, (str, os.PathLike), "a file name (str or pathlib.Path)")
    if str(path) in _HELD:
        name, data = _HELD[str(path)]
        return name, io.BytesIO(data)
    if str(path) == "-":
        if sys.stdin is None:  # Python's stand-in for a closed descriptor 0 (`<&-`)
            raise InputError("-: standard input is closed; pipe the CSV in or name a file")
        try:
            fd = os.dup(sys.stdin.fileno())
        except (OSError, ValueError, io.UnsupportedOperation):
            raise InputError("-: standard input is not readable") from None
        return "<stdin>", open(fd, "rb")  # noqa: SIM115
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, expected a CSV file")
    try:
        return str(p), p.open("rb")  # decoded line by line: errors name their line
    except OSError as exc:
        raise InputError(f"{p}: cannot open ({exc.strerror})") from None


@dataclass
class TextRows:
    """A text table opened once: its header and a lazy iterator over its data rows.

    Attributes:
        name: the input as shown in messages (``<stdin>`` for ``-``).
        header: lower-case column names; a ``t_ms`` column is renamed ``t``.
        rows: ``(line_number, fields)`` of each data row, fields stripped; blank and
            ``#`` lines skipped. Read once.
        separator: the field separator found in the header.
        time_scale: seconds per unit of the ``t`` column (1e-3 for ``t_ms``).
        comments: the ``#`` lines before the first data row, without the ``#``.
        written: the column names as the file writes them (their case, ``t_ms``), one
            for each of ``header``; messages quote these (:meth:`as_written`).
    """

    name: str
    header: list[str]
    rows: Iterator[tuple[int, list[str]]]
    separator: str = ","
    time_scale: float = 1.0
    comments: list[str] = field(default_factory=list)
    _stream: IO[bytes] | None = None
    _pending: list[tuple[int, str]] = field(default_factory=list)  # data lines read already
    _next_line: int = 0  # the number of the first line not read yet
    written: list[str] = field(default_factory=list)

    def as_written(self, column: str) -> str:
        """The header's ``column`` (a name of :attr:`header`) as the file writes it, for
        messages; ``column`` itself where the header has no such column."""
        if column in self.header and len(self.written) == len(self.header):
            return self.written[self.header.index(column)]
        return column

    def close(self) -> None:
        if self._stream is not None:
            self._stream.close()

    def __enter__(self) -> TextRows:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def shorten(text: str, limit: int = SHOWN_CHARS) -> str:
    """``text`` cut to ``limit`` characters (``...`` marks the cut), for messages."""
    return text if len(text) <= limit else text[:limit] + "..."


def _read_line(fh: IO[bytes]) -> bytes:
    """One raw line with its end, at most :data:`MAX_LINE_BYTES` and its CRLF (``b""``
    at the end of the input)."""
    return fh.readline(MAX_LINE_BYTES + 2)


def _decode(name: str, n: int, raw: bytes) -> str:
    """Line ``n``'s text without its end: a line over :data:`MAX_LINE_BYTES`, a CR-only
    line end, a NUL byte or bytes that are not UTF-8 are one-line errors naming it."""
    if n == 1 and raw.startswith(b"\xef\xbb\xbf"):  # a BOM (Excel) is fine
        raw = raw[3:]
    body = raw.rstrip(b"\r\n") if raw.endswith(b"\n") else raw
    if b"\r" in body.rstrip(b"\r"):
        raise InputError(
            f"{name}: line {n}: lines end in CR alone (classic Mac OS line ends); save "
            "the file with LF or CRLF line ends"
        )
    if b"\x00" in body:
        raise InputError(f"{name}: line {n}: contains a NUL byte (a binary file, not CSV)")
    if len(body) > MAX_LINE_BYTES:
        raise InputError(f"{name}: line {n}: longer than {MAX_LINE_BYTES} bytes (not a CSV file?)")
    try:
        line = body.decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{name}: line {n}: not UTF-8 text (a binary file?)") from None
    return line.rstrip("\r")


def _lines(name: str, fh: IO[bytes]) -> Iterator[tuple[int, str]]:
    """``(line_number, text)`` of every line, whole and without its end (:func:`_decode`)."""
    n = 0
    while raw := _read_line(fh):
        n += 1
        yield n, _decode(name, n, raw)


def split_fields(text: str, separator: str) -> list[str]:
    """Fields of one line, stripped (quotes handled as in CSV)."""
    if '"' not in text:
        return [c.strip() for c in text.split(separator)]
    return [c.strip() for c in next(csv.reader([text], delimiter=separator))]


def _separator(header: str) -> str:
    for sep in SEPARATORS:
        if sep in header:
            return sep
    return ","


def to_float(text: str) -> float:
    """``float(text)`` for ASCII text without ``_``: Python's extensions that ``float``
    reads (``1_0`` as 10, fullwidth or other Unicode digits, Unicode spaces) raise
    ``ValueError``, as any other text that is not a number."""
    if not text.isascii() or "_" in text:
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def _is_number(text: str) -> bool:
    try:
        to_float(text)
    except ValueError:
        return False
    return True


#: A comment that declares the columns: ``# fields: t_ms,ax,ay,az,gx,gy,gz (units...)``
#: as the ``continuum_imu`` firmware prints it (``format`` and ``columns`` work too).
_DECLARED = re.compile(
    r"#?\s*(?:fields|format|columns)\s*:\s*([A-Za-z0-9_,;\t ]+?)\s*(?:\(.*)?$", re.IGNORECASE
)


def declared_fields(comment: str) -> tuple[str, ...] | None:
    """The field names a header comment declares (``# fields: t_ms,ax,... (units)``,
    with or without its ``#``), or None for any other comment. The one reading of the
    firmware's header line: files (:func:`open_rows`) and ``live`` use it."""
    m = _DECLARED.match(comment.strip())
    if m is None:
        return None
    text = m.group(1)
    names = tuple(f.strip() for f in text.split(_separator(text)) if f.strip())
    return names or None


def _header_from_comments(comments: list[str]) -> str | None:
    """The header a comment declares (:func:`declared_fields`), comma-separated, if any."""
    for c in comments:
        names = declared_fields(c)
        if names is not None:
            return ",".join(names)
    return None


def _check_names(name: str, line: int, header: list[str], written: list[str]) -> None:
    """One line for a header that names a column twice (which holds the data?), in any
    case (``Roll`` and ``roll``), quoting the file's own names."""
    seen: dict[str, str] = {}
    for h, w in zip(header, written):
        if h and h in seen:
            first = seen[h]
            what = (
                f"column {shorten(w)!r} appears twice in the header"
                if first == w
                else f"columns {shorten(first)!r} and {shorten(w)!r} of the header are one "
                "column, its case not read"
            )
            raise InputError(
                f"{name}: line {line}: {what} (which one holds the data?); rename or remove one"
            )
        seen[h] = w


#: the header a measurement file starts with, as the errors suggest it
MEASUREMENT_HEADER_HINT = "t,roll,pitch (or t_ms,ax,ay,az,gx,gy,gz)"


def open_rows(path: str | os.PathLike[str], header_hint: str = MEASUREMENT_HEADER_HINT) -> TextRows:
    """Open a text table once and read up to its header (see the module doc).

    Raises :class:`InputError` for a missing, empty, binary or header-less input (the
    message suggests ``header_hint``).
    """
    name, fh = _open(path)
    try:
        lines = _lines(name, fh)
        comments: list[str] = []
        first: tuple[int, str] | None = None
        for n, text in lines:
            s = text.strip()
            if s.startswith("#"):
                comments.append(s[1:].strip())
            elif s:
                first = (n, text)
                break
        if first is None:
            what = "only comments" if comments else "file is empty"
            raise InputError(f"{name}: line 1: {what}, expected a header such as {header_hint}")
        n0, text0 = first
        pending: list[tuple[int, str]] = []
        declared = _header_from_comments(comments)
        sep = _separator(text0)
        fields0 = split_fields(text0, sep)
        if declared is not None and fields0 and _is_number(fields0[0]):
            header_text = declared  # a serial capture: the header is in a comment
            pending.append(first)
        else:
            header_text = text0
        written = split_fields(header_text, _separator(header_text))
        header = [h.lower() for h in written]
        if header and _is_number(header[0]) and len(header) > 1:
            raise InputError(
                f"{name}: line {n0}: no header line; the first line is data. Add a header "
                f"such as {header_hint}"
            )
        _check_names(name, n0, header, written)
        scale = 1.0
        if "t" in header and "t_ms" in header:
            raise InputError(
                f"{name}: line {n0}: the header has both t and t_ms: one time column, t in "
                "seconds or t_ms in milliseconds"
            )
        if "t" not in header and "t_ms" in header:
            header[header.index("t_ms")] = "t"
            scale = 1e-3
        rows = _data_rows(lines, pending, sep)
    except BaseException:
        fh.close()
        raise
    return TextRows(name, header, rows, sep, scale, comments, fh, pending, n0 + 1, written)


def _data_rows(
    lines: Iterator[tuple[int, str]], pending: list[tuple[int, str]], sep: str
) -> Iterator[tuple[int, list[str]]]:
    for n, text in [*pending]:
        yield n, split_fields(text, sep)
    for n, text in lines:
        s = text.strip()
        if not s or s.startswith("#"):
            continue
        yield n, split_fields(text, sep)


#: header names a recording's time column often has elsewhere; the files here name it ``t``
TIME_LIKE_NAMES = frozenset(
    {"time", "times", "timestamp", "stamp", "time_s", "t_s", "sec", "secs", "seconds"}
)


#: the columns that IMU readings have (tilt or raw, first IMU or only one)
_READING_COLUMNS = frozenset({"roll", "pitch", "ax", "roll_1", "pitch_1", "ax_1"})


def _other_kind_of_file(header: Sequence[str], missing: Sequence[str]) -> str:
    """A hint where the table read for IMU readings is another kind of file: a robot
    file (TOML: its first line a ``key = value``, or a ``[table]``) or an estimate or
    truth (tip columns x, y, z); else ""."""
    first = header[0] if header else ""
    if "=" in first or first.startswith("["):
        return " (a robot file? it is given with --robot ROBOT.toml)"
    if _READING_COLUMNS & set(missing) and {"x", "y", "z"} <= set(header):
        return (
            " (an estimate or truth table, not IMU readings: estimate reads a recording of "
            "the IMUs; continuum-mhe evaluate EST.csv TRUTH.csv scores an estimate)"
        )
    return ""


def column_indices(rows: TextRows, required: Sequence[str]) -> list[int]:
    """Positions of ``required`` columns in the header, or a one-line error that names
    what the header has (and the separator, when it is likely the problem)."""
    missing = [c for c in required if c not in rows.header]
    if missing:
        has = shorten(", ".join(rows.written or rows.header), 200) or "nothing"
        hint = _other_kind_of_file(rows.header, missing)
        if not hint and len(rows.header) == 1:
            hint = (
                f" (one column: the separator must be {', '.join(map(repr, SEPARATORS))}; "
                f"read as {_SEPARATOR_NAMES[rows.separator]})"
            )
        elif not hint and "t" in missing:
            named = [c for c in rows.header if c.lower() in TIME_LIKE_NAMES]
            if named:
                hint = (
                    f" (the time in seconds is named t: rename {rows.as_written(named[0])!r} to t)"
                )
        raise InputError(f"{rows.name}: line 1: missing column(s) {', '.join(missing)} "
                         f"(header has: {has}){hint}")  # fmt: skip
    return [rows.header.index(c) for c in required]


def parse_float(name: str, line: int, column: str, text: str) -> float:
    """``float(text)`` or a one-line error naming file, line and column."""
    try:
        return to_float(text)
    except ValueError:
        shown = shorten(text, 20)
        hint = ""
        if "," in text and _is_number(text.replace(",", ".", 1)):
            hint = " (a decimal comma? use a point, e.g. 0.5)"
        raise InputError(
            f"{name}: line {line}: column {column}: {shown!r} is not a number{hint}"
        ) from None


@dataclass
class RowProblems:
    """Bad rows met while reading with ``skip_bad``: a count, the first few, how many of
    them were dropped (a bad or non-increasing ``t``) and how many kept with every value
    a dropout (``whole``: too few or too many fields, so that which value belongs to
    which column is unknown); the others were kept, their bad values read as dropouts
    of their IMU."""

    count: int = 0
    first: list[str] = field(default_factory=list)
    keep: int = 20
    dropped: int = 0
    whole: int = 0

    def add(self, what: str) -> None:
        self.count += 1
        if len(self.first) < self.keep:
            self.first.append(what)

    def summary(self) -> str:
        """One clause for a run's summary line (``""`` when nothing was bad)."""
        if not self.count:
            return ""
        kept = self.count - self.dropped - self.whole
        parts = [f"{kept} sample(s) with a bad value, read as a dropout of its IMU"] if kept else []
        if self.whole:
            parts.append(
                f"{self.whole} sample(s) with too few or too many fields, read as a dropout "
                "of every IMU (which value is whose is unknown)"
            )
        if self.dropped:
            parts.append(f"{self.dropped} sample(s) dropped (bad or non-increasing t)")
        return f"bad rows: {'; '.join(parts)}; first: {self.first[0]}"


def has_extra_fields(row: Sequence[str], width: int) -> bool:
    """The row has a non-empty field beyond the header's ``width`` columns (empty
    trailing fields, from a separator at the end of the line, are no data)."""
    return any(f != "" for f in row[width:])


def iter_samples(
    rows: TextRows,
    columns: Sequence[str],
    *,
    skip_bad: bool = False,
    empty_is_dropout: bool = False,
    problems: RowProblems | None = None,
    skip_hint: str | None = None,
) -> Iterator[tuple[int, float, list[float]]]:
    """Validated ``(line, t, values)`` of a sample table whose ``columns[0]`` is the
    time ``t`` (converted to s), one row at a time.

    A missing, non-numeric or non-finite value is an error, or with ``skip_bad`` a
    dropout (NaN, row kept); so is a row with fewer or more fields than the header
    (every value of a row with an extra field is a dropout: which one is extra is
    unknown); a bad, duplicate or decreasing ``t`` is an error, or with ``skip_bad`` the
    row is dropped; each skip is counted in ``problems``. With
    ``empty_is_dropout`` an empty value is a dropout without complaint. ``skip_hint``:
    what the error of a non-finite value says ``--skip-bad`` does with it (default
    :data:`DROPOUT_HINT`).
    """
    checks = _SampleChecks(
        rows, columns, skip_bad, empty_is_dropout, problems, skip_hint or DROPOUT_HINT
    )
    yield from checks.rows(rows.rows)
    checks.finish()


@dataclass(frozen=True)
class SampleBlock:
    """Validated rows of a sample table (:func:`sample_blocks`): ``lines`` the file's
    line number of each row, ``t`` (n,) s, ``values`` (n, k) the other columns, NaN for
    a dropout."""

    lines: list[int]
    t: FloatArray
    values: FloatArray

    def __len__(self) -> int:
        return len(self.lines)


def sample_blocks(
    rows: TextRows,
    columns: Sequence[str],
    size: int,
    *,
    skip_bad: bool = False,
    empty_is_dropout: bool = False,
    problems: RowProblems | None = None,
) -> Iterator[SampleBlock]:
    """The samples of :func:`iter_samples`, the same values, errors and ``problems``,
    as blocks of ``size`` rows (the last one shorter); reads ``rows``' input itself
    (``rows.rows`` is not to be used as well).

    The lines are read :data:`BLOCK_BYTES` at a time and parsed as a block by numpy's
    :func:`numpy.loadtxt` when the block's text can only mean what the row-by-row reading
    finds in it: ASCII digits, signs, points and exponents, separators and blanks; every
    data line with the header's number of fields; finite values, empty ones only where
    they are dropouts; ``t`` increasing. Any other block is read row by row, as
    :func:`iter_samples` reads it, so a problem is reported exactly as there (file, line,
    what is wrong), after the samples before it.
    """
    checks = _SampleChecks(rows, columns, skip_bad, empty_is_dropout, problems)
    pieces: list[SampleBlock] = []
    loose: list[tuple[int, float, list[float]]] = []  # rows read one at a time
    count = 0
    for item in checks.blocks():
        if isinstance(item, SampleBlock):
            pieces += [_block_of(loose, len(columns) - 1), item] if loose else [item]
            loose = []
            count += len(item)
        else:
            loose.append(item)
            count += 1
        while count >= size:  # as soon as a block is complete: errors after it come later
            if loose:
                pieces.append(_block_of(loose, len(columns) - 1))
                loose = []
            whole = _joined(pieces)
            yield _part(whole, 0, size)
            pieces = [_part(whole, size, len(whole))] if len(whole) > size else []
            count -= size
    checks.finish()
    if loose:
        pieces.append(_block_of(loose, len(columns) - 1))
    if pieces:
        yield _joined(pieces)


#: Bytes of whole lines read and parsed together by :func:`sample_blocks` (about 3,000
#: rows of a tilt table).
BLOCK_BYTES = 1 << 17
#: The bytes of a block that :func:`numpy.loadtxt` reads as the rows would be read:
#: ASCII digits, signs, decimal points, exponents, blanks, line ends (with a separator).
_PLAIN = b"0123456789.eE+- \t\r\n"
#: A line of blanks only (skipped), in a block of lines.
_BLANK_LINE = re.compile(rb"^[ \t\r]*$", re.M)


def _block_of(rows: list[tuple[int, float, list[float]]], width: int) -> SampleBlock:
    t = np.array([r[1] for r in rows], dtype=np.float64)
    values = np.array([r[2] for r in rows], dtype=np.float64).reshape(len(rows), width)
    return SampleBlock([r[0] for r in rows], t, values)


def _joined(pieces: list[SampleBlock]) -> SampleBlock:
    if len(pieces) == 1:
        return pieces[0]
    lines = [n for p in pieces for n in p.lines]
    return SampleBlock(
        lines, np.concatenate([p.t for p in pieces]), np.vstack([p.values for p in pieces])
    )


def _part(block: SampleBlock, i: int, j: int) -> SampleBlock:
    return SampleBlock(block.lines[i:j], block.t[i:j], block.values[i:j])


def empty_field_pattern(sep: bytes) -> re.Pattern[bytes]:
    """An empty or blank (spaces, tabs) field of lines separated by ``sep``."""
    blank = b"[" + b" \t".replace(sep, b"") + b"]*"
    sep_re = re.escape(sep)
    return re.compile(b"(?:(?<=" + sep_re + b")|^)" + blank + b"(?=" + sep_re + b"|$)", re.M)


def may_have_empty_field(body: bytes, sep: bytes) -> bool:
    """False only where the lines ``body`` (none of them empty) have no empty or blank
    field: no separator at a line's start or end, none beside another, and no space or
    tab (a blank field's): a quick test before :func:`empty_field_pattern`'s search."""
    return (
        body.startswith(sep)
        or body.endswith(sep)
        or sep + sep in body
        or b"\n" + sep in body
        or sep + b"\n" in body
        or b" " in body
        or b"\t" in body
    )


#: What a non-finite value's error says ``--skip-bad`` does with a sensor's reading.
DROPOUT_HINT = "a dropout; --skip-bad keeps it, skip_bad=True in Python"


class _SampleChecks:
    """The checks of :func:`iter_samples` over one table, row by row or a block at a
    time, with their state: the last ``t``, the rows seen, the problems."""

    def __init__(
        self,
        rows: TextRows,
        columns: Sequence[str],
        skip_bad: bool,
        empty_is_dropout: bool,
        problems: RowProblems | None,
        skip_hint: str = DROPOUT_HINT,
    ) -> None:
        self.table = rows
        self.skip_hint = skip_hint  # what --skip-bad does with a non-finite value
        self.columns = columns
        self.idx = column_indices(rows, columns)
        #: the columns as the file writes them, for messages
        self.shown = [rows.as_written(c) for c in columns]
        self.skip_bad = skip_bad
        self.empty_is_dropout = empty_is_dropout
        self.problems = problems if problems is not None else RowProblems()
        self.last_t = -math.inf
        self.last_bad = -1
        self.n_rows = 0  # data rows read
        self.n_out = 0  # samples given
        #: an empty or blank field (a dropout where ``empty_is_dropout``)
        self.empty_field = empty_field_pattern(rows.separator.encode())

    def bad(self, line: int, msg: str, dropped: bool = False) -> None:
        if not self.skip_bad:
            raise InputError(f"{self.table.name}: line {line}: {msg}")
        if self.last_bad != line:  # one per row
            self.problems.add(f"line {line}: {msg}")
            self.last_bad = line
        self.problems.dropped += dropped  # the row's last word: its t is bad, it is dropped

    def rows(
        self, rows: Iterator[tuple[int, list[str]]]
    ) -> Iterator[tuple[int, float, list[float]]]:
        """The checked samples of ``(line, fields)`` rows, one at a time."""
        columns, idx, bad, shown = self.columns, self.idx, self.bad, self.shown
        name, scale, width = self.table.name, self.table.time_scale, len(self.table.header)
        truncated = "expected {} fields, found {} (truncated row?)"
        for line, row in rows:
            self.n_rows += 1
            extra = has_extra_fields(row, width)
            if extra:  # which field is extra is unknown: no value of the row is trusted
                bad(
                    line,
                    f"expected {width} fields, found {len(row)} (an extra field or separator?)",
                )
            if len(row) <= idx[0]:
                bad(line, truncated.format(width, len(row)), dropped=True)
                continue
            try:
                t = parse_float(name, line, shown[0], row[idx[0]]) * scale
            except InputError as exc:
                bad(line, str(exc).split(": ", 2)[-1], dropped=True)
                continue
            if not math.isfinite(t):
                bad(line, f"{shown[0]} is {row[idx[0]]}", dropped=True)
                continue
            if t <= self.last_t:
                kind = "duplicate" if t == self.last_t else "decreasing"
                msg = (
                    f"{kind} timestamp t={time_text(t)} after t={time_text(self.last_t)} "
                    "(t must strictly increase)"
                )
                bad(line, msg, dropped=True)
                continue
            vals: list[float] = []
            for col, j in zip(shown[1:], idx[1:]):
                if extra:
                    self.problems.whole += 1
                    vals = [math.nan] * (len(columns) - 1)
                    break
                if j >= len(row):
                    bad(line, truncated.format(width, len(row)))
                    self.problems.whole += 1
                    vals = [math.nan] * (len(columns) - 1)
                    break
                if self.empty_is_dropout and row[j] == "":
                    vals.append(math.nan)
                    continue
                try:
                    v = parse_float(name, line, col, row[j])
                except InputError as exc:
                    empty = row[j] == ""  # a missing value, which --skip-bad leaves out
                    bad(line, f"column {col} is empty ({self.skip_hint})" if empty
                        else str(exc).split(": ", 2)[-1])  # fmt: skip
                    v = math.nan
                else:
                    if not math.isfinite(v):
                        bad(
                            line,
                            f"column {col} is {row[j]} ({self.skip_hint})",
                        )
                        v = math.nan  # with --skip-bad: a dropout, as the message says
                vals.append(v)
            self.last_t = t
            self.n_out += 1
            yield line, t, vals

    def blocks(self) -> Iterator[SampleBlock | tuple[int, float, list[float]]]:
        """The table's samples, read from its input: a :class:`SampleBlock` for each
        block of lines parsed whole, one ``(line, t, values)`` at a time for the others."""
        table = self.table
        yield from self.rows(iter([(n, split_fields(text, table.separator))
                                   for n, text in table._pending]))  # fmt: skip
        assert table._stream is not None, "sample_blocks reads an open table"
        for first, text in _line_blocks(table._stream, table._next_line):
            block = self._parse(text, first)
            if block is None:
                yield from self.rows(_split_rows(table.name, text, first, table.separator))
            elif len(block):
                yield block

    def _parse(self, text: bytes, first: int) -> SampleBlock | None:
        """The samples of the lines ``text`` (numbered from ``first``) parsed as one
        block, or None when they are to be read row by row (see :func:`sample_blocks`)."""
        table, sep = self.table, self.table.separator.encode()
        if text.translate(None, _PLAIN + sep):
            return None
        if b"\r" in text:
            if text.count(b"\r") != text.count(b"\r\n"):
                return None
            text = text.replace(b"\r\n", b"\n")
        lines = text.split(b"\n")
        if text.endswith(b"\n"):
            lines.pop()
        if len(text) > MAX_LINE_BYTES and max(map(len, lines)) > MAX_LINE_BYTES:
            return None
        numbers = range(first, first + len(lines))
        if _has_blank_line(text[:-1] if text.endswith(b"\n") else text):
            kept = [(n, ln) for n, ln in zip(numbers, lines) if ln.strip()]
            numbers, lines = [k[0] for k in kept], [k[1] for k in kept]  # type: ignore[assignment]
            text = b"\n".join(lines)
        if not lines:
            return SampleBlock([], np.empty(0), np.empty((0, len(self.columns) - 1)))
        # every line with the header's number of fields (numpy reads the columns it is
        # given from each line, whatever the line's number of fields)
        byte = np.frombuffer(text, dtype=np.uint8)
        ends = np.append(np.flatnonzero(byte == ord("\n")), len(byte))[: len(lines)]
        seps = np.searchsorted(np.flatnonzero(byte == sep[0]), ends)
        if (np.diff(seps, prepend=0) != len(table.header) - 1).any():
            return None
        body = text[:-1] if text.endswith(b"\n") else text
        if (
            self.empty_is_dropout
            and may_have_empty_field(body, sep)
            and self.empty_field.search(body)
        ):
            lines = self.empty_field.sub(b"nan", body).split(b"\n")
        try:
            values = np.loadtxt(
                lines, dtype=np.float64, delimiter=table.separator, comments=None,
                usecols=self.idx, ndmin=2, encoding="ascii",
            )  # fmt: skip
        except ValueError:
            return None
        t = values[:, 0] * table.time_scale
        if np.isinf(values).any() or not np.isfinite(t).all():
            return None
        if not (t[0] > self.last_t and (t[1:] > t[:-1]).all()):
            return None
        if not self.empty_is_dropout and np.isnan(values).any():
            return None
        self.last_t = float(t[-1])
        self.n_rows += len(t)
        self.n_out += len(t)
        return SampleBlock(list(numbers), t, np.ascontiguousarray(values[:, 1:]))

    def finish(self) -> None:
        """The errors of a table without samples, once it is read."""
        if self.n_rows == 0:
            raise InputError(f"{self.table.name}: line 2: no data rows after the header")
        if self.n_out == 0:
            raise InputError(f"{self.table.name}: no usable rows ({self.problems.count} skipped)")


def _has_blank_line(body: bytes) -> bool:
    """Whether the lines ``body`` (without the last one's end) have a blank one."""
    if not body or body.startswith(b"\n") or body.endswith(b"\n") or b"\n\n" in body:
        return True
    return (b" " in body or b"\t" in body) and _BLANK_LINE.search(body) is not None


def _line_blocks(fh: IO[bytes], first: int) -> Iterator[tuple[int, bytes]]:
    """``(number of the first line, text)`` of the rest of ``fh`` in blocks of whole lines
    of about :data:`BLOCK_BYTES` (the last line of the input may have no end; a line
    longer than :data:`MAX_LINE_BYTES` comes in a block of its own, cut)."""
    rest = b""
    # what has arrived, up to the size asked (a pipe's reader gets the lines written so
    # far instead of waiting for a whole block)
    read = getattr(fh, "read1", fh.read)
    while True:
        data = read(max(BLOCK_BYTES, len(rest)))  # a long line: reads that double
        text = rest + data
        if not text:
            return
        cut = text.rfind(b"\n") + 1 if data else len(text)
        if cut == 0:  # no line end yet: read on, up to the longest line taken
            if len(text) <= MAX_LINE_BYTES + 2:
                rest = text
                continue
            cut = len(text)
        text, rest = text[:cut], text[cut:]
        yield first, text
        first += text.count(b"\n")


def _split_rows(name: str, text: bytes, first: int, sep: str) -> Iterator[tuple[int, list[str]]]:
    """The data rows of the lines ``text`` (numbered from ``first``) read one at a time,
    as :attr:`TextRows.rows` reads them (a line cut where :func:`_read_line` cuts it)."""
    lines = text.split(b"\n")
    last = lines.pop()  # the text after the last line end: a line without one, or b""
    raw = [ln + b"\n" for ln in lines] + ([last] if last else [])
    for n, line in enumerate(raw, start=first):
        text_line = _decode(name, n, line[: MAX_LINE_BYTES + 2])
        s = text_line.strip()
        if s and not s.startswith("#"):
            yield n, split_fields(text_line, sep)
