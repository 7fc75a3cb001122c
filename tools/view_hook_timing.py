"""Time the live view hook, ``BackboneView.log_estimate``, per estimate (.rrd sink).

    python tools/view_hook_timing.py /tmp/hook.rrd

1000 estimates at 100 Hz of sample time (bends drawn at random, every one drawn:
``max_hz`` unset) for the shipped two-section robot and a one-section robot; prints the
median and 99th percentile after the first 50 (the compile of the geometry function).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.descriptions import pcc_outputs
from continuum_mhe.model.robot import Robot
from continuum_mhe.results import Estimate
from continuum_mhe.viewer import BackboneView, ViewerSink


def main(path: Path) -> None:
    for robot in (read_robot("two-section"), Robot.single(0.2)):
        outputs = pcc_outputs(robot.n_sections)
        view = BackboneView(robot, outputs, ViewerSink("save", path))
        rng = np.random.default_rng(0)
        seconds = []
        for k in range(1000):
            out = np.array([0.1 if o.unit == "m" else rng.uniform(0.1, 1) for o in outputs])
            est = Estimate(0.01 * k, None, out, None, "ok", 0.1)
            start = time.perf_counter()
            view.log_estimate(est)
            seconds.append(time.perf_counter() - start)
        view.close()
        ms = np.array(seconds[50:]) * 1e3
        print(
            f"{robot.describe()}: log_estimate median {np.median(ms):.3f} ms, "
            f"p99 {np.percentile(ms, 99):.3f} ms"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("rrd", nargs="?", type=Path, default=Path("hook.rrd"),
                        help="the recording to write (default hook.rrd)")  # fmt: skip
    main(parser.parse_args().rrd)
