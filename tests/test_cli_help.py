"""The commands' help and option values: help in plain text, the shipped robots it
names, the options measured worse, the options --robot replaces; values out of range
in one line; simulate's notes on the robot's theta_max and mount_rpy; tables as wide as
a pipe takes."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_helpers import good_rows, meas_csv, write_file

from continuum_mhe.cli import main


def test_invalid_option_values_are_one_line_errors(tmp_path, capsys):
    meas = meas_csv(tmp_path, good_rows(5))
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


def test_simulate_rejects_absurd_sizes_and_seeds(tmp_path, capsys):
    out = str(tmp_path / "s.csv")
    assert main(["simulate", "paper3d", "-o", out, "--dt", "1e-9"]) == 2
    assert "--dt 1e-09 is outside its valid range [0.0001, 10] s" in capsys.readouterr().err
    assert main(["simulate", "paper3d", "-o", out, "--seed", "-1"]) == 2
    assert "--seed -1 is outside its valid range" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


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


def test_simulate_says_where_the_motion_bends_past_theta_max(tmp_path, capsys):
    """paper3d bends a section to 1.44 rad: on a robot whose theta_max is 1 the note
    says so (its estimates there are at-bound); within the bound, nothing."""
    robot = write_file(tmp_path / "r.toml", "[[section]]\nlength = 0.05\ntheta_max = 1.0\n"
                   "[[imu]]\nsection = 1\n")  # fmt: skip
    assert main(["simulate", "paper3d", "--robot", str(robot), "-o", str(tmp_path / "a.csv")]) == 0
    err = capsys.readouterr().err
    assert (
        "bends section 1 to 1.44 rad, beyond its theta_max 1: estimates there are at-bound" in err
    )
    assert main(["simulate", "paper3d", "-o", str(tmp_path / "b.csv")]) == 0
    assert "theta_max" not in capsys.readouterr().err


def test_a_theta_max_below_its_least_is_named_as_the_option(tmp_path, capsys) -> None:
    """``--theta-max 0.001`` (below the least bend bound a robot file takes, 0.01 rad):
    one line naming the option and the range it has, as every numeric option's."""
    rows = good_rows(10)
    meas, est = meas_csv(tmp_path, rows), tmp_path / "e.csv"
    assert main(["estimate", str(meas), "-o", str(est), "--theta-max", "0.001"]) == 2
    assert capsys.readouterr().err == (
        "continuum-mhe: error: --theta-max 0.001 is outside its valid range [0.01, 3.14159) "
        "rad: a section that bends no further is no bending section; give its largest bend\n"
    )
    assert not est.exists()
