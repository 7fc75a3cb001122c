"""An estimator of a robot that may carry an external load, as two hypotheses.

A tendon robot's model estimates the tip force (:attr:`Formulation.load_states
<continuum_mhe.model.formulations.Formulation.load_states>`). Where the readings are
tilt, or the IMUs' constant errors are not yet known, a small force and the IMUs'
misalignments and biases tilt the readings alike, and an estimator that carries the
force takes part of those errors for a load the robot does not have: the shape follows
that force, millimetres off. Two estimators of one kind run side by side on every
sample (the EKF: two compiled EKFs; the MHE on IPOPT: two windows):

- **loaded**: the model as it is, the force a state;
- **free of load**: the same model with the force and its derivatives held at zero
  (zero and certain at every start, no process noise: :class:`UnloadedKalmanInference`;
  the MHE's window pins them at zero at every node and conditions its arrival prior
  and covariance on them: :class:`UnloadedHorizonInference`).

Each step's innovation log-density (``log N(r; 0, S)``: the compiled EKF step's
``log_likelihood``; for the MHE, the EKF step from each hypothesis' previous answer to
the new reading, so that the windows are weighed as the filters are) of the two is
compared; for a formulation with :attr:`Formulation.evidence_given
<continuum_mhe.model.formulations.Formulation.evidence_given>` rows (a tendon robot with
one IMU: its tensions and its tip condition), the density of the other components (the
IMUs') given those. The tip condition is a pseudo-measurement of the model, always
zero, no reading of a load: its predicted density grows without bound where the tip
moment's sensitivity to the base curvature falls (a force near buckling), and weighed
in it lets a loaded hypothesis gone astray take the estimate of a robot free of load
(docs/tendon-studies.md, "The tip IMU alone under load"). Their difference, summed
with a memory of :data:`EVIDENCE_MEMORY` per reading, is the evidence for the robot free
of load (held where neither hypothesis has a valid reading, and only decaying where one
has no density). Against prior odds of ``exp(EVIDENCE_MARGIN)`` to 1 for a load, the
estimate is the free-of-load hypothesis' where the evidence exceeds
:data:`EVIDENCE_MARGIN`, else the loaded one's;
its covariance is the two hypotheses' mixture about it, weighted by those posterior
odds, so that the standard deviations carry what the other hypothesis would make of
the readings. A load that appears makes the free-of-load hypothesis' predictions miss the
readings, and the evidence turns within a few readings. Each hypothesis keeps its own
state between restarts: the free-of-load one's IMU errors are not the loaded one's,
which may have taken part of a load for them. A restart gives both the sensor states of
the estimate it keeps (the hypothesis chosen then). Where one hypothesis' step fails,
the sample's estimate is the other's, and the failed one starts again at the next
sample with the other's sensor states.

A start that knows nothing of the sensors and whose first reading shows a load (the
free-of-load start fit misses it beyond the IMUs' noise and their own errors:
:meth:`Formulation.unloaded_start
<continuum_mhe.model.formulations.Formulation.unloaded_start>`) cannot tell that load
from the IMUs' errors, and neither hypothesis' estimates can be trusted: the inference
says so (:meth:`LoadHypothesesInference.start_untrusted`), and the estimator's policy
makes every estimate of that start that would be ``ok`` ``uncertain`` (``drifted``
where its IMU errors have left their prior) until the next restart, as for every
estimator of such a robot (``Diagnostics.untrusted_start_samples`` counts them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import Inference, Measurement, Status, judged_untrusted
from continuum_mhe.estimators.fast.model import Feasible
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.estimators.mhe import MovingHorizonInference, ReferenceWindow
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.estimators.sensor_health import NUMERICAL_FAILURES, Estimator
from continuum_mhe.estimators.window_nlp import Nlp
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings

#: The weight of the evidence of the reading before, per reading: the evidence is
#: ``EVIDENCE_MEMORY * evidence + (log N_free - log N_loaded)`` (a memory of about ten
#: readings, so that a load that appears is followed within a few).
EVIDENCE_MEMORY = 0.9
#: The evidence above which the robot is taken as free of load: prior odds of
#: ``exp(EVIDENCE_MARGIN)`` to 1 for a load, so that a load that grows from zero is
#: followed before the free-of-load filter has bent its IMU errors to it.
EVIDENCE_MARGIN = 3.0


_Answer = tuple[FloatArray, FloatArray]
_Hypothesis = CompiledExtendedKalmanInference | MovingHorizonInference


def _step(
    hypothesis: _Hypothesis, m: Measurement
) -> tuple[tuple[FloatArray | None, FloatArray | None, Status] | None, float]:
    """``((x, P, status), log-likelihood)`` of one hypothesis' step, or ``(None, nan)``
    where it failed: a numerical failure, or a state or covariance that is not finite."""
    try:
        x, P, status = hypothesis.infer(m)
    except NUMERICAL_FAILURES:
        return None, math.nan
    if (x is not None and not np.isfinite(x).all()) or (P is not None and not np.isfinite(P).all()):
        return None, math.nan
    return (x, P, status), hypothesis.log_likelihood


class UnloadedKalmanInference(CompiledExtendedKalmanInference):
    """The compiled EKF with the formulation's load states held at zero: its starts
    are :meth:`~continuum_mhe.model.formulations.Formulation.unloaded_start`'s, its
    process noise has none on them.

    Attributes:
        start_shows_load: whether the reading of its last start showed a load that the
            start could not tell from the sensors' errors (``unloaded_start``).
    """

    def __init__(self, formulation: Formulation) -> None:
        super().__init__(formulation)
        self._q = ProcessNoiseCache(formulation, held=formulation.load_states)
        self.start_shows_load = False

    def start_prior(self, z: FloatArray, t: float | None = None) -> tuple[FloatArray, FloatArray]:
        self.kept_sensors = self.kept_at(t)
        x, P, self.start_shows_load = self.formulation.unloaded_start(z, self.kept_sensors)
        return x, P


class UnloadedHorizonInference(MovingHorizonInference):
    """The MHE on IPOPT with the formulation's load states held at zero: its starts are
    :meth:`~continuum_mhe.model.formulations.Formulation.unloaded_start`'s, the load
    states are pinned at zero at every node of the window (IPOPT's bounds), and its
    arrival prior and covariances are conditioned on them (the covariance's feasible set
    pins them: they carry no variance, nor does the shape through them). Its
    :attr:`log_likelihood` is always tracked.

    Attributes:
        start_shows_load: whether the reading of its last start showed a load that the
            start could not tell from the sensors' errors (``unloaded_start``).
    """

    def __init__(self, formulation: Formulation, settings: MHESettings) -> None:
        if settings.solver != "ipopt":
            raise UserError(
                "the MHE free of load runs on IPOPT (solver='ipopt'): the fast MHE "
                "cannot take a model with load states"
            )
        super().__init__(formulation, settings)
        held = np.asarray(formulation.load_states, dtype=np.intp)
        self._held = held
        self._free = np.setdiff1d(np.arange(formulation.nx), held)
        #: the load states' entries in the window's decision vector (node by node)
        self._held_in_window = (
            np.arange(settings.horizon)[:, None] * formulation.nx + held[None, :]
        ).ravel()
        #: the pinned states' prior variances (any positive value: they do not move)
        self._held_var = np.diag(formulation.initial_cov())[held].copy()
        self._process_weight = ProcessNoiseCache(formulation, held=formulation.load_states)
        window = self._window
        assert isinstance(window, ReferenceWindow)
        lo, hi = (np.array(v, dtype=float) for v in formulation.state_bounds())
        lo[held] = hi[held] = 0.0
        fs = window.feasible
        window.feasible = (
            Feasible(lo, hi, np.zeros((0, 1), dtype=np.int64), np.zeros(0))
            if fs is None
            else replace(fs, lo=lo, hi=hi)
        )
        window.condition = self.conditioned
        self.start_shows_load = False
        self.tracks_likelihood = True

    def conditioned(self, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(x, P)`` (nx,), (nx, nx) conditioned on the load states at zero: the other
        states' Gaussian conditional, the load states zero with their prior variances and
        no correlation (where ``P`` holds them certain, the others as given)."""
        h, k = self._held, self._free
        x, P = np.array(x, dtype=float), np.array(P, dtype=float)
        P_kh = P[np.ix_(k, h)]
        gain = P_kh @ np.linalg.pinv(P[np.ix_(h, h)], rcond=1e-12, hermitian=True)
        xc = np.zeros_like(x)
        xc[k] = x[k] - gain @ x[h]
        Pc = np.zeros_like(P)
        Pc[np.ix_(k, k)] = P[np.ix_(k, k)] - gain @ P_kh.T
        Pc[h, h] = self._held_var
        return xc, 0.5 * (Pc + Pc.T)

    def _set_prior(self, xbar: FloatArray, P: FloatArray) -> None:
        super()._set_prior(*self.conditioned(xbar, P))

    def _window_nlp(self, scale_exp: int) -> Nlp:
        nlp = super()._window_nlp(scale_exp)
        idx = self._held_in_window
        if np.any(nlp.lbx[idx] != 0.0) or np.any(nlp.ubx[idx] != 0.0):
            lbx, ubx = np.array(nlp.lbx, dtype=float), np.array(nlp.ubx, dtype=float)
            lbx[idx] = ubx[idx] = 0.0
            nlp = replace(nlp, lbx=lbx, ubx=ubx)
            self._nlps[scale_exp] = nlp
        return nlp

    def start_prior(self, z: FloatArray, t: float | None = None) -> tuple[FloatArray, FloatArray]:
        self.kept_sensors = self.kept_at(t)
        self.fresh_start = self.kept_sensors is None
        x, P, self.start_shows_load = self.formulation.unloaded_start(z, self.kept_sensors)
        return x, P


class LoadHypothesesInference(Inference):
    """The EKF of a formulation with load states, as the robot loaded and free of load
    (see the module docstring), ``name`` ``ekf``; with ``mhe`` (the MHE's settings, its
    solver IPOPT) the MHE, ``name`` ``mhe``.

    Attributes:
        loaded: the EKF (or MHE) with the load as states.
        unloaded: the EKF (or MHE) with the load held at zero.
        evidence: the log-likelihood ratio, free of load over loaded, with its memory.
        unloaded_chosen: whether the last estimate is the free-of-load hypothesis'.
        free_of_load_samples: the estimates the free-of-load hypothesis gave since the
            estimator's last reset.
        load_at_start: whether the current start's first reading showed a load it
            could not tell from the sensors' errors (see the module docstring).
    """

    name = "ekf"

    def __init__(self, formulation: Formulation, mhe: MHESettings | None = None) -> None:
        super().__init__(formulation)
        self.loaded: _Hypothesis
        self.unloaded: UnloadedKalmanInference | UnloadedHorizonInference
        if mhe is None:
            self.loaded = CompiledExtendedKalmanInference(formulation)
            self.unloaded = UnloadedKalmanInference(formulation)
        else:
            self.unloaded = UnloadedHorizonInference(formulation, mhe)
            loaded = MovingHorizonInference(formulation, mhe)
            loaded.tracks_likelihood = True
            self.loaded = loaded
            self.name = "mhe"
            #: the MHE's settings (its horizon, for the policy's messages)
            self.settings = mhe
            self.holds_bounds = True
            self.flags_outliers = loaded.flags_outliers
        # each reading weighs the hypotheses by the density of its components given
        # the formulation's evidence_given ones (a one-IMU tendon robot's: the IMUs given
        # the tensions and the tip condition)
        given = formulation.evidence_given
        self.loaded.likelihood_given = self.unloaded.likelihood_given = given
        self.evidence = 0.0
        self.unloaded_chosen = False
        self._chosen: _Hypothesis = self.loaded
        self.free_of_load_samples = 0
        self.load_at_start = False
        #: the time of the current start's first sample, s
        self._start_t = math.nan
        #: the time of the last answer counted, and whether it counted it as free of load
        self._counted_t: float | None = None
        self._counted = 0
        #: the last answer's covariance and the loaded hypothesis' answer at that sample
        self._answer_P: FloatArray | None = None
        self._loaded_answer: _Answer | None = None

    def clear_counts(self) -> None:
        self.free_of_load_samples = 0
        self._counted_t = None
        self.loaded.clear_counts()
        self.unloaded.clear_counts()

    def sync_counts(self) -> None:
        self.loaded.sync_counts()
        self.unloaded.sync_counts()

    def outlier(self) -> bool:
        return self._chosen.outlier()

    def rejected_every_reading(self, rows: Sequence[int] | None = None) -> bool | None:
        return self._chosen.rejected_every_reading(rows)

    def close_recording(self) -> None:
        self._counted_t = None  # a sample at the same time is then another one

    def forget(self) -> None:
        """Both hypotheses restart, keeping the sensor states of the estimate the restart
        keeps (the chosen hypothesis' at that time: where the loaded one was chosen, the
        free-of-load filter's IMU errors may have taken part of the load), and the
        evidence is zero."""
        kept = (None, None, None) if self._kept is None else self._kept
        self._loaded_answer = None  # the floor of a free-of-load answer: none before one
        self.loaded.restart(*kept)
        self.unloaded.restart(*kept)
        self.evidence = 0.0
        self.unloaded_chosen = False
        self.load_at_start = False
        self._start_t = math.nan
        self._chosen = self.loaded

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        if self._counted_t is not None and m.t == self._counted_t:
            self.free_of_load_samples -= self._counted  # the policy steps this sample again
        self._counted_t = None
        starting = not self.unloaded.has_state
        got_l, ll_loaded = _step(self.loaded, m)
        got_u, ll_free = _step(self.unloaded, m)
        if starting and self.unloaded.has_state and self.unloaded.kept_sensors is None:
            self._start_t = m.t  # a start of the estimator
            self.load_at_start = self.unloaded.start_shows_load
        if got_l is None and got_u is None:
            raise FloatingPointError(f"both hypotheses' {self.name} steps failed (non-finite)")
        # a hypothesis whose step failed starts again at the next sample, keeping the
        # other's sensor states; this sample's answer is the other's alone
        if got_l is None and got_u is not None:
            self.loaded.restart(got_u[0], got_u[1], m.t)
            return self._answer(self.unloaded, m, got_u[0], got_u[1], got_u[2])
        if got_u is None and got_l is not None:
            self.unloaded.restart(got_l[0], got_l[1], m.t)
            return self._answer(self.loaded, m, got_l[0], got_l[1], got_l[2])
        assert got_l is not None and got_u is not None
        (xl, Pl, status), (xu, Pu, status_u) = got_l, got_u
        if xl is None or Pl is None or xu is None or Pu is None:
            # one without an estimate yet (restarted after a failure, and this sample
            # without a valid reading to start from): the other's, where it has one
            if xu is not None and Pu is not None:
                return self._answer(self.unloaded, m, xu, Pu, status_u)
            if xl is not None and Pl is not None:
                return self._answer(self.loaded, m, xl, Pl, status)
            self._chosen, self.unloaded_chosen = self.loaded, False
            return xl, Pl, status  # no estimate yet
        if self.loaded.outlier() or self.unloaded.outlier():
            pass  # a reading a robust window rejects weighs neither hypothesis: held
        elif math.isfinite(ll_loaded) and math.isfinite(ll_free):
            self.evidence = EVIDENCE_MEMORY * self.evidence + (ll_free - ll_loaded)
        elif math.isfinite(ll_loaded) or math.isfinite(ll_free):
            self.evidence *= EVIDENCE_MEMORY  # one side without a density: no new evidence
        # the odds of the robot free of load: the evidence against the prior odds of a load
        log_odds = self.evidence - EVIDENCE_MARGIN
        self._loaded_answer = (xl, Pl)
        if log_odds > 0.0:
            return self._answer(self.unloaded, m, xu, mixture(xu, Pu, xl, Pl, log_odds), status_u)
        return self._answer(self.loaded, m, xl, mixture(xl, Pl, xu, Pu, -log_odds), status)

    def _answer(
        self,
        hypothesis: _Hypothesis,
        m: Measurement,
        x: FloatArray | None,
        P: FloatArray | None,
        status: Status,
    ) -> tuple[FloatArray | None, FloatArray | None, Status]:
        """``(x, P, status)`` as the answer of ``hypothesis``, counted where it is the
        free-of-load one (where the loaded one has no answer at this sample, the
        free-of-load answer's standard deviations are floored by the loaded hypothesis'
        last answer since the hypotheses' restart, if any)."""
        self._chosen = hypothesis
        self._answer_P = P
        self.unloaded_chosen = hypothesis is self.unloaded
        self.kept_sensors = hypothesis.kept_sensors
        free = int(self.unloaded_chosen and x is not None)
        self.free_of_load_samples += free
        self._counted = free
        self._counted_t = m.t if free else None
        return x, P, status

    def start_untrusted(self, t: float, z: FloatArray) -> bool:
        """Whether the current start, which knows nothing of the sensors, shows at its
        first IMU reading ``z`` (at ``t`` s) a load it could not tell from the IMUs'
        errors: :attr:`load_at_start` (the free-of-load hypothesis' start fit, no second
        fit) where that reading is the start's own, else the formulation's judgement of
        ``z`` (a start on a sample without IMU readings)."""
        if self._kept is not None:  # the estimator's restart kept the sensor states
            return False
        if t == self._start_t:
            return self.load_at_start
        return judged_untrusted(self.formulation, z)

    def output(self, state: FloatArray) -> FloatArray:
        return self._chosen.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        """The chosen hypothesis' output standard deviations; for the answer of the
        free-of-load one, each at least the loaded hypothesis' at that sample, or at its
        last answer where its step failed there (the load outputs, 0 N held, and the
        shape): a load smaller than what the loaded filter can tell from none is not
        excluded by taking the robot as free of load, nor is the shape it would bend the
        robot into."""
        std = np.array(self._chosen.output_std(state, cov), dtype=float)
        loaded = self._loaded_answer
        if self.unloaded_chosen and cov is self._answer_P and loaded is not None:
            floor = np.asarray(self.loaded.output_std(loaded[0], loaded[1]), dtype=float)
            std = np.maximum(std, floor)
        return std


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


class LoadHypothesesHorizonEstimator(Estimator[LoadHypothesesInference]):
    """The MHE on IPOPT of a robot that may carry a load (``make_estimator("mhe", ...)``
    gives it for a formulation with load states and ``MHESettings(solver="ipopt")``): the
    two windows of :class:`LoadHypothesesInference` with the sensor-health policy. It
    costs two window solves a sample."""

    def __init__(
        self,
        formulation: Formulation,
        settings: MHESettings,
        recovery: RecoverySettings | None = None,
    ) -> None:
        super().__init__(LoadHypothesesInference(formulation, settings), recovery)
