"""Soak test of ``continuum-mhe live`` on a pseudo-terminal.

A simulated device streams two raw IMUs (the shipped ``two-section`` robot) at
``--rate`` Hz for ``--seconds`` s into a pty, with faults at intervals: garbage bursts,
lines cut short, lines arriving in pieces, 1 MB lines without a line end, and the
port disappearing for a second and coming back (a new pty behind the same path).
``live`` runs with ``-o`` and ``--record`` and is stopped with SIGINT or SIGTERM.
Reported (JSON on stdout):

* valid samples sent (complete lines, not sent while the port was gone) against rows
  in the recording and in the estimate file, and whether every recorded row reads
  back (``estimate``'s raw CSV reader);
* the RSS of ``live`` over time (after the warm-up) and its growth;
* ``live``'s own latency from line received to estimate written (median, p99), its
  counts, and the exit status.

    PYTHONPATH=src python tools/live_soak.py --seconds 150 --rate 500 --signal INT
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import select
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path
from typing import Any

G = 9.80665
STALL_S = 120.0  # s without progress before a wait fails instead of blocking


def new_pty(link: Path) -> int:
    """A pseudo-terminal whose device ``link`` points to; returns the master fd."""
    master, slave = os.openpty()
    tty.setraw(slave)  # no echo: nothing comes back to the master
    name = os.ttyname(slave)
    os.close(slave)
    tmp = link.with_suffix(".new")
    tmp.unlink(missing_ok=True)
    tmp.symlink_to(name)
    os.replace(tmp, link)
    return master


def write_pty(master: int, data: bytes, reading: Callable[[], bool] = lambda: True) -> None:
    """Write ``data`` to the pty's ``master`` as a device would. A write to a pty blocks
    once the kernel's buffer is full, which a reader that stopped reading leaves full:
    this returns as soon as ``reading()`` says the reader has gone (the rest can never be
    read) and fails after ``STALL_S`` without progress, instead of blocking."""
    os.set_blocking(master, False)
    left = memoryview(data)
    end = time.monotonic() + STALL_S
    while left:
        if not select.select([], [master], [], 0.05)[1]:
            if not reading():
                return
            if time.monotonic() > end:
                raise RuntimeError(f"the pty's reader took no data for {STALL_S:g} s")
            continue
        try:
            left = left[os.write(master, left) :]
        except BlockingIOError:
            continue
        end = time.monotonic() + STALL_S


def _line(t_ms: int) -> str:
    """Two IMUs swinging smoothly: ``t_ms`` + 6 raw values per IMU."""
    t = t_ms / 1e3
    vals = []
    for k in range(2):
        roll = 0.3 * (k + 1) * math.sin(2 * math.pi * 0.2 * t + k)
        pitch = 0.2 * (k + 1) * math.cos(2 * math.pi * 0.15 * t)
        acc = (
            -G * math.sin(pitch),
            G * math.sin(roll) * math.cos(pitch),
            G * math.cos(roll) * math.cos(pitch),
        )
        gyr = (0.01 * math.sin(t), -0.02 * math.cos(t), 0.005)
        vals += [f"{v:.3f}" for v in acc] + [f"{v:.4f}" for v in gyr]
    return f"{t_ms}," + ",".join(vals) + "\n"


def _rss_kb(pid: int) -> int | None:
    try:
        text = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return None
    m = re.search(r"VmRSS:\s+(\d+) kB", text)
    return int(m.group(1)) if m else None


def _rows(path: Path) -> int:
    """Rows of a CSV so far: its lines after the column line, without the ``#`` lines
    (an estimate file's options and notes)."""
    if not path.exists():
        return 0
    with path.open("rb") as fh:
        return max(sum(1 for ln in fh if not ln.startswith(b"#")) - 1, 0)


class Device(threading.Thread):
    """Writes the stream and its faults into the pty, paced by the wall clock."""

    def __init__(
        self,
        port: Path,
        rate: float,
        seconds: float,
        faults_every: float,
        received: Any,
        reopened: Any,
    ) -> None:
        super().__init__(daemon=True)
        self.received = received  # () -> samples live has recorded so far
        self.reopened = reopened  # () -> times live said the port is back
        self.port, self.rate, self.seconds, self.faults_every = port, rate, seconds, faults_every
        self.master = new_pty(port)
        self.sent = 0
        self.sent_ranges: list[tuple[int, int, float]] = []  # [first, last) index, time
        self.faults: dict[str, int] = {"garbage": 0, "partial": 0, "mb_line": 0, "port_gone": 0}
        self.late_max_s = 0.0
        self.rng = random.Random(1)
        self.t0 = time.monotonic()
        self.timeline: list[tuple[float, str]] = []  # (s since start, fault)
        self.next_index = 0  # the next sample's index (device time = index / rate)
        self.error: BaseException | None = None  # what stopped the stream, if anything

    def _write(self, data: bytes) -> None:
        write_pty(self.master, data)

    def _fault(self, k: int) -> None:
        kind = ("garbage", "partial", "mb_line", "port_gone")[k % 4]
        self.faults[kind] += 1
        self.timeline.append((round(time.monotonic() - self.t0, 2), kind))
        if kind == "garbage":
            burst = bytes(self.rng.randrange(256) for _ in range(2000))
            self._write(b"\n" + burst + b"\n")
        elif kind == "partial":  # a line cut short (garbled), then one sent in pieces
            self._write(_line(0)[:25].encode() + b"\n")
            t_ms = int(round(self.next_index * 1000 / self.rate))
            whole = _line(t_ms).encode()
            for a, b in ((0, 7), (7, 40), (40, len(whole))):
                self._write(whole[a:b])
                time.sleep(0.02)  # the reader sees each piece alone
            self.sent += 1
            self.sent_ranges.append((self.next_index, self.next_index + 1, time.monotonic()))
            self.next_index += 1
        elif kind == "mb_line":
            self._write(b"z" * 1_000_000 + b"\n")
        else:
            # a real unplug loses what the driver held; here the test waits until live
            # has read everything sent, so that 'lost' can only mean lost by live
            end = time.monotonic() + 10
            while self.received() < self.sent and time.monotonic() < end:
                time.sleep(0.01)
            # the device node goes first, as a USB adapter's does: the pty's number, free
            # once closed, may go to another program's pty, which live must not reopen
            self.port.unlink()
            os.close(self.master)
            time.sleep(1.0)
            self.master = new_pty(self.port)
            # pyserial flushes what waits in the port when it opens it (as it would with a
            # real device): send nothing until live has reopened the port
            end = time.monotonic() + 30
            while self.reopened() < self.faults["port_gone"] and time.monotonic() < end:
                time.sleep(0.01)
            # the device was unplugged mid-stream: its first bytes end a line in
            # progress (live drops that first line after a reopen)
            self._write(b"\n")

    def run(self) -> None:
        try:
            self._stream()
        except BaseException as exc:  # noqa: BLE001 - re-raised by run_soak
            self.error = exc

    def _stream(self) -> None:
        start = self.t0 = time.monotonic()
        next_fault = start + self.faults_every
        n_fault = 0
        i = self.next_index = 0
        while True:
            now = time.monotonic()
            if now - start >= self.seconds:
                break
            if now >= next_fault:
                self.next_index = i
                self._fault(n_fault)
                i = self.next_index
                n_fault += 1
                next_fault = time.monotonic() + self.faults_every
                # the device's clock ran on while the port was gone: skip those samples
                i = max(i, int((time.monotonic() - start) * self.rate))
                continue
            due = int((now - start) * self.rate)
            if due <= i:
                time.sleep(min(0.005, (i + 1) / self.rate - (now - start)))
                continue
            self.late_max_s = max(self.late_max_s, (due - i) / self.rate)
            chunk = "".join(_line(int(round(j * 1000 / self.rate))) for j in range(i, due))
            self._write(chunk.encode())
            self.sent += due - i
            self.sent_ranges.append((i, due, time.monotonic()))
            i = due


def _lost(
    raw: Path, rate: float, sent: list[tuple[int, int, float]], t0: float
) -> list[tuple[int, int, float]]:
    """Runs of samples sent but not in the recording: (first index, count, sent at s)."""
    import numpy as np

    t = np.loadtxt(raw, delimiter=",", skiprows=1, usecols=0, ndmin=1)
    got = set(np.rint(t * rate).astype(int).tolist())
    runs: list[tuple[int, int, float]] = []
    for a, b, when in sent:
        for j in range(a, b):
            if j in got:
                continue
            if runs and runs[-1][0] + runs[-1][1] == j:
                runs[-1] = (runs[-1][0], runs[-1][1] + 1, runs[-1][2])
            else:
                runs.append((j, 1, round(when - t0, 2)))
    return runs


def run_soak(
    seconds: float,
    rate: float = 500.0,
    method: str = "mhe",
    stop_signal: str = "INT",
    faults_every: float = 10.0,
    folder: Path | None = None,
) -> dict[str, Any]:
    """Run the soak; return the measurements (see the module docstring)."""
    tmp = Path(folder or tempfile.mkdtemp(prefix="live_soak_"))
    port, est, raw = tmp / "ttySOAK", tmp / "est.csv", tmp / "raw.csv"
    err: list[str] = []
    device = Device(
        port,
        rate,
        seconds,
        faults_every,
        lambda: _rows(raw),
        lambda: sum("is back after" in ln for ln in err),
    )
    cmd = [sys.executable, "-m", "continuum_mhe.cli", "live", "--port", str(port)]
    cmd += ["--robot", "two-section", "--method", method, "-o", str(est), "--record", str(raw)]
    cmd += ["--status-every", "1", "--retry-max", "0.2"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    stamps: list[float] = []  # monotonic arrival of each stderr line

    def drain() -> None:
        for ln in iter(proc.stderr.readline, ""):  # type: ignore[union-attr]
            err.append(ln)
            stamps.append(time.monotonic())

    reader = threading.Thread(target=drain)
    reader.daemon = True
    reader.start()
    try:
        start = time.monotonic()
        while not any("reading " in ln for ln in err):
            if proc.poll() is not None:
                raise RuntimeError("live ended at start: " + "".join(err))
            if time.monotonic() - start > STALL_S:
                raise RuntimeError(f"live did not start within {STALL_S:g} s: " + "".join(err))
            time.sleep(0.05)
        t0 = time.monotonic()
        device.start()
        rss: list[tuple[float, int]] = []
        while device.is_alive():
            kb = _rss_kb(proc.pid)
            if kb is not None:
                rss.append((time.monotonic() - t0, kb))
            device.join(timeout=1.0)
        if device.error is not None:
            raise device.error
        # all sent: wait until live has written every sample (or stops making progress),
        # then stop it: any difference between sent and written is then a loss
        last, still = -1, time.monotonic()
        while _rows(est) < device.sent and time.monotonic() - still < 30:
            if _rows(est) != last:
                last, still = _rows(est), time.monotonic()
            time.sleep(0.2)
        proc.send_signal(signal.SIGINT if stop_signal == "INT" else signal.SIGTERM)
        code = proc.wait(timeout=120)
        reader.join(timeout=5)
    finally:
        if proc.poll() is None:  # the soak itself failed: never leave live running
            proc.kill()
    os.close(device.master)
    summary = next((ln for ln in reversed(err) if "samples," in ln), "")
    lat = re.search(r"median ([\d.]+) ms, p99 ([\d.]+) ms", summary)
    readable = True
    try:
        from continuum_mhe.io.raw_imu import read_raw_imus

        read_raw_imus(raw, 2)
    except Exception as exc:  # report, do not hide
        readable = f"{type(exc).__name__}: {exc}"  # type: ignore[assignment]
    warm = [kb for t, kb in rss if t >= min(20.0, seconds / 4)]
    lost = _lost(raw, rate, device.sent_ranges, t0)
    worst = []  # the status lines whose window saw the largest latencies
    for ts, ln in zip(stamps, err):
        m = re.search(r"line to estimate max ([\d.]+) ms", ln)
        if m:
            worst.append((float(m.group(1)), round(ts - t0, 1)))
    worst.sort(reverse=True)
    return {
        "seconds": seconds,
        "rate_hz": rate,
        "method": method,
        "signal": stop_signal,
        "exit_status": code,
        "sent": device.sent,
        "recorded_rows": _rows(raw),
        "estimate_rows": _rows(est),
        "recording_reads_back": readable,
        "faults": device.faults,
        "writer_late_max_s": round(device.late_max_s, 3),
        "rss_kb_after_warmup_first_last_max": [warm[0], warm[-1], max(warm)] if warm else None,
        "latency_ms_median_p99": [float(lat.group(1)), float(lat.group(2))] if lat else None,
        "fault_timeline_s": device.timeline,
        "lost_runs_first_count_sent_at_s": lost[:10],
        "worst_latency_ms_at_s": worst[:8],
        "behind": [ln.strip() for ln in err if "falling behind" in ln or "caught up" in ln],
        "summary": summary.strip(),
        "folder": str(tmp),
    }


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=150.0)
    p.add_argument("--rate", type=float, default=500.0, help="samples per second")
    p.add_argument("--method", default="mhe", choices=("mhe", "ekf", "ukf"))
    p.add_argument("--signal", default="INT", choices=("INT", "TERM"))
    p.add_argument("--faults-every", type=float, default=10.0, help="seconds between faults")
    a = p.parse_args()
    res = run_soak(a.seconds, a.rate, a.method, a.signal, a.faults_every)
    print(json.dumps(res, indent=1))
    ok = res["sent"] == res["recorded_rows"] == res["estimate_rows"]
    return 0 if ok and res["recording_reads_back"] is True else 1


if __name__ == "__main__":
    sys.exit(main())
