"""Where a view goes: an .rrd file, Rerun's native viewer, or its web viewer served on
127.0.0.1 only (a ``rerun --serve-web`` process this module starts and stops)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Literal
from urllib.parse import quote

from continuum_mhe.display import display_problem
from continuum_mhe.errors import InputError, UserError

LOOPBACK = "127.0.0.1"
SinkKind = Literal["save", "spawn", "web"]
SINK_KINDS: tuple[SinkKind, ...] = ("save", "spawn", "web")


@dataclass(frozen=True)
class ViewerSink:
    """Where the stream goes.

    Attributes:
        kind: ``save`` (an .rrd file at ``path``), ``spawn`` (Rerun's native viewer), or
            ``web`` (Rerun's web viewer served on 127.0.0.1 only).
        path: the .rrd file for ``save``.
        web_port: HTTP port of the web viewer (``web``).
        grpc_port: port of the Rerun server the stream goes to (``web``, ``spawn``).
    """

    kind: SinkKind
    path: Path | None = None
    web_port: int = 9090
    grpc_port: int = 9876

    def __post_init__(self) -> None:
        if self.kind not in SINK_KINDS:
            raise UserError(
                f"ViewerSink kind must be one of {', '.join(SINK_KINDS)}, got {self.kind!r}"
            )
        if self.path is not None and not isinstance(self.path, Path):
            if not isinstance(self.path, (str, os.PathLike)):
                raise UserError(f"ViewerSink path must be a file path, got {self.path!r}")
            object.__setattr__(self, "path", Path(self.path))  # a path given as a str
        if self.kind == "save" and (self.path is None or self.path.suffix.lower() != ".rrd"):
            raise InputError(f"{self.path}: the view is saved as a Rerun file ending in .rrd")
        for name in ("web_port", "grpc_port"):
            v = getattr(self, name)
            if not (isinstance(v, int) and 0 < v < 65536):
                raise InputError(f"--{name.replace('_', '-')} must be a port in 1..65535, got {v}")

    def display_missing(self) -> str | None:
        """Why Rerun's native viewer cannot open here (no display, or one that does not
        answer: :func:`~continuum_mhe.display.display_problem`), or None (it can, or
        this is not the native viewer)."""
        return display_problem() if self.kind == "spawn" else None

    @property
    def grpc_url(self) -> str:
        """The Rerun server the stream goes to."""
        return f"rerun+http://{LOOPBACK}:{self.grpc_port}/proxy"

    @property
    def web_url(self) -> str:
        """The page to open: the web viewer, connected to the server."""
        return f"http://{LOOPBACK}:{self.web_port}/?url={quote(self.grpc_url, safe='')}"


def _check_free(port: int, option: str) -> None:
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as servers do: a listener
        try:  # blocks, a closed connection's TIME_WAIT does not
            s.bind((LOOPBACK, port))
        except OSError:
            raise InputError(
                f"port {port} on {LOOPBACK} is in use; pick another with {option}"
            ) from None


def _wait_for_port(port: int, proc: subprocess.Popen[bytes], seconds: float = 20.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise InputError(
                f"the Rerun web viewer exited at start (status {proc.returncode}); "
                f"is port {port} already in use?"
            )
        with socket.socket() as s:
            s.settimeout(0.2)
            if s.connect_ex((LOOPBACK, port)) == 0:
                return
        time.sleep(0.1)
    raise InputError(f"the Rerun web viewer did not open port {port} within {seconds:g} s")


def stop_web_viewer(proc: subprocess.Popen[bytes] | None) -> None:
    """Stop the web viewer process group this module started."""
    if proc is None or proc.poll() is not None:
        return
    try:
        if hasattr(os, "killpg"):
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.terminate()
        proc.wait(timeout=5)
    except (ProcessLookupError, subprocess.TimeoutExpired):
        proc.kill()


def start_web_viewer(sink: ViewerSink) -> subprocess.Popen[bytes]:
    """Start ``rerun --serve-web`` bound to 127.0.0.1 (its own process group, its output
    discarded) and wait until both its ports answer."""
    if sink.web_port == sink.grpc_port:
        raise InputError(
            f"--web-port and --grpc-port are both {sink.web_port}: the web viewer and the "
            "data server need a port each"
        )
    _check_free(sink.web_port, "--web-port")
    _check_free(sink.grpc_port, "--grpc-port")
    cmd = [
        sys.executable, "-m", "rerun", "--serve-web", "--bind", LOOPBACK,
        "--web-viewer-port", str(sink.web_port), "--port", str(sink.grpc_port),
    ]  # fmt: skip
    proc = subprocess.Popen(
        cmd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        _wait_for_port(sink.web_port, proc)
        _wait_for_port(sink.grpc_port, proc)
    except BaseException:
        stop_web_viewer(proc)
        raise
    return proc
