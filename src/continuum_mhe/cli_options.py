"""Command-line options shared by every command that estimates (``estimate``, ``live``,
``simulate``, ``evaluate``, ``demo``): the robot, the model and the MHE. One place, used
by the CLI and by ``live``."""

from __future__ import annotations

import argparse
import math

from continuum_mhe.io.csv_files import InputError
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import (
    DEFAULT_LOSS_SCALE,
    FORMULATIONS,
    MHE_LOSSES,
    MHELoss,
    MHESettings,
    NoiseSettings,
)


def add_robot_option(g: argparse._ActionsContainer) -> None:
    g.add_argument(
        "--robot",
        metavar="ROBOT.toml",
        help="robot file (sections, IMUs, mounting; see README); replaces --length, "
        "--theta-max and --mounting",
    )


def robot_from_args(args: argparse.Namespace) -> Robot:
    """The robot of a command: ``--robot`` file, else the one-section flags."""
    if getattr(args, "robot", None):
        from continuum_mhe.io.robot_file import read_robot

        return read_robot(args.robot)
    try:
        return Robot.single(
            args.length,
            getattr(args, "theta_max", math.pi / 2),
            getattr(args, "mounting", "z-up"),
        )
    except ValueError as exc:
        raise InputError(f"robot: {exc}") from None


def add_model_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("model")
    add_robot_option(g)
    g.add_argument("--length", type=float, default=0.2, help="section length in m (default 0.2)")
    g.add_argument(
        "--theta-max",
        type=float,
        default=math.pi / 2,
        help="upper bound on theta in rad (default pi/2)",
    )
    g.add_argument("--mounting", choices=MOUNTINGS, default="z-up", help="base orientation")
    g.add_argument(
        "--formulation",
        choices=FORMULATIONS,
        default="bend",
        help="motion model: bend (default, singularity-free) or paper (5-state, eq. 4)",
    )
    g.add_argument(
        "--noise-deg",
        type=float,
        default=2.0,
        help="roll/pitch noise standard deviation in degrees (default 2)",
    )
    g.add_argument(
        "--accel-psd",
        type=float,
        default=NoiseSettings.bend_accel_psd,
        help="bend formulation: white-noise acceleration density in rad^2/s^3 (default 0.5)",
    )


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
        help="MHE measurement cost per IMU: l2 (quadratic, default), or huber or cauchy "
        "(robust to outliers; flags the samples they down-weight)",
    )
    g.add_argument(
        "--loss-scale",
        type=float,
        default=None,
        metavar="K",
        help="where the robust loss departs from l2, in standard deviations of the "
        f"measurement noise (default: huber {DEFAULT_LOSS_SCALE['huber']:g}, "
        f"cauchy {DEFAULT_LOSS_SCALE['cauchy']:g})",
    )


def formulation_from_args(args: argparse.Namespace) -> Formulation:
    if not (math.isfinite(args.noise_deg) and args.noise_deg > 0):
        raise InputError(f"--noise-deg must be positive, got {args.noise_deg}")
    robot = robot_from_args(args)
    noise = NoiseSettings(
        measurement_std=math.radians(args.noise_deg), bend_accel_psd=args.accel_psd
    )
    try:
        return make_formulation(args.formulation, robot, noise)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def mhe_settings_from_args(args: argparse.Namespace) -> MHESettings:
    loss: MHELoss = getattr(args, "loss", "l2")
    scale = getattr(args, "loss_scale", None)
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise InputError(f"--loss-scale must be a positive number of stds, got {scale}")
    if scale is not None and loss == "l2":
        raise InputError("--loss-scale needs a robust --loss (huber or cauchy)")
    method = getattr(args, "method", "mhe")
    if loss != "l2" and method != "mhe":
        raise InputError(f"--loss {loss} is an MHE option; the {method} keeps the l2 cost")
    try:
        return MHESettings(
            horizon=args.horizon,
            paper_start=args.paper_start,
            solver=args.solver,
            loss=loss,
            loss_scale=scale,
        )
    except ValueError as exc:
        raise InputError(str(exc)) from None
