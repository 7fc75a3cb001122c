"""Simulated raw IMU readings (``continuum-mhe simulate --imu raw``)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.imu import tilt_from_accelerometer
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.simulation.raw_readings import RawNoise, raw_readings
from continuum_mhe.simulation.scenarios import Recording, simulate_robot

#: the raw CSV's reading columns of two IMUs, in the order the raw reader takes
TWO_IMUS = tuple(f"{c}_{i}" for i in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz"))
QUIET = RawNoise(accel_std=0.0, gyro_std=0.0, gyro_bias_std=0.0)
TWO = Robot((Section(0.16, 3.0), Section(0.14, 3.0)), (ImuPlacement(0), ImuPlacement(1)))


def _held(rec: Recording, row: int) -> Recording:
    """``rec`` with every sample at the shape of ``row`` (a robot at rest)."""
    return replace(rec, truth=np.repeat(rec.truth[row : row + 1], len(rec.t), axis=0))


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_at_rest_the_accelerometer_reads_gravity_as_the_tilt_model_does(mounting: str) -> None:
    """A robot held at a bent shape: each accelerometer reads g along the model's
    gravity direction (the roll and pitch of the tilt simulation without noise, to
    1e-9 rad) and each gyro zero."""
    robot = replace(TWO, mounting=mounting)
    rec = simulate_robot("spatial", robot, duration=2.0, noise_deg=0.0, seed=1)
    row = 37
    values, names = raw_readings(_held(rec, row), robot, QUIET)
    assert names == TWO_IMUS and names[:3] == ("ax_1", "ay_1", "az_1")
    for i in range(2):
        f, w = values[:, 6 * i : 6 * i + 3], values[:, 6 * i + 3 : 6 * i + 6]
        np.testing.assert_allclose(np.linalg.norm(f, axis=1), 9.80665, rtol=1e-12)
        np.testing.assert_allclose(w, 0.0, atol=1e-12)
        np.testing.assert_allclose(
            tilt_from_accelerometer(f[0]), rec.z[row, 2 * i : 2 * i + 2], atol=1e-9
        )


def test_a_mounted_sensor_reads_in_its_own_frame_and_estimates_alike(tmp_path: Path) -> None:
    """The same motion with IMU 2 mounted at roll 4, pitch -3, yaw 10 degrees: the raw
    reader's mounting undoes it, and the estimates equal those of the unmounted robot
    (no noise) to 1e-8; both robot files give IMU 2 the gyro bias its readings carry,
    which the reader removes (the bias states' prior is then the calibrated one in
    both)."""
    rec = simulate_robot("spatial", TWO, duration=3.0, seed=2)
    bias = (0.02, -0.01, 0.03)
    biased = replace(TWO, imus=(TWO.imus[0], replace(TWO.imus[1], gyro_bias=bias)))
    mounted = replace(
        biased, imus=(TWO.imus[0], replace(biased.imus[1], mount_rpy=(4.0, -3.0, 10.0)))
    )
    unbiased, _ = raw_readings(rec, TWO, QUIET)
    plain, names = raw_readings(rec, biased, QUIET)
    turned, _ = raw_readings(rec, mounted, QUIET)
    np.testing.assert_allclose(plain[:, 9:12] - unbiased[:, 9:12], np.tile(bias, (len(rec.t), 1)),
                               atol=1e-15)  # fmt: skip
    assert np.abs(turned[:, 6:] - plain[:, 6:]).max() > 0.1  # another frame
    np.testing.assert_array_equal(turned[:, :6], plain[:, :6])
    estimates = []
    for robot, values, name in ((biased, plain, "plain"), (mounted, turned, "mounted")):
        path = tmp_path / f"{name}.csv"
        header = ",".join(("t", *names))
        np.savetxt(path, np.column_stack([rec.t, values]), delimiter=",", header=header,
                   comments="", fmt="%.17g")  # fmt: skip
        toml = tmp_path / f"{name}.toml"
        toml.write_text(_robot_text(robot))
        out = tmp_path / f"{name}_est.csv"
        assert main(["estimate", str(path), "--robot", str(toml), "--method", "ekf",
                     "-o", str(out)]) == 0  # fmt: skip
        estimates.append(read_state_table(out))
    np.testing.assert_allclose(estimates[0].values, estimates[1].values, atol=1e-8)


def _robot_text(robot: Robot) -> str:
    sections = "".join(
        f"[[section]]\nlength = {s.length}\ntheta_max = {s.theta_max}\n" for s in robot.sections
    )
    imus = "".join(
        f"[[imu]]\nsection = {p.section + 1}\nmount_rpy = {list(p.mount_rpy)}\n"
        f"gyro_bias = {list(p.gyro_bias)}\n"
        for p in robot.imus
    )
    return f'mounting = "{robot.mounting}"\n' + sections + imus


def test_simulate_writes_raw_readings_that_estimate_takes_as_raw(tmp_path: Path, capsys) -> None:
    """``simulate --imu raw`` writes the robot's raw columns (m/s^2, rad/s); ``estimate``
    reads them as raw IMUs with their gyros (the default for raw input) and follows the
    truth to a few millimetres; a tendon robot is refused in one line."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "spatial", "--robot", "two-section", "--imu", "raw", "-o",
                 str(meas), "--truth", str(truth), "--duration", "6"]) == 0  # fmt: skip
    assert meas.read_text().splitlines()[0] == ",".join(("t", *TWO_IMUS))
    assert main(["estimate", str(meas), "--robot", "two-section", "-o", str(est)]) == 0
    capsys.readouterr()
    assert main(["evaluate", str(est), str(truth), "--robot", "two-section", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["tip_mean_mm"] < 5.0
    model = next(ln for ln in est.read_text().splitlines() if ln.startswith("# model"))
    assert 'name = "direct"' in model and '"bgx_2"' in model  # raw, with gyro-bias states
    tendon = tmp_path / "tendon.csv"
    assert main(["simulate", "spatial", "--robot", "tendon-two-section", "--imu", "raw",
                 "-o", str(tendon)]) == 2  # fmt: skip
    assert capsys.readouterr().err.count("\n") == 1 and not tendon.exists()


def test_each_imus_bias_is_the_same_in_recordings_of_any_length() -> None:
    """The constant gyro bias of every IMU is drawn from the seed before any noise: a
    rest recording of another length (the one calibrate takes) carries the same biases
    as the motion it calibrates (IMU 2's does not depend on the samples IMU 1 draws)."""
    robot = read_robot("two-section")
    quiet = RawNoise(accel_std=0.0, gyro_std=0.0, gyro_bias_std=0.01)
    rates = []
    for duration in (1.0, 3.0):
        rec = simulate_robot("rest", robot, duration=duration, dt=0.02)
        values, names = raw_readings(rec, robot, quiet, seed=5)
        gyros = [i for i, n in enumerate(names) if n.startswith("g")]
        assert np.ptp(values[:, gyros], axis=0).max() < 1e-12  # still: the bias alone
        rates.append(values[0, gyros])
    assert np.array_equal(rates[0], rates[1]) and np.abs(rates[0]).min() > 0
