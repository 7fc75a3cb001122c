"""``continuum-mhe calibrate --from RAW.csv``: known answers on a constructed recording."""

from __future__ import annotations

import math
import re
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest
from live_helpers import alive

from continuum_mhe.calibration.at_rest import calibrate, mounting_from_gravity
from continuum_mhe.cli import main
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.imu import STANDARD_GRAVITY

#: The columns of one raw IMU's rest recording.
RAW_COLUMNS = ("t", "ax", "ay", "az", "gx", "gy", "gz")


def _write_rows(path: Path, columns: Sequence[str], rows: np.ndarray) -> None:
    """A CSV of ``rows`` under ``columns``, each value as Python writes it (every digit)
    and every line ended."""
    lines = [",".join(columns), *(",".join(repr(float(v)) for v in r) for r in rows)]
    path.write_text("\n".join(lines) + "\n")


G = 9.80665


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_mounting_from_gravity_inverts_the_mount_rotation(mounting: str) -> None:
    up = G if mounting == "z-up" else -G
    for rpy in [(10.0, -20.0, 0.0), (-35.0, 5.0, 0.0), (0.0, 0.0, 0.0)]:
        m = mount_rotation(rpy).T @ np.array([0.0, 0.0, up])  # what the tilted sensor reads
        np.testing.assert_allclose(mounting_from_gravity(m, mounting), rpy, atol=1e-9)  # type: ignore[arg-type]


def test_calibrate_from_a_recording_of_two_imus(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    n, dt, d = 500, 0.002, 0.05
    rpy = [(12.0, -7.0, 0.0), (-3.0, 25.0, 0.0)]
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)  # +-d: mean 0, std d*sqrt(n/(n-1))
    cols, blocks = ["t"], []
    for k, r in enumerate(rpy, start=1):
        acc = np.tile(mount_rotation(r).T @ [0, 0, G], (n, 1))
        acc[:, 0] += d * sign
        gyr = np.tile([0.01 * k, -0.02, 0.003], (n, 1))
        blocks.append(np.hstack([acc, gyr]))
        cols += [f"{c}_{k}" for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    t = 100.0 + dt * np.arange(n)
    path = tmp_path / "rest.csv"
    rows = np.column_stack([t, *blocks])
    _write_rows(path, cols, rows)
    cal = calibrate(t, np.hstack(blocks), "raw", 2, "z-up")
    assert cal.rate_hz == pytest.approx(500.0, rel=1e-9)
    for k, imu in enumerate(cal.imus):
        assert imu.std[0] == pytest.approx(d * math.sqrt(n / (n - 1)), rel=1e-9)
        np.testing.assert_allclose(imu.mean[3:], [0.01 * (k + 1), -0.02, 0.003], atol=1e-12)
        # the mean is off the noise-free reading by the mean of +-d (0): the mounting is exact
        np.testing.assert_allclose(imu.mount_rpy, rpy[k], atol=1e-9)  # type: ignore[arg-type]
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0, err
    assert "500 samples over 0.998 s of device time: 500.0 Hz" in out
    assert "IMU 1: mounting with the robot straight: --mount-rpy 12,-7,0" in out
    assert "IMU 2: mounting with the robot straight: --mount-rpy -3,25,0" in out
    assert "IMU 2: gyro bias (rad/s) gx=0.02000 gy=-0.02000 gz=0.00300" in out
    assert "(robot file: gyro_bias = [0.020000, -0.020000, 0.003000])" in out  # to paste
    # the noise at rest as tilt (the x axis' alone), said not to be estimate's --noise-deg
    tilt_noise = math.degrees(d * math.sqrt(n / (n - 1)) / G)
    assert (
        f"accelerometer noise as tilt: {tilt_noise:.2f} deg at rest (not estimate's "
        "--noise-deg, the scatter in motion: keep its default)" in out
    )


def _calibrate_port(
    tmp_path: Path, lines: list[str], seconds: str = "2", more: tuple[str, ...] = ()
) -> tuple[int, str, str]:
    """``calibrate --port`` for ``seconds`` (and the options ``more``) on a
    pseudo-terminal that sends ``lines``: ``(exit status, stdout, stderr)``."""
    from live_helpers import LiveProcess, new_pty, send_and_finish

    port = tmp_path / "ttyIMU"
    master = new_pty(port)
    argv = ["--port", str(port), "--seconds", seconds, *more]
    cal = LiveProcess(argv, command="calibrate", stdout=True)
    code = send_and_finish(cal, master, lines)
    assert cal.proc.stdout is not None
    return code, cal.proc.stdout.read(), cal.err


def _device_lines(acc: np.ndarray) -> list[str]:
    """The banner and a line per accelerometer row of ``acc`` (n, 3), 100 Hz, one IMU
    with a small gyro bias."""
    from live_helpers import alive, raw_line

    lines = ["# continuum_imu 1.1.0 imus=1", "# fields: t_ms,ax,ay,az,gx,gy,gz (ms)"]
    gyr = np.array([[0.002, 0.0, -0.001]])
    return lines + [raw_line(1000 + 10 * i, a[None], alive(gyr, i)) for i, a in enumerate(acc)]


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port(tmp_path: Path) -> None:
    """A device at rest, tilted by a known mounting, through a pseudo-terminal: the
    device's messages are shown and the mounting comes back."""
    acc = mount_rotation((8.0, 4.0, 0.0)).T @ [0, 0, G]
    code, out, err = _calibrate_port(tmp_path, _device_lines(np.tile(acc, (400, 1))))
    assert code == 0, err
    assert "device says: # continuum_imu 1.1.0 imus=1" in err
    assert "201 samples over 2.000 s of device time: 100.0 Hz" in out
    assert "--mount-rpy 8,4,0" in out


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_names_a_device_clock_in_microseconds(tmp_path: Path) -> None:
    """A device at 50 Hz that sends micros() as t_ms, its lines 20 ms apart in arrival
    and 20,000 apart in t_ms (each far ahead of the last): one line naming
    microseconds, exit 2 (not every line skipped as out of order and the stream called
    silent)."""
    import os
    import time

    from live_helpers import LiveProcess, new_pty

    lines = _device_lines(np.tile([0.0, 0.0, G], (60, 1)))
    for i in range(2, len(lines)):  # 50 Hz, the device's microseconds as t_ms
        t_ms, rest = lines[i].split(",", 1)
        lines[i] = f"{int(t_ms) * 2000},{rest}"
    port = tmp_path / "ttyIMU"
    master = new_pty(port)
    cal = LiveProcess(["--port", str(port), "--seconds", "2"], command="calibrate", stdout=True)
    try:
        cal.wait_ready()
        for line in lines:  # at the device's pace: the check compares it with arrival
            os.write(master, (line + "\n").encode())
            time.sleep(0.02)
        code = cal.finish()
    finally:
        if cal.proc.poll() is None:
            cal.proc.kill()
        os.close(master)
    assert code == 2, cal.err
    assert "t_ms in microseconds?" in cal.err and cal.err.count("error:") == 1, cal.err


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_skips_a_corrupted_or_repeated_line(tmp_path: Path) -> None:
    """One line whose t_ms lost a digit (13 s back) and lines sent twice: each skipped
    and counted, the samples before them kept (no starting over), the median step the
    board's 10 ms (the rate over the span counts the line lost)."""
    acc = np.tile([0.0, 0.0, G], (400, 1))
    lines = _device_lines(acc)
    for i in range(2, len(lines)):  # device times from 20 s on
        t_ms, rest = lines[i].split(",", 1)
        lines[i] = f"{int(t_ms) + 19000},{rest}"
    glitch = lines[150].split(",", 1)
    lines[150] = f"{int(glitch[0]) - 13000},{glitch[1]}"  # a digit lost
    for i in (120, 90, 60):  # three lines sent twice
        lines.insert(i, lines[i])
    code, out, err = _calibrate_port(tmp_path, lines)
    assert code == 0, err
    assert "starting over" not in err
    assert "4 line(s) out of order skipped" in err, err
    assert "200 samples over 2.000 s of device time: 99.5 Hz (median step 10.00 ms" in out, out


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_says_a_board_sending_degrees_must_send_radians(
    tmp_path: Path,
) -> None:
    """A board that sends its tilt in degrees (1 and -1, read as radians): the warning
    says the board must send radians (--degrees is for a recording)."""
    wobble = 1e-3 * np.where(np.arange(300) % 2 == 0, 1.0, -1.0)[:, None]
    rows = np.tile([1.0, -1.0], (300, 1)) + wobble
    lines = ["# continuum_imu 1.1.0 imus=1"]
    lines += [f"{10 * k},{r:.5f},{p:.5f}" for k, (r, p) in enumerate(rows)]
    code, out, err = _calibrate_port(tmp_path, lines, more=("--format", "tilt"))
    assert code == 0, err
    warning = [ln for ln in err.splitlines() if "degrees?" in ln]
    assert len(warning) == 1 and warning[0].endswith("degrees? the board must send radians")


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_names_a_gyro_in_deg_s(tmp_path: Path) -> None:
    """A still board whose gyro sends deg/s (a bias of 2.1 deg/s, noise 0.1 deg/s as the
    shipped rod's MPU9250s have in rad/s): one line saying deg/s, as ``--from`` and
    ``live`` say it, not "the robot moved" and to raise --still-gyro-std (its noise in
    deg/s, read as rad/s, is twice the stillness bound)."""
    rng = np.random.default_rng(3)
    n = 200
    acc = np.tile([0.1, -0.05, G], (n, 1)) + 0.02 * rng.standard_normal((n, 3))
    gyr_rad = np.array([0.03, -0.02, 0.005]) + 0.0018 * rng.standard_normal((n, 3))
    lines = ["# continuum_imu 1.1.0 imus=1", "# fields: t_ms,ax,ay,az,gx,gy,gz (ms)"]
    lines += [
        "{},{}".format(2300 + 10 * i, ",".join(f"{v:.5f}" for v in (*a, *np.degrees(w))))
        for i, (a, w) in enumerate(zip(acc, gyr_rad))
    ]
    code, out, err = _calibrate_port(tmp_path, lines, seconds="1.5")
    assert code == 2 and out == ""
    error = [ln for ln in err.splitlines() if ln.startswith("continuum-mhe: error:")]
    assert len(error) == 1 and "with the gyro in deg/s" in error[0], err
    assert error[0].endswith("give rad/s (gx, gy, gz times pi/180 = 0.0174533)")
    assert "the robot moved" not in err and "--still-gyro-std" not in err


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_refuses_a_moving_robot(tmp_path: Path) -> None:
    """The device tilts from 0 to 30 deg about x while calibrate reads it: exit 2."""
    a = np.radians(np.linspace(0.0, 30.0, 400))
    acc = np.column_stack([np.zeros_like(a), G * np.sin(a), G * np.cos(a)])
    code, out, err = _calibrate_port(tmp_path, _device_lines(acc))
    assert code == 2, err
    assert out == ""
    assert "the robot moved: IMU 1's accelerometer spread (std of ay) is" in err
    assert "above the 0.2 m/s^2 of a still robot" in err


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_names_the_garbled_lines(tmp_path: Path) -> None:
    """Two IMUs' lines to a one-IMU calibrate: the first garbled line's cause (not 'is
    it streaming?'), once garbled lines have come for 2 s beyond --seconds with no valid
    one (not after the board's 15 s start-up allowance)."""
    from live_helpers import raw_line

    acc, gyr = np.tile([0.0, 0.0, G], (2, 1)), np.zeros((2, 3))
    lines = [raw_line(1000 + 10 * i, acc, gyr) for i in range(50)]
    code, _, err = _calibrate_port(tmp_path, lines, seconds="0.1")
    port = tmp_path / "ttyIMU"
    assert code == 2, err
    assert err.splitlines()[-1] == (
        f"continuum-mhe: error: {port}: 0 valid sample(s) in 2.1 s of garbled lines; 50 "
        "garbled line(s), the "
        "first: expected 7 fields, found 13: a line of 2 IMU(s) in --format raw; --robot with "
        "2 IMU(s)?; check --format, --robot and --baud"
    )


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_leaves_out_lines_with_one_bad_imu(tmp_path: Path) -> None:
    """Live keeps the good IMU of a line with one bad field (a dropout of the other);
    calibrate needs every IMU of a sample, so it counts such a line as garbled instead of
    averaging a NaN into the calibration."""
    from live_helpers import raw_line

    acc, gyr = np.tile([0.0, 0.0, G], (2, 1)), np.zeros((2, 3))
    lines = [raw_line(1000 + 10 * i, acc, alive(gyr, i)) for i in range(400)]
    for i in range(0, 400, 10):  # IMU 2's az unreadable on every tenth line
        fields = lines[i].split(",")
        fields[9] = "x"
        lines[i] = ",".join(fields)
    code, out, err = _calibrate_port(tmp_path, lines, more=("--robot", "two-section"))
    assert code == 0, err
    assert "nan" not in out
    # lines 1 to 202 (the 200th is bad: 2 s end at 202), less every tenth: 182
    assert "182 samples over 2.010 s of device time" in out, out
    assert "garbled line(s) skipped" in err


def _rest_values(n: int, acc_swing: float, gyro_swing: float, tilt_deg: float = 0.0) -> np.ndarray:
    """(n, 6) raw samples of one IMU: gravity tilted by ``tilt_deg`` about x, with ``+-acc_swing``
    on ay and ``+-gyro_swing`` on gx around a gyro bias of 0.1 rad/s per axis."""
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    a = np.radians(tilt_deg)
    acc = np.tile([0.0, G * math.sin(a), G * math.cos(a)], (n, 1))
    acc[:, 1] += acc_swing * sign
    gyr = np.full((n, 3), 0.1)  # a large bias is no motion
    gyr[:, 0] += gyro_swing * sign
    return np.hstack([acc, gyr])


def test_motion_at_rest_names_the_largest_spread_against_its_bound() -> None:
    from continuum_mhe.calibration.at_rest import STILL_ACC_STD, STILL_GYRO_STD, motion_at_rest

    n = 400  # +-d has std d * sqrt(n / (n - 1))
    d_in = 0.99 * STILL_ACC_STD * math.sqrt((n - 1) / n)
    assert motion_at_rest(_rest_values(n, d_in, 0.99 * STILL_GYRO_STD), "raw", 1) is None
    moved = motion_at_rest(_rest_values(n, 1.02 * STILL_ACC_STD, 0.0), "raw", 1)
    assert moved is not None and "IMU 1's accelerometer spread (std of ay) is 0.204 m/s^2" in moved
    assert "above the 0.2 m/s^2 of a still robot" in moved
    # IMU 2 turns (gyro), IMU 1 is still
    two = np.hstack([_rest_values(n, 0.0, 0.0), _rest_values(n, 0.0, 0.5)])
    moved = motion_at_rest(two, "raw", 2)
    assert moved is not None and "IMU 2's gyro spread (std of gx) is 0.501 rad/s" in moved
    # tilt: a hanging robot's roll around +-pi is still; a swinging pitch is not
    roll = np.where(np.arange(n) % 2 == 0, math.pi - 0.001, -math.pi + 0.001)
    tilt = np.column_stack([roll, np.full(n, 0.2)])
    assert motion_at_rest(tilt, "tilt", 1) is None
    tilt[:, 1] += np.linspace(-0.5, 0.5, n)
    moved = motion_at_rest(tilt, "tilt", 1)
    assert moved is not None and "IMU 1's tilt spread (std of pitch) is 0.29 rad" in moved


def _calibrate_main(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    from continuum_mhe.cli import main

    code = main(["calibrate", *args])
    out, err = capsys.readouterr()
    return code, out, err


def test_calibrate_refuses_a_moving_recording(capsys: pytest.CaptureFixture[str]) -> None:
    """The shipped planar-S run bends to 87 deg: refused in one line as a moving robot
    (taken as still, it would give mount_rpy = [43.85, -0.60, 0])."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    robot = ("--robot", "two-section")
    code, out, err = _calibrate_main(capsys, "--from", str(data / "planar-s_raw.csv"), *robot)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1
    assert (
        "planar-s_raw.csv: the robot moved: IMU 1's accelerometer spread (std of ay) is "
        "4.15 m/s^2, above the 0.2 m/s^2 of a still robot" in err
    )
    # its rest recording passes, and a bend belongs to --bend, not --from
    code, _, err = _calibrate_main(capsys, "--from", str(data / "planar-s_rest.csv"), *robot)
    assert code == 0, err
    code, _, err = _calibrate_main(capsys, "--from", str(data / "planar-s_bend.csv"), *robot)
    assert code == 2 and "--bend BEND.csv" in err


def test_an_accelerometer_off_g_at_rest_is_noted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped planar-S rest with IMU 2's accelerometer scaled by 1.03 (a scale error
    inside MEMS specifications) reads 3.8 % over g: calibrate says so in a note naming the
    IMU and pointing to the six-position method, which a rest cannot replace; the rest as
    shipped gets no such note."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    rest = data / "planar-s_rest.csv"
    robot = ("--robot", "two-section")
    code, _, err = _calibrate_main(capsys, "--from", str(rest), *robot)
    assert code == 0 and "from g" not in err, err
    header, *rows = rest.read_text().splitlines()
    values = np.array([[float(v) for v in r.split(",")] for r in rows])
    values[:, 7:10] *= 1.03  # ax_2, ay_2, az_2
    scaled = tmp_path / "scaled_rest.csv"
    scaled.write_text(
        header + "\n" + "\n".join(",".join(f"{v:.10g}" for v in r) for r in values) + "\n"
    )
    code, _, err = _calibrate_main(capsys, "--from", str(scaled), *robot)
    assert code == 0, err
    (note,) = [line for line in err.splitlines() if "from g" in line]
    assert note.startswith(f"continuum-mhe: note: {scaled}: the accelerometer magnitude at rest")
    # (IMU 2 reads 0.8 % over g as shipped: its accelerometer bias)
    assert "IMU 2 10.183 m/s^2 (+3.8 %)" in note and "IMU 1 " not in note
    assert "six-position method" in note


def test_the_stillness_bounds_are_options_for_a_noisier_imu(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A still robot with an IMU noisier than the MPU9250 (here +-0.3 m/s^2 on ay, std
    0.3; +-0.06 rad/s on gx) can be calibrated: the default stillness bounds refuse it
    and say which option to raise; --still-acc-std and --still-gyro-std let it pass,
    with the exact mounting."""
    n = 400
    values = _rest_values(n, 0.3, 0.06, tilt_deg=5.0)
    t = 0.01 * np.arange(n)
    path = tmp_path / "noisy_rest.csv"
    rows = np.column_stack([t, values])
    _write_rows(path, RAW_COLUMNS, rows)
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 2 and out == ""
    assert err == (
        f"continuum-mhe: error: {path}: the robot moved: IMU 1's accelerometer spread (std of "
        "ay) is 0.3 m/s^2, above the 0.2 m/s^2 of a still robot; calibrate needs it straight "
        "and still (a bend in a known plane goes to --bend BEND.csv); if the robot was still, "
        "raise --still-acc-std\n"
    )
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--still-acc-std", "0.4")
    assert code == 2 and out == ""  # then the gyro's spread is the one beyond its bound
    assert "IMU 1's gyro spread (std of gx) is 0.0601 rad/s, above the 0.05 rad/s" in err
    assert err.endswith("; if the robot was still, raise --still-gyro-std\n")
    args = ["--from", str(path), "--still-acc-std", "0.4", "--still-gyro-std", "0.1"]
    code, out, err = _calibrate_main(capsys, *args)
    assert code == 0, err
    assert "IMU 1: mounting with the robot straight: --mount-rpy 5," in out  # pitch 0


def test_a_gyro_spread_with_still_accelerometers_suggests_deg_s(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A rest recording whose accelerometer is still but whose gyro spreads by 0.35 (a
    MEMS gyro's noise in deg/s, read as rad/s): the refusal says the accelerometers
    stayed still and asks whether the gyro is in deg/s, instead of "the robot moved";
    a gyro only a little beyond its bound (a noisy IMU) still gets "the robot moved"."""
    n = 400
    t = 0.01 * np.arange(n)
    path = tmp_path / "rest_degs.csv"
    for swing, deg_s in ((0.35, True), (0.06, False)):
        rows = np.column_stack([t, _rest_values(n, 0.0, swing, tilt_deg=5.0)])
        _write_rows(path, RAW_COLUMNS, rows)
        code, out, err = _calibrate_main(capsys, "--from", str(path))
        assert code == 2 and out == "" and err.count("\n") == 1
        assert "IMU 1's gyro spread (std of gx) is" in err
        if deg_s:
            assert "while every accelerometer stayed still: a gyro in deg/s? give rad/s" in err
            assert "the robot moved" not in err
        else:
            assert f"{path}: the robot moved: IMU 1's gyro spread" in err
            assert "deg/s" not in err


def test_a_raised_gyro_bound_over_still_accelerometers_warns_of_deg_s(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A gyro in deg/s with 0.1 deg/s of noise (the firmware's MPU9250's) spreads by 0.1
    "rad/s", twice the bound, which the refusal cannot tell from a noisy gyro: it says
    to raise --still-gyro-std. Raised, the calibration goes through and writes the
    deg/s mean as the gyro bias, with a warning that says a gyro in deg/s reads so; an
    IMU whose accelerometer spread as much (a noisy IMU, both bounds raised) is not
    said, nor a gyro within the default bound."""
    n = 400
    t = 0.01 * np.arange(n)
    path = tmp_path / "rest_deg_s.csv"
    _write_rows(path, RAW_COLUMNS, np.column_stack([t, _rest_values(n, 0.0, 0.1, 5.0)]))
    code, _, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 2 and err.endswith("; if the robot was still, raise --still-gyro-std\n")
    out_toml = tmp_path / "cal.toml"
    args = ["--from", str(path), "--still-gyro-std", "0.2", "--write-robot", str(out_toml)]
    code, _, err = _calibrate_main(capsys, *args)
    assert code == 0 and out_toml.exists()
    assert (
        f"continuum-mhe: warning: {path}: IMU 1's gyro spread (std of gx) is 0.1 rad/s at "
        "rest, above the 0.05 rad/s of a still robot, while its accelerometer stayed still: "
        "a gyro in deg/s reads so (its noise, 0.1 deg/s, a MEMS gyro's), and its gyro_bias "
        "would then be 57.3 times too large: give rad/s (gx, gy, gz times pi/180 = "
        "0.0174533) and calibrate again\n"
    ) in err
    noisy = np.column_stack([t, _rest_values(n, 0.3, 0.1, 5.0)])
    _write_rows(path, RAW_COLUMNS, noisy)
    args[2:] = ["--still-gyro-std", "0.2", "--still-acc-std", "0.4"]
    code, _, err = _calibrate_main(capsys, *args)
    assert code == 0 and "warning" not in err, err
    _write_rows(path, RAW_COLUMNS, np.column_stack([t, _rest_values(n, 0.0, 0.04, 5.0)]))
    code, _, err = _calibrate_main(capsys, *args[:2], "--still-gyro-std", "0.2")
    assert code == 0 and "warning" not in err, err


def test_the_tilt_stillness_bound_follows_still_acc_std(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tilt recording's bound is --still-acc-std over g (default 0.2 / 9.81 = 0.0204 rad)."""
    n = 200
    sign = np.where(np.arange(n) % 2 == 0, 1.0, -1.0)
    path = tmp_path / "tilt_rest.csv"
    rows = [f"{0.01 * i!r},{0.1 + 0.03 * float(sign[i])!r},-0.2" for i in range(n)]
    path.write_text("t,roll,pitch\n" + "\n".join(rows) + "\n")
    code, _, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 2 and "above the 0.0204 rad of a still robot" in err
    # a spread that scatters as noise, in degrees within the bound: degrees named too
    assert err.endswith(
        "raise --still-acc-std (bound: it / g); or are the angles in degrees? (read as "
        "degrees, every spread is within the bound, 0.0301 degrees at most) pass --degrees\n"
    )
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--still-acc-std", "0.4")
    assert code == 0, err
    assert "IMU 1: roll mean 5.730 deg" in out
    # a tilt recording has no gyro: the gyro bound would do nothing, so it is refused
    code, out, err = _calibrate_main(
        capsys, "--from", str(path), "--still-acc-std", "0.4", "--still-gyro-std", "0.1"
    )
    assert (code, out) == (2, "") and err.endswith(
        "tilt_rest.csv: --still-gyro-std needs a raw recording (this one is tilt)\n"
    )


def test_the_printed_mounting_keeps_the_robot_files_yaw(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An IMU mounted turned 90 degrees about its disk's axis (``mount_rpy = [0, 0, 90]``
    in the robot file): gravity does not see the yaw, so calibrate prints the roll and
    pitch it measures with the file's yaw, as ``--write-robot`` writes it; a line copied
    from the output into the robot file keeps the mounting."""
    robot = tmp_path / "robot.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.2\ntheta_max = 3.0\n'
        "[[imu]]\nsection = 1\nmount_rpy = [0.0, 0.0, 90.0]\n"
    )
    n = 200
    acc = np.tile(mount_rotation((4.0, -2.0, 90.0)).T @ [0, 0, G], (n, 1))
    rows = np.column_stack([0.01 * np.arange(n), alive(np.hstack([acc, np.zeros((n, 3))]))])
    path = tmp_path / "rest.csv"
    _write_rows(path, RAW_COLUMNS, rows)
    written = tmp_path / "calibrated.toml"
    code, out, err = _calibrate_main(
        capsys, "--from", str(path), "--robot", str(robot), "--write-robot", str(written)
    )
    assert code == 0, err
    assert (
        "IMU 1: mounting with the robot straight: --mount-rpy 4,-2,90 (robot file: "
        "mount_rpy = [4, -2, 90]); yaw: the robot file's" in out
    )
    from continuum_mhe.io.robot_file import read_robot

    np.testing.assert_allclose(read_robot(written).imus[0].mount_rpy, (4.0, -2.0, 90.0), atol=1e-6)


@pytest.mark.parametrize(
    ("option", "value", "needle"),
    [
        ("--still-acc-std", "0", "--still-acc-std 0.0 is outside its valid range (0, 10] m/s^2"),
        ("--still-gyro-std", "50", "degrees? --still-gyro-std is in rad/s"),
    ],
)
def test_the_stillness_options_are_range_checked(
    capsys: pytest.CaptureFixture[str], option: str, value: str, needle: str
) -> None:
    code, out, err = _calibrate_main(capsys, "--from", "unread.csv", option, value)
    assert code == 2 and out == "" and needle in err and err.count("\n") == 1


@pytest.mark.skipif(not hasattr(__import__("os"), "openpty"), reason="needs a pseudo-terminal")
def test_calibrate_from_the_port_takes_lines_with_tensions(tmp_path: Path) -> None:
    """A tendon robot's board sends its tensions after the IMUs' fields (as ``live``
    reads them): calibrate takes those lines as samples, and lines without the
    tensions too, instead of counting either as garbled."""
    from live_helpers import raw_line

    acc = np.tile(mount_rotation((5.0, -3.0, 0.0)).T @ [0, 0, G], (2, 1))
    gyr = np.zeros((2, 3))
    tensions = ",0.0,1.5,0.25,0.0,2.0,0.0"  # the shipped robot's six tendons, N
    lines = [
        raw_line(1000 + 10 * i, acc, alive(gyr, i)) + (tensions if i % 2 else "")
        for i in range(400)
    ]
    code, out, err = _calibrate_port(tmp_path, lines, more=("--robot", "tendon-two-section"))
    assert code == 0, err
    assert "garbled" not in err
    assert "IMU 1: mounting with the robot straight: --mount-rpy 5,-3,0" in out
    assert "IMU 2: mounting with the robot straight: --mount-rpy 5,-3,0" in out


def _turned_over_about_y(source: Path, out: Path, imus: tuple[int, ...]) -> None:
    """The raw recording ``source`` written to ``out`` with the IMUs ``imus`` (numbered
    from 1) turned over about their y axis: x and z of the accelerometer and gyro
    negated."""
    header, *rows = source.read_text().splitlines()
    names = header.split(",")
    flip = [names.index(f"{c}_{k}") for k in imus for c in ("ax", "az", "gx", "gz")]
    turned = []
    for row in rows:
        v = row.split(",")
        for j in flip:
            v[j] = repr(-float(v[j]))
        turned.append(",".join(v))
    out.write_text("\n".join([header, *turned]) + "\n")


def test_calibrate_refuses_a_robot_file_whose_mounting_gravity_contradicts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shipped rod stands on its base (z-up). Described as z-down, its rest
    recording puts every IMU about 180 degrees from where z-down puts it (calibrated,
    mount_rpy = [179.8, 0.19, 0] for each, every board "upside down", and estimates
    mirrored, 183 mm off, every row ok): refused in one line naming mounting, nothing
    written; one IMU turned over on its disk still calibrates."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    robot = tmp_path / "down.toml"
    robot.write_text(
        'mounting = "z-down"\n[[section]]\nlength = 0.16\ntheta_max = 3.0\n'
        "[[section]]\nlength = 0.14\ntheta_max = 3.0\n[[imu]]\nsection = 1\n[[imu]]\nsection = 2\n"
    )
    out = tmp_path / "cal.toml"
    rest = str(data / "planar-s_rest.csv")
    code, stdout, err = _calibrate_main(
        capsys, "--from", rest, "--robot", str(robot), "--write-robot", str(out)
    )
    assert code == 2 and stdout == "" and not out.exists()
    assert err.count("\n") == 1
    assert "planar-s_rest.csv: mounting: the robot is described as z-down" in err
    assert 'set mounting = "z-up"' in err
    one = tmp_path / "one_rest.csv"  # IMU 1 alone, for the one-section options
    table = [ln.split(",")[:7] for ln in Path(rest).read_text().splitlines()]
    table[0] = ["t", "ax", "ay", "az", "gx", "gy", "gz"]
    one.write_text("\n".join(",".join(r) for r in table) + "\n")
    code, _, err = _calibrate_main(capsys, "--from", str(one), "--mounting", "z-down")
    assert code == 2 and "the robot stands on its base? --mounting z-up; or, where " in err
    # one board upside down on a robot mounted as described reads the same: said too
    assert err.rstrip().endswith(
        "its board is upside down on it: give its mount_rpy (a roll of 180 degrees) "
        "in the robot file"
    )
    code, _, err = _calibrate_main(capsys, "--from", rest, "--robot", "two-section")
    assert code == 0, err
    # IMU 2's readings turned over (x and z negated: 180 degrees about y): one board
    # mounted upside down is calibrated, with a pitch of about 180 degrees
    lines = Path(rest).read_text().splitlines()
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    names = lines[head].split(",")
    flip = [names.index(c) for c in names if c in ("ax_2", "az_2", "gx_2", "gz_2")]
    assert len(flip) == 4, names
    rows = []
    for ln in lines[head + 1 :]:
        v = ln.split(",")
        for j in flip:
            v[j] = repr(-float(v[j]))
        rows.append(",".join(v))
    turned = tmp_path / "turned_rest.csv"
    turned.write_text("\n".join(lines[: head + 1] + rows) + "\n")
    code, stdout, err = _calibrate_main(
        capsys, "--from", str(turned), "--robot", "two-section", "--write-robot", str(out)
    )
    assert code == 0, err
    assert out.exists()
    # calibrated, and said: a robot mounted the other way reads so in all but one board
    assert "warning: " + str(turned) + ": IMU 2 (of 2) reads gravity 178 degrees" in err, err
    assert 'the robot hangs from its base, set mounting = "z-down" in the robot file' in err


def test_calibrate_refuses_most_imus_upside_down_against_the_mounting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot hanging from its base (its tip board mounted upside down) described as
    standing: at rest IMUs 1 and 2 of 3 read gravity upside down, IMU 3 upright. Refused
    in one line naming mounting, nothing written, as a rest in which every IMU reads
    upside down is (calibrated, IMUs 1 and 2 would get rolls of 180 degrees and the
    estimates would be the truth mirrored, 197 mm off, every row ok); described as
    hanging, IMU 3 is calibrated as upside down, with a warning."""
    from continuum_mhe.cli import main

    sections = "".join(f"[[section]]\nlength = {v}\ntheta_max = 3.0\n" for v in (0.12, 0.1, 0.08))
    imus = "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3))
    up, down = tmp_path / "up.toml", tmp_path / "down.toml"
    up.write_text('mounting = "z-up"\n' + sections + imus)
    down.write_text('mounting = "z-down"\n' + sections + imus)
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "--robot", str(up), "--imu", "raw", "-o", str(rest)]) == 0
    hanging = tmp_path / "hanging_rest.csv"
    _turned_over_about_y(rest, hanging, (1, 2))
    out = tmp_path / "cal.toml"
    capsys.readouterr()
    code, stdout, err = _calibrate_main(
        capsys, "--from", str(hanging), "--robot", str(up), "--write-robot", str(out)
    )
    assert code == 2 and stdout == "" and not out.exists()
    assert err.count("\n") == 1, err
    assert f"{hanging}: mounting: the robot is described as z-up, but at rest gravity puts " \
        "IMUs 1 and 2 (of 3) 180 degrees from where that mounting puts them: the robot hangs " \
        'from its base? set mounting = "z-down" in the robot file' in err, err  # fmt: skip
    code, stdout, err = _calibrate_main(
        capsys, "--from", str(hanging), "--robot", str(down), "--write-robot", str(out)
    )
    assert code == 0 and out.exists(), err
    assert "IMU 3 (of 3) reads gravity 180 degrees" in err and "IMUs 1" not in err, err


def test_a_board_upside_down_at_rest_says_its_yaw_is_unseen(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2 of the two-section robot turned over about its y axis (x and z reversed) at
    rest: gravity reads as for a board turned over about its x axis, which calibrate
    writes (a roll of 180 degrees, the file's yaw), 180 degrees off in yaw for this one
    (a hanging three-section robot so calibrated: no row ok, 195 mm off on average). The
    upside-down warning says that the yaw is the file's and that --bend measures it."""
    rest = tmp_path / "rest.csv"
    assert (
        main(["simulate", "rest", "--robot", "two-section", "--imu", "raw", "-o", str(rest)]) == 0
    )
    _turned_over_about_y(rest, rest, (2,))
    capsys.readouterr()
    code, out, err = _calibrate_main(capsys, "--from", str(rest), "--robot", "two-section")
    assert code == 0 and "IMU 2: mounting" in out, err
    assert err.count("\n") == 1, err
    assert "IMU 2 (of 2) reads gravity 180 degrees" in err, err
    assert (
        "its yaw is the robot file's, right for a board turned over about its x axis: one "
        "turned over about its y axis reads gravity alike and lies 180 degrees from that yaw"
    ) in err and "(--bend) measures it" in err, err


def test_calibrate_reads_files_and_writes_robot_files(tmp_path, capsys) -> None:
    """--from - (standard input, which calibrate would read twice) is refused in one
    line, as a pipe is; --write-robot takes a .toml name; a nan reading names what
    calibrate needs, not --skip-bad, which calibrate does not have."""
    import sys
    from io import StringIO
    from pathlib import Path

    from continuum_mhe.cli import main

    rest = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    rest = rest / "spatial-tendon_rest.csv"
    stdin = sys.stdin
    sys.stdin = StringIO(rest.read_text())
    try:
        assert main(["calibrate", "--from", "-", "--robot", "two-section"]) == 2
    finally:
        sys.stdin = stdin
    assert "--from reads a file (not standard input" in capsys.readouterr().err
    out = tmp_path / "cal.png"
    argv = ["calibrate", "--from", str(rest), "--robot", "two-section", "--write-robot", str(out)]
    assert main(argv) == 2
    assert "--write-robot writes a robot file (.toml)" in capsys.readouterr().err
    lines = rest.read_text().splitlines()
    cells = lines[11].split(",")
    cells[3] = "nan"
    lines[11] = ",".join(cells)
    nan = tmp_path / "nan.csv"
    nan.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", "--from", str(nan), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err
    assert "calibrate needs every reading of the still robot" in err and "--skip-bad" not in err


def test_a_rest_recording_too_short_to_calibrate_is_refused(tmp_path, capsys) -> None:
    """Two rows (0.02 s), or an IMU read in 3 rows of 601, are refused in one line naming
    the file, nothing written (not calibrated without a word)."""
    from pathlib import Path

    from continuum_mhe.cli import main

    rest = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (rest / "spatial-tendon_rest.csv").read_text().splitlines()
    header = lines[0]
    short = tmp_path / "short.csv"
    short.write_text("\n".join(lines[:3]) + "\n")
    sparse = tmp_path / "sparse.csv"
    i2 = [i for i, c in enumerate(header.split(",")) if c.endswith("_2")]
    rows = [header]
    for n, ln in enumerate(lines[1:]):
        cells = ln.split(",")
        if n >= 3:
            for i in i2:
                cells[i] = ""
        rows.append(",".join(cells))
    sparse.write_text("\n".join(rows) + "\n")
    for path, needle in ((short, "calibration needs the robot still for at least 0.5 s"),
                         (sparse, "IMU 2: 3 valid sample(s)")):  # fmt: skip
        out = tmp_path / "cal.toml"
        argv = ["calibrate", "--from", str(path), "--robot", "two-section", "--write-robot",
                str(out)]  # fmt: skip
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"{path}: " in err and needle in err, err
        assert not out.exists()
    # seconds in a column named t_ms: the rest is 1000 times too short, and the error
    # says why, not only that it is short
    seconds = tmp_path / "seconds_as_ms.csv"
    seconds.write_text("\n".join([header.replace("t,", "t_ms,", 1), *lines[1:]]) + "\n")
    assert main(["calibrate", "--from", str(seconds), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("times in another unit (seconds in a t_ms column?)"), err


def test_the_serial_line_s_options_with_a_recording_are_refused(capsys) -> None:
    """--seconds (and --baud, --format, --port) with --from are refused, not ignored."""
    from pathlib import Path

    from continuum_mhe.cli import main

    rest = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    argv = ["calibrate", "--from", str(rest / "spatial-tendon_rest.csv"), "--robot", "two-section"]
    for extra in (["--seconds", "5"], ["--baud", "9600"]):
        assert main([*argv, *extra]) == 2
        assert f"{extra[0]} does not apply with --from" in capsys.readouterr().err
    assert main(argv) == 0


@pytest.mark.parametrize("name", ["rest.mcap", "rest.bag", "rest.db3"])
def test_calibrate_from_a_damaged_robot_log_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str
) -> None:
    """A ROS bag or MCAP file cut short in its header is read as a robot log (by its
    topics) and refused in one line naming it, nothing written."""
    log = tmp_path / name
    log.write_bytes(b"\x89MCAP0\r\n")
    out = tmp_path / "robot.toml"
    argv = ["calibrate", "--from", str(log), "--robot", "two-section", "--write-robot", str(out)]
    argv += ["--topic", "/imu1", "--topic", "/imu2"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(log) in err and "CSV" not in err
    assert not out.exists()


@pytest.mark.parametrize("cell", ["", "1e6"])
def test_an_empty_or_impossible_reading_left_out_is_said(tmp_path, capsys, cell) -> None:
    """An empty field or an acceleration of 1e6 m/s^2 on one row of a two-IMU rest
    recording (that IMU's dropout there) is left out of its mean and noise, and said with
    its time (the report's sample count is the file's rows)."""
    from continuum_mhe.cli import main

    rest = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (rest / "spatial-tendon_rest.csv").read_text().splitlines()
    cells = lines[11].split(",")
    cells[3] = cell
    lines[11] = ",".join(cells)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", "--from", str(bad), "--robot", "two-section"]) == 0
    err = capsys.readouterr().err
    t = float(cells[0])
    assert err == (
        f"continuum-mhe: warning: {bad}: 1 of {len(lines) - 1} row(s) with a reading missing, "
        f"zero or beyond any IMU's range (the first at t = {t:g} s): that IMU's reading is left "
        "out of its mean and noise there\n"
    )


@pytest.mark.parametrize("cells", [("0", "0", "0"), ("1e6", "0", "0")], ids=["zero", "huge"])
def test_an_impossible_reading_of_one_imu_is_left_out_as_of_several(
    tmp_path, capsys, cells
) -> None:
    """A zero acceleration, or one of 1e6 m/s^2, on one row of a one-IMU rest recording
    is left out and said, as one IMU's of several is, and the IMU's means, noise and
    mounting equal those of the recording without that row."""
    from continuum_mhe.cli import main

    rest = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (rest / "planar-s_rest.csv").read_text().splitlines()
    one = [",".join(line.split(",")[:7]).replace("_1", "") for line in lines]
    bad_cells = one[11].split(",")
    bad_cells[1:4] = cells
    bad, clean = tmp_path / "bad.csv", tmp_path / "clean.csv"
    bad.write_text("\n".join([*one[:11], ",".join(bad_cells), *one[12:]]) + "\n")
    clean.write_text("\n".join([*one[:11], *one[12:]]) + "\n")
    assert main(["calibrate", "--from", str(clean)]) == 0
    want = capsys.readouterr().out
    assert main(["calibrate", "--from", str(bad)]) == 0
    out, err = capsys.readouterr()
    assert err == (
        f"continuum-mhe: warning: {bad}: 1 of {len(one) - 1} row(s) with a reading missing, "
        f"zero or beyond any IMU's range (the first at t = {float(bad_cells[0]):g} s): that "
        "IMU's reading is left out of its mean and noise there\n"
    )
    # the same means, noise and mounting (the sample count and steps are the file's)
    imus = [line for line in out.splitlines() if line.startswith("IMU 1")]
    assert imus and imus == [line for line in want.splitlines() if line.startswith("IMU 1")]


def _two_imu_rest(path: Path, tilts_deg: tuple[float, float], n: int = 400) -> np.ndarray:
    """A two-IMU rest recording at 100 Hz (noise on each gyro's x), the IMUs tilted by
    ``tilts_deg`` about x; returns its values (n, 12)."""
    values = np.hstack([alive(_rest_values(n, 0.0, 0.0, tilt_deg=a)) for a in tilts_deg])
    _write_rest(path, values)
    return values


def _write_rest(path: Path, values: np.ndarray) -> None:
    cols = ["t"] + [f"{c}_{k}" for k in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    rows = np.column_stack([0.01 * np.arange(len(values)), values])
    _write_rows(path, cols, rows)


def test_a_frozen_imu_at_rest_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """IMU 2 repeating one reading exactly for 1.5 s of a rest (a stuck sensor, whose
    noise and offsets the calibration would have taken as its own) is refused in one
    line, as estimate's --freeze would flag it; the same IMU alive is calibrated."""
    path = tmp_path / "rest.csv"
    values = _two_imu_rest(path, (1.0, -2.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and "IMU 2: mounting" in out, err
    values[200:350, 6:] = values[200, 6:]  # and row 350 reads as row 200 does
    _write_rest(path, values)
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 2 and out == ""
    assert err == (
        f"continuum-mhe: error: {path}: IMU 2 repeats one reading exactly for 151 samples "
        "(1.5 s from t = 2 s): a frozen sensor, whose noise and offsets would be the "
        "freeze's; record the rest again\n"
    )


def test_a_rest_in_which_every_imu_reads_tilted_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every IMU tilted (12 and 20 degrees: a robot bent, or its base not level, at rest)
    is calibrated as the IMUs' mountings, which puts every estimate off (a user's robot:
    rows 57 mm off, `ok`): one warning with each IMU's tilt. One IMU tilted on its disk
    says nothing."""
    path = tmp_path / "rest.csv"
    _two_imu_rest(path, (12.0, 20.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and "--mount-rpy 20," in out
    assert err == (
        f"continuum-mhe: warning: {path}: every IMU reads more than 5 degrees from the "
        "straight robot's gravity direction (IMU 1 12.0, IMU 2 20.0 degrees), and mount_rpy "
        "takes that as its mounting: was the robot straight and its base level at rest? If "
        "not, every estimate is off by as much; record the rest again (IMUs mounted tilted "
        "on their disks are calibrated right)\n"
    )
    _two_imu_rest(path, (12.0, 1.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and err == ""
    # a board upside down counts from its pose: at 180 degrees it is not tilted, at 173
    # it is (as a robot bent, or a base not level, tilts every board off its pose)
    _two_imu_rest(path, (5.8, 180.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and "upside down" in err and "every IMU reads" not in err
    _two_imu_rest(path, (8.0, 173.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and (
        "every IMU reads more than 5 degrees from the straight robot's gravity direction (IMU "
        "1 8.0, IMU 2 7.0 degrees; a board on its side or upside down from that pose)"
    ) in " ".join(err.split())


_HANGING_THREE_SECTIONS = """mounting = "z-down"
[[section]]
length = 0.12
theta_max = 2.0
[[section]]
length = 0.18
theta_max = 2.0
[[section]]
length = 0.10
theta_max = 2.0
[[imu]]
section = 1
mount_rpy = [{0}, 90.0]
[[imu]]
section = 2
at = 0.5
mount_rpy = [{1}, -45.0]
[[imu]]
section = 2
mount_rpy = [{2}, 180.0]
[[imu]]
section = 3
mount_rpy = [{3}, 30.0]
"""


def _bent_rest(robot_path: Path, path: Path, theta1_deg: float, section: int = 0) -> None:
    """A raw rest (10 s at 20 Hz, the simulator's noise) of the robot file's robot, its
    section ``section`` (from 0; the first by default) bent by ``theta1_deg`` towards
    phi = 0, the others straight."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.model.kinematics import bend_from_shape
    from continuum_mhe.simulation.raw_readings import raw_readings
    from continuum_mhe.simulation.scenarios import Recording

    robot = read_robot(robot_path)
    t = np.arange(201) * 0.05
    bends = np.zeros((len(t), robot.n_sections, 2))
    a, b = bend_from_shape(np.full(len(t), math.radians(theta1_deg)), np.zeros(len(t)))
    bends[:, section, 0], bends[:, section, 1] = a, b
    f = BendFormulation(robot=robot)
    x = np.concatenate([bends.reshape(len(t), -1), np.zeros((len(t), bends[0].size))], axis=1)
    rec = Recording(
        t=t, z=np.zeros((len(t), 2 * robot.n_imus)), truth=f.output(x), length=robot.length,
        outputs=f.outputs, measurement_names=f.measurement_names,
    )  # fmt: skip
    values, names = raw_readings(rec, robot, seed=0)
    _write_rows(path, ("t", *names), np.column_stack([t, values]))


def _hanging_tilted_robots(folder: Path) -> tuple[Path, Path]:
    """``(nominal, true)`` robot files of the hanging three-section robot of four IMUs:
    every board flat, and its boards tilted 2 to 4 degrees on their disks (IMU 4's yaw
    3 degrees off), written in ``folder``."""
    tilted = ("2.5, -3.0", "-4.0, 1.5", "1.0, 3.5", "-2.0, -2.0")
    nominal = folder / "robot.toml"
    nominal.write_text(
        _HANGING_THREE_SECTIONS.format("0.0, 0.0", "0.0, 0.0", "0.0, 0.0", "0.0, 0.0")
    )
    true = folder / "true.toml"
    true.write_text(_HANGING_THREE_SECTIONS.format(*tilted).replace("30.0]", "33.0]"))
    return nominal, true


def test_a_rest_in_which_every_imu_leans_one_way_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hanging robot of four IMUs, their boards tilted 3 to 4 degrees on their disks,
    at rest with its first section bent 8 degrees: the boards' own tilts leave one of
    them 4.5 degrees from straight, under the bound of the every-IMU test, yet the bend
    leans every board the same way (calibrated so, the estimates of a spatial run were
    35 mm off on average, their `ok` rows up to 8.8 standard deviations off). One
    warning says the shared lean; the same robot straight says nothing."""
    nominal, true = _hanging_tilted_robots(tmp_path)
    rest = tmp_path / "rest.csv"
    _bent_rest(true, rest, 0.0)
    code, out, err = _calibrate_main(capsys, "--from", str(rest), "--robot", str(nominal))
    assert code == 0 and "IMU 4: mounting" in out and err == ""
    _bent_rest(true, rest, 8.0)
    code, out, err = _calibrate_main(capsys, "--from", str(rest), "--robot", str(nominal))
    assert code == 0 and "IMU 4: mounting" in out
    assert "every IMU reads" not in err  # IMU 2 reads 4.5 degrees off straight
    assert err.startswith(
        f"continuum-mhe: warning: {rest}: the IMUs' gravity directions lean 7.9 degrees the "
        "same way on average, turned into the backbone's frame by the robot file's yaws "
        "(each board 5.4, 4.1, 11.5, 10.8 degrees that way)"
    ), err
    assert "was the robot straight and its base level at rest?" in err
    assert err.count("\n") == 1


def test_a_rest_with_a_later_section_bent_warns_of_the_boards_after_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same hanging robot, its boards tilted on their disks, at rest with its second
    section bent 10 degrees: IMU 1 (on section 1) reads straight, so not every board
    leans, but the boards after the bend lean the same way: one warning names them and
    the section between; the robot straight says nothing (the test above)."""
    nominal, true = _hanging_tilted_robots(tmp_path)
    rest = tmp_path / "rest.csv"
    _bent_rest(true, rest, 10.0, section=1)
    code, out, err = _calibrate_main(capsys, "--from", str(rest), "--robot", str(nominal))
    assert code == 0 and "IMU 4: mounting" in out
    assert "every IMU reads" not in err and "the IMUs' gravity directions" not in err
    assert err.startswith(
        f"continuum-mhe: warning: {rest}: the gravity directions of IMUs 3 and 4 lean 13.1 "
        "degrees the same way on average"
    ), err
    assert "(the IMUs before IMU 3 do not: a section bent between IMU 2 and IMU 3?)" in err
    assert err.count("\n") == 1


def test_a_rest_in_which_an_imu_reads_far_off_straight_warns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One IMU 45 degrees off straight at rest (a robot left bent: its section bent 45
    degrees, the other IMU straight) is not taken as its mounting without a word: a
    warning names it, since a board is mounted flat, on its side or upside down. 25 degrees, and
    a board on its side (90), say nothing (one upside down: the test above)."""
    path = tmp_path / "rest.csv"
    _two_imu_rest(path, (45.0, 1.0))
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and "IMU 1: mounting" in out
    assert err == (
        f"continuum-mhe: warning: {path}: IMU 1 reads 45.0 degrees from the straight robot's "
        "gravity direction, which mount_rpy takes as its mounting: a board is mounted flat, "
        "on its side or upside down, seldom in between; was the robot straight and its base "
        "level at rest? If not, every estimate is off by as much; record the rest again (an "
        "IMU that is mounted so is calibrated right)\n"
    )
    for quiet in (25.0, 90.0):
        _two_imu_rest(path, (quiet, 1.0))
        code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
        assert code == 0 and err == "", quiet


def _tilt_rest(path: Path, roll: float, pitch: float, noise: float) -> None:
    """A tilt rest recording of one IMU (10 s at 20 Hz), its angles as numbers around
    ``roll`` and ``pitch``."""
    rng = np.random.default_rng(3)
    rows = [f"{0.05 * k:.2f},{roll + rng.normal(0, noise):.5f},{pitch + rng.normal(0, noise):.5f}"
            for k in range(200)]  # fmt: skip
    path.write_text("t,roll,pitch\n" + "\n".join(rows) + "\n")


def test_a_tilt_rest_in_degrees_is_read_with_degrees_or_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tilt rest recording in degrees: ``--degrees`` reads it (the refusal of angles
    beyond radians' range names it, and calibrate takes it); a quiet one whose angles,
    read as radians, are tens of degrees is calibrated with a warning that says
    degrees; ``--degrees`` with a raw recording or the port is one line."""
    path = tmp_path / "rest_deg.csv"
    _tilt_rest(path, 3.5, -2.7, 0.3)  # beyond pi: refused, naming --degrees
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 2 and err.endswith("the angles look like degrees: pass --degrees (degrees=True "
                                      "in Python)\n")  # fmt: skip
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--degrees")
    assert code == 0 and err == "" and "roll mean 3.5" in out and "pitch mean -2.6" in out
    _tilt_rest(path, 1.0, -1.0, 0.005)  # within radians' range: read, and said
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 0 and "roll mean 57.3" in out
    assert err == (
        f"continuum-mhe: warning: {path}: every IMU reads more than 30 degrees from the "
        "straight robot's gravity direction (IMU 1 73.0 degrees) if its roll and pitch are "
        "in radians, and within 5 if they are in degrees: degrees? pass --degrees\n"
    )
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--degrees")
    assert code == 0 and err == "" and "roll mean 1.000 deg" in out
    _tilt_rest(path, 0.2, -0.1, 0.005)  # radians, tilted 12.8 degrees: no hint
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 0 and err == ""
    hanging = tmp_path / "hanging.toml"  # a z-down robot's rest in radians, 5 degrees off
    hanging.write_text('mounting = "z-down"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    _tilt_rest(path, 3.05, 0.02, 0.005)
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", str(hanging))
    assert code == 0 and err == ""
    raw = tmp_path / "rest_raw.csv"
    assert main(["simulate", "rest", "--imu", "raw", "-o", str(raw)]) == 0
    capsys.readouterr()
    code, out, err = _calibrate_main(capsys, "--from", str(raw), "--degrees")
    assert code == 2 and err == (
        f"continuum-mhe: error: {raw}: --degrees is for a tilt recording's roll and pitch; "
        "this one is raw (accelerometer in m/s^2, gyro in rad/s)\n"
    )
    code, out, err = _calibrate_main(capsys, "--port", str(tmp_path / "tty"), "--degrees")
    assert code == 2 and err == (
        "continuum-mhe: error: --degrees reads a tilt recording in degrees (--from "
        "TILT.csv); a board's tilt lines are in radians\n"
    )


def test_a_tilt_rest_of_a_robot_mounted_the_other_way_is_refused_naming_the_mounting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hanging robot's tilt rest (roll near 180 degrees) with a z-up robot: refused in
    one line naming the mounting, as a raw rest is and as ``estimate`` refuses the same
    file, not as degrees given for radians (3.1 read as degrees is near straight); the
    same rest with a z-down robot file calibrates."""
    path = tmp_path / "hang.csv"
    _tilt_rest(path, 3.1, 0.01, 0.005)
    up = tmp_path / "up.toml"
    up.write_text('mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", str(up))
    assert (code, out) == (2, "")
    assert err == (
        f"continuum-mhe: error: {path}: mounting: the robot is described as z-up, but at "
        "rest gravity puts every IMU 178 degrees from where that mounting puts it: the "
        'robot hangs from its base? set mounting = "z-down" in the robot file\n'
    )
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert code == 2 and err.endswith("the robot hangs from its base? --mounting z-down\n")
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--mounting", "z-down")
    assert code == 0 and err == "" and "roll mean 177.6" in out, err


def test_a_still_tilt_rest_in_degrees_is_said_to_be_degrees_not_a_motion_alone(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A still IMU's tilt rest in degrees within radians' range (0.3 degrees of noise,
    which read as radians spreads by 17 degrees) is refused as a motion that names
    --degrees too; ``--degrees`` calibrates it; a robot's motion in radians (the
    paper's, which steps smoothly from sample to sample) is refused without it."""
    path = tmp_path / "rest_deg.csv"
    _tilt_rest(path, 0.4, -0.2, 0.3)
    code, out, err = _calibrate_main(capsys, "--from", str(path))
    assert (code, out) == (2, "") and err.count("\n") == 1
    assert "the robot moved: IMU 1's tilt spread" in err
    assert err.endswith(
        "; or are the angles in degrees? (read as degrees, every spread is within the bound, "
        "0.311 degrees at most) pass --degrees\n"
    ), err
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--degrees")
    assert code == 0 and err == "" and "roll mean 0.4" in out, err
    moving = tmp_path / "paper3d.csv"
    assert main(["simulate", "paper3d", "-o", str(moving)]) == 0
    capsys.readouterr()
    code, out, err = _calibrate_main(capsys, "--from", str(moving))
    assert code == 2 and "the robot moved: IMU 1's tilt spread" in err
    assert "degrees" not in err, err


def test_a_hanging_robots_tilt_rest_is_averaged_about_its_straight_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hanging robot's tilt rest reads roll near +-180 degrees, both signs in one
    recording: its mean is about +-180 (not the 0 of an average over the two signs),
    its spread the noise's, and the straight pose named is the mounting's."""
    rng = np.random.default_rng(5)
    roll = np.angle(np.exp(1j * (np.pi + rng.normal(0, 0.005, 200))))  # both signs
    pitch = rng.normal(0.01, 0.005, 200)
    path = tmp_path / "hang.csv"
    rows = [f"{0.05 * k:.2f},{r:.6f},{p:.6f}" for k, (r, p) in enumerate(zip(roll, pitch))]
    path.write_text("t,roll,pitch\n" + "\n".join(rows) + "\n")
    hanging = tmp_path / "hanging.toml"
    hanging.write_text('mounting = "z-down"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n')
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", str(hanging))
    assert code == 0 and err == "", err
    line = next(ln for ln in out.splitlines() if ln.startswith("IMU 1:"))
    mean = float(line.split("roll mean ")[1].split(" deg")[0])
    std = float(line.split("(std ")[1].split(")")[0])
    assert abs(abs(mean) - 180.0) < 0.1 and std < 0.5, line
    assert line.endswith("a straight robot should read +-180, 0")


def test_a_missing_recording_is_said_to_be_missing(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = _calibrate_main(capsys, "--from", "no_such_rest.csv")
    assert (code, out) == (2, "")
    assert err == "continuum-mhe: error: no_such_rest.csv: no such file\n"


def test_a_rest_in_another_acceleration_unit_is_refused_naming_the_unit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Readings in cm/s^2 (gravity 981, a noise 100 times larger) are refused for their
    magnitude by the reader (as every command's), not read as a motion, and not
    calibrated when the stillness bound is raised for them."""
    n = 400
    values = _rest_values(n, 0.02, 0.001)
    values[:, :3] *= 100.0
    rows = np.column_stack([0.01 * np.arange(n), values])
    path = tmp_path / "rest_cms2.csv"
    _write_rows(path, RAW_COLUMNS, rows)
    for extra in ((), ("--still-acc-std", "5")):
        code, out, err = _calibrate_main(capsys, "--from", str(path), *extra)
        assert code == 2 and out == ""
        assert err == (
            f"continuum-mhe: error: {path}: accelerometer magnitude is about 980.7: the "
            "values look like cm/s^2 (or milli-g, which reads 1000 at rest); ax, ay, az must "
            "be in m/s^2 (cm/s^2: divide by 100; milli-g: multiply by 0.00980665)\n"
        )


def test_a_bend_plane_in_radians_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    """--bend-phi is in degrees: 1.5708 (a quarter turn in radians) is said; 90 is not."""
    from continuum_mhe.calibration.robot_calibration import radians_like_degrees

    rod = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    args = ["--from", str(rod / "spatial_rest.csv"), "--bend", str(rod / "spatial_bend.csv")]
    code, _, err = _calibrate_main(capsys, *args, "--robot", "two-section", "--bend-phi", "1.5708")
    assert code == 0
    assert (
        "continuum-mhe: warning: --bend-phi 1.5708 is in degrees: radians? (1.5708 rad is 90 "
        "degrees: give --bend-phi 90)\n"
    ) in err
    assert [radians_like_degrees(a) for a in (90.0, 0.0, 45.0, -3.0, 0.7854, -1.5708, 6.3)] == [
        False, False, False, False, True, True, False,
    ]  # fmt: skip
    for beyond in ("1e300", "nan", "-400"):  # not an angle in degrees: one line, exit 2
        code, out, err = _calibrate_main(capsys, *args, "--robot", "two-section",
                                         "--bend-phi", beyond)  # fmt: skip
        assert code == 2 and not out
        assert err == (
            f"continuum-mhe: error: --bend-phi must be an angle in degrees from -360 to 360, "
            f"got {float(beyond):g}\n"
        )


def test_a_simulated_rest_calibrates_a_robot_of_three_sections(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``simulate rest`` (every section straight and still) gives a robot without
    hardware the recording ``calibrate --from`` takes: on a three-section robot whose
    second IMU is mounted at roll 3 and pitch -2 degrees, the written robot file holds
    that mounting (to the readings' noise) and each IMU's gyro bias, and reading it back
    says nothing of radians (a well-mounted IMU's near-zero angles are not taken for
    radians)."""
    import warnings

    from continuum_mhe.io.robot_file import read_robot

    robot = tmp_path / "r3.toml"
    robot.write_text(
        "".join(f"[[section]]\nlength = {s}\ntheta_max = 3.0\n" for s in (0.12, 0.10, 0.08))
        + "[[imu]]\nsection = 1\n[[imu]]\nsection = 2\nmount_rpy = [3.0, -2.0, 0.0]\n"
        "[[imu]]\nsection = 3\n"
    )
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "--robot", str(robot), "--imu", "raw", "--duration", "5",
                 "-o", str(rest)]) == 0  # fmt: skip
    cal = tmp_path / "cal.toml"
    assert main(["calibrate", "--from", str(rest), "--robot", str(robot),
                 "--write-robot", str(cal)]) == 0  # fmt: skip
    capsys.readouterr()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = read_robot(cal)
    rpy = np.array([imu.mount_rpy for imu in got.imus])
    np.testing.assert_allclose(rpy[1, :2], [3.0, -2.0], atol=0.3)
    np.testing.assert_allclose(rpy[[0, 2], :2], 0.0, atol=0.3)


def test_a_rest_whose_t_is_in_milliseconds_says_no_rate_and_the_same_results(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A raw rest recording whose ``t`` column holds milliseconds: the report line says
    the times look like milliseconds and gives no rate (not "0.0 Hz" of steps read as
    50 s), and every other line is the one the same recording in seconds gives; in
    seconds its rate is said (20.0 Hz, the simulated 50 ms step)."""
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "--robot", "two-section", "--imu", "raw", "--duration",
                 "5", "-o", str(rest)]) == 0  # fmt: skip
    lines = rest.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("t,")) + 1
    in_ms = tmp_path / "rest_ms.csv"
    in_ms.write_text(
        "\n".join(
            lines[:first]
            + [f"{1000 * float(ln.split(',')[0]):g},{ln.split(',', 1)[1]}" for ln in lines[first:]]
        )
        + "\n"
    )
    args = ("--robot", "two-section")
    code, out, _ = _calibrate_main(capsys, "--from", str(rest), *args)
    assert code == 0
    seconds = out.splitlines()
    with pytest.warns(UnitWarning, match="t advances by a median of 50 s per sample"):
        code, out, _ = _calibrate_main(capsys, "--from", str(in_ms), *args)
    assert code == 0
    millis = out.splitlines()
    assert seconds[0] == (
        f"calibration from {rest}: 101 samples over 5.000 s of device time: 20.0 Hz (median "
        "step 50.00 ms, longest 50.00 ms)"
    )
    assert millis[0] == (
        f"calibration from {in_ms}: 101 samples whose times look like milliseconds (t steps "
        "by a median of 50 per sample, read as seconds): no sample rate is said (name the "
        "column t_ms for one); the means, noise and mountings below do not depend on the times"
    )
    assert millis[1:] == seconds[1:] and len(seconds) == 7


def test_a_rest_too_short_whose_t_is_in_milliseconds_is_refused_as_too_short(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A raw rest of 0.4 s (41 samples at 100 Hz, under the 0.5 s calibration needs)
    whose ``t`` holds milliseconds spans 400 read as seconds: it is judged in
    milliseconds and refused in one line, as the same rest in seconds is."""
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "--robot", "two-section", "--imu", "raw", "--duration",
                 "0.4", "--dt", "0.01", "-o", str(rest)]) == 0  # fmt: skip
    capsys.readouterr()
    lines = rest.read_text().splitlines()
    first = next(i for i, ln in enumerate(lines) if ln.startswith("t,")) + 1
    in_ms = tmp_path / "rest_ms.csv"
    rows = [f"{1000 * float(ln.split(',')[0]):g},{ln.split(',', 1)[1]}" for ln in lines[first:]]
    in_ms.write_text("\n".join(lines[:first] + rows) + "\n")
    for path in (rest, in_ms):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnitWarning)
            code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
        assert code == 2 and out == "", (path, out)
        assert (
            err.count("\n") == 1 and "calibration needs the robot still for at least 0.5 s" in err
        )
    assert "its times look like milliseconds: 0.4 s read so" in err, err


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_simulated_tilt_rest_is_one_calibrate_takes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], seed: int
) -> None:
    """``simulate rest`` with tilt IMUs (the default) draws a still IMU's noise, not the
    2 degrees of a moving one (the IMU's own acceleration in it), so that ``calibrate
    --from`` takes it (not refused as a robot that moved); an explicit
    ``--noise-deg`` is kept. The still noise is the raw accelerometer's at rest, as
    tilt."""
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.simulation.raw_readings import RawNoise
    from continuum_mhe.simulation.scenarios import REST_NOISE_DEG

    assert REST_NOISE_DEG == pytest.approx(
        math.degrees(RawNoise().accel_std / STANDARD_GRAVITY), abs=0.005
    )
    rest = tmp_path / "rest.csv"
    assert main(["simulate", "rest", "-o", str(rest), "--seed", str(seed)]) == 0
    roll = read_state_table(rest, ()).column("roll")
    assert math.degrees(float(np.std(roll, ddof=1))) == pytest.approx(REST_NOISE_DEG, rel=0.15)
    code, out, err = _calibrate_main(capsys, "--from", str(rest))
    assert code == 0, err
    assert "roll mean" in out
    noisy = tmp_path / "noisy.csv"
    assert main(["simulate", "rest", "-o", str(noisy), "--noise-deg", "2"]) == 0
    roll = read_state_table(noisy, ()).column("roll")
    assert math.degrees(float(np.std(roll, ddof=1))) == pytest.approx(2.0, rel=0.15)
    # the library's default is the same, for one section and for several
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate, simulate_robot

    for rec in (simulate("rest", seed=seed), simulate_robot("rest", read_robot("two-section"))):
        spread = math.degrees(float(np.std(rec.z[:, 0], ddof=1)))
        assert spread == pytest.approx(REST_NOISE_DEG, rel=0.15)
    moving = (
        simulate("paper3d", seed=seed).z[:, 0]
        - simulate("paper3d", seed=seed, noise_deg=0.0).z[:, 0]
    )
    assert math.degrees(float(np.std(moving, ddof=1))) == pytest.approx(2.0, rel=0.15)


def _collect_events(
    monkeypatch: pytest.MonkeyPatch, events: list[tuple[str, object, float]], seconds: float
) -> tuple[object, list[str]]:
    """``collect`` from a reader that puts ``events`` (kind, payload, arrival s) and
    nothing more: ``(its result or the InputError raised, what it said)``."""
    from continuum_mhe.calibration import at_rest
    from continuum_mhe.errors import InputError

    class Reader:
        def __init__(self, port: str, baud: int, conn: object, queue: object, retry: float):
            self.queue = queue
            self.stop = threading.Event()

        def start(self) -> None:
            for event in events:
                self.queue.put(event)  # type: ignore[attr-defined]

    monkeypatch.setattr(at_rest, "SerialReader", Reader)
    monkeypatch.setattr(at_rest, "open_port", lambda *a: None)
    monkeypatch.setattr(at_rest, "BOOT_S", 0.0)  # the events are all there at once
    said: list[str] = []
    try:
        got: object = at_rest.collect("PORT", 115200, "raw", 1, seconds, said.append)
    except InputError as exc:
        got = exc
    return got, said


def _line(t_ms: float) -> bytes:
    return f"{t_ms:g},0,0,9.81,0.001,-0.001,0".encode()


def test_calibrate_from_the_port_starts_over_at_a_reset_within_the_clocks_first_second(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A board that resets 0.78 s into its clock, with no banner: the collection starts
    over at its first line (said once), not 0.8 s of lines out of order; lines sent
    again 0.2 s back, the next going on from the last, start nothing over."""
    reset = [*range(0, 790, 10), *range(0, 2500, 10)]
    events = [("line", _line(ms), 0.01 * i) for i, ms in enumerate(reset)]
    got, said = _collect_events(monkeypatch, events, 2.0)
    assert isinstance(got, tuple) and len(got[0]) == 201, got
    assert sum("starting over" in m for m in said) == 1, said
    again = [*range(0, 1300, 10), *range(1100, 1300, 10), *range(1300, 2500, 10)]
    events = [("line", _line(ms), 0.01 * i) for i, ms in enumerate(again)]
    got, said = _collect_events(monkeypatch, events, 2.0)
    assert isinstance(got, tuple) and not any("starting over" in m for m in said), said


def test_calibrate_from_the_port_says_a_device_clock_in_another_unit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """t_ms sent in seconds, or in microseconds, over 2 s of arrival time: one line naming
    the unit (not a calibration of 0.02 s, or of two samples)."""
    for scale, unit in ((1e-3, "seconds"), (1e3, "microseconds")):
        events = [("line", _line(10 * i * scale), 0.01 * i) for i in range(400)]
        got, _ = _collect_events(monkeypatch, events, 3.0)
        assert f"t_ms in {unit}?" in str(got), got


def test_calibrate_from_the_port_says_a_short_collection_and_bytes_without_line_ends(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The device stops after 1 s of the 1.3 asked: the calibration is of that second,
    with a warning that says so; a device whose bytes have no line end is named so."""
    events = [("line", _line(10 * i), 0.01 * i) for i in range(101)]
    events.append(("lost", "device disconnected", 1.1))
    (t, _), said = _collect_events(monkeypatch, events, 1.3)
    assert t[-1] - t[0] == pytest.approx(1.0)
    assert any("device lost (device disconnected)" in m for m in said), said
    assert any("1.000 s of the 1.3 s asked arrived" in m for m in said), said
    got, _ = _collect_events(monkeypatch, [("unended", 9000, 0.5), ("unended", 12000, 1.0)], 0.3)
    assert "12000 bytes arrived without a line end (LF or CR)" in str(got), got


def test_write_robot_takes_a_robot_file_that_starts_with_a_byte_order_mark(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot file saved with a UTF-8 byte-order mark (as some Windows editors write
    it) is read by every command; ``--write-robot`` rewrites it too (not an
    internal error in the TOML writer), without the mark, with the same mountings as
    from the file without it."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data"
    plain = (data / "robots" / "two_section.toml").read_text(encoding="utf-8")
    rest = str(data / "rod2" / "planar-s_rest.csv")
    written = []
    for name, text in (("bom", "\ufeff# saved on Windows\n" + plain), ("plain", plain)):
        robot, out = tmp_path / f"{name}.toml", tmp_path / f"{name}_cal.toml"
        robot.write_text(text, encoding="utf-8")
        code, _, err = _calibrate_main(
            capsys, "--from", rest, "--robot", str(robot), "--write-robot", str(out)
        )
        assert code == 0, err
        written.append(out.read_bytes())
    assert not written[0].startswith(b"\xef\xbb\xbf")
    assert written[0] == b"# saved on Windows\n" + written[1]


def _noisy_two_imu_rest(n: int, seed: int) -> np.ndarray:
    """(n, 12) raw samples of two still IMUs (:func:`_rest_values`) with MEMS-like white
    noise: 0.05 m/s^2 and 0.005 rad/s per axis."""
    rng = np.random.default_rng(seed)
    values = np.hstack([_rest_values(n, 0.0, 0.0), _rest_values(n, 0.0, 0.0)])
    values[:, [0, 1, 2, 6, 7, 8]] += rng.normal(0.0, 0.05, (n, 6))
    values[:, [3, 4, 5, 9, 10, 11]] += rng.normal(0.0, 0.005, (n, 6))
    return values


def test_a_short_knock_at_rest_is_left_out_and_said(tmp_path: Path, capsys) -> None:
    """A 50 ms knock on IMU 2 (gx +0.3 rad/s, ay +0.5 m/s^2 for 5 of 500 samples), within
    the stillness bounds over the whole rest: its samples are left out of IMU 2's means
    (the gyro bias printed is the mean of the other samples; with them it would be
    0.003 rad/s higher) and said in one warning line; the same rest without the knock,
    noise alone, has no sample left out."""
    n = 500
    values = _noisy_two_imu_rest(n, seed=3)
    quiet = tmp_path / "quiet.csv"
    _write_rest(quiet, values)
    code, _, err = _calibrate_main(capsys, "--from", str(quiet), "--robot", "two-section")
    assert code == 0 and "left out" not in err, err
    knocked = values.copy()
    knocked[250:255, 9] += 0.3
    knocked[250:255, 7] += 0.5
    path = tmp_path / "knock.csv"
    _write_rest(path, knocked)
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0
    assert err.count("\n") == 1 and (
        "IMU 2: 5 of 500 sample(s) from t = 2.5 to 2.54 s left out of its means" in err
    )
    rest = np.delete(np.arange(n), np.arange(250, 255))
    assert f"IMU 2: gyro bias (rad/s) gx={knocked[rest, 9].mean():.5f} " in out
    assert f"gx={knocked[:, 9].mean():.5f} " not in out


def test_a_knock_after_which_the_robot_rests_in_another_pose_is_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A knock on both IMUs (5 of 500 samples) after which the robot rests 1.5 degrees
    about y from its pose before (within the stillness bounds over the whole rest): the
    knock's warning says the IMU rests in another pose and to record again (the printed
    pitch, about -0.75, is a mix of the two poses); a knock with the pose kept does not."""
    n = 500
    values = _noisy_two_imu_rest(n, seed=5)
    values[250:255, [4, 10]] += 0.3
    path = tmp_path / "knock.csv"
    _write_rest(path, values)
    code, _, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and err.count("(a knock?)") == 2 and "another pose" not in err, err
    turn = math.radians(1.5)
    for first in (0, 6):  # about y: ax, az of each IMU from the knock on
        ax, az = values[255:, first].copy(), values[255:, first + 2].copy()
        values[255:, first] = math.cos(turn) * ax + math.sin(turn) * az
        values[255:, first + 2] = -math.sin(turn) * ax + math.cos(turn) * az
    _write_rest(path, values)
    code, out, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0
    assert err.count("degrees from its pose before it: the robot settled in another pose") == 2
    assert "record the rest again" in err


def test_a_robot_that_creeps_through_its_rest_is_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both IMUs turning steadily about y at 0.01 rad/s through a 5 s rest (2.9 degrees,
    each axis's spread within the stillness bounds; the gyros read the turn as a bias):
    one warning per IMU that the robot crept, with the turn between the first and last
    thirds (1.9 degrees); the same rest held still has none."""
    n, rate = 500, 0.01
    values = _noisy_two_imu_rest(n, seed=7)
    path = tmp_path / "rest.csv"
    _write_rest(path, values)
    code, _, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0 and "crept" not in err, err
    turn = rate * 0.01 * np.arange(n)  # _write_rest's 0.01 s steps
    for first in (0, 6):  # about y: ax, az of each IMU, and the gyros' y
        ax, az = values[:, first].copy(), values[:, first + 2].copy()
        values[:, first] = np.cos(turn) * ax + np.sin(turn) * az
        values[:, first + 2] = -np.sin(turn) * ax + np.cos(turn) * az
        values[:, first + 4] += rate
    _write_rest(path, values)
    code, _, err = _calibrate_main(capsys, "--from", str(path), "--robot", "two-section")
    assert code == 0
    for imu in (1, 2):
        assert f"IMU {imu}'s gravity direction turned by 1.9" in err, err
    assert err.count("the robot crept") == 2


def test_calibrate_prints_and_writes_no_negative_zero(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A gyro bias of -3e-7 rad/s and a roll of -6e-5 degrees, which round to zero from
    below: the report and the robot file both say 0, never -0, and the report's numbers
    are the file's."""
    values = _noisy_two_imu_rest(400, seed=9)
    values[:, :6] -= values[:, :6].mean(axis=0)  # IMU 1: its means set exactly below
    values[:, :6] += [0.0, -1e-5, G, -3e-7, 0.1, 0.1]  # roll -6e-5 degrees, gx -3e-7
    path = tmp_path / "rest.csv"
    _write_rest(path, values)
    out_robot = tmp_path / "cal.toml"
    code, out, err = _calibrate_main(
        capsys, "--from", str(path), "--robot", "two-section", "--write-robot", str(out_robot)
    )
    assert code == 0, err
    # the paths named (pytest's own folders, such as .../pytest-0/) are not numbers
    written = out_robot.read_text().replace(str(tmp_path), "TMP")
    out = out.replace(str(tmp_path), "TMP")
    negative_zero = re.compile(r"-0(\.0*)?(?![.\d])")  # -0, -0.0, -0.000000
    assert not negative_zero.search(out) and not negative_zero.search(written), (out, written)
    assert "gyro_bias = [0.000000, 0.100000, 0.100000]" in out
    assert "--mount-rpy 0,0,0 " in out
    assert "gyro_bias = [0.0, 0.1, 0.1]" in written and "mount_rpy = [0.0, 0.0, 0.0]" in written


def test_calibrate_port_given_a_recording_says_calibrate_from(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """calibrate --port with a recording's path names calibrate --from, not estimate."""
    path = tmp_path / "rest.csv"
    path.write_text("t,ax,ay,az,gx,gy,gz\n", encoding="utf-8")
    code, _, err = _calibrate_main(capsys, "--port", str(path))
    assert code == 2 and err.count("\n") == 1
    assert "a recording is calibrated with continuum-mhe calibrate --from FILE" in err


def test_a_board_on_its_side_keeps_the_robot_file_s_roll(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A board mounted on its side (``mount_rpy = [0, 90, 0]``: its x axis along the
    backbone): at rest gravity lies along its x axis, about which the roll turns it, so
    the roll a rest measures is the noise's: the robot file's roll is kept, with a
    note, and the pitch is measured (three rests, three draws of the noise)."""
    robot = tmp_path / "side.toml"
    robot.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\n'
        "mount_rpy = [0, 90, 0]\n"
    )
    rest = tmp_path / "rest.csv"
    for seed in ("1", "2", "3"):
        assert main(["simulate", "rest", "--robot", str(robot), "--imu", "raw", "--duration",
                     "5", "--seed", seed, "-o", str(rest), "--overwrite"]) == 0  # fmt: skip
        code, out, err = _calibrate_main(capsys, "--from", str(rest), "--robot", str(robot))
        assert code == 0 and "IMU 1's x axis lies within 0." in err
        assert "of gravity at rest" in err and "the robot file's roll (0 degrees) is kept" in err
        assert re.search(r"--mount-rpy 0,(89\.9\d*|90),0 ", out), out


ROD2 = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"


@pytest.mark.parametrize("bent", [False, True])
def test_calibrate_robot_gives_the_robot_that_write_robot_writes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], bent: bool
) -> None:
    """The library's calibrate_robot on the shipped spatial run (with its bend towards
    phi = 0, or without) returns the robot that ``calibrate --write-robot`` writes, read
    back from the file: each IMU's mount_rpy and gyro_bias, the rest of it the robot
    file's; its report is the command's standard output."""
    from continuum_mhe import RobotCalibration, calibrate_robot
    from continuum_mhe.io import read_robot

    rest, bend = ROD2 / "spatial_rest.csv", ROD2 / "spatial_bend.csv"
    out = tmp_path / "cal.toml"
    more = ("--bend", str(bend)) if bent else ()
    code, stdout, err = _calibrate_main(
        capsys, "--from", str(rest), *more, "--robot", "two-section", "--write-robot", str(out)
    )
    assert code == 0, err
    written = read_robot(str(out))
    given = read_robot("two-section")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the shipped run is calibrated without a warning
        result = calibrate_robot(given, rest, bend=bend if bent else None)
    assert isinstance(result, RobotCalibration)
    assert result.robot == written
    assert result.robot != given  # measured: not the file's zeros
    assert [imu.mount_rpy for imu in result.robot.imus] == [imu.mount_rpy for imu in written.imus]
    assert [imu.gyro_bias for imu in result.robot.imus] == [imu.gyro_bias for imu in written.imus]
    assert result.report + "\n" == stdout
    assert (result.yaws is not None) == bent
    if bent:  # the yaws measured from the bend are those written (to the file's 0.001 deg)
        assert result.yaws is not None
        for imu, yaw in zip(written.imus, result.yaws):
            assert imu.mount_rpy[2] == round(yaw.yaw_deg, 3) + 0.0


def test_calibrate_robot_refuses_as_the_command_does(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A recording of the robot moving (the planar-S run) is refused by calibrate_robot
    in an InputError whose message is the command's one-line error, as is a
    --bend-phi without a bend."""
    from continuum_mhe import InputError, calibrate_robot
    from continuum_mhe.io import read_robot

    moving = ROD2 / "planar-s_raw.csv"
    code, stdout, err = _calibrate_main(capsys, "--from", str(moving), "--robot", "two-section")
    assert code == 2 and stdout == "" and err.count("\n") == 1
    with pytest.raises(InputError) as refused:
        calibrate_robot(read_robot("two-section"), moving)
    assert err == f"continuum-mhe: error: {refused.value}\n"
    assert "the robot moved" in str(refused.value)
    with pytest.raises(InputError, match=r"^--bend-phi needs --bend BEND.csv$"):
        calibrate_robot(read_robot("two-section"), ROD2 / "spatial_rest.csv", bend_phi_deg=90.0)


def _board_2_turned_over(
    path: Path, samples: int | None = None, dropouts: tuple[int, ...] = ()
) -> Path:
    """The shipped ``spatial_rest.csv`` (its first ``samples`` rows, or all) with IMU 2's
    board turned over (x and z negated) and IMU 1's ``ay`` empty in the rows
    ``dropouts`` (0-based), written to ``path``."""
    lines = (ROD2 / "spatial_rest.csv").read_text().splitlines()
    names = lines[0].split(",")
    flip = [names.index(c) for c in ("ax_2", "az_2", "gx_2", "gz_2")]
    rows = []
    for k, ln in enumerate(lines[1:] if samples is None else lines[1 : samples + 1]):
        v = ln.split(",")
        for j in flip:
            v[j] = repr(-float(v[j]))
        if k in dropouts:
            v[names.index("ay_1")] = ""  # a dropout
        rows.append(",".join(v))
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    return path


def test_calibrate_robot_warns_as_python_warnings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A rest recording with two readings missing, IMU 2's board turned over (x and z
    negated), and a bend plane that looks given in radians: calibrate_robot says each
    as a CalibrationWarning (nothing printed), the lines the command prints as its
    warnings, in the same order."""
    from continuum_mhe import CalibrationWarning, calibrate_robot
    from continuum_mhe.io import read_robot

    rest = _board_2_turned_over(tmp_path / "turned_rest.csv", dropouts=(50, 200))
    bend = ROD2 / "spatial_bend.csv"
    code, stdout, err = _calibrate_main(
        capsys, "--from", str(rest), "--bend", str(bend), "--bend-phi", "0.5",
        "--robot", "two-section",
    )  # fmt: skip
    assert code == 0, err
    said = [ln for ln in err.splitlines() if ln.startswith("continuum-mhe: warning: ")]
    assert len(said) == 3 and len(err.splitlines()) == 3, err
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = calibrate_robot(read_robot("two-section"), rest, bend=bend, bend_phi_deg=0.5)
    assert capsys.readouterr() == ("", "")
    assert result.report + "\n" == stdout
    assert all(w.category is CalibrationWarning for w in caught)
    assert {w.filename for w in caught} == {__file__}  # the caller's line, not the library's
    assert [f"continuum-mhe: warning: {w.message}" for w in caught] == said
    assert "IMU 2 (of 2) reads gravity 178 degrees" in said[0]
    assert "2 of 601 row(s) with a reading missing" in said[1]
    assert said[2].startswith("continuum-mhe: warning: --bend-phi 0.5 is in degrees")
    with warnings.catch_warnings():  # as an error where a script asks for one
        warnings.simplefilter("error", CalibrationWarning)
        with pytest.raises(CalibrationWarning, match="reads gravity 178 degrees"):
            calibrate_robot(read_robot("two-section"), rest)


def test_calibrate_robot_refuses_arguments_the_command_refuses() -> None:
    """The library's still spreads, bend plane, robot and topics are held as the
    command's options are (one ``UserError`` naming the argument, before anything is
    read): a NaN or infinite spread calibrated a moving run, 0 divided by zero; the
    bounds are the command's ``--still-acc-std`` and ``--still-gyro-std`` ranges."""
    from continuum_mhe import calibrate_robot
    from continuum_mhe.calibration.robot_calibration import (
        STILL_ACC_STD_MAX,
        STILL_GYRO_STD_MAX,
    )
    from continuum_mhe.cli.options import OPTION_RANGES
    from continuum_mhe.errors import UserError
    from continuum_mhe.io import read_robot

    assert (OPTION_RANGES["still_acc_std"].hi, OPTION_RANGES["still_gyro_std"].hi) == (
        STILL_ACC_STD_MAX, STILL_GYRO_STD_MAX,
    )  # fmt: skip
    robot, moving = read_robot("two-section"), str(ROD2 / "planar-s_raw.csv")
    for kwargs, said in (
        ({"still_acc_std": math.nan}, "still_acc_std must be above 0 and at most 10 m/s^2"),
        ({"still_acc_std": math.inf}, "still_acc_std must be above 0"),
        ({"still_acc_std": 0.0}, "still_acc_std must be above 0"),
        ({"still_gyro_std": -1.0}, "still_gyro_std must be above 0 and at most 5 rad/s"),
        ({"still_acc_std": "0.2"}, "still_acc_std must be a number"),
        ({"bend_phi_deg": "90"}, "bend_phi_deg must be a number"),
        ({"topics": "/imu1"}, "topics must be a sequence of topic names"),
    ):
        with pytest.raises(UserError, match=f"^{re.escape(said)}"):
            calibrate_robot(robot, moving, **kwargs)
    with pytest.raises(UserError, match="^robot must be a Robot"):
        calibrate_robot("two-section", moving)  # type: ignore[arg-type]
    with pytest.raises(UserError, match="^require_raw must be "):
        calibrate_robot(robot, moving, require_raw=True)  # type: ignore[arg-type]


def test_the_calibrate_command_says_its_warnings_under_an_error_filter(capsys) -> None:
    """``calibrate --from`` with a bend whose plane looks given in radians, under ``-W
    error``: its warning is its own line, exit 0 (not an internal error from the
    library's warning)."""
    import warnings as _warnings

    capsys.readouterr()
    with _warnings.catch_warnings():
        _warnings.simplefilter("error")
        status = main(["calibrate", "--from", str(ROD2 / "spatial_rest.csv"), "--robot",
                       "two-section", "--bend", str(ROD2 / "spatial_bend.csv"),
                       "--bend-phi", "0.5"])  # fmt: skip
    err = capsys.readouterr().err
    assert status == 0 and "continuum-mhe: warning: " in err, err


def test_a_short_rest_with_a_board_turned_over_is_refused_without_a_warning_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A rest of 0.2 s with IMU 2's board turned over: the refusal (too short) is the
    library's one error, also where a script turns warnings into errors (the board's
    warning came first and took its place), and the command's one line."""
    import warnings as _warnings

    from continuum_mhe import calibrate_robot
    from continuum_mhe.errors import InputError
    from continuum_mhe.io import read_robot

    rest = _board_2_turned_over(tmp_path / "short_rest.csv", samples=10)  # 0.2 s at 50 Hz
    with _warnings.catch_warnings():
        _warnings.simplefilter("error")
        with pytest.raises(InputError, match="calibration needs the robot still"):
            calibrate_robot(read_robot("two-section"), rest)
    capsys.readouterr()
    assert main(["calibrate", "--from", str(rest), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"continuum-mhe: error: {rest}: "), err


def test_a_measured_mounting_near_a_radian_turn_is_written_so_that_it_reads_back_silently(
    tmp_path: Path,
) -> None:
    """A board's measured roll of 1.571 degrees (pi/2 rad to 0.0002) is written beside
    the multiple's tolerance band, within 0.002 degrees of the measurement, so that
    reading the written robot file gives no radians warning; values away from any such
    turn are written to a thousandth as measured."""
    from continuum_mhe.io.robot_file import read_robot, robot_source_text, with_imu_calibration
    from continuum_mhe.model.robot import mount_rpy_hint

    measured = [(0.866, 1.571, 0.0), (-3.1414, 0.7851, 2.5)]
    text = with_imu_calibration(
        robot_source_text("two-section", read_robot("two-section")),
        measured,
        None,
        tmp_path / "cal.toml",
    )
    out = tmp_path / "cal.toml"
    out.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a radians warning would raise here
        robot = read_robot(out)
    for imu, rpy in zip(robot.imus, measured):
        assert mount_rpy_hint(imu.mount_rpy) == ""
        assert np.allclose(imu.mount_rpy, rpy, atol=0.002)
    assert robot.imus[0].mount_rpy[0] == 0.866 and robot.imus[1].mount_rpy[2] == 2.5
