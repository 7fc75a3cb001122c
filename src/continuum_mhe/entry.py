"""The ``continuum-mhe`` executable's entry point, light on purpose.

``continuum-mhe --help``, ``--version`` and a bare ``continuum-mhe`` are answered here
from a table of the commands, without importing numpy, CasADi, numba or the estimators
(the full command line, :mod:`continuum_mhe.cli`, takes seconds to import on a small
machine); everything else goes to :func:`continuum_mhe.cli.main`. The table is checked
against the full parser by the tests.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

PROG = "continuum-mhe"
DESCRIPTION = (
    "Shape and tip estimation of continuum robots from IMUs on the robot "
    "(constrained MHE, EKF, UKF; any piecewise-constant-curvature robot)."
)

#: every command and its one-line help, in the order of ``continuum-mhe --help``
COMMANDS: tuple[tuple[str, str], ...] = (
    ("demo", "simulate paper3d, run MHE, EKF and UKF, print errors, plot"),
    ("simulate", "write a synthetic measurement CSV and its truth"),
    ("estimate", "estimate shape and tip from a measurement CSV"),
    ("evaluate", "errors of an estimate CSV against a truth CSV"),
    (
        "check-robot",
        "observability of a robot: rank of the measurement Jacobian over the workspace",
    ),
    ("live", "estimate in real time from a serial IMU stream"),
    ("calibrate", "accelerometer mean and noise, gyro bias, sample rate and mounting, at rest"),
    ("reproduce", "run every experiment of the paper: data, figures and report.md"),
    ("plot", "re-render the reproduction's figures from its saved data"),
    ("benchmark", "time the fast MHE beside IPOPT, do-mpc's MHE and the EKF (compiled too)"),
    ("view", "3D view of an estimate CSV in Rerun (backbone, IMU frames, tip trail)"),
)


def version() -> str:
    """The installed version (from the package metadata; no import of the package's
    modules)."""
    from importlib import metadata

    try:
        return metadata.version("continuum-mhe")
    except metadata.PackageNotFoundError:  # running from a source tree
        from continuum_mhe import __version__

        return __version__


def overview_parser() -> argparse.ArgumentParser:
    """The top-level parser with every command listed (and none of their options)."""
    parser = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, text in COMMANDS:
        sub.add_parser(name, help=text)
    return parser


def _light(argv: Sequence[str]) -> bool:
    """True when only the overview is asked for: no command word before any option
    other than ``-h``, ``--help`` and ``--version``."""
    return all(a in ("-h", "--help", "--version") for a in argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if _light(args):
        overview_parser().parse_args(args)  # prints help or version and exits
        return 0  # pragma: no cover - argparse exits before
    from continuum_mhe.cli import main as full_main

    return full_main(args)


if __name__ == "__main__":
    sys.exit(main())
