"""The block reader of sample tables (:func:`~continuum_mhe.io.sample_rows.sample_blocks`,
numpy's ``loadtxt`` over blocks of lines) against the row-by-row reader
(:func:`~continuum_mhe.io.sample_rows.read_samples`): the same samples to the bit, the
same problems counted, the same one-line error, on tricky inputs and on random text."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from continuum_mhe.errors import InputError
from continuum_mhe.io import sample_rows, text_rows
from continuum_mhe.io.sample_rows import RowProblems, read_samples, sample_blocks
from continuum_mhe.io.text_rows import open_rows

Outcome = tuple[Any, ...]


def _by_rows(path: Path, columns: tuple[str, ...], **kw: bool) -> Outcome:
    problems = RowProblems(keep=1000)
    try:
        with open_rows(path) as rows:
            got = read_samples(rows, columns, problems=problems, **kw)
    except InputError as exc:
        return ("error", str(exc), len(problems.first))
    lines = [g[0] for g in got]
    t = np.array([g[1] for g in got])
    values = np.array([g[2] for g in got]).reshape(len(got), len(columns) - 1)
    return _outcome(lines, t, values, problems)


def _by_blocks(path: Path, columns: tuple[str, ...], size: int, **kw: bool) -> Outcome:
    problems = RowProblems(keep=1000)
    lines: list[int] = []
    t, values = [np.empty(0)], [np.empty((0, len(columns) - 1))]
    try:
        with open_rows(path) as rows:
            for block in sample_blocks(rows, columns, size, problems=problems, **kw):
                assert 0 < len(block) <= size
                lines += block.lines
                t.append(block.t)
                values.append(block.values)
    except InputError as exc:
        return ("error", str(exc), len(problems.first))
    return _outcome(lines, np.concatenate(t), np.vstack(values), problems)


def _outcome(lines: list[int], t: np.ndarray, values: np.ndarray, problems: RowProblems) -> Outcome:
    # bit patterns: NaN equals NaN, -0.0 differs from 0.0
    return (lines, t.tobytes(), values.tobytes(), problems.count, problems.dropped, problems.first)


def _same(tmp_path: Path, text: bytes | str, columns: tuple[str, ...] = ("t", "roll", "pitch"),
          **kw: bool) -> Outcome:  # fmt: skip
    path = tmp_path / "in.csv"
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    expected = _by_rows(path, columns, **kw)
    for size in (1, 3, 4096):
        assert _by_blocks(path, columns, size, **kw) == expected, size
    return expected


@pytest.fixture(autouse=True)
def _small_line_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Blocks of a few lines, so that a problem falls in the middle of the input, with
    blocks read whole before it and after it."""
    monkeypatch.setattr(sample_rows, "BLOCK_BYTES", 40)


ROW_LIST = [f"{0.05 * i:.10g},{0.01 * i:.10g},{-0.02 * i:.10g}\n" for i in range(20)]
ROWS = "".join(ROW_LIST)
TRICKY = {
    "plain": "t,roll,pitch\n" + ROWS,
    "crlf": ("t,roll,pitch\n" + ROWS).replace("\n", "\r\n"),
    "no final line end": "t,roll,pitch\n" + ROWS.rstrip("\n"),
    "comments and blank lines": (
        "# a\nt,roll,pitch\n" + "".join(ROW_LIST[:2]) + "\n  \n# x 1\n\t\n" + "".join(ROW_LIST[2:])
    ),
    "spaces around fields": "t , roll , pitch\n" + ROWS.replace(",", " , "),
    "exponents and signs": "t,roll,pitch\n0,1e-3,+.5\n1.,-1E-02,5e+0\n2,0001,-0\n",
    "nan": "t,roll,pitch\n" + ROWS + "1.5,nan,0.1\n1.6,0.1,0.1\n",
    "a missing field": "t,roll,pitch\n0,0.1,0.1\n0.05,0.1\n0.1,0.1,0.1\n",
    "an empty field": "t,roll,pitch\n0,0.1,0.1\n0.05,,0.1\n0.1,0.1,0.1\n",
    "an extra field": "t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1,7\n0.1,0.1,0.1\n",
    "a trailing separator": "t,roll,pitch\n0,0.1,0.1,\n0.05,0.1,0.1,\n",
    "an unused column": "t,roll,pitch,note\n0,0.1,0.1,\n0.05,0.1,0.1,x\n0.1,0.1,0.1\n",
    "decreasing t": "t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1\n0.05,0.1,0.1\n0.01,0.1,0.1\n0.2,0,0\n",
    "decreasing t across blocks": "t,roll,pitch\n" + ROWS + "0.5,0.1,0.1\n",
    "an overflow": "t,roll,pitch\n0,0.1,0.1\n0.05,1e999,0.1\n0.1,0.1,0.1\n",
    "infinite t": "t,roll,pitch\n0,0.1,0.1\n1e400,0.1,0.1\n",
    "text": "t,roll,pitch\n0,0.1,0.1\n0.05,abc,0.1\n0.1,0.1,0.1\n",
    "a quoted number": 't,roll,pitch\n0,0.1,0.1\n0.05,"0.3",0.1\n0.1,0.1,0.1\n',
    "underscores": "t,roll,pitch\n0,0.1,0.1\n0.05,1_0,0.1\n",
    "a decimal comma": "t;roll;pitch\n0;0,1;0,1\n0,05;0,1;0,1\n",
    "semicolons": "t;roll;pitch\n" + ROWS.replace(",", ";"),
    "an Excel sep line": "sep=;\nt;roll;pitch\n" + ROWS.replace(",", ";"),
    "an Excel sep line, tabs": "sep=\t\nt\troll\tpitch\n" + ROWS.replace(",", "\t"),
    "tabs": "t\troll\tpitch\n" + ROWS.replace(",", "\t"),
    "t in ms": "t_ms,roll,pitch\n" + "".join(f"{10 * i},0.1,0.2\n" for i in range(9)),
    "a lone e": "t,roll,pitch\n0,0.1,0.1\n0.05,e,0.1\n",
    "a point alone": "t,roll,pitch\n0,0.1,0.1\n0.05,.,0.1\n",
    "a space inside a number": "t,roll,pitch\n0,0.1,0.1\n0.05,1 2,0.1\n",
    "a firmware capture": "# fields: t_ms,roll,pitch\n0,0.1,0.1\n20,0.1,0.1\n40,0.1,0.2\n",
    "header only": "t,roll,pitch\n\n\n",
}


@pytest.mark.parametrize("skip_bad", [False, True])
@pytest.mark.parametrize("name", sorted(TRICKY))
def test_block_reader_matches_the_row_reader(tmp_path: Path, name: str, skip_bad: bool) -> None:
    _same(tmp_path, TRICKY[name], skip_bad=skip_bad)


def test_the_block_reader_reads_what_it_should(tmp_path: Path) -> None:
    """Known answers: the tricky inputs read, not only read alike."""
    lines, t, *_ = _same(tmp_path, TRICKY["an Excel sep line"])
    assert lines == list(range(3, 23))  # Excel's "sep=;" line names the separator
    assert np.frombuffer(t) == pytest.approx(0.05 * np.arange(20))
    lines, t, values, *_ = _same(tmp_path, TRICKY["comments and blank lines"])
    assert lines == [3, 4, *range(9, 27)]  # the comment and blank lines are skipped
    assert np.frombuffer(t) == pytest.approx(0.05 * np.arange(20))
    lines, t, values, *_ = _same(tmp_path, TRICKY["t in ms"])
    assert np.frombuffer(t) == pytest.approx(0.01 * np.arange(9))
    error = _same(tmp_path, TRICKY["an overflow"])
    assert error[:2] == ("error", f"{tmp_path / 'in.csv'}: line 3: column roll is 1e999 (a "
                                  "dropout; --skip-bad keeps it, skip_bad=True in "
                                  "Python)")  # fmt: skip


def test_a_last_line_without_an_end_is_read_and_said(tmp_path: Path) -> None:
    """A file cut off as it was written ends inside a number (``0.19`` of ``0.19,...``
    read as ``0.1``): its last line, without a line end, is read as written with a
    warning that names it, by either reader, with ``skip_bad`` too (a whole file's
    last row is needed: a tensions file's covers the recording's end). A CR before the
    cut ends the line."""
    from continuum_mhe.io.text_rows import CutLineWarning

    text = TRICKY["no final line end"]
    for skip_bad in (False, True):
        with pytest.warns(CutLineWarning, match=r"in.csv: line 21: the last line has no line"):
            lines, t, _, count, *_ = _same(tmp_path, text, skip_bad=skip_bad)
        assert lines == list(range(2, 22)) and count == 0
        assert np.frombuffer(t)[-1] == pytest.approx(0.05 * 19)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lines, *_ = _same(tmp_path, text + "\r")
    assert lines == list(range(2, 22))


TWO_IMUS = ("t", "roll_1", "pitch_1", "roll_2", "pitch_2")


@pytest.mark.parametrize("skip_bad", [False, True])
@pytest.mark.parametrize(
    "body",
    [
        "0,0.1,0.1,0.2,0.2\n0.05,,,0.2,0.2\n0.1,0.1,0.1, , \n0.15,0.1,,0.2,0.2\n",
        ",0.1,0.1,0.2,0.2\n0.05,0.1,0.1,0.2,0.2\n",  # an empty t
        "0,0.1,0.1,0.2,0.2\n0.05,0.1,0.1,0.2,\n0.1,0.1,0.1,0.2\n",  # a missing last field
        "0,0.1,0.1,0.2,0.2\r\n0.05,,,,\r\n\r\n0.1,0.1,0.1,0.2,0.2\r\n",
    ],
)
def test_empty_fields_are_dropouts_of_several_imus(
    tmp_path: Path, body: str, skip_bad: bool
) -> None:
    _same(tmp_path, ",".join(TWO_IMUS) + "\n" + body, TWO_IMUS, skip_bad=skip_bad,
          empty_is_dropout=True)  # fmt: skip


def test_a_dropout_of_several_imus_is_nan(tmp_path: Path) -> None:
    text = ",".join(TWO_IMUS) + "\n0,0.1,0.1,0.2,0.2\n0.05, ,,0.2,0.2\n"
    _, _, values, *_ = _same(tmp_path, text, TWO_IMUS, empty_is_dropout=True)
    got = np.frombuffer(values).reshape(2, 4)
    assert np.isnan(got[1, :2]).all() and (got[1, 2:] == 0.2).all()


@pytest.mark.parametrize("line", [b"0.1,0.1,0.1" + b"0" * (text_rows.MAX_LINE_BYTES) + b"\n",
                                  b"0.1,\x000.1,0.1\n", b"0.1,0.1,\xff\n", b"0.1,0.1,0.1\r0.2\n",
                                  b"0.1,0.1,\xef\xbc\x91\n"])  # fmt: skip
def test_lines_refused_whole_are_refused_alike(tmp_path: Path, line: bytes) -> None:
    """A line too long, a NUL byte, bytes that are not UTF-8, a CR alone, a fullwidth
    digit: the same one-line error from either reader."""
    outcome = _same(tmp_path, b"t,roll,pitch\n0,0.1,0.1\n" + line + b"0.2,0.1,0.1\n")
    assert outcome[0] == "error"


# random text of the characters that matter to either reader
_CHARS = '0123456789.,e+-  \n\n\n\r\t#n_"a;'


@settings(
    max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(body=st.text(_CHARS, max_size=120), skip_bad=st.booleans(), dropouts=st.booleans())
@example(body="1", skip_bad=False, dropouts=True)  # a last line of its t alone, without an end
@example(body="1", skip_bad=False, dropouts=False)
def test_random_text_reads_alike(tmp_path: Path, body: str, skip_bad: bool, dropouts: bool) -> None:
    _same(tmp_path, "t,roll,pitch\n0,0.1,0.1\n" + body, skip_bad=skip_bad,
          empty_is_dropout=dropouts)  # fmt: skip


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    rows=st.lists(
        st.tuples(st.floats(-1e3, 1e3), st.floats(allow_nan=True), st.floats(allow_infinity=True)),
        max_size=12,
    )
)
def test_random_numbers_read_alike(tmp_path: Path, rows: list[tuple[float, float, float]]) -> None:
    """Numbers as Python writes them (``repr``: every digit), any order of t."""
    body = "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in rows)
    for skip_bad in (False, True):
        _same(tmp_path, "t,roll,pitch\n" + body, skip_bad=skip_bad)


PLAIN = ["plain", "crlf", "comments and blank lines", "semicolons", "tabs", "t in ms",
         "exponents and signs", "an Excel sep line", "an Excel sep line, tabs"]  # fmt: skip


@pytest.mark.parametrize("name", PLAIN)
def test_plain_tables_are_read_by_blocks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    """Blocks without a comment or a problem never go through the row-by-row reader."""
    text = TRICKY[name]
    if name == "comments and blank lines":
        text = text.replace("# x 1\n", "")
    (tmp_path / "in.csv").write_text(text)

    def refused(*args: object) -> None:
        raise AssertionError("read row by row")

    expected = _by_rows(tmp_path / "in.csv", ("t", "roll", "pitch"))
    monkeypatch.setattr(sample_rows, "_split_rows", refused)
    assert _by_blocks(tmp_path / "in.csv", ("t", "roll", "pitch"), 5) == expected
    assert len(expected[0]) > 2


@settings(max_examples=400, deadline=None)
@given(
    st.sampled_from([b",", b";", b"\t", b" "]),
    st.lists(
        st.lists(st.sampled_from([b"1", b"-2.5", b"nan", b"", b" ", b"\t", b" 3", b"4\t"]),
                 min_size=1, max_size=4),
        min_size=1, max_size=4,
    ),
)  # fmt: skip
def test_the_quick_empty_field_test_never_misses_one(sep: bytes, rows: list[list[bytes]]) -> None:
    """Wherever the pattern finds an empty or blank field, the quick test says there may
    be one (it only spares the search on lines that cannot have one)."""
    from continuum_mhe.io.sample_rows import empty_field_pattern, may_have_empty_field

    lines = [sep.join(r) for r in rows]
    body = b"\n".join(ln for ln in lines if ln.strip())  # blank lines are dropped first
    if body and empty_field_pattern(sep).search(body):  # a block has a line at least
        assert may_have_empty_field(body, sep)


def test_a_pipe_whose_writer_is_behind_gets_its_rows_as_they_come(tmp_path: Path) -> None:
    # 300 rows written, the writer still open: the first block holds them (the reader
    # waits neither for a whole block of rows nor for the input's end, once the first
    # block has rows enough for its checks); then 10 rows more: a block of their own
    import os
    import threading

    fifo = tmp_path / "stream.csv"
    os.mkfifo(fifo)
    blocks: list[int] = []
    got = [threading.Event(), threading.Event()]

    def rows(first: int, n: int) -> str:
        return "".join(f"{0.05 * i},0.1,0.2\n" for i in range(first, first + n))

    def write() -> None:
        with open(fifo, "w") as fh:
            fh.write("t,roll,pitch\n" + rows(0, 300))
            fh.flush()
            got[0].wait(60)
            fh.write(rows(300, 10))
            fh.flush()
            got[1].wait(60)

    writer = threading.Thread(target=write)
    writer.start()

    def read() -> None:
        with open_rows(fifo) as table:
            for block in sample_blocks(table, ("t", "roll", "pitch"), 4096):
                blocks.append(len(block))
                got[min(len(blocks), 2) - 1].set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    assert got[0].wait(60), "no block before the writer closed the pipe"
    assert got[1].wait(60), "no second block before the writer closed the pipe"
    writer.join()
    reader.join(60)
    assert blocks == [300, 10]


def test_a_file_is_read_in_whole_blocks_and_a_short_pipe_start_waits_for_more(
    tmp_path: Path,
) -> None:
    """A regular file's blocks are whole (a short read is its end, not a writer behind);
    a pipe's first block holds FIRST_STREAMED_ROWS rows before a short read hands it on."""
    import os
    import threading

    path = tmp_path / "m.csv"
    path.write_text("t,roll,pitch\n" + "".join(f"{0.05 * i},0.1,0.2\n" for i in range(5000)))
    with open_rows(path) as table:
        assert [len(b) for b in sample_blocks(table, ("t", "roll", "pitch"), 4096)] == [4096, 904]
    fifo = tmp_path / "few.csv"
    os.mkfifo(fifo)
    n = sample_rows.FIRST_STREAMED_ROWS

    def write() -> None:  # the first rows in small pieces, then the rest, then the end
        with open(fifo, "w") as fh:
            fh.write("t,roll,pitch\n")
            for i in range(n + 20):
                fh.write(f"{0.05 * i},0.1,0.2\n")
                fh.flush()

    writer = threading.Thread(target=write)
    writer.start()
    with open_rows(fifo) as table:
        sizes = [len(b) for b in sample_blocks(table, ("t", "roll", "pitch"), 4096)]
    writer.join()
    assert sizes[0] >= n and sum(sizes) == n + 20, sizes
