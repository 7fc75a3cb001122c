"""The gyro-bias prior of a calibrated robot file, measured (docs/model-studies.md, "The
gyro-bias prior after a calibration"): each two-section rod recording's robot calibrated
from its rest recording (``calibrate --write-robot``), then its raw recording estimated
with the command line's defaults by the EKF and the MHE, with the calibrated IMUs' bias
prior at each value given (``DirectFormulation.calibrated_gyro_bias_std``, rad/s);
prints the mean and largest tip error (mm) of each run, one line per recording::

    python tools/gyro_bias_prior_study.py                       # the shipped rod2
    python tools/gyro_bias_prior_study.py --rods DIR            # e.g. rod_variants.py's
    python tools/gyro_bias_prior_study.py --stds 0.05,0.01,0.005
    python tools/gyro_bias_prior_study.py --only planar-s --stale 0.03,-0.02

``--stale GX,GY`` moves every IMU's calibrated ``gyro_bias`` by ``(GX, GY, 0)`` rad/s
after the calibration: a calibration that no longer holds.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from continuum_mhe.cli import main as cli
from continuum_mhe.estimators import make_estimator
from continuum_mhe.io.input_options import InputOptions
from continuum_mhe.io.inputs import load_input
from continuum_mhe.io.robot_file import read_robot
from continuum_mhe.io.state_tables import read_state_table
from continuum_mhe.model.direct import DirectFormulation
from continuum_mhe.model.registry import make_formulation

ROD2 = Path(__file__).resolve().parents[1] / "src/continuum_mhe/data/rod2"


def tip_errors_mm(
    folder: Path, name: str, stds: list[float], stale: tuple[float, float] = (0.0, 0.0)
) -> dict[str, tuple[float, float]]:
    """``{"METHOD std": (mean, largest)}`` tip error in mm of recording ``name`` in
    ``folder`` (its ``_rest``, ``_raw`` and ``_truth`` files), calibrated, each IMU's
    ``gyro_bias`` then moved by ``(*stale, 0)`` rad/s."""
    with tempfile.TemporaryDirectory() as tmp:
        cal = Path(tmp) / "cal.toml"
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            code = cli(["calibrate", "--from", str(folder / f"{name}_rest.csv"), "--robot",
                        "two-section", "--write-robot", str(cal)])  # fmt: skip
        if code != 0:
            raise SystemExit(f"{name}: calibrate failed ({code})")
        robot = read_robot(str(cal))
    moved = tuple(
        replace(
            imu,
            gyro_bias=(imu.gyro_bias[0] + stale[0], imu.gyro_bias[1] + stale[1], imu.gyro_bias[2]),
        )  # fmt: skip
        for imu in robot.imus
    )
    robot = replace(robot, imus=moved)
    data = load_input(folder / f"{name}_raw.csv", InputOptions(), make_formulation("bend", robot))
    f = data.formulation
    assert isinstance(f, DirectFormulation)
    truth = read_state_table(folder / f"{name}_truth.csv")
    tip = np.column_stack([np.interp(data.t, truth.t, truth.column(c)) for c in "xyz"])
    out: dict[str, tuple[float, float]] = {}
    for method in ("ekf", "mhe"):
        for std in stds:
            series = make_estimator(method, replace(f, calibrated_gyro_bias_std=std)).run(
                data.t, data.z
            )
            names = [o.name for o in series.outputs]
            cols = [names.index(c) for c in "xyz"]
            err = 1e3 * np.linalg.norm(series.output[:, cols] - tip, axis=1)
            out[f"{method} {std:g}"] = (float(np.nanmean(err)), float(np.nanmax(err)))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rods", type=Path, default=ROD2, help="folder of recordings (default rod2)")
    p.add_argument("--stds", default="0.05,0.01", help="prior values, rad/s (default 0.05,0.01)")
    p.add_argument("--only", nargs="*", default=None, help="these recordings only")
    p.add_argument("--stale", default="0,0", help="GX,GY rad/s added to each gyro_bias")
    a = p.parse_args()
    stds = [float(v) for v in a.stds.split(",")]
    gx, gy = (float(v) for v in a.stale.split(","))
    names = sorted(r.name[: -len("_rest.csv")] for r in a.rods.glob("*_rest.csv"))
    for name in names if a.only is None else [n for n in names if n in a.only]:
        res = tip_errors_mm(a.rods, name, stds, (gx, gy))
        cells = "  ".join(f"{k}: {m:.2f} / {x:.2f}" for k, (m, x) in res.items())
        print(f"{name:28s} {cells}", flush=True)


if __name__ == "__main__":
    main()
