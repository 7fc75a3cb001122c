"""The command line and file formats: round trips, bad input, atomic output."""

from __future__ import annotations

import csv
import functools
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import reading_by_reading
from hypothesis import given, settings
from hypothesis import strategies as st

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.io.estimate_csv import ESTIMATE_COLUMNS, write_measurements
from continuum_mhe.io.state_tables import read_state_table, read_states
from continuum_mhe.model.kinematics import tip_position
from continuum_mhe.simulation.scenarios import simulate


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _good_rows(n: int = 40, dt: float = 0.05) -> list[str]:
    rec = simulate("paper3d", duration=(n - 1) * dt, dt=dt, seed=3)
    return [f"{t:.3f},{r:.6f},{p:.6f}" for t, (r, p) in zip(rec.t, rec.z)]


def _meas(tmp_path: Path, rows: list[str], header: str = "t,roll,pitch") -> Path:
    return _write(tmp_path / "meas.csv", "\n".join([header, *rows]) + "\n")


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
    source = [[float(v) for v in r.split(",")] for r in _good_rows(10)]  # t, roll, pitch
    rows = [f"{p!r},x,{t!r},{r!r}" for t, r, p in source]
    table = read_measurements(_meas(tmp_path, rows, header="pitch,note,t,roll"))
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
    meas = _write(tmp_path / "meas.csv", text)
    est = tmp_path / "est.csv"
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    assert len(read_state_table(est).t) == rows


@pytest.mark.parametrize("case", sorted(BAD_INPUTS))
def test_bad_measurement_file_is_rejected_cleanly(tmp_path, capsys, case):
    text, expected = BAD_INPUTS[case]
    meas = _write(tmp_path / "meas.csv", text)
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
    meas = _write(tmp_path / "meas.csv", text)
    code = main(["estimate", str(meas), "--skip-bad", "-o", str(tmp_path / "est.csv")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and expected in err
    assert list(tmp_path.iterdir()) == [meas]


def test_swapped_angles_of_one_imu_of_several_are_named_by_their_columns(tmp_path, capsys):
    """Two IMUs, the second's pitch column holding roll values (up to pi) and its roll
    column pitch values: the line names that IMU's columns and says they look swapped."""
    text = "t,roll_1,pitch_1,roll_2,pitch_2\n0,0.1,0.1,0.3,0.2\n0.05,0.1,0.1,0.2,2.8\n"
    meas = _write(tmp_path / "meas.csv", text)
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
    meas = _write(tmp_path / "meas.csv", "t,roll,pitch\n" + "\n".join(rows) + "\n")
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


def test_output_folder_missing_is_an_error(tmp_path, capsys):
    meas = _meas(tmp_path, _good_rows(5))
    assert main(["estimate", str(meas), "-o", str(tmp_path / "no" / "e.csv")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_existing_output_is_kept_on_error(tmp_path):
    meas = _write(tmp_path / "meas.csv", "t,roll,pitch\n0,0.1,0.1\n0.05,abc,0.1\n")
    est = _write(tmp_path / "est.csv", "previous result\n")
    assert main(["estimate", str(meas), "-o", str(est)]) == 2
    assert est.read_text() == "previous result\n"


def test_skip_bad_keeps_rows_as_dropouts_and_counts(tmp_path, capsys):
    rows = _good_rows(40)
    rows[10] = rows[10].split(",")[0] + ",nan,0.1"
    rows[20] = rows[20].split(",")[0] + ",oops,0.1"
    rows.insert(30, rows[29])  # duplicate timestamp: dropped
    meas, est = _meas(tmp_path, rows), tmp_path / "est.csv"
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
    rows = _good_rows(20)
    good = read_measurements(_meas(tmp_path, rows)).z
    rows[7] += ",0.3"  # which field is extra is unknown: the whole sample is a dropout
    rows[12] += ","  # an empty trailing field is no data: read as it is
    rows[15] = rows[15].rsplit(",", 1)[0]  # a field short: the whole sample as well
    meas, est = _meas(tmp_path, rows), tmp_path / "e.csv"
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


def test_estimate_or_truth_row_with_an_extra_field_is_refused(tmp_path, capsys):
    est = _write(tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n")
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2,0.1\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {truth}: line 2: expected 4 fields, found 5 (an extra field or "
        "separator?)\n"
    )


def test_evaluate_rejects_bad_truth(tmp_path, capsys):
    est = _write(tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n")
    truth = _write(tmp_path / "truth.csv", "t,x,y\n0,0,0\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert "truth.csv: line 1: missing column(s) z (header has: t, x, y)" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("which", "text"),
    [("truth", "t,x,y,z\n0,1e300,0,0.2\n"), ("estimate", "t,x,y,z,theta,phi,status,solve_ms\n"
     "0,0,0,0.2,0,0,ok,1\n0.05,0,-2e9,0.2,0,0,ok,1\n")],
)  # fmt: skip
def test_evaluate_refuses_values_beyond_any_robot(tmp_path, capsys, which, text):
    """A value of 1e300 m in the truth or the estimate is refused in one line naming the
    file and line (not an infinite mean error, nor ``Infinity`` in --json)."""
    good = {"truth": "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n",
            "estimate": "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n"}  # fmt: skip
    files = {k: _write(tmp_path / f"{k}.csv", text if k == which else good[k]) for k in good}
    assert main(["evaluate", str(files["estimate"]), str(files["truth"])]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{files[which]}: line " in err and "out of range" in err


def test_evaluate_of_a_one_row_estimate_says_so(tmp_path, capsys):
    est = _write(tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n")
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err.endswith(f"{est}: one row: evaluate needs at least two\n")


def test_evaluate_with_a_wrong_truth_shift_names_the_shift_that_fits(tmp_path, capsys):
    """Files on one clock compared with ``--truth-shift 1.9``: the refusal names the
    shift that lines them up, none (not -1.9, which names 1.9 in turn)."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas), "--truth",
                 str(truth)]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    for shift in ("1.9", "-1.9"):
        assert main(["evaluate", str(est), str(truth), "--truth-shift", shift]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--truth-shift 0 (leave --truth-shift out)" in err, err


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


def test_evaluate_of_a_one_row_truth_says_so(tmp_path, capsys):
    """A truth of one row is named, not the estimate whose rows it cannot cover."""
    est = _write(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n0.05,0,0,0.2,0,0,ok,1\n",
    )
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {truth}: one row: evaluate needs a truth of at least two\n"
    )


def test_evaluate_reads_a_standard_deviation_beyond_the_value_limit(tmp_path, capsys):
    """An estimate may say it knows nothing (a std of 1e7 rad, as the EKF of a soft
    tendon robot wrote): the readers take what estimate writes."""
    est = _write(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms\n"
        "0,0,0,0.2,0,0,1,1,1,1e7,1,ok,1\n0.05,0,0,0.2,0,0,1,1,1,1e7,1,ok,1\n",
    )
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 0
    table = read_state_table(est)  # the value itself, not a dropout
    assert table.std is not None and table.std[:, 3].tolist() == [1e7, 1e7]


@pytest.mark.parametrize("value", ["inf", "nan", "-0.1", "1e400"])
def test_evaluate_refuses_a_standard_deviation_that_is_no_finite_number_at_least_0(
    tmp_path, capsys, value
):
    """A ``std_`` cell infinite, not a number or negative is refused in one line that
    says what it must be."""
    est = _write(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms\n"
        f"0,0,0,0.2,0,0,1,1,1,1,1,ok,1\n0.05,0,0,0.2,0,0,{value},1,1,1,1,ok,1\n",
    )
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {est}: line 3: std_x must be a finite number >= 0, got {value!r}\n"
    )


def test_evaluate_refuses_an_estimate_given_as_the_truth(tmp_path, capsys):
    """An estimate given as the truth (the estimate against itself: a 0 mm error and
    every coverage 1.000) is refused in one line naming it."""
    est = _write(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n0.05,0,0,0.2,0,0,ok,1\n",
    )
    truth = _write(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    for argv in ([str(est), str(est)], [str(truth), str(est)]):
        assert main(["evaluate", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{est}: has an estimate's status" in err, err
    assert main(["evaluate", str(est), str(truth)]) == 0


@pytest.mark.parametrize("command", ["plot", "view"])
def test_plot_and_view_refuse_an_estimate_without_any(tmp_path, capsys, command):
    est = _write(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,,,,,,no-estimate,1\n0.05,,,,,,no-estimate,1\n",
    )
    out = {"plot": ["-o", str(tmp_path / "f.png")], "view": ["--save", str(tmp_path / "f.rrd")]}
    assert main([command, str(est), *out[command]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no row has an estimate" in err
    assert list(tmp_path.iterdir()) == [est]


@pytest.mark.parametrize("suffix", [".bag", ".png", ".rrd", ".toml"])
def test_estimate_refuses_an_output_another_reader_would_misread(tmp_path, capsys, suffix):
    meas = _meas(tmp_path, _good_rows(5))
    out = tmp_path / f"e{suffix}"
    assert main(["estimate", str(meas), "-o", str(out)]) == 2
    assert "an estimate is written as CSV" in capsys.readouterr().err
    assert not out.exists()
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.txt")]) == 0


@pytest.mark.parametrize("name", ["e.txt", "e"])
def test_an_estimate_written_as_txt_or_without_suffix_keeps_its_options(tmp_path, capsys, name):
    # estimate writes CSV under these names: evaluate, plot and --config read its options
    # line as they read an estimate .csv's, not the whole file as an options TOML
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    sim = ["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "2"]
    assert main([*sim, "--length", "0.3"]) == 0
    est = tmp_path / name
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", "--length", "0.3"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    out, err = capsys.readouterr()
    assert "TOML" not in err and "warning" not in err
    assert json.loads(out)["tip_max_pct"] == pytest.approx(json.loads(out)["tip_max_mm"] / 3)
    again = tmp_path / "again.csv"
    assert main(["estimate", str(meas), "--config", str(est), "-o", str(again)]) == 0
    assert "TOML" not in capsys.readouterr().err
    assert again.read_text().splitlines()[:2] == est.read_text().splitlines()[:2]


@pytest.mark.parametrize("value", ["3", '"ekf"', "[1, 2]"])
def test_an_options_line_that_is_no_table_is_said_not_a_crash(tmp_path, capsys, value):
    # evaluate and plot warn and use the default robot, as for an options line that is
    # not TOML; --config refuses it in one line
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth)]) == 0
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    lines = est.read_text().splitlines()
    assert lines[1].startswith("# options = {")
    lines[1] = f"# options = {value}"
    est.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "line 2: options = " in err and "not a table" in err
    assert main(["estimate", str(meas), "--config", str(est), "-o", str(tmp_path / "a.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error:" in err and "not a table of options" in err
    assert not (tmp_path / "a.csv").exists()


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
    capture = _write(tmp_path / "capture.csv", "\n".join(lines) + "\n")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    code = main(["estimate", str(capture), "-o", str(out), "--method", "ekf"])
    err = capsys.readouterr().err
    if again.startswith("t_ms,ax"):  # the same fields again: a board reset, read on
        assert code == 0 and out.exists()
        return
    assert code == 2 and not out.exists()
    assert err.count("\n") == 1 and "capture.csv: line 32: " in err and "another order" in err


def test_invalid_option_values_are_one_line_errors(tmp_path, capsys):
    meas = _meas(tmp_path, _good_rows(5))
    for opts in (
        ["--theta-max", "4"],
        ["--length", "-1"],
        ["--horizon", "1"],
        ["--noise-deg", "0"],
    ):
        assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), *opts]) == 2
        err = capsys.readouterr().err
        assert err.startswith("continuum-mhe: error:") and err.count("\n") == 1
    assert not (tmp_path / "e.csv").exists()


def test_read_measurements_raises_input_error_with_line(tmp_path):
    meas = _write(tmp_path / "m.csv", "t,roll,pitch\n0,0.1,0.1\n\n0.1,0.1,inf\n")
    with pytest.raises(InputError, match=r"m.csv: line 4: column pitch is inf"):
        read_measurements(meas)


def test_utf8_bom_header_is_accepted(tmp_path):
    text = "\ufefft,roll,pitch\r\n0,0.1,0.1\r\n0.05,0.1,0.12\r\n"
    table = read_measurements(_write(tmp_path / "bom.csv", text))
    assert table.t.tolist() == [0.0, 0.05]


@pytest.mark.parametrize("target", ["-", "DIR"])
def test_output_must_be_a_regular_file_name(tmp_path, capsys, target):
    meas = _meas(tmp_path, _good_rows(5))
    out = str(tmp_path) if target == "DIR" else target
    assert main(["estimate", str(meas), "-o", out]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert ("standard output" if target == "-" else "is a directory") in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["meas.csv"]


def test_an_output_link_is_written_through(tmp_path):
    """``-o LINK`` writes the file the link points to and keeps the link (a link such as
    ``/dev/stdout`` is not replaced by a file); a link to a folder or a device is
    refused as they are."""
    meas = _meas(tmp_path, _good_rows(5))
    real, link = tmp_path / "real.csv", tmp_path / "link.csv"
    real.write_text("old\n")
    link.symlink_to(real.name)
    assert main(["estimate", str(meas), "-o", str(link), "--overwrite"]) == 0
    assert link.is_symlink() and link.readlink() == Path("real.csv")
    assert real.read_text().startswith("# continuum-mhe = ")
    dangling = tmp_path / "new-link.csv"
    dangling.symlink_to("made.csv")
    assert main(["estimate", str(meas), "-o", str(dangling)]) == 0
    assert dangling.is_symlink() and (tmp_path / "made.csv").is_file()
    to_folder, to_device = tmp_path / "to-folder.csv", tmp_path / "to-device.csv"
    to_folder.symlink_to(tmp_path)
    to_device.symlink_to("/dev/null")
    assert main(["estimate", str(meas), "-o", str(to_folder), "--overwrite"]) == 2
    assert main(["estimate", str(meas), "-o", str(to_device), "--overwrite"]) == 2
    assert to_folder.is_symlink() and to_device.is_symlink()


@pytest.mark.parametrize(("umask", "mode"), [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_outputs_follow_the_umask_at_write_time(tmp_path, umask, mode):
    """The umask in force when the file is written (set here after the import), not
    the one at import: a 0o077 caller gets a private file."""
    import os
    import stat

    meas, est = _meas(tmp_path, _good_rows(5)), tmp_path / "est.csv"
    old = os.umask(umask)
    try:
        assert main(["estimate", str(meas), "-o", str(est)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(est.stat().st_mode) == mode


def test_no_estimate_at_all_is_an_error_and_writes_nothing(tmp_path, capsys):
    meas = _write(tmp_path / "m.csv", "t,roll,pitch\n0,nan,nan\n0.05,,\n0.1,abc,x\n")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 2
    err = capsys.readouterr().err
    assert "no sample gave an estimate" in err and err.count("\n") == 1
    assert not est.exists()


def test_skip_count_is_per_row_not_per_field(tmp_path, capsys):
    rows = _good_rows(10)
    rows[4] = rows[4].split(",")[0] + ",nan,nan"
    meas, est = _meas(tmp_path, rows), tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--skip-bad"]) == 0
    assert "bad rows: 1 sample(s) with a bad value" in capsys.readouterr().err


def test_simulate_rejects_absurd_sizes_and_seeds(tmp_path, capsys):
    out = str(tmp_path / "s.csv")
    assert main(["simulate", "paper3d", "-o", out, "--dt", "1e-9"]) == 2
    assert "--dt 1e-09 is outside its valid range [0.0001, 10] s" in capsys.readouterr().err
    assert main(["simulate", "paper3d", "-o", out, "--seed", "-1"]) == 2
    assert "--seed -1 is outside its valid range" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_evaluate_reports_unmatched_rows(tmp_path, capsys):
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    args = ["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "2"]
    assert main(args) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    lines = truth.read_text().splitlines()
    _write(truth, "\n".join(lines[:11]) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "unmatched rows       31 of 41" in capsys.readouterr().out


def test_table_console_is_wide_when_piped_unless_columns_is_set(monkeypatch):
    """Tables printed into a pipe or a log are not cut at rich's default 80 columns; an
    explicit COLUMNS still wins."""
    from continuum_mhe.progress import PIPED_WIDTH, table_console

    monkeypatch.delenv("COLUMNS", raising=False)
    assert table_console().width == PIPED_WIDTH  # pytest's stdout is not a terminal
    monkeypatch.setenv("COLUMNS", "90")
    assert table_console().width == 90


def test_every_commands_help_is_plain_text():
    """``--help`` of every command has no reStructuredText from a docstring (roles such
    as ``:mod:`` or double backticks)."""
    import argparse

    from continuum_mhe.cli import build_parser

    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    assert len(commands.choices) >= 11
    for name, sub in [("continuum-mhe", parser), *commands.choices.items()]:
        text = sub.format_help()
        for markup in (":mod:", ":func:", ":class:", ":meth:", ":data:", "``"):
            assert markup not in text, f"{name} --help shows {markup}"


def test_a_help_that_names_shipped_robots_names_those_the_command_takes():
    """Where a command's ``--help`` says it takes a shipped robot's name, it lists every
    shipped robot (every command reads tendon robots but those whose help says it takes
    constant-curvature robots only, which list those)."""
    import argparse

    from continuum_mhe.cli import build_parser
    from continuum_mhe.io.robot_file import shipped_robots

    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    said = 0
    for name, sub in commands.choices.items():
        text = " ".join(sub.format_help().split())
        for listed in re.findall(r"shipped robot's name \(([^)]*)\)", text):
            said += 1
            pcc = "constant-curvature" in text and "[[tendon]]" not in text
            want = shipped_robots(tendons=False) if pcc else shipped_robots()
            assert listed.replace("- ", "-").split(", ") == list(want), (name, listed)
    assert said >= 5


#: Options measured worse than the default on the shipped two-section rods (raw IMUs,
#: the MHE, mean tip error in mm, `continuum-mhe estimate ... --robot two-section` and
#: `evaluate`): the option, its `estimate --help` entry, its docs/options.md row, the
#: clause both say.
MEASURED_WORSE = [
    ("--loss welsch", "--loss", "| `--loss huber/cauchy/welsch` |",
     "spatial-tendon 82.82, spatial-stiff-torsion 101.42 mm against 6.89, 16.24 mm"),
    ("--no-estimate-gyro-bias", "--no-estimate-gyro-bias", "| `--no-estimate-gyro-bias` |",
     "planar-s 14.85, spatial-tendon 13.41 mm against 3.77, 6.89 mm"),
    ("--imu-model tilt", "--imu-model", "| `--imu-model tilt` |",
     "planar-s 5.00, spatial-stiff-torsion 29.57 mm against 3.77, 16.24 mm"),
]  # fmt: skip


@pytest.mark.parametrize(("option", "flag", "row", "numbers"), MEASURED_WORSE)
def test_the_help_and_the_options_page_say_an_option_measured_worse(
    option: str, flag: str, row: str, numbers: str
) -> None:
    """An option measurably worse than the default on the shipped rod recordings says
    so in its ``estimate --help`` entry and its docs/options.md table row, with the
    numbers."""
    import argparse

    from continuum_mhe.cli import build_parser

    clause = (
        f"worse on the shipped two-section rods (the shipped robot file, uncalibrated): {numbers}"
    )
    parser = build_parser(only="estimate")
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    help_text = commands.choices["estimate"]._option_string_actions[flag].help or ""
    assert clause in help_text, help_text
    page = (Path(__file__).parents[1] / "docs" / "options.md").read_text(encoding="utf-8")
    (line,) = [ln for ln in page.splitlines() if ln.startswith(row)]
    assert clause in line, line


def test_robot_option_names_only_options_its_command_has():
    """``--robot``'s help says which one-section options it replaces; each is an option
    of that command (view and calibrate have no --theta-max)."""
    import argparse
    import re

    from continuum_mhe.cli import build_parser

    parser = build_parser()
    (commands,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    checked = 0
    for name, sub in commands.choices.items():
        robot = sub._option_string_actions.get("--robot")
        if robot is None:
            continue
        replaced = re.findall(r"--[a-z-]+", (robot.help or "").split("replaces", 1)[-1])
        if "replaces" in (robot.help or ""):
            assert replaced, name
        for option in replaced:
            action = sub._option_string_actions.get(option)
            assert action is not None and action.help != argparse.SUPPRESS, (name, option)
        checked += 1
    assert checked >= 6


def test_simulate_writes_both_files_or_neither(tmp_path, capsys):
    """simulate writes both files or neither: a --truth path in a missing folder, or
    --truth naming -o's file, is one line, exit 2, and no measurement file is written."""
    meas, lost = tmp_path / "g.csv", tmp_path / "no" / "t.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(lost)]) == 2
    assert "folder" in capsys.readouterr().err and not meas.exists()
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(meas)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("--truth names the measurement file -o too; give two files")
    assert len(err.splitlines()) == 1 and not meas.exists()
    # a figure's name for either CSV is refused (not written as CSV under that name)
    for argv in (
        ["-o", str(tmp_path / "m.png")],
        ["-o", str(meas), "--truth", str(tmp_path / "t.pdf")],
    ):
        assert main(["simulate", "paper3d", *argv]) == 2
        err = capsys.readouterr().err.strip()
        assert (
            len(err.splitlines()) == 1 and "is written as CSV (.csv or .txt, or no suffix)" in err
        )
        assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_benchmark_checks_its_json_path_before_the_run(tmp_path, capsys, monkeypatch):
    from continuum_mhe.cli import benchmark

    def no_run(*args, **kwargs):
        raise AssertionError("the benchmark ran before its --json path was checked")

    monkeypatch.setattr(benchmark, "run_benchmark", no_run)
    monkeypatch.setattr(benchmark, "run_robot_benchmark", no_run)
    json_path = str(tmp_path / "no" / "b.json")
    assert main(["benchmark", "--skip", "do-mpc", "--json", json_path]) == 2
    assert capsys.readouterr().err.strip().endswith("does not exist")


def test_demo_refuses_a_file_as_its_folder(tmp_path, capsys):
    target = tmp_path / "afile"
    target.write_text("mine\n")
    assert main(["demo", "--out", str(target)]) == 2
    assert capsys.readouterr().err.strip().endswith("afile: exists and is not a folder")
    assert target.read_text() == "mine\n"


@pytest.fixture
def short_demo(monkeypatch):
    """``demo`` on a 2 s recording (its default is 20 s): the tests that use it check
    the files the demo writes and removes, which the recording's length does not
    change (the README's numbers are checked on the full demo in test_hygiene)."""
    from continuum_mhe.cli import demo

    short = functools.partial(demo.simulate_robot, duration=2.0)
    monkeypatch.setattr(demo, "simulate_robot", short)


def test_a_demo_s_estimates_are_evaluated_on_its_robot(tmp_path, capsys, short_demo) -> None:
    """The demo's estimate files record their method and --robot, as estimate's do:
    evaluate of a two-section demo's file against its truth takes the two-section robot
    without --robot (not the default 0.2 m section, refused)."""
    out = tmp_path / "d"
    assert main(["demo", "--robot", "two-section", "--out", str(out)]) == 0
    assert (
        (out / "estimates_ekf.csv")
        .read_text()
        .startswith('# options = {method = "ekf", robot = "two-section"}\n')
    )
    capsys.readouterr()
    assert main(["evaluate", str(out / "estimates_mhe.csv"), str(out / "truth.csv")]) == 0
    assert "estimated with --robot two-section (its options line)" in capsys.readouterr().err


def test_a_demo_of_one_section_with_its_imu_midway_runs_paper3d(
    tmp_path, capsys, short_demo
) -> None:
    """A one-section robot whose IMU is not at the tip gets the one-section scenario
    (paper3d), not refused as a robot of too few sections for the spatial one."""
    robot = tmp_path / "mid.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\nat = 0.5\n")
    out = tmp_path / "d"
    assert main(["demo", "--robot", str(robot), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "paper3d, 1 section (0.2 m), IMUs at 1@0.5" in said
    assert main(["evaluate", str(out / "estimates_mhe.csv"), str(out / "truth.csv")]) == 0


@pytest.mark.parametrize("existing", [False, True], ids=["new-folder", "existing-folder"])
def test_an_interrupted_demo_leaves_nothing_it_wrote(
    tmp_path, capsys, monkeypatch, existing, short_demo
):
    """Ctrl-C during ``demo`` leaves nothing it wrote: the files are written after the
    estimates, and an interruption while writing (here: while saving the second figure)
    removes the files it created, and the folder it created; a user's own files in an
    existing folder stay."""
    from continuum_mhe.evaluation import plotting

    out = tmp_path / "demo"
    if existing:
        out.mkdir(parents=True)
        (out / "mine.txt").write_text("mine\n")
    saved = []
    real_save = plotting.save

    def save_then_interrupt(fig, path, formats=("png",)):
        saved.append(path)
        if len(saved) == 2:
            raise KeyboardInterrupt
        return real_save(fig, path, formats)

    monkeypatch.setattr(plotting, "save", save_then_interrupt)
    assert main(["demo", "--out", str(out)]) == 130
    assert capsys.readouterr().err.strip().endswith("interrupted")
    assert len(saved) == 2
    if existing:
        assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    else:
        assert not out.exists()  # the folder it made too


def test_a_failed_demo_keeps_the_files_that_were_there(tmp_path, capsys, short_demo):
    """A demo that fails writing (a read-only truth.csv) removes only what it created:
    the read-only file, never replaced, stays as it was (the clean-up does not delete
    it), and so does a replaced estimates file."""
    out = tmp_path / "demo"
    out.mkdir()
    (out / "estimates_mhe.csv").write_text("old\n")
    (out / "truth.csv").write_text("mine\n")
    (out / "truth.csv").chmod(0o444)
    assert main(["demo", "--out", str(out), "--overwrite"]) == 2
    assert "truth.csv: the file is read-only; not replaced" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["estimates_mhe.csv", "truth.csv"]
    assert (out / "truth.csv").read_text() == "mine\n"
    assert (out / "estimates_mhe.csv").read_text().startswith("# options = ")  # replaced, kept


def test_demo_checks_its_folder_before_estimating(tmp_path, capsys, monkeypatch):
    from continuum_mhe.cli import demo

    def no_run(*args, **kwargs):
        raise AssertionError("the demo simulated before checking its --out")

    monkeypatch.setattr(demo, "simulate_robot", no_run)
    (tmp_path / "afile").write_text("x\n")
    assert main(["demo", "--out", str(tmp_path / "afile" / "sub")]) == 2
    assert capsys.readouterr().err.strip().endswith("afile is not a folder")


def test_demo_and_reproduce_keep_their_files_in_their_folder_without_overwrite(
    tmp_path, capsys, monkeypatch
):
    """``demo`` does not replace a ``truth.csv`` already in its folder, nor ``reproduce``
    its experiments' data, without ``--overwrite``: one line naming the file and
    ``--overwrite``, exit 2, before any work, the file kept. A file of another name does
    not stop the demo, nor another part's data ``reproduce --only`` (the report covers
    every part in the folder)."""
    from continuum_mhe.cli import demo
    from continuum_mhe.reproduce import pipeline

    def no_run(*args, **kwargs):
        raise RuntimeError("ran")

    monkeypatch.setattr(demo, "simulate_robot", no_run)
    monkeypatch.setattr(pipeline, "reproduce", no_run)
    out = tmp_path / "out"
    out.mkdir()
    for name, command in (("truth.csv", ["demo"]), ("exp1_synthetic3d.json",
                          ["reproduce", "--quick"])):  # fmt: skip
        (out / name).write_text("mine\n")
        assert main([*command, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err == (
            f"continuum-mhe: error: {out / name}: exists; give --overwrite to replace it, or "
            "another --out\n"
        )
        assert (out / name).read_text() == "mine\n"
        assert main([*command, "--out", str(out), "--overwrite"]) == 70  # the stand-in ran
        assert "RuntimeError: ran" in capsys.readouterr().err
    (out / "truth.csv").rename(out / "notes.txt")
    assert main(["demo", "--out", str(out)]) == 70
    assert main(["reproduce", "--quick", "--only", "beyond", "--out", str(out)]) == 70
    assert main(["reproduce", "--quick", "--only", "paper", "--out", str(out)]) == 2
    capsys.readouterr()


def test_main_gives_the_caller_its_warnings_and_signal_handlers_back(tmp_path):
    """A script or test that calls ``main`` keeps numpy's warnings, its warning format
    and its Ctrl-C handler: the command's settings do not outlive the call."""
    import signal
    import warnings

    meas, est = _meas(tmp_path, _good_rows(5)), tmp_path / "est.csv"
    fmt, filters = warnings.formatwarning, list(warnings.filters)
    handlers = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    assert warnings.formatwarning is fmt
    assert warnings.filters == filters
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == handlers
    with pytest.warns(RuntimeWarning, match="divide by zero"):
        np.float64(1.0) / np.float64(0.0)


def test_evaluate_warns_when_the_length_does_not_fit_the_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """evaluate --length 0.3 on files made for a 0.2 m robot (tip errors in % of the
    wrong length) warns: each file whose tip is not where its own angles put it on the
    given robot is named, with the length it was made for; a truth without angles whose
    tip is farther from the base than the length is named too."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth),
                 "--duration", "2"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--length", "0.2"]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["evaluate", str(est), str(truth), "--length", "0.3"]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert said == [
        f"continuum-mhe: warning: {path}: its tip is 0.67 times as far from the base as its own "
        "angles put it on a robot of 0.3 m: it was made for a robot of about 0.2 m; pass the "
        "--length (or --robot) it was made with"
        for path in (est, truth)
    ]
    tip_only = tmp_path / "tip.csv"
    rows = [ln.split(",")[:4] for ln in truth.read_text().splitlines()]
    tip_only.write_text("\n".join(",".join(r) for r in rows) + "\n")
    assert main(["evaluate", str(est), str(tip_only), "--length", "0.1"]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if str(tip_only) in ln]
    assert len(said) == 1 and "m from the base, beyond the robot's length 0.1 m" in said[0]


def test_evaluate_takes_the_length_the_estimate_records(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An estimate made with --length 0.3 is evaluated on 0.3 m without --length (its
    options line records it, so that the tip error in % is of 0.3 m, as the note
    says), said in a note; --length given wins; the default length records
    nothing to say."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth),
                 "--duration", "2", "--length", "0.3"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf", "--length", "0.3"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: note: {est} was estimated on 1 section (0.3 m), IMUs at 1@1, z-up "
        "(its options line: --length 0.3): evaluated on that robot (pass --length or --robot "
        "for another)\n"
    )
    tip_mm = float(out.split("tip error mean")[1].split("mm")[0])
    share = float(out.split("tip error mean")[1].split("(")[1].split("%")[0])
    assert share == pytest.approx(100 * tip_mm / 300, abs=0.01)
    assert main(["evaluate", str(est), str(truth), "--length", "0.3"]) == 0
    assert "note" not in capsys.readouterr().err
    # a hanging robot of the default length: its mounting is recorded too
    meas_down, est_down = tmp_path / "md.csv", tmp_path / "ed.csv"
    assert main(["simulate", "paper3d", "-o", str(meas_down), "--duration", "2",
                 "--mounting", "z-down"]) == 0  # fmt: skip
    argv = ["estimate", str(meas_down), "-o", str(est_down), "--method", "ekf"]
    assert main([*argv, "--mounting", "z-down"]) == 0
    capsys.readouterr()
    from continuum_mhe.cli.robot_options import recorded_robot

    robot = recorded_robot(str(est_down), "used")
    assert robot is not None and robot.mounting == "z-down" and robot.lengths == (0.2,)


def test_simulate_says_that_a_robot_files_mount_rpy_is_not_applied(tmp_path, capsys):
    """simulate --robot writes the disks' roll and pitch and says, in a note, that the
    robot file's mount_rpy of an IMU is not applied (estimate says the same of tilt
    input); a robot file without mount_rpy gets no note."""
    robot = tmp_path / "r.toml"
    robot.write_text(
        "[[section]]\nlength = 0.16\ntheta_max = 3.0\n[[section]]\nlength = 0.14\n"
        "theta_max = 3.0\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
        "mount_rpy = [0.0, 8.0, -20.0]\n"
    )
    argv = ["simulate", "spatial", "--robot", str(robot), "--duration", "1"]
    assert main([*argv, "-o", str(tmp_path / "m.csv")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[1] == (
        "continuum-mhe: note: the robot file's mount_rpy of IMU 2 is not applied: the roll "
        "and pitch written are those of each IMU's disk, as estimate takes tilt input"
    )
    assert main(["simulate", "spatial", "--robot", "two-section", "--duration", "1",
                 "-o", str(tmp_path / "m2.csv")]) == 0  # fmt: skip
    assert "mount_rpy" not in capsys.readouterr().err
    # raw readings are turned by mount_rpy (as estimate reads them back): no note
    assert main([*argv, "--imu", "raw", "-o", str(tmp_path / "m3.csv")]) == 0
    assert "mount_rpy" not in capsys.readouterr().err


def _shifted(truth: Path, out: Path, seconds: float) -> Path:
    """``truth`` with every ``t`` later by ``seconds``, written to ``out``."""
    rows = truth.read_text().splitlines()
    shifted = [f"{float(r.split(',')[0]) + seconds!r},{r.split(',', 1)[1]}" for r in rows[1:]]
    out.write_text("\n".join([rows[0], *shifted]) + "\n")
    return out


def test_evaluate_warns_when_the_truths_clock_is_offset(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A truth file whose times run 0.5 s late (another clock): evaluate warns, naming
    the shift and both errors; the truth as it was gives no warning."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--seed", "2"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    late = _shifted(truth, tmp_path / "late.csv", 0.5)
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "warning" not in capsys.readouterr().err
    assert main(["evaluate", str(est), str(late)]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(said) == 1 and re.fullmatch(
        rf"continuum-mhe: warning: {re.escape(str(late))}: the truth fits the estimate best "
        r"\+0\.5 s later \(mean tip error \d\.\d+ mm against \d\d\.?\d* mm as the times match\): "
        r"are the two files' clocks offset\? \(a motion that repeats can fit shifted too; "
        r"--truth-shift 0\.5 compares them so\)",
        said[0],
    ), said
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    same = json.loads(capsys.readouterr().out)
    assert main(["evaluate", str(est), str(late), "--truth-shift", "0.5", "--json"]) == 0
    shifted, err = capsys.readouterr()
    assert "warning" not in err  # compared as the clocks run, the tip as on one clock
    assert json.loads(shifted)["tip_mean_mm"] == pytest.approx(same["tip_mean_mm"], abs=1e-9)
    # a shift given the wrong way: the shift advised is the whole one, not the rest
    assert main(["evaluate", str(est), str(late), "--truth-shift", "-0.5"]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(said) == 1 and "+1 s later than --truth-shift -0.5 puts it" in said[0], said
    assert said[0].endswith("--truth-shift 0.5 compares them so)"), said
    far = _shifted(truth, tmp_path / "far.csv", 12.75)  # the whole shift, every digit
    assert main(["evaluate", str(est), str(far), "--truth-shift", "12.25"]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "clocks offset" in ln]
    assert len(said) == 1 and said[0].endswith("--truth-shift 12.75 compares them so)"), said
    # one row far off (a glitch) makes no shift look better
    lines = est.read_text().splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("t,")) + 3
    head = lines[at].split(",")
    head[1] = "1000000"
    lines[at] = ",".join(head)
    glitch = tmp_path / "glitch.csv"
    glitch.write_text("\n".join(lines) + "\n")
    assert main(["evaluate", str(glitch), str(truth)]) == 0
    assert "clocks offset" not in capsys.readouterr().err


def test_evaluate_skip_start_scores_the_rows_after_the_start_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--skip-start 1``: the scores are those of the estimate rows from 1 s after its
    first on, the tip error's mean and maximum computed here from the two files; a skip
    that leaves fewer than two rows is one line and exit 2."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--seed", "3",
                 "--duration", "4"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    e, tr = read_state_table(est), read_state_table(truth)
    assert np.array_equal(e.t, tr.t)
    tip = np.linalg.norm(np.column_stack([e.column(c) - tr.column(c) for c in "xyz"]), axis=1)
    later = e.t >= e.t[0] + 1.0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--skip-start", "1", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["n"] == int(later.sum()) < len(e.t) and got["skip_start_s"] == 1.0
    assert got["tip_mean_mm"] == pytest.approx(1e3 * float(tip[later].mean()), rel=1e-9)
    assert got["tip_max_mm"] == pytest.approx(1e3 * float(tip[later].max()), rel=1e-9)
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    whole = json.loads(capsys.readouterr().out)
    assert whole["tip_mean_mm"] == pytest.approx(1e3 * float(tip.mean()), rel=1e-9)
    assert whole["tip_mean_mm"] != pytest.approx(got["tip_mean_mm"], rel=1e-3)
    assert main(["evaluate", str(est), str(truth), "--skip-start", "10"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == (
        f"continuum-mhe: error: {est}: fewer than two rows after --skip-start 10 s (its rows "
        "span 4 s)\n"
    )


def test_skip_start_keeps_the_row_at_its_time_and_starts_at_the_first_finite_time() -> None:
    """Rows 0.01 s apart from t = 0.29 s, the first time NaN (a row without an estimate):
    ``--skip-start 1`` keeps the rows from 1.30 s on, the row at 1.30 s included (its
    time, 1.2999999999999998, rounds below 0.30000000000000004 + 1), and no other."""
    from continuum_mhe.cli.evaluate import _after_start
    from continuum_mhe.io.state_tables import StateTable

    t = 0.14 + 0.01 * np.arange(15, 315)
    t[0] = np.nan
    assert t[101] < t[1] + 1.0
    table = StateTable(
        t=t, names=("x",), values=t[:, None].copy(), status=np.full(300, "ok"),
        std=np.ones((300, 1)), outlier=np.zeros(300, bool),
    )  # fmt: skip
    kept = _after_start("e.csv", table, 1.0)
    assert len(kept.t) == 300 - 101 and kept.t[0] == t[101]  # 0.15 + 1.0, to rounding
    assert np.array_equal(kept.values[:, 0], t[101:]) and kept.std is not None
    assert kept.std.shape == (199, 1) and kept.outlier is not None and len(kept.outlier) == 199


def test_the_tip_nees_line_says_which_side_of_its_band_and_what_it_means() -> None:
    """Below the band the intervals are wider than the errors, above it narrower."""
    from continuum_mhe.cli.evaluate import format_calibration
    from continuum_mhe.evaluation.metrics import Calibration

    def line(nees: float) -> str:
        c = Calibration({"x": 0.95}, {"x": 100}, nees, (2.7, 3.3), 100, 40.2)
        return format_calibration(c).splitlines()[1]

    assert line(3.0).endswith(
        "95% band 2.70 to 3.30, for the 40 independent samples they are worth, their "
        "errors correlated in time: inside)"
    )
    assert line(0.6).endswith(": outside, below: the intervals are wider than the errors)")
    assert line(9.0).endswith(": outside, above: the intervals are narrower than the errors)")


def test_zero_tip_stds_count_as_misses_and_are_said_left_out_of_the_nees() -> None:
    """Rows with a zero standard deviation on a tip axis: the coverage counts them, as
    misses where the error is not zero; the NEES (infinite for them) leaves them out, and
    says how many, so that the two numbers' rows can be told apart."""
    from continuum_mhe.cli.evaluate import format_calibration
    from continuum_mhe.evaluation.metrics import compute_calibration

    names = ["x", "y", "z"]
    truth = np.zeros((10, 3))
    est = np.full((10, 3), 0.001)
    std = np.full((10, 3), 0.001)
    std[:3, 2] = 0.0  # three rows claim an exact z, 1 mm off
    c = compute_calibration(est, std, truth, names)
    assert c.coverage == {"x": 1.0, "y": 1.0, "z": 0.7} and c.n == {"x": 10, "y": 10, "z": 10}
    assert (c.tip_n, c.tip_zero_std) == (7, 3) and c.tip_nees == pytest.approx(3.0)
    assert (
        format_calibration(c)
        .splitlines()[1]
        .endswith(
            "; 3 samples with a zero tip std left out, counted in the coverage as misses unless "
            "their error is zero)"
        )
    )
    est[:3, 2] = 0.0  # exact where the std says so: inside
    assert compute_calibration(est, std, truth, names).coverage["z"] == 1.0


def test_a_truth_on_its_own_clock_is_interpolated_at_the_estimates_times(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A motion capture's rows are not at the IMUs' times: the truth of the same motion
    at 120 Hz, 3 ms off the estimate's 20 Hz grid, is interpolated at the estimate's
    times (a note says so) and scores within 0.05 mm of the truth on the same grid, and
    plot draws it; a truth sampled more sparsely than twice the estimate's step is
    compared at the estimate rows nearest its samples, within 0.2 mm of
    the scores on the same grid."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--seed", "2"]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    fine = tmp_path / "t120.csv"
    assert main(["simulate", "paper3d", "-o", str(tmp_path / "m120.csv"), "--truth", str(fine),
                 "--seed", "2", "--dt", str(1 / 120)]) == 0  # fmt: skip
    rows = fine.read_text().splitlines()
    off = _shifted(fine, tmp_path / "t120_off.csv", 0.003)
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    same = json.loads(capsys.readouterr().out)
    assert main(["evaluate", str(est), str(off), "--json"]) == 0
    captured = capsys.readouterr()
    interpolated = json.loads(captured.out)
    assert f"{off}'s rows are not at {est}'s times: the truth is interpolated" in captured.err
    assert interpolated["tip_mean_mm"] == pytest.approx(same["tip_mean_mm"], abs=0.05)
    figure = tmp_path / "e.png"  # plot draws it so too
    assert main(["plot", str(est), "--truth", str(off), "-o", str(figure)]) == 0
    assert "the truth is interpolated linearly at them (400 of 401 rows)" in (  # t = 0: before
        capsys.readouterr().err
    )
    assert figure.stat().st_size > 1000
    sparse = tmp_path / "t5.csv"
    sparse.write_text("\n".join([rows[0], *rows[3::24]]) + "\n")  # 5 Hz, off the grid
    assert main(["evaluate", str(est), str(sparse), "--json"]) == 0
    captured = capsys.readouterr()
    assert "rows nearest the truth's samples" in captured.err
    got = json.loads(captured.out)
    assert got["n"] >= 0.9 * (len(rows) - 1) / 24
    assert got["tip_mean_mm"] == pytest.approx(same["tip_mean_mm"], abs=0.2)


def test_truth_at_interpolates_inside_its_span_and_not_across_a_gap() -> None:
    """Known answers: a line is interpolated exactly; a wrapped angle crossing pi is
    interpolated through its unwrapped values; rows outside the truth's span or inside
    a gap of it are left out; a truth sparser than twice the estimate's step is
    interpolated at the estimate rows nearest its samples alone (within half a step),
    the first sample's nearest row too where it lies before that sample."""
    from continuum_mhe.evaluation.metrics import truth_at

    t_truth = np.array([0.0, 0.1, 0.2, 0.3, 1.0, 1.1])  # a gap from 0.3 to 1.0 s
    values = np.column_stack([2.0 * t_truth, [3.0, 3.1, -3.1, -3.0, 0.0, 0.0]])
    t_est = np.array([-0.05, 0.05, 0.15, 0.25, 0.6, 1.05, 1.2])
    i_est, rows = truth_at(t_est, t_truth, values, ["x", "phi"])
    assert list(i_est) == [1, 2, 3, 5]
    np.testing.assert_allclose(rows[:, 0], 2.0 * t_est[i_est])
    unwrapped = np.unwrap(values[:, 1])
    expected = (np.interp(t_est[i_est], t_truth, unwrapped) + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(rows[:, 1], expected)
    assert abs(rows[1, 1]) > 3.1  # across pi, not through 0
    sparse = np.arange(0, 1, 0.05) + 0.002  # a step of five of the estimate's, 2 ms off
    t_fine = np.arange(0, 1, 0.01)
    near = truth_at(t_fine, sparse, 3.0 * sparse[:, None], ["x"])
    assert near is not None and list(near[0]) == list(range(0, 96, 5))
    np.testing.assert_allclose(near[1][1:, 0], 3.0 * t_fine[near[0][1:]])
    assert near[1][0, 0] == 3.0 * sparse[0]  # t = 0, 2 ms before the first sample: its value
    column = values[:, 1].copy()  # a NaN row elsewhere does not stop the unwrapping
    column[-1] = np.nan
    _, with_nan = truth_at(t_est, t_truth, np.column_stack([values[:, 0], column]), ["x", "psi_1"])
    np.testing.assert_allclose(with_nan[:3, 1], expected[:3])


def test_best_time_shift_finds_a_clock_offset_to_the_sample_and_none_where_there_is_none() -> None:
    """On a 1 kHz tip path whose truth runs 0.317 s late, the shift found is 0.317 s to
    the sample (the grid, then its refinement), with no error left; a truth on the same
    clock, and a constant tip (every shift ties), give a shift of 0."""
    from continuum_mhe.evaluation.metrics import best_time_shift

    t = np.arange(0.0, 20.0, 0.001)
    tip = np.column_stack([np.sin(0.7 * t), np.cos(0.3 * t), 0.2 + 0.1 * np.sin(1.1 * t)]) * 0.1
    late = best_time_shift(t, tip, t + 0.317, tip)
    assert late is not None and late.shift_s == pytest.approx(0.317, abs=1e-9)
    assert late.error < 1e-9 < late.unshifted
    same = best_time_shift(t, tip, t, tip)
    assert same is not None and same.shift_s == 0.0
    still = np.tile([0.0, 0.0, 0.2], (len(t), 1))
    flat = best_time_shift(t, still, t, still + 1e-3)
    assert flat is not None and flat.shift_s == 0.0 and flat.error == flat.unshifted


def test_simulate_says_where_the_motion_bends_past_theta_max(tmp_path, capsys):
    """paper3d bends a section to 1.44 rad: on a robot whose theta_max is 1 the note
    says so (its estimates there are at-bound); within the bound, nothing."""
    robot = _write(tmp_path / "r.toml", "[[section]]\nlength = 0.05\ntheta_max = 1.0\n"
                   "[[imu]]\nsection = 1\n")  # fmt: skip
    assert main(["simulate", "paper3d", "--robot", str(robot), "-o", str(tmp_path / "a.csv")]) == 0
    err = capsys.readouterr().err
    assert (
        "bends section 1 to 1.44 rad, beyond its theta_max 1: estimates there are at-bound" in err
    )
    assert main(["simulate", "paper3d", "-o", str(tmp_path / "b.csv")]) == 0
    assert "theta_max" not in capsys.readouterr().err


@pytest.mark.parametrize("command", ["plot", "view"])
def test_plot_and_view_of_an_estimate_without_its_tip_columns_is_one_line(
    tmp_path, capsys, command
):
    """A table without x, y, z is refused in one line by plot and view, not an internal
    error (exit 70)."""
    est = _write(tmp_path / "est.csv", "t,theta,phi,status\n0,0.1,0.2,ok\n0.05,0.1,0.2,ok\n")
    out = {"plot": ["-o", str(tmp_path / "f.png")], "view": ["--save", str(tmp_path / "f.rrd")]}
    assert main([command, str(est), *out[command]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "x, y, z" in err


@settings(max_examples=60, deadline=None)
@given(
    rate=st.floats(20.0, 400.0),
    ratio=st.floats(0.55, 1.9),
    offset=st.floats(0.0, 0.02),
    omega=st.floats(-40.0, 40.0),
)
def test_truth_at_follows_a_turning_angle_across_pi(
    rate: float, ratio: float, offset: float, omega: float
) -> None:
    """A bending plane turning at ``omega`` rad/s (phi wrapped, crossing pi many times)
    sampled at ``rate`` Hz, read at another rate and offset: the interpolated phi is
    the turning angle there, wrapped, to the chord's error of a linear interpolation
    (none: the angle is linear in t), and a line in ``x`` is exact."""
    from continuum_mhe.evaluation.metrics import truth_at
    from continuum_mhe.model.imu import wrap_angle

    t_truth = np.arange(0.0, 2.0, 1.0 / rate)
    values = np.column_stack([3.0 * t_truth, wrap_angle(omega * t_truth)])
    t_est = np.arange(offset, 2.0, ratio / rate)
    found = truth_at(t_est, t_truth, values, ["x", "phi_2"])
    assert found is not None
    i_est, rows = found  # every row inside the truth's span, none outside
    assert list(i_est) == list(np.flatnonzero(t_est <= t_truth[-1]))
    np.testing.assert_allclose(rows[:, 0], 3.0 * t_est[i_est], atol=1e-12)
    # the wrapped difference: the interpolated angle against the true one
    diff = wrap_angle(rows[:, 1] - omega * t_est[i_est])
    assert np.max(np.abs(diff)) < 1e-9


def test_evaluate_takes_the_truth_as_plot_does_too(tmp_path, capsys):
    """``evaluate EST --truth TRUTH`` (as ``plot`` and ``view`` take it) scores as
    ``evaluate EST TRUTH``; both, or neither, is one line, exit 2. (``--truth`` is not
    read as an abbreviation of ``--truth-shift``: "expected a number".)"""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert (
        main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "2"])
        == 0
    )
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    positional = json.loads(capsys.readouterr().out)
    assert main(["evaluate", str(est), "--truth", str(truth), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == positional
    for argv, says in (
        ([str(est), str(truth), "--truth", str(truth)], "two truths"),
        ([str(est)], "no truth to score it against"),
    ):
        assert main(["evaluate", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and says in err[0], err


def test_evaluate_says_the_ok_rows_are_unknown_without_a_status_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An estimate without a status column: its ok rows are unknown (not every row), in
    the text and as null in --json; without std_ columns: the ok rows counted, and no
    coverage (not 0 ok rows)."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert (
        main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "4"])
        == 0
    )
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    lines = [ln for ln in est.read_text().splitlines() if not ln.startswith("#")]
    header = lines[0].split(",")
    rows = [ln.split(",") for ln in lines[1:]]
    n_ok = sum(r[header.index("status")] == "ok" for r in rows)

    def without(keep: list[int], name: str) -> Path:
        out = tmp_path / name
        out.write_text("\n".join(",".join(r[i] for i in keep) for r in [header, *rows]) + "\n")
        return out

    no_status = without([i for i, c in enumerate(header) if c != "status"], "nostatus.csv")
    no_std = without([i for i, c in enumerate(header) if not c.startswith("std_")], "nostd.csv")
    capsys.readouterr()
    assert main(["evaluate", str(no_status), str(truth)]) == 0
    assert (
        f"ok rows              unknown: {no_status} has no status column" in capsys.readouterr().out
    )
    assert main(["evaluate", str(no_status), str(truth), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ok_rows"] is None
    assert main(["evaluate", str(no_std), str(truth)]) == 0
    said = capsys.readouterr().out
    assert f"ok rows              {n_ok} of {len(rows)} (no std_ columns: no coverage)" in said
    assert main(["evaluate", str(no_std), str(truth), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["ok_rows"] == n_ok > 0


def test_a_second_demo_in_its_own_folder_replaces_its_files(tmp_path, monkeypatch, short_demo):
    """The README's main command runs twice: without ``--out`` the demo writes into its
    own folder and replaces the files of the demo before (with ``--out`` a folder that
    holds them needs ``--overwrite``: the test above)."""
    from continuum_mhe.cli.demo import DEFAULT_OUT

    monkeypatch.chdir(tmp_path)
    assert main(["demo"]) == 0
    for name in ("truth.csv", "estimates_mhe.csv"):
        (tmp_path / DEFAULT_OUT / name).write_text("old\n")
    assert main(["demo"]) == 0
    assert (tmp_path / DEFAULT_OUT / "truth.csv").read_text().startswith("t,")
    assert (tmp_path / DEFAULT_OUT / "estimates_mhe.csv").read_text().startswith("# options")


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (("length = 0.3", 'length = "abc"'), "its options line's length = 'abc' make(s) no robot"),
        (("length = 0.3", "length = -1.0"), "its options line makes no robot (section length"),
        (
            ('mounting = "z-up"', 'mounting = "sideways"'),
            "its options line's mounting = 'sideways' make(s) no robot",
        ),
    ],
    ids=["length-text", "length-negative", "mounting"],
)
def test_an_options_line_that_makes_no_robot_is_said(tmp_path, capsys, edit, said):
    """An estimate whose options line records a length or mounting that makes no robot
    (edited by hand) is evaluated on the default section with a note naming the value
    (not taken silently, nor a mounting read as z-up); the recorded 0.3 m is taken."""
    meas, truth, est = (tmp_path / n for n in ("m.csv", "t.csv", "e.csv"))
    assert (
        main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth", str(truth)])
        == 0
    )
    assert main(["estimate", str(meas), "--length", "0.3", "--method", "ekf", "-o", str(est)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "estimated on 1 section (0.3 m)" in capsys.readouterr().err
    text = est.read_text()
    assert text.count(edit[0]) == 1
    est.write_text(text.replace(*edit))
    assert main(["evaluate", str(est), str(truth)]) == 0
    err = capsys.readouterr().err
    assert f"note: {est}: {said}" in err and "the default one section of 0.2 m is used" in err
    assert err.count("note:") == 1, err  # said once


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


def test_plot_of_a_folder_without_results_says_so_before_its_options(tmp_path, capsys) -> None:
    """``plot FOLDER -o P.png`` on a folder that ``reproduce`` did not write: the folder
    holds no results (not that the folder is a reproduce folder and -o the fault)."""
    from continuum_mhe.cli import main

    folder = tmp_path / "empty"
    folder.mkdir()
    assert main(["plot", str(folder), "-o", str(tmp_path / "p.png")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith(f"continuum-mhe: error: {folder}: no experiment data (expected "), line
    assert not (tmp_path / "p.png").exists()


def test_a_gap_in_a_truth_file_is_a_row_without_truth_and_named_elsewhere(tmp_path, capsys):
    """A truth row with a NaN or an empty cell (a marker the motion capture lost):
    ``evaluate`` compares the other rows and counts it "without a finite truth" (not
    refused with a "NaN or infinite value" that names no column), and leaves out a column of
    text that no output is named as; a reader that takes no gaps (``read_state_table``
    without ``gaps``) names the line and the column."""
    from continuum_mhe.cli import main
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.state_tables import read_state_table

    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth",
                 str(truth)]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    lines = truth.read_text().splitlines()
    header = lines[0].split(",")
    for i, cell in ((5, "nan"), (9, "")):
        row = lines[i].split(",")
        row[header.index("y")] = cell
        lines[i] = ",".join(row)
    truth.write_text("\n".join(lines) + "\n")
    # and a column of text that no output is named as (a motion capture's marker label)
    with_label = [lines[0] + ",marker"] + [ln + ",tip" for ln in lines[1:]]
    truth.write_text("\n".join(with_label) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    out = capsys.readouterr().out
    assert "(0 without estimate, 2 without a finite truth)" in out, out
    truth.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as refused:
        read_state_table(truth)
    assert str(refused.value) == (
        f"{truth}: line 6: column y is nan (every row needs a finite value in each column)"
    )
    # where an empty or nan cell is a gap, an infinity is not one: the line says what is
    row = lines[5].split(",")
    row[header.index("y")] = "inf"
    lines[5] = ",".join(row)
    truth.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as refused:
        read_state_table(truth, gaps=True)
    assert str(refused.value) == (
        f"{truth}: line 6: column y is inf (leave the cell empty (or nan) for a value not measured)"
    )
    row = lines[5].split(",")  # a gap before it in the row: the infinity is named
    row[header.index("x")] = ""
    lines[5] = ",".join(row)
    truth.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="line 6: column y is inf"):
        read_state_table(truth, gaps=True)


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


def test_evaluate_names_the_shift_of_a_clock_that_did_not_start_at_zero(tmp_path, capsys):
    """An estimate whose times are the truth's plus one offset (a device clock that did
    not start at 0, as live's): the refusal names the --truth-shift that compares them,
    and that shift scores them."""
    t = np.arange(50) * 0.02
    tip = np.column_stack([0.01 * np.sin(t), 0.01 * np.cos(t), 0.2 + 0 * t])
    truth = tmp_path / "truth.csv"
    est = tmp_path / "est.csv"
    _write(truth, "t,x,y,z\n" + "".join(f"{a:.6f},{b},{c},{d}\n" for a, (b, c, d) in zip(t, tip)))
    _write(est, "t,x,y,z\n" + "".join(
        f"{a + 123.456:.6f},{b},{c},{d}\n" for a, (b, c, d) in zip(t, tip)))  # fmt: skip
    assert main(["evaluate", str(est), str(truth), "--length", "0.2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "the files' times do not match" in err
    assert err.endswith("(a clock that did not start at 0?): --truth-shift -123.456 compares them")
    assert main(["evaluate", str(est), str(truth), "--length", "0.2",
                 "--truth-shift=-123.456"]) == 0  # fmt: skip
    # the offset is the clock's, not moved by the rows --skip-start leaves out
    assert main(["evaluate", str(est), str(truth), "--length", "0.2",
                 "--skip-start", "0.4"]) == 2  # fmt: skip
    assert capsys.readouterr().err.strip().endswith("--truth-shift -123.456 compares them")


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
    meas = _write(tmp_path / "m.csv", "t,roll,pitch\n" + "\n".join(rows) + "\n")
    with open_input(meas, InputOptions(skip_bad=True), make_formulation("bend")) as stream:
        z = np.vstack([b[1] for b in stream.blocks])
    assert len(z) == n and np.isnan(z[-2]).all() and np.isfinite(z[-1]).all()


@pytest.fixture(scope="module")
def mocap_run(tmp_path_factory) -> tuple[Path, Path, Path]:
    """A two-section raw estimate at 100 Hz (``spatial``, 10 s; about 2.5 mm off at the
    tip) and its truth at 1 kHz, from which motion captures are taken."""
    folder = tmp_path_factory.mktemp("mocap")
    meas, truth, est = folder / "m.csv", folder / "t.csv", folder / "e.csv"
    fine = ["simulate", "spatial", "--robot", "two-section", "--imu", "raw", "--dt", "0.001"]
    assert main([*fine, "--duration", "10", "-o", str(meas), "--truth", str(truth)]) == 0
    lines = meas.read_text().splitlines()
    (folder / "m100.csv").write_text("\n".join([lines[0], *lines[1::10]]) + "\n")
    assert (
        main(["estimate", str(folder / "m100.csv"), "--robot", "two-section", "-o", str(est)]) == 0
    )
    return folder, truth, est


def _capture(truth: Path, out: Path, hz: float, offset: float = 0.0, t0: float = 0.0) -> Path:
    """``truth`` (1 kHz) sampled at ``hz`` as a motion capture whose clock reads ``t0``
    at the estimate's 0 and runs ``offset`` s late (each row holds the truth ``offset``
    s before its time), tip columns only."""
    rows = np.loadtxt(truth, delimiter=",", skiprows=1, usecols=(0, 1, 2, 3))
    t = np.arange(0.0, rows[-1, 0] - offset, 1.0 / hz)
    xyz = np.column_stack([np.interp(t, rows[:, 0], rows[:, k]) for k in (1, 2, 3)])
    table = np.column_stack([t0 + t + offset, xyz])
    out.write_text("t,x,y,z\n" + "".join(",".join(repr(float(v)) for v in r) + "\n" for r in table))
    return out


def _evaluate_json(capsys, *argv: str) -> tuple[dict, str]:
    assert main(["evaluate", *argv, "--json"]) == 0
    out, err = capsys.readouterr()
    return json.loads(out), err


def test_a_motion_capture_offset_by_tens_of_ms_is_said(mocap_run, capsys) -> None:
    """A 120 Hz motion capture whose clock runs 40 ms late triples a 2.5 mm error: the
    offset is looked for from a mean tip error of 1 % of the robot's length, said, and
    the shift advised brings the error back."""
    folder, truth, est = mocap_run
    good = _capture(truth, folder / "mc120.csv", 120.0)
    late = _capture(truth, folder / "mc120_late.csv", 120.0, offset=0.04)
    base, err = _evaluate_json(capsys, str(est), str(good))
    assert base["tip_mean_mm"] < 4.0 and "clocks offset" not in err
    off, err = _evaluate_json(capsys, str(est), str(late))
    assert off["tip_mean_mm"] > 2 * base["tip_mean_mm"]
    (line,) = [ln for ln in err.splitlines() if "clocks offset" in ln]
    shift = float(re.search(r"--truth-shift (\S+) compares them so", line)[1])
    assert 0.02 <= shift <= 0.05
    back, _ = _evaluate_json(capsys, str(est), str(late), "--truth-shift", "0.04")
    assert back["tip_mean_mm"] == pytest.approx(base["tip_mean_mm"], rel=0.05)
    # the text report says what it compared
    assert (
        main(["evaluate", str(est), str(late), "--truth-shift", "0.04", "--skip-start", "1"]) == 0
    )
    assert "compared             the truth 0.04 s later, from 1 s after the first row\n" in (
        capsys.readouterr().out
    )


def test_a_sparser_motion_capture_is_scored_at_the_rows_nearest_its_samples(
    mocap_run, capsys
) -> None:
    """A 30 Hz capture against 100 Hz estimates (a truth more than twice as sparse) is
    compared at the estimate row nearest each
    of its samples (within half an estimate step; a row just outside its times takes its
    end sample's values), said in the note
    and with no warning of rows left out, and its tip error there is the numpy one (the
    capture interpolated linearly at those rows) to 1 um."""
    folder, truth, est = mocap_run
    sparse = _capture(truth, folder / "mc30.csv", 30.0)
    got, err = _evaluate_json(capsys, str(est), str(sparse))
    assert "of its 1001 rows nearest the truth's samples" in err and "warning" not in err
    e = read_state_table(est)
    tr = np.loadtxt(sparse, delimiter=",", skiprows=1)
    near = np.abs(e.t[None, :] - tr[:, :1]).argmin(axis=1)
    near = near[np.abs(e.t[near] - tr[:, 0]) <= 0.005 + 1e-12]
    true = np.column_stack([np.interp(e.t[near], tr[:, 0], tr[:, k]) for k in (1, 2, 3)])
    tip = np.column_stack([e.column(c)[near] for c in ("x", "y", "z")])
    mean = np.linalg.norm(tip - true, axis=1).mean() * 1e3
    assert np.any(e.t[near] > tr[-1, 0])  # the last sample's row lies after it
    assert got["n"] == len(near) > 290
    assert got["tip_mean_mm"] == pytest.approx(mean, abs=1e-3)
    # plot draws that truth and its error: no NaN row between its samples
    from continuum_mhe.evaluation.estimate_tables import truth_at_rows
    from continuum_mhe.evaluation.metrics import aligned_truth

    t_sparse = read_state_table(sparse)
    i_est, rows, interpolated = aligned_truth(
        e.t, t_sparse.t, t_sparse.values, t_sparse.names, warn=False
    )
    at = truth_at_rows(e, t_sparse, i_est, rows, interpolated)
    assert at is not None and np.isfinite(at.values).all() and len(at.t) == len(near)


@pytest.mark.parametrize("hz", [1.0, 2.5])
def test_a_truth_far_sparser_on_the_estimates_times_is_scored_on_its_rows(
    mocap_run, capsys, hz: float
) -> None:
    """Snapshots at 1 and 2.5 Hz against 100 Hz estimates (40 and 100 times as sparse),
    on the estimate's own times across the whole run: scored at those rows, neither
    refused as times that do not match (11 rows) nor said to cover part of the run."""
    folder, truth, est = mocap_run
    snaps = _capture(truth, folder / f"snap{hz:g}.csv", hz)
    got, err = _evaluate_json(capsys, str(est), str(snaps))
    assert got["n"] == len(snaps.read_text().splitlines()) - 1, err
    assert "warning" not in err, err
    # a capture at the estimate's rate with t in milliseconds spans 1000 times the run:
    # refused, not scored on the rows whose t it happens to reach
    lines = _capture(truth, folder / "c100.csv", 100.0).read_text().splitlines()
    ms = folder / f"snap{hz:g}_ms.csv"
    rows = [r.split(",", 1) for r in lines[1:]]
    ms.write_text("\n".join([lines[0]] + [f"{float(a) * 1e3!r},{b}" for a, b in rows]) + "\n")
    assert main(["evaluate", str(est), str(ms)]) == 2
    assert "milliseconds" in capsys.readouterr().err


def test_a_capture_of_part_of_the_run_is_scored_with_a_warning(mocap_run, capsys) -> None:
    """A 1.5 s capture inside the 10 s run (15 % of its rows): scored on those rows with
    a warning, not refused as times that do not match (a truth of other times is)."""
    folder, truth, est = mocap_run
    part = _capture(truth, folder / "part.csv", 120.0)
    lines = part.read_text().splitlines()
    keep = [ln for ln in lines[1:] if 3.0 <= float(ln.split(",")[0]) <= 4.5]
    part.write_text("\n".join([lines[0], *keep]) + "\n")
    got, err = _evaluate_json(capsys, str(est), str(part))
    assert got["n"] == 151 and "which covers that part of the run alone" in err
    other = _capture(truth, folder / "other.csv", 120.0, t0=30.0)
    assert main(["evaluate", str(est), str(other)]) == 2
    assert "the files' times do not match" in capsys.readouterr().err


def test_an_epoch_clock_truth_names_the_whole_shift_and_takes_it(mocap_run, capsys) -> None:
    """A capture stamped in epoch seconds: the refusal names the shift to the
    microsecond, and that shift scores it as the capture on the estimate's clock."""
    folder, truth, est = mocap_run
    good = _capture(truth, folder / "mc120.csv", 120.0)
    epoch = _capture(truth, folder / "epoch.csv", 120.0, t0=1712345678.123456)
    assert main(["evaluate", str(est), str(epoch)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("--truth-shift 1712345678.123456 compares them"), err[-200:]
    base, _ = _evaluate_json(capsys, str(est), str(good))
    got, _ = _evaluate_json(capsys, str(est), str(epoch), "--truth-shift", "1712345678.123456")
    assert got["tip_mean_mm"] == pytest.approx(base["tip_mean_mm"], abs=1e-4)
    # a shift given 0.25 s short: the whole shift advised keeps its microseconds
    _, err = _evaluate_json(capsys, str(est), str(epoch), "--truth-shift", "1712345677.873456")
    advised = re.search(r"--truth-shift (1712345\d+\.\d+) compares them so", err)
    assert advised and abs(float(advised[1]) - 1712345678.123456) < 0.02, err[-300:]
    assert len(advised[1].split(".")[1]) >= 5  # the microseconds kept
    # a truth whose t is in milliseconds (1000 times as sparse) is refused, not scored
    ms = epoch.parent / "ms.csv"
    lines = good.read_text().splitlines()
    ms.write_text(
        "\n".join(
            [
                lines[0],
                *(f"{float(r.split(',', 1)[0]) * 1000!r},{r.split(',', 1)[1]}" for r in lines[1:]),
            ]
        )
        + "\n"
    )
    assert main(["evaluate", str(est), str(ms)]) == 2
    assert "the files' times do not match" in capsys.readouterr().err


def test_the_truth_may_follow_an_option(mocap_run, capsys) -> None:
    """``evaluate EST.csv --json TRUTH.csv`` takes the truth (argparse fills an optional
    positional only beside the ones before it); a word more is refused."""
    folder, truth, est = mocap_run
    assert main(["evaluate", str(est), "--json", str(truth)]) == 0
    first = json.loads(capsys.readouterr().out)
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == first
    with pytest.raises(SystemExit) as exit_:
        main(["evaluate", str(est), "--json", str(truth), "more.csv"])
    assert exit_.value.code == 2
    assert "unrecognized arguments: more.csv" in capsys.readouterr().err


def test_plot_draws_a_truths_missing_rows_as_a_gap_and_takes_its_shift(
    mocap_run, tmp_path, capsys
) -> None:
    """A capture with 0.5 s of rows missing: the truth plot compares at the estimate's
    times holds a NaN row there (the error curve breaks, not a straight line across),
    and ``plot --truth-shift`` compares an offset capture as ``evaluate --truth-shift``
    does (no offset warning)."""
    from continuum_mhe.evaluation.estimate_tables import truth_at_rows
    from continuum_mhe.evaluation.metrics import aligned_truth

    folder, truth, est = mocap_run
    holed = _capture(truth, tmp_path / "holed.csv", 120.0)
    lines = holed.read_text().splitlines()
    keep = [ln for ln in lines[1:] if not 5.0 <= float(ln.split(",")[0]) <= 5.5]
    holed.write_text("\n".join([lines[0], *keep]) + "\n")
    e, tr = read_state_table(est), read_state_table(holed, gaps=True)
    i_est, rows, interpolated = aligned_truth(e.t, tr.t, tr.values, tr.names, warn=False)
    at = truth_at_rows(e, tr, i_est, rows, interpolated)
    assert at is not None
    missing = ~np.isfinite(at.values).all(axis=1)
    (hole,) = np.flatnonzero(missing)  # one NaN row, inside the gap, none compared there
    assert 5.0 < at.t[hole] < 5.5 and not ((at.t > 4.995) & (at.t < 5.505) & ~missing).any()
    assert np.array_equal(at.t[~missing], e.t[i_est])
    late = _capture(truth, tmp_path / "late.csv", 120.0, offset=0.04)
    fig = str(tmp_path / "f.png")
    assert main(["plot", str(est), "--truth", str(late), "-o", fig]) == 0
    assert "clocks offset" in capsys.readouterr().err
    assert main(["plot", str(est), "--truth", str(late), "--truth-shift", "0.04", "-o", fig,
                 "--overwrite"]) == 0  # fmt: skip
    assert "clocks offset" not in capsys.readouterr().err
    assert main(["plot", str(est), "--truth-shift", "0.04", "-o", fig, "--overwrite"]) == 2
    assert "--truth-shift needs --truth" in capsys.readouterr().err


def test_plot_of_a_recording_with_its_truth_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    """``plot`` given a recording with truth columns beside its readings (the rod
    generator's ``x_true, y_true, z_true``) and no estimate drew that truth as the
    estimate; it is refused, exit 2, naming the file and its truth columns and pointing
    to ``estimate`` and ``--truth``, and no figure is written. Given as ``--truth`` of an
    estimate of it, it is drawn."""
    from importlib.resources import files

    rod = tmp_path / "rod.csv"
    lines = (files("continuum_mhe") / "data" / "rod_planar.csv").read_text().splitlines()
    rod.write_text("\n".join(lines[:41]) + "\n")  # the first 2 s
    fig = tmp_path / "f.png"
    assert main(["plot", str(rod), "-o", str(fig)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {rod}: a recording with truth columns (x_true, y_true, "
        "z_true) but no estimate columns (x, y, z, status): run continuum-mhe estimate "
        f"{rod} -o EST.csv first, then continuum-mhe plot EST.csv --truth {rod}\n"
    )
    assert not fig.exists()
    est = tmp_path / "e.csv"
    assert main(["estimate", str(rod), "--method", "ekf", "-o", str(est)]) == 0
    assert main(["plot", str(est), "--truth", str(rod), "-o", str(fig)]) == 0
    assert fig.exists()


def test_evaluate_scores_the_calibration_over_the_rows_compared(tmp_path: Path, capsys) -> None:
    """The calibration is over the rows compared, as the RMSEs are: a no-estimate row and
    a row whose tip truth has a gap are in neither, so that a row of ``tip_far_worst_row``
    counts from 0 among the rows compared, and a column's ``n`` leaves out the gap's row
    even where that column's own truth is there."""
    t = np.arange(8) * 0.02
    dx = np.array([0.5, 0.0, 0.5, 0.5, 0.5, 6.0, 0.5, 0.5]) * 0.001  # 1 mm std
    rows = []
    for k, (tk, e) in enumerate(zip(t, dx)):
        if k == 1:  # no estimate
            rows.append(f"{tk:g}" + "," * 10 + ",no-estimate,0.1")
        else:
            rows.append(f"{tk:g},{e},0,0.2,0,0,0.001,0.001,0.001,0.01,0.01,ok,0.1")
    header = "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms"
    est = _write(tmp_path / "e.csv", "\n".join([header, *rows]) + "\n")
    truth_rows = [f"{tk:g},{'' if k == 2 else 0},0,0.2,0,0" for k, tk in enumerate(t)]
    truth = _write(tmp_path / "t.csv", "\n".join(["t,x,y,z,theta,phi", *truth_rows]) + "\n")
    assert main(["evaluate", str(est), str(truth), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert (report["n"], report["n_without_estimate"], report["n_without_truth"]) == (6, 1, 1)
    every, ok = report["calibration"], report["calibration_ok"]
    assert every["n"] == {"x": 6, "y": 6, "z": 6, "theta": 6, "phi": 6}
    # the row 6 std off is the file's sixth, the fourth of the rows compared
    assert (every["tip_far"], every["tip_far_of"], every["tip_far_worst_row"]) == (1, 6, 3)
    assert (ok["tip_far"], ok["tip_far_of"], ok["tip_far_worst_row"]) == (1, 6, 3)
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "(the largest 6.0 std at t = 0.1 s;" in capsys.readouterr().out


def test_the_srmse_sums_the_columns_in_m_and_rad_alone() -> None:
    """A tendon robot's tension gain (unit 1) is not summed into the SRMSE (m + rad),
    as its tip force (N) is not."""
    from continuum_mhe.evaluation.metrics import compute_metrics, srmse_columns

    names = ["x", "y", "z", "fx", "tension_gain_1"]
    est = np.array([[0.001, 0.0, 0.2, 0.1, 1.5]] * 3)
    truth = np.array([[0.0, 0.0, 0.2, 0.0, 1.0]] * 3)
    m = compute_metrics(est, truth, 0.2, names)
    assert m.rmse["tension_gain_1"] == pytest.approx(0.5)
    assert m.srmse == pytest.approx(0.001)
    assert srmse_columns(names) == ["x", "y", "z"]


def test_a_theta_max_below_its_least_is_named_as_the_option(tmp_path, capsys) -> None:
    """``--theta-max 0.001`` (below the least bend bound a robot file takes, 0.01 rad):
    one line naming the option and the range it has, as every numeric option's."""
    rows = _good_rows(10)
    meas, est = _meas(tmp_path, rows), tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--theta-max", "0.001"]) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: --theta-max 0.001 is outside its valid range [0.01, 3.14159) "
        "rad: a section that bends no further is no bending section; give its largest bend\n"
    )
    assert not est.exists()
