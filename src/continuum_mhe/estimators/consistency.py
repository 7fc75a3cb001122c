"""Whether the readings agree with the estimates, every sample, in every estimator
(status ``inconsistent``), and the model error they show (the ``noise_scale`` that
widens the standard deviations).

An estimate is only worth ``ok`` when the readings around it agree with its model and
noise. Two tests, on the formulation's own residual ``r(z, x)`` (the one every
estimator weights with ``R^-1``), valid components only:

* **this reading against the previous estimate** (innovation): the previous
  ``(x, P)`` predicted to this sample (``x+ = f(x, u, dt)``, ``P+ = F P F^T + Q``),
  ``NIS = r^T (H P+ H^T + R)^-1 r`` with ``r = r(z, x+)``; a covariance collapsed on a
  wrong shape gives a huge NIS at the next reading;
* **this reading against this estimate** (fit): ``r(z, x)^T R^-1 r(z, x)``, never
  larger than the NIS for a consistent estimator (the update only shrinks the
  residual); a window dragged by a wrong reading, or a shape the model cannot reach,
  leaves it large.

Either beyond the ``SAMPLE_QUANTILE`` (99 %) chi-square quantile marks this sample
``inconsistent``. Model error that no single reading shows is caught by the average:
an exponentially weighted mean of ``NIS / dof`` over about ``MEMORY`` samples
(covariance matching: the factor by which the innovations exceed what ``R`` and ``P``
predict) is :attr:`ConsistencyCheck.noise_scale`; beyond the ``QUANTILE`` (99.9 %)
quantile of its own distribution (a chi-square of ``dof * (2 MEMORY - 1)`` degrees of
freedom, scaled) the sample is ``inconsistent`` too, and every output standard
deviation is widened by ``sqrt(noise_scale)`` where it exceeds 1 (the covariances are
scaled as the noise is).

A formulation whose covariance is not one (``Formulation.calibrated_covariance``
False: the paper formulation's weight ``W``) is not checked, nor an estimate without a
covariance.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from continuum_mhe.model.formulations import Formulation

FloatArray = NDArray[np.float64]

#: Chi-square quantile beyond which the average of NIS / dof is inconsistent.
QUANTILE = 0.999
#: Chi-square quantile beyond which one reading is inconsistent with the estimate.
SAMPLE_QUANTILE = 0.99
#: Samples the average of ``NIS / dof`` remembers (its exponential weight is 1/MEMORY).
MEMORY = 20


def predicted_nis(
    formulation: Formulation,
    R: FloatArray,
    prev: tuple[float, FloatArray, FloatArray, FloatArray],
    t: float,
    z: FloatArray,
    mask: FloatArray,
) -> tuple[float, int]:
    """``(NIS, dof)`` of reading ``z`` at ``t`` s against the estimate
    ``prev = (t0, x, P, z0)`` predicted to ``t`` (valid components of ``mask`` only;
    ``mask`` must have one)."""
    t0, x, P, z0 = prev
    f = formulation
    dt = t - t0
    u = f.inputs(z0, z, dt) if f.nu else np.zeros(0)
    xn, F, Q = (np.asarray(v, dtype=float) for v in f.functions.predict(x, u, dt))
    nx = len(x)
    F = F.reshape(nx, nx)
    Pn = F @ P @ F.T + Q.reshape(nx, nx)
    rows = np.flatnonzero(mask)
    r, Jr = (
        np.asarray(v, dtype=float)
        for v in f.functions.innovate(np.where(mask > 0, z, 0.0), xn.ravel())
    )
    H = Jr.reshape(len(z), nx)[rows]
    r = r.ravel()[rows]
    S = H @ Pn @ H.T + R[np.ix_(rows, rows)]
    return float(r @ np.linalg.solve(S, r)), len(rows)


class ConsistencyCheck:
    """The consistency of one estimator's estimates with its readings (module doc)."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        self._R = formulation.meas_cov()
        self._r_inv = 1.0 / np.diag(self._R)
        nz = formulation.nz
        self._limit = [math.inf] + [float(chi2.ppf(SAMPLE_QUANTILE, k)) for k in range(1, nz + 1)]
        n_avg = 2 * MEMORY - 1  # the effective samples of the exponential average
        self._avg_limit = [math.inf] + [
            float(chi2.ppf(QUANTILE, k * n_avg)) / (k * n_avg) for k in range(1, nz + 1)
        ]
        self.reset()

    def reset(self) -> None:
        """Forget the previous estimate and the average (a (re)start)."""
        self._prev: tuple[float, FloatArray, FloatArray, FloatArray] | None = None
        #: exponentially weighted mean of NIS / dof (1 where nothing was seen yet)
        self.noise_scale = 1.0
        self._dof = 0

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
        prev, fit_bad, nis_bad = self._prev, False, False
        valid = bool(mask.any())
        if state is None or cov is None:
            self._prev = None
            return False
        f = self.formulation
        if valid:
            rows = np.flatnonzero(mask)
            r = np.asarray(f.functions.innovate(np.where(mask > 0, z, 0.0), state)[0])
            r = r.ravel()[rows]
            dof = len(rows)
            fit_bad = float(np.sum(r * r * self._r_inv[rows])) > self._limit[dof]
            if prev is not None:
                nis, dof = predicted_nis(f, self._R, prev, t, z, mask)
                nis_bad = nis > self._limit[dof]
                # covariance matching: the average factor of the innovations over their
                # predicted size (a wrong reading counts at most the limit)
                value = min(nis, self._limit[dof]) / dof
                self.noise_scale += (value - self.noise_scale) / MEMORY
                self._dof = dof
        self._prev = (t, np.array(state, dtype=float), np.array(cov, dtype=float), z.copy())
        avg_bad = self._dof > 0 and self.noise_scale > self._avg_limit[self._dof]
        return valid and (fit_bad or nis_bad or avg_bad)

    @property
    def std_factor(self) -> float:
        """The factor (>= 1) the output standard deviations are widened by:
        ``sqrt(noise_scale)`` where the readings scatter more than predicted."""
        return math.sqrt(self.noise_scale) if self.noise_scale > 1.0 else 1.0
