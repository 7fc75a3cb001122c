"""An estimate CSV or MCAP (and its truth) replayed as a 3D view (``continuum-mhe view``,
:mod:`continuum_mhe.cli.view`)."""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe.errors import InputError, UserError, expect_type
from continuum_mhe.io.estimate_files import read_estimates, require_an_estimate
from continuum_mhe.io.position_units import position_unit_problem
from continuum_mhe.io.state_tables import (
    check_estimate_fits,
    model_backbone_misfit,
    read_state_table,
    robot_misfit,
)
from continuum_mhe.io.tensions import Tensions, read_drawn_tensions
from continuum_mhe.model.descriptions import OutputSpec, robot_outputs
from continuum_mhe.model.robot import Robot
from continuum_mhe.viewer.geometry import TendonShapes
from continuum_mhe.viewer.sink import ViewerSink
from continuum_mhe.viewer.view import BackboneView, ViewNote, ViewWarning


def estimated_extras(names: Sequence[str], robot: Robot) -> tuple[OutputSpec, ...]:
    """The outputs beyond the shape that an estimate's columns ``names`` hold, named and
    in the order the formulation that made them gives them (:func:`robot_outputs` with
    the option): a tendon robot's tension gains ``tension_gain_s`` that are there
    (``--estimate-tension-gain``: the backbone is drawn under the given tensions times
    these), or each IMU's twist ``imu_twist_i`` where every IMU's is (``--imu-twist``;
    ``imu_twist`` for one IMU). ``live --view`` draws the same outputs (its
    formulation's)."""
    tendon = robot.backbone is not None
    shape = len(robot_outputs(robot))
    extras = robot_outputs(robot, tension_gain=tendon, imu_twist=not tendon)[shape:]
    if tendon:
        return tuple(o for o in extras if o.name in names)
    return extras if all(o.name in names for o in extras) else ()


def _not_a_tendon_robot(name: str) -> str:
    """The refusal of the tensions ``name`` beside a robot without a backbone."""
    return f"{name}: --inputs is for a tendon robot (a [backbone] in --robot)"


def read_view_tensions(path: str, robot: Robot, t0_ns: int = 0) -> Tensions:
    """The tensions file ``path`` (read as ``estimate --inputs`` reads it; or a recording
    with its tension columns, as ``live --record`` writes one, read as ``estimate`` reads
    them from it: :func:`~continuum_mhe.io.tensions.read_tensions`) for the view of a
    tendon robot ``robot``'s estimate: its
    times on a robot log's clock where they are since 1970 and the estimate's ``t = 0``
    is ``t0_ns`` (ns since 1970; 0: none), as ``estimate`` took them (said in a
    :class:`~continuum_mhe.viewer.view.ViewNote`); refused in one line for a robot without
    a backbone, and in mN for N."""
    if robot.backbone is None:
        raise InputError(_not_a_tendon_robot(path))
    table, note = read_drawn_tensions(path, robot, t0_ns)
    if note:
        warnings.warn(note, ViewNote, stacklevel=2)
    return table


def replay(
    estimates: str, robot: Robot, sink: ViewerSink, truth: str | None = None,
    trail_s: float = 10.0, points_per_section: int = 16, tensions: Tensions | None = None,
    truth_shift: float = 0.0, say: Callable[[str], None] | None = None,
) -> int:  # fmt: skip
    """Write or show the view of an estimate CSV (and its truth). Returns the number of
    estimates drawn. A tendon robot's backbone (``robot.backbone``) is its mechanics
    model's at each row's tip force under the ``tensions``
    (:func:`read_view_tensions`); without them, its tips alone are drawn (said in a
    :class:`~continuum_mhe.viewer.view.ViewNote`). The truth's row at time ``t`` is drawn
    at ``t - truth_shift`` s (a truth on a clock that runs ``truth_shift`` ahead of the
    estimate's). A backbone that misses the estimated tip is a
    :class:`~continuum_mhe.viewer.view.ViewWarning`. ``say`` (where given) takes the line
    that says what was drawn and where, and a web viewer's lines (:meth:`BackboneView.
    close`); nothing is printed."""
    expect_type("robot", robot, Robot, "a Robot (read_robot(NAME) reads a robot file)")
    expect_type("sink", sink, ViewerSink, "a ViewerSink ('save' with a .rrd path, 'web')")
    tendon = None
    if robot.backbone is not None:
        tendon = TendonShapes(robot, points_per_section, tensions)
        if tensions is None:
            warnings.warn(
                "a tendon robot's backbone is drawn from its mechanics model with its "
                "tensions (--inputs TENSIONS.csv; tensions=read_view_tensions(...) in "
                "Python); without them, the tips alone",
                ViewNote,
                stacklevel=2,
            )
    elif tensions is not None:
        raise InputError(_not_a_tendon_robot(tensions.name))
    est = read_estimates(estimates, "view EST.csv")
    require_an_estimate(estimates, est)
    check_estimate_fits(estimates, est.names, robot)
    outputs = (*robot_outputs(robot), *estimated_extras(est.names, robot))
    if tendon is not None and tendon.tensions is not None and len(est.t):
        tendon.tensions.check_span(float(est.t[0]), float(est.t[-1]))  # milliseconds?
    cols = [est.names.index(o.name) for o in outputs]
    truth_table = None
    if truth is not None:
        truth_table = read_state_table(truth, gaps=True)  # t, x, y, z and any per-section columns
        if truth_shift:
            truth_table = replace(truth_table, t=truth_table.t - truth_shift)
        misfit = robot_misfit(truth_table.names, robot, complete=False)
        if misfit:
            raise InputError(f"{truth}: {misfit}; pass --robot with its robot")
    for path, shown in ((estimates, est), (truth, truth_table)):
        if shown is not None and (unit := position_unit_problem(shown.names, shown.values,
                                                                robot.lengths)):  # fmt: skip
            raise InputError(f"{path}: {unit}")
    view = BackboneView(
        robot, outputs, sink, trail_s=trail_s, points_per_section=points_per_section,
        name=Path(estimates).name, tendon=tendon,
    )  # fmt: skip
    with_truth = ""
    try:
        if truth_table is not None:
            try:
                drawn_truth = view.log_truth(truth_table.t, truth_table.values, truth_table.names)
            except InputError:  # names its file (the tensions')
                raise
            except UserError as exc:  # a row's loads without an equilibrium
                raise InputError(f"{truth}: {exc}") from None
            missing = "theta/phi columns for every section"
            if tendon is not None:  # its equilibrium needs the tensions and the tip force
                missing = "tensions" if tendon.tensions is None else "fx, fy, fz columns"
            with_truth = ", with truth" + (
                "" if drawn_truth else f" (tip and section ends only: no {missing})"
            )
        try:
            # a file without a status column (a truth's, another tool's) logs no status
            statuses = list(est.status) if est.status_column else [""] * len(est.t)
            view.log_rows(est.t, est.values[:, cols], statuses)
        except InputError:  # names its file (the tensions')
            raise
        except UserError as exc:  # a row's loads without an equilibrium
            raise InputError(f"{estimates}: {exc}") from None
    except BaseException:
        view.close(keep=False)
        raise
    drawn = int(np.sum(np.all(np.isfinite(est.values[:, cols]), axis=1)))
    where = {
        "save": f"wrote {sink.path}",
        "spawn": "sent to the Rerun viewer",
        "web": "sent to the web viewer",
    }[sink.kind]
    if sink.kind == "save":  # written out first: a full disk is said instead
        view.close()
    misfit = model_backbone_misfit(view.model_tip_off, robot.length)
    if misfit:  # as plot says it
        warnings.warn(misfit, ViewWarning, stacklevel=2)
    joined = view.joined_through_ends["estimate"]
    if joined:  # as plot draws them: not the mechanics model's backbone
        drawn_as = (
            f" ({joined} of them joined through their section ends: no equilibrium under "
            "their loads)"
        )
    else:
        drawn_as = ""
    if say is not None:
        say(
            f"{where}: {drawn} of {len(est.t)} estimate(s) of {robot.describe()}{drawn_as}"
            f"{with_truth}"
        )
    if sink.kind != "save":
        view.close(wait=True, say=say)
    return drawn
