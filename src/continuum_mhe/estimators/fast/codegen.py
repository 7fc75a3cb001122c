"""The fast backend's model: CasADi functions from the formulation, C code, compiled once.

Nothing of the model is written a second time: :func:`window_function` and
:func:`node_function` are built from the formulation's symbolic methods
(``measurement_residual_sym``, ``transition_sym``, ``output_sym``). CasADi's code
generator turns them into C, compiled with the system C compiler and cached on disk
(``$CONTINUUM_MHE_CACHE``, else ``~/.cache/continuum-mhe``), keyed by a hash of the
source, with a sha256 of each library stored beside it and checked before loading (a
truncated or corrupted library would crash the process). Without a working compiler the
same functions run in CasADi's virtual machine behind the same C calling convention
(a ctypes callback): identical answers, about 10x slower, said once
(:class:`BackendFallbackWarning`).

Every model evaluation is ``int f(const double** inputs, double* out)`` (:data:`CFunction`),
0 on success; :func:`failure_message` gives the reason of a failed one.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import signal
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from continuum_mhe.estimators.fast.warmup import say_once
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.numba_cache import writable


def transition_is_linear(formulation: Formulation) -> bool:
    """True if the formulation's transition is affine in the state (its Jacobian
    ``df/dx`` does not depend on ``x``): then the window's exact Hessian is the
    measurement terms' Newton Hessian the fast backend forms, and Newton's quadratic rate
    applies (:func:`~continuum_mhe.estimators.fast.sqp.quadratic_rate`)."""
    f = formulation
    x, u, dt = ca.SX.sym("x", f.nx), ca.SX.sym("u", f.nu), ca.SX.sym("dt")
    return not ca.depends_on(ca.jacobian(f.transition_sym(x, u, dt), x), x)


def node_pieces(formulation: Formulation) -> tuple[ca.Function, ca.Function]:
    """``meas: (x, z, m) -> (r, JR, SR)`` and ``proc: (x, xn, u, dt) -> (W, FJ)``: one
    node's and one stage's part of :func:`window_function` (the layout described
    there); given to both :func:`window_function` and :func:`tail_function`, they
    compute each node with the same code."""
    f, nx, nu, nz = formulation, formulation.nx, formulation.nu, formulation.nz
    x, xn, z = ca.SX.sym("x", nx), ca.SX.sym("xn", nx), ca.SX.sym("z", nz)
    u, dt, mk = ca.SX.sym("u", nu), ca.SX.sym("dt"), ca.SX.sym("m", nz)
    r = mk * f.measurement_residual_sym(z, x)
    jr = ca.jacobian(r, x)
    rinv = np.linalg.inv(f.meas_cov())
    # second-order part of each block's Hessian, sum_a (R_b^-1 r_b)_a d2 r_a/dx2
    curv = []
    for b in f.measurement_blocks:
        rb, jb, wb = r[b.slice], jr[b.slice, :], ca.DM(rinv[b.slice, b.slice])
        curv.append(ca.vec(ca.hessian(0.5 * ca.bilin(wb, rb, rb), x)[0] - jb.T @ wb @ jb))
    meas = ca.Function("mhe_meas", [x, z, mk], [r, ca.vec(jr.T), ca.vertcat(*curv)])
    xf = f.transition_sym(x, u, dt)
    proc = ca.Function("mhe_proc", [x, xn, u, dt], [xn - xf, ca.vec(ca.jacobian(xf, x).T)])
    return meas, proc


NodePieces = tuple[ca.Function, ca.Function]


def window_function(
    formulation: Formulation, horizon: int, pieces: NodePieces | None = None
) -> ca.Function:
    """``(X, Z, M, U, DT) -> (R, JR, W, FJ, SR)`` for the whole window, in one call.

    Inputs (CasADi column-major): ``X`` (nx, N), ``Z`` (nz, N), ``M`` (nz, N) the 0/1
    measurement mask (a masked component has zero residual, Jacobian and curvature: a
    sensor that dropped out), ``U`` (nu, N-1), ``DT`` (1, N-1). Outputs: masked
    measurement residuals ``R`` (nz, N); their Jacobians
    ``JR`` (nz nx, N), each column the row-major ``dr/dx``; process residuals
    ``W = x_{i+1} - f(x_i, u_i, dt_i)`` (nx, N-1); ``FJ`` (nx^2, N-1), each column
    the row-major ``df/dx_i``; ``SR`` (nblocks nx^2, N), the second-order part of each
    measurement block's quadratic cost Hessian ``sum_a (R_b^-1 r_b)_a d2r_a/dx2`` per
    node (one per block, so that a robust loss can weight each block; ``R`` is
    block-diagonal). ``pieces``: :func:`node_pieces` (built here if None).
    """
    f, nx, nu, nz, n = formulation, formulation.nx, formulation.nu, formulation.nz, horizon
    meas, proc = pieces or node_pieces(f)
    # MX, so that the maps stay loops in the generated code (SX would unroll them)
    X, Z, M = ca.MX.sym("X", nx, n), ca.MX.sym("Z", nz, n), ca.MX.sym("M", nz, n)
    U, DT = ca.MX.sym("U", nu, n - 1), ca.MX.sym("DT", 1, n - 1)
    R, JR, SR = meas.map(n, "serial")(X, Z, M)
    W, FJ = proc.map(n - 1, "serial")(X[:, : n - 1], X[:, 1:], U, DT)
    outs = [ca.densify(v) for v in (R, JR, W, FJ, SR)]
    return ca.Function("mhe_window", [X, Z, M, U, DT], outs)


def tail_function(formulation: Formulation, pieces: NodePieces | None = None) -> ca.Function:
    """``(x_prev, x, z, m, u, dt) -> (r, JR, W, FJ, SR)``: :func:`window_function`'s
    outputs of one last node ``x`` and of the stage into it from ``x_prev`` (the same
    layout, one column each): what a window shifted by one sample lacks. ``pieces``:
    :func:`node_pieces`, the same as the window function's (built here if None)."""
    f, nx, nu, nz = formulation, formulation.nx, formulation.nu, formulation.nz
    meas, proc = pieces or node_pieces(f)
    xp, x, z = ca.MX.sym("xp", nx), ca.MX.sym("x", nx), ca.MX.sym("z", nz)
    mk, u, dt = ca.MX.sym("m", nz), ca.MX.sym("u", nu), ca.MX.sym("dt")
    r, jr, sr = meas(x, z, mk)
    w, fj = proc(xp, x, u, dt)
    outs = [ca.densify(v) for v in (r, jr, w, fj, sr)]
    return ca.Function("mhe_tail", [xp, x, z, mk, u, dt], outs)


def node_function(formulation: Formulation) -> ca.Function:
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


def c_source(fns: tuple[ca.Function, ...]) -> str:
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


def output_function(formulation: Formulation) -> ca.Function:
    """``x -> y``: the formulation's outputs (``output_sym``), dense."""
    x = ca.SX.sym("x", formulation.nx)
    return ca.Function("mhe_output", [x], [ca.densify(formulation.output_sym(x))])


def output_jacobian_function(formulation: Formulation) -> ca.Function:
    """``x -> dy/dx`` (ny, nx), dense: the formulation's ``output_jacobian``."""
    x = ca.SX.sym("x", formulation.nx)
    return ca.Function("mhe_output_jacobian", [x], [ca.densify(formulation.output_jacobian(x))])


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


@dataclass(frozen=True)
class Library:
    """Outcome of :func:`compile_library`: the loaded library, or why there is none.

    Attributes:
        lib: the shared library (None when it could not be built or loaded).
        reason: why not, in a few words (``"cc failed"``, ``"cc not found"``, ...);
            None with a library.
        fix: what the user can do about it; None with a library.
    """

    lib: ctypes.CDLL | None
    reason: str | None = None
    fix: str | None = None


def _compiler() -> str:
    return os.environ.get("CC") or "cc"


#: the C compiler's options for a model. ``-O3`` against ``-O2``: 6.8 to 6.3 us per
#: evaluation of the ``N = 30`` window, the same compile time (0.4 s for one tilt IMU,
#: 30 s for two raw IMUs with gyro biases and their own acceleration, on 2 cores) and the
#: same numbers. Part of the cache key.
CFLAGS = ("-O3", "-fPIC", "-shared")


#: said once, before the C compiler builds a model that is not in the cache (a new
#: robot, option set or horizon): on 2 cores 1 s for one tilt IMU, 34 s for two raw IMUs
#: with the gyro biases and the own acceleration
COMPILING_MODEL = (
    "compiling the C model of this robot and these options (first run only for them; "
    "up to a minute on 2 cores)"
)


def compile_library(src: str) -> Library:
    """Compile C source to a shared library, cached by content hash.

    Building one is said first, once per process (:data:`COMPILING_MODEL`, a
    :class:`~continuum_mhe.estimators.fast.warmup.CompileNotice`). A cached library is
    loaded only if it matches the sha256 stored beside it; on a
    mismatch (truncated, bit-flipped) it is rebuilt. The library and then its digest are
    each written atomically (temporary file, then rename), so a reader sees a digest
    only for a complete library.
    """
    key = hashlib.sha256((" ".join(CFLAGS) + "\n" + src).encode()).hexdigest()[:20]
    cc = _compiler()
    try:
        cache = _cache_dir()
        cache.mkdir(parents=True, exist_ok=True)
        lib = cache / f"mhe_{key}.so"
        if not _cached_library(lib):
            say_once(COMPILING_MODEL)
            with tempfile.TemporaryDirectory(dir=cache) as tmp:
                c_file = Path(tmp, "model.c")
                c_file.write_text(src)
                so_tmp = Path(tmp, "model.so")
                cmd = [cc, *CFLAGS, "-o", str(so_tmp), str(c_file), "-lm"]
                try:
                    proc = subprocess.Popen(
                        cmd,
                        stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL,
                        start_new_session=True,  # so that a timeout ends the compiler's children
                    )
                except OSError:
                    return Library(None, f"{cc} not found", "install gcc")
                with proc:
                    try:
                        if proc.wait(timeout=120) != 0:
                            return Library(None, f"{cc} failed", "install gcc")
                    except subprocess.TimeoutExpired:
                        os.killpg(proc.pid, signal.SIGKILL)
                        return Library(None, f"{cc} took over 120 s", "install gcc")
                digest_tmp = Path(tmp, "model.sha256")
                digest_tmp.write_text(_file_digest(so_tmp) + "\n")
                # the library first, then its digest, each atomically: a reader sees a
                # digest only for a complete library (a race ends in a rebuild, not a crash)
                os.replace(so_tmp, lib)
                os.replace(digest_tmp, lib.with_name(lib.name + ".sha256"))
        if not _cached_library(lib):
            return Library(None, f"the compiled model in {cache} fails its checksum",
                           f"remove {cache}")  # fmt: skip
        return Library(ctypes.CDLL(str(lib)))
    except OSError as exc:
        where = os.environ.get("CONTINUUM_MHE_CACHE") or "the model cache"
        folder = _cache_dir()
        fix = "set CONTINUUM_MHE_CACHE to a writable folder"
        if writable(folder):  # the folder is fine: one of its entries is damaged
            fix = f"a damaged cache entry: remove {folder / ('mhe_' + key + '.so')}*"
        return Library(
            None,
            f"cannot build or load the compiled model in {where}: {exc.strerror or exc}",
            fix,
        )


class BackendFallbackWarning(UserWarning):
    """The requested MHE backend or compiled model is not what runs (said once)."""


def announce_vm_fallback(library: Library) -> str:
    """Warn (:class:`BackendFallbackWarning`, one line under the CLI) that the model runs
    in CasADi's VM, once per process and reason; returns the notice (for the
    estimator's ``backend_note``)."""
    what = "no working C compiler" if library.fix == "install gcc" else "no compiled model"
    note = (
        f"{what} ({library.reason}): the fast MHE runs through CasADi's VM, "
        f"about 10x slower; {library.fix}"
    )
    say_once(note, BackendFallbackWarning, stacklevel=4)
    return note


#: C signature of every model evaluation: ``int f(const double** inputs, double* out)``.
CFunction = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p)


def _vm_function(fn: ca.Function) -> Any:
    """A C-callable that evaluates ``fn`` with CasADi's virtual machine (no compiler).

    A C callback must not raise: an exception returns 1, and its text is kept in the
    callable's ``errors`` (the last one) for :func:`failure_message`.
    """
    shapes = [fn.size_in(i) for i in range(fn.n_in())]
    total = sum(fn.nnz_out(i) for i in range(fn.n_out()))
    dptr = ctypes.POINTER(ctypes.c_double)
    errors: list[str] = []

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
            res = np.ctypeslib.as_array(ctypes.cast(out, dptr), shape=(total,))
            pos = 0
            for v in fn.call(args):
                flat = np.asarray(v, dtype=float).ravel(order="F")
                res[pos : pos + flat.size] = flat
                pos += flat.size
            return 0
        except Exception as exc:  # noqa: BLE001 - a C callback must not raise
            errors[:] = [f"{type(exc).__name__}: {' '.join(str(exc).split())}"]
            return 1

    cfn = CFunction(evaluate)
    cfn.errors = errors  # type: ignore[attr-defined]  # read by failure_message
    return cfn


def failure_message(fn: Any) -> str:
    """The message of a failed evaluation of ``fn`` (a :data:`CFunction`): with the
    exception text of CasADi's VM when it ran there."""
    errors = getattr(fn, "errors", None)
    if errors:
        return f"model evaluation failed: {errors[-1]}"
    return "model evaluation failed"


def c_function(fn: ca.Function, lib: ctypes.CDLL | None) -> Any:
    """The compiled ``<name>_flat`` entry of ``lib``, or the VM fallback."""
    if lib is None:
        return _vm_function(fn)
    return CFunction((fn.name() + "_flat", lib))
