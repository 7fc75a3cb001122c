"""Which IMU error limits each two-section rod recording: simulate the recording's rod
once, sample it again with one error source at a time (the same random draws, the
others zeroed), and run an estimator on each variant beside the PCC-model floor.

    python tools/rod_error_sources.py [--only NAME ...] [--out DIR] [--method ekf]
    # needs the rod extra (PyElastica); the variants go to DIR (a temporary folder by
    # default), never into the shipped data

Variants: ``shipped`` (every error, as shipped), ``no-calibration-errors`` (no
accelerometer bias, no board misalignment), ``accel-bias`` (bias only of the two),
``misalignment``, ``misalignment-xy`` (about the board's x and y only),
``misalignment-z`` (about the backbone only), ``noise-only`` (no gyro bias either),
``noise-only-no-own-acceleration`` (as ``noise-only``, but the accelerometers do not
feel the IMU's own acceleration). Each is estimated with raw IMUs and the gyro bias
estimated (the study's ``raw+bias`` case; with ``--own-acceleration``, ``raw+bias+own``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.simulation.cosserat_sections import (
    DEFAULT_IMU,
    SectionRodSettings,
    simulate_sections,
    write_trajectory_recording,
)

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
_CLEAN = replace(DEFAULT_IMU, accel_bias=0.0, misalignment_deg=0.0)
#: name -> (IMU settings, misalignment axes kept, own acceleration felt)
VARIANTS = {
    "shipped": (DEFAULT_IMU, (0, 1, 2), True),
    "no-calibration-errors": (_CLEAN, (0, 1, 2), True),
    "accel-bias": (replace(DEFAULT_IMU, misalignment_deg=0.0), (0, 1, 2), True),
    "misalignment": (replace(DEFAULT_IMU, accel_bias=0.0), (0, 1, 2), True),
    "misalignment-xy": (replace(DEFAULT_IMU, accel_bias=0.0), (0, 1), True),
    "misalignment-z": (replace(DEFAULT_IMU, accel_bias=0.0), (2,), True),
    "noise-only": (replace(_CLEAN, gyro_bias=0.0), (0, 1, 2), True),
    "noise-only-no-own-acceleration": (replace(_CLEAN, gyro_bias=0.0), (0, 1, 2), False),
}


def rod_settings(info: dict[str, object]) -> SectionRodSettings:
    """The rod of a shipped recording, from its info (G = 5E needs the finer step)."""
    shear = float(info["shear_ratio"])  # type: ignore[arg-type]
    return SectionRodSettings(
        shear_ratio=shear,
        sim_dt=5e-6 if shear > 1 else 2e-5,
        drive=info["drive"],  # type: ignore[arg-type]
    )


def main() -> None:
    from two_section_rod_study import evaluate  # type: ignore[import-not-found]

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "--only", nargs="+", metavar="NAME", help="recordings (default: all but spatial)"
    )
    p.add_argument("--out", type=Path, help="folder for the variants (default: a temporary one)")
    p.add_argument("--method", default="ekf", choices=["mhe", "ekf", "ukf"])
    p.add_argument(
        "--own-acceleration", action="store_true", help="the model includes it (--own-acceleration)"
    )
    args = p.parse_args()
    warnings.simplefilter("ignore")
    names = args.only or ["planar-s", "spatial-tendon", "spatial-stiff-torsion"]
    robot = read_robot("two-section")
    with tempfile.TemporaryDirectory() as tmp:
        root = args.out or Path(tmp)
        for name in names:
            info = json.loads((DATA / f"{name}_info.json").read_text())
            settings = rod_settings(info)
            traj = simulate_sections(settings, str(info["scenario"]), 12.0)
            floor = info["pcc_floor_mean_mm"]
            what = " + own acceleration" if args.own_acceleration else ""
            print(f"== {name}: PCC floor {floor:.2f} mm ({args.method}, raw+bias{what})")
            for variant, (imu, axes, felt) in VARIANTS.items():
                out = root / variant
                out.mkdir(parents=True, exist_ok=True)
                tr = traj if felt else replace(traj, velocities=np.zeros_like(traj.velocities))
                write_trajectory_recording(
                    out, name, tr, settings, str(info["scenario"]), imu, 0, axes
                )
                mean = evaluate(
                    robot, out / f"{name}_raw.csv", "direct", True, False,
                    out / f"{name}_truth.csv", 1e-6, (args.method,), own=args.own_acceleration,
                )[args.method][0]  # fmt: skip
                print(f"   {variant:32s} tip {mean:6.2f} mm mean ({mean / floor:.2f}x floor)")


if __name__ == "__main__":
    main()
