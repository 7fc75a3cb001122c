"""Piecewise-constant-curvature (PCC) kinematics: a chain of constant-curvature sections.

Section ``k`` has the singularity-free bend vector ``u_k = (a_k, b_k)`` (rad) and length
``L_k`` (m), expressed in the frame at its own base (the end frame of section
``k - 1``). Composition::

    R_k = R_{k-1} R(u_k),    p_k = p_{k-1} + R_{k-1} p(u_k, L_k)

with ``R(u)``, ``p(u, L)`` of :mod:`continuum_mhe.model.kinematics` (no torsion: each
section's rotation vector is ``(b, -a, 0)`` in its base frame). A point at fraction
``s`` of section ``k`` has the pose of a section with bend ``s u_k`` and length
``s L_k`` on top of sections ``0..k-1``: every quantity is analytic in the bend
vectors, straight sections included.

Everything is written once, symbolically (CasADi); the numeric functions below are
compiled from the same expressions.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from functools import cache, lru_cache

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike

from continuum_mhe.arrays import FloatArray, holds_bools
from continuum_mhe.errors import UserError, is_real
from continuum_mhe.model.imu import Mounting, _up_sign, gravity_direction_bend_sym
from continuum_mhe.model.kinematics import Sym, rotation_bend_sym, tip_position_bend_sym
from continuum_mhe.model.robot import Robot


def pose_at_sym(
    bends: Sequence[tuple[Sym, Sym]], lengths: Sequence[float], section: int, frac: float = 1.0
) -> tuple[Sym, Sym]:
    """``(R, p)``: orientation (3x3, local-to-base) and position (3,) in metres at
    fraction ``frac`` of ``section`` (0-based). Section 0's pose is that section's own
    (no product with the identity, so a one-section robot has exactly the one-section
    expressions)."""
    R: Sym = None
    p: Sym = None
    for k in range(section + 1):
        s = frac if k == section else 1.0
        a, b = bends[k]
        if s != 1.0:
            a, b = s * a, s * b
        rk = rotation_bend_sym(a, b)
        pk = tip_position_bend_sym(a, b, s * lengths[k] if s != 1.0 else lengths[k])
        if R is None:
            R, p = rk, pk
        else:
            p = p + ca.mtimes(R, pk)
            R = ca.mtimes(R, rk)
    return R, p


def gravity_direction_at_sym(
    bends: Sequence[tuple[Sym, Sym]], section: int, frac: float, mounting: Mounting
) -> Sym:
    """Unit specific-force direction ``R^T u`` (3,) in the local frame at fraction
    ``frac`` of ``section``, for a body at rest (``u`` the world's up direction).

    Built from the base up, ``v_k = R(u_k)^T v_{k-1}`` with ``v_0 = R(u_0)^T u``, which
    for section 0 is :func:`~continuum_mhe.model.imu.gravity_direction_bend_sym`.
    """
    v: Sym = None
    for k in range(section + 1):
        s = frac if k == section else 1.0
        a, b = bends[k]
        a_s, b_s = (s * a, s * b) if s != 1.0 else (a, b)
        if v is None:
            v = gravity_direction_bend_sym(a_s, b_s, mounting)
        else:
            v = ca.mtimes(rotation_bend_sym(a_s, b_s).T, v)
    return v


def angular_velocity_at_sym(
    bends: Sequence[tuple[Sym, Sym]],
    rates: Sequence[tuple[Sym, Sym]],
    section: int,
    frac: float,
) -> Sym:
    """Angular velocity (3,) rad/s in the local frame at fraction ``frac`` of
    ``section``: ``vee(R^T dR/dt)`` with ``dR/dt`` by CasADi's chain rule through the
    composed rotation, so it includes the motion of every section below."""
    coords = ca.vertcat(*[c for ab in bends[: section + 1] for c in ab])
    dots = ca.vertcat(*[c for ab in rates[: section + 1] for c in ab])
    rot, _ = pose_at_sym(bends, [1.0] * (section + 1), section, frac)
    d_vec = ca.mtimes(ca.jacobian(ca.vec(rot), coords), dots)
    w_hat = ca.mtimes(rot.T, ca.reshape(d_vec, 3, 3))
    return 0.5 * ca.vertcat(
        w_hat[2, 1] - w_hat[1, 2], w_hat[0, 2] - w_hat[2, 0], w_hat[1, 0] - w_hat[0, 1]
    )


@cache
def _pose_function(lengths: tuple[float, ...], section: int, frac: float) -> ca.Function:
    u = ca.SX.sym("u", 2 * len(lengths))
    bends = [(u[2 * k], u[2 * k + 1]) for k in range(len(lengths))]
    R, p = pose_at_sym(bends, lengths, section, frac)
    return ca.Function("pose", [u], [ca.reshape(R, 9, 1), p])


def pose_at(
    bends: ArrayLike, lengths: Sequence[float], section: int, frac: float = 1.0
) -> tuple[FloatArray, FloatArray]:
    """Numeric :func:`pose_at_sym`: ``bends`` (..., n_sections, 2) rad, ``section``
    0-based (``n_sections - 1`` is the tip's), ``frac`` the fraction of its length; returns
    ``R`` (..., 3, 3) and ``p`` (..., 3) m. A ``section`` outside the robot is a
    ``ValueError`` naming the range."""
    if not 0 <= int(section) < len(lengths):
        raise ValueError(
            f"section {section} is outside the robot's {len(lengths)} section(s): 0-based, "
            f"0 to {len(lengths) - 1}"
        )
    u = np.asarray(bends, dtype=float)
    lead = u.shape[:-2]
    flat = u.reshape(-1, 2 * len(lengths)).T
    fn = _pose_function(tuple(float(v) for v in lengths), int(section), float(frac))
    r, p = (np.asarray(v, dtype=float) for v in fn(flat))
    r = r.reshape(9, -1).T.reshape(-1, 3, 3).transpose(0, 2, 1)  # column-major
    return r.reshape(*lead, 3, 3), p.reshape(3, -1).T.reshape(*lead, 3)


def backbone(
    bends: ArrayLike, lengths: Sequence[float], points_per_section: int = 10
) -> FloatArray:
    """Backbone points (..., n_sections * points_per_section + 1, 3) in metres, from
    the base to the tip, for drawing."""
    u = np.asarray(bends, dtype=float)
    pts = [np.zeros((*u.shape[:-2], 3))]
    for k in range(len(lengths)):
        for j in range(1, points_per_section + 1):
            pts.append(pose_at(u, lengths, k, j / points_per_section)[1])
    return np.stack(pts, axis=-2)


@lru_cache(maxsize=64)
def _points_function(
    lengths: tuple[float, ...], places: tuple[tuple[int, float], ...]
) -> ca.Function:
    """bends (2 n_sections,) -> the points (3, len(places)) at (section, fraction)."""
    u = ca.SX.sym("u", 2 * len(lengths))
    bends = [(u[2 * k], u[2 * k + 1]) for k in range(len(lengths))]
    return ca.Function(
        "points", [u], [ca.horzcat(*[pose_at_sym(bends, lengths, k, f)[1] for k, f in places])]
    )


def arc_places(lengths: Sequence[float], s: ArrayLike) -> tuple[tuple[int, float], ...]:
    """Each arc length ``s`` (m from the base, ``0 <= s <= sum(lengths)``) as ``(section,
    fraction of that section)``; a section's end belongs to that section. Raises
    ``ValueError`` for an ``s`` outside the backbone."""
    total = float(sum(lengths))
    ends = np.cumsum(lengths)
    places = []
    for v in np.atleast_1d(np.asarray(s, dtype=float)):
        if not (0.0 <= v <= total * (1 + 1e-12)):
            raise ValueError(f"arc length {v:g} m is outside the backbone (0 to {total:g} m)")
        k = min(int(np.searchsorted(ends, v, side="left")), len(lengths) - 1)
        start = float(ends[k] - lengths[k])
        places.append((k, min(1.0, (float(v) - start) / float(lengths[k]))))
    return tuple(places)


def _section_lengths(robot: object) -> tuple[float, ...]:
    """The section lengths (m) of ``robot`` (a :class:`Robot`, or a sequence of lengths)
    for :func:`backbone_points`, or a :class:`UserError` naming the argument: each
    length must be a positive finite number."""
    if isinstance(robot, Robot):
        return tuple(float(v) for v in robot.lengths)
    if (
        not isinstance(robot, Iterable)
        or isinstance(robot, (str, bytes))
        or getattr(robot, "ndim", 1) == 0  # a numpy scalar array is not a sequence
    ):
        raise UserError(
            "backbone_points: robot must be a Robot or a sequence of section lengths (m), "
            f"got {robot!r:.60}"
        )
    lengths = list(robot)
    if not lengths:
        raise UserError("backbone_points: robot has no section lengths: give one a section (m)")
    for k, v in enumerate(lengths):
        if not (is_real(v) and math.isfinite(v) and v > 0):
            raise UserError(
                f"backbone_points: robot[{k}], a section length, must be a positive finite "
                f"number (m), got {v!r}"
            )
    return tuple(float(v) for v in lengths)


def backbone_points(
    robot: Robot | Sequence[float], theta: ArrayLike, phi: ArrayLike, s: ArrayLike
) -> FloatArray:
    """Points of the backbone at arc lengths ``s`` (m from the base along the backbone,
    from 0 to ``robot.length``) of a ``robot`` (or of sections of these lengths, m), for
    shapes given by each section's bending angle
    ``theta`` and bending-plane direction ``phi`` (rad, shape (..., n_sections), as the
    ``theta_k``, ``phi_k`` columns of an estimate; one section: (...) or (..., 1)).

    Returns (..., len(s), 3) in metres, in the robot's base frame (z along the straight
    robot). ``s = robot.length`` is the tip; a section boundary is that section's end.
    A section length that is not a positive finite number, ``theta``, ``phi`` or ``s``
    given as text or bools, and an ``s`` of more than one dimension, are a
    :class:`~continuum_mhe.errors.UserError` naming the argument.
    """
    lengths = _section_lengths(robot)
    for name, values in (("theta", theta), ("phi", phi), ("s", s)):
        if np.asarray(values).dtype.kind in "SUO" or holds_bools(values):
            raise UserError(f"backbone_points: {name} must be numbers, got {values!r:.60}")
    if np.ndim(s) > 1:  # (arc_places takes a number or a row of them)
        raise UserError(
            f"backbone_points: s must be an arc length or a 1-D sequence of them (m), got "
            f"shape {np.shape(s)}"
        )
    th = np.asarray(theta, dtype=float)
    ph = np.asarray(phi, dtype=float)
    n = len(lengths)
    if n == 1 and (th.ndim == 0 or th.shape[-1] != 1):
        th, ph = th[..., None], ph[..., None]
    if th.shape != ph.shape or th.shape[-1] != n:
        raise ValueError(
            f"theta and phi must both be (..., {n}) for a {n}-section robot, got "
            f"{th.shape} and {ph.shape}"
        )
    if np.any(np.abs(th[np.isfinite(th)]) > math.tau):
        raise UserError(
            f"backbone_points: a bend theta of {float(np.nanmax(np.abs(th))):g} rad is "
            "beyond a turn: degrees? give radians"
        )
    a, b = th * np.cos(ph), th * np.sin(ph)
    lead = th.shape[:-1]
    u = np.stack([a, b], axis=-1).reshape(-1, 2 * n)  # (m, 2 n): a_1, b_1, a_2, ...
    places = arc_places(lengths, s)
    fn = _points_function(lengths, places)
    pts = np.asarray(fn.map(u.shape[0])(u.T), dtype=float)  # (3, len(s) m), per shape
    pts = pts.reshape(3, u.shape[0], len(places)).transpose(1, 2, 0)
    return pts.reshape(*lead, len(places), 3)


def bend_from_tangent_frames(R_prev: FloatArray, R_next: FloatArray) -> FloatArray:
    """The bend vector ``(a, b)`` of a torsion-free section that turns the tangent
    ``R_prev e_z`` into ``R_next e_z`` (the section's own frame is ``R_prev``).

    The tangent in the section's base frame is ``t = R_prev^T R_next e_z``; a section
    with bend ``(a, b)`` has end tangent ``(-a sinc, -b sinc, cos theta)`` there, so
    ``theta = acos(t_z)`` and ``(a, b) = -theta (t_x, t_y) / |(t_x, t_y)|``. Used to
    compute the PCC model's floor on rod data (the FK of the true section-end tangents).
    """
    t = np.einsum("...ji,...j->...i", R_prev, R_next[..., :, 2])
    theta = np.arccos(np.clip(t[..., 2], -1.0, 1.0))
    h = np.hypot(t[..., 0], t[..., 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(h > 0, -theta / np.where(h > 0, h, 1.0), 0.0)
    return np.stack([scale * t[..., 0], scale * t[..., 1]], axis=-1)


def section_frames_from_bends(bends: ArrayLike, lengths: Sequence[float]) -> FloatArray:
    """End frames ``R_k`` (..., n_sections, 3, 3) of every section (for tests/plots)."""
    u = np.asarray(bends, dtype=float)
    return np.stack([pose_at(u, lengths, k)[0] for k in range(len(lengths))], axis=-3)


def up_vector(mounting: Mounting) -> FloatArray:
    """The world's up direction in the base frame."""
    return np.array([0.0, 0.0, _up_sign(mounting)])


@cache
def _backbone_function(lengths: tuple[float, ...], per_section: int) -> ca.Function:
    u = ca.SX.sym("u", 2 * len(lengths))
    bends = [(u[2 * k], u[2 * k + 1]) for k in range(len(lengths))]
    poses = [
        pose_at_sym(bends, lengths, k, j / per_section)
        for k in range(len(lengths))
        for j in range(1, per_section + 1)
    ]
    rots = ca.horzcat(*[ca.reshape(r, 9, 1) for r, _ in poses])
    return ca.Function("backbone", [u], [rots, ca.horzcat(*[p for _, p in poses])])


def backbone_frames(
    bends: ArrayLike, lengths: Sequence[float], per_section: int = 10
) -> tuple[FloatArray, FloatArray]:
    """Poses along the backbone of one shape in one call: ``bends`` (n_sections, 2)
    rad; returns ``R`` (m, 3, 3) and ``p`` (m, 3) m for the base, then ``per_section``
    evenly spaced poses per section (``m = 1 + per_section n_sections``; the last is
    the tip), as :func:`pose_at` gives them one at a time."""
    u = np.asarray(bends, dtype=float).reshape(-1)
    fn = _backbone_function(tuple(float(v) for v in lengths), int(per_section))
    r, p = (np.asarray(v, dtype=float) for v in fn(u))
    rots = r.T.reshape(-1, 3, 3).transpose(0, 2, 1)  # column-major
    return (
        np.concatenate([np.eye(3)[None], rots]),
        np.concatenate([np.zeros((1, 3)), p.T]),
    )


#: Relative singular value below which :func:`shape_rank` counts a direction as unseen.
SHAPE_RANK_TOL = 1e-8


@cache
def _shape_jacobians(robot: Robot) -> tuple[tuple[FloatArray, int], ...]:
    """The Jacobian of the robot's IMUs' gravity directions with respect to its ``2 n``
    bend coordinates at three random generic shapes (the singular ones are a set of
    measure zero), each with its rank (singular values above :data:`SHAPE_RANK_TOL` of
    the largest, at least of 1 rad per rad: an IMU at ``at = 1e-300`` sees nothing,
    whatever the ratio)."""
    n = robot.n_sections
    b = ca.SX.sym("b", 2 * n)
    bends = [(b[2 * k], b[2 * k + 1]) for k in range(n)]
    g = ca.vertcat(
        *[gravity_direction_at_sym(bends, i.section, i.at, robot.mounting) for i in robot.imus]
    )
    jac = ca.Function("shape_jacobian", [b], [ca.jacobian(g, b)])
    rng = np.random.default_rng(0)
    reach = np.repeat([s.theta_max for s in robot.sections], 2)
    out = []
    for _ in range(3):
        x = reach * rng.uniform(0.15, 0.45, 2 * n) * rng.choice((-1.0, 1.0), 2 * n)
        J = np.asarray(jac(x), dtype=float).reshape(g.numel(), 2 * n)
        sv = np.linalg.svd(J, compute_uv=False)
        out.append((J, int(np.sum(sv > SHAPE_RANK_TOL * max(sv[0], 1.0)))))
    return tuple(out)


@cache
def shape_rank(robot: Robot) -> int:
    """How many of the robot's ``2 n`` bend coordinates one sample of its IMUs' gravity
    directions (what tilt and the accelerometers at rest measure) determines: the rank
    of their Jacobian with respect to the bends, the largest over three random shapes
    (generic shapes). Below ``2 n`` the shape is not observable anywhere, for example
    with one IMU on two sections."""
    return max(rank for _, rank in _shape_jacobians(robot))


#: A section whose bend coordinates carry at least this share of a direction the IMUs
#: do not see is one they leave free (:func:`free_sections`).
FREE_SECTION_SHARE = 1e-6
#: A direction whose move across the whole reach changes the readings by less than the
#: noise of the mean of this many of them is one they do not see (:func:`free_sections`):
#: a motion model holds a shape for about as many samples (two seconds at 50 Hz).
FREE_AVERAGED_READINGS = 100


@cache
def free_sections(robot: Robot, reading_std: float = 0.0) -> tuple[int, ...]:
    """The sections (0-based) whose bend the IMUs' gravity directions leave partly free:
    those with a share of a direction along which the readings do not change, or change
    by less than the noise of the mean of :data:`FREE_AVERAGED_READINGS` readings
    (``reading_std``, rad, is one reading's) when the bends move across their whole
    reach (``theta_max``): the Jacobian of :func:`shape_rank` with its columns
    scaled by each section's reach, its directions of singular values below that (or
    below the rank tolerance), at each of the three shapes (a section is free where it
    is at all three: one of them may lie near a singular shape by chance). Empty where
    the IMUs determine the shape; with IMUs at the ends of sections 1 and 3 of three,
    sections 2 and 3 (the tip IMU sees how far the two bend together, not how they
    share it); with an IMU a thousandth of the way along section 1 and one at the tip
    of two, both (that IMU turns by a few hundredths of a degree across section 1's
    reach)."""
    reach = np.repeat([s.theta_max for s in robot.sections], 2)
    free = set(range(robot.n_sections))
    for J, _ in _shape_jacobians(robot):  # free at every shape: not a singular one's
        _, sv, vt = np.linalg.svd(J * reach)
        sv = np.concatenate([sv, np.zeros(len(reach) - len(sv))])
        floor = max(
            SHAPE_RANK_TOL * max(sv[0], 1.0), reading_std / math.sqrt(FREE_AVERAGED_READINGS)
        )
        unseen = vt[sv <= floor]  # rows: directions (in reach units) the readings miss
        share = (unseen * unseen).sum(axis=0)  # per bend coordinate
        free &= {
            k
            for k in range(robot.n_sections)
            if share[2 * k : 2 * k + 2].sum() > FREE_SECTION_SHARE
        }
    return tuple(sorted(free))
