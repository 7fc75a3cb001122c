"""The tendon model's tip against the discrete rod with its tendons drawn from disk to
disk, as the disks' spacing grows: for each number of disks a section, the tip of
``TendonFormulation.shape`` with ``tendon_route = "disks"`` and ``"continuous"``, and of
the generator's rod at its default 4 segments a disk, each against the rod extrapolated
to zero segment length from 4 and 8 segments a disk (mm)::

    python tools/disk_spacing_study.py ROBOT.toml 4,5,6,8 T1,T2,...

``T1,T2,...``: the tensions, N, in the robot file's tendon order (the tip force is zero).
The rod is solved at tensions raised in ten steps to the given ones, each step warm
started from the last.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from continuum_mhe.io import read_robot
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.simulation.cosserat_tendon import energy_equilibrium


def rod_tip(robot, tensions: np.ndarray, per: int) -> np.ndarray:
    """The discrete rod's tip (m) at ``per`` segments a disk, tendons from disk to disk."""
    w = None
    for share in np.linspace(0.1, 1.0, 10):
        w, frames = energy_equilibrium(robot, tensions * share, np.zeros(3), w, per, "disks")
    return frames[9:, -1]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("robot", help="a tendon robot file")
    p.add_argument("disks", help="disks a section to try, comma-separated")
    p.add_argument("tensions", help="N, comma-separated, in the robot file's tendon order")
    a = p.parse_args()
    base = read_robot(a.robot)
    tensions = np.array([float(v) for v in a.tensions.split(",")])
    print("disks | model, disks | continuous model | rod at 4 a disk   (tip off, mm)")
    for disks in (int(v) for v in a.disks.split(",")):
        robot = replace(base, sections=tuple(replace(s, disks=disks) for s in base.sections))
        coarse, fine = rod_tip(robot, tensions, 4), rod_tip(robot, tensions, 8)
        rod = fine + (fine - coarse) / 3
        off = []
        for route in ("disks", "continuous"):
            shape = TendonFormulation(replace(robot, tendon_route=route)).shape(
                tensions, np.zeros(3)
            )
            tip = np.array([shape["x"], shape["y"], shape["z"]])
            off.append(1e3 * float(np.linalg.norm(tip - rod)))
        rod_off = 1e3 * float(np.linalg.norm(coarse - rod))
        print(f"{disks:5d} | {off[0]:12.2f} | {off[1]:16.1f} | {rod_off:15.2f}")


if __name__ == "__main__":
    main()
