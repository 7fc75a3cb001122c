"""A two-pass start for the tendon EKF with tilt IMUs (docs/tendon-studies.md, "Tilt IMUs
on `unloaded`"): the compiled EKF's inference stepped over a generator recording, then
stepped again from its own start with the IMUs' misalignment and accelerometer-bias
states (and their covariance) taken from the previous pass's last sample, as a batch
run could do; prints one JSON line with the mean tip error (mm, after the first second)
of each pass.

    python tools/tendon_two_pass_study.py DIR SCENARIO [--passes 3]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from tendon_study import _table

from continuum_mhe.estimators.base import Measurement
from continuum_mhe.estimators.kalman import CompiledExtendedKalmanInference
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--passes", type=int, default=3)
    a = p.parse_args()
    robot = read_robot("tendon-two-section")
    base = make_formulation("bend", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    tensions = read_tensions(a.folder / f"{a.scenario}_tensions.csv", robot.n_tendons)
    _, tilt = _table(a.folder / f"{a.scenario}_tilt.csv")
    names, truth = _table(a.folder / f"{a.scenario}_truth.csv")
    t = tilt[:, 0]
    z = np.array([f.measurement_row(r[1:5], *tensions.at(r[0])) for r in tilt])
    errors = [i for i, n in enumerate(f.state_names) if n.startswith(("mis", "ba"))]
    cols = [o.name for o in f.outputs]
    tip_est = [cols.index(c) for c in "xyz"]
    tip_true = [names.index(c) for c in "xyz"]

    def run(prior: tuple[np.ndarray, np.ndarray] | None) -> tuple[float, np.ndarray, np.ndarray]:
        inference = CompiledExtendedKalmanInference(f)
        tip = []
        for i, tk in enumerate(t):
            x, P, _ = inference.infer(Measurement(float(tk), z[i]))
            assert x is not None and P is not None
            if i == 0 and prior is not None:
                x, P = x.copy(), P.copy()
                x[errors] = prior[0][errors]
                P[errors, :], P[:, errors] = 0.0, 0.0
                P[np.ix_(errors, errors)] = prior[1][np.ix_(errors, errors)]
                inference._x, inference._P = x.copy(), P.copy()
            y = inference.output(x)
            tip.append(np.linalg.norm(y[tip_est] - truth[i, tip_true]))
        keep = t >= 1.0
        assert x is not None and P is not None
        return float(np.mean(np.array(tip)[keep]) * 1e3), x.copy(), P.copy()

    means, prior = [], None
    for _ in range(a.passes):
        mean, x, P = run(prior)
        means.append(round(mean, 2))
        prior = (x, P)
    print(json.dumps({"scenario": a.scenario, "tip_mean_mm_by_pass": means}))


if __name__ == "__main__":
    main()
