"""Known-answer tests of the kinematics and the IMU measurement model.

Every reference value here is computed independently of the library: elementary
rotations built in numpy, the circle geometry of the arc, accelerometer tilt of the
specific force, and central finite differences. See ``docs/model-notes`` for the
corrected equations (erratum 1: rotation entry (2,2); erratum 2: roll/pitch labels).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import casadi as ca
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from continuum_mhe.model import imu, kinematics
from continuum_mhe.model.imu import (
    as_sensor_reads,
    gravity_direction_from_tilt,
    shape_from_tilt,
    tilt,
    tilt_bend_sym,
    tilt_from_accelerometer,
    tilt_sym,
    wrap_angle,
)
from continuum_mhe.model.kinematics import (
    SERIES_SWITCH_Q,
    cosc_q,
    rotation,
    rotation_bend,
    rotation_bend_sym,
    rotation_sym,
    sinc_q,
    tip_jacobian,
    tip_jacobian_bend,
    tip_position,
    tip_position_bend,
    tip_position_bend_sym,
    tip_position_sym,
)

LENGTH = 0.2
G = 9.81
HALF_PI = math.pi / 2

# theta exactly at the singular / boundary points, then interior values
THETAS = np.array([0.0, 1e-8, 1e-4, 0.05, 0.0999, 0.1001, 0.3, 0.9, 1.2, HALF_PI])
PHIS = np.array([-math.pi, -2.5, -HALF_PI, -0.7, 0.0, 0.4, 1.3, HALF_PI, 2.9, math.pi])
# a grid over the workspace (theta x phi)
GRID_T, GRID_P = (g.ravel() for g in np.meshgrid(THETAS, PHIS, indexing="ij"))
# Z-Y-X Euler gimbal lock: pitch = +-pi/2 where theta = pi/2 and sin(phi) = 0. Roll is
# undefined there (atan2 of two round-off values), so roll comparisons skip it.
GIMBAL_LOCK = (GRID_T == HALF_PI) & (np.abs(np.sin(GRID_P)) < 1e-12)


# --- independent references --------------------------------------------------------
def rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_reference(theta: float, phi: float) -> np.ndarray:
    """``Rz(phi) Ry(-theta) Rz(-phi)`` from elementary rotations."""
    return rz(phi) @ ry(-theta) @ rz(-phi)


def arc_point(theta: float, phi: float, length: float, s: float) -> np.ndarray:
    """Point at arclength ``s`` of the circular arc (radius ``length/theta``), theta > 0."""
    r = length / theta
    alpha = s / r  # bend angle swept up to arclength s
    cos_minus_1 = -2 * math.sin(alpha / 2) ** 2  # cos(alpha) - 1 without cancellation
    return np.array(
        [
            r * math.cos(phi) * cos_minus_1,
            r * math.sin(phi) * cos_minus_1,
            r * math.sin(alpha),
        ]
    )


def central_difference(fun, x: np.ndarray, h: float) -> np.ndarray:
    """Jacobian of ``fun: R^n -> R^m`` by central differences, shape (m, n)."""
    x = np.asarray(x, dtype=float)
    cols = []
    for i in range(len(x)):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((np.asarray(fun(x + e)) - np.asarray(fun(x - e))) / (2 * h))
    return np.stack(cols, axis=-1)


# --- tip Jacobians -------------------------------------------------------------------
@pytest.mark.parametrize("theta", [1e-3, 0.05, 0.0999, 0.1001, 0.3, 0.9, HALF_PI])
@pytest.mark.parametrize("phi", [-2.5, 0.0, 0.4, HALF_PI, math.pi])
def test_tip_jacobian_matches_central_differences(theta: float, phi: float) -> None:
    numeric = central_difference(lambda v: tip_position(v[0], v[1], LENGTH), [theta, phi], 1e-6)
    assert_allclose(tip_jacobian(theta, phi, LENGTH), numeric, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "a, b",
    [(0.0, 0.0), (1e-8, -1e-8), (1e-3, 2e-3), (0.07, 0.0707), (0.0, 0.1), (-0.5, 0.8), (1.1, 1.1)],
)
def test_tip_jacobian_bend_matches_central_differences(a: float, b: float) -> None:
    numeric = central_difference(lambda v: tip_position_bend(v[0], v[1], LENGTH), [a, b], 1e-6)
    assert_allclose(tip_jacobian_bend(a, b, LENGTH), numeric, rtol=0, atol=1e-9)


def test_tip_jacobian_is_vectorised_over_samples() -> None:
    jac = tip_jacobian(GRID_T, GRID_P, LENGTH)
    assert jac.shape == (len(GRID_T), 3, 2)
    for k in (0, 17, len(GRID_T) - 1):
        assert_allclose(jac[k], tip_jacobian(GRID_T[k], GRID_P[k], LENGTH), rtol=0, atol=1e-15)


# --- rotation ------------------------------------------------------------------------
def test_rotation_is_orthonormal_with_unit_determinant() -> None:
    R = rotation(GRID_T, GRID_P)
    eye = np.broadcast_to(np.eye(3), R.shape)
    assert_allclose(R @ np.swapaxes(R, -1, -2), eye, rtol=0, atol=1e-14)
    assert_allclose(np.linalg.det(R), 1.0, rtol=0, atol=1e-14)


def test_rotation_bend_is_orthonormal_with_unit_determinant() -> None:
    a, b = GRID_T * np.cos(GRID_P), GRID_T * np.sin(GRID_P)
    R = rotation_bend(a, b)
    eye = np.broadcast_to(np.eye(3), R.shape)
    assert_allclose(R @ np.swapaxes(R, -1, -2), eye, rtol=0, atol=1e-14)
    assert_allclose(np.linalg.det(R), 1.0, rtol=0, atol=1e-14)


def test_rotation_equals_product_of_elementary_rotations() -> None:
    R = rotation(GRID_T, GRID_P)
    for k in range(len(GRID_T)):
        assert_allclose(
            R[k], rotation_reference(GRID_T[k], GRID_P[k]), rtol=0, atol=1e-14, err_msg=f"k={k}"
        )


def test_rotation_bend_equals_elementary_rotations_of_its_shape() -> None:
    a, b = GRID_T * np.cos(GRID_P), GRID_T * np.sin(GRID_P)
    R = rotation_bend(a, b)
    for k in range(len(GRID_T)):
        assert_allclose(R[k], rotation_reference(GRID_T[k], GRID_P[k]), rtol=0, atol=1e-14)


def test_rotation_entry_22_is_the_corrected_erratum_value() -> None:
    # erratum 1: printed cos^2 phi (cos theta - 1) + cos theta is wrong
    R = rotation(GRID_T, GRID_P)
    corrected = np.sin(GRID_P) ** 2 * (np.cos(GRID_T) - 1) + 1
    assert_allclose(R[:, 1, 1], corrected, rtol=0, atol=1e-14)
    printed = np.cos(GRID_P) ** 2 * (np.cos(GRID_T) - 1) + np.cos(GRID_T)
    bent = GRID_T > 0.3
    assert np.max(np.abs(R[bent, 1, 1] - printed[bent])) > 0.1  # the test can tell them apart


def test_rotation_third_column_is_the_closed_form_tangent() -> None:
    R = rotation(GRID_T, GRID_P)
    tangent = np.column_stack(
        [-np.cos(GRID_P) * np.sin(GRID_T), -np.sin(GRID_P) * np.sin(GRID_T), np.cos(GRID_T)]
    )
    assert_allclose(R[:, :, 2], tangent, rtol=0, atol=1e-14)


# --- arc tangent -----------------------------------------------------------------------
@pytest.mark.parametrize("theta", [0.05, 0.3, 0.9, 1.2, HALF_PI])
@pytest.mark.parametrize("phi", [-2.5, -0.7, 0.0, 1.3, math.pi])
def test_arc_tangent_from_circle_geometry_equals_rotation_z_column(theta: float, phi: float):
    h = 1e-6
    d = (arc_point(theta, phi, LENGTH, LENGTH + h) - arc_point(theta, phi, LENGTH, LENGTH - h)) / (
        2 * h
    )
    assert_allclose(d, rotation(theta, phi)[:, 2], rtol=0, atol=1e-8)


@pytest.mark.parametrize("theta", [0.0, 1e-8, 0.05, 0.3, 0.9, HALF_PI])
@pytest.mark.parametrize("phi", [-2.5, 0.0, 1.3, math.pi])
def test_arc_tangent_from_tip_position_along_arclength_equals_rotation_z_column(
    theta: float, phi: float
) -> None:
    # a sub-arc of length s of the same curvature has bending angle theta * s / length
    def point(s: float) -> np.ndarray:
        return tip_position(theta * s / LENGTH, phi, s)

    h = 1e-6
    d = (point(LENGTH + h) - point(LENGTH - h)) / (2 * h)
    assert_allclose(d, rotation(theta, phi)[:, 2], rtol=0, atol=1e-8)


def test_tip_position_matches_circle_geometry() -> None:
    for theta, phi in zip(GRID_T, GRID_P):
        if theta == 0.0:
            expected = np.array([0.0, 0.0, LENGTH])
        else:
            expected = arc_point(theta, phi, LENGTH, LENGTH)
        assert_allclose(tip_position(theta, phi, LENGTH), expected, rtol=0, atol=1e-15)


# --- IMU tilt ---------------------------------------------------------------------------
def test_tilt_equals_accelerometer_tilt_z_up() -> None:
    for theta, phi in zip(GRID_T[~GIMBAL_LOCK], GRID_P[~GIMBAL_LOCK]):
        f = rotation_reference(theta, phi).T @ np.array([0.0, 0.0, G])
        expected = tilt_from_accelerometer(f)
        got = tilt(theta, phi)
        assert_allclose(wrap_angle(got - expected), 0.0, rtol=0, atol=1e-12)


def test_tilt_equals_accelerometer_tilt_z_down() -> None:
    for theta, phi in zip(GRID_T[~GIMBAL_LOCK], GRID_P[~GIMBAL_LOCK]):
        f = rotation_reference(theta, phi).T @ np.array([0.0, 0.0, -G])
        expected = tilt_from_accelerometer(f)
        got = tilt(theta, phi, "z-down")
        assert_allclose(wrap_angle(got - expected), 0.0, rtol=0, atol=1e-12)


def test_tilt_equals_corrected_roll_pitch_formulas() -> None:
    # erratum 2: roll = atan2(sin phi sin theta, cos theta), pitch = asin(-cos phi sin theta)
    roll = np.arctan2(np.sin(GRID_P) * np.sin(GRID_T), np.cos(GRID_T))
    pitch = np.arcsin(-np.cos(GRID_P) * np.sin(GRID_T))
    got = tilt(GRID_T, GRID_P)
    ok = ~GIMBAL_LOCK
    assert_allclose(got[ok, 0], roll[ok], rtol=0, atol=1e-12)
    assert_allclose(got[:, 1], pitch, rtol=0, atol=1e-7)  # asin is ill-conditioned at +-pi/2


def test_tilt_at_gimbal_lock_gives_pitch_minus_half_pi() -> None:
    # theta = pi/2, phi = 0: tip points along -x, the accelerometer's x axis is vertical
    assert_allclose(tilt(HALF_PI, 0.0)[1], -HALF_PI, rtol=0, atol=1e-7)
    assert_allclose(tilt(HALF_PI, math.pi)[1], HALF_PI, rtol=0, atol=1e-7)


def test_tilt_z_down_straight_reads_roll_pi() -> None:
    got = tilt(0.0, 0.3, "z-down")
    assert_allclose(abs(got[0]), math.pi, rtol=0, atol=1e-15)
    assert_allclose(got[1], 0.0, rtol=0, atol=1e-15)


def test_tilt_from_accelerometer_known_values() -> None:
    # level: (0, 0, g) -> (0, 0); rolled +90 deg: gravity along +y; pitched nose-down
    assert_allclose(tilt_from_accelerometer([0.0, 0.0, G]), [0.0, 0.0], atol=1e-15)
    assert_allclose(tilt_from_accelerometer([0.0, G, 0.0]), [HALF_PI, 0.0], atol=1e-15)
    assert_allclose(tilt_from_accelerometer([-G, 0.0, 0.0]), [0.0, HALF_PI], atol=1e-15)


def test_offset_readings_as_a_sensor_reports_them() -> None:
    """Known answers: a pitch pushed past 90 deg comes back as 180 deg - pitch with roll
    turned by 180 deg (the same gravity direction); in-range readings are unchanged;
    two IMUs' pairs are converted independently."""
    d = math.radians
    z = np.array([[d(20.0), d(110.0), d(10.0), d(-100.0)], [d(190.0), d(30.0), 0.3, -0.2]])
    got = as_sensor_reads(z)
    want = np.array([[d(-160.0), d(70.0), d(-170.0), d(-80.0)], [d(-170.0), d(30.0), 0.3, -0.2]])
    assert_allclose(got, want, rtol=0, atol=1e-12)
    pairs = z.reshape(2, 2, 2)
    assert_allclose(
        gravity_direction_from_tilt(got.reshape(2, 2, 2)), gravity_direction_from_tilt(pairs),
        rtol=0, atol=1e-15,
    )  # fmt: skip
    assert_allclose(np.linalg.norm(gravity_direction_from_tilt(pairs), axis=-1), 1.0, rtol=1e-15)


def test_invalid_mounting_is_rejected() -> None:
    with pytest.raises(ValueError, match="mounting"):
        tilt(0.1, 0.2, "sideways")  # type: ignore[arg-type]


@settings(max_examples=60, deadline=None)
@given(
    theta=st.floats(1e-3, HALF_PI - 1e-3),
    phi=st.floats(-3 * math.pi, 3 * math.pi),
    mounting=st.sampled_from(imu.MOUNTINGS),
)
@example(theta=1e-3, phi=math.pi, mounting="z-up")
@example(theta=1.5, phi=-math.pi, mounting="z-down")
@example(theta=0.3, phi=0.0, mounting="z-down")
def test_shape_from_tilt_round_trips(theta: float, phi: float, mounting: imu.Mounting) -> None:
    roll, pitch = tilt(theta, phi, mounting)
    theta_back, phi_back = shape_from_tilt(roll, pitch, mounting)
    assert_allclose(theta_back, theta, rtol=0, atol=1e-9)
    assert_allclose(wrap_angle(phi_back - phi), 0.0, rtol=0, atol=1e-9)


@pytest.mark.parametrize("mounting", imu.MOUNTINGS)
def test_shape_from_tilt_straight_gives_theta_zero_phi_zero(mounting: imu.Mounting) -> None:
    roll, pitch = tilt(0.0, 1.0, mounting)
    theta, phi = shape_from_tilt(roll, pitch, mounting)
    assert_allclose([theta, phi], [0.0, 0.0], rtol=0, atol=1e-12)


# --- derivatives at the singular points (CasADi AD) -----------------------------------
def _value_jac_hess(expr: ca.SX, v: ca.SX) -> ca.Function:
    """Value, Jacobian, and stacked Hessians of every component of ``expr`` w.r.t. ``v``."""
    flat = ca.vec(expr)
    hessians = [ca.hessian(flat[i], v)[0] for i in range(flat.numel())]
    return ca.Function("vjh", [v], [flat, ca.jacobian(flat, v), ca.vertcat(*hessians)])


def _assert_all_finite(fun: ca.Function, point: list[float]) -> None:
    for name, out in zip(("value", "jacobian", "hessian"), fun(point)):
        arr = np.asarray(out, dtype=float)
        assert np.all(np.isfinite(arr)), f"{name} not finite at {point}: {arr}"


def _assert_finite_differences(
    fun: ca.Function,
    point: list[float],
    reference: Callable[[np.ndarray], np.ndarray] | None = None,
    angles: bool = False,
) -> None:
    """The Jacobian against central differences of ``reference`` (an independent value;
    default: the value itself), and the Hessians against central differences of the
    Jacobian. ``angles``: value differences wrapped to ``[-pi, pi)``, for roll beside
    its +-pi seam."""
    x = np.asarray(point, dtype=float)
    value, jac, hess = (np.asarray(out, dtype=float) for out in fun(x))
    if reference is None:
        reference = lambda y: np.asarray(fun(y)[0], dtype=float)  # noqa: E731
    else:
        diff = value.ravel() - np.ravel(reference(x))
        assert_allclose(wrap_angle(diff) if angles else diff, 0.0, rtol=0, atol=1e-12)
    h = 1e-6
    fd_jac, fd_hess = np.zeros_like(jac), np.zeros_like(hess)
    for j in range(x.size):
        e = np.zeros(x.size)
        e[j] = h
        dv = np.ravel(reference(x + e)) - np.ravel(reference(x - e))
        fd_jac[:, j] = (wrap_angle(dv) if angles else dv) / (2 * h)
        jp, jm = (np.asarray(fun(x + s * e)[1], dtype=float) for s in (1, -1))
        fd_hess[:, j] = ((jp - jm) / (2 * h)).ravel()  # row i*n+k: d2 value_i / dx_k dx_j
    scale = max(1.0, float(np.max(np.abs(jac))))
    assert_allclose(jac, fd_jac, rtol=0, atol=1e-7 * scale, err_msg=f"Jacobian at {point}")
    scale = max(1.0, float(np.max(np.abs(hess))))
    assert_allclose(hess, fd_hess, rtol=0, atol=1e-5 * scale, err_msg=f"Hessian at {point}")


def _bend_rotation_reference(x: np.ndarray) -> np.ndarray:
    """The tip rotation from the bend vector ``(a, b) = theta (cos phi, sin phi)``."""
    return rotation_reference(math.hypot(x[0], x[1]), math.atan2(x[1], x[0]))


def _tilt_reference(mounting: imu.Mounting) -> Callable[[np.ndarray], np.ndarray]:
    """Accelerometer tilt of world up seen in the tip frame, from the bend vector."""
    up = np.array([0.0, 0.0, 1.0 if mounting == "z-up" else -1.0])
    return lambda x: tilt_from_accelerometer(_bend_rotation_reference(x).T @ up)


SHAPE_POINTS = [(t, p) for t in (0.0, 1e-8, HALF_PI) for p in (-math.pi, -1.0, 0.0, 0.7, HALF_PI)]
BEND_POINTS = [(0.0, 0.0), (1e-8, 0.0), (0.0, -1e-8), (HALF_PI, 0.0), (0.0, HALF_PI), (-1.0, 1.2)]


@pytest.mark.parametrize("theta, phi", SHAPE_POINTS)
def test_tip_position_sym_derivatives_finite_and_match_fd(theta: float, phi: float) -> None:
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(tip_position_sym(v[0], v[1], LENGTH), v)
    _assert_all_finite(fun, [theta, phi])
    _assert_finite_differences(fun, [theta, phi])  # smooth in (theta, phi) everywhere


@pytest.mark.parametrize("theta, phi", SHAPE_POINTS)
def test_rotation_sym_derivatives_finite_and_match_fd(theta: float, phi: float) -> None:
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(rotation_sym(v[0], v[1]), v)
    _assert_all_finite(fun, [theta, phi])
    # smooth everywhere: differences of the elementary rotations' product
    _assert_finite_differences(fun, [theta, phi], lambda x: rotation_reference(*x).T)


@pytest.mark.parametrize("a, b", BEND_POINTS)
def test_tip_position_bend_sym_derivatives_finite_and_match_fd(a: float, b: float) -> None:
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(tip_position_bend_sym(v[0], v[1], LENGTH), v)
    _assert_all_finite(fun, [a, b])
    _assert_finite_differences(fun, [a, b])  # smooth everywhere: the series branch


@pytest.mark.parametrize("a, b", BEND_POINTS)
def test_rotation_bend_sym_derivatives_finite_and_match_fd(a: float, b: float) -> None:
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(rotation_bend_sym(v[0], v[1]), v)
    _assert_all_finite(fun, [a, b])
    _assert_finite_differences(fun, [a, b], lambda x: _bend_rotation_reference(x).T)


# Roll/pitch is a Z-Y-X Euler measurement with a gimbal lock at pitch = +-pi/2, i.e.
# theta = pi/2 with phi = 0 or pi (b = 0): (HALF_PI, 0.0) and (-HALF_PI, 0.0) below. The
# model defines roll = 0 there and floors hypot(f_y, f_z), so derivatives stay finite.
TILT_BEND_POINTS = [(0.0, 0.0), (1e-8, 0.0), (0.0, 1e-8), (-1e-8, 1e-8), (0.0, HALF_PI),
                    (0.0, -HALF_PI), (HALF_PI * math.cos(0.7), HALF_PI * math.sin(0.7)),
                    (HALF_PI * math.cos(-2.0), HALF_PI * math.sin(-2.0)), (-1.0, 1.2),
                    (HALF_PI, 0.0), (-HALF_PI, 0.0)]  # fmt: skip


GIMBAL_LOCK_BENDS = {(HALF_PI, 0.0), (-HALF_PI, 0.0)}
# beside the gimbal lock, where roll and pitch are smooth but steep (hypot(f_y, f_z)
# 0.01 to 0.05), and the straight rod's neighbours
NEAR_SINGULAR_BENDS = [(HALF_PI - 0.05, 0.0), (-HALF_PI + 0.05, 0.0), (HALF_PI, 0.01),
                       (-HALF_PI, -0.02), (HALF_PI + 0.03, 0.0), (1e-4, -1e-4)]  # fmt: skip


@pytest.mark.parametrize("mounting", imu.MOUNTINGS)
@pytest.mark.parametrize("a, b", TILT_BEND_POINTS)
def test_tilt_bend_sym_derivatives_finite(a: float, b: float, mounting: imu.Mounting) -> None:
    """Finite everywhere; equal to finite differences except at the gimbal lock itself,
    where roll is undefined (z-down's straight rod reads roll = +-pi: differences are
    wrapped)."""
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(tilt_bend_sym(v[0], v[1], mounting), v)
    _assert_all_finite(fun, [a, b])
    if (a, b) not in GIMBAL_LOCK_BENDS:
        _assert_finite_differences(fun, [a, b], _tilt_reference(mounting), angles=True)


@pytest.mark.parametrize("mounting", imu.MOUNTINGS)
@pytest.mark.parametrize("a, b", NEAR_SINGULAR_BENDS)
def test_tilt_bend_sym_derivatives_near_the_singular_points(
    a: float, b: float, mounting: imu.Mounting
) -> None:
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(tilt_bend_sym(v[0], v[1], mounting), v)
    _assert_finite_differences(fun, [a, b], _tilt_reference(mounting), angles=True)


@pytest.mark.parametrize("mounting", imu.MOUNTINGS)
def test_tilt_bend_sym_at_straight_known_values(mounting: imu.Mounting) -> None:
    """Near straight the tip is rotated by the vector ``(b, -a, 0)``, ``R = I + [k]x``
    to first order, so the specific force ``R^T u`` is ``s (a, b, 1)`` with ``s = +1``
    (z-up) or ``-1`` (z-down). z-up: roll = atan2(b, 1) = b, pitch = atan2(-a, 1) = -a, so
    d(roll, pitch)/d(a, b) = [[0, 1], [-1, 0]]. z-down: roll = atan2(-b, -1) = +-pi + b,
    pitch = atan2(a, 1) = a: [[0, 1], [1, 0]]."""
    v = ca.SX.sym("v", 2)
    value, jac, _ = (np.asarray(x, float) for x in _value_jac_hess(
        tilt_bend_sym(v[0], v[1], mounting), v)([0.0, 0.0]))  # fmt: skip
    if mounting == "z-up":
        assert_allclose(value.ravel(), [0.0, 0.0], rtol=0, atol=1e-16)
        assert_allclose(jac, [[0.0, 1.0], [-1.0, 0.0]], rtol=0, atol=1e-15)
    else:
        assert_allclose([abs(value[0, 0]), value[1, 0]], [math.pi, 0.0], rtol=0, atol=1e-15)
        assert_allclose(jac, [[0.0, 1.0], [1.0, 0.0]], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "theta, phi", [(0.0, 0.0), (1e-8, 2.0), (HALF_PI, HALF_PI), (HALF_PI, 0.0), (HALF_PI, math.pi)]
)
def test_tilt_sym_derivatives_finite(theta: float, phi: float) -> None:
    """Finite everywhere; equal to finite differences except at the gimbal lock
    (theta = pi/2 with phi = 0 or pi)."""
    v = ca.SX.sym("v", 2)
    fun = _value_jac_hess(tilt_sym(v[0], v[1]), v)
    _assert_all_finite(fun, [theta, phi])
    if not (theta == HALF_PI and math.sin(phi) ** 2 < 1e-20):
        _assert_finite_differences(fun, [theta, phi], angles=True)


def test_tip_position_bend_sym_derivatives_at_straight_known_values() -> None:
    # p(a, b) = L (a c(q), b c(q), s(q)) with c(0) = -1/2, s'(q) = -1/6:
    # dp/d(a, b) = L [[-1/2, 0], [0, -1/2], [0, 0]], d2 p_z / d(a, b)^2 = -L/3 I
    v = ca.SX.sym("v", 2)
    value, jac, hess = (np.asarray(x, float) for x in _value_jac_hess(
        tip_position_bend_sym(v[0], v[1], LENGTH), v)([0.0, 0.0]))  # fmt: skip
    assert_allclose(value.ravel(), [0.0, 0.0, LENGTH], rtol=0, atol=1e-16)
    assert_allclose(jac, LENGTH * np.array([[-0.5, 0.0], [0.0, -0.5], [0.0, 0.0]]), atol=1e-16)
    assert_allclose(hess[4:6], -LENGTH / 3 * np.eye(2), rtol=0, atol=1e-15)


# --- series switch -----------------------------------------------------------------------
def _sinc_exact(q: float, order: int) -> float:
    """``d^order/dq^order sin(sqrt q)/sqrt q`` from its power series (40 terms)."""
    return sum(
        (-1) ** k / math.factorial(2 * k + 1) * math.perm(k, order) * q ** (k - order)
        for k in range(order, 40)
    )


def _cosc_exact(q: float, order: int) -> float:
    """``d^order/dq^order (cos(sqrt q) - 1)/q`` from its power series (40 terms)."""
    return sum(
        (-1) ** (k + 1) / math.factorial(2 * k + 2) * math.perm(k, order) * q ** (k - order)
        for k in range(order, 40)
    )


@pytest.mark.parametrize(
    "fun, exact", [(sinc_q, _sinc_exact), (cosc_q, _cosc_exact)], ids=["sinc_q", "cosc_q"]
)
def test_series_switch_is_continuous_to_second_derivative(fun, exact) -> None:
    q = ca.SX.sym("q")
    expr = fun(q)
    d1 = ca.jacobian(expr, q)
    d2 = ca.jacobian(d1, q)
    f = ca.Function("f", [q], [expr, d1, d2])
    below = np.nextafter(SERIES_SWITCH_Q, 0.0)
    above = SERIES_SWITCH_Q * (1 + 1e-12)
    left = [float(v) for v in f(below)]
    right = [float(v) for v in f(above)]
    # Relative tolerances per derivative order. The closed form's AD derivatives lose
    # digits to cancellation near the switch (measured: 1e-14, 1.2e-11, 3.7e-8 for
    # cosc_q); dropping the last series term breaks the second-derivative bound.
    rtol = (3e-14, 1e-10, 1e-7)
    for order in range(3):
        assert_allclose(left[order], right[order], rtol=rtol[order], err_msg=f"d{order}")
        assert_allclose(left[order], exact(below, order), rtol=rtol[order], err_msg=f"d{order}")
        assert_allclose(right[order], exact(above, order), rtol=rtol[order], err_msg=f"d{order}")


@pytest.mark.parametrize("q", [0.0, 1e-16, 1e-4, 5e-3, 0.02, 0.5, 2.4])
def test_sinc_q_and_cosc_q_values(q: float) -> None:
    sym = ca.SX.sym("q")
    f = ca.Function("f", [sym], [sinc_q(sym), cosc_q(sym)])
    s, c = (float(v) for v in f(q))
    assert_allclose(s, _sinc_exact(q, 0), rtol=0, atol=4e-15)
    assert_allclose(c, _cosc_exact(q, 0), rtol=0, atol=4e-15)


# --- workspace properties (hypothesis) ------------------------------------------------------
thetas = st.floats(0.0, HALF_PI, allow_nan=False)
phis = st.floats(-math.pi, math.pi, allow_nan=False)


@settings(max_examples=80, deadline=None)
@given(theta=thetas, phi=phis)
@example(theta=0.0, phi=0.0)
@example(theta=1e-8, phi=-math.pi)
@example(theta=HALF_PI, phi=math.pi)
@example(theta=HALF_PI, phi=0.0)
def test_tip_stays_inside_the_workspace(theta: float, phi: float) -> None:
    p = tip_position(theta, phi, LENGTH)
    eps = 1e-15
    assert np.linalg.norm(p) <= LENGTH + eps
    assert np.all(np.abs(p) <= LENGTH + eps)
    assert p[2] >= 0.0


@settings(max_examples=80, deadline=None)
@given(theta=thetas, phi=phis)
@example(theta=0.0, phi=1.0)
@example(theta=1e-8, phi=2.0)
@example(theta=HALF_PI, phi=-math.pi)
def test_tip_position_of_the_bend_vector_matches_circle_geometry(theta: float, phi: float) -> None:
    pb = tip_position_bend(theta * math.cos(phi), theta * math.sin(phi), LENGTH)
    straight = theta < 1e-300  # the arc's radius overflows; its bow is below 1e-300 m
    expected = [0.0, 0.0, LENGTH] if straight else arc_point(theta, phi, LENGTH, LENGTH)
    assert_allclose(pb, expected, rtol=0, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(theta=thetas, phi=phis)
@example(theta=0.0, phi=0.0)
@example(theta=1e-8, phi=0.5)
@example(theta=HALF_PI, phi=-2.0)
@example(theta=5e-324, phi=0.0)
def test_tip_distance_from_base_is_the_chord(theta: float, phi: float) -> None:
    # chord of an arc of length L and angle theta: 2 L sin(theta/2)/theta
    h = theta / 2
    chord = LENGTH * (math.sin(h) / h if h > 1e-6 else 1 - h * h / 6)  # L sinc(theta/2)
    assert_allclose(np.linalg.norm(tip_position(theta, phi, LENGTH)), chord, rtol=1e-14, atol=0)


def test_straight_tip_is_on_the_z_axis_for_every_phi() -> None:
    p = tip_position(np.zeros_like(PHIS), PHIS, LENGTH)
    assert_allclose(p, np.tile([0.0, 0.0, LENGTH], (len(PHIS), 1)), rtol=0, atol=1e-18)


def test_series_switch_constant_is_where_the_branch_changes() -> None:
    """Below ``SERIES_SWITCH_Q`` sinc_q is its degree-4 series in q (fifth derivative
    exactly 0), from it on the closed form (fifth derivative not 0): the published
    constant is the one the expressions use."""
    sym = ca.SX.sym("q")
    d = sinc_q(sym)
    for _ in range(5):
        d = ca.jacobian(d, sym)
    f = ca.Function("f", [sym], [sinc_q(sym), d])
    below = float(np.nextafter(kinematics.SERIES_SWITCH_Q, 0.0))
    series = 1 - below / 6 + below**2 / 120 - below**3 / 5040 + below**4 / 362880
    value, d5 = (float(v) for v in f(below))
    assert value == series and d5 == 0.0
    assert float(f(kinematics.SERIES_SWITCH_Q)[1]) != 0.0


@pytest.mark.parametrize(
    "bends", [[[0.3, 0.2], [0.5, -0.1], [0.0, 0.0]], [[0.0, 0.0]], [[1.2, -0.4], [-0.7, 0.9]]]
)
def test_backbone_in_one_call_equals_pose_at_one_pose_at_a_time(bends: list[list[float]]) -> None:
    from continuum_mhe.model.pcc import backbone_frames, pose_at

    lengths = [0.16, 0.14, 0.1][: len(bends)]
    rots, points = backbone_frames(np.array(bends), lengths, per_section=4)
    assert rots.shape == (1 + 4 * len(bends), 3, 3)
    assert_allclose(rots[0], np.eye(3))
    assert_allclose(points[0], 0.0)
    i = 1
    for k in range(len(bends)):
        for j in range(1, 5):
            r, p = pose_at(np.array(bends), lengths, k, j / 4)
            assert_allclose(rots[i], r, atol=1e-14)
            assert_allclose(points[i], p, atol=1e-14)
            i += 1


@pytest.mark.parametrize("columns", [1, 7, 64])
def test_a_long_evaluation_in_parts_equals_it_in_one(monkeypatch, columns: int) -> None:
    """The numeric kinematics evaluate a long array in parts of ``CALL_COLUMNS``
    columns (so that Ctrl-C is handled between them): every part's columns land where
    one call puts them, for any part size, including a last part of one column."""
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.0, 3.0, (5, 13))
    phi = rng.uniform(-math.pi, math.pi, (5, 13))
    whole = (kinematics.tip_position(theta, phi, 0.2), kinematics.rotation(theta, phi))
    monkeypatch.setattr(kinematics, "CALL_COLUMNS", columns)
    parts = (kinematics.tip_position(theta, phi, 0.2), kinematics.rotation(theta, phi))
    for a, b in zip(whole, parts):
        assert a.shape == b.shape
        assert_allclose(b, a, rtol=0, atol=0)
    one = kinematics.tip_position(0.5, 0.1, 0.2)
    assert one.shape == (3,)


def test_the_kinematics_helpers_refuse_a_negative_length_shapes_apart_and_degrees() -> None:
    """The public helpers refuse in one UserError what would give a mirrored tip (a negative
    length), numpy's broadcasting error (shapes apart), or a drawing of bends in degrees
    (``backbone_points``, theta past a turn; past pi is a file's EKF row, drawn); an arc
    length of 0 is the base."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.pcc import backbone_points

    with pytest.raises(UserError, match=r"^tip_position: length must be finite and not negative"):
        tip_position(0.5, 0.3, -0.2)
    with pytest.raises(UserError, match=r"^tip_jacobian_bend: length must be finite"):
        tip_jacobian_bend(0.5, 0.3, math.nan)
    with pytest.raises(UserError, match=r"shapes \(3,\), \(2,\), \(\) do not broadcast together"):
        tip_position(np.zeros(3), np.zeros(2), 0.2)
    assert_allclose(tip_position(0.5, 0.3, 0.0), [0.0, 0.0, 0.0], atol=1e-15)
    with pytest.raises(UserError, match=r"a bend theta of 50 rad is beyond a turn: degrees\?"):
        backbone_points((0.15, 0.15), [50.0, 30.0], [0.0, 0.0], [0.1])
    assert backbone_points((0.15, 0.15), [3.2, 0.1], [0.0, 0.0], [0.1]).shape == (1, 3)


def test_backbone_points_refuses_section_lengths_that_are_no_lengths() -> None:
    """``backbone_points`` given a negative, zero or non-finite section length, or one
    as text or a bool, refuses it in a UserError naming it (not a mirrored backbone, a
    backbone of the length ``float("0.2")`` reads, or an IndexError from inside), and
    theta, phi or s given as text the same; a straight 0.2 m section's tip is at
    (0, 0, 0.2) m."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.pcc import backbone_points

    for lengths, k in (([-0.2], 0), (["0.2"], 0), ([0.1, -0.1], 1), ([True], 0), ([0.0], 0)):
        said = rf"^backbone_points: robot\[{k}\], a section length, must be a positive finite"
        with pytest.raises(UserError, match=said):
            backbone_points(lengths, [0.3] * len(lengths), [0.1] * len(lengths), [0.0])
    with pytest.raises(UserError, match=r"^backbone_points: robot must be a Robot or a sequence"):
        backbone_points("0.2", 0.3, 0.1, [0.0])  # type: ignore[arg-type]
    for args, name in ((("0.3", 0.1, [0.1]), "theta"), ((0.3, 0.1, ["0.1"]), "s")):
        with pytest.raises(UserError, match=rf"^backbone_points: {name} must be numbers"):
            backbone_points([0.2], *args)
    assert_allclose(backbone_points([0.2], 0.0, 0.0, [0.2]), [[0.0, 0.0, 0.2]], atol=1e-15)


def test_backbone_points_refuses_arc_lengths_of_more_than_one_dimension() -> None:
    """``backbone_points`` given ``s`` as a table (1, 2) of arc lengths refuses it in a
    UserError naming ``s`` and its shape (not numpy's ambiguous truth value from
    inside); a number or a row of arc lengths is taken."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.model.pcc import backbone_points

    with pytest.raises(
        UserError, match=r"^backbone_points: s must be an arc length or a 1-D .*\(1, 2\)"
    ):
        backbone_points([0.2], 0.0, 0.0, [[0.1, 0.2]])
    assert backbone_points([0.2], 0.0, 0.0, 0.2).shape == (1, 3)
    assert backbone_points([0.2], 0.0, 0.0, [0.1, 0.2]).shape == (2, 3)


def test_pose_at_names_the_sections_it_has() -> None:
    """``section`` counts from 0; one beyond the robot (the 1-based count a user may
    try) is a ValueError naming the range, not an IndexError from inside."""
    from continuum_mhe.model.pcc import pose_at

    bends = np.array([[0.3, 0.1], [-0.2, 0.4]])
    _, tip = pose_at(bends, [0.16, 0.14], 1)
    _, mid = pose_at(bends, [0.16, 0.14], 0)
    assert tip[2] > mid[2] > 0
    for bad in (2, -1):
        with pytest.raises(ValueError, match=r"section .* 0-based, 0 to 1"):
            pose_at(bends, [0.16, 0.14], bad)


def test_equal_formulations_share_their_functions_and_others_do_not() -> None:
    """A formulation's CasADi functions are built once for all formulations equal to it
    (by value), and equal tendon statics share their shooting; a robot that differs in
    one length gets its own."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.model.robot import ImuPlacement, Robot, Section
    from continuum_mhe.model.tendon_statics import TendonStatics

    def robot(length: float) -> Robot:
        return Robot((Section(0.16, 3.0), Section(length, 3.0)), (ImuPlacement(0), ImuPlacement(1)))

    a, b, c = (make_formulation("bend", robot(v)) for v in (0.14, 0.14, 0.15))
    assert a is not b and a.functions is b.functions and a.functions is not c.functions
    x = np.array([0.3, 0.1, 0.2, -0.1, 0, 0, 0, 0])
    assert not np.allclose(np.asarray(a.functions.output(x)), np.asarray(c.functions.output(x)))
    tendon = read_robot("tendon-two-section")
    assert TendonStatics(tendon).function is TendonStatics(tendon).function
