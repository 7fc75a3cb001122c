"""``continuum-mhe plot``: the figure of an estimate file (against a truth, where given),
or the reproduction's figures rendered again from a folder's saved data."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from continuum_mhe.cli.options import add_overwrite_option
from continuum_mhe.io.csv_files import InputError

DESCRIPTION = (
    "Draw an estimate file (CSV or MCAP from estimate or live): each section end and the "
    "tip over time with their 95 % bands, the error against --truth, the statuses, and "
    "the backbone in 3D (its curve from --robot, else from the file's own rows). Given a "
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
    from continuum_mhe.io.csv_files import new_files
    from continuum_mhe.reproduce.figures import render_all
    from continuum_mhe.reproduce.pipeline import load_results

    for flag, given in (("--truth", args.truth), ("--robot", args.robot), ("-o", args.output)):
        if given is not None:
            raise InputError(f"{args.source}: a reproduce folder; {flag} is for an estimate file")
    results = load_results(args.source)
    out = Path(args.out) if args.out else Path(args.source)
    with new_files(out) as files:  # Ctrl-C: none of the new figures, no new folder
        render_all(results, out, files)
    print(f"rendered {len(files)} figure files into {out}", file=sys.stderr)
    return 0


#: the figure formats ``plot -o`` writes, by suffix
FIGURE_SUFFIXES = (".png", ".pdf", ".svg")


def _estimate(args: argparse.Namespace) -> int:
    from continuum_mhe.evaluation.estimate_figure import estimate_figure, section_count
    from continuum_mhe.evaluation.plotting import save
    from continuum_mhe.io.csv_files import check_output_target, read_state_table
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.viewer.replay import read_estimates

    output = Path(args.output) if args.output else Path(args.source).with_suffix(".png")
    if output.suffix.lower() not in FIGURE_SUFFIXES:
        raise InputError(f"{output}: give a figure file ending in {', '.join(FIGURE_SUFFIXES)}")
    check_output_target(output, overwrite=args.overwrite, option="-o")  # before reading
    est = read_estimates(args.source)
    truth = read_state_table(args.truth) if args.truth else None
    lengths = None
    if args.robot:
        robot = read_robot(args.robot)
        n = section_count(est.names)
        if n and n != robot.n_sections:
            raise InputError(
                f"{args.source}: an estimate of {n} section(s), but {args.robot} has "
                f"{robot.n_sections}; give the robot file it was made with"
            )
        lengths = robot.lengths
    title = Path(args.source).name + (f" against {Path(args.truth).name}" if args.truth else "")
    try:
        fig = estimate_figure(est, truth, lengths, title)
    except ValueError as exc:
        raise InputError(f"{args.truth}: {exc}") from None
    save(fig, output, (output.suffix.lower()[1:],))
    print(f"wrote {output}", file=sys.stderr)
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "source",
        metavar="EST.csv",
        help="an estimate CSV or MCAP, or a folder written by 'continuum-mhe reproduce'",
    )
    p.add_argument("--truth", metavar="TRUTH.csv", help="truth CSV: the error is drawn too")
    p.add_argument(
        "--robot",
        metavar="ROBOT.toml",
        help="the robot file of the estimate: the backbone's curve (default: the section "
        "lengths the file's own rows give)",
    )
    p.add_argument(
        "-o", "--output", metavar="FIG.png", help="figure to write (.png, .pdf, .svg; default: "
        "EST.png beside the estimate)",
    )  # fmt: skip
    add_overwrite_option(p)
    p.add_argument(
        "--out",
        default=None,
        help="a reproduce folder only: folder for its figures (default: RESULTS)",
    )
