"""A second start for the robust MHE when its newest sample is rejected.

A nonconvex loss (Cauchy) gives the window problem one local minimum per way of
explaining its samples. The warm start (the previous solution shifted, its last node
predicted) follows the explanation the previous window chose. After a burst of
consistent bad samples the previous windows had accepted the burst (nothing later
contradicted it), so the warm start follows it, and the good samples that come after
the burst are then rejected as outliers against it: the estimator stays on the burst
until the good samples outnumber it. Profiled on ``paper3d`` (tools/burst_study.py):
solved from a trajectory that never saw the burst, the same window problems reached a
lower cost and the clean error in 5 to 10 samples after each burst.

:class:`SecondStart` keeps the last solutions. When the warm-started answer rejects
the newest sample (its weight ``rho'(s) < OUTLIER_WEIGHT``), the same window problem is
solved once more from the solution of ``LAG`` samples ago (at most ``N - 1``), shifted
by ``LAG`` nodes and its newest nodes predicted by the model; the answer with the lower
window cost (the NLP objective, lower by more than ``REL_MARGIN``) is kept. Both
answers are KKT points of the same problem, so both backends choose alike. On data
where no newest sample is rejected nothing changes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Status
from continuum_mhe.estimators.loss import OUTLIER_WEIGHT

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem

#: Age of the solution the second start comes from, samples (longer than the bursts
#: it must undo: the warm start follows a burst for its length plus the samples after
#: it until they outnumber it).
LAG = 12
#: The second answer replaces the first when its window cost is lower by more than
#: this fraction (equal minima from two starts differ by rounding only).
REL_MARGIN = 1e-6

#: ``predict(x, u, dt) -> next state``.
PredictFn = Callable[[FloatArray, FloatArray, float], FloatArray]
#: ``weights(x) -> rho'(s_b)`` per block of the newest node at state ``x``.
WeightsFn = Callable[[FloatArray], FloatArray]
#: ``solve(problem, X0) -> (X, status)``: one solve of the window from a start.
SolveFn = Callable[["WindowProblem", FloatArray], tuple[FloatArray, Status]]
#: ``cost(problem, X) -> window cost`` (the NLP objective).
CostFn = Callable[["WindowProblem", FloatArray], float]
#: Statuses of a usable answer.
USABLE = (Status.OK, Status.FALLBACK_IPOPT)


class PastAnswers(Protocol):
    """Where the answers of the last ``lag`` full windows are kept: the compiled step
    (``_core.MovingHorizon``, which keeps the answers that need no second start itself)
    or :class:`KeptAnswers`."""

    @property
    def past_count(self) -> int: ...

    def remember(self, X: FloatArray) -> None: ...

    def forget_past(self) -> None: ...

    def past_oldest(self) -> FloatArray: ...


class KeptAnswers:
    """The last ``lag`` answers (N, nx) in a deque: :class:`PastAnswers` in Python."""

    def __init__(self, lag: int) -> None:
        self._past: deque[FloatArray] = deque(maxlen=lag)

    @property
    def past_count(self) -> int:
        return len(self._past)

    def remember(self, X: FloatArray) -> None:
        self._past.append(np.array(X, dtype=np.float64))

    def forget_past(self) -> None:
        self._past.clear()

    def past_oldest(self) -> FloatArray:
        return self._past[0]


class SecondStart:
    """Past window solutions and the second starting trajectory built from them.

    ``past``: where the solutions are kept (a :class:`KeptAnswers` of :attr:`lag` when
    None); a compiled window keeps them itself and must have ``past_lag`` equal to
    :attr:`lag`.
    """

    def __init__(self, horizon: int, lag: int = LAG, past: PastAnswers | None = None) -> None:
        #: the age of the solution a second start comes from (at most ``horizon - 1``)
        self.lag = max(1, min(lag, horizon - 1))
        self._past = KeptAnswers(self.lag) if past is None else past
        #: second starts tried and those whose answer was kept, since the estimator's
        #: last ``reset()``
        self.tried = 0
        self.kept = 0

    def clear(self) -> None:
        """Forget the past solutions (a reset of the estimator)."""
        self._past.forget_past()

    def remember(self, X: FloatArray) -> None:
        """Store the answer of this sample's window (N, nx)."""
        self._past.remember(X)

    def start(self, u: FloatArray, dt: FloatArray, predict: PredictFn) -> FloatArray | None:
        """The second start for the current window (N, nx), before this sample's answer
        is remembered; None until ``lag`` solutions exist.

        ``u`` (N-1, nu) and ``dt`` (N-1,) are the current window's stage inputs and
        time steps (s): node ``i`` of the old solution is node ``i - lag`` now.
        """
        if self._past.past_count < self.lag:
            return None
        old = self._past.past_oldest()  # the answer of `lag` samples ago
        keep = len(old) - self.lag
        X = np.empty_like(old)
        X[:keep] = old[self.lag :]
        for i in range(keep, len(old)):
            X[i] = predict(X[i - 1], u[i - 1], float(dt[i - 1]))
        return X

    def check(
        self,
        problem: WindowProblem,
        X: FloatArray,
        status: Status,
        weights: WeightsFn,
        solve: SolveFn,
        cost: CostFn,
        predict: PredictFn,
    ) -> tuple[FloatArray, Status, FloatArray | None]:
        """The answer to keep for this full window: ``(X, status, newest weights)``.

        ``X`` is returned itself (same object) unless the second start won; the
        newest node's weights are returned when computed for the answer returned
        (None otherwise). The kept answer is remembered for later second starts.
        """
        w = weights(X[-1]) if status in USABLE else None
        start = None
        if w is not None and float(np.min(w)) < OUTLIER_WEIGHT:
            start = self.start(problem.u, problem.dt, predict)
        if start is not None:
            self.tried += 1
            X2, status2 = solve(problem, start)
            c1 = cost(problem, X)
            if status2 in USABLE and cost(problem, X2) < c1 - REL_MARGIN * abs(c1):
                self.kept += 1
                X, status, w = X2, status2, None
        self.remember(X)
        return X, status, w
