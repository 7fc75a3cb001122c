"""User mistakes in the recordings given to estimate (and calibrate): IMU columns
numbered from 0 or by section, mistyped or given twice, a time column of another name,
a time that jumps ahead or goes back, rows separated otherwise than their header, a last
line cut off, a binary file, another kind of file given as the recording (an estimate,
a truth, a robot file, a folder), robot logs without a clock or in another unit: one
line naming the file and the line, exit 2, nothing written (with --skip-bad, the bad
row a dropout)."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import notes_and_rows, simulated

from continuum_mhe import simulate
from continuum_mhe.cli import main
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.text_rows import CutLineWarning


@pytest.mark.parametrize(
    ("header", "row", "column"),
    [
        ("t,roll_0,pitch_0,roll_1,pitch_1", "0,0.1,0.1,0.2,0.2", "roll_0"),
        ("t,ax_0,ay_0,az_0,gx_0,gy_0,gz_0", "0,0,0,9.8,0,0,0", "ax_0"),
    ],
)
def test_imu_columns_numbered_from_zero_are_named(tmp_path, capsys, header, row, column) -> None:
    """IMU columns numbered from 0 (roll_0 ... roll_1) are named as such, with or
    without a robot file: one line, 'IMU columns are numbered from 1', nothing written."""
    meas = tmp_path / "m.csv"
    meas.write_text(f"{header}\n{row}\n")
    for robot in ([], ["--robot", "two-section"]):
        assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), *robot]) == 2
        err = capsys.readouterr().err
        assert (
            err.count("\n") == 1
            and (f"{meas}: line 1: column {column}: IMU columns are numbered from 1 (") in err
            and "renumber the file's columns" in err
        )
        assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


@pytest.mark.parametrize(
    ("time", "hint"),
    [
        ("time", "(the time in seconds is named t: rename 'time' to t)"),
        ("Time_ms", "(a time in milliseconds is named t_ms: rename 'Time_ms' to t_ms)"),
        ("timestamp_ms", "(a time in milliseconds is named t_ms: rename 'timestamp_ms' to t_ms)"),
        # a unit after the name, as spreadsheets and MATLAB write it, is not read
        ("Time (s)", "(a unit in a column's name is not read: rename 'Time (s)' to t)"),
        ("t [ms]", "(a unit in a column's name is not read: rename 't [ms]' to t_ms)"),
        # microseconds or nanoseconds, which no column name takes
        (
            "t_ns",
            "('t_ns' is a time in microseconds or nanoseconds? give it in seconds, as t, or in "
            "milliseconds, as t_ms)",
        ),
        # pandas' index, written without a name before the columns
        (
            "",
            "(a column without a name, as pandas writes its index: the time in seconds is "
            "named t; pandas' to_csv(..., index=False) leaves the index out)",
        ),
    ],
)
def test_a_time_column_named_otherwise_is_told_its_name(tmp_path, capsys, time, hint) -> None:
    """A recording whose time column is named ``time`` (seconds) or ``time_ms``
    (milliseconds), or with its unit (``Time (s)``, ``t [ms]``), is refused in one line
    naming the column to rename it to, ``t`` or ``t_ms``: renamed to ``t``, milliseconds
    would be read as seconds; one in nanoseconds is told to give seconds, and one whose
    first column has no name (pandas' index) is told that the time is named ``t``."""
    meas = tmp_path / "m.csv"
    meas.write_text(f"{time},roll,pitch\n0,0.1,0.2\n50,0.1,0.2\n")
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{meas}: line 1: missing column(s) t (" in err
    assert err.rstrip().endswith(hint), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def test_a_t_beside_a_time_column_is_refused(tmp_path, capsys) -> None:
    """A header with a ``time`` column and a ``T`` (a temperature, most often), which
    reads as ``t``: one line naming both, nothing written (read, the temperature would
    be the sample times)."""
    meas = tmp_path / "m.csv"
    meas.write_text("time,roll,pitch,T\n0,0.1,0.2,25.0\n0.05,0.1,0.2,25.1\n0.1,0.1,0.2,25.2\n")
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv")]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {meas}: line 1: column 'T' is read as the time t, but the "
        "header has 'time' too (and 'T' may be a temperature): name the time column t "
        "(seconds) or t_ms (milliseconds), and the other otherwise\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


@pytest.mark.parametrize(
    ("second", "said"),
    [
        ("s,rad,rad", "line 2: column t: 's' is not a number (a row of units under the "
         "header? remove it: each column's unit is fixed)"),
        ("[s],[rad],[rad]", "line 2: column t: '[s]' is not a number (a row of units"),
        ("2026-03-04T10:15:00.020,0.1,0.2", "line 2: column t: '2026-03-04T10:15:00....' is "
         "not a number (a date and time: t is a number of seconds, such as since the start)"),
        ("0,deg,0.2", "line 2: column roll: 'deg' is not a number (a row of units"),
    ],
)  # fmt: skip
def test_a_units_row_or_a_date_is_told_what_it_is(tmp_path, capsys, second, said) -> None:
    """A row of units under the header (as an export from a spreadsheet has), and a date
    and time in ``t``: one line saying what the field looks like, nothing written."""
    meas = tmp_path / "m.csv"
    meas.write_text(f"t,roll,pitch\n{second}\n0.05,0.1,0.2\n0.1,0.1,0.2\n")
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"error: {meas}: {said}" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def test_a_time_that_starts_over_is_told_so(tmp_path, capsys) -> None:
    """Two recordings joined (``t`` back at the file's first): the line of the step back
    says the time starts over and to split the file there; a step back past a later
    time (not the first) does not."""
    meas = tmp_path / "m.csv"
    for times, said in (
        (
            (0.0, 0.05, 0.1, 0.15, 0.0, 0.05),
            "line 6: decreasing timestamp t=0 after t=0.15 on line 5 (t must strictly "
            "increase); the file's first t is 0: two recordings joined, or a logger "
            "restarted? split the file there",
        ),
        (
            (0.0, 0.05, 0.1, 0.15, 0.2, 0.18),
            "line 7: decreasing timestamp t=0.18 after t=0.2 on line 6 (t must strictly increase)",
        ),
    ):
        rows = "".join(f"{t},0.1,0.2\n" for t in times)
        meas.write_text(f"t,roll,pitch\n{rows}")
        assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv")]) == 2
        assert capsys.readouterr().err == f"continuum-mhe: error: {meas}: {said}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def test_a_time_in_nanoseconds_is_refused_naming_the_recording(tmp_path, capsys) -> None:
    """``t`` in nanoseconds since 1970 read as seconds (steps of 2e7 s from 1.77e18 s,
    which the estimate would write as one time): one line naming the recording, the
    unit and the fix, not the estimate file's row; nothing written."""
    meas = tmp_path / "m.csv"
    t0 = 1_772_619_300_000_000_000
    rows = "".join(f"{t0 + k * 20_000_000},0.1,0.2\n" for k in range(10))
    meas.write_text(f"t,roll,pitch\n{rows}")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {meas}: t advances by a median of 2e+07 s per sample; t is "
        "read in seconds: if it is in milliseconds, name the column t_ms; if in "
        "microseconds or nanoseconds, give seconds (t reaches 1.77261930002e+18 s, whose "
        "steps the estimate cannot write apart); nothing written\n"
    )
    assert not out.exists()


def test_an_empty_field_of_a_one_imu_file_is_a_dropout_as_with_several(tmp_path) -> None:
    """An empty roll or pitch in a one-IMU file is a dropout, as the same field of a
    several-IMU file is a dropout of its IMU, in ``estimate`` and in
    ``read_measurements`` (not an error such as ``'' is not a number``)."""
    from continuum_mhe.io.csv_files import read_measurements

    m, _ = simulated(tmp_path, "a")
    header, *rows = m.read_text().splitlines(keepends=True)
    assert header.strip() == "t,roll,pitch"
    rows[49] = rows[49].split(",")[0] + ",,\n"  # both fields
    rows[60] = rows[60].split(",")[0] + ",," + rows[60].split(",")[2]  # roll alone
    blank = tmp_path / "blank.csv"
    blank.write_text(header + "".join(rows))
    table = read_measurements(blank)
    assert np.isnan(table.z[[49, 60]]).any(axis=1).all() and np.isfinite(table.z[48]).all()
    est = tmp_path / "e.csv"
    assert main(["estimate", str(blank), "--method", "ekf", "-o", str(est)]) == 0
    names = notes_and_rows(est)[1][0].strip().split(",")
    status = [r.strip().split(",")[names.index("status")] for r in notes_and_rows(est)[1][1:]]
    assert status[49] == status[60] == "dropout" and status[48] == "ok"


def test_estimate_of_a_folder_that_is_not_a_bag(tmp_path, capsys) -> None:
    assert main(["estimate", str(tmp_path), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "is a directory without metadata.yaml, expected a CSV file or a ROS 2 bag folder" in err


@pytest.mark.parametrize(
    ("header", "row", "match"),
    [
        ("t,ax_2,ay_2,az_2,gx_2,gy_2,gz_2", "0,0,0,9.81,0,0,0", "numbered ax_2"),
        ("t,roll_2,pitch_2", "0,0.1,0.1", "numbered roll_2"),
    ],
)
def test_imu_columns_numbered_by_section_are_named(tmp_path, capsys, header, row, match) -> None:
    """A one-IMU robot whose IMU sits on section 2, recorded with columns numbered by that
    section (``ax_2``...): one line saying IMUs are numbered in the robot file's order,
    not by section, and how to name them; nothing written."""
    robot = tmp_path / "r.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 2\n")
    meas = tmp_path / "m.csv"
    meas.write_text(f"{header}\n{row}\n")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", str(robot), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{meas}: line 1: the header's IMU columns are {match}" in err[0]
    assert "not by section" in err[0] and not out.exists()


@pytest.mark.parametrize(
    ("header", "match"),
    [
        ("t,rol_1,pitch_1,roll_2,pitch_2,roll_3,pitch_3", "the header has rol_1 \\(a typo\\?\\)"),
        ("t,roll_1,roll_2,pitch_2,roll_3,pitch_3", "missing column\\(s\\) pitch_1"),
    ],
)
def test_a_typo_or_a_missing_column_is_named_before_the_numbering(
    tmp_path, capsys, header, match
) -> None:
    """A two-IMU robot's header with a typo or a missing column in IMU 1's set: that is
    what the one line names, though two whole sets are numbered 2 and 3."""
    robot = tmp_path / "r.toml"
    robot.write_text(
        "[[section]]\nlength = 0.2\n[[section]]\nlength = 0.2\n"
        "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    meas = tmp_path / "m.csv"
    meas.write_text(header + "\n" + ",".join(["0"] + ["0.1"] * header.count(",")) + "\n")
    assert main(["estimate", str(meas), "--robot", str(robot), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(match, err[0]) and "not by section" not in err[0]


@pytest.mark.parametrize("name", ["time", "timestamp", "Time"])
def test_a_time_column_named_otherwise_gets_the_name_t(tmp_path, capsys, name) -> None:
    rec = simulate("paper3d", duration=1.0, seed=0)
    m = tmp_path / "m.csv"
    write_table(m, [name, "roll", "pitch"], np.column_stack([rec.t, rec.z]))
    out = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"rename '{name}' to t" in err[0] and "line 1" in err[0]
    assert not out.exists()


@pytest.mark.parametrize(
    ("header", "said"),
    [
        ("t,roll,pitch,roll_1,pitch_1", "the header has both roll, pitch and roll_1, pitch_1"),
        ("t,t_ms,roll,pitch", "the header has both t and t_ms"),
    ],
)
def test_a_header_with_two_sets_of_the_same_columns_is_refused(
    tmp_path, capsys, header: str, said: str
) -> None:
    """Two columns for the same reading (an IMU's unnumbered and numbered tilt, the
    time in s and in ms): which one is meant is not guessed."""
    f = tmp_path / "two.csv"
    n = header.count(",")
    f.write_text(header + "\n" + "\n".join(",".join([str(0.05 * i)] + ["0.1"] * n)
                                           for i in range(1, 30)) + "\n")  # fmt: skip
    out = tmp_path / "o.csv"
    assert main(["estimate", str(f), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {f}: line 1: {said}") and err.count("\n") == 1
    assert not out.exists()


def test_a_recording_of_another_kind_says_which_kind_and_what_the_command_reads(
    tmp_path, capsys
) -> None:
    """An estimate, a truth or a robot file given to ``estimate`` as the recording (an
    estimate or truth to ``calibrate --from``): one line that says what the file is and
    what the command run reads, exit 2, nothing written."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert (
        main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth", str(truth)])
        == 0
    )
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    robot = tmp_path / "r.toml"
    robot.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    out = tmp_path / "x.csv"
    for given, says in (
        (truth, "an estimate or truth table, not IMU readings: estimate reads a recording"),
        (est, "an estimate or truth table, not IMU readings: estimate reads a recording"),
        (robot, "a robot file? it is given with --robot ROBOT.toml"),
    ):
        capsys.readouterr()
        assert main(["estimate", str(given), "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and says in err[0], err
        assert not out.exists()
    # calibrate --from names what calibrate reads, not what estimate reads
    for given in (truth, est):
        assert main(["calibrate", "--from", str(given)]) == 2
        out_text, err_text = capsys.readouterr()
        assert out_text == "" and err_text.count("\n") == 1, err_text
        assert (
            "(an estimate or truth table, not IMU readings: calibrate reads a recording of the "
            "IMUs on the still robot; continuum-mhe evaluate EST.csv TRUTH.csv scores an "
            "estimate)\n"
        ) in err_text


def _cut_last_line(src: Path, dst: Path, chars: int = 5) -> None:
    """``src`` cut off inside its last line, as a logger killed while writing leaves it."""
    dst.write_bytes(src.read_bytes()[: -(chars + 1)])


def test_a_file_cut_off_inside_its_last_line_is_said(tmp_path, capsys) -> None:
    """The last line of a cut-off file ends inside a number, which reads as another
    number: every reader says so in one warning naming the line and reads it as written
    (a file whose writer left out the last line end is whole), with ``--skip-bad`` too."""
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    assert (
        main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth", str(truth)])
        == 0
    )
    cut = tmp_path / "cut.csv"
    _cut_last_line(meas, cut)
    last = len(meas.read_text().splitlines())
    out = tmp_path / "e.csv"
    capsys.readouterr()
    with pytest.warns(CutLineWarning) as said:
        assert main(["estimate", str(cut), "--method", "ekf", "-o", str(out)]) == 0
    assert [str(w.message) for w in said] == [
        f"{cut}: line {last}: the last line has no line end: if the file was cut off as it "
        "was written, its last value may be cut short (read as written; end the line if it "
        "is whole, or remove it)"
    ]
    err = capsys.readouterr().err
    assert f"wrote {last - 1} estimates" in err
    with pytest.warns(CutLineWarning):  # --skip-bad reads it too: a row, not a bad one
        assert main(["estimate", str(cut), "--method", "ekf", "--skip-bad", "-o", str(out),
                     "--overwrite"]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert f"wrote {last - 1} estimates" in err and "bad rows" not in err
    whole = tmp_path / "whole.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("error", CutLineWarning)
        assert main(["estimate", str(meas), "--method", "ekf", "-o", str(whole)]) == 0
    cut_truth = tmp_path / "cut_truth.csv"
    _cut_last_line(truth, cut_truth)
    with pytest.warns(CutLineWarning, match=rf"{cut_truth.name}: line {last}: the last line"):
        assert main(["evaluate", str(whole), str(cut_truth)]) == 0


def test_a_last_line_cut_short_of_its_fields_is_one_error_without_the_cut_warning(
    tmp_path, capsys
) -> None:
    """A file cut off before its last line's last field: the error that the line has
    too few fields, alone (not the cut-line warning that it is read as written, and then
    the error that it cannot be), for a recording and for an estimate file."""
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth",
                 str(truth)]) == 0  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    last = len(meas.read_text().splitlines())
    cut, cut_est = tmp_path / "cut.csv", tmp_path / "cut_e.csv"
    _cut_last_line(meas, cut, chars=len(meas.read_text().splitlines()[-1].split(",")[-1]) + 1)
    _cut_last_line(est, cut_est, chars=30)
    capsys.readouterr()
    for argv, name in (
        (["estimate", str(cut), "-o", str(tmp_path / "x.csv")], cut),
        (["evaluate", str(cut_est), str(truth)], cut_est),
    ):
        with warnings.catch_warnings():
            warnings.simplefilter("error", CutLineWarning)
            assert main(argv) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line.startswith(f"continuum-mhe: error: {name}: line "), line
        assert "expected" in line and "fields, found" in line and "(truncated" in line, line
    assert not (tmp_path / "x.csv").exists() and last > 2


def test_a_bend_recording_with_a_bad_value_names_no_skip_bad_calibrate_lacks(tmp_path, capsys):
    rod = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    lines = (rod / "spatial_bend.csv").read_text().splitlines()
    fields = lines[49].split(",")
    fields[2] = "nan"
    lines[49] = ",".join(fields)
    bend = tmp_path / "bend.csv"
    bend.write_text("\n".join(lines) + "\n")
    argv = ["calibrate", "--from", str(rod / "spatial_rest.csv"), "--bend", str(bend)]
    assert main([*argv, "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"{bend}: line 50: column ay_1 is nan (calibrate needs every reading "
                        "of the bent robot)")  # fmt: skip


def test_a_time_that_jumps_ahead_alone_is_named_as_the_likely_fault(tmp_path, capsys) -> None:
    """One row whose t jumps far ahead (a corrupted stamp) makes every later row a
    decreasing one: the error at the next row says that the row before it jumped ahead
    of the rows around it, naming its line; a row that goes back alone is named by its
    own error, without that note."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    lines = meas.read_text().splitlines()
    for line, t, hint in ((10, "1000", True), (10, "0.2", False)):
        bad = tmp_path / f"bad{t}.csv"
        rows = list(lines)
        rows[line - 1] = t + "," + rows[line - 1].split(",", 1)[1]
        bad.write_text("\n".join(rows) + "\n")
        capsys.readouterr()
        assert main(["estimate", str(bad), "-o", str(tmp_path / "e.csv")]) == 2
        (said,) = capsys.readouterr().err.strip().splitlines()
        if hint:
            assert said.endswith(
                f"line {line + 1}: decreasing timestamp t=0.45 after t=1000 on line {line} "
                f"(t must strictly increase); line {line}'s t jumps ahead of the rows around "
                "it (t=0.35 before it): is it the wrong one? every later row before its t is "
                "refused too"
            ), said
        else:
            assert said.endswith(
                f"line {line}: decreasing timestamp t=0.2 after t=0.35 on line {line - 1} "
                "(t must strictly increase)"
            ), said
        assert not (tmp_path / "e.csv").exists()


def test_rows_separated_otherwise_than_their_header_are_said_so(tmp_path, capsys) -> None:
    """A header separated by ``;`` over rows separated by ``,`` (two tools' output
    joined): one line saying which separator each uses (not that the time column's value
    is not a number, quoting the whole row)."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    lines = meas.read_text().splitlines()
    mixed = tmp_path / "mixed.csv"
    mixed.write_text("\n".join([lines[0].replace(",", ";"), *lines[1:]]) + "\n")
    capsys.readouterr()
    assert main(["estimate", str(mixed), "-o", str(tmp_path / "e.csv")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert (
        line
        == f"continuum-mhe: error: {mixed}: line 2: fields separated by ',', the header's by ';'"
    )
    assert not (tmp_path / "e.csv").exists()


def test_skip_bad_drops_a_time_that_jumped_ahead_alone_not_the_rows_after_it(
    tmp_path, capsys
) -> None:
    """With ``--skip-bad`` one row whose t jumps far ahead is the row dropped, in a
    recording (read in blocks) and in a tensions file (read whole), not every row after
    it dropped as decreasing (92 of 101; the tensions interpolated across 99.7 s, 17
    rows on them ``ok`` and the tip 10 mm off). A row that goes back alone is the one
    dropped."""
    from continuum_mhe.io import read_measurements
    from continuum_mhe.io.csv_files import DropoutWarning

    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "5", "-o", str(meas)]) == 0
    lines = meas.read_text().splitlines()
    for t, dropped in (("1000", 10), ("0.2", 10)):
        bad = tmp_path / f"bad{t}.csv"
        rows = list(lines)
        rows[9] = t + "," + rows[9].split(",", 1)[1]
        bad.write_text("\n".join(rows) + "\n")
        out = tmp_path / f"e{t}.csv"
        capsys.readouterr()
        assert main(["estimate", str(bad), "--skip-bad", "-o", str(out)]) == 0
        err = capsys.readouterr().err
        assert f"wrote {len(lines) - 2} estimates" in err, err
        assert (
            f"bad rows: 1 sample(s) dropped (bad or non-increasing t); first: line {dropped}:"
            in err
        )
        kept = read_measurements(bad, skip_bad=True)
        assert len(kept.t) == len(lines) - 2 and kept.t.max() < 100  # line 10 (t = 0.4) left
        assert not np.isclose(kept.t, 0.4).any() and (np.diff(kept.t) > 0).all()
    # a duplicated row, and one that steps back a little: the row after is the one
    # dropped, and no jump is said (the row before did not jump ahead)
    for label, t_new, dropped_line in (("dup", None, 11), ("back", "0.38", 11)):
        rows = list(lines)
        rows.insert(10, rows[9] if t_new is None else t_new + "," + rows[9].split(",", 1)[1])
        bad = tmp_path / f"{label}.csv"
        bad.write_text("\n".join(rows) + "\n")
        kept = read_measurements(bad, skip_bad=True)
        assert len(kept.t) == len(lines) - 1 and np.isclose(kept.t, 0.45).any()
        assert kept.skipped[0].startswith(f"line {dropped_line}: "), kept.skipped
        capsys.readouterr()
        assert main(["estimate", str(bad), "-o", str(tmp_path / f"{label}.out")]) == 2
        assert "jumps ahead" not in capsys.readouterr().err
    # a tensions file (the tendon robot's): one row dropped and interpolated across
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/tendon"
    raw = tmp_path / "raw.csv"
    raw.write_text("\n".join((data / "force-08_raw.csv").read_text().splitlines()[:101]) + "\n")
    tension_lines = (data / "force-08_tensions.csv").read_text().splitlines()[:101]
    tension_lines[19] = "100," + tension_lines[19].split(",", 1)[1]
    tensions = tmp_path / "tensions.csv"
    tensions.write_text("\n".join(tension_lines) + "\n")
    with pytest.warns(DropoutWarning, match=r"1 tension row\(s\) .*line 20: t=100 jumps ahead"):
        assert main(["estimate", str(raw), "--robot", "tendon-two-section", "--inputs",
                     str(tensions), "--skip-bad", "-o", str(tmp_path / "te.csv")]) == 0  # fmt: skip


def test_a_binary_file_with_a_cr_before_any_nul_is_said_to_be_no_text(tmp_path, capsys) -> None:
    # bytes that are not UTF-8 with a CR among them are a binary file, not a file whose
    # lines end in CR alone; a text file whose lines do is still said so
    binary = tmp_path / "capture.csv"
    binary.write_bytes(b"\x93\xfa\x10\r\xc3\x28\xa0\xff\n" + bytes(range(1, 256)) * 4)
    classic = tmp_path / "classic.csv"
    classic.write_bytes(b"t,roll,pitch\r0,0.01,0.02\r0.05,0.01,0.02\r")
    for path, needle in (
        (binary, "line 1: not UTF-8 text"),
        (classic, "line 1: lines end in CR alone"),
    ):
        out = tmp_path / f"{path.stem}_est.csv"
        assert main(["estimate", str(path), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{path}: {needle}" in err, err
        assert not out.exists()


def _two_section_estimate(tmp_path: Path) -> Path:
    """An estimate of a 1 s simulated two-section recording (its options line names the
    robot ``two-section``)."""
    two = tmp_path / "two.csv"
    assert main(["simulate", "s-curve", "--robot", "two-section", "--duration", "1",
                 "-o", str(two)]) == 0  # fmt: skip
    est = tmp_path / "two_est.csv"
    assert main(["estimate", str(two), "--robot", "two-section", "-o", str(est)]) == 0
    return est


def test_a_config_of_another_robot_is_named_where_the_recording_does_not_fit(
    tmp_path, capsys
) -> None:
    # the robot comes from --config's options line, not from --robot: the error names
    # the line that set it
    est = _two_section_estimate(tmp_path)
    one = tmp_path / "one.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(one)]) == 0
    capsys.readouterr()
    out = tmp_path / "one_est.csv"
    assert main(["estimate", str(one), "--config", str(est), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert f"error: {est}: line 2: robot = 'two-section': {one}: line 1:" in err, err


def _bag_of(path: Path, stamps: np.ndarray, acc: np.ndarray, gyr: np.ndarray) -> Path:
    """A ROS 1 bag of one Imu topic, each message logged at its header stamp."""
    from robot_log_helpers import IMU, imu_msg
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    with Writer(path) as w:
        conn = w.add_connection("/tip/imu", IMU, typestore=store)
        for ns, a, g in zip(stamps, acc, gyr):
            w.write(conn, int(ns), store.serialize_ros1(imu_msg(store, int(ns), a, g, True), IMU))
    return path


def _still_imu(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    acc = np.array([0.0, 0.0, 9.81]) + rng.normal(size=(n, 3)) * 0.05
    gyr = rng.normal(size=(n, 3)) * 0.005
    stamps = 1_700_000_000_000_000_000 + np.arange(n, dtype=np.int64) * 20_000_000
    return stamps, acc, gyr


def test_a_robot_log_without_a_clock_is_refused(tmp_path, capsys) -> None:
    stamps, acc, gyr = _still_imu(60)
    # every header stamp zero and every message logged at time 0: no order to estimate
    # in (not one estimate of the first message, the others dropped)
    bag = _bag_of(tmp_path / "zero.bag", np.zeros_like(stamps), acc, gyr)
    out = tmp_path / "est.csv"
    for extra in ([], ["--skip-bad"]):
        assert main(["estimate", str(bag), "-o", str(out), *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and not out.exists()
        assert (
            f"{bag}: topic /tip/imu: neither the header stamps (all zero) nor the log's times "
            "advance (59 of 60 messages" in err
        ), err
    # a duplicated stamp among advancing ones is still one message left out, counted
    stamps[21] = stamps[20]
    assert main(["estimate", str(_bag_of(tmp_path / "dup.bag", stamps, acc, gyr)),
                 "-o", str(out)]) == 0  # fmt: skip
    assert "1 sample(s) dropped" in capsys.readouterr().err


def test_a_robot_log_reading_beyond_any_imus_range_is_named(tmp_path, capsys) -> None:
    stamps, acc, gyr = _still_imu(60)
    acc[30, 2] = 1e300  # a corrupt value, as a CSV row's is refused
    bag = _bag_of(tmp_path / "huge.bag", stamps, acc, gyr)
    out = tmp_path / "est.csv"
    assert main(["estimate", str(bag), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert (
        f"{bag}: topic /tip/imu: the message at t = 0.6 s (message 31): a reading beyond "
        "any IMU's range (|a| 1e+300 m/s^2" in err
    ), err
    gyr[30] = [0.0, 0.0, 1e30]
    acc[30, 2] = 9.81
    bag = _bag_of(tmp_path / "spin.bag", stamps, acc, gyr)
    assert main(["estimate", str(bag), "-o", str(out)]) == 2
    assert "|omega| 1e+30 rad/s, limit 1000" in capsys.readouterr().err
    # --skip-bad: that message a dropout, the others estimated
    assert main(["estimate", str(bag), "-o", str(out), "--skip-bad"]) == 0
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")][1:]
    statuses = [ln.rsplit(",", 2)[1] for ln in rows]
    assert len(statuses) == 60 and statuses[30] == "dropout"


@pytest.mark.parametrize("skip_bad", [[], ["--skip-bad"]])
def test_a_robot_log_in_another_accelerometer_unit_is_said_so_not_as_corrupt(
    tmp_path, capsys, skip_bad
) -> None:
    # readings in mm/s^2 (some above 1e4) or in raw counts (all above it) are another
    # unit, as a CSV's are, not a message with a corrupt value (nor, with --skip-bad, a
    # recording of dropouts alone)
    stamps, acc, gyr = _still_imu(60)
    out = tmp_path / "est.csv"
    for name, scale, needle in (
        ("mm", 1000.0, "the values look like mm/s^2"),
        ("counts", 1670.0, "beyond any IMU's range in m/s^2 (limit 10000): raw counts?"),
    ):
        bag = _bag_of(tmp_path / f"{name}.bag", stamps, acc * scale, gyr)
        assert main(["estimate", str(bag), "-o", str(out), *skip_bad]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and not out.exists()
        assert f"{bag}: topic /tip/imu: accelerometer magnitude is about" in err, err
        assert needle in err, err


def test_a_robot_file_given_as_the_recording_is_not_blamed_on_the_configs_robot(
    tmp_path, capsys
) -> None:
    # the hint names --robot (a robot file is given with it), but the options file's
    # robot is not what is wrong: the message is the recording's own
    est = _two_section_estimate(tmp_path)
    robot = tmp_path / "robot.toml"
    robot.write_text('mounting = "z-up"\n')
    capsys.readouterr()
    out = tmp_path / "x.csv"
    assert main(["estimate", str(robot), "--config", str(est), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not out.exists()
    assert err.startswith(f"continuum-mhe: error: {robot}: line 1:"), err
    assert "(a robot file? it is given with --robot ROBOT.toml)" in err
