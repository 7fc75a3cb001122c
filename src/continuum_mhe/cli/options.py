"""Command-line options shared by every command: the names given on the command line
(:func:`given_options`), ``--overwrite``, and the valid range of every numeric option.
The model's, the method's, the recovery's and the input's options: :mod:`.model_options`,
:mod:`.method_options`, :mod:`.recovery_options`, :mod:`.input_options`; the robot's:
:mod:`.robot_options`; the serial stream's and the 3D view's: :mod:`.live_options`."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from continuum_mhe.errors import InputError
from continuum_mhe.model.robot import MIN_THETA_MAX, theta_max_hint
from continuum_mhe.settings import (
    MAX_HORIZON,
)

if TYPE_CHECKING:
    pass


def given_options(args: argparse.Namespace) -> frozenset[str]:
    """The destinations of the options given on the command line (``app._parse`` finds
    them); empty where the namespace was made otherwise (a test's, a library caller's)."""
    given: frozenset[str] = getattr(args, "given_options", frozenset())
    return given


def add_overwrite_option(p: argparse.ArgumentParser, what: str = "output") -> None:
    """``--overwrite``: every command that writes files refuses an existing one without
    it (checked before any work)."""
    p.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace an existing {what} file (else refused)",
    )


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
    #: the likely cause of a value outside the range, where ``above`` is too coarse
    hint: Callable[[float], str] | None = None

    def describe(self) -> str:
        lo = "(" if self.lo_open else "["
        hi = ")" if self.hi_open else "]"
        a, b = (f"{int(v)}" if self.integer else f"{v:g}" for v in (self.lo, self.hi))
        return f"{lo}{a}, {b}{hi}" + (f" {self.unit}" if self.unit else "")

    def contains(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        above_lo = v > self.lo if self.lo_open else v >= self.lo
        below_hi = v < self.hi if self.hi_open else v <= self.hi
        return above_lo and below_hi


#: Every numeric command-line option (by its ``argparse`` destination) and its valid
#: range: the one place they are stated; docs/reliability.md lists them (a test checks).
OPTION_RANGES: dict[str, OptionRange] = {
    "length": OptionRange(
        0.005, 5.0, "m", above="millimetres or centimetres? --length is in metres, e.g. 0.2"
    ),
    "theta_max": OptionRange(MIN_THETA_MAX, math.pi, "rad", hi_open=True, hint=theta_max_hint),
    "noise_deg": OptionRange(
        0.0, 90.0, "deg", above="--noise-deg is in degrees",
        # the estimators' own check refuses 0 (model_options): say so for a negative too
        hint=lambda v: "the estimators need more than 0 (simulate takes 0: noise-free data)"
        if v < 0 else "",
    ),  # fmt: skip
    "accel_psd": OptionRange(1e-9, 1e4, "rad^2/s^3"),
    "gyro_std": OptionRange(1e-6, 10.0, "rad/s", above="degrees? --gyro-std is in rad/s"),
    "horizon": OptionRange(2, MAX_HORIZON, "samples", integer=True),
    "duration": OptionRange(0.0, 1e6, "s", lo_open=True),
    "dt": OptionRange(1e-4, 10.0, "s", above="milliseconds? --dt is in seconds"),
    "seed": OptionRange(0, 2**32 - 1, integer=True),
    "samples": OptionRange(10, 100_000, integer=True),  # 100,000: about 1.3 GB
    "baud": OptionRange(50, 10_000_000, "baud", integer=True),
    "status_every": OptionRange(0.0, 3600.0, "s", lo_open=True),
    "retry_max": OptionRange(0.0, 3600.0, "s", lo_open=True),
    "memory_samples": OptionRange(0, 10_000_000, "samples", integer=True),
    "jobs": OptionRange(1, 1024, integer=True),
    "loss_scale": OptionRange(0.0, 100.0, "std", lo_open=True),
    "gap_reset": OptionRange(0.0, 1e6, "s"),
    "freeze": OptionRange(0.0, 1e6, "s"),
    "bad_start": OptionRange(0.0, 1e6, "s"),
    "reject_reset": OptionRange(0.0, 1e6, "s"),
    "drift_reset": OptionRange(0.0, 1e6, "s"),
    "glitch": OptionRange(0.0, 1e6),
    "uncertain_fraction": OptionRange(0.0, 100.0, lo_open=True),
    "model_error_deg": OptionRange(0.0, 90.0, "deg", above="--model-error-deg is in degrees"),
    "model_error_floor_deg": OptionRange(
        0.0, 90.0, "deg", above="--model-error-floor-deg is in degrees"
    ),
    "reading_bias_deg": OptionRange(0.0, 90.0, "deg", above="--reading-bias-deg is in degrees"),
    "truth_shift": OptionRange(-1e10, 1e10, "s"),  # an epoch time's offset
    "skip_start": OptionRange(0.0, 1e6, "s"),
    "pair_tolerance": OptionRange(0.0, 10.0, "s", lo_open=True,
                                  above="milliseconds? --pair-tolerance is in seconds"),
    "view_hz": OptionRange(0.0, 10_000.0, "Hz"),
    "trail": OptionRange(0.0, 1e6, "s", lo_open=True),
    "points": OptionRange(1, 10_000, integer=True),
    "web_port": OptionRange(1, 65535, integer=True),
    "grpc_port": OptionRange(1, 65535, integer=True),
    "still_acc_std": OptionRange(0.0, 10.0, "m/s^2", lo_open=True,
                                 above="a spread of 1 g is no robot at rest; it is in m/s^2"),
    "still_gyro_std": OptionRange(0.0, 5.0, "rad/s", lo_open=True,
                                  above="degrees? --still-gyro-std is in rad/s"),
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
            if rng.hint is not None and rng.hint(float(v)):
                why = f": {rng.hint(float(v))}"
            # an options file's value is named by its file and line
            named = getattr(args, "config_sources", {}).get(dest) or f"{flag} {v!r}"
            raise InputError(f"{named} is outside its valid range {rng.describe()}{why}")
