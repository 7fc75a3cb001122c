"""The inference interface every estimator's filter or window solver implements.

An :class:`Inference` turns one sample into ``(state, covariance, status)`` and holds
nothing but the state it infers from: the MHE's window and arrival prior, the EKF's and
UKF's mean and covariance. The policy around it (frozen sensors, gaps, restarts,
statuses) is the :class:`~continuum_mhe.estimators.sensor_health.Estimator` that owns
it. Results are data (:mod:`continuum_mhe.results`).
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.model.formulations import Formulation, KeptSensors
from continuum_mhe.results import Estimate, EstimateSeries, Measurement, Status

__all__ = ["Estimate", "EstimateSeries", "FloatArray", "Inference", "Measurement", "Status"]

#: The exceptions a numerical failure raises (a singular matrix, an overflow, CasADi's or
#: the compiled core's errors); the estimator's policy restarts on them.
NUMERICAL_FAILURES = (np.linalg.LinAlgError, ArithmeticError, RuntimeError)


def judged_untrusted(formulation: Formulation, z: FloatArray) -> bool:
    """``formulation.start_untrusted(z)``, and True where judging fails numerically (a
    start whose reading the model cannot judge is not trusted either)."""
    try:
        return formulation.start_untrusted(z)
    except NUMERICAL_FAILURES:
        return True


def tilt_rows(formulation: Formulation) -> list[int]:
    """The measurement rows of the formulation's tilt blocks (roll and pitch, rad)."""
    return [
        i for b in formulation.measurement_blocks if b.kind == "tilt"
        for i in range(b.start, b.start + b.size)
    ]  # fmt: skip


def tension_rows(formulation: Formulation) -> list[int]:
    """The measurement rows of a tendon robot's tensions (N; not their rates)."""
    names = formulation.measurement_names
    return [
        i for b in formulation.measurement_blocks if b.kind == "tension"
        for i in range(b.start, b.start + b.size) if re.fullmatch(r"tension_\d+", names[i])
    ]  # fmt: skip


class Inference(ABC):
    """The filter or window solver of an estimator: its narrow interface.

    :meth:`infer` advances the state by one sample; :meth:`restart` forgets it. The
    :class:`~continuum_mhe.estimators.sensor_health.Estimator` that owns the object
    calls only these methods and the ones below; it decides when to restart and what
    the answer's status is.
    """

    name: str = "inference"
    #: whether estimates carry outlier flags (a robust MHE)
    flags_outliers: bool = False
    #: whether its estimates keep the formulation's state bounds (a section's bend at
    #: most its ``theta_max``): the MHE's constraints; a filter's estimates can pass them
    holds_bounds: bool = False

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        #: what the last start kept of the estimate before its restart (the sensor
        #: states and their covariance: ``Formulation.kept_sensors``), or None
        self.kept_sensors: KeptSensors | None = None
        self._kept: tuple[FloatArray, FloatArray, float | None] | None = None
        #: whether the current start knows nothing of the sensors (kept none of them)
        self.fresh_start = False

    def restart(
        self,
        kept_x: FloatArray | None = None,
        kept_P: FloatArray | None = None,
        kept_t: float | None = None,
    ) -> None:
        """Forget the state (:meth:`forget`): the next :meth:`infer` starts from its
        sample, keeping the sensor states of the estimate ``kept_x`` (nx,) at ``kept_t``
        s with covariance ``kept_P`` before the restart where they are given (a restart
        within a recording that does not doubt them: :meth:`start_prior`)."""
        self._kept = None if kept_x is None or kept_P is None else (kept_x, kept_P, kept_t)
        self.forget()

    @abstractmethod
    def forget(self) -> None:
        """Forget the state: the next :meth:`infer` starts from its sample."""

    def start_prior(self, z: FloatArray, t: float | None = None) -> tuple[FloatArray, FloatArray]:
        """The formulation's start at the reading ``z`` (at ``t`` s), with the sensor
        states kept by the last restart, their covariance grown by their random walks
        over the time since (:meth:`~continuum_mhe.model.formulations.Formulation.
        kept_sensors`; ``t`` None: not grown)."""
        self.kept_sensors = self.kept_at(t)
        self.fresh_start = self.kept_sensors is None
        return self.formulation.start_prior(z, self.kept_sensors)

    def start_untrusted(self, t: float, z: FloatArray) -> bool:
        """Whether the current start is one that no later reading confirms: it knows
        nothing of the sensors (:attr:`fresh_start`), and its formulation cannot tell
        what the reading ``z`` at ``t`` s, the start's first with an IMU's reading,
        shows from their own errors
        (:meth:`~continuum_mhe.model.formulations.Formulation.start_untrusted`: a tendon
        robot's tip load; a reading the formulation fails to judge is not trusted
        either). The policy asks it once per start, and no estimate of that start is
        then ``ok``."""
        return self.fresh_start and judged_untrusted(self.formulation, z)

    def kept_at(self, t: float | None) -> KeptSensors | None:
        """The sensor states the last restart kept, at ``t`` s: their covariance grown by
        their random walks since (``t`` None: not grown); None where it kept none."""
        if self._kept is None:
            return None
        x, P, t0 = self._kept
        dt = 0.0 if t is None or t0 is None else max(float(t) - float(t0), 0.0)
        return self.formulation.kept_sensors(x, P, dt)

    @abstractmethod
    def infer(
        self, measurement: Measurement
    ) -> tuple[FloatArray | None, FloatArray | None, Status]:
        """``(state, covariance, status)`` after this sample (None, None and
        ``no-estimate`` when there is none yet). May raise ``ArithmeticError``,
        ``RuntimeError`` or ``numpy.linalg.LinAlgError`` on a numerical failure."""

    def step_problem(self, step: float) -> str | None:
        """Why this inference cannot follow its settings on samples ``step`` s apart (the
        median of a recording's first steps), in words that finish a warning's line;
        None where it can (here always)."""
        return None

    def clear_counts(self) -> None:
        """Zero the object's own counts (none here; the MHE's second start and branch
        check keep theirs)."""
        return None

    def close_recording(self) -> None:
        """The samples so far are final: the next :meth:`infer`, even of a sample at the
        last one's time, begins another recording (or another stretch of one), not the
        estimator's second step of that sample (none here)."""
        return None

    def sync_counts(self) -> None:
        """Bring the object's own counts up to date with its compiled step's (none here;
        the MHE's branch check counts some windows in the compiled step)."""
        return None

    def outlier(self) -> bool:
        """Whether the last :meth:`infer` down-weighted its measurement (robust MHE only)."""
        return False

    def bound_free_covariance(self) -> FloatArray | None:
        """Where the last :meth:`infer`'s estimate sits on a bending bound that its
        covariance is conditioned on (the MHE holds it there), the covariance not
        conditioned on it (nx, nx), which its standard deviations are written from; else
        None (an estimator that does not hold its bounds)."""
        return None

    def rejected_every_reading(self, rows: Sequence[int] | None = None) -> bool | None:
        """Whether the last :meth:`infer` down-weighted every valid reading of its sample
        (the reject reset counts these), or every valid reading of the blocks that hold
        any of the reading ``rows``: always False here, as for every inference without a
        robust loss; a robust MHE's answers None when the sample had no such valid
        reading."""
        return False

    def policy_inference(self) -> object | None:
        """The object the compiled sensor-health policy steps instead of :meth:`infer`
        (a compiled inference), or None: it steps :meth:`infer`."""
        return None

    def output(self, state: FloatArray) -> FloatArray:
        """The outputs of a state (an object may use a compiled copy of the model)."""
        return self.formulation.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        """Output standard deviations for a state with covariance ``cov``
        (:meth:`~continuum_mhe.model.formulations.Formulation.output_std`; an object may
        use the compiled core's, with the same values)."""
        return self.formulation.output_std(state, cov)
