"""The IMUs' twist about the backbone's tangent (``--imu-twist``) on the shipped
two-section rod recordings, against the PCC model's torsion-free frames.

For each rod recording the robot file is calibrated at rest as a user would (``continuum-mhe
calibrate --from NAME_rest.csv --robot two-section --write-robot``: each IMU's mounting
and gyro bias), then ``continuum-mhe estimate NAME_raw.csv --robot CAL --method M``
runs with and without ``--imu-twist`` (``--uncalibrated``: the shipped robot file
instead, the gyro biases estimated). ``--tendon``: the shipped tendon robot's recordings
(``data/tendon``, no rest recordings: uncalibrated) without their tensions, with the
PCC robot of its geometry (0.2 m + 0.2 m, ``theta_max = 3``, an IMU at each section's
end). Prints per estimate the tip error's mean and
largest value (mm), the rows ``ok``, those of them more than 20 mm off and those more
than 4 of their own standard deviations off on a tip axis (and over 5 mm), and the
``ok`` rows' 95 % interval coverage of the tip per axis::

    python tools/imu_twist_study.py                       # every rod, MHE, EKF and UKF
    python tools/imu_twist_study.py --only spatial --methods ekf --uncalibrated
    python tools/imu_twist_study.py --tendon --methods mhe ekf
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from honesty_study import PCC_TENDON_GEOMETRY  # the tendon robot's PCC geometry

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
RODS = ("planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial")
TENDON = DATA.parent / "tendon"
TENDON_RECORDINGS = ("unloaded", "force-08", "force-29", "twist-08", "twist-29")


def cli(*argv: str) -> None:
    """``continuum-mhe ARGV`` in a new process (its output dropped; a failure raised)."""
    subprocess.run([sys.executable, "-m", "continuum_mhe", *argv], check=True, capture_output=True)


def read(path: Path) -> tuple[list[str], list[list[str]]]:
    """The header and rows of a CSV whose comment lines start with ``#``."""
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    return lines[0].split(","), [ln.split(",") for ln in lines[1:]]


def summary(estimate: Path, truth: Path) -> str:
    """The tip error, the rows ``ok`` and how far off they are, and their coverage."""
    head, rows = read(estimate)
    t_head, t_rows = read(truth)

    def cols(names: list[str], table: list[list[str]], keys: tuple[str, ...]) -> np.ndarray:
        idx = [names.index(k) for k in keys]
        return np.array([[float(r[i]) if r[i] else np.nan for i in idx] for r in table])

    tip = cols(head, rows, ("x", "y", "z")) - cols(t_head, t_rows, ("x", "y", "z"))
    std = cols(head, rows, ("std_x", "std_y", "std_z"))
    ok = np.array([r[head.index("status")] == "ok" for r in rows])
    err = np.linalg.norm(tip, axis=1) * 1e3
    far = np.any(np.abs(tip) > 4 * std, axis=1)  # a row without an estimate: not far
    cover = (np.abs(tip[ok]) <= 1.96 * std[ok]).mean(axis=0)
    return (
        f"mean {np.nanmean(err):6.2f}, max {np.nanmax(err):6.1f} mm; ok {ok.sum():3d}, of them "
        f"> 20 mm off {(ok & (err > 20)).sum():3d}, > 4 std off {(ok & far & (err > 5)).sum():3d};"
        f" coverage {' / '.join(f'{c:.2f}' for c in cover)}"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--methods", nargs="+", default=["mhe", "ekf", "ukf"], help="estimators")
    p.add_argument("--only", nargs="+", help="recordings (default: every rod, or tendon one)")
    p.add_argument("--uncalibrated", action="store_true", help="the shipped robot file")
    p.add_argument("--tendon", action="store_true", help="the tendon robot, no tensions")
    a = p.parse_args()
    data = TENDON if a.tendon else DATA
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        pcc = folder / "pcc.toml"
        pcc.write_text(PCC_TENDON_GEOMETRY)
        for name in a.only or (TENDON_RECORDINGS if a.tendon else RODS):
            robot = str(pcc) if a.tendon else "two-section"
            if not (a.uncalibrated or a.tendon):
                robot = str(folder / f"{name}.toml")
                cli("calibrate", "--from", str(DATA / f"{name}_rest.csv"), "--robot",
                    "two-section", "--write-robot", robot)  # fmt: skip
            for method in a.methods:
                for twist in ([], ["--imu-twist"]):
                    out = folder / "e.csv"
                    cli("estimate", str(data / f"{name}_raw.csv"), "--robot", robot, "--method",
                        method, *twist, "-o", str(out), "--overwrite")  # fmt: skip
                    label = "twist" if twist else "PCC"
                    result = summary(out, data / f"{name}_truth.csv")
                    print(f"{name:22s} {method} {label:5s} {result}", flush=True)


if __name__ == "__main__":
    main()
