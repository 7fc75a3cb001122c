"""Command-line options shared by every command that estimates (``estimate``, ``live``,
``simulate``, ``evaluate``, ``demo``): the model, the method, the MHE, recovery and raw
IMUs. One place, used by every command module of this package (``estimate``, ``live``,
``calibrate``, ...). The robot's options: :mod:`.robot_options`; the serial stream's and
the 3D view's: :mod:`.live_options`."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from continuum_mhe.cli.config import options_record
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import DEFAULT_LENGTH, add_robot_option, robot_from_args
from continuum_mhe.errors import InputError
from continuum_mhe.io.input_options import DEFAULT_GYRO_STD
from continuum_mhe.io.raw_imu import ATTITUDES, IMU_MODELS, RawImuSettings, parse_mount_rpy
from continuum_mhe.model.formulations import Formulation
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import theta_max_hint
from continuum_mhe.settings import (
    DEFAULT_LOSS_SCALE,
    FORMULATIONS,
    FREEZE_MIN_SAMPLES,
    MAX_HORIZON,
    MAX_MEASUREMENT_STD,
    MHE_LOSSES,
    MIN_MEASUREMENT_STD,
    MHELoss,
    MHESettings,
    NoiseSettings,
    RecoverySettings,
)

if TYPE_CHECKING:
    from continuum_mhe.estimators import Method


#: Options measurably worse than the default on the shipped two-section rod recordings
#: (``data/rod2``, raw IMUs, the MHE, ``--robot two-section``): per rod, the mean tip
#: error in mm with the option and with the default (``continuum-mhe evaluate``).
#: Their help and docs/options.md's table say it (:func:`worse_on_rods`).
WORSE_ON_RODS: dict[str, tuple[tuple[str, float, float], ...]] = {
    "--loss welsch": (("spatial-tendon", 82.82, 6.89), ("spatial-stiff-torsion", 101.42, 16.24)),
    "--no-estimate-gyro-bias": (("planar-s", 14.85, 3.77), ("spatial-tendon", 13.41, 6.89)),
    "--imu-model tilt": (("planar-s", 5.00, 3.77), ("spatial-stiff-torsion", 29.57, 16.24)),
}


def worse_on_rods(option: str) -> str:
    """The clause of :data:`WORSE_ON_RODS` for ``option``: ``worse on the shipped
    two-section rods: planar-s 14.85, spatial-tendon 13.41 mm against 3.77, 6.89 mm``."""
    rods = WORSE_ON_RODS[option]
    given = ", ".join(f"{rod} {mm:.2f}" for rod, mm, _ in rods)
    default = ", ".join(f"{mm:.2f}" for _, _, mm in rods)
    return f"worse on the shipped two-section rods: {given} mm against {default} mm"


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
        "--model-error-floor-deg",
        type=float,
        default=math.degrees(NoiseSettings.model_error_std),
        help="the constant-curvature model's error of a real robot, in degrees per "
        "gravity-direction reading, carried in the standard deviations until the "
        "readings show a larger one (default %(default).2g); 0 for data the model "
        "generated (continuum-mhe simulate), where the default makes the intervals too "
        "wide (docs/uncertainty.md)",
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
        "--own-acceleration, a tendon robot)",
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


def add_method_option(p: argparse.ArgumentParser) -> None:
    """``--method``; left out, the robot's default (:func:`method_from_args`)."""
    from continuum_mhe.estimators import METHODS

    p.add_argument(
        "--method",
        choices=METHODS,
        default=None,
        help="estimator (default: mhe; ekf for a tendon robot, whose model the fast MHE "
        "cannot take, and on which the UKF is far slower and less accurate than the EKF: "
        "docs/tendon.md)",
    )


def _bend_accel_psd_applies(formulation: Formulation) -> bool:
    """Whether ``formulation``'s process noise depends on ``noise.bend_accel_psd``: its
    covariance over one 0.05 s step at two values of it."""
    import numpy as np

    doubled = replace(
        formulation,
        noise=replace(formulation.noise, bend_accel_psd=2.0 * formulation.noise.bend_accel_psd),
    )
    return not np.array_equal(formulation.process_cov(0.05), doubled.process_cov(0.05))


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
         lambda: _bend_accel_psd_applies(formulation),
         f"its process noise is {formulation.process_noise_source}"),
    ):  # fmt: skip
        given = getattr(args, attr, None)
        if given is not None and given != default and not applies():
            named = getattr(args, "config_sources", {}).get(attr) or flag
            raise InputError(f"{prefix}{named} does not apply to {model}: {why}")


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
            "minutes a window, more with a longer --horizon or a softer backbone (docs: "
            "tendon robots); the EKF is this robot's default",
            file=sys.stderr,
        )
    if method != "mhe":
        _refuse_mhe_options(args, method, defaulted, fast_mhe=obstacle is None)
    _refuse_outlier_options(args, method)
    args.method = method
    parser = getattr(args, "options_parser", None)
    if parser is not None:  # the estimate file records the method that made it
        leave_out = () if method == "mhe" else MHE_OPTIONS  # a profile's, unused
        args.options_record = options_record(parser, args, leave_out)
    return method


def given_options(args: argparse.Namespace) -> frozenset[str]:
    """The destinations of the options given on the command line (``app._parse`` finds
    them); empty where the namespace was made otherwise (a test's, a library caller's)."""
    given: frozenset[str] = getattr(args, "given_options", frozenset())
    return given


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
    ask = "--method mhe" if fast_mhe else "--method mhe --solver ipopt (slow)"
    default = f" (this robot's default; {ask} for the MHE)" if defaulted else ""
    which = f"the {method}{default}"
    if dest == "loss":
        raise InputError(f"{flag} {args.loss} is an MHE option; {which} keeps the l2 cost")
    raise InputError(f"{flag} is an MHE option; {which} has no window")


def _refuse_outlier_options(args: argparse.Namespace, method: str) -> None:
    """One line for a recovery option typed on the command line that the estimator
    ``method`` with its cost makes do nothing: ``--bad-start`` for a robust MHE (it
    rejects inconsistent readings instead), ``--reject-reset`` for any other estimator
    (nothing is rejected). The loss may come from an options file (named)."""
    given = given_options(args)
    loss = getattr(args, "loss", "l2")
    named = getattr(args, "config_sources", {}).get("loss") or f"--loss {loss}"
    if "bad_start" in given and method == "mhe" and loss != "l2":
        raise InputError(
            f"--bad-start does not apply with {named} (the robust MHE rejects readings "
            "inconsistent with its estimate instead of restarting on them; --reject-reset "
            "restarts it after it rejected every reading for that long)"
        )
    if "reject_reset" in given and (method != "mhe" or loss == "l2"):
        which = f"the {method}" if method != "mhe" else "the MHE with the l2 cost"
        raise InputError(
            f"--reject-reset does not apply to {which}: only a robust MHE (--loss huber, "
            "cauchy, ...) rejects readings as outliers"
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


def add_tensions_option(p: argparse.ArgumentParser, otherwise: str) -> None:
    """``--inputs TENSIONS.csv``: a tendon robot's tensions file (``otherwise``: where
    the tensions come from without it)."""
    p.add_argument(
        "--inputs",
        metavar="TENSIONS.csv",
        help="tendon tensions t,tension_1,...,tension_k (N, the robot file's [[tendon]] "
        f"order), interpolated linearly to the sample times ({otherwise}; docs/tendon.md)",
    )


def add_tension_gain_option(p: argparse.ArgumentParser) -> None:
    """``--estimate-tension-gain``: a tendon robot's gain per section on the tensions
    given (``estimate`` and ``live``)."""
    p.add_argument(
        "--estimate-tension-gain",
        action="store_true",
        help="a tendon robot with raw IMUs: estimate a gain per section on the tensions "
        "given (the tension acting over the one given: a tension sensor's gain, tendon "
        "friction; a unit error such as kgf given as N is said, not recovered), a warning "
        "where it ends far from 1; costs accuracy where the tensions are right, and "
        "misleads with tilt IMUs (docs/tendon.md)",
    )


def add_overwrite_option(p: argparse.ArgumentParser, what: str = "output") -> None:
    """``--overwrite``: every command that writes files refuses an existing one without
    it (checked before any work)."""
    p.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace an existing {what} file (else refused)",
    )


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
        help="an IMU whose reading repeats exactly for longer than this, over at least "
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
        "--uncertain-fraction",
        type=float,
        default=RecoverySettings.uncertain_fraction,
        metavar="F",
        help="status uncertain instead of ok when the tip's standard deviation exceeds "
        "F times the robot's length, and for the --gap-reset window (1 s without it) "
        f"after it last did (default {RecoverySettings.uncertain_fraction:g})",
    )


def recovery_settings_from_args(args: argparse.Namespace) -> RecoverySettings:
    for name in ("gap_reset", "freeze", "bad_start", "reject_reset"):
        v = getattr(args, name)
        if not (math.isfinite(v) and v >= 0):
            raise InputError(f"--{name.replace('_', '-')} must be >= 0 seconds, got {v}")
    f = args.uncertain_fraction
    if not (math.isfinite(f) and f > 0):
        raise InputError(f"--uncertain-fraction must be positive, got {f}")
    return RecoverySettings(
        gap_reset=args.gap_reset or None,
        freeze=args.freeze or None,
        uncertain_fraction=f,
        bad_start=args.bad_start or None,
        reject_reset=args.reject_reset or None,
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
    "theta_max": OptionRange(0.0, math.pi, "rad", lo_open=True, hi_open=True, hint=theta_max_hint),
    "noise_deg": OptionRange(0.0, 90.0, "deg", above="--noise-deg is in degrees"),
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
    "uncertain_fraction": OptionRange(0.0, 100.0, lo_open=True),
    "model_error_deg": OptionRange(0.0, 90.0, "deg", above="--model-error-deg is in degrees"),
    "model_error_floor_deg": OptionRange(
        0.0, 90.0, "deg", above="--model-error-floor-deg is in degrees"
    ),
    "reading_bias_deg": OptionRange(0.0, 90.0, "deg", above="--reading-bias-deg is in degrees"),
    "truth_shift": OptionRange(-1e6, 1e6, "s"),
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


def add_raw_imu_options(p: argparse.ArgumentParser) -> None:
    """Options that turn raw IMU samples into measurements (estimate and live)."""
    g = p.add_argument_group("raw IMU input (accelerometer m/s^2, gyro rad/s)")
    g.add_argument(
        "--imu-model",
        choices=IMU_MODELS,
        default=None,
        help="direct: gravity direction and gyro rates in the model, gyro biases "
        "estimated (default where the input has gyro columns); tilt: roll/pitch from the "
        "accelerometer alone (default without gyros; on raw input "
        f"{worse_on_rods('--imu-model tilt')}; docs/options.md)",
    )
    g.add_argument(
        "--attitude",
        choices=ATTITUDES,
        default="accel",
        help="for --imu-model tilt: accel (accelerometer only, default), or madgwick / "
        "mahony gyro fusion from the ahrs package; both measurably worse than the default "
        "direct model (planar-S rod, EKF: madgwick 33 mm, mahony 5.8 mm, direct 3.8 mm "
        "mean tip error; docs/options.md)",
    )
    g.add_argument(
        "--mount-rpy",
        default=None,  # None: not given (0,0,0); given, it must apply to some IMU
        metavar="R,P,Y",
        help="sensor mounting roll,pitch,yaw in degrees: v_tip = Rz(Y) Ry(P) Rx(R) v_sensor "
        "(default 0,0,0); for the IMUs without a robot-file mount_rpy",
    )
    g.add_argument(
        "--gyro-std",
        type=float,
        default=DEFAULT_GYRO_STD,
        help="gyro white noise std in rad/s for --imu-model direct (default "
        f"{DEFAULT_GYRO_STD:g}: a MEMS gyro, with room for the model's error)",
    )
    g.add_argument(
        "--estimate-gyro-bias",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="for --imu-model direct: estimate each gyro's bias (a random-walk state per "
        "IMU; default) or, with --no-estimate-gyro-bias, count it as gyro noise "
        f"({worse_on_rods('--no-estimate-gyro-bias')})",
    )
    g.add_argument(
        "--estimate-accel-bias",
        action="store_true",
        help="for --imu-model direct: estimate each accelerometer's bias (a random-walk "
        "state per IMU, m/s^2); needs motion through several orientations (docs/model.md; "
        "a tendon robot estimates it by default: docs/tendon.md)",
    )
    g.add_argument(
        "--own-acceleration",
        action="store_true",
        help="for --imu-model direct: model each IMU's own acceleration (the bend "
        "accelerations become states; docs/model.md). On the shipped rod recordings it "
        "helps the MHE and can cost the EKF and UKF (restarts, largest errors over 200 mm: "
        "docs/estimators.md)",
    )


def raw_settings(args: argparse.Namespace) -> RawImuSettings:
    """:class:`RawImuSettings` from parsed options (defaults where absent); an
    ``--attitude`` filter with ``--imu-model direct``, which has none, is refused in one
    line naming both (and the options file of either)."""
    model, attitude = getattr(args, "imu_model", None), getattr(args, "attitude", "accel")
    if model == "direct" and attitude != "accel":
        sources = getattr(args, "config_sources", {})
        named = [
            sources.get(dest) or f"--{dest.replace('_', '-')} {value}"
            for dest, value in (("imu_model", model), ("attitude", attitude))
        ]
        raise InputError(
            f"{named[1]} does not apply with {named[0]}: --attitude chooses how --imu-model "
            "tilt makes roll and pitch from raw readings, and --imu-model direct puts the "
            "accelerometer and gyro readings into the model itself, with no attitude "
            "filter; leave one of the two out"
        )
    return RawImuSettings(
        imu_model=getattr(args, "imu_model", None),
        attitude=getattr(args, "attitude", "accel"),
        mount_rpy=parse_mount_rpy(getattr(args, "mount_rpy", None) or "0,0,0"),
    )


def input_options(args: argparse.Namespace) -> Any:
    """``input_options.InputOptions`` for ``estimate`` (and ``live``) from parsed options."""
    from continuum_mhe.io.input_options import InputOptions

    topics = tuple(getattr(args, "topic", None) or ())
    gyro_std = float(getattr(args, "gyro_std", DEFAULT_GYRO_STD))
    if not (math.isfinite(gyro_std) and gyro_std > 0):
        raise InputError(f"--gyro-std must be positive, got {gyro_std}")
    return InputOptions(
        raw=raw_settings(args),
        mount_rpy_given=getattr(args, "mount_rpy", None) is not None,
        gyro_std_given="gyro_std" in given_options(args),
        gyro_bias_off_given="estimate_gyro_bias" in given_options(args)
        and getattr(args, "estimate_gyro_bias", None) is False,
        topic=topics[0] if len(topics) == 1 else None,
        topics=topics,
        pair_tolerance=getattr(args, "pair_tolerance", None),
        use_orientation=bool(getattr(args, "orientation", False)),
        gyro_std=gyro_std,
        estimate_gyro_bias=getattr(args, "estimate_gyro_bias", None),
        estimate_accel_bias=bool(getattr(args, "estimate_accel_bias", False)),
        own_acceleration=bool(getattr(args, "own_acceleration", False)),
        degrees=bool(getattr(args, "degrees", False)),
        skip_bad=bool(getattr(args, "skip_bad", False)),
        tensions=getattr(args, "inputs", None),
        estimate_tension_gain=bool(getattr(args, "estimate_tension_gain", False)),
    )


def input_files(args: argparse.Namespace) -> list[tuple[str, str | None]]:
    """The files besides the recording that ``estimate`` and ``live`` read, as
    :func:`continuum_mhe.io.output_files.refuse_inputs` takes them: an output must not
    replace one. (Not ``--config``: an estimate CSV given as its own options file is
    read before the new one replaces it, a re-run.)"""
    return [
        ("the tensions file --inputs", getattr(args, "inputs", None)),
        ("the robot file --robot", getattr(args, "robot", None)),
    ]
