"""Tables of states read back: an estimate CSV (``t``, the outputs, their ``std_``
columns, ``status``...) or a truth CSV (``t,x,y,z`` and any per-section columns), and
the checks that a table fits a robot (docs/formats.md). Every problem raises
:class:`~continuum_mhe.errors.InputError` naming the file and line."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.io.estimate_csv import STD_PREFIX
from continuum_mhe.io.sample_rows import has_extra_fields
from continuum_mhe.io.text_rows import (
    TextRows,
    column_indices,
    open_rows,
    parse_float,
    shorten,
    to_float,
    warn_cut_line,
)
from continuum_mhe.model.descriptions import (
    TIP_COLUMNS,
    TIP_FORCE_COLUMNS,
    angle_beyond_a_turn,
    output_names,
    pcc_outputs,
    robot_outputs,
    section_end_columns,
    sections_with_ends,
)
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import STATUS_MEANINGS, Status

#: One section's state columns (the paper's robot); several sections: see
#: :func:`~continuum_mhe.model.descriptions.pcc_outputs`.
STATE_COLUMNS = ("t", *output_names(pcc_outputs(1)))


#: The header an estimate or truth table's refusal suggests (an empty file, no header).
STATE_HEADER_HINT = "t,x,y,z,theta,phi (an estimate's or a truth's)"


def _read_rows(path: str | os.PathLike[str]) -> tuple[TextRows, list[tuple[int, list[str]]]]:
    """The opened table and all its ``(line_number, fields)`` rows (a small file); a
    last line without an end is said by the caller once it has read it
    (``rows.cut.line``)."""
    with open_rows(path, STATE_HEADER_HINT) as rows:
        rows.cut.checked = True
        return rows, list(rows.rows)


@dataclass(frozen=True)
class StateTable:
    """An estimate or truth CSV: ``t`` (n,), ``values`` (n, k) with NaN where empty,
    ``names`` (k,) the columns (outputs such as ``x``, ``theta_2``), ``status`` (n,)
    (``"ok"`` where the file has no status column), ``std`` (n, k) the ``std_``
    columns of the outputs (NaN where empty or absent), and ``outlier`` (n,) bool where
    the file has an ``outlier`` column (else None)."""

    t: FloatArray
    names: tuple[str, ...]
    values: FloatArray
    status: NDArray[np.str_]
    std: FloatArray | None = None
    outlier: NDArray[np.bool_] | None = None
    #: the file has ``std_`` columns (perhaps all empty)
    std_columns: bool = False
    #: the file has a ``status`` column (an estimate's)
    status_column: bool = False

    @property
    def has_std(self) -> bool:
        """The file has a finite standard deviation somewhere."""
        return self.std is not None and bool(np.isfinite(self.std).any())

    def _index(self, name: str) -> int:
        if name not in self.names:
            raise KeyError(f"no column {name!r} (the table's: {', '.join(self.names)})")
        return self.names.index(name)

    def column(self, name: str) -> FloatArray:
        """The column ``name`` (n,), in its unit; NaN where empty."""
        return self.values[:, self._index(name)]

    def std_column(self, name: str) -> FloatArray:
        """One standard deviation of the column ``name`` (n,), in its unit; NaN where
        the file has none."""
        i = self._index(name)
        return np.full(len(self.t), np.nan) if self.std is None else self.std[:, i]


_NOT_STATES = {"t", "status", "solve_ms", "outlier"}


def _holds_text(cells: list[str]) -> bool:
    """Whether a column's ``cells`` hold a value that is not a number (nor empty)."""
    for text in cells:
        if text == "":
            continue
        try:
            to_float(text)
        except ValueError:
            return True
    return False


#: the suffix of a truth column kept beside the measurements of a recording
TRUE_SUFFIX = "_true"


def truth_named(header: list[str], required: Sequence[str]) -> list[str]:
    """``header`` with each ``NAME_true`` column renamed ``NAME`` when the ``required``
    columns are absent and their ``_true`` columns present (a recording with its truth
    beside the measurements); else ``header`` itself."""
    if all(c in header for c in required) or not all(c + TRUE_SUFFIX in header for c in required):
        return header
    return [h[: -len(TRUE_SUFFIX)] if h.endswith(TRUE_SUFFIX) else h for h in header]


#: The largest magnitude of a value in an estimate or truth file (m, rad, N): none of a
#: robot's; beyond it errors and their squares lose meaning or overflow. (A standard
#: deviation may be larger: an estimate that says it knows nothing.)
STATE_LIMIT = 1e9


def read_state_table(
    path: str | os.PathLike[str], required: Sequence[str] = TIP_COLUMNS, gaps: bool = False
) -> StateTable:
    """Read an estimate or truth CSV with at least ``t`` and ``required`` columns; every
    other numeric output column (``theta``, ``phi_2``, ``std_x``...) is kept. A
    recording that carries its truth beside the measurements (``x_true, y_true, z_true``,
    as the shipped ``rod_planar.csv``) is read as that truth: each ``NAME_true`` column
    is the output ``NAME``. ``gaps``: an empty or NaN value (not ``t``) is read as NaN,
    a gap of a truth (a marker the motion capture lost), not refused; a column with no
    value in any row is left out, and a file without a row that has every ``required``
    column is refused."""
    table, body = _read_rows(path)
    table.header = truth_named(table.header, required)
    p, header = table.name, table.header
    column_indices(table, ("t", *required))
    names = tuple(h for h in header if h not in _NOT_STATES and h and not h.startswith(STD_PREFIX))
    if gaps:  # a truth's columns of text that no output is named as (a marker's label)
        whole = [row for _, row in body if len(row) == len(header)]
        names = tuple(
            c
            for c, j in zip(names, (header.index(c) for c in names))
            if c in required or _is_output_column(c) or not _holds_text([row[j] for row in whole])
        )
    idx = [header.index(c) for c in names]
    sd_idx = [header.index(STD_PREFIX + c) if STD_PREFIX + c in header else -1 for c in names]
    sd: list[list[float]] = []
    t_idx = header.index("t")
    if not body:
        raise InputError(
            f"{p}: line {table.first_data_line - 1}: the header has no data rows after it"
        )
    s_idx = header.index("status") if "status" in header else None
    o_idx = header.index("outlier") if "outlier" in header else None
    flags: list[bool] = []
    t: list[float] = []
    out: list[list[float]] = []
    status: list[str] = []
    lines: list[int] = []
    for line, row in body:
        if len(row) < len(header):
            raise InputError(
                f"{p}: line {line}: expected {len(header)} fields, found {len(row)} (truncated?)"
            )
        if has_extra_fields(row, len(header)):
            raise InputError(
                f"{p}: line {line}: expected {len(header)} fields, found {len(row)} (an extra "
                "field or separator?)"
            )
        st = row[s_idx] if s_idx is not None else "ok"
        if st not in STATUS_MEANINGS:
            known = ", ".join(STATUS_MEANINGS)
            raise InputError(f"{p}: line {line}: status {st!r} is not one of {known}")
        tv = parse_float(p, line, table.as_written("t"), row[t_idx]) * table.time_scale
        vals = [
            math.nan
            if (row[j] == "" and (st == Status.NO_ESTIMATE or gaps))
            else parse_float(p, line, table.as_written(c), row[j])
            for c, j in zip(names, idx)
        ]
        finite = [tv, *(v for v in vals if not (gaps and math.isnan(v)))]
        if st != "no-estimate" and not all(map(math.isfinite, finite)):
            cells = zip(("t", *names), (row[t_idx], *(row[j] for j in idx)), (tv, *vals))
            col, text = next(  # (not a gap: a value left out where gaps are allowed)
                (c, x)
                for c, x, v in cells
                if not math.isfinite(v) and not (gaps and c != "t" and math.isnan(v))
            )
            if not gaps:
                rule = "every row needs a finite value in each column"
            elif col == "t":
                rule = "every row needs a finite time"
            else:  # an infinity: a gap is an empty cell
                rule = "leave the cell empty (or nan) for a value not measured"
            raise InputError(
                f"{p}: line {line}: column {table.as_written(col)} is {shorten(text) or 'empty'} "
                f"({rule})"
            )
        sd.append(
            [
                math.nan if j < 0 or row[j] == "" else _parse_std(p, line, c, row[j])
                for c, j in zip(names, sd_idx)
            ]
        )
        if t and tv <= t[-1]:
            raise InputError(
                f"{p}: line {line}: t={time_text(tv)} does not increase (previous "
                f"t={time_text(t[-1])})"
            )
        if o_idx is not None:
            if row[o_idx] not in ("0", "1"):
                raise InputError(f"{p}: line {line}: outlier must be 0 or 1, got {row[o_idx]!r}")
            flags.append(row[o_idx] == "1")
        t.append(tv)
        out.append(vals)
        status.append(st)
        lines.append(line)
    values = np.array(out, dtype=float).reshape(len(t), len(names))
    beyond = np.argwhere(np.abs(values) > STATE_LIMIT)  # squares would overflow the metrics
    if len(beyond):
        i, j = beyond[0]
        raise InputError(
            f"{p}: line {lines[i]}: {names[j]}={values[i, j]:.6g} out of range (|value| <= "
            f"{STATE_LIMIT:g} in m, rad and N)"
        )
    turned = angle_beyond_a_turn(names, values)
    if turned is not None:
        raise InputError(f"{p}: line {lines[turned[0]]}: {turned[1]}")
    held = [names.index(c) for c in required]
    if gaps and held and not np.all(np.isfinite(values[:, held]), axis=1).any():
        raise InputError(
            f"{p}: no row has a value in each of {', '.join(required)} (every row a gap)"
        )
    if table.cut.line is not None:  # read as written: its last value may be cut short
        warn_cut_line(p, table.cut.line)
    std = np.array(sd, dtype=float).reshape(len(t), len(names))
    if gaps:  # a column without any value (an angle the capture does not give) is absent
        some = [j for j in range(len(names)) if np.isfinite(values[:, j]).any()]
        names, values, std = tuple(names[j] for j in some), values[:, some], std[:, some]
    return StateTable(
        np.array(t), names, values,
        np.array(status, dtype=str), std,
        None if o_idx is None else np.array(flags, dtype=bool), any(j >= 0 for j in sd_idx),
        s_idx is not None,
    )  # fmt: skip


#: The per-section columns of a state table: ``theta, phi`` (one section), or
#: ``theta_k, phi_k, x_k, y_k, z_k``.
SECTION_FIELDS = ("theta", "phi", "x", "y", "z")


def _is_output_column(name: str) -> bool:
    """Whether ``name`` is an estimate's output column: the tip's position or force, a
    section's column, a twist ``psi_k`` or a tension gain ``tension_gain_k``."""
    base, _, k = name.rpartition("_")
    return (
        name in (*TIP_COLUMNS, *TIP_FORCE_COLUMNS)
        or _is_section_column(name)
        or (base in ("psi", "tension_gain") and k.isdigit())
    )


def _is_section_column(name: str) -> bool:
    base, _, k = name.rpartition("_")
    return name in ("theta", "phi") or (base in SECTION_FIELDS and k.isdigit())


def robot_misfit(names: Sequence[str], robot: Robot, complete: bool) -> str:
    """``""`` when a state table's per-section columns fit ``robot``'s outputs, else
    what does not (``missing theta_3; extra theta``). ``complete``: every output must be
    there (an estimate, as ``estimate`` writes it); else any subset (a truth). A tendon
    robot's (a ``[backbone]``) are its mechanics model's (``theta_k`` even for one
    section, and each section's twist ``psi_k``)."""
    outputs = output_names(robot_outputs(robot))
    extra = [n for n in names if _is_section_column(n) and n not in outputs]
    missing = [n for n in outputs if n not in names] if complete else []
    if not (extra or missing):
        return ""
    parts = [
        f"{what} {', '.join([n for n in cols if n.startswith('theta')] or cols)}"
        for what, cols in (("missing", missing), ("extra", extra))
        if cols
    ]  # a section named by its theta column, where there is one
    has = [n for n in names if n.startswith("theta")]
    return (
        f"its columns ({', '.join(has) or 'no theta'}) do not fit the robot "
        f"({robot.describe()}): {'; '.join(parts)}"
    )


def check_estimate_fits(path: str | os.PathLike[str], names: Sequence[str], robot: Robot) -> None:
    """A one-line :class:`InputError` unless an estimate CSV's columns are ``robot``'s
    outputs (estimated on another robot, or ``--robot`` forgotten)."""
    misfit = robot_misfit(names, robot, complete=True)
    if misfit:
        raise InputError(f"{path}: {misfit}; pass --robot with the robot it was estimated on")


def check_same_robot(
    estimates: str | os.PathLike[str], estimate: StateTable,
    truth: str | os.PathLike[str], truth_table: StateTable, robot: Robot,
) -> str:  # fmt: skip
    """``evaluate``'s check that the estimate and the truth are of ``robot``: an estimate
    with section columns of another robot is a one-line :class:`InputError` (one with the
    tip only passes); a truth with columns of another robot, or one whose section ``k``
    ends at its tip where the robot has more sections (:func:`tip_section`), gives the
    warning returned (``""`` when it fits: any other subset of the robot's columns
    does)."""
    if any(_is_section_column(n) for n in estimate.names):
        check_estimate_fits(estimates, estimate.names, robot)
    misfit = robot_misfit(truth_table.names, robot, complete=False)
    if not misfit:
        ends = tip_section(truth_table)
        if ends is None or ends >= robot.n_sections:
            return ""
        misfit = (
            f"section {ends}'s end is its tip in every row: a robot of {ends} section(s), "
            f"not {robot.n_sections}"
        )
    return f"{truth}: {misfit}: the truth is of another robot (pass --robot with its robot)"


#: The largest distance, m, between a section's end and the tip in every row of a file
#: for that section to be the file's last (rounding of the written digits only).
TIP_SECTION_TOLERANCE = 1e-6


def tip_section(table: StateTable) -> int | None:
    """The first section ``k`` (1-based) whose end (``x_k, y_k, z_k``) is the file's tip
    (``x, y, z``) in every row that has both, within :data:`TIP_SECTION_TOLERANCE`: the
    last section of the robot the file was made for; None where no section's is (or
    none is given). A truth of a robot of fewer sections fits a subset of another
    robot's columns, and this tells it apart."""
    names = list(table.names)
    if not all(c in names for c in TIP_COLUMNS):
        return None
    tip = table.values[:, [names.index(c) for c in TIP_COLUMNS]]
    for k in sections_with_ends(names):  # a truth may have some sections' ends, not others'
        end = table.values[:, [names.index(c) for c in section_end_columns(k)]]
        both = np.all(np.isfinite(tip), axis=1) & np.all(np.isfinite(end), axis=1)
        if both.any() and np.abs(end[both] - tip[both]).max() <= TIP_SECTION_TOLERANCE:
            return k
    return None


def misspelt_columns(names: Sequence[str], outputs: Sequence[str]) -> str:
    """``""``, or a line naming each column of ``names`` that is none of ``outputs`` but
    one letter off one of them that ``names`` lacks (``xx_2 for x_2``): a typo in a
    truth's header leaves that column out of the comparison."""
    lacking = [o for o in outputs if o not in names]
    pairs = []
    for n in names:
        if n in outputs:
            continue
        close = next((o for o in lacking if _edit_distance_one(n, o)), None)
        if close is not None:
            pairs.append(f"{n} for {close}")
    if not pairs:
        return ""
    return f"column(s) {', '.join(pairs)}? (a typo: such a column is left out)"


def _edit_distance_one(a: str, b: str) -> bool:
    """Whether ``a`` becomes ``b`` by one inserted, deleted or replaced character."""
    if abs(len(a) - len(b)) > 1:
        return False
    if len(a) == len(b):
        return sum(x != y for x, y in zip(a, b)) == 1
    short, long_ = (a, b) if len(a) < len(b) else (b, a)
    return any(long_[:i] + long_[i + 1 :] == short for i in range(len(long_)))


def _parse_std(path: str, line: int, name: str, text: str) -> float:
    v = parse_float(path, line, STD_PREFIX + name, text)
    if not (math.isfinite(v) and v >= 0):
        raise InputError(
            f"{path}: line {line}: {STD_PREFIX}{name} must be a finite number >= 0, "
            f"got {shorten(text)!r}"
        )
    return v


def read_states(path: str | os.PathLike[str]) -> tuple[FloatArray, FloatArray, NDArray[np.str_]]:
    """Read a one-section estimate or truth CSV: ``t`` (n,), states (n, 5)
    ``x, y, z, theta, phi`` with NaN where empty, and status (n,). A file of several
    sections (``theta_1``...) is refused with a pointer to :func:`read_state_table`,
    which reads any."""
    cols = STATE_COLUMNS[1:]
    try:
        table = read_state_table(path, cols)
    except InputError:  # the header read again only to say which reader fits
        with open_rows(path) as rows:
            several = "theta" not in rows.header and "theta_1" in rows.header
        if not several:
            raise
        raise InputError(
            f"{rows.name}: a robot of several sections (theta_1, ...): read it with "
            "read_state_table, which reads any estimate or truth file"
        ) from None
    values = np.column_stack([table.column(c) for c in cols])
    return table.t, values, table.status


#: The mechanics model's backbone drawn from a row's tip force and tensions ending more
#: than this share of the robot's length from the row's tip is said (a warning).
BACKBONE_MISFIT = 0.05


def model_backbone_misfit(off: float, reach: float) -> str:
    """What to say where the mechanics model's backbone at the rows' tip forces and
    tensions ends up to ``off`` (m) from their estimated tips, more than
    :data:`BACKBONE_MISFIT` of the robot's ``reach`` (m): a robot file or tensions other
    than the estimate's; ``""`` where within it."""
    if not off > BACKBONE_MISFIT * max(reach, 1e-9):
        return ""
    return (
        "the mechanics model's backbone at the estimate's tip force and the tensions ends "
        f"up to {off * 1e3:.0f} mm from the estimated tip in the rows drawn: are --robot "
        "and --inputs those of the estimate?"
    )
