"""Estimators on the two-section Cosserat-rod recordings (data the PCC model did not
generate): tip and section-end errors of MHE, EKF and UKF with raw IMUs (``direct``) and
with tilt only (``bend``), beside the PCC-model floor and a one-section model of the
whole robot driven by the tip IMU.

    python tools/two_section_rod_study.py [FOLDER]   # default: the shipped data/rod2
"""

import json
import sys
import warnings
from pathlib import Path

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.io.csv_files import read_state_table
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.robot_logs import InputOptions, load_estimate_input
from continuum_mhe.metrics import compute_metrics
from continuum_mhe.model.robot import Robot

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"


def evaluate(robot: Robot, path: Path, model: str, truth_path: Path) -> dict[str, tuple]:
    truth = read_state_table(truth_path)
    opts = InputOptions(raw=RawImuSettings(imu_model="direct" if model == "direct" else "tilt"))
    data = load_estimate_input(path, opts, make_formulation("bend", robot))
    out = {}
    for m in ("mhe", "ekf", "ukf"):
        s = make_estimator(m, data.formulation, MHESettings(horizon=30)).run(data.t, data.z)  # type: ignore[arg-type]
        names = [o.name for o in data.formulation.outputs]
        met = compute_metrics(s.output, truth.values, robot.length, names, truth.names)
        ends = met.section_end_mean_mm
        out[m] = (met.tip_mean_mm, met.tip_max_mm, ends.get("1", float("nan")))
    return out


def main() -> None:
    warnings.simplefilter("ignore")
    folder = Path(sys.argv[1]) if len(sys.argv) > 1 else DATA
    robot = read_robot("two-section")
    one = Robot.single(robot.length, 3.0)
    for info_path in sorted(folder.glob("*_info.json")):
        name = info_path.name[: -len("_info.json")]
        info = json.loads(info_path.read_text())
        truth = folder / f"{name}_truth.csv"
        print(
            f"== {name}: PCC floor {info['pcc_floor_mean_mm']:.2f} mm mean "
            f"({info['pcc_floor_max_mm']:.2f} max), one-section arc through the true tip "
            f"tangent {info['one_section_mean_mm']:.1f} mm, twist up to "
            f"{info['twist_max_deg']:.1f} deg, bends up to "
            f"{', '.join(f'{v:.0f}' for v in info['theta_max_deg'])} deg"
        )
        for model, file in (("direct", "raw"), ("bend", "tilt")):
            res = evaluate(robot, folder / f"{name}_{file}.csv", model, truth)
            for m, (mean, mx, end1) in res.items():
                ratio = mean / info["pcc_floor_mean_mm"]
                print(
                    f"   {file:4s} {m}: tip {mean:6.2f} mm mean ({ratio:.1f}x floor), "
                    f"max {mx:6.1f} mm; section 1 end {end1:5.2f} mm"
                )
        # one-section model of the whole robot, driven by the tip IMU (columns _2)
        import numpy as np

        from continuum_mhe.io.csv_files import read_measurements

        tilt = read_measurements(folder / f"{name}_tilt.csv", n_imus=2)
        f1 = make_formulation("bend", one)
        s = make_estimator("mhe", f1, MHESettings(horizon=30)).run(tilt.t, tilt.z[:, 2:4])
        t_tab = read_state_table(truth)
        err = np.linalg.norm(s.output[:, :3] - t_tab.values[:, :3], axis=1) * 1e3
        print(f"   one-section model (tip IMU, tilt, MHE): tip {err.mean():6.2f} mm mean")


if __name__ == "__main__":
    main()
