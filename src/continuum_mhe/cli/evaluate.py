"""``continuum-mhe evaluate``: the errors of an estimate CSV against a truth CSV."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from continuum_mhe.cli.config import recorded_t0_s
from continuum_mhe.cli.held_notes import said_unless_refused
from continuum_mhe.cli.program import PROG
from continuum_mhe.cli.robot_options import (
    DEFAULT_LENGTH,
    add_robot_option,
    estimate_robot,
    robot_given,
)
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.evaluation.estimate_tables import lengths_misfit
from continuum_mhe.evaluation.metrics import (
    FAR_STD,
    Calibration,
    Metrics,
    aligned_truth,
    compared_rows,
    compute_calibration,
    compute_metrics,
    interpolated_note,
    length_misfit,
    srmse_columns,
    truth_sparser,
)
from continuum_mhe.evaluation.truth_checks import (
    WARN_MATCHED,
    clock_offset_warning,
    comparable_rows,
    frame_fit,
    frame_fit_warning,
    moves_the_base,
    offset_hint,
    refuse_an_estimate_as_truth,
    rows_matched,
    seconds_text,
    spans_the_truth,
    truth_covers_part,
    truth_frame_warning,
    truth_time_unit_problem,
)
from continuum_mhe.io.estimate_files import read_estimates
from continuum_mhe.io.position_units import (
    force_unit_against,
    position_unit_against,
    position_unit_problem,
    steady_ratio,
)
from continuum_mhe.io.state_tables import (
    StateTable,
    check_same_robot,
    misspelt_columns,
    read_state_table,
)
from continuum_mhe.io.text_rows import held_for_rereading
from continuum_mhe.model.descriptions import TIP_COLUMNS, TIP_FORCE_COLUMNS, section_numbers
from continuum_mhe.results import Status


def _log_clock_hint(
    path_est: str, t_est: np.ndarray, t_truth: np.ndarray, given_shift: float
) -> str:
    """Where the estimate is of a robot log (its ``t0_ns`` line or note) and the truth's
    times, read at the log's clock less ``t0_ns``, overlap the estimate's: the
    ``--truth-shift`` that compares them (a clause to end a refusal); else ``""``."""
    t0_s = recorded_t0_s(path_est)
    if t0_s is None:
        return ""
    total = given_shift + t0_s
    shifted = t_truth + given_shift - total
    if shifted[-1] < t_est[0] or shifted[0] > t_est[-1]:
        return ""
    return (
        f"; the estimate's t = 0 is {time_text(t0_s)} s on its robot log's clock (its "
        f"t0_ns): a truth on that clock compares with --truth-shift {total!r}"
    )


def _align(
    path_est: str,
    t_est: np.ndarray,
    path_truth: str,
    truth: StateTable,
    scored_from: float | None = None,
    first_t: float | None = None,
    given_shift: float = 0.0,
) -> Aligned:
    """The estimate rows compared and the truth's values at them
    (:func:`~continuum_mhe.evaluation.metrics.aligned_truth`; a note where the truth is
    interpolated; ``scored_from``: the time from which ``--skip-start`` scores, s, the
    start of the span the rows should cover); a one-line error where too few rows
    compare, the warnings where few do. ``first_t``: the estimate's first time before
    ``--skip-start`` (s), from which a clock offset is told (``t_est[0]`` without it);
    ``given_shift``: the ``--truth-shift`` already applied to ``truth``, s."""
    t_truth = truth.t
    if len(t_est) < 2:
        raise InputError(f"{path_est}: one row: evaluate needs at least two")
    if len(t_truth) < 2:
        raise InputError(f"{path_truth}: one row: evaluate needs a truth of at least two")
    i_est, rows, interpolated = aligned_truth(t_est, t_truth, truth.values, truth.names, warn=False)
    n, k = len(t_est), len(i_est)
    if interpolated:
        note = interpolated_note(path_truth, path_est, k, n, truth_sparser(t_est, t_truth))
        print(f"{PROG}: note: {note}", file=sys.stderr)
    # the truth from where the scores start (--skip-start): a truth of part of the run
    # is judged by what is left of it there
    scored_truth = t_truth if scored_from is None else t_truth[t_truth >= scored_from]
    part = truth_covers_part(path_est, t_est, k, path_truth, t_truth)
    spanned = bool(part) and spans_the_truth(t_est, i_est, scored_truth)
    comparable = comparable_rows(t_est, t_truth)
    problem, warning = rows_matched(path_est, path_truth, k, n, interpolated, spanned, comparable)
    if scored_from is not None and len(t_truth) and float(t_truth[-1]) < float(t_est[-1]):
        # a truth that ends early, --skip-start cutting into what is left of it
        cut = (
            f"; or the truth ends at t = {time_text(float(t_truth[-1]))} s and --skip-start "
            f"scores from t = {time_text(scored_from)} s: few of those rows, or none, have "
            "a truth"
        )
        if problem:
            problem += cut
        if "files' times do not match" in warning:  # (not the part-of-the-run warning)
            warning += cut
    if problem and (unit := truth_time_unit_problem(path_truth, t_est, t_truth)):
        raise InputError(unit)
    if problem:
        first = float(t_est[0]) if first_t is None or not math.isfinite(first_t) else first_t
        hint = _log_clock_hint(path_est, t_est, t_truth, given_shift)
        raise InputError(problem + (hint or offset_hint(first, t_est, t_truth, given_shift)))
    warnings = [line for line in (warning, part) if line]
    covered = t_est[i_est]
    t0, t1 = float(t_truth[0]), float(t_truth[-1])
    if scored_from is not None:
        t0 = min(max(t0, scored_from), t1)
    share = (covered[-1] - covered[0]) / (t1 - t0) if t1 > t0 else 1.0
    if share < WARN_MATCHED:  # by time span: a truth sampled more densely is no mistake
        warnings.append(
            f"{path_est}: its rows cover t = {time_text(covered[0])} to "
            f"{time_text(covered[-1])} s of {path_truth}'s {time_text(t0)} to {time_text(t1)} s "
            f"({100 * share:.0f} %): "
            "the scores are of that part only (an interrupted or cut estimate?)"
        )
    return Aligned(i_est, rows, interpolated, warnings)


class Aligned(NamedTuple):
    """The estimate rows compared (``i_est``) and the truth's values at them (``rows``,
    one per index, the truth file's columns), whether the truth was interpolated at the
    estimate's times, and the warnings of the alignment (said by the caller)."""

    i_est: np.ndarray
    rows: np.ndarray
    interpolated: bool
    warnings: list[str]


def _length_hint(est_xyz: np.ndarray, truth_xyz: np.ndarray, tip_mean: float, length: float) -> str:
    """A hint when the estimate's tip distances from the base are a constant multiple of
    the truth's (made with another length), else ``""``."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.linalg.norm(est_xyz, axis=1) / np.linalg.norm(truth_xyz, axis=1)
    r = steady_ratio(ratio)
    if tip_mean < 0.1 * length or r is None or 0.8 < r < 1.25:
        return ""
    return (
        f"the estimate's tip is {r:.2f} times as far from the base as the truth's: "
        "was it made with another --length (or robot file) than the truth?"
    )


#: ``--skip-start`` keeps a row this close before its time (s): the rows' times rounded
#: as ``evaluate`` matches them
SKIP_TOLERANCE = 1e-6


def _scored_from(est: StateTable, seconds: float) -> float | None:
    """The time from which ``--skip-start SECONDS`` scores, s: that long after the
    estimate's first row with a finite time (None without a skip or such a row)."""
    finite = est.t[np.isfinite(est.t)]
    return float(finite.min()) + seconds if seconds > 0.0 and len(finite) else None


def _after_start(path: str, est: StateTable, seconds: float) -> StateTable:
    """The rows of ``est`` from ``seconds`` after its first row on (``--skip-start``: the
    start's transient left out of the scores)."""
    start = _scored_from(est, seconds)
    if start is None:
        return est
    keep = est.t >= start - SKIP_TOLERANCE
    if int(keep.sum()) < 2:
        raise InputError(
            f"{path}: fewer than two rows after --skip-start {seconds:g} s (its rows span "
            f"{time_text(float(np.nanmax(est.t) - np.nanmin(est.t)))} s)"
        )
    return replace(
        est,
        t=est.t[keep],
        values=est.values[keep],
        status=est.status[keep],
        std=None if est.std is None else est.std[keep],
        outlier=None if est.outlier is None else est.outlier[keep],
    )


def _same_file(a: str, b: str) -> bool:
    """``a`` and ``b`` name one file (a link or another spelling of its path too)."""
    if a == b:  # standard input twice, too
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them is missing: its reader says so
        return False


def run(args: argparse.Namespace) -> int:
    given = getattr(args, "truth_option", None)
    if given is not None and args.truth is not None:
        raise InputError(
            f"two truths, {args.truth} and --truth {given}: give one (evaluate EST.csv TRUTH.csv)"
        )
    args.truth = args.truth if given is None else given
    if args.truth is None:
        raise InputError(
            f"{args.estimates}: no truth to score it against: continuum-mhe evaluate EST.csv "
            "TRUTH.csv"
        )
    # the estimate is read twice; the notes and warnings are said once it is scored
    with held_for_rereading(args.estimates, args.truth), said_unless_refused():
        return _evaluate(args)


def _evaluate(args: argparse.Namespace) -> int:
    est = read_estimates(args.estimates, f"evaluate EST.csv {args.truth}", TIP_COLUMNS)
    truth = read_state_table(args.truth, gaps=True)  # a motion capture's lost markers
    if args.truth_shift:  # the truth read at t + shift: its rows that much earlier
        truth = replace(truth, t=truth.t - args.truth_shift)
    refuse_an_estimate_as_truth(
        args.truth, truth, "evaluate EST.csv TRUTH.csv: the truth comes second"
    )
    if _same_file(args.estimates, args.truth):
        raise InputError(
            f"{args.truth}: the truth is the estimate file itself (evaluate EST.csv TRUTH.csv): "
            "give the truth the estimate is scored against"
        )
    # without --robot or --length: the estimate's own, else one section of --length
    warned: list[str] = []  # said once the scores are known, and in --json
    robot = estimate_robot(args, args.estimates, "evaluated on that robot", warned)
    tendon_estimate = all(c in est.names for c in TIP_FORCE_COLUMNS)
    if args.robot and tendon_estimate and not robot.has_mechanics:
        raise InputError(
            f"{args.robot}: the robot has no [backbone], but {args.estimates} is a tendon "
            "robot's estimate (its tip force columns): give that robot's file, or no "
            "--robot for the one its options line names"
        )
    other_recorded = bool(warned)  # the estimate's options line names another robot
    other_robot = check_same_robot(args.estimates, est, args.truth, truth, robot)
    for path, table in ((args.estimates, est), (args.truth, truth)):
        if unit := position_unit_problem(table.names, table.values, robot.lengths):
            raise InputError(f"{path}: {unit}")
    if unit := position_unit_against(truth.names, truth.values, est.names, est.values):
        raise InputError(f"{args.truth}: {unit}")  # tip positions alone in cm
    scored_from = _scored_from(est, args.skip_start)
    first_t = float(est.t[0]) if len(est.t) else math.nan  # the clock's, before any skip
    est = _after_start(args.estimates, est, args.skip_start)
    aligned = _align(
        args.estimates, est.t, args.truth, truth, scored_from, first_t, args.truth_shift or 0.0
    )
    i_e, truth_rows = aligned.i_est, aligned.rows
    # the tip force's unit over the rows compared: a partial estimate (an interrupted
    # run, a cut recording) is not compared with the forces of the rest of the truth
    if unit := force_unit_against(truth.names, truth_rows, est.names, est.values[i_e]):
        raise InputError(f"{args.truth}: {unit}")
    length = robot.length
    out_names = [n for n in est.names if not n.startswith("std_")]
    cols = [est.names.index(n) for n in out_names]
    if typo := misspelt_columns(truth.names, out_names):
        warned.append(f"{args.truth}: {typo}")
    try:
        m = compute_metrics(est.values[i_e][:, cols], truth_rows, length, out_names, truth.names)
    except ValueError as exc:
        raise InputError(f"{args.estimates}: {exc}") from None
    cal = cal_ok = None
    n_ok: int | None = None  # None: the file says no status (no column)
    if est.status_column:
        n_ok = int((np.asarray(est.status)[i_e] == Status.OK).sum())
    # the calibration is over the rows compared (m.n of them), as the RMSEs are: its
    # rows (tip_far_worst_row) counted among those
    values = est.values[i_e][:, cols]
    scored = compared_rows(values, truth_rows, out_names, truth.names)
    ok = (np.asarray(est.status)[i_e] == Status.OK)[scored]
    std = None if est.std is None else est.std[i_e][:, cols][scored]
    if est.has_std and std is not None and np.isfinite(std).any():
        cal = compute_calibration(values[scored], std, truth_rows[scored], out_names, truth.names)
        # what the status promises: the rows marked ok alone
        if est.status_column and n_ok and np.isfinite(std[ok]).any():
            cal_ok = compute_calibration(
                values[scored][ok], std[ok], truth_rows[scored][ok], out_names,
                truth.names,
            )  # fmt: skip
    unmatched = int(len(est.t) - len(i_e))
    xyz = ([est.names.index(c) for c in TIP_COLUMNS], [truth.names.index(c) for c in TIP_COLUMNS])
    # a truth in another frame (a motion capture's origin): its distances from the base
    # say nothing of the robot's length
    tip_est, tip_truth = est.values[i_e][:, xyz[0]], truth_rows[:, xyz[1]]
    fit = frame_fit(tip_est, tip_truth, length)
    about_another_origin = moves_the_base(fit, length)
    hint = other_robot or (
        ""
        if about_another_origin
        else _length_hint(tip_est, tip_truth, m.tip_mean_mm / 1e3, length)
    )
    # the robot from the estimate's options line: a truth that misfits it is another
    # robot's (its --length would misfit the estimate instead)
    given_length = (
        "pass the --length (or --robot) it was made with"
        if robot.n_sections == 1
        else "pass the --robot it was made with"
    )
    other = "the estimate's robot (its options line) is another: score it against its robot's truth"
    recorded = not robot_given(args) and robot.lengths != (DEFAULT_LENGTH,)
    misfits = [
        f"{path}: {misfit}; {other if recorded and path == args.truth else given_length}"
        for path, table in ((args.estimates, est), (args.truth, truth))
        if (misfit := length_misfit(table.names, table.values, robot.lengths))
        and not (about_another_origin and path == args.truth)
    ]  # tip errors in % of the length are then of another robot's length
    if not (misfits or other_robot or other_recorded or about_another_origin) and (
        sections := lengths_misfit(truth, robot.lengths)
    ):
        # the same length in all, shared otherwise among the sections (their order)
        misfits.append(
            f"{args.truth}: {sections}: check the robot's section lengths and their order"
        )
    # a file made for another length explains the estimate-truth ratio too: say it once
    warned += [*aligned.warnings, *([hint] if other_robot or not misfits else misfits)]
    # the truth's own positions against its own angles (an estimate's can drift from
    # its angles by design: the paper formulation's positions are states of their own)
    warned.append(truth_frame_warning(args.truth, truth, robot.lengths))
    warned.append(frame_fit_warning(args.truth, fit, length))
    warned.append(
        clock_offset_warning(
            args.truth, est, truth, length, m.tip_mean_mm / 1e3,
            given_shift=args.truth_shift or 0.0,
        )
    )  # fmt: skip
    warned = [line for line in warned if line]
    for line in warned:
        print(f"{PROG}: warning: {line}", file=sys.stderr)
    if args.json:
        extra = {
            "calibration": None if cal is None else cal.as_dict(),
            "ok_rows": n_ok,
            "calibration_ok": None if cal_ok is None else cal_ok.as_dict(),
        }
        srmse = {"srmse": None} if hint else {}  # not a score of two different robots
        summed = srmse_columns(list(m.rmse))  # as the text says
        made = {
            "srmse_columns": [] if hint else summed,
            "skip_start_s": args.skip_start,
            "truth_shift_s": args.truth_shift or 0.0,
            "interpolated": aligned.interpolated,
            "warnings": warned,  # as said on standard error
        }
        from continuum_mhe.reproduce.experiments import to_jsonable

        report = {**m.as_dict(), **extra, **srmse, "unmatched": unmatched, **made}
        # a coverage without any row to count (a column without std) is null, not NaN
        print(json.dumps(to_jsonable(report), indent=2, allow_nan=False))
    else:
        compared = []  # what the scores below are of, where an option says
        if args.truth_shift:
            compared.append(f"the truth {seconds_text(args.truth_shift)} s later")
        if args.skip_start:
            compared.append(f"from {seconds_text(args.skip_start)} s after the first row")
        if compared:
            print(f"compared             {', '.join(compared)}")
        print(format_metrics(m, comparable=not hint))
        print(format_calibration(cal, est.std_columns))
        if cal_ok is not None:
            tip = ", ".join(f"{c} {cal_ok.coverage[c]:.3f}" for c in "xyz" if c in cal_ok.coverage)
            print(f"ok rows              {n_ok} of {len(i_e)}: tip 95% interval coverage {tip}")
            if all(c in cal_ok.coverage for c in "xyz"):
                row = cal_ok.tip_far_worst_row  # of the ok rows
                t_ok = est.t[i_e][scored][ok]
                print(format_far(cal_ok, float(t_ok[row]) if row >= 0 else None))
        elif n_ok is None:
            print(f"ok rows              unknown: {args.estimates} has no status column")
        elif not (est.has_std and est.std is not None):
            print(f"ok rows              {n_ok} of {len(i_e)} (no std_ columns: no coverage)")
        elif n_ok == 0:
            print(f"ok rows              0 of {len(i_e)}: no coverage of the ok rows")
        else:
            print(f"ok rows              {n_ok} of {len(i_e)} (no std on them: no coverage)")
        if unmatched:
            print(f"unmatched rows       {unmatched} of {len(est.t)} (no truth at their t)")
    return 0


def _ratio_text(ratio: float) -> str:
    """``ratio`` to one decimal, or to as many more as keep it on its side of
    :data:`FAR_STD` (4.03 is "4.03", not the "4.0" that reads as within; 3.98 is "3.98",
    not the "4.0" of the bound)."""
    for decimals in range(1, 7):
        text = f"{ratio:.{decimals}f}"
        shown = float(text)
        if (shown > FAR_STD) if ratio > FAR_STD else (shown < FAR_STD or shown == ratio):
            return text
    return text


def format_far(c: Calibration, t_worst: float | None = None) -> str:
    """The ok rows far outside their standard deviations, as a line of ``evaluate``
    (``t_worst``: the time of the row with the largest ratio, s)."""
    far = f"{c.tip_far} of {c.tip_far_of} more than {FAR_STD:g} std off on a tip axis ("
    if c.tip_far_of:
        at = f" at t = {time_text(t_worst)} s" if t_worst is not None else ""
        largest = (
            "a zero std" if math.isinf(c.tip_far_worst) else f"{_ratio_text(c.tip_far_worst)} std"
        )
        far += f"the largest {largest}{at}; "
    return f"ok rows far off      {far}about 2 in 10,000 rows where the std is right)"


def format_calibration(c: Calibration | None, std_columns: bool = False) -> str:
    """Coverage of the 95 % intervals per output, and the tip NEES with its band; without
    them, why (``std_columns``: the file has ``std_`` columns, all empty)."""
    if c is None:
        if std_columns:
            return (
                "calibration          the std_ columns of the estimate file are empty (made "
                "without standard deviations)"
            )
        return "calibration          no std_ columns in the estimate file"
    # a column without a finite truth (or std) in any row has no coverage to say
    cover = ", ".join(f"{k} {v:.3f}" for k, v in c.coverage.items() if math.isfinite(v))
    lo, hi = c.tip_nees_band
    if c.tip_nees < lo:  # what each side means, for a reader who meets the NEES here
        inside = "outside, below: the intervals are wider than the errors"
    elif c.tip_nees > hi:
        inside = "outside, above: the intervals are narrower than the errors"
    else:
        inside = "inside"
    zero = ""
    if c.tip_zero_std:
        zero = (
            f"; {c.tip_zero_std} samples with a zero tip std left out, counted in the coverage "
            "as misses unless their error is zero"
        )
    return (
        f"95% interval coverage {cover} (0.95 where the std is right)\n"
        f"tip NEES             {c.tip_nees:.2f} over {c.tip_n} samples (3 where the std is right; "
        f"95% band {lo:.2f} to {hi:.2f}, for the {c.tip_n_eff:.0f} independent samples they "
        f"are worth, their errors correlated in time: {inside}{zero})"
    )


def format_metrics(m: Metrics, comparable: bool = True) -> str:
    """``evaluate``'s error lines; no SRMSE unless the estimate and the truth are
    ``comparable`` (not of different lengths or robots)."""
    r = m.rmse
    lines = [
        f"samples compared     {m.n} ({m.n_without_estimate} without estimate"
        + (f", {m.n_without_truth} without a finite truth)" if m.n_without_truth else ")"),
        f"tip error mean       {m.tip_mean_mm:.2f} mm ({m.tip_mean_pct:.2f} % of length)",
        f"tip error max        {m.tip_max_mm:.2f} mm ({m.tip_max_pct:.2f} % of length)",
        f"RMSE x, y, z         {r['x'] * 1e3:.2f}, {r['y'] * 1e3:.2f}, {r['z'] * 1e3:.2f} mm",
    ]
    if "theta" in r and "phi" in r:
        lines.append(
            f"RMSE theta, phi      {math.degrees(r['theta']):.2f}, {math.degrees(r['phi']):.2f} deg"
        )
    for sec, mean in m.section_end_mean_mm.items():
        lines.append(
            f"section {sec} end error  mean {mean:.2f} mm, max {m.section_end_max_mm[sec]:.2f} mm"
        )
    for k in section_numbers(r, "theta"):  # every section both files have, gaps or not
        bend = [f"theta_{k}"] + ([f"phi_{k}"] if f"phi_{k}" in r else [])
        values = ", ".join(f"{math.degrees(r[c]):.2f}" for c in bend)
        lines.append(f"RMSE {', '.join(bend)}".ljust(21) + f"{values} deg")
    for k in section_numbers(r, "psi"):
        lines.append(f"RMSE psi_{k}           {math.degrees(r[f'psi_{k}']):.2f} deg (twist)")
    if m.tip_force_rms_n is not None:
        fx, fy, fz = (r[c] for c in TIP_FORCE_COLUMNS)
        lines.append(
            f"tip force error      rms {m.tip_force_rms_n:.4f} N "
            f"(RMSE fx, fy, fz {fx:.4f}, {fy:.4f}, {fz:.4f} N)"
        )
    if comparable:
        summed = ", ".join(srmse_columns(list(r)))
        lines.append(f"SRMSE                {m.srmse:.4f} (sum of the RMSEs of {summed}, m + rad)")
    else:  # a score of two different robots would read as a real one
        lines.append(
            "SRMSE                not given: the estimate and the truth differ (see the warning)"
        )
    return "\n".join(lines)


DESCRIPTION = (
    "Score an estimate file against a truth (a simulation's, or a motion-capture log with "
    "t,x,y,z and any per-section columns), aligned by time (interpolated where the rows "
    "differ): the tip error in mm and in % of the robot's length, the RMSE of every "
    "output the truth has, how often the 95 % intervals held the truth (all rows, and "
    "the rows marked ok) and the tip NEES. The robot is the estimate's own (its options "
    "line) unless --robot or --length is given."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("estimates", help="estimate CSV or MCAP, as estimate -o writes it")
    p.add_argument("truth", nargs="?", help="truth CSV: t and the true outputs (x, y, z, ...)")
    p.add_argument(
        "--truth",
        dest="truth_option",
        metavar="TRUTH.csv",
        help="the truth given as plot and view take it (instead of the second argument)",
    )
    p.add_argument(
        "--length",
        type=float,
        default=None,
        help="section length in m (default: the robot the estimate records, else 0.2)",
    )
    add_robot_option(p, replaces=("--length",))
    p.add_argument(
        "--truth-shift",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="compare each estimate row with the truth SECONDS later (a truth on a clock "
        "offset from the estimate's; the warning of an offset names the shift)",
    )
    p.add_argument(
        "--skip-start",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="score only the estimate rows from SECONDS after its first row on (the start's "
        "transient left out; the scores of docs/tendon.md are from 1 s on)",
    )
    p.add_argument("--json", action="store_true", help="print JSON")
