"""Calling a model evaluation (:data:`~continuum_mhe.estimators.fast.codegen.CFunction`)
from numba kernels by its address.

A ctypes function passed to a numba kernel is typed on every call (a ``ctypes.cast``
each time); its address, an integer, costs nothing to pass. The
kernels call ``int f(const double** inputs, double* out)`` through :func:`call_model`;
the caller keeps the ctypes function (and so its code, compiled or a VM callback) alive.

A numba dispatcher types every argument on each call to pick the compiled overload, a
cost that grows with the number of arrays (the fast MHE's step passes about 60);
:class:`CompiledCall` picks it once and then calls that overload's entry point
directly.
"""

from __future__ import annotations

import ctypes
from typing import Any

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


class CompiledCall:
    """A numba kernel called through the overload its first call selected.

    Every later call must pass arguments of the same numba types as the first (the
    same dtypes, dimensions and layouts; the callers pass their own fixed buffers and
    normalise what comes from outside). Where numba's dispatcher does not expose its
    overloads (``NUMBA_DISABLE_JIT``), every call goes through the dispatcher.
    """

    def __init__(self, kernel: Any) -> None:
        self.kernel = kernel
        self._entry: Any = None

    def __call__(self, *args: Any) -> Any:
        if self._entry is not None:
            return self._entry(*args)
        result = self.kernel(*args)
        try:
            types_ = tuple(self.kernel.typeof_pyval(a) for a in args)
            self._entry = self.kernel.overloads[types_].entry_point
        except (AttributeError, KeyError):  # not a numba dispatcher, or no such overload
            self._entry = None
        return result


def address(fn: Any) -> int:
    """The address of a ctypes function (a :data:`CFunction`)."""
    value = ctypes.cast(fn, ctypes.c_void_p).value
    if not value:
        raise ValueError("a model function without an address")
    return int(value)


@intrinsic
def call_model(typingctx: Any, fn: Any, inputs: Any, out: Any) -> Any:
    """``fn(inputs, out)`` for the address ``fn`` of ``int f(const double**, double*)``
    and the addresses ``inputs`` (of the argument pointers) and ``out``; its int result
    (0 on success)."""
    if not all(isinstance(a, types.Integer) for a in (fn, inputs, out)):
        return None
    sig = types.intc(fn, inputs, out)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        ptr = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [ptr, ptr])
        callee = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(
            callee, [builder.inttoptr(args[1], ptr), builder.inttoptr(args[2], ptr)]
        )

    return sig, codegen
