"""``continuum-mhe plot``: the figure of an estimate file (against a truth, where given),
or the reproduction's figures rendered again from a folder's saved data."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from continuum_mhe.cli.input_options import add_tensions_option
from continuum_mhe.cli.program import PROG
from continuum_mhe.errors import InputError, UserError
from continuum_mhe.model.descriptions import TIP_COLUMNS, section_count

if TYPE_CHECKING:
    from continuum_mhe.arrays import FloatArray
    from continuum_mhe.evaluation.estimate_tables import BackboneOf
    from continuum_mhe.model.robot import Robot

DESCRIPTION = (
    "Draw an estimate file (CSV or MCAP from estimate or live): each section end and the "
    "tip over time with their 95 % bands, the error against --truth, a tendon robot's tip "
    "force, the statuses, and the backbone in 3D (its curve from --robot, else from the "
    "file's own rows; a tendon robot's from --robot and --inputs). Given a "
    "folder written by 'continuum-mhe reproduce', render its figures again instead."
)


def run(args: argparse.Namespace) -> int:
    source = Path(args.source)
    if source.is_dir():
        return _reproduction(args)
    if args.out is not None:
        raise InputError(f"--out is the figure folder of a reproduce folder; for {source} give -o")
    return _estimate(args)


def _reproduction(args: argparse.Namespace) -> int:
    from continuum_mhe.io.output_files import new_files, refuse_missing_parent
    from continuum_mhe.reproduce.figures import render_all
    from continuum_mhe.reproduce.pipeline import load_results

    out = Path(args.out) if args.out else Path(args.source)
    refuse_missing_parent(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: not a folder: give --out a folder for the figures")
    results = load_results(args.source)  # a folder without them: said before its options
    for flag, given in (("--truth", args.truth), ("--robot", args.robot), ("-o", args.output)):
        if given is not None:
            raise InputError(f"{args.source}: a reproduce folder; {flag} is for an estimate file")
    if args.truth_shift:
        raise InputError(
            f"{args.source}: a reproduce folder; --truth-shift is for an estimate file"
        )
    # re-rendering a folder's own figures is what plot of a folder is for; figures in
    # another folder are kept unless --overwrite
    overwrite = args.overwrite or args.out is None
    with new_files(out) as files:  # Ctrl-C: none of the new figures, no new folder
        render_all(results, out, files, overwrite=overwrite)
    print(f"rendered {len(files)} figure files into {out}", file=sys.stderr)
    return 0


#: the figure formats ``plot -o`` writes, by suffix
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def _estimate(args: argparse.Namespace) -> int:
    from continuum_mhe.cli.held_notes import said_unless_refused
    from continuum_mhe.io.output_files import check_output_target, refuse_inputs
    from continuum_mhe.io.text_rows import held_for_rereading

    if args.output is None and (
        args.source == "-" or (Path(args.source).exists() and not Path(args.source).is_file())
    ):
        raise InputError(f"{args.source}: not a file to put the figure beside; give -o FIG.png")
    output = Path(args.output) if args.output else Path(args.source).with_suffix(".png")
    if output.suffix.lower() not in FIGURE_SUFFIXES:
        raise InputError(f"{output}: give a figure file ending in {', '.join(FIGURE_SUFFIXES)}")
    # the file save writes (its suffix is the format's name): checked and said as written
    output = output.with_suffix(output.suffix.lower())
    refuse_inputs(output, [("the estimate", args.source), ("the truth --truth", args.truth),
                           ("the tensions file --inputs", args.inputs),
                           ("the robot file --robot", args.robot)])  # fmt: skip
    check_output_target(output, overwrite=args.overwrite, option="-o")  # before reading
    # the estimate is read twice; the notes and warnings are said once the figure is made
    with held_for_rereading(args.source, args.truth), said_unless_refused():
        return _figure(args, output)


def _figure(args: argparse.Namespace, output: Path) -> int:
    """The figure of the estimate ``args.source`` to ``output`` (see :func:`_estimate`)."""
    from continuum_mhe.cli.config import recorded_option
    from continuum_mhe.cli.robot_options import (
        DEFAULT_LENGTH,
        recorded_mounting,
        recorded_robot,
        warn_other_recorded_robot,
    )
    from continuum_mhe.evaluation.estimate_figure import estimate_figure
    from continuum_mhe.evaluation.estimate_tables import (
        has_tip_force,
        lengths_from_estimate,
        lengths_misfit,
    )
    from continuum_mhe.evaluation.metrics import interpolated_note, truth_sparser
    from continuum_mhe.evaluation.plotting import save
    from continuum_mhe.evaluation.truth_checks import refuse_an_estimate_as_truth, truth_beside
    from continuum_mhe.io.estimate_files import read_estimates, require_an_estimate
    from continuum_mhe.io.position_units import position_unit_against, position_unit_problem
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.io.state_tables import read_state_table
    from continuum_mhe.model.robot import MAX_SECTION_LENGTH

    if args.truth_shift and not args.truth:
        raise InputError("--truth-shift needs --truth TRUTH.csv: it shifts the truth's times")
    est = read_estimates(args.source, "plot EST.csv", TIP_COLUMNS, truth_as_estimate=False)
    require_an_estimate(args.source, est)
    truth = read_state_table(args.truth, gaps=True) if args.truth else None
    if truth is not None:
        refuse_an_estimate_as_truth(args.truth, truth, "plot EST.csv --truth TRUTH.csv")
        if args.truth_shift:  # the truth read at t + shift, as evaluate reads it
            truth = replace(truth, t=truth.t - args.truth_shift)
    lengths = None
    robot: Robot | None = None
    # the paper formulation's x, y, z are states of their own, not the end of its arc:
    # its rows give no section lengths (view and evaluate take the recorded robot's)
    paper = recorded_option(args.source, "formulation") == "paper"
    if args.robot:
        robot = read_robot(args.robot)
        n = section_count(est.names)
        if n and n != robot.n_sections:
            raise InputError(
                f"{args.source}: an estimate of {n} section(s), but {args.robot} has "
                f"{robot.n_sections}; give the robot file it was made with"
            )
        lengths = robot.lengths
        misfit = None if paper else lengths_misfit(est, lengths)
        recorded_length = recorded_option(args.source, "length")
        if (
            paper
            and recorded_option(args.source, "robot") is None
            and isinstance(recorded_length, (int, float))
            and not math.isclose(float(recorded_length), robot.length, rel_tol=1e-6)
        ):
            # its states give no lengths: the options line's --length is the robot's
            misfit = (
                f"it was estimated with --length {recorded_length:g} (its options line), "
                f"not the given robot's {robot.length:g} m"
            )
        if misfit:  # drawn on the robot file's sections, off the estimate's points
            print(
                f"{PROG}: warning: {args.source}: {misfit}; its backbone is drawn on "
                f"{args.robot}'s and misses its section ends: give the robot file it was "
                "estimated with, or leave --robot out",
                file=sys.stderr,
            )
        else:
            warn_other_recorded_robot(args.source, args.robot, robot)
    elif paper and not has_tip_force(est.names):
        recorded = recorded_robot(args.source, "drawn on that robot")
        lengths = recorded.lengths if recorded is not None else (DEFAULT_LENGTH,)
    # a tendon robot's sections are not arcs: its rows give no lengths
    own = lengths_from_estimate(est) if lengths is None and not has_tip_force(est.names) else None
    if own is not None and max(own) > MAX_SECTION_LENGTH:  # positions in mm, or cm
        raise InputError(
            f"{args.source}: its rows give sections of "
            f"{', '.join(f'{v:.4g}' for v in own)} m (its positions against its own bend "
            "angles), beyond any robot's: positions in mm? give x, y, z in m"
        )
    for path, table in ((args.source, est), (args.truth, truth)):
        unit = ""
        if table is not None and lengths is not None:
            unit = position_unit_problem(table.names, table.values, lengths)
        if not unit and table is truth and truth is not None:  # tip positions alone in cm
            unit = position_unit_against(truth.names, truth.values, est.names, est.values)
        if unit:
            raise InputError(f"{path}: {unit}")
    backbone, drawn_on = _tendon_backbone(args, est.names, est.t, robot)
    # the robot file's mounting, else the one the estimate's options line records
    mounting = robot.mounting if robot is not None else recorded_mounting(args.source)
    title = Path(args.source).name + (f" against {Path(args.truth).name}" if args.truth else "")
    if truth is not None:
        at_est, warned = truth_beside(
            args.source,
            est,
            args.truth,
            truth,
            tuple(lengths or (drawn_on.lengths if drawn_on else None) or own or (DEFAULT_LENGTH,)),
            "--truth-shift",
            args.truth_shift,
        )
        if at_est is not None:
            sparser = truth_sparser(est.t, truth.t)
            compared = int(np.isfinite(at_est.values).any(axis=1).sum())  # not the gaps
            note = interpolated_note(args.truth, args.source, compared, len(est.t), sparser)
            print(f"{PROG}: note: {note}", file=sys.stderr)
            truth = at_est
        for line in warned:
            print(f"{PROG}: warning: {line}", file=sys.stderr)
    try:
        fig = estimate_figure(
            est, truth, lengths, title, backbone, mounting == "z-down", est.status_column
        )
    except InputError:  # names its file
        raise
    except UserError as exc:  # a row's loads (the estimate's or the truth's)
        files = f"{args.source} or {args.truth}" if args.truth else args.source
        raise InputError(f"{files}: {exc}") from None
    save(fig, output, (output.suffix[1:],))
    print(f"wrote {output}", file=sys.stderr)
    return 0


def _tendon_backbone(
    args: argparse.Namespace, names: Sequence[str], t: FloatArray, robot: Robot | None
) -> tuple[BackboneOf | None, Robot | None]:
    """The mechanics model's backbone for a tendon robot's estimate (columns ``names``
    at the times ``t``, s), from ``--robot`` (``robot``, as read; without it the robot
    file the estimate's options line names, said in a note) and ``--inputs`` (checked
    against ``t`` as ``estimate`` checks it), and the robot it is drawn on; None (the
    section ends joined, said in a note) without them."""
    from continuum_mhe.cli.config import recorded_option, recorded_t0_ns, recorded_tensions
    from continuum_mhe.cli.robot_options import recorded_robot
    from continuum_mhe.evaluation.estimate_tables import has_tip_force, tendon_backbone
    from continuum_mhe.io.tensions import read_drawn_tensions

    if not has_tip_force(names):
        if args.inputs:
            raise InputError(
                f"{args.source}: --inputs draws a tendon robot's backbone, but the "
                "estimate has no tip force columns (fx, fy, fz)"
            )
        return None, robot
    name = args.robot
    recorded = None if args.inputs else recorded_tensions(args.source)
    inputs = args.inputs or (recorded.path if recorded else None)
    if robot is None and inputs:  # the robot the estimate's options line names
        # where it cannot be read, the section ends are joined (said in a note)
        robot = recorded_robot(args.source, "drawn on that robot", needed=False)
        name = recorded_option(args.source, "robot")
    tendons = robot is not None and robot.backbone is not None and robot.n_tendons > 0
    if robot is not None and inputs and not tendons:
        if args.inputs:
            raise InputError(f"{name}: --inputs needs a tendon robot ([backbone], [[tendon]])")
        how = recorded.how if recorded else f"with --inputs {inputs}, its options line"
        raise InputError(
            f"{name}: the robot has no [[tendon]], but {args.source} is a tendon robot's "
            f"estimate (its tip force columns; estimated {how}): give that robot's file, "
            "or no --robot for the one it names"
        )
    if robot is not None and recorded:
        print(recorded.note(args.source), file=sys.stderr)
    if robot is None or not inputs:
        print(
            f"{PROG}: note: the backbone is drawn through the section ends; give "
            "--robot ROBOT.toml --inputs TENSIONS.csv for the mechanics model's curve",
            file=sys.stderr,
        )
        return None, robot
    # (a recording that carries its tensions beside its IMUs' columns, as live records
    # them, gives them too, read as estimate reads them from it; a tensions file is
    # read as estimate --inputs reads it)
    # a robot log's estimate with its tensions on the log's clock, as estimate took them
    tensions, note = read_drawn_tensions(inputs, robot, recorded_t0_ns(args.source) or 0)
    if note:
        print(f"{PROG}: note: {note}", file=sys.stderr)
    if len(t):
        tensions.check_span(float(t[0]), float(t[-1]))  # milliseconds?
        tensions.check_covers(t, args.source)
    return tendon_backbone(robot, tensions), robot


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "source",
        metavar="EST.csv",
        help="an estimate CSV or MCAP, or a folder written by 'continuum-mhe reproduce'",
    )
    p.add_argument("--truth", metavar="TRUTH.csv", help="truth CSV: the error is drawn too")
    p.add_argument(
        "--truth-shift",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="draw each estimate row against the truth SECONDS later (a truth on a clock "
        "offset from the estimate's, as evaluate --truth-shift compares them)",
    )
    p.add_argument(
        "--robot",
        metavar="ROBOT.toml",
        help="the robot file of the estimate: the backbone's curve (default: the section "
        "lengths the file's own rows give)",
    )
    add_tensions_option(
        p, "with --robot, a tendon robot's estimate: its backbone drawn from the mechanics "
        "model at the estimated tip force; a recording with its tension columns, as live "
        "--record writes it, gives them too"
    )  # fmt: skip
    p.add_argument(
        "-o", "--output", metavar="FIG.png", help="figure to write (.png, .pdf, .svg; default: "
        "EST.png beside the estimate)",
    )  # fmt: skip
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace existing figure files, -o's or those in --out (else refused; plot of "
        "a results folder without --out re-renders its own figures)",
    )
    p.add_argument(
        "--out",
        default=None,
        help="a reproduce folder only: folder for its figures (default: RESULTS)",
    )
