"""The simulator's noise models against the estimators' own residual."""

from __future__ import annotations

import math

import numpy as np
import pytest

from continuum_mhe.errors import UserError
from continuum_mhe.model.imu import shape_from_tilt
from continuum_mhe.model.kinematics import bend_from_shape
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate, simulate_robot, tangent_plane_noise

SIGMA = math.radians(2.0)


def _residuals(z: np.ndarray, roll: float, pitch: float) -> np.ndarray:
    """The bend formulation's tangent-plane residuals of readings ``z`` at the shape
    whose noise-free reading is ``(roll, pitch)``."""
    f = make_formulation("bend")
    a, b = bend_from_shape(*shape_from_tilt(roll, pitch))
    x = np.array([float(a), float(b), 0.0, 0.0])
    return np.array([np.asarray(f.functions.innovate(zi, x)[0]).ravel() for zi in z])


@pytest.mark.parametrize("pitch_deg", [5.0, 80.0])
def test_tangent_noise_is_what_r_models_at_any_pitch(pitch_deg: float) -> None:
    roll, pitch = 0.3, math.radians(pitch_deg)
    clean = np.tile([roll, pitch], (4000, 1))
    z = tangent_plane_noise(clean, SIGMA, np.random.default_rng(1))
    r = _residuals(z, roll, pitch)
    # |r| = 2 tan(angle / 2) does not depend on the residual's frame: E|r|^2 = 2 sigma^2
    np.testing.assert_allclose(np.mean(np.sum(r**2, axis=1)), 2 * SIGMA**2, rtol=0.05)
    # per component (the roll/pitch frame curves near the pole: a bias of order
    # sigma^2 / cos(pitch) is the residual's own, 0.2 sigma at 80 deg)
    np.testing.assert_allclose(r.std(axis=0), SIGMA, rtol=0.05)
    assert np.abs(r.mean(axis=0)).max() < 0.3 * SIGMA
    assert abs(np.corrcoef(r.T)[0, 1]) < 0.06


def test_tilt_noise_understates_roll_residual_where_pitch_is_large() -> None:
    # the paper's noise: roll's residual shrinks by cos(pitch), so R over-states it
    roll, pitch = 0.3, math.radians(80.0)
    z = np.array([roll, pitch]) + np.random.default_rng(2).normal(size=(4000, 2)) * SIGMA
    r = _residuals(z, roll, pitch)
    np.testing.assert_allclose(r.std(axis=0), [SIGMA * math.cos(pitch), SIGMA], rtol=0.06)
    np.testing.assert_allclose(
        np.mean(np.sum(r**2, axis=1)), SIGMA**2 * (1 + math.cos(pitch) ** 2), rtol=0.06
    )


def test_tilt_is_the_default_and_tangent_differs() -> None:
    a = simulate("paper3d", duration=2.0, seed=4)
    b = simulate("paper3d", duration=2.0, seed=4, noise_model="tilt")
    c = simulate("paper3d", duration=2.0, seed=4, noise_model="tangent")
    np.testing.assert_array_equal(a.z, b.z)
    assert not np.allclose(a.z, c.z)
    np.testing.assert_array_equal(a.truth, c.truth)


def test_bad_noise_model_and_anisotropic_tangent_noise() -> None:
    with pytest.raises(UserError, match="noise model"):
        simulate("paper3d", duration=1.0, noise_model="gauss")  # type: ignore[arg-type]
    with pytest.raises(UserError, match="isotropic"):
        simulate("paper3d", duration=1.0, noise_model="tangent", noise_std=(0.01, 0.02))


def test_simulated_tilt_readings_stay_within_an_imus_pitch_range(tmp_path) -> None:
    """Tilt noise near the gimbal lock can push pitch past pi/2, which no IMU reports and
    the CSV reader refuses: the simulated readings are the same gravity direction with
    |pitch| <= pi/2, so ``estimate`` takes what ``simulate spatial`` of a three-section
    robot writes on seed 11, and the estimates do not depend on which of the two a
    reading is written as."""
    from continuum_mhe.cli import main
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.model.imu import canonical_tilt, wrap_angle
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section

    robot_file = tmp_path / "pcc3.toml"
    robot_file.write_text("".join("[[section]]\nlength = 0.12\n" for _ in range(3))
                          + "".join(f"[[imu]]\nsection = {k}\n" for k in (1, 2, 3)))  # fmt: skip
    meas = tmp_path / "m.csv"
    assert (
        main(["simulate", "spatial", "--robot", str(robot_file), "--seed", "11", "-o", str(meas)])
        == 0
    )
    assert (
        main(["estimate", str(meas), "--robot", str(robot_file), "-o", str(tmp_path / "e.csv")])
        == 0
    )
    robot = Robot(
        tuple(Section(0.12, 3.0) for _ in range(3)), tuple(ImuPlacement(k) for k in range(3))
    )
    rec = simulate_robot("spatial", robot, duration=20.0, seed=11)
    assert np.all(np.abs(rec.z[:, 1::2]) <= np.pi / 2)
    other = rec.z.copy()  # every steep reading written the other way
    steep = np.abs(other[:, 1::2]) > 1.2
    other[:, 1::2][steep] = np.copysign(np.pi, other[:, 1::2][steep]) - other[:, 1::2][steep]
    other[:, 0::2][steep] = wrap_angle(other[:, 0::2][steep] + np.pi)
    assert steep.sum() > 10
    np.testing.assert_allclose(canonical_tilt(other), rec.z, rtol=0, atol=1e-12)
    f = make_formulation("bend", robot)
    a, b = (make_estimator("ekf", f).run(rec.t, z).output for z in (rec.z, other))
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


def test_simulated_truth_phi_lies_in_the_outputs_range() -> None:
    """The truth's ``phi`` follows the outputs' convention, ``[-pi, pi)``, as every
    estimate's (paper3d's motion reaches phi = pi exactly)."""
    rec = simulate("paper3d", seed=0)
    phi = rec.truth[:, 4]
    assert np.all((phi >= -np.pi) & (phi < np.pi))
    assert np.isclose(np.abs(phi).max(), np.pi)  # the motion reaches it
