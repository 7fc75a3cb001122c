"""Where the bare MHE kernel's time goes, part by part, from the CPU's cycle counter.

Runs :func:`~continuum_mhe.benchmark.kernels.run_mhe_kernel` (N = 30 unless given) on
the 20 s ``paper3d`` recording of ``tools/kernel_timing.py``, with instrumented copies
of :func:`~continuum_mhe.estimators.fast.step.advance_finish`, ``advance`` and
:func:`~continuum_mhe.estimators.fast.sqp._sqp`: the same source with cycle-counter
reads (``llvm.readcyclecounter``) around each part, summed per part. The counter's
rate is measured against ``time.perf_counter`` over 0.5 s. Prints the mean per sample
of each part (us), the kernel's mean inside numba, and the mean and median timed from
Python (the difference is the call), then what passing the MHE's and the EKF's
kernel arguments costs alone (a kernel that does nothing, given them) and the bare EKF
kernel's median::

    python tools/kernel_breakdown.py        # N = 30
    python tools/kernel_breakdown.py 100

The copies are made by text replacement of the kernels' source: when a kernel changes
so that a marker is no longer found, this script stops and names it.
"""

from __future__ import annotations

import inspect
import sys
import textwrap
import time
from typing import Any

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from continuum_mhe.benchmark.kernels import run_ekf_kernel, run_mhe_kernel
from continuum_mhe.estimators.fast import sqp as sqp_module
from continuum_mhe.estimators.fast import step as step_module
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.scenarios import simulate

TICKS = np.zeros(16, dtype=np.int64)  # cycles per part
CALLS = np.zeros(16, dtype=np.int64)  # and calls


@intrinsic
def _cycles(typingctx: Any) -> Any:
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        fnty = ir.FunctionType(ir.IntType(64), [])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.readcyclecounter")
        return builder.call(fn, [])

    return types.int64(), codegen


@intrinsic
def _int64_pointer(typingctx: Any, addr: Any) -> Any:
    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], ir.IntType(64).as_pointer())

    return types.CPointer(types.int64)(addr), codegen


PARTS = {
    1: "QP solves",
    2: "line-search evaluations (C model + assembly)",
    3: "first assembly (shifted outputs)",
    4: "arrival prior's EKF step",
    5: "window shifts and node mask",
    6: "initial guess (tail prediction)",
    7: "arrival weights, multipliers",
    8: "shifted model outputs (tail node)",
    9: "SQP (all of it)",
    10: "advance (all of it)",
    11: "covariance, outputs and their std",
    12: "advance_finish (all of it)",
}
_ARRAYS = (
    "    TK = numba.carray(_int64_pointer(TICKS_AT), (16,))\n"
    "    CN = numba.carray(_int64_pointer(CALLS_AT), (16,))\n"
)


def _timed(part: int) -> tuple[str, str]:
    return "    _t = _cycles()\n", f"    TK[{part}] += _cycles() - _t\n    CN[{part}] += 1\n"


def _instrument(kernel: Any, marks: list[tuple[str, str]], namespace: dict[str, Any]) -> Any:
    """``kernel``'s source with each ``old`` replaced by ``new``, compiled in
    ``namespace`` (the kernel's module's names and the counters)."""
    name = kernel.py_func.__name__
    src = textwrap.dedent(inspect.getsource(kernel.py_func))
    src = src.replace("@numba.njit(cache=True)\n", "")
    head, doc, body = src.split('"""', 2)
    src = head + '"""' + doc + '"""' + body.replace("\n", "\n" + _ARRAYS, 1)
    for old, new in marks:
        if old not in src:
            sys.exit(f"kernel_breakdown: {name} changed: marker {old!r} not found")
        src = src.replace(old, new, 1)
    ns = dict(namespace)
    exec(compile(src, f"<instrumented {name}>", "exec"), ns)
    return numba.njit(ns[name])


def _indent(code: str, by: int) -> str:
    return "".join(" " * by + ln + "\n" for ln in code.splitlines())


def _before(marker: str, code: str, by: int = 0) -> tuple[str, str]:
    """A replacement that puts ``code`` (indented by ``by`` more) before ``marker``."""
    return marker, _indent(code, by) + marker


def instrumented() -> Any:
    """The instrumented ``advance_finish`` (with ``advance`` and ``_sqp``)."""
    counters = {
        "_cycles": _cycles, "_int64_pointer": _int64_pointer,
        "TICKS_AT": TICKS.ctypes.data, "CALLS_AT": CALLS.ctypes.data, "numba": numba,
    }  # fmt: skip
    t = {p: _timed(p) for p in PARTS}  # (start, end) per part
    whole = {p: (a.replace("_t ", "_t0 "), b.replace("_t\n", "_t0\n")) for p, (a, b) in t.items()}
    sqp = _instrument(sqp_module._sqp, [
        _before("    if evaluated:  # out[0]", t[3][0]),
        _before("    _add_balls(D[0], Dgn[0], lam, bidx)\n", t[3][1]),
        _before("        status, _, active = solve_qp(\n", t[1][0], 4),
        _before("        if status == NOT_PD and exact:", t[1][1], 4),
        _before("            ct = _evaluate(", t[2][0], 8),
        _before("            _add_balls(D[tr], Dgn[tr], lam_qp, bidx)\n", t[2][1], 8),
    ], {**vars(sqp_module), **counters})  # fmt: skip
    advance = _instrument(step_module.advance, [
        _before("    xbar, P, Pinv, kk = prior\n", whole[10][0]),
        _before("    full = k == n", t[4][0]),
        _before("    _shift(z)\n", t[4][1] + t[5][0]),
        _before("    # initial guess", t[5][1] + t[6][0]),
        _before("    if not solve:\n", t[6][1] + t[7][0]),
        _before("    evaluated = b >= 0", t[7][1] + t[8][0]),
        _before("    res = _sqp(", t[8][1] + t[9][0]),
        _before("    if res[0] == CONVERGED:\n        last[0]", t[9][1] + whole[10][1]),
    ], {**vars(step_module), **counters, "_sqp": sqp})  # fmt: skip
    return _instrument(step_module.advance_finish, [
        _before("    res = advance(", whole[12][0]),
        _before("    failed = finish(", t[11][0]),
        _before("    return res, failed\n", t[11][1] + whole[12][1]),
    ], {**vars(step_module), **counters, "advance": advance})  # fmt: skip


def call_cost(run: Any) -> tuple[float, int]:
    """``(us, arrays)``: one call (through ``CompiledCall``) of a kernel that does
    nothing, with the arguments of the last compiled call ``run()`` made (the cost of
    passing them: unboxing the arrays), and how many arrays they hold."""
    from continuum_mhe.estimators.fast.ccall import CompiledCall

    seen: list[tuple[Any, ...]] = []
    call = CompiledCall.__call__

    def spy(self: CompiledCall, *args: Any) -> Any:
        seen.append(args)
        return call(self, *args)

    CompiledCall.__call__ = spy  # type: ignore[method-assign]
    try:
        run()
    finally:
        CompiledCall.__call__ = call  # type: ignore[method-assign]
    args = seen[-1]
    ns: dict[str, Any] = {}
    exec(f"def nothing({', '.join(f'a{i}' for i in range(len(args)))}):\n    return 0", ns)
    nothing = CompiledCall(numba.njit(ns["nothing"]))
    nothing(*args)
    t0 = time.perf_counter()
    for _ in range(20000):
        nothing(*args)

    def arrays(a: Any) -> int:
        return sum(map(arrays, a)) if isinstance(a, tuple) else int(isinstance(a, np.ndarray))

    return (time.perf_counter() - t0) / 20000 * 1e6, arrays(args)


def main() -> None:
    horizon = int(sys.argv[1]) if len(sys.argv) > 1 else 30
    step_module.advance_finish = instrumented()  # StepBuffers' CompiledCall takes it
    read = numba.njit(lambda: _cycles())  # type: ignore[call-arg]
    read()
    c0, t0 = read(), time.perf_counter()
    time.sleep(0.5)
    hz = (read() - c0) / (time.perf_counter() - t0)
    f = make_formulation("bend")
    rec = simulate("paper3d", duration=20, noise_deg=2.0, seed=0)
    run_mhe_kernel(f, rec, horizon)  # compiles
    for _ in range(3):
        TICKS[:] = 0
        CALLS[:] = 0
        _, sec, _ = run_mhe_kernel(f, rec, horizon)
    n = CALLS[12]
    print(f"N = {horizon}, {n} samples (the last of 3 rounds); mean us per sample:")
    for part, label in PARTS.items():
        per_call = TICKS[part] / max(CALLS[part], 1) / hz * 1e6
        print(f"  {label:46s} {TICKS[part] / n / hz * 1e6:6.2f}   ({CALLS[part] / n:.2f} "
              f"calls of {per_call:.2f})")  # fmt: skip
    print(f"  timed from Python: mean {sec.mean() * 1e6:.2f}, median {np.median(sec) * 1e6:.2f}")
    short = simulate("paper3d", duration=2, noise_deg=2.0, seed=0)
    for name, run in (
        ("MHE", lambda: run_mhe_kernel(f, short, horizon)),
        ("EKF", lambda: run_ekf_kernel(f, short)),
    ):
        us, n = call_cost(run)
        print(f"{name} kernel's arguments ({n} arrays) to a kernel that does nothing: {us:.2f} us")
    _, ekf = run_ekf_kernel(f, rec)
    print(f"bare EKF kernel, timed from Python: median {np.median(ekf[1:]) * 1e6:.2f} us")


if __name__ == "__main__":
    main()
