"""The IMU's own acceleration in the raw-IMU (``direct``) model (``own_acceleration``):
the specific force against finite differences of the composed positions in time, the
constant-acceleration motion model, the state layout with the bias states, the fast
MHE against IPOPT on the larger state, and the option refused without raw gyros."""

from __future__ import annotations

import numpy as np
import pytest
from estimator_helpers import fast_and_ipopt_states
from numpy.testing import assert_allclose

from continuum_mhe.errors import InputError
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.pcc import pose_at, up_vector
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section

#: a two-section robot with an IMU inside section 2 and one at the tip
ROBOT = Robot(
    (Section(0.16, 3.0), Section(0.14, 3.0)),
    (ImuPlacement(1, 0.5), ImuPlacement(1, 1.0)),
    "z-up",
)


def _header(path) -> str:
    """The column line of an estimate CSV (after its ``#`` lines: the options)."""
    return next(ln for ln in path.read_text().splitlines() if not ln.startswith("#"))


def _bends(t: np.ndarray) -> np.ndarray:
    """A smooth two-section motion (n, 4) rad with all four coordinates moving."""
    return np.stack(
        [
            0.9 * np.sin(1.3 * t),
            0.5 * np.cos(0.7 * t) - 0.2,
            -1.1 * np.sin(0.9 * t + 0.4),
            0.6 * np.sin(1.7 * t),
        ],
        axis=1,
    )


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_specific_force_matches_finite_differences_of_the_positions(mounting: str) -> None:
    """``f/|f|`` of the model with the bends, rates and bend accelerations of a known
    motion equals ``R^T (d^2p/dt^2 + g u)`` normalised, with ``d^2p/dt^2`` by central
    differences in time of the numeric positions (independent of the model's chain
    rule), to 1e-6; without ``own_acceleration`` it differs by over 1e-3."""
    from dataclasses import replace

    robot = replace(ROBOT, mounting=mounting)
    f = DirectFormulation(robot=robot, own_acceleration=True)
    plain = DirectFormulation(robot=robot)
    h, t0 = 1e-4, np.array([0.3, 1.1, 2.6])
    up = up_vector(mounting)  # type: ignore[arg-type]
    for tc in t0:
        ts = tc + h * np.array([-1.0, 0.0, 1.0])
        q = _bends(ts)
        qd = (q[2] - q[0]) / (2 * h)
        qdd = (q[2] - 2 * q[1] + q[0]) / h**2
        x = np.concatenate([q[1], qd, qdd])
        z = np.asarray(f.functions.observe(x)).ravel()
        z0 = np.asarray(plain.functions.observe(x[:8])).ravel()
        for i, (blk, imu) in enumerate(zip(f.measurement_blocks, robot.imus)):
            R, p = pose_at(q.reshape(3, 2, 2), robot.lengths, imu.section, imu.at)
            acc = (p[2] - 2 * p[1] + p[0]) / h**2
            spec = R[1].T @ (acc + STANDARD_GRAVITY * up)
            assert_allclose(z[blk.start : blk.start + 3], spec / np.linalg.norm(spec), atol=1e-6)
            gap = z0[blk.start : blk.start + 3] - z[blk.start : blk.start + 3]
            assert np.max(np.abs(gap)) > 1e-3, i
            assert_allclose(z[blk.start + 3 : blk.start + 6], z0[blk.start + 3 : blk.start + 6])


def test_constant_acceleration_motion_and_layout() -> None:
    f = DirectFormulation(
        robot=read_robot("two-section"),
        own_acceleration=True,
        estimate_gyro_bias=True,
        estimate_accel_bias=True,
    )
    assert f.nx == 12 + 6 + 6 and f.n_motion == 12
    assert f.state_names[8:12] == ("a_1_ddot", "b_1_ddot", "a_2_ddot", "b_2_ddot")
    assert f.state_names[12] == "bgx_1" and f.state_names[18] == "bax_1"
    rng = np.random.default_rng(1)
    x = rng.normal(size=f.nx) * 0.3
    dt = 0.05
    xn, _, q = (np.asarray(v) for v in f.functions.predict(x, [], dt))
    xn = xn.ravel()
    assert_allclose(xn[:4], x[:4] + dt * x[4:8] + dt**2 / 2 * x[8:12], atol=1e-15)
    assert_allclose(xn[4:8], x[4:8] + dt * x[8:12], atol=1e-15)
    assert_allclose(xn[8:], x[8:], atol=0)
    j = f.bend_jerk_psd
    assert_allclose(q[0, 0], j * dt**5 / 20)
    assert_allclose(q[0, 8], j * dt**3 / 6)
    assert_allclose(q[8, 8], j * dt)
    assert_allclose(q[0, 1], 0.0)
    assert_allclose(q[18:, 18:], np.eye(6) * f.accel_bias_psd * dt, atol=1e-20)
    assert np.all(np.linalg.eigvalsh(q[:12, :12]) > 0)
    p0 = np.diag(f.initial_cov())
    assert_allclose(p0[8:12], f.initial_bend_accel_std**2)
    x0 = f.initial_state(np.asarray(f.functions.observe(np.zeros(f.nx))).ravel())
    assert x0.shape == (24,) and np.all(x0 == 0)
    with pytest.raises(ValueError, match="bend_jerk_psd"):
        DirectFormulation(own_acceleration=True, bend_jerk_psd=0.0)


def _assert_fast_agrees_with_ipopt(f: DirectFormulation, bends) -> None:
    """The fast MHE and IPOPT (N = 4) on the model's own readings of ``bends(t)`` (n, 2
    sections) over 1 s at 20 Hz, noise 0.005 and gyro biases zero: the same states to
    1e-6 on every sample."""
    t = np.arange(20) * 0.05
    q = bends(t)
    qd = np.gradient(q, t, axis=0)
    biases = np.zeros((len(t), 3 * f.robot.n_imus))
    x = np.concatenate([q, qd, np.gradient(qd, t, axis=0), biases], axis=1)
    z = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    z += np.random.default_rng(3).normal(scale=0.005, size=z.shape)
    states = fast_and_ipopt_states(f, t, z, horizon=4)
    assert_allclose(states["fast"], states["ipopt"], atol=1e-6, rtol=0)


def test_fast_mhe_agrees_with_ipopt_with_own_acceleration() -> None:
    """Two sections (an IMU inside section 2), the model's own readings of the motion
    above plus noise 0.005, 1 s (N = 4: the window slides for 16 samples): fast MHE
    (VM) and IPOPT give the same states to 1e-6 on every sample."""
    f = DirectFormulation(robot=ROBOT, own_acceleration=True, estimate_gyro_bias=True)
    _assert_fast_agrees_with_ipopt(f, _bends)


def test_own_acceleration_needs_the_direct_model(tmp_path, capsys) -> None:
    """Refused with the tilt model (chosen: raw gyros otherwise take the direct model);
    taken by the default model of raw input with gyros, and by the direct model."""
    from continuum_mhe.cli import main

    raw = tmp_path / "raw.csv"
    raw.write_text("t,ax,ay,az,gx,gy,gz\n0,0,0,9.8,0,0,0\n0.05,0,0,9.8,0,0,0\n")
    opts = InputOptions(raw=RawImuSettings(imu_model="tilt"), own_acceleration=True)
    with pytest.raises(InputError, match="--own-acceleration needs --imu-model direct"):
        load_input(raw, opts, make_formulation("bend"))
    out = tmp_path / "est.csv"
    capsys.readouterr()
    tilt = ["estimate", str(raw), "-o", str(out), "--imu-model", "tilt"]
    assert main([*tilt, "--own-acceleration"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["continuum-mhe: error: --own-acceleration needs --imu-model direct (raw gyros)"]
    assert not out.exists()
    default = load_input(
        raw, InputOptions(own_acceleration=True), make_formulation("bend")
    ).formulation
    assert isinstance(default, DirectFormulation) and default.own_acceleration
    args = ["estimate", str(raw), "-o", str(out), "--method", "ukf", "--own-acceleration"]
    assert main(args) == 0
    assert _header(out).startswith("t,x,y,z,theta,phi,")
    assert main([*args, "--imu-model", "direct", "--overwrite"]) == 0
    assert _header(out).startswith("t,x,y,z,theta,phi,")


def test_large_bend_accelerations_are_not_divergence() -> None:
    """A vibrating rod's bend accelerations reach hundreds of rad/s^2: not a diverged
    state; a rate over the limit or a non-finite acceleration still is."""
    f = DirectFormulation(own_acceleration=True)
    x = np.array([0.3, 0.1, 1.0, -0.5, 400.0, -300.0])
    assert not f.is_diverged(x)
    assert f.is_diverged(np.array([0.3, 0.1, 80.0, -0.5, 0.0, 0.0]))
    assert f.is_diverged(np.array([0.3, 0.1, 1.0, -0.5, np.nan, 0.0]))
    assert DirectFormulation().is_diverged(np.array([0.3, 0.1, 80.0, 0.0]))


def test_three_sections_agree_with_ipopt_with_own_acceleration() -> None:
    """Three sections with the IMUs' own acceleration (a residual of 13,378
    instructions, its second derivatives formed as for any model): the fast MHE agrees
    with IPOPT to 1e-6 on every sample of the motion above (N = 4, 16 slides)."""
    three = Robot(
        (Section(0.12, 3.0), Section(0.1, 3.0), Section(0.08, 3.0)),
        tuple(ImuPlacement(k) for k in range(3)),
        "z-up",
    )
    f = DirectFormulation(robot=three, own_acceleration=True, estimate_gyro_bias=True)
    # the third section's bend too: half of the first's
    _assert_fast_agrees_with_ipopt(f, lambda t: np.hstack([_bends(t), _bends(t)[:, :2] * 0.5]))


def test_gauss_newton_answers_lie_near_the_converged_ones() -> None:
    """Gauss-Newton steps (``FastOptions(newton=False)``) on three sections with the
    IMUs' own acceleration: their rate is linear and drifts from one iteration to the
    next. Certified by the bound and the step size as a Newton step is (as if the
    steps were exact), answers would lie up to 11 times ``err_tol`` from the answer
    iterated to 1e-13 (10 of the 81 windows of a 4 s recording); with the core's safety
    factor on both they lie within twice ``err_tol`` (the worst 1.49 times: a rate that
    jumps between iterations). The steps are Gauss-Newton: the model
    forms the second-order term (Newton steps by default), and Newton steps from the
    same windows' starts take fewer iterations on more than half of the windows."""
    import tempfile
    from pathlib import Path

    from estimator_helpers import fast_windows, worst_certified_error

    import continuum_mhe.estimators.fast as fm
    import continuum_mhe.estimators.fast.model as fmodel
    from continuum_mhe.estimators.fast.sqp import newton_steps
    from continuum_mhe.estimators.mhe import MovingHorizonEstimator
    from continuum_mhe.io.estimate_csv import write_measurements
    from continuum_mhe.settings import MHESettings
    from continuum_mhe.simulation.raw_readings import raw_readings
    from continuum_mhe.simulation.scenarios import simulate_robot

    three = Robot(
        tuple(Section(0.1, 3.0) for _ in range(3)), tuple(ImuPlacement(k) for k in range(3))
    )
    rec = simulate_robot("spatial", three, duration=4.0, seed=0)
    values, names = raw_readings(rec, three, seed=0)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "raw.csv"
        write_measurements(path, rec.t, values, names)
        opts = InputOptions(
            raw=RawImuSettings(imu_model="direct"), estimate_gyro_bias=True, own_acceleration=True
        )
        data = load_input(path, opts, make_formulation("bend", three))
    f = data.formulation
    model = fmodel.build_window_model(f, 30)
    steps = fm.FastOptions(newton=False)
    est = MovingHorizonEstimator(f, MHESettings(horizon=30), steps)
    windows = fast_windows(est, data.t, data.z)
    worst = worst_certified_error(model, windows, steps)
    assert len(windows) > 75
    assert worst <= 2 * fm.FastOptions().err_tol, worst
    assert newton_steps(model, fm.FastOptions()) and not newton_steps(model, steps)
    gauss = np.array([res.iterations for *_, res in windows])
    newton = np.array(
        [fm.solve_window(model, p, X0, lam0=lam0).iterations for p, X0, lam0, _ in windows]
    )
    assert np.sum(gauss > newton) > len(windows) // 2, (gauss.sum(), newton.sum())


@pytest.mark.parametrize("rates", [0.0, 1.0])
def test_own_acceleration_leaves_the_constant_errors_shift_of_the_bends(rates: float) -> None:
    """The readings' constant errors (a misalignment, the model error) shift the bends
    as much with ``own_acceleration`` as without it: a constant error of a gravity
    direction is no lasting acceleration (the bends would follow it) and the gyros hold
    the rates, so the bend accelerations and rates are held to their priors in the
    sensitivity. Peer: the formulation without own acceleration, on a three-section
    robot with an IMU at the middle of section 1 and at each section's end, at rest and
    moving (rates up to 0.6 rad/s, accelerations up to 2 rad/s^2); left free, the
    motion states would take up the errors so that the bends' standard deviation came
    out 3 to 5 times the peer's."""
    from continuum_mhe.estimators.consistency import ConsistencyCheck

    robot = Robot(
        tuple(Section(length, 2.5) for length in (0.12, 0.10, 0.08)),
        (ImuPlacement(0, 0.5), ImuPlacement(0), ImuPlacement(1), ImuPlacement(2)),
    )
    n2 = 2 * robot.n_sections
    bends = np.array([0.5, 0.3, -0.4, 0.6, 0.2, -0.5])
    stds = []
    for own in (False, True):
        f = DirectFormulation(robot, own_acceleration=own)
        x = np.zeros(f.nx)
        x[:n2] = bends
        x[n2 : 2 * n2] = rates * np.array([0.5, -0.3, 0.4, 0.2, -0.6, 0.1])
        if own:
            x[2 * n2 : 3 * n2] = rates * np.array([1.0, 2.0, -1.0, 0.5, -2.0, 1.0])
        z = np.asarray(f.functions.measure(x)[0]).ravel()
        cov = np.asarray(ConsistencyCheck(f).constant_error_cov(z, f.measurement_mask(z), x))
        stds.append(np.sqrt(np.diag(cov.reshape(f.nx, f.nx))[:n2]))
    assert_allclose(stds[1], stds[0], rtol=0.05)


def test_own_acceleration_ok_rows_of_the_shipped_rods_lie_within_their_intervals(
    tmp_path, capsys, monkeypatch
) -> None:
    """``--own-acceleration`` on the shipped spatial-tendon rod, calibrated (the README's
    five steps): the EKF's ``ok`` rows lie within 4 standard deviations on every tip
    axis (with the motion states free to take up the readings' constant errors, 164 of
    368 would not, 27 std), and the estimates are those of the same run with the motion
    states left free there: the hold changes the standard deviations, not a prior."""
    from cli_helpers import ROD2, calibrated_spatial_tendon

    from continuum_mhe.cli import main
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.model.bend import BendFormulation
    from continuum_mhe.model.direct import DirectFormulation

    cal, est, report = calibrated_spatial_tendon(tmp_path, capsys, "--own-acceleration")
    free = tmp_path / "free.csv"
    with monkeypatch.context() as m:  # the constant-error term's range: the bends' alone
        m.setattr(DirectFormulation, "range_std", BendFormulation.range_std)
        assert main(["estimate", str(ROD2 / "spatial-tendon_raw.csv"), "--robot", str(cal),
                     "--method", "ekf", "--own-acceleration", "-o", str(free)]) == 0  # fmt: skip
    held, left = read_state_table(est), read_state_table(free)
    np.testing.assert_allclose(held.values, left.values, rtol=0, atol=1e-12)
    assert held.std is not None and left.std is not None
    assert not np.allclose(held.std, left.std)
    ok = report["calibration_ok"]
    assert ok["tip_far_of"] > 300
    assert ok["tip_far"] <= 2, (ok["tip_far"], ok["tip_far_worst"])
