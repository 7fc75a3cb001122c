"""Write ``src/continuum_mhe/data/quantiles.json``: the chi-square and F quantiles the
estimators' checks use, computed by ``scipy.special`` (``chdtri``, ``fdtri``), so that an
estimator reads them instead of importing ``scipy.special`` (slow to import: it brings
much of numpy's and scipy's array-API support with it).

Rows: the chi-square quantile at each level the estimators use (the consistency check's
``SAMPLE_QUANTILE``, ``RUN_QUANTILE`` and ``SHIFT_QUANTILE``, the start check's and the
branch check's ``QUANTILE``, the tendon model's ``IMU_ERROR_PROBABILITY``, ``1 -
LOADED_START_PROBABILITY`` and ``1 - LOAD_AT_START_PROBABILITY``) for 1 to ``CHI2_DOF``
degrees of freedom, and the F quantile of the consistency check's average
(``QUANTILE``, ``k (2 MEMORY - 1)`` and ``k (2 QUIET_MEMORY - 1)`` degrees of freedom)
for ``k`` = 1 to ``F_ROWS`` judged readings.
:mod:`continuum_mhe.quantiles` computes anything else with ``scipy.special``
itself; ``tests/test_consistency.py`` checks the table against it::

    python tools/quantile_table.py
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from scipy.special import chdtri, fdtri

from continuum_mhe.estimators import branch, consistency, start_check
from continuum_mhe.model import tendon
from continuum_mhe.quantiles import TABLE_PATH

#: Degrees of freedom of the chi-square rows: 1 to this (the branch check's goes to
#: the horizon times the measurement rows).
CHI2_DOF = 1024
#: Judged readings of the F rows: 1 to this.
F_ROWS = 64


def chi2_levels() -> list[float]:
    """The chi-square quantile levels the estimators and the tendon model use, each
    once, in order."""
    levels = (
        tendon.IMU_ERROR_PROBABILITY,
        1.0 - tendon.LOADED_START_PROBABILITY,
        1.0 - tendon.LOAD_AT_START_PROBABILITY,
        consistency.SHIFT_QUANTILE,
        consistency.RUN_QUANTILE,
        consistency.SAMPLE_QUANTILE,
        start_check.QUANTILE,
        branch.QUANTILE,
    )
    return sorted(set(levels))


def f_rows() -> list[tuple[float, int, int]]:
    """``(level, dfn, dfd)`` of the consistency check's F quantiles, 1 to ``F_ROWS``
    judged readings."""
    n_avg, n_quiet = 2 * consistency.MEMORY - 1, 2 * consistency.QUIET_MEMORY - 1
    return [(consistency.QUANTILE, k * n_avg, k * n_quiet) for k in range(1, F_ROWS + 1)]


def table() -> dict[str, object]:
    """The table as written: ``chi2`` maps each level (as text) to its quantiles for 1
    to ``CHI2_DOF`` degrees of freedom; ``f`` lists ``[level, dfn, dfd, quantile]``."""
    return {
        "chi2": {
            repr(q): [float(chdtri(k, 1.0 - q)) for k in range(1, CHI2_DOF + 1)]
            for q in chi2_levels()
        },
        "f": [[q, dfn, dfd, float(fdtri(dfn, dfd, q))] for q, dfn, dfd in f_rows()],
    }


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()  # --help
    path = Path(TABLE_PATH)
    path.write_text(json.dumps(table(), separators=(",", ":")) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
