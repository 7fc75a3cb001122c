"""The sensor-health policy that depends on the input alone, for a span of samples at once.

What a recording's readings say about its sensors does not depend on any estimate:
which measurement blocks are valid (finite), which IMU repeats the same reading for
longer than ``RecoverySettings.freeze`` (a frozen sensor, treated as a dropout), which
valid sample ends a gap longer than ``gap_reset`` (the estimator restarts there), which
IMU is back after a silence, and whether the IMUs that reported recently determine the
shape. :class:`SensorHealth` decides all of it for a whole span of samples in a few
array operations (:meth:`SensorHealth.plan`), carrying its state from one span to the
next: a batch run plans the whole recording (or each chunk of a stream) once, and
:meth:`~continuum_mhe.estimators.base.Estimator.step` plans a span of one sample, so
the policy has one implementation. The estimator's own policy (restarts after a
divergence, bad starts, the consistency of the estimates) needs the estimates and
stays in the per-sample loop (:meth:`~continuum_mhe.estimators.base.Estimator.run_span`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import RecoverySettings

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: An IMU silent for longer than this (s) no longer observes its part of the shape when
#: the gap reset is off (else the gap reset's time).
UNOBSERVED_AFTER = 1.0


@dataclass(frozen=True)
class SensorPlan:
    """The input-only decisions for a span of ``n`` samples.

    Attributes:
        z: (n, nz) the readings, a frozen sensor's block set to NaN (a dropout).
        mask: (n, nz) 1.0 on the components of the valid blocks (all finite), else 0.0
            (:meth:`~continuum_mhe.model.formulations.Formulation.measurement_mask`).
        frozen: (n,) a sensor was treated as frozen at this sample.
        gap_reset: (n,) the first valid sample after more than ``gap_reset`` s without
            one: the estimator restarts here.
        back: per sample, the measurement rows of the IMUs back after more than the gap
            reset (1 s when it is off) without a valid reading, or None.
        observed: (n,) the IMUs that reported within the gap reset (1 s when off)
            determine the shape.
    """

    z: FloatArray
    mask: FloatArray
    frozen: BoolArray
    gap_reset: BoolArray
    back: list[NDArray[np.intp] | None]
    observed: BoolArray


def _last_time(t: FloatArray, hit: BoolArray, carried: float) -> FloatArray:
    """Per sample, the ``t`` of the latest sample up to and including it where ``hit``
    (``carried`` before the span's first)."""
    idx = np.where(hit, np.arange(len(t)), -1)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx >= 0, t[np.maximum(idx, 0)], carried)


def _before(a: FloatArray, carried: float) -> FloatArray:
    """``a`` shifted by one sample: entry ``i`` is ``a[i - 1]`` (``carried`` for 0)."""
    out = np.empty_like(a)
    out[0] = carried
    out[1:] = a[:-1]
    return out


class SensorHealth:
    """The input-only sensor-health policy of one estimator (module doc); its state is
    the end of the samples planned so far."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        imus = tuple(b for b in formulation.measurement_blocks if b.is_imu)
        self._slices = tuple(b.slice for b in formulation.measurement_blocks)
        #: the IMUs' measurement columns, block after block, and where each block begins
        #: among them; each IMU's first measurement row
        self._imu_cols = np.array([c for b in imus for c in range(b.start, b.start + b.size)])
        self._imu_offsets = np.cumsum([0] + [b.size for b in imus[:-1]]).astype(np.intp)
        self._imu_sizes = np.array([b.size for b in imus], dtype=np.intp)
        self._imu_starts = np.array([b.start for b in imus], dtype=np.intp)
        self._imu_rows = [np.arange(b.start, b.start + b.size) for b in imus]
        #: whether every IMU together determines the shape
        self.shape_observable = formulation.imus_determine_shape(
            tuple(range(formulation.robot.n_imus))
        )
        self._observable_subsets: dict[tuple[int, ...], bool] = {}
        self.reset()

    def reset(self, keep_counts: bool = False) -> None:
        """Forget the samples planned so far (a new recording) and, unless
        ``keep_counts``, the counts (:attr:`frozen_samples`, :attr:`first_freezes`)."""
        k = len(self._imu_starts)
        #: per IMU block: its last reading (NaN before the first: NaN never repeats),
        #: the ``t`` of the first of its repeats, how many samples repeated it
        self._freeze_value = np.full(len(self._imu_cols), np.nan)
        self._freeze_since = np.full(k, -math.inf)
        self._freeze_count = np.zeros(k, dtype=np.intp)
        self._freeze_last_t = -math.inf  # t of the last sample
        self._last_valid_t = -math.inf  # t of the last valid sample (gap reset on)
        self._imu_last_valid = np.full(k, -math.inf)  # per IMU, t of its last valid reading
        self._first_valid_t = -math.inf  # t of the recording's first valid reading
        if keep_counts:
            return
        #: samples with at least one sensor treated as frozen
        self.frozen_samples = 0
        #: the first freeze of each sensor, in the order they happened: IMU block index ->
        #: ``t`` (s) of the first of its repeated readings
        self.first_freezes: dict[int, float] = {}

    def plan(self, t: FloatArray, z: FloatArray, recovery: RecoverySettings) -> SensorPlan:
        """The decisions for the samples ``t`` (n,) s, ``z`` (n, nz) that follow those
        planned so far (validated: ``t`` strictly increasing)."""
        z, frozen = self._unfreeze(t, z, recovery)
        mask = self._masks(z)
        valid: BoolArray = np.asarray(mask.any(axis=1))
        gap_reset = np.zeros(len(t), dtype=bool)
        gap = recovery.gap_reset
        if gap is not None:
            prev = _before(_last_time(t, valid, self._last_valid_t), self._last_valid_t)
            gap_reset = valid & (prev > -math.inf) & (prev < t - gap)
            if valid.any():
                self._last_valid_t = float(t[np.flatnonzero(valid)[-1]])
        window = gap or UNOBSERVED_AFTER
        back, last = self._returns(t, mask, valid, window)
        return SensorPlan(z, mask, frozen, gap_reset, back, self._observed(t, last, window))

    def _masks(self, z: FloatArray) -> FloatArray:
        """:meth:`Formulation.measurement_mask` of every row of ``z`` (n, nz)."""
        finite = np.isfinite(z)
        every = finite.all(axis=1)
        mask = np.zeros(z.shape)
        for sl in self._slices:
            mask[:, sl] = np.asarray(finite[:, sl].all(axis=1))[:, None]
        mask[every] = 1.0
        return mask

    def _unfreeze(
        self, t: FloatArray, z: FloatArray, recovery: RecoverySettings
    ) -> tuple[FloatArray, BoolArray]:
        """``z`` with every sensor whose reading has repeated exactly for longer than
        ``recovery.freeze`` seconds, over at least ``recovery.freeze_samples``
        consecutive samples none more than ``recovery.freeze`` s after the one before
        (a gap in the data is not a freeze), set to NaN (a dropout); and per sample
        whether one was."""
        n, k = len(t), len(self._imu_starts)
        freeze = recovery.freeze
        if freeze is None or not k:
            return z, np.zeros(n, dtype=bool)
        idx = np.arange(n)[:, None]
        zi = z[:, self._imu_cols]  # (n, columns of the IMUs)
        prev = np.empty_like(zi)
        prev[0], prev[1:] = self._freeze_value, zi[:-1]
        same = np.logical_and.reduceat(zi == prev, self._imu_offsets, axis=1)  # (n, k)
        new = ~same | (t - _before(t, self._freeze_last_t) > freeze)[:, None]
        start = np.where(new, idx, -1)
        np.maximum.accumulate(start, axis=0, out=start)
        carried = start < 0  # the run that the samples before this span began
        count = np.where(carried, self._freeze_count + idx + 1, idx - start + 1)
        since = np.where(carried, self._freeze_since, t[np.maximum(start, 0)])
        frozen = ~new & (count >= recovery.freeze_samples) & (t[:, None] - since > freeze)
        self._freeze_value, self._freeze_last_t = zi[-1].copy(), float(t[-1])
        self._freeze_since, self._freeze_count = since[-1].copy(), count[-1].copy()
        frozen_any: BoolArray = np.asarray(frozen.any(axis=1))
        if not frozen_any.any():
            return z, frozen_any
        out = z.copy()
        cols = np.repeat(frozen, self._imu_sizes, axis=1)
        out[:, self._imu_cols] = np.where(cols, np.nan, zi)
        blocks = np.flatnonzero(frozen.any(axis=0))
        first = frozen[:, blocks].argmax(axis=0)
        for i, b in sorted(zip(first.tolist(), blocks.tolist())):
            self.first_freezes.setdefault(b, float(since[i, b]))
        self.frozen_samples += int(frozen_any.sum())
        return out, frozen_any

    def _returns(
        self, t: FloatArray, mask: FloatArray, valid: BoolArray, window: float
    ) -> tuple[list[NDArray[np.intp] | None], FloatArray]:
        """Per sample, the measurement rows of the IMUs back at it after more than
        ``window`` s without a valid reading (never having reported counts from the
        recording's first valid reading), or None; and (n, n_imus) each IMU's last valid
        ``t`` up to and including each sample."""
        n = len(t)
        first = self._first_valid_t
        if first == -math.inf and valid.any():
            first = self._first_valid_t = float(t[np.flatnonzero(valid)[0]])
        hit = mask[:, self._imu_starts] > 0.0  # (n, n_imus)
        at = np.where(hit, np.arange(n)[:, None], -1)
        np.maximum.accumulate(at, axis=0, out=at)
        last = np.where(at >= 0, t[np.maximum(at, 0)], self._imu_last_valid)
        prev = np.empty_like(last)
        prev[0], prev[1:] = self._imu_last_valid, last[:-1]
        returns = hit & (t[:, None] - prev > window) & (t[:, None] - first > window)
        back: list[NDArray[np.intp] | None] = [None] * n
        for i in np.flatnonzero(returns.any(axis=1)):
            back[i] = np.concatenate([self._imu_rows[k] for k in np.flatnonzero(returns[i])])
        if n:
            self._imu_last_valid = last[-1].copy()
        return back, last

    def _observed(self, t: FloatArray, last: FloatArray, window: float) -> BoolArray:
        """Per sample, whether the IMUs that reported within ``window`` s up to it
        (``last``: each IMU's last valid ``t``) determine the shape
        (:meth:`Formulation.imus_determine_shape`)."""
        n, n_imus = last.shape
        if not self.shape_observable:
            return np.zeros(n, dtype=bool)
        if n_imus <= 1:
            return np.ones(n, dtype=bool)  # its silence is the whole robot's gap
        recent = t[:, None] - last <= window
        observed = np.ones(n, dtype=bool)  # all reporting, or none (the gap's dropouts)
        some = recent.any(axis=1) & ~recent.all(axis=1)
        if some.any():
            patterns, inverse = np.unique(recent[some], axis=0, return_inverse=True)
            known = np.array([self._determines(tuple(np.flatnonzero(p))) for p in patterns])
            observed[some] = known[inverse.ravel()]
        return observed

    def _determines(self, imus: tuple[int, ...]) -> bool:
        """Whether the IMUs ``imus`` determine the shape (cached)."""
        known = self._observable_subsets.get(imus)
        if known is None:
            known = self.formulation.imus_determine_shape(tuple(int(k) for k in imus))
            self._observable_subsets[imus] = known
        return known
