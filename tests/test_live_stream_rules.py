"""Live mode keeps every sample it can: the first line after a replug, samples faster
than the millisecond stamps, the good IMUs of a line with one bad field, the lines still
in the port at the end; and it stops on a stream of garbage with the cause. Each test
names the defect it guards against."""

from __future__ import annotations

import io
import math
import queue
import time
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.errors import InputError
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.csv_files import read_measurements
from continuum_mhe.live.run import run_live
from continuum_mhe.live.session import GARBAGE_STOP_S, LiveSession, LiveSettings
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.settings import NoiseSettings
from continuum_mhe.stream.clock import DeviceClock
from continuum_mhe.stream.reader import Event, SerialReader
from continuum_mhe.stream.recording import RowFile

REPRO = Path(__file__).parent / "data" / "repro"


def _session(
    n_imus: int = 1, record: RowFile | None = None, port: str = "x"
) -> tuple[LiveSession, list[str]]:
    said: list[str] = []
    robot = Robot(
        tuple(Section(0.2 / n_imus) for _ in range(n_imus)),
        tuple(ImuPlacement(k) for k in range(n_imus)),
    )
    est = make_estimator("ekf", make_formulation("bend", robot, NoiseSettings()))
    settings = LiveSettings(port=port, fmt="tilt")
    return LiveSession(settings, est, None, io.StringIO(), said.append, record), said


# --- 2 kHz with whole-millisecond stamps ---------------------------------------------------
def test_2_khz_with_whole_millisecond_stamps_keeps_the_samples() -> None:
    """millis() at 2 kHz gives pairs of equal t_ms: the second of each pair is a sample,
    not 'out of order' (which would lose half of them). The target is at least 99 %:
    all 8,000 are estimated, 0.5 ms apart."""
    s, _ = _session()
    start = time.monotonic()
    for i in range(8000):  # sample i taken at i * 0.5 ms, stamped with whole ms
        s.handle_line(f"{i // 2},0.1,0.05".encode(), start + i * 5e-4)
    s.finish()
    assert s.counts.out_of_order == 0 and s.counts.gaps == 0
    assert s.counts.estimates == 8000  # 100 %
    assert s.clock.t_last == pytest.approx(3.9995, abs=1e-9)  # 0.5 ms apart, to the end


@pytest.mark.parametrize(
    ("period", "gap", "steps"),
    [(0.02, 0.0200153, 1), (0.02, 0.3004, 15), (0.02, 0.0071, 1), (5e-4, 2e-4, 1), (5e-4, 6e-4, 1)],
)
def test_a_restarted_clock_goes_on_in_whole_samples(period: float, gap: float, steps: int) -> None:
    """A device clock that restarts (back to 3 ms) goes on from the last sample by the
    host's gap between their lines rounded to whole sample periods (at least one, at
    50 Hz and at 2 kHz alike): the
    axis keeps the device's grid (8.0 s stays 8.0 s, within a tensions file ending
    there), where the host's gap as measured put every later sample microseconds off
    it."""
    clock = DeviceClock()
    n = round(5.0 / period)  # 5 s of samples: the step back is a restart, not a late line
    for i in range(n):
        clock.place(1e3 * period * i, period * i, period)
    last = clock.t_last
    placed = clock.place(3.0, period * (n - 1) + gap, period)
    assert placed.event == "restart"
    assert placed.t == pytest.approx(last + steps * period, abs=1e-12)
    later = clock.place(3.0 + 1e3 * period * 150, period * (n - 1) + gap + 150 * period, period)
    assert later.t == pytest.approx(last + steps * period + 150 * period, abs=1e-12)


def test_samples_sharing_a_stamp_are_spread_over_its_millisecond() -> None:
    clock = DeviceClock()
    stamps = [0, 0, 1, 1, 2, 2, 2, 3, 3, 3, 4]
    t_ms = [1e3 * clock.place(ms, 0.0, None).t for ms in stamps]
    # 0.5 ms apart while two share a stamp; the third of one stamp goes between the
    # second and the next millisecond; then a third apart, as the previous stamp had 3
    np.testing.assert_allclose(
        t_ms, [0, 0.5, 1, 1.5, 2, 2.5, 2 + 2 / 3, 3, 3 + 1 / 3, 3 + 2 / 3, 4], atol=1e-9
    )
    assert np.all(np.diff(t_ms) > 0)


def test_samples_of_a_stamp_repeated_many_times_are_written_apart() -> None:
    """A device clock at a Unix time in ms that repeats one stamp 40 times at 1 kHz (a
    clock stuck for a while): each sample after the first of the stamp is placed at
    least 2 us after the one before (the spread over the millisecond, k / (k + 1) ms,
    would put the 32nd and later ones under a microsecond apart), so that an estimate
    file, which keeps times to the microsecond, writes each at its own time."""
    from continuum_mhe.io.estimate_csv import format_time

    clock = DeviceClock()
    base = 1_700_000_000_000
    stamps = [base] * 40 + [base + 1 + i for i in range(5)]
    placed = [clock.place(ms, 1e-3 * i, 1e-3).t for i, ms in enumerate(stamps)]
    steps = np.diff(placed)
    assert np.all(steps[:39] >= 2e-6 - 1e-7), steps[:39].min()
    written = [format_time(t) for t in placed]
    assert len(set(written)) == len(written)
    assert placed[1] - placed[0] == pytest.approx(0.5e-3, abs=1e-6)  # the spread's


def test_a_repeated_stamp_at_a_slow_rate_is_still_out_of_order() -> None:
    """At 100 Hz an equal stamp is a line sent twice, not a faster sample."""
    s, _ = _session()
    now = time.monotonic()
    for i, ms in enumerate([0, 10, 20, 30, 40, 40, 50]):
        s.handle_line(f"{ms},0.1,0.05".encode(), now + 0.01 * i)
    assert (s.counts.samples, s.counts.out_of_order) == (6, 1)


# --- the clock reset and wrap reproducer ------------------------------------------------
def test_live_clock_reset_reproducer() -> None:
    """tests/data/repro/live_clock_reset.py.txt: a device clock restarting at 0 after
    10 s, and millis() wrapping at 2^32 ms; every later sample is estimated, none
    dropped as out of order. Its scenario, with the EKF."""
    assert "reset = list(range(0, 10000, 10))" in (REPRO / "live_clock_reset.py.txt").read_text()
    for stamps in (
        list(range(0, 10000, 10)) + list(range(0, 5000, 10)),
        [(2**32 - 3000 + 10 * i) % 2**32 for i in range(800)],
    ):
        s, _ = _session()
        now = time.monotonic()
        for i, ms in enumerate(stamps):
            s.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
        s.finish()
        assert (s.counts.estimates, s.counts.out_of_order) == (len(stamps), 0)


# --- a two-IMU line with one bad field ---------------------------------------------------
def test_a_bad_field_of_one_imu_keeps_the_other_imu(tmp_path: Path) -> None:
    """A line with one IMU's field unreadable keeps the other IMU's reading: a dropout
    of that IMU, said once, recorded so that it replays; a line with no good IMU is
    garbled."""
    record = RowFile(tmp_path / "rec.csv", ["t", "roll_1", "pitch_1", "roll_2", "pitch_2"], False)
    s, said = _session(n_imus=2, record=record)
    now = time.monotonic()
    for i in range(20):
        bad = "abc" if i == 10 else "0.2"
        s.handle_line(f"{10 * i},0.1,0.05,{bad},0.1".encode(), now + 0.01 * i)
    s.finish()
    record.close()
    assert (s.counts.samples, s.counts.garbled, s.counts.imu_dropouts) == (20, 0, 1)
    assert [m for m in said if "unreadable" in m] == [
        "a line with unreadable values of one IMU (IMU 2: non-numeric field): read as a "
        "dropout of that IMU, the others kept (said for the first only; all are counted)"
    ]
    table = read_measurements(tmp_path / "rec.csv", n_imus=2)  # the recording replays
    assert len(table.t) == 20
    np.testing.assert_allclose(table.z[10, :2], [0.1, 0.05])
    assert np.isnan(table.z[10, 2:]).all() and np.isfinite(np.delete(table.z, 10, 0)).all()
    s.handle_line(b"300,abc,0.05,0.2,inf", now + 1.0)  # no good IMU: garbled
    assert (s.counts.samples, s.counts.garbled) == (20, 1)


# --- garbage ------------------------------------------------------------------------------
def test_a_stream_of_garbage_stops_the_session_with_the_cause() -> None:
    """A stream of nothing but garbled lines stops live after GARBAGE_STOP_S (not at the
    end of --duration, or never), with the cause."""
    s, _ = _session(port="/dev/ttyIMU")
    now = time.monotonic()
    for i in range(1000):  # 100 Hz of lines with one field too many
        s.handle_line(f"{10 * i},0.1,0.05,7".encode(), now + 0.01 * i)
        if s.fatal is not None:
            break
    assert GARBAGE_STOP_S / 0.01 <= i <= GARBAGE_STOP_S / 0.01 + 2  # stopped 3 s in
    assert s.fatal is not None
    assert s.fatal.startswith("/dev/ttyIMU: nothing but garbled lines for 3.0 s (30")
    assert s.fatal.endswith(
        "lines; the last: expected 3 fields, found 4); check --format, --robot and --baud"
    )
    s.handle_line(b"5000,0.1,0.1", now + 20)  # nothing is handled after
    assert s.counts.samples == 0


def test_valid_samples_between_garbled_lines_keep_the_session_going() -> None:
    s, _ = _session()
    now = time.monotonic()
    for i in range(1000):
        line = f"{10 * i},0.1,0.05" if i % 10 == 0 else f"{10 * i},0.1"
        s.handle_line(line.encode(), now + 0.01 * i)
    assert s.fatal is None and s.counts.samples == 100


class _Port:
    """A serial port stand-in: ``data`` arrives ``per_read`` bytes at a time, then
    reads time out (b'')."""

    def __init__(self, data: bytes, per_read: int = 1 << 16, forever: bytes = b"") -> None:
        self.data, self.per_read, self.forever = bytearray(data), per_read, forever

    @property
    def in_waiting(self) -> int:
        if not self.data and self.forever:
            self.data += self.forever
        return len(self.data)

    def read(self, n: int) -> bytes:
        if not self.data and not self.forever:
            time.sleep(0.01)  # a read timing out
        n = min(n, self.per_read, self.in_waiting)
        chunk = bytes(self.data[:n])
        del self.data[:n]
        return chunk

    def close(self) -> None:
        pass


def test_live_on_a_garbled_port_stops_with_the_cause_before_its_duration(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A port that sends garbage as fast as it is read (its stop after
    ``GARBAGE_STOP_S`` of arrival time is checked above; here half a second of it)."""
    monkeypatch.setattr("continuum_mhe.live.session.GARBAGE_STOP_S", 0.5)
    s, said = _session(port="/dev/ttyIMU")
    settings = LiveSettings(port="/dev/ttyIMU", fmt="tilt", duration=600.0)
    port = _Port(b"", forever=b"\x01\x02garbage;;\n" * 20)
    cause = r"^/dev/ttyIMU: nothing but garbled lines for \d+\.\d s \("
    with pytest.raises(InputError, match=cause):  # not the duration's normal end
        run_live(settings, s, port)
    assert not [m for m in said if m.startswith("device says")]


def test_the_hosts_own_notes_are_not_said_as_the_devices() -> None:
    """The host's own notes ('dropped a line longer than 4096 bytes') are said as the
    host's, without 'device says:', which only the device's messages get."""
    s, said = _session()
    s.too_long_line(4096, time.monotonic())
    assert said == [
        "dropped a line longer than 4096 bytes (no line end: wrong baud rate or not this protocol?)"
    ]
    s.handle_line(b"# error: I2C read failed, IMU 1", time.monotonic())
    assert said[-1] == "device says: # error: I2C read failed, IMU 1"


# --- the lines still in the port when live stops ---------------------------------------------
def test_lines_still_in_the_port_at_the_end_are_estimated() -> None:
    """Lines still in the port when the reader is told to stop are read and handed on:
    a busy machine can leave some of the samples sent before --duration ends there."""
    lines = b"".join(f"{10 * i},0.1,0.05\n".encode() for i in range(200))
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader("x", 115200, _Port(lines), events, 1.0)
    reader.stop.set()  # told to stop before it read anything: a starved thread
    reader.run()
    got = [payload for kind, payload, _ in list(events.queue) if kind == "line"]
    assert len(got) == 200 and got[-1] == b"1990,0.1,0.05"


def test_a_defect_met_while_draining_the_port_at_the_end_is_not_swallowed(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The lines read from the port after the reader is told to stop go through the
    same splitter: a defect there ends the reader with the ``failed`` event, as in the
    main loop (only the port's own errors end the draining quietly)."""
    monkeypatch.setattr(
        "continuum_mhe.stream.reader.LineSplitter", lambda max_bytes: _BrokenSplitter()
    )
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader("x", 115200, _Port(b"0,0.1,0.05\n"), events, 1.0)
    reader.stop.set()
    reader.run()
    kind, payload, _ = list(events.queue)[-1]
    assert kind == "failed" and str(payload) == "a defect in the splitter"


def test_each_new_reason_a_lost_port_does_not_reopen_for_is_one_event(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """While a lost port is retried, each change of the reason it does not open for
    (gone while unplugged, which says nothing new, then no permission after the replug)
    is one ``retrying`` event, then ``back``."""
    failures = [FileNotFoundError("no such device")] * 3 + [PermissionError("denied")] * 2
    events: queue.Queue[Event] = queue.Queue()
    reader = SerialReader("x", 115200, _Port(b""), events, 0.001)

    def open_port(port: str, baud: int) -> _Port:
        if failures:
            raise failures.pop(0)
        reader.stop.set()  # back: end the test's reader after this
        return _Port(b"")

    monkeypatch.setattr("continuum_mhe.stream.reader.open_port", open_port)
    reader._reopen()
    got = [(kind, payload) for kind, payload, _ in list(events.queue)]
    assert got[:1] == [("retrying", "denied")] and [k for k, _ in got] == ["retrying", "back"]
    failures[:] = [PermissionError("busy")] * 3  # a first reason that is not "gone": said
    reader.stop.clear()
    events.queue.clear()
    reader._reopen()
    assert [(k, p) for k, p, _ in list(events.queue)][:1] == [("retrying", "busy")]


def test_run_live_estimates_every_line_sent_before_the_end() -> None:
    s, _ = _session()
    lines = b"".join(f"{10 * i},0.1,0.05\n".encode() for i in range(400))
    settings = LiveSettings(port="x", fmt="tilt", duration=0.3)
    assert run_live(settings, s, _Port(lines, per_read=64)) == 0  # slow reads: 64 bytes
    assert (s.counts.samples, s.counts.estimates) == (400, 400)
    assert math.isclose(s.clock.t_last or 0.0, 3.99)


class _BrokenSplitter:
    """A line splitter with a defect: its feed raises on the first chunk."""

    max_bytes = 4096
    too_long: list[int] = []

    def feed(self, chunk: bytes) -> list[bytes]:
        raise ValueError("a defect in the splitter")

    def pending(self) -> bytes:
        return b""


def test_a_reader_that_fails_stops_live_with_the_cause_instead_of_waiting(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An unexpected exception in the reader thread does not leave live, without
    --duration, waiting for lines for ever: the reader's last event carries the
    exception; live says the summary and raises it (the command line's one line for a
    bug, exit 70), the estimates so far kept."""
    s, said = _session(port="/dev/ttyIMU")
    settings = LiveSettings(port="/dev/ttyIMU", fmt="tilt", duration=None)
    monkeypatch.setattr(
        "continuum_mhe.stream.reader.LineSplitter", lambda max_bytes: _BrokenSplitter()
    )
    done: queue.Queue[BaseException | int] = queue.Queue()

    def run() -> None:
        try:
            done.put(run_live(settings, s, _Port(b"0,0.1,0.05\n")))
        except BaseException as exc:  # noqa: BLE001 - handed to the test's thread
            done.put(exc)

    import threading

    threading.Thread(target=run, daemon=True).start()
    got = done.get(timeout=60)
    assert isinstance(got, ValueError), got
    assert str(got) == "a defect in the splitter"
    assert any(m.startswith("0 samples") for m in said), said


def test_a_device_time_far_ahead_of_real_time_is_out_of_order() -> None:
    """One line's t_ms corrupted 1e15 ms ahead is dropped as out of order (not kept as a
    sample, which would move the axis by 1e12 s and count the next real line as a device
    restart), and the stream goes on without a gap or a restart; the line is said as
    far ahead, with every digit of its stamp."""
    s, said = _session()
    now = time.monotonic()
    stamps = [10 * i for i in range(200)]
    stamps[100] += 10**15
    for i, ms in enumerate(stamps):
        s.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
    s.finish()
    assert (s.counts.estimates, s.counts.out_of_order, s.counts.gaps) == (199, 1, 0)
    assert s.clock.t_last == pytest.approx(1.99, abs=1e-9)
    told = [m for m in said if "out of order" in m]
    assert len(told) == 1 and told[0].startswith(
        "a line with t_ms 1000000000001000 after one with t_ms 990: out of order, far "
        "ahead of the time the host saw pass while the next line goes on from the last (a "
        "corrupted t_ms), skipped"
    ), told


@pytest.mark.parametrize("ahead_ms", [80_000, 31_000])
def test_a_device_time_seconds_ahead_of_real_time_is_out_of_order(ahead_ms: int) -> None:
    """One line's t_ms corrupted 80 s (or 31 s) ahead, 10 ms of host time after the last:
    no gap, no restart, the axis where it was; one line out of order."""
    s, _ = _session()
    now = time.monotonic()
    stamps = [10 * i for i in range(200)]
    stamps[100] += ahead_ms
    for i, ms in enumerate(stamps):
        s.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
    s.finish()
    c = s.counts
    assert (c.estimates, c.out_of_order, c.gaps, c.clock_restarts) == (199, 1, 0, 0)
    assert s.clock.t_last == pytest.approx(1.99, abs=1e-9)


def test_a_jump_ahead_that_the_next_line_confirms_is_a_gap() -> None:
    """Two lines left in the port from a session that ended 20 minutes earlier, then the
    device's live lines: the first live line, far ahead, is held until the next confirms
    the jump (not every later line dropped), then estimated, and the stream goes on
    after a gap: no line is lost. A jump that the next line does not confirm (one
    corrupted t_ms) is that line alone (the tests above)."""
    s, said = _session()
    now = time.monotonic()
    stamps = [1000, 1010, *(1_201_000 + 10 * i for i in range(300))]
    for i, ms in enumerate(stamps):
        s.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
    s.finish()
    assert (s.counts.estimates, s.counts.out_of_order) == (302, 0), said
    assert s.clock.t_last == pytest.approx(1_203_990 / 1e3, abs=1e-9)  # the device's time
