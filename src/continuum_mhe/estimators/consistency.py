"""Whether the readings agree with the estimates, every sample, in every estimator
(status ``inconsistent``), and the model error they show (the ``noise_scale`` that
widens the standard deviations).

An estimate is only worth ``ok`` when the readings around it agree with its model and
noise. Two tests, on the formulation's own residual ``r(z, x)`` (the one every
estimator weights with ``R^-1``), valid components only, and readings only: a model's
pseudo-measurement (a tendon robot's tip condition, block kind ``"equilibrium"``) is
met by an EKF step only to the step's linearisation, many of its tiny standard
deviations off, and says nothing about the readings; nor are the rows a model reads as
inputs (:meth:`Formulation.input_rows
<continuum_mhe.model.formulations.Formulation.input_rows>`: a tendon robot's tension
rates), whose residual is zero at every state: counted, they would add degrees of
freedom to every quantile below without adding to the statistic:

* **this reading against the previous estimate** (innovation): the previous
  ``(x, P)`` predicted to this sample (``x+ = f(x, u, dt)``, ``P+ = F P F^T + Q``),
  ``NIS = r^T (H P+ H^T + R)^-1 r`` with ``r = r(z, x+)``; a covariance collapsed on a
  wrong shape gives a huge NIS at the next reading;
* **this reading against this estimate** (fit): ``r(z, x)^T R^-1 r(z, x)``, never
  larger than the NIS for a consistent estimator (the update only shrinks the
  residual); a window dragged by a wrong reading, or a shape the model cannot reach,
  leaves it large.

Either beyond the ``SAMPLE_QUANTILE`` (99.99 %) chi-square quantile, or beyond the
``RUN_QUANTILE`` (99 %) at this reading and the one before, marks this sample
``inconsistent``. On data that agree with the model these tests flag about 1 row in
100,000; the average's test below flags stretches of tens of rows in a few of 100
one-minute recordings, about 24 rows in 10,000 in all (docs/options.md).

An update that is not a linear one is tested too: a linear model's exact update leaves
the residual ``r = R S^-1 nu`` (``S = H P+ H^T + R``, ``nu`` the innovation), so the fit
implies the innovation ``S R^-1 r``, whose NIS ``(R^-1 r)^T S (R^-1 r)`` is the NIS
itself for a linear model. Where it is beyond the ``SAMPLE_QUANTILE`` quantile the
estimate left more of the reading unexplained than an update could (a filter's one
linearisation across a large step, sampled at 1 Hz); the sample is ``inconsistent``
when, in addition, the shift that fits the readings, ``d = (H^T R^-1 H)^+ H^T R^-1 r``
over the states they depend on, lies outside the estimate's own covariance:
``d^T P^+ d`` beyond the ``SHIFT_QUANTILE`` (95 %) quantile of as many degrees of
freedom (an unscented filter that left the reading unexplained with a covariance that
says so is not). Model
error that no single reading shows is caught by the average (of the readings not
flagged on their own):
an exponentially weighted mean of ``NIS / dof`` over about ``MEMORY`` samples
(covariance matching: the factor by which the innovations exceed what ``R`` and ``P``
predict) is :attr:`ConsistencyCheck.noise_scale`. It is judged against the level the
readings scattered at while the model followed them, the *quiet level*: a slower
average over about ``QUIET_MEMORY`` samples while no model error shows
(:attr:`ConsistencyCheck.quiet_scale`, starting at 1), never taken above 1, learned
from the samples with as many readings as the most of any sample so far, and started
again from 1 when a sample has more (an IMU's first reading): while an IMU is silent
the others' innovations scatter less, and a level learned from them would flag the
rows after its return. Real
readings are often less noisy than ``R`` says (a MEMS IMU's direction noise is a
fraction of the 2 degrees assumed), and a model error then shows as innovations two to
four times their own level while still below ``R``'s. The ratio of the two averages is
F-distributed where the model follows (``dof * (2 MEMORY - 1)`` and ``dof * (2
QUIET_MEMORY - 1)`` degrees of freedom); beyond its ``QUANTILE`` (99.9 %) quantile the
sample is ``inconsistent`` too. On every sample, ``inconsistent`` or not, the
estimator's own output standard deviations are multiplied by ``sqrt(noise_scale)``
where it exceeds 1 (the covariances are scaled as the noise is; the constant-error
term below is added afterwards, not multiplied).
Once beyond that quantile, the samples stay ``inconsistent`` until the average has been
back at the quiet level for ``MEMORY`` samples in a row (as long as it remembers): a
model error does not end when the average merely drops below the quantile, nor when
it touches the quiet level between two phases of a motion that shows it.

What the check learned is the robot's: an estimator's restart within a recording (a
gap, a bad start, a divergence) forgets only the previous estimate
(:meth:`ConsistencyCheck.restart`); the averages, the ``inconsistent`` run and the
model error stay, and only a new recording (:meth:`ConsistencyCheck.reset`) starts
them again.

A model error the readings showed does not go away when their residuals quieten: with
one IMU per section the gravity directions determine the shape exactly, so a shape the
model gets wrong (a curvature that is not constant, a twist) leaves no residual at all
most of the time, and shows only while the robot moves in a way the model cannot
follow. The excess the average showed at such a detection over the quiet level,
``noise_scale - min(1, quiet_scale)`` in units of ``R``, is
:attr:`ConsistencyCheck.model_error`: the largest of the
recording (the estimator's restarts keep it), carried as a constant error of the
gravity-direction readings (below), not as white noise (a slowly varying model error is
not averaged away by the filter or the window). Before the readings show one, and
wherever the one they showed is smaller, each gravity-direction reading carries the
model error the constant-curvature model is taken to make of a real robot
(``Formulation.model_error_floor``, ``NoiseSettings.model_error_std``): the rows
before a model error first shows, and the rows of a robot whose readings never show
it (two IMUs' tilt fit two sections' bends exactly whatever the model error), are
otherwise widened by nothing.

Some error no residual shows: a constant error in every reading of an IMU (its
mounting misalignment, its accelerometer's bias) looks like a different shape.
:meth:`ConsistencyCheck.constant_error_cov` is the estimate's covariance from it, the
readings' constant-error covariance ``B`` (``Formulation.reading_bias_cov``,
``NoiseSettings.reading_bias_std``, plus ``model_error`` times ``R``, at least the
floor, on the gravity-direction readings) carried through the estimate's weighted
least-squares sensitivity to the readings that carry such an error (the gravity
directions; the states they depend on: the bends),
``A = (H^T R^-1 H + G)^+ H^T R^-1`` at the estimate: ``A B A^T``. ``G`` is the
bends' range as information (``1 / theta_max^2`` on each bend coordinate of the
constant-curvature formulations, ``Formulation.range_std``; 0 for a tendon robot's
mechanics model): where the readings barely pin a direction of the shape,
the linear sensitivity alone would shift it by tens of radians, and ``G`` keeps the
shift within the range the robot has (at most ``theta_max / 2`` per unit of the
constant error in units of ``R``); where the readings pin the shape it changes ``A``
by a fraction of ``G`` against ``H^T R^-1 H`` (about 1e-4). Its output standard
deviations are added in quadrature to the estimator's (a constant reading error
shifts an estimate by ``A`` times it, as long as the window or the filter's memory is
shorter than the motion); the status does not depend on it.

An IMU's own acceleration is such an error too, while it lasts, where the model reads
the accelerometer's direction as gravity's and nothing else holds the bends: tilt
readings (:func:`~continuum_mhe.model.imu_motion.takes_acceleration_as_gravity`, the
``bend`` formulation). Raw readings' gyros hold the bends through a motion that lasts
a fraction of a second, so the sensitivity ``A`` of the gravity directions alone
overstates what such an error does to their estimate: carried so, it took the shipped
rods' raw recordings' ``ok`` rows' coverage to 0.993 / 0.993 / 0.983 (EKF, pooled),
beyond the 0.99 that intervals of the right width reach.
The estimate gives each IMU's velocity; differenced over :data:`ACCELERATION_SPAN_S`,
it gives the acceleration, and the error it puts into each gravity-direction reading
(:func:`~continuum_mhe.model.imu_motion.own_acceleration_functions`) enters ``B`` as
that reading's model error where it exceeds the one carried already (the one learned,
at least the floor): ``max(model_error R, floor, e^2)``. Where the robot leaves a pose
quickly the standard deviations widen with it (and a row whose written tip standard
deviation then exceeds the uncertain fraction is ``uncertain``); at rest and in slow
motion nothing changes. Not where the floor is 0 (readings drawn from the model
itself, as ``continuum-mhe simulate`` draws them, carry no acceleration).

The numerics run in the compiled core (``continuum_mhe._core.ConsistencyCheck``,
``csrc/consistency.*``), which evaluates the node model the EKF uses
(:func:`~continuum_mhe.estimators.fast.window_functions.node_function`, split into the parts
each step needs: :func:`model_tapes`) without Python in between; this class gives it
the formulation's noise, limits and, per sample, the inputs and the process noise
``Q(dt)``.

A formulation whose covariance is not one (``Formulation.calibrated_covariance``
False: the paper formulation's weight ``W``) is not checked, nor an estimate without a
covariance.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache

import numpy as np

from continuum_mhe import _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.estimators.fast.model import node_functions
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu_motion import (
    own_acceleration_functions,
    takes_acceleration_as_gravity,
)
from continuum_mhe.model.tape import tape_function
from continuum_mhe.quantiles import chi2_quantile, f_quantile

#: Quantile of the F distribution beyond which the average of NIS / dof over the quiet
#: level is inconsistent.
QUANTILE = 0.999
#: Chi-square quantile beyond which one reading is inconsistent with the estimate.
SAMPLE_QUANTILE = 0.9999
#: Chi-square quantile beyond which two readings in a row are inconsistent.
RUN_QUANTILE = 0.99
#: Chi-square quantile beyond which the shift that fits the readings is outside the
#: estimate's covariance (tested only where the fit is not a linear update's, and only
#: for models without pseudo-measurements).
SHIFT_QUANTILE = 0.95
#: Samples the average of ``NIS / dof`` remembers (its exponential weight is 1/MEMORY).
MEMORY = 20
#: Samples the average of ``NIS / dof`` while no model error shows remembers (the
#: level the readings scatter at while the model follows them).
QUIET_MEMORY = 5 * MEMORY
#: The time over which the IMUs' velocities from the estimate are differenced into their
#: acceleration, s (four samples at 50 Hz): a difference over one sample carries the
#: estimated rates' noise, a longer one lags the motion it should follow.
ACCELERATION_SPAN_S = 0.08
#: Eigenvalues of ``H^T R^-1 H`` at most this times the largest are taken as zero in
#: its pseudo-inverse (:meth:`ConsistencyCheck.constant_error_cov`).
PINV_RCOND = 1e-9

_EMPTY = np.zeros(0)


class ConsistencyCheck:
    """The consistency of one estimator's estimates with its readings (module doc)."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        f, nz = formulation, formulation.nz
        R = np.asarray(f.meas_cov(), dtype=float)
        # the effective samples of the exponential averages
        n_avg, n_quiet = 2 * MEMORY - 1, 2 * QUIET_MEMORY - 1
        # the rows judged: the readings, not a model's pseudo-measurements (a tendon
        # robot's tip condition, met only to the linearisation of a step) nor the rows it
        # reads as inputs (a tendon robot's tension rates), whose residual is zero: counted
        # among the degrees of freedom they would loosen every chi-square limit
        judged = f.judged_rows()
        self._judged_rows = np.flatnonzero(judged)
        gravity_r = np.where(f.gravity_direction_rows(), np.diag(R), 0.0)
        # the shift test reads the update as a linear one of the judged rows alone
        # (``r = R S^-1 nu``); pseudo-measurements pull the update too, so it is off
        # for a model that has them
        shift_limit = (
            _limits(lambda k: chi2_quantile(SHIFT_QUANTILE, k), f.nx)
            if judged.all()
            else [math.inf] * (f.nx + 1)
        )
        transition, measurement, residual = model_tapes(f)
        self._core = _core.ConsistencyCheck(
            transition,
            measurement,
            residual,
            nx=f.nx,
            nu=f.nu,
            nz=nz,
            R=R.ravel().tolist(),
            judged=judged.astype(float).tolist(),
            limit=_limits(lambda k: chi2_quantile(SAMPLE_QUANTILE, k), nz),
            run_limit=_limits(lambda k: chi2_quantile(RUN_QUANTILE, k), nz),
            avg_limit=_limits(lambda k: f_quantile(QUANTILE, k * n_avg, k * n_quiet), nz),
            shift_limit=shift_limit,
            bias=np.diag(np.asarray(f.reading_bias_cov(), dtype=float)).tolist(),
            gravity_r=gravity_r.tolist(),
            memory=MEMORY,
            quiet_memory=QUIET_MEMORY,
            rcond=PINV_RCOND,
            model_error_floor=f.model_error_floor(),
            range_info=(1.0 / np.asarray(f.range_std(), dtype=float) ** 2).tolist(),
        )
        if f.model_error_floor() > 0.0 and f.name == "bend" and takes_acceleration_as_gravity(f):
            self._motion = motion_tapes(f)  # kept alive with the check
            self._core.set_own_acceleration(*self._motion, ACCELERATION_SPAN_S)
        self._q = ProcessNoiseCache(formulation)
        self._prev: tuple[float, FloatArray] | None = None  # the previous (t, z)

    @property
    def core(self) -> _core.ConsistencyCheck:
        """The compiled check (the compiled sensor-health policy steps it)."""
        return self._core

    def reset(self) -> None:
        """Forget the previous estimate, the average and the model error (a new
        recording)."""
        self._core.reset()
        self._prev = None

    def restart(self) -> None:
        """Forget the previous estimate only (the estimator restarts within a
        recording): the average, whether it is beyond its quantile and the model error
        learned are the robot's, and stay."""
        self._core.forget()
        self._prev = None

    @property
    def noise_scale(self) -> float:
        """The exponentially weighted mean of NIS / dof (1 where nothing was seen yet)."""
        return self._core.noise_scale

    @property
    def model_error(self) -> float:
        """The model error the average showed (module doc): the largest excess of
        ``noise_scale`` over the quiet level beyond its quantile in the recording, in
        units of ``R``."""
        return self._core.model_error

    @model_error.setter
    def model_error(self, value: float) -> None:
        self._core.model_error = value

    def check(
        self,
        t: float,
        z: FloatArray,
        mask: FloatArray,
        state: FloatArray | None,
        cov: FloatArray | None,
    ) -> bool:
        """Whether this sample's estimate disagrees with its readings (status
        ``inconsistent``); remembers the estimate for the next sample. A sample
        without a valid reading, an estimate or a covariance is not judged (False)."""
        if state is None or cov is None:
            self._core.forget()
            self._prev = None
            return False
        u = Q = _EMPTY
        prev = self._prev
        if prev is not None and mask[self._judged_rows].any():
            # the prediction from the previous estimate: its inputs and process noise
            t0, z0 = prev
            dt = t - t0
            f = self.formulation
            if f.nu:
                u = np.asarray(f.inputs(z0, z, dt), dtype=float)
            Q = self._q(dt)[0]
        self._prev = (t, z.copy())
        return self._core.check(t, z, mask, state, cov, u, Q)

    def constant_error_cov(self, z: FloatArray, mask: FloatArray, state: FloatArray) -> FloatArray:
        """The state covariance (nx, nx) from the readings' constant errors and the
        model error (module doc): ``A B A^T`` with ``B`` the readings' constant-error
        covariance plus :attr:`model_error` times ``R``, at least
        ``Formulation.model_error_floor``, on the gravity-direction readings and
        ``A = (H^T R^-1 H + G)^+ H^T R^-1`` over the valid readings that carry a
        constant error (``B > 0``: the gravity directions) and the states they depend on
        (the bends: the readings that set the shape) at ``state``, ``G`` the diagonal of
        ``1 / Formulation.range_std()^2`` (0 where a state has no bound); zero where
        ``B`` is."""
        return self._core.constant_error_cov(z, mask, state)


def model_tapes(
    formulation: Formulation,
) -> tuple[_core.ModelFunction, _core.ModelFunction, _core.ModelFunction]:
    """The node function's outputs (:func:`~continuum_mhe.estimators.fast.window_functions.
    node_function`: ``(x, u, dt, z, m) -> (f, F, H, r)``) as three functions of its
    inputs, each the core evaluates only where the check needs it: the transition
    ``(f, F)`` (the prediction), the measurement ``(H, r)`` (at the prediction, and
    the constant-error covariance) and the residual ``r`` (the fit, without the
    Jacobian: the residual's own instructions, masked). The same expressions, so the
    same values as the node function's (with
    :attr:`~continuum_mhe.model.formulations.Formulation.forward_mode_jacobian`, ``H``
    by forward mode from the residual's instructions, as the EKF's node takes it). The
    objects are the EKF's node's (:func:`~continuum_mhe.estimators.fast.model.
    node_functions`): the check's prediction takes the EKF update's evaluation."""
    node = node_functions(formulation)
    return node.transition, node.measurement, node.residual


@lru_cache(maxsize=32)
def motion_tapes(formulation: Formulation) -> tuple[_core.TapeFunction, _core.TapeFunction]:
    """The IMUs' velocities and the reading errors of their acceleration
    (:func:`~continuum_mhe.model.imu_motion.own_acceleration_functions`) as the core
    evaluates them, built once per formulation (estimators side by side share them)."""
    velocity, error = own_acceleration_functions(formulation)
    return tape_function(velocity), tape_function(error)


def _limits(limit: Callable[[int], float], n: int) -> list[float]:
    """``[inf, limit(1), ..., limit(n)]``: a chi-square limit by the degrees of freedom
    (the judged readings, or the states of a shift; none: never beyond)."""
    return [math.inf] + [limit(k) for k in range(1, n + 1)]
