"""Robot files (TOML): the sections, the IMUs and the base mounting.

Format (every key but ``length`` is optional)::

    mounting = "z-up"          # base mounting: "z-up" (default) or "z-down"
    [[section]]
    length = 0.16              # m
    theta_max = 3.0            # rad, default 3.0 (172 deg: a bound the robot never reaches)
    [[section]]
    length = 0.14
    [[imu]]
    section = 1                # 1-based, from the base
    at = 1.0                   # fraction of the section's length, default 1.0 (its end)
    mount_rpy = [0, 0, 0]      # sensor mounting roll, pitch, yaw in degrees, default 0
                               # (rotates raw readings; tilt input is used as it is)
    gyro_bias = [0, 0, 0]      # gyro bias at rest, rad/s, sensor frame, default 0
                               # (subtracted from raw gyro readings)
    accel_range = 19.61        # accelerometer full scale, m/s^2 (+-2 g), optional
    gyro_range = 4.363         # gyro full scale, rad/s (+-250 deg/s), optional
                               # (a raw reading at either is clipped: skipped)
    [[imu]]
    section = 2

A tendon-driven robot adds its backbone's material, the spacer disks of each section
and its tendons (:mod:`continuum_mhe.model.tendon`)::

    tendon_route = "disks"     # optional: tendons straight from disk to disk (default
                               # "continuous": along the backbone, Rucker and Webster)
    [backbone]
    youngs_modulus = 54e9      # Pa
    shear_modulus = 20.77e9    # Pa
    radius = 0.0007            # m, a solid round rod
    density = 6450             # kg/m^3, optional (without it the robot is weightless)
    [[section]]
    length = 0.2
    disks = 10                 # evenly spaced, the last one at the section's end
    [[tendon]]
    section = 1                # anchored at the end of this section
    angle = 90                 # deg, around the backbone from the disk frame's x axis
    radius = 0.01              # m from the backbone
    [[imu]]
    section = 1
    disk = 5                   # at a disk instead of ``at`` (at = disk / disks)

The tensions file's columns follow the ``[[tendon]]`` order. Tendons without a
``[backbone]`` are refused.

Without ``[[imu]]`` entries a robot file is refused (a robot needs a sensor). Every
problem gives :class:`~continuum_mhe.errors.InputError` naming the file and key.
The IMUs are numbered in the file's order, and the measurement columns follow it
(``roll_1, pitch_1`` are the first ``[[imu]]``'s): IMUs listed out of base-to-tip order
(by section, then ``at``), or one place listed twice, give a
:class:`RobotFileWarning`; an ``at`` that equals its section's length in m (``at =
0.18`` on a 0.18 m section: metres?) or a ``mount_rpy`` that looks like radians
(:func:`~continuum_mhe.model.robot.mount_rpy_hint`) a
:class:`~continuum_mhe.io.csv_files.UnitWarning`.
"""

from __future__ import annotations

import datetime
import difflib
import math
import os
import re
import shlex
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from continuum_mhe.errors import FieldError, InputError, UserError, expect_type
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.io.text_rows import not_utf8_problem, shorten, utf16_encoding
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.robot import (
    DEFAULT_THETA_MAX,
    GYRO_BIAS_LIKE_DEG,
    MAX_MOUNT_DEG,
    RADIAN_TOLERANCE,
    TENDON_ROUTES,
    Backbone,
    ImuPlacement,
    Robot,
    Section,
    Tendon,
    at_in_metres,
    full_scale_problem,
    long_section_hint,
    misplaced_imus,
    mount_rpy_hint,
    slips_said,
)
from continuum_mhe.model.settings import RobotSettings

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

_TOP_KEYS = {"mounting", "section", "imu", "backbone", "tendon", "tendon_route"}
_SECTION_KEYS = {"length", "theta_max", "disks"}
_IMU_KEYS = {"section", "at", "disk", "mount_rpy", "gyro_bias", "accel_range", "gyro_range"}
_BACKBONE_KEYS = {"youngs_modulus", "shear_modulus", "radius", "density"}
_TENDON_KEYS = {"section", "angle", "radius"}


class RobotFileWarning(UserWarning):
    """A robot-file entry that is valid but likely a slip (IMUs out of base order, two
    IMUs at one place, a backbone without its density)."""


def _place(imu: ImuPlacement) -> str:
    return f"section {imu.section + 1}, at {imu.at:g}"


def warn_imu_order(path: Path, imus: Sequence[ImuPlacement]) -> None:
    """Warn (:class:`RobotFileWarning`, one line each) where the IMUs are not listed from
    the base to the tip (by section, then ``at``), and where two are at one place: the
    measurement columns follow the file's order, so such a file usually pairs the
    columns with the wrong IMUs."""
    later, same = misplaced_imus(imus)
    if later is not None:
        warnings.warn(
            f"{path}: imu {later + 1} ({_place(imus[later])}) is nearer the base than imu "
            f"{later} ({_place(imus[later - 1])}) but listed after it: the measurement "
            "columns follow the file's order, and IMU 1 is expected nearest the base; list "
            "the [[imu]] entries from base to tip (or check that the columns follow this order)",
            RobotFileWarning,
            stacklevel=4,
        )
    if same is not None:
        warnings.warn(
            f"{path}: imu {same[0] + 1} is at the same place as imu {same[1] + 1} "
            f"({_place(imus[same[0]])}): two IMUs listed at one place (a copied entry?)",
            RobotFileWarning,
            stacklevel=4,
        )


def warn_tendon_twins(path: Path, tendons: Sequence[Tendon]) -> None:
    """Warn (:class:`RobotFileWarning`, one line) where two tendons are anchored at the
    same section, angle (modulo a turn: 360 and -120 degrees are 0 and 240) and radius:
    a copied entry, which adds a tensions column that pulls on the same path."""
    seen: dict[tuple[int, float, float], int] = {}
    for i, tendon in enumerate(tendons):
        turn = round(tendon.angle % math.tau, 9) % round(math.tau, 9)  # 2 pi - 1e-12 is 0
        key = (tendon.section, turn, round(tendon.radius, 12))
        if key in seen:
            warnings.warn(
                f"{path}: tendon {i + 1} is at the same place as tendon {seen[key] + 1} "
                f"(section {tendon.section + 1}, angle {math.degrees(tendon.angle):g} deg, "
                f"radius {tendon.radius:g} m): two tendons listed on one path (a copied "
                "entry? each adds a tensions column)",
                RobotFileWarning,
                stacklevel=4,
            )
            return
        seen[key] = i


def _shown(value: object) -> str:
    """``repr(value)`` for a message, cut short (a value may be a list of thousands); a
    TOML date or time as the file writes it (``2000-01-01``, not Python's repr)."""
    if isinstance(value, (datetime.date, datetime.time)):  # datetime is a date too
        return f"{value.isoformat()} (a TOML date or time)"
    return shorten(repr(value), 60)


def _not_whole(value: object) -> str:
    """``" (write 1, without a decimal point)"`` for a float with a whole value (TOML's
    ``1.0`` where a whole number is meant), else ``""``."""
    if isinstance(value, float) and math.isfinite(value) and value.is_integer():
        return f" (write {int(value)}, without a decimal point)"
    return ""


def _section_numbers(n: int) -> str:
    """What a ``section`` key of a robot of ``n`` sections may be, for its refusal."""
    return "1, the robot's only section" if n == 1 else f"a whole section number from 1 to {n}"


def _number(path: Path, where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{path}: {where}: expected a finite number, got {_shown(value)}")
    return float(value)


def _unknown(path: Path, where: str, table: dict[str, Any], allowed: set[str]) -> None:
    extra = sorted(set(table) - allowed)
    if extra:
        near = difflib.get_close_matches(extra[0], sorted(allowed), n=1, cutoff=0.75)
        typo = f" ({near[0]}?)" if near else ""
        if where != "top level" and extra[0] in {"mounting", "tendon_route"}:
            # TOML puts a key after a table's header into that table
            typo = " (a top-level key: write it before the file's first [table])"
        raise InputError(
            f"{path}: {where}: unknown key {_shown(extra[0])}{typo} "
            f"(allowed: {', '.join(sorted(allowed))})"
        )


def _tables(path: Path, doc: dict[str, Any], key: str) -> list[dict[str, Any]]:
    value = doc.get(key, [])
    if not isinstance(value, list) or not all(isinstance(t, dict) for t in value):
        raise InputError(f"{path}: '{key}' must be a list of tables, written [[{key}]]")
    return value


def parse_robot(doc: dict[str, Any], path: Path) -> Robot:
    """A :class:`Robot` from a parsed robot-file document (``path`` for messages)."""
    others = sorted(set(doc) - _TOP_KEYS)
    # an options file: option values and [estimate] / [live] tables, none of them a list
    # of tables as a robot file's (a mistyped [[segment]] is a robot file's key)
    robot_like = [
        k
        for k in others
        if difflib.get_close_matches(k, sorted(_TOP_KEYS), cutoff=0.75)
        or (isinstance(doc[k], list) and any(isinstance(v, dict) for v in doc[k]))
    ]
    if others and not robot_like and "section" not in doc:
        raise InputError(
            f"{path}: top level: unknown key {_shown(others[0])} and no [[section]]: not a "
            "robot file (an options file? it goes to --config)"
        )
    _unknown(path, "top level", doc, _TOP_KEYS)
    mounting = doc.get("mounting", "z-up")
    if mounting not in MOUNTINGS:
        raise InputError(
            f"{path}: mounting: must be one of {', '.join(MOUNTINGS)}, got {_shown(mounting)}"
        )
    sections: list[Section] = []
    for k, table in enumerate(_tables(path, doc, "section"), start=1):
        where = f"section {k}"
        _unknown(path, where, table, _SECTION_KEYS)
        if "length" not in table:
            raise InputError(f"{path}: {where}: missing key 'length' (m)")
        length = _number(path, f"{where}: length", table["length"])
        theta_max = _number(path, f"{where}: theta_max", table.get("theta_max", DEFAULT_THETA_MAX))
        disks = table.get("disks", 0)
        if isinstance(disks, bool) or not isinstance(disks, int) or disks < 0:
            raise InputError(
                f"{path}: {where}: disks must be a whole number of spacer disks >= 0, got {disks!r}"
            )
        try:
            sections.append(Section(length, theta_max, disks))
        except FieldError as exc:
            # the key the problem is with, first, so that the message names its line
            named = "" if str(exc).startswith(exc.field) else f"{exc.field}: "
            raise InputError(f"{path}: {where}: {named}{exc}") from None
        if hint := long_section_hint(length):
            warnings.warn(f"{path}: {where}: {hint}", RobotFileWarning, stacklevel=3)
    if not sections:
        raise InputError(f"{path}: no [[section]]: a robot needs at least one section")
    imus: list[ImuPlacement] = []
    for i, table in enumerate(_tables(path, doc, "imu"), start=1):
        where = f"imu {i}"
        _unknown(path, where, table, _IMU_KEYS)
        if "section" not in table:
            raise InputError(f"{path}: {where}: missing key 'section' (1-based section number)")
        sec = table["section"]
        if isinstance(sec, bool) or not isinstance(sec, int) or not 1 <= sec <= len(sections):
            raise InputError(
                f"{path}: {where}: section must be {_section_numbers(len(sections))}, got "
                f"{_shown(sec)}{_not_whole(sec)}"
            )
        at = _number(path, f"{where}: at", table.get("at", 1.0))
        if "disk" in table:
            at = _disk_place(path, where, table, sections[sec - 1], sec)
        if not 0 < at <= 1:
            raise InputError(
                f"{path}: {where}: at must lie in (0, 1] (fraction of the section), got {at!r}"
            )
        if "at" in table and at_in_metres(at, sections[sec - 1].length):
            warnings.warn(
                f"{path}: {where}: at is a fraction of the section's length; {at:g} equals "
                f"section {sec}'s length in m: metres? (at = 1 is its end, 0.5 its middle)",
                UnitWarning,
                stacklevel=3,
            )
        rpy = table.get("mount_rpy", [0.0, 0.0, 0.0])
        if not isinstance(rpy, list) or len(rpy) != 3:
            raise InputError(f"{path}: {where}: mount_rpy must be [roll, pitch, yaw] in degrees")
        mount = tuple(_number(path, f"{where}: mount_rpy", v) for v in rpy)
        if any(abs(v) > MAX_MOUNT_DEG for v in mount):
            raise InputError(
                f"{path}: {where}: mount_rpy must be angles in degrees within "
                f"+-{MAX_MOUNT_DEG:g}, got {_shown(rpy)}"
            )
        hint = mount_rpy_hint(mount)
        if hint:
            shown = ", ".join(f"{v:g}" for v in mount)
            warnings.warn(
                f"{path}: {where}: mount_rpy = [{shown}] is read in degrees: {hint}",
                UnitWarning,
                stacklevel=3,
            )
        bias = table.get("gyro_bias", [0.0, 0.0, 0.0])
        if not isinstance(bias, list) or len(bias) != 3:
            raise InputError(f"{path}: {where}: gyro_bias must be [gx, gy, gz] in rad/s")
        gb = tuple(_number(path, f"{where}: gyro_bias", v) for v in bias)
        if max(abs(v) for v in gb) > GYRO_BIAS_LIKE_DEG:
            shown = ", ".join(f"{v:g}" for v in gb)
            warnings.warn(
                f"{path}: {where}: gyro_bias = [{shown}] is read in rad/s: "
                f"{math.degrees(max(abs(v) for v in gb)):.0f} deg/s is no MEMS gyro's bias at "
                "rest: deg/s? (calibrate writes rad/s)",
                UnitWarning,
                stacklevel=3,
            )
        ranges = {}
        for key in ("accel_range", "gyro_range"):
            if key in table:
                if problem := full_scale_problem(key, table[key]):
                    raise InputError(f"{path}: {where}: {problem}")
                ranges[key] = float(table[key])
        try:
            imus.append(
                ImuPlacement(
                    sec - 1, at, (mount[0], mount[1], mount[2]), (gb[0], gb[1], gb[2]), **ranges
                )
            )
        except ValueError as exc:
            raise InputError(f"{path}: {where}: {exc}") from None
    if not imus:
        raise InputError(f"{path}: no [[imu]]: a robot needs at least one IMU")
    warn_imu_order(path, imus)
    backbone = _backbone(path, doc)
    tendons = _tendons(path, doc, len(sections))
    warn_tendon_twins(path, tendons)
    if tendons and backbone is None:
        raise InputError(
            f"{path}: {len(tendons)} [[tendon]] but no [backbone]: a tendon-driven robot needs "
            "its backbone's material (youngs_modulus, shear_modulus, radius)"
        )
    route = doc.get("tendon_route", "continuous")
    if route not in TENDON_ROUTES:
        raise InputError(
            f"{path}: tendon_route: must be one of {', '.join(TENDON_ROUTES)}, got {_shown(route)}"
        )
    try:
        robot = Robot(tuple(sections), tuple(imus), mounting, backbone, tuple(tendons), route)
    except UserError as exc:
        raise InputError(f"{path}: {exc}") from None
    slips_said(robot)  # said above with the file's lines
    return robot


def _disk_place(path: Path, where: str, table: dict[str, Any], section: Section, sec: int) -> float:
    """``at`` of an IMU placed at a disk (``disk = d``: ``d / disks``)."""
    if "at" in table:
        raise InputError(f"{path}: {where}: give at or disk, not both")
    disk = table["disk"]
    if section.disks == 0:
        raise InputError(f"{path}: {where}: disk given, but section {sec} has no disks")
    if isinstance(disk, bool) or not isinstance(disk, int) or not 1 <= disk <= section.disks:
        raise InputError(
            f"{path}: {where}: disk must be a disk number from 1 to {section.disks} "
            f"(section {sec}'s disks), got {disk!r}"
        )
    return disk / section.disks


def _backbone(path: Path, doc: dict[str, Any]) -> Backbone | None:
    table = doc.get("backbone")
    if table is None:
        return None
    if not isinstance(table, dict):
        raise InputError(f"{path}: 'backbone' must be a table, written [backbone]")
    _unknown(path, "backbone", table, _BACKBONE_KEYS)
    for key in ("youngs_modulus", "shear_modulus", "radius"):
        if key not in table:
            raise InputError(f"{path}: backbone: missing key {key!r}")
    values = {k: _number(path, f"backbone: {k}", v) for k, v in table.items()}
    if "density" not in values:
        warnings.warn(
            f"{path}: backbone: no density: the backbone is modelled weightless, and its "
            "weight is read as a tip force (the shipped tendon robot free of load: 0.02 N of "
            "force and 1.1 mm at the tip instead of 0.10 mm); give its density in kg/m^3 "
            "(nitinol 6450, spring steel 7850)",
            RobotFileWarning,
            stacklevel=3,
        )
    try:
        return Backbone(
            values["youngs_modulus"],
            values["shear_modulus"],
            values["radius"],
            values.get("density"),
        )
    except UserError as exc:
        raise InputError(f"{path}: {exc}") from None


def _tendons(path: Path, doc: dict[str, Any], n_sections: int) -> list[Tendon]:
    tendons = []
    for i, table in enumerate(_tables(path, doc, "tendon"), start=1):
        where = f"tendon {i}"
        _unknown(path, where, table, _TENDON_KEYS)
        for key in ("section", "angle", "radius"):
            if key not in table:
                raise InputError(f"{path}: {where}: missing key {key!r}")
        sec = table["section"]
        if isinstance(sec, bool) or not isinstance(sec, int) or not 1 <= sec <= n_sections:
            raise InputError(
                f"{path}: {where}: section must be {_section_numbers(n_sections)}, got "
                f"{_shown(sec)}{_not_whole(sec)}"
            )
        angle = _number(path, f"{where}: angle", table["angle"])
        if not abs(angle) <= 360:
            raise InputError(
                f"{path}: {where}: angle must be in degrees within +-360, got {angle!r}"
            )
        radius = _number(path, f"{where}: radius", table["radius"])
        try:
            tendons.append(Tendon(sec - 1, math.radians(angle), radius))
        except UserError as exc:  # the radius (the angle is checked above): its line
            raise InputError(f"{path}: {where}: radius = {table['radius']!r}: {exc}") from None
    degrees = [math.degrees(t.angle) for t in tendons]
    if angles_look_like_radians(degrees):
        shown = ", ".join(f"{v:g}" for v in degrees)
        warnings.warn(
            f"{path}: the tendons' angles [{shown}] are read in degrees, but all lie "
            "within 2 pi and are not whole degrees: radians? (angle = 90 is a quarter turn)",
            UnitWarning,
            stacklevel=3,
        )
    elif huddled := huddled_tendons(tendons):
        section, spread = huddled
        shown = ", ".join(f"{math.degrees(t.angle):g}" for t in tendons if t.section == section)
        warnings.warn(
            f"{path}: the tendons anchored at section {section + 1}'s end (angles [{shown}], "
            f"read in degrees) lie within {spread:.3g} degrees of each other around the "
            "backbone, where tendons are spread to bend it every way: radians? (angle = 90 "
            "is a quarter turn)",
            UnitWarning,
            stacklevel=3,
        )
    else:
        for i in angles_among_degrees_like_radians(degrees):
            warnings.warn(
                f"{path}: tendon {i + 1}: angle = {degrees[i]:g} is read in degrees, beside "
                f"other tendons' angles beyond 2 pi: radians? ({degrees[i]:g} rad is "
                f"{math.degrees(degrees[i]):.4g} degrees)",
                UnitWarning,
                stacklevel=3,
            )
    return tendons


#: Tendons anchored at one section's end whose angles all lie within this many degrees of
#: each other (2 pi, the span of whole radians read as degrees) are
#: :func:`huddled_tendons`.
HUDDLED_SPREAD_DEG = 2 * math.pi


def huddled_tendons(tendons: list[Tendon]) -> tuple[int, float] | None:
    """The first section (from 0) whose two or more tendons' angles all lie within
    :data:`HUDDLED_SPREAD_DEG` of each other around the backbone, and that spread in
    degrees (the smallest arc holding them), or None: angles in radians read as degrees
    (0, 2, 4), or the same angle given to every tendon."""
    for section in sorted({t.section for t in tendons}):
        angles = sorted(math.degrees(t.angle) % 360.0 for t in tendons if t.section == section)
        if len(angles) < 2:
            continue
        gaps = [b - a for a, b in zip(angles, angles[1:])] + [angles[0] + 360.0 - angles[-1]]
        spread = 360.0 - max(gaps)
        if spread <= HUDDLED_SPREAD_DEG + 1e-9:
            return section, spread
    return None


#: Within how many degrees of a multiple of 15 degrees an angle read as radians must lie
#: for :func:`angles_among_degrees_like_radians` (2 pi / 3 written as 2.094 is 119.98).
RADIANS_LAYOUT_TOL_DEG = 0.3


def angles_look_like_radians(degrees: list[float]) -> bool:
    """Whether tendon angles given in degrees look like radians: two or more, all within
    ``2 pi`` in magnitude, one of them nonzero and not a whole number of degrees (the
    angles of tendons are spread around the backbone, so in degrees some exceed 2 pi);
    one alone where it is a quarter or eighth turn in radians (:func:`mount_rpy_hint`'s
    rule: 1.5708, 0.7854, 3.1416 ...)."""
    if len(degrees) == 1:
        return bool(mount_rpy_hint(degrees))
    return (
        len(degrees) >= 2
        and all(abs(v) <= 2 * math.pi + 1e-9 for v in degrees)
        and any(abs(v - round(v)) > 1e-6 for v in degrees)
    )


def angles_among_degrees_like_radians(degrees: list[float]) -> list[int]:
    """The indices of tendon angles (in degrees) that look like radians beside others
    that do not: where some angle exceeds ``2 pi`` in magnitude (degrees), one within
    ``2 pi``, nonzero, not a whole number of degrees, which read in radians lies within
    :data:`RADIANS_LAYOUT_TOL_DEG` of a multiple of 15 degrees (the angles tendons are
    laid out at: 4.712 is 270 degrees)."""
    if not any(abs(v) > 2 * math.pi + 1e-9 for v in degrees):
        return []
    out = []
    for i, v in enumerate(degrees):
        if 0 < abs(v) <= 2 * math.pi and abs(v - round(v)) > 1e-6:
            as_deg = math.degrees(v)
            if abs(as_deg - 15.0 * round(as_deg / 15.0)) <= RADIANS_LAYOUT_TOL_DEG:
                out.append(i)
    return out


#: where tomllib's messages say the problem is: "(at line N, column C)"
_TOML_AT = re.compile(r"\s*\(at line (\d+), column (\d+)\)$")


def toml_error_line(
    path: object,
    exc: tomllib.TOMLDecodeError,
    first_line: int = 1,
    first_column: int = 1,
    text: str | None = None,
) -> str:
    """The one-line error of a TOML file that does not parse, in the form of every other
    input error: ``PATH: line N: not valid TOML: PROBLEM (column C)``; ``first_line`` and
    ``first_column``: where the parsed text starts in the file (an options line in a
    CSV's comment: its line, and its column after the ``#``); ``text``: the parsed text,
    whose last line a problem "at end of document" names (else no line)."""
    msg = str(exc)
    at = _TOML_AT.search(msg)
    if at is None:  # "(at end of document)"
        if text is None or not text.strip():
            return f"{path}: not valid TOML: {shorten(msg, 200)}"
        last = first_line + len(text.rstrip("\n").splitlines()) - 1
        return f"{path}: line {last}: not valid TOML: {shorten(msg, 200)}"
    line, problem = int(at.group(1)) + first_line - 1, shorten(msg[: at.start()], 200)
    column = int(at.group(2)) + (first_column - 1 if at.group(1) == "1" else 0)
    return f"{path}: line {line}: not valid TOML: {problem} (column {column})"


def shipped_robots(tendons: bool = True) -> dict[str, Path]:
    """Robot files shipped with the package, by name (``two-section``...); without
    ``tendons``, only those of constant-curvature robots (no ``[[tendon]]``)."""
    folder = Path(__file__).parents[1] / "data" / "robots"
    found = {f.stem.replace("_", "-"): f for f in sorted(folder.glob("*.toml"))}
    if tendons:
        return found
    return {name: f for name, f in found.items() if not read_robot(f).tendons}


def _single_table_hint(text: str) -> str:
    """Where a list of tables (``[[imu]]``, ``[[section]]``, ``[[tendon]]``) is also
    written with single brackets, which TOML reads as one table and refuses where the
    list follows: ``; line N: [imu] ...``; else ``""``."""
    lines = text.splitlines()
    for name in ("section", "imu", "tendon"):
        one = re.compile(rf"\s*\[\s*{name}\s*\]\s*(#.*)?")
        single = [i for i, ln in enumerate(lines, 1) if one.fullmatch(ln)]
        listed = re.compile(rf"\s*\[\[\s*{name}\s*\]\]\s*(#.*)?")
        if single and any(listed.fullmatch(ln) for ln in lines):
            return (
                f"; line {single[0]}: [{name}] is one table, and every {name} is a "
                f"[[{name}]] (double brackets)"
            )
    return ""


def _not_utf8(path: Path, raw: bytes, start: int) -> str:
    """The one line of a robot file whose bytes ``raw`` are no UTF-8 from byte ``start``
    (from 0, after a UTF-8 byte-order mark, as the decoder counts): UTF-16 text named
    as such, else its line, the byte (counted after the mark, as in a CSV file) and the
    fix."""
    first_line = raw.split(b"\n", 1)[0]
    if encoding := utf16_encoding(first_line):
        return (
            f"{path}: not UTF-8 text but UTF-16: save it as UTF-8 (iconv -f {encoding} -t "
            f"UTF-8 {shlex.quote(str(path))} > NEW.toml)"
        )
    data = raw[3:] if raw.startswith(b"\xef\xbb\xbf") else raw
    begin = data.rfind(b"\n", 0, start) + 1
    end = data.find(b"\n", start)
    body = data[begin : len(data) if end < 0 else end].rstrip(b"\r")
    line = data.count(b"\n", 0, start) + 1
    return not_utf8_problem(str(path), line, body, start - begin, "NEW.toml")


def read_robot(path: str | os.PathLike[str]) -> Robot:
    """Read and validate a robot file (TOML), or a shipped robot by name
    (:func:`shipped_robots`, e.g. ``two-section``)."""
    expect_type("path", path, (str, os.PathLike), "a file name (str or pathlib.Path)")
    p = Path(path)
    if not p.exists() and str(path) in shipped_robots():
        p = shipped_robots()[str(path)]
    if not p.exists() or p.is_dir():  # a pipe or <(...) is read as a file
        names = ", ".join(shipped_robots())
        what = "a folder, not a robot file" if p.is_dir() else "no such robot file"
        raise InputError(f"{p}: {what} (shipped robots by name: {names})")
    try:
        raw = p.read_bytes()
        text = raw.decode("utf-8-sig")  # a byte-order mark is read, as in a CSV
        doc = tomllib.loads(text)
    except UnicodeDecodeError as exc:
        raise InputError(_not_utf8(p, raw, exc.start)) from None
    except tomllib.TOMLDecodeError as exc:
        raise InputError(toml_error_line(p, exc) + _single_table_hint(text)) from None
    except RecursionError:  # the parser recurses into nested arrays and tables
        raise InputError(f"{p}: not a robot file (nested too deeply for TOML's parser)") from None
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror})") from None
    try:
        return parse_robot(doc, p)
    except InputError as exc:
        raise InputError(_with_line(str(exc), f"{p}: ", text)) from None


#: ``section 2: length: ...``, ``imu 1: unknown key 'x' ...``, ``backbone: ...``,
#: ``top level: unknown key 'x' ...``, ``tendon_route = ...``: the table a robot-file
#: message names (none for a top-level key), then the word after it (a key, where it is
#: one); a message that starts with a quoted key (``'section' must be a list of
#: tables``) names a top-level key.
_WHERE = re.compile(
    r"(?:(section|imu|tendon) (\d+)|(backbone)|top level|(?=mounting|tendon_route)|(?='))"
    r"(?::\s*|\s+)?'?(\w*)"
)
_UNKNOWN_KEY = re.compile(r"unknown key '([^']+)'")
_TABLE_HEADER = re.compile(r"\s*\[")


def _with_line(message: str, prefix: str, text: str) -> str:
    """``message`` (``prefix`` + the problem) with the robot file's line of the table or
    key it names (``PATH: line N: section 2: ...``); unchanged where none is found. A
    top-level key is found before the first table, or as a table's header (``[[imus]]``,
    ``[extra.part]``) anywhere."""
    if not message.startswith(prefix):
        return message
    problem = message[len(prefix) :]
    m = _WHERE.match(problem)
    if m is None:
        return message
    lines = text.splitlines()
    table = m.group(1) or m.group(3)
    unknown = _UNKNOWN_KEY.search(problem)
    key = unknown.group(1) if unknown else m.group(4)
    if table is None:  # a top-level key: before the first table
        start = 0
        stop = next((i for i, ln in enumerate(lines) if _TABLE_HEADER.match(ln)), len(lines))
        if key and not any(map(_assigns(key).match, lines[start:stop])):
            header = _table_header(key)
            at = next((i for i, ln in enumerate(lines) if header.match(ln)), None)
            return message if at is None else f"{prefix}line {at + 1}: {problem}"
    else:
        k = int(m.group(2)) if m.group(2) else 1
        pattern = re.compile(rf"\s*\[\[?\s*{table}\s*\]\]?\s*(#.*)?$")
        found = [i for i, ln in enumerate(lines) if pattern.match(ln)]
        if len(found) < k:
            return message
        start = found[k - 1]
        stop = next(
            (i for i in range(start + 1, len(lines)) if _TABLE_HEADER.match(lines[i])), len(lines)
        )
    line = start
    if key:
        assign = _assigns(key)
        line = next((i for i in range(start, stop) if assign.match(lines[i])), start)
    return f"{prefix}line {line + 1}: {problem}"


def _assigns(key: str) -> re.Pattern[str]:
    """A line that sets ``key`` (``key =``, ``"key" =`` or the dotted ``key.part =``)."""
    name = re.escape(key)
    return re.compile(rf"""\s*(?:{name}|"{name}"|'{name}')\s*[=.]""")


def _table_header(key: str) -> re.Pattern[str]:
    """The header of the table ``key`` or of a table inside it: ``[key]``, ``[[key]]``,
    ``[key.part]``."""
    name = re.escape(key)
    return re.compile(rf"""\s*\[\[?\s*(?:{name}|"{name}"|'{name}')\s*[.\]]""")


def robot_toml(robot: Robot) -> str:
    """The robot file text of ``robot`` (round-trips through :func:`read_robot`)."""
    lines = [f'mounting = "{robot.mounting}"']
    if robot.tendon_route != "continuous":
        lines.append(f'tendon_route = "{robot.tendon_route}"')
    bb = robot.backbone
    if bb is not None:
        lines += ["", "[backbone]", f"youngs_modulus = {bb.youngs_modulus!r}"]
        lines += [f"shear_modulus = {bb.shear_modulus!r}", f"radius = {bb.radius!r}"]
        if bb.density is not None:
            lines.append(f"density = {bb.density!r}")
    for s in robot.sections:
        lines += ["", "[[section]]", f"length = {s.length!r}", f"theta_max = {s.theta_max!r}"]
        if s.disks:
            lines.append(f"disks = {s.disks}")
    for td in robot.tendons:
        lines += ["", "[[tendon]]", f"section = {td.section + 1}"]
        lines += [f"angle = {math.degrees(td.angle)!r}", f"radius = {td.radius!r}"]
    for imu in robot.imus:
        lines += ["", "[[imu]]", f"section = {imu.section + 1}", f"at = {imu.at!r}"]
        if any(imu.mount_rpy):
            lines.append(f"mount_rpy = {list(imu.mount_rpy)!r}")
        if any(imu.gyro_bias):
            lines.append(f"gyro_bias = {list(imu.gyro_bias)!r}")
        for key in ("accel_range", "gyro_range"):
            if (value := getattr(imu, key)) is not None:
                lines.append(f"{key} = {value!r}")
    return "\n".join(lines) + "\n"


def write_robot(path: str | os.PathLike[str], robot: Robot | RobotSettings) -> None:
    """Write ``robot`` (read from a file or built in code; a one-section
    :class:`RobotSettings` too) as the robot file ``path`` (:func:`robot_toml`), for the
    commands that take ``--robot FILE`` (``evaluate``, ``view``, ``estimate``). The file
    is written whole or not at all; a ``robot`` of another type (a robot file's name,
    None) is a :class:`UserError` naming it, before ``path`` is touched."""
    from continuum_mhe.io.output_files import atomic_writer
    from continuum_mhe.model.formulations import as_robot

    expect_type(
        "write_robot robot", robot, (Robot, RobotSettings),
        "a Robot or RobotSettings (read_robot(NAME) reads a robot file)",
    )  # fmt: skip
    text = robot_toml(as_robot(robot))
    with atomic_writer(path) as fh:
        fh.write(text)


def robot_source_text(name: str | None, robot: Robot) -> str:
    """The text of the robot file ``name`` (a path or a shipped robot's name), or, without
    one, the file of ``robot`` (:func:`robot_toml`)."""
    if not name:
        return robot_toml(robot)
    p = Path(name)
    if not p.exists() and name in shipped_robots():
        p = shipped_robots()[name]
    return p.read_text(encoding="utf-8-sig")  # a byte-order mark dropped, as read_robot does


def _written_mount_angle(degrees: float) -> float:
    """A measured mounting angle as ``calibrate`` writes it: to a thousandth of a degree
    (no -0.0), and, where that lies within :data:`RADIAN_TOLERANCE` of a quarter or
    eighth turn in radians (1.571 degrees is pi/2 rad to 0.0002), moved to the nearest
    thousandth beyond it (at most 0.002 degrees, a hundredth of a calibration's noise at
    rest), so that reading the file back does not take the measurement for a radian
    slip (:func:`~continuum_mhe.model.robot.mount_rpy_hint`)."""
    value = round(degrees, 3) + 0.0
    if not mount_rpy_hint([value]):
        return value
    quarter = math.pi / 4
    turn = round(value / quarter) * quarter
    side = 1.0 if value >= turn else -1.0
    return round(turn + side * (RADIAN_TOLERANCE + 0.0005), 3) + 0.0


def with_imu_calibration(
    text: str,
    mount_rpy: Sequence[Sequence[float]],
    gyro_bias: Sequence[Sequence[float]] | None,
    path: str | os.PathLike[str],
) -> str:
    """The robot file ``text`` with each ``[[imu]]``'s ``mount_rpy`` (degrees) and, where
    given, ``gyro_bias`` (rad/s) set, in the file's IMU order; its comments and layout
    kept (tomlkit). The result is checked as :func:`read_robot` would (``path`` names it
    in messages)."""
    import tomlkit

    doc = tomlkit.parse(text)
    imus = doc.get("imu", [])
    if len(imus) != len(mount_rpy):
        raise InputError(f"{path}: {len(imus)} [[imu]] tables, calibrated {len(mount_rpy)} IMUs")
    for i, table in enumerate(imus):
        table["mount_rpy"] = [_written_mount_angle(float(v)) for v in mount_rpy[i]]
        if gyro_bias is not None:
            table["gyro_bias"] = [round(float(v), 6) + 0.0 for v in gyro_bias[i]]
    out = tomlkit.dumps(doc)
    parse_robot(tomllib.loads(out), Path(path))
    return out
