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
for the quadratic cost, Huber or Cauchy of each block's whitened norm for the robust
ones. The NLP is built once per (formulation, N, loss) with the window's measurements,
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
the Gauss-Newton SQP of :mod:`continuum_mhe.estimators.fast` and hands the window
to IPOPT when it cannot certify convergence (status ``"fallback-ipopt"``);
``"ipopt"`` is the reference.

:class:`MovingHorizonInference` is the window and its solve (the inference object);
:class:`MovingHorizonEstimator` is the sensor-health policy
(:mod:`~continuum_mhe.estimators.sensor_health`) around it.
"""

from __future__ import annotations

import warnings

import numpy as np

from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import FloatArray, Inference, Measurement, Status
from continuum_mhe.estimators.branch import FORGET, BranchCheck, BranchStats, checks_branch
from continuum_mhe.estimators.fast import (
    BackendFallbackWarning,
    FastOptions,
    FastResult,
    NodeEvaluator,
    WindowModel,
    Workspace,
    build_window_model,
    solve_window,
    window_cost,
)
from continuum_mhe.estimators.fast.covariance import casadi_window_covariance, window_covariance
from continuum_mhe.estimators.fast.model import Feasible, LossKernel, feasible_set
from continuum_mhe.estimators.kalman import ekf_predict, ekf_update
from continuum_mhe.estimators.loss import (
    LOSS_CODES,
    OUTLIER_WEIGHT,
    block_array,
    block_weights,
)
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.estimators.second_start import SecondStart
from continuum_mhe.estimators.sensor_health import Estimator
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


class MovingHorizonInference(Inference):
    """The MHE's inference: the window problem over the last ``N`` samples, solved
    each sample, and its arrival prior (:class:`MovingHorizonEstimator` steps it).

    Backends (``settings.solver``): ``"fast"`` (default), the structure-exploiting
    Gauss-Newton SQP of :mod:`continuum_mhe.estimators.fast`, which falls back to
    IPOPT on the same window (status ``"fallback-ipopt"``) when it cannot certify
    convergence; ``"ipopt"``, the paper's solver and the reference.

    Args:
        formulation: the model.
        settings: horizon, solver and IPOPT options.
        fast_options: options of the fast backend (iterations, tolerance).
    """

    name = "mhe"

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
        self._node = None if self._fast is None else NodeEvaluator(self._fast)
        self._workspace = None if self._fast is None else Workspace(self._fast)
        self._nlp_built: Nlp | None = None
        if self._fast is None:
            self._nlp_built = self._nlp
        self._process_weight = ProcessNoiseCache(formulation)
        self._R = formulation.meas_cov()
        self._feasible: Feasible | None = None if self._fast is None else self._fast.feasible
        #: why the window covariance leaves the constraints out (None when it does not)
        self.covariance_note: str | None = None
        if self._feasible is None:
            try:
                self._feasible = feasible_set(formulation)
            except NotImplementedError as exc:  # a feasible set the kernel cannot read
                self.covariance_note = (
                    f"the window covariance leaves this problem's constraints out ({exc}): "
                    "its standard deviations are too large where a bound is active"
                )
                warnings.warn(self.covariance_note, BackendFallbackWarning, stacklevel=2)
        self._blocks = block_array(formulation.measurement_blocks)
        #: per measurement component, its block's index (nblocks: in no block)
        self._block_of = np.full(formulation.nz, len(self._blocks))
        for b, (start, size) in enumerate(self._blocks):
            self._block_of[start : start + size] = b
        self._Rinv = np.asarray(np.linalg.inv(self._R), dtype=np.float64)
        #: True when the robust loss is in use (estimates carry outlier flags)
        self.flags_outliers = self.settings.loss != "l2"
        #: the robust loss's second start (:mod:`.second_start`), with its counts
        self.second_start = SecondStart(s.horizon) if self.flags_outliers else None
        #: the branch check (``settings.branch_check``, by default for tilt only; see
        #: :mod:`.branch`), with its counts
        self.branch = (
            BranchCheck(formulation, s.horizon, quadratic=s.loss == "l2")
            if checks_branch(formulation, s.branch_check)
            else None
        )
        self._rinv_max = float(np.abs(np.linalg.inv(self._R)).max())
        self.restart()

    @property
    def _nlp(self) -> Nlp:
        """The IPOPT NLP, built on first use (the fast backend needs it only to fall back)."""
        if self._nlp_built is None:
            s = self.settings
            self._nlp_built = build_nlp(
                self.formulation, s.horizon, s.max_iter, s.tol, s.loss, s.scale
            )
        return self._nlp_built

    @_nlp.setter
    def _nlp(self, nlp: Nlp) -> None:
        self._nlp_built = nlp

    def clear_counts(self) -> None:
        """Zero the second start's and the branch check's counts."""
        if self.second_start is not None:
            self.second_start.tried = self.second_start.kept = 0
        if self.branch is not None:
            self.branch.stats = BranchStats()

    def restart(self) -> None:
        f, n, nx = self.formulation, self.settings.horizon, self.formulation.nx
        # window buffers, aligned at the end: sample i of N, stage i joins i and i+1
        self._k = 0  # samples in the window
        self._tw = np.zeros(n)
        self._zw = np.zeros((n, f.nz))  # 0 where masked
        self._zmask = np.zeros((n, f.nz))
        self._dt = np.ones(n - 1)  # 1 s on inactive stages
        self._uw = np.zeros((n - 1, f.nu))
        self._qw = np.zeros((n - 1, nx, nx))  # Q(dt)
        self._qinvw = np.zeros((n - 1, nx, nx))  # Q(dt)^-1 (0 on inactive stages)
        self._arrival = np.zeros((n, nx, nx))  # see window_problem
        self._z_prev_valid: FloatArray | None = None
        self._xbar: FloatArray | None = None
        self._P: FloatArray | None = None
        self._Pinv: FloatArray | None = None  # P^-1, the arrival weight
        self._X: FloatArray | None = None  # (N, nx) previous solution
        #: the fast SQP's last evaluated iterate when its certified answer was kept as
        #: ``_X``: the next warm start
        self._X_last: FloatArray | None = None
        self._lam: FloatArray | None = None  # (N,) its ball multipliers (fast backend)
        #: the last fast SQP's Gauss-Newton blocks (FastResult.hessian) for the covariance
        self._last_hessian: tuple[FloatArray, FloatArray] | None = None
        self._last_iterate: FloatArray | None = None  # and FastResult.X_last
        #: the last fast SQP's window cost at its last evaluated iterate (None on IPOPT)
        self._last_cost: float | None = None
        #: SQP iterations of the last fast solve (0 before one)
        self.sqp_iterations = 0
        # robust weights rho'(s_b) per block of the first and last node of the last solve
        self._w_first = np.ones(len(self._blocks))
        self._w_last = np.ones(len(self._blocks))
        self._w_new: FloatArray | None = None  # robust weights of the newest node, if known
        if self.second_start is not None:
            self.second_start.clear()

    # --- window bookkeeping -------------------------------------------------
    def _push(self, m: Measurement, mask: FloatArray) -> None:
        f = self.formulation
        valid = bool(mask.any())
        n = self.settings.horizon
        if self._k == n:
            self._slide_arrival()
        u = np.zeros(f.nu)
        if self._k and f.nu:
            u = f.inputs(self._z_prev_valid, m.z, m.t - self._tw[-1])
        for buf in (self._tw, self._zw, self._zmask, self._dt, self._uw, self._qw, self._qinvw):
            buf[:-1] = buf[1:]
        self._tw[-1] = m.t
        self._zmask[-1] = mask
        self._zw[-1] = np.where(mask > 0, m.z, 0.0)
        if self._k:
            dt = m.t - self._tw[-2]
            self._dt[-1] = dt
            self._uw[-1] = u
            self._qw[-1], self._qinvw[-1] = self._process_weight(dt)
        else:
            self._dt[-1], self._uw[-1], self._qw[-1], self._qinvw[-1] = 1.0, 0.0, 0.0, 0.0
        self._k = min(self._k + 1, n)
        if valid:
            self._z_prev_valid = m.z

    def _leaving_R(self) -> FloatArray:
        """Covariance of the leaving sample's update: ``R``, or with a robust loss
        ``R_b / w_b`` per block at its weight in the last solve."""
        R = self._R
        if self.flags_outliers:  # the leaving sample at its weight in the last solve
            scale = np.append(1.0 / np.maximum(self._w_first, 1e-12), 1.0)[self._block_of]
            R = R * np.sqrt(np.outer(scale, scale))
        return R

    def _slide_arrival(self) -> None:
        """Move the arrival prior from window sample 0 to window sample 1.

        One EKF step on the prior itself: update ``(xbar, P)`` with the sample that
        leaves the window, then predict to the next sample. The prior therefore holds
        only information from samples that have left the window (no measurement is
        counted twice), and on a linear Gaussian model the MHE equals the Kalman
        filter at every sample, sliding or not.
        """
        assert self._xbar is not None and self._P is not None
        f, x, P = self.formulation, self._xbar, self._P
        u, dt, z = self._uw[0], float(self._dt[0]), self._zw[0]
        R = self._leaving_R()
        if self._node is not None:  # the same EKF step, on the compiled model
            xn, self._P, self._Pinv = self._node.arrival_step(
                x, P, u, dt, z, self._zmask[0], R, self._qw[0]
            )
        else:
            if self._zmask[0].any():
                x, P = ekf_update(f, x, P, z, R, self._zmask[0])
            xn, P = ekf_predict(f.functions, x, P, u, dt)
            self._P = 0.5 * (P + P.T)
            self._Pinv = np.asarray(np.linalg.inv(self._P), dtype=np.float64)
        self._xbar = f.project(xn)

    def window_problem(self, copy: bool = True) -> WindowProblem:
        """The NLP data for the current window (for tests and other backends).

        With ``copy=False`` the arrays are views of the window buffers, valid until
        the next sample.
        """
        off = self.settings.horizon - self._k  # leading inactive nodes
        assert self._Pinv is not None and self._xbar is not None
        arrival = self._arrival  # pinned identity before off, P^-1 at off, 0 after
        if off:
            arrival[:off] = np.eye(self.formulation.nx)
        arrival[off : off + 2] = 0.0  # off moves down by one per sample while growing
        arrival[off] = self._Pinv
        c = np.copy if copy else np.asarray
        return WindowProblem(
            z=c(self._zw),
            zmask=c(self._zmask),
            dt=c(self._dt),
            u=c(self._uw),
            qinv=c(self._qinvw),
            xbar=c(self._xbar),
            arrival=c(arrival),
        )

    def _initial_guess(self) -> FloatArray:
        n = self.settings.horizon
        assert self._xbar is not None
        if self._X is None:
            return np.tile(self._xbar, (n, 1))
        prev = self._X if self._X_last is None else self._X_last
        X = np.empty_like(prev)
        X[:-1] = prev[1:]
        dt = float(self._tw[-1] - self._tw[-2]) if self._k > 1 else 0.0
        X[-1] = self._predict(prev[-1], self._uw[-1], dt)
        return X

    def _predict(self, x: FloatArray, u: FloatArray, dt: float) -> FloatArray:
        """The model's next state from ``x`` after ``dt`` s, projected on the bounds."""
        if self._node is not None:
            xn = self._node.evaluate(x, u, dt)[0]
        else:
            xn = np.asarray(self.formulation.functions.transition(x, u, dt), float).ravel()
        return self.formulation.project(xn)

    # --- solve ----------------------------------------------------------------
    def output(self, state: FloatArray) -> FloatArray:
        if self._node is not None:
            return self._node.output(state)
        return self.formulation.output(state)

    def output_std(self, state: FloatArray, cov: FloatArray) -> FloatArray:
        if self._node is not None:
            return self._node.output_std(state, cov)
        return self.formulation.output_std(state, cov)

    def infer(self, m: Measurement) -> tuple[FloatArray | None, FloatArray | None, Status]:
        f = self.formulation
        mask = f.measurement_mask(m.z)
        valid = bool(mask.any())
        if self._xbar is None:
            if not valid:
                return None, None, Status.NO_ESTIMATE
            self._xbar = np.array(f.project(f.initial_state(m.z)), dtype=np.float64)
            self._P = np.array(f.initial_cov(), dtype=np.float64)
            self._Pinv = np.asarray(np.linalg.inv(self._P), dtype=np.float64)
        self._push(m, mask)
        X0 = self._initial_guess()
        self._X_last = None
        if self.settings.paper_start and self._k < self.settings.horizon:
            self._X = X0
            return None, None, Status.NO_ESTIMATE
        problem = self.window_problem(copy=False)
        X, status = self._solve(problem, X0)
        solved, hessian, last_iterate = X, self._last_hessian, self._last_iterate
        if self.branch is not None:
            X, status = self._check_branch(problem, X, status)
        if self.second_start is not None:
            X, status = self._try_second_start(problem, X, status)
        status = self._keep(X, status, valid)
        if X is solved:  # the SQP's answer is kept: warm-start from its last iterate
            self._X_last = last_iterate
        hessian = hessian if X is solved else None  # the SQP's, if its answer is kept
        cov = None if status == Status.SOLVER_FAILED else self.covariance(problem, X, hessian)
        return X[-1].copy(), cov, status

    def _keep(
        self, X: FloatArray, status: Status, valid: bool, weights: FloatArray | None = None
    ) -> Status:
        """Keep the answer ``X`` (N, nx) as the next warm start, with its robust weights
        (``weights``: those of its first and last node (2, nblocks) if known); returns the
        sample's status (``dropout`` for an ``ok`` one without a sensor)."""
        self._X = X
        if weights is not None:
            self._w_first, self._w_last = weights[0].copy(), weights[1].copy()
            self._w_new = None
        elif self.flags_outliers:
            self._w_first = self._node_weights(0, X[0])
            w_new, self._w_new = self._w_new, None  # the newest node's, if computed
            self._w_last = self._node_weights(-1, X[-1]) if w_new is None else w_new
        return Status.DROPOUT if status == Status.OK and not valid else status

    def covariance(
        self,
        problem: WindowProblem,
        X: FloatArray,
        hessian: tuple[FloatArray, FloatArray] | None = None,
    ) -> FloatArray | None:
        """Covariance of the estimate ``X[-1]`` (nx, nx): the last block of the inverse
        of the window's Gauss-Newton Hessian at ``X`` (N, nx), conditioned on the active
        bounds (:mod:`continuum_mhe.estimators.fast.covariance`); from the compiled
        model on the fast backend, from CasADi on IPOPT. ``hessian``: the fast SQP's
        blocks at its last evaluated iterate when ``X`` is its certified answer (that
        iterate is within the convergence tolerance of ``X``; no evaluation then). None
        if not positive definite.
        """
        if self._fast is not None:
            return window_covariance(self._fast, problem, X, self._workspace, hessian=hessian)
        loss = LossKernel(self._blocks, LOSS_CODES[self.settings.loss], float(self.settings.scale))
        return casadi_window_covariance(self.formulation, problem, X, self._feasible, loss=loss)

    def _node_weights(self, i: int, x: FloatArray) -> FloatArray:
        """Robust weights ``rho'(s_b)`` (nblocks,) of window node ``i`` at state ``x``."""
        z, mask = self._zw[i], self._zmask[i]
        if self._node is not None:
            r = self._node.evaluate(x, self._uw[0], 0.0, z, mask)[3]
        else:
            fns = self.formulation.functions
            r = mask * np.asarray(fns.innovate(z, x)[0], float).ravel()
        s = self.settings
        return block_weights(s.loss, s.scale, r, self._Rinv, self._blocks)

    def outlier(self) -> bool:
        """True when the last solve down-weighted a block of the newest sample below
        :data:`~continuum_mhe.estimators.loss.OUTLIER_WEIGHT`."""
        return self.flags_outliers and bool(np.min(self._w_last) < OUTLIER_WEIGHT)

    def rejected_every_reading(self) -> bool | None:
        """True when the last solve down-weighted every valid block of the newest sample
        below :data:`~continuum_mhe.estimators.loss.OUTLIER_WEIGHT` (one faulty IMU of
        several is not a lost estimate); None when the sample had no valid block."""
        if not self.flags_outliers:
            return False
        valid = self._zmask[-1][self._blocks[:, 0]] > 0.0
        if not valid.any():
            return None
        return bool(np.all(self._w_last[valid] < OUTLIER_WEIGHT))

    def _solve(self, problem: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status]:
        self._last_hessian = self._last_iterate = self._last_cost = None
        if self._fast is None:
            X, status = self._solve_ipopt(problem, X0)
            if self.settings.solver == "fast" and status == Status.OK:
                status = Status.FALLBACK_IPOPT  # announced once at construction
            return X, status
        lam0 = None
        if self._lam is not None:
            lam0 = np.empty_like(self._lam)
            lam0[:-1] = self._lam[1:]
            lam0[-1] = 0.0
        res = self._solve_fast(problem, X0, lam0)
        self.sqp_iterations = res.iterations
        self._last_hessian, self._last_iterate = res.hessian, res.X_last
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
        return solve_window(self._fast, problem, X0, self.fast_options, lam0, self._workspace)

    def _try_second_start(
        self, problem: WindowProblem, X: FloatArray, status: Status
    ) -> tuple[FloatArray, Status]:
        """:meth:`.second_start.SecondStart.check` on this window (full windows only);
        the second solve starts without multipliers, the kept answer's warm-start."""
        second = self.second_start
        assert second is not None
        if self._k < self.settings.horizon:
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
        backend compares costs with its compiled model (no IPOPT NLP is built)."""
        assert self.branch is not None
        kept = self._lam

        def solve(p: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status, object]:
            self._lam = None
            Xc, st = self._solve(p, X0)
            return Xc, st, self._lam

        fast = self._fast
        cost = self.window_cost if fast is None else lambda p, Xc: window_cost(fast, p, Xc)
        X, status, lam, forget = self.branch.check(
            problem, X, status, solve, cost, window_cost=self._last_cost
        )
        self._lam = kept if status != Status.BRANCH_RESTART else lam  # type: ignore[assignment]
        if forget:  # the answer came with the arrival prior forgotten: re-anchor it there
            assert self._P is not None
            self._xbar = self.formulation.project(X[0])
            self._P = self._P * FORGET
            self._Pinv = np.asarray(np.linalg.inv(self._P), dtype=np.float64)
        return X, status

    def _solve_ipopt(self, problem: WindowProblem, X0: FloatArray) -> tuple[FloatArray, Status]:
        n, nx, s = self.settings.horizon, self.formulation.nx, self.settings
        exp = objective_scale_exponent(problem, self._rinv_max)
        nlp = self._nlp if exp == 0 else build_nlp(
            self.formulation, n, s.max_iter, s.tol, s.loss, s.scale, exp)  # fmt: skip
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
        """The NLP's objective for a trajectory ``X`` (N, nx)."""
        return float(self._nlp.cost(X.ravel(), pack_parameters(problem)))


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
