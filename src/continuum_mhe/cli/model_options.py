"""The model's command-line options (``--formulation``, the noise levels, the
mounting...) and the formulation they make, with the checks that they apply."""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from typing import TYPE_CHECKING

from continuum_mhe.cli.robot_options import DEFAULT_LENGTH, add_robot_option, robot_from_args
from continuum_mhe.errors import InputError
from continuum_mhe.estimators.process_noise import bend_accel_psd_applies
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.settings import (
    FORMULATIONS,
    MAX_MEASUREMENT_STD,
    MIN_MEASUREMENT_STD,
    NoiseSettings,
)

if TYPE_CHECKING:
    pass


#: Options measurably worse than the default on the shipped two-section rod recordings
#: (``data/rod2``, raw IMUs, the MHE, ``--robot two-section``): per rod, the mean tip
#: error in mm with the option and with the default (``continuum-mhe evaluate``).
#: Their help and docs/options.md's table say it (:func:`worse_on_rods`).
WORSE_ON_RODS: dict[str, tuple[tuple[str, float, float], ...]] = {
    "--loss welsch": (("spatial-tendon", 82.82, 6.89), ("spatial-stiff-torsion", 101.42, 16.24)),
    "--no-estimate-gyro-bias": (("planar-s", 14.85, 3.77), ("spatial-tendon", 13.41, 6.89)),
    "--imu-model tilt": (("planar-s", 5.00, 3.77), ("spatial-stiff-torsion", 29.57, 16.24)),
}


#: How :func:`worse_on_rods` names the recordings: the robot file as shipped, not
#: calibrated (a calibrated one scores spatial-tendon lower: the README's 6.15 mm).
ROD_CLAUSE = "worse on the shipped two-section rods (the shipped robot file, uncalibrated)"


#: Of those, the rods where the option is better than the default (the same run):
#: :func:`worse_on_rods` says these too.
BETTER_ON_RODS: dict[str, tuple[tuple[str, float, float], ...]] = {
    "--imu-model tilt": (("spatial", 62.67, 68.51),),
}


def worse_on_rods(option: str) -> str:
    """The clause of :data:`WORSE_ON_RODS` for ``option``: ``worse on the shipped
    two-section rods (...): planar-s 14.85, spatial-tendon 13.41 mm against 3.77, 6.89
    mm``, and where :data:`BETTER_ON_RODS` has it, where it is better."""
    rods = WORSE_ON_RODS[option]
    given = ", ".join(f"{rod} {mm:.2f}" for rod, mm, _ in rods)
    default = ", ".join(f"{mm:.2f}" for _, _, mm in rods)
    better = ""
    if option in BETTER_ON_RODS:
        won = BETTER_ON_RODS[option]
        better = (
            "; better on "
            + ", ".join(f"{rod} {mm:.2f} against {d:.2f} mm" for rod, mm, d in won)
            + ", where every estimator loses the bend's branch"
        )
    return f"{ROD_CLAUSE}: {given} mm against {default} mm{better}"


def add_model_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("model")
    add_robot_option(g)
    g.add_argument(
        "--length",
        type=float,
        default=DEFAULT_LENGTH,
        help=f"section length in m (default {DEFAULT_LENGTH:g})",
    )
    g.add_argument(
        "--theta-max",
        type=float,
        default=math.pi / 2,
        help="upper bound on theta in rad (default pi/2)",
    )
    g.add_argument(
        "--mounting", choices=MOUNTINGS, default="z-up",
        help="base orientation: z-up (default), its z axis up, or z-down, hanging from it",
    )  # fmt: skip
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
        help="roll/pitch (gravity direction) noise standard deviation in degrees, the "
        "readings' scatter while the robot moves (default 2); the noise at rest that "
        "calibrate prints is far smaller, and given here it makes most rows inconsistent "
        "(docs/options.md)",
    )
    g.add_argument(
        "--model-error-deg",
        type=float,
        default=0.0,
        help="model error in degrees, added in quadrature to --noise-deg in R: widens "
        "the uncertainty for data the model does not describe exactly (default 0)",
    )
    g.add_argument(
        "--model-error-floor-deg",
        type=float,
        default=math.degrees(NoiseSettings.model_error_std),
        help="the constant-curvature model's error of a real robot, in degrees per "
        "gravity-direction reading, carried in the standard deviations until the "
        "readings show a larger one (default %(default).2g); 0 for data the model "
        "generated (continuum-mhe simulate), where the default makes the intervals too "
        "wide, and for simulate's raw readings with --own-acceleration too, as they "
        "carry the IMUs' own acceleration (without it rows are ok far outside their "
        "intervals; docs/uncertainty.md)",
    )
    g.add_argument(
        "--reading-bias-deg",
        type=float,
        default=math.degrees(NoiseSettings.reading_bias_std),
        help="the readings' constant error (an IMU's mounting misalignment and "
        "accelerometer bias), in degrees per gravity-direction reading, carried in the "
        "standard deviations (default %(default).2g); 0 for readings without one "
        "(continuum-mhe simulate; its raw readings with --own-acceleration), where the "
        "default makes the intervals too wide (docs/options.md)",
    )
    g.add_argument(
        "--accel-psd",
        type=float,
        default=NoiseSettings.bend_accel_psd,
        help="bend formulation: white-noise acceleration density in rad^2/s^3 (default "
        "0.5); refused where the model does not take it (--formulation paper, "
        "--own-acceleration, a tendon robot). Smaller is stiffer: 0.1 with raw IMUs "
        "lowers the mean error on most shipped and variant rods but leaves fewer rows "
        "ok, and with tilt it is worse (docs/options.md)",
    )


#: The options of a constant-curvature robot's models, by destination, which a tendon
#: robot's model does not take: its process noise, its IMUs' error states (always
#: estimated) and the IMUs' own acceleration are its own, and it has no formulation to
#: choose (each is refused where it would change the model, or has no effect).
CONSTANT_CURVATURE_OPTIONS = (
    "formulation",
    "model_error_floor_deg",
    "reading_bias_deg",
    "accel_psd",
    "estimate_accel_bias",
    "own_acceleration",
    "imu_twist",
)
#: The options of a tendon robot alone, by destination (refused for another robot).
TENDON_OPTIONS = ("inputs", "estimate_tension_gain")


def options_not_taken(formulation: Formulation) -> tuple[str, ...]:
    """The destinations of the options that ``formulation``'s robot does not take, which
    an estimate file's options line leaves out: a tendon robot's model (with tendons)
    takes none of :data:`CONSTANT_CURVATURE_OPTIONS`, another robot's none of
    :data:`TENDON_OPTIONS`."""
    return CONSTANT_CURVATURE_OPTIONS if formulation.robot.n_tendons else TENDON_OPTIONS


def formulation_from_args(args: argparse.Namespace) -> Formulation:
    if not (math.isfinite(args.noise_deg) and args.noise_deg > 0):
        raise InputError(
            f"--noise-deg {args.noise_deg:g}: the estimators need a positive measurement noise, "
            "valid range (0, 90] deg here (simulate takes 0: noise-free data)"
        )
    if math.radians(args.noise_deg) < MIN_MEASUREMENT_STD:
        raise InputError(
            f"--noise-deg {args.noise_deg:g}: below the smallest measurement noise the "
            f"estimators take, {math.degrees(MIN_MEASUREMENT_STD):.2g} deg (no IMU is that "
            "precise; --noise-deg is the std of roll and pitch in degrees, e.g. 2)"
        )
    model_error = getattr(args, "model_error_deg", 0.0)
    if not (math.isfinite(model_error) and model_error >= 0):
        raise InputError(f"--model-error-deg must be >= 0, got {model_error}")
    combined = math.hypot(args.noise_deg, model_error)
    if math.radians(combined) > MAX_MEASUREMENT_STD:
        raise InputError(
            f"--noise-deg {args.noise_deg:g} with --model-error-deg {model_error:g}: a "
            f"measurement noise of {combined:.3g} deg (added in quadrature), beyond "
            f"{math.degrees(MAX_MEASUREMENT_STD):g} deg"
        )
    robot = robot_from_args(args)
    floor = getattr(args, "model_error_floor_deg", math.degrees(NoiseSettings.model_error_std))
    if not (math.isfinite(floor) and floor >= 0):
        raise InputError(f"--model-error-floor-deg must be >= 0, got {floor}")
    bias = getattr(args, "reading_bias_deg", math.degrees(NoiseSettings.reading_bias_std))
    if not (math.isfinite(bias) and bias >= 0):
        raise InputError(f"--reading-bias-deg must be >= 0, got {bias}")
    noise = NoiseSettings(
        measurement_std=math.radians(math.hypot(args.noise_deg, model_error)),
        bend_accel_psd=args.accel_psd,
        model_error_std=math.radians(floor),
        reading_bias_std=math.radians(bias),
    )
    try:
        return make_formulation(args.formulation, robot, noise)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def check_noise_options_apply(args: argparse.Namespace, formulation: Formulation) -> None:
    """Refuse ``--reading-bias-deg``, ``--model-error-floor-deg`` or ``--accel-psd``
    given (not at its default) where the model takes no such term, in one line naming
    the option (an options file's value by its file and line): a tendon robot carries
    its IMUs' constant errors as states, assumes no constant-curvature model error and
    has a process noise of its own; the paper's model (``W = w I``) and the direct model
    with the IMUs' own acceleration (white jerk) do not take ``--accel-psd``."""
    robot = getattr(args, "robot", None)
    prefix, model = (
        (f"{robot}: ", "this robot's model") if robot else ("", f"the {formulation.name} model")
    )
    # the model with each term at one radian: a term it ignores stays zero
    probe = replace(
        formulation, noise=replace(formulation.noise, reading_bias_std=1.0, model_error_std=1.0)
    )
    for flag, attr, default, applies, why in (
        ("--reading-bias-deg", "reading_bias_deg", math.degrees(NoiseSettings.reading_bias_std),
         lambda: bool(probe.reading_bias_cov().any()),
         "its IMUs' misalignments and accelerometer biases are states, whose covariance "
         "the standard deviations carry (docs/tendon.md)"),
        ("--model-error-floor-deg", "model_error_floor_deg",
         math.degrees(NoiseSettings.model_error_std), lambda: probe.model_error_floor() > 0.0,
         "it is a mechanics model, not a constant-curvature one, and assumes no model "
         "error before the readings show one (docs/tendon.md)"),
        ("--accel-psd", "accel_psd", NoiseSettings.bend_accel_psd,
         lambda: bend_accel_psd_applies(formulation),
         f"its process noise is {formulation.process_noise_source}"),
    ):  # fmt: skip
        given = getattr(args, attr, None)
        if given is not None and given != default and not applies():
            named = getattr(args, "config_sources", {}).get(attr) or flag
            raise InputError(f"{prefix}{named} does not apply to {model}: {why}")
