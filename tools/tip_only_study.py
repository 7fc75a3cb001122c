"""One IMU at the tip of a two-section robot: its shape is not observable. Tip error,
statuses, mean tip standard deviation and the fraction of samples outside their 95 %
interval (tip error beyond 2.45 standard deviations, the 95 % radius of a 3-D Gaussian
of that size, approximately), MHE and EKF, tilt (``spatial``) and gyros (raw IMUs,
``direct``), 2 seeds, 20 s at 20 Hz, N = 30.

    python tools/tip_only_study.py
"""

import argparse
import warnings
from collections import Counter

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.benchmark.harness import raw_imu_model, raw_imu_recording
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.simulation.scenarios import simulate_robot

ROBOT = Robot((Section(0.16), Section(0.14)), (ImuPlacement(1),))  # theta_max pi/2


def main() -> None:
    argparse.ArgumentParser(description=__doc__.split("\n\n")[0]).parse_args()  # --help
    warnings.simplefilter("ignore")
    for kind in ("tilt", "gyro"):
        for seed in range(2):
            if kind == "tilt":
                rec = simulate_robot("spatial", ROBOT, duration=20, dt=0.05, seed=seed)
                f = make_formulation("bend", ROBOT)
            else:
                rec = raw_imu_recording(ROBOT, 20, dt=0.05, seed=seed)
                f = raw_imu_model(ROBOT)
            tip = [i for i, o in enumerate(f.outputs) if o.section == 0 and o.unit == "m"]
            for m in ("mhe", "ekf"):
                s = make_estimator(m, f, MHESettings(horizon=30)).run(rec.t, rec.z)  # type: ignore[arg-type]
                err = np.linalg.norm(s.output[:, tip] - rec.truth[:, tip], axis=1) * 1e3
                assert s.output_std is not None
                std = np.linalg.norm(s.output_std[:, tip], axis=1) * 1e3
                counts = dict(Counter(s.status.tolist()))
                print(
                    f"{kind} seed {seed} {m}: tip mean {np.nanmean(err):.1f} mm, max "
                    f"{np.nanmax(err):.1f} mm; mean tip std {np.nanmean(std):.1f} mm; outside "
                    f"95 % {np.nanmean(err > 2.45 * std):.2f}; {counts}"
                )


if __name__ == "__main__":
    main()
