"""evaluate, plot and view reading an estimate and a truth: bad or one-row files, std_
columns, the robot an estimate's options line records, the truth's clock (offsets,
--truth-shift, --skip-start), truths at other times (interpolated, sparser motion
captures), the calibration and the SRMSE."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small, write_file
from hypothesis import given, settings
from hypothesis import strategies as st

from continuum_mhe.cli import main
from continuum_mhe.io.state_tables import read_state_table


def test_estimate_or_truth_row_with_an_extra_field_is_refused(tmp_path, capsys):
    est = write_file(
        tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n"
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2,0.1\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {truth}: line 2: expected 4 fields, found 5 (an extra field or "
        "separator?)\n"
    )


def test_evaluate_rejects_bad_truth(tmp_path, capsys):
    est = write_file(
        tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n"
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y\n0,0,0\n")
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
    files = {k: write_file(tmp_path / f"{k}.csv", text if k == which else good[k]) for k in good}
    assert main(["evaluate", str(files["estimate"]), str(files["truth"])]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{files[which]}: line " in err and "out of range" in err


def test_evaluate_of_a_one_row_estimate_says_so(tmp_path, capsys):
    est = write_file(
        tmp_path / "est.csv", "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n"
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err.endswith(f"{est}: one row: evaluate needs at least two\n")


def test_evaluate_with_a_wrong_truth_shift_names_the_shift_that_fits(tmp_path, capsys):
    """Files on one clock compared with ``--truth-shift 1.9``: the refusal says that the
    files' own times match and the shift given moved the truth off them (not that a
    shift of -1.9 would fit, which names 1.9 in turn; nor a clock that did not start
    at 0)."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas), "--truth",
                 str(truth)]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    for shift in ("1.9", "-1.9"):
        assert main(["evaluate", str(est), str(truth), "--truth-shift", shift]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.endswith(
            f"; the files' own times match: --truth-shift {shift} moved the truth off them "
            "(leave --truth-shift out)\n"
        ), err


def test_evaluate_of_a_one_row_truth_says_so(tmp_path, capsys):
    """A truth of one row is named, not the estimate whose rows it cannot cover."""
    est = write_file(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n0.05,0,0,0.2,0,0,ok,1\n",
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {truth}: one row: evaluate needs a truth of at least two\n"
    )


def test_evaluate_reads_a_standard_deviation_beyond_the_value_limit(tmp_path, capsys):
    """An estimate may say it knows nothing (a std of 1e7 rad, as the EKF of a soft
    tendon robot wrote): the readers take what estimate writes."""
    est = write_file(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms\n"
        "0,0,0,0.2,0,0,1,1,1,1e7,1,ok,1\n0.05,0,0,0.2,0,0,1,1,1,1e7,1,ok,1\n",
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 0
    table = read_state_table(est)  # the value itself, not a dropout
    assert table.std is not None and table.std[:, 3].tolist() == [1e7, 1e7]


@pytest.mark.parametrize("value", ["inf", "nan", "-0.1", "1e400"])
def test_evaluate_refuses_a_standard_deviation_that_is_no_finite_number_at_least_0(
    tmp_path, capsys, value
):
    """A ``std_`` cell infinite, not a number or negative is refused in one line that
    says what it must be."""
    est = write_file(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms\n"
        f"0,0,0,0.2,0,0,1,1,1,1,1,ok,1\n0.05,0,0,0.2,0,0,{value},1,1,1,1,ok,1\n",
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    assert main(["evaluate", str(est), str(truth)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {est}: line 3: std_x must be a finite number >= 0, got {value!r}\n"
    )


def test_evaluate_refuses_an_estimate_given_as_the_truth(tmp_path, capsys):
    """An estimate given as the truth (the estimate against itself: a 0 mm error and
    every coverage 1.000) is refused in one line naming it."""
    est = write_file(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,1\n0.05,0,0,0.2,0,0,ok,1\n",
    )
    truth = write_file(tmp_path / "truth.csv", "t,x,y,z\n0,0,0,0.2\n0.05,0,0,0.2\n")
    for argv in ([str(est), str(est)], [str(truth), str(est)]):
        assert main(["evaluate", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{est}: has an estimate's status" in err, err
    assert main(["evaluate", str(est), str(truth)]) == 0


@pytest.mark.parametrize("command", ["plot", "view"])
def test_plot_and_view_refuse_an_estimate_without_any(tmp_path, capsys, command):
    est = write_file(
        tmp_path / "est.csv",
        "t,x,y,z,theta,phi,status,solve_ms\n0,,,,,,no-estimate,1\n0.05,,,,,,no-estimate,1\n",
    )
    out = {"plot": ["-o", str(tmp_path / "f.png")], "view": ["--save", str(tmp_path / "f.rrd")]}
    assert main([command, str(est), *out[command]]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no row has an estimate" in err
    assert list(tmp_path.iterdir()) == [est]


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


def test_evaluate_reports_unmatched_rows(tmp_path, capsys):
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    args = ["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "2"]
    assert main(args) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    lines = truth.read_text().splitlines()
    write_file(truth, "\n".join(lines[:11]) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "unmatched rows       31 of 41" in capsys.readouterr().out


def test_a_truth_of_part_of_the_estimates_times_is_said_by_evaluate_plot_and_view(tmp_path, capsys):
    """A truth of the first 1.5 s of a 3 s estimate (31 of its 61 rows, more than the
    half below which the rows compared were said): evaluate, plot and view say in one
    line how much of the estimate's time it covers and how many rows are compared. A
    truth with rows dropped inside the run, or one row short at its end, is no truth of
    part of the run: not said so."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    args = ["simulate", "paper3d", "-o", str(meas), "--truth", str(truth), "--duration", "3"]
    assert main(args) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    header, *rows = truth.read_text().splitlines()
    assert len(rows) == 61
    part = write_file(tmp_path / "part.csv", "\n".join([header, *rows[:31]]) + "\n")
    said = (
        f"warning: {part}: its rows cover t = 0 to 1.5 s of {est}'s 0 to 3 s (50 %): 31 of "
        "the estimate's 61 rows compared (a truth of part of the run?)"
    )
    capsys.readouterr()
    out = {"plot": ["-o", str(tmp_path / "f.png")], "view": ["--save", str(tmp_path / "f.rrd")]}
    for argv in (
        ["evaluate", str(est), str(part)],
        ["plot", str(est), "--truth", str(part), *out["plot"]],
        ["view", str(est), "--truth", str(part), *out["view"]],
    ):
        assert main(argv) == 0
        err = capsys.readouterr().err
        assert [ln for ln in err.splitlines() if "warning" in ln] == [f"continuum-mhe: {said}"]
    dropped = write_file(
        tmp_path / "dropped.csv", "\n".join([header, *rows[:20], *rows[30:]]) + "\n"
    )
    short = write_file(tmp_path / "short.csv", "\n".join([header, *rows[:-1]]) + "\n")
    for other in (dropped, short):
        assert main(["evaluate", str(est), str(other)]) == 0
        assert "part of the run" not in capsys.readouterr().err


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


@pytest.mark.parametrize("formulation", ["bend", "paper"])
def test_an_estimates_robot_file_gone_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], formulation: str
) -> None:
    """An estimate whose options line names a robot file since moved: ``evaluate`` and
    ``view`` (and ``plot`` of a paper-formulation estimate, whose rows give no lengths)
    refuse it in one line naming the file and asking for --robot, nothing written (not a
    note and then an error about the default 0.2 m section, nor, for one section, scores
    on 0.2 m against the robot's 0.25 m); with --robot it is evaluated."""
    robot = write_file(
        tmp_path / "R.toml",
        'mounting = "z-up"\n[[section]]\nlength = 0.25\ntheta_max = 3.0\n'
        + ("" if formulation == "paper" else "[[section]]\nlength = 0.14\ntheta_max = 3.0\n")
        + "[[imu]]\nsection = 1\nat = 1.0\n"
        + ("" if formulation == "paper" else "[[imu]]\nsection = 2\nat = 1.0\n"),
    )
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    scenario = "paper3d" if formulation == "paper" else "spatial"
    argv = ["simulate", scenario, "--robot", str(robot), "--duration", "2"]
    assert main([*argv, "-o", str(meas), "--truth", str(truth)]) == 0
    argv = ["estimate", str(meas), "--robot", str(robot), "--method", "ekf"]
    assert main([*argv, "--formulation", formulation, "-o", str(est)]) == 0
    moved = robot.rename(tmp_path / "moved.toml")
    capsys.readouterr()
    commands = [
        ["evaluate", str(est), str(truth)],
        ["view", str(est), "--save", str(tmp_path / "v.rrd")],
        *([["plot", str(est), "-o", str(tmp_path / "p.png")]] if formulation == "paper" else []),
    ]
    for argv in commands:
        assert main(argv) == 2, argv
        out, err = capsys.readouterr()
        assert out == "" and err.count("\n") == 1, err
        assert err.startswith(
            f"continuum-mhe: error: {est}: it was estimated with the robot file {robot} (its "
            "options line), which cannot be read here ("
        ), err
        assert err.endswith("give --robot with the robot it was estimated on\n"), err
    assert not (tmp_path / "v.rrd").exists() and not (tmp_path / "p.png").exists()
    assert main(["evaluate", str(est), str(truth), "--robot", str(moved)]) == 0


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


def test_a_truth_on_an_offset_clock_is_said_from_a_section_end_the_imus_determine(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hanging robot of three sections with IMUs at the ends of sections 1 and 3: the
    IMUs leave sections 2 and 3 free, so the tip is far off however the clocks run and
    its error does not halve at the truth's offset; section 1's end, which IMU 1
    determines, shows it. A truth 0.5 s late is warned of from that end (it had been
    scored silently); the truth as it was is not."""
    robot = tmp_path / "three.toml"
    sections = "".join(f"[[section]]\nlength = {L}\n" for L in (0.12, 0.18, 0.09))
    robot.write_text(
        f'mounting = "z-down"\n{sections}[[imu]]\nsection = 1\n[[imu]]\nsection = 3\n',
        encoding="utf-8",
    )
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    argv = ["simulate", "spatial", "--robot", str(robot), "--duration", "8", "--seed", "1"]
    assert main([*argv, "-o", str(meas), "--truth", str(truth)]) == 0
    with pytest.warns(UserWarning):  # the robot's IMUs do not determine its shape
        assert main(["estimate", str(meas), "--robot", str(robot), "--method", "ekf",
                     "-o", str(est)]) == 0  # fmt: skip
    late = _shifted(truth, tmp_path / "late.csv", 0.5)
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth)]) == 0
    assert "clocks offset" not in capsys.readouterr().err
    assert main(["evaluate", str(est), str(late)]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "clocks offset" in ln]
    assert len(said) == 1 and re.fullmatch(
        rf"continuum-mhe: warning: {re.escape(str(late))}: the truth fits the estimate best "
        r"\+0\.5 s later \(mean error of section 1's end \d\.\d+ mm against \d\d\.?\d* mm "
        r"as the times match\): are the two files' clocks offset\? \(a motion that repeats "
        r"can fit shifted too; --truth-shift 0\.5 compares them so\)",
        said[0],
    ), said


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


@pytest.mark.parametrize("command", ["plot", "view"])
def test_plot_and_view_of_an_estimate_without_its_tip_columns_is_one_line(
    tmp_path, capsys, command
):
    """A table without x, y, z is refused in one line by plot and view, not an internal
    error (exit 70)."""
    est = write_file(tmp_path / "est.csv", "t,theta,phi,status\n0,0.1,0.2,ok\n0.05,0.1,0.2,ok\n")
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


def test_evaluate_names_the_shift_of_a_clock_that_did_not_start_at_zero(tmp_path, capsys):
    """An estimate whose times are the truth's plus one offset (a device clock that did
    not start at 0, as live's): the refusal names the --truth-shift that compares them,
    and that shift scores them."""
    t = np.arange(50) * 0.02
    tip = np.column_stack([0.01 * np.sin(t), 0.01 * np.cos(t), 0.2 + 0 * t])
    truth = tmp_path / "truth.csv"
    est = tmp_path / "est.csv"
    write_file(
        truth, "t,x,y,z\n" + "".join(f"{a:.6f},{b},{c},{d}\n" for a, (b, c, d) in zip(t, tip))
    )
    write_file(est, "t,x,y,z\n" + "".join(
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
    assert got["n"] == 151 and "(a truth of part of the run?)" in err
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
    assert f"{ms}: t advances by a median of" in (err := capsys.readouterr().err)
    assert "is the truth's t in milliseconds? name its column t_ms" in err


def test_a_refusal_after_a_note_is_its_one_line_alone(mocap_run, capsys, tmp_path) -> None:
    """``evaluate`` of an estimate whose options line names its robot says so in a note
    when it scores it; when it then refuses an option or the truth, the refusal is the
    one line written, without the note; ``plot`` alike with its warning of a robot file
    of other lengths."""
    _, truth, est = mocap_run
    assert main(["evaluate", str(est), str(truth)]) == 0
    said = capsys.readouterr().err
    assert "note: " in said and "was estimated with --robot two-section" in said
    assert main(["evaluate", str(est), str(truth), "--skip-start", "100"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("continuum-mhe: error: "), err
    # plot on a robot file of other lengths (a warning that the backbone misses the
    # estimate's section ends), then a truth whose times meet none of the estimate's
    other = tmp_path / "other.toml"
    other.write_text(
        "[[section]]\nlength = 0.2\n[[section]]\nlength = 0.1\n"
        "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    late = _capture(truth, tmp_path / "late.csv", 10.0, t0=100.0)
    fig = tmp_path / "fig.png"
    with pytest.MonkeyPatch.context() as m:  # what plot says, not what it draws
        figures_drawn_small(m)
        assert main(["plot", str(est), "--robot", str(other), "-o", str(fig)]) == 0
    assert "misses its section ends" in capsys.readouterr().err
    argv = ["plot", str(est), "--robot", str(other), "--truth", str(late), "-o", str(fig)]
    assert main([*argv, "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("continuum-mhe: error: "), err


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
    mocap_run, tmp_path, capsys, monkeypatch
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
    figures_drawn_small(monkeypatch)  # what plot says of the shift, not what it draws
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
    est = write_file(tmp_path / "e.csv", "\n".join([header, *rows]) + "\n")
    truth_rows = [f"{tk:g},{'' if k == 2 else 0},0,0.2,0,0" for k, tk in enumerate(t)]
    truth = write_file(tmp_path / "t.csv", "\n".join(["t,x,y,z,theta,phi", *truth_rows]) + "\n")
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


def test_a_length_warning_of_several_sections_asks_for_the_robot_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Files of a two-section robot scored on a robot file of other section lengths: the
    length warning asks for the robot file they were made with (``--length`` gives one
    section alone)."""
    robot, other = tmp_path / "r.toml", tmp_path / "long.toml"
    body = "[[section]]\nlength = {a}\n[[section]]\nlength = {b}\n[[imu]]\nsection = 1\n"
    robot.write_text('mounting = "z-up"\n' + body.format(a=0.15, b=0.15) + "[[imu]]\nsection = 2\n")
    other.write_text('mounting = "z-up"\n' + body.format(a=0.3, b=0.3) + "[[imu]]\nsection = 2\n")
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "spatial", "--robot", str(robot), "-o", str(meas), "--truth",
                 str(truth), "--duration", "2"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--robot", str(robot),
                 "--method", "ekf"]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--robot", str(other)]) == 0
    said = [ln for ln in capsys.readouterr().err.splitlines() if "made for a robot of" in ln]
    assert said and all(ln.endswith("; pass the --robot it was made with") for ln in said), said


def test_the_largest_far_off_ratio_is_written_beyond_the_limit() -> None:
    """An ok row 4.03 std off is counted beyond the 4 std limit, and written so: "4.03",
    not the "4.0" that reads as within it; ratios well beyond keep one decimal."""
    from continuum_mhe.cli.evaluate import _ratio_text

    assert [_ratio_text(r) for r in (4.03, 4.0004, 6.0, 25.64)] == ["4.03", "4.0004", "6.0", "25.6"]
