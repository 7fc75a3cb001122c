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
    assert "IMUs at 1@1 (+-19.6133 m/s^2, +-0.5 rad/s), 2@1 (+-19.6133" in robot.describe()
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
    gyr = np.clip(1.5 * d[:, [header.index(f"g{a}_2") for a in "xyz"]], -4.363, 4.363)  # 250 deg/s
    whole = ClipWatch(None, None).see(d[:, 0], acc, gyr)
    one = ClipWatch(None, None)
    steps = [
        bool(one.see(d[i : i + 1, 0], acc[i : i + 1], gyr[i : i + 1])[0]) for i in range(len(d))
    ]
    assert whole.sum() > 10 and np.array_equal(whole, steps)


def test_a_gyro_the_tilt_model_leaves_out_is_not_watched(tmp_path: Path) -> None:
    """``--imu-model tilt`` reads the accelerometers alone: with the gyros clipped at a
    declared ``gyro_range`` the estimate is the unclipped recording's (each clipped gyro
    had dropped its IMU's good accelerometer reading: 300 of IMU 1's 601)."""
    header, d = _gyro_clipped(slice(None), 0.5)
    clipped = _write(tmp_path / "clipped.csv", header, d)
    plain = _write(tmp_path / "plain.csv", *_table(ROD / "planar-s_raw.csv", slice(None)))
    text = (DATA / "robots" / "two_section.toml").read_text()
    robot = tmp_path / "robot.toml"
    robot.write_text(text.replace("[[imu]]", "[[imu]]\ngyro_range = 0.5"))
    outs = []
    for meas, robot_file in ((plain, "two-section"), (clipped, str(robot))):
        outs.append(tmp_path / f"{meas.stem}.est.csv")
        argv = ["estimate", str(meas), "--robot", robot_file, "--imu-model", "tilt"]
        assert main([*argv, "--method", "ekf", "-o", str(outs[-1])]) == 0
    from continuum_mhe.io.state_tables import read_state_table

    first, second = (read_state_table(o) for o in outs)
    assert list(first.status) == list(second.status)
    np.testing.assert_array_equal(first.values, second.values)


def test_readings_rounded_to_two_decimals_make_no_flat_top() -> None:
    """``spatial-tendon``'s raw readings as a logger writing two decimals keeps them:
    IMU 2's gyro repeats 3.11 rad/s three times in a row at its peak, above all it read
    before, which no gyro has as its range (178 deg/s): not taken as a full scale (it
    was, and 23 of its readings were skipped, some of them reading 3.36 rad/s)."""
    from continuum_mhe.io.raw_imu import ClipWatch

    header, d = _table(ROD / "spatial-tendon_raw.csv", slice(None))
    d = np.round(d, 2)
    for k in (1, 2):
        acc = d[:, [header.index(f"a{a}_{k}") for a in "xyz"]]
        gyr = d[:, [header.index(f"g{a}_{k}") for a in "xyz"]]
        watch = ClipWatch(None, None)
        assert not watch.see(d[:, 0], acc, gyr).any() and watch.learned == [None, None]


def test_readings_beyond_a_declared_range_are_kept_and_named() -> None:
    """A gyro declared to clip at 0.5 rad/s that reads 1.24: no sensor reads past its
    range, so the declaration is wrong; those readings are kept (they had been skipped
    as clipped) and the notice names them, with the largest."""
    from continuum_mhe.io.raw_imu import ClipWatch, RawImuConverter, RawImuSettings, clip_notice

    header, d = _table(ROD / "planar-s_raw.csv", slice(None))
    acc = d[:, [header.index(f"a{a}_1") for a in "xyz"]]
    gyr = d[:, [header.index(f"g{a}_1") for a in "xyz"]]
    largest = np.abs(gyr).max(axis=1)
    assert largest.max() > 1.05 * 0.5
    watch = ClipWatch(None, 0.5)
    clipped = watch.see(d[:, 0], acc, gyr)
    assert np.array_equal(clipped, (largest >= 0.495) & (largest <= 0.525))
    assert watch.beyond[1] == int((largest > 0.525).sum()) > 0
    conv = RawImuConverter(RawImuSettings(imu_model="direct", gyro_range=0.5))
    conv.convert_many(d[:, 0], acc, gyr)
    note = clip_notice([conv])
    assert note is not None
    assert f"{watch.beyond[1]} gyro reading(s) up to {largest.max():.4g} rad/s beyond" in note


def test_a_flat_top_runs_across_a_converter_reset_as_across_a_file_gap() -> None:
    """``live`` resets its converters at a gap, ``estimate`` reads on: the flat-top rule
    sees the same readings in both (a reset had cleared its run, so that ``live`` found
    1 clipped reading where ``estimate`` found 3)."""
    from continuum_mhe.io.raw_imu import RawImuConverter, RawImuSettings

    n = 12
    acc = np.tile([0.0, 0.0, STANDARD_GRAVITY], (n, 1))
    acc[4:9, 0] = TWO_G  # a knock clipped at 2 g, five readings
    t = np.arange(n) * 0.02
    t[6:] += 2.0  # a gap after the first two clipped readings
    gyr = np.zeros((n, 3))
    stepped = RawImuConverter(RawImuSettings(imu_model="direct"))
    rows = []
    for i in range(n):
        if i == 6:
            stepped.reset()
        rows.append(stepped.convert(float(t[i]), acc[i], gyr[i]))
    whole = RawImuConverter(RawImuSettings(imu_model="direct")).convert_many(t, acc, gyr)
    np.testing.assert_array_equal(np.isnan(np.array(rows)), np.isnan(whole))
    assert stepped.clips.clipped == 3


def test_an_accel_range_in_g_of_a_common_scale_is_refused(tmp_path: Path) -> None:
    """``accel_range = 16`` (a +-16 g accelerometer's range written in g) lies within the
    m/s^2 limits, where it would skip every reading beyond 1.6 g: refused as g."""
    text = (DATA / "robots" / "two_section.toml").read_text()
    path = tmp_path / "robot.toml"
    for value in ("16", "24", "32"):
        path.write_text(text.replace("[[imu]]", f"[[imu]]\naccel_range = {value}"))
        with pytest.raises(InputError, match=r"in g\? give m/s\^2"):
            read_robot(path)
    path.write_text(text.replace("[[imu]]", "[[imu]]\naccel_range = 156.9"))
    assert read_robot(path).imus[0].accel_range == 156.9


def test_a_flat_top_that_a_later_reading_passes_is_no_longer_taken() -> None:
    """Three readings at 2 g in a row are taken as a flat top at the full scale; a later
    reading of 30 m/s^2 shows that 2 g was no full scale: from it on the readings are
    kept (a 19.7 m/s^2 one after it was skipped as clipped), and the notice says that the
    flat top was taken until then."""
    from continuum_mhe.io.raw_imu import ClipWatch, RawImuConverter, RawImuSettings, clip_notice

    n = 12
    acc = np.tile([0.0, 0.0, STANDARD_GRAVITY], (n, 1))
    acc[3:6, 0] = TWO_G
    acc[8, 0], acc[10, 0] = 30.0, 19.7
    t = np.arange(n) * 0.02
    watch = ClipWatch(None, None)
    clipped = watch.see(t, acc, None)
    assert list(np.flatnonzero(clipped)) == [5]  # the flat top's third reading alone
    assert watch.learned[0] is None and watch.refuted[0] == pytest.approx(TWO_G)
    one = ClipWatch(None, None)
    assert [bool(one.see(t[i : i + 1], acc[i : i + 1], None)[0]) for i in range(n)] == list(clipped)
    conv = RawImuConverter(RawImuSettings(imu_model="tilt"))
    conv.convert_many(t, acc, None)
    note = clip_notice([conv])
    assert note is not None and "taken as its full scale until then" in note
