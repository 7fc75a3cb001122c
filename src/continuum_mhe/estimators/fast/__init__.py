"""Structure-exploiting MHE backend: Newton-type SQP with a block-tridiagonal solver.

It solves exactly the window problem of :mod:`continuum_mhe.estimators.mhe` (same
:class:`~continuum_mhe.estimators.mhe.WindowProblem`, same cost, same hard
constraints) and reaches the same KKT point as the IPOPT backend.

Algorithm (see ``docs/fast-solver.md``):

* **Model.** Residuals and Jacobians of the whole window come from one call into the
  compiled core, which evaluates the CasADi functions built from the formulation's
  symbolic methods (``measurement_residual_sym``, ``transition_sym``) node by node from
  their instruction lists (:mod:`~continuum_mhe.model.tape`). The model is
  never written a second time by hand, and a new robot compiles nothing.
* **Step.** The Hessian of the window cost is block-tridiagonal (blocks
  ``nx x nx``): Gauss-Newton ``J^T W J`` plus the measurement residuals' exact
  second-order term (Newton; dropped for an iterate where it is not positive
  definite); each QP subproblem is solved by a primal active-set method
  whose equality-constrained steps use a block-tridiagonal Cholesky factorisation,
  ``O(N nx^3)`` per factorisation. Box bounds fix coordinates; each ball constraint
  ``sum_{S_b} x_j^2 <= r_b^2`` (one per robot section, on disjoint coordinates,
  recognised from the CasADi expression) is linearised and eliminated by a Householder
  reflection on its coordinates; a node's reflections commute, and their product keeps
  the Hessian's block structure. Each ball's curvature ``2 lam_b I`` enters the
  Hessian of the Lagrangian through its multiplier estimate.
* **Globalisation.** Projected line search on the exact cost (iterates always
  satisfy the bounds exactly: clipping for boxes, radial scaling for each ball).
* **Certificate.** The QP at an iterate has the NLP's KKT conditions as its own at
  ``d = 0`` (nonnegative multipliers by construction). Converged when the QP step
  is below ``step_tol`` in the max norm (a rate's entry weighted by 0.1 s, the angle
  its error moves in that time: :func:`~.model.step_scale`), or, with no constraint
  active, when the
  contraction of two successive full steps bounds the answer's error by
  ``err_tol``. Otherwise (iteration limit, failed line search, QP failure) the
  caller falls back to IPOPT.

Modules (one responsibility each):

* :mod:`~continuum_mhe.estimators.fast.window_functions`: CasADi functions of the window, node and
  outputs, evaluated by the compiled core.
* :mod:`~continuum_mhe.estimators.fast.model`: the feasible set read from the
  formulation, :class:`WindowModel`, :class:`NodeEvaluator`, :func:`build_window_model`.
* :mod:`~continuum_mhe.estimators.fast.sqp`: :func:`solve_window` and its
  :class:`Workspace`, over the compiled core's window solver (assembly, active-set QP
  with block-tridiagonal Cholesky, SQP; ``csrc/sqp.cpp``, ``csrc/qp.hpp``,
  ``csrc/btd.hpp``).
* :mod:`~continuum_mhe.estimators.fast.qp`: the solver outcomes.
* :mod:`~continuum_mhe.estimators.fast.covariance`: the covariance of the estimate (the
  core's ``last_block_covariance``).
* :mod:`~continuum_mhe.model.tape`: CasADi functions as instruction lists for
  the core.

The arrival prior's EKF step, the compiled EKF's step and the outputs with their
standard deviations are the core's :class:`~continuum_mhe._core.NodeModel`
(``csrc/filter.cpp``), used through :class:`NodeEvaluator`.
"""

from __future__ import annotations

from continuum_mhe.estimators.fast.model import (
    Feasible,
    LossKernel,
    NodeEvaluator,
    NodeFunctions,
    WindowModel,
    build_window_model,
    feasible_set,
    node_functions,
)
from continuum_mhe.estimators.fast.qp import (
    CONVERGED,
    LINE_SEARCH_FAILED,
    MAX_ITER,
    NOT_PD,
    OUTCOMES,
    QP_FAILED,
)
from continuum_mhe.estimators.fast.sqp import (
    FastOptions,
    FastResult,
    Workspace,
    solve_window,
    window_cost,
)
from continuum_mhe.estimators.fast.window_functions import BackendFallbackWarning

__all__ = [
    "BackendFallbackWarning",
    "CONVERGED",
    "Feasible",
    "FastOptions",
    "FastResult",
    "LINE_SEARCH_FAILED",
    "LossKernel",
    "MAX_ITER",
    "NOT_PD",
    "NodeEvaluator",
    "NodeFunctions",
    "OUTCOMES",
    "QP_FAILED",
    "WindowModel",
    "Workspace",
    "build_window_model",
    "node_functions",
    "feasible_set",
    "solve_window",
    "window_cost",
]
