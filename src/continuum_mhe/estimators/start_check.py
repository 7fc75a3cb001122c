"""The bad-start check shared by every estimator (``RecoverySettings.bad_start``).

An estimator starts from its first reading. When the first readings are far off and
then become right, every estimator follows the wrong ones and needs several samples
to walk back (about 0.5 s on ``paper3d`` for MHE, EKF and UKF). The check: for
``RecoverySettings.bad_start`` seconds after each (re)start, the previous estimate
``(x, P)`` is predicted to the new sample (``x+ = f(x, u, dt)``,
``P+ = F P F^T + Q(dt)``) and the reading's normalised innovation squared
``NIS = r^T (H P+ H^T + R)^-1 r`` (``r = r(z, x+)``) is compared with the ``QUANTILE``
quantile of a chi-square with as many degrees of freedom as the rows it judges:
the valid rows that the consistency check judges (:mod:`.consistency`: the readings,
every row of a PCC robot; a tendon robot's IMUs and tensions, 10 rows with two tilt
IMUs and six tendons, 18 with raw IMUs), with the innovation taken given the sample's
other valid rows (a tendon robot's tip condition, a pseudo-measurement that says
nothing of the readings but pins states the motion model leaves free, and its tension
rates, inputs whose residual is zero at every state). Counted among the degrees of
freedom, those rows would loosen the limit (25 and 36 rows: 52.6 and 68.0 against 29.6
and 42.3), the rates without adding to the statistic. ``SAMPLES`` consecutive readings
above it restart the estimator from the current reading (status ``reset``). It uses
only the estimates' states and covariances and the formulation's model, so MHE, EKF and
UKF are checked alike; an estimate without a covariance is not checked, nor a
formulation whose covariance is not one
(``Formulation.calibrated_covariance`` False: the paper formulation's ``W`` is a
weight). On data that agree with the model the chance of
``SAMPLES`` consecutive exceedances is about ``(1 - QUANTILE)^SAMPLES`` (1e-6): the
check never fired on clean ``paper3d`` data (``reproduce``'s ``bad-start`` group).
A burst of consistent bad readings inside the probation time restarts the estimator
on the burst; the good readings after it then restart it again.

An IMU back after a silence longer than the gap reset (1 s when it is off) restarts its
part of the shape, which was predicted blindly meanwhile, without restarting the
estimator: the probation time opens again from its return,
and the estimate is *unconfirmed* (``Estimator.step``
makes it ``uncertain``, not ``ok``) until the returned IMUs' readings have agreed with
the estimate (NIS within the quantile) for as long as that silence threshold, which the
estimator's own restarts in between do not shorten. This part runs whether
``bad_start`` is set or not. The reason: the EKF's first update with the returned reading
can land far off with a small covariance, and readings of a wrong shape can agree with
it for a few samples. Two-section robot, one IMU silent for 1.5 to 5 s, 120 returns
(``python tools/imu_return_study.py``): within 2 s of the return, unconfirmed ``ok``
estimates are up to 143 standard deviations of their own tip position off (EKF; UKF 30,
MHE 41); with confirmation after two consistent readings still 7.8 (EKF) and 7.6 (UKF);
after 1 s of them at most 3.1, at a cost of about 20 samples (1 s at 20 Hz) not ``ok``
after each return.

The check runs in the compiled sensor-health policy (``csrc/sensor_health.*``, the
NIS on the consistency check's model functions, ``csrc/consistency.*``); this module
holds its constants.
"""

#: Chi-square quantile above which one reading is inconsistent with the estimate.
QUANTILE = 0.999
#: Consecutive inconsistent readings that restart the estimator.
SAMPLES = 2
#: Readings that must agree with an unconfirmed start (the first estimate, a forced
#: restart) once one of them disagreed with it, before its estimates are ``ok``: a wrong
#: shape fits a few readings in a row (an IMU upside down, two IMUs' columns swapped).
CONFIRM_SAMPLES = 5
