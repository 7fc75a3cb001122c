"""The strongest peers of the fast MHE, on the very window problems it solves:
acados (SQP with HPIPM, generated C), CasADi's fatrop, CasADi's sqpmethod with HPIPM
as its QP solver, and IPOPT warm-started (``continuum-mhe benchmark``'s rows
``acados``, ``fatrop``, ``sqp-hpipm``, ``ipopt-warm``; the ``ipopt`` row is the
estimator's own IPOPT backend, its whole step).

The windows are the MHE's own (:class:`~continuum_mhe.estimators.window_nlp.WindowProblem`,
recorded from the IPOPT-backend estimator over the recording: the same measurements,
masks, time steps, inputs, ``Q(dt)^-1`` and arrival prior, growing windows included).
Each peer solves them in order, warm-started as the MHE is: from its own previous
answer shifted by one sample, the new node predicted by the model and projected on
the bounds (:func:`shifted_guess`). The peers need the structure of an optimal control
problem, so the window is written with the process noise as the control:
``x_{i+1} = f(x_i, u_i, dt_i) + w_i`` as equality constraints and
``1/2 ||w_i||^2_{Q_i^-1}`` as the stage cost, the measurement and arrival terms on
the nodes. Its states at the optimum are the window's (the noise is determined by
them), so the answers are comparable with IPOPT's node by node.

Each peer is timed on its solve alone, from the problem data and the warm start
formed outside the timed part (the fast MHE's row times its whole estimator step:
the arrival update, the covariance and the outputs too). acados reports its own
time without the Python interface beside it (``solver_us``).

acados comes from the registry package ``comma-deps-acados`` (its prebuilt libraries,
``acados_template`` and the template renderer ``t_renderer``). That wheel also
installs a slimmed CasADi of its own into the ``casadi`` folder, without IPOPT, over
the real one, so it is installed apart (``pip install --no-deps --target DIR
comma-deps-acados``) and found there (:func:`find_acados`); acados' code generation
uses the real CasADi. Its solver is generated and compiled in a temporary folder
when the benchmark starts (a C compiler and ``make`` are needed).
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import io
import math
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Protocol

import casadi as ca
import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.estimators.window_nlp import WindowParameters, WindowProblem, pack_parameters
from continuum_mhe.extras import import_problem, install_advice
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.scenarios import Recording

PEERS = ("acados", "fatrop", "sqp-hpipm", "ipopt-warm")

#: The CasADi whose fatrop and sqpmethod with HPIPM solve the peers' windows (the
#: ``peers`` extra's; older wheels lack fatrop, or their sqpmethod stops short).
CASADI_PEERS = "casadi>=3.8.2"

#: What each peer's time covers.
PEER_NOTES: dict[str, str] = {
    "acados": "acados SQP (exact Hessian) with HPIPM (SPEED mode, QP warm start), "
    "generated C, on the same windows (noise as control), warm-started from its shifted "
    "answer and multipliers: the solve and read-back through acados_template; solver us: "
    "acados' own time",
    "fatrop": "CasADi's fatrop (structure-exploiting interior point) on the same windows "
    "(noise as control), warm-started from its shifted answer (it takes no multipliers), "
    "its barrier started at mu_init 1e-6: "
    "the nlpsol call (its functions compiled where a C compiler is found)",
    "sqp-hpipm": "CasADi's sqpmethod with HPIPM as QP solver (exact Hessian, full steps "
    "as acados': no line search) on the same windows (noise as control), warm-started "
    "from its shifted answer and multipliers: "
    "the nlpsol call (its functions compiled where a C compiler is found)",
    "ipopt-warm": "IPOPT through CasADi on the same windows (noise as control), "
    "warm-started as an interior point can be: its shifted answer and multipliers, "
    "warm_start_init_point, mu_init 1e-4, bound pushes 1e-9, adaptive mu: the nlpsol "
    "call (its functions compiled where a C compiler is found), no covariance (the ipopt "
    "row is the whole estimator step)",
}

#: IPOPT's options as the ipopt-warm peer runs it: a warm start from the previous
#: window's answer and multipliers, its barrier started small (the answer is near).
IPOPT_WARM_OPTIONS: dict[str, Any] = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-4,
    "warm_start_bound_push": 1e-9,
    "warm_start_mult_bound_push": 1e-9,
    "mu_strategy": "adaptive",
}

#: fatrop's options beyond its tolerance and iteration limit: its barrier started small,
#: as a warm-started interior point's is (the answer is near; fatrop takes no
#: multipliers and no ``warm_start_init_point``). From its default start fatrop takes
#: about 5.1 iterations a full window of the benchmark's N = 30, from 1e-6 about 3.5
#: (1e-4: 4.0, 1e-8: 3.9), to the same answers (docs/benchmarks.md).
FATROP_WARM_OPTIONS: dict[str, Any] = {"mu_init": 1e-6}

#: sqpmethod's options beyond its tolerances and iteration limit: full Newton steps, no
#: line search (``max_iter_ls`` 0), as acados' SQP takes them (its ``FIXED_STEP``
#: globalization) and as the fast MHE's Newton steps are taken from a warm start. With
#: CasADi's default line search sqpmethod stopped on some windows with
#: ``Search_Direction_Becomes_Too_Small`` (7 of 401 at N = 30) and took 2.56 iterations
#: a full window; with full steps it converges on every one, in 2.40.
SQP_OPTIONS: dict[str, Any] = {"max_iter_ls": 0}

#: Convergence tolerance of every peer (the fast MHE's step and error tolerances and
#: IPOPT's ``tol`` are 1e-8).
PEER_TOL = 1e-8

#: SQP iterations (and fatrop's) allowed per window.
PEER_MAX_ITER = 100

#: Stands for an absent bound where a solver takes no infinity (acados): beyond any
#: value the benchmark's windows reach (bends and rates in rad and rad/s, the disk's sum
#: of squares, never negative), and near enough to the problem's scale for HPIPM's
#: interior point, which with a bound of 1e9 runs into its iteration limit in most QPs
#: (docs/benchmarks.md).
INFINITE_BOUND = 1e3

#: acados' complementarity tolerance (see :class:`AcadosPeer`); its stationarity,
#: equality and inequality tolerances are :data:`PEER_TOL`.
ACADOS_TOL_COMP = 1e-6

#: The registry package of acados, and how it is installed apart from CasADi.
ACADOS_PACKAGE = "comma-deps-acados"
ACADOS_HINT = (
    f"pip install --no-deps --target DIR {ACADOS_PACKAGE} (apart: it ships a CasADi "
    "without IPOPT into the casadi folder), then --acados DIR"
)


class WindowSolver(Protocol):
    """A peer: :meth:`reset` starts a recording (no previous answer), :meth:`prepare`
    hands it one window and its guess (the problem data and the warm start, formed
    outside the timed part), :meth:`solve` solves it (the timed part) and returns ``(X
    (N, nx), converged, the solver's own seconds or nan)``."""

    def reset(self) -> None: ...

    def prepare(self, problem: WindowProblem, X0: FloatArray) -> None: ...

    def solve(self) -> tuple[FloatArray, bool, float]: ...


def solve_window(
    solver: WindowSolver, problem: WindowProblem, X0: FloatArray
) -> tuple[FloatArray, bool, float]:
    """``solver`` on one window from the guess ``X0``: :meth:`~WindowSolver.prepare`,
    then :meth:`~WindowSolver.solve`."""
    solver.prepare(problem, X0)
    return solver.solve()


def record_windows(
    formulation: Formulation, rec: Recording, horizon: int
) -> list[WindowProblem | None]:
    """The MHE's window problem at each sample of ``rec`` (None where it made no
    estimate), from the IPOPT-backend estimator (the problems do not depend on the
    backend: with the quadratic loss the arrival prior slides on the data alone)."""
    est = MovingHorizonEstimator(formulation, MHESettings(horizon=horizon, solver="ipopt"))
    windows: list[WindowProblem | None] = []
    for t, z in zip(rec.t, rec.z):
        e = est.step(Measurement(float(t), z))
        windows.append(None if e.state is None else est.inference.window_problem(copy=True))
    return windows


def shifted_guess(
    formulation: Formulation, problem: WindowProblem, previous: FloatArray | None
) -> FloatArray:
    """The MHE's warm start: the previous answer (N, nx) shifted by one sample, its last
    node carried to the new sample by the model and projected on the bounds; the
    arrival prior at every node for the first window."""
    n = len(problem.zmask)
    if previous is None:
        return np.tile(problem.xbar, (n, 1))
    X = np.empty_like(previous)
    X[:-1] = previous[1:]
    xn = formulation.functions.transition(previous[-1], problem.u[-1], problem.dt[-1])
    X[-1] = formulation.project(np.asarray(xn, dtype=float).ravel())
    return X


def run_peer(
    formulation: Formulation, solver: WindowSolver, windows: list[WindowProblem | None]
) -> tuple[FloatArray, FloatArray, int, FloatArray]:
    """The peer over the recorded windows in order, each warm-started from its own
    shifted answer. Returns ``(output (n, ny), seconds per sample (n,), windows not
    converged, the solver's own seconds per sample (n,), nan where it reports none)``;
    only the solve is timed (:meth:`~WindowSolver.prepare` before the clock starts)."""
    f = formulation
    n = len(windows)
    out = np.full((n, f.ny), np.nan)
    sec = np.zeros(n)
    own = np.full(n, np.nan)
    failed = 0
    X: FloatArray | None = None
    solver.reset()
    for i, problem in enumerate(windows):
        if problem is None:
            continue
        solver.prepare(problem, shifted_guess(f, problem, X))
        t0 = time.perf_counter()
        X, converged, own[i] = solver.solve()
        sec[i] = time.perf_counter() - t0
        failed += not converged
        out[i] = f.output(X[-1])
    return out, sec, failed, own


# --- CasADi: the window with the noise as control --------------------------------


@dataclass(frozen=True)
class OcpNlp:
    """The window NLP in optimal-control form for CasADi's structure-exploiting
    solvers: decision vector ``[x_0, w_0, x_1, w_1, ..., x_{N-1}]``, constraints per
    stage the dynamics gap then the formulation's constraints, parameters as
    :func:`~continuum_mhe.estimators.window_nlp.pack_parameters` packs them."""

    nlp: dict[str, Any]
    lbx: FloatArray
    ubx: FloatArray
    lbg: FloatArray
    ubg: FloatArray
    ng: int  # constraints per node (the formulation's)


def ocp_nlp(formulation: Formulation, horizon: int) -> OcpNlp:
    """:class:`OcpNlp` of the window cost (quadratic loss) at ``horizon``."""
    f, n, nx = formulation, horizon, formulation.nx
    par = WindowParameters.symbols(f, n)
    Z, zmask, DT, U, QI, xbar, AR = par.Z, par.zmask, par.DT, par.U, par.QI, par.xbar, par.AR
    X = [ca.SX.sym(f"x{i}", nx) for i in range(n)]
    W = [ca.SX.sym(f"w{i}", nx) for i in range(n - 1)]
    rinv = np.linalg.inv(f.meas_cov())
    cost = ca.SX(0)
    g = []
    for i in range(n):
        r = zmask[:, i] * f.measurement_residual_sym(Z[:, i], X[i])
        e = X[i] - xbar
        cost += 0.5 * ca.bilin(rinv, r, r) + 0.5 * ca.bilin(ca.reshape(AR[:, i], nx, nx), e, e)
        if i < n - 1:
            cost += 0.5 * ca.bilin(ca.reshape(QI[:, i], nx, nx), W[i], W[i])
            g.append(X[i + 1] - f.transition_sym(X[i], U[:, i], DT[i]) - W[i])
        g.append(f.constraint_sym(X[i])[0])
    w = ca.vertcat(*[v for i in range(n) for v in ((X[i], W[i]) if i < n - 1 else (X[i],))])
    lo, hi = f.state_bounds()
    cg, clo, chi = f.constraint_sym(ca.SX.sym("x", nx))
    clo, chi = (np.asarray(b, dtype=float).ravel() for b in (clo, chi))
    free = np.full(nx, np.inf)
    gap = np.zeros(nx)
    return OcpNlp(
        nlp={"x": w, "p": par.vector, "f": cost, "g": ca.vertcat(*g)},
        lbx=np.concatenate([*[np.concatenate([lo, -free])] * (n - 1), lo]),
        ubx=np.concatenate([*[np.concatenate([hi, free])] * (n - 1), hi]),
        lbg=np.concatenate([*[np.concatenate([gap, clo])] * (n - 1), clo]),
        ubg=np.concatenate([*[np.concatenate([gap, chi])] * (n - 1), chi]),
        ng=int(cg.numel()),
    )


def ocp_guess(formulation: Formulation, problem: WindowProblem, X0: FloatArray) -> FloatArray:
    """The decision vector of :class:`OcpNlp` for states ``X0`` (N, nx): the noise of
    each stage the gap the states leave (a guess that satisfies the dynamics)."""
    f = formulation
    parts = []
    for i in range(len(X0) - 1):
        xn = np.asarray(f.functions.transition(X0[i], problem.u[i], problem.dt[i]), float)
        parts += [X0[i], X0[i + 1] - xn.ravel()]
    parts.append(X0[-1])
    return np.concatenate(parts)


def ocp_states(w: FloatArray, nx: int, horizon: int) -> FloatArray:
    """The states (N, nx) of an :class:`OcpNlp` decision vector."""
    full = np.append(w, np.zeros(nx)).reshape(horizon, 2 * nx)
    return full[:, :nx].copy()


class CasadiPeer:
    """A CasADi ``nlpsol`` on :class:`OcpNlp`: ``"fatrop"`` (its structure detected,
    :data:`FATROP_WARM_OPTIONS`), ``"sqp-hpipm"`` (sqpmethod, exact Hessian, HPIPM with
    the stage sizes given, :data:`SQP_OPTIONS`) or
    ``"ipopt-warm"`` (IPOPT warm-started: :data:`IPOPT_WARM_OPTIONS`). ``options``:
    the solver's own options changed from the benchmark's (fatrop's and IPOPT's, or
    sqpmethod's), a None value leaving that option at the solver's default
    (``tools/peer_options.py`` measures the peers by option)."""

    def __init__(
        self,
        formulation: Formulation,
        horizon: int,
        name: str,
        compiled: bool | None = None,
        options: Mapping[str, Any] | None = None,
    ) -> None:
        self.formulation, self.horizon = formulation, horizon
        self.ocp = o = ocp_nlp(formulation, horizon)
        # the bounds and the prepared window (prepare) as nlpsol takes them: CasADi
        # matrices, so that no array is converted inside the timed call
        self._bounds = {k: ca.DM(getattr(o, k)) for k in ("lbx", "ubx", "lbg", "ubg")}
        self._x0 = self._p = ca.DM()
        # the previous answer's multipliers (lam_x, lam_g), and the prepared window's
        # start from them, shifted (prepare)
        self._lam: tuple[ca.DM, ca.DM] | None = None
        self._lam0: dict[str, ca.DM] = {}
        nx, n = formulation.nx, horizon
        common: dict[str, Any] = {
            "print_time": False,
            "error_on_fail": False,
            **casadi_peer_compile_options(compiled),
        }
        if name == "fatrop":
            opts = {
                **common,
                "structure_detection": "auto",
                "equality": [bool(e) for e in o.lbg == o.ubg],
                "fatrop": _changed(
                    {
                        "tol": PEER_TOL,
                        "max_iter": PEER_MAX_ITER,
                        "print_level": 0,
                        **FATROP_WARM_OPTIONS,
                    },
                    options,
                ),
            }
            with _quiet():
                self.solver = ca.nlpsol("peer", "fatrop", o.nlp, opts)
        elif name == "sqp-hpipm":
            opts = _changed(
                {
                    **common,
                    "qpsol": "hpipm",
                    "qpsol_options": {
                        "N": n - 1,
                        "nx": [nx] * n,
                        "nu": [nx] * (n - 1) + [0],
                        "ng": [o.ng] * n,
                        "print_problem": False,
                        "error_on_fail": False,
                    },
                    "tol_pr": PEER_TOL,
                    "tol_du": PEER_TOL,
                    "max_iter": PEER_MAX_ITER,
                    **SQP_OPTIONS,
                    "print_header": False,
                    "print_iteration": False,
                    "print_status": False,
                },
                options,
            )
            with _quiet():
                self.solver = ca.nlpsol("peer", "sqpmethod", o.nlp, opts)
        elif name == "ipopt-warm":
            opts = {
                **common,
                "ipopt": _changed(
                    {
                        "tol": PEER_TOL,
                        "max_iter": PEER_MAX_ITER,
                        "print_level": 0,
                        "sb": "yes",
                        **IPOPT_WARM_OPTIONS,
                    },
                    options,
                ),
            }
            with _quiet():
                self.solver = ca.nlpsol("peer", "ipopt", o.nlp, opts)
        else:
            raise ValueError(f"no CasADi peer named {name!r}")

    def reset(self) -> None:
        """A new recording: no previous multipliers."""
        self._lam, self._lam0 = None, {}

    def prepare(self, problem: WindowProblem, X0: FloatArray) -> None:
        """The window's parameters and the guess, as ``nlpsol`` takes them: the states'
        and the multipliers of the previous answer shifted by one sample, as the fast
        MHE shifts its own (:func:`shifted_multipliers`; none before the first answer of
        a recording; fatrop, an interior-point method, does not take them). All are
        converted to CasADi matrices here, outside the timed :meth:`solve`."""
        self._x0 = ca.DM(ocp_guess(self.formulation, problem, X0))
        self._p = ca.DM(pack_parameters(problem))
        self._lam0 = {}
        if self._lam is not None:
            nx, ng = self.formulation.nx, self.ocp.ng
            lam_x, lam_g = (np.asarray(v, dtype=float).ravel() for v in self._lam)
            x, g = shifted_multipliers(lam_x, lam_g, nx, ng)
            self._lam0 = {"lam_x0": ca.DM(x), "lam_g0": ca.DM(g)}

    def solve(self) -> tuple[FloatArray, bool, float]:
        sol = self.solver(x0=self._x0, p=self._p, **self._bounds, **self._lam0)
        self._lam = (sol["lam_x"], sol["lam_g"])  # (shifted by the next prepare)
        X = ocp_states(np.asarray(sol["x"], dtype=float).ravel(), self.formulation.nx, self.horizon)
        return X, bool(self.solver.stats()["success"]), math.nan


def _changed(options: dict[str, Any], change: Mapping[str, Any] | None) -> dict[str, Any]:
    """``options`` with ``change`` over them, an option changed to None left out."""
    merged = {**options, **(change or {})}
    return {k: v for k, v in merged.items() if v is not None}


def shifted_multipliers(
    lam_x: FloatArray, lam_g: FloatArray, nx: int, ng: int
) -> tuple[FloatArray, FloatArray]:
    """The multipliers of an :class:`OcpNlp` answer moved by one sample, as its states
    are (:func:`shifted_guess`): stage ``i`` takes stage ``i + 1``'s; the new last
    stage's noise bound none (the noise is unbounded), its state bounds and constraints
    the old last ones', and the dynamics of the stage before it the old last dynamics'."""
    stage_x, stage_g = 2 * nx, nx + ng
    x = np.concatenate([lam_x[stage_x:], np.zeros(nx), lam_x[-nx:]])
    dyn_last = lam_g[-ng - stage_g : -ng - ng] if ng else lam_g[-stage_g:]
    g = np.concatenate([lam_g[stage_g : len(lam_g) - ng], dyn_last, lam_g[len(lam_g) - ng :],
                        lam_g[len(lam_g) - ng :]])  # fmt: skip
    return x, g


@contextlib.contextmanager
def _quiet() -> Iterator[list[str]]:
    """Silence what a solver's construction prints on the process's own stdout (C
    code, a compiler's make, write there, past Python's ``sys.stdout``); the list
    yielded receives what was printed once the block ends (for a message where the
    construction failed)."""
    sys.stdout.flush()
    saved = os.dup(1)
    printed: list[str] = []
    python_out = io.StringIO()
    with tempfile.TemporaryFile("w+") as sink:
        try:
            os.dup2(sink.fileno(), 1)
            with contextlib.redirect_stdout(python_out):
                yield printed
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
            sink.seek(0)
            printed.append(sink.read() + python_out.getvalue())


# --- acados ----------------------------------------------------------------------


def find_acados(folder: str | None = None) -> ModuleType | None:
    """The ``acados`` package of ``comma-deps-acados``: from ``folder`` (where ``pip
    install --target`` put it) when given, else as installed; None when absent. Only
    the package is loaded, never its CasADi (``acados_template`` uses the real one)."""
    if folder is None:
        spec = importlib.util.find_spec("acados")
        if spec is None or spec.origin is None:
            return None
        init = Path(spec.origin)
    else:
        init = Path(folder) / "acados" / "__init__.py"
        if not init.is_file():
            return None
    if "acados" in sys.modules:
        return sys.modules["acados"]
    spec = importlib.util.spec_from_file_location(
        "acados", init, submodule_search_locations=[str(init.parent)]
    )
    if spec is None or spec.loader is None:
        return None
    module = importlib.util.module_from_spec(spec)
    sys.modules["acados"] = module
    spec.loader.exec_module(module)
    if not hasattr(module, "TERA_PATH"):  # an unrelated package of that name
        del sys.modules["acados"]
        return None
    return module


class AcadosPeer:
    """acados' SQP (exact Hessian, as the fast MHE's Newton steps; nonlinear least
    squares cost) with HPIPM (its SPEED mode, each QP warm-started) on the window with
    the noise as control (see the module docstring), generated and built in a
    temporary folder, removed by :meth:`close`. With the Gauss-Newton Hessian it takes
    about five SQP iterations a window where the exact one takes two."""

    def __init__(self, formulation: Formulation, horizon: int, acados: ModuleType) -> None:
        f, n, nx, m = formulation, horizon, formulation.nx, formulation.nz
        self.formulation, self.horizon = f, n
        os.environ["ACADOS_SOURCE_DIR"] = acados.DIR
        os.environ["TERA_PATH"] = acados.TERA_PATH  # never the renderer's download prompt
        os.environ["ACADOS_PYTHON_INTERFACE_PATH"] = acados.TEMPLATE_DIR
        for lib in ("libblasfeo", "libhpipm", "libqpOASES_e", "libacados"):
            ctypes.CDLL(os.path.join(acados.LIB_DIR, lib + ".so"), mode=ctypes.RTLD_GLOBAL)
        from acados.acados_template import AcadosModel, AcadosOcp, AcadosOcpSolver

        x = ca.SX.sym("x", nx)
        w = ca.SX.sym("w", nx)
        z, mask = ca.SX.sym("z", m), ca.SX.sym("mask", m)
        u, dt = ca.SX.sym("u", f.nu), ca.SX.sym("dt")
        model = AcadosModel()
        model.name = f"continuum_mhe_window_{n}"
        model.x, model.u, model.p = x, w, ca.vertcat(z, mask, u, dt)
        model.disc_dyn_expr = f.transition_sym(x, u, dt) + w
        r = mask * f.measurement_residual_sym(z, x)
        model.cost_y_expr = ca.vertcat(r, w, x)
        model.cost_y_expr_e = ca.vertcat(r, x)
        cg, clo, chi = f.constraint_sym(x)
        ocp = AcadosOcp()
        ocp.model = model
        ocp.dims.N = n - 1
        ocp.solver_options.tf = float(n - 1)  # unit steps: acados scales stage costs by them
        ocp.cost.cost_type = ocp.cost.cost_type_e = "NONLINEAR_LS"
        self.rinv = np.linalg.inv(f.meas_cov())
        ocp.cost.W = np.eye(m + 2 * nx)
        ocp.cost.W_e = np.eye(m + nx)
        ocp.cost.yref = np.zeros(m + 2 * nx)
        ocp.cost.yref_e = np.zeros(m + nx)
        ocp.parameter_values = np.zeros(2 * m + f.nu + 1)
        lo, hi = f.state_bounds()
        bounded = np.flatnonzero(np.isfinite(lo) | np.isfinite(hi))
        if len(bounded):
            clip = np.clip
            blo = clip(lo[bounded], -INFINITE_BOUND, INFINITE_BOUND)
            bhi = clip(hi[bounded], -INFINITE_BOUND, INFINITE_BOUND)
            c = ocp.constraints
            c.idxbx_0 = c.idxbx = c.idxbx_e = bounded
            c.lbx_0 = c.lbx = c.lbx_e = blo
            c.ubx_0 = c.ubx = c.ubx_e = bhi
        if cg.numel():
            hlo = np.clip(np.asarray(clo, float).ravel(), -INFINITE_BOUND, INFINITE_BOUND)
            hhi = np.clip(np.asarray(chi, float).ravel(), -INFINITE_BOUND, INFINITE_BOUND)
            model.con_h_expr_0 = model.con_h_expr = model.con_h_expr_e = cg
            c = ocp.constraints
            c.lh_0 = c.lh = c.lh_e = hlo
            c.uh_0 = c.uh = c.uh_e = hhi
        s = ocp.solver_options
        s.integrator_type = "DISCRETE"
        s.nlp_solver_type = "SQP"
        s.hessian_approx = "EXACT"  # the fast MHE's Newton steps: two SQP iterations
        s.exact_hess_constr = 1
        s.qp_solver = "PARTIAL_CONDENSING_HPIPM"
        s.hpipm_mode = "SPEED"
        s.qp_solver_warm_start = 1
        s.nlp_solver_max_iter = PEER_MAX_ITER
        s.tol = PEER_TOL
        # complementarity: an absent bound stands at INFINITE_BOUND, where its slack times
        # its multiplier need not reach the other tolerances
        s.nlp_solver_tol_comp = ACADOS_TOL_COMP
        s.print_level = 0
        self.folder = tempfile.mkdtemp(prefix="continuum-mhe-acados-")
        ocp.code_export_directory = os.path.join(self.folder, "c_generated_code")
        json_file = os.path.join(self.folder, "ocp.json")
        printed: list[str] = []
        try:
            with _quiet() as printed:
                self.solver = AcadosOcpSolver(ocp, json_file=json_file, verbose=False)
        except BaseException as exc:  # Ctrl-C or a failed build: no folder left behind
            shutil.rmtree(self.folder, ignore_errors=True)
            if not isinstance(exc, Exception):
                raise
            said = [ln.strip() for ln in "".join(printed).splitlines() if ln.strip()]
            tail = f"; it printed: {' | '.join(said[-3:])}" if said else ""
            raise UserError(
                f"acados: its generated solver for N = {horizon} did not build or load "
                f"({type(exc).__name__}: {exc}){tail}: check the C compiler and make it "
                "uses; --skip acados times the others"
            ) from None
        #: whether the solver holds an answer of this recording (its multipliers)
        self._solved = False
        self._W = np.zeros((m + 2 * nx, m + 2 * nx))
        self._W[:m, :m] = self.rinv
        self._W_e = np.zeros((m + nx, m + nx))
        self._W_e[:m, :m] = self.rinv

    def reset(self) -> None:
        """A new recording: its first window starts from the multipliers acados holds,
        not shifted (no answer of this recording to shift)."""
        self._solved = False

    def prepare(self, problem: WindowProblem, X0: FloatArray) -> None:
        """The window's parameters, weights and guess, set in the solver through
        ``acados_template``, with the multipliers of the previous answer shifted by one
        sample as the fast MHE shifts its own (:meth:`_set_shifted_duals`)."""
        self._set_shifted_duals()  # (read from the last answer before anything is set)
        f, n, nx, m = self.formulation, self.horizon, self.formulation.nx, self.formulation.nz
        s, W = self.solver, self._W
        yref = np.zeros(m + 2 * nx)
        yref[m + nx :] = problem.xbar
        guess = ocp_guess(f, problem, X0)
        for i in range(n - 1):
            s.set(i, "p", np.concatenate([problem.z[i], problem.zmask[i], problem.u[i],
                                          problem.dt[i : i + 1]]))  # fmt: skip
            W[m : m + nx, m : m + nx] = problem.qinv[i]
            W[m + nx :, m + nx :] = problem.arrival[i]
            s.cost_set(i, "W", W, api="new")
            s.cost_set(i, "yref", yref)
            s.set(i, "x", X0[i])
            s.set(i, "u", guess[2 * nx * i + nx : 2 * nx * (i + 1)])
        last = n - 1
        s.set(last, "p", np.concatenate([problem.z[last], problem.zmask[last],
                                         np.zeros(f.nu), [1.0]]))  # fmt: skip
        self._W_e[m:, m:] = problem.arrival[last]
        s.cost_set(last, "W", self._W_e, api="new")
        s.cost_set(last, "yref", np.concatenate([np.zeros(m), problem.xbar]))
        s.set(last, "x", X0[last])

    def _set_shifted_duals(self) -> None:
        """The previous answer's multipliers moved by one sample, as
        :func:`shifted_multipliers` moves sqpmethod's: each stage takes the next one's
        dynamics multipliers (``pi``) and inequality multipliers and slacks (``lam``,
        ``t``: the state bounds and the constraints, alike at every stage); the new
        last stage and the dynamics into it keep the old last ones'. acados otherwise
        starts from its own last multipliers, unshifted. Nothing before the first
        answer of a recording."""
        if not self._solved:
            return
        s, last = self.solver, self.horizon - 1
        for field, stages in (("pi", last), ("lam", last + 1), ("t", last + 1)):
            old = [np.array(s.get(i, field)) for i in range(stages)]
            for i in range(stages):
                s.set(i, field, old[min(i + 1, stages - 1)])
        self._solved = False  # shifted once: a second prepare does not shift again

    def solve(self) -> tuple[FloatArray, bool, float]:
        s = self.solver
        status = s.solve()
        X = np.array([s.get(i, "x") for i in range(self.horizon)])
        self._solved = True
        return X, status == 0, float(np.asarray(s.get_stats("time_tot")).ravel()[0])

    def close(self) -> None:
        """Remove the generated solver's folder."""
        shutil.rmtree(self.folder, ignore_errors=True)


def acados_version(acados: ModuleType) -> str | None:
    """The version of the ``comma-deps-acados`` that holds ``acados`` (from its
    ``.dist-info`` folder beside the package); None if it names none."""
    site = Path(str(acados.__file__)).parent.parent
    for info in sorted(site.glob("comma_deps_acados-*.dist-info")):
        return info.name[len("comma_deps_acados-") : -len(".dist-info")]
    return None


def casadi_peers_compiled(compiled: bool | None = None) -> bool:
    """Whether the CasADi peers' functions are compiled: ``compiled``, or (None) where a
    C compiler (``cc``) is found."""
    return shutil.which("cc") is not None if compiled is None else compiled


def casadi_peer_compile_options(compiled: bool | None = None) -> dict[str, Any]:
    """The ``nlpsol`` options of a CasADi peer (:func:`casadi_peers_compiled`): its
    window's functions compiled to C (``jit``, ``-O2``) before the clock starts, as
    acados' generated C is; CasADi's SX virtual machine otherwise evaluates them, fatrop
    about twice as slowly at N = 30."""
    if not casadi_peers_compiled(compiled):
        return {}
    return {"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"]}}


def make_peer(
    name: str,
    formulation: Formulation,
    horizon: int,
    acados: ModuleType | None = None,
    compiled: bool | None = None,
) -> WindowSolver:
    """The peer ``name`` of :data:`PEERS` at ``horizon`` (``acados``: the package
    :func:`find_acados` found; ``compiled``: the CasADi peers', see
    :func:`casadi_peers_compiled`)."""
    if name == "acados":
        if acados is None:
            raise ValueError("the acados peer needs the acados package (find_acados)")
        return AcadosPeer(formulation, horizon, acados)
    return CasadiPeer(formulation, horizon, name, compiled)


def missing_peers(acados_folder: str | None = None) -> dict[str, str]:
    """The peers that cannot run here, each with the one line that says what to
    install."""
    why: dict[str, str] = {}
    if (problem := import_problem("do_mpc")) is not None:
        why["do-mpc"] = f"needs do-mpc, {problem}: {install_advice('peers', problem)}"
    if find_acados(acados_folder) is None:
        where = f" (not in {acados_folder})" if acados_folder else ""
        why["acados"] = f"needs {ACADOS_PACKAGE}{where}: {ACADOS_HINT}"
    elif shutil.which("make") is None or shutil.which("cc") is None:
        why["acados"] = "needs a C compiler (cc) and make to build its generated solver"
    if not ca.has_nlpsol("fatrop"):
        why["fatrop"] = f"this CasADi has no fatrop: pip install '{CASADI_PEERS}'"
    if not ca.has_conic("hpipm"):
        why["sqp-hpipm"] = f"this CasADi has no HPIPM: pip install '{CASADI_PEERS}'"
    return why
