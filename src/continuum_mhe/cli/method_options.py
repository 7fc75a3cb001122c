"""The estimator's command-line options (``--method``, the MHE's horizon, loss and
solver), the method and MHE settings they make, and the refusals of options that would
do nothing with the method chosen."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

from continuum_mhe.cli.config import options_record
from continuum_mhe.cli.program import PROG
from continuum_mhe.errors import InputError
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.settings import (
    DEFAULT_LOSS_SCALE,
    MHE_LOSSES,
    MHELoss,
    MHESettings,
)

if TYPE_CHECKING:
    from continuum_mhe.estimators import Method
from continuum_mhe.cli.model_options import options_not_taken, worse_on_rods
from continuum_mhe.cli.options import given_options


def add_mhe_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("MHE")
    g.add_argument("--horizon", type=int, default=30, help="window length N (default 30)")
    g.add_argument(
        "--paper-start",
        action="store_true",
        help="no estimate before N samples (the paper's Algorithm 1)",
    )
    g.add_argument(
        "--solver",
        choices=("fast", "ipopt"),
        default="fast",
        help="MHE backend: fast (structure-exploiting, default) or ipopt (the paper's)",
    )
    g.add_argument(
        "--loss",
        choices=MHE_LOSSES,
        default="l2",
        help="MHE measurement cost per IMU: l2 (quadratic, default), or huber, cauchy or "
        "welsch (robust to outliers; flags the samples they down-weight; welsch also "
        "rejects bursts of consistent wrong readings, docs/robust.md; welsch is "
        f"{worse_on_rods('--loss welsch')})",
    )
    g.add_argument(
        "--loss-scale",
        type=float,
        default=None,
        metavar="K",
        help="where the robust loss departs from l2, in standard deviations of the "
        f"measurement noise (default: huber {DEFAULT_LOSS_SCALE['huber']:g}, "
        f"cauchy {DEFAULT_LOSS_SCALE['cauchy']:g}, welsch {DEFAULT_LOSS_SCALE['welsch']:g})",
    )
    g.add_argument(
        "--branch-check",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="when a window's fit is implausible (chi-square), re-solve it from other "
        "starts and, if none fits, with the arrival prior forgotten; keep the better fit "
        "(status branch-restart). Default: on for several sections with tilt only "
        "(--imu-model tilt) and the l2 loss, off with gyros (--imu-model direct, where it "
        "measured worse), with a robust --loss and for one section",
    )


def add_method_option(p: argparse.ArgumentParser) -> None:
    """``--method``; left out, the robot's default (:func:`method_from_args`)."""
    from continuum_mhe.estimators import METHODS

    p.add_argument(
        "--method",
        choices=METHODS,
        default=None,
        help="estimator (default: mhe; ekf for a tendon robot, whose model the fast MHE "
        "cannot take, and on which the UKF is slower and less accurate than the EKF, far "
        "off with tilt IMUs: docs/tendon.md)",
    )


def method_from_args(args: argparse.Namespace, formulation: Formulation) -> Method:
    """The ``--method`` given, else ``formulation``'s default
    (:func:`~continuum_mhe.estimators.default_method`); ``args.method`` is set to it, and
    where the default is not the MHE, ``args.method_note`` says so, for the command's
    summary line (after its input was read: a bad input stays one line). The fast MHE
    on a formulation it cannot take is refused (one line naming the alternatives)."""
    from continuum_mhe.estimators import default_method

    method: Method | None = getattr(args, "method", None)
    args.method_note = None
    defaulted = method is None
    if method is None:
        method = default_method(formulation)
        if method != "mhe":
            args.method_note = (
                f"by the {method}, this robot's default (the fast MHE does not take its "
                "model; --method chooses)"
            )
    obstacle = formulation.fast_mhe_obstacle
    if method == "mhe" and obstacle is not None and getattr(args, "solver", "fast") == "fast":
        robot = getattr(args, "robot", None) or "the robot"
        raise InputError(
            f"{robot}: --method mhe: {obstacle}; --method ekf (this robot's default) or ukf, "
            "or --solver ipopt (the MHE on IPOPT: slow, its memory grows with --horizon)"
        )
    if method == "mhe" and obstacle is not None:  # asked for the MHE on IPOPT
        print(
            f"{PROG}: warning: the MHE on IPOPT with this robot's model takes seconds to "
            "minutes a sample (two windows: the robot loaded, and free of load), more with "
            "a longer --horizon or a softer backbone (docs: tendon robots); the EKF is this "
            "robot's default",
            file=sys.stderr,
        )
    if method != "mhe":
        _refuse_mhe_options(args, method, defaulted, fast_mhe=obstacle is None)
    _refuse_outlier_options(args, method)
    _refuse_drift_reset(args, formulation)
    args.method = method
    parser = getattr(args, "options_parser", None)
    if parser is not None:  # the estimate file records the method that made it
        leave_out = {*(() if method == "mhe" else MHE_OPTIONS)}  # a profile's, unused
        # recovery options the run leaves unused, recorded where they act
        robust = method == "mhe" and getattr(args, "loss", "l2") != "l2"
        leave_out |= {"bad_start", "glitch"} if robust else {"reject_reset"}
        if not formulation.drift_resets():
            leave_out.add("drift_reset")
        leave_out |= set(options_not_taken(formulation))  # the other kind of robot's
        args.options_record = options_record(parser, args, leave_out)
    return method


#: The options of the MHE's window, by destination, in the order they are refused
MHE_OPTIONS = ("loss", "loss_scale", "horizon", "paper_start", "solver", "branch_check")


def _refuse_mhe_options(
    args: argparse.Namespace, method: str, defaulted: bool, fast_mhe: bool = True
) -> None:
    """One line for an MHE option given on the command line (``args.given_options``)
    where the estimator is the ``method`` (the robot's default where ``defaulted``),
    which has no window; it names how to ask for the MHE (on IPOPT where the fast MHE
    does not take the robot's model: ``fast_mhe`` false). An options file's MHE options
    are a profile's: they apply where the MHE runs."""
    given = given_options(args)
    dest = next((d for d in MHE_OPTIONS if d in given), None)
    in_file = getattr(args, "config_sources", {})
    table = getattr(args, "config_tables", {})
    if dest is None and "method" in in_file and table.get("method") != "recorded":
        # the filter and an MHE option in one table of the file contradict each other;
        # across tables (a top-level profile, an [estimate] method) the option waits for
        # the MHE, as one given beside another method does
        both = next(
            (d for d in MHE_OPTIONS if d in in_file and table.get(d) == table["method"]), None
        )
        if both is not None:
            raise InputError(
                f"{in_file[both]} is an MHE option, and the same file chooses the {method} "
                f"({in_file['method'].split(': ')[-1]}), which has no window: remove one"
            )
    if dest is None:
        return
    flag = "--" + dest.replace("_", "-")
    if dest == "branch_check" and args.branch_check is False:
        flag = "--no-branch-check"
    ask = "--method mhe" if fast_mhe else "--method mhe --solver ipopt (slow)"
    default = f" (this robot's default; {ask} for the MHE)" if defaulted else ""
    which = f"the {method}{default}"
    if dest == "loss":
        raise InputError(f"{flag} {args.loss} is an MHE option; {which} keeps the l2 cost")
    raise InputError(f"{flag} is an MHE option; {which} has no window")


def _refuse_outlier_options(args: argparse.Namespace, method: str) -> None:
    """One line for a recovery option typed on the command line that the estimator
    ``method`` with its cost makes do nothing: ``--bad-start`` and ``--glitch`` for a
    robust MHE (it rejects inconsistent readings instead), ``--reject-reset`` for any
    other estimator (nothing is rejected). Each is accepted at 0 (never), which is what
    that estimator does anyway. The loss may come from an options file (named)."""
    given = {dest for dest in given_options(args) if getattr(args, dest, None) != 0}
    loss = getattr(args, "loss", "l2")
    named = getattr(args, "config_sources", {}).get("loss") or f"--loss {loss}"
    if "bad_start" in given and method == "mhe" and loss != "l2":
        raise InputError(
            f"--bad-start does not apply with {named} (the robust MHE rejects readings "
            "inconsistent with its estimate instead of restarting on them; --reject-reset "
            "restarts it after it rejected every reading for that long)"
        )
    if "glitch" in given and method == "mhe" and loss != "l2":
        raise InputError(
            f"--glitch does not apply with {named} (the robust MHE weighs readings far from "
            "its estimate by its loss instead of skipping them)"
        )
    if "reject_reset" in given and (method != "mhe" or loss == "l2"):
        which = f"the {method}" if method != "mhe" else "the MHE with the l2 cost"
        raise InputError(
            f"--reject-reset does not apply to {which}: only a robust MHE (--loss huber, "
            "cauchy, ...) rejects readings as outliers"
        )


def _refuse_drift_reset(args: argparse.Namespace, formulation: Formulation) -> None:
    """One line for ``--drift-reset`` typed on the command line for a model whose
    estimates have no slowly varying error states to drift (a robot without tendons), or
    whose drift is its tension gains settling (``--estimate-tension-gain``): it would
    change nothing."""
    if "drift_reset" not in given_options(args) or formulation.drift_resets():
        return
    if getattr(formulation, "estimate_tension_gain", False):
        raise InputError(
            "--drift-reset does not apply with --estimate-tension-gain (the estimates' "
            "drift is then the tension gains settling, which no restart helps)"
        )
    raise InputError(
        "--drift-reset does not apply: it restarts a tendon robot's estimate whose IMU "
        "error states drift (a robot file with [[tendon]] entries and a [backbone]); "
        "this model has no such states"
    )


def check_robot_replaces(args: argparse.Namespace) -> None:
    """One line for a one-section option given on the command line (``--length``,
    ``--theta-max``, ``--mounting``) beside a robot file, which describes the robot
    instead."""
    robot = getattr(args, "robot", None)
    if not robot:
        return
    given = given_options(args)
    dest = next((d for d in getattr(args, "robot_replaces", ()) if d in given), None)
    if dest is None:
        return
    flag = "--" + dest.replace("_", "-")
    source = getattr(args, "config_sources", {}).get("robot")  # an options file's
    named = f"the robot file {robot}" + (f" ({source})" if source else "")
    raise InputError(
        f"{flag} does not apply with {named}, which describes the robot (its sections, "
        "theta_max and mounting): leave it out, or edit the robot file"
    )


def mhe_settings_from_args(args: argparse.Namespace) -> MHESettings:
    loss: MHELoss = getattr(args, "loss", "l2")
    scale = getattr(args, "loss_scale", None)
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise InputError(f"--loss-scale must be a positive number of stds, got {scale}")
    if scale is not None and loss == "l2":
        raise InputError("--loss-scale needs a robust --loss (huber, cauchy or welsch)")
    try:
        return MHESettings(
            horizon=args.horizon,
            paper_start=args.paper_start,
            solver=args.solver,
            loss=loss,
            loss_scale=scale,
            branch_check=getattr(args, "branch_check", None),
        )
    except ValueError as exc:
        raise InputError(str(exc)) from None
