"""Shared test helpers for the command line's tests: files written as a user's program
writes them, a measurement CSV of good rows, a simulated recording and its truth, an
estimate file's notes and rows, and the shipped spatial-tendon rod calibrated and
estimated as the README's five steps do."""

from __future__ import annotations

import json
from pathlib import Path

from continuum_mhe.cli import main
from continuum_mhe.simulation.scenarios import simulate


def write_file(path: Path, text: str) -> Path:
    """``text`` written to ``path`` in UTF-8; ``path``."""
    path.write_text(text, encoding="utf-8")
    return path


def good_rows(n: int = 40, dt: float = 0.05) -> list[str]:
    """``n`` rows ``t,roll,pitch`` (s, rad) of a ``paper3d`` recording ``dt`` s apart."""
    rec = simulate("paper3d", duration=(n - 1) * dt, dt=dt, seed=3)
    return [f"{t:.3f},{r:.6f},{p:.6f}" for t, (r, p) in zip(rec.t, rec.z)]


def meas_csv(tmp_path: Path, rows: list[str], header: str = "t,roll,pitch") -> Path:
    """``rows`` under ``header``, written to ``tmp_path/meas.csv``."""
    return write_file(tmp_path / "meas.csv", "\n".join([header, *rows]) + "\n")


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


#: the shipped two-section rod recordings
ROD2 = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"


def calibrated_spatial_tendon(tmp_path: Path, capsys, *options: str) -> tuple[Path, Path, dict]:  # type: ignore[no-untyped-def]
    """The README's five steps on the shipped spatial-tendon rod: ``calibrate`` its rest
    into ``tmp_path/cal.toml``, ``estimate`` its raw recording with the EKF and
    ``options`` into ``tmp_path/e.csv``, ``evaluate --json`` against its truth:
    ``(cal, estimate, report)``."""
    cal, est = tmp_path / "cal.toml", tmp_path / "e.csv"
    assert main(["calibrate", "--from", str(ROD2 / "spatial-tendon_rest.csv"), "--robot",
                 "two-section", "--write-robot", str(cal)]) == 0  # fmt: skip
    assert main(["estimate", str(ROD2 / "spatial-tendon_raw.csv"), "--robot", str(cal),
                 "--method", "ekf", *options, "-o", str(est)]) == 0  # fmt: skip
    capsys.readouterr()
    truth = ROD2 / "spatial-tendon_truth.csv"
    assert main(["evaluate", str(est), str(truth), "--robot", str(cal), "--json"]) == 0
    return cal, est, json.loads(capsys.readouterr().out)


def figures_drawn_small(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``plotting.save`` (``plot``'s, the demo's) writes a one-inch empty figure in each
    figure's stead, the figure made in full first (its notes and warnings said) and
    closed: for tests of what ``plot`` says and which files it writes, not of what its
    figures show (rendering a figure is about half of a plot's time)."""
    from matplotlib.figure import Figure

    from continuum_mhe.evaluation import plotting

    real_save = plotting.save

    def save(fig, path, *args, **kw):  # type: ignore[no-untyped-def]
        plotting.close(fig)
        return real_save(Figure(figsize=(1, 1)), path, *args, **kw)

    monkeypatch.setattr(plotting, "save", save)
