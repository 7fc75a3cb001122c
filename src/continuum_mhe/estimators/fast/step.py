"""One MHE step of the fast backend in one compiled call (numba kernels).

The estimator's per-sample work around the SQP (sliding the arrival prior, shifting the
window's buffers, the initial guess, the arrival weights, the covariance and the
outputs) is small arithmetic, which costs more than the SQP itself when done in Python
(the interpreter's overhead per operation). :func:`advance` does it
up to and including the SQP, :func:`finish` the covariance and the outputs, and
:func:`advance_finish` both in one call when the SQP's answer is final (certified,
no branch check or second start to follow; made through :class:`~.ccall.CompiledCall`,
which skips the dispatcher's typing of its 60 arrays on every call), on buffers that
:class:`~continuum_mhe.estimators.mhe.MovingHorizonEstimator` owns (its window
buffers are the :class:`~continuum_mhe.estimators.fast.sqp.Workspace`'s, so
the C model's argument pointers never change). The equations are those of the
estimator's Python path: :meth:`~continuum_mhe.estimators.mhe.MovingHorizonEstimator._push`,
``_slide_arrival``, ``_initial_guess`` and ``window_problem``, then
:func:`~continuum_mhe.estimators.fast.sqp.solve_window`,
:func:`~continuum_mhe.estimators.fast.covariance.window_covariance` and
:class:`~continuum_mhe.estimators.fast.model.NodeEvaluator`'s ``output`` and
``output_std``.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.estimators.fast.arrival import arrival_step
from continuum_mhe.estimators.fast.ccall import CompiledCall, address, call_model
from continuum_mhe.estimators.fast.codegen import failure_message
from continuum_mhe.estimators.fast.covariance import last_block_covariance
from continuum_mhe.estimators.fast.memory import copy_into, shift_rows
from continuum_mhe.estimators.fast.model import NodeEvaluator, WindowModel
from continuum_mhe.estimators.fast.outputs import (
    OUTPUT_FAILED,
    OUTPUT_JACOBIAN_FAILED,
    output_std,
    output_values,
)
from continuum_mhe.estimators.fast.qp import CONVERGED
from continuum_mhe.estimators.fast.sqp import Workspace
from continuum_mhe.estimators.loss import OUTLIER_WEIGHT, _block_weights

FloatArray = NDArray[np.float64]
OptArray = FloatArray | None
#: ``(xbar, P, P^-1)`` of the arrival prior.
Prior = tuple[FloatArray, FloatArray, FloatArray]
#: ``(t, z, mask, u, dt, Q, Q^-1)``: the new sample (see :func:`advance`).
Sample = tuple[float, FloatArray, FloatArray, FloatArray, float, FloatArray, FloatArray]
#: ``(solve, max_iter, step_tol, err_tol, max_qp, newton, quadratic)``.
StepOptions = tuple[bool, int, float, float, int, bool, bool]
#: ``(outcome, iterations, step, cost, buffer of the answer)``.
Outcome = tuple[int, int, float, float, int]
#: ``(outputs, covariance, output standard deviations)``; None: not positive definite.
Finished = tuple[FloatArray, FloatArray | None, FloatArray | None]

#: :func:`advance` did not solve (``paper_start`` before ``N`` samples).
NOT_SOLVED = -1
#: :func:`advance_finish` did not finish: the window was not certified ...
UNCERTIFIED = -1
#: ... or its answer rejects the newest sample, so a second start may replace it.
NEWEST_REJECTED = -2

#: The kernels' error when the window's or node's model fails (the kernels cannot format
#: the model's own message; the wrappers do; the outputs': :data:`.outputs.OUTPUT_FAILED`).
MODEL_FAILED = "model evaluation failed"


@numba.njit(cache=True)
def _core_solve(core, qinv, xbar, arrival, zmask, lam, options, result):
    """The compiled core's SQP (``WindowSolver.solve``) through its C entry point;
    ``core``: :attr:`StepBuffers.core`; ``options`` (8,) and ``result`` (5,) as
    ``csrc/sqp.hpp`` lays them out. Returns ``(outcome, iterations, step, cost, buffer
    of the answer)``."""
    args = np.empty(7, dtype=np.uintp)
    args[0] = core[0]
    args[1] = qinv.ctypes.data
    args[2] = xbar.ctypes.data
    args[3] = arrival.ctypes.data
    args[4] = zmask.ctypes.data
    args[5] = lam.ctypes.data
    args[6] = options.ctypes.data
    if call_model(core[1], args.ctypes.data, result.ctypes.data) != 0:
        raise RuntimeError(MODEL_FAILED)
    return int(result[0]), int(result[1]), result[2], result[3], int(result[4])


@numba.njit(cache=True)
def _core_evaluate(core, buf, qinv, xbar, arrival, zmask):
    """The core's model evaluation and assembly of workspace buffer ``buf``; the cost
    (inf if the model failed)."""
    args = np.empty(6, dtype=np.uintp)
    which = np.full(1, float(buf))
    cost = np.empty(1)
    args[0] = core[0]
    args[1] = qinv.ctypes.data
    args[2] = xbar.ctypes.data
    args[3] = arrival.ctypes.data
    args[4] = zmask.ctypes.data
    args[5] = which.ctypes.data
    if call_model(core[2], args.ctypes.data, cost.ctypes.data) != 0:
        return np.inf
    return cost[0]


@numba.njit(cache=True)
def _core_shift(core, src, dst):
    """The core's ``shift_outputs(src, dst)``; False if the tail function failed."""
    args = np.empty(2, dtype=np.uintp)
    which = np.array([float(src), float(dst)])
    args[0] = core[0]
    args[1] = which.ctypes.data
    return call_model(core[3], args.ctypes.data, which.ctypes.data) == 0


@numba.njit(cache=True)
def _core_project(core, X, rows):
    """Project ``rows`` nodes of ``X`` (C-contiguous, from its start) in place."""
    args = np.empty(3, dtype=np.uintp)
    count = np.full(1, float(rows))
    args[0] = core[0]
    args[1] = X.ctypes.data
    args[2] = count.ctypes.data
    call_model(core[4], args.ctypes.data, count.ctypes.data)


@numba.njit(cache=True)
def _shift(a):
    """``a[:-1] = a[1:]`` along the first axis, in place (C-contiguous)."""
    shift_rows(a, a, 0, a.shape[0] - 1)


@numba.njit(cache=True)
def advance(
    node, nptrs, nout, nin, win, wptrs, prior, window, new, Rs, X, has_X, lam, has_lam, X0,
    feasible, options, ws, loss,
):  # fmt: skip
    """Take one sample into the window and solve it.

    ``node``/``win``: addresses of the node and window functions; ``nptrs``, ``nout``
    and ``nin = (x, u, dt, z, m)`` the node function's argument pointers, output and
    inputs. ``prior = (xbar, P, Pinv, k)`` (``k`` (1,) int: samples in the window,
    updated); ``window = (tw, z, m, nodemask, u, dt, qw, qinvw, arrival)``;
    ``new = (t, z, mask, u, dt, Q, Qinv)`` the sample (``z`` as read: its components
    with ``mask`` 0 are stored as 0 here; ``dt`` from the
    previous sample, ``Q`` and ``Qinv`` at ``dt``; ignored on the first sample);
    ``Rs`` the measurement covariance of the leaving sample's update. ``X``: the
    previous solution (if ``has_X``), ``lam`` its ball multipliers (if ``has_lam``;
    shifted here, the answer's on return); ``X0`` receives the initial guess.
    ``options = (solve, max_iter, step_tol, err_tol, max_qp, newton, quadratic)``
    (``quadratic``: :func:`~continuum_mhe.estimators.fast.sqp.quadratic_rate`); ``loss = (R^-1,
    LossKernel)``; ``ws``: the workspace's SQP buffers, the stage products, the tail
    function's address, pointers and output, and ``last`` (``StepBuffers.sqp``).
    With ``last[0] = b >= 0`` (set here when the previous window was certified; the
    caller resets it to -1 when it replaced that answer or solved in these buffers), the
    warm start is buffer ``b``'s iterate (the SQP's last evaluated one) shifted, not
    ``X``, and its model outputs shift with it (:func:`~.sqp.shift_outputs`).
    Returns ``(outcome, iterations, step, cost, buffer of the answer)``; ``outcome``
    :data:`NOT_SOLVED` when ``solve`` is 0.
    """
    xbar, P, Pinv, kk = prior
    tw, z, m, nodemask, u, dt, qw, qinvw, arrival = window
    t, znew, mask, unew, dtnew, Qn, Qinvn = new
    lo, hi, bidx, r2 = feasible
    solve, max_iter, step_tol, err_tol, max_qp, newton, quadratic = options
    Xb, out, D, E, g, d, lam_qp, wgt, extra, gb, Dgn, ncost, stage, core, last = ws
    xin, uin, dtin, zin, min_ = nin
    rinv, lossk = loss
    n, nx = X0.shape
    k = kk[0]
    full = k == n  # the previous window was full: its arrival weighted only its node 0
    if full:  # slide the arrival prior: the EKF step on the sample that leaves
        uin[:] = u[0]
        dtin[0] = dt[0]
        zin[:] = z[0]
        min_[:] = m[0]
        valid = False
        for c in range(m.shape[1]):
            if m[0, c] != 0.0:
                valid = True
        xn, Pn, Pinvn = arrival_step(node, nptrs, nout, xin, xbar, P, valid, Rs, qw[0], nx)
        xbar[:] = xn
        _core_project(core, xbar, 1)
        P[:] = Pn
        Pinv[:] = Pinvn
    _shift(z)
    _shift(m)
    _shift(qw)
    _shift(qinvw)
    done, eq, fqf = stage
    if done.shape[0] > 0:  # the stage products move with Q^-1; the new stage's are formed
        _shift(done)
        _shift(eq)
        _shift(fqf)
        done[n - 2] = 0
    _shift(tw)
    _shift(dt)
    _shift(u)
    tw[n - 1] = t
    for c in range(znew.shape[0]):
        m[n - 1, c] = mask[c]
        z[n - 1, c] = znew[c] if mask[c] > 0 else 0.0
    if k:
        dt[n - 2] = dtnew
        u[n - 2] = unew
        qw[n - 2] = Qn
        qinvw[n - 2] = Qinvn
    elif n > 1:
        dt[n - 2] = 1.0
        u[n - 2] = 0.0
        qw[n - 2] = 0.0
        qinvw[n - 2] = 0.0
    k = min(k + 1, n)
    kk[0] = k
    for i in range(n):
        nodemask[i] = 0.0
        for c in range(m.shape[1]):
            if m[i, c] != 0.0:
                nodemask[i] = 1.0
    # initial guess: the previous solution shifted, its last node predicted; the SQP's
    # last evaluated iterate when the previous answer is its certified one (``last``:
    # that buffer, whose model outputs then shift with it), so that only the new node
    # and stage need the model
    b = last[0] if has_X and n > 1 and core[5] != 0 else -1
    last[0] = -1
    if b >= 0:
        X = Xb[b]
    if has_X:
        for i in range(n - 1):
            X0[i] = X[i + 1]
        xin[:] = X[n - 1]
        if n > 1:
            uin[:] = u[n - 2]
        dtin[0] = tw[n - 1] - tw[n - 2] if k > 1 else 0.0
        zin[:] = 0.0
        min_[:] = 1.0
        if call_model(node, nptrs.ctypes.data, nout.ctypes.data) != 0:
            raise RuntimeError(MODEL_FAILED)
        X0[n - 1] = nout[:nx]
        _core_project(core, X0[n - 1], 1)
    else:
        for i in range(n):
            X0[i] = xbar
    if not solve:
        return NOT_SOLVED, 0, np.inf, np.inf, 0
    # arrival weights: pinned identity before the first active node, P^-1 on it
    off = n - k
    for i in range(off):
        arrival[i] = 0.0
        for j in range(nx):
            arrival[i, j, j] = 1.0
    for i in range(off, min(off + 2, n)):
        arrival[i] = 0.0
    arrival[off] = Pinv
    if has_lam:
        _shift(lam)
        lam[n - 1] = 0.0
    else:
        lam[:] = 0.0
    copy_into(Xb[0], X0)
    evaluated = b >= 0 and _core_shift(core, b, 0)
    shifted = b if full else -1  # the buffer whose assembly shifts with its outputs
    opts = np.array([max_iter, step_tol, err_tol, max_qp, newton, quadratic, evaluated, shifted],
                    dtype=np.float64)  # fmt: skip
    res = _core_solve(core, qinvw, xbar, arrival, nodemask, lam, opts, np.empty(5))
    if res[0] == CONVERGED:
        last[0] = 1 - res[4]
    return res


@numba.njit(cache=True)
def finish(win, wptrs, X, xbar, window, feasible, ws, loss, hb, tol, cov, outputs, y, std):
    """Covariance of ``X[-1]`` (into ``cov``) and its outputs ``y`` and standard
    deviations ``std``, as :func:`~.covariance.window_covariance` and
    :class:`~.model.NodeEvaluator` compute them (``outputs``: see :mod:`.outputs`).
    ``hb``: the workspace buffer whose Gauss-Newton blocks to use (the SQP's last
    evaluated iterate, when ``X`` is its certified answer), or -1 to evaluate them at
    ``X``.
    Returns 0, or 1 when the covariance is not available (``cov`` and ``std`` then
    unset); raises when the output functions fail."""
    tw, z, m, nodemask, u, dt, qw, qinvw, arrival = window
    lo, hi, bidx, r2 = feasible
    Xb, out, D, E, g, d, lam_qp, wgt, extra, gb, Dgn, ncost, stage, core, last = ws
    rinv, lossk = loss
    n = X.shape[0]
    output_values(outputs, X[n - 1], y)
    if hb >= 0:
        Dh, Eh = Dgn[hb], E[hb]
    else:  # evaluated in buffer 0: no window's outputs are kept for the next shift
        last[0] = -1
        Xb[0] = X
        c = _core_evaluate(core, 0, qinvw, xbar, arrival, nodemask)
        if not np.isfinite(c):
            return 1
        Dh, Eh = D[0], E[0]
    if not last_block_covariance(X, Dh, Eh, lo, hi, bidx, r2, tol, cov):
        return 1
    output_std(outputs, cov, std)
    return 0


@numba.njit(cache=True)
def node_weights(node, nptrs, nout, nin, x, z, m, u, rinv, lossk, w):
    """Into ``w`` (nblocks,): the robust weights ``rho'(s_b)`` of one window node at state
    ``x`` with reading ``z`` and mask ``m`` (its residual from the node function at
    ``u``, ``dt = 0``), as the estimator's Python path computes them
    (:meth:`~continuum_mhe.estimators.mhe.MovingHorizonEstimator._node_weights`)."""
    xin, uin, dtin, zin, min_ = nin
    xin[:] = x
    uin[:] = u
    dtin[0] = 0.0
    zin[:] = z
    min_[:] = m
    if call_model(node, nptrs.ctypes.data, nout.ctypes.data) != 0:
        raise RuntimeError(MODEL_FAILED)
    nx, nz = x.shape[0], z.shape[0]
    r0 = nx + nx * nx + nz * nx  # the node function's outputs: f, df/dx, -dr/dx, r
    w[:] = _block_weights(lossk.code, lossk.scale, nout[r0 : r0 + nz], rinv, lossk.blocks)


@numba.njit(cache=True)
def advance_finish(
    node, nptrs, nout, nin, win, wptrs, prior, window, new, Rs, X, has_X, lam, has_lam, X0,
    feasible, options, ws, loss, tol, outputs, answer, cov, y, std, robust, weights,
):  # fmt: skip
    """:func:`advance`, then, if its SQP certified the window, the answer into ``answer``
    (N, nx) and :func:`finish` on it with the SQP's last Gauss-Newton blocks: one
    compiled call per sample where nothing (IPOPT, the branch check, a second start)
    may change the answer in between. With a ``robust`` loss, first the robust weights
    of the answer's first and last node into ``weights`` (2, nblocks;
    :func:`node_weights`); when the window is full and the last node's lowest weight is
    below :data:`~continuum_mhe.estimators.loss.OUTLIER_WEIGHT` (the estimator then
    tries a second start, which may change the answer), nothing is finished. Returns
    ``(advance's result, finish's result)``, the second :data:`UNCERTIFIED` or
    :data:`NEWEST_REJECTED` when nothing was finished."""
    res = advance(
        node, nptrs, nout, nin, win, wptrs, prior, window, new, Rs, X, has_X, lam, has_lam,
        X0, feasible, options, ws, loss,
    )  # fmt: skip
    if res[0] != CONVERGED:
        return res, UNCERTIFIED
    cur = res[4]
    copy_into(answer, ws[0][cur])
    if robust:
        z, m, u = window[1], window[2], window[4]
        n = answer.shape[0]
        rinv, lossk = loss
        node_weights(node, nptrs, nout, nin, answer[0], z[0], m[0], u[0], rinv, lossk, weights[0])
        node_weights(
            node, nptrs, nout, nin, answer[n - 1], z[n - 1], m[n - 1], u[0], rinv, lossk,
            weights[1],
        )  # fmt: skip
        if prior[3][0] == n and np.min(weights[1]) < OUTLIER_WEIGHT:
            return res, NEWEST_REJECTED
    failed = finish(
        win, wptrs, answer, prior[0], window, feasible, ws, loss, 1 - cur, tol, cov, outputs, y,
        std,
    )  # fmt: skip
    return res, failed


class StepBuffers:
    """The buffers of :func:`advance` and :func:`finish` for one estimator: its window
    (``tw``, ``z``, ``m``, ``u``, ``dt``, ``qw``, ``qinvw``, ``arrival``, aligned at
    the end as the estimator's), the SQP's workspace (whose ``z``, ``m``, ``u`` and
    ``dt`` are the window's), and the node evaluator's inputs and outputs."""

    def __init__(self, model: WindowModel, node: NodeEvaluator) -> None:
        n, nx, nu = model.horizon, model.nx, model.nu
        fs = model.feasible
        self.workspace = ws = Workspace(model)
        self.tw, self.z, self.m, self.u, self.dt = np.zeros(n), ws.z, ws.m, ws.u, ws.dt
        self.nodemask = np.zeros(n)
        self.qw = np.zeros((n - 1, nx, nx))  # Q(dt)
        self.qinvw = np.zeros((n - 1, nx, nx))  # Q(dt)^-1 (0 on inactive stages)
        self.arrival = np.zeros((n, nx, nx))
        self.k = np.zeros(1, dtype=np.int64)  # samples in the window
        #: the workspace buffer holding the SQP's last evaluated iterate of the previous
        #: window, when its certified answer was kept (:func:`advance`); -1: none
        self.last = np.full(1, -1, dtype=np.int64)
        self.X0 = np.zeros((n, nx))  # initial guess
        self.lam = np.zeros((n, len(fs.ball_r2)))  # multipliers when none are kept
        self.cov = np.empty((nx, nx))
        self.y = np.empty(model.ny)
        self.std = np.empty(model.ny)
        #: robust weights of the fused call's answer's first and last node (its ``robust``)
        self.weights = np.ones((2, len(model.loss.blocks)))
        self.u0 = np.zeros(nu)
        self.zeros = np.zeros((nx, nx))
        self.node = node
        # the fused kernel through the overload its first call selects: its arguments
        # are these buffers, the estimator's own (kept, never replaced, on the path
        # that uses it) and the sample, normalised (_advance_args)
        self._advance_finish = CompiledCall(advance_finish)
        self.nin = (node._x, node._u, node._dt, node._z, node._m)
        self.window_fn = address(model.window)
        self.output_fn = model.output
        self.output_jacobian_fn = model.output_jacobian
        self.outputs = node.outputs
        self.feasible = (fs.lo, fs.hi, fs.ball_idx, fs.ball_r2)
        self.loss = (model.rinv, model.loss)
        #: the core's window solver and its C entry points, then the tail function's
        #: address (0: none): ``_core_solve`` and its siblings
        self.core = np.array([*ws.core.entries, ws.tail], dtype=np.uintp)
        self.sqp = (ws.Xb, ws.out, ws.D, ws.E, ws.g, ws.d, ws.lam_qp, ws.wgt, ws.extra, ws.gb,
                    ws.Dgn, ws.ncost, ws.stage, self.core, self.last)  # fmt: skip
        self.window = (self.tw, self.z, self.m, self.nodemask, self.u, self.dt, self.qw,
                       self.qinvw, self.arrival)  # fmt: skip
        self.reset()

    def reset(self) -> None:
        """Empty the window."""
        for a in (self.tw, self.z, self.m, self.u, self.qw, self.qinvw, self.arrival):
            a[:] = 0.0
        self.dt[:] = 1.0  # 1 s on inactive stages
        self.workspace.stage[0][:] = 0
        self.last[0] = -1
        self.k[0] = 0

    def _advance_args(
        self, prior: Prior, new: Sample, R: FloatArray, X: OptArray, lam: OptArray,
        options: StepOptions,
    ) -> tuple[object, ...]:  # fmt: skip
        node = self.node
        t, z, mask, u, dt, Q, Qinv = new  # the sample's values as the kernel's types
        f64 = np.float64
        if u is not self.u0:  # (the estimator's own zeros need no normalising)
            u = np.ascontiguousarray(u, dtype=f64).reshape(-1)
        new = (float(t), np.ascontiguousarray(z, dtype=f64), np.ascontiguousarray(mask, dtype=f64),
               u, float(dt), Q, Qinv)  # fmt: skip
        return (
            node._addr, node._ptrs, node._out, self.nin, self.window_fn, self.workspace.ptrs,
            (*prior, self.k), self.window, new, R, self.X0 if X is None else X, X is not None,
            self.lam if lam is None else lam, lam is not None, self.X0, self.feasible, options,
            self.sqp, self.loss,
        )  # fmt: skip

    def _failure(self, exc: RuntimeError) -> RuntimeError:
        """The kernel's error ``exc`` with the failed compiled function's own message."""
        if str(exc) == MODEL_FAILED:
            return RuntimeError(failure_message(self.node._fn))
        if str(exc) == OUTPUT_FAILED:
            return RuntimeError(failure_message(self.output_fn))
        if str(exc) == OUTPUT_JACOBIAN_FAILED:
            return RuntimeError(failure_message(self.output_jacobian_fn))
        return exc

    def advance(
        self, prior: Prior, new: Sample, R: FloatArray, X: OptArray, lam: OptArray,
        options: StepOptions,
    ) -> Outcome:  # fmt: skip
        """:func:`advance` on these buffers; ``prior = (xbar, P, Pinv)`` (updated in
        place), ``X`` and ``lam`` the previous solution and multipliers (None: none).
        A failed model evaluation raises ``RuntimeError`` with the model's message."""
        try:
            return advance(*self._advance_args(prior, new, R, X, lam, options))
        except RuntimeError as exc:
            raise self._failure(exc) from exc

    def advance_finish(
        self, prior: Prior, new: Sample, R: FloatArray, X: OptArray, lam: OptArray,
        options: StepOptions, answer: FloatArray, robust: bool = False, tol: float = 1e-6,
    ) -> tuple[Outcome, Finished | None]:  # fmt: skip
        """:meth:`advance`, then, if the window was certified, its answer into ``answer``
        (N, nx) and :meth:`finish`'s result for it, in one compiled call
        (:func:`advance_finish`); the second item is None when nothing was finished: the
        window was not certified, or (``robust``: the robust weights of the answer's first
        and last node, into :attr:`weights`) the window is full and its answer rejects
        the newest sample. Call :meth:`finish` once the answer is settled."""
        try:
            args = (
                *self._advance_args(prior, new, R, X, lam, options), tol, self.outputs, answer,
                self.cov, self.y, self.std, robust, self.weights,
            )  # fmt: skip
            res, failed = self._advance_finish(*args)
        except RuntimeError as exc:
            raise self._failure(exc) from exc
        if failed < 0:
            return res, None
        if failed:
            return res, (self.y.copy(), None, None)
        return res, (self.y.copy(), self.cov.copy(), self.std.copy())

    def finish(
        self, X: FloatArray, xbar: FloatArray, tol: float = 1e-6, answer: int = -1
    ) -> Finished:
        """``(outputs, covariance, output standard deviations)`` of ``X[-1]`` for the
        window solved at ``X`` (N, nx) with prior ``xbar`` (copies; None: the
        covariance is not positive definite). ``answer``: the buffer index that
        :meth:`advance` returned when ``X`` is its certified answer (the Hessian of its
        last evaluated iterate is then used, as :attr:`FastResult.hessian`), else -1."""
        try:
            failed = finish(
                self.window_fn, self.workspace.ptrs, np.ascontiguousarray(X, dtype=float),
                xbar, self.window, self.feasible, self.sqp, self.loss,
                1 - answer if answer >= 0 else -1, tol,
                self.cov, self.outputs, self.y, self.std,
            )  # fmt: skip
        except RuntimeError as exc:
            raise self._failure(exc) from exc
        if failed:
            return self.y.copy(), None, None
        return self.y.copy(), self.cov.copy(), self.std.copy()
