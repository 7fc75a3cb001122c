"""Raw IMU readings (accelerometer and gyro) of a simulated constant-curvature motion.

Each IMU's pose along the truth's bends (:func:`~continuum_mhe.model.pcc.pose_at`, the
robot's sections and placements), its acceleration by central differences of its
position, its angular velocity by central differences of its orientation; the specific
force ``R^T (a + g u)`` (``u`` the world's up direction) in m/s^2 and the angular
velocity in rad/s, both in the sensor frame of the placement's ``mount_rpy``, the
placement's ``gyro_bias`` added, then white noise and a constant gyro bias of each IMU
drawn once. What ``continuum-mhe simulate --imu raw`` writes: the readings a raw-IMU
robot of the robot file would send, to try the raw path (``--imu-model direct``, the
default for raw input) or ``live`` on a pseudo-terminal without hardware.
The motion is the estimators' own model (constant curvature, no twist); the Cosserat-rod
recordings (:mod:`continuum_mhe.simulation.cosserat_sections`) are the data it did not
generate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, expect_type, is_integer
from continuum_mhe.io.raw_imu import raw_columns
from continuum_mhe.model.descriptions import pcc_outputs
from continuum_mhe.model.imu import STANDARD_GRAVITY
from continuum_mhe.model.kinematics import bend_from_shape
from continuum_mhe.model.pcc import pose_at, up_vector
from continuum_mhe.model.robot import Robot
from continuum_mhe.simulation.scenarios import Recording


@dataclass(frozen=True)
class RawNoise:
    """White noise and bias of simulated MEMS IMUs (one standard deviation each).

    Attributes:
        accel_std: accelerometer white noise per axis, m/s^2.
        gyro_std: gyro white noise per axis, rad/s.
        gyro_bias_std: each gyro axis's constant bias, drawn once per IMU, rad/s.
    """

    accel_std: float = 0.05
    gyro_std: float = 0.005
    gyro_bias_std: float = 0.01


def _bends(rec: Recording, n_sections: int) -> FloatArray:
    """The truth's bend coordinates (n, n_sections, 2), rad."""
    names = [o.name for o in rec.outputs]
    keys = [("theta", "phi")] if n_sections == 1 else [
        (f"theta_{k}", f"phi_{k}") for k in range(1, n_sections + 1)
    ]  # fmt: skip
    out = np.empty((len(rec.t), n_sections, 2))
    for k, (th, ph) in enumerate(keys):
        a, b = bend_from_shape(rec.truth[:, names.index(th)], rec.truth[:, names.index(ph)])
        out[:, k, 0], out[:, k, 1] = a, b
    return out


def _angular_velocity(t: FloatArray, R: FloatArray) -> FloatArray:
    """Body-frame angular velocity (n, 3), rad/s, of orientations ``R`` (n, 3, 3)
    (local to base) at times ``t``: the rotation vector of ``R_{k-1}^T R_{k+1}`` over
    ``t_{k+1} - t_{k-1}``, one-sided at the ends."""
    n = len(t)
    lo = np.clip(np.arange(n) - 1, 0, n - 1)
    hi = np.clip(np.arange(n) + 1, 0, n - 1)
    rel = np.einsum("nji,njk->nik", R[lo], R[hi])
    return Rotation.from_matrix(rel).as_rotvec() / (t[hi] - t[lo])[:, None]


def raw_readings(
    rec: Recording, robot: Robot, noise: RawNoise | None = None, seed: int = 0
) -> tuple[FloatArray, tuple[str, ...]]:
    """The raw readings (n, 6 m) of the ``robot``'s m IMUs along ``rec``'s truth, m/s^2
    and rad/s in each sensor frame (see the module), with their column names."""
    expect_type("rec", rec, Recording, "a Recording (simulate_robot(SCENARIO, robot))")
    expect_type("robot", robot, Robot, "a Robot (read_robot(NAME) reads a robot file)")
    if robot.tendons:
        raise UserError(
            "raw readings are simulated for constant-curvature robots only (a tendon "
            "robot straight and still, simulate_robot('rest', ...), reads as its robot "
            "without tendons: robot.without_tendons())"
        )
    if not (is_integer(seed) and seed >= 0):
        raise UserError(f"seed must be a non-negative integer, got {seed!r}")
    names = tuple(o.name for o in rec.outputs)
    want = tuple(o.name for o in pcc_outputs(robot.n_sections))
    if names != want or not np.isclose(rec.length, robot.length, rtol=1e-9, atol=0.0):
        raise UserError(
            f"rec is a recording of another robot ({len(names)} outputs, {rec.length:g} m "
            f"long) than robot ({robot.describe()}): simulate it with "
            "simulate_robot(SCENARIO, robot) for this robot"
        )
    if len(rec.t) < 3:
        raise UserError("raw readings need at least 3 samples (their rates are differences)")
    noise = noise or RawNoise()
    rng = np.random.default_rng(seed)
    bends = _bends(rec, robot.n_sections)
    up = up_vector(robot.mounting)
    t = np.asarray(rec.t, dtype=float)
    # every IMU's bias first: a recording of another length (a rest to calibrate from)
    # draws the same biases from the same seed
    biases = [
        np.asarray(place.gyro_bias) + rng.normal(0.0, noise.gyro_bias_std, 3)
        for place in robot.imus
    ]
    blocks = []
    for place, bias in zip(robot.imus, biases):
        R, p = pose_at(bends, robot.lengths, place.section, place.at)
        accel = np.gradient(np.gradient(p, t, axis=0), t, axis=0)
        force = np.einsum("nji,nj->ni", R, accel + STANDARD_GRAVITY * up)
        rate = _angular_velocity(t, R)
        mount = Rotation.from_euler("ZYX", place.mount_rpy[::-1], degrees=True).as_matrix()
        force, rate = force @ mount, rate @ mount  # v_sensor = M^T v_backbone, by rows
        force = force + rng.normal(0.0, noise.accel_std, force.shape)
        rate = rate + bias + rng.normal(0.0, noise.gyro_std, rate.shape)
        blocks.append(np.hstack([force, rate]))
    names = tuple(c for i in range(robot.n_imus) for c in raw_columns(i, robot.n_imus))
    return np.hstack(blocks), names
