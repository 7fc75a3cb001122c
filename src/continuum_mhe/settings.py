"""Typed, frozen settings of the estimators (:class:`MHESettings`) and of the sensor-health
policy around them (:class:`RecoverySettings`). Every field is validated on
construction. The model's settings (:class:`RobotSettings`, :class:`NoiseSettings`,
:data:`FormulationName`) live in :mod:`continuum_mhe.model.settings` and are
re-exported here."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Literal

from continuum_mhe.errors import UserError
from continuum_mhe.model.settings import (
    FORMULATIONS,
    MAX_MEASUREMENT_STD,
    MIN_MEASUREMENT_STD,
    FormulationName,
    NoiseSettings,
    RobotSettings,
    check_positive,
)

__all__ = [
    "DEFAULT_LOSS_SCALE",
    "MAX_HORIZON",
    "MAX_MEASUREMENT_STD",
    "MIN_MEASUREMENT_STD",
    "FORMULATIONS",
    "FREEZE_MIN_SAMPLES",
    "FREEZE_TOLERANCE",
    "GLITCH_FACTOR",
    "MHE_LOSSES",
    "MHE_SOLVERS",
    "FormulationName",
    "MHELoss",
    "MHESettings",
    "MHESolver",
    "NoiseSettings",
    "RecoverySettings",
    "RobotSettings",
    "SILENT_AFTER",
]

MHESolver = Literal["fast", "ipopt"]
MHE_SOLVERS: tuple[MHESolver, ...] = ("fast", "ipopt")
MHELoss = Literal["l2", "huber", "cauchy", "welsch"]
MHE_LOSSES: tuple[MHELoss, ...] = ("l2", "huber", "cauchy", "welsch")
#: Default ``loss_scale`` per robust loss, in standard deviations of the whitened
#: residual norm of one IMU's (roll, pitch) block (docs/robust.md). Huber: 1.5, its 95 %
#: asymptotic efficiency on Gaussian noise for a two-component block (1.345 is the
#: one-component value). Cauchy: 1.6, the smallest scale whose clean-data cost stays
#: inside the 2 % target on the 50-seed Monte Carlo of ``reproduce``'s outlier groups
#: with the second start (a smaller scale rejects bursts better and costs more on clean
#: data). Welsch: 3.0, near its 95 % efficiency constant for one component (2.985; a
#: two-component block's is 3.25), which meets every outlier target of that Monte Carlo
#: with ``RecoverySettings.reject_reset``. The measurements: docs/robust.md.
DEFAULT_LOSS_SCALE: dict[str, float] = {
    "l2": math.inf, "huber": 1.5, "cauchy": 1.6, "welsch": 3.0,
}  # fmt: skip


#: Longest MHE window, samples (the command line's ``--horizon`` range: a window of
#: 10^9 samples is a memory error in CasADi, not an estimator).
MAX_HORIZON = 1000
#: Most IPOPT iterations a sample may take (``MHESettings.max_iter``): IPOPT takes a C
#: int, and a window that needs more does not converge.
MAX_ITER = 100_000
#: Most samples a frozen reading is counted over (``RecoverySettings.freeze_samples``):
#: 1000 s at 1 kHz; the compiled check counts in a C int.
MAX_FREEZE_SAMPLES = 1_000_000


@dataclass(frozen=True)
class MHESettings:
    """Moving-horizon settings.

    Attributes:
        horizon: number of measurements ``N`` in the window.
        paper_start: if True, give no estimate before ``N`` samples (Algorithm 1);
            otherwise the window grows from the first sample.
        max_iter: IPOPT iteration limit per sample.
        tol: IPOPT convergence tolerance.
        solver: ``"fast"`` (default), the structure-exploiting Gauss-Newton SQP that
            falls back to IPOPT when it cannot certify convergence; ``"ipopt"``, the
            reference.
        loss: measurement cost per IMU block and node: ``"l2"`` (quadratic, default),
            ``"huber"``, ``"cauchy"`` or ``"welsch"`` of the block's whitened residual norm
            (docs/robust.md). The arrival prior and process terms stay quadratic.
        loss_scale: where the robust loss departs from l2, in standard deviations of
            the measurement noise (whitened norm of one block); None takes
            :data:`DEFAULT_LOSS_SCALE` of the loss. Given with ``"l2"``, a
            :class:`~continuum_mhe.errors.UserError`.
        branch_check: after each window, test its measurement cost against a
            chi-square quantile and, where implausible, solve the same window from
            other starts and keep the lowest cost, then, if none wins, with the arrival
            prior forgotten (status ``branch-restart``; see
            :mod:`continuum_mhe.estimators.branch`). None (default): on for a robot of
            several sections with the tilt formulation (``bend``), whose window has far
            branches, and the quadratic loss. Off with a robust loss (a restart would
            follow the faulty IMU the loss rejects), with gyros (``direct``: the rates
            hold the branch, and the check measured worse), for one section and for
            the other formulations (measured in docs/model.md).
    """

    horizon: int = 30
    paper_start: bool = False
    max_iter: int = 100
    tol: float = 1e-8
    solver: MHESolver = "fast"
    loss: MHELoss = "l2"
    loss_scale: float | None = None
    branch_check: bool | None = None

    def __post_init__(self) -> None:
        if self.solver not in MHE_SOLVERS:
            raise UserError(f"solver must be one of {MHE_SOLVERS}, got {self.solver!r}")
        if self.loss not in MHE_LOSSES:
            raise UserError(f"loss must be one of {MHE_LOSSES}, got {self.loss!r}")
        if self.loss_scale is not None:
            check_positive("loss_scale", self.loss_scale)
            if self.loss == "l2":
                raise UserError(
                    f"loss_scale={self.loss_scale!r} is a robust loss's scale; loss='l2' has "
                    "none: give loss='huber', 'cauchy' or 'welsch' with it, or leave it out"
                )
        whole = numbers.Integral  # numpy's integers too
        if not (
            isinstance(self.horizon, whole)
            and not isinstance(self.horizon, bool)
            and 2 <= self.horizon <= MAX_HORIZON
        ):
            raise UserError(
                f"horizon must be an integer from 2 to {MAX_HORIZON} samples, got {self.horizon!r}"
            )
        object.__setattr__(self, "horizon", int(self.horizon))
        if not (self.branch_check is None or isinstance(self.branch_check, bool)):
            raise UserError(f"branch_check must be True, False or None, got {self.branch_check!r}")
        if not isinstance(self.paper_start, bool):
            raise UserError(f"paper_start must be True or False, got {self.paper_start!r}")
        if not (
            isinstance(self.max_iter, whole)
            and not isinstance(self.max_iter, bool)
            and 1 <= self.max_iter <= MAX_ITER
        ):
            raise UserError(
                f"max_iter must be an integer from 1 to {MAX_ITER:,}, got {self.max_iter!r:.40}"
            )
        object.__setattr__(self, "max_iter", int(self.max_iter))
        check_positive("tol", self.tol)

    @property
    def scale(self) -> float:
        """The loss scale in use, standard deviations (inf for ``"l2"``)."""
        if self.loss == "l2":
            return math.inf
        return DEFAULT_LOSS_SCALE[self.loss] if self.loss_scale is None else self.loss_scale


#: The fewest consecutive samples with one same reading that can be a frozen sensor
#: (``RecoverySettings.freeze_samples``). The duration alone cannot tell a stuck sensor
#: from a gap in the data: two equal readings 60 s apart say nothing about the time
#: between them. Five in a row is a sensor seen stuck at five instants (a live IMU's
#: noise makes even two exact repeats uncommon), and a reading repeated for more than
#: :data:`FREEZE_S` (the command line's ``--freeze``) at 25 Hz or more already spans five
#: samples, so at the usual rates the duration decides and only slow or gappy data feel
#: the count.
FREEZE_MIN_SAMPLES = 5
#: How long a sensor's reading must repeat to be frozen by default, s
#: (``RecoverySettings.freeze``). Noise changes a live IMU's raw readings every sample;
#: an IMU polled faster than it samples repeats each reading for less than its own
#: sampling period, under this at 5 Hz or more. Shorter than a second, so that a freeze of
#: half a second is caught: on a three-section robot at 100 Hz one IMU frozen for 0.5 s
#: puts the estimate 17 to 28 mm off and holds it off for seconds at 1 s, not at this.
FREEZE_S = 0.2
#: How far, as a fraction of each reading's noise standard deviation (the formulation's
#: measurement covariance), a reading may move from a freeze's first one and still repeat
#: it. A stuck IMU whose driver adds a tiny jitter (1e-6 rad on a 2-degree tilt) is
#: frozen too. A live IMU's noise moves its readings a thousand times further; a reading
#: that stays within it while its sensor is live is one quantised more coarsely than
#: that, which repeats exactly, as a freeze without the tolerance would count too.
FREEZE_TOLERANCE = 1e-3
#: An IMU silent for longer than this (s; or than the gap reset, where shorter) no
#: longer observes its part of the shape: where the IMUs left do not determine it, the
#: rows are ``uncertain``. Extrapolated at its last rates, the silent IMU's section
#: drifts beyond its standard deviation within a quarter of a second on the shipped rods
#: (spatial-tendon, tilt, the tip IMU silent from 3 s: 22 mm off at 1.7 standard
#: deviations after 0.24 s, 72 mm at 3.9 after 0.56 s).
SILENT_AFTER = 0.2
#: An IMU's reading whose NIS against the prediction from the previous estimate, where
#: that estimate was ``ok``, exceeds this many times the one-sample limit (chi-square
#: 99.99 % for its readings, times the model error the readings showed; given the
#: sample's readings that are not an IMU's, such as a tendon robot's tensions and tip
#: condition) is skipped as a glitch: a dropout of that IMU for the sample, whose row is
#: not ``ok`` (``inconsistent`` unless another status applies). So the next reading is
#: taken whatever it is: a second such reading in a row
#: is followed, as the robot may have moved so. A single upside-down raw reading (a
#: serial line's corrupted field) is then not absorbed into the estimate, where a tendon
#: robot's IMU error states would carry it for the rest of the recording. A tilt reading
#: near the opposite of the predicted gravity direction, where the tilt residual and its
#: linearised prediction grow together, is judged again with the Jacobian at the IMU's
#: reading before, where the reading's whitened residual alone is beyond the limit. At 3
#: no reading of the shipped two-section rod and tendon recordings is skipped (a few are
#: at 1), and a single 1 rad/s spike in one gyro reading of a tendon robot is (taken, it
#: leaves ``ok`` rows 20 mm and 3 standard deviations off).
GLITCH_FACTOR = 3.0
#: How long (s) a tendon robot's estimates may drift before the estimator restarts from
#: the sensor states of the last ``ok`` one (``RecoverySettings.drift_reset``): on the
#: shipped ``force-29`` with a passing fault (a tip IMU frozen for a second, a tension
#: 0.05 N off for 0.2 s, a tensions file with a 0.9 s hole) its rows stay far off for
#: the rest of the recording without it (docs/tendon-studies.md).
DRIFT_RESET_S = 0.5
#: A tendon robot's samples without tensions for longer than this (s; the gap reset's,
#: where shorter) make the next sample with them restart as after a gap, keeping the
#: sensors' states (one missing sample of a stream's tensions makes five samples, 0.12
#: s at 50 Hz, without them: no restart): such samples use no reading (the IMUs' model
#: needs the tensions),
#: and the prediction has no tensions to follow; on the shipped ``force-29`` a 0.4 s
#: hole in them leaves ``ok`` rows 12 mm off, 4 to 5 standard deviations, without the
#: restart and none over 5 mm with it (docs/guide/library.md, "A tendon robot").
TENSION_GAP_S = 0.15


@dataclass(frozen=True)
class RecoverySettings:
    """How every estimator recovers from gaps and frozen sensors, and when it says its
    estimate should not be trusted (:meth:`~continuum_mhe.estimators.sensor_health.Estimator.step`).

    Attributes:
        gap_reset: after no valid measurement for longer than this (s), the next valid
            sample restarts the estimator from its own measurement (status ``reset``)
            instead of continuing from a blind prediction; None: never (``--gap-reset``
            on the command line; default 1 s, as there). With it on, the first reading
            of an IMU that had not read since the last (re)start, beside every IMU that
            had, restarts the estimator too (the start lacked its part of the shape).
        freeze: a sensor (measurement block) whose reading repeats (every value within
            :data:`FREEZE_TOLERANCE` of its noise standard deviation of the first
            repeated reading) for longer than this (s), over at least
            ``freeze_samples`` consecutive samples none more than ``gap_reset`` (1 s when
            it is off; ``freeze`` where that is longer) after the one before (a gap is not
            a freeze), is treated as
            dropped out until its reading changes; None: never (command line
            ``--freeze``; default :data:`FREEZE_S`).
        freeze_samples: the fewest consecutive samples with the same reading (the first
            one included) that can be a freeze (default :data:`FREEZE_MIN_SAMPLES`);
            the duration alone is not enough: two equal readings 60 s apart are a gap in
            the data, not a sensor seen to be stuck.
        bad_start: for this long (s) after each (re)start, and after each return of an
            IMU silent for longer than ``gap_reset`` (1 s when it is off), ``SAMPLES``
            consecutive readings inconsistent with the estimate (normalised innovation
            beyond a chi-square quantile; :mod:`continuum_mhe.estimators.start_check`)
            restart the estimator from the current reading (status ``reset``); not for
            a robust MHE (``MHESettings.loss`` not ``l2``), which rejects such readings
            as outliers and has ``reject_reset``; None: never (command line
            ``--bad-start``; default 2 s). Either way an estimate after such a return
            is ``uncertain`` until the returned IMU's readings have agreed with it for
            as long as that silence threshold. A formulation's ``bad_start_chain`` such
            restarts in a row, each contradicted in turn, stop them until one holds;
            four or more forced restarts within this time make the estimates meanwhile
            ``uncertain``.
        reject_reset: a robust MHE (``MHESettings.loss`` not ``l2``) whose newest reading
            was rejected as an outlier at every sample for longer than this (s)
            restarts from the next valid reading (status ``reset``): readings that
            disagree with the estimate for this long are taken as right and the
            estimate as lost (a redescending loss such as Welsch never follows them on
            its own; docs/robust.md). Acts only on estimators that flag outliers; None:
            never (command line ``--reject-reset``).
        uncertain_fraction: an estimate whose reported tip position standard
            deviation (``sqrt(std_x^2 + std_y^2 + std_z^2)`` as written, the readings'
            constant errors ``NoiseSettings.reading_bias_std`` in it) exceeds this
            fraction of the robot's length gets status ``uncertain`` instead of ``ok``.
            Where the estimator's own covariance (without those constant errors)
            exceeds it, so does every estimate within the unobserved window after
            (``gap_reset``, or 1 s when that is off): a filter linearised on one of
            several shapes that fit the readings narrows around it whether or not it is
            the robot's.
        glitch: an IMU's reading whose NIS against the prediction from an ``ok``
            estimate (or, for a reading near the opposite gravity direction, from the
            first estimate of a start, uncertain until a reading confirms it) exceeds
            this many times the one-sample limit (times the model error
            the readings showed) is skipped as a glitch (:data:`GLITCH_FACTOR`, the
            default); not for a robust MHE, whose loss weighs such readings, nor for the
            ``paper`` formulation, which has no consistency check; None: never (command
            line ``--glitch``, 0).
        drift_reset: where a model's estimates drift (a tendon robot's IMU error states
            leave their prior or change faster than their model allows: status
            ``drifted``) for longer than this (s) since the last ``ok`` one, the
            estimator restarts (status ``reset``) keeping that ``ok`` estimate's sensor
            states: a fault that has passed (an IMU frozen for a while, wrong tensions
            for a while) left the estimate off, and the sensors are as they were
            before it. Once after each ``ok`` row; where the model does not fit the
            robot (tensions of another scale) the rows after stay ``drifted`` or
            ``uncertain``. Only formulations that have such states (a tendon robot),
            and not with ``estimate_tension_gain`` (the gains drift as they settle);
            None: never (command line ``--drift-reset``, 0).

    The defaults are the command line's; :meth:`off` gives the bare estimator (no
    gap reset, freeze, bad-start check, reject reset, glitch skip or drift reset), as
    the paper's experiments run it.
    """

    gap_reset: float | None = 1.0
    freeze: float | None = FREEZE_S
    uncertain_fraction: float = 0.1
    bad_start: float | None = 2.0
    reject_reset: float | None = 0.5
    # last, so that the fields before them keep their positions
    freeze_samples: int = FREEZE_MIN_SAMPLES
    glitch: float | None = GLITCH_FACTOR
    drift_reset: float | None = DRIFT_RESET_S

    def __post_init__(self) -> None:
        for name in ("gap_reset", "freeze", "bad_start", "reject_reset", "glitch", "drift_reset"):
            value = getattr(self, name)
            if value is not None and value == 0 and not isinstance(value, bool):
                raise UserError(
                    f"{name} must be positive, or None for never (the command line's 0)"
                )
            if value is not None:
                check_positive(name, value)
        check_positive("uncertain_fraction", self.uncertain_fraction)
        n = self.freeze_samples
        if not (
            isinstance(n, numbers.Integral)
            and not isinstance(n, bool)
            and 2 <= n <= MAX_FREEZE_SAMPLES
        ):
            raise UserError(
                f"freeze_samples must be an integer from 2 to {MAX_FREEZE_SAMPLES:,}, got {n!r:.40}"
            )
        object.__setattr__(self, "freeze_samples", int(n))

    @classmethod
    def off(cls) -> RecoverySettings:
        """No gap reset, freeze, bad-start check, reject reset, glitch skip or drift reset: the
        estimator as the paper runs it (statuses and the ``uncertain`` threshold stay)."""
        return cls(
            gap_reset=None,
            freeze=None,
            bad_start=None,
            reject_reset=None,
            glitch=None,
            drift_reset=None,
        )
