"""The window solve: Newton-type SQP with a projected line search, in the compiled core.

Each iteration evaluates the whole window's model in one call (residuals, Jacobians and
the measurement residuals' second-order term), assembles the block-tridiagonal Hessian
of the Lagrangian (Gauss-Newton ``J^T W J``, plus the exact second-order term where
that keeps it positive definite, plus ``2 lam_b I`` on the coordinates of each ball
``b`` with a positive multiplier), and solves the QP subproblem by a primal active-set
method. Iterates stay exactly feasible (projection). The core's
:class:`~continuum_mhe._core.WindowSolver` does all of it (``csrc/sqp.cpp``, ``csrc/qp.hpp``,
``csrc/btd.hpp``); :func:`solve_window` and :func:`window_cost` call it, and
:class:`Workspace` holds its buffers. See ``docs/fast-solver.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.fast.model import LossKernel, WindowModel
from continuum_mhe.estimators.fast.qp import CONVERGED, OUTCOMES
from continuum_mhe.estimators.loss import LOSS_CODES

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem as WindowProblemLike

from continuum_mhe.arrays import FloatArray


@dataclass(frozen=True)
class FastOptions:
    """Options of the fast backend.

    Attributes:
        max_iter: SQP (Gauss-Newton) iterations per window before falling back.
        step_tol: convergence certificate: max-norm of the QP step, each state in
            its own units (rad, m, a gyro bias's rad/s) but a rate, whose error counts
            as the angle it moves over 0.1 s (:func:`~.model.step_scale`); a tenth of
            it after a Gauss-Newton step, whose rate is linear (the core's
            ``kContractionSafety``).
        err_tol: convergence certificate: error bound of the answer estimated from
            the contraction of successive steps, in the same norm: the angles to
            ``err_tol`` rad, their rates to ``10 * err_tol`` rad/s (after a
            Gauss-Newton step the bound is taken ten times).
        max_qp_iter: active-set changes allowed per QP subproblem.
        newton: add the measurement residuals' second-order term to the Hessian
            (exact Newton; Gauss-Newton where that is not positive definite, or where
            the model does not form the term: :func:`newton_steps`).
    """

    max_iter: int = 30
    step_tol: float = 1e-8
    err_tol: float = 1e-8
    newton: bool = True
    max_qp_iter: int = 500

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise UserError(f"max_iter must be a positive integer, got {self.max_iter!r}")
        if not (isinstance(self.max_qp_iter, int) and self.max_qp_iter >= 1):
            raise UserError(f"max_qp_iter must be a positive integer, got {self.max_qp_iter!r}")
        if not (isinstance(self.step_tol, float) and 0 < self.step_tol < 1e-3):
            raise UserError(f"step_tol must lie in (0, 1e-3), got {self.step_tol!r}")
        if not (isinstance(self.err_tol, float) and 0 < self.err_tol < 1e-3):
            raise UserError(f"err_tol must lie in (0, 1e-3), got {self.err_tol!r}")


def newton_steps(model: WindowModel, options: FastOptions) -> bool:
    """Whether the SQP takes exact Newton steps: ``options.newton`` where the model
    forms the residuals' second-order term (else its steps are Gauss-Newton, certified
    with the core's safety factor on their linear rate)."""
    return options.newton and model.second_order_residuals


def quadratic_rate(model: WindowModel, options: FastOptions) -> bool:
    """Whether the SQP may certify by Newton's quadratic rate: exact Newton steps
    (``options.newton``), a transition affine in the state (else the Hessian the
    backend forms lacks the process model's second-order term), and not the Huber
    loss, whose second derivative jumps at its scale (with the estimate, Huber's worst
    certified window is 3.3e-7 from the converged answer in the certificate's norm,
    above its 1e-8: docs/fast-solver.md)."""
    huber = model.loss.code == LOSS_CODES["huber"]
    return newton_steps(model, options) and model.linear_transition and not huber


@dataclass(frozen=True)
class FastResult:
    """Outcome of :func:`solve_window`.

    Attributes:
        X: (N, nx) the answer; feasible exactly.
        converged: True if the KKT certificate holds at ``X``.
        outcome: one of :data:`OUTCOMES`.
        iterations: SQP iterations (QP solves).
        step: max-norm of the last QP step, in the certificate's norm
            (:attr:`FastOptions.step_tol`).
        cost: the window cost at the last evaluated iterate (the answer minus the last
            step when certified).
        lam: (N, nb) multipliers of the ball constraints at ``X``.
    """

    X: FloatArray
    converged: bool
    outcome: str
    iterations: int
    step: float
    cost: float
    lam: FloatArray


class Workspace:
    """Buffers of :func:`solve_window`, reusable across windows of one model: those of
    the compiled core's :class:`~continuum_mhe._core.WindowSolver` (NumPy views of its
    memory, so the model's argument pointers are fixed and the core solves in place).

    ``loss`` and ``linear`` replace the model's measurement loss and its
    :attr:`~.model.WindowModel.linear_transition` (whether the stage products are kept
    across iterations and windows).
    """

    def __init__(
        self, model: WindowModel, loss: LossKernel | None = None, linear: bool | None = None
    ) -> None:
        fs, lossk = model.feasible, loss or model.loss
        cols = model.block_columns  # the layout of the window function's SR
        self.core = core = _core.WindowSolver(
            model.horizon, model.nx, model.nz, model.nu, model.window, model.tail, fs.lo, fs.hi,
            np.ascontiguousarray(fs.ball_idx, dtype=np.int64), fs.ball_r2, model.rinv,
            np.ascontiguousarray(lossk.blocks, dtype=np.int64), lossk.code, lossk.scale,
            model.linear_transition if linear is None else linear,
            None if cols is None else np.ascontiguousarray(cols, dtype=np.int64),
            None if lossk.robust is None else np.ascontiguousarray(lossk.robust, dtype=np.int64),
        )  # fmt: skip
        # Gauss-Newton steps (no second-order term): a rejected full step is corrected
        # by one more step from its trial point before it is shortened (csrc/sqp.hpp)
        core.watchdog = not model.second_order_residuals
        if model.step_scale is not None:
            core.step_scale[:] = model.step_scale
        self.z, self.m, self.u, self.dt = core.z, core.m, core.u, core.dt
        self.Xb, self.out, self.D, self.E, self.g = core.Xb, core.out, core.D, core.E, core.g
        self.d, self.lam_qp, self.wgt, self.extra = core.d, core.lam_qp, core.wgt, core.extra
        self.gb = core.gb
        self.Dgn = core.Dgn  # Gauss-Newton diagonal blocks per iterate
        self.ncost = core.ncost  # each node's cost per iterate
        # which stage products are formed (``core.stage_eq`` and ``core.stage_fqf`` are
        # views of the rows now: ``shift_stages`` moves them)
        self.stage_done = core.stage_done
        # the tail function's outputs (``WindowSolver.shift_outputs``): buffer 0's last stage
        self.tail_out = core.tail_out

    def load(self, problem: WindowProblemLike, X: FloatArray) -> None:
        """Copy ``problem``'s data and the iterate ``X`` (N, nx) into buffer 0, and mark
        the stage products to be formed anew (for this problem's ``Q^-1``)."""
        self.z[:] = problem.z
        self.m[:] = problem.zmask
        self.u[:] = problem.u
        self.dt[:] = problem.dt
        self.Xb[0] = X
        self.stage_done[:] = 0


def _weights(problem: WindowProblemLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(qinv, xbar, arrival)`` of ``problem`` as the core takes them."""
    return (
        np.ascontiguousarray(problem.qinv, dtype=np.float64),
        np.ascontiguousarray(problem.xbar, dtype=np.float64),
        np.ascontiguousarray(problem.arrival, dtype=np.float64),
    )


def solve_window(
    model: WindowModel,
    problem: WindowProblemLike,
    X0: FloatArray,
    options: FastOptions | None = None,
    lam0: FloatArray | None = None,
    workspace: Workspace | None = None,
) -> FastResult:
    """Solve one window problem from the initial guess ``X0`` (N, nx).

    ``problem.zmask`` (N, nz) masks the measurement components of sensors that dropped
    out. ``lam0`` (N, nb) warm-starts the ball multipliers (the curvature term). The guess is
    projected onto the feasible set first. ``workspace`` (of this model) saves the
    allocations. See the module docstring for the method.
    """
    opt = options or FastOptions()
    n, nb = model.horizon, len(model.feasible.ball_r2)
    ws = workspace or Workspace(model)
    ws.load(problem, X0)
    lam = np.zeros((n, nb)) if lam0 is None else np.array(lam0, dtype=float).reshape(n, nb)
    r = ws.core.solve(
        *_weights(problem), lam, opt.max_iter, opt.step_tol, opt.err_tol, opt.max_qp_iter,
        newton_steps(model, opt), quadratic_rate(model, opt),
    )  # fmt: skip
    return FastResult(
        X=ws.Xb[r.buffer].copy(),
        converged=r.outcome == CONVERGED,
        outcome=OUTCOMES[r.outcome],
        iterations=int(r.iterations),
        step=float(r.step),
        cost=float(r.cost),
        lam=lam,
    )


def window_cost(model: WindowModel, problem: WindowProblemLike, X: FloatArray) -> float:
    """The window cost at ``X`` (N, nx), from the compiled model."""
    ws = Workspace(model)
    ws.load(problem, np.asarray(X, dtype=np.float64))
    return float(ws.core.evaluate(0, *_weights(problem)))
