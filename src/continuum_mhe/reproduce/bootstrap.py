"""Percentile-bootstrap intervals of means over seeds (fixed seed: the same data give
the same interval in every run)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

#: Resamples of every bootstrap here (fixed seed: the same data give the same
#: interval in every run).
BOOTSTRAP_RESAMPLES = 10_000


def mean_ci(values: Sequence[float], level: float = 0.95) -> dict[str, float]:
    """Mean and a two-sided ``level`` percentile-bootstrap interval of the mean.

    The interval is made of means of resampled data, so it never leaves the range of
    the values: errors and times (non-negative) never get a negative bound, whatever
    the number of seeds. With few seeds it is narrow and optimistic (two values give
    their range); the report says so. Non-finite values are left out; fewer than two
    values give no interval (nan)."""
    v = np.asarray([x for x in values if x is not None and math.isfinite(x)], dtype=float)
    n = len(v)
    if n == 0:
        return {"mean": math.nan, "lo": math.nan, "hi": math.nan, "n": 0}
    mean = float(v.mean())
    if n < 2:
        return {"mean": mean, "lo": math.nan, "hi": math.nan, "n": n}
    rng = np.random.default_rng(0)
    means = v[rng.integers(0, n, size=(BOOTSTRAP_RESAMPLES, n))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, (1 + level) / 2])
    return {"mean": mean, "lo": float(lo), "hi": float(hi), "n": n}


def paired(
    a: Sequence[float], b: Sequence[float], kind: Literal["ratio", "diff"]
) -> dict[str, Any]:
    """``mean(a) / mean(b)`` (``ratio``) or ``mean(a - b)`` (``diff``) over paired seeds
    with a 95 % percentile-bootstrap interval (the same resampled seeds on both sides)."""
    x, y = np.asarray(a, float), np.asarray(b, float)
    n = len(x)
    value = float(x.mean() / y.mean()) if kind == "ratio" else float((x - y).mean())
    if n < 2:
        return {"value": value, "lo": math.nan, "hi": math.nan, "n": n}
    pick = np.random.default_rng(0).integers(0, n, size=(BOOTSTRAP_RESAMPLES, n))
    if kind == "ratio":
        boot = x[pick].mean(axis=1) / y[pick].mean(axis=1)
    else:
        boot = (x - y)[pick].mean(axis=1)
    lo, hi = np.quantile(boot, [0.025, 0.975])
    return {"value": value, "lo": float(lo), "hi": float(hi), "n": n}
