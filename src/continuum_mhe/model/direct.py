"""Direct raw-IMU measurement model: gravity direction and gyro, no Euler angles.

The state and motion model are those of ``bend`` (bend vectors and their rates, rad
and rad/s, constant velocity). The measurement is six numbers per IMU, in that IMU's
frame (shown here for one section with a tip IMU)::

    z = [f / |f|, omega]      f: specific force (any unit), omega: gyro, rad/s

with the model

* ``f / |f| = R^T u`` (:func:`~continuum_mhe.model.imu.gravity_direction_bend_sym`,
  ``u`` the world's up direction for the mounting); the tip's own acceleration is
  not modelled and acts as measurement noise;
* ``omega = vee(R^T dR/dt)``, the tip's angular velocity in the tip frame, with
  ``dR/dt = dR/d(a, b) (a_dot, b_dot)`` by CasADi's chain rule on
  :func:`~continuum_mhe.model.kinematics.rotation_bend_sym`.

Residuals are plain differences (no wrapping), so nothing is singular at
``pitch = +-pi/2`` or at ``theta = 0``.

Gyro bias (``estimate_gyro_bias=True``): the state gains a bias ``b_i`` (rad/s, IMU
frame) per IMU, after the bend rates, and the gyro model becomes ``omega + b_i``. Each
bias is a random walk, ``b+ = b + w``, ``w ~ N(0, gyro_bias_psd dt I_3)``, with prior
standard deviation ``initial_gyro_bias_std`` about zero, or ``calibrated_gyro_bias_std``
for an IMU whose robot file gives a calibrated ``gyro_bias`` (not zero; the readings
have it removed, so the state is what is left of it). It is observable because the
accelerometers pin the bends and hence their rates; the estimates settle over seconds
(a few mrad/s after 12 s in the tests). It is a state, not an output.

Own acceleration (``own_acceleration=True``): the accelerometer reads the specific
force ``f = R^T (a + g u)``, where ``a = d^2p/dt^2`` is the IMU's acceleration. By
default ``a`` is left out (it acts as noise). With the option the motion model becomes
constant acceleration: the state gains the bend accelerations ``q''`` (rad/s^2) after
the rates, ``q+ = q + dt q' + dt^2/2 q''``, ``q'+ = q' + dt q''``, ``q''+ = q''`` with
white jerk of density ``bend_jerk_psd`` (replacing the white-noise acceleration of
``bend``), and ``a = J q'' + (dJ/dt) q'`` with ``J = dp/dq`` (CasADi's chain rule on the
composed position of each IMU).

Accelerometer bias (``estimate_accel_bias=True``): the state gains a bias ``c_i``
(m/s^2, IMU frame) per IMU, after the gyro biases if any, and the accelerometer model
becomes ``f/|f| = (g R^T u + c_i) / |g R^T u + c_i|`` with ``g`` standard gravity (the
model stays unit-free: the bias counts in units of ``|f|`` at rest). Each bias is a
random walk like the gyro's (``accel_bias_psd``, ``initial_accel_bias_std``).
Observability: at one pose the bias component along gravity only changes ``|f|``,
which the model does not read, and the two components across it are a tilt; so a
robot held in one pose cannot tell bias from bend. As the IMU turns through several
orientations the gyro ties the successive gravity directions together and a bias fixed
in the sensor frame separates from the bend; a board misalignment about x or y looks
the same as a bias at a pose and is partly absorbed by it.

IMU twist (``imu_twist=True``): each IMU's frame is the PCC frame at its place turned
about its z axis (the backbone's tangent) by a twist ``psi_i`` (rad), a state with its
rate after every other (``psi_1 .. psi_m``, then their rates), constant velocity driven
by white-noise acceleration (``twist_accel_psd``), starting untwisted. The accelerometer
reads ``Rz(psi_i)^T f`` (the bias, in the sensor frame, added after) and the gyro
``Rz(psi_i)^T omega + (0, 0, psi_i')``. It is what a rod that twists does to its IMUs and a
torsion-free PCC frame cannot: the positions stay the PCC model's. The twist and the
direction of the bending plane trade off (an accelerometer sees their difference, the
gyros integrated see each), so a gyro bias about the z axis turns the estimated plane:
where every IMU has a calibrated gyro bias (``continuum-mhe calibrate``), the biases are
held at it by default (:func:`gyro_biases_calibrated`), not estimated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, is_real
from continuum_mhe.model.bend import BendFormulation
from continuum_mhe.model.descriptions import (
    MeasurementBlock,
    OutputSpec,
    direct_blocks,
    imu_twist_outputs,
)
from continuum_mhe.model.imu import STANDARD_GRAVITY, shape_from_tilt, tilt_from_accelerometer
from continuum_mhe.model.kinematics import Sym, rotation_bend_sym
from continuum_mhe.model.pcc import angular_velocity_at_sym, pose_at_sym
from continuum_mhe.model.robot import ImuPlacement, Robot
from continuum_mhe.model.settings import FormulationName


def tip_angular_velocity_bend_sym(a: Sym, b: Sym, a_dot: Sym, b_dot: Sym) -> Sym:
    """Tip angular velocity of one section in the tip frame, rad/s: ``vee(R^T dR/dt)``.

    ``dR/dt`` is the chain rule through ``ca.jacobian`` of
    :func:`rotation_bend_sym`, so the kinematics are written once.
    """
    bend = ca.vertcat(a, b)
    rot = rotation_bend_sym(a, b)
    d_vec = ca.mtimes(ca.jacobian(ca.vec(rot), bend), ca.vertcat(a_dot, b_dot))
    w_hat = ca.mtimes(rot.T, ca.reshape(d_vec, 3, 3))
    # vee of the (skew-symmetric) matrix, averaged over both triangles
    return 0.5 * ca.vertcat(
        w_hat[2, 1] - w_hat[1, 2], w_hat[0, 2] - w_hat[2, 0], w_hat[1, 0] - w_hat[0, 1]
    )


#: Gyro white noise of the direct model, rad/s: a MEMS gyro's (MPU-9250 class: 0.01
#: deg/s/sqrt(Hz), 0.0012 rad/s at 50 Hz; the shipped rod recordings' IMUs 0.0018) with
#: room for the PCC model's own error in the rates (docs/options.md); the command
#: line's ``--gyro-std`` default too.
DEFAULT_GYRO_STD = 0.01


@dataclass(frozen=True)
class DirectFormulation(BendFormulation):
    """``bend`` state and motion, raw IMU measurement ``[f/|f|, omega]`` per IMU
    (6 per IMU).

    The gyro of an IMU sees the composed body rate of every section below it (and of
    its own section up to its place). By default the gyro bias is not estimated:
    calibrate it at rest (``continuum-mhe calibrate``) and subtract it; what remains
    counts as gyro noise. With ``estimate_gyro_bias`` each IMU's bias is a state (see
    the module docstring).

    Attributes:
        gyro_std: gyro noise standard deviation, rad/s (includes uncalibrated bias
            when the bias is not estimated).
        accel_direction_std: standard deviation of each component of ``f/|f|``
            (dimensionless, about rad). ``None`` uses ``noise.measurement_std``.
        estimate_gyro_bias: add a gyro bias per IMU to the state.
        gyro_bias_psd: the bias random walk's spectral density, (rad/s)^2/s.
        initial_gyro_bias_std: prior standard deviation of each bias, rad/s, for an IMU
            without a calibrated ``gyro_bias``.
        calibrated_gyro_bias_std: prior standard deviation of each bias, rad/s, for an
            IMU whose ``gyro_bias`` is calibrated (not zero): what a MEMS gyro's bias
            moves between a calibration at rest and a recording of the same session
            (warm-up, temperature).
        estimate_accel_bias: add an accelerometer bias per IMU to the state.
        accel_bias_psd: its random walk's spectral density, (m/s^2)^2/s.
        initial_accel_bias_std: prior standard deviation of each accelerometer bias
            component, m/s^2 (an MPU9250-class board after its factory trim: about
            10 mg, as the rod recordings' IMU model).
        own_acceleration: model each IMU's own acceleration in its specific force;
            the state gains the bend accelerations (constant acceleration, white jerk).
        bend_jerk_psd: the white jerk's spectral density per bend coordinate,
            rad^2/s^5 (used with ``own_acceleration``).
        initial_bend_accel_std: prior standard deviation of each bend acceleration,
            rad/s^2.
        imu_twist: a twist of each IMU about the backbone's tangent and its rate as
            states (see the module docstring).
        twist_accel_psd: the twists' white-noise acceleration density, rad^2/s^3.
        initial_twist_std: prior standard deviation of each twist (rad) and of its
            rate (rad/s) at a start, about zero (the robot starts untwisted).
    """

    name: FormulationName = "direct"
    gyro_std: float = DEFAULT_GYRO_STD
    accel_direction_std: float | None = None
    estimate_gyro_bias: bool = False
    gyro_bias_psd: float = 1e-6
    initial_gyro_bias_std: float = 0.05
    calibrated_gyro_bias_std: float = 0.01
    estimate_accel_bias: bool = False
    accel_bias_psd: float = 1e-6
    initial_accel_bias_std: float = 0.1
    own_acceleration: bool = False
    bend_jerk_psd: float = 4.0
    initial_bend_accel_std: float = 1.0
    imu_twist: bool = False
    twist_accel_psd: float = 0.5
    initial_twist_std: float = 0.02

    def __post_init__(self) -> None:
        super().__post_init__()
        for label, v in (
            ("gyro_std", self.gyro_std),
            ("accel_direction_std", self.accel_direction_std),
            ("gyro_bias_psd", self.gyro_bias_psd),
            ("initial_gyro_bias_std", self.initial_gyro_bias_std),
            ("calibrated_gyro_bias_std", self.calibrated_gyro_bias_std),
            ("accel_bias_psd", self.accel_bias_psd),
            ("initial_accel_bias_std", self.initial_accel_bias_std),
            ("bend_jerk_psd", self.bend_jerk_psd),
            ("initial_bend_accel_std", self.initial_bend_accel_std),
            ("twist_accel_psd", self.twist_accel_psd),
            ("initial_twist_std", self.initial_twist_std),
        ):
            if v is None and label == "accel_direction_std":  # (None: from gyro_std)
                continue
            # a number whose square (a variance) is a positive finite float: not None, a
            # string, 1e300 (an OverflowError in meas_cov) or 1e-300 (a zero variance)
            if not (
                is_real(v) and math.isfinite(v) and v > 0 and 0 < float(v) * float(v) < math.inf
            ):
                raise UserError(
                    f"{label} must be a positive finite number whose square a float holds, "
                    f"got {v!r}"
                )

    @cached_property
    def measurement_blocks(self) -> tuple[MeasurementBlock, ...]:
        return direct_blocks(self.robot.n_imus)

    # --- the bias states (after the bends and their rates: gyro, then accelerometer) --
    @property
    def n_gyro_bias(self) -> int:
        """Number of gyro-bias states: 3 per IMU when estimated, else 0."""
        return 3 * self.robot.n_imus if self.estimate_gyro_bias else 0

    @property
    def n_motion(self) -> int:
        """Number of motion states: bends and rates, and bend accelerations with
        ``own_acceleration``."""
        return (6 if self.own_acceleration else 4) * self.robot.n_sections

    @property
    def n_accel_bias(self) -> int:
        """Number of accelerometer-bias states: 3 per IMU when estimated, else 0."""
        return 3 * self.robot.n_imus if self.estimate_accel_bias else 0

    @property
    def n_bias(self) -> int:
        """Number of bias states (gyro and accelerometer)."""
        return self.n_gyro_bias + self.n_accel_bias

    @property
    def n_twist(self) -> int:
        """Number of twisted IMUs (``imu_twist``: every IMU, else 0); each has a twist
        and its rate as states, after the biases."""
        return self.robot.n_imus if self.imu_twist else 0

    def twists_sym(self, x: Sym) -> tuple[list[Sym], list[Sym]]:
        """``(psi, psi_dot)``: each IMU's twist (rad) and its rate (rad/s) (call only
        with ``imu_twist``)."""
        m, n0 = self.n_twist, self.n_motion + self.n_bias
        return [x[n0 + i] for i in range(m)], [x[n0 + m + i] for i in range(m)]

    def _bias_names(self, prefix: str) -> tuple[str, ...]:
        single = self.robot.n_imus == 1
        return tuple(
            f"{prefix}{c}" if single else f"{prefix}{c}_{i}"
            for i in range(1, self.robot.n_imus + 1)
            for c in "xyz"
        )

    @property
    def state_names(self) -> tuple[str, ...]:
        names = super().state_names
        if self.own_acceleration:
            names += tuple(f"{c}_ddot" for c in names[: 2 * self.robot.n_sections])
        if self.estimate_gyro_bias:
            names += self._bias_names("bg")
        if self.estimate_accel_bias:
            names += self._bias_names("ba")
        if self.imu_twist:
            single = self.robot.n_imus == 1
            twist = tuple("psi" if single else f"psi_{i}" for i in range(1, self.robot.n_imus + 1))
            names += twist + tuple(f"{c}_dot" for c in twist)
        return names

    def gyro_biases_sym(self, x: Sym) -> list[Sym]:
        """Gyro bias of each IMU, rad/s (call only when estimated)."""
        n4 = self.n_motion
        return [x[n4 + 3 * i : n4 + 3 * i + 3] for i in range(self.robot.n_imus)]

    def accel_biases_sym(self, x: Sym) -> list[Sym]:
        """Accelerometer bias of each IMU, m/s^2 (call only when estimated)."""
        n0 = self.n_motion + self.n_gyro_bias
        return [x[n0 + 3 * i : n0 + 3 * i + 3] for i in range(self.robot.n_imus)]

    def _rate_rows(self) -> list[int]:
        """As ``bend``'s; the bend accelerations (``own_acceleration``) are not held to
        the rate limit (a vibrating rod's can be hundreds of rad/s^2)."""
        n2 = 2 * self.robot.n_sections
        accel = range(2 * n2, 3 * n2) if self.own_acceleration else range(0)
        n0 = self.n_motion + self.n_bias
        twist = range(n0, n0 + self.n_twist)  # angles, not rates
        return [i for i in super()._rate_rows() if i not in accel and i not in twist]

    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        if not self.own_acceleration:
            moved = super().transition_sym(x, u, dt)
        else:
            n2 = 2 * self.robot.n_sections
            q, qd, qdd = x[:n2], x[n2 : 2 * n2], x[2 * n2 : 3 * n2]
            moved = ca.vertcat(q + dt * qd + dt**2 / 2 * qdd, qd + dt * qdd, x[2 * n2 :])
        if not self.imu_twist:
            return moved
        n0 = self.n_motion + self.n_bias
        psi, rate = self.twists_sym(x)
        return ca.vertcat(moved[:n0], *[p + dt * r for p, r in zip(psi, rate)], *rate)

    def _motion_cov_sym(self, dt: Sym) -> Sym:
        if not self.own_acceleration:
            return super().process_cov_sym(dt)
        j, n2 = self.bend_jerk_psd, 2 * self.robot.n_sections
        blk = j * ca.blockcat(
            [
                [dt**5 / 20, dt**4 / 8, dt**3 / 6],
                [dt**4 / 8, dt**3 / 3, dt**2 / 2],
                [dt**3 / 6, dt**2 / 2, dt],
            ]
        )
        return ca.kron(blk, ca.SX.eye(n2))

    @property
    def process_noise_source(self) -> str:
        if self.own_acceleration:
            return "the bends' white jerk, with their own acceleration (bend_jerk_psd)"
        return super().process_noise_source

    def process_cov_sym(self, dt: Sym) -> Sym:
        """The bends' white-noise acceleration (white jerk with ``own_acceleration``);
        each bias a random walk."""
        q = self._motion_cov_sym(dt)
        if self.estimate_gyro_bias:
            q = ca.diagcat(q, self.gyro_bias_psd * dt * ca.SX.eye(self.n_gyro_bias))
        if self.estimate_accel_bias:
            q = ca.diagcat(q, self.accel_bias_psd * dt * ca.SX.eye(self.n_accel_bias))
        if self.imu_twist:
            w = self.twist_accel_psd
            blk = w * ca.blockcat([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
            q = ca.diagcat(q, ca.kron(blk, ca.SX.eye(self.n_twist)))
        return q

    def initial_cov(self) -> FloatArray:
        # diagonal: the bends' and rates' variances (the base class's), then the bend
        # accelerations', the gyro biases' and the accelerometer biases'
        n2 = 2 * self.robot.n_sections if self.own_acceleration else 0
        var = np.concatenate(
            [
                np.diag(super().initial_cov()),
                np.full(n2, self.initial_bend_accel_std**2),
                self.gyro_bias_prior_std() ** 2,
                np.full(self.n_accel_bias, self.initial_accel_bias_std**2),
                np.full(2 * self.n_twist, self.initial_twist_std**2),
            ]
        )
        return np.diag(var)

    def gyro_bias_prior_std(self) -> FloatArray:
        """The gyro-bias states' prior standard deviations, rad/s (three per IMU, in the
        robot's IMU order; empty without ``estimate_gyro_bias``):
        ``calibrated_gyro_bias_std`` for an IMU with a calibrated ``gyro_bias`` (not
        zero), ``initial_gyro_bias_std`` for the others."""
        if not self.estimate_gyro_bias:
            return np.zeros(0)
        return np.repeat(
            [
                self.calibrated_gyro_bias_std
                if gyro_bias_calibrated(imu)
                else self.initial_gyro_bias_std
                for imu in self.robot.imus
            ],
            3,
        )

    @cached_property
    def outputs(self) -> tuple[OutputSpec, ...]:
        """``bend``'s, then with ``imu_twist`` each IMU's twist ``imu_twist_i`` (rad, about
        its z axis from the torsion-free frame; ``imu_twist`` for one IMU), unwrapped."""
        base = super().outputs
        if not self.imu_twist:
            return base
        return (*base, *imu_twist_outputs(self.robot.n_imus))

    def output_sym(self, x: Sym) -> Sym:
        """``bend``'s outputs, then each IMU's twist (``imu_twist``)."""
        base = super().output_sym(x)
        return ca.vertcat(base, *self.twists_sym(x)[0]) if self.imu_twist else base

    def range_std(self) -> FloatArray:
        """``bend``'s, and each IMU's twist (``imu_twist``) held to its prior standard
        deviation: the gyros, integrated, hold the twist, so a constant error of the
        accelerometers' directions is taken as a shift of the bends alone (turning the
        IMU about its z axis would take up part of it and narrow the bends' share). Each
        accelerometer bias (``estimate_accel_bias``, m/s^2) is held to its prior standard
        deviation too: a bias explains one sample's constant error of a direction
        exactly, so left free it would take up the misalignment and the model error as
        well and leave the bends none (on the shipped spatial-tendon rod, calibrated,
        349 of the EKF's 424 ``ok`` rows would lie more than 4 standard deviations off
        at the tip). With ``own_acceleration`` the bend accelerations and rates are held
        to their priors too (``initial_bend_accel_std``, rad/s^2, and the noise's
        ``initial_rate_std``, rad/s: the prior, clipped to this range, stays as given): a
        constant error is no lasting acceleration, as the bends would
        follow it, and the gyros hold the rates; left free they would take up part of it
        along directions that nearly repeat the bends' and shift the bends' share by 3
        to 5 times what it is without own acceleration, now more and now less (on the
        same rod, 164 of 368 ``ok`` rows beyond 4 standard deviations)."""
        std = super().range_std()
        n0 = self.n_motion + self.n_bias
        std[n0 : n0 + self.n_twist] = self.initial_twist_std
        na = self.n_motion + self.n_gyro_bias
        std[na : na + self.n_accel_bias] = self.initial_accel_bias_std
        if self.own_acceleration:
            n2 = 2 * self.robot.n_sections
            std[n2 : 2 * n2] = self.noise.initial_rate_std
            std[2 * n2 : 3 * n2] = self.initial_bend_accel_std
        return std

    def gravity_directions_sym(self, x: Sym) -> list[Sym]:
        """Unit specific-force direction at rest in each IMU's frame, with the
        accelerometer bias when estimated (see the module docstring)."""
        g = super().gravity_directions_sym(x)
        psi = self.twists_sym(x)[0] if self.imu_twist else [0.0] * len(g)
        if not (self.estimate_accel_bias or self.own_acceleration):
            return [_turned(p, gi) for p, gi in zip(psi, g)] if self.imu_twist else g
        n = self.robot.n_imus
        c = self.accel_biases_sym(x) if self.estimate_accel_bias else [0.0] * n
        if self.own_acceleration:
            n2 = 2 * self.robot.n_sections
            acc = self._imu_acceleration(x[:n2], x[n2 : 2 * n2], x[2 * n2 : 3 * n2])
            a = [acc[3 * i : 3 * i + 3] for i in range(n)]
        else:
            a = [0.0] * n
        out = []
        for gi, ci, ai, p in zip(g, c, a, psi):
            f = STANDARD_GRAVITY * gi + ai
            f = (_turned(p, f) if self.imu_twist else f) + ci
            out.append(f / ca.sqrt(ca.sumsqr(f)))
        return out

    @cached_property
    def _imu_acceleration(self) -> ca.Function:
        """``(bends, rates, bend accelerations) -> R^T d^2p/dt^2`` per IMU (3 m),
        m/s^2, ``d^2p/dt^2 = J qdd + (dJ/dt) qd`` with ``J = dp/dq``."""
        n2 = 2 * self.robot.n_sections
        q, qd, qdd = ca.SX.sym("q", n2), ca.SX.sym("qd", n2), ca.SX.sym("qdd", n2)
        bends = [(q[2 * k], q[2 * k + 1]) for k in range(self.robot.n_sections)]
        parts = []
        for imu in self.robot.imus:
            R, p = pose_at_sym(bends, self.robot.lengths, imu.section, imu.at)
            jac = ca.jacobian(p, q)
            v = ca.mtimes(jac, qd)
            a = ca.mtimes(jac, qdd) + ca.mtimes(ca.jacobian(v, q), qd)
            parts.append(ca.mtimes(R.T, a))
        return ca.Function("imu_acc", [q, qd, qdd], [ca.vertcat(*parts)])

    def angular_velocities_sym(self, x: Sym) -> list[Sym]:
        """Angular velocity in each IMU's frame, rad/s."""
        if self.robot.is_single:
            w = [tip_angular_velocity_bend_sym(x[0], x[1], x[2], x[3])]
        else:
            bends, rates = self.bends_sym(x), self.rates_sym(x)
            w = [
                angular_velocity_at_sym(bends, rates, imu.section, imu.at)
                for imu in self.robot.imus
            ]
        if not self.imu_twist:
            return w
        psi, rate = self.twists_sym(x)
        return [_turned(p, wi) + ca.vertcat(0, 0, r) for p, r, wi in zip(psi, rate, w)]

    def measurement_sym(self, x: Sym) -> Sym:
        g, w = self.gravity_directions_sym(x), self.angular_velocities_sym(x)
        if self.estimate_gyro_bias:
            w = [wi + bi for wi, bi in zip(w, self.gyro_biases_sym(x))]
        return ca.vertcat(*[ca.vertcat(gi, wi) for gi, wi in zip(g, w)])

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """``z - h(x)``, unwrapped (unit vector and rates are not angles)."""
        return z - self.measurement_sym(x)

    @property
    def gravity_direction_std(self) -> float:
        """The standard deviation of each component of an accelerometer's direction
        (about rad)."""
        return self.accel_direction_std or self.noise.measurement_std

    def meas_cov(self) -> FloatArray:
        f_std = self.gravity_direction_std
        one = np.diag([f_std**2] * 3 + [self.gyro_std**2] * 3)
        full = one if self.robot.n_imus == 1 else np.kron(np.eye(self.robot.n_imus), one)
        return np.asarray(full, dtype=np.float64)

    def gravity_direction_rows(self) -> NDArray[np.bool_]:
        """The accelerometer directions (the gyros' bias is a state or counted in
        ``gyro_std``)."""
        return np.tile([True] * 3 + [False] * 3, self.robot.n_imus)

    @cached_property
    def _rate_map(self) -> ca.Function:
        """``bends -> d omega / d rates`` (3 m x 2 n; omega is linear in the rates)."""
        x = ca.SX.sym("x", self.nx)
        n2 = 2 * self.robot.n_sections
        w = ca.vertcat(*self.angular_velocities_sym(x))
        return ca.Function("rate_map", [x], [ca.jacobian(w, x[n2 : 2 * n2])])

    def initial_state(self, z0: FloatArray) -> FloatArray:
        """Bends from the gravity directions (closed-form tilt inverse for one section,
        section by section otherwise), rates from the gyros by least squares, biases
        zero (their prior mean)."""
        z0 = np.asarray(z0, dtype=float)
        gravity: list[FloatArray | None] = []
        gyro_rows: list[int] = []
        for b in self.measurement_blocks:
            zb = z0[b.slice]
            ok = bool(np.all(np.isfinite(zb)))
            gravity.append(zb[:3] / np.linalg.norm(zb[:3]) if ok else None)
            if ok:
                gyro_rows += list(range(b.start + 3, b.start + 6))
        if self.robot.is_single and gravity[0] is not None:  # closed form
            roll, pitch = tilt_from_accelerometer(z0[:3])
            th, ph = shape_from_tilt(roll, pitch, self.robot.mounting)
            theta, phi = min(float(th), self.robot.theta_max), float(ph)
            bends = np.array([[theta * math.cos(phi), theta * math.sin(phi)]])
        else:
            bends = self._initial_bends(gravity)
        n2 = bends.size
        x = np.concatenate([bends.ravel(), np.zeros(self.nx - n2)])
        if gyro_rows:
            m = np.asarray(self._rate_map(x), dtype=float).reshape(self.nz // 2, n2, order="F")
            rows = [3 * (r // 6) + (r % 6 - 3) for r in gyro_rows]
            x[n2 : 2 * n2] = np.linalg.lstsq(m[rows], z0[gyro_rows], rcond=None)[0]
        return x


def gyro_bias_calibrated(imu: ImuPlacement) -> bool:
    """Whether ``imu`` has a gyro bias from a calibration (a robot file's ``gyro_bias``,
    not zero)."""
    return any(v != 0.0 for v in imu.gyro_bias)


def gyro_biases_calibrated(robot: Robot) -> bool:
    """Whether every IMU of ``robot`` has a gyro bias from a calibration
    (:func:`gyro_bias_calibrated`): with ``imu_twist`` their biases are then held at it,
    not estimated (a bias about an IMU's z axis and its twist trade off)."""
    return all(gyro_bias_calibrated(imu) for imu in robot.imus)


def _turned(psi: Sym, v: Sym) -> Sym:
    """``Rz(psi)^T v``: a vector of the frame before a turn by ``psi`` (rad) about its z
    axis, in the turned frame."""
    c, s = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2])


def direct_measurements(acc: FloatArray, gyr: FloatArray) -> FloatArray:
    """Measurement rows ``[f/|f|, omega]`` (n, 6) from raw specific force (n, 3), any
    unit, and gyro (n, 3) rad/s. A zero or non-finite accelerometer reading gives a
    NaN row (a dropout)."""
    acc = np.atleast_2d(np.asarray(acc, dtype=float))
    gyr = np.atleast_2d(np.asarray(gyr, dtype=float))
    norm = np.linalg.norm(acc, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = np.where(norm > 0, acc / norm, np.nan)
    z = np.hstack([unit, gyr])
    z[~np.all(np.isfinite(z), axis=1)] = np.nan
    return z


def raw_imu_readings(
    t: FloatArray,
    theta: FloatArray,
    phi: FloatArray,
    length: float,
    mounting: str = "z-up",
    gravity: float = STANDARD_GRAVITY,
) -> tuple[FloatArray, FloatArray]:
    """Noise-free raw IMU readings of a moving tip, for simulation and tests.

    Specific force ``f = R^T (a_tip + g u)`` in m/s^2, with ``a_tip`` the second
    finite difference of the true tip position, and angular rate
    ``omega = vee(R^T dR/dt)`` in rad/s from central differences of the rotation
    (independent of :func:`tip_angular_velocity_bend_sym`). ``t`` (n,) s, uniform.
    Returns ``(acc (n, 3), gyr (n, 3))``.
    """
    from continuum_mhe.model.kinematics import bend_from_shape, rotation_bend, tip_position_bend

    a, b = bend_from_shape(theta, phi)
    pos = tip_position_bend(a, b, length)
    rot = rotation_bend(a, b)
    acc_tip = np.gradient(np.gradient(pos, t, axis=0), t, axis=0)
    up = np.array([0.0, 0.0, 1.0 if mounting == "z-up" else -1.0])
    f = np.einsum("nji,nj->ni", rot, acc_tip + gravity * up)
    w_hat = np.einsum("nji,njk->nik", rot, np.gradient(rot, t, axis=0))
    gyr = 0.5 * np.stack(
        [
            w_hat[:, 2, 1] - w_hat[:, 1, 2],
            w_hat[:, 0, 2] - w_hat[:, 2, 0],
            w_hat[:, 1, 0] - w_hat[:, 0, 1],
        ],
        axis=-1,
    )
    return f, gyr
