"""Estimators with one interface: ``step(Measurement) -> Estimate`` and ``run``.

Each estimator is the sensor-health policy (:class:`Estimator`,
:mod:`.sensor_health`) around an inference object (:class:`Inference`: the MHE's
window solver, the EKF, the UKF); :class:`Diagnostics` says what the policy did.
"""

from __future__ import annotations

from typing import Literal

from continuum_mhe.errors import UserError, expect_type
from continuum_mhe.estimators.base import (
    Estimate,
    EstimateSeries,
    Inference,
    Measurement,
    Status,
)
from continuum_mhe.estimators.kalman import (
    CompiledExtendedKalmanFilter,
    ExtendedKalmanFilter,
    UnscentedKalmanFilter,
)
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.estimators.sensor_health import Diagnostics, Estimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings

Method = Literal["mhe", "ekf", "ukf"]
METHODS: tuple[Method, ...] = ("mhe", "ekf", "ukf")


def default_method(formulation: Formulation) -> Method:
    """The estimator ``formulation`` gets when none is chosen: the MHE on its fast
    backend, or the EKF where the fast backend cannot take the formulation
    (:attr:`~continuum_mhe.model.formulations.Formulation.fast_mhe_obstacle`, a tendon
    robot's mechanics model: its MHE solves every window with IPOPT, seconds a sample)."""
    return "mhe" if formulation.fast_mhe_obstacle is None else "ekf"


def make_estimator(
    method: Method,
    formulation: Formulation,
    mhe: MHESettings | None = None,
    recovery: RecoverySettings | None = None,
) -> Estimator:
    """Estimator by name on ``formulation``; ``mhe`` settings apply to ``"mhe"`` only,
    ``recovery`` (gap reset, frozen sensors, ``uncertain``) to every method.
    """
    if method not in METHODS:
        raise UserError(f"method must be one of {METHODS}, got {method!r}")
    expect_type("formulation", formulation, Formulation, "a Formulation (make_formulation)")
    expect_type("mhe", mhe, (MHESettings, type(None)), "MHESettings or None")
    expect_type("recovery", recovery, (RecoverySettings, type(None)), "RecoverySettings or None")
    return _make(method, formulation, mhe, recovery)


def _make(
    method: Method,
    formulation: Formulation,
    mhe: MHESettings | None,
    recovery: RecoverySettings | None,
) -> Estimator:
    if method == "mhe":
        return MovingHorizonEstimator(formulation, mhe, recovery=recovery)
    if method == "ekf":
        return CompiledExtendedKalmanFilter(formulation, recovery)
    if method == "ukf":
        return UnscentedKalmanFilter(formulation, recovery=recovery)
    raise UserError(f"method must be one of {METHODS}, got {method!r}")


__all__ = [
    "METHODS",
    "Diagnostics",
    "Estimate",
    "EstimateSeries",
    "Estimator",
    "CompiledExtendedKalmanFilter",
    "ExtendedKalmanFilter",
    "Inference",
    "Measurement",
    "Method",
    "MovingHorizonEstimator",
    "Status",
    "default_method",
    "UnscentedKalmanFilter",
    "make_estimator",
]
