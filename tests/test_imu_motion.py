"""The IMUs' own acceleration as a model error of tilt readings
(``continuum_mhe.model.imu_motion``, ``ConsistencyCheck`` in
``continuum_mhe.estimators.consistency``): the functions against finite differences and
known rotations, and the ``ok`` rows of a rod leaving its pose."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from continuum_mhe.estimators import make_estimator
from continuum_mhe.io import InputOptions, load_input, read_robot
from continuum_mhe.model.imu_motion import (
    own_acceleration_functions,
    takes_acceleration_as_gravity,
)
from continuum_mhe.model.pcc import pose_at_sym
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.cosserat import default_data_path

G = 9.80665


def _positions(f, x: np.ndarray) -> np.ndarray:
    robot = f.robot
    S = list(f.sigma_states)
    bends = [(x[S[2 * k]], x[S[2 * k + 1]]) for k in range(robot.n_sections)]
    return np.concatenate(
        [
            np.asarray(pose_at_sym(bends, robot.lengths, i.section, i.at)[1], dtype=float).ravel()
            for i in robot.imus
        ]
    )


@pytest.mark.parametrize("name", ["bend", "direct"])
def test_the_imus_velocity_is_the_derivative_of_their_position(name) -> None:
    f = make_formulation(name, read_robot("two-section"))
    velocity, _ = own_acceleration_functions(f)
    rng = np.random.default_rng(3)
    names = f.state_names
    for _ in range(5):
        x = np.zeros(f.nx)
        S = list(f.sigma_states)
        x[S] = rng.uniform(-1.5, 1.5, len(S))
        rates = [names.index(f"{names[s]}_dot") for s in S]
        x[rates] = rng.uniform(-2.0, 2.0, len(S))
        h = 1e-6
        step = np.zeros(f.nx)
        step[S] = h * x[rates]
        fd = (_positions(f, x + step) - _positions(f, x - step)) / (2 * h)
        v = np.asarray(velocity(x), dtype=float).ravel()
        assert np.allclose(v, fd, atol=1e-7), (v, fd)


def test_an_acceleration_across_gravity_tilts_the_reading_by_its_angle() -> None:
    # a straight, standing one-section robot: the IMU's frame is the base's; an
    # acceleration of a across gravity turns the specific force by atan(a / g); the
    # residual, on the tangent plane of the reading, is 2 tan(angle / 2) long
    f = make_formulation("bend")
    _, error = own_acceleration_functions(f)
    x = np.zeros(f.nx)
    for a in (0.05, 0.13, 0.5):
        for direction in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.6, 0.8, 0.0)):
            acc = a * G * np.array(direction)
            e = np.asarray(error(x, acc), dtype=float).ravel()
            angle = math.atan(a)
            assert np.linalg.norm(e) == pytest.approx(2 * math.tan(angle / 2), rel=1e-9)
    # along gravity (up or down) the direction does not turn
    e = np.asarray(error(x, np.array([0.0, 0.0, 3.0])), dtype=float).ravel()
    assert np.allclose(e, 0.0, atol=1e-15)


@pytest.mark.parametrize("mounting", ["z-up", "z-down"])
def test_the_error_is_the_formulations_residual_of_the_accelerated_reading(mounting) -> None:
    # bent poses, an IMU in the middle of its section: the reading of an IMU that
    # accelerates is the direction of R^T (up + a / g); the formulation's own residual of
    # that reading (the other IMUs reading what the model predicts) is the error
    robot = read_robot("two-section")
    robot = replace(
        robot,
        mounting=mounting,
        imus=(replace(robot.imus[0], at=0.6), *robot.imus[1:]),
    )
    f = make_formulation("bend", robot)
    _, error = own_acceleration_functions(f)
    rng = np.random.default_rng(7)
    up = np.array([0.0, 0.0, 1.0 if mounting == "z-up" else -1.0])
    S = list(f.sigma_states)
    for _ in range(6):
        x = np.zeros(f.nx)
        x[S] = rng.uniform(-1.2, 1.2, len(S))
        acc = rng.normal(0.0, 0.15 * G, 3 * robot.n_imus)
        e = np.asarray(error(x, acc), dtype=float).ravel()
        bends = [(x[S[2 * k]], x[S[2 * k + 1]]) for k in range(robot.n_sections)]
        z = []
        for i, imu in enumerate(robot.imus):
            R = np.asarray(pose_at_sym(bends, robot.lengths, imu.section, imu.at)[0], dtype=float)
            g = R.T @ (up + acc[3 * i : 3 * i + 3] / G)
            g /= np.linalg.norm(g)
            z += [math.atan2(g[1], g[2]), math.atan2(-g[0], math.hypot(g[1], g[2]))]
        r, _ = f.functions.innovate(np.array(z), x)
        assert np.allclose(e, np.asarray(r, dtype=float).ravel(), atol=1e-12)


def test_a_raw_imus_acceleration_turns_its_unit_specific_force_and_no_gyro_row() -> None:
    f = make_formulation("direct", read_robot("two-section"))
    _, error = own_acceleration_functions(f)
    x = np.zeros(f.nx)
    acc = np.zeros(6)
    acc[3] = 0.1 * G  # IMU 2 accelerates along the base's x
    e = np.asarray(error(x, acc), dtype=float).ravel()
    expected = np.array([0.1, 0.0, 1.0]) / math.hypot(0.1, 1.0) - np.array([0.0, 0.0, 1.0])
    assert np.allclose(e[6:9], expected, atol=1e-12)  # straight: the IMU's frame is the base's
    assert np.allclose(e[:6], 0.0) and np.allclose(e[9:], 0.0)


def test_models_that_have_the_acceleration_or_a_twist_are_left_out() -> None:
    robot = read_robot("two-section")
    assert takes_acceleration_as_gravity(make_formulation("bend", robot))
    assert takes_acceleration_as_gravity(make_formulation("direct", robot))
    direct = make_formulation("direct", robot)
    for f in (replace(direct, own_acceleration=True), replace(direct, imu_twist=True)):
        assert not takes_acceleration_as_gravity(f)
    with pytest.raises(ValueError, match=r"^the paper formulation has no such readings$"):
        own_acceleration_functions(make_formulation("paper"))


@pytest.mark.parametrize("method", ["mhe", "ekf", "ukf"])
def test_no_ok_row_of_a_rod_leaving_its_pose_lies_far_outside_its_std(method) -> None:
    # the shipped tendon-drive rod with tilt IMUs: where the robot leaves a pose its tip
    # IMU accelerates at up to 0.13 g across gravity, a reading error of 7 degrees that
    # the two IMUs' four angles fit exactly; carried in the standard deviations, no ok
    # row lies more than 4 of them off (without it 11 do, in each estimator), and most
    # rows stay ok
    folder = default_data_path().parent / "rod2"
    f = make_formulation("bend", read_robot("two-section"))
    data = load_input(str(folder / "spatial-tendon_tilt.csv"), InputOptions(), f)
    truth = np.loadtxt(
        folder / "spatial-tendon_truth.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3)
    )
    series = make_estimator(method, data.formulation).run(data.t, data.z)
    ok = series.status == "ok"
    assert ok.mean() > 0.85
    z = np.abs(series.output[ok, :3] - truth[ok]) / series.std[ok, :3]
    assert z.max() < 4.0, (int((z.max(axis=1) > 4).sum()), float(z.max()))


def test_the_check_carries_the_acceleration_until_it_forgets_the_motion() -> None:
    from continuum_mhe.estimators.consistency import ConsistencyCheck

    f = make_formulation("bend", read_robot("two-section"))
    check = ConsistencyCheck(f).core
    names = f.state_names
    x0 = np.zeros(f.nx)
    x0[list(f.sigma_states)] = [0.8, 0.2, -0.5, 0.4]
    x1 = x0.copy()
    rates = [names.index(f"{names[s]}_dot") for s in f.sigma_states]
    x1[rates] = [1.5, -1.0, 2.0, 0.5]  # from still to moving within 0.08 s
    z = np.asarray(f.functions.observe(x1), dtype=float).ravel()
    mask = np.ones(f.nz)
    still = np.asarray(check.constant_error_cov(z, mask, x1)).reshape(f.nx, f.nx)
    check.note_motion(0.0, x0)
    check.note_motion(0.08, x1)
    moving = np.asarray(check.constant_error_cov(z, mask, x1)).reshape(f.nx, f.nx)
    assert np.trace(moving) > 2.0 * np.trace(still)
    assert np.all(np.linalg.eigvalsh(moving - still) > -1e-12)  # only ever wider
    t = 0.08
    for forget in (check.forget, check.forget_motion):  # a restart, an unconfirmed row
        forget()  # the motion starts again: no acceleration from one sample
        t += 0.1
        check.note_motion(t, x0)
        again = np.asarray(check.constant_error_cov(z, mask, x1)).reshape(f.nx, f.nx)
        assert np.allclose(again, still, rtol=1e-12, atol=0.0)
        t += 0.08
        check.note_motion(t, x1)  # and the motion again from there
        moving_again = np.asarray(check.constant_error_cov(z, mask, x1)).reshape(f.nx, f.nx)
        assert np.allclose(moving_again, moving, rtol=1e-9, atol=0.0)
