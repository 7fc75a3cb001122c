"""Extended and unscented Kalman filters on a formulation's model.

Both use exactly the formulation's ``Q(dt)`` and ``R`` (the same numbers the MHE
weights with). Innovations use the formulation's residual ``r(z, x)``. Validity is per
measurement block: a sensor that dropped out is left out of the update, the others are
used. The pure functions :func:`ekf_predict` and :func:`ekf_update` are shared with the
MHE's arrival cost.

The ``*Inference`` classes are the filters alone (inference objects);
:class:`CasadiExtendedKalmanFilter`, :class:`ExtendedKalmanFilter` and
:class:`UnscentedKalmanFilter` are the sensor-health policy
(:mod:`~continuum_mhe.estimators.sensor_health`) around them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.arrays import contiguous_f64 as f64
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import Inference, Measurement, Status, tilt_rows
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.estimators.sensor_health import (
    NUMERICAL_FAILURES,
    Estimator,
    numerical_failure,
    status_code,
)
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.formulations import Formulation, ModelFunctions
from continuum_mhe.settings import RecoverySettings


def ekf_predict(
    fns: ModelFunctions,
    x: FloatArray,
    P: FloatArray,
    u: FloatArray,
    dt: float,
    Q: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Prediction ``x+ = f(x, u, dt)``, ``P+ = F P F^T + Q``: ``Q`` (nx, nx) the
    process noise given, or None for the model's ``Q(dt)``."""
    xn, F, Q_model = (np.asarray(v, dtype=float) for v in fns.predict(x, u, dt))
    F = F.reshape(len(x), len(x))
    Q = Q_model.reshape(len(x), len(x)) if Q is None else Q
    return xn.ravel(), F @ P @ F.T + Q


def valid_rows(mask: FloatArray | None, nz: int) -> NDArray[np.intp]:
    """Indices of the measurement components to use (all when ``mask`` is None)."""
    return np.arange(nz) if mask is None else np.flatnonzero(mask)


def ekf_update(
    formulation: Formulation,
    x: FloatArray,
    P: FloatArray,
    z: FloatArray,
    R: FloatArray,
    mask: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Measurement update on the formulation's residual ``r(z, x)``, Joseph form.

    The innovation is ``r(z, x)`` and ``H = -dr/dx``; for ``r = z - h(x)`` this is the
    textbook EKF (with wrapped angles). ``mask`` (nz,) selects the valid components
    (:meth:`Formulation.measurement_mask`); masked ones are left out.
    """
    zf = np.where(np.isfinite(z), z, 0.0)
    r, Jr = (np.asarray(v, dtype=float) for v in formulation.functions.innovate(zf, x))
    return joseph_update(x, P, r.ravel(), -Jr.reshape(len(z), len(x)), R, mask)


def joseph_update(
    x: FloatArray,
    P: FloatArray,
    r: FloatArray,
    H: FloatArray,
    R: FloatArray,
    mask: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The EKF's measurement update, Joseph form, with the innovation ``r`` (nz,) and
    ``H = -dr/dx`` (nz, nx) at ``x``; ``mask`` (nz,) selects the valid components."""
    rows = valid_rows(mask, len(r))
    H, r, R = H[rows], r[rows], R[np.ix_(rows, rows)]
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    ikh = np.eye(len(x)) - K @ H
    return x + K @ r, ikh @ P @ ikh.T + K @ R @ K.T


class _KalmanBase(Inference):
    def __init__(self, formulation: Formulation) -> None:
        super().__init__(formulation)
        self._R = formulation.meas_cov()
        self.restart()

    @property
    def has_state(self) -> bool:
        """Whether the filter has started: it holds a state since its last restart."""
        return self._x is not None

    def forget(self) -> None:
        self._x: FloatArray | None = None
        self._P: FloatArray | None = None
        self._t_prev = 0.0
        self._z_prev: FloatArray | None = None

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        f = self.formulation
        mask = f.measurement_mask(m.z)
        if self._x is None or self._P is None:
            if not mask.any():  # nothing to start from yet
                return None, None, Status.NO_ESTIMATE
            # prior from the first reading's inverse, then updated with that reading:
            # the same convention as the MHE (arrival prior plus the first measurement)
            self._x, self._P = self._update(*self.start_prior(m.z, m.t), m.z, mask)
            self._t_prev, self._z_prev = m.t, m.z
            return self._x.copy(), self._P.copy(), Status.OK
        dt = m.t - self._t_prev
        u = f.inputs(self._z_prev, m.z, dt)
        x, P = self._predict(self._x, self._P, u, dt)
        status: Status = Status.DROPOUT
        if mask.any():
            x, P = self._update(x, P, m.z, mask)
            status = Status.OK
            self._z_prev = m.z
        self._x, self._P, self._t_prev = x, P, m.t
        return x.copy(), P.copy(), status

    def _predict(
        self, x: FloatArray, P: FloatArray, u: FloatArray, dt: float
    ) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError

    def _update(
        self, x: FloatArray, P: FloatArray, z: FloatArray, mask: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        raise NotImplementedError


class ExtendedKalmanInference(_KalmanBase):
    """The EKF's inference, with Jacobians from CasADi's automatic differentiation of
    the model (:class:`CasadiExtendedKalmanFilter` steps it)."""

    name = "ekf"

    def _predict(
        self, x: FloatArray, P: FloatArray, u: FloatArray, dt: float
    ) -> tuple[FloatArray, FloatArray]:
        return ekf_predict(self.formulation.functions, x, P, u, dt)

    def _update(
        self, x: FloatArray, P: FloatArray, z: FloatArray, mask: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        return ekf_update(self.formulation, x, P, z, self._R, mask)


class CompiledExtendedKalmanInference(ExtendedKalmanInference):
    """The same EKF, each step one call into the compiled core (the node model and the
    EKF step in C++): the strongest EKF baseline for timing. Same equations and answers
    as :class:`ExtendedKalmanInference` (to rounding)."""

    name = "ekf"

    def __init__(self, formulation: Formulation) -> None:
        from continuum_mhe.estimators.fast import NodeEvaluator, node_functions

        self._node = NodeEvaluator(node_functions(formulation))
        self._q = ProcessNoiseCache(formulation)
        #: ``(state, outputs, standard deviations)`` of the last fused step
        #: (state, outputs, output std, covariance) of the last compiled call
        self._outputs_of: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None
        #: the last :meth:`infer`'s innovation log-density ``-(r^T S^-1 r + log|S|) / 2``
        #: (NaN for a start, and for a sample without a valid reading); with
        #: :attr:`likelihood_given`, the other components' density given those
        self.log_likelihood = math.nan
        super().__init__(formulation)

    @property
    def likelihood_given(self) -> tuple[int, ...]:
        """The measurement components (rows of ``z``) on which :attr:`log_likelihood` is
        conditioned: it is then the density of the others given them (the whole density
        less theirs; NaN where theirs has no Cholesky factor). Empty, the default: the
        whole innovation's density."""
        return tuple(int(i) for i in self._node.core.likelihood_given)

    @likelihood_given.setter
    def likelihood_given(self, rows: Sequence[int]) -> None:
        self._node.core.likelihood_given = [int(i) for i in rows]

    def _update(
        self, x: FloatArray, P: FloatArray, z: FloatArray, mask: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The first sample's update (later ones run inside the compiled step): the
        equations of :func:`ekf_update` on the compiled node's residual and Jacobian."""
        zf = np.where(np.isfinite(z), z, 0.0)
        _, _, H, r = self._node.evaluate(x, np.zeros(self.formulation.nu), 0.0, zf)
        return joseph_update(x, P, r, H, self._R, mask)

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        if self._x is None or self._P is None:
            self.log_likelihood = math.nan
            return super().infer(m)  # the first sample: prior, then its update
        f = self.formulation
        mask = f.measurement_mask(m.z)
        dt = m.t - self._t_prev
        u = f.inputs(self._z_prev, m.z, dt)
        x, P, y, std = self._node.ekf_step_outputs(
            self._x, self._P, u, dt, m.z, mask, self._R, self._q(dt)[0]
        )
        self.log_likelihood = float(self._node.core.log_likelihood)
        status: Status = Status.OK if mask.any() else Status.DROPOUT
        if mask.any():
            self._z_prev = m.z
        self._x, self._P, self._t_prev = x, P, m.t
        state, cov = x.copy(), P.copy()
        self._outputs_of = (state, y, std, cov)
        return state, cov, status

    def policy_inference(self) -> _core.KalmanInference | None:
        """The compiled policy's EKF (``_core.KalmanInference``: each step in compiled
        code, this object only for the first sample and restarts)."""
        if type(self).infer is not CompiledExtendedKalmanInference.infer:
            return None
        return _core.KalmanInference(
            self._node.core, _KalmanHooks(self), np.ascontiguousarray(self._R, dtype=float),
            self._q.compiled, self.formulation.input_function,
        )  # fmt: skip

    def output(self, state: FloatArray) -> FloatArray:
        kept = self._outputs_of
        if kept is not None and kept[0] is state:  # computed in the same compiled call
            return kept[1]
        return self._node.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        kept = self._outputs_of
        if kept is not None and kept[0] is state and kept[3] is cov:
            return kept[2]
        return self._node.output_std(state, cov)


class _KalmanHooks:
    """What ``_core.KalmanInference`` asks of a :class:`CompiledExtendedKalmanInference`
    or :class:`UnscentedKalmanInference`: its restart and its first sample (the prior
    from the reading, updated with it)."""

    def __init__(self, inference: _KalmanBase) -> None:
        self.inference = inference
        self.formulation = inference.formulation
        self.nu = inference.formulation.nu

    def restart(self, *kept: object) -> None:
        """The inference's restart, with what the policy hands it (``kept_x, kept_P,
        kept_t``: :meth:`~continuum_mhe.estimators.base.Inference.restart`)."""
        self.inference.restart(*kept)  # type: ignore[arg-type]

    def start_untrusted(self, t: float, z: FloatArray) -> bool:
        """The inference's :meth:`~continuum_mhe.estimators.base.Inference.start_untrusted`."""
        return self.inference.start_untrusted(t, z)

    def first(
        self, t: float, z: FloatArray
    ) -> tuple[FloatArray | None, FloatArray | None, int, str | None]:
        """``(state, covariance, status code, None)``, or a numerical failure's message."""
        try:
            with np.errstate(all="ignore"):  # non-finite results are the policy's to catch
                x, P, status = self.inference.infer(Measurement(t, z))
        except NUMERICAL_FAILURES as exc:
            return None, None, 0, numerical_failure(exc)
        return x, P, status_code(status), None


@dataclass(frozen=True)
class SigmaPointSettings:
    """Van der Merwe's scaled sigma points (alpha, beta, kappa). ``alpha`` None: the
    formulation's (:attr:`~continuum_mhe.model.formulations.Formulation.unscented_alpha`:
    0.5, and 0.01 for a tendon robot's mechanics, whose shooting is too nonlinear across
    a wider spread)."""

    #: the sigma points' spread about the mean, in (0, 1]; None: the formulation's
    alpha: float | None = None
    #: the prior's kurtosis term of the central point's covariance weight (2: Gaussian)
    beta: float = 2.0
    #: the secondary scaling (sigma points at ``sqrt(alpha^2 (n + kappa))`` standard
    #: deviations along each factor column of an ``n``-state covariance)
    kappa: float = 0.0

    def __post_init__(self) -> None:
        if self.alpha is not None and not 0 < self.alpha <= 1:
            raise UserError(f"alpha must lie in (0, 1], got {self.alpha!r}")


#: How the UKF's failure begins where its sigma points spread a tilt reading across a
#: half turn (:class:`UnscentedKalmanInference`; the core writes the message).
UNSCENTED_SPREAD = "the unscented transform's"
#: The tilt error (rad) whose tangent-plane residual ``2 tan(e / 2)`` is pi: a sigma
#: point's tilt this far from the reading fails the UKF's update
#: (:class:`UnscentedKalmanInference`).
CHART_LIMIT = 2.0 * math.atan(math.pi / 2.0)
#: The share of :data:`CHART_LIMIT` that the first prediction's sigma points may spread
#: the tilts over before a start's rate prior is warned of
#: (:meth:`UnscentedKalmanInference.step_problem`): the reading lies a step's motion
#: and noise from the prediction, and the updates fail from 0.98 of it on (one
#: section, ``paper3d``) and 1.05 (two sections, ``spatial``).
CHART_SHARE = 0.95
#: Innovation standard deviations from the prediction that a reading may lie, as the
#: robot moves, when the settled filter's spread is judged
#: (:meth:`UnscentedKalmanInference.step_problem`): on ``paper3d`` (0.05 s steps, 400
#: samples) the UKF's updates fail and restart it from ``bend_accel_psd`` 1e4 on (16
#: restarts; 174 at 3e4), where a settled spread and two innovation standard deviations
#: pass :data:`CHART_LIMIT`, and not at 5e3; nor at 1 Hz with the default (there the
#: two-section rods' tilt recordings are warned of, and restart too).
SETTLED_READING_SIGMAS = 2.0
#: The most steps the settled covariance of
#: :meth:`UnscentedKalmanInference._settled_spread` takes.
SETTLE_STEPS = 1000


class UnscentedKalmanInference(_KalmanBase):
    """The UKF's inference, with Van der Merwe's scaled sigma points, each step in the
    compiled core (``_core.UnscentedFilter``, ``csrc/unscented.hpp``; through
    ``_core.KalmanInference`` in the compiled policy, this object only for the first
    sample and restarts). The sigma points go through the transition and the residual
    ``r(z, .)``: the innovation is the residuals' weighted mean, the predicted
    measurement's deviations ``-(r_i - mean)``; only the valid blocks take part.
    Angle residuals that wrap (the paper formulation's Euler angles) are averaged as they
    come. Where a residual does not wrap (the bend formulation's tangent plane,
    ``2 tan(error / 2)``), a valid tilt component whose residuals differ by more than pi
    from the central point's fails the update with an ``ArithmeticError``: its values
    differ that much only near its singularity, where the reading is about a half turn
    from the sigma points' tilts (from about 130 degrees on), and the transform's mean and
    covariance mean nothing there (unchecked, on ``gimbal_flip.csv`` they keep the previous
    estimate, ``ok``, with a standard deviation of 1e-6 m).
    :meth:`~continuum_mhe.estimators.sensor_health.Estimator.step` then restarts the
    filter from the reading (status ``reset``), as for a diverged EKF. Not checked in the
    first update of a (re)start, whose prior comes from the reading itself. A covariance
    without a Cholesky factor, or a singular innovation covariance, is a
    ``numpy.linalg.LinAlgError``. :class:`UnscentedKalmanFilter` steps it."""

    name = "ukf"

    def __init__(self, formulation: Formulation, sigma: SigmaPointSettings | None = None):
        from continuum_mhe.estimators.fast import NodeEvaluator, node_functions

        self.sigma = s = sigma or SigmaPointSettings()
        #: the sigma points' spread in use (the settings', or the formulation's)
        self.alpha = formulation.unscented_alpha if s.alpha is None else s.alpha
        if not 0 < self.alpha <= 1:
            raise UserError(f"the UKF's alpha must lie in (0, 1], got {self.alpha!r}")
        functions = node_functions(formulation)
        self._node = NodeEvaluator(functions)
        self._q = ProcessNoiseCache(formulation)
        chart = [] if formulation.tilt_residual_wraps else tilt_rows(formulation)
        self._unscented = _core.UnscentedFilter(
            functions.transition, functions.residual, formulation.nx, formulation.nu,
            formulation.nz, self.alpha, s.beta, s.kappa, chart,
            list(formulation.measurement_names),
        )  # fmt: skip
        super().__init__(formulation)

    def step_problem(self, step: float) -> str | None:
        """Where the UKF's sigma points spread so far over a step of ``step`` s that a
        reading's tilt can lie :data:`CHART_LIMIT` from a sigma point's, so that updates
        fail and restart the filter (status ``reset``); the EKF and the MHE take any such
        setting. Two causes, each measured on the straight, still robot (its tilt
        Jacobian):

        - the start's bend-rate prior (``NoiseSettings.initial_rate_std``): every start's
          first prediction spreads the sigma points by the sigma points' scale
          ``alpha sqrt(n + kappa)`` times the largest standard deviation the rates give a
          tilt reading over the step, past :data:`CHART_SHARE` of the limit, and each
          start then fails and restarts from the same prior, sample after sample;
        - the bends' process noise (``NoiseSettings.bend_accel_psd``): the filter's
          predicted covariance once it has settled (its own recursion, run on the
          readings' noise ``R``) spreads the sigma points so far that with a reading
          :data:`SETTLED_READING_SIGMAS` innovation standard deviations from the
          prediction, as the robot's motion puts it, the limit is passed."""
        f = self.formulation
        rows = [] if f.tilt_residual_wraps else tilt_rows(f)
        if not rows or not isinstance(f, BendFormulation) or not math.isfinite(step):
            return None
        x = np.zeros(f.nx)  # straight and still
        z = np.asarray(f.functions.observe(x), dtype=float).ravel()
        _, jacobian = (np.asarray(v, dtype=float) for v in f.functions.innovate(z, x))
        H = jacobian.reshape(f.nz, f.nx)
        bends = 2 * f.robot.n_sections
        scale = self.alpha * math.sqrt(f.nx + self.sigma.kappa)
        settled = self._settled_spread(H, step)
        worst = scale * settled[rows] + SETTLED_READING_SIGMAS * np.sqrt(
            settled[rows] ** 2 + np.diag(f.meas_cov())[rows]
        )
        if worst.max() > CHART_LIMIT:
            psd = f.noise.bend_accel_psd
            return (
                f"bend_accel_psd (--accel-psd) {psd:g} spreads the UKF's sigma points up to "
                f"{scale * settled[rows].max():.3g} rad of tilt from its prediction over "
                f"the {step:.3g} s between samples once the filter has settled, with "
                f"readings {SETTLED_READING_SIGMAS:g} standard deviations "
                f"({(worst - scale * settled[rows]).max():.3g} rad) from it as the robot "
                f"moves: near or past the {CHART_LIMIT:.3g} rad at which a reading's "
                "residual 2 tan(e/2) passes pi and the update fails, which restarts the "
                "filter (status reset); a smaller bend_accel_psd narrows the spread where "
                "the robot's motion between samples allows it (the EKF and the MHE take "
                "it)"
            )
        rate_gain = np.linalg.norm(H[rows, :bends], axis=1).max()
        rate_scale = scale * rate_gain * step
        rate = f.noise.initial_rate_std
        spread = rate_scale * rate
        if spread <= CHART_SHARE * CHART_LIMIT:
            return None
        return (
            f"initial_rate_std {rate:g} rad/s spreads the UKF's sigma points up to "
            f"{spread:.3g} rad of tilt from its prediction over the {step:.3g} s between "
            f"samples, near or past the {CHART_LIMIT:.3g} rad at which a reading's "
            "residual 2 tan(e/2) passes pi and the update fails: a start's first update "
            "then fails and restarts the filter from the same prior (status reset), past "
            "it on most samples; give initial_rate_std at most "
            f"{CHART_SHARE * CHART_LIMIT / rate_scale:.3g} rad/s (the EKF and the MHE take it)"
        )

    def _settled_spread(self, H: FloatArray, step: float) -> FloatArray:
        """Each reading's standard deviation (nz,) under the filter's predicted
        covariance once settled on the straight, still robot: the Kalman covariance
        recursion with the transition's Jacobian and ``Q`` over ``step`` s, every reading
        taken with the readings' noise ``R``, until the prediction changes by less than
        1e-9 of itself (at most :data:`SETTLE_STEPS` steps)."""
        f = self.formulation
        nx = f.nx
        _, F, Q = (
            np.asarray(v, dtype=float)
            for v in f.functions.predict(np.zeros(nx), np.zeros(f.nu), step)
        )
        F, Q = F.reshape(nx, nx), Q.reshape(nx, nx)
        R = f.meas_cov()
        P = np.zeros((nx, nx))  # the first prediction's covariance is Q
        predicted = np.full((nx, nx), np.nan)
        for _ in range(SETTLE_STEPS):
            predicted_next = F @ P @ F.T + Q
            gain = np.linalg.solve(H @ predicted_next @ H.T + R, H @ predicted_next).T
            P = predicted_next - gain @ H @ predicted_next
            done = np.allclose(predicted_next, predicted, rtol=1e-9, atol=0.0)
            predicted = predicted_next
            if done:
                break
        return np.sqrt(np.maximum(np.diag(H @ predicted @ H.T), 0.0))

    def _predict(
        self, x: FloatArray, P: FloatArray, u: FloatArray, dt: float
    ) -> tuple[FloatArray, FloatArray]:
        got = self._unscented.predict(f64(x), f64(P), f64(u), float(dt), self._q(dt)[0])
        return _unscented_result(*got)

    def _update(
        self, x: FloatArray, P: FloatArray, z: FloatArray, mask: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """The update with the valid blocks (``mask``); the tilt chart is checked except
        in a (re)start's first update."""
        got = self._unscented.update(
            f64(x),
            f64(P),
            f64(z),
            f64(mask),
            f64(self._R),
            self._x is not None,
        )
        return _unscented_result(*got)

    def policy_inference(self) -> _core.KalmanInference | None:
        """The compiled policy's UKF (``_core.KalmanInference`` with this filter's
        ``UnscentedFilter``: each step in compiled code, this object only for the first
        sample and restarts); None where a subclass steps otherwise."""
        cls = type(self)
        if (cls.infer, cls._predict, cls._update) != (
            _KalmanBase.infer,
            UnscentedKalmanInference._predict,
            UnscentedKalmanInference._update,
        ):
            return None
        return _core.KalmanInference(
            self._node.core, _KalmanHooks(self), f64(self._R), self._q.compiled,
            self.formulation.input_function, self._unscented,
        )  # fmt: skip

    def output(self, state: FloatArray) -> FloatArray:
        return self._node.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        return self._node.output_std(state, cov)


def _unscented_result(
    x: FloatArray, P: FloatArray, failure: int, message: str
) -> tuple[FloatArray, FloatArray]:
    """``(x, P)`` of an ``UnscentedFilter`` call, or its failure raised as the policy
    names it: a tilt reading across the chart's singularity an ``ArithmeticError``
    (whose message begins with :data:`UNSCENTED_SPREAD`), a linear-algebra failure a
    ``numpy.linalg.LinAlgError``."""
    if failure == 2:
        raise ArithmeticError(message)
    if failure:
        raise np.linalg.LinAlgError(message)
    return x, P


class CasadiExtendedKalmanFilter(Estimator[ExtendedKalmanInference]):
    """The EKF of :class:`ExtendedKalmanFilter` on CasADi's functions, stepped in Python
    (:class:`ExtendedKalmanInference`, CasADi Jacobians), with the same sensor-health
    policy: the independent reference the tests hold the compiled EKF to, and the
    benchmark's ``ekf`` row. The same estimates, many times slower: use
    :class:`ExtendedKalmanFilter` (``make_estimator("ekf", ...)``)."""

    def __init__(self, formulation: Formulation, recovery: RecoverySettings | None = None):
        super().__init__(ExtendedKalmanInference(formulation), recovery)


class ExtendedKalmanFilter(Estimator[CompiledExtendedKalmanInference]):
    """The EKF (``make_estimator("ekf", ...)`` gives it): one compiled call per step
    (:class:`CompiledExtendedKalmanInference`), with the sensor-health policy of
    :class:`~continuum_mhe.estimators.sensor_health.Estimator`.
    :class:`CasadiExtendedKalmanFilter` is the same filter on CasADi's functions."""

    def __init__(self, formulation: Formulation, recovery: RecoverySettings | None = None):
        super().__init__(CompiledExtendedKalmanInference(formulation), recovery)


class UnscentedKalmanFilter(Estimator[UnscentedKalmanInference]):
    """UKF with scaled sigma points and the sensor-health policy of
    :class:`~continuum_mhe.estimators.sensor_health.Estimator`; the filter is
    :attr:`inference` (:class:`UnscentedKalmanInference`)."""

    def __init__(
        self,
        formulation: Formulation,
        sigma: SigmaPointSettings | None = None,
        recovery: RecoverySettings | None = None,
    ):
        super().__init__(UnscentedKalmanInference(formulation, sigma), recovery)
