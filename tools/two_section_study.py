"""Two-section ``spatial`` scenario (bends up to 1.7 rad per section, bending planes
turning at different rates): tip error of MHE, EKF and UKF with tilt only and with the
gyros (raw IMUs, ``direct``), 5 seeds, 20 s at 20 Hz, N = 30.

    python tools/two_section_study.py
"""

import argparse
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.benchmark.harness import raw_imu_model, raw_imu_recording
from continuum_mhe.evaluation.metrics import compute_metrics
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.simulation.scenarios import simulate_robot

ROBOT = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/two_section.toml"


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()  # --help
    warnings.simplefilter("ignore")
    robot = read_robot(ROBOT)
    res: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for seed in range(5):
        for kind in ("tilt", "gyro"):
            if kind == "tilt":
                rec = simulate_robot("spatial", robot, duration=20, dt=0.05, seed=seed)
                f = make_formulation("bend", robot)
            else:
                rec = raw_imu_recording(robot, 20, dt=0.05, seed=seed)
                f = raw_imu_model(robot)
            names = [o.name for o in f.outputs]
            for m in ("mhe", "ekf", "ukf"):
                s = make_estimator(m, f, MHESettings(horizon=30)).run(rec.t, rec.z)  # type: ignore[arg-type]
                met = compute_metrics(s.output, rec.truth, robot.length, names)
                res.setdefault((kind, m), []).append((met.tip_mean_mm, met.tip_max_mm))
    for (kind, m), v in res.items():
        a = np.array(v)
        print(
            f"{kind:4s} {m}: tip mean {a[:, 0].mean():.2f} mm "
            f"(seeds {a[:, 0].min():.2f}-{a[:, 0].max():.2f}), max {a[:, 1].max():.1f} mm"
        )


if __name__ == "__main__":
    main()
