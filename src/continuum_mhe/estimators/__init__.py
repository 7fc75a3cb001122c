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
    CasadiExtendedKalmanFilter,
    ExtendedKalmanFilter,
    UnscentedKalmanFilter,
)
from continuum_mhe.estimators.load_hypotheses import (
    LoadHypothesesHorizonEstimator,
    LoadHypothesesKalmanFilter,
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
    robot's mechanics model: its MHE solves every window with IPOPT, seconds to minutes a
    sample)."""
    return "mhe" if formulation.fast_mhe_obstacle is None else "ekf"


def make_estimator(
    method: Method,
    formulation: Formulation,
    mhe: MHESettings | None = None,
    recovery: RecoverySettings | None = None,
) -> Estimator:
    """Estimator by name on ``formulation``.

    ``recovery`` (gap reset, frozen sensors, ``uncertain``) applies to every method.
    ``mhe`` describes the MHE's window (its horizon, start, solver and cost) and applies
    to ``"mhe"``; the EKF and the UKF have no window, and take the same ``mhe`` without
    using it, so that one settings object serves a loop over :data:`METHODS`. A robust
    ``loss`` (other than ``"l2"``) with ``"ekf"`` or ``"ukf"`` is a
    :class:`~continuum_mhe.errors.UserError` (a ``ValueError``): those filters keep the
    l2 cost, so the estimate asked for is the MHE's (``method="mhe"``), or ``mhe=None``
    (or ``loss="l2"``) for the filter.

    ``"ekf"`` is :class:`ExtendedKalmanFilter`, or for a formulation with load states (a
    tendon robot's tip force) :class:`LoadHypothesesKalmanFilter`, which weighs the
    robot free of load against loaded; ``"mhe"`` on such a formulation with
    ``MHESettings(solver="ipopt")`` (the fast MHE cannot take it) is
    :class:`LoadHypothesesHorizonEstimator`, the same two hypotheses as two windows.
    """
    if isinstance(method, Formulation):  # the formulation given first
        raise UserError(
            "make_estimator takes the method first: make_estimator('mhe', formulation) "
            f"(one of {', '.join(METHODS)}), got a formulation as the method"
        )
    if not isinstance(method, str) or method not in METHODS:  # (an array: no truth value)
        raise UserError(f"method must be one of {METHODS}, got {method!r:.60}")
    expect_type("formulation", formulation, Formulation, "a Formulation (make_formulation)")
    expect_type("mhe", mhe, (MHESettings, type(None)), "MHESettings or None")
    expect_type("recovery", recovery, (RecoverySettings, type(None)), "RecoverySettings or None")
    if method != "mhe" and mhe is not None and mhe.loss != "l2":
        raise UserError(
            f"mhe loss={mhe.loss!r} is the MHE's robust cost; the {method} keeps the l2 "
            f"cost: method='mhe' for the robust loss, or mhe=None (or loss='l2') for the "
            f"{method}"
        )
    return _make(method, formulation, mhe, recovery)


def _make(
    method: Method,
    formulation: Formulation,
    mhe: MHESettings | None,
    recovery: RecoverySettings | None,
) -> Estimator:
    if method == "mhe" and formulation.load_states and mhe is not None and mhe.solver == "ipopt":
        return LoadHypothesesHorizonEstimator(formulation, mhe, recovery)
    if method == "mhe":
        return MovingHorizonEstimator(formulation, mhe, recovery=recovery)
    if method == "ekf" and formulation.load_states:
        return LoadHypothesesKalmanFilter(formulation, recovery)
    if method == "ekf":
        return ExtendedKalmanFilter(formulation, recovery)
    if method == "ukf":
        return UnscentedKalmanFilter(formulation, recovery=recovery)
    raise UserError(f"method must be one of {METHODS}, got {method!r}")


__all__ = [
    "METHODS",
    "Diagnostics",
    "Estimate",
    "EstimateSeries",
    "Estimator",
    "ExtendedKalmanFilter",
    "CasadiExtendedKalmanFilter",
    "Inference",
    "LoadHypothesesHorizonEstimator",
    "LoadHypothesesKalmanFilter",
    "Measurement",
    "Method",
    "MovingHorizonEstimator",
    "Status",
    "default_method",
    "UnscentedKalmanFilter",
    "make_estimator",
]
