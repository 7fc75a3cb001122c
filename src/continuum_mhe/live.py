"""``continuum-mhe live``: estimate in real time from a serial IMU stream.

The line protocol (one or more IMUs, :mod:`continuum_mhe.stream.protocol`):
``t_ms`` then ``ax,ay,az,gx,gy,gz`` (raw) or ``roll,pitch`` (tilt) per IMU, in the
robot file's order; ``#`` lines are the device's messages, shown and counted.

Every valid sample gives exactly one estimate row in ``-o`` and one row in
``--record`` (the raw or tilt CSV that ``estimate`` reads, ``t`` in seconds of the
device clock), each written whole as it arrives. Garbled, over-long, partial or
out-of-order lines are counted and skipped. A gap in time is reported and estimated
across, never filled. A device clock that wraps (``millis()`` at 2^32 ms) goes on
seamlessly; one that restarts (reset button, reconnect) continues the time axis after
the time it was away, and the estimator restarts there. An estimator that fails or
returns a non-finite estimate is restarted; that sample's row says ``no-estimate``.
When the device disappears the reader reopens it with backoff. A reader thread drains
the port into an unbounded queue: a slow estimator falls behind (and says so) but
never loses a sample.

This module also adds the raw-IMU and robot-log options to ``estimate``, and the
``calibrate`` command.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import queue
import sys
import time
from collections import deque
from typing import Any

import numpy as np

from continuum_mhe.estimators.base import Estimate, Estimator, Measurement
from continuum_mhe.extras import MissingExtraError
from continuum_mhe.io.csv_files import FloatArray, InputError, estimate_columns
from continuum_mhe.io.raw_imu import (
    ATTITUDES,
    IMU_MODELS,
    RawImuSettings,
    parse_mount_rpy,
)
from continuum_mhe.model.descriptions import OutputSpec
from continuum_mhe.signals import SIGNALS_SEEN, defer, stop_deferring
from continuum_mhe.stream.protocol import (
    GarbledLine,
    Sample,
    line_fields,
    parse_line,
    value_columns,
)
from continuum_mhe.stream.reader import Event, SerialReader, open_port, port_hint, stderr_say
from continuum_mhe.stream.recording import RowFile, check_target
from continuum_mhe.stream.session import LiveSession, LiveSettings, imu_converters

__all__ = ["GarbledLine", "LiveSession", "LiveSettings", "Sample", "parse_line", "run_live"]


def run_live(
    settings: LiveSettings,
    session: LiveSession,
    conn: Any,
    plot: Any = None,
    view: Any = None,
) -> int:
    """Read ``conn`` until the duration ends or Ctrl-C / SIGTERM; every queued line is
    processed before returning. ``plot``: anything with ``update(estimate, outputs)``,
    called at each status line; ``view.log_estimate(est)`` (``--view``) sees every
    estimate. Returns the exit status (0); a run that read lines but not one valid
    sample (every line garbled) raises :class:`InputError` naming the first one's cause,
    and so does an accelerometer in g, or a gyro in deg/s where the estimate uses it
    (checked once on the first raw samples, :meth:`LiveSession.check_units`): the run
    stops there, the lines still queued are left, and the summary is said before the
    error."""
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader(settings.port, settings.baud, conn, events, settings.retry_max_s)
    say = session.say
    start = time.monotonic()
    deadline = None if settings.duration is None else start + settings.duration
    next_status = start + settings.status_every
    window_start, window_n = start, 0
    behind_since: float | None = None
    stopping = waiting = False
    # Under the CLI, SIGINT/SIGTERM only set a flag while this loop runs; the loop stops
    # between two lines, so a sample is never in the recording without its estimate.
    defer()
    reader.start()
    try:
        while True:
            if SIGNALS_SEEN:
                raise KeyboardInterrupt
            now = time.monotonic()
            if not stopping and deadline is not None and now >= deadline:
                stopping = True
                reader.stop.set()
                reader.join()
            try:
                kind, payload, arrival = events.get(timeout=0.05)
            except queue.Empty:
                if stopping:
                    break
                kind = ""
            now = time.monotonic()
            if kind == "line":
                est = session.handle_line(payload, arrival)
                if session.fatal is not None:
                    break
                if est is not None:
                    window_n += 1
                    if view is not None:
                        view.log_estimate(est)
                lag = now - arrival
                if lag > settings.behind_s and behind_since is None:
                    behind_since = now
                    say(
                        f"falling behind real time: {lag:.1f} s, {events.qsize()} lines queued "
                        "(all are kept; try --method ekf or a shorter --horizon)"
                    )
                elif lag < 0.5 * settings.behind_s and behind_since is not None:
                    say(f"caught up with real time after {now - behind_since:.1f} s")
                    behind_since = None
            elif kind == "too-long":
                session.counts.too_long += 1
                session.messages.show(
                    f"dropped a line longer than {reader.splitter.max_bytes} bytes "
                    "(no line end: wrong baud rate or not this protocol?)",
                    now,
                )
            elif kind == "partial":
                session.counts.partial += 1
            elif kind == "lost":
                waiting = True
                session.counts.disconnects += 1
                say(
                    f"{settings.port} disconnected ({payload}); waiting for it to come back "
                    f"(retrying up to every {settings.retry_max_s:g} s, Ctrl-C to stop)"
                )
            elif kind == "back":
                waiting = False
                session.device_back()
                say(f"{settings.port} is back after {payload:.1f} s")
            if now >= next_status:
                rate = window_n / max(now - window_start, 1e-9)
                lag = now - arrival if kind == "line" else 0.0
                say(session.status(rate, lag, events.qsize(), waiting))
                window_start, window_n = now, 0
                next_status = now + settings.status_every
                if plot is not None and session.last is not None:
                    plot.update(session.last, session.formulation.outputs)
    except KeyboardInterrupt:
        stop_deferring()  # a second signal abandons the queue at once
        reader.stop.set()
        left = events.qsize()
        say(f"stopping; estimating {left} queued line(s), Ctrl-C again to abandon them")
        try:
            while True:
                try:
                    kind, payload, arrival = events.get_nowait()
                except queue.Empty:
                    break
                if kind == "line":
                    session.handle_line(payload, arrival)
                    if session.fatal is not None:
                        break
        except KeyboardInterrupt:
            say(f"abandoned {events.qsize()} received line(s) without estimates")
    finally:
        stop_deferring()
        reader.stop.set()
    if session.fatal is not None:
        reader.join(timeout=1.0)  # it closes the port (reads time out after 0.05 s)
    session.check_units()  # a session shorter than the check's samples: on them all
    say(session.summary())
    failed = session.fatal or session.only_garbled()
    if failed:
        raise InputError(failed)
    return 0


# --- optional live plot -------------------------------------------------------------------
_NON_INTERACTIVE = {"agg", "pdf", "ps", "svg", "pgf", "cairo", "template"}


def plot_unavailable() -> str | None:
    """Why a matplotlib window cannot open here (one line), or None."""
    try:
        import matplotlib
    except ImportError:
        return "--plot needs matplotlib (pip install matplotlib)"
    on_x11 = sys.platform.startswith(("linux", "freebsd"))
    if on_x11 and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "--plot needs a display (DISPLAY is not set: ssh -X, or a desktop session)"
    backend = str(matplotlib.get_backend()).lower()
    if backend in _NON_INTERACTIVE:
        return (
            f"--plot needs an interactive matplotlib backend, not {backend!r} "
            "(set MPLBACKEND=TkAgg or QtAgg)"
        )
    return None


class LivePlot:
    """Matplotlib view of the current backbone and the tip's trace (``--plot``)."""

    def __init__(self, lengths: tuple[float, ...]) -> None:
        import matplotlib.pyplot as plt

        self.plt = plt
        self.lengths = lengths
        length = sum(lengths)
        plt.ion()
        self.fig = plt.figure("continuum-mhe live")
        self.ax = self.fig.add_subplot(projection="3d")
        s = length
        self.ax.set_xlim(-s, s)
        self.ax.set_ylim(-s, s)
        self.ax.set_zlim(0, s)
        self.ax.set_xlabel("x (m)")
        self.ax.set_ylabel("y (m)")
        self.ax.set_zlabel("z (m)")
        (self.body,) = self.ax.plot([], [], [], lw=3, color="C0")
        (self.trace,) = self.ax.plot([], [], [], lw=1, color="C1")
        self.tips: deque[FloatArray] = deque(maxlen=500)

    def update(self, est: Estimate, outputs: tuple[OutputSpec, ...]) -> None:
        from continuum_mhe.model.descriptions import section_bends
        from continuum_mhe.model.pcc import backbone

        if est.output is None or not np.all(np.isfinite(est.output)):
            return
        pts = backbone(section_bends(outputs, est.output), self.lengths)
        self.body.set_data_3d(pts[:, 0], pts[:, 1], pts[:, 2])
        self.tips.append(pts[-1])
        tr = np.asarray(self.tips)
        self.trace.set_data_3d(tr[:, 0], tr[:, 1], tr[:, 2])
        self.plt.pause(0.001)


def open_plot(lengths: tuple[float, ...], say: Any) -> LivePlot | None:
    """The ``--plot`` window, or None after one line saying why it cannot open."""
    why = plot_unavailable()
    if why is None:
        try:
            return LivePlot(lengths)
        except Exception as exc:  # a backend that fails to open a window
            why = f"--plot: cannot open a matplotlib window ({type(exc).__name__}: {exc})"
    say(f"{why}; estimating without the plot")
    return None


# --- command line ---------------------------------------------------------------------------
def add_raw_imu_options(p: argparse.ArgumentParser) -> None:
    """Options that turn raw IMU samples into measurements (estimate and live)."""
    g = p.add_argument_group("raw IMU input (accelerometer m/s^2, gyro rad/s)")
    g.add_argument(
        "--imu-model",
        choices=IMU_MODELS,
        default="tilt",
        help="tilt: roll/pitch from the accelerometer (default); direct: gravity "
        "direction and gyro rates in the model (needs the gyro)",
    )
    g.add_argument(
        "--attitude",
        choices=ATTITUDES,
        default="accel",
        help="for --imu-model tilt: accel (accelerometer only, default), or madgwick / "
        "mahony gyro fusion from the ahrs package",
    )
    g.add_argument(
        "--mount-rpy",
        default="0,0,0",
        metavar="R,P,Y",
        help="sensor mounting roll,pitch,yaw in degrees: v_tip = Rz(Y) Ry(P) Rx(R) v_sensor",
    )
    g.add_argument(
        "--gyro-std",
        type=float,
        default=0.05,
        help="gyro noise std in rad/s for --imu-model direct (default 0.05)",
    )
    g.add_argument(
        "--estimate-gyro-bias",
        action="store_true",
        help="for --imu-model direct: estimate each gyro's bias (a random-walk state per "
        "IMU) instead of counting it as gyro noise",
    )
    g.add_argument(
        "--estimate-accel-bias",
        action="store_true",
        help="for --imu-model direct: estimate each accelerometer's bias (a random-walk "
        "state per IMU, m/s^2); needs motion through several orientations (docs/model.md)",
    )
    g.add_argument(
        "--own-acceleration",
        action="store_true",
        help="for --imu-model direct: model each IMU's own acceleration (the bend "
        "accelerations become states; docs/model.md)",
    )


def raw_settings(args: argparse.Namespace) -> RawImuSettings:
    """:class:`RawImuSettings` from parsed options (defaults where absent)."""
    return RawImuSettings(
        imu_model=getattr(args, "imu_model", "tilt"),
        attitude=getattr(args, "attitude", "accel"),
        mount_rpy=parse_mount_rpy(getattr(args, "mount_rpy", "0,0,0")),
    )


def input_options(args: argparse.Namespace) -> Any:
    """``input_options.InputOptions`` for ``estimate`` from parsed options."""
    from continuum_mhe.io.input_options import InputOptions

    topics = tuple(getattr(args, "topic", None) or ())
    gyro_std = float(getattr(args, "gyro_std", 0.05))
    if not (math.isfinite(gyro_std) and gyro_std > 0):
        raise InputError(f"--gyro-std must be positive, got {gyro_std}")
    return InputOptions(
        raw=raw_settings(args),
        topic=topics[0] if len(topics) == 1 else None,
        topics=topics,
        pair_tolerance=getattr(args, "pair_tolerance", None),
        use_orientation=bool(getattr(args, "orientation", False)),
        gyro_std=gyro_std,
        estimate_gyro_bias=bool(getattr(args, "estimate_gyro_bias", False)),
        estimate_accel_bias=bool(getattr(args, "estimate_accel_bias", False)),
        own_acceleration=bool(getattr(args, "own_acceleration", False)),
        degrees=bool(getattr(args, "degrees", False)),
        skip_bad=bool(getattr(args, "skip_bad", False)),
    )


def warm_up(estimator: Estimator, steps: int = 40, period_s: float = 0.01) -> None:
    """Run ``steps`` samples of the straight robot through ``estimator``, then reset
    it: compilation and first-call costs (shared by every estimator of the same kind)
    are paid before the first real sample. Give it a throwaway estimator: after this
    warm-up and ``reset()`` the fast MHE's estimates differed from a fresh one's by up
    to 2e-8, enough to break the sample-for-sample replay of a recording."""
    f = estimator.formulation
    h, _ = f.functions.measure(np.zeros(f.nx))
    z = np.asarray(h, dtype=float).reshape(-1)
    for i in range(steps):
        estimator.step(Measurement(i * period_s, z))
    estimator.reset()  # zeroes its counts too


def cmd_live(args: argparse.Namespace) -> int:
    from continuum_mhe.cli_options import (
        formulation_from_args,
        mhe_settings_from_args,
        recovery_settings_from_args,
    )
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.model.direct import DirectFormulation

    settings = LiveSettings(
        port=args.port,
        baud=args.baud,
        fmt=args.format,
        duration=args.duration,
        status_every=args.status_every,
        retry_max_s=args.retry_max,
    )
    raw = raw_settings(args)
    formulation = formulation_from_args(args)
    for dest in ("estimate_gyro_bias", "estimate_accel_bias", "own_acceleration"):
        if getattr(args, dest, False) and raw.imu_model != "direct":
            flag = "--" + dest.replace("_", "-")
            raise InputError(f"{flag} needs --imu-model direct (raw gyros)")
    if raw.imu_model == "direct":
        if settings.fmt != "raw":
            raise InputError("--imu-model direct needs --format raw")
        if formulation.name != "bend":
            raise InputError(f"--imu-model direct uses the bend state, not {formulation.name}")
        if not (math.isfinite(args.gyro_std) and args.gyro_std > 0):
            raise InputError(f"--gyro-std must be positive, got {args.gyro_std}")
        formulation = DirectFormulation(
            robot=formulation.robot,
            noise=formulation.noise,
            gyro_std=args.gyro_std,
            estimate_gyro_bias=bool(getattr(args, "estimate_gyro_bias", False)),
            estimate_accel_bias=bool(getattr(args, "estimate_accel_bias", False)),
            own_acceleration=bool(getattr(args, "own_acceleration", False)),
        )
    robot = formulation.robot
    converters = imu_converters(raw, robot) if settings.fmt == "raw" else None
    out_path = check_target(args.output, args.overwrite, "-o") if args.output else None
    rec_path = check_target(args.record, args.overwrite, "--record") if args.record else None
    if out_path and rec_path and os.path.abspath(out_path) == os.path.abspath(rec_path):
        raise InputError(f"{out_path}: -o and --record name the same file")
    sink = None
    if args.view is not None:  # the 3D view (continuum_mhe.viewer): checked before the port
        from continuum_mhe.cli_options import viewer_sink_from_args
        from continuum_mhe.viewer import BackboneView, require_rerun

        require_rerun()
        sink = viewer_sink_from_args(args)
    try:
        conn = open_port(settings.port, settings.baud)
    except MissingExtraError:
        raise
    except Exception as exc:
        raise InputError(port_hint(settings.port, exc)) from None
    # after the port opened: a first run compiles here (said once) before any line is
    # read; a throwaway estimator pays the first-call costs (warm_up)
    estimator = make_estimator(
        args.method,
        formulation,
        mhe_settings_from_args(args),
        recovery=recovery_settings_from_args(args),
    )
    warm_up(make_estimator(args.method, formulation, mhe_settings_from_args(args)))
    gc.collect()
    gc.freeze()  # the long-lived objects made so far are never scanned again: shorter GC pauses
    say = stderr_say("live")
    plot = open_plot(robot.lengths, say) if args.plot else None
    columns = value_columns(settings.fmt, robot.n_imus)
    out = (
        None
        if out_path is None
        else RowFile(
            out_path,
            estimate_columns(formulation.outputs, outlier=estimator.flags_outliers),
            args.overwrite,
        )
    )
    record = None if rec_path is None else RowFile(rec_path, ("t", *columns), args.overwrite)
    view = None if sink is None else BackboneView(
        robot, formulation.outputs, sink, trail_s=args.trail,
        points_per_section=args.points, max_hz=args.view_hz,
    )  # fmt: skip
    try:
        session = LiveSession(settings, estimator, converters, out, say, record)
        say(
            f"reading {settings.port} at {settings.baud} baud "
            f"({','.join(line_fields(settings.fmt, robot.n_imus))}); {args.method} estimates"
            f"{' to ' + str(out_path) if out_path else ''}"
            f"{'; recording to ' + str(rec_path) if rec_path else ''}; Ctrl-C stops"
        )
        if out is None and record is None:
            say(
                "nothing is saved: give -o EST.csv for the estimates, "
                "--record RAW.csv for the samples"
            )
        return run_live(settings, session, conn, plot, view)
    finally:
        if view is not None:
            view.close()
        for sink, what in ((out, "estimates"), (record, "samples")):
            if sink is None:
                continue
            sink.close()
            if sink.rows:
                say(f"{sink.rows} {what} in {sink.path}")
            else:
                say(f"no sample arrived: {sink.path} not written")


def register(subparsers: Any) -> None:
    """Add ``live``, ``calibrate`` and the raw-IMU / robot-log options of ``estimate``."""
    from continuum_mhe.cli_options import (
        add_live_view_option,
        add_mhe_options,
        add_model_options,
        add_recording_options,
        add_recovery_options,
        add_serial_options,
    )
    from continuum_mhe.estimators import METHODS
    from continuum_mhe.stream.calibrate import register_calibrate

    est = subparsers.choices.get("estimate")
    if est is not None:
        add_raw_imu_options(est)
        g = est.add_argument_group("robot logs (ROS 1/2 bags, MCAP)")
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

    p = subparsers.add_parser(
        "live",
        help="estimate in real time from a serial IMU stream",
        description="Estimate in real time from a serial IMU stream (line protocol: "
        "t_ms, then ax,ay,az,gx,gy,gz or roll,pitch per IMU in the robot file's order; "
        "'#' lines are the device's messages).",
    )
    add_serial_options(p)
    p.add_argument("-o", "--output", help="estimate CSV, written row by row as samples arrive")
    add_recording_options(p)
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument("--method", choices=METHODS, default="mhe", help="estimator (default mhe)")
    p.add_argument("--plot", action="store_true", help="show the shape and tip trace live")
    p.add_argument("--status-every", type=float, default=1.0, help="seconds between status lines")
    p.add_argument(
        "--retry-max", type=float, default=5.0, help="longest wait between reopen attempts, s"
    )
    add_model_options(p)
    add_mhe_options(p)
    add_recovery_options(p)
    add_raw_imu_options(p)
    add_live_view_option(p)
    p.set_defaults(func=cmd_live)
    register_calibrate(subparsers)
