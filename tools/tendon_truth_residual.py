"""The tendon EKF's measurement residual at the TRUE state of a generator recording
(docs/tendon-studies.md, "Under load"): the true tip force and its first and second time
derivatives (central differences of the truth file), the true tensions, the base
curvature that meets the tip condition, and the IMUs' true misalignment and biases
(drawn again from the recording's seed, in the order of
``continuum_mhe.simulation.cosserat_sections.imu_samples``). A model that describes the
IMUs leaves the noise (accelerometer direction 0.12 degrees, gyro 0.1 deg/s); prints
the rms and the largest mean over 0.5 s windows of each IMU reading, degrees and deg/s.

    python tools/tendon_truth_residual.py DIR SCENARIO --seed S [--set NAME=VALUE]
"""

from __future__ import annotations

import argparse
import ast
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
from tendon_study import _table, imu_readings

from continuum_mhe.estimators.fast import NodeEvaluator, node_functions
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.tensions import Tensions, read_tensions, tendon_formulation_for
from continuum_mhe.model.registry import make_formulation
from continuum_mhe.model.settings import NoiseSettings
from continuum_mhe.model.tendon import TendonFormulation
from continuum_mhe.simulation.cosserat_sections import DEFAULT_IMU


def true_imu_errors(seed: int, n: int, n_imus: int) -> dict[str, np.ndarray]:
    """The constant errors the generator drew for ``n`` samples: misalignment (rad),
    accelerometer bias (m/s^2) and gyro bias (rad/s), 3 per IMU, keyed ``mis``, ``ba``,
    ``bg``."""
    rng, imu = np.random.default_rng(seed), DEFAULT_IMU
    out: dict[str, list[np.ndarray]] = {"mis": [], "ba": [], "bg": []}
    for _ in range(n_imus):
        out["mis"].append(np.radians(imu.misalignment_deg) * rng.normal(size=3))
        out["ba"].append(imu.accel_bias * rng.normal(size=3))
        rng.normal(size=(n, 3))  # the accelerometer's noise
        out["bg"].append(imu.gyro_bias * rng.normal(size=3))
        rng.normal(size=(n, 3))  # the gyro's noise
    return {k: np.concatenate(v) for k, v in out.items()}


class RawRecording(NamedTuple):
    """A generator recording read for the tendon EKF with raw IMUs."""

    formulation: TendonFormulation
    tensions: Tensions
    t: np.ndarray
    z_imu: np.ndarray
    names: list[str]
    truth: np.ndarray


def read_raw_recording(folder: Path, scenario: str, changes: list[str]) -> RawRecording:
    """The command line's tendon formulation with raw IMUs (``changes``: its fields as
    ``NAME=VALUE``), the recording's tensions, times, IMU readings and truth."""
    robot = read_robot("tendon-two-section")
    base = make_formulation("direct", robot, NoiseSettings(measurement_std=math.radians(2.0)))
    f = tendon_formulation_for(base, InputOptions())
    f = replace(f, **{k: ast.literal_eval(v) for k, v in (kv.split("=", 1) for kv in changes)})
    tensions = read_tensions(folder / f"{scenario}_tensions.csv", robot.n_tendons)
    t, z_imu = imu_readings(folder, scenario, "direct", range(robot.n_imus))
    names, truth = _table(folder / f"{scenario}_truth.csv")
    return RawRecording(f, tensions, t, z_imu, names, truth)


def recording_parser() -> argparse.ArgumentParser:
    """The arguments naming a recording: its folder, scenario, seed and the
    formulation's changes (``--set NAME=VALUE``)."""
    p = argparse.ArgumentParser()
    p.add_argument("folder", type=Path)
    p.add_argument("scenario")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", action="append", default=[], metavar="NAME=VALUE")
    return p


def main() -> None:
    p = recording_parser()
    a = p.parse_args()
    f, tensions, t, z_imu, names, truth = read_raw_recording(a.folder, a.scenario, a.set)
    robot = f.robot
    force = truth[:, [names.index(c) for c in ("fx", "fy", "fz")]]
    force_dot = np.gradient(force, t, axis=0)
    force_ddot = np.gradient(force_dot, t, axis=0)
    sn = list(f.state_names)
    errors = true_imu_errors(a.seed, len(t), robot.n_imus)
    node = NodeEvaluator(node_functions(f))
    k0s, k0 = [], None
    for tk, fk in zip(t, force):
        k0, _ = f.statics.solve(fk, tensions.at(tk)[0], k0)
        k0s.append(k0)
    k0_dot = np.gradient(np.array(k0s), t, axis=0)
    n_imu = f.n_imu_measurements
    residuals = []
    for i, tk in enumerate(t):
        x = np.zeros(f.nx)
        x[:3], x[3:6] = k0s[i], force[i]
        x[[sn.index(f"tension_{j + 1}") for j in range(robot.n_tendons)]] = tensions.at(tk)[0]
        x[[sn.index(f"k0{c}_dot") for c in "xyz"]] = k0_dot[i]
        x[[sn.index(f"f{c}_dot") for c in "xyz"]] = force_dot[i]
        if "fx_ddot" in sn:
            x[[sn.index(f"f{c}_ddot") for c in "xyz"]] = force_ddot[i]
        for key in ("mis", "ba", "bg"):
            if f"{key}x_1" in sn:
                x[[sn.index(f"{key}{c}_{k + 1}") for k in range(robot.n_imus) for c in "xyz"]] = (
                    errors[key]
                )
        z = f.measurement_row(z_imu[i], *tensions.at(tk))
        residuals.append(node.evaluate(x, np.zeros(f.nu), 0.0, z)[3][:n_imu])
    r = np.degrees(np.array(residuals))
    window = max(1, int(round(0.5 / float(t[1] - t[0]))))
    means = np.array([r[j : j + window].mean(axis=0) for j in range(0, len(r), window)])
    print(json.dumps({
        "scenario": a.scenario, "seed": a.seed, "set": a.set,
        "reading": [n for b in f.measurement_blocks if b.is_imu for n in b.names],
        "rms_deg": np.round(np.sqrt(np.mean(r**2, axis=0)), 3).tolist(),
        "largest_window_mean_deg": np.round(np.abs(means).max(axis=0), 3).tolist(),
    }))  # fmt: skip


if __name__ == "__main__":
    main()
