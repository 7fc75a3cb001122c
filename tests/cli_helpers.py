"""Shared test helpers for the command line's tests: a simulated recording and its truth,
and an estimate file's notes and rows."""

from __future__ import annotations

from pathlib import Path

from continuum_mhe.cli import main


def simulated(tmp_path: Path, name: str, *extra: str) -> tuple[Path, Path]:
    """A 5 s ``paper3d`` recording (tilt readings) and its truth, simulated into
    ``tmp_path`` as ``NAME_m.csv`` and ``NAME_t.csv``; ``extra``: more simulate options."""
    m, t = tmp_path / f"{name}_m.csv", tmp_path / f"{name}_t.csv"
    args = ["simulate", "paper3d", "-o", str(m), "--truth", str(t), "--duration", "5"]
    assert main([*args, *extra]) == 0
    return m, t


def notes_and_rows(estimate: Path) -> tuple[list[str], list[str]]:
    """An estimate CSV's ``#`` lines (the options it was made with) and its other lines
    (the column line, then the rows), each with its line end."""
    lines = estimate.read_text().splitlines(keepends=True)
    notes = [ln for ln in lines if ln.startswith("#")]
    return notes, [ln for ln in lines if not ln.startswith("#")]
