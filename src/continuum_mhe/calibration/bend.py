"""Each IMU's yaw (its rotation about the tangent) from a slow bend in a known plane,
for ``continuum-mhe calibrate --from REST.csv --bend BEND.csv``.

Physics. A torsion-free PCC robot bent in the plane ``phi0`` (every section bent
towards ``phi0``, ``u_k = theta_k (cos phi0, sin phi0)``) turns every section frame about
the same axis ``n = (sin phi0, -cos phi0, 0)``: each section's rotation vector is
``(b, -a, 0)`` in its base frame, and turning about ``n`` leaves ``n`` and the plane's
in-plane direction where they were in the next section's base frame. So every IMU, at
any bend, has angular velocity ``Theta_dot n`` (``Theta`` its total bend, section 1's
included) and gravity direction ``(cos phi0 sin Theta, sin phi0 sin Theta, cos Theta)``
in its backbone frame, whatever the bends' sizes. An IMU turned about the tangent by
``yaw`` sees both turned by ``-yaw`` about z.

Estimator: after the rest recording's roll and pitch (and, for the gyro, its bias) are
removed, ``yaw`` turns the principal axis of the gyro's rates in the x-y plane (the
total-least-squares line through the rate samples) onto ``n``. The gyro is used, not
gravity, because the accelerometer's bias across the tangent (the rest recording folds
it into roll and pitch, right only when straight) turns the horizontal gravity
component by about ``bias / g tan(Theta / 2)`` (0.3 to 0.6 deg on the rod recordings'
0.1 m/s^2 at 60 to 90 deg of bend), comparable with the yaw itself, while the gyro's
bias is measured at rest to a few thousandths of a degree per second against rates of
tens of degrees per second. The rate axis is known up to its sign; the gravity
direction (the bend is towards ``phi0``) picks it, and the yaw it gives is kept as a
cross-check: a bend not in one plane makes the two disagree.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError
from continuum_mhe.io.raw_imu import mount_rotation
from continuum_mhe.model.imu import Mounting
from continuum_mhe.model.pcc import up_vector

#: an IMU must tilt this far from straight in the bend (90th percentile of the samples)
MIN_TILT_DEG = 10.0
#: largest standard error of the yaw that the gyro's noise at rest allows, deg
MAX_YAW_STD_DEG = 0.5
#: least rate energy about the bending axis, in units of the gyro noise's over the
#: recording (``sum w^2 >= 100 n sigma^2``: the rms rate 10 times the noise's)
MIN_RATE_SNR = 100.0
#: largest rms rate across the bending axis, as a fraction of the rms rate about it
MAX_OFF_AXIS = 0.15
#: largest disagreement of the gyro's yaw and the gravity direction's yaw, deg
MAX_DISAGREEMENT_DEG = 5.0


@dataclass(frozen=True)
class YawCalibration:
    """One IMU's yaw from a bend in a known plane (degrees unless stated).

    Attributes:
        yaw_deg: rotation about the tangent that turns the gyro's rate axis, once the
            rest recording's roll and pitch are removed, onto the plane's normal:
            the third angle of ``mount_rpy``, in ``(-180, 180]``.
        gravity_yaw_deg: the yaw that turns the horizontal gravity direction onto the
            plane (a cross-check; biased by the accelerometer bias, see the module).
        tilt_deg: the IMU's tilt from straight in the bend (90th percentile).
        yaw_std_deg: the yaw's standard error from the gyro's noise at rest,
            ``sigma / sqrt(sum w^2)`` rad (``w`` the rates about the bending axis).
        off_axis: rms rate across the bending axis / rms rate about it (0 in one plane).
    """

    yaw_deg: float
    gravity_yaw_deg: float
    tilt_deg: float
    yaw_std_deg: float
    off_axis: float


def _wrap_deg(x: float) -> float:
    """Degrees wrapped to ``(-180, 180]``."""
    w = math.degrees(math.atan2(math.sin(math.radians(x)), math.cos(math.radians(x))))
    return 180.0 if w == -180.0 else w


def yaw_from_bend(
    acc: FloatArray,
    gyr: FloatArray,
    rest_rpy: tuple[float, float, float],
    gyro_bias: FloatArray,
    gyro_noise: FloatArray,
    phi_deg: float = 0.0,
    mounting: Mounting = "z-up",
) -> YawCalibration:
    """The yaw of one IMU from its samples during a bend towards ``phi_deg``.

    Args:
        acc, gyr: specific force (n, 3) m/s^2 and rate (n, 3) rad/s in the sensor frame
            (rows with a NaN are skipped).
        rest_rpy: ``(roll, pitch, _)`` degrees from the rest recording (the yaw given
            is ignored).
        gyro_bias, gyro_noise: the gyro's mean and standard deviation per axis (3,)
            rad/s at rest.
        phi_deg: the bending plane's direction, degrees (0: towards base -x).

    Raises:
        InputError: too little bend, too little motion, or not a bend in one plane
            (the message names the problem; the caller adds the file and IMU).
    """
    ok = np.all(np.isfinite(acc), axis=1) & np.all(np.isfinite(gyr), axis=1)
    if ok.sum() < 2:
        raise InputError("fewer than 2 valid samples")
    rp = mount_rotation((rest_rpy[0], rest_rpy[1], 0.0))
    up = up_vector(mounting)[2]
    g = up * acc[ok] @ rp.T  # backbone frame up to yaw, +z when straight
    tilt = np.degrees(np.arccos(np.clip(g[:, 2] / np.linalg.norm(g, axis=1), -1.0, 1.0)))
    tilt_deg = float(np.percentile(tilt, 90))
    if tilt_deg < MIN_TILT_DEG:
        raise InputError(
            f"tilts by only {tilt_deg:.1f} deg in the bend: yaw needs {MIN_TILT_DEG:g} deg or "
            "more (bend the robot further)"
        )
    w = ((gyr[ok] - gyro_bias) @ rp.T)[:, :2]
    scatter = w.T @ w
    (small, big), vecs = np.linalg.eigh(scatter)
    noise_var = float(np.mean(np.asarray(gyro_noise, dtype=float)[:2] ** 2))
    if not big > MIN_RATE_SNR * len(w) * noise_var:
        raise InputError(
            "the gyro saw too little rate about the bending axis (under "
            f"{math.sqrt(MIN_RATE_SNR):g} times its noise at rest, rms): record while "
            "bending, slowly"
        )
    yaw_std = math.degrees(math.sqrt(noise_var / big))  # the line fit's angle error
    if yaw_std > MAX_YAW_STD_DEG:
        raise InputError(
            f"the gyro turned too little about the bending axis (yaw standard error "
            f"{yaw_std:.2f} deg over {MAX_YAW_STD_DEG:g}): bend further while recording"
        )
    off_axis = math.sqrt(max(small, 0.0) / big)
    if off_axis > MAX_OFF_AXIS:
        raise InputError(
            f"rates across the bending axis are {100 * off_axis:.0f} % of those about it "
            f"(over {100 * MAX_OFF_AXIS:.0f} %): not a bend in one plane"
        )
    axis = vecs[:, 1]
    yaw_gyro = (phi_deg - 90.0) - math.degrees(math.atan2(axis[1], axis[0]))  # mod 180
    horizontal = g[:, :2].sum(axis=0)
    yaw_grav = _wrap_deg(phi_deg - math.degrees(math.atan2(horizontal[1], horizontal[0])))
    if abs(_wrap_deg(yaw_gyro - yaw_grav)) > 90.0:
        yaw_gyro += 180.0
    yaw_gyro = _wrap_deg(yaw_gyro)
    if abs(_wrap_deg(yaw_gyro - yaw_grav)) > MAX_DISAGREEMENT_DEG:
        raise InputError(
            f"the gyro's rate axis gives yaw {yaw_gyro:.1f} deg, the gravity direction "
            f"{yaw_grav:.1f} deg: not a bend in one plane towards phi = {phi_deg:g} deg"
        )
    return YawCalibration(yaw_gyro, yaw_grav, tilt_deg, yaw_std, off_axis)


def yaws_from_bend(
    path: str,
    values: FloatArray,
    rest: list[tuple[tuple[float, float, float], FloatArray, FloatArray]],
    phi_deg: float,
    mounting: Mounting,
) -> list[YawCalibration]:
    """Every IMU's yaw from a raw bend recording's values (n, 6 * n_imus), given each
    IMU's ``(rest mount_rpy, gyro mean, gyro std)`` at rest; a problem is one
    :class:`InputError` naming ``path`` and the IMU."""
    if not (math.isfinite(phi_deg) and abs(phi_deg) <= 360.0):
        raise InputError(
            f"--bend-phi must be an angle in degrees from -360 to 360, got {phi_deg:g}"
        )
    if values.shape[1] != 6 * len(rest):
        raise InputError(f"{path}: {values.shape[1] // 6} IMU(s), the rest recording {len(rest)}")
    out = []
    for i, (rpy, bias, noise) in enumerate(rest):
        block = values[:, 6 * i : 6 * i + 6]
        try:
            out.append(
                yaw_from_bend(block[:, :3], block[:, 3:], rpy, bias, noise, phi_deg, mounting)
            )
        except InputError as exc:
            raise InputError(f"{path}: IMU {i + 1}: {exc}") from None
    return out


#: How far (deg, the tilts' 90th percentiles) an IMU further out along the backbone may
#: tilt less than one before it in a bend of every section the same way
#: (:func:`tilt_order_warning`): the percentiles' scatter and a slightly uneven bend.
TILT_ORDER_MARGIN_DEG = 5.0


def tilt_order_warning(
    places: Sequence[tuple[int, float]],
    yaws: Sequence[YawCalibration],
    theta_max: Sequence[float],
) -> str:
    """``""``, or why the IMUs' tilts in a bend of every section the same way (the
    recording the yaw calibration asks for) cannot be the robot's: an IMU further out
    along the backbone (``places``: each IMU's ``(section, at)``, 0-based, in the files'
    order) tilting less than one before it by over :data:`TILT_ORDER_MARGIN_DEG`, as the
    IMUs' columns in another order than the robot file's give it; the yaws then go to
    the wrong IMUs. A tilt reads at most 180 degrees: an outer IMU bent further reads
    less, so the order is judged only where the sections between them (their
    ``theta_max``, rad, by section) cannot bend it past 180 degrees."""
    order = sorted(range(len(places)), key=lambda i: places[i])
    for inner, outer in zip(order, order[1:]):
        a, b = yaws[inner].tilt_deg, yaws[outer].tilt_deg
        between = math.degrees(_bend_between(places[inner], places[outer], theta_max))
        folded = 360.0 - b - a <= between  # the outer IMU may be bent past 180 degrees
        if b < a - TILT_ORDER_MARGIN_DEG and not folded:
            return (
                f"IMU {outer + 1} tilts up to {b:.0f} deg in the bend, less than IMU "
                f"{inner + 1} nearer the base ({a:.0f} deg): with every section bent the same "
                "way an IMU further out tilts at least as far; are the recordings' IMU "
                "columns in the robot file's order? (each yaw goes to the IMU of its columns)"
            )
    return ""


def _bend_between(
    inner: tuple[int, float], outer: tuple[int, float], theta_max: Sequence[float]
) -> float:
    """The most the backbone between two places ``(section, at)`` (0-based) can bend,
    rad: each section's ``theta_max`` over the share of it between them."""
    (s0, a0), (s1, a1) = inner, outer
    if s0 == s1:
        return (a1 - a0) * theta_max[s0]
    return (1.0 - a0) * theta_max[s0] + sum(theta_max[s0 + 1 : s1]) + a1 * theta_max[s1]


#: An IMU's yaw from the bend this far (deg) from the robot's own yaw is doubtful where
#: every IMU's is (:func:`bend_plane_warning`): nearer a quarter turn than none.
BEND_YAW_TURN_DEG = 45.0
#: ... and every IMU's turn lies within this many degrees of their mean turn (boards
#: mounted by hand differ by a few degrees; a bend in another plane turns all alike).
BEND_YAW_AGREEMENT_DEG = 15.0


def bend_plane_warning(
    yaws: Sequence[YawCalibration], robot_yaws: Sequence[float], phi_deg: float, robot_file: bool
) -> str:
    """``""``, or why the yaws from a bend may be those of a bend in another plane than
    ``phi_deg``: every IMU's yaw turned from the robot's own (``robot_yaws``, deg: the
    robot file's, 0 without one) by over :data:`BEND_YAW_TURN_DEG`, all by the same turn
    within :data:`BEND_YAW_AGREEMENT_DEG`. A bend towards ``phi_deg + d`` reads as IMUs
    turned by ``-d`` about the tangent, and nothing in the readings tells the two apart:
    a robot bent the other way (``d = 180``) or in the other plane (``d = +-90``) gives
    every IMU a yaw a quarter or half turn off, silently. Boards that are turned so
    declare it with their yaw in the robot file (as the file written with these yaws
    does), which silences this."""
    turns = np.radians([_wrap_deg(y.yaw_deg - own) for y, own in zip(yaws, robot_yaws)])
    mean = math.atan2(float(np.mean(np.sin(turns))), float(np.mean(np.cos(turns))))
    spread = np.degrees(np.abs(np.angle(np.exp(1j * (turns - mean)))))
    turn = math.degrees(mean)
    if not (abs(turn) > BEND_YAW_TURN_DEG and np.all(spread <= BEND_YAW_AGREEMENT_DEG)):
        return ""
    each = "; ".join(
        f"IMU {i}: {y.yaw_deg:.1f} against {own:g}"
        for i, (y, own) in enumerate(zip(yaws, robot_yaws), start=1)
    )
    own = "the robot file's" if robot_file else "the robot's (0: no robot file gives one)"
    every = "every IMU's yaw" if len(yaws) > 1 else "the IMU's yaw"
    given = f"{phi_deg:g}" + (" (towards base -x)" if phi_deg == 0 else "")
    return (
        f"{every} from the bend is {own} turned by {_wrap_deg(round(turn)):g} degrees "
        f"({each}): a bend towards phi = {_wrap_deg(round(phi_deg - turn)):g} instead of "
        f"--bend-phi's {given} reads so. Was the robot bent the other way, or in another "
        "plane? Record the bend again towards --bend-phi, or give the plane it was bent in "
        "(--bend-phi). Are the boards turned so about the backbone? Then the yaws written "
        "are right and the robot file's were not"
    )
