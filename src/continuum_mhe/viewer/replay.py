"""``continuum-mhe view``: an estimate CSV (and its truth) replayed as a 3D view."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

from continuum_mhe.io.csv_files import (
    InputError,
    check_estimate_fits,
    read_state_table,
    robot_misfit,
)
from continuum_mhe.model.descriptions import pcc_outputs
from continuum_mhe.model.robot import Robot
from continuum_mhe.viewer.sink import ViewerSink
from continuum_mhe.viewer.view import INSTALL_HINT, BackboneView


def replay(
    estimates: str, robot: Robot, sink: ViewerSink, truth: str | None = None,
    trail_s: float = 10.0, points_per_section: int = 16,
) -> int:  # fmt: skip
    """Write or show the view of an estimate CSV (and its truth). Returns the number of
    estimates drawn."""
    outputs = pcc_outputs(robot.n_sections)
    est = read_state_table(estimates, ())
    check_estimate_fits(estimates, est.names, robot)
    cols = [est.names.index(o.name) for o in outputs]
    truth_table = None
    if truth is not None:
        truth_table = read_state_table(truth)  # t, x, y, z and any per-section columns
        misfit = robot_misfit(truth_table.names, robot, complete=False)
        if misfit:
            raise InputError(f"{truth}: {misfit}; pass --robot with its robot")
    view = BackboneView(
        robot, outputs, sink, trail_s=trail_s, points_per_section=points_per_section,
        name=Path(estimates).name,
    )  # fmt: skip
    with_truth = ""
    try:
        if truth_table is not None:
            drawn_truth = view.log_truth(truth_table.t, truth_table.values, truth_table.names)
            with_truth = ", with truth" + (
                ""
                if drawn_truth
                else " (tip and section ends only: no theta/phi columns for every section)"
            )
        view.log_rows(est.t, est.values[:, cols], list(est.status))
    except BaseException:
        view.close()
        raise
    drawn = int(np.sum(np.all(np.isfinite(est.values[:, cols]), axis=1)))
    where = {
        "save": f"wrote {sink.path}",
        "spawn": "sent to the Rerun viewer",
        "web": "sent to the web viewer",
    }[sink.kind]
    print(
        f"{where}: {drawn} of {len(est.t)} estimate(s) of {robot.describe()}{with_truth}",
        file=sys.stderr,
    )
    view.close(wait=True)
    return drawn


def cmd_view(args: argparse.Namespace) -> int:
    from continuum_mhe.cli_options import robot_from_args, viewer_sink_from_args

    sink = viewer_sink_from_args(args)
    replay(args.estimates, robot_from_args(args), sink, args.truth, args.trail, args.points)
    return 0


def register(subparsers: Any) -> None:
    """Add ``view``."""
    from continuum_mhe.cli_options import add_robot_option, add_viewer_options
    from continuum_mhe.model.imu import MOUNTINGS

    p = subparsers.add_parser(
        "view",
        help="3D view of an estimate CSV in Rerun (backbone, IMU frames, tip trail)",
        description="Replay an estimate CSV as a 3D view in Rerun: every section of the "
        f"backbone, the IMU frames and the tip trail. Needs rerun-sdk ({INSTALL_HINT}).",
    )
    p.add_argument("estimates", metavar="EST.csv", help="estimate CSV (from estimate or live)")
    p.add_argument("--truth", metavar="TRUTH.csv", help="truth CSV, drawn in grey")
    add_robot_option(p, replaces=("--length", "--mounting"))
    p.add_argument("--length", type=float, default=0.2, help="section length in m (default 0.2)")
    p.add_argument("--mounting", choices=MOUNTINGS, default="z-up", help="base orientation")
    add_viewer_options(p)
    p.set_defaults(func=cmd_view)
