"""Chi-square and F quantiles for the estimators' consistency tests (``scipy.special``'s
``chdtri`` and ``fdtri``: the same numbers as ``scipy.stats.chi2.ppf`` and
``scipy.stats.f.ppf``, without importing ``scipy.stats``)."""

from __future__ import annotations

from scipy.special import chdtri, fdtri


def chi2_quantile(q: float, dof: int | float) -> float:
    """The ``q`` quantile of the chi-square distribution with ``dof`` degrees of freedom."""
    return float(chdtri(dof, 1.0 - q))


def f_quantile(q: float, dfn: float, dfd: float) -> float:
    """The ``q`` quantile of the F distribution with ``dfn`` and ``dfd`` degrees of
    freedom (the ratio of two independent chi-square averages)."""
    return float(fdtri(dfn, dfd, q))
