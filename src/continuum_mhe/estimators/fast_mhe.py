"""Structure-exploiting MHE backend: Newton-type SQP with a block-tridiagonal solver.

It solves exactly the window problem of :mod:`continuum_mhe.estimators.mhe` (same
:class:`~continuum_mhe.estimators.mhe.WindowProblem`, same cost, same hard
constraints) and reaches the same KKT point as the IPOPT backend.

Algorithm (see ``docs/fast-solver.md``):

* **Model.** Residuals and Jacobians of the whole window come from one call of a
  CasADi function built from the formulation's symbolic methods
  (``measurement_residual_sym``, ``transition_sym``) and ``map``-ped over the
  window. It is compiled to C with CasADi's code generator when a C compiler is
  available (cached on disk) and evaluated by CasADi's virtual machine otherwise.
  The model is never written a second time by hand.
* **Step.** The Hessian of the window cost is block-tridiagonal (blocks
  ``nx x nx``): Gauss-Newton ``J^T W J`` plus the measurement residuals' exact
  second-order term (Newton; dropped for an iterate where it is not positive
  definite); each QP subproblem is solved by a primal active-set method
  whose equality-constrained steps use a block-tridiagonal Cholesky factorisation,
  ``O(N nx^3)`` per factorisation. Box bounds fix coordinates; the ball constraint
  ``sum_S x_j^2 <= r^2`` (the ``bend`` formulation's disk, recognised from the
  CasADi expression) is linearised and eliminated by a per-node Householder
  reflection, so the Hessian keeps its block structure. Its curvature enters the
  Hessian of the Lagrangian through the multiplier estimate.
* **Globalisation.** Projected line search on the exact cost (iterates always
  satisfy the bounds exactly: clipping for boxes, radial scaling for the ball).
* **Certificate.** The QP at an iterate has the NLP's KKT conditions as its own at
  ``d = 0`` (nonnegative multipliers by construction). Converged when the QP step
  is below ``step_tol`` in the max norm, or, with no constraint active, when the
  contraction of two successive full steps bounds the answer's error by
  ``err_tol``. Otherwise (iteration limit, failed line search, QP failure) the
  caller falls back to IPOPT.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import signal
import subprocess
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any

import casadi as ca
import numba
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.formulations import Formulation

if TYPE_CHECKING:
    from continuum_mhe.estimators.mhe import WindowProblem as WindowProblemLike

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: Solver outcomes of :func:`solve_window`.
CONVERGED, MAX_ITER, LINE_SEARCH_FAILED, QP_FAILED, NOT_PD = 0, 1, 2, 3, 4
OUTCOMES = ("converged", "max-iter", "line-search-failed", "qp-failed", "not-positive-definite")


@dataclass(frozen=True)
class FastOptions:
    """Options of the fast backend.

    Attributes:
        max_iter: SQP (Gauss-Newton) iterations per window before falling back.
        step_tol: convergence certificate: max-norm of the QP step, state units
            (rad, rad/s, m).
        err_tol: convergence certificate: error bound of the answer estimated from
            the contraction of successive steps, state units.
        max_qp_iter: active-set changes allowed per QP subproblem.
        newton: add the measurement residuals' second-order term to the Hessian
            (exact Newton; Gauss-Newton where that is not positive definite).
        compile: compile the CasADi model to C (cached on disk) when a C compiler is
            available; otherwise, or if False, CasADi's virtual machine evaluates it.
    """

    max_iter: int = 30
    step_tol: float = 1e-8
    err_tol: float = 1e-8
    newton: bool = True
    max_qp_iter: int = 500
    compile: bool = True

    def __post_init__(self) -> None:
        if not (isinstance(self.max_iter, int) and self.max_iter >= 1):
            raise ValueError(f"max_iter must be a positive integer, got {self.max_iter!r}")
        if not (isinstance(self.max_qp_iter, int) and self.max_qp_iter >= 1):
            raise ValueError(f"max_qp_iter must be a positive integer, got {self.max_qp_iter!r}")
        if not (isinstance(self.step_tol, float) and 0 < self.step_tol < 1e-3):
            raise ValueError(f"step_tol must lie in (0, 1e-3), got {self.step_tol!r}")
        if not (isinstance(self.err_tol, float) and 0 < self.err_tol < 1e-3):
            raise ValueError(f"err_tol must lie in (0, 1e-3), got {self.err_tol!r}")


# --- the model, from the formulation's CasADi expressions -------------------------


@dataclass(frozen=True)
class Feasible:
    """The feasible set of one node: a box and balls on disjoint coordinate sets.

    Attributes:
        lo, hi: (nx,) box bounds (may be infinite).
        ball_idx: (nb, k) coordinates ``S_b`` of ball ``b``,
            ``sum_{S_b} x_j^2 <= ball_r2[b]`` (one per robot section; ``nb = 0`` if none).
        ball_r2: (nb,) squared radii, rad^2.
    """

    lo: FloatArray
    hi: FloatArray
    ball_idx: IntArray
    ball_r2: FloatArray


def feasible_set(formulation: Formulation) -> Feasible:
    """Read the feasible set from the formulation's bounds and ``constraint_sym``.

    Every component of the path constraint must be a ball ``sum_S x_j^2 <= r^2`` (checked
    on the CasADi expression: Hessian ``2 diag(1_S)``, value and gradient 0 at 0), all of
    one size, on disjoint coordinates without box bounds. Raises ``NotImplementedError``
    with the reason otherwise.
    """
    nx = formulation.nx
    lo, hi = (np.asarray(v, dtype=float) for v in formulation.state_bounds())
    x = ca.SX.sym("x", nx)
    g, glo_v, ghi_v = formulation.constraint_sym(x)
    glo, ghi = np.ravel(np.asarray(glo_v, float)), np.ravel(np.asarray(ghi_v, float))
    if g.numel() == 0:
        return Feasible(lo, hi, np.zeros((0, 1), dtype=np.int64), np.zeros(0))
    if len(glo) != g.numel() or len(ghi) != g.numel():
        raise NotImplementedError("constraint bounds do not match the constraints")
    rng = np.random.default_rng(0)
    balls: list[IntArray] = []
    used = np.zeros(nx, dtype=bool)
    for j in range(g.numel()):
        if glo[j] > 0 or not np.isfinite(ghi[j]):
            raise NotImplementedError("only ball constraints g(x) <= r^2 are supported")
        fn = ca.Function("g", [x], [g[j], ca.gradient(g[j], x), ca.hessian(g[j], x)[0]])
        v0, g0, h0 = (np.asarray(v, dtype=float) for v in fn(np.zeros(nx)))
        idx = np.flatnonzero(np.isclose(np.diag(h0.reshape(nx, nx)), 2.0)).astype(np.int64)
        mask = np.zeros(nx)
        mask[idx] = 1.0
        for xt in rng.normal(size=(5, nx)):
            value = float(np.asarray(fn(xt)[0])[0, 0])
            if not np.isclose(value, float(np.sum(mask * xt**2)), rtol=1e-12, atol=0):
                raise NotImplementedError(f"constraint {j + 1} is not a ball sum_S x_j^2")
        if (
            np.any(v0 != 0)
            or np.any(g0 != 0)
            or np.any(np.isfinite(lo[idx]) | np.isfinite(hi[idx]))
        ):
            raise NotImplementedError("ball coordinates must have no box bounds")
        if np.any(used[idx]) or (balls and len(idx) != len(balls[0])) or len(idx) == 0:
            raise NotImplementedError("balls must be non-empty, disjoint and of one size")
        used[idx] = True
        balls.append(idx)
    return Feasible(lo, hi, np.array(balls, dtype=np.int64), ghi.copy())


def _window_function(formulation: Formulation, horizon: int) -> ca.Function:
    """``(X, Z, M, U, DT) -> (R, JR, W, FJ, SR)`` for the whole window, in one call.

    Inputs (CasADi column-major): ``X`` (nx, N), ``Z`` (nz, N), ``M`` (nz, N) the 0/1
    measurement mask (a masked component has zero residual, Jacobian and curvature: a
    sensor that dropped out), ``U`` (nu, N-1), ``DT`` (1, N-1). Outputs: masked
    measurement residuals ``R`` (nz, N); their Jacobians
    ``JR`` (nz nx, N), each column the row-major ``dr/dx``; process residuals
    ``W = x_{i+1} - f(x_i, u_i, dt_i)`` (nx, N-1); ``FJ`` (nx^2, N-1), each column
    the row-major ``df/dx_i``; ``SR`` (nx^2, N), the second-order part of the
    measurement cost's Hessian ``sum_a (R^-1 r)_a d2r_a/dx2`` per node.
    """
    f, nx, nu, nz, n = formulation, formulation.nx, formulation.nu, formulation.nz, horizon
    x, xn, z = ca.SX.sym("x", nx), ca.SX.sym("xn", nx), ca.SX.sym("z", nz)
    u, dt, mk = ca.SX.sym("u", nu), ca.SX.sym("dt"), ca.SX.sym("m", nz)
    r = mk * f.measurement_residual_sym(z, x)
    jr = ca.jacobian(r, x)
    rinv = ca.DM(np.linalg.inv(f.meas_cov()))
    # second-order part of the measurement cost's Hessian, sum_a (R^-1 r)_a d2 r_a/dx2
    curv = ca.hessian(0.5 * ca.bilin(rinv, r, r), x)[0] - ca.mtimes([jr.T, rinv, jr])
    meas = ca.Function("meas", [x, z, mk], [r, ca.vec(jr.T), ca.vec(curv)])
    xf = f.transition_sym(x, u, dt)
    proc = ca.Function("proc", [x, xn, u, dt], [xn - xf, ca.vec(ca.jacobian(xf, x).T)])
    # MX, so that the maps stay loops in the generated code (SX would unroll them)
    X, Z, M = ca.MX.sym("X", nx, n), ca.MX.sym("Z", nz, n), ca.MX.sym("M", nz, n)
    U, DT = ca.MX.sym("U", nu, n - 1), ca.MX.sym("DT", 1, n - 1)
    R, JR, SR = meas.map(n, "serial")(X, Z, M)
    W, FJ = proc.map(n - 1, "serial")(X[:, : n - 1], X[:, 1:], U, DT)
    outs = [ca.densify(v) for v in (R, JR, W, FJ, SR)]
    return ca.Function("mhe_window", [X, Z, M, U, DT], outs)


def _node_function(formulation: Formulation) -> ca.Function:
    """``(x, u, dt, z, m) -> (f, F, H, r)``: transition, its Jacobian, the measurement
    Jacobian ``H = -dr(z, x)/dx`` (row-major), as the EKF uses it, and ``r(z, x)``, with
    the masked components (``m = 0``) zero."""
    f, nx = formulation, formulation.nx
    x, u, dt = ca.SX.sym("x", nx), ca.SX.sym("u", f.nu), ca.SX.sym("dt")
    z, mk = ca.SX.sym("z", f.nz), ca.SX.sym("m", f.nz)
    xf, r = f.transition_sym(x, u, dt), mk * f.measurement_residual_sym(z, x)
    outs = [xf, ca.vec(ca.jacobian(xf, x).T), ca.vec(-ca.jacobian(r, x).T), r]
    return ca.Function("mhe_node", [x, u, dt, z, mk], [ca.densify(v) for v in outs])


_WRAPPER = """
static __thread const casadi_real* {name}_arg[{sz_arg}];
static __thread casadi_real* {name}_res[{sz_res}];
static __thread casadi_int {name}_iw[{sz_iw}];
static __thread casadi_real {name}_w[{sz_w}];
int {name}_flat(const casadi_real** in, casadi_real* out) {{
  int i;
  for (i = 0; i < {n_in}; ++i) {name}_arg[i] = in[i];
{res}
  return {name}({name}_arg, {name}_res, {name}_iw, {name}_w, 0);
}}
"""


def _c_source(fns: tuple[ca.Function, ...]) -> str:
    """C source of ``fns`` with a flat entry ``<name>_flat(inputs, out)`` each.

    The entries' work arrays are thread-local: ctypes releases the GIL during calls.
    """
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator("model.c", {"with_header": False, "casadi_real": "double"})
        for fn in fns:
            cg.add(fn)
        cg.generate(tmp + os.sep)
        src = Path(tmp, "model.c").read_text()
    for fn in fns:
        offsets = np.cumsum([0] + [fn.nnz_out(i) for i in range(fn.n_out())])
        res = "\n".join(
            f"  {fn.name()}_res[{i}] = out + {int(o)};" for i, o in enumerate(offsets[:-1])
        )
        src += _WRAPPER.format(
            name=fn.name(),
            sz_arg=max(fn.sz_arg(), 1),
            sz_res=max(fn.sz_res(), 1),
            sz_iw=max(fn.sz_iw(), 1),
            sz_w=max(fn.sz_w(), 1),
            n_in=fn.n_in(),
            res=res,
        )
    return src


def _cache_dir() -> Path:
    """``$CONTINUUM_MHE_CACHE``, else ``$XDG_CACHE_HOME/continuum-mhe`` or ``~/.cache/...``."""
    own = os.environ.get("CONTINUUM_MHE_CACHE")
    if own:
        return Path(own)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "continuum-mhe"


def _file_digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _cached_library(lib: Path) -> bool:
    """True if ``lib`` exists and matches the sha256 stored beside it when it was built
    (a truncated or corrupted library would crash the process when loaded)."""
    digest = lib.with_name(lib.name + ".sha256")
    try:
        return lib.is_file() and digest.read_text().strip() == _file_digest(lib)
    except OSError:
        return False


def _compile(src: str) -> ctypes.CDLL | None:
    """Compile C source to a shared library (cached by content hash, checked against
    the sha256 stored beside it, rebuilt on mismatch); None on failure."""
    key = hashlib.sha256(src.encode()).hexdigest()[:20]
    try:
        cache = _cache_dir()
        cache.mkdir(parents=True, exist_ok=True)
        lib = cache / f"mhe_{key}.so"
        if not _cached_library(lib):
            with tempfile.TemporaryDirectory(dir=cache) as tmp:
                c_file = Path(tmp, "model.c")
                c_file.write_text(src)
                so_tmp = Path(tmp, "model.so")
                cmd = [os.environ.get("CC", "cc"), "-O2", "-fPIC", "-shared", "-o", str(so_tmp)]
                with subprocess.Popen(
                    [*cmd, str(c_file), "-lm"],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                    start_new_session=True,  # so that a timeout ends the compiler's children
                ) as proc:
                    try:
                        if proc.wait(timeout=120) != 0:
                            return None
                    except subprocess.TimeoutExpired:
                        os.killpg(proc.pid, signal.SIGKILL)
                        raise
                digest_tmp = Path(tmp, "model.sha256")
                digest_tmp.write_text(_file_digest(so_tmp) + "\n")
                # the library first, then its digest, each atomically: a reader sees a
                # digest only for a complete library (a race ends in a rebuild, not a crash)
                os.replace(so_tmp, lib)
                os.replace(digest_tmp, lib.with_name(lib.name + ".sha256"))
        if not _cached_library(lib):
            return None
        return ctypes.CDLL(str(lib))
    except (OSError, subprocess.SubprocessError):
        return None


#: C signature of every model evaluation: ``int f(const double** inputs, double* out)``.
CFunction = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


def _vm_function(fn: ca.Function) -> Any:
    """A C-callable that evaluates ``fn`` with CasADi's virtual machine (no compiler)."""
    shapes = [fn.size_in(i) for i in range(fn.n_in())]
    dptr = ctypes.POINTER(ctypes.c_double)

    def evaluate(inputs: int, out: int) -> int:
        try:
            addr = np.ctypeslib.as_array(
                ctypes.cast(inputs, ctypes.POINTER(ctypes.c_uint64)), shape=(len(shapes),)
            )
            args: list[Any] = []
            for a, (rows, cols) in zip(addr, shapes):
                if rows * cols == 0:
                    args.append(np.zeros((rows, cols)))
                    continue
                v = np.ctypeslib.as_array(ctypes.cast(int(a), dptr), shape=(cols, rows))
                args.append(v.T)
            total = sum(fn.nnz_out(i) for i in range(fn.n_out()))
            res = np.ctypeslib.as_array(ctypes.cast(out, dptr), shape=(total,))
            pos = 0
            for v in fn.call(args):
                flat = np.asarray(v, dtype=float).ravel(order="F")
                res[pos : pos + flat.size] = flat
                pos += flat.size
            return 0
        except Exception:  # noqa: BLE001 - a C callback must not raise
            return 1

    return CFunction(evaluate)


def _c_function(fn: ca.Function, lib: ctypes.CDLL | None) -> Any:
    """The compiled ``<name>_flat`` entry of ``lib``, or the VM fallback."""
    if lib is None:
        return _vm_function(fn)
    return CFunction((fn.name() + "_flat", lib))


@dataclass(frozen=True)
class WindowModel:
    """Compiled window model of one (formulation, horizon).

    Attributes:
        nx, nu, nz, horizon: sizes.
        feasible: the node feasible set.
        rinv: (nz, nz) inverse measurement covariance (rad^-2 for tilt).
        window: C function of :func:`_window_function`.
        node: C function of :func:`_node_function`.
        output: C function of the formulation's ``output_sym``.
        ny: number of outputs; wrapped: indices of the outputs that are wrapped angles.
        compiled: True if the model runs as compiled C (else through CasADi's VM).
    """

    nx: int
    nu: int
    nz: int
    horizon: int
    feasible: Feasible
    rinv: FloatArray
    window: Any  # ctypes function pointer (CFunction)
    node: Any
    output: Any  # formulation.output_sym: state -> the formulation's outputs
    compiled: bool
    ny: int = 5
    wrapped: tuple[int, ...] = (4,)

    @property
    def window_size(self) -> int:
        n, nx, nz = self.horizon, self.nx, self.nz
        return nz * n + nz * nx * n + nx * (n - 1) + nx * nx * (n - 1) + nx * nx * n

    def evaluate_node(
        self,
        x: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray | None = None,
        mask: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(f(x, u, dt), df/dx, -dr(z, x)/dx, r(z, x))`` at one node."""
        return NodeEvaluator(self).evaluate(x, u, dt, z, mask)


class NodeEvaluator:
    """Reusable buffers for :meth:`WindowModel.evaluate_node` (one per estimator)."""

    def __init__(self, model: WindowModel) -> None:
        nx, nz = model.nx, model.nz
        self._fn = model.node
        self._x = np.zeros(nx)
        self._u = np.zeros(model.nu)
        self._dt = np.zeros(1)
        self._z = np.zeros(nz)
        self._m = np.ones(nz)
        self._out = np.empty(nx + nx * nx + nz * nx + nz)
        self._ptrs = np.array(
            [
                self._x.ctypes.data,
                self._u.ctypes.data if model.nu else 0,
                self._dt.ctypes.data,
                self._z.ctypes.data,
                self._m.ctypes.data,
            ],
            dtype=np.uintp,
        )
        self._ofn = model.output
        self._ox = np.zeros(nx)
        self._oout = np.empty(model.ny)
        self._wrapped = list(model.wrapped)
        self._optrs = np.array([self._ox.ctypes.data], dtype=np.uintp)
        k = nx + nx * nx
        self._views = (
            self._out[:nx],
            self._out[nx:k].reshape(nx, nx),
            self._out[k : k + nz * nx].reshape(nz, nx),
            self._out[k + nz * nx :],
        )

    def evaluate(
        self,
        x: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray | None = None,
        mask: FloatArray | None = None,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(f(x, u, dt), df/dx, -dr(z, x)/dx, r(z, x))``, copies: (nx,), (nx, nx),
        (nz, nx), (nz,). ``z`` matters for the last two only (zeros when omitted);
        ``mask`` (nz,) zeroes the components of sensors that dropped out."""
        self._x[:] = x
        self._u[:] = u
        self._dt[0] = dt
        self._z[:] = 0.0 if z is None else z
        self._m[:] = 1.0 if mask is None else mask
        if self._fn(self._ptrs.ctypes.data, self._out.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        f, F, H, r = self._views
        return f.copy(), F.copy(), H.copy(), r.copy()

    def arrival_step(
        self,
        x: FloatArray,
        P: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray,
        mask: FloatArray,
        R: FloatArray,
        Q: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """One EKF step of the arrival prior in one compiled call: update with ``z``
        (its valid components, ``mask``; none: prediction only), predict with
        ``(u, dt)``. Returns ``(x+, P+, P+^-1)``; the same
        equations as :func:`arrival_update` then :func:`arrival_predict`."""
        self._u[:] = u
        self._dt[0] = dt
        self._z[:] = z
        self._m[:] = mask
        valid = bool(np.any(mask))
        return _arrival_step(
            self._fn, self._ptrs, self._out, self._x, x, P, valid, R, Q, self._x.shape[0]
        )

    def ekf_step(
        self,
        x: FloatArray,
        P: FloatArray,
        u: FloatArray,
        dt: float,
        z: FloatArray,
        mask: FloatArray,
        R: FloatArray,
        Q: FloatArray,
    ) -> tuple[FloatArray, FloatArray]:
        """One EKF step in one compiled call: predict with ``(u, dt)``, then update with
        the valid components of ``z`` (``mask``); the equations of
        :func:`~continuum_mhe.estimators.kalman.ekf_predict` and ``ekf_update``."""
        self._u[:] = u
        self._dt[0] = dt
        self._z[:] = np.where(mask > 0, z, 0.0)
        self._m[:] = mask
        return _ekf_step(
            self._fn, self._ptrs, self._out, self._x, x, P, bool(np.any(mask)), R, Q, len(x)
        )

    def output(self, x: FloatArray) -> FloatArray:
        """The outputs of state ``x`` (compiled ``output_sym``; wrapped angles in
        ``[-pi, pi)`` as :meth:`Formulation.output` does)."""
        self._ox[:] = x
        if self._ofn(self._optrs.ctypes.data, self._oout.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        y = self._oout.copy()
        for i in self._wrapped:
            y[i] = (y[i] + np.pi) % (2 * np.pi) - np.pi
        return y


@lru_cache(maxsize=32)
def build_window_model(formulation: Formulation, horizon: int, compile: bool = True) -> WindowModel:
    """Build (and compile, if possible) the window model. Cached per arguments."""
    win, node = _window_function(formulation, horizon), _node_function(formulation)
    xo = ca.SX.sym("x", formulation.nx)
    out = ca.Function("mhe_output", [xo], [ca.densify(formulation.output_sym(xo))])
    lib = _compile(_c_source((win, node, out))) if compile else None
    return WindowModel(
        nx=formulation.nx,
        nu=formulation.nu,
        nz=formulation.nz,
        horizon=horizon,
        feasible=feasible_set(formulation),
        rinv=np.asarray(np.linalg.inv(formulation.meas_cov()), dtype=np.float64),
        window=_c_function(win, lib),
        node=_c_function(node, lib),
        output=_c_function(out, lib),
        compiled=lib is not None,
        ny=formulation.ny,
        wrapped=tuple(i for i, o in enumerate(formulation.outputs) if o.wrapped),
    )


# --- numerical kernels (numba) ------------------------------------------------------


@numba.njit(cache=True)
def _assemble(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, lam, ball_idx, D, E, g):
    """Gauss-Newton Hessian blocks ``D`` (diagonal), ``E`` (``(i, i+1)``), exact
    gradient ``g`` and the cost; ``lam`` (n, nb) adds each ball's curvature
    ``2 lam_b I_{S_b}``."""
    n, nx = X.shape
    D[:] = 0.0
    E[:] = 0.0
    g[:] = 0.0
    cost = 0.0
    nz = R.shape[1]
    wr = np.empty(nz)
    qw = np.empty(nx)
    qf = np.empty((nx, nx))
    e = np.empty(nx)
    wj = np.empty((nz, nx))
    for i in range(n):
        m = zmask[i]
        if m != 0.0:
            for a in range(nz):
                s = 0.0
                for b in range(nz):
                    s += rinv[a, b] * R[i, b]
                wr[a] = s
                cost += 0.5 * m * R[i, a] * s
                for k in range(nx):
                    s = 0.0
                    for b in range(nz):
                        s += rinv[a, b] * JR[i, b, k]
                    wj[a, k] = s
            for j in range(nx):
                s = 0.0
                for a in range(nz):
                    s += JR[i, a, j] * wr[a]
                g[i, j] += m * s
                for k in range(nx):
                    s = 0.0
                    for a in range(nz):
                        s += JR[i, a, j] * wj[a, k]
                    D[i, j, k] += m * s
        for j in range(nx):
            e[j] = X[i, j] - xbar[j]
        for j in range(nx):
            s = 0.0
            for k in range(nx):
                s += arrival[i, j, k] * e[k]
                D[i, j, k] += arrival[i, j, k]
            g[i, j] += s
            cost += 0.5 * e[j] * s
        if i < n - 1:
            for j in range(nx):
                s = 0.0
                for k in range(nx):
                    s += qinv[i, j, k] * W[i, k]
                qw[j] = s
                cost += 0.5 * W[i, j] * s
            for j in range(nx):
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += qinv[i, j, a] * FJ[i, a, k]
                    qf[j, k] = s
            for j in range(nx):
                s = 0.0
                for a in range(nx):
                    s += FJ[i, a, j] * qw[a]
                g[i, j] -= s
                g[i + 1, j] += qw[j]
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += FJ[i, a, j] * qf[a, k]
                    D[i, j, k] += s
                    D[i + 1, j, k] += qinv[i, j, k]
                    E[i, j, k] = -qf[k, j]
    for i in range(n):
        for bb in range(ball_idx.shape[0]):
            if lam[i, bb] > 0.0:
                for s_ in ball_idx[bb]:
                    D[i, s_, s_] += 2.0 * lam[i, bb]
    return cost


@numba.njit(cache=True)
def _matvec(D, E, v, out):
    """``out = H v`` for the symmetric block-tridiagonal ``H = (D, E)``."""
    n, nx = v.shape
    for i in range(n):
        for j in range(nx):
            s = 0.0
            for k in range(nx):
                s += D[i, j, k] * v[i, k]
                if i < n - 1:
                    s += E[i, j, k] * v[i + 1, k]
                if i > 0:
                    s += E[i - 1, k, j] * v[i - 1, k]
            out[i, j] = s


@numba.njit(cache=True)
def _btd_solve(D, E, b, L, M, y):
    """Solve ``H y = b`` by block-tridiagonal Cholesky ``H = L L^T``; False if not PD.

    ``L`` (n, nx, nx) holds the diagonal factors, ``M`` (n-1, nx, nx) the sub-diagonal
    blocks ``M_i = E_i^T L_i^-T``.
    """
    n, nx = b.shape
    a = np.empty((nx, nx))
    for i in range(n):
        for j in range(nx):
            for k in range(nx):
                s = D[i, j, k]
                if i > 0:
                    for c in range(nx):
                        s -= M[i - 1, j, c] * M[i - 1, k, c]
                a[j, k] = s
        for j in range(nx):  # dense Cholesky of the nx x nx block
            s = a[j, j]
            for c in range(j):
                s -= L[i, j, c] * L[i, j, c]
            if not s > 0.0:
                return False
            L[i, j, j] = np.sqrt(s)
            for k in range(j + 1, nx):
                t = a[k, j]
                for c in range(j):
                    t -= L[i, k, c] * L[i, j, c]
                L[i, k, j] = t / L[i, j, j]
            for k in range(j):
                L[i, k, j] = 0.0
        if i < n - 1:  # M_i L_i^T = E_i^T, row by row (forward substitution)
            for r in range(nx):
                for j in range(nx):
                    t = E[i, j, r]
                    for c in range(j):
                        t -= M[i, r, c] * L[i, j, c]
                    M[i, r, j] = t / L[i, j, j]
    for i in range(n):  # L z = b
        for j in range(nx):
            t = b[i, j]
            if i > 0:
                for c in range(nx):
                    t -= M[i - 1, j, c] * y[i - 1, c]
            for c in range(j):
                t -= L[i, j, c] * y[i, c]
            y[i, j] = t / L[i, j, j]
    for i in range(n - 1, -1, -1):  # L^T y = z
        for j in range(nx - 1, -1, -1):
            t = y[i, j]
            if i < n - 1:
                for c in range(nx):
                    t -= M[i, c, j] * y[i + 1, c]
            for c in range(j + 1, nx):
                t -= L[i, c, j] * y[i, c]
            y[i, j] = t / L[i, j, j]
    return True


@numba.njit(cache=True)
def _householder(nrm, ball_idx, T):
    """Symmetric orthogonal ``T`` with ``T n = -+e_c``; returns the pivot coordinate c."""
    nx = T.shape[0]
    for j in range(nx):
        for k in range(nx):
            T[j, k] = 1.0 if j == k else 0.0
    piv = ball_idx[0]
    for s_ in ball_idx:
        if abs(nrm[s_]) > abs(nrm[piv]):
            piv = s_
    sg = 1.0 if nrm[piv] >= 0.0 else -1.0
    v = np.zeros(nx)
    for s_ in ball_idx:
        v[s_] = nrm[s_]
    v[piv] += sg
    vv = 0.0
    for j in range(nx):
        vv += v[j] * v[j]
    for j in range(nx):
        for k in range(nx):
            T[j, k] -= 2.0 * v[j] * v[k] / vv
    return piv


@numba.njit(cache=True)
def _eqp(D, E, grad, wbox, wball, nrm, ball_idx, p, Dt, Et, b, L, M, T):
    """Equality-constrained Newton step ``H p = -grad`` on the working set.

    Box-fixed coordinates get ``p = 0``; each active ball ``b`` of a node gets
    ``n_b . p = 0``, eliminated by a Householder reflection on its coordinates. The
    balls of a node are disjoint, so their reflections commute and their product ``T``
    is symmetric and orthogonal; the blocks keep their structure.
    """
    n, nx = grad.shape
    nb = ball_idx.shape[0]
    anyb = np.zeros(n, dtype=np.bool_)
    fixed = np.zeros((n, nx), dtype=np.bool_)
    tmp = np.empty((nx, nx))
    Tb = np.empty((nx, nx))
    for i in range(n):
        for bb in range(nb):
            if wball[i, bb] != 0:
                if not anyb[i]:
                    for j in range(nx):
                        for k in range(nx):
                            T[i, j, k] = 1.0 if j == k else 0.0
                    anyb[i] = True
                piv = _householder(nrm[i, bb], ball_idx[bb], Tb)
                fixed[i, piv] = True
                for j in ball_idx[bb]:
                    for k in ball_idx[bb]:
                        T[i, j, k] = Tb[j, k]
    for i in range(n):
        if anyb[i]:
            for j in range(nx):
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += D[i, j, a] * T[i, a, k]
                    tmp[j, k] = s
            for j in range(nx):
                for k in range(nx):
                    s = 0.0
                    for a in range(nx):
                        s += T[i, j, a] * tmp[a, k]
                    Dt[i, j, k] = s
                s = 0.0
                for a in range(nx):
                    s += T[i, j, a] * grad[i, a]
                b[i, j] = -s
        else:
            for j in range(nx):
                b[i, j] = -grad[i, j]
                for k in range(nx):
                    Dt[i, j, k] = D[i, j, k]
        if i < n - 1:
            for j in range(nx):
                for k in range(nx):
                    Et[i, j, k] = E[i, j, k]
            if anyb[i]:
                for j in range(nx):
                    for k in range(nx):
                        s = 0.0
                        for a in range(nx):
                            s += T[i, j, a] * Et[i, a, k]
                        tmp[j, k] = s
                Et[i] = tmp
            if anyb[i + 1]:
                for j in range(nx):
                    for k in range(nx):
                        s = 0.0
                        for a in range(nx):
                            s += Et[i, j, a] * T[i + 1, a, k]
                        tmp[j, k] = s
                Et[i] = tmp
    for i in range(n):
        for c in range(nx):
            if wbox[i, c] != 0 or fixed[i, c]:
                for k in range(nx):
                    Dt[i, c, k] = 0.0
                    Dt[i, k, c] = 0.0
                    if i < n - 1:
                        Et[i, c, k] = 0.0
                    if i > 0:
                        Et[i - 1, k, c] = 0.0
                Dt[i, c, c] = 1.0
                b[i, c] = 0.0
    if not _btd_solve(Dt, Et, b, L, M, p):
        return False
    for i in range(n):
        if anyb[i]:
            for j in range(nx):
                s = 0.0
                for a in range(nx):
                    s += T[i, j, a] * p[i, a]
                tmp[0, j] = s
            for j in range(nx):
                p[i, j] = tmp[0, j]
        for c in range(nx):
            if wbox[i, c] != 0:
                p[i, c] = 0.0
    return True


@numba.njit(cache=True)
def _solve_qp(X, D, E, g, lo, hi, ball_idx, ball_r2, max_it, d, lam):
    """Primal active-set solution ``d`` of the SQP subproblem at ``X``.

    ``min 1/2 d^T H d + g^T d`` s.t. ``lo <= X + d <= hi`` and every ball linearised at
    ``X``. Starts from ``d = 0`` with the constraints active at ``X``. On success
    ``lam`` (n, nb) holds the ball multipliers. Returns ``(status, iterations, number
    of active constraints)``.
    """
    n, nx = X.shape
    nb = ball_idx.shape[0]
    wbox = np.zeros((n, nx), dtype=np.int8)
    wball = np.zeros((n, max(nb, 1)), dtype=np.int8)
    nrm = np.zeros((n, max(nb, 1), nx))
    gnorm = np.zeros((n, max(nb, 1)))
    slack = np.zeros((n, max(nb, 1)))
    for i in range(n):
        for j in range(nx):
            if X[i, j] <= lo[j]:
                wbox[i, j] = -1
            elif X[i, j] >= hi[j]:
                wbox[i, j] = 1
        for bb in range(nb):
            q = 0.0
            for s_ in ball_idx[bb]:
                q += X[i, s_] * X[i, s_]
            if q > 0.0:
                rq = np.sqrt(q)
                for s_ in ball_idx[bb]:
                    nrm[i, bb, s_] = X[i, s_] / rq
                gnorm[i, bb] = 2.0 * rq
                slack[i, bb] = max(ball_r2[bb] - q, 0.0) / gnorm[i, bb]
                if q >= ball_r2[bb] * (1.0 - 1e-12):
                    wball[i, bb] = 1
                    slack[i, bb] = 0.0
    gscale = 1.0
    for i in range(n):
        for j in range(nx):
            gscale = max(gscale, abs(g[i, j]))
    mu_tol = 1e-12 * gscale
    d[:] = 0.0
    p = np.empty((n, nx))
    grad = np.empty((n, nx))
    Dt = np.empty_like(D)
    Et = np.empty_like(E)
    b = np.empty((n, nx))
    L = np.empty_like(D)
    M = np.empty_like(E)
    T = np.empty_like(D)
    for it in range(max_it):
        nfix = np.count_nonzero(wbox) + np.count_nonzero(wball)
        if it == 0:  # d = 0
            grad[:] = g
        else:
            _matvec(D, E, d, grad)
            for i in range(n):
                for j in range(nx):
                    grad[i, j] += g[i, j]
        if nfix == 0:  # nothing fixed: the plain Newton system
            for i in range(n):
                for j in range(nx):
                    b[i, j] = -grad[i, j]
            if not _btd_solve(D, E, b, L, M, p):
                return NOT_PD, it, 0
        elif not _eqp(D, E, grad, wbox, wball, nrm, ball_idx, p, Dt, Et, b, L, M, T):
            return NOT_PD, it, 0
        alpha = 1.0
        kind, bi, bj = 0, -1, -1
        for i in range(n):
            for j in range(nx):
                if wbox[i, j] == 0:
                    pij = p[i, j]
                    if pij > 0.0 and hi[j] < np.inf:
                        a = max((hi[j] - X[i, j] - d[i, j]) / pij, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, 1, i, j
                    elif pij < 0.0 and lo[j] > -np.inf:
                        a = max((lo[j] - X[i, j] - d[i, j]) / pij, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, -1, i, j
            for bb in range(nb):
                if wball[i, bb] == 0 and gnorm[i, bb] > 0.0:
                    sp = 0.0
                    sd = 0.0
                    for s_ in ball_idx[bb]:
                        sp += nrm[i, bb, s_] * p[i, s_]
                        sd += nrm[i, bb, s_] * d[i, s_]
                    if sp > 0.0:
                        a = max((slack[i, bb] - sd) / sp, 0.0)
                        if a < alpha:
                            alpha, kind, bi, bj = a, 2, i, bb
        for i in range(n):
            for j in range(nx):
                d[i, j] += alpha * p[i, j]
        if kind != 0:
            if kind == 2:
                wball[bi, bj] = 1
            else:
                wbox[bi, bj] = kind
                d[bi, bj] = (hi[bj] if kind == 1 else lo[bj]) - X[bi, bj]
            continue
        # at the minimiser on the working set: check the multipliers' signs
        if nfix == 0:
            lam[:] = 0.0
            return CONVERGED, it + 1, 0
        _matvec(D, E, d, grad)
        worst, wi, wj = -mu_tol, -1, 0
        for i in range(n):
            for j in range(nx):
                if wbox[i, j] != 0:
                    mu = -grad[i, j] - g[i, j] if wbox[i, j] == 1 else grad[i, j] + g[i, j]
                    if mu < worst:
                        worst, wi, wj = mu, i, j
            for bb in range(nb):
                lam[i, bb] = 0.0
                if wball[i, bb] != 0:
                    s = 0.0
                    for s_ in ball_idx[bb]:
                        s += (grad[i, s_] + g[i, s_]) * nrm[i, bb, s_]
                    lam[i, bb] = -s / gnorm[i, bb]
                    if lam[i, bb] < worst:
                        worst, wi, wj = lam[i, bb], i, -1 - bb
        if wi < 0:
            return CONVERGED, it + 1, np.count_nonzero(wbox) + np.count_nonzero(wball)
        if wj < 0:
            wball[wi, -1 - wj] = 0
        else:
            wbox[wi, wj] = 0
    return QP_FAILED, max_it, 0


@numba.njit(cache=True)
def _project(X, lo, hi, ball_idx, ball_r2):
    """Project each node onto the box and the balls, in place (bounds hold exactly)."""
    n, nx = X.shape
    for i in range(n):
        for j in range(nx):
            X[i, j] = min(max(X[i, j], lo[j]), hi[j])
        for bb in range(ball_idx.shape[0]):
            r2 = ball_r2[bb]
            q = 0.0
            for s_ in ball_idx[bb]:
                q += X[i, s_] * X[i, s_]
            if q > r2:
                c = np.sqrt(r2 / q)
                for _ in range(4):  # rounding: shrink by ulps until it holds exactly
                    q = 0.0
                    for s_ in ball_idx[bb]:
                        q += (c * X[i, s_]) ** 2
                    if q <= r2:
                        break
                    c = np.nextafter(c, 0.0) * (1.0 - 2e-16)
                for s_ in ball_idx[bb]:
                    X[i, s_] *= c


@numba.njit(cache=True)
def arrival_update(x, P, r, H, R):
    """EKF measurement update of the arrival prior, Joseph form: ``(x, P)``.

    Same equations as :func:`continuum_mhe.estimators.kalman.ekf_update`, with the
    residual ``r`` (nz,) and ``H = -dr/dx`` (nz, nx) from
    :meth:`WindowModel.evaluate_node`.
    """
    nx = P.shape[0]
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    ikh = np.eye(nx) - K @ H
    return x + K @ r, ikh @ P @ ikh.T + K @ R @ K.T


@numba.njit(cache=True)
def _arrival_step(fn, ptrs, out, xin, x, P, valid, R, Q, nx):
    """:meth:`NodeEvaluator.arrival_step` in one compiled call (two model calls)."""
    nz = R.shape[0]
    k = nx + nx * nx
    if valid:
        xin[:] = x
        if fn(ptrs.ctypes.data, out.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        H = out[k : k + nz * nx].copy().reshape(nz, nx)
        r = out[k + nz * nx : k + nz * nx + nz].copy()
        x, P = arrival_update(x, P, r, H, R)
    xin[:] = x
    if fn(ptrs.ctypes.data, out.ctypes.data) != 0:
        raise RuntimeError("model evaluation failed")
    xn = out[:nx].copy()
    F = out[nx:k].copy().reshape(nx, nx)
    P, Pinv = arrival_predict(P, F, Q)
    return xn, P, Pinv


@numba.njit(cache=True)
def _ekf_step(fn, ptrs, out, xin, x, P, valid, R, Q, nx):
    """:meth:`NodeEvaluator.ekf_step`: EKF prediction, then (if ``valid``) the update on
    the masked residual, in one compiled call (two model calls)."""
    nz = R.shape[0]
    k = nx + nx * nx
    xin[:] = x
    if fn(ptrs.ctypes.data, out.ctypes.data) != 0:
        raise RuntimeError("model evaluation failed")
    xn = out[:nx].copy()
    F = out[nx:k].copy().reshape(nx, nx)
    P = F @ P @ F.T + Q
    if valid:
        xin[:] = xn
        if fn(ptrs.ctypes.data, out.ctypes.data) != 0:
            raise RuntimeError("model evaluation failed")
        H = out[k : k + nz * nx].copy().reshape(nz, nx)
        r = out[k + nz * nx : k + nz * nx + nz].copy()
        xn, P = arrival_update(xn, P, r, H, R)
    return xn, P


@numba.njit(cache=True)
def arrival_predict(P, F, Q):
    """EKF covariance prediction of the arrival prior: ``(P, P^-1)``."""
    P = F @ P @ F.T + Q
    P = 0.5 * (P + P.T)
    return P, np.linalg.inv(P)


# --- the window solve -----------------------------------------------------------------


@numba.njit(cache=True)
def _evaluate(fn, ptrs, out, X, zmask, rinv, qinv, xbar, arrival, lam, bidx, D, E, g):
    """Evaluate the model at ``X`` (one C call) and assemble; inf cost on failure."""
    n, nx = X.shape
    nz = rinv.shape[0]
    if fn(ptrs.ctypes.data, out.ctypes.data) != 0:
        return np.inf
    o1, o2, o3 = nz * n, nz * n + nz * nx * n, nz * n + nz * nx * n + nx * (n - 1)
    o4 = o3 + nx * nx * (n - 1)
    R = out[:o1].reshape(n, nz)
    JR = out[o1:o2].reshape(n, nz, nx)
    W = out[o2:o3].reshape(n - 1, nx)
    FJ = out[o3:o4].reshape(n - 1, nx, nx)
    return _assemble(X, R, JR, W, FJ, zmask, rinv, qinv, xbar, arrival, lam, bidx, D, E, g)


@numba.njit(cache=True)
def _add_curvature(out, zmask, D, sign):
    """``D_i += sign * m_i S_i``: the measurement residuals' second-order Hessian term
    (exact Newton instead of Gauss-Newton); ``S`` is the model's last output."""
    n, nx = D.shape[0], D.shape[1]
    S = out[out.shape[0] - n * nx * nx :].reshape(n, nx, nx)
    for i in range(n):
        if zmask[i] != 0.0:
            for j in range(nx):
                for k in range(nx):
                    D[i, j, k] += sign * zmask[i] * S[i, j, k]


@numba.njit(cache=True)
def _sqp(
    fn,
    ptrs,
    Xb,
    out,
    zmask,
    rinv,
    qinv,
    xbar,
    arrival,
    lo,
    hi,
    bidx,
    r2,
    lam,
    max_iter,
    step_tol,
    err_tol,
    max_qp,
    newton,
    D,
    E,
    g,
    d,
    lam_qp,
):
    """Newton-type SQP on two buffers (current, trial); returns
    ``(outcome, iterations, step, cost, index of the buffer with the answer)``.

    Certified when the QP step ``d`` is below ``step_tol``, or, with no constraint
    active, when the observed contraction ``rho = |d_k| / |d_k-1| <= 1/2`` of two
    full steps bounds the error of ``X_k + d_k`` by ``rho / (1 - rho) |d_k| <= err_tol``.
    The answer is then the projection of ``X_k + d_k`` (not evaluated again);
    ``cost`` is at ``X_k``.
    """
    cur = 0
    _project(Xb[0], lo, hi, bidx, r2)
    cost = _evaluate(
        fn, ptrs[0], out[0], Xb[0], zmask, rinv, qinv, xbar, arrival, lam, bidx, D[0], E[0], g[0]
    )
    exact = newton  # exact Hessian at the current iterate (else Gauss-Newton)
    if exact:
        _add_curvature(out[0], zmask, D[0], 1.0)
    step = np.inf
    prev = np.inf  # previous full step (inf after a shortened one)
    for it in range(1, max_iter + 1):
        if not np.isfinite(cost):
            return LINE_SEARCH_FAILED, it, step, cost, cur
        status, _, active = _solve_qp(
            Xb[cur], D[cur], E[cur], g[cur], lo, hi, bidx, r2, max_qp, d, lam_qp
        )
        if status == NOT_PD and exact:  # indefinite: fall back to Gauss-Newton here
            _add_curvature(out[cur], zmask, D[cur], -1.0)
            exact = False
            status, _, active = _solve_qp(
                Xb[cur], D[cur], E[cur], g[cur], lo, hi, bidx, r2, max_qp, d, lam_qp
            )
        if status != CONVERGED:
            return status, it, step, cost, cur
        step = np.max(np.abs(d))
        tr = 1 - cur
        contracted = active == 0 and prev < np.inf and step <= 0.5 * prev
        if step <= step_tol or (contracted and step * step / (prev - step) <= err_tol):
            lam[:] = lam_qp
            Xb[tr] = Xb[cur] + d
            _project(Xb[tr], lo, hi, bidx, r2)
            return CONVERGED, it, step, cost, tr
        alpha = 1.0
        slack = 1e-13 * (1.0 + abs(cost))
        accepted = False
        for _ in range(30):
            Xb[tr] = Xb[cur] + alpha * d
            _project(Xb[tr], lo, hi, bidx, r2)
            ct = _evaluate(
                fn,
                ptrs[tr],
                out[tr],
                Xb[tr],
                zmask,
                rinv,
                qinv,
                xbar,
                arrival,
                lam_qp,
                bidx,
                D[tr],
                E[tr],
                g[tr],
            )
            if ct <= cost + 1e-4 * np.sum(g[cur] * (Xb[tr] - Xb[cur])) + slack:
                accepted = True
                exact = newton
                if exact:
                    _add_curvature(out[tr], zmask, D[tr], 1.0)
                break
            alpha *= 0.5
        if not accepted:
            return LINE_SEARCH_FAILED, it, step, cost, cur
        prev = step if alpha == 1.0 else np.inf
        cur, cost = tr, ct
        lam[:] = lam_qp
    return MAX_ITER, max_iter, step, cost, cur


@dataclass(frozen=True)
class FastResult:
    """Outcome of :func:`solve_window`.

    Attributes:
        X: (N, nx) the answer (see :func:`_sqp`); feasible exactly.
        converged: True if the KKT certificate holds at ``X``.
        outcome: one of :data:`OUTCOMES`.
        iterations: SQP iterations (QP solves).
        step: max-norm of the last QP step, state units.
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


def _pointers(
    X: FloatArray, z: FloatArray, m: FloatArray, u: FloatArray, dt: FloatArray
) -> NDArray[np.uintp]:
    return np.array(
        [
            X.ctypes.data,
            z.ctypes.data,
            m.ctypes.data,
            u.ctypes.data if u.size else 0,
            dt.ctypes.data,
        ],
        dtype=np.uintp,
    )


class Workspace:
    """Buffers of :func:`solve_window`, reusable across windows of one model.

    The window data are copied into fixed buffers, so the C model's argument
    pointers are computed once.
    """

    def __init__(self, model: WindowModel) -> None:
        n, nx, nz, nu = model.horizon, model.nx, model.nz, model.nu
        self.z = np.zeros((n, nz))
        self.m = np.zeros((n, nz))
        self.u = np.zeros((n - 1, nu))
        self.dt = np.zeros(n - 1)
        self.Xb = np.empty((2, n, nx))
        self.out = np.empty((2, model.window_size))
        self.D = np.empty((2, n, nx, nx))
        self.E = np.empty((2, n - 1, nx, nx))
        self.g = np.empty((2, n, nx))
        self.d = np.empty((n, nx))
        self.lam_qp = np.zeros((n, len(model.feasible.ball_r2)))
        self.ptrs = np.stack([_pointers(x, self.z, self.m, self.u, self.dt) for x in self.Xb])


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
    fs, n = model.feasible, model.horizon
    ws = workspace or Workspace(model)
    ws.z[:] = problem.z
    ws.m[:] = problem.zmask
    ws.u[:] = problem.u
    ws.dt[:] = problem.dt
    ws.Xb[0] = X0
    nb = len(fs.ball_r2)
    lam = np.zeros((n, nb)) if lam0 is None else np.array(lam0, dtype=float).reshape(n, nb)
    node_mask = np.any(ws.m != 0.0, axis=1).astype(np.float64)  # the residuals are masked
    outcome, it, step, cost, cur = _sqp(
        model.window, ws.ptrs, ws.Xb, ws.out, node_mask, model.rinv, problem.qinv,
        problem.xbar, problem.arrival, fs.lo, fs.hi, fs.ball_idx, fs.ball_r2, lam,
        opt.max_iter, opt.step_tol, opt.err_tol, opt.max_qp_iter, opt.newton, ws.D, ws.E,
        ws.g, ws.d, ws.lam_qp,
    )  # fmt: skip
    return FastResult(
        X=ws.Xb[cur].copy(),
        converged=outcome == CONVERGED,
        outcome=OUTCOMES[outcome],
        iterations=int(it),
        step=float(step),
        cost=float(cost),
        lam=lam,
    )


def window_cost(model: WindowModel, problem: WindowProblemLike, X: FloatArray) -> float:
    """The window cost at ``X`` (N, nx), from the compiled model."""
    n, nx = model.horizon, model.nx
    Xc = np.array(X, dtype=float)
    z, u = np.ascontiguousarray(problem.z, float), np.ascontiguousarray(problem.u, float)
    dt = np.ascontiguousarray(problem.dt, float)
    m = np.ascontiguousarray(problem.zmask, float)
    node_mask = np.any(m != 0.0, axis=1).astype(np.float64)
    nb = len(model.feasible.ball_r2)
    return float(
        _evaluate(
            model.window, _pointers(Xc, z, m, u, dt), np.empty(model.window_size), Xc,
            node_mask, model.rinv, problem.qinv, problem.xbar, problem.arrival,
            np.zeros((n, nb)), model.feasible.ball_idx, np.empty((n, nx, nx)),
            np.empty((n - 1, nx, nx)), np.empty((n, nx)),
        )
    )  # fmt: skip
