"""The bad-start check shared by every estimator (``RecoverySettings.bad_start``).

An estimator starts from its first reading. When the first readings are far off and
then become right, every estimator follows the wrong ones and needs several samples
to walk back (about 0.5 s on ``paper3d`` for MHE, EKF and UKF). The check: for
``RecoverySettings.bad_start`` seconds after each (re)start, the previous estimate
``(x, P)`` is predicted to the new sample (``x+ = f(x, u, dt)``,
``P+ = F P F^T + Q(dt)``) and the reading's normalised innovation squared
``NIS = r^T (H P+ H^T + R)^-1 r`` (valid components only, ``r = r(z, x+)``) is compared
with the ``QUANTILE`` quantile of a chi-square with as many degrees of freedom as valid
components. ``SAMPLES`` consecutive readings above it restart the estimator from the
current reading (status ``reset``). It uses only the estimates' states and covariances
and the formulation's model, so MHE, EKF and UKF are checked alike; an estimate
without a covariance is not checked, nor a formulation whose covariance is not one
(``Formulation.calibrated_covariance`` False: the paper formulation's ``W`` is a
weight). On data that agree with the model the chance of
``SAMPLES`` consecutive exceedances is about ``(1 - QUANTILE)^SAMPLES`` (1e-6): the
check never fired on clean ``paper3d`` data (``reproduce``'s ``bad-start`` group).
A burst of consistent bad readings inside the probation time restarts the estimator
on the burst; the good readings after it then restart it again.

An IMU back after a silence longer than the gap reset (1 s when it is off) restarts its
part of the shape, which was predicted blindly meanwhile, without restarting the
estimator (:meth:`StartCheck.reopen`): the probation time opens again from its return,
and the estimate is *unconfirmed* (:attr:`StartCheck.unconfirmed`; ``Estimator.step``
makes it ``uncertain``, not ``ok``) until the returned IMUs' readings have agreed with
the estimate (NIS within the quantile) for as long as that silence threshold, which the
estimator's own restarts in between do not shorten. This part runs whether
``bad_start`` is set or not. The reason: the EKF's first update with the returned reading
can land far off with a small covariance, and readings of a wrong shape can agree with
it for a few samples. Two-section robot, one IMU silent for 1.5 to 5 s, 120 returns
(``python tools/imu_return_study.py``): within 2 s of the return, ``ok`` estimates were
up to 143 standard deviations of their own tip position off before (EKF; UKF 30, MHE
41); with confirmation after two consistent readings still 7.8 (EKF) and 7.6 (UKF);
after 1 s of them at most 3.1, at a cost of about 20 samples (1 s at 20 Hz) not ``ok``
after each return.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.estimators.chi2 import chi2_quantile
from continuum_mhe.model.formulations import Formulation

FloatArray = NDArray[np.float64]

#: Chi-square quantile above which one reading is inconsistent with the estimate.
QUANTILE = 0.999
#: Consecutive inconsistent readings that restart the estimator.
SAMPLES = 2


class StartCheck:
    """State of the bad-start check of one estimator."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        self._R = formulation.meas_cov()
        self._limit = {k: chi2_quantile(QUANTILE, k) for k in range(1, formulation.nz + 1)}
        self.reset()

    def reset(self) -> None:
        """A new recording: :meth:`clear`, and no IMU is back from a silence."""
        self.clear()
        #: measurement rows of the IMUs back from a silence, not yet confirmed
        self._returned: NDArray[np.intp] | None = None
        self._hold = 0.0  # how long their readings must agree to confirm, s

    def clear(self) -> None:
        """Forget the previous estimate (a (re)start: the next estimate opens the
        probation time). IMUs back from a silence stay unconfirmed: agreement with the
        estimate before the restart does not count for the new one."""
        self._since = math.nan  # time of the first estimate after the (re)start, s
        self._prev: tuple[float, FloatArray, FloatArray, FloatArray] | None = None
        self._run = 0  # consecutive inconsistent readings
        self._agreed_since = math.nan  # t of the first estimate the returned IMUs agree with

    def reopen(self, rows: NDArray[np.intp], hold: float) -> None:
        """The IMUs of measurement ``rows`` are back after a silence: open the probation
        time again from the next estimate, as a (re)start does but keeping the
        estimate, and hold it unconfirmed until their readings have agreed with it for
        ``hold`` s. The kept previous estimate is dropped: outside the probation time it
        is stale, and the returned reading can only be judged against an estimate that
        used it."""
        self.clear()
        if self._returned is not None:
            rows = np.union1d(self._returned, rows)
        self._returned, self._hold = rows, hold

    @property
    def unconfirmed(self) -> bool:
        """Whether IMUs came back from a silence and their readings have not yet agreed
        with the estimate for long enough (its status must not be ``ok``)."""
        return self._returned is not None

    def watching(self, t: float, window: float | None) -> bool:
        """True before the first estimate after a (re)start and for ``window`` s after
        it (None: never), and while :attr:`unconfirmed`; outside, the check costs
        nothing per sample."""
        if self._returned is not None:
            return True
        return window is not None and (math.isnan(self._since) or t - self._since <= window)

    def nis(self, t: float, z: FloatArray, mask: FloatArray) -> tuple[float, int] | None:
        """``(NIS, dof)`` of reading ``z`` at ``t`` s against the previous estimate
        predicted to ``t``; None without a previous estimate with a covariance."""
        if self._prev is None or not mask.any():
            return None
        t0, x, P, z0 = self._prev
        f = self.formulation
        dt = t - t0
        u = f.inputs(z0, z, dt) if f.nu else np.zeros(0)
        xn, F, Q = (np.asarray(v, dtype=float) for v in f.functions.predict(x, u, dt))
        nx = len(x)
        xn = xn.ravel()
        Pn = F.reshape(nx, nx) @ P @ F.reshape(nx, nx).T + Q.reshape(nx, nx)
        rows = np.flatnonzero(mask)
        r, Jr = (
            np.asarray(v, dtype=float) for v in f.functions.innovate(np.where(mask > 0, z, 0.0), xn)
        )
        H = Jr.reshape(len(z), nx)[rows]
        r = r.ravel()[rows]
        S = H @ Pn @ H.T + self._R[np.ix_(rows, rows)]
        return float(r @ np.linalg.solve(S, r)), len(rows)

    def inconsistent(self, t: float, z: FloatArray, mask: FloatArray, window: float | None) -> bool:
        """True when this reading is the ``SAMPLES``-th inconsistent one in a row
        within ``window`` s (None: never) of the (re)start (then the caller restarts).
        Readings of every returned IMU consistent for the hold time confirm the
        estimate."""
        in_window = window is not None and t - self._since <= window
        if self._prev is None or not (in_window or self._returned is not None):
            return False
        got = self.nis(t, z, mask)
        if got is None:
            return False
        value, dof = got
        consistent = value <= self._limit[dof]
        self._run = 0 if consistent else self._run + 1
        if self._returned is not None and (mask[self._returned] > 0).all():
            if not consistent:
                self._agreed_since = math.nan
            elif math.isnan(self._agreed_since):
                self._agreed_since = self._prev[0]  # the estimate this reading agrees with
            if t - self._agreed_since >= self._hold:  # NaN compares False
                self._returned = None
        return in_window and self._run >= SAMPLES

    def remember(
        self, t: float, z: FloatArray, state: FloatArray | None, cov: FloatArray | None
    ) -> None:
        """Keep this sample's estimate for the next reading's check."""
        if state is None:
            return
        if math.isnan(self._since):
            self._since = t
        if cov is None:
            self._prev = None
            return
        self._prev = (
            t,
            np.array(state, dtype=float),
            np.array(cov, dtype=float),
            np.array(z, dtype=float),
        )
