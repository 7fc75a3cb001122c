"""Noisy tensions (docs/tendon-studies.md, "Noisy tensions"): a shipped recording's
tensions with white noise of a given standard deviation added (seeded; clipped at 0),
or resampled from every fifth row (10 Hz) back to the rows by linear interpolation,
estimated by ``continuum-mhe estimate`` with the command line's defaults: the file
taken as ``estimate`` takes it (``as-read``: its rows on the line through their
neighbours left out of the differences, smoothed where its rows scatter) and, for
comparison, differenced row by row (``row-by-row``, as a recording's own tension
columns are). Prints one JSON line per run: the mean tip error after the first second
(mm), the tip force's rms error (N), the mean norm of its standard deviations (N) and
the share of its per-axis 95 % intervals that cover the truth, the smoothing's span (s)
and the statuses.

    python tools/tension_noise_study.py unloaded --noise 0 0.003 0.01 0.03
    python tools/tension_noise_study.py force-29 --noise 0.01 --imu tilt
    python tools/tension_noise_study.py unloaded --resampled
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe.arrays import FloatArray
from continuum_mhe.cli import main as cli_main
from continuum_mhe.io import tensions as tension_io
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.io.tension_derivatives import DifferencedTensions

DATA = Path(tension_io.__file__).resolve().parents[1] / "data" / "tendon"


AS_READ = tension_io.tension_derivatives


def row_by_row(t: FloatArray, values: FloatArray, binned: bool = True) -> DifferencedTensions:
    """The tensions differenced row by row, as a recording's own columns, whatever asked."""
    return AS_READ(t, values, binned=False)


def estimate(meas: Path, given: Path, out: Path) -> None:
    """``continuum-mhe estimate MEAS --robot tendon-two-section --inputs GIVEN -o OUT``."""
    argv = ["estimate", str(meas), "--robot", "tendon-two-section", "--inputs", str(given),
            "-o", str(out), "--overwrite"]  # fmt: skip
    quiet = contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO())
    with quiet[0], quiet[1], warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if cli_main(argv) != 0:
            raise SystemExit(f"estimate failed: {argv}")


def errors(out: Path, truth_path: Path) -> dict[str, object]:
    """Mean tip error after 1 s (mm), tip-force rms error (N), statuses."""
    est, truth = read_state_table(out), read_state_table(truth_path)

    def stack(table: object, names: tuple[str, ...]) -> np.ndarray:
        return np.stack([table.column(c) for c in names], axis=1)  # type: ignore[attr-defined]

    after = est.t >= 1.0
    tip = np.linalg.norm(stack(est, ("x", "y", "z")) - stack(truth, ("x", "y", "z")), axis=1)
    force = stack(est, ("fx", "fy", "fz")) - stack(truth, ("fx", "fy", "fz"))
    assert est.std is not None
    force_std = est.std[:, [est.names.index(c) for c in ("fx", "fy", "fz")]]
    statuses: dict[str, int] = {}
    for s in est.status:
        statuses[str(s)] = statuses.get(str(s), 0) + 1
    return {
        "tip_mean_mm": round(float(np.mean(tip[after])) * 1e3, 2),
        "force_rms_n": round(float(np.sqrt(np.mean(np.sum(force[after] ** 2, axis=1)))), 4),
        "force_std_mean_n": round(float(np.mean(np.linalg.norm(force_std[after], axis=1))), 4),
        "force_coverage": round(float(np.mean(np.abs(force[after]) <= 1.96 * force_std[after])), 2),
        "statuses": statuses,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scenario")
    p.add_argument("--noise", nargs="+", type=float, default=[0.0, 0.003, 0.01, 0.03])
    p.add_argument("--imu", choices=("raw", "tilt"), default="raw")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resampled", action="store_true", help="every fifth row, linearly back")
    a = p.parse_args()
    rows = np.loadtxt(DATA / f"{a.scenario}_tensions.csv", delimiter=",", skiprows=1)
    header = "t," + ",".join(f"tension_{j}" for j in range(1, rows.shape[1]))
    meas, truth = DATA / f"{a.scenario}_{a.imu}.csv", DATA / f"{a.scenario}_truth.csv"
    cases: list[tuple[str, np.ndarray]] = []
    if a.resampled:
        keep = np.arange(0, len(rows), 5)
        lin = rows.copy()
        for j in range(1, rows.shape[1]):
            lin[:, j] = np.interp(rows[:, 0], rows[keep, 0], rows[keep, j])
        cases.append(("10 Hz, linear", lin))
    else:
        rng = np.random.default_rng(a.seed)
        for noise in a.noise:
            noisy = rows.copy()
            noisy[:, 1:] = np.maximum(rows[:, 1:] + rng.normal(0.0, noise, rows[:, 1:].shape), 0)
            cases.append((f"{noise:g} N", noisy))
    with tempfile.TemporaryDirectory() as tmp:
        for label, table in cases:
            given = Path(tmp) / "tensions.csv"
            np.savetxt(given, table, delimiter=",", header=header, comments="", fmt="%.6f")
            smoothing = tension_io.read_tensions(given, rows.shape[1] - 1).smoothing
            span = 0.0 if smoothing is None else smoothing.span_s
            for mode in ("as-read", "row-by-row"):
                if mode == "row-by-row":
                    tension_io.tension_derivatives = row_by_row
                try:
                    estimate(meas, given, Path(tmp) / "est.csv")
                finally:
                    tension_io.tension_derivatives = AS_READ
                print(json.dumps({"scenario": a.scenario, "imu": a.imu, "tensions": label,
                                  "mode": mode, "smoothing_s": round(span, 3) if mode ==
                                  "as-read" else 0.0, **errors(Path(tmp) / "est.csv", truth)}),
                      flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
