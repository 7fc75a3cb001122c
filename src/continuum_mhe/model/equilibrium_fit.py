"""A least-squares fit of a state to one reading, with the model's equilibrium rows met
exactly: the start of a tendon robot (:meth:`TendonFormulation._start_fit
<continuum_mhe.model.tendon.TendonFormulation>`).

The tendon model carries its tip condition as residual rows of a tiny standard
deviation (``equilibrium_std``). Fitted as rows like the others, their weight makes
the problem stiff: a step that improves the readings breaks the tip condition to
second order, and Levenberg-Marquardt creeps, hundreds of evaluations a start. Here
the variables that the tip condition settles (the base curvature, and with raw IMUs
its rate) are solved from those rows by Newton's method at every trial point, and the
least-squares problem runs over the rest (variable projection): its Jacobian is the
readings' total derivative along the equilibrium, ``J_o - J_s E_s^-1 E_o``, where ``J``
and ``E`` are the fitted rows' and the equilibrium rows' derivatives with respect to
the settled states (``s``) and the others (``o``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray

#: Newton iterations of the equilibrium at one trial point, at most.
SETTLE_ITERATIONS = 30
#: Newton iterations in a row that do not halve the equilibrium rows' largest value
#: from its best at that point, after which the point is taken as not settling.
SETTLE_STALLS = 4
#: The equilibrium rows' largest value (their own unit: rad/m for the tip condition,
#: rad/(m s) for its rate) at which Newton's method stops.
SETTLE_TOLERANCE = 1e-10


@dataclass(frozen=True)
class EquilibriumFit:
    """What to fit and how (indices are into the state and the residual).

    Attributes:
        free: the fitted states.
        settled: those of ``free`` that the equilibrium rows determine (as many as
            ``equilibrium_rows``), solved from them by Newton's method.
        equilibrium_rows: the residual rows met exactly.
        rows: the residual rows fitted in least squares, with their ``weights``.
        weights: one per residual row (all ``nz``), the inverse standard deviations.
        prior, prior_weights: each free state's prior value and inverse standard
            deviation (a row ``prior_weight * (x - prior)`` each).
        scale: each free state's characteristic size (``x_scale`` of the fit).
    """

    free: NDArray[np.int64]
    settled: NDArray[np.int64]
    equilibrium_rows: NDArray[np.int64]
    rows: NDArray[np.int64]
    weights: FloatArray
    prior: FloatArray
    prior_weights: FloatArray
    scale: FloatArray

    def __post_init__(self) -> None:
        free = {int(j) for j in self.free}
        if not {int(j) for j in self.settled} <= free:
            raise ValueError("EquilibriumFit: every settled state must be free")
        if len(self.settled) != len(self.equilibrium_rows):
            raise ValueError(
                "EquilibriumFit: as many settled states as equilibrium rows are needed "
                f"({len(self.settled)} and {len(self.equilibrium_rows)})"
            )
        for name in ("prior", "prior_weights", "scale"):
            if len(getattr(self, name)) != len(self.free):
                raise ValueError(f"EquilibriumFit: {name} needs one value per free state")


@dataclass(frozen=True)
class FitResult:
    """What :func:`fit_on_equilibrium` found.

    Attributes:
        x: the state (the fitted point, or the best settled point where the fit ended
            early, or ``x0`` where none settled).
        residual: the model's residual at ``x`` (``evaluate``'s ``r``); None where no
            point settled.
        settled: whether ``x`` meets the equilibrium rows (to :data:`SETTLE_TOLERANCE`).
        converged: whether the least-squares fit converged within the budget.
        evaluations: the calls of ``evaluate``.
    """

    x: FloatArray
    residual: FloatArray | None
    settled: bool
    converged: bool
    evaluations: int


#: ``evaluate(x) -> (r, J)``: the residual (nz,) at the state ``x`` and its Jacobian
#: ``dr/dx`` (nz, nx); raises ``ArithmeticError`` where the model fails.
Evaluate = Callable[[FloatArray], tuple[FloatArray, FloatArray]]


def fit_on_equilibrium(
    evaluate: Evaluate, x0: FloatArray, spec: EquilibriumFit, max_evaluations: int
) -> FitResult:
    """``x0`` with its free states fitted (variable projection, as the module says), the
    settled ones meeting the equilibrium rows, in at most ``max_evaluations`` calls of
    ``evaluate`` (each Newton step of the equilibrium is one). Where the budget runs out
    the result is the settled point of lowest cost met so far (``converged`` False);
    where not even ``x0``'s free states settle, ``x0`` itself (``settled`` False)."""
    from scipy.optimize import least_squares  # imported on use (slow to import)

    free = np.asarray(spec.free)
    settled = np.asarray(spec.settled)
    other = np.array([j for j in free if j not in set(settled.tolist())], dtype=np.int64)
    in_free = {int(j): i for i, j in enumerate(free)}
    pos_s = np.array([in_free[int(j)] for j in settled], dtype=np.int64)
    pos_o = np.array([in_free[int(j)] for j in other], dtype=np.int64)
    x = np.array(x0, dtype=float)
    eq, rows = np.asarray(spec.equilibrium_rows), np.asarray(spec.rows)
    w_rows = spec.weights[rows]
    kept: dict[bytes, tuple[FloatArray, FloatArray, FloatArray]] = {}
    best: list[tuple[float, FloatArray, FloatArray]] = []  # (cost, x, r) of the best point
    count = [0]

    def settle(v_o: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """``(x, r, J)`` at the free states ``v_o`` with the settled ones solved (from
        the last settled point), or None where Newton's method does not converge."""
        key = v_o.tobytes()
        if key in kept:
            return kept[key]
        trial = x.copy()
        trial[other] = v_o
        lowest, stalls = math.inf, 0
        for _ in range(SETTLE_ITERATIONS):
            if count[0] >= max_evaluations:
                return None
            count[0] += 1
            try:
                r, J = evaluate(trial)
            except ArithmeticError:
                return None
            c = r[eq]
            if not np.all(np.isfinite(c)) or not np.all(np.isfinite(J[eq][:, settled])):
                return None
            size = float(np.max(np.abs(c)))
            if size <= SETTLE_TOLERANCE:
                x[:] = trial  # the next trial's settled states start here
                kept.clear()
                kept[key] = (trial, r, J)
                return kept[key]
            stalls = 0 if size < 0.5 * lowest else stalls + 1
            lowest = min(lowest, size)
            if stalls >= SETTLE_STALLS:
                return None
            try:
                trial[settled] -= np.linalg.solve(J[np.ix_(eq, settled)], c)
            except np.linalg.LinAlgError:
                return None
        return None

    def reduced(v_o: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The weighted residual over the fitted rows and the priors, and its Jacobian
        along the equilibrium; a large residual where the point does not settle."""
        got = settle(v_o)
        n_res = len(rows) + len(free)
        if got is None:
            return np.full(n_res, 1e10), np.zeros((n_res, len(other)))
        trial, r, J = got
        E_s, E_o = J[np.ix_(eq, settled)], J[np.ix_(eq, other)]
        ds = -np.linalg.solve(E_s, E_o)  # d settled / d other
        J_rows = J[np.ix_(rows, other)] + J[np.ix_(rows, settled)] @ ds
        dfree = np.zeros((len(free), len(other)))
        dfree[pos_o, np.arange(len(other))] = 1.0
        dfree[pos_s] = ds
        res = np.r_[w_rows * r[rows], spec.prior_weights * (trial[free] - spec.prior)]
        jac = np.vstack([w_rows[:, None] * J_rows, spec.prior_weights[:, None] * dfree])
        cost = float(res @ res)
        if not best or cost < best[0][0]:
            best[:] = [(cost, trial.copy(), r.copy())]
        return res, jac

    if settle(x[other]) is None:
        return FitResult(np.array(x0, dtype=float), None, False, False, count[0])
    fit = least_squares(
        lambda v: reduced(v)[0],
        x[other],
        jac=lambda v: reduced(v)[1],
        method="lm",
        x_scale=spec.scale[pos_o],
        max_nfev=max_evaluations,
    )
    spent = count[0] >= max_evaluations
    got = settle(fit.x) if np.all(np.isfinite(fit.x)) else None
    if got is None or spent:  # the best point the fit settled
        _, xb, rb = best[0]
        return FitResult(xb, rb, True, False, count[0])
    return FitResult(got[0], got[1], True, bool(fit.status > 0), count[0])
