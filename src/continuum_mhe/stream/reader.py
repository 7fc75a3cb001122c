"""The serial port: opening it (with a one-line hint when that fails) and a reader
thread that drains it into a queue of whole lines, reopening a lost device."""

from __future__ import annotations

import errno
import glob
import math
import os
import queue
import sys
import threading
import time
from typing import Any

from continuum_mhe.extras import require
from continuum_mhe.stream.protocol import MAX_LINE_BYTES, LineSplitter

Event = tuple[str, Any, float]  # (kind, payload, monotonic arrival time)


def open_port(port: str, baud: int, feature: str = "live on a serial port") -> Any:
    """Open a serial device or pyserial URL with a short read timeout; without pyserial,
    a :class:`~continuum_mhe.extras.MissingExtraError` naming ``feature``. On POSIX the
    device is locked for this process alone (pyserial's ``exclusive``): a second
    reader of one port would take some of its lines, leaving both streams garbled."""
    serial = require("serial", "robot", feature, package="pyserial")
    exclusive = True if os.name == "posix" else None
    return serial.serial_for_url(port, baudrate=baud, timeout=0.05, exclusive=exclusive)


def port_hint(
    port: str,
    exc: BaseException,
    recording: str = "a recording is estimated with continuum-mhe estimate FILE",
) -> str:
    """One line: why ``port`` did not open, the likely causes, the ports present;
    ``recording`` says what to run where ``port`` is a file or folder (a recording)."""
    present = sorted(
        p for pat in ("/dev/ttyACM*", "/dev/ttyUSB*", "/dev/cu.usb*") for p in glob.glob(pat)
    )
    text = str(exc).replace("\n", " ")
    if os.path.isfile(port) or os.path.isdir(port):  # a recording's path, not a device
        kind = "a folder" if os.path.isdir(port) else "a regular file"
        return (
            f"{port}: {kind}, not a serial device: give the device (Linux /dev/ttyACM0, "
            f"macOS /dev/cu.usbmodem*); {recording}"
        )
    if isinstance(exc, PermissionError) or "Permission denied" in text:
        causes = (
            "no permission: on Linux add yourself to the dialout group "
            "(sudo usermod -aG dialout $USER, then log in again)"
        )
    elif "busy" in text.lower() or "Resource temporarily unavailable" in text:
        causes = "the port is in use: close the Arduino IDE's Serial Monitor or other program"
    else:
        causes = (
            "is the board plugged in? Linux: /dev/ttyACM0 (a CH340 clone: /dev/ttyUSB0), "
            "dialout group; macOS: /dev/cu.usbmodem*; the Arduino IDE's Serial Monitor "
            "must not hold the port"
        )
    found = f"ports present: {', '.join(present)}" if present else "no serial ports found"
    return f"{port}: cannot open serial device ({text}); {causes}; {found}"


#: While bytes arrive with no line end, the reader says so this often at most, s.
UNENDED_EVERY_S = 0.5


class SerialReader(threading.Thread):
    """Reads the port into ``events``: ``("line", bytes, t)``, ``("too-long", nbytes,
    t)``, ``("unended", nbytes, t)`` (at most every :data:`UNENDED_EVERY_S` while a line
    too long goes on: the bytes since its start), ``("partial", bytes, t)``, ``("lost",
    reason, t)``, ``("retrying", reason, t)`` (the port does not reopen for another
    reason than before) and ``("back", seconds_away, t)``.
    Reopens with backoff. An exception it does not expect (a
    defect) closes the port and ends the thread with ``("failed", exception, t)`` as its
    last event, so that the queue's reader raises it instead of waiting for lines that
    will never come."""

    def __init__(
        self,
        port: str,
        baud: int,
        conn: Any,
        events: queue.Queue[Event],
        retry_max_s: float,
        max_line_bytes: int = MAX_LINE_BYTES,
    ) -> None:
        super().__init__(name="continuum-mhe-serial", daemon=True)
        self.port, self.baud, self.conn = port, baud, conn
        self.events = events
        self.retry_max_s = retry_max_s
        self.splitter = LineSplitter(max_line_bytes)
        self.stop = threading.Event()
        self._unended_said = -math.inf  # when the last "unended" event was put

    def run(self) -> None:
        try:
            self._read_until_stopped()
        except BaseException as exc:  # noqa: BLE001 - handed to the queue's reader, which raises it
            self._close()
            self.events.put(("failed", exc, time.monotonic()))

    def _read_until_stopped(self) -> None:
        while not self.stop.is_set():
            try:
                chunk = self.conn.read(max(1, min(self.conn.in_waiting, 1 << 16)))
            except Exception as exc:  # SerialException, OSError: the device went away
                left = self.splitter.pending()
                if left:
                    self.events.put(("partial", left, time.monotonic()))
                self.events.put(("lost", str(exc) or type(exc).__name__, time.monotonic()))
                self._close()
                self._reopen()
                continue
            if not chunk:
                continue
            self._feed(chunk)
        self._drain()
        self._close()

    def _feed(self, chunk: bytes) -> None:
        now = time.monotonic()
        for line in self.splitter.feed(chunk):
            self.events.put(("line", line, now))
        for n in self.splitter.too_long:
            self.events.put(("too-long", n, now))
        if self.splitter.unended and now - self._unended_said >= UNENDED_EVERY_S:
            self.events.put(("unended", self.splitter.unended, now))
            self._unended_said = now

    def _drain(self, limit_s: float = 1.0) -> None:
        """Read what the port holds when told to stop: lines the device sent before the
        end arrive late when this thread was slow (a busy machine), and are estimated
        too. At most ``limit_s`` s, for a device that keeps sending."""
        end = time.monotonic() + limit_s
        while time.monotonic() < end:
            try:
                waiting = self.conn.in_waiting
                chunk = self.conn.read(min(waiting, 1 << 16)) if waiting else b""
            except Exception:  # the device went away meanwhile: nothing more to read
                return
            if not chunk:
                return
            self._feed(chunk)

    def _close(self) -> None:
        try:
            self.conn.close()
        except Exception:  # noqa: S110 - closing a vanished device may fail; nothing to do
            pass

    def _reopen(self) -> None:
        """Open the port again, with backoff, until it opens or the thread is told to
        stop; each reason it does not open for (no permission after a replug, a port
        another program holds) is one ``("retrying", reason, t)`` event when it changes,
        but a first one that only says the device is gone (unplugged)."""
        lost = time.monotonic()
        delay = 0.1
        last = None  # the reason of the last failed attempt
        while not self.stop.wait(delay):
            try:
                self.conn = open_port(self.port, self.baud)
            except Exception as exc:
                reason = str(exc).replace("\n", " ") or type(exc).__name__
                gone = (
                    getattr(exc, "errno", None) == errno.ENOENT
                    or isinstance(exc, FileNotFoundError)
                    or "No such file" in reason
                    or "FileNotFoundError" in reason
                )
                if reason != last and not (last is None and gone):
                    self.events.put(("retrying", reason, time.monotonic()))
                last = reason
                delay = min(2 * delay, self.retry_max_s)
                continue
            self.splitter.resync()
            self.events.put(("back", time.monotonic() - lost, time.monotonic()))
            return


def stderr_say(prefix: str) -> Any:
    """A ``say(msg)`` that prints ``prefix: msg`` to stderr at once."""
    return lambda msg: print(f"{prefix}: {msg}", file=sys.stderr, flush=True)
