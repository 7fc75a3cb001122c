"""Command line: ``continuum-mhe {demo,simulate,estimate,evaluate,...}``.

User errors (:class:`~continuum_mhe.errors.UserError`, unreadable or unwritable files)
print one line, ``continuum-mhe: error: ...``, and exit with status 2. Anything else is
a bug: one line that says so, with where it happened and where to report it, and exit
status 70 (``CONTINUUM_MHE_TRACEBACK=1`` shows the traceback).
"""

from __future__ import annotations

import argparse
import importlib
import itertools
import json
import math
import os
import signal
import sys
import warnings
from collections.abc import Generator, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from continuum_mhe.cli_options import (
    add_mhe_options,
    add_model_options,
    add_recovery_options,
    add_robot_option,
    check_option_ranges,
    formulation_from_args,
    input_options,
    mhe_settings_from_args,
    recovery_settings_from_args,
    robot_from_args,
)
from continuum_mhe.errors import UserError
from continuum_mhe.estimators import METHODS, EstimateSeries, Measurement, make_estimator
from continuum_mhe.estimators.fast.warmup import (
    CompileNotice,
    FirstRun,
    first_run_mode,
    kernels_ready,
)
from continuum_mhe.io.csv_files import (
    InputError,
    check_new_folder,
    check_output_target,
    check_same_robot,
    new_files,
    read_state_table,
    write_estimates,
    write_measurements,
    write_truth,
)
from continuum_mhe.metrics import (
    Calibration,
    Metrics,
    compute_calibration,
    compute_metrics,
    length_misfit,
)
from continuum_mhe.model.imu import MOUNTINGS
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.program import DESCRIPTION, PROG, version
from continuum_mhe.program import signal_exit as _signal_exit
from continuum_mhe.progress import progress_bar, table_console
from continuum_mhe.settings import MHESettings, NoiseSettings
from continuum_mhe.signals import SIGNALS_SEEN as _SIGNALS_SEEN
from continuum_mhe.signals import (
    interrupt_in_chain,
    interruptible,
    quiet_unraisable,
    signals_deferred,
)
from continuum_mhe.signals import on_signal as _on_signal
from continuum_mhe.simulation.scenarios import (
    NOISE_MODELS,
    SCENARIOS,
    Recording,
    ScenarioName,
    simulate_robot,
)

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from continuum_mhe.io.sample_stream import SampleStream
    from continuum_mhe.io.tensions import Tensions
    from continuum_mhe.model.formulations import Formulation


#: Modules that add subcommands through ``register(subparsers)``.
COMMAND_MODULES: tuple[str, ...] = (
    "continuum_mhe.cli_live",
    "continuum_mhe.cli_calibrate",
    "continuum_mhe.reproduce.cli",
    "continuum_mhe.benchmark",
    "continuum_mhe.cli_view",
)


# --- commands --------------------------------------------------------------------------
#: Most samples ``simulate`` writes (``--duration / --dt``).
MAX_SIMULATED_SAMPLES = 10_000_000


def cmd_simulate(args: argparse.Namespace) -> int:
    n = args.duration / args.dt
    if n > MAX_SIMULATED_SAMPLES:
        raise InputError(
            f"--duration {args.duration:g} / --dt {args.dt:g} is {n:.3g} samples; at most "
            f"{MAX_SIMULATED_SAMPLES:,} (write longer recordings in parts)"
        )
    check_output_target(args.output)  # both before writing either
    if args.truth:
        truth = check_output_target(args.truth)
        if truth.resolve() == Path(args.output).resolve():
            raise InputError(
                f"{args.truth}: --truth names the measurement file -o too; give two files"
            )
    robot = robot_from_args(args)
    rec = simulate_robot(
        args.scenario,
        robot,
        duration=args.duration,
        dt=args.dt,
        noise_deg=args.noise_deg,
        seed=args.seed,
        noise_model=args.noise_model,
    )
    write_measurements(args.output, rec.t, rec.z, rec.measurement_names)
    if args.truth:
        try:
            write_truth(args.truth, rec.t, rec.truth, rec.outputs)
        except BaseException:  # (a full disk, a signal): no measurements without truth
            Path(args.output).unlink(missing_ok=True)
            raise
    print(f"wrote {len(rec.t)} samples of {args.scenario} to {args.output}", file=sys.stderr)
    return 0


def cmd_estimate(args: argparse.Namespace) -> int:
    # input kind (tilt CSV, raw IMU CSV, ROS bag, MCAP) and output (.csv/.mcap): issue #5;
    # streamed: the input is read once and memory stays flat (issue #12)
    from continuum_mhe.io.imu_topics import warn_topic_order
    from continuum_mhe.io.sample_stream import EstimateSink, open_estimate_input

    check_output_path(args.output, args.measurements)
    out = args.output
    counts: dict[str, int] = {}
    base = formulation_from_args(args)
    tensions = _tensions_of(args, base)
    with open_estimate_input(args.measurements, input_options(args), base) as stream:
        formulation, samples = stream.formulation, stream.samples
        if base.robot.has_mechanics:
            formulation, samples = _with_tensions(args, stream, tensions)
        est = make_estimator(
            args.method,
            formulation,
            mhe_settings_from_args(args),
            recovery_settings_from_args(args),
            first_run=first_run_mode(_first_run_default(args.measurements)),
        )
        est.reset()
        flags_outliers = bool(getattr(est, "flags_outliers", False))
        outliers = 0
        frozen: dict[str, int] = {}  # statuses of the samples with a frozen sensor
        bar = progress_bar(f"{args.method} estimate")
        ticks = cast(Generator[int, None, None], (bar or _passthrough)(itertools.count()))
        with EstimateSink(out, formulation, stream.t0_ns, flags_outliers) as sink:
            try:
                for t, z in samples:  # a signal while waiting for input ends it at once
                    next(ticks)
                    frozen_before, freezes_before = est.frozen_samples, len(est.first_freezes)
                    with signals_deferred():  # inside C code: stop after this sample
                        e = est.step(Measurement(t, z))
                    counts[e.status] = counts.get(e.status, 0) + 1
                    if est.frozen_samples > frozen_before:
                        frozen[e.status] = frozen.get(e.status, 0) + 1
                        note = est.freezes_notice(freezes_before)  # said once per IMU
                        if note:
                            print(f"{PROG}: note: {note}", file=sys.stderr)
                    outliers += e.outlier
                    sink.write(e)
            finally:
                ticks.close()
            n = sum(counts.values())
            if n == counts.get("no-estimate", 0):
                why = (
                    "every sample is a dropout"
                    if not args.paper_start
                    else (f"--paper-start needs at least --horizon {args.horizon} samples")
                )
                raise InputError(
                    f"{stream.name}: no sample gave an estimate ({n} samples; {why}); "
                    "nothing written"
                )
            if n >= 3 and est.gap_resets > n // 2:  # t in ms read as s, most often
                fix = "raise --gap-reset, or 0: never"
                if stream.kind != "log":  # a log's t comes from its own timestamps
                    fix = f"if t is in milliseconds, name the column t_ms (else {fix})"
                raise InputError(
                    f"{stream.name}: {est.gap_resets} of {n} samples restarted the estimator "
                    f"after a gap longer than --gap-reset {args.gap_reset:g} s: {fix}; "
                    "nothing written"
                )
    if stream.kind == "log":  # several topics in the wrong order, most often
        warn_topic_order(stream.name, args.topic or (), n, est.restarts + est.bad_starts)
    summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    if flags_outliers:
        summary += f"; outliers flagged: {outliers}"
    msg = f"wrote {n} estimates to {out} ({summary})"
    for clause in (stream.readings.summary() if stream.readings else "", stream.problems.summary()):
        msg += f"; {clause}" if clause else ""
    if est.frozen_samples:
        of = ", ".join(f"{k}: {v}" for k, v in sorted(frozen.items()))
        msg += (
            f"; {est.frozen_samples} of them had a frozen IMU (the same reading for over "
            f"{args.freeze:g} s, treated as a dropout): {of}"
        )
    if est.restarts:
        msg += (
            f"; restarted {est.restarts} time(s) after the estimate diverged, failed or its "
            "uncertainty outgrew the workspace (status reset, or no-estimate on a sample without "
            "a valid reading)"
        )
    if est.gap_resets:
        msg += f"; restarted after {est.gap_resets} gap(s) longer than {args.gap_reset:g} s"
    if est.bad_starts:
        msg += (
            f"; restarted {est.bad_starts} time(s) after readings inconsistent with the "
            "start or an IMU's return"
        )
    if est.reject_resets:
        msg += (
            f"; restarted {est.reject_resets} time(s) after rejecting every reading for over "
            f"{args.reject_reset:g} s"
        )
    for note in stream.notes:  # e.g. how the samples of several Imu topics paired
        print(note, file=sys.stderr)
    print(msg, file=sys.stderr)
    return 0


def _tensions_of(args: argparse.Namespace, base: Formulation) -> Tensions | None:
    """The ``--inputs`` tensions file, read and checked for the robot's tendons."""
    from continuum_mhe.io.tensions import read_tensions

    robot = base.robot
    given = getattr(args, "inputs", None)
    if not robot.n_tendons:
        if given:
            raise InputError(
                f"{given}: --inputs gives tendon tensions, but the robot has no [[tendon]]"
            )
        return None
    if not given:
        raise InputError(
            f"{args.robot}: the robot has {robot.n_tendons} tendons: give their tensions "
            "with --inputs TENSIONS.csv (t,tension_1,...)"
        )
    return read_tensions(given, robot.n_tendons)


def _with_tensions(
    args: argparse.Namespace, stream: SampleStream, tensions: Tensions | None
) -> tuple[Formulation, Iterator[tuple[float, np.ndarray]]]:
    """The tendon formulation of the stream's robot and its samples with the tensions
    (interpolated at each sample's time) appended."""
    from continuum_mhe.io.tensions import tendon_formulation_for

    f = tendon_formulation_for(stream.formulation, input_options(args))
    k = f.robot.n_tendons

    def rows() -> Iterator[tuple[float, np.ndarray]]:
        for t, z in stream.samples:
            tau, rate = tensions.at(t) if tensions is not None else (np.zeros(k), np.zeros(k))
            yield t, f.measurement_row(z, tau, rate)

    return f, rows()


def _passthrough(it: Iterable[int]) -> Iterator[int]:
    yield from it


#: input size up to which a first run (kernels not compiled) uses IPOPT while the kernels
#: compile in the background: IPOPT takes about 5 ms a sample at N = 30 on 2 cores, so
#: up to about 5,000 samples (about 250 kB of tilt CSV) that run ends within about 25 s
#: instead of after the one to two minutes of compiling. (Beyond it the command compiles
#: first; with the 108 s measured in session 27, IPOPT would still be the quicker path up
#: to about 20,000 samples, but that run would take over a minute on the slower solver.)
FIRST_RUN_BACKGROUND_MAX_BYTES = 250_000
#: samples up to which ``demo`` (which knows its length) does the same
FIRST_RUN_BACKGROUND_MAX_SAMPLES = 5000


def _first_run_default(source: str | int) -> FirstRun:
    """``background`` for a short recording (a file of at most
    ``FIRST_RUN_BACKGROUND_MAX_BYTES``, or at most ``FIRST_RUN_BACKGROUND_MAX_SAMPLES``
    samples), ``foreground`` (compile, then run fast) for a long one or a stream."""
    if isinstance(source, int):
        return "background" if source <= FIRST_RUN_BACKGROUND_MAX_SAMPLES else "foreground"
    try:
        path = Path(source)
        small = path.is_file() and path.stat().st_size <= FIRST_RUN_BACKGROUND_MAX_BYTES
    except OSError:
        small = False
    return "background" if small else "foreground"


def check_output_path(output: str, source: str) -> None:
    """The output must be a writable file name in an existing folder (see
    :func:`check_output_target`), not the input itself; checked before any work."""
    out = check_output_target(output)
    if source != "-" and out.exists() and out.resolve() == Path(source).resolve():
        raise InputError(f"{out}: refusing to overwrite the input file")


def _align(
    path_est: str, t_est: np.ndarray, path_truth: str, t_truth: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    idx = np.searchsorted(t_truth, t_est)
    idx = np.clip(idx, 0, len(t_truth) - 1)
    lo = np.clip(idx - 1, 0, len(t_truth) - 1)
    nearest = np.where(np.abs(t_truth[lo] - t_est) < np.abs(t_truth[idx] - t_est), lo, idx)
    match = np.abs(t_truth[nearest] - t_est) <= 1e-6 * np.maximum(1.0, np.abs(t_est))
    n, k = len(t_est), int(match.sum())
    what = (
        f"only {k} of {n} rows have a row at the same t in {path_truth} (within 1 us): "
        "the files' times do not match (another --dt or duration, t in milliseconds, "
        "or the wrong truth file?)"
    )
    if k < max(2, MIN_MATCHED * n):
        raise InputError(f"{path_est}: {what}")
    if k < WARN_MATCHED * n:
        print(f"{PROG}: warning: {path_est}: {what}", file=sys.stderr)
    covered = t_est[match]
    t0, t1 = float(t_truth[0]), float(t_truth[-1])
    share = (covered[-1] - covered[0]) / (t1 - t0) if t1 > t0 else 1.0
    if share < WARN_MATCHED:  # by time span: a truth sampled more densely is no mistake
        print(
            f"{PROG}: warning: {path_est}: its rows cover t = {covered[0]:g} to "
            f"{covered[-1]:g} s of {path_truth}'s {t0:g} to {t1:g} s ({100 * share:.0f} %): "
            "the scores are of that part only (an interrupted or cut estimate?)",
            file=sys.stderr,
        )
    return np.flatnonzero(match), nearest[match]


#: ``evaluate`` refuses files whose times match on fewer than this share of rows (or
#: fewer than 2), and warns below :data:`WARN_MATCHED`, and when the matched rows span
#: less than that share of the truth's time span.
MIN_MATCHED = 0.1
WARN_MATCHED = 0.5


def _length_hint(est_xyz: np.ndarray, truth_xyz: np.ndarray, tip_mean: float, length: float) -> str:
    """A hint when the estimate's tip distances from the base are a constant multiple of
    the truth's (made with another length), else ``""``."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.linalg.norm(est_xyz, axis=1) / np.linalg.norm(truth_xyz, axis=1)
    ratio = ratio[np.isfinite(ratio)]
    if tip_mean < 0.1 * length or not len(ratio):
        return ""
    r = float(np.median(ratio))
    if 0.8 < r < 1.25:
        return ""
    return (
        f"the estimate's tip is {r:.2f} times as far from the base as the truth's: "
        "was it made with another --length (or robot file) than the truth?"
    )


def cmd_evaluate(args: argparse.Namespace) -> int:
    est = read_state_table(args.estimates)
    truth = read_state_table(args.truth)
    robot = robot_from_args(args)  # without --robot: one section of --length
    other_robot = check_same_robot(args.estimates, est, args.truth, truth, robot)
    i_e, i_t = _align(args.estimates, est.t, args.truth, truth.t)
    length = robot.length
    out_names = [n for n in est.names if not n.startswith("std_")]
    cols = [est.names.index(n) for n in out_names]
    try:
        m = compute_metrics(
            est.values[i_e][:, cols], truth.values[i_t], length, out_names, truth.names
        )
    except ValueError as exc:
        raise InputError(f"{args.estimates}: {exc}") from None
    cal = None
    if est.has_std and est.std is not None:
        std = est.std[i_e][:, cols]
        cal = compute_calibration(
            est.values[i_e][:, cols], std, truth.values[i_t], out_names, truth.names
        )
    unmatched = int(len(est.t) - len(i_e))
    xyz = [est.names.index(c) for c in ("x", "y", "z")], [truth.names.index(c) for c in "xyz"]
    hint = other_robot or _length_hint(
        est.values[i_e][:, xyz[0]], truth.values[i_t][:, xyz[1]], m.tip_mean_mm / 1e3, length
    )
    misfits = [
        f"{path}: {misfit}; pass the --length (or --robot) it was made with"
        for path, table in ((args.estimates, est), (args.truth, truth))
        if (misfit := length_misfit(table.names, table.values, robot.lengths))
    ]  # tip errors in % of the length are then of another robot's length
    # a file made for another length explains the estimate-truth ratio too: say it once
    warned = [hint] if other_robot or not misfits else misfits
    for line in filter(None, warned):
        print(f"{PROG}: warning: {line}", file=sys.stderr)
    if args.json:
        extra = {"calibration": None if cal is None else cal.as_dict()}
        srmse = {"srmse": None} if hint else {}  # not a score of two different robots
        print(json.dumps({**m.as_dict(), **extra, **srmse, "unmatched": unmatched}, indent=2))
    else:
        print(format_metrics(m, comparable=not hint))
        print(format_calibration(cal, est.std_columns))
        if unmatched:
            print(f"unmatched rows       {unmatched} of {len(est.t)} (no truth at their t)")
    return 0


def format_calibration(c: Calibration | None, std_columns: bool = False) -> str:
    """Coverage of the 95 % intervals per output, and the tip NEES with its band; without
    them, why (``std_columns``: the file has ``std_`` columns, all empty)."""
    if c is None:
        if std_columns:
            return (
                "calibration          the std_ columns of the estimate file are empty (made "
                "without standard deviations, e.g. on a first run while the kernels compiled)"
            )
        return "calibration          no std_ columns in the estimate file"
    cover = ", ".join(f"{k} {v:.3f}" for k, v in c.coverage.items())
    lo, hi = c.tip_nees_band
    inside = "inside" if lo <= c.tip_nees <= hi else "outside"
    return (
        f"95% interval coverage {cover} (0.95 when calibrated)\n"
        f"tip NEES             {c.tip_nees:.2f} over {c.tip_n} samples (3 when calibrated; "
        f"95% band {lo:.2f} to {hi:.2f}: {inside})"
    )


def format_metrics(m: Metrics, comparable: bool = True) -> str:
    """``evaluate``'s error lines; no SRMSE unless the estimate and the truth are
    ``comparable`` (not of different lengths or robots)."""
    r = m.rmse
    lines = [
        f"samples compared     {m.n} ({m.n_without_estimate} without estimate)",
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
    k = 1
    while f"theta_{k}" in r:
        lines.append(
            f"RMSE theta_{k}, phi_{k}  {math.degrees(r[f'theta_{k}']):.2f}, "
            f"{math.degrees(r[f'phi_{k}']):.2f} deg"
        )
        k += 1
    if comparable:
        summed = ", ".join(r)
        lines.append(f"SRMSE                {m.srmse:.4f} (sum of the RMSEs of {summed}, m + rad)")
    else:  # a score of two different robots would read as a real one
        lines.append(
            "SRMSE                not given: the estimate and the truth differ (see the warning)"
        )
    return "\n".join(lines)


def cmd_demo(args: argparse.Namespace) -> int:
    from rich.table import Table

    from continuum_mhe.estimators.kalman import CompiledExtendedKalmanFilter

    out = Path(args.out)
    check_new_folder(out)
    robot = robot_from_args(args) if args.robot else Robot.single(0.2)
    scenario: ScenarioName = "paper3d" if robot.is_single else "spatial"
    rec = simulate_robot(scenario, robot, seed=args.seed)
    formulation = make_formulation("bend", robot, NoiseSettings())
    names = [o.name for o in rec.outputs]
    results: list[tuple[EstimateSeries, Metrics]] = []
    labels: list[str] = []  # the method, and the backend where it is not the compiled one
    first_run = first_run_mode(_first_run_default(len(rec.t)))
    compiling = first_run == "background" and not kernels_ready()  # before the first start
    for method in METHODS:
        est = make_estimator(method, formulation, MHESettings(), first_run=first_run)
        series = est.run(rec.t, rec.z, progress=interruptible(progress_bar(f"demo: {method}")))
        results.append((series, compute_metrics(series.output, rec.truth, robot.length, names)))
        if "fallback-ipopt" in set(series.status):
            labels.append(f"{method.upper()} (IPOPT)")
        elif method == "ekf" and not isinstance(est, CompiledExtendedKalmanFilter):
            labels.append(f"{method.upper()} (CasADi)")
        else:
            labels.append(method.upper())
    what = "0.2 m" if robot.is_single else robot.describe()
    marked = compiling and labels != [m.upper() for m in METHODS]
    table = Table(
        title=f"{scenario}, {what}, 2 deg noise, N = 30 (continuum-mhe demo)",
        caption=(
            "(IPOPT), (CasADi): the paths that ran, and their times, while the fast "
            "solver's kernels compile in the background (first run only)"
            if marked
            else None
        ),
    )
    angles = [n for n in names if n.startswith(("theta", "phi"))]
    for col in ("method", "tip mean mm", "tip mean %", "tip max mm"):
        table.add_column(col, justify="right")
    for n in angles:
        table.add_column(f"{n} RMSE deg", justify="right")
    table.add_column("median solve ms", justify="right")
    for label, (s, m) in zip(labels, results):
        table.add_row(
            label,
            f"{m.tip_mean_mm:.2f}",
            f"{m.tip_mean_pct:.2f}",
            f"{m.tip_max_mm:.2f}",
            *(f"{math.degrees(m.rmse[n]):.2f}" for n in angles),
            f"{float(np.median(s.solve_ms)):.3f}",
        )
    table_console().print(table)
    all_series = [s for s, _ in results]
    csvs = [out / f"estimates_{m}.csv" for m in METHODS] + [
        out / "measurements.csv", out / "truth.csv"]  # fmt: skip
    with new_files(out) as written:  # after the estimates, not during them
        for path, (series, _) in zip(csvs, results):
            write_estimates(path, series)
            written.append(path)
        write_measurements(csvs[-2], rec.t, rec.z, rec.measurement_names)
        written.append(csvs[-2])
        write_truth(csvs[-1], rec.t, rec.truth, rec.outputs)
        written.append(csvs[-1])
        _demo_figures(out, rec, all_series, robot, scenario, what, written)
    figs = written[len(csvs) :]
    print(f"figures: {', '.join(str(p) for p in figs)}", file=sys.stderr)
    return 0


def _demo_figures(
    out: Path, rec: Recording, all_series: list[EstimateSeries], robot: Robot, scenario: str,
    what: str, written: list[Path],
) -> None:  # fmt: skip
    """The demo's figures in ``out`` (PNG), each file into ``written`` once saved."""
    from continuum_mhe import plotting

    def save(fig: Figure, name: str) -> None:
        written.extend(plotting.save(fig, out / name, ("png",)))  # atomic: saved or not

    where = f"simulated {scenario} recording, {what}"
    save(
        plotting.trajectory_3d(rec.truth, all_series, f"Tip path: truth and estimates ({where})"),
        "demo_trajectory_3d",
    )
    bounds = [sec.theta_max for sec in robot.sections]
    title = f"Tip error, position and bend over time ({where})"
    save(plotting.states_vs_time(rec.t, rec.truth, all_series, title, bounds), "demo_states")
    if not robot.is_single:
        title = f"Backbone at four instants: truth and estimates ({where})"
        save(
            plotting.backbone_snapshots(rec.t, rec.truth, all_series, robot.lengths, title),
            "demo_backbone",
        )


def cmd_check_robot(args: argparse.Namespace) -> int:
    from continuum_mhe.analysis.observability import format_report, observability_report

    robot = robot_from_args(args)
    report = observability_report(robot, samples=args.samples, seed=args.seed)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        print(format_report(robot, report))
    return 0


# --- parser ---------------------------------------------------------------------------
def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"%(prog)s {version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = sub.add_parser("demo", help="simulate paper3d, run MHE, EKF and UKF, print errors, plot")
    p.add_argument("--out", default="continuum-mhe-demo", help="folder for figures and CSVs")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    add_robot_option(p, replaces=())
    p.set_defaults(func=cmd_demo)

    p = sub.add_parser("simulate", help="write a synthetic measurement CSV and its truth")
    p.add_argument("scenario", choices=SCENARIOS)
    p.add_argument("-o", "--output", required=True, help="measurement CSV to write")
    p.add_argument("--truth", help="truth CSV to write")
    p.add_argument("--noise-deg", type=float, default=2.0, help="noise std in degrees")
    p.add_argument(
        "--noise-model",
        choices=NOISE_MODELS,
        default="tilt",
        help="tilt: on roll and pitch independently (default, the paper's); tangent: "
        "isotropic on the tangent plane of gravity (what the estimators' R assumes)",
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--duration", type=float, default=20.0, help="seconds (default 20)")
    p.add_argument("--dt", type=float, default=0.05, help="sample time in s (default 0.05)")
    p.add_argument("--length", type=float, default=0.2, help="section length in m")
    p.add_argument("--mounting", choices=MOUNTINGS, default="z-up")
    add_robot_option(p, replaces=("--length", "--mounting"))
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("estimate", help="estimate shape and tip from a measurement CSV")
    p.add_argument(
        "measurements",
        help="CSV (t,roll,pitch or raw t,ax,ay,az[,gx,gy,gz]), ROS bag, or .mcap",
    )
    p.add_argument("-o", "--output", required=True, help="estimate CSV to write")
    p.add_argument("--method", choices=METHODS, default="mhe")
    p.add_argument("--degrees", action="store_true", help="roll and pitch are in degrees")
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip bad samples (NaN, non-numeric, non-increasing t) and count them",
    )
    p.add_argument(
        "--inputs",
        metavar="TENSIONS.csv",
        help="tendon tensions t,tension_1,...,tension_k (N, the robot file's [[tendon]] "
        "order), interpolated linearly to the measurement times (docs/tendon.md)",
    )
    add_model_options(p)
    add_mhe_options(p)
    add_recovery_options(p)
    p.set_defaults(func=cmd_estimate)

    p = sub.add_parser("evaluate", help="errors of an estimate CSV against a truth CSV")
    p.add_argument("estimates")
    p.add_argument("truth")
    p.add_argument("--length", type=float, default=0.2, help="section length in m")
    add_robot_option(p, replaces=("--length",))
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser(
        "check-robot",
        help="observability of a robot: rank of the measurement Jacobian over the workspace",
    )
    p.add_argument("robot", metavar="ROBOT.toml", help="robot file")
    p.add_argument("--samples", type=int, default=2000, help="random shapes (default 2000)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_check_robot)

    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _one_line_warning(
    message: Warning | str,
    category: type[Warning],
    filename: str,
    lineno: int,
    line: str | None = None,
) -> str:
    kind = "note" if issubclass(category, CompileNotice) else "warning"
    return f"{PROG}: {kind}: {message}\n"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; returns its exit status. The one-line warnings, the numpy
    filter, the signal handlers and the unraisable hook it sets last as long as the
    command: a caller (a script, a test) gets its own back."""
    handlers = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGINT)}
    _SIGNALS_SEEN.clear()  # those of an earlier command run in this process are done
    formatwarning = warnings.formatwarning
    unraisablehook = sys.unraisablehook
    sys.unraisablehook = quiet_unraisable(unraisablehook)
    try:
        with warnings.catch_warnings():
            warnings.formatwarning = _one_line_warning
            # numerical trouble is flagged in each row's status; numpy's own notes would
            # only surround the summary or the one-line error
            warnings.filterwarnings(
                "ignore",
                r"(invalid value|overflow|divide by zero|underflow) encountered",
                RuntimeWarning,
            )
            try:
                signal.signal(signal.SIGTERM, _on_signal)
                signal.signal(signal.SIGINT, _on_signal)
            except ValueError:  # not the main thread (e.g. called from a test runner's thread)
                pass
            return _run_command(argv)
    finally:
        warnings.formatwarning = formatwarning
        sys.unraisablehook = unraisablehook
        for sig, handler in handlers.items():
            try:
                signal.signal(sig, handler)
            except (ValueError, TypeError):  # not the main thread; a handler not set from Python
                pass


def _parse(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = build_parser()  # imports the command modules: seconds on a small machine
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # said by the command's parser, so the usage shown is the command's
        (commands,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        commands.choices[args.command].error(f"unrecognized arguments: {' '.join(unknown)}")
    return args


def _run_command(argv: Sequence[str] | None) -> int:
    try:  # a signal while the parser imports the commands ends the run as one too
        args = _parse(argv)
        check_option_ranges(args)
        code = int(args.func(args))
    except BaseException as exc:  # noqa: BLE001 - sorted out just below
        if _SIGNALS_SEEN and isinstance(exc, UserError) and interrupt_in_chain(exc) is None:
            # a command that stopped cleanly on the signal and then found a problem with
            # its input (``live``'s end-of-session unit check) says it, as without one
            code = _user_error(exc)
            return _signal_exit() if signal.SIGTERM in _SIGNALS_SEEN else code
        # a signal raised inside a C extension (CasADi, numpy) can surface as any
        # exception type: once a signal arrived, the run ends as interrupted
        if _SIGNALS_SEEN or isinstance(exc, KeyboardInterrupt):
            return _signal_exit()
        return _user_error(exc)
    # a command that drained and finished on its own (``live`` after Ctrl-C) keeps its
    # exit status; after SIGTERM the status is 143, as a service manager expects
    return _signal_exit() if signal.SIGTERM in _SIGNALS_SEEN else code


#: exit status of a bug (sysexits.h EX_SOFTWARE)
EXIT_BUG = 70


def _user_error(exc: BaseException) -> int:
    """One line and exit 2 for user errors and file-system errors; anything else is
    a bug: one line saying so (exit 70), the traceback with ``CONTINUUM_MHE_TRACEBACK=1``."""
    if isinstance(exc, UserError):
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    if isinstance(exc, BrokenPipeError):  # e.g. `... | head`: the reader left; stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 1
    if isinstance(exc, OSError) and exc.strerror:
        print(f"{PROG}: error: {exc.filename or ''}: {exc.strerror}", file=sys.stderr)
        return 2
    if not isinstance(exc, Exception):  # SystemExit and the like: not ours to report
        raise exc
    return _report_bug(exc)


def _issues_hint() -> str:
    """``at URL`` from the package's ``Project-URL`` metadata, else ``to the maintainers``."""
    from importlib import metadata

    try:
        urls = metadata.metadata("continuum-mhe").get_all("Project-URL") or []
    except metadata.PackageNotFoundError:
        urls = []
    for entry in urls:
        label, _, url = entry.partition(",")
        if label.strip().lower() in ("issues", "bug tracker", "bugs", "tracker"):
            return f"at {url.strip()}"
    return "to the maintainers"


def _report_bug(exc: Exception) -> int:
    """``continuum-mhe: internal error (a bug): TYPE: message (at FILE:LINE)`` and 70."""
    import traceback

    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (at {Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""
    text = str(exc).splitlines()[0] if str(exc) else ""
    if os.environ.get("CONTINUUM_MHE_TRACEBACK"):
        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    print(
        f"{PROG}: internal error (a bug in continuum-mhe): {type(exc).__name__}: {text}"
        f"{where}; please report it with the command {_issues_hint()} "
        "(CONTINUUM_MHE_TRACEBACK=1 shows the traceback)",
        file=sys.stderr,
    )
    return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
