"""What the ``continuum-mhe`` program is called and says about itself: its name, its
description, its table of commands and its version. Light (no numpy): both the entry
point (:mod:`continuum_mhe.cli.entry`) and the full command line
(:mod:`continuum_mhe.cli.app`) build their parsers from it, so each command's name and
one-line help are written here and nowhere else.
"""

from __future__ import annotations

from dataclasses import dataclass

PROG = "continuum-mhe"
DESCRIPTION = (
    "Shape and tip estimation of continuum robots from IMUs on the robot "
    "(constrained MHE, EKF, UKF): any piecewise-constant-curvature robot, and "
    "tendon-driven robots on a Cosserat-rod model with their tensions as inputs and "
    "the tip force estimated."
)


@dataclass(frozen=True)
class Command:
    """One ``continuum-mhe`` command: its name, its one-line help (``continuum-mhe
    --help``) and the module of :mod:`continuum_mhe.cli` that implements it. That module
    defines ``add_arguments(parser)`` and ``run(args) -> int`` (the exit status), and may
    define ``DESCRIPTION``, the longer text of ``continuum-mhe NAME --help``. A command
    of subcommands (``rod``) adds them as subparsers whose destination is not
    ``command``; the full command line reads the options of the one given."""

    name: str
    help: str
    module: str


#: every command, in the order of ``continuum-mhe --help``
COMMANDS: tuple[Command, ...] = (
    Command("demo", "simulate paper3d, run MHE, EKF and UKF, print errors, plot", "demo"),
    Command("simulate", "write a synthetic measurement CSV and its truth", "simulate"),
    Command(
        "rod",
        "write Cosserat-rod recordings that the estimators' models did not generate",
        "rod",
    ),
    Command("estimate", "estimate shape and tip from a recording (CSV, ROS bag, MCAP)", "estimate"),
    Command("evaluate", "errors of an estimate CSV against a truth CSV", "evaluate"),
    Command(
        "check-robot",
        "observability of a robot: rank of the measurement Jacobian over the workspace",
        "check_robot",
    ),
    Command("live", "estimate in real time from a serial IMU stream", "live"),
    Command(
        "calibrate",
        "accelerometer mean and noise, gyro bias, sample rate and mounting, at rest",
        "calibrate",
    ),
    Command(
        "reproduce",
        "run every experiment of the paper: data, figures and report.md",
        "reproduce",
    ),
    Command(
        "plot",
        "figure of an estimate file (against a truth), or of a reproduce folder's data",
        "plot",
    ),
    Command(
        "benchmark",
        "time the fast MHE beside IPOPT, do-mpc, acados, fatrop, sqpmethod+HPIPM and the EKF",
        "benchmark",
    ),
    Command(
        "view",
        "3D view of an estimate CSV or MCAP in Rerun (backbone, IMU frames, tip trail)",
        "view",
    ),
)


def version() -> str:
    """The version (``continuum_mhe.__version__``, which the package's metadata takes
    when it is built: no search of the installed packages)."""
    from continuum_mhe import __version__

    return __version__


def signal_exit() -> int:
    """``continuum-mhe: terminated`` (exit status 143) after SIGTERM, else
    ``continuum-mhe: interrupted`` (130), on stderr; returns the status."""
    import signal
    import sys

    from continuum_mhe.signals import SIGNALS_SEEN

    if signal.SIGTERM in SIGNALS_SEEN:
        print(f"{PROG}: terminated", file=sys.stderr)
        return 143
    print(f"{PROG}: interrupted", file=sys.stderr)
    return 130
