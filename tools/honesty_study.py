"""Whether ``ok`` means ok and the standard deviations mean what they say, with the
command line's defaults, for MHE, EKF and UKF: the four figures of the consistency
targets in one run (docs/uncertainty.md, "Honest ``ok``: the four targets").

(a) two-section Cosserat rods (``--robot two-section``; the shipped ``rod2`` recordings
    and any folder given with ``--rods``, raw IMUs and tilt): the share of rows ``ok``
    and the per-axis (x, y, z) coverage of the ``ok`` rows' 95 % intervals, per
    recording and pooled over the recordings (target 85 to 99 % per axis);
(b) the loaded tendon robot (``data/tendon/*loaded*`` recordings: ``force-08``,
    ``force-29``) estimated without tensions with a PCC robot of the same geometry
    (0.2 m + 0.2 m, ``theta_max = 3.0``, an IMU at each section's end): the share of
    the rows more than 20 mm off that are not ``ok`` (target at least 80 %);
(c) ``paper3d`` with one reading turned upside down (roll plus or minus pi, pitch
    negated): the rows more than 50 mm off that are ``ok`` (target none);
(d) ``paper3d`` sampled at 1 Hz: the ``ok`` rows 4 or more of their own standard
    deviations off on some tip axis (target none; the EKF's one linearisation is the
    case in point).

Every estimate is made by ``continuum-mhe estimate`` with nothing but ``--robot`` and
``--method`` (in this process), so the figures are those a user gets.

    python tools/honesty_study.py                          # all four, every method
    python tools/honesty_study.py --only a --rods DIR ...  # more rod recordings
    python tools/honesty_study.py --methods ekf --only c d
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import shlex
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from continuum_mhe.cli.app import main as cli_main
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.simulation.cosserat import default_data_path

DATA = default_data_path().parent  # the package's data folder
Z95 = 1.959964
#: the PCC robot of the tendon robot's geometry (``data/robots/tendon_two_section.toml``
#: without its tendons and backbone)
PCC_TENDON_GEOMETRY = """mounting = "z-up"
[[section]]
length = 0.2
theta_max = 3.0
[[section]]
length = 0.2
theta_max = 3.0
[[imu]]
section = 1
[[imu]]
section = 2
"""


def estimate(folder: Path, recording: Path, method: str, *options: str) -> dict[str, np.ndarray]:
    """``continuum-mhe estimate RECORDING --method METHOD OPTIONS``: the tip (n, 3) m, its
    std (n, 3) m and the status (n,) of each row."""
    out = folder / f"{recording.parent.name}_{recording.stem}_{method}.csv"
    argv = ["estimate", str(recording), "-o", str(out), "--method", method, *options]
    with contextlib.redirect_stderr(io.StringIO()) as said:
        code = cli_main(argv)
    if code != 0:
        raise SystemExit(f"{' '.join(argv)}: exit {code}: {said.getvalue().strip()}")
    with out.open() as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))

    def column(name: str) -> list[float]:  # a row without an estimate: NaN
        return [float(r[name] or "nan") for r in rows]

    tip = np.column_stack([column(c) for c in "xyz"])
    std = np.column_stack([column(f"std_{c}") for c in "xyz"])
    return {"tip": tip, "std": std, "status": np.array([r["status"] for r in rows])}


def truth_tip(path: Path) -> np.ndarray:
    """The truth file's tip ``x, y, z`` (n, 3), m."""
    return read_state_table(path).values[:, :3]


def coverage(est: dict[str, np.ndarray], truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row: whether it is ``ok`` (n,), and whether each axis' 95 % interval holds
    the truth (n, 3)."""
    ok = est["status"] == "ok"
    return ok, np.abs(est["tip"] - truth) <= Z95 * est["std"]


def target_a(
    tmp: Path,
    methods: Sequence[str],
    folders: Sequence[Path],
    cases: Sequence[str],
    extra: Sequence[str] = (),
) -> None:
    print("(a) rods: ok share; ok rows' 95 % coverage x / y / z (target 0.85 to 0.99)")
    for method in methods:
        pooled_ok, pooled_cov = [], []
        for folder in folders:
            for truth_path in sorted(folder.glob("*_truth.csv")):
                name = truth_path.name[: -len("_truth.csv")]
                truth = truth_tip(truth_path)
                for case in cases:
                    rec = folder / f"{name}_{case}.csv"
                    if not rec.exists():
                        continue
                    est = estimate(tmp, rec, method, "--robot", "two-section", *extra)
                    ok, cov = coverage(est, truth)
                    pooled_ok.append(ok)
                    pooled_cov.append(cov[ok])
                    err = np.linalg.norm(est["tip"] - truth, axis=1) * 1e3
                    c = cov[ok].mean(axis=0) if ok.any() else np.full(3, np.nan)
                    print(
                        f"  {method} {folder.name}/{name} {case}: tip {np.nanmean(err):.1f} mm "
                        f"({np.isnan(err).sum()} rows without an estimate), "
                        f"ok {ok.mean():.2f}, coverage {c[0]:.2f} / {c[1]:.2f} / {c[2]:.2f}",
                        flush=True,
                    )
        c = np.concatenate(pooled_cov).mean(axis=0)
        share = np.concatenate(pooled_ok).mean()
        print(f"  {method} pooled: ok {share:.2f}, coverage {c[0]:.2f} / {c[1]:.2f} / {c[2]:.2f}")


def target_b(tmp: Path, methods: Sequence[str], cases: Sequence[str]) -> None:
    print("(b) loaded tendon robot, no tensions: rows > 20 mm off not ok (target >= 0.80)")
    robot = tmp / "pcc_tendon_geometry.toml"
    robot.write_text(PCC_TENDON_GEOMETRY)
    folder = DATA / "tendon"
    for method in methods:
        for truth_path in sorted(folder.glob("force-*_truth.csv")):
            name = truth_path.name[: -len("_truth.csv")]
            truth = truth_tip(truth_path)
            for case in cases:
                est = estimate(tmp, folder / f"{name}_{case}.csv", method, "--robot", str(robot))
                far = np.linalg.norm(est["tip"] - truth, axis=1) > 0.02
                flagged = np.mean(est["status"][far] != "ok") if far.any() else np.nan
                print(
                    f"  {method} {name} {case}: {far.sum()} rows > 20 mm, not ok {flagged:.2f}, "
                    f"ok share {np.mean(est['status'] == 'ok'):.2f}",
                    flush=True,
                )


def _simulate(tmp: Path, name: str, *options: str) -> tuple[Path, Path]:
    rec, truth = tmp / f"{name}.csv", tmp / f"{name}_truth.csv"
    with contextlib.redirect_stderr(io.StringIO()):
        code = cli_main(["simulate", "paper3d", "-o", str(rec), "--truth", str(truth), *options])
    if code != 0:
        raise SystemExit(f"simulate {options}: exit {code}")
    return rec, truth


def upside_down(path: Path, row: int) -> None:
    """Turn reading ``row`` of a one-IMU tilt CSV upside down (roll plus or minus pi,
    pitch negated), in place."""
    lines = path.read_text().splitlines()
    data = [i for i, line in enumerate(lines) if line and not line.startswith("#")][1:]
    header = next(line for line in lines if line and not line.startswith("#")).split(",")
    i = data[row]
    values = lines[i].split(",")
    r, p = header.index("roll"), header.index("pitch")
    roll = float(values[r])
    values[r] = repr(roll + np.pi if roll < 0 else roll - np.pi)
    values[p] = repr(-float(values[p]))
    lines[i] = ",".join(values)
    path.write_text("\n".join(lines) + "\n")


def target_c(tmp: Path, methods: Sequence[str], seeds: Sequence[int]) -> None:
    print("(c) paper3d, one upside-down reading: ok rows > 50 mm off (target 0)")
    for seed in seeds:
        rec, truth_path = _simulate(tmp, f"upside_{seed}", "--duration", "8", "--seed", str(seed))
        upside_down(rec, 60)
        truth = truth_tip(truth_path)
        for method in methods:
            est = estimate(tmp, rec, method)
            err = np.linalg.norm(est["tip"] - truth, axis=1)
            ok = est["status"] == "ok"
            bad = ok & (err > 0.05)
            worst = err[bad].max() * 1e3 if bad.any() else 0.0
            print(
                f"  {method} seed {seed}: ok rows > 50 mm off {bad.sum()} (worst {worst:.0f} mm), "
                f"ok share {ok.mean():.2f}",
                flush=True,
            )


def target_d(tmp: Path, methods: Sequence[str], seeds: Sequence[int]) -> None:
    print("(d) paper3d at 1 Hz: ok rows >= 4 std off on a tip axis (target 0)")
    for seed in seeds:
        rec, truth_path = _simulate(
            tmp, f"slow_{seed}", "--duration", "120", "--dt", "1", "--seed", str(seed)
        )
        truth = truth_tip(truth_path)
        for method in methods:
            est = estimate(tmp, rec, method)
            off = (np.abs(est["tip"] - truth) / est["std"]).max(axis=1)
            ok = est["status"] == "ok"
            bad = ok & (off >= 4.0)
            worst = off[ok].max() if ok.any() else 0.0  # the ok rows' largest
            print(
                f"  {method} seed {seed}: ok rows >= 4 std off {bad.sum()} (worst ok row "
                f"{worst:.1f} std), "
                f"ok share {ok.mean():.2f}",
                flush=True,
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", nargs="+", choices="abcd", default=list("abcd"))
    p.add_argument("--methods", nargs="+", default=["mhe", "ekf", "ukf"])
    p.add_argument("--rods", nargs="+", type=Path, default=[DATA / "rod2"],
                   help="folders of two-section rod recordings (NAME_truth.csv and "
                   "NAME_raw.csv / NAME_tilt.csv)")  # fmt: skip
    p.add_argument("--cases", nargs="+", default=["raw", "tilt"], help="recording kinds")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2, 3, 4], help="paper3d seeds")
    p.add_argument("--estimate-options", default="",
                   help="part (a) only (the other parts run with the defaults): options "
                   "for each of its estimates, one string: "
                   "--estimate-options='--model-error-floor-deg 0'")  # fmt: skip
    args = p.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        if "a" in args.only:
            target_a(tmp, args.methods, args.rods, args.cases, shlex.split(args.estimate_options))
        if "b" in args.only:
            target_b(tmp, args.methods, args.cases)
        if "c" in args.only:
            target_c(tmp, args.methods, args.seeds)
        if "d" in args.only:
            target_d(tmp, args.methods, args.seeds)


if __name__ == "__main__":
    main()
