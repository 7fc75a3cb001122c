"""The recovery options (``--gap-reset``, ``--freeze``, ``--bad-start``, ...) and
the :class:`~continuum_mhe.settings.RecoverySettings` they make."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from continuum_mhe.errors import InputError
from continuum_mhe.settings import (
    FREEZE_MIN_SAMPLES,
    RecoverySettings,
)

if TYPE_CHECKING:
    pass


#: ``--gap-reset``, ``--freeze`` and ``--bad-start`` defaults, s (the library's).
GAP_RESET_S = RecoverySettings.gap_reset


FREEZE_S = RecoverySettings.freeze


BAD_START_S = RecoverySettings.bad_start


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
        help="an IMU whose reading repeats (to within a thousandth of its noise std) for "
        "longer than this, over at least "
        f"{FREEZE_MIN_SAMPLES} consecutive samples, is treated as dropped out until it "
        f"changes; 0: never (default {FREEZE_S:g})",
    )
    g.add_argument(
        "--bad-start",
        type=float,
        default=BAD_START_S,
        metavar="SECONDS",
        help="for this long after each (re)start, two consecutive readings inconsistent "
        "with the estimate (normalised innovation beyond the chi-square 99.9 %% quantile) "
        f"restart the estimator from the reading (status reset); not with --loss, "
        f"whose MHE rejects such readings (see --reject-reset); 0: never "
        f"(default {BAD_START_S:g})",
    )
    g.add_argument(
        "--reject-reset",
        type=float,
        default=RecoverySettings.reject_reset,
        metavar="SECONDS",
        help="robust MHE: after every reading was rejected as an outlier for longer than "
        "this, restart from the next reading (status reset; the estimate, not the "
        f"sensor, is taken as lost); 0: never (default {RecoverySettings.reject_reset:g})",
    )
    g.add_argument(
        "--glitch",
        type=float,
        default=RecoverySettings.glitch,
        metavar="FACTOR",
        help="an IMU's reading whose normalised innovation against the prediction from an "
        "ok estimate (or, near the opposite gravity direction, a start's first) exceeds "
        "FACTOR times the chi-square 99.99 %% "
        "quantile (times the model error the readings showed) is skipped as a glitch "
        "(that IMU's dropout for the "
        "sample, the row not ok); the next reading is taken, as the robot may have moved "
        "so; not with --loss; 0: never "
        f"(default {RecoverySettings.glitch:g})",
    )
    g.add_argument(
        "--drift-reset",
        type=float,
        default=RecoverySettings.drift_reset,
        metavar="SECONDS",
        help="a tendon robot: where the estimates drift (the IMUs' error states leave their "
        "prior or change faster than their model allows) for longer than this since the "
        "last ok one, restart keeping that ok estimate's IMU errors (status reset): a "
        "fault that has passed (an IMU frozen, tensions wrong for a while) left the "
        f"estimate off; 0: never (default {RecoverySettings.drift_reset:g})",
    )
    g.add_argument(
        "--uncertain-fraction",
        type=float,
        default=RecoverySettings.uncertain_fraction,
        metavar="F",
        help="status uncertain instead of ok when the tip's standard deviation as "
        "written (sqrt(std_x^2 + std_y^2 + std_z^2)) exceeds F times the robot's length; "
        "after the estimator's own tip standard deviation (without the readings' constant "
        "errors, --reading-bias-deg) last exceeded it, the rows stay uncertain for the "
        "--gap-reset window (1 s without it) "
        f"(default {RecoverySettings.uncertain_fraction:g})",
    )


def recovery_settings_from_args(args: argparse.Namespace) -> RecoverySettings:
    for name in ("gap_reset", "freeze", "bad_start", "reject_reset", "drift_reset"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v >= 0):
            raise InputError(f"--{name.replace('_', '-')} must be >= 0 seconds, got {v}")
    if not (math.isfinite(args.glitch) and args.glitch >= 0):
        raise InputError(f"--glitch must be >= 0, got {args.glitch}")
    f = args.uncertain_fraction
    if not (math.isfinite(f) and f > 0):
        raise InputError(f"--uncertain-fraction must be positive, got {f}")
    return RecoverySettings(
        gap_reset=args.gap_reset or None,
        freeze=args.freeze or None,
        uncertain_fraction=f,
        bad_start=args.bad_start or None,
        reject_reset=args.reject_reset or None,
        glitch=args.glitch or None,
        drift_reset=args.drift_reset or None,
    )
