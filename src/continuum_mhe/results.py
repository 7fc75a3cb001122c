"""Result types shared by estimators, io, metrics and plots (a neutral layer).

:class:`Measurement` is one sample in; :class:`Estimate` one sample out;
:class:`EstimateSeries` a recording's estimates, with a description of its columns.
Plots, metrics, writers and the CLI read these and never touch an estimator.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.descriptions import OutputSpec, pcc_outputs

FloatArray = NDArray[np.float64]

Status = Literal[
    "ok",  # converged (or a filter update)
    "dropout",  # no valid measurement at this sample: prediction only
    "not-converged",  # solver stopped early; its last feasible iterate is used
    "solver-failed",  # solver error; projected prediction is used
    "no-estimate",  # --paper-start: fewer than N samples so far
    "fallback-ipopt",  # fast backend could not certify convergence; IPOPT answered
    "reset",  # diverged, failed numerically or lost all certainty: restarted from this sample
    "drifted",  # position state inconsistent with its own angles (paper formulation)
]

#: Every status, with its meaning (the one vocabulary of every estimator and output).
STATUS_MEANINGS: dict[str, str] = {
    "ok": "converged (MHE) or updated with a measurement (filters)",
    "dropout": "no valid measurement at this sample: prediction only",
    "not-converged": "solver stopped early; its last feasible iterate is used",
    "solver-failed": "solver error; the projected prediction is used",
    "no-estimate": "no estimate yet (before the first valid reading, or --paper-start)",
    "fallback-ipopt": "the fast MHE backend did not answer; IPOPT solved this window",
    "reset": "the estimator diverged (non-finite or far outside the workspace), failed "
    "numerically, or its uncertainty exceeded the workspace (a long gap): it restarted "
    "from this sample's measurement, and this is the restarted estimate",
    "drifted": "the position state is more than DRIFT_FRACTION (10 %) of the length from "
    "the forward kinematics of the row's own theta and phi (the paper formulation's "
    "separate x, y, z): the row is not one consistent shape",
}


@dataclass(frozen=True)
class Measurement:
    """One sample: time ``t`` in seconds and the measurement vector ``z``.

    ``z`` holds the formulation's measurement blocks one after the other (for one tilt
    IMU ``[roll, pitch]`` in radians). NaN in a block marks a dropout of that sensor.
    """

    t: float
    z: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "z", np.asarray(self.z, dtype=float))

    @property
    def valid(self) -> bool:
        """Every value is finite (no sensor dropped out)."""
        return bool(np.all(np.isfinite(self.z)))


@dataclass(frozen=True)
class Estimate:
    """The estimate at one sample.

    Attributes:
        t: sample time, s.
        state: the formulation's state vector, or None for ``no-estimate``.
        output: the formulation's outputs (m, rad; see ``Formulation.outputs``), or
            None for ``no-estimate``.
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
        output: (n, ny), the columns described by ``outputs`` (m, rad).
        status: (n,) status strings.
        solve_ms: (n,) ms.
        outputs: what each column of ``output`` is (default: one section's
            ``x, y, z, theta, phi``).
    """

    method: str
    t: FloatArray
    output: FloatArray
    status: NDArray[np.str_]
    solve_ms: FloatArray
    outputs: tuple[OutputSpec, ...] = pcc_outputs(1)

    def __post_init__(self) -> None:
        if self.output.ndim != 2 or self.output.shape != (len(self.t), len(self.outputs)):
            raise ValueError(
                f"output has shape {self.output.shape}, expected ({len(self.t)}, "
                f"{len(self.outputs)}) for columns {', '.join(o.name for o in self.outputs)}"
            )

    def column(self, name: str) -> FloatArray:
        """The output column ``name`` (n,)."""
        for i, o in enumerate(self.outputs):
            if o.name == name:
                return self.output[:, i]
        raise KeyError(f"no output column {name!r}")

    @property
    def has_estimate(self) -> NDArray[np.bool_]:
        return self.status != "no-estimate"

    @classmethod
    def from_estimates(
        cls,
        method: str,
        estimates: Iterable[Estimate],
        outputs: tuple[OutputSpec, ...] = pcc_outputs(1),
    ) -> EstimateSeries:
        est = list(estimates)
        out = np.full((len(est), len(outputs)), np.nan)
        for i, e in enumerate(est):
            if e.output is not None:
                out[i] = e.output
        return cls(
            method=method,
            t=np.array([e.t for e in est], dtype=float),
            output=out,
            status=np.array([e.status for e in est], dtype=str),
            solve_ms=np.array([e.solve_ms for e in est], dtype=float),
            outputs=outputs,
        )
