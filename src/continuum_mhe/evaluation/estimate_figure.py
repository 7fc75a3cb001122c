"""The figure of one estimate file (``continuum-mhe plot EST.csv``): each section end and
the tip over time with their 95 % bands, the error against a truth, a tendon robot's
tip force, the statuses, and the backbone in 3D. It reads the file's table
(:class:`~continuum_mhe.io.state_tables.StateTable`) and never an estimator; any number of
sections, with or without a truth or a robot."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray, typical_step
from continuum_mhe.errors import UserError
from continuum_mhe.evaluation.metrics import INTERPOLATE_GAP, Z95, IndexArray, match_rows
from continuum_mhe.evaluation.plotting import Figure, hang, plt
from continuum_mhe.io.state_tables import SECTION_FIELDS, StateTable, tip_section
from continuum_mhe.io.tensions import Tensions
from continuum_mhe.model.descriptions import TIP_COLUMNS, TIP_FORCE_COLUMNS
from continuum_mhe.model.pcc import backbone_points
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.tendon import acting_tensions
from continuum_mhe.model.tendon_statics import TendonStatics, no_equilibrium_at
from continuum_mhe.results import Status

#: backbones drawn in the 3D view
SNAPSHOTS = 4
#: points drawn per section of a backbone
POINTS_PER_SECTION = 16

#: The backbone of one row of a table, ``(table, row) -> (points, 3)`` m from the base to
#: the tip (a tendon robot's: the mechanics model's equilibrium at the row's tip force
#: and tensions).
BackboneOf = Callable[[StateTable, int], FloatArray]


@dataclass(frozen=True)
class TrackedPoint:
    """One point of the backbone that an estimate file tracks: its label and its
    position columns (``x_k, y_k, z_k`` for section ``k``'s end, ``x, y, z`` for the
    tip of a one-section file)."""

    label: str
    columns: tuple[str, str, str]


def section_count(names: Sequence[str]) -> int:
    """Sections of the robot an estimate was made for, from its bend columns (``theta``:
    one; ``theta_1 ... theta_n``: n); 0 when the file has none."""
    if "theta" in names:
        return 1
    n = 0
    while f"theta_{n + 1}" in names:
        n += 1
    return n


def tracked_points(names: Sequence[str]) -> tuple[TrackedPoint, ...]:
    """Every section end the file has positions of (``x_k, y_k, z_k``), the last being
    the tip; just the tip (``x, y, z``) when it has none."""
    ends = []
    k = 1
    while all(f"{c}_{k}" in names for c in "xyz"):
        ends.append(TrackedPoint(f"section {k} end", (f"x_{k}", f"y_{k}", f"z_{k}")))
        k += 1
    if not ends:
        return (TrackedPoint("tip", TIP_COLUMNS),)
    last = ends[-1]
    return (*ends[:-1], TrackedPoint(f"tip (section {len(ends)} end)", last.columns))


def has_bend_columns(names: Sequence[str], n_sections: int) -> bool:
    """Whether a table has every section's bend columns (``theta, phi`` for one section,
    ``theta_k, phi_k`` for each of several): what :func:`section_shapes` reads."""
    if n_sections == 1 and "theta" in names:
        return "phi" in names
    return n_sections > 0 and all(
        f"{c}_{k}" in names for k in range(1, n_sections + 1) for c in ("theta", "phi")
    )


def section_shapes(table: StateTable, n_sections: int) -> tuple[FloatArray, FloatArray]:
    """Each row's ``theta`` and ``phi`` per section (n_rows, n_sections), rad (one
    section's columns ``theta, phi``, or ``theta_1, phi_1`` as a tendon robot's of one
    section are named)."""
    if n_sections == 1 and "theta" in table.names:
        return table.column("theta")[:, None], table.column("phi")[:, None]
    theta = np.stack([table.column(f"theta_{k}") for k in range(1, n_sections + 1)], axis=1)
    phi = np.stack([table.column(f"phi_{k}") for k in range(1, n_sections + 1)], axis=1)
    return theta, phi


def lengths_from_estimate(table: StateTable) -> tuple[float, ...] | None:
    """The section lengths (m) an estimate was made with, from its own rows: a section
    of length ``L`` bent by ``theta`` has a chord ``2 L sin(theta/2) / theta`` from its
    base to its end, so each row gives ``L``; the median over the rows. None when the
    file lacks the bend or end columns."""
    n = section_count(table.names)
    points = tracked_points(table.names)
    if n == 0 or len(points) != n:
        return None
    if not all(c in table.names for p in points for c in p.columns):
        return None  # a table without a section end's (or the tip's) positions
    bends = (
        ["theta"] if n == 1 and "theta" in table.names else [f"theta_{k}" for k in range(1, n + 1)]
    )
    if not all(c in table.names for c in bends):
        return None  # a table without a section's bend (a partial truth)
    theta = np.stack([table.column(c) for c in bends], axis=1)
    ends = np.stack([np.stack([table.column(c) for c in p.columns], axis=1) for p in points], 1)
    starts = np.concatenate([np.zeros_like(ends[:, :1]), ends[:, :-1]], axis=1)
    chord = np.linalg.norm(ends - starts, axis=2)
    half = np.abs(theta) / 2
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(half > 1e-9, half / np.sin(half), 1.0)  # L / chord
    lengths = np.nanmedian(np.where(np.isfinite(chord * ratio), chord * ratio, np.nan), axis=0)
    if not np.all(np.isfinite(lengths) & (lengths > 0)):
        return None
    return tuple(float(v) for v in lengths)


def lengths_misfit(table: StateTable, lengths: Sequence[float]) -> str | None:
    """Where the section lengths the estimate's own rows give
    (:func:`lengths_from_estimate`) differ from ``lengths`` (m, a robot file's) by more
    than :data:`BACKBONE_MISFIT` of the robot's length: what to say (the two lengths),
    else None (also where the rows give none, and for a tendon robot's estimate, whose
    sections are not arcs)."""
    if has_tip_force(table.names):
        return None
    own = lengths_from_estimate(table)
    if own is None or len(own) != len(lengths):
        return None
    if max(abs(a - b) for a, b in zip(own, lengths)) <= BACKBONE_MISFIT * sum(lengths):
        return None

    def shown(v: Sequence[float]) -> str:
        return ", ".join(f"{x:.3g}" for x in v) + " m"

    return f"its rows fit sections of {shown(own)}, not the given robot's {shown(lengths)}"


def has_tip_force(names: Sequence[str]) -> bool:
    """Whether a table has a tendon robot's tip force columns (:data:`TIP_FORCE_COLUMNS`)."""
    return all(c in names for c in TIP_FORCE_COLUMNS)


def tendon_backbone(robot: Robot, tensions: Tensions) -> BackboneOf:
    """A tendon robot's backbone for a row of an estimate or truth table: the mechanics
    model's equilibrium (:meth:`TendonStatics.backbone_points`) at the row's tip force
    (:data:`TIP_FORCE_COLUMNS`) and the tensions at the row's time (an
    :class:`~continuum_mhe.errors.InputError` where ``tensions`` do not cover it), times
    the row's tension gains where it has them (:func:`acting_tensions`)."""
    statics = TendonStatics(robot)

    def points(table: StateTable, row: int) -> FloatArray:
        force = np.array([table.column(c)[row] for c in TIP_FORCE_COLUMNS])
        t = float(table.t[row])
        given, _, _ = tensions.at(t)
        gains = [c for c in table.names if c.startswith("tension_gain_")]
        values = np.array([[table.column(c)[row] for c in gains]])
        tension = acting_tensions(robot, given, gains, values)[0]
        try:
            return statics.backbone_points(force, tension, POINTS_PER_SECTION)
        except ArithmeticError as exc:
            raise UnsolvedBackbone(str(no_equilibrium_at(t, exc))) from None

    return points


class UnsolvedBackbone(UserError):
    """A row whose loads the mechanics model holds no equilibrium under: its backbone
    cannot be drawn from the model (the drawing joins its section ends instead)."""


#: The mechanics model's backbone drawn from a row's tip force and tensions ending more
#: than this share of the robot's length from the row's tip is said (a warning).
BACKBONE_MISFIT = 0.05


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


def broken(t: np.ndarray, *ys: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t`` and each of ``ys`` with a NaN inserted in each step of ``t`` wider than
    :data:`~continuum_mhe.evaluation.metrics.INTERPOLATE_GAP` of its typical step
    (:func:`~continuum_mhe.arrays.typical_step`; rows
    missing: a gap of the recording, or of the truth), so that a line breaks there
    instead of joining its two sides."""
    t = np.asarray(t, dtype=float)
    if len(t) < 3:
        return (t, *ys)
    steps = np.diff(t)
    gaps = np.flatnonzero(steps > INTERPOLATE_GAP * typical_step(t))
    if not len(gaps):
        return (t, *ys)
    at = gaps + 1
    return (
        np.insert(t, at, t[gaps] + 0.5 * steps[gaps]),
        *(np.insert(np.asarray(y, dtype=float), at, np.nan, axis=0) for y in ys),
    )


def truth_points(est: StateTable, truth: StateTable) -> list[TrackedPoint | None]:
    """For each of ``est``'s tracked points, the ``truth``'s columns of it: its own
    (``x_k, y_k, z_k``), or for the tip the truth's ``x, y, z`` (a motion-capture log of
    the tip alone); None where the truth has neither."""
    points = tracked_points(est.names)
    found: list[TrackedPoint | None] = []
    for i, p in enumerate(points):
        if all(c in truth.names for c in p.columns):
            found.append(p)
        elif i == len(points) - 1 and all(c in truth.names for c in TIP_COLUMNS):
            found.append(TrackedPoint(p.label, TIP_COLUMNS))
        else:
            found.append(None)
    return found


def truth_problem(est: StateTable, truth: StateTable) -> str | None:
    """Why :func:`estimate_figure` cannot draw ``truth`` beside ``est`` (it has none of
    the estimate's tracked points, or fewer than two of its rows share a time with the
    estimate's, or it has the bend or position columns of a section the estimate has
    not: a truth of a robot of more sections; or its section ``k`` ends at its tip
    where the estimate has more: of fewer), or None."""
    n_est = section_count(est.names)
    if n_est:
        single = "theta" in est.names

        def beyond(c: str) -> bool:  # a section column of a section the estimate has not
            field, _, k = c.rpartition("_")
            return field in SECTION_FIELDS and k.isdigit() and (single or int(k) > n_est)

        other = [c for c in truth.names if (c == "theta" and not single) or beyond(c)]
        if other:
            return (
                f"the truth has section columns ({', '.join(other)}) that an estimate of "
                f"{n_est} section(s) has not: a truth of another robot?"
            )
        ends = tip_section(truth)
        if ends is not None and ends < n_est:
            return (
                f"the truth's section {ends} ends at its tip in every row: a truth of a "
                f"robot of {ends} section(s), not of this estimate's {n_est}?"
            )
    if not any(truth_points(est, truth)):
        wanted = ", ".join(", ".join(p.columns) for p in tracked_points(est.names))
        return f"the truth has none of the estimate's positions ({wanted}; or x, y, z)"
    if len(est.t) < 2:
        return f"the estimate has {len(est.t)} row: a truth is drawn beside two rows or more"
    matched = match_rows(est.t, truth.t)
    if len(matched[0]) < 2:
        return (
            f"only {len(matched[0])} of the estimate's {len(est.t)} rows have a truth row "
            "at the same t (another recording, or t in milliseconds?)"
        )
    return None


def truth_at_rows(
    est: StateTable, truth: StateTable, i_est: IndexArray, rows: FloatArray, interpolated: bool
) -> StateTable | None:
    """``truth`` interpolated at ``est``'s times (the table of its values there, with a
    NaN row in each gap of those rows, as :func:`broken` finds them: a gap of the truth
    is drawn as one), where
    ``evaluate`` would compare it so, from their alignment ``(i_est, rows,
    interpolated)`` (:func:`~continuum_mhe.evaluation.metrics.aligned_truth`'s result);
    else None (the truth as it is)."""
    if not interpolated or len(i_est) < 2:
        return None
    t, values = broken(est.t[i_est], rows)  # a NaN row in each gap: the line breaks there
    return StateTable(t, truth.names, values, np.full(len(values), "ok"))


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
                except UnsolvedBackbone as exc:  # drawn through its section ends, said
                    unsolved.append(str(exc))
                    est_unsolved += table is est
                    if est_unsolved == len(picks):  # none of the estimate's: no figure
                        raise UnsolvedBackbone(unsolved[0]) from None
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
    if off > BACKBONE_MISFIT * max(reach, 1e-9):
        # the file holds the tip force, not the estimator's state: the model re-solved at
        # it need not be the estimate's shape (tensions or robot of another recording)
        how += f"\nmodel's tip up to {off * 1e3:.0f} mm from the estimate's"
        warnings.warn(
            f"the mechanics model's backbone at the estimate's tip force and the tensions "
            f"ends up to {off * 1e3:.0f} mm from the estimated tip in the rows drawn: are "
            "--robot and --inputs those of the estimate?",
            FigureWarning,
            stacklevel=2,
        )
    ax.set_title("backbone" + (" (truth dashed)" if truth is not None else "") + how)
    ax.legend(loc="upper left", fontsize="small")
