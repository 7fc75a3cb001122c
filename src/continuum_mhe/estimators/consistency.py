"""Whether the readings agree with the estimates, every sample, in every estimator
(status ``inconsistent``), and the model error they show (the ``noise_scale`` that
widens the standard deviations).

An estimate is only worth ``ok`` when the readings around it agree with its model and
noise. Two tests, on the formulation's own residual ``r(z, x)`` (the one every
estimator weights with ``R^-1``), valid components only, and readings only: a model's
pseudo-measurement (a tendon robot's tip condition, block kind ``"equilibrium"``) is
met by an EKF step only to the step's linearisation, many of its tiny standard
deviations off, and says nothing about the readings:

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
``inconsistent`` (on data that agree with the model about 2 rows in 10,000). Model
error that no single reading shows is caught by the average (of the readings not
flagged on their own):
an exponentially weighted mean of ``NIS / dof`` over about ``MEMORY`` samples
(covariance matching: the factor by which the innovations exceed what ``R`` and ``P``
predict) is :attr:`ConsistencyCheck.noise_scale`; beyond the ``QUANTILE`` (99.9 %)
quantile of its own distribution (a chi-square of ``dof * (2 MEMORY - 1)`` degrees of
freedom, scaled) the sample is ``inconsistent`` too, and every output standard
deviation is widened by ``sqrt(noise_scale)`` where it exceeds 1 (the covariances are
scaled as the noise is). Once beyond that quantile, the samples stay ``inconsistent``
until the average is back at 1, what the noise model predicts (a model error does not
end when the average merely drops below the quantile).

A model error the readings showed does not go away when their residuals quieten: with
one IMU per section the gravity directions determine the shape exactly, so a shape the
model gets wrong (a curvature that is not constant, a twist) leaves no residual at all
most of the time, and shows only while the robot moves in a way the model cannot
follow. The excess the average showed at such a detection, ``noise_scale - 1`` in
units of ``R``, is :attr:`ConsistencyCheck.model_error`: the largest since the
(re)start, carried as a constant error of the gravity-direction readings (below), not
as white noise (a slowly varying model error is not averaged away by the filter or the
window).

Some error no residual shows: a constant error in every reading of an IMU (its
mounting misalignment, its accelerometer's bias) looks like a different shape.
:meth:`ConsistencyCheck.constant_error_cov` is the estimate's covariance from it, the
readings' constant-error covariance ``B`` (``Formulation.reading_bias_cov``,
``NoiseSettings.reading_bias_std``, plus ``model_error`` times ``R`` on the
gravity-direction readings) carried through the estimate's weighted
least-squares sensitivity to the readings that carry such an error (the gravity
directions; the states they depend on: the bends), ``A = (H^T R^-1 H)^+ H^T R^-1``
at the estimate: ``A B A^T``. Its output standard deviations are added in quadrature
to the estimator's (a constant reading error shifts an estimate by ``A`` times it, as
long as the window or the filter's memory is shorter than the motion); the status
does not depend on it.

A formulation whose covariance is not one (``Formulation.calibrated_covariance``
False: the paper formulation's weight ``W``) is not checked, nor an estimate without a
covariance.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.estimators.chi2 import chi2_quantile
from continuum_mhe.estimators.fast.codegen import node_tape
from continuum_mhe.estimators.process_noise import ProcessNoiseCache
from continuum_mhe.model.formulations import Formulation

FloatArray = NDArray[np.float64]

#: Chi-square quantile beyond which the average of NIS / dof is inconsistent.
QUANTILE = 0.999
#: Chi-square quantile beyond which one reading is inconsistent with the estimate.
SAMPLE_QUANTILE = 0.9999
#: Chi-square quantile beyond which two readings in a row are inconsistent.
RUN_QUANTILE = 0.99
#: Samples the average of ``NIS / dof`` remembers (its exponential weight is 1/MEMORY).
MEMORY = 20


class ConsistencyCheck:
    """The consistency of one estimator's estimates with its readings (module doc)."""

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        self._R = formulation.meas_cov()
        self._r_inv = 1.0 / np.diag(self._R)
        nz = formulation.nz
        self._limit = [math.inf] + [chi2_quantile(SAMPLE_QUANTILE, k) for k in range(1, nz + 1)]
        self._run_limit = [math.inf] + [chi2_quantile(RUN_QUANTILE, k) for k in range(1, nz + 1)]
        n_avg = 2 * MEMORY - 1  # the effective samples of the exponential average
        self._avg_limit = [math.inf] + [
            chi2_quantile(QUANTILE, k * n_avg) / (k * n_avg) for k in range(1, nz + 1)
        ]
        self._q = ProcessNoiseCache(formulation)
        #: the rows (nz,) judged: the readings, not a model's pseudo-measurements (a
        #: tendon robot's tip condition, met only to the linearisation of a step)
        self._judged_rows = np.concatenate(
            [np.full(b.size, b.kind != "equilibrium") for b in formulation.measurement_blocks]
        )
        self.reset()

    def reset(self) -> None:
        """Forget the previous estimate and the average (a (re)start)."""
        self._prev: tuple[float, FloatArray, FloatArray, FloatArray] | None = None
        #: exponentially weighted mean of NIS / dof (1 where nothing was seen yet)
        self.noise_scale = 1.0
        #: the model error the average showed (module doc): the largest
        #: ``noise_scale - 1`` beyond its quantile since the (re)start, in units of ``R``
        self.model_error = 0.0
        self._dof = 0
        self._high = False  # the previous reading was beyond RUN_QUANTILE
        self._persists = False  # the average went beyond its quantile, and is not back at 1

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
        prev, fit, nis = self._prev, 0.0, 0.0
        judged = np.where(self._judged_rows, mask, 0.0)
        valid = bool(judged.any())
        if state is None or cov is None:
            self._prev = None
            return False
        if valid:
            rows = np.flatnonzero(judged)
            dof = len(rows)
            zv = np.where(mask > 0, z, 0.0)
            if prev is None:
                r = np.asarray(self.formulation.functions.innovate(zv, state)[0]).ravel()
            else:
                t0, x0, P0, z0 = prev
                dt = t - t0
                f = self.formulation
                u = f.inputs(z0, z, dt) if f.nu else np.zeros(0)
                r, r_pred, H, Pn = self._judged(x0, P0, u, dt, zv, state)
                H = H[rows]
                rp = r_pred[rows]
                S = H @ Pn @ H.T + self._R[np.ix_(rows, rows)]
                nis = float(rp @ np.linalg.solve(S, rp))
                # covariance matching: the average factor of the innovations over their
                # predicted size; a reading flagged on its own (an outlier) stays out of it
                if nis <= self._limit[dof]:
                    self.noise_scale += (nis / dof - self.noise_scale) / MEMORY
                    self._dof = dof
            r = r[rows]
            fit = float(np.sum(r * r * self._r_inv[rows]))
        self._prev = (t, np.array(state, dtype=float), np.array(cov, dtype=float), z.copy())
        if not valid:
            return False
        worst = max(fit, nis)
        high, self._high = self._high, worst > self._run_limit[dof]
        if self._dof > 0 and self.noise_scale > self._avg_limit[self._dof]:
            self._persists = True
            self.model_error = max(self.model_error, self.noise_scale - 1.0)
        elif self.noise_scale <= 1.0:
            self._persists = False
        return worst > self._limit[dof] or (high and self._high) or self._persists

    def _node(
        self, x: FloatArray, u: FloatArray, dt: float, z: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """The model at one node, from the tape the EKF shares
        (:func:`~continuum_mhe.estimators.fast.codegen.node_tape`): ``(f(x, u, dt) (nx,),
        F = df/dx (nx, nx), H = -dr/dx (nz, nx), r(z, x) (nz,))``, no reading masked."""
        f, core = self.formulation, node_tape(self.formulation)
        nx, nz = f.nx, f.nz
        out = np.empty(core.output_size)
        flat = [x, u, np.array([dt]), z, np.ones(nz)]
        core.evaluate([np.ascontiguousarray(v, dtype=float).ravel() for v in flat], out)
        F = out[nx : nx + nx * nx].reshape(nx, nx)
        H = out[nx + nx * nx : nx + nx * nx + nz * nx].reshape(nz, nx)
        return out[:nx], F, H, out[nx + nx * nx + nz * nx :]

    def _judged(
        self, x0: FloatArray, P0: FloatArray, u: FloatArray, dt: float, z: FloatArray,
        x: FloatArray,
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:  # fmt: skip
        """This estimate's residual and the previous estimate's prediction to this
        sample: ``(r(z, x) (nz,), r(z, x+) (nz,), H (nz, nx), P+ (nx, nx))`` with
        ``x+ = f(x0, u, dt)``, ``P+ = F P0 F^T + Q``, ``H = -dr/dx`` at ``x+``."""
        xn, F, _, _ = self._node(x0, u, dt, z)
        _, _, H, r_pred = self._node(xn, u, dt, z)
        r = self._node(x, u, dt, z)[3]
        Pn = F @ np.asarray(P0, dtype=float) @ F.T + self._q(dt)[0]
        return r, r_pred, H, Pn

    @cached_property
    def _bias(self) -> FloatArray:
        """``B``'s diagonal (nz,): the readings' constant-error variances (``B`` is
        diagonal: each reading's constant error is its own)."""
        return np.diag(np.asarray(self.formulation.reading_bias_cov(), dtype=float)).copy()

    @cached_property
    def _gravity_r(self) -> FloatArray:
        """``R``'s diagonal (nz,) on the gravity-direction readings, 0 elsewhere: the
        constant-error variance per unit of :attr:`model_error`."""
        return np.where(self.formulation.gravity_direction_rows(), np.diag(self._R), 0.0)

    def constant_error_cov(self, z: FloatArray, mask: FloatArray, state: FloatArray) -> FloatArray:
        """The state covariance (nx, nx) from the readings' constant errors and the
        model error learned so far (module doc): ``A B A^T`` with ``B`` the readings'
        constant-error covariance plus :attr:`model_error` times ``R`` on the
        gravity-direction readings and ``A = (H^T R^-1 H)^+ H^T R^-1`` over the valid
        readings that carry a constant error (``B > 0``: the gravity directions) and the
        states they depend on (the bends: the readings that set the shape) at
        ``state``; zero where ``B`` is."""
        nx = self.formulation.nx
        bias = self._bias + self.model_error * self._gravity_r if self.model_error else self._bias
        rows = np.flatnonzero((mask > 0) & (bias > 0))
        out_cov = np.zeros((nx, nx))
        if len(rows) == 0:
            return out_cov
        zv = np.where(mask > 0, z, 0.0)
        f = self.formulation
        H = self._node(state, np.zeros(f.nu), 0.0, zv)[2][rows]
        cols = np.flatnonzero(H.any(axis=0))
        H = H[:, cols]
        wh = H * self._r_inv[rows, None]  # R^-1 H
        A = _pinv_symmetric(H.T @ wh, 1e-9) @ wh.T
        out_cov[np.ix_(cols, cols)] = (A * bias[rows]) @ A.T
        return out_cov

    @property
    def std_factor(self) -> float:
        """The factor (>= 1) the output standard deviations are widened by:
        ``sqrt(noise_scale)`` where the readings scatter more than predicted."""
        return math.sqrt(self.noise_scale) if self.noise_scale > 1.0 else 1.0


def _pinv_symmetric(a: FloatArray, rcond: float) -> FloatArray:
    """The pseudo-inverse of the symmetric matrix ``a`` from its eigendecomposition,
    eigenvalues at most ``rcond`` times the largest in magnitude taken as zero (what
    ``numpy.linalg.pinv(a, rcond, hermitian=True)`` computes, without its per-call
    overhead, which dominates for the few-by-few matrices of a sample)."""
    s, u = np.linalg.eigh(a)
    big = np.abs(s) > rcond * np.max(np.abs(s), initial=0.0)
    inv_s = np.divide(1.0, s, out=np.zeros_like(s), where=big)
    return (u * inv_s) @ u.T
