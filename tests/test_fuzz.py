"""Fuzzing the readers and the estimate command (bounded, a few seconds).

A seed corpus (tests/data/fuzz/: inputs that can make a reader crash, hang or lie) runs through
``estimate`` with every estimator; hypothesis then builds CSV texts from valid rows,
garbage tokens, separators, comments and extreme numbers. Every outcome must be one of:
estimates for every kept row, finite, with a documented status (exit 0, one summary
line), or one error line naming the input (exit 2) and nothing written.
"""

from __future__ import annotations

import csv
import math
import warnings
from itertools import accumulate
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from continuum_mhe import RobotSettings, make_estimator, make_formulation
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.slack_readings import slack_reading_limit
from continuum_mhe.results import STATUS_MEANINGS

CORPUS = sorted((Path(__file__).parent / "data" / "fuzz").iterdir())
#: each seed's outcome, the same for every estimator: exit status and a fragment of
#: its one line (the error, or the summary with the estimate count and its notes)
SEED_OUTCOMES = {
    "accel_in_g.csv": (2, "accelerometer magnitude is about 1.01: the values look like g"),
    "bom_crlf.csv": (0, "wrote 2 estimates"),
    "both_tilt_raw.csv": (2, "line 1: the header has both tilt (roll, pitch) and raw IMU columns"),
    "cr_only.csv": (2, "line 1: lines end in CR alone (classic Mac OS line ends)"),
    "dup_header.csv": (2, "line 1: column 'roll' appears twice in the header"),
    "firmware_capture.txt": (0, "wrote 2 estimates"),
    "underscore_number.csv": (2, "line 3: column roll: '1_0' is not a number"),
    "decimal_comma.csv": (2, "line 2: column roll: '0,1' is not a number (a decimal comma?"),
    "gimbal_flip.csv": (0, "wrote 2 estimates"),
    "huge.csv": (2, "line 2: roll=1e+308, pitch=0.1 is out of range even in degrees"),
    "huge_t.csv": (0, "reset: 1, uncertain: 1); restarted after 1 gap(s) longer than 1 s"),
    "inf_angle.csv": (
        2,
        "line 3: column roll is inf (a dropout; --skip-bad keeps it, skip_bad=True in Python)",
    ),
    "long_gap.csv": (0, "restarted after 1 gap(s) longer than 1 s"),
    "mhe_stops.csv": (0, "wrote 33 estimates"),
    "negative_t.csv": (0, "wrote 2 estimates"),
    "not_utf8.csv": (2, "line 3: not UTF-8 text"),
    "quoted_truncated.csv": (2, "line 3: expected 3 fields, found 2 (truncated row?)"),
    "serial_capture_zero_acc.txt": (2, "line 5: acceleration is zero (no gravity direction)"),
    "tabs.csv": (0, "wrote 2 estimates"),
}

#: seeds whose equal readings have a long gap between them: a gap, not a frozen IMU
#: (the second reading taken as frozen would give huge_t's sample at t=1e300
#: no-estimate or not-converged, long_gap's at t=60 no-estimate from the EKF)
GAP_NOT_FREEZE = ("huge_t.csv", "long_gap.csv")


def _check_outcome(code: int, err: str, out: Path, inp: Path) -> None:
    notes = ("continuum-mhe: warning: ", "continuum-mhe: note: ")
    lines = [ln for ln in err.splitlines() if not ln.startswith(notes)]
    assert len(lines) == 1, err
    if code == 2:
        assert lines[0].startswith("continuum-mhe: error: ") and str(inp) in lines[0], err
        assert not out.exists()
        return
    assert code == 0 and lines[0].startswith("wrote "), err
    rows = list(csv.DictReader(ln for ln in out.open() if not ln.startswith("#")))
    assert rows and {r["status"] for r in rows} <= set(STATUS_MEANINGS)
    assert lines[0].startswith(f"wrote {len(rows)} estimates to "), err
    for r in rows:
        if r["status"] != "no-estimate":
            assert all(math.isfinite(float(r[k])) for k in ("x", "y", "z", "theta", "phi"))


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
@pytest.mark.parametrize("path", CORPUS, ids=[p.name for p in CORPUS])
def test_seed_corpus(tmp_path: Path, capfd: pytest.CaptureFixture[str], path: Path, method: str):
    out = tmp_path / "e.csv"
    code = main(["estimate", str(path), "-o", str(out), "--method", method])
    err = capfd.readouterr().err
    _check_outcome(code, err, out, path)
    expected_code, needle = SEED_OUTCOMES[path.name]
    assert code == expected_code, err
    assert needle in err, err
    if path.name in GAP_NOT_FREEZE:
        assert "frozen" not in err, err
        rows = list(csv.DictReader(ln for ln in out.open() if not ln.startswith("#")))
        assert "no-estimate" not in {r["status"] for r in rows}, rows


def test_every_seed_has_its_outcome() -> None:
    assert sorted(SEED_OUTCOMES) == [p.name for p in CORPUS]


_NUMBER = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-4, 4).map(lambda v: f"{v:.4f}"),
    st.sampled_from(["", "nan", "-inf", "1e308", "0x10", "1,5", "abc", '"0.1"', " 0.2 "]),
    # what Python's float reads beyond CSV's numbers: refused, never read as 10 or 0.1
    st.sampled_from(["1_0", "0.1_5", "\uff10.1", "\u0661", "\u00a00.1"]),
)
_ROW = st.lists(_NUMBER, min_size=0, max_size=5)
_LINE = st.one_of(
    _ROW.map(",".join),
    st.sampled_from(["", "# comment", "#", "t,roll,pitch", "\x00", "\t", ";;"]),
    st.text(st.characters(exclude_categories=("Cs",)), max_size=12),  # any encodable text
    # long lines (read whole: a comment's text never becomes a row), a CR inside a line
    st.integers(1, 40_000).map(lambda n: "#" + "\u00e9" * n + "0.025,1.2,-0.9"),
    _ROW.map(lambda r: "\r".join([",".join(r), "0.3,0.1,0.1"])),
)

#: a valid reading of each column: angles (rad) within 90 degrees of upright (the EKF
#: refuses a start beyond 135: a robot upside down), a gravity-like specific force
#: (m/s^2), rates (rad/s), any number in an ignored column
_COLUMN_RANGES = {
    **dict.fromkeys(("roll", "pitch"), (-1.5, 1.5)),
    "x": (-10.0, 10.0),
    **dict.fromkeys(("ax", "ay"), (-4.0, 4.0)),
    "az": (6.0, 12.0),
    **dict.fromkeys(("gx", "gy", "gz"), (-2.0, 2.0)),  # a median |omega| over 5 reads as deg/s
}


def _columns(header: str) -> tuple[str, list[str]]:
    """The separator and the column names of one of the valid headers below."""
    names = header.lstrip("\ufeff").removeprefix("# fields: ").split(" (")[0]
    sep = next(s for s in ";\t," if s in names)
    return sep, names.split(sep)


@st.composite
def _valid_file(draw, headers: list[str], values: tuple[str, ...]):
    """``(header, lines, t, values)``: one of ``headers`` and 1 to 12 valid rows (t
    strictly increasing, in s or ms as the header says; every value in range), their
    known answers ``t`` (s) and the reader's ``values`` columns, row by row; sometimes
    with a comment or blank line among the rows (skipped)."""
    header = draw(st.sampled_from(headers))
    sep, names = _columns(header)
    n = draw(st.integers(1, 12))
    steps = draw(st.lists(st.integers(1, 200), min_size=n, max_size=n))
    ms = list(accumulate(steps, initial=draw(st.integers(0, 10**6))))[1:]
    cells = {"t": [f"{m / 1000:.3f}" for m in ms], "t_ms": [str(m) for m in ms]}
    for name in names:
        if name not in cells:
            numbers = st.floats(*_COLUMN_RANGES[name])
            cells[name] = [f"{v:.6f}" for v in draw(st.lists(numbers, min_size=n, max_size=n))]
    lines = [sep.join(cells[c][i] for c in names) for i in range(n)]
    if draw(st.booleans()):
        lines.insert(draw(st.integers(0, n)), draw(st.sampled_from(["", "# comment", "#"])))
    known = [[float(cells[c][i]) for c in values if c in names] for i in range(n)]
    return header, lines, [m / 1000 for m in ms], known


_TILT_HEADERS = [
    "t,roll,pitch",
    "t_ms,roll,pitch",
    "t;roll;pitch",
    "roll,t,pitch,x",
    "\ufefft,roll,pitch",  # a byte-order mark: read
    "# fields: t_ms,roll,pitch (ms, rad)",  # the firmware's header comment
]
_RAW_HEADERS = ["t,ax,ay,az", "t_ms,ax,ay,az,gx,gy,gz", "t\tax\tay\taz"]
_RAW_VALUES = ("ax", "ay", "az", "gx", "gy", "gz")


def _any_file(headers: list[str]):
    """``(header, lines, None, None)``: any lines under one of ``headers`` (no known
    answer)."""
    return st.tuples(st.sampled_from(headers), st.lists(_LINE, max_size=12), st.none(), st.none())


@settings(
    max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    # two valid files (whose rows are read to their known values) for each of any text
    file=st.one_of(
        _valid_file(_TILT_HEADERS, ("roll", "pitch")),
        _valid_file(_TILT_HEADERS, ("roll", "pitch")),
        _any_file([*_TILT_HEADERS, "t,roll,pitch,roll"]),  # a column named twice: refused
    ),
    skip_bad=st.booleans(),
)
@example(
    file=(
        "t,roll,pitch",
        ["0.5,0.1,-0.2", "0.75,3.1,1.55"],
        [0.5, 0.75],
        [[0.1, -0.2], [3.1, 1.55]],
    ),
    skip_bad=False,
)
@example(
    file=("# fields: t_ms,roll,pitch (ms, rad)", ["# c", "20,-0.3,0.4"], [0.02], [[-0.3, 0.4]]),
    skip_bad=True,
)
def test_reader_is_total(tmp_path_factory, file: tuple, skip_bad: bool) -> None:
    """Any text: measurements whose t strictly increases, or one-line InputError of at
    most a few hundred characters (never the input quoted whole); a valid file: its
    rows' t and angles, every row."""
    header, lines, t, z = file
    path = tmp_path_factory.mktemp("fz") / "m.csv"
    path.write_text("\n".join([header, *lines]) + "\n", encoding="utf-8")
    try:
        table = read_measurements(path, skip_bad=skip_bad)
    except InputError as exc:
        assert t is None, exc  # a valid file is read
        assert "\n" not in str(exc) and str(path) in str(exc)
        assert len(str(exc)) < 400 + len(str(path)), str(exc)
        return
    assert "roll,pitch,roll" not in header
    assert len(table.t) >= 1 and np.all(np.diff(table.t) > 0) and np.isfinite(table.t).all()
    ok = np.isfinite(table.z).all(axis=1)
    assert np.all(np.abs(table.z[ok]) <= math.pi + 0.05)
    if t is not None:
        assert_allclose(table.t, t, rtol=1e-15, atol=0)
        assert_array_equal(table.z, z)
    est = make_estimator("ekf", make_formulation("bend", RobotSettings()))
    try:
        series = est.run(table.t, table.z)
    except UserError as exc:  # a run's refusal of what it read (a start the other way
        assert t is None, exc  # up, a unit): one line; a valid file runs
        assert "\n" not in str(exc) and len(str(exc)) < 1000, str(exc)
        return
    assert set(series.status) <= set(STATUS_MEANINGS)
    has = series.has_estimate
    assert np.isfinite(series.output[has]).all()


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    file=st.one_of(
        _valid_file(_RAW_HEADERS, _RAW_VALUES),
        _valid_file(_RAW_HEADERS, _RAW_VALUES),
        _any_file(_RAW_HEADERS),
    ),
    skip_bad=st.booleans(),
)
@example(
    file=(
        "t_ms,ax,ay,az,gx,gy,gz",
        ["1500,0.1,0.2,9.8,0.01,0.02,0.03", "1520,-0.1,0.3,9.7,0,0,-0.5"],
        [1.5, 1.52],
        [[0.1, 0.2, 9.8, 0.01, 0.02, 0.03], [-0.1, 0.3, 9.7, 0.0, 0.0, -0.5]],
    ),
    skip_bad=False,
)
@example(file=("t,ax,ay,az", ['\r"\x1f'], None, None), skip_bad=False)  # the CSV reader's error
def test_raw_reader_is_total(tmp_path_factory, file: tuple, skip_bad: bool):
    """Any raw text: samples with increasing t, or one-line InputError; a valid file:
    its rows' t, specific forces and rates, every row."""
    from continuum_mhe.io.raw_imu import read_raw_imu

    header, lines, t, values = file
    path = tmp_path_factory.mktemp("fz") / "raw.csv"
    path.write_text("\n".join([header, *lines]) + "\n", encoding="utf-8")
    try:
        table = read_raw_imu(path, skip_bad=skip_bad)
    except InputError as exc:
        assert t is None, exc  # a valid file is read
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    assert len(table.t) >= 1 and np.all(np.diff(table.t) > 0) and np.isfinite(table.t).all()
    ok = np.isfinite(table.acc).all(axis=1)
    assert np.all(np.linalg.norm(table.acc[ok], axis=1) > 0)
    if t is not None:
        assert_allclose(table.t, t, rtol=1e-15, atol=0)
        read = table.acc if table.gyr is None else np.hstack([table.acc, table.gyr])
        assert_array_equal(read, values)


# --- robot files ------------------------------------------------------------------------------
_VALUE = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.sampled_from(["1e-300", "1e300", "-0.2", "0", "nan", "inf", "0.2", "1.0", "1_0", '"0.2"']),
    st.sampled_from(["true", "[1, 2, 3]", "[1e300, 0, 0]", "[0, 0]", "{}", "2024-01-01"]),
)
_KEY = st.sampled_from(["length", "theta_max", "section", "at", "mount_rpy", "mounting", "x"])
_ENTRY = st.tuples(_KEY, _VALUE).map(lambda kv: f"{kv[0]} = {kv[1]}")
_TABLE = st.tuples(
    st.sampled_from(["[[section]]", "[[imu]]", "[section]", "[[imu"]), st.lists(_ENTRY, max_size=4)
).map(lambda t: "\n".join([t[0], *t[1]]))
_VALID = "[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n"
_ROBOT_TEXT = st.one_of(
    st.lists(_TABLE, max_size=5).map("\n".join),
    st.lists(_ENTRY, max_size=3).map(lambda e: _VALID + "\n".join(e)),  # a valid robot's IMU
    st.lists(_ENTRY, max_size=3).map(
        lambda e: _VALID.replace("[[imu]]", "\n".join([*e, "[[imu]]"]))
    ),
    st.integers(1, 3000).map(lambda n: "a = " + "[" * n + "]" * n),  # nesting
    st.text(st.characters(exclude_categories=("Cs",)), max_size=40),
)


@settings(
    max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(text=_ROBOT_TEXT, bom=st.booleans())
@example(text=_VALID, bom=True)
def test_robot_reader_is_total(tmp_path_factory, text: str, bom: bool) -> None:
    """Any robot-file text: a robot within the documented limits, or one InputError line
    naming the file (never a RecursionError, TypeError or a traceback); the valid robot
    the strategy builds on, with a byte order mark or without: its section and IMU."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.robot import MAX_MOUNT_DEG, MAX_SECTION_LENGTH, MIN_SECTION_LENGTH

    path = tmp_path_factory.mktemp("fz") / "r.toml"
    path.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.encode())
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # unit and order hints are warnings, not errors
            robot = read_robot(path)
    except InputError as exc:
        assert text != _VALID, exc
        assert "\n" not in str(exc) and str(exc).startswith(str(path))
        assert len(str(exc)) < 600, str(exc)
        return
    if text == _VALID:
        assert [(s.length, s.theta_max) for s in robot.sections] == [(0.2, 3.0)]
        assert [(i.section, i.at, i.mount_rpy) for i in robot.imus] == [(0, 1.0, (0.0,) * 3)]
    assert all(MIN_SECTION_LENGTH <= s.length <= MAX_SECTION_LENGTH for s in robot.sections)
    assert all(0 < s.theta_max < math.pi for s in robot.sections)
    for imu in robot.imus:
        assert 0 < imu.at <= 1 and 0 <= imu.section < robot.n_sections
        assert all(abs(v) <= MAX_MOUNT_DEG for v in imu.mount_rpy)


# --- the live protocol --------------------------------------------------------------------------
@st.composite
def _protocol_line(draw) -> tuple[str, str, int, int, bool]:
    """``(line, fmt, n_imus, n_tensions, plausible)``: mostly the field count
    ``parse_line`` expects (sometimes one field more or fewer), each field a plausible
    time, IMU value or tension, sometimes any :data:`_NUMBER` instead (a bad time or
    tension), or all of one IMU's fields (a dropout, where another IMU is good);
    ``plausible`` where the count is right and every field is plausible (no raw
    accelerometer reading exactly zero): a sample that ``parse_line`` must read."""
    from continuum_mhe.stream.protocol import VALUES_PER_IMU

    fmt = draw(st.sampled_from(["tilt", "raw"]))
    n_imus, n_tensions = draw(st.integers(1, 2)), draw(st.integers(0, 2))
    k = VALUES_PER_IMU[fmt]
    n_values = k * n_imus
    n_fields = 1 + n_values + n_tensions + draw(st.sampled_from([0] * 8 + [-1, 1]))
    plausible = {
        "time": st.floats(0, 1e7).map(lambda v: f"{v:.3f}"),
        "imu": st.floats(-1.5, 1.5).map(lambda v: f"{v:.5f}"),  # rad, m/s^2, rad/s
        "tension": st.floats(0, 50).map(lambda v: f"{v:.4f}"),
    }
    spoilt = draw(st.integers(0, 3 * n_imus))  # an IMU whose fields are any (none: past the last)
    fields, whole = [], True
    for i in range(n_fields):
        kind = "time" if i == 0 else "imu" if i <= n_values else "tension"
        imu = (i - 1) // k if kind == "imu" else -1
        any_number = imu == spoilt or draw(st.integers(0, 19)) == 0
        fields.append(draw(_NUMBER if any_number else plausible[kind]))
        whole = whole and not any_number
    whole = whole and n_fields == 1 + n_values + n_tensions
    if whole and fmt == "raw":  # every field a plausible number: an accelerometer of zeros?
        whole = not any(
            all(float(v) == 0.0 for v in fields[1 + k * i : 4 + k * i]) for i in range(n_imus)
        )
    return ",".join(fields), fmt, n_imus, n_tensions, whole


@settings(max_examples=200, deadline=None)
@given(case=_protocol_line())
@example(case=("1500,0.1,0.2,9.8,0.01,0.02,0.03", "raw", 1, 0, True))
@example(case=("20,0.1,-0.2,0.3,0.4,1.5", "tilt", 2, 1, True))
@example(case=("20,0.1,-0.2,nan,0.4,1.5", "tilt", 2, 1, False))  # IMU 2 dropped
@example(case=("20,,0.2,9.8,0.01,0.02,0.03", "raw", 1, 0, False))  # an empty field
def test_protocol_parser_is_total(case: tuple[str, str, int, int, bool]) -> None:
    """Any line: a sample with a finite, non-negative time, its tensions finite and
    non-negative, and each IMU either wholly finite or wholly a dropout (NaN, with its
    problem said), at least one IMU good; or GarbledLine. A line of plausible fields in
    the expected count is a sample without a dropout. The sample's time, tensions and
    good IMUs' values are the line's numbers."""
    from continuum_mhe.stream.protocol import VALUES_PER_IMU, GarbledLine, parse_line

    line, fmt, n_imus, n_tensions, plausible = case
    try:
        sample = parse_line(line, fmt, n_imus, n_tensions)  # type: ignore[arg-type]
    except GarbledLine as exc:
        assert not plausible, (line, str(exc))
        return
    assert sample is not None  # a line of numbers is no comment
    assert not (plausible and sample.problems), (line, sample.problems)
    assert math.isfinite(sample.t_ms) and sample.t_ms >= 0
    assert sample.tensions.shape == (n_tensions,)
    # a slack tendon's reading below zero is read (the stream takes it as 0)
    assert np.isfinite(sample.tensions).all()
    assert (sample.tensions >= -slack_reading_limit(sample.tensions)).all()
    k = VALUES_PER_IMU[fmt]
    blocks = sample.values.reshape(n_imus, k)
    bad = [i for i, b in enumerate(blocks) if not np.isfinite(b).all()]
    assert all(np.isnan(blocks[i]).all() for i in bad) and len(bad) == len(sample.problems)
    assert len(bad) < n_imus
    parts = line.strip().split(",")
    assert sample.t_ms == float(parts[0])
    assert_array_equal(sample.tensions, [float(f) for f in parts[1 + k * n_imus :]])
    for i in set(range(n_imus)) - set(bad):
        assert_array_equal(blocks[i], [float(f) for f in parts[1 + k * i : 1 + k * (i + 1)]])
