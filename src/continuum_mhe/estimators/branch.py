"""Branch check of the MHE window: detect an implausible fit, restart, keep the best.

With tilt only, a multi-section robot's window problem has several local minima (the
branches of the tilt inverse: a section bent one way or far the other way, often at
its bound). A warm-started solver stays in the basin it was in, so once the MHE is on
the wrong branch it can stay there for seconds. The check:

1. **Detect.** After the window is solved, its normalised measurement cost
   ``c = sum_i r_i^T R^-1 r_i`` (valid readings only) is compared with the
   ``QUANTILE`` quantile of a chi-square with ``dof`` = the number of valid readings in
   the window: the rows the consistency check judges (:meth:`Formulation.judged_rows`;
   every row of a PCC robot; not a tendon robot's tension rates, inputs whose residual
   is zero, nor its tip condition, a pseudo-measurement whose tiny standard deviation
   its residual exceeds off the equilibrium). Below it, nothing else happens (the check
   costs one residual evaluation of the window).
2. **Restart.** Above it, the SAME window problem is solved again from other starting
   trajectories (:meth:`BranchCheck.candidates`): a re-initialisation from the
   window's measurements (each sample's state from the formulation's tilt inverse,
   :meth:`Formulation.initial_state`, which sets each section's bend from the tilt of
   its IMU relative to the frame below; rates by finite differences), the same with
   each sample's state taken nearest to its neighbour (one continuous branch), the
   arrival prior propagated through the window, and an EKF run over the window from
   the arrival prior.
3. **Keep the best.** Of the converged answers, the one with the lowest window cost
   (the full NLP objective) replaces the warm-started answer when it is lower by more
   than ``REL_MARGIN`` of it; the sample's status is then ``branch-restart``. Every
   answer is a KKT point of the same problem, so both backends keep agreeing wherever
   no restart happens.
4. **Forget the prior** (stage 2, only for a full window). When no restart of the same
   problem wins, the arrival prior itself may hold the wrong branch (it is an EKF
   lagging the window, and every start then falls into the basin it pulls towards).
   The window is solved once more with the arrival weight divided by ``FORGET``, from
   the warm answer and every candidate; its lowest-cost answer is kept when its
   measurement cost is below ``FIT_GAIN`` times the warm answer's (status
   ``branch-restart``), and the estimator re-anchors its arrival prior on that answer's
   first node with the covariance times ``FORGET``. This answer is a KKT point of the
   relaxed problem, not of the original one.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.base import Status
from continuum_mhe.estimators.fast.model import NodeEvaluator, node_functions
from continuum_mhe.estimators.kalman import joseph_update
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.quantiles import chi2_quantile

if TYPE_CHECKING:
    from continuum_mhe.estimators.window_nlp import WindowProblem

#: Chi-square quantile above which a window's measurement cost is implausible.
QUANTILE = 0.999
#: A restarted answer replaces the warm-started one when its window cost is lower by
#: more than this fraction (equal minima reached from two starts differ by ~1e-12).
REL_MARGIN = 1e-6

#: Stage 2: the arrival weight on the window's first node is divided by this (the
#: prior's covariance multiplied) when no restart of the same problem helps.
FORGET = 100.0
#: Stage 2 is kept when its measurement cost is below this fraction of the warm answer's.
FIT_GAIN = 0.5

#: Formulations whose MHE checks its branch when ``MHESettings.branch_check`` is None,
#: for a robot of more than one section: tilt only (such a window has far branches).
#: With gyros (``direct``) the rates hold the branch and the check measured worse; one
#: section has no far branch within its bound.
CHECKED_BY_DEFAULT = ("bend",)


def checks_branch(formulation: Formulation, setting: bool | None, robust: bool = False) -> bool:
    """Whether the MHE runs the branch check: ``setting``, or by default (None) for a
    robot of several sections in one of the formulations of :data:`CHECKED_BY_DEFAULT`,
    with the quadratic loss (``robust`` False): a robust loss rejects a faulty IMU's
    readings, and a restart from the readings' own shapes would follow that IMU."""
    if setting is not None:
        return setting
    return formulation.name in CHECKED_BY_DEFAULT and not formulation.robot.is_single and not robust


#: ``solve(problem, X0) -> (X, status, backend state)``: one solve from a start.
SolveFn = Callable[["WindowProblem", FloatArray], tuple[FloatArray, Status, object]]
#: ``cost(problem, X) -> window cost`` (the NLP objective).
CostFn = Callable[["WindowProblem", FloatArray], float]


@dataclass
class BranchStats:
    """Counts since the estimator's last ``reset()``: windows checked, of which those
    whose measurement cost had to be evaluated (``evaluated``; the others passed on the
    solver's window cost alone), found implausible (``fired``), restarts that changed the
    answer (``restarted``), of which with the arrival prior forgotten
    (``prior_forgotten``), and the winning starts of stage 1 (``sources``)."""

    checked: int = 0
    evaluated: int = 0
    fired: int = 0
    restarted: int = 0
    prior_forgotten: int = 0
    sources: dict[str, int] = field(default_factory=dict)


class BranchCheck:
    """The branch check for one formulation and horizon (see the module docstring)."""

    def __init__(
        self,
        formulation: Formulation,
        horizon: int,
        forget_prior: bool = True,
        quadratic: bool = True,
    ) -> None:
        """``quadratic``: the window's measurement cost is the l2 one (no robust loss), so
        :meth:`measurement_cost` can take it from the backend's window cost with the
        arrival and process weights zeroed."""
        self.formulation = formulation
        self.forget_prior = forget_prior
        self.quadratic = quadratic
        self.horizon = horizon
        self._innovate = formulation.functions.innovate.map(horizon)
        self._rinv = np.linalg.inv(formulation.meas_cov())
        #: the rows a chi-square test judges (:meth:`Formulation.judged_rows`)
        self._judged = formulation.judged_rows()
        # the mask's factor for the measurement cost where some row is not judged: the
        # pseudo-measurements left out, the rows the model reads as inputs kept (their
        # residual is zero, and a masked row's value is no input)
        pseudo = ~self._judged & ~formulation.input_rows()
        self._counted = (~pseudo).astype(float) if pseudo.any() else None
        self.stats = BranchStats()
        self._inverse: dict[bytes, FloatArray] = {}  # tilt inverse per sample, by its z
        self._node: NodeEvaluator | None = None  # the model's node in the compiled core
        self._process_noise = ProcessNoiseCache(formulation)  # (Q(dt), Q(dt)^-1)
        self._zero_weights: tuple[FloatArray, FloatArray] | None = None
        #: the first test of :meth:`check` (a quadratic loss; None otherwise): a certified
        #: window whose twice window cost is at most entry ``dof`` (its valid readings,
        #: :meth:`dof`, 0 to ``horizon * nz``) is plausible without an evaluation; the
        #: compiled MHE step applies it itself (``_core.MovingHorizon.plausible_limit``)
        dofs = range(1, horizon * formulation.nz + 1)
        self.plausible_limits: FloatArray | None = (
            np.array([np.inf] + [chi2_quantile(QUANTILE, d) for d in dofs]) if quadratic else None
        )

    # --- detect -----------------------------------------------------------------
    def dof(self, zmask: FloatArray) -> int:
        """The valid readings of a window's mask ``zmask`` (N, nz): its judged rows'."""
        return int(zmask[:, self._judged].sum())

    def measurement_cost(
        self, problem: WindowProblem, X: FloatArray, cost: CostFn | None = None
    ) -> tuple[float, int]:
        """``(sum r^T R^-1 r, dof)`` over the valid readings of the window (rad^2/rad^2;
        :meth:`dof`).

        With ``cost`` (the backend's window cost, ``1/2`` of the weighted squares) and a
        quadratic loss, twice that cost with the arrival and process weights zeroed;
        otherwise from the formulation's residuals."""
        z, zmask = problem.z, problem.zmask
        dof = self.dof(zmask)
        if cost is not None and self.quadratic:
            return 2.0 * cost(self._measurements_only(problem), X), dof
        if self._counted is not None:
            zmask = zmask * self._counted
        r = np.asarray(self._innovate(z.T, X.T)[0], dtype=float).T * zmask  # (N, nz)
        return float(np.einsum("ij,jk,ik->", r, self._rinv, r)), dof

    def _measurements_only(self, problem: WindowProblem) -> WindowProblem:
        """``problem`` with no arrival and no process weight, and its pseudo-measurements
        masked (its cost: the readings')."""
        zeros = self._zero_weights
        if zeros is None or zeros[0].shape != problem.arrival.shape:
            zeros = self._zero_weights = (
                np.zeros_like(problem.arrival),
                np.zeros_like(problem.qinv),
            )
        if self._counted is None:
            return replace(problem, arrival=zeros[0], qinv=zeros[1])
        zmask = problem.zmask * self._counted
        return replace(problem, zmask=zmask, arrival=zeros[0], qinv=zeros[1])

    def implausible(
        self, problem: WindowProblem, X: FloatArray, cost: CostFn | None = None
    ) -> bool:
        """True when the window's measurement cost exceeds the chi-square quantile."""
        c, dof = self.measurement_cost(problem, X, cost)
        return dof > 0 and c > chi2_quantile(QUANTILE, dof)

    # --- restart ------------------------------------------------------------------
    def candidates(self, problem: WindowProblem) -> dict[str, FloatArray]:
        """Starting trajectories ``(N, nx)`` for the window, by name."""
        p = problem
        z, zmask, dt = p.z, p.zmask, p.dt
        active = np.flatnonzero(zmask.any(axis=1))
        out: dict[str, FloatArray] = {}
        if len(active):
            out["measurements"] = self._from_measurements(z, zmask, dt, active)
        out["prior"] = self._propagate_prior(p)
        out["ekf"] = self._ekf_window(p)
        return out

    def _from_measurements(
        self, z: FloatArray, zmask: FloatArray, dt: FloatArray, active: np.ndarray
    ) -> FloatArray:
        """Each valid sample's state from its tilt inverse; samples without a
        measurement hold their neighbour; rates by finite differences."""
        f, n = self.formulation, self.horizon
        X = np.zeros((n, f.nx))
        prev: FloatArray | None = None
        for i in range(n):
            if i in active:
                prev = self._tilt_inverse(np.where(zmask[i] > 0, z[i], np.nan))
            X[i] = X[max(i - 1, 0)] if prev is None or i not in active else prev
        first = int(active[0])
        X[:first] = X[first]
        _fill_rates(f, X, dt)
        return np.array([f.project(x) for x in X])

    def _tilt_inverse(self, z: FloatArray) -> FloatArray:
        """``initial_state(z)``, remembered for the samples of the last few windows (a
        sample stays in the window for ``horizon`` solves)."""
        key = z.tobytes()
        x = self._inverse.get(key)
        if x is None:
            if len(self._inverse) >= 4 * self.horizon:
                del self._inverse[next(iter(self._inverse))]
            x = self._inverse[key] = self.formulation.initial_state(z)
        return x

    def _node_model(self) -> NodeEvaluator:
        """The formulation's node (transition, residual and their Jacobians) evaluated in
        the compiled core, built when a check first fires."""
        if self._node is None:
            self._node = NodeEvaluator(node_functions(self.formulation))
        return self._node

    def _propagate_prior(self, p: WindowProblem) -> FloatArray:
        f, n, node = self.formulation, self.horizon, self._node_model()
        X = np.empty((n, f.nx))
        X[0] = p.xbar
        for i in range(n - 1):
            X[i + 1] = f.project(node.evaluate(X[i], p.u[i], float(p.dt[i]))[0])
        return X

    def _ekf_window(self, p: WindowProblem) -> FloatArray:
        """The EKF (update, then prediction from the projected state) over the window from
        the arrival prior's node, each node's model evaluated in the compiled core."""
        f, n, node = self.formulation, self.horizon, self._node_model()
        arrival, zmask = p.arrival, p.zmask
        off = int(np.flatnonzero(np.abs(arrival).sum(axis=(1, 2)) > 0)[-1])  # prior node
        x = np.array(p.xbar, dtype=float)
        P = np.linalg.inv(arrival[off])
        R = f.meas_cov()
        ones, still = np.ones(f.nz), np.zeros(f.nu)
        X = np.tile(x, (n, 1))
        for i in range(off, n):
            if zmask[i].any():
                # (the transition's terms of this evaluation are not used: any step)
                z = np.where(np.isfinite(p.z[i]), p.z[i], 0.0)
                _, _, H, r = node.evaluate(x, still, 1.0, z, ones)
                x, P = joseph_update(x, P, r, H, R, zmask[i])
            X[i] = f.project(x)
            if i < n - 1:
                dt = float(p.dt[i])
                x, F, _, _ = node.evaluate(X[i], p.u[i], dt)
                P = F @ P @ F.T + self._process_noise(dt)[0]
        return X

    # --- keep the best ----------------------------------------------------------------
    def check(
        self,
        problem: WindowProblem,
        X: FloatArray,
        status: Status,
        solve: SolveFn,
        cost: CostFn,
        window_cost: float | None = None,
    ) -> tuple[FloatArray, Status, object | None, bool]:
        """The answer to keep: ``(X, status, backend state, forget_prior)``.

        ``X`` is the warm-started answer; ``None`` as the backend state means it stays.
        ``window_cost``: its window cost if the solver knows it (the fast SQP's, at its
        last iterate). With a quadratic loss the measurement cost is at most twice the
        window cost, so a window cost below half the quantile needs no evaluation.
        ``forget_prior`` is True when the answer comes from the window with the arrival
        weight divided by ``FORGET`` (stage 2): the caller then re-anchors its arrival
        prior on the answer's first node with its covariance times ``FORGET``.
        """
        self.stats.checked += 1
        if status not in (Status.OK, Status.FALLBACK_IPOPT):
            return X, status, None, False
        limits = self.plausible_limits
        if limits is not None and window_cost is not None:
            if 2.0 * window_cost <= limits[self.dof(problem.zmask)]:
                return X, status, None, False
        self.stats.evaluated += 1
        if not self.implausible(problem, X, cost):
            return X, status, None, False
        self.stats.fired += 1
        starts = self.candidates(problem)
        won = self._best_restart(problem, X, solve, cost, starts)
        if won is not None:
            self.stats.restarted += 1
            self.stats.sources[won[3]] = self.stats.sources.get(won[3], 0) + 1
            return won[0], Status.BRANCH_RESTART, won[2], False
        if not self.forget_prior:
            return X, status, None, False
        return self._forget_prior(problem, X, status, solve, cost, starts)

    def _best_restart(
        self,
        problem: WindowProblem,
        X: FloatArray,
        solve: SolveFn,
        cost: CostFn,
        starts: dict[str, FloatArray],
    ) -> tuple[FloatArray, Status, object, str] | None:
        """Stage 1: the restart of the same problem from each of ``starts``
        (:meth:`candidates`) with the lowest cost, if lower than ``X``'s by more than
        ``REL_MARGIN``."""
        best_cost = cost(problem, X)
        bar = best_cost - REL_MARGIN * max(abs(best_cost), 1.0)
        best: tuple[FloatArray, Status, object, str] | None = None
        for name, X0 in starts.items():
            Xc, st, state = solve(problem, X0)
            if st not in (Status.OK, Status.FALLBACK_IPOPT):
                continue
            c = cost(problem, Xc)
            if c < bar and (best is None or c < best_cost):
                best, best_cost = (Xc, st, state, name), c
        return best

    def _forget_prior(
        self,
        problem: WindowProblem,
        X: FloatArray,
        status: Status,
        solve: SolveFn,
        cost: CostFn,
        starts: dict[str, FloatArray],
    ) -> tuple[FloatArray, Status, object | None, bool]:
        """Stage 2: the same window with the arrival weight on its first node divided by
        ``FORGET``, solved from ``X`` and from every candidate (stage 1's ``starts``, the
        EKF's run again from the weaker prior); its lowest-cost answer is kept when it
        explains the measurements better by at least ``1/FIT_GAIN``."""
        full = problem.arrival.copy()
        if not np.array_equal(full[1:], np.zeros_like(full[1:])):
            return X, status, None, False  # a growing window: its prior is the first reading
        full[0] = full[0] / FORGET
        relaxed = replace(problem, arrival=full)
        best: tuple[float, FloatArray, object] | None = None
        for X0 in (X, *{**starts, "ekf": self._ekf_window(relaxed)}.values()):
            Xc, st, state = solve(relaxed, X0)
            if st in (Status.OK, Status.FALLBACK_IPOPT):
                c = cost(relaxed, Xc)
                if best is None or c < best[0]:
                    best = (c, Xc, state)
        fit, _ = self.measurement_cost(problem, X, cost)
        if best is None or self.measurement_cost(problem, best[1], cost)[0] >= FIT_GAIN * fit:
            return X, status, None, False
        self.stats.restarted += 1
        self.stats.prior_forgotten += 1
        return best[1], Status.BRANCH_RESTART, best[2], True


def _fill_rates(f: Formulation, X: FloatArray, dt: FloatArray) -> None:
    """Set the rate states (named ``*_dot``) to finite differences of their coordinates."""
    names = f.state_names
    for j, name in enumerate(names):
        if name.endswith("_dot") and name[: -len("_dot")] in names:
            k = names.index(name[: -len("_dot")])
            X[1:, j] = np.diff(X[:, k]) / dt
            X[0, j] = X[1, j] if len(X) > 1 else 0.0


__all__ = [
    "CHECKED_BY_DEFAULT",
    "FIT_GAIN",
    "FORGET",
    "QUANTILE",
    "REL_MARGIN",
    "BranchCheck",
    "BranchStats",
    "checks_branch",
]
