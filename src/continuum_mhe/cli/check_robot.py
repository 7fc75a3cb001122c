"""``continuum-mhe check-robot``: the observability of a robot file."""

from __future__ import annotations

import argparse
import json
import sys

from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import robot_from_args, robot_name_arg
from continuum_mhe.errors import InputError, UserError

#: From this many sections on, ``check-robot`` says first that it takes a while (its
#: cost grows with about the cube of the sections: docs/formats.md gives a time).
SLOW_CHECK_SECTIONS = 10


def run(args: argparse.Namespace) -> int:
    from continuum_mhe.analysis.observability import (
        format_report,
        observability_report,
        unsolved_warning,
    )

    robot = robot_from_args(args)
    if robot.n_sections >= SLOW_CHECK_SECTIONS:  # a long wait without a word looks hung
        print(
            f"{PROG}: note: checking {robot.n_sections} sections: the check's cost grows "
            "with about the cube of their number, so it takes a minute or more (docs/"
            "formats.md)",
            file=sys.stderr,
        )
    try:
        report = observability_report(robot, samples=args.samples, seed=args.seed)
    except UserError as exc:  # the robot's own: its file named
        raise InputError(f"{args.robot}: {exc}") from None
    unsolved = unsolved_warning(report)
    if unsolved is not None:  # on stderr, as every warning: stdout holds the report
        print(f"{PROG}: warning: {args.robot}: {unsolved}", file=sys.stderr)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        print(format_report(robot, report))
    return 0


DESCRIPTION = (
    "Say whether a robot's IMUs determine its shape: the rank of their readings with "
    "respect to the bend coordinates (a tendon robot: the tip force, its tensions given) "
    "over random shapes of the workspace, for tilt IMUs and with gyros, its least "
    "observable shapes, and a verdict. A robot whose shape its IMUs do not determine is "
    "estimated with every row uncertain."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    from continuum_mhe.io.robot_file import shipped_robots

    names = ", ".join(shipped_robots())
    p.add_argument(
        "robot",
        metavar="ROBOT.toml",
        type=robot_name_arg,
        help=f"robot file, or a shipped robot's name ({names})",
    )
    p.add_argument("--samples", type=int, default=2000, help="random shapes (default 2000)")
    p.add_argument("--seed", type=int, default=0, help="seed of the random shapes (default 0)")
    p.add_argument("--json", action="store_true", help="print JSON")
