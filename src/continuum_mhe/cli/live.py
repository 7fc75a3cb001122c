"""``continuum-mhe live``: estimate in real time from a serial IMU stream
(:mod:`continuum_mhe.live.run` runs it)."""

from __future__ import annotations

import argparse
import gc
import json
import os

from continuum_mhe.cli.config import (
    LIVE_RECORDING,
    MADE_LINE,
    MODEL_LINE,
    OPTIONS_LINE,
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
from continuum_mhe.cli.live_options import (
    add_live_view_option,
    add_recording_options,
    add_serial_options,
    refuse_unused_view_options,
    viewer_sink_from_args,
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
from continuum_mhe.cli.program import version
from continuum_mhe.cli.recovery_options import add_recovery_options, recovery_settings_from_args
from continuum_mhe.errors import InputError
from continuum_mhe.extras import MissingExtraError
from continuum_mhe.io.estimate_csv import estimate_columns
from continuum_mhe.io.input_options import MountingWatch
from continuum_mhe.io.inputs import serial_input
from continuum_mhe.io.output_files import refuse_inputs
from continuum_mhe.live.run import WARM_UP_STEPS, open_plot, run_live, warm_up
from continuum_mhe.live.session import LiveSession, LiveSettings
from continuum_mhe.stream.protocol import line_fields, value_columns
from continuum_mhe.stream.reader import open_port, port_hint, stderr_say
from continuum_mhe.stream.recording import RowFile, check_target


def run(args: argparse.Namespace) -> int:
    from continuum_mhe.estimators import make_estimator

    if not args.port:
        raise InputError(
            "--port is required: the serial device (e.g. /dev/ttyACM0), on the command "
            "line or as port in --config"
        )
    settings = LiveSettings(
        port=args.port,
        baud=args.baud,
        fmt=args.format,
        duration=args.duration,
        status_every=args.status_every,
        retry_max_s=args.retry_max,
        # the twist weighed for the summary's warning where estimate would weigh it:
        # neither --imu-twist nor --no-imu-twist given
        weigh_twist=getattr(args, "imu_twist", None) is None,
    )
    # the IMUs' constant-curvature frames unless --imu-twist is given: a stream gives no
    # recording to weigh the twist on first, as estimate does; recorded so, so that
    # estimate --config EST.csv replays the session with them
    if getattr(args, "imu_twist", None) is None:
        args.imu_twist = False
    # nor gyro biases from a still start (estimate's), which it cannot wait for
    if getattr(args, "still_start", None):
        raise InputError(
            "--still-start: live estimates from its first sample, without waiting for a "
            "still start; calibrate the gyro biases at rest (calibrate --port ... "
            "--write-robot) and give that robot file"
        )
    args.still_start = False
    # the options checked and the IMU model decided as estimate does (io.inputs)
    line = serial_input(
        settings.port, settings.fmt, input_options(args), formulation_from_args(args)
    )
    formulation, robot = line.formulation, line.formulation.robot
    check_noise_options_apply(args, formulation)
    method = method_from_args(args, formulation)  # its refusals before the port opens
    # the MHE's window: an options file's MHE options apply where the MHE runs
    mhe = mhe_settings_from_args(args)
    mhe_settings = mhe if method == "mhe" else None
    for target in (args.output, args.record):  # before --overwrite is asked for
        if target:
            refuse_inputs(target, input_files(args))
    out_path = check_target(args.output, args.overwrite, "-o") if args.output else None
    rec_path = check_target(args.record, args.overwrite, "--record") if args.record else None
    if out_path and rec_path and os.path.abspath(out_path) == os.path.abspath(rec_path):
        raise InputError(f"{out_path}: -o and --record name the same file")
    view_sink = None
    if args.view is None:
        refuse_unused_view_options(args, None)
    else:  # the 3D view (continuum_mhe.viewer): checked before the port
        from continuum_mhe.extras import require_together
        from continuum_mhe.viewer import BackboneView, TendonShapes, require_rerun

        # both of live --view's extras named at once where both are missing
        require_together(
            [("serial", "robot", "pyserial"), ("rerun", "view", "rerun-sdk")], "live --view"
        )
        require_rerun()
        view_sink = viewer_sink_from_args(args)
    # before the port opens: the estimator reads its model here, and a throwaway one pays
    # the first-call costs (warm_up), so that no line waits in the port's buffer meanwhile
    # (a device that streams from the start would have them queued, or lost where the
    # buffer is full)
    estimator = make_estimator(
        method, formulation, mhe_settings, recovery=recovery_settings_from_args(args)
    )
    # the first readings against the mounting, named as estimate's reader names them
    estimator.mounting_watch = MountingWatch(
        formulation, name=settings.port, robot_file=args.robot, python=False
    )
    warm_up(make_estimator(method, formulation, mhe_settings), WARM_UP_STEPS[method])
    gc.collect()
    gc.freeze()  # the long-lived objects made so far are never scanned again: shorter GC pauses
    try:
        conn = open_port(settings.port, settings.baud)
    except MissingExtraError:
        raise
    except Exception as exc:
        raise InputError(port_hint(settings.port, exc)) from None
    say = stderr_say("live")
    plot = (
        open_plot(robot.lengths, say, tuple(sec.theta_max for sec in robot.sections))
        if args.plot
        else None
    )
    columns = value_columns(settings.fmt, robot.n_imus, line.tensions_on_line)
    out = (
        None
        if out_path is None
        else RowFile(
            out_path,
            estimate_columns(formulation.outputs, outlier=estimator.flags_outliers),
            args.overwrite,
            (
                f"{MADE_LINE} = "
                + json.dumps(
                    f"{version()} live"
                    + (f", {LIVE_RECORDING} {rec_path.resolve()}" if rec_path is not None else "")
                ),
                f"{OPTIONS_LINE} = {args.options_record}",
                f"{MODEL_LINE} = {model_record(formulation, branch_check_ran(estimator))}",
            ),
        )
    )
    record = None if rec_path is None else RowFile(rec_path, ("t", *columns), args.overwrite)
    view = None if view_sink is None else BackboneView(
        robot, formulation.outputs, view_sink, trail_s=args.trail,
        points_per_section=args.points, max_hz=args.view_hz,
        tendon=TendonShapes(robot, args.points) if robot.backbone is not None else None,
    )  # fmt: skip
    if view_sink is not None and view_sink.kind == "web":
        say(f"serving the view at {view_sink.web_url}")
    session: LiveSession | None = None
    view_error: InputError | None = None
    failed = False
    try:
        session = LiveSession(settings, estimator, line.converters, out, say, record, line.tensions)
        default = " (this robot's default)" if args.method_note else ""
        say(
            f"reading {settings.port} at {settings.baud} baud "
            f"({','.join(line_fields(settings.fmt, robot.n_imus, line.tensions_on_line))}"
            f"{'; tensions from ' + line.tensions.name if line.tensions else ''}); "
            f"{args.method} estimates{default}"
            f"{' to ' + str(out_path) if out_path else ''}"
            f"{'; recording to ' + str(rec_path) if rec_path else ''}; Ctrl-C stops"
        )
        if out is None and record is None:
            say(
                "nothing is saved: give -o EST.csv for the estimates, "
                "--record RAW.csv for the samples"
            )
        code = run_live(settings, session, conn, plot, view)
    except BaseException:
        failed = True
        raise
    finally:
        if view is not None and view_sink is not None:  # a view file without an estimate
            try:  # is not written; one it cannot write (a full disk) is said after
                view.close(keep=view.estimates > 0)  # the other files are closed
            except InputError as exc:
                view_error = exc
                if failed:  # another error ends the session: this one said here
                    say(str(exc))
            if view_sink.kind == "save" and view_error is None:
                path = view_sink.path
                why = None if session is None else session.discarded
                say(
                    f"the view in {path}" + (f" (with the estimates {why})" if why else "")
                    if view.estimates
                    else _not_written(session, path, "estimate")
                )
        removed = False  # the estimates not kept (session.discarded), and the file
        why = None if session is None else session.discarded
        if session is not None and why and out is not None:
            mark = session.discard_from
            wrong = out.rows - mark[0]
            if wrong:
                kept = (
                    f"{out.path} keeps the {mark[0]} before" if mark[0] else f"{out.path} removed"
                )
                say(
                    f"the {wrong} estimates {why} are not "
                    f"kept: {kept}"
                    + (f" ({record.path} keeps the readings as received)" if record else "")
                )
            out.cut_back(mark)
            removed = not out.rows
        for sink, what in ((out, "estimates"), (record, "samples")):
            if sink is None or (removed and sink is out):
                continue
            sink.close()
            if sink.rows:
                say(f"{sink.rows} {what} in {sink.path}")
            else:
                say(_not_written(session, sink.path, "estimate" if sink is out else "sample"))
    if view_error is not None:
        raise view_error
    return code


def _not_written(session: LiveSession | None, path: object, what: str) -> str:
    """The line that the file ``path`` was not written, as it holds no ``what``: no
    sample arrived, or (the session's counts) lines arrived that gave none."""
    counts = None if session is None else session.counts
    if counts is None or not (counts.samples or counts.garbled):
        data = counts.lines - counts.comments - counts.partial if counts else 0
        if session is not None and session.fatal is not None and data > 0:
            # a line that stopped the session (a sample beyond --inputs' times)
            return (
                f"{data} line(s) arrived, but the session stopped before a sample was kept "
                f"(the error below says why): {path} not written"
            )
        return f"no sample arrived: {path} not written"
    arrived = [
        f"{n} {name}"
        for n, name in ((counts.samples, "sample(s)"), (counts.garbled, "garbled line(s)"))
        if n
    ]
    return (
        f"{' and '.join(arrived)} arrived, but no {what} was made of them (the summary "
        f"says why): {path} not written"
    )


DESCRIPTION = (
    "Estimate in real time from a serial IMU stream (line protocol: "
    "t_ms, then ax,ay,az,gx,gy,gz or roll,pitch per IMU in the robot file's order, "
    "then a tendon robot's tension_1..tension_k in N unless --inputs gives them; "
    "'#' lines are the device's messages)."
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_serial_options(p)
    p.add_argument("-o", "--output", help="estimate CSV, written row by row as samples arrive")
    add_tensions_option(p, "instead of the tensions on every line")
    add_tension_gain_option(p)
    add_recording_options(p)
    add_config_option(p)
    p.add_argument(
        "--duration", type=float, help="stop after this many seconds (default: until Ctrl-C)"
    )
    add_method_option(p)
    p.add_argument("--plot", action="store_true", help="show the shape and tip trace live")
    p.add_argument(
        "--status-every", type=float, default=1.0,
        help="seconds between status lines (default 1)",
    )  # fmt: skip
    p.add_argument(
        "--retry-max", type=float, default=5.0,
        help="longest wait between reopen attempts, s (default 5)",
    )  # fmt: skip
    add_model_options(p)
    add_mhe_options(p)
    add_recovery_options(p)
    add_raw_imu_options(p)
    add_live_view_option(p)
