"""The input's command-line options: raw IMUs (``--imu-model``, ``--attitude``,
``--gyro-std``...), tendon tensions (``--inputs``), and the input options and files
they make."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from continuum_mhe.errors import InputError
from continuum_mhe.io.input_options import DEFAULT_GYRO_STD
from continuum_mhe.io.raw_imu import ATTITUDES, IMU_MODELS, RawImuSettings, parse_mount_rpy
from continuum_mhe.model.tendon import SINGLE_IMU_GYRO_STD

if TYPE_CHECKING:
    pass
from continuum_mhe.cli.model_options import worse_on_rods
from continuum_mhe.cli.options import given_options


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
        "friction; a unit error such as kgf given as N is said, and recovered only in part "
        "under load), a warning "
        "where it ends far from 1; costs accuracy where the tensions are right, and "
        "misleads with tilt IMUs (docs/tendon.md)",
    )


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
        "mahony gyro fusion from the ahrs package. madgwick estimates no gyro bias: it is "
        "refused unless the robot file gives every IMU a calibrated gyro_bias (calibrate "
        "--from REST.csv --write-robot); mahony estimates the bias. Both measurably worse "
        "than the default direct model (planar-S rod, EKF mean tip error: mahony 5.8 mm "
        "against 3.8 mm; calibrated madgwick 3.7, mahony 2.8, direct 2.2 mm; "
        "docs/options.md), but for mahony on the spatial rod, where every estimator loses "
        "the bend's branch (MHE: 60.63 against 68.51 mm)",
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
        default=None,
        help="gyro white noise std in rad/s for --imu-model direct (default "
        f"{DEFAULT_GYRO_STD:g}: a MEMS gyro, with room for the model's error; a tendon "
        f"robot with one IMU takes {SINGLE_IMU_GYRO_STD:g} unless a value is given here "
        "or in an options file); a "
        "gyro's own noise is far smaller, and given on a tendon robot (under 0.005) "
        "it leaves rows ok outside their intervals, with a warning (docs/tendon.md)",
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
        "lowers the MHE's mean tip error by up to 0.7 mm but raises its largest (planar-s: "
        "26.45 against 6.91 mm, with 48 rows inconsistent and 15 restarts), and can cost "
        "the EKF and UKF (restarts, largest errors over 200 mm: docs/estimators.md)",
    )
    g.add_argument(
        "--still-start",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="for --imu-model direct: take each gyro bias the robot file does not give from "
        "the recording's first seconds where the robot is still there (a second or more; "
        "the summary says so), which lets estimate weigh --imu-twist as for a calibrated "
        "robot file. Default: estimate does; live does not (it estimates from its first "
        "sample) and records --no-still-start, so that estimate --config replays it. A "
        "steady turn about the vertical reads as a bias: --no-still-start where the robot "
        "starts so",
    )
    g.add_argument(
        "--imu-twist",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="for --imu-model direct: each IMU turned about the backbone's tangent by a "
        "twist state, for a backbone that twists (a rod under couples or a tip load); give "
        "calibrated gyro biases (calibrate --from REST.csv --write-robot), held then, not "
        "estimated. Default: estimate chooses it for a recording (not a pipe) whose robot file "
        "has every IMU's gyro_bias calibrated, or that starts with the robot still (the "
        "gyro biases taken from it), where the readings fit it better (the "
        "summary says which; live: off). On the shipped twisting rods, calibrated, it "
        "takes the EKF's mean tip error from 66 and 13 mm to 8.8 and 8.1 mm; on a rod that "
        "hardly twists it costs 1.5 to 2.0 mm (about 4 mm with other draws of the IMUs' "
        "errors), and on readings the model follows (simulate) 14 against 2.4 mm, with rows "
        "ok 20 mm off (docs/model.md): --no-imu-twist keeps the constant-curvature frames",
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
    pair_tolerance = getattr(args, "pair_tolerance", None)
    use_orientation = bool(getattr(args, "orientation", False))
    profile = set(getattr(args, "config_sources", {})) - given_options(args)
    if not _reads_robot_log(args):  # an options file's options for logs apply where they can
        if "topic" in profile:
            topics = ()
        if "pair_tolerance" in profile:
            pair_tolerance = None
        if "orientation" in profile:
            use_orientation = False
    gyro_std = getattr(args, "gyro_std", None)  # None: the model's own (recorded only if set)
    if gyro_std is not None and not (math.isfinite(gyro_std) and gyro_std > 0):
        raise InputError(f"--gyro-std must be positive, got {gyro_std}")
    return InputOptions(
        raw=raw_settings(args),
        mount_rpy_given=getattr(args, "mount_rpy", None) is not None,
        gyro_std_given="gyro_std" in given_options(args),
        gyro_bias_off_given="estimate_gyro_bias" in given_options(args)
        and getattr(args, "estimate_gyro_bias", None) is False,
        topic=topics[0] if len(topics) == 1 else None,
        topics=topics,
        pair_tolerance=pair_tolerance,
        use_orientation=use_orientation,
        gyro_std=gyro_std,
        estimate_gyro_bias=getattr(args, "estimate_gyro_bias", None),
        estimate_accel_bias=bool(getattr(args, "estimate_accel_bias", False)),
        own_acceleration=bool(getattr(args, "own_acceleration", False)),
        imu_twist=bool(getattr(args, "imu_twist", False)),
        degrees=bool(getattr(args, "degrees", False)),
        skip_bad=bool(getattr(args, "skip_bad", False)),
        tensions=getattr(args, "inputs", None),
        estimate_tension_gain=bool(getattr(args, "estimate_tension_gain", False)),
        from_profile=frozenset(profile & {"degrees", "mount_rpy", "attitude", "pair_tolerance"}),
    )


def _reads_robot_log(args: argparse.Namespace) -> bool:
    """Whether the command reads a ROS bag or MCAP file (``estimate``'s recording; not
    ``live``'s port)."""
    from continuum_mhe.io.robot_logs import is_robot_log

    measurements = getattr(args, "measurements", None)
    return measurements is not None and is_robot_log(measurements)


def input_files(args: argparse.Namespace) -> list[tuple[str, str | None]]:
    """The files that ``estimate`` and ``live`` read (``estimate``'s recording too), as
    :func:`continuum_mhe.io.output_files.refuse_inputs` takes them: an output must not
    replace one. (Not ``--config``: an estimate CSV given as its own options file is
    read before the new one replaces it, a re-run.)"""
    return [
        ("the recording", getattr(args, "measurements", None)),
        ("the tensions file --inputs", getattr(args, "inputs", None)),
        ("the robot file --robot", getattr(args, "robot", None)),
    ]
