"""Constant-curvature kinematics of one inextensible section.

Conventions (see ``docs/model.md``):

* ``theta`` (rad) is the bending angle, ``phi`` (rad) the angle of the bending plane
  from the base x axis. The tip bends towards ``-(cos phi, sin phi)`` (the paper's
  convention), so ``R(theta, phi) = Rz(phi) Ry(-theta) Rz(-phi)``.
* The singularity-free *bend vector* is ``(a, b) = (theta cos phi, theta sin phi)``.
  ``R`` is the rotation by the rotation vector ``(b, -a, 0)``; every quantity is an
  analytic function of ``(a, b)``, including at the straight configuration.
* Lengths are in metres.

Every expression is written once, symbolically in CasADi. The symbolic builders
(``*_sym``) are used by the optimisation-based estimators; the numeric functions
below are compiled from the same expressions and accept numpy arrays of any
matching shape (vectorised over trailing samples).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError

Sym = Any  # casadi.SX or casadi.MX

#: Below this value of ``theta**2`` the series branches are used. The truncation
#: error of the series at the switch is below 3e-18, under double precision, so the
#: value and its first and second derivatives are continuous to machine precision.
SERIES_SWITCH_Q = 1e-2


def _series_or_closed(q: Sym, series: Sym, closed: Any) -> Sym:
    """Pick ``series(q)`` for small ``q`` and ``closed(theta_safe)`` otherwise.

    ``closed`` is evaluated on a *safe* argument (never below the switch), so its
    derivative is finite even in the branch that is not taken (no NaN * 0).
    """
    q_safe = ca.if_else(q < SERIES_SWITCH_Q, SERIES_SWITCH_Q, q)
    return ca.if_else(q < SERIES_SWITCH_Q, series, closed(ca.sqrt(q_safe)))


def sinc_q(q: Sym) -> Sym:
    """``sin(theta)/theta`` as an analytic function of ``q = theta**2``."""
    series = 1 - q / 6 + q**2 / 120 - q**3 / 5040 + q**4 / 362880
    return _series_or_closed(q, series, lambda t: ca.sin(t) / t)


def cosc_q(q: Sym) -> Sym:
    """``(cos(theta) - 1)/theta**2`` as an analytic function of ``q = theta**2``."""
    series = -0.5 + q / 24 - q**2 / 720 + q**3 / 40320 - q**4 / 3628800
    # -2 sin^2(t/2)/t^2: no cancellation near the switch, unlike (cos t - 1)/t^2
    return _series_or_closed(q, series, lambda t: -0.5 * (ca.sin(t / 2) / (t / 2)) ** 2)


def rotation_bend_sym(a: Sym, b: Sym) -> Sym:
    """Tip rotation (3x3) from the bend vector, by Rodrigues' formula."""
    q = a**2 + b**2
    k = ca.vertcat(b, -a, 0)
    kx = ca.skew(k)
    # R = I + sinc(theta) [k]x + (1 - cos theta)/theta^2 [k]x^2
    return ca.DM.eye(3) + sinc_q(q) * kx - cosc_q(q) * ca.mtimes(kx, kx)


def tip_position_bend_sym(a: Sym, b: Sym, length: Sym | float) -> Sym:
    """Tip position (3,) in metres from the bend vector."""
    q = a**2 + b**2
    c = cosc_q(q)
    return length * ca.vertcat(a * c, b * c, sinc_q(q))


def bend_from_shape_sym(theta: Sym, phi: Sym) -> tuple[Sym, Sym]:
    """Bend vector ``(theta cos phi, theta sin phi)``."""
    return theta * ca.cos(phi), theta * ca.sin(phi)


def rotation_sym(theta: Sym, phi: Sym) -> Sym:
    """Tip rotation ``Rz(phi) Ry(-theta) Rz(-phi)`` (corrected eq. 2)."""
    return rotation_bend_sym(*bend_from_shape_sym(theta, phi))


def tip_position_sym(theta: Sym, phi: Sym, length: Sym | float) -> Sym:
    """Tip position, eq. (3), with the 0/0 at ``theta = 0`` removed."""
    return tip_position_bend_sym(*bend_from_shape_sym(theta, phi), length)


@cache
def _numeric() -> dict[str, ca.Function]:
    theta, phi, length = ca.SX.sym("theta"), ca.SX.sym("phi"), ca.SX.sym("length")
    a, b = ca.SX.sym("a"), ca.SX.sym("b")
    p = tip_position_sym(theta, phi, length)
    shape = ca.vertcat(theta, phi)
    pb = tip_position_bend_sym(a, b, length)
    bend = ca.vertcat(a, b)
    return {
        "R": ca.Function("R", [theta, phi], [ca.reshape(rotation_sym(theta, phi), 9, 1)]),
        "p": ca.Function("p", [theta, phi, length], [p]),
        "J": ca.Function("J", [theta, phi, length], [ca.reshape(ca.jacobian(p, shape), 6, 1)]),
        "Rb": ca.Function("Rb", [a, b], [ca.reshape(rotation_bend_sym(a, b), 9, 1)]),
        "pb": ca.Function("pb", [a, b, length], [pb]),
        "Jb": ca.Function("Jb", [a, b, length], [ca.reshape(ca.jacobian(pb, bend), 6, 1)]),
    }


#: columns per CasADi call: a long recording is evaluated in parts, so that Ctrl-C
#: (handled between Python steps, never inside a call) stops it within a part's time
CALL_COLUMNS = 1 << 16


#: The public function of each numeric one, for messages.
_CALLER = {"R": "rotation", "p": "tip_position", "J": "tip_jacobian", "Rb": "rotation_bend",
           "pb": "tip_position_bend", "Jb": "tip_jacobian_bend"}  # fmt: skip


def _call(name: str, *args: ArrayLike) -> tuple[FloatArray, tuple[int, ...]]:
    """The numeric function ``name`` over the broadcast ``args`` (the last a length, m,
    for the positions and Jacobians: finite, not negative)."""
    given = [np.asarray(x, dtype=float) for x in args]
    try:
        arrays = np.broadcast_arrays(*given)
    except ValueError:
        shapes = ", ".join(str(x.shape) for x in given)
        raise UserError(
            f"{_CALLER[name]}: the arguments' shapes {shapes} do not broadcast together"
        ) from None
    if name in ("p", "J", "pb", "Jb") and not (np.isfinite(given[-1]) & (given[-1] >= 0)).all():
        raise UserError(
            f"{_CALLER[name]}: length must be finite and not negative (m, an arc length from "
            f"the base), got {args[-1]!r}"
        )
    shape = arrays[0].shape
    flat = [x.reshape(1, -1) for x in arrays]
    f = _numeric()[name]
    parts = []
    for start in range(0, max(flat[0].shape[1], 1), CALL_COLUMNS):
        part = np.asarray(f(*(x[:, start : start + CALL_COLUMNS] for x in flat)), dtype=float)
        parts.append(part.reshape(-1, 1) if part.ndim == 1 else part)  # casadi: (rows,)
    return (parts[0] if len(parts) == 1 else np.concatenate(parts, axis=1)), shape


def _as_matrix(out: FloatArray, shape: tuple[int, ...], rows: int, cols: int) -> FloatArray:
    # casadi reshapes column-major; (rows*cols, n) -> (..., rows, cols)
    mats = out.T.reshape(-1, cols, rows).transpose(0, 2, 1)
    return mats.reshape(*shape, rows, cols)


def rotation(theta: ArrayLike, phi: ArrayLike) -> FloatArray:
    """Tip rotation matrix, shape ``(..., 3, 3)``; maps tip-frame vectors to the base."""
    out, shape = _call("R", theta, phi)
    return _as_matrix(out, shape, 3, 3)


def tip_position(theta: ArrayLike, phi: ArrayLike, length: ArrayLike) -> FloatArray:
    """Tip position in the base frame, metres, shape ``(..., 3)``."""
    out, shape = _call("p", theta, phi, length)
    return out.T.reshape(*shape, 3)


def tip_jacobian(theta: ArrayLike, phi: ArrayLike, length: ArrayLike) -> FloatArray:
    """``dp/d(theta, phi)``, metres per radian, shape ``(..., 3, 2)``."""
    out, shape = _call("J", theta, phi, length)
    return _as_matrix(out, shape, 3, 2)


def rotation_bend(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Tip rotation from the bend vector ``(a, b)`` (rad), shape ``(..., 3, 3)``."""
    out, shape = _call("Rb", a, b)
    return _as_matrix(out, shape, 3, 3)


def tip_position_bend(a: ArrayLike, b: ArrayLike, length: ArrayLike) -> FloatArray:
    """Tip position from the bend vector, metres, shape ``(..., 3)``."""
    out, shape = _call("pb", a, b, length)
    return out.T.reshape(*shape, 3)


def tip_jacobian_bend(a: ArrayLike, b: ArrayLike, length: ArrayLike) -> FloatArray:
    """``dp/d(a, b)``, metres per radian, shape ``(..., 3, 2)``."""
    out, shape = _call("Jb", a, b, length)
    return _as_matrix(out, shape, 3, 2)


def shape_from_bend(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``(theta, phi)`` from the bend vector; ``phi = 0`` when straight."""
    a_ = np.asarray(a, dtype=float)
    b_ = np.asarray(b, dtype=float)
    return np.hypot(a_, b_), np.arctan2(b_, a_)


def bend_from_shape(theta: ArrayLike, phi: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Bend vector ``(theta cos phi, theta sin phi)``."""
    t = np.asarray(theta, dtype=float)
    p = np.asarray(phi, dtype=float)
    return t * np.cos(p), t * np.sin(p)
