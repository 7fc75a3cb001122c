"""Forward-mode derivatives in the compiled core (``csrc/forward.hpp``) against CasADi's
symbolic Jacobians of the same functions: every operation that has a derivative, ties
of ``fmin``/``fmax`` (split in halves, as CasADi's), and the tendon robot's EKF node
(tilt and raw IMUs, a slack tendon), whose Jacobian the core takes by forward mode."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import continuum_mhe._core as _core
from continuum_mhe.estimators.fast import NodeEvaluator, node_functions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.tape import tape_function
from continuum_mhe.model.tendon import TendonFormulation

_v = ca.SX.sym("v", 4)
_a, _b, _small = _v[0], _v[3], ca.tanh(_v[1])  # small: the inverse sines' domain
_OUTS = [
    *(op(_small) for op in (ca.sin, ca.cos, ca.tan, ca.atan, ca.exp, ca.sinh, ca.cosh,
                            ca.tanh, ca.asinh, ca.fabs, ca.sign, ca.floor, ca.ceil, ca.erf,
                            ca.log1p, ca.expm1, ca.asin, ca.acos, ca.atanh)),
    ca.sqrt(ca.exp(_v[2])), ca.log(ca.exp(_v[2]) + 1), _v[2] ** 2, 2 * _v[2], 1 / _v[2],
    -_v[2], ca.fabs(_v[2]) ** 3.5, ca.acosh(2 + _v[2] ** 2), ca.logic_not(_v[2] > 0),
    ca.atan2(_a, _b), ca.fmin(_a, _b), ca.fmax(_a, _b), ca.copysign(_a, _b),
    ca.fabs(_a) ** _b, _a / _b, _a - _b, _a * _b, ca.hypot(_a, _b),
    ca.if_else(_a < _b, _a * _a, _b), _a <= _b, _a == _b, _a != _b,
    ca.logic_and(_a > 0, _b > 0), ca.logic_or(_a > 0, _b > 0),
]  # fmt: skip
_F = ca.Function("ops", [_v], [ca.vertcat(*_OUTS)])
_J = ca.Function("ops_jacobian", [_v], [ca.densify(ca.jacobian(_F(_v), _v))])
_FORWARD = _core.ForwardJacobianFunction(tape_function(_F))


# zero, or far enough from it that no partial derivative overflows (1 / v^2)
_VALUES = st.floats(-3, 3).filter(lambda v: v == 0 or abs(v) > 1e-6)


@settings(max_examples=80, deadline=None)
@given(
    st.lists(_VALUES, min_size=3, max_size=3),
    st.one_of(_VALUES, st.sampled_from([0.0, 1.0, -1.0])),
    st.booleans(),
)
def test_every_derivative_equals_casadis(x: list[float], y: float, tie: bool) -> None:
    v = np.array([*x, x[0] if tie else y])  # a tie of fmin and fmax
    expected = np.asarray(_J(v), dtype=float)
    out, filled = np.full(_FORWARD.output_size, np.nan), np.full(_FORWARD.output_size, -7.25)
    _FORWARD.evaluate([v], out)
    _FORWARD.evaluate([v], filled)
    np.testing.assert_array_equal(out, filled)  # every value written, finite or not
    got = out.reshape(expected.shape, order="F")
    finite = np.isfinite(expected)
    assert np.isfinite(got[finite]).all()
    np.testing.assert_allclose(got[finite], expected[finite], rtol=1e-13, atol=1e-13)


_BINARY = (lambda p, q: p + q, lambda p, q: p - q, lambda p, q: p * q,
           lambda p, q: p / (1 + q * q), ca.fmin, ca.fmax, ca.hypot, ca.atan2,
           lambda p, q: ca.if_else(p < q, p, 0))  # fmt: skip
_UNARY = (ca.sin, ca.cos, ca.tanh, lambda p: p * p, lambda p: ca.exp(-p * p), ca.sign)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(st.integers(0, 14), st.integers(0, 63), st.integers(0, 63)),
        min_size=1, max_size=40,
    ),
    # away from zero: atan2 and hypot of two zeros have no derivative
    st.lists(st.floats(0.1, 2) | st.floats(-2, -0.1), min_size=8, max_size=8),
)  # fmt: skip
def test_random_expressions_over_parts_of_the_input_equal_casadis(
    steps: list[tuple[int, int, int]], values: list[float]
) -> None:
    """Expressions that each read a few of eight inputs (as a shooting reads the bends
    and an IMU's error states enter at its end), their work slots reused: the
    forward-mode Jacobian, propagated over each value's own inputs alone, equals
    CasADi's symbolic one."""
    v = ca.SX.sym("v", 8)
    nodes = [v[i] for i in range(8)]
    for op, i, j in steps:
        p, q = nodes[i % len(nodes)], nodes[j % len(nodes)]
        nodes.append(_BINARY[op](p, q) if op < len(_BINARY) else _UNARY[op - len(_BINARY)](p))
    out = ca.vertcat(*nodes[8:][-6:], nodes[-1] * v[7])
    f = ca.Function("f", [v], [out])
    expected = np.asarray(ca.Function("j", [v], [ca.densify(ca.jacobian(out, v))])(values))
    forward = _core.ForwardJacobianFunction(tape_function(f))
    got = np.full(forward.output_size, np.nan)
    forward.evaluate([np.array(values)], got)
    got = got.reshape(expected.shape, order="F")
    finite = np.isfinite(expected)
    np.testing.assert_allclose(got[finite], expected[finite], rtol=1e-12, atol=1e-12)


# a function whose every value reads all eight inputs: evaluated first, it leaves the
# forward mode's reused tangent memory nonzero in every entry of many work slots
_v8 = ca.SX.sym("v", 8)
_DENSE = _core.ForwardJacobianFunction(
    tape_function(
        ca.Function(
            "dense", [_v8], [ca.vertcat(*(ca.sin(ca.sum1(_v8) * (k + 1)) * _v8[k % 8]
                                          for k in range(64)))]
        )
    )
)  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(0.1, 2) | st.floats(-2, -0.1), min_size=8, max_size=8),
    st.booleans(),
    st.integers(1, 6),
)
def test_slots_reused_after_a_skipped_branch_carry_no_stale_derivatives(
    values: list[float], taken: bool, depth: int
) -> None:
    """A value of one input read only by ``if_else(c, value, 0)`` is skipped where ``c``
    is zero (a GUARD); its work slots are reused afterwards by values of one or two
    other inputs. Evaluated after a function whose tangents fill every entry (the
    tangents' memory is reused from call to call and from function to function), the
    forward-mode Jacobian, which keeps each slot's tangent zero outside its value's
    inputs, equals CasADi's whether or not the branch ran."""
    v = ca.SX.sym("v", 8)
    chain = v[1]
    for _ in range(depth + 2):  # values of v[1] alone, in slots reused later
        chain = ca.sin(chain) * chain + v[1]
    c = v[0] > 0 if taken else v[0] > 100
    gated = ca.if_else(c, chain * chain, 0)
    narrow = [ca.cos(v[k] * v[(k + depth) % 6 + 2]) for k in range(2, 8)]
    out = ca.vertcat(gated, *narrow, narrow[0] * narrow[-1] + v[7])
    f = ca.Function("f", [v], [out])
    forward = _core.ForwardJacobianFunction(tape_function(f))
    other = np.array(values)
    other[0] = -other[0] if taken else 200.0  # the branch's other outcome
    scratch = np.empty(_DENSE.output_size)
    for x in (np.array(values), other, np.array(values)):
        expected = np.asarray(ca.Function("j", [v], [ca.densify(ca.jacobian(out, v))])(x))
        _DENSE.evaluate([x], scratch)
        got = np.full(forward.output_size, np.nan)
        forward.evaluate([x], got)
        np.testing.assert_allclose(
            got.reshape(expected.shape, order="F"), expected, rtol=1e-12, atol=1e-12
        )


def test_an_operation_without_a_derivative_is_refused() -> None:
    w = ca.SX.sym("w")
    with pytest.raises(ValueError, match="FMOD"):
        _core.ForwardJacobianFunction(tape_function(ca.Function("g", [w], [ca.fmod(w, 2.0)])))


@pytest.mark.parametrize("imu_model", ["tilt", "direct"])
def test_the_tendon_node_equals_the_symbolic_jacobian(imu_model: str) -> None:
    """The EKF's node of the shipped tendon robot (residual's Jacobian by forward mode)
    against CasADi's symbolic Jacobian of the same residual, at a loaded state with
    tension rates and a slack tendon; and its output Jacobian."""
    f = TendonFormulation(
        robot=read_robot("tendon-two-section"),
        imu_model=imu_model,  # type: ignore[arg-type]
        estimate_gyro_bias=imu_model == "direct",
    )
    rng = np.random.default_rng(3)
    tau = np.array([1.0, 0.5, 0.0, 0.0, 1.5, 0.3])  # tendons 3 and 4 slack
    force = np.array([0.03, -0.02, 0.01])
    x = np.zeros(f.nx)
    x[:3], x[3:6], x[6:12] = f.statics.solve(force, tau)[0], force, tau
    x[12:] = rng.normal(size=f.nx - 12) * 0.05
    z = f.measurement_row(
        rng.normal(size=f.n_imu_measurements) * 0.1, tau, rng.normal(size=6), rng.normal(size=6)
    )
    mask = np.ones(f.nz)
    mask[0] = 0.0  # a masked reading: zero residual and Jacobian row
    evaluator = NodeEvaluator(node_functions(f))
    _, _, H, r = evaluator.evaluate(x, np.zeros(f.nu), 0.02, z, mask)
    z_used = np.where(mask > 0, z, 0.0)  # the core reads a masked reading as zero
    xs, zs = ca.SX.sym("x", f.nx), ca.SX.sym("z", f.nz)
    res = f.measurement_residual_sym(zs, xs)
    r_ref, J_ref = (
        np.asarray(v, dtype=float)
        for v in ca.Function("rj", [xs, zs], [res, ca.jacobian(res, xs)])(x, z_used)
    )
    np.testing.assert_allclose(r, mask * r_ref.ravel(), rtol=0, atol=1e-15)
    J = -mask[:, None] * J_ref
    np.testing.assert_allclose(
        np.asarray(H).reshape(f.nz, f.nx), J, rtol=0, atol=1e-12 * np.abs(J).max()
    )
    P = np.diag(rng.uniform(0.5, 2.0, f.nx)) * 1e-4
    Jy = np.asarray(f.output_jacobian(x), dtype=float).reshape(f.ny, f.nx)
    np.testing.assert_allclose(
        evaluator.output_std(x, P), np.sqrt(np.diag(Jy @ P @ Jy.T)), rtol=1e-12, atol=1e-15
    )
