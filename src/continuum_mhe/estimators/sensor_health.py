"""The estimator a user steps: the sensor-health policy around an inference object.

:class:`Estimator` owns an :class:`~continuum_mhe.estimators.base.Inference` (the MHE's
window solver, the EKF, the UKF) and calls only its narrow interface (``infer``,
``restart``, ``output``, ...). Around each sample it applies the policy that decides
what the inference sees and what its answer is worth: the input's checks, frozen
sensors, gaps and gap resets, IMUs back from a silence, bad starts
(:mod:`.start_check`), a robust MHE's reject resets, the readings' consistency and the
model error they show (:mod:`.consistency`), and the status of each estimate. What the
policy did over a recording is one :class:`~continuum_mhe.results.Diagnostics` value:
``run`` returns a copy with the estimates, and a step-by-step caller reads
:attr:`Estimator.diagnostics`.
"""

from __future__ import annotations

import math
import os
import sys
import time
import warnings
from collections.abc import Callable, Iterable, Iterator
from typing import Generic, TypeVar

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.errors import UnobservableShapeWarning, UserError, expect_type
from continuum_mhe.estimators.base import FloatArray, Inference, tilt_rows
from continuum_mhe.estimators.consistency import ConsistencyCheck
from continuum_mhe.estimators.start_check import StartCheck
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.pcc import shape_rank
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import Diagnostics, Estimate, EstimateSeries, Measurement, Status
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.signals import interrupt_in_chain

#: Statuses of an estimate that would be trusted; ``uncertain`` replaces them where the
#: data do not determine the shape (the others already say more).
TRUSTED = (Status.OK, Status.FALLBACK_IPOPT, Status.BRANCH_RESTART)
#: An IMU silent for longer than this (s) no longer observes its part of the shape when
#: the gap reset is off (else the gap reset's time).
UNOBSERVED_AFTER = 1.0
#: A tilt measurement beyond this (rad) cannot be radians: degrees were given.
DEGREES_LIKE = 2 * math.pi

#: The inference object an :class:`Estimator` owns.
InferenceT = TypeVar("InferenceT", bound=Inference)

__all__ = ["Diagnostics", "Estimator", "bound_notice", "freeze_notice"]


def _reraise_interrupt(exc: BaseException) -> None:
    """A Ctrl-C or SIGTERM that surfaced inside C code as another exception is not a
    numerical failure: raise it again."""
    seen = interrupt_in_chain(exc)
    if seen is not None:
        raise seen


def freeze_notice(new: dict[int, float], freeze_s: float) -> str:
    """One line for sensors newly treated as frozen (``--freeze``): ``new`` maps a
    measurement block (an IMU) to the ``t`` of the first of its repeated readings."""
    same = f"repeated the same reading for more than {freeze_s:g} s"
    if len(new) == 1:
        ((k, t),) = new.items()
        who, repeats = f"IMU {k + 1} {same} from t={t:g} s", "it repeats"
    else:
        each = " and ".join(f"IMU {k + 1} (from t={t:g} s)" for k, t in new.items())
        who, repeats = f"{each} {same}", "they repeat"
    return f"{who}: treated as frozen (a dropout) while {repeats}; --freeze 0 turns this off"


def bound_notice(count: int, n: int, robot: Robot) -> str:
    """One line for ``count`` of ``n`` estimates on a section's ``theta_max`` (status
    ``at-bound``)."""
    bounds = ", ".join(f"{s.theta_max:.4g}" for s in robot.sections)
    return (
        f"{count} of {n} estimates sat on a section's bending bound theta_max ({bounds} rad; "
        "status at-bound): the robot may bend further than that bound allows, and the "
        "bound, not the data, set those shapes; raise theta_max in the robot file (or "
        "--theta-max) if the robot bends so far"
    )


def _outside_stacklevel() -> int:
    """The ``warnings.warn`` stacklevel of the first caller outside this package (a
    warning of the library names the user's line, not ours)."""
    package = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    return level


class Estimator(Generic[InferenceT]):
    """An estimator: ``step(measurement) -> Estimate`` and ``run``, the sensor-health
    policy (:meth:`step`) around the inference object :attr:`inference`.

    Args:
        inference: the filter or window solver (:class:`~.base.Inference`).
        recovery: gap reset, frozen sensors, bad starts, reject resets and the
            ``uncertain`` threshold (default :class:`~continuum_mhe.settings.RecoverySettings`).
    """

    def __init__(self, inference: InferenceT, recovery: RecoverySettings | None = None) -> None:
        expect_type("inference", inference, Inference, "an Inference (MHE, EKF or UKF)")
        #: the filter or window solver this estimator steps
        self.inference: InferenceT = inference
        formulation = inference.formulation
        self.formulation: Formulation = formulation
        #: the estimator's name (``mhe``, ``ekf``, ``ukf``)
        self.name: str = inference.name
        #: whether estimates carry outlier flags (a robust MHE)
        self.flags_outliers: bool = inference.flags_outliers
        #: gap reset, frozen sensors and the ``uncertain`` threshold (see :meth:`step`)
        self.recovery = RecoverySettings() if recovery is None else recovery
        #: what the policy did since the last :meth:`reset` (:class:`Diagnostics`)
        self.diagnostics = Diagnostics()
        #: the IMUs' measurement blocks (the sensor-health checks watch only these)
        self._imu_blocks = tuple(b for b in formulation.measurement_blocks if b.is_imu)
        self._last_t = -math.inf
        self._ran = False  # the last call was run(): a later step needs reset()
        self._rejecting_since: float | None = None  # t of the first of the run
        self._start_check = StartCheck(formulation)
        self._consistency = ConsistencyCheck(formulation)
        # the bad-start check needs a covariance that is one (not the paper's weight W)
        self._checks_start = formulation.calibrated_covariance
        outs = formulation.outputs
        self._tip = [i for i, o in enumerate(outs) if o.section == 0 and o.unit == "m"]
        robot = formulation.robot
        rank, bends = shape_rank(robot), 2 * robot.n_sections
        #: whether the IMUs determine the shape (:meth:`Formulation.imus_determine_shape`;
        #: for PCC robots :func:`~continuum_mhe.model.pcc.shape_rank` equals the number of
        #: bend coordinates); if not, no estimate is ``ok``
        self.shape_observable = formulation.imus_determine_shape(tuple(range(robot.n_imus)))
        #: per IMU ``k``, ``(k, start, stop)`` of its measurement rows
        self._imu_rows = [(k, b.start, b.start + b.size) for k, b in enumerate(self._imu_blocks)]
        self._observable_subsets: dict[tuple[int, ...], bool] = {}
        if not self.shape_observable:
            warnings.warn(
                f"the IMUs of this robot ({robot.describe()}) "
                f"{formulation.unobservable_detail(rank, bends)}: its shape is not "
                f"observable, so every estimate is marked uncertain "
                f"({formulation.observable_hint})",
                UnobservableShapeWarning,
                stacklevel=_outside_stacklevel(),
            )
        self._tilt = tilt_rows(formulation)
        self.reset()

    def reset(self, keep_counts: bool = False) -> None:
        """Forget all samples and, unless ``keep_counts``, zero :attr:`diagnostics` and
        the inference's own counts; the next ``step`` starts a new recording. (The
        estimator's own restarts, within a recording, keep the counts; so does a caller
        that restarts it within one, as ``live`` does.)"""
        if not keep_counts:
            self.diagnostics = Diagnostics()
            self.inference.clear_counts()
        n_blocks = len(self._imu_blocks)
        self._last_t = -math.inf
        self._ran = False
        self._last_valid_t = -math.inf
        self._freeze_value: list[FloatArray | None] = [None] * n_blocks
        self._freeze_since = [-math.inf] * n_blocks
        self._freeze_count = [0] * n_blocks  # consecutive samples with that reading
        self._freeze_last_t = [-math.inf] * n_blocks  # t of each block's previous sample, s
        #: per IMU, t of its last valid reading (s): the IMUs silent for longer than the
        #: gap reset no longer observe their part of the shape
        self._imu_last_valid = [-math.inf] * n_blocks
        self._first_valid_t = -math.inf  # t of the recording's first valid reading, s
        self._start_check.reset()
        self._consistency.reset()
        self._restart()

    def _restart(self) -> None:
        """Clear the inference's state and the bad-start and rejection checks' (a
        (re)start). The consistency check forgets the previous estimate only: the model
        error the readings showed is the robot's, and a restart does not make the model
        follow."""
        self._start_check.clear()
        self._consistency.restart()
        self._rejecting_since = None
        self.inference.restart()

    def _unfreeze(self, m: Measurement) -> Measurement:
        """``m`` with every sensor whose reading has repeated exactly for longer than
        ``recovery.freeze`` seconds, over at least ``recovery.freeze_samples``
        consecutive samples none more than ``recovery.freeze`` s after the one before
        (a gap in the data is not a freeze), marked as dropped out (NaN)."""
        freeze = self.recovery.freeze
        if freeze is None:
            return m
        min_samples = self.recovery.freeze_samples
        z: FloatArray | None = None
        for k, b in enumerate(self._imu_blocks):
            zb = m.z[b.slice]
            last = self._freeze_value[k]
            gap = m.t - self._freeze_last_t[k] > freeze
            self._freeze_last_t[k] = m.t
            if last is None or gap or not np.array_equal(zb, last):  # NaN never repeats
                self._freeze_value[k], self._freeze_since[k] = zb.copy(), m.t
                self._freeze_count[k] = 1
                continue
            self._freeze_count[k] += 1
            # both: two equal readings with a long gap between them are not a freeze
            if self._freeze_count[k] >= min_samples and m.t - self._freeze_since[k] > freeze:
                if z is None:
                    z = m.z.copy()
                z[b.slice] = np.nan
                self.diagnostics.first_freezes.setdefault(k, self._freeze_since[k])
        if z is None:
            return m
        self.diagnostics.frozen_samples += 1
        return Measurement(m.t, z)

    def step(self, measurement: Measurement) -> Estimate:
        """Process one sample and return its estimate. Never raises on solver failure.

        A diverged (non-finite, or far outside the workspace: ``is_diverged``) or
        numerically failed step restarts the inference from this sample's measurement;
        that estimate has status ``"reset"`` (``no-estimate`` if the sample has none).
        ``recovery`` (:class:`~continuum_mhe.settings.RecoverySettings`): a sensor
        frozen longer than ``freeze`` s (over ``freeze_samples`` samples or more) counts
        as dropped out; the first valid sample after more than ``gap_reset`` s without
        one restarts the inference the same way (``reset``), and so do readings
        inconsistent with the estimate within ``bad_start`` s of a (re)start or of an
        IMU's return after a silence of more than ``gap_reset`` (1 s when it is off)
        (:mod:`.start_check`) and, for a robust MHE, a valid reading after every reading
        of more than ``reject_reset`` s was rejected as an outlier (the estimate, not
        the sensor, is taken as lost); an ``ok`` estimate whose tip standard deviation
        exceeds ``uncertain_fraction`` of the robot's length is ``uncertain``, and so is
        every ``ok``, ``fallback-ipopt`` or ``branch-restart`` estimate
        (:data:`TRUSTED`) of a robot whose IMUs do not determine its shape
        (:attr:`shape_observable`), or whose IMUs that reported within the gap reset do
        not (an IMU silent for longer: its part of the shape is predicted blindly), or
        after such an IMU's return until its readings have agreed with the estimate for
        as long (whether ``bad_start`` is set or not); a trusted estimate with a
        section's bend on its ``theta_max`` is ``at-bound``
        (:meth:`~continuum_mhe.model.formulations.Formulation.at_bound`), and one whose
        readings disagree with it beyond their noise is ``inconsistent``
        (:mod:`.consistency`, which also widens ``output_std`` by the model error the
        readings show). The estimate carries ``output_std`` wherever the method has a
        covariance. Each restart and its cause is counted in :attr:`diagnostics`.

        Raises:
            UserError: if ``measurement.z`` does not have the formulation's size, holds
                a tilt angle beyond 2 pi (degrees given for radians), or
                ``measurement.t`` is not finite or not later than the previous
                sample's (time must strictly increase).
        """
        expect_type("measurement", measurement, Measurement, "a Measurement(t, z)")
        t = measurement.t
        nz = self.formulation.nz
        if np.shape(measurement.z) != (nz,):
            raise UserError(
                f"measurement z must have shape ({nz},) for the {self.formulation.name} "
                f"formulation, got {np.shape(measurement.z)}"
            )
        if not (math.isfinite(t) and t > self._last_t):
            hint = ""
            if math.isfinite(t) and self._ran:
                hint = "; run() left the estimator at its recording's end: call reset() first"
            elif math.isfinite(t):
                hint = "; to start a new recording, call reset() first"
            raise UserError(
                f"sample time t={t!r} s must be finite and later than the previous "
                f"sample's t={self._last_t!r} s{hint}"
            )
        self._ran = False
        if self._tilt:
            zl = measurement.z.tolist()
            if any(abs(zl[i]) > DEGREES_LIKE for i in self._tilt):  # NaN compares False
                names = self.formulation.measurement_names
                shown = ", ".join(f"{names[i]}={zl[i]:g}" for i in self._tilt)
                if any(math.isinf(zl[i]) for i in self._tilt):
                    raise UserError(
                        f"measurement at t={t!r} s: {shown}: an infinite angle; a sensor "
                        "that dropped out is NaN"
                    )
                raise UserError(
                    f"measurement at t={t!r} s: {shown}: beyond 2 pi, the angles look like "
                    "degrees; measurements are in radians (numpy.radians converts)"
                )
        self._last_t = t
        start = time.perf_counter()
        inference, diagnostics = self.inference, self.diagnostics
        measurement = self._unfreeze(measurement)
        gap_reset = False
        gap = self.recovery.gap_reset
        mask = self.formulation.measurement_mask(measurement.z)
        if gap is not None and mask.any():
            gap_reset = -math.inf < self._last_valid_t < t - gap
            self._last_valid_t = t
        back = self._note_imus(t, mask)
        observed = self._observed_now(t)
        if gap_reset:  # restart from this sample instead of a blind prediction
            diagnostics.gap_resets += 1
            self._restart()
        elif back is not None and self._checks_start:
            # their part of the shape was predicted blindly: check it as after a start
            self._start_check.reopen(back, self.recovery.gap_reset or UNOBSERVED_AFTER)
        bad_start = False
        window = self.recovery.bad_start
        check_start = self._checks_start and self._start_check.watching(t, window)
        if check_start:
            bad_start = self._start_check.inconsistent(t, measurement.z, mask, window)
            if bad_start:  # the start was wrong: restart from this reading
                diagnostics.bad_starts += 1
                self._restart()
        reject_reset = False
        since, limit = self._rejecting_since, self.recovery.reject_reset
        if since is not None and limit is not None and t - since > limit:
            if mask.any():
                reject_reset = True  # restart from this reading
                diagnostics.reject_resets += 1
                self._restart()
        try:
            with np.errstate(all="ignore"):  # non-finite results are caught below
                state, cov, status = inference.infer(measurement)
            healthy = state is None or not self.formulation.is_diverged(state, cov)
        except (np.linalg.LinAlgError, ArithmeticError, RuntimeError) as exc:
            _reraise_interrupt(exc)
            diagnostics.last_failure = f"{type(exc).__name__}: {exc}"
            healthy = False
        if not healthy:  # flag it and restart from this sample's measurement
            diagnostics.restarts += 1
            self._restart()
            try:
                with np.errstate(all="ignore"):
                    state, cov, status = inference.infer(measurement)
            except (np.linalg.LinAlgError, ArithmeticError, RuntimeError) as exc:
                _reraise_interrupt(exc)
                diagnostics.last_failure = f"{type(exc).__name__}: {exc}"
                state, cov, status = None, None, Status.NO_ESTIMATE
            if state is not None and self.formulation.is_diverged(state, cov):
                self._restart()
                state, cov, status = None, None, Status.NO_ESTIMATE
            if state is not None:
                status = Status.RESET
        if (gap_reset or bad_start or reject_reset) and state is not None:
            status = Status.RESET
        if check_start:
            self._start_check.remember(t, measurement.z, state, cov)
        if status == Status.OK and state is not None and self.formulation.drifted(state):
            status = Status.DRIFTED
        if status in TRUSTED and not observed:
            status = Status.UNCERTAIN  # the data do not determine the shape
        elif status in TRUSTED and self._start_check.unconfirmed:
            status = Status.UNCERTAIN  # an IMU is back and no reading has confirmed the estimate
        elif status in TRUSTED and state is not None and self.formulation.at_bound(state):
            status = Status.AT_BOUND  # the bound, not the data, may have set the shape
            diagnostics.bound_samples += 1
        factor = 1.0
        if self._checks_start:  # the readings against the estimates (.consistency)
            # a reading the robust MHE rejected as an outlier is flagged as one, and
            # says nothing about the estimate
            judged = mask if state is None or not inference.outlier() else np.zeros_like(mask)
            disagree = self._consistency.check(t, measurement.z, judged, state, cov)
            if disagree and status in TRUSTED:
                status = Status.INCONSISTENT
            factor = self._consistency.std_factor
            noise_scale = self._consistency.noise_scale
            if noise_scale > diagnostics.max_noise_scale:
                diagnostics.max_noise_scale = noise_scale
            model_error = self._consistency.model_error
            if model_error > diagnostics.model_error:
                diagnostics.model_error = model_error
        ms = (time.perf_counter() - start) * 1e3
        output = None if state is None else inference.output(state)
        std = None
        if state is not None and cov is not None:
            std = inference.output_std(state, cov)
            if factor != 1.0:  # the model error the readings show (covariance matching)
                std = std * factor
            if status == Status.OK and self._tip and self.formulation.calibrated_covariance:
                sl = std.tolist()  # a few floats: plain Python is faster than numpy here
                tip_std = math.sqrt(sum(sl[i] * sl[i] for i in self._tip))
                if tip_std > self.recovery.uncertain_fraction * self.formulation.robot.length:
                    status = Status.UNCERTAIN
            if self._checks_start:  # constant reading errors, model error: no residual shows them
                bias = self._consistency.constant_error_cov(measurement.z, mask, state)
                std = np.hypot(std, inference.output_std(state, bias))
        outlier = state is not None and inference.outlier()
        # the reject reset's run; a sample without readings (None) neither ends nor extends it
        rejected = state is not None and inference.rejected_every_reading()
        if rejected is False:
            self._rejecting_since = None
        elif rejected and self._rejecting_since is None:
            self._rejecting_since = t
        return Estimate(measurement.t, state, output, cov, status, ms, std, outlier=outlier)

    def freezes_notice(self, before: int) -> str | None:
        """One line for the sensors first treated as frozen after the first ``before``
        of ``diagnostics.first_freezes`` (:func:`freeze_notice`), or None when there are
        none."""
        freeze, first = self.recovery.freeze, self.diagnostics.first_freezes
        if len(first) <= before or freeze is None:
            return None
        return freeze_notice(dict(list(first.items())[before:]), freeze)

    def _note_imus(self, t: float, mask: FloatArray) -> NDArray[np.intp] | None:
        """Update each IMU's last valid time from ``mask`` (nz,) and return the
        measurement rows of the IMUs back at ``t`` after more than the gap reset (1 s
        when it is off) without a valid reading (never having reported counts from the
        recording's first valid reading), or None if none is."""
        first = self._first_valid_t
        if first == -math.inf:
            if not mask.any():
                return None
            first = self._first_valid_t = t
        window = self.recovery.gap_reset or UNOBSERVED_AFTER
        last, back = self._imu_last_valid, None
        for k, start, stop in self._imu_rows:  # plain Python: this runs on every sample
            if mask[start] > 0.0:
                if t - last[k] > window and t - first > window:
                    rows = np.arange(start, stop)
                    back = rows if back is None else np.concatenate([back, rows])
                last[k] = t
        return back

    def _observed_now(self, t: float) -> bool:
        """Whether the IMUs that reported within the gap reset (1 s when it is off) up to
        ``t`` determine the shape (:func:`~continuum_mhe.model.pcc.shape_rank`), from
        each IMU's last valid time (:meth:`_note_imus`)."""
        if not self.shape_observable:
            return False
        blocks = self._imu_blocks
        if len(blocks) == 1:
            return True  # its silence is the whole robot's gap
        last = self._imu_last_valid
        window = self.recovery.gap_reset or UNOBSERVED_AFTER
        recent = tuple(k for k in range(len(blocks)) if t - last[k] <= window)
        if len(recent) == len(blocks) or not recent:
            return True  # all reporting, or none (the gap's dropout rows say it)
        known = self._observable_subsets.get(recent)
        if known is None:
            known = self.formulation.imus_determine_shape(recent)
            self._observable_subsets[recent] = known
        return known

    def run(
        self,
        t: FloatArray,
        z: FloatArray,
        progress: Callable[[Iterable[int]], Iterator[int]] | None = None,
    ) -> EstimateSeries:
        """Estimate over a whole recording (``t`` (n,) s, ``z`` (n, m)), from a reset;
        the series carries a copy of :attr:`diagnostics` (``series.diagnostics``)."""
        try:
            t, z = np.asarray(t, dtype=float), np.asarray(z, dtype=float)
        except (TypeError, ValueError):
            raise UserError("t and z must be arrays of numbers (t (n,) s, z (n, m))") from None
        if t.ndim != 1 or z.ndim != 2:
            raise UserError(f"t must be (n,) and z (n, m); got shapes {t.shape} and {z.shape}")
        if len(t) != len(z):
            raise UserError(f"t has {len(t)} samples but z has {len(z)}")
        self.reset()
        idx: Iterable[int] = range(len(t))
        if progress is not None:
            idx = progress(idx)
        estimates = [self.step(Measurement(float(t[i]), np.asarray(z[i], float))) for i in idx]
        series = EstimateSeries.from_estimates(
            self.name,
            estimates,
            self.formulation.outputs,
            self.flags_outliers,
            self.diagnostics.copy(),
        )
        self._ran = True
        return series
