"""Unit checks of raw IMU readings: an accelerometer in g or in raw counts, a gyro in
deg/s (by its median rate, or against the turn of gravity's direction that the
accelerometer shows, at rest and in motion), and times a thousand times too long (the
gyro's turn against the accelerometer's). Each check names the file or IMU and the fix
in one line."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, TimeUnitError
from continuum_mhe.io.csv_files import UnitWarning
from continuum_mhe.model.imu import STANDARD_GRAVITY

#: Median |a| in this band (in the file's unit) means the file is in g, not m/s^2.
_LOOKS_LIKE_G = (0.5, 2.0)
#: Median |omega| above this (rad/s, 286 deg/s: turning most of the time faster than
#: most continuum robots ever do; the shipped rod recordings' largest median is 2.7)
#: means the gyro is in deg/s, not rad/s. A deg/s file whose median rate stays below
#: 5 deg/s is not caught (its rates are small either way).
GYRO_MEDIAN_MAX = 5.0
#: A stream's units are checked on the medians of its first samples, at least this many
#: (1 s at 100 Hz) over at least :data:`UNIT_CHECK_SPAN_S`, where a recording's are
#: checked on all of them.
UNIT_CHECK_SAMPLES = 100
UNIT_CHECK_SPAN_S = 1.0
#: The gravity check of a gyro's units (:func:`gyro_gravity_problem`) compares the
#: accelerometer's direction with the gyro's turn over stretches of this length (s), of
#: at least :data:`GRAVITY_TURN_ROWS` readings (a recording sampled more slowly than
#: that, under 11 Hz, is judged over stretches of :data:`GRAVITY_TURN_ROWS` and a half
#: of its median step, the mismatch allowed growing with the stretch:
#: :func:`gravity_turn_span`), ...
GRAVITY_TURN_SPAN_S = 0.5
GRAVITY_TURN_ROWS = 5
#: ... and not at all where those stretches would be longer than this (s): a recording
#: sampled below about 1 Hz, or one whose times are in another unit (ms read as s),
#: which the time checks name
GRAVITY_TURN_SPAN_MAX_S = 6.0
#: ... where the IMU is still: its specific force's magnitude spreads by at most this
#: fraction of its mean over the stretch (the noise of a MEMS accelerometer at rest is
#: about 0.5 %; a swing's own acceleration is more) ...
GRAVITY_TURN_ACCEL_SPREAD = 0.01
#: ... and its rates are steady, as a bias: their spread (the norm of the axes' standard
#: deviations) at most this fraction of their mean rate's magnitude ...
GRAVITY_TURN_RATE_SPREAD = 0.5
#: ... and not frozen: a stretch in which both sensors repeat their first reading to
#: within this (the accelerometer: a fraction of its magnitude; the gyro: in the file's
#: unit, tiny in rad/s and in deg/s alike) says nothing of the gyro's unit (a stuck
#: IMU's rates turn no accelerometer); a live IMU's noise is a thousand times more. The
#: unit check runs before any noise model, so these are not ``FREEZE_TOLERANCE``'s; a
#: still gyro that repeats alone (coarsely quantised) is judged ...
FROZEN_ACCEL_SPREAD = 1e-6
FROZEN_GYRO_SPREAD = 1e-4
#: ... and finds deg/s where the gyro, read as rad/s, misses the accelerometer's turn by
#: more than this (rad, 6 deg) in the median stretch: a MEMS gyro's bias in rad/s
#: (under 0.05, a cheap one's 0.09) turns a direction by about 1.5 (2.5) deg in a
#: stretch, one of 1 deg/s read as rad/s by 29 deg, of 0.4 deg/s by 11 deg.
GRAVITY_TURN_MISMATCH = math.radians(6.0)
#: A still gyro in rad/s whose zero-rate offset across gravity exceeds about 12 deg/s
#: (some MEMS parts allow 20) reads as deg/s there too: a turn tells the two apart. A
#: stretch in which the gravity direction turns by more than this (rad) as the gyro read
#: as rad/s, less its median (the offset), says shows rad/s
#: (:func:`_turns_as_rad_s`): a gyro in deg/s, read so, turns it 57 times too far, and a
#: push of the IMU that turns its specific force this far changes its magnitude by more
#: than :data:`GRAVITY_TURN_ACCEL_SPREAD`. At least :data:`RAD_S_TURN_STRETCHES` such
#: stretches clear the gyro.
RAD_S_TURN_MIN = math.radians(12.0)
RAD_S_TURN_STRETCHES = 2
#: An acceleration (m/s^2) or a rate (rad/s) of a larger magnitude is beyond any IMU's
#: range (high-g accelerometers end near 4,000 m/s^2, MEMS gyros near 70 rad/s): a
#: corrupt value, not a reading.
ACCEL_READING_MAX = 1e4
GYRO_READING_MAX = 1e3
#: :func:`check_accel_range` judges an accelerometer's unit on at least this many rows
#: (a block of fewer, such as a file's last rows, holds corrupt values at most).
ACCEL_RANGE_ROWS = 10


def check_accel_range(label: str, acc_norm: FloatArray) -> None:
    """An accelerometer most of whose readings (magnitudes ``acc_norm`` of its finite
    rows, m/s^2; at least :data:`ACCEL_RANGE_ROWS` of them) are beyond any IMU's range
    is in another unit (raw counts): a one-line :class:`InputError` naming ``label``,
    rather than every reading a dropout (a few corrupt values stay dropouts)."""
    finite = acc_norm[np.isfinite(acc_norm)]
    if len(finite) < ACCEL_RANGE_ROWS or 2 * int((finite > ACCEL_READING_MAX).sum()) <= len(finite):
        return
    raise InputError(
        f"{label}: accelerometer magnitude is about {float(np.median(finite)):.3g} (median), "
        f"beyond any IMU's range in m/s^2 (limit {ACCEL_READING_MAX:g}): raw counts? "
        "give m/s^2 (counts times g over the counts per g, e.g. 9.81 / 16384 at +-2 g)"
    )


#: Other units an accelerometer's readings come in: the unit, and the factor from m/s^2
#: (a median magnitude within :data:`_LOOKS_LIKE_G` times g in it is refused).
_OTHER_ACCEL_UNITS = (
    ("cm/s^2 (or milli-g, which reads 1000 at rest)", 100.0,
     "cm/s^2: divide by 100; milli-g: multiply by 0.00980665"),
    ("mm/s^2", 1000.0, "divide by 1000"),
)  # fmt: skip


def check_accel_units(path: Path | str, acc: FloatArray) -> None:
    """An accelerometer whose median magnitude is about 1 (within :data:`_LOOKS_LIKE_G`)
    is in g, not m/s^2, and one whose median is about 100 or 1000 times g is in cm/s^2
    or mm/s^2: a one-line :class:`InputError` naming ``path``."""
    norm = np.linalg.norm(acc, axis=1)
    norm = norm[np.isfinite(norm)]
    if not len(norm):
        return
    median = float(np.median(norm))
    if _LOOKS_LIKE_G[0] < median < _LOOKS_LIKE_G[1]:
        raise InputError(
            f"{path}: accelerometer magnitude is about {median:.2f}: the "
            f"values look like g; ax, ay, az must be in m/s^2 (multiply by {STANDARD_GRAVITY})"
        )
    for unit, factor, fix in _OTHER_ACCEL_UNITS:
        g = STANDARD_GRAVITY * factor
        if _LOOKS_LIKE_G[0] * g < median < _LOOKS_LIKE_G[1] * g:
            raise InputError(
                f"{path}: accelerometer magnitude is about {median:.4g}: the values look "
                f"like {unit}; ax, ay, az must be in m/s^2 ({fix})"
            )


def gyro_units_problem(gyr: FloatArray, names: str = "gx, gy, gz") -> str | None:
    """Where the median magnitude of a gyro's readings ``gyr`` (n, 3) exceeds
    :data:`GYRO_MEDIAN_MAX` rad/s (deg/s given for rad/s): what to say, naming the
    columns ``names``; else None. Non-finite rows are left out."""
    norm = np.linalg.norm(gyr, axis=1)
    norm = norm[np.isfinite(norm)]
    if not len(norm) or float(np.median(norm)) <= GYRO_MEDIAN_MAX:
        return None
    return (
        f"gyro magnitude is about {float(np.median(norm)):.3g} (median), implausible in "
        f"rad/s (above {GYRO_MEDIAN_MAX:g}): deg/s? give rad/s ({names} times pi/180 = "
        f"{math.pi / 180:.7f})"
    )


def gravity_turn_span(t: FloatArray) -> float:
    """The length (s) of the gravity check's stretches for the times ``t``:
    :data:`GRAVITY_TURN_SPAN_S`, or, where that holds fewer than
    :data:`GRAVITY_TURN_ROWS` steps of the median step (a recording under 11 Hz),
    :data:`GRAVITY_TURN_ROWS` and a half steps, so that each stretch holds
    :data:`GRAVITY_TURN_ROWS` readings or more."""
    t = np.asarray(t, float)
    steps = np.diff(t[np.isfinite(t)])
    steps = steps[steps > 0]
    if not len(steps):
        return GRAVITY_TURN_SPAN_S
    return max(GRAVITY_TURN_SPAN_S, (GRAVITY_TURN_ROWS + 0.5) * float(np.median(steps)))


def _turn_errors(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, span: float = GRAVITY_TURN_SPAN_S
) -> FloatArray:
    """Per still stretch of ``span`` s (:func:`gravity_turn_span`): the angle (rad) between the
    accelerometer's last direction and its first one turned by the gyro's summed rates
    (one rotation vector: exact for a rate of constant direction, such as a resting
    gyro's bias), the gyro read as rad/s (column 0) and as deg/s (column 1); (k, 2).

    A stretch is judged where it has at least :data:`GRAVITY_TURN_ROWS` finite rows, its
    specific force's magnitude spreads by at most :data:`GRAVITY_TURN_ACCEL_SPREAD` of
    its mean (no acceleration of the IMU's own: a swinging IMU's specific force turns
    with it) and its rates by at most :data:`GRAVITY_TURN_RATE_SPREAD` of their mean (a
    steady rate, as a bias; a swing's rates change sign). Rows are paired with the next
    row of their own stretch only (a gap or a short stretch adds nothing). A stretch in
    which both sensors are frozen (:data:`FROZEN_ACCEL_SPREAD`, :data:`FROZEN_GYRO_SPREAD`)
    is not judged."""
    ok = np.isfinite(t) & np.isfinite(acc).all(axis=1) & np.isfinite(gyr).all(axis=1)
    t, acc, gyr = t[ok], acc[ok], gyr[ok]
    norm = np.linalg.norm(acc, axis=1)
    t, acc, gyr, norm = t[norm > 0], acc[norm > 0], gyr[norm > 0], norm[norm > 0]
    if len(t) < GRAVITY_TURN_ROWS:
        return np.zeros((0, 2))
    direction = acc / norm[:, None]
    stretch = np.floor((t - t[0]) / span).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, np.diff(stretch) != 0])
    stops = np.r_[starts[1:], len(t)]
    count = (stops - starts).astype(float)
    # each row's rate over the step to the next row of its own stretch
    step = np.r_[np.diff(t), 0.0]
    step[stops - 1] = 0.0
    turn = np.add.reduceat(gyr * step[:, None], starts, axis=0)
    norm_mean = np.add.reduceat(norm, starts) / count
    norm_var = np.add.reduceat(norm**2, starts) / count - norm_mean**2
    rate_mean = np.add.reduceat(gyr, starts, axis=0) / count[:, None]
    rate_var = np.add.reduceat(gyr**2, starts, axis=0) / count[:, None] - rate_mean**2
    # each row's largest departure from its stretch's first reading, per sensor
    of_stretch = np.repeat(np.arange(len(starts)), stops - starts)
    acc_moved = np.maximum.reduceat(np.abs(acc - acc[starts][of_stretch]).max(axis=1), starts)
    gyr_moved = np.maximum.reduceat(np.abs(gyr - gyr[starts][of_stretch]).max(axis=1), starts)
    frozen = (acc_moved <= FROZEN_ACCEL_SPREAD * norm_mean) & (gyr_moved <= FROZEN_GYRO_SPREAD)
    still = (
        ~frozen
        & (count >= GRAVITY_TURN_ROWS)
        & (np.sqrt(np.maximum(norm_var, 0.0)) <= GRAVITY_TURN_ACCEL_SPREAD * norm_mean)
        & (
            np.sqrt(np.maximum(rate_var, 0.0).sum(axis=1))
            <= GRAVITY_TURN_RATE_SPREAD * np.linalg.norm(rate_mean, axis=1)
        )
    )
    if not still.any():
        return np.zeros((0, 2))
    first, last, turn = direction[starts[still]], direction[stops[still] - 1], turn[still]
    errors = np.empty((len(first), 2))
    moved = np.arccos(np.clip(np.sum(first * last, axis=1), -1.0, 1.0))  # the direction's own
    for col, scale in enumerate((1.0, math.pi / 180.0)):
        # a direction fixed in the world turns in the IMU's frame as dv/dt = -w x v
        turned = _rotated_by_vectors(first, -scale * turn)
        errors[:, col] = np.arccos(np.clip(np.sum(turned * last, axis=1), -1.0, 1.0))
        # the angle above wraps: a turn of about a whole turn (deg/s read as rad/s over
        # the long stretches of a slow recording) would seem to follow gravity. Beyond a
        # half turn, the turn across the direction less the direction's own move is a
        # mismatch that does not wrap
        across = np.linalg.norm(np.cross(scale * turn, first), axis=1)
        beyond = np.linalg.norm(scale * turn, axis=1) > math.pi
        errors[beyond, col] = np.maximum(errors[beyond, col], (across - moved)[beyond])
    return errors


def _rotated_by_vectors(v: FloatArray, rotvec: FloatArray) -> FloatArray:
    """Each row of ``v`` (n, 3) turned by the rotation vector in the same row of
    ``rotvec`` (n, 3; axis times angle, rad), by Rodrigues' formula: what
    ``scipy.spatial.transform.Rotation.from_rotvec(rotvec).apply(v)`` gives, without
    importing it (slow to import for one formula)."""
    angle = np.linalg.norm(rotvec, axis=1)
    # the axis of a zero turn is any: the formula's terms vanish with it
    axis = rotvec / np.where(angle > 0.0, angle, 1.0)[:, None]
    cos, sin = np.cos(angle)[:, None], np.sin(angle)[:, None]
    along = np.sum(axis * v, axis=1)[:, None] * axis
    return v * cos + np.cross(axis, v) * sin + along * (1.0 - cos)


def gyro_gravity_problem(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, names: str = "gx, gy, gz"
) -> str | None:
    """A gyro in deg/s whose rates are too small for :func:`gyro_units_problem`, told by
    the accelerometer: on its still stretches (:func:`_still_gyro_problem`: an IMU at
    rest with its bias), else on the turns of its motion (:func:`gyro_motion_problem`:
    a bias too small to tell, a recording that starts at rest or moves slowly). What to
    say, naming the columns ``names``, else None."""
    return _still_gyro_problem(t, acc, gyr, names) or gyro_motion_problem(t, acc, gyr, names)


def _still_gyro_problem(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, names: str = "gx, gy, gz"
) -> str | None:
    """A gyro in deg/s whose rates are too small for :func:`gyro_units_problem` (an IMU
    at rest with its bias), told by the accelerometer: where, over the still stretches
    of the times ``t`` (n,) s (:func:`_turn_errors`: the specific force ``acc`` (n, 3;
    any unit) steady in magnitude, the rates ``gyr`` (n, 3) steady), the rates read as
    rad/s would turn the gravity direction by more than :data:`GRAVITY_TURN_MISMATCH`
    rad in the median stretch of :data:`GRAVITY_TURN_SPAN_S` (in proportion over the
    longer stretches of a recording under 11 Hz: :func:`gravity_turn_span`), while read
    as deg/s they follow it at least three times as closely: what to say, naming the
    columns ``names``; else None (also with fewer than two still stretches, and where
    the stretches would be longer than :data:`GRAVITY_TURN_SPAN_MAX_S`, and where at
    least :data:`RAD_S_TURN_STRETCHES` stretches turn the gravity direction as the rates
    read as rad/s say (:func:`_turns_as_rad_s`): a turn shows rad/s where the still
    stretches cannot tell a gyro in deg/s from a rad/s gyro's large offset). A turn
    about the vertical moves no accelerometer and says nothing."""
    t = np.asarray(t, float)
    span = gravity_turn_span(t)
    if span > GRAVITY_TURN_SPAN_MAX_S:
        return None
    errors = _turn_errors(t, np.asarray(acc, float), np.asarray(gyr, float), span)
    if len(errors) < 2:
        return None
    as_rad, as_deg = (float(v) for v in np.median(errors, axis=0))
    if as_rad <= GRAVITY_TURN_MISMATCH * span / GRAVITY_TURN_SPAN_S or as_deg * 3.0 > as_rad:
        return None
    if _turns_as_rad_s(t, np.asarray(acc, float), np.asarray(gyr, float), span):
        return None
    return (
        "the accelerometer's gravity direction turns as the gyro says only with the gyro "
        f"in deg/s (read as rad/s it misses by {math.degrees(as_rad):.0f} deg every "
        f"{span:.3g} s, median; read as deg/s by {math.degrees(as_deg):.1f} "
        f"deg; in rad/s it would need a zero-rate offset of {math.degrees(as_rad) / span:.0f} "
        "deg/s across gravity, beyond most MEMS gyros': where yours has one, subtract it "
        "on the board, or record the IMU turning about a horizontal axis too, which tells "
        f"the units apart): give rad/s ({names} times pi/180 = {math.pi / 180:.7f})"
    )


def _turns_as_rad_s(t: FloatArray, acc: FloatArray, gyr: FloatArray, span: float) -> bool:
    """Whether at least :data:`RAD_S_TURN_STRETCHES` stretches of ``span`` s
    (:func:`_turn_errors`) turn the gravity direction by more than
    :data:`RAD_S_TURN_MIN` as the rates ``gyr`` (n, 3), read as rad/s less their
    per-axis median (a still gyro's offset), say: to within a third of the miss read as
    deg/s. A gyro in deg/s, read so, turns it 57 times too far."""
    finite = np.isfinite(gyr).all(axis=1)
    if not finite.any():
        return False
    errors = _turn_errors(t, acc, gyr - np.median(gyr[finite], axis=0), span)
    turned = (errors[:, 1] > RAD_S_TURN_MIN) & (3.0 * errors[:, 0] <= errors[:, 1])
    return int(np.count_nonzero(turned)) >= RAD_S_TURN_STRETCHES


#: The time check of a raw recording (:func:`time_unit_problem`) cuts the rows into
#: windows, each as long as the gyro's rates, taken over a thousandth of each step of
#: ``t``, need to turn the gravity direction by this (rad) ...
TIME_CHECK_MIN_TURN = 0.1
#: ... and judges at least this many such windows ...
TIME_CHECK_WINDOWS = 5
#: ... where the accelerometer's direction follows that turn to within this fraction of
#: it (median), while the turn over each step as given misses it by more than
#: :data:`TIME_CHECK_MIN_TURN` and by this factor more than the thousandth's. The check
#: of a gyro in deg/s in motion (:func:`gyro_motion_problem`) is the same with the rates
#: taken pi/180 times instead of a thousandth (:func:`_scaled_turn_evidence`): it finds
#: none in the shipped recordings (rad/s); with their gyros in deg/s it finds them in
#: every IMU of every motion but the tendon robot's planar-s IMU 2 (its turns across
#: gravity too small), following to 0.3 to 1.3 deg of turns of about 6 deg, the rates
#: read as rad/s missing by over 300 deg.
TIME_CHECK_FOLLOW = 0.35
TIME_CHECK_RATIO = 5.0
#: The rows examined, at most (the first ones), and the longest window.
TIME_CHECK_ROWS = 100_000
TIME_CHECK_WINDOW_ROWS = 20_000


def _angles(a: FloatArray, b: FloatArray) -> FloatArray:
    """The angles (rad) between the unit vectors of the rows of ``a`` and ``b``."""
    return np.arccos(np.clip(np.sum(a * b, axis=1), -1.0, 1.0))


def _scaled_turn_evidence(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, scale: float, unwrap: bool = False
) -> tuple[int, float, float, float] | None:
    """Whether the rates ``gyr`` (n, 3) over the times ``t`` (n,) s, taken ``scale``
    times (a thousandth: times in ms read as s; pi/180: a gyro in deg/s read as rad/s),
    turn the specific force's direction ``acc`` (n, 3; any unit) as the accelerometer
    shows, where as given they do not; on positive evidence only: the rows (finite, the
    first :data:`TIME_CHECK_ROWS`) are cut into consecutive windows over which the
    rates (the mean of a step's two rows) taken ``scale`` times turn the direction by
    :data:`TIME_CHECK_MIN_TURN` across it; with at least :data:`TIME_CHECK_WINDOWS` of
    them, where the accelerometer's direction at a window's end follows that turn
    (median miss within :data:`TIME_CHECK_FOLLOW` of the turn) and the turn as given
    misses it by more than :data:`TIME_CHECK_MIN_TURN` and :data:`TIME_CHECK_RATIO`
    times as much: ``(windows, miss taken scale times, miss as given, turn)``, the
    misses and the turn as medians in rad; else None. With ``unwrap``, a turn as given
    beyond half a turn misses by at least its part across the direction less the
    direction's own move (the angle between two directions wraps: deg/s read as rad/s
    turns a window's :data:`TIME_CHECK_MIN_TURN` into 5.7 rad, near a whole turn, which
    would seem to follow). A gyro that reads more than the IMU turns (a bias) or an
    accelerometer that does not follow gravity (a swing's own acceleration) gives no
    such evidence."""
    t, acc, gyr = (np.asarray(a, float) for a in (t, acc, gyr))
    norm = np.linalg.norm(acc, axis=1)
    ok = np.isfinite(t) & np.isfinite(acc).all(axis=1) & np.isfinite(gyr).all(axis=1) & (norm > 0)
    keep = np.flatnonzero(ok)[:TIME_CHECK_ROWS]
    if len(keep) < 2 * TIME_CHECK_WINDOWS:
        return None
    t, direction, gyr = t[keep], acc[keep] / norm[keep, None], gyr[keep]
    step = np.diff(t)
    if not (step > 0).all():
        return None
    # the turn of a direction fixed in the world, seen in the IMU's frame: dv/dt = -w x v;
    # the summed rotation vector from row 0 (exact for a turn about one axis)
    turn = np.vstack(
        [np.zeros(3), np.cumsum(-scale * 0.5 * (gyr[:-1] + gyr[1:]) * step[:, None], axis=0)]
    )
    ends: list[tuple[int, int]] = []
    i = 0
    while i < len(t) - 1:
        j = _window_end(turn, direction[i], i)
        if j is None:
            if i + 1 + TIME_CHECK_WINDOW_ROWS >= len(t):
                break
            i += TIME_CHECK_WINDOW_ROWS  # a still stretch: the next window starts after it
            continue
        ends.append((i, j))
        i = j
    if len(ends) < TIME_CHECK_WINDOWS:
        return None
    from scipy.spatial.transform import Rotation  # here: a tilt run imports no SciPy

    first, last = (np.asarray(ix) for ix in zip(*ends))
    rotvec = turn[last] - turn[first]
    start = direction[first]
    moved = _angles(start, direction[last])  # the direction's own move
    medians = []
    for factor in (1.0, 1.0 / scale):
        predicted = Rotation.from_rotvec(factor * rotvec).apply(start)
        miss = _angles(predicted, direction[last])
        if unwrap:
            across = np.linalg.norm(np.cross(factor * rotvec, start), axis=1)
            beyond = np.linalg.norm(factor * rotvec, axis=1) > math.pi
            miss[beyond] = np.maximum(miss, across - moved)[beyond]
        medians.append(float(np.median(miss)))
    as_scaled, as_given = medians
    turned = float(np.median(_angles(Rotation.from_rotvec(rotvec).apply(start), start)))
    if (
        as_scaled > TIME_CHECK_FOLLOW * turned
        or as_given <= TIME_CHECK_MIN_TURN
        or as_scaled * TIME_CHECK_RATIO > as_given
    ):
        return None
    return len(ends), as_scaled, as_given, turned


#: A window's end is looked for in this many rows first, then in
#: :data:`TIME_CHECK_WINDOW_ROWS` (the same end, found without turning every row ahead
#: where windows are short).
WINDOW_LOOK_ROWS = 256


def _window_end(turn: FloatArray, direction: FloatArray, i: int) -> int | None:
    """The first row after ``i``, within :data:`TIME_CHECK_WINDOW_ROWS`, at which the
    summed rotation vectors ``turn`` (n, 3) have turned ``direction`` (3,) by
    :data:`TIME_CHECK_MIN_TURN` across it since row ``i``; None where none has."""
    for rows in (WINDOW_LOOK_ROWS, TIME_CHECK_WINDOW_ROWS):
        ahead = turn[i + 1 : i + 1 + rows] - turn[i]
        reached = np.flatnonzero(
            np.linalg.norm(np.cross(ahead, direction), axis=1) >= TIME_CHECK_MIN_TURN
        )
        if len(reached):
            return i + 1 + int(reached[0])
        if i + 1 + rows >= len(turn):
            return None
    return None


def time_unit_problem(t: FloatArray, acc: FloatArray, gyr: FloatArray) -> str | None:
    """Times ``t`` (n,) a thousand times too long (milliseconds read as seconds), told by
    the gyro (``gyr`` (n, 3), rad/s) against the accelerometer (``acc`` (n, 3), any
    unit): where the rates taken over a thousandth of each step turn the specific
    force's direction as the accelerometer shows and over the steps as given do not
    (:func:`_scaled_turn_evidence`): what to say (the two misses), else None. A gyro
    that reads more than the IMU turns (a bias, deg/s, counts) gives no such
    evidence."""
    found = _scaled_turn_evidence(t, acc, gyr, 1e-3)
    if found is None:
        return None
    windows, as_thousandth, as_given, turned = found
    return (
        f"over {windows} stretches the accelerometer's gravity direction turns as the "
        "gyro's rates say over a thousandth of the steps of t (to a median of "
        f"{math.degrees(as_thousandth):.1f} deg of a {math.degrees(turned):.1f}-deg turn), "
        f"not over the steps as given (to {math.degrees(as_given):.0f} deg)"
    )


def gyro_motion_problem(
    t: FloatArray, acc: FloatArray, gyr: FloatArray, names: str = "gx, gy, gz"
) -> str | None:
    """A gyro in deg/s told by the turns of a motion (a recording that starts at rest, or
    moves slowly, whose median rate stays below :data:`GYRO_MEDIAN_MAX` and whose still
    stretches' bias is too small for :func:`gyro_gravity_problem`'s still check):
    where the rates ``gyr`` (n, 3) taken as deg/s turn the accelerometer's gravity
    direction (``acc`` (n, 3), any unit; times ``t`` (n,) s) as it turns, and read as
    rad/s turn it 57 times too far (:func:`_scaled_turn_evidence`): what to say, naming
    the columns ``names``; else None."""
    found = _scaled_turn_evidence(t, acc, gyr, math.pi / 180.0, unwrap=True)
    if found is None:
        return None
    windows, as_deg, as_rad, turned = found
    return (
        f"over {windows} stretches of its motion the accelerometer's gravity direction turns "
        "as the gyro says only with the gyro in deg/s (to a median of "
        f"{math.degrees(as_deg):.1f} deg of a {math.degrees(turned):.1f}-deg turn; read as "
        "rad/s they say a turn 57 times as large, which it misses by a median of "
        f"{math.degrees(as_rad):.0f} deg): give rad/s ({names} times pi/180 = "
        f"{math.pi / 180:.7f})"
    )


class MotionUnitWatch:
    """The units that a stream's motion tells, over the first :data:`TIME_CHECK_ROWS`
    rows of a stream read in blocks, each IMU's rows gathered from block to block (a
    still start longer than a block gives no evidence in its first one): times a
    thousand times too long (:func:`check_time_unit`), and, from an IMU's second block
    on, a gyro in deg/s that the estimate uses (:func:`gyro_motion_problem`; the first
    block's gyro is judged by :func:`check_gyro_units`)."""

    def __init__(self, time_scale: float) -> None:
        self.time_scale = time_scale
        self._rows: dict[str, list[FloatArray]] = {}
        self._count: dict[str, int] = {}

    def add(
        self, label: str, t: FloatArray, acc: FloatArray, gyr: FloatArray, gyro_used: bool = False
    ) -> None:
        """Take a block of IMU ``label``'s rows (``t`` s, ``acc``, ``gyr`` as
        :func:`time_unit_problem` takes them) and check its rows so far: a one-line
        :class:`InputError` where they are a thousand times too long, or, where the
        estimate uses the gyro (``gyro_used``) and this is not the IMU's first block,
        where its rates turn the accelerometer's gravity direction as deg/s do."""
        seen = self._count.get(label, 0)
        if seen >= TIME_CHECK_ROWS:
            return
        take = TIME_CHECK_ROWS - seen  # the rows beyond are never judged
        self._rows.setdefault(label, []).append(np.column_stack([t, acc, gyr])[:take])
        self._count[label] = seen + min(len(t), take)
        rows = np.vstack(self._rows[label])
        check_time_unit(label, rows[:, 0], rows[:, 1:4], rows[:, 4:7], self.time_scale)
        if gyro_used and len(self._rows[label]) > 1:
            problem = gyro_motion_problem(rows[:, 0], rows[:, 1:4], rows[:, 4:7])
            if problem is not None:
                raise InputError(f"{label}: {problem}")
        if self._count[label] >= TIME_CHECK_ROWS:
            del self._rows[label]  # judged: the memory goes


def check_time_unit(
    name: str, t: FloatArray, acc: FloatArray, gyr: FloatArray, time_scale: float
) -> None:
    """A one-line :class:`InputError` where :func:`time_unit_problem` finds the times of
    ``name`` (s; read from a ``t`` column, or ``t_ms`` where ``time_scale`` is 1e-3) a
    thousand times too long."""
    problem = time_unit_problem(t, acc, gyr)
    if problem is None:
        return
    fix = (
        "t_ms looks like microseconds: give milliseconds"
        if time_scale == 1e-3
        else "t looks like milliseconds: name the column t_ms (t is read in seconds; "
        "microseconds: divide them by 1000 first)"
    )
    raise TimeUnitError(f"{name}: {problem}: {fix}")


def check_gyro_units(
    path: Path | str,
    gyr: FloatArray,
    used: bool = True,
    t: FloatArray | None = None,
    acc: FloatArray | None = None,
) -> None:
    """A gyro whose median magnitude exceeds :data:`GYRO_MEDIAN_MAX` rad/s looks like deg/s
    (:func:`gyro_units_problem`), and so does one whose rates, given its times ``t`` and
    accelerometer ``acc``, turn the gravity direction as deg/s would, at rest or in
    motion (:func:`gyro_gravity_problem`): an error where the estimate uses it
    (``used``), else one warning (it is ignored)."""
    problem = gyro_units_problem(gyr)
    if problem is None and t is not None and acc is not None:
        problem = gyro_gravity_problem(t, acc, gyr)
    if problem is not None:
        msg = f"{path}: {problem}"
        if used:
            raise InputError(msg)
        warnings.warn(
            f"{msg}; these options do not use the gyro, so the estimate is unaffected",
            UnitWarning,
            stacklevel=2,
        )
