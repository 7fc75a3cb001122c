"""Raw IMU input: the direct formulation, the raw CSV reader, the attitude options, and
estimation from a simulated recording whose accelerometer feels the tip's own
acceleration."""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from header_helpers import assert_header_refused, imu_columns, renamed

from continuum_mhe.arrays import FloatArray
from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.io.raw_imu import (
    RawImuConverter,
    RawImuSettings,
    gravity_from_quaternion,
    mount_rotation,
    raw_to_measurements,
    read_raw_imu,
    read_raw_imus,
)
from continuum_mhe.io.raw_units import (
    GYRO_MEDIAN_MAX,
    gyro_gravity_problem,
    gyro_motion_problem,
)
from continuum_mhe.io.state_tables import read_states
from continuum_mhe.model.direct import (
    DEFAULT_GYRO_STD,
    DirectFormulation,
    direct_measurements,
    raw_imu_readings,
    tip_angular_velocity_bend_sym,
)
from continuum_mhe.model.imu import tilt_from_accelerometer
from continuum_mhe.model.kinematics import rotation_bend
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings, NoiseSettings, RobotSettings
from continuum_mhe.simulation.scenarios import simulate

G = 9.80665
_X = ca.SX.sym("x", 4)
OMEGA = ca.Function("w", [_X], [tip_angular_velocity_bend_sym(_X[0], _X[1], _X[2], _X[3])])


@pytest.mark.parametrize(
    "x",
    [
        [0.0, 0.0, 0.3, -0.2],  # straight
        [1e-8, 0.0, 0.4, 0.5],
        [math.pi / 2, 0.0, 0.1, 0.2],
        [0.3, -0.9, -0.7, 0.25],
        [-0.6, 0.2, 0.0, 1.3],
    ],
)
def test_angular_velocity_matches_finite_differences(x: list[float]) -> None:
    a, b, ad, bd = x
    h = 1e-6
    dr = (rotation_bend(a + h * ad, b + h * bd) - rotation_bend(a - h * ad, b - h * bd)) / (2 * h)
    w_hat = rotation_bend(a, b).T @ dr
    np.testing.assert_allclose(w_hat, -w_hat.T, atol=1e-8)  # skew: R^T dR/dt is so(3)
    expected = [w_hat[2, 1], w_hat[0, 2], w_hat[1, 0]]
    np.testing.assert_allclose(np.asarray(OMEGA(x)).ravel(), expected, atol=1e-7)


def test_direct_formulation_model() -> None:
    f = make_formulation("direct", estimate_gyro_bias=False)
    assert isinstance(f, DirectFormulation) and f.nz == 6
    x = np.array([0.4, -0.3, 0.2, 0.1])
    z = np.asarray(f.functions.observe(x)).ravel()
    assert np.linalg.norm(z[:3]) == pytest.approx(1.0)
    # gravity part agrees with the tilt model, rates are linear in (a_dot, b_dot)
    np.testing.assert_allclose(
        tilt_from_accelerometer(z[:3]),
        np.asarray(make_formulation("bend").functions.observe(x)).ravel(),
    )
    np.testing.assert_allclose(f.initial_state(z), x, atol=1e-12)
    # residuals are plain differences: no wrapping
    z_far = z + 4.0
    r = np.asarray(f.functions.innovate(z_far, x)[0], dtype=float).ravel()
    np.testing.assert_allclose(r, [4.0] * 6, atol=1e-12)
    r = np.diag(f.meas_cov())
    assert r[0] == pytest.approx(f.noise.measurement_std**2) and r[3] == pytest.approx(
        DEFAULT_GYRO_STD**2
    )
    with pytest.raises(ValueError, match="gyro_std"):
        DirectFormulation(gyro_std=-1.0)


def test_mhe_uses_direct_model_generically() -> None:
    """The IPOPT MHE builds its NLP from nz and measurement_residual_sym unchanged."""
    f = make_formulation("direct", estimate_gyro_bias=False)
    t = np.arange(40) * 0.05
    X = np.column_stack([0.5 * np.sin(t), 0.3 * np.cos(t), 0.5 * np.cos(t), -0.3 * np.sin(t)])
    Z = np.array([np.asarray(f.functions.observe(x)).ravel() for x in X])
    Z[20] = np.nan
    s = make_estimator("mhe", f, MHESettings(horizon=10)).run(t, Z)
    assert s.status[20] == "dropout" and set(s.status[1:]) <= {"ok", "dropout"}
    np.testing.assert_allclose(s.output[:, 3], np.hypot(X[:, 0], X[:, 1]), atol=5e-3)


@pytest.fixture(scope="module")
def moving_tip() -> dict[str, np.ndarray]:
    """A 0.2 m robot moving through paper3d, 50 Hz; accelerometer includes a_tip."""
    rec = simulate("paper3d", duration=8.0, dt=0.02, noise_deg=0.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], 0.2)
    rng = np.random.default_rng(7)
    return {
        "t": rec.t,
        "truth": rec.truth,
        "acc_clean": acc,
        "acc": acc + rng.normal(size=acc.shape) * 0.3,  # about 1.8 deg of direction
        "gyr": gyr + rng.normal(size=gyr.shape) * 0.02,
    }


def test_simulated_accelerometer_feels_tip_acceleration(moving_tip: dict[str, np.ndarray]) -> None:
    """The specific force's magnitude is |a + g e_z| whatever the sensor's orientation,
    with the tip's acceleration ``a`` differenced from the simulator's own tip positions
    (not the readings' kinematics)."""
    norm = np.linalg.norm(moving_tip["acc_clean"], axis=1)
    t, tip = moving_tip["t"], moving_tip["truth"][:, :3]
    a = np.gradient(np.gradient(tip, t, axis=0), t, axis=0)
    np.testing.assert_allclose(norm, np.linalg.norm(a + [0.0, 0.0, G], axis=1), rtol=1e-9)
    assert np.abs(norm - G).max() > 1e-3  # the tip's own acceleration is in there


@pytest.mark.parametrize("method", ["ekf", "mhe"])
def test_raw_imus_estimate_better_than_their_tilt(
    moving_tip: dict[str, np.ndarray], method: str
) -> None:
    """The gyros fused (the direct model) at most half the tip error of the same IMU
    reduced to tilt: an estimator that ignored the gyros would give the tilt's."""
    t, truth = moving_tip["t"], moving_tip["truth"]
    robot, noise = RobotSettings(length=0.2), NoiseSettings(measurement_std=math.radians(2))
    mhe = MHESettings(horizon=10)
    errors = {}
    for model in ("tilt", "direct"):
        z = raw_to_measurements(
            t, moving_tip["acc"], moving_tip["gyr"], RawImuSettings(imu_model=model)
        )
        f = make_formulation("direct" if model == "direct" else "bend", robot, noise)
        s = make_estimator(method, f, mhe).run(t, z)
        errors[model] = compute_metrics(s.output, truth, robot.length).tip_mean_mm
    assert errors["direct"] < 0.5 * errors["tilt"], errors


def test_the_up_direction_of_an_attitude_quaternion_is_scipys() -> None:
    """The up direction in the sensor frame of a sensor-to-world quaternion ``(w, x, y,
    z)`` is ``R(q)^T e_z`` of SciPy's rotation of that quaternion, at any yaw (where
    every term counts: near yaw 0 the ``y z`` one vanishes) and of any norm; known
    answers: a turn by ``a`` about x reads ``(0, sin a, cos a)``, a half turn about y
    ``(0, 0, -1)``."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(4)
    quats = rng.normal(size=(200, 4)) * rng.uniform(0.1, 3.0, (200, 1))
    quats[:3] = [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]]
    up = Rotation.from_quat(quats[:, [1, 2, 3, 0]]).as_matrix()[:, 2, :]  # R^T e_z: row 3
    got = np.array([gravity_from_quaternion(q) for q in quats])
    np.testing.assert_allclose(got, up, rtol=0, atol=1e-14)
    a = 0.7
    about_x = [math.cos(a / 2), math.sin(a / 2), 0.0, 0.0]
    np.testing.assert_allclose(gravity_from_quaternion(about_x), [0.0, math.sin(a), math.cos(a)],
                               rtol=0, atol=1e-15)  # fmt: skip
    np.testing.assert_allclose(gravity_from_quaternion([0.0, 0.0, 1.0, 0.0]), [0.0, 0.0, -1.0],
                               rtol=0, atol=1e-15)  # fmt: skip


def test_gyro_fusion_tracks_tilt(moving_tip: dict[str, np.ndarray]) -> None:
    t, acc, gyr = moving_tip["t"], moving_tip["acc"], moving_tip["gyr"]
    truth = tilt_from_accelerometer(
        np.einsum("nji,j->ni", rotation_bend(*_bend(moving_tip["truth"])), [0.0, 0.0, 1.0])
    )
    err = {}
    for att in ("accel", "madgwick", "mahony"):
        z = raw_to_measurements(t, acc, gyr, RawImuSettings(attitude=att))
        err[att] = float(np.sqrt(np.mean((z - truth)[50:] ** 2)))
    # the gyro smooths the accelerometer noise (measured: accel 0.070, madgwick 0.017,
    # mahony 0.013 rad RMS)
    assert err["madgwick"] < 0.5 * err["accel"], err
    assert err["mahony"] < 0.5 * err["accel"], err


def _bend(truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return truth[:, 3] * np.cos(truth[:, 4]), truth[:, 3] * np.sin(truth[:, 4])


def test_mount_rotation_undoes_a_rotated_sensor(moving_tip: dict[str, np.ndarray]) -> None:
    t, acc, gyr = moving_tip["t"], moving_tip["acc"], moving_tip["gyr"]
    rpy = (10.0, -20.0, 90.0)
    m = mount_rotation(rpy)
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-12)
    sensor_acc, sensor_gyr = acc @ m, gyr @ m  # v_sensor = M^T v_tip
    for model in ("tilt", "direct"):
        ref = raw_to_measurements(t, acc, gyr, RawImuSettings(imu_model=model))
        got = raw_to_measurements(
            t, sensor_acc, sensor_gyr, RawImuSettings(imu_model=model, mount_rpy=rpy)
        )
        np.testing.assert_allclose(got, ref, atol=1e-12)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("body", "needle"),
    [
        ("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.1,0,zz,9.8,0,0,0\n", "line 3: column ay: 'zz'"),
        ("t,ax,ay,az\n0,0,0,9.8\n0.1,0,0,9.8\n0.05,0,0,9.8\n", "line 4: decreasing timestamp"),
        ("t,ax,ay,az\n0,0,0,1.0\n0.1,0,0,1.0\n", "look like g"),
        (
            "t,ax,ay,az\n0,0,0,980.7\n0.1,0,0,980.7\n",
            "look like cm/s^2 (or milli-g, which reads 1000 at rest); ax, ay, az must be",
        ),
        ("t,ax,ay,az\n0,0,0,9807\n0.1,0,0,9807\n", "like mm/s^2; ax, ay, az must be in m/s^2"),
        ("t,ax,ay\n0,0,0\n", "line 1: the IMU has no az column (an IMU's raw columns: ax,"),
        ("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0\n", "line 2: expected 7 fields, found 6"),
    ],
)
def test_raw_csv_errors_name_the_line(tmp_path: Path, body: str, needle: str) -> None:
    with pytest.raises(InputError, match=None) as info:
        read_raw_imu(_write(tmp_path / "raw.csv", body))
    assert needle in str(info.value) and "\n" not in str(info.value)


_THREE_IMUS = imu_columns(("ax", "ay", "az", "gx", "gy", "gz"), 3)


def _renamed(old: str, new: str) -> str:
    """The three-IMU raw header with column ``old`` renamed ``new`` (``""``: left out)."""
    return renamed(_THREE_IMUS, {old: new})


def _read_raw(n_imus: int) -> Callable[[Path], object]:
    return (lambda p: read_raw_imus(p, n_imus)) if n_imus > 1 else read_raw_imu


@pytest.mark.parametrize(
    ("header", "n_imus", "message"),
    [
        (_renamed("ay_2", "ay2"), 3, "IMU 2 has no ay_2 column; the header has ay2 (a typo?)"),
        (_renamed("ax_3", "ax_4"), 3, "IMU 3 has no ax_3 column; the header has ax_4 (a typo?)"),
        (_renamed("ax_2", ""), 3,
         "IMU 2 has no ax_2 column (an IMU's raw columns: ax_k, ay_k, az_k, and gx_k, gy_k, "
         "gz_k for its gyro)"),
        (_renamed("ax_1", "ax_0"), 3, "IMU 1 has no ax_1 column; the header has ax_0 (a typo?)"),
        (_renamed("gx_2", "gx2"), 3, "IMU 2 has no gx_2 column; the header has gx2 (a typo?)"),
        ("t,ax,ay_,az,gx,gy,gz", 1, "the IMU has no ay column; the header has ay_ (a typo?)"),
        # not IMU 1 read alone, the typo beyond the robot's IMU unseen
        (_renamed("ay_3", "ay3"), 1, "IMU 3 has no ay_3 column; the header has ay3 (a typo?)"),
        # no column besides the IMU's: not an internal error (difflib's n must be > 0)
        ("ax,ay,az,gx,gy", 1,
         "the IMU has no gz column (an IMU's raw columns: ax, ay, az, and gx, gy, gz for its "
         "gyro)"),
    ],
)  # fmt: skip
def test_a_raw_header_typo_names_the_missing_column_and_the_typo(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], header: str, n_imus: int, message: str
) -> None:
    """A raw header with a typo names the missing column and the typo, refused in one
    line: not blamed on the IMU count ("the file has raw columns for 1 IMU(s) ..." for
    ay2), not read as a tilt file ("missing column(s) roll, pitch" for ay_), and a
    renamed gx_2 does not drop every IMU's gyro."""
    assert_header_refused(tmp_path, capsys, header, n_imus, message, _read_raw(n_imus))


@pytest.mark.parametrize(
    ("left_out", "message"),
    [
        ((2,), "IMU 2 has no gx_2, gy_2, gz_2 columns, IMU 1 and 3 have them"),
        ((2, 3), "IMU 2 and 3 have no gyro columns (gx_k, gy_k, gz_k), IMU 1 has them"),
    ],
)
def test_some_imus_gyro_columns_without_the_others_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], left_out: tuple[int, ...], message: str
) -> None:
    """Some IMUs' gyro columns without the others' are refused in one line naming them
    (every IMU's gyro or none), not every IMU read without its gyro."""
    header = renamed(_THREE_IMUS, {f"{c}_{k}": "" for k in left_out for c in ("gx", "gy", "gz")})
    message += ": give every IMU's gyro or none"
    assert_header_refused(tmp_path, capsys, header, 3, message, _read_raw(3))


def test_raw_csv_skip_bad_keeps_dropouts(tmp_path: Path) -> None:
    body = (
        "t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.1,0,x,9.8,0,0,0\n"
        "0.05,0,0,9.8,0,0,0\n0.2,0,0,9.8,0,0,0\n"
    )
    table = read_raw_imu(_write(tmp_path / "raw.csv", body), skip_bad=True)
    assert table.t.tolist() == [0.0, 0.1, 0.2]
    assert np.isnan(table.acc[1, 1]) and len(table.skipped) == 2


def test_estimate_cli_on_raw_csv(tmp_path: Path, moving_tip: dict[str, np.ndarray]) -> None:
    t, acc, gyr = moving_tip["t"][:100], moving_tip["acc"][:100], moving_tip["gyr"][:100]
    rows = ["t,ax,ay,az,gx,gy,gz"] + [
        ",".join(repr(float(v)) for v in (ti, *a, *g)) for ti, a, g in zip(t, acc, gyr)
    ]
    raw = _write(tmp_path / "raw.csv", "\n".join(rows) + "\n")
    for model, extra in (("tilt", ["--attitude", "mahony"]), ("direct", [])):
        out = tmp_path / f"est_{model}.csv"
        assert (
            main(
                [
                    "estimate",
                    str(raw),
                    "-o",
                    str(out),
                    "--method",
                    "ekf",
                    "--imu-model",
                    model,
                    *extra,
                ]
            )
            == 0
        )
        te, xe, _ = read_states(out)
        np.testing.assert_allclose(te, t, rtol=1e-9)
        assert np.linalg.norm(xe[:, :3] - moving_tip["truth"][:100, :3], axis=1).mean() < 5e-3


def test_direct_on_tilt_csv_is_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tilt_csv = _write(tmp_path / "m.csv", "t,roll,pitch\n0,0.1,0.2\n0.05,0.1,0.2\n")
    assert (
        main(["estimate", str(tilt_csv), "-o", str(tmp_path / "e.csv"), "--imu-model", "direct"])
        == 2
    )
    err = capsys.readouterr().err
    assert err.startswith("continuum-mhe: error: ") and "needs raw" in err and err.count("\n") == 1
    raw = _write(tmp_path / "r.csv", "t,ax,ay,az\n0,0,0,9.8\n0.05,0,0,9.8\n")
    assert main(["estimate", str(raw), "-o", str(tmp_path / "e.csv"), "--imu-model", "direct"]) == 2
    assert "needs gyro columns" in capsys.readouterr().err
    assert main(["estimate", str(raw), "-o", str(tmp_path / "e.csv"), "--mount-rpy", "1,2"]) == 2
    assert "--mount-rpy" in capsys.readouterr().err
    assert not (tmp_path / "e.csv").exists()


def test_mount_calibration_recipe_of_the_docs() -> None:
    """docs/hardware.md: a still, straight robot reading m needs --mount-rpy roll,pitch,0."""
    m = np.array([1.5, -2.0, 9.5])
    roll, pitch = np.degrees(tilt_from_accelerometer(m))
    z = raw_to_measurements(
        np.array([0.0]),
        m[None],
        np.zeros((1, 3)),
        RawImuSettings(imu_model="direct", mount_rpy=(roll, pitch, 0.0)),
    )
    np.testing.assert_allclose(z[0, :3], [0.0, 0.0, 1.0], atol=1e-12)


@pytest.mark.parametrize("zero", ["0,0,0", "1e-200,0,1e-200", "0,5e-163,0"])
def test_zero_acceleration_is_an_error_unless_skipped(tmp_path, zero: str) -> None:
    """A zero, or one so small that its square underflows (no direction to read either:
    the conversions would make it a dropout that no count or line names)."""
    from continuum_mhe.errors import InputError
    from continuum_mhe.io.raw_imu import read_raw_imu

    p = tmp_path / "raw.csv"
    p.write_text(f"t,ax,ay,az\n0,0,0,9.81\n0.01,{zero}\n0.02,0,0.1,9.8\n")
    with pytest.raises(InputError, match=r"raw.csv: line 3: acceleration is zero"):
        read_raw_imu(p)
    table = read_raw_imu(p, skip_bad=True)
    assert np.isnan(table.acc[1]).all() and len(table.skipped) == 1


@pytest.mark.parametrize(
    ("row", "magnitude"),
    [("1e200,1e200,9.8,0,0,0", "1.41e+200 m/s^2"), ("0,0,9.8,0,2e3,0", "2e+03 rad/s")],
)
def test_a_reading_beyond_any_imus_range_is_an_error_unless_skipped(
    tmp_path: Path, row: str, magnitude: str
) -> None:
    """A corrupt value far beyond any sensor (a 1e200 would overflow the magnitude and
    reach the mounting check as 'nan degrees') is named with its line; ``--skip-bad``
    reads it as a dropout; with several IMUs it names the IMU too, and ``--skip-bad``
    reads it as that IMU's dropout (the others' readings kept)."""
    good = "0,0,9.8,0,0,0"
    path = _write(tmp_path / "raw.csv", f"t,ax,ay,az,gx,gy,gz\n0,{good}\n0.02,{row}\n0.04,{good}\n")
    with pytest.raises(
        InputError,
        match=rf"raw.csv: line 3: a reading beyond any IMU's range .*{re.escape(magnitude)}",
    ):
        read_raw_imu(path)
    table = read_raw_imu(path, skip_bad=True)
    assert np.isnan(table.acc[1]).all() and np.isfinite(table.acc[[0, 2]]).all()
    assert len(table.skipped) == 1
    header = "t," + ",".join(
        f"{c}_{i}" for i in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz")
    )
    two = _write(tmp_path / "two.csv", f"{header}\n0,{good},{good}\n0.02,{row},{good}\n")
    with pytest.raises(
        InputError,
        match=rf"two.csv: line 3: IMU 1: a reading beyond any IMU's range .*{re.escape(magnitude)}",
    ):
        read_raw_imus(two, 2)
    skipped = read_raw_imus(two, 2, skip_bad=True)
    first, second = skipped.imus
    assert np.isnan(first.acc[1]).all() and np.isfinite(second.acc).all()
    assert len(skipped.skipped) == 1 and skipped.skipped[0].startswith("line 3: IMU 1: ")


def test_an_accelerometer_in_raw_counts_is_named_not_read_as_dropouts(tmp_path: Path) -> None:
    """Most readings of one IMU of several beyond any IMU's range (an accelerometer in
    raw counts, 16384 per g): one InputError naming that IMU and the unit, not a
    recording whose IMU never reported; a single such reading stays a dropout (above)."""
    header = "t," + ",".join(
        f"{c}_{i}" for i in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz")
    )
    rows = "".join(f"{0.02 * k},0,0,9.8,0,0,0,0,164,16383,0,0,0\n" for k in range(12))
    path = _write(tmp_path / "counts.csv", header + "\n" + rows)
    with pytest.raises(
        InputError,
        match=r"^.*counts.csv: IMU 2: accelerometer magnitude is about 1\.64e\+04 \(median\), "
        r"beyond any IMU's range in m/s\^2 \(limit 10000\): raw counts\? give m/s\^2",
    ):
        read_raw_imus(path, 2)


@pytest.mark.parametrize(
    ("rate", "fails"), [(0.99 * GYRO_MEDIAN_MAX, False), (1.01 * GYRO_MEDIAN_MAX, True)]
)
def test_gyro_rates_implausible_in_rad_s_are_an_error(
    tmp_path: Path, rate: float, fails: bool
) -> None:
    """Median |omega| against the documented bound: above it the gyro is in deg/s."""
    body = "t,ax,ay,az,gx,gy,gz\n" + "".join(
        f"{0.02 * i},0,0,9.8,0,{rate * 0.6},{rate * 0.8}\n" for i in range(5)
    )
    path = _write(tmp_path / "raw.csv", body)
    if not fails:
        np.testing.assert_allclose(np.linalg.norm(read_raw_imu(path).gyr, axis=1), rate)
        return
    with pytest.raises(InputError) as info:
        read_raw_imu(path)
    assert str(info.value) == (
        f"{path}: gyro magnitude is about {rate:.3g} (median), implausible in rad/s "
        "(above 5): deg/s? give rad/s (gx, gy, gz times pi/180 = 0.0174533)"
    )


@pytest.mark.parametrize(
    ("header", "said"),
    [
        (
            "t,ax1,ay1,az1,gx1,gy1,gz1,ax2,ay2,az2,gx2,gy2,gz2",
            "ax1 -> ax_1, ay1 -> ay_1, az1 -> az_1, ...",
        ),
        (
            "time_s,acc_x,acc_y,acc_z,gyro_x,gyro_y,gyro_z",
            "acc_x -> ax, acc_y -> ay, acc_z -> az, ...",
        ),
        ("t,Accel_X_2,wz", "Accel_X_2 -> ax_2, wz -> gz"),
        ("t,ax0,ay0,az0,ax1,ay1,az1", "ax0 -> ax_1, ay0 -> ay_1, az0 -> az_1, ..."),
        # the IMU's number before the name (a logger's imu1_ax, MATLAB's imu1.ax)
        (
            "t,imu1_ax,imu1_ay,imu1_az,imu1_gx,imu1_gy,imu1_gz,imu2_ax,imu2_ay,imu2_az",
            "imu1_ax -> ax_1, imu1_ay -> ay_1, imu1_az -> az_1, ...",
        ),
        ("t,IMU2.acc_x,imu1.gyro_z", "IMU2.acc_x -> ax_2, imu1.gyro_z -> gz_1"),
        # a unit after the name, which is not read
        (
            "t,ax_1 [m/s^2],ay_1 [m/s^2],az_1 [m/s^2],ax_2 (m/s^2)",
            "ax_1 [m/s^2] -> ax_1, ay_1 [m/s^2] -> ay_1, az_1 [m/s^2] -> az_1, ...",
        ),
        # tilt angles so named
        (
            "t,imu1_roll,imu1_pitch,imu2_roll,imu2_pitch",
            "imu1_roll -> roll_1, imu1_pitch -> pitch_1, imu2_roll -> roll_2, ...",
        ),
    ],
)
def test_a_logger_header_with_other_imu_names_is_told_the_names_to_use(
    tmp_path: Path, capsys: pytest.CaptureFixture, header: str, said: str
) -> None:
    """A header whose accelerometer and gyro columns are spelled otherwise (a logger's
    ``ax1``, ``acc_x``): one line giving the names the reader takes and the rename of
    the first columns, not a request for tilt columns."""
    values = ",".join(["0.0"] * len(header.split(",")))
    path = _write(tmp_path / "logger.csv", f"{header}\n{values}\n")
    out = tmp_path / "est.csv"
    code = main(["estimate", str(path), "-o", str(out), "--robot", "two-section"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and not out.exists()
    assert err == (
        f"continuum-mhe: error: {path}: line 1: no column is named as this reader takes IMU "
        "readings: raw columns are t,ax,ay,az,gx,gy,gz for one IMU and ax_1 ... gz_1, ax_2 ... "
        "for several (m/s^2, rad/s), tilt ones roll, pitch (roll_1, pitch_1 ...); rename the "
        f"columns ({said})\n"
    )


@pytest.mark.parametrize(
    ("header", "robot", "said"),
    [
        ("t,ax,ay,az,gyro_x,gyro_y,gyro_z", [], "gyro_x -> gx, gyro_y -> gy, gyro_z -> gz"),
        (
            "t,ax_1,ay_1,az_1,gyro_x_1,gyro_y_1,gyro_z_1,ax_2,ay_2,az_2,Gyro_X_2,gyro_y_2,gyro_z_2",
            ["--robot", "two-section"],
            "gyro_x_1 -> gx_1, gyro_y_1 -> gy_1, gyro_z_1 -> gz_1, ...",
        ),
        ("t,ax,ay,az,wx,wy,wz", [], "wx -> gx, wy -> gy, wz -> gz"),
        ("t,ax,ay,az,gx_1,gy_1,gz_1", [], "gx_1 -> gx, gy_1 -> gy, gz_1 -> gz"),
        (
            "t,ax,ay,az,gyro_x_1,gyro_y_1,gyro_z_1",
            [],
            "gyro_x_1 -> gx, gyro_y_1 -> gy, gyro_z_1 -> gz",
        ),
        # a unit after the name (an export's gx_1_rad_s, gx_dps, gx_1 (rad/s))
        (
            "t,ax_1,ay_1,az_1,gx_1_rad_s,gy_1_rad_s,gz_1_rad_s,ax_2,ay_2,az_2,gx_2_rad_s,"
            "gy_2_rad_s,gz_2_rad_s",
            ["--robot", "two-section"],
            "gx_1_rad_s -> gx_1, gy_1_rad_s -> gy_1, gz_1_rad_s -> gz_1, ...",
        ),
        ("t,ax,ay,az,gx_dps,gy_dps,gz_dps", [], "gx_dps -> gx, gy_dps -> gy, gz_dps -> gz"),
        (
            "t,ax,ay,az,gx (rad/s),gy (rad/s),gz (rad/s)",
            [],
            "gx (rad/s) -> gx, gy (rad/s) -> gy, gz (rad/s) -> gz",
        ),
        # the IMU's number before the name
        (
            "t,ax_1,ay_1,az_1,imu1_gx,imu1_gy,imu1_gz,ax_2,ay_2,az_2,imu2_gx,imu2_gy,imu2_gz",
            ["--robot", "two-section"],
            "imu1_gx -> gx_1, imu1_gy -> gy_1, imu1_gz -> gz_1, ...",
        ),
    ],
)
def test_gyro_columns_named_otherwise_beside_the_accelerometer_are_not_left_out(
    tmp_path: Path, capsys: pytest.CaptureFixture, header: str, robot: list[str], said: str
) -> None:
    """Accelerometer columns as the reader takes them and gyro columns spelled
    otherwise (``gyro_x``, ``wx``): one line giving the renames, nothing written; the
    gyros are not left out without a word."""
    values = ",".join(["0.0"] * len(header.split(",")))
    rows = "\n".join(values.replace("0.0", str(k * 0.05), 1) for k in range(5))
    path = _write(tmp_path / "imu.csv", f"{header}\n{rows}\n")
    out = tmp_path / "est.csv"
    assert main(["estimate", str(path), "-o", str(out), *robot]) == 2
    assert not out.exists()
    assert capsys.readouterr().err == (
        f"continuum-mhe: error: {path}: line 1: columns named like gyro readings that this "
        f"reader does not take, which would be left out: rename them ({said}; gx, gy, gz "
        "in rad/s, gx_1 ... for several IMUs), or remove them to estimate from the "
        "accelerometers alone\n"
    )


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (
            "t,gx,gy,gz\n0.0,0.0,0.0,0.0\n",
            "gyro columns (gx, gy, gz) but no accelerometer columns (ax, ay, az; ax_1 ... for "
            "several IMUs): raw readings need the accelerometer (m/s^2); the gyro is optional",
        ),
        (
            "t,ax_mps2,ay_mps2,az_mps2,gx,gy,gz\n0,0,0,9.8,0,0,0\n",
            "no accelerometer column is named as this reader takes IMU readings: raw columns "
            "are t,ax,ay,az,gx,gy,gz for one IMU and ax_1 ... gz_1, ax_2 ... for several "
            "(m/s^2, rad/s), tilt ones roll, pitch (roll_1, pitch_1 ...); rename the columns "
            "(ax_mps2 -> ax, ay_mps2 -> ay, az_mps2 -> az)",
        ),
    ],
)
def test_a_header_with_gyro_columns_alone_asks_for_the_accelerometer(
    tmp_path: Path, capsys: pytest.CaptureFixture, text: str, said: str
) -> None:
    """Gyro columns without accelerometer ones: one line saying the accelerometer is
    needed (not a rename of gx to gx); beside accelerometer columns with a unit in their
    names (``ax_mps2``), the renames of those."""
    path = _write(tmp_path / "gyro.csv", text)
    assert main(["estimate", str(path), "-o", str(tmp_path / "e.csv")]) == 2
    assert capsys.readouterr().err == f"continuum-mhe: error: {path}: line 1: {said}\n"
    assert not (tmp_path / "e.csv").exists()


def test_a_header_without_imu_columns_names_the_robots_columns(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A header with no IMU column at all asks for the robot's own columns: numbered
    for a robot of two IMUs, unnumbered for one."""
    path = _write(tmp_path / "other.csv", "t,x,y\n0.0,0.0,0.0\n")
    out = tmp_path / "est.csv"
    for robot, missing in (
        (["--robot", "two-section"], "roll_1, pitch_1, roll_2, pitch_2"),
        ([], "roll, pitch"),
    ):
        assert main(["estimate", str(path), "-o", str(out), *robot]) == 2
        err = capsys.readouterr().err
        assert err == (
            f"continuum-mhe: error: {path}: line 1: missing column(s) {missing} "
            "(header has: t, x, y)\n"
        )


def _still_two_imus(tmp_path: Path, gyro: np.ndarray, name: str) -> Path:
    """A 10 s raw recording of the shipped two-section robot held straight and still
    (each IMU's accelerometer gravity plus noise), its gyros reading ``gyro`` (n, 6)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 10.0, 0.02)
    acc = np.array([0.05, -0.08, 9.80]) + rng.normal(0.0, 0.05, (len(t), 6))[:, :3]
    cols = [acc, gyro[:, :3], acc + rng.normal(0.0, 0.05, acc.shape), gyro[:, 3:]]
    rows = np.column_stack([t, *cols])
    header = "t,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,ay_2,az_2,gx_2,gy_2,gz_2"
    text = header + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    return _write(tmp_path / name, text)


def test_a_resting_gyro_in_deg_s_is_told_by_the_accelerometers(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """A robot at rest whose gyros are in deg/s (biases of 1 to 2 deg/s, noise 0.3
    deg/s): their median rate is far below the deg/s threshold, but read as rad/s they
    would turn the gravity direction by tens of degrees a second where the
    accelerometers stay still: one line naming IMU 1 and the likely unit, exit 2,
    nothing written. The same gyros in rad/s, and in rad/s turning at 1.5 rad/s about
    the vertical (which no accelerometer sees), are estimated."""
    rng = np.random.default_rng(4)
    n = 500
    bias = np.array([1.2, -1.5, 0.8, -0.9, 1.1, 1.6])  # deg/s
    degs = bias + rng.normal(0.0, 0.3, (n, 6))
    out = tmp_path / "est.csv"
    for name, gyro, refused in (
        ("degs.csv", degs, True),
        ("rads.csv", np.radians(degs), False),
        ("yaw.csv", np.radians(degs) + np.array([0.0, 0.0, 1.5] * 2), False),
    ):
        path = _still_two_imus(tmp_path, gyro, name)
        code = main(["estimate", str(path), "-o", str(out), "--robot", "two-section"])
        err = capsys.readouterr().err
        if refused:
            assert code == 2 and err.count("\n") == 1 and not out.exists()
            assert err.startswith(
                f"continuum-mhe: error: {path}: IMU 1: the accelerometer's gravity direction "
                "turns as the gyro says only with the gyro in deg/s (read as rad/s it misses by"
            )
            assert err.rstrip().endswith("give rad/s (gx, gy, gz times pi/180 = 0.0174533)")
        else:
            assert code == 0, err
            assert "deg/s" not in err
            out.unlink()


def test_the_gravity_checks_turns_are_scipys_rotations() -> None:
    """The gravity check turns a direction by each stretch's rotation vector as SciPy's
    ``Rotation.from_rotvec(...).apply`` does: random turns, none, tiny ones (1e-9 rad),
    half and whole turns, and turns about the direction itself."""
    from scipy.spatial.transform import Rotation

    from continuum_mhe.io.raw_units import _rotated_by_vectors

    rng = np.random.default_rng(3)
    v = rng.normal(size=(12, 3))
    axis = rng.normal(size=(12, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    angles = np.r_[0.0, 1e-9, math.pi, 2 * math.pi, 7.0, rng.uniform(-4, 4, 7)]
    rotvec = axis * angles[:, None]
    rotvec[-1] = 2.5 * v[-1] / np.linalg.norm(v[-1])  # about the direction itself
    np.testing.assert_allclose(
        _rotated_by_vectors(v, rotvec), Rotation.from_rotvec(rotvec).apply(v), atol=1e-12
    )


def test_the_gravity_check_of_gyro_units_judges_still_stretches_alone() -> None:
    """Known answers of the gravity check: a resting IMU's gyro in deg/s (bias about 2
    deg/s, or 0.4) is found; in rad/s (bias 0.05 rad/s) it is not, also at 100 Hz with a 20 s
    gap and short stretches between its readings (each stretch pairs its own rows
    only); nor is a swinging IMU in rad/s (a pendulum: the specific force stays along
    the rod while the gyro turns, so its stretches are not still), nor a turn about the
    vertical."""
    rng = np.random.default_rng(8)
    t = np.arange(0.0, 10.0, 0.01)
    acc = np.array([0.1, -0.2, 9.8]) + rng.normal(0.0, 0.05, (len(t), 3))
    bias = np.array([1.2, -1.5, 0.9])
    assert gyro_gravity_problem(t, acc, bias + rng.normal(0.0, 0.3, (len(t), 3))) is not None
    rad_s = np.array([0.03, -0.04, 0.01]) + rng.normal(0.0, 0.003, (len(t), 3))
    assert gyro_gravity_problem(t, acc, rad_s) is None
    # a small bias in deg/s (0.4; read as rad/s, 11 deg in half a second) is found, a
    # cheap MEMS gyro's in rad/s (0.09 rad/s, 5 deg/s: 2.5 deg) is not
    small = np.array([0.3, -0.25, 0.1]) + rng.normal(0.0, 0.05, (len(t), 3))
    assert gyro_gravity_problem(t, acc, small) is not None
    cheap = np.array([0.06, -0.06, 0.02]) + rng.normal(0.0, 0.003, (len(t), 3))
    assert gyro_gravity_problem(t, acc, cheap) is None
    # 0.53 s, then 0.5 s more 20 s later: two still stretches and a short one (0.5 to
    # 0.53 s) before the gap, whose step across the gap belongs to no stretch
    gap = np.r_[t[:53], 20.5 + t[:50]]
    assert gyro_gravity_problem(gap, acc[: len(gap)], rad_s[: len(gap)]) is None
    for amp_deg, hz in ((20.0, 0.7), (20.0, 1.2), (25.0, 0.5), (10.0, 1.0)):
        a, w = math.radians(amp_deg), 2 * math.pi * hz
        swing, rate = a * np.sin(w * t), a * w * np.cos(w * t)
        along = 9.81 * np.cos(swing) + 0.3 * rate**2  # the rod's tension, per unit mass
        spec = np.column_stack([np.zeros_like(t), np.zeros_like(t), along])
        gyro = np.column_stack([rate, np.zeros_like(t), np.zeros_like(t)]) + 0.01
        assert gyro_gravity_problem(t, spec, gyro) is None, (amp_deg, hz)
    yaw = np.tile([0.0, 0.0, 1.5], (len(t), 1))  # about the vertical: rad/s, seen by nobody
    assert gyro_gravity_problem(t, np.tile([0.0, 0.0, 9.8], (len(t), 1)), yaw) is None


def _turning_about_x(rates: np.ndarray, t: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The specific force (n, 3; m/s^2, noise 0.05) of an IMU that starts level and turns
    about its x axis at ``rates`` (n,; rad/s) over the times ``t`` (n,; s)."""
    angle = np.r_[0.0, np.cumsum(0.5 * (rates[1:] + rates[:-1]) * np.diff(t))]
    acc = 9.8 * np.column_stack([np.zeros_like(t), np.sin(angle), np.cos(angle)])
    return acc + rng.normal(0.0, 0.05, acc.shape)


def test_a_turn_tells_a_rad_s_gyros_large_offset_from_deg_s() -> None:
    """A still gyro in rad/s with a zero-rate offset of 18 deg/s across gravity (0.32
    rad/s, within some MEMS gyros' tolerance) reads as deg/s on its still stretches. The
    same IMU turned about its x axis by 46 degrees and back (0.8 rad/s, 1 s each way,
    over 10 s mostly still) shows rad/s: not refused. Still throughout it is, in words
    that name the offset a rad/s gyro would need; a gyro in deg/s (offsets of 1 to 2
    deg/s) with the same turns is refused too, and so are a single half-second of turning
    and turns the gyro's rates do not follow (its x and y swapped)."""
    rng = np.random.default_rng(11)
    t = np.arange(0.0, 10.0, 0.01)
    rates = np.where((t >= 4.0) & (t < 5.0), 0.8, 0.0) - np.where((t >= 7.0) & (t < 8.0), 0.8, 0.0)
    acc = _turning_about_x(rates, t, rng)
    offset = np.array([0.25, -0.2, 0.05])  # rad/s
    turning = np.column_stack([rates, 0 * t, 0 * t]) + offset + rng.normal(0.0, 0.003, acc.shape)
    assert gyro_gravity_problem(t, acc, turning) is None
    still = offset + rng.normal(0.0, 0.003, acc.shape)
    flat = np.array([0.0, 0.0, 9.8]) + rng.normal(0.0, 0.05, acc.shape)
    problem = gyro_gravity_problem(t, flat, still)
    assert problem is not None
    assert "a zero-rate offset of 18 deg/s across gravity" in problem
    deg_s = np.degrees(turning - offset) + np.array([1.2, -1.5, 0.9])
    assert gyro_gravity_problem(t, acc, deg_s) is not None
    # one half-second of turning is not enough to clear the still stretches' verdict
    once = np.where((t >= 4.0) & (t < 4.5), 0.8, 0.0)
    one_turn = np.column_stack([once, 0 * t, 0 * t]) + offset + rng.normal(0.0, 0.003, acc.shape)
    assert gyro_gravity_problem(t, _turning_about_x(once, t, rng), one_turn) is not None
    # nor are turns the rates, read as rad/s, do not follow (a gyro whose x and y are
    # swapped: it says a turn about y where the accelerometer turns about x)
    swapped = turning[:, [1, 0, 2]]
    assert gyro_gravity_problem(t, acc, swapped) is not None


def test_the_gravity_check_of_gyro_units_judges_recordings_under_10_hz() -> None:
    """At 5 Hz and at 1 Hz, half a second holds too few readings for a stretch: the
    check judges stretches of five and a half steps, with the mismatch allowed in
    proportion. A resting gyro in deg/s (bias 0.4 deg/s, or 2) is found; one in rad/s,
    a cheap MEMS gyro's bias of 0.09 rad/s, is not."""
    rng = np.random.default_rng(3)
    for step in (0.2, 1.0):
        t = np.arange(0.0, 60.0, step)
        acc = np.array([0.1, -0.2, 9.8]) + rng.normal(0.0, 0.05, (len(t), 3))
        for bias_deg_s in ((0.3, -0.25, 0.1), (1.2, -1.5, 0.9)):
            deg_s = np.array(bias_deg_s) + rng.normal(0.0, 0.05, (len(t), 3))
            problem = gyro_gravity_problem(t, acc, deg_s)
            assert problem is not None, (step, bias_deg_s)
            assert f"every {5.5 * step:.3g} s" in problem
        cheap = np.array([0.06, -0.06, 0.02]) + rng.normal(0.0, 0.003, (len(t), 3))
        assert gyro_gravity_problem(t, acc, cheap) is None, step


def test_the_gravity_check_of_gyro_units_passes_the_shipped_recordings() -> None:
    """No shipped raw recording (rad/s: the rods bend, turn and twist fast, the tendon
    robot works under load, and each IMU also feels its own acceleration) is taken for
    deg/s by the gravity check: their gyros follow the accelerometers' turns."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data"
    files = sorted(data.glob("rod2/*_raw.csv")) + sorted(data.glob("tendon/*_raw.csv"))
    assert len(files) == 10
    for path in files:
        table = read_raw_imus(path, 2)
        for imu in table.imus:
            assert imu.gyr is not None
            assert gyro_gravity_problem(table.t, imu.acc, imu.gyr) is None, path


def test_the_motion_check_of_gyro_units_tells_the_shipped_recordings_in_deg_s() -> None:
    """The motion check (the gyro's turns against the accelerometer's in motion) takes
    no shipped recording (rad/s) for deg/s; with their gyros in deg/s it finds every IMU
    of every motion (the rods' raw and bend recordings, the tendon robot's), but the
    tendon robot's planar-s IMU 2, which turns too little across gravity, and says
    nothing of a rest (no turn)."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data"
    files = sorted(data.glob("rod2/*.csv")) + sorted(data.glob("tendon/*.csv"))
    files = [f for f in files if f.name.endswith(("_raw.csv", "_bend.csv", "_rest.csv"))]
    assert len(files) == 10 + 4 + 4
    found = []
    for path in files:
        table = read_raw_imus(path, 2)
        for k, imu in enumerate(table.imus, start=1):
            assert imu.gyr is not None
            assert gyro_motion_problem(table.t, imu.acc, imu.gyr) is None, path
            if gyro_motion_problem(table.t, imu.acc, np.degrees(imu.gyr)) is not None:
                found.append(f"{path.parent.name}/{path.name} {k}")
    moving = [
        f"{f.parent.name}/{f.name} {k}" for f in files if "_rest" not in f.name for k in (1, 2)
    ]
    assert found == [m for m in moving if m != "tendon/planar-s_raw.csv 2"]


def test_a_frozen_imu_is_not_taken_for_a_gyro_in_deg_s(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The shipped spatial-tendon recording (rad/s) with IMU 2 stuck from 3 to 5 s
    mid-motion, exactly or with 1e-7 of jitter: its stuck rates turn no accelerometer,
    which, judged, reads as a gyro in deg/s (exit 2, "read as rad/s it misses by 62
    deg"). A frozen stretch says nothing of the unit: the file is estimated, and the
    freeze said; a gyro in deg/s is still found beside the freeze."""
    for scale in (0.0, 1e-7):
        header, _, frozen = _tip_imu_stuck(scale)
        table = read_raw_imus(_write(tmp_path / "f.csv", _csv(header, frozen)), 2)
        assert all(gyro_gravity_problem(table.t, m.acc, m.gyr) is None for m in table.imus)
        imu = table.imus[1]  # the frozen one: its other stretches tell deg/s
        assert gyro_gravity_problem(table.t, imu.acc, np.degrees(imu.gyr)) is not None
    out = tmp_path / "est.csv"
    args = ["estimate", str(tmp_path / "f.csv"), "--robot", "two-section", "-o", str(out)]
    capsys.readouterr()
    assert main(args) == 0
    assert "IMU 2 repeated the same reading" in capsys.readouterr().err


def test_rows_after_a_silent_imu_reports_are_judged_as_with_it_throughout(
    tmp_path: Path,
) -> None:
    """The shipped spatial-tendon recording with IMU 2 stuck from 3 to 5 s, or silent
    (empty cells) until 3 s: while it is silent the other IMU's innovations scatter
    less than all of them do, and a level of the consistency check learned from them
    would flag nearly every row after it reports (6 of the 251 rows from 7 s on `ok`
    after the freeze, against 188 without it; 188 of 351 from 5 s on after the late
    start, against 260). The level learns only from samples with every IMU reporting,
    anew from an IMU's first reading: the rows are `ok` about as often as with the IMU
    reporting throughout."""
    header, rows, frozen = _tip_imu_stuck(0.0)
    late = rows.copy()
    late[np.ix_(rows[:, 0] < 3.0, [i for i, c in enumerate(header) if c.endswith("_2")])] = np.nan
    ok_after = {}
    for name, table in (("whole", rows), ("frozen", frozen), ("late", late)):
        out = tmp_path / f"{name}_est.csv"
        src = _write(tmp_path / f"{name}.csv", _csv(header, table))
        argv = ["estimate", str(src), "--robot", "two-section", "-o", str(out), "--skip-bad"]
        assert main(argv) == 0
        est = [ln.split(",") for ln in out.read_text().splitlines() if not ln.startswith("#")]
        t_col, status_col = est[0].index("t"), est[0].index("status")
        for since in (5.0, 7.0):
            after = [r[status_col] for r in est[1:] if float(r[t_col]) >= since]
            ok_after[name, since] = after.count("ok")
    assert ok_after["whole", 7.0] > 150
    assert ok_after["frozen", 7.0] >= 0.9 * ok_after["whole", 7.0], ok_after
    assert ok_after["late", 5.0] >= 0.9 * ok_after["whole", 5.0], ok_after


def _tip_imu_stuck(jitter: float) -> tuple[list[str], FloatArray, FloatArray]:
    """The shipped spatial-tendon raw recording: its header, its rows, and the rows with
    IMU 2's six values stuck at their t = 3 s reading until 5 s, plus ``jitter`` times
    standard normal noise."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"
    lines = (data / "spatial-tendon_raw.csv").read_text().splitlines()
    header = lines[0].split(",")
    rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    stuck = (rows[:, 0] >= 3.0) & (rows[:, 0] < 5.0)
    imu2 = [header.index(c + "_2") for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    noise = np.random.default_rng(0).standard_normal((int(stuck.sum()), 6))
    frozen = rows.copy()
    frozen[np.ix_(stuck, imu2)] = rows[np.flatnonzero(stuck)[0], imu2] + jitter * noise
    return header, rows, frozen


def _csv(header: list[str], rows: FloatArray) -> str:
    """A CSV text of ``rows`` under ``header``."""
    lines = (",".join("" if v != v else repr(v) for v in r) for r in rows.tolist())  # NaN: empty
    return "\n".join([",".join(header), *lines]) + "\n"


def test_estimate_names_a_gyro_in_deg_s(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The shipped planar-S recording with its gyros in deg/s, estimated with the
    gyros: one line naming IMU 1 and the likely unit, exit 2, nothing written (not
    estimates with many ``no-estimate`` and ``reset`` rows); with tilt from the
    accelerometer, a warning per IMU."""
    data = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2/planar-s_raw.csv"
    lines = data.read_text().splitlines()
    header = lines[0].split(",")
    gyro = [i for i, c in enumerate(header) if c[:2] in ("gx", "gy", "gz")]
    rows = [[float(v) for v in ln.split(",")] for ln in lines[1:]]
    for r in rows:
        for i in gyro:
            r[i] = math.degrees(r[i])
    text = "\n".join([lines[0], *(",".join(map(repr, r)) for r in rows)]) + "\n"
    degs = _write(tmp_path / "degs.csv", text)
    out = tmp_path / "est.csv"
    # the direct model (the default with gyro columns) uses the gyros: refused
    for method, model in (("mhe", ["--imu-model", "direct"]), ("ekf", [])):
        code = main(
            ["estimate", str(degs), "-o", str(out), "--robot", "two-section", *model,
             "--method", method]
        )  # fmt: skip
        err = capsys.readouterr().err
        assert code == 2
        assert err.count("\n") == 1
        assert f"{degs}: IMU 1: gyro magnitude is about 27.4 (median)" in err
        assert "deg/s? give rad/s" in err
        assert not out.exists()
    # tilt from the accelerometer does not use the gyro: a warning per IMU
    with pytest.warns(UnitWarning) as seen:
        code = main(
            ["estimate", str(degs), "-o", str(out), "--robot", "two-section", "--imu-model", "tilt"]
        )
    warned = [str(w.message) for w in seen if "deg/s?" in str(w.message)]
    assert code == 0 and out.exists()
    assert len(warned) == 2 and all(w.endswith("so the estimate is unaffected") for w in warned)


@pytest.mark.parametrize("imu_model", ["direct", "tilt"])
def test_whole_recording_conversion_equals_the_sample_by_sample_one(imu_model: str) -> None:
    """``convert_many`` (one pass over the arrays) gives what ``convert`` gives sample by
    sample, mounting rotation, gyro bias and unusable readings (NaN, zero) included."""
    rng = np.random.default_rng(3)
    n = 50
    t = np.arange(n) * 0.02
    acc = rng.normal(size=(n, 3)) * 5.0 + np.array([0.0, 0.0, 9.8])
    gyr = rng.normal(size=(n, 3))
    acc[7] = 0.0
    acc[11, 1] = np.nan
    gyr[13, 2] = np.inf
    settings = RawImuSettings(
        imu_model=imu_model, mount_rpy=(10.0, -20.0, 35.0), gyro_bias=(0.01, -0.02, 0.03)
    )
    one_by_one = RawImuConverter(settings)
    expected = np.array([one_by_one.convert(t[i], acc[i], gyr[i]) for i in range(n)])
    got = RawImuConverter(settings).convert_many(t, acc, gyr)
    assert got.shape == expected.shape == (n, 6 if imu_model == "direct" else 2)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expected))
    assert np.isnan(got[7]).all() and np.isnan(got[11]).all()
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-15)


def test_a_short_last_block_of_a_fast_turn_is_not_taken_for_deg_s(tmp_path: Path) -> None:
    """``estimate`` reads a file in blocks of 4,096 rows: a file at rest whose last 4
    rows turn at 6 rad/s (a short last block of more than 5 rad/s) is read whole, as the
    gyro's unit is judged on the first block or on blocks of 100 readings or more; the
    same turn over a whole block of its own is still refused."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import CHUNK, open_input

    def recording(turning: int) -> Path:
        n = CHUNK + turning
        rate = np.where(np.arange(n) >= CHUNK, 6.0, 0.01)
        rows = "".join(f"{0.001 * k!r},0,0,9.8,{float(rate[k])!r},0,0\n" for k in range(n))
        return _write(tmp_path / f"turn{turning}.csv", "t,ax,ay,az,gx,gy,gz\n" + rows)

    f = make_formulation("direct")
    with open_input(recording(4), InputOptions(), f) as stream:
        assert sum(len(t) for t, _ in stream.blocks) == CHUNK + 4
    with pytest.raises(InputError, match=r"turn4096.csv: gyro magnitude is about 6 "):
        with open_input(recording(CHUNK), InputOptions(), f) as stream:
            for _ in stream.blocks:
                pass


def test_raw_arrays_of_a_robot_give_what_its_file_gives() -> None:
    """``raw_measurements`` turns each IMU's readings by its robot's ``mount_rpy`` (and
    removes its ``gyro_bias``) as the file reader does: IMU 2 of the shipped planar-s
    recording turned 90 degrees about z, with a robot that says so, gives the estimates
    of the file as shipped; without the conversion (``direct_measurements`` alone) they
    are far off."""
    from continuum_mhe.io import load_input, raw_measurements, read_raw_imus, read_robot
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.model.robot import ImuPlacement, Robot

    path = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    shipped = read_robot("two-section")
    table = read_raw_imus(str(path / "planar-s_raw.csv"), 2)
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # Rz(90 deg)
    turned = Robot(
        shipped.sections, (shipped.imus[0], ImuPlacement(1, mount_rpy=(0, 0, 90))),
        shipped.mounting,
    )  # fmt: skip
    acc = np.stack([table.imus[0].acc, table.imus[1].acc @ turn], axis=1)
    gyr = np.stack([table.imus[0].gyr, table.imus[1].gyr @ turn], axis=1)
    z = raw_measurements(turned, table.t, acc, gyr)
    got = make_estimator("ekf", make_formulation("direct", turned)).run(table.t, z)
    data = load_input(
        str(path / "planar-s_raw.csv"), InputOptions(), make_formulation("bend", shipped)
    )
    want = make_estimator("ekf", data.formulation).run(data.t, data.z)
    np.testing.assert_allclose(got.output, want.output, atol=1e-12)
    np.testing.assert_array_equal(got.status, want.status)
    plain = np.hstack(
        [direct_measurements(acc[:, i], gyr[:, i]).reshape(len(z), 6) for i in range(2)]
    )
    off = make_estimator("ekf", make_formulation("direct", turned)).run(table.t, plain)
    assert np.abs(off.output[:, :3] - want.output[:, :3]).max() > 0.01
    from continuum_mhe.errors import UserError

    for t, a, needle in ((table.t[:-1], acc, "t must be"), (0.0, acc, "t must be"),
                         (table.t, acc[:, :1], "acc must be (n, 2, 3)")):  # fmt: skip
        with pytest.raises(UserError, match=re.escape(needle)):
            raw_measurements(turned, t, a, None)
    # a corrupt reading is refused, naming its sample and IMU; NaN is a dropout
    for value, shown in ((np.inf, "inf"), (-np.inf, "inf"), (1e300, "1e+300"), (2e4, "2e+04")):
        bad = acc.copy()
        bad[7, 1, 2] = value
        with pytest.raises(
            UserError,
            match=re.escape(
                "acc[7, 1] (sample 7, IMU 2): a reading beyond any IMU's range "
                f"(|acc| {shown} m/s^2"
            ),
        ):
            raw_measurements(turned, table.t, bad, gyr)
    bad = gyr.copy()
    bad[3, 0, 0] = np.inf
    with pytest.raises(UserError, match=re.escape("gyr[3, 0] (sample 3, IMU 1)")):
        raw_measurements(turned, table.t, acc, bad)
    dropped = acc.copy()
    dropped[7, 1] = np.nan
    z_dropped = raw_measurements(turned, table.t, dropped, gyr)
    assert np.isnan(z_dropped[7, 6:]).all() and np.isfinite(z_dropped[7, :6]).all()
    np.testing.assert_array_equal(np.delete(z_dropped, 7, 0), np.delete(z, 7, 0))


def test_an_imu_whose_gyro_columns_are_empty_in_every_row_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A two-IMU raw file whose IMU 2 has its gyro columns empty in every row (an IMU
    without a gyro, written into a template with gyro columns): one line naming those
    columns and what to give, exit 2, nothing written (not every row a dropout of IMU 2,
    its accelerometer thrown away, and 'IMU 2 never reported'). A gyro
    with a few empty cells is read, those rows dropouts of its IMU."""
    from continuum_mhe.cli import main

    shipped = (Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
               / "planar-s_raw.csv").read_text().splitlines()  # fmt: skip
    header = shipped[0].split(",")
    gyro2 = [header.index(c) for c in ("gx_2", "gy_2", "gz_2")]
    rows = [ln.split(",") for ln in shipped[1:41]]
    for r in rows:
        for c in gyro2:
            r[c] = ""
    meas = tmp_path / "no_gyro_2.csv"
    meas.write_text("\n".join([shipped[0], *(",".join(r) for r in rows)]) + "\n")
    out = tmp_path / "e.csv"
    assert main(["estimate", str(meas), "--robot", "two-section", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"continuum-mhe: error: {meas}: gx_2, gy_2, gz_2 are empty in every row while IMU 2's "
        "accelerometer reads: an IMU without a gyro?"
    )
    assert "leave every IMU's gyro columns out of the file" in err[0] and not out.exists()
    some = [ln.split(",") for ln in shipped[1:41]]
    for r in some[5:8]:
        for c in gyro2:
            r[c] = ""
    meas.write_text("\n".join([shipped[0], *(",".join(r) for r in some)]) + "\n")
    assert main(["estimate", str(meas), "--robot", "two-section", "-o", str(out)]) == 0


def test_the_gravity_check_of_gyro_units_finds_a_whole_turn_at_1_hz() -> None:
    """At 1 Hz a stretch is 5.5 s: a resting gyro in deg/s read as rad/s turns the
    gravity direction by about a whole turn in it (1.3 to 1.8 deg/s, 2.9 to 3.3 ...),
    which the angle between two directions (at most pi) would take as following it."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 60.0, 1.0)
    acc = np.array([0.1, -0.2, 9.8]) + rng.normal(0.0, 0.05, (len(t), 3))
    for bias in (1.4, 1.6, 3.1, 4.6):
        deg_s = np.array([bias, 0.0, 0.0]) + rng.normal(0.0, 0.05, (len(t), 3))
        assert gyro_gravity_problem(t, acc, deg_s) is not None, bias


def test_one_imu_of_several_in_g_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A two-IMU raw recording whose second accelerometer is in g: refused in one line
    naming that IMU (as a gyro in deg/s is), with the factor to m/s^2."""
    raw = tmp_path / "raw.csv"
    assert main(["simulate", "s-curve", "--robot", "two-section", "--imu", "raw",
                 "--duration", "1", "-o", str(raw)]) == 0  # fmt: skip
    lines = raw.read_text().splitlines()
    header = lines[0].split(",")
    in_g = {header.index(c) for c in ("ax_2", "ay_2", "az_2")}
    rows = [",".join(repr(float(v) / 9.80665) if i in in_g else v
                     for i, v in enumerate(ln.split(","))) for ln in lines[1:]]  # fmt: skip
    raw.write_text("\n".join([lines[0], *rows]) + "\n")
    capsys.readouterr()
    out = tmp_path / "e.csv"
    assert main(["estimate", str(raw), "--robot", "two-section", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{raw}: IMU 2: accelerometer magnitude is about 1.00" in err
    assert not out.exists()


def test_madgwick_without_calibrated_gyro_biases_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--attitude madgwick`` on IMUs without a calibrated ``gyro_bias`` is refused in
    one line (exit 2) naming the IMUs, calibration and mahony: the filter estimates no
    bias, and the shipped planar-s rod's IMU 1, whose bias across gravity exceeds the
    filter's correction rate, turns its tilt further every second while every row stays
    ``ok``. ``live`` and an options file (an estimate's options line) naming it are
    refused alike. With
    every IMU's bias calibrated it runs, and on the whole planar-s rod no ``ok`` row is
    more than 4 standard deviations off at the tip; mahony, which estimates the bias,
    runs uncalibrated."""
    from ahrs.filters import Madgwick

    from continuum_mhe.io.input_options import MADGWICK_CORRECTION_RATE

    assert MADGWICK_CORRECTION_RATE == pytest.approx(2 * Madgwick().gain_imu)
    rod = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (rod / "planar-s_raw.csv").read_text().splitlines()
    raw = _write(tmp_path / "raw.csv", "\n".join(lines[:61]) + "\n")
    calibrated = tmp_path / "cal.toml"
    imu = "[[imu]]\nsection = {}\ngyro_bias = [-0.0876, 0.0597, 0.0108]\n"
    calibrated.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\ntheta_max = 3.0\n'
        "[[section]]\nlength = 0.14\ntheta_max = 3.0\n" + imu.format(1) + imu.format(2)
    )
    one_bare = tmp_path / "one.toml"
    one_bare.write_text(calibrated.read_text().replace(imu.format(2), "[[imu]]\nsection = 2\n"))
    out = tmp_path / "est.csv"

    def estimate(source: Path, robot: str, *options: str) -> tuple[int, str]:
        argv = ["estimate", str(source), "--robot", robot, *options, "--method", "ekf",
                "-o", str(out), "--overwrite"]  # fmt: skip
        code = main(argv)
        return code, capsys.readouterr().err

    tilt = ("--imu-model", "tilt", "--attitude")
    code, err = estimate(raw, "two-section", *tilt, "madgwick")
    assert code == 2 and err.count("\n") == 1 and not out.exists(), err
    assert err.startswith(
        f"continuum-mhe: error: {raw}: --attitude madgwick needs a calibrated gyro_bias for "
        "IMU 1, 2 in the robot file: the Madgwick filter estimates no gyro bias"
    )
    assert "continuum-mhe calibrate" in err and "--attitude mahony" in err
    code, err = estimate(raw, str(one_bare), "--attitude", "madgwick")  # tilt by the attitude
    assert code == 2 and err.count("\n") == 1 and "for IMU 2 in the robot file" in err, err
    live = ["live", "--port", str(tmp_path / "none"), "--format", "raw", "--robot"]
    assert main([*live, "two-section", *tilt, "madgwick"]) == 2  # before the port opens
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "madgwick needs a calibrated gyro_bias for IMU 1, 2" in err
    assert estimate(raw, "two-section", *tilt, "mahony")[0] == 0
    assert estimate(raw, str(calibrated), *tilt, "madgwick")[0] == 0
    recorded = tmp_path / "recorded.csv"
    out.rename(recorded)  # its options line: attitude = "madgwick"
    code, err = estimate(raw, "two-section", "--config", str(recorded))
    assert code == 2 and err.count("\n") == 1, err
    assert "--attitude madgwick (from the options file) needs a calibrated gyro_bias" in err
    cal = tmp_path / "planar-s.toml"
    assert main(["calibrate", "--from", str(rod / "planar-s_rest.csv"), "--robot",
                 "two-section", "--write-robot", str(cal)]) == 0  # fmt: skip
    assert estimate(rod / "planar-s_raw.csv", str(cal), *tilt, "madgwick")[0] == 0
    truth = rod / "planar-s_truth.csv"
    assert main(["evaluate", str(out), str(truth), "--robot", str(cal), "--json"]) == 0
    ok = json.loads(capsys.readouterr().out)["calibration_ok"]
    assert ok["tip_far_of"] > 590 and ok["tip_far"] == 0, ok  # measured: 0 of 600


def test_a_raw_table_without_gyros_says_its_tilt_comes_from_the_accelerometers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A raw table whose gyro columns are not there is estimated from its
    accelerometers alone, as the docs say, and the run says so in a note; the same
    table with its gyros has no such note."""
    rod = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"
    lines = (rod / "planar-s_raw.csv").read_text().splitlines()[:120]
    header = lines[0].split(",")
    keep = [i for i, c in enumerate(header) if not c.startswith("g")]
    without = tmp_path / "accel.csv"
    without.write_text("\n".join(",".join(ln.split(",")[i] for i in keep) for ln in lines) + "\n")
    full = tmp_path / "full.csv"
    full.write_text("\n".join(lines) + "\n")
    for source, said in ((without, True), (full, False)):
        code = main(["estimate", str(source), "--robot", "two-section", "--method", "ekf",
                     "-o", str(tmp_path / f"{source.stem}.est.csv")])  # fmt: skip
        err = capsys.readouterr().err
        assert code == 0, err
        assert ("note: no gyro columns (gx_i, gy_i, gz_i): each IMU's tilt from its "
                "accelerometer alone" in err) is said, err  # fmt: skip
