"""Motion models ("formulations") shared by every estimator.

A formulation fixes the state, the discrete transition ``x+ = f(x, u, dt)``, the
measurement ``z = h(x)``, the noise covariances, and the feasible set. Each is written
once, symbolically; :meth:`Formulation.functions` compiles the numeric versions the
filters use, and the MHE builds its NLP from the same symbolic methods.

* ``bend`` (default): state ``[a, b, a_dot, b_dot]`` with the bend vector
  ``(a, b) = (theta cos phi, theta sin phi)`` and a constant-velocity model driven by
  white-noise acceleration. Position is always ``p(a, b)``; nothing is singular at
  ``theta = 0``. Feasible set: ``a^2 + b^2 <= theta_max^2``.
* ``paper``: the paper's state ``[x, y, z, theta, phi]`` with
  ``u = [theta_dot, phi_dot]`` from consecutive readings and the (sign-corrected)
  Euler step ``x+ = x + dt [J u; u]``; process noise ``W^-1`` is a soft penalty.
  Feasible set: eq. (11) boxes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.imu import (
    gravity_direction_bend_sym,
    shape_from_tilt,
    tilt_bend_sym,
    tilt_sym,
    tilt_tangent_residual_sym,
    wrap_angle,
)
from continuum_mhe.model.kinematics import (
    Sym,
    tip_position,
    tip_position_bend_sym,
    tip_position_sym,
)
from continuum_mhe.settings import FormulationName, NoiseSettings, RobotSettings

FloatArray = NDArray[np.float64]

OUTPUT_NAMES = ("x", "y", "z", "theta", "phi")


@dataclass(frozen=True)
class ModelFunctions:
    """Numeric CasADi functions compiled from a formulation's symbolic model.

    ``predict(x, u, dt) -> (x+, F, Q)``, ``measure(x) -> (h, H)``,
    ``innovate(z, x) -> (r, dr/dx)`` (the residual the estimators weight with
    ``R^-1``), ``output(x) -> [x, y, z, theta, phi]``.
    """

    predict: ca.Function
    measure: ca.Function
    innovate: ca.Function
    output: ca.Function
    transition: ca.Function
    observe: ca.Function


@dataclass(frozen=True)
class Formulation:
    """Base class: subclasses define the symbolic model."""

    robot: RobotSettings = field(default_factory=RobotSettings)
    noise: NoiseSettings = field(default_factory=NoiseSettings)

    name: FormulationName = "bend"
    state_names: tuple[str, ...] = ()
    nu: int = 0

    #: size of the measurement vector z
    nz: int = 2

    @property
    def nx(self) -> int:
        return len(self.state_names)

    # --- symbolic model (override) ---------------------------------------------
    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        raise NotImplementedError

    def measurement_sym(self, x: Sym) -> Sym:
        raise NotImplementedError

    def process_cov_sym(self, dt: Sym) -> Sym:
        raise NotImplementedError

    def output_sym(self, x: Sym) -> Sym:
        """``[x, y, z, theta, phi]`` (m, rad) from the state."""
        raise NotImplementedError

    def constraint_sym(self, x: Sym) -> tuple[Sym, float, float]:
        """Nonlinear path constraint ``lo <= g(x) <= hi`` (empty if none)."""
        return ca.SX(0, 1), 0.0, 0.0

    def state_bounds(self) -> tuple[FloatArray, FloatArray]:
        return np.full(self.nx, -np.inf), np.full(self.nx, np.inf)

    # --- numeric helpers (override) ----------------------------------------------
    def initial_state(self, z0: FloatArray) -> FloatArray:
        raise NotImplementedError

    def initial_cov(self) -> FloatArray:
        raise NotImplementedError

    def inputs(self, z_prev: FloatArray | None, z: FloatArray, dt: float) -> FloatArray:
        """Input ``u`` driving the transition into the sample with measurement ``z``."""
        return np.zeros(self.nu)

    def project(self, x: FloatArray) -> FloatArray:
        """Closest feasible state (used only for flagged fallbacks)."""
        lo, hi = self.state_bounds()
        return np.clip(x, lo, hi)

    def is_feasible(self, x: FloatArray, tol: float = 1e-7) -> bool:
        lo, hi = self.state_bounds()
        return bool(np.all(x >= lo - tol) and np.all(x <= hi + tol))

    # --- shared -------------------------------------------------------------------
    def meas_cov(self) -> FloatArray:
        return np.eye(2) * self.noise.measurement_std**2

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """Residual ``r(z, x)``, "measurement minus model", weighted by ``R^-1``.

        Here ``z - h(x)`` with both angles wrapped to ``(-pi, pi]`` (the paper's
        measurement model); formulations may override it. Every estimator uses it: the
        MHE's cost, and the filters' innovation with ``H = -dr/dx``.
        """
        d = z - self.measurement_sym(x)
        return ca.atan2(ca.sin(d), ca.cos(d))

    @cached_property
    def functions(self) -> ModelFunctions:
        x = ca.SX.sym("x", self.nx)
        u = ca.SX.sym("u", self.nu)
        dt = ca.SX.sym("dt")
        xn = self.transition_sym(x, u, dt)
        h = self.measurement_sym(x)
        z = ca.SX.sym("z", self.nz)
        r = self.measurement_residual_sym(z, x)
        return ModelFunctions(
            predict=ca.Function(
                "predict", [x, u, dt], [xn, ca.jacobian(xn, x), self.process_cov_sym(dt)]
            ),
            measure=ca.Function("measure", [x], [h, ca.jacobian(h, x)]),
            innovate=ca.Function("innovate", [z, x], [r, ca.jacobian(r, x)]),
            output=ca.Function("output", [x], [self.output_sym(x)]),
            transition=ca.Function("f", [x, u, dt], [xn]),
            observe=ca.Function("h", [x], [h]),
        )

    def output(self, x: FloatArray) -> FloatArray:
        """``[x, y, z, theta, phi]`` for states ``x`` of shape ``(nx,)`` or ``(n, nx)``."""
        x = np.asarray(x, dtype=float)
        out = np.asarray(self.functions.output(np.atleast_2d(x).T), dtype=float)
        out = out.reshape(5, -1).T
        out[:, 4] = wrap_angle(out[:, 4])
        return out[0] if x.ndim == 1 else out


@dataclass(frozen=True)
class BendFormulation(Formulation):
    """Default formulation: bend vector and its rate, constant-velocity model."""

    name: FormulationName = "bend"
    state_names: tuple[str, ...] = ("a", "b", "a_dot", "b_dot")
    nu: int = 0

    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        return ca.vertcat(x[0] + dt * x[2], x[1] + dt * x[3], x[2], x[3])

    def measurement_sym(self, x: Sym) -> Sym:
        return tilt_bend_sym(x[0], x[1], self.robot.mounting)

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """Tilt residual on the tangent plane of the measured gravity direction
        (stereographic). Smooth everywhere (no Euler-angle wrap or gimbal lock), norm
        ``2 tan(error/2)``; to first order ``(cos(pitch) d_roll, d_pitch)``. See
        :func:`imu.tilt_tangent_residual_sym`.
        """
        f_model = gravity_direction_bend_sym(x[0], x[1], self.robot.mounting)
        return tilt_tangent_residual_sym(z, f_model)

    def process_cov_sym(self, dt: Sym) -> Sym:
        q = self.noise.bend_accel_psd
        q11, q12, q22 = q * dt**3 / 3, q * dt**2 / 2, q * dt
        return ca.vertcat(
            ca.horzcat(q11, 0, q12, 0),
            ca.horzcat(0, q11, 0, q12),
            ca.horzcat(q12, 0, q22, 0),
            ca.horzcat(0, q12, 0, q22),
        )

    def output_sym(self, x: Sym) -> Sym:
        p = tip_position_bend_sym(x[0], x[1], self.robot.length)
        return ca.vertcat(p, ca.sqrt(x[0] ** 2 + x[1] ** 2), ca.atan2(x[1], x[0]))

    def constraint_sym(self, x: Sym) -> tuple[Sym, float, float]:
        return x[0] ** 2 + x[1] ** 2, -np.inf, self.robot.theta_max**2

    def initial_state(self, z0: FloatArray) -> FloatArray:
        th, ph = shape_from_tilt(z0[0], z0[1], self.robot.mounting)
        theta, phi = min(float(th), self.robot.theta_max), float(ph)
        return np.array([theta * math.cos(phi), theta * math.sin(phi), 0.0, 0.0])

    def initial_cov(self) -> FloatArray:
        n = self.noise
        return np.diag([n.initial_bend_std**2] * 2 + [n.initial_rate_std**2] * 2)

    def project(self, x: FloatArray) -> FloatArray:
        x = np.array(x, dtype=float)
        r = math.hypot(x[0], x[1])
        if r > self.robot.theta_max:
            x[:2] *= self.robot.theta_max / r
        return x

    def is_feasible(self, x: FloatArray, tol: float = 1e-7) -> bool:
        return bool(math.hypot(x[0], x[1]) <= self.robot.theta_max + tol)


@dataclass(frozen=True)
class PaperFormulation(Formulation):
    """The paper's five-state formulation, eqs. (3), (4), (10), (11), sign-corrected."""

    name: FormulationName = "paper"
    state_names: tuple[str, ...] = ("x", "y", "z", "theta", "phi")
    nu: int = 2

    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        p = tip_position_sym(x[3], x[4], self.robot.length)
        jac = ca.jacobian(p, x[3:5])
        return x + dt * ca.vertcat(ca.mtimes(jac, u), u)

    def measurement_sym(self, x: Sym) -> Sym:
        return tilt_sym(x[3], x[4], self.robot.mounting)

    def process_cov_sym(self, dt: Sym) -> Sym:
        return ca.SX.eye(5) / self.noise.paper_process_weight

    def output_sym(self, x: Sym) -> Sym:
        return x

    def state_bounds(self) -> tuple[FloatArray, FloatArray]:
        s = self.robot.length
        return (
            np.array([-s, -s, -s, 0.0, -math.pi]),
            np.array([s, s, s, self.robot.theta_max, math.pi]),
        )

    def initial_state(self, z0: FloatArray) -> FloatArray:
        th, ph = shape_from_tilt(z0[0], z0[1], self.robot.mounting)
        theta, phi = min(float(th), self.robot.theta_max), float(ph)
        pos = tip_position(theta, phi, self.robot.length)
        return np.array([*pos, theta, phi])

    def initial_cov(self) -> FloatArray:
        n = self.noise
        s = self.robot.length
        return np.diag([(0.1 * s) ** 2] * 3 + [n.initial_bend_std**2] * 2)

    def inputs(self, z_prev: FloatArray | None, z: FloatArray, dt: float) -> FloatArray:
        if z_prev is None or not np.all(np.isfinite(z_prev)) or not np.all(np.isfinite(z)):
            return np.zeros(2)
        t0, p0 = shape_from_tilt(z_prev[0], z_prev[1], self.robot.mounting)
        t1, p1 = shape_from_tilt(z[0], z[1], self.robot.mounting)
        return np.array([(t1 - t0) / dt, float(wrap_angle(p1 - p0)) / dt])


def make_formulation(
    name: FormulationName = "bend",
    robot: RobotSettings | None = None,
    noise: NoiseSettings | None = None,
) -> Formulation:
    """Formulation by name: ``"bend"`` (default), ``"paper"`` or ``"direct"`` (raw IMU)."""
    kwargs: dict[str, Any] = {
        "robot": robot or RobotSettings(),
        "noise": noise or NoiseSettings(),
    }
    if name == "bend":
        return BendFormulation(**kwargs)
    if name == "paper":
        return PaperFormulation(**kwargs)
    if name == "direct":  # raw IMU: gravity direction and gyro (model/direct.py)
        from continuum_mhe.model.direct import DirectFormulation

        return DirectFormulation(**kwargs)
    raise ValueError(f"formulation must be 'bend', 'paper' or 'direct', got {name!r}")
