"""The usual user mistakes get one line with the likely cause; bugs are not shown as
user errors. Here: how a mistake is said (exit 2 and one line; a bug's exit 70), and the
command line's options: values out of range, options that would do nothing with the rest
of the command line (an MHE option with a filter, --mount-rpy on tilt input, a noise
option a tendon robot ignores), options files and their lines, robot and file names
given empty or in each other's place, outputs in missing folders. The mistakes in
recordings, in truths and in library calls are in test_user_mistakes_readings.py,
test_user_mistakes_truth.py and test_user_mistakes_library.py."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import simulated
from numpy.testing import assert_allclose

import continuum_mhe.cli.app as cli
import continuum_mhe.cli.check_robot as check_robot
from continuum_mhe import simulate
from continuum_mhe.cli import main
from continuum_mhe.cli.options import OPTION_RANGES
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.io.estimate_csv import write_table
from continuum_mhe.io.input_options import OptionWarning
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import RobotSettings
from continuum_mhe.simulation.scenarios import simulate_robot

DOCS = Path(__file__).resolve().parents[1] / "docs" / "reliability.md"


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
    assert "the demo simulates the motions of a constant-curvature robot" in err[0]
    assert "continuum-mhe rod tendon, estimated with --inputs" in err[0]
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


def test_a_broken_options_line_is_said_with_its_line(tmp_path, capsys) -> None:
    """An estimate whose ``# options`` line is cut: ``evaluate`` warns that the options
    it records are not read (it takes the defaults' robot), and ``--config`` of it names
    the line."""
    m, t = simulated(tmp_path, "a")
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
    m, _ = simulated(tmp_path, "a")
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
    m, _ = simulated(tmp_path, "a")
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


def test_a_multi_section_scenario_on_one_section_names_the_ones_it_takes(tmp_path, capsys) -> None:
    """``simulate spatial`` without ``--robot``: one line that names ``--robot`` and the
    scenarios a one-section robot takes, exit 2, nothing written."""
    out = tmp_path / "m.csv"
    assert main(["simulate", "spatial", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is for a robot of two or more sections (--robot)" in err[0], err
    assert "choose from paper3d, planar-overbend, rest, straight" in err[0]
    assert not out.exists()


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
