"""Does a tendon robot gain from ``calibrate --write-robot`` before ``estimate``?
(docs/tendon.md#the-estimator, docs/tendon-studies.md#calibrating-the-imus-at-rest).

For each seed the generator's recordings (``continuum-mhe rod tendon --scenario NAME
--seed S``: the same IMUs' errors in every scenario of one seed and duration) and a rest
recording of the same IMUs (the rod held in its first, straight and still state, fresh
noise: :func:`~continuum_mhe.simulation.cosserat_sections.write_rest_recording`, which
``rod tendon`` writes as ``NAME_rest.csv`` beside each recording).
Then, through the command line: ``calibrate --from rest.csv --robot tendon-two-section
--write-robot cal.toml``, and per scenario and IMU kind (raw, tilt) ``estimate`` with
the shipped robot file and with ``cal.toml`` (``--inputs`` the tensions) and ``evaluate
--skip-start 1``. Prints one JSON line per run: the mean tip error (mm), the tip force's
rms error (N) and the statuses of all rows. ``--board-rpy R P Y`` (degrees) turns every
IMU's board on its disk by that mounting (``v_disk = Rz(Y) Ry(P) Rx(R) v_board``, as a
robot file's ``mount_rpy``) in the raw recordings and the rest recording (a board
mounted further off than the estimator's misalignment prior; raw IMUs alone).
``--parts``: also with the calibrated robot file's ``mount_rpy`` alone (``mount_only``)
and its ``gyro_bias`` alone (``gyro_bias_only``).

    python tools/tendon_calibration_study.py OUT [--seeds 1 2 3]
        [--scenarios unloaded force-29 twist-08] [--imu raw tilt] [--duration 8]
        [--board-rpy R P Y] [--parts]
"""

from __future__ import annotations

import argparse
import collections
import json
import subprocess
import sys
from pathlib import Path

ROBOT = "tendon-two-section"


def cli(*args: str) -> str:
    """``continuum-mhe ARGS`` in this interpreter; its standard output."""
    done = subprocess.run(
        [sys.executable, "-m", "continuum_mhe.cli", *args],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode:
        raise SystemExit(f"continuum-mhe {' '.join(args)} failed: {done.stderr.strip()}")
    return done.stdout


def make_recordings(out: Path, seeds: list[int], scenarios: list[str], duration: float) -> None:
    """Each seed's recordings of ``scenarios`` and its ``rest_raw.csv`` under
    ``out/seedS``; each motion simulated once, the files written where missing."""
    from continuum_mhe.io.robot_file import read_robot
    from continuum_mhe.simulation.cosserat_sections import DEFAULT_IMU, write_rest_recording
    from continuum_mhe.simulation.cosserat_tendon import (
        quasi_static_trajectory,
        write_tendon_recording,
    )

    robot = read_robot(ROBOT)
    for s in seeds:
        (out / f"seed{s}").mkdir(parents=True, exist_ok=True)
    for name in scenarios:
        missing = [s for s in seeds if not (out / f"seed{s}" / f"{name}_truth.csv").exists()]
        rest_missing = [s for s in seeds if not (out / f"seed{s}" / "rest_raw.csv").exists()]
        if not missing and not rest_missing:
            continue
        traj = quasi_static_trajectory(robot, name, duration)
        for s in missing:
            write_tendon_recording(
                out / f"seed{s}", name, robot, name, duration, seed=s, trajectory=traj
            )
        for s in rest_missing:  # the first state: straight, no tension, no force
            folder = out / f"seed{s}"
            write_rest_recording(folder, "rest", traj.sections, DEFAULT_IMU, seed=s)
            (folder / "rest_rest.csv").rename(folder / "rest_raw.csv")


def turn_boards(folder: Path, turned: Path, rpy: tuple[float, float, float]) -> None:
    """``folder``'s raw recordings (rest included) with every IMU's board turned by the
    mounting ``rpy`` (degrees), its tensions and truth as they are, into ``turned``."""
    import shutil

    import numpy as np

    from continuum_mhe.io.raw_imu import mount_rotation

    turned.mkdir(exist_ok=True)
    back = mount_rotation(rpy).T  # disk frame to board frame
    for path in folder.iterdir():
        if path.name.endswith(("_tensions.csv", "_truth.csv")):
            shutil.copy(path, turned / path.name)
        elif path.name.endswith("_raw.csv"):
            head, *rows = path.read_text().splitlines()
            table = np.array([[float(v) for v in row.split(",")] for row in rows])
            for c in range(1, table.shape[1], 3):  # each IMU's accelerometer, then gyro
                table[:, c : c + 3] = table[:, c : c + 3] @ back.T
            lines = [head, *(",".join(f"{v:.9g}" for v in row) for row in table)]
            (turned / path.name).write_text("\n".join(lines) + "\n")


def statuses(estimate: Path) -> dict[str, int]:
    """The count of each status over every row of an estimate file."""
    from continuum_mhe.io.state_tables import read_state_table

    counts = collections.Counter(read_state_table(estimate).status.tolist())
    return dict(sorted(counts.items()))


def run(folder: Path, name: str, imu: str, robot: str, tag: str) -> dict[str, object]:
    est = folder / f"{name}_{imu}_{tag}_est.csv"
    cli(
        "estimate",
        str(folder / f"{name}_{imu}.csv"),
        "--robot",
        robot,
        "--inputs",
        str(folder / f"{name}_tensions.csv"),
        "-o",
        str(est),
        "--overwrite",
    )
    report = json.loads(
        cli(
            "evaluate",
            str(est),
            str(folder / f"{name}_truth.csv"),
            "--robot",
            ROBOT,
            "--skip-start",
            "1",
            "--json",
        )
    )
    return {
        "tip_mm": round(report["tip_mean_mm"], 3),
        "force_rms_n": round(report["tip_force_rms_n"], 4),
        "status": statuses(est),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="the folder of the recordings (seedS/)")
    parser.add_argument(
        "--seeds", type=int, nargs="+", default=[1, 2, 3], help="the IMUs' error draws"
    )
    parser.add_argument("--scenarios", nargs="+", default=["unloaded", "force-29", "twist-08"])
    parser.add_argument("--imu", nargs="+", default=["raw", "tilt"], choices=["raw", "tilt"])
    parser.add_argument("--duration", type=float, default=8.0, help="s, each recording's")
    parser.add_argument(
        "--board-rpy",
        type=float,
        nargs=3,
        metavar=("R", "P", "Y"),
        help="degrees: every IMU's board turned so on its disk (raw IMUs alone)",
    )
    parser.add_argument(
        "--parts",
        action="store_true",
        help="also the calibrated file's mount_rpy alone and its gyro_bias alone",
    )
    args = parser.parse_args()
    make_recordings(args.out, args.seeds, args.scenarios, args.duration)
    if args.board_rpy:
        args.imu = ["raw"]
    for s in args.seeds:
        folder = args.out / f"seed{s}"
        if args.board_rpy:
            rpy = (args.board_rpy[0], args.board_rpy[1], args.board_rpy[2])
            turned = args.out / f"seed{s}-board{'_'.join(f'{v:g}' for v in rpy)}"
            turn_boards(folder, turned, rpy)
            folder = turned
        cal = folder / "cal.toml"
        if not cal.exists():
            rest = str(folder / "rest_raw.csv")
            cli("calibrate", "--from", rest, "--robot", ROBOT, "--write-robot", str(cal))
        for name in args.scenarios:
            for imu in args.imu:
                row: dict[str, object] = {"seed": s, "scenario": name, "imu": imu}
                if args.board_rpy:
                    row["board_rpy"] = args.board_rpy
                row["shipped"] = run(folder, name, imu, ROBOT, "shipped")
                row["calibrated"] = run(folder, name, imu, str(cal), "cal")
                if args.parts:
                    for part, drop in (
                        ("mount_only", "gyro_bias"),
                        ("gyro_bias_only", "mount_rpy"),
                    ):
                        lines = cal.read_text().splitlines(keepends=True)
                        robot = folder / f"cal_{part}.toml"
                        robot.write_text("".join(ln for ln in lines if not ln.startswith(drop)))
                        row[part] = run(folder, name, imu, str(robot), part)
                print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
