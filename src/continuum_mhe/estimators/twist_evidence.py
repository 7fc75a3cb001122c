"""Whether a recording's raw readings show IMUs that twist about the backbone.

A backbone that twists (a rod under couples, a tendon robot under a tip load) turns
each IMU about its tangent, which the constant-curvature frames cannot follow; the
``direct`` model's ``imu_twist`` states follow it, but cost accuracy where the backbone
does not twist (docs/model.md, "The IMUs' twist"). The readings say which: each model's
compiled EKF predicts every reading, and the twist model's wider predictions make its
log-density of a reading lower where the frames follow the robot, higher where they
cannot. :func:`twist_evidence` runs both filters over a recording and compares the
log-densities sample by sample (the prediction-error decomposition of each model's
likelihood); :attr:`TwistEvidence.twists` is true where the twist model predicted the
median sample better (docs/model-studies.md, "The IMUs' twist, measured").
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

import continuum_mhe._core as _core
from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.model.direct import DirectFormulation, gyro_biases_calibrated

#: The fewest samples whose readings both filters predicted (a log-density each) for a
#: choice: 2 s at 50 Hz.
MIN_SAMPLES = 100


@dataclass(frozen=True)
class TwistEvidence:
    """What the readings say of the IMUs' twist.

    Attributes:
        median: the median over the samples of the twist model's log-density of the
            reading less the constant-curvature frames' (nats per sample; positive:
            the twist model predicted the reading better).
        share: the share of those samples on which the twist model predicted better.
        samples: the samples compared (those with a log-density in both filters).
    """

    median: float
    share: float
    samples: int

    @property
    def twists(self) -> bool:
        """Whether the twist model is the better description: at least
        :data:`MIN_SAMPLES` samples, and its log-density higher on the median one."""
        return self.samples >= MIN_SAMPLES and self.median > 0.0


def twisted_formulation(frames: DirectFormulation) -> DirectFormulation:
    """``frames`` with each IMU's twist as states (``imu_twist``), as ``--imu-twist`` makes
    it (:func:`~continuum_mhe.model.registry.make_formulation`): its gyro biases held at
    the robot file's calibration where every IMU has one, else estimated as the frames'
    are (a bias about an IMU's z axis then reads as a twist)."""
    return replace(
        frames, imu_twist=True, estimate_gyro_bias=not gyro_biases_calibrated(frames.robot)
    )


def twist_evidence(frames: DirectFormulation, t: ArrayLike, z: ArrayLike) -> TwistEvidence:
    """Run the compiled EKF of ``frames`` (the constant-curvature frames, raw IMUs with
    their gyro biases estimated) and of its twisted formulation
    (:func:`twisted_formulation`) over the readings ``z`` (n, nz) at ``t`` (n,) s, as an
    estimator's ``run`` takes them, each in one compiled call (the two side by side, the
    twist model's on a second thread), and compare their
    innovation log-densities sample by sample (no restart but after a failed step: a
    filter that loses the readings keeps predicting them badly, which is the
    evidence). With every IMU's ``gyro_bias`` calibrated the twist model holds the
    biases, which is what ``estimate`` chooses on; without, it estimates them too, which
    tells a twisting robot from one that does not as well but estimates it worse
    (docs/model-studies.md, "The IMUs' twist, measured")."""
    if not isinstance(frames, DirectFormulation) or frames.imu_twist:
        raise UserError("twist_evidence takes the direct formulation without imu_twist")
    if not frames.estimate_gyro_bias:
        raise UserError("twist_evidence needs the gyro biases estimated")
    t_arr = np.ascontiguousarray(t, dtype=float)
    z_arr = np.ascontiguousarray(z, dtype=float)
    runs = []  # each model's compiled steps, built here (CasADi builds on one thread)
    for formulation in (frames, twisted_formulation(frames)):
        stepped = CompiledExtendedKalmanInference(formulation).policy_inference()
        if stepped is None:  # pragma: no cover - the compiled EKF's own infer has them
            raise TypeError("the compiled EKF has no compiled steps")
        masks = np.ascontiguousarray(formulation.measurement_masks(z_arr))
        runs.append((stepped, masks, np.full(len(t_arr), math.nan)))

    def step(run: tuple[_core.KalmanInference, FloatArray, FloatArray]) -> FloatArray:
        stepped, masks, ll = run
        stepped.log_likelihoods(t_arr, z_arr, masks, ll)  # without the GIL
        return ll

    # the two filters side by side: the twist model's on a worker, the frames' on this
    # thread, where a signal's handler (Ctrl-C) can end it
    with ThreadPoolExecutor(1, thread_name_prefix="twist-evidence") as pool:
        twisted = pool.submit(step, runs[1])
        densities = [step(runs[0]), twisted.result()]
    diff = densities[1] - densities[0]
    diff = diff[np.isfinite(diff)]
    if not len(diff):
        return TwistEvidence(math.nan, math.nan, 0)
    return TwistEvidence(float(np.median(diff)), float(np.mean(diff > 0.0)), len(diff))
