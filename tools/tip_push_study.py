"""How hard the tendon robot's estimated tip force pushes along the tip's tangent, in
buckling loads (docs/tendon.md, the estimate: a push beyond the buckling load makes a
row ``drifted``).

Each estimate is ``continuum-mhe estimate REC --robot tendon-two-section --inputs
TENSIONS -o EST.csv`` (the EKF, the command line's defaults). The push of a row is
``-f . t``, ``f`` its ``fx, fy, fz`` and ``t`` the tip's tangent from its ``theta_k,
phi_k, psi_k`` (docs/tendon.md, the estimate: ``t = Q_1 Q_2 e3`` with ``Q_k = R(theta_k,
phi_k) Rz(psi_k)``), over the load that buckles the straight backbone as a cantilever
(``TendonFormulation.buckling_load``, ``pi^2 EI / (4 L^2)``).

* the shipped recordings (``data/tendon``, raw and tilt IMUs): the largest push of the
  estimates and of the truth, in buckling loads;
* ``--rest``: ``continuum-mhe simulate rest --robot tendon-two-section --imu raw --seed
  2`` estimated with its ``rest_tensions.csv``: the rows ``drifted``, their largest tip
  force and push, and their smallest ``std_fz``.

::

    python tools/tip_push_study.py
    python tools/tip_push_study.py --rest
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import tempfile
from pathlib import Path

import numpy as np

from continuum_mhe.cli.app import main as cli_main
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.tendon import TendonFormulation

DATA = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "tendon"
NAMES = ("unloaded", "planar-s", "force-08", "force-29", "twist-08", "twist-29")


def csv_columns(path: Path) -> dict[str, np.ndarray]:
    """The columns of an estimate, truth or tensions CSV by name (``status`` as text)."""
    with path.open() as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    return {
        k: np.array([r[k] for r in rows])
        if k == "status"
        else np.array([float(r[k] or "nan") for r in rows])
        for k in rows[0]
    }


def _turn(theta: float, phi: float, psi: float) -> np.ndarray:
    """``R(theta, phi) Rz(psi)``, ``R(theta, phi) = Rz(phi) Ry(-theta) Rz(-phi)``."""

    def rz(a: float) -> np.ndarray:
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    c, s = np.cos(-theta), np.sin(-theta)
    ry = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return rz(phi) @ ry @ rz(-phi) @ rz(psi)


def pushes(table: dict[str, np.ndarray]) -> np.ndarray:
    """Each row's tip force along the tip's tangent, N (positive: a push)."""
    out = np.full(len(table["fx"]), np.nan)
    for i in range(len(out)):
        tip = np.eye(3)
        for k in (1, 2):
            tip = tip @ _turn(table[f"theta_{k}"][i], table[f"phi_{k}"][i], table[f"psi_{k}"][i])
        force = np.array([table[c][i] for c in ("fx", "fy", "fz")])
        out[i] = -force @ tip[:, 2]
    return out


def _run(argv: list[str]) -> None:
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        if cli_main(argv) != 0:
            raise SystemExit(f"continuum-mhe {' '.join(argv)} failed")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rest", action="store_true", help="the still robot's drifted rows")
    args = p.parse_args()
    buckling = TendonFormulation(read_robot("tendon-two-section")).buckling_load
    print(f"buckling load {buckling:.4f} N")
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        if args.rest:
            rec = tmp / "rest.csv"
            _run(["simulate", "rest", "--robot", "tendon-two-section", "--imu", "raw"]
                 + ["--seed", "2", "-o", str(rec)])  # fmt: skip
            out = tmp / "est.csv"
            _run(["estimate", str(rec), "--robot", "tendon-two-section"]
                 + ["--inputs", str(tmp / "rest_tensions.csv"), "-o", str(out)])  # fmt: skip
            est = csv_columns(out)
            drifted = est["status"] == "drifted"
            force = np.linalg.norm(np.column_stack([est[c] for c in ("fx", "fy", "fz")]), axis=1)
            print(
                f"rest, seed 2: {drifted.sum()} of {len(drifted)} rows drifted; their tip force "
                f"up to {force[drifted].max():.2f} N, push up to "
                f"{pushes(est)[drifted].max():.2f} N; their std_fz down to "
                f"{est['std_fz'][drifted].min():.3f} N"
            )
            return
        for rec_name in NAMES:
            truth = csv_columns(DATA / f"{rec_name}_truth.csv")
            line = f"{rec_name}: truth {np.nanmax(pushes(truth)) / buckling:.3f}"
            for case in ("raw", "tilt"):
                out = tmp / f"{rec_name}_{case}.csv"
                tensions = DATA / f"{rec_name}_tensions.csv"
                _run(["estimate", str(DATA / f"{rec_name}_{case}.csv")]
                     + ["--robot", "tendon-two-section"]
                     + ["--inputs", str(tensions), "-o", str(out)])  # fmt: skip
                line += f", {case} {np.nanmax(pushes(csv_columns(out))) / buckling:.3f}"
            print(line + " buckling loads at most", flush=True)


if __name__ == "__main__":
    main()
