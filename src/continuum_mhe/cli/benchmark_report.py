"""The tables ``continuum-mhe benchmark`` prints (on stdout, through rich) of the
reports of :mod:`continuum_mhe.benchmark.harness` (:func:`~continuum_mhe.benchmark.
harness.run_benchmark`, :func:`~continuum_mhe.benchmark.harness.run_robot_benchmark`)
and :mod:`continuum_mhe.benchmark.losses`, which hold the data alone."""

from __future__ import annotations

import math
from typing import Any

from continuum_mhe.benchmark.environment import environment_line
from continuum_mhe.benchmark.harness import AGREEMENT_TOL
from continuum_mhe.benchmark.peers import PEERS


def _rounds(repeats: int) -> str:
    """How each sample's time was taken over ``repeats`` rounds, for a table's title."""
    if repeats == 1:
        return "one round after the warm-up"
    return f"each sample's median over {repeats} interleaved rounds"


def print_robot_report(report: dict[str, Any]) -> None:
    """Rich table of :func:`~continuum_mhe.benchmark.harness.run_robot_benchmark`'s
    report, and its environment line."""
    from rich.table import Table

    from continuum_mhe.progress import table_console

    table = Table(
        title=f"fast MHE vs IPOPT on the same windows: {report['robot']}, raw IMUs "
        f"({report['model']}), {report['samples']} samples, {_rounds(report['repeats'])}"
    )
    for col in ("N", "fast us", "fast p99 us", "IPOPT us", "IPOPT / fast", "max|d|", "fallbk"):
        table.add_column(col, justify="right", no_wrap=True)
    for r in report["rows"]:
        table.add_row(
            str(r["horizon"]),
            f"{r['fast_median_us']:.0f}",
            f"{r['fast_p99_us']:.0f}",
            f"{r['ipopt_median_us']:.0f}",
            f"{r['ipopt_over_fast']:.1f}",
            f"{r['max_diff_vs_ipopt']:.1e}",
            str(r["fallbacks"]),
        )
    console = table_console()
    console.print(table)
    console.print(environment_line(report))


def _us(x: float) -> str:
    """Microseconds as printed: one decimal below 10 (the EKF kernel), else whole."""
    return f"{x:.1f}" if x < 10 else f"{x:.0f}"


def _times(x: float) -> str:
    """A ratio as people read it: ``1/23`` below 0.1, else ``0.42`` or ``1.80``."""
    if not math.isfinite(x):
        return "-"
    return f"1/{1 / x:.0f}" if x < 0.1 else f"{x:.2f}"


def _disagrees(row: dict[str, Any]) -> str:
    """What a ratio line adds for an MHE whose answers are not IPOPT's (its time then
    compares unlike things); empty where they agree or the row has no such flag."""
    if row.get("agrees_with_ipopt") is False:
        if row.get("missing_from_n"):
            return (
                f"; NOT IPOPT's answers (none at {row['missing_from_n']} samples from "
                "sample N on where IPOPT has one): its time is no like-for-like comparison"
            )
        return (
            f"; NOT IPOPT's answers ({row['max_diff_from_n']:.1e} from sample N on, above "
            f"{AGREEMENT_TOL:g}): its time is no like-for-like comparison"
        )
    return ""


def _seconds(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.2f}"


def print_report(report: dict[str, Any]) -> None:
    """Rich table of :func:`~continuum_mhe.benchmark.harness.run_benchmark`'s report, the
    lines of its ratios, its losses' table (:func:`print_loss_report`), its memory and its
    environment."""
    from rich.table import Table

    from continuum_mhe.progress import table_console

    table = Table(
        title=f"Time per sample: bend, {report['scenario']}, {report['samples']} samples "
        f"(median and p99 from sample N on, {_rounds(report['repeats'])}; /fast, /IPOPT, "
        "/EKFc, /kernel: the median over the fast MHE's, IPOPT's, the compiled EKF's and "
        "the bare compiled EKF kernel's median; max|d|: largest "
        "output difference from IPOPT's, m and rad, over the run and from sample N on; "
        "fallbk: windows handed to IPOPT, or a peer did not converge on; solver us: the "
        "peer's own reported time)"
    )
    cols = ("N", "method", "median us", "p99 us", "/fast", "/IPOPT", "/EKFc", "/kernel",
            "max|d|", "from N", "fallbk", "solver us")  # fmt: skip
    for col in cols:
        table.add_column(col, justify="right", no_wrap=True)
    for r in report["results"]:
        table.add_row(
            str(r["horizon"]),
            r["method"],
            _us(r["median_us"]),
            _us(r["p99_us"]),
            _times(r["over_fast"]),
            _times(r["over_ipopt"]),
            _times(r["over_ekf_compiled"]),
            _times(r["over_ekf_kernel"]),
            f"{r['max_diff_vs_ipopt']:.1e}",
            f"{r['max_diff_from_n']:.1e}",
            str(r["fallbacks"]),
            "-"
            if r.get("solver_median_us") is None or math.isnan(r["solver_median_us"])
            else _us(r["solver_median_us"]),
        )
    console = table_console()
    console.width = max(console.width, 130)
    console.print(table)
    for name, note in report["methods"].items():
        console.print(f"  {name}: {note}")
    for name, why in report.get("skipped", {}).items():
        console.print(f"  {name}: not timed: {why}")
    fast = {r["horizon"]: r for r in report["results"] if r["method"] == "fast"}
    for n, r in fast.items():
        against = [
            f"{_times(r[key])}{times} {what}"
            for key, times, what in (
                ("over_ipopt", "", "of IPOPT"),
                ("over_ekf_compiled", "x", "the compiled EKF"),
                ("over_ekf_kernel", "x", "the bare EKF kernel"),
            )
            if math.isfinite(r[key])  # a contender skipped: no ratio to say
        ]
        if against:
            console.print(f"fast MHE at N = {n}: {', '.join(against)}{_disagrees(r)}")
    for r in report["results"]:
        if r["method"] == "mhe-kernel" and math.isfinite(r["over_ekf_kernel"]):
            console.print(
                f"bare MHE kernel at N = {r['horizon']}: {_times(r['over_ekf_kernel'])}x "
                "the bare EKF kernel"
            )
    for r in report["results"]:
        if r["method"] in PEERS and math.isfinite(r["over_fast"]):  # no ratio without fast
            own = r.get("solver_median_us")
            alone = (
                ""
                if own is None or math.isnan(own) or r["horizon"] not in fast
                else f" (its own solver time alone {own / fast[r['horizon']]['median_us']:.2f}x)"
            )
            console.print(
                f"{r['method']} at N = {r['horizon']}: {_times(r['over_fast'])}x the fast "
                f"MHE's time per sample{alone}, {r['max_diff_from_n']:.1e} from IPOPT"
                f"{_disagrees(r)}"
            )
    for n in sorted({r["horizon"] for r in report["results"]}):
        setup = [
            f"{r['method']} {_seconds(r.get('build_s'))} / {_seconds(r.get('warmup_s'))}"
            for r in report["results"]
            if r["horizon"] == n and "warmup_s" in r
        ]
        if setup:
            console.print(
                f"before the clock at N = {n}, s (build / warm-up run, not in the times): "
                + ", ".join(setup)
            )
    ns = sorted(fast)
    if len(ns) > 1:
        growth = fast[ns[-1]]["median_us"] / fast[ns[0]]["median_us"]
        console.print(f"fast: time(N={ns[-1]}) / time(N={ns[0]}) = {growth:.2f}")
    if report.get("losses"):
        print_loss_report(report["losses"])
    mem = report.get("memory")
    if mem:
        console.print(
            f"fast MHE memory over {mem['samples']} samples (N=30): "
            f"tracemalloc slope {mem['tracemalloc_slope_bytes_per_sample']:.3f} B/sample, "
            f"peak {mem['tracemalloc_peak_kib']:.0f} KiB; "
            f"RSS slope {mem['rss_slope_bytes_per_sample']:.2f} B/sample"
        )
    console.print(environment_line(report))


def print_loss_report(rows: list[dict[str, Any]]) -> None:
    """Rich table of :func:`~continuum_mhe.benchmark.losses.run_loss_benchmark`'s rows."""
    from rich.table import Table

    from continuum_mhe.progress import table_console

    table = Table(
        title="Cost of each MHE loss (median us per sample from sample N on, the smallest "
        "of three runs' medians, whatever --repeats; / l2: over "
        "the same backend's l2 time on the same data; SQP it: the fast backend's mean "
        "iterations per sample; max|d|: fast vs IPOPT, m and rad)"
    )
    for col in ("N", "data", "loss", "fast us", "fast / l2", "SQP it", "IPOPT us",
                "IPOPT / l2", "max|d|", "fallbk"):  # fmt: skip
        table.add_column(col, justify="right", no_wrap=True)
    for r in rows:
        table.add_row(
            str(r["horizon"]),
            r["data"],
            r["loss"] if r["loss"] == "l2" else f"{r['loss']} {r['scale']:g}",
            f"{r['fast_median_us']:.0f}",
            f"{r['fast_over_l2']:.2f}",
            f"{r['fast_iterations']:.2f}",
            f"{r['ipopt_median_us']:.0f}",
            f"{r['ipopt_over_l2']:.2f}",
            f"{r['max_diff_vs_ipopt']:.1e}",
            str(r["fallbacks"]),
        )
    console = table_console()
    console.width = max(console.width, 110)
    console.print(table)
