"""Newton against Gauss-Newton steps in the fast MHE, for a robot of K sections.

A robot of K sections of ``0.3 / K`` m with an IMU at each section's end, raw IMUs
(direct model, gyro biases estimated; ``--own-acceleration`` with the IMUs' own
acceleration), ``simulate_robot("spatial", ...)`` of 4 s (20 Hz, seed 0). The fast MHE
(N = 30) runs twice (``--tilt``: the tilt IMUs' readings of the same motion;
``--recording`` with ``--robot``: a raw recording of that robot instead): with the
measurement residuals' second-order term formed (exact
Newton steps, whatever the residual's size) and without it (Gauss-Newton steps). Prints
each one's build time, run time, median ``solve_ms`` from sample 30 on and statuses, the
residual's instruction count, and the largest difference of the two runs' outputs (the
fast MHE itself forms the second-order term wherever the formulation can)::

    python tools/second_order_study.py 3 --own-acceleration
    python tools/second_order_study.py 6 --own-acceleration
    python tools/second_order_study.py 4
    python tools/second_order_study.py 3 --tilt
    python tools/second_order_study.py 2 --own-acceleration --robot two-section \\
        --recording src/continuum_mhe/data/rod2/planar-s_raw.csv
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path

import numpy as np

from continuum_mhe.estimators.fast import FastOptions
from continuum_mhe.estimators.mhe import MovingHorizonEstimator
from continuum_mhe.io.estimate_csv import write_measurements
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.robot import ImuPlacement, Robot, Section
from continuum_mhe.model.tape import residual_function
from continuum_mhe.settings import MHESettings
from continuum_mhe.simulation.raw_readings import raw_readings
from continuum_mhe.simulation.scenarios import simulate_robot


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sections", type=int, help="sections of the robot (2 or more)")
    p.add_argument("--own-acceleration", action="store_true", help="the IMUs' own acceleration")
    p.add_argument("--tilt", action="store_true", help="tilt IMUs instead of raw ones")
    p.add_argument("--recording", type=Path, help="a raw recording to run instead (with --robot)")
    p.add_argument("--robot", help="its robot file, or a shipped robot's name")
    a = p.parse_args()
    k = a.sections
    robot = Robot(
        tuple(Section(0.3 / k, 3.0) for _ in range(k)), tuple(ImuPlacement(i) for i in range(k))
    )
    if a.recording is not None:
        robot = read_robot(a.robot)
    rec = simulate_robot("spatial", robot, duration=4.0, seed=0)
    options = InputOptions(
        raw=RawImuSettings(imu_model="direct"),
        estimate_gyro_bias=True,
        own_acceleration=a.own_acceleration,
    )
    if a.tilt:
        f, data = make_formulation("bend", robot), None
        t, z = rec.t, rec.z
    else:
        with tempfile.TemporaryDirectory() as folder:  # read as estimate reads it
            path = a.recording
            if path is None:
                path = Path(folder) / "raw.csv"
                values, names = raw_readings(rec, robot, seed=0)
                write_measurements(path, rec.t, values, names)
            data = load_input(path, options, make_formulation("bend", robot))
        f, t, z = data.formulation, data.t, data.z
    size = residual_function(f).n_instructions()
    print(
        f"{robot.n_sections} sections, {'tilt' if a.tilt else 'raw'} IMUs"
        f"{' with their own acceleration' if a.own_acceleration else ''}:"
        f" residual {size} instructions"
    )
    # a formulation of its own class each (the window model is cached per formulation)
    newton = type("Newton", (type(f),), {})(**_fields(f))
    gauss = type("GaussNewton", (type(f),), {"second_order_residuals": False})(**_fields(f))
    outputs = []
    for label, form, exact in (("Newton", newton, True), ("Gauss-Newton", gauss, False)):
        t0 = time.perf_counter()
        est = MovingHorizonEstimator(form, MHESettings(horizon=30), FastOptions(newton=exact))
        t1 = time.perf_counter()
        s = est.run(t, z)
        t2 = time.perf_counter()
        outputs.append(s.output)
        names, counts = np.unique(s.status, return_counts=True)
        print(
            f"  {label:12s} built in {t1 - t0:5.1f} s, ran {len(t)} samples in "
            f"{t2 - t1:5.2f} s, median solve {np.median(s.solve_ms[30:]):7.3f} ms; "
            + ", ".join(f"{n} {c}" for n, c in zip(names, counts))
        )
    print(f"  largest difference of the outputs: {np.nanmax(np.abs(outputs[0] - outputs[1])):.1e}")


def _fields(f: object) -> dict[str, object]:
    return {fl.name: getattr(f, fl.name) for fl in dataclasses.fields(f) if fl.init}  # type: ignore[arg-type]


if __name__ == "__main__":
    main()
