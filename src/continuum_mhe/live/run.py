"""``continuum-mhe live``: estimate in real time from a serial IMU stream.

The line protocol (one or more IMUs, :mod:`continuum_mhe.stream.protocol`):
``t_ms`` then ``ax,ay,az,gx,gy,gz`` (raw) or ``roll,pitch`` (tilt) per IMU, in the
robot file's order, then a tendon robot's ``tension_1..k`` (N) unless a tensions file
gives them; ``#`` lines are the device's messages, shown and counted.

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

The command itself (its options, the estimator and the files): :mod:`continuum_mhe.cli.live`.
"""

from __future__ import annotations

import math
import os
import queue
import time
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.display import display_problem
from continuum_mhe.errors import InputError
from continuum_mhe.estimators.base import Estimate, Measurement
from continuum_mhe.estimators.sensor_health import Estimator
from continuum_mhe.live.session import LiveSession, LiveSettings
from continuum_mhe.model.descriptions import OutputSpec
from continuum_mhe.signals import SIGNALS_SEEN, defer, signals_deferred, stop_deferring
from continuum_mhe.stream.protocol import (
    GarbledLine,
    Sample,
    parse_line,
)
from continuum_mhe.stream.reader import Event, SerialReader

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
    error. An exception of the reader thread (a defect) is raised after the summary."""
    events: queue.Queue[Event] = queue.Queue()
    failure: BaseException | None = None  # the reader thread's defect
    reader = SerialReader(settings.port, settings.baud, conn, events, settings.retry_max_s)
    say = session.say
    start = time.monotonic()
    deadline = None if settings.duration is None else start + settings.duration
    next_status = start + settings.status_every
    window_start, window_n = start, 0
    last_line = start  # when the last line arrived (monotonic s)
    behind_since: float | None = None
    stopping = waiting = False
    acted: list[int] = []  # the signals that stopped the loop, set aside while it drains
    # Under the CLI, SIGINT/SIGTERM only set a flag while this loop runs; the loop stops
    # between two lines, so a sample is never in the recording without its estimate.
    if view is not None:  # every estimate, as it is written
        session.on_estimate = view.log_estimate
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
                reader.join(timeout=2.0)  # its reads time out; its drain takes at most 1 s
            reading = reader.is_alive()  # before the wait: its last event comes first
            try:
                kind, payload, arrival = events.get(timeout=0.05)
            except queue.Empty:
                if stopping:
                    break
                kind = ""
                if not reading:  # ended without its last event: never wait for lines
                    failure = RuntimeError("the serial reader thread ended on its own")
                    break
            if kind == "failed":  # a defect in the reader: raised after the summary
                failure = payload
                break
            now = time.monotonic()
            if kind == "line":
                last_line = now
                est = session.handle_line(payload, arrival)
                if session.fatal is not None:
                    break
                if est is not None:
                    window_n += 1
                lag = now - arrival
                if lag > settings.behind_s and behind_since is None:
                    behind_since = now
                    say(
                        f"falling behind real time: {lag:.1f} s, {events.qsize()} lines queued "
                        f"(all are kept; {_faster(session)})"
                    )
                elif lag < 0.5 * settings.behind_s and behind_since is not None:
                    say(f"caught up with real time after {now - behind_since:.1f} s")
                    behind_since = None
            elif kind == "too-long":
                session.too_long_line(reader.splitter.max_bytes, arrival)
                if session.fatal is not None:
                    break
            elif kind == "unended":
                session.unended_bytes(payload, arrival)
                if session.fatal is not None:
                    break
            elif kind == "partial":
                session.counts.partial += 1
            elif kind == "lost":
                waiting = True
                session.counts.disconnects += 1
                say(
                    f"{settings.port} disconnected ({payload}); waiting for it to come back "
                    f"(retrying up to every {settings.retry_max_s:g} s, Ctrl-C to stop)"
                )
            elif kind == "retrying":
                say(f"{settings.port} does not open yet ({payload}); still retrying")
            elif kind == "back":
                waiting = False
                session.device_back()
                say(f"{settings.port} is back after {payload:.1f} s")
            if now >= next_status:
                rate = window_n / max(now - window_start, 1e-9)
                lag = now - arrival if kind == "line" else 0.0
                say(session.status(rate, lag, events.qsize(), waiting, now - last_line))
                window_start, window_n = now, 0
                next_status = now + settings.status_every
                if plot is not None and session.last is not None:
                    plot.update(session.last, session.formulation.outputs)
    except KeyboardInterrupt:
        # the signal that stopped the loop is acted on by the drain and the end below:
        # set aside (while signals are still deferred), so that only a new one stops
        # them (a solve that defers signals raises those it finds)
        acted[:] = SIGNALS_SEEN
        SIGNALS_SEEN.clear()
        reader.stop.set()
        left = events.qsize()
        say(f"stopping; estimating {left} queued line(s), Ctrl-C again to abandon them")
        try:
            stop_deferring()  # a second signal abandons the queue after its line
            done = 0
            next_progress = time.monotonic() + settings.status_every
            for kind, payload, arrival in _queued(events):
                if kind == "line":
                    # a second signal abandons the queue after this line, not inside it
                    # (its sample recorded without its estimate)
                    with signals_deferred():
                        session.handle_line(payload, arrival)
                    if session.fatal is not None:
                        break
                    done += 1
                if time.monotonic() >= next_progress:  # as the status line, while it waits
                    # (the reader may still add what the port held when it stopped)
                    say(
                        f"estimated {done} queued line(s), {events.qsize()} still queued; "
                        "Ctrl-C abandons them"
                    )
                    next_progress = time.monotonic() + settings.status_every
        except KeyboardInterrupt:
            acted.extend(SIGNALS_SEEN)  # the second signal is acted on here, as the first
            SIGNALS_SEEN.clear()
            reader.join(timeout=1.5)  # what the port still held, read: counted too
            # --record keeps every sample received: these too, without estimates (a
            # third signal waits for this, which takes no estimator's time)
            session.record_only = session.record is not None
            left = 0
            with signals_deferred():
                for kind, payload, arrival in _queued(events):
                    if kind == "line":
                        left += 1
                        if session.record_only:
                            session.handle_line(payload, arrival)
            if session.record is None:
                say(f"abandoned {left} received line(s): neither estimated nor recorded")
            else:
                where = getattr(session.record, "path", "the recording")
                say(
                    f"abandoned the estimates of {left} received line(s); their samples are "
                    f"recorded in {where}"
                )
    finally:
        stop_deferring()
        reader.stop.set()
    if session.fatal is not None:
        reader.join(timeout=1.0)  # it closes the port (reads time out after 0.05 s)
    try:
        session.finish()  # a first sample still waiting for the next one
        session.check_units()  # a session shorter than the check's samples: on them all
    finally:
        SIGNALS_SEEN[:0] = acted  # the command's exit status reads them
    say(session.summary())
    if failure is not None:
        raise failure
    failed = session.fatal or session.only_garbled()
    if failed:
        raise InputError(failed)
    return 0


def _queued(events: queue.Queue[Event]) -> Iterator[Event]:
    """The events queued, taken one at a time until the queue is empty."""
    while True:
        try:
            yield events.get_nowait()
        except queue.Empty:
            return


def _faster(session: LiveSession) -> str:
    """What may make the estimator keep up with the stream, or, where the last estimate
    was a restart that took long (a start fits the state to the readings: a tendon
    robot's, the tip force), that the queue is that restart's."""
    last = session.last
    if last is not None and str(last.status) == "reset" and last.solve_ms > 100.0:
        return (
            f"the estimator's restart took {last.solve_ms:.0f} ms (a start fits the state "
            "to the readings); the queue drains once it is done"
        )
    if session.estimator.name == "mhe":
        return "try --method ekf or a shorter --horizon"
    return (
        f"the {session.estimator.name} is slower than the stream: a lower rate or a faster machine"
    )


# --- optional live plot -------------------------------------------------------------------
_NON_INTERACTIVE = {"agg", "pdf", "ps", "svg", "pgf", "cairo", "template"}


def plot_unavailable() -> str | None:
    """Why a matplotlib window cannot open here (one line), or None."""
    try:
        import matplotlib
    except ImportError:
        return "--plot needs matplotlib (pip install matplotlib)"
    except ValueError as exc:  # its rcParams refuse a setting, such as MPLBACKEND's
        named = os.environ.get("MPLBACKEND")
        if named is not None and "backend" in str(exc):
            return (
                f"--plot needs a matplotlib backend: MPLBACKEND={named!r} names none "
                "(set MPLBACKEND=TkAgg or QtAgg)"
            )
        return f"--plot: matplotlib does not start here ({exc})"
    if (why := display_problem()) is not None:
        return f"--plot needs a display ({why}: ssh -X, or a desktop session)"
    backend = str(matplotlib.get_backend()).lower()
    if backend in _NON_INTERACTIVE:
        return (
            f"--plot needs an interactive matplotlib backend, not {backend!r} "
            "(set MPLBACKEND=TkAgg or QtAgg)"
        )
    return None


class LivePlot:
    """Matplotlib view of the current backbone and the tip's trace (``--plot``): each
    section drawn as the circular arc of its estimated bend (``theta_k, phi_k``; a tendon
    robot's equivalent bend between its end tangents, a sketch of its shape), the trace
    through the estimated tips (``x, y, z``), m, base frame."""

    def __init__(self, lengths: tuple[float, ...], theta_max: tuple[float, ...] = ()) -> None:
        """``lengths``: the sections' lengths, m; ``theta_max``: their bending bounds, rad
        (a robot whose sections together can bend past 90 degrees is drawn below its base
        too)."""
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
        self.ax.set_zlim(-s if sum(theta_max) > math.pi / 2 else 0.0, s)
        self.ax.set_xlabel("x (m)")
        self.ax.set_ylabel("y (m)")
        self.ax.set_zlabel("z (m)")
        (self.body,) = self.ax.plot([], [], [], lw=3, color="C0")
        (self.trace,) = self.ax.plot([], [], [], lw=1, color="C1")
        self.tips: deque[FloatArray] = deque(maxlen=500)

    def update(self, est: Estimate, outputs: tuple[OutputSpec, ...]) -> None:
        from continuum_mhe.model.descriptions import section_bends, tip_position_indices
        from continuum_mhe.model.pcc import backbone

        if est.output is None or not np.all(np.isfinite(est.output)):
            return
        pts = backbone(section_bends(outputs, est.output), self.lengths)
        self.body.set_data_3d(pts[:, 0], pts[:, 1], pts[:, 2])
        self.tips.append(np.asarray(est.output)[list(tip_position_indices(outputs))])
        tr = np.asarray(self.tips)
        self.trace.set_data_3d(tr[:, 0], tr[:, 1], tr[:, 2])
        self.plt.pause(0.001)


def open_plot(
    lengths: tuple[float, ...], say: Any, theta_max: tuple[float, ...] = ()
) -> LivePlot | None:
    """The ``--plot`` window (:class:`LivePlot`), or None after one line saying why it
    cannot open."""
    why = plot_unavailable()
    if why is None:
        try:
            return LivePlot(lengths, theta_max)
        except Exception as exc:  # a backend that fails to open a window
            why = f"--plot: cannot open a matplotlib window ({type(exc).__name__}: {exc})"
    say(f"{why}; estimating without the plot")
    return None


#: Warm-up samples per method: the MHE's fill its window (the default horizon, 30) and
#: run full windows; a filter pays its first-call costs on its first steps (a tendon
#: robot's EKF takes a good part of a second per step: 40 would hold the start back).
WARM_UP_STEPS = {"mhe": 40, "ekf": 3, "ukf": 3}


def warm_up(estimator: Estimator, steps: int = 40, period_s: float = 0.01) -> None:
    """Run ``steps`` samples of the straight robot through ``estimator``, then reset
    it: compilation and first-call costs (shared by every estimator of the same kind)
    are paid before the first real sample (:data:`WARM_UP_STEPS`). Give it a throwaway
    estimator: after this warm-up and ``reset()`` the fast MHE's estimates differed from
    a fresh one's by up to 2e-8, enough to break the sample-for-sample replay of a
    recording."""
    f = estimator.formulation
    z = np.asarray(f.functions.observe(np.zeros(f.nx)), dtype=float).reshape(-1)
    for i in range(steps):
        estimator.step(Measurement(i * period_s, z))
    estimator.reset()  # zeroes its counts too
