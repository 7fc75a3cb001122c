"""The compiled core's evaluation of CasADi functions (``continuum_mhe._core``) against
CasADi's own evaluation of the same functions: every operation the models use, the
window built node by node against the ``map``-ped CasADi window, one and two sections,
tilt and raw IMUs."""

from __future__ import annotations

import functools
import math

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import continuum_mhe._core as _core
from continuum_mhe.estimators.fast import window_functions
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.model.tape import tape_function


def casadi_flat(fn: ca.Function, args: list[np.ndarray]) -> np.ndarray:
    """CasADi's own evaluation, every output column-major, concatenated."""
    out = fn.call([ca.DM(a) for a in args])
    return np.concatenate([np.asarray(ca.densify(v)).ravel(order="F") for v in out])


def core_flat(core: _core.ModelFunction, args: list[np.ndarray]) -> np.ndarray:
    """The core's evaluation; every output value must be written: two evaluations into
    buffers filled with NaN and with a finite value give the same values."""
    flat = [np.ascontiguousarray(np.asarray(a, float).ravel(order="F")) for a in args]
    outs = []
    for fill in (np.nan, -7.25):
        out = np.full(core.output_size, fill)
        core.evaluate(flat, out)
        outs.append(out)
    np.testing.assert_array_equal(outs[0], outs[1])
    return outs[0]


_x = ca.SX.sym("x", 3)
_y = ca.SX.sym("y")
_UNARY = [ca.sin, ca.cos, ca.tan, ca.atan, ca.exp, ca.sinh, ca.cosh, ca.tanh, ca.asinh,
          ca.fabs, ca.sign, ca.floor, ca.ceil, ca.erf, ca.sqrt, ca.log, lambda v: v**2,
          lambda v: 2 * v, lambda v: 1 / v, lambda v: -v, lambda v: v**3.5, ca.log1p,
          ca.expm1, lambda v: ca.logic_not(v > 0), ca.asin, ca.acos, ca.atanh,
          lambda v: ca.acosh(1 + v * v)]  # fmt: skip
_BINARY = [ca.atan2, ca.fmin, ca.fmax, ca.fmod, ca.copysign, lambda a, b: a**b,
           lambda a, b: a / b, lambda a, b: a - b, ca.hypot, ca.remainder,
           lambda a, b: ca.if_else(a < b, a, b), lambda a, b: a <= b, lambda a, b: a == b,
           lambda a, b: a != b, lambda a, b: ca.logic_and(a > 0, b > 0),
           lambda a, b: ca.logic_or(a > 0, b > 0)]  # fmt: skip


def _all_operations() -> ca.Function:
    a, b = _x[0], _y
    small = ca.tanh(_x[1])  # in (-1, 1): the inverse trigonometric functions' domain
    outs = [op(small) for op in _UNARY[:-1]] + [_UNARY[-1](_x[2])]
    outs += [op(a, b) for op in _BINARY] + [ca.fabs(a) ** b]
    return ca.Function("ops", [_x, _y], [ca.vertcat(*outs), ca.jacobian(ca.vertcat(*outs), _x)])


_OPS = _all_operations()
_OPS_CORE = tape_function(_OPS)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-3, 3), min_size=3, max_size=3),
    st.one_of(st.floats(-3, 3), st.sampled_from([0.0, 1.0, -1.0])),
)
def test_every_operation_equals_casadi(x: list[float], y: float) -> None:
    args = [np.array(x), np.array([y])]
    np.testing.assert_array_equal(core_flat(_OPS_CORE, args), casadi_flat(_OPS, args))


def test_an_operation_the_core_lacks_is_refused_by_name() -> None:
    v = ca.SX.sym("v")
    with pytest.raises(NotImplementedError, match="OP_ERFINV"):
        tape_function(ca.Function("g", [v], [ca.erfinv(v)]))


def _formulations():
    two = Robot((Section(0.16, 1.5), Section(0.14, 1.5)), (ImuPlacement(0), ImuPlacement(1)))
    yield "bend", make_formulation("bend")
    yield "paper", make_formulation("paper")
    yield "bend-two", make_formulation("bend", two)
    yield "direct", make_formulation("direct")


@pytest.mark.parametrize(
    "name, f", list(_formulations()), ids=lambda v: v if isinstance(v, str) else ""
)
def test_window_and_node_functions_equal_casadi(name: str, f) -> None:
    """The window built node by node in the core equals CasADi's mapped window function
    to the last bit (to the rounding of sin and cos where the batched evaluation takes
    them from the vector library: :func:`test_batched_sin_and_cos_are_the_c_librarys_to_4_ulp`);
    the tail, node and output functions likewise."""
    n = 5
    rng = np.random.default_rng(3)
    X = rng.normal(scale=0.4, size=(f.nx, n))
    Z = rng.normal(scale=0.3, size=(f.nz, n))
    M = (rng.random((f.nz, n)) > 0.2).astype(float)
    U = rng.normal(size=(f.nu, n - 1))
    DT = rng.uniform(0.01, 0.1, size=(1, n - 1))
    window, tail = window_functions.core_window_functions(f, n)
    args = [X, Z, M, U, DT]
    expected = casadi_flat(window_functions.window_function(f, n), args)
    if _core.uses_vector_sin_cos():
        # a few ulp in each sin and cos, carried through the derivatives' sums: to 1e-12
        # of the window's largest output (measured at most 1.6e-13 over 200 draws)
        scale = max(1.0, float(np.abs(expected).max()))
        np.testing.assert_allclose(core_flat(window, args), expected, rtol=0, atol=1e-12 * scale)
    else:
        np.testing.assert_allclose(core_flat(window, args), expected, rtol=1e-14, atol=1e-14)
    targs = [X[:, 0], X[:, 1], Z[:, 1], M[:, 1], U[:, 0], DT[:, 0]]
    np.testing.assert_allclose(
        core_flat(tail, targs),
        casadi_flat(window_functions.tail_function(f), targs),
        rtol=1e-14,
        atol=1e-14,
    )
    node = window_functions.node_function(f)
    nargs = [X[:, 0], U[:, 0], DT[:, 0], Z[:, 0], M[:, 0]]
    expected_node = casadi_flat(node, nargs)
    np.testing.assert_array_equal(core_flat(tape_function(node), nargs), expected_node)
    # the node as the EKF and the consistency check take it: its transition, its
    # measurement terms, and the masked residual alone
    from continuum_mhe.estimators.consistency import model_tapes

    halves = [window_functions.transition_model(f), window_functions.measurement_model(f)]
    np.testing.assert_array_equal(
        np.concatenate([core_flat(h, nargs) for h in halves]), expected_node
    )
    np.testing.assert_array_equal(core_flat(model_tapes(f)[2], nargs), expected_node[-f.nz :])


@pytest.mark.parametrize("scale", [1e-8, 1e-3, 0.5, 3.2, 40.0, 1e4, 1e8])
def test_batched_sin_and_cos_are_the_c_librarys_to_4_ulp(scale: float) -> None:
    """The batched evaluations' sin and cos (``_core.sin_cos_rows``) are the C library's
    (``math.sin``, ``math.cos``) within 4 ulp where they come from the vector library,
    and the same bits where they do not; a row whose length is not a multiple of four
    (here 4003 values) ends one value at a time."""
    x = np.random.default_rng(7).uniform(-scale, scale, 4003)
    x[:6] = [0.0, -0.0, math.pi / 2, math.pi, 1e-300, 2.0**-1022]
    s, c = (np.asarray(v) for v in _core.sin_cos_rows(x))
    want_s, want_c = np.array([math.sin(v) for v in x]), np.array([math.cos(v) for v in x])
    if _core.uses_vector_sin_cos():
        for got, want in ((s, want_s), (c, want_c)):
            assert np.all(np.abs(got - want) <= 4 * np.spacing(np.abs(want)))
    else:
        np.testing.assert_array_equal(s, want_s)
        np.testing.assert_array_equal(c, want_c)


def test_the_typing_stub_is_the_built_module(tmp_path) -> None:
    """``src/continuum_mhe/_core/_ext.pyi`` (what type checkers read) is what nanobind's
    stub generator writes for the built module: regenerate it after changing a binding
    (``python -m nanobind.stubgen -m continuum_mhe._core._ext -o
    src/continuum_mhe/_core/_ext.pyi``)."""
    import subprocess
    import sys
    from pathlib import Path

    out = tmp_path / "_core.pyi"
    r = subprocess.run(
        [sys.executable, "-m", "nanobind.stubgen", "-q", "-m", "continuum_mhe._core._ext",
         "-o", str(out)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    committed = Path(__file__).resolve().parents[1] / "src/continuum_mhe/_core/_ext.pyi"
    assert out.read_text() == committed.read_text()


def test_a_repeated_expression_is_evaluated_once() -> None:
    """The tape computes a subexpression that occurs twice (as the derivatives of a model
    repeat its terms) once, and the values stay CasADi's to the last bit."""
    from continuum_mhe.model.tape import shared_tape, tape_arrays

    v = ca.SX.sym("v", 2)
    # two separately built copies of sin(v0) * v1: CasADi keeps both
    fn = ca.Function("g", [v], [ca.vertcat(ca.sin(v[0]) * v[1], v[1] * ca.sin(v[0]) + 1.0)])
    code, constants = tape_arrays(fn)
    shared, _, work = shared_tape(code, constants)
    ops = [_core.OPERATIONS[op] for op in shared[:, 0]]
    assert ops.count("SIN") == 1 and ops.count("MUL") == 1
    assert len(shared) < len(code) and work <= fn.sz_w()
    args = [np.array([0.7, -1.3])]
    np.testing.assert_array_equal(core_flat(tape_function(fn), args), casadi_flat(fn, args))


def test_a_remembered_function_answers_only_for_its_own_inputs() -> None:
    """A remembered evaluation is reused only for the same function at the same inputs,
    bit for bit: another input one ulp away, another function at the same inputs, and a
    new function made after the first was freed (perhaps at its address) each get their
    own values, CasADi's."""
    import gc

    x, y = ca.SX.sym("x", 2), ca.SX.sym("y")
    first = ca.Function("first", [x, y], [ca.sin(x[0]) * y + x[1]])
    second = ca.Function("second", [x, y], [ca.cos(x[0]) + y * x[1]])

    def remembered(fn: ca.Function) -> _core.RememberedFunction:
        return _core.RememberedFunction(tape_function(fn), [2, 1])

    a = [np.array([0.3, -1.2]), np.array([2.5])]
    b = [np.array([np.nextafter(0.3, 1.0), -1.2]), np.array([2.5])]
    one, two = remembered(first), remembered(second)
    for fn, core, args in [
        (first, one, a),
        (first, one, a),  # the remembered values
        (second, two, a),  # another function at the same inputs
        (first, one, a),
        (first, one, b),  # one ulp away
        (first, one, a),
    ]:
        np.testing.assert_array_equal(core_flat(core, args), casadi_flat(fn, args))
    assert casadi_flat(first, a)[0] != casadi_flat(first, b)[0]
    core_flat(one, a)
    del one
    gc.collect()
    three = remembered(second)
    np.testing.assert_array_equal(core_flat(three, a), casadi_flat(second, a))


def test_a_remembered_function_keeps_the_last_two_evaluations() -> None:
    """The last two evaluations on a thread are kept: two inputs in turn (two filters of
    one model side by side) are each evaluated once, and a third input takes the place
    of the older of the two; every answer is CasADi's."""
    x, y = ca.SX.sym("x", 2), ca.SX.sym("y")
    fn = ca.Function("f", [x, y], [ca.sin(x[0]) * y + x[1]])
    core = _core.RememberedFunction(tape_function(fn), [2, 1])
    inputs = {
        name: [np.array([v, -1.2]), np.array([2.5])]
        for name, v in (("a", 0.3), ("b", 0.4), ("c", 0.5))
    }
    hits = []
    for name in ["a", "b", "a", "b", "a", "c", "a", "b"]:
        args = inputs[name]
        out = np.full(core.output_size, np.nan)
        before = core.hits
        core.evaluate([np.ascontiguousarray(a) for a in args], out)
        hits.append(core.hits - before)
        np.testing.assert_array_equal(out, casadi_flat(fn, args))
    # c takes b's place (a was the latest); b is then evaluated again
    assert hits == [0, 0, 1, 1, 1, 0, 1, 0]


def _branch_function() -> ca.Function:
    """sinc-like branches as the kinematics write them (a series below a switch, a closed
    form above it), with their Jacobians: each side long enough to be guarded."""
    v = ca.SX.sym("v", 2)
    q = v[0] ** 2 + v[1] ** 2
    series = 1 - q / 6 + q**2 / 120 - q**3 / 5040 + q**4 / 362880
    t = ca.sqrt(ca.if_else(q < 1e-2, 1e-2, q))
    value = ca.if_else(q < 1e-2, series, ca.sin(t) / t) * v[1] + ca.cos(v[0])
    return ca.Function("branch", [v], [value, ca.jacobian(value, v)])


def test_each_side_of_a_branch_is_guarded_and_no_output_is() -> None:
    """The shared tape puts each side of an ``if_else`` behind a guard on its condition,
    and no guard skips an output."""
    from continuum_mhe.model.tape import shared_tape, tape_arrays

    shared, _, _ = shared_tape(*tape_arrays(_branch_function()))
    ops = [_core.OPERATIONS[op] for op in shared[:, 0]]
    guards = [i for i, op in enumerate(ops) if op == "GUARD"]
    assert len(guards) >= 2
    for i in guards:
        assert "OUTPUT" not in ops[i + 1 : i + 1 + shared[i, 1]]
    conditions = {ops[j] for i in guards for j in [_defined_at(shared, i)]}
    assert conditions <= {"LT", "NOT"} and len(conditions) == 2


def _defined_at(code: np.ndarray, i: int) -> int:
    """The row that last wrote the slot row ``i`` reads."""
    slot = code[i, 2]  # OUTPUT and GUARD rows write no slot (res: an offset, a count)
    writes = [j for j in range(i) if _core.OPERATIONS[code[j, 0]] not in ("OUTPUT", "GUARD")]
    return max(j for j in writes if code[j, 1] == slot)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.3, 0.3), min_size=10, max_size=10), st.integers(0, 2))
def test_a_guarded_branch_equals_casadi_on_each_side_and_mixed(
    values: list[float], side: int
) -> None:
    """A window whose nodes all lie on one side of the kinematics' series switch
    (``theta^2 = 1e-2``: the other side's guard skips it), or on both (nothing is
    skipped), near the switch too, equals CasADi's window to the last bit (to the
    rounding of the vector library's sin and cos in the batch); one node and the
    forward-mode Jacobian likewise."""
    f = make_formulation("bend")
    n = 5
    bend = np.array(values).reshape(2, n)
    if side == 0:  # straight: every node in the series
        bend *= 0.09 / max(0.3, float(np.abs(bend).max()))
    elif side == 1:  # bent: every node on the closed form, one at the switch
        bend += np.sign(bend) * 0.2 + (bend == 0) * 0.2
        bend[:, 0] = [math.sqrt(1e-2), 0.0]
    rng = np.random.default_rng(len(values) + side)
    X = np.vstack([bend, rng.normal(scale=0.3, size=(f.nx - 2, n))])
    Z = rng.normal(scale=0.3, size=(f.nz, n))
    M = np.ones((f.nz, n))
    U = np.zeros((f.nu, n - 1))
    DT = np.full((1, n - 1), 0.05)
    window, _ = window_functions.core_window_functions(f, n)
    args = [X, Z, M, U, DT]
    expected = casadi_flat(window_functions.window_function(f, n), args)
    scale = max(1.0, float(np.abs(expected).max()))
    atol = 1e-12 * scale if _core.uses_vector_sin_cos() else 0.0
    np.testing.assert_allclose(core_flat(window, args), expected, rtol=0, atol=atol)
    fn = _branch_function()
    for k in range(n):
        point = [X[:2, k]]
        np.testing.assert_array_equal(core_flat(tape_function(fn), point), casadi_flat(fn, point))
    value = ca.Function("value", fn.sx_in(), [fn.call(fn.sx_in())[0]])
    forward = _core.ForwardJacobianFunction(tape_function(value))
    for k in range(n):
        got = np.full(forward.output_size, np.nan)
        forward.evaluate([X[:2, k].copy()], got)
        np.testing.assert_allclose(got, casadi_flat(fn, [X[:2, k]])[1:], rtol=1e-14, atol=1e-15)


@functools.cache
def _model_functions() -> list[ca.Function]:
    """Every operation, a two-section raw-IMU model's node functions with their
    derivatives (thousands of instructions, constants, several outputs), and a function
    whose first instruction is a constant."""
    from continuum_mhe.estimators.fast.model import output_function
    from continuum_mhe.model.tape import residual_function, transition_function

    two = Robot((Section(0.15, 3.0), Section(0.15, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    f = make_formulation("direct", two, estimate_gyro_bias=True)
    residual = residual_function(f)
    x, z = residual.sx_in()
    jac = ca.Function("residual_jacobian", [x, z], [ca.jacobian(residual(x, z), x)])
    # constants first, among thousands of whole numbers that the serialized expressions
    # hold before the algorithm (each a false match of a key without the value)
    v = ca.SX.sym("v", 3)
    whole = ca.vertcat(*(v[i % 3] * float(i + 2) for i in range(2000)))
    constants = ca.Function("constants", [v], [ca.vertcat(0.5, ca.sin(whole), whole)])
    return [_OPS, transition_function(f), residual, jac, output_function(f), constants]


@pytest.mark.parametrize(
    "k", range(6), ids=["operations", "transition", "residual", "jacobian", "outputs", "constants"]
)
def test_the_serialized_algorithm_is_the_queried_one(k: int) -> None:
    """The tape read in one piece from CasADi's serialization is, array for array, the
    one read instruction by instruction through CasADi's queries; and the serialization
    was read (not the queries' fallback)."""
    from continuum_mhe.model import tape

    fn = tape._sx(_model_functions()[k])
    algorithm = tape._serialized_algorithm(fn)
    assert algorithm is not None
    code, constants = tape._serialized_tape_arrays(fn, *algorithm)
    queried_code, queried_constants = tape._queried_tape_arrays(fn)
    np.testing.assert_array_equal(code, queried_code)
    np.testing.assert_array_equal(constants, queried_constants)
    assert code.dtype == np.int32 and constants.dtype == np.float64
    if fn.n_instructions() > tape.SERIALIZED_FROM:  # the path tape_arrays takes
        np.testing.assert_array_equal(tape.tape_arrays(fn)[0], queried_code)
        np.testing.assert_array_equal(tape.tape_arrays(fn)[1], queried_constants)


def test_a_serialization_not_recognised_is_read_by_the_queries(monkeypatch) -> None:
    """Where the serialized algorithm is not where it is looked for, or one instruction
    in it differs from CasADi's queries, it is not taken, and the tape comes from the
    queries: the same arrays, and the same values as CasADi's."""
    from continuum_mhe.model import tape

    fn = _OPS
    n = fn.n_instructions()
    assert n <= tape._CHECKED_INSTRUCTIONS  # every instruction is checked
    text = fn.serialize()
    key = tape._letters(tape._row_bytes(tape._queried_row(fn, 0)))
    start = text.index(key)
    # instruction n // 2's result slot, one more
    at = start + 32 * (n // 2) + 8
    changed = tape._letters(bytes([(ord(text[at]) - 97 + 1) % 16 | (ord(text[at + 1]) - 97) << 4]))
    queried = tape._queried_tape_arrays(fn)
    monkeypatch.setattr(tape, "SERIALIZED_FROM", 0)
    for other in ("", text[:at] + changed + text[at + 2 :]):
        monkeypatch.setattr(ca.Function, "serialize", lambda self, *a, _t=other: _t)
        assert tape._serialized_algorithm(fn) is None
        code, constants = tape.tape_arrays(fn)
        np.testing.assert_array_equal(code, queried[0])
        np.testing.assert_array_equal(constants, queried[1])
    monkeypatch.undo()
    args = [np.array([0.3, -0.4, 0.8]), np.array([1.7])]
    np.testing.assert_array_equal(core_flat(tape_function(fn), args), casadi_flat(fn, args))
