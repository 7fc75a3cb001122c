"""Calling a model evaluation (:data:`~continuum_mhe.estimators.fast.codegen.CFunction`)
from numba kernels by its address.

A ctypes function passed to a numba kernel is typed on every call (about 3 us, a
``ctypes.cast`` each time); its address, an integer, costs nothing to pass. The
kernels call ``int f(const double** inputs, double* out)`` through :func:`call_model`;
the caller keeps the ctypes function (and so its code, compiled or a VM callback) alive.
"""

from __future__ import annotations

import ctypes
from typing import Any

from llvmlite import ir
from numba import types
from numba.extending import intrinsic


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
