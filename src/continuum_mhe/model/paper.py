"""The ``paper`` formulation (the seed paper's): state ``[x, y, z, theta, phi]`` (one
section, tip IMU) with ``u = [theta_dot, phi_dot]`` from consecutive readings and the
(sign-corrected) Euler step ``x+ = x + dt [J u; u]``; process noise ``W^-1`` is a soft
penalty. Feasible set: eq. (11) boxes (:mod:`.formulations` for what every formulation
provides)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.formulations import AT_BOUND_TOL, DIVERGED_MARGIN, Formulation
from continuum_mhe.model.imu import (
    shape_from_tilt,
    shape_from_tilt_sym,
    tilt_sym,
    wrap_angle_sym,
)
from continuum_mhe.model.kinematics import Sym, tip_position, tip_position_sym
from continuum_mhe.model.settings import FormulationName
from continuum_mhe.model.tape import tape_function

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
        """Not finite, theta more than ``DIVERGED_MARGIN`` outside ``[0, theta_max]``, or
        the position more than three lengths from the base (:meth:`state_checks`)."""
        f64 = np.ascontiguousarray
        cov = None if P is None else f64(P, dtype=np.float64)
        return bool(self._checks.is_diverged(f64(x, dtype=np.float64), cov))

    def at_bound(self, x: FloatArray) -> bool:
        """theta on ``theta_max`` (or beyond), or, with the section bent by more than
        :data:`PHI_BOUND_THETA` (nearly straight, phi hardly moves the shape), phi on its
        state bound ``-pi`` or ``pi`` (within :data:`AT_BOUND_TOL`): the MHE's box cannot
        wrap phi, and holds it there while the bending plane turns past it."""
        return bool(self._checks.at_bound(np.ascontiguousarray(x, dtype=np.float64)))

    def drifted(self, x: FloatArray) -> bool:
        """The position state is more than :data:`DRIFT_FRACTION` of the length from the
        forward kinematics of its own theta and phi (status ``drifted``)."""
        return bool(self._checks.drifted(np.ascontiguousarray(x, dtype=np.float64)))

    def state_checks(self) -> _core.StateChecks:
        """:meth:`is_diverged`, :meth:`at_bound` and :meth:`drifted` as data for the
        compiled core: one function of the state, taped from its symbolic form."""
        return self._checks

    @cached_property
    def _checks(self) -> _core.StateChecks:
        x = ca.SX.sym("x", 5)
        position, theta, phi = x[:3], x[3], x[4]
        length, theta_max = self.length, self.robot.theta_max
        diverged = ca.logic_or(
            ca.logic_or(theta < -DIVERGED_MARGIN, theta > theta_max + DIVERGED_MARGIN),
            ca.sumsqr(position) > (3 * length) ** 2,
        )
        # (a filter's phi passes the bound, unheld: on it, not beyond it)
        on_phi = ca.logic_and(
            theta > PHI_BOUND_THETA, ca.fabs(ca.fabs(phi) - math.pi) <= AT_BOUND_TOL
        )
        at_bound = ca.logic_or(theta >= theta_max - AT_BOUND_TOL, on_phi)
        drift = position - tip_position_sym(theta, phi, length)
        drifted = ca.sumsqr(drift) > (DRIFT_FRACTION * length) ** 2
        flags = ca.Function("paper_checks", [x], [ca.vertcat(diverged, at_bound, drifted)])
        return _core.StateChecks(
            nx=self.nx, pairs=[], diverged_r2=[], at_bound_r=[], rate_rows=[],
            rate_limit=math.inf, std_rows=[], std_limit2=math.inf, flags=tape_function(flags),
        )  # fmt: skip

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
        """``(theta_dot, phi_dot)``, rad/s: the change of the shape read from the readings
        (:func:`~continuum_mhe.model.imu.shape_from_tilt`, phi's wrapped) over ``dt`` s;
        zero without a previous reading or where either has a dropout
        (:attr:`input_function`)."""
        f64 = np.ascontiguousarray
        prev = None if z_prev is None else f64(z_prev, dtype=np.float64)
        return np.asarray(self.input_function(prev, f64(z, dtype=np.float64), dt))

    @cached_property
    def input_function(self) -> _core.CompiledInputs:
        """:meth:`inputs` in compiled code, taped from its symbolic form."""
        mounting = self.robot.mounting
        z_prev, z, dt = ca.SX.sym("z_prev", 2), ca.SX.sym("z", 2), ca.SX.sym("dt")
        theta0, phi0 = shape_from_tilt_sym(z_prev, mounting)
        theta1, phi1 = shape_from_tilt_sym(z, mounting)
        u = ca.vertcat((theta1 - theta0) / dt, wrap_angle_sym(phi1 - phi0) / dt)
        fn = ca.Function("paper_inputs", [z_prev, z, dt], [u])
        return _core.CompiledInputs(tape_function(fn), nz=2, nu=2)
