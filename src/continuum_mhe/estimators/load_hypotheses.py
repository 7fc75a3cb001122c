"""The EKF of a robot that may carry an external load, as two hypotheses.

A tendon robot's model estimates the tip force (:attr:`Formulation.load_states
<continuum_mhe.model.formulations.Formulation.load_states>`). Where the readings are
tilt, or the IMUs' constant errors are not yet known, a small force and the IMUs'
misalignments and biases tilt the readings alike, and a filter that carries the force
takes part of those errors for a load the robot does not have: the shape follows that
force, millimetres off. Two compiled EKFs run side by side on every sample:

- **loaded**: the model as it is, the force a state;
- **free of load**: the same model with the force and its derivatives held at zero
  (zero and certain at every start, no process noise: :class:`UnloadedKalmanInference`).

Each step's innovation log-density (``log N(r; 0, S)``, the compiled step's
``log_likelihood``) of the two is compared; their difference, summed with a memory of
:data:`EVIDENCE_MEMORY` per reading, is the evidence for the robot free of load. The
estimate is the hypothesis that evidence favours (free of load where it is positive),
and its covariance is the two hypotheses' mixture about it, weighted by the evidence's
odds, so that the standard deviations carry what the other hypothesis would make of
the readings. A load that appears makes the free-of-load filter's predictions miss the
readings, and the evidence turns within a few readings. Each hypothesis keeps its own
state: the free-of-load filter's IMU errors are never the loaded one's, which may have
taken part of a load for them.
"""

from __future__ import annotations

import math

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Inference, Measurement, Status
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import RecoverySettings

#: The weight of the evidence of the reading before, per reading: the evidence is
#: ``EVIDENCE_MEMORY * evidence + (log N_free - log N_loaded)`` (a memory of about ten
#: readings, so that a load that appears is followed within a few).
EVIDENCE_MEMORY = 0.9
#: The evidence above which the robot is taken as free of load: prior odds of
#: ``exp(EVIDENCE_MARGIN)`` to 1 for a load, so that a load that grows from zero is
#: followed before the free-of-load filter has bent its IMU errors to it.
EVIDENCE_MARGIN = 3.0


class _NoiseWithoutLoad:
    """A process-noise cache's ``(Q, Q^-1)`` with the load states' rows and columns of
    ``Q`` zero (the force held: no random walk)."""

    def __init__(self, inner: object, load: tuple[int, ...]) -> None:
        self._inner = inner
        self._load = np.asarray(load, dtype=np.intp)
        self._cache: dict[float, tuple[FloatArray, FloatArray]] = {}

    def __call__(self, dt: float) -> tuple[FloatArray, FloatArray]:
        key = round(dt, 9)
        got = self._cache.get(key)
        if got is None:
            Q, Qinv = self._inner(dt)  # type: ignore[operator]
            Q = np.array(Q, dtype=float)
            Q[self._load, :] = 0.0
            Q[:, self._load] = 0.0
            got = (Q, Qinv)
            if len(self._cache) < 4096:
                self._cache[key] = got
        return got


class UnloadedKalmanInference(CompiledExtendedKalmanInference):
    """The compiled EKF with the formulation's load states held at zero: its starts
    are :meth:`~continuum_mhe.model.formulations.Formulation.unloaded_start_prior`, its
    process noise has none on them."""

    def __init__(self, formulation: Formulation) -> None:
        super().__init__(formulation)
        self._q = _NoiseWithoutLoad(self._q, formulation.load_states)  # type: ignore[assignment]

    def start_prior(self, z: FloatArray, t: float | None = None) -> tuple[FloatArray, FloatArray]:
        self.kept_sensors = self.kept_at(t)
        return self.formulation.unloaded_start_prior(z, self.kept_sensors)

    def policy_inference(self) -> None:
        return None  # stepped by LoadHypothesesInference


class LoadHypothesesInference(Inference):
    """The EKF of a formulation with load states, as the robot loaded and free of load
    (see the module docstring); ``name`` ``ekf``.

    Attributes:
        loaded: the EKF with the load as states.
        unloaded: the EKF with the load held at zero.
        evidence: the log-likelihood ratio, free of load over loaded, with its memory.
        unloaded_chosen: whether the last estimate is the free-of-load hypothesis'.
        free_of_load_samples: the estimates the free-of-load hypothesis gave since the
            estimator's last reset.
    """

    name = "ekf"

    def __init__(self, formulation: Formulation) -> None:
        super().__init__(formulation)
        self.loaded = CompiledExtendedKalmanInference(formulation)
        self.unloaded = UnloadedKalmanInference(formulation)
        self.evidence = 0.0
        self.unloaded_chosen = False
        self._chosen: CompiledExtendedKalmanInference = self.loaded
        self.free_of_load_samples = 0

    def clear_counts(self) -> None:
        self.free_of_load_samples = 0

    def forget(self) -> None:
        """Both hypotheses restart, with the sensor states the restart kept (each keeps
        them from the estimate before it), and the evidence is zero."""
        kept = (None, None, None) if self._kept is None else self._kept
        self.loaded.restart(*kept)
        self.unloaded.restart(*kept)
        self.evidence = 0.0
        self.unloaded_chosen = False
        self._chosen = self.loaded

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        xl, Pl, status = self.loaded.infer(m)
        if xl is None or Pl is None:
            return xl, Pl, status
        ll_loaded = self.loaded.log_likelihood
        xu, Pu, _ = self.unloaded.infer(m)
        ll_free = self.unloaded.log_likelihood
        kept = self.loaded.kept_sensors
        self.kept_sensors = kept
        if math.isfinite(ll_loaded) and math.isfinite(ll_free):
            self.evidence = EVIDENCE_MEMORY * self.evidence + (ll_free - ll_loaded)
        free = xu is not None and Pu is not None and self.evidence > EVIDENCE_MARGIN
        self.unloaded_chosen = free
        if not free or xu is None or Pu is None:
            self._chosen = self.loaded
            x, P = xl, Pl
            if xu is not None and Pu is not None:
                P = mixture(xl, Pl, xu, Pu, -self.evidence)
        else:
            self._chosen = self.unloaded
            self.free_of_load_samples += 1
            x, P = xu, mixture(xu, Pu, xl, Pl, self.evidence)
        return x, P, status

    def output(self, state: FloatArray) -> FloatArray:
        return self._chosen.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        return self._chosen.output_std(state, cov)


def mixture(
    x: FloatArray, P: FloatArray, x_other: FloatArray, P_other: FloatArray, log_odds: float
) -> FloatArray:
    """The covariance about ``x`` of the mixture of ``N(x, P)`` and ``N(x_other,
    P_other)``, the first weighted by ``1 / (1 + exp(-log_odds))`` (``log_odds``: the
    log of its odds against the other)."""
    w_other = 1.0 / (1.0 + math.exp(min(log_odds, 700.0)))
    d = np.asarray(x_other, dtype=float) - np.asarray(x, dtype=float)
    return np.asarray((1.0 - w_other) * P + w_other * (P_other + np.outer(d, d)), dtype=float)


class LoadHypothesesKalmanFilter(Estimator[LoadHypothesesInference]):
    """The EKF of a robot that may carry a load (``make_estimator("ekf", ...)`` gives it
    for a formulation with :attr:`~continuum_mhe.model.formulations.Formulation.
    load_states`): :class:`LoadHypothesesInference` with the sensor-health policy of
    :class:`~continuum_mhe.estimators.sensor_health.Estimator`."""

    def __init__(self, formulation: Formulation, recovery: RecoverySettings | None = None):
        super().__init__(LoadHypothesesInference(formulation), recovery)
