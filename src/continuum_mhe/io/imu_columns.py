"""The IMUs' columns of a recording's header: which IMUs it has (numbered from 1 in
the robot file's order) and the suffix each IMU's columns carry, with one-line errors
for numbering, count and typing mistakes."""

from __future__ import annotations

import difflib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from continuum_mhe.errors import InputError
from continuum_mhe.io.text_rows import TextRows, column_indices

#: The fix named when a file's IMU count is not the robot's (``{found}``: the file's).
ROBOT_FIX = "pass --robot FILE with a robot file of {found} IMU(s)"
#: The same for a tendon robot, whose file a robot of one section without it is not.
TENDON_ROBOT_FIX = (
    "pass --robot FILE with a tendon robot file of {found} IMU(s) (its [[imu]] entries; "
    "docs/tendon.md)"
)
#: The same for :func:`~continuum_mhe.io.csv_files.read_measurements`, called from Python
#: and from ``calibrate``.
READER_FIX = "pass the robot of {found} IMU(s) (--robot FILE; n_imus={found} in Python)"
#: Added to a fix naming ``--robot`` when the file has one IMU.
ONE_IMU_FIX = ", or leave --robot out: one section with its IMU at the tip needs no robot file"


def numbered_imus(rows: TextRows, fields: Sequence[str]) -> int:
    """The highest IMU number ``k`` of a ``<field>_k`` column in the header (0: none).
    IMUs are numbered from 1, as in the robot file: a ``<field>_0`` column is a one-line
    error saying so (never read as another IMU count)."""
    numbers = {
        h: int(number)
        for h in rows.header
        for base, _, number in [h.rpartition("_")]
        if base in fields and number.isdigit()
    }
    zero = [h for h, k in numbers.items() if k == 0]
    if zero:
        first = "_1, ".join(fields[:2]) + "_1"
        raise InputError(
            f"{rows.name}: line 1: column {rows.as_written(zero[0])}: IMU columns are numbered "
            f"from 1 ({first} ... for the robot file's first IMU); renumber the file's columns"
        )
    return max(numbers.values(), default=0)


def numbered_span(first: str, found: int, shown: Callable[[str], str] = str) -> str:
    """``roll_1 ... roll_3`` (``roll_1`` for one IMU), each name as ``shown`` gives it
    (:meth:`~continuum_mhe.io.text_rows.TextRows.as_written`: as the file writes it)."""
    span = shown(f"{first}_1")
    return span + (f" ... {shown(f'{first}_{found}')}" if found > 1 else "")


def imu_count_error(
    name: str, kind: str, columns: str, found: int, n_imus: int, fix: str = ROBOT_FIX
) -> InputError:
    """The one-line error of a file whose ``kind`` columns (``columns``, as shown) are
    for ``found`` IMUs when the robot has ``n_imus``; ``fix`` ends it (for one IMU with
    :data:`ONE_IMU_FIX` where it names ``--robot``)."""
    more = ONE_IMU_FIX if found == 1 and fix == ROBOT_FIX else ""
    if found > n_imus and "--robot" in fix:  # a robot of some of the recording's IMUs
        more += (
            "; for a robot of fewer of them, cut the file to their columns, numbered "
            "from 1 in the robot file's order"
        )
    return InputError(
        f"{name}: line 1: the file has {kind} columns for {found} IMU(s) ({columns}) "
        f"but the robot describes {n_imus}; {fix.format(found=found)}{more}"
    )


#: An unknown header column at least this similar to a column missing from an IMU's set
#: (difflib's ratio) is named as a likely typo of it: ``ay2`` or ``ay_`` for ``ay_2`` or
#: ``ay``, ``roll_4`` or ``roll_0`` for ``roll_3`` or ``roll_1``, ``rol`` for ``roll``.
TYPO_SIMILARITY = 0.75


@dataclass(frozen=True)
class ImuColumns:
    """One IMU's columns in a sample file's header: ``fields`` (every IMU has them) and
    ``optional`` ones (a gyro's: an IMU has all or none of them), named ``<field>`` for
    the one IMU of an unnumbered file and ``<field>_k`` for IMU ``k``. ``kind`` names
    them in messages (``"raw"``); ``holds`` (``{k}``: ``""`` or ``"_k"``) says what a
    set holds where a missing column has no look-alike in the header, or is None for
    :func:`~continuum_mhe.io.text_rows.column_indices`' message (with the header)."""

    kind: str
    fields: tuple[str, ...]
    optional: tuple[str, ...] = ()
    holds: str | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return (*self.fields, *self.optional)

    def number(self, column: str) -> tuple[str, int]:
        """``("ax", 2)`` for the numbered column ``ax_2``; ``("", -1)`` for any other."""
        base, _, number = column.rpartition("_")
        return (base, int(number)) if base in self.names and number.isdigit() else ("", -1)

    def numbered(self, header: Sequence[str]) -> dict[int, set[str]]:
        """The fields of each numbered IMU in the header (``ax_2`` -> ``{2: {"ax"}}``)."""
        numbers: dict[int, set[str]] = {}
        for base, k in map(self.number, header):
            if base:
                numbers.setdefault(k, set()).add(base)
        return numbers

    def whole(self, fields: set[str]) -> bool:
        """An IMU's fields are a whole set: all ``fields``, with all or none of
        ``optional``."""
        optional = fields & set(self.optional)
        return set(self.fields) <= fields and optional in (set(), set(self.optional))

    def missing(
        self, header: Sequence[str], suffixes: Sequence[str]
    ) -> tuple[dict[str, list[str]], list[str]]:
        """The columns missing from each IMU's set (``suffixes``: ``""`` for the one IMU
        of an unnumbered file, ``"_k"`` for IMU ``k``), and the header's unknown columns
        that look like typos of them (:data:`TYPO_SIMILARITY`). An IMU's set is its
        ``fields``, and its ``optional`` ones where the header has one of them or a
        look-alike. A column of another IMU's whole set is never taken for a typo."""
        whole = [k for k, fields in self.numbered(header).items() if self.whole(fields)]
        known = {c + s for s in [*suffixes, *(f"_{k}" for k in whole)] for c in self.names}
        unknown = [h for h in header if h not in known]
        most = max(len(unknown), 1)
        missing: dict[str, list[str]] = {}
        typos: list[str] = []
        for s in suffixes:
            near = {
                c + s: difflib.get_close_matches(c + s, unknown, most, TYPO_SIMILARITY)
                for c in self.names
                if c + s not in header
            }
            optional = [c + s for c in self.optional]
            wanted = [c + s for c in self.fields]
            if any(o in header or near.get(o) for o in optional):
                wanted += optional
            gone = [c for c in wanted if c not in header]
            if gone:
                missing[s] = gone
            typos += [u for c in gone for u in near[c] if u not in typos]
        return missing, typos

    def missing_error(
        self, rows: TextRows, missing: dict[str, list[str]], typos: Sequence[str]
    ) -> InputError:
        """``line 1: IMU 2 has no ay_2 column; the header has ay2 (a typo?)`` for
        :meth:`missing`' result; without look-alikes, what a set holds (:attr:`holds`)."""
        if not typos and self.holds is None:
            try:
                column_indices(rows, [c for gone in missing.values() for c in gone])
            except InputError as error:
                return error
        said: list[str] = []
        for s, gone in missing.items():
            who = f"IMU {s[1:]}" if s else "the IMU"
            cols = f"{', '.join(gone)} column{'s' if len(gone) > 1 else ''}"
            said.append(f"{who} has no {cols}" if not said else f"{who} no {cols}")
        if typos:
            guess = "a typo" if len(typos) == 1 else "typos"
            what = f"the header has {', '.join(map(rows.as_written, typos))} ({guess}?)"
            return InputError(f"{rows.name}: line 1: {', '.join(said)}; {what}")
        k = "" if "" in missing else "_k"  # "": the one IMU of an unnumbered file
        holds = str(self.holds).format(k=k)
        return InputError(f"{rows.name}: line 1: {', '.join(said)} ({holds})")


def _beyond_error(
    rows: TextRows, columns: ImuColumns, sets: dict[int, set[str]], n_imus: int
) -> InputError:
    """``line 1: roll_9 is a column of IMU 9, but the robot describes 2 IMU(s) ...``:
    the header holds the robot's IMUs' whole sets and columns of IMUs beyond them."""
    beyond = sorted(k for k in sets if k > n_imus)
    shown = [rows.as_written(f"{c}_{k}") for k in beyond for c in columns.names if c in sets[k]]
    listed = ", ".join(shown[:4]) + (f" and {len(shown) - 4} more" if len(shown) > 4 else "")
    imus = ", ".join(map(str, beyond[:4])) + (" ..." if len(beyond) > 4 else "")
    which = f"IMU{'s' if len(beyond) > 1 else ''} {imus}"
    return InputError(
        f"{rows.name}: line 1: {listed} {'is a column' if len(shown) == 1 else 'are columns'} "
        f"of {which}, but the robot describes {n_imus} IMU(s), whose columns the header "
        f"holds: remove {'it' if len(shown) == 1 else 'them'}, or describe every IMU in "
        "the robot ([[imu]] entries, numbered from 1 in their order)"
    )


#: The tilt columns of an IMU: ``roll, pitch`` (``roll_k, pitch_k`` for IMU ``k``).
TILT_IMU_COLUMNS = ImuColumns("tilt", ("roll", "pitch"))


def imu_suffixes(
    rows: TextRows, n_imus: int, columns: ImuColumns, fix: str = ROBOT_FIX
) -> list[str]:
    """The suffix of each of ``n_imus`` IMUs' columns in the header: ``[""]`` for one
    IMU's unnumbered columns, else ``["_1", ..., "_n"]``.

    A header with a column missing from an IMU's set is a one-line error naming it and
    the columns that look like a typo of it (:meth:`ImuColumns.missing`); one whose
    columns are whole sets for another number of IMUs, an error naming both counts
    (:func:`imu_count_error`, ending in ``fix``); ``<field>_0`` columns, an error saying
    IMUs are numbered from 1 (:func:`numbered_imus`)."""
    header = rows.header
    if all(f"{c}_0" in header for c in columns.fields):
        numbered_imus(rows, columns.names)  # raises: IMUs are numbered from 1
    sets = columns.numbered(header)
    numbers = [k for k in sets if k > 0]
    plain = any(c in header for c in columns.names)  # unnumbered columns
    numbered_whole = [k for k, f in sets.items() if k > 0 and columns.whole(f)]
    if numbered_whole and columns.whole({c for c in columns.names if c in header}):
        both = ", ".join(map(rows.as_written, columns.fields))
        other = ", ".join(rows.as_written(f"{c}_{numbered_whole[0]}") for c in columns.fields)
        raise InputError(
            f"{rows.name}: line 1: the header has both {both} and {other}: which are the "
            "IMU's readings? keep one set of columns per IMU (numbered from 1 where the "
            "robot has several)"
        )
    # no IMU column at all: the robot's own count, numbered where it has several IMUs
    unnumbered = (not numbers and (plain or n_imus == 1)) or (
        n_imus == 1 and plain and not any(columns.whole(f) for k, f in sets.items() if k > 0)
    )
    found = 1 if unnumbered else max(numbers, default=n_imus)

    def suffixes(count: int) -> list[str]:
        return [""] if unnumbered else [f"_{k}" for k in range(1, count + 1)]

    missing, typos = columns.missing(header, suffixes(n_imus))
    if found != n_imus and not typos:
        # whole sets of ``found`` IMUs fit in the header (else its count implies sets the
        # header cannot hold, and listing them, or their look-alikes, takes as long as
        # that number says)
        own: tuple[dict[str, list[str]], list[str]] = ({}, [])
        if found * len(columns.fields) <= len(header):
            own = columns.missing(header, suffixes(found))  # the file's sets, for its count
            if not own[0]:
                shown = (
                    ", ".join(map(rows.as_written, columns.fields))
                    if unnumbered
                    else numbered_span(columns.fields[0], found, rows.as_written)
                )
                raise imu_count_error(rows.name, columns.kind, shown, found, n_imus, fix)
        if not missing and own[1]:  # whole sets for the robot, a typo in one beyond it
            missing, typos = own
        elif not missing:  # whole sets for the robot, columns of IMUs beyond it
            raise _beyond_error(rows, columns, sets, n_imus)
    whole = sorted(k for k, f in sets.items() if k > 0 and columns.whole(f))
    by_section = (  # whole sets, none broken, no typo: numbered otherwise than 1..n
        missing and not typos and len(whole) == n_imus == len(numbers)
        and whole != list(range(1, n_imus + 1))
    )  # fmt: skip
    if by_section:
        shown = ", ".join(rows.as_written(f"{columns.fields[0]}_{k}") for k in whole)
        first = columns.fields[0]
        want = f"1 to {n_imus}" if n_imus > 1 else f"1 ({first}_1..., or {first}... unnumbered)"
        raise InputError(
            f"{rows.name}: line 1: the header's IMU columns are numbered {shown}, but IMUs "
            f"are numbered in the robot file's [[imu]] order, not by section: name them {want}"
        )
    if missing:
        raise columns.missing_error(rows, missing, typos)
    numbered_imus(rows, columns.names)  # a stray roll_0 beside whole sets: numbered from 1
    return suffixes(n_imus)
