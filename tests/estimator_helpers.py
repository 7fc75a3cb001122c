"""Shared test helpers: the five estimators of the recovery tests, and the fast MHE
against IPOPT on the same samples."""

from __future__ import annotations

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.base import Estimator, Measurement
from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.kalman import ExtendedKalmanFilter
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.model.formulations import BendFormulation, Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings


def recovery_estimators(recovery: RecoverySettings) -> list[Estimator]:
    """Compiled EKF, CasADi EKF, UKF, fast MHE and IPOPT MHE (N = 10) on the default
    bend formulation, all with ``recovery``."""
    f = BendFormulation()
    out: list[Estimator] = [
        make_estimator("ekf", f, recovery=recovery),
        ExtendedKalmanFilter(f),
        make_estimator("ukf", f, recovery=recovery),
        make_estimator("mhe", f, MHESettings(horizon=10), recovery),
        make_estimator("mhe", f, MHESettings(horizon=10, solver="ipopt"), recovery),
    ]
    out[1].recovery = recovery  # the CasADi EKF too
    return out


def fast_and_ipopt_states(
    f: Formulation, t: np.ndarray, z: np.ndarray, horizon: int
) -> dict[str, np.ndarray]:
    """``{"fast": states, "ipopt": states}`` (n, nx) of the MHE on both backends (the
    fast one on CasADi's VM), every sample asserted ``ok``."""
    states = {}
    for solver in ("fast", "ipopt"):
        est = MovingHorizonEstimator(
            f, MHESettings(horizon=horizon, solver=solver), FastOptions(compile=False)
        )
        res = [est.step(Measurement(float(t[i]), z[i])) for i in range(len(t))]
        assert {r.status for r in res} == {"ok"}
        states[solver] = np.array([r.state for r in res])
    return states
