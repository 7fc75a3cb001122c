"""``continuum-mhe live`` on a pseudo-terminal: a recorded raw stream with garbage,
a partial line, a time gap, out-of-order lines and a mid-stream hang-up, followed by
the device coming back (the port is a symlink re-pointed to a new pty); the recording
replayed by ``estimate``; and the session's parts (protocol, clock, files) alone."""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from live_helpers import (
    SAFETY_S,
    LiveProcess,
    data_rows,
    new_pty,
    raw_line,
    raw_lines,
    send,
    send_and_finish,
    send_until_estimated,
    send_until_rows,
    specific_force,
    unplug,
    wait_for,
)

from continuum_mhe.io.state_tables import read_state_table, read_states
from continuum_mhe.live.run import GarbledLine, parse_line

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")


def test_parse_line_protocol() -> None:
    s = parse_line("1500,0.1,0.2,9.8,0.01,0.02,0.03\r\n", "raw")
    assert s is not None and s.t == 1.5 and s.values.shape == (6,)
    assert parse_line("# continuum_imu 1.0", "raw") is None
    assert parse_line("   ", "tilt") is None
    t = parse_line("20,0.1,-0.2", "tilt")
    assert t is not None and list(t.values) == [0.1, -0.2]
    two = parse_line("20,0.1,-0.2,0.3,0.4", "tilt", n_imus=2)
    assert two is not None and list(two.values) == [0.1, -0.2, 0.3, 0.4]
    for bad in (
        "1,2,3",
        "x,0,0,9.8,0,0,0",
        "1,nan,0,9.8,0,0,0",
        "1,0,0,9999,0,0,0",
        "12,0.1,0.2,9.8,0.01,0.0",
        "12,0,0,0,0.01,0.0,0",  # an accelerometer reading exactly zero
        "12,1e-200,0,1e-200,0.01,0.0,0",  # one whose square underflows: no direction
    ):
        with pytest.raises(GarbledLine):
            parse_line(bad, "raw")
    with pytest.raises(GarbledLine):
        parse_line("20,45.0,10.0", "tilt")  # degrees, not radians
    with pytest.raises(GarbledLine, match="expected 5 fields, found 3"):
        parse_line("20,0.1,-0.2", "tilt", n_imus=2)  # one IMU's fields for two


def test_live_pty_stream_with_faults(tmp_path: Path) -> None:
    port = tmp_path / "ttyIMU"
    out = tmp_path / "live.csv"
    master = new_pty(port)
    # the first session: 60 samples, gap of 10 samples after sample 40 (device lost them)
    first = raw_lines(0, 70, skip=range(40, 50))
    garbage = [
        "#continuum_imu 1.0 accel=+-4g gyro=+-500dps rate=50Hz\n",
        "\x00\xff\xfe garbage\n",
        "hello world\n",
        "12,0.1\n",
        "\n",
    ]
    lines = [
        garbage[0],
        *first[:5],
        garbage[1],
        garbage[2],
        *first[5:20],
        garbage[3],
        first[10],  # an old (out-of-order) sample
        *first[20:30],
        first[30][:17] + first[31],  # a line cut short, run into the next
        *first[32:],
        garbage[4],
    ]
    valid_first = len(first) - 2  # first[30] and first[31] were destroyed together
    live = LiveProcess(
        ["--port", str(port), "--format", "raw", "--method", "ekf", "-o", str(out)]
        + ["--status-every", "0.2", "--retry-max", "0.2"]
    )
    try:
        live.wait_ready()
        for line in lines:
            send(master, line.encode("latin-1"))
            time.sleep(0.002)
        send(master, b"99999,0.1,0.2")  # a partial line, then the device hangs up
        wait_for(lambda: data_rows(out) >= valid_first, "estimates of session 1")
        time.sleep(0.3)
        unplug(master, port)
        # the file is complete while live waits for the device
        wait_for(lambda: "disconnected" in live.err, "the hang-up")
        t1, x1, s1 = read_states(out)
        assert len(t1) == valid_first
        assert np.all(np.diff(t1) > 0)
        assert np.all(np.isfinite(x1))
        # the second session: the device comes back and restarts its clock at 0
        master = new_pty(port)
        wait_for(lambda: "is back" in live.err, "the device to be reopened")
        second = raw_lines(0, 25)
        send(master, b"# continuum_imu 1.0 (after its reset)\n")  # kept: a message
        for line in second:
            send(master, line.encode())
            time.sleep(0.002)
        wait_for(lambda: data_rows(out) >= valid_first + len(second), "estimates of session 2")
        code = live.finish(signal.SIGINT)
    finally:
        if live.proc.poll() is None:
            live.proc.kill()
        os.close(master)
    err = live.err
    assert code == 0, err
    t, x, status = read_states(out)
    # every valid sample produced exactly one estimate, in order, none invented
    assert len(t) == valid_first + len(second)
    assert np.all(np.diff(t) > 0)
    # the device's second session comes over a second later: --gap-reset (1 s) restarts
    # the estimator there, once (the same mechanism as in estimate)
    assert status[0] == "uncertain" and set(status[1:valid_first]) == {"ok"}
    assert status[valid_first] == "reset" and set(status[valid_first + 1 :]) == {"ok"}
    assert np.all(x[:, 3] <= np.pi / 2 + 0.05)  # no runaway across the long gap
    # the gap: one step of 11 periods, no estimates inside it
    steps = np.diff(t[:valid_first])
    assert np.sum(steps > 0.05) == 2  # the 10-sample gap and the destroyed pair
    assert steps.max() == pytest.approx(0.22, abs=1e-9)
    # the restarted device continues after the old samples
    assert t[valid_first] > t[valid_first - 1]
    assert "disconnected" in err and "is back" in err and "gap of" in err
    assert "device clock restarted" in err
    assert "device says: #continuum_imu 1.0" in err
    summary = [ln for ln in err.splitlines() if "samples," in ln][-1]
    assert f"{valid_first + len(second)} samples, {valid_first + len(second)} estimates" in summary
    assert "4 garbled" in summary  # non-ASCII, text, too few fields, the run-together line
    assert "1 partial" in summary
    assert "1 out of order" in summary
    assert "1 disconnect" in summary
    assert "1 clock restart(s)" in summary


def test_live_bad_port_is_one_line_with_causes(tmp_path: Path) -> None:
    res = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(tmp_path / "none")],
        capture_output=True,
        text=True,
        timeout=SAFETY_S,
    )
    assert res.returncode == 2
    assert res.stderr.startswith("continuum-mhe: error: ") and res.stderr.count("\n") == 1
    for cause in ("dialout", "/dev/cu.usbmodem", "/dev/ttyUSB0", "Serial Monitor"):
        assert cause in res.stderr


def test_a_recording_given_as_the_port_is_said_to_be_no_serial_device(tmp_path: Path) -> None:
    """``--port rec.csv`` (a recording's path): one line saying it is a regular file and
    how a recording is estimated (not that the board may be unplugged)."""
    from continuum_mhe.stream.reader import port_hint

    rec = tmp_path / "rec.csv"
    rec.write_text("t,roll,pitch\n")
    said = port_hint(str(rec), OSError(25, "Inappropriate ioctl for device"))
    assert said == (
        f"{rec}: a regular file, not a serial device: give the device (Linux /dev/ttyACM0, "
        "macOS /dev/cu.usbmodem*); a recording is estimated with continuum-mhe estimate FILE"
    )


@pytest.mark.skipif(os.name != "posix", reason="exclusive serial access is POSIX's")
def test_a_second_reader_of_a_port_is_refused_with_the_port_in_use(tmp_path: Path) -> None:
    """Two readers of one port would each take some of its lines: the second ``live``
    on a port one already reads is one line saying the port is in use, exit 2, and the
    first reads on."""
    port, out = tmp_path / "ttyIMU", tmp_path / "est.csv"
    master = new_pty(port)
    first = LiveProcess(["--port", str(port), "--method", "ekf", "-o", str(out)])
    try:
        first.wait_ready()
        res = subprocess.run(
            [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(port)],
            capture_output=True,
            text=True,
            timeout=SAFETY_S,
        )
        assert res.returncode == 2, res.stderr
        assert res.stderr.count("\n") == 1, res.stderr
        assert "the port is in use" in res.stderr
        assert first.proc.poll() is None, first.err
        send(master, "".join(raw_lines(0, 5)).encode())
        wait_for(lambda: data_rows(out) >= 5, "the first reader's estimates")
    finally:
        code = first.finish(signal.SIGINT)
        unplug(master, port)
    assert code == 0, first.err


def test_live_refuses_to_replace_an_output_without_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """In this process: the refusal comes before the port is opened (two fresh
    interpreters cost 2.5 s of imports)."""
    from continuum_mhe.cli import main

    for option in ("-o", "--record"):
        old = tmp_path / "old.csv"
        old.write_text("t,x\n1,2\n")
        capsys.readouterr()
        assert main(["live", "--port", str(tmp_path / "none"), option, str(old)]) == 2
        assert f"{old}: exists; give --overwrite" in capsys.readouterr().err
        assert old.read_text() == "t,x\n1,2\n"
        # live writes CSV: a name that says MCAP held CSV text the MCAP readers refuse
        other = tmp_path / "new.mcap"
        assert main(["live", "--port", str(tmp_path / "none"), option, str(other)]) == 2
        assert f"{other}: {option} writes CSV (.csv or .txt), not .mcap" in capsys.readouterr().err
        assert not other.exists()


def test_live_refuses_an_output_naming_its_input_without_asking_for_overwrite(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``-o`` or ``--record`` naming the tensions file ``--inputs``: one line saying it is
    an input of the command, with or without ``--overwrite`` (not a request for
    ``--overwrite``, which would be refused next), before the port is opened."""
    from continuum_mhe.cli import main

    shipped = Path(__file__).parents[1] / "src/continuum_mhe/data/tendon/force-29_tensions.csv"
    tensions = tmp_path / "ten.csv"
    tensions.write_bytes(shipped.read_bytes())
    base = ["live", "--port", str(tmp_path / "none"), "--robot", "tendon-two-section"]
    for option in ("-o", "--record"):
        for extra in ([], ["--overwrite"]):
            capsys.readouterr()
            argv = [*base, "--inputs", str(tensions), option, str(tensions), *extra]
            assert main(argv) == 2, argv
            err = capsys.readouterr().err
            assert err.count("\n") == 1, err
            assert "refusing to overwrite the tensions file --inputs" in err, err
            assert tensions.read_bytes() == shipped.read_bytes()


def _two_imu_stream(t0_ms: int, n: int, dt_ms: int = 10) -> list[str]:
    """Raw lines of the two-section robot (s-curve motion), one IMU per section."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.scenarios import simulate_robot

    robot = read_robot("two-section")
    rec = simulate_robot("s-curve", robot, duration=(n - 1) * dt_ms / 1e3, dt=dt_ms / 1e3)
    rng = np.random.default_rng(3)
    lines = []
    for i in range(n):
        acc = np.array([specific_force(rec.z[i, 2 * k], rec.z[i, 2 * k + 1]) for k in range(2)])
        lines.append(raw_line((t0_ms + i * dt_ms) % 2**32, acc, rng.normal(0, 0.01, (2, 3))))
    return lines


def test_a_live_session_that_starts_still_replays_with_its_options(tmp_path: Path) -> None:
    """``live`` estimates from its first sample and takes no gyro biases from a still
    start, as ``estimate`` of a recording does, and records ``still-start = false``: a
    session whose robot rests for 2 s (gyro biases of 0.03 to 0.06 rad/s) before its
    s-curve replays with ``estimate RAW.csv --config EST.csv`` to 1e-9, while ``estimate
    RAW.csv`` alone takes the biases from the rest and says so. ``live --still-start``
    is refused in one line."""
    port, est, raw = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "raw.csv"
    master = new_pty(port)
    moving = _two_imu_stream(200 * 10, 200)
    rng = np.random.default_rng(5)
    bias = np.array([[0.03, -0.04, 0.05], [-0.06, 0.03, 0.04]])
    rest = np.array([specific_force(0.0, 0.0)] * 2)
    lines = [raw_line(i * 10, rest + rng.normal(0, 0.02, (2, 3)),
                      bias + rng.normal(0, 0.002, (2, 3))) for i in range(200)]  # fmt: skip
    for line in moving:  # the same biases in the motion
        t_ms, rest_of_line = line.split(",", 1)
        values = np.array(rest_of_line.split(","), dtype=float).reshape(2, 6)
        values[:, 3:] += bias
        lines.append(raw_line(int(t_ms), values[:, :3], values[:, 3:]))
    header = "# fields: t_ms," + ",".join(
        f"{c}_{k}" for k in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz")
    )
    live = LiveProcess(
        ["--port", str(port), "--robot", "two-section", "--method", "ekf", "-o", str(est)]
        + ["--record", str(raw)]
    )
    chunks = ["# continuum_imu 1.1.0 imus=2\n", header + "\n", *(ln + "\n" for ln in lines)]
    code = send_until_estimated(live, master, chunks, est, len(lines), 0.0005)
    assert code == 143, live.err
    assert "still-start = false" in est.read_text().splitlines()[1]  # the options line
    from continuum_mhe.cli import main

    a = read_state_table(est)
    for extra, same in ((["--config", str(est)], True), ([], False)):
        replay = tmp_path / f"replay{len(extra)}.csv"
        said = io.StringIO()
        with contextlib.redirect_stderr(said):
            assert main(["estimate", str(raw), "-o", str(replay), "--robot", "two-section",
                         "--method", "ekf", *extra]) == 0, said.getvalue()  # fmt: skip
        b = read_state_table(replay)
        assert ("gyro biases from the still start" in said.getvalue()) is not same
        assert bool(np.abs(a.values - b.values).max() <= 1e-9) is same
    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        assert main(["live", "--port", str(port), "--robot", "two-section",
                     "--still-start"]) == 2  # fmt: skip
    assert said.getvalue().startswith("continuum-mhe: error: --still-start: live estimates")


def test_live_record_replays_to_the_same_estimates(tmp_path: Path) -> None:
    """Two raw IMUs through a pty with CR, LF and CRLF line ends, garbage, a 1 MB line
    without a line end, device messages and a millis() wrap; then SIGTERM. The
    recording holds every valid sample, and 'estimate' on it gives the live estimates
    to 1e-9, sample for sample."""
    port, est, raw = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "raw.csv"
    master = new_pty(port)
    lines = _two_imu_stream(2**32 - 1500, 300)  # the device clock wraps after 150 samples
    ends = ["\n", "\r", "\r\n"]
    stream = [
        "# continuum_imu 1.1.0 imus=2\n",
        "# fields: t_ms,"
        + ",".join(f"{c}_{k}" for k in (1, 2) for c in ("ax", "ay", "az", "gx", "gy", "gz"))
        + "\n",
    ]
    for i, line in enumerate(lines):
        stream.append(line + ends[i % 3])
        if i == 40:
            stream.append("\x01\x02garbage,,,\n")
        if i == 80:
            stream.append("y" * 1_000_000)  # 1 MB without a line end, then a newline
            stream.append("\n")
        if i == 120:
            stream.append("# error: I2C read failed\n")
        if i == 200:
            stream.append(lines[i].split(",", 8)[0] + ",1,2\n")  # a line of the wrong length
    live = LiveProcess(
        ["--port", str(port), "--robot", "two-section", "--method", "mhe", "-o", str(est)]
        + ["--record", str(raw), "--status-every", "0.5"]
    )
    code = send_until_estimated(live, master, stream, est, len(lines), 0.001)
    err = live.err
    assert code == 143, err
    assert data_rows(raw) == len(lines) and data_rows(est) == len(lines)
    assert "device clock wrapped" in err and "device says: # error: I2C read failed" in err
    summary = [ln for ln in err.splitlines() if "samples," in ln][-1]
    assert "2 garbled" in summary and "1 over-long" in summary and "0 out of order" in summary
    replay = tmp_path / "replay.csv"
    from continuum_mhe.cli import main  # in this process (a fresh one: 1.5 s of imports)

    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        code = main(["estimate", str(raw), "-o", str(replay), "--robot", "two-section",
                     "--method", "mhe"])  # fmt: skip
    assert code == 0, said.getvalue()
    a, b = read_state_table(est), read_state_table(replay)
    assert a.names == b.names and len(a.t) == len(lines)
    np.testing.assert_allclose(a.t, b.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.values, b.values, rtol=0, atol=1e-9)
    assert list(a.status) == list(b.status)
    assert a.status[0] == "uncertain" and set(a.status[1:]) == {"ok"}
    assert np.all(np.isfinite(a.values))
    assert np.all(np.diff(a.t) > 0) and a.t[0] == pytest.approx((2**32 - 1500) / 1e3)


def test_live_takes_its_port_from_an_options_file_and_records_it(tmp_path: Path) -> None:
    """``port`` in an options file's ``[live]`` table (docs/workflow.md) opens that port;
    the estimate file records it, so that ``--config EST.csv`` runs the session again;
    without a port anywhere, one line says it is required."""
    port, est, cfg = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "opts.toml"
    cfg.write_text(f'method = "ekf"\nrobot = "two-section"\n[live]\nport = "{port}"\n')
    master = new_pty(port)
    live = LiveProcess(["--config", str(cfg), "-o", str(est)])
    lines = _two_imu_stream(1000, 20)
    data = "\n".join(lines) + "\n"
    assert send_until_rows(live, master, data, est, len(lines), signal.SIGINT) == 0, live.err
    assert f"reading {port}" in live.err and data_rows(est) == len(lines)
    assert f'port = "{port}"' in est.read_text().split("\n# model", 1)[0]
    # live keeps the IMUs' constant-curvature frames, and says so for a replay
    assert "imu-twist = false" in est.read_text().split("\n# model", 1)[0]
    res = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "live", "--method", "ekf", "-o", str(est)],
        capture_output=True, text=True, timeout=SAFETY_S,
    )  # fmt: skip
    assert res.returncode == 2
    assert res.stderr == (
        "continuum-mhe: error: --port is required: the serial device (e.g. /dev/ttyACM0), "
        "on the command line or as port in --config\n"
    )


def test_live_says_nothing_is_saved_and_why_no_plot(tmp_path: Path) -> None:
    port = tmp_path / "ttyIMU"
    master = new_pty(port)
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env.pop("MPLBACKEND", None)
    try:
        res = subprocess.run(
            [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(port)]
            + ["--method", "ekf", "--duration", "0.5", "--plot"],
            capture_output=True,
            text=True,
            timeout=SAFETY_S,
            env=env,
        )
    finally:
        os.close(master)
    assert res.returncode == 0, res.stderr
    assert res.stderr.count("nothing is saved") == 1
    if sys.platform.startswith("linux"):
        assert res.stderr.count("--plot needs a display (DISPLAY is not set") == 1


def test_live_without_samples_leaves_an_existing_output_alone(tmp_path: Path) -> None:
    """A session in which no sample arrives leaves an existing -o file as it is, even
    with --overwrite, and says it was not written; so for a --view file (not replaced
    by a view without an estimate, nothing said)."""
    port, out, view = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "v.rrd"
    out.write_text("an earlier session\n")
    view.write_bytes(b"an earlier view")
    master = new_pty(port)
    try:
        res = subprocess.run(
            [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(port)]
            + ["--method", "ekf", "--duration", "0.5", "-o", str(out), "--overwrite"]
            + ["--view", str(view)],
            capture_output=True,
            text=True,
            timeout=SAFETY_S,
        )
    finally:
        os.close(master)
    assert res.returncode == 0, res.stderr
    assert out.read_text() == "an earlier session\n"
    assert f"no sample arrived: {out} not written" in res.stderr
    assert view.read_bytes() == b"an earlier view"
    assert f"no sample arrived: {view} not written" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.csv", "ttyIMU", "v.rrd"]


def test_short_soak_two_imus_500_hz_with_faults(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """tools/live_soak.py with its device driven by sample count, not by the clock: 200
    samples, then garbage, a partial line, a 1 MB line and the port disappearing and
    returning, each after another 200 samples, and 200 more; every valid sample recorded
    and estimated."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "tools"))
    import live_soak

    between = 200

    class CountedDevice(live_soak.Device):
        def run(self) -> None:
            self.t0 = time.monotonic()
            for kind in range(4):  # garbage, partial, mb_line, port_gone
                self._send(self.next_index, self.next_index + between)
                self._fault(kind)  # partial: sends one sample, in pieces
            self._send(self.next_index, self.next_index + between)

        def _send(self, first: int, end: int) -> None:
            """Samples ``first`` to ``end``, 10 ms of them at a time at about the rate."""
            step = max(1, round(self.rate / 100))
            for a in range(first, end, step):
                b = min(a + step, end)
                ms = [round(j * 1000 / self.rate) for j in range(a, b)]
                self._write("".join(map(live_soak._line, ms)).encode())
                self.sent += b - a
                self.sent_ranges.append((a, b, time.monotonic()))
                time.sleep(0.01)
            self.next_index = end

    monkeypatch.setattr(live_soak, "Device", CountedDevice)
    res = live_soak.run_soak(0.0, 500.0, "ekf", "TERM", folder=tmp_path)
    assert res["exit_status"] == 143, res["summary"]
    assert res["faults"] == {"garbage": 1, "partial": 1, "mb_line": 1, "port_gone": 1}
    assert res["sent"] == 5 * between + 1, res["summary"]
    assert res["sent"] == res["recorded_rows"] == res["estimate_rows"], res["summary"]
    assert res["recording_reads_back"] is True
    assert f"{res['faults']['mb_line']} over-long" in res["summary"]


def test_live_with_only_garbled_lines_says_why_and_exits_2(tmp_path: Path) -> None:
    """Live opened after the device's '# fields' banner, without --robot, on two IMUs:
    the first garbled line is said once with its likely cause, and the session ends
    with one error line naming the cause, exit 2, nothing written; the first line, with
    more fields than a line has, counts as garbled, not as the tail of a line."""
    port, out = tmp_path / "ttyIMU", tmp_path / "est.csv"
    master = new_pty(port)
    acc, gyr = np.tile(specific_force(0.1, 0.2), (2, 1)), np.zeros((2, 3))
    live = LiveProcess(["--port", str(port), "--method", "ekf", "--duration", "2", "-o", str(out)])
    lines = [raw_line(1000 + 20 * i, acc, gyr) for i in range(40)]
    code = send_and_finish(live, master, lines)
    first = (
        "expected 7 fields, found 13: a line of 2 IMU(s) in --format raw; --robot with 2 IMU(s)?"
    )
    err = live.err.splitlines()
    assert code == 2, live.err
    said = [
        ln for ln in err if ln.startswith(f"live: garbled line skipped: {first} ({port}, line ")
    ]
    assert len(said) == 1 and said[0].endswith("; said for the first only; all are counted)")
    assert err[-1] == (
        f"continuum-mhe: error: {port}: no valid sample: 40 garbled line(s) "
        f"(the first: {first}); check --format, --robot and --baud"
    )
    assert not out.exists()


def _deg_s_stream(n: int) -> list[str]:
    """``n`` raw lines at 50 Hz whose gyro is in deg/s (median 41 over the first 100)."""
    return [ln.rstrip("\n") for ln in raw_lines(1000, n, gyro_scale=180 / math.pi)]


def _estimate_says(tmp_path: Path, lines: list[str], options: list[str]) -> str:
    """``estimate``'s stderr for ``lines`` as a raw CSV (``t`` in s), its warnings as
    the command line prints them, the file's name replaced by ``PORT``."""
    from continuum_mhe.cli import main

    raw = tmp_path / "same.csv"
    rows = [f"{int(ln.split(',', 1)[0]) / 1e3!r},{ln.split(',', 1)[1]}" for ln in lines]
    raw.write_text("t,ax,ay,az,gx,gy,gz\n" + "\n".join(rows) + "\n")
    out = tmp_path / "same_est.csv"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        main(["estimate", str(raw), "-o", str(out), "--method", "ekf", *options])
    said = "".join(f"continuum-mhe: warning: {w.message}\n" for w in caught) + err.getvalue()
    return said.replace(str(raw), "PORT")


def test_live_stops_on_a_deg_s_gyro_it_uses_with_estimates_message(tmp_path: Path) -> None:
    """With --imu-model direct a deg/s gyro (57 times too fast) stops live at its
    gyro-unit check: the first 100 samples estimated as they arrive, then the summary,
    estimate's one line for the same samples (naming the port) and exit 2, the lines
    queued after them left; the estimates made from those readings are removed (not
    kept, with `ok` rows among them), the recording of the readings kept."""
    from continuum_mhe.live.session import UNIT_CHECK_SAMPLES

    port, out = tmp_path / "ttyIMU", tmp_path / "est.csv"
    master = new_pty(port)
    lines = _deg_s_stream(UNIT_CHECK_SAMPLES + 100)
    args = ["--port", str(port), "--method", "ekf", "--imu-model", "direct"]
    raw = tmp_path / "raw.csv"
    live = LiveProcess([*args, "--duration", "30", "-o", str(out), "--record", str(raw)])
    code = send_and_finish(live, master, lines)
    assert code == 2, live.err  # stopped at the check (the summary below: its samples only)
    err = live.err.splitlines()
    said = _estimate_says(tmp_path, lines[:UNIT_CHECK_SAMPLES], ["--imu-model", "direct"])
    (expected,) = [ln for ln in said.splitlines() if "gyro magnitude" in ln]
    assert expected.startswith("continuum-mhe: error: PORT: gyro magnitude is about 41 ")
    assert err[-1] == expected.replace("PORT", str(port))
    summary = f"live: {UNIT_CHECK_SAMPLES} samples, {UNIT_CHECK_SAMPLES - 1} estimates; "
    assert sum(ln.startswith(summary) for ln in err) == 1, live.err
    removed = (
        f"live: the {UNIT_CHECK_SAMPLES - 1} estimates made from readings in the wrong units "
        f"are not kept: {out} removed ({raw} keeps the readings as received)"
    )
    assert removed in err and not out.exists(), live.err
    assert data_rows(raw) == UNIT_CHECK_SAMPLES - 1
    assert sum("gyro magnitude" in ln for ln in err) == 1


def test_live_stops_on_a_hanging_robot_described_z_up_and_keeps_no_estimate(
    tmp_path: Path,
) -> None:
    """Tilt lines of a hanging robot read with the default (z-up) robot: at its 25th
    sample the mounting check stops live, the summary then estimate's line for such a
    file (naming the port, and the option that fixes it), exit 2; the estimates made
    until then are removed (the 25th a no-estimate row), the recording of the readings
    kept."""
    from continuum_mhe.simulation.scenarios import simulate

    rec = simulate("paper3d", duration=4.0, seed=2, mounting="z-down")
    lines = [f"{round(1000 * t)},{z[0]:.9f},{z[1]:.9f}" for t, z in zip(rec.t, rec.z)]
    port, out, raw = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "rec.csv"
    master = new_pty(port)
    args = ["--port", str(port), "--format", "tilt", "--method", "ekf", "--duration", "30"]
    live = LiveProcess([*args, "-o", str(out), "--record", str(raw)])
    code = send_and_finish(live, master, lines)
    assert code == 2, live.err
    err = live.err.splitlines()
    assert err[-1].startswith(
        f"continuum-mhe: error: {port}: mounting: the robot is described as z-up"
    ), live.err
    assert err[-1].endswith("the robot hangs from its base? give --mounting z-down"), err[-1]
    removed = (
        f"live: the 25 estimates made with the robot described the wrong way up are not "
        f"kept: {out} removed ({raw} keeps the readings as received)"
    )
    assert removed in err and not out.exists(), live.err
    assert data_rows(raw) == 25


def test_live_cli_warns_once_about_a_deg_s_gyro_it_does_not_use(tmp_path: Path) -> None:
    """Tilt from the accelerometer (``--imu-model tilt``): estimate's warning, once, and
    the session goes on to estimate every sample (exit 0)."""
    port, out = tmp_path / "ttyIMU", tmp_path / "est.csv"
    master = new_pty(port)
    lines = _deg_s_stream(300)
    tilt = ["--imu-model", "tilt"]
    live = LiveProcess(["--port", str(port), "--method", "ekf", "-o", str(out), *tilt])
    data = "\n".join(lines) + "\n"
    code = send_until_rows(live, master, data, out, len(lines), signal.SIGINT)
    assert code == 0, live.err
    said = _estimate_says(tmp_path, lines[:100], tilt)
    (expected,) = [ln for ln in said.splitlines() if "gyro magnitude" in ln]
    assert expected.startswith("continuum-mhe: warning: PORT: gyro magnitude is about 41 ")
    assert expected.endswith("these options do not use the gyro, so the estimate is unaffected")
    err = live.err.splitlines()
    assert [ln for ln in err if "gyro magnitude" in ln] == [expected.replace("PORT", str(port))]
    assert any(ln.startswith("live: 300 samples, 300 estimates; ") for ln in err), live.err


@pytest.mark.parametrize(
    ("sig", "code", "last"), [(signal.SIGINT, 2, None), (signal.SIGTERM, 143, "terminated")]
)
def test_live_stopped_by_a_signal_still_says_its_end_of_session_unit_check(
    tmp_path: Path, sig: int, code: int, last: str | None
) -> None:
    """A session shorter than the gyro check's samples, stopped by a signal, still says
    the end-of-session check's deg/s error, as the same run stopped by --duration does:
    the summary, then that error line, not 'interrupted'; exit 2 after Ctrl-C (143
    after SIGTERM, as a service manager expects, the error said first); the rows
    written from those readings are removed, as where the check stops a session."""
    port, out = tmp_path / "ttyIMU", tmp_path / "est.csv"
    master = new_pty(port)
    lines = _deg_s_stream(50)
    live = LiveProcess(["--port", str(port), "--method", "ekf", "--imu-model", "direct",
                        "-o", str(out)])  # fmt: skip
    try:
        live.wait_ready()
        send(master, ("\n".join(lines) + "\n").encode())
        wait_for(lambda: data_rows(out) >= len(lines), "the estimates")
        got = live.finish(sig)
    finally:
        if live.proc.poll() is None:
            live.proc.kill()
        os.close(master)
    assert got == code, live.err
    err = live.err.splitlines()
    if last is not None:
        assert err.pop() == f"continuum-mhe: {last}"
    said = _estimate_says(tmp_path, lines, ["--imu-model", "direct"])  # the same samples
    (expected,) = [ln for ln in said.splitlines() if "gyro magnitude" in ln]
    assert err[-1] == expected.replace("PORT", str(port)) and "interrupted" not in live.err
    assert any(ln.startswith("live: 50 samples, 50 estimates; ") for ln in err), live.err
    assert (
        f"live: the 50 estimates made from readings in the wrong units are not kept: {out} removed"
        in err
    )
    assert not out.exists()


def test_one_ctrl_c_estimates_every_queued_line_with_ipopt(tmp_path: Path) -> None:
    """The MHE on IPOPT defers a signal over each solve; the first Ctrl-C, which stops
    reading and drains the queue, is not raised again by the next solve: every line
    received is estimated (none abandoned), and the recording and the estimates have a
    row per sample. The drain says how far it is at the status lines' interval."""
    port, out, rec = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "rec.csv"
    master = new_pty(port)
    lines = raw_lines(1000, 200)
    live = LiveProcess(["--port", str(port), "--solver", "ipopt", "--horizon", "10",
                        "-o", str(out), "--record", str(rec), "--status-every", "0.2"])  # fmt: skip
    try:
        live.wait_ready()
        send(master, "".join(lines).encode())
        wait_for(lambda: data_rows(out) >= 3, "the first estimates")
        got = live.finish(signal.SIGINT)
    finally:
        if live.proc.poll() is None:
            live.proc.kill()
        os.close(master)
    assert got == 0, live.err
    queued = re.search(r"stopping; estimating (\d+) queued line", live.err)
    assert queued is not None and int(queued.group(1)) >= 100, live.err  # a queue to drain
    progress = [
        (int(a), int(b))
        for a, b in re.findall(r"estimated (\d+) queued line\(s\), (\d+) still queued", live.err)
    ]
    assert progress, live.err
    done = [a for a, _ in progress]  # lines estimated since the stop, as it goes
    assert done == sorted(set(done)) and 0 < done[-1] < len(lines), live.err
    assert all(a + b <= len(lines) for a, b in progress), live.err
    assert "abandoned" not in live.err, live.err
    assert data_rows(out) == data_rows(rec) == len(lines), live.err


def test_a_second_ctrl_c_abandons_the_queue_between_two_lines(tmp_path: Path) -> None:
    """The second Ctrl-C, while the first one's drain estimates the queue with IPOPT
    (most of a line's time is its solve), abandons the queue after the line it came in,
    not inside it: no estimate is left ``no-estimate``, the lines it abandoned are
    recorded all the same (``--record`` keeps every sample received), and it says how
    many it abandoned."""
    port, out, rec = tmp_path / "ttyIMU", tmp_path / "est.csv", tmp_path / "rec.csv"
    master = new_pty(port)
    lines = raw_lines(1000, 200)
    live = LiveProcess(["--port", str(port), "--solver", "ipopt", "--horizon", "10",
                        "-o", str(out), "--record", str(rec)])  # fmt: skip
    try:
        live.wait_ready()
        send(master, "".join(lines).encode())
        wait_for(lambda: data_rows(out) >= 3, "the first estimates")
        live.proc.send_signal(signal.SIGINT)
        wait_for(lambda: "stopping; estimating" in live.err, "the drain")
        time.sleep(0.3)  # some lines into it, inside a solve
        got = live.finish(signal.SIGINT)
    finally:
        if live.proc.poll() is None:
            live.proc.kill()
        os.close(master)
    assert got == 0, live.err  # a stop asked for, as with one Ctrl-C
    said = re.search(
        r"abandoned the estimates of (\d+) received line\(s\); their samples are recorded "
        rf"in {re.escape(str(rec))}",
        live.err,
    )
    assert said, live.err
    # the recording keeps every sample received, the abandoned ones too
    assert 3 <= data_rows(out) < data_rows(rec) == data_rows(out) + int(said[1]), live.err
    statuses = [ln.rsplit(",", 2)[-2:] for ln in out.read_text().splitlines()[1:]]
    assert not any("no-estimate" in row for row in statuses), live.err


def test_the_latency_quantiles_say_where_they_are_beyond_the_histogram() -> None:
    """Known answers: a latency's quantile is the upper edge of its bin (2.3 % wide); one
    beyond the histogram's last edge (100 s: a session that fell minutes behind) is said
    as over it, not as the edge itself."""
    from continuum_mhe.live.counts import LatencyHistogram

    h = LatencyHistogram()
    assert math.isnan(h.quantile(0.5))
    for ms in (10.0, 10.0, 10.0, 250_000.0):
        h.add(ms)
    assert h.quantile(0.5) == pytest.approx(10.0, rel=0.024) and h.quantile(0.5) >= 10.0
    assert h.text(0.5).endswith(" ms") and not h.text(0.5).startswith("over")
    assert math.isinf(h.quantile(0.99)) and h.text(0.99) == "over 100000 ms"


def test_live_warms_its_estimator_up_before_it_opens_the_port(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """The port opens after the estimator is built and warmed up, so that a device that
    streams from the start has no lines waiting meanwhile (1.5 s on a tendon robot, a
    false "falling behind" at every start, lines lost where the port's buffer fills)."""
    import continuum_mhe.cli.live as live_cli
    from continuum_mhe.cli import main

    order: list[str] = []
    real_warm_up = live_cli.warm_up

    def warm_up(*args: object) -> None:
        order.append("warm-up")
        real_warm_up(*args)  # type: ignore[arg-type]

    def open_port(port: str, baud: int) -> None:
        order.append("open")
        raise OSError("no such port (the test stops here)")

    monkeypatch.setattr(live_cli, "warm_up", warm_up)
    monkeypatch.setattr(live_cli, "open_port", open_port)
    assert main(["live", "--port", str(tmp_path / "ttyIMU"), "--method", "ekf"]) == 2
    assert order == ["warm-up", "open"]


def test_the_firmware_header_of_a_tendon_robot_names_what_to_change(tmp_path: Path) -> None:
    """The IMU firmware's ``# fields:`` line, forwarded as it is by a controller that adds
    the tensions to the lines, names the IMUs' fields alone: live says that the tensions
    are missing from it (not to check --format and --robot, which are right); a header
    that names the tensions where --inputs gives them says that instead."""
    from continuum_mhe.estimators import make_estimator
    from continuum_mhe.io.input_options import InputOptions
    from continuum_mhe.io.inputs import serial_input
    from continuum_mhe.io.robot_file import read_robot, shipped_robots
    from continuum_mhe.live.session import LiveSession, LiveSettings
    from continuum_mhe.model.registry import make_formulation
    from continuum_mhe.settings import MHESettings, NoiseSettings

    base = make_formulation(
        "bend", read_robot(shipped_robots()["tendon-two-section"]), NoiseSettings()
    )
    imus = ",".join(f"{a}_{i}" for i in (1, 2) for a in ("ax", "ay", "az", "gx", "gy", "gz"))
    board = f"# fields: t_ms,{imus} (ms, m/s^2, rad/s; sensor frames)\r".encode()
    tensions = ",".join(f"tension_{k}" for k in range(1, 7))
    merged = f"# fields: t_ms,{imus},{tensions}".encode()
    inputs = tmp_path / "tensions.csv"
    inputs.write_text(
        f"t,{tensions}\n" + "".join(f"{t},0.2,0.3,0.2,0.3,0.2,0.3\n" for t in range(3))
    )

    def said_to(header: bytes, options: InputOptions) -> str:
        said: list[str] = []
        serial = serial_input("/dev/ttyTEN", "raw", options, base)
        est = make_estimator("ekf", serial.formulation, MHESettings())
        s = LiveSession(
            LiveSettings(port="/dev/ttyTEN"), est, serial.converters, None, said.append,
            None, serial.tensions,
        )  # fmt: skip
        s.handle_line(header, time.monotonic())
        return "\n".join(m for m in said if not m.startswith("device says"))

    on_line, from_file = InputOptions(), InputOptions(tensions=str(inputs))
    first = said_to(board, on_line)
    assert "names 13 fields" in first and "expects 19" in first, first
    assert "it names no tendon tensions" in first and "check --format" not in first, first
    assert said_to(merged, on_line) == ""  # the controller named its tensions too
    second = said_to(merged, from_file)
    assert "which --inputs gives too" in second and "check --format" not in second, second
    assert said_to(board, from_file) == ""


def test_the_live_plot_traces_the_estimated_tip_and_shows_a_robot_bent_below_its_base() -> None:
    """``live --plot`` traces the estimate's own tip (``x, y, z``), not the end of the
    arcs it draws from the bends: a tendon robot's tip under load lies off the arcs of
    its equivalent bends. A robot whose sections together bend past 90 degrees is drawn
    below its base too."""
    import matplotlib

    matplotlib.use("Agg")
    from continuum_mhe.live.run import LivePlot
    from continuum_mhe.model.tendon import tendon_outputs
    from continuum_mhe.results import Estimate

    outputs = tendon_outputs(2)
    row = np.zeros(len(outputs))
    named = {o.name: i for i, o in enumerate(outputs)}
    row[named["theta_1"]], row[named["theta_2"]] = 0.4, 0.3
    row[[named["x"], named["y"], named["z"]]] = (-0.05, 0.01, 0.27)  # off the arcs' end
    plot = LivePlot((0.16, 0.14), (3.0, 3.0))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # Agg cannot show the window
        plot.update(Estimate(0.0, None, row, None, "ok", 0.1), outputs)
    np.testing.assert_array_equal(plot.tips[-1], [-0.05, 0.01, 0.27])
    body = np.asarray(plot.body.get_data_3d())
    assert np.linalg.norm(body[:, -1] - [-0.05, 0.01, 0.27]) > 0.01  # the arcs end elsewhere
    assert plot.ax.get_zlim()[0] == pytest.approx(-0.3)
    assert LivePlot((0.2,), (1.5,)).ax.get_zlim()[0] == 0.0
    assert LivePlot((0.1, 0.1, 0.1), (1.0, 1.0, 1.0)).ax.get_zlim()[0] == pytest.approx(-0.3)
    matplotlib.pyplot.close("all")


def test_live_weighs_the_imus_twist_only_where_neither_twist_option_is_given(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """As ``estimate``, which weighs the twist only where neither ``--imu-twist`` nor
    ``--no-imu-twist`` is given: live of the shipped ``spatial`` rod (its tip IMU twists
    up to 122 degrees), calibrated, warns that the readings show the twist, and is
    silent with ``--no-imu-twist``, the constant-curvature frames asked for."""
    import continuum_mhe.cli.live as live_cli
    from continuum_mhe.cli import main
    from continuum_mhe.live.session import LiveSession

    rod = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
    cal = tmp_path / "cal.toml"
    assert main(["calibrate", "--from", str(rod / "spatial_rest.csv"), "--robot",
                 "two-section", "--write-robot", str(cal)]) == 0  # fmt: skip
    lines = []
    for row in (rod / "spatial_raw.csv").read_text().splitlines()[1:]:
        t, rest = row.split(",", 1)
        lines.append(f"{round(float(t) * 1000)},{rest}".encode())

    def run_live(settings: object, session: LiveSession, *rest: object) -> int:
        now = time.monotonic()
        for i, line in enumerate(lines):
            session.handle_line(line, now + 0.001 * i)
        session.finish()
        print(session.summary(), file=sys.stderr)
        return 0

    monkeypatch.setattr(live_cli, "open_port", lambda port, baud: object())
    monkeypatch.setattr(live_cli, "run_live", run_live)
    said = "the readings show the IMUs turning about the backbone"
    base = ["live", "--port", "/dev/ttyIMU", "--robot", str(cal), "--method", "ekf"]
    capsys.readouterr()
    assert main(base) == 0
    assert said in capsys.readouterr().err
    assert main([*base, "--no-imu-twist"]) == 0
    assert said not in capsys.readouterr().err
