"""The parts of a live session without a port: line splitting, the device clock,
device messages, estimator failures, non-finite estimates, and the files written
row by row. Each test names the defect it guards against."""

from __future__ import annotations

import errno
import io
import math
import os
import re
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from estimator_helpers import bare

from continuum_mhe.errors import InputError
from continuum_mhe.estimators import EstimateSeries, make_estimator
from continuum_mhe.estimators.base import Estimate
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.live.session import LiveSession, LiveSettings
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import Robot
from continuum_mhe.settings import MHESettings, NoiseSettings
from continuum_mhe.stream.clock import MILLIS_WRAP
from continuum_mhe.stream.protocol import LineSplitter, header_fields
from continuum_mhe.stream.recording import RowFile, check_target


def _session(
    method: str = "ekf", out: io.StringIO | None = None, robot: Robot | None = None
) -> tuple[LiveSession, list[str]]:
    said: list[str] = []
    f = make_formulation("bend", robot or Robot.single(), NoiseSettings())
    est = make_estimator(method, f, MHESettings(horizon=10))
    s = LiveSession(LiveSettings(port="x", fmt="tilt"), est, None, out, say=said.append)
    return s, said


def _feed(s: LiveSession, t_ms: list[int]) -> None:
    now = time.monotonic()
    for i, t in enumerate(t_ms):
        s.handle_line(f"{t},0.1,0.1".encode(), now + 0.01 * i)


def test_line_splitter_accepts_lf_cr_crlf_and_drops_long_lines() -> None:
    sp = LineSplitter(max_bytes=16)
    assert sp.feed(b"a,1\nb,2\rc,3\r\nd") == [b"a,1", b"b,2", b"c,3"]
    assert sp.feed(b",4\r") == [b"d,4"]
    assert sp.feed(b"\ne,5\n") == [b"e,5"]  # the LF of a CRLF split across reads: no blank line
    # a line longer than the cap is dropped whole, however it arrives, and counted
    assert sp.feed(b"x" * 10) == []
    assert sp.feed(b"x" * 1_000_000) == [] and sp.too_long == []
    assert sp.feed(b"x\nf,6\n") == [b"f,6"] and sp.too_long == [1_000_011]
    assert sp.feed(b"g,7") == [] and sp.pending() == b"g,7"
    # the cap is the longest line kept (its line end aside), whole or in two reads
    assert sp.feed(b"1" * 16 + b"\r\n") == [b"1" * 16] and sp.too_long == []
    assert sp.feed(b"2" * 9) == [] and sp.feed(b"2" * 7 + b"\n") == [b"2" * 16]
    assert sp.feed(b"3" * 17 + b"\n") == [] and sp.too_long == [17]


def test_the_tail_of_a_line_cut_at_a_reopen_is_not_a_sample() -> None:
    """A reopened port may start mid-line (pyserial empties the buffer on open): a
    tail such as '35,0.1,...' (of '1035,...') must not pass as a sample with a tiny
    t_ms; the next sample shows it (1000 ms later, where 10 ms is usual)."""
    s, _ = _session()
    _feed(s, [1000 + 10 * i for i in range(20)])
    s.device_back()
    now = time.monotonic()
    s.handle_line(b"35,0.1,0.2", now)
    _feed(s, [1400, 1410])
    assert (s.counts.partial, s.counts.samples, s.counts.clock_restarts) == (1, 22, 0)


def test_the_first_whole_line_after_a_reopen_is_kept() -> None:
    """The first whole line after a reopen is a sample, whatever it holds: all 400
    samples are estimated across a replug; a session of one line estimates it at the end."""
    s, _ = _session()
    splitter = LineSplitter()  # as the reader thread splits the port's bytes
    now = time.monotonic()
    for t0 in (0, 2000):  # plugged in, then unplugged and plugged in again at 2 s
        splitter.resync()
        s.device_back()
        data = "".join(f"{t0 + 10 * i},0.1,0.1\n" for i in range(200)).encode()
        for line in splitter.feed(data):
            s.handle_line(line, now)
    s.finish()
    assert (s.counts.samples, s.counts.estimates, s.counts.partial) == (400, 400, 0)
    s2, _ = _session()  # the first line of a session, and a session of one line
    _feed(s2, [500])
    assert s2.counts.samples == 0
    s2.finish()
    assert (s2.counts.samples, s2.counts.estimates) == (1, 1)


def test_the_view_sees_every_estimate_the_first_after_an_open_included() -> None:
    """The ``live --view`` hook (``on_estimate``) sees every estimate written, in time
    order: the first sample after an open (estimated when the next one shows it whole)
    and one still held at the end included."""
    out = io.StringIO()
    s, _ = _session(out=out)
    seen: list[float] = []
    s.on_estimate = lambda e: seen.append(e.t)
    _feed(s, [1000 + 10 * i for i in range(5)])
    s.device_back()
    _feed(s, [2000])  # held until the end: nothing follows it
    s.finish()
    rows = [float(r.split(",")[0]) for r in out.getvalue().splitlines()[1:]]
    assert s.counts.estimates == 6 and seen == rows and rows == sorted(rows)


def test_a_status_line_after_a_silence_says_its_estimate_is_that_old() -> None:
    """A device that stops sending: the status line does not show the last estimate as
    the robot's current one (``0.0 Hz ... [ok]``); it says how long no line came and
    that the estimate is from then, and nothing of the kind while lines arrive."""
    s, _ = _session()
    _feed(s, [1000 + 10 * i for i in range(5)])
    assert "no line" not in s.status(100.0, 0.0, 0, silent_s=0.2)
    line = s.status(0.0, 0.0, 0, silent_s=2.5)
    assert "no line for 2.5 s, the last estimate from then: t=" in line
    assert "no line for 0.0 s, the last estimate from then" in s.status(0.0, 0.0, 0, True)
    empty, _ = _session()
    assert "no line for 3.0 s" in empty.status(0.0, 0.0, 0, silent_s=3.0)


def test_the_first_garbled_line_is_said_with_its_port_place_and_beginning() -> None:
    """The notice of the first garbled line named neither the port, nor where, nor
    what came: it names them (a line not in ASCII by its bytes, a long one cut), and a
    tilt in degrees names the field, its value and the unit. A line not in ASCII names
    the likely cause, another baud rate: such bytes can end lines too seldom for the run
    of garbage to stop the session, which then goes on with its first notice alone."""
    s, said = _session()
    now = time.monotonic()
    s.handle_line(b"0,0.1,0.1", now)  # the first line after the open: kept
    s.handle_line(b"\xff\xfe10,0.1,0.1", now)
    assert [m for m in said if "garbled" in m] == [
        "garbled line skipped: not ASCII (the device sending at another baud rate than "
        "--baud?) (x, line 2: b'\\xff\\xfe10,0.1,0.1'; said for the first only; all are "
        "counted)"
    ]
    assert s.counts.reasons == {"not ASCII": 1}  # the summary counts them by the cause
    s, said = _session()
    s.handle_line(b"0,0.1,0.1", now)
    s.handle_line(b"20,45.0,0.1," + b"9" * 60, now)
    (first,) = [m for m in said if "garbled" in m]
    assert first.startswith("garbled line skipped: expected 3 fields, found 4")
    assert first.endswith(f"(x, line 2: '20,45.0,0.1,{'9' * 36}...'; said for the first only; "
                          "all are counted)")  # fmt: skip
    s, said = _session()
    s.handle_line(b"0,0.1,0.1", now)
    s.handle_line(b"20,45.0,0.1", now)
    assert [m for m in said if "garbled" in m] == [
        "garbled line skipped: roll = 45, beyond pi: degrees given for radians? (x, line 2: "
        "'20,45.0,0.1'; said for the first only; all are counted)"
    ]


def test_header_fields() -> None:
    assert header_fields("# fields: t_ms,ax_1,ay_1") == ("t_ms", "ax_1", "ay_1")
    assert header_fields("# format: t_ms,ax,ay,az,gx,gy,gz (ms, m/s^2, rad/s)") == (
        "t_ms",
        "ax",
        "ay",
        "az",
        "gx",
        "gy",
        "gz",
    )
    assert header_fields("# error: I2C read failed") is None


def test_device_clock_restart_gives_estimates_and_says_so() -> None:
    """A device clock restart (a reset button press) keeps the samples after it: every
    one estimated, none 'out of order'; one restart, said once."""
    s, said = _session()
    reset = list(range(0, 10000, 10)) + list(range(0, 5000, 10))
    _feed(s, reset)
    assert (s.counts.estimates, s.counts.out_of_order) == (len(reset), 0)
    assert s.counts.clock_restarts == 1 and s.counts.restarts == 1
    assert sum("device clock restarted (9990 ms -> 0 ms)" in m for m in said) == 1


@pytest.mark.parametrize(
    ("t_ms", "arrival_step", "slow"),
    [
        ([0.02 * i for i in range(200)], 0.0200034, True),  # seconds sent as t_ms, in real
        # time (a host clock's steps, not round numbers)
        ([20 * i for i in range(200)], 0.02, False),  # milliseconds, in real time
        ([20 * i for i in range(200)], 0.0005, False),  # a file replayed 40 times faster
    ],
)
def test_a_device_clock_in_seconds_stops_the_session(
    t_ms: list[float], arrival_step: float, slow: bool
) -> None:
    """A device that sends seconds as ``t_ms`` (0.02 a line at 50 Hz): its clock
    advances 2 ms in 2 s of arrival, which stops the session in one line (the steps are
    not read a thousand times too short; its estimates are not kept); milliseconds, or a
    replay faster than real time, go on without a word."""
    s, said = _session()
    now = time.monotonic()
    for i, t in enumerate(t_ms):
        s.handle_line(f"{t:g},0.1,0.1".encode(), now + arrival_step * i)
    assert not [m for m in said if "t_ms in seconds?" in m], said
    if slow:  # the times as a user reads them (three digits, not a float's repr)
        assert s.fatal is not None and s.wrong_units, said
        assert re.match(
            r"x: the device clock advanced \d\.?\d{0,2} ms in \d\.?\d{0,2} s of .*t_ms in "
            r"seconds\?",
            s.fatal,
        ), s.fatal
    else:
        assert s.fatal is None, s.fatal


def test_a_device_clock_that_does_not_run_stops_the_session_naming_it() -> None:
    """A device whose ``t_ms`` stays at 1500 in every line (a clock not started): the
    session stops after 2 s of arrivals, naming a clock that does not run (not seconds
    sent as milliseconds)."""
    s, said = _session()
    now = time.monotonic()
    for i in range(300):
        s.handle_line(b"1500,0.1,0.1", now + 0.02 * i)
        if s.fatal is not None:
            break
    assert s.fatal is not None and "a clock that does not run?" in s.fatal, (s.fatal, said)
    assert "t_ms in seconds?" not in s.fatal


@pytest.mark.parametrize(
    ("step_ms", "arrival_step", "lines", "fast"),
    [
        (20_000, 0.02, 200, True),  # micros() at 50 Hz: every line far ahead, dropped
        (10_000, 0.01, 200, True),  # at 100 Hz: every line a gap of 10 s, kept
        (2_000, 0.002, 400, True),  # at 500 Hz
        (20, 0.02, 200, False),  # milliseconds in real time
        (20, 0.0005, 200, False),  # a file replayed 40 times faster
        (20, 2e-5, 12_000, False),  # 50 Hz lines written into a pseudo-terminal at once
        (1_000, 1 / 420, 200, False),  # a 1 Hz recording replayed through a 115200-baud port
    ],
)
def test_a_device_clock_in_microseconds_stops_the_session(
    step_ms: int, arrival_step: float, lines: int, fast: bool
) -> None:
    """A device that sends ``micros()`` as ``t_ms``: its clock advances a thousand times
    as fast as its lines arrive, which stops the session in one line naming microseconds
    (its estimates not kept), where each line was dropped as a corrupted ``t_ms`` or
    taken as a gap; milliseconds, or lines faster than real time, do not."""
    s, said = _session()
    now = time.monotonic()
    for i in range(lines):
        s.handle_line(f"{1500 + step_ms * i},0.1,0.1".encode(), now + arrival_step * i)
        if s.fatal is not None:
            break
    if fast:
        assert s.fatal is not None and "t_ms in microseconds?" in s.fatal, (s.fatal, said)
        assert s.wrong_units and s.discarded == "made from readings in the wrong units"
        assert i < 0.3 / arrival_step  # within a third of a second of arrivals
    else:
        assert s.fatal is None, s.fatal


def test_a_banner_after_samples_is_a_board_reset_even_without_a_first_banner() -> None:
    """A board that streamed before live saw its banner, then reset: the banner after
    samples arms the restart, so its clock stepping back by less than a second (2,500
    to 1,700 ms) is a restart, said once, and no sample after it is dropped as out of
    order (not 80 of them, without a word)."""
    s, said = _session()
    before, after = list(range(1000, 2510, 10)), list(range(1700, 3000, 10))
    _feed(s, before)
    s.handle_line(b"# continuum_imu 1.1.0 mpu9250 imus=1 rate_hz=100", time.monotonic())
    _feed(s, after)
    assert s.counts.out_of_order == 0 and s.counts.clock_restarts == 1
    assert s.counts.estimates == len(before) + len(after)
    assert sum("device clock restarted (2500 ms -> 1700 ms)" in m for m in said) == 1


def _restart_with_record(tmp_path: Path, silence_s: float) -> tuple[LiveSession, Path, str]:
    """A tilt session recording to a file: 3 s of samples, then the device clock
    restarts at 0 after ``silence_s`` s of silence (arrival time), and 1 s more."""
    out = io.StringIO()
    s, _ = _session(out=out)
    rec = tmp_path / "raw.csv"
    s.record = RowFile(rec, ("t", "roll_1", "pitch_1"), overwrite=False)
    now = time.monotonic()
    for i in range(300):
        s.handle_line(f"{10 * i},{0.1 + 0.002 * i},0.1".encode(), now + 0.01 * i)
    for i in range(100):
        s.handle_line(f"{10 * i},{0.7 - 0.002 * i},0.1".encode(), now + 2.99 + silence_s + 0.01 * i)
    s.record.close()
    return s, rec, out.getvalue()


def _replayed(rec: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``estimate``'s run (the compiled batch) on the recording, with the session's
    estimator settings."""
    series = _replay_series(rec)
    return series.t, series.output, series.status


def _replay_series(rec: Path) -> EstimateSeries:
    data = np.loadtxt(rec, delimiter=",", skiprows=1)
    f = make_formulation("bend", Robot.single(), NoiseSettings())
    return make_estimator("ekf", f, MHESettings(horizon=10)).run(data[:, 0], data[:, 1:])


def test_summary_after_a_clock_restart_in_a_long_silence_says_the_replay_restarts_too(
    tmp_path: Path,
) -> None:
    """A clock restart after a silence longer than --gap-reset is a gap in the recording
    too: estimate restarts at the same sample with the same estimates, and the summary
    says so (not that the replay matches only before the restart)."""
    s, rec, out = _restart_with_record(tmp_path, silence_s=2.0)
    assert s.counts.restarts == 1
    rows = [r.split(",") for r in out.splitlines()[1:]]
    t, output, status = _replayed(rec)
    np.testing.assert_allclose(t, [float(r[0]) for r in rows], rtol=0, atol=1e-6)
    ny = output.shape[1]
    np.testing.assert_allclose(output, [[float(v) for v in r[1 : 1 + ny]] for r in rows], atol=1e-6)
    assert status[300] == rows[300][-2] == "reset"
    summary = s.summary()
    assert "'estimate' on the recording restarts at the same sample(s)" in summary
    assert "with the same estimates, statuses and standard deviations" in summary
    assert "does not" not in summary


def test_a_clock_restart_keeps_the_model_error_learned_as_the_replays_gap_does(
    tmp_path: Path,
) -> None:
    """Readings that scatter far beyond their noise model (the model error the
    consistency check learns and widens the standard deviations by), then a device clock
    restart after a silence longer than --gap-reset: live keeps what it learned, as the
    replay's gap restart does, so every row's standard deviations and status equal the
    replay's after the restart too."""
    out = io.StringIO()
    s, _ = _session(out=out)
    rec = tmp_path / "raw.csv"
    s.record = RowFile(rec, ("t", "roll_1", "pitch_1"), overwrite=False)
    rng = np.random.default_rng(4)
    scatter = np.radians(6.0) * rng.standard_normal((400, 2))  # R says 2 degrees
    now = time.monotonic()
    for i in range(400):
        t_ms, arrival = (10 * i, 0.01 * i) if i < 300 else (10 * (i - 300), 5.0 + 0.01 * i)
        roll, pitch = 0.3 + scatter[i, 0], 0.2 + scatter[i, 1]
        s.handle_line(f"{t_ms},{roll:.6f},{pitch:.6f}".encode(), now + arrival)
    s.record.close()
    assert s.counts.restarts == 1
    rows = [r.split(",") for r in out.getvalue().splitlines()[1:]]
    header = out.getvalue().splitlines()[0].split(",")
    std = [j for j, name in enumerate(header) if name.startswith("std_")]
    series = _replay_series(rec)
    live_std = np.array([[float(r[j]) for j in std] for r in rows])
    np.testing.assert_allclose(live_std, series.output_std, rtol=1e-6, atol=1e-9)
    assert [r[-2] for r in rows] == [str(v) for v in series.status]


def test_summary_after_a_clock_restart_in_a_short_silence_says_where_the_replay_differs(
    tmp_path: Path,
) -> None:
    """A board that restarts within --gap-reset leaves no long gap in the recording:
    estimate goes on across it where live restarted, and the summary says so."""
    s, rec, out = _restart_with_record(tmp_path, silence_s=0.3)
    t, _, status = _replayed(rec)
    assert status[300] == "ok" and out.splitlines()[301].split(",")[-2] == "reset"
    assert (
        f"'estimate' on the recording does not restart at t={t[300]:.3f} s (the clock "
        "restart after 0.300 s of silence, not a gap longer than --gap-reset (1 s)), so its "
        "estimates match this run's only before that time"
    ) in s.summary()


def test_device_clock_wrap_goes_on_seamlessly() -> None:
    """Samples after the device's millis() counter wraps are estimated, not rejected as
    'out of order': one 10 ms step across the wrap, no restart, the wrap said once."""
    out = io.StringIO()
    s, said = _session(out=out)
    wrap = [(MILLIS_WRAP - 3000 + 10 * i) % MILLIS_WRAP for i in range(800)]
    _feed(s, wrap)
    assert (s.counts.estimates, s.counts.out_of_order, s.counts.clock_wraps) == (800, 0, 1)
    assert s.counts.restarts == 0  # the time base is intact: no restart needed
    t = np.array([float(r.split(",")[0]) for r in out.getvalue().splitlines()[1:]])
    np.testing.assert_allclose(np.diff(t), 0.01, atol=1e-6)  # one step of 10 ms across the wrap
    assert sum("wrapped" in m for m in said) == 1


@pytest.mark.parametrize("glitch", [1660, 24660])  # a digit lost; the first digit off by one
def test_one_corrupted_t_ms_is_one_out_of_order_line_and_the_time_axis_goes_on(
    glitch: int,
) -> None:
    """A single line whose t_ms is corrupted (jumping 13 s back, or 10 s ahead) between
    lines that go on from the old clock: that line is skipped and counted, no restart
    and no gap, and every other sample is at its device time (the axis is not moved)."""
    out = io.StringIO()
    s, said = _session(out=out)
    stamps = list(range(12000, 17000, 20))
    k = stamps.index(14660)
    _feed(s, [*stamps[:k], glitch, *stamps[k + 1 :]])
    s.finish()
    assert (s.counts.out_of_order, s.counts.clock_restarts, s.counts.restarts) == (1, 0, 0)
    assert s.counts.estimates == len(stamps) - 1
    t = np.array([float(r.split(",")[0]) for r in out.getvalue().splitlines()[1:]])
    want = np.array([ms / 1e3 for ms in stamps if ms != 14660])
    np.testing.assert_allclose(t - t[0], want - want[0], atol=1e-9)
    assert not any("restarted" in m or "gap" in m for m in said), said


def _fed_to_the_end(stamps: list[int]) -> tuple[tuple[int, int, int], list[str]]:
    """A session fed lines at ``stamps`` (t_ms) to the stream's end: its estimates,
    out-of-order lines and clock restarts, and what it said."""
    s, said = _session()
    _feed(s, stamps)
    s.finish()
    return (s.counts.estimates, s.counts.out_of_order, s.counts.clock_restarts), said


def test_a_restart_without_a_banner_keeps_its_first_sample() -> None:
    """A board that restarts its clock with no banner: the first line after the jump is
    held until the next follows it, and then estimated as the restart's first sample."""
    stamps = list(range(0, 3000, 10)) + list(range(0, 1000, 10))
    counts, said = _fed_to_the_end(stamps)
    assert counts == (len(stamps), 0, 1)
    assert sum("device clock restarted (2990 ms -> 0 ms)" in m for m in said) == 1


def test_a_restart_within_the_clock_s_first_second_is_a_restart() -> None:
    """A board that resets 780 ms into its clock, with no banner, steps back by less
    than a second: the next line follows the held one, so it is the device's restart
    (the time axis goes on), not 0.8 s of lines out of order until the new clock passes
    the old; a line 200 ms late, the next going on from the old clock, is still one
    line out of order."""
    stamps = list(range(0, 790, 10)) + list(range(0, 2000, 10))
    counts, said = _fed_to_the_end(stamps)
    assert counts == (len(stamps), 0, 1)
    assert sum("device clock restarted (780 ms -> 0 ms)" in m for m in said) == 1
    late = [*range(0, 1000, 10), 800, *range(1000, 2000, 10)]
    assert _fed_to_the_end(late)[0] == (len(late) - 1, 1, 0)
    # lines that step back but land near the last one are no restart, whatever follows:
    # two corrupted lines in a row, the last 200 ms sent again, two lines repeated at
    # 10 Hz: each line out of order, the time axis as it was
    head = list(range(0, 1300, 10))
    for back, tail in (
        ([1100, 1110], list(range(1300, 2000, 10))),
        (list(range(1100, 1300, 10)), list(range(1300, 2000, 10))),
    ):
        assert _fed_to_the_end([*head, *back, *tail])[0] == (len(head) + len(tail), len(back), 0)
    slow = list(range(0, 2000, 100))
    assert _fed_to_the_end([*slow, 1800, 1900, *range(2000, 3000, 100)])[0] == (30, 2, 0)


def test_bytes_without_a_line_end_for_3_s_stop_the_session_in_one_line() -> None:
    """A device whose lines end otherwise (or another baud rate): the splitter tells the
    bytes of the line that never ends, and 3 s of them stop the session with the cause;
    a line end in between starts the count again."""
    sp = LineSplitter(max_bytes=100)
    assert sp.feed(b"1,0.1;" * 30) == [] and sp.unended == 180 and sp.too_long == []
    assert sp.feed(b"\n2,0.1,0.1\n") == [b"2,0.1,0.1"] and sp.too_long == [180]
    assert sp.unended == 0
    import queue

    from continuum_mhe.stream.reader import SerialReader

    events: queue.Queue = queue.Queue()
    reader = SerialReader("x", 115200, None, events, 1.0, max_line_bytes=100)
    reader._feed(b"1,0.1;" * 30)
    reader._feed(b"1,0.1;" * 30)  # within UNENDED_EVERY_S of the first: not said again
    assert [(k, n) for k, n, _ in list(events.queue)] == [("unended", 180)]
    s, _ = _session()
    s.unended_bytes(5000, 10.0)
    s.unended_bytes(9000, 12.0)
    assert s.fatal is None
    s.handle_line(b"100,0.1,0.1", 12.5)  # a line end came: the run starts again
    s.unended_bytes(4500, 13.0)
    s.unended_bytes(9000, 15.9)
    assert s.fatal is None
    s.unended_bytes(12000, 16.1)
    assert s.fatal == (
        "x: 12000 bytes without a line end (LF or CR) over 3.1 s (7500 in the last "
        "3.1 s): check --baud, or how the device ends its lines"
    )


@pytest.mark.parametrize("n_imus", [1, 2])
def test_garbled_lines_are_counted_by_cause_and_not_as_missing_samples(n_imus: int) -> None:
    """Tilt lines in degrees, each beyond pi by another value: one cause in the summary
    (not one per value), and the gap they leave between valid samples says that its
    lines came and were skipped, none missing; a line sent again and 10 lines that never
    came leave 10 missing."""
    robot = None
    if n_imus > 1:
        from continuum_mhe.model.robot import ImuPlacement, Section

        robot = Robot((Section(0.15, 3.0), Section(0.15, 3.0)), (ImuPlacement(0), ImuPlacement(1)))
    s, said = _session(robot=robot)
    now = time.monotonic()
    for i in range(60):
        # degrees-like, each its own: 19 lines, one short of what stops a session
        roll = 0.1 if not 20 <= i < 39 else 3.5 + 0.01 * i
        s.handle_line(f"{1000 + 20 * i}{f',{roll},0.1' * n_imus}".encode(), now + 0.02 * i)
    for i in (59, 59, 70):  # the last line twice more, then 10 lines lost
        s.handle_line(f"{1000 + 20 * i}{',0.1,0.1' * n_imus}".encode(), now + 0.02 * i)
    s.finish()
    cause = "roll beyond pi: degrees given for radians?"
    want = cause if n_imus == 1 else f"IMU 1: roll_1 {cause.removeprefix('roll ')}"
    assert s.counts.reasons == {want: 19}
    assert (s.counts.gaps, s.counts.missing, s.counts.out_of_order) == (2, 10, 2)
    gaps = [m for m in said if m.startswith("gap of")]
    assert "(about 0 samples missing, 19 line(s) in it skipped)" in gaps[0], gaps
    assert "(about 10 samples missing)" in gaps[1], gaps


def test_a_gap_under_a_millisecond_is_said_to_its_digits() -> None:
    """Whole seconds sent as ``t_ms`` (50 lines a stamp): the samples of a stamp are
    spread over its millisecond, ever closer, so the next stamp is a gap against that
    tiny period: its length is said to its digits (0.00099 s), not as 0.000 s; the
    clock's unit then stops the session."""
    s, said = _session()
    now = time.monotonic()
    for i in range(150):
        s.handle_line(f"{i // 50},0.1,0.1".encode(), now + 0.02 * i)
        if s.fatal:
            break
    gaps = [m for m in said if m.startswith("gap of")]
    assert gaps and gaps[0].startswith("gap of 0.00099 s before t=0.002 s"), gaps
    assert s.fatal is not None and "t_ms in seconds?" in s.fatal


def test_a_gap_of_exactly_the_gap_reset_on_an_epoch_clock_is_decided_as_the_policy_does() -> None:
    """A device clock in Unix milliseconds (t near 1.7e9 s): a gap of exactly
    ``--gap-reset`` (0.3 s, 1700000000.001 to 1700000000.301 s, which subtract to
    0.30000019 s) is no long gap to the estimator's policy (no gap reset), and live says
    ``predicting across it`` (not ``estimator restarts``, restarting the raw IMUs'
    attitude filters where the estimator goes on); a gap 1 ms longer restarts both."""
    from continuum_mhe.settings import RecoverySettings

    for gap_ms, resets, how in (
        (
            300,
            0,
            "predicting across it (a restart if the readings after it lie far beyond the "
            "prediction: --glitch)",
        ),
        (301, 1, "estimator restarts"),
    ):
        said: list[str] = []
        f = make_formulation("bend", Robot.single(), NoiseSettings())
        est = make_estimator("ekf", f, recovery=RecoverySettings(gap_reset=0.3))
        s = LiveSession(LiveSettings(port="x", fmt="tilt"), est, None, None, say=said.append)
        last = 1_700_000_000_001  # ms: the last sample before the gap
        stamps = [last - 50 * i for i in range(39, -1, -1)]
        stamps += [last + gap_ms + 50 * i for i in range(40)]
        now = time.monotonic()
        for ms in stamps:
            s.handle_line(f"{ms},0.1,0.1".encode(), now + (ms - stamps[0]) / 1e3)
        s.finish()
        assert est.diagnostics.gap_resets == resets
        t = (last + gap_ms) / 1e3
        assert [m for m in said if m.startswith("gap of")] == [
            f"gap of {gap_ms / 1e3:.3f} s before t={t:.3f} s (about 5 samples missing); {how}"
        ]


def test_a_line_held_for_jumping_back_is_settled_when_the_device_comes_back() -> None:
    """A line whose clock jumped back, then the device lost and back: the held line is
    the device's restart, estimated before the lines after the reopen (in time order,
    one restart); one held with nothing after it is counted, said as such."""
    out = io.StringIO()
    s, said = _session(out=out)
    now = time.monotonic()
    stamps = [*range(5000, 6000, 10), 100]
    for i, ms in enumerate(stamps):
        s.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
    s.device_back()
    for i, ms in enumerate((1200, 1210, 1220)):
        s.handle_line(f"{ms},0.1,0.1".encode(), now + 2 + 0.01 * i)
    s.finish()
    t = [float(r.split(",")[0]) for r in out.getvalue().splitlines()[1:]]
    assert all(b > a for a, b in zip(t, t[1:])) and len(t) == len(stamps) + 3
    assert (s.counts.clock_restarts, s.counts.out_of_order) == (1, 0)
    s2, said2 = _session()
    for i, ms in enumerate([*range(5000, 6000, 10), 100]):
        s2.handle_line(f"{ms},0.1,0.1".encode(), now + 0.01 * i)
    s2.finish()
    assert s2.counts.out_of_order == 1
    assert any("no line came after it" in m for m in said2), said2


def test_small_backward_step_is_out_of_order_not_a_restart() -> None:
    """A line stamped 15 ms after one at 30 ms is skipped and counted, and the first
    such line is said as it comes (with both stamps), the later ones only counted."""
    s, said = _session()
    _feed(s, [3600000, 3600010, 3600020, 3600030, 3600025, 3600040, 3600040, 3600050])
    assert (s.counts.estimates, s.counts.out_of_order, s.counts.clock_restarts) == (6, 2, 0)
    told = [m for m in said if "out of order" in m]
    assert told == [
        "a line with t_ms 3600025 after one with t_ms 3600030: out of order, not after the "
        "last sample (a repeated, late or stray line), skipped (said for the first only; "
        "all are counted)"
    ]


def test_device_messages_all_shown_repeats_rate_limited() -> None:
    s, said = _session()
    now = time.monotonic()
    s.handle_line(b"# continuum_imu 1.0.0", now)
    s.handle_line(b"# gyro bias rad/s: 0.01,0.02,0.03", now)
    for i in range(50):
        s.handle_line(b"# error: I2C read failed", now + 0.01 * i)
    s.handle_line(b"# error: I2C read failed", now + 10.0)
    shown = [m for m in said if m.startswith("device says:")]
    assert shown[:3] == [
        "device says: # continuum_imu 1.0.0",
        "device says: # gyro bias rad/s: 0.01,0.02,0.03",
        "device says: # error: I2C read failed",
    ]
    assert shown[3] == "device says: # error: I2C read failed (and 49 more time(s) since)"
    assert s.counts.comments == 53


def test_header_with_wrong_field_count_is_reported() -> None:
    s, said = _session()
    s.handle_line(b"# fields: t_ms,roll_1,pitch_1,roll_2,pitch_2", time.monotonic())
    assert any("names 5 fields" in m and "expects 3" in m for m in said)


def test_estimator_exception_never_ends_the_session() -> None:
    """An exception in an estimator does not end `live`: that sample is ``no-estimate``,
    the estimator restarts (its next estimate ``reset``) and the session goes on."""
    out = io.StringIO()
    s, said = _session("mhe", out)
    real_step = s.estimator.step
    calls = {"n": 0}

    def flaky(m):  # type: ignore[no-untyped-def]
        calls["n"] += 1
        if calls["n"] == 20:
            raise ValueError("Array must not contain infs or NaNs")
        return real_step(m)

    s.estimator.step = flaky  # type: ignore[method-assign]
    _feed(s, list(range(0, 400, 10)))
    rows = out.getvalue().splitlines()[1:]
    assert len(rows) == 40 and s.counts.estimates == 40
    assert rows[19].split(",")[-2] == "no-estimate" and rows[19].split(",")[1] == ""
    assert s.counts.estimator_failures == 1 and s.counts.restarts == 1
    # the restarted estimator's first estimate says so; the rest are ok
    assert rows[20].split(",")[-2] == "reset"
    assert all(r.split(",")[-2] == "ok" for r in rows[21:])
    assert any("estimator failed (ValueError: Array must not" in m for m in said)


def test_non_finite_estimate_is_never_written_as_ok() -> None:
    """The live writer never writes a non-finite estimate: its row is ``no-estimate``
    (no NaN, never ``ok``), counted as an estimator failure."""
    out = io.StringIO()
    s, _ = _session("ekf", out)
    real_step = s.estimator.step

    def nan_at_5(m):  # type: ignore[no-untyped-def]
        e = real_step(m)
        if abs(m.t - 0.05) < 1e-9:
            return Estimate(e.t, e.state, np.full_like(e.output, np.nan), None, "ok", 0.1)
        return e

    s.estimator.step = nan_at_5  # type: ignore[method-assign]
    _feed(s, list(range(0, 200, 10)))
    rows = [r.split(",") for r in out.getvalue().splitlines()[1:]]
    assert not any("nan" in c.lower() for r in rows for c in r)
    assert rows[5][-2] == "no-estimate" and s.counts.estimator_failures == 1


def test_row_file_is_created_at_the_first_row_only(tmp_path: Path) -> None:
    """-o leaves an existing file as it is until the first row arrives (a session
    without samples keeps it); each row is on disk as soon as written."""
    old = tmp_path / "est.csv"
    old.write_text("precious\n")
    f = RowFile(check_target(old, True, "-o"), ("t", "x"), overwrite=True)
    f.close()
    assert old.read_text() == "precious\n"
    f = RowFile(old, ("t", "x"), overwrite=True)
    f.write_row(["0.1", "1"])
    f.write_row(["0.2", "2"])
    assert old.read_text() == "t,x\n0.1,1\n0.2,2\n"  # on disk at once, before close
    f.close()
    with pytest.raises(InputError, match=r"est.csv: exists; give --overwrite"):
        check_target(old, False, "-o")


def test_row_file_replaces_a_symlink_never_its_target(tmp_path: Path) -> None:
    """-o naming a symlink replaces the link with the file and leaves its target as it
    is."""
    target = tmp_path / "target.csv"
    target.write_text("keep me\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    f = RowFile(check_target(link, True, "-o"), ("t",), overwrite=True)
    f.write_row(["1.0"])
    f.close()
    assert target.read_text() == "keep me\n"
    assert not link.is_symlink() and link.read_text() == "t\n1.0\n"


def test_row_file_full_disk_keeps_whole_rows_and_names_the_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk leaves only whole rows (a short write's half row is taken back) and
    one error naming the file ('est.csv: cannot write (No space left on device)')."""
    path = tmp_path / "est.csv"
    f = RowFile(path, ("t", "x"), overwrite=False)
    f.write_row(["0.1", "1"])
    real_write = os.write

    def half_then_full(fd: int, data: bytes) -> int:
        if len(data) > 4:
            return real_write(fd, data[:4])  # a short write: half a row reaches the disk
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", half_then_full)
    with pytest.raises(InputError, match=r"est.csv: cannot write \(No space left on device\)"):
        f.write_row(["0.123456", "2"])
    monkeypatch.undo()
    f.close()
    assert path.read_text() == "t,x\n0.1,1\n"


def test_one_imu_robot_file_mounting_is_applied_by_live_and_estimate(tmp_path: Path) -> None:
    """A one-IMU robot file's mount_rpy is applied by live and by estimate alike, so a
    recording replays to the same measurements (the mounting undone)."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import imu_converters, load_input
    from continuum_mhe.io.raw_imu import RawImuSettings, mount_rotation
    from continuum_mhe.io.robot_file import read_robot

    robot_file = tmp_path / "tilted.toml"
    robot_file.write_text(
        "[[section]]\nlength = 0.2\n[[imu]]\nsection = 1\nmount_rpy = [10, -5, 0]\n"
    )
    robot = read_robot(robot_file)
    acc = [float(v) for v in mount_rotation((10.0, -5.0, 0.0)).T @ [0.0, 0.0, 9.80665]]
    raw = tmp_path / "raw.csv"
    rows = "\n".join(f"{0.01 * i!r},{acc[0]!r},{acc[1]!r},{acc[2]!r},0.0,0.0,0.0" for i in range(5))
    raw.write_text("t,ax,ay,az,gx,gy,gz\n" + rows + "\n")
    f = make_formulation("bend", robot, NoiseSettings())
    z_batch = load_input(raw, InputOptions(raw=RawImuSettings(imu_model="tilt")), f).z
    (conv,) = imu_converters(RawImuSettings(), robot)
    z_live = conv.convert(0.0, acc, np.zeros(3))
    np.testing.assert_allclose(z_batch[0], z_live, atol=1e-15)
    np.testing.assert_allclose(z_live, [0.0, 0.0], atol=1e-12)  # the mounting undone


def test_a_frozen_sensor_is_said_once_in_live() -> None:
    """A repeating reading in live is said once: treated as frozen (a dropout) while it
    repeats, with the option that turns this off."""

    said: list[str] = []
    f = make_formulation("bend", Robot.single(), NoiseSettings())
    est = make_estimator("ekf", f, recovery=bare(freeze=1.0))
    s = LiveSession(LiveSettings(port="x", fmt="tilt"), est, None, None, say=said.append)
    _feed(s, list(range(0, 3000, 50)))  # the same reading for 3 s
    notes = [m for m in said if "repeated the same reading" in m]
    assert notes == [
        "IMU 1 repeated the same reading for more than 1 s from t=0 s: treated as frozen "
        "(a dropout) while it repeats; --freeze 0 turns this off (RecoverySettings(freeze=None) "
        "in Python)"
    ]


def test_the_first_garbled_line_is_said_once_with_its_likely_cause() -> None:
    """A missed '# fields' banner (here a two-IMU tilt line to a one-IMU session): the
    first garbled line is said once with its likely cause, a session of garbled lines
    alone says it in one line, and one valid sample makes the session no failure. The
    first line after the open, with more fields than a line has, is a whole line,
    garbled, not the tail of one (not counted as partial)."""
    s, said = _session()
    now = time.monotonic()
    for i in range(10):
        s.handle_line(f"{10 * i},0.1,0.1,0.2,0.2".encode(), now)
    s.handle_line(b"100,0.1,abc", now)
    garbled = [m for m in said if "garbled" in m]
    assert garbled == [
        "garbled line skipped: expected 3 fields, found 5: a line of 2 IMU(s) in --format "
        "tilt; --robot with 2 IMU(s)? (x, line 1: '0,0.1,0.1,0.2,0.2'; said for the first "
        "only; all are counted)"
    ]
    assert s.only_garbled() == (
        "x: no valid sample: 11 garbled line(s) (the first: expected 3 fields, found "
        "5: a line of 2 IMU(s) in --format tilt; --robot with 2 IMU(s)?); check --format, "
        "--robot and --baud"
    )
    _feed(s, [200])  # one valid sample: the session is not a failure
    assert s.only_garbled() is None


def test_fields_named_in_another_order_stop_the_session() -> None:
    """A device whose ``# fields:`` line names live's fields in another order (pitch
    before roll) stops the session in one line saying so and giving live's order (every
    reading would be taken for another); fields named otherwise are said, and the
    session goes on."""
    s, said = _session()
    s.handle_line(b"# fields: t_ms,pitch,roll (ms, rad, rad)", time.monotonic())
    assert s.fatal is not None and s.wrong_units
    assert "the same fields in another order: the device must send them in live's order, " \
        "t_ms,roll,pitch" in s.fatal, s.fatal  # fmt: skip
    s, said = _session()
    s.handle_line(b"# fields: t_ms,r,p (ms, rad, rad)", time.monotonic())
    assert s.fatal is None and any("check --format and --robot" in m for m in said), said


def test_fields_named_again_in_another_order_stop_the_session() -> None:
    """A device that named live's fields in its order, then after samples (a board
    restarted with other firmware) names them in another: the later line stops the
    session as the first would, the estimates of the samples up to it kept (read as
    declared); the same declaration said again at a restart does not stop it,
    and a later declaration of other fields is said once, however often it comes."""
    s, said = _session()
    now = time.monotonic()
    s.handle_line(b"# fields: t_ms,roll,pitch (ms, rad, rad)", now)
    _feed(s, [0, 20, 40])
    s.handle_line(b"# fields: t_ms,roll,pitch (ms, rad, rad)", now)
    assert s.fatal is None
    s.handle_line(b"# fields: t_ms,pitch,roll (ms, rad, rad)", now)
    assert s.fatal is not None and not s.wrong_units and s.discarded is None
    assert (
        "t_ms,roll,pitch" in s.fatal
        and "the estimates of the 3 samples up to it are kept" in s.fatal
    ), s.fatal
    s, said = _session()
    s.handle_line(b"# fields: t_ms,roll,pitch (ms, rad, rad)", now)
    _feed(s, [0, 20, 40])
    for _ in range(3):
        s.handle_line(b"# fields: t_ms,r,p (ms, rad, rad)", now)
    assert s.fatal is None
    assert len([m for m in said if "check --format and --robot" in m]) == 1, said
    s.handle_line(b"# fields: t_ms,roll,pitch (ms, rad, rad)", now)  # live's again
    assert s._fields_match
    # samples read before any declaration, then one in another order: they were read
    # as live's order, not the device's, and their estimates are not kept
    s, said = _session()
    _feed(s, [0, 20, 40])
    s.handle_line(b"# fields: t_ms,pitch,roll (ms, rad, rad)", now)
    assert s.fatal is not None and s.wrong_units and "are kept" not in s.fatal


def test_a_line_cut_after_the_device_named_its_fields_gets_no_other_format_hint() -> None:
    """A line of the wrong field count in a one-IMU tilt session whose fields the
    device named (``# fields:``) is a garbled line without a format hint ('--format
    raw?'); a session without that line gets the hint."""
    for banner in (True, False):
        s, said = _session()
        now = time.monotonic()
        if banner:
            s.handle_line(b"# fields: t_ms,roll,pitch (ms, rad, rad)", now)
        _feed(s, [0, 20, 40])
        s.handle_line(b"60,0.1,0.1,0.2,0.2,0.3,0.3", now)
        (first,) = [m for m in said if "garbled line skipped" in m]
        assert ("--format raw?" in first) is not banner
        assert first.startswith("garbled line skipped: expected 3 fields, found 7")


def test_a_cut_first_line_after_opening_or_reopening_is_partial_not_garbled() -> None:
    """A cut first line after the port opens or reopens is partial, not garbled, so the
    first garbled line's cause is a whole line's ('found 13: ... --robot with 2 IMU(s)?'),
    not the cut one's ('found 12'); a whole first line is a sample and ends the grace."""
    s, said = _session()
    now = time.monotonic()
    s.handle_line(b".2,0.1", now)  # the tail of a line the device was sending at the open
    _feed(s, [100, 120])
    assert (s.counts.partial, s.counts.garbled) == (1, 0)
    assert not [m for m in said if "garbled" in m]
    s.handle_line(b"140,0.1", now)  # mid-stream: garbled, said with its cause
    assert (s.counts.partial, s.counts.garbled) == (1, 1)
    assert s.counts.first_garbled == "expected 3 fields, found 2"
    s.device_back()  # reopened: its first line may be cut again
    s.handle_line(b"1,0.2", now)
    _feed(s, [160])
    s.handle_line(b"180,0.1", now)
    assert (s.counts.partial, s.counts.garbled) == (2, 2)
    s.device_back()  # a whole first line after a reopen is a sample, and ends the grace
    _feed(s, [200])
    s.handle_line(b"220,0.1", now)
    assert (s.counts.partial, s.counts.garbled, s.counts.samples) == (2, 3, 3)
    _feed(s, [240])  # the next sample follows it: it was whole, and is kept
    assert (s.counts.partial, s.counts.garbled, s.counts.samples) == (2, 3, 5)


@pytest.mark.parametrize(
    ("line", "fmt", "n_imus", "hint"),
    [
        ("1,2,3,4,5,6,7,8,9,10,11,12,13", "raw", 1, "2 IMU(s) in --format raw; --robot with 2"),
        ("1,2,3", "raw", 1, "1 IMU(s) in --format tilt; --format tilt?"),
        # a raw line read as tilt: the format is named, not three tilt IMUs
        ("1,2,3,4,5,6,7", "tilt", 1, ": a line of 1 IMU(s) in --format raw; --format raw?"),
        ("1,2,3,4,5,6,7", "raw", 2, "1 IMU(s) in --format raw; --robot with 1 IMU(s)?"),
        ("1,2,3,4", "raw", 1, ""),  # no whole number of IMUs in either format
        ("1,2,x,4,5,6,7", "raw", 1, ""),  # the right count: garbled otherwise
    ],
)
def test_field_count_hint(line: str, fmt: str, n_imus: int, hint: str) -> None:
    from continuum_mhe.stream.protocol import field_count_hint

    got = field_count_hint(line, fmt, n_imus)  # type: ignore[arg-type]
    assert (hint in got) if hint else got == ""


def _deg_s_lines(n: int, degrees: bool = True) -> list[str]:
    """``n`` raw lines at 50 Hz whose gyro is in deg/s (median 41 over the first 100), as
    a board that skips the conversion sends; rad/s with ``degrees=False``."""
    from live_helpers import raw_lines

    scale = 180 / math.pi if degrees else 1.0
    return [ln.rstrip("\n") for ln in raw_lines(0, n, gyro_scale=scale)]


def _raw_session(
    raw: RawImuSettings, robot: Robot | None = None
) -> tuple[LiveSession, list[str], io.StringIO]:
    from continuum_mhe.io.inputs import imu_converters
    from continuum_mhe.model.direct import DirectFormulation

    said: list[str] = []
    robot = robot if robot is not None else Robot.single()
    f = (
        DirectFormulation(robot=robot)
        if raw.imu_model == "direct"
        else make_formulation("bend", robot, NoiseSettings())
    )
    out = io.StringIO()
    s = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"),
        make_estimator("ekf", f),
        imu_converters(raw, robot),
        out,
        say=said.append,
    )
    return s, said, out


def _handle(s: LiveSession, lines: list[str]) -> None:
    now = time.monotonic()
    for i, line in enumerate(lines):
        s.handle_line(line.encode(), now + 0.001 * i)


@pytest.mark.parametrize(
    "raw",
    [RawImuSettings(imu_model="direct"), RawImuSettings(attitude="madgwick")],
    ids=["direct", "madgwick"],
)
def test_live_stops_on_a_gyro_in_deg_s_where_the_estimate_uses_it(raw: RawImuSettings) -> None:
    """Live checks the gyro's unit as estimate does for raw files, so a deg/s gyro (57
    times too fast) does not stream on: the first UNIT_CHECK_SAMPLES samples are
    estimated while they arrive, and at the last of them the session stops (fatal:
    run_live says the summary and raises it), later lines ignored."""
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES

    s, said, out = _raw_session(raw)
    lines = _deg_s_lines(UNIT_CHECK_SAMPLES + 20)
    _handle(s, lines[: UNIT_CHECK_SAMPLES - 1])
    assert s.fatal is None and s.counts.estimates == UNIT_CHECK_SAMPLES - 1  # not held back
    _handle(s, lines[UNIT_CHECK_SAMPLES - 1 :])
    assert s.fatal is not None and s.fatal.startswith(
        "/dev/ttyIMU: gyro magnitude is about 41 (median), implausible in rad/s (above 5): "
        "deg/s? give rad/s (gx, gy, gz times pi/180 = 0.0174533)"
    )
    assert s.counts.estimates == UNIT_CHECK_SAMPLES - 1  # the last checked one: not estimated
    assert s.counts.samples == UNIT_CHECK_SAMPLES  # the lines after it: ignored
    assert len(out.getvalue().splitlines()) == UNIT_CHECK_SAMPLES  # header + estimates
    s.check_units()  # once: a second call neither says nor changes anything
    assert s.fatal.startswith("/dev/ttyIMU: gyro magnitude")


def test_live_stops_on_a_resting_gyro_in_deg_s() -> None:
    """A board at rest whose gyro sends deg/s (a bias of 1 to 2 deg/s: a median far
    below the deg/s threshold): live's unit check finds it from the accelerometer, which
    stays still where the rates read as rad/s would turn it, and stops the session; the
    same board in rad/s streams on."""
    from live_helpers import raw_line, specific_force

    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES

    rng = np.random.default_rng(6)
    n = UNIT_CHECK_SAMPLES + 10
    acc = specific_force(0.05, -0.03) + rng.normal(0.0, 0.05, (n, 3))
    deg_s = np.array([1.2, -1.5, 0.9]) + rng.normal(0.0, 0.3, (n, 3))
    for gyro, stops in ((deg_s, True), (np.radians(deg_s), False)):
        s, said, out = _raw_session(RawImuSettings(imu_model="direct"))
        _handle(s, [raw_line(20 * i, acc[i][None], gyro[i][None]) for i in range(n)])
        if stops:
            assert s.fatal is not None and s.fatal.startswith(
                "/dev/ttyIMU: the accelerometer's gravity direction turns as the gyro says "
                "only with the gyro in deg/s"
            )
            assert s.counts.estimates == UNIT_CHECK_SAMPLES - 1
        else:
            assert s.fatal is None and s.counts.estimates == n


def test_live_stops_when_the_estimator_finds_readings_in_the_wrong_units(monkeypatch) -> None:
    """Readings whose units the estimator's own check refuses (an IMU that was silent
    through live's check, then sends deg/s: ReadingUnitsError from step) stop the
    session in one line naming the port, as live's check does; they are not an
    estimator failure to restart from, sample after sample."""
    from continuum_mhe.estimators.reading_units import ReadingUnitsError

    s, said, out = _raw_session(RawImuSettings(imu_model="direct"))
    lines = _deg_s_lines(30, degrees=False)
    _handle(s, lines[:20])
    assert s.fatal is None and s.counts.estimates == 20
    why = "measurement at t=0.4 s: wx, wy, wz: gyro magnitude is about 41 (median ...)"

    def refuse(measurement: object) -> None:
        raise ReadingUnitsError(why)

    monkeypatch.setattr(s.estimator, "step", refuse)
    _handle(s, lines[20:])
    assert s.fatal == f"/dev/ttyIMU: {why}"
    assert s.counts.estimator_failures == 1 and s.counts.samples == 21  # later lines ignored


def test_live_stops_where_the_first_readings_put_the_robot_the_other_way_up() -> None:
    """A hanging robot's tilt lines read by a session whose robot is z-up: at the 25th
    sample the estimator's mounting check stops the session in one line naming the port
    and ``mounting`` (not an estimator failure to restart from, sample after sample), and
    the estimates made before it are the ones not kept; a z-down robot runs on."""
    from continuum_mhe.simulation.scenarios import simulate

    rec = simulate("paper3d", duration=3.0, seed=2, mounting="z-down")
    lines = [f"{round(1000 * t)},{z[0]:.9f},{z[1]:.9f}" for t, z in zip(rec.t, rec.z)]
    for mounting, stops in (("z-up", True), ("z-down", False)):
        f = make_formulation("bend", Robot.single(mounting=mounting), NoiseSettings())
        s = LiveSession(
            LiveSettings(port="/dev/ttyIMU", fmt="tilt"), make_estimator("ekf", f), None,
            io.StringIO(), say=[].append,
        )  # fmt: skip
        _handle(s, lines)
        if stops:
            assert s.fatal is not None and s.fatal.startswith(
                "/dev/ttyIMU: step: mounting: the robot is described as z-up"
            )
            assert s.counts.samples == 25 and s.counts.estimator_failures == 1
            assert s.wrong_mounting and not s.wrong_units
            assert s.discarded == "made with the robot described the wrong way up"
            # the estimates are not kept, and why is said: their warnings are left out
            assert s.summary().endswith(
                "; the estimates' own warnings left out (every one made with the robot "
                "described the wrong way up)"
            )
            assert "warning:" not in s.summary()
        else:
            assert s.fatal is None and s.discarded is None
            assert s.counts.estimates >= len(lines) - 1
            assert "left out" not in s.summary()


def test_live_checks_the_gyro_again_after_a_board_reset() -> None:
    """The gyro's unit is checked again after a board reset, which may bring firmware
    that sends deg/s: a device clock restart re-arms the check on the samples after it."""
    from live_helpers import raw_lines

    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES

    s, said, _ = _raw_session(RawImuSettings(imu_model="direct"))
    before = [ln.rstrip("\n") for ln in raw_lines(60_000, UNIT_CHECK_SAMPLES + 10)]
    _handle(s, before)  # checked: rad/s
    assert s.fatal is None and s.counts.clock_restarts == 0
    _handle(s, _deg_s_lines(UNIT_CHECK_SAMPLES + 5))  # restarted (clock from 0), deg/s
    assert s.counts.clock_restarts == 1
    assert s.fatal is not None and "deg/s? give rad/s" in s.fatal


def test_a_units_stop_after_a_board_reset_cuts_back_only_the_rows_after_it(
    tmp_path: Path,
) -> None:
    """rad/s readings checked and estimated, then a board reset brings firmware that
    sends deg/s: the session stops at the check re-armed by the reset, and only the
    estimates made since it are cut from the file (not the whole file, the estimates
    from the right readings with it)."""
    from live_helpers import raw_lines

    from continuum_mhe.io.estimate_csv import estimate_columns
    from continuum_mhe.io.inputs import imu_converters
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES
    from continuum_mhe.model.direct import DirectFormulation

    robot = Robot.single()
    f = DirectFormulation(robot=robot)
    path = tmp_path / "est.csv"
    out = RowFile(path, estimate_columns(f.outputs), overwrite=False)
    raw = RawImuSettings(imu_model="direct")
    s = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"), make_estimator("ekf", f),
        imu_converters(raw, robot), out, say=[].append,
    )  # fmt: skip
    before = [ln.rstrip("\n") for ln in raw_lines(60_000, UNIT_CHECK_SAMPLES + 10)]
    _handle(s, before)
    assert s.fatal is None and out.rows == len(before)
    _handle(s, _deg_s_lines(UNIT_CHECK_SAMPLES + 5))
    assert s.wrong_units and s.units_mark is not None
    good = s.units_mark[0]
    assert good == len(before) and out.rows > good
    out.cut_back(s.units_mark)
    assert out.rows == good and path.read_text().count("\n") == good + 1  # and the header
    # a stop at the first check removes the file: no row came from readings in units known
    out2 = RowFile(tmp_path / "e2.csv", estimate_columns(f.outputs), overwrite=False)
    s2 = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"), make_estimator("ekf", f),
        imu_converters(raw, robot), out2, say=[].append,
    )  # fmt: skip
    _handle(s2, _deg_s_lines(UNIT_CHECK_SAMPLES + 5))
    assert s2.wrong_units and out2.rows > 0 and s2.units_mark == (0, 0)
    out2.cut_back(s2.units_mark)
    assert out2.rows == 0 and not (tmp_path / "e2.csv").exists()


def test_live_warns_once_about_a_deg_s_gyro_it_does_not_use() -> None:
    """Tilt from the accelerometer (the default): one UnitWarning, as estimate gives for
    a raw file, and every sample is estimated."""
    from continuum_mhe.io.csv_files import UnitWarning

    s, said, _ = _raw_session(RawImuSettings())
    lines = _deg_s_lines(250)
    with pytest.warns(UnitWarning) as caught:
        _handle(s, lines)
    assert [str(w.message) for w in caught] == [
        "/dev/ttyIMU: gyro magnitude is about 41 (median), implausible in rad/s (above 5): "
        "deg/s? give rad/s (gx, gy, gz times pi/180 = 0.0174533); these options do not use "
        "the gyro, so the estimate is unaffected"
    ]
    assert s.fatal is None and s.counts.estimates == 250


def test_live_gyro_in_rad_s_passes_and_a_short_session_is_checked_at_its_end() -> None:
    import warnings

    s, _, _ = _raw_session(RawImuSettings(imu_model="direct"))
    rad = _deg_s_lines(150, degrees=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _handle(s, rad)
    assert s.fatal is None and s.counts.estimates == 150
    short, _, _ = _raw_session(RawImuSettings(imu_model="direct"))
    _handle(short, _deg_s_lines(30))
    assert short.fatal is None and short.counts.estimates == 30  # too few yet
    short.check_units()  # run_live at the session's end
    assert short.fatal is not None and "deg/s? give rad/s" in short.fatal


def test_a_deg_s_gyro_line_names_its_field_and_the_likely_unit() -> None:
    """A gyro in deg/s beyond the sensor's range (|g| > 52 rad/s) is named: the field,
    the range and 'deg/s given for rad/s?' (an IMU's dropout, or the garbled line)."""
    from live_helpers import raw_line, specific_force

    from continuum_mhe.stream.protocol import GarbledLine, parse_line

    acc = np.tile(specific_force(0.1, 0.2), (2, 1))
    gyr = np.array([[0.1, 0.2, 0.3], [0.1, 0.2, 120.0]])  # IMU 2's gz: 120 deg/s
    sample = parse_line(raw_line(20, acc, gyr), "raw", n_imus=2)  # IMU 1 is kept
    assert sample is not None and sample.problems == (
        "IMU 2: gz_2 beyond the gyro's range (|gz_2| > 52.4 rad/s, 2000 deg/s and a margin): "
        "deg/s given for rad/s?",
    )
    s, said, _ = _raw_session(RawImuSettings())
    _handle(s, ["0,0.1,0.2,9.8,0.01,0.02,0.03", "20,0.1,0.2,9.8,-90.0,0.02,0.03"])
    assert [m for m in said if "garbled" in m] == [
        "garbled line skipped: gx beyond the gyro's range (|gx| > 52.4 rad/s, 2000 deg/s and "
        "a margin): deg/s given for rad/s? (/dev/ttyIMU, line 2: "
        "'20,0.1,0.2,9.8,-90.0,0.02,0.03'; said for the first only; all are counted)"
    ]
    with pytest.raises(GarbledLine, match=r"^ay beyond the accelerometer's range \(\|ay\| > 235 "):
        parse_line("20,0.1,981.0,9.8,0.01,0.02,0.03", "raw")


def test_a_gyro_declared_beyond_the_default_range_is_read_live_as_estimate_reads_it() -> None:
    """An IMU whose robot file declares a gyro of +-4000 deg/s (``gyro_range = 69.8``
    rad/s) sends rates beyond the default limit (2000 deg/s and a margin): ``live`` reads
    them, as ``estimate`` reads them from a file, and names the declared range where a
    value lies beyond it with the margin; an accelerometer's declared +-64 g alike. A
    declared range below the default's leaves the default limit."""
    from dataclasses import replace

    from continuum_mhe.model.robot import ImuPlacement
    from continuum_mhe.stream.protocol import GarbledLine, parse_line, raw_limits

    fast = "20,0.1,0.2,9.8,60.0,0.02,0.03"  # gx 60 rad/s
    with pytest.raises(GarbledLine, match=r"^gx beyond the gyro's range \(\|gx\| > 52.4 "):
        parse_line(fast, "raw")
    wide = raw_limits(None, 69.8)
    sample = parse_line(fast, "raw", limits=(wide,))
    assert sample is not None and sample.values[3] == 60.0
    with pytest.raises(GarbledLine) as caught:
        parse_line("20,0.1,0.2,9.8,120.0,0.02,0.03", "raw", limits=(wide,))
    assert str(caught.value) == (
        "gx beyond the gyro's range (|gx| > 104.7 rad/s, the robot file's gyro_range 69.8 "
        "rad/s and a margin): deg/s given for rad/s?"
    )
    assert parse_line("20,400.0,0.2,9.8,0.1,0.02,0.03", "raw", limits=(raw_limits(627.6, None),))
    assert raw_limits(19.61, 4.363) == raw_limits(None, None)  # +-2 g, +-250 deg/s

    robot = Robot.single()
    declared = replace(robot, imus=(ImuPlacement(0, 1.0, gyro_range=69.8),))
    for r, garbled in ((robot, 1), (declared, 0)):
        s, said, _ = _raw_session(RawImuSettings(imu_model="direct"), r)
        _handle(s, ["0,0.1,0.2,9.8,0.01,0.02,0.03", fast])
        assert (s.counts.garbled, s.counts.lines) == (garbled, 2), said


def test_live_stops_early_on_an_accelerometer_in_g() -> None:
    """An accelerometer in g (|a| about 1), which estimate refuses ('the values look
    like g'), stops live early, so no unreplayable recording is made: estimate's check
    on the first UNIT_CHECK_SAMPLES samples, one line naming the port, the session stops
    (fatal), even with tilt from the accelerometer alone (the default), later lines
    ignored."""
    from continuum_mhe.io.raw_units import UNIT_CHECK_SAMPLES

    rows = [ln.split(",") for ln in _deg_s_lines(UNIT_CHECK_SAMPLES + 20, degrees=False)]
    in_g = [",".join([r[0], *(f"{float(v) / 9.80665:.5f}" for v in r[1:4]), *r[4:]]) for r in rows]
    s, said, out = _raw_session(RawImuSettings())
    _handle(s, in_g[: UNIT_CHECK_SAMPLES - 1])
    assert s.fatal is None and s.counts.estimates == UNIT_CHECK_SAMPLES - 1
    _handle(s, in_g[UNIT_CHECK_SAMPLES - 1 :])
    assert s.fatal == (
        "/dev/ttyIMU: accelerometer magnitude is about 1.00: the values look like g; ax, ay, "
        "az must be in m/s^2 (multiply by 9.80665)"
    )
    assert s.counts.samples == UNIT_CHECK_SAMPLES and s.counts.estimates == UNIT_CHECK_SAMPLES - 1
    rad, _, _ = _raw_session(RawImuSettings())  # the same stream in m/s^2 goes on
    _handle(rad, [",".join(r) for r in rows])
    assert rad.fatal is None and rad.counts.estimates == len(rows)


def test_a_sample_whose_solve_a_signal_stops_keeps_its_row(monkeypatch) -> None:
    """A second Ctrl-C that stops the estimator's step on a sample (already recorded)
    still writes that sample's row, without an estimate, before the signal goes on: the
    recording and the estimates keep a row per sample."""
    out = io.StringIO()
    s, _ = _session(out=out)
    step = s.estimator.step
    calls = []

    def stopped(m: object) -> object:
        calls.append(m)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return step(m)  # type: ignore[arg-type]

    monkeypatch.setattr(s.estimator, "step", stopped)
    with pytest.raises(KeyboardInterrupt):
        _feed(s, [0, 50, 100, 150, 200, 250])
    rows = [ln for ln in out.getvalue().splitlines() if ln and not ln.startswith(("#", "t,"))]
    assert len(rows) == s.counts.estimates == 4
    assert rows[-1].endswith(",no-estimate,0")


def test_seconds_of_lines_of_another_field_count_say_why_where_fields_were_declared() -> None:
    """A device that declared its fields (``# fields: t_ms,roll,pitch``), whose lines
    then carry a second IMU's tilt for seconds: a single such line is taken as cut (no
    hint), but the stop after seconds of them names the likely cause, as it does
    without the declaration."""
    s, _ = _session()
    now = time.monotonic()
    s.handle_line(b"# fields: t_ms,roll,pitch", now)
    _feed(s, [0, 50, 100])
    for i in range(80):  # 4 s of two-IMU lines at 20 Hz
        s.handle_line(f"{150 + 50 * i},0.1,0.1,0.2,0.2".encode(), now + 0.05 * i)
    assert s.fatal is not None and "nothing but garbled lines" in s.fatal
    assert ": a line of 2 IMU(s) in --format tilt; --robot with 2 IMU(s)?" in s.fatal, s.fatal


def test_the_gyro_units_check_of_a_live_stream_imports_no_scipy() -> None:
    """The gyros' units check (about a second into a raw stream) turns the gravity
    direction with numpy alone: a raw stream's warm-up and the check itself import no
    part of SciPy (hundreds of modules that would stall the stream where it runs)."""
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import numpy as np\n"
        "from continuum_mhe.estimators import make_estimator\n"
        "from continuum_mhe.io.raw_units import gyro_gravity_problem\n"
        "from continuum_mhe.io.robot_file import read_robot\n"
        "from continuum_mhe.live.run import warm_up\n"
        "from continuum_mhe.model.registry import make_formulation\n"
        "f = make_formulation('direct', read_robot('two-section'))\n"
        "warm_up(make_estimator('ekf', f), 5)\n"
        "rng = np.random.default_rng(0)\n"
        "t = np.arange(400) * 0.01\n"  # still, a gyro bias: stretches the check turns
        "acc = [0.0, 0.0, 9.81] + 1e-3 * rng.normal(size=(400, 3))\n"
        "gyr = [0.0, 0.02, 0.01] + 1e-3 * rng.normal(size=(400, 3))\n"
        "assert gyro_gravity_problem(t, acc, gyr) is None\n"
        "print(sorted(m for m in sys.modules if m.startswith('scipy')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_falling_behind_after_a_long_restart_names_the_restart() -> None:
    """The falling-behind line names a restart that took long (a tendon robot's start
    fits the tip force: half a second) rather than advising a lower rate."""
    from types import SimpleNamespace

    from continuum_mhe.live.run import _faster
    from continuum_mhe.results import Estimate, Status

    ekf = SimpleNamespace(name="ekf")
    restart = Estimate(1.0, None, None, None, Status.RESET, 540.0)
    said = _faster(SimpleNamespace(last=restart, estimator=ekf))  # type: ignore[arg-type]
    assert said.startswith("the estimator's restart took 540 ms")
    ok = Estimate(1.0, None, None, None, Status.OK, 3.0)
    said = _faster(SimpleNamespace(last=ok, estimator=ekf))  # type: ignore[arg-type]
    assert said == "the ekf is slower than the stream: a lower rate or a faster machine"


def test_device_message_repeats_not_shown_are_counted_for_the_summary() -> None:
    """A banner repeated within the rate limit (a board that resets twice in 5 s) is
    shown once; the repeats hidden are counted (the summary says how many), and said
    with the message where it is shown again later."""
    from continuum_mhe.live.counts import DeviceMessages

    said: list[str] = []
    messages = DeviceMessages(said.append, 5.0)
    for now in (0.0, 1.0, 2.0):
        messages.show("continuum_imu v1", now)
    assert said == ["device says: continuum_imu v1"] and messages.not_shown() == 2
    messages.show("continuum_imu v1", 6.0)
    assert said[-1] == "device says: continuum_imu v1 (and 2 more time(s) since)"
    assert messages.not_shown() == 0
    # the host's own notes, rate-limited alike, are not counted as the device's
    for now in (7.0, 8.0, 9.0):
        messages.show("dropped a line longer than 4096 bytes", now, source="")
    assert said[-1] == "dropped a line longer than 4096 bytes" and messages.not_shown() == 0


@pytest.mark.parametrize(
    ("first", "count", "then", "wrong"),
    [
        ("{i:.1f},1.0", 4, "degrees", True),  # bending from the start, in degrees
        ("1.0,1.0", 150, "degrees", True),  # upright in degrees for 3 s, then bending
        ("0.1,0.1", 150, "garbage", False),  # radians, then garbage beyond pi
        ("0.1,0.1", 10, "garbage", False),  # the same, early
    ],
    ids=["degrees-at-once", "degrees-later", "radians-then-garbage", "radians-early-garbage"],
)
def test_tilt_in_degrees_stops_live_and_its_estimates_are_not_kept(
    first: str, count: int, then: str, wrong: bool
) -> None:
    """Tilt lines in degrees: those near straight are within the radians' range and
    estimated; once the angles grow past it, every line is garbled and the session
    stops. Where the garbled angles follow on from the last valid ones, the valid ones
    were degrees read as radians: the session says the readings were in the wrong
    units (``live`` then removes their estimates, as for g or deg/s), however many there
    were. A radians stream that turns to garbage beyond pi keeps its estimates."""
    s, _ = _session()
    now = time.monotonic()
    lines = [f"{20 * i}," + first.format(i=1.0 + 0.5 * i) for i in range(count)]
    start = float(first.format(i=1.0 + 0.5 * (count - 1)).split(",")[0])
    for i in range(300):
        roll = start + 0.3 * (i + 1) if then == "degrees" else 57.3
        lines.append(f"{20 * (count + i)},{roll:.2f},1.0")
    for i, line in enumerate(lines):
        s.handle_line(line.encode(), now + 0.02 * i)
        if s.fatal:
            break
    assert s.fatal is not None and "degrees given for radians?" in s.fatal
    # (the session's first line may be the tail of one sent before it opened the port)
    assert s.counts.samples >= count - 1
    assert s.wrong_units is wrong


def test_tilt_in_degrees_of_several_imus_is_found_past_an_imus_dropout() -> None:
    """Two IMUs sending degrees, IMU 2 bending twice as fast: its angle leaves the
    radians' range first (that IMU a dropout on the lines after), then IMU 1's, and the
    lines are garbled. IMU 1's angle follows on from its last valid one: the readings
    were degrees read as radians."""
    from continuum_mhe.io.robot_file import read_robot

    s, _ = _session(robot=read_robot("two-section"))
    now = time.monotonic()
    for i in range(400):
        s.handle_line(f"{20 * i},0.5,{0.05 * i:.3f},0.5,{0.1 * i:.3f}".encode(), now + 0.02 * i)
        if s.fatal:
            break
    assert s.fatal is not None and "degrees given for radians?" in s.fatal
    assert s.counts.samples > 16  # IMU 2 left the range at line 16, IMU 1 at line 32
    assert s.wrong_units is True


@pytest.mark.parametrize(
    ("line", "imus", "degrees"),
    [
        ("0,95.0,0.1", 1, True),  # a roll past pi
        ("0,0.1,x", 1, False),  # not a number
        ("0,95.0,0.1,x,0.1", 2, True),  # both IMUs bad: the first one's cause
        ("0,x,0.1,95.0,0.1", 2, False),
        ("0,1e9,0.1", 1, True),
    ],
)
def test_a_garbled_lines_cause_says_whether_it_is_degrees(
    line: str, imus: int, degrees: bool
) -> None:
    """The garbled line's cause carries whether it is a tilt angle beyond the radians'
    range (what the degrees rules count), as a flag, not in its words alone."""
    from continuum_mhe.stream.protocol import GarbledLine, parse_line

    with pytest.raises(GarbledLine) as caught:
        parse_line(line, "tilt", imus)
    assert caught.value.degrees_for_radians is degrees
    assert ("degrees given for radians?" in str(caught.value)) is degrees


@pytest.mark.parametrize(("garbled", "wrong"), [(46, True), (5, False)])
def test_a_stream_that_ends_in_tilt_degrees_is_found_without_the_stop(
    garbled: int, wrong: bool
) -> None:
    """A short recording in degrees (a few lines near straight, valid as radians, then
    the angles past the radians' range) ends before the garbled lines last the 3 s that
    stop a session: 20 lines or more that grew from the valid ones say the readings were
    degrees, as the stop would (``live`` removes their estimates, exit 2); a few such
    lines at the end are counted as garbled, the estimates kept."""
    s, _ = _session()
    now = time.monotonic()
    lines = [f"{20 * i},{0.5 * i:.2f},0.5" for i in range(4)]
    lines += [f"{20 * (4 + i)},{3.5 + 2.5 * i:.2f},0.5" for i in range(garbled)]
    for i, line in enumerate(lines):
        s.handle_line(line.encode(), now + 0.02 * i)
    s.finish()
    assert s.wrong_units is wrong
    if wrong:
        assert s.fatal is not None and "degrees given for radians?" in s.fatal
    else:
        assert s.fatal is None and s.counts.garbled == garbled


@pytest.mark.parametrize("degrees", [True, False])
def test_tilt_degrees_in_short_runs_stop_live_by_their_share(degrees: bool) -> None:
    """A fast stream (a line every 5 ms) of tilt in degrees swinging through straight
    (10 degrees either way, once a second): each run of angles past the radians' range
    lasts well under the 3 s that stop a session, but such lines, grown from the valid
    ones, are a tenth of the lines or more: the readings were degrees (the session
    stops, its estimates not kept), as ``estimate`` refuses such a file. A radians
    stream with as many lines of garbage beyond pi between its valid ones, which do not
    follow on from them, runs to its end with its estimates."""
    s, _ = _session()
    now = time.monotonic()
    for i in range(1200):
        if degrees:
            roll = 10.0 * math.sin(2 * math.pi * i / 200)
        else:
            roll = 57.3 if i % 5 == 4 else 0.1 * math.sin(2 * math.pi * i / 200)
        s.handle_line(f"{5 * i},{roll:.3f},0.2".encode(), now + 0.005 * i)
        if s.fatal:
            break
    s.finish()
    assert s.wrong_units is degrees
    if degrees:
        assert s.fatal is not None and "lines skipped for tilt angles that grew" in s.fatal
        assert "the angles are in degrees; send radians" in s.fatal
        assert s.counts.lines < 200  # stopped within the first swing
    else:
        assert s.fatal is None and s.counts.garbled == 240


def test_the_summary_says_how_many_estimates_are_uncertain_for_their_width() -> None:
    """As ``estimate`` does: with ``uncertain_fraction`` far below the estimates' tip
    standard deviation, every estimate after the start is ``uncertain`` for its width,
    and the summary counts them (the start's own ``uncertain`` row counts too, its
    standard deviation as wide); at the default it says nothing of it."""
    from continuum_mhe.settings import RecoverySettings

    for fraction, said in ((1e-5, True), (0.1, False)):
        out = io.StringIO()
        f = make_formulation("bend", Robot.single(), NoiseSettings())
        est = make_estimator("ekf", f, recovery=RecoverySettings(uncertain_fraction=fraction))
        s = LiveSession(LiveSettings(port="x", fmt="tilt"), est, None, out, say=[].append)
        now = time.monotonic()
        noise = np.random.default_rng(1).normal(0.0, 0.01, (60, 2))
        for i in range(60):
            line = f"{10 * i},{0.1 + noise[i, 0]},{0.1 + noise[i, 1]}"
            s.handle_line(line.encode(), now + 0.01 * i)
        statuses = [r.split(",")[-2] for r in out.getvalue().splitlines()[1:]]
        summary = s.summary()
        if said:
            n = statuses.count("uncertain")
            assert n == len(statuses) > 50
            assert f"; note: {n} of {len(statuses)} estimates are uncertain" in summary
            assert "over --uncertain-fraction 1e-05 of the robot's length (0 mm)" in summary
        else:
            assert statuses.count("ok") > 50 and "pin the shape down" not in summary


def test_a_glitch_is_skipped_and_said_in_the_summary() -> None:
    """One tilt line whose roll is 1 rad off between steady ones: the session skips it
    as a glitch (its row inconsistent, the estimates after it as before) and its summary
    counts it."""
    out = io.StringIO()
    s, _ = _session(out=out)
    now = time.monotonic()
    noise = np.random.default_rng(0).normal(0.0, 0.01, (200, 2))  # not a frozen IMU
    for i in range(200):
        roll = 0.1 + noise[i, 0] + (1.0 if i == 150 else 0.0)
        s.handle_line(f"{10 * i},{roll},{0.1 + noise[i, 1]}".encode(), now + 0.01 * i)
    rows = [r.split(",") for r in out.getvalue().splitlines()[1:]]
    assert rows[150][-2] == "inconsistent" and rows[151][-2] == "ok"
    assert s.estimator.diagnostics.glitches == 1
    assert "skipped 1 IMU reading(s) far beyond the prediction" in s.summary()


def test_the_live_summary_counts_frozen_rows_and_restarts_as_estimate_does(tmp_path) -> None:
    """A tilt stream whose IMU repeats one reading for 0.5 s, then stops for 2 s: the
    session's summary counts the frozen rows and the restart after the gap, as
    estimate's summary of the same samples does, with the same counts."""
    from continuum_mhe.cli import main

    s, _ = _session()
    now = time.monotonic()
    noise = np.random.default_rng(1).normal(0.0, 0.01, (300, 2))
    lines = []
    for i in range(300):
        t_ms = 10 * i + (2000 if i >= 200 else 0)  # 2 s without a sample after 200
        k = 100 if 100 <= i < 150 else i  # the reading of sample 100 held for 0.5 s
        lines.append(f"{t_ms},{0.1 + noise[k, 0]},{0.1 + noise[k, 1]}")
    for i, line in enumerate(lines):
        s.handle_line(line.encode(), now + 0.01 * i)
    s.finish()
    diag = s.estimator.diagnostics
    assert diag.frozen_samples > 0 and diag.gap_resets == 1
    summary = s.summary()
    frozen = f"{diag.frozen_samples} of the {s.counts.estimates} estimates had a frozen IMU"
    assert frozen in summary
    assert "restarted after 1 gap(s) longer than 1 s without a valid reading" in summary
    # estimate says the same of the same samples
    csv = tmp_path / "m.csv"
    csv.write_text("t,roll,pitch\n" + "\n".join(
        f"{int(ln.split(',')[0]) / 1e3},{','.join(ln.split(',')[1:])}" for ln in lines
    ) + "\n")  # fmt: skip
    import contextlib
    import io as io_module

    err = io_module.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(["estimate", str(csv), "-o", str(tmp_path / "e.csv"), "--method", "ekf"]) == 0
    assert frozen in err.getvalue()
    assert "restarted after 1 gap(s) longer than 1 s" in err.getvalue()


def test_a_live_mhe_builds_its_ipopt_fallback_once_its_window_is_full(monkeypatch) -> None:
    """A live session has the fast MHE's IPOPT fallback built in the background from
    the second sample on (the sample period sets the objective's scale), once, so that a
    first uncertified window does not hold the stream while it is built (about 8 s for
    two raw IMUs); a fallback takes the NLP that build made; the stream's end waits for a
    build still running; an EKF's session builds none."""
    from continuum_mhe.estimators import mhe as mhe_module

    built: list[int] = []
    real = mhe_module.build_nlp

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        built.append(args[-1])
        return real(*args, **kwargs)

    monkeypatch.setattr(mhe_module, "build_nlp", counted)
    s, _ = _session("mhe")
    inference = s.estimator.inference
    _feed(s, [0])  # one sample: its period not known yet
    assert not inference._nlp_builds and not inference._nlps
    _feed(s, [10 + 10 * i for i in range(14)])  # past the full window (10)
    (scale_exp,) = set(inference._nlp_builds) | set(inference._nlps)  # started (or done)
    nlp = inference._window_nlp(scale_exp)  # a fallback: waits for that build
    assert not inference._nlp_builds and inference._nlps[scale_exp] is nlp
    assert built == [scale_exp]  # once, by the thread
    assert inference.prepare_fallback() is False  # built: nothing more
    e, _ = _session("ekf")
    _feed(e, [10 * i for i in range(20)])
    assert e._fallback_prepared and "ipopt-fallback-nlp" not in {
        t.name for t in threading.enumerate()
    }
    # a stream's end waits for a build still running (a process torn down under it
    # crashes)
    s2, _ = _session("mhe")
    _feed(s2, [10 * i for i in range(3)])
    assert s2.estimator.inference._nlp_builds
    s2.finish()
    assert not any(t.is_alive() for t in s2.estimator.inference._nlp_builds.values())
    assert not any(t.daemon for t in s2.estimator.inference._nlp_builds.values())


def test_live_skips_readings_at_a_declared_gyro_range_and_names_them() -> None:
    """A one-IMU board whose gyro is declared (``gyro_range``) to clip at 0.8 of the
    motion's largest rate: the lines whose rates reach it are that IMU's dropouts, as
    ``estimate`` takes them from a file, and the summary names how many and from when."""
    from dataclasses import replace

    from live_helpers import raw_line

    from continuum_mhe.io.inputs import imu_converters
    from continuum_mhe.model.direct import DirectFormulation, raw_imu_readings
    from continuum_mhe.simulation.scenarios import simulate

    rec = simulate("paper3d", duration=4.0, dt=0.02, noise_deg=0.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], 0.2)
    full_scale = 0.8 * float(np.abs(gyr).max())  # a gyro whose range the motion passes
    gyr = np.clip(gyr, -full_scale, full_scale)
    at_scale = (np.abs(gyr) >= 0.99 * full_scale).any(axis=1)
    assert 0 < at_scale.sum() < len(gyr)
    single = Robot.single()
    robot = replace(single, imus=(replace(single.imus[0], gyro_range=full_scale),))
    out = io.StringIO()
    s = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"),
        make_estimator("ekf", DirectFormulation(robot=robot)),
        imu_converters(RawImuSettings(imu_model="direct"), robot),
        out,
        say=[].append,
    )
    _handle(s, [raw_line(20 * i, acc[i][None], gyr[i][None]) for i in range(len(gyr))])
    first = float(rec.t[np.argmax(at_scale)])
    assert f"{int(at_scale.sum())} reading(s) clipped, from t = {first:g} s" in s.summary()
    header, *lines = out.getvalue().splitlines()
    status = [ln.split(",")[header.split(",").index("status")] for ln in lines]
    assert len(status) == len(gyr) and "ok" in status
    assert all(st == "dropout" for st, hit in zip(status, at_scale) if hit)


#: The shipped two-section rod recordings (raw: t in s, two IMUs at 50 Hz).
ROD2 = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"


def _two_section_ekf_session(
    lines: list[str], robot: str = "two-section", imu_twist: bool = False
) -> LiveSession:
    """A live session of the EKF of ``robot``'s two raw IMUs (a robot file's name or
    path) that has handled ``lines`` (the line protocol's), each 1 ms after the last,
    and finished."""
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import serial_input
    from continuum_mhe.io.robot_file import read_robot

    base = make_formulation("bend", read_robot(robot), NoiseSettings())
    serial = serial_input("/dev/ttyIMU", "raw", InputOptions(imu_twist=imu_twist), base)
    s = LiveSession(
        LiveSettings(port="/dev/ttyIMU", fmt="raw"),
        make_estimator("ekf", serial.formulation),
        serial.converters,
        io.StringIO(),
        say=[].append,
    )
    _handle(s, lines)
    s.finish()
    return s


def _two_section_ekf_summary(lines: list[str]) -> str:
    """The summary of :func:`_two_section_ekf_session` of the ``two-section`` robot."""
    return _two_section_ekf_session(lines).summary()


def _rod_lines(name: str) -> list[str]:
    """The shipped rod recording ``name``'s raw rows as the line protocol's (t in ms)."""
    lines = []
    for row in (ROD2 / f"{name}_raw.csv").read_text().splitlines()[1:]:
        t, rest = row.split(",", 1)
        lines.append(f"{round(float(t) * 1000)},{rest}")
    return lines


def test_live_says_where_the_readings_show_the_imus_twisting(tmp_path: Path) -> None:
    """Live keeps the IMUs' constant-curvature frames, and weighs their twist alongside
    on the readings it estimates: the shipped ``spatial`` rod (the tip IMU twists up to
    122 degrees) gets a warning that names --imu-twist, with the evidence that
    ``estimate`` of the same readings weighs (the filters stepped in blocks, to 1e-9);
    uncalibrated, it names the calibration first. The planar S (no twist) and a session
    given --imu-twist get none."""
    from continuum_mhe.cli.entry import main
    from continuum_mhe.estimators.twist_evidence import twist_evidence
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import load_input
    from continuum_mhe.io.robot_file import read_robot

    said = "the readings show the IMUs turning about the backbone"
    calibrated = {}
    for name in ("spatial", "planar-s"):
        calibrated[name] = str(tmp_path / f"{name}_cal.toml")
        assert main(["calibrate", "--from", str(ROD2 / f"{name}_rest.csv"), "--robot",
                     "two-section", "--write-robot", calibrated[name]]) == 0  # fmt: skip
    s = _two_section_ekf_session(_rod_lines("spatial"), calibrated["spatial"])
    summary, streamed = s.summary(), s.twist_evidence.evidence()
    robot = make_formulation("bend", read_robot(calibrated["spatial"]))
    data = load_input(ROD2 / "spatial_raw.csv", InputOptions(), robot)
    weighed = twist_evidence(data.formulation, data.t, data.z)
    assert streamed is not None and streamed.samples == weighed.samples == 600
    assert streamed.share == weighed.share > 0.9
    assert streamed.median == pytest.approx(weighed.median, rel=1e-9) and weighed.median > 100
    assert f"warning: {said}" in summary and "live --imu-twist follows it" in summary
    assert (
        f"96 % of 600 readings better, median log-density gain {weighed.median:+.3g} nats"
        in summary
    )
    assert "calibrate the gyro biases" not in summary
    uncalibrated = _two_section_ekf_session(_rod_lines("spatial")).summary()
    assert f"{said}" in uncalibrated and "are inconsistent" in uncalibrated
    assert "calibrate the gyro biases with the robot straight and still" in uncalibrated
    planar = _two_section_ekf_session(_rod_lines("planar-s"), calibrated["planar-s"])
    evidence = planar.twist_evidence.evidence()
    assert evidence is not None and evidence.samples == 600 and not evidence.twists
    assert said not in planar.summary()
    given = _two_section_ekf_session(_rod_lines("spatial"), calibrated["spatial"], imu_twist=True)
    assert given.twist_evidence.evidence() is None and said not in given.summary()


def test_live_names_a_forward_clock_jump_that_restarts_the_estimate() -> None:
    """The shipped planar-s rod's raw lines (two IMUs, 50 Hz) whose device clock steps
    0.9 s forward at 4 s: as ``estimate`` of the same file, the readings after the jump
    restart the EKF (one ``reset``) and the summary names the jump, not a glitch."""
    lines = []
    for line in (ROD2 / "planar-s_raw.csv").read_text().splitlines()[1:]:
        t, rest = line.split(",", 1)
        lines.append(
            f"{round((float(t) + (0.9 if float(t) >= 4.0 - 1e-9 else 0.0)) * 1000)},{rest}"
        )
    summary = _two_section_ekf_summary(lines)
    assert "restarted after 1 jump(s) in t shorter than 1 s (the first 0.92 s long" in summary
    assert "glitch" not in summary and "reset: 1" in summary


def test_live_warns_of_readings_that_restart_the_estimator_as_estimate_does() -> None:
    """The shipped spatial-tendon rod's raw lines with the two IMUs' fields swapped (the
    boards' addresses the other way round): the EKF restarts on about a third of the
    samples, and the summary says so in ``estimate``'s warning, which names the IMUs'
    order; the lines in the right order restart it too seldom to be said."""
    rows = (ROD2 / "spatial-tendon_raw.csv").read_text().splitlines()[1:]
    summaries = []
    for swap in (False, True):
        lines = []
        for row in rows:
            t, *v = row.split(",")
            v = v[6:] + v[:6] if swap else v
            lines.append(f"{2300 + round(float(t) * 1000)}," + ",".join(v))
        summaries.append(_two_section_ekf_summary(lines))
    assert "restarted the estimator" not in summaries[0]
    said = re.search(
        r"warning: (\d+) of 601 samples \((\d+) %\) restarted the estimator", summaries[1]
    )
    assert said is not None, summaries[1]
    assert 20 <= int(said[2]) <= 45
    assert "the readings do not fit the model of the robot" in summaries[1]
    # what to check is said once, in the warning on inconsistent estimates it points to
    assert "(what to check: the warning on inconsistent estimates, which follows)" in summaries[1]
    assert summaries[1].count("check the robot file against the robot (the IMUs' order") == 1


def test_the_live_twist_warning_follows_estimate_s_rules() -> None:
    """As ``estimate`` chooses and hints: a calibrated robot's session is told whenever
    the readings favour the twist; an uncalibrated one only where its estimates were
    mostly inconsistent (the twist model would take a gyro bias about z for a twist);
    no warning on fewer readings than a choice needs, or where the frames predicted
    better."""
    from continuum_mhe.estimators.twist_evidence import MIN_SAMPLES, TwistEvidence
    from continuum_mhe.live.twist_hint import twist_hint

    favours = TwistEvidence(12.5, 0.8, MIN_SAMPLES)
    calibrated = twist_hint(favours, calibrated=True, inconsistent=False)
    assert calibrated is not None and "80 % of 100 readings better" in calibrated
    assert "live --imu-twist follows it" in calibrated and "calibrate" not in calibrated
    assert twist_hint(favours, calibrated=False, inconsistent=False) is None
    uncalibrated = twist_hint(favours, calibrated=False, inconsistent=True)
    assert uncalibrated is not None and "continuum-mhe calibrate --port PORT" in uncalibrated
    for weak in (TwistEvidence(12.5, 0.8, MIN_SAMPLES - 1), TwistEvidence(-0.1, 0.4, 600)):
        for cal, inc in ((True, True), (False, True)):
            assert twist_hint(weak, calibrated=cal, inconsistent=inc) is None
    assert twist_hint(None, calibrated=True, inconsistent=True) is None
