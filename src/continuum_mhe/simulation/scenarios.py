"""Synthetic recordings: a true shape trajectory and noisy roll/pitch readings.

Truth comes from the same kinematics the estimators use (``model.kinematics``); the
IMU readings from the measurement model plus Gaussian noise of ``noise_deg``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from continuum_mhe.model.imu import Mounting, shape_from_tilt, tilt, wrap_angle
from continuum_mhe.model.kinematics import (
    FloatArray,
    bend_from_shape,
    shape_from_bend,
    tip_position,
)

ScenarioName = Literal["paper3d", "planar-overbend", "straight"]
SCENARIOS: tuple[ScenarioName, ...] = ("paper3d", "planar-overbend", "straight")

#: Largest recording :func:`simulate` makes (10 million samples, about 0.5 GB).
MAX_SAMPLES = 10_000_000


@dataclass(frozen=True)
class Recording:
    """A recording with its truth.

    Attributes:
        t: (n,) sample times, s.
        z: (n, 2) measured ``[roll, pitch]``, rad.
        truth: (n, 5) ``[x, y, z, theta, phi]`` (m, rad).
        length: section length, m.
    """

    t: FloatArray
    z: FloatArray
    truth: FloatArray
    length: float


def _paper3d(t: FloatArray) -> tuple[FloatArray, FloatArray]:
    # roll in [0, pi/4] and pitch in [0, 0.45 pi] (the paper's ranges, kept off the
    # pitch = pi/2 gimbal lock), inverted to (theta, phi) as in Sec. 3.1
    roll = math.pi / 8 * (1 - np.cos(2 * np.pi * t / 8.0))
    pitch = 0.225 * math.pi * (1 - np.cos(2 * np.pi * t / 5.3))
    return shape_from_tilt(roll, pitch)


def _planar_overbend(t: FloatArray) -> tuple[FloatArray, FloatArray]:
    # bending in the base y-z plane (roll only); theta crosses pi/2 at about 6.4 s
    theta = 1.1 * (1 - np.cos(np.pi * t / 10.0))
    return theta, np.full_like(t, math.pi / 2)


def _straight(t: FloatArray) -> tuple[FloatArray, FloatArray]:
    # the bend vector passes through zero: bends one way, straight, the other way
    w = 2 * np.pi * t / 10.0
    return shape_from_bend(0.8 * np.sin(w), 0.3 * np.sin(w))


_SHAPES: dict[str, Callable[[FloatArray], tuple[FloatArray, FloatArray]]] = {
    "paper3d": _paper3d,
    "planar-overbend": _planar_overbend,
    "straight": _straight,
}


def simulate(
    scenario: ScenarioName,
    *,
    duration: float = 20.0,
    dt: float = 0.05,
    noise_deg: float = 2.0,
    length: float = 0.2,
    seed: int = 0,
    mounting: Mounting = "z-up",
    noise_std: tuple[float, float] | None = None,
) -> Recording:
    """Simulate ``scenario`` for ``duration`` s at sample time ``dt`` s.

    ``noise_std`` (roll, pitch) in rad overrides ``noise_deg`` (used for Table 1).
    """
    if scenario not in _SHAPES:
        raise ValueError(f"unknown scenario {scenario!r}; choose from {', '.join(SCENARIOS)}")
    for name, v in (("duration", duration), ("dt", dt), ("length", length)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be positive, got {v}")
    if not (math.isfinite(noise_deg) and noise_deg >= 0):
        raise ValueError(f"noise-deg must be >= 0, got {noise_deg}")
    if not (isinstance(seed, int) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    n = int(round(duration / dt)) + 1
    if n > MAX_SAMPLES:
        raise ValueError(
            f"duration/dt gives {n} samples, more than {MAX_SAMPLES}: "
            "use a shorter --duration or a larger --dt"
        )
    t: FloatArray = np.arange(n, dtype=float) * dt
    theta, phi = _SHAPES[scenario](t)
    a, b = bend_from_shape(theta, phi)
    theta, phi = shape_from_bend(a, b)  # canonical: theta >= 0, phi in (-pi, pi]
    truth = np.column_stack([tip_position(theta, phi, length), theta, phi])
    std = np.radians([noise_deg, noise_deg]) if noise_std is None else np.abs(noise_std)
    rng = np.random.default_rng(seed)
    z = tilt(theta, phi, mounting) + rng.normal(size=(n, 2)) * std
    z = wrap_angle(z)
    return Recording(t=t, z=z, truth=truth, length=length)
