"""The MHE's window problem as a CasADi NLP for IPOPT: the problem's data
(:class:`WindowProblem`), the NLP built once per formulation, horizon, loss and
objective scale (:func:`build_nlp`), and the parameter vector of one window
(:func:`pack_parameters`). The cost is the one :mod:`continuum_mhe.estimators.mhe`
states; the fast backend solves the same problem (:mod:`.fast`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from continuum_mhe.estimators.base import FloatArray
from continuum_mhe.estimators.loss import rho_sym
from continuum_mhe.model.formulations import Formulation


@dataclass(frozen=True)
class WindowProblem:
    """The window NLP's data for one solve (all numeric, shapes for horizon N)."""

    z: FloatArray  # (N, m) measurements (0 where masked)
    zmask: FloatArray  # (N, m) 1 for a valid, active measurement component
    dt: FloatArray  # (N-1,) s
    u: FloatArray  # (N-1, nu)
    qinv: FloatArray  # (N-1, nx, nx) inverse process covariance per stage (0 if inactive)
    xbar: FloatArray  # (nx,) arrival prior
    arrival: FloatArray  # (N, nx, nx) arrival weight per node (P^-1 on first active node)


@dataclass(frozen=True)
class WindowParameters:
    """The window's parameters as CasADi symbols, for the window NLP and its peers:
    ``Z``, ``zmask`` (nz, N) the readings and their mask; ``DT`` (N - 1) s; ``U``
    (nu, N - 1) inputs; ``QI`` (nx^2, N - 1) and ``AR`` (nx^2, N) the process-noise and
    arrival weights, column-major; ``xbar`` (nx) the arrival state."""

    Z: ca.SX
    zmask: ca.SX
    DT: ca.SX
    U: ca.SX
    QI: ca.SX
    xbar: ca.SX
    AR: ca.SX

    @classmethod
    def symbols(cls, formulation: Formulation, horizon: int) -> WindowParameters:
        f, n, nx = formulation, horizon, formulation.nx
        return cls(
            Z=ca.SX.sym("Z", f.nz, n),
            zmask=ca.SX.sym("zmask", f.nz, n),
            DT=ca.SX.sym("DT", n - 1),
            U=ca.SX.sym("U", f.nu, n - 1),
            QI=ca.SX.sym("QI", nx * nx, n - 1),
            xbar=ca.SX.sym("xbar", nx),
            AR=ca.SX.sym("AR", nx * nx, n),
        )

    @property
    def vector(self) -> ca.SX:
        """The parameters in one vector, in the order :func:`pack_parameters` packs."""
        return ca.vertcat(
            ca.vec(self.Z), ca.vec(self.zmask), self.DT, ca.vec(self.U), ca.vec(self.QI),
            self.xbar, ca.vec(self.AR),
        )  # fmt: skip


@dataclass(frozen=True)
class Nlp:
    """An IPOPT solver of the window NLP, its bounds and its cost function."""

    solver: ca.Function
    lbx: FloatArray
    ubx: FloatArray
    lbg: FloatArray
    ubg: FloatArray
    cost: ca.Function


#: Largest window weight (an entry of ``Q(dt)^-1``, ``P^-1`` or ``R^-1``) at which IPOPT's
#: objective is left unscaled; above it the objective is divided by a power of ten.
WEIGHT_REFERENCE = 1e6


def objective_scale_exponent(problem: WindowProblem, rinv_max: float) -> int:
    """``e`` such that the window objective divided by ``10**e`` has its largest weight
    at most :data:`WEIGHT_REFERENCE` (0 when it already has).

    IPOPT's tolerance is absolute on the gradient; at a high sample rate ``Q(dt)^-1``
    grows as ``dt^-3`` (2.4e10 at 1 kHz), rounding alone exceeds the tolerance and IPOPT
    stopped with ``Search_Direction_Becomes_Too_Small`` on accurate answers. Scaling
    the objective makes the test relative to the problem's own weights.
    """
    w = max(float(np.abs(problem.qinv).max()), float(np.abs(problem.arrival).max()), rinv_max)
    if not (math.isfinite(w) and w > WEIGHT_REFERENCE):
        return 0
    return int(math.ceil(math.log10(w / WEIGHT_REFERENCE)))


@lru_cache(maxsize=32)
def build_nlp(
    formulation: Formulation,
    horizon: int,
    max_iter: int,
    tol: float,
    loss: str = "l2",
    scale: float = float("inf"),
    scale_exp: int = 0,
) -> Nlp:
    """The window NLP (decision variables the ``(nx, N)`` states, column-major; the
    parameters as :func:`pack_parameters` packs them), solved by IPOPT with ``max_iter``
    and ``tol``, the objective divided by ``10**scale_exp``."""
    f, n, nx = formulation, horizon, formulation.nx
    X = ca.SX.sym("X", nx, n)
    par = WindowParameters.symbols(f, n)
    Z, zmask, DT, U, QI, xbar, AR = par.Z, par.zmask, par.DT, par.U, par.QI, par.xbar, par.AR
    rinv = np.linalg.inv(f.meas_cov())
    cost = ca.SX(0)
    g = []
    for i in range(n):
        r = zmask[:, i] * f.measurement_residual_sym(Z[:, i], X[:, i])
        if loss == "l2":
            cost += 0.5 * ca.bilin(rinv, r, r)
        else:  # one loss per measurement block (R is block-diagonal)
            for b in f.measurement_blocks:
                rb = r[b.slice]
                cost += 0.5 * rho_sym(loss, scale, ca.bilin(rinv[b.slice, b.slice], rb, rb))
        e = X[:, i] - xbar
        cost += 0.5 * ca.bilin(ca.reshape(AR[:, i], nx, nx), e, e)
        if i < n - 1:
            w = X[:, i + 1] - f.transition_sym(X[:, i], U[:, i], DT[i])
            cost += 0.5 * ca.bilin(ca.reshape(QI[:, i], nx, nx), w, w)
        gi, _, _ = f.constraint_sym(X[:, i])
        g.append(gi)
    w, params = ca.vec(X), par.vector
    nlp: dict[str, Any] = {"x": w, "p": params, "f": cost, "g": ca.vertcat(*g)}
    opts: dict[str, Any] = {
        "print_time": False,
        "show_eval_warnings": False,  # a NaN in an evaluation is a failed solve: flagged
        "calc_lam_p": False,  # not used; its failure was printed as a warning
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.max_iter": max_iter,
        "ipopt.tol": tol,
        "ipopt.acceptable_tol": 1e-6,
    }
    if scale_exp:
        opts["ipopt.obj_scaling_factor"] = 10.0**-scale_exp
    solver = ca.nlpsol("mhe", "ipopt", nlp, opts)
    lo, hi = f.state_bounds()
    _, glo, ghi = f.constraint_sym(ca.SX.sym("x", nx))
    ng = int(ca.vertcat(*g).numel())
    return Nlp(
        solver=solver,
        lbx=np.tile(lo, n),
        ubx=np.tile(hi, n),
        lbg=np.tile(np.asarray(glo, dtype=float).ravel(), n)[:ng],
        ubg=np.tile(np.asarray(ghi, dtype=float).ravel(), n)[:ng],
        cost=ca.Function("cost", [w, params], [cost]),
    )


def pack_parameters(problem: WindowProblem) -> FloatArray:
    """Flatten a :class:`WindowProblem` in the NLP's parameter order (column-major)."""
    return np.concatenate(
        [
            problem.z.ravel(),  # (N, m) row-major == (m, N) column-major
            problem.zmask.ravel(),  # (N, m) row-major == (m, N) column-major
            problem.dt,
            problem.u.ravel(),
            problem.qinv.reshape(len(problem.dt), -1).ravel(),
            problem.xbar,
            problem.arrival.reshape(len(problem.zmask), -1).ravel(),
        ]
    )
