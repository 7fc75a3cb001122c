"""Moving a window's rows in place (numba kernels).

Sliding the window moves every per-node buffer one node towards its start. Written as
an element loop, numba cannot vectorise the copy when source and destination are the
same array; :func:`move` is one ``memmove``, several times faster on a window's
blocks.
"""

from __future__ import annotations

from typing import Any

import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def move(typingctx: Any, dst: Any, dst_at: Any, src: Any, src_at: Any, count: Any) -> Any:
    """``dst.flat[dst_at:dst_at + count] = src.flat[src_at:src_at + count]`` for
    C-contiguous arrays of the same dtype, as one ``memmove`` (the ranges may overlap).
    No bounds checks: the caller keeps the ranges inside both arrays."""
    arrays = (dst, src)
    if not all(isinstance(a, types.Array) and a.layout == "C" for a in arrays):
        return None
    if dst.dtype != src.dtype or not all(
        isinstance(i, types.Integer) for i in (dst_at, src_at, count)
    ):
        return None
    sig = types.void(dst, dst_at, src, src_at, count)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        tys = signature.args
        size = context.get_abi_sizeof(context.get_data_type(tys[0].dtype))
        item = context.get_constant(types.intp, size)

        def nbytes(k: int) -> Any:  # argument k (an element count) in bytes
            return builder.mul(context.cast(builder, args[k], tys[k], types.intp), item)

        def at(k: int) -> Any:  # array argument k's data, offset by argument k + 1
            data = context.make_array(tys[k])(context, builder, args[k]).data
            return builder.gep(builder.bitcast(data, cgutils.voidptr_t), [nbytes(k + 1)])

        one = context.get_constant(types.intp, 1)
        cgutils.raw_memmove(builder, at(0), at(2), nbytes(4), one)
        return context.get_dummy_value()

    return sig, codegen


@numba.njit(cache=True)
def shift_rows(dst, src, start, stop):
    """``dst[start:stop] = src[start + 1:stop + 1]`` along the first axis (``src`` may be
    ``dst``): one :func:`move`. C-contiguous arrays of the same row size."""
    if stop <= start:
        return
    if start < 0 or stop > dst.shape[0] or stop + 1 > src.shape[0]:
        raise IndexError("shift_rows: rows out of range")
    chunk = dst.size // dst.shape[0]
    if src.size // src.shape[0] != chunk:
        raise IndexError("shift_rows: rows of different sizes")
    move(dst, start * chunk, src, (start + 1) * chunk, (stop - start) * chunk)


@numba.njit(cache=True)
def copy_into(dst, src):
    """``dst[...] = src`` for C-contiguous arrays of one size: one :func:`move` (numba's
    slice assignment of a 30 x 4 x 4 array takes 10 times as long)."""
    if dst.size != src.size:
        raise IndexError("copy_into: sizes differ")
    move(dst, 0, src, 0, src.size)
