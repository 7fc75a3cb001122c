"""SIGTERM is handled like Ctrl-C: nothing partial is left, exit 143; stale temporary
files of a killed writer are removed by the next write into the same folder."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from live_helpers import temporary_bytes, wait_for

from continuum_mhe.io.csv_files import atomic_writer

EXE = str(Path(sys.executable).with_name("continuum-mhe"))


def test_sigterm_during_estimate_leaves_nothing_and_exits_143(tmp_path: Path) -> None:
    from continuum_mhe.cli import main

    meas = tmp_path / "m.csv"
    assert main(["simulate", "paper3d", "--duration", "3000", "-o", str(meas)]) == 0
    out = tmp_path / "e.csv"
    proc = subprocess.Popen(
        [EXE, "estimate", str(meas), "-o", str(out), "--method", "ukf"],
        stderr=subprocess.PIPE,
        text=True,
    )
    # well into the estimation loop (60,001 samples, about 9 MB of rows): its estimates
    # are being written to the temporary file
    wait_for(
        lambda: temporary_bytes(tmp_path, "e.csv") > 100_000 or proc.poll() is not None,
        "the first estimates",
    )
    assert proc.poll() is None, proc.communicate()[1]
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert err.strip().splitlines()[-1] == "continuum-mhe: terminated"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]  # no output, no temp


def test_stale_temporary_of_a_dead_writer_is_removed(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".e.csv.{dead.pid}.abc123.tmp"
    stale.write_text("partial")
    alive = tmp_path / f".e.csv.{os.getpid()}.def456.tmp"  # ours: still running
    alive.write_text("in progress")
    other = tmp_path / f".other.csv.{dead.pid}.x.tmp"  # another target: not ours to judge
    other.write_text("x")
    with atomic_writer(tmp_path / "e.csv") as fh:
        fh.write("t\n")
    assert not stale.exists()
    assert alive.exists() and other.exists()
    assert (tmp_path / "e.csv").read_text() == "t\n"
