"""Figures. Plots read results (arrays, :class:`EstimateSeries`); they never run estimators."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from continuum_mhe.results import EstimateSeries  # noqa: E402

_STYLE = {"mhe": "C0", "ekf": "C1", "ukf": "C2"}


def _unit(name: str) -> str:
    return "deg" if name.startswith(("theta", "phi")) else "mm"


def _scale(name: str, v: np.ndarray) -> np.ndarray:
    """Display units; phi gets NaN breaks where it wraps at +-180 deg."""
    if _unit(name) == "mm":
        return v * 1e3
    d = np.degrees(v)
    if name.startswith("phi") and len(d) > 1:
        jump = np.abs(np.diff(d)) > 180
        d = np.insert(d, np.flatnonzero(jump) + 1, np.nan)
    return d


def _breaks(name: str, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Time axis matching :func:`_scale` (NaN inserted at phi wraps)."""
    if not name.startswith("phi") or len(v) < 2:
        return t
    jump = np.abs(np.diff(np.degrees(v))) > 180
    return np.insert(np.asarray(t, float), np.flatnonzero(jump) + 1, np.nan)


def trajectory_3d(
    truth: np.ndarray, series: Sequence[EstimateSeries], title: str = "Tip trajectory"
) -> Figure:
    """3D tip trajectory (mm): truth against each estimate."""
    fig = plt.figure(figsize=(6.4, 5.2))
    ax = fig.add_subplot(projection="3d")
    ax.plot(*(truth[:, :3].T * 1e3), "k-", lw=2.0, label="truth")
    for i, s in enumerate(series):
        ok = s.has_estimate
        ax.plot(
            *(s.output[ok, :3].T * 1e3),
            "--",
            lw=1.2,
            color=_STYLE.get(s.method, f"C{i + 3}"),
            label=s.method.upper(),
        )
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_title(title)
    ax.legend(loc="upper left")
    fig.tight_layout()
    return fig


def states_vs_time(
    t: np.ndarray,
    truth: np.ndarray | None,
    series: Sequence[EstimateSeries],
    title: str = "States",
    theta_max: float | Sequence[float] | None = None,
) -> Figure:
    """The tip position and every section's ``theta, phi`` against time, with truth
    (same columns as the series) and optional theta bounds (one per section)."""
    outputs = series[0].outputs
    names = [o.name for o in outputs]
    shown = [
        i for i, n in enumerate(names) if n in ("x", "y", "z") or n.startswith(("theta", "phi"))
    ]
    bounds = [theta_max] if isinstance(theta_max, (int, float)) else list(theta_max or [])
    fig, axes = plt.subplots(len(shown), 1, figsize=(7.5, 1.8 * len(shown)), sharex=True)
    for ax, k in zip(np.atleast_1d(axes), shown):
        name = names[k]
        if truth is not None:
            ax.plot(
                _breaks(name, t, truth[:, k]),
                _scale(name, truth[:, k]),
                "k-",
                lw=2.0,
                label="truth",
            )
        for i, s in enumerate(series):
            ax.plot(
                _breaks(name, s.t, s.output[:, k]),
                _scale(name, s.output[:, k]),
                "-",
                lw=1.0,
                color=_STYLE.get(s.method, f"C{i + 3}"),
                label=s.method.upper(),
            )
        if name.startswith("theta") and bounds:
            sec = int(name.split("_")[1]) - 1 if "_" in name else 0
            if sec < len(bounds):
                ax.axhline(np.degrees(bounds[sec]), color="r", ls=":", lw=1.0, label="bound")
        ax.set_ylabel(f"{name} ({_unit(name)})")
        ax.grid(alpha=0.3)
    first = np.atleast_1d(axes)[0]
    first.legend(loc="upper right", ncol=5, fontsize="small")
    np.atleast_1d(axes)[-1].set_xlabel("t (s)")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def backbone_snapshots(
    t: np.ndarray,
    truth: np.ndarray,
    series: Sequence[EstimateSeries],
    lengths: Sequence[float],
    title: str = "Backbone",
    count: int = 4,
) -> Figure:
    """The whole backbone (every section, mm) at ``count`` instants: truth (black)
    against each estimate, with the section ends marked."""
    from continuum_mhe.model.descriptions import section_bends
    from continuum_mhe.model.pcc import backbone

    outputs = series[0].outputs
    idx = np.linspace(len(t) // (count + 1), len(t) - 1, count).astype(int)
    fig = plt.figure(figsize=(4.2 * count, 4.4))
    ends = np.cumsum([0, *[10] * len(lengths)])
    for j, i in enumerate(idx):
        ax = fig.add_subplot(1, count, j + 1, projection="3d")
        pts = backbone(section_bends(outputs, truth[i]), lengths) * 1e3
        ax.plot(*pts.T, "k-", lw=3, label="truth")
        ax.plot(*pts[ends].T, "ko", ms=4)
        for k, s in enumerate(series):
            if not np.all(np.isfinite(s.output[i])):
                continue
            est = backbone(section_bends(outputs, s.output[i]), lengths) * 1e3
            color = _STYLE.get(s.method, f"C{k + 3}")
            ax.plot(*est.T, "-", lw=1.4, color=color, label=s.method.upper())
            ax.plot(*est[ends].T, "o", ms=3, color=color)
        reach = sum(lengths) * 1e3
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_zlim(-0.2 * reach, reach)
        ax.set_title(f"t = {t[i]:.1f} s", fontsize="medium")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_zlabel("z (mm)")
        if j == 0:
            ax.legend(loc="upper left", fontsize="small")
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def save(fig: Figure, path: Path, formats: Sequence[str] = ("png",)) -> list[Path]:
    """Save ``fig`` as ``path`` with each suffix in ``formats``; closes the figure."""
    out = []
    for fmt in formats:
        p = path.with_suffix(f".{fmt}")
        fig.savefig(p, dpi=130)
        out.append(p)
    plt.close(fig)
    return out
