"""What the consistency check flags and what it leaves ``ok`` (docs/options.md,
"Consistency: what ``ok`` means"), one part at a time:

* ``rate``: ``simulate("paper3d", duration=60, seed=S)`` (one 0.2 m section, 2 degrees
  of noise, data that agree with the model), S = 0 to ``--seeds`` - 1, estimated by each
  method with its defaults (``make_estimator(method, make_formulation("bend"))``): the
  rows ``inconsistent`` in all, per 10,000 rows, and the stretches they come in;
* ``quiet``: the shipped two-section rod recordings (``rod2``, raw and tilt, the EKF
  with its defaults): the level the readings' innovations scattered at while the model
  followed them (``ConsistencyCheck.quiet_scale``, in units of what ``R`` predicts) at
  the recording's end and at its least, and how many times less than ``R`` that is;
* ``slow``: ``continuum-mhe simulate paper3d --duration 120 --dt 1 --seed S`` (121
  samples at 1 Hz), ``continuum-mhe estimate --method ekf``, S = 0 to 4: the statuses,
  the rows more than 50 mm off the truth and those of them ``ok``, and the rows not
  ``ok`` that are 4 or more of their standard deviations off on a tip axis;
* ``upside``: ``continuum-mhe simulate paper3d --duration 8 --seed S`` with reading 60
  turned upside down (as ``tools/honesty_study.py`` part (c)), estimated by the MHE, the
  EKF and the UKF, S = 0 to 4: the statuses and the rows more than 50 mm off;
* ``assumed``: 16 random one- and two-section robots (as
  ``tests/test_consistency.py``'s pooled test: lengths 0.1 to 0.4 m, ``paper3d`` or
  ``spatial``, 10 s at 20 Hz, seeds 0 to 15), noise as assumed, IMUs mounted exactly
  and said to be (``NoiseSettings(reading_bias_std=0, model_error_std=0)``), the EKF:
  each recording's statuses and the per-axis coverage of its ``ok`` rows' 95 % intervals;
* ``overbend``: ``continuum-mhe simulate planar-overbend --mounting z-down --imu raw
  --seed 13 --duration 15``, its rows from 8 s on, estimated without ``--mounting`` (the
  MHE and the EKF): the angle its readings put the IMU from the standing robot's
  straight pose (at every row, and the start check's median), the rows ``ok`` and the
  tip's mean error.

::

    python tools/consistency_catches.py                  # every part
    python tools/consistency_catches.py --only rate --seeds 50
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import tempfile
import warnings
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
from honesty_study import DATA, _simulate, estimate, truth_tip, upside_down

from continuum_mhe.cli.app import main as cli_main
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions, _imu_angles, imu_start_angle
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.results import Measurement
from continuum_mhe.settings import NoiseSettings
from continuum_mhe.simulation.scenarios import Recording, simulate, simulate_robot

Z95 = 1.959964
RODS = ("planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial")


def _stretches(flagged: np.ndarray) -> list[int]:
    """The lengths of the runs of consecutive True rows."""
    rows = np.flatnonzero(flagged)
    if not len(rows):
        return []
    return [len(r) for r in np.split(rows, np.flatnonzero(np.diff(rows) > 1) + 1)]


def part_rate(seeds: int, methods: list[str]) -> None:
    print(f"rate: paper3d, 60 s at 20 Hz, seeds 0 to {seeds - 1}; rows inconsistent")
    f = make_formulation("bend", Robot.single(0.2))
    recordings = [simulate("paper3d", duration=60.0, seed=s) for s in range(seeds)]
    for method in methods:
        rows, runs = 0, []
        for rec in recordings:
            status = np.asarray(make_estimator(method, f).run(rec.t, rec.z).status)  # type: ignore[arg-type]
            rows += len(status)
            runs += _stretches(status == "inconsistent")
        flagged = sum(runs)
        longer = sorted(r for r in runs if r > 1)
        print(
            f"  {method}: {flagged} of {rows} rows ({1e4 * flagged / rows:.1f} in 10,000); "
            f"{sum(r == 1 for r in runs)} single rows, {len(longer)} stretches"
            + (f" of {longer[0]} to {longer[-1]} rows" if longer else ""),
            flush=True,
        )


def part_quiet() -> None:
    print("quiet: rod2, EKF; the readings' quiet level (units of R) at the end and least")
    robot = read_robot("two-section")
    for name in RODS:
        for case in ("raw", "tilt"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                data = load_input(
                    DATA / "rod2" / f"{name}_{case}.csv",
                    InputOptions(),
                    make_formulation("bend", robot),
                )
                est = make_estimator("ekf", data.formulation)
                est.reset()
                quiet = []
                for t, z in zip(data.t, data.z):
                    est.step(Measurement(float(t), z))
                    quiet.append(est._consistency.core.quiet_scale)  # type: ignore[attr-defined]
            q = np.asarray(quiet)
            print(
                f"  {name} {case}: end {q[-1]:.3f} ({1 / q[-1]:.1f} times less than R), "
                f"least {q.min():.3f} ({1 / q.min():.1f} times)",
                flush=True,
            )


def _statuses(
    est: dict[str, np.ndarray], truth: np.ndarray
) -> tuple[np.ndarray, np.ndarray, dict[str, int]]:
    """An estimate's statuses, which rows are more than 50 mm off the truth's tip, and
    the count of each status."""
    status = est["status"]
    far = np.linalg.norm(est["tip"] - truth, axis=1) > 0.05
    return status, far, dict(sorted(Counter(status.tolist()).items()))


def part_slow(tmp: Path) -> None:
    print("slow: paper3d at 1 Hz (121 samples), EKF: statuses; rows > 50 mm off")
    for seed in range(5):
        rec, truth_path = _simulate(
            tmp, f"slow_{seed}", "--duration", "120", "--dt", "1", "--seed", str(seed)
        )
        truth = truth_tip(truth_path)
        est = estimate(tmp, rec, "ekf")
        status, far, counts = _statuses(est, truth)
        off = (np.abs(est["tip"] - truth) / est["std"]).max(axis=1)
        flagged = status != "ok"
        print(
            f"  seed {seed}: {counts}; "
            f"{far.sum()} rows > 50 mm off, {np.sum(far & ~flagged)} of them ok; "
            f"not ok and >= 4 std off on a tip axis {np.sum(flagged & (off >= 4))} "
            f"(the largest {np.nanmax(off[flagged]):.1f} std)",
            flush=True,
        )


def part_upside(tmp: Path) -> None:
    print("upside: paper3d, 8 s, reading 60 upside down: statuses; rows > 50 mm off")
    for seed in range(5):
        rec, truth_path = _simulate(tmp, f"upside_{seed}", "--duration", "8", "--seed", str(seed))
        upside_down(rec, 60)
        truth = truth_tip(truth_path)
        for method in ("mhe", "ekf", "ukf"):
            status, far, counts = _statuses(estimate(tmp, rec, method), truth)
            print(
                f"  seed {seed} {method}: {counts}; "
                f"row 60 {status[60]}; {far.sum()} rows > 50 mm off, "
                f"{np.sum(far & (status == 'ok'))} of them ok",
                flush=True,
            )


def random_recording(
    length: float, seed: int, two: bool, reading_bias_std: float
) -> tuple[Robot, Recording]:
    """``tests/test_consistency.py``'s ``_recording`` with the noise as assumed: one
    section (``paper3d``) or two (``spatial``, 0.55 and 0.45 of ``length``), 10 s at 20
    Hz, each reading's constant error drawn with ``reading_bias_std`` (rad)."""
    if not two:
        robot = Robot.single(length)
        rec = simulate(
            "paper3d", duration=10.0, length=length, seed=seed, noise_deg=2.0,
            noise_model="tangent",
        )  # fmt: skip
    else:
        robot = Robot(
            (Section(0.55 * length), Section(0.45 * length)), (ImuPlacement(0), ImuPlacement(1))
        )
        rec = simulate_robot("spatial", robot, duration=10.0, dt=0.05, seed=seed, noise_deg=2.0)
    bias = np.random.default_rng(seed).normal(size=rec.z.shape[1]) * reading_bias_std
    return robot, replace(rec, z=rec.z + bias)


def random_recordings(reading_bias_std: float) -> list[tuple[Robot, Recording]]:
    """The 16 recordings of ``tests/test_consistency.py``'s pooled test (lengths drawn
    with seed 7; odd seeds two sections)."""
    rng = np.random.default_rng(7)
    return [
        random_recording(rng.uniform(0.1, 0.4), s, bool(s % 2), reading_bias_std) for s in range(16)
    ]


def part_assumed() -> None:
    print("assumed: 16 random PCC robots, EKF, no constant error: statuses; ok coverage")
    noise = NoiseSettings(reading_bias_std=0.0, model_error_std=0.0)
    covers, pooled = [], []
    for k, (robot, rec) in enumerate(random_recordings(0.0)):
        s = make_estimator("ekf", make_formulation("bend", robot, noise)).run(rec.t, rec.z)
        status = np.asarray(s.status)
        ok = status == "ok"
        covered = np.abs(s.output[ok, :3] - rec.truth[ok, :3]) <= Z95 * s.std[ok, :3]
        covers.append(covered.mean(axis=0))
        pooled.append(covered)
        c = covers[-1]
        length = sum(x.length for x in robot.sections)
        print(
            f"  seed {k} ({robot.n_sections} section(s), {length:.3f} m): "
            f"{dict(sorted(Counter(status.tolist()).items()))}; "
            f"ok coverage {c[0]:.3f} / {c[1]:.3f} / {c[2]:.3f}",
            flush=True,
        )
    c = np.asarray(covers)
    p = np.concatenate(pooled).mean(axis=0)
    print(
        f"  per recording and axis {c.min():.3f} to {c.max():.3f}; "
        f"pooled {p[0]:.3f} / {p[1]:.3f} / {p[2]:.3f}"
    )


def part_overbend(tmp: Path) -> None:
    print("overbend: planar-overbend hanging, rows from 8 s, estimated as standing")
    rec, truth = tmp / "overbend.csv", tmp / "overbend_truth.csv"
    argv = ["simulate", "planar-overbend", "--mounting", "z-down", "--imu", "raw"]
    argv += ["--seed", "13", "--duration", "15", "-o", str(rec), "--truth", str(truth)]
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        if cli_main(argv) != 0:
            raise SystemExit("simulate planar-overbend failed")
    for path in (rec, truth):  # awk -F, 'NR==1 || $1>=8'
        lines = path.read_text().splitlines()
        keep = [lines[0]] + [ln for ln in lines[1:] if float(ln.split(",")[0]) >= 8.0]
        path.write_text("\n".join(keep) + "\n")
    f = make_formulation("bend", Robot.single(0.2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = load_input(rec, InputOptions(), f)
    angles = np.degrees(_imu_angles(data.z, data.formulation, 0))
    start = imu_start_angle(data.z, data.formulation, 0)
    assert start is not None
    print(
        f"  the IMU {np.nanmin(angles):.1f} to {np.nanmax(angles):.1f} degrees from the standing "
        f"robot's straight pose ({len(angles)} rows; the start check's median "
        f"{math.degrees(start):.1f})"
    )
    tip = truth_tip(truth)
    for method in ("mhe", "ekf"):
        est = estimate(tmp, rec, method)
        err = np.linalg.norm(est["tip"] - tip, axis=1) * 1e3
        print(
            f"  {method}: {dict(sorted(Counter(est['status'].tolist()).items()))}; "
            f"tip {np.nanmean(err):.1f} mm off on average"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parts = ["rate", "quiet", "slow", "upside", "assumed", "overbend"]
    p.add_argument("--only", nargs="+", choices=parts, default=parts)
    p.add_argument("--seeds", type=int, default=200, help="part rate's recordings (200)")
    p.add_argument("--methods", nargs="+", default=["ekf", "ukf", "mhe"], help="part rate's")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        if "rate" in args.only:
            part_rate(args.seeds, args.methods)
        if "quiet" in args.only:
            part_quiet()
        if "slow" in args.only:
            part_slow(tmp)
        if "upside" in args.only:
            part_upside(tmp)
        if "assumed" in args.only:
            part_assumed()
        if "overbend" in args.only:
            part_overbend(tmp)


if __name__ == "__main__":
    main()
