"""Input read once (pipes, FIFOs, ``-``, ``/dev/stdin``) and CSV dialects (``#``
comments, ``t_ms``, ``;`` and tab, a plain serial capture), with one-line errors."""

from __future__ import annotations

import contextlib
import json
import math
import os
import subprocess
import sys
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest
from live_helpers import SAFETY_S, unblock_fifo_reader

from continuum_mhe.cli import main
from continuum_mhe.errors import InputError
from continuum_mhe.io.csv_files import UnitWarning, read_measurements
from continuum_mhe.io.inputs import CHUNK
from continuum_mhe.io.raw_imu import read_raw_imu
from continuum_mhe.io.state_tables import read_state_table, read_states
from continuum_mhe.io.text_rows import MAX_LINE_BYTES
from continuum_mhe.simulation.scenarios import simulate

CLI = [sys.executable, "-m", "continuum_mhe.cli"]


def _csv(n: int = 30, sep: str = ",", t_ms: bool = False) -> str:
    rec = simulate("paper3d", duration=(n - 1) * 0.05, dt=0.05, seed=1)
    t = rec.t * 1e3 if t_ms else rec.t
    head = sep.join(["t_ms" if t_ms else "t", "roll", "pitch"])
    rows = [sep.join(f"{v:.6f}" for v in (a, r, p)) for a, (r, p) in zip(t, rec.z)]
    return "\n".join([head, *rows]) + "\n"


def _estimate_rows(path: Path) -> list[str]:
    """The data rows of an estimate CSV (after its comment lines and column line)."""
    return [ln for ln in path.read_text().splitlines() if not ln.startswith("#")][1:]


def _feed(path: str, text: str) -> threading.Thread:
    """Write ``text`` into a FIFO or pipe from another thread (the reader opens it)."""

    def run() -> None:
        with open(path, "w") as fh:
            fh.write(text)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th


def test_named_fifo_is_read_once(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    th = _feed(str(fifo), _csv())
    out = tmp_path / "e.csv"
    # a command that opened the FIFO again, after its writer left, would wait for ever:
    # the guard ends that wait, and the test fails
    fired = threading.Event()

    def unblock() -> None:
        fired.set()
        unblock_fifo_reader(fifo)

    guard = threading.Timer(SAFETY_S, unblock)
    guard.start()
    try:
        assert main(["estimate", str(fifo), "-o", str(out), "--method", "ekf"]) == 0
    finally:
        guard.cancel()
    assert not fired.is_set(), "the command opened the FIFO a second time"
    th.join(5)
    assert len(_estimate_rows(out)) == 30
    assert "wrote 30 estimates" in capsys.readouterr().err


def test_pipe_as_dev_fd_like_process_substitution(tmp_path: Path) -> None:
    r, w = os.pipe()
    data = _csv().encode()

    def feed() -> None:
        with os.fdopen(w, "wb") as fh:  # closing the only write end gives the reader EOF
            fh.write(data)

    th = threading.Thread(target=feed, daemon=True)
    th.start()
    out = tmp_path / "e.csv"
    try:
        assert main(["estimate", f"/dev/fd/{r}", "-o", str(out), "--method", "ekf"]) == 0
    finally:
        th.join(5)
        os.close(r)
    assert len(_estimate_rows(out)) == 30


def test_dash_reads_standard_input(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    r, w = os.pipe()
    os.write(w, _csv().encode())
    os.close(w)
    with os.fdopen(r) as stdin:
        monkeypatch.setattr(sys, "stdin", stdin)
        out = tmp_path / "e.csv"
        assert main(["estimate", "-", "-o", str(out), "--method", "ekf"]) == 0
    assert len(_estimate_rows(out)) == 30


@pytest.mark.parametrize("source", ["-", "/dev/stdin"])
def test_shell_pipe_into_estimate(tmp_path: Path, source: str) -> None:
    meas = tmp_path / "m.csv"
    meas.write_text(_csv())
    out = tmp_path / "e.csv"
    with meas.open("rb") as fh:
        proc = subprocess.run(
            [*CLI, "estimate", source, "-o", str(out), "--method", "ekf"],
            stdin=fh,
            capture_output=True,
            text=True,
            timeout=120,
        )
    assert proc.returncode == 0, proc.stderr
    assert len(_estimate_rows(out)) == 30


@pytest.mark.parametrize("sep", [";", "\t"])
def test_semicolon_and_tab_separators(tmp_path: Path, sep: str) -> None:
    plain = read_measurements(_write(tmp_path / "a.csv", _csv()))
    other = read_measurements(_write(tmp_path / "b.csv", _csv(sep=sep)))
    np.testing.assert_array_equal(plain.t, other.t)
    np.testing.assert_array_equal(plain.z, other.z)


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_comments_anywhere_and_t_ms(tmp_path: Path) -> None:
    plain = read_measurements(_write(tmp_path / "a.csv", _csv()))
    lines = _csv(t_ms=True).splitlines()
    text = "\n".join(["# continuum_imu 1.0.0 mpu9250", lines[0], "# mid", *lines[1:]]) + "\n"
    got = read_measurements(_write(tmp_path / "b.csv", text))
    np.testing.assert_allclose(got.t, plain.t, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(got.z, plain.z)


def test_plain_serial_capture_reads_as_raw_csv(tmp_path: Path) -> None:
    text = (
        "# continuum_imu 1.0.0 mpu9250 who_am_i=0x71 rate_hz=100 baud=115200\n"
        "# format: t_ms,ax,ay,az,gx,gy,gz (ms, m/s^2, rad/s; sensor frame)\n"
        "# calibrating gyro bias: keep the robot still\n"
        "1532,0.123,-0.045,9.811,0.0012,-0.0003,0.0001\n"
        "1542,0.125,-0.044,9.810,0.0011,-0.0002,0.0001\n"
    )
    table = read_raw_imu(_write(tmp_path / "cap.txt", text))
    np.testing.assert_allclose(table.t, [1.532, 1.542])
    np.testing.assert_allclose(table.acc[0], [0.123, -0.045, 9.811])
    out = tmp_path / "e.csv"
    assert main(["estimate", str(tmp_path / "cap.txt"), "-o", str(out), "--method", "ekf"]) == 0
    assert _estimate_rows(out)[0].startswith("1.532,")


def test_states_table_with_t_ms(tmp_path: Path) -> None:
    p = _write(tmp_path / "s.csv", "t_ms,x,y,z,theta,phi\n1000,0,0,0.2,0,0\n1050,0,0,0.2,0,0\n")
    t, _, _ = read_states(p)
    np.testing.assert_allclose(t, [1.0, 1.05])


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("t roll pitch\n0 0.1 0.1\n", "read as comma"),
        ("t;roll;pitch\n0;0,1;0,1\n", "a decimal comma?"),
        (
            "t,roll,pitch\n0,0.1,0.1\nt,roll,pitch\n0.05,0.1,0.1\n",
            "line 3: column t: 't' is not a number (the header again: two files joined?)",
        ),
        ("0,0.1,0.1\n0.05,0.1,0.1\n", "no header line"),
        ("# only a comment\n", "only comments"),
        ("x" * (MAX_LINE_BYTES + 10), f"longer than {MAX_LINE_BYTES}"),
    ],
)
def test_dialect_errors_are_one_line(tmp_path: Path, text: str, needle: str) -> None:
    with pytest.raises(InputError) as info:
        read_measurements(_write(tmp_path / "m.csv", text))
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_dev_zero_gives_one_line(tmp_path: Path) -> None:
    proc = subprocess.run(
        [*CLI, "estimate", "/dev/zero", "-o", str(tmp_path / "e.csv")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "line 1: contains a NUL byte" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_t_in_milliseconds_warns_with_the_cause(tmp_path: Path) -> None:
    text = _csv().replace("t,roll", "t,roll")
    lines = text.splitlines()
    ms = [lines[0]] + [
        ",".join([f"{float(r.split(',')[0]) * 1e3:.0f}", *r.split(",")[1:]]) for r in lines[1:]
    ]
    path = _write(tmp_path / "m.csv", "\n".join(ms) + "\n")
    with pytest.warns(UnitWarning, match="name the column t_ms"):
        read_measurements(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read_measurements(_write(tmp_path / "s.csv", _csv()))  # seconds: no warning


def test_not_utf8_names_its_line(tmp_path: Path) -> None:
    path = tmp_path / "m.csv"
    path.write_bytes(b"t,roll,pitch\n0,0.1,0.1\n\xff\xfe,0.1,0.1\n")
    with pytest.raises(InputError, match=r"m.csv: line 3: not UTF-8 text"):
        read_measurements(path)


def test_text_in_windows_1252_names_the_byte_and_the_conversion(tmp_path: Path) -> None:
    """A comment saved in an 8-bit encoding (a degree sign as Windows-1252's 0xB0):
    one line naming the byte, what it reads as there, and the conversion to UTF-8; a
    binary file's bytes are not given that advice."""
    path = tmp_path / "m.csv"
    path.write_bytes(b"# sensor at 25\xb0C\nt,roll,pitch\n0,0.1,0.1\n")
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert str(info.value) == (
        f"{path}: line 1: not UTF-8 text: byte 15 of the line, 0xB0 ('°' in "
        "Windows-1252), text saved in an 8-bit encoding; save it as UTF-8 (iconv -f CP1252 "
        f"-t UTF-8 {path} > NEW.csv)"
    )
    path.write_bytes(b"t,roll,pitch\n0,0.1,0.1\n\xff\x01\x02,0.1\n")
    with pytest.raises(InputError, match=r"line 3: not UTF-8 text \(a binary file\?\)$"):
        read_measurements(path)


@pytest.mark.parametrize("tail", [b"\x00" * 40, b"0.1,0.1\x00\x00\x00", b"\x00\x00\n\x00"])
def test_nul_bytes_a_logger_left_at_the_end_name_the_lines_to_keep(
    tmp_path: Path, tail: bytes
) -> None:
    """A logger that stopped or restarted mid-write pads a line with NUL bytes: one line
    saying so, with the command that removes them; a NUL byte inside a line stays a
    binary file's."""
    path = tmp_path / "m.csv"
    path.write_bytes(b"t,roll,pitch\n0,0.1,0.1\n0.05,0.1,0.1\n" + tail)
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert str(info.value) == (
        f"{path}: line 4: ends in NUL bytes, as a logger that stopped or restarted mid-write "
        f"leaves them: remove them (tr -d '\\000' < {path} > NEW.csv; a line they cut short "
        "is then refused, or skipped with --skip-bad)"
    )
    path.write_bytes(b"t,roll,pitch\n0,0.1,0.1\n0.05,\x000.1,0.1\n")
    with pytest.raises(InputError, match=r"line 3: contains a NUL byte \(a binary file"):
        read_measurements(path)


def test_sigterm_while_waiting_on_an_idle_pipe_ends_at_once(tmp_path: Path) -> None:
    import signal

    from live_helpers import blocked_reading, open_fifo_writer, temporary_bytes, wait_for

    fifo = tmp_path / "in.fifo"
    os.mkfifo(fifo)
    out = tmp_path / "e.csv"
    proc = subprocess.Popen(
        [*CLI, "estimate", str(fifo), "-o", str(out), "--method", "ekf"],
        stderr=subprocess.PIPE,
        text=True,
    )
    with open_fifo_writer(fifo, lambda: proc.poll() is None) as writer:
        writer.write(_csv(CHUNK + 10))  # one chunk is estimated, then it waits for more
        writer.flush()
        sizes: list[int] = []

        def waiting_for_input() -> bool:
            """Estimates written (the first chunk's), then blocked reading the FIFO; where
            /proc cannot tell (macOS), the output unchanged for 1 s stands in for it."""
            sizes.append(temporary_bytes(tmp_path, "e.csv"))
            blocked = blocked_reading(proc.pid, fifo) if sizes[-1] > 100_000 else False
            if blocked is None:
                blocked = len(sizes) > 50 and len(set(sizes[-50:])) == 1
            return blocked or proc.poll() is not None

        wait_for(waiting_for_input, "the command to wait for more input")
        assert proc.poll() is None, proc.communicate(timeout=SAFETY_S)[1]
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)  # the writer is still open: no EOF
    assert proc.returncode == 143, err
    # the rows estimated before the signal are kept, the file marked partial
    *_, kept, last = err.strip().splitlines()
    assert last == "continuum-mhe: terminated"
    t, _, status = read_states(out)
    n = len(t)
    assert n >= 1 and status[0] == "uncertain" and set(status[1:]) <= {"ok"}
    np.testing.assert_allclose(t, read_measurements(_write(tmp_path / "m.csv", _csv(n))).t)
    assert kept == (
        f"continuum-mhe: kept the {n} estimates made before the interruption in {out}, "
        "marked '# partial = ...'"
    )
    assert out.read_text().splitlines()[-1] == (
        f'# partial = "interrupted after {n} samples, at t = {t[-1]:g} s"'
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.csv", "in.fifo", "m.csv"]


def test_raw_t_in_milliseconds_warns(tmp_path: Path) -> None:
    rows = [f"{1000 + 10 * i},0.1,0.0,9.8" for i in range(5)]
    path = _write(tmp_path / "raw.csv", "\n".join(["t,ax,ay,az", *rows]) + "\n")
    with pytest.warns(UnitWarning, match="name the column t_ms"):
        read_raw_imu(path)
    ms = _write(tmp_path / "raw_ms.csv", "\n".join(["t_ms,ax,ay,az", *rows]) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(read_raw_imu(ms).t, [1.0, 1.01, 1.02, 1.03, 1.04])


def test_estimate_refuses_t_in_milliseconds_where_every_sample_restarts(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A t in milliseconds, where every sample after the first would restart the
    estimator (a file of ``reset`` rows): one line naming the fix (the time unit's
    warning, which it repeats, held back), exit 2, nothing written; with --gap-reset 0
    the estimate is written, with the warning."""
    from continuum_mhe.cli import main

    lines = _csv().splitlines()
    ms = [lines[0]] + [
        ",".join([f"{float(r.split(',')[0]) * 1e3:.0f}", *r.split(",")[1:]]) for r in lines[1:]
    ]
    path = _write(tmp_path / "m.csv", "\n".join(ms) + "\n")
    out = tmp_path / "e.csv"
    code = main(["estimate", str(path), "-o", str(out)])
    n = len(lines) - 1
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.strip().endswith(
        f"m.csv: {n - 1} of {n} samples restarted the estimator after a gap longer than "
        "--gap-reset 1 s: t must be in seconds: if in milliseconds, name the column t_ms; "
        "if in microseconds or nanoseconds, give seconds (else raise --gap-reset, or 0: "
        "never); nothing written"
    )
    # told to: the estimate is written, and the time unit's warning said before its summary
    assert main(["estimate", str(path), "-o", str(out), "--gap-reset", "0"]) == 0
    err = capsys.readouterr().err
    assert "t advances by a median of" in err and "name the column t_ms" in err


@pytest.mark.parametrize(("gaps", "refused"), [(15, False), (16, True)])
def test_estimate_refuses_a_recording_where_most_samples_restart_after_a_gap(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], gaps: int, refused: bool
) -> None:
    """The refusal's threshold: of 30 samples, 15 that each follow a gap longer than
    --gap-reset (half of them) are estimated and written; 16 (more than half) are
    refused in one line, exit 2, nothing written."""
    from continuum_mhe.cli import main

    lines = _csv(30).splitlines()
    rows = []
    for i, r in enumerate(lines[1:]):
        t = 0.05 * i + 2.0 * min(i, gaps)  # samples 1 to gaps each 2 s after the one before
        rows.append(",".join([f"{t:.6f}", *r.split(",")[1:]]))
    path = _write(tmp_path / "gaps.csv", "\n".join([lines[0], *rows]) + "\n")
    out = tmp_path / "e.csv"
    code = main(["estimate", str(path), "-o", str(out), "--method", "ekf"])
    err = capsys.readouterr().err
    if refused:
        assert code == 2 and not out.exists()
        assert err.count("\n") == 1, err
        assert f"gaps.csv: {gaps} of 30 samples restarted the estimator after a gap" in err
    else:
        assert code == 0 and len(_estimate_rows(out)) == 30, err
        assert "samples restarted the estimator after a gap" not in err


def _raw_recording(path: Path, dt: float, duration: float, scale: float, column: str) -> Path:
    """A two-section raw recording (``simulate spatial --imu raw``) at ``dt`` s, its times
    multiplied by ``scale`` in a column named ``column``."""
    made = path.with_name(f"{path.stem}_made.csv")
    args = ["simulate", "spatial", "--robot", "two-section", "--imu", "raw", "--dt", str(dt)]
    assert main([*args, "--duration", str(duration), "-o", str(made)]) == 0
    lines = made.read_text().splitlines()
    rows = [",".join([repr(float(r.split(",")[0]) * scale), *r.split(",")[1:]]) for r in lines[1:]]
    path.write_text("\n".join([column + lines[0][1:], *rows]) + "\n")
    return path


@pytest.mark.parametrize(
    ("scale", "column", "says"),
    [
        (
            1e3,
            "t",
            "t looks like milliseconds: name the column t_ms (t is read in seconds; "
            "microseconds: divide them by 1000 first)",
        ),
        (1e6, "t_ms", "t_ms looks like microseconds: give milliseconds"),
    ],
)
def test_raw_times_a_thousand_times_too_long_are_told_by_the_gyros(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], scale: float, column: str, says: str
) -> None:
    """A 1 kHz raw recording with its times in milliseconds read as seconds steps by 1 s
    a sample, as a 1 Hz recording does (no gap restarts it), which, estimated, would
    leave no row `ok` and a warning blaming the robot file. The gyros turn the gravity
    direction over a second far from where the accelerometers show it next, over a
    millisecond onto it: one line, exit 2, nothing written. The same with ``t_ms`` in
    microseconds."""
    path = _raw_recording(tmp_path / "k.csv", 0.001, 2.0, scale, column)
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(path), "-o", str(out), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("continuum-mhe: error: ") and err.endswith(says), err
    assert "\n" not in err and not out.exists()
    good = _raw_recording(tmp_path / "g.csv", 0.001, 2.0, scale * 1e-3, column)
    assert main(["estimate", str(good), "-o", str(out), "--robot", "two-section"]) == 0


def test_raw_times_in_milliseconds_at_100_hz_are_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 100 Hz raw recording with its times in milliseconds read as seconds steps by
    10 s a sample, which the reader warns of as it reads; the gyros then show the unit,
    and the refusal is the one line (the warning is not said before it)."""
    path = _raw_recording(tmp_path / "c.csv", 0.01, 4.0, 1e3, "t")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(path), "-o", str(out), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "t looks like milliseconds: name the column t_ms" in err, err
    assert not out.exists()


def test_a_refusal_for_another_fault_keeps_the_time_units_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Times in milliseconds and gyros in deg/s: the gyros' refusal is said, and the
    warning that t steps like milliseconds before it (the second fault, so that fixing
    the first does not meet it as a surprise)."""
    path = _raw_recording(tmp_path / "d.csv", 0.01, 4.0, 1e3, "t")
    lines = path.read_text().splitlines()
    names = lines[0].split(",")
    gyro = [i for i, n in enumerate(names) if n.startswith("g")]
    rows = []
    for line in lines[1:]:
        v = line.split(",")
        rows.append(",".join(repr(math.degrees(float(x))) if i in gyro else x
                             for i, x in enumerate(v)))  # fmt: skip
    path.write_text("\n".join([lines[0], *rows]) + "\n")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(path), "-o", str(out), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "t advances by a median of" in err[0] and "name the column t_ms" in err[0], err
    assert err[-1].startswith("continuum-mhe: error: ") and "deg/s" in err[-1], err
    assert not out.exists()


def test_a_still_start_longer_than_a_block_does_not_hide_milliseconds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """5 s of rest at 1 kHz (more than the 4,096 rows of the first block read) before
    the motion, times in milliseconds read as seconds: the rest gives no evidence, the
    motion after it does, and the file is refused as a whole one is."""
    moving = _raw_recording(tmp_path / "k.csv", 0.001, 2.0, 1e3, "t").read_text().splitlines()
    first = moving[1].split(",")
    still = [v if h.startswith("a") else "0.0" for h, v in zip(moving[0].split(","), first)]
    rest = [",".join([repr(float(k)), *still[1:]]) for k in range(5000)]  # gyros at rest
    rows = [
        ",".join([repr(5000.0 + float(r.split(",")[0])), *r.split(",")[1:]]) for r in moving[1:]
    ]
    path = tmp_path / "still.csv"
    path.write_text("\n".join([moving[0], *rest, *rows]) + "\n")
    out = tmp_path / "e.csv"
    capsys.readouterr()
    assert main(["estimate", str(path), "-o", str(out), "--robot", "two-section"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.endswith(
        "t looks like milliseconds: name the column t_ms (t is read in seconds; microseconds: "
        "divide them by 1000 first)"
    )
    assert not out.exists()


def test_gyros_that_read_more_than_the_imu_turns_are_not_taken_for_milliseconds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Readings in seconds whose gyro turns more than the accelerometer shows, for
    another reason than the time's unit: a resting IMU at 1 Hz with an uncalibrated
    consumer gyro's bias (15, -10, 5 deg/s), and a 100 Hz recording whose gyro, unused
    by ``--imu-model tilt``, is in deg/s (warned of). Neither has the accelerometer
    follow the gyro's turn over a thousandth of the steps: both are read."""
    from continuum_mhe.io.raw_units import time_unit_problem

    rng = np.random.default_rng(0)
    t = np.arange(0.0, 120.0, 1.0)
    acc = np.array([0.5, -0.3, 9.78]) + rng.normal(0, 0.03, (len(t), 3))
    gyr = np.radians([15.0, -10.0, 5.0]) + rng.normal(0, 0.005, (len(t), 3))
    assert time_unit_problem(t, acc, gyr) is None
    degrees = _raw_recording(tmp_path / "d.csv", 0.01, 10.0, 1.0, "t")
    lines = degrees.read_text().splitlines()
    header = lines[0].split(",")
    gyro = [i for i, h in enumerate(header) if h.startswith("g")]
    rows = [r.split(",") for r in lines[1:]]
    for r in rows:
        for i in gyro:
            r[i] = repr(math.degrees(float(r[i])))
    degrees.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    out = tmp_path / "e.csv"
    args = ["estimate", str(degrees), "-o", str(out), "--robot", "two-section"]
    with pytest.warns(UnitWarning, match="deg/s"):
        assert main([*args, "--imu-model", "tilt"]) == 0


def test_t_in_microseconds_read_as_seconds_warns(tmp_path: Path) -> None:
    """The log's rule (check_time_steps), in a CSV: steps under 0.1 ms are another unit."""
    lines = _csv().splitlines()
    us = [lines[0]] + [
        ",".join([f"{float(r.split(',')[0]) * 1e-6!r}", *r.split(",")[1:]]) for r in lines[1:]
    ]
    with pytest.warns(UnitWarning, match=r"samples per second\); t must be in seconds$"):
        read_measurements(_write(tmp_path / "m.csv", "\n".join(us) + "\n"))


@pytest.mark.parametrize(
    ("column", "scale", "said"),
    [
        (
            "t_ms",
            1.0,
            r"t_ms advances by a median of 5e-05 s per sample \(2e\+04 samples per "
            r"second\); t_ms must be in milliseconds: seconds\? name the column t$",
        ),
        (
            "t_ms",
            1e6,
            r"t_ms advances by a median of 50 s per sample; t_ms must be in "
            r"milliseconds: microseconds\? give milliseconds$",
        ),
        (
            "t",
            1e6,
            r"t advances by a median of 50000 s per sample; t is read in seconds: if it is in "
            r"milliseconds, name the column t_ms; if in microseconds or nanoseconds, give seconds$",
        ),
    ],
)
def test_a_time_column_in_another_unit_is_named_with_its_own_fix(
    tmp_path: Path, column: str, scale: float, said: str
) -> None:
    """Seconds in a ``t_ms`` column, microseconds in ``t_ms`` or in ``t``: the warning
    names the column's unit and the fix that fits it (not "name the column t_ms" for a
    column so named)."""
    lines = _csv().splitlines()
    header = lines[0].replace("t,", f"{column},", 1)
    rows = [",".join([f"{float(r.split(',')[0]) * scale!r}", *r.split(",")[1:]])
            for r in lines[1:]]  # fmt: skip
    with pytest.warns(UnitWarning, match=said):
        read_measurements(_write(tmp_path / "m.csv", "\n".join([header, *rows]) + "\n"))


def test_microseconds_in_a_t_ms_column_are_refused_naming_that_column(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A ``t_ms`` column in microseconds restarts at every sample: the refusal names the
    column's own unit, not a rename to the name it has."""
    lines = _csv().splitlines()
    header = lines[0].replace("t,", "t_ms,", 1)
    rows = [",".join([f"{float(r.split(',')[0]) * 1e6!r}", *r.split(",")[1:]])
            for r in lines[1:]]  # fmt: skip
    path = _write(tmp_path / "m.csv", "\n".join([header, *rows]) + "\n")
    assert main(["estimate", str(path), "-o", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err  # one line: the time unit's warning is in it
    assert err.strip().endswith(
        "--gap-reset 1 s: t_ms must be in milliseconds: microseconds? (else raise "
        "--gap-reset, or 0: never); nothing written"
    )


def _piped_into(text: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """Standard input a pipe that gives ``text`` (written from a thread: the pipe may hold
    less than a whole estimate; one a command refuses unread ends it), which cannot be
    read again from its start."""
    r, w = os.pipe()

    def feed() -> None:
        with contextlib.suppress(BrokenPipeError), os.fdopen(w, "w") as fh:
            fh.write(text)  # closing the only write end gives the reader EOF

    threading.Thread(target=feed, daemon=True).start()
    monkeypatch.setattr(sys, "stdin", os.fdopen(r))


@pytest.mark.parametrize("command", ["evaluate", "plot"])
def test_an_estimate_piped_in_is_read_as_from_its_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
    command: str,
) -> None:  # fmt: skip
    """``evaluate`` and ``plot`` read an estimate more than once (its header, its options
    line, its rows): from a pipe on standard input, which cannot be read from its start
    again, they give what they give from the file (both in this process, standard input
    a pipe: ``-`` is read from its descriptor)."""
    meas, truth, est = tmp_path / "m.csv", tmp_path / "t.csv", tmp_path / "e.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth),
                 "--duration", "3"]) == 0  # fmt: skip
    assert main(["estimate", str(meas), "-o", str(est), "--method", "ekf"]) == 0
    args = (
        [str(truth), "--json"]
        if command == "evaluate"
        else ["-o", str(tmp_path / "p.png"), "--overwrite"]
    )
    capsys.readouterr()
    assert main([command, str(est), *args]) == 0
    from_file = capsys.readouterr().out
    figure = tmp_path / "p.png"
    figure.unlink(missing_ok=True)
    with monkeypatch.context() as m:
        _piped_into(est.read_text(), m)
        assert main([command, "-", *args]) == 0
        sys.stdin.close()
    piped = capsys.readouterr()
    assert piped.out == from_file, piped.err
    if command == "evaluate":
        assert json.loads(from_file)["n"] == 61  # every row of the 3 s at 20 Hz
    else:  # plot prints nothing: the figure is what it makes
        assert figure.stat().st_size > 0
        with monkeypatch.context() as m:  # no file to put the figure beside
            _piped_into(est.read_text(), m)
            assert main(["plot", "-"]) == 2
            sys.stdin.close()
        assert "give -o" in capsys.readouterr().err


def test_a_robot_file_from_a_fifo_is_read(tmp_path: Path) -> None:
    """``--robot <(...)``: a pipe named by a path is a robot file, not a missing one."""
    from continuum_mhe.io.robot_file import read_robot, shipped_robots

    fifo = tmp_path / "robot.fifo"
    os.mkfifo(fifo)
    text = shipped_robots()["two-section"].read_text()

    def write() -> None:
        with open(fifo, "w") as fh:
            fh.write(text)

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    robot = read_robot(fifo)
    writer.join(timeout=SAFETY_S)
    assert robot == read_robot("two-section")


def test_a_second_estimate_piped_in_the_same_process_is_read_anew(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Standard input is held for one command only: a second ``evaluate -`` in the same
    process (a notebook, a test) scores the second estimate, not the first again."""
    import json

    meas, truth = tmp_path / "m.csv", tmp_path / "t.csv"
    assert main(["simulate", "paper3d", "-o", str(meas), "--truth", str(truth),
                 "--duration", "3"]) == 0  # fmt: skip
    scores = {}
    for method in ("ekf", "ukf"):
        est = tmp_path / f"{method}.csv"
        assert main(["estimate", str(meas), "-o", str(est), "--method", method]) == 0
        capsys.readouterr()
        assert main(["evaluate", str(est), str(truth), "--json"]) == 0
        from_file = json.loads(capsys.readouterr().out)["tip_mean_mm"]
        r, w = os.pipe()
        os.write(w, est.read_bytes())
        os.close(w)
        with os.fdopen(r) as stdin:
            monkeypatch.setattr(sys, "stdin", stdin)
            assert main(["evaluate", "-", str(truth), "--json"]) == 0
        scores[method] = (from_file, json.loads(capsys.readouterr().out)["tip_mean_mm"])
    assert scores["ekf"][0] != scores["ukf"][0]  # two estimates that differ
    assert all(file == piped for file, piped in scores.values()), scores


@pytest.mark.parametrize(
    ("start", "what"),
    [
        (b"\x1f\x8b\x08\x00\x00\x00\x00\x00\x00\x03\r\n", "a gzip file: decompress it first"),
        (b"PK\x03\x04\x14\x00\x06\x00\r\n", "a zip file (an Excel .xlsx?)"),
    ],
)
def test_a_packed_file_is_named_for_what_it_is(tmp_path: Path, start: bytes, what: str) -> None:
    """A compressed recording (its bytes may hold a CR before a LF) is named as such,
    not told about its line ends."""
    path = tmp_path / "m.csv"
    path.write_bytes(start + bytes(range(1, 200)))
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert (
        str(info.value)
        == f"{path}: line 1: not CSV text but {what}" + str(info.value).split(what, 1)[1]
    )


@pytest.mark.parametrize(
    ("encoding", "iconv"),
    [("utf-16", "UTF-16"), ("utf-16-le", "UTF-16LE"), ("utf-16-be", "UTF-16BE")],
)
def test_a_utf16_file_is_told_to_be_saved_as_utf8(
    tmp_path: Path, encoding: str, iconv: str
) -> None:
    """Excel's "Unicode Text" (UTF-16, with or without a byte-order mark): named as
    UTF-16 with the fix (iconv's encoding names the byte order where no mark does), not
    as a binary file with a NUL byte."""
    path = tmp_path / "m.csv"
    path.write_bytes(_csv().encode(encoding))
    with pytest.raises(InputError) as info:
        read_measurements(path)
    assert str(info.value).startswith(f"{path}: line 1: not UTF-8 text but UTF-16 text")
    assert f"iconv -f {iconv} -t UTF-8" in str(info.value)


def test_a_torn_row_out_of_order_says_both(tmp_path: Path) -> None:
    # a row cut short by a torn write, its t a piece of another: the time is refused,
    # and the message says the row is short too
    text = _csv(5) + "0.01,abc\n"
    path = _write(tmp_path / "m.csv", text)
    with pytest.raises(InputError) as info:
        read_measurements(path)
    said = str(info.value)
    assert said.startswith(f"{path}: line 7: decreasing timestamp t=0.01 after t=")
    assert said.endswith("; the row has 2 of the header's 3 fields (truncated?)")


def test_a_header_without_rows_names_the_header_line(tmp_path: Path) -> None:
    path = _write(tmp_path / "m.csv", "# a\n# b\nt,roll,pitch\n")
    with pytest.raises(InputError, match=r"m.csv: line 3: the header has no data rows after it"):
        read_measurements(path)
    truth = _write(tmp_path / "truth.csv", "# a\n# b\nt,x,y,z\n")
    with pytest.raises(InputError, match=r"truth.csv: line 3: the header has no data rows after"):
        read_state_table(truth)


def test_a_whole_set_numbered_beyond_the_gap_is_named_not_the_sets_between(
    tmp_path: Path,
) -> None:
    """Two IMUs' columns and a whole set numbered 4 or 9: the line names that IMU's
    columns, not the columns of IMUs 3 to 8 that its number would imply, whatever other
    columns the header holds."""
    for k, extra in ((9, ""), (4, ",x,y"), (4, ",x,y,u,v,w")):
        header = f"t,roll_1,pitch_1,roll_2,pitch_2,roll_{k},pitch_{k}{extra}"
        values = ",".join("0" * len(header.split(",")))
        path = _write(tmp_path / "m.csv", f"{header}\n{values}\n")
        with pytest.raises(InputError) as info:
            read_measurements(path, n_imus=2)
        text = str(info.value)
        assert f"line 1: roll_{k}, pitch_{k} are columns of IMU {k}," in text, text
        assert "roll_3" not in text and "describes 2 IMU(s)" in text


def test_a_stray_imu_column_far_beyond_the_robot_is_a_short_line(tmp_path: Path) -> None:
    """A column of IMU 100000 beside two IMUs' columns: named as a column beyond the
    robot's IMUs, without the missing columns it implies (a line of megabytes) or a
    search for their look-alikes (time in proportion to the number)."""
    path = _write(tmp_path / "m.csv", "t,roll_1,pitch_1,roll_2,pitch_2,roll_100000\n0,0,0,0,0,0\n")
    with pytest.raises(InputError) as info:
        read_measurements(path, n_imus=2)
    text = str(info.value)
    assert len(text) < 600 and "roll_100000 is a column of IMU 100000" in text
    assert "the robot describes 2 IMU(s)" in text
