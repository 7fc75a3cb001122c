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
import itertools
import os
import re
import shlex
import sys
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, cast

from continuum_mhe.errors import InputError, NotANumberError, expect_type

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


def held_text(path: str | os.PathLike[str]) -> str | None:
    """The text of ``path`` where :func:`held_for_rereading` holds it (``-``, a pipe),
    decoded as UTF-8 (undecodable bytes replaced), else None."""
    held = _HELD.get(str(path))
    return held[1].decode("utf-8", errors="replace") if held is not None else None


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
        return "<stdin>", _named("<stdin>", open(fd, "rb"))  # noqa: SIM115
    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file")
    if p.is_dir():
        raise InputError(f"{p}: is a directory, expected a CSV file")
    try:
        return str(p), _named(str(p), p.open("rb"))  # decoded line by line
    except OSError as exc:
        raise InputError(f"{p}: cannot open ({exc.strerror})") from None


def _named(name: str, raw: io.BufferedReader) -> IO[bytes]:
    """``raw`` behind a :class:`_NamedReader` (a binary stream as ``open(..., "rb")``
    gives)."""
    return cast("IO[bytes]", _NamedReader(name, raw))


class _NamedReader(io.BufferedIOBase):
    """A binary stream whose read errors (an I/O error of the device, a file on a lost
    network share) are one-line :class:`InputError` naming the input: an OSError from
    a read carries no file name."""

    def __init__(self, name: str, raw: io.BufferedReader) -> None:
        self._name, self._raw = name, raw

    def _failed(self, exc: OSError) -> InputError:
        return InputError(f"{self._name}: cannot read ({exc.strerror or exc})")

    def read(self, size: int | None = -1, /) -> bytes:
        try:
            return self._raw.read(size)
        except OSError as exc:
            raise self._failed(exc) from None

    def read1(self, size: int = -1, /) -> bytes:
        try:
            return self._raw.read1(size)
        except OSError as exc:
            raise self._failed(exc) from None

    def readline(self, size: int | None = -1, /) -> bytes:
        try:
            return self._raw.readline(size)
        except OSError as exc:
            raise self._failed(exc) from None

    def readable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._raw.fileno()

    def close(self) -> None:
        self._raw.close()
        super().close()


class CutLineWarning(UserWarning):
    """The last line of an input has no line end: read as written, but a file cut off
    as it was written ends inside a number, which reads as another one."""


@dataclass
class CutLine:
    """The last line of an input that has no line end (a file cut off as it was
    written, or a writer that ends without one), once read: ``line`` its number (None
    until then, or where every line ends); ``checked`` where the reader of the rows
    says it itself (:mod:`~continuum_mhe.io.sample_rows`), else reading it warns
    (:func:`warn_cut_line`). It is read as written either way: a ``skip_bad`` that
    dropped it would drop a whole file's last row (a tensions file's, which the
    recording's last sample needs)."""

    line: int | None = None
    checked: bool = False


#: What a last line without a line end may be, for messages after ``line N:``.
CUT_LINE = (
    "the last line has no line end: if the file was cut off as it was written, its last "
    "value may be cut short"
)


def warn_cut_line(name: str, line: int) -> None:
    """Say (a :class:`CutLineWarning`) that line ``line`` of ``name``, the last, has no
    line end and is read as written."""
    warnings.warn(
        f"{name}: line {line}: {CUT_LINE} (read as written; end the line if it is whole, "
        "or remove it)",
        CutLineWarning,
        stacklevel=3,
    )


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
    cut: CutLine = field(default_factory=CutLine)

    @property
    def first_data_line(self) -> int:
        """The number of the line after the header (where the data rows start); the
        header's is the one before it."""
        return self._next_line

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


def read_line(fh: IO[bytes]) -> bytes:
    """One raw line with its end, at most :data:`MAX_LINE_BYTES` and its CRLF (``b""``
    at the end of the input)."""
    return fh.readline(MAX_LINE_BYTES + 2)


def decode_line(name: str, n: int, raw: bytes) -> str:
    """Line ``n``'s text without its end: a line over :data:`MAX_LINE_BYTES`, a CR-only
    line end, a NUL byte or bytes that are not UTF-8 are one-line errors naming it."""
    if n == 1 and raw.startswith(b"\xef\xbb\xbf"):  # a BOM (Excel) is fine
        raw = raw[3:]
    if n == 1:
        for magic, what in _PACKED:
            if raw.startswith(magic):
                raise InputError(f"{name}: line 1: not CSV text but {what}")
    body = raw.rstrip(b"\r\n") if raw.endswith(b"\n") else raw
    if b"\x00" in body:
        if n == 1 and (encoding := utf16_encoding(body)):
            raise InputError(f"{name}: line 1: not UTF-8 text but {UTF16.format(encoding)}")
        if n > 1 and b"\x00" not in body.rstrip(b"\x00"):
            raise InputError(
                f"{name}: line {n}: ends in NUL bytes, as a logger that stopped or restarted "
                f"mid-write leaves them: remove them (tr -d '\\000' < {shlex.quote(name)} > "
                "NEW.csv; a line they cut short is then refused, or skipped with --skip-bad)"
            )
        raise InputError(f"{name}: line {n}: contains a NUL byte (a binary file, not CSV)")
    # a binary file's bytes hold CRs too: said as not text, not as its line ends
    if b"\r" in body.rstrip(b"\r") and _text_like(body):
        raise InputError(
            f"{name}: line {n}: lines end in CR alone (classic Mac OS line ends); save "
            "the file with LF or CRLF line ends"
        )
    if len(body) > MAX_LINE_BYTES:
        raise InputError(f"{name}: line {n}: longer than {MAX_LINE_BYTES} bytes (not a CSV file?)")
    try:
        line = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(not_utf8_problem(name, n, body, exc.start, "NEW.csv")) from None
    return line.rstrip("\r")


def not_utf8_problem(name: str, n: int, body: bytes, start: int, new_name: str) -> str:
    """What to say of line ``n`` (its bytes ``body``) of the file ``name`` whose byte
    ``start`` (from 0) is no UTF-8: the byte, the character it is in Windows-1252 and
    the ``iconv`` command that converts the file to ``new_name``; or, where the line
    holds control bytes, that the file is no text."""
    if not _text_like(body):
        return f"{name}: line {n}: not UTF-8 text (a binary file?)"
    byte = body[start]
    return (
        f"{name}: line {n}: not UTF-8 text: byte {start + 1} of the line, 0x{byte:02X} "
        f"({bytes([byte]).decode('cp1252', 'replace')!r} in Windows-1252), text saved in "
        "an 8-bit encoding; save it as UTF-8 (iconv -f CP1252 -t UTF-8 "
        f"{shlex.quote(name)} > {new_name})"
    )


def _text_like(body: bytes) -> bool:
    """``body`` holds no control byte but tab and CR: text, in any 8-bit encoding (an
    old Mac file's MacRoman among them), not the bytes of a binary file."""
    return _CONTROL_BYTES.search(body) is None


#: The control bytes that text holds none of (tab, LF and CR aside).
_CONTROL_BYTES = re.compile(rb"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


#: What a file of UTF-16 text is told.
UTF16 = (
    'UTF-16 text (Excel\'s "Unicode Text"?): save it as "CSV UTF-8", or convert it '
    "(iconv -f {} -t UTF-8)"
)


def utf16_encoding(first: bytes) -> str:
    """The encoding for ``iconv`` of a first line of UTF-16 text (``UTF-16`` with its
    byte-order mark; without one, ``UTF-16LE`` or ``UTF-16BE`` where every other byte
    of an ASCII header is NUL), else ``""``."""
    if first.startswith((b"\xff\xfe", b"\xfe\xff")):
        return "UTF-16"
    even, odd = set(first[0::2]), set(first[1::2])
    if len(first) < 4:
        return ""
    if odd == {0} and 0 not in even:
        return "UTF-16LE"
    return "UTF-16BE" if even == {0} and 0 not in odd else ""


#: The first bytes of packed files that a CSV reader meets, and what each is.
_PACKED = (
    (b"\x1f\x8b", "a gzip file: decompress it first (gunzip)"),
    (b"PK\x03\x04", "a zip file (an Excel .xlsx?): unpack it, or save the sheet as CSV"),
    (b"\x89HDF", "an HDF5 file"),
    (b"\x7fELF", "a program"),
)


def _lines(name: str, fh: IO[bytes], cut: CutLine) -> Iterator[tuple[int, str]]:
    """``(line_number, text)`` of every line, whole and without its end
    (:func:`decode_line`); a last line without an end (LF, or CR before it) is noted in
    ``cut``."""
    n = 0
    while raw := read_line(fh):
        n += 1
        text = decode_line(name, n, raw)
        if not raw.endswith((b"\n", b"\r")):  # the input's end (a longer line is refused)
            cut.line = n
        yield n, text


def split_fields(text: str, separator: str) -> list[str]:
    """Fields of one line, stripped (quotes handled as in CSV; a line the CSV reader
    refuses, such as a quote beside a lone carriage return, is split as it is, and its
    fields are judged as any others)."""
    if '"' in text:
        try:
            return [c.strip() for c in next(csv.reader([text], delimiter=separator))]
        except csv.Error:
            pass
    return [c.strip() for c in text.split(separator)]


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


def _check_upper_t(name: str, line: int, header: list[str], written: list[str]) -> None:
    """One line for a header whose ``t`` is written ``T`` beside a column named as a
    time (``time``, ``timestamp``, ``time_ms``...): ``T`` is often a temperature, and the
    time would be read from it."""
    if "t" not in header or written[header.index("t")] != "T":
        return
    times = [w for h, w in zip(header, written) if h != "t" and _time_name(h) is not None]
    if times:
        raise InputError(
            f"{name}: line {line}: column 'T' is read as the time t, but the header has "
            f"{times[0]!r} too (and 'T' may be a temperature): name the time column t "
            "(seconds) or t_ms (milliseconds), and the other otherwise"
        )


#: the header a measurement file starts with, as the errors suggest it
MEASUREMENT_HEADER_HINT = "t,roll,pitch (or t_ms,ax,ay,az,gx,gy,gz)"


def open_rows(path: str | os.PathLike[str], header_hint: str = MEASUREMENT_HEADER_HINT) -> TextRows:
    """Open a text table once and read up to its header (see the module doc).

    Raises :class:`InputError` for a missing, empty, binary or header-less input (the
    message suggests ``header_hint``).
    """
    name, fh = _open(path)
    cut = CutLine()
    try:
        lines = _lines(name, fh, cut)
        comments: list[str] = []
        first: tuple[int, str] | None = None
        excel_sep = False  # Excel's first line "sep=;" names the separator: read past it
        for n, text in lines:
            s = text.strip()
            if s.startswith("#"):
                comments.append(s[1:].strip())
            elif first is None and not excel_sep and re.fullmatch(r"(?i) *sep=[,;\t] *", text):
                excel_sep = True
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
        _check_upper_t(name, n0, header, written)
        rows = _data_rows(name, lines, pending, sep, cut, tuple(header))
    except BaseException:
        fh.close()
        raise
    return TextRows(name, header, rows, sep, scale, comments, fh, pending, n0 + 1, written, cut)


def _data_rows(
    name: str,
    lines: Iterator[tuple[int, str]],
    pending: list[tuple[int, str]],
    sep: str,
    cut: CutLine,
    header: tuple[str, ...] = (),
) -> Iterator[tuple[int, list[str]]]:
    """The data rows of ``pending`` and ``lines``; a last data line without an end is
    said (:func:`warn_cut_line`) unless the reader says it (``cut.checked``), once the
    reader has taken it (asks for the row after it): a reader that refuses the row
    says that alone. A later comment that declares the ``header``'s columns in another
    order (``# fields:``, a device that restarted with other firmware, two captures
    joined) is an error naming its line: the rows after it would be read by place, each
    value as another column's."""
    for n, text in itertools.chain(pending, lines):
        s = text.strip()
        if s.startswith("#"):
            check_declared_again(name, n, s, header)
            continue
        if not s:
            continue
        yield n, split_fields(text, sep)
        if n == cut.line and not cut.checked:
            warn_cut_line(name, n)


def check_declared_again(name: str, line: int, comment: str, header: tuple[str, ...]) -> None:
    """Refuse a comment among the data rows that declares the ``header``'s columns (lower
    case, ``t_ms`` as ``t``) in another order."""
    names = declared_fields(comment)
    if names is None or not header:
        return
    again = tuple("t" if f.lower() == "t_ms" else f.lower() for f in names)
    if again != header and sorted(again) == sorted(header):
        raise InputError(
            f"{name}: line {line}: '{shorten(comment, 80)}' declares the columns in another "
            f"order than the header in force ({','.join(header)}): the rows after it would be "
            "read as each other's columns (a device restarted with other firmware, or two "
            "captures joined?); split the file there"
        )


#: header names a recording's time column often has elsewhere; the files here name it ``t``
TIME_LIKE_NAMES = frozenset(
    {"time", "times", "timestamp", "stamp", "time_s", "t_s", "sec", "secs", "seconds"}
)

#: header names of a time column in milliseconds, which the files here name ``t_ms``
MS_TIME_LIKE_NAMES = frozenset(
    {"time_ms", "timestamp_ms", "stamp_ms", "ms", "millis", "t_millis", "time_millis"}
)


#: header names of a time column in microseconds or nanoseconds, which the files here
#: give in seconds (``t``) or milliseconds (``t_ms``)
FINE_TIME_LIKE_NAMES = frozenset(
    {
        "t_us", "t_ns", "time_us", "time_ns", "timestamp_us", "timestamp_ns", "stamp_us",
        "stamp_ns", "us", "ns", "micros", "nanos", "time_micros", "time_nanos",
    }
)  # fmt: skip

#: the units a time column's name may carry, by the column this reader names it
_SECOND_UNITS = frozenset({"", "s", "sec", "secs", "second", "seconds"})
_MILLISECOND_UNITS = frozenset({"ms", "msec", "millisecond", "milliseconds"})

#: a unit in parentheses or brackets after a column's name (``x [m]``, ``Time (s)``)
_NAME_AND_UNIT = re.compile(r"(.+?)\s*[\[(]\s*([^\])]*?)\s*[\])]")


def name_and_unit(column: str) -> tuple[str, str]:
    """``("x", "m")`` for a header column ``x [m]`` or ``x (m)``; ``(column, "")`` for
    one without a unit in parentheses or brackets."""
    m = _NAME_AND_UNIT.fullmatch(column)
    return (m.group(1), m.group(2).lower()) if m else (column, "")


def _time_name(column: str) -> str | None:
    """The name this package gives a header's time column (``time``, ``Time (s)``,
    ``t [ms]``): ``t`` (seconds) or ``t_ms`` (milliseconds); ``""`` for one in
    microseconds or nanoseconds (neither); None for a column not named as a time."""
    base, unit = name_and_unit(column.lower())
    if base in FINE_TIME_LIKE_NAMES:
        return ""
    if base in MS_TIME_LIKE_NAMES or base == "t_ms":
        return "t_ms" if unit in _SECOND_UNITS | _MILLISECOND_UNITS else None
    if base == "t" or base in TIME_LIKE_NAMES:
        if unit in _MILLISECOND_UNITS:
            return "t_ms"
        if unit in _SECOND_UNITS:
            return "t"
        return "" if unit in ("us", "\u00b5s", "ns", "usec", "nsec") else None
    return None


def _unit_renames(rows: TextRows, missing: Sequence[str]) -> list[str]:
    """``'x [m]' to x`` for each header column that is a ``missing`` column (or the
    time) with a unit in parentheses or brackets after its name, which is not read."""
    renames = []
    for column in rows.header:
        base, unit = name_and_unit(column)
        if not unit:
            continue
        name = _time_name(column) if "t" in missing else None
        if name is None and base in missing:
            name = base
        if name:
            renames.append(f"{rows.as_written(column)!r} to {name}")
    return renames


def _time_hint(rows: TextRows) -> str:
    """What a header without ``t`` is told of its time column: the name to give a column
    named otherwise (``time``: ``t``; ``time_ms``: ``t_ms``), that microseconds or
    nanoseconds are to be given in seconds, or that an unnamed column (an index, as
    pandas writes one) is no time; ``""`` where it has none of these."""
    for column in rows.header:
        name = _time_name(column)
        shown = rows.as_written(column)
        if name == "t":
            return f" (the time in seconds is named t: rename {shown!r} to t)"
        if name == "t_ms":
            return f" (a time in milliseconds is named t_ms: rename {shown!r} to t_ms)"
        if name == "":
            return (
                f" ({shown!r} is a time in microseconds or nanoseconds? give it in seconds, "
                "as t, or in milliseconds, as t_ms)"
            )
    if rows.header and rows.header[0] == "":
        return (
            " (a column without a name, as pandas writes its index: the time in seconds "
            "is named t; pandas' to_csv(..., index=False) leaves the index out)"
        )
    return ""


#: the columns that IMU readings have (tilt or raw, first IMU or only one)
_READING_COLUMNS = frozenset({"roll", "pitch", "ax", "roll_1", "pitch_1", "ax_1"})

#: What reads IMU readings, in the hint where an estimate or truth is given for them:
#: ``estimate``'s; ``calibrate`` puts its own in its place
READINGS_READER = "estimate reads a recording of the IMUs"


def _other_kind_of_file(header: Sequence[str], missing: Sequence[str]) -> str:
    """A hint where the table read for IMU readings is another kind of file: a robot
    file (TOML: its first line a ``key = value``, or a ``[table]``) or an estimate or
    truth (tip columns x, y, z); else ""."""
    first = header[0] if header else ""
    if "=" in first or first.startswith("["):
        return " (a robot file? it is given with --robot ROBOT.toml)"
    if _READING_COLUMNS & set(missing) and {"x", "y", "z"} <= set(header):
        return (
            f" (an estimate or truth table, not IMU readings: {READINGS_READER}; "
            "continuum-mhe evaluate EST.csv TRUTH.csv scores an estimate)"
        )
    return ""


#: The missing columns a header error names (the rest are counted).
MISSING_SHOWN = 12


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
        elif not hint and (renames := _unit_renames(rows, missing)):
            shown = ", ".join(renames[:3]) + (", ..." if len(renames) > 3 else "")
            hint = f" (a unit in a column's name is not read: rename {shown})"
        elif not hint and "t" in missing:
            hint = _time_hint(rows)
        shown = ", ".join(missing)
        if len(missing) > MISSING_SHOWN:
            shown = f"{', '.join(missing[:MISSING_SHOWN])} and {len(missing) - MISSING_SHOWN} more"
        raise InputError(f"{rows.name}: line 1: missing column(s) {shown} "
                         f"(header has: {has}){hint}")  # fmt: skip
    return [rows.header.index(c) for c in required]


#: A field that is a unit, as a row of units under a header holds them (``s``,
#: ``m/s^2``, ``[rad/s]``, ``deg``, ``N``).
_UNIT_TEXT = re.compile(
    r"[\[(]?\s*(?:s|sec|ms|us|\u00b5s|ns|m|mm|cm|rad|deg|\u00b0|n|mn|g|mg|m/s\^?2|m/s\u00b2"
    r"|m/s/s|rad/s|deg/s|\u00b0/s|dps|mps2|c|\u00b0c|degc)\s*[\])]?",
    re.IGNORECASE,
)
#: A date and time, or a time of day (``2026-03-04T10:15:00.020``, ``10:15:00``).
_DATE_TIME = re.compile(r"\d{4}-\d{2}-\d{2}[T ]\d{1,2}:\d{2}|\d{1,2}:\d{2}:\d{2}")


def parse_float(name: str, line: int, column: str, text: str) -> float:
    """``float(text)`` or a one-line :class:`NotANumberError` naming file, line and
    column."""
    try:
        return to_float(text)
    except ValueError:
        shown = shorten(text, 20)
        hint = ""
        if "," in text and _is_number(text.replace(",", ".", 1)):
            hint = " (a decimal comma? use a point, e.g. 0.5)"
        elif column in ("t", "t_ms") and text.strip().strip('"').lower() == column:
            hint = " (the header again: two files joined?)"
        elif _UNIT_TEXT.fullmatch(text.strip().strip('"')):
            hint = " (a row of units under the header? remove it: each column's unit is fixed)"
        elif column in ("t", "t_ms") and _DATE_TIME.match(text.strip().strip('"')):
            unit = "seconds" if column == "t" else "milliseconds"
            hint = f" (a date and time: {column} is a number of {unit}, such as since the start)"
        raise NotANumberError(
            name, line, f"column {column}: {shown!r} is not a number{hint}"
        ) from None
