"""One interface for every estimator: ``step(measurement) -> Estimate`` and ``run``.

Results are data: :class:`Estimate` for one sample, :class:`EstimateSeries` for a
recording. Plots, metrics and the CLI read these and never touch an estimator.
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.formulations import Formulation

FloatArray = NDArray[np.float64]

Status = Literal[
    "ok",  # converged (or a filter update)
    "dropout",  # no valid measurement at this sample: prediction only
    "not-converged",  # solver stopped early; its last feasible iterate is used
    "solver-failed",  # solver error; projected prediction is used
    "no-estimate",  # --paper-start: fewer than N samples so far
    "fallback-ipopt",  # fast backend could not certify convergence; IPOPT answered
]


@dataclass(frozen=True)
class Measurement:
    """One sample: time ``t`` in seconds and the measurement vector ``z``.

    For tilt input ``z = [roll, pitch]`` in radians. NaN entries mark a dropout.
    """

    t: float
    z: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "z", np.asarray(self.z, dtype=float))

    @property
    def valid(self) -> bool:
        return bool(np.all(np.isfinite(self.z)))


@dataclass(frozen=True)
class Estimate:
    """The estimate at one sample.

    Attributes:
        t: sample time, s.
        state: the formulation's state vector, or None for ``no-estimate``.
        output: ``[x, y, z, theta, phi]`` (m, rad), or None for ``no-estimate``.
        covariance: state covariance where the method has one, else None.
        status: see :data:`Status`.
        solve_ms: wall time spent on this sample, ms.
    """

    t: float
    state: FloatArray | None
    output: FloatArray | None
    covariance: FloatArray | None
    status: Status
    solve_ms: float


@dataclass(frozen=True)
class EstimateSeries:
    """Estimates over a recording. Rows without an estimate hold NaN in ``output``.

    Attributes:
        method: estimator name (``mhe``, ``ekf``, ``ukf``...).
        t: (n,) s.
        output: (n, 5) ``[x, y, z, theta, phi]`` (m, rad).
        status: (n,) status strings.
        solve_ms: (n,) ms.
    """

    method: str
    t: FloatArray
    output: FloatArray
    status: NDArray[np.str_]
    solve_ms: FloatArray

    @property
    def has_estimate(self) -> NDArray[np.bool_]:
        return self.status != "no-estimate"

    @classmethod
    def from_estimates(cls, method: str, estimates: Iterable[Estimate]) -> EstimateSeries:
        est = list(estimates)
        out = np.full((len(est), 5), np.nan)
        for i, e in enumerate(est):
            if e.output is not None:
                out[i] = e.output
        return cls(
            method=method,
            t=np.array([e.t for e in est], dtype=float),
            output=out,
            status=np.array([e.status for e in est], dtype=str),
            solve_ms=np.array([e.solve_ms for e in est], dtype=float),
        )


class Estimator(ABC):
    """Base class of every estimator. Subclasses implement ``reset`` and ``_step``."""

    name: str = "estimator"

    def __init__(self, formulation: Formulation) -> None:
        self.formulation = formulation
        self._last_t = -math.inf

    def reset(self) -> None:
        """Forget all samples; the next ``step`` starts a new recording."""
        self._last_t = -math.inf
        self._reset()

    @abstractmethod
    def _reset(self) -> None:
        """Clear the estimator's own state (called by :meth:`reset`)."""

    @abstractmethod
    def _step(
        self, measurement: Measurement
    ) -> tuple[FloatArray | None, FloatArray | None, Status]:
        """Return ``(state, covariance, status)`` for this sample."""

    def _output(self, state: FloatArray) -> FloatArray:
        """``[x, y, z, theta, phi]`` of a state (a backend may use a compiled copy)."""
        return self.formulation.output(state)

    def step(self, measurement: Measurement) -> Estimate:
        """Process one sample and return its estimate. Never raises on solver failure.

        Raises:
            ValueError: if ``measurement.z`` does not have the formulation's size, or
                ``measurement.t`` is not finite or not later than the previous
                sample's (time must strictly increase).
        """
        t = measurement.t
        nz = self.formulation.nz
        if np.shape(measurement.z) != (nz,):
            raise ValueError(
                f"measurement z must have shape ({nz},) for the {self.formulation.name} "
                f"formulation, got {np.shape(measurement.z)}"
            )
        if not (math.isfinite(t) and t > self._last_t):
            raise ValueError(
                f"sample time t={t!r} s must be finite and later than the previous "
                f"sample's t={self._last_t!r} s"
            )
        self._last_t = t
        start = time.perf_counter()
        state, cov, status = self._step(measurement)
        ms = (time.perf_counter() - start) * 1e3
        output = None if state is None else self._output(state)
        return Estimate(measurement.t, state, output, cov, status, ms)

    def run(
        self,
        t: FloatArray,
        z: FloatArray,
        progress: Callable[[Iterable[int]], Iterator[int]] | None = None,
    ) -> EstimateSeries:
        """Estimate over a whole recording (``t`` (n,) s, ``z`` (n, m)), from a reset."""
        if len(t) != len(z):
            raise ValueError(f"t has {len(t)} samples but z has {len(z)}")
        self.reset()
        idx: Iterable[int] = range(len(t))
        if progress is not None:
            idx = progress(idx)
        return EstimateSeries.from_estimates(
            self.name, [self.step(Measurement(float(t[i]), np.asarray(z[i], float))) for i in idx]
        )
