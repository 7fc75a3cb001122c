"""Result types shared by estimators, io, metrics and plots (a neutral layer).

:class:`Measurement` is one sample in; :class:`Estimate` one sample out;
:class:`EstimateSeries` a recording's estimates, with a description of its columns;
:class:`Diagnostics` what the sensor-health policy did over a recording.
Plots, metrics, writers and the CLI read these and never touch an estimator.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields, replace
from enum import Enum

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray, holds_bools
from continuum_mhe.errors import UserError, masked_as_missing, real_number
from continuum_mhe.model.descriptions import OutputSpec, pcc_outputs


class Status(str, Enum):
    """What became of one sample: the one vocabulary of every estimator and output file.

    Each member is its string (``Status.OK == "ok"``, written as ``ok`` in a CSV) and
    carries its :attr:`meaning`.
    """

    meaning: str

    def __new__(cls, value: str, meaning: str) -> Status:
        member = str.__new__(cls, value)
        member._value_ = value
        member.meaning = meaning
        return member

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)

    __hash__ = str.__hash__

    OK = "ok", "converged (MHE) or updated with a measurement (filters)"
    DROPOUT = (
        "dropout",
        "no valid reading of any IMU at this sample: prediction only (a tendon robot's "
        "tensions still update it; a sample where some IMUs reported is updated with "
        "those and keeps that update's status)",
    )
    NOT_CONVERGED = "not-converged", "solver stopped early; its last feasible iterate is used"
    SOLVER_FAILED = "solver-failed", "solver error; the projected prediction is used"
    NO_ESTIMATE = (
        "no-estimate",
        "no estimate: before the first valid reading; the first N-1 samples with "
        "--paper-start; after a restart (divergence, failure, an uncertainty beyond the "
        "workspace) at a sample without a valid reading, until the next valid reading; a "
        "restart that failed even from the reading; live: an estimator step that raised",
    )
    FALLBACK_IPOPT = (
        "fallback-ipopt",
        "the fast MHE backend could not certify its answer to this window; IPOPT solved "
        "it, and no check made it a dropout, drifted, uncertain, at-bound or inconsistent "
        "(each judges it as an ok row)",
    )
    BRANCH_RESTART = (
        "branch-restart",
        "the MHE's window fit was implausible (chi-square test of its measurement cost) "
        "and a restart from another start found a lower window cost, or, with the arrival "
        "prior forgotten, a fit at least twice as good: this answer replaced the "
        "warm-started one (the branch check: on by default with tilt only), and no check "
        "made it a dropout, drifted, uncertain, at-bound or inconsistent (each judges it as "
        "an ok row)",
    )
    RESET = (
        "reset",
        "the estimator diverged (non-finite or far outside the workspace), failed "
        "numerically, or its uncertainty exceeded the workspace (a long gap): it restarted "
        "from this sample's measurement, and this is the restarted estimate; also after a "
        "gap in the data longer than --gap-reset",
    )
    UNCERTAIN = (
        "uncertain",
        "an estimate was made (one that would be ok, fallback-ipopt or branch-restart), "
        "but it is the first estimate of a start (the recording's first, or a restart's "
        "made at a sample after the restart's own; a restart's own row is reset) or comes "
        "after a start or a restart before later readings agree with it, or the tip "
        "position's "
        "standard deviation exceeds the stated fraction of the robot's length "
        "(--uncertain-fraction), or the IMUs (those "
        "that reported within the last SILENT_AFTER, 0.2 s, or --gap-reset where shorter) "
        "do not determine the robot's shape, or the "
        "estimator restarted on readings that contradicted it and they have not yet "
        "agreed with it (or it did so four times or more within --bad-start), or, with "
        "tilt IMUs, within --gap-reset of a reading its prediction called impossible "
        "(beyond one sample's limit: a burst of wrong readings agrees with an estimate "
        "that moved onto it): do not trust it",
    )
    DRIFTED = (
        "drifted",
        "the state is not one the model holds: the paper formulation's position state "
        "more than DRIFT_FRACTION (10 %) of the length from the forward kinematics of the "
        "row's own theta and phi (its separate x, y, z), or a tendon robot's IMU error "
        "states beyond their prior or changing faster than their model allows "
        "(chi-square 99.9 %: the model follows the readings only with IMU errors the "
        "IMUs are not taken to have; wrong tensions, a wrong robot file), or its tip force "
        "pushing along the backbone harder than its buckling load (an equilibrium "
        "the backbone cannot hold): do not trust it",
    )
    AT_BOUND = (
        "at-bound",
        "an estimate was made, but a section's bend sits on its theta_max (the MHE holds "
        "it there: the bound, not the data, set the shape) or beyond it (the EKF and UKF "
        "do not hold it): the robot may bend further than theta_max allows (the robot "
        "file's; --theta-max without one); raise it if the robot really bends so far",
    )
    INCONSISTENT = (
        "inconsistent",
        "an estimate was made, but the readings disagree with it beyond their noise (this "
        "sample's normalised residual beyond the chi-square 99.99 % quantile, or beyond "
        "99 % here and at the sample before, or a residual no linear update leaves whose "
        "shift to the readings lies outside the estimate's covariance, or their recent "
        "average beyond the 99.9 % quantile of its F distribution): the model does not "
        "follow the data here; the standard deviations are widened by the estimated model "
        "error (noise_scale); or a row whose newest reading a robust MHE rejected as an "
        "outlier; or an IMU's reading so far beyond the prediction from the ok estimate "
        "before it that it was skipped as a glitch (the estimate is the prediction "
        "without it)",
    )


#: Every status's meaning by its string (read from :class:`Status`).
STATUS_MEANINGS: dict[str, str] = {status.value: status.meaning for status in Status}
#: The longest status, characters (the width of a series' status array).
STATUS_WIDTH = max(len(name) for name in STATUS_MEANINGS)


@dataclass(frozen=True)
class Measurement:
    """One sample: time ``t`` in seconds and the measurement vector ``z``.

    ``z`` holds the formulation's measurement blocks one after the other (for one tilt
    IMU ``[roll, pitch]`` in radians). NaN in a block marks a dropout of that sensor; a
    raw IMU's block is its accelerometer and gyro together (NaN in any of them: the
    IMU's whole reading is left out).
    ``labels``: the names of ``z``'s values where it came labelled (a pandas Series's
    index), which the estimator checks against its formulation's order.
    """

    t: float
    z: FloatArray
    labels: tuple[str, ...] | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        index = getattr(self.z, "index", None)  # a pandas Series's (numpy drops it)
        if self.labels is None and index is not None and hasattr(index, "tolist"):
            object.__setattr__(self, "labels", tuple(str(c) for c in index.tolist()))
        object.__setattr__(self, "t", real_number("measurement t", self.t))
        if np.iscomplexobj(self.z):  # numpy would drop the imaginary part
            raise UserError(f"measurement z must be real numbers, got complex {self.z!r:.60}")
        try:  # numpy would read True as 1 and "0.1" as 0.1, which run() refuses
            given = np.asarray(masked_as_missing(self.z))
            if given.dtype.kind in "SU" or holds_bools(self.z):
                raise TypeError
            z = given.astype(float)
        except (TypeError, ValueError):
            raise UserError(f"measurement z must be numbers, got {self.z!r:.60}") from None
        object.__setattr__(self, "z", z)

    @property
    def valid(self) -> bool:
        """Every value is finite (no sensor dropped out)."""
        return bool(np.all(np.isfinite(self.z)))


@dataclass(frozen=True)
class Estimate:
    """The estimate at one sample.

    Attributes:
        t: sample time, s.
        state: the formulation's state vector, or None for ``no-estimate``.
        output: the formulation's outputs (m, rad, a tip force in N; see
            ``Formulation.outputs``), or None for ``no-estimate``. Positions are in the
            robot's base frame (z along the base's tangent); ``theta_k`` is section
            ``k``'s bending angle and ``phi_k`` the angle of its bending plane from its
            base frame's x axis: the section bends towards ``-(cos phi, sin phi)``
            (docs/model.md).
        covariance: state covariance where the method has one, else None.
        status: see :data:`Status`.
        solve_ms: wall time spent on this sample, ms.
        output_std: one standard deviation of every output (same units as ``output``),
            from ``covariance`` through the outputs (``Formulation.output_std``: its
            sigma points), widened by the model error the readings show, by the
            shift the readings ask for where the estimate cannot explain them (a row
            ``inconsistent``), and by the readings' constant errors
            (``estimators.consistency``); None where unknown. A ``drifted`` row (the
            readings explained with IMU errors the IMUs are not taken to have) and a
            ``dropout`` row (the prediction) are not widened for what they may miss:
            their status, not their standard deviation, says not to trust them.
        outlier: the robust MHE down-weighted this sample's measurement (a block's
            weight below ``estimators.loss.OUTLIER_WEIGHT`` in this solve); always
            False for the quadratic cost and the filters.
        outputs: what each entry of ``output`` is (the formulation's outputs; an
            estimator's ``step`` sets them): :meth:`value` and :meth:`std` read by name.
    """

    t: float
    state: FloatArray | None
    output: FloatArray | None
    covariance: FloatArray | None
    status: Status
    solve_ms: float
    output_std: FloatArray | None = None
    outlier: bool = False
    outputs: tuple[OutputSpec, ...] = ()

    def _index(self, name: str) -> int:
        for i, o in enumerate(self.outputs):
            if o.name == name:
                return i
        known = ", ".join(o.name for o in self.outputs) or "none: outputs not set"
        raise KeyError(f"no output {name!r} (the outputs: {known})")

    def value(self, name: str) -> float:
        """The output ``name`` (``x``, ``theta_2``, ``fx``...), in its unit (m, rad, N);
        NaN where the sample has no estimate."""
        i = self._index(name)
        return math.nan if self.output is None else float(self.output[i])

    def std(self, name: str) -> float:
        """One standard deviation of the output ``name``, in its unit; NaN where the
        sample has none."""
        i = self._index(name)
        return math.nan if self.output_std is None else float(self.output_std[i])


@dataclass
class Diagnostics:
    """What an estimator's sensor-health policy did over a recording (since its last
    ``reset``): its restarts and their causes, the frozen sensors, the model error.

    ``Estimator.run`` returns a copy with the estimates (:attr:`EstimateSeries.diagnostics`);
    a step-by-step caller reads the live value from ``Estimator.diagnostics``.

    Attributes:
        restarts: restarts after a divergence or numerical failure.
        gap_resets: restarts after a gap longer than ``recovery.gap_reset``.
        frozen_samples: samples with at least one IMU treated as frozen
            (``recovery.freeze``).
        first_freezes: the first freeze of each IMU, in the order they happened: its
            measurement block index among the IMUs -> ``t`` (s) of the first of its
            repeated readings.
        bad_starts: restarts after a bad start (``recovery.bad_start``), the start of an
            IMU back from a silence included.
        bad_start_chains: times the bad-start check stopped restarting after the
            formulation's ``bad_start_chain`` restarts in a row whose readings stayed
            inconsistent (the model does not fit them).
        reject_resets: restarts of a robust MHE after it rejected every reading for longer
            than ``recovery.reject_reset``.
        drift_resets: restarts from the last ``ok`` estimate's sensor states after the
            estimates drifted for longer than ``recovery.drift_reset`` (a tendon robot).
        late_imu_starts: restarts at the first reading of an IMU that had not read since
            the last (re)start, given beside every IMU that had (a log whose IMUs start
            apart): the start was made without its part of the shape. On with
            ``recovery.gap_reset``.
        jump_resets: restarts at the sample after a jump in ``t`` shorter than
            ``recovery.gap_reset`` but more than five times the average step before it (a
            clock that stepped forward, a block of samples lost) whose readings the glitch
            test (``recovery.glitch``) would have skipped: the prediction across the jump,
            not one reading, failed. On with ``recovery.gap_reset``.
        first_jump: the first such jump: (``t`` of the sample after it, its length), s;
            None where there was none.
        last_failure: the last numerical failure's message, if any.
        bound_samples: estimates of status ``at-bound``: a section's bend on its
            ``theta_max`` (the MHE holds it there) or beyond it (a filter); such an
            estimate with a status that comes first (``reset``) is not counted.
        max_noise_scale: the largest model-error factor seen: the innovations' variance
            over the one the noise model predicts (1 when the readings fit their noise).
        model_error: the largest model error learned
            (:attr:`~continuum_mhe.estimators.consistency.ConsistencyCheck.model_error`:
            the excess of the innovations over the noise model, in units of ``R``,
            carried in the standard deviations as a constant error of the gravity
            directions); 0 when none showed.
        untrusted_start_samples: estimates of a start that no later reading confirms
            (:meth:`~continuum_mhe.estimators.base.Inference.start_untrusted`: a tendon
            robot's first reading that showed a tip load it cannot tell from the IMUs'
            errors), none of them ``ok``.
        glitches: IMU readings skipped as glitches
            (:data:`~continuum_mhe.settings.GLITCH_FACTOR`: far beyond the prediction
            from an ``ok`` estimate), each a dropout of that IMU for its sample, whose
            row is not ``ok`` (``inconsistent`` unless another status applies).
    """

    restarts: int = 0
    gap_resets: int = 0
    frozen_samples: int = 0
    first_freezes: dict[int, float] = field(default_factory=dict)
    bad_starts: int = 0
    reject_resets: int = 0
    last_failure: str | None = None
    bound_samples: int = 0
    max_noise_scale: float = 1.0
    model_error: float = 0.0
    bad_start_chains: int = 0
    untrusted_start_samples: int = 0
    glitches: int = 0
    drift_resets: int = 0
    late_imu_starts: int = 0
    jump_resets: int = 0
    first_jump: tuple[float, float] | None = None

    def copy(self) -> Diagnostics:
        """An independent copy (later steps do not change it)."""
        return replace(self, first_freezes=dict(self.first_freezes))

    def clear(self) -> None:
        """Zero every count in place (``first_freezes`` emptied, the same dict): whoever
        holds this object, or its ``first_freezes``, sees the counts of a new recording."""
        zero = Diagnostics()
        for f in fields(self):
            if f.name != "first_freezes":
                setattr(self, f.name, getattr(zero, f.name))
        self.first_freezes.clear()


@dataclass(frozen=True)
class EstimateSeries:
    """Estimates over a recording. Rows without an estimate hold NaN in ``output``.

    Attributes:
        method: estimator name (``mhe``, ``ekf``, ``ukf``...).
        t: (n,) s.
        output: (n, ny), the columns described by ``outputs`` (m, rad; a tendon
            robot's tip force in N); conventions as :attr:`Estimate.output`'s.
        status: (n,) status strings.
        solve_ms: (n,) ms.
        outputs: what each column of ``output`` is (default: one section's
            ``x, y, z, theta, phi``).
        output_std: (n, ny) one standard deviation of each output (its unit), NaN where
            unknown (default: all NaN).
        outlier: (n,) bool, the samples the robust MHE down-weighted (see
            :attr:`Estimate.outlier`); None when the estimator does not flag outliers.
        diagnostics: what the estimator's sensor-health policy did over the recording
            (:class:`Diagnostics`); None for a series not made by ``Estimator.run``.
    """

    method: str
    t: FloatArray
    output: FloatArray
    status: NDArray[np.str_]
    solve_ms: FloatArray
    outputs: tuple[OutputSpec, ...] = pcc_outputs(1)
    output_std: FloatArray | None = None
    outlier: NDArray[np.bool_] | None = None
    diagnostics: Diagnostics | None = None

    def __post_init__(self) -> None:
        # arrays of numbers, t one time per sample: a list or a column (n, 1) of times
        # would pass the shape checks below and fail later, in rows() or a writer
        for name in ("t", "solve_ms"):
            value = getattr(self, name)
            try:
                if holds_bools(value):
                    raise TypeError
                array = np.asarray(value, dtype=float)
            except (TypeError, ValueError):
                raise UserError(f"{name} must be an array of numbers, got {value!r:.60}") from None
            object.__setattr__(self, name, array)
        if self.t.ndim != 1:
            raise UserError(f"t has shape {self.t.shape}, expected (n,): one time (s) per sample")
        n = len(self.t)
        for name in ("status", "solve_ms"):  # one per sample (a writer's zip would cut)
            if np.shape(getattr(self, name)) != (n,):
                raise UserError(
                    f"{name} has shape {np.shape(getattr(self, name))}, expected ({n},): one "
                    "per sample of t"
                )
        # wide enough for every status: an array of "ok"s would cut a later "uncertain"
        status = np.asarray(self.status)
        if status.dtype.kind == "U":
            status = status.astype(np.result_type(status.dtype, f"<U{STATUS_WIDTH}"))
        object.__setattr__(self, "status", status)
        known = {s.value for s in Status}
        unknown = sorted({str(v) for v in np.unique(status)} - known)
        if unknown:
            raise UserError(
                f"status {unknown[0]!r} is not one of {', '.join(s.value for s in Status)}"
            )
        if self.outlier is not None and np.shape(self.outlier) != (len(self.t),):
            raise UserError(
                f"outlier has shape {np.shape(self.outlier)}, expected ({len(self.t)},)"
            )
        shape = (len(self.t), len(self.outputs))
        if np.shape(self.output) != shape:
            raise UserError(
                f"output has shape {np.shape(self.output)}, expected ({len(self.t)}, "
                f"{len(self.outputs)}) for columns {', '.join(o.name for o in self.outputs)}"
            )
        object.__setattr__(self, "output", np.asarray(self.output, dtype=float))
        if self.output_std is None:
            object.__setattr__(self, "output_std", np.full(shape, np.nan))
        elif np.shape(self.output_std) != shape:
            raise UserError(f"output_std has shape {np.shape(self.output_std)}, expected {shape}")
        else:
            object.__setattr__(self, "output_std", np.asarray(self.output_std, dtype=float))

    @property
    def std(self) -> FloatArray:
        """``output_std`` (n, ny), NaN where unknown."""
        assert self.output_std is not None  # set in __post_init__
        return self.output_std

    def __len__(self) -> int:
        """The number of samples."""
        return len(self.t)

    def statuses(self) -> list[Status]:
        """Each sample's status as a :class:`Status` (``status`` holds the strings)."""
        by_value = {str(m): m for m in Status}
        return [by_value[str(s)] for s in self.status]

    def rows(
        self, which: slice | Sequence[int] | NDArray[np.bool_] | NDArray[np.integer]
    ) -> EstimateSeries:
        """The series at the samples ``which`` selects (a slice, a boolean mask of
        ``len(self)``, or indices, negative ones from the end; one index: a series of
        that row), for example
        ``series.rows(series.t >= 1.0)``: the rows after the first second, as ``evaluate
        --skip-start 1`` scores them. The ``diagnostics`` are the whole run's.

        Raises:
            UserError: a mask of another length, or an index outside the series.
        """
        if not isinstance(which, slice):
            which = np.asarray(which)
            if which.ndim == 0 and which.dtype != bool:  # one index: the series of that row
                which = which.reshape(1)
            if which.size == 0 and which.dtype != bool:  # no index: no row
                which = which.astype(np.intp)
            if which.dtype == bool and which.shape != (len(self),):
                raise UserError(
                    f"a row mask has shape {which.shape}, expected ({len(self)},): one per sample"
                )
            if which.dtype != bool:
                if which.dtype.kind not in "iu":
                    raise UserError(
                        f"rows takes a slice, a boolean mask or integer indices, got {which!r:.60}"
                    )
                outside = which[(which >= len(self)) | (which < -len(self))]
                if len(outside):
                    raise UserError(
                        f"row index {int(outside[0])} is outside the series of {len(self)} samples"
                    )
        outlier = None if self.outlier is None else self.outlier[which]
        return replace(
            self,
            t=self.t[which],
            output=self.output[which],
            status=self.status[which],
            solve_ms=self.solve_ms[which],
            output_std=self.std[which],
            outlier=outlier,
        )

    def column(self, name: str) -> FloatArray:
        """The output column ``name`` (n,); a KeyError naming the columns for a name
        not among them."""
        return self.output[:, self._index(name)]

    def _index(self, name: str) -> int:
        names = self.names
        if name not in names:
            raise KeyError(f"no output column {name!r} (the columns: {', '.join(names)})")
        return names.index(name)

    def std_column(self, name: str) -> FloatArray:
        """One standard deviation of the output column ``name`` (n,), in its unit; NaN
        where the series has none."""
        i = self._index(name)
        if self.output_std is None:
            return np.full(len(self.t), np.nan)
        return self.output_std[:, i]

    @property
    def names(self) -> list[str]:
        """The output columns' names, in order."""
        return [o.name for o in self.outputs]

    @property
    def has_estimate(self) -> NDArray[np.bool_]:
        """(n,): True where the sample has an estimate (every status but
        ``no-estimate``)."""
        return self.status != "no-estimate"

    @classmethod
    def from_estimates(
        cls,
        method: str,
        estimates: Iterable[Estimate],
        outputs: tuple[OutputSpec, ...] | None = None,
        flags_outliers: bool = False,
        diagnostics: Diagnostics | None = None,
    ) -> EstimateSeries:
        """The series of ``estimates``; ``outputs`` (default: those the estimates carry,
        :attr:`Estimate.outputs`, else one section's) names their entries; with
        ``flags_outliers`` it keeps their outlier flags (a robust MHE's), else
        ``outlier`` is None."""
        est = list(estimates)
        if outputs is None:
            outputs = next((e.outputs for e in est if e.outputs), pcc_outputs(1))
        out = np.full((len(est), len(outputs)), np.nan)
        std = np.full_like(out, np.nan)
        for i, e in enumerate(est):
            if e.output is not None:
                if len(e.output) != len(outputs):
                    raise UserError(
                        f"estimate {i + 1} has {len(e.output)} outputs, but outputs "
                        f"describes {len(outputs)}: pass outputs=formulation.outputs"
                    )
                out[i] = e.output
                if e.output_std is not None:
                    std[i] = e.output_std
        return cls(
            method=method,
            t=np.array([e.t for e in est], dtype=float),
            output=out,
            status=np.array([e.status for e in est], dtype=str),
            solve_ms=np.array([e.solve_ms for e in est], dtype=float),
            outputs=outputs,
            output_std=std,
            outlier=np.array([e.outlier for e in est], dtype=bool) if flags_outliers else None,
            diagnostics=diagnostics,
        )
