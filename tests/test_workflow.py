"""The user's walk from a recording to a figure: ``plot`` of any estimate file, the
backbone's points, ``calibrate --write-robot``, options files, outputs that are never
silently replaced, an interrupted ``estimate`` that keeps its rows, and the shipped rod
recording evaluated as shipped."""

from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import figures_drawn_small

from continuum_mhe.cli import main
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.pcc import backbone_points
from continuum_mhe.model.robot import Robot

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"
TWO_SECTION = DATA / "robots" / "two_section.toml"


# --- the backbone's points --------------------------------------------------------------
def _arc_point(theta: float, phi: float, s: float, length: float) -> np.ndarray:
    """A point at arc length s of one constant-curvature section (written out here)."""
    k = theta / length  # curvature
    if abs(k) < 1e-12:
        return np.array([0.0, 0.0, s])
    r = (1 - math.cos(k * s)) / k
    return np.array([-r * math.cos(phi), -r * math.sin(phi), math.sin(k * s) / k])


def test_backbone_points_of_one_section_lie_on_its_arc() -> None:
    robot = Robot.single(0.2)
    s = np.array([0.0, 0.05, 0.1234, 0.2])
    for theta, phi in ((0.0, 0.0), (0.7, 0.3), (2.0, -2.5)):
        pts = backbone_points(robot, theta, phi, s)
        expected = np.array([_arc_point(theta, phi, v, 0.2) for v in s])
        np.testing.assert_allclose(pts, expected, atol=1e-12)


def test_backbone_points_move_at_unit_speed_and_end_at_the_tip() -> None:
    """|dp/ds| = 1 along an inextensible backbone (central differences), and the last
    point of each section is its end column in an estimate's sense (pose_at)."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.pcc import pose_at

    robot = read_robot(TWO_SECTION)
    theta, phi = np.array([1.1, 0.6]), np.array([0.4, -1.9])
    s = np.linspace(0.01, robot.length - 0.01, 23)
    h = 1e-6
    speed = np.linalg.norm(
        backbone_points(robot, theta, phi, s + h) - backbone_points(robot, theta, phi, s - h),
        axis=1,
    ) / (2 * h)
    np.testing.assert_allclose(speed, 1.0, atol=1e-6)
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1)
    ends = backbone_points(robot, theta, phi, np.cumsum(robot.lengths))
    for k in range(2):
        np.testing.assert_allclose(ends[k], pose_at(bends, robot.lengths, k)[1], atol=1e-12)
    # a batch of shapes gives each shape's points
    batch = backbone_points(robot, np.stack([theta, 0 * theta]), np.stack([phi, phi]), s[:3])
    assert batch.shape == (2, 3, 3)
    np.testing.assert_allclose(batch[1], [[0, 0, v] for v in s[:3]], atol=1e-12)
    with pytest.raises(ValueError, match="outside the backbone"):
        backbone_points(robot, theta, phi, [robot.length + 0.01])


# --- plot ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def two_section_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A two-section recording, its truth and an EKF estimate."""
    d = tmp_path_factory.mktemp("two")
    assert main(["simulate", "spatial", "--robot", str(TWO_SECTION), "--duration", "3",
                 "-o", str(d / "m.csv"), "--truth", str(d / "t.csv")]) == 0  # fmt: skip
    assert main(["estimate", str(d / "m.csv"), "--robot", str(TWO_SECTION), "--method", "ekf",
                 "-o", str(d / "e.csv")]) == 0  # fmt: skip
    return d


def test_lengths_from_an_estimate_are_its_robot_s(two_section_run: Path) -> None:
    from continuum_mhe.evaluation.estimate_tables import lengths_from_estimate, tracked_points

    truth = read_state_table(two_section_run / "t.csv")
    np.testing.assert_allclose(lengths_from_estimate(truth), (0.16, 0.14), rtol=1e-9)
    labels = [p.label for p in tracked_points(truth.names)]
    assert labels == ["section 1 end", "tip (section 2 end)"]


@pytest.mark.parametrize("extra", [[], ["--truth", "t.csv"], ["--robot", str(TWO_SECTION)]])
def test_plot_draws_a_two_section_estimate(two_section_run: Path, extra, capsys) -> None:
    out = two_section_run / f"fig{len(extra)}{extra[0][2:] if extra else ''}.png"
    argv = [a if a != "t.csv" else str(two_section_run / "t.csv") for a in extra]
    assert main(["plot", str(two_section_run / "e.csv"), *argv, "-o", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert capsys.readouterr().err.strip() == f"wrote {out}"


def test_plot_draws_a_one_section_estimate_as_pdf(tmp_path: Path) -> None:
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(tmp_path / "m.csv"),
                 "--truth", str(tmp_path / "t.csv")]) == 0  # fmt: skip
    assert main(["estimate", str(tmp_path / "m.csv"), "--method", "ekf",
                 "-o", str(tmp_path / "e.csv")]) == 0  # fmt: skip
    out = tmp_path / "e.pdf"
    assert main(["plot", str(tmp_path / "e.csv"), "--truth", str(tmp_path / "t.csv"),
                 "-o", str(out)]) == 0  # fmt: skip
    assert out.read_bytes()[:5] == b"%PDF-"


def test_plot_draws_a_hanging_robot_hanging(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The backbone's panel of a z-down robot's estimate draws the base's z axis pointing
    down (the robot hangs there as it hangs), with the robot file, from the mounting the
    estimate's options line records, and from standard input; a z-up robot's points up.
    Its z range is what is drawn (an S that stays on its side of the base), not minus
    the robot's reach, which leaves half the panel empty."""
    from continuum_mhe.evaluation import plotting

    drawn: list[bool] = []  # whether each figure's backbone panel has z pointing down
    beyond_base: list[float] = []  # how far each panel's z runs past the base, mm

    def kept(fig, path, formats=("png",)):
        (view,) = [ax for ax in fig.axes if ax.name == "3d"]
        low, high = view.get_zlim()
        drawn.append(bool(low > high))
        beyond_base.append(-min(low, high))  # the base frame's z, drawn up or down
        path.with_suffix(".png").write_bytes(b"")

    monkeypatch.setattr(plotting, "save", kept)
    for mounting in ("z-down", "z-up"):
        robot = tmp_path / f"{mounting}.toml"
        robot.write_text(
            f'mounting = "{mounting}"\n[[section]]\nlength = 0.15\n[[section]]\n'
            "length = 0.12\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
        )
        meas, est = tmp_path / f"m{mounting}.csv", tmp_path / f"e{mounting}.csv"
        assert main(["simulate", "s-curve", "--robot", str(robot), "--duration", "1",
                     "-o", str(meas)]) == 0  # fmt: skip
        assert main(["estimate", str(meas), "--robot", str(robot), "--method", "ekf",
                     "-o", str(est)]) == 0  # fmt: skip
        fig = tmp_path / f"{mounting}.png"
        assert main(["plot", str(est), "--robot", str(robot), "-o", str(fig)]) == 0
        assert main(["plot", str(est), "-o", str(fig), "--overwrite"]) == 0
        with est.open() as piped:
            monkeypatch.setattr("sys.stdin", piped)
            assert main(["plot", "-", "-o", str(fig), "--overwrite"]) == 0
    assert drawn == [True] * 3 + [False] * 3
    assert max(beyond_base) < 0.1 * 270, beyond_base  # the robot: 0.15 + 0.12 m


def test_plot_refuses_a_truth_of_another_robot_and_an_existing_figure(
    two_section_run: Path, tmp_path: Path, capsys
) -> None:
    one = tmp_path / "t1.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(tmp_path / "m1.csv"),
                 "--truth", str(one)]) == 0  # fmt: skip
    capsys.readouterr()
    fig = tmp_path / "f.png"
    assert main(["plot", str(two_section_run / "e.csv"), "--truth", str(one), "-o", str(fig)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "section columns (theta) that an estimate of 2" in err
    assert not fig.exists()
    fig.write_text("mine")
    assert main(["plot", str(two_section_run / "e.csv"), "-o", str(fig)]) == 2
    assert "exists; give --overwrite" in capsys.readouterr().err
    assert fig.read_text() == "mine"
    assert main(["plot", str(two_section_run / "e.csv"), "-o", str(fig), "--overwrite"]) == 0
    assert fig.read_bytes()[:4] == b"\x89PNG"


def test_plot_warns_of_a_robot_file_whose_sections_the_estimate_does_not_fit(
    two_section_run: Path, tmp_path: Path, capsys
) -> None:
    """A robot file of other section lengths (0.3 + 0.3 m for an estimate on 0.16 + 0.14
    m) would draw a backbone that misses the estimate's section ends: said, with both."""
    big = tmp_path / "big.toml"
    big.write_text(TWO_SECTION.read_text().replace("0.16", "0.3").replace("0.14", "0.3"))
    fig = tmp_path / "f.png"
    capsys.readouterr()
    with pytest.MonkeyPatch.context() as m:  # what plot says, not what it draws
        figures_drawn_small(m)
        assert main(["plot", str(two_section_run / "e.csv"), "--robot", str(big),
                     "-o", str(fig)]) == 0  # fmt: skip
    err = capsys.readouterr().err
    assert "fit sections of 0.16, 0.14 m, not the given robot's 0.3, 0.3 m" in err, err
    assert main(["plot", str(two_section_run / "e.csv"), "--robot", str(TWO_SECTION),
                 "-o", str(fig), "--overwrite"]) == 0  # fmt: skip
    assert capsys.readouterr().err.strip() == f"wrote {fig}"


# --- calibrate --write-robot --------------------------------------------------------------
def _rest_recording(path: Path, rpy_deg: tuple[float, float, float], bias: np.ndarray) -> None:
    """A straight, still robot seen by an IMU mounted at ``rpy_deg`` (Z-Y-X: v_tip =
    Rz Ry Rx v_sensor, built with scipy), with noise and a gyro bias."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(3)
    n = 400
    tip_to_sensor = Rotation.from_euler("ZYX", rpy_deg[::-1], degrees=True).inv()
    acc = tip_to_sensor.apply([0.0, 0.0, 9.81]) + rng.normal(0, 0.02, (n, 3))
    gyr = bias + rng.normal(0, 0.001, (n, 3))
    t = np.arange(n) * 0.01
    rows = ["t,ax,ay,az,gx,gy,gz"] + [
        ",".join(f"{v:.6f}" for v in (t[i], *acc[i], *gyr[i])) for i in range(n)
    ]
    path.write_text("\n".join(rows) + "\n")


def test_calibrate_writes_a_robot_file_with_the_known_mounting(tmp_path: Path, capsys) -> None:
    robot = tmp_path / "robot.toml"
    robot.write_text(
        '# my rod: one section\nmounting = "z-up"\n\n[[section]]\nlength = 0.25  # m\n\n'
        "[[imu]]\nsection = 1\nmount_rpy = [0, 0, 30]  # yaw measured by hand\n"
    )
    bias = np.array([0.012, -0.021, 0.004])
    _rest_recording(tmp_path / "rest.csv", (7.0, -12.0, 0.0), bias)
    out = tmp_path / "out.toml"
    assert main(["calibrate", "--from", str(tmp_path / "rest.csv"), "--robot", str(robot),
                 "--write-robot", str(out)]) == 0  # fmt: skip
    assert f"wrote {out}" in capsys.readouterr().err
    from continuum_mhe.io.robot_file import read_robot

    placed = read_robot(out).imus[0]
    assert abs(placed.mount_rpy[0] - 7.0) < 0.3 and abs(placed.mount_rpy[1] + 12.0) < 0.3
    assert placed.mount_rpy[2] == 30.0  # gravity does not show yaw: the file's is kept
    np.testing.assert_allclose(placed.gyro_bias, bias, atol=3e-4)  # 0.001 / sqrt(400) noise
    text = out.read_text()
    assert "# my rod: one section" in text and "length = 0.25  # m" in text
    assert main(["calibrate", "--from", str(tmp_path / "rest.csv"), "--robot", str(robot),
                 "--write-robot", str(out)]) == 2  # fmt: skip
    assert "exists; give --overwrite" in capsys.readouterr().err


def test_a_robot_file_gyro_bias_is_subtracted_from_the_readings() -> None:
    from continuum_mhe.io.input_options import imu_settings_for
    from continuum_mhe.io.raw_imu import RawImuConverter, RawImuSettings
    from continuum_mhe.model.robot import ImuPlacement

    bias = (0.01, -0.02, 0.03)
    raw = RawImuSettings(imu_model="direct")
    conv = RawImuConverter(imu_settings_for(raw, ImuPlacement(0, 1.0, (0, 0, 0), bias)))
    z = conv.convert(0.0, np.array([0.0, 0.0, 9.81]), np.array(bias) + [0.1, 0.0, 0.0])
    np.testing.assert_allclose(z[3:6], [0.1, 0.0, 0.0], atol=1e-15)


# --- options files ------------------------------------------------------------------------
def _options_of(path: Path) -> dict[str, object]:
    line = next(ln for ln in path.read_text().splitlines() if ln.startswith("# options ="))
    return dict(tomllib.loads(line[2:])["options"])


def test_config_file_sets_options_and_the_command_line_overrides(tmp_path: Path) -> None:
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(tmp_path / "m.csv")]) == 0
    cfg = tmp_path / "opts.toml"
    cfg.write_text(
        'method = "ukf"\nhorizon = 12\n[estimate]\ngap-reset = 3.5\n[live]\nbaud = 9600\n'
    )
    out = tmp_path / "e.csv"
    assert main(["estimate", str(tmp_path / "m.csv"), "--config", str(cfg), "--method", "ekf",
                 "-o", str(out)]) == 0  # fmt: skip
    rec = _options_of(out)
    assert rec["method"] == "ekf" and rec["gap-reset"] == 3.5
    assert "horizon" not in rec  # the profile's MHE option did not make the EKF's estimate
    assert "baud" not in rec and "output" not in rec and "config" not in rec
    # the estimate file is an options file: the same options again
    again = tmp_path / "e2.csv"
    assert main(["estimate", str(tmp_path / "m.csv"), "--config", str(out), "-o", str(again)]) == 0
    assert _options_of(again) == rec
    np.testing.assert_array_equal(read_state_table(again).values, read_state_table(out).values)


def test_an_estimate_file_of_another_command_or_folder_is_an_options_file(
    tmp_path: Path, capsys
) -> None:
    """A live recording's estimate records live's port and baud: ``estimate --config``
    with it leaves them out, said in a note (not refused as "baud is not an option of
    estimate"). Its robot file, recorded relative to where live ran, is found beside the
    estimate from another folder. An error in its options line names that line of the
    file (not line 1 for the line under the header comment)."""
    sub = tmp_path / "run"
    sub.mkdir()
    robot = sub / "robot.toml"
    robot.write_text("[[section]]\nlength = 0.25\ntheta_max = 3.0\n[[imu]]\nsection = 1\n")
    meas = tmp_path / "m.csv"
    assert (
        main(["simulate", "paper3d", "--duration", "1", "--length", "0.25", "-o", str(meas)]) == 0
    )
    est = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", str(robot), "-o", str(est)]) == 0
    lines = est.read_text().splitlines(True)
    at = next(i for i, ln in enumerate(lines) if ln.startswith("# options"))
    lines[at] = (  # as live writes it, run from the folder of its robot file
        lines[at].replace(f'robot = "{robot}"', 'robot = "robot.toml"')
        .replace("{", '{port = "/dev/ttyACM0", baud = 115200, ', 1)
    )  # fmt: skip
    live = sub / "live.csv"
    live.write_text("".join(lines))
    capsys.readouterr()
    again = tmp_path / "again.csv"
    assert main(["estimate", str(meas), "--config", str(live), "-o", str(again)]) == 0
    err = capsys.readouterr().err
    assert f"{live}: port, baud (of the command that wrote it) are no option of estimate" in err
    assert _options_of(again)["robot"] == str(robot)
    np.testing.assert_array_equal(read_state_table(again).values, read_state_table(est).values)
    lines[at] = lines[at].replace('method = "mhe"', 'method = "kalman"')
    live.write_text("".join(lines))
    assert main(["estimate", str(meas), "--config", str(live), "-o", str(tmp_path / "x.csv")]) == 2
    assert f"{live}: line {at + 1}: method = 'kalman' is not one of" in capsys.readouterr().err


def test_a_live_estimate_as_options_file_does_not_name_its_recording(tmp_path, capsys) -> None:
    """``live --config`` with a live estimate never writes the new session's raw
    readings over the recording it names: ``--record`` is not recorded, and a file that
    names one (``record = "raw.csv"``) has it left out, said in a note, as a view file
    (``view = "session.rrd"``); an options file of the user's own with ``record`` is
    refused as ``output`` is."""
    from continuum_mhe.cli.app import _parse

    est = tmp_path / "live.csv"
    est.write_text('# options = {port = "/dev/ttyACM0", record = "raw.csv", method = "ekf"}\n'
                   "t,x,y,z,theta,phi,status\n")  # fmt: skip
    args = _parse(["live", "--port", "/dev/null", "--config", str(est), "--record", "new.csv"])
    assert "record" not in args.options_record and args.record == "new.csv"
    args = _parse(["live", "--port", "/dev/null", "--config", str(est)])
    assert args.record is None and args.method == "ekf"
    assert "record names a file of the run that wrote it: left out" in capsys.readouterr().err
    own = tmp_path / "opts.toml"
    own.write_text('record = "raw.csv"\n')
    assert main(["live", "--port", "/dev/null", "--config", str(own)]) == 2
    assert "line 1: record is given on the command line" in capsys.readouterr().err
    # a session drawn to a file (live --view FILE.rrd): left out too; the web view stays
    for view, kept in (("session.rrd", None), ("web", "web")):
        est.write_text(f'# options = {{port = "/dev/ttyACM0", view = "{view}"}}\n'
                       "t,x,y,z,theta,phi,status\n")  # fmt: skip
        args = _parse(["live", "--config", str(est)])
        assert args.view == kept and args.port == "/dev/ttyACM0"
    assert "view names a file of the run that wrote it: left out" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (
            'method = "ekf"\nhorizn = 12\n',
            "line 2: horizn is not an option of estimate; did you mean horizon?",
        ),
        ("zzz = 1\n", "line 1: zzz is not an option of estimate\n"),
        ('method = "ekf"\n"horizn" = 12\n', "line 2: horizn is not an option of estimate"),
        ("['estimate']\nhorizon = 1\n", "line 2: horizon = 1 is outside its valid range"),
        ('method = "kalman"\n', "line 1: method = 'kalman' is not one of mhe, ekf, ukf"),
        ("skip-bad = 1\n", "line 1: skip-bad must be true or false"),
        ('output = "x.csv"\n', "line 1: output is given on the command line"),
        ("method = \n", "opts.toml: "),
        ('[estimat]\nmethod = "ekf"\n', "line 1: [estimat] is not a table of an options file"),
        ('method = "ekf"\n[estimate]\nhorizn = 3\n', "line 3: horizn is not an option of"),
        ("[estimate.noise]\ngyro-std = 0.1\n", "line 1: [estimate.noise] is not a table"),
        ('[[estimate]]\nmethod = "ekf"\n',
         "line 1: [[estimate]]: the estimate options are one table, [estimate]"),
        ("estimate = 5\n", "line 1: estimate = ...: the estimate options are one table"),
        ('[[live]]\nport = "x"\n', "line 1: [[live]]: the live options are one table, [live]"),
        ("live = [1, 2]\n", "line 1: live = ...: the live options are one table, [live]"),
        ("gap-reset = 0.5\ngap_reset = 2\n",
         "line 2: gap_reset is given twice, as gap-reset too (line 1): give it once"),
        ("a = " + "[" * 600 + "]" * 600 + "\n", "opts.toml: nested too deep to be an options"),
    ],
)  # fmt: skip
def test_a_bad_options_file_is_one_line_naming_it(tmp_path: Path, capsys, text, needle) -> None:
    cfg = tmp_path / "opts.toml"
    cfg.write_text(text)
    out = tmp_path / "e.csv"
    assert main(["estimate", "m.csv", "--config", str(cfg), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(cfg) in err and needle in err, err
    assert not out.exists()


def _switches(command: str) -> list[tuple[str, str]]:
    """``(dest, spelling)`` of every on/off switch of ``command`` that an options file
    may set (each spelling of an on/off pair)."""
    import argparse

    from continuum_mhe.cli.app import build_parser
    from continuum_mhe.cli.config import NOT_OPTIONS

    (commands,) = (
        a for a in build_parser(only=command)._actions if isinstance(a, argparse._SubParsersAction)
    )
    kinds = (argparse._StoreTrueAction, argparse._StoreFalseAction, argparse.BooleanOptionalAction)
    return [
        (a.dest, flag)
        for a in commands.choices[command]._actions
        if isinstance(a, kinds) and a.dest not in NOT_OPTIONS
        for flag in a.option_strings
        if flag.startswith("--")
    ]


@pytest.mark.parametrize("command", ["estimate", "live"])
def test_every_switch_replays_from_its_record(tmp_path: Path, command) -> None:
    """Each spelling of each on/off switch of ``estimate`` and ``live``
    (``--no-estimate-gyro-bias`` and ``--estimate-gyro-bias`` alike) is recorded under
    one key with true or false, and ``--config EST.csv`` gives the same parsed option
    and the same record again."""
    from continuum_mhe.cli.app import _parse

    switches = _switches(command)
    assert ("estimate_gyro_bias", "--no-estimate-gyro-bias") in switches
    assert ("branch_check", "--no-branch-check") in switches
    argv = {"estimate": ["estimate", "m.csv", "-o", "e.csv"], "live": ["live", "--port", "p"]}
    for dest, flag in switches:
        given = _parse([*argv[command], flag])
        est = tmp_path / f"{flag[2:]}.csv"
        est.write_text(f"# options = {given.options_record}\nt,x,y,z,theta,phi,status\n")
        again = _parse([*argv[command], "--config", str(est)])
        assert getattr(again, dest) == getattr(given, dest), flag
        assert again.options_record == given.options_record, flag
        assert flag.removeprefix("--no-").removeprefix("--") in _options_of(est), flag


@pytest.mark.parametrize(
    ("line", "dest", "value"),
    [
        ("no-estimate-gyro-bias = false", "estimate_gyro_bias", False),
        ("no-estimate-gyro-bias = true", "estimate_gyro_bias", True),
        ("no-branch-check = false", "branch_check", False),
    ],
)
def test_an_estimate_file_naming_a_switch_by_its_no_spelling_keeps_its_value(
    tmp_path: Path, capsys, line, dest, value
) -> None:
    """An estimate file's options line that names an on/off pair by its ``--no-``
    spelling holds the positive switch's value (``no-estimate-gyro-bias = false``: the
    run was given ``--no-estimate-gyro-bias``); replayed as such, with no note."""
    from continuum_mhe.cli.app import _parse

    est = tmp_path / "old.csv"
    est.write_text(f"# options = {{{line}}}\nt,x,y,z,theta,phi,status\n")
    args = _parse(["estimate", "m.csv", "-o", "e.csv", "--config", str(est)])
    assert getattr(args, dest) is value
    assert "left out" not in capsys.readouterr().err


def test_an_options_file_sets_an_on_off_pair_by_its_positive_name(tmp_path: Path, capsys) -> None:
    """``estimate-gyro-bias = false`` in a TOML file is ``--no-estimate-gyro-bias``; the
    ``--no-`` spelling as a key is one line saying which key to write."""
    from continuum_mhe.cli.app import _parse

    cfg = tmp_path / "opts.toml"
    cfg.write_text("estimate-gyro-bias = false\nbranch-check = true\n")
    args = _parse(["estimate", "m.csv", "-o", "e.csv", "--config", str(cfg)])
    assert (args.estimate_gyro_bias, args.branch_check) == (False, True)
    cfg.write_text("no-estimate-gyro-bias = true\n")
    assert main(["estimate", "m.csv", "--config", str(cfg), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{cfg}: line 1: no-estimate-gyro-bias" in err
    assert "estimate-gyro-bias = false for --no-estimate-gyro-bias" in err


# --- outputs that exist, and an interrupted estimate --------------------------------------
@pytest.mark.parametrize("command", ["estimate", "simulate"])
def test_an_existing_output_is_refused_without_overwrite(tmp_path: Path, capsys, command) -> None:
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    out = tmp_path / "out.csv"
    out.write_text("mine\n")
    argv = {
        "estimate": ["estimate", str(meas), "--method", "ekf", "-o", str(out)],
        "simulate": ["simulate", "paper3d", "--duration", "1", "-o", str(out)],
    }[command]
    capsys.readouterr()
    assert main(argv) == 2
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {out}: exists; give --overwrite to replace it, or another -o\n"
    )
    assert out.read_text() == "mine\n"
    assert main([*argv, "--overwrite"]) == 0
    assert out.read_text() != "mine\n"


def test_overwrite_never_replaces_an_input_of_the_command(tmp_path: Path, capsys) -> None:
    """``-o`` (or ``--write-robot``) naming one of the command's own input files, by any
    path (a link too), with ``--overwrite`` or without: one line naming it, exit 2, the
    file kept."""
    tendon, rod = DATA / "tendon", DATA / "rod2"
    tensions, robot, rest = tmp_path / "ten.csv", tmp_path / "rob.toml", tmp_path / "rest.csv"
    tensions.write_bytes((tendon / "force-29_tensions.csv").read_bytes())
    robot.write_bytes((DATA / "robots" / "two_section.toml").read_bytes())
    rest.write_bytes((rod / "spatial-tendon_rest.csv").read_bytes())
    link = tmp_path / "link.csv"
    link.symlink_to(tensions)
    # an estimate named as a figure (plot's default output is the estimate's name with
    # .png), a truth as one, and a robot file as a benchmark's JSON
    est_png, truth_svg, robot_json = tmp_path / "e.png", tmp_path / "t.svg", tmp_path / "r.json"
    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth",
                 str(tmp_path / "t.csv")]) == 0  # fmt: skip
    truth_svg.write_bytes((tmp_path / "t.csv").read_bytes())
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(tmp_path / "e.csv")]) == 0
    est_png.write_bytes((tmp_path / "e.csv").read_bytes())
    robot_json.write_bytes(robot.read_bytes())
    cases = [
        (["estimate", str(meas), "-o", str(meas)], meas, "the recording"),
        (["estimate", str(tendon / "force-29_raw.csv"), "--robot", "tendon-two-section",
          "--inputs", str(tensions), "-o", str(link)], tensions, "the tensions file --inputs"),
        (["estimate", str(rod / "spatial_tilt.csv"), "--robot", str(robot), "-o", str(robot)],
         robot, "the robot file --robot"),
        (["calibrate", "--from", str(rest), "--robot", "two-section", "--write-robot",
          str(rest)], rest, "the recording --from"),
        (["calibrate", "--from", str(rest), "--robot", str(robot), "--write-robot",
          str(robot)], robot, "the robot file --robot"),
        (["simulate", "paper3d", "--robot", str(robot), "-o", str(robot)], robot,
         "the robot file --robot"),
        (["plot", str(est_png)], est_png, "the estimate"),
        (["plot", str(est_png), "--truth", str(truth_svg), "-o", str(truth_svg)], truth_svg,
         "the truth --truth"),
        (["benchmark", "--robot", str(robot_json), "--json", str(robot_json)], robot_json,
         "the robot file --robot"),
    ]  # fmt: skip
    for argv, kept, what in cases:
        before = kept.read_bytes()
        for extra in ([], ["--overwrite"]):  # without it, not a request for it
            capsys.readouterr()
            assert main([*argv, *extra]) == 2, argv
            err = capsys.readouterr().err
            assert err.count("\n") == 1 and f"refusing to overwrite {what}" in err, err
            assert kept.read_bytes() == before
    # an estimate given as its own options file is read first: a re-run replaces it
    est = tmp_path / "est.csv"
    first = ["estimate", str(rod / "spatial_tilt.csv"), "--robot", "two-section"]
    assert main([*first, "--method", "ekf", "-o", str(est)]) == 0
    assert main([*first, "--config", str(est), "-o", str(est), "--overwrite"]) == 0
    assert 'method = "ekf"' in est.read_text()


def test_an_interrupted_estimate_keeps_its_rows_marked_partial(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    from continuum_mhe.cli import estimate as estimate_command

    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas)]) == 0
    real = estimate_command.make_estimator

    def interrupted_in_block_3(*args, **kwargs):
        est = real(*args, **kwargs)
        run, calls = est.continue_run, []

        def run_then_interrupt(t, z, *more, **options):
            calls.append(1)
            if len(calls) == 3:  # after two blocks of 7 samples
                raise KeyboardInterrupt
            return run(t, z, *more, **options)

        est.continue_run = run_then_interrupt
        return est

    monkeypatch.setattr(estimate_command, "BLOCK", 7)
    monkeypatch.setattr(estimate_command, "make_estimator", interrupted_in_block_3)
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(out)]) == 130
    err = capsys.readouterr().err
    assert "kept the 14 estimates made before the interruption" in err
    assert err.endswith("continuum-mhe: interrupted\n")
    table = read_state_table(out)
    assert len(table.t) == 14 and table.t[-1] == pytest.approx(13 * 0.05)
    assert re.search(r"^# partial = \"interrupted after 14 samples", out.read_text(), re.M)


# --- the shipped rod recording ------------------------------------------------------------
def test_plot_draws_a_truth_with_positions_alone(
    two_section_run: Path, tmp_path: Path, capsys
) -> None:
    """A truth without bend columns (a motion-capture log: the tip alone, or with some
    section ends) is drawn with the points it has: the shipped rod recording as its own
    truth (``x_true, y_true, z_true``), and a two-section estimate against the tip alone
    and against the tip and section 1's end."""
    rod = tmp_path / "rod.csv"
    assert main(["estimate", str(DATA / "rod_planar.csv"), "--method", "ekf", "-o", str(rod)]) == 0
    assert main(["plot", str(rod), "--truth", str(DATA / "rod_planar.csv"),
                 "-o", str(tmp_path / "rod.png")]) == 0  # fmt: skip
    truth = read_state_table(two_section_run / "t.csv")
    # positions of a third section end: a truth of a robot of more sections, refused
    more = tmp_path / "more.csv"
    values = np.column_stack([truth.t] + [truth.column(c) for c in ("x", "y", "z")] * 2)
    np.savetxt(more, values, delimiter=",", header="t,x,y,z,x_3,y_3,z_3", comments="")
    capsys.readouterr()
    argv = ["plot", str(two_section_run / "e.csv"), "--truth", str(more)]
    assert main([*argv, "-o", str(tmp_path / "more.png")]) == 2
    assert "section columns (x_3, y_3, z_3) that an estimate of 2" in capsys.readouterr().err
    for cols in (("x", "y", "z"), ("x", "y", "z", "x_1", "y_1", "z_1")):
        log = tmp_path / f"mocap{len(cols)}.csv"
        values = np.column_stack([truth.t] + [truth.column(c) for c in cols])
        np.savetxt(log, values, delimiter=",", header=",".join(("t", *cols)), comments="")
        fig = tmp_path / f"mocap{len(cols)}.png"
        assert main(["plot", str(two_section_run / "e.csv"), "--truth", str(log),
                     "-o", str(fig)]) == 0  # fmt: skip
        assert fig.read_bytes()[:4] == b"\x89PNG"
    capsys.readouterr()


def test_the_shipped_rod_recording_is_its_own_truth(tmp_path: Path, capsys) -> None:
    """``rod_planar.csv`` carries its truth as ``x_true, y_true, z_true``: evaluate reads
    them as the truth's ``x, y, z`` (against a copy of itself: no error at all; the file
    itself given twice is refused)."""
    rod = DATA / "rod_planar.csv"
    table = read_state_table(rod)
    raw = np.genfromtxt(rod, delimiter=",", names=True)
    np.testing.assert_array_equal(table.column("x"), raw["x_true"])
    np.testing.assert_array_equal(table.column("z"), raw["z_true"])
    copy = tmp_path / "rod_copy.csv"
    copy.write_bytes(rod.read_bytes())
    assert main(["evaluate", str(rod), str(rod)]) == 2
    capsys.readouterr()
    assert main(["evaluate", str(rod), str(copy), "--json"]) == 0
    import json

    scores = json.loads(capsys.readouterr().out)
    assert scores["tip_mean_mm"] == 0.0 and scores["n"] == len(table.t)


def test_live_reads_its_table_of_an_options_file(tmp_path: Path) -> None:
    from continuum_mhe.cli.app import _parse

    cfg = tmp_path / "opts.toml"
    cfg.write_text('method = "ekf"\n[estimate]\nskip-bad = true\n[live]\nbaud = 9600\n')
    args = _parse(["live", "--port", "/dev/null", "--config", str(cfg), "--method", "ukf"])
    assert (args.baud, args.method) == (9600, "ukf")
    assert "baud = 9600" in args.options_record and "skip-bad" not in args.options_record
    est = _parse(["estimate", "m.csv", "-o", "e.csv", "--config", str(cfg)])
    assert (est.method, est.skip_bad) == ("ekf", True)


def test_options_record_leaves_out_the_flags_a_robot_file_replaces() -> None:
    """With ``--robot`` the section length, bend bound and mounting come from the robot
    file, so the record does not carry the one-section flags' values."""
    from continuum_mhe.cli.app import _parse

    with_robot = _parse(["estimate", "m.csv", "-o", "e.csv", "--robot", "r.toml"])
    assert "robot = " in with_robot.options_record
    for key in ("theta-max", "length", "mounting"):
        assert f"{key} = " not in with_robot.options_record
    alone = _parse(["estimate", "m.csv", "-o", "e.csv", "--theta-max", "2.5"])
    assert "theta-max = 2.5" in alone.options_record and "length = 0.2" in alone.options_record


def test_the_estimate_file_records_the_model_the_input_chose(tmp_path: Path) -> None:
    """Raw IMUs with gyros take the direct model and its gyro biases without a flag; the
    file says so (its options record only what was given)."""
    raw = tmp_path / "m_raw.csv"
    lines = (DATA / "rod2" / "planar-s_raw.csv").read_text().splitlines()
    raw.write_text("\n".join(lines[:41]) + "\n")  # 40 samples
    cases = {"raw": (raw, "direct"), "tilt": (DATA / "rod2" / "planar-s_tilt.csv", "bend")}
    for name, (meas, model) in cases.items():
        est = tmp_path / f"e_{name}.csv"
        assert main(["estimate", str(meas), "-o", str(est), "--robot", "two-section"]) == 0
        line = next(ln for ln in est.read_text().splitlines() if ln.startswith("# model ="))
        record = tomllib.loads(line[2:])["model"]
        assert record["name"] == model
        assert ("bgx_1" in record["states"]) == (name == "raw")
        assert record["states"][:4] == ["a_1", "b_1", "a_2", "b_2"]


def test_the_estimate_file_records_the_method_that_made_it(tmp_path: Path) -> None:
    """Without ``--method`` the record names the default that ran, so the file's options
    (``--config EST.csv``) give the same estimator again."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--duration", "0.5"]) == 0
    assert main(["estimate", str(meas), "-o", str(est)]) == 0
    record = next(ln for ln in est.read_text().splitlines() if ln.startswith("# options"))
    assert 'method = "mhe"' in record


def test_a_metres_wide_band_does_not_flatten_the_position_panels(tmp_path: Path) -> None:
    """An estimate's rows far from sure (std_x of 1.76 m on a 0.3 m robot) do not
    autoscale the x panel to +-4000 mm with the lines flat: the panels frame the lines
    (estimate and truth) with room, and such a band fills the panel."""
    from continuum_mhe.evaluation.estimate_figure import estimate_figure

    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(tmp_path / "m.csv"),
                 "--truth", str(tmp_path / "t.csv")]) == 0  # fmt: skip
    assert main(["estimate", str(tmp_path / "m.csv"), "--method", "ekf",
                 "-o", str(tmp_path / "e.csv")]) == 0  # fmt: skip
    est, truth = read_state_table(tmp_path / "e.csv"), read_state_table(tmp_path / "t.csv")
    assert est.std is not None
    est.std[10:20, est.names.index("x")] = 1.76
    fig = estimate_figure(est, truth)
    x_mm = np.concatenate([est.column("x"), truth.column("x")]) * 1e3
    lo, hi = fig.axes[0].get_ylim()
    span = x_mm.max() - x_mm.min()
    assert lo <= x_mm.min() and hi >= x_mm.max()
    assert hi - lo <= 2.0 * span + 20.0 + 1e-9  # the lines with half their span each side


def test_calibrate_writes_the_given_one_section_robot_and_says_what_it_assumed(
    tmp_path: Path, capsys
) -> None:
    """Without --robot the written file holds --length and --theta-max (the robot file's
    3.0 rad by default, not the one-section command line's pi/2), and the message says
    they were not measured."""
    from continuum_mhe.io.robot_file import read_robot

    rest = tmp_path / "rest.csv"
    _rest_recording(rest, (0.0, 0.0, 0.0), np.array([0.01, 0.0, 0.0]))
    out = tmp_path / "c.toml"
    assert main(["calibrate", "--from", str(rest), "--write-robot", str(out)]) == 0
    robot = read_robot(out)
    assert robot.lengths == (0.2,) and robot.sections[0].theta_max == 3.0
    assert "length = 0.2 m (--length) and theta_max = 3 rad" in capsys.readouterr().err
    assert main(["calibrate", "--from", str(rest), "--write-robot", str(out), "--overwrite",
                 "--length", "0.35", "--theta-max", "2.5"]) == 0  # fmt: skip
    robot = read_robot(out)
    assert robot.lengths == (0.35,) and robot.sections[0].theta_max == 2.5
    two = str(TWO_SECTION)
    assert main(["calibrate", "--from", str(rest), "--robot", two, "--theta-max", "2"]) == 2
    assert "--theta-max does not apply with the robot file" in capsys.readouterr().err


def test_view_warns_of_a_drawing_that_misses_the_estimate(tmp_path: Path, capsys) -> None:
    """``view`` with other sections than the estimate's rows fit (``--length``), or a
    tendon robot's other tensions file than the one its options line names: a warning
    each, the view written; none with the estimate's own. (The tendon recording's first
    40 samples: the warnings are about the files the estimate names, not its rows.)"""
    from continuum_mhe.io.robot_file import shipped_robots

    data = shipped_robots()["tendon-two-section"].parents[1] / "tendon"
    est, raw = tmp_path / "e.csv", tmp_path / "raw.csv"
    raw.write_text("".join((data / "force-08_raw.csv").read_text().splitlines(True)[:41]))
    own = str(data / "force-08_tensions.csv")
    assert main(["estimate", str(raw), "--robot", "tendon-two-section",
                 "--inputs", own, "-o", str(est)]) == 0  # fmt: skip
    view = ["view", str(est), "--robot", "tendon-two-section", "--save", str(tmp_path / "v.rrd")]
    capsys.readouterr()
    assert main([*view, "--inputs", str(data / "twist-29_tensions.csv")]) == 0
    assert "was estimated with --inputs" in capsys.readouterr().err
    assert main([*view, "--inputs", own, "--overwrite"]) == 0
    assert "warning" not in capsys.readouterr().err
    one = tmp_path / "one.csv"
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(tmp_path / "m.csv")]) == 0
    assert main(["estimate", str(tmp_path / "m.csv"), "--method", "ekf", "-o", str(one)]) == 0
    capsys.readouterr()
    assert main(["view", str(one), "--length", "0.3", "--save", str(tmp_path / "w.rrd")]) == 0
    assert "its rows fit sections of 0.2 m, not the given robot's 0.3 m" in capsys.readouterr().err


def test_an_estimate_made_in_another_folder_repeats_from_anywhere(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A robot file given by a relative name from a subfolder: the estimate records it so
    that --config EST.csv (and evaluate's robot from the record) finds it from another
    working folder, and still beside the estimate once the folder has moved."""
    from continuum_mhe.cli.config import recorded_option

    (tmp_path / "sub").mkdir()
    robot = tmp_path / "r2.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\ntheta_max = 2.5\n'
        "[[section]]\nlength = 0.14\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    monkeypatch.chdir(tmp_path)
    assert (
        main(["simulate", "s-curve", "--robot", "r2.toml", "-o", "m.csv", "--duration", "2"]) == 0
    )
    monkeypatch.chdir(tmp_path / "sub")
    assert main(["estimate", "../m.csv", "--robot", "../r2.toml", "-o", "est.csv"]) == 0
    assert recorded_option("est.csv", "robot") == str(robot)
    monkeypatch.chdir(tmp_path)
    assert main(["estimate", "m.csv", "--config", "sub/est.csv", "-o", "again.csv"]) == 0

    def rows(path: Path) -> list[str]:  # without solve_ms, a time
        return [ln.rsplit(",", 1)[0] for ln in path.read_text().splitlines()[3:]]

    assert rows(tmp_path / "again.csv") == rows(tmp_path / "sub" / "est.csv")
    # moved with its robot file: found beside the estimate by its name
    moved = tmp_path / "moved"
    moved.mkdir()
    (tmp_path / "sub" / "est.csv").rename(moved / "est.csv")
    robot.rename(moved / "r2.toml")
    assert main(["estimate", "m.csv", "--config", "moved/est.csv", "-o", "third.csv"]) == 0


def test_an_options_file_that_starts_with_a_byte_order_mark_is_read(tmp_path: Path) -> None:
    """An options file saved with a UTF-8 byte-order mark is read as without it (robot
    files and CSVs are), not refused as not valid TOML at column 1."""
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(tmp_path / "m.csv")]) == 0
    cfg = tmp_path / "opts.toml"
    cfg.write_text('\ufeffmethod = "ekf"\n', encoding="utf-8")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(tmp_path / "m.csv"), "--config", str(cfg), "-o", str(out)]) == 0
    assert _options_of(out)["method"] == "ekf"


def test_plot_of_a_one_row_estimate_with_a_truth_says_so(tmp_path: Path, capsys) -> None:
    """A truth beside an estimate of one row is refused saying that the estimate has one
    row (not 'only 1 of the estimate's 1 rows have a truth row at the same t')."""
    meas, truth, est = (tmp_path / n for n in ("m.csv", "t.csv", "e.csv"))
    assert (
        main(["simulate", "paper3d", "--duration", "1", "-o", str(meas), "--truth", str(truth)])
        == 0
    )
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(est)]) == 0
    lines = est.read_text().splitlines()
    one = tmp_path / "one.csv"
    one.write_text("\n".join([ln for ln in lines if ln.startswith("#")] + lines[3:5]) + "\n")
    capsys.readouterr()
    assert main(["plot", str(one), "--truth", str(truth), "-o", str(tmp_path / "f.png")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith("the estimate has 1 row: a truth is drawn beside two rows or more"), err
    assert not (tmp_path / "f.png").exists()


def test_figures_of_a_long_robot_description_keep_their_titles_whole() -> None:
    """The demo's titles name the robot (sections, IMUs, mounting): a title wider than
    its figure is wrapped, not cut at the figure's edges."""
    from matplotlib.text import Text

    from continuum_mhe.evaluation import plotting
    from continuum_mhe.results import EstimateSeries, Status

    t = np.linspace(0.0, 1.0, 21)
    truth = np.column_stack([0 * t, 0 * t, 0.2 + 0 * t, 0.1 + t, 0 * t])
    series = EstimateSeries("mhe", t, truth.copy(), np.full(len(t), Status.OK.value), 0 * t)
    title = "Tip path (simulated spatial recording, " + "2 sections (0.16 m, 0.14 m), " * 4
    for fig in (
        plotting.trajectory_3d(truth, [series], title),
        plotting.states_vs_time(t, truth, [series], title),
    ):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        titles = [x for x in fig.findobj(Text) if x.get_text() == title]
        assert titles
        for text in titles:
            extent = text.get_window_extent(renderer)
            assert fig.bbox.x0 <= extent.x0 and extent.x1 <= fig.bbox.x1
        plotting.close(fig)


def test_a_status_has_one_colour_in_every_estimate_figure() -> None:
    """The status strip colours each status alike in every file, whichever other
    statuses the file has (``uncertain`` beside ``ok`` alone, or beside ``reset``), and
    no two statuses alike."""
    from continuum_mhe.evaluation import plotting
    from continuum_mhe.evaluation.estimate_figure import estimate_figure
    from continuum_mhe.io.state_tables import StateTable

    t = np.linspace(0.0, 1.0, 6)
    names = ["x", "y", "z", "theta", "phi"]
    values = np.column_stack([0 * t, 0 * t, 0.2 + 0 * t, 0 * t, 0 * t])
    colours = []
    for other in ("ok", "reset"):
        statuses = np.array(["uncertain", other, "ok", "ok", "ok", "ok"])
        fig = estimate_figure(StateTable(t, names, values, statuses))
        strip = fig.axes[-2]  # the status strip (the 3D view is the last axes)
        row = [lab.get_text() for lab in strip.get_yticklabels()].index("uncertain")
        colours.append(next(ln for ln in strip.get_lines() if ln.get_ydata()[0] == row).get_color())
        plotting.close(fig)
    assert colours[0] == colours[1]
    from matplotlib.colors import to_hex

    from continuum_mhe.evaluation.estimate_figure import status_color
    from continuum_mhe.results import Status

    assert len({to_hex(status_color(s)) for s in Status}) == len(Status)  # none alike


def test_a_hanging_robot_is_drawn_turned_over_not_mirrored(tmp_path: Path) -> None:
    """A robot hanging from its base (mounting z-down) is drawn as it hangs, its base
    frame turned half a turn about x in every 3D panel (``plot``'s and the demo's): z
    and y reversed, x not, so the frame stays right-handed and a bend to +y is not
    drawn as one to -y."""
    from continuum_mhe import Section, make_estimator, make_formulation
    from continuum_mhe.evaluation import plotting
    from continuum_mhe.evaluation.estimate_figure import estimate_figure
    from continuum_mhe.model.robot import ImuPlacement
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = Robot((Section(0.16), Section(0.14)), (ImuPlacement(0), ImuPlacement(1)), "z-down")
    rec = simulate_robot("spatial", robot, duration=1.0)
    series = make_estimator("ekf", make_formulation("bend", robot)).run(rec.t, rec.z)
    views = [
        plotting.trajectory_3d(rec.truth, [series], z_down=True).axes[0],
        *plotting.backbone_snapshots(rec.t, rec.truth, [series], robot.lengths, z_down=True).axes,
    ]
    m, t = str(tmp_path / "m.csv"), str(tmp_path / "t.csv")
    assert main(["simulate", "paper3d", "--duration", "2", "--mounting", "z-down",
                 "-o", m, "--truth", t]) == 0  # fmt: skip
    assert main(["estimate", str(tmp_path / "m.csv"), "--method", "ekf", "--mounting",
                 "z-down", "-o", str(tmp_path / "e.csv")]) == 0  # fmt: skip
    est, truth = read_state_table(tmp_path / "e.csv"), read_state_table(tmp_path / "t.csv")
    views += [a for a in estimate_figure(est, truth, z_down=True).axes if a.name == "3d"]
    assert len(views) == 6
    for ax in views:
        assert ax.zaxis_inverted() and ax.yaxis_inverted() and not ax.xaxis_inverted()
    upright = plotting.trajectory_3d(rec.truth, [series]).axes[0]
    assert not (upright.zaxis_inverted() or upright.yaxis_inverted())


def test_a_key_at_the_options_files_top_applies_where_it_can(tmp_path: Path, capsys) -> None:
    """A key at an options file's top is for both commands: one that only the other
    command takes (``topic``, for a bag, in ``live``; ``baud`` in ``estimate``) is left
    out there, not refused; under the command's own table it is refused."""
    from continuum_mhe.cli.app import _parse

    profile = tmp_path / "profile.toml"
    profile.write_text('method = "ekf"\ntopic = ["/imu1"]\nbaud = 9600\n')
    args = _parse(["live", "--port", "/dev/null", "--config", str(profile)])
    assert args.baud == 9600 and args.method == "ekf"
    args = _parse(["estimate", "m.csv", "-o", "e.csv", "--config", str(profile)])
    assert args.topic == ["/imu1"] and args.method == "ekf"
    own = tmp_path / "own.toml"
    own.write_text('[live]\ntopic = ["/imu1"]\n')
    assert main(["live", "--port", "/dev/null", "--config", str(own)]) == 2
    assert "line 2: topic is not an option of live" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("argv", "left_out", "kept"),
    [
        (["--method", "ekf"], ("reject-reset", "drift-reset", "horizon"), ("bad-start", "glitch")),
        (["--loss", "huber"], ("bad-start", "glitch", "drift-reset"), ("reject-reset", "loss")),
        ([], ("reject-reset", "drift-reset"), ("bad-start", "glitch", "horizon")),
    ],
)
def test_the_options_line_records_the_options_the_run_used(
    tmp_path: Path, argv: list[str], left_out: tuple[str, ...], kept: tuple[str, ...]
) -> None:
    """An estimate file's options line leaves out what the run did not use: the reject
    reset but where a robust MHE rejects readings, the bad-start check and the glitch
    skip for a robust MHE, the drift reset and the tension gains for a robot without
    tendons, an MHE option for a filter; it keeps the constant-curvature model's options
    (a tendon robot's record leaves them out: test_tendon_tensions)."""
    from continuum_mhe.cli.config import recorded_option

    meas, out = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "-o", str(out), *argv]) == 0
    for key in (*left_out, "estimate-tension-gain"):
        assert recorded_option(str(out), key) is None, key
    model = ("formulation", "model-error-floor-deg", "reading-bias-deg", "accel-psd",
             "estimate-accel-bias", "own-acceleration", "imu-twist")  # fmt: skip
    for key in (*kept, *model):
        assert recorded_option(str(out), key) is not None, key


def _captured_figure(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> object:
    """The figure ``plot`` (``argv``) saves, captured before it is written."""
    from matplotlib.figure import Figure

    figures: list[Figure] = []

    def keep(self: Figure, *args: object, **kwargs: object) -> None:
        figures.append(self)

    monkeypatch.setattr(Figure, "savefig", keep)
    assert main(argv) == 0
    return figures[0]


def test_plot_breaks_its_lines_and_bands_at_a_gap_and_says_a_file_has_no_statuses(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An estimate with 3 s of rows missing (a recording cut), and a truth with 2 s
    missing: every line (positions, truth, error) has a break (NaN) in each gap, not a
    straight segment across it. A file without a status column says so in the status
    strip, not a strip of ok rows."""
    meas, truth, est = (tmp_path / n for n in ("m.csv", "t.csv", "e.csv"))
    assert main(["simulate", "paper3d", "--duration", "12", "-o", str(meas),
                 "--truth", str(truth)]) == 0  # fmt: skip
    lines = meas.read_text().splitlines()
    cut = tmp_path / "cut.csv"
    cut.write_text(
        "\n".join(ln for ln in lines if ln[0] == "t" or not 5 <= float(ln.split(",")[0]) < 8) + "\n"
    )
    assert main(["estimate", str(cut), "--method", "ekf", "-o", str(est)]) == 0
    tl = truth.read_text().splitlines()
    holed = tmp_path / "holed.csv"
    holed.write_text(
        "\n".join(ln for ln in tl if ln[0] == "t" or not 9 <= float(ln.split(",")[0]) < 11) + "\n"
    )
    fig = _captured_figure(monkeypatch, ["plot", str(est), "--truth", str(holed), "-o",
                                         str(tmp_path / "f.png")])  # fmt: skip
    axes = fig.axes  # type: ignore[attr-defined]
    for gap in ((4.95, 8.0), (8.95, 11.0)):
        for ax in axes[:4]:  # x, y, z and the error
            for line in ax.get_lines():
                t, v = (np.asarray(a, dtype=float) for a in line.get_data())
                if len(t) < 10:
                    continue
                inside = (t > gap[0]) & (t < gap[1])
                across = np.flatnonzero((t[:-1] <= gap[0]) & (t[1:] >= gap[1]))
                assert not len(across) or np.isnan(v[inside]).all() or inside.sum() == 0
                if inside.any() and not np.isnan(v[inside]).all():
                    continue  # a line of the other file, which has rows there
                assert np.isnan(v).any(), (ax.get_ylabel(), line.get_label(), gap)
    # a file without statuses: said
    est.write_text("\n".join(ln.rsplit(",", 0)[0] for ln in
                             truth.read_text().splitlines()) + "\n")  # fmt: skip
    fig = _captured_figure(monkeypatch, ["plot", str(est), "-o", str(tmp_path / "g.png")])
    strip = next(ax for ax in fig.axes if ax.get_ylabel() == "status")  # type: ignore[attr-defined]
    assert [t.get_text() for t in strip.texts] == ["the file has no status column"]


def test_plot_writes_the_file_it_names_whatever_the_suffix_case(tmp_path: Path, capsys) -> None:
    """``-o FIG.PNG`` where ``FIG.png`` exists: refused without ``--overwrite`` (the
    figure is written with the suffix in lower case), not written over."""
    meas, est = tmp_path / "m.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "--duration", "1", "-o", str(meas)]) == 0
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(est)]) == 0
    (tmp_path / "fig.png").write_text("precious")
    capsys.readouterr()
    assert main(["plot", str(est), "-o", str(tmp_path / "fig.PNG")]) == 2
    assert "fig.png: exists" in capsys.readouterr().err
    assert (tmp_path / "fig.png").read_text() == "precious"


def test_evaluate_matches_rows_of_a_large_clock_to_the_microsecond(tmp_path: Path) -> None:
    """On an epoch-seconds clock (t about 1.7e9 s) a truth row matches an estimate row
    within 1 us and the times' rounding, not within a share of t (1700 s there): the
    same truth 20 ms later is interpolated, and one 300 s later, beside no row, is
    refused."""
    from continuum_mhe.evaluation.metrics import match_rows

    t = 1.7e9 + np.arange(100) * 0.05
    i_est, i_truth = match_rows(t, t.copy())
    assert len(i_est) == 100 and np.array_equal(i_est, i_truth)
    assert len(match_rows(t, t + 0.02)[0]) == 0
    assert len(match_rows(t, t + 300.0)[0]) == 0
    assert len(match_rows(np.arange(10) * 0.05, np.arange(10) * 0.05 + 5e-7)[0]) == 10


def test_plot_and_view_name_the_shift_that_lines_up_a_truth_on_another_clock(
    tmp_path: Path, capsys
) -> None:
    """A truth whose clock runs 100 s ahead of the estimate's (no time in common): plot
    and view refuse it in one line naming the ``--truth-shift`` that compares them, as
    evaluate does."""
    meas, truth, est = (tmp_path / n for n in ("m.csv", "t.csv", "e.csv"))
    assert main(["simulate", "paper3d", "--duration", "2", "-o", str(meas),
                 "--truth", str(truth)]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "--method", "ekf", "-o", str(est)]) == 0
    lines = truth.read_text().splitlines()
    shifted = [f"{float(ln.split(',')[0]) + 100:g}," + ln.split(",", 1)[1] for ln in lines[1:]]
    later = tmp_path / "later.csv"
    later.write_text("\n".join([lines[0], *shifted]) + "\n")
    capsys.readouterr()
    figure = ["plot", str(est), "--truth", str(later), "-o", str(tmp_path / "f.png")]
    view = ["view", str(est), "--truth", str(later), "--save", str(tmp_path / "v.rrd")]
    option = "--truth-shift 100 compares them"  # (view's names evaluate's option)
    for argv in (figure, ["evaluate", str(est), str(later)], view):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].endswith(option), err


def test_a_figures_lines_break_at_gaps_not_within_bursts() -> None:
    """Rows stamped in bursts of three 1 us apart every 50 ms (a logger's bursts): no
    break inside the recording; a 1 s hole in it: one break there."""
    from continuum_mhe.evaluation.estimate_tables import broken

    t = (np.arange(40)[:, None] * 0.05 + np.array([0.0, 1e-6, 2e-6])).ravel()
    assert not np.isnan(broken(t, np.ones_like(t))[1]).any()
    holed = np.concatenate([t[:60], t[60:] + 1.0])
    _, y = broken(holed, np.ones_like(holed))
    assert np.isnan(y).sum() == 1
