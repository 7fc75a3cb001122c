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

The policy runs in the compiled core (``continuum_mhe._core.SensorHealth``,
``csrc/sensor_health.*``), one implementation for ``step`` and ``run``: ``run`` steps a
whole recording there into arrays. It steps the fast MHE's and the compiled EKF's steps directly
(:meth:`~.base.Inference.policy_inference`), any other inference through
:class:`PythonInference`, and the formulation's checks of a state as data where the
formulation states them so (:meth:`~continuum_mhe.model.formulations.Formulation.state_checks`).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Generic, NoReturn, SupportsIndex, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray, holds_bools
from continuum_mhe.errors import (
    SampleTimeError,
    UnobservableShapeWarning,
    UserError,
    expect_type,
    is_integer,
    masked_as_missing,
    outside_stacklevel,
    time_text,
)
from continuum_mhe.estimators import start_check
from continuum_mhe.estimators.base import NUMERICAL_FAILURES, Inference, tension_rows, tilt_rows
from continuum_mhe.estimators.consistency import ConsistencyCheck
from continuum_mhe.estimators.process_noise import compiled_process_noise
from continuum_mhe.estimators.reading_units import (
    ReadingUnitsError,
    ReadingUnitsWatch,
    direct_blocks,
    direct_units_problem,
)
from continuum_mhe.io.csv_files import (
    DropoutWarning,
    TimeStepWarning,
    TimeStepWatch,
    check_time_steps,
)
from continuum_mhe.io.input_options import (
    MountingTally,
    MountingWatch,
    OptionWarning,
    check_mounting,
    mounting_checked,
)
from continuum_mhe.io.raw_imu import RAW_IMU_COLUMNS
from continuum_mhe.io.slack_readings import take_slack_readings
from continuum_mhe.io.tensions import TensionsWarning, tension_scale_problem
from continuum_mhe.model.descriptions import tip_position_indices, wrapped_indices
from continuum_mhe.model.formulations import MIN_NOISE_STEP_S, Formulation
from continuum_mhe.model.imu import ROLL_LIMIT
from continuum_mhe.model.pcc import shape_rank
from continuum_mhe.model.robot import Robot, warn_mount_not_applied
from continuum_mhe.quantiles import chi2_quantile
from continuum_mhe.results import Diagnostics, Estimate, EstimateSeries, Measurement, Status
from continuum_mhe.settings import (
    FREEZE_TOLERANCE,
    SILENT_AFTER,
    TENSION_GAP_S,
    RecoverySettings,
)
from continuum_mhe.signals import interrupt_in_chain

#: The unobserved window when the gap reset is off (else the gap reset's time), s: an IMU
#: silent for longer ends the probation of its return, a row within it of a jump or of a
#: wide standard deviation is ``uncertain``, and a reading that old no longer carries its
#: constant error.
UNOBSERVED_AFTER = 1.0
#: A tilt angle beyond this (rad) is out of range, degrees given for radians: every
#: gravity direction is a roll and a pitch within +-pi (a pitch beyond pi/2 with the roll
#: turned by pi is the same direction as its canonical pair, and is taken as it is).
DEGREES_LIKE = ROLL_LIMIT

#: The inference object an :class:`Estimator` owns.
InferenceT = TypeVar("InferenceT", bound=Inference)

#: The statuses by the compiled policy's codes (``_core.STATUS_NAMES``).
STATUSES: tuple[Status, ...] = tuple(
    next(s for s in Status if s.value == name) for name in _core.STATUS_NAMES
)
_CODES = {status.value: code for code, status in enumerate(STATUSES)}


def status_code(status: Status | str) -> int:
    """The compiled policy's code of a status (its index in :data:`STATUSES`)."""
    return _CODES[str(status)]


__all__ = ["Diagnostics", "Estimator", "PythonInference", "freeze_notice"]


def _reraise_interrupt(exc: BaseException) -> None:
    """A Ctrl-C or SIGTERM that surfaced inside C code as another exception is not a
    numerical failure: raise it again."""
    seen = interrupt_in_chain(exc)
    if seen is not None:
        raise seen


def numerical_failure(exc: BaseException) -> str:
    """The policy's message of a numerical failure of an inference step (a Ctrl-C that
    surfaced as one is raised again)."""
    _reraise_interrupt(exc)
    return f"{type(exc).__name__}: {exc}"


def freeze_notice(new: dict[int, float], freeze_s: float) -> str:
    """One line for sensors newly treated as frozen (``--freeze``): ``new`` maps a
    measurement block (an IMU) to the ``t`` of the first of its repeated readings."""
    same = f"repeated the same reading for more than {freeze_s:g} s"
    if len(new) == 1:
        ((k, t),) = new.items()
        who, repeats = f"IMU {k + 1} {same} from t={time_text(t)} s", "it repeats"
    else:
        each = " and ".join(f"IMU {k + 1} (from t={time_text(t)} s)" for k, t in new.items())
        who, repeats = f"{each} {same}", "they repeat"
    return (
        f"{who}: treated as frozen (a dropout) while {repeats}; --freeze 0 turns this off "
        "(RecoverySettings(freeze=None) in Python)"
    )


class PythonInference:
    """The compiled policy's view of an :class:`~.base.Inference` and of its
    formulation's checks of a state (``is_diverged``, ``drifted``, ``at_bound``): the
    methods ``_core.SensorHealth`` calls (``csrc/bind_sensor_health.cpp``). A numerical
    failure of ``infer`` is returned as its message, a Ctrl-C raised again."""

    def __init__(self, inference: Inference) -> None:
        self.inference = inference
        self.formulation = inference.formulation
        self._state: FloatArray | None = None
        self._cov: FloatArray | None = None

    def restart(self, *kept: object) -> None:
        """The inference's restart, with what the policy hands it (``kept_x, kept_P,
        kept_t``: :meth:`~continuum_mhe.estimators.base.Inference.restart`)."""
        self._state = self._cov = None
        self.inference.restart(*kept)  # type: ignore[arg-type]

    def infer(
        self, t: float, z: FloatArray, mask: FloatArray
    ) -> tuple[FloatArray | None, FloatArray | None, int, str | None]:
        """``(state, covariance, status code, None)``, or ``(None, None, 0, message)``
        after a numerical failure."""
        try:
            with np.errstate(all="ignore"):  # non-finite results are the policy's to catch
                state, cov, status = self.inference.infer(Measurement(t, z))
        except NUMERICAL_FAILURES as exc:
            self._state = self._cov = None
            return None, None, 0, numerical_failure(exc)
        self._state, self._cov = state, cov
        return state, cov, status_code(status), None

    def output(self, x: FloatArray) -> FloatArray:
        """The outputs of the state ``x``: the last inferred state's copy (whose outputs
        the inference may hold), or another."""
        last = self._state
        return self.inference.output(last if last is not None and np.array_equal(x, last) else x)

    def output_std(self, x: FloatArray, P: FloatArray, answer: bool) -> FloatArray:
        """Output standard deviations of the last inferred state with covariance ``P``
        (``answer``: its own covariance, which the inference may have them of)."""
        state = x if self._state is None else self._state
        if answer and self._cov is not None:
            P = self._cov
        return self.inference.output_std(state, P)

    def outlier(self) -> bool:
        return self.inference.outlier()

    def bound_free_covariance(self) -> FloatArray | None:
        return self.inference.bound_free_covariance()

    def rejected(self, rows: list[int] | None = None) -> int:
        """:meth:`~.base.Inference.rejected_every_reading` (of the blocks that hold any
        of the reading ``rows``, where given) as 1, 0, or -1 for None."""
        rejected = self.inference.rejected_every_reading(rows)
        return -1 if rejected is None else int(rejected)

    def is_diverged(self, x: FloatArray, P: FloatArray | None) -> bool:
        return self.formulation.is_diverged(x, P)

    def drifted(self, x: FloatArray) -> bool:
        return self.formulation.drifted(x)

    def at_bound(self, x: FloatArray) -> bool:
        return self.formulation.at_bound(x)

    def start_untrusted(self, t: float, z: FloatArray) -> bool:
        return self.inference.start_untrusted(t, z)


#: Why an estimator is not copied (a copy would share its compiled state).
_NOT_COPIED = (
    "an estimator holds compiled state that a copy would share: it cannot be copied or "
    "pickled; make another with make_estimator (and feed it the same samples)"
)


def refuse_tendons_ignored(formulation: Formulation) -> None:
    """Refuse, in one line, a model without tendons of a robot with tendons (a ``bend``
    or ``direct`` formulation of a tendon robot's file): it ignores the tendons' loads,
    the backbone bends off constant curvature under them, and its rows would say ``ok``
    tens of millimetres off. ``load_input`` and ``open_input`` make the tendon
    formulation from such a base, with the tensions; the command line refuses a tendon
    robot without its tensions."""
    robot = formulation.robot
    k = robot.n_tendons if isinstance(robot, Robot) else 0
    if k and formulation.name != "tendon":
        raise UserError(
            f"the robot has {k} tendons, but the {formulation.name} model ignores their "
            "loads (the estimates would be far off and say ok): estimate it with its "
            "tensions, make_formulation('tendon', robot, ...) or load_input / open_input "
            "with InputOptions(tensions=...), which make that model; for the "
            "constant-curvature model, give a Robot without tendons"
        )


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
        refuse_tendons_ignored(formulation)
        self._mount_said = False  # _say_mount_not_applied ran
        self.formulation: Formulation = formulation
        #: the estimator's name (``mhe``, ``ekf``, ``ukf``)
        self.name: str = inference.name
        #: whether estimates carry outlier flags (a robust MHE)
        self.flags_outliers: bool = inference.flags_outliers
        self._recovery = RecoverySettings() if recovery is None else recovery
        #: what the policy did since the last :meth:`reset` (:class:`Diagnostics`); one
        #: object for the estimator's life, which :meth:`reset` zeroes in place
        self.diagnostics = Diagnostics()
        self._ran = False  # the last call was run(): a later step needs reset()
        robot = formulation.robot
        rank, bends = shape_rank(robot), 2 * robot.n_sections
        #: whether the IMUs determine the shape (:meth:`Formulation.imus_determine_shape`;
        #: for PCC robots :func:`~continuum_mhe.model.pcc.shape_rank` equals the number of
        #: bend coordinates); if not, no estimate is ``ok``
        self.shape_observable = formulation.imus_determine_shape(tuple(range(robot.n_imus)))
        if not self.shape_observable:
            warnings.warn(
                f"the IMUs of this robot ({robot.describe()}) "
                f"{formulation.unobservable_detail(rank, bends)}: its shape is not "
                f"observable, so every estimate is marked uncertain "
                f"({formulation.observable_hint})",
                UnobservableShapeWarning,
                stacklevel=outside_stacklevel(),
            )
        self._consistency = ConsistencyCheck(formulation)
        self._direct_rows = direct_blocks(formulation)
        self._tension_rows = tension_rows(formulation)
        # whether a slack tendon's reading below zero was said (once a recording)
        self._slack_said = False
        #: the rows of the tensions and their derivatives (blocks of kind "tension"):
        #: without one, a sample is a dropout as a whole (the IMUs' model needs them)
        self._tension_block_rows = [
            i
            for b in formulation.measurement_blocks
            if b.kind == "tension"
            for i in range(b.start, b.start + b.size)
        ]
        #: the units of the readings that step and continue_run hand over
        self._units = ReadingUnitsWatch(self._direct_rows)
        #: the unit of the times that step and continue_run hand over
        self._time_steps = TimeStepWatch()
        #: the step of the first sample times since a reset, for the inference's
        #: settings (:meth:`~.base.Inference.step_problem`): warned of once a recording
        self._setting_steps = TimeStepWatch()
        #: run's refusal of times that step faster than any IMU stream, once step or
        #: continue_run found it (raised for every later sample until a reset)
        self._too_fast: str | None = None
        #: the first sample times since a reset that judge it (:data:`TOO_FAST_STEPS`
        #: steps), None once judged
        self._fast_times: list[float] | None = []
        #: whether step and continue_run refuse times too fast for seconds; False for a
        #: caller that judges its stream's clock itself, with its own words (``live``:
        #: a device clock that does not run, or runs in microseconds)
        self.refuses_fast_times = True
        #: the robot's mounting against the first readings that step and continue_run
        #: hand over (run checks its whole recording); a command line sets its own,
        #: whose messages name its input and its options
        self.mounting_watch = MountingWatch(formulation)
        self._policy = self._compiled_policy()
        self.reset()

    @property
    def recovery(self) -> RecoverySettings:
        """Gap reset, frozen sensors, bad starts, reject resets and the ``uncertain``
        threshold (see :meth:`step`); setting them starts a new recording (:meth:`reset`)."""
        return self._recovery

    @recovery.setter
    def recovery(self, recovery: RecoverySettings) -> None:
        expect_type("recovery", recovery, RecoverySettings, "a RecoverySettings")
        self._policy.check_idle()  # not while another thread steps samples
        kept, self._recovery = self._recovery, recovery
        try:
            policy = self._compiled_policy()
        finally:
            self._recovery = kept
        self._policy.check_idle()  # (nor if one started while the new one was built)
        self._recovery, self._policy = recovery, policy
        self.reset()

    def _compiled_policy(self) -> _core.SensorHealth:
        """The compiled policy over :attr:`inference` (:class:`PythonInference`)."""
        f, r = self.formulation, self.recovery
        blocks = f.measurement_blocks

        def off(value: float | None) -> float:
            return math.nan if value is None else float(value)

        quantile = start_check.QUANTILE
        compiled = self.inference.policy_inference()
        change = f.change_test()
        change_rows = list(change.rows) if change is not None else []
        change_limit = (
            [math.inf]
            + [chi2_quantile(change.probability, k) for k in range(1, len(change_rows) + 1)]
            if change is not None
            else []
        )
        free = f.free_bends()  # the sections whose bend the IMUs leave free
        #: the policy's Q(dt) and Q^-1, in compiled code (the core caches them per step)
        self.process_noise = compiled_process_noise(f)
        return _core.SensorHealth(
            PythonInference(self.inference) if compiled is None else compiled,
            self._consistency.core,
            nx=f.nx,
            nu=f.nu,
            nz=f.nz,
            ny=f.ny,
            blocks=[(b.start, b.size) for b in blocks],
            imu_blocks=[(b.start, b.size) for b in blocks if b.is_imu],
            tilt_rows=tilt_rows(f),
            tip_rows=list(tip_position_indices(f.outputs)),
            freeze=off(r.freeze),
            freeze_samples=r.freeze_samples,
            gap_reset=off(r.gap_reset),
            # a robust MHE rejects readings that disagree with its estimate (a burst at
            # the start would restart it onto them); its reject reset covers a lost start
            bad_start=off(None if self.flags_outliers else r.bad_start),
            reject_reset=off(r.reject_reset),
            # the formulations whose drift is that of their slowly varying error states
            drift_reset=off(r.drift_reset if f.drift_resets() else None),
            # a tendon robot's tensions missing: no reading is used, and the prediction
            # has no tensions (it leaves the robot within a fraction of a second)
            whole_gap_reset=off(
                min(TENSION_GAP_S, r.gap_reset)
                if r.gap_reset is not None and self._tension_block_rows
                else None
            ),
            uncertain_fraction=r.uncertain_fraction,
            length=f.robot.length,
            # the start and consistency checks need a covariance that is one (not the
            # paper's weight W)
            checks_start=f.calibrated_covariance,
            # an ok row with a tip standard deviation past the robot's length is uncertain
            # where no other test judges a standard deviation (the paper's weight W)
            judges_reach=not f.calibrated_covariance,
            shape_observable=self.shape_observable,
            start_limit=[math.inf] + [chi2_quantile(quantile, k) for k in range(1, f.nz + 1)],
            start_samples=start_check.SAMPLES,
            confirm_samples=start_check.CONFIRM_SAMPLES,
            start_chain=f.bad_start_chain or 0,
            unobserved_after=UNOBSERVED_AFTER,
            degrees_like=DEGREES_LIKE,
            whole_rows=self._tension_block_rows,
            process_noise=self.process_noise,
            inputs=f.input_function,
            observable=lambda imus: f.imus_determine_shape(tuple(imus)),
            checks=f.state_checks(),
            # a covariance's standard deviations (not the paper formulation's weight W,
            # whose position std grows as its model implies)
            std_limit=f.output_std_limit().tolist() if f.calibrated_covariance else [],
            # an estimate held on a bending bound: its bend may lie beyond it
            bound_std_limit=(
                f.output_std_limit(beyond_bound=True).tolist() if f.calibrated_covariance else []
            ),
            # IMUs without gyros: a burst of wrong readings agrees with the estimate that
            # moved onto it (gyros see that it turned nothing)
            jump_hold=all(b.kind == "tilt" for b in blocks if b.is_imu),
            freeze_tolerance=list(FREEZE_TOLERANCE * np.sqrt(np.diag(f.meas_cov()))),
            silent_after=SILENT_AFTER,
            # a robust MHE weighs readings that disagree with its estimate itself
            glitch_factor=0.0 if self.flags_outliers or r.glitch is None else r.glitch,
            change_rows=change_rows,
            change_scale=list(change.scale) if change is not None else [],
            change_psd=list(change.psd) if change is not None else [],
            change_limit=change_limit,
            change_lag=change.lag if change is not None else 0.0,
            # (no reading narrows them)
            free_pairs=[(i, j) for i, j, _ in free],
            free_reach=[reach for _, _, reach in free],
            wrapped_outputs=list(wrapped_indices(f.outputs)),
            # while some IMUs are silent: the bends the others leave free (asked once
            # for each set of silent IMUs)
            free_of=lambda imus: f.free_bends(tuple(imus)),
        )

    def __copy__(self) -> NoReturn:
        raise TypeError(_NOT_COPIED)

    def __deepcopy__(self, memo: object) -> NoReturn:
        raise TypeError(_NOT_COPIED)

    def __reduce_ex__(self, protocol: SupportsIndex) -> NoReturn:
        raise TypeError(_NOT_COPIED)

    def reset(self, keep_counts: bool = False, keep_sensors: bool | None = None) -> None:
        """Forget all samples and, unless ``keep_counts``, zero :attr:`diagnostics` (in
        place: a caller that holds it sees the new recording's counts) and the
        inference's own counts; the next ``step`` starts a new recording. (The
        estimator's own restarts, within a recording, keep the counts and the model
        error the readings showed; so does a caller that restarts it within one, as
        ``live`` does.) ``keep_sensors`` (default
        ``keep_counts``; only with it, else a UserError): the next start keeps what the
        last estimate says of the sensors (the formulation's ``sensor_states``, as a restart after a
        gap does), the same sensors on the same robot; not after a failure that may
        have come from them. A RuntimeError, changing nothing, while another thread
        steps this estimator."""
        expect_type("reset keep_counts", keep_counts, bool, "True or False")
        if keep_sensors is not None:
            expect_type("reset keep_sensors", keep_sensors, bool, "True, False or None")
        if keep_sensors and not keep_counts:
            raise UserError(
                "reset(keep_sensors=True) needs keep_counts=True: the sensors are kept "
                "within one recording (a restart of the same robot), and keep_counts=False "
                "starts a new one"
            )
        self._policy.check_idle()
        self.inference.close_recording()
        if not keep_counts:
            self.diagnostics.clear()
            self.inference.clear_counts()
        self._ran = False
        if not keep_counts:  # a new recording: its units and mounting are checked anew
            self._slack_said = False
            self._units.reset()
            self._time_steps.reset()
            self._setting_steps.reset()
            self._too_fast = None
            self._fast_times = []
            self.mounting_watch.reset()
        keep = keep_counts if keep_sensors is None else keep_sensors
        self._policy.reset(keep_counts, keep_counts and keep)

    def _sync_diagnostics(self) -> None:
        """:attr:`diagnostics` from the compiled policy's counts (the same object)."""
        d, got = self.diagnostics, self._policy.diagnostics
        d.restarts, d.gap_resets = got.restarts, got.gap_resets
        d.frozen_samples, d.bad_starts = got.frozen_samples, got.bad_starts
        d.reject_resets, d.last_failure = got.reject_resets, got.last_failure
        d.bound_samples, d.bad_start_chains = got.bound_samples, got.bad_start_chains
        d.max_noise_scale, d.model_error = got.max_noise_scale, got.model_error
        d.untrusted_start_samples = got.untrusted_start_samples
        d.glitches = got.glitches
        d.drift_resets, d.late_imu_starts = got.drift_resets, got.late_imu_starts
        d.jump_resets = got.jump_resets
        d.first_jump = (got.first_jump_t, got.first_jump_step) if got.jump_resets else None
        for k, t in got.first_freezes[len(d.first_freezes) :]:
            d.first_freezes[k] = t
        self.inference.sync_counts()

    def _say_mount_not_applied(self) -> None:
        """Readings in the sensors' frames, handed over without the conversion that turns
        them by ``mount_rpy`` (:func:`~continuum_mhe.model.robot.warn_mount_not_applied`,
        naming the user's line): said at the first samples handed over, by which a caller
        that converts each sample before stepping it has converted one."""
        if not self._mount_said:
            self._mount_said = True
            warn_mount_not_applied(self.formulation.robot, stacklevel=outside_stacklevel() + 1)

    def step(self, measurement: Measurement) -> Estimate:
        """Process one sample and return its estimate. Never raises on solver failure.

        Restarts (status ``reset``; ``no-estimate`` if the sample has none), each counted
        with its cause in :attr:`diagnostics`:

        - a diverged step (non-finite, or far outside the workspace: ``is_diverged``) or
          a numerically failed one restarts the inference from this sample's
          measurement;
        - the first valid sample after more than ``recovery.gap_reset`` s without one;
        - with the gap reset on, the first reading of an IMU that had not read since the
          last (re)start, given beside every IMU that had (a log whose IMUs start
          apart; the start was made without its part of the shape);
        - readings inconsistent with the estimate within ``recovery.bad_start`` s of a
          (re)start or of an IMU's return after a silence of more than ``gap_reset``
          (1 s when it is off) (:mod:`.start_check`). Not for a robust MHE, which
          rejects such readings as outliers; a formulation's ``bad_start_chain`` such
          restarts in a row, each contradicted in turn, end them until one holds;
        - for a robust MHE, a valid reading after every reading of more than
          ``recovery.reject_reset`` s was rejected as an outlier (the estimate, not the
          sensor, is taken as lost).

        A sensor frozen longer than ``recovery.freeze`` s (over ``freeze_samples``
        samples or more) counts as dropped out
        (:class:`~continuum_mhe.settings.RecoverySettings`).

        Statuses other than ``ok``:

        - ``uncertain``: an ``ok`` estimate whose reported tip standard deviation (the
          readings' constant errors in it) exceeds ``uncertain_fraction`` of the
          robot's length, or whose own one (without them) did within the unobserved
          window (a formulation whose covariance is no noise model, the paper's
          weight ``W``: whose reported tip standard deviation is past the robot's
          length); and every
          trusted estimate (``ok``, ``fallback-ipopt``, ``branch-restart``) of a robot
          whose IMUs do not determine its shape (:attr:`shape_observable`), or whose
          IMUs that reported within :data:`~continuum_mhe.settings.SILENT_AFTER` (the gap
          reset where shorter)
          do not (an IMU silent for longer: its part of the shape is predicted blindly),
          or after the return of an IMU silent for longer than the gap reset until
          its readings have agreed with the estimate for as long (whether ``bad_start``
          is set or not), or while four or more restarts that the readings forced fall
          within ``bad_start`` (or the unobserved window where longer, or without the
          check); a frozen IMU's silence counts from the freeze's start; and on a tendon
          robot every estimate of a start whose first reading showed a tip load it could
          not tell from the IMUs' errors (:mod:`.load_hypotheses`), until the next
          restart;
        - ``at-bound``: a trusted estimate with a section's bend on its ``theta_max``
          (:meth:`~continuum_mhe.model.formulations.Formulation.at_bound`);
        - ``inconsistent``: one whose readings disagree with it beyond their noise
          (:mod:`.consistency`, which also widens ``output_std`` by the model error the
          readings show).

        The estimate carries ``output_std`` wherever the method has a covariance, and
        its outputs' names (:meth:`~continuum_mhe.results.Estimate.value`). Sample
        times whose first steps after a reset exceed 2 s (milliseconds given for
        seconds: every step a gap that restarts the estimate) are warned of once, a
        :class:`~continuum_mhe.io.csv_files.UnitWarning`; so are settings the inference
        cannot follow at their median step (a UKF's start rate prior that spreads its
        sigma points past its tilt chart:
        :meth:`~continuum_mhe.estimators.kalman.UnscentedKalmanInference.step_problem`),
        an :class:`~continuum_mhe.io.input_options.OptionWarning`.

        Raises:
            UserError: if ``measurement.z`` does not have the formulation's size, holds
                an infinite value (a missing reading is NaN), a negative tension, a tilt
                angle beyond pi (:data:`DEGREES_LIKE`: degrees given for radians), a raw
                IMU's
                specific force that is not a unit vector (each IMU's first full reading
                after a reset is checked) or a gyro in deg/s (the median of each IMU's
                first full readings after a reset, of samples not refused, at least
                :data:`~continuum_mhe.io.raw_units.UNIT_CHECK_SAMPLES` over at least a
                second: the samples before are estimated; then the turns of its motion,
                :class:`~.reading_units.ReadingUnitsWatch`; ``run`` checks the whole
                recording; both a :class:`~.reading_units.ReadingUnitsError`, raised
                again for every later sample until a reset), times whose first
                :data:`TOO_FAST_STEPS` steps after a reset have a median under
                :data:`~continuum_mhe.model.formulations.MIN_NOISE_STEP_S` (not
                seconds: ``run`` refuses a recording whose median step is; a
                ``ReadingUnitsError`` too, from the sample that ends them on until a
                reset; a burst of rows a few microseconds apart at a stream's start
                is not enough), or
                ``measurement.t`` is not finite or not later than the previous
                sample's (time must strictly increase).
            ~continuum_mhe.io.input_options.MountingError: at the
                :data:`~continuum_mhe.io.input_options.MOUNTING_START_SAMPLES`-th sample
                after a reset, where the first readings put the robot the other way up
                (as :meth:`run` checks a recording's: a
                :class:`~continuum_mhe.io.input_options.MountingWarning` where they start
                bent past 100 degrees, 90 and ``MOUNTING_MARGIN``), and for every later
                sample until a reset.
        """
        expect_type("measurement", measurement, Measurement, "a Measurement(t, z)")
        if measurement.labels is not None:
            self._check_labels("the measurement's labels", list(measurement.labels))
        t = measurement.t
        nz = self.formulation.nz
        if np.shape(measurement.z) != (nz,):
            raise UserError(
                f"measurement z must have shape ({nz},) for the {self.formulation.name} "
                f"formulation, got {np.shape(measurement.z)}"
            )
        z = np.ascontiguousarray(measurement.z, dtype=np.float64)
        self._say_mount_not_applied()
        times = np.array([t], dtype=float)  # the one sample's, for the stream's checks
        self._refuse_too_fast(times, "step")
        if self._tension_rows:
            z = self._check_tensions(z[None, :], times, stacklevel=3)[0]
        if not self._units.done:
            # a sample the policy refuses is no reading of the stream: its refusal first,
            # before the first readings' check counts it (the motion's check leaves out
            # the samples refused)
            if self._units.judging_first:
                self._refuse_before_stepping(times, z[None, :])
            problem = self._units.see(times, z[None, :])
            if problem is not None:
                raise ReadingUnitsError(problem)
        if self.mounting_watch.error is not None:  # the robot is still the other way up
            raise self.mounting_watch.error
        r = self._policy.step(t, z)
        if r.input_error:
            self._refuse(r.input_error, t, z)
        status = STATUSES[r.status]
        if not self.mounting_watch.done:  # a sample the policy took, not one it refused
            self.mounting_watch.see(z[None, :], "step")
        if not self._time_steps.done:
            self._warn_time_unit(times, "step")
        if not self._setting_steps.done:
            self._warn_step_problem(times, "step")
        self._ran = False
        if r.diagnostics_changed:
            self._sync_diagnostics()
        else:
            self.inference.sync_counts()
        return Estimate(
            t, r.state, r.output, r.covariance, status, r.solve_ms, r.output_std,
            outlier=r.outlier, outputs=self.formulation.outputs,
        )  # fmt: skip

    def _check_tensions(self, z: FloatArray, t: FloatArray, stacklevel: int = 4) -> FloatArray:
        """``z`` (n, nz) at the times ``t`` (n,) s with a slack tendon's tension read
        below zero taken as 0 (a copy where one is; said once until a reset, a
        :class:`~continuum_mhe.io.tensions.TensionsWarning`); a :class:`UserError` for
        the first tension further below zero (:mod:`~continuum_mhe.io.slack_readings`),
        and for tensions that would bend a section through turns on their own (mN given
        for N), as the tensions file's reader gives them. ``stacklevel``: the warning's,
        the caller of ``step`` (3) or of ``run`` (4, through ``_samples``)."""
        names = self.formulation.measurement_names
        tensions = z[:, self._tension_rows]
        taken = take_slack_readings(tensions)
        negative = np.argwhere(taken.too_negative & np.isfinite(tensions))  # -inf: infinite
        if len(negative):
            i, j = negative[0]
            row = self._tension_rows[j]
            raise UserError(
                f"measurement at t={float(t[i])!r} s: {names[row]} = {z[i, row]:g} N is "
                "negative: a tendon cannot push (a slack tendon's tension is 0; its load "
                f"cell may read down to -{taken.limit[i]:.3g} N there, taken as 0)"
            )
        if taken.count:
            z = z.copy()
            z[:, self._tension_rows] = taken.values
            if not self._slack_said:
                self._slack_said = True
                first = int(np.flatnonzero(taken.slack.any(axis=1))[0])
                warnings.warn(
                    taken.said(
                        "the measurements' tensions",
                        f"t = {time_text(float(t[first]))} s",
                        once=len(t) == 1,  # a step's: the first of those to come
                    ),
                    TensionsWarning,
                    stacklevel=stacklevel,
                )
        robot = getattr(self.formulation, "robot", None)
        if isinstance(robot, Robot):  # (an infinite tension is the policy's to refuse)
            finite = np.where(np.isfinite(tensions), tensions, np.nan)
            problem = tension_scale_problem(robot, t, finite, "the measurements' tensions")
            if problem is not None:
                raise UserError(problem)
        return z

    def _check_units(self, t: FloatArray, z: FloatArray) -> None:
        """A :class:`UserError` where the ``direct`` IMU readings of a whole recording
        ``z`` (n, nz) at the times ``t`` (n,) s are not a unit specific force and rad/s
        (:mod:`.reading_units`)."""
        problem = direct_units_problem(self._direct_rows, z, t=t)
        if problem is not None:
            raise ReadingUnitsError(problem)

    def _refuse(
        self, err: _core.InputProblem, t: float, z: FloatArray, previous: float | None = None
    ) -> None:
        """Raise the :class:`UserError` of a sample the policy refused (``err``, its
        input error: the time order, a :class:`SampleTimeError`, or a tilt in degrees or
        infinite); ``previous``: the time of the sample before it in the same call (else
        the policy's last)."""
        if err == _core.InputProblem.TIME:
            last, hint = (self._policy.last_t if previous is None else previous), ""
            first = previous is None and math.isfinite(t)  # the call's first sample
            if first and self._ran:
                hint = "; run() left the estimator at its recording's end: call reset() first"
            elif first and math.isfinite(last) and last - t > (self.recovery.gap_reset or 1.0):
                hint = (
                    f"; the sample before it is {last - t:g} s later: if this sample's time "
                    "is the wrong one, leave it out and step on; if that sample's was, or "
                    "the clock stepped back, every later sample is refused against it until "
                    "reset() (reset(keep_counts=True) within one recording)"
                )
            elif first:
                hint = (
                    "; a sample that came late or twice is to be left out (the estimator is "
                    "as it was: step on), a new recording starts with reset()"
                )
            if not math.isfinite(t) and not math.isfinite(last):  # no sample before it
                raise SampleTimeError(f"sample time t={t!r} s must be finite")
            raise SampleTimeError(
                f"sample time t={t!r} s must be finite and later than the previous "
                f"sample's t={last!r} s{hint}"
            )
        names, zl = self.formulation.measurement_names, z.tolist()
        if err == _core.InputProblem.INFINITE:
            infinite = ", ".join(f"{names[i]}={v:g}" for i, v in enumerate(zl) if math.isinf(v))
            raise UserError(
                f"measurement at t={t!r} s: {infinite}: an infinite value; a reading that "
                "is not there (a sensor that dropped out) is NaN"
            )
        shown = ", ".join(f"{names[i]}={zl[i]:g}" for i in tilt_rows(self.formulation))
        raise UserError(
            f"measurement at t={t!r} s: {shown}: beyond pi, out of range: degrees? "
            "measurements are in radians (numpy.radians converts); a reading that is not "
            "there is NaN"
        )

    def freezes_notice(self, before: int) -> str | None:
        """One line for the sensors first treated as frozen after the first ``before``
        of ``diagnostics.first_freezes`` (:func:`freeze_notice`), or None when there are
        none."""
        freeze, first = self.recovery.freeze, self.diagnostics.first_freezes
        if len(first) <= before or freeze is None:
            return None
        return freeze_notice(dict(list(first.items())[before:]), freeze)

    def run(
        self,
        t: ArrayLike,
        z: ArrayLike,
        progress: Callable[[Iterable[int]], Iterator[int]] | None = None,
    ) -> EstimateSeries:
        """Estimate over a whole recording (``t`` (n,) s; ``z`` (n, nz), the readings in
        the order of the formulation's ``measurement_names``, in their units: rad for
        tilt; for raw IMUs (the direct model) the unit specific force ``f/|f|`` and
        rad/s, in each IMU's disk frame, as :func:`~continuum_mhe.io.raw_measurements`
        gives them (not the accelerometer's m/s^2); N for tensions; NaN or a masked entry of a
        numpy masked array is a reading missing, a dropout), from a reset,
        in the compiled policy, which steps each block without holding the GIL (other
        Python threads go on; another thread's call into this estimator meanwhile is a
        RuntimeError; ``progress`` is shown per block of samples); the series carries a
        copy of :attr:`diagnostics` (``series.diagnostics``).

        The first readings are checked against the robot's ``mounting`` as a recording's
        reader checks them (:func:`~continuum_mhe.io.input_options.check_mounting`): a
        :class:`UserError` where gravity says the robot is mounted the other way, a
        :class:`~continuum_mhe.io.input_options.MountingWarning` where it starts bent past
        100 degrees (90 and ``MOUNTING_MARGIN``) or an IMU reads as if mounted upside
        down; not again for the array
        that :func:`~continuum_mhe.io.inputs.load_input` read, which it checked for the
        same robot."""
        if progress is not None and not callable(progress):
            raise UserError(
                "progress must be a callable that wraps an iterable and yields its items "
                f"(such as tqdm.tqdm), got {progress!r}"
            )
        checked = mounting_checked(z, self.formulation.robot)  # read whole and checked
        t, z = self._samples(t, z)
        self._say_mount_not_applied()
        check_time_steps(  # milliseconds for seconds: every step a gap that restarts it
            "run", "t advances", t,
            "t must be in seconds (milliseconds? every step longer than the gap reset "
            "restarts the estimate)",
            "t must be in seconds",
        )  # fmt: skip
        too_fast = too_fast_problem("run", t)
        if too_fast is not None:
            raise ReadingUnitsError(too_fast)
        self._check_units(t, z)
        # the first readings against the robot's mounting, as a recording's reader checks
        # them (where it has not: load_input's): a robot described the wrong way up fits
        # them bent past 90 degrees
        if not checked:
            check_mounting("run", z, self.formulation, python=True)
            tally = MountingTally(self.formulation)  # and the whole recording's readings
            tally.add(z)
            tally.warn("run", python=True)
        self.reset()
        self._time_steps.done = True  # the whole recording's times were checked above
        self.mounting_watch.done = True  # and its mounting: a continue_run goes on from it
        self._refuse_before_stepping(t, z)
        self._warn_step_problem(t, "run")
        n = len(t)
        block = RUN_BLOCK if progress is not None else max(n, 1)
        starts: Iterable[int] = range(0, n, block)
        if progress is not None:
            starts = progress(starts)
        batch = self._step_blocks(t, z, starts, block)
        self._ran = True
        no_estimate = STATUSES.index(Status.NO_ESTIMATE)
        if n and bool((batch.status == no_estimate).all()):
            settings = getattr(self.inference, "settings", None)
            horizon = getattr(settings, "horizon", 0)
            why = (
                "every reading is missing (NaN: a dropout)"
                if not np.isfinite(z).any()
                else f"paper_start makes no estimate before the window's horizon of {horizon} "
                "samples is full: give a shorter horizon or leave paper_start out"
                if getattr(settings, "paper_start", False) and horizon > n
                else "see series.diagnostics"
            )
            warnings.warn(
                f"run: none of the {n} samples gave an estimate (every status no-estimate): {why}",
                DropoutWarning,
                stacklevel=2,
            )
        return EstimateSeries(
            method=self.name,
            t=t.copy(),
            output=batch.output,
            status=np.array([str(STATUSES[c]) for c in batch.status], dtype=str),
            solve_ms=batch.solve_ms,
            outputs=self.formulation.outputs,
            output_std=batch.output_std,
            outlier=batch.outlier if self.flags_outliers else None,
            diagnostics=self.diagnostics.copy(),
        )

    def _check_labels(self, what: str, got: list[str]) -> None:
        """A :class:`UserError` where labelled readings (``what``: a DataFrame's columns,
        a Series's index) are not the formulation's readings in its order: the same
        names in another order, other names (raw accelerometer and gyro columns, or a
        name that says degrees), or another count. Unlabelled values (a numpy array)
        are taken in the formulation's order."""
        want = list(self.formulation.measurement_names)
        if got == want:
            return
        name = self.formulation.name
        if sorted(got) == sorted(want):
            raise UserError(
                f"{what} are {', '.join(got)}; the {name} formulation "
                f"reads {', '.join(want)} in that order (z[{want!r}])"
            )
        raw = bool(got) and all(  # a raw IMU file's columns (ax, gz_2)
            g in RAW_IMU_COLUMNS.names or RAW_IMU_COLUMNS.number(g)[1] > 0 for g in got
        )
        hint = (
            "raw accelerometer and gyro readings become its readings with "
            "continuum_mhe.io.inputs.raw_measurements (each IMU's mount_rpy and gyro_bias "
            "applied)"
            if raw
            else f"name them so, or give the values alone (z.to_numpy()) to pass {len(want)} "
            "readings a sample in that order"
        )
        raise UserError(
            f"{what} are {', '.join(got)}; the {name} formulation reads "
            f"{len(want)} readings a sample, {', '.join(want)}: {hint}"
        )

    def _samples(self, t: ArrayLike, z: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """``t`` (n,) and ``z`` (n, nz) as C-contiguous float64 arrays, or a
        :class:`UserError` naming what does not fit (a table whose columns are the
        formulation's readings in another order, too)."""
        labels = getattr(z, "columns", None)  # a pandas DataFrame's (numpy drops them)
        if labels is not None:
            self._check_labels("z's columns", [str(c) for c in labels])
        if np.asarray(t).dtype.kind in "mM":  # datetime64, timedelta64: not seconds
            raise UserError(
                "t must be seconds (numbers), got numpy datetime or timedelta values: give "
                "(t - t[0]) / np.timedelta64(1, 's')"
            )
        nz = self.formulation.nz
        if z is None:
            raise UserError(f"z is None: give the readings, an array (n, {nz})")
        if t is None:
            raise UserError("t is None: give the sample times, an array (n,) of seconds")
        for name, values in (("t", t), ("z", z)):  # numpy would read True as 1, "0.1" as 0.1
            try:
                kind = np.asarray(values).dtype.kind
            except ValueError:  # rows of different lengths (a ragged list)
                raise UserError(
                    f"{name} must be an array (t (n,) s, z (n, {nz})): its rows differ in length"
                ) from None
            bools = holds_bools(values)  # all bools, or bools among numbers
            if bools or kind in "SU":
                held = (
                    "bool values (True, False)" if bools else f"{np.asarray(values).dtype} values"
                )
                raise UserError(
                    f"t and z must be arrays of numbers (t (n,) s, z (n, m)); {name} holds {held}"
                )
        if np.iscomplexobj(t) or np.iscomplexobj(z):  # numpy would drop the imaginary part
            raise UserError(
                "t and z must be arrays of real numbers (t (n,) s, z (n, m)), got complex"
            )
        try:  # masked or pandas' missing entries are NaN (such a t is refused: not finite)
            t = np.ascontiguousarray(masked_as_missing(t), dtype=np.float64)
            z = np.ascontiguousarray(masked_as_missing(z), dtype=np.float64)
        except (TypeError, ValueError):
            raise UserError("t and z must be arrays of numbers (t (n,) s, z (n, m))") from None
        if t.ndim != 1 or z.ndim != 2:
            raise UserError(f"t must be (n,) and z (n, {nz}); got shapes {t.shape} and {z.shape}")
        if len(t) != len(z):
            transposed = (
                f": z is ({nz}, n), transposed? (z.T gives rows)" if z.shape == (nz, len(t)) else ""
            )
            raise UserError(
                f"t has {len(t)} samples but z has {len(z)} (z's shape {z.shape}, a row of "
                f"{nz} readings a sample expected){transposed}"
            )
        if z.shape[1] != nz:
            raise UserError(
                f"z must have shape (n, {nz}) for the {self.formulation.name} formulation "
                f"(a row of {nz} readings a sample), got {z.shape}"
            )
        if self._tension_rows:
            z = self._check_tensions(z, t)
        return t, z

    def continue_run(
        self,
        t: ArrayLike,
        z: ArrayLike,
        starts: Iterable[int] | None = None,
        block: int | None = None,
        check_units: bool = True,
        should_stop: Callable[[], bool] | None = None,
        check_mounting_start: bool = True,
    ) -> Batch:
        """Step the samples ``t`` (n,) s, ``z`` (n, nz) on from the last one, in the
        compiled policy, ``block`` samples per call (a positive integer) from each of
        ``starts`` (default: all in one call; else ``range(0, n, block)`` in order,
        which a progress display may wrap: the blocks must cover every sample once, in
        order); raises the :class:`UserError` of :meth:`step` for a refused sample
        before any sample of the call is stepped (and for readings in the wrong units,
        checked as :meth:`step` checks them unless ``check_units`` is False (a caller
        that checked them itself), before any sample of the call; unless it is False,
        sample times that step like milliseconds are warned of as :meth:`step` warns,
        and times that step faster than any IMU stream are refused as :meth:`step`
        refuses them), and one for arrays whose shapes do not fit (as :meth:`run`), a
        ``block`` that
        is not a positive integer, or ``starts`` that skip, repeat or leave out
        samples. The first readings since a reset are checked against the robot's
        mounting as :meth:`step` checks them, unless ``check_mounting_start`` is False
        (a caller that checked them itself). ``should_stop()`` (a caller's signal flag,
        say) is asked before the
        first sample and then every 10 ms or so, between two samples: once it says True
        the call returns the samples stepped so far (a shorter batch; the next call goes
        on from there)."""
        t, z = self._samples(t, z)
        self._say_mount_not_applied()
        if check_units:
            self._refuse_too_fast(t, "continue_run")
        if block is not None and not (is_integer(block) and block >= 1):
            raise UserError(f"continue_run: block must be a positive integer, got {block!r}")
        if starts is not None and block is None:
            raise UserError(
                "continue_run: starts needs block (the samples stepped from each start)"
            )
        self._refuse_before_stepping(t, z)  # before the unit check counts what it refuses
        if check_units and not self._units.done:
            problem = self._units.see(t, z)
            if problem is not None:
                raise ReadingUnitsError(problem)
        self._warn_step_problem(t, "continue_run")
        if check_mounting_start:  # (at once where its samples are in and checked)
            self.mounting_watch.see(z, "continue_run")
        if check_units:
            self._warn_time_unit(t, "continue_run")
        if should_stop is not None and not callable(should_stop):
            raise UserError(
                f"continue_run: should_stop must be a function that says when to stop, got "
                f"{should_stop!r:.40}"
            )
        size = max(len(t), 1) if block is None else int(block)
        if isinstance(starts, (Sequence, np.ndarray)):  # checked before any is stepped
            _check_starts(starts, len(t), size)  # (an iterator, a progress display's, as stepped)
        starts = range(0, len(t), size) if starts is None else starts
        return self._step_blocks(t, z, starts, size, should_stop)

    def _refuse_too_fast(self, t: FloatArray, what: str) -> None:
        """The :class:`~.reading_units.ReadingUnitsError` of :meth:`run` for times that
        step faster than any IMU stream (:func:`too_fast_problem`), judged on the first
        :data:`TOO_FAST_STEPS` steps handed over since a reset (``what``: the method
        called), before the samples ``t`` are stepped; raised again for every later
        sample until a reset (a new recording)."""
        times = self._fast_times
        if times is not None and self.refuses_fast_times:
            for v in t:  # (a time not after the last, or not finite, is refused elsewhere)
                if len(times) > TOO_FAST_STEPS:
                    break
                if math.isfinite(v) and (not times or float(v) > times[-1]):
                    times.append(float(v))
            if len(times) > TOO_FAST_STEPS:
                self._too_fast = too_fast_problem(what, np.asarray(times))
                self._fast_times = None
        if self._too_fast is not None:
            raise ReadingUnitsError(self._too_fast)

    def _warn_time_unit(self, t: FloatArray, what: str) -> None:
        """A :class:`~continuum_mhe.io.csv_files.TimeStepWarning` (``what: ...``, the method
        called), once a recording, where the first sample times handed over step like
        milliseconds (as :meth:`run` warns of a whole recording)."""
        if not self._time_steps.done:
            problem = self._time_steps.see(t, what)
            if problem is not None:
                warnings.warn(problem, TimeStepWarning, stacklevel=3)

    def _warn_step_problem(self, t: FloatArray, what: str) -> None:
        """An :class:`~continuum_mhe.io.input_options.OptionWarning` (``what: ...``, the
        method called), once a recording, where the inference cannot follow its settings
        at the median step of the first sample times handed over
        (:meth:`~.base.Inference.step_problem`); not where that step is a gap that
        restarts the estimate at every sample (``recovery.gap_reset``), which predicts
        across none."""
        watch = self._setting_steps
        if watch.done:
            return
        watch.see(t, what)
        gap = self.recovery.gap_reset
        if watch.step is not None and (gap is None or watch.step <= gap):
            problem = self.inference.step_problem(watch.step)
            if problem is not None:
                warnings.warn(f"{what}: {problem}", OptionWarning, stacklevel=3)

    def _refuse_before_stepping(self, t: FloatArray, z: FloatArray) -> None:
        """The :class:`UserError` of the first sample of ``t``, ``z`` that the policy
        would refuse (a time not after the one before, an infinite reading, a tilt in
        degrees), raised before any sample is stepped: a refusal in the middle of a
        call would leave the samples before it stepped but not returned."""
        previous = np.concatenate([[self._policy.last_t], t[:-1]])
        late = ~(np.isfinite(t) & (t > previous))
        infinite = np.asarray(np.isinf(z).any(axis=1), dtype=bool)
        rows = tilt_rows(self.formulation)
        degrees = np.zeros(len(t), dtype=bool)
        if rows:
            degrees = np.asarray((np.abs(z[:, rows]) > DEGREES_LIKE).any(axis=1), dtype=bool)
        bad = late | infinite | degrees
        if bad.any():
            i = int(np.argmax(bad))
            err = (
                _core.InputProblem.TIME if late[i]
                else _core.InputProblem.INFINITE if infinite[i]
                else _core.InputProblem.DEGREES
            )  # fmt: skip
            self._refuse(err, float(t[i]), z[i], None if i == 0 else float(previous[i]))

    def _step_blocks(
        self,
        t: FloatArray,
        z: FloatArray,
        starts: Iterable[int],
        size: int,
        should_stop: Callable[[], bool] | None = None,
    ) -> Batch:
        """:meth:`continue_run` on arrays already checked (:meth:`_samples`): ``size``
        samples per call from each of ``starts``, up to where ``should_stop()`` says
        True."""
        n, ny = len(t), self.formulation.ny
        batch = Batch(
            status=np.zeros(n, dtype=np.int32),
            solve_ms=np.zeros(n),
            outlier=np.zeros(n, dtype=np.bool_),
            frozen=np.zeros(n, dtype=np.bool_),
            output=np.empty((n, ny)),
            output_std=np.empty((n, ny)),
        )
        u8 = np.uint8
        done = 0  # the samples stepped: each block starts where the last one ended
        for i in starts:
            done = j = _next_block(i, done, n, size)
            stop, err = self._policy.run(
                t[i:j], z[i:j], batch.status[i:j], batch.solve_ms[i:j],
                batch.outlier[i:j].view(u8), batch.frozen[i:j].view(u8),
                batch.output[i:j], batch.output_std[i:j], should_stop,
            )  # fmt: skip
            self._sync_diagnostics()
            if err:
                self._refuse(err, float(t[i + stop]), z[i + stop])
            if stop < j - i:  # should_stop said so: the samples stepped
                return batch.head(i + stop)
        _check_covered(done, n)
        return batch


#: Steps after a reset whose median ``step`` and ``continue_run`` judge against
#: :data:`~continuum_mhe.model.formulations.MIN_NOISE_STEP_S` (``run`` judges a whole
#: recording's): enough that a burst of rows stamped microseconds apart at a stream's
#: start (a serial buffer read at once) does not decide it.
TOO_FAST_STEPS = 100


def too_fast_problem(what: str, t: FloatArray) -> str | None:
    """The one-line refusal (``what: t advances by a median of ...``) of sample times
    ``t`` (s, increasing, at least 3) whose median step is below
    :data:`~continuum_mhe.model.formulations.MIN_NOISE_STEP_S`: no IMU stream is that
    fast, so the times are in a unit other than seconds; None where they are not."""
    if len(t) >= 3 and 0 < (step := float(np.median(np.diff(t)))) < MIN_NOISE_STEP_S:
        return (
            f"{what}: t advances by a median of {step:g} s per sample ({1 / step:.3g} "
            "samples per second): t must be in seconds"
        )
    return None


def _next_block(i: object, done: int, n: int, size: int) -> int:
    """The end of the block of :meth:`Estimator.continue_run` that starts at ``i``,
    where sample ``done`` is next of ``n``, or a :class:`UserError`: a block that does not
    start there."""
    if not is_integer(i) or i != done or i >= n:
        raise UserError(
            f"continue_run: the blocks must cover the {n} samples in order, {size} at a "
            f"time from 0 (starts range(0, n, block)): a block starts at {i!r} where "
            f"sample {done} is next"
        )
    return min(int(i) + size, n)


def _check_covered(done: int, n: int) -> None:
    """A :class:`UserError` where the blocks stepped fewer than the ``n`` samples."""
    if done != n:
        raise UserError(
            f"continue_run: the blocks stepped the first {done} of the {n} samples: the "
            "starts must cover every sample (range(0, n, block))"
        )


def _check_starts(starts: Iterable[object], n: int, size: int) -> None:
    """The blocks of :meth:`Estimator.continue_run` from ``starts`` (a sequence), checked
    as stepping them checks them, before any is stepped."""
    done = 0
    for i in starts:
        done = _next_block(i, done, n, size)
    _check_covered(done, n)


#: Samples per call into the compiled policy when ``run`` shows its progress.
RUN_BLOCK = 256


@dataclass
class Batch:
    """Samples stepped by :meth:`Estimator.continue_run`: per sample its status code
    (an index into :data:`STATUSES`; :meth:`statuses` gives the ``Status`` values, which
    compare equal to their strings), solve time (ms), outlier and frozen flags, outputs
    (in the formulation's ``outputs`` order) and their standard deviations (NaN where
    there are none)."""

    status: NDArray[np.int32]
    solve_ms: FloatArray
    outlier: NDArray[np.bool_]
    frozen: NDArray[np.bool_]
    output: FloatArray
    output_std: FloatArray

    def head(self, n: int) -> Batch:
        """The first ``n`` samples' results (views)."""
        return Batch(
            self.status[:n], self.solve_ms[:n], self.outlier[:n], self.frozen[:n],
            self.output[:n], self.output_std[:n],
        )  # fmt: skip

    def statuses(self) -> list[Status]:
        """The statuses as :class:`~continuum_mhe.results.Status` values."""
        return [STATUSES[c] for c in self.status.tolist()]

    def status_strings(self) -> NDArray[np.str_]:
        """The statuses' strings, an array (compared as one, not sample by sample)."""
        return _STATUS_STRINGS[self.status]


#: Each status code's string (:data:`STATUSES`), indexed by code
_STATUS_STRINGS = np.array([str(s) for s in STATUSES])
