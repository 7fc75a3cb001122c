"""Chi-square quantiles for the estimators' consistency tests (``scipy.special``'s
``chdtri``: the same numbers as ``scipy.stats.chi2.ppf``, without importing
``scipy.stats``)."""

from __future__ import annotations

from scipy.special import chdtri


def chi2_quantile(q: float, dof: int | float) -> float:
    """The ``q`` quantile of the chi-square distribution with ``dof`` degrees of freedom."""
    return float(chdtri(dof, 1.0 - q))
