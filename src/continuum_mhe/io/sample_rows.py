"""Validated samples of a sample table (:mod:`~continuum_mhe.io.text_rows`' rows): the time
and the readings of each row checked and converted, row by row (:func:`read_samples`) or
a block of rows at a time (:func:`sample_blocks`, the same values, errors and problems);
bad rows counted (:class:`RowProblems`) where ``skip_bad`` keeps or drops them.
"""

from __future__ import annotations

import math
import os
import re
import stat
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import IO

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, NotANumberError, time_text
from continuum_mhe.io.text_rows import (
    MAX_LINE_BYTES,
    TextRows,
    check_declared_again,
    column_indices,
    decode_line,
    parse_float,
    shorten,
    split_fields,
    warn_cut_line,
)

#: ``millis()`` (a board's ``t_ms``) wraps at this many ms.
MILLIS_WRAP = 2**32
#: A step back from the last ``WRAP_WINDOW_MS`` before the wrap into the first ones
#: after it is a wrap, not a restart.
WRAP_WINDOW_MS = 60_000.0


def millis_wrapped(last_ms: float, t_ms: float) -> bool:
    """Whether a board's ``t_ms`` after ``last_ms`` (both ms as ``millis()`` counts
    them, the last not unwrapped) is the counter's wrap: from its last
    :data:`WRAP_WINDOW_MS` before :data:`MILLIS_WRAP` into its first ones after."""
    return (
        last_ms >= MILLIS_WRAP - WRAP_WINDOW_MS
        and 0 < t_ms + MILLIS_WRAP - last_ms <= WRAP_WINDOW_MS
    )


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


def read_samples(
    rows: TextRows,
    columns: Sequence[str],
    *,
    skip_bad: bool = False,
    empty_is_dropout: bool = False,
    problems: RowProblems | None = None,
    skip_hint: str | None = None,
) -> list[tuple[int, float, list[float]]]:
    """Validated ``(line, t, values)`` of every row of a sample table whose
    ``columns[0]`` is the time ``t`` (converted to s).

    A missing, non-numeric or non-finite value is an error, or with ``skip_bad`` a
    dropout (NaN, row kept); so is a row with fewer or more fields than the header
    (every value of a row with an extra field is a dropout: which one is extra is
    unknown); a bad, duplicate or decreasing ``t`` is an error, or with ``skip_bad`` the
    row is dropped, unless the row before it jumped ahead alone (:meth:`_SampleChecks.
    _retracted_jump`), which is dropped instead; each skip is counted in ``problems``.
    With ``empty_is_dropout`` an empty value is a dropout without complaint.
    ``skip_hint``: what the error of a non-finite value says ``--skip-bad`` does with
    it (default :data:`DROPOUT_HINT`).
    """
    checks = _SampleChecks(
        rows, columns, skip_bad, empty_is_dropout, problems, skip_hint or DROPOUT_HINT
    )
    out: list[tuple[int, float, list[float]]] = []

    def retract(line: int) -> bool:
        if out and out[-1][0] == line:
            out.pop()
            return True
        return False

    checks.retract = retract
    for sample in checks.rows(rows.rows):  # one at a time: retract sees the last one
        out.append(sample)
    checks.finish()
    return out


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
    """The samples of :func:`read_samples`, the same values, errors and ``problems``,
    as blocks of ``size`` rows (the last one shorter, and a block shorter wherever a
    read took all that the input had, the first one once it holds
    :data:`FIRST_STREAMED_ROWS`: a pipe whose writer is behind gets its rows
    estimated as they come); reads ``rows``' input itself
    (``rows.rows`` is not to be used as well).

    The lines are read :data:`BLOCK_BYTES` at a time and parsed as a block by numpy's
    :func:`numpy.loadtxt` when the block's text can only mean what the row-by-row reading
    finds in it: ASCII digits, signs, points and exponents, separators and blanks; every
    data line with the header's number of fields; finite values, empty ones only where
    they are dropouts; ``t`` increasing. Any other block is read row by row, as
    :func:`read_samples` reads it, so a problem is reported exactly as there (file, line,
    what is wrong), after the samples before it.
    """
    checks = _SampleChecks(rows, columns, skip_bad, empty_is_dropout, problems)
    pieces: list[SampleBlock] = []
    loose: list[tuple[int, float, list[float]]] = []  # rows read one at a time
    count = 0
    given = 0  # blocks yielded

    def retract(line: int) -> bool:  # the last row read, if not yet yielded
        nonlocal count
        if loose and loose[-1][0] == line:
            loose.pop()
        elif not loose and pieces and pieces[-1].lines[-1:] == [line]:
            pieces[-1] = _part(pieces[-1], 0, len(pieces[-1]) - 1)
        else:
            return False
        count -= 1
        return True

    checks.retract = retract
    for item in checks.blocks():
        if isinstance(item, _Drained):  # the input has nothing more for now: estimate what came
            if given == 0 and count < min(size, FIRST_STREAMED_ROWS):
                continue  # the first block's checks (units, mounting) need rows enough
            if loose:
                pieces.append(_block_of(loose, len(columns) - 1))
                loose = []
            if pieces:
                yield _joined(pieces)
                given += 1
            pieces, count = [], 0
            continue
        if isinstance(item, SampleBlock):
            pieces += [_block_of(loose, len(columns) - 1), item] if loose else [item]
            loose = []
            count += len(item)
        else:
            loose.append(item)
            count += 1
        # as soon as a block is complete and a row after it has come (the block's last
        # row may yet be taken back, a time that jumped ahead): errors after it come later
        while count > size:
            if loose:
                pieces.append(_block_of(loose, len(columns) - 1))
                loose = []
            whole = _joined(pieces)
            yield _part(whole, 0, size)
            given += 1
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


def _other_separator(text: str, width: int, sep: str) -> str | None:
    """The separator other than ``sep`` that splits a row's ``text`` (one field by
    ``sep``) into the header's ``width`` fields, if one does: a file whose header and
    rows were written with different separators."""
    return next((c for c in (",", ";", "\t") if c != sep and text.count(c) == width - 1), None)


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


#: Rows the first block of a pipe holds at least (where the input has as many) before a
#: read that took all the pipe had hands it on: the checks of a recording's first block
#: (its time unit, an IMU's units over at least 100 readings, the mounting) judge it.
FIRST_STREAMED_ROWS = 256


class _Drained:
    """The mark :meth:`_SampleChecks.blocks` gives after a read that took all the input
    had."""


_DRAINED = _Drained()

#: What a non-finite value's error says ``--skip-bad`` does with a sensor's reading.
DROPOUT_HINT = "a dropout; --skip-bad keeps it, skip_bad=True in Python"


class _SampleChecks:
    """The checks of :func:`read_samples` over one table, row by row or a block at a
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
        #: takes back the last sample given, by its line, where it has not been handed
        #: on yet (True); :func:`sample_blocks` and :func:`read_samples` set it: with
        #: ``skip_bad`` a time that jumped ahead alone is dropped, not every row after it
        self.retract: Callable[[int], bool] | None = None
        self.last_t = -math.inf
        self.first_t = math.nan  # the first sample's time
        #: a ``t_ms`` column's ``millis()`` wraps seen (2^32 ms each), unwrapped as
        #: ``live`` unwraps them: a plain capture of the serial line across a wrap
        self.wraps = 0
        self.last_line = 0  # the line of the last sample given
        self.before_last_t = -math.inf  # the time of the sample given before it
        self.last_bad = -1
        self.n_rows = 0  # data rows read
        self.n_out = 0  # samples given
        #: an empty or blank field (a dropout where ``empty_is_dropout``)
        self.empty_field = empty_field_pattern(rows.separator.encode())
        rows.cut.checked = True  # a last line without an end: said by rows()

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
        # a separator at the header's end names no column: rows without it are whole
        named = width
        while named > 1 and self.table.header[named - 1].strip() == "":
            named -= 1
        sep = self.table.separator
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
            if len(row) == 1 < width and (other := _other_separator(row[0], width, sep)):
                bad(line, f"fields separated by {other!r}, the header's by {sep!r}", dropped=True)
                continue
            try:
                raw_t = parse_float(name, line, shown[0], row[idx[0]])
            except NotANumberError as exc:
                bad(line, exc.problem, dropped=True)
                continue
            t = (raw_t + self.wraps * MILLIS_WRAP) * scale
            if not math.isfinite(t):
                bad(line, f"{shown[0]} is {row[idx[0]]}", dropped=True)
                continue
            last_ms = self.last_t / scale - self.wraps * MILLIS_WRAP  # as the board counts
            before_ms = self.before_last_t / scale - self.wraps * MILLIS_WRAP
            if (
                t <= self.last_t
                and scale == 1e-3
                and millis_wrapped(last_ms, raw_t)
                and before_ms >= MILLIS_WRAP - WRAP_WINDOW_MS  # the counter got there itself
            ):
                # millis() wrapped (every 49.7 days): the time goes on, as live takes it;
                # not after one t that jumped there alone (a corrupted stamp, -1 as uint32)
                self.wraps += 1
                t = (raw_t + self.wraps * MILLIS_WRAP) * scale
            if t <= self.last_t and self._retracted_jump(t):
                pass  # the row before jumped ahead alone, and is dropped instead
            elif t <= self.last_t:
                kind = "duplicate" if t == self.last_t else "decreasing"
                msg = (
                    f"{kind} timestamp t={time_text(t)} after t={time_text(self.last_t)} "
                    f"on line {self.last_line} (t must strictly increase)"
                )
                before = self.before_last_t
                if before > -math.inf and before < t < self.last_t - (t - before):
                    # line last_line jumped ahead alone: further past the row before it
                    # than this row is from that one, twice over
                    msg += (
                        f"; line {self.last_line}'s t jumps ahead of the rows around it "
                        f"(t={time_text(self.before_last_t)} before it): is it the wrong "
                        "one? every later row before its t is refused too"
                    )
                elif t < self.last_t and t <= self.first_t:
                    msg += (
                        f"; the file's first t is {time_text(self.first_t)}: two recordings "
                        "joined, or a logger restarted? split the file there"
                    )
                if len(row) < width:  # a torn row: its t may be a piece of another
                    msg += f"; the row has {len(row)} of the header's {width} fields (truncated?)"
                bad(line, msg, dropped=True)
                continue
            vals: list[float] = []
            for col, j in zip(shown[1:], idx[1:]):
                if extra:
                    self.problems.whole += 1
                    vals = [math.nan] * (len(columns) - 1)
                    break
                # a field missing, even one no estimator reads: which one is unknown, and
                # every value after it may be its neighbour's (a last line without its
                # line end that holds every column read is read as written, with the
                # warning that it may be cut)
                if j >= len(row) or (len(row) < named and line != self.table.cut.line):
                    bad(line, truncated.format(width, len(row)))
                    self.problems.whole += 1
                    vals = [math.nan] * (len(columns) - 1)
                    break
                if self.empty_is_dropout and row[j] == "":
                    vals.append(math.nan)
                    continue
                try:
                    v = parse_float(name, line, col, row[j])
                except NotANumberError as exc:
                    empty = row[j] == ""  # a missing value, which --skip-bad leaves out
                    bad(line, f"column {col} is empty ({self.skip_hint})" if empty
                        else exc.problem)  # fmt: skip
                    v = math.nan
                else:
                    if not math.isfinite(v):
                        bad(
                            line,
                            f"column {col} is {shorten(row[j])} ({self.skip_hint})",
                        )
                        v = math.nan  # with --skip-bad: a dropout, as the message says
                vals.append(v)
            self.before_last_t, self.last_t, self.last_line = self.last_t, t, line
            if self.n_out == 0:
                self.first_t = t
            self.n_out += 1
            if line == self.table.cut.line:  # read as written: its last value may be cut short
                warn_cut_line(self.table.name, line)
            yield line, t, vals

    def _retracted_jump(self, t: float) -> bool:
        """With ``skip_bad``, where the last sample given jumped ahead of the samples
        around it (``t``, the next row's time, lies after the one before it) and could be
        taken back (:attr:`retract`): count it as a bad row, dropped, and go on from the
        sample before it (True)."""
        before, last = self.before_last_t, self.last_t
        if not (self.skip_bad and self.retract is not None and before < t < last):
            return False
        # a jump: the last sample lies further past the one before it than twice the
        # span from that one to this row (two steps); not a row that stepped back a little
        jumped = before > -math.inf and last - before > 2.0 * (t - before)
        if not jumped or self.last_bad == self.last_line or not self.retract(self.last_line):
            return False  # (a row already counted bad is left as it was counted)
        self.problems.add(
            f"line {self.last_line}: t={time_text(self.last_t)} jumps ahead of the rows "
            f"around it (t={time_text(self.before_last_t)} before it, {time_text(t)} after "
            "it): dropped"
        )
        self.problems.dropped += 1
        self.n_out -= 1
        self.last_t, self.before_last_t = self.before_last_t, -math.inf
        return True

    def blocks(self) -> Iterator[SampleBlock | tuple[int, float, list[float]] | _Drained]:
        """The table's samples, read from its input: a :class:`SampleBlock` for each
        block of lines parsed whole, one ``(line, t, values)`` at a time for the others,
        and :data:`_DRAINED` after the lines of a read that took all the input had (a
        pipe whose writer is slower than the reader)."""
        table = self.table
        yield from self.rows(iter([(n, split_fields(text, table.separator))
                                   for n, text in table._pending]))  # fmt: skip
        assert table._stream is not None, "sample_blocks reads an open table"
        for first, text, drained in _line_blocks(table._stream, table._next_line):
            if text and not text.endswith((b"\n", b"\r")):  # the input's last line, no end
                table.cut.line = first + text.count(b"\n")
            block = None if table.cut.line is not None else self._parse(text, first)
            if block is None:
                yield from self.rows(
                    _split_rows(table.name, text, first, table.separator, tuple(table.header))
                )
            elif len(block):
                yield block
            if drained:
                yield _DRAINED

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
        t = (values[:, 0] + self.wraps * MILLIS_WRAP) * table.time_scale
        if np.isinf(values).any() or not np.isfinite(t).all():
            return None
        if not (t[0] > self.last_t and (t[1:] > t[:-1]).all()):
            return None
        if not self.empty_is_dropout and np.isnan(values).any():
            return None
        self.before_last_t = float(t[-2]) if len(t) > 1 else self.last_t
        self.last_t, self.last_line = float(t[-1]), int(numbers[-1])
        if self.n_out == 0:
            self.first_t = float(t[0])
        self.n_rows += len(t)
        self.n_out += len(t)
        return SampleBlock(list(numbers), t, np.ascontiguousarray(values[:, 1:]))

    def finish(self) -> None:
        """The errors of a table without samples, once it is read."""
        if self.n_rows == 0:
            line = self.table.first_data_line - 1  # the header's
            raise InputError(
                f"{self.table.name}: line {line}: the header has no data rows after it"
            )
        if self.n_out == 0:
            raise InputError(f"{self.table.name}: no usable rows ({self.problems.count} skipped)")


def _has_blank_line(body: bytes) -> bool:
    """Whether the lines ``body`` (without the last one's end) have a blank one."""
    if not body or body.startswith(b"\n") or body.endswith(b"\n") or b"\n\n" in body:
        return True
    return (b" " in body or b"\t" in body) and _BLANK_LINE.search(body) is not None


def _line_blocks(fh: IO[bytes], first: int) -> Iterator[tuple[int, bytes, bool]]:
    """``(number of the first line, text, drained)`` of the rest of ``fh`` in blocks of
    whole lines of about :data:`BLOCK_BYTES` (the last line of the input may have no
    end; a line longer than :data:`MAX_LINE_BYTES` comes in a block of its own, cut);
    ``drained``: the read got less than it asked for, all that the input had then (a
    pipe's writer is behind: what came is to be used before the next read waits)."""
    rest = b""
    # what has arrived, up to the size asked (a pipe's reader gets the lines written so
    # far instead of waiting for a whole block)
    read = getattr(fh, "read1", fh.read)
    # a file's short read is its end, which the next read shows: only a pipe, FIFO or
    # terminal is drained (a block handed on early would not be known as the last)
    try:
        streamed = not stat.S_ISREG(os.fstat(fh.fileno()).st_mode)
    except (AttributeError, OSError, ValueError):  # not a file descriptor (in memory)
        streamed = False
    while True:
        asked = max(BLOCK_BYTES, len(rest))  # a long line: reads that double
        data = read(asked)
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
        yield first, text, streamed and 0 < len(data) < asked
        first += text.count(b"\n")


def _split_rows(
    name: str, text: bytes, first: int, sep: str, header: tuple[str, ...] = ()
) -> Iterator[tuple[int, list[str]]]:
    """The data rows of the lines ``text`` (numbered from ``first``) read one at a time,
    as :attr:`TextRows.rows` reads them (a line cut where :func:`read_line` cuts it; a
    comment that declares the ``header``'s columns in another order refused)."""
    lines = text.split(b"\n")
    last = lines.pop()  # the text after the last line end: a line without one, or b""
    raw = [ln + b"\n" for ln in lines] + ([last] if last else [])
    for n, line in enumerate(raw, start=first):
        text_line = decode_line(name, n, line[: MAX_LINE_BYTES + 2])
        s = text_line.strip()
        if s.startswith("#"):
            check_declared_again(name, n, s, header)
        elif s:
            yield n, split_fields(text_line, sep)
