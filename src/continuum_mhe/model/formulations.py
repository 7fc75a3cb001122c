"""Motion models ("formulations") shared by every estimator.

A formulation fixes the state, the discrete transition ``x+ = f(x, u, dt)``, the
measurement ``z = h(x)`` (one block per IMU), the noise covariances, the feasible set,
and the outputs. Each is written once, symbolically; :attr:`Formulation.functions`
compiles the numeric versions the filters use, and the MHE builds its NLP from the same
symbolic methods. The robot (:class:`~continuum_mhe.model.robot.Robot`) is data: the
same formulation code serves one section with a tip IMU or several sections with an IMU
each.

This module holds what every formulation provides (:class:`Formulation`); each
formulation is a module of its own:

* ``bend`` (default, :mod:`continuum_mhe.model.bend`): state
  ``[a_1, b_1, ..., a_n, b_n, a_1', b_1', ..., b_n']``, the
  bend vector ``(a_k, b_k) = (theta_k cos phi_k, theta_k sin phi_k)`` of every section
  and its rate, with a constant-velocity model driven by white-noise acceleration.
  Positions always equal the PCC forward kinematics; nothing is singular at a straight
  section. Measurement: roll and pitch of every IMU. Feasible set: one disk
  ``a_k^2 + b_k^2 <= theta_max_k^2`` per section.
* ``paper`` (:mod:`continuum_mhe.model.paper`): the paper's state
  ``[x, y, z, theta, phi]`` (one section, tip IMU) with ``u = [theta_dot, phi_dot]``
  from consecutive readings and the (sign-corrected) Euler step
  ``x+ = x + dt [J u; u]``; process noise ``W^-1`` is a soft penalty. Feasible set:
  eq. (11) boxes.
* ``direct`` (:mod:`continuum_mhe.model.direct`): the ``bend`` state with raw IMUs.
* ``tendon`` (:mod:`continuum_mhe.model.tendon`): a tendon-driven robot's mechanics,
  its tensions as inputs and its tip force as a state.

Formulations are looked up by name in :mod:`continuum_mhe.model.registry`.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field, fields, replace
from functools import cached_property, lru_cache
from typing import ClassVar, TypeAlias

import casadi as ca
import numpy as np
from numpy.typing import NDArray

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.model.descriptions import (
    MeasurementBlock,
    OutputSpec,
    pcc_outputs,
    tilt_blocks,
    wrapped_indices,
)
from continuum_mhe.model.imu import (
    wrap_angle,
)
from continuum_mhe.model.kinematics import Sym
from continuum_mhe.model.pcc import shape_rank
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.settings import FormulationName, NoiseSettings, RobotSettings

#: A model's inputs as the compiled core takes them: ``(z_prev | None, z, dt) -> u``
#: called back in Python, or taped (:meth:`Formulation.input_function`).
InputFunction: TypeAlias = (
    "Callable[[FloatArray | None, FloatArray, float], FloatArray] | _core.CompiledInputs"
)


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
        q = self._formulation.process_cov_sym(noise_step(self._dt))
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


#: A sensor state is kept by a restart (:meth:`Formulation.kept_sensors`) where the data
#: have informed it: its standard deviation below this fraction of its prior's (a tendon
#: robot's tension gains after one reading, kept, set a run 6.7 mm off instead of 1.3;
#: 0.5 dropped states informed enough to help: `twist-08` after a gap 10.6 mm instead of
#: 4.3).
KEPT_INFORMED_FRACTION = 0.8


@dataclass(frozen=True)
class KeptSensors:
    """What a restart within a recording keeps of the estimate before it
    (:meth:`Formulation.kept_sensors`): the sensor states ``states`` (indices into the
    state), their values and their covariance (``len(states)`` square)."""

    states: NDArray[np.intp]
    values: FloatArray
    cov: FloatArray


def without_load(
    x: FloatArray, P: FloatArray, load: tuple[int, ...]
) -> tuple[FloatArray, FloatArray]:
    """Copies of the state ``x`` (nx,) and its covariance ``P`` with the states ``load``
    zero and certain (their rows and columns of ``P`` zero)."""
    x, P = np.array(x, dtype=float), np.array(P, dtype=float)
    idx = np.asarray(load, dtype=np.intp)
    x[idx] = 0.0
    P[idx, :] = 0.0
    P[:, idx] = 0.0
    return x, P


@lru_cache(maxsize=32)
def shared_functions(formulation: Formulation) -> ModelFunctions:
    """The :class:`ModelFunctions` of ``formulation``, one for all formulations equal to
    it (frozen dataclasses compared by value): a robot's symbolic model is built once
    however many estimators are made of it."""
    return ModelFunctions(formulation)


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
    #: the UKF's sigma-point spread (Van der Merwe's alpha, in (0, 1]) where its
    #: :class:`~continuum_mhe.estimators.kalman.SigmaPointSettings` leave it to the model
    unscented_alpha: ClassVar[float] = 0.5
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

    def __getstate__(self) -> dict[str, object]:
        """Its fields alone, for pickle and copy: the descriptions and functions it
        builds on first use (symbolic expressions, the compiled core's objects) are
        built again by the copy, so a formulation pickles whether or not an estimator
        has used it."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # --- sizes and descriptions -----------------------------------------------------
    @property
    def state_names(self) -> tuple[str, ...]:
        """The names of the state vector's entries, in order (``bend``'s ``a_1, b_1, ...,
        a_1_dot, ...``; ``direct``'s gyro biases ``bgx_1, ...`` after them); an estimate's
        ``state`` and ``covariance`` follow this order."""
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
        """The names of ``z``'s columns, in order (``roll_1, pitch_1, ...`` for tilt IMUs,
        ``roll, pitch`` for one; ``fx_1, ..., wz_1, ...`` for raw ones): the blocks'
        names one after the other."""
        return tuple(n for b in self.measurement_blocks for n in b.names)

    @cached_property
    def outputs(self) -> tuple[OutputSpec, ...]:
        """The outputs, in order (see :func:`~continuum_mhe.model.descriptions.pcc_outputs`)."""
        return pcc_outputs(self.robot.n_sections)

    @cached_property
    def ny(self) -> int:
        """Number of outputs (the columns of an estimate's ``output``)."""
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

    def measurement_masks(self, z: FloatArray) -> FloatArray:
        """``(n, nz)``: :meth:`measurement_mask` of each of the readings ``z`` (n, nz)."""
        finite = np.isfinite(np.asarray(z, dtype=float))
        mask = np.zeros(finite.shape)
        for sl in self._block_slices:
            mask[:, sl] = finite[:, sl].all(axis=1, keepdims=True)
        mask[finite.all(axis=1)] = 1.0
        return mask

    # --- symbolic model (override) ---------------------------------------------
    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        """The next state ``f(x, u, dt)`` (nx,) from the state ``x`` (nx,), the input
        ``u`` (nu,) and the step ``dt`` (s), symbolic (CasADi)."""
        raise NotImplementedError

    def measurement_sym(self, x: Sym) -> Sym:
        """The readings ``h(x)`` (nz,) the state ``x`` predicts, in the units of
        :attr:`measurement_blocks` (rad for tilt, a unit direction and rad/s for
        ``direct``), symbolic; the estimators take residuals from it."""
        raise NotImplementedError

    def process_cov_sym(self, dt: Sym) -> Sym:
        """``Q(dt)`` (nx, nx): the process noise over a step of ``dt`` s, symbolic."""
        raise NotImplementedError

    def process_cov(self, dt: float) -> FloatArray:
        """``Q(dt)``: :meth:`process_cov_sym` over a step of ``dt`` s, as numbers, as
        every estimator takes it (over at least :data:`MIN_NOISE_STEP_S`:
        :func:`noise_step`)."""
        return np.array(ca.evalf(self.process_cov_sym(noise_step(ca.DM(dt)))), dtype=float)

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
        """``(lo, hi)`` (nx,) each: the box every estimate is held in (the MHE's hard
        bounds, the filters' projection; -inf and inf where a state is free)."""
        return np.full(self.nx, -np.inf), np.full(self.nx, np.inf)

    def range_std(self) -> FloatArray:
        """(nx,) each state's range that the robot allows, as the standard deviation of
        a Gaussian over it, in the state's units (inf where a state has no bound): the
        largest shift that the readings' constant errors are taken to make
        (:meth:`~continuum_mhe.estimators.consistency.ConsistencyCheck.constant_error_cov`)."""
        return np.full(self.nx, np.inf)

    def output_std_limit(self, beyond_bound: bool = False) -> FloatArray:
        """(ny,) the largest standard deviation each output can have: half the width of
        the range its value has on this robot, as no distribution within a range has a
        larger one (inf where an output has none). A point's coordinates (m) lie within
        the length of the backbone up to it of the base, an angle wrapped to a turn
        within pi of any value, a section's bend ``theta`` (rad) within 0 and its
        ``theta_max`` (``beyond_bound``: within 0 and pi, for an estimate held on a
        bound that may not be the robot's); a force or a gain has no range. The
        estimators hold the standard deviations they write to it where their covariance
        is one (:attr:`calibrated_covariance`: not the paper formulation's weight)."""
        robot = self.robot
        reach = np.cumsum(robot.lengths)
        bound = [math.pi if beyond_bound else s.theta_max for s in robot.sections]
        limit = np.full(self.ny, np.inf)
        for i, o in enumerate(self.outputs):
            if o.unit == "m":
                limit[i] = reach[o.section - 1] if o.section else reach[-1]
            elif o.unit == "rad" and o.wrapped:
                limit[i] = math.pi
            elif o.unit == "rad" and o.name.startswith("theta"):
                limit[i] = (bound[o.section - 1] if o.section else max(bound)) / 2.0
        return limit

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

    def free_bends(self, imus: tuple[int, ...] | None = None) -> tuple[tuple[int, int, float], ...]:
        """``(i, j, reach)`` for each section whose bend the IMUs (``imus``, 0-based:
        those alone, the others silent; None: every IMU) leave free: the state rows of
        its bend coordinates ``(a, b)`` and the radius of their range, its ``theta_max``
        (rad). No reading pins them, so an estimate may be any bend there: the written
        standard deviations carry the outputs' spread over those bends (the
        sensor-health policy). None here (a formulation whose IMUs may leave a section's
        bend free overrides this)."""
        return ()

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
        """The state (nx,) a start takes from the first reading ``z0`` (nz; NaN where a
        sensor dropped out): the estimators' prior mean (:meth:`start_prior`)."""
        raise NotImplementedError

    def initial_cov(self) -> FloatArray:
        """The prior covariance (nx, nx) of a start, in the state's units squared."""
        raise NotImplementedError

    @property
    def sensor_states(self) -> tuple[int, ...]:
        """The states that describe the sensors rather than the robot's motion
        (biases, misalignments, gains: what a restart within a recording keeps, see
        :meth:`kept_sensors`); none here."""
        return ()

    def kept_sensors(
        self, x: FloatArray | None, P: FloatArray | None, dt: float = 0.0
    ) -> KeptSensors | None:
        """What a restart within a recording keeps of the last estimate ``x`` (nx,) and
        its covariance ``P``, made ``dt`` s before the start: the :attr:`sensor_states`
        the data have informed (standard deviation below :data:`KEPT_INFORMED_FRACTION`
        of the prior's), their values and covariance grown by their process noise over
        ``dt`` (their random walks); None where none is, and for no estimate, a
        non-finite one, or one :meth:`drifted` (its sensor states may be why)."""
        idx = np.asarray(self.sensor_states, dtype=np.intp)
        if not len(idx) or x is None or P is None:
            return None
        x, P = np.asarray(x, dtype=float), np.asarray(P, dtype=float)
        if not (np.isfinite(x).all() and np.isfinite(P).all()) or self.drifted(x):
            return None
        prior = np.sqrt(np.diag(self.initial_cov())[idx])
        idx = idx[np.sqrt(np.diag(P)[idx]) < KEPT_INFORMED_FRACTION * prior]
        if not len(idx):
            return None
        cov = P[np.ix_(idx, idx)].copy()
        if dt > 0.0:
            cov += self.process_cov(dt)[np.ix_(idx, idx)]
        return KeptSensors(idx, x[idx].copy(), cov)

    @property
    def load_states(self) -> tuple[int, ...]:
        """The states of an external load the robot may be free of (a tendon robot's tip
        force and its derivatives), indices into :attr:`state_names`; none here. The
        EKF of a model that has them weighs the robot free of load against loaded
        (:mod:`continuum_mhe.estimators.load_hypotheses`)."""
        return ()

    @property
    def evidence_given(self) -> tuple[int, ...]:
        """The measurement components on which the load hypotheses' evidence is
        conditioned (:mod:`continuum_mhe.estimators.load_hypotheses`): each reading weighs
        them by the density of the other components given these; none here (the whole
        reading's density)."""
        return ()

    @property
    def load_outputs(self) -> tuple[int, ...]:
        """The outputs that are the load of :attr:`load_states` (a tendon robot's ``fx,
        fy, fz``), indices into :attr:`outputs`; none here."""
        return ()

    def start_untrusted(self, z0: FloatArray) -> bool:
        """Whether a start that knows nothing of the sensors' own errors cannot be
        trusted at the reading ``z0``, whatever the readings after it show: the reading
        shows what the start cannot tell from those errors (never here; a tendon robot's
        tip load). Every estimator's rows of such a start are not ``ok`` until the next
        restart."""
        return False

    def unloaded_start(
        self, z0: FloatArray, kept: KeptSensors | None = None
    ) -> tuple[FloatArray, FloatArray, bool]:
        """``(x0, P0, shows_load)``: :meth:`start_prior` with the :attr:`load_states`
        held at zero (their values and their rows and columns of the covariance zero),
        and whether the reading shows a load that a start cannot tell from the sensors'
        own errors, so that the estimates of that start are not to be trusted (never
        here; a formulation whose start fit depends on the load overrides this)."""
        x, P = self.start_prior(z0, kept)
        x, P = without_load(x, P, self.load_states)
        return x, P, False

    def start_prior(
        self, z0: FloatArray, kept: KeptSensors | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """``(x0, P0)``: the prior every estimator starts (and restarts) from at the
        reading ``z0``, before its update with that reading: :meth:`initial_state` and
        :meth:`initial_cov`, with the sensor states' values and covariance ``kept`` by
        a restart (:meth:`kept_sensors`) in place of theirs (a formulation whose prior
        depends on what the reading shows overrides this). A prior wider than a state's
        range (:meth:`range_std`: a bend's ``theta_max``) is taken as that range: it says
        no more, and an unscented filter's sigma points would wrap the angles."""
        x, P = self.initial_state(z0), self.initial_cov()
        std, reach = np.sqrt(np.diag(P)), self.range_std()
        scale = np.where(std > reach, reach / np.where(std > 0, std, 1.0), 1.0)
        P = P * np.outer(scale, scale)
        if kept is not None:
            x[kept.states] = kept.values
        return x, self.with_kept_covariance(P, kept)

    @staticmethod
    def with_kept_covariance(P: FloatArray, kept: KeptSensors | None) -> FloatArray:
        """``P`` (changed in place) with the kept states' rows and columns those of the
        covariance ``kept`` (:meth:`kept_sensors`; None: ``P`` as it is)."""
        if kept is not None:
            P[kept.states, :] = 0.0
            P[:, kept.states] = 0.0
            P[np.ix_(kept.states, kept.states)] = kept.cov
        return P

    def inputs(self, z_prev: FloatArray | None, z: FloatArray, dt: float) -> FloatArray:
        """Input ``u`` driving the transition into the sample with measurement ``z``."""
        return np.zeros(self.nu)

    @property
    def input_function(self) -> InputFunction:
        """:meth:`inputs` as the compiled core takes it: the method itself, called back
        from the core (none is, where ``nu`` is 0); a formulation whose inputs are taped
        gives their :class:`~continuum_mhe._core.CompiledInputs`, which the core evaluates
        without Python."""
        return self.inputs

    def project(self, x: FloatArray) -> FloatArray:
        """Closest feasible state (used only for flagged fallbacks)."""
        lo, hi = self.state_bounds()
        return np.clip(x, lo, hi)

    def is_feasible(self, x: FloatArray, tol: float = 1e-7) -> bool:
        """Whether the state ``x`` (nx,) lies within :meth:`state_bounds`, to ``tol``."""
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
        redundant states can drift; see :class:`~continuum_mhe.model.paper.PaperFormulation`)."""
        return False

    def at_bound(self, x: FloatArray) -> bool:
        """True when a section's bending angle sits within :data:`AT_BOUND_TOL` of its
        ``theta_max`` or beyond it (status ``at-bound``: the MHE holds a bend there, and
        the bound, not the data, set the shape; a filter's estimate passes it)."""
        return False

    def state_checks(self) -> _core.StateChecks | None:
        """The checks of a state (:meth:`is_diverged`, :meth:`at_bound` and, by their
        ``flags``, :meth:`drifted`) as data for the compiled core, or None: the core asks
        these methods."""
        return None

    def change_test(self) -> ChangeTest | None:
        """The slowly varying states whose estimate may not move faster than their
        model allows (the estimate-change test, status ``drifted``), or None: none."""
        return None

    def drift_resets(self) -> bool:
        """Whether a drift reset (``RecoverySettings.drift_reset``) can act: the model has
        slowly varying error states whose drift a restart from the last ``ok``
        estimate's clears (:meth:`change_test`)."""
        return self.change_test() is not None

    # --- shared -------------------------------------------------------------------
    def meas_cov(self) -> FloatArray:
        """``R``: block-diagonal, one block per IMU (roll, pitch: ``measurement_std``)."""
        return np.eye(self.nz) * self.noise.measurement_std**2

    def gravity_direction_rows(self) -> NDArray[np.bool_]:
        """Which readings (nz,) are gravity directions, the readings that set the shape
        and carry an IMU's constant error (here every reading is one: roll and
        pitch)."""
        return np.ones(self.nz, dtype=bool)

    def input_rows(self) -> NDArray[np.bool_]:
        """Which rows (nz,) of ``z`` the model reads as inputs and not as readings of the
        state: their residual is zero whatever the state, so no check judges them nor
        counts them among a test's degrees of freedom (here none)."""
        return np.zeros(self.nz, dtype=bool)

    def judged_rows(self) -> NDArray[np.bool_]:
        """Which rows (nz,) of ``z`` are readings that a chi-square test judges and counts
        among its degrees of freedom (the consistency check, the bad-start check, the
        MHE's branch check): every row but a model's pseudo-measurements (blocks of kind
        ``"equilibrium"``: a tendon robot's tip condition, met only to the linearisation
        of a step) and the rows it reads as inputs (:meth:`input_rows`, whose residual is
        zero)."""
        pseudo = np.concatenate(
            [np.full(b.size, b.kind == "equilibrium") for b in self.measurement_blocks]
        )
        return ~pseudo & ~self.input_rows()

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
        """The model's numeric functions (each built on first use, once for all equal
        formulations: :func:`shared_functions`)."""
        return shared_functions(self)

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


#: Divergence test (:meth:`~continuum_mhe.model.bend.BendFormulation.is_diverged`): rad
#: beyond ``theta_max``.
DIVERGED_MARGIN = 1.0
#: Status ``at-bound`` (:meth:`Formulation.at_bound`): a bend within this many rad of
#: its ``theta_max`` (a constrained solver's answer on the bound is within its
#: tolerance of it, far below this; a free bend is that close about once in a thousand).
AT_BOUND_TOL = 1e-3
#: The shortest step whose process noise the estimators take, s: ``Q(dt)`` of a shorter
#: step (two samples a logger stamped microseconds apart) is that of this one, so that
#: the MHE's process weights, ``Q^-1`` of order ``1 / dt^3``, stay within the window's
#: conditioning (a sample 0.1 us after another would leave windows unsolved); the
#: step's own transition is unchanged.
MIN_NOISE_STEP_S = 1e-5


def noise_step(dt: Sym) -> Sym:
    """The step (s) whose process noise a step of ``dt`` s takes: ``max(dt,``
    :data:`MIN_NOISE_STEP_S` ``)``, symbolic."""
    return ca.fmax(dt, MIN_NOISE_STEP_S)


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
