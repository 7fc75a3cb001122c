"""A live session: protocol lines in; the device clock, conversion, the tendon tensions,
estimation, the recording and the estimate rows out (no threads, no port:
:mod:`continuum_mhe.live.run` drives it)."""

from __future__ import annotations

import math
import statistics
import time
from collections import Counter, deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import IO, Any, Protocol

import numpy as np

from continuum_mhe.arrays import FloatArray, longer
from continuum_mhe.errors import InputError, time_text
from continuum_mhe.estimators.base import Estimate, Measurement, Status
from continuum_mhe.estimators.reading_units import ReadingUnitsError
from continuum_mhe.estimators.run_notices import (
    GAP_FACTOR,
    BendsBeyondBound,
    ForceBeyondTensions,
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
from continuum_mhe.estimators.sensor_health import Estimator, _reraise_interrupt
from continuum_mhe.estimators.twist_evidence import StreamedTwistEvidence
from continuum_mhe.io.csv_files import DEGREES_LIKE_SHARE
from continuum_mhe.io.estimate_csv import estimate_columns, estimate_row, format_number
from continuum_mhe.io.input_options import MountingError
from continuum_mhe.io.raw_imu import RawImuConverter, clip_notice
from continuum_mhe.io.raw_units import (
    UNIT_CHECK_SAMPLES,
    UNIT_CHECK_SPAN_S,
    check_accel_units,
    check_gyro_units,
)
from continuum_mhe.io.tensions import (
    Tensions,
    TensionsAt,
    TensionStream,
    span_buckling_problem,
    tension_scale_problem,
)
from continuum_mhe.live.counts import DeviceMessages, LatencyHistogram, LiveCounts
from continuum_mhe.live.twist_hint import twist_hint
from continuum_mhe.model.descriptions import TIP_COLUMNS, TIP_FORCE_COLUMNS
from continuum_mhe.model.direct import gyro_biases_calibrated
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.stream.clock import DeviceClock, MicrosecondsCheck
from continuum_mhe.stream.protocol import (
    LINE_FORMATS,
    GarbledLine,
    LineFormat,
    Sample,
    field_count_hint,
    header_fields,
    header_hint,
    line_fields,
    parse_line,
    raw_limits,
)
from continuum_mhe.stream.reader import stderr_say
from continuum_mhe.stream.recording import csv_cell

# Raw lines: the units are checked once, as ``estimate`` checks a raw file (an
# accelerometer in g, ``check_accel_units``; a gyro in deg/s, ``check_gyro_units``), on
# the medians of the first samples, at least UNIT_CHECK_SAMPLES (1 s at the firmware's
# 100 Hz) over at least UNIT_CHECK_SPAN_S, or of all the samples of a shorter session at
# its end; again after a board reset (the
# device clock restarting). The samples are estimated meanwhile: the check never holds
# the stream back.

#: The first sample after the port opened is kept when the next one follows it within
#: ``gap_factor`` usual periods, or this many seconds before the period is known: a line
#: cut inside its ``t_ms`` (``1234,...`` read as ``34,...``) lies 1 s or more before it
#: whenever the device clock is past 1 s.
FIRST_STEP_MAX_S = 0.25
#: A stream of nothing but garbled lines for this long (s, arrival time) with at least
#: ``GARBAGE_STOP_LINES`` of them stops the session with the last one's cause.
GARBAGE_STOP_S = 3.0
GARBAGE_STOP_LINES = 20
#: the largest step (in the units sent) from the last valid tilt angles to the first
#: garbled ones for the garbled run to be taken as degrees that grew past the radians'
#: range (successive samples of a moving robot differ by a few degrees at most)
DEGREES_CONTINUED = 5.0
#: A status line after this many seconds (arrival time) without a line says so, and
#: that its last estimate is that old.
SILENT_S = 1.0
#: The characters of the first garbled line that its notice shows.
SHOWN_CHARS = 48

#: The cause of a line that is not ASCII, with its likely fix: bytes read at another
#: baud rate than the device sends at are mostly not ASCII, and they can end lines too
#: seldom for the run of garbage to stop the session.
NOT_ASCII = "not ASCII (the device sending at another baud rate than --baud?)"


#: The device clock is held against the host's arrival times once this many seconds
#: of arrival have passed since the first sample of a run of the clock (and
#: :data:`CLOCK_CHECK_SAMPLES` samples): a clock that advanced less than
#: :data:`CLOCK_SLOW_FACTOR` times as much sends seconds as ``t_ms`` (the session stops).
CLOCK_CHECK_S = 2.0
CLOCK_CHECK_SAMPLES = 20
CLOCK_SLOW_FACTOR = 0.01
#: A stream that starts this many seconds after its tensions file's first row is said:
#: a file that starts with the stream on another clock gives every sample another
#: time's tensions.
TENSIONS_LATE_START_S = 0.5


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
        restart_jump_s: a device clock that jumps back by more than this (s) restarted;
            so did one that jumps back by less to under half its last time, where the
            next line follows it (:data:`~continuum_mhe.stream.clock.HELD_BACK_S`).
        repeat_every_s: a device message that repeats is shown at most this often, s.
        weigh_twist: weigh the IMUs' twist on the readings for the summary's warning
            (:class:`~continuum_mhe.estimators.twist_evidence.StreamedTwistEvidence`);
            off where ``--imu-twist`` or ``--no-imu-twist`` was given, as ``estimate``
            weighs it only where neither was.

    After a gap longer than the estimator's ``recovery.gap_reset`` (``--gap-reset``) the
    estimator itself restarts from the next sample (status ``reset``), as in
    ``estimate``: one mechanism, :meth:`~continuum_mhe.estimators.sensor_health.Estimator.step`.
    """

    port: str
    baud: int = 115200
    fmt: LineFormat = "raw"
    duration: float | None = None
    status_every: float = 1.0
    gap_factor: float = GAP_FACTOR
    behind_s: float = 1.0
    retry_max_s: float = 5.0
    restart_jump_s: float = 1.0
    repeat_every_s: float = 5.0
    weigh_twist: bool = True

    def __post_init__(self) -> None:
        if self.fmt not in LINE_FORMATS:
            raise ValueError(f"format must be one of {LINE_FORMATS}, got {self.fmt!r}")
        if not (isinstance(self.baud, int) and self.baud > 0):
            raise ValueError(f"baud must be a positive integer, got {self.baud!r}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be positive seconds, got {self.duration!r}")
        for name in (
            "status_every",
            "behind_s",
            "retry_max_s",
            "restart_jump_s",
            "repeat_every_s",
        ):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be positive, got {v!r}")
        if not self.gap_factor > 1:
            raise ValueError(f"gap_factor must exceed 1, got {self.gap_factor!r}")


@dataclass(frozen=True)
class _Pending:
    """A sample converted and recorded, waiting for its estimate: ``given`` its tendon
    tensions, rates and second derivatives (None: not known yet, or a robot without a
    mechanics model); ``restart``: the estimator restarts before it (a clock restart)."""

    t: float
    z: FloatArray
    restart: bool
    arrival: float
    given: tuple[FloatArray, FloatArray, FloatArray] | None = None


class RowSink(Protocol):
    def write_row(self, cells: Sequence[str]) -> None: ...


class _TextSink:
    """Rows to an open text stream (the header at once), flushed per row."""

    def __init__(self, out: IO[str], header: Sequence[str]) -> None:
        self.out = out
        out.write(",".join(header) + "\n")
        out.flush()

    def write_row(self, cells: Sequence[str]) -> None:
        self.out.write(",".join(cells) + "\n")
        self.out.flush()


# --- session ----------------------------------------------------------------------------------
class LiveSession:
    """Turns protocol lines into estimates: parsing, the device clock, conversion,
    estimation, recording and output. No I/O except the sinks and messages.

    ``converter``: None for tilt lines, else one converter per IMU (a single converter
    serves a one-IMU robot). ``out``: estimate rows (an open text stream or a
    :class:`RowFile`); ``record``: a :class:`RowFile` for the samples as received.

    A robot with a mechanics model (a tendon formulation) takes its tendon tensions
    from ``tensions``, a tensions file (each sample's at its time, as ``estimate``
    reads it; a sample outside the file's times stops the session), else from every
    line's fields after the IMUs' (``tension_1..k``, N; recorded as such columns).
    Tensions from the line enter with the derivatives the same rows give in a file
    (:class:`~continuum_mhe.io.tensions.TensionStream`): each sample is estimated once
    the two samples after it have arrived (four near a candidate glitch of the tensions,
    until it is judged; the last ones at the end of the session), so that ``estimate``
    on the recording gives the same estimates.
    """

    def __init__(
        self,
        settings: LiveSettings,
        estimator: Estimator,
        converter: RawImuConverter | Sequence[RawImuConverter] | None,
        out: IO[str] | RowSink | None,
        say: Any = None,
        record: RowSink | None = None,
        tensions: Tensions | None = None,
    ) -> None:
        self.settings = settings
        self.estimator = estimator
        # the device clock's unit is judged here, with the device's words (a clock that
        # does not run, or runs in microseconds), not as the estimator's times
        estimator.refuses_fast_times = False
        self.formulation = estimator.formulation
        #: whether the fast MHE's IPOPT fallback is being built, or need not be
        #: (:meth:`_prepare_fallback`), and the estimates it counts towards a full window
        self._fallback_prepared = False
        self._estimated = 0
        self.n_imus = self.formulation.robot.n_imus
        #: each IMU's plausibility limits of a raw line (its robot file's full scales)
        self._raw_limits = tuple(
            raw_limits(p.accel_range, p.gyro_range) for p in self.formulation.robot.imus
        )
        f = self.formulation
        #: the tendon formulation that takes the tensions (None: a robot without them)
        self.tendon = f if isinstance(f, TendonFormulation) else None
        if tensions is not None and self.tendon is None:
            raise ValueError("tendon tensions given for a robot without a mechanics model")
        self.tension_file = tensions
        #: the tensions a file gives (``--inputs``): a line that carries them too is told so
        self._file_tensions = f.robot.n_tendons if tensions is not None else 0
        #: tendon tensions on every line, after the IMUs' values
        self.n_tensions = f.robot.n_tendons if self.tendon is not None and tensions is None else 0
        #: where tensions on the line first neared the load that buckles a disk-routed
        #: section between its disks (:func:`span_buckling_problem`), for the summary
        self._span_buckling = ""
        self._tension_stream = (
            TensionStream(f"{settings.port}: the tensions on the line", self.n_tensions)
            if self.n_tensions
            else None
        )
        self._pending: deque[_Pending] = deque()
        #: samples are recorded (``record``) and counted but not estimated: the lines
        #: queued when a second signal abandoned their estimates
        self.record_only = False
        self.converters: list[RawImuConverter] | None = (
            None
            if converter is None
            else [converter]
            if isinstance(converter, RawImuConverter)
            else list(converter)
        )
        if self.converters is not None and len(self.converters) != self.n_imus:
            raise ValueError(f"{len(self.converters)} converter(s) for {self.n_imus} IMU(s)")
        self.flags_outliers = bool(getattr(estimator, "flags_outliers", False))
        #: a tendon robot's tension gains, for the summary's warning where one ends far
        #: from 1 (``--estimate-tension-gain``)
        self.gains = TensionGainFromOne(self.formulation)
        #: a tendon robot's twist estimated from tilt IMUs, for the summary's warning
        self.twist = TwistWithTiltImus(self.formulation)
        #: raw IMUs on the constant-curvature frames: the readings' evidence for the
        #: IMUs' twist, weighed alongside for the summary's warning
        self.twist_evidence = StreamedTwistEvidence(self.formulation, settings.weigh_twist)
        #: a tendon robot's tip force against its tensions, and its bends past a
        #: section's theta_max, for the summary's warnings (as estimate's)
        self.force = ForceBeyondTensions(self.formulation)
        self.beyond = BendsBeyondBound(self.formulation)
        #: the estimates ``uncertain`` for their width, for the summary's note (as
        #: estimate's)
        self.wide = WideUncertain(self.formulation, estimator.recovery.uncertain_fraction)
        #: the estimates written, by status (the summary's drifted warning counts them)
        self.status_counts: Counter[str] = Counter()
        #: rows inconsistent because the robust MHE rejected their newest reading
        self.rejected_inconsistent = 0
        columns = estimate_columns(self.formulation.outputs, outlier=self.flags_outliers)
        self.out: RowSink | None = (
            None if out is None else out if hasattr(out, "write_row") else _TextSink(out, columns)
        )
        self.record = record
        #: called with every estimate as it is made (``live --view``'s hook), the first
        #: sample after an open included, which is estimated when the next one arrives
        self.on_estimate: Callable[[Estimate], None] | None = None
        self.say = say or stderr_say("live")
        self.counts = LiveCounts()
        self.messages = DeviceMessages(self.say, settings.repeat_every_s)
        self.clock = DeviceClock(settings.restart_jump_s)
        self.latency = LatencyHistogram()
        self.latency_max_window = 0.0  # largest latency since the last status line, ms
        self.last: Estimate | None = None
        self.solve_ms: deque[float] = deque(maxlen=200)
        self._periods: deque[float] = deque(maxlen=50)
        self._period: float | None = None  # median of _periods, while they are unchanged
        #: the ``# fields:`` declarations judged so far (a device that restarts says its
        #: own again; another firmware may say others): each said once
        self._fields_seen: set[tuple[str, ...]] = set()
        #: the device named the fields --format and --robot expect (its ``# fields:``
        #: line): a line of another count is cut or garbled, not another format
        self._fields_match = False
        #: the first raw samples' values, until their units are checked (None: checked,
        #: or tilt lines)
        self._units_unchecked: list[FloatArray] | None = None if self.converters is None else []
        self._units_since = 0.0  # the time of the first sample in _units_unchecked, s
        self._units_times: list[float] = []  # the times of the samples in _units_unchecked, s
        self._unused_gyro_checked = False  # a gyro the estimate ignores: warned once at most
        #: :attr:`fatal` says the readings are in the wrong units (an accelerometer in g,
        #: a gyro in deg/s the estimate uses): the estimates made since
        #: :attr:`units_mark` are from them
        self.wrong_units = False
        #: :attr:`fatal` says the first readings put the robot the other way up from its
        #: stated mounting: every estimate of the session assumed it
        self.wrong_mounting = False
        #: the estimate sink's end (its ``mark()``, where it has one) when the units check
        #: was last armed: at the start, and at each board reset
        self.units_mark: tuple[int, int] | None = None
        self._mark_units()
        #: tilt: the last valid sample's angles, and whether the current run of garbled
        #: lines began with angles beyond their range that follow on from them
        self._last_tilt: FloatArray | None = None
        self._degrees_run = False
        #: the lines skipped in such runs, and the valid samples, since the units check
        #: was last armed (:meth:`_mark_units`)
        self._degree_lines = 0
        self._samples_at_mark = 0
        #: the last garbled line's cause, text and arrival (s), and whether its cause was
        #: a tilt angle beyond the radians' range
        self._garbage_last: tuple[str, str, float, bool] = ("", "", 0.0, False)
        #: the first sample of the device clock's run (its arrival and time, s), and the
        #: samples since, until the clock is held against the arrival times
        self._clock_checked = False
        #: where the clock check starts: the arrival (s), the axis time (s) and the
        #: device's stamp (ms)
        self._clock_since: tuple[float, float, float | None] | None = None
        self._clock_samples = 0
        #: whether the lines' device clock runs a thousand times too fast (microseconds)
        self._microseconds = MicrosecondsCheck()
        #: why the session must stop (an accelerometer in g, a gyro in deg/s where the
        #: estimate uses it): one line, raised by :func:`~continuum_mhe.live.run_live`; no
        #: line is handled after
        self.fatal: str | None = None
        self._restarted = False  # the estimator was restarted: flag its next estimate
        #: the next line is the first since the port opened (or reopened): the device may
        #: have been mid-line then, so if it does not parse it counts as partial
        self._joined = True
        #: that first line, parsed, until the next sample shows whether it was whole
        self._held: tuple[Sample, float] | None = None
        # a sample whose t_ms jumped back with no reconnect or banner before it (a
        # restart if the next sample follows it, else a corrupted t_ms), or ahead of the
        # time the host saw pass (a gap if the next sample follows it, else a corrupted
        # t_ms), with its arrival and whether it jumped ahead
        self._jumped: tuple[Sample, float, bool] | None = None
        #: arrival of the first of the garbled lines since the last valid sample, and
        #: their count
        self._garbage_since: float | None = None
        #: (arrival, bytes) of the first report of bytes with no line end, since the
        #: last line end
        self._unended_since: tuple[float, int] | None = None
        #: lines skipped (garbled, over-long, out of order) since the last valid sample
        self._skipped = 0
        self._garbage_lines = 0
        estimator.reset()

    def period(self) -> float | None:
        """The usual sample period (median of recent steps), s."""
        if self._period is None and len(self._periods) >= 3:
            self._period = statistics.median(self._periods)
        return self._period

    def device_back(self) -> None:
        """The device was reopened: its clock may have restarted, and its first line may
        be cut. A line held for jumping back before it went away is settled first, as
        the device's restart (no line after it can say otherwise)."""
        if self._jumped is not None and self.fatal is None:
            (held, arrival, ahead), self._jumped = self._jumped, None
            self._handle_sample(held, arrival, confirmed=ahead)
        self.clock.expect_restart()
        self._joined = True

    def _bad(
        self,
        reason: str,
        arrival: float,
        text: str = "",
        shown: str | None = None,
        kind: str | None = None,
        degrees: bool = False,
    ) -> None:
        """One garbled line (``reason``), ``text`` its characters (``shown``: how to show
        it where it has none, its bytes); the first is said with the port, its line
        number in the session and its beginning, the rest are counted by ``kind`` (the
        cause without the line's values; ``reason`` where None); ``degrees``: its cause
        is a tilt angle beyond the radians' range."""
        c = self.counts
        self._skipped += 1
        if self._joined:  # the port opened mid-line: the tail of a line, not a garbled one
            self._joined = False
            expected = len(line_fields(self.settings.fmt, self.n_imus, self.n_tensions))
            if len(text.split(",")) <= expected:  # (more fields: a whole line, garbled)
                c.partial += 1
                return
        c.garbled += 1
        key = kind or reason
        c.reasons[key] = c.reasons.get(key, 0) + 1
        if c.first_garbled is None:  # said once, as it happens (the rest are counted)
            c.first_garbled = reason + self._hint(text)
            begin = text[:SHOWN_CHARS] + ("..." if len(text) > SHOWN_CHARS else "")
            self.say(
                f"garbled line skipped: {c.first_garbled} ({self.settings.port}, line "
                f"{c.lines}: {repr(begin) if shown is None else shown}; said for the first "
                "only; all are counted)"
            )
        self._garbage(arrival, reason + self._hint(text), text, degrees)

    def _continues(self, text: str) -> bool:
        """Whether the tilt angles of the line ``text`` follow on from the last valid
        sample's (each within :data:`DEGREES_CONTINUED` of it, in the units sent; an
        IMU that was a dropout there, such as one already past the radians' range on a
        line of several IMUs, is not compared): angles in degrees that grew past the
        radians' range, not a stream that turned to garbage."""
        last = self._last_tilt
        fields = text.split(",")[1 : 1 + len(last)] if last is not None else []
        if last is None or len(fields) < len(last):
            return False
        try:
            angles = np.array([float(f) for f in fields])
        except ValueError:
            return False
        known = np.isfinite(last)
        step = np.abs(angles[known] - last[known])
        return bool(known.any() and np.all(np.isfinite(step)) and step.max() <= DEGREES_CONTINUED)

    def _hint(self, text: str) -> str:
        hint = field_count_hint(
            text, self.settings.fmt, self.n_imus, self.n_tensions, self._file_tensions
        )
        if self._fields_match and "tendon tensions" not in hint:
            return ""  # the device named the expected fields: a cut line
        return hint  # (a line of the IMUs' fields alone lacks the tensions either way)

    def _garbage(self, arrival: float, why: str, text: str = "", degrees: bool = False) -> None:
        """One more garbled line in the run of them since the last valid sample: a run
        over ``GARBAGE_STOP_S`` s of ``GARBAGE_STOP_LINES`` lines or more sets
        :attr:`fatal` with the cause of its last line (``text``), and the likely cause of
        its field count (:func:`~continuum_mhe.stream.protocol.field_count_hint`; said
        here even where the device declared its fields, whose wrong count in one line
        is taken as a cut line: not for seconds of them)."""
        if self._garbage_since is None:
            self._garbage_since = arrival
        self._garbage_lines += 1
        self._garbage_last = (why, text, arrival, degrees)
        span = arrival - self._garbage_since
        if span >= GARBAGE_STOP_S and self._garbage_lines >= GARBAGE_STOP_LINES:
            self._stop_on_garbage()

    def _stop_on_garbage(self) -> None:
        """Set :attr:`fatal` for the run of garbled lines since the last valid sample,
        naming its last line's cause; where the run is of tilt angles in degrees that grew
        past the radians' range from the last valid sample, the samples since the start
        or a board reset were degrees read as radians (:attr:`wrong_units`: their
        estimates are not kept); a stream that turned to garbage keeps its estimates."""
        why, text, arrival, degrees = self._garbage_last
        since = arrival if self._garbage_since is None else self._garbage_since
        span = arrival - since
        after = f" after {self.counts.samples} valid sample(s)" if self.counts.samples else ""
        hint = field_count_hint(
            text, self.settings.fmt, self.n_imus, self.n_tensions, self._file_tensions
        )
        if hint and hint not in why:
            why += hint
        self.fatal = (
            f"{self.settings.port}: nothing but garbled lines for {span:.1f} s{after} "
            f"({self._garbage_lines} lines; the last: {why}); check --format, --robot "
            "and --baud"
        )
        if degrees and self._degrees_run:
            self.wrong_units = True

    def _stop_on_degrees(self, why: str) -> None:
        """Set :attr:`fatal` (:attr:`wrong_units`) where the lines skipped for tilt
        angles that grew past the radians' range from the valid samples' (degrees read as
        radians) number :data:`GARBAGE_STOP_LINES` or more and
        :data:`~continuum_mhe.io.csv_files.DEGREES_LIKE_SHARE` or more of the lines read
        since the units check was armed, however short each run (a fast stream, or a robot
        that passes near straight, where degrees read as radians, more often than every
        :data:`GARBAGE_STOP_S` s): the rule ``estimate`` applies to a file's rows."""
        n = self._degree_lines
        judged = n + self.counts.samples - self._samples_at_mark
        if self.fatal is not None or n < GARBAGE_STOP_LINES or n < DEGREES_LIKE_SHARE * judged:
            return
        self.fatal = (
            f"{self.settings.port}: {n} of {judged} lines skipped for tilt angles that grew "
            f"past the radians' range from the samples before them (the last: {why}): the "
            "angles are in degrees; send radians"
        )
        self.wrong_units = True

    @property
    def discarded(self) -> str | None:
        """Why the estimates from :attr:`discard_from` on are not to be kept (what they
        were made from), or None."""
        if self.wrong_units:
            return "made from readings in the wrong units"
        if self.wrong_mounting:
            return "made with the robot described the wrong way up"
        return None

    @property
    def discard_from(self) -> tuple[int, int]:
        """The estimate sink's mark from which :attr:`discarded` applies: readings in
        the wrong units, since the units check was last armed (a board reset re-arms
        it); the wrong mounting, every estimate of the session."""
        return (self.units_mark or (0, 0)) if self.wrong_units else (0, 0)

    def only_garbled(self) -> str | None:
        """Why the session failed if it read lines but not one valid sample (every line
        garbled: the wrong --format, --robot or --baud), else None."""
        c = self.counts
        bad = c.garbled + c.partial + c.too_long
        if c.samples or not bad:
            return None
        first = f" (the first: {c.first_garbled})" if c.first_garbled else ""
        kinds = [f"{c.garbled} garbled"]  # as the summary counts them
        kinds += [
            f"{n} {what}" for n, what in ((c.partial, "partial"), (c.too_long, "over-long")) if n
        ]
        return (
            f"{self.settings.port}: no valid sample: {', '.join(kinds)} line(s){first}; check "
            "--format, --robot and --baud"
        )

    def handle_line(self, raw: bytes, arrival: float) -> Estimate | None:
        """Process one line from the device; return its estimate, if it made one.
        Once :attr:`fatal` is set, lines are ignored."""
        if self.fatal is not None:
            return None
        c = self.counts
        c.lines += 1
        self._unended_since = None  # a line end came
        try:
            text = raw.decode("ascii")
        except UnicodeDecodeError:
            self._bad(NOT_ASCII, arrival, shown=repr(bytes(raw[:SHOWN_CHARS])), kind="not ASCII")
            return None
        try:
            sample = parse_line(
                text, self.settings.fmt, self.n_imus, self.n_tensions, self._raw_limits
            )
        except GarbledLine as exc:
            if self._garbage_since is None:  # the first garbled line of a run
                self._degrees_run = exc.degrees_for_radians and self._continues(text)
            self._bad(str(exc), arrival, text, kind=exc.kind, degrees=exc.degrees_for_radians)
            if self._degrees_run and exc.degrees_for_radians:
                self._degree_lines += 1
                self._stop_on_degrees(str(exc))
            return None
        joined, self._joined = self._joined, False
        if sample is None:
            if text.strip().startswith("#"):
                self._comment(text.strip(), arrival)
            return None
        self._garbage_since, self._garbage_lines = None, 0
        self._check_fast_clock(sample.t_ms, arrival)
        if self.fatal is not None:
            return None
        if joined:  # the first line since the port opened: whole, or the tail of a line?
            self._held = (sample, arrival)
            return None
        if self._held is not None:
            self._release_held(sample)
            if self.fatal is not None:  # the held sample stopped the session
                return None
        if self._jumped is not None:
            self._release_jumped(sample)
            if self.fatal is not None:
                return None
        if self.clock.jumps_back(sample.t_ms):  # a restart, or one corrupted t_ms?
            self._jumped = (sample, arrival, False)
            return None
        if self.clock.jumps_ahead(sample.t_ms, arrival):  # a gap, or one corrupted t_ms?
            self._jumped = (sample, arrival, True)
            return None
        return self._handle_sample(sample, arrival)

    def _release_jumped(self, following: Sample | None) -> None:
        """The sample held for jumping back: the device's restart when ``following``
        (the next sample) follows it rather than the old clock, else an out-of-order
        sample (its ``t_ms`` corrupted; also when nothing follows). Held for jumping
        ahead: the first sample after a gap when ``following`` follows it, else out of
        order."""
        assert self._jumped is not None
        (held, arrival, ahead), self._jumped = self._jumped, None
        if ahead:
            if following is not None and self.clock.confirms_ahead(held.t_ms, following.t_ms):
                self._handle_sample(held, arrival, confirmed=True)
            else:
                self._out_of_order(
                    held,
                    self.clock.last_ms,
                    "far ahead of the time the host saw pass while the next line goes on "
                    "from the last (a corrupted t_ms), skipped"
                    if following is not None
                    else "far ahead of the time the host saw pass, and no line came after "
                    "it, skipped",
                )
            return
        if following is not None and self.clock.confirms_jump(held.t_ms, following.t_ms):
            self._handle_sample(held, arrival, confirmed=True)
        else:
            self._out_of_order(
                held,
                self.clock.last_ms,
                "far behind the last sample while the next line goes on from the last "
                "(a corrupted t_ms), skipped"
                if following is not None
                else "far behind the last sample, and no line came after it, skipped",
            )

    def _release_held(self, following: Sample | None) -> None:
        """Keep the first sample after an open when ``following`` (the next sample)
        comes within ``gap_factor`` usual periods of it (``FIRST_STEP_MAX_S`` before the
        period is known), or when nothing follows (the end); else it was the tail of a
        line cut at the open (a partial line)."""
        assert self._held is not None
        (held, arrival), self._held = self._held, None
        p = self.period()
        limit_ms = 1e3 * (self.settings.gap_factor * p if p is not None else FIRST_STEP_MAX_S)
        if following is None or 0 <= following.t_ms - held.t_ms <= limit_ms:
            self._handle_sample(held, arrival)
        else:
            self.counts.partial += 1

    def finish(self) -> None:
        """The stream ended: a first sample still waiting for the next is kept, the
        samples waiting for the tensions of the ones after them are estimated, and a
        background build of the fast MHE's IPOPT fallback is waited for."""
        if self._held is not None and self.fatal is None:
            self._release_held(None)
        if self._jumped is not None:
            if self.fatal is None:
                self._release_jumped(None)
            else:  # the session stopped: the line is counted, not estimated
                self._jumped = None
                self.counts.out_of_order += 1
        if self._tension_stream is not None:
            self._estimate_pending(self._tension_stream.end(), timed=False)
        # a stream that ended inside a run of tilt angles past the radians' range that
        # grew from its valid samples (shorter than the run that stops a session): degrees
        if (
            self.fatal is None
            and self._degrees_run
            and self._garbage_since is not None
            and self._garbage_lines >= GARBAGE_STOP_LINES
        ):
            self._stop_on_garbage()
        # the fast MHE's IPOPT fallback still being built (_prepare_fallback): waited for
        join = getattr(self.estimator.inference, "join_fallback", None)
        if join is not None:
            join()

    def _comment(self, text: str, arrival: float) -> None:
        c = self.counts
        c.comments += 1
        if "continuum_imu" in text and c.samples:  # a banner after samples: the board reset
            self.clock.expect_restart()  # (the first banner may have been missed)
        if not c.header:
            c.header = text
        self.messages.show(text, arrival)
        names = header_fields(text)
        # every declaration, a later one too (a board restarted with other firmware)
        if names is not None:
            want = line_fields(self.settings.fmt, self.n_imus, self.n_tensions)
            # the samples so far were read by the declaration in force: live's order
            kept = self._fields_match and c.samples > 0
            self._fields_match = names == want
            if names != want and names not in self._fields_seen:
                tensions = f" and {self.n_tensions} tensions" if self.n_tensions else ""
                said = (
                    f"the device names {len(names)} fields ({','.join(names)}) but "
                    f"--format {self.settings.fmt} with {self.n_imus} IMU(s){tensions} "
                    f"expects {len(want)} ({','.join(want)}); "
                    + header_hint(
                        names, self.settings.fmt, self.n_imus, self.n_tensions, self._file_tensions
                    )
                )
                if sorted(names) == sorted(want):  # every reading would be another's
                    # samples read under a declaration in live's order keep their
                    # estimates; those read under none, or another, do not
                    self.wrong_units = not kept
                    self.fatal = f"{self.settings.port}: {said}" + (
                        f" (the estimates of the {c.samples} samples up to it are kept)"
                        if kept
                        else ""
                    )
                else:
                    self.say(said)
            self._fields_seen.add(names)

    def unended_bytes(self, nbytes: int, arrival: float) -> None:
        """``nbytes`` have arrived since the last line end, more than a line may hold: a
        run of them over :data:`GARBAGE_STOP_S` s sets :attr:`fatal` (the wrong baud
        rate, or a device whose lines end otherwise: no line would ever come)."""
        if self._unended_since is None:
            self._unended_since = (arrival, nbytes)
            return
        since, first = self._unended_since
        span = arrival - since
        if span >= GARBAGE_STOP_S:
            self.fatal = (
                f"{self.settings.port}: {nbytes} bytes without a line end (LF or CR) over "
                f"{span:.1f} s ({nbytes - first} in the last {span:.1f} s): check --baud, or "
                "how the device ends its lines"
            )

    def too_long_line(self, max_bytes: int, arrival: float) -> None:
        """The reader dropped a line longer than ``max_bytes`` (no line end: the wrong
        baud rate, or not this protocol): counted, said (rate-limited) as the host's own
        note, and part of a run of garbage (:data:`GARBAGE_STOP_S`)."""
        self.counts.too_long += 1
        self._skipped += 1
        self._unended_since = None  # its end came
        self.messages.show(
            f"dropped a line longer than {max_bytes} bytes (no line end: wrong baud rate or "
            "not this protocol?)",
            arrival,
            source="",
        )
        self._garbage(arrival, f"a line longer than {max_bytes} bytes")

    def _mark_units(self) -> None:
        """Keep where the estimate sink ends as the units check is armed."""
        mark = getattr(self.out, "mark", None)
        self.units_mark = mark() if mark is not None else None
        self._degree_lines, self._samples_at_mark = 0, self.counts.samples

    def _check_clock_rate(self, t: float, arrival: float, restart: bool) -> None:
        """Set :attr:`fatal` where the device clock (``t``, s) advanced less than
        :data:`CLOCK_SLOW_FACTOR` times the arrival time over the first
        :data:`CLOCK_CHECK_S` s of its run: ``t_ms`` sent in seconds (a 50 Hz stream's
        steps of 0.02 read as 0.02 ms). A faster device clock is a feed faster than real
        time (a file replayed through a port), not a unit, up to
        :meth:`_check_fast_clock`'s microseconds."""
        if self._clock_checked:
            return
        if restart or self._clock_since is None:
            self._clock_since, self._clock_samples = (arrival, t, self.clock.last_ms), 0
            return
        self._clock_samples += 1
        since, t0, since_ms = self._clock_since
        host = arrival - since
        if host < CLOCK_CHECK_S or self._clock_samples < CLOCK_CHECK_SAMPLES:
            return
        self._clock_checked = True
        device = t - t0
        if device < CLOCK_SLOW_FACTOR * host:
            self.wrong_units = True
            cause = (
                "a clock that does not run? (the first field is the device's millis(), "
                "which must advance with every sample)"
                if self.clock.last_ms == since_ms  # one stamp, spread
                else "t_ms in seconds? (the first field is milliseconds, as millis() gives; "
                "every step reads a thousand times too short)"
            )
            self.fatal = (
                f"{self.settings.port}: the device clock advanced {1e3 * device:.3g} ms in "
                f"{host:.3g} s of arrival time: {cause}"
            )

    def _check_fast_clock(self, t_ms: float, arrival: float) -> None:
        """Set :attr:`fatal` where the lines' device clock (``t_ms``, arriving at
        ``arrival``, s) runs a thousand times as fast as they arrive: ``t_ms`` in
        microseconds (:class:`~continuum_mhe.stream.clock.MicrosecondsCheck`). Each of
        its lines lands far ahead of the last (dropped as a corrupted ``t_ms``) or
        seconds after it (a gap), so no other check sees the unit."""
        problem = self._microseconds.add(t_ms, arrival)
        if problem is not None:
            self.wrong_units = True
            self.fatal = f"{self.settings.port}: {problem}"

    def _out_of_order(
        self, s: Sample, dev_prev: float | None, why: str, fills_slot: bool = True
    ) -> None:
        """Count the sample ``s`` as out of order (after one with device time
        ``dev_prev``, ms), said for the first with ``why``; ``fills_slot``: it was a
        sample of its own (a corrupted t_ms), not a repeated or late line, so that a
        gap it leaves is not a missing sample."""
        c = self.counts
        self._skipped += fills_slot
        if c.out_of_order == 0 and dev_prev is not None:
            self.say(
                f"a line with t_ms {time_text(s.t_ms)} after one with t_ms "
                f"{time_text(dev_prev)}: out of order, {why} (said for the first only; "
                "all are counted)"
            )
        c.out_of_order += 1

    def _handle_sample(self, s: Sample, arrival: float, confirmed: bool = False) -> Estimate | None:
        """Estimate the sample ``s`` (arrived at ``arrival``, monotonic s), placed on the
        device clock's axis (``confirmed``: a jump ahead or back that the next sample
        confirmed)."""
        c = self.counts
        if s.problems:
            if c.imu_dropouts == 0:
                self.say(
                    f"a line with unreadable values of one IMU ({s.problems[0]}): read as a "
                    "dropout of that IMU, the others kept (said for the first only; all are "
                    "counted)"
                )
            c.imu_dropouts += len(s.problems)
        t_prev = self.clock.t_last
        dev_prev = self.clock.last_ms
        p = self.period()
        placed = self.clock.place(s.t_ms, arrival, p, confirmed)
        t = placed.t
        if placed.event == "out-of-order":
            self._out_of_order(
                s,
                dev_prev,
                "far ahead of the time the host saw pass (a corrupted t_ms?), skipped"
                if dev_prev is not None and s.t_ms > dev_prev
                else "not after the last sample (a repeated, late or stray line), skipped",
                fills_slot=dev_prev is not None and s.t_ms > dev_prev,
            )
            return None
        given = None
        if self.tension_file is not None:
            outside = self.tension_file.coverage_problem(t, self.settings.port, stream=True)
            if outside:
                self.fatal = outside
                return None  # neither recorded nor estimated: the session stops
            first = float(self.tension_file.t[0])
            if c.samples == 0 and t - first > TENSIONS_LATE_START_S:
                self.say(
                    f"the stream starts at t = {time_text(t)} s (the device clock), "
                    f"{time_text(t - first)} s after the first row of "
                    f"{self.tension_file.name} (t = {time_text(first)} s): if that file "
                    "starts with the stream, its t is on another clock, and every tension "
                    "is taken from another time"
                )
            given = self.tension_file.at(t)
        elif self.tendon is not None and not self.n_tensions:  # a backbone, no tendons
            given = (np.zeros(0),) * 3
        elif self.tendon is not None:  # tensions on the line: in N, as a file's
            problem = tension_scale_problem(
                self.tendon.robot,
                np.array([t]),
                np.asarray(s.tensions, dtype=float)[None, :],
                f"{self.settings.port}: the tensions on the line",
            )
            if problem is not None:
                self.fatal = problem
                return None  # neither recorded nor estimated: the session stops
            if not self._span_buckling:  # the first, as a file's check says it
                self._span_buckling = span_buckling_problem(
                    self.tendon.robot,
                    np.array([t]),
                    np.asarray(s.tensions, dtype=float)[None, :],
                    f"{self.settings.port}: the tensions on the line",
                )
        c.samples += 1
        if self.converters is None:  # tilt: where a run of degrees would continue from
            self._last_tilt = np.array(s.values[: 2 * self.n_imus], dtype=float)
        self._check_clock_rate(t, arrival, placed.event == "restart")
        if placed.event == "restart" and self.fatal is None:
            # a board reset: it may run other firmware now, so the units are checked again
            # (a gyro the estimate ignores was warned about once: enough); tilt angles
            # in degrees count from here
            if self.converters is not None:
                self._units_unchecked = []
            self._mark_units()
        if self._units_unchecked is not None:
            if not self._units_unchecked:
                self._units_since = t
                self._units_times = []
            self._units_unchecked.append(s.values)
            self._units_times.append(t)
            if (
                len(self._units_unchecked) >= UNIT_CHECK_SAMPLES
                and t - self._units_since >= UNIT_CHECK_SPAN_S
            ):
                self.check_units()
                if self.fatal is not None:
                    return None  # neither recorded nor estimated: the session stops
        restart = by_gap = False
        if placed.event == "wrap":
            c.clock_wraps += 1
            self.say(
                f"device clock wrapped (millis() at 2^32 ms: {dev_prev:.0f} -> {s.t_ms:.0f}); "
                f"time goes on at t={t:.3f} s"
            )
        elif placed.event == "restart":
            c.clock_restarts += 1
            restart = True
            assert t_prev is not None  # a restart steps back from a sample
            gap_reset = self.estimator.recovery.gap_reset
            # a silence longer than the estimator's gap reset (as its policy decides it,
            # the times' rounding allowed) is a gap in t, at which the estimator restarts
            # itself, as estimate's does on the recording: the same restart
            by_gap = gap_reset is not None and longer(t - t_prev, gap_reset, t)
            if by_gap:
                self._count_restart(t)
            else:
                self._replay_differs(
                    t,
                    f"the clock restart after {t - t_prev:.3f} s of silence, not a gap longer "
                    f"than --gap-reset ({gap_reset or 0:g} s)",
                )
            self.say(
                f"device clock restarted ({dev_prev:.0f} ms -> {s.t_ms:.0f} ms); continuing at "
                f"t={t:.3f} s, estimator restarts"
            )
        elif t_prev is not None:
            dt = t - t_prev
            if p is not None and dt > self.settings.gap_factor * p:
                # the lines that came and were skipped are not missing
                lost = max(int(round(dt / p)) - 1 - self._skipped, 0)
                skipped = f", {self._skipped} line(s) in it skipped" if self._skipped else ""
                c.gaps += 1
                c.missing += lost
                gap_reset = self.estimator.recovery.gap_reset
                # decided as the estimator's policy decides its gap reset (the times'
                # rounding allowed), so that the two restart together
                long_gap = gap_reset is not None and longer(dt, gap_reset, t)
                how = (
                    "estimator restarts"
                    if long_gap
                    else "predicting across it (a restart if the readings after it lie far "
                    "beyond the prediction: --glitch)"
                )
                if long_gap:  # the estimator restarts itself (status reset); so do the
                    for conv in self.converters or ():  # attitude filters of raw IMUs
                        conv.reset()
                # to the millisecond, or two digits under one (a sub-millisecond period's)
                gap = f"{dt:.3f}" if dt >= 1e-3 else f"{dt:.2g}"
                self.say(
                    f"gap of {gap} s before t={t:.3f} s (about {lost} samples missing"
                    f"{skipped}); {how}"
                )
            else:
                self._periods.append(dt)
                self._period = None
        self._skipped = 0
        if self.record is not None:
            # "": a dropout, as estimate reads
            cells = (csv_cell(float(v)) if math.isfinite(v) else "" for v in s.values)
            tensions = (csv_cell(float(v)) for v in s.tensions)
            self.record.write_row([csv_cell(t), *cells, *tensions])
        if self.record_only:  # abandoned: recorded as received, not estimated
            return None
        if restart:  # the estimator restarts when this sample is estimated
            for conv in self.converters or ():
                conv.reset()
        restart_here = restart and not by_gap  # a gap's restart is the estimator's own
        self._pending.append(
            _Pending(t, self._measurement(t, s.values), restart_here, arrival, given)
        )
        if self._tension_stream is None:
            return self._estimate_pending([None])
        return self._estimate_pending(self._tension_stream.push(t, s.tensions))

    def _estimate_pending(
        self, ready: Sequence[TensionsAt | None], timed: bool = True
    ) -> Estimate | None:
        """Estimate the oldest waiting samples, one per item of ``ready``: with the
        tensions from the lines (:class:`TensionsAt`), or (None) with their own
        ``given``; the last estimate made, if any. ``timed``: their latency counts (not
        for the samples the stream's end released: they waited for it, however long
        the line was quiet)."""
        est = None
        for g in ready:
            p = self._pending.popleft()
            if g is not None:
                p = replace(p, given=(g.values, g.rates, g.accelerations))
            z = p.z if p.given is None or self.tendon is None else (
                self.tendon.measurement_row(p.z, *p.given)
            )  # fmt: skip
            if p.restart:
                self._restart(p.t, converters=False)
            try:
                est = self._estimate(p.t, z)
            except KeyboardInterrupt:  # recorded: its row, without an estimate, then stop
                self._write(Estimate(p.t, None, None, None, Status.NO_ESTIMATE, 0.0))
                raise
            self._write(est)
            if timed:
                ms = (time.monotonic() - p.arrival) * 1e3
                self.latency.add(ms)
                self.latency_max_window = max(self.latency_max_window, ms)
        return est

    def check_units(self) -> None:
        """Check the units of the raw samples so far, once (later calls do nothing,
        until a board reset re-arms the check), with ``estimate``'s rules and wording
        for a raw file, naming the port: an accelerometer whose median magnitude is
        about 1 is in g and sets :attr:`fatal` (``estimate`` refuses the recording);
        a gyro whose median rate exceeds ``GYRO_MEDIAN_MAX`` (5 rad/s), or whose rates
        turn the accelerometer's gravity direction as deg/s would
        (``gyro_gravity_problem``), looks like deg/s, and sets :attr:`fatal` where the
        estimate uses it, else warns (``UnitWarning``) that it is ignored."""
        seen, self._units_unchecked = self._units_unchecked, None
        if not seen or self.converters is None:
            return
        values = np.asarray(seen, dtype=float).reshape(len(seen), -1)
        times = np.asarray(self._units_times, dtype=float)
        used = self.converters[0].settings.needs_gyro
        gyro = used or not self._unused_gyro_checked
        self._unused_gyro_checked = True
        port = self.settings.port
        try:
            for i in range(self.n_imus):
                label = port if self.n_imus == 1 else f"{port}: IMU {i + 1}"
                block = values[:, 6 * i : 6 * i + 6]
                full = np.isfinite(block).all(axis=1)  # an IMU's dropouts left out
                block = block[full]
                check_accel_units(label, block[:, :3])
                if gyro:
                    check_gyro_units(label, block[:, 3:], used, times[full], block[:, :3])
        except InputError as exc:
            self.fatal = str(exc)
            self.wrong_units = True

    def _measurement(self, t: float, values: FloatArray) -> FloatArray:
        if self.converters is None:
            return np.asarray(values, dtype=float)
        return np.concatenate(
            [
                conv.convert(t, values[6 * i : 6 * i + 3], values[6 * i + 3 : 6 * i + 6])
                for i, conv in enumerate(self.converters)
            ]
        )

    def _restart(self, t: float, converters: bool = True, keep_sensors: bool = True) -> None:
        """Restart the estimator at the sample at ``t`` s (and the raw converters, unless
        they were restarted when that sample arrived), keeping what it knew of the
        sensors unless not ``keep_sensors`` (after an estimator failure)."""
        self._count_restart(t)
        for conv in (self.converters or ()) if converters else ():
            conv.reset()
        # the same session: its freezes said once
        self.estimator.reset(keep_counts=True, keep_sensors=keep_sensors)
        self._restarted = True  # the next estimate says so (status reset)

    def _count_restart(self, t: float) -> None:
        """Count a restart of the estimator at ``t`` s (the summary's, the first time
        kept)."""
        c = self.counts
        c.restarts += 1
        if c.first_restart_t is None:
            c.first_restart_t = t

    def _replay_differs(self, t: float, why: str) -> None:
        """Live restarts the estimator at ``t`` s where ``estimate`` on the recording
        does not (said in the summary, the first only)."""
        c = self.counts
        if c.replay_differs_t is None:
            c.replay_differs_t, c.replay_differs_why = t, why

    def _say_freezes(self, before: int) -> None:
        """Say once (one line) which sensors the estimator began to treat as frozen."""
        note = self.estimator.freezes_notice(before)
        if note:
            self.say(note)

    def _estimate(self, t: float, z: FloatArray) -> Estimate:
        """One estimator step that never ends the session: an exception or a non-finite
        estimate restarts the estimator and flags the sample ``no-estimate``."""
        start = time.perf_counter()
        freezes = len(self.estimator.diagnostics.first_freezes)
        self.twist_evidence.add(t, z)
        try:
            est = self.estimator.step(Measurement(t, z))
            self._say_freezes(freezes)
            problem = None
            if est.output is not None and not np.all(np.isfinite(est.output)):
                problem = "a non-finite estimate"
        except (ReadingUnitsError, MountingError) as exc:  # every later reading alike: stop
            port = self.settings.port
            self.fatal = str(exc) if str(exc).startswith(f"{port}: ") else f"{port}: {exc}"
            if isinstance(exc, MountingError):
                self.wrong_mounting = True
            else:
                self.wrong_units = True
            self.counts.estimator_failures += 1
            return Estimate(t, None, None, None, Status.NO_ESTIMATE, 0.0)
        except Exception as exc:  # any failure of one window: flag, restart, go on
            _reraise_interrupt(exc)
            problem = f"{type(exc).__name__}: {exc}"
        if problem is None:
            if self.force.active and est.output is not None:
                self.force.add(np.asarray(z, dtype=float)[None], np.asarray(est.output)[None])
            if self._restarted and est.state is not None:
                self._restarted = False
                # restarted where the time base broke: the start's row says reset, as
                # the policy's own restarts' rows do whatever else they would say
                est = replace(est, status=Status.RESET)
            self._prepare_fallback()
            return est
        self.counts.estimator_failures += 1
        self._replay_differs(t, "an estimator failure")
        self.messages.show(
            f"estimator failed ({problem}); sample flagged, estimator restarts",
            time.monotonic(),
            source="",
        )
        self._restart(t, keep_sensors=False)  # the failure may have come from them
        solve_ms = (time.perf_counter() - start) * 1e3
        return Estimate(t, None, None, None, Status.NO_ESTIMATE, solve_ms)

    def _prepare_fallback(self) -> None:
        """Have the fast MHE's IPOPT fallback built in the background
        (:meth:`~continuum_mhe.estimators.mhe.MovingHorizonInference.prepare_fallback`)
        from the second estimate on, where the window's objective scale (set by the
        sample period) is known, and again once the window is full (no second build
        where the scale is the same): a first uncertified window then does not hold the
        stream for the seconds the build takes."""
        if self._fallback_prepared:
            return
        inference = self.estimator.inference
        prepare = getattr(inference, "prepare_fallback", None)
        horizon = getattr(getattr(inference, "settings", None), "horizon", None)
        if prepare is None or horizon is None:
            self._fallback_prepared = True
            return
        self._estimated += 1
        if self._estimated in (2, horizon):
            prepare()
        self._fallback_prepared = self._estimated >= horizon

    def _write(self, est: Estimate) -> None:
        self.counts.estimates += 1
        self.last = est
        self.status_counts[str(est.status)] += 1
        if est.outlier and est.status == "inconsistent":
            self.rejected_inconsistent += 1  # the robust cost rejected its reading
        self.solve_ms.append(est.solve_ms)
        if self.on_estimate is not None:
            self.on_estimate(est)
        if self.gains.active and est.output is not None and est.output_std is not None:
            self.gains.add(np.asarray(est.output)[None], np.asarray(est.output_std)[None])
        if self.twist.active and est.output is not None:
            self.twist.add(np.asarray(est.output)[None])
        if self.beyond.active and est.output is not None:
            self.beyond.add(np.asarray(est.output)[None])
        if est.output_std is not None:
            self.wide.add(np.asarray(est.output_std)[None], [str(est.status)])
        if self.out is None:
            return
        ny = self.formulation.ny
        flag = est.outlier if self.flags_outliers else None
        row = estimate_row(est.t, est.output, est.status, est.solve_ms, ny, est.output_std, flag)
        self.out.write_row([format_number(v) if isinstance(v, float) else str(v) for v in row])

    def _describe(self, est: Estimate) -> str:
        outputs = self.formulation.outputs
        names = [o.name for o in outputs]
        v = dict(zip(names, est.output if est.output is not None else ()))
        tip = ",".join(f"{v[k] * 1e3:.0f}" for k in TIP_COLUMNS if k in v)
        angles = " ".join(
            f"{o.name}={math.degrees(v[o.name]):.1f}" for o in outputs if o.unit == "rad"
        )
        force = ",".join(f"{v[k]:.3f}" for k in TIP_FORCE_COLUMNS if k in v)
        force = f" tip force=({force}) N" if force else ""
        return f"t={est.t:.2f} s tip=({tip}) mm {angles} deg{force} [{est.status}]"

    def status(
        self,
        rate_hz: float,
        behind_s: float,
        queued: int,
        waiting: bool = False,
        silent_s: float = 0.0,
    ) -> str:
        """The status line: the rate of lines (``rate_hz``), the solve times, the last
        estimate, the counts, and how far behind real time (``behind_s``, ``queued``
        lines). Where no line has arrived for :data:`SILENT_S` or more (``silent_s``; or
        while ``waiting`` for the device), the last estimate is said to be that old: it
        says nothing of the robot now."""
        c = self.counts
        parts = ["WAITING for the device" if waiting else f"{rate_hz:5.1f} Hz"]
        if self.solve_ms:
            ms = np.asarray(self.solve_ms)
            parts.append(
                f"solve {np.median(ms):.1f} ms (max {ms.max():.1f}), line to estimate max "
                f"{self.latency_max_window:.1f} ms"
            )
        self.latency_max_window = 0.0
        if self.last is not None and self.last.output is not None:
            last = self._describe(self.last)
            if waiting or silent_s >= SILENT_S:
                last = f"no line for {silent_s:.1f} s, the last estimate from then: {last}"
            parts.append(last)
        elif silent_s >= SILENT_S:
            parts.append(f"no line for {silent_s:.1f} s")
        parts.append(
            f"estimates {c.estimates}, lines skipped {c.garbled + c.partial + c.too_long} "
            "(garbled, partial or over-long), "
            f"out-of-order {c.out_of_order}, gaps {c.gaps} (~{c.missing} missing)"
        )
        if behind_s > self.settings.behind_s:
            parts.append(f"BEHIND real time by {behind_s:.1f} s ({queued} lines queued)")
        return ", ".join(parts)

    def _replay_note(self) -> str:
        """How ``estimate`` on the recording compares with this run, given live's
        restarts of the estimator. A clock restart after a silence longer than
        ``--gap-reset`` is a gap in the recording, where ``estimate`` restarts at the
        same sample with the same estimates, statuses and standard deviations (both keep
        the readings' consistency average and the model error learned)."""
        c = self.counts
        if c.replay_differs_t is None:
            return (
                "'estimate' on the recording restarts at the same sample(s) (a gap longer "
                "than --gap-reset) with the same estimates, statuses and standard deviations"
            )
        return (
            f"'estimate' on the recording does not restart at t={c.replay_differs_t:.3f} s "
            f"({c.replay_differs_why}), so its estimates match this run's only before that "
            "time"
        )

    def _not_shown(self) -> str:
        """The device messages' repeats not shown, for the summary, or ""."""
        hidden = self.messages.not_shown()
        return (
            f" ({hidden} repeated within {self.settings.repeat_every_s:g} s not shown)"
            if hidden
            else ""
        )

    def summary(self) -> str:
        c = self.counts
        msg = (
            f"{c.samples} samples, {c.estimates} estimates; {c.garbled} garbled, "
            f"{c.imu_dropouts} unreadable IMU reading(s) on kept lines, "
            f"{c.partial} partial and {c.too_long} over-long line(s), {c.out_of_order} out of "
            f"order, {c.gaps} gap(s) (~{c.missing} samples missing), {c.disconnects} "
            f"disconnect(s), {c.comments} device message(s){self._not_shown()}, "
            f"{c.clock_restarts} clock "
            f"restart(s), {c.clock_wraps} clock wrap(s), {c.estimator_failures} estimator "
            f"failure(s)"
        )
        if self.status_counts:  # as estimate's summary gives them
            msg += "; statuses: " + ", ".join(
                f"{k}: {v}" for k, v in sorted(self.status_counts.items())
            )
        if free_note := free_of_load_clause(self.estimator.inference, c.estimates):
            msg += f"; {free_note}"  # as estimate's summary says it
        if self.latency.n:
            msg += (
                f"; latency from line received to estimate written: median "
                f"{self.latency.text(0.5)}, p99 {self.latency.text(0.99)}"
            )
        if c.reasons:
            msg += "; garbled: " + ", ".join(f"{k} x{v}" for k, v in c.reasons.items())
        # the readings' own notes (not of the estimates)
        if clip_note := clip_notice(self.converters or ()):  # as estimate's warning
            msg += "; warning: " + clip_note
        if self._span_buckling:  # as a tensions file's warning
            msg += "; warning: " + self._span_buckling
        if self._tension_stream is not None and self._tension_stream.glitches:
            msg += (
                f"; replaced {self._tension_stream.glitches} tension glitch(es) (a tension "
                "off the curve through the samples around alone)"
            )
        if self.discarded is not None and self.discard_from == (0, 0):
            # no estimate is kept, and why is said: what the estimates showed is moot
            return msg + f"; the estimates' own warnings left out (every one {self.discarded})"
        if gain_note := self.gains.notice():
            msg += "; warning: " + gain_note
        if twist_note := self.twist.notice():
            msg += "; warning: " + twist_note
        if beyond_note := self.beyond.notice(c.estimates):
            msg += "; warning: " + beyond_note
        if force_note := self.force.notice():
            msg += "; warning: " + force_note
        if wide_note := self.wide.notice(c.estimates):
            msg += "; note: " + wide_note
        for clause in recovery_clauses(
            self.estimator.diagnostics, self.estimator.recovery, c.estimates
        ):  # as estimate's summary says them
            msg += f"; {clause}"
        diag = self.estimator.diagnostics
        restarts = diag.restarts + diag.bad_starts + diag.reject_resets  # as estimate counts
        inconsistent = self.status_counts.get("inconsistent", 0) - self.rejected_inconsistent
        inconsistent_note = inconsistent_notice(inconsistent, c.estimates, self.formulation)
        if restarts_note := restarts_notice(
            c.estimates, restarts, diag.last_failure, inconsistent_note is not None
        ):
            msg += "; warning: " + restarts_note
        if chains := self.estimator.diagnostics.bad_start_chains:
            msg += (
                f"; warning: stopped restarting {chains} time(s) after "
                f"{self.formulation.bad_start_chain} restarts in a row that the readings "
                "contradicted too: the model does not fit them (check the robot file and "
                "the inputs)"
            )
        drifted = self.status_counts.get("drifted", 0)
        if drift_note := drifted_notice(drifted, c.estimates, self.formulation):
            msg += "; warning: " + drift_note
        if load_note := untrusted_start_notice(
            self.estimator.diagnostics, c.estimates, bool(self.formulation.robot.tendons)
        ):
            msg += "; warning: " + load_note
        if inconsistent_note is not None:
            msg += "; warning: " + inconsistent_note
        if hint := twist_hint(
            self.twist_evidence.evidence(),
            gyro_biases_calibrated(self.formulation.robot),
            inconsistent_note is not None,
        ):
            msg += "; warning: " + hint
        if self.record is not None and c.first_restart_t is not None:
            msg += (
                f"; live restarted the estimator {c.restarts} time(s), first at "
                f"t={c.first_restart_t:.3f} s: {self._replay_note()}"
            )
        return msg
