"""What a live session counts and shows besides its estimates: the running counts of
lines, samples and problems (:class:`LiveCounts`), the device's own messages, each
text at most once per interval (:class:`DeviceMessages`), and the latencies in constant
memory (:class:`LatencyHistogram`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class LiveCounts:
    """Running counts of a live session (reported in the status line and at the end)."""

    lines: int = 0
    samples: int = 0
    estimates: int = 0
    comments: int = 0
    garbled: int = 0
    imu_dropouts: int = 0  # IMU readings unreadable on a line whose other IMUs' were kept
    partial: int = 0
    too_long: int = 0
    out_of_order: int = 0
    gaps: int = 0
    missing: int = 0  # samples the gaps are estimated to have lost on the device side
    disconnects: int = 0
    clock_restarts: int = 0
    clock_wraps: int = 0
    estimator_failures: int = 0  # exceptions and non-finite estimates: flagged, restarted
    restarts: int = 0  # times live restarted the estimator (clock restart, failure)
    first_restart_t: float | None = None
    # the first restart that 'estimate' on the recording does not make, and why
    replay_differs_t: float | None = None
    replay_differs_why: str = ""
    header: str = ""
    reasons: dict[str, int] = field(default_factory=dict)
    first_garbled: str | None = None  # why the first garbled line was, with a likely cause


class DeviceMessages:
    """Shows every device ``#`` line, the same text at most once per ``every`` s (with
    the count of repeats not shown)."""

    def __init__(self, say: Any, every: float) -> None:
        self.say, self.every = say, every
        self._shown: dict[str, tuple[float, int]] = {}  # text -> (last shown, hidden since)
        self._own: set[str] = set()  # the texts that are the host's own notes

    def show(self, text: str, now: float, source: str = "device says: ") -> None:
        """Say ``source`` and ``text`` (``source=""``: a note of the host's own, such as
        an estimator failure, rate-limited the same way and not counted as the
        device's)."""
        if not source:
            self._own.add(text)
        last, hidden = self._shown.get(text, (-math.inf, 0))
        if now - last < self.every:
            self._shown[text] = (last, hidden + 1)
            return
        more = f" (and {hidden} more time(s) since)" if hidden else ""
        self.say(f"{source}{text}{more}")
        if len(self._shown) > 1000:  # a device that never repeats itself: forget the oldest
            self._own.discard(oldest := next(iter(self._shown)))
            self._shown.pop(oldest)
        self._shown[text] = (now, 0)

    def not_shown(self) -> int:
        """The device messages' repeats hidden since they were last shown (none said
        yet): the summary counts them (the host's own notes apart)."""
        return sum(h for text, (_, h) in self._shown.items() if text not in self._own)


class LatencyHistogram:
    """Latencies (ms) in log-spaced bins (2.3 % wide), so memory stays constant."""

    EDGES = np.geomspace(1e-3, 1e5, 801)

    def __init__(self) -> None:
        self.counts = np.zeros(len(self.EDGES) + 1, dtype=np.int64)
        self.n = 0

    def add(self, ms: float) -> None:
        self.counts[int(np.searchsorted(self.EDGES, ms))] += 1
        self.n += 1

    def quantile(self, q: float) -> float:
        """The ``q`` quantile, ms (upper edge of its bin); inf beyond the last edge
        (:meth:`text` says so); NaN when empty."""
        if self.n == 0:
            return math.nan
        i = int(np.searchsorted(np.cumsum(self.counts), q * self.n))
        return math.inf if i >= len(self.EDGES) else float(self.EDGES[i])

    def text(self, q: float) -> str:
        """The ``q`` quantile as the summary says it: ``12.34 ms``, or ``over 100000 ms``
        beyond the last edge."""
        v = self.quantile(q)
        return f"over {self.EDGES[-1]:.0f} ms" if math.isinf(v) else f"{v:.2f} ms"
