"""One IMU of the two-section robot silent, then back: are the estimates after its
return honest? (``start_check``'s IMU-return confirmation.)

For each of ``spatial`` and ``s-curve``, each seed (20 s at 20 Hz), each IMU and each
silence (from 4 s for 3 s, 6 s for 3 s, 8 s for 1.5 s, 10 s for 2 s, 12 s for 5 s) the
IMU's readings are NaN; compiled EKF, UKF and MHE (N = 30) run with recovery off
(``--recovery off``: ``RecoverySettings.off()``, gap reset and bad-start check off) or the
defaults (``--recovery defaults``: ``RecoverySettings()``, the command line's). Reported per
method: the largest tip error, in standard deviations of the estimate's own tip
position, of an ``ok`` estimate within 2 s after the return and anywhere; the ``ok``
samples within the 2 s beyond 5 standard deviations; and the mean number of samples
not ``ok`` from the return to the end.

    python tools/imu_return_study.py --seeds 6 --recovery off
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.settings import RecoverySettings
from continuum_mhe.simulation.scenarios import simulate_robot

ROBOT = Path(__file__).parents[1] / "src/continuum_mhe/data/robots/two_section.toml"
SILENCES = ((4.0, 3.0), (6.0, 3.0), (8.0, 1.5), (10.0, 2.0), (12.0, 5.0))
RECOVERY = {
    "off": RecoverySettings.off(),
    "defaults": RecoverySettings(),
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", type=int, default=6)
    p.add_argument("--recovery", choices=sorted(RECOVERY), default="off")
    args = p.parse_args()
    warnings.simplefilter("ignore")
    robot = read_robot(ROBOT)
    f = make_formulation("bend", robot)
    rs = RECOVERY[args.recovery]
    # method -> [worst within 2 s, worst anywhere, ok beyond 5 within 2 s, not ok, runs]
    res: dict[str, list[float]] = {}
    for scenario in ("spatial", "s-curve"):
        for seed in range(args.seeds):
            rec = simulate_robot(scenario, robot, duration=20.0, dt=0.05, seed=seed)  # type: ignore[arg-type]
            for imu in range(len(robot.imus)):
                for t0, seconds in SILENCES:
                    z = rec.z.copy()
                    z[(rec.t >= t0) & (rec.t < t0 + seconds), 2 * imu : 2 * imu + 2] = np.nan
                    back = rec.t >= t0 + seconds
                    near = back & (rec.t < t0 + seconds + 2.0)
                    for m in ("ekf", "ukf", "mhe"):
                        est = make_estimator(m, f, MHESettings(horizon=30), rs)  # type: ignore[arg-type]
                        s = est.run(rec.t, z)
                        err = np.linalg.norm(s.output[:, :3] - rec.truth[:, :3], axis=1)
                        sigmas = err / np.linalg.norm(s.output_std[:, :3], axis=1)
                        ok = s.status == "ok"
                        r = res.setdefault(m, [0.0, 0.0, 0, 0, 0])
                        r[0] = max(r[0], sigmas[ok & near].max(initial=0.0))
                        r[1] = max(r[1], sigmas[ok].max(initial=0.0))
                        r[2] += int(np.sum(ok & near & (sigmas > 5.0)))
                        r[3] += int(np.sum(back & ~ok))
                        r[4] += 1
    for m, (near_w, any_w, beyond, not_ok, runs) in res.items():
        print(
            f"{args.recovery} {m}: ok within 2 s of the return at most {near_w:.2f} std off "
            f"({int(beyond)} beyond 5), anywhere {any_w:.2f}; not ok from the return on: "
            f"{not_ok / runs:.1f} samples per run ({int(runs)} runs)"
        )


if __name__ == "__main__":
    main()
