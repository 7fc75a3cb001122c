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
import threading
from array import array
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from queue import Empty, SimpleQueue

import numpy as np
from numpy.typing import ArrayLike

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import UserError
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.model.direct import DirectFormulation, gyro_biases_calibrated
from continuum_mhe.model.formulations import Formulation

#: The fewest samples whose readings both filters predicted (a log-density each) for a
#: choice: 2 s at 50 Hz.
MIN_SAMPLES = 100
#: The samples of a stream stepped together (:class:`StreamedTwistEvidence`): about a
#: second at 50 Hz, so that the filters' steps cost one call a block.
STREAM_BLOCK = 64
#: A stream's worker ends after this many seconds without a block (s).
STREAM_IDLE_S = 5.0
#: The blocks a stream's worker may have waiting: where its filters fall further behind
#: (about half a minute of a 500 Hz stream), the evidence ends (:meth:`evidence` None).
STREAM_BACKLOG = 256


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
    def said(self) -> str:
        """The evidence in the summaries' words: ``96 % of 600 readings better, median
        log-density gain +947 nats per reading``."""
        return (
            f"{100 * self.share:.0f} % of {self.samples} readings better, median "
            f"log-density gain {self.median:+.3g} nats per reading"
        )

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
    pair = _FilterPair(frames)
    return _evidence(pair.differences(t_arr, z_arr))


def weighs_the_twist(formulation: Formulation) -> bool:
    """Whether :func:`twist_evidence` weighs ``formulation``'s readings: raw IMUs read by
    the direct model of a robot without a mechanics model, its gyro biases estimated,
    without the IMUs' twist or their own acceleration (as ``estimate`` weighs them)."""
    return (
        isinstance(formulation, DirectFormulation)
        and formulation.estimate_gyro_bias
        and not formulation.imu_twist
        and not formulation.own_acceleration
        and not formulation.robot.has_mechanics
    )


class _FilterPair:
    """The compiled EKFs of ``frames`` and of its twisted formulation
    (:func:`twisted_formulation`), stepped side by side over the same readings."""

    def __init__(self, frames: DirectFormulation) -> None:
        self.formulations = (frames, twisted_formulation(frames))
        self.stepped = []  # each model's compiled steps, built here (CasADi builds on one thread)
        for formulation in self.formulations:
            stepped = CompiledExtendedKalmanInference(formulation).policy_inference()
            if stepped is None:  # pragma: no cover - the compiled EKF's own infer has them
                raise TypeError("the compiled EKF has no compiled steps")
            self.stepped.append(stepped)

    def differences(self, t: FloatArray, z: FloatArray, side_by_side: bool = True) -> FloatArray:
        """Each sample's innovation log-density under the twist model less the frames'
        (NaN where either has none), both filters stepped on from where the last call
        left them over the readings ``z`` (n, nz) at ``t`` (n,) s (C-contiguous);
        ``side_by_side``: the twist model's on a second thread."""

        # the twist adds states, not readings: one mask for both models
        masks = np.ascontiguousarray(self.formulations[0].measurement_masks(z))

        def step(k: int) -> FloatArray:
            ll = np.full(len(t), math.nan)
            self.stepped[k].log_likelihoods(t, z, masks, ll)  # without the GIL
            return ll

        if not side_by_side:
            return step(1) - step(0)
        # the frames' on this thread, where a signal's handler (Ctrl-C) can end it
        with ThreadPoolExecutor(1, thread_name_prefix="twist-evidence") as pool:
            twisted = pool.submit(step, 1)
            frames = step(0)
            return twisted.result() - frames


def _evidence(diff: FloatArray) -> TwistEvidence:
    """The evidence of the per-sample log-density differences ``diff`` (NaN: none)."""
    diff = diff[np.isfinite(diff)]
    if not len(diff):
        return TwistEvidence(math.nan, math.nan, 0)
    return TwistEvidence(float(np.median(diff)), float(np.mean(diff > 0.0)), len(diff))


class StreamedTwistEvidence:
    """:func:`twist_evidence` of a stream of readings, sample by sample (:meth:`add`),
    for ``live``, which estimates with the constant-curvature frames: the same filters
    over the same readings give the evidence that ``estimate`` of the session's recording
    weighs. The readings are passed in blocks of :data:`STREAM_BLOCK` samples to a thread
    of their own that steps the two filters (their compiled steps without the GIL), so
    that the stream's estimates do not wait for them; :meth:`evidence` passes what is
    left and waits for the thread. Active where :func:`weighs_the_twist`; the two filters
    are built here, before the stream starts; not where ``weigh`` is False. An exception
    of the filters, or filters :data:`STREAM_BACKLOG` blocks behind the stream, end it:
    :meth:`evidence` is None from then on."""

    def __init__(self, formulation: Formulation, weigh: bool = True) -> None:
        self.active = weigh and weighs_the_twist(formulation)
        self._pair = (
            _FilterPair(formulation)
            if self.active and isinstance(formulation, DirectFormulation)
            else None
        )
        self._t: list[float] = []
        self._z: list[FloatArray] = []
        self._blocks: SimpleQueue[tuple[FloatArray, FloatArray] | None] = SimpleQueue()
        self._worker: threading.Thread | None = None
        self._lock = threading.Lock()
        self._diff = array("d")  # each stepped sample's difference (NaN: none)

    def add(self, t: float, z: ArrayLike) -> None:
        """The reading ``z`` (nz,) at ``t`` s, in the order of the stream."""
        if not self.active:
            return
        self._t.append(float(t))
        self._z.append(np.asarray(z, dtype=float))
        if len(self._t) >= STREAM_BLOCK:
            self._pass_block()

    def _pass_block(self) -> None:
        """The readings added since the last block, to the worker (started where none
        runs)."""
        if not self._t:
            return
        block = (np.ascontiguousarray(self._t), np.ascontiguousarray(np.vstack(self._z)))
        self._t.clear()
        self._z.clear()
        if self._blocks.qsize() >= STREAM_BACKLOG:  # the filters cannot keep up: a hint,
            self.active, self._pair = False, None  # it ends rather than hold the stream
            return
        with self._lock:  # a worker ends only with the queue empty, under this lock
            self._blocks.put(block)
            if self._worker is None:
                self._worker = threading.Thread(
                    target=self._step_blocks, name="twist-evidence", daemon=True
                )
                self._worker.start()

    def _step_blocks(self) -> None:
        """The worker: each block's differences, until the end (None), or until no block
        has come for :data:`STREAM_IDLE_S` (a stream that stopped without asking for
        the evidence; the next block starts another worker)."""
        while True:
            try:
                block = self._blocks.get(timeout=STREAM_IDLE_S)
            except Empty:
                with self._lock:
                    if self._blocks.empty():
                        self._worker = None
                        return
                continue
            if block is None:
                return
            self._step(block)

    def _step(self, block: tuple[FloatArray, FloatArray]) -> None:
        """One block's differences, in order after the blocks before it."""
        if self._pair is None:
            return
        try:
            diff = self._pair.differences(*block, side_by_side=False)
        except Exception:  # a hint: its filters failing end it, not the stream
            self.active, self._pair = False, None
            return
        self._diff.extend(diff.tolist())

    def evidence(self) -> TwistEvidence | None:
        """The evidence of every reading added so far (once the worker has stepped them);
        None where not active."""
        if self.active:
            self._pass_block()
        with self._lock:
            worker = self._worker
            if worker is not None:
                self._blocks.put(None)
        if worker is not None:
            worker.join()
            with self._lock:
                self._worker = None
        if not self.active:
            return None
        return _evidence(np.frombuffer(self._diff, dtype=float))
