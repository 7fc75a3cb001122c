"""``continuum-mhe live`` on a pseudo-terminal: a recorded raw stream with garbage,
a partial line, a time gap, out-of-order lines and a mid-stream hang-up, followed by
the device coming back (the port is a symlink re-pointed to a new pty)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import tty
from pathlib import Path

import numpy as np
import pytest

from continuum_mhe.io.csv_files import read_states
from continuum_mhe.live import GarbledLine, parse_line
from continuum_mhe.model.direct import raw_imu_readings
from continuum_mhe.simulation.scenarios import simulate

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")

SAFETY_S = 120.0  # a hung test fails after this long instead of blocking the suite


def _raw_lines(t0_ms: int, n: int, dt_ms: int = 20, skip: range = range(0)) -> list[str]:
    rec = simulate("paper3d", duration=(n - 1) * dt_ms / 1e3, dt=dt_ms / 1e3, noise_deg=0.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], 0.2)
    return [
        f"{t0_ms + i * dt_ms},{a[0]:.4f},{a[1]:.4f},{a[2]:.4f},{g[0]:.5f},{g[1]:.5f},{g[2]:.5f}\n"
        for i, (a, g) in enumerate(zip(acc, gyr))
        if i not in skip
    ]


def _new_pty(link: Path) -> int:
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo: nothing comes back to the master
    name = os.ttyname(slave)
    os.close(slave)
    tmp = link.with_suffix(".new")
    tmp.unlink(missing_ok=True)
    tmp.symlink_to(name)
    os.replace(tmp, link)
    return master


def _wait_for(pred, what: str) -> None:  # type: ignore[no-untyped-def]
    end = time.monotonic() + SAFETY_S
    while not pred():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def _rows(path: Path) -> int:
    if not path.exists():
        return 0
    return max(sum(1 for _ in path.open()) - 1, 0)


def test_parse_line_protocol() -> None:
    s = parse_line("1500,0.1,0.2,9.8,0.01,0.02,0.03\r\n", "raw")
    assert s is not None and s.t == 1.5 and s.values.shape == (6,)
    assert parse_line("# continuum_imu 1.0", "raw") is None
    assert parse_line("   ", "tilt") is None
    t = parse_line("20,0.1,-0.2", "tilt")
    assert t is not None and list(t.values) == [0.1, -0.2]
    for bad in (
        "1,2,3",
        "x,0,0,9.8,0,0,0",
        "1,nan,0,9.8,0,0,0",
        "1,0,0,9999,0,0,0",
        "12,0.1,0.2,9.8,0.01,0.0",
    ):
        with pytest.raises(GarbledLine):
            parse_line(bad, "raw")
    with pytest.raises(GarbledLine):
        parse_line("20,45.0,10.0", "tilt")  # degrees, not radians


def test_live_pty_stream_with_faults(tmp_path: Path) -> None:
    port = tmp_path / "ttyIMU"
    out = tmp_path / "live.csv"
    master = _new_pty(port)
    # session 1: 60 samples, gap of 10 samples after sample 40 (device lost them)
    first = _raw_lines(0, 70, skip=range(40, 50))
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
    cmd = [
        sys.executable,
        "-m",
        "continuum_mhe.cli",
        "live",
        "--port",
        str(port),
        "--format",
        "raw",
        "--method",
        "ekf",
        "-o",
        str(out),
        "--status-every",
        "0.2",
        "--retry-max",
        "0.2",
    ]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for(lambda: out.exists(), "live to open its output")
        for line in lines:
            os.write(master, line.encode("latin-1"))
            time.sleep(0.002)
        os.write(master, b"99999,0.1,0.2")  # a partial line, then the device hangs up
        _wait_for(lambda: _rows(out) >= valid_first, "estimates of session 1")
        time.sleep(0.3)
        os.close(master)
        # the file is complete while live waits for the device
        time.sleep(0.5)
        t1, x1, s1 = read_states(out)
        assert len(t1) == valid_first
        assert np.all(np.diff(t1) > 0)
        assert np.all(np.isfinite(x1))
        # session 2: the device comes back and restarts its clock at 0
        master = _new_pty(port)
        time.sleep(1.0)
        second = _raw_lines(0, 25)
        for line in second:
            os.write(master, line.encode())
            time.sleep(0.002)
        _wait_for(lambda: _rows(out) >= valid_first + len(second), "estimates of session 2")
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=SAFETY_S)
    finally:
        if proc.poll() is None:
            proc.kill()
        os.close(master)
    assert proc.returncode == 0, err
    t, x, status = read_states(out)
    # every valid sample produced exactly one estimate, in order, none invented
    assert len(t) == valid_first + len(second)
    assert np.all(np.diff(t) > 0)
    # the device's second session comes over a second later: --gap-reset (1 s) restarts
    # the estimator there, once (the same mechanism as in estimate)
    assert set(status[:valid_first]) == {"ok"}
    assert status[valid_first] == "reset" and set(status[valid_first + 1 :]) == {"ok"}
    assert np.all(x[:, 3] <= np.pi / 2 + 0.05)  # no runaway across the long gap
    # the gap: one step of 11 periods, no estimates inside it
    steps = np.diff(t[:valid_first])
    assert np.sum(steps > 0.05) == 2  # the 10-sample gap and the destroyed pair
    assert steps.max() == pytest.approx(0.22, abs=1e-9)
    # the restarted device continues after the old samples
    assert t[valid_first] > t[valid_first - 1]
    assert "disconnected" in err and "is back" in err and "gap of" in err
    summary = [ln for ln in err.splitlines() if "samples," in ln][-1]
    assert f"{valid_first + len(second)} samples, {valid_first + len(second)} estimates" in summary
    assert "4 garbled" in summary  # non-ASCII, text, too few fields, the run-together line
    assert "1 partial" in summary
    assert "1 out of order" in summary
    assert "1 disconnect" in summary


def test_live_bad_port_is_one_line(tmp_path: Path) -> None:
    res = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(tmp_path / "none")],
        capture_output=True,
        text=True,
        timeout=SAFETY_S,
    )
    assert res.returncode == 2
    assert res.stderr.startswith("continuum-mhe: error: ") and res.stderr.count("\n") == 1
