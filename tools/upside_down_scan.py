"""One tilt reading turned upside down (roll plus or minus pi, pitch negated) at random
places in the shipped two-section rods' tilt recordings, at 50, 5 and 1 Hz (every 1st,
10th and 50th row), for each IMU, with the MHE, the EKF and the UKF with their defaults:
prints every run that has an ``ok`` row more than 50 mm off that the clean recording
does not have (docs/reliability.md, "Never ok when wrong"). A few minutes on 2 cores.

    python tools/upside_down_scan.py [--seed S] [--places N]
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np

from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.simulation.cosserat import default_data_path

RODS = ("planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial")
FAR = 0.05  # m


def rod_tilt(name: str, every: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, z, tip truth)`` of a shipped rod's tilt recording, every ``every``-th row."""
    folder = default_data_path().parent / "rod2"
    rows = np.genfromtxt(folder / f"{name}_tilt.csv", delimiter=",", names=True)[::every]
    truth = np.genfromtxt(folder / f"{name}_truth.csv", delimiter=",", names=True)[::every]
    z = np.column_stack([rows[c] for c in ("roll_1", "pitch_1", "roll_2", "pitch_2")])
    return rows["t"], z, np.column_stack([truth["x"], truth["y"], truth["z"]])


def upside_down(z: np.ndarray, k: int, imu: int) -> np.ndarray:
    """``z`` with IMU ``imu``'s reading ``k`` upside down."""
    z = z.copy()
    j = 2 * (imu - 1)
    z[k, j] += -math.pi if z[k, j] > 0 else math.pi
    z[k, j + 1] = -z[k, j + 1]
    return z


def far_ok_rows(method: str, f, t, z, tip) -> set[int]:  # type: ignore[no-untyped-def]
    s = make_estimator(method, f).run(t, z)
    err = np.linalg.norm(np.asarray(s.output)[:, :3] - tip, axis=1)
    return set(np.flatnonzero((err > FAR) & (s.status == "ok")).tolist())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=0, help="the places' draw")
    p.add_argument("--places", type=int, default=4, help="places per recording and IMU")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    f = make_formulation("bend", read_robot("two-section"))
    rng = np.random.default_rng(args.seed)
    cases = runs = 0
    for name in RODS:
        for every in (1, 10, 50):
            t, z, tip = rod_tilt(name, every)
            clean = {m: far_ok_rows(m, f, t, z, tip) for m in ("mhe", "ekf", "ukf")}
            n = len(t)
            for imu in (1, 2):
                places = rng.choice(
                    np.arange(2, n - 1), size=min(args.places, n - 3), replace=False
                )
                for k in places:
                    zk = upside_down(z, int(k), imu)
                    for method in ("mhe", "ekf", "ukf"):
                        runs += 1
                        new = sorted(far_ok_rows(method, f, t, zk, tip) - clean[method])
                        if new:
                            cases += 1
                            print(
                                f"{name} at {50 // every} Hz, IMU {imu} upside down at t = "
                                f"{t[k]:g} s, {method}: new ok rows more than 50 mm off at "
                                f"t = {', '.join(f'{t[i]:g}' for i in new[:5])} s",
                                flush=True,
                            )
    print(f"{cases} of {runs} runs with a new ok row more than 50 mm off")


if __name__ == "__main__":
    main()
