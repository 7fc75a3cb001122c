"""Accelerometer-bias estimation in the raw-IMU (``direct``) formulation: the model
against its definition and finite differences, a known constant bias recovered by
every estimator when the IMU turns through several orientations, not when it is held
in one pose, the fast MHE against IPOPT with the new states, bad options, and the rod
generator's rest recording (the same IMU errors, fresh noise)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import assert_ok_after_the_start, bare, fast_and_ipopt_states
from numpy.testing import assert_allclose

from continuum_mhe.errors import InputError
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, UnscentedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate_robot

#: constant accelerometer biases, m/s^2 (1 to 2 % of g), and gyro biases, rad/s
ACC_1 = np.array([0.15, -0.10, 0.12])
ACC_2 = np.array([-0.12, 0.08, -0.15])
GYR_1 = np.array([0.03, -0.02, 0.025])
GYR_2 = np.array([-0.035, 0.015, 0.02])


def _header(path) -> str:
    """The column line of an estimate CSV (after its ``#`` lines: the options)."""
    return next(ln for ln in path.read_text().splitlines() if not ln.startswith("#"))


def _recording(robot_name: str, duration: float, seed: int = 1) -> tuple[np.ndarray, ...]:
    """The robot's raw IMUs on a moving scenario (``paper3d`` for one section,
    ``spatial`` otherwise): the model's values with the biases above (both kinds) plus
    noise 0.003, as ``(t, z, x)`` (``x`` the true states with the biases)."""
    from continuum_mhe.model.descriptions import section_bends

    robot = read_robot(robot_name) if robot_name != "one" else None
    f = DirectFormulation(robot=robot, estimate_gyro_bias=True, estimate_accel_bias=True)
    scenario = "spatial" if robot else "paper3d"
    rec = simulate_robot(scenario, f.robot, duration=duration, dt=0.05, seed=seed)  # type: ignore[arg-type]
    bends = np.array([section_bends(rec.outputs, row).ravel() for row in rec.truth])
    n = f.robot.n_imus
    biases = np.concatenate([*(GYR_1, GYR_2)[:n], *(ACC_1, ACC_2)[:n]])
    x = np.concatenate(
        [bends, np.gradient(bends, rec.t, axis=0), np.tile(biases, (len(rec.t), 1))], axis=1
    )
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(seed).normal(scale=0.003, size=z.shape)
    return rec.t, z, x


def test_accel_bias_state_layout_and_model() -> None:
    """States after the gyro biases; ``f/|f| = (g R^T u + c)/|g R^T u + c|``; a
    random walk in Q; the prior; the innovation Jacobian against finite differences."""
    robot = read_robot("two-section")
    f = DirectFormulation(robot=robot, estimate_gyro_bias=True, estimate_accel_bias=True)
    plain = DirectFormulation(robot=robot, estimate_gyro_bias=True)
    assert f.nx == 20 and f.n_gyro_bias == 6 and f.n_accel_bias == 6
    assert f.state_names[:14] == plain.state_names
    assert f.state_names[14:] == ("bax_1", "bay_1", "baz_1", "bax_2", "bay_2", "baz_2")
    only = DirectFormulation(estimate_accel_bias=True)
    assert only.state_names[4:] == ("bax", "bay", "baz") and only.n_bias == 3
    assert f.outputs == plain.outputs
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.normal(size=8) * 0.6, GYR_1, GYR_2])
    h0 = np.asarray(plain.functions.observe(x)).ravel()
    h = np.asarray(f.functions.observe(np.concatenate([x, ACC_1, ACC_2]))).ravel()
    for blk, c in zip(f.measurement_blocks, (ACC_1, ACC_2)):
        s = blk.start
        spec = STANDARD_GRAVITY * h0[s : s + 3] + c
        assert_allclose(h[s : s + 3], spec / np.linalg.norm(spec), atol=1e-14)
        assert_allclose(h[s + 3 : s + 6], h0[s + 3 : s + 6], atol=0)  # gyros unchanged
    xb = np.concatenate([x, ACC_1, ACC_2])
    xn, _, q = (np.asarray(v) for v in f.functions.predict(xb, [], 0.05))
    assert_allclose(xn.ravel()[14:], np.concatenate([ACC_1, ACC_2]), atol=0)
    assert_allclose(q[14:, 14:], np.eye(6) * f.accel_bias_psd * 0.05, atol=1e-20)
    assert np.all(q[:14, 14:] == 0)
    assert_allclose(np.diag(f.initial_cov())[14:], f.initial_accel_bias_std**2)
    z = h + 0.01
    _, jac = f.functions.innovate(z, xb)
    fd = np.zeros((f.nz, f.nx))
    for j in range(f.nx):
        e = np.zeros(f.nx)
        e[j] = 1e-6
        rp = np.asarray(f.functions.innovate(z, xb + e)[0]).ravel()
        rm = np.asarray(f.functions.innovate(z, xb - e)[0]).ravel()
        fd[:, j] = (rp - rm) / 2e-6
    assert_allclose(np.asarray(jac), fd, atol=1e-7)
    with pytest.raises(ValueError, match="accel_bias_psd"):
        DirectFormulation(estimate_accel_bias=True, accel_bias_psd=-1.0)
    with pytest.raises(ValueError, match="initial_accel_bias_std"):
        DirectFormulation(estimate_accel_bias=True, initial_accel_bias_std=0.0)


def test_every_estimator_recovers_a_constant_accel_bias_with_motion() -> None:
    """One section, tip IMU, 20 s of the paper3d scenario (the tip turns through many
    orientations), accelerometer offset by ``ACC_1`` (up to 0.15 m/s^2) and gyro by
    ``GYR_1``: every estimator's last accelerometer-bias estimate is within
    0.03 m/s^2 of it on every axis, a fifth of the largest component (from a prior of
    zero). The MHE runs on the fast solver: the MHE on IPOPT gives its states with these
    states to 1e-6 (:func:`test_fast_mhe_agrees_with_ipopt_with_the_accel_bias_states`)."""
    t, z, _ = _recording("one", 20.0)
    f = DirectFormulation(
        accel_direction_std=0.01, gyro_std=0.01, estimate_gyro_bias=True, estimate_accel_bias=True
    )  # noise settings near the recording's 0.003 (the default 2 deg tilt noise: slower)
    no_c = FastOptions()
    estimators = {
        "ekf": CasadiExtendedKalmanFilter(f),
        "ukf": UnscentedKalmanFilter(f),
        "mhe-fast": MovingHorizonEstimator(f, MHESettings(horizon=10), no_c),
    }
    for name, est in estimators.items():
        res = [est.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
        assert_ok_after_the_start([r.status for r in res])
        last = res[-1].state[7:10]  # type: ignore[index]
        assert np.max(np.abs(last - ACC_1)) < 0.03, (name, last)


def test_one_pose_leaves_the_bias_along_gravity_unknown() -> None:
    """The robot held straight and still for 10 s: the EKF learns nothing about the
    bias along gravity (its variance stays at the prior's plus the random walk), the
    observability statement of the module docstring."""
    f = DirectFormulation(estimate_gyro_bias=True, estimate_accel_bias=True)
    z = np.asarray(f.functions.observe(np.zeros(f.nx)), dtype=float).ravel()
    ekf = CasadiExtendedKalmanFilter(f, recovery=bare())  # the exact repeats are no freeze here
    for i in range(200):
        ekf.step(Measurement(i * 0.05, z))
    P = ekf.inference._P
    assert P is not None
    # exactly the prior plus 199 random-walk steps of 0.05 s, correlated with nothing
    expected = f.initial_accel_bias_std**2 + f.accel_bias_psd * 199 * 0.05
    assert P[9, 9] == pytest.approx(expected, rel=1e-12)
    assert np.all(P[9, :9] == 0.0) and np.all(P[:9, 9] == 0.0)


def test_fast_mhe_agrees_with_ipopt_with_the_accel_bias_states() -> None:
    """Two sections, two raw IMUs with both biases, 2 s, N = 8: the fast MHE (VM) and IPOPT
    give the same states (bends, rates, gyro and accelerometer biases) to 1e-6."""
    t, z, _ = _recording("two-section", 2.0, seed=2)
    f = DirectFormulation(
        robot=read_robot("two-section"), estimate_gyro_bias=True, estimate_accel_bias=True
    )
    states = fast_and_ipopt_states(f, t, z, horizon=8)
    assert states["fast"].shape[1] == 20
    assert_allclose(states["fast"], states["ipopt"], atol=1e-6, rtol=0)


def test_accel_bias_flag_needs_the_direct_model(tmp_path, capsys) -> None:
    from continuum_mhe.cli import main

    raw = tmp_path / "raw.csv"
    raw.write_text("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.05,0,0,9.8,0,0,0\n")
    opts = InputOptions(raw=RawImuSettings(imu_model="tilt"), estimate_accel_bias=True)
    with pytest.raises(InputError, match="--estimate-accel-bias needs --imu-model direct"):
        load_input(raw, opts, make_formulation("bend"))
    opts = InputOptions(raw=RawImuSettings(imu_model="direct"), estimate_accel_bias=True)
    data = load_input(raw, opts, make_formulation("bend"))
    assert isinstance(data.formulation, DirectFormulation)
    # the gyro biases are estimated by default with raw gyros, then the accelerometer's
    assert data.formulation.nx == 10 and data.formulation.state_names[-3:] == ("bax", "bay", "baz")
    out = tmp_path / "est.csv"
    capsys.readouterr()
    tilt = ["--imu-model", "tilt"]  # raw gyros take the direct model unless told
    assert main(["estimate", str(raw), "-o", str(out), *tilt, "--estimate-accel-bias"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "continuum-mhe: error: --estimate-accel-bias needs --imu-model direct (raw gyros)"
    ]
    assert not out.exists()
    args = ["estimate", str(raw), "-o", str(out), "--imu-model", "direct", "--method", "ekf"]
    assert main([*args, "--estimate-accel-bias"]) == 0
    assert _header(out).startswith("t,x,y,z,theta,phi,")


def test_rest_recording_has_the_recordings_imu_errors() -> None:
    """``imu_samples`` with ``noise_seed``: the same misalignments and biases as the
    recording (noise-free IMUs give identical readings), fresh noise otherwise; the
    rest trajectory is the first state held still."""
    from dataclasses import replace

    from continuum_mhe.simulation.cosserat_sections import (
        DEFAULT_IMU,
        SectionTrajectory,
        at_rest,
        imu_samples,
    )

    n = 101
    rng = np.random.default_rng(0)
    directors = np.tile(np.eye(3), (n, 2, 1, 1))
    directors[50:] = np.eye(3)[[1, 2, 0]]  # the rod turned, then held
    traj = SectionTrajectory(
        np.arange(n) * 1e-3, rng.normal(size=(n, 3, 31)), directors,
        rng.normal(size=(n, 2, 3)), rng.normal(size=(n, 2, 3)), np.zeros(n), (16, 30),
    )  # fmt: skip
    rest = at_rest(traj)
    assert np.all(rest.directors == np.eye(3)) and np.all(rest.velocities == 0)
    quiet = replace(DEFAULT_IMU, sample_dt=0.002, accel_noise=0.0, gyro_noise=0.0)
    a = imu_samples(rest, quiet, seed=4)
    b = imu_samples(rest, quiet, seed=4, noise_seed=9)
    assert_allclose(a[1], b[1], atol=0)
    assert_allclose(a[2], b[2], atol=0)
    c = imu_samples(rest, quiet, seed=5)
    assert np.max(np.abs(a[1] - c[1])) > 1e-3  # another seed: other errors
    noisy = replace(DEFAULT_IMU, sample_dt=0.002)
    d, e = imu_samples(rest, noisy, seed=4), imu_samples(rest, noisy, seed=4, noise_seed=9)
    assert np.max(np.abs(d[1] - e[1])) > 1e-3  # fresh noise
    assert_allclose(d[1].mean(axis=0), a[1].mean(axis=0), atol=0.02)  # same errors


@pytest.mark.parametrize("name", ["planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial"])
def test_shipped_rest_recordings_carry_the_recordings_imu_errors(name: str) -> None:
    """Each shipped ``NAME_rest.csv`` reads what the recording's first sample (the rod
    straight and still, before the couples act) read, up to noise: its mean lies within
    0.06 m/s^2 (three noise sigmas) of that sample on the accelerometers' x and y axes,
    where the two IMUs' own errors differ by up to 0.25 m/s^2."""
    from continuum_mhe.io.raw_imu import read_raw_imus

    folder = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
    rest = read_raw_imus(folder / f"{name}_rest.csv", 2).imus
    rec = read_raw_imus(folder / f"{name}_raw.csv", 2).imus
    for r, m in zip(rest, rec):
        assert_allclose(r.acc.mean(axis=0)[:2], m.acc[0, :2], atol=0.06)
    assert abs(rest[0].acc[:, 0].mean() - rest[1].acc[:, 0].mean()) > 0.1  # errors differ


def test_estimated_accel_biases_do_not_take_up_the_readings_constant_errors(
    tmp_path, capsys
) -> None:
    """With ``--estimate-accel-bias`` the readings' constant errors (a misalignment, the
    model error) still shift the bends: a bias state explains one sample's constant
    error of a direction exactly, but only within its prior (0.1 m/s^2, about 0.6
    degrees), so it is held there (``range_std``) and the rest is carried in the
    standard deviations. On the shipped spatial-tendon rod (the README's five steps,
    calibrated) the EKF's ``ok`` rows then lie within 4 standard deviations on every tip
    axis; with the biases free to take the errors up, 349 of 424 of them would not (31
    std)."""
    from cli_helpers import calibrated_spatial_tendon

    cal, _, report = calibrated_spatial_tendon(tmp_path, capsys, "--estimate-accel-bias")
    ok = report["calibration_ok"]
    assert ok["tip_far_of"] > 300  # most of the 601 rows still ok
    assert ok["tip_far"] <= 2, (ok["tip_far"], ok["tip_far_worst"])
    f = DirectFormulation(read_robot(cal), estimate_accel_bias=True)
    rows = slice(f.n_motion + f.n_gyro_bias, f.n_motion + f.n_bias)
    assert_allclose(f.range_std()[rows], f.initial_accel_bias_std)
