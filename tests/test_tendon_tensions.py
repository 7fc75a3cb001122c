"""Tendon-driven robots' tensions input: the tensions file and the recording's own
tension columns, their checks, rates and noise, and the one-line refusals."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small
from tendon_helpers import (
    BACKBONE,
    one_section_robot,
    small_robot,
    small_robot_recording,
    small_robot_recording_rows,
    write_text_table,
)

from continuum_mhe.cli import main
from continuum_mhe.io.csv_files import DropoutWarning
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import OptionWarning
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tensions import read_tensions
from continuum_mhe.model.robot import ImuPlacement, Robot, Tendon
from continuum_mhe.model.tendon import TendonFormulation

# --- the tensions input ----------------------------------------------------------------


def test_estimate_reads_tensions_and_writes_the_tip_force(tmp_path: Path) -> None:
    meas, tensions = small_robot_recording(tmp_path)
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(small_robot(tmp_path)), "--inputs",
            str(tensions), "-o", str(out), "--method", "ekf"]  # fmt: skip
    assert main(argv) == 0
    table = read_state_table(out)  # the project's reader: past the '#' lines
    for col in ("fx", "fy", "fz", "psi_1", "x_1", "theta_1"):
        assert col in table.names
    assert table.std is not None
    assert np.all(np.isfinite(table.std[:, table.names.index("fx")]))
    # the readings are the model's at no tip force: the estimate is the statics' shape at
    # each sample's tension (1 + 5 t N, interpolated from the file) and a force near 0
    f = TendonFormulation(robot=read_robot(small_robot(tmp_path)))
    names = [o.name for o in f.outputs]
    assert list(table.names) == names
    want = []
    np.testing.assert_allclose(table.t, np.arange(6) * 0.02)
    for tk in table.t:
        tau = 1.0 + 5.0 * tk
        k0, _ = f.statics.solve(np.zeros(3), np.array([tau]))
        x = np.zeros(f.nx)
        x[:3], x[6] = k0, tau
        want.append(np.asarray(f.output(x), float).ravel())
    got = table.values
    tip = [names.index(c) for c in ("x", "y", "z")]
    np.testing.assert_allclose(got[:, tip], np.array(want)[:, tip], atol=5e-4)
    force = [names.index(c) for c in ("fx", "fy", "fz")]
    assert np.abs(got[:, force]).max() < 0.002  # its std: 0.02 N and more
    # numpy's reader as docs/workflow.md gives it reads the same columns
    lines = (ln for ln in out.open() if not ln.startswith("#"))
    data = np.genfromtxt(lines, delimiter=",", names=True, dtype=None, encoding="utf-8")
    np.testing.assert_array_equal(data["fx"], table.column("fx"))


def _small_robot_estimate(tmp_path: Path) -> tuple[Path, Path, Path, Path]:
    """The small robot's recording, tensions file and robot file in ``tmp_path``, and
    its EKF estimate ``e.csv`` made from them by ``estimate``: ``(meas, tensions, robot,
    est)``."""
    meas, tensions = small_robot_recording(tmp_path)
    robot = small_robot(tmp_path)
    est = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(robot), "--inputs", str(tensions),
            "-o", str(est), "--method", "ekf"]  # fmt: skip
    assert main(argv) == 0
    return meas, tensions, robot, est


def test_plot_draws_a_tendon_estimate_with_its_tip_force_and_model_backbone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``plot`` of a tendon robot's estimate: with ``--robot`` and ``--inputs`` the
    backbone from the mechanics model; without them those its options line names
    (said in a note), and where those are gone the section ends joined, said in a
    note; ``--inputs`` on an estimate without a tip force: one line, nothing written."""
    meas, tensions, robot, est = _small_robot_estimate(tmp_path)
    capsys.readouterr()
    fig = tmp_path / "e.png"
    argv = ["plot", str(est), "--robot", str(robot), "--inputs", str(tensions), "-o", str(fig)]
    assert main(argv) == 0
    assert fig.stat().st_size > 0 and "note" not in capsys.readouterr().err
    figures_drawn_small(monkeypatch)  # the rest: what plot says, not what it draws
    # without --inputs: the tensions the estimate's options line names, said in a note
    assert main(["plot", str(est), "-o", str(tmp_path / "recorded.png")]) == 0
    err = capsys.readouterr().err
    assert f"was estimated with --inputs {tensions}" in err and "section ends" not in err
    moved = tensions.rename(tmp_path / "moved.csv")  # those tensions are gone
    assert main(["plot", str(est), "-o", str(tmp_path / "ends.png")]) == 0
    assert "drawn through the section ends" in capsys.readouterr().err
    moved.rename(tensions)
    # the tensions here but the robot file gone: only the notes of what is drawn
    gone = robot.rename(tmp_path / "gone.toml")
    assert main(["plot", str(est), "-o", str(tmp_path / "no_robot.png")]) == 0
    err = capsys.readouterr().err
    assert "cannot be read here" in err and "drawn through the section ends" in err
    assert "drawn with those tensions" not in err
    gone.rename(robot)
    # a recording with its tension columns beside its IMU's (live --record's) gives them
    # too, for plot and view
    both = tmp_path / "recorded_with_tensions.csv"
    write_table(both, ["t", "roll", "pitch", "tension_1"],
                [[*r, 1.0 + 5 * r[0]] for r in small_robot_recording_rows()])  # fmt: skip
    argv = ["plot", str(est), "--robot", str(robot), "--inputs", str(both), "-o", str(fig),
            "--overwrite"]  # fmt: skip
    assert main(argv) == 0 and "note" not in capsys.readouterr().err
    argv = ["view", str(est), "--robot", str(robot), "--inputs", str(both), "--save",
            str(tmp_path / "v.rrd")]  # fmt: skip
    assert main(argv) == 0 and (tmp_path / "v.rrd").stat().st_size > 0
    assert "note" not in capsys.readouterr().err
    # --inputs alone: the robot the estimate's options line names draws the backbone
    argv = ["plot", str(est), "--inputs", str(tensions), "-o", str(tmp_path / "rec.png")]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "(its options line): drawn on that robot" in err and "section ends" not in err
    pcc = tmp_path / "pcc.csv"
    table = read_state_table(est)
    keep = [c for c in table.names if c not in ("fx", "fy", "fz")]
    write_table(pcc, ["t", *keep], np.column_stack([table.t, *(table.column(c) for c in keep)]))
    refused = tmp_path / "refused.png"
    assert main(["plot", str(pcc), "--inputs", str(tensions), "-o", str(refused)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no tip force columns" in err[0] and not refused.exists()
    # --robot without tendons, no --inputs: the estimate's recorded tensions are not
    # called the user's --inputs, and the line names what is wrong
    plain = tmp_path / "plain.toml"
    plain.write_text("[[section]]\nlength = 0.2\ntheta_max = 3.0\n[[imu]]\nsection = 1\n")
    assert main(["plot", str(est), "--robot", str(plain), "-o", str(refused)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (
        f"continuum-mhe: error: {plain}: the robot has no [[tendon]], but {est} is a tendon "
        f"robot's estimate (its tip force columns; estimated with --inputs {tensions}, its "
        "options line): give that robot's file, or no --robot for the one it names"
    )
    assert not any("drawn with those tensions" in line for line in err)
    assert not refused.exists()


def test_plot_and_view_draw_an_estimate_with_its_recordings_tension_columns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An estimate of a recording that carries its tensions beside its IMU's columns
    (no ``--inputs``): ``plot`` and ``view`` find them in the recording its first line
    names, say so in a note, and draw what ``--inputs`` that recording draws; where the
    recording is not found, or has no tension columns, the section ends joined."""
    robot = small_robot(tmp_path)
    rec = tmp_path / "with_tensions.csv"
    write_table(rec, ["t", "roll", "pitch", "tension_1"],
                [[*r, 1.0 + 5 * r[0]] for r in small_robot_recording_rows()])  # fmt: skip
    est = tmp_path / "e.csv"
    argv = ["estimate", str(rec), "--robot", str(robot), "-o", str(est), "--method", "ekf"]
    assert main(argv) == 0
    assert est.read_text().splitlines()[0].endswith(f' estimate {rec.resolve()}"')
    capsys.readouterr()
    found, given = tmp_path / "found.png", tmp_path / "given.png"
    assert main(["plot", str(est), "-o", str(found)]) == 0
    err = capsys.readouterr().err
    assert f"{est} was estimated from {rec.resolve()} (its first line): its backbone " in err
    assert "section ends" not in err
    assert main(["plot", str(est), "--inputs", str(rec), "-o", str(given)]) == 0
    assert found.read_bytes() == given.read_bytes()
    figures_drawn_small(monkeypatch)  # the rest: what plot says, not what it draws
    saved = tmp_path / "found.rrd"
    assert main(["view", str(est), "--save", str(saved)]) == 0
    assert f"{rec.resolve()} (its first line)" in capsys.readouterr().err
    # a recording without tension columns, or none found: the section ends joined
    rec.write_text("t,roll,pitch\n0,0,0\n")
    assert main(["plot", str(est), "-o", str(tmp_path / "ends.png")]) == 0
    assert "drawn through the section ends" in capsys.readouterr().err
    rec.unlink()
    # the estimate and its recording moved to another folder together: found beside it
    moved = tmp_path / "moved"
    moved.mkdir()
    write_table(moved / rec.name, ["t", "roll", "pitch", "tension_1"],
                [[*r, 1.0 + 5 * r[0]] for r in small_robot_recording_rows()])  # fmt: skip
    est.rename(moved / est.name)
    assert main(["plot", str(moved / est.name), "-o", str(tmp_path / "moved.png")]) == 0
    assert "(its first line): its backbone" in capsys.readouterr().err
    (moved / est.name).rename(est)
    assert main(["plot", str(est), "-o", str(tmp_path / "gone.png")]) == 0
    assert "drawn through the section ends" in capsys.readouterr().err


def _recorded_options(est: Path) -> dict[str, object]:
    """The options line of the estimate file ``est``, read as TOML."""
    import tomllib

    line = next(ln for ln in est.read_text().splitlines() if ln.startswith("# options ="))
    return dict(tomllib.loads(line[2:])["options"])


def test_a_tendon_estimates_options_line_records_only_the_options_its_model_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon robot's estimate file records no option of the constant-curvature models
    (the formulation, their noise terms, the IMU error and own-acceleration switches:
    the tendon model has its own), and records the tensions and the noise it takes;
    ``--config EST.csv`` repeats the run and its record. ``--formulation paper`` on a
    tendon robot (one section with its IMU at the tip, which the paper's model takes
    otherwise) is refused in one line, nothing written."""
    meas, tensions, robot, est = _small_robot_estimate(tmp_path)
    recorded = _recorded_options(est)
    for key in ("formulation", "model-error-floor-deg", "reading-bias-deg", "accel-psd",
                "estimate-accel-bias", "own-acceleration", "imu-twist"):  # fmt: skip
        assert key not in recorded, key
    assert recorded["inputs"] == str(tensions) and recorded["robot"] == str(robot)
    for key in ("estimate-tension-gain", "noise-deg", "model-error-deg", "drift-reset"):
        assert key in recorded, key
    again = tmp_path / "again.csv"
    assert main(["estimate", str(meas), "--config", str(est), "-o", str(again)]) == 0
    assert _recorded_options(again) == recorded
    np.testing.assert_array_equal(read_state_table(again).values, read_state_table(est).values)
    capsys.readouterr()
    paper = tmp_path / "paper.csv"
    argv = ["estimate", str(meas), "--robot", str(robot), "--inputs", str(tensions),
            "--formulation", "paper", "--method", "ekf", "-o", str(paper)]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (
        "continuum-mhe: error: --formulation paper is not available for a tendon robot (a "
        "[backbone] robot file): it is a constant-curvature robot's model; a tendon robot's "
        "is its mechanics model (leave --formulation out)"
    )
    assert not paper.exists()


def test_evaluate_gives_the_tip_force_error_and_keeps_it_out_of_the_srmse(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tendon estimate whose tip force is off by (0.03, 0.04, 0) N and whose tip is off
    by 1 mm in x: the force's rms error is 0.05 N, and the SRMSE (m + rad) is 0.001."""
    from continuum_mhe.evaluation.metrics import compute_metrics

    names = ["x", "y", "z", "psi_1", "fx", "fy", "fz"]
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(20, len(names)))
    est = truth + [0.001, 0.0, 0.0, 0.0, 0.03, 0.04, 0.0]
    m = compute_metrics(est, truth, 0.2, names)
    assert m.tip_force_rms_n == pytest.approx(0.05, rel=1e-12)
    assert m.srmse == pytest.approx(0.001, rel=1e-9)
    assert compute_metrics(est[:, :4], truth[:, :4], 0.2, names[:4]).tip_force_rms_n is None
    t = np.arange(20) * 0.02
    write_table(tmp_path / "e.csv", ["t", *names], np.column_stack([t, est]))
    write_table(tmp_path / "t.csv", ["t", *names], np.column_stack([t, truth]))
    assert main(["evaluate", str(tmp_path / "e.csv"), str(tmp_path / "t.csv")]) == 0
    out = capsys.readouterr().out
    assert "tip force error      rms 0.0500 N (RMSE fx, fy, fz 0.0300, 0.0400, 0.0000 N)" in out
    assert "SRMSE                0.0010 (sum of the RMSEs of x, y, z, psi_1, m + rad)" in out


@pytest.mark.parametrize(
    ("rows", "columns", "message"),
    [
        ([[0.0, 1.0], [0.1, -0.5]], ["t", "tension_1"], "tension_1 = -0.5 N is negative"),
        ([[0.0, 1.0, 1.0], [0.1, 1.0, 1.0]], ["t", "tension_1", "tension_2"],
         "line 1: tension_2 not the robot's: expected the columns t,tension_1"),
        ([[0.0, 1.0], [0.1, 1.0]], ["t", "tension_2"],  # the one missing is named
         "line 1: tension_1 missing; tension_2 not the robot's: expected the columns"),
        ([[0.0, 1.0], [0.1, 1.0]], ["t", "Tension_1 (N)"],  # as the file spells it
         "line 1: tension_1 missing; Tension_1 (N) not the robot's: expected the columns"),
        # the row the recording runs past named by its line: the last, or the first
        ([[0.0, 1.0], [0.05, 1.0]], ["t", "tension_1"],
         "line 3: the tensions cover t = 0 to 0.05 s, but a sample of"),
        ([[0.02, 1.0], [0.2, 1.0]], ["t", "tension_1"],
         "line 2: the tensions cover t = 0.02 to 0.2 s, but a sample of"),
        # milliseconds in t: the 0.1 s recording lies within the first two rows, and would
        # be estimated on tensions held at their first values
        ([[0.0, 1.0], [20.0, 1.1], [40.0, 1.2], [60.0, 1.3], [80.0, 1.4], [100.0, 1.5]],
         ["t", "tension_1"], "its t spans 100 s in steps of 20 s, the recording 0.1 s: if t is "
         "in milliseconds, name the column t_ms"),
        # milliseconds at 2 kHz: rows 0.5 apart, which read in milliseconds cover the
        # recording
        ([[0.5 * i, 1.0 + 0.001 * i] for i in range(201)], ["t", "tension_1"],
         "its t spans 100 s in steps of 0.5 s, the recording 0.1 s: if t is in "
         "milliseconds, name the column t_ms"),
        # microseconds in t
        ([[0.0, 1.0], [20000.0, 1.1], [40000.0, 1.2], [60000.0, 1.3], [80000.0, 1.4],
          [100000.0, 1.5]], ["t", "tension_1"], "name the column t_ms (it is read in "
         "seconds; microseconds: divide them by 1000 first)"),
        # microseconds in t_ms: the column is already t_ms
        ([[0.0, 1.0], [20000.0, 1.1], [40000.0, 1.2], [60000.0, 1.3], [80000.0, 1.4],
          [100000.0, 1.5]], ["t_ms", "tension_1"], "its t_ms spans 100 s in steps of 20 s, "
         "the recording 0.1 s: if t_ms is in microseconds, give milliseconds; if it is in "
         "milliseconds, cut the file"),
        ([[0.0, 1.0], [0.05, "nan"], [0.1, 1.5]], ["t", "tension_1"],
         "line 3: column tension_1 is nan (estimate --skip-bad (skip_bad=True in Python) "
         "leaves the row out and interpolates across it; live, plot and view need the row "
         "fixed or removed)"),
        ([[0.0, 1.0], [0.05, ""], [0.1, 1.5]], ["t", "tension_1"],
         "line 3: column tension_1 is empty (estimate --skip-bad (skip_bad=True in Python) "
         "leaves the row out and interpolates across it; live, plot and view need the row "
         "fixed or removed)"),
    ],
)  # fmt: skip
def test_bad_tensions_are_one_line_errors_and_nothing_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], rows: list[list[object]],
    columns: list[str], message: str,
) -> None:  # fmt: skip
    meas, tensions = small_robot_recording(tmp_path)
    write_text_table(tensions, columns, rows)
    _assert_refused_in_one_line(tmp_path, capsys, meas, tensions, message)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "line 1: file is empty, expected a header such as t,tension_1 (or t_ms,...)"),
        ("0,1.0\n0.1,1.2\n", "line 1: no header line; the first line is data. Add a header "
         "such as t,tension_1 (or t_ms,...)"),
        # a column without a name is said by its place, not as an empty name
        ("t,,tension_1\n0,,1.0\n0.1,,1.2\n", "line 1: column 2 has no name (a separator too "
         "many?): expected the columns t,tension_1"),
        (",tension_1\n0,1.0\n0.1,1.2\n", "line 1: t missing; column 1 has no name: expected "
         "the columns t,tension_1"),
    ],
)  # fmt: skip
def test_a_tensions_file_without_a_header_is_told_the_tensions_header(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    """An empty or header-less tensions file is told the header a tensions file needs
    (not a measurement file's)."""
    meas, tensions = small_robot_recording(tmp_path)
    tensions.write_text(text)
    _assert_refused_in_one_line(tmp_path, capsys, meas, tensions, message)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        # a misspelt column named, not only the one it should have been
        ("t,tenson_1\n0,1.0\n0.1,1.5\n", "line 1: tension_1 missing; tenson_1 not the "
         "robot's: expected the columns t,tension_1"),
        # a separator too many in the header, not a row too short
        ("t,,tension_1\n0,1.0\n0.1,1.5\n", "line 1: column 2 has no name (a separator too "
         "many?): expected the columns t,tension_1"),
        # pandas' index before the columns, written without a name
        (",t,tension_1\n0,0,1.0\n1,0.1,1.5\n", "line 1: column 1 has no name (an index, as "
         "pandas writes one? remove it: to_csv(..., index=False)): expected the columns "
         "t,tension_1"),
        # a column of another name beside all the tension columns: no IMU's readings,
        # so a tensions file's, not a recording's whose other columns are left out
        ("t,tension_1,foo\n0,1.0,2\n0.1,1.5,2\n", "line 1: foo not the robot's: expected "
         "the columns t,tension_1 (one per [[tendon]]"),
    ],
)  # fmt: skip
def test_plot_and_view_read_a_tensions_file_as_estimate_does(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, message: str
) -> None:
    """``plot`` and ``view`` with ``--inputs`` refuse a bad tensions header in the line
    ``estimate --inputs`` gives it (one reader: a recording's other columns are left out
    only for a recording, with an IMU's readings and all the robot's tension columns),
    exit 2, nothing written; tensions that end before the estimate are said with the
    estimate's name, as estimate names its recording."""
    meas, tensions, robot, est = _small_robot_estimate(tmp_path)
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    fig, saved = tmp_path / "f.png", tmp_path / "f.rrd"
    lines = []
    for argv in (
        ["estimate", str(meas), "--robot", str(robot), "-o", str(tmp_path / "e2.csv")],
        ["plot", str(est), "--robot", str(robot), "-o", str(fig)],
        ["view", str(est), "--robot", str(robot), "--save", str(saved)],
    ):
        capsys.readouterr()
        assert main([*argv, "--inputs", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"error: {bad}: {message}" in err[0], err
        lines.append(err[0])
    assert len(set(lines)) == 1
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".png", ".rrd")) == []
    assert not (tmp_path / "e2.csv").exists()
    # tensions that end before the estimate: the estimate named, as estimate names its
    # recording
    bad.write_text("t,tension_1\n0,1.0\n0.05,1.2\n")
    for argv in (
        ["plot", str(est), "--robot", str(robot), "-o", str(fig)],
        ["view", str(est), "--robot", str(robot), "--save", str(saved)],
    ):
        assert main([*argv, "--inputs", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"but a sample of {est} is at t = " in err[0], err
        assert "the tensions must cover the recording" in err[0]


def test_a_recordings_other_columns_are_left_out_and_a_tensions_files_refused(
    tmp_path: Path,
) -> None:
    """The tensions of ``plot`` and ``view`` (``read_drawn_tensions``): a recording (an
    IMU's readings beside the tension columns) has its other columns left out, a
    temperature's too; a tensions file with that column is refused as ``estimate
    --inputs`` refuses it."""
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.tensions import read_drawn_tensions

    robot = read_robot(small_robot(tmp_path))
    rec, file = tmp_path / "rec.csv", tmp_path / "file.csv"
    write_text_table(rec, ["t", "roll", "pitch", "tension_1", "temp_c"],
                     [[0.0, 0.0, 0.0, 1.0, 20.0], [0.1, 0.0, 0.0, 1.5, 21.0]])  # fmt: skip
    table, _ = read_drawn_tensions(rec, robot)
    np.testing.assert_array_equal(table.values, [[1.0], [1.5]])
    write_text_table(file, ["t", "tension_1", "temp_c"], [[0.0, 1.0, 20.0], [0.1, 1.5, 21.0]])
    with pytest.raises(InputError, match=r"line 1: temp_c not the robot's: expected the colu"):
        read_drawn_tensions(file, robot)
    with pytest.raises(InputError, match=r"line 1: temp_c not the robot's: expected the colu"):
        read_tensions(file, 1)  # as estimate --inputs reads it


def _assert_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], meas: Path, tensions: Path, message: str
) -> None:
    """``estimate`` of ``meas`` with ``tensions``: exit 2, one line naming the tensions
    file with ``message``, nothing written."""
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(small_robot(tmp_path)), "--inputs",
            str(tensions), "-o", str(out), "--method", "ekf"]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and str(tensions) in err[0]
    assert not out.exists()


#: Tension rows 0.0045 and 0.0055 s apart in turn (uneven: the noise estimate grids
#: them) over the recording of :func:`small_robot_recording`, 0 to 0.1 s.
_UNEVEN_TENSION_ROWS = [[round(0.005 * i + 0.0005 * (i % 2), 4), 1 + 0.01 * i] for i in range(21)]


def test_one_tension_row_far_after_the_others_is_named_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A row 1e9 s after the others (a logger's clock that jumped) is refused at once in
    one line naming its line and the jump, not gridded over the whole span (which asks
    for hundreds of GiB)."""
    meas, tensions = small_robot_recording(tmp_path)
    write_text_table(tensions, ["t", "tension_1"], [*_UNEVEN_TENSION_ROWS, [1e9, 1.2]])
    message = (
        "line 23: its t jumps by 1e+09 s from the row before (0.1 to 1e+09 s; the rows "
        "step by 0.0055 s): a logger's clock that jumped? Cut the file to the recording's "
        "times"
    )
    _assert_refused_in_one_line(tmp_path, capsys, meas, tensions, message)


def test_one_tension_row_far_before_the_recording_is_left_out(tmp_path: Path) -> None:
    """A first row stamped 1e9 s before the others (a logger's clock not yet set) is
    not one the recording uses: the estimate is written from the other rows' tensions."""
    meas, tensions = small_robot_recording(tmp_path)
    write_text_table(tensions, ["t", "tension_1"], [[-1e9, 0.0], *_UNEVEN_TENSION_ROWS])
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(small_robot(tmp_path)), "--inputs",
            str(tensions), "-o", str(out), "--method", "ekf"]  # fmt: skip
    assert main(argv) == 0
    assert len(read_state_table(out).t) == len(small_robot_recording_rows())


def test_tensions_at_a_slow_rate_in_seconds_are_read(tmp_path: Path) -> None:
    """A tensions file that spans the recording with a second or more between rows
    (tensions 1 s apart beside a 50 Hz recording) is no millisecond file: read in
    seconds and interpolated, so the estimates are those of the same tensions given at
    every sample's time (a held or ramped load given by a few rows is said nothing of:
    the tensions are linear)."""
    meas, tensions = small_robot_recording(tmp_path)
    write_table(tensions, ["t", "tension_1"], [[0.0, 1.0], [1.0, 1.5]])
    dense = tmp_path / "dense.csv"
    t = np.arange(6) * 0.02
    write_table(dense, ["t", "tension_1"], [[tk, 1.0 + 0.5 * tk] for tk in t])
    from continuum_mhe.io.tensions import TensionsWarning

    robot = str(small_robot(tmp_path))
    for given, out in ((tensions, tmp_path / "e.csv"), (dense, tmp_path / "d.csv")):
        argv = ["estimate", str(meas), "--robot", robot, "--inputs", str(given), "-o", str(out),
                "--method", "ekf"]  # fmt: skip
        with warnings.catch_warnings():  # linear tensions: no warning of rows far apart
            warnings.simplefilter("error", TensionsWarning)
            assert main(argv) == 0
    slow, every = read_state_table(tmp_path / "e.csv"), read_state_table(tmp_path / "d.csv")
    assert list(slow.status) == list(every.status)
    np.testing.assert_allclose(slow.values, every.values, rtol=0, atol=1e-9)


def test_skip_bad_leaves_out_a_bad_tension_row_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The error of a bad tension names --skip-bad: with it the row is left out (the
    tensions interpolated across it, so the estimate is the one without the row) and
    counted in a warning."""
    meas, tensions = small_robot_recording(tmp_path)
    robot = str(small_robot(tmp_path))
    write_table(tensions, ["t", "tension_1"], [[0.0, 1.0], [0.1, 1.5]])
    clean = tmp_path / "clean.csv"
    argv = ["estimate", str(meas), "--robot", robot, "--inputs", str(tensions), "-o"]
    assert main([*argv, str(clean)]) == 0
    write_text_table(tensions, ["t", "tension_1"], [[0.0, 1.0], [0.05, "nan"], [0.1, 1.5]])
    skipped = tmp_path / "skipped.csv"
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main([*argv, str(skipped), "--skip-bad"]) == 0
    said = [str(w.message) for w in seen if w.category is DropoutWarning]
    assert said == [f"{tensions}: 1 tension row(s) with a bad value or time left out (--skip-bad; "
                    "first: line 3: column tension_1 is nan): the tensions are interpolated "
                    "across them"]  # fmt: skip
    a, b = read_state_table(clean), read_state_table(skipped)
    np.testing.assert_allclose(b.column("fx"), a.column("fx"), rtol=0, atol=1e-12)


def test_tensions_of_inputs_beside_the_recordings_own_are_said_to_win(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording with its own tension columns and --inputs: the --inputs tensions are
    used, and a warning says so and how far the two differ (or that they are the same);
    without --inputs the recording's own are used, with no warning."""
    meas, tensions = small_robot_recording(tmp_path)
    header, *rows = meas.read_text().splitlines()
    both = tmp_path / "both.csv"  # its own tensions, not those of --inputs
    both.write_text("\n".join([f"{header},tension_1", *(f"{r},9.0" for r in rows)]) + "\n")
    argv = ["estimate", str(both), "--robot", str(small_robot(tmp_path)), "-o"]
    said = []
    for extra in (["--inputs", str(tensions)], []):
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            assert main([*argv, str(tmp_path / f"e{len(extra)}.csv"), *extra]) == 0
        said.append([str(w.message) for w in seen if w.category is OptionWarning])
    assert said == [[f"{both}: the recording carries tension columns, but the tensions of "
                     f"--inputs {tensions} are the ones used (they differ by up to 8 N)"],
                    []]  # fmt: skip
    same = tmp_path / "same.csv"  # its own columns, the tensions of --inputs at its times
    same.write_text("\n".join([f"{header},tension_1",
                               *(f"{r},{1.0 + 5 * float(r.split(',')[0])!r}" for r in rows)])
                    + "\n")  # fmt: skip
    with pytest.warns(OptionWarning, match=r"are the ones used \(the same tensions\)$"):
        assert main(["estimate", str(same), "--robot", str(small_robot(tmp_path)), "-o",
                     str(tmp_path / "s.csv"), "--inputs", str(tensions)]) == 0  # fmt: skip
    own, given = (read_state_table(tmp_path / f"e{k}.csv").column("fz") for k in (0, 2))
    assert not np.allclose(own, given)  # the files' tensions differ, and so do the estimates


def test_a_recordings_tension_columns_unused_by_a_robot_without_tendons_are_said(
    tmp_path: Path,
) -> None:
    """A tendon robot's recording (its own tension columns, as ``live --record`` writes
    them) estimated with a robot file without tendons: the estimate runs, and a warning
    names the columns it leaves out (``--inputs`` on such a robot is refused)."""
    meas, _ = small_robot_recording(tmp_path)
    header, *rows = meas.read_text().splitlines()
    rec = tmp_path / "rec.csv"
    rec.write_text("\n".join([f"{header},tension_1", *(f"{r},2.0" for r in rows)]) + "\n")
    plain = tmp_path / "plain.toml"
    plain.write_text("[[section]]\nlength = 0.2\ntheta_max = 3.0\n[[imu]]\nsection = 1\n")
    out = tmp_path / "e.csv"
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["estimate", str(rec), "--robot", str(plain), "--method", "ekf",
                     "-o", str(out)]) == 0  # fmt: skip
    said = [str(w.message) for w in seen if w.category is OptionWarning]
    assert said == [f"{rec}: its column tension_1 is not used: the robot ({plain}) has no "
                    "[[tendon]] (a tendon robot's file, with [backbone] and its [[tendon]]s, "
                    "takes them)"]  # fmt: skip
    assert out.exists()
    # without --robot: the command line's robot described; bad input: its one line alone
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert main(["estimate", str(rec), "--method", "ekf", "-o", str(tmp_path / "d.csv")]) == 0
        assert main(["estimate", str(rec), "--robot", "two-section", "-o",
                     str(tmp_path / "two.csv")]) == 2  # fmt: skip
    said = [str(w.message) for w in seen if w.category is OptionWarning]
    assert said == [f"{rec}: its column tension_1 is not used: the robot (1 section (0.2 m), "
                    "IMUs at 1@1, z-up) has no [[tendon]] (a tendon robot's file, with "
                    "[backbone] and its [[tendon]]s, takes them)"]  # fmt: skip


def test_a_tendon_robot_needs_its_tensions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    meas, _ = small_robot_recording(tmp_path)
    out = tmp_path / "e.csv"
    argv = ["estimate", str(meas), "--robot", str(small_robot(tmp_path)), "-o", str(out)]
    assert main(argv) == 2
    assert "give their tensions with --inputs" in capsys.readouterr().err
    assert not out.exists()


def test_a_missing_recording_is_said_before_the_tensions_it_lacks(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording name with no file behind it (a typo), a folder that is not a ROS 2
    bag, or a bag's metadata file, is the recording's fault: said as such, not as
    tensions that a pipe or the recording's columns do not carry."""
    robot = str(small_robot(tmp_path))
    out = tmp_path / "e.csv"
    missing = tmp_path / "no_such_run.csv"
    assert main(["estimate", str(missing), "--robot", robot, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{missing}: no such file" in err
    assert "pipe" not in err and "tensions" not in err
    folder = tmp_path / "runs"
    folder.mkdir()
    assert main(["estimate", str(folder), "--robot", robot, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{folder}: is a directory without metadata.yaml" in err
    assert "pipe" not in err
    # a ROS 2 bag's metadata file given for its folder: the bag's folder named, not
    # tensions asked of it as of a CSV recording's columns
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information:\n  version: 5\n")
    metadata = folder / "metadata.yaml"
    assert main(["estimate", str(metadata), "--robot", robot, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"continuum-mhe: error: {metadata}: the metadata file of a ROS 2 bag: give the "
        f"bag's folder, {folder}"
    ], err
    assert not out.exists()


def test_a_recordings_column_without_a_name_is_left_to_its_imu_reader(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording that carries its tensions beside its IMU's columns and a column
    without a name (a separator too many, values in it) gives the estimates the same
    recording gives without that column: the IMU reader leaves such a column out, and
    the tensions reader, which reads the tension columns alone there, does too (it
    refused the recording with a tensions file's expected columns, t,tension_1); plot
    draws its estimate with them."""
    robot = str(small_robot(tmp_path))
    rows = small_robot_recording_rows()
    plain, blank = tmp_path / "plain.csv", tmp_path / "blank.csv"
    plain.write_text(
        "t,roll,pitch,tension_1\n" + "".join(f"{t},{r},{p},{1 + 5 * t}\n" for t, r, p in rows)
    )
    blank.write_text(
        "t,roll,,pitch,tension_1\n" + "".join(f"{t},{r},7,{p},{1 + 5 * t}\n" for t, r, p in rows)
    )
    outs = []
    for rec in (plain, blank):
        out = tmp_path / f"e_{rec.stem}.csv"
        argv = ["estimate", str(rec), "--robot", robot, "-o", str(out), "--method", "ekf"]
        assert main(argv) == 0, capsys.readouterr().err
        outs.append(read_state_table(str(out)))
    assert outs[0].names == outs[1].names
    np.testing.assert_array_equal(outs[0].values, outs[1].values)
    # plot draws it with the tensions of the recording its first line names, as read
    assert main(["plot", str(tmp_path / "e_blank.csv"), "-o", str(tmp_path / "f.png")]) == 0
    assert "section ends" not in capsys.readouterr().err


def test_own_tension_columns_from_standard_input_are_said_unread(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A recording read from standard input (or a pipe) is read once, after the
    tensions: its own tension columns are not read, and the error says so instead of
    asking for the columns it has."""
    meas, _ = small_robot_recording(tmp_path)
    lines = meas.read_text().splitlines()
    header, rows = lines[0], lines[1:]
    own = tmp_path / "own.csv"  # the recording with its tension column
    own.write_text("\n".join([f"{header},tension_1", *(f"{r},1.0" for r in rows)]) + "\n")
    robot = str(small_robot(tmp_path))
    out = tmp_path / "e.csv"
    assert main(["estimate", str(own), "--robot", robot, "-o", str(out)]) == 0  # by name
    out.unlink()
    with own.open() as stdin:
        monkeypatch.setattr(sys, "stdin", stdin)
        assert main(["estimate", "-", "--robot", robot, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "from standard input or a pipe they are not read" in err
    assert not out.exists()


def test_tensions_interpolate_linearly(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    rows = [[0.0, 1.0, 0.0], [1.0, 3.0, 0.0], [2.0, 7.0, 0.0]]
    write_table(path, ["t", "tension_1", "tension_2"], rows)
    tensions = read_tensions(path, 2)
    tau, rate, acceleration = tensions.at(0.25)
    np.testing.assert_allclose(tau, [1.5, 0.0])
    # central differences, one-sided of second order at the ends of a file slower than
    # the IMUs: exact for the quadratic 1 + t + t^2, rates 1, 3, 5 N/s, their rate 2 N/s^2
    np.testing.assert_allclose(rate, [1.5, 0.0])
    np.testing.assert_allclose(acceleration, [2.0, 0.0])


def test_tensions_stamped_in_milliseconds_are_said_and_read_as_t_ms(tmp_path: Path) -> None:
    """A tensions file whose t is in milliseconds (0 to 80 in steps of 20 for a 50 Hz
    log), read in seconds, would give an 8 s recording the first rows' tensions, its rows
    86 mm off and ok: it is said, with the fix; as t_ms it reads."""
    from continuum_mhe.io.csv_files import UnitWarning

    rows = [[20.0 * i, 1.0 + i, 0.0] for i in range(5)]
    path = tmp_path / "ms.csv"
    write_table(path, ["t", "tension_1", "tension_2"], rows)
    with pytest.warns(
        UnitWarning, match="median of 20 s per sample; t is read in seconds: if it is in milli"
    ):
        read_tensions(path, 2)
    write_table(path, ["t_ms", "tension_1", "tension_2"], rows)
    np.testing.assert_allclose(read_tensions(path, 2).at(0.03)[0], [2.5, 0.0])


def test_one_imu_does_not_determine_the_tip_force() -> None:
    """Two of the tip force's three components per IMU (its gravity direction): one IMU,
    raw or tilt, leaves the shape unobservable; two determine it."""
    from continuum_mhe.errors import UnobservableShapeWarning
    from continuum_mhe.estimators import CasadiExtendedKalmanFilter

    one = one_section_robot(Tendon(0, 0.0, 0.01))
    two = Robot(one.sections, (ImuPlacement(0, 0.5), ImuPlacement(0, 1.0)), "z-up", BACKBONE,
                one.tendons)  # fmt: skip
    for model in ("tilt", "direct"):
        f1 = TendonFormulation(robot=one, imu_model=model)  # type: ignore[arg-type]
        assert not f1.imus_determine_shape((0,))
        assert TendonFormulation(robot=two, imu_model=model).imus_determine_shape((0, 1))  # type: ignore[arg-type]
    with pytest.warns(UnobservableShapeWarning, match="two per IMU"):
        CasadiExtendedKalmanFilter(TendonFormulation(robot=one))
