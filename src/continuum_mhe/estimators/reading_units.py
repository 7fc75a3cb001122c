"""The units of a ``direct`` IMU block's readings, checked where a library caller hands
them to an estimator (the CSV readers check a file's raw readings themselves).

A ``direct`` block (:class:`~continuum_mhe.model.descriptions.MeasurementBlock`) holds
the IMU's unit specific force ``fx, fy, fz`` (a direction, magnitude 1) and its gyro
``wx, wy, wz`` (rad/s). An accelerometer's reading in m/s^2, or a gyro in deg/s, would be
read as a direction ten times too long or rates 57 times too fast, and the estimate
would be wrong without a word; :func:`direct_units_problem` names it. (A reading in g is
the unit direction to within the IMU's own acceleration.)

A whole recording's units are checked at once (:func:`direct_units_problem`); samples
handed over one by one or in blocks, as they arrive, by :class:`ReadingUnitsWatch`.
"""

from __future__ import annotations

import math

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.io.raw_units import (
    TIME_CHECK_ROWS,
    UNIT_CHECK_SAMPLES,
    UNIT_CHECK_SPAN_S,
    gyro_gravity_problem,
    gyro_motion_problem,
    gyro_units_problem,
)
from continuum_mhe.model.formulations import Formulation

#: A unit specific force whose magnitude is off 1 by more than this is not a direction
#: (readings built by ``direct_measurements`` are 1 to rounding).
UNIT_TOLERANCE = 0.05


DirectRows = tuple[slice, slice, tuple[str, ...]]

#: Once an IMU's first readings are judged, its gyro is judged again by the turns of its
#: motion (:func:`~continuum_mhe.io.raw_units.gyro_motion_problem`) each time this many
#: more samples have come, over their full readings and those of the
#: :data:`MOTION_CHECK_KEPT` samples before them, up to
#: :data:`~continuum_mhe.io.raw_units.TIME_CHECK_ROWS` samples: a stream
#: that starts still, with a small bias, tells no gyro's unit in its first second.
MOTION_CHECK_ROWS = 256
MOTION_CHECK_KEPT = 768


def gyro_label(names: tuple[str, ...]) -> str:
    """A ``direct`` block's gyro readings as a message names them: the model's
    ``wx_i, wy_i, wz_i``, with the raw file's ``gx_i, gy_i, gz_i`` they come from."""
    model, raw = names[3:], tuple("g" + n[1:] for n in names[3:])
    return f"{', '.join(model)} (the gyro's {', '.join(raw)})"


def direct_blocks(formulation: Formulation) -> list[DirectRows]:
    """Per ``direct`` block: the rows of its unit specific force, of its gyro, and its
    six names."""
    return [
        (slice(b.start, b.start + 3), slice(b.start + 3, b.start + 6), b.names)
        for b in formulation.measurement_blocks
        if b.kind == "direct"
    ]


def direct_units_problem(
    blocks: list[DirectRows], z: FloatArray, gyro: bool = True, t: FloatArray | None = None
) -> str | None:
    """What is wrong with the units of ``z`` (n, nz) in the ``direct`` ``blocks``
    (:func:`direct_blocks`), as a line for :class:`~continuum_mhe.errors.UserError`, or
    None: a specific force whose median magnitude is not 1, or (``gyro``: a recording,
    where a median says it; one sample of a fast turn may exceed it) a gyro whose median
    rate says deg/s (:func:`~continuum_mhe.io.raw_units.gyro_units_problem`), or, given
    the samples' times ``t`` (n,) s, whose rates turn the specific force as deg/s would
    (:func:`~continuum_mhe.io.raw_units.gyro_gravity_problem`: a gyro in deg/s at rest or
    in motion).
    Rows with a non-finite reading (dropouts) are left out."""
    for force_rows, gyro_rows, names in blocks:
        f, w = z[:, force_rows], z[:, gyro_rows]
        finite = np.all(np.isfinite(f), axis=1) & np.all(np.isfinite(w), axis=1)
        if not finite.any():
            continue
        typical = " (median)" if finite.sum() > 1 else ""
        size = float(np.median(np.linalg.norm(f[finite], axis=1)))
        if abs(size - 1.0) > UNIT_TOLERANCE:
            return (
                f"{', '.join(names[:3])} have magnitude {size:.3g}{typical}: the direct model "
                "takes the unit specific force, not the accelerometer's reading in m/s^2 "
                "(continuum_mhe.io.raw_measurements(robot, t, acc, gyr) gives the rows, each IMU "
                "turned by its mount_rpy)"
            )
        problem = gyro_units_problem(w[finite], ", ".join(names[3:])) if gyro else None
        if problem is None and gyro and t is not None:
            problem = gyro_gravity_problem(t[finite], f[finite], w[finite], ", ".join(names[3:]))
        if problem is not None:
            return f"{gyro_label(names)}: {problem}"
    return None


class ReadingUnitsError(UserError):
    """Raw readings in the wrong units (an accelerometer in m/s^2, a gyro in deg/s), or
    sample times in a unit other than seconds (stepping faster than any IMU stream),
    found by an estimator's step: every later reading of the stream is wrong alike."""


class ReadingUnitsWatch:
    """The units of ``direct`` readings that arrive sample by sample (or block by
    block): each block's first full reading's specific force, and its gyros' median
    over its first full readings, at least
    :data:`~continuum_mhe.io.raw_units.UNIT_CHECK_SAMPLES` of them over at least
    :data:`~continuum_mhe.io.raw_units.UNIT_CHECK_SPAN_S` (the check of a whole
    recording, on the samples a stream has; one fast turn says nothing); then, until
    :data:`~continuum_mhe.io.raw_units.TIME_CHECK_ROWS` full readings, the turns of its
    motion (:data:`MOTION_CHECK_ROWS`). A stream shorter than a second has its gyros
    unchecked. A problem found is given again for every later sample, until
    :meth:`reset` (a new recording)."""

    def __init__(self, blocks: list[DirectRows]) -> None:
        self._blocks = blocks
        self.reset()

    def reset(self) -> None:
        #: nothing left to look at (every block checked, and no problem found)
        self.done = not self._blocks
        #: the problem found (the line naming the sample that showed it); every later
        #: sample is refused with it, named with its own time
        self.problem: str | None = None
        self._found: tuple[float, str] | None = None  # that sample's time, the problem
        self._pending = list(range(len(self._blocks)))  # blocks still to check
        self._force_unchecked = [True] * len(self._blocks)
        self._gyros: list[list[FloatArray]] = [[] for _ in self._blocks]
        self._forces: list[list[FloatArray]] = [[] for _ in self._blocks]
        self._times: list[list[FloatArray]] = [[] for _ in self._blocks]
        self._first_t = [math.nan] * len(self._blocks)
        self._counts = [0] * len(self._blocks)
        #: blocks whose first readings passed, their gyros judged by their motion over
        #: the samples since (times and readings, kept as handed over: each block's full
        #: readings are picked at a check), the samples seen and those since the last check
        self._moving: list[int] = []
        self._motion: list[tuple[FloatArray, FloatArray]] = []
        self._motion_seen = 0
        self._motion_fresh = 0

    @property
    def judging_first(self) -> bool:
        """Whether some block's first readings are still being gathered (every sample
        counts there: a caller refuses bad samples before handing them over)."""
        return bool(self._pending)

    def see(self, t: FloatArray, z: FloatArray) -> str | None:
        """Look at the samples ``t`` (n,) s, ``z`` (n, nz) that follow those seen: what
        is wrong with their units, as a line naming the sample that showed it
        (``measurement at t=... s: ...``), or None."""
        if self._found is not None:
            found_t, problem = self._found
            now = float(t[0]) if len(t) else found_t
            if now == found_t:
                return self.problem
            return f"measurement at t={now!r} s: as found at t={found_t!r} s, {problem}"
        if self.done:
            return None
        moving = list(self._moving)  # (not those that begin to move with these samples)
        for k in list(self._pending):
            found = self._see_block(k, t, z)
            if found is not None:
                self._found = found
                self.problem = f"measurement at t={found[0]!r} s: {found[1]}"
                return self.problem
        if moving:
            found = self._see_motion(moving, t, z)
            if found is not None:
                self._found = found
                self.problem = f"measurement at t={found[0]!r} s: {found[1]}"
                return self.problem
        self.done = not self._pending and not self._moving
        return None

    def _full_rows(self, k: int, z: FloatArray) -> np.ndarray:
        """The rows of ``z`` with block ``k``'s whole reading."""
        force_rows, gyro_rows, _ = self._blocks[k]
        return np.flatnonzero(
            np.isfinite(z[:, force_rows]).all(axis=1) & np.isfinite(z[:, gyro_rows]).all(axis=1)
        )

    def _see_motion(
        self, blocks: list[int], t: FloatArray, z: FloatArray
    ) -> tuple[float, str] | None:
        """The gyros of ``blocks`` judged by their motion (:data:`MOTION_CHECK_ROWS`):
        the time and the problem of the sample that showed deg/s, else None. A sample
        kept is a copy; the work is done at a check, not sample by sample."""
        self._motion.append((np.array(t, dtype=float), np.array(z, dtype=float)))
        self._motion_seen += len(t)
        self._motion_fresh += len(t)
        last = self._motion_seen >= TIME_CHECK_ROWS
        if last:
            self._moving = []
        elif self._motion_fresh < MOTION_CHECK_ROWS:
            return None
        self._motion_fresh = 0
        kept = MOTION_CHECK_KEPT + MOTION_CHECK_ROWS
        times = np.concatenate([m[0] for m in self._motion])[-kept:]
        rows = np.concatenate([m[1] for m in self._motion])[-kept:]
        self._motion = [] if last else [(times, rows)]
        # a sample the estimator refused (its time not after the one before) is left out
        later = times > np.concatenate([[-math.inf], np.maximum.accumulate(times)[:-1]])
        for k in blocks:
            force_rows, gyro_rows, names = self._blocks[k]
            full = self._full_rows(k, rows)
            full = full[later[full]]
            problem = gyro_motion_problem(
                times[full], rows[full, force_rows], rows[full, gyro_rows], ", ".join(names[3:])
            )
            if problem is not None:
                return float(times[-1]), f"{gyro_label(names)}: {problem}"
        return None

    def _see_block(self, k: int, t: FloatArray, z: FloatArray) -> tuple[float, str] | None:
        force_rows, gyro_rows, names = self._blocks[k]
        if len(z) == 1 and not all(  # one sample (a step) without this IMU: nothing to see
            map(math.isfinite, z[0, force_rows].tolist() + z[0, gyro_rows].tolist())
        ):
            return None
        full = self._full_rows(k, z)
        if not len(full):
            return None
        if self._force_unchecked[k]:
            self._force_unchecked[k] = False
            i = int(full[0])
            problem = direct_units_problem([self._blocks[k]], z[i : i + 1], gyro=False)
            if problem is not None:
                return float(t[i]), problem
            self._first_t[k] = float(t[i])
        seen = self._gyros[k]
        seen.append(z[full, gyro_rows].copy())
        self._forces[k].append(z[full, force_rows].copy())
        self._times[k].append(np.asarray(t, dtype=float)[full].copy())
        self._counts[k] += len(full)
        span = float(t[full[-1]]) - self._first_t[k]
        if self._counts[k] < UNIT_CHECK_SAMPLES or span < UNIT_CHECK_SPAN_S:
            return None
        self._pending.remove(k)
        gyros = np.concatenate(seen)
        times, forces = np.concatenate(self._times[k]), np.concatenate(self._forces[k])
        problem = gyro_units_problem(gyros, ", ".join(names[3:]))
        if problem is None:
            problem = gyro_gravity_problem(times, forces, gyros, ", ".join(names[3:]))
        self._gyros[k], self._forces[k], self._times[k] = [], [], []
        if problem is None:  # its motion judges it from here on
            self._moving.append(k)
            return None
        of = f"(median of the first {self._counts[k]} full readings, {span:.3g} s)"
        return float(t[full[-1]]), f"{gyro_label(names)}: " + problem.replace("(median)", of, 1)
