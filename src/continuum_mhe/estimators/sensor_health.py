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
        self._imu_blocks = tuple(b for b in formulation.measurement_blocks if b.is_imu)
        self._slices = tuple(b.slice for b in formulation.measurement_blocks)
        #: per IMU ``k``, ``(start, stop)`` of its measurement rows
        self._imu_rows = [(b.start, b.start + b.size) for b in self._imu_blocks]
        #: whether every IMU together determines the shape
        self.shape_observable = formulation.imus_determine_shape(
            tuple(range(formulation.robot.n_imus))
        )
        self._observable_subsets: dict[tuple[int, ...], bool] = {}
        self.reset()

    def reset(self, keep_counts: bool = False) -> None:
        """Forget the samples planned so far (a new recording) and, unless
        ``keep_counts``, the counts (:attr:`frozen_samples`, :attr:`first_freezes`)."""
        k = len(self._imu_blocks)
        #: per IMU block: its last reading, the ``t`` of the first of its repeats, how
        #: many samples repeated it, and the ``t`` of its last sample
        self._freeze_value: list[FloatArray | None] = [None] * k
        self._freeze_since = [-math.inf] * k
        self._freeze_count = [0] * k
        self._freeze_last_t = [-math.inf] * k
        self._last_valid_t = -math.inf  # t of the last valid sample (gap reset on)
        self._imu_last_valid = [-math.inf] * k  # per IMU, t of its last valid reading
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
        n = len(t)
        frozen_any = np.zeros(n, dtype=bool)
        freeze = recovery.freeze
        if freeze is None:
            return z, frozen_any
        out = z
        firsts: list[tuple[int, int, float]] = []  # (sample, block, since)
        idx = np.arange(n)
        for k, b in enumerate(self._imu_blocks):
            zb = z[:, b.slice]
            last = self._freeze_value[k]
            prev = np.empty_like(zb)
            prev[0] = np.nan if last is None else last  # NaN never repeats
            prev[1:] = zb[:-1]
            prev_t = _before(t, self._freeze_last_t[k])
            new = ~(zb == prev).all(axis=1) | (t - prev_t > freeze)
            start = np.where(new, idx, -1)
            np.maximum.accumulate(start, out=start)
            carried = start < 0  # the run that the samples before this span began
            count = np.where(carried, self._freeze_count[k] + idx + 1, idx - start + 1)
            since = np.where(carried, self._freeze_since[k], t[np.maximum(start, 0)])
            frozen = ~new & (count >= recovery.freeze_samples) & (t - since > freeze)
            self._freeze_value[k] = zb[-1].copy()
            self._freeze_since[k], self._freeze_count[k] = float(since[-1]), int(count[-1])
            self._freeze_last_t[k] = float(t[-1])
            if frozen.any():
                if out is z:
                    out = z.copy()
                out[frozen, b.slice] = np.nan
                frozen_any |= frozen
                i = int(np.argmax(frozen))
                firsts.append((i, k, float(since[i])))
        for _, k, since_k in sorted(firsts):
            self.first_freezes.setdefault(k, since_k)
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
        back: list[NDArray[np.intp] | None] = [None] * n
        last = np.empty((n, len(self._imu_rows)))
        for k, (start, stop) in enumerate(self._imu_rows):
            hit = mask[:, start] > 0.0
            last[:, k] = _last_time(t, hit, self._imu_last_valid[k])
            prev = _before(last[:, k], self._imu_last_valid[k])
            returns = hit & (t - prev > window) & (t - first > window)
            for i in np.flatnonzero(returns):
                rows = np.arange(start, stop)
                back[i] = rows if back[i] is None else np.concatenate([back[i], rows])
            self._imu_last_valid[k] = float(last[-1, k])
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
