"""Figures. Plots read results (arrays, :class:`EstimateSeries`); they never run estimators."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

# The figures are drawn off screen (Agg): the backend that MPLBACKEND names is not used,
# and one that names no backend would stop matplotlib's import
_named_backend = os.environ.pop("MPLBACKEND", None)
try:
    import matplotlib
finally:
    if _named_backend is not None:
        os.environ["MPLBACKEND"] = _named_backend

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from continuum_mhe.io.output_files import atomic_binary_writer  # noqa: E402
from continuum_mhe.results import EstimateSeries  # noqa: E402

_STYLE = {"mhe": "C0", "ekf": "C1", "ukf": "C2"}
#: line style per method: on smooth data the three estimates lie within a line width of
#: each other, so they differ in width and dash as well as colour (all stay visible)
_LINES: dict[str, dict[str, object]] = {
    "mhe": {"ls": "-", "lw": 3.2, "alpha": 0.55},
    "ekf": {"ls": "--", "lw": 1.6, "alpha": 0.95},
    "ukf": {"ls": ":", "lw": 1.6, "alpha": 0.95},
}
#: below this true bend angle (rad) the bending plane phi is shaded as undefined
STRAIGHT_THETA = np.radians(3.0)


def _line(method: str, i: int) -> dict[str, object]:
    """Matplotlib keywords for method ``method`` (the ``i``-th series)."""
    style = {"ls": "-", "lw": 1.2, "alpha": 0.9, **_LINES.get(method, {})}
    return {"color": _STYLE.get(method, f"C{i + 3}"), "label": method.upper(), **style}


def _spans(mask: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` index ranges where ``mask`` is True."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)))


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


def hang(ax: Any) -> None:
    """Draw the 3D axes ``ax`` of a robot whose base frame's z points down in the world
    (mounting ``z-down``) as it hangs: turned half a turn about x (z and y both
    reversed, so the frame stays right-handed and a bend is not mirrored)."""
    ax.invert_zaxis()
    ax.invert_yaxis()
    ax.set_zlabel("z (mm, base z down)")


def trajectory_3d(
    truth: np.ndarray,
    series: Sequence[EstimateSeries],
    title: str = "Tip trajectory",
    z_down: bool = False,
) -> Figure:
    """3D tip trajectory (mm): truth against each estimate; ``z_down``: a hanging
    robot's, drawn as it hangs (:func:`hang`)."""
    fig = plt.figure(figsize=(6.4, 5.2))
    ax = fig.add_subplot(projection="3d")
    ax.plot(*(truth[:, :3].T * 1e3), "k-", lw=2.0, label="truth")
    for i, s in enumerate(series):
        ok = s.has_estimate
        ax.plot(*(s.output[ok, :3].T * 1e3), **_line(s.method, i))
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    ax.set_aspect("equal")  # a path's shape as it is: one mm as long on every axis
    if z_down:
        hang(ax)
    ax.set_title(title, wrap=True)  # a robot's long description: wrapped, not cut
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
    (same columns as the series) and optional theta bounds (one per section).

    With truth, a first panel shows each method's tip error (mm), and each ``phi`` panel
    shades the stretches where the true section is nearly straight
    (``theta < STRAIGHT_THETA``), where ``phi`` is undefined.
    """
    outputs = series[0].outputs
    names = [o.name for o in outputs]
    shown = [
        i for i, n in enumerate(names) if n in ("x", "y", "z") or n.startswith(("theta", "phi"))
    ]
    bounds = [theta_max] if isinstance(theta_max, (int, float)) else list(theta_max or [])
    panels = len(shown) + (truth is not None)
    fig, axes = plt.subplots(panels, 1, figsize=(7.5, 1.8 * panels), sharex=True)
    axes = np.atleast_1d(axes)
    if truth is not None:
        ax = axes[0]
        for i, s in enumerate(series):
            err = np.linalg.norm(s.output[:, :3] - truth[:, :3], axis=1) * 1e3
            ax.plot(s.t, err, **_line(s.method, i))
        ax.set_ylabel("tip error (mm)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        axes = axes[1:]
    for ax, k in zip(axes, shown):
        name = names[k]
        if truth is not None and name.startswith("phi"):
            theta_name = "theta" + name[len("phi") :]
            if theta_name in names:
                straight = np.abs(truth[:, names.index(theta_name)]) < STRAIGHT_THETA
                for j, (a, b) in enumerate(_spans(straight)):
                    ax.axvspan(
                        t[a], t[min(b, len(t) - 1)], color="0.85", zorder=0,
                        label=f"phi undefined (theta < {np.degrees(STRAIGHT_THETA):.0f} deg)"
                        if j == 0 else None,
                    )  # fmt: skip
                if straight.any():
                    ax.legend(loc="best", fontsize="small")  # off the phi line
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
                **_line(s.method, i),
            )
        if name.startswith("theta") and bounds:
            sec = int(name.split("_")[1]) - 1 if "_" in name else 0
            if sec < len(bounds):
                bound = np.degrees(bounds[sec])
                ax.axhline(bound, color="r", ls="-.", lw=1.0)
                ax.annotate(
                    f"bound theta_max = {bound:.0f} deg", (0.01, bound), color="r",
                    xycoords=("axes fraction", "data"), va="bottom", fontsize="small",
                )  # fmt: skip
                top = max(ax.get_ylim()[1], bound * 1.12)
                ax.set_ylim(top=top)
        ax.set_ylabel(f"{name} ({_unit(name)})")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()  # truth, the methods, the bound
    keep = [j for j, lab in enumerate(labels) if not lab.startswith("phi undefined")]
    fig.axes[0].legend(
        [handles[j] for j in keep],
        [labels[j] for j in keep],
        loc="lower right",
        bbox_to_anchor=(1.0, 1.0),
        ncol=5,
        fontsize="small",
        frameon=False,
    )  # fmt: skip: above the axes, off the curves
    axes[-1].set_xlabel("t (s)")
    fig.suptitle(title, wrap=True)
    fig.tight_layout()
    return fig


def backbone_snapshots(
    t: np.ndarray,
    truth: np.ndarray,
    series: Sequence[EstimateSeries],
    lengths: Sequence[float],
    title: str = "Backbone",
    count: int = 4,
    z_down: bool = False,
) -> Figure:
    """The whole backbone (every section, mm) at ``count`` instants: truth (black)
    against each estimate, with the section ends marked; ``z_down``: a hanging robot's,
    drawn as it hangs (:func:`hang`)."""
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
            style = _line(s.method, k)
            ax.plot(*est.T, **style)
            ax.plot(*est[ends].T, "o", ms=3, color=style["color"])
        reach = sum(lengths) * 1e3
        ax.set_xlim(-reach, reach)
        ax.set_ylim(-reach, reach)
        ax.set_zlim(-0.2 * reach, reach)
        ax.set_title(f"t = {t[i]:.1f} s", fontsize="medium")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_zlabel("z (mm)")
        if z_down:
            hang(ax)
        ax.set_box_aspect(None, zoom=0.85)  # the z label inside the figure
        if j == 0:
            ax.legend(loc="upper left", fontsize="small")
    fig.suptitle(title, wrap=True)
    fig.tight_layout()
    return fig


def save(
    fig: Figure, path: Path, formats: Sequence[str] = ("png",), into: list[Path] | None = None
) -> list[Path]:
    """Save ``fig`` as ``path`` with each suffix in ``formats``, each file atomically (an
    interrupted save leaves no partial file and an existing one untouched); closes the
    figure. Returns the files; each is also put in ``into`` as soon as it is saved (so
    that a caller's clean-up knows the first format of a save interrupted at the next)."""
    out: list[Path] = []
    try:
        for fmt in formats:
            p = path.with_suffix(f".{fmt}")
            with atomic_binary_writer(p) as fh:
                fig.savefig(fh, format=fmt, dpi=130)
            out.append(p)
            if into is not None:
                into.append(p)
    finally:
        plt.close(fig)
    return out


def close(fig: Figure) -> None:
    """Close ``fig`` unsaved (its memory freed)."""
    plt.close(fig)
