"""The device clock: ``millis()`` on the wire, one strictly increasing time axis out.

* A wrap of ``millis()`` (every 2^32 ms, 49.7 days) is unwrapped exactly: the time
  axis goes on as if the counter were wider, and the estimator need not restart.
* A restart (the reset button, or a board that resets when the port reopens) is a
  backwards jump of more than ``restart_jump_s``, or any backwards step once
  :meth:`DeviceClock.expect_restart` was called. The time base is broken there: the
  axis continues after the wall-clock time the device was silent, and the caller
  restarts the estimator. A caller that can hold a sample asks :meth:`jumps_back`
  first (also a step back of more than :data:`HELD_BACK_S` to under half the last
  time: a board reset within its clock's first second steps back by less than
  ``restart_jump_s``) and keeps such a
  sample until the next one says whether the device restarted (:meth:`confirms_jump`:
  it follows the held one, within :data:`CONFIRM_MS`, instead of the old clock; placed
  with ``confirmed``) or the held one's ``t_ms`` was corrupted (an out-of-order sample).
* A smaller backwards step is an out-of-order sample, dropped by the caller, and so is
  a step forward of more than :data:`FORWARD_JUMP_S` beyond the time the host saw pass
  since the last sample (a corrupted ``t_ms`` would move the whole axis and make the
  next sample look like a restart), unless the next sample confirms it (within
  :data:`CONFIRM_MS` after it: lines left in the port from an earlier run, or a
  host that was suspended): the axis then jumps with the device's time, a gap. A
  caller that can hold a sample asks :meth:`jumps_ahead` first and keeps such a sample
  until the next one says whether it was the jump's first (:meth:`confirms_ahead`; it
  is then placed with ``confirmed``) or a corrupted ``t_ms``; a caller that does not
  hold loses the jump's first sample. A single corrupted ``t_ms``, ahead or behind, is
  so one out-of-order sample, and the axis goes on with the samples after it.
* Samples that share a whole-millisecond stamp (a device faster than 1 kHz stamping
  with ``millis()``: 2 kHz gives pairs of equal ``t_ms``) are spread evenly over that
  millisecond, by the number of samples the previous stamp had: the protocol carries
  no finer time, so such a sample's time is known to within 1 ms. This holds while the
  usual period is under :data:`SUB_MS_PERIOD_S` (or not known yet); at slower rates an
  equal stamp is a repeated line, out of order.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass
from typing import Literal

from continuum_mhe.io.sample_rows import MILLIS_WRAP, millis_wrapped

#: A device time further ahead of the last one than the host's time since then plus
#: this, s, is not (yet) a sample's: the device's clock and the host's advance alike
#: between two lines, less the lines' difference in delay on the way, a fraction of a
#: second (a host that was suspended, whose clock stood still meanwhile, has its first
#: line back dropped and the next confirms the jump).
FORWARD_JUMP_S = 2.0
#: A sample this soon after one dropped for jumping ahead or behind (ms of device time)
#: confirms that jump.
CONFIRM_MS = 10_000.0
#: A step back of more than this (s), to a device time under half the last one, is held
#: by a caller that can hold (:meth:`DeviceClock.jumps_back`) until the next sample says
#: whether the device restarted: a reset within the first second of its clock steps
#: back by less than ``restart_jump_s``, to a clock that starts again near zero; a line
#: sent again, late or corrupted lands nearer the last one.
HELD_BACK_S = 0.05

#: Equal stamps are samples of one millisecond while the usual period is below this, s.
SUB_MS_PERIOD_S = 1.5e-3
#: The least step (s) between samples that share a stamp: estimate files keep times to
#: the microsecond, so two samples closer than that would be written as one time.
REPEAT_MIN_STEP_S = 2e-6

ClockEvent = Literal["first", "next", "wrap", "restart", "out-of-order"]


@dataclass(frozen=True)
class Placed:
    """A device time placed on the axis: ``t`` in s and what happened."""

    t: float
    event: ClockEvent


class DeviceClock:
    """Maps device times (ms) to one strictly increasing axis (s).

    Attributes:
        restart_jump_s: a backwards jump longer than this (s) is a restart.
    """

    def __init__(self, restart_jump_s: float = 1.0) -> None:
        self.restart_jump_s = restart_jump_s
        self._epoch_ms = 0.0  # 2^32 ms per wrap seen
        self._offset_s = 0.0  # added after a restart
        self._last_ms: float | None = None  # device time of the last accepted sample
        self._t_last: float | None = None  # axis time of the last accepted sample, s
        self._arrival_last = 0.0
        self._restart_armed = False
        self._repeat = 0  # samples before this one with the same stamp
        self._per_stamp = 1  # samples the previous stamp had
        self._ahead_ms: float | None = None  # the last device time dropped as far ahead

    @property
    def t_last(self) -> float | None:
        """Axis time of the last accepted sample, s."""
        return self._t_last

    @property
    def last_ms(self) -> float | None:
        """Device time of the last accepted sample, ms."""
        return self._last_ms

    def expect_restart(self) -> None:
        """The device reconnected or printed its banner again: its next backwards step,
        however small, is a restart."""
        self._restart_armed = True

    def jumps_back(self, t_ms: float) -> bool:
        """Whether the device time ``t_ms`` (ms) steps back as a restart that no
        reconnect or banner announced would, which the next sample may confirm
        (:meth:`confirms_jump`; then placed with ``confirmed``): a jump back of more than
        ``restart_jump_s``, or of more than :data:`HELD_BACK_S` to under half the last
        device time (a clock that starts again); not a wrap."""
        last = self._last_ms
        if last is None or t_ms >= last or self._restart_armed:
            return False
        if millis_wrapped(last, t_ms):
            return False
        back = last - t_ms
        return back > self.restart_jump_s * 1e3 or (back > HELD_BACK_S * 1e3 and t_ms < last / 2)

    def confirms_jump(self, held_ms: float, t_ms: float) -> bool:
        """Whether the device time ``t_ms`` (ms) of the sample after one held for jumping
        back (``held_ms``, :meth:`jumps_back`) follows the held one, within
        :data:`CONFIRM_MS` (the device restarted), rather than the old clock (the held
        one's ``t_ms`` was corrupted)."""
        last = self._last_ms
        follows_old = last is not None and last < t_ms <= last + CONFIRM_MS
        return 0 < t_ms - held_ms <= CONFIRM_MS and not follows_old

    def jumps_ahead(self, t_ms: float, arrival: float) -> bool:
        """Whether :meth:`place` would drop the device time ``t_ms`` (ms), arriving at
        ``arrival`` (monotonic, s), as further ahead of the last sample than the host's
        time since then plus :data:`FORWARD_JUMP_S`."""
        last = self._last_ms
        if last is None or t_ms <= last:
            return False
        return t_ms - last > 1e3 * (arrival - self._arrival_last + FORWARD_JUMP_S)

    @staticmethod
    def confirms_ahead(held_ms: float, t_ms: float) -> bool:
        """Whether the device time ``t_ms`` (ms) of the sample after one held for jumping
        ahead (``held_ms``, :meth:`jumps_ahead`) follows it within :data:`CONFIRM_MS`:
        the device's time did jump (else the held one's ``t_ms`` was corrupted)."""
        return 0 < t_ms - held_ms <= CONFIRM_MS

    def place(
        self, t_ms: float, arrival: float, period_s: float | None, confirmed: bool = False
    ) -> Placed:
        """Place one sample (device ``t_ms``, monotonic ``arrival`` in s); the usual
        ``period_s`` spaces a restarted axis. Out-of-order samples do not move the clock.
        ``confirmed``: a jump ahead that the next sample confirmed
        (:meth:`confirms_ahead`), placed as the gap it is, or back (:meth:`confirms_jump`),
        placed as the restart it is."""
        last = self._last_ms
        event: ClockEvent = "first" if last is None else "next"
        if last is not None and t_ms < last:
            if millis_wrapped(last, t_ms):
                self._epoch_ms += MILLIS_WRAP
                event = "wrap"
            elif self._restart_armed or confirmed or last - t_ms > self.restart_jump_s * 1e3:
                assert self._t_last is not None
                away = max(arrival - self._arrival_last, period_s or 1e-3)
                if period_s:  # the host's gap to whole samples: the axis keeps its grid
                    away = max(1, round(away / period_s)) * period_s
                self._offset_s = self._t_last + away - (t_ms + self._epoch_ms) / 1e3
                event = "restart"
            else:
                return Placed((t_ms + self._epoch_ms) / 1e3 + self._offset_s, "out-of-order")
        elif (
            not confirmed
            and last is not None
            and t_ms - last > 1e3 * (arrival - self._arrival_last + FORWARD_JUMP_S)
        ):
            ahead, self._ahead_ms = self._ahead_ms, t_ms
            if ahead is None or not 0 < t_ms - ahead <= CONFIRM_MS:  # not (yet) confirmed
                return Placed((t_ms + self._epoch_ms) / 1e3 + self._offset_s, "out-of-order")
        t = (t_ms + self._epoch_ms) / 1e3 + self._offset_s
        repeat = 0
        if event == "next" and t_ms == last and (period_s is None or period_s < SUB_MS_PERIOD_S):
            repeat = self._repeat + 1  # within the millisecond the stamp names
            t += 1e-3 * repeat / max(self._per_stamp, repeat + 1)
            if self._t_last is not None:  # more than the last stamp had: ever closer
                t = max(t, self._t_last + REPEAT_MIN_STEP_S)
        if self._t_last is not None and t <= self._t_last:
            return Placed(t, "out-of-order")
        if repeat == 0:
            self._per_stamp = self._repeat + 1
        self._repeat = repeat
        self._restart_armed = False
        self._ahead_ms = None
        self._last_ms, self._t_last, self._arrival_last = t_ms, t, arrival
        return Placed(t, event)


#: A device clock whose lines advance this many times as fast as they arrive (the
#: median step of the lines over at least :data:`FAST_CLOCK_WINDOW_S` s of arrival and
#: :data:`FAST_CLOCK_LINES` lines), in steps of :data:`FAST_CLOCK_MIN_STEP_MS` or more,
#: sends microseconds as ``t_ms`` (``micros()`` of a device at up to 500 Hz). A file
#: replayed faster than real time can arrive that much faster too, but its steps are the
#: recording's (milliseconds apart, not seconds); a replay of a recording slower than
#: 0.5 Hz at hundreds of lines a second would read as one.
FAST_CLOCK_FACTORS = (300.0, 3000.0)
FAST_CLOCK_WINDOW_S = 0.2
FAST_CLOCK_LINES = 10
FAST_CLOCK_MIN_STEP_MS = 2000.0
#: The most recent lines :class:`MicrosecondsCheck` keeps (its window is that many
#: lines where they arrive faster than the window's time: at 500 Hz, 0.25 s).
FAST_CLOCK_KEPT = 128


class MicrosecondsCheck:
    """Whether a device sends microseconds as ``t_ms``: its lines' device times advance
    :data:`FAST_CLOCK_FACTORS` times as fast as they arrive. A step back (a restart, a
    wrap, a stray line) starts the count again; the median step keeps one corrupted line
    from moving it."""

    def __init__(self) -> None:
        self._lines: deque[tuple[float, float]] = deque(maxlen=FAST_CLOCK_KEPT)

    def add(self, t_ms: float, arrival: float) -> str | None:
        """Take one line's device time ``t_ms`` (ms as sent), arrived at ``arrival``
        (monotonic, s): the problem in words once the lines show microseconds, else
        None."""
        lines = self._lines
        if lines and t_ms <= lines[-1][0]:
            lines.clear()
        lines.append((t_ms, arrival))
        while len(lines) > FAST_CLOCK_LINES and arrival - lines[1][1] >= FAST_CLOCK_WINDOW_S:
            lines.popleft()
        host = arrival - lines[0][1]
        if len(lines) < FAST_CLOCK_LINES or host < FAST_CLOCK_WINDOW_S:
            return None
        if lines[-1][0] - lines[-2][0] < FAST_CLOCK_MIN_STEP_MS:  # a usual line: no median
            return None
        step = statistics.median(b[0] - a[0] for a, b in zip(lines, list(lines)[1:]))
        factor = step * (len(lines) - 1) / (1e3 * host)
        low, high = FAST_CLOCK_FACTORS
        if not (step >= FAST_CLOCK_MIN_STEP_MS and low <= factor <= high):
            return None
        return (
            f"the device clock advanced {factor:.0f} times as fast as the lines arrived over "
            f"the last {len(lines)} lines (steps of {step:g} ms in t_ms): t_ms in "
            "microseconds? (the first field is milliseconds, as millis() gives; "
            "micros() / 1000.0 keeps the decimals)"
        )
