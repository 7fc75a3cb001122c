"""CasADi SX functions as data for the compiled core: their instruction lists ("tapes").

The model of a robot is written once, symbolically (:mod:`continuum_mhe.model`); the
compiled core (:mod:`continuum_mhe._core`) evaluates its functions from the algorithm
that CasADi keeps for every SX function (``instruction_id``, ``instruction_input``,
``instruction_output``, ``instruction_constant``). A new robot or option set is new
data: nothing is compiled when it is first used.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.model.formulations import Formulation

#: CasADi's operation numbers (``casadi.OP_<NAME>``) to the core's, by name.
_OPCODES = {
    int(getattr(ca, "OP_" + name)): code
    for code, name in enumerate(_core.OPERATIONS)
    if hasattr(ca, "OP_" + name)
}
_INPUT, _OUTPUT, _CONST = (_core.OPERATIONS.index(n) for n in ("INPUT", "OUTPUT", "CONST"))


def _sx(fn: ca.Function) -> ca.Function:
    """``fn`` as an SX function with dense inputs. Its outputs keep their sparsity: the
    core writes an output's structural zeros itself."""
    if not fn.is_a("SXFunction"):
        fn = fn.expand()
    for i in range(fn.n_in()):
        if not fn.sparsity_in(i).is_dense():
            raise ValueError(f"{fn.name()}: input {i} is not dense")
    return fn


def tape_arrays(fn: ca.Function) -> tuple[np.ndarray, np.ndarray]:
    """``(code, constants)`` of an SX function: ``code`` (n, 4) int32 rows
    ``(op, res, a, b)`` in the core's numbering (see ``csrc/tape.hpp``); an output's
    offsets are those of its dense column-major layout."""
    n = fn.n_instructions()
    code = np.zeros((n, 4), dtype=np.int32)
    constants: list[float] = []
    dense = [_dense_offsets(fn.sparsity_out(i)) for i in range(fn.n_out())]
    for k in range(n):
        op = fn.instruction_id(k)
        try:
            core_op = _OPCODES[op]
        except KeyError:
            names = [m for m in dir(ca) if m.startswith("OP_") and getattr(ca, m) == op]
            raise NotImplementedError(
                f"{fn.name()}: the compiled core has no operation {names or op}"
            ) from None
        args, res = fn.instruction_input(k), fn.instruction_output(k)
        if core_op == _INPUT:  # res <- input args[0], nonzero args[1]
            code[k] = (core_op, res[0], args[0], args[1])
        elif core_op == _OUTPUT:  # output res[0], nonzero res[1] <- work args[0]
            code[k] = (core_op, dense[res[0]][res[1]], args[0], res[0])
        elif core_op == _CONST:
            code[k] = (core_op, res[0], len(constants), 0)
            constants.append(float(fn.instruction_constant(k)))
        else:
            a = args[0]
            code[k] = (core_op, res[0], a, args[1] if len(args) > 1 else a)
    return code, np.asarray(constants, dtype=np.float64)


def _dense_offsets(sp: ca.Sparsity) -> np.ndarray:
    """Each nonzero's offset in the dense column-major layout of ``sp``."""
    return np.asarray(sp.row(), dtype=np.int64) + sp.size1() * np.asarray(
        sp.get_col(), dtype=np.int64
    )


def shared_tape(code: np.ndarray, constants: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """``(code, constants, work_size)``: the tape ``(code, constants)`` (of
    :func:`tape_arrays`) with every value computed once and only the values an output
    needs (the core's ``share_tape``). The derivatives of a model repeat its terms: an
    instruction that reads the same inputs, constant or values as an earlier one and
    applies the same operation is the earlier value (value numbering), so each is
    evaluated once; work slots are then reassigned (a slot is free after its value's
    last use). The arithmetic of every value is unchanged."""
    shared, work_size = _core.share_tape(np.ascontiguousarray(code, dtype=np.int32), constants)
    return shared, constants, int(work_size)


def tape_function(fn: ca.Function) -> _core.TapeFunction:
    """The core's evaluation of ``fn`` (an SX function, or one that expands to one)."""
    fn = _sx(fn)
    code, constants, work_size = shared_tape(*tape_arrays(fn))
    return _core.TapeFunction(
        code,
        constants,
        [int(fn.nnz_in(i)) for i in range(fn.n_in())],
        [int(fn.numel_out(i)) for i in range(fn.n_out())],
        work_size,
    )


def transition_function(formulation: Formulation) -> ca.Function:
    """``(x, u, dt) -> (f, F)``: the transition and its Jacobian (row-major), the first
    two outputs of :func:`~continuum_mhe.estimators.fast.window_functions.node_function`."""
    f, nx = formulation, formulation.nx
    x, u, dt = ca.SX.sym("x", nx), ca.SX.sym("u", f.nu), ca.SX.sym("dt")
    xf = f.transition_sym(x, u, dt)
    return ca.Function("mhe_transition", [x, u, dt], [xf, ca.vec(ca.jacobian(xf, x).T)])


def residual_function(formulation: Formulation) -> ca.Function:
    """``(x, z) -> r(z, x)``: the measurement residual alone (its Jacobian by forward
    mode in the core: :attr:`~continuum_mhe.model.formulations.Formulation.
    forward_mode_jacobian`)."""
    x, z = ca.SX.sym("x", formulation.nx), ca.SX.sym("z", formulation.nz)
    return ca.Function("mhe_residual", [x, z], [formulation.measurement_residual_sym(z, x)])


@lru_cache(maxsize=32)
def residual_node_tapes(formulation: Formulation) -> tuple[_core.TapeFunction, _core.TapeFunction]:
    """``(transition, residual)``: :func:`transition_function` and
    :func:`residual_function` as the core evaluates them (read once per formulation)."""
    return tape_function(transition_function(formulation)), tape_function(
        residual_function(formulation)
    )
