"""``continuum-mhe estimate``: shape and tip from a recording (tilt or raw CSV, ROS bag,
MCAP), written as an estimate CSV or MCAP."""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
import warnings
from collections import Counter
from collections.abc import Generator, Iterable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, TextIO, cast

import numpy as np

from continuum_mhe.cli.config import (
    MADE_LINE,
    MODEL_LINE,
    OPTIONS_LINE,
    T0_LINE,
    add_config_option,
    branch_check_ran,
    model_record,
)
from continuum_mhe.cli.input_options import (
    add_raw_imu_options,
    add_tension_gain_option,
    add_tensions_option,
    input_files,
    input_options,
)
from continuum_mhe.cli.method_options import (
    add_method_option,
    add_mhe_options,
    method_from_args,
    mhe_settings_from_args,
)
from continuum_mhe.cli.model_options import (
    add_model_options,
    check_noise_options_apply,
    formulation_from_args,
)
from continuum_mhe.cli.options import add_overwrite_option, given_options
from continuum_mhe.cli.program import PROG, version
from continuum_mhe.cli.recovery_options import add_recovery_options, recovery_settings_from_args
from continuum_mhe.errors import InputError, TimeUnitError, UserError, time_text
from continuum_mhe.estimators import make_estimator
from continuum_mhe.estimators.run_notices import (
    BendsBeyondBound,
    BendsOnBound,
    ForceBeyondTensions,
    GapsInTime,
    TensionGainFromOne,
    TwistWithTiltImus,
    WideUncertain,
    drifted_notice,
    free_of_load_clause,
    inconsistent_notice,
    recovery_clauses,
    restarts_notice,
    untrusted_start_notice,
)
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.io.csv_files import TimeStepWarning
from continuum_mhe.io.estimate_csv import TimesWrittenAsOneError
from continuum_mhe.io.input_options import robot_fix
from continuum_mhe.io.output_files import check_output_target, refuse_inputs
from continuum_mhe.progress import progress_bar
from continuum_mhe.signals import SIGNALS_SEEN, signals_deferred

if TYPE_CHECKING:
    from continuum_mhe.calibration.still_start import StillStart
    from continuum_mhe.estimators.twist_evidence import TwistEvidence
    from continuum_mhe.io.background import WriteBehind
    from continuum_mhe.io.estimate_sink import EstimateSink
    from continuum_mhe.model.formulations import Formulation

#: Samples read, estimated and written as one block (the compiled policy steps a block in
#: one call; memory stays flat).
BLOCK = 1024

#: the comment key that marks an estimate file cut short by a signal (Ctrl-C, SIGTERM)
PARTIAL = "partial"


def _blocks(
    blocks: Iterable[tuple[np.ndarray, np.ndarray]],
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The input's blocks of samples ``(t, z)`` cut to at most :data:`BLOCK` samples."""
    for t, z in blocks:
        for i in range(0, len(t), BLOCK):
            yield t[i : i + BLOCK], z[i : i + BLOCK]


@dataclass
class _Tally:
    """What ``estimate`` counts over the blocks for its summary: statuses, the statuses
    of samples with a frozen IMU, outliers, samples with a reading, the bends on (or
    past) a section's ``theta_max``, a tendon robot's bends past it, tip force against
    its tensions and tension gains; ``ticks`` moves the progress bar (None: no bar)."""

    ticks: Iterator[int] | None
    bound: BendsOnBound
    beyond: BendsBeyondBound
    force: ForceBeyondTensions
    gain: TensionGainFromOne
    twist: TwistWithTiltImus
    wide: WideUncertain
    gaps: GapsInTime
    counts: dict[str, int] = field(default_factory=dict)
    frozen: dict[str, int] = field(default_factory=dict)
    outliers: int = 0
    #: rows inconsistent because the robust MHE rejected their newest reading
    rejected_inconsistent: int = 0
    readings: int = 0


def _estimate_block(
    t: np.ndarray,
    z: np.ndarray,
    est: Estimator,
    tally: _Tally,
    sink: EstimateSink,
    behind: WriteBehind,
) -> float | None:
    """Step one block of samples (``t`` (n,), ``z`` (n, nz)), count it into ``tally`` and
    hand its rows to ``behind`` for ``sink``; a signal seen meanwhile stops the block
    between two samples, and only the samples stepped are counted and written. Returns
    the last stepped sample's time (None: none)."""
    freezes_before = len(est.diagnostics.first_freezes)
    batch = est.continue_run(
        t, z, check_units=False, should_stop=lambda: bool(SIGNALS_SEEN), check_mounting_start=False
    )
    done = len(batch.status)  # (read checked the units)
    if done == 0:
        return None
    t, z = t[:done], z[:done]
    if tally.ticks is not None:  # the bar moves per sample
        for _ in range(done):
            next(tally.ticks)
    codes = batch.status_strings()
    statuses: list[str] = codes.tolist()
    for status, k in Counter(statuses).items():
        tally.counts[status] = tally.counts.get(status, 0) + k
    for i in np.flatnonzero(batch.frozen).tolist():
        tally.frozen[statuses[i]] = tally.frozen.get(statuses[i], 0) + 1
    note = est.freezes_notice(freezes_before)  # said once per IMU
    if note:
        print(f"{PROG}: note: {note}", file=sys.stderr)
    tally.outliers += int(batch.outlier.sum())
    inconsistent = codes == "inconsistent"
    tally.rejected_inconsistent += int((inconsistent & batch.outlier.astype(bool)).sum())
    tally.bound.add(batch.output, statuses, z)
    tally.beyond.add(batch.output)
    tally.force.add(z, batch.output)
    tally.twist.add(batch.output)
    tally.gain.add(batch.output, batch.output_std)
    tally.wide.add(batch.output_std, codes)
    tally.gaps.add(t, codes == "reset")
    tally.readings += int(np.isfinite(z).any(axis=1).sum())
    behind.submit(sink.write_batch, t, batch.output, batch.output_std, batch.outlier,
                  statuses, batch.solve_ms)  # fmt: skip
    return float(t[-1])


def _reads_ahead(source: str) -> bool:
    """Whether the input is read a block ahead (io.background): a file or a bag folder,
    whose reads end by themselves; not standard input or a pipe, which may wait for data
    (a signal then ends the command in its read)."""
    return source != "-" and (Path(source).is_file() or Path(source).is_dir())


class _HeldTimeUnitWarnings:
    """While active, the warnings that the input's ``t`` steps like another unit are
    held instead of shown (:mod:`warnings`' display, process-wide: the read-ahead thread
    warns too); on leaving, they are shown unless :meth:`drop` was called: a run that
    ends in the error of a time unit says it in that one line alone."""

    def __init__(self) -> None:
        self.held: list[str] = []

    def __enter__(self) -> _HeldTimeUnitWarnings:
        self._saved = warnings.showwarning

        def show(
            message: Warning | str,
            category: type[Warning],
            filename: str,
            lineno: int,
            file: TextIO | None = None,
            line: str | None = None,
        ) -> None:
            if issubclass(category, TimeStepWarning):
                self.held.append(str(message))
                return
            self._saved(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        return self

    def drop(self) -> None:
        self.held = []

    def show(self) -> None:
        """Show the warnings held so far."""
        for message in self.held:
            print(f"{PROG}: warning: {message}", file=sys.stderr)
        self.held = []

    def __exit__(self, *exc: object) -> None:
        warnings.showwarning = self._saved
        self.show()


def run(args: argparse.Namespace) -> int:
    with _HeldTimeUnitWarnings() as held:
        try:
            return _run(args, held)
        except TimeUnitError:  # its line names the unit that the warnings would
            held.drop()
            raise
        except TimesWrittenAsOneError as exc:
            if not held.held:  # times a hair apart, not in another unit: the writer's line
                raise
            said = held.held[0]  # the input's t steps like another unit, and says so
            held.drop()
            raise TimeUnitError(
                f"{said} (t reaches {time_text(exc.t)} s, whose steps the estimate cannot "
                "write apart); nothing written"
            ) from None


def _run(args: argparse.Namespace, held: _HeldTimeUnitWarnings) -> int:
    # any input kind (tilt CSV, raw IMU CSV, ROS bag, MCAP; io.inputs reads it) and
    # output (.csv, .mcap), streamed: the input is read once and memory stays flat
    from continuum_mhe.io.background import WriteBehind, read_ahead
    from continuum_mhe.io.estimate_sink import EstimateSink
    from continuum_mhe.io.imu_topics import warn_topic_order
    from continuum_mhe.io.inputs import open_input

    refuse_inputs(args.output, input_files(args))  # first: an input is the worst to lose
    check_output_path(args.output, args.overwrite)
    out = args.output
    base = formulation_from_args(args)
    twist_given = getattr(args, "imu_twist", None) is not None
    still, base = still_start_biases(args, base)
    twist = choose_imu_twist(args, base)
    with open_input(args.measurements, input_options(args), base, args.robot) as stream:
        formulation = stream.formulation
        check_noise_options_apply(args, formulation)
        method = method_from_args(args, formulation)
        # the MHE's window: an options file's MHE options apply where the MHE runs
        mhe = mhe_settings_from_args(args)
        est = make_estimator(
            method,
            formulation,
            mhe if method == "mhe" else None,
            recovery_settings_from_args(args),
        )
        est.reset()
        diag = est.diagnostics  # the sensor-health policy's counts, kept by each step
        flags_outliers = bool(getattr(est, "flags_outliers", False))
        bar = progress_bar(f"{args.method} estimate")
        ticks = cast(Generator[int, None, None], (bar or _passthrough)(itertools.count()))
        tally = _Tally(
            ticks if bar else None,
            BendsOnBound(formulation),
            BendsBeyondBound(formulation),
            ForceBeyondTensions(formulation),
            TensionGainFromOne(formulation),
            TwistWithTiltImus(formulation),
            WideUncertain(formulation, args.uncertain_fraction),
            GapsInTime(est.recovery.gap_reset),
        )
        source = args.measurements  # by its full path, as --robot and --inputs are
        made = f"{version()} estimate {source if source == '-' else Path(source).resolve()}"
        notes = [
            (MADE_LINE, json.dumps(made)),
            (OPTIONS_LINE, args.options_record),
            (MODEL_LINE, model_record(formulation, branch_check_ran(est))),
        ]
        if stream.t0_ns:  # an MCAP's messages are stamped t0_ns + t, and say it too
            notes.append((T0_LINE, str(stream.t0_ns)))
        interrupted: BaseException | None = None
        # the next block is read and the last one written while the estimator steps this
        # one (io.background); the writes are done before the sink closes
        with (
            EstimateSink(out, formulation, stream.t0_ns, flags_outliers, notes) as sink,
            WriteBehind("estimate-writer") as behind,
        ):
            try:
                last_t = math.nan
                ahead = None
                if _reads_ahead(args.measurements):
                    ahead = read_ahead(stream.blocks, "estimate-reader")
                try:
                    # a signal while waiting for input ends it
                    for t, z in _blocks(stream.blocks if ahead is None else ahead):
                        # a signal stops the block between two samples; the samples
                        # stepped are counted and written, then it is raised
                        with signals_deferred():
                            stepped_to = _estimate_block(t, z, est, tally, sink, behind)
                            if stepped_to is not None:
                                last_t = stepped_to
                finally:
                    if ahead is not None:  # its reader stops before the input closes
                        ahead.close()
                behind.finish()
            except BaseException as exc:  # a signal (in C code: any type): keep what is done
                if not (SIGNALS_SEEN or isinstance(exc, KeyboardInterrupt)):
                    raise
                behind.finish()  # the rows submitted are written (or a write's error)
                if not sink.rows:
                    raise
                interrupted = exc
                cut = f"interrupted after {sink.rows} samples, at t = {time_text(last_t)} s"
                sink.note(PARTIAL, json.dumps(cut))
            finally:
                ticks.close()
            counts = tally.counts
            n = sum(counts.values())
            if n == counts.get("no-estimate", 0):
                why = no_estimate_cause(args, tally.readings, tally.outliers)
                raise InputError(
                    f"{stream.name}: no sample gave an estimate ({n} samples; {why}); "
                    "nothing written"
                )
            if n >= 3 and diag.gap_resets > n // 2:  # t in ms read as s, most often
                fix = "raise --gap-reset, or 0: never"
                if stream.description.time_in_ms:
                    fix = f"t_ms must be in milliseconds: microseconds? (else {fix})"
                elif stream.kind != "log":  # a log's t comes from its own timestamps
                    fix = (
                        "t must be in seconds: if in milliseconds, name the column t_ms; if "
                        f"in microseconds or nanoseconds, give seconds (else {fix})"
                    )
                elif held.held:  # its stamps step like another unit: the warning says how
                    fix = f"{held.held[0].split(': ', 1)[-1]} (else {fix})"
                held.drop()  # this says what the time unit's warning would
                raise InputError(
                    f"{stream.name}: {diag.gap_resets} of {n} samples restarted the estimator "
                    f"after a gap longer than --gap-reset {args.gap_reset:g} s: {fix}; "
                    "nothing written"
                )
            held.show()
    if interrupted is not None:
        print(
            f"{PROG}: kept the {n} estimates made before the interruption in {out}, marked "
            f"'# {PARTIAL} = ...'",
            file=sys.stderr,
        )
        raise interrupted
    restarts = diag.restarts + diag.bad_starts + diag.reject_resets
    # (a row whose reading the robust cost rejected says what the estimator did, not
    # that the model does not follow the robot: the summary counts those as outliers)
    inconsistent = tally.counts.get("inconsistent", 0) - tally.rejected_inconsistent
    inconsistent_note = inconsistent_notice(inconsistent, n, formulation)
    causes_follow = inconsistent_note is not None  # its causes, said once after the others
    if stream.kind == "log" and len(args.topic or ()) > 1:  # topics in the wrong order, most often
        warn_topic_order(stream.name, args.topic, n, restarts)
    elif restarts_note := restarts_notice(n, restarts, diag.last_failure, causes_follow):
        print(f"{PROG}: warning: {stream.name}: {restarts_note}", file=sys.stderr)
    summary = ", ".join(f"{k}: {v}" for k, v in sorted(counts.items()))
    if flags_outliers:
        summary += f"; outliers flagged: {tally.outliers}"
    msg = f"wrote {n} estimates to {out} ({summary})"
    if getattr(args, "method_note", None):
        msg += f"; estimated {args.method_note}"
    for clause in stream.description.summary():
        msg += f"; {clause}"
    if free_note := free_of_load_clause(est.inference, n):
        msg += f"; {free_note}"
    if still is not None:
        msg += f"; {still.clause()}"
    if twist is not None:
        msg += f"; {twist_clause(twist)}"
    if gaps := tally.gaps.clause():
        msg += f"; {gaps}"
    frozen = ", ".join(f"{k}: {v}" for k, v in sorted(tally.frozen.items()))
    for clause in recovery_clauses(diag, est.recovery, n, frozen):
        msg += f"; {clause}"
    if diag.bad_start_chains:
        msg += (
            f"; stopped restarting {diag.bad_start_chains} time(s) after "
            f"{est.formulation.bad_start_chain} restarts in a row that the readings "
            "contradicted too: the model does not fit them (check the robot file and the inputs)"
        )
    if counts.get("inconsistent") or diag.max_noise_scale > 1.5:
        scatter = math.sqrt(diag.max_noise_scale)
        widened = (
            f"the readings scattered up to {scatter:.2g} times their noise model's std "
            "(standard deviations widened by it; "
            if scatter >= 1.05
            else "the readings scattered within their noise model's std ("
        )
        msg += f"; model error: {widened}status inconsistent where they disagree beyond the noise)"
        if diag.model_error > 0:
            msg += (
                f"; a model error of {math.sqrt(diag.model_error):.2g} times the readings' "
                "noise std carried in the standard deviations as a constant error of the "
                "gravity directions"
            )
    raise_it = robot_fix("theta_max", args.robot)
    holds = est.inference.holds_bounds
    # readings that contradicted the estimate on many samples, said above (by
    # restarts_notice, or warn_topic_order for a log's topics, on the same share):
    # restarts from the readings (a bad start, rejected readings), not those of an
    # estimate that diverged (which an estimate held beyond a bound it passes may do)
    contradicted = restarts_notice(n, diag.bad_starts + diag.reject_resets) is not None
    if bound_note := tally.bound.notice(
        n, args.method, holds, raise_it, est.shape_observable, contradicted, causes_follow
    ):
        print(f"{PROG}: warning: {bound_note}", file=sys.stderr)
    if beyond_note := tally.beyond.notice(n):
        print(f"{PROG}: warning: {beyond_note}", file=sys.stderr)
    if force_note := tally.force.notice():
        print(f"{PROG}: warning: {force_note}", file=sys.stderr)
    if gain_note := tally.gain.notice():
        print(f"{PROG}: warning: {gain_note}", file=sys.stderr)
    if twist_note := tally.twist.notice():
        print(f"{PROG}: warning: {twist_note}", file=sys.stderr)
    if wide_note := tally.wide.notice(n):
        print(f"{PROG}: note: {wide_note}", file=sys.stderr)
    if drift_note := drifted_notice(tally.counts.get("drifted", 0), n, formulation):
        print(f"{PROG}: warning: {drift_note}", file=sys.stderr)
    if load_note := untrusted_start_notice(diag, n, bool(formulation.robot.tendons)):
        print(f"{PROG}: warning: {load_note}", file=sys.stderr)
    if inconsistent_note is not None:
        print(f"{PROG}: warning: {inconsistent_note}", file=sys.stderr)
        if not twist_given and twist is None and (hint := uncalibrated_twist_hint(args, base)):
            print(f"{PROG}: warning: {hint}", file=sys.stderr)
    if diag.reject_resets:
        msg += (
            f"; restarted {diag.reject_resets} time(s) after rejecting every reading for over "
            f"{args.reject_reset:g} s"
        )
    for note in stream.description.notes:  # e.g. how the samples of several Imu topics paired
        print(f"{PROG}: note: {note}", file=sys.stderr)
    print(msg, file=sys.stderr)
    return 0


@dataclass(frozen=True)
class _Readings:
    """A recording's measurements read for a choice before the estimate: ``t`` (n,) s,
    ``z`` (n, nz), for ``formulation``."""

    t: np.ndarray
    z: np.ndarray
    formulation: Formulation


def _recording_for_a_choice(
    args: argparse.Namespace, base: Formulation, seconds: float | None = None
) -> _Readings | None:
    """The input's measurements for ``base`` (its first ``seconds`` s, or the whole of it
    for None), for a choice made before the estimate (:func:`still_start_biases`,
    :func:`choose_imu_twist`), where it is a recording (a file, or a ROS 2 bag's folder;
    not a pipe) of a robot with IMUs and without a mechanics model; else None, and None
    where it cannot be read: the estimate's own reading then says why, in the command
    line's words, with the warnings it holds."""
    from continuum_mhe.io.inputs import open_input
    from continuum_mhe.io.robot_logs import is_robot_log

    source = Path(args.measurements)
    if (
        args.measurements == "-"
        or not (source.is_file() or is_robot_log(source))  # a ROS 2 bag is a folder
        or base.robot.has_mechanics
        or not base.robot.imus
    ):
        return None
    times: list[np.ndarray] = []
    values: list[np.ndarray] = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            with open_input(source, input_options(args), base, args.robot) as stream:
                for t, z in stream.blocks:
                    times.append(t)
                    values.append(z)
                    if seconds is not None and len(t) and t[-1] - times[0][0] >= seconds:
                        break  # a block at a time: the rest is not read
                formulation = stream.formulation
        except UserError:
            return None
    if not times:
        return _Readings(np.zeros(0), np.zeros((0, formulation.nz)), formulation)
    return _Readings(np.concatenate(times), np.concatenate(values), formulation)


def still_start_biases(
    args: argparse.Namespace, base: Formulation
) -> tuple[StillStart | None, Formulation]:
    """Where the input is a recording (a file, or a ROS 2 bag's folder; not a pipe) of
    raw IMUs read by the direct model, on a robot without a mechanics model whose robot
    file does not calibrate every IMU's gyro bias, and the recording starts still
    (:func:`~continuum_mhe.calibration.still_start.find_still_start`): the still start,
    and ``base`` with its robot's uncalibrated IMUs given the still start's gyro biases;
    else ``(None, base)``. Its first seconds are read once more for it (its warnings said by
    the estimate's own reading). ``--no-still-start`` (``live``'s record) takes none."""
    from continuum_mhe.calibration.still_start import MAX_S as STILL_START_MAX_S
    from continuum_mhe.calibration.still_start import find_still_start, with_still_start_biases
    from continuum_mhe.model.direct import DirectFormulation, gyro_biases_calibrated

    robot = base.robot
    if getattr(args, "still_start", None) is False or gyro_biases_calibrated(robot):
        return None, base
    data = _recording_for_a_choice(args, base, STILL_START_MAX_S)
    f = None if data is None else data.formulation
    if data is None or not isinstance(f, DirectFormulation):
        return None, base
    still = find_still_start(data.t, data.z, f.measurement_names, robot.n_imus)
    if still is None:
        return None, base
    mount = input_options(args).raw.mount_rpy  # --mount-rpy: the IMUs without their own
    return still, replace(base, robot=with_still_start_biases(robot, still, mount))


def choose_imu_twist(args: argparse.Namespace, base: Formulation) -> TwistEvidence | None:
    """Where neither ``--imu-twist`` nor ``--no-imu-twist`` was given, the input is a
    recording (a file, or a ROS 2 bag's folder; not a pipe) of raw IMUs (the direct
    model, its gyro biases estimated, no ``--own-acceleration``) and the robot file
    gives every IMU a calibrated
    ``gyro_bias``: the readings' evidence for the IMUs' twist
    (:func:`~continuum_mhe.estimators.twist_evidence.twist_evidence`), and
    ``args.imu_twist`` set to its choice; else None, ``args.imu_twist`` off where it was
    not given. The recording is read once more for it (its warnings said by the
    estimate's own reading)."""
    from continuum_mhe.model.direct import gyro_biases_calibrated

    if getattr(args, "imu_twist", None) is not None:
        return None
    args.imu_twist = False
    if not gyro_biases_calibrated(base.robot):
        return None
    evidence = _twist_evidence(args, base)
    if evidence is not None:
        args.imu_twist = evidence.twists
    return evidence


def _twist_evidence(args: argparse.Namespace, base: Formulation) -> TwistEvidence | None:
    """The readings' evidence for the IMUs' twist
    (:func:`~continuum_mhe.estimators.twist_evidence.twist_evidence`) where the input is
    a recording (a file, or a ROS 2 bag's folder; not a pipe) of raw IMUs on a robot
    without a mechanics model, read by the direct model with its gyro biases estimated
    and without ``--own-acceleration``; else None. The recording is read once more for
    it (its warnings said by the estimate's own reading)."""
    from continuum_mhe.estimators.twist_evidence import twist_evidence, weighs_the_twist
    from continuum_mhe.model.direct import DirectFormulation

    if getattr(args, "own_acceleration", False):  # not weighed: the file is not read
        return None
    data = _recording_for_a_choice(args, base)
    f = None if data is None else data.formulation
    if data is None or not isinstance(f, DirectFormulation) or not weighs_the_twist(f):
        return None
    return twist_evidence(f, data.t, data.z)


def uncalibrated_twist_hint(args: argparse.Namespace, base: Formulation) -> str | None:
    """For a run the model did not fit (the warning on inconsistent estimates) of raw
    IMUs whose gyro biases the robot file does not calibrate (so :func:`choose_imu_twist`
    did not weigh the twist): where the readings show the IMUs twisting about the
    backbone (:func:`_twist_evidence`, the twist model estimating the biases too), the
    line that says so and to calibrate first; else None."""
    from continuum_mhe.model.direct import gyro_biases_calibrated

    if gyro_biases_calibrated(base.robot):
        return None
    evidence = _twist_evidence(args, base)
    if evidence is None or not evidence.twists:
        return None
    # the robot as this run gave it: a robot file, or the one section of --length (its
    # --theta-max where given, its --mounting where hanging)
    if args.robot:
        robot = f"--robot {args.robot}"
    else:
        parts = [f"--length {args.length:g}"]
        if "theta_max" in given_options(args):
            parts.append(f"--theta-max {args.theta_max:g}")
        if getattr(args, "mounting", "z-up") == "z-down":
            parts.append("--mounting z-down")
        robot = " ".join(parts)
    return (
        f"{args.measurements}: the readings show the IMUs turning about the backbone, which "
        "the constant-curvature frames do not follow (a model of each IMU's twist predicted "
        f"{evidence.said}): calibrate the gyro "
        "biases with the robot straight and still (continuum-mhe calibrate --from REST.csv "
        f"{robot} --write-robot CAL.toml) and estimate with --robot CAL.toml, or "
        "record the robot still for a second or more before it moves (estimate takes the "
        "biases from that start): either lets the readings weigh the twist; uncalibrated, "
        "--imu-twist takes a gyro's bias about its z axis for a twist (docs/model.md)"
    )


def twist_clause(evidence: TwistEvidence) -> str:
    """The summary's clause on the IMUs' twist that :func:`choose_imu_twist` chose."""
    from continuum_mhe.estimators.twist_evidence import MIN_SAMPLES

    if evidence.samples < MIN_SAMPLES:
        return (
            f"the IMUs' twist not estimated: {evidence.samples} readings to weigh it on, "
            f"fewer than {MIN_SAMPLES} (--imu-twist asks for it)"
        )
    weighed = f"the twist model predicted {evidence.said}"
    if evidence.twists:
        return (
            f"the IMUs' twist estimated (--imu-twist: {weighed}; --no-imu-twist keeps the "
            "constant-curvature frames; a board's yaw about the backbone that the robot "
            "file does not give reads as a twist too: where the robot does not twist, "
            "measure the yaw, calibrate --bend; and so do IMUs in another order than the "
            "robot file's: the columns', or a log's --topic order)"
        )
    return f"the IMUs' twist not estimated ({weighed}; --imu-twist asks for it)"


def _passthrough(it: Iterable[int]) -> Iterator[int]:
    yield from it


def no_estimate_cause(args: argparse.Namespace, readings: int, outliers: int) -> str:
    """Why no sample of ``estimate`` gave an estimate: ``readings`` samples had a
    reading (the others were dropouts), ``outliers`` were rejected by the robust loss."""
    if args.paper_start:
        return f"--paper-start needs at least --horizon {args.horizon} samples"
    if readings == 0:
        return "every sample is a dropout"
    if outliers:
        return (
            f"the robust loss rejected {outliers} sample(s) as outliers (--loss "
            f"{getattr(args, 'loss', 'l2')}; a larger --loss-scale, or --loss l2)"
        )
    return "the estimator failed on every sample (see the statuses in docs/formats.md)"


#: the suffixes of an estimate file ``-o`` may name: CSV, or MCAP (estimate_sink)
ESTIMATE_SUFFIXES = (".csv", ".txt", "", ".mcap")


def check_output_path(output: str, overwrite: bool = False) -> None:
    """The output must be a writable file name in an existing folder (see
    :func:`check_output_target`) with an estimate's suffix, and new unless
    ``overwrite``; checked before any work, after :func:`refuse_inputs` has refused an
    output that is one of the inputs."""
    out = check_output_target(output)
    if out.suffix.lower() not in ESTIMATE_SUFFIXES:  # a name another reader would misread
        raise InputError(
            f"{output}: an estimate is written as CSV (.csv or .txt, or no suffix) or MCAP "
            f"(.mcap), not {out.suffix}"
        )
    check_output_target(output, overwrite)


DESCRIPTION = (
    "Estimate the robot's shape and tip from a recording of its IMUs (tilt or raw "
    "accelerometer and gyro), one row per sample: the tip x, y, z (m), each section's "
    "bend, their standard deviations, the row's status and the solve time. The robot "
    "comes from --robot (a robot file, or a shipped robot's name) or, for one section, "
    "--length; a tendon robot takes its tensions with --inputs and adds the tip force. "
    "The defaults are the best configuration measured for the data given (raw IMUs: their "
    "gyros and gyro biases); the options below say where one helps and where it is worse."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "measurements", help="CSV (t,roll,pitch or raw t,ax,ay,az[,gx,gy,gz]), ROS bag, or .mcap"
    )
    p.add_argument(
        "-o",
        "--output",
        required=True,
        help="estimate file to write: CSV (.csv, .txt or no suffix) or MCAP (.mcap)",
    )
    add_overwrite_option(p)
    add_config_option(p)
    add_method_option(p)
    p.add_argument("--degrees", action="store_true", help="roll and pitch are in degrees")
    p.add_argument(
        "--skip-bad",
        action="store_true",
        help="skip bad samples (NaN, non-numeric, non-increasing t) and count them; a "
        "tensions file's rows with a missing or non-finite tension too (interpolated "
        "across)",
    )
    add_tensions_option(p, "or the recording's own tension_1..k columns")
    add_tension_gain_option(p)
    add_model_options(p)
    add_mhe_options(p)
    add_recovery_options(p)
    add_raw_imu_options(p)
    g = p.add_argument_group("robot logs (ROS 1/2 bags, MCAP)")
    g.add_argument(
        "--topic",
        action="append",
        help="sensor_msgs/msg/Imu topic (default: the only one); with several IMUs, "
        "once per IMU in the robot file's order",
    )
    g.add_argument(
        "--pair-tolerance",
        type=float,
        metavar="SECONDS",
        help="several topics: largest header-stamp difference of paired samples "
        "(default: half of the first topic's median sample period)",
    )
    g.add_argument(
        "--orientation",
        action="store_true",
        help="use the Imu message's orientation (roll, pitch) instead of its raw readings",
    )
