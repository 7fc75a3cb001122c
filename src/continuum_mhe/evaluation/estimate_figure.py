"""The figure of one estimate file (``continuum-mhe plot EST.csv``): each section end and
the tip over time with their 95 % bands, the error against a truth, a tendon robot's
tip force, the statuses, and the backbone in 3D. It reads the file's table
(:class:`~continuum_mhe.io.state_tables.StateTable`) and never an estimator; any number of
sections, with or without a truth or a robot."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.evaluation.estimate_tables import (
    POINTS_PER_SECTION,
    BackboneOf,
    TrackedPoint,
    UnsolvedBackboneError,
    broken,
    has_bend_columns,
    has_tip_force,
    lengths_from_estimate,
    section_shapes,
    tracked_points,
    truth_points,
    truth_problem,
)
from continuum_mhe.evaluation.metrics import Z95, IndexArray, match_rows
from continuum_mhe.evaluation.plotting import Figure, hang, plt
from continuum_mhe.io.state_tables import StateTable, model_backbone_misfit
from continuum_mhe.model.descriptions import TIP_COLUMNS, TIP_FORCE_COLUMNS, section_count
from continuum_mhe.model.pcc import backbone_points
from continuum_mhe.results import Status

#: backbones drawn in the 3D view
SNAPSHOTS = 4


class FigureWarning(UserWarning):
    """What a figure draws may not be what it looks like."""


def _positions(table: StateTable, point: TrackedPoint) -> FloatArray:
    return np.stack([table.column(c) for c in point.columns], axis=1)


def _stds(table: StateTable, point: TrackedPoint) -> FloatArray | None:
    if not table.has_std or table.std is None:
        return None
    return np.stack([table.std[:, table.names.index(c)] for c in point.columns], axis=1)


#: Room around a position panel's lines, as a share of their span (at least
#: :data:`BAND_ROOM_MM`): a 95 % band wider than that is cut at the panel's edge.
BAND_ROOM = 0.5
BAND_ROOM_MM = 10.0


def _limit_to_lines(ax: plt.Axes, lines: Sequence[np.ndarray]) -> None:
    """The panel's y limits around its ``lines`` (mm) with :data:`BAND_ROOM`, so that a
    band of an estimate that is far from sure (metres wide) does not squeeze the lines
    flat: the band then fills the panel."""
    finite = [v[np.isfinite(v)] for v in lines]
    values = np.concatenate(finite) if finite else np.empty(0)
    if not len(values):
        return
    lo, hi = float(values.min()), float(values.max())
    room = max(BAND_ROOM * (hi - lo), BAND_ROOM_MM)
    ax.set_ylim(lo - room, hi + room)


def estimate_figure(
    est: StateTable,
    truth: StateTable | None = None,
    lengths: Sequence[float] | None = None,
    title: str = "",
    backbone: BackboneOf | None = None,
    z_down: bool = False,
    statuses: bool = True,
) -> Figure:
    """The figure of an estimate table ``est``: per axis, the position of each section
    end and of the tip over time (mm) with its 95 % band where the file has standard
    deviations; the distance of each from the ``truth``'s (mm) when one is given; a
    tendon robot's tip force (N, with its band, the truth's dashed); the status of each
    row; and the backbone at :data:`SNAPSHOTS` instants, the truth's dashed: from
    ``backbone`` when given; else, for a constant-curvature estimate, the arcs from
    ``lengths`` (m; else from the file's own rows) and the bend columns; else (a tendon
    robot's estimate without ``backbone``) straight lines through the section ends;
    ``statuses`` False: the table's statuses were not in its file (the strip says so);
    ``z_down``: the robot hangs (mounting ``z-down``), and the backbone's panel draws
    the base's z axis pointing down, so that the robot hangs there too.

    The truth draws the points it has (:func:`truth_points`: a motion-capture log may
    have the tip alone) and its backbone as arcs where it has the bend columns, else as
    straight lines through its points. Raises ``ValueError`` (:func:`truth_problem`'s
    line) when the truth has none of the tracked points or shares no time with the
    estimate."""
    points = tracked_points(est.names)
    matched = None
    in_truth: list[TrackedPoint | None] = [None] * len(points)
    if truth is not None:
        in_truth = truth_points(est, truth)
        problem = truth_problem(est, truth)
        if problem is not None:
            raise ValueError(problem)
        matched = match_rows(est.t, truth.t)
    force = has_tip_force(est.names)
    rows = 3 + (truth is not None) + force + 1
    fig = plt.figure(figsize=(14, 2.3 * rows + 0.6))
    grid = fig.add_gridspec(rows, 2, width_ratios=(1.7, 1.0))
    first = fig.add_subplot(grid[0, 0])
    axes = [first] + [fig.add_subplot(grid[r, 0], sharex=first) for r in range(1, rows)]
    band_named = False  # the legend's one entry for the bands
    for j, axis in enumerate("xyz"):
        ax = axes[j]
        drawn: list[np.ndarray] = []  # the panel's lines, which its limits show whole
        for i, p in enumerate(points):
            color = f"C{i}"
            v = _positions(est, p)[:, j] * 1e3
            drawn.append(v)
            ax.plot(*broken(est.t, v), color=color, lw=1.3, label=p.label)
            sd = _stds(est, p)
            if sd is not None:
                half = Z95 * sd[:, j] * 1e3
                t_b, lo, hi = broken(est.t, v - half, v + half)
                ax.fill_between(t_b, lo, hi, color=color, alpha=0.2, lw=0)
                if j == 0 and not band_named:  # one grey entry: each band is in its colour
                    ax.fill_between(
                        [], [], [], color="0.5", alpha=0.3, lw=0,
                        label="95 % band (in its line's colour)",
                    )  # fmt: skip
                    band_named = True
            tp = in_truth[i]
            if truth is not None and tp is not None:
                first_truth = tp is next(p for p in in_truth if p is not None)
                drawn.append(_positions(truth, tp)[:, j] * 1e3)
                ax.plot(*broken(truth.t, drawn[-1]), color=color, ls="--",
                        lw=1.0, label="truth" if first_truth else None)  # fmt: skip
        _limit_to_lines(ax, drawn)
        ax.set_ylabel(f"{axis} (mm)")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small", ncol=min(4, len(points) + 2))
    if truth is not None and matched is not None:
        ax = axes[3]
        i_e, i_t = matched
        for i, (p, tp) in enumerate(zip(points, in_truth)):
            if tp is None:
                continue
            err = np.linalg.norm(_positions(est, p)[i_e] - _positions(truth, tp)[i_t], axis=1)
            ax.plot(*broken(est.t[i_e], err * 1e3), color=f"C{i}", lw=1.2, label=p.label)
        ax.set_ylabel("error (mm)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    if force:
        _force_panel(axes[-2], est, truth)
    _status_strip(axes[-1], est, statuses)
    axes[-1].set_xlabel("t (s)")
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    view = fig.add_subplot(grid[:, 1], projection="3d")
    _backbones(view, est, truth, matched, lengths, backbone, in_truth)
    if z_down:
        hang(view)
    fig.suptitle(title, wrap=True)
    fig.tight_layout()
    return fig


def _force_panel(ax: plt.Axes, est: StateTable, truth: StateTable | None) -> None:
    """The tip force's components (N) with their 95 % bands, the truth's dashed."""
    for j, c in enumerate(TIP_FORCE_COLUMNS):
        v = est.column(c)
        ax.plot(*broken(est.t, v), color=f"C{j + 4}", lw=1.3, label=c)
        if est.has_std and est.std is not None:
            half = Z95 * est.std[:, est.names.index(c)]
            t_b, lo, hi = broken(est.t, v - half, v + half)
            ax.fill_between(t_b, lo, hi, color=f"C{j + 4}", alpha=0.2, lw=0)
        if truth is not None and c in truth.names:
            ax.plot(*broken(truth.t, truth.column(c)), color=f"C{j + 4}", ls="--", lw=1.0)
    ax.set_ylabel("tip force (N)")
    ax.legend(loc="upper right", fontsize="small", ncol=3)
    ax.grid(alpha=0.3)


#: the colours of the statuses other than ok (green), in :class:`Status`'s order: each
#: status has the same colour in every figure, whichever others its file has
#: one colour a status other than ``ok`` (green), none of them alike
_STATUS_COLORS = (
    "tab:red", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:gray",
    "tab:olive", "tab:cyan", "tab:blue", "black", "gold", "navy",
)  # fmt: skip


def status_color(status: Status) -> str:
    """The colour of ``status``'s marks in the status strip."""
    if status is Status.OK:
        return "C2"
    others = [s for s in Status if s is not Status.OK]
    return _STATUS_COLORS[others.index(status) % len(_STATUS_COLORS)]


def _status_strip(ax: plt.Axes, est: StateTable, statuses: bool = True) -> None:
    """One row of marks per status the file has, at the times it has it."""
    if not statuses:  # a file without them (read as ok): said, not a strip of ok rows
        ax.set_yticks([])
        ax.set_ylabel("status")
        ax.text(0.5, 0.5, "the file has no status column", ha="center", va="center",
                transform=ax.transAxes)  # fmt: skip
        return
    present = [s for s in Status if np.any(est.status == s.value)]
    for k, s in enumerate(present):
        at = est.t[est.status == s.value]
        ax.plot(at, np.full(len(at), k), "|", ms=9, color=status_color(s))
    ax.set_yticks(range(len(present)), [s.value for s in present], fontsize="small")
    ax.set_ylim(-0.7, len(present) - 0.3)
    ax.set_ylabel("status")
    ax.grid(alpha=0.3, axis="x")


def _backbones(
    ax: Any,
    est: StateTable,
    truth: StateTable | None,
    matched: tuple[IndexArray, IndexArray] | None,
    lengths: Sequence[float] | None,
    backbone: BackboneOf | None,
    in_truth: Sequence[TrackedPoint | None],
) -> None:
    """The backbone at a few instants with an estimate (and the truth's at the same
    instants, dashed): from ``backbone`` when given; else the arcs from ``lengths`` and
    the bend columns when both are known and the estimate is of constant curvature
    (a tendon robot's sections are not arcs); else straight lines through the section
    ends. A table without what its backbone needs (a truth without the bend or tip-force
    columns) is drawn as straight lines through the points it has (``in_truth`` for the
    truth's)."""
    n = section_count(est.names)
    points = tracked_points(est.names)
    arcs = backbone is None and not has_tip_force(est.names)
    if arcs:
        lengths = lengths if lengths is not None else lengths_from_estimate(est)
    has = np.flatnonzero(np.all(np.isfinite(est.values), axis=1))
    if not len(has):
        ax.set_title("no row has an estimate")
        return
    picks = has[np.linspace(0, len(has) - 1, min(SNAPSHOTS, len(has))).astype(int)]
    truth_row = dict(zip(*matched)) if matched is not None else {}
    curve = arcs and lengths is not None and n == len(lengths)
    s = None
    if curve:
        assert lengths is not None
        ends = np.cumsum([0.0, *lengths])
        s = np.concatenate(
            [np.linspace(a, b, POINTS_PER_SECTION + 1)[int(k > 0):]
             for k, (a, b) in enumerate(zip(ends[:-1], ends[1:]))]
        )  # fmt: skip
    reach = float(sum(lengths)) if lengths is not None else 0.0
    z_drawn = [0.0, 0.0]  # the lowest and highest z drawn (m), the base's included
    off = 0.0  # the model's backbone's tip from the estimate's (m), at most
    unsolved: list[str] = []  # the rows drawn whose loads have no equilibrium
    est_unsolved = 0  # of them the estimate's
    for j, i in enumerate(picks):
        color = plt.get_cmap("viridis")(j / max(1, len(picks) - 1))
        for table, row, style in ((est, i, "-"), (truth, truth_row.get(i), "--")):
            if table is None or row is None:
                continue
            if table is truth and not np.all(np.isfinite(table.values[row])):
                continue  # a gap of the truth (a lost marker) at this instant: not drawn
            shown = points if table is est else [p for p in in_truth if p is not None]
            ends_xyz = np.array([[table.column(c)[row] for c in p.columns] for p in shown])
            solved = None
            if backbone is not None and has_tip_force(table.names):
                try:
                    solved = backbone(table, row)
                except UnsolvedBackboneError as exc:  # drawn through its section ends, said
                    unsolved.append(str(exc))
                    est_unsolved += table is est
                    if est_unsolved == len(picks):  # none of the estimate's: no figure
                        raise UnsolvedBackboneError(unsolved[0]) from None
            if solved is not None:
                line = solved
                if table is est:
                    tip = [table.column(c)[row] for c in TIP_COLUMNS]
                    off = max(off, float(np.linalg.norm(line[-1] - tip)))
            elif (
                curve and s is not None and lengths is not None and has_bend_columns(table.names, n)
            ):
                theta, phi = section_shapes(table, n)
                line = backbone_points(lengths, theta[row], phi[row], s)
            else:
                line = np.concatenate([np.zeros((1, 3)), ends_xyz])
            label = f"t = {est.t[i]:.2f} s" if style == "-" else None
            ax.plot(*(line * 1e3).T, style, color=color, lw=2.0 if style == "-" else 1.2,
                    label=label)  # fmt: skip
            ax.plot(*(ends_xyz * 1e3).T, "o", color=color, ms=3)
            reach = max(reach, float(np.max(np.linalg.norm(line, axis=1))))
            z_drawn = [
                min(z_drawn[0], float(line[:, 2].min())),
                max(z_drawn[1], float(line[:, 2].max())),
            ]
    if unsolved:  # (every one of the estimate's: the error above)
        warnings.warn(
            f"{len(unsolved)} of the backbones drawn joined through their section ends: the "
            f"mechanics model holds no equilibrium under their loads; the first: {unsolved[0]}",
            FigureWarning,
            stacklevel=3,
        )
    r = reach * 1e3
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    # z over what is drawn (a robot standing on its base leaves the half below it empty),
    # at the same scale as x and y
    low, high = z_drawn[0] * 1e3 - 0.05 * r, z_drawn[1] * 1e3 + 0.05 * r
    ax.set_zlim(low, high)
    ax.set_box_aspect((2 * r, 2 * r, high - low), zoom=0.88)  # the z label inside the figure
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    how = "" if backbone is not None or curve else ", section ends joined"
    misfit = model_backbone_misfit(off, reach)
    if misfit:
        # the file holds the tip force, not the estimator's state: the model re-solved at
        # it need not be the estimate's shape (tensions or robot of another recording)
        how += f"\nmodel's tip up to {off * 1e3:.0f} mm from the estimate's"
        warnings.warn(misfit, FigureWarning, stacklevel=2)
    ax.set_title("backbone" + (" (truth dashed)" if truth is not None else "") + how)
    ax.legend(loc="upper left", fontsize="small")
