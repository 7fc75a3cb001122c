"""The readings' constant errors and the model error in the standard deviations
(docs/options.md, "The readings' constant errors in the standard deviation" and "The
model error the readings showed"), one part at a time:

* ``pooled``: the 16 random one- and two-section PCC robots of
  ``tests/test_consistency.py``'s pooled test (``tools/consistency_catches.py``'s
  ``assumed`` recordings with each reading's constant error drawn at the default
  ``reading_bias_std``, 1.2 degrees), the EKF with ``model_error_std`` 0 (the model made
  the motion), with the constant-error term (the default ``reading_bias_std``) and
  without it (0): the pooled per-axis coverage of the ``ok`` rows' 95 % intervals, the
  rows ``ok``, each two-section recording's ``uncertain`` rows after its first, and the
  largest model error learned;
* ``uncertain``: ``continuum-mhe estimate src/continuum_mhe/data/rod2/spatial-tendon_raw.csv
  --robot two-section`` (the fast MHE), and the same with ``--reading-bias-deg 0``: the
  rows ``uncertain`` and the largest written tip standard deviation
  (``sqrt(std_x^2 + std_y^2 + std_z^2)``);
* ``missed``: the shipped raw rod recordings, the EKF with the command line's defaults:
  per tip axis, the ``ok`` rows whose 95 % interval misses the rod's tip, the median of
  the innovations' average over them (``ConsistencyCheck.noise_scale``, in units of
  what the noise model predicts), the share of the ``ok`` rows whose interval holds
  the constant-curvature shape of the rod's own end tangents (the truth file's
  ``theta_k, phi_k``), and over the missed rows the median distance of that shape's tip
  from the rod's and of the estimate's tip from that shape's;
* ``start``: spatial-stiff-torsion and spatial, raw, with the defaults and recovery off
  (``RecoverySettings.off()``, as ``tools/ok_coverage_study.py``): the first row
  ``inconsistent`` (the model error first shows) and the ``ok`` rows whose z interval
  misses the tip, before it and after it.

::

    python tools/model_error_study.py                  # every part
    python tools/model_error_study.py --only pooled
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import tempfile
import warnings
from pathlib import Path

import numpy as np
from consistency_catches import RODS, Z95, random_recordings

from continuum_mhe import MHESettings
from continuum_mhe.cli.app import main as cli_main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.pcc import pose_at
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.results import Measurement
from continuum_mhe.settings import NoiseSettings, RecoverySettings

ROD2 = Path(__file__).parents[1] / "src" / "continuum_mhe" / "data" / "rod2"


def part_pooled() -> None:
    print("pooled: 16 random PCC robots, constant errors drawn at 1.2 deg, EKF")
    default = NoiseSettings(model_error_std=0.0)
    runs = random_recordings(default.reading_bias_std)
    for label, noise in (
        ("with the term", default),
        ("without it", NoiseSettings(model_error_std=0.0, reading_bias_std=0.0)),
    ):
        covered, ok_rows, rows, later, model_error = [], 0, 0, [], 0.0
        for robot, rec in runs:
            s = make_estimator("ekf", make_formulation("bend", robot, noise)).run(rec.t, rec.z)
            status = np.asarray(s.status)
            ok = status == "ok"
            covered.append(np.abs(s.output[ok, :3] - rec.truth[ok, :3]) <= Z95 * s.std[ok, :3])
            ok_rows += int(ok.sum())
            rows += len(ok)
            if robot.n_sections == 2:
                later.append(int(np.sum(status[1:] == "uncertain")))
            model_error = max(model_error, float(s.diagnostics.model_error))
        c = np.concatenate(covered).mean(axis=0)
        print(
            f"  {label}: ok coverage {c[0]:.3f} / {c[1]:.3f} / {c[2]:.3f}; {ok_rows} of {rows} "
            f"rows ok; two-section recordings' uncertain rows after the first "
            f"{min(later)} to {max(later)}; largest model error {model_error:.2f}",
            flush=True,
        )


def part_uncertain(tmp: Path) -> None:
    print("uncertain: spatial-tendon raw, the command line's defaults (the fast MHE)")
    for extra in ([], ["--reading-bias-deg", "0"]):
        out = tmp / f"spatial-tendon{len(extra)}.csv"
        argv = ["estimate", str(ROD2 / "spatial-tendon_raw.csv"), "--robot", "two-section"]
        with contextlib.redirect_stderr(io.StringIO()):
            if cli_main([*argv, "-o", str(out), *extra]) != 0:
                raise SystemExit(f"{' '.join(argv + extra)} failed")
        with out.open() as fh:
            rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
        status = np.array([r["status"] for r in rows])
        std = np.array([[float(r[f"std_{c}"] or "nan") for c in "xyz"] for r in rows])
        print(
            f"  {' '.join(extra) or 'defaults'}: {np.sum(status == 'uncertain')} rows uncertain; "
            f"the largest tip std {1e3 * np.nanmax(np.linalg.norm(std, axis=1)):.1f} mm",
            flush=True,
        )


def _rod(name: str) -> tuple[np.ndarray, np.ndarray]:
    """The rod's tip (n, 3) and the tip of the constant-curvature shape of its own end
    tangents (the truth file's ``theta_k, phi_k``) (n, 3), m."""
    truth = read_state_table(ROD2 / f"{name}_truth.csv")
    theta = np.stack([truth.column(f"theta_{k}") for k in (1, 2)], axis=1)
    phi = np.stack([truth.column(f"phi_{k}") for k in (1, 2)], axis=1)
    bends = np.stack([theta * np.cos(phi), theta * np.sin(phi)], axis=-1)
    lengths = [s.length for s in read_robot("two-section").sections]
    return truth.values[:, :3], pose_at(bends, lengths, 1)[1]


def _medians(values: np.ndarray, rows: np.ndarray) -> str:
    """The median of ``values`` (n,) over each axis' rows (n, 3), as ``x / y / z``."""
    return " / ".join(
        f"{np.median(values[rows[:, a]]):.2f}" if rows[:, a].any() else "-" for a in range(3)
    )


def part_missed() -> None:
    print("missed: rod2 raw, EKF, the command line's defaults; per axis x / y / z")
    robot = read_robot("two-section")
    for name in RODS:
        tip, pcc = _rod(name)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = load_input(
                ROD2 / f"{name}_raw.csv", InputOptions(), make_formulation("bend", robot)
            )
            est = make_estimator("ekf", data.formulation)
            est.reset()
            out = np.full((len(data.t), 3), np.nan)
            std = np.full((len(data.t), 3), np.nan)
            status, average = [], []
            for i, (t, z) in enumerate(zip(data.t, data.z)):
                e = est.step(Measurement(float(t), z))
                if e.output is not None and e.output_std is not None:
                    out[i], std[i] = e.output[:3], e.output_std[:3]
                status.append(str(e.status))
                average.append(est._consistency.core.noise_scale)  # type: ignore[attr-defined]
        ok = np.array(status) == "ok"
        missed = (np.abs(out - tip) > Z95 * std) & ok[:, None]
        holds = (np.abs(out - pcc) <= Z95 * std)[ok].mean(axis=0)
        to_rod = np.linalg.norm(pcc - tip, axis=1) * 1e3
        to_pcc = np.linalg.norm(out - pcc, axis=1) * 1e3
        print(
            f"  {name}: {ok.sum()} rows ok, missed {' / '.join(map(str, missed.sum(axis=0)))}; "
            f"innovations' average over the missed {_medians(np.asarray(average), missed)}; "
            f"ok rows whose interval holds the PCC shape {holds[0]:.3f} / {holds[1]:.3f} / "
            f"{holds[2]:.3f}; on the missed rows the PCC shape's tip off the rod's "
            f"{_medians(to_rod, missed)} mm, the estimate off the PCC shape "
            f"{_medians(to_pcc, missed)} mm",
            flush=True,
        )


def part_start() -> None:
    print("start: raw, defaults, recovery off: the first row inconsistent; ok rows missing z")
    robot = read_robot("two-section")
    for name in ("spatial-stiff-torsion", "spatial"):
        tip = _rod(name)[0]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = load_input(
                ROD2 / f"{name}_raw.csv", InputOptions(), make_formulation("bend", robot)
            )
        for method in ("ekf", "ukf", "mhe"):
            est = make_estimator(method, data.formulation, MHESettings(), RecoverySettings.off())  # type: ignore[arg-type]
            s = est.run(data.t, data.z)
            status = np.asarray(s.status)
            first = int(np.flatnonzero(status == "inconsistent")[0])
            miss_z = (status == "ok") & (np.abs(s.output[:, 2] - tip[:, 2]) > Z95 * s.std[:, 2])
            print(
                f"  {name} {method}: first inconsistent row {first} (t = {data.t[first]:.2f} s); "
                f"ok rows missing z {miss_z.sum()}, {miss_z[:first].sum()} of them before it",
                flush=True,
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parts = ["pooled", "uncertain", "missed", "start"]
    p.add_argument("--only", nargs="+", choices=parts, default=parts)
    args = p.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as name:
        if "pooled" in args.only:
            part_pooled()
        if "uncertain" in args.only:
            part_uncertain(Path(name))
        if "missed" in args.only:
            part_missed()
        if "start" in args.only:
            part_start()


if __name__ == "__main__":
    main()
