"""Helpers for the tests that run the command line in a subprocess: ``live`` on a
pseudo-terminal, and what a running command is doing (writing, waiting for input)."""

from __future__ import annotations

import errno
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np

from continuum_mhe.model.direct import raw_imu_readings
from continuum_mhe.simulation.scenarios import simulate

sys.path.append(str(Path(__file__).resolve().parents[1] / "tools"))
from live_soak import new_pty as new_pty  # noqa: E402 - the soak tool's simulated device
from live_soak import write_pty  # noqa: E402

SAFETY_S = 120.0  # a hung test fails after this long instead of blocking the suite

#: a device's write to a pty (:func:`live_soak.write_pty`): fails after its stall time
send = write_pty


def unplug(master: int, link: Path) -> None:
    """The device behind ``link`` goes away: the link first, as a USB adapter's device
    node goes, then the pty. Closed first, the pty's number could go to another test's
    pty while ``link`` still names it, and the reader reopening ``link`` would read that
    test's lines."""
    link.unlink()
    os.close(master)


def open_fifo_writer(fifo: Path, reading: Callable[[], bool]) -> IO[str]:
    """``fifo`` opened for writing once a reader has opened it. A plain ``open`` blocks
    until then, for ever when the reader ends first: this fails instead, as soon as
    ``reading()`` says the reader has gone, or after ``SAFETY_S``."""
    end = time.monotonic() + SAFETY_S
    while True:
        try:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno != errno.ENXIO:  # ENXIO: no reader yet
                raise
            if not reading():
                raise AssertionError(f"the reader ended before opening {fifo}") from None
            if time.monotonic() > end:
                raise AssertionError(f"nothing opened {fifo} within {SAFETY_S:g} s") from None
            time.sleep(0.02)
            continue
        os.set_blocking(fd, True)
        return os.fdopen(fd, "w")


def unblock_fifo_reader(fifo: Path) -> None:
    """Open ``fifo`` for writing and close it at once: a reader blocked opening it (one
    that opened it a second time, after its writer left) gets end-of-file."""
    try:
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
    except OSError:  # no reader waiting
        pass


def wait_for(pred: Callable[[], bool], what: str, said: Callable[[], str] = str) -> None:
    """Wait until ``pred()``; fails after :data:`SAFETY_S` with ``what`` and ``said()``
    (what the process wrote so far)."""
    end = time.monotonic() + SAFETY_S
    while not pred():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}: {said()}")
        time.sleep(0.02)


def temporary_bytes(folder: Path, name: str) -> int:
    """The size of the atomic writer's temporary file for ``folder / name`` (0 while
    there is none): a running command's output so far."""
    for p in folder.glob(f".{name}.*.tmp"):
        try:
            return p.stat().st_size
        except FileNotFoundError:  # renamed or removed meanwhile
            pass
    return 0


def blocked_reading(pid: int, path: Path) -> bool | None:
    """Whether process ``pid`` is blocked in ``read`` on its open file ``path``, from
    Linux's ``/proc/PID/syscall``; None where the system cannot tell (no ``/proc``)."""
    try:
        # read while the kernel writes this file: it shows the read call's number
        read_call = Path("/proc/self/syscall").read_text().split()[0]
        call = Path(f"/proc/{pid}/syscall").read_text().split()
    except OSError:
        return None
    if call[0] != read_call:  # another call, or "running"
        return False
    try:
        return os.readlink(f"/proc/{pid}/fd/{int(call[1], 16)}") == str(path.resolve())
    except OSError:
        return False


def data_rows(path: Path) -> int:
    """The rows of a CSV written so far: its lines after the column line, without the
    ``#`` lines (an estimate file's options and notes)."""
    if not path.exists():
        return 0
    return max(sum(1 for ln in path.open() if not ln.startswith("#")) - 1, 0)


class LiveProcess:
    """``continuum-mhe live ...`` (or another ``command``) in a subprocess, its stderr
    collected by a thread (stdout too, with ``stdout=True``)."""

    def __init__(self, args: list[str], command: str = "live", stdout: bool = False) -> None:
        cmd = [sys.executable, "-m", "continuum_mhe.cli", command, *args]
        pipe = subprocess.PIPE if stdout else None
        self.proc = subprocess.Popen(cmd, stdout=pipe, stderr=subprocess.PIPE, text=True)
        self.lines: list[str] = []
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line)

    @property
    def err(self) -> str:
        return "".join(self.lines)

    def wait_ready(self) -> None:
        wait_for(lambda: "reading " in self.err or self.proc.poll() is not None, "live to start",
                 lambda: self.err)  # fmt: skip
        assert self.proc.poll() is None, self.err

    def finish(self, sig: int | None = None) -> int:
        if sig is not None:
            self.proc.send_signal(sig)
        try:
            code = self.proc.wait(timeout=SAFETY_S)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()
        self._thread.join(timeout=5)
        return code


def send_and_finish(proc: LiveProcess, master: int, lines: list[str]) -> int:
    """Once ``proc`` reads its port, write ``lines`` to the pty's ``master`` and wait for
    ``proc`` to end on its own (``--duration``, ``--seconds``); returns its exit status.
    The process is killed and ``master`` closed whatever happens."""
    try:
        proc.wait_ready()
        send(master, ("\n".join(lines) + "\n").encode(), lambda: proc.proc.poll() is None)
        return proc.finish()
    finally:
        if proc.proc.poll() is None:
            proc.proc.kill()
        os.close(master)


def send_until_estimated(
    proc: LiveProcess, master: int, chunks: list[str], est: Path, rows: int, pause: float
) -> int:
    """Once ``proc`` reads its port, write ``chunks`` to the pty's ``master`` one at a
    time, ``pause`` s apart, wait for ``rows`` estimates in ``est`` and end ``proc`` with
    SIGTERM; returns its exit status. The process is killed and ``master`` closed
    whatever happens."""
    try:
        proc.wait_ready()
        for chunk in chunks:
            send(master, chunk.encode())
            time.sleep(pause)
        wait_for(lambda: data_rows(est) >= rows, "every estimate")
        return proc.finish(signal.SIGTERM)
    finally:
        if proc.proc.poll() is None:
            proc.proc.kill()
        os.close(master)


def alive(values: np.ndarray, i: int | None = None, amplitude: float = 1e-4) -> np.ndarray:
    """Raw readings with a real IMU's noise where a test's have none: ``values`` (n, 6 k)
    with ``+-amplitude`` rad/s, alternating sample by sample, on each IMU's gx (mean zero
    over an even count); or, with ``i``, one sample's gyro rows (k, 3) with the sign of
    sample ``i``. Readings that repeat exactly for 0.2 s are a frozen sensor's."""
    out = np.array(values, dtype=float)
    if i is not None:
        out[:, 0] += amplitude * (1.0 if i % 2 == 0 else -1.0)
        return out
    out[:, 3::6] += amplitude * np.where(np.arange(len(out)) % 2 == 0, 1.0, -1.0)[:, None]
    return out


def raw_line(t_ms: int, acc: np.ndarray, gyr: np.ndarray) -> str:
    """``t_ms`` then ``ax,ay,az,gx,gy,gz`` per IMU (``acc``, ``gyr``: (n_imus, 3))."""
    vals = [f"{v:.4f}" for a, g in zip(acc, gyr) for v in (*a, *g)]
    return f"{t_ms}," + ",".join(vals)


def specific_force(roll: float, pitch: float, g: float = 9.80665) -> np.ndarray:
    """The accelerometer reading of a still sensor at ``roll``, ``pitch`` (rad)."""
    return g * np.array(
        [-math.sin(pitch), math.sin(roll) * math.cos(pitch), math.cos(roll) * math.cos(pitch)]
    )


def raw_lines(
    t0_ms: int, n: int, dt_ms: int = 20, skip: range = range(0), gyro_scale: float = 1.0
) -> list[str]:
    """``n`` lines of one raw IMU (the paper3d scenario, noise-free, 0.2 m) from
    ``t0_ms`` every ``dt_ms``, leaving out the samples in ``skip``; the gyro (rad/s)
    times ``gyro_scale`` (``180 / pi``: a board that sends deg/s, median 41 over the
    first 100 samples at 20 ms)."""
    rec = simulate("paper3d", duration=(n - 1) * dt_ms / 1e3, dt=dt_ms / 1e3, noise_deg=0.0)
    acc, gyr = raw_imu_readings(rec.t, rec.truth[:, 3], rec.truth[:, 4], 0.2)
    gyr = gyr * gyro_scale
    return [
        raw_line(t0_ms + i * dt_ms, a[None], g[None]) + "\n"
        for i, (a, g) in enumerate(zip(acc, gyr))
        if i not in skip
    ]


def stubborn_trial(spec: object) -> dict[str, object]:
    """A reproduce task that marks its start (a file named by its PID in
    ``$STUBBORN_MARKS``), then runs for an hour, dropping every KeyboardInterrupt (and
    so SIGTERM's :class:`~continuum_mhe.signals.Terminated`) as IPOPT drops a Ctrl-C:
    a parent that waits for its workers waits for it."""
    Path(os.environ["STUBBORN_MARKS"], str(os.getpid())).touch()
    end = time.monotonic() + 3600
    while time.monotonic() < end:
        try:
            time.sleep(0.01)
        except KeyboardInterrupt:
            pass
    return {}


def slow_pool_thread() -> None:
    """Widen, in this process, the race between the interpreter's exit and a process
    pool's own thread as it ends: the thread takes a tenth of a second to close its
    wake-up pipe, and the exit's write to that pipe comes half a second after its check
    that the pipe is open. A pool's thread still running at exit then meets a closed
    pipe (a traceback on stderr)."""
    from concurrent.futures import process

    wakeup_class = process._ThreadWakeup
    close = wakeup_class.close
    wakeup = wakeup_class.wakeup

    def slow_close(self: Any) -> None:
        time.sleep(0.1)
        close(self)

    def late_wakeup(self: Any) -> None:
        if process._global_shutdown and not self._closed:  # the exit's call
            time.sleep(0.5)
            self._writer.send_bytes(b"")
        else:
            wakeup(self)

    wakeup_class.close = slow_close
    wakeup_class.wakeup = late_wakeup


def send_until_rows(
    proc: LiveProcess, master: int, data: str, out: Path, rows: int, sig: int
) -> int:
    """Once ``proc`` reads its port, write ``data`` to the pty's ``master``, wait until
    ``out`` holds ``rows`` rows, stop ``proc`` with ``sig`` and return its exit status.
    The process is killed and ``master`` closed whatever happens."""
    try:
        proc.wait_ready()
        send(master, data.encode())
        wait_for(lambda: data_rows(out) >= rows, f"{rows} rows in {out.name}")
        return proc.finish(sig)
    finally:
        if proc.proc.poll() is None:
            proc.proc.kill()
        os.close(master)
