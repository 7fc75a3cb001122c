"""Motion models ("formulations") shared by every estimator.

A formulation fixes the state, the discrete transition ``x+ = f(x, u, dt)``, the
measurement ``z = h(x)`` (one block per IMU), the noise covariances, the feasible set,
and the outputs. Each is written once, symbolically; :attr:`Formulation.functions`
compiles the numeric versions the filters use, and the MHE builds its NLP from the same
symbolic methods. The robot (:class:`~continuum_mhe.model.robot.Robot`) is data: the
same formulation code serves one section with a tip IMU or several sections with an IMU
each.

* ``bend`` (default): state ``[a_1, b_1, ..., a_n, b_n, a_1', b_1', ..., b_n']``, the
  bend vector ``(a_k, b_k) = (theta_k cos phi_k, theta_k sin phi_k)`` of every section
  and its rate, with a constant-velocity model driven by white-noise acceleration.
  Positions always equal the PCC forward kinematics; nothing is singular at a straight
  section. Measurement: roll and pitch of every IMU. Feasible set: one disk
  ``a_k^2 + b_k^2 <= theta_max_k^2`` per section.
* ``paper``: the paper's state ``[x, y, z, theta, phi]`` (one section, tip IMU) with
  ``u = [theta_dot, phi_dot]`` from consecutive readings and the (sign-corrected)
  Euler step ``x+ = x + dt [J u; u]``; process noise ``W^-1`` is a soft penalty.
  Feasible set: eq. (11) boxes.
* ``direct`` (:mod:`continuum_mhe.model.direct`): the ``bend`` state with raw IMUs.

Formulations are looked up by name in :mod:`continuum_mhe.model.registry`.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import ClassVar

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.model.descriptions import (
    MeasurementBlock,
    OutputSpec,
    pcc_outputs,
    tilt_blocks,
    wrapped_indices,
)
from continuum_mhe.model.imu import (
    shape_from_tilt,
    tilt_from_gravity_sym,
    tilt_sym,
    tilt_tangent_residual_sym,
    wrap_angle,
)
from continuum_mhe.model.kinematics import Sym, rotation_bend, tip_position, tip_position_sym
from continuum_mhe.model.pcc import gravity_direction_at_sym, pose_at_sym, shape_rank, up_vector
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.settings import FormulationName, NoiseSettings, RobotSettings


@dataclass(frozen=True)
class ChangeTest:
    """The estimate-change test of slowly varying states (random walks, such as an
    IMU's misalignment and biases): between the estimate ``lag`` seconds ago and this
    one, the change of these states against the covariance that the information gained
    and their random walk give it (``P_then + Q(dt) - P_now``), beyond the chi-square
    quantile of ``probability``, makes an estimate ``drifted``.

    Attributes:
        rows: the states' indices.
        scale: their prior standard deviations (the test's units).
        psd: their random walks' white-noise densities, per second.
        lag: the time between the two estimates compared, s.
        probability: the chi-square probability of the limit.
    """

    rows: tuple[int, ...]
    scale: tuple[float, ...]
    psd: tuple[float, ...]
    lag: float
    probability: float


class ModelFunctions:
    """Numeric CasADi functions of a formulation's symbolic model, each built on first
    use (a model whose symbolic Jacobians are large, such as the tendon robot's, builds
    only the functions an estimator asks for).

    ``predict(x, u, dt) -> (x+, F, Q)``, ``measure(x) -> (h, H)``,
    ``innovate(z, x) -> (r, dr/dx)`` (the residual the estimators weight with
    ``R^-1``), ``output(x) -> outputs`` (see :attr:`Formulation.outputs`),
    ``transition(x, u, dt) -> x+`` and ``observe(x) -> h``.
    """

    def __init__(self, formulation: Formulation) -> None:
        self._formulation = formulation
        f = formulation
        self._x = ca.SX.sym("x", f.nx)
        self._u = ca.SX.sym("u", f.nu)
        self._dt = ca.SX.sym("dt")
        self._z = ca.SX.sym("z", f.nz)

    @cached_property
    def _next_state(self) -> Sym:
        return self._formulation.transition_sym(self._x, self._u, self._dt)

    @cached_property
    def _reading(self) -> Sym:
        return self._formulation.measurement_sym(self._x)

    @cached_property
    def predict(self) -> ca.Function:
        xn, x = self._next_state, self._x
        q = self._formulation.process_cov_sym(self._dt)
        return ca.Function("predict", [x, self._u, self._dt], [xn, ca.jacobian(xn, x), q])

    @cached_property
    def measure(self) -> ca.Function:
        h, x = self._reading, self._x
        return ca.Function("measure", [x], [h, ca.jacobian(h, x)])

    @cached_property
    def innovate(self) -> ca.Function:
        r = self._formulation.measurement_residual_sym(self._z, self._x)
        return ca.Function("innovate", [self._z, self._x], [r, ca.jacobian(r, self._x)])

    @cached_property
    def output(self) -> ca.Function:
        return ca.Function("output", [self._x], [self._formulation.output_sym(self._x)])

    @cached_property
    def transition(self) -> ca.Function:
        return ca.Function("f", [self._x, self._u, self._dt], [self._next_state])

    @cached_property
    def observe(self) -> ca.Function:
        return ca.Function("h", [self._x], [self._reading])


def as_robot(robot: Robot | RobotSettings | None) -> Robot:
    """A :class:`Robot` from a robot, one-section settings, or None (the default)."""
    if robot is None:
        robot = RobotSettings()
    if isinstance(robot, RobotSettings):
        return Robot.single(robot.length, robot.theta_max, robot.mounting)
    return robot


@dataclass(frozen=True)
class Formulation:
    """Base class: subclasses define the symbolic model.

    Attributes:
        robot: the robot (a :class:`RobotSettings` is turned into a one-section robot).
        noise: noise settings shared by every estimator.
    """

    robot: Robot = field(default_factory=lambda: Robot.single())
    noise: NoiseSettings = field(default_factory=NoiseSettings)

    name: FormulationName = "bend"
    #: whether each tilt block's residual is an angle difference wrapped to (-pi, pi]
    #: (:meth:`measurement_residual_sym`), or a smooth chart that never wraps (the bend
    #: formulation's tangent plane, singular at a half turn; formulations without tilt
    #: blocks inherit theirs unused)
    tilt_residual_wraps: ClassVar[bool] = True
    #: whether the fast MHE adds the measurement residuals' second derivatives to its
    #: Hessian (exact Newton steps); False for a model whose second derivatives are too
    #: large to form symbolically (a shooting model): Gauss-Newton steps, the same
    #: minimum, a slower final convergence
    second_order_residuals: ClassVar[bool] = True
    #: why the fast MHE cannot take this formulation (None: it can); where it cannot,
    #: the MHE solves every window with IPOPT and the EKF is the default estimator
    #: (:func:`continuum_mhe.estimators.default_method`)
    fast_mhe_obstacle: ClassVar[str | None] = None
    #: whether the compiled core takes the measurement Jacobian by forward-mode
    #: differentiation of the residual's instructions (``csrc/forward.hpp``) instead of
    #: evaluating a symbolic Jacobian: True for a model whose symbolic Jacobian is far
    #: larger than the model (a shooting model)
    forward_mode_jacobian: ClassVar[bool] = False
    #: whether the outputs' standard deviations come from sigma points on the states the
    #: outputs depend on (:meth:`output_std`), which carry the outputs' curvature, or are
    #: linearised (``sqrt(diag(J P J^T))``): False for a model whose outputs cost a
    #: shooting each, where the 2 x (states) sigma-point evaluations would cost more
    #: than a filter step
    sigma_point_output_std: ClassVar[bool] = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "robot", as_robot(self.robot))

    # --- sizes and descriptions -----------------------------------------------------
    @property
    def state_names(self) -> tuple[str, ...]:
        raise NotImplementedError

    @property
    def nx(self) -> int:
        return len(self.state_names)

    @property
    def nu(self) -> int:
        return 0

    # The descriptions below are fixed by the (frozen) formulation and read on every
    # sample by the estimators: computed once.
    @cached_property
    def measurement_blocks(self) -> tuple[MeasurementBlock, ...]:
        """One block per IMU, in the robot's IMU order."""
        return tilt_blocks(self.robot.n_imus)

    @cached_property
    def nz(self) -> int:
        """Size of the measurement vector z."""
        return sum(b.size for b in self.measurement_blocks)

    @cached_property
    def measurement_names(self) -> tuple[str, ...]:
        return tuple(n for b in self.measurement_blocks for n in b.names)

    @cached_property
    def outputs(self) -> tuple[OutputSpec, ...]:
        """The outputs, in order (see :func:`~continuum_mhe.model.descriptions.pcc_outputs`)."""
        return pcc_outputs(self.robot.n_sections)

    @cached_property
    def ny(self) -> int:
        return len(self.outputs)

    @cached_property
    def _block_slices(self) -> tuple[slice, ...]:
        return tuple(b.slice for b in self.measurement_blocks)

    def measurement_mask(self, z: FloatArray) -> FloatArray:
        """``(nz,)``: 1.0 on the components of every block whose values are all finite
        (a sensor that reported), 0.0 on the others (a dropout of that sensor only)."""
        finite = np.isfinite(z)
        if finite.all():
            return np.ones(len(finite))
        mask = np.zeros(len(finite))
        for sl in self._block_slices:
            if finite[sl].all():
                mask[sl] = 1.0
        return mask

    # --- symbolic model (override) ---------------------------------------------
    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        raise NotImplementedError

    def measurement_sym(self, x: Sym) -> Sym:
        raise NotImplementedError

    def process_cov_sym(self, dt: Sym) -> Sym:
        raise NotImplementedError

    def process_cov(self, dt: float) -> FloatArray:
        """``Q(dt)``: :meth:`process_cov_sym` over a step of ``dt`` s, as numbers."""
        return np.array(ca.evalf(self.process_cov_sym(ca.DM(dt))), dtype=float)

    @property
    def process_noise_source(self) -> str:
        """What sets :meth:`process_cov_sym`, in words, for a message that names an
        option that does not reach it."""
        return "the bends' white-noise acceleration (NoiseSettings.bend_accel_psd)"

    def output_sym(self, x: Sym) -> Sym:
        """The outputs (:attr:`outputs`; m, rad) from the state."""
        raise NotImplementedError

    def constraint_sym(self, x: Sym) -> tuple[Sym, FloatArray, FloatArray]:
        """Nonlinear path constraints ``lo <= g(x) <= hi`` (empty if none)."""
        return ca.SX(0, 1), np.zeros(0), np.zeros(0)

    def state_bounds(self) -> tuple[FloatArray, FloatArray]:
        return np.full(self.nx, -np.inf), np.full(self.nx, np.inf)

    # --- numeric helpers (override) ----------------------------------------------
    def imus_determine_shape(self, imus: tuple[int, ...]) -> bool:
        """Whether the IMUs ``imus`` (0-based) alone determine the shape: their
        independent tilt readings (:func:`~continuum_mhe.model.pcc.shape_rank`) match
        the bend coordinates."""
        robot = self.robot
        if len(imus) == robot.n_imus:
            sub = robot
        else:
            sub = replace(robot, imus=tuple(robot.imus[k] for k in imus))
        return shape_rank(sub) == 2 * robot.n_sections

    #: what makes an unobservable robot observable (the warning's hint)
    observable_hint: ClassVar[str] = (
        "one IMU per section makes it observable; `continuum-mhe check-robot` tells"
    )

    def unobservable_detail(self, rank: int, bends: int) -> str:
        """What the IMUs miss, for the warning of a robot whose shape they do not
        determine (``rank`` of ``bends`` bend coordinates by
        :func:`~continuum_mhe.model.pcc.shape_rank`)."""
        return f"determine {rank} of its {bends} bend coordinates"

    def initial_state(self, z0: FloatArray) -> FloatArray:
        raise NotImplementedError

    def initial_cov(self) -> FloatArray:
        raise NotImplementedError

    def start_prior(self, z0: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(x0, P0)``: the prior every estimator starts (and restarts) from at the
        reading ``z0``, before its update with that reading: :meth:`initial_state` and
        :meth:`initial_cov` (a formulation whose prior depends on what the reading shows
        overrides this)."""
        return self.initial_state(z0), self.initial_cov()

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

    def is_diverged(self, x: FloatArray, P: FloatArray | None = None) -> bool:
        """True when a state (and covariance) cannot be a meaningful estimate: not
        finite, or far outside the workspace (see subclasses)."""
        if not np.isfinite(x).all():
            return True
        return P is not None and not np.isfinite(P).all()

    def drifted(self, x: FloatArray) -> bool:
        """True when a state is not one consistent shape (only formulations with
        redundant states can drift; see :class:`PaperFormulation`)."""
        return False

    def at_bound(self, x: FloatArray) -> bool:
        """True when a section's bending angle sits within :data:`AT_BOUND_TOL` of its
        ``theta_max`` or beyond it (status ``at-bound``: the MHE holds a bend there, and
        the bound, not the data, set the shape; a filter's estimate passes it)."""
        return False

    def state_checks(self) -> _core.StateChecks | None:
        """The checks of a state (:meth:`is_diverged`, :meth:`at_bound`; nothing
        drifts) as data for the compiled core, or None: the core asks these methods."""
        return None

    def change_test(self) -> ChangeTest | None:
        """The slowly varying states whose estimate may not move faster than their
        model allows (the estimate-change test, status ``drifted``), or None: none."""
        return None

    # --- shared -------------------------------------------------------------------
    def meas_cov(self) -> FloatArray:
        """``R``: block-diagonal, one block per IMU (roll, pitch: ``measurement_std``)."""
        return np.eye(self.nz) * self.noise.measurement_std**2

    def gravity_direction_rows(self) -> NDArray[np.bool_]:
        """Which readings (nz,) are gravity directions, the readings that set the shape
        and carry an IMU's constant error (here every reading is one: roll and
        pitch)."""
        return np.ones(self.nz, dtype=bool)

    def reading_bias_cov(self) -> FloatArray:
        """The covariance (nz, nz) of the readings' constant errors, in the residual's
        units: ``noise.reading_bias_std^2`` on each gravity-direction reading
        (:meth:`gravity_direction_rows`)."""
        return np.diag(self.gravity_direction_rows() * self.noise.reading_bias_std**2)

    def model_error_floor(self) -> float:
        """The variance of each gravity-direction reading's model error assumed before
        the readings show one, in the residual's units (rad^2):
        ``noise.model_error_std^2``, the constant-curvature model's error of a real
        robot."""
        return float(self.noise.model_error_std**2)

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """Residual ``r(z, x)``, "measurement minus model", weighted by ``R^-1``.

        Here ``z - h(x)`` with every angle wrapped to ``(-pi, pi]`` (the paper's
        measurement model); formulations may override it. Every estimator uses it: the
        MHE's cost, and the filters' innovation with ``H = -dr/dx``.
        """
        d = z - self.measurement_sym(x)
        return ca.atan2(ca.sin(d), ca.cos(d))

    @cached_property
    def functions(self) -> ModelFunctions:
        """The model's numeric functions (each built on first use)."""
        return ModelFunctions(self)

    #: Whether ``Q`` and ``R`` are noise models, so that the covariances the estimators
    #: compute from them describe the errors (the ``uncertain`` status relies on it).
    calibrated_covariance = True
    #: Bad-start restarts in a row (each within the probation time of the one before,
    #: the readings inconsistent after each) after which the estimators stop restarting
    #: until a restart holds through its probation time or another kind of restart;
    #: None: no limit. A restart of this model fits its shape to one reading, cheaply, and
    #: where the model cannot follow the robot (the shipped ``spatial`` rod, raw IMUs,
    #: twisting 120 degrees) the restarts keep the estimates nearer the robot (MHE mean
    #: tip error 68.5 mm without a limit, 154 mm with a limit of 3).
    bad_start_chain: ClassVar[int | None] = None

    @cached_property
    def output_jacobian(self) -> ca.Function:
        """``J(x) = d output / d x`` (ny, nx), written once from :meth:`output_sym`."""
        x = ca.SX.sym("x", self.nx)
        return ca.Function("output_jacobian", [x], [ca.jacobian(self.output_sym(x), x)])

    @cached_property
    def sigma_states(self) -> tuple[int, ...]:
        """The states the outputs depend on (the columns of the output Jacobian's
        sparsity), over which :meth:`output_std` places its sigma points; ``()`` where
        :attr:`sigma_point_output_std` is False (linearised standard deviations)."""
        if not self.sigma_point_output_std:
            return ()
        x = ca.SX.sym("x", self.nx)
        jac = ca.jacobian(self.output_sym(x), x).sparsity()
        return tuple(sorted(set(jac.get_col())))

    def output_std(self, x: FloatArray, P: FloatArray) -> FloatArray:
        """One standard deviation of every output (ny,) (m, rad) for a state with mean
        ``x`` and covariance ``P``: the root mean square of ``y(X) - y(x)`` over the
        ``2 s`` sigma points ``X = x +- sqrt(s) L e_j`` with ``L L^T = P[S, S]`` on the
        ``s`` states :attr:`sigma_states` (the unscented transform, weights ``1 / (2 s)``;
        wrapped outputs' differences wrapped to ``[-pi, pi)``). It carries the outputs'
        curvature: where a section is straight, its end's ``z`` has no first derivative
        and a linearised standard deviation would be zero whatever ``P``. Without
        :attr:`sigma_states`: ``sqrt(diag(J P J^T))``, linearised at ``x``. The compiled
        core computes the same (``NodeModel::output_std``)."""
        x = np.asarray(x, dtype=float)
        P = np.asarray(P, dtype=float)
        S = list(self.sigma_states)
        if not S:
            J = np.asarray(self.output_jacobian(x), dtype=float).reshape(self.ny, self.nx)
            var = np.einsum("ij,jk,ik->i", J, P, J)
            return np.sqrt(np.maximum(var, 0.0))
        s = len(S)
        L = psd_cholesky(P[np.ix_(S, S)])
        points = np.tile(x, (2 * s + 1, 1))  # x, then the sigma points
        points[1 : s + 1, S] += math.sqrt(s) * L.T
        points[s + 1 :, S] -= math.sqrt(s) * L.T
        y = np.asarray(self.functions.output(points.T), dtype=float).reshape(self.ny, -1).T
        d = y[1:] - y[0]
        wrapped = list(wrapped_indices(self.outputs))
        d[:, wrapped] = wrap_angle(d[:, wrapped])
        return np.sqrt(np.mean(d * d, axis=0))

    def output(self, x: FloatArray) -> FloatArray:
        """Outputs ``(ny,)`` for a state ``(nx,)``, or ``(n, ny)`` for states ``(n, nx)``;
        wrapped angles in ``[-pi, pi)``."""
        x = np.asarray(x, dtype=float)
        out = np.asarray(self.functions.output(np.atleast_2d(x).T), dtype=float)
        out = out.reshape(self.ny, -1).T
        for i in wrapped_indices(self.outputs):
            out[:, i] = wrap_angle(out[:, i])
        return out[0] if x.ndim == 1 else out


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


#: Divergence test (:meth:`BendFormulation.is_diverged`): rad beyond ``theta_max``.
DIVERGED_MARGIN = 1.0
#: Status ``at-bound`` (:meth:`Formulation.at_bound`): a bend within this many rad of
#: its ``theta_max`` (a constrained solver's answer on the bound is within its
#: tolerance of it, far below this; a free bend is that close about once in a thousand).
AT_BOUND_TOL = 1e-3
#: Status ``drifted`` (paper formulation): position state this share of the length away
#: from the forward kinematics of the state's theta and phi.
DRIFT_FRACTION = 0.1
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


@dataclass(frozen=True)
class PaperFormulation(Formulation):
    """The paper's five-state formulation, eqs. (3), (4), (10), (11), sign-corrected.
    One section with one IMU at its tip only."""

    name: FormulationName = "paper"
    #: ``W`` is a weight (a soft penalty), not a noise model: with ``W = 10 I`` the
    #: implied position covariance grows by 0.1 m^2 a step, so the standard deviations
    #: are reported as the model implies them but never turn an estimate ``uncertain``.
    calibrated_covariance = False

    def __post_init__(self) -> None:
        super().__post_init__()
        if not self.robot.is_single:
            raise UserError(
                "the paper formulation models one section with one tip IMU; "
                f"this robot has {self.robot.describe()}: leave --formulation paper out "
                "(the default model, bend with tilt readings and direct with raw ones, "
                "takes any robot)"
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
        return bool(x[3] >= self.robot.theta_max - AT_BOUND_TOL)

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


def psd_cholesky(A: FloatArray) -> FloatArray:
    """Lower ``L`` with ``L L^T = A`` for a symmetric positive semidefinite ``A``: the
    Cholesky factor (LAPACK's where ``A`` is positive definite), with a zero column
    where the pivot is below 1e-14 of ``A``'s largest diagonal entry (a direction
    without variance: a state held at a bound, or rounding). The compiled core's
    ``psd_cholesky`` (``csrc/filter.cpp``) is the same to rounding."""
    A = np.asarray(A, dtype=float)
    with contextlib.suppress(np.linalg.LinAlgError):  # positive definite: LAPACK's
        return np.asarray(np.linalg.cholesky(A), dtype=np.float64)
    n = A.shape[0]
    L = np.zeros_like(A)
    diag = np.diag(A)
    floor = 1e-14 * float(np.max(diag[~np.isnan(diag)], initial=0.0))
    for j in range(n):
        d = A[j, j] - L[j, :j] @ L[j, :j]
        if not d > floor:
            if math.isnan(d):
                L[j, j] = d
            continue
        L[j, j] = math.sqrt(d)
        L[j + 1 :, j] = (A[j + 1 :, j] - L[j + 1 :, :j] @ L[j, :j]) / L[j, j]
    return L
