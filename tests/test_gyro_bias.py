"""Gyro-bias estimation in the raw-IMU (``direct``) formulation: the augmented state,
its Jacobians against finite differences, every estimator converging to a known
constant bias, and the fast MHE against IPOPT on the augmented state."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from estimator_helpers import assert_ok_after_the_start, fast_and_ipopt_states
from numpy.testing import assert_allclose

from continuum_mhe.errors import InputError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.kalman import CasadiExtendedKalmanFilter, UnscentedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import simulate_robot

#: the constant gyro biases of the recordings below, rad/s (about 1.1 to 2 deg/s)
BIAS_1 = np.array([0.03, -0.02, 0.025])
BIAS_2 = np.array([-0.035, 0.015, 0.02])


def _header(path) -> str:
    """The column line of an estimate CSV (after its ``#`` lines: the options)."""
    return next(ln for ln in path.read_text().splitlines() if not ln.startswith("#"))


def _recording(robot_name: str, duration: float, seed: int = 1) -> tuple[np.ndarray, ...]:
    """The ``spatial`` scenario measured by the robot's raw IMUs (noise-free model
    values plus noise 0.01), the gyros offset by ``BIAS_1``, ``BIAS_2``."""
    from continuum_mhe.model.descriptions import section_bends

    robot = read_robot(robot_name) if robot_name != "one" else None
    f = make_formulation("direct", robot, estimate_gyro_bias=False)  # the readings' model
    scenario = "spatial" if robot else "paper3d"
    rec = simulate_robot(scenario, f.robot, duration=duration, dt=0.05, seed=seed)  # type: ignore[arg-type]
    bends = np.array([section_bends(rec.outputs, row).ravel() for row in rec.truth])
    x = np.concatenate([bends, np.gradient(bends, rec.t, axis=0)], axis=1)
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(seed).normal(scale=0.01, size=z.shape)
    for b, bias in zip(f.measurement_blocks, (BIAS_1, BIAS_2)):
        z[:, b.start + 3 : b.start + 6] += bias
    return rec.t, z, x


def test_bias_state_layout_and_model() -> None:
    robot = read_robot("two-section")
    plain = DirectFormulation(robot=robot)
    f = DirectFormulation(robot=robot, estimate_gyro_bias=True)
    assert plain.nx == 8 and f.nx == 14 and f.n_bias == 6
    assert f.state_names[:8] == plain.state_names
    assert f.state_names[8:] == ("bgx_1", "bgy_1", "bgz_1", "bgx_2", "bgy_2", "bgz_2")
    assert DirectFormulation(estimate_gyro_bias=True).state_names[4:] == ("bgx", "bgy", "bgz")
    assert f.outputs == plain.outputs  # the bias is a state, not an output
    rng = np.random.default_rng(0)
    x = rng.normal(size=8) * 0.5
    bias = np.concatenate([BIAS_1, BIAS_2])
    h0 = np.asarray(plain.functions.observe(x)).ravel()
    h = np.asarray(f.functions.observe(np.concatenate([x, bias]))).ravel()
    expected = h0.copy()
    expected[3:6] += BIAS_1
    expected[9:12] += BIAS_2
    assert_allclose(h, expected, atol=1e-15)  # gyro = body rate + bias; f/|f| unchanged
    # the bias is constant in the transition and a random walk in Q
    xb = np.concatenate([x, bias])
    xn, _, q = (np.asarray(v) for v in f.functions.predict(xb, [], 0.05))
    assert_allclose(xn.ravel()[8:], bias, atol=0)
    assert_allclose(q[8:, 8:], np.eye(6) * f.gyro_bias_psd * 0.05, atol=1e-20)
    assert_allclose(q[:8, :8], np.asarray(plain.functions.predict(x, [], 0.05)[2]), atol=0)
    assert np.all(q[:8, 8:] == 0)
    p0 = f.initial_cov()
    assert_allclose(np.diag(p0)[8:], f.initial_gyro_bias_std**2)
    assert_allclose(p0[:8, :8], plain.initial_cov())
    x0 = f.initial_state(h)
    assert x0.shape == (14,) and np.all(x0[8:] == 0)
    assert_allclose(x0[:8], plain.initial_state(h), atol=1e-12)
    with pytest.raises(ValueError, match="gyro_bias_psd"):
        DirectFormulation(estimate_gyro_bias=True, gyro_bias_psd=0.0)


def test_a_calibrated_gyro_bias_gets_the_calibrated_prior() -> None:
    """An IMU whose robot file gives a gyro_bias (a calibration's, removed from its
    readings) starts its bias states at calibrated_gyro_bias_std; one without, at
    initial_gyro_bias_std; the bends' prior is unchanged."""
    robot = read_robot("two-section")
    first_calibrated = replace(
        robot, imus=(replace(robot.imus[0], gyro_bias=(0.01, -0.002, 0.0)), robot.imus[1])
    )
    plain = DirectFormulation(robot=robot, estimate_gyro_bias=True)
    f = DirectFormulation(robot=first_calibrated, estimate_gyro_bias=True)
    assert (f.calibrated_gyro_bias_std, f.initial_gyro_bias_std) == (0.01, 0.05)
    assert_allclose(np.diag(f.initial_cov())[8:], [1e-4] * 3 + [2.5e-3] * 3, rtol=1e-15)
    assert_allclose(np.diag(plain.initial_cov())[8:], [2.5e-3] * 6, rtol=1e-15)
    assert_allclose(f.initial_cov()[:8, :8], plain.initial_cov()[:8, :8], atol=0)
    assert DirectFormulation(robot=first_calibrated).gyro_bias_prior_std().shape == (0,)
    with pytest.raises(ValueError, match="calibrated_gyro_bias_std"):
        DirectFormulation(estimate_gyro_bias=True, calibrated_gyro_bias_std=0.0)


def test_a_calibrated_robot_file_narrows_the_bias_prior_and_the_error(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """The shipped stiff-torsion rod's robot calibrated from its rest recording (every
    IMU's gyro_bias written): on its raw recording the EKF with the calibrated prior
    (the default, 0.01 rad/s) is closer to the rod's tip than with the uncalibrated one
    (0.05 rad/s) on the same readings (13.2 against 19.4 mm)."""
    from cli_helpers import ROD2

    from continuum_mhe.cli import main
    from continuum_mhe.io.state_tables import read_state_table

    cal = tmp_path / "cal.toml"
    assert main(["calibrate", "--from", str(ROD2 / "spatial-stiff-torsion_rest.csv"),
                 "--robot", "two-section", "--write-robot", str(cal)]) == 0  # fmt: skip
    capsys.readouterr()
    robot = read_robot(str(cal))
    assert all(any(imu.gyro_bias) for imu in robot.imus)
    data = load_input(ROD2 / "spatial-stiff-torsion_raw.csv", InputOptions(),
                      make_formulation("bend", robot))  # fmt: skip
    f = data.formulation
    assert isinstance(f, DirectFormulation) and f.estimate_gyro_bias
    truth = read_state_table(ROD2 / "spatial-stiff-torsion_truth.csv")
    tip = np.column_stack([truth.column(c) for c in ("x", "y", "z")])
    assert_allclose(truth.t, data.t, atol=1e-9)
    mean_mm = {}
    for std in (f.calibrated_gyro_bias_std, f.initial_gyro_bias_std):
        series = make_estimator("ekf", replace(f, calibrated_gyro_bias_std=std)).run(data.t, data.z)
        cols = [[o.name for o in series.outputs].index(c) for c in ("x", "y", "z")]
        mean_mm[std] = 1e3 * np.nanmean(np.linalg.norm(series.output[:, cols] - tip, axis=1))
    assert mean_mm[0.01] < 14.0 < 18.0 < mean_mm[0.05], mean_mm


@pytest.mark.parametrize(
    "x",
    [
        np.zeros(8),  # both sections straight
        np.array([1e-9, 0.0, 0.0, 0.0, 0.3, -0.2, 0.1, 0.4]),
        np.array([0.9, -0.4, -1.2, 0.7, 0.5, 0.2, -0.6, 0.3]),
    ],
)
def test_innovation_jacobian_with_bias_matches_finite_differences(x: np.ndarray) -> None:
    f = DirectFormulation(robot=read_robot("two-section"), estimate_gyro_bias=True)
    xb = np.concatenate([x, np.concatenate([BIAS_1, BIAS_2])])
    z = np.asarray(f.functions.observe(xb + 0.05)).ravel()
    _, jac = f.functions.innovate(z, xb)
    fd = np.zeros((f.nz, f.nx))
    h = 1e-6
    for j in range(f.nx):
        e = np.zeros(f.nx)
        e[j] = h
        rp = np.asarray(f.functions.innovate(z, xb + e)[0]).ravel()
        rm = np.asarray(f.functions.innovate(z, xb - e)[0]).ravel()
        fd[:, j] = (rp - rm) / (2 * h)
    assert_allclose(np.asarray(jac), fd, atol=1e-7)
    assert_allclose(np.asarray(jac)[[3, 4, 5], 8:11], -np.eye(3), atol=0)  # dr/db = -I


def _estimators(f: DirectFormulation) -> dict[str, object]:
    no_c = FastOptions()  # the VM: no C build in the test (same answers)
    return {
        "ekf": CasadiExtendedKalmanFilter(f),
        "ukf": UnscentedKalmanFilter(f),
        "mhe-fast": MovingHorizonEstimator(f, MHESettings(horizon=20), no_c),
    }


def test_every_estimator_converges_to_a_constant_bias() -> None:
    """One section, tip IMU, 12 s of the paper3d scenario with the gyro offset by a
    constant ``BIAS_1`` (2 deg/s on its largest axis): every estimator's last bias
    estimate lies within 3 mrad/s (0.17 deg/s) of it, and its bend rates are better
    than without bias estimation: the same estimator without the bias state on the same
    samples has over twice the RMS bend-rate error (measured 0.0315 against 0.0116
    rad/s for every estimator). The MHE on IPOPT gives the fast MHE's states with the
    bias state to 1e-6 (:func:`test_fast_mhe_agrees_with_ipopt_with_the_bias_state`), so
    the MHE is run here on the fast solver alone."""
    t, z, x_true = _recording("one", 12.0)
    with_bias = _estimators(DirectFormulation(estimate_gyro_bias=True))
    # without the bias state: a gyro noise that covers the 2 deg/s bias (0.05 rad/s)
    without = _estimators(DirectFormulation(gyro_std=0.05))
    for name, est in with_bias.items():
        res = _run(est, t, z)
        assert_ok_after_the_start([r.status for r in res])
        b_last = res[-1].state[4:7]
        assert np.max(np.abs(b_last - BIAS_1)) < 3e-3, (name, b_last)
        plain = _run(without[name], t, z)
        assert_ok_after_the_start([r.status for r in plain])
        rate_rms = [
            np.sqrt(np.mean((np.array([r.state[2:4] for r in rs]) - x_true[:, 2:4]) ** 2))
            for rs in (res, plain)
        ]
        assert rate_rms[0] < 0.5 * rate_rms[1], (name, rate_rms)


def _run(est: object, t: np.ndarray, z: np.ndarray) -> list:  # type: ignore[type-arg]
    est.reset()  # type: ignore[attr-defined]
    return [est.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]  # type: ignore[attr-defined]


def test_fast_mhe_agrees_with_ipopt_with_the_bias_state() -> None:
    """Two sections, two raw IMUs with biases, 3 s, N = 8: the fast MHE (VM) and IPOPT give the
    same states (bends, rates and biases) to 1e-6 on every sample."""
    t, z, _ = _recording("two-section", 3.0, seed=2)
    f = DirectFormulation(robot=read_robot("two-section"), estimate_gyro_bias=True)
    states = fast_and_ipopt_states(f, t, z, horizon=8)
    assert_allclose(states["fast"], states["ipopt"], atol=1e-6, rtol=0)


def test_compiled_ekf_takes_the_bias_state() -> None:
    """``--method ekf`` (the compiled EKF) on the augmented state gives the CasADi EKF's
    answers (sizes from the formulation, nothing hard-coded)."""
    f = DirectFormulation(estimate_gyro_bias=True)
    t, z, _ = _recording("one", 1.0)
    compiled, plain = make_estimator("ekf", f), CasadiExtendedKalmanFilter(f)
    a = [compiled.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
    b = [plain.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
    assert a[-1].state is not None and a[-1].state.shape == (7,)
    assert math.isfinite(float(a[-1].output[0]))
    assert_allclose([r.state for r in a], [r.state for r in b], atol=1e-9)


def test_bias_flag_needs_the_direct_model(tmp_path) -> None:  # type: ignore[no-untyped-def]
    path = tmp_path / "tilt.csv"
    path.write_text("t,roll,pitch\n0,0.1,0.2\n0.05,0.1,0.2\n")
    opts = InputOptions(raw=RawImuSettings(imu_model="tilt"), estimate_gyro_bias=True)
    with pytest.raises(InputError, match="--estimate-gyro-bias needs --imu-model direct"):
        load_input(path, opts, make_formulation("bend"))
    raw = tmp_path / "raw.csv"
    raw.write_text("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.05,0,0,9.8,0,0,0\n")
    opts = InputOptions(raw=RawImuSettings(imu_model="direct"), estimate_gyro_bias=True)
    data = load_input(raw, opts, make_formulation("bend"))
    assert isinstance(data.formulation, DirectFormulation)
    assert data.formulation.estimate_gyro_bias and data.formulation.nx == 7


def test_estimate_cli_with_bias_keeps_the_columns(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """``estimate --imu-model direct --estimate-gyro-bias`` writes the columns of any
    estimate (the bias is a state, not an output); the flag on tilt input is one line,
    exit 2, nothing written."""
    from continuum_mhe.cli import main

    t, z, _ = _recording("one", 2.0)
    g = z[:, :3] * 9.81  # specific force from its direction (any unit)
    rows = ["t,ax,ay,az,gx,gy,gz"] + [
        ",".join(f"{v:.9g}" for v in (ti, *gi, *zi[3:6])) for ti, gi, zi in zip(t, g, z)
    ]
    raw = tmp_path / "raw.csv"
    raw.write_text("\n".join(rows) + "\n")
    out = tmp_path / "est.csv"
    args = ["estimate", str(raw), "-o", str(out), "--imu-model", "direct", "--method", "ukf"]
    assert main([*args, "--estimate-gyro-bias"]) == 0
    assert _header(out) == (
        "t,x,y,z,theta,phi,std_x,std_y,std_z,std_theta,std_phi,status,solve_ms"
    )  # the bias is a state, not an output: the columns are those of any estimate
    tilt = tmp_path / "tilt.csv"
    tilt.write_text("t,roll,pitch\n0,0.1,0.2\n0.05,0.1,0.2\n")
    out2 = tmp_path / "est2.csv"
    capsys.readouterr()
    assert main(["estimate", str(tilt), "-o", str(out2), "--estimate-gyro-bias"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--estimate-gyro-bias needs --imu-model direct" in err[0]
    assert not out2.exists()


def test_live_bias_flag_needs_the_direct_model(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    from continuum_mhe.cli import main

    out = tmp_path / "live.csv"
    args = ["live", "--port", str(tmp_path / "none"), "--format", "raw", "-o", str(out)]
    assert main([*args, "--imu-model", "tilt", "--estimate-gyro-bias"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "continuum-mhe: error: --estimate-gyro-bias needs --imu-model direct (raw gyros)"
    ]
    assert not out.exists()


@pytest.mark.parametrize("flag", [["--no-estimate-gyro-bias"], ["--gyro-std", "0.01"]])
def test_gyro_options_without_gyros_are_refused(tmp_path, capsys, flag) -> None:  # type: ignore[no-untyped-def]
    """``--no-estimate-gyro-bias`` and ``--gyro-std`` where no gyro is read (a tilt file,
    or raw input taken as tilt) would do nothing: one line, exit 2, nothing written; an
    options file's ``gyro-std`` (for every recording) is not refused."""
    from continuum_mhe.cli import main

    tilt = tmp_path / "tilt.csv"
    tilt.write_text("t,roll,pitch\n0,0.1,0.2\n0.05,0.1,0.2\n")
    raw = tmp_path / "raw.csv"
    raw.write_text("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.05,0,0,9.8,0,0,0\n")
    out = tmp_path / "est.csv"
    for argv in (
        ["estimate", str(tilt), "-o", str(out), *flag],
        ["estimate", str(raw), "-o", str(out), "--imu-model", "tilt", *flag],
    ):
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"continuum-mhe: error: {flag[0]} needs --imu-model direct (raw gyros)"]
        assert not out.exists()
    assert main(["estimate", str(raw), "-o", str(out), *flag]) == 0  # raw: the gyros read
    config = tmp_path / "c.toml"
    config.write_text("gyro-std = 0.01\nestimate-gyro-bias = false\n")
    assert (
        main(["estimate", str(tilt), "-o", str(out), "--overwrite", "--config", str(config)]) == 0
    )
