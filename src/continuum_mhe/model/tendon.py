"""Tendon-driven robots: the estimators' formulation of a robot whose backbone is shot
by :class:`~continuum_mhe.model.tendon_statics.TendonStatics` (its mechanics are described
there).

The formulation (:class:`TendonFormulation`)
---------------------------------------------
State ``x = [k0, F, tau, k0', F']``, with ``estimate_force_acceleration`` (by default
with raw IMUs) the tip force's acceleration
``F''``, then the IMUs' own errors: a gyro bias per IMU with ``estimate_gyro_bias``
(raw IMUs), each board's misalignment with ``estimate_misalignment`` and each
accelerometer's bias with ``estimate_accel_bias`` (both by default), random walks.
The base curvature ``k0 = R0^T M(0) / EI`` (rad/m, 3:
the total base moment scaled to a curvature) follows constant velocity driven by
white-noise acceleration (as the ``bend`` formulation); the tip force ``F`` (N, base
frame, 3) the same, or, where ``F''`` is a state, constant acceleration driven by
white-noise jerk; the tendon tensions ``tau`` (N, one per tendon) a random walk held to
the given ones. ``F''`` moves the IMUs: a tip force that swings across a bent robot
accelerates its tip, and at constant velocity that acceleration, about a degree of the
tip IMU's gravity direction at 0.08 N on the shipped robot, is left to the IMUs'
misalignment and bias states, which then turn the estimate about the vertical. With it
as a state the model describes the readings at the true state to their noise; the
filter then depends on its start's tip force (:meth:`TendonFormulation.initial_state`).
A robot with one raw IMU takes ``F''`` too, at a slower jerk with a white acceleration
beside it (:data:`SINGLE_IMU_FORCE_JERK_PSD`, :data:`SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD`)
and less gyro noise (:data:`SINGLE_IMU_GYRO_STD`); no setting tried is better on every
recording (docs/tendon-studies.md, "The tip IMU alone under load").
The IMUs' errors are states by default
because they, not the model, are what is left: a degree of misalignment, or 0.17
m/s^2 of accelerometer bias, reads as a tip force that moves the tip of the shipped
robot by about 5 mm; as the robot moves through several poses they separate from the
force (docs/tendon-studies.md).
With ``estimate_tension_gain`` (off by default) the last states are a gain per section
with tendons anchored at its end, a slow random walk with the prior 1: the tension
acting on a tendon is its section's gain times the one given (the residual below reads
``gain * z_tau - tau``, and the given rates and their rates enter the IMUs' model times
the gain), for tensions whose scale is in doubt (a tension sensor's gain, tendon
friction, kgf given as N). With raw IMUs the gains recover tensions given half to
twice the acting ones, and kgf for N in part under load; a gain that ends far from 1
is said by ``estimate``. With the right tensions the gains cost
accuracy, and with tilt IMUs they trade with the IMUs' errors and mislead: hence off
by default (docs/tendon-studies.md, "Tension gains", has the measurements).
The measurement vector is the IMUs' (tilt: roll and pitch, or raw: ``f/|f|`` and gyro,
as ``bend`` and ``direct``), then the given tensions and their rates (kind
``"tension"``: the tensions are measurements of ``tau`` (or of ``tau`` over the gain)
with the standard deviation :attr:`TendonFormulation.tension_std`; the rates enter the
gyros' model and have a zero residual), then zeros (kind ``"equilibrium"``): the tip
condition ``R(L)^T M(L) / EI = 0``, and with raw IMUs its time derivative, as a
pseudo-measurement with the tiny standard deviation :attr:`TendonFormulation.equilibrium_std`.

Why a pseudo-measurement rather than a constraint: every estimator then runs the model
unchanged (the filters have no constraints, and the fast MHE handles only box and ball
constraints); its weight makes the equilibrium exact to about 1e-4 rad/m of tip
curvature in the estimate, a few micrometres at the tip. Why tensions in the
measurement rather than as the transition's input ``u``: the estimators form ``u`` from
the measurements alone, so a tension given with the sample reaches the model in ``z``
either way; there the start (:meth:`TendonFormulation.initial_state`) sees the
tensions, and a sample without them is a dropout as a whole. Why the tensions are
states: the outputs (the shape) are functions of the state alone in every estimator.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, fields
from functools import cached_property
from typing import ClassVar, Literal

import casadi as ca
import numpy as np
from numpy.typing import NDArray

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError, is_real
from continuum_mhe.model.descriptions import (
    TIP_FORCE_COLUMNS,
    MeasurementBlock,
    OutputSpec,
    direct_blocks,
    tendon_outputs,
    tension_gain_outputs,
    tilt_blocks,
)
from continuum_mhe.model.direct import DEFAULT_GYRO_STD
from continuum_mhe.model.equilibrium_fit import EquilibriumFit, fit_on_equilibrium
from continuum_mhe.model.formulations import ChangeTest, Formulation, KeptSensors, without_load
from continuum_mhe.model.imu import (
    STANDARD_GRAVITY,
    tilt_from_gravity_sym,
    tilt_tangent_residual_sym,
)
from continuum_mhe.model.kinematics import Sym
from continuum_mhe.model.pcc import up_vector
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.settings import FormulationName
from continuum_mhe.model.tape import residual_node_tapes
from continuum_mhe.model.tendon_statics import (
    Station,
    TendonStatics,
    hat_sym,
    swing_twist_sym,
)
from continuum_mhe.quantiles import chi2_quantile

#: Time step, s, of the central differences that give the IMUs' own acceleration
#: (:meth:`TendonFormulation._imu_accelerations`; their error is of order its square).
ACCELERATION_STEP = 0.01
#: The start's prior weight relative to :meth:`TendonFormulation.initial_cov`'s: enough
#: to settle the directions the IMUs do not see, far too faint to move the others.
START_PRIOR_WEIGHT = 1e-3
#: The start's most model evaluations (each Newton step of the equilibrium counts,
#: :func:`~continuum_mhe.model.equilibrium_fit.fit_on_equilibrium`). A start cut short
#: leaves a force error that the IMUs' misalignment and bias states then absorb, and the
#: filter follows the wrong shape for many samples; readings the model cannot fit take
#: the whole budget.
START_EVALUATIONS = 600
#: A restart within a recording that keeps the sensors' states (the IMUs' biases and
#: misalignments, the tension gains: :meth:`TendonFormulation.kept_sensors`) fits the
#: tip force, and with raw IMUs its rate, under a prior of this many times the robot's
#: buckling load (per second for the rate). With the IMUs' errors known, one reading
#: determines the force and the gyros its rate; a start that does not know them holds
#: the force to a third of the buckling load, as those errors tilt the readings as a
#: small force would, and under a larger load it does not find it again.
KEPT_START_BUCKLING_MULTIPLE = 3.0
#: The tip force's prior standard deviation, N, in the start fit of the robot free of
#: load (:meth:`TendonFormulation.unloaded_start`): the force held at zero.
UNLOADED_FIT_FORCE_STD = 1e-9
#: The tip force's white-noise acceleration by default at constant velocity (tilt IMUs,
#: or ``estimate_force_acceleration=False``), N^2/s^3: with two or more IMUs, and with
#: one. One IMU's gravity direction and gyro hold a faster force only loosely:
#: with the shipped robot's tip IMU alone, the Kalman covariance along the true states of
#: the unloaded recording keeps each horizontal component's standard deviation at about
#: 0.09 N at 1 N^2/s^3 and 0.012 N at 1e-3. The default EKF weighs the robot free of load
#: against loaded (estimators.load_hypotheses), so a robot free of load does not pay for
#: a faster force there (the single loaded EKF does: free_of_load_hypothesis=False); the
#: one-IMU value is the one of those measured (6e-4 to 1e-2) that is best under load and
#: twist on seeds 0 to 2 of docs/tendon-studies.md ("One IMU").
FORCE_ACCEL_PSD = 1.0
SINGLE_IMU_FORCE_ACCEL_PSD = 2e-3
#: The clip of a tension at zero for a robot with one IMU, N (:attr:`TendonFormulation.
#: slack_smoothing`, resolved): smooth, over the given tensions' standard deviation. With
#: one IMU the mean tip error falls on 13 of the 15 recordings of seeds 0 to 2 (every
#: loaded or twisted one; force-08 3.49 to 2.60 mm on seed 0), the other two equal; with
#: two IMUs it moves by -0.08 to +0.06 mm, either way, and the exact clip stays
#: (docs/tendon-studies.md, "One IMU").
SINGLE_IMU_SLACK_SMOOTHING = 1e-3
#: The tip force's prior standard deviation by default, as a fraction of the load that
#: buckles the straight backbone (a cantilever with a free tip): a wider prior lets the
#: first updates on a nearly straight rod, which barely sees its axial force, push that
#: force into compression past the buckling load, where the shape bifurcates and the
#: filter follows another one (docs/tendon-studies.md, "The tip force's prior").
FORCE_PRIOR_BUCKLING_FRACTION = 1.0 / 3.0
#: The tip force's prior at a start free of load, as a fraction of the wide one
#: (:meth:`TendonFormulation.start_prior`; docs/tendon-studies.md, "The tip force's
#: prior").
FREE_START_FORCE_FRACTION = 0.01
#: A start whose tensions alone would bend the robot's tip further than this from the
#: base axis (rad) is not taken as free of load: a load across a bent robot can tilt its
#: IMUs as a change of its shape does, which the readings' misfit does not tell apart
#: (docs/tendon-studies.md, "The tip force's prior"). Well beyond the tilt the IMUs'
#: misalignment gives a reading (:attr:`TendonFormulation.initial_misalignment_std`).
FREE_START_MAX_BEND = math.radians(10.0)
#: A start whose readings, fitted without a load, are less likely than this under their
#: noise and the IMUs' own errors is taken to be under load (the wide prior). Lenient on
#: purpose: a free start taken for a loaded one keeps the wide prior, which costs
#: millimetres in the first seconds; a loaded start taken for a free one holds the load
#: back, which costs far more.
LOADED_START_PROBABILITY = 0.05
#: A start that knows nothing of the sensors, whose readings, fitted free of load, are
#: less likely than this under their noise and the IMUs' own errors, shows a load that
#: it cannot tell from those errors (:meth:`TendonFormulation.unloaded_start`): the
#: estimates of that start are not trusted. Strict: a false alarm leaves a whole
#: recording untrusted.
LOAD_AT_START_PROBABILITY = 1e-3
#: A tip force estimate (or its standard deviation) beyond this many times the buckling
#: load, and beyond :data:`MAX_FORCE_FLOOR`, has diverged (:meth:`TendonFormulation.
#: is_diverged`): a stiff backbone's prior alone may exceed a fixed limit.
DIVERGED_BUCKLING_MULTIPLE = 10.0
#: The least tip force, N, that counts as diverged by default.
MAX_FORCE_FLOOR = 50.0
#: A tip force that pushes along the tip's tangent harder than this many times the
#: buckling load makes an estimate ``drifted`` (:meth:`TendonFormulation.drifted`; a
#: free tip holds no more, and between one and two such loads a filter's standard
#: deviation collapses on rows far off): the
#: quasi-static model then solves a nearly straight equilibrium that the backbone cannot
#: hold (it buckles), along which the IMUs barely see the force, and a filter's
#: covariance linearised there collapses (a still, straight robot: tip forces of 4 N
#: along its axis at 0.04 N standard deviations). A bent backbone with a free tip holds
#: the load along its tip's tangent near the buckling load at most (a tip held sideways
#: by what it presses on holds more, a push the IMUs do not see either); on the shipped
#: recordings the push stays under 0.8 of it.
BUCKLED_PUSH_MULTIPLE = 1.0
#: The chi-square probability beyond which the IMUs' error states (gyro biases,
#: misalignments, accelerometer biases), measured against their prior
#: (:meth:`TendonFormulation.initial_cov`), make an estimate ``drifted``
#: (:meth:`TendonFormulation.drifted`): the readings are then followed only with IMU
#: errors these IMUs are not taken to have. On the shipped recordings with their own
#: tensions and raw IMUs the statistic stays at 6.8 or less against the 42.3 of 18 such
#: states; tensions given 0.8, 1.2 or 2 times those acting take it past that within
#: seconds (docs/tendon.md, "Limits").
IMU_ERROR_PROBABILITY = 0.999
#: The estimate-change test of the IMUs' error states
#: (:meth:`TendonFormulation.change_test`): its lag, s, and its chi-square probability.
#: A model that does not describe the robot (a wrong IMU position, backbone or tensions)
#: is followed by error states that keep moving while their covariance shrinks; on the
#: right robot their change stays within a fifth of the limit (docs/tendon.md, "Limits").
CHANGE_LAG = 0.25
CHANGE_PROBABILITY = 0.999
#: The tip force's white-noise jerk, N^2/s^5, where its acceleration is a state
#: (:attr:`TendonFormulation.estimate_force_acceleration`): with two or more IMUs, and
#: with one; with one IMU a white-noise acceleration of the force beside it, N^2/s^3,
#: which keeps the loaded hypothesis' force covariance from collapsing. The one-IMU
#: values are those measured that are best under load over seeds 0 and 1 with the
#: one-IMU gyro noise (:data:`SINGLE_IMU_GYRO_STD`; docs/tendon-studies.md, "The tip IMU
#: alone under load": over the 20 loaded recordings of seeds 0 to 4 a mean tip error of
#: 3.28 mm against 5.00 at a jerk of 0.01 and an acceleration of 3e-3, worse on four
#: `force-08` recordings, and on one seed of five free of load 0.56 mm against 0.10).
FORCE_JERK_PSD = 1.0
SINGLE_IMU_FORCE_JERK_PSD = 0.03
SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD = 3e-4
#: The gyros' white noise, rad/s, assumed by default for a robot with one raw IMU
#: (:attr:`TendonFormulation.gyro_std`, resolved; with two or more the command line's
#: :data:`~continuum_mhe.model.direct.DEFAULT_GYRO_STD`). With one IMU its gyro is what
#: tells the tip force's motion from the IMU's constant errors (its misalignment and
#: gyro bias take up what the gyro is not trusted with); 0.005, the least gyro noise
#: the tendon recordings' standard deviations are calibrated at with two IMUs, and still
#: three times a MEMS gyro's own (0.1 deg/s), lowers the mean tip error under load over
#: seeds 0 to 4 from 6.13 to 5.00 mm at a jerk of 0.01 and an acceleration of 3e-3, free
#: of load alike (docs/tendon-studies.md, "The tip IMU alone under load").
SINGLE_IMU_GYRO_STD = 0.005
#: Equilibrium pseudo-measurement names: the tip curvature and its rate.
EQUILIBRIUM_NAMES = ("eq_kx", "eq_ky", "eq_kz", "eq_kx_dot", "eq_ky_dot", "eq_kz_dot")
#: The tension gains' prior standard deviation by default
#: (:attr:`TendonFormulation.estimate_tension_gain`; dimensionless, about the prior
#: mean 1): tendon friction, a load cell's calibration.
INITIAL_TENSION_GAIN_STD = 0.3
#: The tension gains' random walk by default, 1/s: a gain that drifts by about 0.03
#: in 100 s, far slower than the motion (1e-6 to 1e-3 give the same tip errors within
#: 0.3 mm on the shipped recordings: docs/tendon-studies.md, "Tension gains").
TENSION_GAIN_PSD = 1e-5
#: The least tension gain (:meth:`TendonFormulation.state_bounds`): a tension that acts
#: in the direction it is given.
MIN_TENSION_GAIN = 0.01
#: The tension states' prior standard deviation, N, where the tension gains are states
#: (:meth:`TendonFormulation.initial_cov`): far wider than a gain's prior times any
#: tension, so the gain's prior, not the tensions', holds the start.
GAIN_TENSION_PRIOR_STD = 100.0


ImuModel = Literal["tilt", "direct"]


@dataclass(frozen=True)
class TendonFormulation(Formulation):
    """A tendon-driven robot's mechanics with the base curvature and the tip force as
    states, the tensions given with every sample; the IMUs as tilt or raw (see the
    module docstring).

    Attributes:
        imu_model: ``"tilt"`` (roll, pitch per IMU) or ``"direct"`` (``f/|f|`` and gyro).
        gyro_std: gyro noise, rad/s (``direct``; None, the default:
            :data:`~continuum_mhe.model.direct.DEFAULT_GYRO_STD`, or
            :data:`SINGLE_IMU_GYRO_STD` for a robot with one IMU; :attr:`gyro_noise_std`
            is the value used).
        accel_direction_std: standard deviation of each component of ``f/|f|``
            (``direct``; None: ``noise.measurement_std``).
        estimate_gyro_bias: a gyro bias per IMU as states (``direct``), random walk.
        own_acceleration: the IMUs' own acceleration in their specific force (from the
            tip force's rate and the tensions' first and second derivatives along the
            equilibria); without it the accelerometers are taken to read gravity alone.
        acceleration_from_force_rate: the tip force's rate moves the IMUs too (None,
            the default: with raw IMUs, whose gyros hold the rate, yes; with tilt IMUs
            no, only the tensions' changes do: there the force's rate is loosely held,
            and its square in the acceleration fed back into the force).
        gyro_bias_psd: its spectral density, (rad/s)^2/s.
        initial_gyro_bias_std: its prior standard deviation, rad/s.
        estimate_misalignment: each IMU's small mounting rotation (rad, 3, board
            from disk frame, about the disk frame's axes) as states, a random walk
            (default on).
        initial_misalignment_std: its prior standard deviation, rad.
        misalignment_psd: its spectral density, rad^2/s.
        estimate_accel_bias: each accelerometer's bias (m/s^2, 3, its board's frame) as
            states, a random walk: the specific force read is ``R^T (g up + a) + c``
            (tilt and raw IMUs alike: tilt is the accelerometer's direction; default
            on).
        initial_accel_bias_std: its prior standard deviation, m/s^2.
        accel_bias_psd: its spectral density, (m/s^2)^2/s.
        tension_std: the given tensions' standard deviation, N.
        tension_psd: the tension states' random walk, N^2/s (large: the given
            tensions, not the motion model, set them).
        equilibrium_std: the tip condition's pseudo-measurement standard deviation, rad/m
            (and rad/m/s for its rate).
        curvature_accel_psd: white-noise acceleration of the base curvature,
            (rad/m)^2/s^3 (large: the equilibrium, not the motion model, sets it).
        force_accel_psd: white-noise acceleration of the tip force, N^2/s^3 (None, the
            default: at constant velocity :data:`FORCE_ACCEL_PSD`, or
            :data:`SINGLE_IMU_FORCE_ACCEL_PSD` for a robot with one IMU; with the
            force's acceleration a state, none beside the jerk with two or more IMUs,
            :data:`SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD` with one; a value given is
            added to the jerk there (0: none); :attr:`force_psd` is the value used).
        estimate_force_acceleration: the tip force's acceleration ``F''`` (N/s^2, 3)
            as states, the force at constant acceleration driven by white jerk, ``F''``
            in the IMUs' own acceleration (needs the force's rate in the acceleration,
            :attr:`force_rate_moves_imus`). None, the default: on where the force's rate
            moves the IMUs (raw IMUs); :attr:`n_force_acceleration` says what is used.
        force_jerk_psd: the tip force's white-noise jerk there, N^2/s^5 (None, the
            default: :data:`FORCE_JERK_PSD`, or :data:`SINGLE_IMU_FORCE_JERK_PSD` for a
            robot with one IMU; :attr:`jerk_psd` is the value used).
        initial_force_acceleration_std: ``F''``'s prior standard deviation, N/s^2.
        initial_force_std: the tip force's prior standard deviation, N (None, the
            default: :data:`FORCE_PRIOR_BUCKLING_FRACTION` of the robot's buckling load;
            :attr:`force_prior_std` is the value used).
        max_force: a tip force estimate (or its standard deviation) beyond this, N, has
            diverged (None, the default: :data:`DIVERGED_BUCKLING_MULTIPLE` times the
            buckling load, at least :data:`MAX_FORCE_FLOOR`; :attr:`max_force_used`).
        estimate_tension_gain: a tension gain per section with tendons anchored at its
            end (:attr:`tension_gain_sections`) as states, the last ones, a random walk:
            the tension acting on the robot is the gain times the given one, for each
            tendon anchored at that section (the gain is acting over given: tensions
            given 1.2 times too large read as a gain of 1/1.2).
        initial_tension_gain_std: the gains' prior standard deviation about 1
            (dimensionless).
        tension_gain_psd: the gains' spectral density, 1/s.
        free_of_load_hypothesis: the EKF weighs the robot free of load against loaded
            (:attr:`load_states`, :mod:`continuum_mhe.estimators.load_hypotheses`;
            default on); off, ``make_estimator("ekf", ...)`` gives the single loaded
            EKF.
        slack_smoothing: the width of the clip of a tension at zero, N: 0, the exact
            ``max(tension, 0)``; positive, the smooth ``(tension + sqrt(tension^2 +
            e^2)) / 2`` (a slack tendon pulls ``e / 2``). None, the default: 0 for a
            robot with several IMUs, :data:`SINGLE_IMU_SLACK_SMOOTHING` for a robot with
            one (:attr:`slack_width` is the value used). The MHE on IPOPT converges on
            windows whose optimum sits on the clip's kink (the first windows of a start
            with the tendons slack) with the smooth clip; the EKF's mean tip errors on
            the shipped two-IMU recordings move by -0.02 to +0.05 mm at 1 mN
            (docs/tendon-studies.md, "The MHE's two windows").
        imu_evidence: the load hypotheses are weighed by the IMU readings' density given
            the tensions and the tip condition (:attr:`evidence_given`), not by the
            whole measurement's: the tip condition is the model's pseudo-measurement, and
            its predicted density grows without bound near buckling, where a loaded
            hypothesis gone astray then takes the estimate of a robot free of load. None,
            the default: on for a robot with one IMU (whose loaded hypothesis can stray
            that far; with two IMUs the shipped raw recordings are unchanged by it, and
            with tilt IMUs it is better on some twisting recordings and worse on others
            over seeds 0 to 4: docs/tendon-studies.md, "The tip IMU alone under
            load").
    """

    name: FormulationName = "tendon"
    #: the shooting model's second derivatives are too large to form (Gauss-Newton)
    second_order_residuals: ClassVar[bool] = False
    #: A restart fits the start to the reading by least squares (up to
    #: :data:`START_EVALUATIONS` model evaluations); where the readings contradict every
    #: restart (tensions of another scale or order) the restarts do not bring the estimate
    #: nearer the robot and cost most of the run, so three in a row stop them (the rows
    #: are then ``drifted`` or ``inconsistent``). A burst of wild readings counts toward
    #: the three too.
    bad_start_chain: ClassVar[int | None] = 3
    observable_hint: ClassVar[str] = "a second IMU makes it observable"
    fast_mhe_obstacle: ClassVar[str | None] = (
        "the fast MHE does not take this robot's mechanics model (its windows do not "
        "converge within their iterations, and IPOPT, which would take those, needs "
        "seconds to minutes a window; the docs' tendon robots page)"
    )
    tilt_residual_wraps: ClassVar[bool] = False
    forward_mode_jacobian: ClassVar[bool] = True
    #: the UKF's sigma points close about the mean: spread across several standard
    #: deviations of the tip force and the base curvature, the shooting's curvature
    #: makes the tip condition's residuals (standard deviation :attr:`equilibrium_std`)
    #: average far from zero, an innovation the update meets by moving the state. Much
    #: closer than this, the weights' rounding takes over (docs/tendon-studies.md, "The UKF")
    unscented_alpha: ClassVar[float] = 0.01
    #: each output evaluation is a shooting: the outputs' standard deviations are
    #: linearised (sigma points would cost a shooting per state the outputs depend on)
    sigma_point_output_std: ClassVar[bool] = False
    imu_model: ImuModel = "tilt"
    gyro_std: float | None = None
    accel_direction_std: float | None = None
    estimate_gyro_bias: bool = False
    own_acceleration: bool = True
    acceleration_from_force_rate: bool | None = None
    gyro_bias_psd: float = 1e-6
    initial_gyro_bias_std: float = 0.05
    estimate_misalignment: bool = True
    initial_misalignment_std: float = 0.03
    misalignment_psd: float = 1e-9
    estimate_accel_bias: bool = True
    initial_accel_bias_std: float = 0.1
    accel_bias_psd: float = 1e-6
    tension_std: float = 1e-3
    tension_psd: float = 1e3
    equilibrium_std: float = 1e-4
    curvature_accel_psd: float = 1e4
    force_accel_psd: float | None = None
    estimate_force_acceleration: bool | None = None
    force_jerk_psd: float | None = None
    initial_force_acceleration_std: float = 0.1
    initial_force_std: float | None = None
    max_force: float | None = None
    estimate_tension_gain: bool = False
    initial_tension_gain_std: float = INITIAL_TENSION_GAIN_STD
    tension_gain_psd: float = TENSION_GAIN_PSD
    free_of_load_hypothesis: bool = True
    slack_smoothing: float | None = None
    imu_evidence: bool | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        for f in fields(self):  # a number option given None or a string
            kind, v = str(f.type), getattr(self, f.name)
            if kind in ("float", "float | None") and not (
                is_real(v) or (v is None and kind == "float | None")
            ):
                raise UserError(
                    f"{f.name} must be a number{' or None' if kind != 'float' else ''}, got {v!r}"
                )
        if not self.robot.has_mechanics:
            raise UserError("the tendon formulation needs a robot file with a [backbone]")
        if self.imu_model not in ("tilt", "direct"):
            raise UserError(f"imu_model must be tilt or direct, got {self.imu_model!r}")
        if self.estimate_gyro_bias and self.imu_model != "direct":
            raise UserError("estimate_gyro_bias needs the direct (raw gyro) IMU model")
        resolved = {
            "initial_force_std": self.force_prior_std,
            "max_force": self.max_force_used,
            "force_jerk_psd": self.jerk_psd,
            "gyro_std": self.gyro_noise_std,
        }
        if self.estimate_force_acceleration and not self.force_rate_moves_imus:
            raise UserError(
                "estimate_force_acceleration needs the tip force's rate in the IMUs' "
                "acceleration (acceleration_from_force_rate)"
            )
        for label in (
            "gyro_std",
            "gyro_bias_psd",
            "initial_gyro_bias_std",
            "initial_misalignment_std",
            "misalignment_psd",
            "initial_accel_bias_std",
            "accel_bias_psd",
            "tension_std",
            "tension_psd",
            "equilibrium_std",
            "curvature_accel_psd",
            "force_jerk_psd",
            "initial_force_acceleration_std",
            "initial_force_std",
            "max_force",
            "initial_tension_gain_std",
            "tension_gain_psd",
        ):
            v = resolved[label] if label in resolved else getattr(self, label)
            if not (math.isfinite(v) and v > 0):
                raise UserError(f"{label} must be a positive finite number, got {v!r}")
        # a force_accel_psd given (None: force_psd's default); 0 where the force's
        # acceleration is a state, its jerk alone driving the force (the default there)
        psd, least = self.force_accel_psd, "0 or more" if self.n_force_acceleration else "positive"
        if psd is not None and not (
            math.isfinite(psd) and (psd > 0 or (psd == 0 and self.n_force_acceleration))
        ):
            raise UserError(f"force_accel_psd must be a {least} finite number, got {psd!r}")
        if not (math.isfinite(self.slack_width) and self.slack_width >= 0):
            raise UserError(
                f"slack_smoothing must be a finite number of newtons, 0 or more, got "
                f"{self.slack_smoothing!r}"
            )

    @property
    def force_rate_moves_imus(self) -> bool:
        """Whether the tip force's rate enters the IMUs' own acceleration
        (:attr:`acceleration_from_force_rate`, resolved)."""
        if self.acceleration_from_force_rate is None:
            return self.imu_model == "direct"
        return self.acceleration_from_force_rate

    @property
    def n_force_acceleration(self) -> int:
        """States of the tip force's acceleration: 3 with
        :attr:`estimate_force_acceleration` (resolved: by default with raw IMUs), else
        0."""
        on = self.estimate_force_acceleration
        if on is None:
            on = self.force_rate_moves_imus
        return 3 if on else 0

    def _by_imus(self, given: float | None, one: float, several: float) -> float:
        """A field's value used: ``given``, or where it is None the default for a robot
        with one IMU (``one``) or with several (``several``)."""
        if given is not None:
            return given
        return one if self.robot.n_imus == 1 else several

    @property
    def gyro_noise_std(self) -> float:
        """The gyros' white noise used, rad/s (:attr:`gyro_std`, resolved from the
        robot's IMUs)."""
        return self._by_imus(self.gyro_std, SINGLE_IMU_GYRO_STD, DEFAULT_GYRO_STD)

    @property
    def jerk_psd(self) -> float:
        """The tip force's white-noise jerk used where its acceleration is a state,
        N^2/s^5 (:attr:`force_jerk_psd`, resolved from the robot's IMUs)."""
        return self._by_imus(self.force_jerk_psd, SINGLE_IMU_FORCE_JERK_PSD, FORCE_JERK_PSD)

    @property
    def _n_motion(self) -> int:
        """Size of the state before the IMUs' errors: ``[k0, F, tau, k0', F']`` and
        ``F''`` where estimated."""
        return 12 + self.robot.n_tendons + self.n_force_acceleration

    @property
    def force_psd(self) -> float:
        """The tip force's white-noise acceleration used, N^2/s^3
        (:attr:`force_accel_psd`, resolved from the robot's IMUs and whether the force's
        acceleration is a state)."""
        if self.n_force_acceleration:
            return self._by_imus(self.force_accel_psd, SINGLE_IMU_FORCE_ACCEL_WITH_JERK_PSD, 0.0)
        return self._by_imus(self.force_accel_psd, SINGLE_IMU_FORCE_ACCEL_PSD, FORCE_ACCEL_PSD)

    @property
    def slack_width(self) -> float:
        """The clip's width used, N (:attr:`slack_smoothing`, resolved from the robot's
        IMUs)."""
        return self._by_imus(self.slack_smoothing, SINGLE_IMU_SLACK_SMOOTHING, 0.0)

    @property
    def force_prior_std(self) -> float:
        """The tip force's prior standard deviation used, N (:attr:`initial_force_std`,
        resolved): by default :data:`FORCE_PRIOR_BUCKLING_FRACTION` of the load that
        buckles the straight backbone as a cantilever, ``pi^2 EI / (4 L^2)``."""
        if self.initial_force_std is not None:
            return self.initial_force_std
        return FORCE_PRIOR_BUCKLING_FRACTION * self.buckling_load

    @cached_property
    def buckling_load(self) -> float:
        """The load that buckles the straight backbone as a cantilever, N:
        ``pi^2 EI / (4 L^2)``."""
        ei, _ = self.statics.stiffness
        return math.pi**2 * ei / (4 * self.robot.length**2)

    @property
    def max_force_used(self) -> float:
        """The tip force beyond which an estimate has diverged, N (:attr:`max_force`,
        resolved)."""
        if self.max_force is not None:
            return self.max_force
        return max(MAX_FORCE_FLOOR, DIVERGED_BUCKLING_MULTIPLE * self.buckling_load)

    @cached_property
    def statics(self) -> TendonStatics:
        return TendonStatics(self.robot, slack_smoothing=self.slack_width)

    # --- the state ----------------------------------------------------------------
    @property
    def n_misalignment(self) -> int:
        return 3 * self.robot.n_imus if self.estimate_misalignment else 0

    @property
    def n_accel_bias(self) -> int:
        return 3 * self.robot.n_imus if self.estimate_accel_bias else 0

    @property
    def n_gyro_bias(self) -> int:
        return 3 * self.robot.n_imus if self.estimate_gyro_bias else 0

    @cached_property
    def tension_gain_sections(self) -> tuple[int, ...]:
        """The sections (0-based) with a tension gain state, in the states' order:
        with :attr:`estimate_tension_gain`, each section at whose end a tendon is
        anchored; else none."""
        if not self.estimate_tension_gain:
            return ()
        return self.robot.anchored_sections

    @property
    def n_tension_gain(self) -> int:
        """States of the tension gains: one per section of
        :attr:`tension_gain_sections`."""
        return len(self.tension_gain_sections)

    @property
    def tension_gain_start(self) -> int:
        """The first tension gain's index in the state: the gains come last, after
        the IMUs' errors."""
        return self._n_motion + self.n_gyro_bias + self.n_misalignment + self.n_accel_bias

    def _tendon_gains(self, x: Sym) -> Sym:
        """Each tendon's gain (k,): its section's tension gain state (the acting
        tension over the given one), 1 without :attr:`estimate_tension_gain`."""
        k = self.robot.n_tendons
        if not self.n_tension_gain:
            return ca.DM.ones(k)
        g0, where = self.tension_gain_start, self.tension_gain_sections
        return ca.vertcat(*[x[g0 + where.index(t.section)] for t in self.robot.tendons])

    @property
    def state_names(self) -> tuple[str, ...]:
        """``k0x, k0y, k0z, fx, fy, fz, tension_1..k``, then the rates of the first six,
        the tip force's acceleration ``fx_ddot, fy_ddot, fz_ddot`` (N/s^2), then the
        gyro biases, the misalignments, the accelerometer biases and the tension gains
        ``tension_gain_s`` (``s`` the 1-based section; dimensionless) (each where
        estimated)."""
        q = (*(f"k0{c}" for c in "xyz"), *(f"f{c}" for c in "xyz"))
        tau = tuple(f"tension_{i}" for i in range(1, self.robot.n_tendons + 1))
        bias = tuple(f"bg{c}_{i}" for i in range(1, self.robot.n_imus + 1) for c in "xyz")
        mis = tuple(f"mis{c}_{i}" for i in range(1, self.robot.n_imus + 1) for c in "xyz")
        acc = tuple(f"ba{c}_{i}" for i in range(1, self.robot.n_imus + 1) for c in "xyz")
        f_ddot = tuple(f"f{c}_ddot" for c in "xyz")[: self.n_force_acceleration]
        return (
            *q, *tau, *(f"{n}_dot" for n in q), *f_ddot, *bias[: self.n_gyro_bias],
            *mis[: self.n_misalignment], *acc[: self.n_accel_bias],
            *(f"tension_gain_{s + 1}" for s in self.tension_gain_sections),
        )  # fmt: skip

    def _split(self, x: Sym) -> tuple[Sym, Sym, Sym]:
        """``(q = [k0, F], tau, q')`` of a state."""
        k = self.robot.n_tendons
        return x[:6], x[6 : 6 + k], x[6 + k : 12 + k]

    @staticmethod
    def statics_of_states(
        states: FloatArray, n_tendons: int
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The statics' arguments of states ``states`` (n, nx) in this formulation's
        layout (:attr:`state_names`): the base curvature (n, 3) rad/m, the tip force
        (n, 3) N and the tensions (n, ``n_tendons``) N."""
        x = np.atleast_2d(np.asarray(states, dtype=float))
        return x[:, :3], x[:, 3:6], x[:, 6 : 6 + n_tendons]

    # --- measurement blocks -----------------------------------------------------------
    @cached_property
    def measurement_blocks(self) -> tuple[MeasurementBlock, ...]:
        n = self.robot.n_imus
        imu = tilt_blocks(n) if self.imu_model == "tilt" else direct_blocks(n)
        start = sum(b.size for b in imu)
        extra = []
        k = self.robot.n_tendons
        if k:
            names = tuple(f"tension_{i}" for i in range(1, k + 1))
            names += tuple(f"tension_{i}_dot" for i in range(1, k + 1))
            names += tuple(f"tension_{i}_ddot" for i in range(1, k + 1))
            extra.append(MeasurementBlock("tensions", names, start, "tension"))
            start += len(names)
        eq = EQUILIBRIUM_NAMES if self.imu_model == "direct" else EQUILIBRIUM_NAMES[:3]
        extra.append(MeasurementBlock("equilibrium", eq, start, "equilibrium"))
        return (*imu, *extra)

    @cached_property
    def n_imu_measurements(self) -> int:
        """Size of the IMUs' part of ``z`` (the rest: tensions, their rates, then the
        equilibrium's zeros)."""
        return sum(b.size for b in self.measurement_blocks if b.is_imu)

    def measurement_row(
        self,
        imu: FloatArray,
        tensions: FloatArray,
        tension_rates: FloatArray,
        tension_accelerations: FloatArray | None = None,
    ) -> FloatArray:
        """The measurement vector ``z`` (nz,) from the IMUs' part (``n_imu_measurements``
        values), the tensions (N), their rates (N/s) and their second derivatives (N/s^2;
        None: zero), one per tendon each. A :class:`UserError` names a part that is not
        a 1-D array of its size."""
        k = self.robot.n_tendons
        acc = np.zeros(k) if tension_accelerations is None else tension_accelerations
        parts = {
            "imu": (imu, self.n_imu_measurements),
            "tensions": (tensions, k),
            "tension_rates": (tension_rates, k),
            "tension_accelerations": (acc, k),
        }
        for label, (value, size) in parts.items():
            shape = np.shape(value)
            if shape != (size,):
                raise UserError(
                    f"measurement_row: {label} must have shape ({size},) (the robot has "
                    f"{k} tendons and {self.robot.n_imus} IMUs), got {shape}"
                )
        n_eq = self.measurement_blocks[-1].size
        values = [np.asarray(v, dtype=float) for v, _ in parts.values()]
        return np.concatenate([*values, np.zeros(n_eq)])

    def measurement_mask(self, z: FloatArray) -> FloatArray:
        """As the base class's; a sample without its tensions is a dropout as a whole
        (the model cannot predict its IMUs)."""
        n, k = self.n_imu_measurements, self.robot.n_tendons
        if not np.isfinite(z[n : n + 3 * k]).all():
            return np.zeros(len(z))
        return super().measurement_mask(z)

    @cached_property
    def outputs(self) -> tuple[OutputSpec, ...]:
        """:func:`~continuum_mhe.model.descriptions.tendon_outputs`, then each tension
        gain ``tension_gain_s`` (dimensionless, the acting tension over the given one)
        where estimated."""
        gains = tension_gain_outputs(self.tension_gain_sections)
        return (*tendon_outputs(self.robot.n_sections), *gains)

    # --- model ----------------------------------------------------------------------
    def transition_sym(self, x: Sym, u: Sym, dt: Sym) -> Sym:
        """``k0`` constant velocity, ``F`` constant velocity or, with
        :attr:`estimate_force_acceleration`, constant acceleration; the tensions,
        biases and tension gains random walks."""
        q, tau, qd = self._split(x)
        k = self.robot.n_tendons
        if not self.n_force_acceleration:
            return ca.vertcat(q + dt * qd, tau, x[6 + k :])
        f_ddot = x[12 + k : 15 + k]
        step = ca.vertcat(ca.SX.zeros(3), f_ddot)
        return ca.vertcat(q + dt * qd + dt**2 / 2 * step, tau, qd + dt * step, x[12 + k :])

    @property
    def process_noise_source(self) -> str:
        return (
            "the base curvature's, the tip force's and the tensions' own "
            "(curvature_accel_psd, force_accel_psd, force_jerk_psd, tension_psd: "
            "docs/tendon-studies.md)"
        )

    def process_cov_sym(self, dt: Sym) -> Sym:
        psd = [self.curvature_accel_psd] * 3 + [self.force_psd] * 3
        q = ca.diag(ca.DM(psd))
        k = self.robot.n_tendons
        t = self.tension_psd * dt * ca.SX.eye(k)
        z6k = ca.SX.zeros(6, k)
        cov = ca.blockcat(
            [
                [q * dt**3 / 3, z6k, q * dt**2 / 2],
                [z6k.T, t, z6k.T],
                [q * dt**2 / 2, z6k, q * dt],
            ]
        )
        if self.n_force_acceleration:
            # the tip force driven by white jerk too (a Wiener-process acceleration)
            j = self.jerk_psd
            fi, fdi = [3, 4, 5], [9 + k, 10 + k, 11 + k]
            cov = ca.diagcat(cov, ca.SX.zeros(3, 3))
            n = 15 + k
            blocks = {(0, 0): dt**5 / 20, (0, 1): dt**4 / 8, (0, 2): dt**3 / 6,
                      (1, 1): dt**3 / 3, (1, 2): dt**2 / 2, (2, 2): dt}  # fmt: skip
            idx = (fi, fdi, [n - 3, n - 2, n - 1])
            for (a, b), c in blocks.items():
                for i in range(3):
                    cov[idx[a][i], idx[b][i]] += j * c
                    if a != b:
                        cov[idx[b][i], idx[a][i]] += j * c

        if self.estimate_gyro_bias:
            cov = ca.diagcat(cov, self.gyro_bias_psd * dt * ca.SX.eye(self.n_gyro_bias))
        if self.estimate_misalignment:
            cov = ca.diagcat(cov, self.misalignment_psd * dt * ca.SX.eye(self.n_misalignment))
        if self.estimate_accel_bias:
            cov = ca.diagcat(cov, self.accel_bias_psd * dt * ca.SX.eye(self.n_accel_bias))
        if self.n_tension_gain:
            cov = ca.diagcat(cov, self.tension_gain_psd * dt * ca.SX.eye(self.n_tension_gain))
        return cov

    def _imu_accelerations(
        self,
        v: Sym,
        v_dot: Sym,
        v_ddot_given: Sym,
        res: Sym,
        poses: dict[Station, tuple[Sym, Sym]],
    ) -> list[Sym]:
        """Each IMU's own acceleration (m/s^2, base frame) along the equilibria, with
        ``v = [k0, F, tau]``: the second derivatives ``v_ddot_given = [F'', tau'']``
        (the tip force's from the state, zero at constant velocity; the tensions'
        given), and the base curvature's rate and
        acceleration those that keep the tip condition (the first and second time
        derivatives of the residual zero).

        The second derivatives are central differences along the Taylor curve
        ``v(t) = v + t v' + t^2 v''/2`` (``k0'' = 0`` on it) with the step
        :data:`ACCELERATION_STEP`, corrected to first order for ``k0''``: two more
        shootings instead of the nested derivatives of the whole shooting (which the
        estimators differentiate again)."""
        h = ACCELERATION_STEP
        j_k0 = ca.jacobian(res, v[:3])
        rest = ca.vertcat(ca.SX.zeros(3), v_dot[3:])
        if not self.force_rate_moves_imus:
            rest = ca.vertcat(ca.SX.zeros(6), v_dot[6:])
        k0_dot = -ca.solve(j_k0, ca.jtimes(res, v, rest))
        v_dot = ca.vertcat(k0_dot, rest[3:])
        v_ddot = ca.vertcat(ca.SX.zeros(3), v_ddot_given)
        shifted = []
        for sign in (1.0, -1.0):
            w = v + sign * h * v_dot + h**2 / 2 * v_ddot
            there, r = self.statics.shoot(w[:3], w[3:6], w[6:])
            shifted.append((r, [there[st][1] for st in self._imu_stations]))
        res_ddot = (shifted[0][0] - 2 * res + shifted[1][0]) / h**2
        k0_ddot = -ca.solve(j_k0, res_ddot)
        along = ca.vertcat(k0_ddot, ca.SX.zeros(v.numel() - 3))
        return [
            (shifted[0][1][i] - 2 * poses[st][1] + shifted[1][1][i]) / h**2
            + ca.jtimes(poses[st][1], v, along)
            for i, st in enumerate(self._imu_stations)
        ]

    @cached_property
    def _imu_stations(self) -> tuple[Station, ...]:
        return tuple(Station(i.section, i.at) for i in self.robot.imus)

    def _model(self, x: Sym, z: Sym | None) -> tuple[list[Sym], list[Sym], Sym]:
        """``(specific-force directions, IMU blocks, equilibrium block)`` at the state
        ``x``, with the sample's tension rates and their rates from ``z`` (zero without
        ``z``). The specific force is ``R^T (a / g + up)``: gravity and, with
        :attr:`own_acceleration`, the IMU's own acceleration ``a``."""
        n, k = self.n_imu_measurements, self.robot.n_tendons
        q, tau, qd = self._split(x)
        gain = self._tendon_gains(x)  # the given tensions' rates scaled to the acting ones
        tau_dot = ca.SX.zeros(k) if z is None else gain * z[n + k : n + 2 * k]
        tau_ddot = ca.SX.zeros(k) if z is None else gain * z[n + 2 * k : n + 3 * k]
        poses, res = self.statics.shoot(q[:3], q[3:6], tau)
        up = up_vector(self.robot.mounting)
        rots = [poses[st][0] for st in self._imu_stations]
        v = ca.vertcat(q, tau)
        v_dot = ca.vertcat(qd, tau_dot)
        if self.own_acceleration:
            f_ddot = x[12 + k : 12 + k + self.n_force_acceleration]
            if not self.n_force_acceleration:
                f_ddot = ca.SX.zeros(3)
            accel = self._imu_accelerations(v, v_dot, ca.vertcat(f_ddot, tau_ddot), res, poses)
            specific = [ca.DM(up) + a / STANDARD_GRAVITY for a in accel]
        else:
            specific = [ca.DM(up) for _ in rots]
        if self.estimate_misalignment:  # the board turned by a small rotation
            n0 = self._n_motion + self.n_gyro_bias
            rots = [
                ca.mtimes(R, ca.SX.eye(3) + hat_sym(x[n0 + 3 * i : n0 + 3 * i + 3]))
                for i, R in enumerate(rots)
            ]
        gravity = []
        n0 = self._n_motion + self.n_gyro_bias + self.n_misalignment
        for i, (R, f) in enumerate(zip(rots, specific)):
            fb = ca.mtimes(R.T, f)
            if self.estimate_accel_bias:  # in units of g, as the specific force here
                fb = fb + x[n0 + 3 * i : n0 + 3 * i + 3] / STANDARD_GRAVITY
            gravity.append(fb / ca.norm_2(fb))
        if self.imu_model == "tilt":
            return gravity, [tilt_from_gravity_sym(g) for g in gravity], res
        eq = ca.vertcat(res, ca.jtimes(res, v, v_dot))
        imu = []
        for i, R in enumerate(rots):
            dR = ca.reshape(ca.jtimes(ca.vec(R), v, v_dot), 3, 3)
            w = ca.mtimes(R.T, dR)
            rate = 0.5 * ca.vertcat(w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1])
            if self.estimate_gyro_bias:
                n0 = self._n_motion
                rate = rate + x[n0 + 3 * i : n0 + 3 + 3 * i]
            imu.append(ca.vertcat(gravity[i], rate))
        return gravity, imu, eq

    def measurement_sym(self, x: Sym) -> Sym:
        """The model's measurement with no tension (use
        :meth:`measurement_residual_sym`, which reads the sample's tensions)."""
        _, imu, eq = self._model(x, None)
        k = self.robot.n_tendons
        given = x[6 : 6 + k] / self._tendon_gains(x)
        return ca.vertcat(*imu, given, ca.SX.zeros(2 * k), eq)

    def measurement_residual_sym(self, z: Sym, x: Sym) -> Sym:
        """Tilt blocks on the tangent plane of the measured gravity direction (as
        ``bend``), raw blocks and the tensions as plain differences (the tension rates
        are the model's inputs: their rows are zero), the equilibrium ``0 -
        residual``."""
        gravity, imu, eq = self._model(x, z)
        n, k = self.n_imu_measurements, self.robot.n_tendons
        if self.imu_model == "direct":
            r_imu = z[:n] - ca.vertcat(*imu)
        else:
            r_imu = ca.vertcat(
                *[
                    tilt_tangent_residual_sym(z[b.slice], g)
                    for b, g in zip(self.measurement_blocks, gravity)
                ]
            )
        r_tau = self._tendon_gains(x) * z[n : n + k] - x[6 : 6 + k]
        return ca.vertcat(r_imu, r_tau, ca.SX.zeros(2 * k), -eq)

    def meas_cov(self) -> FloatArray:
        if self.imu_model == "tilt":
            imu = np.eye(self.n_imu_measurements) * self.noise.measurement_std**2
        else:
            f_std = self.accel_direction_std or self.noise.measurement_std
            one = np.diag([f_std**2] * 3 + [self.gyro_noise_std**2] * 3)
            imu = np.asarray(np.kron(np.eye(self.robot.n_imus), one), dtype=np.float64)
        k = self.robot.n_tendons
        # the rates' rows are zero residuals: any weight
        tension = np.diag([self.tension_std**2] * k + [1.0] * 2 * k)
        eq = np.eye(self.measurement_blocks[-1].size) * self.equilibrium_std**2
        # every block is diagonal: so is the whole
        return np.diag(np.concatenate([np.diag(imu), np.diag(tension), np.diag(eq)]))

    def reading_bias_cov(self) -> FloatArray:
        """The readings' constant errors carried outside the state: none where each
        IMU's misalignment and accelerometer bias are states (the default), whose
        covariance the estimate's holds already; carrying ``noise.reading_bias_std``
        on top would count the same errors twice (docs/tendon-studies.md, "The
        standard deviations"). Without both states, the base class's."""
        if self.estimate_misalignment and self.estimate_accel_bias:
            return np.zeros((self.nz, self.nz))
        return super().reading_bias_cov()

    def model_error_floor(self) -> float:
        """0: the model is the robot's mechanics, not a constant-curvature one, and no
        model error before the readings show one has been measured for it."""
        return 0.0

    def gravity_direction_rows(self) -> NDArray[np.bool_]:
        """The IMUs' gravity-direction readings (tilt, or the accelerometer
        directions); not the tensions nor the equilibrium rows."""
        if self.imu_model == "tilt":
            per_reading = [True] * self.n_imu_measurements
        else:
            per_reading = ([True] * 3 + [False] * 3) * self.robot.n_imus
        out = np.zeros(self.nz, dtype=bool)
        out[: len(per_reading)] = per_reading
        return out

    def input_rows(self) -> NDArray[np.bool_]:
        """The given tensions' rates and their rates: the model's inputs (the IMUs'
        model reads them), whose rows of the residual are zero."""
        n, k = self.n_imu_measurements, self.robot.n_tendons
        out = np.zeros(self.nz, dtype=bool)
        out[n + k : n + 3 * k] = True
        return out

    def output_sym(self, x: Sym) -> Sym:
        q, tau, _ = self._split(x)
        poses, _ = self.statics.shoot(q[:3], q[3:6], tau)
        ends = [poses[Station(k, 1.0)] for k in range(self.robot.n_sections)]
        parts = [ends[-1][1]]
        R_prev: Sym = ca.SX.eye(3)
        for R, p in ends:
            theta, phi, psi = swing_twist_sym(ca.mtimes(R_prev.T, R))
            parts += [theta, phi, p, psi]
            R_prev = R
        g0 = self.tension_gain_start
        return ca.vertcat(*parts, x[3:6], x[g0 : g0 + self.n_tension_gain])

    # --- numeric helpers ----------------------------------------------------------
    def shape(
        self,
        tensions: Sequence[float] | FloatArray,
        force: Sequence[float] | FloatArray = (0, 0, 0),
    ) -> dict[str, float]:
        """The robot's equilibrium as the estimators' model computes it, under the
        tendon tensions ``tensions`` (N, the robot file's tendon order; a slack tendon
        at 0) and the tip force ``force`` (N, base frame): the estimate file's columns
        (:attr:`outputs`, by name): the tip ``x, y, z`` (m), then per section ``theta_k,
        phi_k`` (rad; ``phi_k`` 0 where straight), its end ``x_k, y_k, z_k`` (m) and twist
        ``psi_k`` (rad), then ``fx, fy, fz`` (N), and each tension gain at 1. For
        checking a robot file against a pose measured on the robot.

        Raises:
            UserError: if ``tensions`` is not one finite, non-negative tension per
                tendon, or ``force`` not three finite values.
            ArithmeticError: if the rod holds no equilibrium under these loads.
        """
        tau = np.asarray(tensions, dtype=float).reshape(-1)
        f = np.asarray(force, dtype=float).reshape(-1)
        k = self.robot.n_tendons
        if tau.size != k or not np.all(np.isfinite(tau)) or np.any(tau < 0):
            raise UserError(
                f"shape: give {k} finite, non-negative tensions (N) in the robot file's "
                f"tendon order, got {np.array2string(tau, precision=4)}"
            )
        if f.size != 3 or not np.all(np.isfinite(f)):
            raise UserError(f"shape: the tip force is three finite values (N), got {f}")
        k0, _ = self.statics.solve(f, tau)
        x = np.zeros(self.nx)
        x[:3], x[3:6], x[6 : 6 + k] = k0, f, tau
        g0 = self.tension_gain_start
        x[g0 : g0 + self.n_tension_gain] = 1.0
        return dict(zip((o.name for o in self.outputs), map(float, self.output(x))))

    def imus_determine_shape(self, imus: tuple[int, ...]) -> bool:
        """With the tensions given, the shape follows from the tip force: three unknowns.
        Each IMU pins two of them at once through its gravity direction, so two IMUs
        determine the shape at every sample. One raw IMU determines it only over time:
        its gyro, integrated from the start, gives the third (the stacked Jacobians of
        the shipped robot's tip IMU have full rank over 25 samples, IMU-error states
        included), but loosely (docs/tendon-studies.md, "One IMU"), so a single IMU is
        still reported as not determining the shape."""
        return 2 * len(imus) >= 3

    def unobservable_detail(self, rank: int, bends: int) -> str:
        return (
            "read fewer than the three components of the tip force that set its shape "
            "with the tensions (two per IMU: its gravity direction)"
        )

    @property
    def sensor_states(self) -> tuple[int, ...]:
        """The states that describe the sensors, not the robot's motion: the gyro
        biases, the IMUs' misalignments and accelerometer biases, the tension gains."""
        g0 = self._n_motion
        return tuple(range(g0, self.nx))

    def start_prior(
        self, z0: FloatArray, kept: KeptSensors | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """``(x0, P0)``: the start at the reading ``z0`` (:meth:`initial_state`), with the
        tip force's prior that the reading allows.

        With raw IMUs (``direct``) and :attr:`initial_force_std` None (the default), a
        start on a nearly straight robot (:meth:`start_bend` at most
        :data:`FREE_START_MAX_BEND`) that the readings show free of load takes a tip
        force prior of :data:`FREE_START_FORCE_FRACTION` of the wide one. At a start
        the IMUs' misalignment and accelerometer bias tilt their readings as a small
        tip force would; under the wide prior the start and the first updates take them
        for a force, and the shape is off by millimetres until the robot has bent
        enough to tell the two apart (docs/tendon-studies.md, "The tip force's prior").
        Free of load: fitted with the narrow prior, the readings' misfit
        (:meth:`start_misfit`) is at most its chi-square quantile of
        :data:`LOADED_START_PROBABILITY`. Under
        load, with tilt IMUs (where the narrow prior is not better on the recordings
        measured) and with :attr:`initial_force_std` given: the wide prior of
        :meth:`initial_cov`. Only the force's own prior narrows: its rate's stays wide,
        so that a load that comes later is followed.

        ``kept``: a restart within a recording (after a gap, a live reconnect), with
        the sensor states' values and covariance of the estimate before it
        (:meth:`kept_sensors`). The fit then holds the IMUs' errors and gyro biases at
        those values, and with the IMUs' errors known the reading shows a load: where it
        is not free of load, the force, and with raw IMUs its rate (fitted to the gyros),
        take a prior of :data:`KEPT_START_BUCKLING_MULTIPLE` times the buckling load."""
        if (
            self.initial_force_std is None
            and self.imu_model == "direct"
            and self.start_bend(z0) <= FREE_START_MAX_BEND
        ):
            narrow = FREE_START_FORCE_FRACTION * self.force_prior_std
            x, misfit, limit = self._start_fit(z0, narrow, kept)
            if misfit <= limit:
                P = self.with_kept_covariance(self.initial_cov(), kept)
                P[3:6, 3:6] = np.eye(3) * narrow**2
                return x, P
        if kept is not None:  # the IMUs' errors known: the reading shows the load
            wide = KEPT_START_BUCKLING_MULTIPLE * self.buckling_load
            x = self._start_fit(z0, wide, kept)[0]
            P = self.with_kept_covariance(self.initial_cov(), kept)
            k = self.robot.n_tendons
            P[3:6, 3:6] = np.eye(3) * wide**2
            if self.imu_model == "direct" and self._gyro_biases_kept(kept):
                P[9 + k : 12 + k, 9 + k : 12 + k] = np.eye(3) * wide**2  # fitted to the gyros
            return x, P
        return self._start_fit(z0, self.force_prior_std)[0], self.initial_cov()

    @property
    def load_states(self) -> tuple[int, ...]:
        """The tip force ``fx, fy, fz``, its rate and (where estimated) its acceleration;
        none without :attr:`free_of_load_hypothesis`."""
        if not self.free_of_load_hypothesis:
            return ()
        names = self.state_names
        return tuple(i for i, n in enumerate(names) if re.fullmatch(r"f[xyz](_dot|_ddot)?", n))

    @property
    def evidence_given(self) -> tuple[int, ...]:
        """With :attr:`imu_evidence` (resolved: by default for a robot with one IMU) the
        tensions' and the tip condition's rows, so that the load hypotheses are weighed
        by the IMU readings given them; else none (the whole measurement)."""
        on = self.imu_evidence
        if on is None:
            on = self.robot.n_imus == 1
        if not on:
            return ()
        return tuple(
            i
            for b in self.measurement_blocks
            if not b.is_imu
            for i in range(b.start, b.start + b.size)
        )

    @property
    def load_outputs(self) -> tuple[int, ...]:
        """The tip force ``fx, fy, fz``."""
        names = [o.name for o in self.outputs]
        return tuple(names.index(c) for c in TIP_FORCE_COLUMNS)

    def unloaded_start(
        self, z0: FloatArray, kept: KeptSensors | None = None
    ) -> tuple[FloatArray, FloatArray, bool]:
        """``(x0, P0, shows_load)``: the start free of load, :meth:`start_prior`'s fit
        with the tip force held at zero (a prior of :data:`UNLOADED_FIT_FORCE_STD`), the
        force and its derivatives zero and certain; and whether the reading shows a load
        that a start cannot tell from the IMUs' errors: without ``kept`` sensors, the
        fit's misfit (:meth:`start_misfit`) beyond its chi-square quantile of
        :data:`LOAD_AT_START_PROBABILITY` (never for a reading without an accelerometer
        row, which shows no load). At one pose a load tilts the IMUs as their
        misalignments and accelerometer biases do, and the estimates that follow such a
        start take part of the load for those errors (docs/tendon.md, "Limits")."""
        x, misfit, limit = self._start_fit(
            z0, UNLOADED_FIT_FORCE_STD, kept, probability=LOAD_AT_START_PROBABILITY
        )
        P = self.with_kept_covariance(self.initial_cov(), kept)
        x, P = without_load(x, P, self.load_states)
        return x, P, kept is None and _shows_load(misfit, limit)

    def start_untrusted(self, z0: FloatArray) -> bool:
        """Whether the reading ``z0`` shows a tip load that a start knowing nothing of
        the IMUs' errors cannot tell from them: :meth:`unloaded_start`'s test (its fit
        free of load misses the reading beyond the chance
        :data:`LOAD_AT_START_PROBABILITY`), asked by every estimator at such a start."""
        _, misfit, limit = self._start_fit(
            z0, UNLOADED_FIT_FORCE_STD, None, probability=LOAD_AT_START_PROBABILITY
        )
        return _shows_load(misfit, limit)

    def _gyro_biases_kept(self, kept: KeptSensors | None) -> bool:
        """Whether a restart kept every gyro bias (with raw IMUs): the gyros then show
        the force's rate."""
        if kept is None or self.imu_model != "direct":
            return False
        biases = range(self._n_motion, self._n_motion + self.n_gyro_bias)
        return set(biases) <= {int(i) for i in kept.states}

    def start_bend(self, z0: FloatArray) -> float:
        """The angle, rad, between the base axis and the tip's tangent in the unloaded
        equilibrium of the reading ``z0``'s tensions (inf where the statics find none)."""
        try:
            _, poses = self.statics.solve(np.zeros(3), self._start_tensions(z0))
        except ArithmeticError:
            return math.inf
        tip = poses[Station(self.robot.n_sections - 1, 1.0)][0]
        return float(np.arccos(np.clip(tip[2, 2], -1.0, 1.0)))

    def _start_tensions(self, z0: FloatArray) -> FloatArray:
        """The tensions of the reading ``z0`` a start takes, N: a missing one as 0, and
        none below 0."""
        n, k = self.n_imu_measurements, self.robot.n_tendons
        return np.maximum(np.nan_to_num(np.asarray(z0, dtype=float)[n : n + k], nan=0.0), 0.0)

    def initial_state(self, z0: FloatArray) -> FloatArray:
        """The base curvature and the tip force that fit the IMUs best in equilibrium
        with the sample's tensions (least squares from the unloaded equilibrium), held
        to it by a faint prior (:data:`START_PRIOR_WEIGHT` times that of
        :meth:`initial_cov`) that keeps what the IMUs cannot see, such as the twist of
        a straight rod, at the unloaded value instead of leaving the fit to wander
        along it. With raw IMUs the base curvature's rate that keeps the tip condition
        at the tensions' rates (the tip force's rate zero) and, where estimated, each
        gyro's bias (its reading less the rate the model predicts) are fitted with
        them: a gyro reading fixes its bias, not the force (a bias left at zero reads as
        a force, on a straight rod an axial one the IMUs barely see). The other rates
        and biases zero, the tension gains 1 (the tensions as given).
        The tip force's prior is :meth:`start_prior`'s."""
        return self.start_prior(z0)[0]

    def _start_fit(
        self,
        z0: FloatArray,
        force_std: float,
        kept: KeptSensors | None = None,
        probability: float = LOADED_START_PROBABILITY,
    ) -> tuple[FloatArray, float, float]:
        """``(x, misfit, limit)``: :meth:`initial_state`'s fit with the tip force's prior
        standard deviation ``force_std`` (N), the fitted readings' misfit (see
        :meth:`start_misfit`) and its chi-square quantile of ``probability`` (inf and 0
        without a valid reading).
        ``kept`` (:meth:`kept_sensors`): the sensor states held at those values (the
        gyro biases to their kept standard deviations), and with raw IMUs the force's
        rate fitted too (``force_std`` per second)."""
        z0 = np.asarray(z0, dtype=float)
        n, k = self.n_imu_measurements, self.robot.n_tendons
        tau = self._start_tensions(z0)
        k0, _ = self.statics.solve(np.zeros(3), tau)
        x = np.zeros(self.nx)
        x[:3], x[6 : 6 + k] = k0, tau
        g0 = self.tension_gain_start
        x[g0 : g0 + self.n_tension_gain] = 1.0  # the prior: the tensions as given
        if kept is not None:
            x[kept.states] = kept.values
        z = np.nan_to_num(z0, nan=0.0)
        z[n : n + k] = tau
        valid = np.isfinite(z0[:n])
        if not valid.any():
            return x, math.inf, 0.0  # nothing shows the start free of load
        # fitted: k0, F; with raw IMUs k0' (held by the tip condition's rate) and the
        # gyro biases
        free = np.r_[0:6]
        if self.imu_model == "direct":
            bias = self._n_motion  # the gyro biases follow the motion states
            free = np.r_[free, 6 + k : 9 + k, bias : bias + self.n_gyro_bias]
            if self._gyro_biases_kept(kept):  # the gyros then show the force's rate
                free = np.r_[free, 9 + k : 12 + k]
        w = np.sqrt(1.0 / np.diag(self.meas_cov()))
        prior = x[free].copy()
        std = np.sqrt(np.diag(self.initial_cov()))
        prior_w = START_PRIOR_WEIGHT / std[free]
        prior_w[3:6] = 1.0 / force_std  # the force's own prior
        if self.imu_model == "direct" and self._gyro_biases_kept(kept):
            prior_w[-3:] = 1.0 / force_std  # the force's rate, per second
        if kept is not None:  # the kept gyro biases: their own standard deviations
            at = {int(state): i for i, state in enumerate(kept.states)}
            for j, state in enumerate(free):
                if int(state) in at:
                    i = at[int(state)]
                    prior_w[j] = 1.0 / math.sqrt(max(float(kept.cov[i, i]), 1e-30))
        # the residual and its Jacobian by the compiled core (forward mode), the same
        # functions the compiled EKF evaluates
        model = _core.ResidualNodeFunction(*residual_node_tapes(self), with_transition=False)
        nz, nx = self.nz, self.nx
        inputs = [x.copy(), np.zeros(self.nu), np.zeros(1), z, np.ones(nz)]
        out = np.empty(model.output_size)

        def evaluate(v: FloatArray) -> tuple[FloatArray, FloatArray]:
            """The residual at the state ``v`` and its Jacobian ``dr/dx``."""
            inputs[0][:] = v
            model.evaluate(inputs, out)
            return out[nz * nx :].copy(), -out[: nz * nx].reshape(nz, nx)  # H = -dr/dx

        scale = np.r_[[1.0] * 3, [0.1] * 3, [1.0] * 3, [0.01] * self.n_gyro_bias, [0.1] * 3]
        eq = self.measurement_blocks[-1]  # the tip condition (with raw IMUs, its rate too)
        spec = EquilibriumFit(
            free=free,
            # the base curvature (with raw IMUs, its rate too), which those rows settle
            settled=np.r_[0:3, 6 + k : 9 + k] if self.imu_model == "direct" else np.r_[0:3],
            equilibrium_rows=np.arange(eq.start, eq.start + eq.size),
            rows=np.flatnonzero(valid),
            weights=w,
            prior=prior,
            prior_weights=prior_w,
            scale=scale[: len(free)],
        )
        fit = fit_on_equilibrium(evaluate, x, spec, START_EVALUATIONS)
        # (where not even the unloaded equilibrium settles, its misfit says so)
        x, r = fit.x, fit.residual if fit.residual is not None else evaluate(fit.x)[0]
        misfit, limit = self.start_misfit(r[:n], valid, probability)
        return x, misfit, limit

    def start_misfit(
        self,
        r: FloatArray,
        valid: NDArray[np.bool_],
        probability: float = LOADED_START_PROBABILITY,
    ) -> tuple[float, float]:
        """``(misfit, limit)``: the squares of the IMUs' residuals ``r`` (the first
        :attr:`n_imu_measurements` of the residual) where ``valid``, each over its
        reading's variance plus that of the IMU's misalignment and accelerometer bias
        priors (the gyros' rows left out: a start fits their biases), summed; and the
        chi-square quantile of ``probability`` (the chance of a larger misfit free of
        load) for as many terms (inf and 0 without an accelerometer row: nothing shows
        the start free of load)."""
        var = np.diag(self.meas_cov())[: self.n_imu_measurements].copy()
        errors = self.initial_misalignment_std**2 if self.estimate_misalignment else 0.0
        if self.estimate_accel_bias:
            errors += (self.initial_accel_bias_std / STANDARD_GRAVITY) ** 2
        direction = np.ones(self.n_imu_measurements, dtype=bool)
        if self.imu_model == "direct":  # per IMU: f / |f| (3), then the gyro (3)
            direction = np.tile(np.r_[[True] * 3, [False] * 3], self.robot.n_imus)
        used = direction & np.asarray(valid, dtype=bool)
        if not used.any():  # no accelerometer: nothing shows the start free of load
            return math.inf, 0.0
        misfit = float(np.sum(np.asarray(r)[used] ** 2 / (var[used] + errors)))
        return misfit, chi2_quantile(1.0 - probability, int(used.sum()))

    def initial_cov(self) -> FloatArray:
        """The start's prior: the tensions' that of the given ones
        (:attr:`tension_std`), or with the tension gains as states
        :data:`GAIN_TENSION_PRIOR_STD`, which leaves them to the gains (a tight prior
        on both would pin each gain to 1 at a start under tension)."""
        f = self.force_prior_std**2
        tension = GAIN_TENSION_PRIOR_STD if self.n_tension_gain else self.tension_std
        diag = [10.0**2] * 3 + [f] * 3 + [tension**2] * self.robot.n_tendons
        diag += [50.0**2] * 3 + [f] * 3
        diag += [self.initial_force_acceleration_std**2] * self.n_force_acceleration
        diag += [self.initial_gyro_bias_std**2] * self.n_gyro_bias
        diag += [self.initial_misalignment_std**2] * self.n_misalignment
        diag += [self.initial_accel_bias_std**2] * self.n_accel_bias
        diag += [self.initial_tension_gain_std**2] * self.n_tension_gain
        return np.diag(diag)

    def state_bounds(self) -> tuple[FloatArray, FloatArray]:
        """None but the tension gains', at least :data:`MIN_TENSION_GAIN`."""
        lo, hi = np.full(self.nx, -np.inf), np.full(self.nx, np.inf)
        g0 = self.tension_gain_start
        lo[g0 : g0 + self.n_tension_gain] = MIN_TENSION_GAIN
        return lo, hi

    @cached_property
    def _imu_error_test(self) -> tuple[NDArray[np.int64], FloatArray, float]:
        """``(indices, prior std, limit)`` of :meth:`drifted`: the IMU-error states, their
        prior standard deviations and the chi-square quantile of
        :data:`IMU_ERROR_PROBABILITY` for as many degrees of freedom."""
        idx = np.array(
            [i for i, n in enumerate(self.state_names) if n.startswith(("bg", "mis", "ba"))],
            dtype=np.int64,
        )
        std = np.sqrt(np.diag(self.initial_cov()))[idx]
        limit = chi2_quantile(IMU_ERROR_PROBABILITY, len(idx)) if len(idx) else np.inf
        return idx, std, limit

    def drift_resets(self) -> bool:
        """As the base class's; not with tension gains estimated, whose drift is the
        gains settling, which no restart helps."""
        return super().drift_resets() and not self.estimate_tension_gain

    def change_test(self) -> ChangeTest | None:
        """The IMUs' error states (those of :meth:`drifted`) for the estimate-change test:
        an estimate whose IMU errors moved in the last :data:`CHANGE_LAG` seconds beyond
        what the information gained and their random walk allow is ``drifted``."""
        idx, std, _ = self._imu_error_test
        if not len(idx):
            return None
        psd = np.diag(self.process_cov(1.0))[idx]
        return ChangeTest(
            rows=tuple(int(i) for i in idx),
            scale=tuple(float(v) for v in std),
            psd=tuple(float(v) for v in psd),
            lag=CHANGE_LAG,
            probability=CHANGE_PROBABILITY,
        )

    def drifted(self, x: FloatArray) -> bool:
        """True when the IMUs' error states have drifted beyond their prior: the sum of
        their squares in units of their prior standard deviations exceeds the
        chi-square quantile of :data:`IMU_ERROR_PROBABILITY` (status ``drifted``). The
        estimate then follows the readings only with IMU errors these IMUs are not taken
        to have: the model does not describe the robot (tensions of another scale or
        order, a load it has no state for). Also true where the tip force pushes along
        the tip's tangent harder than :data:`BUCKLED_PUSH_MULTIPLE` buckling loads
        (:meth:`tip_push`): an equilibrium the backbone cannot hold."""
        x = np.asarray(x, dtype=float)
        limit = BUCKLED_PUSH_MULTIPLE * self.buckling_load
        # the push is at most the force's size: the shooting only where it could pass
        if float(np.linalg.norm(x[3:6])) > limit and self.tip_push(x) > limit:
            return True
        idx, std, limit = self._imu_error_test
        if not len(idx):
            return False
        return float(np.sum((x[idx] / std) ** 2)) > limit

    def tip_push(self, x: FloatArray) -> float:
        """The tip force's component against the tip's tangent at state ``x``, N: the
        push along the backbone (negative: a pull)."""
        q = np.asarray(x, dtype=float)[: 6 + self.robot.n_tendons]
        if not np.all(np.isfinite(q)):
            return math.nan
        return float(self._tip_push_fn(q))

    @cached_property
    def _tip_push_fn(self) -> ca.Function:
        """:meth:`tip_push` of the state, a CasADi function of the state's first
        ``6 + k`` entries (base curvature, tip force, tensions)."""
        k = self.robot.n_tendons
        q = ca.SX.sym("q", 6 + k)
        tip = Station(self.robot.n_sections - 1, 1.0)
        poses, _ = self.statics.shoot(q[:3], q[3:6], q[6:], (tip,))
        return ca.Function("tip_push", [q], [-ca.dot(q[3:6], poses[tip][0][:, 2])])

    def is_diverged(self, x: FloatArray, P: FloatArray | None = None) -> bool:
        """Non-finite, or a tip force over :attr:`max_force_used`, or its standard
        deviation over it, or a tension gain not positive (tendons that push)."""
        if super().is_diverged(x, P):
            return True
        g0 = self.tension_gain_start
        if np.any(np.asarray(x)[g0 : g0 + self.n_tension_gain] <= 0):
            return True
        limit = self.max_force_used
        if float(np.linalg.norm(x[3:6])) > limit:
            return True
        return P is not None and float(np.trace(P[3:6, 3:6])) > limit**2


def acting_tensions(
    robot: Robot, given: FloatArray, names: Sequence[str], values: FloatArray
) -> FloatArray:
    """The tensions acting on ``robot``, N, (n, k): the ``given`` ones (n, k) times each
    tendon's section's tension gain where the rows ``values`` (n, len(names)) of an
    estimate have its column ``tension_gain_s`` (``s`` the 1-based section at whose end
    the tendon is anchored; :attr:`TendonFormulation.estimate_tension_gain`), else as
    given."""
    given = np.atleast_2d(np.asarray(given, dtype=float))
    values = np.atleast_2d(np.asarray(values, dtype=float))
    col = {c: i for i, c in enumerate(names)}
    gains = np.ones_like(given)
    for j, tendon in enumerate(robot.tendons):
        i = col.get(f"tension_gain_{tendon.section + 1}")
        if i is not None:
            gains[:, j] = values[:, i]
    return np.asarray(given * gains, dtype=float)


def _shows_load(misfit: float, limit: float) -> bool:
    """Whether a start fit free of load misses its reading beyond ``limit`` (a reading
    without an accelerometer row shows nothing: an infinite misfit)."""
    return math.isfinite(misfit) and misfit > limit
