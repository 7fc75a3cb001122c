"""The ``paper`` formulation (the seed paper's): state ``[x, y, z, theta, phi]`` (one
section, tip IMU) with ``u = [theta_dot, phi_dot]`` from consecutive readings and the
(sign-corrected) Euler step ``x+ = x + dt [J u; u]``; process noise ``W^-1`` is a soft
penalty. Feasible set: eq. (11) boxes (:mod:`.formulations` for what every formulation
provides)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.formulations import AT_BOUND_TOL, DIVERGED_MARGIN, Formulation
from continuum_mhe.model.imu import (
    shape_from_tilt,
    tilt_sym,
    wrap_angle,
)
from continuum_mhe.model.kinematics import Sym, tip_position, tip_position_sym
from continuum_mhe.model.settings import FormulationName

#: Status ``drifted`` (paper formulation): position state this share of the length away
#: from the forward kinematics of the state's theta and phi.
DRIFT_FRACTION = 0.1


#: A bend (rad) above which phi on its bound makes the paper formulation's state
#: ``at-bound``: below it the tip lies within a twentieth of the length of the straight
#: pose's tip, whatever phi.
PHI_BOUND_THETA = 0.1


@dataclass(frozen=True)
class PaperFormulation(Formulation):
    """The paper's five-state formulation, eqs. (3), (4), (10), (11), sign-corrected.
    One section with one IMU at its tip only."""

    name: FormulationName = "paper"
    #: ``W`` is a weight (a soft penalty), not a noise model: with ``W = 10 I`` the
    #: implied position covariance grows by 0.1 m^2 a step, so the standard deviations
    #: are reported as the model implies them, and only a tip standard deviation past
    #: the robot's length turns an ``ok`` estimate ``uncertain`` (the tip may lie
    #: anywhere in its reach), not ``uncertain_fraction``.
    calibrated_covariance = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.robot.is_single:
            raise UserError(
                "the paper formulation models one section with one tip IMU; "
                f"this robot has {self.robot.describe()}: leave --formulation paper out "
                "(the default model, bend with tilt readings and direct with raw ones, "
                "takes any robot; in Python make_formulation('bend', robot))"
            )

    @property
    def state_names(self) -> tuple[str, ...]:
        return ("x", "y", "z", "theta", "phi")

    @property
    def nu(self) -> int:
        return 2

    @property
    def length(self) -> float:
        return self.robot.length

    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        p = tip_position_sym(x[3], x[4], self.length)
        jac = ca.jacobian(p, x[3:5])
        return x + dt * ca.vertcat(ca.mtimes(jac, u), u)

    def measurement_sym(self, x: Sym) -> Sym:
        return tilt_sym(x[3], x[4], self.robot.mounting)

    def process_cov_sym(self, dt: Sym) -> Sym:
        return ca.SX.eye(5) / self.noise.paper_process_weight

    @property
    def process_noise_source(self) -> str:
        return "the paper's W = w I (NoiseSettings.paper_process_weight)"

    def output_sym(self, x: Sym) -> Sym:
        return x

    def state_bounds(self) -> tuple[FloatArray, FloatArray]:
        s = self.length
        return (
            np.array([-s, -s, -s, 0.0, -math.pi]),
            np.array([s, s, s, self.robot.theta_max, math.pi]),
        )

    def is_diverged(self, x: FloatArray, P: FloatArray | None = None) -> bool:
        """Non-finite, theta more than ``DIVERGED_MARGIN`` outside ``[0, theta_max]``, or
        the position more than three lengths from the base."""
        if super().is_diverged(x, P):
            return True
        theta_out = x[3] < -DIVERGED_MARGIN or x[3] > self.robot.theta_max + DIVERGED_MARGIN
        return bool(theta_out or np.linalg.norm(x[:3]) > 3 * self.length)

    def at_bound(self, x: FloatArray) -> bool:
        """theta on ``theta_max`` (or beyond), or, with the section bent by more than
        :data:`PHI_BOUND_THETA` (nearly straight, phi hardly moves the shape), phi on its
        state bound ``-pi`` or ``pi`` (within :data:`AT_BOUND_TOL`): the MHE's box cannot
        wrap phi, and holds it there while the bending plane turns past it."""
        on_theta = x[3] >= self.robot.theta_max - AT_BOUND_TOL
        # (a filter's phi passes the bound, unheld: on it, not beyond it)
        on_phi = x[3] > PHI_BOUND_THETA and abs(abs(x[4]) - math.pi) <= AT_BOUND_TOL
        return bool(on_theta or on_phi)

    def drift(self, x: FloatArray) -> float:
        """Distance, m, from the position state to the tip of the state's own theta, phi."""
        tip = tip_position(float(x[3]), float(x[4]), self.length)
        return float(np.linalg.norm(np.asarray(x[:3], dtype=float) - tip))

    def drifted(self, x: FloatArray) -> bool:
        """The position state is more than :data:`DRIFT_FRACTION` of the length from the
        forward kinematics of its own theta and phi (status ``drifted``)."""
        return self.drift(x) > DRIFT_FRACTION * self.length

    def initial_state(self, z0: FloatArray) -> FloatArray:
        th, ph = shape_from_tilt(z0[0], z0[1], self.robot.mounting)
        theta, phi = min(float(th), self.robot.theta_max), float(ph)
        pos = tip_position(theta, phi, self.length)
        return np.array([*pos, theta, phi])

    def initial_cov(self) -> FloatArray:
        n = self.noise
        s = self.length
        return np.diag([(0.1 * s) ** 2] * 3 + [n.initial_bend_std**2] * 2)

    def inputs(self, z_prev: FloatArray | None, z: FloatArray, dt: float) -> FloatArray:
        if z_prev is None or not np.all(np.isfinite(z_prev)) or not np.all(np.isfinite(z)):
            return np.zeros(2)
        t0, p0 = shape_from_tilt(z_prev[0], z_prev[1], self.robot.mounting)
        t1, p1 = shape_from_tilt(z[0], z[1], self.robot.mounting)
        return np.array([(t1 - t0) / dt, float(wrap_angle(p1 - p0)) / dt])
