"""What an estimate or truth table says of the robot, for the figures, ``view`` and
``evaluate``: the points it tracks, each section's bend and length, a tendon robot's
tip force and backbone, and how a truth lines up with an estimate. Geometry of the
file's :class:`~continuum_mhe.io.state_tables.StateTable` alone (no plotting)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from continuum_mhe.arrays import FloatArray, typical_step
from continuum_mhe.errors import UserError
from continuum_mhe.evaluation.metrics import INTERPOLATE_GAP, IndexArray, match_rows
from continuum_mhe.io.state_tables import (
    BACKBONE_MISFIT,
    SECTION_FIELDS,
    StateTable,
    tip_section,
)
from continuum_mhe.io.tensions import Tensions
from continuum_mhe.model.descriptions import (
    TIP_COLUMNS,
    TIP_FORCE_COLUMNS,
    bend_columns,
    section_count,
    section_end_columns,
)
from continuum_mhe.model.robot import Robot
from continuum_mhe.model.tendon import acting_tensions
from continuum_mhe.model.tendon_statics import TendonStatics, no_equilibrium_at

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


def tracked_points(names: Sequence[str]) -> tuple[TrackedPoint, ...]:
    """Every section end the file has positions of (``x_k, y_k, z_k``), the last being
    the tip; just the tip (``x, y, z``) when it has none."""
    ends = []
    k = 1
    while all(c in names for c in section_end_columns(k)):
        ends.append(TrackedPoint(f"section {k} end", section_end_columns(k)))
        k += 1
    if not ends:
        return (TrackedPoint("tip", TIP_COLUMNS),)
    last = ends[-1]
    return (*ends[:-1], TrackedPoint(f"tip (section {len(ends)} end)", last.columns))


def has_bend_columns(names: Sequence[str], n_sections: int) -> bool:
    """Whether a table has every section's bend columns (``theta, phi`` for one section,
    ``theta_k, phi_k`` for each of several): what :func:`section_shapes` reads."""
    return n_sections > 0 and set(bend_columns(names, n_sections)) <= set(names)


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
    the row's tension gains where it has them (:func:`acting_tensions`).

    The equilibrium is followed along the table's rows from its first, each row's
    solved from the one before it (as ``view`` solves them): under loads past the ones
    that buckle the backbone the rod holds more than one equilibrium, and a solution
    from the straight rod can reach another one than the rows came through (the tip
    hundreds of millimetres from the row's). A row whose loads are not finite is passed
    over (the next row starts from the one before it); one whose time ``tensions`` do
    not cover, or whose loads hold no equilibrium, leaves the next row to start from
    the straight rod."""
    statics = TendonStatics(robot)
    followed: dict[int, tuple[StateTable, int, FloatArray | None]] = {}

    def loads(table: StateTable, row: int) -> tuple[FloatArray, FloatArray]:
        force = np.array([table.column(c)[row] for c in TIP_FORCE_COLUMNS])
        given, _, _ = tensions.at(float(table.t[row]))
        names = [c for c in table.names if c.startswith("tension_gain_")]
        values = np.array([[table.column(c)[row] for c in names]])
        return force, acting_tensions(robot, given, names, values)[0]

    def points(table: StateTable, row: int) -> FloatArray:
        held = followed.get(id(table))
        start, k0 = (
            (held[1], held[2]) if held and held[0] is table and held[1] < row else (-1, None)
        )
        for r in range(start + 1, row):  # the rows before it, each from the one before
            try:
                force, tension = loads(table, r)
                if not (np.all(np.isfinite(force)) and np.all(np.isfinite(tension))):
                    continue  # a gap (a lost marker): the next row from this one's start
                k0, _ = statics.solve(force, tension, k0)
            except (ArithmeticError, UserError):
                k0 = None
        force, tension = loads(table, row)
        try:
            k0, _ = statics.solve(force, tension, k0)
            followed[id(table)] = (table, row, k0)
            return statics.backbone_points(force, tension, POINTS_PER_SECTION, k0=k0)
        except ArithmeticError as exc:
            followed[id(table)] = (table, row, None)
            raise UnsolvedBackboneError(str(no_equilibrium_at(float(table.t[row]), exc))) from None

    return points


class UnsolvedBackboneError(UserError):
    """A row whose loads the mechanics model holds no equilibrium under: its backbone
    cannot be drawn from the model (the drawing joins its section ends instead)."""


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
    """Why :func:`~continuum_mhe.evaluation.estimate_figure.estimate_figure` cannot draw
    ``truth`` beside ``est`` (it has none of
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
