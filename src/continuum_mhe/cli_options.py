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
from continuum_mhe.settings import FORMULATIONS, MHESettings, NoiseSettings, RecoverySettings


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
        "--model-error-deg",
        type=float,
        default=0.0,
        help="model error in degrees, added in quadrature to --noise-deg in R: widens "
        "the uncertainty for data the model does not describe exactly (default 0)",
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


def formulation_from_args(args: argparse.Namespace) -> Formulation:
    if not (math.isfinite(args.noise_deg) and args.noise_deg > 0):
        raise InputError(f"--noise-deg must be positive, got {args.noise_deg}")
    model_error = getattr(args, "model_error_deg", 0.0)
    if not (math.isfinite(model_error) and model_error >= 0):
        raise InputError(f"--model-error-deg must be >= 0, got {model_error}")
    robot = robot_from_args(args)
    noise = NoiseSettings(
        measurement_std=math.radians(math.hypot(args.noise_deg, model_error)),
        bend_accel_psd=args.accel_psd,
    )
    try:
        return make_formulation(args.formulation, robot, noise)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def mhe_settings_from_args(args: argparse.Namespace) -> MHESettings:
    return MHESettings(horizon=args.horizon, paper_start=args.paper_start, solver=args.solver)


#: ``--gap-reset`` and ``--freeze`` defaults, s.
GAP_RESET_S = 1.0
FREEZE_S = 1.0


def add_recovery_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("recovery and trust")
    g.add_argument(
        "--gap-reset",
        type=float,
        default=GAP_RESET_S,
        metavar="SECONDS",
        help="after no valid reading for longer than this, restart the estimator from "
        f"the next reading (status reset); 0: never (default {GAP_RESET_S:g})",
    )
    g.add_argument(
        "--freeze",
        type=float,
        default=FREEZE_S,
        metavar="SECONDS",
        help="an IMU whose reading repeats exactly for longer than this is treated as "
        f"dropped out until it changes; 0: never (default {FREEZE_S:g})",
    )
    g.add_argument(
        "--uncertain-fraction",
        type=float,
        default=RecoverySettings.uncertain_fraction,
        metavar="F",
        help="status uncertain instead of ok when the tip's standard deviation exceeds "
        f"F times the robot's length (default {RecoverySettings.uncertain_fraction:g})",
    )


def recovery_settings_from_args(args: argparse.Namespace) -> RecoverySettings:
    for name in ("gap_reset", "freeze"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v >= 0):
            raise InputError(f"--{name.replace('_', '-')} must be >= 0 seconds, got {v}")
    f = args.uncertain_fraction
    if not (math.isfinite(f) and f > 0):
        raise InputError(f"--uncertain-fraction must be positive, got {f}")
    return RecoverySettings(
        gap_reset=args.gap_reset or None, freeze=args.freeze or None, uncertain_fraction=f
    )
