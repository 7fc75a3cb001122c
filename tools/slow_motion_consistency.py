"""Rows ``inconsistent`` on model-consistent raw readings of a slow motion.

A three-section robot (0.12 + 0.10 + 0.08 m, an IMU at each section's end) follows the
``spatial`` scenario ``SLOWDOWN`` times slower (120 / SLOWDOWN s of the scenario
stretched to 120 s, at 20 Hz), its raw readings simulated along that slow truth (noise
and biases as ``simulate --imu raw``), then estimated by ``continuum-mhe estimate
--method ekf`` with the command line's defaults. Prints the rows ``inconsistent``, the
stretches they come in, and the mean tip error::

    python tools/slow_motion_consistency.py          # slowdown 20, seeds 1 and 2
    python tools/slow_motion_consistency.py 10 --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np

from continuum_mhe.cli import main as cli_main
from continuum_mhe.io.estimate_csv import write_measurements
from continuum_mhe.io.robot_file import robot_toml
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.simulation.raw_readings import raw_readings
from continuum_mhe.simulation.scenarios import simulate_robot

DURATION_S = 120.0  # of the slowed recording
DT_S = 0.05
#: the robot: three sections with an IMU at each section's end
ROBOT = Robot(
    (Section(0.12, 3.0), Section(0.10, 3.0), Section(0.08, 3.0)),
    tuple(ImuPlacement(i) for i in range(3)),
)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("slowdown", nargs="?", type=float, default=20.0, help="times slower (20)")
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2], help="IMU noise seeds")
    a = p.parse_args()
    k = a.slowdown
    with tempfile.TemporaryDirectory() as folder:
        robot_file = Path(folder) / "robot.toml"
        robot_file.write_text(robot_toml(ROBOT))
        robot = ROBOT
        rec = simulate_robot("spatial", robot, duration=DURATION_S / k, dt=DT_S / k)
        rec = dataclasses.replace(rec, t=rec.t * k)
        names = [o.name for o in rec.outputs]
        xyz = [names.index(c) for c in ("x", "y", "z")]
        for seed in a.seeds:
            z, columns = raw_readings(rec, robot, seed=seed)
            meas, out = Path(folder) / f"m{seed}.csv", Path(folder) / f"e{seed}.csv"
            write_measurements(str(meas), rec.t, z, columns)
            argv = ["estimate", str(meas), "--robot", str(robot_file), "--method", "ekf"]
            if cli_main([*argv, "-o", str(out)]) != 0:
                raise SystemExit(f"estimate failed on seed {seed}")
            est = read_state_table(out)
            status = np.asarray(est.status)
            bad = np.flatnonzero(status == "inconsistent")
            runs = np.split(bad, np.flatnonzero(np.diff(bad) > 1) + 1) if len(bad) else []
            got = np.column_stack([est.column(c) for c in ("x", "y", "z")])
            err = np.linalg.norm(got - rec.truth[:, xyz], axis=1) * 1e3
            print(
                f"slowdown {k:g}, seed {seed}: {len(bad)} of {len(status)} rows inconsistent "
                f"({100 * len(bad) / len(status):.1f} %) in {len(runs)} stretch(es) of "
                f"{', '.join(str(len(r)) for r in runs) or 'no'} rows; mean tip error "
                f"{np.nanmean(err):.2f} mm"
            )


if __name__ == "__main__":
    main()
