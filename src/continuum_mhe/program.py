"""What the ``continuum-mhe`` program is called and says about itself: its name, its
description, its commands and its version. Light (no numpy): both the entry point
(:mod:`continuum_mhe.entry`) and the full command line (:mod:`continuum_mhe.cli`) read
it.
"""

from __future__ import annotations

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
    ("view", "3D view of an estimate CSV or MCAP in Rerun (backbone, IMU frames, tip trail)"),
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
