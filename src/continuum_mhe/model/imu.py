"""IMU measurement model: roll and pitch of the tip (corrected eq. 6).

Convention: Z-Y-X Euler angles of eq. (5), ``R = Rz(alpha) Ry(beta) Rx(gamma)`` with
roll ``gamma`` about x and pitch ``beta`` about y, both in radians. An accelerometer at
rest measures the specific force ``f = R^T u g`` in the tip frame, where ``u`` is the
world's "up" direction in the base frame; then ``roll = atan2(f_y, f_z)`` and
``pitch = atan2(-f_x, hypot(f_y, f_z))``.

Mounting:

* ``"z-up"`` (default): the base z axis points up, against gravity, ``u = (0, 0, 1)``.
  Then ``roll = atan2(sin phi sin theta, cos theta)`` and
  ``pitch = asin(-cos phi sin theta)``.
* ``"z-down"``: the robot hangs from its base, ``u = (0, 0, -1)``. Straight down reads
  ``roll = pi``.
"""

from __future__ import annotations

import math
from functools import cache
from typing import Literal

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.kinematics import Sym, cosc_q, sinc_q

Mounting = Literal["z-up", "z-down"]
MOUNTINGS: tuple[Mounting, ...] = ("z-up", "z-down")

#: Largest plausible |roll| and |pitch| of a tilt reading, rad (roll in (-pi, pi], pitch
#: in [-pi/2, pi/2], with a margin for noise): beyond them, the angles are in degrees or
#: the reading is a glitch.
#: Standard gravity, m/s^2 (the accelerometers' unit of g; the one value everywhere).
STANDARD_GRAVITY = 9.80665

ROLL_LIMIT = math.pi + 0.05
PITCH_LIMIT = math.pi / 2 + 0.05
#: Floor of ``hypot(f_y, f_z)`` (unit specific force) in the pitch formula.
_LOCK_EPS = 1e-9


def _up_sign(mounting: Mounting) -> float:
    if mounting == "z-up":
        return 1.0
    if mounting == "z-down":
        return -1.0
    raise UserError(f"mounting must be one of {MOUNTINGS}, got {mounting!r}")


def gravity_direction_bend_sym(a: Sym, b: Sym, mounting: Mounting = "z-up") -> Sym:
    """Unit specific-force direction in the tip frame, ``R^T u``, from the bend vector.

    ``R^T e_z`` is R's third row, ``(a sinc theta, b sinc theta, cos theta)``.
    """
    q = a**2 + b**2
    s = sinc_q(q)
    return _up_sign(mounting) * ca.vertcat(a * s, b * s, 1 + q * cosc_q(q))


def tilt_from_gravity_sym(f: Sym) -> Sym:
    """``(roll, pitch)`` in radians from a specific-force vector in the tip frame.

    At gimbal lock (``f_y = f_z = 0``, pitch = +-pi/2) roll is undefined and both
    formulas have unbounded derivatives. Roll is taken as 0 there (derivative 0) and
    ``hypot`` gets a 1e-9 floor, so automatic derivatives stay finite; elsewhere the
    values are exact to 1e-18 rad.
    """
    r2 = f[1] ** 2 + f[2] ** 2
    lock = r2 < _LOCK_EPS**2
    roll = ca.if_else(lock, 0.0, ca.atan2(ca.if_else(lock, 0.0, f[1]), ca.if_else(lock, 1.0, f[2])))
    pitch = ca.atan2(-f[0], ca.sqrt(r2 + _LOCK_EPS**2))
    return ca.vertcat(roll, pitch)


def gravity_direction_from_tilt_sym(z: Sym) -> Sym:
    """Unit specific-force direction in the tip frame from measured ``(roll, pitch)``."""
    roll, pitch = z[0], z[1]
    cb = ca.cos(pitch)
    return ca.vertcat(-ca.sin(pitch), cb * ca.sin(roll), cb * ca.cos(roll))


def tilt_tangent_residual_sym(z: Sym, f_model: Sym) -> Sym:
    """Smooth tilt residual: the model's gravity direction seen from the measured one.

    ``f(z)`` is the measured gravity direction, ``E = [e_roll, e_pitch]`` the unit
    tangent basis there (``e_roll = (0, cos g, -sin g)``, ``e_pitch = df/d pitch``).
    The residual is the stereographic projection of ``f_model`` from ``-f(z)`` onto
    that tangent plane, negated: ``-2 E^T f_model / (1 + f(z) . f_model)``. Its norm is
    ``2 tan(alpha/2)`` for the angle ``alpha`` between the two directions, so the cost
    grows monotonically with the tilt error (no spurious minimum at the antipode, as a
    plain tangent projection would have), and to first order it is
    ``(cos(pitch) d_roll, d_pitch)``: isotropic noise on the gravity direction, as an
    accelerometer has. It is smooth in the state everywhere, including at gimbal lock
    (pitch = +-pi/2) and where roll wraps.
    """
    roll, pitch = z[0], z[1]
    e_roll = ca.vertcat(0, ca.cos(roll), -ca.sin(roll))
    e_pitch = ca.vertcat(
        -ca.cos(pitch), -ca.sin(pitch) * ca.sin(roll), -ca.sin(pitch) * ca.cos(roll)
    )
    c = 1 + ca.dot(gravity_direction_from_tilt_sym(z), f_model)
    return -2 * ca.vertcat(ca.dot(e_roll, f_model), ca.dot(e_pitch, f_model)) / c


def tilt_bend_sym(a: Sym, b: Sym, mounting: Mounting = "z-up") -> Sym:
    """Measurement ``h``: ``(roll, pitch)`` from the bend vector."""
    return tilt_from_gravity_sym(gravity_direction_bend_sym(a, b, mounting))


def tilt_sym(theta: Sym, phi: Sym, mounting: Mounting = "z-up") -> Sym:
    """Measurement ``h``: ``(roll, pitch)`` from ``(theta, phi)``."""
    return tilt_bend_sym(theta * ca.cos(phi), theta * ca.sin(phi), mounting)


def wrap_angle(x: ArrayLike) -> FloatArray:
    """Angle wrapped to ``[-pi, pi)`` (numpy)."""
    return (np.asarray(x, dtype=float) + np.pi) % (2 * np.pi) - np.pi


def canonical_tilt(z: ArrayLike) -> FloatArray:
    """``(roll, pitch)`` pairs ``z`` (n, 2 m), rad, as an IMU's attitude reports them:
    a pitch beyond +-pi/2 (a noisy reading near the gimbal lock) as the same gravity
    direction with pitch ``+-pi - pitch`` and roll turned by pi; roll wrapped to
    ``[-pi, pi)``. Pairs within the range are returned as they are."""
    out = np.array(z, dtype=float, copy=True)
    roll, pitch = out[:, 0::2], out[:, 1::2]
    over = np.abs(pitch) > np.pi / 2
    pitch[over] = np.copysign(np.pi, pitch[over]) - pitch[over]
    roll[over] = wrap_angle(roll[over] + np.pi)
    return out


@cache
def _tilt_function(mounting: Mounting) -> ca.Function:
    theta, phi = ca.SX.sym("theta"), ca.SX.sym("phi")
    return ca.Function("tilt", [theta, phi], [tilt_sym(theta, phi, mounting)])


def tilt(theta: ArrayLike, phi: ArrayLike, mounting: Mounting = "z-up") -> FloatArray:
    """``(roll, pitch)`` in radians, shape ``(..., 2)``."""
    t, p = np.broadcast_arrays(np.asarray(theta, dtype=float), np.asarray(phi, dtype=float))
    out = np.asarray(_tilt_function(mounting)(t.reshape(1, -1), p.reshape(1, -1)), dtype=float)
    return out.reshape(2, -1).T.reshape(*t.shape, 2)


def shape_from_tilt(
    roll: ArrayLike, pitch: ArrayLike, mounting: Mounting = "z-up"
) -> tuple[FloatArray, FloatArray]:
    """Closed-form inverse: ``(theta, phi)`` from ``(roll, pitch)``.

    For ``"z-up"``: ``theta = acos(cos pitch cos roll)``,
    ``phi = atan2(cos pitch sin roll, -sin pitch)``. ``phi = 0`` when straight.
    """
    g = np.asarray(roll, dtype=float)
    bt = np.asarray(pitch, dtype=float)
    sign = _up_sign(mounting)
    r3 = sign * np.moveaxis(gravity_direction_from_tilt(np.stack([g, bt], axis=-1)), -1, 0)
    theta = np.arccos(np.clip(r3[2], -1.0, 1.0))
    phi = np.arctan2(r3[1], r3[0])
    phi = np.where(theta == 0.0, 0.0, phi)
    return theta, phi


def shape_from_tilt_sym(z: Sym, mounting: Mounting = "z-up") -> tuple[Sym, Sym]:
    """:func:`shape_from_tilt` of one reading ``z = (roll, pitch)``, symbolically."""
    r3 = _up_sign(mounting) * gravity_direction_from_tilt_sym(z)
    theta = ca.acos(ca.fmin(ca.fmax(r3[2], -1.0), 1.0))
    phi = ca.if_else(theta == 0.0, 0.0, ca.atan2(r3[1], r3[0]))
    return theta, phi


def wrap_angle_sym(x: Sym) -> Sym:
    """:func:`wrap_angle`, symbolically: ``x`` wrapped to ``[-pi, pi)``."""
    turn = 2 * math.pi
    rest = ca.fmod(x + math.pi, turn)  # numpy's % of a positive divisor: fmod, then
    return ca.if_else(rest < 0, rest + turn, rest) - math.pi  # made non-negative


def gravity_direction_from_tilt(z: ArrayLike) -> FloatArray:
    """Unit specific-force direction (..., 3) in the tip frame from ``(roll, pitch)``
    (..., 2) in radians; any angles, e.g. a pitch past +-pi/2 (numpy)."""
    z_ = np.asarray(z, dtype=float)
    roll, pitch = z_[..., 0], z_[..., 1]
    cb = np.cos(pitch)
    return np.stack([-np.sin(pitch), cb * np.sin(roll), cb * np.cos(roll)], axis=-1)


def tilt_from_accelerometer(f: ArrayLike) -> FloatArray:
    """``(roll, pitch)`` from specific force ``f`` (..., 3) in the tip frame, any units."""
    f_ = np.asarray(f, dtype=float)
    roll = np.arctan2(f_[..., 1], f_[..., 2])
    pitch = np.arctan2(-f_[..., 0], np.hypot(f_[..., 1], f_[..., 2]))
    return np.stack([roll, pitch], axis=-1)


def as_sensor_reads(z: ArrayLike) -> FloatArray:
    """Offset readings ``(n, 2 m)`` (roll, pitch of ``m`` IMUs, rad) as a real sensor
    reports the offset orientation: its gravity direction back into roll and pitch
    (pitch inside +-90 deg, roll wrapped). A pitch pushed past 90 deg comes back as
    ``180 deg - pitch`` with roll turned by 180 deg, the same direction, so the pitch
    offset stays a full turn of the gravity direction. (Clipping the pitch
    at 90 deg instead turns a +30 deg offset at 81 deg pitch into a 7-18 deg error at
    gimbal lock: a different, smaller fault than the one stated.)"""
    z = np.asarray(z, dtype=float)
    pairs = z.reshape(len(z), -1, 2)
    return tilt_from_accelerometer(gravity_direction_from_tilt(pairs)).reshape(z.shape)
