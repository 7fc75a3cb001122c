"""The command line's round trips (simulate, estimate, evaluate) and the recordings
estimate reads: units, columns, bad rows (one line naming the file and the line, exit 2,
no output; --skip-bad's dropouts, counted), gaps in t and the summary that counts them."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import good_rows, meas_csv, write_file
from estimator_helpers import reading_by_reading

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.estimate_csv import ESTIMATE_COLUMNS, write_measurements
from continuum_mhe.io.state_tables import read_state_table, read_states
from continuum_mhe.model.kinematics import tip_position
from continuum_mhe.simulation.scenarios import simulate


# --- round trips ------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_simulate_estimate_evaluate_round_trip(tmp_path, capsys, method):
    meas, truth, est = tmp_path / "m.csv", tmp_path / "truth.csv", tmp_path / "est.csv"
    assert (
        main(
            [
                "simulate",
                "paper3d",
                "-o",
                str(meas),
                "--truth",
                str(truth),
                "--duration",
                "6",
                "--seed",
                "4",
            ]
        )
        == 0
    )
    assert main(["estimate", str(meas), "-o", str(est), "--method", method]) == 0
    with est.open() as fh:
        rows = list(csv.reader(ln for ln in fh if not ln.startswith("#")))
    assert tuple(rows[0][: len(ESTIMATE_COLUMNS)]) == ESTIMATE_COLUMNS
    t_m = [r[0] for r in list(csv.reader(meas.open()))[1:]]
    assert [r[0] for r in rows[1:]] == [f"{float(t):.10g}" for t in t_m]  # one row per input row
    st = rows[0].index("status")
    assert rows[1][st] == "uncertain"  # the start: one reading's fit, unconfirmed
    assert all(r[st] in ("ok", "dropout") for r in rows[2:])
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["n"] == len(rows) - 1
    # filtered: below the error of each reading read alone (the EKF's 0.6 of it)
    _, states, _ = read_states(truth)
    unfiltered = reading_by_reading(read_measurements(meas).z)[:, 2:] - states[:, :3]
    unfiltered_pct = 100 * np.linalg.norm(unfiltered, axis=1).mean() / 0.2
    assert report["tip_mean_pct"] < 0.8 * unfiltered_pct, (report["tip_mean_pct"], unfiltered_pct)
    assert set(report["rmse"]) == {"x", "y", "z", "theta", "phi"}


def test_estimate_positions_match_forward_kinematics(tmp_path):
    meas, est = tmp_path / "m.csv", tmp_path / "est.csv"
    assert main(["simulate", "straight", "-o", str(meas), "--duration", "12"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "mhe"]) == 0
    t, out, status = read_states(est)
    assert np.all(np.isfinite(out))
    np.testing.assert_allclose(out[:, :3], tip_position(out[:, 3], out[:, 4], 0.2), atol=1e-9)


def test_paper_start_leaves_first_rows_empty(tmp_path):
    meas, est = tmp_path / "m.csv", tmp_path / "est.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "2"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--horizon", "10", "--paper-start"]) == 0
    header, *rows = list(csv.reader(ln for ln in est.open() if not ln.startswith("#")))
    st = header.index("status")
    assert all(r[1:st] == [""] * 10 and r[st] == "no-estimate" for r in rows[:9])
    assert rows[9][st] == "uncertain" and rows[10][st] == "ok"  # the start, then confirmed
    assert all(r[1:6] != [""] * 5 for r in rows[9:])
    assert "nan" not in est.read_text().lower()


def test_theta_max_option_bounds_and_releases(tmp_path):
    meas, est = tmp_path / "m.csv", tmp_path / "est.csv"
    assert main(["simulate", "planar-overbend", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    _, out, _ = read_states(est)
    assert out[:, 3].max() <= math.pi / 2 + 1e-7
    assert main(["estimate", str(meas), "-o", str(est), "--theta-max", "3", "--overwrite"]) == 0
    _, out3, _ = read_states(est)
    assert out3[:, 3].max() > 2.0


def test_degrees_flag_matches_radians(tmp_path):
    rec = simulate("paper3d", duration=2, seed=1)
    rad, deg = tmp_path / "rad.csv", tmp_path / "deg.csv"
    write_measurements(rad, rec.t, rec.z)
    write_measurements(deg, rec.t, np.degrees(rec.z))
    a = read_measurements(rad)
    b = read_measurements(deg, degrees=True)
    np.testing.assert_allclose(a.z, b.z, atol=1e-9)


def test_degrees_given_for_a_recording_in_radians_warns_once(tmp_path):
    """``--degrees`` (``degrees=True``) on angles all within pi, as radians are: one
    warning naming the file, from the reader and from ``estimate``, which still writes
    (a robot that barely moves may be in degrees); the same file in degrees, or read
    as radians, gives none."""
    import warnings

    from continuum_mhe.io.csv_files import UnitWarning

    rec = simulate("paper3d", duration=2, seed=1)
    rad, deg = tmp_path / "rad.csv", tmp_path / "deg.csv"
    write_measurements(rad, rec.t, rec.z)
    write_measurements(deg, rec.t, np.degrees(rec.z))
    largest = f"{np.abs(rec.z).max():.3g}"
    with pytest.warns(UnitWarning) as caught:
        read_measurements(rad, degrees=True)
    assert [str(w.message) for w in caught] == [
        f"{rad}: read in degrees (--degrees; degrees=True in Python), but every roll and "
        f"pitch of its 41 rows is within {largest}: radians? in degrees no IMU tilts more "
        f"than {largest} degrees in the whole recording; without --degrees the angles are "
        "read as radians"
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_measurements(deg, degrees=True)
        read_measurements(rad)
    with pytest.warns(UnitWarning) as caught:
        assert main(["estimate", str(rad), "-o", str(tmp_path / "e.csv"), "--degrees"]) == 0
    said = [str(w.message) for w in caught if issubclass(w.category, UnitWarning)]
    assert len(said) == 1 and said[0].startswith(f"{rad}: read in degrees")
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnitWarning)
        assert main(["estimate", str(deg), "-o", str(tmp_path / "f.csv"), "--degrees"]) == 0


def test_a_mounting_refused_on_radians_read_as_degrees_names_the_unit(tmp_path, capsys):
    """A hanging robot's tilt recording in radians, read with ``--degrees``: the angles
    (roll near pi) read as a few degrees look like an upright robot, and the mounting
    check refuses; its line also asks whether the angles are radians and says to leave
    out ``--degrees``. Read as radians, the same file runs."""
    robot = tmp_path / "hanging.toml"
    robot.write_text(
        'mounting = "z-down"\n[[section]]\nlength = 0.1\ntheta_max = 2.0\n'
        "[[section]]\nlength = 0.1\ntheta_max = 2.0\n"
        "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    rec = simulate_robot("spatial", read_robot(str(robot)), duration=2.0, seed=1)
    rad = tmp_path / "rad.csv"
    write_measurements(rad, rec.t, rec.z, ["roll_1", "pitch_1", "roll_2", "pitch_2"])
    out = tmp_path / "e.csv"
    argv = ["estimate", str(rad), "--robot", str(robot), "-o", str(out)]
    assert main([*argv, "--degrees"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"continuum-mhe: error: {rad}: mounting: the robot is described as z-down"
    )
    assert err[0].endswith(
        f"or are the angles radians? every roll and pitch of its first {len(rec.t)} rows is "
        f"within {np.abs(rec.z).max():.3g}: leave out --degrees (degrees=False in Python)"
    )
    assert not out.exists()
    assert main(argv) == 0


def test_extra_columns_and_column_order_are_accepted(tmp_path):
    source = [[float(v) for v in r.split(",")] for r in good_rows(10)]  # t, roll, pitch
    rows = [f"{p!r},x,{t!r},{r!r}" for t, r, p in source]
    table = read_measurements(meas_csv(tmp_path, rows, header="pitch,note,t,roll"))
    np.testing.assert_array_equal(table.t, [t for t, _, _ in source])
    np.testing.assert_array_equal(table.z, [[r, p] for _, r, p in source])


# --- bad input: one line, file and line named, exit 2, no output ---------------------------
BAD_INPUTS = {
    "missing-columns": ("t,roll\n0,0.1\n", "missing column(s) pitch"),
    "empty-file": ("", "line 1: file is empty"),
    "header-only": ("t,roll,pitch\n", "no data rows"),
    "non-numeric": ("t,roll,pitch\n0,0.1,0.1\n0.05,abc,0.1\n", "line 3: column roll: 'abc'"),
    "nan-row": ("t,roll,pitch\n0,0.1,0.1\n0.05,nan,0.1\n", "line 3: column roll is nan"),
    "decreasing-t": (
        "t,roll,pitch\n0,0.1,0.1\n0.1,0.1,0.1\n0.05,0.1,0.1\n",
        "line 4: decreasing timestamp t=0.05 after t=0.1 on line 3",
    ),
    "duplicate-t": ("t,roll,pitch\n0,0.1,0.1\n0,0.1,0.1\n", "line 3: duplicate timestamp"),
    "degrees": ("t,roll,pitch\n0,10,20\n0.05,11,21\n", "look like degrees: pass --degrees"),
    # a pitch column with a roll's range (up to pi), a roll column within pi/2: swapped
    "roll-pitch-swapped": (
        "t,roll,pitch\n0,0.2,1.2\n0.05,0.3,2.9\n0.1,0.1,-2.5\n",
        "the columns roll and pitch look swapped: pitch reaches 2.9 rad",
    ),
    "roll-pitch-swapped-numbered": (  # named as the file writes them
        "t,Roll_1,pitch_1\n0,0.2,1.2\n0.05,0.3,2.9\n0.1,0.1,-2.5\n",
        "line 3: Roll_1=0.3, pitch_1=2.9 rad is out of range (|roll| <= pi, |pitch| <= pi/2); "
        "the columns Roll_1 and pitch_1 look swapped",
    ),
    "truncated-row": ("t,roll,pitch\n0,0.1,0.1\n0.05\n", "line 3: expected 3 fields"),
    # a field missing from a column no estimator reads: which one is unknown, and the
    # values after it may be their neighbours'
    "unread-field-missing": (
        "t,roll,pitch,x\n0,0.1,0.1,5\n0.05,0.1,0.1,5\n0.1,0.1,0.1\n",
        "line 4: expected 4 fields, found 3 (truncated row?)",
    ),
    "extra-field": (
        "t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1,0.2\n",
        "line 3: expected 3 fields, found 4 (an extra field or separator?)",
    ),
    "binary": ("t,roll,pitch\n0,0.1,\x000.1\n", "line 2"),
}


@pytest.mark.parametrize(
    ("text", "rows"),
    [
        # a separator at the header's end: no column, rows without it are whole
        ("t,roll,pitch,\n0,0.1,0.1\n0.05,0.1,0.1\n", 2),
        # a last line without its line end, short of a column no estimator reads: read as
        # written (with the warning that it may be cut)
        ("t,roll,pitch,x\n0,0.1,0.1,5\n0.05,0.1,0.1,5\n0.1,0.1,0.1", 3),
    ],
)
def test_rows_short_of_no_named_column_are_read(tmp_path, text, rows):
    meas = write_file(tmp_path / "meas.csv", text)
    est = tmp_path / "est.csv"
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    assert len(read_state_table(est).t) == rows


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_measurement_file_is_rejected_cleanly(tmp_path, capsys, case):
    text, expected = BAD_INPUTS[case]
    meas = write_file(tmp_path / "meas.csv", text)
    est = tmp_path / "est.csv"
    code = main(["estimate", str(meas), "-o", str(est)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("continuum-mhe: error: ") and str(meas) in err
    assert expected in err
    assert list(tmp_path.iterdir()) == [meas]  # no output, no temporary left behind


@pytest.mark.parametrize("case", ["degrees", "roll-pitch-swapped"])
def test_skip_bad_does_not_read_a_files_wrong_unit_or_columns_as_dropouts(tmp_path, capsys, case):
    """Angles in degrees, or roll and pitch swapped, are the file's, not a few rows'
    glitches: refused with --skip-bad as without it (not read as dropouts with the rest
    estimated with the wrong unit or columns, `ok` and far off)."""
    text, expected = BAD_INPUTS[case]
    meas = write_file(tmp_path / "meas.csv", text)
    code = main(["estimate", str(meas), "--skip-bad", "-o", str(tmp_path / "est.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and expected in err
    assert list(tmp_path.iterdir()) == [meas]


def test_swapped_angles_of_one_imu_of_several_are_named_by_their_columns(tmp_path, capsys):
    """Two IMUs, the second's pitch column holding roll values (up to pi) and its roll
    column pitch values: the line names that IMU's columns and says they look swapped."""
    text = "t,roll_1,pitch_1,roll_2,pitch_2\n0,0.1,0.1,0.3,0.2\n0.05,0.1,0.1,0.2,2.8\n"
    meas = write_file(tmp_path / "meas.csv", text)
    code = main(["estimate", str(meas), "--robot", "two-section", "-o", str(tmp_path / "e.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "line 3: roll_2=0.2, pitch_2=2.8 rad is out of range" in err
    assert "the columns roll_2 and pitch_2 look swapped: pitch_2 reaches 2.8 rad" in err
    assert list(tmp_path.iterdir()) == [meas]


@pytest.mark.parametrize("glitch", ["45", "2"])
def test_one_angle_out_of_range_is_a_glitch_not_degrees(tmp_path, capsys, glitch):
    """One pitch of 45 (or of 2, within a roll's range: not a swap of the columns either)
    among radians is a glitch, not degrees: the line names it, says how many rows are
    out of range and that --skip-bad reads them as dropouts, and does not suggest
    --degrees (which would read the whole file 57 times too small) nor swapping the
    columns; with --skip-bad that row is a dropout, counted."""
    rows = [f"{0.05 * i:g},{0.1 + 0.001 * i:g},{0.2:g}" for i in range(60)]
    rows[30] = f"1.5,0.13,{glitch}"
    meas = write_file(tmp_path / "meas.csv", "t,roll,pitch\n" + "\n".join(rows) + "\n")
    est = tmp_path / "est.csv"
    assert main(["estimate", str(meas), "-o", str(est)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"line 32: roll=0.13, pitch={glitch} rad is out of range" in err
    assert "--degrees" not in err and "swapped" not in err and "1 of 60 rows read here are" in err
    assert "--skip-bad reads them as dropouts" in err and not est.exists()
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 0
    said = capsys.readouterr()
    said_all = said.out + said.err
    assert "dropout: 1" in said_all
    assert f"line 32: roll=0.13, pitch={glitch} rad out of range" in said_all
    table = read_state_table(est)
    assert list(table.status).count("dropout") == 1 and table.status[30] == "dropout"


def test_missing_file(tmp_path, capsys):
    assert main(["estimate", str(tmp_path / "nope.csv"), "-o", str(tmp_path / "e.csv")]) == 2
    assert "nope.csv: no such file" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_skip_bad_keeps_rows_as_dropouts_and_counts(tmp_path, capsys):
    rows = good_rows(40)
    rows[10] = rows[10].split(",")[0] + ",nan,0.1"
    rows[20] = rows[20].split(",")[0] + ",oops,0.1"
    rows.insert(30, rows[29])  # duplicate timestamp: dropped
    meas, est = meas_csv(tmp_path, rows), tmp_path / "est.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 0
    err = capsys.readouterr().err
    assert (
        "bad rows: 2 sample(s) with a bad value, read as a dropout of its IMU; 1 sample(s) "
        "dropped (bad or non-increasing t); first: line 12: column roll is nan" in err
    )
    t, out, status = read_states(est)
    assert len(t) == 40 and np.all(np.isfinite(out))
    assert list(np.flatnonzero(status == "dropout")) == [10, 20]


def test_a_row_with_an_extra_field_is_a_counted_dropout_with_skip_bad(tmp_path, capsys):
    """A row with one field more than its header is not read as if the field were not
    there: with --skip-bad the whole sample is a dropout, counted and named ('expected 3
    fields, found 4'); an empty trailing field is read as it is."""
    rows = good_rows(20)
    good = read_measurements(meas_csv(tmp_path, rows)).z
    rows[7] += ",0.3"  # which field is extra is unknown: the whole sample is a dropout
    rows[12] += ","  # an empty trailing field is no data: read as it is
    rows[15] = rows[15].rsplit(",", 1)[0]  # a field short: the whole sample as well
    meas, est = meas_csv(tmp_path, rows), tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", "--skip-bad"]) == 0
    err = capsys.readouterr().err
    assert (
        "bad rows: 2 sample(s) with too few or too many fields, read as a dropout of every "
        "IMU (which value is whose is unknown); first: line 9: expected 3 fields, found 4" in err
    )
    t, out, status = read_states(est)
    assert len(t) == 20 and list(np.flatnonzero(status == "dropout")) == [7, 15]
    table = read_measurements(meas, skip_bad=True)
    assert np.isnan(table.z[[7, 15]]).all() and table.skipped == [
        "line 9: expected 3 fields, found 4 (an extra field or separator?)",
        "line 17: expected 3 fields, found 2 (truncated row?)",
    ]
    np.testing.assert_array_equal(np.delete(table.z, [7, 15], 0), np.delete(good, [7, 15], 0))


def test_a_gap_reset_of_exactly_the_sample_period_restarts_nothing(tmp_path, capsys):
    """An even 20 Hz recording with ``--gap-reset 0.05``: its steps (0.05 s, give or take
    the times' rounding) are no gap, so nothing restarts and every row after the start
    is ``ok``, as with the default."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--gap-reset", "0.05"]) == 0
    assert "wrote 41 estimates to " in capsys.readouterr().err
    assert list(read_state_table(est).status).count("ok") == 40


@pytest.mark.parametrize(
    ("cut", "said"),
    [
        ((4.0, 4.5), "estimated across 1 gap(s) in t up to --gap-reset 1 s (about 9 samples "
         "missing at the usual step of 0.05 s; the largest 0.5 s, before t = 4.5 s)"),
        ((4.0, 4.2), "estimated across 1 gap(s) in t up to --gap-reset 1 s (about 3 samples "
         "missing at the usual step of 0.05 s; the largest 0.2 s, before t = 4.2 s)"),
        ((4.0, 4.1), None),  # one sample lost: a step of twice the usual one, no gap
        ((4.0, 5.5), None),  # longer than --gap-reset: the restart's clause says it
        (None, None),
    ],
)  # fmt: skip
def test_the_summary_names_the_gaps_in_t_the_estimate_went_across(tmp_path, capsys, cut, said):
    """Samples lost for less than --gap-reset (a 20 Hz recording with the rows from 4 s
    up to 4.5 s left out): the estimator predicts across them, and the summary counts
    them with the largest; a step of up to three usual ones is no gap, a gap longer than
    --gap-reset is said as the restart it is, and an even recording has none."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "20", "-o", str(meas)]) == 0
    if cut is not None:
        lines = meas.read_text().splitlines()
        kept = [ln for ln in lines[1:] if not cut[0] < float(ln.split(",")[0]) < cut[1]]
        meas.write_text("\n".join([lines[0], *kept]) + "\n")
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    summary = capsys.readouterr().err.splitlines()[-1]
    if said is None:
        assert "estimated across" not in summary, summary
    else:
        assert said in summary, summary
    assert ("restarted after 1 gap(s) longer than 1 s" in summary) == (cut == (4.0, 5.5))


def test_gaps_in_t_are_counted_across_blocks_and_in_a_short_recording() -> None:
    """The gap tally sees a gap between two blocks as one within a block, and judges a
    recording shorter than its usual-step sample at the end."""
    from continuum_mhe.estimators.run_notices import GapsInTime

    t = np.arange(0, 30, 0.1)
    t = np.delete(t, range(100, 104))  # 10.0 to 10.3 s lost: a 0.5 s step
    whole, split, reset = GapsInTime(1.0), GapsInTime(1.0), GapsInTime(1.0)
    going_on = np.zeros(len(t), dtype=bool)
    whole.add(t, going_on)
    split.add(t[:100], going_on[:100])  # the gap between the two blocks
    split.add(t[100:], going_on[100:])
    for tally in (whole, split):
        assert (tally.count, tally.missing) == (1, 4)
        assert tally.largest == pytest.approx(0.5) and tally.largest_t == pytest.approx(10.4)
    restarted = going_on.copy()
    restarted[100] = True  # the estimator restarted after it: not estimated across
    reset.add(t, restarted)
    assert reset.count == 0 and reset.clause() is None
    short = GapsInTime(None)
    times = np.array([0.0, 0.1, 0.2, 0.3, 0.9, 1.0])
    short.add(times, np.zeros(len(times), dtype=bool))
    assert short.clause() is not None and short.count == 1 and short.missing == 5
    assert GapsInTime(1.0).clause() is None
    # at --gap-reset itself, within the times' rounding, the policy does not restart:
    # such a gap is counted; one clearly longer is the restart's to say
    even = np.arange(0, 30, 0.1)
    edge = np.concatenate([even, even + even[-1] + 1.0000005])  # a step of 1.0000005 s
    beyond = np.concatenate([even, even + even[-1] + 1.01])
    for times, counted in ((edge, 1), (beyond, 0)):
        tally = GapsInTime(1.0)
        tally.add(times, np.zeros(len(times), dtype=bool))
        assert tally.count == counted


def test_rows_written_twice_are_no_gaps_in_t() -> None:
    """A logger that writes each row twice, a microsecond apart: the usual step is the
    rows' period (the project's typical step, bursts left out), so no step is a gap."""
    from continuum_mhe.estimators.run_notices import GapsInTime

    even = np.arange(0, 20, 0.05)
    twice = np.sort(np.concatenate([even, even + 1e-6]))
    tally = GapsInTime(1.0)
    tally.add(twice, np.zeros(len(twice), dtype=bool))
    assert tally.clause() is None and tally.period == pytest.approx(0.05, rel=1e-3)


@pytest.mark.parametrize("again", ["t_ms,ax,ay,az,gx,gy,gz", "t_ms,ay,ax,az,gy,gx,gz"])
def test_a_capture_that_declares_its_fields_again_in_another_order_is_refused(
    tmp_path, capsys, again
):
    # a board restarted with other firmware mid-capture: the rows after its second
    # '# fields:' line would be read by the first's order, each value as another's
    sim = tmp_path / "raw.csv"
    assert main(["simulate", "paper3d", "--imu", "raw", "-o", str(sim), "--duration", "3"]) == 0
    rows = [r.split(",") for r in sim.read_text().splitlines()[1:]]
    order = [again.split(",").index(c) for c in "t_ms,ax,ay,az,gx,gy,gz".split(",")]
    lines = ["# fields: t_ms,ax,ay,az,gx,gy,gz (ms, m/s^2, rad/s)"]
    for i, r in enumerate(rows):
        r = [str(round(float(r[0]) * 1000)), *r[1:]]
        if i == 30:
            lines.append(f"# fields: {again} (ms, m/s^2, rad/s)")
        if i >= 30:
            r = [r[order.index(k)] for k in range(7)]
        lines.append(",".join(r))
    capture = write_file(tmp_path / "capture.csv", "\n".join(lines) + "\n")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    code = main(["estimate", str(capture), "-o", str(out), "--method", "ekf"])
    err = capsys.readouterr().err
    if again.startswith("t_ms,ax"):  # the same fields again: a board reset, read on
        assert code == 0 and out.exists()
        return
    assert code == 2 and not out.exists()
    assert err.count("\n") == 1 and "capture.csv: line 32: " in err and "another order" in err


def test_read_measurements_raises_input_error_with_line(tmp_path):
    meas = write_file(tmp_path / "m.csv", "t,roll,pitch\n0,0.1,0.1\n\n0.1,0.1,inf\n")
    with pytest.raises(InputError, match=r"m.csv: line 4: column pitch is inf"):
        read_measurements(meas)


def test_utf8_bom_header_is_accepted(tmp_path):
    text = "\ufefft,roll,pitch\r\n0,0.1,0.1\r\n0.05,0.1,0.12\r\n"
    table = read_measurements(write_file(tmp_path / "bom.csv", text))
    assert table.t.tolist() == [0.0, 0.05]


def test_no_estimate_at_all_is_an_error_and_writes_nothing(tmp_path, capsys):
    meas = write_file(tmp_path / "m.csv", "t,roll,pitch\n0,nan,nan\n0.05,,\n0.1,abc,x\n")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 2
    err = capsys.readouterr().err
    assert "no sample gave an estimate" in err and err.count("\n") == 1
    assert not est.exists()


def test_skip_count_is_per_row_not_per_field(tmp_path, capsys):
    rows = good_rows(10)
    rows[4] = rows[4].split(",")[0] + ",nan,nan"
    meas, est = meas_csv(tmp_path, rows), tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 0
    assert "bad rows: 1 sample(s) with a bad value" in capsys.readouterr().err


@pytest.mark.skipif(not Path("/proc/self/mem").exists(), reason="needs Linux's /proc")
@pytest.mark.parametrize("command", ["estimate", "evaluate"])
def test_a_file_that_fails_to_read_is_named_in_the_error(tmp_path, capsys, command) -> None:
    """A read that fails after the file opened (``/proc/self/mem`` opens and then gives
    an I/O error, as a device or a lost network share may) is one line naming the file,
    exit 2, not a "reading or writing a file" error without the file's name."""
    from continuum_mhe.cli import main

    meas, est, truth = tmp_path / "m.csv", tmp_path / "e.csv", tmp_path / "t.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth",
                 str(truth)]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    capsys.readouterr()
    argv = {
        "estimate": ["estimate", "/proc/self/mem", "-o", str(tmp_path / "x.csv")],
        "evaluate": ["evaluate", str(est), "/proc/self/mem"],
    }[command]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["continuum-mhe: error: /proc/self/mem: cannot read (Input/output error)"]
    assert not (tmp_path / "x.csv").exists()


def test_a_value_of_many_digits_is_named_short(tmp_path, capsys) -> None:
    """A field of 100,000 digits (a logger's garbage; it reads as inf) is not echoed
    whole in the one-line error (100 KB long): the value is cut to a few dozen
    characters, in a recording and in a truth file alike."""
    from continuum_mhe.cli import main

    digits = "1" * 100_000
    meas = tmp_path / "m.csv"
    meas.write_text(f"t,roll,pitch\n0,0.01,0.02\n0.05,{digits},0.02\n0.1,0.01,0.02\n")
    est = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(est)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < 300, err[:300]
    assert f"{meas}: line 3: column roll is {'1' * 40}... (a dropout" in err
    assert not est.exists()
    truth = tmp_path / "t.csv"
    truth.write_text(f"t,x,y,z\n0,0,0,0.2\n0.05,{digits},0,0.2\n")
    assert main(["evaluate", str(truth), str(truth)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < 300, err[:300]


def test_skip_bad_takes_one_angle_out_of_range_in_a_short_last_block_as_a_glitch(tmp_path):
    """A file read in blocks whose last block holds a few rows, one of them out of
    range: with --skip-bad that row is a dropout (a glitch), as in any other block,
    not the file's unit refused."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.model.registry import make_formulation

    n = 4100  # the last of 4096-row blocks holds four
    rows = [f"{0.01 * k:.2f},0.1,0.05" for k in range(n)]
    rows[-2] = f"{0.01 * (n - 2):.2f},5.0,0.05"
    meas = write_file(tmp_path / "m.csv", "t,roll,pitch\n" + "\n".join(rows) + "\n")
    with open_input(meas, InputOptions(skip_bad=True), make_formulation("bend")) as stream:
        z = np.vstack([b[1] for b in stream.blocks])
    assert len(z) == n and np.isnan(z[-2]).all() and np.isfinite(z[-1]).all()
