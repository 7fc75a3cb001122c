"""The gyro-fusing attitude filters (``--imu-model tilt --attitude madgwick|mahony``)
on the shipped two-section rod recordings, with and without a calibrated robot file.

For each rod recording ``continuum-mhe calibrate --from NAME_rest.csv --robot
two-section --write-robot CAL`` calibrates the robot file at rest as a user would (each
IMU's mounting and gyro bias); then ``continuum-mhe estimate NAME_raw.csv --robot ROBOT
--method M --imu-model tilt --attitude A`` runs on CAL and on the shipped robot file
(``two-section``, uncalibrated), and ``continuum-mhe evaluate --json`` against the
truth. ``estimate`` refuses madgwick on IMUs without a calibrated gyro bias; its
uncalibrated row runs on the shipped robot file with a gyro bias of 1e-12 rad/s per
IMU, which subtracts nothing (the readings' bias as read). Prints per estimate the
tip error's mean (mm) and the ``ok`` rows more than 4 of their own standard
deviations off on a tip axis, of the ``ok`` rows::

    python tools/attitude_study.py                       # every rod, EKF and MHE
    python tools/attitude_study.py --only planar-s --methods ekf
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).parents[1] / "src/continuum_mhe/data"
DATA = ROOT / "rod2"
RODS = ("planar-s", "spatial", "spatial-tendon", "spatial-stiff-torsion")
ATTITUDES = ("madgwick", "mahony")


def cli(*argv: str) -> str:
    """``continuum-mhe ARGV`` in a new process: its standard output (a failure raised)."""
    done = subprocess.run(
        [sys.executable, "-m", "continuum_mhe", *argv], check=True, capture_output=True, text=True
    )
    return done.stdout


def as_read(folder: Path) -> Path:
    """The shipped two-section robot file with a gyro bias of 1e-12 rad/s per IMU: the
    readings' bias as read, which ``estimate`` lets madgwick fuse."""
    text = (ROOT / "robots/two_section.toml").read_text()
    text = text.replace("[[imu]]\n", "[[imu]]\ngyro_bias = [1e-12, 0.0, 0.0]\n")
    path = folder / "as_read.toml"
    path.write_text(text)
    return path


def summary(estimate: Path, truth: Path, robot: str) -> str:
    """The tip error's mean and the ``ok`` rows far off, from ``evaluate --json``."""
    report = json.loads(cli("evaluate", str(estimate), str(truth), "--robot", robot, "--json"))
    ok = report["calibration_ok"] or {"tip_far": 0, "tip_far_of": 0}
    return f"{report['tip_mean_mm']:6.2f} mm; ok far off {ok['tip_far']:3d} of {ok['tip_far_of']}"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--methods", nargs="+", default=["ekf", "mhe"], help="estimators")
    p.add_argument("--only", nargs="+", default=list(RODS), help="recordings (default: all)")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        bare = str(as_read(folder))
        for name in a.only:
            cal = str(folder / f"{name}.toml")
            cli("calibrate", "--from", str(DATA / f"{name}_rest.csv"), "--robot",
                "two-section", "--write-robot", cal)  # fmt: skip
            for label, robot in (("uncalibrated", None), ("calibrated", cal)):
                for method in a.methods:
                    for attitude in ATTITUDES:
                        used = robot or (bare if attitude == "madgwick" else "two-section")
                        out = folder / "e.csv"
                        cli("estimate", str(DATA / f"{name}_raw.csv"), "--robot", used,
                            "--method", method, "--imu-model", "tilt", "--attitude", attitude,
                            "-o", str(out), "--overwrite")  # fmt: skip
                        result = summary(out, DATA / f"{name}_truth.csv", used)
                        print(f"{name:22s} {label:12s} {method} {attitude:8s} {result}", flush=True)


if __name__ == "__main__":
    main()
