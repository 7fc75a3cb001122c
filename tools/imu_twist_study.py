"""A twist of each IMU about the backbone's tangent as a state: a prototype, not in the
library.

The PCC model's frames are torsion-free, and a rod that twists turns each IMU about the
tangent by an angle no PCC shape explains (``tangent_twist_max_deg`` in a rod
recording's ``*_info.json``: up to 122 degrees at the tip of the shipped ``spatial``
rod). Here the raw-IMU model (``direct``, gyro biases estimated, as the command line
has it for a raw recording) gains, per IMU ``i`` (``--twist all``) or for the tip IMU
alone (``--twist tip``), a twist ``psi_i`` about its z axis and its rate, a
constant-velocity state driven by white-noise acceleration (``--psd``, rad^2/s^3),
starting at 0 with standard deviations ``--initial-std`` (rad and rad/s). The IMU's
frame is the PCC frame turned by ``Rz(psi_i)``: the gravity direction it reads is
``Rz(psi_i)^T g`` and its gyro ``Rz(psi_i)^T omega + (0, 0, psi_i')``. The positions
stay the PCC model's.

Prints, per shipped rod recording and estimator, the mean and largest tip error (mm),
the rows ``ok`` and those of them more than 20 mm off, without the twist states and
with them::

    python tools/imu_twist_study.py                      # every rod, EKF, --twist all
    python tools/imu_twist_study.py --twist tip --methods ekf mhe
"""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from continuum_mhe import MHESettings, make_estimator, make_formulation
from continuum_mhe.arrays import FloatArray
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.raw_imu import RawImuSettings
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.formulations import Formulation

DATA = Path(__file__).parents[1] / "src/continuum_mhe/data/rod2"
RODS = ("planar-s", "spatial-tendon", "spatial-stiff-torsion", "spatial")


@dataclass(frozen=True)
class ImuTwistDirect(DirectFormulation):
    """``direct`` with a twist about the z axis of the IMUs ``twisted`` (indices) as
    states after the others: their angles (rad), then their rates (rad/s)."""

    twisted: tuple[int, ...] = ()
    twist_accel_psd: float = 0.5
    initial_twist_std: float = 0.02

    @property
    def state_names(self) -> tuple[str, ...]:
        names = tuple(f"psi_{i + 1}" for i in self.twisted)
        return super().state_names + names + tuple(f"{n}_dot" for n in names)

    def _twist_states(self, x: Any) -> tuple[list[Any], list[Any]]:
        m = len(self.twisted)
        n0 = self.nx - 2 * m
        return [x[n0 + j] for j in range(m)], [x[n0 + m + j] for j in range(m)]

    def transition_sym(self, x: Any, u: Any, dt: Any) -> Any:
        m = len(self.twisted)
        n0 = self.nx - 2 * m
        psi, rate = self._twist_states(x)
        moved = [p + dt * r for p, r in zip(psi, rate)]
        return ca.vertcat(super().transition_sym(x, u, dt)[:n0], *moved, *rate)

    def process_cov_sym(self, dt: Any) -> Any:
        m = len(self.twisted)
        n0 = self.nx - 2 * m
        q = self.twist_accel_psd
        block = q * ca.blockcat([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        return ca.diagcat(super().process_cov_sym(dt)[:n0, :n0], ca.kron(block, ca.SX.eye(m)))

    def initial_cov(self) -> FloatArray:
        m = len(self.twisted)
        n0 = self.nx - 2 * m
        var = np.diag(super().initial_cov())[:n0]
        return np.diag(np.concatenate([var, np.full(2 * m, self.initial_twist_std**2)]))

    @staticmethod
    def _turned(psi: Any, v: Any) -> Any:
        """``Rz(psi)^T v``."""
        c, s = ca.cos(psi), ca.sin(psi)
        return ca.vertcat(c * v[0] + s * v[1], -s * v[0] + c * v[1], v[2])

    def gravity_directions_sym(self, x: Any) -> list[Any]:
        g = super().gravity_directions_sym(x)
        psi, _ = self._twist_states(x)
        for j, i in enumerate(self.twisted):
            g[i] = self._turned(psi[j], g[i])
        return g

    def angular_velocities_sym(self, x: Any) -> list[Any]:
        w = super().angular_velocities_sym(x)
        psi, rate = self._twist_states(x)
        for j, i in enumerate(self.twisted):
            w[i] = self._turned(psi[j], w[i]) + ca.vertcat(0, 0, rate[j])
        return w


def run(name: str, method: str, twisted: tuple[int, ...] | None, args: Any) -> str:
    """One estimate of ``NAME_raw.csv``; ``twisted`` None: the plain ``direct`` model."""
    robot = read_robot("two-section")
    options = InputOptions(raw=RawImuSettings(imu_model="direct"), estimate_gyro_bias=True)
    data = load_input(DATA / f"{name}_raw.csv", options, make_formulation("bend", robot))
    f: Formulation = data.formulation
    if twisted is not None:
        fields = {fl.name: getattr(f, fl.name) for fl in dataclasses.fields(f) if fl.init}
        fields.pop("name")
        f = ImuTwistDirect(
            **fields,
            twisted=twisted,
            twist_accel_psd=args.psd,
            initial_twist_std=args.initial_std,
        )
    est = make_estimator(method, f, MHESettings(horizon=30))
    s = est.run(data.t, data.z)
    truth = np.genfromtxt(DATA / f"{name}_truth.csv", delimiter=",", names=True)
    tip = np.column_stack([truth["x"], truth["y"], truth["z"]])
    err = np.linalg.norm(s.output[:, :3] - tip, axis=1) * 1e3
    ok = np.asarray(s.status) == "ok"
    return (
        f"mean {np.nanmean(err):6.2f}, max {np.nanmax(err):6.1f} mm; ok {ok.sum():3d}, "
        f"of them > 20 mm off {(ok & (err > 20)).sum():3d}"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--twist", choices=("all", "tip"), default="all", help="which IMUs twist")
    p.add_argument("--methods", nargs="+", default=["ekf"], help="estimators (default ekf)")
    p.add_argument("--only", nargs="+", default=list(RODS), help="rod recordings")
    p.add_argument("--psd", type=float, default=0.5, help="twist acceleration psd, rad^2/s^3")
    p.add_argument("--initial-std", type=float, default=0.02, help="twist prior std, rad")
    args = p.parse_args()
    twisted = (0, 1) if args.twist == "all" else (1,)
    for name in args.only:
        for method in args.methods:
            print(f"{name:22s} {method}: PCC   {run(name, method, None, args)}", flush=True)
            print(f"{'':22s} {method}: twist {run(name, method, twisted, args)}", flush=True)


if __name__ == "__main__":
    main()
