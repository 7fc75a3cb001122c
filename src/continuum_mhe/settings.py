"""Typed, frozen settings. Every field is validated on construction."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Literal

from continuum_mhe.errors import UserError
from continuum_mhe.model.imu import MOUNTINGS, Mounting
from continuum_mhe.model.robot import check_theta_max

FormulationName = Literal["bend", "paper", "direct", "tendon"]
FORMULATIONS: tuple[FormulationName, ...] = ("bend", "paper")
MHESolver = Literal["fast", "ipopt"]
MHE_SOLVERS: tuple[MHESolver, ...] = ("fast", "ipopt")
MHELoss = Literal["l2", "huber", "cauchy", "welsch"]
MHE_LOSSES: tuple[MHELoss, ...] = ("l2", "huber", "cauchy", "welsch")
#: Default ``loss_scale`` per robust loss, in standard deviations of the whitened
#: residual norm of one IMU's (roll, pitch) block (docs/robust.md). Huber: 1.5, its 95 %
#: asymptotic efficiency on Gaussian noise for a two-component block (1.345 is the
#: one-component value). Cauchy: 1.6, chosen by the 50-seed Monte Carlo of
#: ``reproduce``'s outlier groups with the second start (docs/robust.md): at 1.6 the
#: clean-data error is 1.3 % above the quadratic cost's (paired 95 % interval up to
#: 1.9 %, inside the 2 % target), bursts cost 1.30x the clean error (2.0: 1.61x, clean
#: +0.3 %), isolated spikes 1.016x (2.0: 1.017x); 1.5 was 2.0 % above on clean data.
#: Welsch: 3.0, near its 95 % efficiency constant for one component (2.985; 93.5 % for a
#: two-component block, whose 95 % value is 3.25, Cauchy 1.6: 87.3 %); on the same
#: Monte Carlo (with ``RecoverySettings.reject_reset``) clean +0.26 %, bursts 1.061x,
#: spikes 1.012x (bursts 1.14x while the corruption clipped pitch at 90 deg; without
#: the reset, on that data, 10 seeds: 2.5, 2.75 and 3.0 all gave bursts 1.12x, clean
#: +1.6 %, +0.8 % and +0.3 %; 2.0 lost one recording).
DEFAULT_LOSS_SCALE: dict[str, float] = {
    "l2": math.inf, "huber": 1.5, "cauchy": 1.6, "welsch": 3.0,
}  # fmt: skip


def _positive(name: str, value: float) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise UserError(f"{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class RobotSettings:
    """One inextensible constant-curvature section with an IMU at its tip.

    Attributes:
        length: section length ``s`` in metres.
        theta_max: upper bound on the bending angle ``theta`` in radians (eq. 11 uses
            ``pi/2``). Must lie in ``(0, pi)``.
        mounting: ``"z-up"`` (base z against gravity) or ``"z-down"`` (hanging).
    """

    length: float = 0.2
    theta_max: float = math.pi / 2
    mounting: Mounting = "z-up"

    def __post_init__(self) -> None:
        _positive("length", self.length)
        check_theta_max(self.theta_max)
        if self.mounting not in MOUNTINGS:
            raise UserError(f"mounting must be one of {MOUNTINGS}, got {self.mounting!r}")


@dataclass(frozen=True)
class NoiseSettings:
    """Noise model shared by every estimator (same Q and R for MHE, EKF and UKF).

    Attributes:
        measurement_std: standard deviation of roll and pitch, rad. The paper's
            ``V = diag(2, 2)`` "degrees" is read as 2 degrees; weights are 1/std^2.
        bend_accel_psd: white-noise acceleration spectral density of the bend vector
            ``(a, b)`` in the default formulation, rad^2/s^3. The default came from a
            sweep of the EKF's tip error over simulated recordings (docs/model.md).
        paper_process_weight: the paper's ``W = w I`` (weight, i.e. inverse
            covariance per step) for the five-state formulation.
        initial_bend_std: prior standard deviation of the initial ``(a, b)`` or
            ``(theta, phi)``, rad.
        initial_rate_std: prior standard deviation of the initial bend rates, rad/s.
    """

    measurement_std: float = math.radians(2.0)
    bend_accel_psd: float = 0.5
    paper_process_weight: float = 10.0
    initial_bend_std: float = 0.1
    initial_rate_std: float = 0.5

    def __post_init__(self) -> None:
        for name in (
            "measurement_std",
            "bend_accel_psd",
            "paper_process_weight",
            "initial_bend_std",
            "initial_rate_std",
        ):
            _positive(name, getattr(self, name))


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
            :data:`DEFAULT_LOSS_SCALE` of the loss. Ignored for ``"l2"``.
        branch_check: after each window, test its measurement cost against a
            chi-square quantile and, where implausible, solve the same window from
            other starts and keep the lowest cost, then, if none wins, with the arrival
            prior forgotten (status ``branch-restart``; see
            :mod:`continuum_mhe.estimators.branch`). Off by default: measured in
            docs/model.md.
    """

    horizon: int = 30
    paper_start: bool = False
    max_iter: int = 100
    tol: float = 1e-8
    solver: MHESolver = "fast"
    loss: MHELoss = "l2"
    loss_scale: float | None = None
    branch_check: bool = False

    def __post_init__(self) -> None:
        if self.solver not in MHE_SOLVERS:
            raise UserError(f"solver must be one of {MHE_SOLVERS}, got {self.solver!r}")
        if self.loss not in MHE_LOSSES:
            raise UserError(f"loss must be one of {MHE_LOSSES}, got {self.loss!r}")
        if self.loss_scale is not None:
            _positive("loss_scale", self.loss_scale)
        if not (isinstance(self.horizon, int) and self.horizon >= 2):
            raise UserError(f"horizon must be an integer >= 2, got {self.horizon!r}")
        if not isinstance(self.branch_check, bool):
            raise UserError(f"branch_check must be True or False, got {self.branch_check!r}")
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise UserError(f"max_iter must be a positive integer, got {self.max_iter!r}")
        _positive("tol", self.tol)

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
#: 1 s (the command line's ``--freeze``) at 3 Hz or more already spans five samples, so
#: at the usual rates the duration decides as before and only slow or gappy data feel
#: the count.
FREEZE_MIN_SAMPLES = 5


@dataclass(frozen=True)
class RecoverySettings:
    """How every estimator recovers from gaps and frozen sensors, and when it says its
    estimate should not be trusted (:meth:`~continuum_mhe.estimators.base.Estimator.step`).

    Attributes:
        gap_reset: after no valid measurement for longer than this (s), the next valid
            sample restarts the estimator from its own measurement (status ``reset``)
            instead of continuing from a blind prediction; None: never (the library's
            default; the command line's ``--gap-reset`` default is 1 s).
        freeze: a sensor (measurement block) whose reading repeats exactly for longer
            than this (s), over at least ``freeze_samples`` consecutive samples none more
            than ``freeze`` s after the one before (a gap is not a freeze), is treated as
            dropped out until its reading changes; None: never (command line
            ``--freeze``, default 1 s).
        freeze_samples: the fewest consecutive samples with the same reading (the first
            one included) that can be a freeze (default :data:`FREEZE_MIN_SAMPLES`);
            the duration alone is not enough: two equal readings 60 s apart are a gap in
            the data, not a sensor seen to be stuck.
        bad_start: for this long (s) after each (re)start, and after each return of an
            IMU silent for longer than ``gap_reset`` (1 s when it is off), ``SAMPLES``
            consecutive readings inconsistent with the estimate (normalised innovation
            beyond a chi-square quantile; :mod:`continuum_mhe.estimators.start_check`)
            restart the estimator from the current reading (status ``reset``); None:
            never (the library's default; command line ``--bad-start``, default 2 s).
            Either way an estimate after such a return is ``uncertain`` until the
            returned IMU's readings have agreed with it for as long as that silence
            threshold.
        reject_reset: a robust MHE (``MHESettings.loss`` not ``l2``) whose newest reading
            was rejected as an outlier at every sample for longer than this (s)
            restarts from the next valid reading (status ``reset``): readings that
            disagree with the estimate for this long are taken as right and the
            estimate as lost (a redescending loss such as Welsch never follows them on
            its own; docs/robust.md). Acts only on estimators that flag outliers, so it
            is on in the library too; None: never (command line ``--reject-reset``).
        uncertain_fraction: an estimate whose tip position standard deviation
            (``sqrt(std_x^2 + std_y^2 + std_z^2)``) exceeds this fraction of the robot's
            length gets status ``uncertain`` instead of ``ok``.
    """

    gap_reset: float | None = None
    freeze: float | None = None
    uncertain_fraction: float = 0.1
    bad_start: float | None = None
    reject_reset: float | None = 0.5
    # last, so that the fields before it keep their positions
    freeze_samples: int = FREEZE_MIN_SAMPLES

    def __post_init__(self) -> None:
        for name in ("gap_reset", "freeze", "bad_start", "reject_reset"):
            value = getattr(self, name)
            if value is not None:
                _positive(name, value)
        _positive("uncertain_fraction", self.uncertain_fraction)
        n = self.freeze_samples
        if not (isinstance(n, numbers.Integral) and not isinstance(n, bool) and n >= 2):
            raise UserError(f"freeze_samples must be an integer >= 2, got {n!r}")
        object.__setattr__(self, "freeze_samples", int(n))
