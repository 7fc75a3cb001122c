"""Command-line options shared by every command that estimates (``estimate``, ``live``,
``simulate``, ``evaluate``, ``demo``): the robot, the model and the MHE. One place, used
by the CLI and by ``live``."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from continuum_mhe.io.csv_files import InputError
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import FORMULATIONS, MHESettings, NoiseSettings


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
    return MHESettings(horizon=args.horizon, paper_start=args.paper_start, solver=args.solver)


# --- valid ranges of every numeric option ------------------------------------------
@dataclass(frozen=True)
class OptionRange:
    """The valid values of a numeric option: ``lo <= v <= hi`` (``lo < v`` where
    ``lo_open``), in ``unit``; ``above`` names the likely cause of a value over ``hi``."""

    lo: float
    hi: float
    unit: str = ""
    lo_open: bool = False
    hi_open: bool = False
    above: str = ""
    integer: bool = False

    def describe(self) -> str:
        lo = "(" if self.lo_open else "["
        hi = ")" if self.hi_open else "]"
        return f"{lo}{self.lo:g}, {self.hi:g}{hi}" + (f" {self.unit}" if self.unit else "")

    def contains(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        above_lo = v > self.lo if self.lo_open else v >= self.lo
        below_hi = v < self.hi if self.hi_open else v <= self.hi
        return above_lo and below_hi


#: Every numeric command-line option (by its ``argparse`` destination) and its valid
#: range: the one place they are stated; docs/reliability.md lists them (a test checks).
OPTION_RANGES: dict[str, OptionRange] = {
    "length": OptionRange(0.005, 5.0, "m", above="millimetres? --length is in metres, e.g. 0.2"),
    "theta_max": OptionRange(
        0.0, math.pi, "rad", lo_open=True, hi_open=True,
        above="degrees? --theta-max is in radians, e.g. 1.5708 for 90 degrees",
    ),
    "noise_deg": OptionRange(0.0, 90.0, "deg", above="--noise-deg is in degrees"),
    "accel_psd": OptionRange(1e-9, 1e4, "rad^2/s^3"),
    "gyro_std": OptionRange(1e-6, 10.0, "rad/s", above="degrees? --gyro-std is in rad/s"),
    "horizon": OptionRange(2, 1000, "samples", integer=True),
    "duration": OptionRange(0.0, 1e6, "s", lo_open=True),
    "dt": OptionRange(1e-4, 10.0, "s", above="milliseconds? --dt is in seconds"),
    "seed": OptionRange(0, 2**32 - 1, integer=True),
    "samples": OptionRange(10, 1_000_000, integer=True),
    "baud": OptionRange(50, 10_000_000, "baud", integer=True),
    "status_every": OptionRange(0.0, 3600.0, "s", lo_open=True),
    "retry_max": OptionRange(0.0, 3600.0, "s", lo_open=True),
    "memory_samples": OptionRange(0, 10_000_000, "samples", integer=True),
    "jobs": OptionRange(1, 1024, integer=True),
}  # fmt: skip


def check_option_ranges(args: argparse.Namespace) -> None:
    """Raise a one-line :class:`InputError` for the first numeric option outside its
    :data:`OPTION_RANGES` entry (options a command does not have, or left unset, pass)."""
    for dest, rng in OPTION_RANGES.items():
        v = getattr(args, dest, None)
        if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
            continue
        if not rng.contains(float(v)):
            flag = "--" + dest.replace("_", "-")
            why = f": {rng.above}" if rng.above and math.isfinite(v) and v > rng.hi else ""
            raise InputError(f"{flag} {v!r} is outside its valid range {rng.describe()}{why}")
