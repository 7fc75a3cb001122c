"""Gyro biases from a recording's still start (``calibration.still_start``): known
answers of the detection (a still start found to its length and biases, a slow steady
turn, a start in motion and a dropout not taken for one), the biases written so that
the robot's readings at rest read zero (any mounting), and ``estimate`` of a shipped
twisting rod's recording that starts still: the biases taken, the twist weighed and
estimated, near its calibrated result."""

from __future__ import annotations

import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from continuum_mhe.calibration.still_start import (
    BLOCK_S,
    find_still_start,
    with_still_start_biases,
)
from continuum_mhe.cli import main
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.robot_file import read_robot, shipped_robots
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.registry import make_formulation

ROD = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
NAMES = tuple(f"{q}{a}_{k}" for k in (1, 2) for q in "fw" for a in "xyz")
BIASES = np.array([[0.03, -0.05, 0.02], [-0.01, 0.04, -0.06]])  # rad/s


def _recording(
    still_s: float, turn_rate: float = 0.0, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Two IMUs at 50 Hz over 4 s: at rest for ``still_s`` s (each gyro reading its bias
    with 0.002 rad/s of noise, each accelerometer gravity with 0.02 m/s^2), turning
    about their x axes at ``turn_rate`` rad/s meanwhile; then swinging about x at up
    to 1 rad/s."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 4.0, 0.02)
    moving = t >= still_s
    rate = np.where(moving, np.sin(3.0 * (t - still_s)), turn_rate)
    angle = np.cumsum(rate) * 0.02
    z = np.empty((len(t), 12))
    for k in range(2):
        force = 9.81 * np.column_stack([np.zeros_like(t), np.sin(angle), np.cos(angle)])
        rates = np.column_stack([rate, np.zeros_like(t), np.zeros_like(t)]) + BIASES[k]
        z[:, 6 * k : 6 * k + 3] = force + rng.normal(0.0, 0.02, force.shape)
        z[:, 6 * k + 3 : 6 * k + 6] = rates + rng.normal(0.0, 0.002, rates.shape)
    return t, z


def test_a_still_start_is_found_to_its_length_with_the_gyro_biases() -> None:
    """Two seconds at rest: four still blocks of 0.5 s, the last left out (the motion
    may begin in it), so 1.5 s and 75 samples; the biases within the mean of 75 noisy
    readings (0.002 / sqrt(75) rad/s: 0.001 is over four of its standard errors)."""
    t, z = _recording(2.0)
    still = find_still_start(t, z, NAMES, 2)
    assert still is not None
    assert still.seconds == 3 * BLOCK_S and still.samples == 75
    assert_allclose(np.array(still.gyro_biases), BIASES, atol=1e-3)
    assert "gyro biases from the still start (its first 1.5 s, 75 samples)" in still.clause()


def test_no_still_start_where_the_robot_moves_turns_or_drops_out() -> None:
    """No still start in a recording that moves from its first sample, nor in one whose
    first second is too short a rest (0.9 s: one block left, 0.5 s), nor where the IMUs
    turn steadily at 0.05 rad/s about a horizontal axis (a steady rate, like a bias, but
    the gravity direction turns 1.4 degrees a block), nor with a dropout in the first
    block, nor without gyro columns."""
    for still_s in (0.0, 0.9):
        t, z = _recording(still_s)
        assert find_still_start(t, z, NAMES, 2) is None, still_s
    t, z = _recording(3.0, turn_rate=0.05)
    assert find_still_start(t, z, NAMES, 2) is None
    t, z = _recording(2.0)
    z[3, 4] = math.nan
    assert find_still_start(t, z, NAMES, 2) is None
    tilt_names = tuple(n for n in NAMES if n.startswith("f"))
    assert find_still_start(t, z[:, [0, 1, 2, 6, 7, 8]], tilt_names, 2) is None


def test_no_still_start_where_a_turn_about_the_vertical_speeds_up() -> None:
    """A turn about the vertical moves no accelerometer: the IMUs level, their rates about
    z growing by 0.02 rad/s each second from the first sample (each half-second's rates
    scatter by 0.003 rad/s, well within the noise bound) change their mean by more than
    0.01 rad/s from the first half-second's within 1 s, which is no still start."""
    rng = np.random.default_rng(2)
    t = np.arange(0.0, 4.0, 0.02)
    z = np.empty((len(t), 12))
    for k in range(2):
        z[:, 6 * k : 6 * k + 3] = [0.0, 0.0, 9.81] + rng.normal(0.0, 0.02, (len(t), 3))
        z[:, 6 * k + 3 : 6 * k + 6] = BIASES[k] + rng.normal(0.0, 0.002, (len(t), 3))
        z[:, 6 * k + 5] += 0.02 * t
    assert find_still_start(t, z, NAMES, 2) is None


def _rest_then_run(tmp_path: Path, name: str, still_s: float = 2.0) -> tuple[Path, Path]:
    """The shipped rod recording ``name``: its rest recording's first ``still_s`` s, then
    its raw recording (times moved by ``still_s``); the truth moved alike."""
    rest = (ROD / f"{name}_rest.csv").read_text().splitlines()
    raw = (ROD / f"{name}_raw.csv").read_text().splitlines()
    assert rest[0] == raw[0]
    lines = [raw[0]] + [ln for ln in rest[1:] if float(ln.split(",")[0]) < still_s - 1e-9]
    for ln in raw[1:]:
        t, rest_of_row = ln.split(",", 1)
        lines.append(f"{float(t) + still_s!r},{rest_of_row}")
    run = tmp_path / f"{name}_still_raw.csv"
    run.write_text("\n".join(lines) + "\n")
    truth = (ROD / f"{name}_truth.csv").read_text().splitlines()
    moved = [truth[0]]
    for ln in truth[1:]:
        t, rest_of_row = ln.split(",", 1)
        moved.append(f"{float(t) + still_s!r},{rest_of_row}")
    truth_path = tmp_path / f"{name}_still_truth.csv"
    truth_path.write_text("\n".join(moved) + "\n")
    return run, truth_path


def test_the_biases_taken_make_the_still_start_read_zero_for_any_mounting(tmp_path) -> None:
    """The biases go into the robot file's ``gyro_bias`` (the sensor's frame), which the
    reading removes before turning the rates into the disk's frame by ``mount_rpy``: the
    still start's rates, read with the robot given them, average zero, with one IMU
    mounted turned (20, -10, 35 degrees). An IMU with a calibrated ``gyro_bias`` keeps
    it."""
    run, _ = _rest_then_run(tmp_path, "planar-s")
    robot = read_robot(shipped_robots()["two-section"])
    turned = replace(robot.imus[1], mount_rpy=(20.0, -10.0, 35.0))
    robot = replace(robot, imus=(robot.imus[0], turned))
    data = load_input(run, InputOptions(), make_formulation("bend", robot))
    names = data.formulation.measurement_names
    still = find_still_start(data.t, data.z, names, 2)
    assert still is not None and still.seconds == 1.5
    given = with_still_start_biases(robot, still)
    again = load_input(run, InputOptions(), make_formulation("bend", given))
    rates = [names.index(f"w{a}_{k}") for k in (1, 2) for a in "xyz"]
    at_rest = again.t < again.t[0] + still.seconds - 1e-9
    assert_allclose(again.z[at_rest][:, rates].mean(axis=0), 0.0, atol=1e-12)
    calibrated = replace(robot.imus[0], gyro_bias=(0.1, 0.2, 0.3))
    kept = with_still_start_biases(replace(robot, imus=(calibrated, turned)), still)
    assert kept.imus[0].gyro_bias == (0.1, 0.2, 0.3)
    assert kept.imus[1].gyro_bias == given.imus[1].gyro_bias


def _tip_error_mm(est: Path, truth: Path, after_s: float) -> float:
    e, tr = read_state_table(est), read_state_table(truth)
    keep = e.t >= after_s - 1e-9
    tip_e = np.column_stack([e.column(c) for c in "xyz"])[keep]
    tip_t = np.column_stack([np.interp(e.t[keep], tr.t, tr.column(c)) for c in "xyz"])
    return float(np.mean(np.linalg.norm(tip_e - tip_t, axis=1))) * 1e3


def test_estimate_takes_the_gyro_biases_from_a_still_start(tmp_path, capsys) -> None:
    """The shipped ``spatial`` rod (its IMUs twist up to 122 degrees) recorded after 2 s
    at rest, the robot file uncalibrated: ``estimate`` takes the gyro biases from the
    still start, says so, weighs the twist on the readings and estimates it, within 10
    mm of the tip on average after the rest (the frames, ``--no-imu-twist``, over 50 mm).
    The same recording without its rest, or with a calibrated robot file, takes none."""
    run, truth = _rest_then_run(tmp_path, "spatial")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(run), "--robot", "two-section", "-o", str(out)]) == 0
    said = capsys.readouterr().err.strip().splitlines()[-1]
    assert "; gyro biases from the still start (its first 1.5 s, 75 samples): IMU 1 (" in said
    assert "; the IMUs' twist estimated (--imu-twist: " in said
    assert _tip_error_mm(out, truth, 2.0) < 10.0
    frames = tmp_path / "f.csv"
    assert main(["estimate", str(run), "--robot", "two-section", "--no-imu-twist",
                 "-o", str(frames)]) == 0  # fmt: skip
    assert _tip_error_mm(frames, truth, 2.0) > 50.0
    capsys.readouterr()
    plain = tmp_path / "p.csv"
    assert main(["estimate", str(ROD / "spatial_raw.csv"), "--robot", "two-section",
                 "-o", str(plain)]) == 0  # fmt: skip
    assert "still start" not in capsys.readouterr().err
    cal = tmp_path / "cal.toml"
    assert main(["calibrate", "--from", str(ROD / "spatial_rest.csv"), "--robot", "two-section",
                 "--write-robot", str(cal)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["estimate", str(run), "--robot", str(cal), "-o", str(plain), "--overwrite"]) == 0
    assert "still start" not in capsys.readouterr().err


def test_the_biases_are_turned_by_the_mount_rpy_option_for_imus_without_their_own(
    tmp_path,
) -> None:
    """An IMU without a robot-file ``mount_rpy`` is turned by ``--mount-rpy`` (its
    readings' conversion), and so is the bias ``estimate`` writes for it: the
    ``spatial`` rod's still start recorded in a sensor frame turned by (20, -10, 35)
    degrees, read with ``--mount-rpy 20,-10,35``, reads zero over the still start, as
    with the robot file's ``mount_rpy``."""
    from continuum_mhe.cli import build_parser
    from continuum_mhe.cli.estimate import still_start_biases
    from continuum_mhe.cli.input_options import input_options
    from continuum_mhe.cli.model_options import formulation_from_args
    from continuum_mhe.io.raw_imu import mount_rotation

    run, _ = _rest_then_run(tmp_path, "spatial")
    rows = run.read_text().splitlines()
    turn = mount_rotation((20.0, -10.0, 35.0))
    turned = [rows[0]]
    for ln in rows[1:]:
        v = np.array([float(x) for x in ln.split(",")])
        for c in (1, 4, 7, 10):  # each IMU's accelerometer and gyro: sensor = R^T disk
            v[c : c + 3] = turn.T @ v[c : c + 3]
        turned.append(",".join(repr(float(x)) for x in v))
    path = tmp_path / "turned.csv"
    path.write_text("\n".join(turned) + "\n")
    argv = ["estimate", str(path), "--robot", "two-section", "--mount-rpy", "20,-10,35",
            "-o", str(tmp_path / "e.csv")]  # fmt: skip
    args = build_parser().parse_args(argv)
    still, base = still_start_biases(args, formulation_from_args(args))
    assert still is not None and still.seconds == 1.5
    data = load_input(path, input_options(args), base)
    names = data.formulation.measurement_names
    rates = [names.index(f"w{a}_{k}") for k in (1, 2) for a in "xyz"]
    at_rest = data.t < data.t[0] + still.seconds - 1e-9
    assert_allclose(data.z[at_rest][:, rates].mean(axis=0), 0.0, atol=1e-12)


def test_a_one_imu_robot_has_a_still_start(tmp_path, capsys) -> None:
    """With one IMU the measurements' columns have no ``_1`` (``fx ... wz``): its still
    start is found as with two, and ``estimate`` of a one-section robot (``--length``)
    takes its gyro bias from it."""
    from continuum_mhe.model.descriptions import direct_blocks

    t, z = _recording(2.0)
    names = tuple(n for b in direct_blocks(1) for n in b.names)
    still = find_still_start(t, z[:, :6], names, 1)
    assert still is not None and still.seconds == 3 * BLOCK_S
    assert_allclose(np.array(still.gyro_biases), BIASES[:1], atol=1e-3)
    run, _ = _rest_then_run(tmp_path, "spatial")
    rows = [",".join(ln.split(",")[:7]) for ln in run.read_text().splitlines()]
    one = tmp_path / "one.csv"
    one.write_text("\n".join(rows) + "\n")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(one), "--length", "0.16", "--method", "ekf",
                 "-o", str(out)]) == 0  # fmt: skip
    said = capsys.readouterr().err.strip().splitlines()[-1]
    assert "; gyro biases from the still start (its first 1.5 s, 75 samples): IMU 1 (" in said


def test_a_ros2_bag_that_starts_still_gives_the_csvs_biases(tmp_path, capsys) -> None:
    """A ROS 2 bag (a folder; one ``sensor_msgs/msg/Imu`` topic per IMU) of the
    ``spatial`` rod's readings after 2 s of its rest takes the same gyro biases from its
    still start as the same readings in a CSV file, and says so alike."""
    from robot_log_helpers import csv_and_ros2_bag

    run, _ = _rest_then_run(tmp_path, "spatial")
    lines = run.read_text().splitlines()[:251]  # the rest and 3 s of motion
    said = {}
    for name, source, extra in csv_and_ros2_bag(lines, tmp_path):
        capsys.readouterr()
        assert main(["estimate", str(source), "--robot", "two-section", "--method", "ekf",
                     "-o", str(tmp_path / f"{name}.csv"), *extra]) == 0  # fmt: skip
        summary = capsys.readouterr().err.strip().splitlines()[-1]
        found = re.search(r"gyro biases from the still start \([^)]*\): [^;]*", summary)
        assert found is not None, summary
        said[name] = found.group(0)
    assert said["csv"] == said["bag"]


def _low_noise_gyro_from_rest(tmp_path: Path, still_s: float, deg_s: bool) -> list[str]:
    """The shipped planar-s rod's readings by a gyro with a small bias and little noise:
    its rest recording's first ``still_s`` s (repeated where longer), then its raw
    recording, each gyro's rates less its mean at rest (the rod's bias), the noise at
    rest a tenth, plus 0.001 rad/s; the rates in deg/s (``deg_s``) or rad/s. The CSV's
    lines."""
    rest = np.loadtxt(ROD / "planar-s_rest.csv", delimiter=",", skiprows=1)
    raw = np.loadtxt(ROD / "planar-s_raw.csv", delimiter=",", skiprows=1)
    header = (ROD / "planar-s_raw.csv").read_text().splitlines()[0]
    gyro = [i for i, c in enumerate(header.split(",")) if c[:2] in ("gx", "gy", "gz")]
    bias = rest[:, gyro].mean(axis=0)
    n = round(still_s / 0.02)
    still = rest[np.arange(n) % len(rest)]
    still[:, 0] = 0.02 * np.arange(n)
    still[:, gyro] = 0.1 * (still[:, gyro] - bias)
    moving = raw.copy()
    moving[:, 0] += 0.02 * n
    moving[:, gyro] -= bias
    rows = np.vstack([still, moving])
    rows[:, gyro] += 0.001
    if deg_s:
        rows[:, gyro] = np.degrees(rows[:, gyro])
    return [header, *(",".join(repr(float(v)) for v in r) for r in rows)]


@pytest.mark.parametrize("still_s", [12.0, 90.0])
def test_a_gyro_in_deg_s_that_starts_still_is_told_by_its_motion(
    still_s: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording that starts still for 12 s (or 90 s: the first block of 4096 rows
    still throughout), its gyros in deg/s with a bias of 0.057 deg/s and 0.01 deg/s of
    noise: the median rate (0.13 read as rad/s) is below the deg/s bound and the still
    stretches, read as rad/s, turn gravity by under 2 deg a half-second, so estimate
    took a still start's biases of 0.057 "rad/s" and estimated the motion's rates 57
    times too large, restarting on 31 % of the samples, no line naming the unit. The
    motion tells: the accelerometers' gravity directions turn as the rates say in deg/s
    (one line naming the file and deg/s, exit 2, nothing written), as a CSV and as a
    ROS 2 bag; the same readings in rad/s are estimated."""
    from robot_log_helpers import csv_and_ros2_bag

    for deg_s in (True, False):
        folder = tmp_path / ("deg" if deg_s else "rad")
        folder.mkdir()
        sources = csv_and_ros2_bag(_low_noise_gyro_from_rest(tmp_path, still_s, deg_s), folder)
        for name, source, extra in sources[: 2 if still_s < 60 else 1]:
            out = folder / f"{name}.est.csv"
            args = ["estimate", str(source), "--robot", "two-section", "--method", "ekf"]
            code = main([*args, "-o", str(out), *extra])
            err = capsys.readouterr().err
            if not deg_s:
                assert code == 0 and "deg/s" not in err, err
                assert "gyro biases from the still start" in err
                continue
            assert code == 2 and err.count("\n") == 1 and not out.exists(), err
            imu = "IMU 1" if name == "csv" else "topic /imu1"
            said = re.fullmatch(
                rf"continuum-mhe: error: {re.escape(str(source))}: {imu}: over \d+ stretches "
                r"of its motion the accelerometer's gravity direction turns as the gyro says "
                r"only with the gyro in deg/s \(.*\): give rad/s \(gx, gy, gz times pi/180 = "
                r"0\.0174533\)\n",
                err,
            )
            assert said is not None, err


@pytest.mark.parametrize("deg_s", [True, False])
def test_a_stream_that_starts_still_has_its_gyro_units_told_by_its_motion(deg_s: bool) -> None:
    """The readings of the recording above (12 s still, then the planar-s motion)
    handed to an estimator's ``step`` one sample at a time, as ``live`` does: its first
    second, still, says nothing of the unit; the motion does. In deg/s a
    ``ReadingUnitsError`` naming deg/s is raised within the first
    ``MOTION_CHECK_ROWS + 5 s`` of motion (every later sample refused alike), where the
    stream was stepped to its end without a word; in rad/s the stream runs through."""
    from continuum_mhe import Measurement, make_estimator
    from continuum_mhe.estimators.reading_units import MOTION_CHECK_ROWS, ReadingUnitsError
    from continuum_mhe.io import raw_measurements

    lines = _low_noise_gyro_from_rest(Path("unused"), 12.0, deg_s)
    rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    header = lines[0].split(",")
    acc = np.stack([rows[:, [header.index(f"a{a}_{i}") for a in "xyz"]] for i in (1, 2)], axis=1)
    gyr = np.stack([rows[:, [header.index(f"g{a}_{i}") for a in "xyz"]] for i in (1, 2)], axis=1)
    t = rows[:, 0]
    robot = read_robot("two-section")
    z = raw_measurements(robot, t, acc, gyr)
    est = make_estimator("ekf", make_formulation("direct", robot))
    moving = int(np.searchsorted(t, 12.0))
    stepped = 0
    try:
        for i in range(len(t)):
            est.step(Measurement(float(t[i]), z[i]))
            stepped += 1
    except ReadingUnitsError as exc:
        assert deg_s, exc
        assert "only with the gyro in deg/s" in str(exc)
    if not deg_s:
        assert stepped == len(t)
        return
    assert moving < stepped < moving + MOTION_CHECK_ROWS + 250, (moving, stepped)
    with pytest.raises(ReadingUnitsError, match="as found at"):
        est.step(Measurement(float(t[stepped + 1]), z[stepped + 1]))


@pytest.mark.parametrize("deg_s", [True, False])
def test_live_stops_on_a_gyro_in_deg_s_once_a_still_start_moves(deg_s: bool) -> None:
    """The same readings streamed to ``live``'s session as raw lines (two IMUs, 50 Hz,
    the direct model): its own check of the first 100 samples, still, passes both
    units; in deg/s the estimator's motion check stops the session once the robot moves
    (the estimates already made are not kept: readings in the wrong units), in rad/s it
    streams to the end."""
    import io
    import time

    from live_helpers import raw_line

    from continuum_mhe import make_estimator
    from continuum_mhe.io.inputs import imu_converters
    from continuum_mhe.io.raw_imu import RawImuSettings
    from continuum_mhe.live.session import LiveSession, LiveSettings
    from continuum_mhe.model.direct import DirectFormulation

    lines = _low_noise_gyro_from_rest(Path("unused"), 12.0, deg_s)
    rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    header = lines[0].split(",")
    acc = np.stack([rows[:, [header.index(f"a{a}_{i}") for a in "xyz"]] for i in (1, 2)], axis=1)
    gyr = np.stack([rows[:, [header.index(f"g{a}_{i}") for a in "xyz"]] for i in (1, 2)], axis=1)
    robot = read_robot("two-section")
    raw = RawImuSettings(imu_model="direct")
    session = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"),
        make_estimator("ekf", DirectFormulation(robot=robot)),
        imu_converters(raw, robot),
        io.StringIO(),
        say=lambda _: None,
    )
    now = time.monotonic()
    for i in range(len(rows)):
        session.handle_line(raw_line(20 * i, acc[i], gyr[i]).encode(), now + 0.02 * i)
        if session.fatal is not None:
            break
    if not deg_s:
        assert session.fatal is None and session.counts.estimates == len(rows)
        return
    assert session.fatal is not None and "only with the gyro in deg/s" in session.fatal
    assert session.fatal.startswith("/dev/ttyIMU: ")
    assert session.wrong_units
    assert 600 < session.counts.samples < 600 + 256 + 250  # after 12 s still, as it moves
