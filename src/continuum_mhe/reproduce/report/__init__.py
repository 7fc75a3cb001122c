"""``report.md``: tables, settings of every run, and the paper's claims against ours.

Everything is computed from the saved experiment data (never from live estimators);
verdicts are derived from the numbers with fixed rules stated in the report.
Parts: :mod:`.format` (cells, tables, the paired verdict), :mod:`.sections` (one per
experiment), :mod:`.claims` (the paper's claims), :mod:`.beyond` (beyond the paper),
:mod:`.render` (the whole report).
"""

from continuum_mhe.reproduce.report.beyond import (
    beyond_claims,
    beyond_section,
    claim_bad_start,
    claim_clean,
    claim_coverage,
    claim_freeze,
    claim_gap,
    claim_outliers,
)
from continuum_mhe.reproduce.report.claims import (
    PAPER,
    Claim,
    claim_conditions,
    claim_constraints,
    claim_growing_window,
    claim_horizon_accuracy,
    claim_horizon_time,
    claim_more_accurate,
    claim_noise_robust,
    claim_rod,
    claim_synthetic,
    claims,
)
from continuum_mhe.reproduce.report.format import EQUIVALENCE, Results, verdict
from continuum_mhe.reproduce.report.render import (
    FEW_SEEDS,
    _few_seeds_line,
    render_report,
    write_report,
)

__all__ = [
    "EQUIVALENCE",
    "FEW_SEEDS",
    "PAPER",
    "Claim",
    "Results",
    "_few_seeds_line",
    "beyond_claims",
    "beyond_section",
    "claim_bad_start",
    "claim_clean",
    "claim_coverage",
    "claim_freeze",
    "claim_gap",
    "claim_outliers",
    "claim_conditions",
    "claim_constraints",
    "claim_growing_window",
    "claim_horizon_accuracy",
    "claim_horizon_time",
    "claim_more_accurate",
    "claim_noise_robust",
    "claim_rod",
    "claim_synthetic",
    "claims",
    "render_report",
    "verdict",
    "write_report",
]
