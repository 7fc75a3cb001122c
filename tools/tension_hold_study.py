"""Tensions logged slower than the IMUs and held at every row (a logger's zero-order
hold): a shipped recording's tensions sampled at ``HZ`` and each sample repeated until
the next, estimated by ``continuum-mhe estimate`` with the command line's defaults, as
read (the rows where a value changes taken as the slower log's samples:
:func:`~continuum_mhe.io.tension_derivatives.hold_knots`) and, for comparison, with each
held row taken as given (the hold not looked for; the steps then read as a load cell's
noise and are smoothed). Prints per rate and mode the mean tip error over every row
(mm), the rows ``ok`` and those of them more than 5 mm off::

    python tools/tension_hold_study.py                      # force-29; 10, 9.5, 9.9, 8 Hz
    python tools/tension_hold_study.py unloaded --hz 10
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe.cli import main as cli_main
from continuum_mhe.io import tension_derivatives
from continuum_mhe.io.state_tables import read_state_table

DATA = Path(tension_derivatives.__file__).resolve().parents[1] / "data" / "tendon"
HOLD_KNOTS = tension_derivatives.hold_knots


def held(scenario: str, hz: float, out: Path) -> None:
    """The scenario's tensions sampled at ``hz`` (linear between its rows) and held over
    its rows, as ``out``."""
    d = np.loadtxt(DATA / f"{scenario}_tensions.csv", delimiter=",", skiprows=1)
    t = d[:, 0]
    ts = np.arange(0.0, t[-1] + 1e-9, 1.0 / hz)
    slow = np.column_stack([np.interp(ts, t, d[:, j]) for j in range(1, d.shape[1])])
    rows = slow[np.searchsorted(ts, t + 1e-9, side="right") - 1]
    header = "t," + ",".join(f"tension_{j}" for j in range(1, d.shape[1]))
    np.savetxt(out, np.column_stack([t, rows]), delimiter=",", fmt="%.9g", header=header,
               comments="")  # fmt: skip


def run(scenario: str, tensions: Path, out: Path, as_given: bool) -> str:
    """Estimate with ``tensions``; the scores as one line."""
    tension_derivatives.hold_knots = (lambda t, v: None) if as_given else HOLD_KNOTS  # type: ignore[assignment]
    argv = ["estimate", str(DATA / f"{scenario}_raw.csv"), "--robot", "tendon-two-section",
            "--inputs", str(tensions), "-o", str(out), "--overwrite"]  # fmt: skip
    quiet = contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO())
    with quiet[0], quiet[1], warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if cli_main(argv) != 0:
            raise SystemExit(f"estimate failed: {argv}")
    tension_derivatives.hold_knots = HOLD_KNOTS
    est, truth = read_state_table(out), read_state_table(DATA / f"{scenario}_truth.csv")
    cols = [est.names.index(c) for c in ("x", "y", "z")]
    tcols = [truth.names.index(c) for c in ("x", "y", "z")]
    err = np.linalg.norm(est.values[:, cols] - truth.values[:, tcols], axis=1) * 1e3
    ok = np.asarray(est.status) == "ok"
    return f"tip {err.mean():.2f} mm, ok {int(ok.sum())}, ok > 5 mm {int((ok & (err > 5)).sum())}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenario", nargs="?", default="force-29")
    p.add_argument("--hz", type=float, nargs="+", default=[10.0, 9.5, 9.9, 8.0])
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for hz in args.hz:
            tensions = folder / f"held_{hz:g}.csv"
            held(args.scenario, hz, tensions)
            for mode in ("as read", "as given"):
                line = run(args.scenario, tensions, folder / "est.csv", mode == "as given")
                print(f"{args.scenario} held at {hz:g} Hz, {mode}: {line}", flush=True)


if __name__ == "__main__":
    main()
