"""The ``bend`` formulation (the default for tilt IMUs): state
``[a_1, b_1, ..., a_n, b_n, a_1', b_1', ..., b_n']``, the bend vector
``(a_k, b_k) = (theta_k cos phi_k, theta_k sin phi_k)`` of every section and its rate,
with a constant-velocity model driven by white-noise acceleration. Positions always
equal the PCC forward kinematics; nothing is singular at a straight section.
Measurement: roll and pitch of every IMU. Feasible set: one disk
``a_k^2 + b_k^2 <= theta_max_k^2`` per section (:mod:`.formulations` for what every
formulation provides)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cached_property
from typing import ClassVar

import casadi as ca
import numpy as np

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.model.formulations import AT_BOUND_TOL, DIVERGED_MARGIN, Formulation
from continuum_mhe.model.imu import (
    shape_from_tilt,
    tilt_from_gravity_sym,
    tilt_tangent_residual_sym,
)
from continuum_mhe.model.kinematics import Sym, rotation_bend
from continuum_mhe.model.pcc import (
    free_sections,
    gravity_direction_at_sym,
    pose_at_sym,
    up_vector,
)
from continuum_mhe.model.settings import FormulationName


@dataclass(frozen=True)
class BendFormulation(Formulation):
    """Default formulation: every section's bend vector and its rate, constant velocity;
    roll and pitch of every IMU."""

    name: FormulationName = "bend"
    tilt_residual_wraps: ClassVar[bool] = False

    # --- the state ----------------------------------------------------------------
    @property
    def state_names(self) -> tuple[str, ...]:
        n = self.robot.n_sections
        if n == 1:
            return ("a", "b", "a_dot", "b_dot")
        bends = [f"{c}_{k}" for k in range(1, n + 1) for c in ("a", "b")]
        return (*bends, *(f"{c}_dot" for c in bends))

    def bends_sym(self, x: Sym) -> list[tuple[Sym, Sym]]:
        """``[(a_k, b_k)]`` per section."""
        return [(x[2 * k], x[2 * k + 1]) for k in range(self.robot.n_sections)]

    def rates_sym(self, x: Sym) -> list[tuple[Sym, Sym]]:
        """``[(a_k_dot, b_k_dot)]`` per section, rad/s."""
        n2 = 2 * self.robot.n_sections
        return [(x[n2 + 2 * k], x[n2 + 2 * k + 1]) for k in range(self.robot.n_sections)]

    def gravity_directions_sym(self, x: Sym) -> list[Sym]:
        """Unit specific-force direction at rest in each IMU's frame."""
        bends = self.bends_sym(x)
        return [
            gravity_direction_at_sym(bends, imu.section, imu.at, self.robot.mounting)
            for imu in self.robot.imus
        ]

    # --- model --------------------------------------------------------------------
    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        n2 = 2 * self.robot.n_sections
        return ca.vertcat(*[x[i] + dt * x[n2 + i] for i in range(n2)], x[n2:])

    def measurement_sym(self, x: Sym) -> Sym:
        return ca.vertcat(*[tilt_from_gravity_sym(g) for g in self.gravity_directions_sym(x)])

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """Tilt residual of every IMU on the tangent plane of its measured gravity
        direction (stereographic). Smooth everywhere (no Euler-angle wrap or gimbal
        lock), norm ``2 tan(error/2)``; to first order ``(cos(pitch) d_roll, d_pitch)``.
        See :func:`imu.tilt_tangent_residual_sym`.
        """
        g = self.gravity_directions_sym(x)
        return ca.vertcat(
            *[
                tilt_tangent_residual_sym(z[b.slice], gi)
                for b, gi in zip(self.measurement_blocks, g)
            ]
        )

    def process_cov_sym(self, dt: Sym) -> Sym:
        """White-noise acceleration on every bend coordinate, independent."""
        q = self.noise.bend_accel_psd
        q11, q12, q22 = q * dt**3 / 3, q * dt**2 / 2, q * dt
        n2 = 2 * self.robot.n_sections
        rows = []
        for i in range(2 * n2):
            row = [0] * (2 * n2)
            j = i % n2
            if i < n2:
                row[j], row[n2 + j] = q11, q12
            else:
                row[j], row[n2 + j] = q12, q22
            rows.append(ca.horzcat(*row))
        return ca.vertcat(*rows)

    def output_sym(self, x: Sym) -> Sym:
        bends, lengths = self.bends_sym(x), self.robot.lengths
        n = len(lengths)
        shape = [(ca.sqrt(a**2 + b**2), ca.atan2(b, a)) for a, b in bends]
        if n == 1:
            return ca.vertcat(pose_at_sym(bends, lengths, 0)[1], *shape[0])
        ends = [pose_at_sym(bends, lengths, k)[1] for k in range(n)]
        parts = [ends[-1]]
        for k in range(n):
            parts += [shape[k][0], shape[k][1], ends[k]]
        return ca.vertcat(*parts)

    def constraint_sym(self, x: Sym) -> tuple[Sym, FloatArray, FloatArray]:
        """One disk per section: ``a_k^2 + b_k^2 <= theta_max_k^2``."""
        g = ca.vertcat(*[a**2 + b**2 for a, b in self.bends_sym(x)])
        hi = np.array([s.theta_max**2 for s in self.robot.sections])
        return g, np.full(len(hi), -np.inf), hi

    def range_std(self) -> FloatArray:
        """Each section's bend bound ``theta_max`` (rad) on both of its bend coordinates
        ``(a_k, b_k)``; the other states have none (inf)."""
        std = np.full(self.nx, np.inf)
        for k, sec in enumerate(self.robot.sections):
            std[2 * k : 2 * k + 2] = sec.theta_max
        return std

    # --- numeric helpers ----------------------------------------------------------
    def _measured_gravity(self, z0: FloatArray) -> list[FloatArray | None]:
        """Measured unit gravity direction per IMU (None where that IMU dropped out)."""
        out: list[FloatArray | None] = []
        for b in self.measurement_blocks:
            zb = np.asarray(z0[b.slice], dtype=float)
            if not np.all(np.isfinite(zb)):
                out.append(None)
                continue
            roll, pitch = zb[0], zb[1]
            cb = math.cos(pitch)
            out.append(np.array([-math.sin(pitch), cb * math.sin(roll), cb * math.cos(roll)]))
        return out

    def _initial_bends(self, gravity: list[FloatArray | None]) -> FloatArray:
        """Bend vectors (n, 2) from the measured gravity directions, section by section
        from the base: section ``k`` turns the known up direction in its base frame into
        the measurement of its farthest IMU. Sections without an IMU start straight."""
        robot = self.robot
        bends = np.zeros((robot.n_sections, 2))
        up = up_vector(robot.mounting)
        R_prev = np.eye(3)
        for k, sec in enumerate(robot.sections):
            cands = [
                (imu.at, g)
                for imu, g in zip(robot.imus, gravity)
                if imu.section == k and g is not None
            ]
            if cands:
                at, f = max(cands, key=lambda c: c[0])
                v = R_prev.T @ up
                bends[k] = _bend_turning(v, f, at, sec.theta_max)
            R_prev = R_prev @ rotation_bend(bends[k, 0], bends[k, 1])
        return bends

    def initial_state(self, z0: FloatArray) -> FloatArray:
        z0 = np.asarray(z0, dtype=float)
        if self.robot.is_single:  # closed form (the paper's robot)
            th, ph = shape_from_tilt(z0[0], z0[1], self.robot.mounting)
            theta, phi = min(float(th), self.robot.theta_max), float(ph)
            return np.array([theta * math.cos(phi), theta * math.sin(phi), 0.0, 0.0])
        bends = self._initial_bends(self._measured_gravity(z0))
        return np.concatenate([bends.ravel(), np.zeros(bends.size)])

    def initial_cov(self) -> FloatArray:
        n, n2 = self.noise, 2 * self.robot.n_sections
        return np.diag([n.initial_bend_std**2] * n2 + [n.initial_rate_std**2] * n2)

    def project(self, x: FloatArray) -> FloatArray:
        x = np.array(x, dtype=float)
        for k, sec in enumerate(self.robot.sections):
            r = math.hypot(x[2 * k], x[2 * k + 1])
            if r > sec.theta_max:
                x[2 * k : 2 * k + 2] *= sec.theta_max / r
        return x

    def is_feasible(self, x: FloatArray, tol: float = 1e-7) -> bool:
        return all(
            math.hypot(x[2 * k], x[2 * k + 1]) <= sec.theta_max + tol
            for k, sec in enumerate(self.robot.sections)
        )

    def at_bound(self, x: FloatArray) -> bool:
        return bool(self._checks.at_bound(np.ascontiguousarray(x, dtype=np.float64)))

    def is_diverged(self, x: FloatArray, P: FloatArray | None = None) -> bool:
        """Non-finite; a section bent more than ``DIVERGED_MARGIN`` rad beyond its bound
        (the filters are unconstrained, but not that far); a bend rate over
        ``DIVERGED_RATE`` rad/s; or a bend standard deviation over pi rad (the estimate
        knows nothing any more, e.g. after a long gap). (:meth:`state_checks`.)"""
        f64 = np.ascontiguousarray
        cov = None if P is None else f64(P, dtype=np.float64)
        return bool(self._checks.is_diverged(f64(x, dtype=np.float64), cov))

    def free_bends(self, imus: tuple[int, ...] | None = None) -> tuple[tuple[int, int, float], ...]:
        """``(i, j, reach)`` for each section whose bend the IMUs (``imus``, 0-based;
        None: every IMU) leave free (:func:`~continuum_mhe.model.pcc.free_sections`):
        its bend coordinates' state rows and its ``theta_max`` (rad)."""
        robot = self.robot
        sections = robot.sections
        if imus is not None:
            robot = replace(robot, imus=tuple(robot.imus[k] for k in imus))
        free = free_sections(robot, self.gravity_direction_std)
        return tuple((2 * k, 2 * k + 1, sections[k].theta_max) for k in free)

    @property
    def gravity_direction_std(self) -> float:
        """The standard deviation of a reading of an IMU's gravity direction, rad (each
        roll and pitch)."""
        return self.noise.measurement_std

    def state_checks(self) -> _core.StateChecks:
        """:meth:`is_diverged` and :meth:`at_bound` as data for the compiled core (the
        sensor-health policy runs them there): each section's bend pair, the rates
        (:meth:`_rate_rows`) held to ``DIVERGED_RATE``, the bends' variances to pi^2."""
        return self._checks

    def _rate_rows(self) -> list[int]:
        """The states held to ``DIVERGED_RATE``: every state after the bends."""
        return list(range(2 * self.robot.n_sections, self.nx))

    @cached_property
    def _checks(self) -> _core.StateChecks:
        sections, rate_rows = self.robot.sections, self._rate_rows()
        return _core.StateChecks(
            nx=self.nx,
            pairs=[(2 * k, 2 * k + 1) for k in range(len(sections))],
            diverged_r2=[(s.theta_max + DIVERGED_MARGIN) ** 2 for s in sections],
            at_bound_r=[s.theta_max - AT_BOUND_TOL for s in sections],
            rate_rows=rate_rows,
            rate_limit=DIVERGED_RATE,
            std_rows=list(range(2 * len(sections))),
            std_limit2=math.pi**2,
        )


#: Divergence test: largest plausible bend rate, rad/s.
DIVERGED_RATE = 50.0


def _bend_turning(v: FloatArray, f: FloatArray, at: float, theta_max: float) -> FloatArray:
    """Bend ``(a, b)`` of a section whose frame at fraction ``at`` sees the unit direction
    ``v`` (in the section's base frame) as ``f``: ``R(at u)^T v = f``, clipped to
    ``theta_max``.

    Closed form: a bend rotates about a horizontal axis ``n`` (its rotation vector is
    ``(b, -a, 0)``), which keeps the component along ``n``, so ``n`` is perpendicular to
    ``v - f`` and to ``z``; the angle is the one from ``f`` to ``v`` about ``n``, in
    ``(-pi, pi]`` (the smallest bend). Where ``v - f`` is vertical and not zero (``f`` is
    ``v`` mirrored in the horizontal plane: a half turn about any horizontal axis that
    keeps both), least squares from a few starts picks one."""
    d = np.asarray(v, dtype=float) - np.asarray(f, dtype=float)
    horizontal = math.hypot(d[0], d[1])
    if horizontal > 1e-9 or float(np.linalg.norm(d)) <= 1e-12:
        if horizontal > 1e-9:
            n = np.array([-d[1], d[0], 0.0]) / horizontal
            fp, vp = f - (n @ f) * n, v - (n @ v) * n
            angle = math.atan2(float(n @ np.cross(fp, vp)), float(fp @ vp))
        else:  # v == f: no bend
            n, angle = np.zeros(3), 0.0
        w = np.array([-angle * n[1], angle * n[0]]) / at
    else:

        def resid(w: FloatArray) -> FloatArray:
            return np.asarray(rotation_bend(w[0], w[1]).T @ v - f, dtype=float)

        starts = [np.zeros(2)] + [
            np.array([math.cos(ang), math.sin(ang)])
            for ang in np.linspace(0, 2 * np.pi, 4, endpoint=False)
        ]
        from scipy.optimize import least_squares  # the mirrored case only: imported here

        best = min((least_squares(resid, s) for s in starts), key=lambda r: r.cost)
        w = best.x / at
    r = math.hypot(w[0], w[1])
    if r > theta_max:
        w *= theta_max / r
    return np.asarray(w, dtype=float)
