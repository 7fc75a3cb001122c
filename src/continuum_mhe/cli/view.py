"""``continuum-mhe view``: the command that replays an estimate CSV (or MCAP) as a 3D view in
Rerun (:func:`continuum_mhe.viewer.replay`)."""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from dataclasses import replace
from pathlib import Path

from continuum_mhe.arrays import FloatArray
from continuum_mhe.cli.config import recorded_t0_ns
from continuum_mhe.cli.held_notes import said_as_lines, said_unless_refused
from continuum_mhe.cli.input_options import add_tensions_option
from continuum_mhe.cli.live_options import add_viewer_options, viewer_sink_from_args
from continuum_mhe.cli.options import add_overwrite_option
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import DEFAULT_LENGTH, add_robot_option, estimate_robot
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.evaluation.truth_checks import refuse_an_estimate_as_truth, truth_beside
from continuum_mhe.io.tensions import Tensions
from continuum_mhe.io.text_rows import held_for_rereading, held_text
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.robot import Robot
from continuum_mhe.viewer import INSTALL_HINT, ViewNote, ViewWarning, read_view_tensions, replay


def run(args: argparse.Namespace) -> int:
    if args.truth_shift and not args.truth:
        raise InputError("--truth-shift needs --truth TRUTH.csv: it shifts the truth's times")
    sink = viewer_sink_from_args(args)
    # the estimate is read twice, the tensions again where compared with the recorded ones
    with (
        held_for_rereading(args.estimates, args.truth, args.inputs),
        said_as_lines(ViewNote, ViewWarning),
    ):
        # the notes and warnings about the robot and the truth are said once the files
        # are found fit to draw
        with said_unless_refused():
            checked = _refuse_tendon_estimate_on_another_robot(args)  # before the notes
            robot = estimate_robot(args, args.estimates, "drawn on that robot")
            if not checked:  # a robot from a pipe: checked as it was taken
                _refuse_tendon_estimate_on_another_robot(args, robot)
            est_t = _check_estimate(args, robot)
            if args.truth:
                _check_truth(args, robot)
            path = args.inputs or _recorded_tensions(args.estimates, robot)
            tensions = _checked_tensions(args.estimates, path, robot, est_t) if path else None
        replay(
            args.estimates, robot, sink, args.truth, args.trail, args.points, tensions,
            args.truth_shift, say=_say,
        )  # fmt: skip
        _warn_other_drawing(args, robot)  # after replay's refusals: a drawing was made
    return 0


def _say(line: str) -> None:
    """A line of the replay (what was drawn, where the web viewer serves) on stderr."""
    print(line, file=sys.stderr)


def _check_estimate(args: argparse.Namespace, robot: Robot) -> FloatArray:
    """The estimate file's own refusals, as :func:`~continuum_mhe.viewer.replay` makes
    them: one it cannot read, one without an estimate, one whose columns do not fit
    ``robot``; its times (s) where it passes."""
    from continuum_mhe.io.estimate_files import read_estimates, require_an_estimate
    from continuum_mhe.io.state_tables import check_estimate_fits

    est = read_estimates(args.estimates, "view EST.csv")
    require_an_estimate(args.estimates, est)
    check_estimate_fits(args.estimates, est.names, robot)
    return est.t


def _checked_tensions(estimates: str, path: str, robot: Robot, t: FloatArray) -> Tensions:
    """The tensions ``path`` the view draws with (:func:`~continuum_mhe.viewer.
    read_view_tensions`, on the clock of the robot log the estimate ``estimates`` is of),
    refused where their times (milliseconds?) do not cover the estimate's times ``t``
    (s) from its first row to its last."""
    table = read_view_tensions(path, robot, recorded_t0_ns(estimates) or 0)
    if len(t):
        table.check_span(float(t[0]), float(t[-1]))  # milliseconds?
        table.check_covers(t, estimates)  # the rows' tensions are there
    return table


def _recorded_tensions(estimates: str, robot: Robot) -> str | None:
    """For a tendon robot (``robot``), the tensions file the estimate's options line
    names where it is a file here, said in a note, as ``plot`` takes it; else None."""
    from continuum_mhe.cli.config import recorded_option, recorded_tensions

    if robot.backbone is None or not robot.n_tendons:
        return None
    recorded = recorded_tensions(estimates)
    if recorded is None:
        named = recorded_option(estimates, "inputs")
        if isinstance(named, str):  # the file the options line names is not here
            print(
                f"{PROG}: note: {estimates} was estimated with --inputs {named} (its options "
                "line), which is not there: the tips alone are drawn (pass --inputs)",
                file=sys.stderr,
            )
        return None
    print(recorded.note(estimates), file=sys.stderr)
    return recorded.path


def _refuse_tendon_estimate_on_another_robot(
    args: argparse.Namespace, robot: Robot | None = None
) -> bool:
    """A tendon robot's estimate (its tip force columns) with a ``--robot`` or
    ``--length`` robot without tendons is refused in one line, as ``plot`` refuses it: its
    sections drawn as constant-curvature arcs of that robot would miss the estimate by
    centimetres. Nothing here where a file cannot be read: the reading after says why.
    ``robot``: the robot as read (else read here, before the robot's own notes, unless
    it comes from a pipe, which is read once). False where it was not checked for that
    reason (the caller checks it with the robot it takes), else True."""
    from continuum_mhe.evaluation.estimate_tables import has_tip_force
    from continuum_mhe.io.estimate_files import read_estimates
    from continuum_mhe.io.robot_file import read_robot

    if not (args.robot or args.length is not None):
        return True  # the robot the estimate's options line names
    try:
        if args.robot and robot is None:
            if os.path.exists(args.robot) and not os.path.isfile(args.robot):
                return False  # a pipe (<(...)) is read once, where the robot is taken
            with warnings.catch_warnings():  # said where the robot is taken
                warnings.simplefilter("ignore")
                robot = read_robot(args.robot)
        if robot is not None and robot.backbone is not None and robot.n_tendons > 0:
            return True
        est = read_estimates(args.estimates, "view EST.csv")
    except UserError:
        return True
    if has_tip_force(est.names):
        given = args.robot or f"--length {args.length:g}"
        raise InputError(
            f"{given}: the robot has no [[tendon]], but {args.estimates} is a tendon robot's "
            "estimate (its tip force columns): give that robot's file, or no --robot for "
            "the one its options line names"
        )
    return True


def _check_truth(args: argparse.Namespace, robot: Robot) -> None:
    """The truth against the estimate, as ``plot`` checks it: refused in one line where
    it is an estimate (its ``status`` or ``std_`` columns), its positions are in mm,
    fewer than two of its rows share the estimate's times (``t`` in milliseconds, another
    recording) or it has another robot's sections; a warning where its clock looks
    offset. Nothing here where either file cannot be read: replay says why."""
    from continuum_mhe.io.estimate_files import read_estimates
    from continuum_mhe.io.position_units import position_unit_problem
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.model.descriptions import TIP_COLUMNS

    try:
        est = read_estimates(args.estimates, "view EST.csv", TIP_COLUMNS)
        truth = read_state_table(args.truth, gaps=True)
    except UserError:
        return
    refuse_an_estimate_as_truth(args.truth, truth, "view EST.csv --truth TRUTH.csv")
    if unit := position_unit_problem(truth.names, truth.values, robot.lengths):
        raise InputError(f"{args.truth}: {unit}")  # before a length misfit it would cause
    if len(est.t) < 2:  # one row: nothing to compare times with
        return
    if args.truth_shift:  # the truth read at t + shift, as evaluate reads it
        truth = replace(truth, t=truth.t - args.truth_shift)
    beside = truth_beside(
        args.estimates, est, args.truth, truth, robot.lengths, "--truth-shift", args.truth_shift
    )
    for line in beside[1]:
        print(f"{PROG}: warning: {line}", file=sys.stderr)


def _warn_other_drawing(args: argparse.Namespace, robot: Robot) -> None:
    """A warning where the view would draw the estimate on other sections than its rows
    fit (``--length`` or ``--robot`` of other lengths) or a tendon robot's backbone with
    another tensions file than the one its options line names: the drawn backbone then
    misses the estimate's section ends and tip."""
    from continuum_mhe.cli.config import beside, recorded_option
    from continuum_mhe.evaluation.estimate_tables import lengths_misfit
    from continuum_mhe.io.estimate_files import read_estimates

    try:
        est = read_estimates(args.estimates, "view EST.csv")
    except UserError:
        return  # replay says why, in its words
    # the paper formulation's x, y, z are states of their own, not the bends' end
    paper = recorded_option(args.estimates, "formulation") == "paper"
    if not paper and (misfit := lengths_misfit(est, robot.lengths)):
        print(
            f"{PROG}: warning: {args.estimates}: {misfit}; its backbone is drawn on those "
            "sections and misses its section ends: give the robot (--robot, --length) it "
            "was estimated with",
            file=sys.stderr,
        )
    recorded = recorded_option(args.estimates, "inputs")
    if args.inputs and isinstance(recorded, str):
        here = Path(beside(args.estimates, recorded))
        given = _text_of(args.inputs)
        same = (
            here.is_file()
            and given is not None
            and (here.resolve() == Path(args.inputs).resolve() or _text_of(here) == given)
        )
        if not same:
            print(
                f"{PROG}: warning: {args.estimates} was estimated with --inputs {recorded} "
                f"(its options line), not {args.inputs}: the backbone is drawn with these "
                "tensions and may miss the estimate's tip: give the tensions file it was "
                "estimated with",
                file=sys.stderr,
            )


def _text_of(path: str | Path) -> str | None:
    """The text of ``path``: a file's, or a pipe's (``-``, ``<(...)``) held for rereading
    (:func:`~continuum_mhe.io.text_rows.held_for_rereading`); None for neither."""
    held = held_text(path)
    if held is not None:
        return held
    p = Path(path)
    return p.read_bytes().decode("utf-8", errors="replace") if p.is_file() else None


DESCRIPTION = (
    "Replay an estimate CSV or MCAP as a 3D view in Rerun: every section of the "
    f"backbone, the IMU frames and the tip trail. Needs rerun-sdk ({INSTALL_HINT})."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "estimates", metavar="EST.csv", help="estimate CSV (from estimate or live), or MCAP"
    )
    p.add_argument("--truth", metavar="TRUTH.csv", help="truth CSV, drawn in grey")
    p.add_argument(
        "--truth-shift",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="draw each estimate row beside the truth SECONDS later (a truth on a clock "
        "offset from the estimate's, as evaluate --truth-shift compares them)",
    )
    add_robot_option(p, replaces=("--length", "--mounting"))
    p.add_argument(
        "--length",
        type=float,
        help=f"one section's length in m (default: the estimate's --robot, else "
        f"{DEFAULT_LENGTH:g})",
    )
    p.add_argument(
        "--mounting", choices=MOUNTINGS, help="one section's base orientation (default z-up)"
    )
    add_tensions_option(
        p, "a tendon robot's estimate: its backbone drawn from the mechanics model at the "
        "estimated tip force (a recording with its tension columns, as live --record "
        "writes it, gives them too); without it, the file the estimate's options line "
        "names, else the tips alone"
    )  # fmt: skip
    add_viewer_options(p)
    add_overwrite_option(p, "--save")
