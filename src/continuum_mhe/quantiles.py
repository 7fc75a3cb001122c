"""Chi-square and F quantiles for the consistency tests of the estimators and the model
(``scipy.special``'s ``chdtri`` and ``fdtri``: the same numbers as
``scipy.stats.chi2.ppf`` and ``scipy.stats.f.ppf``).

The levels and degrees of freedom the estimators use are read from a table that
``tools/quantile_table.py`` computes with ``scipy.special`` (``data/quantiles.json``;
``tests/test_consistency.py`` checks it against ``scipy.special``), because
``scipy.special`` is slow to import; any other quantile is computed by
``scipy.special``, imported when first needed.
"""

from __future__ import annotations

import json
from functools import cache
from pathlib import Path
from types import ModuleType

#: The table of quantiles (``tools/quantile_table.py`` writes it).
TABLE_PATH = Path(__file__).parent / "data" / "quantiles.json"


@cache
def _table() -> tuple[dict[float, list[float]], dict[tuple[float, float, float], float]]:
    """The chi-square quantiles by level (entry ``k - 1``: ``k`` degrees of freedom) and
    the F quantiles by ``(level, dfn, dfd)``."""
    data = json.loads(TABLE_PATH.read_text())
    chi2 = {float(q): values for q, values in data["chi2"].items()}
    f = {(float(q), float(n), float(d)): value for q, n, d, value in data["f"]}
    return chi2, f


def _special() -> ModuleType:
    import scipy.special  # imported on use: slow to import, and the table covers most

    return scipy.special


def chi2_quantile(q: float, dof: int | float) -> float:
    """The ``q`` quantile of the chi-square distribution with ``dof`` degrees of freedom."""
    values, k = _table()[0].get(q), float(dof)
    if values is not None and k.is_integer() and 1 <= k <= len(values):
        return values[int(k) - 1]
    return float(_special().chdtri(dof, 1.0 - q))


def f_quantile(q: float, dfn: float, dfd: float) -> float:
    """The ``q`` quantile of the F distribution with ``dfn`` and ``dfd`` degrees of
    freedom (the ratio of two independent chi-square averages)."""
    value = _table()[1].get((q, dfn, dfd))
    if value is not None:
        return value
    return float(_special().fdtri(dfn, dfd, q))
