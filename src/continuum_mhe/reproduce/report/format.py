"""Formatting and the paired-difference verdict shared by every part of the report."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

Results = dict[str, dict[str, Any]]


def _f(v: Any, digits: int = 2) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"{float(v):.{digits}f}"


def _ci(block: dict[str, Any] | None, digits: int = 3, scale: float = 1.0) -> str:
    if not block or block.get("mean") is None:
        return "–"
    m = block["mean"] * scale
    if block.get("lo") is None:
        return _f(m, digits)
    return f"{_f(m, digits)} [{_f(block['lo'] * scale, digits)}, {_f(block['hi'] * scale, digits)}]"


#: Differences whose whole 95 % CI lies within this share of the EKF's mean are
#: reported as practically equivalent.
EQUIVALENCE = 0.02


def verdict(diff: dict[str, Any] | None, reference: dict[str, Any] | None = None) -> str:
    """From the 95 % CI of the paired difference MHE - EKF (``reference``: EKF's mean)."""
    if not diff or diff.get("lo") is None:
        return "n/a"
    if reference and reference.get("mean"):
        tol = EQUIVALENCE * abs(reference["mean"])
        if -tol < diff["lo"] and diff["hi"] < tol:
            return f"equivalent (within {EQUIVALENCE:.0%})"
    if diff["hi"] < 0:
        return "MHE lower"
    if diff["lo"] > 0:
        return "EKF lower"
    return "no significant difference"


def _median_total_ms(block: dict[str, Any]) -> float:
    """The total solve time over the recording at one N, ms: (M - N + 1) estimates at
    the median time per estimate, so that a few samples slowed by other load on the
    machine cannot fake a peak (the summed wall time, also reported, can)."""
    median = block.get("solve_ms_median", block["solve_ms_mean"])["mean"]
    return float(median) * float(block["n_estimates"])


def _total_time_peak(summary: dict[str, Any], ns: list[int]) -> int:
    """N at which the total solve time over the recording (:func:`_median_total_ms`)
    peaks."""
    tot = [_median_total_ms(summary[str(n)]) for n in ns]
    return ns[max(range(len(ns)), key=lambda i: tot[i])]


def _g(v: Any, digits: int = 3) -> str:
    """``v`` to ``digits`` significant digits (a total that spans orders of magnitude)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    x = float(v)
    return f"{x:.0f}" if abs(x) >= 10**digits else f"{x:.{digits}g}"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A Markdown table; a ``|`` inside a cell is escaped."""

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"

    return [line(header), "|" + "---|" * len(header), *(line(r) for r in rows), ""]


def _metric_row(name: str, m: dict[str, Any] | None, ms: float | None = None) -> list[str]:
    if m is None:
        return [name, "–", "–", "–", "–", "–", "–"]
    r = m["rmse"]
    row = [
        name,
        _f(m["tip_mean_mm"]),
        _f(m["tip_max_mm"]),
        _f(math.degrees(r["theta"])),
        _f(math.degrees(r["phi"])),
        _f(m["srmse"], 4),
    ]
    return row + ([_f(ms, 3)] if ms is not None else ["–"])


_METRIC_HEADER = (
    "method",
    "tip mean (mm)",
    "tip max (mm)",
    "theta RMSE (deg)",
    "phi RMSE (deg)",
    "SRMSE",
    "median ms/sample",
)


def _rerun(
    spec: dict[str, Any],
    seeds: str | None = None,
    kind: tuple[str, str, str] = ("experiments", "TrialSpec", "run_trial"),
) -> list[str]:
    """A Python block that reruns ``spec`` (for a group: with its first seed, the others
    named in a comment); ``kind``: module of ``continuum_mhe.reproduce``, spec class
    (with ``from_dict``) and run function."""
    module, cls, fn = kind
    s = {k: v for k, v in spec.items() if k not in ("keep_series",)}
    lines = ["```python", f"from continuum_mhe.reproduce.{module} import {cls}, {fn}"]
    if seeds:
        lines.append(f"SEED = {s['seed']!r}  # the group's seeds: {seeds}")
        s["seed"] = "<seed>"
    lines.append(f"spec = {s!r}")
    if seeds:
        lines.append("spec['seed'] = SEED")
    lines += [f"result = {fn}({cls}.from_dict(spec))", "```", ""]
    return lines


def _seed_range(trials: Sequence[dict[str, Any]]) -> str:
    seeds = sorted(int(t["spec"]["seed"]) for t in trials)
    if seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"{seeds[0]}..{seeds[-1]} ({len(seeds)} seeds)"
    return ", ".join(map(str, seeds))


def _noise_deg(spec: dict[str, Any]) -> float:
    return math.degrees(float(spec["assumed_std"]))
