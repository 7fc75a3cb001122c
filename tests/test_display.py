"""Whether a window can open (:mod:`continuum_mhe.display`): a display that answers, one
that is not set, and one that names no server (a stale ``DISPLAY`` over ssh), which
``live --view``, ``live --plot`` and ``view`` name in one line before they start
instead of waiting for a viewer that never comes up."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from continuum_mhe.cli import main
from continuum_mhe.display import display_problem
from continuum_mhe.live.run import plot_unavailable

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="DISPLAY and abstract sockets are Linux's"
)

#: a display number no X server here uses
FREE_DISPLAY = 4711


def test_a_display_that_answers_is_taken(monkeypatch: pytest.MonkeyPatch) -> None:
    """An X server listening on the display's (abstract) socket: a window can open."""
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as server:
        server.bind(f"\0/tmp/.X11-unix/X{FREE_DISPLAY}")
        server.listen(1)
        monkeypatch.setenv("DISPLAY", f":{FREE_DISPLAY}.0")
        assert display_problem() is None
    monkeypatch.setenv("DISPLAY", f":{FREE_DISPLAY}")  # the server gone
    assert display_problem() == (
        f"DISPLAY=:{FREE_DISPLAY} names no display that answers (one closed since, or a stale "
        "ssh -X?)"
    )
    monkeypatch.delenv("DISPLAY")
    assert display_problem() == "DISPLAY is not set"


@pytest.mark.parametrize(
    ("command", "said"),
    [
        (["live", "--port", "PORT", "--view"], "--view needs a display"),
        (["view", "EST"], "--spawn (the default) needs a display"),
    ],
)
def test_a_display_that_does_not_answer_is_named_before_the_viewer_starts(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    command: list[str],
    said: str,
) -> None:
    """``live --view`` and ``view`` with a ``DISPLAY`` whose server is gone: one line
    naming it, exit 2, before the port or the viewer (not a wait, for ever and past
    Ctrl-C, for a Rerun viewer that never comes up)."""
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("DISPLAY", f":{FREE_DISPLAY}")
    est = tmp_path / "e.csv"
    est.write_text("t,x,y,z,theta,phi\n0,0,0,0.1,0,0\n")
    argv = [str(tmp_path / "none") if a == "PORT" else str(est) if a == "EST" else a
            for a in command]  # fmt: skip
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and said in err[0]
    assert f"(DISPLAY=:{FREE_DISPLAY} names no display that answers" in err[0]


def test_live_plot_names_a_display_that_does_not_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    """``--plot`` with a ``DISPLAY`` whose server is gone says so, not that the backend
    is not interactive (whose advice, an interactive backend, failed without a word)."""
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("DISPLAY", f":{FREE_DISPLAY}")
    why = plot_unavailable()
    assert why is not None and why.startswith(f"--plot needs a display (DISPLAY=:{FREE_DISPLAY}")


def test_a_backend_that_mplbackend_does_not_name_is_said_or_not_used(tmp_path: Path) -> None:
    """``MPLBACKEND`` naming no matplotlib backend (a typo) stops matplotlib's import:
    ``plot`` draws off screen all the same (it does not use that backend), and
    ``live --plot`` says why it shows no window in one line, as it does for a missing
    display (each in a fresh interpreter: matplotlib reads the variable once, at its
    import)."""
    est, fig = tmp_path / "e.csv", tmp_path / "e.png"
    est.write_text("t,x,y,z,theta,phi\n0,0,0,0.2,0,0\n0.05,0,0,0.2,0,0\n")
    env = {**os.environ, "MPLBACKEND": "nonsense"}
    res = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", "plot", str(est), "-o", str(fig)],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    assert fig.stat().st_size > 0 and res.stderr == f"wrote {fig}\n"
    said = subprocess.run(
        [sys.executable, "-c",
         "from continuum_mhe.live.run import plot_unavailable; print(plot_unavailable())"],
        capture_output=True, text=True, env=env, timeout=120,
    )  # fmt: skip
    assert said.returncode == 0, said.stderr
    assert said.stdout == (
        "--plot needs a matplotlib backend: MPLBACKEND='nonsense' names none (set "
        "MPLBACKEND=TkAgg or QtAgg)\n"
    )
