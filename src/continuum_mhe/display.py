"""Whether a window can open here: the display that ``DISPLAY`` or ``WAYLAND_DISPLAY``
names answers (Linux and the BSDs; elsewhere a window is taken to open).

A ``DISPLAY`` that names no X server that answers (a stale one over ssh, a display
closed since) makes a window library fail late and in its own words, or Rerun's viewer
never come up while the stream waits for it: the commands ask here first and say why in
one line.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import sys
from pathlib import Path

#: How long a display over TCP may take to accept a connection, s.
CONNECT_TIMEOUT_S = 1.0
#: The first TCP port of X displays (display N listens on this plus N).
X_TCP_PORT = 6000


def display_problem() -> str | None:
    """Why no window can open here (a phrase such as ``DISPLAY is not set``), or None
    where the display answers (or the platform has no such variable)."""
    if not sys.platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return None
    wayland = os.environ.get("WAYLAND_DISPLAY")
    x11 = os.environ.get("DISPLAY")
    if not (wayland or x11):
        return "DISPLAY is not set"
    if wayland and _wayland_answers(wayland):
        return None
    if x11 and _x11_answers(x11):
        return None
    named = f"DISPLAY={x11}" if x11 else f"WAYLAND_DISPLAY={wayland}"
    return f"{named} names no display that answers (one closed since, or a stale ssh -X?)"


def _wayland_answers(name: str) -> bool:
    path = Path(name) if os.path.isabs(name) else Path(os.environ.get("XDG_RUNTIME_DIR", "")) / name
    return _unix_answers(str(path))


def _x11_answers(display: str) -> bool:
    found = re.fullmatch(r"(?P<host>[^:]*):(?P<number>\d+)(\.\d+)?", display)
    if found is None:  # another form (a launchd path on macOS' XQuartz): not judged here
        return True
    host, number = found["host"], int(found["number"])
    if host in ("", "unix"):
        local = f"/tmp/.X11-unix/X{number}"
        return _unix_answers(local) or _unix_answers("\0" + local)  # file or abstract
    try:
        with socket.create_connection((host, X_TCP_PORT + number), timeout=CONNECT_TIMEOUT_S):
            return True
    except OSError:
        return False


def _unix_answers(address: str) -> bool:
    with contextlib.suppress(OSError), socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(CONNECT_TIMEOUT_S)
        s.connect(address)
        return True
    return False
