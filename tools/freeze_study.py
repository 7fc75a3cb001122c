"""A raw IMU frozen for half a second on a three-section robot at 100 Hz: the tip error
with ``--freeze`` at its default and at 1 s, with and without ``--own-acceleration``.

The robot hangs (``z-down``), sections of 0.12, 0.15 and 0.10 m, a raw IMU at each
section's end; ``continuum-mhe simulate spatial --imu raw --dt 0.01 --duration 20
--seed 3``; IMU 2 repeats its reading of t = 8 s until 8.49 s. Prints, per setting, the
mean and largest tip error (mm) over the recording and from 8 s to 8.5 s, and the
statuses. Also the numbers of docs/options.md for simulated readings (``--reading-bias-deg
0 --model-error-floor-deg 0``, with ``--own-acceleration --noise-deg 0.2`` and without)::

    python tools/freeze_study.py [DIR]   # DIR: where the files go (default: a temporary one)
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from continuum_mhe.io.state_tables import read_state_table

ROBOT = """mounting = "z-down"
[[section]]
length = 0.12
theta_max = 3.0
[[section]]
length = 0.15
theta_max = 3.0
[[section]]
length = 0.10
theta_max = 3.0
[[imu]]
section = 1
[[imu]]
section = 2
[[imu]]
section = 3
"""
FREEZE_ROWS = range(801, 850)  # rows repeating row 800's reading (t = 8.00 s)


def cli(*args: str) -> None:
    subprocess.run(["continuum-mhe", *args], check=True, capture_output=True)


def errors(est: Path, truth: Path) -> str:
    e, t = read_state_table(est), read_state_table(truth)
    tip = np.column_stack([e.column(c) for c in "xyz"])
    true = np.column_stack([t.column(c) for c in "xyz"])
    err = np.linalg.norm(tip - true, axis=1) * 1e3
    during = (e.t >= 8.0) & (e.t < 8.5)
    statuses, counts = np.unique(e.status, return_counts=True)
    shown = ", ".join(f"{s}: {c}" for s, c in zip(statuses, counts))
    return (
        f"tip mean {np.mean(err):.2f} max {np.max(err):.2f} mm, 8 to 8.5 s mean "
        f"{np.mean(err[during]):.2f} mm ({shown})"
    )


def coverage(est: Path, truth: Path) -> str:
    e, t = read_state_table(est), read_state_table(truth)
    ok = e.status == "ok"
    assert e.std is not None
    inside = [
        np.mean(np.abs(e.column(c) - t.column(c))[ok] <= 1.96 * e.std[ok, e.names.index(c)])
        for c in "xyz"
    ]
    tip = np.column_stack([e.column(c) - t.column(c) for c in "xyz"])
    mean = np.mean(np.linalg.norm(tip, axis=1)) * 1e3
    return f"tip mean {mean:.2f} mm, ok rows' coverage " + " / ".join(f"{c:.3f}" for c in inside)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", nargs="?", type=Path, help="where the files go (default: a new one)")
    folder = p.parse_args().folder or Path(tempfile.mkdtemp())
    folder.mkdir(parents=True, exist_ok=True)
    robot, clean, truth = folder / "robot3.toml", folder / "clean.csv", folder / "truth.csv"
    robot.write_text(ROBOT)
    cli("simulate", "spatial", "--robot", str(robot), "--imu", "raw", "--dt", "0.01",
        "--duration", "20", "--seed", "3", "-o", str(clean), "--truth", str(truth),
        "--overwrite")  # fmt: skip
    lines = clean.read_text().splitlines()
    names = lines[0].split(",")
    cols = [names.index(f"{c}_2") for c in ("ax", "ay", "az", "gx", "gy", "gz")]
    rows = [ln.split(",") for ln in lines[1:]]
    for r in FREEZE_ROWS:
        for c in cols:
            rows[r][c] = rows[FREEZE_ROWS.start - 1][c]
    frozen = folder / "frozen.csv"
    frozen.write_text("\n".join([lines[0], *(",".join(r) for r in rows)]) + "\n")
    for freeze in ("default", "1"):
        for own in ((), ("--own-acceleration",)):
            out = folder / f"e-{freeze}-{len(own)}.csv"
            extra = () if freeze == "default" else ("--freeze", freeze)
            cli("estimate", str(frozen), "--robot", str(robot), "-o", str(out),
                "--overwrite", *extra, *own)  # fmt: skip
            print(f"--freeze {freeze} {' '.join(own)}: {errors(out, truth)}")
    none = ("--reading-bias-deg", "0", "--model-error-floor-deg", "0")
    for extra in ((), ("--own-acceleration", "--noise-deg", "0.2")):
        out = folder / f"c-{len(extra)}.csv"
        cli("estimate", str(clean), "--robot", str(robot), "-o", str(out), "--overwrite",
            *none, *extra)  # fmt: skip
        print(f"clean, {' '.join(none + extra)}: {coverage(out, truth)}")


if __name__ == "__main__":
    main()
