"""Typed, frozen settings of the model: the one-section robot of the paper's
formulations (:class:`RobotSettings`) and the noise model every estimator shares
(:class:`NoiseSettings`). Every field is validated on construction."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from continuum_mhe.errors import UserError, is_real
from continuum_mhe.model.imu import MOUNTINGS, Mounting
from continuum_mhe.model.robot import Section

FormulationName = Literal["bend", "paper", "direct", "tendon"]
FORMULATIONS: tuple[FormulationName, ...] = ("bend", "paper")


def check_positive(name: str, value: float) -> None:
    """Raise a :class:`UserError` unless ``value`` is a positive finite number."""
    if not (is_real(value) and math.isfinite(value) and value > 0):
        raise UserError(f"{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class RobotSettings:
    """One inextensible constant-curvature section with an IMU at its tip.

    Attributes:
        length: section length ``s`` in metres.
        theta_max: upper bound on the bending angle ``theta`` in radians; the default
            is the paper's ``pi/2`` (eq. 11), which clips a robot that bends further (a
            :class:`~continuum_mhe.model.robot.Section` and a robot file default to 3.0,
            a bound a robot does not reach). Must lie in ``[0.01, pi)``.
        mounting: ``"z-up"`` (base z against gravity) or ``"z-down"`` (hanging).
    """

    length: float = 0.2
    theta_max: float = math.pi / 2
    mounting: Mounting = "z-up"

    def __post_init__(self) -> None:
        check_positive("length", self.length)
        Section(self.length, self.theta_max)  # a section's range checks (m, rad)
        if self.mounting not in MOUNTINGS:
            raise UserError(f"mounting must be one of {MOUNTINGS}, got {self.mounting!r}")


#: Smallest measurement standard deviation accepted, rad (0.2 arcseconds).
MIN_MEASUREMENT_STD = 1e-6
#: Smallest prior standard deviation of a start accepted (rad, rad/s): a finer one's
#: variance is below what the estimators' matrices hold beside the readings' weights.
MIN_PRIOR_STD = 1e-9
#: Largest, rad (90 degrees, the command line's --noise-deg range: beyond it the value
#: is in degrees).
MAX_MEASUREMENT_STD = math.pi / 2


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
            ``(theta, phi)``, rad (at least :data:`MIN_PRIOR_STD`).
        initial_rate_std: prior standard deviation of the initial bend rates, rad/s (at
            least :data:`MIN_PRIOR_STD`).
        reading_bias_std: the constant error of each gravity-direction reading, rad
            (an IMU's mounting misalignment, about 1 degree by hand, and its
            accelerometer bias, 0.1 m/s^2 or 0.6 degree, in quadrature): no residual
            shows it, so it widens every output standard deviation by the estimate's
            sensitivity to it (:mod:`continuum_mhe.estimators.consistency`); 0 for
            data without it (simulated IMUs mounted exactly).
        model_error_std: the error of each gravity-direction reading that the
            constant-curvature model is taken to make of a real robot before the readings
            show one, rad (a curvature that varies along a section, a twist that turns an
            IMU's frame; with one IMU per section the readings fit such a shape exactly
            and no residual shows it): carried as a constant error, as
            ``reading_bias_std`` is, until the model error learned from the innovations
            exceeds it (:mod:`continuum_mhe.estimators.consistency`); 0 for data the
            model generated.
    """

    measurement_std: float = math.radians(2.0)
    bend_accel_psd: float = 0.5
    paper_process_weight: float = 10.0
    initial_bend_std: float = 0.1
    initial_rate_std: float = 0.5
    reading_bias_std: float = math.radians(1.2)
    model_error_std: float = math.radians(1.7)

    def __post_init__(self) -> None:
        if is_real(self.measurement_std) and 0 < self.measurement_std < MIN_MEASUREMENT_STD:
            raise UserError(
                f"measurement_std {self.measurement_std!r} rad is below "
                f"{MIN_MEASUREMENT_STD:g} rad ({math.degrees(MIN_MEASUREMENT_STD):.2g} deg), "
                "finer than any IMU: its weight 1/std^2 makes the estimators' matrices singular"
            )
        check_positive("measurement_std", self.measurement_std)
        _refuse_degrees_like("measurement_std", self.measurement_std)
        for name in (
            "measurement_std",
            "bend_accel_psd",
            "paper_process_weight",
            "initial_bend_std",
            "initial_rate_std",
        ):
            check_positive(name, getattr(self, name))
        for name in ("initial_bend_std", "initial_rate_std"):
            value = getattr(self, name)
            if not value * value < math.inf:  # a variance no float holds
                raise UserError(f"{name} {value!r} is too large: its square is no float")
            if value < MIN_PRIOR_STD:
                raise UserError(
                    f"{name} {value!r} is below {MIN_PRIOR_STD:g}: a start held that "
                    "tightly makes the estimators' matrices singular (give the prior's "
                    "standard deviation in rad or rad/s)"
                )
        for name in ("reading_bias_std", "model_error_std"):
            value = getattr(self, name)
            if not (is_real(value) and math.isfinite(value) and value >= 0):
                raise UserError(f"{name} must be a finite number >= 0 (rad), got {value!r}")
            _refuse_degrees_like(name, value)  # no reading's constant error is that large


def _refuse_degrees_like(name: str, value: float) -> None:
    """A :class:`UserError` where the angle ``value`` (rad) of the setting ``name`` is
    beyond :data:`MAX_MEASUREMENT_STD`: degrees given for radians."""
    if value > MAX_MEASUREMENT_STD:
        raise UserError(
            f"{name} {value!r} rad ({math.degrees(value):.3g} deg) is beyond 90 degrees: "
            f"degrees? it is in radians ({value!r} deg = {math.radians(value):.4g} rad)"
        )
