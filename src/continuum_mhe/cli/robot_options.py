"""The robot a command estimates on: ``--robot`` (a robot file or a shipped robot's
name) or the one-section flags, and the robot an estimate file records in its options
line, for the commands that read estimates (``evaluate``, ``plot``, ``view``)."""

from __future__ import annotations

import argparse
import math
import sys
import warnings
from collections.abc import Sequence
from dataclasses import replace
from typing import cast

from continuum_mhe.cli.config import beside, recorded_option
from continuum_mhe.cli.program import PROG
from continuum_mhe.errors import InputError
from continuum_mhe.model.imu import MOUNTINGS, Mounting
from continuum_mhe.model.robot import Robot

#: One section's length (m) where neither ``--robot`` nor ``--length`` gives one.
DEFAULT_LENGTH = 0.2


def add_robot_option(
    g: argparse._ActionsContainer,
    replaces: Sequence[str] = ("--length", "--theta-max", "--mounting"),
    tendons: bool = True,
) -> None:
    """``--robot ROBOT.toml``; its help names ``replaces``, the command's one-section
    options that a robot file overrides, and, unless ``tendons`` (the command takes
    tendon robots), says that it takes constant-curvature robots and names only those
    of the shipped robots."""
    from continuum_mhe.io.robot_file import shipped_robots

    if tendons:
        names = ", ".join(shipped_robots())
        text = (
            "robot file (sections, IMUs, mounting; a tendon robot's [backbone] and "
            f"[[tendon]]: docs/tendon.md; see README), or a shipped robot's name ({names})"
        )
    else:
        names = ", ".join(shipped_robots(tendons=False))
        text = (
            "constant-curvature robot file (sections, IMUs, mounting; see README), or a "
            f"shipped one's name ({names}); a tendon robot's recordings come from "
            "continuum-mhe rod tendon"
        )
    if replaces:
        *first, last = replaces
        text += f"; replaces {', '.join(first)} and {last}" if first else f"; replaces {last}"
    g.add_argument("--robot", metavar="ROBOT.toml", type=robot_name_arg, help=text)
    # read by the options record: what a robot file sets is not recorded from the flags
    g.set_defaults(robot_replaces=tuple(o.lstrip("-").replace("-", "_") for o in replaces))


def robot_name_arg(text: str) -> str:
    """``--robot``'s value: a name, not an empty one (a shell variable left unset), which
    would be taken as no robot file at all."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "an empty name: give a robot file or a shipped robot's name (or leave --robot out)"
        )
    return text


def robot_from_args(args: argparse.Namespace) -> Robot:
    """The robot of a command: ``--robot`` file, else the one-section flags (a
    ``--length`` or ``--mounting`` of None: :data:`DEFAULT_LENGTH`, ``z-up``). A
    ``--estimate-tension-gain`` for a robot without tendons is refused, naming the
    options file's line where it came from one."""
    if getattr(args, "robot", None):
        from continuum_mhe.io.robot_file import read_robot

        robot = read_robot(args.robot)
    else:
        length = getattr(args, "length", None)
        try:
            robot = Robot.single(
                DEFAULT_LENGTH if length is None else length,
                getattr(args, "theta_max", math.pi / 2),
                getattr(args, "mounting", None) or "z-up",
            )
        except ValueError as exc:
            raise InputError(f"robot: {exc}") from None
    if getattr(args, "estimate_tension_gain", False) and not robot.n_tendons:
        named = getattr(args, "config_sources", {}).get("estimate_tension_gain")
        raise InputError(
            f"{named or '--estimate-tension-gain'} does not apply: it is for a tendon robot "
            "(a robot file with [[tendon]] entries and a [backbone]), and "
            + (
                f"the robot file {args.robot} has"
                if getattr(args, "robot", None)
                else "this robot has"
            )
            + " no tendons"
        )
    return robot


def estimate_robot(
    args: argparse.Namespace, path: str, use: str, warned: list[str] | None = None
) -> Robot:
    """The robot an estimate CSV ``path`` was made on, for a command that reads it:
    ``--robot``, or one section of ``--length`` (and ``--mounting``, else the mounting
    the estimate's options line records) where one is given, or with ``--mounting``
    alone the recorded robot turned so; a ``--robot`` or
    ``--mounting`` that turns the recorded mounting over is warned of; else the robot
    the estimate's options line records (said in a note ending in ``use``, what the
    command does on it; a recorded robot file that cannot be read is refused in one
    line); else one section of :data:`DEFAULT_LENGTH`. ``warned``: where a warning goes
    (printed when None)."""
    given = robot_given(args)
    robot = None if given else recorded_robot(path, use)
    if robot is not None:
        return robot
    robot = robot_from_args(args)
    if given and not args.robot and getattr(args, "length", None) is None:
        # --mounting alone: the recorded robot's sections, turned as given
        recorded = recorded_robot(path, use)
        if recorded is not None:
            robot = replace(recorded, mounting=robot.mounting)
    line = ""
    recorded_way = recorded_mounting(path)
    if args.robot:
        line = other_robot_file(path, args.robot, robot)
    elif getattr(args, "mounting", None) is None:
        # --length alone: the estimate's own mounting, as its options line records it
        if recorded_way in MOUNTINGS and recorded_way != robot.mounting:
            robot = replace(robot, mounting=cast(Mounting, recorded_way))
    elif recorded_way is not None and recorded_way != args.mounting:
        line = (
            f"{path} was estimated with mounting {recorded_way} (its options line), not "
            f"--mounting {args.mounting}: the given one is used, which turns the "
            "estimate's base over: leave --mounting out to use the recorded one"
        )
    if line and warned is not None:
        warned.append(line)
    elif line:
        print(f"{PROG}: warning: {line}", file=sys.stderr)
    return robot


def recorded_mounting(path: str) -> str | None:
    """The mounting the estimate ``path`` was made with, from its options line (the
    robot file it names, or its ``--mounting``), or None where it records none or the
    robot file cannot be read."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.robot_file import read_robot

    name = recorded_option(path, "robot")
    if isinstance(name, str):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return read_robot(beside(path, name)).mounting
        except UserError:
            return None
    mounting = recorded_option(path, "mounting")
    return mounting if isinstance(mounting, str) else None


def robot_given(args: argparse.Namespace) -> bool:
    """Whether the command line gives the robot (``--robot``, ``--length`` or
    ``--mounting``), rather than the estimate's options line."""
    return bool(args.robot) or any(
        getattr(args, o, None) is not None for o in ("length", "mounting")
    )


def _geometry(robot: Robot) -> tuple[object, ...]:
    """What a robot's outputs depend on: its sections' lengths and its IMUs' places."""
    return (robot.lengths, tuple((i.section, i.at) for i in robot.imus))


def warn_other_recorded_robot(path: str, given: str, robot: Robot) -> None:
    """:func:`other_robot_file`'s warning, printed (a line on stderr)."""
    line = other_robot_file(path, given, robot)
    if line:
        print(f"{PROG}: warning: {line}", file=sys.stderr)


def other_robot_file(path: str, given: str, robot: Robot) -> str:
    """A warning where the ``--robot`` ``given`` (``robot``, as read) is not the robot the
    estimate ``path`` was made on, as its options line records it: other sections or IMUs
    (:func:`other_recorded_robot`), or the other mounting, which turns the estimate's
    base over; ``""`` where neither."""
    line = other_recorded_robot(path, given, robot)
    recorded_way = recorded_mounting(path)
    if not line and recorded_way is not None and recorded_way != robot.mounting:
        line = (
            f"{path} was estimated with mounting {recorded_way} (its options line), but "
            f"{given} says {robot.mounting}: the robot file's is used, which turns "
            "the estimate's base over"
        )
    return line


def other_recorded_robot(path: str, given: str, robot: Robot) -> str:
    """A warning where the estimate ``path`` records, in its options line, a robot file
    other than the ``--robot`` ``given`` (``robot``, as read) with other sections or
    IMUs: the command then uses the given robot, likely not the one the estimate was
    made on; ``""`` where not, or where the recorded file cannot be read."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.robot_file import read_robot

    name = recorded_option(path, "robot")
    if not isinstance(name, str) or name == given:
        return ""
    try:
        with warnings.catch_warnings():  # read only to compare: the given file is said
            warnings.simplefilter("ignore")
            recorded = read_robot(beside(path, name))
    except UserError:
        return ""
    if _geometry(recorded) == _geometry(robot):  # the same robot (a copy, another path)
        return ""

    def described(r: Robot) -> str:
        """Sections and, where those agree, IMU places: what tells the two apart."""
        if r.lengths != (recorded.lengths if r is robot else robot.lengths):
            return "sections of " + ", ".join(f"{v:g}" for v in r.lengths) + " m"
        return "IMUs at " + ", ".join(f"section {i.section + 1} at {i.at:g}" for i in r.imus)

    return (
        f"{path} was estimated with --robot {name} (its options line: "
        f"{described(recorded)}), not with --robot {given} ({described(robot)}); the given "
        "one is used: leave --robot out to use the recorded one"
    )


def recorded_robot(path: str, use: str, needed: bool = True) -> Robot | None:
    """The robot file the options line of the estimate ``path`` names (said in a note),
    or the one section of the ``length`` (``mounting``, ``theta-max``) it records (said
    in a note), else None. A named robot file that cannot be read (moved, deleted) is
    refused in one line where the command ``needed`` it; else said in a note, and None."""
    from continuum_mhe.errors import UserError
    from continuum_mhe.io.robot_file import read_robot

    name = recorded_option(path, "robot")
    if not isinstance(name, str):
        return _recorded_section(path, use)
    try:
        robot = read_robot(beside(path, name))
    except UserError as exc:
        line = (
            f"{path}: it was estimated with the robot file {name} (its options line), "
            f"which cannot be read here ({exc}): give --robot with the robot it was "
            "estimated on"
        )
        if needed:
            raise InputError(line) from None
        print(f"{PROG}: note: {line}", file=sys.stderr)
        return None
    print(
        f"{PROG}: note: {path} was estimated with --robot {name} (its options line): "
        f"{use} (pass --robot for another)",
        file=sys.stderr,
    )
    return robot


def _recorded_section(path: str, use: str) -> Robot | None:
    """The one-section robot of the ``length``, ``mounting`` and ``theta-max`` the options
    line of the estimate ``path`` records (said in a note), where one of them differs
    from the command line's default section, else None; a recorded value that makes no
    robot (a length that is no number, a mounting that is no mounting) is said in a note
    and the default section is used."""
    from continuum_mhe.errors import UserError

    length = recorded_option(path, "length")
    mounting = recorded_option(path, "mounting")
    theta_max = recorded_option(path, "theta-max")
    if length is None and mounting is None and theta_max is None:
        return None
    unusable = [
        f"{key} = {value!r}"
        for key, value, usable in (
            ("length", length, length is None or _real(length)),
            ("theta-max", theta_max, theta_max is None or _real(theta_max)),
            ("mounting", mounting, mounting is None or mounting in ("z-up", "z-down")),
        )
        if not usable
    ]
    robot, why = None, ""
    if not unusable:
        try:
            robot = Robot.single(
                float(length) if length is not None else DEFAULT_LENGTH,
                float(theta_max) if theta_max is not None else math.pi / 2,
                mounting or "z-up",
            )
        except UserError as exc:
            why = f"its options line makes no robot ({exc})"
    else:
        why = f"its options line's {', '.join(unusable)} make(s) no robot"
    if robot is None:
        print(
            f"{PROG}: note: {path}: {why}: the default one section of {DEFAULT_LENGTH:g} m "
            "is used (give --length or --robot)",
            file=sys.stderr,
        )
        return None
    if robot == Robot.single(DEFAULT_LENGTH):
        return None
    given = " ".join(  # the options that differ from the default section's
        f"--{key} {value:g}" if isinstance(value, (int, float)) else f"--{key} {value}"
        for key, value, default in (
            ("length", length, DEFAULT_LENGTH),
            ("theta-max", theta_max, math.pi / 2),
            ("mounting", mounting, "z-up"),
        )
        if value is not None and value != default
    )
    print(
        f"{PROG}: note: {path} was estimated on {robot.describe()} (its options line: "
        f"{given}): {use} (pass --length or --robot for another)",
        file=sys.stderr,
    )
    return robot


def _real(value: object) -> bool:
    """Whether an options line's ``value`` is a finite real number (not a bool)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
