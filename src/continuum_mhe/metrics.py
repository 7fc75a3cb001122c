"""Error metrics of estimates against truth (results as data)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.model.imu import wrap_angle

FloatArray = NDArray[np.float64]

STATE_NAMES = ("x", "y", "z", "theta", "phi")


@dataclass(frozen=True)
class Metrics:
    """Errors over the samples that have an estimate.

    Attributes:
        rmse: RMSE per state ``x, y, z`` (m), ``theta, phi`` (rad; phi wrapped).
        srmse: the paper's SRMSE, the sum of the five RMSEs (mixed units, as printed).
        tip_mean_mm, tip_max_mm: Euclidean tip error, mm.
        tip_mean_pct, tip_max_pct: the same in % of the section length.
        n: samples compared; n_without_estimate: samples with no estimate.
    """

    rmse: dict[str, float]
    srmse: float
    tip_mean_mm: float
    tip_max_mm: float
    tip_mean_pct: float
    tip_max_pct: float
    n: int
    n_without_estimate: int

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def state_errors(estimate: FloatArray, truth: FloatArray) -> FloatArray:
    """Per-sample errors (n, 5), with phi wrapped to ``[-pi, pi)``."""
    err = np.asarray(estimate, float) - np.asarray(truth, float)
    err[:, 4] = wrap_angle(err[:, 4])
    return err


def compute_metrics(estimate: FloatArray, truth: FloatArray, length: float) -> Metrics:
    """Metrics of ``estimate`` (n, 5) against ``truth`` (n, 5); NaN rows are skipped."""
    has = np.all(np.isfinite(estimate), axis=1)
    if not has.any():
        raise ValueError("no sample has an estimate")
    err = state_errors(estimate[has], truth[has])
    rmse = np.sqrt(np.mean(err**2, axis=0))
    tip = np.linalg.norm(err[:, :3], axis=1)
    return Metrics(
        rmse={k: float(v) for k, v in zip(STATE_NAMES, rmse)},
        srmse=float(rmse.sum()),
        tip_mean_mm=float(tip.mean() * 1e3),
        tip_max_mm=float(tip.max() * 1e3),
        tip_mean_pct=float(tip.mean() / length * 100),
        tip_max_pct=float(tip.max() / length * 100),
        n=int(has.sum()),
        n_without_estimate=int((~has).sum()),
    )
