"""A raw reading clipped at its sensor's full scale (a knock beyond an accelerometer's
+-2 g, a turn beyond a gyro's range) says nothing of the shape: it is skipped, that
IMU's dropout for the sample, and said once (:class:`~continuum_mhe.io.raw_imu.ClipWatch`;
docs/reliability.md)."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io import raw_measurements
from continuum_mhe.io.csv_files import DropoutWarning
from continuum_mhe.io.robot_file import read_robot, robot_toml
from continuum_mhe.model.imu import STANDARD_GRAVITY

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data"
ROD = DATA / "rod2"
TWO_G = 2 * STANDARD_GRAVITY


def _table(path: Path, rows: slice) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1)[rows]


def _write(path: Path, header: list[str], values: np.ndarray) -> Path:
    np.savetxt(path, values, delimiter=",", fmt="%.10g", header=",".join(header), comments="")
    return path


def _knocked(tmp_path: Path) -> Path:
    """``spatial-tendon``'s raw readings from 4 s to 8 s, IMU 1 knocked at 6 s (4 g on its
    x axis for 0.1 s, five samples) and every accelerometer clipped at +-2 g."""
    header, d = _table(ROD / "spatial-tendon_raw.csv", slice(200, 401))
    i = int(np.searchsorted(d[:, 0], 6.0))
    d[i : i + 5, header.index("ax_1")] += 4 * STANDARD_GRAVITY
    acc = [header.index(f"a{a}_{k}") for k in (1, 2) for a in "xyz"]
    d[:, acc] = np.clip(d[:, acc], -TWO_G, TWO_G)
    return _write(tmp_path / "knock.csv", header, d)


def test_a_flat_top_is_skipped_and_said(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """No full scale declared: the third reading of the flat top at 2 g on, it is skipped
    (IMU 1 missing in 3 samples) and one warning says so; before, the clipped readings
    were taken and nothing named them."""
    out = tmp_path / "est.csv"
    argv = ["estimate", str(_knocked(tmp_path)), "--robot", "two-section", "--method", "ekf"]
    with pytest.warns(DropoutWarning) as seen:
        assert main([*argv, "-o", str(out)]) == 0
    said = [str(w.message) for w in seen if "clipped" in str(w.message)]
    assert len(said) == 1
    assert "IMU 1: 3 reading(s) clipped, from t = 6.04 s" in said[0]
    assert "a flat top at 19.61 m/s^2" in said[0]
    assert "missing: IMU 1 in 3 samples" in capsys.readouterr().err


def _gyro_clipped(rows: slice, full_scale: float) -> tuple[list[str], np.ndarray]:
    header, d = _table(ROD / "planar-s_raw.csv", rows)
    gyro = [k for k, h in enumerate(header) if h[:2] in ("gx", "gy", "gz")]
    d[:, gyro] = np.clip(d[:, gyro], -full_scale, full_scale)
    return header, d


def test_a_declared_gyro_range_skips_its_clipped_readings(tmp_path: Path) -> None:
    """``planar-s`` (two sections) with its gyros clipped at 0.5 rad/s: taken, the EKF
    left 14 ok rows more than 20 mm off (up to 29 mm); with
    ``gyro_range = 0.5`` in the robot file they are skipped and no ok row is 20 mm
    off."""
    header, d = _gyro_clipped(slice(None), 0.5)
    meas = _write(tmp_path / "clipped.csv", header, d)
    text = (DATA / "robots" / "two_section.toml").read_text()
    robot = tmp_path / "robot.toml"
    robot.write_text(text.replace("[[imu]]", "[[imu]]\naccel_range = 19.6133\ngyro_range = 0.5"))
    out = tmp_path / "est.csv"
    argv = ["estimate", str(meas), "--robot", str(robot), "--method", "ekf", "-o", str(out)]
    with pytest.warns(DropoutWarning, match=r"its gyro's full scale \(its gyro_range, 0.5 rad/s"):
        assert main(argv) == 0
    with out.open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    with (ROD / "planar-s_truth.csv").open() as fh:
        truth = {round(float(r["t"]), 6): r for r in csv.DictReader(fh)}
    ok = [r for r in rows if r["status"] == "ok"]
    assert ok
    for r in ok:
        true = truth[round(float(r["t"]), 6)]
        err = np.linalg.norm([float(r[c]) - float(true[c]) for c in "xyz"])
        assert err < 0.020, (r["t"], err)


def test_declared_ranges_make_clipped_readings_dropouts_and_round_trip(
    tmp_path: Path,
) -> None:
    """The library's conversion skips the readings at a declared full scale (NaN, one
    warning); the robot file keeps the keys, and refuses a range given in g."""
    text = (DATA / "robots" / "two_section.toml").read_text()
    path = tmp_path / "robot.toml"
    path.write_text(text.replace("[[imu]]", "[[imu]]\naccel_range = 19.6133\ngyro_range = 0.5"))
    robot = read_robot(path)
    assert robot.imus[1].gyro_range == 0.5 and robot.imus[0].accel_range == 19.6133
    path.write_text(robot_toml(robot))
    assert read_robot(path) == robot
    header, d = _gyro_clipped(slice(0, 601), 0.5)
    acc = np.stack([d[:, [header.index(f"a{a}_{k}") for a in "xyz"]] for k in (1, 2)], axis=1)
    gyr = np.stack([d[:, [header.index(f"g{a}_{k}") for a in "xyz"]] for k in (1, 2)], axis=1)
    with pytest.warns(DropoutWarning, match=r"IMU 1: \d+ reading\(s\) clipped"):
        z = raw_measurements(robot, d[:, 0], acc, gyr)
    at_scale = (np.abs(gyr) >= 0.5 * 0.99).any(axis=2)
    assert np.array_equal(np.isnan(z[:, :6]).all(axis=1), at_scale[:, 0])
    assert np.array_equal(np.isnan(z[:, 6:]).all(axis=1), at_scale[:, 1])
    path.write_text(text.replace("[[imu]]", "[[imu]]\naccel_range = 2"))
    with pytest.raises(InputError, match=r"accel_range = 2 .* in g\? give m/s\^2"):
        read_robot(path)


def test_the_flat_top_rule_fires_on_no_shipped_recording_and_steps_as_in_blocks() -> None:
    """The automatic rule finds nothing in any shipped raw recording; fed sample by sample
    (as ``live`` feeds it) it finds what it finds in one block."""
    from continuum_mhe.io.raw_imu import ClipWatch

    for path in sorted(DATA.glob("*/*_raw.csv")):
        header, d = _table(path, slice(None))
        for k in (1, 2):
            acc = d[:, [header.index(f"a{a}_{k}") for a in "xyz"]]
            gyr = d[:, [header.index(f"g{a}_{k}") for a in "xyz"]]
            assert not ClipWatch(None, None).see(d[:, 0], acc, gyr).any(), path.name
    header, d = _table(ROD / "spatial-tendon_raw.csv", slice(None))
    acc = d[:, [header.index(f"a{a}_2") for a in "xyz"]]
    gyr = np.clip(1.2 * d[:, [header.index(f"g{a}_2") for a in "xyz"]], -3.0, 3.0)  # rad/s
    whole = ClipWatch(None, None).see(d[:, 0], acc, gyr)
    one = ClipWatch(None, None)
    steps = [
        bool(one.see(d[i : i + 1, 0], acc[i : i + 1], gyr[i : i + 1])[0]) for i in range(len(d))
    ]
    assert whole.sum() > 10 and np.array_equal(whole, steps)
