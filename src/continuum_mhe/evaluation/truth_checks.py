"""The checks of a truth against an estimate that ``evaluate``, ``plot`` and ``view``
share: too few of the estimate's rows with a truth (:func:`rows_matched`), a truth of
part of the estimate's times (:func:`truth_covers_part`), a truth on an
offset clock (:func:`clock_offset_warning`), a truth whose tip points away from its own
bend angles (:func:`truth_frame_warning`), a truth in another frame than the estimate's
(:func:`frame_fit_warning`); ``plot`` and ``view`` take them together
(:func:`truth_beside`)."""

from __future__ import annotations

import math

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.evaluation.estimate_tables import lengths_misfit, truth_at_rows, truth_problem
from continuum_mhe.evaluation.metrics import (
    INTERPOLATE_STEP,
    SHIFT_MAX_S,
    FrameRotation,
    TimeShift,
    aligned_truth,
    best_rotation,
    best_time_shift,
    length_misfit,
    match_rows,
)
from continuum_mhe.io.csv_files import MS_LIKE_STEP_S
from continuum_mhe.io.position_units import tip_direction_problem
from continuum_mhe.io.state_tables import StateTable
from continuum_mhe.model.descriptions import TIP_COLUMNS, section_end_columns, sections_with_ends

#: ``evaluate`` warns where the truth shifted in time fits the estimate with a mean tip
#: error below this share of the unshifted one, itself at least :data:`SHIFT_MIN_ERROR`
#: of the robot's length (a motion capture 40 ms off a good estimate's clock tripled its
#: 2.5 mm error on a 0.3 m robot, to 7 mm).
SHIFT_GAIN = 0.5
SHIFT_MIN_ERROR = 0.01


def clock_offset_warning(
    path: str,
    est: StateTable,
    truth: StateTable,
    length: float,
    tip_mean: float,
    shift_option: str = "--truth-shift",
    given_shift: float = 0.0,
) -> str:
    """A warning where the truth ``path`` (``truth``) looks on a clock offset from the
    estimate ``est``'s (a shift of the truth within :data:`SHIFT_MAX_S` s fits far better:
    :func:`~continuum_mhe.evaluation.metrics.best_time_shift`), else ``""``; not looked
    for where the mean tip error ``tip_mean`` (m) on a robot of ``length`` m is already
    small. A best shift at the edge of the search says that the offset may be larger.
    ``shift_option``: how the command line compares the files shifted (``evaluate``'s
    ``--truth-shift``); ``given_shift``: the shift (s) already applied to ``truth``, which
    the shift advised includes."""
    if not tip_mean >= SHIFT_MIN_ERROR * length:  # close enough: no shift to look for
        return ""
    found = _clock_shift(est, truth, length)
    if found is None:
        return ""
    what, shift = found
    given = seconds_text(given_shift)
    as_given = f"at {shift_option} {given}" if given_shift else "as the times match"
    later = f"s later than {shift_option} {given} puts it" if given_shift else "s later"
    fits = (
        f"({what} {shift.error * 1e3:.3g} mm against {shift.unshifted * 1e3:.3g} mm "
        f"{as_given}): are the two files' clocks offset?"
    )
    if abs(shift.shift_s) >= SHIFT_MAX_S - 0.05:  # at the edge: the offset may be larger
        return (
            f"{path}: the truth fits the estimate better {shift.shift_s:+.3g} {later}, at the "
            f"edge of the +-{SHIFT_MAX_S:g} s searched {fits} The offset may be larger; find "
            f"the shift that fits with {shift_option} (a motion that repeats fits shifted too)"
        )
    total = seconds_text(given_shift + shift.shift_s)
    return (
        f"{path}: the truth fits the estimate best {shift.shift_s:+.3g} {later} {fits} (a "
        f"motion that repeats can fit shifted too; {shift_option} {total} "
        "compares them so)"
    )


def _clock_shift(est: StateTable, truth: StateTable, length: float) -> tuple[str, TimeShift] | None:
    """The words for a point's error and the shift of the truth's clock that fits the
    estimate far better there
    (:func:`~continuum_mhe.evaluation.metrics.best_time_shift`: its mean error below
    :data:`SHIFT_GAIN` of the unshifted one, itself at least :data:`SHIFT_MIN_ERROR` of
    the robot's ``length`` m): the tip's, else the first of the section ends both files
    give (``x_k, y_k, z_k``) that shows one (on a robot whose IMUs do not determine its
    tip, a section end they do determine shows the offset that the tip's error hides);
    None without."""
    points: list[tuple[str, tuple[str, ...]]] = [("mean tip error", tuple(TIP_COLUMNS))]
    for k in sections_with_ends(est.names):
        end = section_end_columns(k)
        if all(c in truth.names for c in end):
            points.append((f"mean error of section {k}'s end", end))
    for what, columns in points:
        e = est.values[:, [est.names.index(c) for c in columns]]
        shift = best_time_shift(
            est.t, e, truth.t, truth.values[:, [truth.names.index(c) for c in columns]]
        )
        if (
            shift is not None
            and shift.shift_s != 0.0
            and shift.unshifted >= SHIFT_MIN_ERROR * length
            and shift.error < SHIFT_GAIN * shift.unshifted
        ):
            return what, shift
    return None


#: ``evaluate`` warns where the truth's positions turned about the base by at least
#: :data:`TURN_MIN_DEG` degrees fit the estimate with a mean tip error below
#: :data:`TURN_GAIN` of the unturned one, itself at least :data:`SHIFT_MIN_ERROR` of the
#: robot's length (a truth in a y-up motion capture's frame, beside an estimate in the
#: robot's z-up base frame).
TURN_MIN_DEG = 15.0
TURN_GAIN = 0.5
#: ... or fit it moved by at least this share of the robot's length (a truth about a
#: motion capture's origin; a smaller steady offset is as likely the estimate's own).
MOVED_MIN_SHARE = 0.5
#: ... with its mean tip error then below this share of the one as given (a truth of a
#: longer robot fits a little better moved too, not this well).
MOVED_GAIN = 0.1
#: An axis of the truth within this angle of one of the estimate's (after the best
#: rotation) is named as lying along it.
AXIS_NAMED_DEG = 20.0


#: A turn or move of the truth is looked for only where its tip positions spread over
#: two directions by at least this share of the robot's length (rms, the second singular
#: value): about a line (a still or straight robot, a motion along one axis) the turn
#: about that line is not determined, and any angle fits.
ROTATION_MIN_SPREAD = 0.05


def _spans_a_plane(tip_truth: np.ndarray, length: float, about_mean: bool) -> bool:
    """Whether the finite rows of ``tip_truth`` (n, 3) m spread over two directions by
    :data:`ROTATION_MIN_SPREAD` of ``length`` m, from the base (``about_mean`` False: a
    turn about the base) or about their mean (a turn and a move)."""
    rows = np.asarray(tip_truth, dtype=float)
    rows = rows[np.all(np.isfinite(rows), axis=1)]
    if len(rows) < 3:
        return False
    if about_mean:
        rows = rows - rows.mean(axis=0)
    spread = np.linalg.svd(rows, compute_uv=False) / math.sqrt(len(rows))
    return bool(spread[1] >= ROTATION_MIN_SPREAD * length)


def frame_fit(tip_est: np.ndarray, tip_truth: np.ndarray, length: float) -> FrameRotation | None:
    """The rigid motion that makes the truth's tip positions ``tip_truth`` (n, 3) m fit
    the estimate's ``tip_est`` (n, 3) m at the same rows far better: a turn about the base
    of at least :data:`TURN_MIN_DEG`, or a move of at least :data:`MOVED_MIN_SHARE` of
    the robot's ``length`` m (and a turn)
    (:func:`~continuum_mhe.evaluation.metrics.best_rotation`), whose mean tip error is
    below :data:`TURN_GAIN` (a move: :data:`MOVED_GAIN`) of the one as given, itself at
    least :data:`SHIFT_MIN_ERROR` of the length, and the truth's positions spread over
    two directions (:data:`ROTATION_MIN_SPREAD`); else None."""
    turn = best_rotation(tip_est, tip_truth)
    if turn is None or turn.unturned < SHIFT_MIN_ERROR * length:
        return None
    if (
        turn.angle_deg >= TURN_MIN_DEG
        and turn.error < TURN_GAIN * turn.unturned
        and _spans_a_plane(tip_truth, length, about_mean=False)
    ):
        return turn
    if not _spans_a_plane(tip_truth, length, about_mean=True):
        return None
    turn = best_rotation(tip_est, tip_truth, moved=True)
    if (
        turn is None
        or not moves_the_base(turn, length)
        or not turn.error < MOVED_GAIN * turn.unturned
    ):
        return None
    return turn


def moves_the_base(fit: FrameRotation | None, length: float) -> bool:
    """Whether ``fit`` (:func:`frame_fit`) moves the truth by :data:`MOVED_MIN_SHARE` of
    the robot's ``length`` m or more: a truth about another origin, whose distances from
    the base say nothing of the robot's length."""
    return fit is not None and float(np.linalg.norm(fit.offset)) >= MOVED_MIN_SHARE * length


def frame_fit_warning(path: str, fit: FrameRotation | None, length: float) -> str:
    """The warning of a truth ``path`` that fits the estimate far better turned or moved
    (``fit``, :func:`frame_fit`; ``""`` for None), on a robot of ``length`` m. Where each
    of the truth's axes lies along one of the estimate's, it names them."""
    if fit is None:
        return ""
    named = []
    for column in fit.matrix.T:  # the truth's x, y, z in the estimate's frame
        k = int(np.argmax(np.abs(column)))
        if abs(column[k]) < math.cos(math.radians(AXIS_NAMED_DEG)):
            break
        named.append(("-" if column[k] < 0 else "") + "xyz"[k])
    axes = (
        f"; its x, y and z lie along the estimate's {', '.join(named)}"
        if len(named) == 3 and named != ["x", "y", "z"]
        else ""
    )
    moved = moves_the_base(fit, length)
    how = []
    if fit.angle_deg >= TURN_MIN_DEG:
        how.append(f"turned by {fit.angle_deg:.0f} degrees")
    if moved:
        shown = ", ".join(f"{v * 1e3:.0f}" for v in fit.offset)
        how.append(f"moved by ({shown}) mm")
    where = " and ".join(how) if moved else f"{how[0]} about the base"
    origin = "; about another origin than the robot's base" if moved else ""
    # a turn about the base's z axis is also what an IMU's wrong yaw makes of the
    # estimate (the bending plane it reads turned with it)
    from scipy.spatial.transform import Rotation  # (slow to import: here, where needed)

    axis = Rotation.from_matrix(fit.matrix).as_rotvec()
    about_z = fit.angle_deg >= TURN_MIN_DEG and abs(axis[2]) >= math.cos(
        math.radians(AXIS_NAMED_DEG)
    ) * float(np.linalg.norm(axis))
    yaw = (
        "; or, turned about z, is an IMU's yaw in the robot file wrong (its mount_rpy: a "
        "calibration at rest keeps the file's yaw, calibrate --bend measures it)?"
        if about_z and not moved
        else ""
    )
    return (
        f"{path}: the truth's tip fits the estimate far better {where} (mean tip error "
        f"{fit.error * 1e3:.3g} mm against {fit.unturned * 1e3:.3g} mm as given){axes}: are "
        "its positions in another frame than the robot's base frame (a motion capture's: "
        f"y up, axes swapped, a sign flipped{origin})? The scores compare them as given: "
        "express the truth in the base frame (its origin at the base, z along the unbent "
        f"backbone for mounting z-up, x where the bend angle phi is 0){yaw}"
    )


def seconds_text(value: float, sign: str = "") -> str:
    """``value`` s to the microsecond, without trailing zeros (an epoch time's offset
    keeps its digits); ``sign`` ``"+"``: with its sign."""
    text = f"{value:{sign}.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "+0", "") else text


#: ``evaluate`` refuses files whose times match on fewer than this share of rows (or
#: fewer than 2), and warns below :data:`WARN_MATCHED`, and when the matched rows span
#: less than that share of the truth's time span.
MIN_MATCHED = 0.1
WARN_MATCHED = 0.5


def rows_matched(
    path_est: str,
    path_truth: str,
    compared: int,
    rows: int,
    interpolated: bool,
    truth_spanned: bool = False,
    comparable: int | None = None,
) -> tuple[str, str]:
    """``(problem, warning)`` where ``compared`` of the estimate's ``rows`` have a truth
    (at the same t, or within the truth's times where it is ``interpolated``): the
    refusal below :data:`MIN_MATCHED` of them (or 2), the warning below
    :data:`WARN_MATCHED`; ``""`` for none. ``truth_spanned``: a truth of part of the
    run (:func:`truth_covers_part`, which says it) whose times the rows compared span
    (:func:`spans_the_truth`): no warning here, and no refusal from :data:`PART_ROWS`
    rows. ``comparable``: the rows a truth sparser
    than the estimate could be compared at (:func:`comparable_rows`), the shares' base
    (``rows`` where None)."""
    at = "lie within the times of" if interpolated else "have a row at the same t (within 1 us) in"
    what = (
        f"{path_est}: only {compared} of {rows} rows {at} {path_truth}: "
        "the files' times do not match (another --dt or duration, t in milliseconds, "
        "or the wrong truth file?)"
    )
    of = rows if comparable is None else comparable
    if compared < max(2, MIN_MATCHED * of) and not (truth_spanned and compared >= PART_ROWS):
        return what, ""
    if truth_spanned:  # said by truth_covers_part
        return "", ""
    return "", what if compared < WARN_MATCHED * of else ""


#: A truth's median step this many times the estimate's, or more (and at most
#: :data:`MS_RATIO_MAX` times), is a truth in milliseconds beside an estimate in seconds
#: (where its times read in milliseconds also overlap the estimate's): a thousand for
#: the same rate, a fifth of that for a truth sampled five times as densely...
MS_RATIO_MIN = 200.0
#: ... and five times that for one sampled five times as sparsely.
MS_RATIO_MAX = 5000.0


def truth_time_unit_problem(path_truth: str, t_est: FloatArray, t_truth: FloatArray) -> str:
    """The refusal of a truth whose ``t`` steps like milliseconds beside an estimate in
    seconds (a median step over :data:`~continuum_mhe.io.csv_files.MS_LIKE_STEP_S`,
    :data:`MS_RATIO_MIN` to :data:`MS_RATIO_MAX` times the estimate's, and its times
    read in milliseconds overlapping the estimate's), naming the truth file and the fix;
    ``""`` where they do not (a sparse truth in seconds, on another clock: the clock's
    hint says it)."""
    if len(t_est) < 3 or len(t_truth) < 3:
        return ""
    step_truth = float(np.median(np.diff(t_truth)))
    step_est = float(np.median(np.diff(t_est)))
    if not (step_truth > MS_LIKE_STEP_S > step_est > 0):
        return ""
    in_ms = MS_RATIO_MIN <= step_truth / step_est <= MS_RATIO_MAX
    overlaps = t_truth[0] / 1e3 <= t_est[-1] and t_truth[-1] / 1e3 >= t_est[0]
    if not (in_ms and overlaps):
        return ""
    return (
        f"{path_truth}: t advances by a median of {step_truth:g} s per sample, the "
        f"estimate's by {step_est:g} s ({step_truth / step_est:.4g} times as long): is the "
        "truth's t in milliseconds? name its column t_ms (read in milliseconds), or give "
        "seconds"
    )


#: A truth of part of the run (:func:`rows_matched`'s ``truth_spanned``) is scored from
#: this many rows compared (fewer: a truth of a few rows, refused below
#: :data:`MIN_MATCHED` of the rows).
PART_ROWS = 20


#: The rows compared span at least this share of the truth's times, itself shorter than
#: the estimate's, for a truth of part of the run (:func:`spans_the_truth`).
TRUTH_SPANNED = 0.9


def comparable_rows(t_est: np.ndarray, t_truth: np.ndarray) -> int:
    """How many of the estimate's rows at ``t_est`` a truth at ``t_truth`` could be
    compared at: each of them, or, for a truth whose median step exceeds
    :data:`~continuum_mhe.evaluation.metrics.INTERPOLATE_STEP` times the estimate's
    (compared at the row nearest each of its samples, or, sparser than
    :data:`~continuum_mhe.evaluation.metrics.SPARSE_STEP_MAX` times, at the rows that
    share its times), the samples at its median step over the estimate's times."""
    if len(t_est) < 2 or len(t_truth) < 2:
        return len(t_est)
    step = float(np.median(np.diff(t_truth)))
    if step <= INTERPOLATE_STEP * float(np.median(np.diff(t_est))):
        return len(t_est)
    # a truth whose times span a hundred times the estimate's or more (t in milliseconds,
    # read as seconds, spans 1000 times as long) is no set of snapshots of this run
    if float(t_truth[-1] - t_truth[0]) > 100.0 * float(t_est[-1] - t_est[0]):
        return len(t_est)
    return int(round(float(t_est[-1] - t_est[0]) / step)) + 1


#: A truth whose times, reaching a step of its own past its first and last rows, cover
#: less than this share of the estimate's time span is said to be of part of the run
#: (:func:`truth_covers_part`): a truth that ends a sample or two early is not.
PART_COVERED = 0.9


def truth_covers_part(
    path_est: str, t_est: np.ndarray, compared: int, path_truth: str, t_truth: np.ndarray
) -> str:
    """The warning of a truth ``path_truth`` (times ``t_truth``) that covers part of the
    estimate ``path_est``'s times ``t_est`` alone (less than :data:`PART_COVERED` of
    them, its median step added at each end), ``compared`` of its rows compared: the two
    spans and that count, as :func:`rows_matched` counts them; ``""`` where it covers
    them, or none of them (refused as times that do not match)."""
    if len(t_est) < 2 or len(t_truth) < 2:
        return ""
    first, last = float(t_est[0]), float(t_est[-1])
    start, end = max(float(t_truth[0]), first), min(float(t_truth[-1]), last)
    step = float(np.median(np.diff(t_truth)))
    reach = min(float(t_truth[-1]) + step, last) - max(float(t_truth[0]) - step, first)
    if not last > first or end < start or reach >= PART_COVERED * (last - first):
        return ""
    share = 100.0 * (end - start) / (last - first)
    return (
        f"{path_truth}: its rows cover t = {time_text(start)} to {time_text(end)} s of "
        f"{path_est}'s {time_text(first)} to {time_text(last)} s ({share:.0f} %): "
        f"{compared} of the estimate's {len(t_est)} rows compared (a truth of part of the "
        "run?)"
    )


def spans_the_truth(t_est: np.ndarray, compared: np.ndarray, t_truth: np.ndarray) -> bool:
    """Whether the estimate rows at ``t_est[compared]`` span :data:`TRUTH_SPANNED` of the
    truth's times ``t_truth``, and those are shorter than the estimate's: a truth (a
    motion capture) of part of the run, not a file of other times."""
    if len(compared) < 2 or len(t_truth) < 2 or len(t_est) < 2:
        return False
    truth_span = float(t_truth[-1] - t_truth[0])
    covered = float(t_est[compared[-1]] - t_est[compared[0]])
    return truth_span < float(t_est[-1] - t_est[0]) and covered >= TRUTH_SPANNED * truth_span


def truth_frame_warning(path_truth: str, truth: StateTable, lengths: tuple[float, ...]) -> str:
    """A warning where the truth's tip points away from its own bend angles on a robot of
    these section ``lengths`` (:func:`~continuum_mhe.io.position_units.tip_direction_problem`:
    x and y swapped, a sign flipped), else ``""``."""
    turned = tip_direction_problem(truth.names, truth.values, lengths)
    return f"{path_truth}: {turned}" if turned else ""


def truth_beside(
    path_est: str,
    est: StateTable,
    path_truth: str,
    truth: StateTable,
    lengths: tuple[float, ...],
    shift_option: str = "evaluate --truth-shift",
    given_shift: float = 0.0,
) -> tuple[StateTable | None, list[str]]:
    """What ``plot`` and ``view`` check of a truth drawn beside an estimate, on one
    alignment of the two (as ``evaluate`` aligns them): an
    :class:`~continuum_mhe.errors.InputError` for a truth of another robot or too few
    rows the estimate's times share (:func:`rows_matched`; not asked of an estimate of one
    row); else the truth interpolated at the estimate's times where ``evaluate`` would
    interpolate it (None: as it is) and the warnings, in order: few rows, a truth of
    part of the estimate's times (:func:`truth_covers_part`), a truth whose
    tip points away from its own angles (:func:`truth_frame_warning`, on a robot of these
    section ``lengths``), a clock offset (:func:`clock_offset_warning`, which advises
    ``shift_option`` and counts in the ``given_shift`` s the truth was shifted by)."""
    i_est, rows, interpolated = aligned_truth(est.t, truth.t, truth.values, truth.names, warn=False)
    at_est = truth_at_rows(est, truth, i_est, rows, interpolated)
    problem = truth_problem(est, at_est or truth)
    if problem is not None and (unit := truth_time_unit_problem(path_truth, est.t, truth.t)):
        raise InputError(unit)
    if problem is not None:
        hint = ""
        if len(est.t):
            hint = offset_hint(float(est.t[0]), est.t, truth.t, given_shift, shift_option)
        raise InputError(f"{path_truth}: {problem}{hint}")
    warned = []
    if len(est.t) >= 2:
        part = truth_covers_part(path_est, est.t, len(i_est), path_truth, truth.t)
        spanned = bool(part) and spans_the_truth(est.t, i_est, truth.t)
        refused, few = rows_matched(
            path_est,
            path_truth,
            len(i_est),
            len(est.t),
            interpolated,
            spanned,
            comparable_rows(est.t, truth.t),
        )
        if refused and (unit := truth_time_unit_problem(path_truth, est.t, truth.t)):
            raise InputError(unit)
        if refused:
            raise InputError(
                refused + offset_hint(float(est.t[0]), est.t, truth.t, given_shift, shift_option)
            )
        warned += [few, part]
    tip = est.values[i_est][:, [est.names.index(c) for c in TIP_COLUMNS]]
    truth_tip = rows[:, [truth.names.index(c) for c in TIP_COLUMNS]]
    fit = frame_fit(tip, truth_tip, sum(lengths))
    # a truth of a robot of other lengths is drawn beside the estimate's backbone as it
    # is: said, as evaluate says it (not of a truth about another origin: said below)
    other = length_misfit(truth.names, truth.values, lengths) or lengths_misfit(truth, lengths)
    if other and not moves_the_base(fit, sum(lengths)):
        shown = ", ".join(f"{v:g}" for v in lengths)
        warned.append(
            f"{path_truth}: {other}; it is drawn beside the estimate of a robot of {shown} m "
            "(the truth of another robot?)"
        )
    warned.append(truth_frame_warning(path_truth, truth, lengths))
    err = np.linalg.norm(tip - truth_tip, axis=1)
    err = err[np.isfinite(err)]
    mean = float(err.mean()) if len(err) else math.nan  # the mean tip error, m
    warned.append(frame_fit_warning(path_truth, fit, sum(lengths)))
    offset = clock_offset_warning(
        path_truth, est, truth, sum(lengths), mean, shift_option, given_shift
    )
    return at_est, [line for line in (*warned, offset) if line]


def refuse_an_estimate_as_truth(path_truth: str, truth: StateTable, usage: str) -> None:
    """A truth file with an estimate's ``status`` or ``std_`` columns is an estimate
    given in the truth's place: a one-line error naming it and ``usage`` (the command's
    form, where the truth comes second)."""
    if truth.status_column or truth.std_columns:
        raise InputError(
            f"{path_truth}: has an estimate's status or std_ columns: an estimate, not a "
            f"truth ({usage})"
        )


def offset_hint(
    first_t: float,
    t_est: np.ndarray,
    t_truth: np.ndarray,
    given_shift: float = 0.0,
    shift_option: str = "--truth-shift",
) -> str:
    """Where the estimate's times ``t_est`` are the truth's plus one offset, that of its
    first time ``first_t`` (before any ``--skip-start``) from the truth's (a device
    clock that did not start at 0, as ``live``'s), the ``--truth-shift`` that compares
    them, the ``given_shift`` already applied to ``t_truth`` counted in (a clause to end
    a refusal, the option named ``shift_option``); else ``""``."""
    offset = float(first_t - t_truth[0])
    if not math.isfinite(offset) or offset == 0.0:
        return ""
    total = given_shift - offset  # the truth read at t + total lines the times up
    shift = "0 (leave --truth-shift out)" if abs(total) < 1e-9 else seconds_text(total)
    matched = len(match_rows(t_est, t_truth + offset)[0])  # as evaluate matches rows
    if matched >= WARN_MATCHED * len(t_est) and abs(total) < 1e-9 and given_shift != 0.0:
        # the files' own times match: the shift given moved the truth off them
        return (
            f"; the files' own times match: {shift_option} {seconds_text(given_shift)} moved "
            f"the truth off them (leave {shift_option} out)"
        )
    if matched >= WARN_MATCHED * len(t_est):
        return (
            f"; the estimate's times are the truth's {seconds_text(offset, '+')} s (a clock that "
            f"did not start at 0?): {shift_option} {shift} compares them"
        )
    if t_truth[-1] < t_est[0] or t_truth[0] > t_est[-1]:  # no time in common at all
        return (
            f"; the truth's t runs from {time_text(float(t_truth[0]))} to "
            f"{time_text(float(t_truth[-1]))} s, the estimate's from "
            f"{time_text(float(t_est[0]))} to {time_text(float(t_est[-1]))} s: if the two "
            f"recordings started together, {shift_option} {shift} compares them"
        )
    return ""
