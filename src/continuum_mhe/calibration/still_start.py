"""Gyro biases from a recording's still start.

A recording that begins with the robot at rest (logging started before the motion, as
it usually is) holds each gyro's bias in its first seconds, as a rest recording does
for ``calibrate``: a gyro at rest reads its bias and its noise alone. With the biases
known, ``estimate`` weighs the IMUs' twist about the backbone on the readings, which
estimated biases do not allow (a bias about an IMU's z axis reads as a twist:
docs/model.md, "The IMUs' twist").

The start counts as still over the longest run of whole blocks of
:data:`BLOCK_S` s from the first sample in which, for every IMU, the gyro's rates
scatter by at most :data:`GYRO_STD` and keep the first block's mean to within
:data:`GYRO_DRIFT`, and the direction of its specific force (the measurements give
the direction alone) stays within :data:`TURN_DEG` of the first block's; the last
such block is left out (the motion may begin inside it), and what is left must span
:data:`MIN_S`. A steady turn about the vertical moves no accelerometer and reads as a
bias (``estimate --no-still-start``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.descriptions import imu_suffix
from continuum_mhe.model.direct import gyro_bias_calibrated
from continuum_mhe.model.robot import Robot

#: The blocks the start is judged in (s) ...
BLOCK_S = 0.5
#: ... each with at least this many samples of every IMU (a recording under 10 Hz has
#: no still start here) ...
BLOCK_SAMPLES = 5
#: ... in which each gyro axis scatters by at most this (rad/s; a MEMS gyro's noise at
#: rest is 0.002 to 0.01, a continuum robot's slowest motion more) ...
GYRO_STD = 0.02
#: ... and its mean stays within this of the first block's (rad/s, per axis) ...
GYRO_DRIFT = 0.01
#: ... and its specific force's direction stays within this of the first block's (deg).
TURN_DEG = 1.0
#: The still start used spans at least this (s), after the last still block is left
#: out, and is looked for in the first :data:`MAX_S` s.
MIN_S = 1.0
MAX_S = 10.0


@dataclass(frozen=True)
class StillStart:
    """A recording's still start.

    Attributes:
        seconds: its length (s), from the first sample.
        samples: the samples in it.
        gyro_biases: each IMU's mean rate over it, in the robot's IMU order: (x, y, z)
            rad/s in the IMU's disk frame, as the measurements give them.
    """

    seconds: float
    samples: int
    gyro_biases: tuple[tuple[float, float, float], ...]

    def clause(self) -> str:
        """The summary's words for it."""
        biases = ", ".join(
            f"IMU {i + 1} ({', '.join(f'{v:.4f}' for v in b)})"
            for i, b in enumerate(self.gyro_biases)
        )
        return (
            f"gyro biases from the still start (its first {self.seconds:.3g} s, "
            f"{self.samples} samples): {biases} rad/s"
        )


def _imu_columns(names: tuple[str, ...], k: int, n_imus: int) -> tuple[list[int], list[int]] | None:
    """The columns of IMU ``k``'s (1-based) specific force and rates among the
    measurement ``names`` of ``n_imus`` IMUs (``fx_k ... wz_k``; ``fx ... wz`` with one
    IMU), or None where it has no gyro there."""
    suffix = imu_suffix(k - 1, n_imus)
    force = [f"f{a}{suffix}" for a in "xyz"]
    rates = [f"w{a}{suffix}" for a in "xyz"]
    if not all(c in names for c in force + rates):
        return None
    return [names.index(c) for c in force], [names.index(c) for c in rates]


def find_still_start(
    t: FloatArray, z: FloatArray, names: tuple[str, ...], n_imus: int
) -> StillStart | None:
    """The still start (module docstring) of the measurements ``z`` (n, nz; columns
    ``names``, raw IMUs as ``fx_k, fy_k, fz_k, wx_k, wy_k, wz_k``, without ``_k`` for one
    IMU: the specific force's direction, or the force itself, and the rates in rad/s)
    at the times ``t`` (n,) s, of ``n_imus`` IMUs; None where there is none (or an IMU
    has no gyro)."""
    found = [_imu_columns(names, k, n_imus) for k in range(1, n_imus + 1)]
    columns = [c for c in found if c is not None]
    if not n_imus or len(columns) < n_imus or len(t) == 0:
        return None
    t = np.asarray(t, dtype=float)
    z = np.asarray(z, dtype=float)
    block = np.floor((t - float(t[0])) / BLOCK_S).astype(np.int64)
    first: list[tuple[FloatArray, FloatArray]] = []
    still_blocks = 0
    for b in range(int(math.floor(MAX_S / BLOCK_S))):
        rows = z[block == b]
        if len(rows) < BLOCK_SAMPLES or not np.isfinite(rows).all():
            break
        if not all(_still(rows, c, first[i] if first else None) for i, c in enumerate(columns)):
            break
        if not first:
            first = [
                (rows[:, rates].mean(axis=0), _direction(rows[:, force]))
                for force, rates in columns
            ]
        still_blocks += 1
    used = still_blocks - 1  # the motion may begin inside the last still block
    if used * BLOCK_S < MIN_S - 1e-9:
        return None
    kept = z[block < used]
    biases = []
    for _, rates in columns:
        mean = kept[:, rates].mean(axis=0)
        biases.append((float(mean[0]), float(mean[1]), float(mean[2])))
    return StillStart(used * BLOCK_S, len(kept), tuple(biases))


def _direction(force: FloatArray) -> FloatArray:
    """The unit vector along the mean of the rows of ``force`` (m, 3)."""
    mean = force.mean(axis=0)
    return mean / max(float(np.linalg.norm(mean)), 1e-300)


def _still(
    rows: FloatArray,
    cols: tuple[list[int], list[int]],
    first: tuple[FloatArray, FloatArray] | None,
) -> bool:
    """Whether one IMU (its columns ``cols``: force, rates) is still over a block's
    ``rows``, against the first block's mean rate and force direction (``first``; None
    for the first block itself)."""
    force, rates = rows[:, cols[0]], rows[:, cols[1]]
    if float(rates.std(axis=0).max()) > GYRO_STD:
        return False
    if first is None:
        return True
    mean_rate, direction = first
    if float(np.abs(rates.mean(axis=0) - mean_rate).max()) > GYRO_DRIFT:
        return False
    cos = float(np.clip(np.dot(_direction(force), direction), -1.0, 1.0))
    return math.degrees(math.acos(cos)) <= TURN_DEG


def with_still_start_biases(
    robot: Robot,
    still: StillStart,
    mount_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Robot:
    """``robot`` with the still start's gyro biases as the ``gyro_bias`` (sensor frame,
    rad/s) of each IMU that has none calibrated; the others kept. A measurement's rates
    are the sensor's less its ``gyro_bias``, turned into the disk frame by its mounting
    (the robot file's ``mount_rpy`` where it gives one, else ``mount_rpy``, as
    ``--mount-rpy`` gives it: :func:`~continuum_mhe.io.input_options.imu_settings_for`),
    so the sensor's bias is the disk-frame mean turned back."""
    imus = []
    for imu, bias in zip(robot.imus, still.gyro_biases):
        if gyro_bias_calibrated(imu):
            imus.append(imu)
            continue
        mount = imu.mount_rpy if any(imu.mount_rpy) else mount_rpy
        sensor = mount_rotation(mount).T @ np.asarray(bias, dtype=float)
        imus.append(replace(imu, gyro_bias=(float(sensor[0]), float(sensor[1]), float(sensor[2]))))
    return replace(robot, imus=tuple(imus))
