"""``continuum-mhe calibrate --from REST.csv --bend BEND.csv``: each IMU's yaw about the
tangent from a bend in a known plane. Known answers on recordings synthesized with the
project's own PCC model (rotations from ``pose_at``, angular rates by central
differences of them) and a known mounting; the bad inputs; and the rod generator's
bend recording keeps the recording's IMU errors."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
from live_helpers import alive

from continuum_mhe.calibration.at_rest import calibrate
from continuum_mhe.calibration.bend import yaws_from_bend
from continuum_mhe.cli import main
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.pcc import pose_at

G = 9.80665
LENGTHS = (0.16, 0.14)  # the shipped two-section robot
DT = 0.01
BIAS = np.array([[0.02, -0.01, 0.005], [-0.015, 0.03, -0.02]])  # rad/s
# large yaws, of both signs and past 90 deg, so that the rate axis's sign matters
MOUNTS = [(3.0, -2.0, 25.0), (-4.0, 6.0, -140.0)]


def _ramp(n: int, start: int, stop: int) -> np.ndarray:
    x = np.clip((np.arange(n) - start) / (stop - start), 0.0, 1.0)
    return 0.5 * (1 - np.cos(np.pi * x))


def _bend_readings(
    bends: np.ndarray, mounts: list[tuple[float, float, float]], up: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free ``(rest values, bend values)`` (n, 12) of the IMUs at both section
    ends, base z up (``up = 1``) or down (-1), for the bend sequence ``bends`` (n, 2, 2)
    rad; the rest's gyros with a real IMU's alternating noise (:func:`live_helpers.alive`)."""
    rest, bend = [], []
    for k, rpy in enumerate(mounts):
        m = mount_rotation(rpy)  # sensor to backbone frame
        R = pose_at(bends, LENGTHS, k)[0]  # (n, 3, 3) backbone to base
        acc = G * np.einsum("nji,j->ni", R, [0.0, 0.0, up]) @ m  # m^T (R^T u g)
        d = np.einsum("nji,njl->nil", R[1:-1], (R[2:] - R[:-2]) / (2 * DT))  # R^T dR/dt
        w = 0.5 * np.stack(
            [d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], 1
        )
        gyr = w @ m + BIAS[k]
        bend.append(np.hstack([acc[1:-1], gyr]))
        rest.append(np.tile(np.hstack([m.T @ [0.0, 0.0, up * G], BIAS[k]]), (len(w), 1)))
    return alive(np.hstack(rest)), np.hstack(bend)


def _planar_bend(phi: float, n: int = 300) -> np.ndarray:
    """Both sections bent towards ``phi`` (rad), ramped to 70 and 40 deg, then held."""
    theta = np.stack([np.radians(70) * _ramp(n, 20, 150), np.radians(40) * _ramp(n, 40, 170)], 1)
    return theta[..., None] * np.array([np.cos(phi), np.sin(phi)])


def _write(path: Path, values: np.ndarray) -> Path:
    n_imus = values.shape[1] // 6
    cols = ["t"] + [
        f"{c}_{k}" for k in range(1, n_imus + 1) for c in ("ax", "ay", "az", "gx", "gy", "gz")
    ]
    rows = np.column_stack([DT * np.arange(len(values)), values])
    path.write_text(
        ",".join(cols) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n"
    )
    return path


class _Said(NamedTuple):
    returncode: int
    stdout: str
    stderr: str


def _calibrate(capsys: pytest.CaptureFixture[str], *args: str) -> _Said:
    """``calibrate ARGS`` through the command line's ``main`` in this process (what
    ``python -m continuum_mhe.cli`` runs): its status and what it wrote on standard
    output and standard error."""
    capsys.readouterr()
    code = main(["calibrate", *args])
    out, err = capsys.readouterr()
    return _Said(code, out, err)


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> _Said:
    """``calibrate --robot two-section ARGS`` (:func:`_calibrate`)."""
    return _calibrate(capsys, "--robot", "two-section", *args)


def _rest_inputs(
    rest: np.ndarray, mounting: str = "z-up"
) -> list[tuple[tuple[float, float, float], np.ndarray, np.ndarray]]:
    t = DT * np.arange(len(rest))
    cal = calibrate(t, rest, "raw", 2, mounting)  # type: ignore[arg-type]
    return [(imu.mount_rpy, imu.mean[3:], np.full(3, 1e-3)) for imu in cal.imus]  # type: ignore[misc]


@pytest.mark.parametrize(
    ("phi_deg", "mounting"), [(0.0, "z-up"), (60.0, "z-up"), (-150.0, "z-up"), (60.0, "z-down")]
)
def test_yaw_round_trip_through_the_pcc_model(phi_deg: float, mounting: str) -> None:
    """A bend towards ``phi`` (the two sections in the same plane, so IMU 2 sees section
    1's bend too) read by IMUs with known mountings: roll and pitch from rest, yaw from
    the bend, together the mounting itself; the wrong plane shifts the yaw by the
    difference."""
    up = 1.0 if mounting == "z-up" else -1.0
    rest, bend = _bend_readings(_planar_bend(np.radians(phi_deg)), MOUNTS, up)
    inputs = _rest_inputs(rest, mounting)
    yaws = yaws_from_bend("bend.csv", bend, inputs, phi_deg, mounting)  # type: ignore[arg-type]
    for (rpy, _, _), y, true in zip(inputs, yaws, MOUNTS):
        np.testing.assert_allclose([rpy[0], rpy[1], y.yaw_deg], true, atol=1e-7)
        assert abs(y.gravity_yaw_deg - true[2]) < 1e-7  # noise- and bias-free: exact too
        assert y.off_axis < 1e-6
    shifted = yaws_from_bend("bend.csv", bend, inputs, phi_deg + 10.0, mounting)  # type: ignore[arg-type]
    for y, true in zip(shifted, MOUNTS):
        assert (y.yaw_deg - true[2] - 10.0 + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-7)


def test_calibrate_cli_prints_the_full_mounting_with_bend_phi(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rest, bend = _bend_readings(_planar_bend(np.radians(60.0)), MOUNTS)
    rest_csv, bend_csv = _write(tmp_path / "rest.csv", rest), _write(tmp_path / "bend.csv", bend)
    res = _cli(capsys, "--from", str(rest_csv), "--bend", str(bend_csv), "--bend-phi", "60")
    assert res.returncode == 0, res.stderr
    for i, (r, p, y) in enumerate(MOUNTS, start=1):
        assert f"IMU {i}: mounting: --mount-rpy {r:g},{p:g},{y:g} " in res.stdout
    # the default plane, phi = 0, is 60 deg off: the yaw follows
    res = _cli(capsys, "--from", str(rest_csv), "--bend", str(bend_csv))
    assert res.returncode == 0, res.stderr
    assert f"--mount-rpy {MOUNTS[0][0]:g},{MOUNTS[0][1]:g},{MOUNTS[0][2] - 60:g} " in res.stdout


def _bad(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    bend: np.ndarray,
    rest: np.ndarray | None = None,
) -> str:
    rest_csv = _write(
        tmp_path / "rest.csv",
        rest if rest is not None else _bend_readings(_planar_bend(0.0), MOUNTS)[0],
    )
    bend_csv = _write(tmp_path / "bend.csv", bend)
    res = _cli(capsys, "--from", str(rest_csv), "--bend", str(bend_csv))
    assert res.returncode == 2
    assert res.stdout == ""  # nothing printed before the error
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"continuum-mhe: error: {bend_csv}")
    return lines[0]


def test_too_little_bend_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    small = _planar_bend(0.0) * (6.0 / 70.0)  # section 1 to 6 deg, the tip to under 10
    line = _bad(capsys, tmp_path, _bend_readings(small, MOUNTS)[1])
    assert "IMU 1: tilts by only 6.0 deg" in line


def test_imu_count_mismatch_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bend = _bend_readings(_planar_bend(0.0), MOUNTS)[1]
    line = _bad(capsys, tmp_path, bend[:, :6])
    assert "raw columns for 1 IMU(s)" in line and "robot describes 2" in line


def test_a_bend_in_two_planes_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Section 1 towards phi = 0, then section 2 towards phi = 90 deg: the tip turns
    about two axes."""
    n = 300
    bends = np.zeros((n, 2, 2))
    bends[:, 0, 0] = np.radians(50) * _ramp(n, 20, 120)
    bends[:, 1, 1] = np.radians(60) * _ramp(n, 150, 250)
    line = _bad(capsys, tmp_path, _bend_readings(bends, MOUNTS)[1])
    assert "IMU 2: rates across the bending axis are" in line and "not a bend in one plane" in line


def test_bend_phi_without_bend_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rest_csv = _write(tmp_path / "rest.csv", _bend_readings(_planar_bend(0.0), MOUNTS)[0])
    res = _cli(capsys, "--from", str(rest_csv), "--bend-phi", "30")
    assert res.returncode == 2 and res.stdout == ""
    assert res.stderr.strip() == "continuum-mhe: error: --bend-phi needs --bend BEND.csv"


def test_a_bend_held_still_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Recorded after the bend: tilted, but the gyro never turned."""
    bend = _bend_readings(_planar_bend(0.0), MOUNTS)[1][-60:]
    line = _bad(capsys, tmp_path, bend)
    assert "IMU 1: the gyro saw too little rate about the bending axis" in line


def test_bend_recording_keeps_the_recordings_imu_errors() -> None:
    """``imu_samples(errors_like=n)`` on a trajectory of another length draws the same
    misalignments and biases as a recording of ``n`` samples (noise-free IMUs, so the
    samples are those errors alone)."""
    from continuum_mhe.simulation.cosserat import ImuSettings
    from continuum_mhe.simulation.cosserat_sections import SectionTrajectory, at_rest, imu_samples

    imu = ImuSettings(sample_dt=0.02, accel_noise=0.0, gyro_noise=0.0)

    def still(n: int) -> SectionTrajectory:
        eye = np.broadcast_to(np.eye(3), (n, 2, 3, 3)).copy()
        z = np.zeros((n, 2, 3))
        return at_rest(
            SectionTrajectory(
                1e-3 * np.arange(n), np.zeros((n, 3, 31)), eye, z, z, np.zeros(n), (16, 30)
            )
        )

    _, f_long, w_long, _ = imu_samples(still(12001), imu, seed=0, noise_seed=5)
    assert len(f_long) == 601
    _, f_short, w_short, _ = imu_samples(still(5001), imu, seed=0, noise_seed=7, errors_like=601)
    np.testing.assert_array_equal(f_short, f_long[: len(f_short)])
    np.testing.assert_array_equal(w_short, w_long[: len(w_short)])
    _, f_other, _, _ = imu_samples(still(5001), imu, seed=0, noise_seed=7)
    assert not np.array_equal(f_other[:, 1], f_long[: len(f_other), 1])  # IMU 2's errors moved


def test_shipped_bend_recordings_give_the_drawn_yaws() -> None:
    """On the rod recordings (PyElastica, not the PCC model), the yaw comes back within
    0.05 deg (3 standard errors) of the board misalignment about z that the generator
    drew (``imu_samples``: per IMU, misalignment, accelerometer bias, its noise, gyro
    bias, its noise, from seed 0, 601 samples; ``_rotation_xyz`` is Z-Y-X as
    ``mount_rpy``)."""
    from continuum_mhe.calibration.at_rest import bend_yaws
    from continuum_mhe.io.inputs import read_recording
    from continuum_mhe.io.robot_file import read_robot

    rng = np.random.default_rng(0)
    drawn = []
    for _ in range(2):
        drawn.append(float(rng.normal(size=3)[2]))  # 1 deg sigma: in degrees
        rng.normal(size=3), rng.normal(size=(601, 3)), rng.normal(size=3), rng.normal(size=(601, 3))
    robot = read_robot("two-section")
    data = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
    names = sorted(p.name[: -len("_info.json")] for p in data.glob("*_info.json"))
    assert len(names) == 4
    for name in names:
        _, t, values = read_recording(str(data / f"{name}_rest.csv"), 2)
        cal = calibrate(t, values, "raw", 2, "z-up")
        yaws = bend_yaws(str(data / f"{name}_bend.csv"), 0.0, cal, robot)
        for y, true in zip(yaws, drawn):
            assert abs(y.yaw_deg - true) < 0.05, (name, y.yaw_deg, true)
            assert y.yaw_std_deg < 0.02


def test_imus_tilting_out_of_order_in_the_bend_are_said() -> None:
    """In a bend of every section the same way an IMU further out tilts at least as far:
    with the second and third IMUs' columns swapped (both recordings), the third tilts
    67 degrees against the second's 100, and their yaws (the second's 90 degrees) would
    go to each other's robot-file entry: said in a warning. IMUs listed out of order in
    the robot file are judged by their places along the backbone."""
    from continuum_mhe.calibration.bend import YawCalibration, tilt_order_warning

    def tilts(*deg: float) -> list[YawCalibration]:
        return [YawCalibration(0.0, 0.0, d, 0.1, 0.01) for d in deg]

    ends = [(0, 1.0), (1, 1.0), (2, 1.0)]
    reach = [3.0, 3.0, 3.0]
    said = tilt_order_warning(ends, tilts(33.0, 100.0, 67.0), reach)
    assert said.startswith("IMU 3 tilts up to 67 deg in the bend, less than IMU 2 nearer")
    assert "IMU columns in the robot file's order?" in said
    assert tilt_order_warning(ends, tilts(33.0, 67.0, 100.0), reach) == ""
    assert tilt_order_warning(ends, tilts(33.0, 70.0, 67.0), reach) == ""  # within the margin
    listed = [(2, 1.0), (0, 1.0), (1, 0.5)]  # the tip's IMU first in the file
    assert tilt_order_warning(listed, tilts(100.0, 33.0, 50.0), reach) == ""
    said = tilt_order_warning(listed, tilts(40.0, 33.0, 50.0), reach)
    assert "IMU 1 tilts up to 40 deg" in said
    # a tilt reads at most 180 degrees: an outer IMU bent to 210 reads 150, which the
    # section between it and one at 150 can bend it to: not said
    assert tilt_order_warning(ends, tilts(60.0, 150.0, 150.0 - 10), reach) == ""


def _robot_with_yaws(path: Path, yaws: tuple[float, float]) -> Path:
    """The shipped two-section robot with each IMU's yaw given (roll and pitch 0)."""
    path.write_text(
        'mounting = "z-up"\n[[section]]\nlength = 0.16\n[[section]]\nlength = 0.14\n'
        f"[[imu]]\nsection = 1\nmount_rpy = [0, 0, {yaws[0]}]\n"
        f"[[imu]]\nsection = 2\nmount_rpy = [0, 0, {yaws[1]}]\n"
    )
    return path


@pytest.mark.parametrize(("bent_deg", "turn", "towards"), [(180.0, 180, 180), (90.0, -90, 90)])
def test_a_bend_in_another_plane_than_bend_phi_is_said(
    tmp_path: Path, bent_deg: float, turn: int, towards: int, capsys: pytest.CaptureFixture[str]
) -> None:
    """A robot bent the other way (towards +x) or in the other plane (towards +y) while
    --bend-phi says -x: the readings are those of a bend towards -x by boards turned
    half or a quarter turn about the backbone, so every yaw comes out that far from the
    robot file's (25 and -140 degrees, the boards' true yaws). Written as measured, with
    a warning that names the turn and the plane that reads so; the bend towards the
    plane given is not said, nor boards whose yaws the file does not give."""
    rest, bend = _bend_readings(_planar_bend(np.radians(bent_deg)), MOUNTS)
    rest_csv, bend_csv = _write(tmp_path / "rest.csv", rest), _write(tmp_path / "bend.csv", bend)
    robot = _robot_with_yaws(tmp_path / "robot.toml", (MOUNTS[0][2], MOUNTS[1][2]))
    out = tmp_path / "cal.toml"
    res = _calibrate(capsys, "--from", str(rest_csv), "--bend", str(bend_csv),
                     "--robot", str(robot), "--write-robot", str(out))  # fmt: skip
    assert res.returncode == 0, res.stderr
    warned = [ln for ln in res.stderr.splitlines() if f"warning: {bend_csv}" in ln]
    assert len(warned) == 1, res.stderr  # (the rest's boards lean: said of rest.csv)
    assert warned[0].startswith(
        f"continuum-mhe: warning: {bend_csv}: every IMU's yaw from the bend is the robot "
        f"file's turned by {turn} degrees (IMU 1: {MOUNTS[0][2] - bent_deg:.1f} against 25; "
    )
    assert (
        f"a bend towards phi = {towards} instead of --bend-phi's 0 (towards base -x) reads so"
        in warned[0]
    )
    assert out.exists()  # the yaws as measured: the warning says what is doubtful
    res = _cli(capsys, "--from", str(rest_csv), "--bend", str(bend_csv), "--bend-phi",
               str(bent_deg))  # fmt: skip
    assert res.returncode == 0 and f"warning: {bend_csv}" not in res.stderr, res.stderr
    res = _calibrate(capsys, "--from", str(rest_csv), "--bend", str(bend_csv),
                     "--robot", str(robot), "--bend-phi", str(bent_deg))  # fmt: skip
    assert res.returncode == 0 and f"warning: {bend_csv}" not in res.stderr, res.stderr


def test_the_bend_plane_warning_wants_every_imu_turned_alike() -> None:
    """Said where every IMU's yaw is over 45 degrees from the robot's, all within 15
    degrees of the same turn; not where one board alone is turned (its file's yaw is
    wrong, the bend is right), nor for the turns boards mounted by hand differ by."""
    from continuum_mhe.calibration.bend import YawCalibration, bend_plane_warning

    def yaws(*deg: float) -> list[YawCalibration]:
        return [YawCalibration(d, d, 60.0, 0.01, 0.01) for d in deg]

    said = bend_plane_warning(yaws(-179.0, 179.0, 180.0), [0.0, 0.0, 0.0], 0.0, True)
    assert "turned by 180 degrees" in said and "phi = 180 instead of" in said
    said = bend_plane_warning(yaws(100.0, 80.0), [10.0, -5.0], 30.0, False)
    assert said.startswith("every IMU's yaw from the bend is the robot's (0: no robot file")
    assert "turned by 88 degrees" in said and "phi = -58 instead of --bend-phi's 30 reads" in said
    assert bend_plane_warning(yaws(-91.0), [0.0], 0.0, True).startswith("the IMU's yaw from")
    assert bend_plane_warning(yaws(179.0, 2.0), [0.0, 0.0], 0.0, True) == ""  # one board
    assert bend_plane_warning(yaws(70.0, 100.0), [0.0, 0.0], 0.0, True) == ""  # 30 apart
    assert bend_plane_warning(yaws(44.0, 44.0), [0.0, 0.0], 0.0, True) == ""
    assert "turned by 135 degrees" in bend_plane_warning(
        yaws(-134.0, -136.0), [90.0, 90.0], 0.0, True
    )


def test_the_printed_yaw_standard_error_is_the_yaws_scatter() -> None:
    """Over 400 draws of a gyro's white noise (0.02 rad/s) on one 60-degree bend in a
    plane, at a yaw of 25 degrees, the yaw's printed standard error equals the scatter
    of the yaws it gives, within the Monte Carlo's own spread (its standard deviation
    is known to about 1/sqrt(2 * 400), 3.5 %)."""
    from continuum_mhe.calibration.bend import yaw_from_bend

    g, dt, n, sigma = 9.80665, 0.01, 300, 0.02
    s = np.clip((np.arange(n) - 20) / 130, 0.0, 1.0)
    bend = np.radians(60.0) * 0.5 * (1.0 - np.cos(np.pi * s))
    rate = np.gradient(bend, dt)
    normal = np.array([0.0, -1.0, 0.0])  # the plane phi = 0's normal
    gravity = np.stack([np.sin(bend), np.zeros(n), np.cos(bend)], axis=1)
    mount = mount_rotation((0.0, 0.0, 25.0))
    rng = np.random.default_rng(0)
    yaws, stds = [], []
    for _ in range(400):
        gyr = (rate[:, None] * normal) @ mount + sigma * rng.standard_normal((n, 3))
        c = yaw_from_bend(g * gravity @ mount, gyr, (0.0, 0.0, 0.0), np.zeros(3),
                          np.full(3, sigma), 0.0)  # fmt: skip
        yaws.append(c.yaw_deg)
        stds.append(c.yaw_std_deg)
    assert np.mean(yaws) == pytest.approx(25.0, abs=3 * np.std(yaws) / np.sqrt(400))
    assert np.mean(stds) == pytest.approx(np.std(yaws), rel=0.12)
