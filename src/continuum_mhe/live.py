"""``continuum-mhe live``: estimate in real time from a serial IMU stream.

Line protocol (ASCII, one sample per line, ending in ``\\n``; ``\\r\\n`` accepted):

* ``raw``:  ``t_ms,ax,ay,az,gx,gy,gz``: device time in ms, specific force in m/s^2 and
  angular rate in rad/s, sensor frame (see ``docs/hardware.md``);
* ``tilt``: ``t_ms,roll,pitch``: device time in ms, angles in rad;
* lines starting with ``#`` are comments (the firmware's header); blank lines are
  ignored.

Every valid sample gives exactly one estimate, appended to the estimate CSV and
flushed at once. Garbled, partial or out-of-order lines are counted and skipped. A gap
in time (longer than ``gap_factor`` times the usual period) is reported and estimated
across, never filled with invented samples. When the device disappears the reader
says so and reopens it with backoff; a device that restarts its clock continues on
the time axis after the wall-clock time it was away. A reader thread drains the port
into an unbounded queue, so an estimator slower than the stream falls behind (and
says so) but never loses a sample.

This module also adds the raw-IMU and robot-log options to ``estimate``.
"""

from __future__ import annotations

import argparse
import csv
import math
import queue
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Literal

import numpy as np

from continuum_mhe.estimators.base import Estimate, Estimator, Measurement
from continuum_mhe.io.csv_files import FloatArray, InputError, estimate_columns, estimate_row
from continuum_mhe.io.raw_imu import (
    ATTITUDES,
    IMU_MODELS,
    RawImuConverter,
    RawImuSettings,
    parse_mount_rpy,
)
from continuum_mhe.model.descriptions import OutputSpec

LineFormat = Literal["raw", "tilt"]
LINE_FORMATS: tuple[LineFormat, ...] = ("raw", "tilt")
FIELDS = {"raw": 7, "tilt": 3}
#: Plausibility limits: MPU9250 full scale (16 g, 2000 deg/s) with 50 % margin.
ACC_LIMIT = 16 * 9.80665 * 1.5
GYRO_LIMIT = math.radians(2000) * 1.5
TILT_LIMITS = (math.pi + 0.05, math.pi / 2 + 0.05)


class GarbledLine(ValueError):
    """A line that is not a valid sample (the message says why)."""


@dataclass(frozen=True)
class Sample:
    """One parsed line: device time ``t`` in s and the values (raw: 6, tilt: 2)."""

    t: float
    values: FloatArray


def parse_line(text: str, fmt: LineFormat) -> Sample | None:
    """Parse one protocol line; None for comments and blank lines.

    Raises :class:`GarbledLine` for anything else that is not a complete, plausible
    sample (wrong field count, non-numbers, non-finite or out-of-range values).
    """
    line = text.strip()
    if not line or line.startswith("#"):
        return None
    parts = line.split(",")
    if len(parts) != FIELDS[fmt]:
        raise GarbledLine(f"expected {FIELDS[fmt]} fields, found {len(parts)}")
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise GarbledLine("non-numeric field") from None
    if not all(math.isfinite(v) for v in nums):
        raise GarbledLine("non-finite value")
    t_ms, vals = nums[0], np.array(nums[1:])
    if t_ms < 0:
        raise GarbledLine("negative time")
    if fmt == "raw":
        if np.any(np.abs(vals[:3]) > ACC_LIMIT) or np.any(np.abs(vals[3:]) > GYRO_LIMIT):
            raise GarbledLine("value beyond the sensor's range")
    elif abs(vals[0]) > TILT_LIMITS[0] or abs(vals[1]) > TILT_LIMITS[1]:
        raise GarbledLine("angle out of range (radians expected)")
    return Sample(t_ms / 1e3, vals)


@dataclass(frozen=True)
class LiveSettings:
    """Settings of a live run.

    Attributes:
        port: serial device (or a pyserial URL such as ``socket://host:port``).
        baud: baud rate.
        fmt: line format, ``"raw"`` or ``"tilt"``.
        duration: stop after this many wall-clock seconds (None: until Ctrl-C).
        status_every: seconds between status lines.
        gap_factor: a step longer than this many usual periods is a gap.
        behind_s: report falling behind when a line waits longer than this, s.
        retry_max_s: longest wait between attempts to reopen a lost device, s.
        restart_gap_s: after a gap longer than this (s) the estimator starts afresh
            from the next sample; the old motion says nothing about the new one.
    """

    port: str
    baud: int = 115200
    fmt: LineFormat = "raw"
    duration: float | None = None
    status_every: float = 1.0
    gap_factor: float = 3.0
    behind_s: float = 1.0
    retry_max_s: float = 5.0
    restart_gap_s: float = 1.0

    def __post_init__(self) -> None:
        if self.fmt not in LINE_FORMATS:
            raise ValueError(f"format must be one of {LINE_FORMATS}, got {self.fmt!r}")
        if not (isinstance(self.baud, int) and self.baud > 0):
            raise ValueError(f"baud must be a positive integer, got {self.baud!r}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be positive seconds, got {self.duration!r}")
        for name in ("status_every", "behind_s", "retry_max_s", "restart_gap_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not self.gap_factor > 1:
            raise ValueError(f"gap_factor must exceed 1, got {self.gap_factor!r}")


@dataclass
class LiveCounts:
    """Running counts of a live session (reported in the status line and at the end)."""

    lines: int = 0
    samples: int = 0
    estimates: int = 0
    comments: int = 0
    garbled: int = 0
    partial: int = 0
    out_of_order: int = 0
    gaps: int = 0
    missing: int = 0  # samples the gaps are estimated to have lost on the device side
    disconnects: int = 0
    header: str = ""
    reasons: dict[str, int] = field(default_factory=dict)


# --- serial reader thread -------------------------------------------------------------------
Event = tuple[str, Any, float]  # (kind, payload, monotonic arrival time)


def open_port(port: str, baud: int) -> Any:
    """Open a serial device or pyserial URL with a short read timeout."""
    import serial

    return serial.serial_for_url(port, baudrate=baud, timeout=0.05)


class SerialReader(threading.Thread):
    """Reads the port into ``events``: ``("line", bytes, t)``, ``("partial", bytes, t)``,
    ``("lost", reason, t)`` and ``("back", seconds_away, t)``. Reopens with backoff."""

    def __init__(
        self, port: str, baud: int, conn: Any, events: queue.Queue[Event], retry_max_s: float
    ) -> None:
        super().__init__(name="continuum-mhe-serial", daemon=True)
        self.port, self.baud, self.conn = port, baud, conn
        self.events = events
        self.retry_max_s = retry_max_s
        self.stop = threading.Event()

    def run(self) -> None:
        buf = b""
        while not self.stop.is_set():
            try:
                chunk = self.conn.read(max(1, self.conn.in_waiting))
            except Exception as exc:  # SerialException, OSError: the device went away
                if buf:
                    self.events.put(("partial", buf, time.monotonic()))
                    buf = b""
                self.events.put(("lost", str(exc) or type(exc).__name__, time.monotonic()))
                self._close()
                self._reopen()
                continue
            if not chunk:
                continue
            now = time.monotonic()
            buf += chunk
            *lines, buf = buf.split(b"\n")
            for line in lines:
                self.events.put(("line", line, now))
        self._close()

    def _close(self) -> None:
        try:
            self.conn.close()
        except Exception:  # noqa: S110 - closing a vanished device may fail; nothing to do
            pass

    def _reopen(self) -> None:
        lost = time.monotonic()
        delay = 0.1
        while not self.stop.wait(delay):
            try:
                self.conn = open_port(self.port, self.baud)
            except Exception:
                delay = min(2 * delay, self.retry_max_s)
                continue
            self.events.put(("back", time.monotonic() - lost, time.monotonic()))
            return


# --- session ----------------------------------------------------------------------------------
class LiveSession:
    """Turns protocol lines into estimates: parsing, time bookkeeping, conversion,
    estimation, output. Thin state; no I/O except the output file and messages."""

    def __init__(
        self,
        settings: LiveSettings,
        estimator: Estimator,
        converter: RawImuConverter | None,
        out: IO[str] | None,
        say: Any = None,
    ) -> None:
        self.settings = settings
        self.estimator = estimator
        self.converter = converter
        self.out = out
        self.writer = None if out is None else csv.writer(out, lineterminator="\n")
        self.say = say or (lambda msg: print(f"live: {msg}", file=sys.stderr, flush=True))
        self.counts = LiveCounts()
        self.last: Estimate | None = None
        self.solve_ms: deque[float] = deque(maxlen=200)
        self._periods: deque[float] = deque(maxlen=50)
        self._t_last: float | None = None  # output time of the last sample, s
        self._dev_last: float | None = None  # device time of the last sample, s
        self._offset = 0.0  # output time = device time + offset
        self._wall_last = 0.0
        self._restarted = False
        if self.writer is not None and out is not None:
            flags = estimator.flags_outliers
            self.writer.writerow(estimate_columns(estimator.formulation.outputs, outlier=flags))
            out.flush()
        estimator.reset()

    def period(self) -> float | None:
        """The usual sample period (median of recent steps), s."""
        return float(np.median(self._periods)) if len(self._periods) >= 3 else None

    def device_back(self) -> None:
        """The device was reopened: its clock may have restarted."""
        self._restarted = True

    def _bad(self, reason: str) -> None:
        self.counts.garbled += 1
        self.counts.reasons[reason] = self.counts.reasons.get(reason, 0) + 1

    def handle_line(self, raw: bytes, arrival: float) -> Estimate | None:
        """Process one line from the device; return its estimate, if it made one."""
        c = self.counts
        c.lines += 1
        try:
            text = raw.decode("ascii")
        except UnicodeDecodeError:
            self._bad("not ASCII")
            return None
        try:
            sample = parse_line(text, self.settings.fmt)
        except GarbledLine as exc:
            self._bad(str(exc))
            return None
        if sample is None:
            if text.strip().startswith("#"):
                c.comments += 1
                if not c.header:
                    c.header = text.strip()
                    self.say(f"device says: {c.header}")
            return None
        return self._handle_sample(sample, arrival)

    def _handle_sample(self, s: Sample, arrival: float) -> Estimate | None:
        c = self.counts
        if self._restarted and self._dev_last is not None and self._t_last is not None:
            self._restarted = False
            if s.t <= self._dev_last:  # the device clock restarted: continue the axis
                away = max(arrival - self._wall_last, self.period() or 0.0)
                self._offset = self._t_last + away - s.t
                self.say(f"device clock restarted; continuing at t={s.t + self._offset:.3f} s")
        t = s.t + self._offset
        if self._t_last is not None and t <= self._t_last:
            c.out_of_order += 1
            return None
        c.samples += 1
        if self._t_last is not None:
            dt = t - self._t_last
            p = self.period()
            if p is not None and dt > self.settings.gap_factor * p:
                lost = max(int(round(dt / p)) - 1, 0)
                c.gaps += 1
                c.missing += lost
                restart = dt > self.settings.restart_gap_s
                how = "estimator restarts" if restart else "estimating across it"
                self.say(
                    f"gap of {dt:.3f} s before t={t:.3f} s (about {lost} samples missing); {how}"
                )
                if self.converter is not None:
                    self.converter.reset()
                if restart:
                    self.estimator.reset()
            else:
                self._periods.append(dt)
        self._t_last, self._dev_last, self._wall_last = t, s.t, arrival
        z = (
            s.values
            if self.converter is None
            else self.converter.convert(t, s.values[:3], s.values[3:])
        )
        est = self.estimator.step(Measurement(t, np.asarray(z, dtype=float)))
        self._write(est)
        return est

    def _write(self, est: Estimate) -> None:
        self.counts.estimates += 1
        self.last = est
        self.solve_ms.append(est.solve_ms)
        if self.writer is None or self.out is None:
            return
        ny = self.estimator.formulation.ny
        flag = est.outlier if self.estimator.flags_outliers else None
        row = estimate_row(est.t, est.output, est.status, est.solve_ms, ny, flag)
        self.writer.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
        self.out.flush()

    def status(self, rate_hz: float, behind_s: float, queued: int, waiting: bool = False) -> str:
        c = self.counts
        parts = ["WAITING for the device" if waiting else f"{rate_hz:5.1f} Hz"]
        if self.solve_ms:
            ms = np.asarray(self.solve_ms)
            parts.append(f"latency {np.median(ms):.1f} ms (max {ms.max():.1f})")
        if self.last is not None and self.last.output is not None:
            x, y, z, th, ph = self.last.output
            parts.append(
                f"t={self.last.t:.2f} s tip=({x * 1e3:.0f},{y * 1e3:.0f},{z * 1e3:.0f}) mm "
                f"theta={math.degrees(th):.1f} phi={math.degrees(ph):.0f} deg [{self.last.status}]"
            )
        parts.append(
            f"estimates {c.estimates}, garbled {c.garbled + c.partial}, "
            f"out-of-order {c.out_of_order}, gaps {c.gaps} (~{c.missing} missing)"
        )
        if behind_s > self.settings.behind_s:
            parts.append(f"BEHIND real time by {behind_s:.1f} s ({queued} lines queued)")
        return ", ".join(parts)

    def summary(self) -> str:
        c = self.counts
        msg = (
            f"{c.samples} samples, {c.estimates} estimates; {c.garbled} garbled and "
            f"{c.partial} partial line(s), {c.out_of_order} out of order, {c.gaps} gap(s) "
            f"(~{c.missing} samples missing), {c.disconnects} disconnect(s)"
        )
        if c.reasons:
            msg += "; garbled: " + ", ".join(f"{k} x{v}" for k, v in c.reasons.items())
        return msg


def run_live(
    settings: LiveSettings,
    session: LiveSession,
    conn: Any,
    plot: Any = None,
) -> int:
    """Read ``conn`` until the duration ends or Ctrl-C; every queued line is processed
    before returning. Returns the exit status (0)."""
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader(settings.port, settings.baud, conn, events, settings.retry_max_s)
    say = session.say
    start = time.monotonic()
    deadline = None if settings.duration is None else start + settings.duration
    next_status = start + settings.status_every
    window_start, window_n = start, 0
    behind_since: float | None = None
    stopping = waiting = False
    reader.start()
    try:
        while True:
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
                if session.handle_line(payload, arrival) is not None:
                    window_n += 1
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
                    plot.update(session.last, session.estimator.formulation.outputs)
    except KeyboardInterrupt:
        reader.stop.set()
        left = events.qsize()
        say(f"stopping (Ctrl-C); estimating {left} queued line(s), Ctrl-C again to abandon them")
        try:
            while True:
                try:
                    kind, payload, arrival = events.get_nowait()
                except queue.Empty:
                    break
                if kind == "line":
                    session.handle_line(payload, arrival)
        except KeyboardInterrupt:
            say(f"abandoned {events.qsize()} received line(s) without estimates")
    finally:
        reader.stop.set()
    say(session.summary())
    return 0


# --- optional live plot -------------------------------------------------------------------
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


def raw_settings(args: argparse.Namespace) -> RawImuSettings:
    """:class:`RawImuSettings` from parsed options (defaults where absent)."""
    return RawImuSettings(
        imu_model=getattr(args, "imu_model", "tilt"),
        attitude=getattr(args, "attitude", "accel"),
        mount_rpy=parse_mount_rpy(getattr(args, "mount_rpy", "0,0,0")),
    )


def input_options(args: argparse.Namespace) -> Any:
    """``robot_logs.InputOptions`` for ``estimate`` from parsed options."""
    from continuum_mhe.io.robot_logs import InputOptions

    gyro_std = float(getattr(args, "gyro_std", 0.05))
    if not (math.isfinite(gyro_std) and gyro_std > 0):
        raise InputError(f"--gyro-std must be positive, got {gyro_std}")
    return InputOptions(
        raw=raw_settings(args),
        topic=getattr(args, "topic", None),
        use_orientation=bool(getattr(args, "orientation", False)),
        gyro_std=gyro_std,
        degrees=bool(getattr(args, "degrees", False)),
        skip_bad=bool(getattr(args, "skip_bad", False)),
    )


def cmd_live(args: argparse.Namespace) -> int:
    from continuum_mhe.cli_options import formulation_from_args, mhe_settings_from_args
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
    if raw.imu_model == "direct":
        if settings.fmt != "raw":
            raise InputError("--imu-model direct needs --format raw")
        if formulation.name != "bend":
            raise InputError(f"--imu-model direct uses the bend state, not {formulation.name}")
        if not (math.isfinite(args.gyro_std) and args.gyro_std > 0):
            raise InputError(f"--gyro-std must be positive, got {args.gyro_std}")
        formulation = DirectFormulation(
            robot=formulation.robot, noise=formulation.noise, gyro_std=args.gyro_std
        )
    converter = RawImuConverter(raw) if settings.fmt == "raw" else None
    estimator = make_estimator(args.method, formulation, mhe_settings_from_args(args))
    try:
        conn = open_port(settings.port, settings.baud)
    except Exception as exc:
        raise InputError(f"{settings.port}: cannot open serial device ({exc})") from None
    out_fh: IO[str] | None = None
    if args.output:
        out = Path(args.output)
        if not (out.parent if str(out.parent) else Path(".")).is_dir():
            raise InputError(f"{out}: folder {out.parent} does not exist")
        out_fh = out.open("w", newline="", encoding="utf-8")
    plot = LivePlot(formulation.robot.lengths) if args.plot else None
    try:
        session = LiveSession(settings, estimator, converter, out_fh)
        fmt = "t_ms,ax,ay,az,gx,gy,gz" if settings.fmt == "raw" else "t_ms,roll,pitch"
        session.say(
            f"reading {settings.port} at {settings.baud} baud ({fmt}); "
            f"{args.method} estimates{' to ' + args.output if args.output else ''}; Ctrl-C stops"
        )
        return run_live(settings, session, conn, plot)
    finally:
        if out_fh is not None:
            out_fh.close()


def register(subparsers: Any) -> None:
    """Add ``live`` and the raw-IMU / robot-log options of ``estimate``."""
    from continuum_mhe.cli_options import add_mhe_options, add_model_options
    from continuum_mhe.estimators import METHODS

    est = subparsers.choices.get("estimate")
    if est is not None:
        add_raw_imu_options(est)
        g = est.add_argument_group("robot logs (ROS 1/2 bags, MCAP)")
        g.add_argument("--topic", help="sensor_msgs/msg/Imu topic (default: the only one)")
        g.add_argument(
            "--orientation",
            action="store_true",
            help="use the Imu message's orientation (roll, pitch) instead of its raw readings",
        )

    p = subparsers.add_parser(
        "live",
        help="estimate in real time from a serial IMU stream",
        description="Estimate in real time from a serial IMU stream (line protocol: "
        "t_ms,ax,ay,az,gx,gy,gz or t_ms,roll,pitch; '#' lines are comments).",
    )
    p.add_argument("--port", required=True, help="serial device, e.g. /dev/ttyACM0 or COM3")
    p.add_argument("--baud", type=int, default=115200, help="baud rate (default 115200)")
    p.add_argument("--format", choices=LINE_FORMATS, default="raw", help="line format")
    p.add_argument("-o", "--output", help="estimate CSV, appended and flushed per sample")
    p.add_argument("--duration", type=float, help="stop after this many seconds")
    p.add_argument("--method", choices=METHODS, default="mhe", help="estimator (default mhe)")
    p.add_argument("--plot", action="store_true", help="show the shape and tip trace live")
    p.add_argument("--status-every", type=float, default=1.0, help="seconds between status lines")
    p.add_argument(
        "--retry-max", type=float, default=5.0, help="longest wait between reopen attempts, s"
    )
    add_model_options(p)
    add_mhe_options(p)
    add_raw_imu_options(p)
    p.set_defaults(func=cmd_live)
