"""Helpers for the pseudo-terminal tests of ``continuum-mhe live``."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Callable
from pathlib import Path

import numpy as np

SAFETY_S = 120.0  # a hung test fails after this long instead of blocking the suite


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


def wait_for(pred: Callable[[], bool], what: str) -> None:
    end = time.monotonic() + SAFETY_S
    while not pred():
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def data_rows(path: Path) -> int:
    if not path.exists():
        return 0
    return max(sum(1 for _ in path.open()) - 1, 0)


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
        wait_for(lambda: "reading " in self.err or self.proc.poll() is not None, "live to start")
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
        os.write(master, ("\n".join(lines) + "\n").encode())
        return proc.finish()
    finally:
        if proc.proc.poll() is None:
            proc.proc.kill()
        os.close(master)


def raw_line(t_ms: int, acc: np.ndarray, gyr: np.ndarray) -> str:
    """``t_ms`` then ``ax,ay,az,gx,gy,gz`` per IMU (``acc``, ``gyr``: (n_imus, 3))."""
    vals = [f"{v:.4f}" for a, g in zip(acc, gyr) for v in (*a, *g)]
    return f"{t_ms}," + ",".join(vals)


def specific_force(roll: float, pitch: float, g: float = 9.80665) -> np.ndarray:
    """The accelerometer reading of a still sensor at ``roll``, ``pitch`` (rad)."""
    return g * np.array(
        [-math.sin(pitch), math.sin(roll) * math.cos(pitch), math.cos(roll) * math.cos(pitch)]
    )
