"""CasADi SX functions as data for the compiled core: their instruction lists ("tapes").

The model of a robot is written once, symbolically (:mod:`continuum_mhe.model`); the
compiled core (:mod:`continuum_mhe._core`) evaluates its functions from the algorithm
that CasADi keeps for every SX function (read from its serialization, or through
``instruction_id``, ``instruction_input``, ``instruction_output`` and
``instruction_constant``). A new robot or option set is new data: nothing is compiled
when it is first used.
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


#: The size (instructions) above which :func:`tape_arrays` reads a function's
#: serialization: up to it, asking CasADi instruction by instruction costs less than
#: serializing the function and checking the serialization.
SERIALIZED_FROM = 1024
#: How many of an algorithm's instructions :func:`_serialized_algorithm` checks against
#: CasADi's instruction queries (evenly spread, the first two and the last included).
_CHECKED_INSTRUCTIONS = 256


def tape_arrays(fn: ca.Function) -> tuple[np.ndarray, np.ndarray]:
    """``(code, constants)`` of an SX function: ``code`` (n, 4) int32 rows
    ``(op, res, a, b)`` in the core's numbering (see ``csrc/tape.hpp``); an output's
    offsets are those of its dense column-major layout.

    A function of more than :data:`SERIALIZED_FROM` instructions is read in one piece
    from CasADi's serialization of it (:func:`_serialized_algorithm`); a smaller one, or
    one whose serialization's layout is not recognised, one instruction at a time
    through CasADi's instruction queries, giving the same arrays."""
    algorithm = _serialized_algorithm(fn) if fn.n_instructions() > SERIALIZED_FROM else None
    if algorithm is None:
        return _queried_tape_arrays(fn)
    return _serialized_tape_arrays(fn, *algorithm)


def _serialized_tape_arrays(
    fn: ca.Function, rows: np.ndarray, constant_values: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`tape_arrays` from instructions as CasADi serializes them: ``(op, i0,
    i1, i2)`` rows and a constant's value per row (of :func:`_serialized_algorithm`, or
    of the queries; an operation of one argument has ``i2 = i1``, as CasADi writes
    it)."""
    if len(rows) == 0:
        return np.zeros((0, 4), dtype=np.int32), np.zeros(0)
    ops, i0, i1, i2 = rows.T
    distinct = np.unique(ops)
    lookup = np.zeros(int(distinct.max()) + 1, dtype=np.int32)
    for op in distinct:
        lookup[op] = _core_op(fn, int(op))
    core_ops = lookup[ops]
    code = np.stack([core_ops, i0, i1, i2], axis=1).astype(np.int32)
    k = np.flatnonzero(core_ops == _OUTPUT)
    if len(k):  # output i0, nonzero i2 <- work i1
        offsets = [_dense_offsets(fn.sparsity_out(i)) for i in range(fn.n_out())]
        first = np.cumsum([0] + [len(o) for o in offsets])
        code[k, 1] = np.concatenate(offsets)[first[i0[k]] + i2[k]]
        code[k, 3] = i0[k]
    k = np.flatnonzero(core_ops == _CONST)
    code[k, 2], code[k, 3] = np.arange(len(k)), 0
    return code, np.ascontiguousarray(constant_values[k], dtype=np.float64)


def _core_op(fn: ca.Function, op: int) -> int:
    """The core's number of CasADi operation ``op``; one the core lacks is an error."""
    try:
        return _OPCODES[op]
    except KeyError:
        names = [m for m in dir(ca) if m.startswith("OP_") and getattr(ca, m) == op]
        raise NotImplementedError(
            f"{fn.name()}: the compiled core has no operation {names or op}"
        ) from None


def _serialized_algorithm(fn: ca.Function) -> tuple[np.ndarray, np.ndarray] | None:
    """``(rows, constants)`` of ``fn``'s algorithm as CasADi serializes an SX function:
    its instructions as ``(op, i0, i1, i2)`` int32 rows (an operation writes work ``i0``
    from ``i1`` and ``i2``, ``i2 = i1`` for one of one argument; an input writes ``i0``
    from input ``i1``'s nonzero ``i2``; an output writes output ``i0``'s nonzero ``i2``
    from work ``i1``), and per row the float64 that a constant keeps in place of ``i1,
    i2``. Each byte of the serialization is two letters, ``a`` plus its low and its high
    four bits. The block is found by its first instruction (a constant's value
    included) and checked against CasADi's instruction queries on
    :data:`_CHECKED_INSTRUCTIONS` instructions; None where it is not found so."""
    n = fn.n_instructions()
    if n < 2:
        return None
    text = fn.serialize()
    key = _letters(_row_bytes(_queried_row(fn, 0)))
    spread = np.linspace(0, n - 1, min(n, _CHECKED_INSTRUCTIONS))
    checked = np.unique(np.r_[1, n - 1, spread].astype(int))
    start = text.find(key)
    while 0 <= start <= len(text) - 32 * n:
        # the second and the last instruction first: a false match costs little
        if start % 2 == 0 and all(
            _matches(text[start + 32 * k : start + 32 * (k + 1)], fn, k) for k in (1, n - 1)
        ):
            letters = np.frombuffer(text[start : start + 32 * n].encode("ascii"), np.uint8) - 97
            block = (letters[0::2] | (letters[1::2] << 4)).astype(np.uint8)
            if all(_row_bytes(_queried_row(fn, int(k))) == block[16 * k : 16 * (k + 1)].tobytes()
                   for k in checked):  # fmt: skip
                rows = block.view("<i4").reshape(n, 4).astype(np.int64)
                return rows, block.view("<f8").reshape(n, 2)[:, 1]
        start = text.find(key, start + 1)
    return None


def _letters(data: bytes) -> str:
    """``data`` as CasADi's serialization writes bytes: two letters each."""
    b = np.frombuffer(data, np.uint8)
    return bytes(np.stack([97 + (b & 15), 97 + (b >> 4)], axis=1).ravel()).decode("ascii")


def _row_bytes(row: tuple[float, ...]) -> bytes:
    """The 16 bytes of a serialized instruction :func:`_queried_row` gives: four int32,
    or for a constant two and its float64 value."""
    if len(row) == 3:
        return np.array(row[:2], "<i4").tobytes() + np.array([row[2]], "<f8").tobytes()
    return np.array(row, "<i4").tobytes()


def _matches(letters: str, fn: ca.Function, k: int) -> bool:
    """Whether 32 letters of a serialization are instruction ``k`` of ``fn``."""
    return letters == _letters(_row_bytes(_queried_row(fn, k)))


def _queried_row(fn: ca.Function, k: int) -> tuple[float, ...]:
    """Instruction ``k`` of ``fn`` from CasADi's instruction queries as
    :func:`_serialized_algorithm` reads it: ``(op, i0, i1, i2)`` (``i2`` repeating
    ``i1`` for an operation of one argument), or ``(op, i0, value)`` for a constant. An
    operation the core lacks is an error (:func:`_core_op`)."""
    op = int(fn.instruction_id(k))
    core = _core_op(fn, op)
    args, res = fn.instruction_input(k), fn.instruction_output(k)
    if core == _INPUT:
        return (op, res[0], args[0], args[1])
    if core == _OUTPUT:
        return (op, res[0], args[0], res[1])
    if core == _CONST:
        return (op, res[0], float(fn.instruction_constant(k)))
    return (op, res[0], args[0], args[1] if len(args) > 1 else args[0])


def _queried_tape_arrays(fn: ca.Function) -> tuple[np.ndarray, np.ndarray]:
    """:func:`tape_arrays` through CasADi's instruction queries, one instruction at a
    time (:func:`_queried_row`), decoded as the serialized rows are."""
    n = fn.n_instructions()
    rows = np.zeros((n, 4), dtype=np.int64)
    constants = np.zeros(n)
    for k in range(n):
        row = _queried_row(fn, k)
        if len(row) == 3:  # a constant: (op, i0, value)
            rows[k, :2], constants[k] = row[:2], row[2]
        else:
            rows[k] = row
    return _serialized_tape_arrays(fn, rows, constants)


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
