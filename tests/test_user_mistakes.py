"""The usual user mistakes get one line with the likely cause; bugs are not shown as
user errors."""

from __future__ import annotations

import importlib.util
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

import continuum_mhe.cli.app as cli
import continuum_mhe.cli.check_robot as check_robot
from continuum_mhe import (
    Measurement,
    MHESettings,
    NoiseSettings,
    compute_metrics,
    make_estimator,
    make_formulation,
    simulate,
)
from continuum_mhe.cli import main
from continuum_mhe.cli.options import OPTION_RANGES
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import OptionWarning
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.text_rows import CutLineWarning
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import RobotSettings
from continuum_mhe.simulation.scenarios import simulate_robot

DOCS = Path(__file__).resolve().parents[1] / "docs" / "reliability.md"
DATA_ROBOTS = Path(__file__).resolve().parents[1] / "src" / "continuum_mhe" / "data" / "robots"


def test_input_error_is_a_user_error_and_a_value_error() -> None:
    assert issubclass(InputError, UserError) and issubclass(UserError, ValueError)


def test_a_bug_is_not_shown_as_a_user_error(monkeypatch, capsys) -> None:
    def broken(args: object) -> int:
        raise ValueError("index 3 is out of bounds")  # a library bug, not the user's

    monkeypatch.setattr(check_robot, "run", broken)
    code = main(["check-robot", "robot.toml"])
    err = capsys.readouterr().err
    assert code == cli.EXIT_BUG == 70
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "internal error (a bug in continuum-mhe): ValueError: index 3" in err
    assert "please report it" in err and "test_user_mistakes.py" in err
    # a space before the parenthesis: never "maintainers(CONTINUUM_MHE_TRACEBACK=1 ..."
    assert re.search(
        r"please report it with the command (at \S+|to the maintainers) "
        r"\(CONTINUUM_MHE_TRACEBACK=1 shows the traceback\)\n$",
        err,
    ), err


def test_a_user_error_is_exit_2(monkeypatch, capsys) -> None:
    def user(args: object) -> int:
        raise UserError("robot.toml: line 3: bad")

    monkeypatch.setattr(check_robot, "run", user)
    assert main(["check-robot", "robot.toml"]) == 2
    assert capsys.readouterr().err == "continuum-mhe: error: robot.toml: line 3: bad\n"


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--noise-deg", "1e300"], "--noise-deg 1e+300 is outside its valid range [0, 90] deg"),
        (["--gyro-std", "1e300"], "--gyro-std 1e+300 is outside"),
        (["--accel-psd", "1e300", "--method", "ukf"], "--accel-psd 1e+300 is outside"),
        (["--length", "200"], "millimetres or centimetres?"),
        (["--theta-max", "90"], "degrees?"),
        (["--horizon", "1"], "--horizon 1 is outside its valid range [2, 1000]"),
        (["--noise-deg", "nan"], "--noise-deg nan is outside"),
        (["--mount-rpy", "1e300,0,0"], "three angles in degrees within +-360"),
    ],
)
def test_numeric_options_out_of_range_are_one_line(tmp_path, capsys, argv, needle) -> None:
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1\n")
    code = main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), *argv])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and needle in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--dt", "50"], "milliseconds?"),
        (["--duration", "1e6", "--dt", "1e-4"], "1e+10 samples; at most"),
        (["--seed", "-1"], "--seed -1 is outside"),
        (["--duration", "1", "--dt", "2"], "--duration 1 s is shorter than --dt 2 s"),
        (["--imu", "raw", "--noise-deg", "0"], "--noise-deg is for the noise of tilt readings"),
        (["--imu", "raw", "--noise-model", "tangent"], "--noise-model is for the noise of"),
    ],
)
def test_simulate_ranges(tmp_path, capsys, argv, needle) -> None:
    assert main(["simulate", "paper3d", "-o", str(tmp_path / "m.csv"), *argv]) == 2
    assert needle in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_every_option_range_is_documented() -> None:
    text = DOCS.read_text()
    for dest, rng in OPTION_RANGES.items():
        flag = "--" + dest.replace("_", "-")
        row = re.search(rf"^\| `{flag}` \| (.*?) \|", text, re.MULTILINE)
        assert row is not None, f"{flag} missing from docs/reliability.md"
        assert row.group(1) == rng.describe(), flag


def test_library_call_given_degrees_says_so() -> None:
    est = make_estimator("ekf", make_formulation("bend", RobotSettings()))
    with pytest.raises(UserError, match="degrees\\? measurements are in radians"):
        est.step(Measurement(0.0, np.array([30.0, 20.0])))
    # beyond pi (no gravity direction needs it): refused, as degrees
    for z in ([3.3, 0.0], [0.0, 3.3]):
        est.reset()
        with pytest.raises(UserError, match="beyond pi, out of range: degrees"):
            est.step(Measurement(0.0, np.array(z)))
    for m in ("mhe", "ukf"):  # every estimator, in run() as in step()
        rec = simulate("paper3d", duration=0.4)
        with pytest.raises(UserError, match="out of range"):
            make_estimator(m, make_formulation("bend")).run(rec.t, np.degrees(rec.z))
    # every reading written as the same gravity direction with its pitch beyond pi/2
    # (pi - pitch, the roll turned by pi): accepted, and the same estimates
    rec = simulate("paper3d", duration=2.0)
    roll, pitch = rec.z[:, 0], rec.z[:, 1]
    other = np.column_stack([(roll + 2 * math.pi) % (2 * math.pi) - math.pi,
                             np.copysign(math.pi, pitch) - pitch])  # fmt: skip
    assert np.all(np.abs(other[:, 1]) > math.pi / 2)
    a, b = (make_estimator("ekf", make_formulation("bend")).run(rec.t, z) for z in (rec.z, other))
    np.testing.assert_allclose(a.output, b.output, rtol=0, atol=1e-9)
    est.reset()  # radians, even the largest: accepted
    e = est.step(Measurement(0.0, np.array([math.pi, math.pi / 2])))
    # pitch pi/2 (the gimbal lock): a quarter-circle bend, theta = pi/2, phi = +-pi, the
    # tip at (r, 0, r) with the radius r = 2 L / pi, on the bound theta_max = pi/2
    assert e.status == "at-bound"
    x, y, z, theta, phi = e.output
    r = 2 * RobotSettings().length / math.pi
    np.testing.assert_allclose([x, y, z], [r, 0.0, r], rtol=0, atol=1e-9)
    np.testing.assert_allclose([theta, abs(phi)], [math.pi / 2, math.pi], rtol=0, atol=1e-9)


def test_continue_run_checks_its_arrays_as_run_does() -> None:
    """``continue_run`` (the guide's block-by-block run) refuses arrays whose lengths or
    widths do not fit in one UserError, as ``run`` does, and takes lists."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match="t has 10 samples but z has 21"):
        est.continue_run(rec.t[:10], rec.z)
    with pytest.raises(UserError, match=r"z must have shape \(n, 2\) for the bend formulation"):
        est.continue_run(rec.t, rec.z[:, :1])
    with pytest.raises(UserError, match=r"z is None: give the readings, an array \(n, 2\)"):
        est.continue_run(rec.t, None)  # type: ignore[arg-type]
    est.reset()
    batch = est.continue_run(list(rec.t), rec.z.tolist())
    np.testing.assert_array_equal(batch.output, est.run(rec.t, rec.z).output)


@pytest.mark.parametrize(
    ("block", "starts", "match"),
    [
        (-1, None, "block must be a positive integer"),
        (0, None, "block must be a positive integer"),
        (2.5, None, "block must be a positive integer"),
        (True, None, "block must be a positive integer"),
        (10, [0], "stepped the first 10 of the 21 samples"),  # samples left out
        (10, [0, 15], "a block starts at 15 where sample 10 is next"),  # a gap
        (10, [0, 0, 10, 20], "a block starts at 0 where sample 10 is next"),  # repeated
        (10, [10, 0, 20], "a block starts at 10 where sample 0 is next"),  # out of order
        (10, [0, 10, 20, 30], "a block starts at 30 where sample 21 is next"),  # beyond
    ],
)
def test_continue_run_refuses_blocks_that_do_not_cover_the_samples(block, starts, match) -> None:
    """``continue_run`` steps every sample once, in order, or refuses in one
    UserError: a block size that is not a positive integer, or starts that skip,
    repeat, reorder or pass the samples (the rows left unstepped would read as ``ok``
    estimates of uninitialised memory). Starts given as a list are checked before any
    sample is stepped (not the blocks before a bad one stepped, their estimates lost,
    and the same call again refused as going back in time)."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=match):
        est.continue_run(rec.t, rec.z, starts=starts, block=block)
    batch = est.continue_run(rec.t, rec.z, starts=range(0, 21, 10), block=10)  # no reset
    np.testing.assert_array_equal(batch.output, est.run(rec.t, rec.z).output)


def test_continue_run_refuses_a_should_stop_that_is_no_function() -> None:
    """``should_stop=5`` is a UserError saying what should_stop must be, not a TypeError
    from inside the compiled loop."""
    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=r"should_stop must be a function that says when"):
        est.continue_run(rec.t, rec.z, should_stop=5)  # type: ignore[arg-type]
    assert len(est.continue_run(rec.t, rec.z).output) == len(rec.t)


def test_theta_max_in_degrees_in_the_library() -> None:
    with pytest.raises(UserError, match="degrees"):
        RobotSettings(theta_max=90)


@pytest.mark.parametrize(
    ("value", "hint"),
    [
        ("3.1416", "a bend of pi folds the section back onto itself; give a bound below pi"),
        ("6", "a bend of pi folds the section back onto itself"),  # radians, past the fold
        ("6.3", "degrees? give radians, e.g. 1.5708 for 90 degrees"),  # over 2 pi: degrees
        ("90", "degrees? give radians"),
        ("0", ""),
        ("1e-12", "a section that bends no further is no bending section"),
    ],
)
def test_theta_max_hint_says_degrees_only_where_it_cannot_be_radians(
    tmp_path, capsys, value: str, hint: str
) -> None:
    """theta_max = 3.1416 (pi, rounded up) or 6 is told that a bend of pi folds the
    section back; only a value that cannot be radians (over 2 pi) is told 'degrees? give
    radians', by check-robot, estimate and the library alike."""
    robot = tmp_path / "robot.toml"
    robot.write_text(f"[[section]]\nlength = 0.16\ntheta_max = {value}\n[[imu]]\nsection = 1\n")
    assert main(["check-robot", str(robot), "--samples", "10"]) == 2
    err = capsys.readouterr().err
    line = f"line 3: section 1: theta_max must lie in [0.01, pi) rad, got {float(value)!r}"
    assert err.startswith(f"continuum-mhe: error: {robot}: {line}") and err.count("\n") == 1
    assert hint in err and ("degrees" in err) == ("degrees" in hint)
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n")
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--theta-max", value]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and (hint in err) and ("degrees" in err) == ("degrees" in hint)
    with pytest.raises(UserError) as info:
        RobotSettings(theta_max=float(value))
    assert ("degrees" in str(info.value)) == ("degrees" in hint)


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


def _simulated(tmp_path: Path, name: str, *extra: str) -> tuple[Path, Path]:
    m, t = tmp_path / f"{name}_m.csv", tmp_path / f"{name}_t.csv"
    args = ["simulate", "paper3d", "-o", str(m), "--truth", str(t), "--duration", "5"]
    assert main([*args, *extra]) == 0
    return m, t


def _notes_and_rows(estimate: Path) -> tuple[list[str], list[str]]:
    """An estimate CSV's ``#`` lines (the options it was made with) and its other lines
    (the column line, then the rows), each with its line end."""
    lines = estimate.read_text().splitlines(keepends=True)
    notes = [ln for ln in lines if ln.startswith("#")]
    return notes, [ln for ln in lines if not ln.startswith("#")]


def test_evaluate_of_a_cut_estimate_warns_that_it_scores_a_part(tmp_path, capsys) -> None:
    """An estimate of the first 30 % of a recording (interrupted, cut with head) is
    scored on that part with a warning giving the span it covers; a truth sampled twice
    as densely as the estimate is no mistake and gets none."""
    m, t = _simulated(tmp_path, "a")
    est, cut = tmp_path / "e.csv", tmp_path / "cut.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    notes, rows = _notes_and_rows(est)
    cut.write_text("".join(notes + rows[:31]))  # the column line and 30 rows
    capsys.readouterr()
    assert main(["evaluate", str(cut), str(t)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err == [
        f"continuum-mhe: warning: {cut}: its rows cover t = 0 to 1.45 s of {t}'s 0 to 5 s "
        "(29 %): the scores are of that part only (an interrupted or cut estimate?)"
    ]
    dense_m, dense_t = _simulated(tmp_path, "d", "--dt", "0.025")
    sparse = tmp_path / "sparse.csv"  # every second row of a 0.025 s estimate
    assert main(["estimate", str(dense_m), "-o", str(sparse), "--method", "ekf"]) == 0
    notes, rows = _notes_and_rows(sparse)
    sparse.write_text("".join(notes + rows[:1] + rows[1::2]))
    capsys.readouterr()
    assert main(["evaluate", str(sparse), str(dense_t)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_evaluate_scores_every_section_end_the_truth_has_and_names_a_typo(tmp_path, capsys) -> None:
    """Every section end and bend both files have is scored: a three-section truth
    without section 2's end scores sections 1 and 3 (the count does not stop at the
    gap); a header typo (``xx_3``, ``x-3``) is named in a warning; a truth with
    ``theta_2`` and no ``phi_2``, or without section 2's bend, is scored by ``evaluate``
    and drawn by ``plot``."""
    m, t, robot = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "three.toml"
    robot.write_text(
        "".join("[[section]]\nlength = 0.1\ntheta_max = 3.0\n" for _ in range(3))
        + "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3))
    )
    assert main(["simulate", "spatial", "--robot", str(robot), "--duration", "2",
                 "-o", str(m), "--truth", str(t)]) == 0  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "--robot", str(robot), "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    header, *rows = t.read_text().splitlines(keepends=True)
    names = header.strip().split(",")
    keep = [i for i, c in enumerate(names) if c in "t x y z x_1 y_1 z_1 x_3 y_3 z_3".split()]
    gap = tmp_path / "gap.csv"
    gap.write_text("".join(",".join(r.strip().split(",")[i] for i in keep) + "\n"
                           for r in [header, *rows]))  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(gap), "--robot", str(robot), "--json"]) == 0
    assert sorted(json.loads(capsys.readouterr().out)["section_end_mean_mm"]) == ["1", "3"]
    typo = tmp_path / "typo.csv"
    typo.write_text(header.replace("x_3", "xx_3") + "".join(rows))
    assert main(["evaluate", str(est), str(typo), "--robot", str(robot), "--json"]) == 0
    out = capsys.readouterr()
    assert sorted(json.loads(out.out)["section_end_mean_mm"]) == ["1", "2"]
    assert out.err == (
        f"continuum-mhe: warning: {typo}: column(s) xx_3 for x_3? (a typo: such a column "
        "is left out)\n"
    )
    substituted = tmp_path / "substituted.csv"
    substituted.write_text(header.replace("x_3", "x-3") + "".join(rows))
    assert main(["evaluate", str(est), str(substituted), "--robot", str(robot)]) == 0
    assert "column(s) x-3 for x_3?" in capsys.readouterr().err
    # a bend without its phi, and a section's bend left out: each bend column there is
    # scored, none stops the command
    for drop in (("phi_2",), ("theta_2", "phi_2")):
        keep = [i for i, c in enumerate(names) if c not in drop]
        partial = tmp_path / f"partial{len(drop)}.csv"
        partial.write_text("".join(",".join(r.strip().split(",")[i] for i in keep) + "\n"
                                   for r in [header, *rows]))  # fmt: skip
        assert main(["evaluate", str(est), str(partial), "--robot", str(robot)]) == 0
        out = capsys.readouterr().out
        assert "RMSE theta_3, phi_3" in out
        assert ("RMSE theta_2 " in out) == (len(drop) == 1)
        fig = tmp_path / f"partial{len(drop)}.png"
        assert main(["plot", str(est), "--truth", str(partial), "--robot", str(robot),
                     "-o", str(fig)]) == 0  # fmt: skip
        assert fig.read_bytes()[:4] == b"\x89PNG"
    assert main(["evaluate", str(est), str(t), "--robot", str(robot)]) == 0
    assert "warning" not in capsys.readouterr().err


def test_an_empty_field_of_a_one_imu_file_is_a_dropout_as_with_several(tmp_path) -> None:
    """An empty roll or pitch in a one-IMU file is a dropout, as the same field of a
    several-IMU file is a dropout of its IMU, in ``estimate`` and in
    ``read_measurements`` (not an error such as ``'' is not a number``)."""
    from continuum_mhe.io.csv_files import read_measurements

    m, _ = _simulated(tmp_path, "a")
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
    names = _notes_and_rows(est)[1][0].strip().split(",")
    status = [r.strip().split(",")[names.index("status")] for r in _notes_and_rows(est)[1][1:]]
    assert status[49] == status[60] == "dropout" and status[48] == "ok"


def test_evaluate_with_times_that_do_not_match_is_an_error(tmp_path, capsys) -> None:
    """A truth at another rate is interpolated at the estimate's times (a note); one in
    milliseconds matches nowhere: one line, exit 2."""
    m, _ = _simulated(tmp_path, "a")
    _, t2 = _simulated(tmp_path, "b", "--dt", "0.0493")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t2)]) == 0
    assert "the truth is interpolated linearly at them (100 of 101 rows)" in (
        capsys.readouterr().err
    )
    rows = t2.read_text().splitlines()
    ms = tmp_path / "b_ms.csv"
    ms.write_text(
        "\n".join([rows[0], *(f"{1000 * float(r.split(',')[0])!r},{r.split(',', 1)[1]}"
                             for r in rows[1:])]) + "\n"
    )  # fmt: skip
    assert main(["evaluate", str(est), str(ms)]) == 2
    err = capsys.readouterr().err
    assert "only 1 of 101 rows" in err and "times do not match" in err


def test_evaluate_of_another_length_gets_a_hint(tmp_path, capsys) -> None:
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf", "--length", "0.5"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    out, err = capsys.readouterr()
    # evaluated on the length the estimate records (a note says so); one warning (not a
    # second, est against truth, for the same mistake), naming the truth and the length
    # it was made for
    assert err.count("warning") == 1, err
    assert f"note: {est} was estimated on 1 section (0.5 m), IMUs at 1@1, z-up" in err
    assert f"warning: {t}: its tip is 0.40 times as far from the base" in err
    # not "pass the --length": the estimate would then misfit it, the other way round
    assert "made for a robot of about 0.2 m; the estimate's robot (its options line) is" in err
    assert "SRMSE                not given" in out and not re.search(r"SRMSE\s+\d", out)
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf", "--overwrite"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    out, err = capsys.readouterr()
    assert "warning" not in err  # same length: no hint
    summed = r"SRMSE\s+\d\.\d{4} \(sum of the RMSEs of x, y, z, theta, phi, m \+ rad\)"
    assert re.search(summed, out)


@pytest.mark.parametrize(
    ("unit", "factor", "angles"), [("mm", 1000.0, True), ("cm", 100.0, True), ("mm", 1000.0, False)]
)
def test_evaluate_refuses_a_truth_whose_positions_are_in_mm_or_cm(
    tmp_path, capsys, unit: str, factor: float, angles: bool
) -> None:
    """A truth file whose x, y, z are in mm (or cm), with or without its bend angles:
    one line naming the file and the likely unit, exit 2, no figures (not a warning about
    a robot 1000 times as long and a tip error of hundreds of metres)."""
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    lines = t.read_text().splitlines()
    header = lines[0].split(",")
    xyz = [header.index(c) for c in ("x", "y", "z")]
    keep = [i for i, c in enumerate(header) if angles or c not in ("theta", "phi")]
    rows = []
    for line in lines[1:]:
        v = line.split(",")
        for i in xyz:
            v[i] = repr(float(v[i]) * factor)
        rows.append(",".join(v[i] for i in keep))
    scaled = tmp_path / "truth_scaled.csv"
    scaled.write_text(",".join(header[i] for i in keep) + "\n" + "\n".join(rows) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(est), str(scaled)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.startswith(f"continuum-mhe: error: {scaled}: its tip is ")
    assert err.rstrip().endswith(
        "times as far from the base as a robot of 0.2 m reaches: "
        f"positions in {unit}? give x, y, z in m"
    )


def test_position_units_without_angles_known_answers() -> None:
    """A file of tip positions alone (no angles): a straight robot's tip 100.5 times as
    far as the robot's length is in cm (not mm, though over 100); 150 times, beyond any
    shape in cm, is mm; 1.0 times is metres."""
    from continuum_mhe.io.position_units import position_unit_problem

    names = ("x", "y", "z")
    for factor, unit in ((100.5, "cm"), (150.0, "mm"), (1.0, None)):
        rows = np.tile([0.0, 0.0, 0.2 * factor], (5, 1))
        said = position_unit_problem(names, rows, (0.2,))
        assert said.endswith(f"positions in {unit}? give x, y, z in m") if unit else said == ""


def test_evaluate_with_another_robot_than_the_estimate_records_warns(tmp_path, capsys) -> None:
    """An estimate made with one robot file, evaluated with ``--robot`` naming another of
    other section lengths: a warning naming both and their lengths (the figures, in %
    of the length, are the given robot's); the recorded robot itself, or ``--robot``
    left out, gives none."""
    robot = tmp_path / "mine.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.15\ntheta_max = 2.5\n'
        "[[section]]\nlength = 0.12\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    m, t, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    argv = ["simulate", "spatial", "--robot", str(robot), "-o", str(m), "--truth", str(t)]
    assert main([*argv, "--duration", "2"]) == 0
    assert main(["estimate", str(m), "-o", str(est), "--robot", str(robot), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t), "--robot", "two-section"]) == 0
    err = capsys.readouterr().err
    assert err.count("warning") == 1, err
    assert (
        f"warning: {est} was estimated with --robot {robot} (its options line: sections of "
        "0.15, 0.12 m), not with --robot two-section (sections of 0.16, 0.14 m); the given "
        "one is used: leave --robot out to use the recorded one"
    ) in err
    for extra in (["--robot", str(robot)], []):
        assert main(["evaluate", str(est), str(t), *extra]) == 0
        assert "warning" not in capsys.readouterr().err


def test_evaluate_of_drifting_positions_names_no_other_length(tmp_path, capsys) -> None:
    """The paper formulation's positions drift from its angles (rows ``drifted``), by a
    factor that changes from row to row: no warning that the file was made for a robot
    of another length, which a constant factor alone means."""
    from continuum_mhe.io.position_units import steady_ratio

    m, t = _simulated(tmp_path, "p", "--duration", "20")
    est = tmp_path / "e.csv"
    argv = ["estimate", str(m), "-o", str(est), "--formulation", "paper", "--paper-start"]
    assert main(argv) == 0
    assert "drifted" in capsys.readouterr().err
    assert main(["evaluate", str(est), str(t)]) == 0
    assert "warning" not in capsys.readouterr().err
    assert steady_ratio(np.array([2.5, 2.51, 2.49, np.nan])) == pytest.approx(2.5)
    assert steady_ratio(np.array([1.0, 1.07, 1.19, 1.49, 1.64])) is None


def test_evaluate_of_an_unknown_status_is_an_error(tmp_path, capsys) -> None:
    # a status outside the vocabulary (edited by hand, another tool's "OK") is not read
    # as a row like any other, to which evaluate and view would give no meaning
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    lines = est.read_text().splitlines(keepends=True)
    row = next(i for i, line in enumerate(lines) if ",ok," in line)
    lines[row] = lines[row].replace(",ok,", ",OK,")
    est.write_text("".join(lines))
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert f"line {row + 1}: status 'OK' is not one of ok, dropout," in err


def test_evaluate_against_another_robots_truth_gives_no_srmse(tmp_path, capsys) -> None:
    """A two-section truth for a one-section estimate: the warning, and no SRMSE summed
    over the x, y, z they share that would read as a score."""
    m, _ = _simulated(tmp_path, "a")
    two = tmp_path / "two.csv"
    args = ["simulate", "spatial", "--robot", "two-section", "--duration", "5"]
    assert main([*args, "-o", str(tmp_path / "m2.csv"), "--truth", str(two)]) == 0
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(two)]) == 0
    out, err = capsys.readouterr()
    assert "warning" in err and "SRMSE                not given" in out
    # one warning: the truth's length is not checked against a robot it is not of
    assert err.count("warning") == 1 and "another robot" in err, err


def test_estimate_of_a_folder_that_is_not_a_bag(tmp_path, capsys) -> None:
    assert main(["estimate", str(tmp_path), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "is a directory without metadata.yaml, expected a CSV file or a ROS 2 bag folder" in err


def test_a_mistyped_option_is_one_line_naming_the_commands_help(tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["estimate", "m.csv", "-o", str(tmp_path / "e.csv"), "--methd", "ekf"])
    assert exit_.value.code == 2
    assert capsys.readouterr().err == (
        "continuum-mhe estimate: error: unrecognized arguments: --methd ekf; did you mean "
        "--method? (continuum-mhe estimate --help lists the options)\n"
    )
    with pytest.raises(SystemExit) as exit_:  # nothing close: no guess
        main(["estimate", "m.csv", "-o", str(tmp_path / "e.csv"), "--zzz"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("continuum-mhe estimate: error: unrecognized arguments: --zzz"), err
    assert err.count("\n") == 1 and "did you mean" not in err, err


def test_evaluate_of_a_partial_truth_warns(tmp_path, capsys) -> None:
    m, t = _simulated(tmp_path, "a")  # 101 rows
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    t.write_text("\n".join(t.read_text().splitlines()[:31]) + "\n")  # 30 of 101 rows
    capsys.readouterr()
    assert main(["evaluate", str(est), str(t)]) == 0
    err = capsys.readouterr().err
    assert err.startswith("continuum-mhe: warning: ") and "only 30 of 101 rows" in err


def _two_imu_robot(path: Path, mounts: tuple[str, str] = ("", "")) -> Path:
    imus = "".join(f"[[imu]]\nsection = {k}\n{m}\n" for k, m in zip((1, 2), mounts))
    sections = "[[section]]\nlength = 0.16\ntheta_max = 3.0\n" * 2
    path.write_text(sections + imus)
    return path


def _raw_two_imus(path: Path, n: int = 20) -> Path:
    rows = [f"{0.05 * i:.2f},0,0,9.8,0,0,0,0.1,0,9.8,0,0,0" for i in range(n)]
    cols = ",".join(f"{c}_{k}" for k in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz"))
    path.write_text("\n".join([f"t,{cols}", *rows]) + "\n")
    return path


@pytest.mark.parametrize(
    ("kind", "argv", "needle"),
    [
        ("tilt", ["--mount-rpy", "0,0,90"], "--mount-rpy does not apply to tilt input: it "
         "rotates raw accelerometer and gyro vectors, and roll and pitch are used as they are"),
        ("tilt", ["--attitude", "madgwick"], "--attitude madgwick does not apply to tilt input"),
        ("raw", ["--degrees"], "--degrees does not apply to this input: it is for roll and "
         "pitch in tilt CSV files; accelerations are read in m/s^2 and gyro rates in rad/s"),
        ("raw-mounted", ["--mount-rpy", "0,0,90"], "--mount-rpy applies to no IMU: the robot "
         "file gives every IMU its own mount_rpy"),
        # given as 0,0,0 (the default's value) it counts as given
        ("raw-mounted", ["--mount-rpy", "0,0,0"], "--mount-rpy applies to no IMU: the robot "
         "file gives every IMU its own mount_rpy, which wins (leave --mount-rpy out, or "
         "edit the robot file)"),
        ("tilt", ["--mount-rpy", "0,0,0"], "--mount-rpy does not apply to tilt input"),
        ("tilt", ["--topic", "/imu"], "--topic does not apply to this input: it is for ROS "
         "bags and MCAP files (sensor_msgs/Imu topics), and this is a CSV file"),
        ("raw", ["--orientation"], "--orientation does not apply to this input: it is for ROS"),
        ("raw", ["--pair-tolerance", "0.01"], "--pair-tolerance does not apply to this input"),
    ],
)  # fmt: skip
def test_an_option_that_does_nothing_on_this_input_is_refused(
    tmp_path, capsys, kind: str, argv: list[str], needle: str
) -> None:
    """An option that would do nothing on this input is refused in one line saying why,
    nothing written: --mount-rpy or --attitude on a tilt CSV, --degrees on a raw CSV,
    --mount-rpy where the robot file mounts every IMU, and a bag's --topic,
    --orientation or --pair-tolerance on a CSV."""
    every = ("mount_rpy = [0, 0, 30]", "mount_rpy = [0, 5, 0]")
    robot = _two_imu_robot(tmp_path / "robot.toml", every if kind == "raw-mounted" else ("", ""))
    if kind == "tilt":
        meas = tmp_path / "m.csv"
        meas.write_text("t,roll_1,pitch_1,roll_2,pitch_2\n0,0.1,0.1,0.2,0.2\n")
    else:
        meas = _raw_two_imus(tmp_path / "m.csv")
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--robot", str(robot), *argv]
    assert main([*argv, "--method", "ekf"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {meas}: {needle}")
    assert err.count("\n") == 1 and sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--method", "ekf", "--horizon", "50"], "--horizon is an MHE option; the ekf has no "
         "window"),
        (["--method", "ukf", "--paper-start"], "--paper-start is an MHE option; the ukf"),
        (["--method", "ekf", "--solver", "ipopt"], "--solver is an MHE option; the ekf"),
        (["--method", "ekf", "--hor", "20"], "--horizon is an MHE option"),  # abbreviated
        (["--method", "ekf", "--no-branch-check"], "--no-branch-check is an MHE option"),
        (["--method", "ekf", "--branch-check"], "--branch-check is an MHE option"),
        (["--method", "ekf", "--loss", "welsch"], "--loss welsch is an MHE option; the ekf "
         "keeps the l2 cost"),
        (["--robot", "two-section", "--length", "0.5"], "--length does not apply with the "
         "robot file two-section, which describes the robot (its sections, theta_max and "
         "mounting): leave it out, or edit the robot file"),
        (["--robot", "two-section", "--theta-max", "3"], "--theta-max does not apply with"),
    ],
)  # fmt: skip
def test_an_option_that_the_run_would_ignore_is_refused(
    tmp_path, capsys, argv: list[str], needle: str
) -> None:
    """An option given on the command line that the chosen estimator or the robot file
    would leave unused (an MHE option with a filter, a one-section option beside a robot
    file) is one line, exit 2, nothing written."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n0.02,0.1,0.1\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {needle}") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_robot_file_given_as_options_file_is_told_to_go_to_robot(tmp_path, capsys) -> None:
    """The robot file passed to ``--config`` by mistake: one line naming its first robot
    table and ``--robot``, not a complaint about an ``[[imu]]``'s ``section`` key."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1\n")
    robot = tmp_path / "robot.toml"
    robot.write_text('mounting = "z-up"\n\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    out = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(out), "--config", str(robot)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {robot}: line 3: [[section]], [[imu]]: a robot file, not an "
        "options file: give it with --robot\n"
    )
    assert not out.exists()


def test_a_profile_sets_mhe_options_a_filter_leaves_unused(tmp_path, capsys) -> None:
    """An options file is a profile for several commands and methods: its MHE options
    with ``--method ekf`` on the command line are no error; the same option given on the
    command line is."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1\n")
    cfg = tmp_path / "opts.toml"
    cfg.write_text('horizon = 12\nsolver = "ipopt"\nloss = "huber"\n')
    out = str(tmp_path / "e.csv")
    assert main(["estimate", str(meas), "--config", str(cfg), "--method", "ekf", "-o", out]) == 0
    capsys.readouterr()
    argv = ["estimate", str(meas), "--method", "ekf", "-o", out, "--overwrite", "--horizon", "12"]
    assert main(argv) == 2
    assert "--horizon is an MHE option" in capsys.readouterr().err
    # the method from the options file is the user's choice, not the robot's default
    cfg.write_text('method = "ekf"\n')
    argv = ["estimate", str(meas), "--config", str(cfg), "-o", out, "--overwrite"]
    assert main([*argv, "--horizon", "12"]) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: --horizon is an MHE option; the ekf has no window\n"
    )
    # the same file choosing the filter and setting an MHE option contradicts itself
    cfg.write_text('method = "ekf"\nhorizon = 10\n')
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {cfg}: line 2: horizon = 10 is an MHE option, and the same "
        "file chooses the ekf (method = 'ekf'), which has no window: remove one\n"
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    # in different tables they are a profile's: the MHE option waits for the MHE (live's)
    cfg.write_text('horizon = 10\n[estimate]\nmethod = "ekf"\n')
    assert main(argv) == 0
    capsys.readouterr()
    # an estimate file records a run, not a profile: its options line read back runs
    recorded = tmp_path / "recorded.csv"
    recorded.write_text(
        '# continuum-mhe = "0.1.0 estimate m.csv"\n'
        '# options = {method = "ekf", horizon = 12}\nt,x,y,z\n0,0,0,0.2\n'
    )
    argv_recorded = ["estimate", str(meas), "--config", str(recorded), "-o", out, "--overwrite"]
    assert main(argv_recorded) == 0
    capsys.readouterr()
    # a profile's MHE options unused by the filter are not recorded as the run's
    cfg.write_text("horizon = 12\n")
    assert main([*argv, "--method", "ekf"]) == 0
    capsys.readouterr()
    record = next(ln for ln in Path(out).read_text().splitlines() if ln.startswith("# options"))
    assert 'method = "ekf"' in record and "horizon" not in record
    # live refuses it before it opens the port (a board resets when it is opened)
    argv = ["live", "--port", str(tmp_path / "no-such-port"), "--method", "ekf", "--horizon", "8"]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: --horizon is an MHE option; the ekf has no window\n"
    )


@pytest.mark.parametrize("option", [["--horizon", "5"], ["--loss", "huber"], ["--branch-check"]])
def test_an_mhe_option_on_a_tendon_robot_names_the_mhe_that_takes_its_model(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: list[str]
) -> None:
    """A tendon robot's default is the EKF, and the fast MHE does not take its model: an
    MHE option given there is refused in one line that names the MHE on IPOPT (the one
    that runs), not ``--method mhe`` alone (itself refused on this robot)."""
    from importlib.resources import files

    tendon = files("continuum_mhe") / "data" / "tendon"
    out = tmp_path / "e.csv"
    argv = ["estimate", str(tendon / "unloaded_raw.csv"), "--robot", "tendon-two-section",
            "--inputs", str(tendon / "unloaded_tensions.csv"), "-o", str(out)]  # fmt: skip
    assert main([*argv, *option]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{option[0]}" in err and "is an MHE option" in err
    assert "(this robot's default; --method mhe --solver ipopt (slow) for the MHE)" in err
    assert not out.exists()


def test_an_options_files_value_out_of_range_names_the_file_and_line(tmp_path, capsys) -> None:
    """A value out of range in an options file is named by the file, its line and key
    (not as a command-line flag); given on the command line as well, the flag wins."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n")
    cfg = tmp_path / "opts.toml"
    cfg.write_text('method = "mhe"\nhorizon = -3\n')
    argv = ["estimate", str(meas), "--config", str(cfg), "-o", str(tmp_path / "e.csv")]
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {cfg}: line 2: horizon = -3 is outside its valid range "
        "[2, 1000] samples\n"
    )
    assert main([*argv, "--horizon", "1"]) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: --horizon 1 is outside its valid range [2, 1000] samples\n"
    )


def test_attitude_fusion_on_raw_input_with_gyros_says_it_takes_the_tilt_model(
    tmp_path, capsys
) -> None:
    """``--attitude`` on raw input with gyros, without ``--imu-model``, runs the tilt
    model instead of the default direct one: a warning says so (none with
    ``--imu-model tilt``)."""
    import ahrs  # noqa: F401  (a core dependency: the test needs it, never skips)

    robot = _two_imu_robot(tmp_path / "robot.toml")
    meas = _raw_two_imus(tmp_path / "m.csv")
    argv = ["estimate", str(meas), "--robot", str(robot), "--attitude", "mahony", "--method",
            "ekf", "-o", str(tmp_path / "e.csv"), "--overwrite"]  # fmt: skip
    said = []
    for extra in ([], ["--imu-model", "tilt"]):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            assert main([*argv, *extra]) == 0
        said.append([str(w.message) for w in seen if w.category is OptionWarning])
    assert [len(s) for s in said] == [1, 0]
    assert said[0][0].startswith("--attitude mahony takes the tilt model (roll and pitch")


def test_an_attitude_filter_with_the_direct_model_is_refused(tmp_path, capsys) -> None:
    """``--attitude`` chooses how the tilt model makes roll and pitch; the direct model
    takes the raw readings and has no attitude filter: the two together are one line
    naming both and what each is for, exit 2, nothing written (from an options file
    too, named by its line; in ``live`` before the port; in the library)."""
    from continuum_mhe.io.raw_imu import RawImuSettings

    robot = _two_imu_robot(tmp_path / "robot.toml")
    meas = _raw_two_imus(tmp_path / "m.csv")
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = ["estimate", str(meas), "--robot", str(robot), "-o", str(tmp_path / "e.csv"),
            "--imu-model", "direct"]  # fmt: skip
    assert main([*argv, "--attitude", "madgwick"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(
        "continuum-mhe: error: --attitude madgwick does not apply with --imu-model direct: "
        "--attitude chooses how --imu-model tilt makes roll and pitch from raw readings, and "
        "--imu-model direct puts the accelerometer and gyro readings into the model itself"
    ), err
    cfg = tmp_path / "opts.toml"
    cfg.write_text('attitude = "mahony"\n')
    assert main([*argv, "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert (
        f"error: {cfg}: line 1: attitude = 'mahony' does not apply with --imu-model direct" in err
    )
    port = tmp_path / "ttyACM9"
    live = ["live", "--port", str(port), "--robot", str(robot), "--imu-model", "direct"]
    assert main([*live, "--attitude", "mahony"]) == 2
    assert "--attitude mahony does not apply with --imu-model direct" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "opts.toml"])
    with pytest.raises(UserError, match=r"attitude='madgwick' is for imu_model='tilt'"):
        RawImuSettings(imu_model="direct", attitude="madgwick")


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--mount-rpy", "0,0,90"], "--mount-rpy applies to no IMU: the robot file gives "
         "every IMU its own mount_rpy, which wins"),
        (["--mount-rpy", "0,0,0"], "--mount-rpy applies to no IMU"),
        (["--format", "tilt", "--mount-rpy", "0,0,90"], "--mount-rpy does not apply to tilt "
         "input: it rotates raw accelerometer and gyro vectors"),
        (["--format", "tilt", "--attitude", "madgwick"], "--attitude madgwick does not apply "
         "to tilt input"),
    ],
)  # fmt: skip
def test_live_refuses_an_option_that_does_nothing_before_the_port(
    tmp_path, capsys, argv: list[str], needle: str
) -> None:
    """Live refuses --mount-rpy where the robot file gives every IMU its mount_rpy (and
    on tilt lines --mount-rpy and --attitude) as estimate does, naming the port, before
    it is opened; nothing written."""
    every = ("mount_rpy = [0, 0, 30]", "mount_rpy = [0, 5, 0]")
    robot = _two_imu_robot(tmp_path / "robot.toml", every)
    port = tmp_path / "ttyACM9"  # no such device: a check after opening it is not reached
    out = ["-o", str(tmp_path / "e.csv"), "--record", str(tmp_path / "r.csv")]
    assert main(["live", "--port", str(port), "--robot", str(robot), *out, *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {port}: {needle}") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["robot.toml"]


def test_a_robot_files_mount_rpy_on_tilt_input_warns_once_and_is_not_applied(
    tmp_path, capsys
) -> None:
    """docs/hardware.md: mount_rpy rotates raw vectors; tilt readings are used as they are.
    A robot file's mount_rpy on tilt input gets one warning, and the estimates equal those
    without it."""
    args = ["simulate", "spatial", "--robot", "two-section", "--duration", "2"]
    meas = tmp_path / "m.csv"
    assert main([*args, "-o", str(meas)]) == 0
    plain = _two_imu_robot(tmp_path / "plain.toml")
    mounted = _two_imu_robot(tmp_path / "mounted.toml", ("", "mount_rpy = [0, 0, 90]"))
    outs = []
    for robot in (plain, mounted):
        out = tmp_path / f"e_{robot.stem}.csv"
        argv = ["estimate", str(meas), "-o", str(out), "--robot", str(robot), "--method", "ekf"]
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            assert main(argv) == 0
        said = [str(w.message) for w in seen if w.category is OptionWarning]
        outs.append((out.read_text(), said))
    assert outs[0][1] == [] and outs[1][1] == [
        f"{meas}: the robot file's mount_rpy of IMU 2 is not applied to tilt input: it "
        "rotates raw readings, and roll and pitch are used as they are, taken as already in "
        "the backbone's frame (as simulate writes them); roll and pitch in an IMU's own "
        "frame need turning into its disk's first (docs/formats.md#tilt), or give its raw "
        "readings"
    ]
    # the same estimates (solve_ms aside; the '#' lines name each run's robot file)
    rows = [
        [r.rsplit(",", 1)[0] for r in text.splitlines() if not r.startswith("#")]
        for text, _ in outs
    ]
    assert len(rows[0]) == 42 and rows[0] == rows[1]  # the column line and 41 rows


def test_tilt_in_an_imus_own_frame_turns_into_its_disks_as_the_formats_page_says() -> None:
    """docs/formats.md#tilt: roll and pitch of a mounted IMU's own frame, turned by its
    mount_rpy through the gravity direction, are the roll and pitch of its disk's frame,
    those a tilt file takes: the same IMU's readings unmounted give them (without noise,
    the motion's own acceleration in both)."""
    from continuum_mhe.io.raw_imu import mount_rotation
    from continuum_mhe.simulation.raw_readings import RawNoise, raw_readings

    def tilt(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return np.arctan2(f[:, 1], f[:, 2]), np.arctan2(-f[:, 0], np.hypot(f[:, 1], f[:, 2]))

    rpy = (10.0, -20.0, 90.0)
    sections = (Section(0.15, theta_max=3.0), Section(0.12, theta_max=3.0))
    still = RawNoise(accel_std=0.0, gyro_std=0.0, gyro_bias_std=0.0)
    mounted, unmounted = (
        Robot(sections, (ImuPlacement(0), ImuPlacement(1, mount_rpy=mount)))
        for mount in (rpy, (0.0, 0.0, 0.0))
    )
    rec = simulate_robot("spatial", unmounted, duration=2.0, noise_deg=0.0)
    own_frame, disk_frame = (
        raw_readings(rec, robot, noise=still)[0][:, 6:9] for robot in (mounted, unmounted)
    )
    roll, pitch = tilt(own_frame)  # what an IMU reporting its own frame's tilt sends
    f = np.stack([-np.sin(pitch), np.sin(roll) * np.cos(pitch), np.cos(roll) * np.cos(pitch)], 1)
    turned = np.column_stack(tilt(f @ mount_rotation(rpy).T))
    disk = np.column_stack(tilt(disk_frame))
    assert np.abs(np.column_stack([roll, pitch]) - disk).max() > 0.3  # not the disk's as sent
    assert_allclose(np.angle(np.exp(1j * (turned - disk))), 0.0, atol=1e-9)


def test_mount_rpy_still_applies_to_raw_imus_without_their_own(tmp_path, capsys) -> None:
    robot = _two_imu_robot(tmp_path / "robot.toml", ("mount_rpy = [0, 0, 30]", ""))
    meas = _raw_two_imus(tmp_path / "m.csv")
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--robot", str(robot)]
    assert main([*argv, "--method", "ekf", "--mount-rpy", "0,0,90"]) == 0
    assert "warning" not in capsys.readouterr().err


THREE_SECTIONS = "".join(
    f"[[section]]\nlength = {v}\ntheta_max = 2.0\n" for v in (0.12, 0.1, 0.08)
) + "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3))


@pytest.fixture(scope="module")
def two_and_three(tmp_path_factory) -> dict[str, Path]:
    """A two-section EKF estimate, its truth, and a three-section truth at the same t."""
    tmp = tmp_path_factory.mktemp("robots")
    (tmp / "robot3.toml").write_text(THREE_SECTIONS)
    paths = {k: tmp / f"{k}.csv" for k in ("m2", "t2", "e2", "m3", "t3")}
    sim = ["simulate", "spatial", "--duration", "2"]
    assert main([*sim, "--robot", "two-section", "-o", str(paths["m2"]),
                 "--truth", str(paths["t2"])]) == 0  # fmt: skip
    assert main([*sim, "--robot", str(tmp / "robot3.toml"), "-o", str(paths["m3"]),
                 "--truth", str(paths["t3"])]) == 0  # fmt: skip
    argv = ["estimate", str(paths["m2"]), "-o", str(paths["e2"]), "--robot", "two-section"]
    assert main([*argv, "--method", "ekf"]) == 0
    return paths


def test_evaluate_against_a_truth_of_more_sections_warns_and_gives_no_srmse(
    two_and_three, capsys
) -> None:
    """A two-section estimate against a three-section truth: a warning that the truth is
    of another robot, and no SRMSE (None in the JSON)."""
    e2, t2, t3 = two_and_three["e2"], two_and_three["t2"], two_and_three["t3"]
    capsys.readouterr()
    assert main(["evaluate", str(e2), str(t2), "--robot", "two-section"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and re.search(r"SRMSE\s+\d", out)
    assert main(["evaluate", str(e2), str(t3), "--robot", "two-section"]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: warning: {t3}: its columns (theta_1, theta_2, theta_3) do not fit the "
        "robot (2 sections (0.16 m, 0.14 m), IMUs at 1@1, 2@1, z-up): extra theta_3: the truth "
        "is of another robot (pass --robot with its robot)\n"
    )
    assert "SRMSE                not given" in out and not re.search(r"SRMSE\s+\d", out)
    assert main(["evaluate", str(e2), str(t3), "--robot", "two-section", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["srmse"] is None


def test_a_truth_of_fewer_sections_is_said_in_evaluate_and_refused_in_plot(
    two_and_three, tmp_path, capsys
) -> None:
    """A three-section estimate against a two-section truth: its columns are a subset of
    the three-section robot's, but its section 2 ends at its tip in every row. evaluate
    warns that it is of another robot and gives no SRMSE; plot refuses it in one line;
    the three-section truth passes both."""
    robot3 = two_and_three["m3"].parent / "robot3.toml"
    e3 = tmp_path / "e3.csv"
    assert main(["estimate", str(two_and_three["m3"]), "--robot", str(robot3), "--method",
                 "ekf", "-o", str(e3)]) == 0  # fmt: skip
    t2, t3 = two_and_three["t2"], two_and_three["t3"]
    capsys.readouterr()
    assert main(["evaluate", str(e3), str(t2), "--robot", str(robot3)]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: warning: {t2}: section 2's end is its tip in every row: a robot of "
        "2 section(s), not 3: the truth is of another robot (pass --robot with its robot)\n"
    )
    assert "SRMSE                not given" in out
    assert main(["plot", str(e3), "--truth", str(t2), "-o", str(tmp_path / "p.png")]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {t2}: the truth's section 2 ends at its tip in every row: a "
        "truth of a robot of 2 section(s), not of this estimate's 3?\n"
    )
    assert not (tmp_path / "p.png").exists()
    # without section 1's columns (a truth may have some sections' and not others')
    table = read_state_table(t2)
    keep = [i for i, n in enumerate(table.names) if not n.endswith("_1")]
    gapped = tmp_path / "t2_gapped.csv"
    write_table(gapped, ["t", *(table.names[i] for i in keep)],
                np.column_stack([table.t, table.values[:, keep]]).tolist())  # fmt: skip
    assert main(["evaluate", str(e3), str(gapped), "--robot", str(robot3)]) == 0
    assert "section 2's end is its tip in every row" in capsys.readouterr().err
    assert main(["evaluate", str(e3), str(t3), "--robot", str(robot3)]) == 0
    out, err = capsys.readouterr()
    assert err == "" and re.search(r"SRMSE\s+\d", out)


def _on_the_device_clock(src: Path, dst: Path, t0: float) -> list[str]:
    """``src`` with ``t0`` s added to every row's t (the first column), as a device
    clock that has run for days gives it; the new t cells, in order."""
    lines, cells = src.read_text().splitlines(keepends=True), []
    with dst.open("w") as fh:
        for ln in lines:
            if ln.startswith("#") or not ln[0].isdigit():
                fh.write(ln)
                continue
            t, rest = ln.split(",", 1)
            cells.append(repr(t0 + float(t)))
            fh.write(f"{cells[-1]},{rest}")
    return cells


def test_evaluate_says_device_clock_times_that_differ_differently(tmp_path, capsys) -> None:
    """Times of a device clock past 4.3e6 s are said as they read back, so times 0.05 s
    apart differ in the messages (%g would print both as ``4.29496e+06``, in ``its rows
    cover t = ...`` and ``t=... does not increase (previous t=...)``)."""
    m, t = _simulated(tmp_path, "a")
    est, cut = tmp_path / "e.csv", tmp_path / "cut.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    notes, rows = _notes_and_rows(est)
    cut.write_text("".join(notes + rows[:31]))
    t0 = 4294960.0
    cut_dev, t_dev = tmp_path / "cut_dev.csv", tmp_path / "t_dev.csv"
    te, tt = _on_the_device_clock(cut, cut_dev, t0), _on_the_device_clock(t, t_dev, t0)
    capsys.readouterr()
    assert main(["evaluate", str(cut_dev), str(t_dev)]) == 0
    assert capsys.readouterr().err.splitlines() == [
        f"continuum-mhe: warning: {cut_dev}: its rows cover t = 4294960 to 4294961.45 s of "
        f"{t_dev}'s 4294960 to 4294965 s (29 %): the scores are of that part only (an "
        "interrupted or cut estimate?)"
    ]
    assert (te[-1], tt[-1]) == ("4294961.45", "4294965.0")
    notes, rows = _notes_and_rows(cut_dev)
    back = tmp_path / "back.csv"  # the fourth row again after the fifth: 0.05 s back
    back.write_text("".join(notes + rows[:6] + rows[4:5]))
    assert main(["evaluate", str(back), str(t_dev)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {back}: line {len(notes) + 7}: t={te[3]} does not increase "
        f"(previous t={te[4]})\n"
    )
    assert te[3] != te[4]


def test_evaluate_of_a_multi_section_estimate_without_its_robot_is_an_error(
    two_and_three, tmp_path, capsys
) -> None:
    """evaluate e2.csv t2.csv of a multi-section estimate without --robot takes the
    robot file the estimate's options line names (said in a note), not the one-section
    0.2 m robot; without that line (an estimate from elsewhere), an error naming --robot."""
    e2, t2 = two_and_three["e2"], two_and_three["t2"]
    capsys.readouterr()
    assert main(["evaluate", str(e2), str(t2)]) == 0
    out, err = capsys.readouterr()
    assert "evaluated on that robot (pass --robot for another)" in err and "tip error mean" in out
    bare = tmp_path / "bare.csv"  # the same rows without the comment lines
    bare.write_text("".join(ln for ln in e2.read_text().splitlines(True) if ln[0] != "#"))
    assert main(["evaluate", str(bare), str(t2)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {bare}: its columns (theta_1, theta_2) do not fit the robot "
        "(1 section (0.2 m), IMUs at 1@1, z-up): missing theta; extra theta_1, theta_2; pass "
        "--robot with the robot it was estimated on\n"
    )
    robot3 = two_and_three["m2"].parent / "robot3.toml"
    assert main(["evaluate", str(e2), str(two_and_three["t3"]), "--robot", str(robot3)]) == 2
    assert "missing theta_3; pass --robot" in capsys.readouterr().err
    tip = tmp_path / "tip.csv"  # an estimate of the tip only: no robot to check against
    rows = e2.read_text().splitlines()
    tip.write_text("\n".join(",".join(r.split(",")[:4]) for r in rows) + "\n")
    assert main(["evaluate", str(tip), str(t2), "--robot", "two-section"]) == 0
    assert "tip error mean" in capsys.readouterr().out


def test_integer_ranges_are_said_as_integers_and_zero_noise_says_why(tmp_path, capsys) -> None:
    """``--seed -1`` says ``valid range [0, 4294967295]`` (not ``4.29497e+09``), and
    ``estimate --noise-deg 0`` says why the estimators need a positive noise, with the
    valid range ``(0, 90]``, where simulate takes 0."""
    assert main(["demo", "--seed", "-1", "--out", str(tmp_path / "d")]) == 2
    assert "valid range [0, 4294967295]" in capsys.readouterr().err
    meas = tmp_path / "m.csv"
    argv = ["simulate", "paper3d", "--duration", "1", "--noise-deg", "0", "-o", str(meas)]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--noise-deg", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "--noise-deg 0: the estimators need a positive measurement noise, valid range "
        "(0, 90] deg here (simulate takes 0: noise-free data)"
    )
    assert not (tmp_path / "e.csv").exists()
    # a negative noise: the option's range, and what the estimators need
    assert main(["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--noise-deg", "-1"]) == 2
    assert (
        capsys.readouterr()
        .err.strip()
        .endswith(
            "--noise-deg -1.0 is outside its valid range [0, 90] deg: the estimators need more "
            "than 0 (simulate takes 0: noise-free data)"
        )
    )


def test_a_multi_section_scenario_from_simulate_names_simulate_robot() -> None:
    """``simulate("spatial")`` names the library call to use, ``simulate_robot('spatial',
    robot)`` (not the command line's --robot), which ``continuum_mhe`` exports and which
    simulates the scenario."""
    import continuum_mhe
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot

    with pytest.raises(UserError, match=r"simulate_robot\('spatial', robot\)"):
        continuum_mhe.simulate("spatial")
    rec = continuum_mhe.simulate_robot("spatial", read_robot("two-section"), duration=1.0)
    assert rec.z.shape == (21, 4) and np.all(np.isfinite(rec.z))


def test_an_imu_on_a_missing_section_in_code_says_the_index_is_0_based() -> None:
    """``ImuPlacement(section=2)`` on a two-section robot names the 0-based index the
    user wrote, not 'section 3' (robot files are 1-based, code 0-based)."""
    from continuum_mhe import ImuPlacement, Robot, Section
    from continuum_mhe.errors import UserError

    sections = (Section(0.1), Section(0.1))
    with pytest.raises(UserError) as info:
        Robot(sections, (ImuPlacement(section=0), ImuPlacement(section=2)))
    assert str(info.value) == (
        "IMU 2: ImuPlacement.section=2 is a 0-based section index, but the robot has 2 "
        "section(s) (indices 0 to 1; robot files number sections from 1)"
    )
    assert Robot(sections, (ImuPlacement(section=0), ImuPlacement(section=1))).n_imus == 2


def test_the_paper_formulation_on_two_sections_names_options_that_exist(tmp_path, capsys) -> None:
    """The paper formulation on two sections says to leave the option out (the default
    model takes the robot, tilt or raw), and the default runs (``--formulation direct``
    is no choice, and ``--imu-model direct`` is the default with raw input)."""
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll_1,pitch_1,roll_2,pitch_2\n0,0.1,0.1,0.2,0.2\n")
    argv = ["estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--robot", "two-section"]
    assert main([*argv, "--formulation", "paper"]) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: the paper formulation models one section with one tip IMU; "
        "this robot has 2 sections (0.16 m, 0.14 m), IMUs at 1@1, 2@1, z-up: leave "
        "--formulation paper out (the default model, bend with tilt readings and direct "
        "with raw ones, takes any robot; in Python make_formulation('bend', robot))\n"
    )
    assert main([*argv, "--method", "ekf"]) == 0


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_raw_readings_in_the_wrong_units_given_to_an_estimator_are_refused(method) -> None:
    """The direct model reads a unit specific force and rad/s: an accelerometer's reading
    in m/s^2 (step and run), or gyros in deg/s (run; step below), is one UserError naming the
    readings, and the readings built by ``direct_measurements`` pass."""
    from continuum_mhe.model.direct import direct_measurements

    f = make_formulation("direct")
    est = make_estimator(method, f)
    acc = np.array([[0.3, -0.2, 9.79]])
    meters_per_s2 = r"^measurement at t=0\.0 s: fx, fy, fz have magnitude 9\.8"
    with pytest.raises(UserError, match=meters_per_s2):
        est.step(Measurement(0.0, np.array([0.3, -0.2, 9.79, 0.01, 0.0, 0.02])))
    t = np.arange(40) * 0.02
    degrees_per_s = np.tile(direct_measurements(acc, np.radians([[30.0, 0.0, 0.0]])), (40, 1))
    degrees_per_s[:, 3:] = np.degrees(degrees_per_s[:, 3:])
    with pytest.raises(
        UserError,
        match=r"^wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30 \(median\)"
        r".*deg/s",
    ):
        est.run(t, degrees_per_s)
    good = np.tile(direct_measurements(acc, [[0.01, 0.0, 0.02]]), (40, 1))
    good[0] = np.nan  # a dropout first: step checks the first full reading
    series = est.run(t, good)
    assert np.isfinite(series.output[5:]).all()
    est.reset()
    for tk, zk in zip(t, good):
        est.step(Measurement(float(tk), zk))
    est.reset()  # a reading in m/s^2 after the dropout is the first full one: refused
    est.step(Measurement(0.0, good[0]))
    with pytest.raises(UserError, match=r"^measurement at t=0\.02 s: fx, fy, fz have magnitude"):
        est.step(Measurement(0.02, np.array([0.3, -0.2, 9.79, 0.01, 0.0, 0.02])))


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_a_resting_gyro_in_degrees_per_second_is_refused_by_run_and_step(method) -> None:
    """``direct`` readings of an IMU at rest whose gyro is in deg/s (a bias of about 2
    deg/s: its median rate is far below the deg/s threshold) are refused by ``run`` (the
    whole recording) and by ``step`` (at the sample that completes the first check),
    because read as rad/s the gyro would turn the still specific force by tens of
    degrees a second; the same readings in rad/s run through."""
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import direct_measurements

    rng = np.random.default_rng(5)
    n = UNIT_CHECK_SAMPLES + 20
    t = np.arange(n) * 0.02
    acc = np.array([0.3, -0.2, 9.79]) + rng.normal(0.0, 0.05, (n, 3))
    deg_s = np.array([1.2, -1.5, 0.9]) + rng.normal(0.0, 0.3, (n, 3))
    degs = direct_measurements(acc, deg_s)
    rads = direct_measurements(acc, np.radians(deg_s))
    said = (
        r"wx, wy, wz \(the gyro's gx, gy, gz\): the accelerometer's gravity direction turns "
        r"as the gyro says only"
    )
    est = make_estimator(method, make_formulation("direct"))
    with pytest.raises(ReadingUnitsError, match=said):
        est.run(t, degs)
    assert np.isfinite(est.run(t, rads).output[-1]).all()
    est.reset()
    for k in range(UNIT_CHECK_SAMPLES - 1):
        est.step(Measurement(float(t[k]), degs[k]))
    with pytest.raises(ReadingUnitsError, match=rf"^measurement at t=.* s: {said}"):
        est.step(Measurement(float(t[UNIT_CHECK_SAMPLES - 1]), degs[UNIT_CHECK_SAMPLES - 1]))


@pytest.mark.parametrize("method", ["mhe", "ekf"])
def test_gyros_in_degrees_per_second_stepped_one_by_one_are_refused(method) -> None:
    """A stream of raw readings whose gyros are in deg/s, handed to ``step`` sample by
    sample or to ``continue_run`` in blocks: a ReadingUnitsError at the sample that
    completes the first UNIT_CHECK_SAMPLES full readings over a second (their median),
    naming the gyro columns, and again at every later sample until a reset (named with its
    own time and the one that showed it); the samples
    before it are estimated. The same stream in rad/s runs through, and so does a
    1 kHz stream that turns at 6 rad/s for its first 0.12 s (a fast start, not deg/s)."""
    from continuum_mhe.estimators.reading_units import ReadingUnitsError
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import direct_measurements

    n = UNIT_CHECK_SAMPLES + 20
    t = np.arange(n) * 0.02
    acc = np.array([[0.3, -0.2, 9.79]])
    rad_s = np.tile(direct_measurements(acc, np.radians([[30.0, 5.0, 0.0]])), (n, 1))
    rad_s[0] = np.nan  # a dropout first: the median is of full readings
    deg_s = rad_s.copy()
    deg_s[:, 3:] = np.degrees(deg_s[:, 3:])
    est = make_estimator(method, make_formulation("direct"))
    last = UNIT_CHECK_SAMPLES  # sample 0 has no reading: sample 100 is the 100th full one
    for k in range(last):
        est.step(Measurement(float(t[k]), deg_s[k]))
    said = (
        rf"^measurement at t={float(t[last])!r} s: wx, wy, wz \(the gyro's gx, gy, gz\): "
        r"gyro magnitude is about "
        rf"30\.4 \(median of the first {UNIT_CHECK_SAMPLES} full readings, 1\.98 s\), "
        r"implausible in rad/s \(above 5\): deg/s\? give rad/s"
    )
    with pytest.raises(ReadingUnitsError, match=said):
        est.step(Measurement(float(t[last]), deg_s[last]))
    later = (  # the next sample too, named with its own time and the one that showed it
        rf"^measurement at t={float(t[last + 1])!r} s: as found at t={float(t[last])!r} s, "
        r"wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30\.4"
    )
    with pytest.raises(ReadingUnitsError, match=later):
        est.step(Measurement(float(t[last + 1]), deg_s[last + 1]))
    est.reset()
    first = est.continue_run(t[:60], deg_s[:60])  # not yet the first 100: stepped
    assert len(first.status) == 60
    with pytest.raises(
        UserError, match=r"wx, wy, wz \(the gyro's gx, gy, gz\): gyro magnitude is about 30\.4"
    ):
        est.continue_run(t[60:], deg_s[60:])
    est.reset()
    for k in range(n):
        assert est.step(Measurement(float(t[k]), rad_s[k])).status != "no-estimate" or k == 0
    est.reset()
    assert np.isfinite(est.continue_run(t, rad_s).output[5:]).all()
    fast = np.arange(1500) * 0.001  # 1 kHz: 6 rad/s for 0.12 s, then nearly at rest
    turn = np.where(fast[:, None] < 0.12, [[6.0, 0.0, 0.0]], [[0.01, 0.0, 0.0]])
    est.reset()
    est.continue_run(fast, direct_measurements(np.tile(acc, (1500, 1)), turn))


def test_each_raw_imus_first_full_reading_is_checked_by_step() -> None:
    """With one IMU silent from the start, the other's readings in m/s^2 are still
    refused at its first reading (the check does not wait for a sample with every IMU)."""
    from continuum_mhe.io.robot_file import read_robot

    est = make_estimator("ekf", make_formulation("direct", read_robot("two-section")))
    z = np.full(12, np.nan)
    z[:6] = [0.3, -0.2, 9.79, 0.01, 0.0, 0.02]  # IMU 1 in m/s^2, IMU 2 silent
    with pytest.raises(UserError, match=r"^measurement at t=0\.0 s: fx_1, fy_1, fz_1 have"):
        est.step(Measurement(0.0, z))


def test_compute_metrics_refuses_what_does_not_fit_in_one_user_error() -> None:
    """``compute_metrics`` names each mistake in a UserError: an estimate series given
    for its array, arrays of different lengths or with another column count than their
    names, a length that is not a number, a string for the names; a length or positions
    in mm (as ``evaluate`` refuses them)."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    in_mm = rec.truth.copy()
    in_mm[:, :3] *= 1000.0
    cases = [
        ((s, rec.truth, 0.2), "not an EstimateSeries: pass its .output"),
        ((s.output[:-1], rec.truth, 0.2), "estimate has 40 rows but truth has 41"),
        ((s.output, rec.truth, "0.2"), "length must be a number"),
        ((s.output, rec.truth, -0.2), "length must be a positive number"),
        ((s.output, rec.truth, math.inf), "length must be a positive number"),
        ((s.output, rec.truth[:, :3], 0.2), r"truth has 3 columns, but names gives 5"),
        ((s.output, rec.truth, 0.2, ["x", "y", "z"]), "estimate has 5 columns, but names gives 3"),
        ((s.output, rec.truth, 0.2, "xyz"), "names must be a sequence of column names"),
        ((s.output[:, :1], rec.truth[:, :1], 0.2, ["x"]), "both sides need the tip column 'y'"),
        ((s.output, rec.truth, 200), r"length 200 m is over 5 m: .*millimetres"),
        ((s.output, in_mm, 0.2), r"^truth: its tip is 1000 times as far .* positions in mm\?"),
        ((in_mm, in_mm, 0.2), r"^estimate: its tip is 1000 times as far .* positions in mm\?"),
    ]
    for args, match in cases:
        with pytest.raises(UserError, match=match):
            compute_metrics(*args)


def test_compute_metrics_refuses_positions_in_mm_of_a_robot_of_several_sections() -> None:
    """Positions in mm on a two-section robot, whose bend columns (theta_1, theta_2, ...)
    the one ``length`` cannot check: the tip's distance from the base alone says it (a
    2,000 mm tip error without it), on either side and on both."""
    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    rec = simulate_robot("s-curve", robot, duration=1.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, rec.z)
    names = list(s.names)
    metres = [i for i, o in enumerate(s.outputs) if o.unit == "m"]
    est_mm, truth_mm = s.output.copy(), rec.truth.copy()
    est_mm[:, metres] *= 1000.0
    truth_mm[:, metres] *= 1000.0
    assert compute_metrics(s.output, rec.truth, 0.3, names).tip_mean_mm < 50.0
    for args, side in (((est_mm, rec.truth), "estimate"), ((s.output, truth_mm), "truth"),
                       ((est_mm, truth_mm), "estimate")):  # fmt: skip
        with pytest.raises(UserError, match=rf"^{side}: its tip is .* positions in mm\?"):
            compute_metrics(*args, 0.3, names)


def test_aligned_truth_refuses_a_truth_whose_rows_and_times_differ() -> None:
    """``aligned_truth`` with times of another length than the truth's rows (rows paired
    five samples apart, 16 mm of error added, without it), or values of another column
    count than their names: a UserError naming both; the same arrays aligned run."""
    from continuum_mhe.evaluation.metrics import aligned_truth

    rec = simulate("paper3d", duration=2.0, seed=1)
    names = [o.name for o in rec.outputs]
    with pytest.raises(UserError, match=r"^values has 41 rows but t_truth has 36"):
        aligned_truth(rec.t, rec.t[5:], rec.truth, names)
    with pytest.raises(UserError, match=r"^values has 5 columns, but names gives 3"):
        aligned_truth(rec.t, rec.t, rec.truth, names[:3])
    for args, needle in (
        (("abc", rec.t), "t_est must be an array of times (s), got 'abc'"),
        ((rec.t, [None, "x"]), "t_truth must be an array of times (s), got [None, 'x']"),
    ):  # a ValueError or TypeError from numpy
        with pytest.raises(UserError, match="^" + re.escape(needle)):
            aligned_truth(*args, rec.truth, names)
    i_est, rows, interpolated = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(i_est) == len(rec.t) and not interpolated
    np.testing.assert_array_equal(rows, rec.truth)


def test_aligned_truth_refuses_times_that_do_not_increase() -> None:
    """A truth whose rows are out of time order: times that do not increase are a
    UserError naming the row (not aligned on 1 of 61 rows, with a warning that blames
    milliseconds); the same truth sorted aligns every row."""
    from continuum_mhe.evaluation.metrics import aligned_truth

    rec = simulate("paper3d", duration=3.0, seed=1)
    names = [o.name for o in rec.outputs]
    order = np.random.default_rng(0).permutation(len(rec.t))
    with pytest.raises(UserError, match=r"^t_truth must increase: row \d+ is at"):
        aligned_truth(rec.t, rec.t[order], rec.truth[order], names)
    with pytest.raises(UserError, match=r"^t_est must increase: row 1 is at 0 s after 0.05 s"):
        aligned_truth(rec.t[[1, 0, 2]], rec.t, rec.truth, names)
    i_est, _, _ = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(i_est) == len(rec.t)


def test_compute_metrics_refuses_angles_in_degrees() -> None:
    """Bend angles in degrees (a theta RMSE of 54 "rad"): beyond a turn, they are a
    UserError naming the side, row and column, as read_state_table refuses them."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    degrees = rec.truth * [1.0, 1.0, 1.0, 180 / math.pi, 180 / math.pi]
    for est, truth, side in ((rec.truth, degrees, "truth"), (degrees, rec.truth, "estimate")):
        with pytest.raises(UserError, match=rf"^{side}: row \d+: (theta|phi)=[\d.]+ beyond 2 pi"):
            compute_metrics(est, truth, 0.2)
    assert compute_metrics(rec.truth, rec.truth, 0.2).tip_mean_mm == 0.0


def test_compute_metrics_skips_rows_without_a_finite_truth_and_counts_them() -> None:
    """Rows whose truth is NaN (a gap in a motion capture) are left out of the metrics
    and counted, as rows without an estimate are: the metrics are those of the other
    rows alone."""
    rec = simulate("paper3d", duration=2.0, seed=1)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    truth = rec.truth.copy()
    truth[5:10] = np.nan
    keep = np.ones(len(truth), dtype=bool)
    keep[5:10] = False
    m = compute_metrics(s.output, truth, 0.2)
    want = compute_metrics(s.output[keep], rec.truth[keep], 0.2)
    assert (m.n, m.n_without_truth, m.n_without_estimate) == (36, 5, 0)
    assert m.tip_mean_mm == want.tip_mean_mm and m.rmse == want.rmse
    truth[:] = np.nan
    with pytest.raises(UserError, match="no estimated sample has a finite truth"):
        compute_metrics(s.output, truth, 0.2)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (
            "make_formulation('direct', gyro_std='0.01')",
            "gyro_std must be a positive finite number",
        ),
        ("read_measurements(CSV, n_imus='2')", "n_imus must be a positive integer"),
        ("read_measurements(CSV, degrees='yes')", "degrees must be True or False"),
        ("load_input(CSV, None, make_formulation('bend'))", "options must be an InputOptions"),
        (
            "load_input(CSV, {'degrees': True}, make_formulation('bend'))",
            "options must be an InputOptions",
        ),
        ("open_input(CSV, InputOptions(), 'bend')", "formulation must be a Formulation"),
        ("write_estimates(None, SERIES)", "path must be a file path"),
        ("ImuPlacement(0, gyro_bias=('a', 'b', 'c'))", "IMU gyro_bias must be three finite rates"),
        ("ImuPlacement(0, gyro_bias=0.0)", "IMU gyro_bias must be three finite rates"),
        ("ImuPlacement(1.0)", "IMU section must be an integer"),
        ("RawImuSettings(mount_rpy=('a', 0, 0))", "mount_rpy must be three finite angles"),
        ("RawImuSettings(gyro_bias=0.1)", "gyro_bias must be three finite rates"),
        ("write_measurements(OUT, [0.0, 0.0], [[0.1, 0.1], [0.1, 0.1]])", "strictly increasing"),
        ("write_measurements(OUT, [0.0], [[0.1]])", "z has 1 columns, expected 2"),
        ("write_measurements(OUT, [0.0], [[0.1] * 4])", r"expected 2 \(roll, pitch\).*names="),
        ("write_truth(OUT, [0.0], [[0.0] * 18])", r"truth has 18 columns.*outputs=rec.outputs"),
        ("write_truth(OUT, [0.0], [[np.nan] * 5])", "refusing to write a non-finite value"),
        ("write_truth(OUT, [0.0], [[0.0] * 5] * 2)", "t has 1 samples and truth 2 rows"),
        ("write_measurements(OUT, [0.0, 1.0], [[0.1, 0.1]])", "t has 2 samples and z 1 rows"),
    ],
)
def test_library_calls_refuse_wrong_types_in_one_user_error(tmp_path, call, match) -> None:
    """Public library calls given a wrong type or an impossible value raise a UserError
    naming the argument, not a TypeError or AttributeError from inside; nothing is
    written."""
    import continuum_mhe.io as io
    from continuum_mhe.io.raw_imu import RawImuSettings
    from continuum_mhe.model.robot import ImuPlacement

    rec = simulate("paper3d", duration=0.2)
    csv = tmp_path / "m.csv"
    io.write_measurements(csv, rec.t, rec.z)
    names = {
        "CSV": csv, "OUT": tmp_path / "out.csv", "np": np, "make_formulation": make_formulation,
        "SERIES": make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z),
        **{name: getattr(io, name) for name in (
            "InputOptions", "load_input", "open_input", "read_measurements", "write_estimates",
            "write_measurements", "write_truth",
        )},
        "RawImuSettings": RawImuSettings, "ImuPlacement": ImuPlacement,
    }  # fmt: skip
    with pytest.raises(UserError, match=match):
        eval(call, names)
    assert not (tmp_path / "out.csv").exists()


def test_an_imu_section_given_as_a_numpy_integer_is_taken() -> None:
    """A section index that is a numpy integer (from an array) is an index like any
    other; a float is refused by its type."""
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot = Robot((Section(0.1), Section(0.1)), (ImuPlacement(0), ImuPlacement(np.int64(1))))
    assert robot.imus[1].section == 1 and type(robot.imus[1].section) is int


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


def test_masked_readings_are_dropouts() -> None:
    """A numpy masked array's masked readings are missing (NaN), in ``run`` and ``step``
    alike: ``numpy.asarray`` would keep the values under the mask (a disconnected
    sensor's noise, estimated as ``ok``)."""
    import numpy as np

    from continuum_mhe import Measurement, make_estimator, make_formulation, simulate

    rec = simulate("paper3d", duration=20.0, seed=0)
    z = rec.z.copy()
    z[100:140] = np.random.default_rng(1).normal(0.0, 0.035, (40, 2))
    masked = np.ma.masked_array(z, mask=False)
    masked[100:140] = np.ma.masked
    nan = z.copy()
    nan[100:140] = np.nan
    est = make_estimator("ekf", make_formulation("bend"))
    by_mask, by_nan = est.run(rec.t, masked), est.run(rec.t, nan)
    assert set(by_mask.status[100:140]) == {"dropout"}
    np.testing.assert_array_equal(by_mask.output, by_nan.output)
    est.reset()
    stepped = [est.step(Measurement(float(t), zi)) for t, zi in zip(rec.t, masked)]
    assert {str(e.status) for e in stepped[100:140]} == {"dropout"}


def test_a_formulation_switch_is_a_bool() -> None:
    import pytest

    from continuum_mhe import make_formulation
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot

    robot = read_robot("two-section")
    for value in ("false", "no", None, 0):
        with pytest.raises(UserError, match="estimate_gyro_bias must be True or False"):
            make_formulation("direct", robot, estimate_gyro_bias=value)
    assert not any(
        s.startswith("bg")
        for s in make_formulation("direct", robot, estimate_gyro_bias=False).state_names
    )
    tendon = read_robot("tendon-two-section")  # an option that None leaves to the model
    with pytest.raises(UserError, match="must be True, False or None, got 'false'"):
        make_formulation("tendon", tendon, acceleration_from_force_rate="false")
    make_formulation("tendon", tendon, acceleration_from_force_rate=None)


def test_measurements_and_truth_on_a_unix_clock_round_trip(tmp_path) -> None:
    """Times of a Unix clock (1.7e9 s) keep their microseconds in the files the library
    writes (10 significant digits made every row 1700000000, which its reader refuses
    as a repeated time)."""
    import numpy as np

    from continuum_mhe import simulate
    from continuum_mhe.io import (
        read_measurements,
        read_state_table,
        write_measurements,
        write_truth,
    )

    rec = simulate("paper3d", duration=5.0)
    t = 1.7e9 + rec.t
    write_measurements(tmp_path / "m.csv", t, rec.z)
    write_truth(tmp_path / "truth.csv", t, rec.truth)
    np.testing.assert_allclose(read_measurements(tmp_path / "m.csv").t, t, rtol=0, atol=5e-7)
    np.testing.assert_allclose(read_state_table(tmp_path / "truth.csv").t, t, rtol=0, atol=5e-7)


def test_an_estimate_series_that_does_not_fit_is_refused(tmp_path) -> None:
    """A series whose status is short (the writer's zip cut the file to it), or whose
    times do not increase or statuses are unknown (the readers refuse such a file): a
    UserError, nothing written."""
    import dataclasses

    import numpy as np
    import pytest

    from continuum_mhe import make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_state_table, write_estimates

    rec = simulate("paper3d", duration=5.0)
    s = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    with pytest.raises(UserError, match=r"status has shape \(30,\), expected \(101,\)"):
        dataclasses.replace(s, status=s.status[:30])
    with pytest.raises(UserError, match=r"solve_ms has shape"):
        dataclasses.replace(s, solve_ms=s.solve_ms[:, None])
    out = tmp_path / "e.csv"
    glued = dataclasses.replace(s, t=np.concatenate([s.t[:50], s.t[:51]]))
    with pytest.raises(UserError, match="strictly increasing"):
        write_estimates(out, glued)
    with pytest.raises(UserError, match="status 'fine' is not one of"):  # refused when made
        dataclasses.replace(s, status=np.array(["fine"] * len(s.t)))
    assert not out.exists()
    write_estimates(out, s)
    assert len(read_state_table(out).t) == len(s.t)


def test_small_library_mistakes_are_user_errors() -> None:
    """A DataFrame whose columns are the readings in another order (numpy would drop the
    labels: every row ok, far off), or not the readings' names, a time beyond a float,
    float block starts, and a truth without rows to match: a UserError each, or nothing
    matched."""
    import numpy as np
    import pandas as pd
    import pytest

    from continuum_mhe import Measurement, make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.evaluation.metrics import match_rows

    rec = simulate("paper3d", duration=5.0)
    f = make_formulation("bend")
    est = make_estimator("ekf", f)
    table = pd.DataFrame(rec.z, columns=list(f.measurement_names))
    np.testing.assert_array_equal(est.run(rec.t, table).output, est.run(rec.t, rec.z).output)
    with pytest.raises(UserError, match="z's columns are pitch, roll"):
        est.run(rec.t, table[["pitch", "roll"]])
    # other names (one that says degrees), or another count: the formulation's names
    for bad in (["roll_deg", "pitch_deg"], ["roll", "pitch", "yaw"]):
        with pytest.raises(
            UserError, match=r"reads 2 readings a sample, roll, pitch: name them so"
        ):
            est.run(
                rec.t, pd.DataFrame(np.column_stack([rec.z, rec.z])[:, : len(bad)], columns=bad)
            )
    with pytest.raises(UserError, match=r"the measurement's labels are roll; .*: name them so"):
        est.step(Measurement(0.0, rec.z[0], labels=("roll",)))
    # raw IMU columns given to the model of raw IMUs: raw_measurements converts them
    direct = make_estimator("ekf", make_formulation("direct"))
    raw = pd.DataFrame(np.zeros((3, 6)), columns=["ax", "ay", "az", "gx", "gy", "gz"])
    with pytest.raises(UserError, match=r"are ax, ay, az, gx, gy, gz; .*inputs\.raw_measurements"):
        direct.run(np.arange(3) * 0.02, raw)
    # pandas' missing value in a nullable column is a dropout, as NaN is
    nullable = table.astype("Float64")
    nullable.iloc[3, 0] = pd.NA
    est.reset()
    assert list(est.run(rec.t, nullable).status[2:5]) == ["ok", "dropout", "ok"]
    missing = pd.Series([pd.NA, rec.z[0, 1]], index=["roll", "pitch"], dtype="Float64")
    assert np.isnan(Measurement(0.0, missing).z[0])  # step() takes it as run() does
    # a labelled Series to step(): the same check (its labels not dropped: no swap)
    est.reset()
    row = pd.Series({"pitch": rec.z[0, 1], "roll": rec.z[0, 0]})
    with pytest.raises(UserError, match="the measurement's labels are pitch, roll"):
        est.step(Measurement(0.0, row))
    first = est.step(Measurement(0.0, row[["roll", "pitch"]]))  # a start, unconfirmed
    assert first.status == "uncertain" and np.all(np.isfinite(first.output))
    est.reset()
    with pytest.raises(UserError, match="a number a float can hold"):
        Measurement(10**400, rec.z[0])
    est.reset()
    with pytest.raises(UserError, match="the blocks must cover"):
        est.continue_run(rec.t, rec.z, starts=[0.0, 50.0], block=50)
    i_est, i_truth = match_rows(rec.t, np.empty(0))
    assert len(i_est) == len(i_truth) == 0


def test_times_that_are_not_seconds_are_user_errors() -> None:
    """numpy datetimes for ``t`` (``run`` read them as nanoseconds, every row reset;
    ``step`` refuses them), and a recording whose median step is below 10 us (no IMU
    stream is that fast: a unit): a UserError each, in every estimator."""
    import numpy as np
    import pytest

    from continuum_mhe import make_estimator, make_formulation, simulate
    from continuum_mhe.errors import UserError

    rec = simulate("paper3d", duration=5.0)
    stamps = np.datetime64("2026-01-01") + (rec.t * 1e9).astype("timedelta64[ns]")
    for method in ("mhe", "ekf", "ukf"):
        est = make_estimator(method, make_formulation("bend"))
        with pytest.raises(UserError, match="numpy datetime or timedelta"):
            est.run(stamps, rec.z)
        for scale in (1e-200, 1e-6):  # 5e-202 and 5e-8 s a sample
            warned = r"^run: t advances by a median of .* s per sample .*; t must be in seconds$"
            with (
                pytest.warns(UserWarning, match=warned),
                pytest.raises(UserError, match="must be in seconds"),
            ):
                est.run(rec.t * scale, rec.z)


def test_step_and_continue_run_refuse_the_times_run_refuses() -> None:
    """Times 50 ns apart (``t`` in a unit far below seconds), which ``run`` refuses, are
    refused by ``continue_run`` and by ``step`` from the sample that ends the first
    ``TOO_FAST_STEPS`` (100) steps, each with run's message naming the method, and
    again at every later sample until ``reset()``; times in seconds step on, and so do
    times in seconds whose first rows are a burst 3 us apart (a serial buffer stamped
    as it is read), which ``run`` estimates too."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.estimators.reading_units import ReadingUnitsError

    rec = simulate("paper3d", duration=6.0)
    t = rec.t * 1e-6  # 5e-8 s a sample
    said = (
        "t advances by a median of 5e-08 s per sample (2e+07 samples per second): "
        "t must be in seconds"
    )
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(ReadingUnitsError, match=re.escape(f"run: {said}")):
        est.run(t, rec.z)
    est.reset()
    with pytest.raises(ReadingUnitsError, match=re.escape(f"continue_run: {said}")):
        est.continue_run(t, rec.z)
    with pytest.raises(ReadingUnitsError, match=re.escape(f"continue_run: {said}")):
        est.step(Measurement(t[0], rec.z[0]))  # again, until a reset
    est.reset()
    for i in range(100):
        assert est.step(Measurement(t[i], rec.z[i])).t == t[i]
    for i in (100, 101):
        with pytest.raises(ReadingUnitsError, match=re.escape(f"step: {said}")):
            est.step(Measurement(t[i], rec.z[i]))
    est.reset()
    assert est.step(Measurement(rec.t[0], rec.z[0])).t == rec.t[0]
    assert len(est.continue_run(rec.t[1:], rec.z[1:]).status) == len(rec.t) - 1
    burst = rec.t.copy()
    burst[1:4] = burst[0] + 3e-6 * np.arange(1, 4)  # rows 2 to 4: 3 us apart
    for how in ("step", "continue_run", "run"):
        est.reset()
        if how == "step":
            statuses = [est.step(Measurement(ti, zi)).status for ti, zi in zip(burst, rec.z)]
        else:
            statuses = list(getattr(est, how)(burst, rec.z).status)
        assert len(statuses) == len(burst), how  # every sample estimated, none refused


@pytest.mark.parametrize("how", ["step", "continue_run"])
def test_a_refused_first_time_that_is_not_finite_leaves_the_too_fast_check_on(how: str) -> None:
    """A garbled first line (t NaN), refused, then times in microseconds read as seconds:
    the check of times far too fast still refuses them from the sample that ends the
    first ``TOO_FAST_STEPS`` steps (a NaN kept in the check's times would compare false
    with every later one, and the check would never fill)."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate
    from continuum_mhe.estimators.reading_units import ReadingUnitsError

    rec = simulate("paper3d", duration=6.0)
    t = rec.t * 1e-6
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(SampleTimeError, match="must be finite"):
        est.step(Measurement(float("nan"), rec.z[0]))
    with pytest.raises(ReadingUnitsError, match="t must be in seconds"):
        if how == "step":
            for ti, zi in zip(t, rec.z):
                est.step(Measurement(ti, zi))
        else:
            est.continue_run(t, rec.z)


def test_a_sample_refused_after_one_stamped_far_ahead_says_that_time_is_the_cause() -> None:
    """One sample stamped 40,000 s ahead (a wrong time) restarts the estimator after the
    gap; every true sample after it is then refused as late, and the refusal names
    both times' cases: reset() where the earlier time was the wrong one."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate

    rec = simulate("paper3d", duration=2.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for i in range(20):
        est.step(Measurement(rec.t[i], rec.z[i]))
    est.step(Measurement(rec.t[20] + 4.0e4, rec.z[20]))
    for i in (21, 22):
        with pytest.raises(SampleTimeError, match=r"before it is 39999\.9 s later: if this "
                           r"sample's time is the wrong one.*until reset\(\)"):  # fmt: skip
            est.step(Measurement(rec.t[i], rec.z[i]))
    est.reset(keep_counts=True)
    assert est.step(Measurement(rec.t[23], rec.z[23])).t == rec.t[23]


def test_a_sample_stamped_far_behind_is_left_out_and_the_next_one_steps() -> None:
    """One sample whose own time is wrong (0 s in a stream at 1.4 s): its refusal says
    it can be left out, and the next true sample steps without a reset."""
    from continuum_mhe import Measurement, SampleTimeError, make_formulation, simulate

    rec = simulate("paper3d", duration=2.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for i in range(30):
        est.step(Measurement(rec.t[i], rec.z[i]))
    with pytest.raises(SampleTimeError, match="leave it out and step on"):
        est.step(Measurement(0.0, rec.z[30]))
    assert est.step(Measurement(rec.t[31], rec.z[31])).t == rec.t[31]


def test_write_measurements_refuses_what_read_measurements_would(tmp_path) -> None:
    """An infinite reading (written empty: read back as a dropout), names given as one
    string (its letters became the columns) and no samples (a header alone): each a
    UserError, nothing written."""
    import numpy as np
    import pytest

    from continuum_mhe.errors import UserError
    from continuum_mhe.io import write_measurements

    out = tmp_path / "m.csv"
    t, z = np.array([0.0, 0.05]), np.array([[0.1, 0.2], [np.inf, 0.2]])
    for args, needle in (
        ((t, z), "row 2: roll is infinite"),
        ((t, np.zeros((2, 2)), "rp"), "names must be a sequence"),
        ((np.zeros(0), np.zeros((0, 2))), "no samples to write"),
    ):
        with pytest.raises(UserError, match=needle):
            write_measurements(out, *args)
        assert not out.exists()


def test_the_writers_refuse_times_their_readers_would_not_read_back(tmp_path, capsys) -> None:
    """Times written as one (1e15 + 0.25 k in ten significant digits: each ``1e+15``;
    1000.25 and 1000.2500001 s, to the microsecond: both ``1000.25``), which
    ``read_state_table`` refused as a time that does not increase, are refused by
    ``write_estimates``, ``write_truth``, ``write_measurements`` and the block writer
    that ``estimate`` uses (across two blocks too), naming the file and the row, and
    nothing is written; times of 0 and 1e300 s, and 1e14 + 0.25 k s, read back exactly."""
    from dataclasses import replace

    from continuum_mhe import make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_state_table, write_measurements, write_truth
    from continuum_mhe.io.estimate_csv import estimate_lines, write_estimates

    rec = simulate("paper3d", duration=0.25)
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    n = len(rec.t)
    out = tmp_path / "e.csv"
    big = 1e15 + 0.25 * np.arange(n)
    hair = 1000.0 + rec.t
    hair[3] = hair[2] + 1e-7  # 1000.1000001 s, written 1000.1
    for t, said in (
        (big, "row 2: t = 1000000000000000.2 s is written 1e+15, not after the row before's 1e+15"),
        (hair, "row 4: t = 1000.1000001 s is written 1000.1, not after the row before's 1000.1"),
    ):
        for write, args in (
            (write_estimates, (replace(series, t=t),)),
            (write_truth, (t, rec.truth, rec.outputs)),
            (write_measurements, (t, rec.z, rec.measurement_names)),
            (estimate_lines, (t, series.output, series.std, None, series.status, series.solve_ms)),
        ):
            with pytest.raises(UserError, match=re.escape(f"{out}: {said}")):
                write(out, *args)  # type: ignore[operator]
            assert not out.exists()
    with pytest.raises(UserError, match=re.escape(f"{out}: row 1: t = 1000.1000001 s is written")):
        estimate_lines(  # the block after one that ended at 1000.1 s
            out, hair[3:], series.output[3:], series.std[3:], None, list(series.status[3:]),
            series.solve_ms[3:], after=hair[2],
        )  # fmt: skip
    for t in (np.array([0.0, 1e300]), 1e14 + 0.25 * np.arange(n)):
        write_estimates(out, replace(series.rows(slice(0, len(t))), t=t))
        assert read_state_table(out).t.tolist() == t.tolist()
    # estimate's blocks (1,024 rows each): the row named is the file's, not the block's
    long = simulate("paper3d", duration=150.0)
    t = 1000.0 + long.t
    t[2500] = t[2499] + 1e-7  # data row 2501, 0.1 us after the row before
    meas = tmp_path / "long.csv"
    rows = np.column_stack([t, long.z])
    header = ",".join(["t", *long.measurement_names])
    np.savetxt(meas, rows, delimiter=",", header=header, comments="", fmt="%.10f")
    from continuum_mhe.cli import main

    out = tmp_path / "long_est.csv"
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(out)]) == 2
    assert f"{out}: row 2501: t = 1124.9500001 s is written 1124.95" in capsys.readouterr().err
    assert not out.exists()


def test_benchmark_and_check_robot_sizes_that_cannot_work_are_refused(capsys) -> None:
    """A horizon given twice mixed the two runs' ratios; check-robot --samples 1,000,000
    needed about 13 GB (an internal error under a memory limit): one line each."""
    import pytest

    from continuum_mhe.cli import main

    with pytest.raises(SystemExit) as info:  # argparse's own refusal of an option value
        main(["benchmark", "--horizons", "10,10", "--duration", "1"])
    assert info.value.code == 2
    assert "horizons must differ" in capsys.readouterr().err
    assert main(["check-robot", "two-section", "--samples", "1000000"]) == 2
    assert "--samples" in capsys.readouterr().err


def test_benchmark_with_a_robot_refuses_options_it_would_not_use(capsys) -> None:
    """--robot times the fast MHE against IPOPT alone: --skip, --loss-horizons, --acados
    and --memory-samples are refused with it, not run without effect, exit 0."""
    from continuum_mhe.cli import main

    for extra in (["--skip", "fatrop"], ["--loss-horizons", "10"], ["--acados", "/none"],
                  ["--memory-samples", "5"]):  # fmt: skip
        argv = ["benchmark", "--robot", "two-section", "--horizons", "10", "--duration", "1"]
        assert main([*argv, *extra]) == 2
        assert f"{extra[0]} does not apply with --robot" in capsys.readouterr().err


def test_benchmark_with_a_robot_takes_the_skip_values_of_what_it_leaves_out(
    capsys, tmp_path
) -> None:
    """``--loss-horizons none`` and ``--memory-samples 0`` (the help's "skip") ask for
    what --robot leaves out anyway: no refusal, the robot's benchmark runs."""
    from continuum_mhe.cli import main

    out = tmp_path / "b.json"
    argv = ["benchmark", "--robot", "two-section", "--horizons", "5", "--duration", "0.5",
            "--repeats", "1", "--loss-horizons", "none", "--memory-samples", "0",
            "--json", str(out)]  # fmt: skip
    assert main(argv) == 0, capsys.readouterr().err
    assert "does not apply" not in capsys.readouterr().err and out.exists()


@pytest.mark.parametrize(
    ("flag", "value", "why"),
    [
        ("--reading-bias-deg", "0", "misalignments and accelerometer biases are states"),
        ("--model-error-floor-deg", "2", "not a constant-curvature one"),
        ("--accel-psd", "50", "the base curvature's, the tip force's and the tensions' own"),
    ],
)
def test_a_noise_option_a_tendon_robot_ignores_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, value: str, why: str
) -> None:
    """A tendon robot's model carries its IMUs' constant errors as states, assumes no
    constant-curvature model error and has a process noise of its own: each option would
    change nothing there, so it is refused in one line naming it, and nothing is written;
    a constant-curvature robot takes it."""
    from importlib.resources import files

    tendon = files("continuum_mhe") / "data" / "tendon"
    out = tmp_path / "e.csv"
    argv = ["estimate", str(tendon / "unloaded_raw.csv"), "--robot", "tendon-two-section",
            "--inputs", str(tendon / "unloaded_tensions.csv"), "-o", str(out)]  # fmt: skip
    assert main([*argv, flag, value]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{flag} does not apply to this robot's model" in err
    assert why in err and not out.exists()
    # from an options file: named by its file and line
    cfg = tmp_path / "opts.toml"
    cfg.write_text(f"# a profile\n{flag.lstrip('-').replace('-', '_')} = {value}\n")
    assert main([*argv, "--config", str(cfg)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and f"{cfg}: line 2" in err and "does not apply" in err
    assert not out.exists()
    rod = files("continuum_mhe") / "data" / "rod2" / "planar-s_raw.csv"
    argv = ["estimate", str(rod), "--robot", "two-section", "--method", "ekf", "-o", str(out)]
    assert main([*argv, flag, value]) == 0 and out.exists()


@pytest.mark.parametrize(
    ("options", "why"),
    [
        (["--formulation", "paper"], "the paper's W = w I"),
        (["--imu-model", "direct", "--own-acceleration"], "white jerk"),
    ],
)
def test_accel_psd_where_the_model_does_not_take_it_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str], why: str
) -> None:
    """--accel-psd sets the bends' white-noise acceleration: the paper's model (W = w I)
    and the direct model with the IMUs' own acceleration (white jerk) do not take it, so
    it is refused in one line there, nothing written; at its default it passes."""
    from importlib.resources import files

    paper = tmp_path / "p.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(paper)]) == 0
    raw = files("continuum_mhe") / "data" / "rod2" / "planar-s_raw.csv"
    source = [str(paper)] if "paper" in options else [str(raw), "--robot", "two-section"]
    out = tmp_path / "e.csv"
    argv = ["estimate", *source, *options, "--method", "ekf", "-o", str(out)]
    capsys.readouterr()
    assert main([*argv, "--accel-psd", "2"]) == 2
    err = capsys.readouterr().err.strip()
    model = "the paper model" if "paper" in options else "this robot's model"
    assert "\n" not in err and f"--accel-psd does not apply to {model}" in err
    assert why in err and not out.exists()
    assert main([*argv, "--accel-psd", "0.5"]) == 0 and out.exists()


def test_demo_of_a_tendon_robot_names_the_robot_and_its_help_offers_none(tmp_path, capsys) -> None:
    """``demo`` and ``simulate`` take constant-curvature robots: a tendon robot is refused
    in one line that starts with the robot, as ``simulate``'s does, nothing is written,
    and their ``--robot`` help lists only the shipped constant-curvature robots."""
    from continuum_mhe.io.robot_file import read_robot, shipped_robots

    out = tmp_path / "demo"
    assert main(["demo", "--robot", "tendon-two-section", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("continuum-mhe: error: tendon-two-section: a tendon")
    assert not out.exists()
    cc = shipped_robots(tendons=False)
    assert "two-section" in cc and "tendon-two-section" not in cc
    assert all(not read_robot(p).tendons for p in cc.values())
    assert any(read_robot(p).tendons for p in shipped_robots().values())
    for command in ("demo", "simulate"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        help_text = " ".join(capsys.readouterr().out.split())
        assert "constant-curvature robot file" in help_text
        assert "tendon-two-section" not in help_text


def test_demo_refuses_an_out_folder_in_a_missing_folder(tmp_path, capsys) -> None:
    """As every command that writes a file refuses a missing folder (a mistyped path),
    ``demo --out`` makes its own folder but not the folders above it."""
    out = tmp_path / "nodir" / "demo"
    assert main(["demo", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"continuum-mhe: error: {out}: folder {out.parent} does not exist"]
    assert not out.parent.exists()


def test_an_output_under_a_file_says_the_file_is_not_a_folder(tmp_path, capsys) -> None:
    """``-o FILE/o.csv`` where FILE is a file: said as a file, not a folder (not that
    the folder does not exist, which it does, as a file); for a folder output too."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    capsys.readouterr()
    for argv, target in (
        (["estimate", str(meas), "-o", str(meas / "e.csv")], meas / "e.csv"),
        (["demo", "--out", str(meas / "demo")], meas / "demo"),
    ):
        assert main(argv) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line == f"continuum-mhe: error: {target}: {meas} is not a folder", line


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


def test_an_options_file_that_is_not_toml_names_its_line(tmp_path, capsys) -> None:
    config = tmp_path / "opts.toml"
    config.write_text('method = "ekf"\nhorizon = \n')
    rec = simulate("paper3d", duration=1.0, seed=0)
    m = tmp_path / "m.csv"
    write_table(m, ["t", "roll", "pitch"], np.column_stack([rec.t, rec.z]))
    out = tmp_path / "e.csv"
    assert main(["estimate", str(m), "--config", str(config), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"continuum-mhe: error: {config}: line 2: not valid TOML: Invalid value (column 11)"
    ]
    assert not out.exists()


def test_an_options_line_of_a_csv_that_is_not_toml_names_its_line_and_column(
    tmp_path, capsys
) -> None:
    """An estimate CSV's recorded options line given to ``--config``: the line and the
    column are the file's (after its ``# ``)."""
    rec = simulate("paper3d", duration=1.0, seed=0)
    m = tmp_path / "m.csv"
    write_table(m, ["t", "roll", "pitch"], np.column_stack([rec.t, rec.z]))
    config = tmp_path / "est.csv"
    config.write_text("# continuum-mhe 0.1.0\n# options = {method = }\nt,x\n")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(m), "--config", str(config), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    line = "# options = {method = }"
    assert err == [
        f"continuum-mhe: error: {config}: line 2: not valid TOML: Invalid value "
        f"(column {line.index('}') + 1})"
    ]


def test_plot_of_a_results_folder_refuses_an_out_folder_in_a_missing_folder(
    tmp_path, capsys
) -> None:
    out = tmp_path / "nodir" / "figures"
    assert main(["plot", str(tmp_path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist" in err[0]
    assert not out.parent.exists()


def test_a_state_tables_columns_by_name_and_the_reader_of_several_sections(tmp_path) -> None:
    """``StateTable.column`` and ``std_column`` read by name, an unknown one a KeyError
    listing the table's; ``read_states`` (one section) points a several-section file to
    ``read_state_table``."""
    from continuum_mhe.io import read_states, write_estimates
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("bend", robot)
    rec = simulate_robot("spatial", robot, duration=1.0, seed=0)
    series = make_estimator("ekf", f).run(rec.t, rec.z)
    path = tmp_path / "two.csv"
    write_estimates(path, series)
    table = read_state_table(path)
    np.testing.assert_allclose(table.column("theta_2"), series.column("theta_2"), rtol=1e-9)
    np.testing.assert_allclose(table.std_column("theta_2"), series.std_column("theta_2"), rtol=1e-9)
    with pytest.raises(KeyError, match="no column 'std_theta_2' .*theta_2"):
        table.column("std_theta_2")
    with pytest.raises(InputError, match="several sections .* read_state_table"):
        read_states(path)


def test_a_first_sample_without_a_finite_time_says_so() -> None:
    from continuum_mhe.errors import SampleTimeError

    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(SampleTimeError, match=r"t=nan s must be finite$"):
        est.step(Measurement(math.nan, np.zeros(2)))


def _scaled_truth(t: Path, out: Path, columns: tuple[str, ...], factor: float) -> Path:
    """The truth ``t`` with ``columns`` multiplied by ``factor``, as ``out``."""
    lines = t.read_text().splitlines()
    header = lines[0].split(",")
    at = [header.index(c) for c in columns]
    rows = []
    for line in lines[1:]:
        v = line.split(",")
        for i in at:
            v[i] = repr(float(v[i]) * factor)
        rows.append(",".join(v))
    out.write_text(lines[0] + "\n" + "\n".join(rows) + "\n")
    return out


def test_bend_angles_in_degrees_are_refused_on_their_line(tmp_path, capsys) -> None:
    """A truth whose theta is in degrees (read as rad, a theta RMSE of thousands of degrees):
    one line naming the file, the first row beyond 2 pi and its value, exit 2."""
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    degrees = _scaled_truth(t, tmp_path / "deg.csv", ("theta",), math.degrees(1.0))
    theta = read_state_table(t).column("theta")
    first = int(np.argmax(np.degrees(theta) > 2 * math.pi))
    capsys.readouterr()
    assert main(["evaluate", str(est), str(degrees)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert err.startswith(f"continuum-mhe: error: {degrees}: line {first + 2}: theta=")
    assert "beyond 2 pi: degrees? angles are in rad" in err


def test_plot_refuses_a_truth_in_mm_without_the_robot(tmp_path, capsys) -> None:
    """``plot --truth`` in mm, no --robot: the truth's tip 1000 times as far from the
    base as the estimate's, one line, nothing drawn; the same truth in m is drawn."""
    from continuum_mhe.io.position_units import position_unit_against

    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    mm = _scaled_truth(t, tmp_path / "mm.csv", ("x", "y", "z"), 1000.0)
    figure = tmp_path / "p.png"
    capsys.readouterr()
    assert main(["plot", str(est), "--truth", str(mm), "-o", str(figure)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {mm}: its tip is ")
    assert "times as far from the base as the estimate's: positions in mm?" in err
    assert not figure.exists()
    truth, e = read_state_table(t), read_state_table(est)
    assert position_unit_against(truth.names, truth.values, e.names, e.values) == ""
    cm = read_state_table(_scaled_truth(t, tmp_path / "cm.csv", ("x", "y", "z"), 100.0))
    assert "positions in cm?" in position_unit_against(cm.names, cm.values, e.names, e.values)
    assert main(["plot", str(est), "--truth", str(t), "-o", str(figure)]) == 0


def test_a_tip_truth_in_cm_is_refused_naming_it(tmp_path, capsys) -> None:
    """Tip positions alone in cm (a motion capture's): 100 times the robot's reach is a
    shape of no unit but cm, so only the estimate tells. ``evaluate`` and ``plot
    --robot`` refuse it in one line naming the truth (not the estimate, and not drawn as
    another robot's truth)."""
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    truth = read_state_table(t)
    cm = tmp_path / "tip_cm.csv"
    write_table(cm, ["t", "x", "y", "z"],
                np.column_stack([truth.t, *(100 * truth.column(c) for c in "xyz")]))  # fmt: skip
    robot = tmp_path / "r.toml"
    robot.write_text("[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n")
    figure = tmp_path / "p.png"
    capsys.readouterr()
    for argv in (
        ["evaluate", str(est), str(cm)],
        ["plot", str(est), "--truth", str(cm), "--robot", str(robot), "-o", str(figure)],
    ):
        assert main(argv) == 2
        (line,) = capsys.readouterr().err.strip().splitlines()[-1:]
        assert line.startswith(f"continuum-mhe: error: {cm}: its tip is "), line
        assert line.endswith("positions in cm? give x, y, z in m"), line
    assert not figure.exists()


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


def test_evaluate_refuses_the_same_file_as_estimate_and_truth(tmp_path, capsys) -> None:
    """``evaluate truth.csv truth.csv`` (or the same file spelt another way) would score
    0 mm: refused."""
    _, t = _simulated(tmp_path, "a")
    capsys.readouterr()
    assert main(["evaluate", str(t), str(tmp_path / "." / t.name)]) == 2
    assert "the truth is the estimate file itself" in capsys.readouterr().err


def test_a_broken_options_line_is_said_with_its_line(tmp_path, capsys) -> None:
    """An estimate whose ``# options`` line is cut: ``evaluate`` warns that the options
    it records are not read (it takes the defaults' robot), and ``--config`` of it names
    the line."""
    m, t = _simulated(tmp_path, "a")
    est = tmp_path / "e.csv"
    assert main(["estimate", str(m), "-o", str(est), "--method", "ekf"]) == 0
    lines = est.read_text().splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("# options = {"))
    lines[at] = lines[at][:40]
    broken = tmp_path / "broken.csv"
    broken.write_text("\n".join(lines) + "\n")
    capsys.readouterr()
    assert main(["evaluate", str(broken), str(t)]) == 0
    err = capsys.readouterr().err
    assert f"warning: {broken}: line {at + 1}: not valid TOML" in err
    assert "the options the estimate was made with (its robot file among them) are not read" in err
    assert main(["estimate", str(m), "--config", str(broken), "-o", str(tmp_path / "o.csv")]) == 2
    assert f"error: {broken}: line {at + 1}: not valid TOML" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("line", "said"),
    [
        ('mount-rpy = "1,2"', "line 1: mount-rpy = '1,2': --mount-rpy must be three angles"),
        ("horizon = 30.5", "line 1: horizon = 30.5: expected a whole number"),
        ("robot = 5", "line 1: robot = 5: 5: no such robot file"),
    ],
)
def test_an_options_files_value_refused_later_names_its_line(
    tmp_path, capsys, line: str, said: str
) -> None:
    """A value the options file sets and a later check refuses (the mounting's three
    angles, the robot file) names the file's line, as a value the parser refuses does;
    a whole number is asked for as on the command line, not in Python's words."""
    m, _ = _simulated(tmp_path, "a")
    raw = tmp_path / "raw.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "--imu", "raw", "-o", str(raw)]) == 0
    config = tmp_path / "c.toml"
    config.write_text(line + "\n")
    capsys.readouterr()
    source = raw if "mount" in line else m
    assert (
        main(["estimate", str(source), "--config", str(config), "-o", str(tmp_path / "o.csv")]) == 2
    )
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {config}: {said}"), err


def test_an_options_files_line_is_not_given_to_another_options_error(tmp_path, capsys) -> None:
    """``loss = "huber"`` in the options file and a bad ``--loss-scale`` on the command
    line: the error is the command line's, without the file's ``loss`` line (a flag that
    begins like another is not that one); a robot file named there whose content is
    wrong is its own error, not the options file's."""
    m, _ = _simulated(tmp_path, "a")
    config = tmp_path / "c.toml"
    config.write_text('loss = "huber"\n')
    out = tmp_path / "o.csv"
    capsys.readouterr()
    argv = ["estimate", str(m), "--config", str(config), "--loss-scale", "-1", "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("continuum-mhe: error: --loss-scale") and str(config) not in err
    robot = tmp_path / "s.toml"
    robot.write_text("[section]\nlength = 0.2\n")
    config.write_text(f"robot = {str(robot)!r}\n")
    assert main(["estimate", str(m), "--config", str(config), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"continuum-mhe: error: {robot}: line 1: 'section' must be"), err


def test_estimate_of_another_kind_of_file_says_which_kind(tmp_path, capsys) -> None:
    """An estimate, a truth or a robot file given to ``estimate`` as the recording: one
    line that says what the file is, exit 2, nothing written."""
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
        (truth, "an estimate or truth table, not IMU readings"),
        (est, "an estimate or truth table, not IMU readings"),
        (robot, "a robot file? it is given with --robot ROBOT.toml"),
    ):
        capsys.readouterr()
        assert main(["estimate", str(given), "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and says in err[0], err
        assert not out.exists()


def test_a_multi_section_scenario_on_one_section_names_the_ones_it_takes(tmp_path, capsys) -> None:
    """``simulate spatial`` without ``--robot``: one line that names ``--robot`` and the
    scenarios a one-section robot takes, exit 2, nothing written."""
    out = tmp_path / "m.csv"
    assert main(["simulate", "spatial", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is for a robot of two or more sections (--robot)" in err[0], err
    assert "choose from paper3d, planar-overbend, rest, straight" in err[0]
    assert not out.exists()


def test_one_section_with_imus_along_it_simulates_the_one_section_scenarios(tmp_path) -> None:
    """A robot of one section with an IMU at its middle and one at its tip takes the
    one-section scenarios (each scenario sent it to the others' list), every IMU reading
    the section's bend as the model reads it (noise 0: to rounding); a two-section
    scenario names those it takes."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.3),), (ImuPlacement(0, 0.5), ImuPlacement(0, 1.0)))
    rec = simulate_robot("paper3d", robot, duration=2.0, noise_deg=0.0)
    f = BendFormulation(robot=robot)
    theta, phi = rec.truth[:, 3], rec.truth[:, 4]
    x = np.column_stack([theta * np.cos(phi), theta * np.sin(phi), np.zeros((len(theta), 2))])
    model = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    np.testing.assert_allclose(rec.z, model, rtol=0, atol=1e-12)
    assert rec.z.shape == (len(rec.t), 4) and np.ptp(rec.z[:, 0]) > 0.1
    with pytest.raises(UserError, match="for a robot of two or more sections.*choose from paper3d"):
        simulate_robot("spatial", robot)
    robot_file = tmp_path / "long.toml"
    robot_file.write_text(
        "[[section]]\nlength = 0.3\n[[imu]]\nsection = 1\nat = 0.5\n[[imu]]\nsection = 1\n"
    )
    out = tmp_path / "m.csv"
    argv = ["simulate", "planar-overbend", "--robot", str(robot_file), "-o", str(out)]
    assert main([*argv, "--duration", "1"]) == 0
    assert out.read_text().startswith("t,roll_1,pitch_1,roll_2,pitch_2\n")


@pytest.fixture(scope="module")
def paper3d_pair(tmp_path_factory) -> dict[str, Path]:
    """A paper3d EKF estimate (6 s), its truth, and three mistaken copies: the estimate's
    positions in mm, the truth on a clock 0.5 s late, and the truth with t in ms."""
    tmp = tmp_path_factory.mktemp("pair")
    paths = {k: tmp / f"{k}.csv" for k in ("m", "t", "e", "e_mm", "t_late", "t_ms")}
    assert main(["simulate", "paper3d", "--duration", "6", "-o", str(paths["m"]),
                 "--truth", str(paths["t"])]) == 0  # fmt: skip
    assert main(["estimate", str(paths["m"]), "-o", str(paths["e"]), "--method", "ekf"]) == 0

    def rewrite(src: Path, dst: Path, change) -> None:
        lines = src.read_text().splitlines()
        body = [ln for ln in lines if not ln.startswith("#")]
        header = body[0].split(",")
        out = [ln for ln in lines if ln.startswith("#")] + [body[0]]
        for ln in body[1:]:
            fields = ln.split(",")
            out.append(",".join(change(header, fields)))
        dst.write_text("\n".join(out) + "\n")

    def in_mm(header, f):
        return [repr(float(v) * 1e3) if h in ("x", "y", "z") and v else v
                for h, v in zip(header, f)]  # fmt: skip

    rewrite(paths["e"], paths["e_mm"], in_mm)
    rewrite(paths["t"], paths["t_late"], lambda h, f: [repr(float(f[0]) + 0.5), *f[1:]])
    rewrite(paths["t"], paths["t_ms"], lambda h, f: [repr(float(f[0]) * 1e3), *f[1:]])
    return paths


def test_plot_refuses_positions_in_mm_without_a_robot(paper3d_pair, tmp_path, capsys) -> None:
    """plot of an estimate whose positions are in mm drew a 200 m robot without a word
    (evaluate and view refused it): its rows' own sections, beyond any robot's, refuse it."""
    fig = tmp_path / "f.png"
    assert main(["plot", str(paper3d_pair["e_mm"]), "-o", str(fig)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and not fig.exists()
    assert "its rows give sections of 200 m (its positions against its own bend angles)" in err
    assert err.endswith("positions in mm? give x, y, z in m\n")


def test_plot_and_view_warn_of_a_truth_on_an_offset_clock(paper3d_pair, tmp_path, capsys) -> None:
    """A truth 0.5 s late: evaluate, plot and view each say it (plot and view do not draw
    the offset as an error of the estimate without a word), naming the --truth-shift that
    compares them (each command's own)."""
    e, late = str(paper3d_pair["e"]), str(paper3d_pair["t_late"])
    said = "the truth fits the estimate best +0.5 s later"
    assert main(["evaluate", e, late]) == 0
    assert said in capsys.readouterr().err
    assert main(["plot", e, "--truth", late, "-o", str(tmp_path / "f.png")]) == 0
    err = capsys.readouterr().err
    assert said in err and "; --truth-shift 0.5 compares them so" in err
    pytest.importorskip("rerun")
    assert main(["view", e, "--truth", late, "--save", str(tmp_path / "v.rrd")]) == 0
    err = capsys.readouterr().err
    assert said in err and "; --truth-shift 0.5 compares them so" in err


def _truth_with_gaps(src: Path, dst: Path, rows: range, columns: set[str] | None) -> None:
    """``src``'s truth with the ``columns`` (None: every one but ``t``) of data rows
    ``rows`` (0-based) empty: a motion capture's lost marker."""
    header, *body = src.read_text().splitlines()
    names = header.split(",")
    out = [header]
    for i, line in enumerate(body):
        f = line.split(",")
        if i in rows:
            f = [v if c == "t" or (columns and c not in columns) else "" for c, v in zip(names, f)]
        out.append(",".join(f))
    dst.write_text("\n".join(out) + "\n")


def test_plot_view_and_evaluate_read_a_truth_with_gaps(paper3d_pair, tmp_path, capsys) -> None:
    """A truth with lost markers (empty cells): evaluate compares the other rows, and plot
    and view take the file too (not refused naming the line). A column empty in every
    row (an angle the capture does not give) is left out (not every row without a finite
    truth, none compared and the coverage nan, nor a traceback in view). A truth without
    any tip value is refused in one line."""
    e, t = paper3d_pair["e"], paper3d_pair["t"]
    gaps, theta, empty = tmp_path / "gaps.csv", tmp_path / "theta.csv", tmp_path / "none.csv"
    _truth_with_gaps(t, gaps, range(40, 50), None)
    _truth_with_gaps(t, theta, range(0, 10**6), {"theta"})
    _truth_with_gaps(t, empty, range(0, 10**6), None)
    n = len(t.read_text().splitlines()) - 1
    assert main(["evaluate", str(e), str(gaps)]) == 0
    assert "without a finite truth)" in capsys.readouterr().out
    assert main(["plot", str(e), "--truth", str(gaps), "-o", str(tmp_path / "f.png")]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(e), str(theta)]) == 0
    out = capsys.readouterr().out
    assert f"samples compared     {n} (0 without estimate)" in out, out
    assert "RMSE theta" not in out and "nan" not in out and "phi 1.000" in out, out
    refused = f"continuum-mhe: error: {empty}: no row has a value in each of x, y, z "
    figure = str(tmp_path / "g.png")
    for argv in (
        ["evaluate", str(e), str(empty)],
        ["plot", str(e), "--truth", str(empty), "-o", figure],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err == refused + "(every row a gap)\n", err
    assert not (tmp_path / "g.png").exists()
    # a truth in mm with an empty angle column: refused by each, naming the truth (its
    # empty angles would say nothing, and view would draw it 1000 times too large)
    header, *rows = t.read_text().splitlines()
    names = header.split(",")
    in_mm = tmp_path / "mm.csv"
    in_mm.write_text("\n".join([header, *(
        ",".join(repr(float(v) * 1e3) if c in "xyz" else "" if c == "theta" else v
                 for c, v in zip(names, r.split(",")))
        for r in rows)]) + "\n")  # fmt: skip
    rrd, png = str(tmp_path / "mm.rrd"), str(tmp_path / "mm.png")
    for argv in (["evaluate", str(e), str(in_mm)],
                 ["view", str(e), "--truth", str(in_mm), "--save", rrd],
                 ["plot", str(e), "--truth", str(in_mm), "-o", png]):  # fmt: skip
        if argv[0] == "view" and importlib.util.find_spec("rerun") is None:
            continue
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"continuum-mhe: error: {in_mm}: its tip is ") and "in mm?" in err, (
            err
        )
    # theta and phi empty in alternate rows: no row has both
    alternate = tmp_path / "alternate.csv"
    alternate.write_text("\n".join([header, *(
        ",".join("" if c == ("theta", "phi")[i % 2] else v for c, v in zip(names, r.split(",")))
        for i, r in enumerate(rows))]) + "\n")  # fmt: skip
    assert main(["plot", str(e), "--truth", str(alternate), "-o", str(tmp_path / "a.png")]) == 0
    pytest.importorskip("rerun")
    for truth in (gaps, theta, alternate):
        out_rrd = tmp_path / f"{truth.stem}.rrd"
        assert main(["view", str(e), "--truth", str(truth), "--save", str(out_rrd)]) == 0
        assert out_rrd.stat().st_size > 0
    assert "(tip and section ends only: no theta/phi" in capsys.readouterr().err


def test_view_refuses_a_truth_with_t_in_milliseconds(paper3d_pair, tmp_path, capsys) -> None:
    """view wrote a recording "with truth" of a truth whose t is in ms (evaluate and plot
    refused it): refused in one line, nothing written."""
    pytest.importorskip("rerun")
    out = tmp_path / "v.rrd"
    argv = ["view", str(paper3d_pair["e"]), "--truth", str(paper3d_pair["t_ms"])]
    assert main([*argv, "--save", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{paper3d_pair['t_ms']}: only " in err and not out.exists()


def test_aligned_truth_warns_where_few_rows_are_scored() -> None:
    """The library's scoring path (aligned_truth, then compute_metrics) scored an
    estimate against a truth whose t is in ms on the one row they shared (a tip error of
    0.64 mm) without a word, where evaluate refuses it: a TruthCoverageWarning says how
    few rows are compared; a matching truth says nothing."""
    from continuum_mhe.evaluation.metrics import TruthCoverageWarning, aligned_truth

    rec = simulate("paper3d", duration=4.0)
    names = [o.name for o in rec.outputs]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rows, _, _ = aligned_truth(rec.t, rec.t, rec.truth, names)
    assert len(rows) == len(rec.t)
    with pytest.warns(TruthCoverageWarning, match=r"only 1 of the estimate's 81 rows have a"):
        rows, _, _ = aligned_truth(rec.t, rec.t * 1e3, rec.truth, names)
    assert len(rows) == 1


def test_evaluate_json_carries_what_the_text_says(paper3d_pair, capsys) -> None:
    """evaluate --json carries the warnings the text run says, the truth shift used,
    whether the truth is interpolated and which columns the SRMSE sums, so that a script
    sees a problem a person would."""
    e, late = str(paper3d_pair["e"]), str(paper3d_pair["t_late"])
    assert main(["evaluate", e, late, "--json"]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)
    said = [ln.removeprefix("continuum-mhe: warning: ") for ln in err.splitlines()]
    assert report["warnings"] == said and len(said) == 1 and "+0.5 s later" in said[0]
    assert report["srmse_columns"] == ["x", "y", "z", "theta", "phi"]
    assert (report["truth_shift_s"], report["interpolated"]) == (0.0, False)
    assert main(["evaluate", e, late, "--json", "--truth-shift", "0.5"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["truth_shift_s"] == 0.5 and report["warnings"] == []
    typo = paper3d_pair["t"].with_name("t_typo.csv")
    typo.write_text(paper3d_pair["t"].read_text().replace(",theta,", ",thetaa,", 1))
    assert main(["evaluate", e, str(typo), "--json"]) == 0
    out, err = capsys.readouterr()
    said = [ln.removeprefix("continuum-mhe: warning: ") for ln in err.splitlines()]
    assert json.loads(out)["warnings"] == said and "thetaa" in said[0]


def test_a_full_disk_on_standard_output_says_what_failed(paper3d_pair) -> None:
    """evaluate > /dev/full says what failed ("writing the output"), not 'error: : No
    space left on device'."""
    import subprocess
    import sys

    if not Path("/dev/full").exists():
        pytest.skip("needs /dev/full")
    with open("/dev/full", "w") as full:
        done = subprocess.run(
            [sys.executable, "-m", "continuum_mhe", "evaluate", str(paper3d_pair["e"]),
             str(paper3d_pair["t"])],
            stdout=full, stderr=subprocess.PIPE, text=True, timeout=120,
        )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr == "continuum-mhe: error: writing the output: No space left on device\n"


def test_an_empty_estimate_names_an_estimate_s_header(tmp_path, capsys) -> None:
    """evaluate of an empty estimate file names an estimate's header, not a measurement
    header (t,roll,pitch)."""
    empty = tmp_path / "e.csv"
    empty.write_text("")
    assert main(["evaluate", str(empty), str(empty)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {empty}: line 1: file is empty, expected a header such as "
        "t,x,y,z,theta,phi (an estimate's or a truth's)\n"
    )


def test_evaluate_plot_and_view_refuse_a_truth_of_two_rows_alike(paper3d_pair, tmp_path, capsys):
    """A truth of the estimate's first two rows: evaluate refused it (under 10 % of the
    rows compare), plot and view drew it without a word; all three refuse it in the
    same line."""
    lines = paper3d_pair["t"].read_text().splitlines()
    body = [i for i, ln in enumerate(lines) if not ln.startswith("#")]
    two = tmp_path / "t2.csv"
    two.write_text("\n".join(lines[: body[0] + 3]) + "\n")
    e = str(paper3d_pair["e"])
    said = f"{e}: only 2 of 121 rows have a row at the same t (within 1 us) in {two}"
    assert main(["evaluate", e, str(two)]) == 2
    assert said in capsys.readouterr().err
    assert main(["plot", e, "--truth", str(two), "-o", str(tmp_path / "f.png")]) == 2
    assert said in capsys.readouterr().err
    pytest.importorskip("rerun")
    assert main(["view", e, "--truth", str(two), "--save", str(tmp_path / "v.rrd")]) == 2
    assert said in capsys.readouterr().err


def test_evaluate_warns_of_a_truth_whose_x_and_y_are_swapped(paper3d_pair, tmp_path, capsys):
    """A truth with x and y swapped (scored 129 mm beside a theta RMSE of 1.15 deg) is not
    scored without a word: its tip points far from where its own angles put it, said in
    a warning; the right truth, and the shipped rods' and tendon robots' truths, say
    nothing of it (their median angle is under 3 degrees)."""
    from continuum_mhe.io.position_units import tip_direction_problem
    from continuum_mhe.io.state_tables import read_state_table

    lines = paper3d_pair["t"].read_text().splitlines()
    header = next(ln for ln in lines if not ln.startswith("#")).split(",")
    ix, iy = header.index("x"), header.index("y")
    swapped = tmp_path / "t_xy.csv"
    out = []
    for ln in lines:
        f = ln.split(",")
        if not ln.startswith("#") and f != header:  # the values, not the names
            f[ix], f[iy] = f[iy], f[ix]
        out.append(",".join(f))
    swapped.write_text("\n".join(out) + "\n")
    e = str(paper3d_pair["e"])
    assert main(["evaluate", e, str(swapped)]) == 0
    err = capsys.readouterr().err
    assert f"warning: {swapped}: its tip points " in err and "x and y swapped" in err
    assert main(["evaluate", e, str(paper3d_pair["t"])]) == 0
    assert "tip points" not in capsys.readouterr().err
    assert main(["plot", e, "--truth", str(swapped), "-o", str(tmp_path / "f.png")]) == 0
    assert f"warning: {swapped}: its tip points " in capsys.readouterr().err  # as evaluate
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data"
    for folder, lengths in (("rod2", (0.16, 0.14)), ("tendon", (0.2, 0.2))):
        for path in sorted((data / folder).glob("*_truth.csv")):
            table = read_state_table(path)
            assert tip_direction_problem(table.names, table.values, lengths) == "", path


def test_the_srmse_counts_the_tip_once_on_several_sections() -> None:
    """A two-section table has the tip twice (x, y, z and the second section's end
    x_2, y_2, z_2): a tip 10 mm off in x sums 10 mm into the SRMSE, not 20 mm. One
    section's SRMSE (the paper's) sums all of its columns."""
    from continuum_mhe.evaluation.metrics import srmse_columns

    names = ["x", "y", "z", "theta_1", "phi_1", "x_1", "y_1", "z_1",
             "theta_2", "phi_2", "x_2", "y_2", "z_2"]  # fmt: skip
    truth = np.zeros((20, len(names)))
    truth[:, names.index("z")] = truth[:, names.index("z_2")] = 0.3
    truth[:, names.index("z_1")] = 0.16
    est = truth.copy()
    est[:, names.index("x")] += 0.01
    est[:, names.index("x_2")] += 0.01
    m = compute_metrics(est, truth, 0.3, names)
    assert m.rmse["x"] == pytest.approx(0.01) and m.rmse["x_2"] == pytest.approx(0.01)
    assert m.srmse == pytest.approx(0.01)
    assert "x_2" not in srmse_columns(names) and "x_1" in srmse_columns(names)
    assert srmse_columns(["x", "y", "z", "theta", "phi"]) == ["x", "y", "z", "theta", "phi"]


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


def test_plot_refuses_an_estimate_given_as_the_truth(tmp_path, capsys) -> None:
    """As ``evaluate`` does: an estimate's status and std_ columns in the truth's place."""
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(a)]) == 0
    assert main(["estimate", str(meas), "--method", "ukf", "-o", str(b)]) == 0
    capsys.readouterr()
    png = tmp_path / "p.png"
    assert main(["plot", str(a), "--truth", str(b), "-o", str(png)]) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {b}: has an estimate's status or std_ columns: an estimate, "
        "not a truth (plot EST.csv --truth TRUTH.csv)\n"
    )
    assert not png.exists()


def test_evaluate_says_when_the_truths_sections_are_the_robot_files_in_another_order(
    tmp_path, capsys
) -> None:
    """Two sections of 0.16 and 0.14 m described as 0.14 and 0.16 m: the whole length
    agrees, so only the truth's own sections (their chords and bends) show that the
    robot file is not the truth's robot."""
    meas, truth = tmp_path / "m.csv", tmp_path / "truth.csv"
    argv = ["simulate", "spatial", "--robot", "two-section", "--duration", "2"]
    assert main([*argv, "-o", str(meas), "--truth", str(truth)]) == 0
    swapped = tmp_path / "swapped.toml"
    text = (DATA_ROBOTS / "two_section.toml").read_text()
    swapped.write_text(text.replace("length = 0.16", "length = X").replace(
        "length = 0.14", "length = 0.16").replace("length = X", "length = 0.14"))  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", str(swapped), "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--robot", str(swapped)]) == 0
    warned = [ln for ln in capsys.readouterr().err.splitlines() if "its rows fit" in ln]
    assert warned == [
        f"continuum-mhe: warning: {truth}: its rows fit sections of 0.16, 0.14 m, not the "
        "given robot's 0.14, 0.16 m: check the robot's section lengths and their order"
    ]
    est_right = tmp_path / "e2.csv"
    argv = ["estimate", str(meas), "--robot", "two-section", "--method", "ekf"]
    assert main([*argv, "-o", str(est_right)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est_right), str(truth), "--robot", "two-section"]) == 0
    assert "its rows fit" not in capsys.readouterr().err


def test_plot_and_view_say_a_truth_of_a_robot_of_other_lengths(tmp_path, capsys) -> None:
    """As ``evaluate`` says it: a truth made for sections twice as long, drawn beside the
    estimate's backbone; the right truth gives no such line."""
    pytest.importorskip("rerun")
    long_robot = tmp_path / "long.toml"
    text = (DATA_ROBOTS / "two_section.toml").read_text()
    long_robot.write_text(text.replace("length = 0.16", "length = 0.3").replace(
        "length = 0.14", "length = 0.3"))  # fmt: skip
    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    long_truth = tmp_path / "tl.csv"
    argv = ["simulate", "spatial", "--duration", "2"]
    assert main([*argv, "--robot", "two-section", "-o", str(meas), "--truth", str(truth)]) == 0
    assert main([*argv, "--robot", str(long_robot), "-o", str(tmp_path / "ml.csv"),
                 "--truth", str(long_truth)]) == 0  # fmt: skip
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", "two-section", "--method", "ekf",
                 "-o", str(est)]) == 0  # fmt: skip
    for command in (["plot", str(est), "-o", str(tmp_path / "p.png")],
                    ["view", str(est), "--save", str(tmp_path / "v.rrd")]):  # fmt: skip
        capsys.readouterr()
        assert main([*command, "--truth", str(long_truth)]) == 0
        err = capsys.readouterr().err
        assert (
            f"warning: {long_truth}: its tip is 2.00 times as far from the base as its own "
            "angles put it on a robot of 0.3 m: it was made for a robot of about 0.6 m; it is "
            "drawn beside the estimate of a robot of 0.16, 0.14 m (the truth of another "
            "robot?)"
        ) in err, err
        assert main([*command, "--truth", str(truth), "--overwrite"]) == 0
        assert "another robot" not in capsys.readouterr().err


def test_the_tip_direction_warning_names_bends_past_180_degrees() -> None:
    """A section bent past 180 degrees (a soft robot curled by the tensions sized for
    another) has a bend angle, the swing of its end's frame, that cannot describe it:
    its positions then disagree with its angles as swapped axes would. The warning names
    that cause where the file's bends reach over 170 degrees, and only there."""
    from continuum_mhe.io.position_units import tip_direction_problem
    from continuum_mhe.model.pcc import pose_at

    names = ["t", "x", "y", "z", "theta_1", "phi_1", "theta_2", "phi_2"]
    lengths = (0.15, 0.15)

    def table(theta_1: float) -> np.ndarray:
        theta = np.column_stack([np.full(40, theta_1), np.linspace(0.1, 0.6, 40)])
        phi = np.column_stack([np.linspace(0.0, 1.0, 40), np.linspace(0.0, 1.0, 40)])
        bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1)
        tip = -np.asarray(pose_at(bends, lengths, 1)[1], dtype=float)  # x and y flipped
        tip[:, 2] *= -1.0
        return np.column_stack([np.arange(40) * 0.02, tip, theta[:, 0], phi[:, 0],
                                theta[:, 1], phi[:, 1]])  # fmt: skip

    said = tip_direction_problem(names, table(math.radians(175.0)), lengths)
    assert "x and y swapped" in said and "bent past 180 degrees (its bends reach 175" in said
    said = tip_direction_problem(names, table(math.radians(120.0)), lengths)
    assert "x and y swapped" in said and "bent past" not in said


def test_tensions_from_arrays_refuse_what_a_tensions_file_would() -> None:
    """``Tensions.from_rows`` (a tendon robot's tensions from arrays): arrays of other
    lengths or shapes, times that do not increase, a tension that is missing or
    negative: one UserError naming the stream and the problem, not an error from inside
    the derivatives."""
    from continuum_mhe.io.tensions import Tensions

    t = np.arange(10) * 0.02
    v = np.ones((10, 6))
    gap = v.copy()
    gap[3, 1] = np.nan
    cases = [
        ((t[:-1], v), r"^log: t has 9 times and the tensions 10 rows: they must match$"),
        ((t, v[:, 0]), r"^log: t must be \(n,\) s and the tensions \(n, k\) N"),
        ((t[::-1], v), r"^log: t must be finite and strictly increasing \(s\)$"),
        ((np.r_[t[:4], t[3:9]], v), r"^log: t must be finite and strictly increasing \(s\)$"),
        ((t[:0], v[:0]), r"^log: no tension rows$"),
        (("abc", v), r"^log: t and the tensions must be arrays of numbers"),
        ((t, gap), r"^log: row 3 \(t = 0.06 s\): tension_2 is nan: leave the row out"),
        ((t, -v), r"^log: row 0 \(t = 0 s\): tension_1 = -1 N is negative: a tendon cannot push"),
    ]
    for (times, values), match in cases:
        with pytest.raises(UserError, match=match):
            Tensions.from_rows("log", times, values)
    taken = Tensions.from_rows("log", list(t), v.tolist())  # lists are arrays too
    np.testing.assert_array_equal(taken.values, v)


def test_raw_readings_and_reset_name_a_wrong_argument() -> None:
    """``raw_readings`` given RobotSettings for its robot, and ``reset(keep_sensors=True)``
    without ``keep_counts`` (the sensors are kept within a recording): a UserError each."""
    from continuum_mhe import raw_readings, simulate_robot
    from continuum_mhe.io.robot_file import read_robot

    robot = read_robot("two-section")
    rec = simulate_robot("s-curve", robot, duration=0.2)
    with pytest.raises(UserError, match=r"^robot must be a Robot \(read_robot"):
        raw_readings(rec, RobotSettings())  # type: ignore[arg-type]
    with pytest.raises(UserError, match=r"^rec must be a Recording"):
        raw_readings(rec.z, robot)  # type: ignore[arg-type]
    est = make_estimator("ekf", make_formulation("bend"))
    with pytest.raises(UserError, match=r"keep_sensors=True\) needs keep_counts=True"):
        est.reset(keep_sensors=True)
    est.reset(keep_counts=True, keep_sensors=True)


def test_a_robot_built_in_code_gets_the_robot_files_slip_warnings() -> None:
    """``make_formulation`` on a robot built in code says what a robot file's reader
    would (IMUs out of base order or at one place, an ``at`` in metres, a ``mount_rpy``
    in radians, a ``gyro_bias`` in deg/s), once per robot, in 0-based terms; a clean
    robot and a robot file's (said by its reader) get none."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.robot import ImuPlacement, Robot, RobotWarning, Section

    # lengths no other test's robot has: a robot equal to one another test made, and
    # still holds, is said there (once per robot)
    two = (Section(0.1617), Section(0.1383))
    cases = [
        (
            (ImuPlacement(1), ImuPlacement(0)),
            r"imus\[1\] \(sections\[0\], at 1\) is nearer the base",
        ),
        ((ImuPlacement(0), ImuPlacement(0)), r"imus\[1\] is at the same place as imus\[0\]"),
        ((ImuPlacement(0, at=0.1617), ImuPlacement(1)), r"imus\[0\]\.at = 0\.1617 .* metres\?"),
        (
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 1.5708, 0.0))),
            r"radians\? imus\[1\]\.mount_rpy",
        ),
        (
            (ImuPlacement(0, gyro_bias=(0.5, 0.0, 0.0)), ImuPlacement(1)),
            r"imus\[0\]\.gyro_bias .*deg/s\?",
        ),
    ]
    for imus, match in cases:
        robot = Robot(two, imus)
        with pytest.warns(RobotWarning, match=r"^robot: " + match):
            make_formulation("bend", robot)
        with warnings.catch_warnings():  # said once
            warnings.simplefilter("error")
            make_formulation("bend", robot)
    # a section of 3.17 m: centimetres read as metres?
    robot = Robot((Section(3.17), Section(0.1383)), (ImuPlacement(0), ImuPlacement(1)))
    with pytest.warns(RobotWarning, match=r"^robot: sections\[0\]: length 3\.17 m .* 0\.0317\)"):
        make_formulation("bend", robot)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make_formulation("bend", Robot(two, (ImuPlacement(0), ImuPlacement(1))))
        make_formulation("bend", read_robot("two-section"))


def test_an_estimator_of_a_robot_built_with_a_mount_rpy_says_that_it_is_not_applied() -> None:
    """A robot built in code with an IMU's ``mount_rpy``, and readings handed to the
    estimator: the estimator takes them in each IMU's disk frame, so its first samples
    (``step``, ``run`` or ``continue_run``) get a warning, once per robot, naming the IMU;
    readings that came through the raw conversion (turned by ``mount_rpy``), before the
    estimator was made or after it (a control loop that converts each sample before it
    steps it), or from ``simulate_robot`` (in the disks' frames) get no warning."""
    from continuum_mhe.io import raw_measurements
    from continuum_mhe.model.robot import RobotWarning

    # lengths no other test's robot has: an equal robot would count as said
    mounted = Robot(
        (Section(0.1571), Section(0.1429)),
        (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 30.0))),
    )
    z = np.zeros(4)
    for k, how in enumerate(("step", "run", "continue_run")):
        if k:  # a robot not said of yet
            mounted = Robot((Section(0.1580 + k * 1e-4), Section(0.1420)), mounted.imus)
        formulation = make_formulation("bend", mounted)
        est = make_estimator("ekf", formulation)
        with pytest.warns(RobotWarning, match=r"^robot: the mount_rpy of IMU 2 is not applied"):
            if how == "step":
                est.step(Measurement(0.0, z))
            else:
                getattr(est, how)([0.0], [z])
        with warnings.catch_warnings():  # said once per robot
            warnings.simplefilter("error")
            make_estimator("ekf", formulation).step(Measurement(0.0, z))
    from continuum_mhe.estimators.kalman import ExtendedKalmanFilter

    built = Robot(  # an estimator built directly says it too, naming the caller's line
        (Section(0.1574), Section(0.1426)),
        (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 30.0))),
    )
    with pytest.warns(RobotWarning, match=r"IMU 2 is not applied") as said:
        ExtendedKalmanFilter(make_formulation("bend", built)).step(Measurement(0.0, z))
    assert said[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        simulated = Robot(
            (Section(0.1572), Section(0.1428)),
            (ImuPlacement(0, mount_rpy=(0.0, 0.0, 20.0)), ImuPlacement(1)),
        )
        rec = simulate_robot("spatial", simulated, duration=0.5)
        make_estimator("ekf", make_formulation("bend", simulated)).run(rec.t, rec.z)
        converted = Robot(
            (Section(0.1573), Section(0.1427)),
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 40.0))),
        )
        acc = np.tile([0.0, 0.0, 9.81], (5, 2, 1))
        raw = raw_measurements(converted, np.arange(5) * 0.02, acc, np.zeros((5, 2, 3)))
        make_estimator("ekf", make_formulation("direct", converted)).run(np.arange(5) * 0.02, raw)
        in_loop = Robot(  # converted sample by sample after the estimator was made
            (Section(0.1575), Section(0.1425)),
            (ImuPlacement(0), ImuPlacement(1, mount_rpy=(0.0, 0.0, 40.0))),
        )
        est = make_estimator("ekf", make_formulation("direct", in_loop))
        for k in range(5):
            one = raw_measurements(
                in_loop, np.array([k * 0.02]), acc[k : k + 1], np.zeros((1, 2, 3))
            )
            est.step(Measurement(k * 0.02, one[0]))


@pytest.mark.parametrize(
    ("command", "said"),
    [
        (["calibrate", "--from", "{rest}", "--length", "0.3"],
         "--length does nothing without --write-robot"),
        (["calibrate", "--from", "{rest}", "--length", "0.3", "--theta-max", "2"],
         "--length and --theta-max do nothing without --write-robot"),
        (["view", "{est}", "--save", "{tmp}/v.rrd", "--web-port", "9000"],
         "--web-port does nothing with the view written to a file"),
        (["view", "{est}", "--spawn", "--web-port", "9000"],
         "--web-port does nothing with Rerun's native viewer"),
        (["live", "--port", "{tmp}/no-port", "--view-hz", "5", "--trail", "3"],
         "--view-hz and --trail do nothing without --view"),
        (["live", "--port", "{tmp}/no-port", "--view", "{tmp}/v.rrd", "--grpc-port", "3000"],
         "--grpc-port does nothing with the view written to a file"),
    ],
    ids=["calibrate-length", "calibrate-both", "view-save", "view-spawn", "live-no-view",
         "live-view-file"],
)  # fmt: skip
def test_an_option_that_does_nothing_here_is_refused(tmp_path, capsys, command, said) -> None:
    """An option that the rest of the command line leaves without effect is one line,
    exit 2, before any work (not accepted without a word, as if it acted), nothing
    written."""
    if command[0] in ("view", "live"):
        pytest.importorskip("rerun")
    rest, est = tmp_path / "rest.csv", tmp_path / "e.csv"
    assert main(["simulate", "rest", "--imu", "raw", "-o", str(rest), "--duration", "2"]) == 0
    est.write_text("t,x,y,z,theta,phi,status,solve_ms\n0,0,0,0.2,0,0,ok,0.1\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    capsys.readouterr()
    args = [a.format(rest=rest, est=est, tmp=tmp_path) for a in command]
    assert main(args) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"continuum-mhe: error: {said}") and err.count("\n") == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("command", ["check-robot", "estimate"])
def test_an_options_file_given_as_the_robot_is_named_as_one(tmp_path, capsys, command) -> None:
    """An options file given where a robot file goes is said to be one, with where it
    goes (the reverse mistake is recognised by --config); a robot file's typo of a
    table (``[[sections]]``) keeps its hint."""
    opts = tmp_path / "opts.toml"
    opts.write_text('# my options\n[estimate]\nmethod = "ekf"\n')
    meas = tmp_path / "m.csv"
    meas.write_text("t,roll,pitch\n0,0.1,0.1\n")
    args = ["check-robot", str(opts)] if command == "check-robot" else [
        "estimate", str(meas), "-o", str(tmp_path / "e.csv"), "--robot", str(opts)]  # fmt: skip
    capsys.readouterr()
    assert main(args) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {opts}: line 2: top level: unknown key 'estimate' and no "
        "[[section]]: not a robot file (an options file? it goes to --config)\n"
    )
    typo = tmp_path / "typo.toml"
    typo.write_text("[[sections]]\nlength = 0.2\n")
    assert main(["check-robot", str(typo)]) == 2
    assert "unknown key 'sections' (section?)" in capsys.readouterr().err
    other = tmp_path / "segment.toml"  # a robot file's table under another name
    other.write_text("[[segment]]\nlength = 0.2\n")
    assert main(["check-robot", str(other)]) == 2
    err = capsys.readouterr().err
    assert "unknown key 'segment' (allowed: " in err and "options file" not in err


@pytest.mark.parametrize("command", ["estimate", "simulate", "check-robot", "evaluate"])
def test_an_empty_robot_name_is_refused_not_taken_as_none(tmp_path, capsys, command) -> None:
    """``--robot ""`` (a shell variable left unset) is refused in one line naming --robot,
    exit 2, not taken as no robot file at all, the run on the default one section."""
    argv = {
        "estimate": ["estimate", "m.csv", "-o", str(tmp_path / "e.csv")],
        "simulate": ["simulate", "paper3d", "-o", str(tmp_path / "m.csv")],
        "check-robot": ["check-robot"],
        "evaluate": ["evaluate", "e.csv", "t.csv"],
    }[command]
    if command == "check-robot":
        argv += [""]
    else:
        argv += ["--robot", ""]
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "an empty name" in err, err
    assert list(tmp_path.iterdir()) == []


def test_an_empty_value_in_an_options_file_is_refused_naming_its_line(tmp_path, capsys) -> None:
    """``inputs = ""`` in a ``--config`` file is not taken as the option left out: one
    line naming the file, its line and the key, exit 2, nothing written."""
    meas, cfg, out = tmp_path / "m.csv", tmp_path / "c.toml", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    cfg.write_text('inputs = ""\n')
    capsys.readouterr()
    assert main(["estimate", str(meas), "-o", str(out), "--config", str(cfg)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == (
        f"continuum-mhe: error: {cfg}: line 1: inputs = '': an empty value: give one, or "
        "leave the key out"
    )
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["calibrate", "--from", "rest.csv", "--write-robot", ""], "--write-robot"),
        (["simulate", "paper3d", "-o", "m.csv", "--truth", ""], "--truth"),
        (["estimate", "m.csv", "-o", "e.csv", "--config", ""], "--config"),
        (["estimate", "m.csv", "-o", "e.csv", "--inputs", " "], "--inputs"),
        (["plot", "e.csv", "-o", ""], "-o/--output"),
        (["estimate", "", "-o", "e.csv"], "measurements"),
        (["evaluate", "", "t.csv"], "estimates"),
        (["view", "e.csv", "--save", ""], "--save"),
        (["demo", "--out", ""], "--out"),
    ],
)
def test_an_empty_file_name_is_refused_not_taken_as_left_out(tmp_path, capsys, argv, name) -> None:
    """A file, folder or port given as an empty string (a shell variable left unset) is
    not taken as the option left out (no truth or robot file written, the options file
    ignored, a plot beside its input) or as the current folder: one line naming the
    argument, exit 2, nothing written."""
    import os

    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        with pytest.raises(SystemExit) as stopped:
            main(argv)
    finally:
        os.chdir(here)
    assert stopped.value.code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert f"error: argument {name}: an empty value (a shell variable left unset?)" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "make",
    [
        lambda big: Section(big),
        lambda big: Section(0.2, theta_max=big),
        lambda big: ImuPlacement(0, gyro_bias=(big, 0.0, 0.0)),
        lambda big: RobotSettings(length=big),
        lambda big: NoiseSettings(measurement_std=big),
        lambda big: MHESettings(tol=big),
    ],
    ids=["section-length", "theta-max", "gyro-bias", "robot-settings", "noise", "mhe-tol"],
)
def test_an_integer_beyond_a_floats_range_is_a_user_error(make) -> None:
    """10**400, a Python integer no float holds, is a UserError naming the argument (not
    an OverflowError from math.isfinite inside the check)."""
    with pytest.raises(UserError) as refused:
        make(10**400)
    assert "\n" not in str(refused.value)


def test_the_writers_refuse_what_their_readers_would_not_read_back(tmp_path) -> None:
    """write_measurements, write_truth and write_estimates wrote files their own readers
    refused (a column named twice or empty, a note over two lines, a truth out of time
    order or in degrees) or failed inside (a note that is no pair, outputs given as
    names): each is a UserError, and no file is written."""
    from continuum_mhe.io.estimate_csv import write_estimates, write_measurements, write_truth

    rec = simulate("paper3d", duration=1.0)
    series = make_estimator("ekf", make_formulation("bend")).run(rec.t, rec.z)
    out = tmp_path / "w.csv"
    refused = [
        (lambda: write_measurements(out, rec.t, rec.z, ["roll", "roll"]), "named twice"),
        (
            lambda: write_measurements(out, rec.t, rec.z, ["t", "pitch"]),
            "column 't' is named twice",
        ),
        (lambda: write_measurements(out, rec.t, rec.z, ["", "pitch"]), "column name ''"),
        (lambda: write_measurements(out, rec.t, rec.z, [1, 2]), "column name 1"),  # type: ignore[list-item]
        (lambda: write_truth(out, rec.t[::-1], rec.truth), "strictly increasing"),
        (lambda: write_truth(out, rec.t, rec.truth * [1, 1, 1, 57.3, 57.3]), "degrees?"),
        (
            lambda: write_truth(out, rec.t, rec.truth, ["x", "y", "z", "theta", "phi"]),
            "OutputSpecs",
        ),  # type: ignore[list-item]
        (lambda: write_estimates(out, series, [("options", "a\nb")]), "one-line strings"),
        (lambda: write_estimates(out, series, ["abc"]), "a (key, value) pair"),  # type: ignore[list-item]
    ]
    for write, said in refused:
        with pytest.raises(UserError, match=re.escape(said)):
            write()
        assert not out.exists()
    write_estimates(out, series, [("options", '{method = "ekf"}')])
    assert out.read_text().startswith('# options = {method = "ekf"}\n')


def test_more_library_mistakes_are_one_line_user_errors(tmp_path) -> None:
    """From a fuzzing of the library: run with t None (not "t has 1 samples"), with
    readings of bools or strings (not taken as 1.0 and 0.0, or parsed); load_input of a
    tilt file for the direct model (not an IndexError); raw_measurements given
    RobotSettings (not an AttributeError): each a UserError naming what to give."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input, raw_measurements

    rec = simulate("paper3d", duration=1.0)
    est = make_estimator("ekf", make_formulation("bend"))
    for t, z, said in (
        (None, rec.z, "t is None: give the sample times"),
        (rec.t, rec.z > 0, "arrays of numbers (t (n,) s, z (n, m)); z holds bool values"),
        (rec.t, rec.z.astype(str), "arrays of numbers (t (n,) s, z (n, m)); z holds <U"),
    ):
        with pytest.raises(UserError, match=re.escape(said)):
            est.run(t, z)
    assert len(est.run(list(rec.t), [list(row) for row in rec.z]).t) == len(rec.t)
    tilt = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(tilt)]) == 0
    with pytest.raises(UserError, match=r"tilt readings \(roll, pitch\) are read for the robot"):
        load_input(tilt, InputOptions(), make_formulation("direct"))
    with pytest.raises(UserError, match=r"^robot must be a Robot \(read_robot"):
        raw_measurements(RobotSettings(), rec.t, np.zeros((len(rec.t), 1, 3)))  # type: ignore[arg-type]


def test_a_tension_stream_refuses_what_is_no_tension_in_one_line() -> None:
    """TensionStream refuses 0, -1 or 2.5 tendons, a string for a time or for the
    tensions, bools and infinite tensions (not a failure inside numpy, nor NaN rates):
    each a UserError; a sample of numbers is taken."""
    from continuum_mhe.io.tensions import TensionStream

    for n in (0, -1, 2.5):
        with pytest.raises(UserError, match="n_tendons must be a positive integer"):
            TensionStream(n_tendons=n)  # type: ignore[arg-type]
    stream = TensionStream(n_tendons=2)
    for text in ("abc", ["1", "2"], [True, False]):  # text, even of numbers; bools
        with pytest.raises(UserError, match="tensions that are not numbers"):
            stream.push(0.05, text)  # type: ignore[arg-type]
    with pytest.raises(UserError, match=r"tension_2 = inf: give NaN for a tension that is missing"):
        stream.push(0.05, [1.0, np.inf])
    with pytest.raises(UserError, match="a sample's time must be a number of seconds"):
        stream.push("0.07", [1.0, 2.0])  # type: ignore[arg-type]
    assert stream.push(0.1, [1.0, 2.0]) == []  # (its derivatives need two more)


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
    pytest.importorskip("rosbags")
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
    pytest.importorskip("rosbags")
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
    pytest.importorskip("rosbags")
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


def _tip_truth_turned(
    src: Path, dst: Path, turn: np.ndarray, move: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> None:
    """``src``'s truth as a motion capture gives it, ``t, x, y, z`` of the tip alone, each
    position turned by the matrix ``turn`` (3, 3), then moved by ``move`` (m)."""
    from continuum_mhe.io.state_tables import read_state_table

    table = read_state_table(src)
    tip = table.values[:, [table.names.index(c) for c in ("x", "y", "z")]] @ turn.T + move
    np.savetxt(dst, np.c_[table.t, tip], delimiter=",", header="t,x,y,z", comments="", fmt="%.9g")


def test_evaluate_and_plot_warn_of_a_truth_in_a_y_up_motion_capture_frame(
    paper3d_pair, tmp_path, capsys
) -> None:
    """A motion capture's tip positions in its y-up frame (x, z, -y of the robot's base
    frame), hundreds of mm off as given, are warned of: the truth turned about the base
    fits far better, and the warning names where its axes lie; the same tip positions in
    the base frame, and turned by 10 degrees only, say nothing."""
    e = str(paper3d_pair["e"])
    y_up = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])  # base frame -> y-up frame
    cases = {"yup": y_up, "base": np.eye(3)}
    small = math.radians(10)
    cases["small"] = np.array(
        [[math.cos(small), -math.sin(small), 0], [math.sin(small), math.cos(small), 0], [0, 0, 1]]
    )
    paths = {k: tmp_path / f"{k}.csv" for k in cases}
    for k, turn in cases.items():
        _tip_truth_turned(paper3d_pair["t"], paths[k], turn)
    said = "the truth's tip fits the estimate far better turned by 90 degrees about the base"
    assert main(["evaluate", e, str(paths["yup"])]) == 0
    err = capsys.readouterr().err
    assert f"warning: {paths['yup']}: {said}" in err
    assert "its x, y and z lie along the estimate's x, z, -y" in err
    assert "an IMU's yaw" not in err  # a turn about x: no yaw of an IMU's does that
    assert main(["plot", e, "--truth", str(paths["yup"]), "-o", str(tmp_path / "f.png")]) == 0
    assert said in capsys.readouterr().err  # as evaluate
    # turned about z: the frame, or an IMU's yaw that a rest calibration kept
    about_z = tmp_path / "about_z.csv"
    _tip_truth_turned(paper3d_pair["t"], about_z, np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]))
    assert main(["evaluate", e, str(about_z)]) == 0
    err = capsys.readouterr().err
    (line,) = [ln for ln in err.splitlines() if said in ln]
    assert line.endswith(
        "; or, turned about z, is an IMU's yaw in the robot file wrong (its mount_rpy: a "
        "calibration at rest keeps the file's yaw, calibrate --bend measures it)?"
    )
    for k in ("base", "small"):
        assert main(["evaluate", e, str(paths[k])]) == 0
        assert "fits the estimate far better" not in capsys.readouterr().err, k
    # about a motion capture's origin 1.5 m away: said, with the move, and not taken for
    # a truth of a longer robot; an offset of 2 cm (as likely the estimate's) is not
    far, near = tmp_path / "far.csv", tmp_path / "near.csv"
    _tip_truth_turned(paper3d_pair["t"], far, y_up, (0.9, 1.2, -0.05))
    _tip_truth_turned(paper3d_pair["t"], near, np.eye(3), (0.02, 0.0, 0.0))
    assert main(["evaluate", e, str(far)]) == 0
    err = capsys.readouterr().err
    moved = re.search(r"far better turned by 90 degrees and moved by \((.*?)\) mm", err)
    assert moved is not None  # by about the move back, within the estimate's own errors
    assert_allclose([float(v) for v in moved.group(1).split(",")], [-900, -50, -1200], atol=20)
    assert "its x, y and z lie along the estimate's x, z, -y" in err
    assert "longer robot" not in err and "another --length" not in err
    assert err.count("warning:") == 1
    assert main(["evaluate", e, str(near)]) == 0
    assert "fits the estimate far better" not in capsys.readouterr().err


def test_best_rotation_recovers_a_known_turn_of_the_positions() -> None:
    """The rotation that takes the truth's positions back to the estimate's: a known
    turn of 40 degrees about a tilted axis is found to 1e-9, with its error 0 against the
    unturned one; positions as they are give 0 degrees; too few rows give None."""
    from scipy.spatial.transform import Rotation

    from continuum_mhe.evaluation.metrics import ROTATION_MIN_ROWS, best_rotation

    rng = np.random.default_rng(3)
    est = rng.normal(size=(50, 3)) * 0.1
    turn = Rotation.from_rotvec(math.radians(40) * np.array([1.0, 2.0, 2.0]) / 3.0)
    found = best_rotation(est, turn.inv().apply(est))
    assert found is not None
    assert found.angle_deg == pytest.approx(40.0, abs=1e-9)
    np.testing.assert_allclose(found.matrix, turn.as_matrix(), atol=1e-9)
    assert found.error < 1e-12 and found.unturned > 0.01
    same = best_rotation(est, est)
    assert same is not None and same.angle_deg < 1e-6 and same.unturned == 0.0
    assert best_rotation(est[: ROTATION_MIN_ROWS - 1], est[: ROTATION_MIN_ROWS - 1]) is None
    # moved as well: the turn and the move are found
    move = np.array([0.7, -1.1, 0.4])
    moved = best_rotation(est, turn.inv().apply(est - move), moved=True)
    assert moved is not None
    np.testing.assert_allclose(moved.matrix, turn.as_matrix(), atol=1e-9)
    np.testing.assert_allclose(moved.offset, move, atol=1e-9)
    assert moved.error < 1e-12
    np.testing.assert_allclose(found.offset, 0.0)


def test_no_frame_is_claimed_for_a_truth_along_a_line() -> None:
    """A truth whose tip stays along a line (a still or straight robot, a motion along
    one axis) leaves the turn about that line undetermined: a still truth 5 to 50 mm off
    the estimate fits turned by 50 to 175 degrees about it, and a wobble along x
    mirrored by 180; no frame is claimed for them (a bent, moving truth turned by 90
    degrees is)."""
    from scipy.spatial.transform import Rotation

    from continuum_mhe.cli.truth_checks import frame_fit

    rng = np.random.default_rng(0)
    n, length = 500, 0.35
    for offset in (0.005, 0.01, 0.05):  # the estimate off the still truth in x
        still_truth = np.array([0.0, 0.0, length]) + rng.normal(0.0, 5e-4, (n, 3))
        still_est = np.array([offset, 0.0, length - 5e-4]) + rng.normal(0.0, 5e-5, (n, 3))
        assert frame_fit(still_est, still_truth, length) is None, offset
    wobble = np.column_stack(
        [0.01 * np.sin(np.linspace(0, 20, n)), np.zeros(n), np.full(n, length)]
    ) + rng.normal(0.0, 3e-4, (n, 3))
    assert frame_fit(wobble * [-1.0, 1.0, 1.0], wobble, length) is None  # mirrored in x
    theta = np.linspace(0.0, 1.2, n)
    bent = np.column_stack([length * np.sin(theta) * np.cos(3 * theta), length * np.sin(theta)
                            * np.sin(3 * theta), length * np.cos(theta)])  # fmt: skip
    turned = Rotation.from_euler("x", 90, degrees=True).apply(bent)
    fit = frame_fit(bent, turned, length)
    assert fit is not None and abs(fit.angle_deg - 90.0) < 1e-6


def test_a_robot_or_formulation_given_before_the_name_is_told_the_order() -> None:
    """``make_formulation(robot)`` and ``make_estimator(formulation, "ekf")``, the
    arguments swapped: one line each saying which comes first, not the name check's
    message with the object's whole repr."""
    robot = Robot((Section(0.2),), (ImuPlacement(0),))
    with pytest.raises(UserError, match=r"^make_formulation takes the formulation's name first"):
        make_formulation(robot)  # type: ignore[arg-type]
    formulation = make_formulation("bend", robot)
    with pytest.raises(UserError, match=r"^make_estimator takes the method first") as info:
        make_estimator(formulation, "ekf")  # type: ignore[arg-type]
    assert len(str(info.value)) < 200


def test_an_estimate_s_recorded_mounting_holds_with_length_and_is_warned_with_a_robot(
    tmp_path, capsys
) -> None:
    """A hanging robot's estimate (its options line records ``z-down``) read with
    ``--length`` alone keeps that mounting; with a robot file that says ``z-up`` the
    turn is warned of, as ``--mounting z-up`` is."""
    import argparse

    from continuum_mhe.cli.robot_options import estimate_robot

    m, t, e = (str(tmp_path / n) for n in ("m.csv", "t.csv", "e.csv"))
    assert main(["simulate", "paper3d", "-o", m, "--truth", t, "--duration", "1",
                 "--mounting", "z-down"]) == 0  # fmt: skip
    assert main(["estimate", m, "-o", e, "--mounting", "z-down", "--method", "ekf"]) == 0
    capsys.readouterr()
    args = argparse.Namespace(robot=None, length=0.2, mounting=None)
    assert estimate_robot(args, e, "drawn").mounting == "z-down"
    up = tmp_path / "up.toml"
    up.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    said: list[str] = []
    robot = estimate_robot(argparse.Namespace(robot=str(up)), e, "drawn", said)
    assert robot.mounting == "z-up" and len(said) == 1
    assert "was estimated with mounting z-down (its options line), but" in said[0]


def test_view_of_a_tendon_estimate_whose_tensions_file_is_gone_names_it(tmp_path, capsys) -> None:
    """A tendon robot's estimate whose options line names a tensions file that is not
    there: ``view`` draws the tips alone and says which file it looked for."""
    from continuum_mhe.cli.view import _recorded_tensions
    from continuum_mhe.io.robot_file import read_robot

    est = tmp_path / "e.csv"
    est.write_text(
        '# options = {robot = "tendon-two-section", inputs = "gone_tensions.csv"}\n'
        "t,x,y,z,status\n0,0,0,0.4,ok\n"
    )
    assert _recorded_tensions(str(est), read_robot("tendon-two-section")) is None
    err = capsys.readouterr().err
    assert "was estimated with --inputs gone_tensions.csv (its options line), which is not" in err


def test_evaluate_of_a_truth_that_ends_early_says_so_after_skip_start(
    paper3d_pair, tmp_path, capsys
) -> None:
    """A truth that ends at 3.6 s of a 6 s run, scored with --skip-start: what is left of
    it decides whether it covers part of the run (from 2.6 s: that part's warning, not
    'the files' times do not match'); where no rows are left, the message says the truth
    ends there, not only that the times do not match."""
    lines = Path(paper3d_pair["t"]).read_text().splitlines()
    head = [ln for ln in lines if not ln[:1].isdigit()]
    rows = [ln for ln in lines if ln[:1].isdigit() and float(ln.split(",")[0]) <= 3.6]
    early = tmp_path / "early.csv"
    early.write_text("\n".join([*head, *rows]) + "\n")
    e = str(paper3d_pair["e"])
    assert main(["evaluate", e, str(early), "--skip-start", "2.6"]) == 0
    err = capsys.readouterr().err
    assert "which covers that part of the run alone" in err and "do not match" not in err
    assert main(["evaluate", e, str(early), "--skip-start", "4.5"]) == 2
    err = capsys.readouterr().err
    assert "or the truth ends at t = 3.6 s and --skip-start scores from t = 4.5 s" in err


def test_formulation_options_of_no_number_are_one_user_error_naming_them() -> None:
    """The raw-IMU model's and the tendon model's number options given None, a string, or
    a value whose square (a variance) a float cannot hold: one UserError naming the
    option, not a TypeError or OverflowError from inside the model; a numpy integer seed
    is a seed (the same recording as the int)."""
    from dataclasses import replace

    from continuum_mhe import make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.robot_file import read_robot

    direct = make_formulation("direct", read_robot("two-section"))
    for value in (None, "0.01", 1e300, 1e-300):
        with pytest.raises(UserError, match=r"^gyro_std must be a positive finite number"):
            replace(direct, gyro_std=value)
    tendon = make_formulation("tendon", read_robot("tendon-two-section"))
    for value in (None, "1.0"):
        with pytest.raises(UserError, match=r"^tension_std must be a number, got"):
            replace(tendon, tension_std=value)
    with pytest.raises(UserError, match=r"^force_accel_psd must be a number or None, got"):
        replace(tendon, force_accel_psd="1.0")
    assert np.array_equal(simulate("paper3d", duration=1.0, seed=np.int64(3)).z,
                          simulate("paper3d", duration=1.0, seed=3).z)  # fmt: skip


def test_a_start_prior_wider_than_the_robots_reach_is_taken_as_its_reach() -> None:
    """``initial_bend_std`` 100 rad, wider than any bend the robot can make: every
    estimator starts from a prior of the bend bound's width (so the unscented filter's
    sigma points do not wrap the angles); one whose square no float holds is refused
    naming it."""
    from continuum_mhe import NoiseSettings, make_formulation, simulate
    from continuum_mhe.errors import UserError

    rec = simulate("paper3d", duration=3.0, seed=1)
    f = make_formulation("bend", None, NoiseSettings(initial_bend_std=100.0))
    _, P = f.start_prior(rec.z[0])
    np.testing.assert_allclose(np.sqrt(np.diag(P))[:2], f.robot.sections[0].theta_max)
    for method in ("ekf", "ukf", "mhe"):
        series = make_estimator(method, f).run(rec.t, rec.z)
        assert np.mean(series.status == "ok") > 0.9, (method, series.diagnostics)
    with pytest.raises(UserError, match=r"^initial_bend_std 1e\+300 is too large"):
        NoiseSettings(initial_bend_std=1e300)


def test_step_refuses_what_run_refuses_and_run_names_a_ragged_list() -> None:
    """``step`` with readings given as bools or text is refused as ``run`` refuses them
    (not estimated from 1.0 and 0.0 rad), and ``run`` given rows of different lengths
    says so in a UserError (not numpy's inhomogeneous-shape ValueError)."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.errors import UserError

    est = make_estimator("ekf", make_formulation("bend"))
    for z in ([True, False], ["0.1", "0.2"]):
        with pytest.raises(UserError, match="measurement z must be numbers"):
            est.step(Measurement(0.0, z))
    rec = simulate("paper3d", duration=1.0)
    with pytest.raises(UserError, match=r"^z must be an array .*its rows differ in length"):
        est.run(rec.t[:3], [[0.1, 0.1], [0.1], [0.1, 0.1]])


def test_readings_that_mix_bools_with_numbers_are_refused_as_bools_are() -> None:
    """A bool among numbers (``[True, 0.1]``, which numpy reads as ``[1.0, 0.1]``) is
    refused by ``step``, ``run``, ``continue_run`` and ``TensionStream.push`` with the
    UserError that readings of bools alone get, not estimated from 1.0."""
    from continuum_mhe import Measurement, make_formulation, simulate
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.tensions import TensionStream

    est = make_estimator("ekf", make_formulation("bend"))
    for z in ([True, False], [True, 0.1], np.array([0.1, np.True_], dtype=object)):
        with pytest.raises(UserError, match=r"^measurement z must be numbers, got"):
            est.step(Measurement(0.0, z))
    rec = simulate("paper3d", duration=0.5)
    said = "t and z must be arrays of numbers (t (n,) s, z (n, m)); z holds bool values"
    for z in (rec.z > 0, [[True, *row[1:]] for row in rec.z.tolist()]):
        for call in (est.run, est.continue_run):
            with pytest.raises(UserError, match=re.escape(said)):
                call(rec.t, z)
    t_said = said.replace("z holds", "t holds")
    with pytest.raises(UserError, match=re.escape(t_said)):
        est.run([True, *rec.t[1:].tolist()], rec.z)
    stream = TensionStream(n_tendons=2)
    for tensions in ([True, False], [True, 1.0]):
        with pytest.raises(UserError, match="tensions that are not numbers"):
            stream.push(0.05, tensions)  # type: ignore[arg-type]
    assert stream.push(0.05, [1.0, 2.0]) == []  # numbers alone are taken


def test_a_method_array_is_refused_and_robot_settings_write_as_a_robot_file(tmp_path) -> None:
    """``make_estimator`` given an array of method names (a loop's mistake) is one
    UserError naming the methods, not numpy's ambiguous truth value; ``write_robot``
    takes a one-section ``RobotSettings`` as ``make_formulation`` does, and the file
    reads back as that robot."""
    from continuum_mhe import RobotSettings, make_formulation
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot, write_robot
    from continuum_mhe.model.formulations import as_robot

    with pytest.raises(UserError, match=r"^method must be one of"):
        make_estimator(np.array(["ekf", "ukf"]), make_formulation("bend"))  # type: ignore[arg-type]
    assert type(make_estimator(np.array(["ekf", "ukf"])[0], make_formulation("bend"))).__name__ == (
        "ExtendedKalmanFilter"
    )
    settings = RobotSettings(length=0.3, mounting="z-down")
    write_robot(tmp_path / "one.toml", settings)
    assert read_robot(tmp_path / "one.toml") == as_robot(settings)


def test_an_estimate_series_built_by_hand_is_checked_in_user_errors() -> None:
    """An ``EstimateSeries`` made in code with outputs of the wrong shape or a status
    that is none of the statuses: one UserError naming it (not a ValueError, or a
    KeyError when its statuses are counted); outputs given as a list are taken."""
    from continuum_mhe import EstimateSeries
    from continuum_mhe.errors import UserError

    t, ok = np.arange(3.0), np.tile([0.01, 0.02, 0.19, 0.1, 0.5], (3, 1))
    status = np.array(["ok"] * 3)
    with pytest.raises(UserError, match=r"^output has shape \(3, 3\), expected \(3, 5\)"):
        EstimateSeries("ekf", t, ok[:, :3], status, np.zeros(3))
    with pytest.raises(UserError, match=r"^status 'bogus' is not one of ok, "):
        EstimateSeries("ekf", t, ok, np.array(["bogus"] * 3), np.zeros(3))
    series = EstimateSeries("ekf", t, ok.tolist(), status, np.zeros(3))  # type: ignore[arg-type]
    assert [str(s.value) for s in series.statuses()] == ["ok"] * 3


def test_an_estimate_series_built_by_hand_takes_its_times_as_an_array() -> None:
    """An ``EstimateSeries`` made in code with its times as a list is one whose rows a
    mask selects (the times an array, not a TypeError from indexing the list), and times
    given as a column (n, 1) or as text are one UserError naming ``t``."""
    from continuum_mhe import EstimateSeries
    from continuum_mhe.errors import UserError

    t, out = [0.0, 0.5, 1.0], np.tile([0.01, 0.02, 0.19, 0.1, 0.5], (3, 1))
    status = np.array(["ok"] * 3)
    series = EstimateSeries("ekf", t, out, status, [0.1, 0.1, 0.1])  # type: ignore[arg-type]
    assert series.t.dtype == np.float64 and series.solve_ms.dtype == np.float64
    late = series.rows(series.t >= 0.5)
    assert late.t.tolist() == [0.5, 1.0]
    with pytest.raises(UserError, match=r"^t has shape \(3, 1\), expected \(n,\)"):
        EstimateSeries("ekf", np.array(t)[:, None], out, status, np.zeros(3))
    with pytest.raises(UserError, match=r"^t must be an array of numbers"):
        EstimateSeries("ekf", ["0", "a", "1"], out, status, np.zeros(3))  # type: ignore[arg-type]


def test_write_robot_refuses_a_robot_of_another_type_naming_it(tmp_path) -> None:
    """``write_robot`` given a robot file's name (what ``read_robot`` takes) or None is
    one UserError naming the argument, and writes no file: not an AttributeError from
    inside the writer, nor the default robot's file for None."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import write_robot

    for robot in ("two-section", None):
        path = tmp_path / "robot.toml"
        with pytest.raises(UserError, match=r"^write_robot robot must be a Robot or RobotSettings"):
            write_robot(path, robot)  # type: ignore[arg-type]
        assert not path.exists()


def test_plot_of_a_paper_formulation_estimate_draws_the_recorded_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The paper formulation's x, y, z are states of their own, off the end of the arc
    of its bend: plot takes the robot its options line records (0.2 m), as evaluate and
    view do, without a warning that the truth or the given robot file is another
    robot's."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth)]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--formulation", "paper"]) == 0
    robot = tmp_path / "one.toml"
    robot.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    capsys.readouterr()
    fig = tmp_path / "f.png"
    for extra in ([], ["--robot", str(robot)]):
        assert main(["plot", str(est), "--truth", str(truth), "-o", str(fig), "--overwrite",
                     *extra]) == 0  # fmt: skip
        err = capsys.readouterr().err
        assert "warning" not in err, (extra, err)
    # a robot file of another length: its states give no lengths, its options line does
    robot.write_text(robot.read_text().replace("length = 0.2", "length = 0.3"))
    assert main(["plot", str(est), "-o", str(fig), "--overwrite", "--robot", str(robot)]) == 0
    assert "it was estimated with --length 0.2 (its options line), not the given robot's 0.3 m" in (
        capsys.readouterr().err
    )


def test_plot_warns_of_a_robot_file_of_another_mounting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """plot --robot with the estimate's sections but the other mounting draws the robot
    turned over: a warning, as evaluate and view give; the same file with the estimate's
    mounting, none."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    fig = tmp_path / "f.png"
    for mounting, warned in (("z-down", True), ("z-up", False)):
        robot = tmp_path / f"{mounting}.toml"
        robot.write_text(
            f'mounting = "{mounting}"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n'
        )
        capsys.readouterr()
        assert main(["plot", str(est), "--robot", str(robot), "-o", str(fig), "--overwrite"]) == 0
        err = capsys.readouterr().err
        assert (f"says {mounting}: the robot file's is used, which turns the estimate's "
                "base over" in err) is warned, err  # fmt: skip
