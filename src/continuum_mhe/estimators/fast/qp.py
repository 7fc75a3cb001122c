"""The QP subproblem of the SQP: its outcomes, and the equality-constrained step.

``min 1/2 d^T H d + g^T d`` over the window's step ``d`` (n, nx), ``H`` block-tridiagonal,
subject to the box ``lo <= X + d <= hi`` and each ball ``sum_{S_b} x_j^2 <= r_b^2``
linearised at ``X``, is solved by a primal active-set method in the compiled core
(``csrc/qp.hpp``; :func:`continuum_mhe._core.solve_qp`). Box-fixed coordinates are removed;
every active ball of a node is eliminated by a Householder reflection on its own
coordinates (the balls are disjoint, so a node's reflections commute and their product
is one symmetric orthogonal ``T``), so each equality-constrained step is one
block-tridiagonal Cholesky solve.
"""

from __future__ import annotations

#: Solver outcomes of the QP and of :func:`~continuum_mhe.estimators.fast.sqp.solve_window`.
CONVERGED, MAX_ITER, LINE_SEARCH_FAILED, QP_FAILED, NOT_PD = 0, 1, 2, 3, 4
OUTCOMES = ("converged", "max-iter", "line-search-failed", "qp-failed", "not-positive-definite")
