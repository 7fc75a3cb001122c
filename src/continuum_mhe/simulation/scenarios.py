"""Synthetic recordings: a true shape trajectory and noisy roll/pitch readings.

Truth comes from the same kinematics the estimators use (``model.kinematics``,
``model.pcc``); the IMU readings from the measurement model plus Gaussian noise of
``noise_deg``, either on roll and pitch independently (``noise_model="tilt"``, the
paper's and the default) or isotropic on the tangent plane of the measured gravity
direction (``"tangent"``: what the estimators' ``R`` assumes, so the data are
model-consistent for the measurement; the two differ where pitch is large, since
roll noise moves the gravity direction by only ``cos(pitch)`` of it).
One-section scenarios: ``paper3d``, ``planar-overbend``, ``straight``.
Any robot: ``rest`` (every section straight and still: a recording at rest, as
``calibrate --from`` takes).
Multi-section scenarios (a robot with two or more sections, one tilt IMU per entry of
the robot's IMU list): ``s-curve`` (planar, neighbouring sections bend in opposite
senses) and ``spatial`` (bending planes turning at different rates, bends up to
1.7 rad per section where the bounds allow).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, expect_type, is_integer, real_number
from continuum_mhe.model.descriptions import OutputSpec, pcc_outputs
from continuum_mhe.model.imu import (
    Mounting,
    canonical_tilt,
    shape_from_tilt,
    tilt,
    tilt_from_accelerometer,
    wrap_angle,
)
from continuum_mhe.model.kinematics import bend_from_shape, shape_from_bend, tip_position
from continuum_mhe.model.robot import Robot, Section, mount_taken

NoiseModel = Literal["tilt", "tangent"]
NOISE_MODELS: tuple[NoiseModel, ...] = ("tilt", "tangent")

#: Tilt noise of the moving scenarios, degrees (the paper's): the default of ``noise_deg``
NOISE_DEG = 2.0
#: Tilt noise of a still IMU, degrees: ``rest``'s default ``noise_deg``, the tilt that a MEMS
#: accelerometer's white noise (``RawNoise.accel_std``, 0.05 m/s^2) gives at rest. The
#: :data:`NOISE_DEG` of the moving scenarios hold the IMUs' own acceleration too, which
#: a still robot does not have (and which ``calibrate`` takes for motion).
REST_NOISE_DEG = 0.29

ScenarioName = Literal["paper3d", "planar-overbend", "straight", "s-curve", "spatial", "rest"]
SCENARIOS: tuple[ScenarioName, ...] = (
    "paper3d",
    "planar-overbend",
    "straight",
    "s-curve",
    "spatial",
    "rest",
)
#: Scenarios for robots with two or more sections.
MULTI_SECTION_SCENARIOS: tuple[ScenarioName, ...] = ("s-curve", "spatial")
#: Scenarios for one section with a tip IMU.
SINGLE_SECTION_SCENARIOS: tuple[ScenarioName, ...] = ("paper3d", "planar-overbend", "straight")

#: Largest recording :func:`simulate` makes (10 million samples, about 0.5 GB).
MAX_SAMPLES = 10_000_000


@dataclass(frozen=True)
class Recording:
    """A recording with its truth.

    Attributes:
        t: (n,) sample times, s.
        z: (n, 2 m) measured ``[roll, pitch]`` of each of the m IMUs, rad.
        truth: (n, ny) the outputs described by ``outputs`` (one section:
            ``[x, y, z, theta, phi]``; m, rad).
        length: the robot's length, m.
        outputs: what each truth column is.
        measurement_names: what each column of ``z`` is.
    """

    t: FloatArray
    z: FloatArray
    truth: FloatArray
    length: float
    outputs: tuple[OutputSpec, ...] = pcc_outputs(1)
    measurement_names: tuple[str, ...] = ("roll", "pitch")


def tangent_plane_noise(z: FloatArray, std: float, rng: np.random.Generator) -> FloatArray:
    """``(roll, pitch)`` readings ``z`` (n, 2), rad, with their gravity direction turned
    by an isotropic Gaussian rotation of ``std`` rad per axis about the tangent plane
    (the noise the estimators' tangent-plane residual models)."""
    from scipy.spatial.transform import Rotation

    roll, pitch = z[:, 0], z[:, 1]
    g = np.stack([-np.sin(pitch), np.cos(pitch) * np.sin(roll), np.cos(pitch) * np.cos(roll)], 1)
    helper = np.where(np.abs(g[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e1 = np.cross(g, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 = np.cross(g, e1)
    v = rng.normal(size=(len(z), 2)) * std
    turned = Rotation.from_rotvec(v[:, :1] * e1 + v[:, 1:] * e2).apply(g)
    return tilt_from_accelerometer(turned)


def _noisy(
    h: FloatArray, std: FloatArray, rng: np.random.Generator, noise_model: NoiseModel
) -> FloatArray:
    """Readings ``h`` (n, 2 m) of m IMUs with noise ``std`` (2,) rad as ``noise_model``."""
    if noise_model == "tilt":  # as an IMU reports its attitude: |pitch| <= pi/2
        noisy = wrap_angle(h + rng.normal(size=h.shape) * np.tile(std, h.shape[1] // 2))
        return canonical_tilt(noisy)
    if noise_model != "tangent":
        choices = ", ".join(NOISE_MODELS)
        raise UserError(f"noise model must be one of {choices}, got {noise_model!r}")
    if std[0] != std[1]:
        raise UserError("tangent-plane noise is isotropic: give one standard deviation")
    cols = [
        tangent_plane_noise(h[:, j : j + 2], float(std[0]), rng) for j in range(0, h.shape[1], 2)
    ]
    return np.concatenate(cols, axis=1)


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


def _multi_bends(scenario: str, t: FloatArray, theta_max: Sequence[float]) -> FloatArray:
    """Bend vectors (n, sections, 2) of a multi-section scenario."""
    out = np.zeros((len(t), len(theta_max), 2))
    for k, tmax in enumerate(theta_max):
        sign = 1.0 if k % 2 == 0 else -1.0
        if scenario == "s-curve":
            # planar (base y-z plane); neighbours bend in opposite senses
            amp = min(1.2, 0.9 * tmax)
            theta = amp * 0.5 * (1 - np.cos(2 * np.pi * t / 8.0))
            out[:, k, 1] = sign * theta
        else:  # spatial: bending planes turn at different rates, large bends
            amp = min(1.7, 0.95 * tmax)
            theta = amp * (0.55 + 0.45 * np.sin(2 * np.pi * t / (7.0 + 2.0 * k)))
            phi = sign * 2 * np.pi * t / (6.0 + 4.0 * k) + 0.7 * k
            out[:, k, 0], out[:, k, 1] = theta * np.cos(phi), theta * np.sin(phi)
    return out


def simulate_robot(
    scenario: ScenarioName,
    robot: Robot,
    *,
    duration: float = 20.0,
    dt: float = 0.05,
    noise_deg: float | None = None,
    seed: int = 0,
    noise_model: NoiseModel = "tilt",
) -> Recording:
    """Simulate a multi-section ``scenario`` on ``robot`` (tilt IMUs as placed): the
    bends for ``duration`` s sampled every ``dt`` s, each IMU's roll and pitch with
    noise of ``noise_deg`` degrees standard deviation (None: :data:`NOISE_DEG`, and
    :data:`REST_NOISE_DEG` for ``rest``; ``noise_model``: how it enters, see the module
    docstring), drawn from ``seed``. A scenario for one section with a
    tip IMU on a one-section robot is :func:`simulate`'s. The one-section scenarios
    (``paper3d``, ``planar-overbend``, ``straight``) are fixed motions that ignore the
    section's ``theta_max`` (``paper3d`` bends to 1.44 rad, ``planar-overbend`` to
    1.99): on a robot with a smaller bound the truth passes it, and the estimates there
    are ``at-bound`` (``continuum-mhe simulate`` says so in a note); the multi-section
    scenarios scale each section's bend to within its ``theta_max``.

    Raises:
        UserError: for a tendon robot but ``rest`` (straight and still, its tendons
            slack: the readings of its sections' geometry; its other recordings come
            from :mod:`continuum_mhe.simulation.cosserat_tendon`, ``continuum-mhe rod
            tendon``), or a scenario the robot's sections and IMUs do not fit.
    """
    from continuum_mhe.model.bend import BendFormulation

    expect_type("robot", robot, Robot, "a Robot (read_robot(NAME) reads a robot file)")
    if robot.tendons and scenario == "rest":  # straight and still: its tendons slack
        robot = robot.without_tendons()
    if robot.tendons:
        raise UserError(
            f"a tendon robot ({robot.describe()}): the scenarios but rest (straight and "
            "still) are the bends of a constant-curvature robot without tensions; a "
            "tendon robot's recordings (tensions, tip force) come from continuum-mhe rod "
            "tendon (two sections, an IMU at each end)"
        )
    if scenario not in _SHAPES and scenario not in (*MULTI_SECTION_SCENARIOS, "rest"):
        raise UserError(f"unknown scenario {scenario!r}; choose from {', '.join(SCENARIOS)}")
    rest = scenario == "rest"
    one_section = scenario in _SHAPES or (rest and robot.n_sections == 1)
    if one_section and robot.n_sections == 1 and robot.is_single:
        return simulate(
            scenario, duration=duration, dt=dt, noise_deg=noise_deg,
            length=robot.length, seed=seed, mounting=robot.mounting,
            noise_model=noise_model,
        )  # fmt: skip
    if one_section != (robot.n_sections == 1):
        shapes = (*(_SHAPES if robot.n_sections == 1 else MULTI_SECTION_SCENARIOS), "rest")
        needs = "one section" if one_section else "two or more sections (--robot)"
        raise UserError(
            f"scenario {scenario!r} is for a robot of {needs}; for this robot "
            f"({robot.describe()}) choose from {', '.join(sorted(shapes))}"
        )
    noise_deg = default_noise_deg(scenario, noise_deg)
    t = _time_axis(duration, dt, noise_deg, seed)
    if rest:  # every section straight, still
        bends = np.zeros((len(t), robot.n_sections, 2))
    elif one_section:  # one section with IMUs along it: the section's bend, read by each
        a, b = bend_from_shape(*_SHAPES[scenario](t))
        bends = np.column_stack([a, b]).reshape(len(t), 1, 2)
    else:
        bends = _multi_bends(scenario, t, [s.theta_max for s in robot.sections])
    f = BendFormulation(robot=robot)
    mount_taken(robot)  # roll and pitch in each IMU's disk frame
    x = np.concatenate([bends.reshape(len(t), -1), np.zeros((len(t), bends[0].size))], axis=1)
    truth = f.output(x)
    h = np.asarray(f.functions.observe(x.T), dtype=float).reshape(f.nz, -1).T
    rng = np.random.default_rng(seed)
    z = _noisy(h, np.radians([noise_deg, noise_deg]), rng, noise_model)
    return Recording(
        t=t, z=z, truth=truth, length=robot.length, outputs=f.outputs,
        measurement_names=f.measurement_names,
    )  # fmt: skip


def sample_count(duration: float, dt: float) -> int:
    """The number of samples of a simulated recording of ``duration`` s at ``dt`` s
    (``t = 0, dt, ...``, the last within half a step of ``duration``)."""
    return int(round(duration / dt)) + 1


def default_noise_deg(scenario: str, noise_deg: float | None) -> float:
    """``noise_deg``, or where None the scenario's default: :data:`REST_NOISE_DEG` for
    ``rest``, else :data:`NOISE_DEG`."""
    if noise_deg is not None:
        return noise_deg
    return REST_NOISE_DEG if scenario == "rest" else NOISE_DEG


def _noise_std(noise_std: object) -> FloatArray:
    """``noise_std`` as two finite standard deviations >= 0 (roll, pitch; rad), or a
    :class:`UserError` naming it."""
    try:
        std = np.asarray(noise_std, dtype=float)
    except (TypeError, ValueError):
        std = np.empty(0)
    if std.shape != (2,) or not (np.isfinite(std).all() and (std >= 0).all()):
        raise UserError(
            f"noise_std must be two finite standard deviations >= 0 (roll, pitch; rad), "
            f"got {noise_std!r}"
        )
    return std


def _time_axis(duration: float, dt: float, noise_deg: float, seed: int) -> FloatArray:
    for name, v in (("duration", duration), ("dt", dt), ("noise_deg", noise_deg)):
        real_number(name, v)
    for name, v in (("duration", duration), ("dt", dt)):
        if not (math.isfinite(v) and v > 0):
            raise UserError(f"{name} must be positive, got {v}")
    if not (math.isfinite(noise_deg) and noise_deg >= 0):
        raise UserError(f"noise_deg (--noise-deg) must be >= 0, got {noise_deg}")
    if not (is_integer(seed) and seed >= 0):
        raise UserError(f"seed must be a non-negative integer, got {seed!r}")
    if dt > duration:
        raise UserError(
            f"dt = {dt:g} s is longer than the duration, {duration:g} s: a recording of one "
            "sample (both in seconds: dt in milliseconds?)"
        )
    n = sample_count(duration, dt)
    if n > MAX_SAMPLES:
        raise UserError(
            f"duration/dt gives {n} samples, more than {MAX_SAMPLES}: "
            "use a shorter duration (--duration) or a larger dt (--dt)"
        )
    return np.arange(n, dtype=float) * dt


def simulate(
    scenario: ScenarioName,
    *,
    duration: float = 20.0,
    dt: float = 0.05,
    noise_deg: float | None = None,
    length: float = 0.2,
    seed: int = 0,
    mounting: Mounting = "z-up",
    noise_std: tuple[float, float] | None = None,
    noise_model: NoiseModel = "tilt",
) -> Recording:
    """Simulate ``scenario`` for ``duration`` s at sample time ``dt`` s.

    ``noise_deg``: the readings' noise, degrees (None: :data:`NOISE_DEG`, and
    :data:`REST_NOISE_DEG` for ``rest``); ``noise_std`` (roll, pitch) in rad overrides
    it (used for Table 1); ``noise_model``: see the module docstring.
    """
    if scenario in MULTI_SECTION_SCENARIOS:
        raise UserError(
            f"scenario {scenario!r} needs a robot with two or more sections: "
            f"simulate_robot({scenario!r}, robot) (on the command line: --robot)"
        )
    if scenario not in _SHAPES and scenario != "rest":
        raise UserError(f"unknown scenario {scenario!r}; choose from {', '.join(SCENARIOS)}")
    length = real_number("length", length)
    Section(length)  # a section's checks: positive, in metres (not millimetres)
    noise_deg = default_noise_deg(scenario, noise_deg)
    t = _time_axis(duration, dt, noise_deg, seed)
    theta, phi = (
        (np.zeros_like(t), np.zeros_like(t)) if scenario == "rest" else _SHAPES[scenario](t)
    )
    a, b = bend_from_shape(theta, phi)
    theta, phi = shape_from_bend(a, b)  # canonical: theta >= 0, phi in (-pi, pi]
    # the outputs' convention: phi in [-pi, pi), as every estimate and truth file has it
    truth = np.column_stack([tip_position(theta, phi, length), theta, wrap_angle(phi)])
    std = np.radians([noise_deg, noise_deg]) if noise_std is None else _noise_std(noise_std)
    rng = np.random.default_rng(seed)
    z = _noisy(tilt(theta, phi, mounting), std, rng, noise_model)
    return Recording(t=t, z=z, truth=truth, length=length)
