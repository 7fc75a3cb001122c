"""Moving horizon estimation: a fast structure-exploiting backend, and IPOPT.

The window holds the last ``N`` samples; node ``i`` of the decision variables is the
state at window sample ``i`` (the last node is the estimate). The cost is::

    1/2 sum_i sum_b rho(||m_i * r_b(z_i, x_i)||^2_{R_b^-1})   (per IMU block b)
  + 1/2 sum_i  ||x_{i+1} - f(x_i, u_i, dt_i)||^2_{Q(dt_i)^-1}
  + 1/2 ||x_0 - xbar||^2_{P^-1}                               (arrival cost)

subject to the formulation's bounds as hard constraints, where ``m_i`` (one 0/1 per
measurement component) masks the sensors that dropped out at sample ``i``: validity is
per measurement block, so one IMU's dropout keeps the others. ``rho`` is the
measurement loss (``MHESettings.loss``, :mod:`continuum_mhe.estimators.loss`): ``s``
for the quadratic cost, Huber, Cauchy or Welsch of each block's whitened norm for the
robust ones. The NLP is built once per (formulation, N, loss) with the window's measurements,
masks, time steps, inputs, per-stage ``Q^-1`` and the arrival prior as parameters.

Arrival cost: when the window slides, ``(xbar, P)`` take one EKF step, an update with
the sample that leaves the window and a prediction to the new first sample. The prior
holds only samples that have left the window, so none is counted twice; on a linear
Gaussian model the MHE equals the Kalman filter at every sample. (Taking the previous
solution's smoothed second node as ``xbar`` instead counts the window's measurements
twice: on raw-IMU data it raised the MHE's tip error by 35 % over the EKF's.)
With a robust loss the prior stays Gaussian, and the leaving sample's update uses
``R_b / w_b`` per block, ``w_b = rho'(s_b)`` its weight in the last solve (the
quadratic model of the robust cost at that solution, as iteratively reweighted least
squares uses it): a rejected outlier does not enter the prior at full weight when it
leaves the window. When a robust answer rejects the newest sample, the window is solved
again from the answer of a few samples ago and the lower cost kept (:mod:`.second_start`).

Growing window: before ``N`` samples exist, the active nodes are the last ``n`` ones;
the inactive leading nodes are pinned to the prior and carry no other cost, so they
are decoupled and do not change the answer. With ``paper_start`` no estimate is made
before ``N`` samples (Algorithm 1).

Backends (``MHESettings.solver``): ``"fast"`` solves the same window problem with
the SQP of :mod:`continuum_mhe.estimators.fast` and hands the window
to IPOPT when it cannot certify convergence (status ``"fallback-ipopt"``);
``"ipopt"`` is the reference.

:class:`MovingHorizonInference` is the window and its solve (the inference object);
:class:`MovingHorizonEstimator` is the sensor-health policy
(:mod:`~continuum_mhe.estimators.sensor_health`) around it.
"""

from __future__ import annotations

import math
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import Inference, Measurement, Status
from continuum_mhe.estimators.branch import FORGET, BranchCheck, BranchStats, checks_branch
from continuum_mhe.estimators.fast import (
    BackendFallbackWarning,
    FastOptions,
    FastResult,
    NodeEvaluator,
    WindowModel,
    Workspace,
    build_window_model,
    node_functions,
    solve_window,
    window_cost,
)
from continuum_mhe.estimators.fast.covariance import casadi_window_covariance
from continuum_mhe.estimators.fast.model import Feasible, LossKernel, feasible_set
from continuum_mhe.estimators.fast.sqp import newton_steps, quadratic_rate
from continuum_mhe.estimators.kalman import ekf_predict, ekf_update
from continuum_mhe.estimators.loss import (
    LOSS_CODES,
    OUTLIER_WEIGHT,
    block_array,
    block_weights,
    robust_blocks,
)
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.estimators.second_start import SecondStart
from continuum_mhe.estimators.sensor_health import (
    NUMERICAL_FAILURES,
    Estimator,
    numerical_failure,
    status_code,
)
from continuum_mhe.estimators.window_nlp import (
    Nlp,
    WindowProblem,
    build_nlp,
    objective_scale_exponent,
    pack_parameters,
)
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings, RecoverySettings
from continuum_mhe.signals import raise_if_solve_interrupted, signals_deferred

#: The statuses of a window's answer from which its prediction of the next reading is
#: weighed (:attr:`MovingHorizonInference.log_likelihood`): a solved window's, not one
#: that stopped short of its solution (``not-converged``) or failed.
EVIDENCE_STATUSES = frozenset(
    {Status.OK, Status.DROPOUT, Status.FALLBACK_IPOPT, Status.BRANCH_RESTART}
)


class Answer(NamedTuple):
    """A kept window answer's newest node: what the estimate of the sample holds."""

    state: FloatArray  #: (nx,)
    covariance: FloatArray | None  #: (nx, nx); None where the window failed or is not PD
    output: FloatArray  #: (ny,), the formulation's outputs
    output_std: FloatArray | None  #: (ny,); None where ``covariance`` is


class ReferenceWindow:
    """The IPOPT backend's window: the same buffers and steps as the compiled
    :class:`continuum_mhe._core.MovingHorizon` of the fast backend (its attribute names,
    ``csrc/horizon.hpp``), on the formulation's CasADi functions, with no solve of its own
    (its :meth:`step` leaves the window to the caller:
    :attr:`~continuum_mhe._core.StepOutcome.UNCERTIFIED`).

    Args:
        formulation: the model.
        settings: horizon, loss and ``paper_start``.
        feasible: the node feasible set the covariance conditions on (None: none).
    """

    def __init__(
        self, formulation: Formulation, settings: MHESettings, feasible: Feasible | None
    ) -> None:
        f, n, nx = formulation, settings.horizon, formulation.nx
        self.formulation, self.settings, self.feasible = formulation, settings, feasible
        self.n, self.nx = n, nx
        #: where the answer's newest node sits on a ball: its covariance not conditioned
        #: on the balls (:func:`casadi_window_covariance`), as the compiled window's
        self.cov_free, self.cov_free_ok = np.zeros((nx, nx)), False
        self._R = np.asarray(f.meas_cov(), dtype=np.float64)
        self._Rinv = np.asarray(np.linalg.inv(self._R), dtype=np.float64)
        self._blocks = block_array(f.measurement_blocks)
        #: per measurement component, its block's index (nblocks: in no block)
        self._block_of = np.full(f.nz, len(self._blocks))
        for b, (start, size) in enumerate(self._blocks):
            self._block_of[start : start + size] = b
        self.robust = settings.loss != "l2"
        self._robust = robust_blocks(f.measurement_blocks)
        self._loss = LossKernel(
            self._blocks, LOSS_CODES[settings.loss], float(settings.scale), self._robust
        )
        self.xbar, self.P, self.Pinv = np.zeros(nx), np.zeros((nx, nx)), np.zeros((nx, nx))
        #: what the arrival prior is conditioned on after each slide (None: nothing): a
        #: map ``(x, P) -> (x, P)``, such as states held at zero
        self.condition: Callable[[FloatArray, FloatArray], tuple[FloatArray, FloatArray]] | None
        self.condition = None
        self.iterations = 0
        #: the compiled step's certified window cost; this window certifies none (NaN)
        self.cost = float("nan")
        self.restart()

    def restart(self) -> None:
        f, n, nx = self.formulation, self.n, self.nx
        self.k = 0  # samples in the window
        self.cov_free_ok = False
        self.tw = np.zeros(n)
        self.zw = np.zeros((n, f.nz))  # 0 where masked
        self.zmask = np.zeros((n, f.nz))
        self.dt = np.ones(n - 1)  # 1 s on inactive stages
        self.uw = np.zeros((n - 1, f.nu))
        self.qw = np.zeros((n - 1, nx, nx))  # Q(dt)
        self.qinvw = np.zeros((n - 1, nx, nx))  # Q(dt)^-1 (0 on inactive stages)
        self.arrival = np.zeros((n, nx, nx))
        self.X = np.zeros((n, nx))
        self.X0 = np.zeros((n, nx))
        self.X_last = np.zeros((n, nx))
        self.lam = np.zeros((n, 0))
        self.X_sol = self.X  # never certified: IPOPT's caller solves every window
        self.solved = False
        self.solve_seconds = 0.0
        self.step_seconds = 0.0  # no compiled step
        self.has_prior = self.has_X = self.has_X_last = self.has_lam = False
        self.w_first = np.ones(len(self._blocks))
        self.w_last = np.ones(len(self._blocks))

    def set_prior(self, xbar: FloatArray, P: FloatArray, Pinv: FloatArray) -> None:
        self.xbar[:], self.P[:], self.Pinv[:] = xbar, P, Pinv
        self.has_prior = True

    def step(
        self,
        t: float,
        z: FloatArray,
        mask: FloatArray,
        u: FloatArray,
        Q: FloatArray,
        Qinv: FloatArray,
        finish: bool,
    ) -> tuple[_core.StepOutcome, None]:
        """Push the sample (sliding the prior when the window was full), form the warm
        start :attr:`X0` and the arrival weights; ``StepOutcome.UNCERTIFIED`` (the caller
        solves), or ``StepOutcome.NO_ESTIMATE`` under ``paper_start``."""
        n = self.n
        if self.k == n:
            self._slide()
        for buf in (self.tw, self.zw, self.zmask, self.dt, self.uw, self.qw, self.qinvw):
            buf[:-1] = buf[1:]
        self.tw[-1] = t
        self.zmask[-1] = mask
        self.zw[-1] = np.where(mask > 0, z, 0.0)
        if self.k:
            self.dt[-1] = t - self.tw[-2]
            self.uw[-1], self.qw[-1], self.qinvw[-1] = u, Q, Qinv
        else:
            self.dt[-1], self.uw[-1], self.qw[-1], self.qinvw[-1] = 1.0, 0.0, 0.0, 0.0
        self.k = min(self.k + 1, n)
        self._warm_start()
        self.has_X_last = False
        if self.settings.paper_start and self.k < n:
            self.X[:], self.has_X = self.X0, True
            return _core.StepOutcome.NO_ESTIMATE, None
        off = n - self.k  # pinned identity before off, P^-1 at off, 0 after
        if off:
            self.arrival[:off] = np.eye(self.nx)
        self.arrival[off : off + 2] = 0.0  # off moves down by one per sample while growing
        self.arrival[off] = self.Pinv
        return _core.StepOutcome.UNCERTIFIED, None

    def _slide(self) -> None:
        """One EKF step of the prior: update with the leaving sample (with a robust loss
        at its weight in the last solve, ``R_b / w_b`` per block), predict with the
        window's own process noise of that stage (as the compiled step slides), then
        :attr:`condition`."""
        f, x, P = self.formulation, self.xbar, self.P
        R = self._R
        if self.robust:
            scale = np.append(1.0 / np.maximum(self.w_first, 1e-12), 1.0)[self._block_of]
            R = R * np.sqrt(np.outer(scale, scale))
        if self.zmask[0].any():
            x, P = ekf_update(f, x, P, self.zw[0], R, self.zmask[0])
        xn, P = ekf_predict(f.functions, x, P, self.uw[0], float(self.dt[0]), self.qw[0])
        if self.condition is not None:
            xn, P = self.condition(xn, P)
        self.P[:] = 0.5 * (P + P.T)
        self.Pinv[:] = np.linalg.inv(self.P)
        self.xbar[:] = f.project(xn)

    def _warm_start(self) -> None:
        if not self.has_X:
            self.X0[:] = self.xbar
            return
        prev = self.X_last if self.has_X_last else self.X
        self.X0[:-1] = prev[1:]
        dt = float(self.tw[-1] - self.tw[-2]) if self.k > 1 else 0.0
        self.X0[-1] = self.predict(prev[-1], self.uw[-1], dt)

    def predict(self, x: FloatArray, u: FloatArray, dt: float) -> FloatArray:
        """The model's next state from ``x`` after ``dt`` s, projected on the bounds."""
        f = self.formulation
        return f.project(np.asarray(f.functions.transition(x, u, dt), float).ravel())

    def node_weights(self, i: int, x: FloatArray) -> FloatArray:
        """Robust weights ``rho'(s_b)`` (nblocks,) of window node ``i`` at state ``x``."""
        r = (
            self.zmask[i]
            * np.asarray(self.formulation.functions.innovate(self.zw[i], x)[0], float).ravel()
        )
        s = self.settings
        return block_weights(s.loss, s.scale, r, self._Rinv, self._blocks, self._robust)

    def finish(self, X: FloatArray, solved: bool, w_new: FloatArray | None, failed: bool) -> Answer:
        """Keep ``X`` (N, nx) as the answer; its last node, covariance and outputs."""
        self.X[:], self.has_X = X, True
        if self.robust:
            self.w_first = self.node_weights(0, X[0])
            self.w_last = self.node_weights(-1, X[-1]) if w_new is None else w_new.copy()
        f, x = self.formulation, X[-1].copy()
        cov = None
        if not failed:
            problem = WindowProblem(
                z=self.zw, zmask=self.zmask, dt=self.dt, u=self.uw, qinv=self.qinvw,
                xbar=self.xbar, arrival=self.arrival,
            )  # fmt: skip
            cov = casadi_window_covariance(f, problem, X, self.feasible, loss=self._loss)
        self.cov_free_ok = False
        if cov is not None and self.feasible is not None and on_a_ball(x, self.feasible):
            free = casadi_window_covariance(
                f, problem, X, self.feasible, loss=self._loss, condition_balls=False
            )
            if free is not None:
                self.cov_free, self.cov_free_ok = free, True
        return Answer(x, cov, f.output(x), None if cov is None else f.output_std(x, cov))


def on_a_ball(x: FloatArray, feasible: Feasible, tol: float = 1e-6) -> bool:
    """Whether the node ``x`` sits on one of ``feasible``'s balls (within ``tol`` of
    its ``r^2``, as the covariance's active set)."""
    for idx, r2 in zip(np.atleast_2d(feasible.ball_idx), feasible.ball_r2):
        q = float(np.sum(np.asarray(x)[idx] ** 2))
        if q > 0.0 and q >= r2 * (1.0 - tol):
            return True
    return False


class MovingHorizonInference(Inference):
    """The MHE's inference: the window problem over the last ``N`` samples, solved
    each sample, and its arrival prior (:class:`MovingHorizonEstimator` steps it).

    Backends (``settings.solver``): ``"fast"`` (default), the structure-exploiting
    SQP of :mod:`continuum_mhe.estimators.fast` (Newton steps, Gauss-Newton where the
    exact Hessian is not positive definite), which falls back to IPOPT on the same
    window (status ``"fallback-ipopt"``) when it cannot certify convergence;
    ``"ipopt"``, the paper's solver and the reference.

    On the fast backend one call into the compiled core
    (:class:`continuum_mhe._core.MovingHorizon`) takes each sample: the window's
    buffers, the prior's slide, the warm start, the solve, the last node's covariance and
    the outputs; the branch check, the second start and IPOPT's fallback are Python hooks
    around its solve. On IPOPT, :class:`ReferenceWindow` holds the same buffers.

    Args:
        formulation: the model.
        settings: horizon, solver and IPOPT options.
        fast_options: options of the fast backend (iterations, tolerance).
    """

    name = "mhe"
    holds_bounds = True

    def __init__(
        self,
        formulation: Formulation,
        settings: MHESettings | None = None,
        fast_options: FastOptions | None = None,
    ) -> None:
        super().__init__(formulation)
        self.settings = settings or MHESettings()
        #: why the requested backend is not the one that runs (None when it is)
        self.backend_note: str | None = None
        self.fast_options = fast_options or FastOptions()
        s = self.settings
        self._fast: WindowModel | None = None
        if s.solver == "fast" and formulation.fast_mhe_obstacle is not None:
            raise UserError(
                f"the fast MHE cannot take this formulation: {formulation.fast_mhe_obstacle}; "
                "the EKF (default_method) runs it, or solver='ipopt' the MHE on IPOPT "
                "(slow, its memory grows with the horizon)"
            )
        if s.solver == "fast":
            try:
                self._fast = build_window_model(formulation, s.horizon, s.loss, s.scale)
            except NotImplementedError as exc:  # feasible set the fast backend cannot take
                self._fast = None
                self.backend_note = (
                    f"the fast MHE backend cannot take this problem ({exc}); "
                    "IPOPT solves every window (status fallback-ipopt)"
                )
                warnings.warn(self.backend_note, BackendFallbackWarning, stacklevel=2)
        #: the IPOPT window NLPs by objective scale exponent
        #: (:func:`~.window_nlp.objective_scale_exponent`), each built when a window first
        #: needs it: a window whose weights exceed the reference never builds the unscaled
        #: one, and the fast backend builds one only to fall back
        self._nlps: dict[int, Nlp] = {}
        #: the NLPs being built in the background (:meth:`prepare_fallback`), by exponent
        self._nlp_builds: dict[int, threading.Thread] = {}
        self._process_weight = ProcessNoiseCache(formulation)
        self._R = formulation.meas_cov()
        #: why the window covariance leaves the constraints out (None when it does not)
        self.covariance_note: str | None = None
        self._window: ReferenceWindow | _core.MovingHorizon
        if self._fast is not None:
            self._workspace: Workspace | None = Workspace(self._fast)
            self._node: NodeEvaluator | None = NodeEvaluator(self._fast)
            opt = self.fast_options
            self._window = _core.MovingHorizon(
                self._workspace.core, self._node.core, np.ascontiguousarray(self._R, float),
                s.loss != "l2", s.paper_start, opt.max_iter, opt.step_tol, opt.err_tol,
                opt.max_qp_iter, newton_steps(self._fast, opt), quadratic_rate(self._fast, opt),
            )  # fmt: skip
        else:
            self._workspace, self._node = None, None
            feasible: Feasible | None = None
            try:
                feasible = feasible_set(formulation)
            except NotImplementedError as exc:  # a feasible set the kernel cannot read
                self.covariance_note = (
                    f"the window covariance leaves this problem's constraints out ({exc}): "
                    "its standard deviations are too large where a bound is active"
                )
                warnings.warn(self.covariance_note, BackendFallbackWarning, stacklevel=2)
            self._window = ReferenceWindow(formulation, s, feasible)
        self._blocks = block_array(formulation.measurement_blocks)
        #: the blocks a robust loss acts on (the IMUs')
        self._robust_block = robust_blocks(formulation.measurement_blocks) == 1
        self._no_input = np.zeros(formulation.nu)
        self._no_weight = np.zeros((formulation.nx, formulation.nx))
        #: True when the robust loss is in use (estimates carry outlier flags)
        self.flags_outliers = self.settings.loss != "l2"
        #: the robust loss's second start (:mod:`.second_start`), with its counts
        self.second_start = self._second_start() if self.flags_outliers else None
        #: the branch check (``settings.branch_check``, by default for tilt only; see
        #: :mod:`.branch`), with its counts
        self.branch = (
            BranchCheck(formulation, s.horizon, quadratic=s.loss == "l2")
            if checks_branch(formulation, s.branch_check, robust=s.loss != "l2")
            else None
        )
        limits = self.branch.plausible_limits if self.branch is not None else None
        if isinstance(self._window, _core.MovingHorizon) and limits is not None:
            if self.second_start is None:  # the check's first test in the compiled step
                self._window.plausible_limit = limits
        if isinstance(self._window, _core.MovingHorizon) and self.second_start is not None:
            # answers that leave the second start nothing to try are kept by the step
            self._window.keep_unrejected = self.branch is None
        self._rinv_max = float(np.abs(np.linalg.inv(self._R)).max())
        #: whether :meth:`infer` computes :attr:`log_likelihood` (the load hypotheses'
        #: evidence, :mod:`.load_hypotheses`; it costs an EKF step a sample)
        self.tracks_likelihood = False
        #: with :attr:`tracks_likelihood`, the last sample's reading's log-density under
        #: the previous answer predicted to it (its state and covariance, one EKF step:
        #: ``-(r^T S^-1 r + log|S|) / 2``, as the compiled EKF's); NaN for a start, a
        #: sample without a valid reading, and a previous answer without a covariance or
        #: with a status outside :data:`EVIDENCE_STATUSES`; with :attr:`likelihood_given`,
        #: the other components' density given those (as the compiled EKF's)
        self.log_likelihood = math.nan
        #: the measurement components on which :attr:`log_likelihood` is conditioned
        #: (:attr:`CompiledExtendedKalmanInference.likelihood_given
        #: <continuum_mhe.estimators.kalman.CompiledExtendedKalmanInference.likelihood_given>`)
        self.likelihood_given: tuple[int, ...] = ()
        self._likelihood_node: NodeEvaluator | None = None
        self.restart()

    def _second_start(self) -> SecondStart:
        """The robust loss's second start, its past answers kept by the compiled step
        where there is one."""
        window = self._window
        if not isinstance(window, _core.MovingHorizon):
            return SecondStart(self.settings.horizon)
        second = SecondStart(self.settings.horizon, past=window)
        window.past_lag = second.lag
        window.outlier_weight = OUTLIER_WEIGHT
        return second

    def _window_nlp(self, scale_exp: int) -> Nlp:
        """The IPOPT NLP with the objective divided by ``10**scale_exp``, built on first use
        (or by :meth:`prepare_fallback`'s thread, waited for)."""
        building = self._nlp_builds.pop(scale_exp, None)
        if building is not None:
            building.join()
        nlp = self._nlps.get(scale_exp)
        if nlp is None:
            s = self.settings
            nlp = build_nlp(
                self.formulation, s.horizon, s.max_iter, s.tol, s.loss, s.scale, scale_exp
            )
            self._nlps[scale_exp] = nlp
        return nlp

    def prepare_fallback(self) -> bool:
        """Start building, in a background thread, the IPOPT NLP that an uncertified
        window of the fast backend falls back to, at the current window's objective scale
        (:func:`~.window_nlp.objective_scale_exponent`): a first fallback then finds it
        built (building it takes seconds for a model of several raw IMUs, CasADi working
        without Python's lock) instead of waiting for it. For a stream estimated in real
        time (``live``), from its second sample on. Returns whether a build started (not
        without the fast backend, whose windows IPOPT solves anyway, nor where the NLP
        is built or being built)."""
        if self._fast is None:
            return False
        scale_exp = objective_scale_exponent(self.window_problem(), self._rinv_max)
        if scale_exp in self._nlps or scale_exp in self._nlp_builds:
            return False
        s = self.settings

        def build() -> None:
            self._nlps[scale_exp] = build_nlp(
                self.formulation, s.horizon, s.max_iter, s.tol, s.loss, s.scale, scale_exp
            )

        # not a daemon: a process that ends while CasADi builds it waits for the build
        # (its interpreter torn down under a running build crashes it)
        thread = threading.Thread(target=build, name="ipopt-fallback-nlp")
        self._nlp_builds[scale_exp] = thread
        thread.start()
        return True

    def join_fallback(self) -> None:
        """Wait for the builds :meth:`prepare_fallback` started (the end of a stream)."""
        for thread in list(self._nlp_builds.values()):
            thread.join()

    @property
    def _nlp(self) -> Nlp:
        """The IPOPT NLP of the unscaled objective (:meth:`_window_nlp`)."""
        return self._window_nlp(0)

    @_nlp.setter
    def _nlp(self, nlp: Nlp) -> None:
        self._nlps[0] = nlp

    def clear_counts(self) -> None:
        """Zero the second start's and the branch check's counts."""
        if self.second_start is not None:
            self.second_start.tried = self.second_start.kept = 0
        if self.branch is not None:
            self.branch.stats = BranchStats()
        if isinstance(self._window, _core.MovingHorizon):
            self._window.plausible_kept = 0

    def sync_counts(self) -> None:
        """Add the windows that the compiled step found plausible by the branch check's
        first test (and kept without calling it) to the check's count."""
        window = self._window
        if self.branch is not None and isinstance(window, _core.MovingHorizon):
            self.branch.stats.checked += window.plausible_kept
            window.plausible_kept = 0

    def forget(self) -> None:
        self._window.restart()
        self._t_last = 0.0  # the last sample's time, s
        self._z_prev_valid: FloatArray | None = None
        #: the outputs of the last answer, for :meth:`output` and :meth:`output_std`
        self._answer: Answer | None = None
        #: the status of the last answer (:meth:`_keep`)
        self._answer_status: Status = Status.NO_ESTIMATE
        #: the window cost of the last certified fast solve (None otherwise): the
        #: branch check's measure of the window's fit
        self._last_cost: float | None = None
        self._w_new: FloatArray | None = None  # robust weights of the newest node, if known
        if self.second_start is not None:
            self.second_start.clear()

    # --- the window's state (the compiled step's or the reference's buffers) -------
    @property
    def has_state(self) -> bool:
        """Whether the window has started: it holds an arrival prior since its last
        restart."""
        return bool(self._window.has_prior)

    @property
    def sqp_iterations(self) -> int:
        """SQP iterations of the last fast solve (0 before one, and on IPOPT)."""
        return int(self._window.iterations)

    @property
    def _xbar(self) -> FloatArray | None:
        """The arrival prior's state (a copy; None before a start)."""
        return self._window.xbar.copy() if self._window.has_prior else None

    @property
    def _P(self) -> FloatArray | None:
        """The arrival prior's covariance (a copy; None before a start)."""
        return self._window.P.copy() if self._window.has_prior else None

    def _set_prior(self, xbar: FloatArray, P: FloatArray) -> None:
        """Anchor the arrival prior at ``xbar`` with covariance ``P``."""
        f64 = np.ascontiguousarray
        P = f64(P, dtype=np.float64)
        self._window.set_prior(f64(xbar, dtype=np.float64), P, f64(np.linalg.inv(P)))

    @property
    def _X(self) -> FloatArray | None:
        """The last answer (N, nx), the next warm start (a copy; None before one)."""
        return self._window.X.copy() if self._window.has_X else None

    @_X.setter
    def _X(self, X: FloatArray | None) -> None:
        self._forget_outputs()
        if X is not None:
            self._window.X[:] = X
        self._window.has_X = X is not None

    @property
    def _X_last(self) -> FloatArray | None:
        """The fast SQP's last evaluated iterate when its answer was kept: the next warm
        start instead of the answer (a copy; None when there is none)."""
        return self._window.X_last.copy() if self._window.has_X_last else None

    @_X_last.setter
    def _X_last(self, X: FloatArray | None) -> None:
        self._forget_outputs()
        if X is not None:
            self._window.X_last[:] = X
        self._window.has_X_last = X is not None

    def _forget_outputs(self) -> None:
        """The compiled step's model outputs at the last iterate are not the next warm
        start's (it was replaced)."""
        if isinstance(self._window, _core.MovingHorizon):
            self._window.outputs_at_last = -1

    @property
    def _lam(self) -> FloatArray | None:
        """The ball multipliers (N, nb) of the last fast answer (a copy; None: none)."""
        return self._window.lam.copy() if self._window.has_lam else None

    @_lam.setter
    def _lam(self, lam: FloatArray | None) -> None:
        if lam is not None:
            self._window.lam[:] = lam
        self._window.has_lam = lam is not None

    @property
    def _w_last(self) -> FloatArray:
        """Robust weights ``rho'(s_b)`` of the last answer's newest node."""
        return np.asarray(self._window.w_last)

    def window_problem(self, copy: bool = True) -> WindowProblem:
        """The NLP data for the current window (for tests and other backends).

        With ``copy=False`` the arrays are views of the window buffers, valid until
        the next sample (the arrival state is copied: a re-anchored prior does not
        change this window's problem).
        """
        w = self._window
        c = np.copy if copy else np.asarray
        return WindowProblem(
            z=c(w.zw),
            zmask=c(w.zmask),
            dt=c(w.dt),
            u=c(w.uw),
            qinv=c(w.qinvw),
            xbar=w.xbar.copy(),
            arrival=c(w.arrival),
        )

    def _predict(self, x: FloatArray, u: FloatArray, dt: float) -> FloatArray:
        """The model's next state from ``x`` after ``dt`` s, projected on the bounds."""
        if self._node is not None:
            xn = self._node.evaluate(x, u, dt)[0]
            out = np.array(xn[None, :])
            _core.project(out, *self._fast_bounds())
            return out[0]
        assert isinstance(self._window, ReferenceWindow)
        return self._window.predict(x, u, dt)

    def _fast_bounds(self) -> tuple[FloatArray, FloatArray, NDArray[np.int64], FloatArray]:
        assert self._fast is not None
        fs = self._fast.feasible
        return fs.lo, fs.hi, np.ascontiguousarray(fs.ball_idx, dtype=np.int64), fs.ball_r2

    # --- solve ----------------------------------------------------------------
    def output(self, state: FloatArray) -> FloatArray:
        answer = self._answer
        if answer is not None and state is answer.state:
            return answer.output
        if self._node is not None:
            return self._node.output(state)
        return self.formulation.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        answer = self._answer
        if answer is not None and state is answer.state and cov is answer.covariance:
            assert answer.output_std is not None
            return answer.output_std
        if self._node is not None:
            return self._node.output_std(state, cov)
        return self.formulation.output_std(state, cov)

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        f, window = self.formulation, self._window
        mask = f.measurement_mask(m.z)
        valid = bool(mask.any())
        previous, self._answer = self._answer, None
        self.log_likelihood = math.nan
        if not window.has_prior:
            if not valid:
                return None, None, Status.NO_ESTIMATE
            x0, P0 = self.start_prior(m.z, m.t)
            self._set_prior(f.project(x0), P0)
        u, (Q, Qinv) = self._no_input, (self._no_weight, self._no_weight)
        if window.k:
            dt = m.t - self._t_last
            Q, Qinv = self._process_weight(dt)
            if f.nu:
                u = f.inputs(self._z_prev_valid, m.z, dt)
            if (
                self.tracks_likelihood
                and valid
                and previous is not None
                and (self._answer_status in EVIDENCE_STATUSES)
            ):
                self.log_likelihood = self._predictive_log_likelihood(previous, m, mask, u, dt, Q)
        self._t_last = m.t
        if valid:
            self._z_prev_valid = m.z
        outcome, answer = window.step(m.t, m.z, mask, u, Q, Qinv, not self._hooks)
        if outcome == _core.StepOutcome.NO_ESTIMATE:
            return None, None, Status.NO_ESTIMATE
        if answer is not None:  # kept by the compiled step
            return self._keep(Answer(*answer), Status.OK, valid)
        answer, status = self._after_step(outcome)
        return self._keep(answer, status, valid)

    def _predictive_log_likelihood(
        self, previous: Answer, m: Measurement, mask: FloatArray, u: FloatArray, dt: float,
        Q: FloatArray,
    ) -> float:  # fmt: skip
        """The reading of ``m`` (its valid components ``mask``)'s log-density under the
        ``previous`` answer predicted over ``dt`` s with the inputs ``u`` and the process
        noise ``Q``: the compiled EKF's step from that answer (NaN where it has no
        covariance)."""
        if previous.covariance is None:
            return math.nan
        node = self._likelihood_node
        if node is None:
            node = self._node or NodeEvaluator(node_functions(self.formulation))
            self._likelihood_node = node
        f64 = np.ascontiguousarray
        node.core.likelihood_given = list(self.likelihood_given)
        node.ekf_step_outputs(
            f64(previous.state, dtype=float), f64(previous.covariance, dtype=float), u, dt,
            m.z, mask, f64(self._R, dtype=float), f64(Q, dtype=float),
        )  # fmt: skip
        return float(node.core.log_likelihood)

    @property
    def solve_seconds(self) -> float:
        """The compiled window solves' time in the last sample, s (0 on IPOPT)."""
        return float(self._window.solve_seconds)

    @solve_seconds.setter
    def solve_seconds(self, seconds: float) -> None:
        self._window.solve_seconds = seconds

    @property
    def step_seconds(self) -> float:
        """The compiled step's time in the last sample, s: the arrival prior's slide, the
        warm start, the step's own window solve, the covariance and the outputs with
        their standard deviations (not the solves of the Python hooks, which
        :attr:`solve_seconds` counts; 0 on IPOPT and for a sample that stepped no
        window)."""
        return float(self._window.step_seconds)

    @property
    def _hooks(self) -> bool:
        """Whether Python hooks follow a certified solve (the branch check, the second
        start): the compiled step then leaves its answer to :meth:`_after_step`."""
        return self.branch is not None or self.second_start is not None

    def _after_step(self, outcome: _core.StepOutcome) -> tuple[Answer, Status]:
        """The window after a step that did not keep its answer (``outcome``): the
        hooks on a certified answer, IPOPT's solve on another; the answer kept and its
        status."""
        window = self._window
        problem = self.window_problem(copy=False)
        self._last_cost = None
        self.sync_counts()
        if outcome == _core.StepOutcome.SOLVED:
            X, status = np.array(window.X_sol), Status.OK
            self._last_cost = window.cost
        elif self._fast is None:  # IPOPT's backend
            X, status = self._solve(problem, np.array(window.X0))
        else:  # the SQP did not certify its answer: IPOPT solves the window
            X, status = self._solve_ipopt(problem, np.array(window.X0))
            status = Status.FALLBACK_IPOPT if status == Status.OK else status
        solved = X
        if self.branch is not None:
            X, status = self._check_branch(problem, X, status)
        if self.second_start is not None:
            X, status = self._try_second_start(problem, X, status)
        w_new, self._w_new = self._w_new, None
        answer = window.finish(
            np.ascontiguousarray(X, dtype=np.float64),
            X is solved and outcome == _core.StepOutcome.SOLVED,
            w_new, status == Status.SOLVER_FAILED,
        )  # fmt: skip
        return Answer(*answer), status

    def policy_inference(self) -> _core.HorizonInference | None:
        """The fast backend's inference for the compiled policy
        (``_core.HorizonInference``: the window step in compiled code, this object only
        for the prior's start, the hooks and IPOPT); None on the IPOPT backend (the
        policy steps :meth:`infer`)."""
        if not isinstance(self._window, _core.MovingHorizon) or type(self).infer is not (
            MovingHorizonInference.infer
        ):
            return None
        f = self.formulation
        return _core.HorizonInference(
            self._window, _HorizonHooks(self), not self._hooks, self.flags_outliers,
            OUTLIER_WEIGHT, self._process_weight.compiled, f.input_function,
        )  # fmt: skip

    def _keep(
        self, answer: Answer, status: Status, valid: bool
    ) -> tuple[FloatArray, FloatArray | None, Status]:
        """The sample's ``(state, covariance, status)`` from the kept answer (its outputs
        kept for :meth:`output`); ``dropout`` for an ``ok`` one without a sensor."""
        self._answer = answer
        status = Status.DROPOUT if status == Status.OK and not valid else status
        self._answer_status = status
        return answer.state, answer.covariance, status

    def _node_weights(self, i: int, x: FloatArray) -> FloatArray:
        """Robust weights ``rho'(s_b)`` (nblocks,) of window node ``i`` at state ``x``."""
        return np.asarray(self._window.node_weights(i, np.ascontiguousarray(x, dtype=np.float64)))

    def bound_free_covariance(self) -> FloatArray | None:
        """The kept answer's covariance not conditioned on the bending bound its newest
        node sits on, or None where it sits on none (the window's ``cov_free``)."""
        window = self._window
        return np.array(window.cov_free) if window.cov_free_ok else None

    def outlier(self) -> bool:
        """True when the last solve down-weighted a block of the newest sample below
        :data:`~continuum_mhe.estimators.loss.OUTLIER_WEIGHT`."""
        return self.flags_outliers and bool(np.min(self._window.w_last) < OUTLIER_WEIGHT)

    def rejected_every_reading(self, rows: Sequence[int] | None = None) -> bool | None:
        """True when the last solve down-weighted every valid block of the newest sample
        below :data:`~continuum_mhe.estimators.loss.OUTLIER_WEIGHT` (one faulty IMU of
        several is not a lost estimate), or every valid block that holds any of the
        reading ``rows``; None when the sample had no such valid block."""
        if not self.flags_outliers:
            return False
        valid = (self._window.zmask[-1][self._blocks[:, 0]] > 0.0) & self._robust_block
        if rows is not None:
            starts, sizes = self._blocks[:, 0], self._blocks[:, 1]
            held = np.array([any(s <= r < s + n for r in rows) for s, n in zip(starts, sizes)])
            valid &= held
        if not valid.any():
            return None
        return bool(np.all(np.asarray(self._window.w_last)[valid] < OUTLIER_WEIGHT))

    def _solve(self, problem: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status]:
        """One solve of ``problem`` from ``X0`` (the hooks' and tests' solve): the fast
        SQP (its multipliers :attr:`_lam`, shifted by one node, warm-start it), IPOPT
        when it does not certify its answer; IPOPT alone on that backend."""
        self._last_cost = None
        if self._fast is None:
            X, status = self._solve_ipopt(problem, X0)
            if self.settings.solver == "fast" and status == Status.OK:
                status = Status.FALLBACK_IPOPT  # announced once at construction
            return X, status
        lam0 = self._lam
        if lam0 is not None:
            lam0[:-1] = lam0[1:]
            lam0[-1] = 0.0
        res = self._solve_fast(problem, X0, lam0)
        self._last_cost = res.cost if res.converged else None
        if res.converged:
            self._lam = res.lam
            return res.X, Status.OK
        self._lam = None
        X, status = self._solve_ipopt(problem, X0)
        return X, Status.FALLBACK_IPOPT if status == Status.OK else status

    def _solve_fast(
        self, problem: WindowProblem, X0: FloatArray, lam0: FloatArray | None
    ) -> FastResult:
        """The compiled core's SQP on ``problem`` from ``X0`` (the window solve alone)."""
        assert self._fast is not None
        start = time.perf_counter()
        result = solve_window(self._fast, problem, X0, self.fast_options, lam0, self._workspace)
        self.solve_seconds += time.perf_counter() - start
        return result

    def _try_second_start(
        self, problem: WindowProblem, X: FloatArray, status: Status
    ) -> tuple[FloatArray, Status]:
        """:meth:`.second_start.SecondStart.check` on this window (full windows only);
        the second solve starts without multipliers, the kept answer's warm-start."""
        second = self.second_start
        assert second is not None
        if self._window.k < self.settings.horizon:
            second.clear()
            return X, status
        kept = self._lam

        def solve(p: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status]:
            self._lam = None
            return self._solve(p, X0)

        fast = self._fast
        cost = self.window_cost if fast is None else lambda p, Xc: window_cost(fast, p, Xc)
        X2, status2, self._w_new = second.check(
            problem, X, status, lambda x: self._node_weights(-1, x), solve, cost, self._predict
        )
        if X2 is X:
            self._lam = kept
        return X2, status2

    def _check_branch(
        self, problem: WindowProblem, X: FloatArray, status: Status
    ) -> tuple[FloatArray, Status]:
        """The branch check's answer (:mod:`.branch`); restarts start without the
        previous window's multipliers, and the winner's become the warm start. When the
        answer needed the arrival prior forgotten (stage 2), the prior is re-anchored
        on the answer's first node with its covariance times ``FORGET``. The fast
        backend compares costs with its compiled model (no IPOPT NLP is built), and a
        start from which its SQP certifies no answer is not a candidate (no IPOPT solve
        of it: the check keeps converged answers only)."""
        assert self.branch is not None
        kept = self._lam

        def solve(p: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status, object]:
            self._lam = None
            if self._fast is None:
                Xc, st = self._solve(p, X0)
                return Xc, st, self._lam
            res = self._solve_fast(p, X0, None)
            self._last_cost = res.cost if res.converged else None
            if not res.converged:
                return res.X, Status.NOT_CONVERGED, None
            return res.X, Status.OK, res.lam

        fast = self._fast
        cost = self.window_cost if fast is None else lambda p, Xc: window_cost(fast, p, Xc)
        X, status, lam, forget = self.branch.check(
            problem, X, status, solve, cost, window_cost=self._last_cost
        )
        self._lam = kept if status != Status.BRANCH_RESTART else lam  # type: ignore[assignment]
        if forget:  # the answer came with the arrival prior forgotten: re-anchor it there
            P = self._P
            assert P is not None
            self._set_prior(self.formulation.project(X[0]), P * FORGET)
        return X, status

    def _solve_ipopt(self, problem: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status]:
        n, nx = self.settings.horizon, self.formulation.nx
        nlp = self._window_nlp(objective_scale_exponent(problem, self._rinv_max))
        try:
            with signals_deferred():  # IPOPT would stop on a signal as if it had failed
                sol = nlp.solver(
                    x0=X0.ravel(),
                    p=pack_parameters(problem),
                    lbx=nlp.lbx,
                    ubx=nlp.ubx,
                    lbg=nlp.lbg,
                    ubg=nlp.ubg,
                )
            stats = nlp.solver.stats()
            X = np.asarray(sol["x"], dtype=float).reshape(n, nx)
        except RuntimeError:
            return self._fallback(X0), Status.SOLVER_FAILED
        # a Ctrl-C inside IPOPT under Python's own handler (a script: not deferred)
        # ends the run, not just this solve
        raise_if_solve_interrupted(stats["return_status"])
        if stats["return_status"] == "Invalid_Number_Detected":
            # the window's model is not finite where IPOPT stands (readings at a
            # singularity of the estimate, such as a flip onto the bound): its answer is
            # the start, which no later window moves from; the estimator restarts
            raise ArithmeticError(
                "IPOPT stopped on a non-finite value of the window's model "
                "(Invalid_Number_Detected): the readings are at a singularity of the estimate"
            )
        if not np.all(np.isfinite(X)):
            return self._fallback(X0), Status.SOLVER_FAILED
        if stats["success"]:
            return X, Status.OK
        if all(self.formulation.is_feasible(x, 1e-6) for x in X):
            return X, Status.NOT_CONVERGED
        return self._fallback(X0), Status.SOLVER_FAILED

    def _fallback(self, X0: FloatArray) -> FloatArray:
        return np.array([self.formulation.project(x) for x in X0])

    def window_cost(self, problem: WindowProblem, X: FloatArray) -> float:
        """The NLP's objective for a trajectory ``X`` (N, nx): the unscaled cost, which
        every scale's NLP shares (the scale is IPOPT's option), so a built one serves."""
        nlp = next(iter(self._nlps.values()), None) or self._nlp
        return float(nlp.cost(X.ravel(), pack_parameters(problem)))


class _HorizonHooks:
    """What ``_core.HorizonInference`` asks of a :class:`MovingHorizonInference`: its
    restart, the prior's start from the first reading, and the step's Python half when
    the compiled step did not keep its answer."""

    def __init__(self, inference: MovingHorizonInference) -> None:
        self.inference = inference
        self.formulation = inference.formulation

    def restart(self, *kept: object) -> None:
        """The inference's restart, with what the policy hands it (``kept_x, kept_P,
        kept_t``: :meth:`~continuum_mhe.estimators.base.Inference.restart`)."""
        self.inference.restart(*kept)  # type: ignore[arg-type]

    def start_untrusted(self, t: float, z: FloatArray) -> bool:
        """The inference's :meth:`~continuum_mhe.estimators.base.Inference.start_untrusted`."""
        return self.inference.start_untrusted(t, z)

    def start(self, z: FloatArray) -> str | None:
        """Anchor the prior at the first reading ``z``; a numerical failure's message."""
        f = self.formulation
        try:
            x0, P0 = self.inference.start_prior(z)
            self.inference._set_prior(f.project(x0), P0)
        except NUMERICAL_FAILURES as exc:
            return numerical_failure(exc)
        return None

    def after_step(self, outcome: _core.StepOutcome, valid: bool) -> tuple[int, str | None]:
        """The status code of the kept answer (``dropout`` for an ``ok`` one without a
        valid reading), or a numerical failure's message."""
        try:
            with np.errstate(all="ignore"):  # non-finite results are the policy's to catch
                answer, status = self.inference._after_step(outcome)
        except NUMERICAL_FAILURES as exc:
            return 0, numerical_failure(exc)
        return status_code(self.inference._keep(answer, status, valid)[2]), None


class MovingHorizonEstimator(Estimator[MovingHorizonInference]):
    """MHE over the last ``N`` samples, with the sensor-health policy of
    :class:`~continuum_mhe.estimators.sensor_health.Estimator`; the window solver is
    :attr:`inference` (:class:`MovingHorizonInference`).

    Args:
        formulation: the model.
        settings: horizon, solver and IPOPT options.
        fast_options: options of the fast backend (iterations, tolerance).
        recovery: the sensor-health policy's settings (default ``RecoverySettings()``).
    """

    def __init__(
        self,
        formulation: Formulation,
        settings: MHESettings | None = None,
        fast_options: FastOptions | None = None,
        recovery: RecoverySettings | None = None,
    ) -> None:
        super().__init__(MovingHorizonInference(formulation, settings, fast_options), recovery)
