"""Figures of the reproduction, rendered from the saved experiment data only.

Nothing here runs an estimator: every function takes the loaded JSON
(:func:`continuum_mhe.reproduce.pipeline.load_results`) and returns a figure.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from continuum_mhe.errors import UserError
from continuum_mhe.estimators.base import EstimateSeries
from continuum_mhe.evaluation import plotting
from continuum_mhe.reproduce.report.format import _median_total_ms

plt = plotting.plt
Figure = plotting.Figure
FORMATS = ("png", "pdf")
_COLORS = {"mhe": "C0", "ekf": "C1", "ukf": "C2", "mhe-l2": "C0", "mhe-robust": "C3"}


def arr(x: Any) -> np.ndarray:
    """JSON list (None for NaN) to a float array."""
    return np.array(x, dtype=float)


def series_of(trial_series: dict[str, Any], method: str) -> EstimateSeries:
    """An :class:`EstimateSeries` view of a saved series (solve times not kept)."""
    t = arr(trial_series["t"])
    out = arr(trial_series[method])
    status = trial_series.get(f"{method}_status")
    if status is None:
        status = np.where(np.all(np.isfinite(out), axis=1), "ok", "no-estimate")
    return EstimateSeries(method, t, out, np.asarray(status, dtype=str), np.zeros(len(t)))


def exp1_figures(d: dict[str, Any]) -> dict[str, Figure]:
    s = d["example"]["series"]
    truth = arr(s["truth"])
    mhe = series_of(s, "mhe")
    return {
        "exp1_synthetic3d_trajectory": plotting.trajectory_3d(
            truth,
            [mhe],
            f"Sec. 3.1 synthetic 3D: tip, truth vs MHE (N = {d['example']['spec']['horizon']})",
        ),
        "exp1_synthetic3d_states": plotting.states_vs_time(
            arr(s["t"]), truth, [mhe], "Sec. 3.1 synthetic 3D: states, truth vs MHE"
        ),
    }


def exp2_figures(d: dict[str, Any]) -> dict[str, Figure]:
    s = d["example"]["series"]
    t, truth = arr(s["t"]), arr(s["truth"])
    fig, axes = plt.subplots(3, 1, figsize=(7.5, 7.5), sharex=True)
    panels = [(3, "theta (deg)", np.degrees), (1, "y (mm)", None), (2, "z (mm)", None)]
    for ax, (k, label, conv) in zip(axes, panels):
        f: Callable[[np.ndarray], np.ndarray] = conv if conv else (lambda v: v * 1e3)
        ax.plot(t, f(truth[:, k]), "k-", lw=2, label="truth")
        for m in ("mhe", "ekf"):
            ax.plot(t, f(arr(s[m])[:, k]), color=_COLORS[m], lw=1.2, label=m.upper())
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    bound = float(d["example"]["theta_max"])
    axes[0].axhline(math.degrees(bound), color="r", ls=":", label="theta_max")
    over = truth[:, 3] > bound
    for ax in axes:
        if over.any():
            ax.axvspan(t[over][0], t[over][-1], color="r", alpha=0.07)
    axes[0].legend(ncol=4, fontsize="small")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle("Sec. 3.2 constraint handling: true theta leaves the workspace (shaded)")
    fig.tight_layout()
    return {"exp2_constraints": fig}


def exp3_figures(d: dict[str, Any]) -> dict[str, Figure]:
    s = d["series"]
    t, truth, fk = arr(s["t"]), arr(s["truth"]), arr(s["fk"])
    mhe, ekf = arr(s["mhe"]), arr(s["ekf"])
    fig, axes = plt.subplots(4, 1, figsize=(7.5, 9), sharex=True)
    rows = [(1, "y (mm)", 1e3), (2, "z (mm)", 1e3), (3, "theta (deg)", 180 / math.pi)]
    for ax, (k, label, sc) in zip(axes, rows):
        ax.plot(t, fk[:, k] * sc, color="0.6", lw=1.0, label="FK of measurements")
        ax.plot(t, truth[:, k] * sc, "k-", lw=1.6, label="rod truth (tip; CC fit theta)")
        ax.plot(t, mhe[:, k] * sc, color=_COLORS["mhe"], lw=1.2, label="MHE")
        ax.plot(t, ekf[:, k] * sc, color=_COLORS["ekf"], lw=1.0, ls="--", label="EKF")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    tip_true = truth[:, :3]
    for name, v, color, ls in (
        ("MHE", mhe, _COLORS["mhe"], "-"),
        ("EKF", ekf, _COLORS["ekf"], "--"),
        ("FK of meas.", fk, "0.6", "-"),
        ("best CC arc", arr(s["cc_fit_tip"]), "k", ":"),
    ):
        err = np.linalg.norm(v[:, :3] - tip_true, axis=1) * 1e3
        axes[3].plot(t, err, color=color, ls=ls, lw=1.0, label=name)
    axes[3].set_ylabel("tip error vs rod (mm)")
    axes[3].grid(alpha=0.3)
    axes[3].legend(ncol=4, fontsize="small")
    axes[0].legend(ncol=2, fontsize="small")
    axes[-1].set_xlabel("t (s)")
    fig.suptitle("Sec. 3.3 rod recording (Cosserat rod + MPU9250-like IMU)")
    fig.tight_layout()
    return {"exp3_rod": fig}


def _mean_and_interval(
    blocks: list[dict[str, Any]], method: str, key: str
) -> tuple[np.ndarray, np.ndarray]:
    """Each block's mean of ``method``'s ``key`` and its interval as errorbar lengths
    (2, n): below and above the mean."""
    mean = np.array([b[method][key]["mean"] for b in blocks], dtype=float)
    lo = np.array([b[method][key]["lo"] for b in blocks], dtype=float)
    hi = np.array([b[method][key]["hi"] for b in blocks], dtype=float)
    return mean, np.vstack([mean - lo, hi - mean])


def _bars(
    ax: Any, labels: list[str], blocks: list[dict[str, Any]], methods: tuple[str, ...], key: str
) -> None:
    x = np.arange(len(labels))
    w = 0.8 / len(methods)
    for j, m in enumerate(methods):
        mean, err = _mean_and_interval(blocks, m, key)
        ax.bar(
            x + (j - (len(methods) - 1) / 2) * w,
            mean,
            w,
            yerr=np.nan_to_num(err),
            capsize=2,
            color=_COLORS[m],
            label=m.upper(),
        )
    ax.set_xticks(x)
    ax.set_xticklabels(labels)
    ax.grid(alpha=0.3, axis="y")


def _points(
    ax: Any, labels: list[str], blocks: list[dict[str, Any]], methods: tuple[str, ...], key: str
) -> None:
    """:func:`_bars`' values as points with their intervals: for shares near 1, whose
    differences bars on a cut axis would magnify."""
    x = np.arange(len(labels))
    w = 0.6 / len(methods)
    for j, m in enumerate(methods):
        mean, err = _mean_and_interval(blocks, m, key)
        ax.errorbar(
            x + (j - (len(methods) - 1) / 2) * w, mean,
            yerr=np.nan_to_num(err), fmt="o", capsize=3,
            color=_COLORS[m], label=m.upper(),
        )  # fmt: skip
    ax.set_xticks(x)
    ax.set_xticklabels(labels)
    ax.grid(alpha=0.3, axis="y")


def exp4_figures(d: dict[str, Any]) -> dict[str, Figure]:
    s = d["example"]["series"]
    truth = arr(s["truth"])
    traj = plotting.trajectory_3d(
        truth,
        [series_of(s, "mhe"), series_of(s, "ekf")],
        "Sec. 3.4: tip, truth vs MHE vs EKF (Table 1 scenario 10 noise)",
    )
    mc = d["monte_carlo"]
    keys = sorted(mc, key=lambda g: int(g.split("-")[1]))
    fig, ax = plt.subplots(figsize=(8.5, 4.2))
    _bars(
        ax, [k.split("-")[1] for k in keys], [mc[k] for k in keys], ("mhe", "ekf", "ukf"), "srmse"
    )
    n = mc[keys[0]]["n_trials"]
    ax.set_xlabel("Table 1 scenario")
    ax.set_ylabel("SRMSE (m + rad)")
    ax.set_title(f"Monte Carlo, {n} seeds per scenario, mean and 95 % CI")
    ax.set_ylim(top=1.2 * ax.get_ylim()[1])  # room above the bars for the legend
    ax.legend(loc="upper center", ncol=3)
    fig.tight_layout()
    cond = d["conditions"]
    ck = list(cond)
    fig2, axes = plt.subplots(1, 2, figsize=(10, 4))
    # the tip error, as the report's table of the conditions and its verdicts give it
    _bars(
        axes[0],
        [k.removeprefix("condition-") for k in ck],
        [cond[k] for k in ck],
        ("mhe", "ekf", "ukf"),
        "tip_mean_mm",
    )
    axes[0].set_ylabel("mean tip error (mm)")
    axes[0].set_title("whole run")
    early = d["conditions_early"]
    _bars(
        axes[1],
        [k.removeprefix("condition-") for k in ck],
        [early[k] for k in ck],
        ("mhe", "ekf", "ukf"),
        "tip_mean_mm",
    )
    axes[1].set_ylabel("mean tip error (mm)")
    axes[1].set_title("first N samples")
    for a in axes:
        a.tick_params(axis="x", labelrotation=20)
        a.legend(fontsize="small")
    fig2.suptitle("Conditions the comparison depends on (mean and 95 % CI)")
    fig2.tight_layout()
    return {"exp4_trajectory_3d": traj, "exp4_monte_carlo": fig, "exp4_conditions": fig2}


def exp5_figures(d: dict[str, Any]) -> dict[str, Figure]:
    summ = d["summary"]
    ns = np.array(sorted(int(k) for k in summ))
    get = lambda key, f="mean": np.array(  # noqa: E731
        [summ[str(n)][key][f] for n in ns], dtype=float
    )
    fig, axes = plt.subplots(3, 1, figsize=(6.5, 8), sharex=True)
    axes[0].errorbar(
        ns,
        get("srmse"),
        yerr=np.nan_to_num([get("srmse") - get("srmse", "lo"), get("srmse", "hi") - get("srmse")]),
        marker="o",
        label="own estimates",
    )
    if "srmse_common" in summ[str(ns[0])]:
        axes[0].plot(ns, get("srmse_common"), marker="s", label="same samples for every N")
        axes[0].legend(fontsize="small")
    axes[0].set_ylabel("SRMSE (m + rad)")
    axes[1].plot(ns, get("solve_ms_mean"), marker="o", label="mean")
    if "solve_ms_median" in summ[str(ns[0])]:
        axes[1].plot(ns, get("solve_ms_median"), marker="s", label="median")
    ip = [summ[str(n)].get("ipopt") for n in ns]
    if all(ip):
        ip_med = [x["solve_ms_median"]["mean"] for x in ip]
        ip_tot = [x["solve_ms_total"]["mean"] / 1e3 for x in ip]
        axes[1].plot(ns, ip_med, marker="^", label="IPOPT median")
        axes[2].plot(ns, ip_tot, marker="^", color="C4", label="IPOPT")
    axes[1].legend(fontsize="small")
    axes[1].set_ylabel("time per estimate (ms)")
    axes[2].plot(ns, get("solve_ms_total") / 1e3, marker="o", color="C3", label="default, sum")
    median_total = [_median_total_ms(summ[str(n)]) / 1e3 for n in ns]  # what's judged
    axes[2].plot(ns, median_total, marker="s", color="C1", label="default, (M - N + 1) x median")
    axes[2].legend(fontsize="small")
    axes[2].set_ylabel("total time, M - N + 1 solves (s)")
    axes[2].set_xlabel("horizon N")
    for a in axes[1:]:  # the default backend's times lie orders of magnitude below IPOPT's
        a.set_yscale("log")
    for a in axes:
        a.grid(alpha=0.3)
    fig.suptitle("Sec. 3.5 horizon sweep (paper start: no estimate before N samples)")
    fig.tight_layout()
    return {"exp5_horizon": fig}


def exp6_figures(d: dict[str, Any]) -> dict[str, Figure]:
    ex = d["examples"]
    fig, ax = plt.subplots(figsize=(7.5, 4))
    g = ex["growing"]["series"]
    t, truth = arr(g["t"]), arr(g["truth"])
    for label, out, color, ls in (
        ("MHE, growing window", arr(g["mhe"]), "C0", "-"),
        ("EKF", arr(g["ekf"]), "C1", "--"),
        # dotted: from sample N on it lies on the growing window's line, which shows through
        ("MHE, paper start", arr(ex["paper-start"]["series"]["mhe"]), "C3", ":"),
    ):
        err = np.linalg.norm(out[:, :3] - truth[:, :3], axis=1) * 1e3
        ax.plot(t, err, color=color, ls=ls, label=label)
    n = int(ex["growing"]["spec"]["horizon"])
    ax.axvline(t[min(n - 1, len(t) - 1)], color="k", ls=":", lw=1, label=f"sample N = {n}")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("tip error (mm)")
    ax.set_title("Growing window vs the paper's start (no estimate before N samples)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    return {"exp6_window": fig}


def exp7_figures(d: dict[str, Any]) -> dict[str, Figure]:
    """Beyond the paper: outliers, coverage of the 95 % intervals, recovery."""
    s = d["summary"]
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    if "outliers" in s:
        out = s["outliers"]
        methods = tuple(out["clean"])
        _bars(
            axes[0], list(out), [{m: {"v": out[g][m]} for m in methods} for g in out], methods, "v"
        )
        axes[0].set_ylabel("mean tip error (mm)")
        axes[0].set_title("outliers (same seeds)")
        axes[0].legend(fontsize="small")
    if "coverage" in s:
        cov = s["coverage"]
        keys = ("coverage_x", "coverage_y", "coverage_z", "coverage_3d")
        methods = tuple(cov)
        blocks = [{m: {"v": cov[m][k]} for m in methods} for k in keys]
        _points(axes[1], [k.removeprefix("coverage_") for k in keys], blocks, methods, "v")
        axes[1].axhspan(0.90, 0.98, color="0.85", zorder=0, label="target 0.90-0.98")
        axes[1].axhline(0.95, color="k", lw=0.8)
        axes[1].set_ylim(0.85, 1.03)  # the legend above the points
        axes[1].set_ylabel("share inside the 95 % interval")
        axes[1].set_title("coverage of the tip's intervals")
        axes[1].legend(fontsize="small", loc="upper center", ncol=4)
    if "recovery" in s:
        rec = s["recovery"]
        methods = tuple(next(iter(rec.values())))
        labels = [f"{g}\n{side}" for g in rec for side in ("off", "on")]
        # the error over the event, and the rows ok while wrong (what a freeze's
        # recovery is for: its error grows, its wrong ok rows go)
        for ax, key, what in (
            (axes[2], "tip_mean_mm", "mean tip error over the event (mm)"),
            (axes[3], "ok_wrong", "rows ok but over 10 % of the length off, per run"),
        ):
            blocks = [
                {m: {"v": rec[g][m][key][side]} for m in rec[g]}
                for g in rec
                for side in ("off", "on")
            ]
            _bars(ax, labels, blocks, methods, "v")
            ax.tick_params(axis="x", labelsize="small")  # six labels: apart, not touching
            ax.set_ylabel(what)
            ax.set_title("recovery settings off / on")
            ax.legend(fontsize="small")
    counts = sorted(set((s.get("n_seeds") or {}).values()))  # seeds per experiment
    over = (
        "seeds" if not counts
        else f"{counts[0]} seeds" if len(counts) == 1
        else f"{counts[0]} to {counts[-1]} seeds"
    )  # fmt: skip
    fig.suptitle(f"Beyond the paper (mean and 95 % CI over {over})")
    fig.tight_layout()
    return {"exp7_beyond": fig}


RENDERERS: dict[str, Callable[[dict[str, Any]], dict[str, Figure]]] = {
    "exp1_synthetic3d": exp1_figures,
    "exp2_constraints": exp2_figures,
    "exp3_rod": exp3_figures,
    "exp4_ekf_comparison": exp4_figures,
    "exp5_horizon": exp5_figures,
    "exp6_window": exp6_figures,
    "exp7_beyond": exp7_figures,
}


def render_all(
    results: dict[str, dict[str, Any]],
    folder: str | Path,
    into: list[Path] | None = None,
    overwrite: bool = True,
) -> list[Path]:
    """Render the figures of every experiment present in ``results`` into ``folder``;
    returns the files, each also put in ``into`` as soon as it is saved. Unless
    ``overwrite``, a figure file that exists is a one-line :class:`UserError` before
    any is written."""
    figures: list[tuple[str, Any]] = []
    for name, render in RENDERERS.items():
        if name not in results:
            continue
        try:
            figures += list(render(results[name]).items())
        except (KeyError, IndexError, TypeError, ValueError) as exc:
            for _, fig in figures:
                plotting.close(fig)
            raise UserError(
                f"{name}.json of the results: not a results file of this version "
                f"({type(exc).__name__}: {exc}); run 'continuum-mhe reproduce' again"
            ) from None
    out: list[Path] = []
    try:
        taken = [
            p
            for fname, _ in figures
            for fmt in FORMATS
            if (p := Path(folder) / f"{fname}.{fmt}").exists()
        ]
        if taken and not overwrite:
            raise UserError(f"{taken[0]}: exists; give --overwrite to replace it, or another --out")
        Path(folder).mkdir(parents=True, exist_ok=True)
        for fname, fig in figures:
            out += plotting.save(fig, Path(folder) / fname, FORMATS, into)
    finally:  # a refusal, or a save that raised (Ctrl-C, a full disk): none left open
        for _, fig in figures:
            plotting.close(fig)
    return out
