"""CasADi SX functions as data for the compiled core: their instruction lists ("tapes").

The model of a robot is written once, symbolically (:mod:`continuum_mhe.model`); the
compiled core (:mod:`continuum_mhe._core`) evaluates its functions from the algorithm
that CasADi keeps for every SX function (``instruction_id``, ``instruction_input``,
``instruction_output``, ``instruction_constant``). A new robot or option set is new
data: nothing is compiled when it is first used.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

import continuum_mhe._core as _core

#: CasADi's operation numbers (``casadi.OP_<NAME>``) to the core's, by name.
_OPCODES = {
    int(getattr(ca, "OP_" + name)): code
    for code, name in enumerate(_core.OPERATIONS)
    if hasattr(ca, "OP_" + name)
}
_INPUT, _OUTPUT, _CONST = (_core.OPERATIONS.index(n) for n in ("INPUT", "OUTPUT", "CONST"))


def _sx(fn: ca.Function) -> ca.Function:
    """``fn`` as an SX function with dense inputs and outputs."""
    if not fn.is_a("SXFunction"):
        fn = fn.expand()
    for i in range(fn.n_in()):
        if not fn.sparsity_in(i).is_dense():
            raise ValueError(f"{fn.name()}: input {i} is not dense")
    if any(not fn.sparsity_out(i).is_dense() for i in range(fn.n_out())):
        sym = [ca.SX.sym(f"i{i}", fn.sparsity_in(i)) for i in range(fn.n_in())]
        fn = ca.Function(fn.name(), sym, [ca.densify(v) for v in fn.call(sym)])
    return fn


def tape_arrays(fn: ca.Function) -> tuple[np.ndarray, np.ndarray]:
    """``(code, constants)`` of an SX function: ``code`` (n, 4) int32 rows
    ``(op, res, a, b)`` in the core's numbering (see ``csrc/tape.hpp``)."""
    # CasADi gives the algorithm one instruction per call: the loop is the cost of
    # reading a model (tens of thousands of instructions), so it stays lean
    op_id, op_in, op_out = fn.instruction_id, fn.instruction_input, fn.instruction_output
    opcodes = _OPCODES
    rows: list[tuple[int, int, int, int]] = []
    append = rows.append
    constants: list[float] = []
    for k in range(fn.n_instructions()):
        core_op = opcodes.get(op_id(k), -1)
        args = op_in(k)
        if core_op == _INPUT:  # res <- input args[0], nonzero args[1]
            append((core_op, op_out(k)[0], args[0], args[1]))
        elif core_op == _OUTPUT:  # output res[0], nonzero res[1] <- work args[0]
            res = op_out(k)
            append((core_op, res[1], args[0], res[0]))
        elif core_op == _CONST:
            append((core_op, op_out(k)[0], len(constants), 0))
            constants.append(float(fn.instruction_constant(k)))
        elif core_op < 0:
            op = op_id(k)
            names = [m for m in dir(ca) if m.startswith("OP_") and getattr(ca, m) == op]
            raise NotImplementedError(
                f"{fn.name()}: the compiled core has no operation {names or op}"
            )
        else:
            a = args[0]
            append((core_op, op_out(k)[0], a, args[1] if len(args) > 1 else a))
    code = np.array(rows, dtype=np.int32).reshape(len(rows), 4)
    return code, np.asarray(constants, dtype=np.float64)


def tape_function(fn: ca.Function) -> _core.TapeFunction:
    """The core's evaluation of ``fn`` (an SX function, or one that expands to one)."""
    fn = _sx(fn)
    code, constants = tape_arrays(fn)
    return _core.TapeFunction(
        code,
        constants,
        [int(fn.nnz_in(i)) for i in range(fn.n_in())],
        [int(fn.nnz_out(i)) for i in range(fn.n_out())],
        max(int(fn.sz_w()), 1),
    )
